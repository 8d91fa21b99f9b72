//! Checkpoints and exported policies (issue 4).
//!
//! A checkpoint holds everything a run needs to continue its learning curve: the model (burn
//! record, parameter ids kept so the optimiser state matches), the Adam state, the normalisers
//! and per-stream return accumulators, the update/step/version counters, the run seed (all
//! later randomness is derived from seed and update index) and the configuration. It is written
//! atomically (temporary file, then rename): a crash mid-write leaves the previous checkpoint.
//!
//! An exported policy ([`PolicyWeights`]: both networks, log-std, normalisers) is what actors and
//! `dupac fly` load; it needs no burn.

use burn::module::Module;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device};
use dupac_common::codec::{self, CodecError};
use dupac_common::policy::PolicyWeights;
use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::model::ActorCritic;

const CHECKPOINT_MAGIC: &[u8; 8] = b"DUPACCKP";
/// Format 3 records the policy's observation ([`PolicyWeights::observation`]), format 4 with
/// the path guide's keys, format 5 with the guide's clearance, format 6 with the source of the
/// sites' line of sight; formats 2 to 5 are still read ([`legacy`]).
const CHECKPOINT_VERSION: u32 = 6;
const POLICY_MAGIC: &[u8; 8] = b"DUPACPOL";
const POLICY_VERSION: u32 = 6;
/// 2026-11-24 to 2026-11-26, read without the observation.
const FORMAT_2: u32 = 2;
/// 2026-11-26, the observation without the path guide.
const FORMAT_3: u32 = 3;
/// 2026-11-26, the path guide without its clearance (it was `planner.clearance_m`).
const FORMAT_4: u32 = 4;
/// The guide with its clearance, the sites' line of sight always cast as rays (no `site_los`).
const FORMAT_5: u32 = 5;
/// Largest checkpoint or policy file read (bytes).
pub const MAX_FILE_BYTES: usize = 512 << 20;

/// Errors of checkpoint and policy files.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error(transparent)]
    Codec(#[from] CodecError),
    #[error("{path}: model record: {message}")]
    Record { path: String, message: String },
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
}

/// Counters and state besides the tensors.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CheckpointMeta {
    pub seed: u64,
    /// PPO updates done.
    pub update: u64,
    /// Environment steps done.
    pub global_step: u64,
    /// Episodes finished.
    pub episodes: u64,
    /// Wall-clock seconds of training so far (across resumes).
    pub train_seconds: f64,
    /// The resolved configuration of the run (TOML).
    pub config_toml: String,
    /// The exported policy at this point (includes normalisers and version).
    pub policy: PolicyWeights,
    /// Discounted-return accumulator per environment stream (reward scaling).
    pub return_acc: Vec<f64>,
}

#[derive(Serialize, Deserialize)]
struct CheckpointFile {
    meta: CheckpointMeta,
    model: Vec<u8>,
    optim: Vec<u8>,
}

/// Files of earlier formats (bincode is not self-describing, so each old layout is spelled out
/// once here and converted): format 2 without [`PolicyWeights::observation`], format 3 with the
/// observation as it was before the path guide (`env.observation.path_guide`,
/// `path_lookahead_m`, `path_guide_lambda`), format 4 before the guide's own clearance
/// (`path_guide_clearance_m`; it used `planner.clearance_m`, which 0 says), format 5 before
/// `site_los` (rays). The tests write old files with these types too.
mod legacy {
    use dupac_common::config::{NearestObstacle, ObservationConfig, SensorScale, SiteLos};
    use dupac_common::normalize::{ObsNormalizer, RewardScaler};
    use dupac_common::policy::{Mlp, PolicyWeights, SiteHead};
    use serde::Deserialize;

