//! The learner's answers to weights queries. No zenoh here: the node hands over its queries
//! behind [`WeightsQuery`], so the rules are tested on their own.
//!
//! * **What is answered**: a query that names the learner's newest weights in its `held`
//!   parameter ([`dupac_common::msg::HELD_PARAMETER`]) gets the small
//!   [`dupac_common::msg::WeightsHeld`] (the header alone); any other query gets the full
//!   weights message. An actor that has heard no weights for a while asks
//!   ([`crate::ask_clock`]): on a slow link the full weights (≈ 0.4 MB) every time would fill it.
//! * **Replies do not wait on each other**: each reply runs on a blocking thread of its own, at
//!   most `parallel` at a time (zenoh's reply blocks while the asker's link is full: one slow
//!   asker must not hold back the others). Queries beyond that wait in the node's bounded
//!   queue, and beyond the queue go unanswered (the asker asks again).

use dupac_common::msg::parse_held;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use tokio::sync::{Semaphore, mpsc, watch};

/// The newest weights the learner serves: their key and both answers, encoded once.
#[derive(Debug, Clone)]
pub struct Served<B> {
    /// Learner incarnation and policy version of the weights.
    pub incarnation: u64,
    pub version: u64,
    /// The weights message.
    pub full: B,
    /// The [`dupac_common::msg::WeightsHeld`] message of these weights.
    pub held: B,
}

impl<B: Clone> Served<B> {
    /// The answer to a query whose `held` parameter is `held` (absent or malformed: none held):
    /// the small message when it names these weights (`true`), else the full one.
    pub fn answer(&self, held: Option<&str>) -> (B, bool) {
        match held.and_then(parse_held) {
            Some(k) if k == (self.incarnation, self.version) => (self.held.clone(), true),
            _ => (self.full.clone(), false),
        }
    }
}

/// A weights query as the server sees it.
pub trait WeightsQuery: Send + 'static {
    /// The reply's bytes (cheap to clone).
    type Bytes: Clone + Send + Sync + 'static;
    /// The query's `held` parameter, if any.
    fn held(&self) -> Option<String>;
    /// Sends the reply; may block while the asker's link is full.
    fn reply(self, bytes: Self::Bytes) -> Result<(), String>;
}

/// Replies sent, by kind ([`crate::learner::LearnerNode::weights_replies`]).
#[derive(Debug, Default)]
pub struct ReplyCounts {
    /// Full weights messages.
    pub full: AtomicU64,
    /// [`dupac_common::msg::WeightsHeld`] messages.
    pub held: AtomicU64,
}

impl ReplyCounts {
    /// (full, held) so far.
    pub fn get(&self) -> (u64, u64) {
        (
            self.full.load(Ordering::Relaxed),
            self.held.load(Ordering::Relaxed),
        )
    }
}

