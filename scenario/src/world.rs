//! The radio world a process flies in and its RSRP source (spec/env.md "World"): the cache,
//! built or opened when fresh, or the world's exact RSRP; the true RSRP of an episode under the
//! real channel.

use crate::error::{Context, ScenarioError};
use crate::progress::progress_bar;
use dupac_common::config::{Config, RadioMode};
use dupac_radio::cache::{GridSpec, RsrpCache};
use dupac_radio::channel::FieldSplit;
use dupac_radio::source::{RsrpSource, ShadowedSource};
use dupac_radio::world::RadioWorld;
use std::sync::Arc;

/// The radio world's RSRP, shared by every environment of a process.
pub type SharedRsrp = Arc<dyn RsrpSource + Send + Sync>;

/// The radio world and its RSRP source: the cache (built, or opened when fresh), or the world
/// itself with `env.radio_mode = "exact"`.
pub fn world_and_cache(
    cfg: &Config,
    quiet: bool,
) -> Result<(Arc<RadioWorld>, SharedRsrp), ScenarioError> {
    let world = Arc::new(RadioWorld::build(cfg).context("building the radio world")?);
    if cfg.env.radio_mode == RadioMode::Exact {
        let exact: SharedRsrp = world.clone();
        return Ok((world, exact));
    }
    let rows = GridSpec::covering(world.city.area_m, &cfg.cache).ny;
    let pb = progress_bar(rows as u64, "RSRP cache", quiet);
    let (cache, _) = RsrpCache::open_or_build(&world, &cfg.cache, &|n| pb.inc(n))?;
    pb.finish_and_clear();
    Ok((world, Arc::new(cache)))
}

/// The true RSRP of the episodes reset with `seed` in `split` (evaluation: the pair's id): `rsrp`
/// less the shadow fading of their field under the real channel (`radio.channel.model =
/// "real"`), `rsrp` itself in the deterministic world.
pub fn true_source(
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    split: FieldSplit,
    seed: u64,
) -> SharedRsrp {
    match &world.channel {
        Some(c) => Arc::new(ShadowedSource {
            base: rsrp.clone(),
            field: c.episode_field(split, seed),
            los: world.clone(),
        }),
        None => rsrp.clone(),
    }
}
