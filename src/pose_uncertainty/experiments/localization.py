"""One localization run: its execution on simulated data, its result, and the pipeline's sets of runs.

A *localization run* simulates a robot driving a path in a world of landmarks and walls
with noisy wheels and sensors (:mod:`pose_uncertainty.localization.simulate`), runs each
configured Bayes filter — the EKF (Method A's prediction), the histogram filter (Method B's)
and the particle filter (Monte Carlo's) — on the same data, and measures them against the
true path. :func:`execute_localization` turns a
:class:`~pose_uncertainty.experiments.localization_config.LocalizationConfig` (its keys, checks
and defaults: :mod:`pose_uncertainty.experiments.localization_config`) into a
:class:`LocalizationResult`; :mod:`pose_uncertainty.records.localization` writes and reads it as
one MCAP log, :mod:`pose_uncertainty.present.localization` draws it.

Seeds: run ``r`` of the ``R`` draws its truth and measurements from
``default_rng([seed, 0, r])`` and the particle filter from ``default_rng([seed, 1, r])``,
so every filter sees the same data and a result is a deterministic function of the
configuration.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis import localization as lm
from ..analysis import measures
from ..core.provenance import provenance
from ..core.validation import parse_numbers
from ..localization import ekf, histogram, particle, simulate
from ..localization.result import FilterResult, Start
from ..localization.world import World
from . import cost
from .localization_config import (  # re-exported: the configuration's public names
    KIND,
    LOCALIZATION_KEYS,
    TRAJECTORY_BUILDERS,
    Array,
    LocalizationConfig,
    build_world,
    code_defaults,
    is_localization_config,
)
from .outcome import Measured
from .progress import Progress
from .sweep import ConfigError, Run, expand_set

__all__ = [
    "KIND",
    "LOCALIZATION_KEYS",
    "TRAJECTORY_BUILDERS",
    "FilterTrack",
    "LocalizationConfig",
    "LocalizationResult",
    "build_world",
    "code_defaults",
    "execute_localization",
    "expand_localization",
    "is_localization_config",
]


# ============================================================================= results


@dataclass(frozen=True, eq=False)
class FilterTrack:
    """One filter on the first of the R runs (what the log shows), with its series over all of them.

    Attributes
    ----------
    name : str — "ekf", "histogram" or "particle"
    mean : ndarray, shape (K, 3) [m, m, rad]; cov : ndarray, shape (K, 3, 3)
    series : dict of str to ndarray (K,) — errors, σ's, NEES (and ``nees_avg`` over the R runs),
        region flags and diagnostics (:func:`pose_uncertainty.analysis.localization.filter_measures`)
    particles : dict of int to ndarray (m, 4) — at the logged steps: x [m], y [m], θ [rad], weight
        (every ``n/m``-th particle, ``m = min(n, max_particles_logged)``)
    grids : dict of int to ndarray (nx, ny) — the histogram filter's θ-marginal mass at the logged steps
    grid_geometry : ndarray, shape (4,) — ``(x0, y0, h, nθ)``: centre of cell [0, 0] [m], side [m], headings
    """

    name: str
    mean: Array
    cov: Array
    series: dict[str, Array] = field(default_factory=dict)
    particles: dict[int, Array] = field(default_factory=dict)
    grids: dict[int, Array] = field(default_factory=dict)
    grid_geometry: Array | None = None


@dataclass(frozen=True, eq=False)
class LocalizationResult(Measured):
    """The outcome of a localization run: the first simulated run's data and every filter on it.

    Attributes
    ----------
    config : LocalizationConfig; world : World
    times : ndarray (K,) [s]; true_poses, odometry : ndarray (K, 3)
    ds_r, ds_l : ndarray (N,) [m] — measured wheel travels
    landmark_z : ndarray (K, L, 2); landmark_valid : ndarray of bool (K, L)
    beam_z : ndarray (K, B) [m] or None; beam_valid : ndarray of bool (K,)
    filters : dict of str to FilterTrack — in the order of
        :data:`~pose_uncertainty.analysis.localization.FILTERS`
    series : dict of str to ndarray (K,) — run-level series (dead-reckoning error)
    metrics, metric_units, metric_definitions : dict — every measure (deterministic)
    timings : dict of str to float — wall-clock seconds, NOT deterministic
        (``<filter>_step_s``: mean compute time per step over the R runs)
    provenance : dict of str to str
    """

    config: LocalizationConfig
    world: World
    times: Array
    true_poses: Array
    odometry: Array
    ds_r: Array
    ds_l: Array
    landmark_z: Array
    landmark_valid: NDArray[np.bool_]
    beam_z: Array | None
    beam_valid: NDArray[np.bool_]
    filters: dict[str, FilterTrack]
    series: dict[str, Array] = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        """Number of steps N."""
        return int(self.times.size - 1)


# ============================================================================= execution


class _Display:
    """Collects what the log shows of a filter on the first run: subsampled particles, grid marginals."""

    def __init__(self, name: str, log: Mapping[str, Any], n_steps: int) -> None:
        self.name, self.n_steps = name, n_steps
        self.p_every, self.g_every, self.m = log["particles_every"], log["grid_every"], log["max_particles_logged"]
        self.particles: dict[int, Array] = {}
        self.grids: dict[int, Array] = {}
        self.geometry: Array | None = None

    def _due(self, k: int, every: int) -> bool:
        return every > 0 and (k % every == 0 or k == self.n_steps)

    def __call__(self, k: int, state: dict[str, Any]) -> None:
        if "particles" in state and self._due(k, self.p_every):
            P, w = state["particles"], state["weights"]
            n = P.shape[0]
            idx = (np.arange(min(n, self.m)) * n) // min(n, self.m)  # every n/m-th: no random draw
            self.particles[k] = np.ascontiguousarray(np.column_stack([P[idx], w[idx]]), dtype=np.float64)
        if "belief_xy" in state:
            g = state["grid"]
            self.geometry = np.array([g.x0, g.y0, g.resolution, g.ntheta], dtype=np.float64)
            if self._due(k, self.g_every):
                self.grids[k] = np.array(state["belief_xy"], dtype=np.float64)


def _on_step(show: _Display | None, progress: Progress, done: int, total: int) -> Callable[[int, dict[str, Any]], None]:
    """The filters' ``on_step``: the display's (first run only), then the run's progress."""

    def on_step(k: int, state: dict[str, Any]) -> None:
        if show is not None:
            show(k, state)
        progress(done + k + 1, total)

    return on_step


