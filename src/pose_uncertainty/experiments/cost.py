"""What a run will cost, known before it runs: peak memory, time, and the guard.

:func:`estimate` predicts, from a run's parameters alone (nothing of the size of
the run is allocated), the peak resident memory [bytes] and the wall-clock time
[s] of computing and logging it (``pose_uncertainty.pipeline.jobs.simulate_run``:
:func:`~pose_uncertainty.experiments.run.execute` then
:func:`~pose_uncertainty.records.run.write_run`), as a sum of named *drivers*:

========================  ===========================================  ==================================
driver                    memory                                       time
========================  ===========================================  ==================================
interpreter               72 MiB (Python, numpy, scipy, mcap)          0.5 s
steps                     2 kB × (N+1): poses, Method A covariances    200 µs × (N+1): mostly writing
                          and the per-step messages of the log         the per-step log messages
Monte Carlo               140 B × n (+ 70 B × n × C checkpoints),      100 ns × n × N (per_step),
                          + the chunks in flight: workers × 80 B ×     50 ns per_run, 220 ns with
                          max(65536, N)                                checkpoints
accuracy metrics (n≥10)   16 MiB + 60 B × n                            1 s + 10 µs × n
single-step map           cells × 50 B (velocity), 160 B (odometry)    cells × 80 ns (velocity), 150 ns
                                                                       (cell-averaged), 700 ns (odometry)
multi-step map            64 MiB + (24 + 0.5 M) B × padded cells: the  cells × N × 120 ns (velocity),
                          final grid (fixed ``size``, or the spread    600 ns (odometry), + 5 ms × N
                          of the noise, at most ``max_cells``),
                          widened by the kernel's window, M its
                          heading offsets
map sampler               140 B × n_sampler                            400 ns × n_sampler × N
ellipses                  40 B × min(n_ellipses, N)                    20 µs × min(n_ellipses, N) (figures)
========================  ===========================================  ==================================

(N steps, n particles, C checkpoints; cells = nx·ny·nθ.) The coefficients were
measured on this project's 2-core CI machine (the peak resident set size of a
fresh process, ``VmHWM``); ``tests/test_cost.py`` checks the memory estimate
against the measured peak of representative runs, within [1/1.1, 2] times it
(0.98–1.4 when last measured, 2026-11-30, after a run stopped importing
``scipy.stats``). Time is an order of magnitude only (machines differ): it
sets a cluster job's ``runtime``, with a wide margin, and the time guard.

The guard (:func:`check`, called by ``execute`` before anything is allocated)
refuses a run whose estimate exceeds a limit, with one line naming the estimate,
the limit and the parameters that drive it. Limits, from the environment:

``POSE_UNCERTAINTY_MAX_MEMORY``
    bytes with an optional unit (``64G``, ``500M``, ``2TiB``) or a percentage of
    the memory available now (``80%``; MemAvailable of ``/proc/meminfo``);
    ``none`` disables. Default ``50%``.
``POSE_UNCERTAINTY_MAX_SECONDS``
    seconds, or with a unit (``90m``, ``6h``); ``none`` disables. Default ``1h``.

Both pass through Snakemake to every job (``POSE_UNCERTAINTY_MAX_MEMORY=64G make
report``; SLURM jobs inherit the submitting environment).
"""

from __future__ import annotations

import json
import math
import os
import re
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core import trajectories
from ..core.threads import default_workers
from .config import RunConfig, map_kind

__all__ = [
    "ANNOUNCE_SECONDS",
    "ENV_MAX_MEMORY",
    "ENV_MAX_SECONDS",
    "Cost",
    "CostError",
    "Driver",
    "Limits",
    "check",
    "check_localization",
    "check_study",
    "estimate",
    "estimate_localization",
    "estimate_study",
    "job_resources",
    "limits",
    "mem_available",
    "resources_of",
]

ENV_MAX_MEMORY = "POSE_UNCERTAINTY_MAX_MEMORY"
ENV_MAX_SECONDS = "POSE_UNCERTAINTY_MAX_SECONDS"
DEFAULT_MAX_MEMORY = "50%"
DEFAULT_MAX_SECONDS = "1h"
#: The largest limits that can be set (beyond them a limit means nothing; ``none`` disables one).
MAX_MEMORY_LIMIT = 1 << 60
MAX_SECONDS_LIMIT = 1e9

MiB = 1 << 20
#: runs estimated to take longer than this [s] say so on stderr before they start
ANNOUNCE_SECONDS = 30.0

