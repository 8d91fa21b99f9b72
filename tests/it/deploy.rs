//! What deploy/README.md relies on outside the namespace rehearsal (`netns::`): the default
//! scenario runs from any working directory (its data is built into the binary), a file at the
//! default path is still read (and its errors name it), `dupac config > run.toml` round-trips,
//! the actor unit's start script picks the actor's own (secured) Zenoh config, and the systemd
//! units pass `systemd-analyze verify`.

use crate::support::prerequisite;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// `dupac ARGS` run in `dir` (not the repository root, unlike `support::dupac_cmd`).
fn dupac_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dupac"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .output()
        .expect("run dupac")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// From a directory without `data/`, the default (Midtown) scenario builds the same world as
/// from the repository root, says at `-v` that it used the built-in copies, and a path that is
/// not the default one is still an error naming the file.
#[test]
fn the_default_scenario_runs_from_any_directory() {
    let dir = tempfile::tempdir().expect("tmp");
    let away = dupac_in(dir.path(), &["-v", "radio", "sites"]);
    let err = text(&away.stderr);
    assert!(away.status.success(), "{err}");
    for file in [
        "data/nyc_midtown_buildings.geojson",
        "data/nyc_midtown_cells.csv",
    ] {
        assert!(
            err.contains(&format!("no {file} in ")) && err.contains("built into this binary"),
            "{file}: {err}"
        );
    }
    let home = dupac_in(&repo(), &["-v", "radio", "sites"]);
    assert!(home.status.success(), "{}", text(&home.stderr));
    assert!(!text(&home.stderr).contains("built into this binary"));
    assert_eq!(
        text(&away.stdout),
        text(&home.stdout),
        "the built-in copies give other sites than data/"
    );
    assert!(text(&away.stdout).lines().count() > 30);

    let other = dupac_in(
        dir.path(),
        &[
            "--set",
            "scenario.buildings_file=./data/nyc_midtown_buildings.geojson",
            "radio",
            "sites",
        ],
    );
    let err = text(&other.stderr);
    assert!(!other.status.success());
    assert!(
        err.contains("cannot read ./data/nyc_midtown_buildings.geojson"),
        "{err}"
    );
}

/// A file at the default path is read, not replaced by the built-in copy: a broken one is an
/// error naming it.
#[test]
fn a_file_at_the_default_path_is_read_and_its_errors_name_it() {
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::create_dir(dir.path().join("data")).expect("mkdir");
    std::fs::copy(
        repo().join("data/nyc_midtown_buildings.geojson"),
        dir.path().join("data/nyc_midtown_buildings.geojson"),
    )
    .expect("copy buildings");
    std::fs::write(
        dir.path().join("data/nyc_midtown_cells.csv"),
        "latitude,longitude,enb\n40.75,-73.98,1\n",
    )
    .expect("write cells");
    let out = dupac_in(dir.path(), &["-v", "radio", "sites"]);
    let err = text(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("data/nyc_midtown_cells.csv:1: missing column `lat`"),
        "{err}"
    );
    assert!(!err.contains("built into this binary"), "{err}");
}

/// `dupac config > run.toml` (with `--set` edits) is a config `--config run.toml` reads back
/// to the same values.
#[test]
fn config_output_round_trips_as_run_toml() {
    let dir = tempfile::tempdir().expect("tmp");
    let first = dupac_in(
        dir.path(),
        &[
            "--set",
            "distributed.run=site-a",
            "--set",
            "ppo.hidden=[32, 32]",
            "config",
        ],
    );
    assert!(first.status.success(), "{}", text(&first.stderr));
    std::fs::write(dir.path().join("run.toml"), &first.stdout).expect("write run.toml");
    let again = dupac_in(dir.path(), &["--config", "run.toml", "config"]);
    assert!(again.status.success(), "{}", text(&again.stderr));
    assert_eq!(text(&again.stdout), text(&first.stdout));
    let plain = dupac_in(dir.path(), &["config"]);
    assert_ne!(text(&plain.stdout), text(&first.stdout));
    assert!(text(&first.stdout).contains("run = \"site-a\""));
}

