//! An actor's or a pilot's Zenoh side: the weights subscriber (a ring channel of 1: only the
//! newest matters), the liveliness of the run's learners and actors, the learner's `Stop`, the
//! trajectory and stats publishers on the network side's tasks ([`crate::netside`]), and the
//! query of the learner's weights queryable (for late joiners and missed publications).

use crate::actor_error::{ActorError, z};
use crate::intake::{Answer, WeightsIntake, WeightsKey};
use crate::netside::{Every, Latest, NetSide};
use crate::outbox::Delivery;
use crate::presence::{LOSS_GRACE, PresenceLog};
use dupac_common::config::Config;
use dupac_common::ids::ActorId;
use dupac_common::jsonmsg::decode_json;
use dupac_common::keys::{KeySpace, Role};
use dupac_common::msg::{Command, ControlMsg, MsgLimits, WeightsMsg};
use std::collections::HashSet;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use zenoh::Wait;
use zenoh::bytes::Encoding;
use zenoh::handlers::{RingChannel, RingChannelHandler};
use zenoh::qos::CongestionControl;
use zenoh::sample::{Sample, SampleKind};

/// Chunks queued for the network side before the environments wait (besides the one being sent).
const CHUNKS_IN_FLIGHT: usize = 2;

/// Everything an actor holds on the Zenoh side.
pub(crate) struct Wiring {
    pub(crate) session: zenoh::Session,
    pub(crate) keys: KeySpace,
    pub(crate) weights: zenoh::pubsub::Subscriber<RingChannelHandler<Sample>>,
    pub(crate) learners: Arc<Mutex<HashSet<String>>>,
    /// Actors of the run with a liveliness token (this one included).
    pub(crate) actors: Arc<Mutex<HashSet<String>>>,
    pub(crate) stop: Arc<AtomicBool>,
    pub(crate) traj: Every,
    /// What this process and its network side know about outgoing chunks.
    pub(crate) delivery: Arc<Mutex<Delivery>>,
    pub(crate) stats: Latest,
    pub(crate) net: NetSide,
    _token: zenoh::liveliness::LivelinessToken,
    _learner_sub: zenoh::pubsub::Subscriber<()>,
    _actors_sub: zenoh::pubsub::Subscriber<()>,
    _ctrl_sub: zenoh::pubsub::Subscriber<()>,
}

impl Wiring {
    pub(crate) fn new(
        session: zenoh::Session,
        cfg: &Config,
        id: ActorId,
    ) -> Result<Wiring, ActorError> {
        Wiring::with_role(session, cfg, id, Role::Actor)
    }

    pub(crate) fn new_pilot(
        session: zenoh::Session,
        cfg: &Config,
        id: ActorId,
    ) -> Result<Wiring, ActorError> {
        Wiring::with_role(session, cfg, id, Role::Pilot)
    }

    fn with_role(
        session: zenoh::Session,
        cfg: &Config,
        id: ActorId,
        role: Role,
    ) -> Result<Wiring, ActorError> {
        let keys = KeySpace::new(&cfg.distributed.run);
        let weights = session
            .declare_subscriber(keys.weights())
            .with(RingChannel::new(1))
            .wait()
            .map_err(z)?;
        let stop = Arc::new(AtomicBool::new(false));
        let (learners, learner_sub) =
            track_alive(&session, &keys, Role::Learner, Some(stop.clone()))?;
        let (actors, actors_sub) = track_alive(&session, &keys, Role::Actor, None)?;
        let ctrl_sub = {
            let (stop, limit) = (stop.clone(), MsgLimits::small(cfg));
            let key = keys.ctrl();
            session
                .declare_subscriber(keys.ctrl())
                .callback(move |s| {
                    match decode_json::<ControlMsg>(&s.payload().to_bytes(), limit, &key) {
                        Ok(m) if m.command == Command::Stop => {
                            tracing::info!("the learner ended the run");
                            stop.store(true, Ordering::Relaxed);
                        }
                        Ok(_) => {}
                        Err(e) => tracing::warn!("control message ignored: {e}"),
                    }
                })
                .wait()
                .map_err(z)?
        };
        let mut net = NetSide::new()
            .map_err(|e| ActorError::Zenoh(format!("cannot start the network side: {e}")))?;
        let delivery = Arc::new(Mutex::new(Delivery::new(cfg.distributed.max_policy_lag)));
        let traj = Every::start(
            &mut net,
            session
                .declare_publisher(keys.traj(id))
                .congestion_control(CongestionControl::Block)
                .wait()
                .map_err(z)?,
            CHUNKS_IN_FLIGHT,
            delivery.clone(),
            "trajectory chunk",
        );
        let stats = Latest::start(
            &mut net,
            session
                .declare_publisher(keys.stats_actor(id))
                .congestion_control(CongestionControl::Drop)
                .encoding(Encoding::APPLICATION_JSON)
                .wait()
                .map_err(z)?,
            "stats",
        );
        let token = session
            .liveliness()
            .declare_token(keys.alive(role, &id.0.to_string()))
            .wait()
            .map_err(z)?;
        Ok(Wiring {
            session,
            keys,
            weights,
            learners,
            actors,
            stop,
            traj,
            delivery,
            stats,
            net,
            _token: token,
            _learner_sub: learner_sub,
            _actors_sub: actors_sub,
            _ctrl_sub: ctrl_sub,
        })
    }

