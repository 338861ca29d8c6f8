"""Sensor models: a range–bearing landmark sensor and the beam model of a laser range finder.

Range–bearing landmark sensor (Thrun, Burgard & Fox §6.6; Kulich 2014)
-----------------------------------------------------------------------
A landmark ``m = (m_x, m_y)`` seen from the pose ``(x, y, θ)`` gives::

    h(x, m) = ( r, φ ) = ( √q,  wrap(atan2(m_y − y, m_x − x) − θ) ),   q = (m_x − x)² + (m_y − y)²

plus independent noise ``N(0, σ_r²)`` and ``N(0, σ_φ²)``. Its Jacobian with respect to the pose::

    H = [[ −(m_x − x)/√q,  −(m_y − y)/√q,   0 ],
         [  (m_y − y)/q,   −(m_x − x)/q,   −1 ]]

(Kulich 2014 prints the second row over ``√q``: wrong — the bearing's derivative
scales with ``1/r``.) At ``q → 0`` the bearing is undefined; ``q`` is floored at
:data:`MIN_RANGE` squared there. A landmark is seen when ``r ≤ max_range`` and
``|φ| ≤ fov/2``, at the observation instants of the sensor's ``period``.
Correspondences are known (the column of a measurement is the landmark's index)
or found by maximum likelihood (:func:`associate`).

Beam model (Thrun §6.3; Kulich 2014)
------------------------------------
Each beam ``k`` of a scan at relative angle ``β_k`` measures ``z_k`` with, given
the expected range ``z*`` (ray casting on the occupancy grid, :func:`cast_rays`)::

    p(z | z*) = z_hit p_hit + z_short p_short + z_max p_max + z_rand p_rand
    p_hit   = η_hit N(z; z*, σ_hit²)                 on [0, z_max]    (η_hit: the truncated mass)
    p_short = η_short λ_short e^{−λ_short z}         on [0, z*]        (η_short = 1/(1 − e^{−λ_short z*}))
    p_max   = 1 if z = z_max                          (a point mass: beams that return nothing)
    p_rand  = 1/z_max                                 on [0, z_max)

Beams are independent: ``log p(scan) = Σ_k log p(z_k | z*_k)``. The weights
``z_hit + z_short + z_max + z_rand = 1``. When ``z* = 0`` (a pose inside a wall)
``p_short`` is the limit of a uniform density on ``[0, z*]``: 0 for ``z > 0``.
"""

from __future__ import annotations

import itertools
import math
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import wrap_angle
from ..core.validation import (
    check_choice,
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_positive,
    check_positive_int,
)
from .world import OccupancyGrid

__all__ = [
    "MIN_RANGE",
    "BeamSensor",
    "LandmarkLikelihood",
    "RangeBearingSensor",
    "associate",
    "beam_log_likelihood",
    "beam_probability",
    "beam_terms",
    "cast_rays",
    "chunks",
    "expected_ranges",
    "landmark_h",
    "landmark_jacobian",
    "landmark_log_likelihood",
    "landmark_log_likelihood_ml",
    "landmark_visible",
    "run_ahead",
    "run_blocks",
    "sample_beam_measurements",
    "sample_landmark_measurements",
]

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Range [m] below which a landmark's bearing is undefined; q is floored at its square.
MIN_RANGE: float = 1e-9
_LOG_2PI = math.log(2.0 * math.pi)
_TWO_PI = 2.0 * math.pi


def _check_fov(fov: float) -> float:
    f = float(check_positive("fov", fov))
    if f > _TWO_PI + 1e-12:
        raise ValueError(f"fov must be <= 2π (allowed: (0, {_TWO_PI:.6f}] rad), got {f}")
    return min(f, _TWO_PI)


@dataclass(frozen=True)
class RangeBearingSensor:
    """Range–bearing landmark sensor.

    Attributes
    ----------
    range_std : float [m], > 0 — σ_r
    bearing_std : float [rad], > 0 — σ_φ
    max_range : float [m], > 0 — landmarks farther away are not seen
    fov : float [rad], in (0, 2π] — field of view, centred on the heading
    period : float [s], > 0 — time between observations (observation rate 1/period)
    """

    range_std: float = 0.1
    bearing_std: float = 0.05
    max_range: float = 10.0
    fov: float = _TWO_PI
    period: float = 0.1

    def __post_init__(self) -> None:
        for name in ("range_std", "bearing_std", "max_range", "period"):
            object.__setattr__(self, name, float(check_positive(name, getattr(self, name))))
        object.__setattr__(self, "fov", _check_fov(self.fov))

    @property
    def Q(self) -> Array:
        """Measurement covariance ``diag(σ_r², σ_φ²)``, shape (2, 2)."""
        return np.diag([self.range_std**2, self.bearing_std**2])


def _check_landmarks(landmarks: ArrayLike) -> Array:
    lm = check_finite("landmarks", check_last_axis("landmarks", landmarks, 2))
    if lm.ndim != 2:
        raise ValueError(f"landmarks must have shape (L, 2), got shape {lm.shape}")
    return lm


