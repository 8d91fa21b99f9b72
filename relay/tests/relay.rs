//! The relay end to end over loopback, with plain blocking sockets as its peers: delays and
//! order, the rate cap, the queue bound, and each scheduled fault. Timings are asserted as lower
//! bounds only (a loaded machine is slower, never faster), with deadlines that are generous.

use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

use dupac_relay::{Fault, LinkImpairment, Relay, RelayConfig, RelayState, RelayStats};

/// A loopback address with any free port.
fn any_port() -> SocketAddr {
    "127.0.0.1:0".parse().unwrap()
}

/// An upstream that echoes every connection, counting the connections it accepted.
struct Echo {
    addr: SocketAddr,
    accepted: Arc<AtomicUsize>,
}

fn echo_server() -> Echo {
    let listener = TcpListener::bind(any_port()).unwrap();
    let addr = listener.local_addr().unwrap();
    let accepted = Arc::new(AtomicUsize::new(0));
    let count = accepted.clone();
    thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            count.fetch_add(1, Ordering::SeqCst);
            thread::spawn(move || {
                let _ = stream.set_nodelay(true);
                let mut buf = [0u8; 65536];
                loop {
                    match stream.read(&mut buf) {
                        Ok(0) | Err(_) => return,
                        Ok(n) => {
                            if stream.write_all(&buf[..n]).is_err() {
                                return;
                            }
                        }
                    }
                }
            });
        }
    });
    Echo { addr, accepted }
}

/// An upstream that reads each connection to its end and reports (bytes, when the last one
/// came).
fn sink_server() -> (SocketAddr, mpsc::Receiver<(Vec<u8>, Instant)>) {
    let listener = TcpListener::bind(any_port()).unwrap();
    let addr = listener.local_addr().unwrap();
    let (tx, rx) = mpsc::channel();
    thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            let tx = tx.clone();
            thread::spawn(move || {
                let mut all = vec![];
                let mut buf = [0u8; 65536];
                let mut last = Instant::now();
                loop {
                    match stream.read(&mut buf) {
                        Ok(0) | Err(_) => break,
                        Ok(n) => {
                            all.extend_from_slice(&buf[..n]);
                            last = Instant::now();
                        }
                    }
                }
                let _ = tx.send((all, last));
            });
        }
    });
    (addr, rx)
}

fn start(cfg: RelayConfig) -> Relay {
    Relay::start(cfg).expect("relay starts")
}

/// A client of the relay, with a read deadline so that a broken relay fails the test rather
/// than hanging it.
fn connect(relay: &Relay) -> TcpStream {
    let s = TcpStream::connect(relay.local_addr()).unwrap();
    s.set_nodelay(true).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s
}

/// Reads exactly `n` bytes or panics.
fn read_n(s: &mut TcpStream, n: usize) -> Vec<u8> {
    let mut buf = vec![0u8; n];
    s.read_exact(&mut buf).expect("the bytes come back");
    buf
}

/// Whether the relay has closed `s` (EOF or a reset) rather than sending data; panics if
/// neither happens within the read deadline.
fn is_closed(s: &mut TcpStream) -> bool {
    let mut buf = [0u8; 1];
    match s.read(&mut buf) {
        Ok(0) => true,
        Ok(_) => false,
        Err(e) if e.kind() == ErrorKind::WouldBlock || e.kind() == ErrorKind::TimedOut => {
            panic!("neither data nor a close within the deadline")
        }
        Err(_) => true,
    }
}

/// The relay's counters once `done` holds of them (or after 5 s, for the caller to assert).
fn eventually(relay: &Relay, done: impl Fn(&RelayStats) -> bool) -> RelayStats {
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let s = relay.stats();
        if done(&s) || Instant::now() > deadline {
            return s;
        }
        thread::sleep(ms(2));
    }
}

fn ms(v: u64) -> Duration {
    Duration::from_millis(v)
}

