"""Type stubs of the Rust core ``dupac._dupac`` (python/src/). Array arguments take any
array-like of real numbers (lists, any integer or float dtype), converted as NumPy converts
them; shapes are checked."""

from os import PathLike
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

__version__: str

def default_config_toml() -> str:
    """The default configuration as TOML: every key with its default (``dupac config``)."""

class Scenario:
    """A resolved configuration with its city, sites, RSRP source and pairs."""

    def __init__(
        self,
        config: str | PathLike[str] | None = None,
        set: Sequence[str] = ...,
        association: str | None = None,
        policy: str | PathLike[str] | None = None,
    ) -> None: ...
    @property
    def city(self) -> str: ...
    @property
    def num_sites(self) -> int: ...
    @property
    def association(self) -> str: ...
    def config_toml(self) -> str: ...
    def bounds_m(self) -> tuple[tuple[float, float, float, float], tuple[float, float]]: ...
    def sites(self) -> dict[str, Any]: ...
    def rsrp_dbm(
        self, points: npt.ArrayLike, exact: bool = False
    ) -> npt.NDArray[np.float64]: ...
    def los(self, points: npt.ArrayLike) -> npt.NDArray[np.bool_]: ...
    def best_site(
        self, points: npt.ArrayLike, exact: bool = False
    ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]: ...
    def rsrp_class(self, rsrp_dbm: npt.ArrayLike) -> npt.NDArray[np.int8]: ...
    def coverage(self, altitude_m: float, resolution_m: float = 5.0) -> dict[str, Any]: ...
    def pairs(self, split: str = "eval") -> dict[str, npt.NDArray[Any]]: ...

class Env:
    """One UAV environment; a step is one decision."""

    def __init__(self, scenario: Scenario, split: str = "train", seed: int = 0) -> None: ...
    @property
    def obs_dim(self) -> int: ...
    @property
    def num_sites(self) -> int: ...
    @property
    def learned_site(self) -> bool: ...
    @property
    def action_repeat(self) -> int: ...
    @property
    def time_limit(self) -> int: ...
    @property
    def num_pairs(self) -> int: ...
    def observation_fields(self) -> list[tuple[str, int, int, str]]: ...
    def reset(
        self, seed: int | None = None, pair: int | None = None, reversed: bool | None = None
    ) -> npt.NDArray[np.float32]: ...
    def step(
        self, move: npt.ArrayLike, site: int = 0
    ) -> tuple[npt.NDArray[np.float32], float, bool, bool, dict[str, Any]]: ...
    def last_steps(self) -> dict[str, npt.NDArray[Any]]: ...
    def observation(self) -> npt.NDArray[np.float32]: ...

class VecEnv:
    """N environments stepped together in Rust on a pool of threads, the GIL released."""

    def __init__(
        self,
        scenario: Scenario,
        num_envs: int,
        split: str = "train",
        seed: int = 0,
        num_threads: int = 0,
    ) -> None: ...
    @property
    def num_envs(self) -> int: ...
    @property
    def obs_dim(self) -> int: ...
    @property
    def num_threads(self) -> int: ...
    def reset(
        self,
        seed: Sequence[int] | None = None,
        pair: Sequence[int] | None = None,
        reversed: Sequence[int] | None = None,
        mask: Sequence[bool] | None = None,
    ) -> npt.NDArray[np.float32]: ...
    def step(
        self, moves: npt.ArrayLike, sites: npt.ArrayLike
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float64],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
        npt.NDArray[np.float32],
        dict[str, npt.NDArray[Any]],
    ]: ...
    def send(self, moves: npt.ArrayLike, sites: npt.ArrayLike) -> None: ...
    def recv(
        self,
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float64],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
        npt.NDArray[np.float32],
        dict[str, npt.NDArray[Any]],
    ]: ...

class Policy:
    """A trained policy (``policy.bin``), acted deterministically."""

    def __init__(self, path: str | PathLike[str]) -> None: ...
    @property
    def obs_dim(self) -> int: ...
    @property
    def n_sites(self) -> int: ...
    @property
    def version(self) -> int: ...
    def act(self, obs: npt.ArrayLike) -> tuple[npt.NDArray[np.float32], int]: ...
    def act_batch(
        self, obs: npt.ArrayLike
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.int64]]: ...
    def value(self, obs: npt.ArrayLike) -> float: ...

def fly(
    scenario: Scenario, policy: Policy, pair: int = 0, split: str = "eval"
) -> tuple[dict[str, Any], dict[str, npt.NDArray[Any]]]: ...

class Planner:
    """The shortest flyable and the coverage-aware planners of a scenario's city."""

    def __init__(self, scenario: Scenario, coverage: bool = True) -> None: ...
    @property
    def has_coverage(self) -> bool: ...
    def check_point(self, point_m: npt.ArrayLike) -> None: ...
    def shortest(
        self, source_m: npt.ArrayLike, destination_m: npt.ArrayLike
    ) -> dict[str, Any]: ...
    def coverage_aware(
        self,
        source_m: npt.ArrayLike,
        destination_m: npt.ArrayLike,
        lam: float | None = None,
    ) -> dict[str, Any]: ...

def fly_path(
    scenario: Scenario, waypoints_m: npt.ArrayLike, pair: int = 0, split: str = "eval"
) -> tuple[dict[str, Any], dict[str, npt.NDArray[Any]]]: ...