# --- coefficients (measured, see the module docstring) --------------------------------------
_BASE_BYTES, _BASE_S = 72 * MiB, 0.5
_STEP_BYTES, _STEP_S = 2000.0, 200e-6
_PARTICLE_BYTES, _CHECKPOINT_BYTES, _CHUNK_BYTES = 140.0, 70.0, 80.0
_CHUNK_ELEMENTS = 1 << 16  # pose_uncertainty.methods.particles.CHUNK_ELEMENTS
_MC_S = {"per_step": 100e-9, "per_run": 50e-9, "checkpoints": 220e-9}
_ACCURACY_BYTES, _ACCURACY_PARTICLE_BYTES = 16 * MiB, 60.0
_ACCURACY_S, _ACCURACY_PARTICLE_S = 1.0, 10e-6
_SINGLE_CELL_BYTES = {"velocity": 50.0, "odometry": 160.0}
_SINGLE_CELL_S = {"velocity": 80e-9, "averaged": 150e-9, "odometry": 700e-9}
_MULTI_MAP_BYTES, _MULTI_PADDED_BYTES, _MULTI_OFFSET_BYTES, _MULTI_STEP_S = 64 * MiB, 24.0, 0.5, 5e-3
_MULTI_CELL_STEP_S = {"velocity": 120e-9, "odometry": 600e-9}
_SAMPLER_BYTES, _SAMPLER_S = 140.0, 400e-9
_ELLIPSE_BYTES, _ELLIPSE_S = 40.0, 20e-6
#: the spread a growing map grid holds, in standard deviations of the model's noise, each side
_SPREAD_SIGMAS = 6.0
#: trajectories longer than this are not built to predict a growing map grid (its cap is used)
_BUILD_MAX_STEPS = 100_000


class CostError(ValueError):
    """A run refused by the guard: its estimate exceeds a limit (one line, says how to change it)."""


@dataclass(frozen=True)
class Driver:
    """One term of a cost estimate.

    Attributes
    ----------
    name : str — what costs (``"steps"``, ``"Monte Carlo"``, ``"map velocity"``)
    params : str — the parameters that set it, as the config spells them
    mem_bytes : float — its own peak memory [bytes]
    seconds : float — its share of the time [s]
    cells : float — the cells of a map (0 for the other drivers)
    """

    name: str
    params: str
    mem_bytes: float
    seconds: float
    cells: float = 0.0


@dataclass(frozen=True)
class Cost:
    """Estimated peak memory [bytes] and wall-clock time [s] of one run, and their drivers."""

    mem_bytes: int
    seconds: float
    drivers: tuple[Driver, ...]

    def top(self, what: str, k: int = 2) -> list[Driver]:
        """The ``k`` largest drivers of ``"mem_bytes"`` or ``"seconds"``."""
        return sorted(self.drivers, key=lambda d: -getattr(d, what))[:k]

    def summary(self) -> str:
        """One line: memory and time, and the largest driver of each."""
        m, t = self.top("mem_bytes", 1)[0], self.top("seconds", 1)[0]
        return (
            f"about {fmt_bytes(self.mem_bytes)} and {fmt_seconds(self.seconds)} "
            f"(memory mostly {m.name}: {m.params}; time mostly {t.name}: {t.params})"
        )


@dataclass(frozen=True)
class Limits:
    """Limits of the guard; None = no limit. ``*_source`` says where each came from."""

    mem_bytes: int | None
    seconds: float | None
    mem_source: str = ""
    seconds_source: str = ""


# --- formatting ----------------------------------------------------------------------------


def fmt_bytes(n: float) -> str:
    """``1.5 GiB``-style size."""
    for unit, size in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def fmt_seconds(s: float) -> str:
    """``45 s``, ``12 min``, ``3.2 h``, ``4.1 days``."""
    if s < 120:
        return f"{s:.2g} s"
    if s < 7200:
        return f"{s / 60:.3g} min"
    if s < 3 * 86400:
        return f"{s / 3600:.3g} h"
    return f"{s / 86400:.3g} days"


# --- the estimate ----------------------------------------------------------------------------


def _config(config: RunConfig | Mapping[str, Any]) -> RunConfig:
    return config if isinstance(config, RunConfig) else RunConfig.from_dict(config)


def _trajectory_text(tp: Mapping[str, Any], n: int) -> str:
    shown = ", ".join(
        f"{k} {v:g}" if isinstance(v, int | float) else f"{k} {v!r}"
        for k, v in tp.items()
        if k not in ("name", "start", "profile", "track", "direction")
    )
    return f"N = {n:,} steps from trajectory {tp['name']} with {shown}"


