"""`dupac export` writes a policy that NumPy alone runs: its actions match the Rust forward pass
to 1e-5, and the official safetensors reader reads the same tensors."""

from __future__ import annotations

import json

import numpy as np
import pytest

import dupac
from dupac.export import ExportedPolicy, read_safetensors
from dupac.gym import DupacEnv

from conftest import prerequisite, run_dupac


def _observations(sc, n=200):
    env = DupacEnv(sc)
    rng = np.random.default_rng(0)
    obs, _ = env.reset(seed=0)
    out = [obs]
    while len(out) < n:
        a = env.action_space.sample()
        obs, _, te, tr, _ = env.step(a)
        out.append(obs)
        if te or tr:
            obs, _ = env.reset(seed=int(rng.integers(1 << 31)))
            out.append(obs)
    return np.stack(out)


@pytest.mark.parametrize("assoc", ["a3", "learned"])
def test_numpy_reproduces_the_policys_actions(trained, small_set, dupac_bin, tmp_path, assoc):
    path = trained[assoc]
    run_dupac(dupac_bin, small_set, "export", "--policy", str(path), "--out", str(tmp_path))
    meta = json.loads((tmp_path / "policy.json").read_text())
    pol = ExportedPolicy.load(tmp_path)
    rust = dupac.Policy(str(path))
    assert meta["obs_dim"] == rust.obs_dim and meta["n_sites"] == rust.n_sites
    assert meta["site_head"] == ("equivariant" if assoc == "learned" else "none")
    fields = meta["observation"]["fields"]
    assert fields[0]["start"] == 0 and fields[-1]["end"] == meta["obs_dim"]
    sc = dupac.Scenario(set=small_set, policy=str(path))
    worst = 0.0
    for obs in _observations(sc):
        m_np, s_np = pol.act(obs)
        m_rs, s_rs = rust.act(obs)
        worst = max(worst, float(np.max(np.abs(m_np - m_rs))))
        assert s_np == s_rs
        assert abs(pol.forward(obs)[2] - rust.value(obs)) < 1e-4
    assert worst < 1e-5, worst


def test_the_official_safetensors_reader_reads_the_export(trained, small_set, dupac_bin, tmp_path):
    try:
        from safetensors.numpy import load_file
    except ImportError:
        prerequisite(False, "the safetensors package (pip install './python[test]')")
    run_dupac(dupac_bin, small_set, "export", "--policy", str(trained["learned"]), "--out", str(tmp_path))
    ours = read_safetensors(tmp_path / "policy.safetensors")
    theirs = load_file(str(tmp_path / "policy.safetensors"))
    assert sorted(ours) == sorted(theirs)
    for k in ours:
        assert ours[k].dtype == theirs[k].dtype and np.array_equal(ours[k], theirs[k]), k
