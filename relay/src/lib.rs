//! A userspace TCP relay that impairs traffic, to rehearse training over a bad WAN on a machine
//! whose kernel lacks `sch_netem` (no `tc qdisc ... netem`).
//!
//! Zenoh runs over TCP: an actor connects to the relay's listening address instead of the
//! learner's router, the relay connects to the router (the *upstream*) and forwards bytes both
//! ways, each direction with its own [`LinkImpairment`] (one-way delay with jitter, rate cap;
//! [`link`]), and the whole relay follows a schedule of [`Fault`]s (stalls, resets,
//! partitions; [`fault`]). [`spec`] parses the compact text forms a command line passes
//! (`delay=50ms,jitter=20ms,rate=10mbit`, `partition@30s+20s,stall@10s+3s,reset@50s`).
//! Counters ([`RelayStats`]) can be read while it runs.
//!
//! Written by hand: no maintained Rust crate gives scheduled partitions together with
//! per-direction delay, jitter and a token bucket in-process, and toxiproxy (the usual tool) is
//! a Go server driven over HTTP, a separate program to install and orchestrate.
//!
//! [`Relay::start`] runs the relay on a runtime of its own (two tokio worker threads named
//! `dupac-relay`) and returns at once: callers are synchronous command-line code and tests, and
//! the relay's timing does not depend on what else the caller's runtime, if any, is doing.
//! Dropping the [`Relay`] (or [`Relay::shutdown`]) stops it and closes its connections.
//!
//! What it is not: packets are not modelled, only the byte stream (TCP's own retransmissions
//! never happen on loopback), and loss is not simulated (on TCP it shows as delay and stalls,
//! which the schedule gives directly).

pub mod fault;
pub mod link;
pub mod spec;
pub mod stats;

mod conn;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::TcpListener;
use tokio::sync::{oneshot, watch};

pub use fault::{Fault, FaultKind, RelayState};
pub use link::LinkImpairment;
pub use spec::{SpecError, parse_faults, parse_link};
pub use stats::{DirectionStats, RelayStats};

use conn::Shared;
use fault::{Control, FaultSchedule};
use stats::Counters;

/// Errors of starting a relay.
#[derive(Debug, thiserror::Error)]
pub enum RelayError {
    #[error("relay configuration: {0}")]
    Config(String),
    #[error("relay: cannot listen on {addr}: {source}")]
    Listen {
        addr: SocketAddr,
        source: std::io::Error,
    },
    #[error("relay: cannot start its runtime: {0}")]
    Runtime(std::io::Error),
}

/// What a relay does.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RelayConfig {
    /// Where it listens for the downstream peers (port 0: any free port, see
    /// [`Relay::local_addr`]).
    pub listen: SocketAddr,
    /// Where it connects for each accepted connection (the learner's router).
    pub upstream: SocketAddr,
    /// The impairment of the bytes going upstream (downstream peer → upstream).
    pub up: LinkImpairment,
    /// The impairment of the bytes coming back (upstream → downstream peer).
    pub down: LinkImpairment,
    /// The fault schedule, offsets from the relay's origin (its start, or the call of
    /// [`Relay::begin_faults`] if `faults_held`).
    pub faults: Vec<Fault>,
    /// Hold the fault schedule until [`Relay::begin_faults`] (the links' impairments apply from
    /// the start): to fault a run once it has warmed up, however long that took.
    pub faults_held: bool,
    /// Seed of the jitter draws (each connection and direction draws its own stream of it, in
    /// the order connections are accepted).
    pub seed: u64,
    /// The most bytes one read takes from a socket (default 64 KiB).
    pub read_chunk_bytes: usize,
    /// The most bytes one direction of one connection holds in its delay queue (default
    /// 4 MiB, at least `read_chunk_bytes`): past it the relay stops reading that side.
    /// With a delay `d`, a direction's throughput is at most this / `d` (4 MiB / 50 ms ≈
    /// 670 Mbit/s).
    pub max_queued_bytes: usize,
}

impl RelayConfig {
    /// The default read chunk, in bytes.
    pub const DEFAULT_READ_CHUNK_BYTES: usize = 64 * 1024;
    /// The default queue bound per direction and connection, in bytes.
    pub const DEFAULT_MAX_QUEUED_BYTES: usize = 4 * 1024 * 1024;

