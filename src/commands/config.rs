//! `dupac config`: the resolved configuration as TOML, or (`--describe`) the key reference:
//! every key with its default and meaning, from the configuration structs' doc comments.

use crate::global_args::GlobalArgs;
use anyhow::Result;
use clap::Args;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct ConfigArgs {
    /// Print every key with its default and what it means, instead of the resolved values.
    #[arg(long)]
    pub describe: bool,
}

pub fn run(global: &GlobalArgs, args: &ConfigArgs) -> Result<ExitCode> {
    if args.describe {
        print!("{}", dupac_common::config::describe::describe(96));
    } else {
        print!("{}", global.config()?.to_toml_string());
    }
    Ok(ExitCode::SUCCESS)
}
