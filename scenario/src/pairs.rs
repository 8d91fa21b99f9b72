//! The pairs a process flies (spec/env.md "Pairs"): the held-out splits (read, or drawn and
//! written), the training pool (through the host's pool file), each pair's guide path (through
//! the guide cache) and the episode of a pair as a configuration's environment flies it.

use crate::error::{Context, ScenarioError};
use crate::guide_cache::{GuideCache, guide_clearance_m};
use crate::planners::Planners;
use crate::progress::{progress_bar, stage_spinner};
use crate::world::SharedRsrp;
use dupac_actor::env::Episode;
use dupac_actor::pairs::{
    Pair, Split, attach_paths, plan_path, read_pairs_jsonl, split_pairs, training_pool,
    write_pairs_jsonl,
};
use dupac_actor::planner::Planner;
use dupac_common::config::Config;
use dupac_radio::channel::FieldSplit;
use dupac_radio::world::RadioWorld;
use std::path::PathBuf;

/// Gives every pair the planned path `cfg`'s episodes are guided along (docs/env.md "Path
/// guide"); nothing when they need none. A pair the guide's clearance cannot join is guided
/// along the path of the pairs' clearance, and the count is logged.
pub fn guide_pairs(
    cfg: &Config,
    planners: &Planners,
    pairs: &mut [Pair],
) -> Result<usize, ScenarioError> {
    guide_pairs_progress(cfg, planners, pairs, &|_| {})
}

/// [`guide_pairs`] calling `progress(1)` after each pair.
fn guide_pairs_progress(
    cfg: &Config,
    planners: &Planners,
    pairs: &mut [Pair],
    progress: &(dyn Fn(u64) + Sync),
) -> Result<usize, ScenarioError> {
    if !cfg.env.needs_path() {
        return Ok(0);
    }
    let guide = planners.guide(cfg)?;
    let fell_back = attach_paths(
        guide,
        &planners.pairs,
        pairs,
        cfg.env.observation.path_guide_lambda,
        progress,
    )
    .map_err(|e| ScenarioError::Refused(format!("planning the episodes' guide paths: {e}")))?;
    if fell_back > 0 {
        tracing::warn!(
            pairs = fell_back,
            of = pairs.len(),
            guide_clearance_m = guide_clearance_m(cfg),
            planner_clearance_m = cfg.planner.clearance_m,
            "no guide path with the guide's clearance: these pairs are guided along the path of planner.clearance_m"
        );
    }
    Ok(fell_back)
}

/// [`guide_pairs`] through the guide cache ([`GuideCache`]): the paths of these pairs under
/// `cfg` are loaded when this host planned them before, else planned (with planners built here:
/// the coverage classes are most of the cost) and cached, with a progress bar unless `quiet`.
/// Returns whether they were loaded.
pub fn guide_pairs_cached(
    cfg: &Config,
    world: &RadioWorld,
    rsrp: &SharedRsrp,
    pairs: &mut [Pair],
    quiet: bool,
) -> Result<bool, ScenarioError> {
    Ok(guide_sets_cached(cfg, world, rsrp, &mut [pairs], quiet)? == 1)
}

/// [`guide_pairs_cached`] for several pair sets (each its own cache entry), the planners built at
/// most once for those the cache misses. Returns how many sets were loaded.
pub fn guide_sets_cached(
    cfg: &Config,
    world: &RadioWorld,
    rsrp: &SharedRsrp,
    sets: &mut [&mut [Pair]],
    quiet: bool,
) -> Result<usize, ScenarioError> {
    if !cfg.env.needs_path() {
        return Ok(0);
    }
    let mut planners: Option<Planners> = None;
    let mut loaded = 0;
    for pairs in sets.iter_mut().filter(|p| !p.is_empty()) {
        let cache = GuideCache::new(cfg, world.fingerprint(), pairs);
        if cache.load(pairs).is_some() {
            tracing::info!(pairs = pairs.len(), file = %cache.path().display(), "guide paths loaded");
            loaded += 1;
            continue;
        }
        let planners = planners.get_or_insert_with(|| {
            let spin = stage_spinner("guide planners", quiet);
            let built = Planners::new(cfg, &[], world, rsrp, false);
            spin.finish_and_clear();
            built
        });
        let pb = progress_bar(pairs.len() as u64, "guide paths", quiet);
        let fell_back = guide_pairs_progress(cfg, planners, pairs, &|n| pb.inc(n))?;
        pb.finish_and_clear();
        cache.save(pairs, fell_back);
    }
    Ok(loaded)
}