#[test]
fn round_trip_takes_both_delays() {
    let echo = echo_server();
    let relay =
        start(RelayConfig::new(any_port(), echo.addr).with_links(LinkImpairment::delay(50, 0)));
    let mut c = connect(&relay);
    for round in 0..3u8 {
        let t0 = Instant::now();
        c.write_all(&[round; 10]).unwrap();
        assert_eq!(read_n(&mut c, 10), [round; 10]);
        let rtt = t0.elapsed();
        assert!(rtt >= ms(100), "round trip {rtt:?} under 2 × 50 ms");
    }
    // The relay counts a write after it returns, which the peer may see first (both ways).
    let s = eventually(&relay, |s| {
        s.down.bytes_forwarded == 30 && s.up.bytes_forwarded == 30
    });
    assert_eq!((s.up.bytes_forwarded, s.down.bytes_forwarded), (30, 30));
    assert_eq!(s.connections_accepted, 1);
}

/// Many small writes 1 ms apart through 50 ± 20 ms each way: each is its own chunk with its own
/// drawn delay, yet the stream comes back identical and in order.
#[test]
fn jitter_keeps_the_stream_in_order() {
    let echo = echo_server();
    let relay = start(RelayConfig {
        seed: 42,
        ..RelayConfig::new(any_port(), echo.addr).with_links(LinkImpairment::delay(50, 20))
    });
    let mut c = connect(&relay);
    let mut reader = c.try_clone().unwrap();
    let n = 200u32;
    let got = thread::spawn(move || read_n(&mut reader, 4 * n as usize));
    let mut sent = vec![];
    for i in 0..n {
        let b = i.to_be_bytes();
        c.write_all(&b).unwrap();
        sent.extend_from_slice(&b);
        thread::sleep(ms(1));
    }
    let got = got.join().unwrap();
    let first_bad = got.chunks(4).zip(sent.chunks(4)).position(|(g, s)| g != s);
    assert_eq!(first_bad, None, "the stream came back reordered");
    assert_eq!(got, sent);
}

/// 500 kB through a 2 Mbit/s (250 kB/s) cap with its 64 KiB burst: at least
/// (500 000 − 65 536) / 250 000 ≈ 1.74 s.
#[test]
fn rate_cap_bounds_throughput() {
    let (sink, received) = sink_server();
    let cfg = RelayConfig {
        up: LinkImpairment::NONE.with_rate(250_000),
        ..RelayConfig::new(any_port(), sink)
    };
    let relay = start(cfg);
    let mut c = connect(&relay);
    let data: Vec<u8> = (0..500_000u32).map(|i| (i % 251) as u8).collect();
    let t0 = Instant::now();
    c.write_all(&data).unwrap();
    c.shutdown(Shutdown::Write).unwrap();
    let (got, last) = received.recv_timeout(Duration::from_secs(8)).unwrap();
    let took = last.duration_since(t0);
    assert_eq!(got.len(), data.len());
    assert!(got == data, "bytes changed on the way");
    assert!(took >= ms(1700), "500 kB at 2 Mbit/s took only {took:?}");
}

/// During a stall the relay reads at most its queue bound from a sender that never stops,
/// and delivers everything after.
#[test]
fn queue_is_bounded_while_stalled() {
    let (sink, received) = sink_server();
    // 2 s: the relay must fill its queue within the stall (milliseconds on loopback).
    let cfg = RelayConfig {
        read_chunk_bytes: 16 * 1024,
        max_queued_bytes: 256 * 1024,
        ..RelayConfig::new(any_port(), sink).with_faults(vec![Fault::stall(0, 2000)])
    };
    let relay = start(cfg);
    let total = 8 * 1024 * 1024;
    let data: Vec<u8> = (0..total as u32).map(|i| (i % 253) as u8).collect();
    let mut c = connect(&relay);
    let sender = {
        let data = data.clone();
        thread::spawn(move || {
            c.write_all(&data).unwrap();
            c.shutdown(Shutdown::Write).unwrap();
        })
    };
    // The reader stops once a further read (16 KiB + overhead) would pass the bound: it has
    // read at least the bound less two reads' worth. Wait for that, in the stall.
    let full = 256 * 1024 - 2 * (16 * 1024 + 1024);
    let s = eventually(&relay, |s| {
        s.up.bytes_read >= full || s.state != RelayState::Stalled
    });
    assert_eq!(s.state, RelayState::Stalled, "{s:?}");
    assert_eq!(s.up.bytes_forwarded, 0);
    assert!(s.up.bytes_read >= full, "the relay read too little: {s:?}");
    assert!(
        s.up.bytes_queued <= 256 * 1024 && s.up.bytes_read <= 256 * 1024,
        "the relay held more than its bound: {s:?}"
    );
    sender.join().unwrap();
    let (got, _) = received.recv_timeout(Duration::from_secs(8)).unwrap();
    assert_eq!(got.len(), total);
    assert!(got == data, "bytes changed on the way");
    let s = eventually(&relay, |s| s.up.bytes_queued == 0);
    assert_eq!(s.up.bytes_queued, 0);
}