def landmark_h(poses: ArrayLike, landmarks: ArrayLike) -> Array:
    """Noiseless range and bearing of every landmark from every pose.

    Parameters
    ----------
    poses : array_like, shape (..., 3) [m, m, rad]
    landmarks : array_like, shape (L, 2) [m]

    Returns
    -------
    ndarray, shape (..., L, 2) — ``(r [m], φ [rad])``, φ wrapped to (−π, π]
    """
    p = check_last_axis("poses", poses, 3)
    lm = _check_landmarks(landmarks)
    dx = lm[:, 0] - p[..., 0, None]
    dy = lm[:, 1] - p[..., 1, None]
    phi = wrap_angle(np.arctan2(dy, dx) - p[..., 2, None])
    return np.stack([np.hypot(dx, dy), phi], axis=-1)


def landmark_jacobian(poses: ArrayLike, landmarks: ArrayLike) -> Array:
    """Jacobian ``H = ∂h/∂(x, y, θ)`` of :func:`landmark_h`, shape (..., L, 2, 3).

    ``q`` is floored at ``MIN_RANGE²`` (the bearing of a landmark at the robot's own
    position is undefined).
    """
    p = check_last_axis("poses", poses, 3)
    lm = _check_landmarks(landmarks)
    dx = lm[:, 0] - p[..., 0, None]
    dy = lm[:, 1] - p[..., 1, None]
    q = np.maximum(dx * dx + dy * dy, MIN_RANGE**2)
    r = np.sqrt(q)
    zero = np.zeros_like(q)
    row_r = np.stack([-dx / r, -dy / r, zero], axis=-1)
    row_phi = np.stack([dy / q, -dx / q, zero - 1.0], axis=-1)
    return np.stack([row_r, row_phi], axis=-2)


def landmark_visible(poses: ArrayLike, landmarks: ArrayLike, sensor: RangeBearingSensor) -> BoolArray:
    """Whether each landmark is within range and field of view, shape (..., L)."""
    z = landmark_h(poses, landmarks)
    return (z[..., 0] <= sensor.max_range) & (np.abs(z[..., 1]) <= sensor.fov / 2 + 1e-12)


def sample_landmark_measurements(
    poses: ArrayLike, landmarks: ArrayLike, sensor: RangeBearingSensor, rng: np.random.Generator
) -> tuple[Array, BoolArray]:
    """Noisy range–bearing measurements of every landmark from every pose.

    Noise is drawn for every landmark (seen or not), so the random stream does not
    depend on the visibility; the mask says which are seen.

    Returns
    -------
    z : ndarray, shape (..., L, 2) — ``(r, φ)`` with noise, φ wrapped
    visible : ndarray of bool, shape (..., L) — from the true geometry
    """
    z = landmark_h(poses, landmarks)
    vis = (z[..., 0] <= sensor.max_range) & (np.abs(z[..., 1]) <= sensor.fov / 2 + 1e-12)
    noise = rng.standard_normal(z.shape) * np.array([sensor.range_std, sensor.bearing_std])
    out = z + noise
    out[..., 1] = wrap_angle(out[..., 1])
    return out, vis


def _loglik_terms(P: Array, z: Array, lm: Array, inv_var: tuple[float, float], dtype: Any) -> Array:
    """Mahalanobis terms ``(r − r̂)²/σ_r² + wrap(φ − φ̂)²/σ_φ²`` of particles (n, 3) × measurements (m,), shape (n, m)."""
    x = P[:, 0, None].astype(dtype)
    y = P[:, 1, None].astype(dtype)
    th = P[:, 2, None].astype(dtype)  # any magnitude: the error is wrapped below
    dx = lm[None, :, 0].astype(dtype) - x
    dy = lm[None, :, 1].astype(dtype) - y
    e_r = np.hypot(dx, dy)
    e_r -= z[None, :, 0].astype(dtype)  # predicted − measured range
    e_phi = np.arctan2(dy, dx, out=dx)
    e_phi -= th
    e_phi -= z[None, :, 1].astype(dtype)  # wrap by the nearest multiple of 2π
    e_phi -= np.rint(e_phi * dtype(1.0 / _TWO_PI)) * dtype(_TWO_PI)
    e_r *= e_r
    e_r *= dtype(inv_var[0])
    e_phi *= e_phi
    e_phi *= dtype(inv_var[1])
    e_r += e_phi
    return e_r


def _measurement_frames(z: Array, lm: Array, center: Array, dtype: Any) -> tuple[Array, Array]:
    """Per-measurement factors of the landmark position in the frame of the measured bearing, each (m, 4).

    For a particle ``(x, y, θ)`` and a measurement ``(r, φ)`` of landmark ``m``, the vector
    ``d = m − (x, y)`` turned by ``−(θ + φ)`` is ``(X, Y) = A·B_X, A·B_Y`` with the particle's
    factors ``A = (cos θ, sin θ, a, b)``, ``a = x cos θ + y sin θ``, ``b = y cos θ − x sin θ``, and
    ``B_X = (m_x cφ + m_y sφ, m_y cφ − m_x sφ, −cφ, −sφ)``,
    ``B_Y = (m_y cφ − m_x sφ, −(m_x cφ + m_y sφ), sφ, −cφ)`` — positions relative to ``center``
    (translation invariance; it keeps the float32 round-off small).
    """
    mx, my = lm[:, 0] - center[0], lm[:, 1] - center[1]
    c, s = np.cos(z[:, 1]), np.sin(z[:, 1])
    u, v = mx * c + my * s, my * c - mx * s
    B = np.empty((2, z.shape[0], 4), dtype)  # the columns rounded to dtype as they are written
    B[0, :, 0], B[0, :, 1], B[0, :, 2], B[0, :, 3] = u, v, -c, -s
    B[1, :, 0], B[1, :, 1], B[1, :, 2], B[1, :, 3] = v, -u, s, -c
    return B[0], B[1]


