//! One direction of a relayed connection: the impairment pipe from a socket's read half to the
//! other socket's write half.
//!
//! A reader reads chunks of at most [`crate::RelayConfig::read_chunk_bytes`] and queues each with
//! a release instant `arrival + delay + U[-jitter, +jitter]` (never before its arrival), raised
//! to the previous chunk's release instant so that release instants never decrease: TCP is a
//! byte stream, the relay must not reorder it. A writer takes the chunks in order, waits for each
//! one's release, for the end of any stall, and for the token bucket (the rate cap), then writes
//! it. The end of the stream (EOF) is queued like a chunk and becomes a write shutdown (FIN).
//!
//! Memory is bounded whatever the peers send: the queue holds at most
//! [`crate::RelayConfig::max_queued_bytes`] (each chunk counted with a small per-chunk overhead),
//! enforced by a semaphore the reader must acquire a full read's worth from before reading:
//! when the queue is full the reader stops, the kernel's buffers fill, and TCP's flow control
//! slows the sender.

use std::io;
use std::sync::Arc;
use std::time::Duration;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::sync::{OwnedSemaphorePermit, Semaphore, mpsc, watch};
use tokio::time::Instant;

use crate::fault::{Control, RelayState};
use crate::stats::{Counters, Side};

/// The impairment of one direction: a one-way delay with jitter and an optional rate cap.
/// The default impairs nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct LinkImpairment {
    /// One-way delay added to every chunk, in milliseconds.
    pub delay_ms: u64,
    /// Half-width of the uniform jitter around the delay, in milliseconds (the delay drawn is
    /// in `[delay - jitter, delay + jitter]`, clamped at 0).
    pub jitter_ms: u64,
    /// Rate cap in bytes per second (10 Mbit/s = 1 250 000); `None`: uncapped.
    pub rate_bytes_per_s: Option<u64>,
    /// Token bucket size in bytes: what may go at once after an idle spell; `None`: one read
    /// chunk ([`crate::RelayConfig::read_chunk_bytes`]). Only meaningful with a rate.
    pub burst_bytes: Option<u64>,
}

impl LinkImpairment {
    /// No impairment.
    pub const NONE: LinkImpairment = LinkImpairment {
        delay_ms: 0,
        jitter_ms: 0,
        rate_bytes_per_s: None,
        burst_bytes: None,
    };

    /// A delay with jitter, uncapped.
    pub fn delay(delay_ms: u64, jitter_ms: u64) -> LinkImpairment {
        LinkImpairment {
            delay_ms,
            jitter_ms,
            ..LinkImpairment::NONE
        }
    }

    /// This with a rate cap in bytes per second.
    pub fn with_rate(self, rate_bytes_per_s: u64) -> LinkImpairment {
        LinkImpairment {
            rate_bytes_per_s: Some(rate_bytes_per_s),
            ..self
        }
    }

    /// Why it cannot be used, if so.
    pub fn check(&self) -> Result<(), String> {
        if self.rate_bytes_per_s == Some(0) {
            return Err("a rate of 0 bytes/s forwards nothing".into());
        }
        if self.burst_bytes == Some(0) {
            return Err("a burst of 0 bytes forwards nothing".into());
        }
        Ok(())
    }
}

/// Bytes each queued chunk is charged on top of its payload (its allocation and bookkeeping),
/// so that a flood of tiny chunks is bounded too.
pub(crate) const CHUNK_OVERHEAD_BYTES: usize = 64;

/// The largest piece the writer writes at once under a rate cap, so that the cap paces the
/// stream rather than letting whole read chunks go at bucket-refill intervals.
const PACED_PIECE_BYTES: usize = 16 * 1024;

/// Draws each chunk's delay: `delay + U[-jitter, +jitter]`, at least 0, deterministic from the
/// relay's seed and the stream (connection and direction).
pub(crate) struct DelayDraw {
    delay_us: i64,
    jitter_us: i64,
    rng: ChaCha8Rng,
}

impl DelayDraw {
    pub(crate) fn new(imp: &LinkImpairment, seed: u64, stream: u64) -> DelayDraw {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        let us = |ms: u64| i64::try_from(ms.saturating_mul(1000)).unwrap_or(i64::MAX);
        DelayDraw {
            delay_us: us(imp.delay_ms),
            jitter_us: us(imp.jitter_ms),
            rng,
        }
    }

    pub(crate) fn draw(&mut self) -> Duration {
        let offset = if self.jitter_us > 0 {
            self.rng.random_range(-self.jitter_us..=self.jitter_us)
        } else {
            0
        };
        let us = self.delay_us.saturating_add(offset).max(0);
        Duration::from_micros(us as u64)
    }
}

