//! What `dupac monitor` shows, from the run's statistics messages: policy version, updates/s,
//! env steps/s in total and per actor, policy lag, drops by reason, training and domain
//! metrics. A value not known yet (before the first update, an actor without stats) shows as
//! [`MISSING`].

use dupac_common::dedup::MAX_TRACKED_SENDERS;
use dupac_common::ids::ActorId;
use dupac_common::metric;
use dupac_common::msg::{ActorStats, LearnerStats, StatsMsg};
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// What the table shows for a value not known yet.
pub const MISSING: &str = "–";

/// The newest stats a monitor has from the learner and from each actor.
#[derive(Debug, Default)]
pub struct Board {
    learner: Option<LearnerStats>,
    actors: BTreeMap<ActorId, ActorStats>,
}

impl Board {
    /// Keeps `msg` as its sender's newest stats (the newest received: the stats carry no
    /// authentication, so the board does not let one message's `seq` hold back the next).
    /// Returns `false`, keeping nothing, for a new actor id while [`MAX_TRACKED_SENDERS`] are
    /// shown.
    pub fn take(&mut self, msg: StatsMsg) -> bool {
        match msg {
            StatsMsg::Learner(s) => self.learner = Some(s),
            StatsMsg::Actor(a) => {
                let id = a.header.actor;
                if !self.actors.contains_key(&id) && self.actors.len() >= MAX_TRACKED_SENDERS {
                    return false;
                }
                self.actors.insert(id, a);
            }
        }
        true
    }

    /// The learner's newest stats.
    pub fn learner(&self) -> Option<&LearnerStats> {
        self.learner.as_ref()
    }

    /// The learner said the run reached `train.total_timesteps`.
    pub fn done(&self) -> bool {
        self.learner.as_ref().is_some_and(|l| l.done)
    }

    /// The table.
    pub fn render(&self) -> String {
        render(self.learner.as_ref(), &self.actors)
    }
}

/// `v` with `decimals` decimals and `unit` (none: `""`), or [`MISSING`].
fn show(v: Option<f64>, decimals: usize, unit: &str) -> String {
    match v {
        Some(v) => format!("{v:.decimals$}{unit}"),
        None => MISSING.to_string(),
    }
}

