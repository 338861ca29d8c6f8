"""A run with a ``drive`` section: the drive's Method A, Monte Carlo, banana and measures.

:func:`pose_uncertainty.experiments.run.execute` calls these when the run configures a
drive (:mod:`pose_uncertainty.experiments.drive_config`); everything else of a run —
its trajectory, the probability maps, the logged measures, the log — is the
same as for the default differential drive.

* The trajectory is the geometric path; :func:`setup` lets the drive follow it
  (:func:`pose_uncertainty.core.drives.follow`): the drive's nominal odometry
  measurements, the path it reports.
* Method A: :func:`pose_uncertainty.methods.drive_covariance.propagate_path`
  (the per-step error model, midpoint steps, as the default route's
  :func:`pose_uncertainty.methods.covariance.propagate`), whatever the Monte
  Carlo regime — as for the differential drive, Method A models random errors.
* Monte Carlo: :func:`pose_uncertainty.methods.drive_sampling.sample_poses` in
  the configured regime, integration method and checkpoints.
* The exponential-coordinates Gaussian: :func:`pose_uncertainty.methods.drive_covariance.expcoords`.
* Measures beyond those of every run (:func:`measures`): the growth exponents of
  the spreads along the path for Method A and, with at least two Monte Carlo
  checkpoints, for the Monte Carlo clouds; for a skid-steer drive, how far plain
  differential odometry is off (the turn bias).

The probability maps (Method B) stay the velocity and odometry motion models of
the path's controls: they do not depend on the drive.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..analysis import drive_growth as adr
from ..core.drives import Drive, DrivePath, follow
from ..core.trajectories import Trajectory
from ..methods import drive_covariance as dc
from ..methods import drive_sampling as dsm
from ..methods.covariance import CovarianceResult
from ..methods.drive_noise import DriveErrorModel
from ..methods.expcoords import ExpGaussian
from ..methods.particles import DrawCache
from .drive_config import DriveConfig

__all__ = ["DriveSetup", "expcoords", "growth_steps", "measures", "method_a", "sample", "setup"]


@dataclass(frozen=True, eq=False)
class DriveSetup:
    """A configured drive on a run's path.

    Attributes
    ----------
    drive : Drive — with its geometry (track from the trajectory when not configured)
    model : DriveErrorModel
    path : DrivePath — the drive's nominal measurements along the trajectory
    """

    drive: Drive
    model: DriveErrorModel
    path: DrivePath


def setup(config: DriveConfig, trajectory: Trajectory, k_r: float, k_l: float) -> DriveSetup:
    """The drive, its error model and its measurements along ``trajectory``."""
    drive = config.drive(trajectory.track)
    return DriveSetup(drive, config.error_model(drive, k_r, k_l), follow(drive, trajectory))


def method_a(s: DriveSetup, cov0: ArrayLike | None) -> CovarianceResult:
    """Method A along the drive's path (per-step errors, midpoint steps); poses and covs (N+1, …)."""
    return dc.propagate_path(s.path, s.model, cov0=cov0, method="midpoint")


def sample(
    s: DriveSetup,
    n: int,
    rng: np.random.Generator,
    *,
    regime: str,
    method: str,
    cov0: ArrayLike | None,
    checkpoints: Sequence[int] | None,
    kernel: str = "auto",
    cache: DrawCache | None = None,
) -> NDArray[np.float64]:
    """Monte Carlo poses: (n, 3) end poses, or (n, C, 3) at ``checkpoints`` (:func:`.drive_sampling.sample_poses`,
    with its ``kernel`` and ``cache``)."""
    return dsm.sample_poses(
        s.path, s.model, n, rng, regime=regime, method=method, checkpoints=checkpoints, cov0=cov0,
        kernel=kernel, cache=cache,
    )  # fmt: skip


def expcoords(s: DriveSetup, cov0: ArrayLike | None) -> ExpGaussian:
    """The drive's exponential-coordinates Gaussian (``cov0`` in body-frame exponential coordinates)."""
    return dc.expcoords(s.path, s.model, cov0=cov0)


def growth_steps(s: DriveSetup, checkpoints: Sequence[int]) -> list[int] | None:
    """The steps a growth law is fitted at: the Monte Carlo checkpoints and the end, if ≥ 2 checkpoints.

    None (20 points evenly spaced in path length, :func:`pose_uncertainty.analysis.drive_growth.growth_points`)
    with fewer checkpoints, so that Method A's and the Monte Carlo's exponents come
    from the same points whenever the Monte Carlo has any to offer.
    """
    if len(checkpoints) < 2:
        return None
    return sorted({*checkpoints, s.path.n_steps})


def measures(
    s: DriveSetup,
    poses: NDArray[np.float64],
    covs: NDArray[np.float64],
    checkpoints: Sequence[int],
    clouds: Mapping[int, NDArray[np.float64]],
    end_poses: NDArray[np.float64] | None,
) -> dict[str, float]:
    """The measures of a drive run beyond every run's: ``A_growth_*``, ``MC_growth_*``, ``drive_plain_odometry_*``.

    Parameters
    ----------
    s : DriveSetup
    poses, covs : ndarray, shapes (N+1, 3), (N+1, 3, 3) — Method A
    checkpoints : sequence of int — the configured Monte Carlo checkpoint steps
    clouds : mapping step → (n, 3) — the Monte Carlo clouds at those steps
    end_poses : ndarray, shape (n, 3), or None — the Monte Carlo end poses
    """
    steps = growth_steps(s, checkpoints)
    idx, dist = adr.growth_points(s.path, steps)
    out = adr.growth_measures("A", dist, poses[idx], covs[idx])
    if steps is not None and end_poses is not None and end_poses.shape[0] >= 3:
        cloud_at = {**clouds, s.path.n_steps: end_poses}
        mc_covs = np.stack([np.cov(cloud_at[int(i)].T) for i in idx])
        out.update(adr.growth_measures("MC", dist, poses[idx], mc_covs))
    out.update(adr.plain_odometry_measures(s.path, covs[-1]))
    return out
