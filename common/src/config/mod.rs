//! The one DUPAC configuration: a TOML file whose every key has a serde default, that rejects
//! unknown keys, and that `--set a.b=v` overrides from the command line.
//!
//! Defaults follow `spec/radio.md` (radio) and `spec/env.md` (scenario).
//! [`Config::load`] parses, applies overrides and validates once; everything downstream receives a
//! resolved, valid [`Config`].

mod channel;
mod check;
pub mod describe;
mod distributed;
mod env;
mod learn;
mod pairs;
mod radio;
mod scenario;

pub use channel::*;
pub use distributed::*;
pub use env::*;
pub use learn::*;
pub use pairs::*;
pub use radio::*;
pub use scenario::*;

use check::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Errors while reading, overriding or validating the configuration. Each names the file, the
/// override or the key at fault.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config file {path}: {cause}")]
    Read {
        path: PathBuf,
        /// The OS error, part of this error's message (not its `source()`, so that a printed
        /// chain shows it once).
        cause: std::io::Error,
    },
    #[error("config file {path}: {message}")]
    Parse { path: String, message: String },
    #[error("--set {arg:?}: {message}")]
    Override { arg: String, message: String },
    #[error("config key `{key}`: {message}")]
    Invalid { key: String, message: String },
    /// [`ConfigError::Invalid`] found in a file (`origin`, with its `--set` overrides if any).
    #[error("config file {origin}: key `{key}`: {message}")]
    InvalidIn {
        origin: String,
        key: String,
        message: String,
    },
}

/// The whole configuration of a DUPAC run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema, Default)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// The city, the flight area and the base stations.
    pub scenario: ScenarioConfig,
    /// The radio model: carrier, powers, path loss, antennas, A3.
    pub radio: RadioConfig,
    /// Coverage maps (`dupac map`).
    pub map: MapConfig,
    /// The per-site 3D RSRP cache.
    pub cache: CacheConfig,
    /// The flight environment: the MDP, its reward and observation.
    pub env: EnvConfig,
    /// Training and held-out evaluation pairs.
    pub pairs: PairsConfig,
    /// The shortest-path and coverage-aware planners.
    pub planner: PlannerConfig,
    /// PPO's hyperparameters and network.
    pub ppo: PpoConfig,
    /// A training run: length, seeds, evaluation, checkpoints, outputs.
    pub train: TrainConfig,
    /// The Zenoh actor/learner run.
    pub distributed: DistributedConfig,
}
/// Largest configuration file read (bytes): a real one is a few KiB.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

impl Config {
    /// The configuration training rollouts step their environments with: the UAV's sphere
    /// grown by `env.training_margin_m` (then 0, so it is never applied twice). Evaluation and
    /// flights use `self` unchanged.
    pub fn training(&self) -> Config {
        let mut c = self.clone();
        c.env.uav_radius_m += c.env.training_margin_m;
        c.env.training_margin_m = 0.0;
        c
    }

    /// Identifies everything that makes one process's environment steps and policy shapes
    /// differ from another's: the radio world (`world_fingerprint`: city, sites, RSRP
    /// parameters), the radio, cache, environment, pairs (without the test split:
    /// [`PairsConfig::fingerprint_json`]) and planner sections and the network widths. Actors whose fingerprint differs from the learner's are refused; the
    /// PPO hyperparameters, seeds and output paths do not count.
    pub fn env_fingerprint(&self, world_fingerprint: u64) -> u64 {
        let mut h = crate::fingerprint::Fnv64::new();
        h.write_u64(world_fingerprint);
        // File locations may differ between hosts; only contents count.
        let mut cache = self.cache.clone();
        cache.path = PathBuf::new();
        for part in [
            serde_json::to_string(&self.radio),
            serde_json::to_string(&cache),
            serde_json::to_string(&self.env),
            Ok(self.pairs.fingerprint_json()),
            serde_json::to_string(&self.planner),
            serde_json::to_string(&self.ppo.hidden),
        ] {
            h.write_str(&part.unwrap_or_default());
        }
        h.finish()
    }

