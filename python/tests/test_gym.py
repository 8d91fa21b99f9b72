"""The Gymnasium interface: Gymnasium's own checker, spaces, seeding, and the vectorised env
against the single one."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import dupac
from dupac.gym import DupacEnv, DupacVecEnv


@pytest.mark.parametrize("which", ["scenario", "base_scenario"])
def test_gymnasium_check_env_passes(which, request):
    sc = request.getfixturevalue(which)
    env = gym.make("dupac/Dupac-v0", scenario=sc, disable_env_checker=True)
    check_env(env.unwrapped, skip_render_check=True)


def test_spaces_follow_the_association(scenario, base_scenario):
    learned = DupacEnv(scenario)
    assert isinstance(learned.action_space, gym.spaces.Dict)
    assert learned.action_space["site"].n == scenario.num_sites == 8
    assert learned.action_space["move"].shape == (3,)
    base = DupacEnv(base_scenario)
    assert isinstance(base.action_space, gym.spaces.Box) and base.action_space.shape == (3,)
    assert learned.observation_space.shape == (learned.unwrapped._env.obs_dim,)
    fields = learned.observation_fields()
    assert fields[0][0] == "position" and fields[-1][2] == learned.observation_space.shape[0]


def _rollout(env, seed, actions):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, te, tr, info = env.step(a)
        out.append(obs)
        out.append(np.array([r, te, tr], dtype=np.float64))
        if te or tr:
            break
    return out


def test_same_seed_same_episode_different_seed_different_episode(scenario):
    rng = np.random.default_rng(0)
    env = DupacEnv(scenario)
    actions = [{"move": rng.uniform(-1, 1, 3), "site": int(rng.integers(8))} for _ in range(40)]
    a = _rollout(env, 5, actions)
    b = _rollout(DupacEnv(scenario), 5, actions)
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    c = _rollout(env, 6, actions)
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_a_pair_is_chosen_by_options(scenario):
    env = DupacEnv(scenario, split="eval")
    pairs = scenario.pairs("eval")
    env.reset(seed=0, options={"pair": 3, "reversed": False})
    env.step({"move": np.zeros(3), "site": 0})
    info_steps = env.last_steps()
    # The first step starts at the pair's source.
    first = info_steps["position_m"][0]
    assert np.linalg.norm(first - pairs["source_m"][3]) <= 3.0
    with pytest.raises(ValueError, match="pair 99"):
        env.reset(options={"pair": 99})


def test_the_vectorised_env_steps_each_env_as_the_single_one_does(base_scenario):
    """Environment i of a VecEnv seeded s is the single env seeded s + i, step for step, through
    its autoresets."""
    n, steps = 4, 60
    vec = DupacVecEnv(n, base_scenario, seed=0)
    rng = np.random.default_rng(1)
    moves = rng.uniform(-1, 1, (steps, n, 3))
    obs, _ = vec.reset(seed=10)
    singles = [DupacEnv(base_scenario) for _ in range(n)]
    sobs = [s.reset(seed=10 + i)[0] for i, s in enumerate(singles)]
    assert np.array_equal(obs, np.stack(sobs))
    ended = 0
    for t in range(steps):
        obs, rew, term, trunc, info = vec.step(moves[t])
        for i, s in enumerate(singles):
            o, r, te, tr, _ = s.step(moves[t, i])
            assert r == rew[i] and te == term[i] and tr == trunc[i]
            if te or tr:
                ended += 1
                assert np.array_equal(o, info["final_obs"][i]) and info["_final_obs"][i]
                assert info["outcome"][i] >= 0
                # The single env resets as the vectorised one did: from its own RNG.
                o, _ = s.reset()
            assert np.array_equal(o, obs[i])
    assert ended > 0, "no episode ended: the autoreset was not exercised"
    assert vec.observation_space.shape == (n, obs.shape[1])
