"""One run: a typed configuration, its execution and its result.

A *run* is one parameter point of a sweep: a trajectory, the odometry error
constants, a seed and what to compute — Method A (covariance propagation with
its error ellipses), Monte Carlo end poses under the same model, and optional
probability maps (Method B). :func:`execute` turns a :class:`RunConfig` into a
:class:`RunResult`; :mod:`pose_uncertainty.logs.runlog` writes and reads results as
MCAP files, :mod:`pose_uncertainty.present.figures` draws them.

A configuration is written as a plain mapping (YAML or JSON)::

    name: circle_a4
    seed: 7
    trajectory: {name: circle, radius: 1.0, speed: 0.5, dt: 0.01, track: 0.2}
    k_r: 5.0e-4            # m   (Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|))
    k_l: 5.0e-4            # m
    pr: 0.98889            # probability inside the drawn ellipse
    n_ellipses: 10         # blue ellipses along the path
    monte_carlo: {n_particles: 1000, regime: per_step, method: midpoint, checkpoints: [100]}
    maps:
      - {name: velocity, model: velocity, alpha: [0.05, 0.05, 0.05, 0.05, 0.05, 0.05]}

:meth:`RunConfig.to_dict` returns *every* parameter, defaults included (the
trajectory builder's defaults too), so that a logged configuration re-runs the
same computation; :meth:`RunConfig.units` gives the unit of each key.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import math
import os
import re
import subprocess
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.validation import NUMBER_HINT, parse_number

__all__ = [
    "DEFAULT_PR",
    "MapConfig",
    "MapRecord",
    "MonteCarloConfig",
    "RunConfig",
    "RunResult",
    "environment_lock_sha256",
    "execute",
    "git_commit",
    "map_kind",
    "provenance",
]

#: ``Pr = 1 − e^{−4.5}`` ⇔ ellipse radius ``r = 3`` (SPEC §2.1), the thesis's 98.89 %.
DEFAULT_PR: float = 1.0 - math.exp(-4.5)

_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")

#: Units of the trajectory builder parameters (SPEC §1, pose_uncertainty.core.trajectories).
TRAJECTORY_UNITS: dict[str, str] = {
    "name": "-",
    "length": "m",
    "radius": "m",
    "angle": "rad",
    "laps": "1",
    "direction": "1 (+1 left, -1 right)",
    "dx": "m",
    "dy": "m",
    "speed": "m/s",
    "angular_speed": "rad/s",
    "dt": "s",
    "track": "m",
    "profile": "- (constant | ramp)",
    "start": "(m, m, rad)",
}


def _fail(key: str, rule: str, value: Any) -> ValueError:
    return ValueError(f"config key {key!r} must be {rule}, got {value!r}")


def _check_keys(where: str, data: Mapping[str, Any], allowed: tuple[str, ...]) -> None:
    if not isinstance(data, Mapping):
        raise _fail(where or "config", "a mapping", data)
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        prefix = f"{where}." if where else ""
        raise ValueError(
            f"unknown config key(s) {', '.join(repr(prefix + k) for k in unknown)} "
            f"(allowed: {', '.join(allowed)})"
        )


def _float(key: str, value: Any, *, positive: bool = False, nonneg: bool = False) -> float:
    value = parse_number(value)  # "5e-4": YAML 1.1 reads a float without a dot as text
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise _fail(key, f"a real number {NUMBER_HINT}", value)
    v = float(value)
    if not math.isfinite(v):
        raise _fail(key, "finite", value)
    if positive and not v > 0:
        raise _fail(key, "> 0 (allowed: (0, inf))", value)
    if nonneg and not v >= 0:
        raise _fail(key, ">= 0 (allowed: [0, inf))", value)
    return v


def _int(key: str, value: Any, *, minimum: int = 0) -> int:
    value = parse_number(value, like=0)  # "1e5" → 100000
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise _fail(key, f"an integer >= {minimum}", value)
    return int(value)


def _numbers(value: Any, like: Any = None) -> Any:
    """``parse_number`` through lists (``alphas``, ``start``): numbers written as text → numbers."""
    if isinstance(value, list | tuple):
        item = like[0] if isinstance(like, list | tuple) and like else None
        return [_numbers(v, item) for v in value]
    return parse_number(value, like)


def _name(key: str, value: Any) -> str:
    if not isinstance(value, str) or not _NAME_RE.match(value):
        raise _fail(key, "a name of letters, digits, '_', '.', '-'", value)
    return value


@dataclass(frozen=True)
class MonteCarloConfig:
    """Monte Carlo sampling of end poses under Method A's noise model (SPEC §2.2).

    Attributes
    ----------
    n_particles : int
        Number of sampled runs [1]; 0 disables Monte Carlo.
    regime : {"per_step", "per_run"}
        Wheel-travel noise drawn every step (random walk) or once per run (systematic).
    method : str
        Forward-kinematics step used by the sampler (``pose_uncertainty.core.kinematics.METHODS``).
    checkpoints : tuple of int
        Step indices (1..N) at which the whole cloud is also kept [step].
    """

    n_particles: int = 1000
    regime: str = "per_step"
    method: str = "midpoint"
    checkpoints: tuple[int, ...] = ()

    KEYS = ("n_particles", "regime", "method", "checkpoints")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> MonteCarloConfig:
        """Validate and build from a mapping; unknown keys raise ValueError naming them."""
        _check_keys("monte_carlo", data, cls.KEYS)
        n = _int("monte_carlo.n_particles", data.get("n_particles", 1000))
        regime = data.get("regime", "per_step")
        if regime not in ("per_step", "per_run"):
            raise _fail("monte_carlo.regime", "one of 'per_step', 'per_run'", regime)
        method = data.get("method", "midpoint")
        methods = ("exact", "euler", "euler_end", "midpoint")
        if method not in methods:
            raise _fail("monte_carlo.method", f"one of {methods}", method)
        cps = data.get("checkpoints", ())
        if not isinstance(cps, list | tuple):
            raise _fail("monte_carlo.checkpoints", "a list of step indices", cps)
        checkpoints = tuple(sorted({_int("monte_carlo.checkpoints[]", c, minimum=1) for c in cps}))
        return cls(n_particles=n, regime=regime, method=method, checkpoints=checkpoints)

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping with every parameter."""
        return {
            "n_particles": self.n_particles,
            "regime": self.regime,
            "method": self.method,
            "checkpoints": list(self.checkpoints),
        }


