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

Particles are processed in chunks of a fixed size (a function of the number of
steps only), each chunk with its own random stream spawned from the caller's
generator, so the same seed gives bit-identical output on any machine and for
any number of threads.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import METHODS, _translation
from ..core.threads import default_workers
from ..core.trajectories import Trajectory
from ..core.validation import check_choice, check_finite, check_nonnegative, check_positive_int

__all__ = ["REGIMES", "chunk_streams", "integrate_end", "sample_end_poses", "start_factor"]

REGIMES: tuple[str, ...] = ("per_step", "per_run")

#: elements per chunk array: large enough for vectorisation, small enough for cache
_CHUNK_ELEMENTS = 1 << 16


def integrate_end(
    ds_r: NDArray[np.float64],
    ds_l: NDArray[np.float64],
    track: float,
    start: ArrayLike = (0.0, 0.0, 0.0),
    method: str = "midpoint",
    checkpoints: Sequence[int] | None = None,
) -> NDArray[np.float64]:
    """Integrate a batch of noisy wheel-travel sequences, keeping only chosen poses.

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
    p0 = np.asarray(start, dtype=np.float64)[..., None, :]  # (1, 3) or (n, 1, 3)
    p0 = p0 if p0.ndim == 3 else p0[None]
    x0, y0, th0 = p0[..., 0], p0[..., 1], p0[..., 2]  # each (1 or n, 1)
    ds = (ds_r + ds_l) * 0.5
    dth = (ds_r - ds_l) / track
    theta = np.cumsum(dth, axis=-1)
    theta_before = np.empty_like(theta)
    theta_before[..., 0] = 0.0
    theta_before[..., 1:] = theta[..., :-1]
    theta_before += th0
    dx, dy = _translation(theta_before, ds, dth, method)
    if checkpoints is None:
        return np.stack(
            [
                x0[:, 0] + dx.sum(axis=-1),
                y0[:, 0] + dy.sum(axis=-1),
                th0[:, 0] + theta[..., -1],
            ],
            axis=-1,
        )[:, None, :]
    idx = np.asarray(checkpoints, dtype=np.intp)
    cx = np.concatenate([np.zeros((*ds.shape[:-1], 1)), np.cumsum(dx, axis=-1)], axis=-1)
    cy = np.concatenate([np.zeros((*ds.shape[:-1], 1)), np.cumsum(dy, axis=-1)], axis=-1)
    ct = np.concatenate([np.zeros((*ds.shape[:-1], 1)), theta], axis=-1)
    return np.stack([x0 + cx[:, idx], y0 + cy[:, idx], th0 + ct[:, idx]], axis=-1)


_HEADING_OFFSET = {"exact": 0.5, "midpoint": 0.5, "euler": 0.0, "euler_end": 1.0}


def _end_poses_perturbed(
    trajectory: Trajectory,
    noise_r: NDArray[np.float64],
    noise_l: NDArray[np.float64],
    method: str,
    start_offset: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """End poses from wheel-travel perturbations, as nominal path + small heading perturbation.

    With per-step perturbations ``(n_r, n_l)`` of shape (m, N), the heading
    noise of step i is ``e_i = (n_r − n_l)/b`` and the particle's step heading is
    ``φ_i = φ̄_i + δ_i``, with ``φ̄_i`` the nominal one and
    ``δ_i = Σ_{j<i} e_j + c·e_i`` (c = ½ midpoint/exact, 0 Euler, 1 Euler-end).
    Then ``x = x₀ + Σ Δs'_i (cos φ̄_i cos δ_i − sin φ̄_i sin δ_i)`` (likewise y):
    the trigonometry of the particles is on the small δ only and the sums are
    matrix–vector products. Same arithmetic as :func:`integrate_end` up to
    rounding. ``start_offset`` (m, 3), optional, moves each particle's start
    pose; its heading offset joins δ. Returns shape (m, 3).
    """
    c = _HEADING_OFFSET[method]
    b = trajectory.track
    ds_nom, dth_nom = trajectory.ds, trajectory.dtheta
    th_before = trajectory.start[2] + np.concatenate([[0.0], np.cumsum(dth_nom)[:-1]])
    phi_nom = th_before + c * dth_nom
    cos_nom, sin_nom = np.cos(phi_nom), np.sin(phi_nom)
    ds = noise_r + noise_l
    ds *= 0.5
    ds += ds_nom  # Δs' per particle and step
    e = noise_r  # reuse the buffer: heading noise per step
    e -= noise_l
    e /= b
    heading_noise_end = e.sum(axis=-1)
    delta = np.cumsum(e, axis=-1, out=noise_l)  # Σ_{j<=i} e_j
    if c != 1.0:
        e *= 1.0 - c
        delta -= e  # Σ_{j<i} e_j + c e_i
        e /= 1.0 - c
    if start_offset is not None:
        delta += start_offset[:, 2:3]
        heading_noise_end += start_offset[:, 2]
    if method == "exact":
        # Δs' · sin(Δθ'/2)/(Δθ'/2), Δθ' = Δθ̄ + e
        e += dth_nom
        e *= 1.0 / (2.0 * np.pi)
        ds *= np.sinc(e)
    np.cos(delta, out=e)
    e *= ds  # u = Δs' cos δ
    np.sin(delta, out=delta)
    delta *= ds  # v = Δs' sin δ
    x = e @ cos_nom - delta @ sin_nom
    y = e @ sin_nom + delta @ cos_nom
    x0, y0, th0 = trajectory.start
    if start_offset is not None:
        x += start_offset[:, 0]
        y += start_offset[:, 1]
    th_end = th0 + dth_nom.sum() + heading_noise_end
    return np.stack([x0 + x, y0 + y, th_end], axis=-1)


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
    chunk = max(1, _CHUNK_ELEMENTS // n_steps)
    starts = list(range(0, n, chunk))
    seq = rng.bit_generator.seed_seq
    if not isinstance(seq, np.random.SeedSequence):
        raise TypeError("rng must be seeded from a SeedSequence (e.g. numpy.random.default_rng(seed))")
    children = [np.random.Generator(np.random.SFC64(s)) for s in seq.spawn(len(starts))]
    return chunk, starts, children


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
) -> NDArray[np.float64]:
    """Noisy executions of a trajectory: the Monte Carlo ground truth of Method A's model.

    Parameters
    ----------
    trajectory : Trajectory
    k_r, k_l : float [m] — error constants, ≥ 0 (wheel-travel variance per metre)
    n : int ≥ 1 — number of particles
    rng : numpy.random.Generator — the only source of randomness: one SFC64
        stream per chunk of particles is spawned from its seed sequence
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

    Returns
    -------
    ndarray, shape (n, 3) — end poses; or, with ``checkpoints``, shape
    (n, C, 3) — poses at the checkpoints. Headings are unwrapped.
    """
    kr = float(check_nonnegative("k_r", k_r))
    kl = float(check_nonnegative("k_l", k_l))
    n = check_positive_int("n", n)
    check_choice("regime", regime, REGIMES)
    check_choice("method", method, METHODS)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    n_workers = default_workers() if workers is None else check_positive_int("workers", workers)
    N = trajectory.n_steps
    if checkpoints is not None:
        cps = [int(c) for c in checkpoints]
        if not cps or min(cps) < 0 or max(cps) > N:
            raise ValueError(f"checkpoints must be step indices in [0, {N}], got {list(checkpoints)}")
    start_sqrt = start_factor(cov0)
    chunk, starts, children = chunk_streams(rng, n, N)
    n_out = 1 if checkpoints is None else len(checkpoints)
    out = np.empty((n, n_out, 3))
    wheel_std = _wheel_noise_std(trajectory, kr, kl, regime)

    def run_chunk(j: int) -> None:
        lo = starts[j]
        m = min(chunk, n - lo)
        out[lo : lo + m] = _sample_chunk(
            trajectory, children[j], m, regime, wheel_std, start_sqrt, method, checkpoints
        )

    if n_workers == 1 or len(starts) == 1:
        for j in range(len(starts)):
            run_chunk(j)
            if progress is not None:
                progress(min(n, starts[j] + chunk), n)
    else:
        with ThreadPoolExecutor(max_workers=n_workers) as pool:
            for j, _ in enumerate(pool.map(run_chunk, range(len(starts)))):
                if progress is not None:
                    progress(min(n, starts[j] + chunk), n)
    return out[:, 0, :] if checkpoints is None else out


def _wheel_noise_std(
    trajectory: Trajectory, kr: float, kl: float, regime: str
) -> tuple[NDArray[np.float64] | float, NDArray[np.float64] | float]:
    """Standard deviations of the wheels' errors (right, left).

    ``per_step``: of each step's travel [m], shape (N,) each; ``per_run``: of the
    relative scale error ``ε`` [-], scalars (0 for a wheel that does not move).
    """
    ds_r, ds_l = trajectory.ds_r, trajectory.ds_l
    if regime == "per_step":
        # Δs' ~ N(Δs, k|Δs|)
        return np.sqrt(kr * np.abs(ds_r)), np.sqrt(kl * np.abs(ds_l))
    # Δs' = Δs (1 + ε), ε ~ N(0, k/L): total-travel variance k·L at the end of the run
    L_r, L_l = trajectory.wheel_travel
    eps_std_r = np.sqrt(kr / L_r) if L_r > 0 else 0.0
    eps_std_l = np.sqrt(kl / L_l) if L_l > 0 else 0.0
    return eps_std_r, eps_std_l


def _sample_chunk(
    trajectory: Trajectory,
    g: np.random.Generator,
    m: int,
    regime: str,
    wheel_std: tuple[NDArray[np.float64] | float, NDArray[np.float64] | float],
    start_sqrt: NDArray[np.float64] | None,
    method: str,
    checkpoints: Sequence[int] | None,
) -> NDArray[np.float64]:
    """Poses of ``m`` particles drawn from the chunk's stream ``g``, shape (m, C, 3) (C = 1: end).

    Draws, in this order: the wheel errors (2, m, N) per step or (2, m, 1) per
    run (standard normal, scaled by :func:`_wheel_noise_std`), then the start
    offsets (m, 3) when ``start_sqrt`` is given.
    """
    ds_r, ds_l = trajectory.ds_r, trajectory.ds_l
    std_r, std_l = wheel_std
    z = g.standard_normal((2, m, trajectory.n_steps) if regime == "per_step" else (2, m, 1))
    if regime == "per_step":
        z[0] *= std_r  # Δs_r' − Δs_r ~ N(0, k_r|Δs_r|)
        z[1] *= std_l
        noise_r, noise_l = z[0], z[1]
    else:
        noise_r = (std_r * z[0]) * ds_r  # Δs_r' − Δs_r = ε_r Δs_r
        noise_l = (std_l * z[1]) * ds_l
    offset = None if start_sqrt is None else g.standard_normal((m, 3)) @ start_sqrt.T
    if checkpoints is None:
        return _end_poses_perturbed(trajectory, noise_r, noise_l, method, offset)[:, None, :]
    start = np.asarray(trajectory.start, dtype=np.float64)
    starts_ = start if offset is None else start + offset
    return integrate_end(
        ds_r + noise_r, ds_l + noise_l, trajectory.track, starts_, method, checkpoints
    )
