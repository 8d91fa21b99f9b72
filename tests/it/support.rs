//! Helpers of the end-to-end tests: the one command builder ([`dupac_cmd`], as ripgrep's
//! `TestCommand`), the small procedural scenario and run ([`small_world_args`],
//! [`small_run_args`], a policy trained once per binary: [`trained_run`]), a small procedural run config, child processes killed when a test ends, and
//! the test's own Zenoh client (stats watcher and rogue publisher).

use dupac_common::ids::ActorId;
use dupac_common::jsonmsg::decode_json;
use dupac_common::keys::KeySpace;
use dupac_common::msg::{Header, LearnerStats, TrajectoryChunk, WeightsMsg, decode_msg};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use zenoh::Wait;

/// The one command builder of the end-to-end tests: the `dupac` binary under test, run from the
/// repository root (where `data/` and `docs/` are).
pub fn dupac_cmd() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dupac"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

/// Whether a test's prerequisite (root, namespaces, openssl, strace) is met. When it is not:
/// with `CI` set the test fails, naming it (CI must run every test); elsewhere it prints a
/// visible `SKIPPED` line and the caller returns.
pub fn prerequisite(what: &str, met: bool) -> bool {
    if met {
        return true;
    }
    if std::env::var_os("CI").is_some_and(|v| !v.is_empty() && v != "0" && v != "false") {
        panic!("prerequisite missing on CI: {what}");
    }
    eprintln!("SKIPPED: prerequisite missing: {what}");
    false
}

/// [`small_world_args`] with two bins (50, 60 m) of 4 short pairs per split, the validation and
/// test files in `dir` (`val.jsonl`, `test.jsonl`).
pub fn split_world_args(dir: &Path) -> Vec<String> {
    let mut a = small_world_args(dir);
    for kv in [
        "pairs.eval_bins_m=[50, 60]".to_string(),
        "pairs.eval_per_bin=4".into(),
        "pairs.bin_tolerance=0.1".into(),
        format!("pairs.eval_file=\"{}\"", dir.join("val.jsonl").display()),
        format!("pairs.test_file=\"{}\"", dir.join("test.jsonl").display()),
    ] {
        a.push("--set".into());
        a.push(kv);
    }
    a
}

/// A small procedural scenario with a coarse cache (`--set` arguments), so the planner commands
/// run in seconds; the cache lives in `dir`.
pub fn small_world_args(dir: &Path) -> Vec<String> {
    [
        "--set",
        "scenario.city=procedural",
        "--set",
        "scenario.procedural.size_m=500",
        "--set",
        "scenario.procedural.n_sites=8",
        "--set",
        "scenario.n_sites=8",
        "--set",
        "cache.horizontal_m=10",
        "--set",
        "cache.vertical_m=10",
    ]
    .iter()
    .map(|s| s.to_string())
    .chain([
        "--set".to_string(),
        format!("cache.path=\"{}\"", dir.join("rsrp.bin").display()),
    ])
    .collect()
}

/// [`small_world_args`] plus [`small_train_args`]: what the `train` and `eval` tests train and
/// fly.
pub fn small_run_args(dir: &Path) -> Vec<String> {
    let mut args = small_world_args(dir);
    args.extend(small_train_args(dir));
    args
}

/// Short held-out pairs (two bins of 4) and a tiny PPO run (4 × 64 samples per update, a
/// [32, 32] network, evaluation and checkpoint every 2 updates), for any scenario; the held-out
/// pairs file lives in `dir`.
pub fn small_train_args(dir: &Path) -> Vec<String> {
    let mut args = Vec::new();
    for kv in [
        "pairs.min_m=40".to_string(),
        "pairs.max_m=70".into(),
        "pairs.eval_bins_m=[50, 60]".into(),
        "pairs.eval_per_bin=4".into(),
        "pairs.bin_tolerance=0.1".into(),
        format!("pairs.eval_file=\"{}\"", dir.join("eval.jsonl").display()),
        // `dupac pairs` writes the test split too: never into the repository's out/.
        format!("pairs.test_file=\"{}\"", dir.join("test.jsonl").display()),
        "train.num_envs=4".into(),
        "train.num_steps=64".into(),
        "train.pool_size=50".into(),
        "train.checkpoint_every=2".into(),
        "train.eval_every=2".into(),
        "train.eval_pairs=8".into(),
        "ppo.num_minibatches=2".into(),
        "ppo.hidden=[32, 32]".into(),
    ] {
        args.push("--set".into());
        args.push(kv);
    }
    args
}