@dataclass(frozen=True)
class MapConfig:
    """One probability map (Method B, SPEC §3) computed for the run.

    Attributes
    ----------
    name : str
        Identifier, used in topic and figure names.
    model : {"velocity", "odometry"}
        Motion model.
    params : dict
        Parameters of the map (every one filled in by :meth:`from_dict`):
        ``alphas`` [1] (6 velocity / 4 odometry error constants, default 0.05 each
        as the thesis), ``noise`` (normal | triangular), ``scaling`` (squared | abs),
        ``resolution`` [m] (cell, default 0.01 m), ``theta_resolution`` [rad]
        (default 2°). A one-step trajectory gives the thesis's single-step map
        (``pose_uncertainty.methods.maps.single_step_map``: also ``corrected`` (the
        change-of-variables-corrected pose-space density instead of Thrun's
        control-space one), ``cell_average``, ``variance_from``, ``size`` [m], the
        side of the grid centred on the noiseless end pose, default 1 m); a longer
        one the multi-step map along the whole trajectory (``multi_step_map``:
        also ``oversample`` (compute on cells that many times finer, summed back;
        for distributions thinner than a cell such as rotation in place, at about
        15–20× the cost for 3), ``diffusion_compensation``, ``max_cells``,
        ``n_nodes_max``, and ``size`` [m]: None = a grid that grows with the
        spread, a number = a fixed square grid of that side centred between the
        start and the noiseless end).
    """

    name: str
    model: str
    params: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], index: int = 0, n_steps: int = 1) -> MapConfig:
        """Validate and build from a mapping with keys ``name``, ``model`` and map parameters.

        ``n_steps`` (the trajectory's N) selects the builder whose parameters apply.
        """
        where = f"maps[{index}]"
        if not isinstance(data, Mapping):
            raise _fail(where, "a mapping", data)
        if "model" not in data:
            raise ValueError(f"config key '{where}.model' is missing (allowed: velocity, odometry)")
        model = data["model"]
        if model not in ("velocity", "odometry"):
            raise _fail(f"{where}.model", "one of 'velocity', 'odometry'", model)
        name = _name(f"{where}.name", data.get("name", model))
        params = {k: v for k, v in data.items() if k not in ("name", "model")}
        return cls(name=name, model=model, params=_map_params(where, model, params, n_steps))

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping with every parameter."""
        return {"name": self.name, "model": self.model, **_plain(self.params)}


def _plain(value: Any) -> Any:
    """Convert tuples/numpy scalars/arrays to JSON-friendly lists and Python numbers."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple | np.ndarray):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


#: Parameters of the map builders that the run supplies itself (not configurable).
_MAP_SUPPLIED = (
    "model", "start", "control", "controls", "dt", "grid", "odometry", "workers", "progress",
)  # fmt: skip


