//! The child processes of a one-machine run (`dupac train` without `--single-process`): a free
//! loopback port for the learner's router, the common arguments of every child, signals, and
//! reaping the actors when the learner is done.

use anyhow::{Context, Result};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A free TCP port on the loopback interface.
pub fn free_port() -> Result<u16> {
    let l = std::net::TcpListener::bind("127.0.0.1:0").context("finding a free loopback port")?;
    Ok(l.local_addr()?.port())
}

pub fn signal(child: &Child, sig: i32) {
    // SAFETY: kill(2) with a pid we spawned and still own (not yet reaped).
    unsafe {
        libc::kill(child.id() as i32, sig);
    }
}

/// Common arguments of every child: the resolved configuration file, no progress bars (the
/// parent draws the run's), and the parent's log level (`--quiet`, `-v`…).
pub fn child(exe: &Path, config: &Path, global: &crate::global_args::GlobalArgs) -> Command {
    let mut c = Command::new(exe);
    c.arg("--config").arg(config).arg("--no-progress");
    if global.quiet {
        c.arg("--quiet");
    }
    for _ in 0..global.verbose {
        c.arg("-v");
    }
    c.stdin(Stdio::null());
    c
}

/// Reaps the actors: they leave on the learner's Stop; each gets a moment, then SIGTERM, then
/// SIGKILL.
pub fn reap(actors: &mut [Child]) {
    let deadline = Instant::now() + Duration::from_secs(5);
    for a in actors.iter_mut() {
        while Instant::now() < deadline {
            if let Ok(Some(_)) = a.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        if let Ok(None) = a.try_wait() {
            // An actor that missed the Stop (still starting, or joining as the run ended):
            // SIGTERM lets it finish its chunk and print its summary; SIGKILL after 10 s.
            signal(a, libc::SIGTERM);
            let grace = Instant::now() + Duration::from_secs(10);
            while Instant::now() < grace && matches!(a.try_wait(), Ok(None)) {
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = a.kill();
        }
        let _ = a.wait();
    }
}
