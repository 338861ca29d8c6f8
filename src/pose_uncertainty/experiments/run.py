"""One run: its execution and its result.

A *run* is one parameter point of a sweep: a trajectory, the odometry error
constants, a seed and what to compute — Method A (covariance propagation with
its error ellipses), Method C (the unscented transform, always: a loop over the
steps, a fraction of a second per 1000 steps), Monte Carlo end poses under the same
model, and optional probability maps (Method B). :func:`execute` turns a
:class:`~pose_uncertainty.experiments.config.RunConfig` into a :class:`RunResult` —
after :mod:`pose_uncertainty.experiments.cost` has checked that it fits the machine —
and computes every measure once (:mod:`pose_uncertainty.analysis.measures`);
:mod:`pose_uncertainty.records.run` writes and reads results as MCAP files,
:mod:`pose_uncertainty.present.figures` draws them. With a ``drive`` section,
:mod:`pose_uncertainty.experiments.drive_run` computes the drive's Method A, Monte Carlo
and banana.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..analysis import accuracy, measures
from ..core import trajectories
from ..core.grids import Grid
from ..core.provenance import provenance
from ..core.table_io import jsonable
from ..methods import covariance, expcoords, maps, motion_models, sampling, unscented
from ..methods.covariance import CovarianceResult
from ..methods.maps import ProbabilityMap
from ..methods.particles import DrawCache
from . import cost
from .config import MapConfig, MonteCarloConfig, RunConfig, map_kind
from .drive_run import DriveSetup
from .drive_run import expcoords as drive_expcoords
from .drive_run import measures as drive_measures
from .drive_run import method_a as drive_method_a
from .drive_run import sample as drive_sample
from .drive_run import setup as drive_setup
from .outcome import Measured
from .progress import Progress

__all__ = [
    # the configuration (pose_uncertainty.experiments.config), imported here for the callers of execute
    "MapConfig",
    "MonteCarloConfig",
    "RunConfig",
    "RunResult",
    "execute",
    "map_kind",
]


@dataclass(frozen=True, eq=False)
class RunResult(Measured):
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
    unscented_covs : ndarray, shape (N+1, 3, 3) or None — Method C's covariance at every pose
        (None with a drive: Method C is the differential drive's)
    expcoords_levels : dict of str to float — per Pr label (``"98_89"``), the density level
        [1/m²] of the exponential-coordinates Gaussian's planar region whose coverage the run
        measured (where its boundary is drawn); not logged, empty without the accuracy comparison
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
    unscented_covs: NDArray[np.float64] | None = None
    expcoords_levels: dict[str, float] = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        """Number of steps N."""
        return int(self.times.size - 1)

    def ellipse_steps(self) -> list[int]:
        """Steps at which ellipses are drawn: ``n_ellipses`` regular intervals, the last = N."""
        n = self.n_steps
        if self.config.n_ellipses >= n:  # marks closer than a step: every step (no array of n_ellipses)
            return list(range(1, n + 1))
        marks = np.linspace(0, n, self.config.n_ellipses + 1).round().astype(int)[1:]
        return sorted({int(m) for m in marks if m > 0})


# --- execution ------------------------------------------------------------------------------


def execute(
    config: RunConfig,
    *,
    distances: bool = True,
    progress: Callable[[str], Callable[[int, int], None]] | None = None,
    kernel: str = "auto",
    cache: DrawCache | None = None,
    coverage_only: bool = False,
    reuse: RunResult | None = None,
) -> RunResult:
    """Compute one run: trajectory, covariance, Monte Carlo, maps and every measure.

    Parameters
    ----------
    config : RunConfig
    distances : bool
        False: the accuracy comparison leaves out its density distances on a grid
        (``accuracy_*_hellinger``, ``_kl``, ``_model_mass_on_grid``, the floors), which cost
        most of a run's measures; every measure it keeps is the same number as with True
        (what the explorer computes on each move of a control; a run logs them all).
    progress : callable, optional
        ``progress(label)`` gives the ``(done, total)`` callback of the long loop ``label``
        (the Monte Carlo, each map); default a :class:`~pose_uncertainty.experiments.progress.Progress`
        on stderr. An exception raised by a callback stops the run (the explorer abandons
        a superseded map this way).
    kernel : {"auto", "numpy", "compiled"}
        The Monte Carlo's end poses by numpy or by the compiled kernel
        (:func:`pose_uncertainty.methods.sampling.sample_end_poses` with ``draws="auto"``: the
        compiled kernel draws its own per-block normals, or, given a ``cache``, takes numpy's
        per-chunk draws and equals the numpy kernel's end poses up to rounding, within the
        reproducibility contract); ``"auto"`` (default) as a run logs them.
        ``"compiled"`` also runs Method C's loop over the steps compiled
        (:func:`pose_uncertainty.methods.unscented.propagate`, equal up to rounding).
    cache : DrawCache, optional
        Keeps the Monte Carlo's standard normals for the next run of the same seed,
        particles and steps (:class:`pose_uncertainty.methods.particles.DrawCache`; the result
        is the same with or without it).
    coverage_only : bool
        True (with ``distances=False``): the accuracy comparison keeps each region's planar
        coverage (and the banana's levels) only, the same numbers
        (:func:`pose_uncertainty.analysis.accuracy.compare_methods`); what the explorer shows.
    reuse : RunResult, optional
        The result of this configuration but for its probability level ``pr``, computed with
        the same ``distances``, ``kernel`` and ``coverage_only``: its Monte Carlo clouds, maps
        and accuracy comparison (which measures every level of
        :data:`pose_uncertainty.analysis.accuracy.PRS` at once) are taken over, the rest is
        computed; the same metrics as without it (the explorer's move of the level).

    Returns
    -------
    RunResult
        Everything but ``timings`` is a deterministic function of ``config``
        (including its seed), the package version and the environment.

    Raises
    ------
    pose_uncertainty.experiments.cost.CostError
        Before anything is allocated, when the run's estimated memory or time
        exceeds the limits (``POSE_UNCERTAINTY_MAX_MEMORY``, ``POSE_UNCERTAINTY_MAX_SECONDS``).
    """
    cost.check(config)  # the guard: one line naming the estimate, the limit and the drivers
    if reuse is not None and reuse.config != dataclasses.replace(config, pr=reuse.config.pr):
        raise ValueError("execute: reuse holds the result of another configuration "
                         "(allowed: one that differs in pr only)")  # fmt: skip
    bar = progress or (lambda label: Progress(f"{config.name}: {label}"))
    timings: dict[str, float] = {}
    t_all = time.perf_counter()
    with _timed(timings, "trajectory_s"):
        traj = trajectories.from_config(config.trajectory)
        ds = None if config.drive is None else drive_setup(config.drive, traj, config.k_r, config.k_l)
    with _timed(timings, "covariance_s"):
        if ds is None:
            cres = covariance.propagate(traj, config.k_r, config.k_l, cov0=_cov0(config))
        else:  # the drive following the path (experiments/drive_run.py)
            cres = drive_method_a(ds, _cov0(config))
    c_end = None
    ures: CovarianceResult | None = None
    if ds is None:  # Method C, on the differential drive's wheel-noise model
        with _timed(timings, "unscented_s"):
            ures = unscented.propagate(traj, config.k_r, config.k_l, cov0=_cov0(config),
                                       kernel="compiled" if kernel == "compiled" else "numpy")  # fmt: skip
        c_end = (np.asarray(ures.poses[-1], dtype=np.float64), np.asarray(ures.covs[-1], dtype=np.float64))
    poses = np.ascontiguousarray(cres.poses, dtype=np.float64)
    covs = np.ascontiguousarray(cres.covs, dtype=np.float64)
    end_poses: NDArray[np.float64] | None = None
    checkpoints: dict[int, NDArray[np.float64]] = {}
    if reuse is not None:
        end_poses, checkpoints = reuse.end_poses, dict(reuse.checkpoints)
    elif config.monte_carlo.n_particles > 0:
        with _timed(timings, "monte_carlo_s"):
            end_poses, checkpoints = _monte_carlo(config, traj, ds, bar("Monte Carlo"), kernel, cache)
    maps, samplers = ([], {}) if reuse is None else (list(reuse.maps), dict(reuse.map_samplers))
    for i, mcfg in enumerate(config.maps if reuse is None else ()):
        with _timed(timings, f"map_{mcfg.name}_s"):
            maps.append(_compute_map(mcfg, traj, bar(f"map {mcfg.name}")))
            samplers[mcfg.name] = _map_sampler(config, mcfg, traj, i)
    with _timed(timings, "measures_s"):
        accuracy = None if reuse is None else {
            **{k: v for k, v in reuse.metrics.items() if k.startswith("accuracy_")},
            **{_LEVEL + k: v for k, v in reuse.expcoords_levels.items()},
        }
        metrics = _measures(config, traj, poses, covs, end_poses, maps, samplers, c_end, ds, distances,
                            coverage_only, accuracy)  # fmt: skip
        if ds is not None:  # the growth laws and the skid-steer's turn bias
            metrics.update(drive_measures(ds, poses, covs, config.monte_carlo.checkpoints,
                                          checkpoints, end_poses))  # fmt: skip
    # the banana's region levels: what its boundary is drawn at, kept beside the measures (not logged)
    levels = {k[len(_LEVEL):]: metrics.pop(k) for k in [k for k in metrics if k.startswith(_LEVEL)]}
    timings["total_s"] = time.perf_counter() - t_all
    return RunResult(
        config=config, times=np.ascontiguousarray(traj.times, dtype=np.float64), poses=poses,
        covs=covs, end_poses=end_poses, checkpoints=checkpoints, maps=tuple(maps),
        map_samplers=samplers, metrics=metrics,
        unscented_covs=None if ures is None else np.ascontiguousarray(ures.covs, dtype=np.float64),
        expcoords_levels=levels,
        metric_units={k: measures.describe(k)[0] for k in metrics},
        metric_definitions={k: measures.describe(k)[1] for k in metrics},
        timings=timings, provenance=provenance(),
    )  # fmt: skip


#: The prefix of the banana's region levels in the accuracy comparison's flattened entries.
_LEVEL = "accuracy_expcoords_level_xy_"


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
    config: RunConfig,
    traj: trajectories.Trajectory,
    ds: DriveSetup | None = None,
    progress: Callable[[int, int], None] | None = None,
    kernel: str = "auto",
    cache: DrawCache | None = None,
) -> tuple[NDArray[np.float64], dict[int, NDArray[np.float64]]]:
    """Monte Carlo end poses (n, 3) and the clouds at the checkpoint steps (of the drive, if any)."""
    mc = config.monte_carlo
    rng = np.random.default_rng(config.seed)
    steps = [*mc.checkpoints, traj.n_steps] if mc.checkpoints else None
    if ds is None:
        out = sampling.sample_end_poses(
            traj, config.k_r, config.k_l, mc.n_particles, rng,
            regime=mc.regime, method=mc.method, cov0=config.cov0, checkpoints=steps,
            progress=progress, kernel=kernel, cache=cache,
        )  # fmt: skip
    else:
        out = drive_sample(ds, mc.n_particles, rng, regime=mc.regime, method=mc.method,
                           cov0=_cov0(config), checkpoints=steps, kernel=kernel, cache=cache)  # fmt: skip
    if steps is None:  # the sampler's fast path: end poses only, (n, 3)
        return np.ascontiguousarray(out, dtype=np.float64), {}
    # (n, C, 3): the clouds at the checkpoints, then at the end
    clouds = {s: np.ascontiguousarray(out[:, j, :], dtype=np.float64) for j, s in enumerate(mc.checkpoints)}
    return np.ascontiguousarray(out[:, -1, :], dtype=np.float64), clouds


def _compute_map(
    mcfg: MapConfig, traj: trajectories.Trajectory, progress: Callable[[int, int], None] | None = None
) -> ProbabilityMap:
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
        pm = maps.multi_step_map(mcfg.model, traj.controls, traj.dt, start=traj.start, grid=fixed,
                                 progress=progress, **params)  # fmt: skip
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
    distances: bool = True,
    coverage_only: bool = False,
    accuracy: dict[str, float] | None = None,
) -> dict[str, float]:
    """Every measure of the run (:mod:`pose_uncertainty.analysis.measures`), computed once here.

    ``c_end`` is Method C's (mean, covariance) at the end of the path (None with a drive:
    Method C is the differential drive's); ``ds`` the drive following the path, if any;
    ``accuracy`` the accuracy comparison's entries when known already (``execute``'s ``reuse``).
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
        out.update(accuracy if accuracy is not None else
                   _accuracy_metrics(config, traj, poses, covs, end_poses, c_end, ds, distances, coverage_only))
    return out


def _accuracy_metrics(
    config: RunConfig,
    traj: trajectories.Trajectory,
    poses: NDArray[np.float64],
    covs: NDArray[np.float64],
    end_poses: NDArray[np.float64],
    c_end: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    ds: DriveSetup | None = None,
    distances: bool = True,
    coverage_only: bool = False,
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
        distances=distances, levels=True, coverage_only=coverage_only,
    )  # fmt: skip
    return accuracy.flatten(res)


def _positive_definite(cov: NDArray[np.float64]) -> bool:
    """Whether a covariance has a Cholesky factor (what the accuracy comparison's densities need)."""
    try:
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        return False
    return True
