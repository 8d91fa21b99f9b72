//! The learner's roster of actors: who is present (liveliness), who sends (accepted chunks),
//! and how each is reported to monitors ([`ActorRow`]). No zenoh here: the node's liveliness
//! subscriber and its batcher report to it, so the rules are tested on their own.
//!
//! An actor is **alive** while its liveliness token is present and it has sent within
//! `distributed.silent_after_s`, **silent** while its token is present but nothing arrived for
//! that long (or nothing yet), **left** once its token is gone. At most
//! [`MAX_TRACKED_SENDERS`] ids are tracked: a flood of made-up ids cannot grow the table.

use dupac_common::dedup::MAX_TRACKED_SENDERS;
use dupac_common::ids::ActorId;
use dupac_common::msg::{ActorRow, ActorState};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// What the learner knows of one actor.
#[derive(Debug, Clone)]
struct Entry {
    state: ActorState,
    env_steps: u64,
    chunks: u64,
    last_version: u64,
    last_seen: Option<Instant>,
    steps_at_last_rows: u64,
}

impl Entry {
    fn new() -> Entry {
        Entry {
            state: ActorState::Alive,
            env_steps: 0,
            chunks: 0,
            last_version: 0,
            last_seen: None,
            steps_at_last_rows: 0,
        }
    }
}

/// The actors of a run as the learner sees them.
#[derive(Debug)]
pub struct Roster {
    actors: BTreeMap<ActorId, Entry>,
    silent_after: Duration,
    last_rows: Instant,
}

impl Roster {
    /// A roster that calls an actor silent after `silent_after` without data.
    pub fn new(silent_after: Duration) -> Roster {
        Roster {
            actors: BTreeMap::new(),
            silent_after,
            last_rows: Instant::now(),
        }
    }

    fn entry(&mut self, id: ActorId) -> Option<&mut Entry> {
        if !self.actors.contains_key(&id) && self.actors.len() >= MAX_TRACKED_SENDERS {
            return None;
        }
        Some(self.actors.entry(id).or_insert_with(Entry::new))
    }

    /// `id`'s liveliness token appeared (`present`) or went; `false` when the id is one too
    /// many to track (ignored).
    pub fn presence(&mut self, id: ActorId, present: bool) -> bool {
        let Some(e) = self.entry(id) else {
            return false;
        };
        e.state = if present {
            ActorState::Alive
        } else {
            ActorState::Left
        };
        true
    }

    /// A chunk of `samples` samples acted with `version` from `id` was taken for training; it
    /// arrived at `at`.
    pub fn accepted(&mut self, id: ActorId, samples: usize, version: u64, at: Instant) {
        if let Some(e) = self.entry(id) {
            e.env_steps += samples as u64;
            e.chunks += 1;
            e.last_version = version;
            e.last_seen = Some(at);
        }
    }

    /// The rows for monitors at `now` while training `version` (steps per second since the
    /// last call).
    pub fn rows(&mut self, version: u64, now: Instant) -> Vec<ActorRow> {
        let dt = now
            .saturating_duration_since(self.last_rows)
            .as_secs_f64()
            .max(1e-9);
        self.last_rows = now;
        let silent_after_s = self.silent_after.as_secs_f64();
        self.actors
            .iter_mut()
            .map(|(id, a)| {
                let last_seen_s = a
                    .last_seen
                    .map(|s| now.saturating_duration_since(s).as_secs_f64());
                let state = match a.state {
                    ActorState::Left => ActorState::Left,
                    _ if last_seen_s.is_none_or(|s| s > silent_after_s) => ActorState::Silent,
                    _ => ActorState::Alive,
                };
                let steps_per_s = (a.env_steps - a.steps_at_last_rows) as f64 / dt;
                a.steps_at_last_rows = a.env_steps;
                ActorRow {
                    actor: *id,
                    state,
                    steps_per_s,
                    env_steps: a.env_steps,
                    chunks: a.chunks,
                    policy_lag: version.saturating_sub(a.last_version),
                    last_seen_s,
                }
            })
            .collect()
    }

    /// Actors whose liveliness token is present.
    pub fn alive(&self) -> usize {
        self.actors
            .values()
            .filter(|a| a.state != ActorState::Left)
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(rows: &[ActorRow], id: u32) -> ActorState {
        rows.iter()
            .find(|r| r.actor == ActorId(id))
            .map(|r| r.state)
            .expect("a row")
    }

    #[test]
    fn an_actor_is_alive_while_it_sends_silent_when_it_stops_and_left_without_its_token() {
        let t0 = Instant::now();
        let at = |s: u64| t0 + Duration::from_secs(s);
        let mut r = Roster::new(Duration::from_secs(10));
        assert!(r.presence(ActorId(1), true));
        assert_eq!(
            state(&r.rows(0, at(0)), 1),
            ActorState::Silent,
            "nothing yet"
        );
        r.accepted(ActorId(1), 256, 3, at(1));
        let rows = r.rows(4, at(2));
        assert_eq!(state(&rows, 1), ActorState::Alive);
        assert_eq!(
            (rows[0].env_steps, rows[0].chunks, rows[0].policy_lag),
            (256, 1, 1)
        );
        assert_eq!(
            state(&r.rows(4, at(12)), 1),
            ActorState::Silent,
            "11 s without data"
        );
        r.accepted(ActorId(1), 256, 4, at(13));
        assert_eq!(
            state(&r.rows(4, at(14)), 1),
            ActorState::Alive,
            "sends again"
        );
        assert!(r.presence(ActorId(1), false));
        assert_eq!(state(&r.rows(4, at(14)), 1), ActorState::Left);
        assert_eq!(r.alive(), 0);
        assert!(r.presence(ActorId(1), true));
        assert_eq!(r.alive(), 1, "a returning token");
    }

    #[test]
    fn steps_per_second_count_since_the_last_rows() {
        let t0 = Instant::now();
        let mut r = Roster::new(Duration::from_secs(10));
        r.rows(0, t0);
        r.accepted(ActorId(2), 1000, 1, t0);
        let rows = r.rows(1, t0 + Duration::from_secs(2));
        assert!((rows[0].steps_per_s - 500.0).abs() < 1e-9);
        let rows = r.rows(1, t0 + Duration::from_secs(4));
        assert_eq!(rows[0].steps_per_s, 0.0);
    }

    #[test]
    fn the_roster_stops_growing_at_the_tracked_limit() {
        let mut r = Roster::new(Duration::from_secs(10));
        for id in 0..MAX_TRACKED_SENDERS as u32 {
            assert!(r.presence(ActorId(id), true));
        }
        assert!(!r.presence(ActorId(u32::MAX), true), "one id too many");
        r.accepted(ActorId(u32::MAX - 1), 10, 0, Instant::now());
        assert_eq!(r.alive(), MAX_TRACKED_SENDERS);
        assert!(r.presence(ActorId(0), false), "a tracked id still updates");
    }
}
