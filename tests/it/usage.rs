//! End-to-end tests of the command line's own manners: plain logs off a terminal, `-q`, each
//! error's cause once, endpoints and zenoh errors in words, arguments checked before any work,
//! help headings, completions, the manual page and the configuration's key reference.

use crate::support::{dupac_cmd, small_world_args};
use std::path::Path;
use std::process::{Output, Stdio};

fn run(args: &[&str]) -> Output {
    dupac_cmd()
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run dupac")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// `args` followed by the small procedural scenario whose cache lives in `dir`.
fn with_small_world(args: &[&str], dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    v.extend(small_world_args(dir));
    v
}

#[test]
fn logs_off_a_terminal_are_plain_text() {
    let dir = tempfile::tempdir().expect("tmp");
    let log = dir.path().join("log");
    let status = dupac_cmd()
        .args(["-v", "radio", "sites"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).expect("log file"))
        .status()
        .expect("run dupac");
    assert!(status.success());
    let written = std::fs::read_to_string(&log).expect("log");
    assert!(written.contains("loaded OSM buildings"), "{written}");
    assert!(
        !written.contains("\x1b["),
        "escape codes in a file: {written:?}"
    );
    // And through a pipe.
    let out = run(&["-v", "radio", "sites"]);
    let err = text(&out.stderr);
    assert!(err.contains("INFO") && !err.contains("\x1b["), "{err:?}");
}

#[test]
fn quiet_leaves_only_errors_in_the_log() {
    let dir = tempfile::tempdir().expect("tmp");
    let cache = dir.path().join("rsrp.bin");
    for quiet in [true, false] {
        // A file that is not a cache: stale, rebuilt with a warning.
        std::fs::write(&cache, b"not a cache").expect("write");
        let mut args = vec!["cache", "build"];
        if quiet {
            args.push("-q");
        }
        let a = with_small_world(&args, dir.path());
        let out = dupac_cmd()
            .args(&a)
            .stdin(Stdio::null())
            .output()
            .expect("run");
        let err = text(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert_eq!(!quiet, err.contains("stale"), "quiet {quiet}: {err}");
        if quiet {
            assert!(!err.contains("WARN"), "{err}");
        }
    }
}
