"""The loops of :mod:`.mc_kernel`, compiled by numba (imported by it on first use only).

Blocks of :data:`BLOCK` particles: the block's wheel errors are laid out step by step
(``(N, BLOCK)``, so that the loop over the particles of one step is a loop over contiguous
numbers, which LLVM turns into AVX2/AVX-512 vector code on any x86-64 CPU), then every step
moves the block's particles in registers. The sine and cosine are :func:`sin_cos`: branch-free
polynomials, so that they vectorise too.
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: particles per block: the block's errors (2 × N × BLOCK numbers) stay in the CPU's caches
BLOCK = 32

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
    zr: np.ndarray, zl: np.ndarray, cum: np.ndarray, off: np.ndarray, x: np.ndarray, y: np.ndarray,
    big: np.ndarray, nb: int, v1: float, dtheta: float, cos_phi: float, sin_phi: float, track: float,
    rest: float, exact: bool, poly: bool,
) -> None:  # fmt: skip
    """One step of ``nb`` particles (the arithmetic of :func:`.drive_sampling._end_poses`)."""
    for q in range(nb):
        dr = zr[q]
        dl = zl[q]
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


@_inline
def _block(
    z_r: np.ndarray, z_l: np.ndarray, p0: int, nb: int, scale_r: np.ndarray, scale_l: np.ndarray,
    eps_r: float, eps_l: float, nominal: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    track: float, rest: float, exact: bool, poly: bool, offset: np.ndarray,
    work: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:  # fmt: skip
    """Particles ``p0 … p0+nb−1``: their errors step by step, then every step."""
    v1, dtheta, cos_phi, sin_phi = nominal
    zr, zl, cum, off, x, y, big = work
    per_run = z_r.shape[1] == 1
    for q in range(nb):
        p = p0 + q
        w_r = z_r[p, 0] * eps_r
        w_l = z_l[p, 0] * eps_l
        for i in range(v1.shape[0]):
            if per_run:  # Δs' − Δs = (ε z) Δs
                zr[i, q] = w_r * scale_r[i]
                zl[i, q] = w_l * scale_l[i]
            else:  # Δs' − Δs = z √(k|Δs|)
                zr[i, q] = z_r[p, i] * scale_r[i]
                zl[i, q] = z_l[p, i] * scale_l[i]
        cum[q] = 0.0
        off[q] = offset[p, 2] if offset.shape[0] > 0 else 0.0
        x[q] = 0.0
        y[q] = 0.0
        big[q] = 0.0
    for i in range(v1.shape[0]):
        _lanes(zr[i], zl[i], cum, off, x, y, big, nb, v1[i], dtheta[i], cos_phi[i], sin_phi[i], track,
               rest, exact, poly)  # fmt: skip


@_jit
def end_poses(
    z_r: np.ndarray, z_l: np.ndarray, scale_r: np.ndarray, scale_l: np.ndarray, eps_r: float,
    eps_l: float, v1: np.ndarray, dtheta: np.ndarray, cos_phi: np.ndarray, sin_phi: np.ndarray,
    track: float, c: float, exact: bool, poly: bool, offset: np.ndarray, x0: float, y0: float,
    th_end: float, out: np.ndarray,
) -> None:  # fmt: skip
    """End poses of ``m`` particles into ``out`` (m, 3) (:func:`.mc_kernel.compiled_end_poses`).

    A block whose heading perturbation leaves ``REDUCTION_LIMIT`` is recomputed with the C
    library's ``cos``/``sin``.
    """
    m = z_r.shape[0]
    n_steps = v1.shape[0]
    work = (np.empty((n_steps, BLOCK)), np.empty((n_steps, BLOCK)), np.empty(BLOCK), np.empty(BLOCK),
            np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK))  # fmt: skip
    nominal = (v1, dtheta, cos_phi, sin_phi)
    cum, x, y, big = work[2], work[4], work[5], work[6]
    for p0 in range(0, m, BLOCK):
        nb = min(BLOCK, m - p0)
        _block(z_r, z_l, p0, nb, scale_r, scale_l, eps_r, eps_l, nominal, track, 1.0 - c, exact, poly,
               offset, work)  # fmt: skip
        if poly and big[:nb].max() > REDUCTION_LIMIT:
            _block(z_r, z_l, p0, nb, scale_r, scale_l, eps_r, eps_l, nominal, track, 1.0 - c, exact,
                   False, offset, work)  # fmt: skip
        for q in range(nb):
            p = p0 + q
            dx = x[q]
            dy = y[q]
            heading = cum[q]
            if offset.shape[0] > 0:
                dx += offset[p, 0]
                dy += offset[p, 1]
                heading += offset[p, 2]
            out[p, 0] = x0 + dx
            out[p, 1] = y0 + dy
            out[p, 2] = th_end + heading


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