/// The episode of `p` as `cfg`'s environment flies it, in `field`'s realisations: with the
/// guide path of `cfg`'s λ and clearance, planned now when `p` has another (a policy is flown
/// with the observation it recorded, which may ask for another guide than the pairs were given).
pub fn episode(
    cfg: &Config,
    planners: &Planners,
    p: &Pair,
    field: FieldSplit,
) -> Result<Episode, ScenarioError> {
    let lambda = cfg.env.observation.path_guide_lambda;
    let has =
        p.path.is_some() && p.path_lambda == lambda && p.path_clearance_m == guide_clearance_m(cfg);
    if !cfg.env.needs_path() || has {
        return Ok(p.episode(false, field));
    }
    let mut q = p.clone();
    plan_path(planners.guide(cfg)?, &planners.pairs, &mut q, lambda).map_err(|e| {
        ScenarioError::Refused(format!("pair {}: planning its guide path: {e}", p.id))
    })?;
    Ok(q.episode(false, field))
}

/// The held-out evaluation pairs (the validation split): `pairs.eval_file` when it exists, else
/// generated and written there; guided as `cfg`'s episodes are ([`guide_pairs`]).
pub fn held_out_pairs(
    cfg: &Config,
    planners: &Planners,
    quiet: bool,
) -> Result<Vec<Pair>, ScenarioError> {
    split_guided(cfg, planners, Split::Validation, quiet)
}

/// The pairs of `split`, guided as `cfg`'s episodes are ([`guide_pairs`]): its file when it
/// exists, else drawn and written there ([`split_unguided`]).
pub fn split_guided(
    cfg: &Config,
    planners: &Planners,
    split: Split,
    quiet: bool,
) -> Result<Vec<Pair>, ScenarioError> {
    let mut pairs = split_unguided(cfg, &planners.pairs, split, quiet)?;
    guide_pairs(cfg, planners, &mut pairs)?;
    Ok(pairs)
}

/// The held-out evaluation pairs (the validation split) without their guide paths:
/// `pairs.eval_file` when it exists, else drawn (seed `pairs.eval_seed`) with `planner` and
/// written there.
pub fn held_out_unguided(
    cfg: &Config,
    planner: &Planner,
    quiet: bool,
) -> Result<Vec<Pair>, ScenarioError> {
    split_unguided(cfg, planner, Split::Validation, quiet)
}

/// The pairs of `split` without their guide paths: its file ([`Split::file`]) when it exists,
/// else drawn (its seed, [`Split::seed`]) with `planner` and written there.
pub fn split_unguided(
    cfg: &Config,
    planner: &Planner,
    split: Split,
    quiet: bool,
) -> Result<Vec<Pair>, ScenarioError> {
    let file = split.file(&cfg.pairs, planner.city());
    if file.exists() {
        return read_pairs_jsonl(&file, planner, &cfg.pairs)
            .context_with(|| format!("reading the {} pairs ({})", split.name(), split.file_key()));
    }
    let total = (cfg.pairs.eval_bins_m.len() * cfg.pairs.eval_per_bin) as u64;
    let pb = progress_bar(total, &format!("{} pairs", split.name()), quiet);
    let pairs = split_pairs(planner, &cfg.pairs, &cfg.env, split, &|n| pb.inc(n));
    pb.finish_and_clear();
    write_pairs_jsonl(&file, &pairs)?;
    eprintln!(
        "wrote {} {} pairs ({} = {}) to {}",
        pairs.len(),
        split.name(),
        split.seed_key(),
        split.seed(&cfg.pairs),
        file.display()
    );
    Ok(pairs)
}