    /// Keys of `[env.observation]` added after file format 3, with what their absence means: what
    /// a run written before them did (the guide off; its clearance `planner.clearance_m`, 0; the
    /// look-ahead 30 m, unused with the guide off but compared on resume). Not today's defaults,
    /// which turn the guide on.
    fn added_after_format_3() -> [(&'static str, toml::Value); 5] {
        [
            ("site_los", toml::Value::String("ray".into())),
            ("path_guide", toml::Value::Boolean(false)),
            // 30 m, the look-ahead of every file that recorded it until 2026-11-27.
            ("path_lookahead_m", toml::Value::Float(30.0)),
            ("path_guide_lambda", toml::Value::Float(0.0)),
            ("path_guide_clearance_m", toml::Value::Float(0.0)),
        ]
    }

    /// Today's observation with the guide as a file of format 3 or older meant it: off (and the
    /// look-ahead of those days, 30 m), the line of sight from rays.
    fn guide_off() -> ObservationConfig {
        ObservationConfig {
            site_los: SiteLos::Ray,
            path_guide: false,
            path_guide_lambda: 0.0,
            path_guide_clearance_m: 0.0,
            path_lookahead_m: 30.0,
            ..ObservationConfig::default()
        }
    }

    /// `env.observation` as format 3 recorded it.
    #[derive(Deserialize)]
    #[cfg_attr(test, derive(serde::Serialize))]
    pub(super) struct ObservationV3 {
        pub(super) goal: bool,
        pub(super) sensor_fan: bool,
        pub(super) rsrp_all: bool,
        pub(super) rsrp_serving: bool,
        pub(super) sensor_range_m: f64,
        pub(super) sensor_scale: SensorScale,
        pub(super) nearest_obstacle: NearestObstacle,
        pub(super) geofence: bool,
        pub(super) goal_scale_m: f64,
        pub(super) goal_direction: bool,
        pub(super) rsrp_centre_dbm: f64,
        pub(super) rsrp_scale_db: f64,
        pub(super) site_features: bool,
        pub(super) site_trend: bool,
        pub(super) site_ping_pong: bool,
    }

    impl ObservationV3 {
        pub(super) fn upgrade(self) -> ObservationConfig {
            ObservationConfig {
                goal: self.goal,
                sensor_fan: self.sensor_fan,
                rsrp_all: self.rsrp_all,
                rsrp_serving: self.rsrp_serving,
                sensor_range_m: self.sensor_range_m,
                sensor_scale: self.sensor_scale,
                nearest_obstacle: self.nearest_obstacle,
                geofence: self.geofence,
                goal_scale_m: self.goal_scale_m,
                goal_direction: self.goal_direction,
                rsrp_centre_dbm: self.rsrp_centre_dbm,
                rsrp_scale_db: self.rsrp_scale_db,
                site_features: self.site_features,
                site_trend: self.site_trend,
                site_ping_pong: self.site_ping_pong,
                ..guide_off()
            }
        }
    }

    /// `env.observation` as format 4 recorded it: format 3's and the guide's first three keys.
    #[derive(Deserialize)]
    #[cfg_attr(test, derive(serde::Serialize))]
    pub(super) struct ObservationV4 {
        pub(super) v3: ObservationV3,
        pub(super) path_guide: bool,
        pub(super) path_lookahead_m: f64,
        pub(super) path_guide_lambda: f64,
    }

    impl ObservationV4 {
        /// The guide's path planned with `planner.clearance_m`, as format 4's was (0).
        pub(super) fn upgrade(self) -> ObservationConfig {
            ObservationConfig {
                path_guide: self.path_guide,
                path_lookahead_m: self.path_lookahead_m,
                path_guide_lambda: self.path_guide_lambda,
                path_guide_clearance_m: 0.0,
                ..self.v3.upgrade()
            }
        }
    }

    /// `env.observation` as format 5 recorded it: format 4's and the guide's clearance.
    #[derive(Deserialize)]
    #[cfg_attr(test, derive(serde::Serialize))]
    pub(super) struct ObservationV5 {
        pub(super) v4: ObservationV4,
        pub(super) path_guide_clearance_m: f64,
    }

    impl ObservationV5 {
        /// The sites' line of sight from rays, as format 5's was.
        pub(super) fn upgrade(self) -> ObservationConfig {
            ObservationConfig {
                path_guide_clearance_m: self.path_guide_clearance_m,
                ..self.v4.upgrade()
            }
        }
    }

    /// The policy of formats 2 and 3: `O` = `()` (format 2, none recorded) or
    /// `Option<ObservationV3>` (format 3).
    #[derive(Deserialize)]
    #[cfg_attr(test, derive(serde::Serialize))]
    pub(super) struct PolicyWeightsOld<O> {
        pub(super) version: u64,
        pub(super) obs_version: u32,
        pub(super) obs_dim: usize,
        pub(super) n_sites: usize,
        pub(super) actor: Mlp,
        pub(super) critic: Mlp,
        pub(super) site_head: Option<SiteHead>,
        pub(super) log_std: [f32; dupac_common::policy::MOVE_DIM],
        pub(super) obs_norm: ObsNormalizer,
        pub(super) reward_scaler: RewardScaler,
        /// `()` encodes to nothing: format 2 had no such field.
        pub(super) observation: O,
    }

    pub(super) type PolicyWeightsV2 = PolicyWeightsOld<()>;
    pub(super) type PolicyWeightsV3 = PolicyWeightsOld<Option<ObservationV3>>;
    pub(super) type PolicyWeightsV4 = PolicyWeightsOld<Option<ObservationV4>>;
    pub(super) type PolicyWeightsV5 = PolicyWeightsOld<Option<ObservationV5>>;

    impl<O> PolicyWeightsOld<O> {
        /// The policy, with `observation`.
        pub(super) fn with(self, observation: Option<ObservationConfig>) -> PolicyWeights {
            PolicyWeights {
                version: self.version,
                obs_version: self.obs_version,
                obs_dim: self.obs_dim,
                n_sites: self.n_sites,
                actor: self.actor,
                critic: self.critic,
                site_head: self.site_head,
                log_std: self.log_std,
                obs_norm: self.obs_norm,
                reward_scaler: self.reward_scaler,
                observation,
            }
        }
    }

    impl PolicyWeightsV3 {
        pub(super) fn upgrade(mut self) -> PolicyWeights {
            let o = self.observation.take().map(ObservationV3::upgrade);
            self.with(o)
        }
    }

    impl PolicyWeightsV4 {
        pub(super) fn upgrade(mut self) -> PolicyWeights {
            let o = self.observation.take().map(ObservationV4::upgrade);
            self.with(o)
        }
    }

    impl PolicyWeightsV5 {
        pub(super) fn upgrade(mut self) -> PolicyWeights {
            let o = self.observation.take().map(ObservationV5::upgrade);
            self.with(o)
        }
    }

    #[derive(Deserialize)]
    #[cfg_attr(test, derive(serde::Serialize))]
    pub(super) struct CheckpointMetaOld<P> {
        pub(super) seed: u64,
        pub(super) update: u64,
        pub(super) global_step: u64,
        pub(super) episodes: u64,
        pub(super) train_seconds: f64,
        pub(super) config_toml: String,
        pub(super) policy: P,
        pub(super) return_acc: Vec<f64>,
    }

    #[derive(Deserialize)]
    #[cfg_attr(test, derive(serde::Serialize))]
    pub(super) struct CheckpointFileOld<P> {
        pub(super) meta: CheckpointMetaOld<P>,
        pub(super) model: Vec<u8>,
        pub(super) optim: Vec<u8>,
    }

    #[cfg(test)]
    pub(super) type CheckpointMetaV2 = CheckpointMetaOld<PolicyWeightsV2>;
    pub(super) type CheckpointFileV2 = CheckpointFileOld<PolicyWeightsV2>;
    pub(super) type CheckpointFileV3 = CheckpointFileOld<PolicyWeightsV3>;
    pub(super) type CheckpointFileV4 = CheckpointFileOld<PolicyWeightsV4>;
    pub(super) type CheckpointFileV5 = CheckpointFileOld<PolicyWeightsV5>;

    /// The observation a run's configuration (TOML) gives, when that is certain: every key of
    /// today's `[env.observation]` written in it (a key added since — a feature that did not
    /// exist then — would otherwise take today's default), those added after format 3 apart
    /// (their absence means what it did then: [`added_after_format_3`]), and the values valid.
    /// `None` else.
    pub(super) fn observation_of(config_toml: &str) -> Option<ObservationConfig> {
        let table: toml::Table = toml::from_str(config_toml).ok()?;
        let mut written = table.get("env")?.get("observation")?.as_table()?.clone();
        let added = added_after_format_3();
        let today = toml::Value::try_from(ObservationConfig::default()).ok()?;
        if !today
            .as_table()?
            .keys()
            .filter(|k| !added.iter().any(|(a, _)| a == k))
            .all(|k| written.contains_key(k))
        {
            return None;
        }
        for (k, then) in added {
            written.entry(k).or_insert(then);
        }
        let o: ObservationConfig = written.try_into().ok()?;
        o.validate().ok()?;
        Some(o)
    }

    impl<P> CheckpointFileOld<P> {
        /// The checkpoint with the policy `upgrade` gives from the file's policy and its
        /// configuration.
        pub(super) fn upgrade(
            self,
            upgrade: impl FnOnce(P, &str) -> PolicyWeights,
        ) -> super::CheckpointFile {
            let m = self.meta;
            let policy = upgrade(m.policy, &m.config_toml);
            super::CheckpointFile {
                meta: super::CheckpointMeta {
                    seed: m.seed,
                    update: m.update,
                    global_step: m.global_step,
                    episodes: m.episodes,
                    train_seconds: m.train_seconds,
                    config_toml: m.config_toml,
                    policy,
                    return_acc: m.return_acc,
                },
                model: self.model,
                optim: self.optim,
            }
        }
    }

    /// A format-2 checkpoint's policy with the observation of the run's own configuration when
    /// it is certain ([`observation_of`]); none recorded otherwise (checked by length).
    pub(super) fn upgrade_v2(p: PolicyWeightsV2, config_toml: &str) -> PolicyWeights {
        let mut policy = p.with(observation_of(config_toml));
        if policy.observation.is_some() && policy.validate().is_err() {
            // The configuration disagrees with the weights (a resume that changed the
            // observation at the same length): not certain either.
            policy.observation = None;
        }
        policy
    }
}

/// Decodes a checkpoint file of this format or of formats 2 to 5.
fn decode_checkpoint(bytes: &[u8], what: &str) -> Result<CheckpointFile, CheckpointError> {
    match codec::decode(
        CHECKPOINT_MAGIC,
        CHECKPOINT_VERSION,
        bytes,
        MAX_FILE_BYTES,
        what,
    ) {
        Err(CodecError::Version { got: FORMAT_2, .. }) => {
            codec::decode::<legacy::CheckpointFileV2>(
                CHECKPOINT_MAGIC,
                FORMAT_2,
                bytes,
                MAX_FILE_BYTES,
                what,
            )
            .map(|c| c.upgrade(legacy::upgrade_v2))
            .map_err(CheckpointError::from)
        }
        Err(CodecError::Version { got: FORMAT_3, .. }) => {
            codec::decode::<legacy::CheckpointFileV3>(
                CHECKPOINT_MAGIC,
                FORMAT_3,
                bytes,
                MAX_FILE_BYTES,
                what,
            )
            .map(|c| c.upgrade(|p, _| p.upgrade()))
            .map_err(CheckpointError::from)
        }
        Err(CodecError::Version { got: FORMAT_4, .. }) => {
            codec::decode::<legacy::CheckpointFileV4>(
                CHECKPOINT_MAGIC,
                FORMAT_4,
                bytes,
                MAX_FILE_BYTES,
                what,
            )
            .map(|c| c.upgrade(|p, _| p.upgrade()))
            .map_err(CheckpointError::from)
        }
        Err(CodecError::Version { got: FORMAT_5, .. }) => {
            codec::decode::<legacy::CheckpointFileV5>(
                CHECKPOINT_MAGIC,
                FORMAT_5,
                bytes,
                MAX_FILE_BYTES,
                what,
            )
            .map(|c| c.upgrade(|p, _| p.upgrade()))
            .map_err(CheckpointError::from)
        }
        r => r.map_err(older_format),
    }
}

/// Writes a checkpoint of `model` and `optim` atomically to `path`.
pub fn save_checkpoint(
    path: &Path,
    meta: &CheckpointMeta,
    model: &ActorCritic,
    optim: &burn::optim::ModuleOptimizer,
) -> Result<(), CheckpointError> {
    let rec = |message: String| CheckpointError::Record {
        path: path.display().to_string(),
        message,
    };
    let model_bytes = model
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| rec(format!("{e:?}")))?;
    let optim_bytes = optim.into_bytes().map_err(|e| rec(format!("{e:?}")))?;
    let file = CheckpointFile {
        meta: meta.clone(),
        model: model_bytes.to_vec(),
        optim: optim_bytes.to_vec(),
    };
    let bytes = codec::encode(CHECKPOINT_MAGIC, CHECKPOINT_VERSION, &file, "checkpoint")?;
    codec::write_atomic(path, &bytes)?;
    Ok(())
}