def _monte_carlo_driver(cfg: RunConfig, n_steps: int) -> list[Driver]:
    mc = cfg.monte_carlo
    n, c = mc.n_particles, len(mc.checkpoints)
    if n == 0:
        return []
    chunk_elements = max(_CHUNK_ELEMENTS, n_steps) * min(default_workers(), max(1, n))  # the Monte Carlo sampler's threads
    mem = _PARTICLE_BYTES * n + _CHECKPOINT_BYTES * n * c + _CHUNK_BYTES * chunk_elements
    rate = _MC_S["checkpoints"] if c else _MC_S[mc.regime]
    params = f"monte_carlo.n_particles = {n:,} × N = {n_steps:,} steps" + (
        f", {c} checkpoints" if c else ""
    )
    out = [Driver("Monte Carlo", params, mem, rate * n * n_steps)]
    if n >= 10:  # execute() compares the methods with the cloud from 10 particles on
        out.append(
            Driver(
                "accuracy metrics",
                f"monte_carlo.n_particles = {n:,}",
                _ACCURACY_BYTES + _ACCURACY_PARTICLE_BYTES * n,
                _ACCURACY_S + _ACCURACY_PARTICLE_S * n,
            )
        )
    return out


def _n_theta(theta_resolution: float) -> int:
    return max(1, math.ceil(2.0 * math.pi / theta_resolution - 1e-9))


@dataclass(frozen=True)
class _MapStepNoise:
    """First-order noise of a map's motion model along the trajectory, per step.

    ds [m] travel; trans [m] std of the travel; head_nodes [rad] std of the heading the
    position nodes of a step's kernel carry (ω̂ / δrot1); head [rad] std of the whole
    heading change; span (2,) [m] extent of the noiseless path.
    """

    ds: NDArray[np.float64]
    trans: NDArray[np.float64]
    head_nodes: NDArray[np.float64]
    head: NDArray[np.float64]
    span: NDArray[np.float64]


def _map_step_noise(cfg: RunConfig, params: Mapping[str, Any], model: str) -> _MapStepNoise:
    from ..methods import motion_models as mm

    tp = dict(cfg.trajectory)
    traj = trajectories.build(tp.pop("name"), **tp)
    a = np.asarray(params["alphas"], dtype=np.float64)
    ds = np.abs(traj.ds)
    if model == "velocity":
        var = mm.velocity_variances(traj.controls, a, params["scaling"])  # (N, 3)
        trans = np.sqrt(var[:, 0]) * traj.dt
        head_nodes = np.sqrt(var[:, 1]) * traj.dt
        head = np.sqrt(var[:, 1] + var[:, 2]) * traj.dt
    else:
        rot = np.abs(traj.dtheta) / 2.0
        v1, v2, v3 = mm.odometry_variances(rot, ds, rot, a, params["scaling"])
        trans, head_nodes, head = np.sqrt(v2), np.sqrt(v1), np.sqrt(v1 + v3)
    return _MapStepNoise(ds, trans, head_nodes, head, np.ptp(traj.poses[:, :2], axis=0))


def _multi_map(cfg: RunConfig, i: int, n_steps: int) -> Driver:
    """A multi-step map: its final grid and the FFT buffers of a step.

    The final grid: fixed (``size``), or the noiseless path's box plus
    ``_SPREAD_SIGMAS`` standard deviations of the accumulated noise on each side (first
    order: translation noise plus heading noise times the path still to drive), at most
    ``max_cells``. A step holds, besides the belief, FFT buffers over the grid padded by
    the kernel's window (w cells a side: the step's travel and ``2 × _SPREAD_SIGMAS``
    standard deviations) for every heading, and per source heading the kernel's spectrum
    for each of its M heading offsets: ``(35 + 1.5 M)`` bytes per padded cell (measured).
    Trajectories longer than ``_BUILD_MAX_STEPS`` are not built: their grid is the cap.
    """
    m = cfg.maps[i]
    p = m.params
    over = int(p.get("oversample", 1))
    h = float(p["resolution"]) / over
    n_t = _n_theta(float(p["theta_resolution"]))
    cap = float(p["max_cells"]) * over * over
    noise = _map_step_noise(cfg, p, m.model) if n_steps <= _BUILD_MAX_STEPS else None
    if p.get("size") is not None:
        n = max(1, round(float(p["size"]) / float(p["resolution"])))
        n += 1 - n % 2
        nx = ny = float(n)
        grid = f"size {p['size']!r} m / resolution {p['resolution']!r} m"
    elif noise is None:
        nx = ny = math.sqrt(cap / n_t)
        grid = f"a growing grid of at most max_cells {p['max_cells']:,}"
    else:
        still = np.cumsum(noise.ds[::-1])[::-1] - noise.ds  # path left after each step [m]
        sigma = math.sqrt(float(np.sum(noise.trans**2) + np.sum((noise.head * still) ** 2)))
        reach = _SPREAD_SIGMAS * float(np.max(noise.trans + noise.head * noise.ds))
        side = 2.0 * (_SPREAD_SIGMAS * sigma + reach) + 8.0 * h
        nx, ny = (float(noise.span[0]) + side) / h, (float(noise.span[1]) + side) / h
        if nx * ny * n_t > cap:
            nx, ny = (math.sqrt(cap / n_t),) * 2
        grid = f"a growing grid at resolution {p['resolution']!r} m"
    cells = nx * ny * n_t
    if noise is None:
        w, offsets = 0.5 * nx, float(n_t)
    else:
        spread = noise.ds + 2.0 * _SPREAD_SIGMAS * (noise.trans + noise.head_nodes * noise.ds / 2)
        w = float(np.max(spread)) / h + 4.0
        offsets = min(n_t, 2.0 * _SPREAD_SIGMAS * float(np.max(noise.head_nodes)) / (2 * math.pi / n_t) + 2)
    padded = (nx + w) * (ny + w) * n_t
    return Driver(
        f"map {m.name}",
        f"maps[{i}]: {cells:,.0f} cells ({grid}) × N = {n_steps:,} steps",
        _MULTI_MAP_BYTES + padded * (_MULTI_PADDED_BYTES + _MULTI_OFFSET_BYTES * offsets),
        cells * n_steps * _MULTI_CELL_STEP_S[m.model] + n_steps * _MULTI_STEP_S,
        cells,
    )


