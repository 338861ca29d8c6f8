"""How well a filter localizes: errors against the true path, NEES, region coverage, convergence.

Per step ``k`` (arrays over ``k = 0 … N``):

* position error ``‖(x̂, ŷ) − (x, y)‖`` [m] and heading error ``|wrap(θ̂ − θ)|`` [rad];
* NEES ``εᵀ Σ⁻¹ ε`` with ``ε = (x − x̂, y − ŷ, wrap(θ − θ̂))`` — χ²(3) for a consistent
  Gaussian filter; the average over ``R`` independent runs times ``R`` is χ²(3R), so
  its two-sided band at confidence ``1 − a`` is :func:`nees_band`;
* whether the truth is inside each filter's regions of probability
  :data:`~pose_uncertainty.core.stats.COVERAGE_LEVELS` (39.35 / 86.47 / 98.89 %): for a
  Gaussian its Pr-ellipse of the ``(x, y)`` block (:func:`gaussian_region_flags`), for a
  grid or particle filter the highest-density region of its ``(x, y)`` cell masses
  (:func:`mass_region_flags`; particles are histogrammed on cells first). Averaged over
  steps and runs these flags are the coverage, to compare with the nominal levels;
* convergence (global localization): the first time from which the errors stay below
  tolerances until the end (:func:`convergence`), and success = the final errors are.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import wrap_angle
from ..core.stats import COVERAGE_LEVELS, chi2_ppf, hdr_levels, hdr_region, pr_to_k
from ..core.validation import check_finite, check_last_axis, check_positive, check_positive_int

__all__ = [
    "convergence",
    "gaussian_region_flags",
    "mass_region_flags",
    "nees",
    "nees_band",
    "pose_errors",
    "region_flags_of_mass",
    "weighted_mean_cov",
]

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
_PRS = tuple(COVERAGE_LEVELS.values())
_PR_ARRAY = np.array(_PRS)
_K_ARRAY = pr_to_k(_PR_ARRAY)  # the levels' squared Mahalanobis radii, computed once


def pose_errors(mean: ArrayLike, truth: ArrayLike) -> tuple[Array, Array]:
    """Position error [m] and absolute wrapped heading error [rad], each shape (...)."""
    m = check_last_axis("mean", mean, 3)
    t = check_last_axis("truth", truth, 3)
    return np.hypot(m[..., 0] - t[..., 0], m[..., 1] - t[..., 1]), np.abs(wrap_angle(m[..., 2] - t[..., 2]))


def nees(mean: ArrayLike, cov: ArrayLike, truth: ArrayLike) -> Array:
    """``εᵀ Σ⁻¹ ε`` per step (heading wrapped), shape (...); NaN where Σ is not positive definite."""
    m = check_last_axis("mean", mean, 3)
    S = check_finite("cov", cov)
    e = check_last_axis("truth", truth, 3) - m
    e[..., 2] = wrap_angle(e[..., 2])
    out = np.full(e.shape[:-1], np.nan)
    ev = np.linalg.eigvalsh(S)
    ok = ev[..., 0] > 1e-15 * np.maximum(ev[..., -1], 1e-300)
    if np.any(ok):
        out[ok] = (e[ok][:, None, :] @ np.linalg.solve(S[ok], e[ok][:, :, None]))[:, 0, 0]
    return out


def nees_band(dof: int, n_runs: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided band of the NEES averaged over ``n_runs`` independent runs.

    ``n_runs · mean NEES ~ χ²(dof · n_runs)`` for a consistent filter, so the band is
    ``[χ²_{a/2}, χ²_{1−a/2}](dof · n_runs) / n_runs`` with ``a = 1 − confidence``.
    """
    d = check_positive_int("dof", dof) * check_positive_int("n_runs", n_runs)
    a = 1.0 - float(check_positive("confidence", confidence))
    return float(chi2_ppf(a / 2, d) / n_runs), float(chi2_ppf(1 - a / 2, d) / n_runs)


