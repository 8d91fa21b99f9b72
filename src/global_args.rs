//! The options every subcommand takes (`--config`, `--set`, `-v`, `-q`) and the configuration
//! they resolve to.

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

/// Options every subcommand takes.
#[derive(Args, Debug, Clone)]
#[command(next_help_heading = "Global options")]
pub struct GlobalArgs {
    /// TOML configuration file (every key has a default; unknown keys are rejected).
    #[arg(long, global = true, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Override one configuration key, e.g. `--set map.resolution_m=10` (repeatable).
    #[arg(long = "set", global = true, value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, global = true, action = clap::ArgAction::Count, conflicts_with = "quiet")]
    pub verbose: u8,
    /// No progress bars, and only errors in the log (no warnings); RUST_LOG overrides.
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// No progress bars, the log as usual (the children of `dupac train` share its terminal).
    #[arg(long, global = true, hide = true)]
    pub no_progress: bool,
}

impl GlobalArgs {
    /// Whether progress bars are hidden (`--quiet`, or a child process of `dupac train`).
    pub fn no_progress(&self) -> bool {
        self.quiet || self.no_progress
    }

    /// Refuses what clap would drop silently: a global option given on both sides of the
    /// subcommand keeps only the occurrences after it (`dupac --set a=1 train --set b=2` loses
    /// `a=1`), so the occurrences on the command line (`argv`, program name first; nothing after
    /// a literal `--`) must all have reached `self`. The error says how to write it instead.
    pub fn check_nothing_dropped<I: IntoIterator<Item = std::ffi::OsString>>(
        &self,
        argv: I,
    ) -> std::result::Result<(), String> {
        let (mut sets, mut configs) = (0usize, 0usize);
        for a in argv.into_iter().skip(1) {
            let a = a.to_string_lossy();
            if a == "--" {
                break;
            }
            if a == "--set" || a.starts_with("--set=") {
                sets += 1;
            } else if a == "--config" || a.starts_with("--config=") {
                configs += 1;
            }
        }
        if sets != self.set.len() {
            return Err(format!(
                "--set was given {sets} times but {} reached the command: give every --set after \
                 the command's name (e.g. `dupac train --set a.b=1 --set c.d=2`), not on both \
                 sides of it",
                self.set.len()
            ));
        }
        if configs > 1 {
            return Err(format!(
                "--config was given {configs} times: give one configuration file (every other \
                 change as --set)"
            ));
        }
        Ok(())
    }

    /// The resolved, validated configuration.
    pub fn config(&self) -> Result<dupac_common::config::Config> {
        Ok(dupac_common::config::Config::load(
            self.config.as_deref(),
            &self.set,
        )?)
    }
}
