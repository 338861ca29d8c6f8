"""One run: a typed configuration, its execution and its result.

A *run* is one parameter point of a sweep: a trajectory, the odometry error
constants, a seed and what to compute — Method A (covariance propagation with
its error ellipses), Method C (the unscented transform, always: a loop over the
steps, a fraction of a second per 1000 steps), Monte Carlo end poses under the same
model, and optional probability maps (Method B). :func:`execute` turns a :class:`RunConfig` into a
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

An optional ``drive`` section (:mod:`pose_uncertainty.logs.drive_config`) makes the
robot any drive of thesis 002; the trajectory is then the path it follows and
:mod:`pose_uncertainty.logs.drive_run` computes the drive's Method A, Monte Carlo and
banana. Without it the run is the differential drive of ``k_r``, ``k_l``.

:meth:`RunConfig.to_dict` returns *every* parameter, defaults included (the
trajectory builder's defaults too), so that a logged configuration re-runs the
same computation; :meth:`RunConfig.units` gives the unit of each key.
"""

from __future__ import annotations

import contextlib
import dataclasses
import inspect
import math
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis import accuracy, measures
from ..core import trajectories
from ..core.grids import Grid
from ..core.stats import PR_3SIGMA
from ..core.tables import jsonable
from ..methods import covariance, expcoords, maps, motion_models, sampling, unscented
from ..methods.maps import ProbabilityMap
from .config_checks import check_keys as _check_keys
from .config_checks import fail as _fail
from .config_checks import integer as _int
from .config_checks import name as _name
from .config_checks import real as _float
from .drive_config import DriveConfig, check_path
from .drive_run import DriveSetup
from .drive_run import expcoords as drive_expcoords
from .drive_run import measures as drive_measures
from .drive_run import method_a as drive_method_a
from .drive_run import sample as drive_sample
from .drive_run import setup as drive_setup
from .provenance import provenance

