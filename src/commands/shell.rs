//! `dupac completions SHELL` and `dupac man`: shell completions (clap_complete) and the manual
//! page (clap_mangen), both generated from the command line's own definition.

use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    pub shell: clap_complete::Shell,
}

#[derive(Args, Debug)]
pub struct ManArgs {
    /// Write `dupac.1` and one page per command (`dupac-train.1`, …) into DIR instead of
    /// printing `dupac.1` on stdout.
    #[arg(long, value_name = "DIR")]
    pub dir: Option<PathBuf>,
}

/// Prints the completion script of the command line `cmd` (the binary's own definition), e.g.
/// `dupac completions bash > ~/.local/share/bash-completion/completions/dupac`.
pub fn completions(args: &CompletionsArgs, mut cmd: clap::Command) -> Result<ExitCode> {
    clap_complete::generate(args.shell, &mut cmd, "dupac", &mut std::io::stdout());
    Ok(ExitCode::SUCCESS)
}

/// Prints the manual page (roff) of the command line `cmd`, or writes every page into `--dir`.
pub fn man(args: &ManArgs, cmd: clap::Command) -> Result<ExitCode> {
    match &args.dir {
        None => {
            clap_mangen::Man::new(cmd)
                .render(&mut std::io::stdout())
                .context("writing the manual page")?;
        }
        Some(dir) => {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
            clap_mangen::generate_to(cmd, dir)
                .with_context(|| format!("writing the manual pages into {}", dir.display()))?;
            eprintln!("wrote {}", dir.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
