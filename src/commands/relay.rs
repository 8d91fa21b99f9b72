//! `dupac relay`: a userspace TCP relay that impairs traffic (delay, jitter, a rate cap per
//! direction; scheduled stalls, resets and partitions), put between an actor and the learner's
//! router to rehearse training over a bad WAN on a machine without `sch_netem`
//! (`dupac_relay`; docs/reliability.md "Over a WAN").

use crate::commands::net::stop_flag;
use anyhow::{Context, Result};
use clap::Args;
use dupac_relay::{LinkImpairment, Relay, RelayConfig, parse_faults, parse_link};
use std::net::SocketAddr;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct RelayArgs {
    /// Address to listen on (actors connect here: `--connect tcp/ADDR`).
    #[arg(long, value_name = "ADDR")]
    pub listen: SocketAddr,
    /// The learner's router or peer to forward to.
    #[arg(long, value_name = "ADDR")]
    pub upstream: SocketAddr,
    /// Impairment of both directions, e.g. `delay=50ms,jitter=20ms,rate=10mbit` (`none`: none).
    #[arg(long, value_name = "SPEC", default_value = "none")]
    pub link: String,
    /// Impairment towards the upstream only (replaces `--link` for that direction).
    #[arg(long, value_name = "SPEC")]
    pub up: Option<String>,
    /// Impairment from the upstream only (replaces `--link` for that direction).
    #[arg(long, value_name = "SPEC")]
    pub down: Option<String>,
    /// Faults from the relay's start (from SIGUSR1 with `--faults-on-signal`), e.g.
    /// `stall@10s+3s,reset@40s,partition@60s+20s`.
    #[arg(long, value_name = "SPEC", default_value = "none")]
    pub faults: String,
    /// Hold the fault schedule until the relay receives SIGUSR1 (`kill -USR1 PID`): its offsets
    /// then count from the signal, to fault a run once it has warmed up however long that took.
    #[arg(long)]
    pub faults_on_signal: bool,
    /// Seed of the jitter.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print the counters every this many seconds (0: only at the end).
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub report_every_s: f64,
}

/// Runs the relay until Ctrl-C, printing its counters.
pub fn run(args: &RelayArgs) -> Result<ExitCode> {
    let stop = stop_flag()?;
    let link = |spec: &str, what: &str| -> Result<LinkImpairment> {
        parse_link(spec).with_context(|| format!("{what} {spec:?}"))
    };
    let both = link(&args.link, "--link")?;
    let up = args.up.as_deref().map(|s| link(s, "--up")).transpose()?;
    let down = args
        .down
        .as_deref()
        .map(|s| link(s, "--down"))
        .transpose()?;
    let mut cfg = RelayConfig::new(args.listen, args.upstream).with_links(both);
    cfg.up = up.unwrap_or(cfg.up);
    cfg.down = down.unwrap_or(cfg.down);
    cfg.faults =
        parse_faults(&args.faults).with_context(|| format!("--faults {:?}", args.faults))?;
    cfg.seed = args.seed;
    cfg.faults_held = args.faults_on_signal;
    let begin = Arc::new(AtomicBool::new(false));
    if args.faults_on_signal {
        signal_hook::flag::register(signal_hook::consts::SIGUSR1, begin.clone())
            .context("installing the SIGUSR1 handler")?;
    }
    let relay = Relay::start(cfg)?;
    eprintln!(
        "relay {} → {} (up: {}, down: {}, faults: {})",
        relay.local_addr(),
        args.upstream,
        args.up.as_deref().unwrap_or(&args.link),
        args.down.as_deref().unwrap_or(&args.link),
        args.faults
    );
    if args.faults_on_signal {
        eprintln!(
            "relay: the fault schedule waits for SIGUSR1 (kill -USR1 {})",
            std::process::id()
        );
    }
    let mut last = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(100));
        if begin.load(Ordering::Relaxed) && relay.origin().is_none() {
            relay.begin_faults();
            eprintln!("relay: the fault schedule begins");
        }
        if args.report_every_s > 0.0 && last.elapsed().as_secs_f64() >= args.report_every_s {
            eprintln!("{}", line(&relay.stats()));
            last = Instant::now();
        }
    }
    eprintln!("{}", line(&relay.stats()));
    relay.shutdown();
    Ok(ExitCode::SUCCESS)
}

/// The counters in one line.
fn line(s: &dupac_relay::RelayStats) -> String {
    let mb = |b: u64| b as f64 / 1e6;
    format!(
        "relay {:?}: {:.1} MB up, {:.1} MB down forwarded; connections {} accepted, {} active, \
         {} cut by faults, {} refused in partitions, {} failed",
        s.state,
        mb(s.up.bytes_forwarded),
        mb(s.down.bytes_forwarded),
        s.connections_accepted,
        s.connections_active,
        s.connections_aborted_by_fault,
        s.connections_refused,
        s.connections_failed
    )
}
