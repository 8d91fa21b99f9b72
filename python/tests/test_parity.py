"""The Python package runs the Rust environment and policies unchanged: a trained policy flown
step by step through the Gymnasium env, through `dupac.fly` and by the `dupac fly` binary gives
the same flight."""

from __future__ import annotations

import csv

import numpy as np
import pytest

import dupac
from dupac.gym import DupacEnv

from conftest import run_dupac


def _fly_in_python(sc, policy, pair):
    """The policy acted on the Gymnasium env's observations, one decision per step."""
    env = DupacEnv(sc, split="eval")
    obs, _ = env.reset(seed=0, options={"pair": pair, "reversed": False})
    rows = []
    while True:
        move, site = policy.act(obs)
        action = {"move": move, "site": site} if env.learned else move
        obs, r, te, tr, info = env.step(action)
        rows.append(env.last_steps())
        if te or tr:
            return {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}, info


@pytest.mark.parametrize("pair", [0, 5])
def test_the_gym_env_flies_a_policy_bit_for_bit_as_rust_does(trained, small_set, pair):
    path = trained["a3"]
    sc = dupac.Scenario(set=small_set, policy=str(path))
    policy = dupac.Policy(str(path))
    assert policy.n_sites == 0 and policy.obs_dim == DupacEnv(sc).observation_space.shape[0]
    py, info = _fly_in_python(sc, policy, pair)
    summary, rust = dupac.fly(sc, policy, pair=pair)
    assert summary["length"] == len(rust["step"]) == len(py["step"])
    for k in rust:
        assert np.array_equal(py[k], rust[k]), k
    assert info["outcome"] == summary["outcome"]


@pytest.mark.parametrize("assoc", ["a3", "learned"])
def test_dupac_fly_matches_the_binary(trained, small_set, dupac_bin, tmp_path, assoc):
    path = trained[assoc]
    sc = dupac.Scenario(set=small_set, policy=str(path))
    summary, steps = dupac.fly(sc, dupac.Policy(str(path)), pair=2)
    out = tmp_path / "fly"
    run_dupac(dupac_bin, small_set, "fly", "--policy", str(path), "--pair", "2", "--out", str(out))
    with open(out / "steps.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(steps["step"]) == summary["length"]
    # The records' per-step layout: positions and powers as f32, each read back exactly.
    for i, r in enumerate(rows):
        assert int(r["step"]) == steps["step"][i]
        for k, axis in (("x_m", 0), ("y_m", 1), ("z_m", 2)):
            assert np.float32(r[k]) == np.float32(steps["position_m"][i, axis])
        assert int(r["serving"]) == steps["serving"][i]
        assert np.float32(r["serving_rsrp_dbm"]) == np.float32(steps["serving_rsrp_dbm"][i])


def test_the_gym_env_flies_held_out_pairs_in_the_evaluation_fields(trained, small_set, dupac_bin, tmp_path):
    """Under the real channel a held-out pair flies in its validation realisation with its own
    measurement errors, in the Gymnasium env as in `dupac.fly` and the `dupac fly` binary (each
    entry point builds the episode with its field: a training field would give other RSRP,
    other rewards and another flight)."""
    path = trained["a3"]
    real = small_set + ["radio.channel.model=real"]
    sc = dupac.Scenario(set=real, policy=str(path))
    policy = dupac.Policy(str(path))
    for pair in (0, 3):
        py, info = _fly_in_python(sc, policy, pair)
        summary, rust = dupac.fly(sc, policy, pair=pair)
        assert summary["length"] == len(py["step"])
        for k in rust:
            assert np.array_equal(py[k], rust[k]), (pair, k)
        out = tmp_path / f"fly{pair}"
        run_dupac(dupac_bin, real, "fly", "--policy", str(path), "--pair", str(pair), "--out", str(out))
        with open(out / "steps.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        assert len(rows) == len(rust["step"])
        for i, r in enumerate(rows):
            want = np.float32(rust["serving_rsrp_dbm"][i])
            assert np.float32(r["serving_rsrp_dbm"]) == want, (pair, i)
            assert int(r["serving"]) == rust["serving"][i]