    /// A relay from `listen` to `upstream` that impairs nothing (until told to).
    pub fn new(listen: SocketAddr, upstream: SocketAddr) -> RelayConfig {
        RelayConfig {
            listen,
            upstream,
            up: LinkImpairment::NONE,
            down: LinkImpairment::NONE,
            faults: vec![],
            faults_held: false,
            seed: 0,
            read_chunk_bytes: Self::DEFAULT_READ_CHUNK_BYTES,
            max_queued_bytes: Self::DEFAULT_MAX_QUEUED_BYTES,
        }
    }

    /// This with the same impairment both ways.
    pub fn with_links(self, link: LinkImpairment) -> RelayConfig {
        RelayConfig {
            up: link,
            down: link,
            ..self
        }
    }

    /// This with a fault schedule.
    pub fn with_faults(self, faults: Vec<Fault>) -> RelayConfig {
        RelayConfig { faults, ..self }
    }

    /// This with a fault schedule held until [`Relay::begin_faults`].
    pub fn with_held_faults(self, faults: Vec<Fault>) -> RelayConfig {
        RelayConfig {
            faults,
            faults_held: true,
            ..self
        }
    }

    /// Why it cannot run, if so.
    pub fn check(&self) -> Result<(), RelayError> {
        let bad = |m: String| Err(RelayError::Config(m));
        if let Err(e) = self.up.check() {
            return bad(format!("up link: {e}"));
        }
        if let Err(e) = self.down.check() {
            return bad(format!("down link: {e}"));
        }
        for f in &self.faults {
            f.check().map_err(RelayError::Config)?;
        }
        if self.read_chunk_bytes == 0 || self.read_chunk_bytes > 16 * 1024 * 1024 {
            return bad(format!(
                "read_chunk_bytes {} is not in 1 B–16 MiB",
                self.read_chunk_bytes
            ));
        }
        if self.max_queued_bytes < self.read_chunk_bytes + link::CHUNK_OVERHEAD_BYTES
            || self.max_queued_bytes > u32::MAX as usize
        {
            return bad(format!(
                "max_queued_bytes {} is not in read_chunk_bytes + {} – 4 GiB",
                self.max_queued_bytes,
                link::CHUNK_OVERHEAD_BYTES
            ));
        }
        Ok(())
    }
}

/// A running relay. Dropping it stops it.
pub struct Relay {
    rt: Option<tokio::runtime::Runtime>,
    local_addr: SocketAddr,
    /// The fault schedule's origin, once it has begun.
    origin: std::sync::OnceLock<std::time::Instant>,
    /// Begins a held schedule at the origin it is sent.
    begin: std::sync::Mutex<Option<oneshot::Sender<std::time::Instant>>>,
    counters: Arc<Counters>,
}

impl Relay {
    /// Checks `cfg`, listens, and starts relaying on a runtime of its own; returns once it
    /// listens. The fault schedule's origin is now, or (`faults_held`) the call of
    /// [`Relay::begin_faults`].
    pub fn start(cfg: RelayConfig) -> Result<Relay, RelayError> {
        cfg.check()?;
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("dupac-relay")
            .enable_io()
            .enable_time()
            .build()
            .map_err(RelayError::Runtime)?;
        let listen_err = |source| RelayError::Listen {
            addr: cfg.listen,
            source,
        };
        let std_listener = std::net::TcpListener::bind(cfg.listen).map_err(listen_err)?;
        std_listener.set_nonblocking(true).map_err(listen_err)?;
        let local_addr = std_listener.local_addr().map_err(listen_err)?;
        let listener = {
            let _in_rt = rt.enter();
            TcpListener::from_std(std_listener).map_err(listen_err)?
        };

        let schedule = FaultSchedule::new(cfg.faults.clone());
        let held = cfg.faults_held;
        // Held, the relay forwards (epoch 0) until the schedule begins.
        let initial = if held {
            Control {
                state: RelayState::Forwarding,
                epoch: 0,
            }
        } else {
            schedule.control_at(Duration::ZERO)
        };
        let counters = Arc::new(Counters::new(initial.state));
        let (control_tx, control_rx) = watch::channel(initial);
        tracing::info!(
            "relay: {local_addr} → {}, up: {}, down: {}, faults: {}",
            cfg.upstream,
            cfg.up,
            cfg.down,
            if cfg.faults.is_empty() {
                "none".to_string()
            } else {
                cfg.faults
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(",")
            }
        );
        let shared = Arc::new(Shared {
            cfg,
            counters: counters.clone(),
        });
        let (begin_tx, begin_rx) = oneshot::channel();
        let origin = std::sync::OnceLock::new();
        let begin = if held {
            Some(begin_tx)
        } else {
            let now = std::time::Instant::now();
            let _ = origin.set(now);
            let _ = begin_tx.send(now);
            None
        };
        let schedule_counters = counters.clone();
        rt.spawn(async move {
            match begin_rx.await {
                Ok(at) => {
                    let at = tokio::time::Instant::from_std(at);
                    run_schedule(schedule, at, control_tx, schedule_counters).await;
                }
                // The relay is going away before its schedule began: keep the channel open
                // while the connections' tasks are dropped.
                Err(_) => std::future::pending::<()>().await,
            }
        });
        rt.spawn(accept_loop(listener, shared, control_rx));
        Ok(Relay {
            rt: Some(rt),
            local_addr,
            origin,
            begin: std::sync::Mutex::new(begin),
            counters,
        })
    }

