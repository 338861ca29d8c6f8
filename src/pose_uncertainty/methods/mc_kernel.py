"""The compiled Monte Carlo kernel of the differential drive: one fused loop per particle.

What it computes
----------------
The end poses of :func:`.drive_sampling.sample_poses` for a differential drive with the
travel noise ``k`` (both regimes, any integration method, an optional start-pose
covariance), from the same standard normals as the numpy kernel (the reference,
``drive_sampling._end_poses``) under either draw scheme (below): the numbers it returns equal
numpy's up to rounding. Per particle and step ``i`` it forms the wheel errors, the twist
perturbation ``δv₁ = (δs_r + δs_l)/2``, ``e = (δs_r − δs_l)/b``, the heading perturbation
``δ_i = Σ_{j<i} e_j + c·e_i`` of the step and adds ``v₁'·(cos(φ̄_i + δ_i), sin(φ̄_i + δ_i))``
to the position, all in registers: no temporaries of the size of the cloud.

The same private module holds Method C's loop over the steps for one set
(``_mc_jit.ut_march``, :func:`.unscented.propagate` with ``kernel="compiled"``): the numpy
step's arithmetic per sigma point, in registers, summed in another order (equal up to rounding).

Why compiled
------------
numpy's float64 ``sin``/``cos`` are vector kernels only on a CPU with AVX-512; elsewhere each
element is a scalar C-library call, and each numpy operation on a (particles × steps) block
writes a temporary. Compiled by numba (LLVM) the loop runs in registers on any x86-64 CPU,
and it releases the GIL, so the chunks of particles run on several threads.

The draws: per chunk or per block
---------------------------------
:data:`DRAWS`, the ``draws`` option of :func:`.drive_sampling.sample_poses`:

``"per-chunk"``
    numpy draws the normals of each chunk of particles from the chunk's stream
    (:func:`.particles.chunk_streams`), in the order of :func:`.drive_noise.sample_errors`, and
    the compiled loop takes them. numpy's draws alone cost about two thirds of what the plain
    numpy loop over the steps spends per particle-step, so no kernel fed by them gets past
    about 5× that loop on two cores (``benchmarks/bench_kernel.py`` measures this ceiling).
``"per-block"``
    each block of :data:`DRAW_BLOCK` particles (particles ``b·DRAW_BLOCK …``) has a stream of
    its own: numpy's SFC64 seeded by ``SeedSequence(key, spawn_key=(b,))``, its normals those of
    numpy's ``Generator.standard_normal`` (the ziggurat). ``key`` is four 32-bit words from a
    child of the caller's seed sequence (:func:`block_key`), so the randomness still comes from
    the caller's generator only. The compiled loop draws them itself, block by block and step
    by step, with numpy's algorithms written out in it (SeedSequence's hash and mixing, SFC64's
    seeding and step, the ziggurat with numpy's tables and its rare branches calling the C
    library's ``exp``/``log1p`` as numpy's does); :func:`block_draws` gives the same numbers
    from numpy's own objects, the numpy kernel's route to them. In a block's stream come
    first the start offsets' normals (``DRAW_BLOCK × 3``, particle by particle), then per step
    (per run: once) the right wheel's ``DRAW_BLOCK`` normals and the left wheel's; a last,
    partial block draws a whole block. So a seed fixes every number, the threads and the
    chunks that share out the blocks change nothing, and a particle's numbers depend on the
    key and its index only. The blocks' streams are children of one seed sequence with distinct
    spawn keys: numpy's own recipe for independent parallel streams.

``tests/test_mc_kernel.py`` checks that the compiled streams equal numpy's bit for bit, that
they are standard normal (moments, a Kolmogorov–Smirnov distance, no correlation across blocks
or along a stream, tolerances from the sample size), that the clouds have the moments of numpy's
per-chunk draws and of Method A, and both kernels against each other on the same draws under
each scheme. With ``draws="auto"`` each kernel takes its own scheme: the compiled one per block
(its draws are what lets it go past the ceiling above), the numpy one per chunk. So
``kernel="auto"`` keeps numpy's per-chunk draws below :data:`MIN_PARTICLE_STEPS` (every run of
the pipeline today: its logged numbers are unchanged, bit for bit) and runs the compiled kernel
with its own per-block draws from there.

The polynomial sine and cosine, and their error bound
------------------------------------------------------
With ``trig="polynomial"`` (the default) the kernel calls no C-library function per step:
``cos δ, sin δ`` are computed by the branch-free polynomials of the C library's own kernels
(fdlibm ``__kernel_cos``/``__kernel_sin``, error < 1 ulp on ``[−π/4, π/4]``) after a
Cody–Waite reduction by ``π/2`` (three 33-bit parts of ``π/2``, exact products for
``|δ| < 2¹⁹·π/2``), the quadrant chosen by selects, so that the loop over a block of
particles compiles to vector instructions on any x86-64 CPU. Each value is within
``SIN_COS_ULPS = 2`` ulp of the true one, as the C library's and numpy's are within 1 ulp: the
two differ by at most 3 ulp, ``3u`` with ``u = 2⁻⁵³``, per step and per call, of the same kind
as between two machines. No error is carried from step to step (the heading perturbation
``δ_i`` itself is summed as numpy sums it), so a particle's position differs from numpy's by at
most ``3u`` times its path length plus the rounding of the sums: within the reproducibility
contract's ``64 u (N + 64)`` of :mod:`pose_uncertainty.records.reproducibility` at any ``N``.
``tests/test_mc_kernel.py`` measures the polynomials against the C library on 10⁶ angles
and the kernel against numpy's on the same draws, over 10⁴ steps and over heading
perturbations of several full turns. A block of particles whose heading perturbation leaves
``|δ| < 2¹⁹·π/2`` (8·10⁵ rad) is recomputed with the C library. ``trig="libm"`` calls
``math.cos``/``math.sin`` every step, as numpy does (on a CPU without AVX-512 the same bits).

Compilation
-----------
numba is imported on the first call only, and the kernel is compiled with ``cache=True``:
the machine code is written beside this file (``__pycache__``; numba falls back to a per-user
cache when that is read-only, and ``NUMBA_CACHE_DIR`` chooses another place) and loaded by the
next process. The first call of a process pays numba's import and the load from the cache,
or on a fresh install the compilation (:data:`MIN_PARTICLE_STEPS` is set from both;
``benchmarks/bench_kernel.py`` measures them). The loops are in the private module
``_mc_jit``; nothing else imports numba. The ziggurat's tables come from numba's copy of
numpy's (``numba.np.random._constants``), a private module of the locked numba: the tests'
bit-for-bit comparison with numpy would catch a change.
"""

