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


@_jit
def _wrap(a: float) -> float:
    """:func:`pose_uncertainty.core.kinematics.wrap_angle` of one angle: (−π, π]."""
    t = a + math.pi
    w = t - 2.0 * math.pi * math.floor(t / (2.0 * math.pi)) if not (0.0 <= t < 2.0 * math.pi) else t
    w -= math.pi
    return math.pi if w == -math.pi else w


@_jit
def ut_march(
    ds_r: np.ndarray, ds_l: np.ndarray, k_r: float, k_l: float, track: float, Wm: np.ndarray,
    Wc: np.ndarray, spread: float, poses: np.ndarray, covs: np.ndarray,
) -> None:  # fmt: skip
    """Method C's loop (:func:`.unscented.ut_step` of one set, step after step), in place.

    ``poses[0]`` (3,) and ``covs[0]`` (3, 3) hold the start; step ``i`` fills ``poses[i + 1]``,
    ``covs[i + 1]``: the PSD Cholesky factor of the covariance (a pivot ≤ 1e-14·max|P| gives a
    zero column), the 11 sigma points of the pose and the two wheel travels, the midpoint step
    of each, and the weighted mean (circular for the heading) and covariance of the moved points.
    """
    n_pts = Wm.size
    L = np.zeros((3, 3))
    pts = np.empty((n_pts, 3))
    r = np.empty(n_pts)
    lw = np.empty(n_pts)
    d = np.empty((n_pts, 3))
    for i in range(ds_r.size):
        P = covs[i]
        tol = 0.0
        for a in range(3):
            for b in range(3):
                tol = max(tol, abs(P[a, b]))
        tol *= 1e-14
        for j in range(3):
            acc = 0.0
            for k in range(j):
                acc += L[j, k] * L[j, k]
            dj = P[j, j] - acc
            ok = dj > tol
            root = math.sqrt(dj) if ok else 1.0
            L[j, j] = root if ok else 0.0
            for a in range(j + 1, 3):
                acc = 0.0
                for k in range(j):
                    acc += L[a, k] * L[j, k]
                L[a, j] = (P[a, j] - acc) / root if ok else 0.0
        for q in range(n_pts):
            for a in range(3):
                pts[q, a] = poses[i, a]
            r[q] = ds_r[i]
            lw[q] = ds_l[i]
        for j in range(3):
            for a in range(3):
                pts[1 + j, a] += spread * L[a, j]
                pts[6 + j, a] -= spread * L[a, j]
        dev_r = spread * math.sqrt(k_r * abs(ds_r[i]))
        dev_l = spread * math.sqrt(k_l * abs(ds_l[i]))
        r[4] += dev_r
        r[9] -= dev_r
        lw[5] += dev_l
        lw[10] -= dev_l
        mx = 0.0
        my = 0.0
        ss = 0.0
        sc = 0.0
        for q in range(n_pts):
            ds = (r[q] + lw[q]) / 2.0
            dth = (r[q] - lw[q]) / track
            th = pts[q, 2]
            phi = th + 0.5 * dth
            pts[q, 0] += ds * math.cos(phi)
            pts[q, 1] += ds * math.sin(phi)
            pts[q, 2] = th + dth
        for q in range(n_pts):
            mx += Wm[q] * pts[q, 0]
            my += Wm[q] * pts[q, 1]
            dq = _wrap(pts[q, 2] - pts[0, 2])
            ss += Wm[q] * math.sin(dq)
            sc += Wm[q] * math.cos(dq)
        mth = pts[0, 2] + math.atan2(ss, sc)
        poses[i + 1, 0] = mx
        poses[i + 1, 1] = my
        poses[i + 1, 2] = mth
        for q in range(n_pts):
            d[q, 0] = pts[q, 0] - mx
            d[q, 1] = pts[q, 1] - my
            d[q, 2] = _wrap(pts[q, 2] - mth)
        for a in range(3):
            for b in range(a, 3):
                s = 0.0
                for q in range(n_pts):
                    s += Wc[q] * d[q, a] * d[q, b]
                covs[i + 1, a, b] = s
                covs[i + 1, b, a] = s