def _run_filter(name: str, cfg: LocalizationConfig, run: simulate.SimulatedRun, world: World, start: Start,
                sensors: Mapping[str, Any], r: int, on_step: Any) -> FilterResult:  # fmt: skip
    """One filter on one simulated run."""
    f = cfg.filters[name]
    sensor = sensors[f["sensor"]]
    if name == "ekf":
        return ekf.run_ekf(run, world, sensor, ekf.EKFConfig(cfg.motion(name), f["association"]), start,
                           on_step=on_step)  # fmt: skip
    if name == "histogram":
        hc = histogram.HistogramFilterConfig(cfg.motion(name), f["resolution"], f["ntheta"], f["mask_occupied"],
                                             f["association"], f["workers"])  # fmt: skip
        return histogram.run_histogram(run, world, sensor, hc, start, on_step=on_step)
    opts = {k: v for k, v in f.items() if k not in ("sensor", "motion")}
    pc = particle.ParticleFilterConfig(motion=cfg.motion(name), **opts)
    return particle.run_particle(run, world, sensor, np.random.default_rng([cfg.seed, 1, r]), pc, start,
                                 on_step=on_step)  # fmt: skip


def execute_localization(config: LocalizationConfig) -> LocalizationResult:
    """Simulate the R runs, run every configured filter on each, and compute every measure.

    The cost guard (:func:`pose_uncertainty.experiments.cost.check_localization`) first
    refuses a run over the memory or time limit, with one line, and announces a long one;
    progress (steps of every filter on every run) goes to stderr
    (:class:`~pose_uncertainty.experiments.progress.Progress`).

    Returns
    -------
    LocalizationResult
        Everything but ``timings`` is a deterministic function of ``config`` (its seed
        included), the package version and the environment.

    Raises
    ------
    pose_uncertainty.experiments.cost.CostError
        The run's estimate exceeds a limit (nothing was allocated).
    """
    cost.check_localization(config)  # the guard: one line naming the estimate, the limit and the drivers
    t_all = time.perf_counter()
    world, traj = config.build_world(), config.build_trajectory()
    lm_sensor, beam_sensor = config.landmark_sensor(), config.beam_sensor()
    sensors: dict[str, Any] = {"landmarks": lm_sensor, "beams": beam_sensor}
    start = config.start(traj)
    sc, truth = config.scenario, config.truth
    names = [f for f in lm.FILTERS if f in config.filters]
    runs: list[simulate.SimulatedRun] = []
    results: dict[str, list[FilterResult]] = {f: [] for f in names}
    shown = {f: _Display(f, config.log, traj.n_steps) for f in names}
    seconds = {f: 0.0 for f in names}
    t_sim = 0.0
    n_steps = traj.n_steps + 1
    progress = Progress(f"{config.name}: filters {', '.join(names)}")
    total = config.repeat * len(names) * n_steps
    for r in range(config.repeat):
        t0 = time.perf_counter()
        run = simulate.simulate(
            traj, world, np.random.default_rng([config.seed, 0, r]), k_r=truth["k_r"], k_l=truth["k_l"],
            regime=truth["regime"], landmark_sensor=lm_sensor, beam_sensor=beam_sensor,
            kidnap_step=-1 if sc["kidnap_step"] is None else sc["kidnap_step"], kidnap_pose=sc["kidnap_pose"],
            truth=truth["path"],
        )  # fmt: skip
        t_sim += time.perf_counter() - t0
        runs.append(run)
        for i, f in enumerate(names):
            done = (r * len(names) + i) * n_steps
            res = _run_filter(f, config, run, world, start, sensors, r,
                              _on_step(shown[f] if r == 0 else None, progress, done, total))  # fmt: skip
            results[f].append(res)
            seconds[f] += float(res.step_seconds.sum())
    t0 = time.perf_counter()
    metrics, run_series = lm.run_measures(runs, world.n_landmarks)
    tracks: dict[str, FilterTrack] = {}
    from_step = sc["kidnap_step"] or 0
    for f in names:
        cells = None
        if f == "histogram" and shown[f].geometry is not None:
            g = histogram.pose_grid_for(world, config.filters[f]["resolution"], config.filters[f]["ntheta"])
            cells = g.nx * g.ny * g.ntheta
        m, series = lm.filter_measures(f, results[f], runs, pos_tol=config.success["pos_tol"],
                                       head_tol=config.success["head_tol"], from_step=from_step, cells=cells)  # fmt: skip
        metrics.update(m)
        first = results[f][0]
        tracks[f] = FilterTrack(f, np.ascontiguousarray(first.mean), np.ascontiguousarray(first.cov), series,
                                shown[f].particles, shown[f].grids, shown[f].geometry)  # fmt: skip
    K = traj.n_steps + 1
    timings = {f"{f}_step_s": seconds[f] / (config.repeat * K) for f in names}
    timings |= {f"{f}_total_s": seconds[f] for f in names}
    timings |= {"simulate_s": t_sim, "measures_s": time.perf_counter() - t0, "total_s": time.perf_counter() - t_all}
    r0 = runs[0]
    return LocalizationResult(
        config=config, world=world, times=np.ascontiguousarray(r0.times, dtype=np.float64),
        true_poses=r0.true_poses, odometry=r0.odometry, ds_r=r0.ds_r, ds_l=r0.ds_l, landmark_z=r0.landmark_z,
        landmark_valid=r0.landmark_valid, beam_z=r0.beam_z, beam_valid=r0.beam_valid, filters=tracks,
        series=run_series, metrics=metrics, metric_units={k: measures.describe(k)[0] for k in metrics},
        metric_definitions={k: measures.describe(k)[1] for k in metrics}, timings=timings, provenance=provenance(),
    )  # fmt: skip