/// Bytes sent during a stall arrive only after it ends, all of them. The schedule begins once
/// the connection has made its first round trip (a busy machine may take long to get there).
#[test]
fn stall_holds_bytes_until_it_ends() {
    let echo = echo_server();
    let relay = start(
        RelayConfig::new(any_port(), echo.addr).with_held_faults(vec![Fault::stall(100, 500)]),
    );
    let mut c = connect(&relay);
    c.write_all(b"before").unwrap();
    assert_eq!(read_n(&mut c, 6), b"before");
    let origin = relay.begin_faults();
    let s = eventually(&relay, |s| s.state != RelayState::Forwarding);
    assert_eq!(s.state, RelayState::Stalled);
    let data: Vec<u8> = (0..100_000u32).map(|i| (i % 241) as u8).collect();
    let mut reader = c.try_clone().unwrap();
    let n = data.len();
    let got = thread::spawn(move || {
        let mut first = [0u8; 1];
        reader.read_exact(&mut first).unwrap();
        let first_at = Instant::now();
        let mut rest = read_n(&mut reader, n - 1);
        rest.insert(0, first[0]);
        (rest, first_at)
    });
    c.write_all(&data).unwrap();
    let (got, first_at) = got.join().unwrap();
    assert!(
        first_at >= origin + ms(600),
        "a byte came back {:?} after the origin, before the stall's end at 600 ms",
        first_at - origin
    );
    assert!(got == data, "bytes lost or changed across the stall");
    assert_eq!(relay.stats().connections_aborted_by_fault, 0);
}

/// An open connection is aborted at the reset; a new one works at once.
#[test]
fn reset_closes_open_connections() {
    let echo = echo_server();
    let relay =
        start(RelayConfig::new(any_port(), echo.addr).with_held_faults(vec![Fault::reset(100)]));
    let mut c = connect(&relay);
    c.write_all(b"ping").unwrap();
    assert_eq!(read_n(&mut c, 4), b"ping");
    let origin = relay.begin_faults();
    assert!(is_closed(&mut c), "the connection outlived the reset");
    let closed_at = origin.elapsed();
    assert!(
        closed_at >= ms(100),
        "closed at {closed_at:?}, before the reset"
    );
    assert_eq!(relay.stats().connections_aborted_by_fault, 1);

    let mut c2 = connect(&relay);
    c2.write_all(b"again").unwrap();
    assert_eq!(read_n(&mut c2, 5), b"again");
    assert_eq!(echo.accepted.load(Ordering::SeqCst), 2);
}

/// A partition aborts the open connection, lets nothing through while it lasts, and heals.
#[test]
fn partition_cuts_and_heals() {
    let echo = echo_server();
    // 1.5 s: the connection attempted during it must reach the relay within it (milliseconds
    // on loopback; the test waits for the partition's state before it connects).
    let relay = start(
        RelayConfig::new(any_port(), echo.addr).with_held_faults(vec![Fault::partition(100, 1500)]),
    );
    let mut before = connect(&relay);
    before.write_all(b"ping").unwrap();
    assert_eq!(read_n(&mut before, 4), b"ping");
    let origin = relay.begin_faults();

    // The open connection is cut at the start.
    assert!(
        is_closed(&mut before),
        "the connection outlived the partition"
    );
    assert!(origin.elapsed() >= ms(100));

    // During it: a new connection gets nowhere, and the upstream never sees it.
    let s = eventually(&relay, |s| s.state != RelayState::Forwarding);
    assert_eq!(s.state, RelayState::Partitioned);
    let mut during = connect(&relay);
    let _ = during.write_all(b"lost?");
    assert!(is_closed(&mut during), "data came through the partition");
    let s = relay.stats();
    assert!(s.connections_refused >= 1, "{s:?}");
    assert_eq!(echo.accepted.load(Ordering::SeqCst), 1);

    // After it: connections work again.
    let s = eventually(&relay, |s| s.state == RelayState::Forwarding);
    assert_eq!(s.state, RelayState::Forwarding);
    assert!(origin.elapsed() >= ms(1600));
    let mut after = connect(&relay);
    after.write_all(b"healed").unwrap();
    assert_eq!(read_n(&mut after, 6), b"healed");
    let s = relay.stats();
    assert_eq!(s.connections_aborted_by_fault, 1);
    assert_eq!(echo.accepted.load(Ordering::SeqCst), 2);
}

