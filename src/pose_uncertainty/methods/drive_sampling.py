"""Monte Carlo for every drive: noisy executions of a drive's path in both error regimes.

Each particle's measurements are the path's plus errors drawn by
:func:`.drive_noise.sample_errors` (``per_step`` or ``per_run``, biases
included, the skid-steer's ICR drawn too); its twists ``ξ(u + δu)`` are
integrated by :func:`~pose_uncertainty.core.kinematics.integrate_twist`. The
particles run in the chunks of :func:`.sampling.chunk_streams` (one random
stream per chunk), so a seed gives bit-identical clouds for any number of
threads, and for the differential drive with ``k`` only the draws are those
of :func:`.sampling.sample_end_poses`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import DrivePath, SkidSteer
from ..core.kinematics import METHODS, integrate_twist
from ..core.threads import default_workers
from ..core.validation import check_choice, check_positive_int
from . import drive_noise as dn
from .sampling import REGIMES, chunk_streams, start_factor

__all__ = ["sample_poses"]


def _check_checkpoints(checkpoints: Sequence[int] | None, n_steps: int) -> list[int] | None:
    if checkpoints is None:
        return None
    cps = [int(c) for c in checkpoints]
    if not cps or min(cps) < 0 or max(cps) > n_steps:
        raise ValueError(
            f"checkpoints must be step indices in [0, {n_steps}], got {list(checkpoints)}"
        )
    return cps


def _particle_poses(
    path: DrivePath,
    errors: dn.SampledErrors,
    start: NDArray[np.float64],
    method: str,
    cps: list[int],
) -> NDArray[np.float64]:
    """Poses (m, C, 3) at the checkpoints of particles with the given errors."""
    u = path.u + errors.du
    drive = path.drive
    if errors.chi is not None and errors.x_icr is not None and isinstance(drive, SkidSteer):
        xi = drive.twist_icr(u, errors.chi, errors.x_icr)
    else:
        xi = drive.twist(u)
    return integrate_twist(xi, start, method)[:, cps, :]  # type: ignore[arg-type]


def sample_poses(
    path: DrivePath,
    model: dn.DriveErrorModel,
    n: int,
    rng: np.random.Generator,
    *,
    regime: str = "per_step",
    method: str = "midpoint",
    checkpoints: Sequence[int] | None = None,
    cov0: ArrayLike | None = None,
    workers: int | None = None,
) -> NDArray[np.float64]:
    """Noisy executions of a drive's path: the Monte Carlo ground truth of its error model.

    Parameters
    ----------
    path : DrivePath — the drive and its nominal (reported) measurements
    model : DriveErrorModel
    n : int ≥ 1 — particles
    rng : numpy.random.Generator — the only source of randomness (streams
        spawned from its seed sequence, one per chunk of particles)
    regime : {"per_step", "per_run"} — see :mod:`.drive_noise`
    method : {"exact", "euler", "euler_end", "midpoint"} — integration of each step
    checkpoints : sequence of int in [0, N], optional — step indices to keep
    cov0 : array_like, shape (3, 3), optional — start-pose covariance; each
        particle starts at a draw from N(path.start, cov0)
    workers : int, optional — threads (default: the cores, at most 8); the
        output does not depend on it

    Returns
    -------
    ndarray, shape (n, 3) — end poses; with ``checkpoints`` (n, C, 3). Headings unwrapped.
    """
    n = check_positive_int("n", n)
    check_choice("regime", regime, REGIMES)
    check_choice("method", method, METHODS)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    dn.channels(path.drive, model)  # validate the model against the drive before drawing
    n_workers = default_workers() if workers is None else check_positive_int("workers", workers)
    N = path.n_steps
    cps = _check_checkpoints(checkpoints, N)
    start_sqrt = start_factor(cov0)
    chunk, starts, children = chunk_streams(rng, n, N)
    out = np.empty((n, 1 if cps is None else len(cps), 3))

    def run_chunk(j: int) -> None:
        lo = starts[j]
        m = min(chunk, n - lo)
        g = children[j]
        errors = dn.sample_errors(path.drive, path.u, path.dt, model, m, g, regime)
        start = path.start[None, :]
        if start_sqrt is not None:
            start = start + g.standard_normal((m, 3)) @ start_sqrt.T
        out[lo : lo + m] = _particle_poses(path, errors, start, method, [N] if cps is None else cps)

    _map_chunks(run_chunk, len(starts), n_workers)
    return out[:, 0, :] if cps is None else out


def _map_chunks(run_chunk: Callable[[int], None], n_chunks: int, workers: int) -> None:
    """Run every chunk, on ``workers`` threads (each chunk writes its own rows)."""
    if workers == 1 or n_chunks == 1:
        for j in range(n_chunks):
            run_chunk(j)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(run_chunk, range(n_chunks)))
