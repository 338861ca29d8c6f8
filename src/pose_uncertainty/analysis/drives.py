"""Which drive accumulates which uncertainty: spreads along and across a path, and their growth.

For a drive's path and error model, Method A (per step or per run, first
order) and optionally the Monte Carlo cloud give the standard deviations along
and across the nominal heading and of the heading at points evenly spaced in
path length; a power law ``σ = a·s^p`` is fitted to each
(:func:`pose_uncertainty.core.stats.fit_growth`). On a straight the differential drive's
across-track spread grows as ``s^1.5`` (an integrated heading random walk) and
its along-track spread as ``s^0.5``; a synchro drive never turns, so both of its
spreads grow as ``s^0.5``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..core.drives import DrivePath
from ..core.stats import fit_growth
from ..core.validation import check_choice, check_positive_int
from ..methods import drive_covariance as dc
from ..methods import drive_noise as dn
from ..methods import drive_sampling as ds
from ..methods.sampling import REGIMES
from .studies import path_spreads

__all__ = ["MEASURES", "drive_growth"]

#: the spreads whose growth is fitted
MEASURES: tuple[str, ...] = ("sigma_along", "sigma_across", "sigma_theta")


def _checkpoints(path: DrivePath, n_points: int, skip: float) -> tuple[np.ndarray, np.ndarray]:
    """Step indices evenly spaced in path length from ``skip`` of the path to its end, and the lengths."""
    xi = path.twists
    dist = np.concatenate([[0.0], np.cumsum(np.hypot(xi[:, 0], xi[:, 1]))])
    targets = np.linspace(skip * dist[-1], dist[-1], n_points)
    idx = np.unique(np.clip(np.searchsorted(dist, targets), 1, path.n_steps))
    return idx, dist[idx]


def _fitted(poses: np.ndarray, covs: np.ndarray, s: np.ndarray) -> dict[str, Any]:
    aa = path_spreads(poses, covs)
    out: dict[str, Any] = {k: aa[k].tolist() for k in MEASURES}
    # a spread that stays zero (a synchro drive's heading) has no growth law
    out["fits"] = {k: fit_growth(s, aa[k]) for k in MEASURES if np.any(aa[k] > 0)}
    return out


def drive_growth(
    path: DrivePath,
    model: dn.DriveErrorModel,
    *,
    regime: str = "per_step",
    n_points: int = 20,
    skip: float = 0.05,
    n_particles: int = 0,
    seed: int = 0,
) -> dict[str, Any]:
    """Spreads along/across the path and of the heading against path length, with power-law fits.

    Parameters
    ----------
    path : DrivePath; model : DriveErrorModel
    regime : {"per_step", "per_run"} — the first-order covariance of that regime
    n_points : int — points evenly spaced in path length from ``skip`` of the path to its end
    n_particles : int — if > 0, also the Monte Carlo cloud's spreads (midpoint integration)
    seed : int — of the Monte Carlo generator

    Returns
    -------
    dict: ``distance`` [m] list; ``method_a`` and possibly ``monte_carlo``:
    {``sigma_along``, ``sigma_across`` [m], ``sigma_theta`` [rad] lists, ``fits``: {measure: fit}}
    """
    check_choice("regime", regime, REGIMES)
    idx, s = _checkpoints(path, check_positive_int("n_points", n_points), skip)
    A = (
        dc.propagate_path(path, model)
        if regime == "per_step"
        else dc.propagate_path_per_run(path, model)
    )
    out: dict[str, Any] = {"distance": s.tolist()}
    out["method_a"] = _fitted(A.poses[idx], A.covs[idx], s)
    if n_particles > 0:
        clouds = ds.sample_poses(
            path,
            model,
            n_particles,
            np.random.default_rng(seed),
            regime=regime,
            checkpoints=idx.tolist(),
        )
        covs = np.stack([np.cov(clouds[:, i, :].T) for i in range(idx.size)])
        out["monte_carlo"] = _fitted(A.poses[idx], covs, s)
    return out
