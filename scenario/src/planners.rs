//! The planners of a process over the world's city: the pairs' planner and one per guide
//! clearance in use, the coverage classes computed once and shared; and a configuration without
//! the path guide for flights that observe nothing.

use crate::error::ScenarioError;
use crate::guide_cache::guide_clearance_m;
use crate::world::SharedRsrp;
use dupac_actor::planner::Planner;
use dupac_common::config::Config;
use dupac_radio::class::RsrpThresholds;
use dupac_radio::world::RadioWorld;

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
/// guide's fallback ([`dupac_actor::pairs::plan_path`]), so it needs the classes whenever a coverage-aware guide
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
    pub fn guide(&self, cfg: &Config) -> Result<&Planner<'w>, ScenarioError> {
        let clearance_m = guide_clearance_m(cfg);
        if clearance_m == self.pairs.free_space().clearance_m() {
            return Ok(&self.pairs);
        }
        self.guides
            .iter()
            .find(|(c, _)| *c == clearance_m)
            .map(|(_, p)| p)
            .ok_or_else(|| {
                ScenarioError::Refused(format!(
                    "no guide planner of clearance {clearance_m} m was built (env.observation.path_guide_clearance_m)"
                ))
            })
    }
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
