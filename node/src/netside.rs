//! A node's network side: a tokio runtime with two worker threads (`dupac-net`) on which the
//! node's zenoh I/O runs as tasks — decoding received chunks, publishing weights, chunks and
//! stats, answering weight queries — apart from the compute threads (the PPO update, the
//! environments), which hand it encoded messages and go on without waiting for the network.
//!
//! zenoh's receive callbacks stay on zenoh's own (tokio) runtime: they only check sizes and
//! queue bytes or update a table, never block and never do I/O (a blocked callback stalls
//! zenoh's receive path; a `Block` sender stalled 5 s loses its transport).
//!
//! zenoh 1.10's `put(..).await` and `reply(..).await` run its blocking call in place: a
//! `Block` publication (an actor's chunks) held up by a slow peer occupies the worker it runs
//! on; the learner's weights replies therefore run on blocking threads of their own
//! ([`crate::weights_server`]). Two workers
//! keep the decode task going beside it, and the decode task yields after each message so
//! that a backlog does not hold back the publishers.

use crate::intake::WeightsKey;
use crate::outbox::Delivery;
use std::future::Future;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;
use zenoh::pubsub::Publisher;

/// The runtime of a node's network side and its tasks.
pub(crate) struct NetSide {
    rt: tokio::runtime::Runtime,
    tasks: Vec<JoinHandle<()>>,
}

impl NetSide {
    /// A runtime of two worker threads named `dupac-net`.
    pub(crate) fn new() -> std::io::Result<NetSide> {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("dupac-net")
            .enable_time()
            .build()?;
        Ok(NetSide {
            rt,
            tasks: Vec::new(),
        })
    }

    /// Runs `task` on the network side until it ends or the node finishes.
    pub(crate) fn spawn(&mut self, task: impl Future<Output = ()> + Send + 'static) {
        self.tasks.push(self.rt.spawn(task));
    }

    /// Waits up to `timeout` for every task to end (the caller has closed their inputs, so
    /// they drain what is queued and stop), then drops the runtime and whatever still runs.
    pub(crate) fn finish(self, timeout: Duration) {
        let NetSide { rt, tasks } = self;
        rt.block_on(async {
            let all = async {
                for t in tasks {
                    let _ = t.await;
                }
            };
            if tokio::time::timeout(timeout, all).await.is_err() {
                tracing::warn!("network tasks still busy after {timeout:?}: dropped");
            }
        });
        rt.shutdown_background();
    }
}

/// A message for a newest-only publication, numbered so that the last one set is published even
/// when the setter closes right after (weights, stats: a newer message replaces one not yet sent).
type Numbered = Option<(u64, zenoh::bytes::ZBytes)>;

/// The compute side of a newest-only publication: [`Latest::set`] never waits; the task of
/// [`Latest::start`] publishes the newest message set, skipping those it had no time for.
pub(crate) struct Latest {
    tx: watch::Sender<Numbered>,
}

impl Latest {
    /// Starts the publishing task of `publisher` on `net`. `what` names the messages in logs.
    pub(crate) fn start(
        net: &mut NetSide,
        publisher: Publisher<'static>,
        what: &'static str,
    ) -> Latest {
        let (tx, mut rx) = watch::channel::<Numbered>(None);
        net.spawn(async move {
            let mut sent = 0u64;
            loop {
                let closed = rx.changed().await.is_err();
                let newest = rx.borrow_and_update().clone();
                if let Some((seq, bytes)) = newest
                    && seq != sent
                {
                    sent = seq;
                    if let Err(e) = publisher.put(bytes).await {
                        tracing::warn!("{what} not published: {e}");
                    }
                }
                if closed {
                    break;
                }
            }
        });
        Latest { tx }
    }

    /// Hands `bytes` to the publishing task (replacing a message it has not sent yet).
    pub(crate) fn set(&self, bytes: Vec<u8>) {
        self.set_bytes(bytes.into());
    }

    /// [`Latest::set`] with bytes already in zenoh's form (shared, not copied).
    pub(crate) fn set_bytes(&self, bytes: zenoh::bytes::ZBytes) {
        // Delivered even when the task is gone (the runtime shut down): then nobody reads it.
        self.tx.send_modify(|m| {
            let seq = m.as_ref().map_or(0, |(s, _)| *s) + 1;
            *m = Some((seq, bytes));
        });
    }
}

/// A trajectory chunk for [`Every`]: its bytes, sequence number and the weights it was acted
/// with.
pub(crate) struct Outgoing {
    pub(crate) bytes: Vec<u8>,
    pub(crate) seq: u64,
    pub(crate) key: WeightsKey,
}

/// The compute side of a publication where every message counts (trajectory chunks):
/// [`Every::send`] waits only while `depth` messages are already queued (backpressure, as
/// `CongestionControl::Block` gives); the task publishes them in order, except those that
/// turned stale while queued ([`Delivery::admit`]), and records in `delivery` which left last.
pub(crate) struct Every {
    tx: mpsc::Sender<Outgoing>,
}

impl Every {
    pub(crate) fn start(
        net: &mut NetSide,
        publisher: Publisher<'static>,
        depth: usize,
        delivery: Arc<Mutex<Delivery>>,
        what: &'static str,
    ) -> Every {
        let (tx, mut rx) = mpsc::channel::<Outgoing>(depth.max(1));
        net.spawn(async move {
            while let Some(m) = rx.recv().await {
                let send = delivery
                    .lock()
                    .map(|mut d| d.admit(m.seq, m.key, Instant::now()))
                    .unwrap_or(true);
                if !send {
                    tracing::debug!(
                        seq = m.seq,
                        version = m.key.version,
                        "stale {what} not sent"
                    );
                    continue;
                }
                if let Err(e) = publisher.put(m.bytes).await {
                    tracing::warn!("{what} not published: {e}");
                }
                if let Ok(mut d) = delivery.lock() {
                    d.sent(m.seq, Instant::now());
                }
            }
        });
        Every { tx }
    }

    /// Queues `m` for publication; waits while the queue is full. Errors when the task is
    /// gone (the runtime shut down).
    pub(crate) fn send(&self, m: Outgoing) -> Result<(), String> {
        self.tx
            .blocking_send(m)
            .map_err(|_| "the network side has stopped".to_string())
    }
}
