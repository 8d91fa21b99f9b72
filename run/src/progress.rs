//! Progress bars on stderr, one style for every long step (cache, pairs, training, evaluation).

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