from __future__ import annotations

import threading
from types import ModuleType
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DRAWS", "DRAW_BLOCK", "MIN_PARTICLE_STEPS", "SIN_COS_ULPS", "TRIG", "BlockDraws", "block_draws",
    "block_generator", "block_key", "compiled_end_poses", "jit_module",
]  # fmt: skip

#: The kernel's trigonometry: branch-free polynomials (vectorised), or a C-library call per step.
TRIG: tuple[str, ...] = ("polynomial", "libm")

#: Bound of the polynomial ``cos``/``sin`` error, in ulp of the value (module docstring).
SIN_COS_ULPS = 2

#: Particle-steps (particles × steps) from which :func:`.drive_sampling.sample_poses` uses the
#: compiled kernel by default: below, numba's import and cache load on first use in a process
#: (measured ~2 CPU-s) cost more than the kernel with its own draws saves (~5·10⁻⁸ CPU-s per
#: particle-step against the numpy kernel); ``benchmarks/bench_kernel.py`` measures both.
MIN_PARTICLE_STEPS = 50_000_000

#: The draw schemes of the Monte Carlo's normals (module docstring): ``"per-chunk"`` (numpy draws
#: each chunk of particles from the chunk's stream), ``"per-block"`` (each block of
#: :data:`DRAW_BLOCK` particles from its own stream, drawn inside the compiled kernel).
DRAWS: tuple[str, ...] = ("per-chunk", "per-block")