/// Answers the queries of `queries` with the newest of `served` (none before the first
/// weights), each reply on a blocking thread of its own, at most `parallel` at a time; ends when
/// `queries` closes. Runs on a tokio runtime with blocking threads (the node's network side).
pub async fn serve<Q: WeightsQuery>(
    mut queries: mpsc::Receiver<Q>,
    served: watch::Receiver<Option<Served<Q::Bytes>>>,
    parallel: usize,
    counts: Arc<ReplyCounts>,
) {
    let permits = Arc::new(Semaphore::new(parallel.max(1)));
    while let Some(query) = queries.recv().await {
        let Ok(permit) = permits.clone().acquire_owned().await else {
            break;
        };
        // The newest weights once a reply slot is free (not those of when the query came).
        let newest = served.borrow().clone();
        let Some(newest) = newest else {
            tracing::debug!("weights query left unanswered: no weights yet");
            continue;
        };
        let (bytes, small) = newest.answer(query.held().as_deref());
        let counts = counts.clone();
        tokio::task::spawn_blocking(move || {
            match query.reply(bytes) {
                Ok(()) if small => counts.held.fetch_add(1, Ordering::Relaxed),
                Ok(()) => counts.full.fetch_add(1, Ordering::Relaxed),
                Err(e) => {
                    tracing::warn!("weights query: cannot reply: {e}");
                    0
                }
            };
            drop(permit);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc as std_mpsc;
    use std::time::Duration;

    fn served() -> Served<&'static str> {
        Served {
            incarnation: 7,
            version: 12,
            full: "FULL",
            held: "held",
        }
    }

    #[test]
    fn a_query_holding_the_newest_weights_gets_the_small_reply() {
        let s = served();
        assert_eq!(s.answer(Some("7.12")), ("held", true));
        assert_eq!(s.answer(Some("7.11")), ("FULL", false), "an older version");
        assert_eq!(
            s.answer(Some("8.12")),
            ("FULL", false),
            "another incarnation"
        );
        assert_eq!(s.answer(Some("7.12x")), ("FULL", false), "malformed");
        assert_eq!(s.answer(None), ("FULL", false), "nothing held");
    }

    /// A query whose reply blocks until `release` says so, and reports what it sent.
    struct TestQuery {
        held: Option<String>,
        release: Option<std_mpsc::Receiver<()>>,
        sent: std_mpsc::Sender<(&'static str, &'static str)>,
        name: &'static str,
    }

    impl WeightsQuery for TestQuery {
        type Bytes = &'static str;
        fn held(&self) -> Option<String> {
            self.held.clone()
        }
        fn reply(self, bytes: &'static str) -> Result<(), String> {
            if let Some(r) = self.release {
                r.recv().map_err(|e| e.to_string())?;
            }
            self.sent
                .send((self.name, bytes))
                .map_err(|e| e.to_string())
        }
    }

    /// A slow asker's reply (blocked on its link) does not hold back the next asker's; each gets
    /// the answer its `held` parameter asks for.
    #[test]
    fn a_slow_asker_delays_no_other_reply() {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .build()
            .expect("runtime");
        let (qtx, qrx) = mpsc::channel(8);
        let (_stx, srx) = watch::channel(Some(served()));
        let counts = Arc::new(ReplyCounts::default());
        let task = rt.spawn(serve(qrx, srx, 4, counts.clone()));
        let (sent_tx, sent) = std_mpsc::channel();
        let (release_slow, slow_link) = std_mpsc::channel();
        let query = |name, held: Option<&str>, release| TestQuery {
            held: held.map(str::to_string),
            release,
            sent: sent_tx.clone(),
            name,
        };
        qtx.blocking_send(query("slow", None, Some(slow_link)))
            .expect("queued");
        qtx.blocking_send(query("fast", Some("7.12"), None))
            .expect("queued");
        let first = sent.recv_timeout(Duration::from_secs(10));
        assert_eq!(
            first,
            Ok(("fast", "held")),
            "the second asker is answered while the first one's reply is still blocked"
        );
        release_slow.send(()).expect("slow reply waits");
        assert_eq!(
            sent.recv_timeout(Duration::from_secs(10)),
            Ok(("slow", "FULL"))
        );
        drop(qtx);
        rt.block_on(task).expect("the server ends with its queue");
        // The counts follow each reply on its own thread.
        let t0 = std::time::Instant::now();
        while counts.get() != (1, 1) && t0.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert_eq!(counts.get(), (1, 1));
    }

    #[test]
    fn no_reply_before_the_first_weights() {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .build()
            .expect("runtime");
        let (qtx, qrx) = mpsc::channel(8);
        let (stx, srx) = watch::channel(None);
        let counts = Arc::new(ReplyCounts::default());
        let task = rt.spawn(serve(qrx, srx, 1, counts.clone()));
        let (sent_tx, sent) = std_mpsc::channel();
        let query = || TestQuery {
            held: None,
            release: None,
            sent: sent_tx.clone(),
            name: "q",
        };
        qtx.blocking_send(query()).expect("queued");
        assert!(sent.recv_timeout(Duration::from_millis(300)).is_err());
        stx.send_replace(Some(served()));
        qtx.blocking_send(query()).expect("queued");
        assert_eq!(
            sent.recv_timeout(Duration::from_secs(10)),
            Ok(("q", "FULL"))
        );
        drop(qtx);
        rt.block_on(task).expect("ends");
    }
}
