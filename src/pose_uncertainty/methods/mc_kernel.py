"""The compiled Monte Carlo kernel of the differential drive: one fused loop per particle.

What it computes
----------------
The end poses of :func:`.drive_sampling.sample_poses` for a differential drive with the
travel noise ``k`` (both regimes, any integration method, an optional start-pose
covariance), from the same standard normals, drawn by numpy from the same streams in the
same order: the numbers it returns equal numpy's (the reference, ``drive_sampling._end_poses``)
up to rounding. Per particle and step ``i`` it forms the wheel errors, the twist
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
and it releases the GIL, so the chunks of particles run on several threads (numpy's normal
draws release it too).

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
or on a fresh install the compilation (:data:`MIN_PARTICLE_STEPS` is set from both). The
loops are in the private module ``_mc_jit``; nothing else imports numba.
"""

from __future__ import annotations

import threading
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

__all__ = ["MIN_PARTICLE_STEPS", "SIN_COS_ULPS", "TRIG", "compiled_end_poses", "jit_module"]

#: The kernel's trigonometry: branch-free polynomials (vectorised), or a C-library call per step.
TRIG: tuple[str, ...] = ("polynomial", "libm")

#: Bound of the polynomial ``cos``/``sin`` error, in ulp of the value (module docstring).
SIN_COS_ULPS = 2

#: Particle-steps (particles × steps) from which :func:`.drive_sampling.sample_poses` uses the
#: compiled kernel by default: below, numba's import and cache load on first use in a process
#: (measured ~1.4 CPU-s) cost more than the kernel saves (~3·10⁻⁸ CPU-s per particle-step);
#: ``benchmarks/bench_kernel.py`` measures both.
MIN_PARTICLE_STEPS = 50_000_000

_JIT: list[ModuleType] = []
_LOCK = threading.Lock()


def jit_module() -> ModuleType:
    """The compiled loops (the private module ``_mc_jit``), imported on first use; thread-safe."""
    with _LOCK:
        if not _JIT:
            from . import _mc_jit  # numba is imported here: only when a kernel runs

            _JIT.append(_mc_jit)
        return _JIT[0]


def compiled_end_poses(
    z_r: NDArray[np.float64], z_l: NDArray[np.float64], scale_r: NDArray[np.float64],
    scale_l: NDArray[np.float64], eps: tuple[float, float], nominal: tuple[NDArray[np.float64], ...],
    start: NDArray[np.float64], track: float, c: float, exact: bool, offset: NDArray[np.float64] | None,
    trig: str = "polynomial",
) -> NDArray[np.float64]:  # fmt: skip
    """End poses (m, 3) of a chunk of differential-drive particles by the compiled kernel.

    Parameters
    ----------
    z_r, z_l : ndarray, shape (m, N) per step or (m, 1) per run — the standard normals of
        each wheel, as drawn for :func:`.drive_noise.sample_errors`
    scale_r, scale_l : ndarray, shape (N,) — per step ``√(k|Δs|)`` [m]; per run the travel ``Δs`` [m]
    eps : (float, float) — per run the scale errors' standard deviations ``√(k/L)`` [1]; per step 1
    nominal : (v₁, Δθ̄, cos φ̄, sin φ̄), each shape (N,) — the nominal twists and step headings
    start : ndarray, shape (3,) — start pose; track : float [m]
    c : float — heading offset of the method within the step; exact : bool — the exact step's
        ``sin(Δθ'/2)/(Δθ'/2)`` factor
    offset : ndarray, shape (m, 3), optional — start offsets of the particles
    trig : {"polynomial", "libm"} — module docstring
    """
    v1, dtheta, cos_phi, sin_phi = nominal
    m = z_r.shape[0]
    out = np.empty((m, 3))
    off = np.zeros((0, 3)) if offset is None else np.ascontiguousarray(offset)
    th_end = float(start[2] + dtheta.sum())
    jit_module().end_poses(
        z_r, z_l, scale_r, scale_l, float(eps[0]), float(eps[1]), v1, dtheta, cos_phi, sin_phi,
        float(track), float(c), bool(exact), trig == "polynomial", off, float(start[0]),
        float(start[1]), th_end, out,
    )  # fmt: skip
    return out