    /// Parses a TOML string (`origin` names it in errors), applies `--set` overrides, validates.
    /// An error of the file names its line and key; one an override causes names the override.
    pub fn from_toml_str(text: &str, origin: &str, sets: &[String]) -> Result<Config, ConfigError> {
        let parse_err = |e: toml::de::Error| ConfigError::Parse {
            path: origin.to_string(),
            message: e.to_string(),
        };
        // Deserialised from the text itself (not from a parsed table) so that errors carry the
        // line and column.
        let mut config: Config = toml::from_str(text).map_err(parse_err)?;
        if !sets.is_empty() {
            let mut value: toml::Table = toml::from_str(text).map_err(parse_err)?;
            // The override after which the configuration stopped deserialising (and why); later
            // overrides may complete it again (e.g. the bounds of `scenario.area` one by one).
            let mut broken_by: Option<(&String, toml::de::Error)> = None;
            for arg in sets {
                apply_override(&mut value, arg)?;
                match Config::deserialize(toml::Value::Table(value.clone())) {
                    Ok(c) => {
                        config = c;
                        broken_by = None;
                    }
                    Err(e) => {
                        broken_by.get_or_insert((arg, e));
                    }
                }
            }
            if let Some((arg, e)) = broken_by {
                return Err(ConfigError::Override {
                    arg: arg.clone(),
                    message: e.to_string(),
                });
            }
        }
        config.validate().map_err(|e| match e {
            ConfigError::Invalid { key, message } => {
                // The last override that sets the key (or a table holding it) is to blame.
                let set_key = |arg: &String| {
                    arg.split_once('=').is_some_and(|(k, _)| {
                        let k = k.trim();
                        key == k || key.strip_prefix(k).is_some_and(|r| r.starts_with('.'))
                    })
                };
                match sets.iter().rev().find(|a| set_key(a)) {
                    Some(arg) => ConfigError::Override {
                        arg: arg.clone(),
                        message: format!("key `{key}`: {message}"),
                    },
                    None => ConfigError::InvalidIn {
                        origin: if sets.is_empty() {
                            origin.to_string()
                        } else {
                            format!("{origin} (with --set overrides)")
                        },
                        key,
                        message,
                    },
                }
            }
            other => other,
        })?;
        Ok(config)
    }

    /// Loads `path` (at most [`MAX_CONFIG_BYTES`]; the defaults when `None`), applies
    /// `--set a.b=v` overrides, validates.
    pub fn load(path: Option<&Path>, sets: &[String]) -> Result<Config, ConfigError> {
        match path {
            Some(p) => {
                let read = |cause| ConfigError::Read {
                    path: p.to_path_buf(),
                    cause,
                };
                let len = std::fs::metadata(p).map_err(read)?.len();
                if len > MAX_CONFIG_BYTES {
                    return Err(ConfigError::Parse {
                        path: p.display().to_string(),
                        message: format!(
                            "{len} bytes: a configuration file is at most {MAX_CONFIG_BYTES} bytes"
                        ),
                    });
                }
                let bytes = std::fs::read(p).map_err(read)?;
                let text = String::from_utf8(bytes).map_err(|e| ConfigError::Parse {
                    path: p.display().to_string(),
                    message: format!("not UTF-8 at byte {}", e.utf8_error().valid_up_to()),
                })?;
                Self::from_toml_str(&text, &p.display().to_string(), sets)
            }
            None => Self::from_toml_str("", "<defaults>", sets),
        }
    }

    /// The configuration as TOML (what a run records next to its outputs).
    pub fn to_toml_string(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# cannot serialise config: {e}"))
    }