/// deploy/systemd/actor-start.sh (the actor unit's `ExecStart`, given `%i`): the actor's own
/// `actor-<id>.json5` when it exists (a secured run), else the shared `actor.json5`; none is
/// an error; the router and extra arguments are passed on.
#[test]
fn the_actor_unit_uses_the_actors_own_zenoh_config() {
    let unit = std::fs::read_to_string(repo().join("deploy/systemd/dupac-actor@.service"))
        .expect("read the unit");
    assert!(
        unit.lines()
            .any(|l| l == "ExecStart=/usr/local/lib/dupac/actor-start.sh %i"),
        "{unit}"
    );
    let dir = tempfile::tempdir().expect("tmp");
    let fake = dir.path().join("dupac");
    std::fs::write(&fake, "#!/bin/sh\necho \"ARGS $*\"\n").expect("write fake dupac");
    make_executable(&fake);
    let zenoh = dir.path().join("zenoh");
    std::fs::create_dir(&zenoh).expect("mkdir");
    let start = |id: &str| -> Output {
        Command::new("sh")
            .arg(repo().join("deploy/systemd/actor-start.sh"))
            .arg(id)
            .env("DUPAC_CONFIG", "/etc/dupac/run.toml")
            .env("DUPAC_ZENOH_DIR", &zenoh)
            .env("DUPAC_ROUTER", "tls/router:7447")
            .env("DUPAC_BIN", &fake)
            .env("DUPAC_ACTOR_ARGS", "--threads 2")
            .output()
            .expect("run actor-start.sh")
    };

    let out = start("3");
    assert!(!out.status.success(), "no config at all must fail");
    assert!(text(&out.stderr).contains("actor-3.json5"));

    std::fs::write(zenoh.join("actor.json5"), "{}").expect("write");
    let out = start("3");
    assert!(out.status.success(), "{}", text(&out.stderr));
    let z = zenoh.display();
    assert!(
        text(&out.stdout).contains(&format!(
            "ARGS --config /etc/dupac/run.toml --quiet actor --id 3 --zenoh-config {z}/actor.json5 --connect tls/router:7447 --threads 2"
        )),
        "{}",
        text(&out.stdout)
    );

    std::fs::write(zenoh.join("actor-3.json5"), "{}").expect("write");
    let out = start("3");
    assert!(
        text(&out.stdout).contains(&format!("--zenoh-config {z}/actor-3.json5 ")),
        "{}",
        text(&out.stdout)
    );
    let out = start("4");
    assert!(
        text(&out.stdout).contains(&format!("--zenoh-config {z}/actor.json5 ")),
        "{}",
        text(&out.stdout)
    );
}

#[cfg(unix)]
fn make_executable(p: &Path) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o755)).expect("chmod");
}

