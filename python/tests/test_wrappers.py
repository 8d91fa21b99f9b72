"""The hybrid action in the shapes other libraries take: a flat Box (SB3, CleanRL) and a Tuple.
Each wrapper passes Gymnasium's checker and steps the environment exactly as DUPAC's own dict
action does."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from dupac.gym import DupacEnv
from dupac.wrappers import FlatHybridAction, TupleHybridAction, flat_to_dict


@pytest.mark.parametrize("wrapper", [FlatHybridAction, TupleHybridAction])
def test_the_wrapped_env_passes_gymnasiums_checker(scenario, wrapper):
    check_env(wrapper(DupacEnv(scenario)), skip_render_check=True)


def test_the_flat_action_is_the_move_then_a_score_per_site(scenario):
    env = FlatHybridAction(DupacEnv(scenario))
    m = scenario.num_sites
    assert env.action_space.shape == (3 + m,)
    assert np.all(env.action_space.low == -1) and np.all(env.action_space.high == 1)
    scores = np.full(m, -0.5)
    scores[5] = 0.9
    flat = np.concatenate([[0.2, -0.1, 0.0], scores])
    assert env.action(flat)["site"] == 5
    assert np.array_equal(env.action(flat)["move"], [0.2, -0.1, 0.0])


@pytest.mark.parametrize("wrapper", [FlatHybridAction, TupleHybridAction])
def test_a_wrapped_step_is_the_dict_step(scenario, wrapper):
    wrapped, plain = wrapper(DupacEnv(scenario)), DupacEnv(scenario)
    o1, _ = wrapped.reset(seed=9)
    o2, _ = plain.reset(seed=9)
    assert np.array_equal(o1, o2)
    for _ in range(30):
        a = wrapped.action_space.sample()
        if wrapper is FlatHybridAction:
            d = {"move": a[:3], "site": int(np.argmax(a[3:]))}
        else:
            d = {"move": a[0], "site": int(a[1])}
        s1, s2 = wrapped.step(a), plain.step(d)
        assert np.array_equal(s1[0], s2[0]) and s1[1:4] == s2[1:4]
        assert s1[4]["serving"] == s2[4]["serving"]
        if s1[2] or s1[3]:
            break


def test_flat_actions_of_a_vector_env_map_row_by_row(scenario):
    m = scenario.num_sites
    flat = np.zeros((4, 3 + m))
    flat[np.arange(4), 3 + np.array([1, 0, 7, 3])] = 1.0
    d = flat_to_dict(flat, m)
    assert d["move"].shape == (4, 3) and list(d["site"]) == [1, 0, 7, 3]
    with pytest.raises(ValueError, match=r"expected \(…, 11\)"):
        flat_to_dict(np.zeros((4, 5)), m)


def test_the_base_methods_env_needs_no_wrapper_and_is_refused(base_scenario):
    with pytest.raises(ValueError, match="association='learned'"):
        FlatHybridAction(DupacEnv(base_scenario))
    with pytest.raises(ValueError, match="association='learned'"):
        TupleHybridAction(gym.make("dupac/Dupac-v0", scenario=base_scenario))