__all__ = [
    "MapConfig",
    "MonteCarloConfig",
    "RunConfig",
    "RunResult",
    "execute",
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


#: Default number of draws of a map's own motion-model sampler (its Monte Carlo truth).
MAP_SAMPLES: int = 20_000

#: Parameters of the map builders that the run supplies itself (not configurable).
_MAP_SUPPLIED = ("model", "start", "control", "controls", "dt", "grid", "odometry", "workers")


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
    full = {"name": name, **jsonable({**defaults, **params})}
    try:
        traj = builder(**{k: v for k, v in full.items() if k != "name"})
    except ValueError as exc:
        raise ValueError(f"config key 'trajectory' ({name}): {exc}") from None
    return full, traj.n_steps


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
        The robot's drive (:mod:`pose_uncertainty.logs.drive_config`): its type,
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
    maps : tuple of ProbabilityMap — each with its name, parameters and centre
    map_samplers : dict of str to ndarray, shape (n, 3) — per map name, the draws of its
        model's own sampler along the run's controls
    metrics : dict of str to float — every measure of the run
        (:mod:`pose_uncertainty.analysis.measures`), deterministic
    metric_units : dict of str to str — unit of each metric
    metric_definitions : dict of str to str — definition of each metric
    timings : dict of str to float — wall-clock durations [s]; NOT deterministic
    provenance : dict of str to str — package version, environment.lock sha256, git commit
    """

    config: RunConfig
    times: NDArray[np.float64]
    poses: NDArray[np.float64]
    covs: NDArray[np.float64]
    end_poses: NDArray[np.float64] | None = None
    checkpoints: dict[int, NDArray[np.float64]] = field(default_factory=dict)
    maps: tuple[ProbabilityMap, ...] = ()
    map_samplers: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    metrics: dict[str, float] = field(default_factory=dict)
    metric_units: dict[str, str] = field(default_factory=dict)
    metric_definitions: dict[str, str] = field(default_factory=dict)
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


# --- execution ------------------------------------------------------------------------------


def execute(config: RunConfig) -> RunResult:
    """Compute one run: trajectory, covariance, Monte Carlo, maps and every measure.

    Parameters
    ----------
    config : RunConfig

    Returns
    -------
    RunResult
        Everything but ``timings`` is a deterministic function of ``config``
        (including its seed), the package version and the environment.
    """
    timings: dict[str, float] = {}
    t_all = time.perf_counter()
    with _timed(timings, "trajectory_s"):
        traj = trajectories.from_config(config.trajectory)
        ds = None if config.drive is None else drive_setup(config.drive, traj, config.k_r, config.k_l)
    with _timed(timings, "covariance_s"):
        if ds is None:
            cres = covariance.propagate(traj, config.k_r, config.k_l, cov0=_cov0(config))
        else:  # the drive following the path (logs/drive_run.py)
            cres = drive_method_a(ds, _cov0(config))
    c_end = None
    if ds is None:  # Method C (issue 11), on the differential drive's wheel-noise model
        with _timed(timings, "unscented_s"):
            ures = unscented.propagate(traj, config.k_r, config.k_l, cov0=_cov0(config))
        c_end = (np.asarray(ures.poses[-1], dtype=np.float64), np.asarray(ures.covs[-1], dtype=np.float64))
    poses = np.ascontiguousarray(cres.poses, dtype=np.float64)
    covs = np.ascontiguousarray(cres.covs, dtype=np.float64)
    end_poses: NDArray[np.float64] | None = None
    checkpoints: dict[int, NDArray[np.float64]] = {}
    if config.monte_carlo.n_particles > 0:
        with _timed(timings, "monte_carlo_s"):
            end_poses, checkpoints = _monte_carlo(config, traj, ds)
    maps, samplers = [], {}
    for i, mcfg in enumerate(config.maps):
        with _timed(timings, f"map_{mcfg.name}_s"):
            maps.append(_compute_map(mcfg, traj))
            samplers[mcfg.name] = _map_sampler(config, mcfg, traj, i)
    with _timed(timings, "measures_s"):
        metrics = _measures(config, traj, poses, covs, end_poses, maps, samplers, c_end, ds)
        if ds is not None:  # the growth laws and the skid-steer's turn bias
            metrics.update(drive_measures(ds, poses, covs, config.monte_carlo.checkpoints,
                                          checkpoints, end_poses))  # fmt: skip
    timings["total_s"] = time.perf_counter() - t_all
    return RunResult(
        config=config, times=np.ascontiguousarray(traj.times, dtype=np.float64), poses=poses,
        covs=covs, end_poses=end_poses, checkpoints=checkpoints, maps=tuple(maps),
        map_samplers=samplers, metrics=metrics,
        metric_units={k: measures.describe(k)[0] for k in metrics},
        metric_definitions={k: measures.describe(k)[1] for k in metrics},
        timings=timings, provenance=provenance(),
    )  # fmt: skip


@contextlib.contextmanager
def _timed(timings: dict[str, float], key: str) -> Iterator[None]:
    """Record the wall-clock duration of the block in ``timings[key]`` [s]."""
    t0 = time.perf_counter()
    try:
        yield
    finally:
        timings[key] = time.perf_counter() - t0


def _cov0(config: RunConfig) -> NDArray[np.float64] | None:
    return None if config.cov0 is None else np.array(config.cov0, dtype=np.float64)


def _monte_carlo(
    config: RunConfig, traj: trajectories.Trajectory, ds: DriveSetup | None = None
) -> tuple[NDArray[np.float64], dict[int, NDArray[np.float64]]]:
    """Monte Carlo end poses (n, 3) and the clouds at the checkpoint steps (of the drive, if any)."""
    mc = config.monte_carlo
    rng = np.random.default_rng(config.seed)
    steps = [*mc.checkpoints, traj.n_steps] if mc.checkpoints else None
    if ds is None:
        out = sampling.sample_end_poses(
            traj, config.k_r, config.k_l, mc.n_particles, rng,
            regime=mc.regime, method=mc.method, cov0=config.cov0, checkpoints=steps,
        )  # fmt: skip
    else:
        out = drive_sample(ds, mc.n_particles, rng, regime=mc.regime, method=mc.method,
                           cov0=_cov0(config), checkpoints=steps)  # fmt: skip
    if steps is None:  # the sampler's fast path: end poses only, (n, 3)
        return np.ascontiguousarray(out, dtype=np.float64), {}
    # (n, C, 3): the clouds at the checkpoints, then at the end
    clouds = {s: np.ascontiguousarray(out[:, j, :], dtype=np.float64) for j, s in enumerate(mc.checkpoints)}
    return np.ascontiguousarray(out[:, -1, :], dtype=np.float64), clouds


def _compute_map(mcfg: MapConfig, traj: trajectories.Trajectory) -> ProbabilityMap:
    """Compute one probability map with :mod:`pose_uncertainty.methods.maps`.

    A one-step trajectory gives the single-step map of its control ``(V, ω)``
    over ``dt`` from the start pose, on a grid centred on the noiseless
    (exact-arc) end pose; a longer one the multi-step map along all its controls
    (on a growing grid unless ``size`` is set). The map's centre is that end pose.
    """
    params = {k: v for k, v in mcfg.params.items() if k not in ("n_sampler", "log_volume")}
    end = np.asarray(traj.poses[-1], dtype=np.float64)
    if map_kind(traj.n_steps) == "single":
        grid_kw = {k: params.pop(k) for k in ("size", "resolution", "theta_resolution")}
        grid = Grid.centered(end, **grid_kw)
        pm = maps.single_step_map(mcfg.model, traj.start, traj.controls[0], traj.dt, grid=grid, **params)
    else:
        size = params.pop("size")
        fixed = None
        if size is not None:
            # a fixed grid must hold the start: centre it between the start and the end
            mid = (np.asarray(traj.start, dtype=np.float64) + end) / 2.0
            fixed = Grid.centered((mid[0], mid[1], end[2]), size, params["resolution"], params["theta_resolution"])
        pm = maps.multi_step_map(mcfg.model, traj.controls, traj.dt, start=traj.start, grid=fixed, **params)
    return dataclasses.replace(pm, name=mcfg.name, params=jsonable(mcfg.params), info=jsonable(pm.info), center=end)


def _map_sampler(
    config: RunConfig, mcfg: MapConfig, traj: trajectories.Trajectory, index: int
) -> NDArray[np.float64]:
    """Draws of the map's own motion-model sampler along the run's controls, shape (n, 3).

    Seeded from the run's seed and the map's index (``default_rng([seed, 2, index])``).
    """
    n = int(mcfg.params["n_sampler"])
    if n == 0:
        return np.zeros((0, 3))
    p = mcfg.params
    rng = np.random.default_rng([config.seed, 2, index])
    out = motion_models.sample_controls(
        mcfg.model, traj.start, traj.controls, traj.dt, p["alphas"], n, rng,
        noise=p.get("noise", "normal"), scaling=p.get("scaling", "squared"),
    )  # fmt: skip
    return np.ascontiguousarray(out, dtype=np.float64)


def _measures(
    config: RunConfig,
    traj: trajectories.Trajectory,
    poses: NDArray[np.float64],
    covs: NDArray[np.float64],
    end_poses: NDArray[np.float64] | None,
    maps_: list[ProbabilityMap],
    samplers: dict[str, NDArray[np.float64]],
    c_end: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
    ds: DriveSetup | None = None,
) -> dict[str, float]:
    """Every measure of the run (:mod:`pose_uncertainty.analysis.measures`), computed once here.

    ``c_end`` is Method C's (mean, covariance) at the end of the path (None with a drive:
    Method C is the differential drive's); ``ds`` the drive following the path, if any.
    """
    out = measures.run_measures(traj.length, traj.duration, poses[-1])
    out.update(measures.gaussian_measures(poses[-1], covs[-1], config.pr))
    if c_end is not None:
        out.update(measures.unscented_measures(c_end[0], c_end[1], poses[-1], config.pr))
    if end_poses is not None and end_poses.shape[0] >= 1:
        out.update(measures.cloud_shift_measures(end_poses, poses[-1], None if c_end is None else c_end[0]))
    if end_poses is not None and end_poses.shape[0] >= 3:
        out.update(measures.cloud_measures(end_poses, poses[-1], covs[-1], config.pr))
    for mp in maps_:
        out.update(measures.map_measures(mp, config.pr, samplers.get(mp.name)))
    if end_poses is not None and end_poses.shape[0] >= 10:
        out.update(_accuracy_metrics(config, traj, poses, covs, end_poses, c_end, ds))
    return out


def _accuracy_metrics(
    config: RunConfig,
    traj: trajectories.Trajectory,
    poses: NDArray[np.float64],
    covs: NDArray[np.float64],
    end_poses: NDArray[np.float64],
    c_end: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    ds: DriveSetup | None = None,
) -> dict[str, float]:
    """How wrong each Gaussian method is against this run's Monte Carlo cloud.

    Method A (Cartesian Gaussian), the exponential-coordinates Gaussian
    (the banana) and Method C (``c_end``: the unscented transform's mean and
    covariance) of the same wheel-noise model, against the end-pose cloud
    (:func:`pose_uncertainty.analysis.accuracy.compare_methods`). Deterministic:
    its own generator is derived from the run's seed. Empty when either Gaussian is
    degenerate (a drive that never turns, the synchro drive, has no heading spread):
    the comparison needs a density.
    """
    cov0 = None
    if config.cov0 is not None:
        # world-frame Σ_0 → body-frame exponential coordinates at the start pose (first order):
        # δp = T ξ with T = blockdiag(R(θ₀), 1), so Σ_ξ = Tᵀ Σ_0 T
        c, s = math.cos(traj.start[2]), math.sin(traj.start[2])
        T = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        cov0 = T.T @ np.asarray(config.cov0, dtype=np.float64) @ T
    if ds is None:
        E = expcoords.propagate(traj, config.k_r, config.k_l, cov0=cov0)
    else:  # the drive's own banana
        E = drive_expcoords(ds, cov0)
    if not (_positive_definite(covs[-1]) and _positive_definite(E.covs[-1])):
        return {}
    res = accuracy.compare_methods(
        end_poses, (poses[-1], covs[-1]), (E.poses[-1], E.covs[-1]),
        np.random.default_rng([config.seed, 1]), n_threshold=50_000, unscented=c_end,
    )  # fmt: skip
    return accuracy.flatten(res)


def _positive_definite(cov: NDArray[np.float64]) -> bool:
    """Whether a covariance has a Cholesky factor (what the accuracy comparison's densities need)."""
    try:
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        return False
    return True
