"""Shared fixtures: the small procedural scenario of the Rust tests (tests/it/support.rs), the
`dupac` binary, and a base-method and a DUPAC policy trained once per session by it."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

import dupac

REPO = Path(__file__).resolve().parents[2]


def _on_ci() -> bool:
    return os.environ.get("CI", "") not in ("", "0", "false")


def prerequisite(ok: bool, what: str) -> None:
    """Skips visibly when `what` is missing, and fails on CI, where every test must run."""
    if ok:
        return
    if _on_ci():
        pytest.fail(f"prerequisite missing on CI: {what}")
    pytest.skip(f"prerequisite missing: {what}")


def small_world(d: Path) -> list[str]:
    """The Rust tests' small procedural scenario: a 500 m city, 8 sites, a coarse cache in `d`,
    short held-out pairs (two bins of 4) and a tiny PPO run."""
    return [
        "scenario.city=procedural",
        "scenario.procedural.size_m=500",
        "scenario.procedural.n_sites=8",
        "scenario.n_sites=8",
        "cache.horizontal_m=10",
        "cache.vertical_m=10",
        f'cache.path="{d / "rsrp.bin"}"',
        "pairs.min_m=40",
        "pairs.max_m=70",
        "pairs.eval_bins_m=[50, 60]",
        "pairs.eval_per_bin=4",
        "pairs.bin_tolerance=0.1",
        f'pairs.eval_file="{d / "eval.jsonl"}"',
        f'pairs.test_file="{d / "test.jsonl"}"',
        "train.num_envs=4",
        "train.num_steps=64",
        "train.pool_size=50",
        "train.checkpoint_every=2",
        "train.eval_every=2",
        "train.eval_pairs=8",
        "ppo.num_minibatches=2",
        "ppo.hidden=[32, 32]",
    ]


@pytest.fixture(scope="session")
def world_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("world")


@pytest.fixture(scope="session")
def small_set(world_dir) -> list[str]:
    return small_world(world_dir)


@pytest.fixture(scope="session")
def scenario(small_set) -> dupac.Scenario:
    return dupac.Scenario(set=small_set)


@pytest.fixture(scope="session")
def base_scenario(small_set) -> dupac.Scenario:
    return dupac.Scenario(set=small_set, association="a3")


@pytest.fixture(scope="session")
def dupac_bin() -> Path:
    """The `dupac` binary: $DUPAC_BIN, else target/{debug,release}/dupac, else on PATH."""
    env = os.environ.get("DUPAC_BIN")
    candidates = [Path(env)] if env else [REPO / "target/debug/dupac", REPO / "target/release/dupac"]
    found = next((c for c in candidates if c.is_file()), None)
    if found is None and shutil.which("dupac"):
        found = Path(shutil.which("dupac"))
    prerequisite(found is not None, "the dupac binary (cargo build; or set DUPAC_BIN)")
    return found


def run_dupac(dupac_bin: Path, small_set: list[str], *args: str, stdin: str | None = None) -> str:
    sets = [a for kv in small_set for a in ("--set", kv)]
    out = subprocess.run(
        [str(dupac_bin), "-q", *args, *sets],
        input=stdin,
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=600,
    )
    assert out.returncode == 0, f"dupac {' '.join(args)} failed:\n{out.stderr}"
    return out.stdout


@pytest.fixture(scope="session")
def trained(dupac_bin, small_set, tmp_path_factory) -> dict[str, Path]:
    """A base-method and a DUPAC policy of the small scenario (`dupac train --single-process`,
    1 024 decisions each)."""
    d = tmp_path_factory.mktemp("runs")
    out = {}
    for assoc in ("a3", "learned"):
        run = d / assoc
        run_dupac(
            dupac_bin,
            small_set,
            "train",
            "--single-process",
            "--association",
            assoc,
            "--out",
            str(run),
            "--set",
            "train.total_timesteps=1024",
        )
        out[assoc] = run / "policy.bin"
    return out
