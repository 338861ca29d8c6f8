"""Monte Carlo for every drive: noisy executions of a drive's path in both error regimes.

Each particle's measurements are the path's plus errors drawn by
:func:`.drive_noise.sample_errors` (``per_step`` or ``per_run``, biases
included, the skid-steer's ICR drawn too). The particles run in the chunks of
:func:`.particles.chunk_streams` (one random stream per chunk), so a seed gives
bit-identical clouds for any number of threads. For the differential drive with the travel
noise ``k`` the normals may instead come per block of particles, each block from its own
stream (``draws="per-block"``, :mod:`.mc_kernel`: drawn inside the compiled kernel), equally
fixed by the seed. The differential drive of a trajectory's wheel travels is one drive among
the others: :func:`.sampling.sample_end_poses` is its front door.

End poses: the nominal path plus a small heading perturbation
--------------------------------------------------------------
For the end poses only (no checkpoints) the particles are not integrated one by one.
A particle's twist in step ``i`` is the nominal ``ξ̄_i = (v̄₁, v̄₂, Δθ̄)`` plus
``δξ_i = ξ(u + δu) − ξ(u)`` (:meth:`~pose_uncertainty.core.drives.Drive.twist_perturbation`,
computed in place for a drive linear in ``u``). Its heading error ``e_i = δΔθ_i`` makes
the step heading ``φ_i = φ̄_i + δ_i`` with the nominal ``φ̄_i`` and
``δ_i = Σ_{j<i} e_j + c·e_i`` (c = ½ midpoint/exact, 0 Euler, 1 Euler-end), so with
``(a, b) = s'·(v̄₁ + δv₁, v̄₂ + δv₂)`` (``s' = sin(Δθ'/2)/(Δθ'/2)`` exact, 1 otherwise)::

    x = x₀ + Σ_i [cos φ̄_i (a cos δ − b sin δ) − sin φ̄_i (a sin δ + b cos δ)]_i     (y likewise)

the trigonometry of the particles is on the small ``δ`` only and the sums over the steps
are matrix–vector products: the same arithmetic as integrating ``ξ(u + δu)`` up to rounding.
With checkpoints, the particles' twists are integrated by
:func:`~pose_uncertainty.core.kinematics.integrate_twist`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import Differential, DrivePath, SkidSteer
from ..core.kinematics import HEADING_OFFSET, METHODS, integrate_twist
from ..core.threads import default_workers
from ..core.validation import check_choice, check_positive_int
from . import drive_noise as dn
from . import mc_kernel
from .particles import CHUNK_ELEMENTS, REGIMES, DrawCache, chunk_streams, start_factor

__all__ = ["DRAWS", "KERNELS", "sample_poses"]

#: The kernels of the end poses: ``"auto"`` (the compiled one from
#: :data:`.mc_kernel.MIN_PARTICLE_STEPS` particle-steps where it applies), ``"numpy"`` (the
#: reference), ``"compiled"`` (:mod:`.mc_kernel` wherever it applies).
KERNELS: tuple[str, ...] = ("auto", "numpy", "compiled")

#: The draw schemes of the normals: ``"auto"`` (``"per-block"`` where the compiled kernel runs,
#: else ``"per-chunk"``), and :data:`.mc_kernel.DRAWS`: ``"per-chunk"``, ``"per-block"``.
DRAWS: tuple[str, ...] = ("auto", *mc_kernel.DRAWS)

#: particle-steps per chunk of the compiled kernel with its own draws (whole blocks of particles): a
#: few milliseconds of work, so that the threads share the chunks evenly
_DRAWN_CHUNK_STEPS = 1 << 20


def _check_checkpoints(checkpoints: Sequence[int] | None, n_steps: int) -> list[int] | None:
    if checkpoints is None:
        return None
    cps = [int(c) for c in checkpoints]
    if not cps or min(cps) < 0 or max(cps) > n_steps:
        raise ValueError(
            f"checkpoints must be step indices in [0, {n_steps}], got {list(checkpoints)}"
        )
    return cps


class _Nominal(NamedTuple):
    """The nominal path of :func:`_end_poses`: twists (N,) each and step headings' cos, sin."""

    v1: NDArray[np.float64]
    v2: NDArray[np.float64] | None  # None: no lateral travel
    dtheta: NDArray[np.float64]
    cos: NDArray[np.float64]  # cos φ̄_i
    sin: NDArray[np.float64]
    start: NDArray[np.float64]


