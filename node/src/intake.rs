//! The weights intake of an actor or a pilot: what a weights message must be to be used, and
//! which of several is the one to act with. No zenoh here: the node hands it bytes (a
//! publication or the replies to a query), so the rules are tested on their own.
//!
//! A message is decoded within the size and allocation limits of this process's own network
//! ([`MsgLimits::weights`]) and checked against what this process expects
//! ([`validate_weights`]: the run, the environment fingerprint, the policy's shape, finite
//! values). Another run or another environment fingerprint is fatal (the process was started
//! with another configuration); anything else wrong is ignored and counted. Weights are
//! **newer** when they come from another learner incarnation (a restarted learner: its versions
//! continue from its checkpoint and may be lower than the ones in use) or carry a higher version
//! of the same incarnation.

use dupac_common::msg::{MsgLimits, WeightsHeld, WeightsMsg, decode_msg, held_value, is_kind};
use dupac_common::validate::{ChunkExpect, DropReason, Rejection, check_header, validate_weights};

/// A learner incarnation and a policy version: which weights are in use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WeightsKey {
    pub incarnation: u64,
    pub version: u64,
}

impl WeightsKey {
    /// The key of a weights message.
    pub fn of(w: &WeightsMsg) -> WeightsKey {
        WeightsKey {
            incarnation: w.header.learner_incarnation,
            version: w.policy.version,
        }
    }
}

/// What a weights query brought back.
#[derive(Debug, Clone, PartialEq)]
pub enum Answer {
    /// The learner's newest weights (the best of the replies).
    Weights(Box<WeightsMsg>),
    /// The learner is at the weights the asker holds ([`WeightsHeld`]): nothing to take.
    Held(WeightsKey),
}

impl Answer {
    /// Which weights the learner is at.
    pub fn learner_at(&self) -> WeightsKey {
        match self {
            Answer::Weights(w) => WeightsKey::of(w),
            Answer::Held(k) => *k,
        }
    }

    /// The weights, when the reply carried them.
    pub fn into_weights(self) -> Option<WeightsMsg> {
        match self {
            Answer::Weights(w) => Some(*w),
            Answer::Held(_) => None,
        }
    }
}

/// What [`WeightsIntake::offer`] did with weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Offer {
    /// Not newer than the weights in use: ignored.
    Stale,
    /// The first weights, or a higher version of the same learner incarnation.
    Newer,
    /// Weights of another learner incarnation (a restarted learner).
    NewIncarnation,
}

/// A fatal mismatch: the weights come from another run or another environment fingerprint.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct Mismatch(pub String);

/// The checks and the "newer" rule for one process's weights.
#[derive(Debug, Clone)]
pub struct WeightsIntake {
    expect: ChunkExpect,
    limit: MsgLimits,
    current: Option<WeightsKey>,
    /// Messages ignored (undecodable, wrong shape, non-finite).
    pub refused: u64,
}

impl WeightsIntake {
    /// An intake expecting `expect`'s run, fingerprint and policy shape, decoding within `limit`.
    pub fn new(expect: ChunkExpect, limit: MsgLimits) -> WeightsIntake {
        WeightsIntake {
            expect,
            limit,
            current: None,
            refused: 0,
        }
    }

    /// The weights in use, if any.
    pub fn current(&self) -> Option<WeightsKey> {
        self.current
    }

    /// Decodes and checks one message from `origin` (a key expression, for the log): `Ok(None)`
    /// when it is ignored (logged once at debug level and counted in `refused`), `Err` when it
    /// belongs to another run or environment.
    pub fn check(&mut self, bytes: &[u8], origin: &str) -> Result<Option<WeightsMsg>, Mismatch> {
        let Some(w) = self.decode::<WeightsMsg>(bytes, origin) else {
            return Ok(None);
        };
        Ok(self.judge(validate_weights(&w, &self.expect))?.then_some(w))
    }

    /// `M` decoded within this process's limits; `None` (counted, logged at debug) when it
    /// cannot be.
    fn decode<M: dupac_common::msg::Message>(&mut self, bytes: &[u8], origin: &str) -> Option<M> {
        decode_msg(bytes, self.limit, origin)
            .map_err(|e| {
                self.refused += 1;
                tracing::debug!("weights ignored: {e}");
            })
            .ok()
    }

    /// A check's verdict: `Ok(true)` passed, `Ok(false)` ignored (counted, logged at debug),
    /// `Err` another run or environment (fatal).
    fn judge(&mut self, checked: Result<(), Rejection>) -> Result<bool, Mismatch> {
        match checked {
            Ok(()) => Ok(true),
            Err(r) if matches!(r.reason, DropReason::Fingerprint | DropReason::WrongRun) => {
                Err(Mismatch(r.detail))
            }
            Err(r) => {
                self.refused += 1;
                tracing::debug!("weights ignored: {r}");
                Ok(false)
            }
        }
    }