/// A loaded checkpoint: metadata plus the model and optimiser bytes, applied with
/// [`LoadedCheckpoint::restore`].
pub struct LoadedCheckpoint {
    pub meta: CheckpointMeta,
    model: Vec<u8>,
    optim: Vec<u8>,
    path: String,
}

/// Reads and validates a checkpoint file.
pub fn load_checkpoint(path: &Path) -> Result<LoadedCheckpoint, CheckpointError> {
    let what = path.display().to_string();
    let bytes = codec::read_limited(path, MAX_FILE_BYTES)?;
    let f = decode_checkpoint(&bytes, &what)?;
    f.meta
        .policy
        .validate()
        .map_err(|message| CheckpointError::Invalid {
            path: what.clone(),
            message,
        })?;
    Ok(LoadedCheckpoint {
        meta: f.meta,
        model: f.model,
        optim: f.optim,
        path: what,
    })
}

impl LoadedCheckpoint {
    /// The model (on `device`, with the saved parameter ids) and the optimiser with its state.
    pub fn restore(
        &self,
        device: &Device,
        optim: burn::optim::ModuleOptimizer,
    ) -> Result<(ActorCritic, burn::optim::ModuleOptimizer), CheckpointError> {
        let rec = |message: String| CheckpointError::Record {
            path: self.path.clone(),
            message,
        };
        let p = &self.meta.policy;
        let skeleton = ActorCritic::from_policy(p, device);
        let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(self.model.clone()))
            .map_err(|e| rec(format!("{e:?}")))?;
        let model = skeleton
            .try_load_record(record)
            .map_err(|e| rec(format!("{e:?}")))?;
        let optim = optim
            .from_bytes(Bytes::from_bytes_vec(self.optim.clone()))
            .map_err(|e| rec(format!("optimiser: {e:?}")))?;
        Ok((model, optim))
    }
}

