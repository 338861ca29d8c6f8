"""Statistics of particle clouds: moments and coverage of Pr-ellipses."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .covariance import pr_to_k
from .validation import check_finite, check_last_axis

__all__ = ["fraction_inside_ellipse", "mahalanobis_sq", "mean_cov"]


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
