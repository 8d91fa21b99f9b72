//! Scenario setup that every command shares: the radio world and its RSRP source, the held-out
//! evaluation pairs and the training pool (spec/env.md "World", "Pairs").

use crate::error::{Context, RunError};
use crate::guide_cache::{GuideCache, guide_clearance_m};
use crate::progress::{progress_bar, stage_spinner};
use dupac_actor::env::Episode;
use dupac_actor::pairs::{
    Pair, Split, attach_paths, plan_path, read_pairs_jsonl, split_pairs, training_pool,
    write_pairs_jsonl,
};
use dupac_actor::planner::Planner;
use dupac_common::config::{Config, RadioMode};
use dupac_radio::cache::{GridSpec, RsrpCache};
use dupac_radio::channel::FieldSplit;
use dupac_radio::class::RsrpThresholds;
use dupac_radio::source::RsrpSource;
use dupac_radio::source::ShadowedSource;
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

/// `cfg` without the path guide (`env.observation.path_guide` off, the straight-line
/// progress): for flights that observe nothing and whose reward is not reported (scripted
/// planners, replays) and for pairs that are written without their paths, so no guide is
/// planned for them.
pub fn unguided(cfg: &Config) -> Config {
    let mut c = cfg.clone();
    c.env.observation.path_guide = false;
    c.env.reward.progress = dupac_common::config::Progress::Straight;
    c
}

/// The planners [`Planners::new`] builds for `cfg` and `flown`: (clearance (m), whether it needs
/// the coverage classes), the pairs' (`planner.clearance_m`) first. The pairs' planner is every
/// guide's fallback ([`plan_path`]), so it needs the classes whenever a coverage-aware guide
/// (λ > 0) is planned, whatever its clearance.
pub fn planner_needs(cfg: &Config, flown: &[Config], coverage: bool) -> Vec<(f64, bool)> {
    let mut want: Vec<(f64, bool)> = vec![(cfg.planner.clearance_m, coverage)];
    for c in std::iter::once(cfg).chain(flown) {
        if !c.env.needs_path() {
            continue;
        }
        let (clearance_m, cov) = (
            guide_clearance_m(c),
            c.env.observation.path_guide_lambda > 0.0,
        );
        want[0].1 |= cov;
        match want.iter_mut().find(|(x, _)| *x == clearance_m) {
            Some(w) => w.1 |= cov,
            None => want.push((clearance_m, cov)),
        }
    }
    want
}

/// The planners of a process over the world's city: `pairs`, with `planner.clearance_m`, draws
/// and checks the pairs and plans the planner methods; one guide planner per other guide
/// clearance in use ([`guide_clearance_m`]) plans the episodes' guide paths (docs/env.md "Path
/// guide"). The per-voxel coverage classes ([`Planner::with_coverage`]) are computed once, on
/// the first planner that needs them, and shared with the others ([`planner_needs`]).
pub struct Planners<'w> {
    /// `planner.clearance_m`: the pairs, their checks, the planner methods.
    pub pairs: Planner<'w>,
    /// (clearance (m), planner) for each guide clearance other than `pairs`'s.
    guides: Vec<(f64, Planner<'w>)>,
}

impl<'w> Planners<'w> {
    /// The planners for `cfg`'s episodes and for those of `flown` (the configurations policies
    /// are flown with, [`dupac_common::policy::PolicyWeights::configure`]); `coverage`: the
    /// pairs' planner needs the classes too (the coverage-aware planner methods).
    pub fn new(
        cfg: &Config,
        flown: &[Config],
        world: &'w RadioWorld,
        rsrp: &SharedRsrp,
        coverage: bool,
    ) -> Self {
        let want = planner_needs(cfg, flown, coverage);
        let mut built: Vec<(f64, bool, Planner<'w>)> = want
            .into_iter()
            .map(|(clearance_m, cov)| {
                let pc = dupac_common::config::PlannerConfig {
                    clearance_m,
                    ..cfg.planner.clone()
                };
                (clearance_m, cov, Planner::new(&world.city, &cfg.env, &pc))
            })
            .collect();
        if let Some(k) = built.iter().position(|b| b.1) {
            let thresholds = RsrpThresholds::from_config(&cfg.radio);
            built[k].2.with_coverage(rsrp.as_ref(), thresholds);
            let need: Vec<usize> = (0..built.len()).filter(|&j| j != k && built[j].1).collect();
            for j in need {
                let (to, from) = if j < k {
                    let (a, b) = built.split_at_mut(k);
                    (&mut a[j].2, &b[0].2)
                } else {
                    let (a, b) = built.split_at_mut(j);
                    (&mut b[0].2, &a[k].2)
                };
                if !to.share_coverage(from) {
                    to.with_coverage(rsrp.as_ref(), thresholds);
                }
            }
        }
        let mut it = built.into_iter().map(|(c, _, p)| (c, p));
        let (_, pairs) = it.next().expect("the pairs' planner is built first");
        Planners {
            pairs,
            guides: it.collect(),
        }
    }

    /// The planner of `cfg`'s guide paths (its [`guide_clearance_m`]); refused when these
    /// planners were not built for it.
    pub fn guide(&self, cfg: &Config) -> Result<&Planner<'w>, RunError> {
        let clearance_m = guide_clearance_m(cfg);
        if clearance_m == self.pairs.free_space().clearance_m() {
            return Ok(&self.pairs);
        }
        self.guides
            .iter()
            .find(|(c, _)| *c == clearance_m)
            .map(|(_, p)| p)
            .ok_or_else(|| {
                RunError::Refused(format!(
                    "no guide planner of clearance {clearance_m} m was built (env.observation.path_guide_clearance_m)"
                ))
            })
    }
}