/// `systemd-analyze verify` of every unit in deploy/systemd, in a root holding what
/// deploy/README.md installs (the binary and start scripts at the units' paths, as stubs) and
/// the system's own unit directory: no error or warning.
#[test]
fn the_systemd_units_verify() {
    let analyze = Command::new("systemd-analyze").arg("--version").output();
    let system_units = ["/usr/lib/systemd/system", "/lib/systemd/system"]
        .into_iter()
        .map(Path::new)
        .find(|p| p.join("multi-user.target").exists());
    if !prerequisite(
        "systemd-analyze and the system's unit directory (systemd)",
        analyze.is_ok_and(|o| o.status.success()) && system_units.is_some(),
    ) {
        return;
    }
    let root = tempfile::tempdir().expect("tmp");
    let r = root.path();
    let copy_dir = |from: &Path, to: &Path| {
        std::fs::create_dir_all(to).expect("mkdir");
        for e in std::fs::read_dir(from).expect("read unit dir") {
            let e = e.expect("entry");
            if e.file_type().is_ok_and(|t| t.is_file()) {
                std::fs::copy(e.path(), to.join(e.file_name())).expect("copy unit");
            }
        }
    };
    copy_dir(system_units.unwrap(), &r.join("usr/lib/systemd/system"));
    let units = r.join("etc/systemd/system");
    std::fs::create_dir_all(&units).expect("mkdir");
    let mut names = Vec::new();
    for e in std::fs::read_dir(repo().join("deploy/systemd")).expect("deploy/systemd") {
        let name = e.expect("entry").file_name().into_string().expect("utf-8");
        if name.ends_with(".service") {
            std::fs::copy(repo().join("deploy/systemd").join(&name), units.join(&name))
                .expect("copy");
            names.push(name.replace("@.", "@7."));
        }
    }
    names.sort();
    assert_eq!(
        names,
        [
            "dupac-actor@7.service",
            "dupac-learner.service",
            "dupac-router.service"
        ]
    );
    for stub in [
        "usr/local/bin/dupac",
        "usr/local/lib/dupac/learner-start.sh",
        "usr/local/lib/dupac/actor-start.sh",
        "usr/bin/flock",
    ] {
        let p = r.join(stub);
        std::fs::create_dir_all(p.parent().unwrap()).expect("mkdir");
        std::fs::write(&p, "#!/bin/sh\n").expect("stub");
        make_executable(&p);
    }
    std::fs::create_dir_all(r.join("etc/dupac")).expect("mkdir");
    std::fs::copy(
        repo().join("deploy/systemd/dupac.env.example"),
        r.join("etc/dupac/dupac.env"),
    )
    .expect("env file");
    let out = Command::new("systemd-analyze")
        .arg("verify")
        .arg(format!("--root={}", r.display()))
        .args(names.iter().map(|n| format!("/etc/systemd/system/{n}")))
        .env("SYSTEMD_LOG_LEVEL", "notice")
        .output()
        .expect("run systemd-analyze");
    let err = text(&out.stderr);
    assert!(out.status.success(), "systemd-analyze verify: {err}");
    assert!(err.trim().is_empty(), "systemd-analyze verify: {err}");
}

/// `make-certs.sh --certs-dir DIR`: the configs name the files where they will be installed
/// (`/etc/dupac/tls` for the units), not where they were made.
#[test]
fn certificates_made_elsewhere_name_their_installed_directory() {
    if !prerequisite(
        "openssl (deploy/tls/make-certs.sh needs it)",
        Command::new("openssl")
            .arg("version")
            .output()
            .is_ok_and(|o| o.status.success()),
    ) {
        return;
    }
    let dir = tempfile::tempdir().expect("tmp");
    let out = Command::new("bash")
        .arg(repo().join("deploy/tls/make-certs.sh"))
        .arg(dir.path())
        .args(["--certs-dir", "/etc/dupac/tls", "--router-host", "10.0.0.1"])
        .output()
        .expect("run make-certs.sh");
    assert!(out.status.success(), "{}", text(&out.stderr));
    for (file, names) in [
        ("actor-1.json5", "/etc/dupac/tls/actor-1.pem"),
        ("learner.json5", "/etc/dupac/tls/learner.key"),
        ("router.json5", "/etc/dupac/tls/ca.pem"),
    ] {
        let config = std::fs::read_to_string(dir.path().join(file)).expect("config");
        assert!(config.contains(names), "{file}: {config}");
        let made = dir.path().display().to_string();
        assert!(!config.contains(&made), "{file} names {made}");
    }
    let bad = Command::new("bash")
        .arg(repo().join("deploy/tls/make-certs.sh"))
        .arg(dir.path().join("b"))
        .args(["--certs-dir", "etc/dupac/tls"])
        .output()
        .expect("run make-certs.sh");
    assert_eq!(bad.status.code(), Some(2), "{}", text(&bad.stderr));
}

/// The certificates directory deploy/README.md makes (`run-certs`, holding `ca.key`) cannot be
/// committed by a plain `git add`.
#[test]
fn the_certificates_directory_is_ignored_by_git() {
    let git = Command::new("git")
        .args(["rev-parse", "--is-inside-work-tree"])
        .current_dir(repo())
        .output();
    if !prerequisite(
        "git and a git work tree of the repository",
        git.is_ok_and(|o| o.status.success()),
    ) {
        return;
    }
    for path in [
        "run-certs/ca.key",
        "run-certs/actor-1.key",
        "run-certs/router.json5",
    ] {
        let out = Command::new("git")
            .args(["check-ignore", "--no-index", "-q", path])
            .current_dir(repo())
            .status()
            .expect("git check-ignore");
        assert!(out.success(), "{path} is not ignored by git");
    }
}