/// Release instants of one direction's chunks: `arrival + drawn delay`, raised to the
/// previous chunk's release so that they never decrease (the writer takes chunks in order too;
/// this keeps the instants honest about when each chunk goes).
pub(crate) struct ReleaseClock {
    delays: DelayDraw,
    last: Option<Instant>,
}

impl ReleaseClock {
    pub(crate) fn new(delays: DelayDraw) -> ReleaseClock {
        ReleaseClock { delays, last: None }
    }

    /// When a chunk that arrived at `arrival` may go.
    pub(crate) fn release(&mut self, arrival: Instant) -> Instant {
        let drawn = arrival + self.delays.draw();
        let release = self.last.map_or(drawn, |last| drawn.max(last));
        self.last = Some(release);
        release
    }
}

/// A token bucket: `rate` bytes per second, at most `burst` bytes saved up; starts full.
pub(crate) struct TokenBucket {
    rate_bytes_per_s: f64,
    burst_bytes: f64,
    tokens: f64,
    /// When `tokens` was last brought up to date (may lie ahead of now: a reservation).
    at: Instant,
}

impl TokenBucket {
    pub(crate) fn new(rate_bytes_per_s: u64, burst_bytes: u64, now: Instant) -> TokenBucket {
        TokenBucket {
            rate_bytes_per_s: rate_bytes_per_s as f64,
            burst_bytes: burst_bytes as f64,
            tokens: burst_bytes as f64,
            at: now,
        }
    }

    /// Reserves `n` bytes (at most the burst) and returns when they may go.
    pub(crate) fn reserve(&mut self, n: usize, now: Instant) -> Instant {
        let n = n as f64;
        debug_assert!(n <= self.burst_bytes + 0.5);
        let base = now.max(self.at);
        let refill = base.duration_since(self.at).as_secs_f64() * self.rate_bytes_per_s;
        self.tokens = (self.tokens + refill).min(self.burst_bytes);
        self.at = base;
        if self.tokens >= n {
            self.tokens -= n;
            return base;
        }
        let wait = Duration::from_secs_f64((n - self.tokens) / self.rate_bytes_per_s);
        self.tokens = 0.0;
        self.at = base + wait;
        self.at
    }
}

/// One direction's settings, as [`pipe`] takes them.
pub(crate) struct Direction {
    pub(crate) imp: LinkImpairment,
    pub(crate) read_chunk_bytes: usize,
    pub(crate) max_queued_bytes: usize,
    pub(crate) delays: DelayDraw,
    pub(crate) counters: Arc<Counters>,
    pub(crate) side: Side,
    pub(crate) control: watch::Receiver<Control>,
}

/// A queued chunk; empty is the end of the stream. Holds its share of the queue bound until
/// dropped (written or discarded).
struct Chunk {
    data: Vec<u8>,
    release: Instant,
    _permit: OwnedSemaphorePermit,
    counters: Arc<Counters>,
    side: Side,
}

impl Drop for Chunk {
    fn drop(&mut self) {
        self.counters.sub_queued(self.side, self.data.len());
    }
}

/// Forwards `rd` to `wr` with the direction's impairment until the end of the stream (then
/// shuts `wr` down) or an I/O error.
pub(crate) async fn pipe<R, W>(rd: &mut R, wr: &mut W, dir: Direction) -> io::Result<()>
where
    R: AsyncRead + Unpin,
    W: AsyncWrite + Unpin,
{
    let Direction {
        imp,
        read_chunk_bytes,
        max_queued_bytes,
        delays,
        counters,
        side,
        mut control,
    } = dir;
    let queue_bound = Arc::new(Semaphore::new(max_queued_bytes));
    let (tx, mut rx) = mpsc::unbounded_channel::<Chunk>();

    let reader = async {
        let mut buf = vec![0u8; read_chunk_bytes];
        let mut clock = ReleaseClock::new(delays);
        // A full read's worth (plus overhead) is acquired before reading, the unused rest
        // given back after: the queue never exceeds the bound.
        let charge = u32::try_from(read_chunk_bytes + CHUNK_OVERHEAD_BYTES)
            .map_err(|_| io::Error::other("read chunk too large"))?;
        loop {
            let mut permit = queue_bound
                .clone()
                .acquire_many_owned(charge)
                .await
                .map_err(|_| io::Error::other("queue closed"))?;
            let n = rd.read(&mut buf).await?;
            let release = clock.release(Instant::now());
            let kept = permit
                .split(n + CHUNK_OVERHEAD_BYTES)
                .expect("the permit covers a full read");
            drop(permit);
            counters.add_read(side, n);
            let chunk = Chunk {
                data: buf[..n].to_vec(),
                release,
                _permit: kept,
                counters: counters.clone(),
                side,
            };
            if tx.send(chunk).is_err() {
                return Ok(()); // the writer has ended (with an error, which the join reports)
            }
            if n == 0 {
                return Ok(());
            }
        }
    };

    let writer = async {
        let now = Instant::now();
        let mut bucket = imp.rate_bytes_per_s.map(|rate| {
            let burst = imp.burst_bytes.unwrap_or(read_chunk_bytes as u64);
            TokenBucket::new(rate, burst, now)
        });
        let piece_bytes = match imp.rate_bytes_per_s {
            None => read_chunk_bytes,
            Some(_) => {
                let burst = imp.burst_bytes.unwrap_or(read_chunk_bytes as u64);
                PACED_PIECE_BYTES.min(usize::try_from(burst).unwrap_or(usize::MAX))
            }
        };
        while let Some(chunk) = rx.recv().await {
            tokio::time::sleep_until(chunk.release).await;
            if chunk.data.is_empty() {
                wait_while_stalled(&mut control).await;
                wr.shutdown().await?;
                return Ok(());
            }
            for piece in chunk.data.chunks(piece_bytes) {
                wait_while_stalled(&mut control).await;
                if let Some(b) = bucket.as_mut() {
                    tokio::time::sleep_until(b.reserve(piece.len(), Instant::now())).await;
                }
                wr.write_all(piece).await?;
                counters.add_forwarded(side, piece.len());
            }
        }
        Ok(())
    };

    tokio::try_join!(reader, writer).map(|_| ())
}

