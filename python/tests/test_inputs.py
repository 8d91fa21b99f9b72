"""Lenient inputs: every radio, planner, policy and environment function takes any real dtype and
array-likes (lists, tuples), converted as NumPy converts them; shapes are still checked, with
errors naming the expected shape."""

from __future__ import annotations

import numpy as np
import pytest

import dupac
from dupac.gym import DupacVecEnv

POINT = [[0, 0, 60], [10, -20, 80]]
FORMS = {
    "int": lambda a: np.asarray(a, dtype=np.int64),
    "float32": lambda a: np.asarray(a, dtype=np.float32),
    "list": lambda a: np.asarray(a).tolist(),
    "tuple": lambda a: tuple(map(tuple, np.atleast_2d(a).tolist())) if np.ndim(a) == 2 else tuple(np.asarray(a).tolist()),
}


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("fn", ["rsrp_dbm", "los", "best_site"])
def test_radio_queries_take_any_real_dtype(scenario, fn, form):
    want = getattr(scenario, fn)(np.asarray(POINT, dtype=np.float64))
    got = getattr(scenario, fn)(FORMS[form](POINT))
    if isinstance(want, tuple):
        assert all(np.array_equal(w, g) for w, g in zip(want, got))
    else:
        assert np.array_equal(want, got)


@pytest.mark.parametrize("form", FORMS)
def test_rsrp_class_takes_any_real_dtype_and_shape(scenario, form):
    values = [[-70, -90], [-110, -80]]
    want = scenario.rsrp_class(np.asarray(values, dtype=np.float64))
    assert want.shape == (2, 2)
    assert np.array_equal(scenario.rsrp_class(FORMS[form](values)), want)


def test_shapes_are_still_checked(scenario):
    with pytest.raises(ValueError, match=r"points: expected an array of shape \(N, 3\), got shape \(3,\)"):
        scenario.rsrp_dbm([0, 0, 60])
    with pytest.raises(ValueError, match="could not convert string to float"):
        scenario.rsrp_dbm([["a", "b", "c"]])


@pytest.mark.parametrize("form", FORMS)
def test_the_planner_takes_any_real_dtype(scenario, form):
    planner = dupac.Planner(scenario, coverage=False)
    pairs = scenario.pairs("eval")
    src, dst = pairs["source_m"][0], pairs["destination_m"][0]
    # Integer and float32 forms round the points: compare with float64 arrays of the same values.
    conv = FORMS[form]
    want = planner.shortest(np.asarray(conv(src), np.float64), np.asarray(conv(dst), np.float64))
    got = planner.shortest(conv(src), conv(dst))
    assert np.array_equal(got["waypoints_m"], want["waypoints_m"])


@pytest.mark.parametrize("form", ["float64", "list", "int"])
def test_a_policy_takes_any_real_dtype(trained, form):
    policy = dupac.Policy(str(trained["learned"]))
    obs = np.linspace(-1, 1, policy.obs_dim, dtype=np.float32)
    conv = {"float64": lambda a: a.astype(np.float64), "list": lambda a: a.tolist(), "int": lambda a: np.round(a).astype(np.int32)}[form]
    ref = obs if form != "int" else np.round(obs).astype(np.float32)
    w = policy.act(ref)
    g = policy.act(conv(obs))
    assert all(np.array_equal(a, b) for a, b in zip(w, g)) if isinstance(w, tuple) else np.array_equal(w, g)
    assert policy.value(conv(obs)) == policy.value(ref)
    batch = np.stack([obs, -obs])
    wb = policy.act_batch(batch if form != "int" else np.round(batch).astype(np.float32))
    gb = policy.act_batch(conv(batch))
    assert all(np.array_equal(a, b) for a, b in zip(wb, gb)) if isinstance(wb, tuple) else np.array_equal(wb, gb)


def test_the_raw_envs_take_any_real_dtype(scenario):
    env = dupac.Env(scenario)
    env.reset(seed=1)
    a = env.step(np.array([0.5, 0.0, 0.0]), 1)
    env.reset(seed=1)
    b = env.step([0.5, 0, 0], 1)
    assert np.array_equal(a[0], b[0]) and a[1] == b[1]
    vec = DupacVecEnv(2, scenario)
    vec.reset(seed=0)
    x = vec._vec.step(np.zeros((2, 3)), np.zeros(2, dtype=np.int64))
    vec.reset(seed=0)
    y = vec._vec.step([[0, 0, 0], [0, 0, 0]], [0, 0])
    assert np.array_equal(x[0], y[0])
