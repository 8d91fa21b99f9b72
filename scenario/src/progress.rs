//! Progress bars on stderr, one style for every long step (cache, pairs, training, evaluation),
//! and the clock of a command's preparation stages.

use indicatif::{ProgressBar, ProgressStyle};
use std::time::{Duration, Instant};

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

/// A spinner on stderr naming a stage whose length is not known (hidden like [`progress_bar`]).
pub fn stage_spinner(what: &str, quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new_spinner();
    let style = ProgressStyle::with_template("{msg:>24} [{elapsed_precise}] {spinner}")
        .unwrap_or_else(|_| ProgressStyle::default_spinner());
    pb.set_style(style);
    pb.set_message(what.to_string());
    pb.enable_steady_tick(Duration::from_millis(200));
    pb
}

/// The wall-clock time of each preparation stage of a command, in order: what `dupac train`
/// prints before it starts training (`prepared in 95 s: RSRP cache 31 s, …`) and logs
/// (`tracing`, target `dupac_scenario::progress`, one event per stage with `stage` and `seconds`).
#[derive(Debug)]
pub struct StageClock {
    start: Instant,
    last: Instant,
    stages: Vec<(String, Duration)>,
}

impl Default for StageClock {
    fn default() -> Self {
        Self::new()
    }
}

impl StageClock {
    /// A clock started now.
    pub fn new() -> StageClock {
        let now = Instant::now();
        StageClock {
            start: now,
            last: now,
            stages: Vec::new(),
        }
    }

    /// Ends the stage `name` (the time since the clock started or the previous stage ended).
    pub fn lap(&mut self, name: &str) {
        let now = Instant::now();
        let took = now - self.last;
        self.last = now;
        tracing::info!(stage = name, seconds = took.as_secs_f64(), "stage done");
        self.stages.push((name.to_string(), took));
    }

    /// The stages so far, in order, with their durations.
    pub fn stages(&self) -> &[(String, Duration)] {
        &self.stages
    }

    /// One line: the time since the clock started, then each stage's (whole seconds, stages
    /// under half a second left out).
    pub fn summary(&self) -> String {
        let parts: Vec<String> = self
            .stages
            .iter()
            .filter(|(_, d)| d.as_secs_f64() >= 0.5)
            .map(|(n, d)| format!("{n} {:.0} s", d.as_secs_f64()))
            .collect();
        let total = self.last - self.start;
        format!(
            "prepared in {:.0} s: {}",
            total.as_secs_f64(),
            parts.join(", ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_names_each_stage_that_took_time_in_order() {
        let mut c = StageClock::new();
        c.stages
            .push(("RSRP cache".into(), Duration::from_secs(31)));
        c.stages.push(("world".into(), Duration::from_millis(100)));
        c.stages
            .push(("training pairs".into(), Duration::from_secs(40)));
        c.last = c.start + Duration::from_millis(71_100);
        assert_eq!(
            c.summary(),
            "prepared in 71 s: RSRP cache 31 s, training pairs 40 s"
        );
    }
}