def gaussian_region_flags(mean: ArrayLike, cov: ArrayLike, truth: ArrayLike) -> BoolArray:
    """Whether the true position lies in the Pr-ellipse of the ``(x, y)`` block, shape (..., 3).

    Columns in the order of :data:`~pose_uncertainty.core.stats.COVERAGE_LEVELS`:
    inside when ``d² ≤ −2 ln(1 − Pr)``; a singular block counts as outside.
    """
    m = check_last_axis("mean", mean, 3)
    S = check_finite("cov", cov)[..., :2, :2]
    d = check_last_axis("truth", truth, 3)[..., :2] - m[..., :2]
    det = S[..., 0, 0] * S[..., 1, 1] - S[..., 0, 1] ** 2
    ok = det > 0
    safe = np.where(ok, det, 1.0)
    d2 = (S[..., 1, 1] * d[..., 0] ** 2 - 2 * S[..., 0, 1] * d[..., 0] * d[..., 1]
          + S[..., 0, 0] * d[..., 1] ** 2) / safe  # fmt: skip
    return ok[..., None] & (d2[..., None] <= _K_ARRAY)


def mass_region_flags(masses: ArrayLike, cell: tuple[int, int]) -> BoolArray:
    """Whether cell ``(i, j)`` lies in the highest-density regions of ``masses`` (nx, ny), shape (3,).

    Levels as :data:`~pose_uncertainty.core.stats.COVERAGE_LEVELS`; a cell off the grid is outside.
    """
    v = np.asarray(masses, dtype=np.float64)
    i, j = cell
    if not (0 <= i < v.shape[0] and 0 <= j < v.shape[1]):
        return np.zeros(len(_PRS), dtype=bool)
    return (v[i, j] >= hdr_region(v, _PR_ARRAY)[0]) & (v[i, j] > 0)


def region_flags_of_mass(mass: float, masses: Array) -> BoolArray:
    """Whether a cell of mass ``mass`` lies in the highest-density regions of the cells ``masses``, shape (3,).

    The flags of :func:`mass_region_flags` for the masses a filter makes at every step
    (finite, ≥ 0, positive total: not validated, :func:`~pose_uncertainty.core.stats.hdr_levels`);
    ``mass`` is one of them, or 0 for a cell off the grid (a cell without mass is outside).
    """
    if not mass > 0:
        return np.zeros(len(_PRS), dtype=bool)
    return mass >= hdr_levels(masses, _PR_ARRAY)


def weighted_mean_cov(particles: ArrayLike, w: ArrayLike) -> tuple[Array, Array]:
    """Weighted mean (circular in θ) and covariance (θ deviations wrapped round the mean).

    Parameters
    ----------
    particles : array_like, shape (n, 3); w : array_like, shape (n,), normalised

    Returns
    -------
    mean : ndarray, shape (3,) — θ in (−π, π]; cov : ndarray, shape (3, 3) — ``Σ w ε εᵀ``
    """
    P = check_last_axis("particles", particles, 3)
    ww = np.asarray(w, dtype=np.float64)
    th = math.atan2(float(ww @ np.sin(P[:, 2])), float(ww @ np.cos(P[:, 2])))
    mean = np.array([float(ww @ P[:, 0]), float(ww @ P[:, 1]), th])
    e = P - mean
    e[:, 2] = wrap_angle(e[:, 2])
    return mean, (e * ww[:, None]).T @ e


def convergence(
    times: ArrayLike, pos_err: ArrayLike, head_err: ArrayLike, pos_tol: float, head_tol: float
) -> tuple[bool, float]:
    """Success and time to converge of a localization.

    Success: the errors at the last step are within ``pos_tol`` [m] and ``head_tol`` [rad].
    Time to converge: the first time from which they stay within both until the end
    (``inf`` when they are not within at the end).
    """
    t = check_finite("times", times)
    ok = (np.asarray(pos_err) <= pos_tol) & (np.asarray(head_err) <= head_tol)
    if not ok[-1]:
        return False, math.inf
    bad = np.flatnonzero(~ok)
    first = 0 if bad.size == 0 else int(bad[-1]) + 1
    return True, float(t[first] - t[0])