/// Writes an exported policy atomically.
pub fn save_policy(path: &Path, policy: &PolicyWeights) -> Result<(), CheckpointError> {
    let bytes = codec::encode(POLICY_MAGIC, POLICY_VERSION, policy, "policy")?;
    codec::write_atomic(path, &bytes)?;
    Ok(())
}

/// An older format of policy or checkpoint file, named in words: format 1 carried observation
/// layouts 1–2 and slot site logits only (format 2 is read: [`legacy`]).
fn older_format(e: CodecError) -> CheckpointError {
    match e {
        CodecError::Version { what, got, want } if got < want => CheckpointError::Invalid {
            path: what,
            message: format!(
                "written by an older DUPAC (file format {got}, observation layout version ≤ 2); this build reads format {want} (observation layout version {}, the equivariant site head of issue 15): retrain with `dupac train`",
                dupac_common::obs::OBS_VERSION
            ),
        },
        e => e.into(),
    }
}

/// Reads a policy: an exported policy file, or the policy inside a checkpoint.
pub fn load_policy(path: &Path) -> Result<PolicyWeights, CheckpointError> {
    let what = path.display().to_string();
    let bytes = codec::read_limited(path, MAX_FILE_BYTES)?;
    let policy: PolicyWeights = if bytes.starts_with(CHECKPOINT_MAGIC) {
        decode_checkpoint(&bytes, &what)?.meta.policy
    } else {
        match codec::decode(POLICY_MAGIC, POLICY_VERSION, &bytes, MAX_FILE_BYTES, &what) {
            Err(CodecError::Version { got: FORMAT_2, .. }) => {
                codec::decode::<legacy::PolicyWeightsV2>(
                    POLICY_MAGIC,
                    FORMAT_2,
                    &bytes,
                    MAX_FILE_BYTES,
                    &what,
                )?
                .with(None)
            }
            Err(CodecError::Version { got: FORMAT_3, .. }) => {
                codec::decode::<legacy::PolicyWeightsV3>(
                    POLICY_MAGIC,
                    FORMAT_3,
                    &bytes,
                    MAX_FILE_BYTES,
                    &what,
                )?
                .upgrade()
            }
            Err(CodecError::Version { got: FORMAT_4, .. }) => {
                codec::decode::<legacy::PolicyWeightsV4>(
                    POLICY_MAGIC,
                    FORMAT_4,
                    &bytes,
                    MAX_FILE_BYTES,
                    &what,
                )?
                .upgrade()
            }
            Err(CodecError::Version { got: FORMAT_5, .. }) => {
                codec::decode::<legacy::PolicyWeightsV5>(
                    POLICY_MAGIC,
                    FORMAT_5,
                    &bytes,
                    MAX_FILE_BYTES,
                    &what,
                )?
                .upgrade()
            }
            r => r.map_err(older_format)?,
        }
    };
    policy
        .validate()
        .map_err(|message| CheckpointError::Invalid {
            path: what,
            message,
        })?;
    Ok(policy)
}