def _map(cfg: RunConfig, i: int, n_steps: int) -> Driver:
    m = cfg.maps[i]
    p = m.params
    if map_kind(n_steps) == "multi":
        return _multi_map(cfg, i, n_steps)
    n = max(1, round(float(p["size"]) / float(p["resolution"])))
    n += 1 - n % 2
    cells = float(n * n * _n_theta(float(p["theta_resolution"])))
    averaged = p.get("cell_average")
    averaged = bool(p.get("corrected")) if averaged is None else bool(averaged)
    kind = "odometry" if m.model == "odometry" else ("averaged" if averaged else "velocity")
    return Driver(
        f"map {m.name}",
        f"maps[{i}]: {cells:,.0f} cells (size {p['size']!r} m / resolution "
        f"{p['resolution']!r} m, theta_resolution {p['theta_resolution']:.4g} rad)",
        cells * _SINGLE_CELL_BYTES[m.model],
        cells * _SINGLE_CELL_S[kind],
        cells,
    )


def _sampler_driver(cfg: RunConfig, i: int, n_steps: int) -> list[Driver]:
    """The draws of a map's own motion-model sampler along the run (``n_sampler`` × N)."""
    m = cfg.maps[i]
    n = int(m.params.get("n_sampler", 0))
    if n == 0:
        return []
    return [Driver(f"map {m.name} sampler", f"maps[{i}].n_sampler = {n:,} × N = {n_steps:,} steps",
                   _SAMPLER_BYTES * n, _SAMPLER_S * n * n_steps)]  # fmt: skip


def _ellipses(cfg: RunConfig, n_steps: int) -> Driver:
    """The ellipses drawn along the path: one per mark, at most one a step."""
    n = min(cfg.n_ellipses, n_steps)
    return Driver("ellipses", f"n_ellipses = {cfg.n_ellipses:,} (at most one a step: {n:,})",
                  _ELLIPSE_BYTES * n, _ELLIPSE_S * n)  # fmt: skip


def estimate(config: RunConfig | Mapping[str, Any]) -> Cost:
    """Peak memory and time of computing and logging a run, from its parameters alone.

    Parameters
    ----------
    config : RunConfig or a run-config mapping (validated with ``RunConfig.from_dict``)

    Returns
    -------
    Cost
        ``mem_bytes`` [bytes] (peak resident set of the process), ``seconds`` [s]
        (order of magnitude) and their ``drivers``: the peak is the drivers' sum, except
        that maps, computed one after the other, add beyond the largest only their
        values (8 B a cell).
    """
    cfg = _config(config)
    tp = cfg.trajectory
    n_steps = trajectories.n_steps(tp["name"], **{k: v for k, v in tp.items() if k != "name"})
    maps_ = [_map(cfg, i, n_steps) for i in range(len(cfg.maps))]
    drivers = [
        Driver("interpreter", "Python, numpy, scipy, mcap", _BASE_BYTES, _BASE_S),
        Driver(
            "steps",
            _trajectory_text(tp, n_steps),
            _STEP_BYTES * (n_steps + 1),
            _STEP_S * (n_steps + 1),
        ),
        *_monte_carlo_driver(cfg, n_steps),
        *maps_,
        *(d for i in range(len(cfg.maps)) for d in _sampler_driver(cfg, i, n_steps)),
        _ellipses(cfg, n_steps),
    ]
    mem = sum(d.mem_bytes for d in drivers)
    if len(maps_) > 1:
        # maps are computed one after the other: beyond the largest, each keeps only its values
        kept = [8.0 * d.cells for d in maps_]
        mem -= sum(d.mem_bytes for d in maps_)
        mem += sum(kept) + max(d.mem_bytes - k for d, k in zip(maps_, kept, strict=True))
    secs = sum(d.seconds for d in drivers)
    return Cost(mem_bytes=int(min(mem, 2**62)), seconds=float(secs), drivers=tuple(drivers))