    /// Begins a held fault schedule now and returns its origin; the origin it already has
    /// otherwise (a schedule that was not held began at the relay's start).
    pub fn begin_faults(&self) -> std::time::Instant {
        *self.origin.get_or_init(|| {
            let now = std::time::Instant::now();
            let sender = self.begin.lock().unwrap_or_else(|p| p.into_inner()).take();
            if let Some(tx) = sender {
                let _ = tx.send(now);
            }
            tracing::info!("relay: fault schedule begins");
            now
        })
    }

    /// The address it listens on (the port chosen, if `listen` had port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The fault schedule's origin: the moment it began (`None` while it is held).
    pub fn origin(&self) -> Option<std::time::Instant> {
        self.origin.get().copied()
    }

    /// The counters now.
    pub fn stats(&self) -> RelayStats {
        self.counters.snapshot()
    }

    /// What the fault schedule says now.
    pub fn state(&self) -> RelayState {
        self.counters.state()
    }

    /// Stops listening and closes every connection; waits up to a second for its threads
    /// (not at all when called on an async runtime's thread).
    pub fn shutdown(mut self) {
        self.stop();
    }

    fn stop(&mut self) {
        if let Some(rt) = self.rt.take() {
            if tokio::runtime::Handle::try_current().is_ok() {
                rt.shutdown_background();
            } else {
                rt.shutdown_timeout(Duration::from_secs(1));
            }
            tracing::debug!("relay: {} stopped", self.local_addr);
        }
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Publishes the schedule's state and abort epoch at each of its boundaries; keeps the
/// channel open afterwards.
async fn run_schedule(
    schedule: FaultSchedule,
    origin: tokio::time::Instant,
    control: watch::Sender<Control>,
    counters: Arc<Counters>,
) {
    let mut previous: Option<Duration> = None;
    loop {
        let t = origin.elapsed();
        for f in schedule.starting_in(previous, t) {
            tracing::info!("relay: fault {f} starts");
        }
        let now = schedule.control_at(t);
        let before = *control.borrow();
        if now.state != before.state {
            tracing::info!("relay: {:?} → {:?}", before.state, now.state);
        }
        // In one update with the state: whoever reads the state finds the connections told,
        // and whoever sees a connection obey it finds the state.
        counters.set_state_telling(now.state, || {
            control.send_replace(now);
        });
        previous = Some(t);
        match schedule.next_boundary_after(t) {
            Some(b) => tokio::time::sleep_until(origin + b).await,
            None => break,
        }
    }
    // The receivers wait on the channel: it must outlive them.
    std::future::pending::<()>().await;
}

/// Accepts connections: refused (aborted at once) during a partition, otherwise relayed.
async fn accept_loop(
    listener: TcpListener,
    shared: Arc<Shared>,
    control: watch::Receiver<Control>,
) {
    let mut next_id: u64 = 0;
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(accepted) => accepted,
            Err(e) => {
                // Out of descriptors and the like: pass, as a server does.
                tracing::warn!("relay: accept failed: {e}");
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        let now = *control.borrow();
        if now.state == RelayState::Partitioned {
            tracing::debug!("relay: connection from {peer} refused: partitioned");
            shared.counters.refused();
            conn::abort(stream);
            continue;
        }
        let conn = shared.counters.accept();
        let id = next_id;
        next_id += 1;
        tracing::debug!("relay: connection {id} from {peer}");
        tokio::spawn(conn::serve(
            stream,
            peer,
            (id, now.epoch, conn),
            shared.clone(),
            control.clone(),
        ));
    }
}
