"""Statistics of particle clouds: moments, Pr-regions of Gaussians and their coverage.

The probability levels used everywhere (one convention): a 2-D Gaussian's
Pr-ellipse is the set of squared Mahalanobis radius ``≤ k = −2 ln(1 − Pr)``
(:func:`pr_to_k`); the levels of radius 1, 2 and 3 are :data:`PR_1SIGMA`,
:data:`PR_2SIGMA` and :data:`PR_3SIGMA` (39.35 %, 86.47 %, 98.89 %, the thesis's
figure), named in :data:`COVERAGE_LEVELS`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .validation import check_finite, check_last_axis, check_nonnegative, check_probability

__all__ = [
    "COVERAGE_LEVELS",
    "PR_1SIGMA",
    "PR_2SIGMA",
    "PR_3SIGMA",
    "fraction_inside_ellipse",
    "hdr_mass_level",
    "k_to_pr",
    "mahalanobis_sq",
    "mean_cov",
    "pr_to_k",
]

#: Probability inside the 2-D ellipse of Mahalanobis radius 1: 1 − e^{−1/2} = 39.35 %.
PR_1SIGMA: float = float(-np.expm1(-0.5))
#: Probability inside the 2-D ellipse of Mahalanobis radius 2: 1 − e^{−2} = 86.47 %.
PR_2SIGMA: float = float(-np.expm1(-2.0))
#: Probability inside the 2-D ellipse of Mahalanobis radius 3: 1 − e^{−4.5} = 98.89 % (the thesis's).
PR_3SIGMA: float = float(-np.expm1(-4.5))
#: The three levels by name (``"1s"``, ``"2s"``, ``"3s"``): keys of coverage measures.
COVERAGE_LEVELS: dict[str, float] = {"1s": PR_1SIGMA, "2s": PR_2SIGMA, "3s": PR_3SIGMA}


def pr_to_k(pr: ArrayLike) -> NDArray[np.float64]:
    """Squared Mahalanobis radius of the 2-D Pr-ellipse: ``k = −2 ln(1 − Pr)``; Pr in (0, 1)."""
    return -2.0 * np.log1p(-check_probability("pr", pr))


def k_to_pr(k: ArrayLike) -> NDArray[np.float64]:
    """Probability inside the 2-D ellipse of squared Mahalanobis radius ``k``: ``1 − e^{−k/2}``."""
    return -np.expm1(-check_nonnegative("k", k) / 2.0)


def mean_cov(samples: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Sample mean and unbiased sample covariance of a cloud.

    Parameters
    ----------
    samples : array_like, shape (n, d), n ≥ 2 — headings should be unwrapped
        (as the samplers return them) so that the θ moments are meaningful.

    Returns
    -------
    mean : ndarray, shape (d,); cov : ndarray, shape (d, d)
    """
    x = check_finite("samples", samples)
    if x.ndim != 2 or x.shape[0] < 2:
        raise ValueError(f"samples must have shape (n, d) with n >= 2, got shape {x.shape}")
    mean = x.mean(axis=0)
    d = x - mean
    return mean, d.T @ d / (x.shape[0] - 1)


def mahalanobis_sq(points: ArrayLike, center: ArrayLike, cov: ArrayLike) -> NDArray[np.float64]:
    """Squared Mahalanobis distance ``(p − c)ᵀ Σ⁻¹ (p − c)``.

    Parameters
    ----------
    points : array_like, shape (..., d); center : array_like, shape (d,)
    cov : array_like, shape (d, d), positive definite
    """
    C = check_finite("cov", cov)
    d = C.shape[-1]
    p = check_last_axis("points", points, d)
    c = check_last_axis("center", center, d)
    diff = p - c
    L = np.linalg.cholesky(C)
    z = np.linalg.solve(L, diff.reshape(-1, d).T).T
    return (z**2).sum(axis=-1).reshape(p.shape[:-1])


def fraction_inside_ellipse(
    xy: ArrayLike, center: ArrayLike, cov_xy: ArrayLike, pr: float
) -> float:
    """Fraction of 2-D points inside the Pr-ellipse of ``(center, cov_xy)``.

    A point is inside when its squared Mahalanobis distance is ≤ ``k = −2 ln(1−Pr)``.

    Parameters
    ----------
    xy : array_like, shape (n, 2) [m]; center : array_like, shape (2,) [m]
    cov_xy : array_like, shape (2, 2) [m²], positive definite; pr : float in (0, 1)
    """
    k = pr_to_k(pr)
    return float(np.mean(mahalanobis_sq(xy, center, cov_xy) <= k))


def hdr_mass_level(masses: ArrayLike, pr: ArrayLike) -> NDArray[np.float64]:
    """Cell-mass threshold of the highest-density region holding ``pr`` of a gridded distribution.

    Cells sorted by mass, largest first; the region is the smallest such set whose
    masses sum to at least ``pr`` of the total, and the level is the mass of its last
    cell: a cell belongs to the region when its mass is ≥ the level (cells of equal
    mass at the boundary all belong). On cells of equal area, mass order is density order.

    Parameters
    ----------
    masses : array_like, any shape, ≥ 0 with a positive sum
    pr : float or array_like in (0, 1) — one sort serves every level

    Returns
    -------
    ndarray, shape of ``pr`` — the levels (mass per cell)
    """
    v = np.sort(check_nonnegative("masses", masses).ravel())[::-1]
    p = check_probability("pr", pr)
    cum = np.cumsum(v)
    if not cum[-1] > 0:
        raise ValueError("masses must have a positive sum (allowed: a distribution), got 0")
    idx = np.searchsorted(cum, p * cum[-1])
    return np.asarray(v[np.minimum(idx, v.size - 1)], dtype=np.float64)