    /// Sends what is still queued, stops the network side and closes the session.
    pub(crate) fn close(self) {
        let Wiring {
            session,
            traj,
            stats,
            net,
            ..
        } = self;
        drop((traj, stats));
        net.finish(Duration::from_secs(5));
        let _ = session.close().wait();
    }

    pub(crate) fn actors_alive(&self) -> usize {
        self.actors.lock().map(|a| a.len()).unwrap_or(1).max(1)
    }

    pub(crate) fn learner_alive(&self) -> bool {
        self.learners.lock().map(|l| !l.is_empty()).unwrap_or(false)
    }

    /// Asks the learner's queryable for its latest weights, naming the weights `intake` holds
    /// (the learner then answers in a few bytes when they are its newest): the best reply by
    /// `intake`'s rules, each reply checked as it arrives (none kept but the best).
    pub(crate) fn query_weights(
        &self,
        intake: &mut WeightsIntake,
    ) -> Result<Option<Answer>, ActorError> {
        let selector = match intake.query_parameters() {
            p if p.is_empty() => self.keys.weights(),
            p => format!("{}?{p}", self.keys.weights()),
        };
        let replies = self
            .session
            .get(selector)
            .timeout(Duration::from_secs(2))
            .wait()
            .map_err(z)?;
        let payloads = std::iter::from_fn(|| replies.recv().ok()).filter_map(|reply| {
            reply
                .result()
                .ok()
                .map(|s| s.payload().to_bytes().into_owned())
        });
        intake
            .best_reply(payloads, &self.keys.weights())
            .map_err(|m| ActorError::Refused(m.0))
    }

    /// The newest published weights, if any arrived (waiting up to `wait` for them), checked by
    /// `intake`.
    pub(crate) fn receive_weights(
        &self,
        intake: &mut WeightsIntake,
        wait: Option<Duration>,
    ) -> Result<Option<WeightsMsg>, ActorError> {
        let received = match wait {
            Some(t) => self.weights.recv_timeout(t),
            None => self.weights.try_recv(),
        };
        match received {
            Ok(Some(sample)) => intake
                .check(&sample.payload().to_bytes(), &self.keys.weights())
                .map_err(|m| ActorError::Refused(m.0)),
            _ => Ok(None),
        }
    }

    /// The learner is at `key` (or later): chunks older than it allows are not sent.
    pub(crate) fn learner_at(&self, key: WeightsKey) {
        if let Ok(mut d) = self.delivery.lock() {
            d.learner_at(key);
        }
    }

    /// The last chunk that left the network side, and when.
    pub(crate) fn last_left(&self) -> Option<(u64, std::time::Instant)> {
        self.delivery.lock().ok().and_then(|d| d.last_left())
    }

    /// The learner ended the run.
    pub(crate) fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

/// The ids of the processes of `role` whose liveliness token is present, kept current by a
/// liveliness subscriber (with history: tokens declared before it count); with `log`, joins and
/// departures are reported (a departure as a warning unless the flag is set: the run ended).
#[allow(clippy::type_complexity)]
pub(crate) fn track_alive(
    session: &zenoh::Session,
    keys: &KeySpace,
    role: Role,
    log: Option<Arc<AtomicBool>>,
) -> Result<(Arc<Mutex<HashSet<String>>>, zenoh::pubsub::Subscriber<()>), ActorError> {
    let present: Arc<Mutex<HashSet<String>>> = Arc::default();
    let (set, keys2) = (present.clone(), keys.clone());
    let presence = PresenceLog::default();
    let sub = session
        .liveliness()
        .declare_subscriber(keys.alive_role(role))
        .history(true)
        .callback(move |s| {
            let Some((_, id)) = keys2.parse_alive(s.key_expr().as_str()) else {
                return;
            };
            let Ok(mut set) = set.lock() else { return };
            match s.kind() {
                SampleKind::Put => {
                    if log.is_some() && !presence.back(&id, &format!("{role} {id}")) {
                        tracing::info!(%role, id, "present");
                    }
                    set.insert(id);
                }
                SampleKind::Delete => {
                    match &log {
                        Some(ended) if ended.load(Ordering::Relaxed) => {
                            tracing::info!(%role, id, "gone (the run ended)");
                        }
                        Some(_) => presence.left(
                            &id,
                            format!(
                                "lost the {role} {id} for {} s (stopped, or the network parted \
                                 us); waiting, will rejoin",
                                LOSS_GRACE.as_secs()
                            ),
                        ),
                        None => {}
                    }
                    set.remove(&id);
                }
            }
        })
        .wait()
        .map_err(z)?;
    Ok((present, sub))
}
