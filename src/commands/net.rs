//! The connection arguments every networked subcommand shares (like zenoh's own tools), the
//! Ctrl-C flag, and `dupac router`.

use crate::global_args::GlobalArgs;
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use dupac_node::net::{ConnectOpts, Mode};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// How long a process waits quietly for its router or peer before it warns (s): a learner's
/// router takes a few seconds to listen when `dupac train` starts everything at once.
const JOIN_GRACE: std::time::Duration = std::time::Duration::from_secs(30);

/// The node's role in the Zenoh network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModeArg {
    Peer,
    Client,
    Router,
}

/// Where and how to join the Zenoh network (zenoh's defaults without any: peer mode with
/// multicast scouting).
#[derive(Args, Debug, Clone, Default)]
#[command(next_help_heading = "Zenoh connection")]
pub struct ConnectArgs {
    /// Zenoh JSON5 configuration file (TLS, access control, …); the flags below override it.
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// Zenoh mode of this process.
    #[arg(long, value_enum)]
    pub mode: Option<ModeArg>,
    /// Endpoint to connect to, e.g. `tcp/10.0.0.1:7447` (repeatable).
    #[arg(short = 'e', long, value_name = "ENDPOINT", value_parser = endpoint)]
    pub connect: Vec<String>,
    /// Endpoint to listen on, e.g. `tcp/0.0.0.0:7447` (repeatable).
    #[arg(short = 'l', long, value_name = "ENDPOINT", value_parser = endpoint)]
    pub listen: Vec<String>,
    /// Turn multicast scouting off.
    #[arg(long)]
    pub no_multicast_scouting: bool,
}

/// `--connect`/`--listen`: an endpoint checked when the arguments are parsed, before any work
/// ([`dupac_node::net::check_endpoint`]); the error says what is wrong in words.
fn endpoint(s: &str) -> Result<String, String> {
    match dupac_node::net::check_endpoint(s) {
        Ok(()) => Ok(s.to_string()),
        Err(dupac_node::net::NetError::Endpoint { message, .. }) => Err(message),
        Err(e) => Err(e.to_string()),
    }
}

impl ConnectArgs {
    pub fn opts(&self) -> ConnectOpts {
        ConnectOpts {
            config: self.zenoh_config.clone(),
            mode: self.mode.map(|m| match m {
                ModeArg::Peer => Mode::Peer,
                ModeArg::Client => Mode::Client,
                ModeArg::Router => Mode::Router,
            }),
            connect: self.connect.clone(),
            listen: self.listen.clone(),
            no_multicast_scouting: self.no_multicast_scouting,
            rx_max_message_bytes: None,
        }
    }

    /// Opens the session, retrying every second until `stop` while the endpoint is not up yet
    /// (a client started before its router: quiet for [`JOIN_GRACE`], then one warning). zenoh drops received messages over
    /// `rx_max_message_bytes` (the run's largest message).
    pub fn open_retrying(
        &self,
        stop: &AtomicBool,
        rx_max_message_bytes: usize,
    ) -> Result<zenoh::Session> {
        let mut opts = self.opts();
        opts.rx_max_message_bytes = Some(rx_max_message_bytes);
        let started = std::time::Instant::now();
        let mut warned = false;
        loop {
            match opts.open() {
                Ok(s) => return Ok(s),
                Err(dupac_node::net::NetError::Open(e)) if !stop.load(Ordering::Relaxed) => {
                    // A client started before its router is a normal start: quiet until the
                    // grace period has passed, then one warning in words.
                    if !warned && started.elapsed() >= JOIN_GRACE {
                        tracing::warn!(
                            "no zenoh router or peer at {} after {} s ({e}); still trying",
                            self.endpoints(),
                            JOIN_GRACE.as_secs()
                        );
                        warned = true;
                    } else {
                        tracing::debug!("cannot join the zenoh network yet ({e}); retrying");
                    }
                    std::thread::sleep(std::time::Duration::from_secs(1));
                }
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// The endpoints this process connects to, for messages ("multicast scouting" without any).
    fn endpoints(&self) -> String {
        if self.connect.is_empty() {
            "any endpoint multicast scouting finds".into()
        } else {
            self.connect.join(", ")
        }
    }
}

/// A flag set by Ctrl-C (SIGINT) and SIGTERM.
pub fn stop_flag() -> Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    let f = flag.clone();
    ctrlc::set_handler(move || {
        if f.swap(true, Ordering::Relaxed) {
            // A second Ctrl-C: leave at once.
            std::process::exit(130);
        }
    })
    .context("installing the Ctrl-C handler")?;
    Ok(flag)
}

#[derive(Args, Debug)]
pub struct RouterArgs {
    #[command(flatten)]
    pub net: ConnectArgs,
}

/// `dupac router`: a Zenoh router in this process (what `zenohd` does, without its plugins),
/// for multi-machine runs where no `zenohd` is installed.
pub fn run_router(global: &GlobalArgs, args: &RouterArgs) -> Result<ExitCode> {
    let stop = stop_flag()?;
    let mut net = args.net.clone();
    net.mode = Some(ModeArg::Router);
    if net.listen.is_empty() && net.zenoh_config.is_none() {
        net.listen = vec!["tcp/0.0.0.0:7447".into()];
    }
    // The router relays every message of the run: its limit is the configured cap.
    let cfg = global.config()?;
    let mut opts = net.opts();
    opts.rx_max_message_bytes = Some(cfg.distributed.max_message_bytes());
    let session = opts.open()?;
    let listen = if net.listen.is_empty() {
        "the endpoints of --zenoh-config".to_string()
    } else {
        net.listen.join(", ")
    };
    eprintln!("router {} listening on {listen}", session.zid());
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(std::time::Duration::from_millis(200));
    }
    use zenoh::Wait;
    let _ = session.close().wait();
    Ok(ExitCode::SUCCESS)
}