def map_kind(n_steps: int) -> str:
    """``"single"`` (the thesis's one-step map) for a one-step trajectory, else ``"multi"``."""
    return "single" if n_steps == 1 else "multi"


def _map_defaults(model: str, kind: str) -> dict[str, Any]:
    """Every configurable parameter of a map builder with its default."""
    from ..methods import maps

    defaults: dict[str, Any] = {"alphas": [0.05] * (6 if model == "velocity" else 4)}
    if kind == "single":
        fns: tuple[Any, ...] = (maps.single_step_map, maps.MapGrid.centered)
    else:
        fns = (maps.multi_step_map,)
        defaults["size"] = None  # None: the growing grid; a number: a fixed square grid [m]
    for fn in fns:
        for p in inspect.signature(fn).parameters.values():
            if p.name in _MAP_SUPPLIED or p.name in ("center", "self", "cls"):
                continue
            if p.default is not inspect.Parameter.empty:
                defaults.setdefault(p.name, p.default)
    return defaults


def _map_params(where: str, model: str, params: dict[str, Any], n_steps: int) -> dict[str, Any]:
    """Validate a map's parameters against its builder and fill in the builder's defaults."""
    from ..methods import maps

    kind = map_kind(n_steps)
    defaults = _map_defaults(model, kind)
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ValueError(
            f"unknown config key(s) {', '.join(repr(f'{where}.{k}') for k in unknown)} "
            f"(allowed for a {kind}-step {model} map: name, model, {', '.join(sorted(defaults))})"
        )
    params = {k: _numbers(v, defaults[k]) for k, v in params.items()}
    full = _plain({**defaults, **params})
    try:
        maps.check_alphas(full["alphas"], 6 if model == "velocity" else 4)
    except ValueError as exc:
        raise ValueError(f"config key '{where}.alphas': {exc}") from None
    return full


def _trajectory_params(data: Any) -> tuple[dict[str, Any], int]:
    """Validate the trajectory mapping, fill in every default of its builder; also return N."""
    if not isinstance(data, Mapping):
        raise _fail("trajectory", "a mapping with a 'name' key", data)
    if "name" not in data:
        raise ValueError("config key 'trajectory.name' is missing (e.g. straight, circle)")
    from ..core import trajectories

    name = data["name"]
    if name not in trajectories.BUILDERS:
        raise _fail("trajectory.name", f"one of {tuple(trajectories.BUILDERS)}", name)
    builder = trajectories.BUILDERS[name]
    defaults: dict[str, Any] = {}
    for fn in (builder, trajectories.from_segments):
        for p in inspect.signature(fn).parameters.values():
            if p.default is not inspect.Parameter.empty and p.name != "name":
                defaults.setdefault(p.name, p.default)
    params = {k: v for k, v in data.items() if k != "name"}
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ValueError(
            f"unknown config key(s) {', '.join(repr('trajectory.' + k) for k in unknown)} "
            f"(allowed for trajectory {name!r}: {', '.join(sorted(defaults))})"
        )
    params = {k: _numbers(v, defaults[k]) for k, v in params.items()}
    full = {"name": name, **_plain({**defaults, **params})}
    try:  # validated and counted without building it (the cost guard comes first)
        n = trajectories.n_steps(name, **{k: v for k, v in full.items() if k != "name"})
    except ValueError as exc:
        raise ValueError(f"config key 'trajectory' ({name}): {exc}") from None
    return full, n