# ============================================================================= the pipeline's sets


def _normalize(cfg: Mapping[str, Any]) -> dict[str, Any]:
    return LocalizationConfig.from_dict(cfg).to_dict()


def expand_localization(config: Mapping[str, Any]) -> dict[str, list[Run]]:
    """Expand the pipeline config's localization sets (key ``localization.sets``) into their runs.

    Each set is a sweep as :func:`pose_uncertainty.experiments.sweep.expand_set` (``base`` + ``sweep``
    axes) over localization configurations; ``localization.defaults`` and the config's ``seed``
    are shared by every set. An empty dict when ``localization.enabled`` is false.

    Raises
    ------
    ConfigError naming ``localization.sets.<set>``, the run and the bad key.
    """
    section = config.get("localization") or {}
    if not section.get("enabled", True):
        return {}
    defaults = parse_numbers(dict(section.get("defaults", {}) or {}))
    if "seed" in config and "seed" not in defaults:
        defaults["seed"] = config["seed"]
    out: dict[str, list[Run]] = {}
    for name, spec in (section.get("sets", {}) or {}).items():
        try:
            out[name] = expand_set(name, parse_numbers(spec), defaults, normalize=_normalize)
        except ConfigError as exc:
            raise ConfigError(str(exc).replace(f"experiment_sets.{name}", f"localization.sets.{name}", 1)) from None
    return out