    /// The selector parameters of a weights query from this process: `held=…` naming the
    /// weights in use (the learner then answers [`WeightsHeld`] when they are its newest), empty
    /// before any.
    pub fn query_parameters(&self) -> String {
        self.current
            .map(|k| {
                let held = held_value(k.incarnation, k.version);
                format!("{}={held}", dupac_common::msg::HELD_PARAMETER)
            })
            .unwrap_or_default()
    }

    /// Decodes and checks one reply to a weights query: the weights ([`WeightsIntake::check`]),
    /// or a [`WeightsHeld`] whose header passes the same checks and names the weights in use
    /// (any other is ignored and counted: this process did not ask for it).
    pub fn check_reply(&mut self, bytes: &[u8], origin: &str) -> Result<Option<Answer>, Mismatch> {
        if !is_kind::<WeightsHeld>(bytes) {
            return Ok(self
                .check(bytes, origin)?
                .map(|w| Answer::Weights(Box::new(w))));
        }
        let Some(h) = self.decode::<WeightsHeld>(bytes, origin) else {
            return Ok(None);
        };
        if !self.judge(check_header(&h.header, &self.expect))? {
            return Ok(None);
        }
        let key = WeightsKey {
            incarnation: h.header.learner_incarnation,
            version: h.header.policy_version,
        };
        if self.current != Some(key) {
            self.refused += 1;
            tracing::debug!(
                ?key,
                "a 'held' reply for weights this process does not hold"
            );
            return Ok(None);
        }
        Ok(Some(Answer::Held(key)))
    }

    /// What a query's replies say, each checked by [`WeightsIntake::check_reply`]: the weights of
    /// the highest version among them, or, when none carried newer weights, that the learner is
    /// at the weights in use.
    pub fn best_reply<B: AsRef<[u8]>>(
        &mut self,
        replies: impl IntoIterator<Item = B>,
        origin: &str,
    ) -> Result<Option<Answer>, Mismatch> {
        let mut best: Option<Answer> = None;
        for bytes in replies {
            let Some(a) = self.check_reply(bytes.as_ref(), origin)? else {
                continue;
            };
            let better = match (&best, &a) {
                (None, _) => true,
                (Some(Answer::Held(_)), Answer::Weights(_)) => true,
                (Some(Answer::Weights(b)), Answer::Weights(w)) => {
                    w.policy.version > b.policy.version
                }
                _ => false,
            };
            if better {
                best = Some(a);
            }
        }
        Ok(best)
    }

    /// Whether `key` is newer than the weights in use: none in use, another learner
    /// incarnation, or a higher version of the same one.
    pub fn is_newer(&self, key: WeightsKey) -> bool {
        match self.current {
            None => true,
            Some(c) => key.incarnation != c.incarnation || key.version > c.version,
        }
    }

