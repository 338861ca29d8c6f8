"""What every filter run returns, how it starts, and the measurements it is given.

:class:`FilterResult` holds, per step ``k = 0 … N`` (after the correction of step k):
the estimate (mean pose), its covariance (the EKF's; the sample or grid covariance
for the others), whether the truth lies in the filter's 39/86/98.89 % regions, the
compute time of the step (measured around the kernels, outside them) and per-step
diagnostics; plus the full state (particles, grid marginals) at requested steps.
A filter run also takes an ``on_step(k, state)`` callback with the full state of
every step, for a logger that streams it.

:class:`Start` is the scenario's initial belief: ``"tracking"`` and ``"kidnapped"``
start from a known pose with a small Gaussian uncertainty; ``"global"`` from
the uniform distribution over the free space (for the EKF: its moment-matched
Gaussian over the world's bounds, which is the best a Gaussian can say).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.stats import COVERAGE_LEVELS
from ..core.validation import check_choice, check_finite, check_nonnegative
from .evaluation import convergence, nees, pose_errors
from .sensors import RangeBearingSensor, associate
from .simulate import SimulatedRun
from .world import World

__all__ = [
    "ASSOCIATIONS",
    "SCENARIOS",
    "FilterResult",
    "Start",
    "StepCallback",
    "StepRecorder",
    "evaluate",
    "landmark_measurements",
]

SCENARIOS: tuple[str, ...] = ("tracking", "global", "kidnapped")
ASSOCIATIONS: tuple[str, ...] = ("known", "ml")

Array = NDArray[np.float64]
#: ``on_step(k, state)``: ``state`` holds ``mean``, ``cov`` and the filter's full state
#: (``particles`` and ``weights``, or ``belief``), valid only during the call.
StepCallback = Callable[[int, dict[str, Any]], None]


@dataclass(frozen=True)
class Start:
    """Initial belief of a scenario.

    Attributes
    ----------
    scenario : {"tracking", "global", "kidnapped"}
    pose : tuple (x, y, θ) [m, m, rad] — the known start (tracking, kidnapped)
    std : tuple (σ_x, σ_y, σ_θ) [m, m, rad], ≥ 0 — its uncertainty
    """

    scenario: str = "tracking"
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    std: tuple[float, float, float] = (0.02, 0.02, 0.01)

    def __post_init__(self) -> None:
        check_choice("scenario", self.scenario, SCENARIOS)
        p = check_finite("start.pose", self.pose)
        s = check_nonnegative("start.std", self.std)
        if p.shape != (3,) or s.shape != (3,):
            raise ValueError(f"start.pose and start.std must have 3 values (x, y, θ), got {p.shape} and {s.shape}")
        object.__setattr__(self, "pose", tuple(float(v) for v in p))
        object.__setattr__(self, "std", tuple(float(v) for v in s))

    @property
    def is_global(self) -> bool:
        """Whether the start is unknown (uniform over the free space)."""
        return self.scenario == "global"

    def gaussian(self, world: World) -> tuple[Array, Array]:
        """The EKF's initial ``(mean (3,), cov (3, 3))``: the known start, or the moments of the uniform."""
        if not self.is_global:
            return np.array(self.pose), np.diag(np.maximum(np.square(self.std), 1e-12))
        x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
        mean = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
        return mean, np.diag([(x1 - x0) ** 2 / 12, (y1 - y0) ** 2 / 12, math.pi**2 / 3])


@dataclass(frozen=True, eq=False)
class FilterResult:
    """A filter's run. Index ``k = 0 … N`` (K = N+1) as the :class:`SimulatedRun`.

    Attributes
    ----------
    filter : str — "ekf", "histogram" or "particle"
    times : ndarray, shape (K,) [s]
    mean : ndarray, shape (K, 3) [m, m, rad] — θ wrapped to (−π, π]
    cov : ndarray, shape (K, 3, 3) [m², m·rad, rad²]
    in_region : ndarray of bool, shape (K, 3) — truth inside the regions of
        :data:`~pose_uncertainty.core.stats.COVERAGE_LEVELS` (columns in that order)
    step_seconds : ndarray, shape (K,) [s] — wall time of prediction + correction (+ resampling)
    diagnostics : dict of ndarray, shape (K,) — filter-specific (``ess``, ``resampled``,
        ``lost_mass``, ``nis``, ``n_measurements``, ``wrong_associations`` …)
    snapshots : dict int → dict of ndarray — full state at the requested steps
        (``particles`` (n, 3) and ``weights`` (n,); or ``belief_xy`` (nx, ny))
    """

    filter: str
    times: Array
    mean: Array
    cov: Array
    in_region: NDArray[np.bool_]
    step_seconds: Array
    diagnostics: dict[str, Array] = field(default_factory=dict)
    snapshots: dict[int, dict[str, Array]] = field(default_factory=dict)


