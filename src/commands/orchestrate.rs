//! `dupac train` (default): the learner and N actor processes on this machine over loopback
//! Zenoh. The learner is the Zenoh router of the run (listening on a free loopback
//! port, multicast scouting off); actors join as clients. This process prepares what every
//! child needs once (RSRP cache, held-out pairs, training pool), starts the children, shows a
//! progress bar from the learner's stats, forwards Ctrl-C (the learner writes its checkpoint)
//! and reaps the children.

use super::children::{child, free_port, reap, signal};
use super::net::{ConnectArgs, ModeArg, stop_flag};
use super::run_args::{DeviceArg, HeldOutSeen, TrainArgs, device, resolve_config};
use crate::global_args::GlobalArgs;
use anyhow::{Context, Result, bail};
use dupac_actor::pairs::write_pairs_jsonl;
use dupac_common::fsio::write_plain;
use dupac_common::jsonmsg::decode_json;
use dupac_common::keys::KeySpace;
use dupac_common::msg::LearnerStats;
use dupac_run::run_dir::{checkpoint_to_resume, ensure_free};
use dupac_scenario::pairs::{guide_sets_cached, held_out_pairs, pool_cached, spread};
use dupac_scenario::progress::{StageClock, stage_spinner};
use dupac_scenario::world::world_and_cache;
use std::process::{Child, ExitCode};
use std::sync::atomic::Ordering;
use std::time::Duration;
use zenoh::Wait;