@dataclass(frozen=True)
class RunConfig:
    """Everything that determines one run (with the package version and environment).

    Attributes
    ----------
    trajectory : dict
        ``name`` of a builder in ``pose_uncertainty.core.trajectories.BUILDERS`` and its
        parameters (units in :data:`TRAJECTORY_UNITS`: lengths m, angles rad,
        speed m/s, angular_speed rad/s, dt s, track m).
    k_r, k_l : float
        Odometry error constants [m]: per-step wheel-travel variance per metre of
        travel, ``Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|)`` (SPEC §2).
    cov0 : tuple of tuple of float or None
        Initial pose covariance, 3×3 over (x [m], y [m], θ [rad]); None = zero.
    pr : float
        Probability inside the drawn error ellipses [1], in (0, 1); default 98.89 %.
    n_ellipses : int
        Number of ellipses drawn at regular intervals along the path [1].
    seed : int
        Seed of the ``numpy.random.Generator`` used for Monte Carlo [1].
    monte_carlo : MonteCarloConfig
    maps : tuple of MapConfig
    name : str
        Run identifier.
    """

    trajectory: dict[str, Any]
    k_r: float = 5e-4
    k_l: float = 5e-4
    cov0: tuple[tuple[float, float, float], ...] | None = None
    pr: float = DEFAULT_PR
    n_ellipses: int = 10
    seed: int = 0
    monte_carlo: MonteCarloConfig = field(default_factory=MonteCarloConfig)
    maps: tuple[MapConfig, ...] = ()
    name: str = "run"

    KEYS = (
        "name",
        "seed",
        "trajectory",
        "k_r",
        "k_l",
        "cov0",
        "pr",
        "n_ellipses",
        "monte_carlo",
        "maps",
    )

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunConfig:
        """Validate a plain mapping and build the configuration.

        Raises
        ------
        ValueError
            Naming the bad key (dotted path, e.g. ``monte_carlo.regime``), the bad
            value and what is allowed; unknown keys are rejected.
        """
        _check_keys("", data, cls.KEYS)
        if "trajectory" not in data:
            raise ValueError("config key 'trajectory' is missing (e.g. {name: straight})")
        traj, n_steps = _trajectory_params(data["trajectory"])
        k_r = _float("k_r", data.get("k_r", 5e-4), nonneg=True)
        k_l = _float("k_l", data.get("k_l", 5e-4), nonneg=True)
        cov0_raw = data.get("cov0")
        cov0 = None
        if cov0_raw is not None:
            try:
                arr = np.asarray(cov0_raw, dtype=np.float64)
            except (TypeError, ValueError):
                raise _fail("cov0", "a 3x3 matrix of numbers", cov0_raw) from None
            if arr.shape != (3, 3) or not np.all(np.isfinite(arr)):
                raise _fail("cov0", "a finite 3x3 matrix", cov0_raw)
            if not np.array_equal(arr, arr.T) or np.linalg.eigvalsh(arr).min() < -1e-15:
                raise _fail("cov0", "symmetric positive semi-definite", cov0_raw)
            cov0 = tuple((float(r[0]), float(r[1]), float(r[2])) for r in arr)
        pr = _float("pr", data.get("pr", DEFAULT_PR))
        if not 0.0 < pr < 1.0:
            raise _fail("pr", "a probability in (0, 1)", data.get("pr"))
        n_ell = _int("n_ellipses", data.get("n_ellipses", 10), minimum=1)
        seed = _int("seed", data.get("seed", 0))
        mc = MonteCarloConfig.from_dict(data.get("monte_carlo", {}))
        late = [c for c in mc.checkpoints if c > n_steps]
        if late:
            raise _fail(
                "monte_carlo.checkpoints",
                f"step indices in 1..{n_steps} (the trajectory's N)",
                late,
            )
        maps_raw = data.get("maps", ())
        if not isinstance(maps_raw, list | tuple):
            raise _fail("maps", "a list of map mappings", maps_raw)
        maps = tuple(MapConfig.from_dict(m, i, n_steps) for i, m in enumerate(maps_raw))
        names = [m.name for m in maps]
        if len(set(names)) != len(names):
            raise _fail("maps[].name", "unique", names)
        name = _name("name", data.get("name", "run"))
        return cls(
            trajectory=traj,
            k_r=k_r,
            k_l=k_l,
            cov0=cov0,
            pr=pr,
            n_ellipses=n_ell,
            seed=seed,
            monte_carlo=mc,
            maps=maps,
            name=name,
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-serialisable mapping with every parameter (round-trips via from_dict)."""
        return {
            "name": self.name,
            "seed": self.seed,
            "trajectory": _plain(self.trajectory),
            "k_r": self.k_r,
            "k_l": self.k_l,
            "cov0": None if self.cov0 is None else [list(r) for r in self.cov0],
            "pr": self.pr,
            "n_ellipses": self.n_ellipses,
            "monte_carlo": self.monte_carlo.to_dict(),
            "maps": [m.to_dict() for m in self.maps],
        }

    @staticmethod
    def units() -> dict[str, Any]:
        """Unit of every configuration key (``"1"`` = dimensionless, ``"-"`` = not a number)."""
        return {
            "name": "-",
            "seed": "1",
            "trajectory": dict(TRAJECTORY_UNITS),
            "k_r": "m (wheel-travel variance per metre of travel)",
            "k_l": "m (wheel-travel variance per metre of travel)",
            "cov0": "3x3 over (x [m], y [m], theta [rad]): m^2, m*rad, rad^2",
            "pr": "1 (probability inside the ellipse)",
            "n_ellipses": "1",
            "monte_carlo": {
                "n_particles": "1",
                "regime": "- (per_step | per_run)",
                "method": "- (exact | euler | euler_end | midpoint)",
                "checkpoints": "step index",
            },
            "maps": {
                "name": "-",
                "model": "- (velocity | odometry)",
                "alphas": "1 (error constants)",
                "noise": "- (normal | triangular)",
                "scaling": "- (squared | abs)",
                "corrected": "- (bool)",
                "cell_average": "- (bool | null = automatic)",
                "oversample": "1 (integer factor)",
                "diffusion_compensation": "- (bool)",
                "max_cells": "1",
                "n_nodes_max": "1",
                "variance_from": "- (hypothesis | odometry | null)",
                "size": "m",
                "resolution": "m",
                "theta_resolution": "rad",
            },
        }


@dataclass(frozen=True, eq=False)
class MapRecord:
    """A probability map over a discretised ``(x, y, θ)`` grid, as computed and logged.

    Holds the data of ``pose_uncertainty.methods.maps.ProbabilityMap`` plus the map's
    name and parameters; :meth:`to_probability_map` gives the full object back.

    Attributes
    ----------
    name : str
    model : str — ``"velocity"`` or ``"odometry"``
    x : ndarray, shape (nx,) — cell centres [m]
    y : ndarray, shape (ny,) — cell centres [m]
    theta : ndarray, shape (nθ,) — cell centres [rad]
    values : ndarray, shape (nx, ny, nθ) — probability mass per cell [1]
    lost_mass : float — probability outside the grid [1]
    params : dict — the map's configuration parameters
    info : dict — the map builder's diagnostics (JSON-compatible)
    center : ndarray, shape (3,) — the noiseless end pose the map is about [m, m, rad]
    """

    name: str
    model: str
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    theta: NDArray[np.float64]
    values: NDArray[np.float64]
    lost_mass: float = 0.0
    params: dict[str, Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
    center: NDArray[np.float64] = field(default_factory=lambda: np.full(3, np.nan))

    def __post_init__(self) -> None:
        for key in ("x", "y", "theta", "values", "center"):
            object.__setattr__(self, key, np.ascontiguousarray(getattr(self, key), np.float64))
        shape = (self.x.size, self.y.size, self.theta.size)
        if self.values.shape != shape:
            raise ValueError(
                f"map values must have shape {shape} (nx, ny, ntheta), got {self.values.shape}"
            )

    @property
    def resolution(self) -> float:
        """Cell side [m] (along x; the grids are square)."""
        if self.x.size > 1:
            return float(self.x[1] - self.x[0])
        return float(self.y[1] - self.y[0]) if self.y.size > 1 else 0.01

    def marginal_xy(self) -> NDArray[np.float64]:
        """Mass per ``(x, y)`` cell with θ summed out [1], shape (nx, ny)."""
        return self.values.sum(axis=2)

    def to_probability_map(self) -> Any:
        """The equivalent ``pose_uncertainty.methods.maps.ProbabilityMap`` (without its grid object)."""
        from ..methods import maps

        return maps.ProbabilityMap(
            self.x,
            self.y,
            self.theta,
            self.values,
            self.lost_mass,
            self.model,
            None,
            dict(self.info),
        )

    @classmethod
    def from_probability_map(
        cls, name: str, pm: Any, params: dict[str, Any], center: Any = None
    ) -> MapRecord:
        """Wrap a ``ProbabilityMap`` with its name, parameters and noiseless end pose."""
        return cls(
            center=np.full(3, np.nan) if center is None else np.asarray(center, np.float64),
            name=name,
            model=str(pm.model),
            x=pm.x,
            y=pm.y,
            theta=pm.theta,
            values=pm.values,
            lost_mass=float(pm.lost_mass),
            params=_plain(params),
            info=_plain(dict(getattr(pm, "info", {}) or {})),
        )


@dataclass(frozen=True, eq=False)
class RunResult:
    """The outcome of one run.

    Attributes
    ----------
    config : RunConfig
    times : ndarray, shape (N+1,) — simulated time of each pose [s]
    poses : ndarray, shape (N+1, 3) — nominal (noiseless) poses (x [m], y [m], θ [rad])
    covs : ndarray, shape (N+1, 3, 3) — pose covariance by Method A [m², m·rad, rad²]
    end_poses : ndarray, shape (n, 3) or None — Monte Carlo end poses
    checkpoints : dict of int to ndarray, shape (n, 3) — Monte Carlo clouds at steps
    maps : tuple of MapRecord
    metrics : dict of str to float — deterministic metrics (units in ``metric_units``)
    metric_units : dict of str to str
    timings : dict of str to float — wall-clock durations [s]; NOT deterministic
    provenance : dict of str to str — package version, environment.lock sha256, git commit
    """

    config: RunConfig
    times: NDArray[np.float64]
    poses: NDArray[np.float64]
    covs: NDArray[np.float64]
    end_poses: NDArray[np.float64] | None = None
    checkpoints: dict[int, NDArray[np.float64]] = field(default_factory=dict)
    maps: tuple[MapRecord, ...] = ()
    metrics: dict[str, float] = field(default_factory=dict)
    metric_units: dict[str, str] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    provenance: dict[str, str] = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        """Number of steps N."""
        return int(self.times.size - 1)

    def ellipse_steps(self) -> list[int]:
        """Steps at which ellipses are drawn: ``n_ellipses`` regular intervals, the last = N."""
        n = self.n_steps
        marks = np.linspace(0, n, self.config.n_ellipses + 1).round().astype(int)[1:]
        return sorted({int(m) for m in marks if m > 0})


# --- provenance ----------------------------------------------------------------------------


_REPO_ROOT = Path(__file__).resolve().parents[3]


@functools.lru_cache(maxsize=1)
def environment_lock_sha256() -> str | None:
    """sha256 (hex) of the ``environment.lock`` the package was built from, or None.

    Looked up, in order: ``$POSE_UNCERTAINTY_ENVIRONMENT_LOCK`` (a path); an
    ``environment.lock`` shipped inside the package; the repository root of a
    source checkout or editable install (``src/pose_uncertainty/../../``); the
    current directory and its parents.
    """
    candidates: list[Path] = []
    env = os.environ.get("POSE_UNCERTAINTY_ENVIRONMENT_LOCK")
    if env:
        candidates.append(Path(env))
    candidates.append(Path(__file__).resolve().parent / "environment.lock")
    candidates.append(_REPO_ROOT / "environment.lock")
    cwd = Path.cwd()
    candidates.extend(d / "environment.lock" for d in (cwd, *cwd.parents))
    for path in candidates:
        if path.is_file():
            return hashlib.sha256(path.read_bytes()).hexdigest()
    return None


@functools.lru_cache(maxsize=1)
def git_commit() -> tuple[str, bool] | None:
    """``(commit, dirty)`` of the git work tree holding this package, or None.

    Runs ``git rev-parse HEAD`` (and ``git status --porcelain --untracked-files=no``)
    in the package's own directory, so the commit is that of the code, not of the
    caller's current directory; None when git or the repository is unavailable.
    """
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
        if head.returncode != 0:
            return None
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip(), bool(status.stdout.strip())


def provenance() -> dict[str, str]:
    """Package version, sha256 of ``environment.lock``, git commit and numpy version.

    Values are strings; an unknown value is ``"unknown"``.
    """
    from .. import __version__

    git = git_commit()
    return {
        "package_version": __version__,
        "environment_lock_sha256": environment_lock_sha256() or "unknown",
        "git_commit": git[0] if git else "unknown",
        "git_dirty": ("true" if git[1] else "false") if git else "unknown",
        "numpy_version": np.__version__,
    }


# --- execution ------------------------------------------------------------------------------


def execute(config: RunConfig) -> RunResult:
    """Compute one run: trajectory, covariance, Monte Carlo, maps and metrics.

    Parameters
    ----------
    config : RunConfig

    Returns
    -------
    RunResult
        Everything but ``timings`` is a deterministic function of ``config``
        (including its seed), the package version and the environment.

    Raises
    ------
    pose_uncertainty.logs.cost.CostError
        Before anything is allocated, when the run's estimated memory or time
        exceeds the limits (``POSE_UNCERTAINTY_MAX_MEMORY``, ``POSE_UNCERTAINTY_MAX_SECONDS``).
    """
    from ..core import stats, trajectories
    from ..methods import covariance, sampling
    from . import cost  # imports this module
    from .progress import Progress

    cost.check(config)  # the guard: one line naming estimate, limit and drivers
    timings: dict[str, float] = {}
    t_all = time.perf_counter()

    t0 = time.perf_counter()
    tp = dict(config.trajectory)
    traj = trajectories.build(tp.pop("name"), **tp)
    timings["trajectory_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    cov0 = None if config.cov0 is None else np.array(config.cov0)
    cres = covariance.propagate(traj, config.k_r, config.k_l, cov0=cov0)
    timings["covariance_s"] = time.perf_counter() - t0
    poses = np.ascontiguousarray(cres.poses, dtype=np.float64)
    covs = np.ascontiguousarray(cres.covs, dtype=np.float64)
    times = np.ascontiguousarray(traj.times, dtype=np.float64)

    rng = np.random.default_rng(config.seed)
    end_poses = None
    checkpoints: dict[int, NDArray[np.float64]] = {}
    mc = config.monte_carlo
    if mc.n_particles > 0:
        t0 = time.perf_counter()
        if not mc.checkpoints:
            # the sampler's fast path: end poses only, shape (n, 3)
            out = sampling.sample_end_poses(
                traj, config.k_r, config.k_l, mc.n_particles, rng,
                regime=mc.regime, method=mc.method, cov0=config.cov0,
                progress=Progress(f"{config.name}: Monte Carlo"),
            )  # fmt: skip
            end_poses = np.ascontiguousarray(out, dtype=np.float64)
        else:
            steps = [*mc.checkpoints, traj.n_steps]
            out = sampling.sample_end_poses(
                traj, config.k_r, config.k_l, mc.n_particles, rng,
                regime=mc.regime, method=mc.method, checkpoints=steps, cov0=config.cov0,
                progress=Progress(f"{config.name}: Monte Carlo"),
            )  # (n, C, 3): the clouds at the checkpoints, then at the end  # fmt: skip
            end_poses = np.ascontiguousarray(out[:, -1, :], dtype=np.float64)
            checkpoints = {
                step: np.ascontiguousarray(out[:, j, :], dtype=np.float64)
                for j, step in enumerate(mc.checkpoints)
            }
        timings["monte_carlo_s"] = time.perf_counter() - t0

    maps: list[MapRecord] = []
    for mcfg in config.maps:
        t0 = time.perf_counter()
        maps.append(_compute_map(mcfg, traj, Progress(f"{config.name}: map {mcfg.name}")))
        timings[f"map_{mcfg.name}_s"] = time.perf_counter() - t0

    metrics, units = _metrics(config, traj, poses, covs, end_poses, maps, covariance, stats)
    if end_poses is not None and end_poses.shape[0] >= 10:
        t0 = time.perf_counter()
        acc, acc_units = _accuracy_metrics(config, traj, poses, covs, end_poses)
        metrics.update(acc)
        units.update(acc_units)
        timings["accuracy_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_all
    return RunResult(
        config=config,
        times=times,
        poses=poses,
        covs=covs,
        end_poses=end_poses,
        checkpoints=checkpoints,
        maps=tuple(maps),
        metrics=metrics,
        metric_units=units,
        timings=timings,
        provenance=provenance(),
    )


def _compute_map(mcfg: MapConfig, traj: Any, progress: Any = None) -> MapRecord:
    """Compute one probability map with ``pose_uncertainty.methods.maps``.

    A one-step trajectory gives the single-step map of its control ``(V, ω)``
    over ``dt`` from the start pose, on a grid centred on the noiseless
    (exact-arc) end pose; a longer one the multi-step map along all its controls
    (on a growing grid unless ``size`` is set).
    """
    from ..methods import maps as maps_mod

    params = dict(mcfg.params)
    end = np.asarray(traj.poses[-1], dtype=np.float64)
    if map_kind(traj.n_steps) == "single":
        grid_kw = {k: params.pop(k) for k in ("size", "resolution", "theta_resolution")}
        grid = maps_mod.MapGrid.centered(end, **grid_kw)
        pm = maps_mod.single_step_map(
            mcfg.model, traj.start, traj.controls[0], traj.dt, grid=grid, **params
        )
    else:
        size = params.pop("size")
        grid = None
        if size is not None:
            # a fixed grid must hold the start: centre it between the start and the end
            mid = (np.asarray(traj.start, dtype=np.float64) + end) / 2.0
            grid = maps_mod.MapGrid.centered(
                (mid[0], mid[1], end[2]), size, params["resolution"], params["theta_resolution"]
            )
        pm = maps_mod.multi_step_map(
            mcfg.model, traj.controls, traj.dt, start=traj.start, grid=grid, progress=progress,
            **params,
        )
    return MapRecord.from_probability_map(mcfg.name, pm, mcfg.params, center=end)


def _accuracy_metrics(
    config: RunConfig,
    traj: Any,
    poses: NDArray[np.float64],
    covs: NDArray[np.float64],
    end_poses: NDArray[np.float64],
) -> tuple[dict[str, float], dict[str, str]]:
    """How wrong each Gaussian method is against this run's Monte Carlo cloud.

    Method A (Cartesian Gaussian) and the exponential-coordinates Gaussian
    (the banana) of the same wheel-noise model, against the end-pose cloud:
    coverage of their Pr-regions for Pr ∈ {0.5, 0.9, 0.9889}, Hellinger and KL
    to the Monte Carlo histogram on one stated grid (60 × 60 bins over the
    cloud), mean log-likelihood and NEES (:func:`pose_uncertainty.analysis.accuracy.compare_methods`).
    Deterministic: its own generator is derived from the run's seed.
    """
    from ..analysis import accuracy
    from ..methods import expcoords

    cov0 = None
    if config.cov0 is not None:
        # world-frame Σ_0 → body-frame exponential coordinates at the start pose (first order):
        # δp = T ξ with T = blockdiag(R(θ₀), 1), so Σ_ξ = Tᵀ Σ_0 T
        c, s = math.cos(traj.start[2]), math.sin(traj.start[2])
        T = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        cov0 = T.T @ np.asarray(config.cov0, dtype=np.float64) @ T
    E = expcoords.propagate(traj, config.k_r, config.k_l, cov0=cov0)
    res = accuracy.compare_methods(
        end_poses,
        (poses[-1], covs[-1]),
        (E.poses[-1], E.covs[-1]),
        np.random.default_rng([config.seed, 1]),
        n_threshold=50_000,
    )
    flat = accuracy.flatten(res)

    def unit(key: str) -> str:
        if "_kl" in key or "loglik" in key or "log_lik" in key:
            return "nat"
        if key.startswith("accuracy_grid_") and key.rsplit("_", 1)[-1] in ("dx", "dy", "min", "max"):
            return "m"
        return "1"

    return flat, {k: unit(k) for k in flat}


def _metrics(
    config: RunConfig,
    traj: Any,
    poses: NDArray[np.float64],
    covs: NDArray[np.float64],
    end_poses: NDArray[np.float64] | None,
    maps: list[MapRecord],
    covariance: Any,
    stats: Any,
) -> tuple[dict[str, float], dict[str, str]]:
    """Deterministic metrics of a run and their units."""
    m: dict[str, float] = {}
    u: dict[str, str] = {}

    def put(key: str, value: float, unit: str) -> None:
        m[key] = float(value)
        u[key] = unit

    end, cov_end = poses[-1], covs[-1]
    put("duration", traj.duration, "s")
    put("path_length", traj.length, "m")
    put("end_x", end[0], "m")
    put("end_y", end[1], "m")
    put("end_theta", end[2], "rad")
    put("end_sigma_x", math.sqrt(max(cov_end[0, 0], 0.0)), "m")
    put("end_sigma_y", math.sqrt(max(cov_end[1, 1], 0.0)), "m")
    put("end_sigma_theta", math.sqrt(max(cov_end[2, 2], 0.0)), "rad")
    alpha, a_major, a_minor = covariance.ellipse(cov_end[:2, :2], config.pr)
    put("ellipse_major", a_major, "m")
    put("ellipse_minor", a_minor, "m")
    put("ellipse_angle", alpha, "rad")
    if end_poses is not None and end_poses.shape[0] > 0:
        inside = stats.fraction_inside_ellipse(
            end_poses[:, :2], end[:2], cov_end[:2, :2], config.pr
        )
        put("mc_coverage", inside, "1 (fraction of particles inside the Pr-ellipse)")
        put("mc_coverage_minus_pr", inside - config.pr, "1")
        mean = end_poses.mean(axis=0)
        put("mc_mean_offset", math.hypot(mean[0] - end[0], mean[1] - end[1]), "m")
        if end_poses.shape[0] > 1:
            cov_mc = np.cov(end_poses[:, :2].T)
            norm = np.linalg.norm(cov_end[:2, :2])
            if norm > 0:
                rel = float(np.linalg.norm(cov_mc - cov_end[:2, :2]) / norm)
                put("mc_cov_xy_rel_error", rel, "1")
    # maps are centred on the noiseless exact-arc end pose (the trajectory's)
    end_exact = traj.poses[-1]
    for mp in maps:
        marg = mp.marginal_xy()
        i, j = np.unravel_index(int(np.argmax(marg)), marg.shape)
        put(
            f"map_{mp.name}_peak_offset",
            math.hypot(mp.x[i] - end_exact[0], mp.y[j] - end_exact[1]),
            "m",
        )
        total = float(marg.sum())
        if total > 0:
            mx = float(marg.sum(axis=1) @ mp.x) / total
            my = float(marg.sum(axis=0) @ mp.y) / total
            put(f"map_{mp.name}_mean_offset", math.hypot(mx - end_exact[0], my - end_exact[1]), "m")
        put(f"map_{mp.name}_lost_mass", mp.lost_mass, "1")
    return m, u