/// Gives every pair the planned path `cfg`'s episodes are guided along (docs/env.md "Path
/// guide"); nothing when they need none. A pair the guide's clearance cannot join is guided
/// along the path of the pairs' clearance, and the count is logged.
pub fn guide_pairs(
    cfg: &Config,
    planners: &Planners,
    pairs: &mut [Pair],
) -> Result<usize, RunError> {
    guide_pairs_progress(cfg, planners, pairs, &|_| {})
}

/// [`guide_pairs`] calling `progress(1)` after each pair.
fn guide_pairs_progress(
    cfg: &Config,
    planners: &Planners,
    pairs: &mut [Pair],
    progress: &(dyn Fn(u64) + Sync),
) -> Result<usize, RunError> {
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
    .map_err(|e| RunError::Refused(format!("planning the episodes' guide paths: {e}")))?;
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
) -> Result<bool, RunError> {
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
) -> Result<usize, RunError> {
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
) -> Result<Episode, RunError> {
    let lambda = cfg.env.observation.path_guide_lambda;
    let has =
        p.path.is_some() && p.path_lambda == lambda && p.path_clearance_m == guide_clearance_m(cfg);
    if !cfg.env.needs_path() || has {
        return Ok(p.episode(false, field));
    }
    let mut q = p.clone();
    plan_path(planners.guide(cfg)?, &planners.pairs, &mut q, lambda)
        .map_err(|e| RunError::Refused(format!("pair {}: planning its guide path: {e}", p.id)))?;
    Ok(q.episode(false, field))
}

/// The held-out evaluation pairs (the validation split): `pairs.eval_file` when it exists, else
/// generated and written there; guided as `cfg`'s episodes are ([`guide_pairs`]).
pub fn held_out_pairs(
    cfg: &Config,
    planners: &Planners,
    quiet: bool,
) -> Result<Vec<Pair>, RunError> {
    split_guided(cfg, planners, Split::Validation, quiet)
}

/// The pairs of `split`, guided as `cfg`'s episodes are ([`guide_pairs`]): its file when it
/// exists, else drawn and written there ([`split_unguided`]).
pub fn split_guided(
    cfg: &Config,
    planners: &Planners,
    split: Split,
    quiet: bool,
) -> Result<Vec<Pair>, RunError> {
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
) -> Result<Vec<Pair>, RunError> {
    split_unguided(cfg, planner, Split::Validation, quiet)
}

/// The pairs of `split` without their guide paths: its file ([`Split::file`]) when it exists,
/// else drawn (its seed, [`Split::seed`]) with `planner` and written there.
pub fn split_unguided(
    cfg: &Config,
    planner: &Planner,
    split: Split,
    quiet: bool,
) -> Result<Vec<Pair>, RunError> {
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
) -> Result<(PathBuf, Vec<Pair>), RunError> {
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
/// [`unguided`] (the guide paths are the guide cache's).
pub fn pool_cached(
    cfg: &Config,
    world: &RadioWorld,
    planners: &Planners,
    quiet: bool,
) -> Result<Vec<Pair>, RunError> {
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
pub fn make_pool(cfg: &Config, planners: &Planners, quiet: bool) -> Result<Vec<Pair>, RunError> {
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
        return Err(RunError::Refused(
            "no training pairs could be drawn: the city has no free pairs of pairs.min_m..max_m"
                .into(),
        ));
    }
    guide_pairs(cfg, planners, &mut pool)?;
    Ok(pool)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Under the defaults (a λ = 1 guide planned with 5 m) the pairs' planner (1.5 m), the
    /// guide's fallback, needs the coverage classes too, or a pair the guide cannot join would
    /// stop the run (`PlanError::NoCoverage`) instead of falling back.
    #[test]
    fn the_fallback_planner_gets_the_classes_a_coverage_aware_guide_needs() {
        let cfg = Config::default();
        assert_eq!(
            planner_needs(&cfg, &[], false),
            vec![(1.5, true), (5.0, true)]
        );
        // Unguided: the pairs' planner only, classes only when asked for.
        let mut off = cfg.clone();
        off.env.observation.path_guide = false;
        off.env.reward.progress = dupac_common::config::Progress::Straight;
        assert_eq!(planner_needs(&off, &[], false), vec![(1.5, false)]);
        assert_eq!(planner_needs(&off, &[], true), vec![(1.5, true)]);
        // A flown policy's guide of the shortest path at 0 (= planner.clearance_m): no classes.
        let mut shortest = cfg.clone();
        shortest.env.observation.path_guide_lambda = 0.0;
        shortest.env.observation.path_guide_clearance_m = 0.0;
        assert_eq!(planner_needs(&off, &[shortest], false), vec![(1.5, false)]);
        // A clearance below the UAV's radius is the radius, as the planner makes it.
        let mut thin = cfg.clone();
        thin.env.observation.path_guide_clearance_m = 0.1;
        assert_eq!(guide_clearance_m(&thin), thin.env.uav_radius_m);
    }
}