/// Flies the committed policy of point directory `point` (its `config.toml` and `policy.bin`,
/// labelled `label`) with `dupac eval` on the pairs file `pairs` at each handover weight of
/// `weights` (comma-separated), without planners or re-flights, into `out`. Exact radio (a ray
/// per site per step) instead of the 200 MB cache, kept under `tmp`: a few flights do not need
/// the cache, and the policy's observation is the same up to the cache's interpolation.
pub fn fly_committed_policy(
    point: &str,
    label: &str,
    pairs: &Path,
    weights: &str,
    tmp: &Path,
    out: &Path,
) -> std::process::Output {
    dupac_output(
        &[
            "--config".into(),
            format!("{point}/config.toml"),
            "--set".into(),
            "env.radio_mode=\"exact\"".into(),
            "--set".into(),
            format!("cache.path=\"{}\"", tmp.join("rsrp.bin").display()),
        ],
        &[
            "eval".into(),
            "-q".into(),
            "--pairs".into(),
            pairs.display().to_string(),
            "--policy".into(),
            format!("{label}={point}/policy.bin"),
            "--handover-weight".into(),
            weights.into(),
            "--no-planners".into(),
            "--no-replay".into(),
            "--out".into(),
            out.display().to_string(),
        ],
    )
}

/// Runs `dupac COMMAND… SCENARIO…` (no stdin) and returns its output. The scenario's `--set`s
/// come after the command's own: clap keeps only the occurrences of a global option on one side
/// of the subcommand.
pub fn dupac_output(scenario: &[String], command: &[String]) -> std::process::Output {
    dupac_cmd()
        .args(command)
        .args(scenario)
        .stdin(Stdio::null())
        .output()
        .expect("run dupac")
}

/// A policy trained once per test binary on [`small_run_args`] (`train --single-process`, 1 024
/// decisions), shared by the tests that fly or evaluate one: its directory (held-out pairs, cache,
/// `run/policy.bin`) and the arguments that select its scenario. It lives under cargo's
/// `CARGO_TARGET_TMPDIR`, in a folder of its own that this process holds locked (`flock` on
/// `.lock`) while it runs; a folder whose lock can be taken belongs to a binary that has ended
/// and is removed when the next one starts. A failed training fails every test that needs it
/// with the same message, without training again.
pub struct TrainedRun {
    pub dir: PathBuf,
    pub args: Vec<String>,
    _lock: std::fs::File,
}

impl TrainedRun {
    pub fn policy(&self) -> PathBuf {
        self.dir.join("run").join("policy.bin")
    }
}

pub fn trained_run() -> &'static TrainedRun {
    static RUN: std::sync::OnceLock<Result<TrainedRun, String>> = std::sync::OnceLock::new();
    match RUN.get_or_init(train_once) {
        Ok(run) => run,
        Err(e) => panic!("the shared trained run failed: {e}"),
    }
}

/// An exclusive advisory lock on an existing `path`, taken without waiting: held while the
/// returned file lives.
fn try_lock(path: &Path, create: bool) -> Option<std::fs::File> {
    use std::os::fd::AsRawFd;
    let f = std::fs::OpenOptions::new()
        .create(create)
        .truncate(false)
        .write(true)
        .open(path)
        .ok()?;
    // SAFETY: flock(2) on a descriptor this function owns.
    (unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } == 0).then_some(f)
}

