"""Monte Carlo under the wheel-noise model of the covariance method (Němec 2012 §2.1.2).

Two named regimes of odometry error:

``"per_step"`` (non-systematic, random walk)
    every step, each wheel's travel is drawn independently:
    ``Δs_r' ~ N(Δs_r, k_r|Δs_r|)``, ``Δs_l' ~ N(Δs_l, k_l|Δs_l|)`` — exactly the
    model Method A linearises; the variance of a wheel's total travel grows
    linearly with distance.

``"per_run"`` (systematic)
    one error is drawn per run and per wheel and kept for the whole run, as a
    scale error of the wheel (a wrong wheel radius): ``Δs_r' = Δs_r (1 + ε_r)``,
    ``ε_r ~ N(0, k_r / L_r)`` with ``L_r = Σ|Δs_r|`` the wheel's total travel, so
    that at the end of the run the total travel has the same variance
    ``k_r L_r`` as in the per-step regime; along the way it grows with the
    square of distance, and the end-pose cloud bends into a banana.

The differential drive is one drive among the others: :func:`sample_end_poses` is the
front door that runs the trajectory's wheel travels (:func:`~pose_uncertainty.core.drives.wheel_path`)
with the error model ``k = (k_r, k_l)`` through the Monte Carlo of every drive
(:func:`.drive_sampling.sample_poses`: chunks of particles with one random stream each, or
for the compiled kernel blocks of particles with one stream each, so the same seed gives
bit-identical output on any machine and for any number of threads; the end poses as the
nominal path plus a small heading perturbation).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import wheel_path
from ..core.trajectories import Trajectory
from ..core.validation import check_nonnegative
from .drive_noise import DriveErrorModel
from .drive_sampling import sample_poses
from .particles import REGIMES, DrawCache, chunk_streams, integrate_end, start_factor

__all__ = ["REGIMES", "DrawCache", "chunk_streams", "integrate_end", "sample_end_poses", "start_factor"]


def sample_end_poses(
    trajectory: Trajectory,
    k_r: float,
    k_l: float,
    n: int,
    rng: np.random.Generator,
    *,
    regime: str = "per_step",
    method: str = "midpoint",
    checkpoints: Sequence[int] | None = None,
    cov0: ArrayLike | None = None,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    kernel: str = "auto",
    draws: str = "auto",
    cache: DrawCache | None = None,
) -> NDArray[np.float64]:
    """Noisy executions of a trajectory: the Monte Carlo ground truth of Method A's model.

    The front door of :func:`.drive_sampling.sample_poses` for the differential drive of
    the trajectory's wheel travels with ``DriveErrorModel(k=(k_r, k_l))``.

    Parameters
    ----------
    trajectory : Trajectory
    k_r, k_l : float [m] — error constants, ≥ 0 (wheel-travel variance per metre)
    n : int ≥ 1 — number of particles
    rng : numpy.random.Generator — the only source of randomness: one SFC64
        stream per chunk of particles (or per block, ``draws``) is spawned from its seed sequence
    regime : {"per_step", "per_run"} — see the module docstring
    method : {"exact", "euler", "euler_end", "midpoint"} — integration of each step
    checkpoints : sequence of int in [0, N], optional — step indices at which
        to keep the cloud as well
    cov0 : array_like, shape (3, 3), optional — covariance of the start pose
        [m², m·rad, rad²]; each particle's start is drawn from
        N(trajectory.start, cov0) (default: every particle starts exactly there)
    workers : int, optional — threads (default: the number of cores, at most 8).
        The output does not depend on it.
    progress : callable, optional — ``progress(done, n)`` with the particles done so
        far, called from the calling thread after each chunk (default None: nothing)
    kernel : {"auto", "numpy", "compiled"} — the end poses by numpy (the reference) or by the
        compiled loop of :mod:`.mc_kernel` (on the same draws, equal up to rounding); ``"auto"``
        (default): compiled from :data:`.mc_kernel.MIN_PARTICLE_STEPS` particle-steps
    draws : {"auto", "per-chunk", "per-block"} — the normals drawn by numpy per chunk of particles,
        or per block of :data:`.mc_kernel.DRAW_BLOCK` particles from the block's own stream (inside
        the compiled kernel; the numpy kernel takes the same numbers from numpy); ``"auto"``
        (default): per block where the compiled kernel runs and no ``cache`` is given, else per
        chunk (:func:`.drive_sampling.sample_poses`)
    cache : DrawCache, optional — the standard normals kept for the next call with
        the same seed (:class:`.particles.DrawCache`; the output does not depend on it); per-chunk
        draws only (``draws="auto"`` is then per chunk, ``"per-block"`` an error)

    Returns
    -------
    ndarray, shape (n, 3) — end poses; or, with ``checkpoints``, shape
    (n, C, 3) — poses at the checkpoints. Headings are unwrapped.
    """
    kr = float(check_nonnegative("k_r", k_r))
    kl = float(check_nonnegative("k_l", k_l))
    return sample_poses(
        wheel_path(trajectory), DriveErrorModel(k=(kr, kl)), n, rng, regime=regime, method=method,
        checkpoints=checkpoints, cov0=cov0, workers=workers, progress=progress, kernel=kernel,
        draws=draws, cache=cache,
    )  # fmt: skip