/// Returns once the relay is not stalled (at once if it is not); waits forever if the relay
/// is going away (its connections are being dropped).
async fn wait_while_stalled(control: &mut watch::Receiver<Control>) {
    if control
        .wait_for(|c| c.state != RelayState::Stalled)
        .await
        .is_err()
    {
        std::future::pending::<()>().await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delays_stay_within_the_jitter_and_repeat_with_the_seed() {
        let imp = LinkImpairment::delay(50, 20);
        let draws = |seed, stream| {
            let mut d = DelayDraw::new(&imp, seed, stream);
            (0..1000).map(|_| d.draw()).collect::<Vec<_>>()
        };
        let a = draws(7, 0);
        assert!(
            a.iter()
                .all(|d| (Duration::from_millis(30)..=Duration::from_millis(70)).contains(d))
        );
        assert!(a.iter().any(|d| *d < Duration::from_millis(35)));
        assert!(a.iter().any(|d| *d > Duration::from_millis(65)));
        assert_eq!(a, draws(7, 0));
        assert_ne!(a, draws(7, 1));
        assert_ne!(a, draws(8, 0));
    }

    #[test]
    fn jitter_larger_than_the_delay_never_goes_negative() {
        let mut d = DelayDraw::new(&LinkImpairment::delay(5, 50), 1, 0);
        let all: Vec<_> = (0..1000).map(|_| d.draw()).collect();
        assert!(all.contains(&Duration::ZERO));
        assert!(all.iter().all(|d| *d <= Duration::from_millis(55)));
    }

    /// Chunks 1 ms apart with 50 ± 20 ms: drawn alone, later ones would often go first.
    #[test]
    fn release_instants_never_decrease() {
        let mut clock = ReleaseClock::new(DelayDraw::new(&LinkImpairment::delay(50, 20), 3, 0));
        let t0 = Instant::now();
        let releases: Vec<Instant> = (0..1000)
            .map(|i| clock.release(t0 + Duration::from_millis(i)))
            .collect();
        assert!(
            releases.windows(2).all(|w| w[0] <= w[1]),
            "a release went back"
        );
        for (i, r) in releases.iter().enumerate() {
            let arrival = t0 + Duration::from_millis(i as u64);
            assert!(*r >= arrival + Duration::from_millis(30));
        }
        // Not all clamped to one instant: a fifth still keep their own later draw.
        let rising = releases.windows(2).filter(|w| w[0] < w[1]).count();
        assert!(rising > 100, "{rising}");
    }

    #[test]
    fn token_bucket_paces_after_the_burst() {
        let t0 = Instant::now();
        let mut b = TokenBucket::new(250_000, 65_536, t0);
        // 500 000 bytes at once in 16 KiB pieces: the burst goes at once, the rest at the rate.
        let mut sent = 0usize;
        let mut last = t0;
        while sent < 500_000 {
            let n = (500_000 - sent).min(16_384);
            last = b.reserve(n, t0);
            sent += n;
        }
        let took = last.duration_since(t0).as_secs_f64();
        let expected = (500_000.0 - 65_536.0) / 250_000.0;
        assert!((took - expected).abs() < 1e-3, "{took} vs {expected}");
        // After an idle spell the bucket is full again, but never above the burst.
        let later = last + Duration::from_secs(100);
        assert_eq!(b.reserve(65_536, later), later);
        assert!(b.reserve(1, later) > later);
    }
}