def _workspace(n: int, m: int, dtype: Any) -> tuple[Array, Array, Array, Array, Array]:
    """This thread's buffers for a chunk of ``n`` particles and ``m`` measurements.

    A (4, n) and three scratch rows (3, n) in ``dtype``; X, Y, E (m, n) in ``dtype``; two sums (2, n)
    in float64. Reused from call to call (large temporaries allocated at every step cost page
    faults); measurements along the first axis, so the sums over them are ``m − 1`` contiguous vector adds.
    """
    key = (n, m, np.dtype(dtype).str)
    cache = getattr(_WORK, "buffers", None)
    if cache is None or cache[0] != key:
        cache = (key, np.empty((7, n), dtype), np.empty((m, n), dtype), np.empty((m, n), dtype),
                 np.empty((m, n), dtype), np.empty((2, n)))  # fmt: skip
        _WORK.buffers = cache
    return cache[1], cache[2], cache[3], cache[4], cache[5]


def _loglik_chunk(
    P: Array, zr: Array, frames: tuple[Array, Array], center: Array, inv_var: tuple[float, float], const: float,
    dtype: Any, out: Array | None = None,
) -> Array:  # fmt: skip
    """Σ_j log N(z_j; h_j(p), Q) for a chunk of particles (n, 3) and m measurements, shape (n,).

    The landmark seen in the frame of the measured bearing (:func:`_measurement_frames`):
    ``X, Y = B_X·A, B_Y·A`` (two (m, 4)·(4, n) matrix products), so the predicted range is
    ``√(X² + Y²)`` and the bearing error ``atan2(Y, X) = wrap(φ̂ − φ)`` without an explicit
    wrap. ``zr``: the measured ranges (m, 1) in ``dtype``. Every array lives in this thread's
    reused buffers, and the result is written into ``out`` (n,) when given.
    """
    n, m = P.shape[0], zr.shape[0]
    W, X, Y, E, S = _workspace(n, m, dtype)
    A, c, s = W[:4], W[0], W[1]
    th, x, y = W[4], W[5], W[6]
    th[...] = P[:, 2]  # (rounded to dtype)
    np.cos(th, out=c)
    np.sin(th, out=s)
    np.subtract(P[:, 0], center[0], out=x)  # in float64, then rounded to dtype
    np.subtract(P[:, 1], center[1], out=y)
    np.multiply(x, c, out=A[2])
    A[2] += np.multiply(y, s, out=th)  # a = x cos θ + y sin θ
    np.multiply(y, c, out=A[3])
    A[3] -= np.multiply(x, s, out=th)  # b = y cos θ − x sin θ
    np.matmul(frames[0], A, out=X)
    np.matmul(frames[1], A, out=Y)
    np.arctan2(Y, X, out=E)  # φ̂ − φ, in (−π, π]
    X *= X
    Y *= Y
    X += Y
    np.sqrt(X, out=X)
    X -= zr  # predicted − measured range
    X *= X
    E *= E
    # Σ over the measurements: m − 1 vector adds in float64 (no matrix–vector product: OpenBLAS runs
    # those on its own threads, whose spinning then takes the cores from the blocks)
    np.add.reduce(X, axis=0, dtype=np.float64, out=S[0])
    np.add.reduce(E, axis=0, dtype=np.float64, out=S[1])
    S[0] *= inv_var[0]
    S[1] *= inv_var[1]
    S[0] += S[1]
    S[0] *= 0.5
    return np.subtract(const, S[0], out=np.empty(n) if out is None else out)


_WORK = threading.local()


