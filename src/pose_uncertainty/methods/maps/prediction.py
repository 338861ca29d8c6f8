"""One histogram-filter prediction step on a fixed grid, by FFT convolution.

The kernel depends on ``x_t − x_{t−1}`` rotated by the source heading ``θ_k`` only, so
:func:`predict_on_grid` convolves every source-heading slice of the belief with its
heading's kernel window (2-D FFT, the kernels of all destination headings accumulated
in the Fourier domain, one inverse FFT per destination slice), then applies the
heading-only noise along θ. Batch and block sizes bound the scratch memory and change
no value.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ...core.grids import Grid
from ...core.threads import default_workers
from ...core.validation import (
    check_nonnegative,
)
from .kernels import AnyArray, Array, _axis_parts
from .transition import GridTransition, _Kernel, _rotated_cells


def _drop_negligible_slices(belief: Array, copy: bool = False) -> tuple[Array, float, AnyArray]:
    """Zero the heading slices holding < 1e-14: (belief, mass dropped, indices of the others).

    In place, or with ``copy`` on a copy made only when a slice has to be zeroed.
    """
    mass_k = belief.sum(axis=(0, 1))
    tiny = mass_k < 1e-14
    dropped = 0.0
    drop = np.flatnonzero(tiny & (mass_k != 0.0))  # (the other tiny slices hold zeros only)
    if drop.size:
        dropped = float(mass_k[tiny].sum())
        belief = belief.copy() if copy else belief
        belief[:, :, drop] = 0.0
    return belief, dropped, np.flatnonzero(~tiny)


#: Scratch bytes of :func:`_source_windows` per batch of headings (the cells and masses of
#: every part of every node: a cache-sized block).
_WINDOW_BATCH_BYTES = 1 << 20


def _source_windows(
    kern: _Kernel,
    ks: AnyArray,
    thetas: Array,
    h: float,
    windows: tuple[AnyArray, AnyArray, int, int],
) -> Array:
    """Kernels of the source headings ``ks`` (K,) on their windows: mass per (x, y, heading offset).

    Returns shape (K, wx, wy, mp). Every node is deposited on the three axes
    (:func:`_axis_parts`: ``S_x · S_y · S_t`` parts), summed by :func:`_sum_parts`; a
    heading's window does not depend on which other headings share its batch.
    """
    ax, ay, wx, wy = windows
    # heading offsets carried by the position nodes (CIC); the heading-only noise
    # (γΔt or δrot2) is applied afterwards as a circular convolution along θ
    jt, vt = kern.head_parts
    mp, n_q = kern.head_mp, kern.weight.size
    batch = max(1, _WINDOW_BATCH_BYTES // (16 * 16 * jt.shape[0] * n_q))  # ≤ 4 × 4 × S_t parts
    fxy = _rotated_cells(kern, thetas, h)
    out = np.empty((ks.size, wx * wy * mp))
    for a in range(0, ks.size, batch):
        k = ks[a : a + batch]
        jx, vx, jy, vy = _position_parts(kern, k, fxy, thetas, h)
        jx -= ax[k][:, None, None]
        jy -= ay[k][:, None, None]
        if jx.min() < 0 or jy.min() < 0 or jx.max() >= wx or jy.max() >= wy:
            raise RuntimeError("kernel node outside its window (internal error)")
        # cell of every (heading, x part, y part, θ part, node) in its window, and its mass
        cell = (jx[:, :, None, None, :] * wy + jy[:, None, :, None, :]) * mp + jt[None, None, None]
        mass = ((kern.weight * vx)[:, :, None, None, :] * vy[:, None, :, None, :]) * vt[None, None, None]
        out[a : a + k.size] = _sum_parts(cell.reshape(k.size, -1, n_q), mass.reshape(k.size, -1, n_q), out.shape[1])
    return out.reshape(ks.size, wx, wy, mp)


def _sum_parts(cell: AnyArray, mass: Array, size: int) -> Array:
    """Deposit the parts of the nodes: ``Σ_p (Σ_q mass[k, p, q] at cell[k, p, q])``, shape (K, size).

    ``cell``, ``mass`` (K, P, Q): the cell (of ``size``) and the mass of node q's part p
    for heading k. As one deposit per part, added one after the other: each part's
    sum over the nodes in node order, then the parts in part order (two sequential
    ``bincount``), without a (K, P, size) array. Every part of a heading is its first part
    moved by one cell offset (:func:`_axis_parts` shifts whole rows), so the nodes that
    share a cell share it in every part and are grouped once.
    """
    n_k, n_p, n_q = cell.shape
    first, group = np.unique((cell[:, 0] + size * np.arange(n_k)[:, None]).ravel(), return_inverse=True)
    group = group.reshape(n_k, 1, n_q)
    # Σ over the nodes of each (part, group), in node order
    per_group = np.bincount((np.arange(n_p)[:, None] * first.size + group).ravel(), mass.ravel(),
                            minlength=n_p * first.size)  # fmt: skip
    # Σ over the parts of each cell, in part order
    shift = cell[:, :, 0] - cell[:, :1, 0]  # (K, P) the parts' offsets
    target = first + shift[first // size].T  # (P, groups)
    return np.asarray(np.bincount(target.ravel(), per_group, minlength=n_k * size), np.float64).reshape(n_k, size)


def _position_parts(
    kern: _Kernel, ks: AnyArray, fxy: tuple[Array, Array], thetas: Array, h: float
) -> tuple[AnyArray, Array, AnyArray, Array]:
    """The nodes' deposits on the x and the y axis for source headings ``ks`` (K,).

    ``fxy``: the nodes' world offsets [cells] for every heading of ``thetas``, (nθ, Q) each
    (:func:`_rotated_cells`). Returns ``(jx, vx, jy, vy)``, each of shape (K, S, Q)
    (:func:`_axis_parts`).
    """
    fx, fy = fxy[0][ks], fxy[1][ks]
    c_ = np.array([math.cos(thetas[k]) for k in ks])[:, None]
    s_ = np.array([math.sin(thetas[k]) for k in ks])[:, None]
    sa, sb = kern.step_a, kern.step_b
    # extent of each node's interval on the world axes [cells]
    wdx = (np.abs(c_ * sa[:, 0] - s_ * sa[:, 1]) + np.abs(c_ * sb[:, 0] - s_ * sb[:, 1])) / h
    wdy = (np.abs(s_ * sa[:, 0] + c_ * sa[:, 1]) + np.abs(s_ * sb[:, 0] + c_ * sb[:, 1])) / h
    jx, vx = _axis_parts(fx, np.minimum(wdx, 1.0), kern.weight)
    jy, vy = _axis_parts(fy, np.minimum(wdy, 1.0), kern.weight)
    return jx, vx, jy, vy


def _heading_noise(
    planes: Array, headings: AnyArray, kern: _Kernel, new: Array, workers: int
) -> tuple[Array, float]:
    """Heading-only noise, then the round-off clipped: (belief, sum of the negatives clipped).

    ``planes`` (T, nx, ny) are the belief's slices at ``headings`` (T,), the other slices
    empty; the result is written into ``new`` (nx, ny, nθ). Circular convolution along θ
    with the CIC-deposited γΔt / δrot2 (FFT along θ), on blocks of x rows that stay in
    cache (each θ line is transformed as a whole, so the blocks do not change a value);
    negative round-off is set to zero.
    """
    import scipy.fft as sfft  # imported where used: a run without a map never pays its 0.15 s

    nx, ny, nt = new.shape
    g_circ = np.bincount((kern.head_lo + np.arange(kern.head_kernel.size)) % nt, kern.head_kernel, minlength=nt)
    g_hat = sfft.rfft(g_circ)
    rows = max(1, _BLOCK // (ny * nt))
    block = np.zeros((nt, rows, ny))  # θ first: the slices are copied as planes; empty headings stay 0
    negatives = []
    for i0 in range(0, nx, rows):
        r = min(rows, nx - i0)
        block[headings, :r] = planes[:, i0 : i0 + r]
        spectrum = sfft.rfft(np.moveaxis(block[:, :r], 0, 2), axis=2, workers=workers)
        spectrum *= g_hat
        out = new[i0 : i0 + r]
        out[...] = sfft.irfft(spectrum, n=nt, axis=2, workers=workers, overwrite_x=True)
        flat = out.reshape(-1)
        neg = np.flatnonzero(flat < 0.0)  # (indices: a boolean mask of ~½ density is slow to apply)
        negatives.append(flat[neg])
        flat[neg] = 0.0
    return new, float(-np.concatenate(negatives).sum())


#: Elements of a block of :func:`_heading_noise` (256 kB of float64: its temporaries stay in
#: cache and are reused by the allocator instead of being mapped afresh at every step).
_BLOCK = 1 << 15


def _convolve_step(
    belief: Array,
    g: Grid,
    kern: _Kernel,
    active: AnyArray,
    windows: tuple[AnyArray, AnyArray, int, int],
    thetas: Array,
    workers: int,
    cache: dict[int, Array] | None = None,
    out: Array | None = None,
) -> tuple[Array, float, float]:
    """One prediction step on a fixed grid: (new belief, round-off clipped, mass lost off the grid).

    Every active source-heading slice is convolved (2-D FFT) with its kernel
    window, the kernels of all destination headings accumulated in the Fourier domain.
    ``thetas`` (nθ,) are the source headings of the belief's slices [rad]. ``cache``
    (a transition's own) keeps each heading's window for the next step with the same kernel.
    ``out``: a C-contiguous array of the belief's shape for the new belief (``belief`` itself
    may be given: it is read before ``out`` is written); default a new array.
    """
    import scipy.fft as sfft  # imported where used: a run without a map never pays its 0.15 s

    ax, ay, wx, wy = windows
    nx, ny, nt = g.nx, g.ny, g.ntheta
    # FFT sizes: linear convolution of every slice with its shifted window, no wrap-around
    sx0, sy0 = min(int(ax.min()), 0), min(int(ay.min()), 0)
    ex, ey = max(int((ax + wx - 1).max()), 0), max(int((ay + wy - 1).max()), 0)
    Px = sfft.next_fast_len(nx + ex - sx0, real=True)
    Py = sfft.next_fast_len(ny + ey - sy0, real=True)
    mass_before = float(belief.sum())
    kernels, dest = _heading_kernels(kern, active, thetas, g.resolution, windows, nt, cache)
    # the spectra of the destination headings that receive mass, accumulated over the sources
    touched = np.unique(dest)
    row = np.zeros(nt, dtype=np.int64)
    row[touched] = np.arange(touched.size)
    dest = row[dest]
    acc = np.zeros((touched.size, Px, Py // 2 + 1), dtype=np.complex128)
    plane, m = Px * (Py // 2 + 1), kernels.shape[1]
    per_heading = 16 * ((m + 1) * plane + m * wx * Py)  # the spectra and the row transforms
    batch = max(1, _SPECTRA_BATCH_BYTES // per_heading)
    for a in range(0, active.size, batch):
        b = min(active.size, a + batch)
        # offsets of the windows in the padded plane
        offsets = (ax[active[a:b]] - sx0, ay[active[a:b]] - sy0)
        khat = _kernel_spectra(kernels[a:b], offsets, (Px, Py), workers)
        khat *= sfft.rfftn(np.moveaxis(belief[:, :, active[a:b]], 2, 0), s=(Px, Py), axes=(1, 2),
                           workers=workers)[:, None]  # fmt: skip
        for i in range(b - a):  # in the order of the headings: the sums do not depend on the batches
            d = dest[a + i]
            if d[-1] - d[0] == m - 1:  # consecutive rows
                acc[d[0] : d[-1] + 1] += khat[i]
            else:
                acc[d] += khat[i]
    planes = sfft.irfft2(acc, s=(Px, Py), workers=workers, overwrite_x=True)[:, -sx0 : -sx0 + nx, -sy0 : -sy0 + ny]
    new, roundoff = _heading_noise(planes, touched, kern, np.empty((nx, ny, nt)) if out is None else out, workers)
    lost_step = max(0.0, mass_before - float(new.sum()))
    return new, roundoff, lost_step


#: Bytes of the FFT buffers of one batch of source headings in :func:`_convolve_step` (a batch
#: shares the FFT calls; its size changes no value).
_SPECTRA_BATCH_BYTES = 1 << 20


def _heading_kernels(
    kern: _Kernel,
    active: AnyArray,
    thetas: Array,
    h: float,
    windows: tuple[AnyArray, AnyArray, int, int],
    nt: int,
    cache: dict[int, Array] | None,
) -> tuple[Array, AnyArray]:
    """Kernels of the active source headings by destination: (K, M, wx, wy), and their destinations (K, M).

    ``M`` is the kernel's number of heading offsets, or ``nθ`` when they wrap round the
    circle (then folded onto the ``nθ`` shifts). Windows missing from ``cache`` are
    built (:func:`_source_windows`) and stored in it.
    """
    m_lo_p, mp = kern.head_m_lo, kern.head_mp
    cache = {} if cache is None else cache
    missing = np.array([k for k in active if int(k) not in cache], dtype=np.int64)
    if missing.size:
        cache.update(zip(missing.tolist(), _source_windows(kern, missing, thetas, h, windows), strict=True))
    win = np.stack([cache[int(k)] for k in active])
    if mp > nt:  # heading offsets wrap round the circle: fold them onto nθ shifts
        folded = np.zeros((*win.shape[:3], nt))
        for j in range(mp):
            folded[..., (m_lo_p + j) % nt] += win[..., j]
        return np.moveaxis(folded, 3, 1), (active[:, None] + np.arange(nt)) % nt
    return np.moveaxis(win, 3, 1), (active[:, None] + m_lo_p + np.arange(mp)) % nt


def _kernel_spectra(
    kernels: Array, offsets: tuple[AnyArray, AnyArray], shape: tuple[int, int], workers: int
) -> Array:
    """2-D real FFT of each kernel window placed at its offset in a zero plane of ``shape``.

    ``kernels`` (K, M, wx, wy), ``offsets`` (K,) each [cells]; returns (K, M, Px, Py//2+1).
    Two passes, so that the rows outside the windows are never transformed.
    """
    import scipy.fft as sfft  # imported where used: a run without a map never pays its 0.15 s

    n_k, m, wx, wy = kernels.shape
    Px, Py = shape
    rows = np.zeros((n_k, m, wx, Py))
    for i, oy_ in enumerate(offsets[1]):
        rows[i, :, :, oy_ : oy_ + wy] = kernels[i]
    khat_y = sfft.rfft(rows, axis=3, workers=workers)
    cols = np.zeros((n_k, m, Px, Py // 2 + 1), dtype=np.complex128)
    for i, ox_ in enumerate(offsets[0]):
        cols[i, :, ox_ : ox_ + wx] = khat_y[i]
    return np.asarray(sfft.fft(cols, axis=2, workers=workers, overwrite_x=True))


def predict_on_grid(
    belief: ArrayLike, transition: GridTransition, workers: int | None = None, *, overwrite_belief: bool = False
) -> tuple[Array, dict[str, float]]:
    """One histogram-filter prediction step on a fixed grid (the step of :func:`multi_step_map`).

    Parameters
    ----------
    belief : array_like, shape (nx, ny, nθ) — probability mass per cell of ``transition.grid``
    transition : GridTransition
    workers : int, optional — FFT threads (default: :func:`~pose_uncertainty.core.threads.default_workers`;
        the result does not depend on it)
    overwrite_belief : bool — ``belief`` (a float64 array the caller no longer needs) may be
        overwritten: its negligible heading slices zeroed in place, and the new belief
        written into it (then returned) instead of into a new array

    Returns
    -------
    belief' : ndarray, shape (nx, ny, nθ) — sums to ``Σ belief − lost_mass``
    info : dict — ``lost_mass`` (left the grid, including negligible heading slices
        dropped), ``roundoff`` (negative round-off clipped), ``negligible_slices``
    """
    g = transition.grid
    b = check_nonnegative("belief", belief)
    if b.shape != g.shape:
        raise ValueError(f"belief must have the grid's shape {g.shape}, got shape {b.shape}")
    own = overwrite_belief or not b.flags.c_contiguous  # (a C-ordered copy is ours; sums run in C order)
    workers = default_workers() if workers is None else workers
    b, dropped, active = _drop_negligible_slices(np.ascontiguousarray(b), copy=not own)
    if active.size == 0:
        return np.zeros(g.shape), {"lost_mass": dropped, "roundoff": 0.0, "negligible_slices": dropped}
    new, roundoff, lost = _convolve_step(
        b, g, transition.kernel, active, transition.windows, g.theta, workers, transition.source_windows,
        b if own else None,
    )  # fmt: skip
    return new, {"lost_mass": lost + dropped, "roundoff": roundoff, "negligible_slices": dropped}
