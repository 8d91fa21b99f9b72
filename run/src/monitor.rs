//! The table `dupac monitor` shows, from the run's statistics messages: policy
//! version, updates/s, env steps/s in total and per actor, policy lag, drops by reason,
//! training and domain metrics.

use dupac_common::ids::ActorId;
use dupac_common::metric;
use dupac_common::msg::{ActorStats, LearnerStats};
use std::collections::BTreeMap;
use std::fmt::Write as _;

fn metric(s: &LearnerStats, k: &str) -> f64 {
    s.metrics.get(k).copied().unwrap_or(f64::NAN)
}

/// The table a monitor shows.
pub fn render(learner: Option<&LearnerStats>, actors: &BTreeMap<ActorId, ActorStats>) -> String {
    let mut t = String::new();
    match learner {
        None => {
            let _ = writeln!(t, "waiting for the learner's stats …");
        }
        Some(s) => {
            let _ = writeln!(
                t,
                "run {:?}  policy v{} ({}/{} updates{})  {:.2} updates/s  {:.0} timesteps/s  {} timesteps",
                s.header.run_id,
                s.update,
                s.update,
                s.total_updates,
                if s.done { ", done" } else { "" },
                s.updates_per_s,
                s.env_steps_per_s,
                s.global_step
            );
            let _ = writeln!(
                t,
                "return {:.1}  success {:.1} %  collision {:.1} %  RSRP {:.1} dBm  excellent/mediocre/poor {:.0}/{:.0}/{:.0} %  handovers {:.1}/km  site regret {:.2} dB (> threshold {:.0} %, class {:.0} %)",
                metric(s, metric::EPISODIC_RETURN),
                100.0 * metric(s, metric::TRAIN.success_rate),
                100.0 * metric(s, metric::TRAIN.collision_rate),
                metric(s, metric::TRAIN.mean_rsrp_dbm),
                metric(s, metric::TRAIN.pct_excellent),
                metric(s, metric::TRAIN.pct_mediocre),
                metric(s, metric::TRAIN.pct_poor),
                metric(s, metric::TRAIN.handovers_per_km),
                metric(s, metric::TRAIN.site_regret_db),
                metric(s, metric::TRAIN.pct_site_regret_high),
                metric(s, metric::TRAIN.pct_class_regret),
            );
            let _ = writeln!(
                t,
                "update time: wait {:.3} s  ppo {:.3} s  publish {:.4} s   chunks accepted {}",
                metric(s, metric::WAIT_S),
                metric(s, metric::PPO_S),
                metric(s, metric::PUBLISH_S),
                s.accepted_chunks
            );
            let drops: Vec<String> = s.drops.iter().map(|(k, v)| format!("{k} {v}")).collect();
            let _ = writeln!(
                t,
                "dropped: {}",
                if drops.is_empty() {
                    "none".to_string()
                } else {
                    drops.join(", ")
                }
            );
            let _ = writeln!(
                t,
                "{:>8} {:>8} {:>12} {:>12} {:>8} {:>5} {:>10} {:>8} {:>12}",
                "actor",
                "state",
                "steps/s",
                "timesteps",
                "chunks",
                "lag",
                "last seen",
                "swaps",
                "swap ms"
            );
            for a in &s.actors {
                let own = actors.get(&a.actor);
                let _ = writeln!(
                    t,
                    "{:>8} {:>8} {:>12.0} {:>12} {:>8} {:>5} {:>9.1}s {:>8} {:>12.1}",
                    a.actor.to_string(),
                    format!("{:?}", a.state).to_lowercase(),
                    a.steps_per_s,
                    a.env_steps,
                    a.chunks,
                    a.policy_lag,
                    a.last_seen_s.unwrap_or(f64::NAN),
                    own.map_or(0, |o| o.swaps),
                    own.and_then(|o| o.last_swap_latency_ms).unwrap_or(f64::NAN),
                );
            }
        }
    }
    t
}