def landmark_log_likelihood_ml(
    particles: ArrayLike, z: ArrayLike, landmarks: ArrayLike, sensor: RangeBearingSensor
) -> tuple[Array, NDArray[np.int64]]:
    """Log-likelihood with unknown correspondences, each hypothesis associating for itself.

    For every particle ``x`` and measurement ``z_i``: ``max_j log p(z_i | x, m_j)`` over all
    landmarks (maximum-likelihood association per hypothesis, Thrun §7.5.2 applied to
    each particle), summed over the measurements.

    Parameters
    ----------
    particles : (n, 3); z : (m, 2); landmarks : (L, 2) — every landmark of the world

    Returns
    -------
    loglik : ndarray, shape (n,)
    index : ndarray of int, shape (n, m) — the landmark each particle attributes each measurement to
    """
    P = check_last_axis("particles", particles, 3).reshape(-1, 3)
    zz = check_finite("z", check_last_axis("z", z, 2)).reshape(-1, 2)
    lm = _check_landmarks(landmarks)
    inv = (1.0 / sensor.range_std**2, 1.0 / sensor.bearing_std**2)
    const = -(_LOG_2PI + math.log(sensor.range_std * sensor.bearing_std))
    out = np.full(P.shape[0], zz.shape[0] * const)
    idx = np.zeros((P.shape[0], zz.shape[0]), dtype=np.int64)
    for i in range(zz.shape[0]):  # one measurement against every landmark
        terms = _loglik_terms(P, np.broadcast_to(zz[i], lm.shape), lm, inv, np.float64)
        idx[:, i] = np.argmin(terms, axis=1)
        out -= 0.5 * terms[np.arange(P.shape[0]), idx[:, i]]
    return out, idx


class LandmarkLikelihood:
    """The measurements of one step, prepared once, evaluated on any block of particles.

    ``LandmarkLikelihood(z, landmarks, sensor, dtype)(P)`` is :func:`landmark_log_likelihood`
    of the particles ``P`` (n, 3); a runner that splits its particles into blocks (threads)
    prepares the measurement frames once per step. :meth:`trusted` skips the checks of the
    inputs (a runner's own measurements, once per step).
    """

    def __init__(self, z: ArrayLike, landmarks: ArrayLike, sensor: RangeBearingSensor, dtype: str = "float64"):
        zz = check_finite("z", check_last_axis("z", z, 2)).reshape(-1, 2)
        lm = _check_landmarks(landmarks)
        if lm.shape != zz.shape:
            raise ValueError(f"landmarks must match z (allowed: shape {zz.shape}), got shape {lm.shape}")
        check_choice("dtype", dtype, ("float64", "float32"))
        self._prepare(zz, lm, sensor, dtype)

    @classmethod
    def trusted(cls, z: Array, landmarks: Array, sensor: RangeBearingSensor, dtype: str) -> LandmarkLikelihood:
        """The same as the constructor for inputs known to be valid: z (m, 2) and landmarks (m, 2)
        finite float64, ``dtype`` one of "float64", "float32"."""
        self = cls.__new__(cls)
        self._prepare(z, landmarks, sensor, dtype)
        return self

    def _prepare(self, z: Array, lm: Array, sensor: RangeBearingSensor, dtype: str) -> None:
        self.z = z
        self.dtype: Any = np.float64 if dtype == "float64" else np.float32
        m = z.shape[0]
        self.inv = (1.0 / sensor.range_std**2, 1.0 / sensor.bearing_std**2)  # of the squared errors
        self.const = -m * (_LOG_2PI + math.log(sensor.range_std * sensor.bearing_std))
        self.center = np.add.reduce(lm, axis=0) / m if m else np.zeros(2)  # the mean
        self.frames = _measurement_frames(z, lm, self.center, self.dtype)
        self.zr: Array = z[:, 0, None].astype(self.dtype)

    def __call__(self, particles: Array, out: Array | None = None) -> Array:
        """``Σ_j log p(z_j | x)`` of each particle (n, 3), shape (n,) (written into ``out`` when given)."""
        if self.z.shape[0] == 0:
            res = np.zeros(particles.shape[0]) if out is None else out
            res[...] = 0.0
            return res
        return _loglik_chunk(particles, self.zr, self.frames, self.center, self.inv, self.const, self.dtype, out)


def landmark_log_likelihood(
    particles: ArrayLike,
    z: ArrayLike,
    landmarks: ArrayLike,
    sensor: RangeBearingSensor,
    *,
    dtype: str = "float64",
    chunk: int | None = None,
    workers: int = 1,
) -> Array:
    """Log-likelihood ``Σ_j log p(z_j | x)`` of measurements of known landmarks, per particle.

    ``log p = −½[(r_j − r̂_j)²/σ_r² + wrap(φ_j − φ̂_j)²/σ_φ² ] − log(2π σ_r σ_φ)`` per measurement.

    Parameters
    ----------
    particles : array_like, shape (n, 3) [m, m, rad]
    z : array_like, shape (m, 2) — measured ``(r, φ)``, only the ones to use
    landmarks : array_like, shape (m, 2) — the landmark of each measurement [m]
    sensor : RangeBearingSensor
    dtype : {"float64", "float32"} — arithmetic of the per-measurement terms
        (float32 is several times faster; its rounding error on a log-likelihood of
        size ``ℓ`` is about ``10⁻⁶·ℓ``); each particle's sum over its measurements is a
        matrix–vector product in ``dtype``, the constant is added in float64
    chunk : int, optional — particles per block (keeps the temporaries in cache); default:
        :func:`chunks` (the fewest equal blocks of at most 8192)
    workers : int — threads over the blocks (numpy releases the GIL); the result does not
        depend on it

    Returns
    -------
    ndarray, shape (n,)
    """
    P = check_last_axis("particles", particles, 3).reshape(-1, 3)
    lik = LandmarkLikelihood(z, landmarks, sensor, dtype)
    n = P.shape[0]
    out = np.empty(n)
    blocks = chunks(n) if chunk is None else [(a, min(n, a + chunk)) for a in range(0, n, check_positive_int("chunk", chunk))]

    def block(c: int) -> None:
        a, b = blocks[c]
        lik(P[a:b], out=out[a:b])

    run_blocks(block, len(blocks), workers)
    return out