pub fn run(global: &GlobalArgs, args: &TrainArgs) -> Result<ExitCode> {
    let stop = stop_flag()?;
    let run = &args.run;
    let cfg = resolve_config(global, run.association, run.out.as_ref())?;
    // Fail early, before the children do.
    let _ = checkpoint_to_resume(&cfg, run.resume, run.checkpoint.as_ref())?;
    device(run.device)?;
    let out = cfg.train.out_dir.clone();
    // A run directory a live learner holds is refused before anything in it is rewritten.
    ensure_free(&out)?;
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let config_path = out.join("config.toml");
    write_plain(&config_path, cfg.to_toml_string().as_bytes())?;

    // Everything the children would otherwise each compute (and race on): built once here,
    // each stage named on the progress bar while it runs and timed (`prepared in … s: …`).
    let quiet = global.no_progress();
    let mut clock = StageClock::new();
    let (world, rsrp) = world_and_cache(&cfg, quiet)?;
    clock.lap("world and RSRP cache");
    // The pairs, drawn with a planner of their clearance (no coverage classes), the pool through
    // the host's pool file; then the guide paths of the pool and of the learner's held-out set,
    // planned once here into the host's guide cache (or found there), so the actors and the
    // learner load them instead of each planning them.
    let unguided = dupac_scenario::planners::unguided(&cfg);
    let spin = stage_spinner("pairs' planner", quiet);
    let planners = dupac_scenario::planners::Planners::new(&unguided, &[], &world, &rsrp, false);
    spin.finish_and_clear();
    clock.lap("pairs' planner");
    let held_out = held_out_pairs(&unguided, &planners, quiet)?;
    clock.lap("validation pairs");
    let pool_path = out.join("train_pool.jsonl");
    let mut pool = pool_cached(&unguided, &world, &planners, quiet)?;
    write_pairs_jsonl(&pool_path, &pool)?;
    drop(planners);
    clock.lap("training pairs");
    let mut eval_set = spread(&held_out, cfg.train.eval_pairs);
    guide_sets_cached(&cfg, &world, &rsrp, &mut [&mut eval_set, &mut pool], quiet)?;
    clock.lap("guide paths");
    eprintln!("{}", clock.summary());
    drop((pool, eval_set, held_out));
    drop(world);

    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let n_actors = match args.actors.unwrap_or(cfg.distributed.actors) {
        0 => cores,
        n => n,
    };
    let port = free_port()?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let exe = std::env::current_exe().context("locating the dupac binary")?;

    let mut learner_cmd = child(&exe, &config_path, global);
    learner_cmd
        .arg("learner")
        .arg("--out")
        .arg(&out)
        .args(["--mode", "router", "--listen", &endpoint])
        .arg("--no-multicast-scouting")
        .arg("--device")
        .arg(match run.device {
            DeviceArg::Cpu => "cpu",
            DeviceArg::Cuda => "cuda",
            DeviceArg::Wgpu => "wgpu",
        });
    if run.resume {
        learner_cmd.arg("--resume");
        if let Some(ck) = &run.checkpoint {
            learner_cmd.arg("--checkpoint").arg(ck);
        }
    }
    let mut learner = learner_cmd.spawn().context("starting the learner")?;
    let mut actors: Vec<Child> = Vec::new();
    for k in 0..n_actors {
        let mut a = child(&exe, &config_path, global);
        a.arg("actor")
            .args(["--id", &k.to_string()])
            .arg("--threads")
            .arg(
                (cfg.distributed
                    .actor_envs
                    .min(cores / n_actors.min(cores))
                    .max(1))
                .to_string(),
            )
            .arg("--pool")
            .arg(&pool_path)
            .args(["--mode", "client", "--connect", &endpoint])
            .arg("--no-multicast-scouting")
            // Each actor steps its environments on its own threads; keep rayon's global pool
            // (used by nothing hot in an actor) small.
            .env("RAYON_NUM_THREADS", "1");
        actors.push(a.spawn().with_context(|| format!("starting actor {k}"))?);
    }
    eprintln!(
        "run {:?}: learner (router on {endpoint}) and {n_actors} actors; Ctrl-C stops with a checkpoint",
        cfg.distributed.run
    );

    // Progress from the learner's stats.
    let watch = ConnectArgs {
        mode: Some(ModeArg::Client),
        connect: vec![endpoint.clone()],
        no_multicast_scouting: true,
        ..ConnectArgs::default()
    };
    let total = cfg.train.total_timesteps;
    let pb = dupac_scenario::progress::progress_bar(total, "timesteps", global.no_progress());
    // Until the learner's first update: the learner and the actors load the world and caches.
    pb.set_message("starting learner, actors");
    let keys = KeySpace::new(&cfg.distributed.run);
    // Connected lazily: the learner may still be starting, or may fail before it listens.
    let mut session: Option<zenoh::Session> = None;
    let mut sub = None;
    let limit = dupac_common::msg::MsgLimits::small(&cfg);
    let mut forwarded = false;
    // The held-out evaluations, from the run's metrics as the learner appends them.
    let metrics_path = out.join("metrics.jsonl");
    let mut metrics_read = std::fs::metadata(&metrics_path).map_or(0, |m| m.len());
    let mut held_out = HeldOutSeen::default();
    let status = loop {
        if let Some(st) = learner.try_wait().context("waiting for the learner")? {
            break st;
        }
        if stop.load(Ordering::Relaxed) && !forwarded {
            // Ctrl-C in a terminal reaches the children too; a signal to this process alone
            // is forwarded.
            signal(&learner, libc::SIGINT);
            for a in &actors {
                signal(a, libc::SIGINT);
            }
            forwarded = true;
        }
        if session.is_none() {
            if let Ok(s) = watch.opts().open() {
                sub = s
                    .declare_subscriber(keys.stats_learner())
                    .with(zenoh::handlers::RingChannel::new(1))
                    .wait()
                    .ok();
                session = Some(s);
            } else {
                std::thread::sleep(Duration::from_millis(250));
            }
        }
        if let Some(sub) = &sub
            && let Ok(Some(s)) = sub.recv_timeout(Duration::from_millis(250))
            && let Ok(st) = decode_json::<LearnerStats>(&s.payload().to_bytes(), limit, "stats")
        {
            pb.set_position(st.global_step);
            let alive = st
                .actors
                .iter()
                .filter(|a| a.state == dupac_common::msg::ActorState::Alive)
                .count();
            metrics_read += held_out.see_new_lines(&metrics_path, metrics_read);
            pb.set_message(format!(
                "v{} {:.0} sps {alive} actors{}",
                st.update,
                st.env_steps_per_s,
                held_out.suffix()
            ));
        }
        for (k, a) in actors.iter_mut().enumerate() {
            if let Ok(Some(st)) = a.try_wait()
                && !st.success()
                && !stop.load(Ordering::Relaxed)
            {
                tracing::warn!("actor {k} exited with {st}");
            }
        }
    };
    pb.finish_and_clear();
    if let Some(s) = session {
        let _ = s.close().wait();
    }
    reap(&mut actors);
    if !status.success() {
        bail!("the learner exited with {status}");
    }
    eprintln!("wrote {}", out.display());
    Ok(ExitCode::SUCCESS)
}
