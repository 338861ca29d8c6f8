"""Statistics of particle clouds: moments, Pr-regions of Gaussians and their coverage.

The probability levels used everywhere (one convention): a 2-D Gaussian's
Pr-ellipse is the set of squared Mahalanobis radius ``≤ k = −2 ln(1 − Pr)``
(:func:`pr_to_k`); the levels of radius 1, 2 and 3 are :data:`PR_1SIGMA`,
:data:`PR_2SIGMA` and :data:`PR_3SIGMA` (39.35 %, 86.47 %, 98.89 %, the thesis's
figure), named in :data:`COVERAGE_LEVELS`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .validation import (
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_positive_int,
    check_probability,
)

__all__ = [
    "COVERAGE_LEVELS",
    "PR_1SIGMA",
    "PR_2SIGMA",
    "PR_3SIGMA",
    "along_across",
    "chi2_ppf",
    "fit_growth",
    "fraction_inside_ellipse",
    "hdr_levels",
    "hdr_region",
    "hellinger",
    "hellinger_noise_floor",
    "k_to_pr",
    "mahalanobis_sq",
    "mean_cov",
    "path_spreads",
    "pr_to_k",
    "wilson_interval",
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


#: ``scipy.special.chdtri(dof, 1 − pr)`` for the levels the runs use (the accuracy measures' and the
#: coverage levels, 95 % and 99 %) and 1–3 degrees of freedom, bit for bit (tests/test_grids_stats.py
#: recomputes every entry): a run job that needs no other special function then does not import
#: ``scipy.special``, 0.2 s of its start-up.
_CHI2_PPF: dict[tuple[float, float], float] = {
    (PR_1SIGMA, 1.0): 0.2652579598005073,
    (0.5, 1.0): 0.4549364231195724,
    (PR_2SIGMA, 1.0): 2.230211931863234,
    (0.9, 1.0): 2.705543454095414,
    (0.95, 1.0): 3.841458820694124,
    (PR_3SIGMA, 1.0): 6.447797658504633,
    (0.99, 1.0): 6.6348966010212145,
    (PR_1SIGMA, 2.0): 1.0,
    (0.5, 2.0): 1.386294361119891,
    (PR_2SIGMA, 2.0): 4.0,
    (0.9, 2.0): 4.605170185988092,
    (0.95, 2.0): 5.991464547107979,
    (PR_3SIGMA, 2.0): 9.000000000000007,
    (0.99, 2.0): 9.21034037197618,
    (PR_1SIGMA, 3.0): 1.8387887712472735,
    (0.5, 3.0): 2.3659738843753377,
    (PR_2SIGMA, 3.0): 5.55586344045028,
    (0.9, 3.0): 6.251388631170327,
    (0.95, 3.0): 7.814727903251179,
    (PR_3SIGMA, 3.0): 11.117146335345817,
    (0.99, 3.0): 11.344866730144373,
}


def chi2_ppf(pr: ArrayLike, dof: ArrayLike) -> NDArray[np.float64]:
    """Quantile of the χ² distribution with ``dof`` degrees of freedom at probability ``pr`` in (0, 1).

    ``scipy.special.chdtri`` (the inverse survival function), so that a run need not import
    ``scipy.stats``; equals ``scipy.stats.chi2.ppf(pr, dof)`` (tests/test_grids_stats.py). A scalar
    level and degree of freedom in :data:`_CHI2_PPF` is looked up there (the same value).
    """
    p = check_probability("pr", pr)
    d = check_nonnegative("dof", dof)
    if p.ndim == 0 and d.ndim == 0:
        known = _CHI2_PPF.get((float(p), float(d)))
        if known is not None:
            return np.asarray(known, dtype=np.float64)
    from scipy.special import chdtri  # imported where used: scipy.special takes 0.2 s to import

    return np.asarray(chdtri(d, 1.0 - p), dtype=np.float64)


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


# --- highest-density regions of gridded distributions -------------------------------------------


def hdr_region(
    mass: ArrayLike, pr: ArrayLike, total: float | None = None
) -> tuple[Any, Any]:
    """The Pr highest-density region of a distribution given as mass per cell.

    The one convention of the package: cells are taken from the most probable
    down until their mass reaches ``pr · total``; the region is every cell of
    mass ≥ ``level``, the mass of the last cell taken (cells of equal mass at the
    boundary all belong; on cells of equal area mass order is density order), and
    its size counts that last cell only in proportion to the mass still needed (so
    the size is continuous in ``pr``).

    Parameters
    ----------
    mass : array_like, any shape — probability mass per cell (≥ 0); equal-sized cells
    pr : float or array_like in (0, 1) — one sort serves every level
    total : float, optional — the probability of the whole distribution in the
        units of ``mass``: default the mass on the cells (a relative map); 1 for a
        map that lost mass off its grid, then the region is ``nan`` when the cells
        hold less than ``pr``.

    Returns
    -------
    level : float, or ndarray of the shape of ``pr`` — mass-per-cell threshold (``nan`` if unreachable)
    n_cells : the same — the region's size in cells, fractional (times the cell area: m²)
    """
    m, cum, need, k = _hdr_cut(check_nonnegative("mass", mass), check_probability("pr", pr), total)
    before = np.where(k > 0, cum[k - 1], 0.0)
    frac = np.where(m[k] > 0, np.minimum(1.0, (need - before) / np.where(m[k] > 0, m[k], 1.0)), 1.0)
    reach = need <= cum[-1] * (1 + 1e-12)
    level = np.where(reach, m[k], np.nan)
    n_cells = np.where(reach, k + frac, np.nan)
    if level.ndim == 0:
        return float(level), float(n_cells)
    return level, n_cells


def hdr_levels(mass: NDArray[np.float64], pr: NDArray[np.float64]) -> NDArray[np.float64]:
    """The ``level`` of :func:`hdr_region` (relative: ``total`` the mass on the cells), inputs not validated.

    For the masses a filter makes at every step (finite, ≥ 0, positive total: the caller's
    guarantee) and levels ``pr`` it holds (in (0, 1)): the same numbers as :func:`hdr_region`
    without its checks (a relative region is always reached).

    Parameters
    ----------
    mass : ndarray of float64, any shape; pr : ndarray of float64, shape (P,)

    Returns
    -------
    level : ndarray, shape (P,) — mass-per-cell threshold of each level
    """
    m, _, _, k = _hdr_cut(mass, pr, None)
    return m[k]


def _hdr_cut(
    mass: NDArray[np.float64], p: NDArray[np.float64], total: float | None
) -> tuple[NDArray[np.float64], NDArray[np.float64], Any, Any]:
    """The masses sorted down, their running sum, the mass each level needs and the index of its last cell."""
    m = np.sort(mass.ravel())[::-1]
    cum = np.cumsum(m)
    if cum.size == 0 or cum[-1] <= 0:
        raise ValueError("mass must have a positive total (allowed: a distribution), got total 0")
    need = p * (cum[-1] if total is None else float(total))
    return m, cum, need, np.minimum(np.searchsorted(cum, need), m.size - 1)


def hellinger(p: ArrayLike, q: ArrayLike) -> float:
    """Hellinger distance ``√(1 − Σ √(p̃_i q̃_i))`` between two distributions given per cell.

    The one convention of the package: ``p`` and ``q`` (non-negative, same shape:
    cell probabilities, masses or counts) are each normalised to sum 1 over the
    compared cells first, so the distance compares the two distributions *on those
    cells* (by shape); the mass either puts off the cells is a separate measure,
    reported beside it (a map's ``lost_mass``, a sampler's share on the grid, a
    model's mass on the stated grid). 0 for identical, 1 for disjoint. Its sampling
    floor is :func:`hellinger_noise_floor`.
    """
    a = check_nonnegative("p", p)
    b = check_nonnegative("q", q)
    if a.shape != b.shape:
        raise ValueError(f"p and q must have the same shape, got {a.shape} and {b.shape}")
    sa, sb = float(a.sum()), float(b.sum())
    if sa <= 0 or sb <= 0:
        raise ValueError(f"p and q must have positive total mass, got {sa} and {sb}")
    bc = float(np.sum(np.sqrt(a / sa * (b / sb))))
    return math.sqrt(max(0.0, 1.0 - bc))


def hellinger_noise_floor(p: ArrayLike, n: int) -> float:
    """Expected Hellinger distance between ``p`` and a histogram of ``n`` samples drawn from it.

    With ``X_i ~ Poisson(λ_i = n p_i)``: ``E[H²] = ½ Σ E[(√(X_i/n) − √p_i)²]
    = Σ (λ_i − √λ_i E√X_i)/n``; ``E√X`` by direct summation for ``λ ≤ 50`` and
    by its asymptotic series above. Returns ``√E[H²]``. A map that is the exact
    density of the sampler sits at this value; anything above it is model or
    discretisation error.
    """
    w = check_nonnegative("p", p).ravel()
    n = check_positive_int("n", n)
    w = w / w.sum()
    lam = n * w[w > 0]
    small = lam <= 50.0
    e_sqrt = np.empty_like(lam)
    big = lam[~small]
    e_sqrt[~small] = np.sqrt(big) * (1 - 1 / (8 * big) - 7 / (128 * big**2))
    if np.any(small):
        from scipy.special import gammaln  # imported where used (0.2 s)

        ls = lam[small][:, None]
        k = np.arange(0, 151)[None, :]
        logpmf = k * np.log(ls) - ls - gammaln(k + 1)
        e_sqrt[small] = np.sum(np.sqrt(k) * np.exp(logpmf), axis=1)
    eh2 = float(np.sum(lam - np.sqrt(lam) * e_sqrt)) / n
    return math.sqrt(max(0.0, eh2))


# --- the path frame -----------------------------------------------------------------------------


def along_across(cov_xy: ArrayLike, heading: ArrayLike) -> NDArray[np.float64]:
    """Standard deviations along and across a heading of planar covariances.

    The one convention of the package for "along / across the path": the frame
    of the *nominal* heading θ, ``along = (cos θ, sin θ)``, ``across = (−sin θ, cos θ)``.

    Parameters
    ----------
    cov_xy : array_like, shape (..., 2, 2) [m²]
    heading : array_like, shape (...) [rad]

    Returns
    -------
    ndarray, shape (..., 2) — ``(σ_along, σ_across)`` [m]
    """
    C = check_finite("cov_xy", cov_xy)
    if C.shape[-2:] != (2, 2):
        raise ValueError(f"cov_xy must have shape (..., 2, 2), got shape {C.shape}")
    th = check_finite("heading", heading)
    c, s = np.cos(th), np.sin(th)
    sxx, syy, sxy = C[..., 0, 0], C[..., 1, 1], C[..., 0, 1]
    along = c * c * sxx + 2 * c * s * sxy + s * s * syy
    across = s * s * sxx - 2 * c * s * sxy + c * c * syy
    return np.sqrt(np.maximum(np.stack([along, across], axis=-1), 0.0))


# --- growth laws --------------------------------------------------------------------------------


def path_spreads(poses: NDArray[np.float64], covs: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
    """Standard deviations along and across the path (frame of the nominal heading) and of θ.

    Parameters
    ----------
    poses : ndarray, shape (M, 3); covs : ndarray, shape (M, 3, 3)

    Returns
    -------
    dict of ndarray (M,): ``sigma_along``, ``sigma_across`` [m]
    (:func:`along_across`), ``sigma_theta`` [rad],
    ``area`` — area of the 98.89 % ellipse ``π k √det Σ_xy`` [m²]
    """
    aa = along_across(covs[:, :2, :2], poses[:, 2])
    det = np.maximum(covs[:, 0, 0] * covs[:, 1, 1] - covs[:, 0, 1] ** 2, 0.0)
    return {
        "sigma_along": aa[:, 0],
        "sigma_across": aa[:, 1],
        "sigma_theta": np.sqrt(np.maximum(covs[:, 2, 2], 0)),
        "area": math.pi * float(pr_to_k(PR_3SIGMA)) * np.sqrt(det),
    }


def fit_growth(distance: ArrayLike, value: ArrayLike) -> dict[str, float]:
    """Fit ``value = a·s^p`` (log-log) and ``value = a·e^{c s}`` (semi-log) by least squares.

    Points with a non-positive distance or value are left out.

    Returns
    -------
    dict: ``power_exponent`` p, ``power_rms_log_residual``, ``exp_rate`` c [1/unit
    of s], ``exp_rms_log_residual`` — rms residuals of ``ln value``, so the smaller
    one is the better law; ``local_exponent_end`` — d ln v / d ln s over the last
    fifth of the range (p when fewer than two points lie there).

    Raises
    ------
    ValueError — fewer than 3 usable points.
    """
    s = np.asarray(distance, dtype=float)
    v = np.asarray(value, dtype=float)
    ok = (s > 0) & (v > 0) & np.isfinite(s) & np.isfinite(v)
    s, v = s[ok], v[ok]
    if s.size < 3:
        raise ValueError(f"need at least 3 positive points to fit a growth law, got {s.size}")
    order = np.argsort(s)
    s, lv = s[order], np.log(v[order])
    p, a = np.polyfit(np.log(s), lv, 1)
    c, b = np.polyfit(s, lv, 1)
    tail = s >= s[0] + 0.8 * (s[-1] - s[0])
    local = float(np.polyfit(np.log(s[tail]), lv[tail], 1)[0]) if tail.sum() >= 2 else float(p)
    return {
        "power_exponent": float(p),
        "power_rms_log_residual": float(np.sqrt(np.mean((lv - a - p * np.log(s)) ** 2))),
        "exp_rate": float(c),
        "exp_rms_log_residual": float(np.sqrt(np.mean((lv - b - c * s) ** 2))),
        "local_exponent_end": local,
    }


# --- proportions --------------------------------------------------------------------------------


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion ``successes / n``.

    ``(p̂ + z²/2n ± z √(p̂(1−p̂)/n + z²/4n²)) / (1 + z²/n)`` with ``z`` the two-sided normal
    quantile of ``confidence``; unlike ``p̂ ± z·SE`` it stays inside [0, 1] and is not
    empty at ``p̂ = 0`` or 1 (Wilson 1927).

    Returns
    -------
    (low, high) — ``(nan, nan)`` for ``n = 0``
    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
        raise ValueError(f"n must be an integer >= 0 (allowed: 0, 1, 2, ...), got {n!r}")
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be in [0, n] (allowed: 0..{n}), got {successes!r}")
    check_probability("confidence", confidence)
    if n == 0:
        return math.nan, math.nan
    from scipy.special import ndtri  # imported where used (0.2 s)

    z = float(ndtri(0.5 + confidence / 2.0))
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    # the interval holds p̂ exactly (rounding could put an end a hair past it at p̂ = 0 or 1)
    return min(max(0.0, centre - half), p), max(min(1.0, centre + half), p)
