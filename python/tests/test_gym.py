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


def test_make_vec_returns_the_rust_vector_env(scenario):
    for mode in ("vector_entry_point", None):
        kw = {} if mode is None else {"vectorization_mode": mode}
        vec = gym.make_vec("dupac/Dupac-v0", num_envs=3, scenario=scenario, **kw)
        assert isinstance(vec, DupacVecEnv) and vec.num_envs == 3
        obs, _ = vec.reset(seed=0)
        assert vec.observation_space.contains(obs)
        out = vec.step(vec.action_space.sample())
        assert vec.observation_space.contains(out[0])
        vec.close()


def _random_actions(vec, steps, seed):
    rng = np.random.default_rng(seed)
    n, m = vec.num_envs, vec.single_action_space["site"].n
    return [{"move": rng.uniform(-1, 1, (n, 3)), "site": rng.integers(0, m, n)} for _ in range(steps)]


def test_the_vector_env_matches_gymnasiums_own_over_single_envs(scenario):
    """Gymnasium's SyncVectorEnv over DupacEnv, same-step autoreset, is the reference: the Rust
    vector env on 2 threads gives the same observations, rewards, ends, final observations and
    final infos, step for step."""
    n, steps = 4, 80
    ours = DupacVecEnv(n, scenario, num_threads=2)
    ref = gym.vector.SyncVectorEnv(
        [lambda: DupacEnv(scenario) for _ in range(n)], autoreset_mode="SameStep"
    )
    o1, _ = ours.reset(seed=7)
    o2, _ = ref.reset(seed=7)
    assert np.array_equal(o1, o2)
    returns, ended = np.zeros(n), 0
    for a in _random_actions(ours, steps, 3):
        o1, r1, te1, tr1, i1 = ours.step(a)
        o2, r2, te2, tr2, i2 = ref.step(a)
        returns += r2
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2)
        assert np.array_equal(te1, te2) and np.array_equal(tr1, tr2)
        done = te1 | tr1
        assert np.array_equal(i1["_final_obs"], done) and np.array_equal(i1["_final_info"], done)
        for k in np.flatnonzero(done):
            ended += 1
            assert np.array_equal(i1["final_obs"][k], i2["final_obs"][k])
            fin = i1["final_info"]
            assert fin["pair_id"][k] == i2["final_info"]["pair_id"][k]
            assert fin["episode"]["r"][k] == pytest.approx(returns[k], rel=1e-12)
            assert fin["distance_flown_m"][k] == i2["final_info"]["distance_flown_m"][k]
            names = ("goal", "collision", "out_of_bounds", "time_limit")
            assert names[fin["outcome"][k]] == (i2["final_info"]["outcome"][k] or "time_limit")
            returns[k] = 0.0
    assert ended > 0, "no episode ended: the autoreset was not exercised"


def test_threads_do_not_change_the_results_and_send_recv_is_step(scenario):
    runs = []
    for threads, split_step in ((1, False), (2, False), (2, True)):
        vec = DupacVecEnv(5, scenario, num_threads=threads)
        assert vec.num_threads == threads
        out = [vec.reset(seed=3)[0]]
        for a in _random_actions(vec, 40, 5):
            if split_step:
                vec.send(a)
                o, r, te, tr, info = vec.recv()
            else:
                o, r, te, tr, info = vec.step(a)
            out += [o, r, te, tr, info["final_obs"]]
        runs.append(out)
    for other in runs[1:]:
        assert all(np.array_equal(x, y) for x, y in zip(runs[0], other))


def test_a_step_in_flight_must_be_received_first(scenario):
    vec = DupacVecEnv(2, scenario)
    vec.reset(seed=0)
    a = _random_actions(vec, 1, 0)[0]
    with pytest.raises(RuntimeError, match="nothing in flight"):
        vec.recv()
    vec.send(a)
    with pytest.raises(RuntimeError, match="in flight"):
        vec.step(a)
    with pytest.raises(RuntimeError, match="in flight"):
        vec.reset()
    vec.recv()
    vec.step(a)


def test_reset_takes_a_seed_per_env_options_and_a_mask(scenario):
    n = 3
    vec = DupacVecEnv(n, scenario, split="eval")
    singles = [DupacEnv(scenario, split="eval") for _ in range(n)]
    obs, _ = vec.reset(seed=[11, 5, 9])
    assert all(np.array_equal(obs[i], s.reset(seed=seed)[0]) for i, (s, seed) in enumerate(zip(singles, [11, 5, 9])))
    obs, _ = vec.reset(seed=0, options={"pair": [2, 0, 1], "reversed": 0})
    for i, k in enumerate([2, 0, 1]):
        want, _ = singles[i].reset(seed=i, options={"pair": k, "reversed": False})
        assert np.array_equal(obs[i], want)
    before = obs.copy()
    obs, _ = vec.reset(options={"pair": 3, "reset_mask": [False, True, False]})
    assert np.array_equal(obs[0], before[0]) and np.array_equal(obs[2], before[2])
    assert not np.array_equal(obs[1], before[1])
    with pytest.raises(ValueError, match="2 values for 3"):
        vec.reset(seed=[1, 2])
    with pytest.raises(ValueError, match="unknown reset options"):
        vec.reset(options={"pairs": 1})