# --- limits and the guard --------------------------------------------------------------------


def mem_available() -> int | None:
    """Memory available for new processes [bytes] (``MemAvailable`` of /proc/meminfo), or None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (OSError, ValueError, AttributeError):
        return None


_UNITS = {"": 1, "k": 1e3, "m": 1e6, "g": 1e9, "t": 1e12,
          "ki": 1 << 10, "mi": 1 << 20, "gi": 1 << 30, "ti": 1 << 40}  # fmt: skip
_NONE = ("none", "off", "unlimited", "0")


def _parse_memory(text: str) -> tuple[int | None, str]:
    t = text.strip().lower()
    if t in _NONE:
        return None, f"{ENV_MAX_MEMORY}={text}"
    m = re.fullmatch(r"(\d+(?:\.\d*)?)\s*%", t)
    if m:
        if not 0 < float(m.group(1)) <= 100:
            raise ValueError(f"{ENV_MAX_MEMORY} must be a percentage in (0, 100] of the available memory "
                             f"(allowed: e.g. 80%, a size such as 64G, or none), got {text!r}")  # fmt: skip
        avail = mem_available()
        if avail is None:
            return None, "unknown available memory"
        return int(avail * float(m.group(1)) / 100.0), (
            f"{m.group(1)} % of the {fmt_bytes(avail)} available now"
        )
    m = re.fullmatch(r"(\d+(?:\.\d*)?(?:e[-+]?\d+)?)\s*([kmgt]?i?)b?", t)
    if not m or m.group(2) not in _UNITS:
        raise ValueError(
            f"{ENV_MAX_MEMORY} must be a size such as 64G, 500M, 2TiB, a percentage such as 80% "
            f"or none (allowed: bytes with an optional unit), got {text!r}"
        )
    size = float(m.group(1)) * _UNITS[m.group(2)]
    if not 1 <= size <= MAX_MEMORY_LIMIT:  # 1e400 is inf: no int of it
        raise ValueError(
            f"{ENV_MAX_MEMORY} must be a size from 1 B to 1 EiB (allowed: bytes with an "
            f"optional unit such as 64G, a percentage such as 80%, or none), got {text!r}"
        )
    return int(size), f"{ENV_MAX_MEMORY}={text}"


def _parse_seconds(text: str) -> tuple[float | None, str]:
    t = text.strip().lower()
    if t in _NONE:
        return None, f"{ENV_MAX_SECONDS}={text}"
    m = re.fullmatch(r"(\d+(?:\.\d*)?(?:e[-+]?\d+)?)\s*(s|m|min|h|d)?", t)
    if not m:
        raise ValueError(
            f"{ENV_MAX_SECONDS} must be a duration such as 600, 90m, 6h or none "
            f"(allowed: seconds with an optional unit s, m, h, d), got {text!r}"
        )
    scale = {None: 1, "s": 1, "m": 60, "min": 60, "h": 3600, "d": 86400}[m.group(2)]
    secs = float(m.group(1)) * scale
    if not 0 < secs <= MAX_SECONDS_LIMIT:
        raise ValueError(
            f"{ENV_MAX_SECONDS} must be a duration in (0, {MAX_SECONDS_LIMIT:g}] s (allowed: seconds with an "
            f"optional unit s, m, h, d, e.g. 90m, or none), got {text!r}"
        )
    return secs, f"{ENV_MAX_SECONDS}={text}"


def limits(env: Mapping[str, str] | None = None) -> Limits:
    """The guard's limits from the environment (see the module docstring for the syntax)."""
    env = os.environ if env is None else env
    mem_text = env.get(ENV_MAX_MEMORY, "")
    sec_text = env.get(ENV_MAX_SECONDS, "")
    mem, mem_src = _parse_memory(mem_text or DEFAULT_MAX_MEMORY)
    secs, sec_src = _parse_seconds(sec_text or DEFAULT_MAX_SECONDS)
    if not mem_text:
        mem_src = f"default: {mem_src}"
    if not sec_text:
        sec_src = f"default: {sec_src.replace(f'{ENV_MAX_SECONDS}=', '')}"
    return Limits(mem, secs, mem_src, sec_src)


