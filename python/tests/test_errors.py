"""Bad input is a clear exception naming what was wrong, never a crash."""

from __future__ import annotations

import numpy as np
import pytest

import dupac


def test_bad_configuration_names_the_key(small_set):
    with pytest.raises(ValueError, match="no_such_key"):
        dupac.Scenario(set=[*small_set, "env.no_such_key=1"])
    with pytest.raises(ValueError, match="association"):
        dupac.Scenario(set=small_set, association="oracle")


def test_bad_points_and_splits(scenario):
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        scenario.rsrp_dbm(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="not finite"):
        scenario.los(np.array([[0.0, np.nan, 50.0]]))
    with pytest.raises(ValueError, match="split"):
        scenario.pairs("test")
    with pytest.raises(ValueError, match="resolution_m"):
        scenario.coverage(60.0, 0.0)


def test_bad_actions(scenario):
    env = dupac.Env(scenario)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="not finite"):
        env.step(np.array([np.nan, 0.0, 0.0]), 0)
    with pytest.raises(ValueError, match="out of range"):
        env.step(np.zeros(3), 8)
    with pytest.raises(ValueError, match=r"move: expected an array of shape \(3,\), got shape \(2,\)"):
        env.step(np.zeros(2), 0)
    vec = dupac.VecEnv(scenario, 2)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        vec.step(np.zeros((3, 3)), np.zeros(3, dtype=np.int64))


def test_a_file_that_is_not_a_policy_is_refused_with_its_name(tmp_path):
    bad = tmp_path / "policy.bin"
    bad.write_bytes(b"not a policy at all")
    with pytest.raises(ValueError, match="policy.bin"):
        dupac.Policy(str(bad))
    with pytest.raises(ValueError, match="missing.bin"):
        dupac.Policy(str(tmp_path / "missing.bin"))