    /// Range checks that serde cannot express: every section's own checks (each error names the
    /// key), then the bounds of values that size memory or time.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.scenario.validate()?;
        self.radio.validate()?;
        self.map.validate()?;
        self.cache.validate()?;
        self.env.validate(&self.cache)?;
        self.pairs.validate(&self.env)?;
        self.planner.validate(&self.env)?;
        self.ppo.validate(&self.env)?;
        self.train.validate(&self.ppo)?;
        self.distributed.validate()?;
        self.validate_bounds()
    }

    /// Upper bounds on every value that sizes memory or time: a value that passes
    /// validation never panics a conversion (`Duration`, an allocation size) later. The bounds
    /// are far above any sensible run; each error names the key and the bound. The sections'
    /// own bounds, then those that involve several sections.
    fn validate_bounds(&self) -> Result<(), ConfigError> {
        self.distributed.validate_bounds()?;
        let t = &self.train;
        at_most("train.num_steps", t.num_steps as u64, 65_536)?;
        if t.num_envs * t.num_steps > 1 << 22 {
            return Err(ConfigError::Invalid {
                key: "train.num_steps".into(),
                message: format!(
                    "num_envs × num_steps = {} samples per batch, at most {}",
                    t.num_envs * t.num_steps,
                    1 << 22
                ),
            });
        }
        at_most("train.pool_size", t.pool_size as u64, 1_000_000)?;
        at_most("train.eval_pairs", t.eval_pairs as u64, 100_000)?;
        at_most(
            "train.total_timesteps",
            t.total_timesteps,
            1_000_000_000_000,
        )?;
        at_most(
            "pairs.eval_per_bin",
            self.pairs.eval_per_bin as u64,
            100_000,
        )?;
        at_most(
            "pairs.eval_bins_m",
            self.pairs.eval_bins_m.len() as u64,
            1_000,
        )?;
        if self.pairs.eval_bins_m.len() * self.pairs.eval_per_bin > 100_000 {
            return Err(ConfigError::Invalid {
                key: "pairs.eval_per_bin".into(),
                message: format!(
                    "{} bins × {} pairs: at most 100000 held-out pairs",
                    self.pairs.eval_bins_m.len(),
                    self.pairs.eval_per_bin
                ),
            });
        }
        at_most("map.altitudes_m", self.map.altitudes_m.len() as u64, 64)?;
        at_most(
            "radio.antenna.boresights_deg",
            self.radio.antenna.boresights_deg.len() as u64,
            16,
        )?;
        at_most("ppo.site_hidden", self.ppo.site_hidden.len() as u64, 16)?;
        // The observation holds 10 features per site; the paper has 30 sites.
        at_most("scenario.n_sites", self.scenario.n_sites as u64, 1_024)?;
        at_most(
            "scenario.procedural.n_sites",
            self.scenario.procedural.n_sites as u64,
            1_024,
        )?;
        self.ppo.validate_bounds()?;
        self.radio.validate_bounds()?;
        let sc = &self.scenario;
        // Search grids of 5 m around each site: these radii size their work.
        within(
            "scenario.roof_search_m",
            sc.roof_search_m,
            0.0,
            1_000.0,
            "m",
        )?;
        within(
            "scenario.macro_radius_m",
            sc.macro_radius_m,
            0.0,
            2_000.0,
            "m",
        )?;
        within(
            "scenario.pole_height_m",
            sc.pole_height_m,
            0.0,
            1_000.0,
            "m",
        )?;
        within("scenario.roof_mast_m", sc.roof_mast_m, -100.0, 100.0, "m")?;
        let pc = &sc.procedural;
        within("scenario.procedural.size_m", pc.size_m, 0.0, 20_000.0, "m")?;
        within(
            "scenario.procedural.street_pitch_m",
            pc.street_pitch_m,
            5.0,
            10_000.0,
            "m",
        )?;
        within(
            "scenario.procedural.avenue_spacing_m",
            pc.avenue_spacing_m,
            5.0,
            10_000.0,
            "m",
        )?;
        // The flight area: at most ≈ 50 km across (a city, not a country).
        within(
            "scenario.area.lon_max_deg",
            sc.area.lon_max_deg - sc.area.lon_min_deg,
            0.0,
            0.5,
            "degrees east of lon_min_deg",
        )?;
        within(
            "scenario.area.lat_max_deg",
            sc.area.lat_max_deg - sc.area.lat_min_deg,
            0.0,
            0.5,
            "degrees north of lat_min_deg",
        )?;
        within("planner.voxel_m", self.planner.voxel_m, 0.5, 1_000.0, "m")?;
        let e = &self.env;
        within("env.z_max_m", e.z_max_m, 0.0, 10_000.0, "m")?;
        within("env.speed_mps", e.speed_mps, 0.0, 1_000.0, "m/s")?;
        at_most("env.action_repeat", u64::from(e.action_repeat), 1_000)?;
        within("pairs.max_m", self.pairs.max_m, 0.0, 100_000.0, "m")?;
        let c = &self.cache;
        within("cache.horizontal_m", c.horizontal_m, 0.5, 1_000.0, "m")?;
        within("cache.z_max_m", c.z_max_m, 0.0, 10_000.0, "m")?;
        within("cache.vertical_m", c.vertical_m, 0.5, 1_000.0, "m")?;
        within(
            "env.time_limit_factor",
            self.env.time_limit_factor,
            0.0,
            1_000.0,
            "",
        )?;
        Ok(())
    }
}

