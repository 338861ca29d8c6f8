"""What every Monte Carlo sampler shares: the error regimes, chunks of particles with their
random streams, the start-pose factor, and the integration of particles' wheel travels.

Particles are processed in chunks of a fixed size (a function of the number of
steps only), each chunk with its own random stream spawned from the caller's
generator, so the same seed gives bit-identical output on any machine and for
any number of threads (:func:`chunk_streams`).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import differential_twist
from ..core.kinematics import integrate_twist
from ..core.validation import check_finite

__all__ = ["REGIMES", "DrawCache", "chunk_streams", "integrate_end", "start_factor"]

#: The two regimes of odometry error (:mod:`.sampling`, :mod:`.drive_noise`): fresh errors
#: every step (non-systematic), or one draw per run kept for the whole run (systematic).
REGIMES: tuple[str, ...] = ("per_step", "per_run")

#: elements per chunk array: large enough for vectorisation, small enough for cache
CHUNK_ELEMENTS = 1 << 16


class DrawCache:
    """Standard normals drawn from the chunks' random streams, kept for the next run of the same seed.

    The Monte Carlo's normals depend on the seed, the number of particles and the steps
    only, not on the error constants, the track or the path's shape: a run that differs from
    the last in those alone (the explorer's move of a slider) draws exactly the normals it
    drew. :meth:`normals` returns what ``g.standard_normal(shape)`` would, and leaves ``g``
    where that draw would have left it, so every later draw from ``g`` is unchanged: the
    output with a cache is the output without it, bit for bit. Entries are keyed by the
    stream's full state and the shape; the least recently used go first beyond
    ``max_bytes``, and a block larger than that is not kept. Thread-safe.

    Parameters
    ----------
    max_bytes : int — memory the kept normals may take (default 256 MiB)
    """

    def __init__(self, max_bytes: int = 256 << 20) -> None:
        self.max_bytes = int(max_bytes)
        self._kept: OrderedDict[tuple[object, ...], tuple[NDArray[np.float64], Mapping[str, Any]]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    def normals(self, g: np.random.Generator, shape: tuple[int, ...]) -> NDArray[np.float64]:
        """``g.standard_normal(shape)`` (a kept copy when this state drew it before; do not write to it)."""
        state = g.bit_generator.state
        key = (tuple(int(d) for d in shape), _state_key(state))
        with self._lock:
            got = self._kept.get(key)
            if got is not None:
                self._kept.move_to_end(key)
        if got is not None:
            g.bit_generator.state = got[1]
            return got[0]
        z = g.standard_normal(shape)
        if z.nbytes <= self.max_bytes:
            with self._lock:
                self._kept[key] = (z, g.bit_generator.state)
                self._bytes += z.nbytes
                while self._bytes > self.max_bytes:
                    _, (old, _) = self._kept.popitem(last=False)
                    self._bytes -= old.nbytes
        return z


def _state_key(state: object) -> object:
    """A hashable copy of a bit generator's state (its arrays as bytes)."""
    if isinstance(state, dict):
        return tuple((k, _state_key(v)) for k, v in sorted(state.items()))
    if isinstance(state, np.ndarray):
        return (state.dtype.str, state.shape, state.tobytes())
    return state


def start_factor(cov0: ArrayLike | None) -> NDArray[np.float64] | None:
    """``A`` with ``A Aᵀ = Σ_0`` for a start-pose covariance (3, 3), singular allowed; None for None.

    From the eigen-decomposition ``Σ_0 = V diag(w) Vᵀ``: ``A = V diag(√w)``. A
    particle's start offset is ``A z``, ``z ~ N(0, I)``.
    """
    if cov0 is None:
        return None
    S0 = check_finite("cov0", cov0)
    if S0.shape != (3, 3) or not np.allclose(S0, S0.T):
        raise ValueError(f"cov0 must be a symmetric 3x3 matrix, got shape {S0.shape}")
    w, V = np.linalg.eigh(S0)
    if w.min() < -1e-12 * max(1.0, float(np.abs(S0).max())):
        raise ValueError(
            f"cov0 must be positive semi-definite (allowed: eigenvalues >= 0), got {w.tolist()}"
        )
    return V * np.sqrt(np.maximum(w, 0.0))  # A with A Aᵀ = Σ_0 (singular allowed)


def chunk_streams(
    rng: np.random.Generator, n: int, n_steps: int
) -> tuple[int, list[int], list[np.random.Generator]]:
    """Chunks of particles and one random stream per chunk.

    The chunk size is a function of the number of steps only; one SFC64 stream
    per chunk (the fastest of numpy's bit generators here) is spawned from the
    caller's generator, so the draws are fixed by the seed and independent of
    the number of threads.

    Returns
    -------
    chunk : int — particles per chunk; starts : list of int — first particle of
    each chunk; children : list of numpy.random.Generator — one per chunk
    """
    chunk = max(1, CHUNK_ELEMENTS // n_steps)
    starts = list(range(0, n, chunk))
    seq = rng.bit_generator.seed_seq
    if not isinstance(seq, np.random.SeedSequence):
        raise TypeError("rng must be seeded from a SeedSequence (e.g. numpy.random.default_rng(seed))")
    children = [np.random.Generator(np.random.SFC64(s)) for s in seq.spawn(len(starts))]
    return chunk, starts, children


def integrate_end(
    ds_r: NDArray[np.float64],
    ds_l: NDArray[np.float64],
    track: float,
    start: ArrayLike = (0.0, 0.0, 0.0),
    method: str = "midpoint",
    checkpoints: Sequence[int] | None = None,
) -> NDArray[np.float64]:
    """Integrate a batch of noisy wheel-travel sequences, keeping only chosen poses.

    The differential drive's twists (:func:`~pose_uncertainty.core.drives.differential_twist`)
    integrated by :func:`~pose_uncertainty.core.kinematics.integrate_twist`.

    Parameters
    ----------
    ds_r, ds_l : ndarray, shape (n, N) — per-particle, per-step wheel travels [m]
    track : float [m]
    start : array_like, shape (3,) or (n, 3) — one start pose, or one per particle
    method : {"exact", "euler", "euler_end", "midpoint"}
    checkpoints : sequence of int in [0, N], optional — step indices to return;
        default only the end (index N)

    Returns
    -------
    ndarray, shape (n, C, 3) — poses at the checkpoints (C = 1 for the end only)
    """
    poses = integrate_twist(differential_twist(ds_r, ds_l, track), start, method)  # type: ignore[arg-type]
    if checkpoints is None:
        return poses[..., -1:, :]
    return poses[..., np.asarray(checkpoints, dtype=np.intp), :]
