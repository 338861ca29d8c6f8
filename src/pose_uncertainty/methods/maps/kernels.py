"""Array kernels shared by the single- and multi-step maps.

Bare functions on arrays, no map objects: the slab test of a ray against a cell
(:func:`_ray_box`), midpoint quadrature nodes, the trilinear deposit of a point mass
on a grid (:func:`_deposit`), and the exact-overlap splat of little intervals on the
cells of one axis (:func:`_splat`, :func:`_axis_parts`, :func:`_split_rows`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...core.grids import Grid

Array = NDArray[np.float64]


AnyArray = NDArray[Any]  # index and mask arrays


def _ray_box(beta: Array, s: Array, lo: Array, hi: Array) -> tuple[Array, Array]:
    """Distances ``t0 ≤ t1`` (≥ 0) at which the ray from ``s`` along ``beta`` is inside the box.

    Slab method; an empty intersection gives ``t0 = t1 = 0``.
    """
    t0 = np.zeros_like(beta)
    t1 = np.full_like(beta, np.inf)
    for axis, d in ((0, np.cos(beta)), (1, np.sin(beta))):
        flat = np.abs(d) < 1e-300
        safe = np.where(flat, 1.0, d)
        ta, tb = (lo[axis] - s[axis]) / safe, (hi[axis] - s[axis]) / safe
        inside = (lo[axis] <= s[axis]) & (s[axis] <= hi[axis])
        t0 = np.maximum(t0, np.where(flat, np.where(inside, 0.0, np.inf), np.minimum(ta, tb)))
        t1 = np.minimum(t1, np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(ta, tb)))
    empty = ~(t1 > t0)
    return np.where(empty, 0.0, t0), np.where(empty, 0.0, t1)


def _midpoint_nodes(
    mean: float, std: float, lo: float, hi: float, reach: float, n_nodes: int
) -> tuple[Array, float]:
    """Midpoint rule on ``mean ± reach·std`` clipped to ``[lo, hi]``: (nodes, their spacing).

    A zero ``std`` gives the single node ``mean`` with weight 1.
    """
    if std <= 0.0:
        return np.array([mean]), 1.0
    a_, b_ = max(mean - reach * std, lo), min(mean + reach * std, hi)
    step = (b_ - a_) / n_nodes
    return np.asarray(a_ + step * (np.arange(n_nodes) + 0.5), dtype=np.float64), step


def _deposit(values: Array, grid: Grid, pose: Array, mass: float = 1.0) -> None:
    """Trilinear (mean-preserving) deposit of ``mass`` at ``pose`` into ``values`` (in place)."""
    h, ht = grid.resolution, grid.theta_resolution
    fx = (pose[0] - grid.x0) / h
    fy = (pose[1] - grid.y0) / h
    ft = (pose[2] - grid.theta0) / ht
    ix, iy, it = math.floor(fx), math.floor(fy), math.floor(ft)
    ax, ay, at = fx - ix, fy - iy, ft - it
    for dx_, wx in ((0, 1 - ax), (1, ax)):
        for dy_, wy in ((0, 1 - ay), (1, ay)):
            for dt_, wt in ((0, 1 - at), (1, at)):
                w = wx * wy * wt
                if w <= 0:
                    continue
                jx, jy = ix + dx_, iy + dy_
                if 0 <= jx < grid.nx and 0 <= jy < grid.ny:
                    values[jx, jy, (it + dt_) % grid.ntheta] += mass * w


def _splat(f: Array, width: Array) -> tuple[AnyArray, Array]:
    """Deposit segments ``[f − w/2, f + w/2]`` (cell units, ``w ≤ 1``) by exact overlap with cells.

    Returns the first cell ``i`` and the fraction ``first`` of the segment in it (the rest
    is in ``i + 1``), both of the shape of ``f``.
    """
    left = f - width / 2.0
    i = np.floor(left + 0.5).astype(np.int64)
    safe = np.where(width > 0, width, 1.0)
    first = np.where(width > 0, np.clip((i + 0.5 - left) / safe, 0.0, 1.0), 1.0)
    return i, first


def _axis_parts(f: Array, width: Array, weight: Array) -> tuple[AnyArray, Array]:
    """How the nodes at continuous cell coordinates ``f`` are deposited on one axis.

    Parameters
    ----------
    f, width : ndarray, shape (K, Q) — K rows (source headings) of the Q nodes [cells]
    weight : ndarray, shape (Q,) — the nodes' masses (for each row's mean and spread)

    Returns
    -------
    index : ndarray of int64, shape (K, S, Q) — cell of each node in each of the S parts
    factor : ndarray, shape (K, S, Q) — the share of the node's mass that part carries

    Each node stands for a segment of ``width`` cells (its control interval seen on
    this axis) and is deposited by exact overlap with the cells: with nodes ≤ ½ cell
    apart this integrates the kernel over the cells, as a histogram of samples does,
    without the aliasing of nearest-cell rounding and with only ``w²/12`` of spread
    (two parts: the first cell and the next). When the kernel of a row is narrower
    than half a cell (weighted standard deviation < ½) it is split into its mean
    ``μ`` and the deviations ``f − μ``: the deviations are deposited as above (exact
    for a thin centred ridge) and the mean is shared linearly between ``⌊μ⌋`` and
    ``⌊μ⌋+1`` (cloud-in-cell), so a sub-cell drift is kept, not rounded away, at the
    price of ``frac(1−frac)`` cell² (four parts). When some rows are split and others
    not, S = 4 and the unsplit rows carry two parts of zero mass (an exact no-op in
    any sum).
    """
    mean, split = _split_rows(f, weight)
    dev = f - mean[:, None]
    i, first = _splat(np.where(split[:, None], dev, f), width)
    rest = 1.0 - first
    if not split.any():
        return np.stack([i, i + 1], axis=1), np.stack([first, rest], axis=1)
    base = np.where(split, np.floor(mean), 0.0)
    frac = mean - base
    lo, hi = np.where(split, 1.0 - frac, 1.0)[:, None], np.where(split, frac, 0.0)[:, None]
    ib = i + base.astype(np.int64)[:, None]
    return (np.stack([ib, ib + split[:, None], ib + 1, ib + 1 + split[:, None]], axis=1),
            np.stack([first * lo, first * hi, rest * lo, rest * hi], axis=1))  # fmt: skip


def _split_rows(f: Array, weight: Array) -> tuple[Array, AnyArray]:
    """Which rows of ``f`` (K, Q) :func:`_axis_parts` splits (spread < ½ cell), and their weighted means.

    Returns ``(mean, split)``, shapes (K,): ``mean`` is exact (the dot product of one row,
    as for a single row) where ``split``, else only an estimate (unused). The decision is
    taken on vectorised estimates of the spread, which differ from the row-by-row value
    by round-off only: rows within 10⁻⁹ of ½ are decided row by row.
    """
    mean = f @ weight
    std = np.sqrt(np.maximum(((f - mean[:, None]) ** 2) @ weight, 0.0))
    split = std < 0.5
    for r in np.flatnonzero(np.abs(std - 0.5) <= 1e-9):  # a spread at the threshold: as one row
        m = float(weight @ f[r])
        split[r] = not math.sqrt(max(float(weight @ (f[r] - m) ** 2), 0.0)) >= 0.5
    for r in np.flatnonzero(split):
        mean[r] = float(weight @ f[r])
    return mean, split