/// Applies one `a.b.c=value` override to a TOML table. The value is parsed as TOML (numbers,
/// booleans, arrays, quoted strings); anything that does not parse is taken as a bare string.
fn apply_override(root: &mut toml::Table, arg: &str) -> Result<(), ConfigError> {
    let err = |message: String| ConfigError::Override {
        arg: arg.to_string(),
        message,
    };
    let (key, raw) = arg
        .split_once('=')
        .ok_or_else(|| err("expected KEY=VALUE, e.g. map.resolution_m=10".into()))?;
    let key = key.trim();
    if key.is_empty() || key.split('.').any(|p| p.is_empty()) {
        return Err(err(format!("malformed key {key:?}")));
    }
    let raw = raw.trim();
    let value: toml::Value = match toml::from_str::<toml::Table>(&format!("v = {raw}")) {
        Ok(mut t) => t
            .remove("v")
            .unwrap_or(toml::Value::String(raw.to_string())),
        Err(_) => toml::Value::String(raw.to_string()),
    };
    let parts: Vec<&str> = key.split('.').collect();
    let (last, parents) = parts
        .split_last()
        .ok_or_else(|| err(format!("malformed key {key:?}")))?;
    let mut table = root;
    for (i, p) in parents.iter().enumerate() {
        let entry = table
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        table = entry.as_table_mut().ok_or_else(|| {
            err(format!(
                "`{}` is a value, not a section",
                parts[..=i].join(".")
            ))
        })?;
    }
    table.insert(last.to_string(), value);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensor_scales_map_the_range_onto_unit_interval() {
        for scale in [SensorScale::Linear, SensorScale::Log] {
            assert_eq!(scale.scale(0.0, 50.0), 0.0);
            assert!((scale.scale(50.0, 50.0) - 1.0).abs() < 1e-12);
            assert!(
                (scale.scale(80.0, 50.0) - 1.0).abs() < 1e-12,
                "beyond range = free"
            );
            assert!(scale.scale(2.0, 50.0) < scale.scale(3.0, 50.0), "monotone");
        }
        assert!((SensorScale::Linear.scale(5.0, 50.0) - 0.1).abs() < 1e-12);
        // The log scale spends a quarter of [0, 1] on the first 2 m (linear: 4 %).
        let log2 = SensorScale::Log.scale(2.0, 50.0);
        assert!((log2 - 3f64.ln() / 51f64.ln()).abs() < 1e-12 && log2 > 0.25);
    }

    #[test]
    fn defaults_are_the_papers() {
        let c = Config::load(None, &[]).expect("defaults valid");
        assert_eq!(c.radio.fc_ghz, 2.0);
        assert_eq!(c.radio.tx_power_dbm, 15.2);
        assert_eq!(c.radio.antenna.boresights_deg, vec![30.0, 150.0, 270.0]);
        assert_eq!(c.scenario.n_sites, 30);
        assert_eq!(c.map.altitudes_m, vec![30.0, 60.0, 90.0, 120.0]);
    }

    #[test]
    fn unknown_key_is_rejected_and_named() {
        let e = Config::from_toml_str("[radio]\nfc_gz = 3.0\n", "x.toml", &[]).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("fc_gz"), "{msg}");
        assert!(msg.contains("x.toml"), "{msg}");
    }

    #[test]
    fn set_overrides_nested_keys_with_typed_values() {
        let sets = vec![
            "radio.fc_ghz=3.5".to_string(),
            "map.altitudes_m=[50, 100]".to_string(),
            "scenario.city=procedural".to_string(),
            "radio.antenna.gain_floor_dbi=-30".to_string(),
        ];
        let c = Config::load(None, &sets).expect("valid");
        assert_eq!(c.radio.fc_ghz, 3.5);
        assert_eq!(c.map.altitudes_m, vec![50.0, 100.0]);
        assert_eq!(c.scenario.city, CityKind::Procedural);
        assert_eq!(c.radio.antenna.gain_floor_dbi, Some(-30.0));
    }

    #[test]
    fn out_of_range_value_names_the_key() {
        let e = Config::load(None, &["radio.fc_ghz=-1".to_string()]).unwrap_err();
        assert!(e.to_string().contains("radio.fc_ghz"), "{e}");
        let e = Config::load(None, &["radio.a3.offset_db=20".to_string()]).unwrap_err();
        assert!(e.to_string().contains("radio.a3.offset_db"), "{e}");
        let e = Config::load(None, &["map.resolution_m".to_string()]).unwrap_err();
        assert!(e.to_string().contains("KEY=VALUE"), "{e}");
        let e = Config::load(None, &["radio.fc_ghz.x=1".to_string()]).unwrap_err();
        assert!(e.to_string().contains("radio.fc_ghz"), "{e}");
    }

    #[test]
    fn training_grows_the_sphere_once_and_checks_its_room() {
        let c = Config::load(None, &["env.training_margin_m=1".to_string()]).expect("valid");
        let t = c.training();
        assert_eq!(t.env.uav_radius_m, c.env.uav_radius_m + 1.0);
        assert_eq!(t.env.training_margin_m, 0.0);
        assert_eq!(t.training(), t, "applied once");
        // Everything else is the same configuration.
        let mut back = t.clone();
        back.env.uav_radius_m = c.env.uav_radius_m;
        back.env.training_margin_m = c.env.training_margin_m;
        assert_eq!(back, c);
        // The grown sphere must fit at every endpoint (5 m of clearance by default).
        let e = Config::load(None, &["env.training_margin_m=4.6".to_string()]).unwrap_err();
        assert!(e.to_string().contains("pairs.endpoint_clearance_m"), "{e}");
        let e = Config::load(None, &["env.training_margin_m=-1".to_string()]).unwrap_err();
        assert!(e.to_string().contains("env.training_margin_m"), "{e}");
    }

    #[test]
    fn round_trips_through_toml() {
        let c = Config::load(None, &["radio.a3.l3_filter_k=4".to_string()]).expect("valid");
        let text = c.to_toml_string();
        let back = Config::from_toml_str(&text, "roundtrip", &[]).expect("valid");
        assert_eq!(c, back);
    }

    /// The test split (`pairs.test_seed`, `pairs.test_file`) is not in the environment
    /// fingerprint, which hashes `[pairs]` as it did before the split existed; the validation
    /// seed is; `--set pairs.test_seed=…` reaches the configuration.
    #[test]
    fn the_test_split_stays_out_of_the_fingerprint() {
        let c = Config::default();
        assert_eq!(
            c.pairs.fingerprint_json(),
            r#"{"min_m":200.0,"max_m":800.0,"endpoint_clearance_m":5.0,"eval_bins_m":[200.0,300.0,400.0,500.0,600.0,700.0,800.0],"bin_tolerance":0.05,"eval_per_bin":50,"eval_seed":2024,"eval_file":""}"#
        );
        let t = Config::load(
            None,
            &[
                "pairs.test_seed=7".to_string(),
                "pairs.test_file=\"elsewhere.jsonl\"".to_string(),
            ],
        )
        .expect("valid");
        assert_eq!(
            (t.pairs.test_seed, t.pairs.test_file.to_str()),
            (7, Some("elsewhere.jsonl"))
        );
        assert_eq!(t.env_fingerprint(1), c.env_fingerprint(1));
        let v = Config::load(None, &["pairs.eval_seed=7".to_string()]).expect("valid");
        assert_ne!(v.env_fingerprint(1), c.env_fingerprint(1));
        let e = Config::load(
            None,
            &["pairs.test_file=\"out/pairs/{city}/eval_pairs.jsonl\"".to_string()],
        )
        .unwrap_err();
        assert!(e.to_string().contains("pairs.test_file"), "{e}");
    }
}