def _nominal(path: DrivePath, method: str) -> _Nominal:
    """The nominal twists and step headings ``φ̄_i = θ̄_i + c Δθ̄_i`` of a path."""
    xi = path.twists
    dth = xi[:, 2]
    th_before = path.start[2] + np.concatenate([[0.0], np.cumsum(dth)[:-1]])
    phi = th_before + HEADING_OFFSET[method] * dth
    v2 = xi[:, 1] if np.any(xi[:, 1]) else None
    return _Nominal(xi[:, 0], v2, dth, np.cos(phi), np.sin(phi), path.start)


def _end_poses(
    nom: _Nominal,
    dv1: NDArray[np.float64],
    dv2: NDArray[np.float64] | None,
    e: NDArray[np.float64],
    scratch: NDArray[np.float64],
    method: str,
    start_offset: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """End poses (m, 3) of particles with twist perturbations ``(δv₁, δv₂, e)`` (m, N) (module docstring).

    Overwrites ``dv1``, ``dv2``, ``e`` and ``scratch`` (m, N, a free buffer). ``start_offset``
    (m, 3), optional, moves each particle's start pose; its heading offset joins δ.
    """
    c = HEADING_OFFSET[method]
    a = dv1
    a += nom.v1  # v₁' per particle and step
    heading_noise_end = e.sum(axis=-1)
    delta = np.cumsum(e, axis=-1, out=scratch)  # Σ_{j<=i} e_j
    if c != 1.0:
        e *= 1.0 - c
        delta -= e  # Σ_{j<i} e_j + c e_i
        e /= 1.0 - c
    if start_offset is not None:
        delta += start_offset[:, 2:3]
        heading_noise_end += start_offset[:, 2]
    b: NDArray[np.float64] | None = dv2  # v₂' per particle and step, None: no lateral travel
    if nom.v2 is not None:
        b = np.broadcast_to(nom.v2, a.shape).copy() if b is None else b + nom.v2
    if method == "exact":
        # s' = sin(Δθ'/2)/(Δθ'/2), Δθ' = Δθ̄ + e
        e += nom.dtheta
        e *= 1.0 / (2.0 * np.pi)
        s = np.sinc(e)
        a *= s
        if b is not None:
            b *= s
    if b is None:
        np.cos(delta, out=e)
        e *= a  # a cos δ
        np.sin(delta, out=delta)
        delta *= a  # a sin δ
        along, across = e, delta
    else:
        cd, sd = np.cos(delta), np.sin(delta)
        along = a * cd - b * sd
        across = a * sd + b * cd
    x = along @ nom.cos - across @ nom.sin
    y = along @ nom.sin + across @ nom.cos
    x0, y0, th0 = nom.start
    if start_offset is not None:
        x += start_offset[:, 0]
        y += start_offset[:, 1]
    th_end = th0 + nom.dtheta.sum() + heading_noise_end
    return np.stack([x0 + x, y0 + y, th_end], axis=-1)


def _particle_twists(path: DrivePath, errors: dn.SampledErrors) -> NDArray[np.float64]:
    """Twists (m, N, 3) of particles with the given errors (the skid-steer's ICR drawn too)."""
    u = path.u + errors.du
    drive = path.drive
    if errors.chi is not None and errors.x_icr is not None and isinstance(drive, SkidSteer):
        return drive.twist_icr(u, errors.chi, errors.x_icr)
    return drive.twist(u)


def _chunk_poses(
    path: DrivePath,
    nom: _Nominal,
    errors: dn.SampledErrors,
    offset: NDArray[np.float64] | None,
    method: str,
    cps: list[int] | None,
) -> NDArray[np.float64]:
    """Poses (m, C, 3) of a chunk's particles: at the checkpoints, or the end (C = 1)."""
    if cps is not None:
        start = path.start[None, :] if offset is None else path.start + offset
        return integrate_twist(_particle_twists(path, errors), start, method)[:, cps, :]  # type: ignore[arg-type]
    du = list(errors.channels)
    scratch = du[-1]
    dv2: NDArray[np.float64] | None
    if errors.chi is not None:
        d = _particle_twists(path, errors) - path.twists
        dv1, dv2, e = d[..., 0].copy(), d[..., 1].copy(), d[..., 2].copy()
        scratch = np.empty_like(e)
    else:
        dv1, dv2, e = path.drive.twist_perturbation(path.u, du)
        if scratch is e or scratch is dv1 or scratch is dv2 or scratch.shape != e.shape:
            scratch = np.empty_like(e)
    return _end_poses(nom, dv1, dv2, e, scratch, method, offset)[:, None, :]


class _Compiled(NamedTuple):
    """What the compiled kernel of a differential drive's chunk needs besides the draws."""

    scale_r: NDArray[np.float64]  # per step √(k|Δs|), per run Δs [m]
    scale_l: NDArray[np.float64]
    eps: tuple[float, float]  # per run √(k/L) [1], per step 1
    nominal: tuple[NDArray[np.float64], ...]  # v₁, Δθ̄, cos φ̄, sin φ̄
    width: int  # draws per particle and wheel: N per step, 1 per run


def _k_only_differential(path: DrivePath, model: dn.DriveErrorModel) -> bool:
    """A differential drive with the travel noise ``k`` only: where the compiled kernel and the
    ``"per-block"`` draws apply."""
    return isinstance(path.drive, Differential) and model.encoder is None and model.slip is None


def _compiled_plan(
    path: DrivePath, model: dn.DriveErrorModel, regime: str, nom: _Nominal, n: int, kernel: str,
    checkpoints: list[int] | None,
) -> _Compiled | None:  # fmt: skip
    """The compiled kernel's inputs where it applies (a differential drive with the travel noise
    ``k``, end poses only) and is asked for, else None (the numpy kernel)."""
    applies = _k_only_differential(path, model) and checkpoints is None
    big = n * path.n_steps >= mc_kernel.MIN_PARTICLE_STEPS
    if not applies or kernel == "numpy" or (kernel == "auto" and not big):
        return None
    k = dn.channels(path.drive, model).k
    u_r, u_l = np.ascontiguousarray(path.u[:, 0]), np.ascontiguousarray(path.u[:, 1])
    nominal = tuple(np.ascontiguousarray(a) for a in (nom.v1, nom.dtheta, nom.cos, nom.sin))
    if regime == "per_step":  # the scales of drive_noise._gaussian_errors, bit for bit
        return _Compiled(np.sqrt(k[0] * np.abs(u_r)), np.sqrt(k[1] * np.abs(u_l)), (1.0, 1.0), nominal, path.n_steps)
    eps = []
    for kj, uj in ((k[0], u_r), (k[1], u_l)):
        L = float(np.abs(uj).sum())
        eps.append(float(np.sqrt(kj / L)) if L > 0 else 0.0)
    return _Compiled(u_r, u_l, (eps[0], eps[1]), nominal, 1)


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
    progress: Callable[[int, int], None] | None = None,
    kernel: str = "auto",
    draws: str = "auto",
    cache: DrawCache | None = None,
) -> NDArray[np.float64]:
    """Noisy executions of a drive's path: the Monte Carlo ground truth of its error model.

    Parameters
    ----------
    path : DrivePath — the drive and its nominal (reported) measurements
    model : DriveErrorModel
    n : int ≥ 1 — particles
    rng : numpy.random.Generator — the only source of randomness (streams
        spawned from its seed sequence: one per chunk of particles, or per block, ``draws``)
    regime : {"per_step", "per_run"} — see :mod:`.drive_noise`
    method : {"exact", "euler", "euler_end", "midpoint"} — integration of each step
    checkpoints : sequence of int in [0, N], optional — step indices to keep
    cov0 : array_like, shape (3, 3), optional — start-pose covariance; each
        particle starts at a draw from N(path.start, cov0)
    workers : int, optional — threads (default: the cores, at most 8); the
        output does not depend on it
    progress : callable, optional — ``progress(done, n)`` with the particles done so
        far, called from the calling thread after each chunk (default None: nothing)
    kernel : {"auto", "numpy", "compiled"} — the end poses of a differential drive with the
        travel noise ``k`` by numpy (the reference) or by the compiled loop of :mod:`.mc_kernel`
        (the same draws, equal up to rounding); ``"auto"``: compiled from
        :data:`.mc_kernel.MIN_PARTICLE_STEPS` particle-steps. Other drives and models, and
        checkpoints, always use numpy.
    draws : {"auto", "per-chunk", "per-block"} — where the normals come from (:mod:`.mc_kernel`):
        ``"per-chunk"``, numpy draws each chunk of particles from the chunk's stream (the kernels
        then differ only by rounding); ``"per-block"``, each block of
        :data:`.mc_kernel.DRAW_BLOCK` particles has its own stream, which the compiled kernel
        draws itself and the numpy kernel takes from numpy (the same numbers). ``"auto"``:
        per block where the compiled kernel runs and no ``cache`` is given, else per chunk.
        ``"per-block"`` applies to the differential drive with the travel noise ``k`` only. For
        every choice a seed gives the same numbers for any number of threads.
    cache : DrawCache, optional — keeps the standard normals of the Gaussian channels for the next
        call with the same seed, particles and steps (the output is the same with or without it);
        per-chunk draws only (the per-block draws are drawn inside the kernel): with a cache
        ``draws="auto"`` is per chunk, and ``"per-block"`` is an error

    Returns
    -------
    ndarray, shape (n, 3) — end poses; with ``checkpoints`` (n, C, 3). Headings unwrapped.
    """
    n = check_positive_int("n", n)
    check_choice("regime", regime, REGIMES)
    check_choice("method", method, METHODS)
    check_choice("kernel", kernel, KERNELS)
    check_choice("draws", draws, DRAWS)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    dn.channels(path.drive, model)  # validate the model against the drive before drawing
    if draws == "per-block" and not _k_only_differential(path, model):
        raise ValueError(
            f"draws 'per-block' applies to the differential drive with the travel noise k only "
            f"(allowed here: 'auto', 'per-chunk'), got a {type(path.drive).__name__} drive"
            + (" with encoder or slip errors" if isinstance(path.drive, Differential) else "")
        )
    if draws == "per-block" and cache is not None:
        raise ValueError("a DrawCache keeps numpy's per-chunk draws (allowed with cache: draws 'auto', 'per-chunk'), "
                         "got draws 'per-block'")  # fmt: skip
    n_workers = default_workers() if workers is None else check_positive_int("workers", workers)
    N = path.n_steps
    cps = _check_checkpoints(checkpoints, N)
    start_sqrt = start_factor(cov0)
    nom = _nominal(path, method)
    plan = _compiled_plan(path, model, regime, nom, n, kernel, cps)
    if draws == "per-block" or (draws == "auto" and plan is not None and cache is None):
        return _sample_per_block(path, model, n, rng, regime, method, cps, start_sqrt, nom, plan, n_workers,
                                 progress)  # fmt: skip
    chunk, starts, children = chunk_streams(rng, n, N)
    out = np.empty((n, 1 if cps is None else len(cps), 3))
    buffers = threading.local()  # each thread's block for the draws of a chunk

    def run_compiled(g: np.random.Generator, m: int, plan: _Compiled) -> NDArray[np.float64]:
        if cache is not None:  # the draw of drive_noise.sample_errors, kept for the next call
            z = cache.normals(g, (2, m, plan.width))
        else:
            size = 2 * chunk * plan.width
            if getattr(buffers, "z", None) is None:
                buffers.z = np.empty(size)
            z = buffers.z[: 2 * m * plan.width].reshape(2, m, plan.width)
            g.standard_normal(out=z)  # the draw of drive_noise.sample_errors, number for number
        offset = None if start_sqrt is None else g.standard_normal((m, 3)) @ start_sqrt.T
        return mc_kernel.compiled_end_poses(
            (z[0], z[1]), plan.scale_r, plan.scale_l, plan.eps, plan.nominal, path.start,
            path.drive.track, HEADING_OFFSET[method], method == "exact", offset,  # type: ignore[attr-defined]
        )  # fmt: skip

    def run_chunk(j: int) -> None:
        lo = starts[j]
        m = min(chunk, n - lo)
        g = children[j]
        if plan is not None:
            out[lo : lo + m, 0] = run_compiled(g, m, plan)
            return
        errors = dn.sample_errors(path.drive, path.u, path.dt, model, m, g, regime, cache)
        offset = None if start_sqrt is None else g.standard_normal((m, 3)) @ start_sqrt.T
        out[lo : lo + m] = _chunk_poses(path, nom, errors, offset, method, cps)

    _map_chunks(run_chunk, starts, chunk, n, n_workers, progress)
    return out[:, 0, :] if cps is None else out