/// A held schedule does nothing until it begins, then counts from its beginning.
#[test]
fn a_held_schedule_waits_for_its_beginning() {
    let echo = echo_server();
    let relay = start(
        RelayConfig::new(any_port(), echo.addr).with_held_faults(vec![Fault::partition(0, 60_000)]),
    );
    thread::sleep(ms(200));
    assert_eq!(relay.origin(), None);
    assert_eq!(relay.state(), RelayState::Forwarding);
    let mut c = connect(&relay);
    c.write_all(b"held").unwrap();
    assert_eq!(read_n(&mut c, 4), b"held");
    let origin = relay.begin_faults();
    assert_eq!(relay.origin(), Some(origin));
    assert!(is_closed(&mut c), "the connection outlived the partition");
    assert_eq!(relay.state(), RelayState::Partitioned);
    assert_eq!(relay.begin_faults(), origin, "a second call begins nothing");
}

/// A normal close travels through with its delay, and the relay counts it as closed.
#[test]
fn end_of_stream_is_forwarded() {
    let echo = echo_server();
    let relay =
        start(RelayConfig::new(any_port(), echo.addr).with_links(LinkImpairment::delay(20, 5)));
    let mut c = connect(&relay);
    c.write_all(b"bye").unwrap();
    c.shutdown(Shutdown::Write).unwrap();
    let mut all = vec![];
    c.read_to_end(&mut all).unwrap();
    assert_eq!(all, b"bye");
    // The client sees the end of the stream before the relay's task ends the connection: wait
    // for it to leave the active count (one update with its ending), then read how it ended.
    let s = eventually(&relay, |s| s.connections_active == 0);
    assert_eq!((s.connections_closed, s.connections_active), (1, 0));
    assert_eq!(s.connections_failed, 0);
}

#[test]
fn unreachable_upstream_fails_the_connection() {
    // A port nobody listens on: bind one, note it, close it.
    let dead = TcpListener::bind(any_port()).unwrap().local_addr().unwrap();
    let relay = start(RelayConfig::new(any_port(), dead));
    let mut c = connect(&relay);
    assert!(is_closed(&mut c));
    assert_eq!(relay.stats().connections_failed, 1);
}

#[test]
fn bad_configurations_are_refused() {
    let cfg = RelayConfig::new(any_port(), any_port());
    let e = Relay::start(RelayConfig {
        max_queued_bytes: 1000,
        ..cfg.clone()
    })
    .err()
    .unwrap();
    assert!(e.to_string().contains("max_queued_bytes"), "{e}");
    let e = Relay::start(cfg.clone().with_faults(vec![Fault::stall(1, 0)]))
        .err()
        .unwrap();
    assert!(e.to_string().contains("needs a duration"), "{e}");
    let e = Relay::start(RelayConfig {
        up: LinkImpairment::NONE.with_rate(0),
        ..cfg
    })
    .err()
    .unwrap();
    assert!(e.to_string().contains("up link"), "{e}");
}

#[test]
fn shutdown_stops_listening() {
    let echo = echo_server();
    let relay = start(RelayConfig::new(any_port(), echo.addr));
    let addr = relay.local_addr();
    let mut c = connect(&relay);
    c.write_all(b"x").unwrap();
    assert_eq!(read_n(&mut c, 1), b"x");
    relay.shutdown();
    assert!(is_closed(&mut c));
    assert!(TcpStream::connect(addr).is_err());
}
