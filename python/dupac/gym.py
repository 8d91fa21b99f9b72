"""Gymnasium interface of the DUPAC environment.

``DupacEnv`` is one UAV (``gymnasium.Env``); ``DupacVecEnv`` steps N of them in Rust per call
with the GIL released (``gymnasium.vector.VectorEnv``, autoreset in the same step). A step is one
decision of a policy: the move held for ``env.action_repeat`` MDP steps, the site held with it,
the rewards summed (frame skip), exactly as ``dupac train``'s rollout workers step.

Spaces:

* observation: ``Box(-inf, inf, (obs_dim,), float32)`` (its fields: ``env.observation_fields()``);
* action, DUPAC (``env.association = "learned"``): ``Dict(move=Box(-1, 1, (3,)), site=Discrete(M))``;
  the base method (``"a3"``, A3 picks the site): ``Box(-1, 1, (3,))``, the move only. Moves are in
  units of ``env.max_step_m``; the environment bounds a larger one per ``env.action_clip``.

DUPAC's own trainer chooses the site at every MDP step of a decision (``env.site_every_step``)
from its site head; a Gymnasium step holds the site for the decision. With
``env.action_repeat = 1`` the two coincide; :func:`dupac.fly` flies a trained DUPAC policy with
the per-step site.
"""

from __future__ import annotations

from typing import Any, Sequence

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from ._dupac import Env as _Env
from ._dupac import Scenario
from ._dupac import VecEnv as _VecEnv

__all__ = ["DupacEnv", "DupacVecEnv", "make_scenario"]


def make_scenario(
    scenario: Scenario | None = None,
    config: str | None = None,
    set: Sequence[str] = (),
    association: str | None = None,
    policy: str | None = None,
) -> Scenario:
    """The given scenario, or a new one from ``config``, ``set``, ``association`` and ``policy``
    (see :class:`dupac.Scenario`)."""
    if scenario is not None:
        return scenario
    return Scenario(config=config, set=list(set), association=association, policy=policy)


def _spaces(obs_dim: int, num_sites: int, learned: bool):
    observation = spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32)
    move = spaces.Box(-1.0, 1.0, (3,), np.float32)
    action = spaces.Dict({"move": move, "site": spaces.Discrete(num_sites)}) if learned else move
    return observation, action


def _split_action(action: Any, learned: bool) -> tuple[np.ndarray, int]:
    if learned:
        if not isinstance(action, dict) or "move" not in action or "site" not in action:
            raise ValueError("DUPAC's action is a dict {'move': (3,) array, 'site': int}")
        return np.asarray(action["move"], dtype=np.float64).reshape(-1), int(action["site"])
    return np.asarray(action, dtype=np.float64).reshape(-1), 0


class DupacEnv(gymnasium.Env):
    """One UAV flying the pairs of a scenario (``split="train"``: the training pool; ``"eval"``:
    the held-out pairs). ``reset(seed=s)`` seeds the episode draws as the trainer's worker does;
    ``reset(options={"pair": k, "reversed": False})`` flies pair k of the split.

    ``info`` holds the last MDP step's record: ``outcome`` (``"goal"``, ``"collision"``,
    ``"out_of_bounds"``, ``"time_limit"`` or ``None``), ``position_m``, ``serving``,
    ``serving_rsrp_dbm``, ``best_site``, ``best_rsrp_dbm``, ``rsrp_class``, ``los``,
    ``handover``, ``ping_pong``, ``distance_flown_m``, ``distance_to_goal_m``, ``pair_id``;
    ``env.unwrapped.last_steps()`` every MDP step of the decision.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        scenario: Scenario | None = None,
        *,
        config: str | None = None,
        set: Sequence[str] = (),
        association: str | None = None,
        policy: str | None = None,
        split: str = "train",
    ) -> None:
        self.scenario = make_scenario(scenario, config, set, association, policy)
        self._env = _Env(self.scenario, split=split)
        self.learned = self._env.learned_site
        self.observation_space, self.action_space = _spaces(
            self._env.obs_dim, self._env.num_sites, self.learned
        )

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        options = options or {}
        obs = self._env.reset(
            seed=None if seed is None else int(seed) % 2**64,
            pair=options.get("pair"),
            reversed=options.get("reversed"),
        )
        return obs, {}

    def step(self, action):
        move, site = _split_action(action, self.learned)
        return self._env.step(move, site)

    def last_steps(self) -> dict:
        """Every MDP step of the last decision (see :meth:`dupac.Env.last_steps`)."""
        return self._env.last_steps()

    def observation_fields(self):
        """The observation's fields: ``(name, start, end, meaning)``."""
        return self._env.observation_fields()


def _per_env(name: str, value: Any, n: int, dtype) -> list | None:
    """``value`` as a list for the binding: ``None``, one value for all, or one per env."""
    if value is None:
        return None
    a = np.asarray(value)
    if a.ndim == 0:
        return [a.astype(dtype).item()]
    a = a.reshape(-1)
    if a.shape[0] != n:
        raise ValueError(f"{name}: {a.shape[0]} values for {n} environments")
    return [x.item() for x in a.astype(dtype)]


