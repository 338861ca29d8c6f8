"""The shape of the cloud and its growth with distance.

:func:`polar_vs_cartesian` gives the moments of a cloud in Cartesian ``(x, y)`` and
polar ``(r, φ)`` coordinates about the start; :func:`growth_laws` fits how σ_along,
σ_across, σ_θ and the credible-region area grow with distance (log-log power laws
against exponential fits) for Method A, Method C and Monte Carlo.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...core import trajectories as tr
from ...core.stats import PR_3SIGMA, fit_growth, path_spreads
from ...core.validation import check_positive_int
from ...methods import covariance as cv
from ...methods import sampling as sp
from ...methods import unscented as ut
from .. import accuracy as ac
from .gaussian_methods import straight_path


def _moments(v: NDArray) -> dict[str, float]:
    """Mean, sample std, and the moment estimates of skewness ``m3/m2^1.5`` and excess kurtosis
    ``m4/m2² − 3`` (``scipy.stats.skew``/``kurtosis`` with their default ``bias=True``)."""
    d = v - v.mean()
    m2, m3, m4 = (float(np.mean(d**k)) for k in (2, 3, 4))
    return {
        "mean": float(v.mean()),
        "std": float(v.std(ddof=1)),
        "skewness": m3 / m2**1.5,
        "excess_kurtosis": m4 / m2**2 - 3.0,
    }


def polar_vs_cartesian(samples: ArrayLike, origin: ArrayLike = (0.0, 0.0)) -> dict[str, Any]:
    """Moments of a cloud of end positions in Cartesian and in polar coordinates about ``origin``.

    Gaussianity of each view: ``coverage_98.89`` is the fraction of points
    inside the 98.89 % ellipse of the view's own mean and covariance (98.89 %
    for a Gaussian cloud); ``|skewness|`` and ``|excess kurtosis|`` near 0.

    Returns
    -------
    dict: ``cartesian`` {``x``, ``y``, ``coverage_98.89``}, ``polar`` {``r``, ``phi``, ``coverage_98.89``}
    """
    s = np.asarray(samples, dtype=float)
    o = np.asarray(origin, dtype=float)
    d = s[:, :2] - o
    r = np.hypot(d[:, 0], d[:, 1])
    phi = np.unwrap(np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(d[:, 1].mean(), d[:, 0].mean()))
    phi = (phi + np.pi) % (2 * np.pi) - np.pi + np.arctan2(d[:, 1].mean(), d[:, 0].mean())

    def cover(a: NDArray, b: NDArray) -> float:
        X = np.stack([a, b], -1)
        return ac.coverage_ellipse(X, X.mean(0), np.cov(X.T), (PR_3SIGMA,))["98.89"]

    return {
        "cartesian": {"x": _moments(s[:, 0]), "y": _moments(s[:, 1]),
                      "coverage_98.89": cover(s[:, 0], s[:, 1])},
        "polar": {"r": _moments(r), "phi": _moments(phi), "coverage_98.89": cover(r, phi)},
    }


def growth_laws(
    trajectory: tr.Trajectory,
    k_r: float,
    k_l: float,
    n_points: int = 50,
    skip: float = 0.05,
    *,
    n_particles: int = 0,
    seed: int = 0,
    regime: str = "per_step",
) -> dict[str, Any]:
    """Fitted growth of the spreads with distance: Method A and (optionally) Monte Carlo.

    ``n_points`` poses evenly spaced in path length from ``skip`` of the path to
    its end; for each measure — σ_along, σ_across (in the frame of the nominal
    heading), σ_θ, and the area of the 98.89 % ellipse ``π k √det Σ_xy`` — a
    power law and an exponential are fitted (:func:`fit_growth`). With
    ``n_particles > 0`` the same measures of the Monte Carlo cloud (its sample
    covariance) are fitted too, and always those of Method C (the unscented
    transform, :func:`pose_uncertainty.methods.unscented.propagate`; along and
    across the nominal heading, as A's). (The exponential-coordinates Gaussian has
    the same second moments as Method A to first order, so it is not repeated.)

    Returns
    -------
    dict: ``distance`` list; ``method_a``, ``method_c`` and possibly ``monte_carlo``:
    {measure: values list, ``fits``: {measure: fit}}
    """
    A = cv.propagate(trajectory, k_r, k_l)
    C = ut.propagate(trajectory, k_r, k_l)
    dist = np.concatenate([[0.0], np.cumsum(np.abs(trajectory.ds))])
    targets = np.linspace(skip * dist[-1], dist[-1], check_positive_int("n_points", n_points))
    idx = np.unique(np.clip(np.searchsorted(dist, targets), 1, trajectory.n_steps))
    s = dist[idx]
    out: dict[str, Any] = {"distance": s.tolist()}
    measures = {"method_a": path_spreads(A.poses[idx], A.covs[idx]),
                "method_c": path_spreads(A.poses[idx], C.covs[idx])}  # frame of the nominal heading
    if n_particles > 0:
        clouds = sp.sample_end_poses(
            trajectory, k_r, k_l, n_particles, np.random.default_rng(seed), regime=regime,
            checkpoints=idx.tolist(),
        )
        covs = np.stack([np.cov(clouds[:, i, :].T) for i in range(idx.size)])
        measures["monte_carlo"] = path_spreads(trajectory.poses[idx], covs)
    for name, d in measures.items():
        out[name] = {k: v.tolist() for k, v in d.items()}
        out[name]["fits"] = {k: fit_growth(s, v) for k, v in d.items()}
    return out


def polar_vs_cartesian_study(
    trajectory: dict[str, Any] = straight_path(1.0),  # noqa: B008
    k: float = 5e-4, n: int = 100_000, seed: int = 5,
) -> dict[str, Any]:
    """:func:`polar_vs_cartesian` of a per-step Monte Carlo cloud of a configured trajectory."""
    t = tr.from_config(trajectory)
    return polar_vs_cartesian(sp.sample_end_poses(t, k, k, n, np.random.default_rng(seed)), t.start[:2])


def growth_laws_study(
    trajectory: dict[str, Any] = straight_path(20.0),  # noqa: B008
    k: float = 5e-4, n_points: int = 20, n_particles: int = 20_000, seed: int = 0,
    regime: str = "per_step",
) -> dict[str, Any]:
    """The fits of :func:`growth_laws` along a configured trajectory."""
    g = growth_laws(tr.from_config(trajectory), k, k, n_points, n_particles=n_particles, seed=seed,
                    regime=regime)  # fmt: skip
    return {m: g[m]["fits"] for m in ("method_a", "method_c", "monte_carlo") if m in g}
