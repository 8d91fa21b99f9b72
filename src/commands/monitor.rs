//! `dupac monitor`: a read-only view of a run from any machine: policy version,
//! updates/s, env steps/s in total and per actor, policy lag, drops by reason, training and
//! domain metrics; a refreshing table on the terminal and, with `--jsonl`, every stats message
//! as a JSON line (as published: [`dupac_common::jsonmsg`]).

use super::net::{ConnectArgs, stop_flag};
use crate::global_args::GlobalArgs;
use anyhow::{Context, Result};
use clap::Args;
use dupac_common::jsonmsg::{decode_json, encode_json};
use dupac_common::keys::{KeySpace, Role};
use dupac_common::msg::StatsMsg;
use dupac_run::monitor::Board;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use zenoh::Wait;

#[derive(Args, Debug)]
pub struct MonitorArgs {
    /// Append every stats message to this file as one JSON object per line.
    #[arg(long, value_name = "FILE")]
    pub jsonl: Option<PathBuf>,
    /// Leave after this many seconds (default: until Ctrl-C or the run ends).
    #[arg(long, value_name = "S")]
    pub duration_s: Option<f64>,
    /// Print the table once per refresh as plain text instead of redrawing the terminal.
    #[arg(long)]
    pub plain: bool,
    #[command(flatten)]
    pub net: ConnectArgs,
}

pub fn run(global: &GlobalArgs, args: &MonitorArgs) -> Result<ExitCode> {
    let stop = stop_flag()?;
    if let Some(d) = args.duration_s {
        // Bounds connecting too.
        let s = stop.clone();
        let d = Duration::try_from_secs_f64(d)
            .ok()
            .filter(|d| d.as_secs() <= 366 * 86_400)
            .ok_or_else(|| {
                anyhow::anyhow!("--duration-s {d}: must be a number of seconds in [0, one year]")
            })?;
        std::thread::spawn(move || {
            std::thread::sleep(d);
            s.store(true, Ordering::Relaxed);
        });
    }
    let cfg = global.config()?;
    let keys = KeySpace::new(&cfg.distributed.run);
    let limit = dupac_common::msg::MsgLimits::small(&cfg);
    let session = args
        .net
        .open_retrying(&stop, cfg.distributed.max_message_bytes())?;
    let _token = session
        .liveliness()
        .declare_token(keys.alive(Role::Monitor, &session.zid().to_string()))
        .wait()
        .map_err(|e| anyhow::anyhow!("zenoh: {e}"))?;
    let sub = session
        .declare_subscriber(keys.stats_all())
        .with(zenoh::handlers::FifoChannel::new(1024))
        .wait()
        .map_err(|e| anyhow::anyhow!("zenoh: {e}"))?;
    let mut jsonl = match &args.jsonl {
        Some(p) => Some(
            std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(p)
                .with_context(|| format!("opening {}", p.display()))?,
        ),
        None => None,
    };
    let start = Instant::now();
    let mut board = Board::default();
    let mut last_draw = Instant::now() - Duration::from_secs(10);
    let interactive =
        !args.plain && !global.quiet && std::io::IsTerminal::is_terminal(&std::io::stdout());
    loop {
        if stop.load(Ordering::Relaxed)
            || args
                .duration_s
                .is_some_and(|d| start.elapsed().as_secs_f64() >= d)
        {
            break;
        }
        if let Ok(Some(sample)) = sub.recv_timeout(Duration::from_millis(200)) {
            let key = sample.key_expr().as_str().to_string();
            match decode_json::<StatsMsg>(&sample.payload().to_bytes(), limit, &key)
                .map_err(|e| e.to_string())
                .and_then(|msg| on_its_key(&keys, &key, msg))
            {
                Ok(msg) => {
                    if let Some(f) = &mut jsonl {
                        f.write_all(&encode_json(&msg)?)
                            .and_then(|()| f.write_all(b"\n"))
                            .context("writing --jsonl")?;
                    }
                    if !board.take(msg) {
                        tracing::warn!("stats ignored on {key}: too many actors shown");
                    }
                }
                Err(e) => tracing::warn!("stats ignored: {e}"),
            }
        }
        if last_draw.elapsed() >= Duration::from_secs(1) {
            let table = board.render();
            if interactive {
                // Clear the screen and home the cursor, then draw.
                print!("\x1b[2J\x1b[H{table}");
            } else {
                println!("{table}");
            }
            std::io::stdout().flush().ok();
            last_draw = Instant::now();
        }
        if board.done() && args.duration_s.is_none() {
            break;
        }
    }
    let _ = session.close().wait();
    Ok(ExitCode::SUCCESS)
}

/// `msg` if it came on its sender's key (the learner's, or its actor id's), so that no process
/// reports for another.
fn on_its_key(keys: &KeySpace, key: &str, msg: StatsMsg) -> Result<StatsMsg, String> {
    let want = match &msg {
        StatsMsg::Learner(_) => keys.stats_learner(),
        StatsMsg::Actor(a) => keys.stats_actor(a.header.actor),
    };
    if key == want {
        Ok(msg)
    } else {
        Err(format!("stats on {key} belong on {want}"))
    }
}