class DupacVecEnv(VectorEnv):
    """``num_envs`` UAVs of one scenario stepped together in Rust on ``num_threads`` threads
    (default: one per core, or ``RAYON_NUM_THREADS``), the GIL released. Each environment draws
    only from its own RNG: the results do not depend on the number of threads.

    Autoreset in the same step (``AutoresetMode.SAME_STEP``): an environment whose episode ends
    is reset at once; its last observation is in ``info["final_obs"]`` and what ended in
    ``info["final_info"]`` (a dict of arrays: ``outcome`` −1 none, 0 goal, 1 collision, 2 out of
    bounds, 3 time limit; ``pair_id``; ``episode`` ``{"r": return, "l": decisions}`` as
    Gymnasium's ``RecordEpisodeStatistics`` names them; ``distance_flown_m``,
    ``distance_to_goal_m``), both with their ``_``-prefixed masks (rows where an episode ended).

    ``reset(seed=s)`` seeds environment i with ``s + i``; ``seed=[s0, s1, …]`` each with its own.
    ``reset(options={"pair": k, "reversed": r, "reset_mask": m})``: a value, or one per
    environment (``pair`` −1: drawn; ``reversed`` −1: drawn); only the environments in
    ``reset_mask`` are reset. ``send(actions)`` starts a step and returns at once, ``recv()``
    returns its result (EnvPool's asynchronous pair): the environments step while Python does
    other work.
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        num_envs: int,
        scenario: Scenario | None = None,
        *,
        config: str | None = None,
        set: Sequence[str] = (),
        association: str | None = None,
        policy: str | None = None,
        split: str = "train",
        seed: int = 0,
        num_threads: int = 0,
    ) -> None:
        self.scenario = make_scenario(scenario, config, set, association, policy)
        self._vec = _VecEnv(self.scenario, num_envs, split=split, seed=seed, num_threads=num_threads)
        probe = _Env(self.scenario, split=split)
        self.num_envs = num_envs
        self.learned = probe.learned_site
        self.single_observation_space, self.single_action_space = _spaces(
            probe.obs_dim, probe.num_sites, self.learned
        )
        self.observation_space = gymnasium.vector.utils.batch_space(
            self.single_observation_space, num_envs
        )
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)

    @property
    def num_threads(self) -> int:
        """Threads the environments are stepped on."""
        return self._vec.num_threads

    def reset(self, *, seed: int | Sequence[int] | None = None, options: dict | None = None):
        n = self.num_envs
        if seed is not None:
            first = seed if np.ndim(seed) == 0 else np.asarray(seed).reshape(-1)[0]
            self._np_random, _ = gymnasium.utils.seeding.np_random(int(first))
        options = options or {}
        unknown = set(options) - {"pair", "reversed", "reset_mask"}
        if unknown:
            raise ValueError(f"unknown reset options {sorted(unknown)}: expected pair, reversed, reset_mask")
        seeds = None
        if seed is not None:
            seeds = [int(x) % 2**64 for x in np.asarray(seed, dtype=object).reshape(-1)]
            if len(seeds) not in (1, n):
                raise ValueError(f"seed: {len(seeds)} values for {n} environments")
        reversed_ = options.get("reversed")
        if reversed_ is not None:
            reversed_ = np.where(np.asarray(reversed_) == -1, -1, np.asarray(reversed_).astype(bool))
        obs = self._vec.reset(
            seed=seeds,
            pair=_per_env("pair", options.get("pair"), n, np.int64),
            reversed=_per_env("reversed", reversed_, n, np.int8),
            mask=_per_env("reset_mask", options.get("reset_mask"), n, bool),
        )
        return obs, {}

    def _actions(self, actions) -> tuple[np.ndarray, np.ndarray]:
        n = self.num_envs
        if self.learned:
            if not isinstance(actions, dict) or "move" not in actions or "site" not in actions:
                raise ValueError("DUPAC's actions are a dict {'move': (N, 3) array, 'site': (N,) ints}")
            moves = np.asarray(actions["move"], dtype=np.float64).reshape(n, 3)
            sites = np.asarray(actions["site"]).astype(np.int64).reshape(n)
        else:
            moves = np.asarray(actions, dtype=np.float64).reshape(n, 3)
            sites = np.zeros(n, dtype=np.int64)
        return np.ascontiguousarray(moves), np.ascontiguousarray(sites)

    @staticmethod
    def _result(out):
        obs, rew, term, trunc, final_obs, fin = out
        done = term | trunc
        final_info = {
            "outcome": fin["outcome"],
            "_outcome": done,
            "pair_id": fin["pair_id"],
            "_pair_id": done,
            "episode": {
                "r": fin["episode_return"],
                "l": fin["episode_length"],
                "_r": done,
                "_l": done,
            },
            "_episode": done,
            "distance_flown_m": fin["distance_flown_m"],
            "_distance_flown_m": done,
            "distance_to_goal_m": fin["distance_to_goal_m"],
            "_distance_to_goal_m": done,
        }
        info = {
            "final_obs": final_obs,
            "_final_obs": done,
            "final_info": final_info,
            "_final_info": done,
            "outcome": fin["outcome"],
            "_outcome": done,
        }
        return obs, rew, term, trunc, info

    def step(self, actions):
        return self._result(self._vec.step(*self._actions(actions)))

    def send(self, actions) -> None:
        """Starts a step with ``actions`` and returns at once; :meth:`recv` returns its result."""
        self._vec.send(*self._actions(actions))

    def recv(self):
        """The result of the step started by :meth:`send`, as :meth:`step` returns it."""
        return self._result(self._vec.recv())


gymnasium.register(
    id="dupac/Dupac-v0",
    entry_point="dupac.gym:DupacEnv",
    vector_entry_point="dupac.gym:DupacVecEnv",
)