def check(config: RunConfig | Mapping[str, Any], limit: Limits | None = None) -> Cost:
    """Estimate a run and refuse it when the estimate exceeds a limit.

    A run estimated to take longer than :data:`ANNOUNCE_SECONDS` is announced with
    one line on stderr (its estimate and drivers) before it starts.

    Returns
    -------
    Cost — the estimate, when within the limits

    Raises
    ------
    CostError
        One line: the estimate, the limit (and where it comes from, how to change it)
        and the parameters that drive the estimate.
    """
    cfg = _config(config)
    return _guard(f"run {cfg.name!r}", estimate(cfg), limits() if limit is None else limit)


#: a cluster job runs snakemake itself before the run (and its script's own interpreter)
_JOB_OVERHEAD_MB = 400


def job_resources(config: RunConfig | Mapping[str, Any]) -> dict[str, int]:
    """Resources of the pipeline job that simulates a run (Snakemake ``resources:``).

    Returns
    -------
    dict with ``mem_mb`` [MB] (the estimate + 25 % + the job's own Snakemake) and
    ``runtime`` [min] (3 × the estimated time + 5 min, at least 10 min)
    """
    return resources_of(estimate(config))


#: The keys of a run configuration an estimate does not read (:func:`estimate`: the trajectory, Monte Carlo,
#: maps, drive and ellipses decide the cost; the error constants, the seed and the name do not).
_NOT_COSTED = ("name", "seed", "k_r", "k_l", "cov0", "pr")


#: The keys of a localization run's configuration its estimate does not read.
_NOT_COSTED_LOCALIZATION = ("name", "seed")


def _estimate_localization_mapping(config: Mapping[str, Any]) -> Cost:
    from .localization_config import LocalizationConfig  # (the localization runs' chunks only)

    return estimate_localization(LocalizationConfig.from_dict(dict(config)))


def chunk_resources(configs: Sequence[Mapping[str, Any]], kind: str = "run") -> dict[str, int]:
    """Resources of a pipeline job that simulates several runs one after the other (a chunk).

    ``mem_mb`` and ``runtime`` as :func:`job_resources` of one run whose memory is the largest of
    the runs' estimates and whose time is the sum of theirs. Runs that differ only in keys the
    estimate does not read (:data:`_NOT_COSTED`: a sweep over the error constants) are estimated once.
    ``kind`` ``"localization"``: localization runs (:func:`estimate_localization`).
    """
    if not configs:
        raise ValueError("a chunk needs at least one run configuration, got none")
    if kind not in ("run", "localization"):
        raise ValueError(f"a chunk's kind must be 'run' or 'localization', got {kind!r}")
    skip, estimate_of = (_NOT_COSTED, estimate) if kind == "run" else (_NOT_COSTED_LOCALIZATION, _estimate_localization_mapping)
    costs = []
    for config in configs:
        key = kind + json.dumps({k: v for k, v in config.items() if k not in skip}, sort_keys=True, default=repr)
        if key not in _CHUNK_COSTS:
            if len(_CHUNK_COSTS) >= 4096:
                _CHUNK_COSTS.clear()
            _CHUNK_COSTS[key] = estimate_of(config)
        costs.append(_CHUNK_COSTS[key])
    return resources_of(Cost(max(c.mem_bytes for c in costs), math.fsum(c.seconds for c in costs), ()))


#: :func:`estimate` of each run configuration seen by :func:`chunk_resources`, by the JSON text of its
#: costed keys (a sweep's chunks repeat a few trajectories over and over).
_CHUNK_COSTS: dict[str, Cost] = {}


def resources_of(cost: Cost) -> dict[str, int]:
    """A cluster job's ``resources:`` for an estimate: ``mem_mb`` [MB] (the estimate + 25 % + the
    job's own Snakemake) and ``runtime`` [min] (3 × the estimated time + 5 min, at least 10 min).
    Every computing rule (runs, localization runs, studies) asks this of its own estimate."""
    mem_mb = math.ceil(cost.mem_bytes * 1.25 / 1e6) + _JOB_OVERHEAD_MB
    runtime = max(10, math.ceil(3.0 * cost.seconds / 60.0) + 5)
    return {"mem_mb": int(mem_mb), "runtime": int(runtime)}


