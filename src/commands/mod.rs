//! One module per subcommand.

pub mod actor;
pub mod cache;
pub mod eval;
pub mod fly;
pub mod learner;
pub mod map;
pub mod monitor;
pub mod net;
pub mod orchestrate;
pub mod pairs;
pub mod plan;
pub mod radio;
pub mod train;

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar on stderr (hidden with `--quiet` or when stderr is not a terminal).
pub fn progress_bar(len: u64, what: &str, quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    let style = ProgressStyle::with_template(
        "{msg:>24} [{elapsed_precise}] {wide_bar} {pos}/{len} (eta {eta})",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    pb.set_style(style);
    pb.set_message(what.to_string());
    pb
}
