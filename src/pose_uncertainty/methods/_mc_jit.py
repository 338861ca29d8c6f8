"""The loops of :mod:`.mc_kernel`, compiled by numba (imported by it on first use only).

One loop for both draw schemes (:func:`end_poses`): blocks of :data:`BLOCK` particles, each
step's normals of a block either taken from numpy's draws (a column of the chunk's ``(m, N)``
normals, ``"per-chunk"``) or drawn from the block's own stream (SFC64 and numpy's ziggurat,
:func:`normal`, ``"per-block"``) into two small buffers. Either way the loop over the particles
of one step is a loop over contiguous numbers, which LLVM turns into AVX2/AVX-512 vector code on
any x86-64 CPU, and every step moves the block's particles in registers. The sine and cosine
are :func:`sin_cos`: branch-free polynomials, so that they vectorise too.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numba.np.random._constants as _zig  # numpy's ziggurat tables, as numba carries them
import numpy as np

from .mc_kernel import DRAW_BLOCK

#: particles per block of the kernel: the blocks of the ``"per-block"`` draws (a block's buffers,
#: 10 × BLOCK numbers, stay in the first-level cache; on numpy's draws a step's column of a block
#: is 2 × BLOCK rows' cache lines, as few)
BLOCK = DRAW_BLOCK

# Cody–Waite reduction by π/2 (fdlibm's pio2_1, pio2_2, pio2_3: 33 bits each, so k·pio2_j is
# exact for |k| < 2²⁰) and fdlibm's __kernel_sin / __kernel_cos (error < 1 ulp on [−π/4, π/4])
_TWO_OVER_PI = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
_ROUND = 6755399441055744.0  # 1.5·2⁵²: (x + _ROUND) − _ROUND rounds x to the nearest integer
#: |x| up to which :func:`sin_cos` reduces exactly (k < 2¹⁹); beyond, the kernel calls the C library
REDUCTION_LIMIT = 2.0**19 * (math.pi / 2)
_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10
_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11

_jit = numba.njit(nogil=True, cache=True, error_model="numpy")
# a function of its own (compiled once, called): the pieces the entry points share, so that numba
# types and inlines each piece once (inlined everywhere, the compilation took minutes)
_part = numba.njit(nogil=True, error_model="numpy")
_inline = numba.njit(inline="always", error_model="numpy")


@_inline
def sin_cos(x: float) -> tuple[float, float]:
    """``(cos x, sin x)`` for ``|x| ≤ REDUCTION_LIMIT``, within 2 ulp, without branches.

    ``x = kπ/2 + r`` with ``|r| ≤ π/4`` (Cody–Waite), the polynomials of fdlibm on ``r``, and
    the quadrant ``k mod 4`` by selects.
    """
    k = (x * _TWO_OVER_PI + _ROUND) - _ROUND
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
    z = r * r
    s = r + z * r * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    hz = 0.5 * z
    w = 1.0 - hz
    c = w + (((1.0 - w) - hz) + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6))))))
    half = 0.5 * k
    odd = half != math.floor(half)  # k odd: cos and sin swap
    quarter = 0.25 * k
    upper = quarter - math.floor(quarter) >= 0.5  # k mod 4 in {2, 3}: both change sign
    cs = -s if odd else c
    sn = c if odd else s
    return (-cs if upper else cs), (-sn if upper else sn)


@_inline
def _lanes(
    zr: np.ndarray, zl: np.ndarray, sr: float, sl: float, cum: np.ndarray, off: np.ndarray, x: np.ndarray,
    y: np.ndarray, big: np.ndarray, nb: int, v1: float, dtheta: float, cos_phi: float, sin_phi: float,
    track: float, rest: float, exact: bool, poly: bool,
) -> None:  # fmt: skip
    """One step of ``nb`` particles (the arithmetic of :func:`.drive_sampling._end_poses`); the wheel
    errors are ``zr·sr``, ``zl·sl`` (``sr = sl = 1`` where ``zr``, ``zl`` are the errors already)."""
    for q in range(nb):
        dr = zr[q] * sr
        dl = zl[q] * sl
        a = (dr + dl) * 0.5 + v1
        e = (dr - dl) / track
        total = cum[q] + e
        d = (total - e * rest) + off[q]  # δ = Σ_{j<i} e_j + c e_i (+ the start's heading offset)
        cum[q] = total
        ad = abs(d)
        big[q] = max(big[q], ad)
        if poly:
            cd, sd = sin_cos(d)
        else:
            cd = math.cos(d)
            sd = math.sin(d)
        if exact:  # numpy.sinc(t) = sin(πt)/(πt) of t = Δθ'/(2π)
            t = (e + dtheta) * (1.0 / (2.0 * np.pi))
            t = np.pi * (t if t != 0.0 else 1.0e-20)
            a *= (sin_cos(t)[1] if poly else math.sin(t)) / t
        x[q] += a * (cd * cos_phi - sd * sin_phi)
        y[q] += a * (sd * cos_phi + cd * sin_phi)


def _lanes_with(exact: bool, poly: bool) -> Callable[..., None]:
    """:func:`_lanes` compiled once with ``exact`` and ``poly`` as constants (the closure's, which
    numba folds): the polynomial loops then vectorise, where with the flags as variables LLVM may
    keep the C-library calls in the loop and leave it scalar. A function of its own, compiled once
    and called, not a ``Literal`` argument that would compile a copy of every caller."""

    def lanes(
        zr: np.ndarray, zl: np.ndarray, sr: float, sl: float, cum: np.ndarray, off: np.ndarray, x: np.ndarray,
        y: np.ndarray, big: np.ndarray, nb: int, v1: float, dtheta: float, cos_phi: float, sin_phi: float,
        track: float, rest: float,
    ) -> None:  # fmt: skip
        _lanes(zr, zl, sr, sl, cum, off, x, y, big, nb, v1, dtheta, cos_phi, sin_phi, track, rest, exact, poly)

    return _part(lanes)


#: the compiled lanes of each case: polynomial or C-library trigonometry, exact step or not
_LANES_POLY = _lanes_with(False, True)
_LANES_POLY_EXACT = _lanes_with(True, True)
_LANES_LIBM = _lanes_with(False, False)
_LANES_LIBM_EXACT = _lanes_with(True, False)


@_inline
def _step(
    zr: np.ndarray, zl: np.ndarray, sr: float, sl: float, cum: np.ndarray, off: np.ndarray, x: np.ndarray,
    y: np.ndarray, big: np.ndarray, nb: int, v1: float, dtheta: float, cos_phi: float, sin_phi: float,
    track: float, rest: float, exact: bool, poly: bool,
) -> None:  # fmt: skip
    """:func:`_lanes` by the compiled loop of its case (:func:`_lanes_with`)."""
    args = (zr, zl, sr, sl, cum, off, x, y, big, nb, v1, dtheta, cos_phi, sin_phi, track, rest)
    if poly:
        if exact:
            _LANES_POLY_EXACT(*args)
        else:
            _LANES_POLY(*args)
    elif exact:
        _LANES_LIBM_EXACT(*args)
    else:
        _LANES_LIBM(*args)


@_jit
def sin_cos_array(x: np.ndarray, out: np.ndarray) -> None:
    """:func:`sin_cos` of every number of ``x`` into ``out`` (2, n): cos, sin (for the tests)."""
    for i in range(x.shape[0]):
        out[0, i], out[1, i] = sin_cos(x[i])


@_inline
def _wheel_lanes(
    P: np.ndarray, z: np.ndarray, travel: tuple[float, float], scale: tuple[float, float], inv_track: float,
    out: np.ndarray, poly: bool,
) -> float:  # fmt: skip
    """:func:`wheel_step`'s loop; returns the largest |φ| (for the reduction's limit)."""
    big = 0.0
    for p in range(P.shape[0]):
        r = z[0, p] * scale[0] + travel[0]
        l = z[1, p] * scale[1] + travel[1]
        ds = (r + l) * 0.5
        dth = (r - l) * inv_track
        th = P[p, 2]
        phi = dth * 0.5 + th
        aphi = abs(phi)
        big = max(big, aphi)
        if poly:
            c, s = sin_cos(phi)
        else:
            c = math.cos(phi)
            s = math.sin(phi)
        out[p, 0] = P[p, 0] + ds * c
        out[p, 1] = P[p, 1] + ds * s
        out[p, 2] = th + dth
    return big


@_jit
def wheel_step(
    P: np.ndarray, z: np.ndarray, travel_r: float, travel_l: float, scale_r: float, scale_l: float,
    inv_track: float, out: np.ndarray,
) -> None:  # fmt: skip
    """The particle filter's wheel-model step (:func:`pose_uncertainty.localization.motion.sample_motion`).

    ``Δs' = Δs + z √(k|Δs|)`` per wheel, then the midpoint step, with the arithmetic of the numpy
    route; the polynomial ``cos``/``sin``, or the C library's for headings beyond ``REDUCTION_LIMIT``.
    """
    travel = (travel_r, travel_l)
    scale = (scale_r, scale_l)
    if _wheel_lanes(P, z, travel, scale, inv_track, out, True) > REDUCTION_LIMIT:
        _wheel_lanes(P, z, travel, scale, inv_track, out, False)


# ---------------------------------------------------------------------------------------------
# Draws inside the kernel: one SFC64 stream per block of particles, seeded by numpy's SeedSequence
# algorithm, and numpy's ziggurat for the standard normals (its tables, as numba carries them)
# ---------------------------------------------------------------------------------------------

_M32 = np.uint64(0xFFFFFFFF)
_U1 = np.uint64(1)
_U3 = np.uint64(3)
_U9 = np.uint64(9)
_U11 = np.uint64(11)
_U16 = np.uint64(16)
_U24 = np.uint64(24)
_U32 = np.uint64(32)
_U40 = np.uint64(40)
_U255 = np.uint64(0xFF)
_U511 = np.uint64(0x1FF)
_MANTISSA = np.uint64(0x000FFFFFFFFFFFFF)
# numpy.random.SeedSequence's hash constants (bit_generator.pyx: INIT_A, MULT_A, INIT_B, MULT_B,
# MIX_MULT_L, MIX_MULT_R), its pool of 4 words
_INIT_A = np.uint64(0x43B0D7E5)
_MULT_A = np.uint64(0x931E8875)
_INIT_B = np.uint64(0x8B51F9DD)
_MULT_B = np.uint64(0x58F38DED)
_MIX_L = np.uint64(0xCA01F9DD)
_MIX_R = np.uint64(0x4973F715)
# numpy's ziggurat of 256 layers (numpy/random/src/distributions/ziggurat_constants.h)
_KI = _zig.ki_double.astype(np.int64)  # below 2⁵²: compared as signed integers
_WI = np.ascontiguousarray(_zig.wi_double, dtype=np.float64)
_WI_SIGNED = np.concatenate([_WI, -_WI])  # the layer's width with the sign: rabs·(−w) = −(rabs·w) exactly
_FI = np.ascontiguousarray(_zig.fi_double, dtype=np.float64)
_ZIG_R = float(_zig.ziggurat_nor_r)
_ZIG_INV_R = float(_zig.ziggurat_nor_inv_r)
_TWO_M53 = 1.0 / 9007199254740992.0


@_inline
def _hashmix(value: np.uint64, hc: np.uint64) -> tuple[np.uint64, np.uint64]:
    value ^= hc
    hc = (hc * _MULT_A) & _M32
    value = (value * hc) & _M32
    return value ^ (value >> _U16), hc


@_inline
def _mix(x: np.uint64, y: np.uint64) -> np.uint64:
    r = (_MIX_L * x - _MIX_R * y) & _M32
    return r ^ (r >> _U16)


@_inline
def _sfc64(s0: np.uint64, s1: np.uint64, s2: np.uint64, s3: np.uint64) -> tuple[np.uint64, ...]:
    """One output of SFC64 (numpy's ``sfc64_next``) and the next state."""
    tmp = s0 + s1 + s3
    return tmp, s1 ^ (s1 >> _U11), s2 + (s2 << _U3), ((s2 << _U24) | (s2 >> _U40)) + tmp, s3 + _U1


@_inline
def block_state(key: np.ndarray, block: int) -> tuple[np.uint64, np.uint64, np.uint64, np.uint64]:
    """The SFC64 state of ``numpy.random.SFC64(numpy.random.SeedSequence(key, spawn_key=(block,)))``.

    ``key``: 4 words below 2³² (uint64); ``block`` < 2³². numpy's SeedSequence (its entropy
    ``key`` and ``block``, mixed into a pool of 4 words; ``generate_state(3, uint64)``), then
    numpy's SFC64 seeding (``a, b, c`` from the state, counter 1, 12 outputs discarded).
    """
    hc = _INIT_A
    pool = np.empty(4, dtype=np.uint64)
    for i in range(4):  # the entropy words key[0..3] (as many as the pool), then the mixing
        pool[i], hc = _hashmix(key[i], hc)
    for src in range(4):
        for dst in range(4):
            if src != dst:
                h, hc = _hashmix(pool[src], hc)
                pool[dst] = _mix(pool[dst], h)
    for dst in range(4):  # the spawn key's word: the block
        h, hc = _hashmix(np.uint64(block), hc)
        pool[dst] = _mix(pool[dst], h)
    hb = _INIT_B
    words = np.empty(6, dtype=np.uint64)  # generate_state(3, uint64): 6 words, little-endian pairs
    for i in range(6):
        v = pool[i % 4] ^ hb
        hb = (hb * _MULT_B) & _M32
        v = (v * hb) & _M32
        words[i] = v ^ (v >> _U16)
    s0 = words[0] | (words[1] << _U32)
    s1 = words[2] | (words[3] << _U32)
    s2 = words[4] | (words[5] << _U32)
    s3 = _U1
    for _ in range(12):
        _, s0, s1, s2, s3 = _sfc64(s0, s1, s2, s3)
    return s0, s1, s2, s3


@_inline
def _next_double(s0: np.uint64, s1: np.uint64, s2: np.uint64, s3: np.uint64) -> tuple:
    r, s0, s1, s2, s3 = _sfc64(s0, s1, s2, s3)
    return float(np.int64(r >> _U11)) * _TWO_M53, s0, s1, s2, s3


@_inline
def normal(s0: np.uint64, s1: np.uint64, s2: np.uint64, s3: np.uint64) -> tuple:
    """One standard normal of numpy's ``Generator.standard_normal`` (its ziggurat) and the next state."""
    while True:
        r, s0, s1, s2, s3 = _sfc64(s0, s1, s2, s3)
        idx = np.intp(r & _U255)
        rabs = np.int64((r >> _U9) & _MANTISSA)
        x = float(rabs) * _WI_SIGNED[np.intp(r & _U511)]  # −x for the sign bit (r's bit 8), no branch
        if rabs < _KI[idx]:
            return x, s0, s1, s2, s3
        if idx == 0:  # the tail beyond r
            while True:
                u, s0, s1, s2, s3 = _next_double(s0, s1, s2, s3)
                xx = -_ZIG_INV_R * math.log1p(-u)
                u, s0, s1, s2, s3 = _next_double(s0, s1, s2, s3)
                yy = -math.log1p(-u)
                if yy + yy > xx * xx:
                    t = _ZIG_R + xx
                    return (-t if (rabs >> 8) & 1 else t), s0, s1, s2, s3
        else:
            u, s0, s1, s2, s3 = _next_double(s0, s1, s2, s3)
            if (_FI[idx - 1] - _FI[idx]) * u + _FI[idx] < math.exp(-0.5 * x * x):
                return x, s0, s1, s2, s3


@_jit
def block_normals(key: np.ndarray, block: int, out: np.ndarray) -> None:
    """``out`` (any shape, C order) filled with the first normals of ``block``'s stream (for the tests)."""
    s0, s1, s2, s3 = block_state(key, block)
    flat = out.reshape(-1)
    for i in range(flat.shape[0]):
        x, s0, s1, s2, s3 = normal(s0, s1, s2, s3)
        flat[i] = x


@_part
def _draw(buf: np.ndarray, nb: int, s0: np.uint64, s1: np.uint64, s2: np.uint64, s3: np.uint64) -> tuple:
    """``buf[:nb]`` filled with the stream's next normals; returns the stream's state."""
    for q in range(nb):
        z, s0, s1, s2, s3 = normal(s0, s1, s2, s3)
        buf[q] = z
    return s0, s1, s2, s3


@_part
def _normals(
    z_r: np.ndarray, z_l: np.ndarray, i: int, p0: int, nb: int, wr: np.ndarray, wl: np.ndarray, drawn: bool,
    s0: np.uint64, s1: np.uint64, s2: np.uint64, s3: np.uint64,
) -> tuple:  # fmt: skip
    """A block's normals of step ``i`` (per run: of the run) into ``wr``, ``wl``: drawn from the
    block's stream (a whole block of each wheel, whose state it returns), or taken from column
    ``i`` of numpy's ``z_r``, ``z_l`` (m, width), rows ``p0 … p0+nb−1``."""
    if drawn:
        s0, s1, s2, s3 = _draw(wr, wr.shape[0], s0, s1, s2, s3)
        return _draw(wl, wl.shape[0], s0, s1, s2, s3)
    for q in range(nb):
        wr[q] = z_r[p0 + q, i]
        wl[q] = z_l[p0 + q, i]
    return s0, s1, s2, s3


@_part
def _block(
    key: np.ndarray, z_r: np.ndarray, z_l: np.ndarray, start_in: np.ndarray, b: int, nb: int, per_run: bool,
    scale_r: np.ndarray, scale_l: np.ndarray, eps_r: float, eps_l: float,
    nominal: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], track: float, rest: float, exact: bool,
    poly: bool,
    work: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:  # fmt: skip
    """Block ``b`` (particles ``b·BLOCK …``, ``nb`` of them) into ``work``, step by step.

    The normals: with a ``key`` (4 words; empty: numpy's draws) the block's own stream, in the
    order of :func:`.mc_kernel.block_draws`: the start offsets (``BLOCK × 3``), then per step (per
    run: once) the right wheel's ``BLOCK`` normals and the left wheel's; a last block of
    ``nb < BLOCK`` particles draws a whole block and moves the first ``nb``, so that a particle's
    numbers depend on the key and its index only. ``start_in``: drawn, ``A`` (3, 3) with the start
    offset ``A z``; else the chunk's offsets (m, 3); (0, 3): none. Without a key, ``z_r``,
    ``z_l`` (m, width) are numpy's normals of the chunk (its rows ``b·BLOCK …``).
    """
    v1, dtheta, cos_phi, sin_phi = nominal
    wr, wl, cum, off, x, y, big, offs = work
    block = wr.shape[0]  # BLOCK, as a variable (a constant argument would compile another copy)
    p0 = b * block
    drawn = key.shape[0] > 0
    s0 = s1 = s2 = s3 = _U1
    if drawn:
        s0, s1, s2, s3 = block_state(key, b)
    start = start_in.shape[0] > 0
    if start and drawn:  # offset = A z, z ~ N(0, I₃), particle by particle
        flat = offs.reshape(-1)
        s0, s1, s2, s3 = _draw(flat, flat.shape[0], s0, s1, s2, s3)
        for q in range(block):
            z0 = offs[q, 0]
            z1 = offs[q, 1]
            z2 = offs[q, 2]
            for j in range(3):
                offs[q, j] = (start_in[j, 0] * z0 + start_in[j, 1] * z1) + start_in[j, 2] * z2
    elif start:  # numpy's offsets of the chunk's particles
        for q in range(nb):
            for j in range(3):
                offs[q, j] = start_in[p0 + q, j]
    for q in range(nb):
        cum[q] = 0.0
        off[q] = offs[q, 2] if start else 0.0
        x[q] = 0.0
        y[q] = 0.0
        big[q] = 0.0
    if per_run:  # Δs' − Δs = (ε z) Δs
        s0, s1, s2, s3 = _normals(z_r, z_l, 0, p0, nb, wr, wl, drawn, s0, s1, s2, s3)
        for q in range(nb):
            wr[q] *= eps_r
            wl[q] *= eps_l
    for i in range(v1.shape[0]):
        if not per_run:  # Δs' − Δs = z √(k|Δs|)
            s0, s1, s2, s3 = _normals(z_r, z_l, i, p0, nb, wr, wl, drawn, s0, s1, s2, s3)
        _step(wr, wl, scale_r[i], scale_l[i], cum, off, x, y, big, nb, v1[i], dtheta[i], cos_phi[i],
              sin_phi[i], track, rest, exact, poly)  # fmt: skip


@_jit
def end_poses(
    key: np.ndarray, z_r: np.ndarray, z_l: np.ndarray, start_in: np.ndarray, block0: int, block1: int,
    per_run: bool, scale_r: np.ndarray, scale_l: np.ndarray, eps_r: float, eps_l: float, v1: np.ndarray,
    dtheta: np.ndarray, cos_phi: np.ndarray, sin_phi: np.ndarray, track: float, c: float, exact: bool,
    poly: bool, x0: float, y0: float, th_end: float, out: np.ndarray,
) -> None:  # fmt: skip
    """End poses of the particles of blocks ``block0 … block1−1`` into their rows of ``out`` (n, 3)
    (:func:`.mc_kernel.compiled_end_poses`; the normals and ``start_in`` as :func:`_block` takes
    them).

    A block whose heading perturbation leaves ``REDUCTION_LIMIT`` is recomputed (the same
    normals) with the C library's ``cos``/``sin``.
    """
    n = out.shape[0]
    B = BLOCK
    work = (np.empty(B), np.empty(B), np.empty(B), np.empty(B), np.empty(B), np.empty(B), np.empty(B),
            np.zeros((B, 3)))  # fmt: skip
    nominal = (v1, dtheta, cos_phi, sin_phi)
    cum, x, y, big, offs = work[2], work[4], work[5], work[6], work[7]
    start = start_in.shape[0] > 0
    for b in range(block0, block1):
        p0 = b * B
        nb = min(B, n - p0)
        _block(key, z_r, z_l, start_in, b, nb, per_run, scale_r, scale_l, eps_r, eps_l, nominal, track, 1.0 - c,
               exact, poly, work)  # fmt: skip
        if poly and big[:nb].max() > REDUCTION_LIMIT:  # again with the C library (not poly: False)
            _block(key, z_r, z_l, start_in, b, nb, per_run, scale_r, scale_l, eps_r, eps_l, nominal, track,
                   1.0 - c, exact, not poly, work)  # fmt: skip
        for q in range(nb):
            p = p0 + q
            dx = x[q]
            dy = y[q]
            heading = cum[q]
            if start:
                dx += offs[q, 0]
                dy += offs[q, 1]
                heading += offs[q, 2]
            out[p, 0] = x0 + dx
            out[p, 1] = y0 + dy
            out[p, 2] = th_end + heading