/// The table a monitor shows.
pub fn render(learner: Option<&LearnerStats>, actors: &BTreeMap<ActorId, ActorStats>) -> String {
    let mut t = String::new();
    let Some(s) = learner else {
        let _ = writeln!(t, "waiting for the learner's stats …");
        return t;
    };
    let m = |k: &str| s.metrics.get(k).copied();
    let pct = |k: &str| m(k).map(|v| 100.0 * v);
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
    let classes = [
        metric::TRAIN.pct_excellent,
        metric::TRAIN.pct_mediocre,
        metric::TRAIN.pct_poor,
    ]
    .map(|k| show(m(k), 0, ""))
    .join("/");
    let _ = writeln!(
        t,
        "return {}  success {}  collision {}  RSRP {}  excellent/mediocre/poor {classes} %  handovers {}  site regret {} (> threshold {}, class {})",
        show(m(metric::EPISODIC_RETURN), 1, ""),
        show(pct(metric::TRAIN.success_rate), 1, " %"),
        show(pct(metric::TRAIN.collision_rate), 1, " %"),
        show(m(metric::TRAIN.mean_rsrp_dbm), 1, " dBm"),
        show(m(metric::TRAIN.handovers_per_km), 1, "/km"),
        show(m(metric::TRAIN.site_regret_db), 2, " dB"),
        show(m(metric::TRAIN.pct_site_regret_high), 0, " %"),
        show(m(metric::TRAIN.pct_class_regret), 0, " %"),
    );
    let _ = writeln!(
        t,
        "update time: wait {}  ppo {}  publish {}   chunks accepted {}",
        show(m(metric::WAIT_S), 3, " s"),
        show(m(metric::PPO_S), 3, " s"),
        show(m(metric::PUBLISH_S), 4, " s"),
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
        "actor", "state", "steps/s", "timesteps", "chunks", "lag", "last seen", "swaps", "swap ms"
    );
    for a in &s.actors {
        let own = actors.get(&a.actor);
        let _ = writeln!(
            t,
            "{:>8} {:>8} {:>12.0} {:>12} {:>8} {:>5} {:>10} {:>8} {:>12}",
            a.actor.to_string(),
            format!("{:?}", a.state).to_lowercase(),
            a.steps_per_s,
            a.env_steps,
            a.chunks,
            a.policy_lag,
            show(a.last_seen_s, 1, "s"),
            own.map_or(MISSING.to_string(), |o| o.swaps.to_string()),
            show(own.and_then(|o| o.last_swap_latency_ms), 1, ""),
        );
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use dupac_common::msg::{ActorRow, ActorState, Header};

    fn learner_before_the_first_update() -> LearnerStats {
        LearnerStats {
            header: Header::new("r", 7, ActorId::LEARNER, 1),
            update: 0,
            total_updates: 10,
            global_step: 0,
            updates_per_s: 0.0,
            env_steps_per_s: 0.0,
            accepted_chunks: 0,
            drops: BTreeMap::new(),
            actors: vec![ActorRow {
                actor: ActorId(0),
                state: ActorState::Alive,
                steps_per_s: 0.0,
                env_steps: 0,
                chunks: 0,
                policy_lag: 0,
                last_seen_s: None,
            }],
            metrics: BTreeMap::new(),
            done: false,
        }
    }

    fn actor(id: u32, incarnation: u64, seq: u64) -> ActorStats {
        let mut h = Header::new("r", 7, ActorId(id), 1);
        h.sender_incarnation = incarnation;
        h.seq = seq;
        ActorStats {
            header: h,
            num_envs: 1,
            env_steps: 0,
            steps_per_s: 0.0,
            chunks_sent: 0,
            swaps: 0,
            last_swap_latency_ms: None,
            episodes: 0,
        }
    }

    /// Before the first update the learner's stats have no metrics and the actor no stats of
    /// its own: the table says so with a dash, never `NaN`.
    #[test]
    fn values_not_known_yet_show_as_a_dash() {
        let table = render(Some(&learner_before_the_first_update()), &BTreeMap::new());
        assert!(!table.contains("NaN"), "{table}");
        assert!(table.contains(&format!("success {MISSING}  ")), "{table}");
        assert!(table.contains(&format!("RSRP {MISSING}  ")), "{table}");
        assert!(table.contains(&format!("wait {MISSING}  ")), "{table}");
        let row = table.lines().last().expect("the actor's row");
        assert_eq!(
            row.split_whitespace().collect::<Vec<_>>(),
            ["0", "alive", "0", "0", "0", "0", MISSING, MISSING, MISSING],
            "{table}"
        );
        // With data, numbers and units.
        let mut s = learner_before_the_first_update();
        s.metrics.insert(metric::TRAIN.success_rate.into(), 0.25);
        s.metrics.insert(metric::TRAIN.mean_rsrp_dbm.into(), -71.04);
        s.actors[0].last_seen_s = Some(0.5);
        let own = ActorStats {
            swaps: 2,
            last_swap_latency_ms: Some(12.5),
            ..actor(0, 1, 1)
        };
        let table = render(Some(&s), &BTreeMap::from([(ActorId(0), own)]));
        assert!(table.contains("success 25.0 %  "), "{table}");
        assert!(table.contains("RSRP -71.0 dBm  "), "{table}");
        assert!(
            table.trim_end().ends_with("0.5s        2         12.5"),
            "{table}"
        );
    }

    #[test]
    fn the_board_holds_a_bounded_number_of_actors() {
        let mut b = Board::default();
        for id in 0..MAX_TRACKED_SENDERS as u32 {
            assert!(b.take(StatsMsg::Actor(actor(id, 1, 0))));
        }
        let extra = MAX_TRACKED_SENDERS as u32;
        assert!(!b.take(StatsMsg::Actor(actor(extra, 1, 0))));
        assert_eq!(b.actors.len(), MAX_TRACKED_SENDERS);
        // Those it holds still update; the learner's stats and the end of the run go through.
        assert!(b.take(StatsMsg::Actor(actor(0, 1, 1))));
        assert_eq!(b.actors[&ActorId(0)].header.seq, 1);
        let mut l = learner_before_the_first_update();
        l.done = true;
        assert!(b.take(StatsMsg::Learner(l)));
        assert!(b.done());
    }
}