/// The pairs of `file`, or (without one) of `split`'s file, drawn and written when missing as
/// [`split_guided`] does, with the file named in errors: what `dupac fly` and `dupac eval`
/// fly.
pub fn read_eval_pairs(
    cfg: &Config,
    file: Option<&PathBuf>,
    split: Split,
    planners: &Planners,
) -> Result<(PathBuf, Vec<Pair>), ScenarioError> {
    let default = split.file(&cfg.pairs, planners.pairs.city());
    if file.is_none() && !default.exists() {
        let pairs = split_guided(cfg, planners, split, true)?;
        return Ok((default, pairs));
    }
    let file = file.cloned().unwrap_or(default);
    let mut pairs = read_pairs_jsonl(&file, &planners.pairs, &cfg.pairs).context_with(|| {
        format!(
            "reading pairs {} (make them with `dupac pairs`)",
            file.display()
        )
    })?;
    guide_pairs(cfg, planners, &mut pairs)?;
    Ok((file, pairs))
}

/// `n` pairs spread evenly over `pairs` (all bins represented).
pub fn spread(pairs: &[Pair], n: usize) -> Vec<Pair> {
    if n >= pairs.len() {
        return pairs.to_vec();
    }
    (0..n).map(|k| pairs[k * pairs.len() / n].clone()).collect()
}

/// The training pool of `cfg` ([`make_pool`]) through the host's pool file: `pool-<key>.jsonl`
/// in the folder of `cache.path`, beside the RSRP and guide caches, read when this host drew the
/// same pool before, else drawn and written (atomically; a failed write is logged, never fatal).
/// The key hashes what decides the draw: the environment fingerprint
/// ([`Config::env_fingerprint`]: world, environment, pairs and planner sections),
/// `train.pool_size` and `train.seed`. The pairs come back as a pairs file gives them (without
/// the sampler's shortest paths), as the actors of a run read `train_pool.jsonl`; `cfg` must be
/// [`crate::planners::unguided`] (the guide paths are the guide cache's).
pub fn pool_cached(
    cfg: &Config,
    world: &RadioWorld,
    planners: &Planners,
    quiet: bool,
) -> Result<Vec<Pair>, ScenarioError> {
    let file = pool_file(cfg, world.fingerprint());
    if file.exists() {
        match read_pairs_jsonl(&file, &planners.pairs, &cfg.pairs) {
            Ok(pool) if pool.len() == cfg.train.pool_size => {
                tracing::info!(pairs = pool.len(), file = %file.display(), "training pool loaded");
                return Ok(pool);
            }
            Ok(pool) => tracing::warn!(
                file = %file.display(),
                pairs = pool.len(),
                wanted = cfg.train.pool_size,
                "pool file of another size: drawing the pool again"
            ),
            Err(e) => tracing::warn!("pool file not used, drawing the pool again: {e}"),
        }
    }
    let mut pool = make_pool(cfg, planners, quiet)?;
    for p in &mut pool {
        p.path = None;
    }
    if let Err(e) = write_pairs_jsonl(&file, &pool) {
        tracing::warn!("training pool not cached: {e}");
    }
    Ok(pool)
}

/// The file [`pool_cached`] keeps `cfg`'s pool in, in a world of fingerprint
/// `world_fingerprint`.
pub fn pool_file(cfg: &Config, world_fingerprint: u64) -> PathBuf {
    let mut h = dupac_common::fingerprint::Fnv64::new();
    h.write_u64(cfg.env_fingerprint(world_fingerprint));
    h.write_u64(cfg.train.pool_size as u64);
    h.write_u64(cfg.train.seed);
    let dir = cfg
        .cache
        .path
        .parent()
        .map(PathBuf::from)
        .unwrap_or_default();
    dir.join(format!("pool-{:016x}.jsonl", h.finish()))
}

/// The training pool (`train.pool_size` pairs from `train.seed`), guided as `cfg`'s episodes
/// are ([`guide_pairs`]).
pub fn make_pool(
    cfg: &Config,
    planners: &Planners,
    quiet: bool,
) -> Result<Vec<Pair>, ScenarioError> {
    let pb = progress_bar(cfg.train.pool_size as u64, "training pairs", quiet);
    let mut pool = training_pool(
        &planners.pairs,
        &cfg.pairs,
        &cfg.env,
        cfg.train.pool_size,
        cfg.train.seed,
        &|n| pb.inc(n),
    );
    pb.finish_and_clear();
    if pool.is_empty() {
        return Err(ScenarioError::Refused(
            "no training pairs could be drawn: the city has no free pairs of pairs.min_m..max_m"
                .into(),
        ));
    }
    guide_pairs(cfg, planners, &mut pool)?;
    Ok(pool)
}