#: :func:`exp_small`'s argument range: ``[-EXP_RANGE, 0]``
EXP_RANGE = 16.0
_INV_FACT = (1.0, 1.0, 1.0 / 2, 1.0 / 6, 1.0 / 24, 1.0 / 120, 1.0 / 720, 1.0 / 5040, 1.0 / 40320, 1.0 / 362880)


@_inline
def exp_small(x: float) -> float:
    """``exp(x)`` for ``x`` in ``[-16, 0]`` within a relative 1.2e-5, branch-free (it vectorises).

    ``exp(x) = exp(u)^16``, ``u = x/16`` in ``[-1, 0]``: ``exp(u)`` by its Taylor polynomial of
    degree 9 (remainder ``≤ |u|^10/10! ≤ 2.8e-7``, relative to ``exp(u) ≥ e^-1``: ``≤ 7.5e-7``),
    then four squarings (the relative error times 16), rounding adding ~1e-15.
    """
    u = x * (1.0 / 16.0)
    p = _INV_FACT[9]
    p = p * u + _INV_FACT[8]
    p = p * u + _INV_FACT[7]
    p = p * u + _INV_FACT[6]
    p = p * u + _INV_FACT[5]
    p = p * u + _INV_FACT[4]
    p = p * u + _INV_FACT[3]
    p = p * u + _INV_FACT[2]
    p = p * u + _INV_FACT[1]
    p = p * u + _INV_FACT[0]
    p = p * p
    p = p * p
    p = p * p
    return p * p


@_jit
def truncated_density(
    x: np.ndarray, y: np.ndarray, mx: np.ndarray, my: np.ndarray, p00: np.ndarray, p01: np.ndarray,
    p11: np.ndarray, log_peak: np.ndarray, log_floor: float, cx: np.ndarray, cy: np.ndarray, m00: np.ndarray,
    m01: np.ndarray, m11: np.ndarray, bound: np.ndarray, block: int, out: np.ndarray,
) -> None:  # fmt: skip
    """The planar density's quadrature sum at points, over the terms above ``e^log_floor`` only.

    Per point, a block of ``block`` consecutive nodes is skipped where its bound proves every
    term of it below the floor (``m00 dx² + 2 m01 dx dy + m11 dy² > bound``, ``d`` from the block's
    centre ``(cx, cy)``; ``bound < 0``: no node kept); in the others each node's term
    ``exp(log_peak_q − ½ (p − μ_q)ᵀ P_q (p − μ_q))`` (node ``q``: mean ``(mx, my)``, precision
    ``(p00, p01, p11)``) is added where its exponent is at least ``log_floor``, by
    :func:`exp_small` about the largest peak (within a relative 1e-5: the brackets of
    ``expcoords.density_quantiles`` allow 1e-4). The arrays are padded to whole blocks (padding:
    ``log_peak = -inf``).
    """
    top = log_floor
    for q in range(log_peak.size):
        top = max(top, log_peak[q])
    low = log_floor - top  # ≥ −(T + log n) > −EXP_RANGE
    terms = np.empty(block)
    for i in range(x.size):
        s = 0.0
        for b in range(cx.size):
            if bound[b] < 0.0:
                continue
            dx = x[i] - cx[b]
            dy = y[i] - cy[b]
            if m00[b] * dx * dx + 2.0 * m01[b] * dx * dy + m11[b] * dy * dy > bound[b]:
                continue
            o = b * block
            for k in range(block):  # elementwise: vectorised
                ex = x[i] - mx[o + k]
                ey = y[i] - my[o + k]
                e = log_peak[o + k] - top - 0.5 * (p00[o + k] * ex * ex + 2.0 * p01[o + k] * ex * ey
                                                   + p11[o + k] * ey * ey)  # fmt: skip
                keep = e >= low
                terms[k] = exp_small(e if keep else low) if keep else 0.0
            for k in range(block):
                s += terms[k]
        out[i] = s * math.exp(top)


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