class StepRecorder:
    """Collects a filter's per-step arrays while it runs (the thin stateful part of a runner)."""

    def __init__(self, name: str, run: SimulatedRun, keep: Sequence[int] = (), on_step: StepCallback | None = None):
        K = run.n_steps + 1
        self.name, self.run, self.keep, self.on_step = name, run, {int(k) for k in keep}, on_step
        self.mean = np.zeros((K, 3))
        self.cov = np.zeros((K, 3, 3))
        self.in_region = np.zeros((K, len(COVERAGE_LEVELS)), dtype=bool)
        self.seconds = np.zeros(K)
        self.diag: dict[str, Array] = {}
        self.snapshots: dict[int, dict[str, Array]] = {}
        self._t0 = 0.0

    def tic(self) -> None:
        """Start the clock of a step."""
        self._t0 = time.perf_counter()

    def toc(self, k: int) -> None:
        """Stop the clock of step ``k``."""
        self.seconds[k] += time.perf_counter() - self._t0

    def record(
        self, k: int, mean: Array, cov: Array, in_region: NDArray[np.bool_] | None, state: dict[str, Any],
        snapshot: Sequence[str] | None = None, **diag: float,
    ) -> None:  # fmt: skip
        """Store step ``k``; keep a copy of ``state`` (its keys ``snapshot``, default all) if asked; call ``on_step``.

        ``in_region`` None: the flags of every step are given to :meth:`result` instead (computed
        after the loop, over all steps at once).
        """
        self.mean[k], self.cov[k] = mean, cov
        if in_region is not None:
            self.in_region[k] = in_region
        for key, value in diag.items():
            column = self.diag.get(key)
            if column is None:
                column = self.diag[key] = np.zeros(self.mean.shape[0])
            column[k] = value
        if k in self.keep:
            keys = state.keys() if snapshot is None else snapshot
            self.snapshots[k] = {key: np.array(state[key]) for key in keys}
        if self.on_step is not None:
            self.on_step(k, {"mean": mean, "cov": cov, **state})

    def result(self, in_region: NDArray[np.bool_] | None = None) -> FilterResult:
        """The finished :class:`FilterResult`; ``in_region`` (K, 3): the flags of every step, if not recorded per step."""
        if in_region is not None:
            self.in_region[...] = in_region
        return FilterResult(self.name, self.run.times, self.mean, self.cov, self.in_region,
                            self.seconds, self.diag, self.snapshots)  # fmt: skip


def landmark_measurements(
    run: SimulatedRun, world: World, sensor: RangeBearingSensor, k: int,
    association: str, mean: Array, cov: Array,
) -> tuple[Array, Array, int]:  # fmt: skip
    """The landmark measurements of step ``k`` and the landmark each is attributed to.

    ``"known"``: the true correspondences; ``"ml"``: maximum likelihood under the
    filter's predicted ``(mean, cov)`` (:func:`~pose_uncertainty.localization.sensors.associate`).

    Returns
    -------
    z : ndarray, shape (m, 2); landmarks : ndarray, shape (m, 2) [m]
    wrong : int — measurements attributed to another landmark than the one seen
    """
    valid = run.landmark_valid[k]
    z = run.landmark_z[k][valid]
    if association == "known" or z.shape[0] == 0:
        return z, world.landmarks[valid], 0
    idx, _ = associate(z, mean, cov, world.landmarks, sensor)
    return z, world.landmarks[idx], int(np.sum(idx != np.flatnonzero(valid)))


def evaluate(
    result: FilterResult, run: SimulatedRun, pos_tol: float = 0.5, head_tol: float = 0.25,
    from_step: int = 0,
) -> dict[str, Any]:  # fmt: skip
    """Measures of a filter run against the true path (see :mod:`.measures`).

    Returns a dict: ``position_error``, ``heading_error``, ``nees`` (arrays (K,));
    ``coverage`` (level name → fraction of steps ≥ ``from_step`` with the truth inside);
    ``success``, ``time_to_converge`` [s] (tolerances ``pos_tol`` [m], ``head_tol`` [rad],
    counted from ``from_step``, e.g. the kidnapping); ``mean_step_seconds``.
    """
    pe, he = pose_errors(result.mean, run.true_poses)
    ok, t_conv = convergence(run.times[from_step:], pe[from_step:], he[from_step:], pos_tol, head_tol)
    cover = result.in_region[from_step:].mean(axis=0)
    return {
        "position_error": pe,
        "heading_error": he,
        "nees": nees(result.mean, result.cov, run.true_poses),
        "coverage": {name: float(c) for name, c in zip(COVERAGE_LEVELS, cover, strict=True)},
        "success": ok,
        "time_to_converge": t_conv,
        "mean_step_seconds": float(result.step_seconds.mean()),
    }


def check_keep(keep: ArrayLike, n_steps: int) -> list[int]:
    """Validate snapshot steps: integers in [0, N]."""
    out = [int(k) for k in np.asarray(keep, dtype=np.int64).ravel()]
    if any(k < 0 or k > n_steps for k in out):
        raise ValueError(f"keep must hold steps in [0, {n_steps}], got {out}")
    return out
