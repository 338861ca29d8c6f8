"""The measures of a localization run, with their units and definitions (a sibling of :mod:`.measures`).

A localization run (:mod:`pose_uncertainty.experiments.localization`) simulates ``R`` independent
runs of one configuration (the same path, world and sensors; independent noise) and runs
each configured filter — ``ekf``, ``histogram``, ``particle`` — on the same data. The
measures below are computed once there, from the filters' results against the true path
(:mod:`pose_uncertainty.localization.evaluation`), logged with the unit and definition of
:func:`pose_uncertainty.analysis.measures.describe` (which consults :data:`DEFINITIONS`),
and read back by the tables, the figures and the report.

Names (``<f>`` is the filter):

* ``loc_*`` — the run: path, landmarks seen, dead reckoning (the odometry alone) against the
  truth, the NEES band of ``R`` runs (:func:`run_measures`);
* ``loc_<f>_*`` — one filter over the ``R`` runs: position and heading errors, NEES and its
  band, coverage of its 39.35 / 86.47 / 98.89 % regions, success and time to converge,
  association failures, effective sample size, lost mass (:func:`filter_measures`).

Per-step series (arrays over the steps ``k = 0 … N`` of the first run, plus the NEES averaged
over the ``R`` runs) come with them, for the figures: :data:`SERIES_UNITS`.

Conventions: errors are estimate − truth, the heading wrapped to (−π, π]; "every step" means
every step ``k = 0 … N`` of every one of the ``R`` runs; a quantity a filter does not have
(the ESS of a Kalman filter) is not logged for it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..core.kinematics import wrap_angle
from ..core.stats import COVERAGE_LEVELS, wilson_interval
from ..localization.evaluation import convergence, nees, nees_band, pose_errors
from ..localization.result import FilterResult
from ..localization.simulate import SimulatedRun

__all__ = [
    "DEFINITIONS",
    "FILTERS",
    "NEES_CONFIDENCE",
    "SERIES_UNITS",
    "filter_measures",
    "run_measures",
]

#: The filters of a localization run, in the order they are run, logged and drawn.
FILTERS: tuple[str, ...] = ("ekf", "histogram", "particle")
#: Confidence of the two-sided χ² band of the averaged NEES.
NEES_CONFIDENCE: float = 0.95

_F = "(ekf|histogram|particle)"
_LEVELS = "(1s|2s|3s)"
_EVERY = "every step of the R runs"

# (pattern, unit, definition); ``{1}``… are the pattern's groups (see analysis.measures.describe).
DEFINITIONS: tuple[tuple[str, str, str], ...] = (
    (r"loc_path_length", "m", "length of the commanded path, Σ|Δs|"),
    (r"loc_duration", "s", "duration of one run, N·Δt"),
    (r"loc_repeat", "1", "number R of simulated runs (one configuration, independent noise) the measures cover"),
    (r"loc_landmarks", "1", "number of landmarks in the world"),
    (r"loc_landmarks_seen", "1", "mean number of landmarks measured per observation step of the landmark sensor"),
    (r"loc_dead_reckoning_rms_position_error", "m",
     f"RMS over {_EVERY} of the distance of the dead-reckoned odometry pose from the true pose"),
    (r"loc_dead_reckoning_final_position_error", "m",
     "mean over the R runs of the dead-reckoning position error at the last step"),
    (r"loc_nees_band_(low|high)", "1",
     ("{1} end of the two-sided 95 % band of the NEES averaged over the R runs at one step, "
      "χ²(3R) quantile / R (a consistent filter's averaged NEES lies inside at 95 % of the steps)")),
    (rf"loc_{_F}_rms_position_error", "m",
     f"RMS over {_EVERY} of the {{1}} filter's position error ‖(x̂, ŷ) − (x, y)‖"),
    (rf"loc_{_F}_rms_heading_error", "rad", f"RMS over {_EVERY} of the {{1}} filter's wrapped heading error"),
    (rf"loc_{_F}_max_position_error", "m", f"largest position error of the {{1}} filter over {_EVERY}"),
    (rf"loc_{_F}_final_position_error", "m", "mean over the R runs of the {1} filter's position error at the last step"),
    (rf"loc_{_F}_final_heading_error", "rad",
     "mean over the R runs of the {1} filter's absolute heading error at the last step"),
    (rf"loc_{_F}_nees_mean", "1",
     f"mean over {_EVERY} of the {{1}} filter's NEES εᵀΣ⁻¹ε (ε = truth − estimate, 3 if consistent)"),
    (rf"loc_{_F}_nees_median", "1",
     (f"median over {_EVERY} of the {{1}} filter's NEES (robust to the rare steps where a collapsed sample "
      "covariance makes the NEES huge)")),
    (rf"loc_{_F}_nees_in_band", "1",
     "fraction of the steps whose NEES averaged over the R runs lies in the 95 % band loc_nees_band_low…high"),
    (rf"loc_{_F}_coverage_{_LEVELS}", "1",
     (f"fraction of {_EVERY} with the true position inside the {{1}} filter's {{2}} region (39.35 / 86.47 / "
      "98.89 % for 1s / 2s / 3s: its Pr-ellipse for the EKF, the highest-density region of its (x, y) cell "
      "masses for the grid and particle filters)")),
    (rf"loc_{_F}_success_rate", "1",
     ("fraction of the R runs the {1} filter ends localized: position and heading errors at the last step "
      "within success.pos_tol and success.head_tol")),
    (rf"loc_{_F}_success_(low|high)", "1", "{2} end of the 95 % Wilson interval of loc_{1}_success_rate"),
    (rf"loc_{_F}_time_to_converge", "s",
     ("median over the successful runs of the time from the scenario's start (or the kidnapping) after which "
      "the {1} filter's errors stay within the success tolerances (nan: no successful run)")),
    (rf"loc_{_F}_measurements", "1", "measurements the {1} filter corrected with, summed over the R runs"),
    (rf"loc_{_F}_association_failures", "1",
     ("measurements the {1} filter attributed to another landmark than the one seen, summed over the R runs "
      "(maximum-likelihood association; the particle filter's count is the weighted mean over its particles)")),
    (rf"loc_{_F}_association_failure_rate", "1", "loc_{1}_association_failures / loc_{1}_measurements"),
    (r"loc_particle_ess_mean", "1", f"mean effective sample size 1/Σw² of the particle filter over {_EVERY}"),
    (r"loc_particle_ess_min", "1", f"smallest effective sample size of the particle filter over {_EVERY}"),
    (r"loc_particle_resampling_rate", "1", "fraction of the particle filter's corrections followed by resampling"),
    (r"loc_particle_injected", "1", "random particles injected per run (mean over the R runs)"),
    (r"loc_histogram_lost_mass", "1",
     "probability mass the histogram filter's predictions moved off its grid, summed over a run (mean over R)"),
    (r"loc_histogram_masked_mass", "1",
     "probability mass the histogram filter's predictions moved into occupied cells, summed over a run (mean over R)"),
    (r"loc_histogram_cells", "1", "cells of the histogram filter's (x, y, θ) grid"),
)

#: Unit of every per-step series (``<f>/<name>`` for a filter's, ``truth/<name>`` for the run's).
SERIES_UNITS: dict[str, str] = {
    "error_x": "m", "error_y": "m", "error_theta": "rad", "sigma_x": "m", "sigma_y": "m", "sigma_theta": "rad",
    "position_error": "m", "heading_error": "rad", "nees": "1", "nees_avg": "1",
    "in_region_1s": "1", "in_region_2s": "1", "in_region_3s": "1",
    "ess": "1", "resampled": "1", "injected": "1", "log_evidence": "nat", "n_measurements": "1",
    "wrong_associations": "1", "lost_mass": "1", "masked_mass": "1", "nis": "1",
    "dead_reckoning_position_error": "m",
}  # fmt: skip

Array = NDArray[np.float64]


def _rms(values: Sequence[Array]) -> float:
    v = np.concatenate([np.asarray(a, dtype=np.float64).ravel() for a in values])
    return float(np.sqrt(np.mean(v * v)))


def run_measures(runs: Sequence[SimulatedRun], n_landmarks: int) -> tuple[dict[str, float], dict[str, Array]]:
    """The run's own measures (``loc_*``) and the dead-reckoning error series of the first run.

    Parameters
    ----------
    runs : the ``R`` simulated runs (same path, independent noise)
    n_landmarks : int — landmarks in the world

    Returns
    -------
    metrics : dict name → value; series : ``{"dead_reckoning_position_error": (N+1,)}``
    """
    first = runs[0]
    R = len(runs)
    dr = [pose_errors(r.odometry, r.true_poses)[0] for r in runs]
    lm_steps = np.concatenate([r.landmark_valid.any(axis=1) for r in runs])
    seen = np.concatenate([r.landmark_valid.sum(axis=1) for r in runs])
    low, high = nees_band(3, R, NEES_CONFIDENCE)
    ds = 0.5 * (first.ds_r + first.ds_l)
    metrics = {
        "loc_path_length": float(np.abs(ds).sum()),
        "loc_duration": float(first.times[-1] - first.times[0]),
        "loc_repeat": float(R),
        "loc_landmarks": float(n_landmarks),
        "loc_landmarks_seen": float(seen[lm_steps].mean()) if lm_steps.any() else 0.0,
        "loc_dead_reckoning_rms_position_error": _rms(dr),
        "loc_dead_reckoning_final_position_error": float(np.mean([e[-1] for e in dr])),
        "loc_nees_band_low": low,
        "loc_nees_band_high": high,
    }
    return metrics, {"dead_reckoning_position_error": dr[0]}


def filter_measures(
    name: str,
    results: Sequence[FilterResult],
    runs: Sequence[SimulatedRun],
    *,
    pos_tol: float,
    head_tol: float,
    from_step: int = 0,
    cells: int | None = None,
) -> tuple[dict[str, float], dict[str, Array]]:
    """One filter's measures over the ``R`` runs (``loc_<name>_*``) and its per-step series.

    Parameters
    ----------
    name : one of :data:`FILTERS`
    results : the filter's result on each run (index as ``runs``)
    runs : the simulated runs
    pos_tol : float [m]; head_tol : float [rad] — the success tolerances
    from_step : int — step the convergence is counted from (the kidnapping; 0 otherwise)
    cells : int, optional — cells of the histogram filter's grid

    Returns
    -------
    metrics : dict name → value (see :data:`DEFINITIONS`)
    series : dict name → array (N+1,) — the first run's errors, σ's, NEES, region flags and
        diagnostics, and ``nees_avg``, the NEES averaged over the runs at each step
    """
    R = len(results)
    pe, he, ne = [], [], []
    for res, run in zip(results, runs, strict=True):
        p, h = pose_errors(res.mean, run.true_poses)
        pe.append(p)
        he.append(h)
        ne.append(nees(res.mean, res.cov, run.true_poses))
    nees_all = np.stack(ne)  # (R, K)
    nees_avg = nees_all.mean(axis=0)
    low, high = nees_band(3, R, NEES_CONFIDENCE)
    finite = np.isfinite(nees_avg)
    inside = np.concatenate([r.in_region for r in results]).mean(axis=0)
    conv = [convergence(run.times[from_step:], p[from_step:], h[from_step:], pos_tol, head_tol)
            for run, p, h in zip(runs, pe, he, strict=True)]  # fmt: skip
    n_ok = sum(ok for ok, _ in conv)
    lo, hi = wilson_interval(n_ok, R)
    t_ok = [t for ok, t in conv if ok]
    m: dict[str, float] = {
        "rms_position_error": _rms(pe),
        "rms_heading_error": _rms(he),
        "max_position_error": float(max(float(p.max()) for p in pe)),
        "final_position_error": float(np.mean([p[-1] for p in pe])),
        "final_heading_error": float(np.mean([h[-1] for h in he])),
        "nees_mean": float(np.nanmean(nees_all)) if np.isfinite(nees_all).any() else math.nan,
        "nees_median": float(np.nanmedian(nees_all)) if np.isfinite(nees_all).any() else math.nan,
        "nees_in_band": float(np.mean((nees_avg[finite] >= low) & (nees_avg[finite] <= high))) if finite.any() else math.nan,
        "success_rate": n_ok / R, "success_low": lo, "success_high": hi,
        "time_to_converge": float(np.median(t_ok)) if t_ok else math.nan,
    }  # fmt: skip
    for key, c in zip(COVERAGE_LEVELS, inside, strict=True):
        m[f"coverage_{key}"] = float(c)
    m.update(_diagnostic_measures(name, results, cells))
    first = results[0]
    err = first.mean - runs[0].true_poses
    err[:, 2] = wrap_angle(err[:, 2])
    sd = np.sqrt(np.maximum(np.diagonal(first.cov, axis1=1, axis2=2), 0.0))
    series: dict[str, Array] = {
        "error_x": err[:, 0], "error_y": err[:, 1], "error_theta": err[:, 2],
        "sigma_x": sd[:, 0], "sigma_y": sd[:, 1], "sigma_theta": sd[:, 2],
        "position_error": pe[0], "heading_error": he[0], "nees": ne[0], "nees_avg": nees_avg,
    }  # fmt: skip
    for key, col in zip(COVERAGE_LEVELS, first.in_region.T, strict=True):
        series[f"in_region_{key}"] = col.astype(np.float64)
    for key, values in sorted(first.diagnostics.items()):
        series[key] = np.asarray(values, dtype=np.float64)
    return {f"loc_{name}_{k}": float(v) for k, v in m.items()}, series


def _diagnostic_measures(name: str, results: Sequence[FilterResult], cells: int | None) -> dict[str, float]:
    """Association failures (every filter), ESS and resampling (particle), lost mass (histogram)."""
    diag = {k: np.stack([r.diagnostics[k] for r in results]) for k in results[0].diagnostics}
    out: dict[str, float] = {}
    n_meas = float(diag["n_measurements"].sum()) if "n_measurements" in diag else 0.0
    out["measurements"] = n_meas
    if "wrong_associations" in diag:
        wrong = float(diag["wrong_associations"].sum())
        out["association_failures"] = wrong
        out["association_failure_rate"] = wrong / n_meas if n_meas > 0 else math.nan
    if name == "particle":
        corrections = diag["n_measurements"] > 0
        out["ess_mean"] = float(diag["ess"].mean())
        out["ess_min"] = float(diag["ess"].min())
        out["resampling_rate"] = float(diag["resampled"][corrections].mean()) if corrections.any() else 0.0
        out["injected"] = float(diag["injected"].sum(axis=1).mean())
    if name == "histogram":
        out["lost_mass"] = float(diag["lost_mass"].sum(axis=1).mean())
        out["masked_mass"] = float(diag["masked_mass"].sum(axis=1).mean())
        if cells is not None:
            out["cells"] = float(cells)
    return out