    /// Takes `key` as the weights in use when it is newer.
    pub fn offer(&mut self, key: WeightsKey) -> Offer {
        if !self.is_newer(key) {
            return Offer::Stale;
        }
        let previous = self.current.replace(key);
        match previous {
            Some(p) if p.incarnation != key.incarnation => Offer::NewIncarnation,
            _ => Offer::Newer,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dupac_common::ids::ActorId;
    use dupac_common::msg::{Header, encode_msg};
    use dupac_common::normalize::{ObsNormalizer, RewardScaler};
    use dupac_common::obs::OBS_VERSION;
    use dupac_common::policy::mlp::{Dense, Mlp};
    use dupac_common::policy::{MOVE_DIM, PolicyWeights};

    fn key(incarnation: u64, version: u64) -> WeightsKey {
        WeightsKey {
            incarnation,
            version,
        }
    }

    const OBS: usize = 6;
    const SITES: usize = 2;

    fn dense(n_in: usize, n_out: usize) -> Dense {
        Dense {
            n_in,
            n_out,
            weight: (0..n_in * n_out)
                .map(|i| (i as f32 * 0.37).sin() * 0.3)
                .collect(),
            bias: vec![0.01; n_out],
        }
    }

    /// A small valid policy: 6 observations, 2 sites, one hidden layer of 4.
    fn policy(version: u64) -> PolicyWeights {
        PolicyWeights {
            version,
            obs_version: OBS_VERSION,
            obs_dim: OBS,
            n_sites: SITES,
            actor: Mlp {
                layers: vec![dense(OBS, 4), dense(4, MOVE_DIM + SITES)],
            },
            critic: Mlp {
                layers: vec![dense(OBS, 4), dense(4, 1)],
            },
            site_head: None,
            log_std: [-0.5; MOVE_DIM],
            obs_norm: ObsNormalizer::new(OBS, true, 5.0),
            reward_scaler: RewardScaler::new(true, 0.95, 10.0),
            observation: None,
        }
    }

    const RUN: &str = "run-a";
    const FINGERPRINT: u64 = 7;

    fn intake() -> WeightsIntake {
        let expect = ChunkExpect {
            run_id: RUN.into(),
            incarnation: 0,
            fingerprint: FINGERPRINT,
            obs_dim: OBS,
            n_sites: SITES,
            max_envs: 4,
            max_steps: 64,
            site_steps: None,
        };
        WeightsIntake::new(expect, MsgLimits::both(1 << 20))
    }

    /// The bytes of weights `version` from learner `incarnation` of `run` in world `fingerprint`.
    fn message(run: &str, incarnation: u64, version: u64, fingerprint: u64) -> Vec<u8> {
        let msg = WeightsMsg {
            header: Header::new(run, incarnation, ActorId(0), fingerprint),
            policy: policy(version),
        };
        encode_msg(&msg).expect("encode")
    }

    #[test]
    fn a_stale_version_is_not_newer_and_a_higher_one_is() {
        let mut i = intake();
        assert_eq!(i.offer(key(1, 5)), Offer::Newer);
        assert_eq!(i.offer(key(1, 5)), Offer::Stale);
        assert_eq!(i.offer(key(1, 4)), Offer::Stale);
        assert_eq!(i.current(), Some(key(1, 5)));
        assert_eq!(i.offer(key(1, 6)), Offer::Newer);
        assert_eq!(i.current(), Some(key(1, 6)));
    }

    #[test]
    fn a_restarted_learner_is_followed_even_at_a_lower_version() {
        let mut i = intake();
        assert_eq!(i.offer(key(1, 40)), Offer::Newer);
        assert_eq!(i.offer(key(2, 12)), Offer::NewIncarnation);
        assert_eq!(i.current(), Some(key(2, 12)));
        // The old incarnation's late publication does not take the weights back.
        assert_eq!(i.offer(key(2, 11)), Offer::Stale);
    }

    #[test]
    fn checks_refuse_garbage_and_stop_at_another_run_or_world() {
        let mut i = intake();
        let w = i
            .check(&message(RUN, 3, 9, FINGERPRINT), "w")
            .expect("same run")
            .expect("valid");
        assert_eq!(WeightsKey::of(&w), key(3, 9));
        assert_eq!(i.check(b"not weights", "w"), Ok(None));
        assert_eq!(i.refused, 1);
        assert!(i.check(&message("run-b", 3, 9, FINGERPRINT), "w").is_err());
        assert!(i.check(&message(RUN, 3, 9, FINGERPRINT + 1), "w").is_err());
    }

    #[test]
    fn the_best_reply_is_the_highest_valid_version() {
        let mut i = intake();
        let replies = [
            message(RUN, 3, 4, FINGERPRINT),
            b"garbage".to_vec(),
            message(RUN, 3, 9, FINGERPRINT),
            message(RUN, 3, 6, FINGERPRINT),
        ];
        let best = i
            .best_reply(&replies, "w")
            .expect("same run")
            .and_then(Answer::into_weights)
            .expect("some");
        assert_eq!(best.policy.version, 9);
        assert_eq!(i.refused, 1);
    }

    /// The bytes of a "held" reply of learner `incarnation` at `version`.
    fn held(run: &str, incarnation: u64, version: u64, fingerprint: u64) -> Vec<u8> {
        let mut header = Header::new(run, incarnation, ActorId::LEARNER, fingerprint);
        header.policy_version = version;
        encode_msg(&WeightsHeld { header }).expect("encode")
    }

    #[test]
    fn a_query_names_the_weights_held_and_a_held_reply_says_the_learner_is_there() {
        let mut i = intake();
        assert_eq!(
            i.query_parameters(),
            "",
            "nothing held: ask for the weights"
        );
        i.offer(key(3, 9));
        assert_eq!(i.query_parameters(), "held=3.9");
        let a = i
            .best_reply([held(RUN, 3, 9, FINGERPRINT)], "w")
            .expect("same run")
            .expect("an answer");
        assert_eq!(a, Answer::Held(key(3, 9)));
        assert_eq!(a.learner_at(), key(3, 9));
        // Weights among the replies win over a "held" one.
        let replies = [
            held(RUN, 3, 9, FINGERPRINT),
            message(RUN, 3, 10, FINGERPRINT),
        ];
        let a = i.best_reply(replies, "w").expect("same run").expect("some");
        assert_eq!(a.learner_at(), key(3, 10));
        assert!(a.into_weights().is_some());
        // A "held" reply for weights not in use is nobody's answer; another run's is fatal.
        assert_eq!(i.check_reply(&held(RUN, 3, 8, FINGERPRINT), "w"), Ok(None));
        assert_eq!(i.refused, 1);
        assert!(
            i.check_reply(&held("run-b", 3, 9, FINGERPRINT), "w")
                .is_err()
        );
        assert!(
            i.check_reply(&held(RUN, 3, 9, FINGERPRINT + 1), "w")
                .is_err()
        );
    }
}
