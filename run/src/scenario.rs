//! Scenario setup that every command shares: the radio world and its RSRP source, the held-out
//! evaluation pairs and the training pool (spec/env.md "World", "Pairs").

use crate::error::{Context, RunError};
use crate::progress::progress_bar;
use dupac_actor::env::Episode;
use dupac_actor::pairs::{
    Pair, attach_paths, eval_pairs, plan_path, read_pairs_jsonl, training_pool, write_pairs_jsonl,
};
use dupac_actor::planner::Planner;
use dupac_common::Config;
use dupac_common::config::RadioMode;
use dupac_radio::cache::{GridSpec, RsrpCache, RsrpSource};
use dupac_radio::class::RsrpThresholds;
use dupac_radio::world::RadioWorld;
use std::path::PathBuf;
use std::sync::Arc;

/// The radio world's RSRP, shared by every environment of a process.
pub type SharedRsrp = Arc<dyn RsrpSource + Send + Sync>;

/// The radio world and its RSRP source: the cache (built, or opened when fresh), or the world
/// itself with `env.radio_mode = "exact"`.
pub fn world_and_cache(
    cfg: &Config,
    quiet: bool,
) -> Result<(Arc<RadioWorld>, SharedRsrp), RunError> {
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

/// The planner of the world's city, with the per-voxel coverage classes
/// ([`Planner::with_coverage`]) when `coverage` or when `cfg`'s episodes are guided along the
/// coverage-aware path (`env.observation.path_guide_lambda` > 0).
pub fn planner<'w>(
    cfg: &Config,
    world: &'w RadioWorld,
    rsrp: &SharedRsrp,
    coverage: bool,
) -> Planner<'w> {
    let mut planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    if coverage || (cfg.env.needs_path() && cfg.env.observation.path_guide_lambda > 0.0) {
        planner.with_coverage(rsrp.as_ref(), RsrpThresholds::from_config(&cfg.radio));
    }
    planner
}

/// Gives every pair the planned path `cfg`'s episodes are guided along (docs/env.md "Path
/// guide"); nothing when they need none.
pub fn guide_pairs(cfg: &Config, planner: &Planner, pairs: &mut [Pair]) -> Result<(), RunError> {
    if !cfg.env.needs_path() {
        return Ok(());
    }
    attach_paths(planner, pairs, cfg.env.observation.path_guide_lambda)
        .map_err(|e| RunError::Refused(format!("planning the episodes' guide paths: {e}")))
}

/// The episode of `p` as `cfg`'s environment flies it: with the guide path of `cfg`'s λ,
/// planned now when `p` has another (a policy is flown with the observation it recorded, which
/// may ask for another guide than the pairs were given).
pub fn episode(cfg: &Config, planner: &Planner, p: &Pair) -> Result<Episode, RunError> {
    let lambda = cfg.env.observation.path_guide_lambda;
    if !cfg.env.needs_path() || (p.path.is_some() && p.path_lambda == lambda) {
        return Ok(p.episode(false));
    }
    let mut q = p.clone();
    plan_path(planner, &mut q, lambda)
        .map_err(|e| RunError::Refused(format!("pair {}: planning its guide path: {e}", p.id)))?;
    Ok(q.episode(false))
}

/// The held-out evaluation pairs: `pairs.eval_file` when it exists, else generated and written
/// there; guided as `cfg`'s episodes are ([`guide_pairs`]).
pub fn held_out_pairs(cfg: &Config, planner: &Planner, quiet: bool) -> Result<Vec<Pair>, RunError> {
    let file = &cfg.pairs.eval_file;
    if file.exists() {
        let mut pairs = read_pairs_jsonl(file, planner, &cfg.pairs)?;
        guide_pairs(cfg, planner, &mut pairs)?;
        return Ok(pairs);
    }
    let total = (cfg.pairs.eval_bins_m.len() * cfg.pairs.eval_per_bin) as u64;
    let pb = progress_bar(total, "evaluation pairs", quiet);
    let mut pairs = eval_pairs(planner, &cfg.pairs, &cfg.env, &|n| pb.inc(n));
    pb.finish_and_clear();
    write_pairs_jsonl(file, &pairs)?;
    guide_pairs(cfg, planner, &mut pairs)?;
    eprintln!("wrote {} held-out pairs to {}", pairs.len(), file.display());
    Ok(pairs)
}

/// The pairs of `file` (default `pairs.eval_file`, the held-out set), with the file named in
/// errors: what `dupac fly` and `dupac eval` fly.
pub fn read_eval_pairs(
    cfg: &Config,
    file: Option<&PathBuf>,
    planner: &Planner,
) -> Result<(PathBuf, Vec<Pair>), RunError> {
    let file = file.cloned().unwrap_or_else(|| cfg.pairs.eval_file.clone());
    let mut pairs = read_pairs_jsonl(&file, planner, &cfg.pairs).context_with(|| {
        format!(
            "reading pairs {} (make them with `dupac pairs`)",
            file.display()
        )
    })?;
    guide_pairs(cfg, planner, &mut pairs)?;
    Ok((file, pairs))
}

/// `n` pairs spread evenly over `pairs` (all bins represented).
pub fn spread(pairs: &[Pair], n: usize) -> Vec<Pair> {
    if n >= pairs.len() {
        return pairs.to_vec();
    }
    (0..n).map(|k| pairs[k * pairs.len() / n].clone()).collect()
}

/// The training pool (`train.pool_size` pairs from `train.seed`), guided as `cfg`'s episodes
/// are ([`guide_pairs`]).
pub fn make_pool(cfg: &Config, planner: &Planner, quiet: bool) -> Result<Vec<Pair>, RunError> {
    let pb = progress_bar(cfg.train.pool_size as u64, "training pairs", quiet);
    let mut pool = training_pool(
        planner,
        &cfg.pairs,
        &cfg.env,
        cfg.train.pool_size,
        cfg.train.seed,
        &|n| pb.inc(n),
    );
    pb.finish_and_clear();
    if pool.is_empty() {
        return Err(RunError::Refused(
            "no training pairs could be drawn: the city has no free pairs of pairs.min_m..max_m"
                .into(),
        ));
    }
    guide_pairs(cfg, planner, &mut pool)?;
    Ok(pool)
}
