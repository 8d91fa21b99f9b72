"""DUPAC's hybrid action for libraries that take one action space kind.

DUPAC's action is ``Dict(move=Box(-1, 1, (3,)), site=Discrete(M))``: a continuous move and the
serving site. Stable-Baselines3 takes no ``Dict`` action and CleanRL's continuous PPO a single
``Box``; libraries that take mixed actions (e.g. RLlib) take a ``Tuple``. These wrappers expose
the same action in those shapes; the environment under them is unchanged.

* :class:`FlatHybridAction` – ``Box(-1, 1, (3 + M,))``: the move, then a score per site; the site
  is the argmax of the scores (ties: the lowest index). A Gaussian policy over this box learns
  the site as it learns the move (the scores' scale does not matter, only their order).
* :class:`TupleHybridAction` – ``Tuple(Box(-1, 1, (3,)), Discrete(M))``.
* :func:`flat_to_dict` – the flat form's mapping, for vectors of actions (``(N, 3 + M)``).

Both wrap a :class:`dupac.gym.DupacEnv` with the learned association (``association="learned"``,
the default); the base method's action (``"a3"``) is already a ``Box`` and needs none.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

__all__ = ["FlatHybridAction", "TupleHybridAction", "flat_to_dict"]


def _hybrid(env: gymnasium.Env) -> tuple[spaces.Box, int]:
    space = env.action_space
    if not (
        isinstance(space, spaces.Dict)
        and isinstance(space.spaces.get("move"), spaces.Box)
        and isinstance(space.spaces.get("site"), spaces.Discrete)
    ):
        raise ValueError(
            f"the wrapped env's action space is {space}: expected DUPAC's hybrid action "
            "Dict(move=Box, site=Discrete) (association='learned')"
        )
    return space["move"], int(space["site"].n)


def flat_to_dict(action: Any, num_sites: int) -> dict:
    """A flat action ``(…, 3 + M)`` (the move, then a score per site) as DUPAC's dict: ``move``
    ``(…, 3)``, ``site`` ``(…)`` the argmax of the scores."""
    a = np.asarray(action, dtype=np.float64)
    if a.shape[-1:] != (3 + num_sites,):
        raise ValueError(f"flat action of shape {a.shape}: expected (…, {3 + num_sites}) (3 + M)")
    return {"move": a[..., :3], "site": np.argmax(a[..., 3:], axis=-1)}


class FlatHybridAction(gymnasium.ActionWrapper):
    """DUPAC's action as one ``Box(-1, 1, (3 + M,))``: the move, then a score per site (the site
    served is the argmax). For Stable-Baselines3 (``PPO("MlpPolicy", FlatHybridAction(env))``)
    and CleanRL's continuous PPO."""

    def __init__(self, env: gymnasium.Env) -> None:
        super().__init__(env)
        move, self.num_sites = _hybrid(env)
        low = np.concatenate([move.low, -np.ones(self.num_sites, np.float32)])
        high = np.concatenate([move.high, np.ones(self.num_sites, np.float32)])
        self.action_space = spaces.Box(low, high, dtype=np.float32)

    def action(self, action):
        d = flat_to_dict(action, self.num_sites)
        return {"move": d["move"], "site": int(d["site"])}


class TupleHybridAction(gymnasium.ActionWrapper):
    """DUPAC's action as ``Tuple(Box(-1, 1, (3,)), Discrete(M))``: (move, site)."""

    def __init__(self, env: gymnasium.Env) -> None:
        super().__init__(env)
        move, self.num_sites = _hybrid(env)
        self.action_space = spaces.Tuple((move, spaces.Discrete(self.num_sites)))

    def action(self, action):
        if not isinstance(action, (tuple, list)) or len(action) != 2:
            raise ValueError("expected the action (move, site)")
        return {"move": np.asarray(action[0], dtype=np.float64), "site": int(action[1])}