def _sample_per_block(
    path: DrivePath, model: dn.DriveErrorModel, n: int, rng: np.random.Generator, regime: str, method: str,
    cps: list[int] | None, start_sqrt: NDArray[np.float64] | None, nom: _Nominal, plan: _Compiled | None,
    workers: int, progress: Callable[[int, int], None] | None,
) -> NDArray[np.float64]:  # fmt: skip
    """:func:`sample_poses` with the ``"per-block"`` draws: by the compiled kernel (``plan``), or by
    numpy from the same per-block numbers. The blocks are fixed; the chunks (whole blocks, each a
    task of a thread) only share out the work."""
    B = mc_kernel.DRAW_BLOCK
    N = path.n_steps
    key = mc_kernel.block_key(rng)
    n_blocks = -(-n // B)
    if n_blocks > 2**32:
        raise ValueError(f"n must be at most {2**32 * B} for draws 'per-block', got {n}")
    width = N if regime == "per_step" else 1
    steps = _DRAWN_CHUNK_STEPS if plan is not None else CHUNK_ELEMENTS
    per_chunk = max(1, steps // (N * B))
    starts = list(range(0, n, per_chunk * B))
    out = np.empty((n, 3) if cps is None else (n, len(cps), 3))

    def run_chunk(j: int) -> None:
        b0 = starts[j] // B
        b1 = min(n_blocks, b0 + per_chunk)
        if plan is not None:
            mc_kernel.compiled_end_poses(
                mc_kernel.BlockDraws(key, (b0, b1), regime == "per_run", start_sqrt), plan.scale_r, plan.scale_l,
                plan.eps, plan.nominal, path.start, path.drive.track, HEADING_OFFSET[method], method == "exact",  # type: ignore[attr-defined]
                out=out,
            )  # fmt: skip
            return
        lo, hi = b0 * B, min(n, b1 * B)
        z = np.empty((2, hi - lo, width))
        z0 = None if start_sqrt is None else np.empty((hi - lo, 3))
        for b in range(b0, b1):
            a = b * B - lo
            nb = min(B, n - b * B)
            zb, z0b = mc_kernel.block_draws(key, b, nb, width, start_sqrt is not None)
            z[:, a : a + nb] = zb
            if z0 is not None:
                z0[a : a + nb] = z0b
        errors = dn.errors_from_normals(path.drive, path.u, model, z, regime)
        offset = None if z0 is None or start_sqrt is None else z0 @ start_sqrt.T
        poses = _chunk_poses(path, nom, errors, offset, method, cps)
        out[lo:hi] = poses[:, 0] if cps is None else poses

    _map_chunks(run_chunk, starts, per_chunk * B, n, workers, progress)
    return out


def _map_chunks(
    run_chunk: Callable[[int], None],
    starts: list[int],
    chunk: int,
    n: int,
    workers: int,
    progress: Callable[[int, int], None] | None,
) -> None:
    """Run every chunk, on ``workers`` threads (each chunk writes its own rows), reporting progress."""
    if workers == 1 or len(starts) == 1:
        for j in range(len(starts)):
            run_chunk(j)
            if progress is not None:
                progress(min(n, starts[j] + chunk), n)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            for j, _ in enumerate(pool.map(run_chunk, range(len(starts)))):
                if progress is not None:
                    progress(min(n, starts[j] + chunk), n)
