"""DUPAC from Python: the UAV path-planning environment with assured connectivity.

The Rust core (``dupac._dupac``) holds a scenario (the configuration, the city, its sites and the
RSRP source), the environment one or N at a time, and trained policies; this package adds the
Gymnasium interface (:mod:`dupac.gym`).

* :class:`Scenario` – the configuration (``config=`` a TOML file, ``set=`` ``a.b=v`` overrides as
  ``dupac --set`` takes them), the radio queries on NumPy arrays (``rsrp_dbm``, ``los``,
  ``best_site``, ``rsrp_class``, ``coverage``, ``sites``) and the pairs (``pairs("train"|"eval")``).
* :class:`Env`, :class:`VecEnv` – the environment (one decision per step), raw.
* :class:`Policy`, :func:`fly` – a trained ``policy.bin`` run on observations, or flown on a pair
  exactly as ``dupac fly`` flies it.
* :class:`Planner`, :func:`fly_path` – the shortest flyable and the coverage-aware paths, and a
  path flown by the scripted pilot with the A3 rule (the planners ``dupac eval`` compares with).
* :mod:`dupac.gym` – ``DupacEnv`` (a ``gymnasium.Env``, registered as ``dupac/Dupac-v0``) and
  ``DupacVecEnv`` (a ``gymnasium.vector.VectorEnv`` stepping N environments in Rust).

Units are in the names: metres (``_m``), dBm (``_dbm``), local ENU coordinates of the scenario.
"""

from ._dupac import (
    Env,
    Planner,
    Policy,
    Scenario,
    VecEnv,
    __version__,
    default_config_toml,
    fly,
    fly_path,
)

#: Names of the RSRP classes by code (spec/radio.md §3).
RSRP_CLASSES = ("excellent", "mediocre", "poor")
#: Names of the episode outcomes by code (−1: the episode goes on).
OUTCOMES = ("goal", "collision", "out_of_bounds", "time_limit")

__all__ = [
    "Env",
    "OUTCOMES",
    "Planner",
    "Policy",
    "RSRP_CLASSES",
    "Scenario",
    "VecEnv",
    "__version__",
    "default_config_toml",
    "fly",
    "fly_path",
]

from . import gym as gym  # noqa: E402  (registers dupac/Dupac-v0 with Gymnasium)