#[cfg(test)]
mod tests {
    use super::legacy::{
        CheckpointFileV2, CheckpointMetaV2, ObservationV3, ObservationV4, ObservationV5,
        PolicyWeightsOld, PolicyWeightsV2,
    };
    use super::*;
    use crate::learner::Learner;
    use dupac_common::config::{Config, SiteLos};
    use dupac_common::obs::ObsLayout;

    fn learner(cfg: &Config) -> Learner {
        let n = 4;
        let obs_dim = ObsLayout::new(&cfg.env.observation, n).len();
        Learner::new(cfg.clone(), obs_dim, n, &Device::flex())
    }

    fn small() -> Config {
        let mut cfg = Config::default();
        cfg.ppo.hidden = vec![8, 8];
        cfg.ppo.site_hidden = vec![8];
        cfg.ppo.site_embed = 4;
        cfg
    }

    /// `p` as file format 2 wrote it (without the observation).
    fn v2(p: &PolicyWeights) -> PolicyWeightsV2 {
        let p = p.clone();
        PolicyWeightsV2 {
            version: p.version,
            obs_version: p.obs_version,
            obs_dim: p.obs_dim,
            n_sites: p.n_sites,
            actor: p.actor,
            critic: p.critic,
            site_head: p.site_head,
            log_std: p.log_std,
            obs_norm: p.obs_norm,
            reward_scaler: p.reward_scaler,
            observation: (),
        }
    }

    /// `p` as file format 3 wrote it (the observation without the path guide's keys).
    fn v3(p: &PolicyWeights) -> PolicyWeightsOld<Option<ObservationV3>> {
        let o = p.observation.clone().map(|o| ObservationV3 {
            goal: o.goal,
            sensor_fan: o.sensor_fan,
            rsrp_all: o.rsrp_all,
            rsrp_serving: o.rsrp_serving,
            sensor_range_m: o.sensor_range_m,
            sensor_scale: o.sensor_scale,
            nearest_obstacle: o.nearest_obstacle,
            geofence: o.geofence,
            goal_scale_m: o.goal_scale_m,
            goal_direction: o.goal_direction,
            rsrp_centre_dbm: o.rsrp_centre_dbm,
            rsrp_scale_db: o.rsrp_scale_db,
            site_features: o.site_features,
            site_trend: o.site_trend,
            site_ping_pong: o.site_ping_pong,
        });
        let v2 = v2(p);
        PolicyWeightsOld {
            version: v2.version,
            obs_version: v2.obs_version,
            obs_dim: v2.obs_dim,
            n_sites: v2.n_sites,
            actor: v2.actor,
            critic: v2.critic,
            site_head: v2.site_head,
            log_std: v2.log_std,
            obs_norm: v2.obs_norm,
            reward_scaler: v2.reward_scaler,
            observation: o,
        }
    }

