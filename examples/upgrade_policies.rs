//! Rewrites policy files of formats 2 to 6 in today's format, in place (a one-off command):
//!
//! ```sh
//! cargo run --release --example upgrade_policies -- DIR/policy.bin …
//! ```
//!
//! Each file is read as `dupac_learner::checkpoint::load_policy` reads it (formats 3 to 6 record
//! their observation; a format-6 policy that observes `site_trend` is refused) and written back
//! with `save_policy`, then read again and compared. A format-2 policy records no observation:
//! it gets the one of its run's `config.toml` (the file beside it): the `[env.observation]` keys
//! written there, and for a key absent from it (added after the run) what its absence meant
//! then: `site_ping_pong` off, `site_los` = `ray`, the path guide off (λ 0, clearance 0, the 30 m
//! look-ahead of those days). Any other absent key, or a record the weights do not fit, is an
//! error and the file is left as it was. For such a policy the command also prints how the
//! recorded observation differs from the one `dupac eval` flew it with under the default
//! configuration (the defaults with the guide off and rays, the site features switched to fit a
//! slot head's length): only keys without effect on that observation may differ.
//! A file already of today's format is left alone.

use anyhow::{Context, Result, anyhow, bail};
use dupac_common::config::{Config, ObservationConfig, SiteLos};
use dupac_common::obs::ObsLayout;
use dupac_common::policy::{PolicyWeights, observation_diff};
use dupac_learner::checkpoint::{load_policy, save_policy};
use std::path::Path;

/// The format this build writes (`learner/src/checkpoint.rs`).
const TODAY: u32 = 7;

/// Keys of `[env.observation]` added after format 2's runs, with what their absence meant then.
fn added_since() -> [(&'static str, toml::Value); 6] {
    [
        ("site_ping_pong", toml::Value::Boolean(false)),
        ("site_los", toml::Value::String("ray".into())),
        ("path_guide", toml::Value::Boolean(false)),
        ("path_lookahead_m", toml::Value::Float(30.0)),
        ("path_guide_lambda", toml::Value::Float(0.0)),
        ("path_guide_clearance_m", toml::Value::Float(0.0)),
    ]
}

/// The observation of a run's configuration file, as the run observed it.
fn observation_of(config: &Path) -> Result<ObservationConfig> {
    let text = std::fs::read_to_string(config)
        .with_context(|| format!("{}: the run's configuration", config.display()))?;
    let table: toml::Table = toml::from_str(&text).with_context(|| config.display().to_string())?;
    let mut written = table
        .get("env")
        .and_then(|e| e.get("observation"))
        .and_then(|o| o.as_table())
        .cloned()
        .ok_or_else(|| anyhow!("{}: no [env.observation]", config.display()))?;
    if let Some(trend) = written.remove("site_trend")
        && trend.as_bool() != Some(false)
    {
        bail!("{}: the run observed the site trend", config.display());
    }
    let today = toml::Value::try_from(ObservationConfig::default())?;
    let added = added_since();
    for key in today.as_table().expect("a table").keys() {
        if !written.contains_key(key) {
            let (_, then) = added.iter().find(|(k, _)| k == key).ok_or_else(|| {
                anyhow!(
                    "{}: env.observation.{key} is not written and did not exist then",
                    config.display()
                )
            })?;
            written.insert(key.clone(), then.clone());
        }
    }
    let o: ObservationConfig = written
        .try_into()
        .with_context(|| config.display().to_string())?;
    o.validate()?;
    Ok(o)
}

/// The observation `dupac eval` flew a policy without a record with, under the default
/// configuration (`PolicyWeights::configure` and the length match of `run/src/eval/fly.rs`).
fn as_eval_flew(p: &PolicyWeights) -> ObservationConfig {
    let mut o = Config::default().env.observation;
    o.path_guide = false;
    o.site_los = SiteLos::Ray;
    if ObsLayout::new(&o, p.n_sites).len() != p.obs_dim && p.site_head.is_none() {
        o.site_features = !o.site_features;
        if ObsLayout::new(&o, p.n_sites).len() != p.obs_dim {
            o.site_features = !o.site_features;
        }
    }
    o
}

fn upgrade(path: &Path) -> Result<()> {
    let bytes = std::fs::read(path).with_context(|| path.display().to_string())?;
    let format = bytes
        .get(8..12)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .ok_or_else(|| anyhow!("{}: too short", path.display()))?;
    if format == TODAY {
        println!("{}: already format {TODAY}", path.display());
        return Ok(());
    }
    let mut p = load_policy(path)?;
    if p.observation.is_none() {
        let config = path.with_file_name("config.toml");
        let o = observation_of(&config)?;
        let flew = observation_diff(&o, &as_eval_flew(&p));
        p.observation = Some(o);
        p.validate()
            .map_err(|e| anyhow!("{}: with {}: {e}", path.display(), config.display()))?;
        println!(
            "{}: observation of {}; against eval's: {}",
            path.display(),
            config.display(),
            if flew.is_empty() {
                "the same".to_string()
            } else {
                flew.join(", ")
            }
        );
    }
    save_policy(path, &p)?;
    let back = load_policy(path)?;
    if back != p {
        bail!(
            "{}: read back differs from what was written",
            path.display()
        );
    }
    println!("{}: format {format} → {TODAY}", path.display());
    Ok(())
}

fn main() -> Result<()> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        bail!("usage: upgrade_policies POLICY.bin …");
    }
    for p in &paths {
        upgrade(Path::new(p))?;
    }
    Ok(())
}
