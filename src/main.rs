//! `dupac`, the one command: a thin layer of argument parsing over the DUPAC libraries.

mod commands;
mod global_args;
mod io;

use clap::{CommandFactory, Parser, Subcommand};
use global_args::GlobalArgs;
use std::process::ExitCode;

/// mimalloc: the learner's tensors of 0.1–2 MB are allocated and freed many times per
/// minibatch, and glibc's malloc maps and unmaps each (Cargo.toml, BENCHMARKS.md).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// DUPAC: Deep UAV Path planning with Assured Connectivity in dense urban settings.
#[derive(Parser, Debug)]
#[command(name = "dupac", version, about, long_about = None)]
struct Cli {
    #[command(flatten)]
    global: GlobalArgs,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Best-server coverage maps of the scenario (paper Fig. 2(b)): PNG, CSV grid, summary.
    Map(commands::map::MapArgs),
    /// Radio tools: the scriptable link calculator, the site list.
    #[command(subcommand)]
    Radio(commands::radio::RadioCommand),
    /// The per-site 3D RSRP cache used by the environment.
    #[command(subcommand)]
    Cache(commands::cache::CacheCommand),
    /// Another city: raw OSM buildings and OpenCelliD cells into a scenario directory and a
    /// configuration (`scenario import`).
    #[command(subcommand)]
    Scenario(commands::scenario::ScenarioCommand),
    /// Held-out pairs binned by shortest flyable distance (JSON Lines): the validation and the
    /// test split.
    Pairs(commands::pairs::PairsArgs),
    /// Shortest and coverage-aware paths of one pair, flown with A3: table, PNG, CSVs.
    Plan(commands::plan::PlanArgs),
    /// Train DUPAC (`--association learned`) or the base method (`a3`): a learner and actor
    /// processes over Zenoh on this machine (or `--single-process`).
    Train(commands::run_args::TrainArgs),
    /// The PPO learner of a Zenoh run (receives trajectories, publishes weights).
    Learner(commands::learner::LearnerArgs),
    /// One actor of a Zenoh run (simulates episodes, publishes trajectories).
    Actor(commands::actor::ActorArgs),
    /// Watch a run: versions, throughput per actor, drops, training and domain metrics.
    Monitor(commands::monitor::MonitorArgs),
    /// A Zenoh router in this process, for multi-machine runs without `zenohd`.
    Router(commands::net::RouterArgs),
    /// A TCP relay that impairs traffic (delay, jitter, rate cap; stalls, resets, partitions),
    /// between an actor and the learner's router: a WAN rehearsal without `sch_netem`.
    Relay(commands::relay::RelayArgs),
    /// Fly one pair with a trained policy (deterministic) and plot it beside the shortest path.
    Fly(commands::fly::FlyArgs),
    /// Evaluate policies and planners on the held-out pairs: step records, the paper's figures,
    /// rates, SINR, a Pareto plot, report.md.
    Eval(commands::eval::EvalArgs),
    /// Tune the base method's A3 (offset × hysteresis × time-to-trigger) on the validation
    /// split's guide paths: `a3_grid.csv`, `tuned_a3.toml`.
    #[command(name = "tune-a3")]
    TuneA3(commands::tune_a3::TuneA3Args),
    /// Write a trained policy as safetensors plus a JSON of its observation layout and
    /// normalisers (`policy.safetensors`, `policy.json`), for NumPy, PyTorch and other readers.
    Export(commands::export::ExportArgs),
    /// Print the resolved configuration as TOML (defaults + file + --set), or with `--describe`
    /// every key with its default and meaning.
    Config(commands::config::ConfigArgs),
    /// Print the completion script of a shell (bash, zsh, fish, elvish, powershell).
    Completions(commands::shell::CompletionsArgs),
    /// Print the manual page (roff), or write one per command into `--dir`.
    Man(commands::shell::ManArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = cli.global.check_nothing_dropped(std::env::args_os()) {
        // A usage error like clap's own: the message, the usage line, exit status 2.
        Cli::command()
            .error(clap::error::ErrorKind::ArgumentConflict, e)
            .exit();
    }
    init_tracing(cli.global.verbose, cli.global.quiet);
    let result = match &cli.command {
        Command::Map(a) => commands::map::run(&cli.global, a),
        Command::Radio(c) => commands::radio::run(&cli.global, c),
        Command::Cache(c) => commands::cache::run(&cli.global, c),
        Command::Scenario(c) => commands::scenario::run(&cli.global, c),
        Command::Pairs(a) => commands::pairs::run(&cli.global, a),
        Command::Plan(a) => commands::plan::run(&cli.global, a),
        Command::Train(a) => commands::train::run(&cli.global, a),
        Command::Learner(a) => commands::learner::run(&cli.global, a),
        Command::Actor(a) => commands::actor::run(&cli.global, a),
        Command::Monitor(a) => commands::monitor::run(&cli.global, a),
        Command::Router(a) => commands::net::run_router(&cli.global, a),
        Command::Relay(a) => commands::relay::run(a),
        Command::Fly(a) => commands::fly::run(&cli.global, a),
        Command::Eval(a) => commands::eval::run(&cli.global, a),
        Command::TuneA3(a) => commands::tune_a3::run(&cli.global, a),
        Command::Export(a) => commands::export::run(a),
        Command::Config(a) => commands::config::run(&cli.global, a),
        Command::Completions(a) => commands::shell::completions(a, Cli::command()),
        Command::Man(a) => commands::shell::man(a, Cli::command()),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// The log on stderr: errors only with `--quiet`, warnings by default, more with `-v`/`-vv`
/// (`RUST_LOG` overrides all three); coloured only on a terminal and without `NO_COLOR`; no
/// line longer than [`dupac_node::ratelog::MAX_LINE_CHARS`] characters.
fn init_tracing(verbose: u8, quiet: bool) {
    // Zenoh's own retry warnings repeat every second while a peer is down, and its transport
    // errors during a partition name internal queues and peer ids: DUPAC says what happened in
    // its own words (a process lost, waiting, back after N s); `-v` shows zenoh's lines too.
    // Zenoh's session logs at ERROR a message that arrives for a key expression its sender has
    // already undeclared ("Received Data for unknown key_expr: Remote resource 1 not found"):
    // actors closing at the end of a run while their last chunk is in flight; the message is
    // dropped, as DUPAC's at-most-once delivery allows (docs/reliability.md P1).
    let default = match (quiet, verbose) {
        (true, _) => "error,zenoh_transport=off,zenoh::api::session=off",
        (false, 0) => {
            "warn,zenoh=error,zenoh_link_tcp=error,zenoh_transport=off,zenoh::api::session=off"
        }
        (false, 1) => "info,zenoh=warn,zenoh_link_tcp=warn,zenoh_transport=warn",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(CutStderr)
        .with_ansi(colour_on_stderr())
        .try_init();
}

/// stderr, every line cut to [`dupac_node::ratelog::MAX_LINE_CHARS`] characters: no log line
/// carries a whole debug dump of an error's inner type.
struct CutStderr;

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for CutStderr {
    type Writer = CutWriter;
    fn make_writer(&'a self) -> CutWriter {
        CutWriter
    }
}

/// One event's text (tracing's formatter writes an event at once), cut line by line.
struct CutWriter;

impl std::io::Write for CutWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let text = String::from_utf8_lossy(buf);
        let mut out = String::with_capacity(buf.len().min(4096));
        for line in text.split_inclusive('\n') {
            let (body, end) = match line.strip_suffix('\n') {
                Some(b) => (b, "\n"),
                None => (line, ""),
            };
            out.push_str(&dupac_node::ratelog::cut_to(
                body,
                dupac_node::ratelog::MAX_LINE_CHARS,
            ));
            out.push_str(end);
        }
        std::io::stderr().write_all(out.as_bytes())?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}

/// Whether stderr gets ANSI colours: only when it is a terminal and `NO_COLOR` is unset or
/// empty (no-color.org), so files, pipes and the journal get plain text.
fn colour_on_stderr() -> bool {
    use std::io::IsTerminal;
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}