#: Particles per block of the ``"per-block"`` draws: part of the draws' definition (a seed's
#: numbers depend on it), and the compiled kernel's block of particles (64 measured ~6 % faster
#: than 32, longer blocks no faster).
DRAW_BLOCK = 64

_JIT: list[ModuleType] = []
_LOCK = threading.Lock()


def jit_module() -> ModuleType:
    """The compiled loops (the private module ``_mc_jit``), imported on first use; thread-safe."""
    with _LOCK:
        if not _JIT:
            from . import _mc_jit  # numba is imported here: only when a kernel runs

            _JIT.append(_mc_jit)
        return _JIT[0]


def block_key(rng: np.random.Generator) -> NDArray[np.uint64]:
    """The key of the ``"per-block"`` draws: 4 words below 2³² from a child of ``rng``'s seed sequence.

    Spawning leaves ``rng``'s own stream untouched, as the ``"per-chunk"`` streams do
    (:func:`.particles.chunk_streams`); a second call spawns another child, so another key.

    Parameters
    ----------
    rng : numpy.random.Generator — seeded from a SeedSequence (e.g. ``numpy.random.default_rng(seed)``)

    Returns
    -------
    ndarray, shape (4,), uint64 — the key's words, each below 2³²
    """
    seq = rng.bit_generator.seed_seq
    if not isinstance(seq, np.random.SeedSequence):
        raise TypeError("rng must be seeded from a SeedSequence (e.g. numpy.random.default_rng(seed))")
    return seq.spawn(1)[0].generate_state(4, np.uint32).astype(np.uint64)


def block_generator(key: NDArray[np.uint64], block: int) -> np.random.Generator:
    """The stream of one block of the ``"per-block"`` draws, by numpy.

    Parameters
    ----------
    key : ndarray (4,) — :func:`block_key`; block : int in [0, 2³²) — the block's index

    Returns
    -------
    numpy.random.Generator — ``Generator(SFC64(SeedSequence(key, spawn_key=(block,))))``, whose
    ``standard_normal`` gives the numbers the compiled kernel draws for the block
    """
    if not 0 <= block < 2**32:
        raise ValueError(f"block must be in [0, 2**32), got {block}")
    return np.random.Generator(np.random.SFC64(np.random.SeedSequence([int(w) for w in key], spawn_key=(block,))))


