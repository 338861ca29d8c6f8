"""Which drive accumulates which uncertainty: spreads along and across a path, and their growth.

For a drive's path and error model, Method A (per step or per run, first
order) and optionally the Monte Carlo cloud give the standard deviations along
and across the nominal heading and of the heading at points evenly spaced in
path length; a power law ``σ = a·s^p`` is fitted to each
(:func:`pose_uncertainty.core.stats.fit_growth`). On a straight the differential drive's
across-track spread grows as ``s^1.5`` (an integrated heading random walk) and
its along-track spread as ``s^0.5``; a synchro drive never turns, so both of its
spreads grow as ``s^0.5``.

A run with a ``drive`` section (:mod:`pose_uncertainty.experiments.drive_run`) logs the
same fits as measures (:func:`growth_measures`, at the points of
:func:`growth_points`), and for a skid-steer drive how far plain differential
odometry is off (:func:`plain_odometry_measures`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import DrivePath, SkidSteer
from ..core.stats import fit_growth, path_spreads
from ..core.validation import check_choice, check_last_axis, check_positive_int
from ..methods import drive_covariance as dc
from ..methods import drive_noise as dn
from ..methods import drive_sampling as ds
from ..methods.sampling import REGIMES

__all__ = [
    "MEASURES",
    "drive_growth",
    "growth_measures",
    "growth_points",
    "plain_odometry_measures",
]

#: the spreads whose growth is fitted
MEASURES: tuple[str, ...] = ("sigma_along", "sigma_across", "sigma_theta")


def _distance(path: DrivePath) -> NDArray[np.float64]:
    """Path length of the reference point at every pose, ``Σ|(v₁, v₂)|`` [m], shape (N+1,)."""
    xi = path.twists
    return np.concatenate([[0.0], np.cumsum(np.hypot(xi[:, 0], xi[:, 1]))])


def _checkpoints(path: DrivePath, n_points: int, skip: float) -> tuple[np.ndarray, np.ndarray]:
    """Step indices evenly spaced in path length from ``skip`` of the path to its end, and the lengths."""
    dist = _distance(path)
    targets = np.linspace(skip * dist[-1], dist[-1], n_points)
    idx = np.unique(np.clip(np.searchsorted(dist, targets), 1, path.n_steps))
    return idx, dist[idx]


def growth_points(
    path: DrivePath, steps: Sequence[int] | None = None, n_points: int = 20, skip: float = 0.05
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """The poses a growth law is fitted at: step indices and their path lengths [m].

    With ``steps`` (e.g. the Monte Carlo checkpoints and the last step) those,
    sorted and unique; otherwise ``n_points`` evenly spaced in path length from
    ``skip`` of the path to its end (:func:`drive_growth`'s choice).
    """
    if steps is None:
        return _checkpoints(path, check_positive_int("n_points", n_points), skip)
    idx = np.unique(np.asarray(list(steps), dtype=np.intp))
    if idx.size == 0 or idx[0] < 0 or idx[-1] > path.n_steps:
        raise ValueError(
            f"steps must be step indices in [0, {path.n_steps}] (allowed: at least one), got {list(steps)}"
        )
    return idx, _distance(path)[idx]


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


def growth_measures(
    prefix: str, distance: ArrayLike, poses: ArrayLike, covs: ArrayLike
) -> dict[str, float]:
    """Power-law exponents of the spreads against path length, as logged measures.

    For each of :data:`MEASURES` with at least 3 points of positive distance and
    spread (a synchro drive's heading spread stays 0: no law), the exponent ``p``
    of ``σ = a·s^p`` (:func:`~pose_uncertainty.core.stats.fit_growth`) as
    ``<prefix>_growth_<measure>`` and its rms log residual as
    ``<prefix>_growth_<measure>_residual``.

    Parameters
    ----------
    prefix : str — ``"A"`` (Method A) or ``"MC"`` (the Monte Carlo clouds' sample covariances)
    distance : array_like, shape (M,) — path length at each point [m]
    poses : array_like, shape (M, 3) — nominal poses (the along/across frame)
    covs : array_like, shape (M, 3, 3) — covariances at those poses
    """
    s = np.asarray(distance, dtype=np.float64)
    spreads = path_spreads(check_last_axis("poses", poses, 3), np.asarray(covs, dtype=np.float64))
    out: dict[str, float] = {}
    for m in MEASURES:
        ok = (s > 0) & (spreads[m] > 0)
        if int(ok.sum()) < 3:
            continue
        fit = fit_growth(s[ok], spreads[m][ok])
        out[f"{prefix}_growth_{m}"] = fit["power_exponent"]
        out[f"{prefix}_growth_{m}_residual"] = fit["power_rms_log_residual"]
    return out


def plain_odometry_measures(path: DrivePath, cov_end: ArrayLike) -> dict[str, float]:
    """How far plain differential odometry is off on a skid-steer drive's path (``drive_plain_odometry_*``).

    The robot truly moves by its ICR model (``path.drive``, ``χ``, ``x_ICR``); its
    odometry integrates the same track travels as a differential drive
    (:func:`~pose_uncertainty.methods.drive_noise.plain_odometry_error`, exact steps).
    Returns the end position error [m], the end heading error and the largest
    heading error along the path [rad] (reported minus true), and the Mahalanobis
    distance of the reported end position from the true one under ``cov_end``
    (Method A's end covariance; its (x, y) block): how many standard deviations
    of the uncertainty the odometry's own bias amounts to. Empty for other drives.

    Parameters
    ----------
    path : DrivePath
    cov_end : array_like, shape (3, 3) — Method A's covariance at the end [m², m·rad, rad²]
    """
    if not isinstance(path.drive, SkidSteer):
        return {}
    err = dn.plain_odometry_error(path.drive, path.u, path.start)
    d = err[-1, :2]
    C = np.asarray(cov_end, dtype=np.float64)[:2, :2]
    maha = math.nan
    if np.linalg.det(C) > 0:
        maha = float(np.sqrt(d @ np.linalg.solve(C, d)))
    return {
        "drive_plain_odometry_position_error": float(np.hypot(d[0], d[1])),
        "drive_plain_odometry_heading_error": float(err[-1, 2]),
        "drive_plain_odometry_max_heading_error": float(np.abs(err[:, 2]).max()),
        "drive_plain_odometry_mahalanobis": maha,
    }