# --- localization runs -----------------------------------------------------------------------
#
# A localization run (``pose_uncertainty.experiments.localization.execute_localization``) runs
# each configured filter on R simulated runs of K = N + 1 steps, one after the other; a filter's
# working memory is freed between runs. Coefficients measured on this project's 2-core machine
# (2026-12-02; the room of ``config/worlds/room.yaml``, 40 steps, a fresh process's peak RSS):
#
# ==============  ===========================================  =====================================
# filter          memory                                       time per step and run
# ==============  ===========================================  =====================================
# EKF             (steps only)                                 4 ms
# histogram       40 B × cells (+ 8 B × nx·ny per logged grid)  20 ms + 0.6 µs × cells (nx·ny·ntheta)
# particle        150 B × n                                    1 ms + 1.5 µs × n
# ==============  ===========================================  =====================================
#
# (histogram: 0.10 s/step at 72,000 cells, 1.27 s at 2.3 M, 38 B a cell; particle: 0.14 s/step at
# n = 100,000, 90 B a particle.) Simulating a step costs 1 ms; steps' own records 2 kB and 200 µs
# (as a dead-reckoning run's).
_LOC_SIM_S = 1e-3
_EKF_STEP_S = 4e-3
_HIST_CELL_BYTES, _HIST_STEP_S, _HIST_CELL_S = 40.0, 20e-3, 0.6e-6
_PART_BYTES, _PART_STEP_S, _PART_S = 150.0, 1e-3, 1.5e-6