    /// `p` as file format 4 wrote it (the path guide without its clearance).
    fn v4(p: &PolicyWeights) -> PolicyWeightsOld<Option<ObservationV4>> {
        let o = p.observation.clone();
        let v3 = v3(p);
        PolicyWeightsOld {
            version: v3.version,
            obs_version: v3.obs_version,
            obs_dim: v3.obs_dim,
            n_sites: v3.n_sites,
            actor: v3.actor,
            critic: v3.critic,
            site_head: v3.site_head,
            log_std: v3.log_std,
            obs_norm: v3.obs_norm,
            reward_scaler: v3.reward_scaler,
            observation: v3.observation.zip(o).map(|(v3, o)| ObservationV4 {
                v3,
                path_guide: o.path_guide,
                path_lookahead_m: o.path_lookahead_m,
                path_guide_lambda: o.path_guide_lambda,
            }),
        }
    }

    /// `p` as file format 5 wrote it (the sites' line of sight from rays, not recorded).
    fn v5(p: &PolicyWeights) -> PolicyWeightsOld<Option<ObservationV5>> {
        let o = p.observation.clone();
        let v4 = v4(p);
        PolicyWeightsOld {
            version: v4.version,
            obs_version: v4.obs_version,
            obs_dim: v4.obs_dim,
            n_sites: v4.n_sites,
            actor: v4.actor,
            critic: v4.critic,
            site_head: v4.site_head,
            log_std: v4.log_std,
            obs_norm: v4.obs_norm,
            reward_scaler: v4.reward_scaler,
            observation: v4.observation.zip(o).map(|(v4, o)| ObservationV5 {
                v4,
                path_guide_clearance_m: o.path_guide_clearance_m,
            }),
        }
    }

    /// A format-2 checkpoint of `p` whose configuration is `config_toml`, loaded.
    fn load_v2_checkpoint(p: &PolicyWeights, config_toml: String) -> LoadedCheckpoint {
        let file = CheckpointFileV2 {
            meta: CheckpointMetaV2 {
                seed: 1,
                update: 2,
                global_step: 3,
                episodes: 4,
                train_seconds: 5.0,
                config_toml,
                policy: v2(p),
                return_acc: vec![0.5],
            },
            model: vec![1, 2],
            optim: vec![3],
        };
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("checkpoint.bin");
        let bytes = codec::encode(CHECKPOINT_MAGIC, FORMAT_2, &file, "checkpoint").expect("encode");
        std::fs::write(&path, bytes).expect("write");
        let ck = load_checkpoint(&path).expect("a format-2 checkpoint loads");
        assert_eq!(ck.meta.update, 2);
        assert_eq!(ck.meta.return_acc, vec![0.5]);
        assert_eq!(load_policy(&path).expect("its policy"), ck.meta.policy);
        ck
    }