fn train_once() -> Result<TrainedRun, String> {
    let root = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let prefix = "it-trained-run-";
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let dir = root.join(format!("{prefix}{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let lock = try_lock(&dir.join(".lock"), true)
        .ok_or_else(|| format!("cannot lock {}", dir.display()))?;
    // Folders of binaries that have ended (their lock is free). One without a lock file is
    // being created, or was left by a crash before it: kept.
    if let Ok(entries) = std::fs::read_dir(root) {
        for e in entries.flatten() {
            let other = e.path();
            if other != dir
                && e.file_name().to_string_lossy().starts_with(prefix)
                && try_lock(&other.join(".lock"), false).is_some()
            {
                let _ = std::fs::remove_dir_all(&other);
            }
        }
    }
    let args = small_run_args(&dir);
    let run = dir.join("run").display().to_string();
    let out = dupac_output(
        &args,
        &[
            "train".into(),
            "-q".into(),
            "--single-process".into(),
            "--out".into(),
            run,
            "--set".into(),
            "train.total_timesteps=1024".into(),
        ],
    );
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    Ok(TrainedRun {
        dir,
        args,
        _lock: lock,
    })
}

/// A small procedural city with short pairs: a run of many updates per second.
pub fn write_config(dir: &Path, run: &str, total_timesteps: u64) -> PathBuf {
    let text = format!(
        r#"
[scenario]
city = "procedural"
n_sites = 8
[scenario.procedural]
size_m = 500
n_sites = 8
[cache]
horizontal_m = 10
vertical_m = 10
path = "{dir}/rsrp.bin"
[pairs]
min_m = 40
max_m = 70
eval_bins_m = [50, 60]
eval_per_bin = 4
bin_tolerance = 0.1
eval_file = "{dir}/eval.jsonl"
test_file = "{dir}/test.jsonl"
[train]
num_envs = 4
num_steps = 64
pool_size = 50
checkpoint_every = 2
eval_every = 1000
eval_pairs = 8
total_timesteps = {total_timesteps}
[ppo]
num_minibatches = 2
hidden = [32, 32]
[distributed]
run = "{run}"
actor_envs = 2
chunk_steps = 32
max_message_mib = 1.0
stats_every_s = 0.2
silent_after_s = 3.0
"#,
        dir = dir.display()
    );
    let path = dir.join("config.toml");
    std::fs::write(&path, text).expect("write config");
    path
}

pub fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    l.local_addr().expect("addr").port()
}

/// Child processes killed when the test ends, whatever happens.
pub struct Procs {
    pub dir: PathBuf,
    pub config: PathBuf,
    pub endpoint: String,
    pub children: Vec<(String, Child)>,
}

impl Drop for Procs {
    fn drop(&mut self) {
        for (_, c) in &mut self.children {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

impl Procs {
    pub fn new(dir: &Path, run: &str, total: u64) -> Procs {
        let config = write_config(dir, run, total);
        // The RSRP cache once, before any process would build it.
        let st = dupac_cmd()
            .args([
                "--config",
                config.to_str().expect("utf8"),
                "-q",
                "cache",
                "build",
            ])
            .status()
            .expect("cache build");
        assert!(st.success(), "cache build failed");
        Procs {
            dir: dir.to_path_buf(),
            config,
            endpoint: format!("tcp/127.0.0.1:{}", free_port()),
            children: Vec::new(),
        }
    }

    pub fn spawn(&mut self, name: &str, args: &[&str]) {
        self.spawn_env(name, args, &[]);
    }

    /// [`Procs::spawn`] with extra environment variables (`DUPAC_FAULT`, say).
    pub fn spawn_env(&mut self, name: &str, args: &[&str], envs: &[(&str, &str)]) {
        self.spawn_logging(name, args, envs, "-q");
    }

    /// [`Procs::spawn`] with the default log level (warnings), as a user runs it: for tests
    /// that count what a process says.
    pub fn spawn_warnings(&mut self, name: &str, args: &[&str]) {
        self.spawn_logging(name, args, &[], "--no-progress");
    }

    /// Spawns `dupac --config CONFIG LEVEL ARGS…` (`LEVEL`: `-q` or a neutral flag).
    fn spawn_logging(&mut self, name: &str, args: &[&str], envs: &[(&str, &str)], level: &str) {
        let log = |ext: &str| {
            std::fs::File::create(self.dir.join(format!("{name}.{ext}"))).expect("log file")
        };
        let child = dupac_cmd()
            .arg("--config")
            .arg(&self.config)
            .arg(level)
            .args(args)
            .envs(envs.iter().copied())
            .stdin(Stdio::null())
            .stdout(log("out"))
            .stderr(log("err"))
            .spawn()
            .expect("spawn dupac");
        self.children.push((name.to_string(), child));
    }

    pub fn learner(&mut self, name: &str, extra: &[&str]) {
        self.learner_env(name, extra, &[]);
    }

    /// [`Procs::learner`] with extra environment variables (`DUPAC_FAULT`, say).
    pub fn learner_env(&mut self, name: &str, extra: &[&str], envs: &[(&str, &str)]) {
        let out = self.dir.join("run").display().to_string();
        let ep = self.endpoint.clone();
        let mut a = vec![
            "learner",
            "--out",
            &out,
            "--mode",
            "router",
            "--listen",
            &ep,
            "--no-multicast-scouting",
        ];
        a.extend_from_slice(extra);
        self.spawn_env(name, &a, envs);
    }

    pub fn actor(&mut self, id: u32) {
        let ep = self.endpoint.clone();
        let id_s = id.to_string();
        self.spawn(
            &format!("actor{id}"),
            &[
                "actor",
                "--id",
                &id_s,
                "--threads",
                "1",
                "--mode",
                "client",
                "--connect",
                &ep,
                "--no-multicast-scouting",
            ],
        );
    }

    pub fn child(&mut self, name: &str) -> &mut Child {
        &mut self
            .children
            .iter_mut()
            .find(|(n, _)| n == name)
            .expect("no such child")
            .1
    }

    /// Sends a signal (`-INT`, `-USR1`, …).
    pub fn signal(&mut self, name: &str, sig: &str) {
        let pid = self.child(name).id().to_string();
        let st = Command::new("kill")
            .args([sig, &pid])
            .status()
            .expect("kill");
        assert!(st.success(), "kill {sig} {name}");
    }

    /// Sends a signal and waits for the process to exit (at most 30 s).
    pub fn signal_and_wait(&mut self, name: &str, sig: &str) -> std::process::ExitStatus {
        self.signal(name, sig);
        self.wait_exit(name, 30)
    }

    /// Waits for the process to exit, at most `secs`.
    pub fn wait_exit(&mut self, name: &str, secs: u64) -> std::process::ExitStatus {
        let t0 = Instant::now();
        loop {
            if let Some(st) = self.child(name).try_wait().expect("wait") {
                return st;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(secs),
                "{name} did not exit within {secs} s; {}",
                self.logs()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    pub fn read(&self, name: &str) -> String {
        std::fs::read_to_string(self.dir.join(name)).unwrap_or_default()
    }

    /// Every process's stderr tail, for failure messages.
    pub fn logs(&self) -> String {
        let mut s = String::new();
        for (n, _) in &self.children {
            let err = self.read(&format!("{n}.err"));
            let tail: Vec<&str> = err.lines().rev().take(15).collect();
            s.push_str(&format!(
                "\n--- {n} stderr (last lines, reversed):\n{}",
                tail.join("\n")
            ));
        }
        s
    }
}

/// The test's own Zenoh client: the learner's stats (newest only), and a rogue publisher.
pub struct Watcher {
    pub session: zenoh::Session,
    pub keys: KeySpace,
    pub stats:
        zenoh::pubsub::Subscriber<zenoh::handlers::RingChannelHandler<zenoh::sample::Sample>>,
}

impl Watcher {
    pub fn new(endpoint: &str, run: &str) -> Watcher {
        let mut c = zenoh::Config::default();
        c.insert_json5("mode", "\"client\"").expect("mode");
        c.insert_json5("connect/endpoints", &format!("[\"{endpoint}\"]"))
            .expect("connect");
        c.insert_json5("scouting/multicast/enabled", "false")
            .expect("scouting");
        Watcher::with_config(c, run)
    }

    /// A watcher with its own Zenoh configuration (TLS certificates, say).
    pub fn with_config(c: zenoh::Config, run: &str) -> Watcher {
        // The router may not listen yet: retry for a while.
        let t0 = Instant::now();
        let session = loop {
            match zenoh::open(c.clone()).wait() {
                Ok(s) => break s,
                Err(e) => {
                    assert!(
                        t0.elapsed() < Duration::from_secs(60),
                        "cannot connect: {e}"
                    );
                    std::thread::sleep(Duration::from_millis(200));
                }
            }
        };
        let keys = KeySpace::new(run);
        let stats = session
            .declare_subscriber(keys.stats_learner())
            .with(zenoh::handlers::RingChannel::new(1))
            .wait()
            .expect("subscribe");
        Watcher {
            session,
            keys,
            stats,
        }
    }

    /// Waits (at most `secs`) for learner stats satisfying `ok` (each published as
    /// `application/json`).
    pub fn wait_for(
        &self,
        procs: &Procs,
        what: &str,
        secs: u64,
        ok: impl Fn(&LearnerStats) -> bool,
    ) -> LearnerStats {
        let t0 = Instant::now();
        let mut last = None;
        while t0.elapsed() < Duration::from_secs(secs) {
            if let Ok(Some(s)) = self.stats.recv_timeout(Duration::from_millis(200))
                && let Ok(st) = decode_json::<LearnerStats>(
                    &s.payload().to_bytes(),
                    dupac_common::msg::MsgLimits::both(1 << 26),
                    "stats",
                )
            {
                // Any zenoh client can tell the stats are JSON.
                assert_eq!(s.encoding(), &zenoh::bytes::Encoding::APPLICATION_JSON);
                if ok(&st) {
                    return st;
                }
                last = Some(st);
            }
        }
        panic!(
            "timed out waiting for {what}; last stats: {:?}{}",
            last.map(|s| (s.update, s.drops, s.actors)),
            procs.logs()
        );
    }

    /// The learner's weights by query, asked again (for up to 30 s) while no reply comes: a
    /// client's query can end at once with none while its session has not yet learnt of the
    /// queryable (zenoh issues 2516, 2767), as the actors' own joining query is retried.
    pub fn weights(&self) -> WeightsMsg {
        let t0 = Instant::now();
        loop {
            let replies = self
                .session
                .get(self.keys.weights())
                .timeout(Duration::from_secs(5))
                .wait()
                .expect("query");
            if let Ok(reply) = replies.recv() {
                let sample = reply.result().expect("ok reply");
                return decode_msg(
                    &sample.payload().to_bytes(),
                    dupac_common::msg::MsgLimits::both(1 << 26),
                    "weights",
                )
                .expect("weights decode");
            }
            assert!(
                t0.elapsed() < Duration::from_secs(30),
                "no weights reply in 30 s"
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    pub fn publish(&self, actor: u32, bytes: Vec<u8>) {
        self.session
            .put(self.keys.traj(ActorId(actor)), bytes)
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .wait()
            .expect("put");
    }
}

/// The `update` column of a run's metrics.
pub fn metric_updates(path: &Path) -> Vec<u64> {
    std::fs::read_to_string(path)
        .expect("metrics")
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).expect("row")["update"]
                .as_f64()
                .expect("update") as u64
        })
        .collect()
}

pub fn drops(s: &LearnerStats, reason: &str) -> u64 {
    s.drops.get(reason).copied().unwrap_or(0)
}

/// A well-formed compact chunk for the learner that `w` came from, acted with `version`: four
/// decisions of random states in the shape of the policy's observation with the default
/// environment (a site chosen at each of a decision's 5 steps), over `w`'s sites.
pub fn valid_chunk(w: &WeightsMsg, actor: u32, version: u64) -> TrajectoryChunk {
    let mut cfg = dupac_common::config::Config::default();
    if let Some(o) = &w.policy.observation {
        cfg.env.observation = o.clone();
    }
    let area = dupac_common::geometry::Bounds2 {
        min_m: dupac_common::geometry::Point2::new(0.0, 0.0),
        max_m: dupac_common::geometry::Point2::new(500.0, 500.0),
    };
    let sites = vec![dupac_common::geometry::Point::new(250.0, 250.0, 30.0); w.policy.n_sites];
    let x = dupac_actor::expand::Expander::of_sites(&cfg, area, sites);
    assert_eq!(
        x.layout().len(),
        w.policy.obs_dim,
        "the policy's observation"
    );
    let mut h = Header::new(
        &w.header.run_id,
        w.header.learner_incarnation,
        ActorId(actor),
        w.header.config_fingerprint,
    );
    h.policy_version = version;
    let tr = x.sample_trajectory(4, u64::from(actor));
    TrajectoryChunk {
        header: h,
        trajectories: vec![tr],
    }
}

/// The value of column `name` in the row of method `label` of a `summary.csv` (`dupac eval`).
pub fn summary_column(summary: &str, label: &str, name: &str) -> f64 {
    let header: Vec<&str> = summary.lines().next().expect("header").split(',').collect();
    let k = header
        .iter()
        .position(|h| *h == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    let row = summary
        .lines()
        .find(|l| l.starts_with(&format!("{label},")))
        .unwrap_or_else(|| panic!("no row {label} in\n{summary}"));
    row.split(',')
        .nth(k)
        .expect("value")
        .parse()
        .expect("number")
}