def chunks(n: int, size: int | None = None) -> list[tuple[int, int]]:
    """``[(start, stop), ...]``: the fewest equal blocks of at most ``size`` (default 8192) covering ``0 … n``.

    A function of ``n`` only, so a result computed block by block does not depend on the
    number of threads that compute the blocks. (Cut otherwise, the likelihood's matrix
    products round a block's last rows by other kernels: the same numbers to ~10⁻¹⁵ in
    float64, ~10⁻⁷ in float32, not the same bits.)
    """
    size = _CHUNK if size is None else check_positive_int("size", size)
    k = max(1, -(-n // size))
    step = -(-n // k) if n else 1
    return [(a, min(n, a + step)) for a in range(0, n, step)] or [(0, 0)]


def run_blocks(fn: Any, n_blocks: int, workers: int = 1) -> None:
    """Call ``fn(0) … fn(n_blocks − 1)``, each once: with ``workers`` > 1 the calling thread and a
    persistent pool of ``workers − 1`` threads take the blocks in turn (numpy releases the GIL in its
    loops). A block goes to whichever thread is free first, and the caller waits only for blocks
    another thread has taken, so a pool thread that is busy or not yet woken (other jobs on the
    cores) never holds it up; ``fn`` must not depend on the thread. An error of a block is raised here.
    """
    if check_positive_int("workers", workers) == 1 or n_blocks == 1:
        for c in range(n_blocks):
            fn(c)
        return
    claim = itertools.count().__next__  # atomic under the GIL: every block is taken once
    done = threading.Semaphore(0)  # released once per finished block
    errors: list[BaseException] = []

    def take() -> None:
        while (c := claim()) < n_blocks:
            try:
                fn(c)
            except Exception as e:  # noqa: BLE001 - any error of a block is re-raised in the caller
                errors.append(e)
            finally:
                done.release()

    pool = _pool(workers - 1)
    for _ in range(min(workers, n_blocks) - 1):
        pool.submit(take)
    take()
    for _ in range(n_blocks):
        done.acquire()
    if errors:
        raise errors[0]


def run_ahead(fn: Callable[[], Any], workers: int) -> Callable[[], Any]:
    """Start ``fn()`` on the pool of :func:`run_blocks` and return ``finish``, which gives its result.

    ``finish()`` runs ``fn`` in the caller if no pool thread has started it yet (a pool thread the
    system has not woken never holds the caller up), else waits for it; with one worker it just runs
    ``fn``. ``fn`` runs once, and must not depend on the thread.
    """
    if check_positive_int("workers", workers) == 1:
        return fn
    claim = itertools.count().__next__

    def once() -> tuple[bool, Any]:
        return (True, fn()) if claim() == 0 else (False, None)

    future = _pool(workers - 1).submit(once)

    def finish() -> Any:
        ran, value = once()
        return value if ran else future.result()[1]

    return finish


#: Largest block of particles of :func:`chunks`.
_CHUNK = 8192
_POOLS: dict[int, ThreadPoolExecutor] = {}


def _pool(workers: int) -> ThreadPoolExecutor:
    """A persistent thread pool of ``workers`` threads (creating one per call costs more than a small step)."""
    if workers not in _POOLS:
        _POOLS[workers] = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="pose-uncertainty-loglik")
    return _POOLS[workers]


def associate(
    z: ArrayLike, mean: ArrayLike, cov: ArrayLike, landmarks: ArrayLike, sensor: RangeBearingSensor
) -> tuple[NDArray[np.int64], Array]:
    """Maximum-likelihood data association (Thrun Table 7.3): the landmark each measurement saw.

    For measurement ``z_i`` and landmark ``j``: ``ẑ_j = h(μ, m_j)``, ``S_j = H_j Σ H_jᵀ + Q``,
    and ``j(i) = argmax_j N(z_i; ẑ_j, S_j)`` (bearing innovation wrapped).

    Parameters
    ----------
    z : array_like, shape (m, 2); mean : array_like, shape (3,); cov : array_like, shape (3, 3)
    landmarks : array_like, shape (L, 2); sensor : RangeBearingSensor

    Returns
    -------
    index : ndarray of int, shape (m,) — row of ``landmarks`` chosen for each measurement
    log_likelihood : ndarray, shape (m,) — ``log N(z_i; ẑ_j(i), S_j(i))``
    """
    zz = check_finite("z", check_last_axis("z", z, 2)).reshape(-1, 2)
    mu = check_finite("mean", check_last_axis("mean", mean, 3))
    S0 = check_finite("cov", cov)
    lm = _check_landmarks(landmarks)
    zhat = landmark_h(mu, lm)  # (L, 2)
    H = landmark_jacobian(mu, lm)  # (L, 2, 3)
    S = H @ S0 @ np.swapaxes(H, -1, -2) + sensor.Q  # (L, 2, 2)
    nu = zz[:, None, :] - zhat[None, :, :]  # (m, L, 2)
    nu[..., 1] = wrap_angle(nu[..., 1])
    Sinv = np.linalg.inv(S)
    maha = np.einsum("mli,lij,mlj->ml", nu, Sinv, nu)
    ll = -0.5 * (maha + np.log(np.linalg.det(S))[None, :]) - _LOG_2PI
    idx = np.argmax(ll, axis=1)
    return idx.astype(np.int64), ll[np.arange(zz.shape[0]), idx]


# ============================================================================= beams


@dataclass(frozen=True)
class BeamSensor:
    """Laser range finder with the beam model's mixture (Thrun §6.3).

    Attributes
    ----------
    n_beams : int ≥ 1 — beams per scan, spread evenly over ``fov``
    fov : float [rad], in (0, 2π]
    max_range : float [m], > 0 — ``z_max``
    sigma_hit : float [m], > 0 — σ_hit
    lambda_short : float [1/m], > 0 — λ_short
    z_hit, z_short, z_max, z_rand : float ≥ 0, summing to 1 — mixture weights
    period : float [s], > 0 — time between scans
    """

    n_beams: int = 8
    fov: float = _TWO_PI
    max_range: float = 8.0
    sigma_hit: float = 0.1
    lambda_short: float = 0.5
    z_hit: float = 0.8
    z_short: float = 0.1
    z_max: float = 0.05
    z_rand: float = 0.05
    period: float = 0.1

    def __post_init__(self) -> None:
        object.__setattr__(self, "n_beams", check_positive_int("n_beams", self.n_beams))
        object.__setattr__(self, "fov", _check_fov(self.fov))
        for name in ("max_range", "sigma_hit", "lambda_short", "period"):
            object.__setattr__(self, name, float(check_positive(name, getattr(self, name))))
        for name in ("z_hit", "z_short", "z_max", "z_rand"):
            object.__setattr__(self, name, float(check_nonnegative(name, getattr(self, name))))
        total = self.z_hit + self.z_short + self.z_max + self.z_rand
        if abs(total - 1.0) > 1e-9:
            raise ValueError(
                f"z_hit + z_short + z_max + z_rand must be 1 (allowed: weights summing to 1), got {total:.12g}"
            )

    @property
    def angles(self) -> Array:
        """Beam angles relative to the heading, shape (n_beams,) [rad].

        A full circle puts beams at ``−π + 2πk/n``; a narrower fov spreads them from
        ``−fov/2`` to ``+fov/2`` (one beam: straight ahead).
        """
        n = self.n_beams
        if self.fov >= _TWO_PI - 1e-12:
            return -math.pi + _TWO_PI * np.arange(n) / n
        if n == 1:
            return np.zeros(1)
        return np.linspace(-self.fov / 2, self.fov / 2, n)


def _dda_init(grid: OccupancyGrid, ox: Array, oy: Array, ang: Array) -> dict[str, Array]:
    """State of the grid traversal (Amanatides & Woo) of rays in cell units."""
    h = grid.resolution
    u = (ox - grid.origin[0]) / h
    v = (oy - grid.origin[1]) / h
    dx, dy = np.cos(ang), np.sin(ang)
    i, j = np.floor(u), np.floor(v)
    with np.errstate(divide="ignore", invalid="ignore"):  # dx = 0: never crosses an x boundary
        tdx = np.where(dx != 0, 1.0 / np.abs(dx), np.inf)
        tdy = np.where(dy != 0, 1.0 / np.abs(dy), np.inf)
        tx = np.where(dx > 0, (i + 1 - u) * tdx, np.where(dx < 0, (u - i) * tdx, np.inf))
        ty = np.where(dy > 0, (j + 1 - v) * tdy, np.where(dy < 0, (v - j) * tdy, np.inf))
    return {"i": i.astype(np.int64), "j": j.astype(np.int64), "tx": tx, "ty": ty,
            "tdx": tdx, "tdy": tdy, "si": np.where(dx > 0, 1, -1), "sj": np.where(dy > 0, 1, -1),
            "id": np.arange(u.size)}  # fmt: skip


def _dda_status(grid: OccupancyGrid, s: dict[str, Array]) -> tuple[BoolArray, BoolArray]:
    """(hit an occupied cell, left the grid for good) for the rays' current cells."""
    nx, ny = grid.shape
    i, j = s["i"], s["j"]
    inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    occ = grid.occupied.ravel()[np.clip(i, 0, nx - 1) * ny + np.clip(j, 0, ny - 1)]
    away = ((i < 0) & (s["si"] < 0)) | ((i >= nx) & (s["si"] > 0))
    away |= ((j < 0) & (s["sj"] < 0)) | ((j >= ny) & (s["sj"] > 0))
    return inside & occ, ~inside & away


def _traverse(grid: OccupancyGrid, s: dict[str, Array], t_max: float, out: Array) -> None:
    """Traverse the rays of state ``s`` (:func:`_dda_init`), writing the distance [cells] of each ray
    that hits an occupied cell before ``t_max`` into ``out[s["id"]]``."""
    hit, gone = _dda_status(grid, s)
    out[s["id"][hit]] = 0.0
    keep = ~(hit | gone)
    while True:
        s = {k: a[keep] for k, a in s.items()}
        if s["id"].size == 0:
            break
        xs = s["tx"] < s["ty"]
        t = np.where(xs, s["tx"], s["ty"])  # distance at which the ray enters its next cell
        s["i"] = s["i"] + np.where(xs, s["si"], 0)
        s["j"] = s["j"] + np.where(xs, 0, s["sj"])
        s["tx"] = np.where(xs, s["tx"] + s["tdx"], s["tx"])
        s["ty"] = np.where(xs, s["ty"], s["ty"] + s["tdy"])
        hit, gone = _dda_status(grid, s)
        far = t >= t_max
        hit &= ~far
        out[s["id"][hit]] = t[hit]
        keep = ~(hit | gone | far)


def _traverse_from_inside(grid: OccupancyGrid, s: dict[str, Array], t_max: float, out: Array) -> None:
    """:func:`_traverse` for rays that start on the grid, the same distances by fewer operations.

    A ray that starts on the grid leaves it for good at its first cell off the grid (a line leaves
    a rectangle once), which is a cell of the ring around the grid: one look-up in the occupancy
    grid padded with that ring (0 free, 1 occupied, 2 off the grid) tells hit, gone or neither, at
    the flat index of the padded grid that each crossing moves by ``±(ny + 2)`` or ``±1``.
    """
    nx, ny = grid.shape
    padded = np.full((nx + 2, ny + 2), 2, dtype=np.int8)
    padded[1:-1, 1:-1] = grid.occupied
    code = padded.ravel()
    cell = (s["i"] + 1) * (ny + 2) + (s["j"] + 1)
    step_x, step_y = s["si"] * (ny + 2), s["sj"]
    tx, ty, tdx, tdy, ids = s["tx"], s["ty"], s["tdx"], s["tdy"], s["id"]
    c = code[cell]
    out[ids[c == 1]] = 0.0
    keep = c == 0
    while True:
        cell, tx, ty, tdx, tdy, step_x, step_y, ids = (
            cell[keep], tx[keep], ty[keep], tdx[keep], tdy[keep], step_x[keep], step_y[keep], ids[keep])  # fmt: skip
        if ids.size == 0:
            break
        xs = tx < ty
        t = np.where(xs, tx, ty)  # distance at which the ray enters its next cell
        cell = cell + np.where(xs, step_x, step_y)
        tx = np.where(xs, tx + tdx, tx)
        ty = np.where(xs, ty, ty + tdy)
        c = code[cell]
        near = t < t_max
        hit = (c == 1) & near
        out[ids[hit]] = t[hit]
        keep = (c == 0) & near


def cast_rays(grid: OccupancyGrid, origins: ArrayLike, angles: ArrayLike, max_range: float) -> Array:
    """Distance to the first occupied cell along each ray, capped at ``max_range``.

    A grid traversal (Amanatides & Woo) vectorised over all rays: every iteration
    moves each unfinished ray into its next cell; only the loop over those
    crossings remains (at most ``√2·max_range/h + 2`` iterations). A ray starting in
    an occupied cell has range 0; cells off the grid do not stop a ray.

    Parameters
    ----------
    grid : OccupancyGrid
    origins : array_like, shape (R, 2) [m]; angles : array_like, shape (R,) [rad], absolute
    max_range : float [m], > 0

    Returns
    -------
    ndarray, shape (R,) [m]
    """
    o = check_finite("origins", check_last_axis("origins", origins, 2)).reshape(-1, 2)
    ang = check_finite("angles", angles).reshape(-1)
    if ang.shape[0] != o.shape[0]:
        raise ValueError(f"angles must have one value per origin ({o.shape[0]}), got {ang.shape[0]}")
    t_max = float(check_positive("max_range", max_range)) / grid.resolution
    out = np.full(o.shape[0], t_max)
    s = _dda_init(grid, o[:, 0], o[:, 1], ang)
    nx, ny = grid.shape
    inner = (s["i"] >= 0) & (s["i"] < nx) & (s["j"] >= 0) & (s["j"] < ny)
    if inner.all():
        _traverse_from_inside(grid, s, t_max, out)
    else:  # rays that start off the grid may enter it later: the general traversal for them
        _traverse_from_inside(grid, {k: a[inner] for k, a in s.items()}, t_max, out)
        _traverse(grid, {k: a[~inner] for k, a in s.items()}, t_max, out)
    return np.minimum(out, t_max) * grid.resolution


def expected_ranges(grid: OccupancyGrid, poses: ArrayLike, sensor: BeamSensor) -> Array:
    """Expected range ``z*`` of every beam from every pose, shape (..., n_beams) [m]."""
    p = check_last_axis("poses", poses, 3)
    beta = sensor.angles
    ang = p[..., 2, None] + beta
    org = np.broadcast_to(p[..., None, :2], (*ang.shape, 2))
    z = cast_rays(grid, org.reshape(-1, 2), ang.reshape(-1), sensor.max_range)
    return z.reshape(ang.shape)


def beam_terms(z_star: ArrayLike, sensor: BeamSensor) -> tuple[Array, Array]:
    """The parts of :func:`beam_probability` that depend on ``z*`` only: the hit component's
    truncated mass ``max(Φ((z_max − z*)/σ) − Φ(−z*/σ), 10⁻³⁰⁰)`` and the short component's
    ``η = 1/max(1 − e^{−λ z*}, 10⁻³⁰⁰)`` (a fixed table of ``z*``, as the histogram filter's, computes them once).
    """
    zs = check_nonnegative("z_star", z_star)
    from scipy.special import ndtr  # imported where used: scipy.special takes 0.2 s to import

    zm, sh = sensor.max_range, sensor.sigma_hit
    mass = np.maximum(ndtr((zm - zs) / sh) - ndtr(-zs / sh), 1e-300)
    eta = 1.0 / np.maximum(-np.expm1(-sensor.lambda_short * zs), 1e-300)
    return mass, eta


def beam_probability(
    z: ArrayLike, z_star: ArrayLike, sensor: BeamSensor, terms: tuple[Array, Array] | None = None
) -> Array:
    """Beam-model density ``p(z | z*)`` per beam (mixture above), broadcast shape.

    ``z`` equal to ``max_range`` (to 10⁻⁹ m) is the max reading and gets the point
    mass ``z_max``; readings are otherwise in ``[0, max_range)``. ``terms``: :func:`beam_terms`
    of ``z_star`` when already computed (the same result).
    """
    zz = check_finite("z", z)
    zs = check_nonnegative("z_star", z_star)
    zm, sh = sensor.max_range, sensor.sigma_hit
    in_range = (zz >= 0) & (zz < zm - 1e-9)
    is_max = np.abs(zz - zm) <= 1e-9
    # p_hit: normal truncated to [0, z_max]; p_short: exponential truncated to [0, z*],
    # η = 1/(1 − e^{−λ z*}); z* = 0 → 0 for z > 0
    mass, eta = beam_terms(zs, sensor) if terms is None else terms
    g = np.exp(-0.5 * ((zz - zs) / sh) ** 2) / (sh * math.sqrt(2 * math.pi))
    p_hit = np.where((zz >= 0) & (zz <= zm), g / mass, 0.0)
    lam = sensor.lambda_short
    p_short = np.where((zz >= 0) & (zz <= zs) & (zs > 0), eta * lam * np.exp(-lam * zz), 0.0)
    p_rand = np.where(in_range, 1.0 / zm, 0.0)
    return (sensor.z_hit * p_hit + sensor.z_short * p_short
            + sensor.z_max * is_max + sensor.z_rand * p_rand)  # fmt: skip


def beam_log_likelihood(
    particles: ArrayLike, z: ArrayLike, grid: OccupancyGrid, sensor: BeamSensor
) -> Array:
    """``Σ_k log p(z_k | z*_k(x))`` of one scan for every particle (rays cast per particle).

    Parameters
    ----------
    particles : array_like, shape (n, 3); z : array_like, shape (n_beams,) [m]

    Returns
    -------
    ndarray, shape (n,) — ``−inf`` where a beam has probability 0
    """
    zz = check_finite("z", z)
    if zz.shape != (sensor.n_beams,):
        raise ValueError(f"z must have shape ({sensor.n_beams},) (one range per beam), got {zz.shape}")
    zs = expected_ranges(grid, particles, sensor)
    with np.errstate(divide="ignore"):
        return np.asarray(np.log(beam_probability(zz, zs, sensor)).sum(axis=-1))


def sample_beam_measurements(z_star: ArrayLike, sensor: BeamSensor, rng: np.random.Generator) -> Array:
    """Draw scans from the beam model given expected ranges ``z*`` (any shape), exactly.

    Each beam picks a component with the mixture weights, then: hit — the normal
    truncated to ``[0, z_max]`` by inverse CDF; short — the exponential truncated to
    ``[0, z*]`` by inverse CDF; max — ``z_max``; rand — uniform on ``[0, z_max)``.
    """
    zs = check_nonnegative("z_star", z_star)
    zm, sh, lam = sensor.max_range, sensor.sigma_hit, sensor.lambda_short
    w = np.array([sensor.z_hit, sensor.z_short, sensor.z_max, sensor.z_rand])
    comp = np.searchsorted(np.cumsum(w), rng.random(zs.shape) * w.sum(), side="right")
    comp = np.minimum(comp, 3)
    u = rng.random(zs.shape)
    from scipy.special import ndtr, ndtri  # imported where used (0.2 s)

    lo, hi = ndtr(-zs / sh), ndtr((zm - zs) / sh)
    hit = zs + sh * ndtri(np.clip(lo + u * (hi - lo), 1e-300, 1 - 1e-16))
    short = -np.log1p(-u * -np.expm1(-lam * zs)) / lam  # inverse CDF on [0, z*]
    rand = u * zm
    out = np.select([comp == 0, comp == 1, comp == 2], [np.clip(hit, 0.0, zm), short, np.full_like(zs, zm)], rand)
    return np.asarray(out)
