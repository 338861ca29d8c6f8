"""A run's configuration: typed, validated, every default filled in, with units.

A *run* is one parameter point of a sweep (:mod:`pose_uncertainty.experiments.run` executes
it). A configuration is written as a plain mapping (YAML or JSON)::

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

An optional ``drive`` section (:mod:`pose_uncertainty.experiments.drive_config`) makes the
robot any drive of thesis 002; the trajectory is then the path it follows. Without it
the run is the differential drive of ``k_r``, ``k_l``.

:meth:`RunConfig.to_dict` returns *every* parameter, defaults included (the
trajectory builder's defaults too), so that a logged configuration re-runs the
same computation; :meth:`RunConfig.units` gives the unit of each key. Numbers
written as text (``1e9``, ``5e-4``: YAML 1.1 reads them as strings) are read as
numbers; trajectories are validated and counted without being built, so a
configuration can be costed (:mod:`pose_uncertainty.experiments.cost`) before anything
is allocated.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core import trajectories
from ..core.grids import Grid
from ..core.stats import PR_3SIGMA
from ..core.table_io import jsonable
from ..core.validation import parse_numbers
from ..methods import maps
from .config_checks import builder_keywords
from .config_checks import check_keys as _check_keys
from .config_checks import fail as _fail
from .config_checks import integer as _int
from .config_checks import name as _name
from .config_checks import real as _float
from .drive_config import DriveConfig, check_path

__all__ = [
    "MAP_SAMPLES",
    "TRAJECTORY_UNITS",
    "MapConfig",
    "MonteCarloConfig",
    "RunConfig",
    "map_kind",
]


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
        start and the noiseless end). Every map also has ``n_sampler`` [1]
        (default :data:`MAP_SAMPLES`): draws of the model's own sampler along the
        same controls, logged with the map and compared with it (0: none); and
        ``log_volume`` (default false): log the full ``(x, y, θ)`` array, lossless but
        large (``nx·ny·nθ·8`` bytes); otherwise the log holds the exact θ-marginal
        and the sha256 of the full array, which ``replay --verify`` compares.
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
        return {"name": self.name, "model": self.model, **jsonable(self.params)}


#: Paths up to this many steps are checked against their drive when the config is read (a
#: longer one when the run executes, after the cost guard: the check builds the path).
_CHECK_PATH_STEPS: int = 1_000_000

#: Default number of draws of a map's own motion-model sampler (its Monte Carlo truth).
MAP_SAMPLES: int = 20_000

#: Parameters of the map builders that the run supplies itself (not configurable).
_MAP_SUPPLIED = (
    "model", "start", "control", "controls", "dt", "grid", "odometry", "workers", "progress",
)  # fmt: skip


def map_kind(n_steps: int) -> str:
    """``"single"`` (the thesis's one-step map) for a one-step trajectory, else ``"multi"``."""
    return "single" if n_steps == 1 else "multi"


def _map_defaults(model: str, kind: str) -> dict[str, Any]:
    """Every configurable parameter of a map builder with its default."""
    defaults: dict[str, Any] = {
        "alphas": [0.05] * (6 if model == "velocity" else 4),
        # draws of the model's own sampler along the run's controls (the map's Monte Carlo truth)
        "n_sampler": MAP_SAMPLES,
        # the full (x, y, θ) array in the log (else its exact θ-marginal and its sha256)
        "log_volume": False,
    }
    if kind == "single":
        fns: tuple[Any, ...] = (maps.single_step_map, Grid.centered)
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
    kind = map_kind(n_steps)
    defaults = _map_defaults(model, kind)
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ValueError(
            f"unknown config key(s) {', '.join(repr(f'{where}.{k}') for k in unknown)} "
            f"(allowed for a {kind}-step {model} map: name, model, {', '.join(sorted(defaults))})"
        )
    params = {k: parse_numbers(v, defaults[k]) for k, v in params.items()}
    full = jsonable({**defaults, **params})
    full["n_sampler"] = _int(f"{where}.n_sampler", full["n_sampler"])
    if not isinstance(full["log_volume"], bool):
        raise _fail(f"{where}.log_volume", "true or false", full["log_volume"])
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
    name = data["name"]
    if name not in trajectories.BUILDERS:
        raise _fail("trajectory.name", f"one of {tuple(trajectories.BUILDERS)}", name)
    defaults, params = builder_keywords("trajectory", trajectories.BUILDERS[name], data)
    params = {k: parse_numbers(v, defaults[k]) for k, v in params.items()}
    full = {"name": name, **jsonable({**defaults, **params})}
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
    drive : DriveConfig or None
        The robot's drive (:mod:`pose_uncertainty.experiments.drive_config`): its type,
        geometry and odometry errors; the trajectory is then the path it follows.
        None (no ``drive`` key) = the differential drive of ``trajectory.track``
        with ``k_r``, ``k_l``, logged exactly as before the drives existed.
    """

    trajectory: dict[str, Any]
    k_r: float = 5e-4
    k_l: float = 5e-4
    cov0: tuple[tuple[float, float, float], ...] | None = None
    pr: float = PR_3SIGMA
    n_ellipses: int = 10
    seed: int = 0
    monte_carlo: MonteCarloConfig = field(default_factory=MonteCarloConfig)
    maps: tuple[MapConfig, ...] = ()
    name: str = "run"
    drive: DriveConfig | None = None

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
        "drive",
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
        pr = _float("pr", data.get("pr", PR_3SIGMA))
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
        drive = None
        if data.get("drive") is not None:
            drive = DriveConfig.from_dict(data["drive"])
            if n_steps <= _CHECK_PATH_STEPS:  # a longer path is checked when the run executes
                check_path(drive, traj, k_r, k_l)  # the drive can follow the path (vectorised, cheap)
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
            drive=drive,
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-serialisable mapping with every parameter (round-trips via from_dict)."""
        return {
            "name": self.name,
            "seed": self.seed,
            "trajectory": jsonable(self.trajectory),
            "k_r": self.k_r,
            "k_l": self.k_l,
            "cov0": None if self.cov0 is None else [list(r) for r in self.cov0],
            "pr": self.pr,
            "n_ellipses": self.n_ellipses,
            "monte_carlo": self.monte_carlo.to_dict(),
            "maps": [m.to_dict() for m in self.maps],
            # only when configured: a run without a drive logs exactly what it logged before
            **({} if self.drive is None else {"drive": self.drive.to_dict()}),
        }

    def units(self) -> dict[str, Any]:
        """Unit of every configuration key (``"1"`` = dimensionless, ``"-"`` = not a number)."""
        units: dict[str, Any] = {
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
                "n_sampler": "1 (draws of the model's own sampler)",
                "log_volume": "- (bool: the full (x, y, theta) array in the log)",
                "size": "m",
                "resolution": "m",
                "theta_resolution": "rad",
            },
        }
        if self.drive is not None:  # only when configured (the logged units of other runs are unchanged)
            units["drive"] = DriveConfig.units()
        return units
