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

/// A log written to a file (as `dupac … 2>log`) or a pipe carries no ANSI escape codes.
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

/// `-q`: no warnings in the log (only errors); without it the same run warns.
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

/// A missing file's OS error is printed once, not once per level of the error chain.
#[test]
fn a_missing_file_names_its_cause_once() {
    for args in [
        &["config", "--config", "/nonexistent/dupac.toml"][..],
        &[
            "radio",
            "sites",
            "--set",
            "scenario.buildings_file=\"/nonexistent/city.geojson\"",
        ],
        &["fly", "--policy", "/nonexistent/policy.bin"],
        &["plan", "--pairs", "/nonexistent/pairs.jsonl"],
    ] {
        let out = run(args);
        let err = text(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(err.contains("/nonexistent/"), "{args:?}: {err}");
        assert_eq!(
            err.matches("No such file or directory").count(),
            1,
            "{args:?}: {err}"
        );
    }
}

/// A malformed endpoint is refused when the arguments are read, in one line that names it and
/// what is wrong; zenoh's own errors come without the source paths of zenoh's build.
#[test]
fn endpoints_and_zenoh_errors_are_in_words() {
    for (args, why) in [
        (
            &["monitor", "--connect", "tcp/300.1.1.1:7447"][..],
            "300.1.1.1 is not an IPv4 address",
        ),
        (
            &["router", "--listen", "tcp/127.0.0.1:99999"],
            "port \"99999\" is not a number",
        ),
        (
            &["actor", "--connect", "7447"],
            "expected PROTOCOL/HOST:PORT",
        ),
        (
            &["router", "--listen", "udp/0.0.0.0:7447"],
            "unknown protocol",
        ),
    ] {
        let out = run(args);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        let line = err.lines().next().unwrap_or_default();
        assert!(
            line.contains(args[2]) && line.contains(why),
            "{args:?}: {err}"
        );
    }
    // 192.0.2.1 (TEST-NET-1) is no address of this machine: zenoh cannot listen on it.
    let out = run(&["router", "--listen", "tcp/192.0.2.1:7447"]);
    let err = text(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("192.0.2.1"), "{err}");
    assert!(!err.contains(".rs:"), "zenoh's source locations: {err}");
}

/// `fly --pair` past the end of the pairs file fails before the world, its RSRP cache or any
/// guide path is built (no cache file appears), with the file and its size named.
#[test]
fn a_pair_past_the_end_fails_before_any_work() {
    let dir = tempfile::tempdir().expect("tmp");
    let pairs = dir.path().join("pairs.jsonl");
    std::fs::write(&pairs, "{}\n\n{}\n").expect("pairs");
    let pairs = pairs.display().to_string();
    for args in [
        // The policy is only checked to be readable before the pair (any file will do).
        &[
            "fly", "-q", "--policy", &pairs, "--pairs", &pairs, "--pair", "999",
        ][..],
        &["plan", "-q", "--pairs", &pairs, "--pair", "2"],
    ] {
        let a = with_small_world(args, dir.path());
        let out = dupac_cmd()
            .args(&a)
            .stdin(Stdio::null())
            .output()
            .expect("run");
        let err = text(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        let pair = args[args.len() - 1];
        assert!(
            err.contains(&format!("--pair {pair} but the file has 2 pairs")),
            "{args:?}: {err}"
        );
        assert!(
            !dir.path().join("rsrp.bin").exists(),
            "{args:?}: cache built"
        );
    }
}

/// Help groups the options: the shared ones under one heading, the Zenoh connection under its
/// own; one name (`--pair`) for a pair's line in every command.
#[test]
fn help_groups_options_under_headings() {
    let out = run(&["actor", "--help"]);
    let help = text(&out.stdout);
    let at = |s: &str| {
        help.find(s)
            .unwrap_or_else(|| panic!("{s} missing: {help}"))
    };
    let (zenoh, global) = (at("Zenoh connection:"), at("Global options:"));
    for (option, heading) in [
        ("--connect", zenoh),
        ("--config <FILE>", global),
        ("--quiet", global),
    ] {
        let pos = at(option);
        let next = [zenoh, global]
            .into_iter()
            .filter(|&h| h > heading)
            .min()
            .unwrap_or(help.len());
        assert!(
            pos > heading && pos < next,
            "{option} not under its heading: {help}"
        );
    }
    assert!(help.contains("only errors in the log"), "{help}");
    for command in ["fly", "plan"] {
        let help = text(&run(&[command, "--help"]).stdout);
        assert!(
            help.contains("--pair <N>") && !help.contains("--index"),
            "{help}"
        );
    }
}

#[test]
fn completions_and_the_manual_page_are_generated() {
    let out = run(&["completions", "bash"]);
    assert!(out.status.success());
    let bash = text(&out.stdout);
    assert!(
        bash.contains("_dupac") && bash.contains("complete"),
        "{bash}"
    );
    assert!(
        bash.contains("--connect"),
        "subcommands' options are completed"
    );
    let out = run(&["completions", "zsh"]);
    assert!(out.status.success() && text(&out.stdout).contains("#compdef dupac"));
    let out = run(&["man"]);
    assert!(out.status.success());
    let page = text(&out.stdout);
    assert!(
        page.contains(".TH dupac") && page.contains("completions"),
        "{page}"
    );
    let dir = tempfile::tempdir().expect("tmp");
    let out = run(&["man", "--dir", dir.path().to_str().expect("utf-8")]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    for page in ["dupac.1", "dupac-train.1", "dupac-fly.1"] {
        let t = std::fs::read_to_string(dir.path().join(page)).expect(page);
        assert!(t.contains(".TH"), "{page}");
    }
}

/// `dupac config --describe`: every key with its default and a description.
#[test]
fn config_describe_explains_every_key() {
    let out = run(&["config", "--describe"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let t = text(&out.stdout);
    assert!(
        t.contains("\n[radio]\n") && t.contains("radio.fc_ghz = 2.0\n"),
        "{t}"
    );
    let lines: Vec<&str> = t.lines().collect();
    let fc = lines
        .iter()
        .position(|l| *l == "radio.fc_ghz = 2.0")
        .expect("key");
    assert!(lines[fc + 1].contains("GHz"), "{}", lines[fc + 1]);
    // Every key line is followed by its description, indented.
    for (k, l) in lines.iter().enumerate() {
        if !l.is_empty() && !l.starts_with(' ') {
            assert!(
                lines.get(k + 1).is_some_and(|d| d.starts_with("    ")),
                "{l} has no description"
            );
        }
    }
}