def estimate_localization(config: Any) -> Cost:
    """Peak memory and time of a localization run, from its parameters alone.

    Parameters
    ----------
    config : LocalizationConfig (:mod:`pose_uncertainty.experiments.localization`, validated)

    Returns
    -------
    Cost
        As :func:`estimate`: ``mem_bytes`` [bytes], ``seconds`` [s] (order of magnitude) and the
        drivers: the interpreter, the steps (R runs × K steps simulated and recorded), and one
        driver per filter (``filter histogram``: cells = nx·ny·ntheta of its grid; ``filter
        particle``: n particles). Filters run one after the other: the peak holds the largest
        filter's memory, not their sum.
    """
    from ..localization.histogram import pose_grid_for  # (a localization run imports it anyway)

    traj = config.build_trajectory()
    k_steps = int(traj.n_steps) + 1
    repeat = int(config.repeat)
    runs_text = f"repeat {repeat} × K = {k_steps:,} steps"
    drivers = [
        Driver("interpreter", "Python, numpy, scipy, mcap", _BASE_BYTES, _BASE_S),
        Driver("steps", f"{runs_text} (trajectory {config.trajectory['name']}, dt {config.trajectory.get('dt', '')})",
               _STEP_BYTES * k_steps, (_STEP_S + _LOC_SIM_S * repeat) * k_steps),
    ]  # fmt: skip
    filters: list[Driver] = []
    f = config.filters
    if "ekf" in f:
        filters.append(Driver("filter ekf", runs_text, 0.0, _EKF_STEP_S * repeat * k_steps))
    if "histogram" in f:
        h = f["histogram"]
        # the filter's own grid: a Grid holds its counts, not its cells (nothing of their size is made)
        g = pose_grid_for(config.build_world(), h["resolution"], h["ntheta"])
        nx, ny, nt = g.nx, g.ny, g.ntheta
        cells = float(nx) * ny * nt
        every = int(config.log.get("grid_every", 0) or 0)
        logged = 8.0 * nx * ny * (k_steps // every + 2) if every > 0 else 0.0
        res = "the world's cells" if h["resolution"] is None else f"resolution {h['resolution']:g}"
        filters.append(Driver(
            "filter histogram",
            f"filters.histogram {res}, ntheta {nt}: {nx:,} × {ny:,} × {nt} = {cells:,.0f} cells; {runs_text}",
            _HIST_CELL_BYTES * cells + logged, (_HIST_STEP_S + _HIST_CELL_S * cells) * repeat * k_steps, cells,
        ))  # fmt: skip
    if "particle" in f:
        n = float(f["particle"]["n_particles"])
        filters.append(Driver("filter particle", f"filters.particle.n_particles {n:,.0f}; {runs_text}",
                              _PART_BYTES * n, (_PART_STEP_S + _PART_S * n) * repeat * k_steps))  # fmt: skip
    drivers += filters
    mem = sum(d.mem_bytes for d in drivers[:2]) + max((d.mem_bytes for d in filters), default=0.0)
    secs = sum(d.seconds for d in drivers)
    return Cost(mem_bytes=int(min(mem, 2**62)), seconds=float(min(secs, 1e30)), drivers=tuple(drivers))


def _guard(label: str, cost: Cost, lim: Limits) -> Cost:
    """Refuse ``cost`` over a limit of ``lim`` (:class:`CostError`, one line: the estimate, the limit and
    where it comes from, the drivers), or announce it on stderr when it is long; return it."""
    for what, over, size, env, example in (
        ("mem_bytes", f"need about {fmt_bytes(cost.mem_bytes)} of memory", fmt_bytes, ENV_MAX_MEMORY, "=64G"),
        ("seconds", f"take about {fmt_seconds(cost.seconds)}", fmt_seconds, ENV_MAX_SECONDS, "=6h"),
    ):
        limit, source = (lim.mem_bytes, lim.mem_source) if what == "mem_bytes" else (lim.seconds, lim.seconds_source)
        if limit is not None and getattr(cost, what) > limit:
            drivers = "; ".join(f"{d.name} {size(getattr(d, what))} ({d.params})" for d in cost.top(what))
            raise CostError(
                f"{label} would {over}, over the limit of {size(limit)} ({source}; set {env}, e.g. "
                f"{example} or =none, to change it); it is driven by {drivers}"
            )
    if cost.seconds > ANNOUNCE_SECONDS:
        print(f"{label}: estimated {cost.summary()}", file=sys.stderr, flush=True)
    return cost


def check_localization(config: Any, limit: Limits | None = None) -> Cost:
    """The guard of :func:`check` for a localization run (:func:`estimate_localization`).

    Refuses a run over a limit with one line (the estimate, the limit, the drivers); announces
    a run estimated over :data:`ANNOUNCE_SECONDS` on stderr before it starts.

    Returns
    -------
    Cost — the estimate, when within the limits

    Raises
    ------
    CostError
    """
    return _guard(f"localization run {config.name!r}", estimate_localization(config), limits() if limit is None else limit)


# --- studies ---------------------------------------------------------------------------------
#
# A study (``pose_uncertainty.analysis.studies``) is dominated by its sampling: n poses carried
# over N steps, for each of E evaluations (growth-law points, checkpoints, cases). Only that is
# modelled, with the Monte Carlo coefficients above (140 B a pose, 100 ns a pose-step): a bound
# that refuses a study of absurd size with the same one line as a run, not a calibrated estimate.
_STUDY_DEFAULT_STEPS = 1000


def _study_steps(params: Mapping[str, Any]) -> int:
    """The steps N a study's parameters imply (its trajectory, ``duration / dt``, ``n_steps``, ``dts``)."""
    tp = params.get("trajectory")
    if isinstance(tp, Mapping) and "name" in tp:
        return trajectories.n_steps(str(tp["name"]), **{k: v for k, v in tp.items() if k != "name"})
    cases = params.get("cases")
    if isinstance(cases, list | tuple) and cases:
        return max(_study_steps({**params, "cases": None, **dict(c)}) for c in cases if isinstance(c, Mapping))
    if "n_steps" in params:
        v = params["n_steps"]
        return int(sum(v)) if isinstance(v, list | tuple) else int(v)
    duration = float(params.get("duration", params.get("length", 0.0)) or 0.0)
    dts = params.get("dts", params.get("dt"))
    dts = dts if isinstance(dts, list | tuple) else [dts]
    if duration > 0 and all(isinstance(d, int | float) and d > 0 for d in dts):
        return int(sum(math.ceil(duration / float(d)) for d in dts))
    return _STUDY_DEFAULT_STEPS


def estimate_study(name: str, kind: str, params: Mapping[str, Any]) -> Cost:
    """A bound on a study's memory and time from its sampling size (see the comment above).

    Parameters
    ----------
    name : the study's name; kind : its kind; params : every parameter (``study_params``)

    Returns
    -------
    Cost — drivers ``interpreter`` and ``sampling`` (n poses × N steps × E evaluations)
    """
    n = float(params.get("n", params.get("n_particles", 1)) or 1)
    steps = _study_steps(params)
    evals = float(params.get("n_points", 0) or 0) + float(params.get("n_checkpoints", 0) or 0)
    cases = params.get("cases")
    evals = max(1.0, evals, float(len(cases)) if isinstance(cases, list | tuple) else 1.0)
    which = "n" if "n" in params else "n_particles"
    drivers = (
        Driver("interpreter", "Python, numpy, scipy", _BASE_BYTES, _BASE_S),
        Driver("sampling", f"study {name!r} ({kind}): {which} {n:,.0f} × N = {steps:,} steps × {evals:g} evaluation(s)",
               _PARTICLE_BYTES * n, _MC_S["per_step"] * n * steps * evals),
    )  # fmt: skip
    return Cost(mem_bytes=int(min(sum(d.mem_bytes for d in drivers), 2**62)),
                seconds=float(min(sum(d.seconds for d in drivers), 1e30)), drivers=drivers)  # fmt: skip


def check_study(name: str, kind: str, params: Mapping[str, Any], limit: Limits | None = None) -> Cost:
    """The guard of :func:`check` for a study (:func:`estimate_study`): one line over a limit.

    Raises
    ------
    CostError
    """
    return _guard(f"study {name!r}", estimate_study(name, kind, params), limits() if limit is None else limit)