    #[test]
    fn a_policy_records_its_observation_and_an_older_file_still_loads() {
        let mut cfg = small();
        // A layout of the same length as the default's, another feature at index 10.
        cfg.env.observation.site_ping_pong = false;
        cfg.env.reward.ping_pong_reward = 0.0;
        cfg.env.observation.site_trend = true;
        cfg.env.site_every_step = false;
        // Unguided, as a file of format 3 or older reads (the guide off, λ 0, clearance 0, the
        // look-ahead of those days, 30 m).
        cfg.env.observation.path_guide = false;
        cfg.env.observation.path_guide_lambda = 0.0;
        cfg.env.observation.path_guide_clearance_m = 0.0;
        cfg.env.observation.path_lookahead_m = 30.0;
        cfg.env.reward.progress = dupac_common::config::Progress::Straight;
        // …and with the line of sight from rays, as every file of format 5 or older reads.
        cfg.env.observation.site_los = SiteLos::Ray;
        cfg.validate().expect("valid");
        let p = learner(&cfg).policy();
        assert_eq!(p.observation.as_ref(), Some(&cfg.env.observation));
        // A record that disagrees with the site head's features is refused.
        let mut wrong = p.clone();
        if let Some(o) = wrong.observation.as_mut() {
            o.site_trend = false;
        }
        let e = wrong.validate().expect_err("10 recorded features, 11 read");
        assert!(
            e.contains("11 features per site") && e.contains("has 10"),
            "{e}"
        );
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("policy.bin");
        save_policy(&path, &p).expect("save");
        assert_eq!(load_policy(&path).expect("load"), p);

        // Format 2 (no observation recorded) loads, with none.
        let bytes = codec::encode(POLICY_MAGIC, FORMAT_2, &v2(&p), "policy").expect("encode");
        std::fs::write(&path, bytes).expect("write");
        let old = load_policy(&path).expect("a format-2 policy loads");
        assert_eq!(old.observation, None);
        // It predates the path guide: flown unguided under today's (guided) defaults.
        let flown = old.configure(&Config::default()).expect("configure");
        assert!(!flown.env.observation.path_guide);
        assert_eq!(flown.env.observation.site_los, SiteLos::Ray);
        assert_eq!(
            flown.env.reward.progress,
            dupac_common::config::Progress::Straight
        );
        // Nor charged for leaving a path it never had.
        let mut keeping = Config::default();
        keeping.env.reward.guide_deviation_weight = 0.2;
        let flown = old.configure(&keeping).expect("configure");
        assert!(!flown.env.needs_path());
        assert_eq!(
            PolicyWeights {
                observation: None,
                ..p.clone()
            },
            old
        );

        // Format 3 (the observation without the path guide) loads, with the guide off.
        let bytes = codec::encode(POLICY_MAGIC, FORMAT_3, &v3(&p), "policy").expect("encode");
        std::fs::write(&path, bytes).expect("write");
        let v3_policy = load_policy(&path).expect("a format-3 policy loads");
        assert_eq!(v3_policy, p);
        assert!(!v3_policy.observation.as_ref().is_some_and(|o| o.path_guide));
        // …and a format-3 checkpoint.
        let file = super::legacy::CheckpointFileOld {
            meta: super::legacy::CheckpointMetaOld {
                seed: 1,
                update: 2,
                global_step: 3,
                episodes: 4,
                train_seconds: 5.0,
                config_toml: String::new(),
                policy: v3(&p),
                return_acc: vec![0.5],
            },
            model: vec![1, 2],
            optim: vec![3],
        };
        let ck_path = dir.path().join("checkpoint.bin");
        let bytes = codec::encode(CHECKPOINT_MAGIC, FORMAT_3, &file, "checkpoint").expect("encode");
        std::fs::write(&ck_path, bytes).expect("write");
        let ck = load_checkpoint(&ck_path).expect("a format-3 checkpoint loads");
        assert_eq!(ck.meta.policy, p);
        assert_eq!(ck.meta.update, 2);

        // Format 4 (the guide without its clearance) loads, its guide planned with
        // `planner.clearance_m` (0) as it was — a guided policy too.
        let mut guided_cfg = small();
        guided_cfg.env.observation.path_guide_clearance_m = 5.0;
        guided_cfg.env.observation.site_los = SiteLos::Ray;
        let guided = learner(&guided_cfg).policy();
        assert!(guided.observation.as_ref().is_some_and(|o| o.path_guide));
        let bytes = codec::encode(POLICY_MAGIC, FORMAT_4, &v4(&guided), "policy").expect("encode");
        std::fs::write(&path, bytes).expect("write");
        let v4_policy = load_policy(&path).expect("a format-4 policy loads");
        let mut want = guided.clone();
        if let Some(o) = want.observation.as_mut() {
            o.path_guide_clearance_m = 0.0;
        }
        assert_eq!(v4_policy, want);

        // Format 5 (before `site_los`) loads with the rays it was trained with, under today's
        // default of the cache's line of sight.
        let bytes = codec::encode(POLICY_MAGIC, FORMAT_5, &v5(&guided), "policy").expect("encode");
        std::fs::write(&path, bytes).expect("write");
        let v5_policy = load_policy(&path).expect("a format-5 policy loads");
        assert_eq!(v5_policy, guided);
        let flown = v5_policy.configure(&Config::default()).expect("configure");
        assert_eq!(flown.env.observation.site_los, SiteLos::Ray);
        assert_eq!(Config::default().env.observation.site_los, SiteLos::Cache);

        // Format 1 is refused by name.
        let bytes = codec::encode(POLICY_MAGIC, 1, &v2(&p), "policy").expect("encode");
        std::fs::write(&path, bytes).expect("write");
        let e = load_policy(&path).expect_err("format 1").to_string();
        assert!(
            e.contains("older DUPAC") && e.contains("file format 1"),
            "{e}"
        );
    }