def block_draws(
    key: NDArray[np.uint64], block: int, nb: int, width: int, start: bool
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """The normals of one block of the ``"per-block"`` draws, by numpy (the reference route).

    Parameters
    ----------
    key : ndarray (4,) — :func:`block_key`; block : int — the block's index (its particles are
        ``block·DRAW_BLOCK …``); nb : int — its particles (``DRAW_BLOCK``, fewer in the last block)
    width : int — draws per particle and wheel: the steps N per step, 1 per run
    start : bool — draw the start offsets' normals first

    Returns
    -------
    z : ndarray, shape (2, nb, width) — the right and left wheels' normals, as
        :func:`.drive_noise.sample_errors` lays them out; z0 : ndarray, shape (nb, 3), or None —
        the start offsets' normals

    The block's stream gives, in this order: the start offsets' normals of ``DRAW_BLOCK``
    particles (particle by particle), then for each step the right wheel's ``DRAW_BLOCK``
    normals and the left wheel's. A last block of ``nb < DRAW_BLOCK`` particles keeps the first
    ``nb`` of each, so a particle's numbers depend on the key and its index only. The compiled
    kernel draws the same numbers in the same order (numpy's ziggurat on numpy's SFC64, seeded
    by numpy's SeedSequence algorithm).
    """
    if not 1 <= nb <= DRAW_BLOCK:
        raise ValueError(f"nb must be in [1, {DRAW_BLOCK}], got {nb}")
    g = block_generator(key, block)
    z0 = g.standard_normal((DRAW_BLOCK, 3))[:nb] if start else None
    z = g.standard_normal((width, 2, DRAW_BLOCK))[:, :, :nb].transpose(1, 2, 0)
    return z, z0


class BlockDraws(NamedTuple):
    """The ``"per-block"`` draws of blocks ``blocks[0] … blocks[1]−1`` (particles ``b·DRAW_BLOCK …``),
    which the compiled kernel draws itself (:func:`compiled_end_poses`)."""

    key: NDArray[np.uint64]  # (4,) — block_key
    blocks: tuple[int, int]  # the first block and one past the last
    per_run: bool  # one draw per wheel and run (else one per step)
    start_sqrt: NDArray[np.float64] | None = None  # (3, 3) A with A Aᵀ the start covariance (offset A z)


def compiled_end_poses(
    normals: tuple[NDArray[np.float64], NDArray[np.float64]] | BlockDraws, scale_r: NDArray[np.float64],
    scale_l: NDArray[np.float64], eps: tuple[float, float], nominal: tuple[NDArray[np.float64], ...],
    start: NDArray[np.float64], track: float, c: float, exact: bool, offset: NDArray[np.float64] | None = None,
    out: NDArray[np.float64] | None = None, trig: str = "polynomial",
) -> NDArray[np.float64]:  # fmt: skip
    """End poses of differential-drive particles by the compiled kernel, on numpy's normals or on
    the ``"per-block"`` draws it draws itself (one loop for both).

    Parameters
    ----------
    normals : (z_r, z_l) or BlockDraws — numpy's standard normals of a chunk of m particles, as
        drawn for :func:`.drive_noise.sample_errors`: each wheel's, shape (m, N) per step or (m, 1)
        per run; or the blocks whose normals the kernel draws (:class:`BlockDraws`)
    scale_r, scale_l : ndarray, shape (N,) — per step ``√(k|Δs|)`` [m]; per run the travel ``Δs`` [m]
    eps : (float, float) — per run the scale errors' standard deviations ``√(k/L)`` [1]; per step 1
    nominal : (v₁, Δθ̄, cos φ̄, sin φ̄), each shape (N,) — the nominal twists and step headings
    start : ndarray, shape (3,) — start pose; track : float [m]
    c : float — heading offset of the method within the step; exact : bool — the exact step's
        ``sin(Δθ'/2)/(Δθ'/2)`` factor
    offset : ndarray, shape (m, 3), optional — start offsets of numpy's particles (with
        :class:`BlockDraws` the kernel draws them: ``start_sqrt``)
    out : ndarray, shape (n, 3), optional — where to write; with :class:`BlockDraws` required, the
        end poses of all n particles of which only these blocks' rows are written; else (m, 3)
    trig : {"polynomial", "libm"} — module docstring

    Returns
    -------
    ndarray — ``out``, or a new (m, 3) array of the end poses
    """
    v1, dtheta, cos_phi, sin_phi = nominal
    if isinstance(normals, BlockDraws):
        if out is None or offset is not None:
            raise ValueError("BlockDraws draw their own start offsets into a given out "
                             f"(allowed: offset None, out (n, 3)), got offset {offset is not None}, out {out is not None}")  # fmt: skip
        key = np.ascontiguousarray(normals.key, dtype=np.uint64)
        z_r = z_l = np.zeros((0, 0))
        first, last = int(normals.blocks[0]), int(normals.blocks[1])
        per_run = bool(normals.per_run)
        sq = normals.start_sqrt
        start_in = np.zeros((0, 3)) if sq is None else np.ascontiguousarray(sq, dtype=np.float64)
    else:
        key = np.zeros(0, dtype=np.uint64)
        z_r, z_l = (np.ascontiguousarray(z, dtype=np.float64) for z in normals)
        m = z_r.shape[0]
        first, last = 0, -(-m // DRAW_BLOCK)
        per_run = z_r.shape[1] == 1
        start_in = np.zeros((0, 3)) if offset is None else np.ascontiguousarray(offset, dtype=np.float64)
        out = np.empty((m, 3)) if out is None else out
    th_end = float(start[2] + dtheta.sum())
    jit_module().end_poses(
        key, z_r, z_l, start_in, first, last, per_run, scale_r, scale_l, float(eps[0]), float(eps[1]), v1,
        dtheta, cos_phi, sin_phi, float(track), float(c), bool(exact), trig == "polynomial", float(start[0]),
        float(start[1]), th_end, out,
    )  # fmt: skip
    return out
