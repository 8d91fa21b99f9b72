//! `dupac radio link` (the scriptable link calculator) and `dupac radio sites`.

use crate::global_args::GlobalArgs;
use anyhow::{Context, Result};
use clap::Subcommand;
use dupac_radio::link_calc::{link_stream, write_sites_csv};
use dupac_radio::world::RadioWorld;
use std::io::Write;
use std::process::ExitCode;

#[derive(Subcommand, Debug)]
pub enum RadioCommand {
    /// Link budgets: one JSON object per input line on stdin, one JSON line per input on stdout.
    ///
    /// Input fields: `bs_xyz`, `uav_xyz` (m, local frame, z above ground), `scenario`
    /// ("umi"/"uma"), optional `los` (absent: decided against the scenario's city), and optional
    /// overrides `boresights_deg`, `n`, `spacing_wavelengths`, `tilt_deg`, `fc_ghz`,
    /// `tx_power_dbm`. Output fields: `d3d_m`, `d2d_m`, `theta_deg`, `best_sector`, `gain_dbi`,
    /// `pl_db`, `rsrp_dbm`, `class`, `los`. A bad line is reported on stderr with its line
    /// number; the rest is still processed; the exit status is 1 if any line failed.
    Link,
    /// The scenario's resolved sites as CSV, in the sites-file format (`scenario.sites_file`).
    Sites,
}

pub fn run(global: &GlobalArgs, cmd: &RadioCommand) -> Result<ExitCode> {
    let cfg = global.config()?;
    match cmd {
        RadioCommand::Link => {
            let stdin = std::io::stdin();
            let stdout = std::io::stdout();
            let mut out = std::io::BufWriter::new(stdout.lock());
            let failed = link_stream(&cfg, stdin.lock(), &mut out, &mut std::io::stderr())?;
            out.flush()?;
            Ok(if failed == 0 {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            })
        }
        RadioCommand::Sites => {
            let world = RadioWorld::build(&cfg).context("building the radio world")?;
            let stdout = std::io::stdout();
            let mut out = stdout.lock();
            write_sites_csv(&world, &mut out)?;
            Ok(ExitCode::SUCCESS)
        }
    }
}