    /// Formats 4 and 5 are today's observation without its last keys: format 5's bincode is
    /// today's less the last field (`site_los`, an enum), format 4's that less the 8 bytes of
    /// `path_guide_clearance_m` (an f64), so each old file reads field by field as written.
    #[test]
    fn formats_4_and_5s_observations_are_todays_less_their_last_keys() {
        let p = learner(&small()).policy();
        let today = p.observation.clone().expect("recorded");
        let enc = |bytes: Vec<u8>| bytes[12..].to_vec();
        let a = enc(codec::encode(b"TESTTEST", 1, &today, "t").expect("encode"));
        let old5 = v5(&p).observation.expect("recorded");
        let old4 = v4(&p).observation.expect("recorded");
        let b5 = enc(codec::encode(b"TESTTEST", 1, &old5, "t").expect("encode"));
        let b4 = enc(codec::encode(b"TESTTEST", 1, &old4, "t").expect("encode"));
        let site_los = enc(codec::encode(b"TESTTEST", 1, &today.site_los, "t").expect("encode"));
        assert_eq!(a.len(), b5.len() + site_los.len());
        assert_eq!(a[..b5.len()], b5[..]);
        assert_eq!(a[b5.len()..], site_los[..]);
        assert_eq!(b5.len(), b4.len() + 8);
        assert_eq!(b5[..b4.len()], b4[..]);
        assert_eq!(b5[b4.len()..], today.path_guide_clearance_m.to_le_bytes());
    }

    /// A policy without site outputs (the A3 base method: `n_sites` = 0, the observation still
    /// M sites long) records its observation and loads; a record of another length is refused.
    #[test]
    fn an_a3_policy_records_its_observation_and_loads() {
        let mut cfg = small();
        cfg.env.association = dupac_common::config::Association::A3;
        cfg.env.observation.path_guide = true;
        let obs_dim = ObsLayout::new(&cfg.env.observation, 4).len();
        let p = Learner::new(cfg.clone(), obs_dim, 0, &Device::flex()).policy();
        assert_eq!(p.n_sites, 0);
        assert_eq!(p.observation.as_ref(), Some(&cfg.env.observation));
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("policy.bin");
        save_policy(&path, &p).expect("save");
        assert_eq!(load_policy(&path).expect("an A3 policy loads"), p);
        let mut other = p.clone();
        if let Some(o) = other.observation.as_mut() {
            o.path_guide = false;
        }
        let e = other.validate().expect_err("4 values fewer");
        assert!(e.contains("does not give"), "{e}");
    }

    #[test]
    fn a_format_2_checkpoint_takes_its_observation_from_its_configuration_when_certain() {
        let mut cfg = small();
        cfg.env.observation.rsrp_scale_db = 17.0;
        let p = learner(&cfg).policy();
        let ck = load_v2_checkpoint(&p, cfg.to_toml_string());
        assert_eq!(
            ck.meta.policy.observation.as_ref(),
            Some(&cfg.env.observation)
        );
        // Written before a key existed (site_ping_pong, 2026-11-26): today's default would be
        // a guess (on, for a feature that did not exist), so none is recorded.
        let mut old = cfg.to_toml_string();
        let line = old
            .lines()
            .find(|l| l.starts_with("site_ping_pong"))
            .expect("the key is written")
            .to_string();
        old = old.replace(&format!("{line}\n"), "");
        let ck = load_v2_checkpoint(&p, old);
        assert_eq!(ck.meta.policy.observation, None);
        // An invalid value in it: none either, and the checkpoint still loads.
        let bad = cfg
            .to_toml_string()
            .replace("rsrp_scale_db = 17.0", "rsrp_scale_db = -1.0");
        let ck = load_v2_checkpoint(&p, bad);
        assert_eq!(ck.meta.policy.observation, None);
        // Written before the path guide existed: its absent keys mean the guide off (λ 0,
        // `planner.clearance_m`), as it was then, not today's defaults (on).
        let mut unguided = cfg.clone();
        unguided.env.observation.path_guide = false;
        unguided.env.observation.path_guide_lambda = 0.0;
        unguided.env.observation.path_guide_clearance_m = 0.0;
        unguided.env.observation.path_lookahead_m = 30.0;
        unguided.env.reward.progress = dupac_common::config::Progress::Straight;
        let pu = learner(&unguided).policy();
        let before_guide: String = unguided
            .to_toml_string()
            .lines()
            .filter(|l| !(l.starts_with("path_guide") || l.starts_with("path_lookahead_m")))
            .map(|l| format!("{l}\n"))
            .collect();
        let ck = load_v2_checkpoint(&pu, before_guide);
        assert_eq!(
            ck.meta.policy.observation.as_ref(),
            Some(&unguided.env.observation)
        );
    }

    #[test]
    fn resuming_on_another_observation_is_refused_by_key() {
        let cfg = small();
        let mut l = learner(&cfg);
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("checkpoint.bin");
        l.save(&path).expect("save");
        let ck = load_checkpoint(&path).expect("load");
        let mut other = small();
        other.env.observation.rsrp_centre_dbm = -80.0;
        let e = learner(&other)
            .restore(&Device::flex(), &ck)
            .expect_err("another observation")
            .to_string();
        assert!(e.contains("env.observation.rsrp_centre_dbm"), "{e}");
        l.restore(&Device::flex(), &ck)
            .expect("the same observation");
    }
}
