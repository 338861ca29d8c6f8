"""Set-membership localization with bounded range and bearing errors: box SIVIA (Jaulin et al. 2001).

The fifth representation of the pose (after the Gaussian, the grid, the particles and the topological
belief): the set of every pose consistent with the measurements, for errors known only by their bounds
(Skalka 2011 §2.8). Each measurement of landmark ``m_j`` constrains the pose ``(x, y, θ)``::

    |‖m_j − (x, y)‖ − r_j| ≤ δ_r,       |wrap(atan2(m_y − y, m_x − x) − θ − φ_j)| ≤ δ_φ

SIVIA (Set Inversion Via Interval Analysis, Jaulin & Walter 1993) classifies boxes with inclusion
functions of the constraints: a box whose image misses a measurement's interval holds no solution
(dropped); one whose image lies inside every interval holds only solutions (kept, *inner*); the others
are bisected along their widest side (in units of ``eps``) until they are smaller than ``eps``
(kept, *boundary*). The kept boxes are a guaranteed outer approximation: the true pose is in one of
them whenever the errors respect their bounds. Every step of the loop classifies all current boxes
at once (vectorised over boxes and landmarks); the loop runs over bisection depths.

Inclusion functions (exact images of a box)
--------------------------------------------
* range: ``[d_min, d_max]`` — distance of the landmark to the nearest and the farthest point of the box;
* bearing: the angles of the landmark seen from the four corners (measured from the angle seen from
  the box centre, so they do not wrap) give the exact range of ``atan2`` over a box that does not
  hold the landmark (a convex set's extreme angles are at its corners); a box holding the landmark
  sees every angle. Minus ``[θ]``, and compared with ``[φ_j − δ_φ, φ_j + δ_φ]`` modulo 2π.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import wrap_angle
from ..core.validation import (
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_positive,
    check_positive_int,
)

__all__ = ["BoxSet", "bearing_image", "range_image", "sivia"]

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, eq=False)
class BoxSet:
    """A union of disjoint pose boxes: the solution set of :func:`sivia`.

    Attributes
    ----------
    lo, hi : ndarray, shape (K, 3) — bounds of ``(x, y, θ)`` [m, m, rad] of every box
    inner : ndarray of bool, shape (K,) — boxes proved to hold only solutions
    complete : bool — False when :func:`sivia` stopped at ``max_boxes`` (the set is still an
        outer approximation, only coarser)
    """

    lo: Array
    hi: Array
    inner: BoolArray
    complete: bool = True

    @property
    def volume(self) -> float:
        """Total volume of the boxes [m²·rad]."""
        return float(np.prod(self.hi - self.lo, axis=1).sum())

    def contains(self, poses: ArrayLike) -> BoolArray:
        """Whether poses (..., 3) lie in one of the boxes (θ compared modulo 2π), shape (...)."""
        p = check_last_axis("poses", poses, 3)
        flat = p.reshape(-1, 3)
        out = np.zeros(flat.shape[0], dtype=bool)
        for i, q in enumerate(flat):  # a few query poses against all boxes at once
            th = self.lo[:, 2] + np.mod(q[2] - self.lo[:, 2], _TWO_PI)  # q's heading, lifted above lo
            ok = np.all((q[:2] >= self.lo[:, :2]) & (q[:2] <= self.hi[:, :2]), axis=1) & (th <= self.hi[:, 2])
            out[i] = bool(ok.any())
        return out.reshape(p.shape[:-1])

    def xy_extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the union [m]."""
        return (float(self.lo[:, 0].min()), float(self.hi[:, 0].max()),
                float(self.lo[:, 1].min()), float(self.hi[:, 1].max()))  # fmt: skip


def range_image(lo: ArrayLike, hi: ArrayLike, landmarks: ArrayLike) -> tuple[Array, Array]:
    """Exact range of ``‖m − (x, y)‖`` over boxes: ``lo``, ``hi`` (K, 2) and landmarks (L, 2) → (K, L) each [m]."""
    a, b = check_last_axis("lo", lo, 2), check_last_axis("hi", hi, 2)
    m = check_last_axis("landmarks", landmarks, 2)
    near = np.maximum(np.maximum(a[:, None, :] - m, m - b[:, None, :]), 0.0)  # (K, L, 2)
    far = np.maximum(np.abs(a[:, None, :] - m), np.abs(b[:, None, :] - m))
    return np.hypot(near[..., 0], near[..., 1]), np.hypot(far[..., 0], far[..., 1])


def bearing_image(lo: ArrayLike, hi: ArrayLike, landmarks: ArrayLike) -> tuple[Array, Array, Array, BoolArray]:
    """Range of the absolute direction ``atan2(m_y − y, m_x − x)`` over boxes (K, 2) for landmarks (L, 2).

    Returns
    -------
    centre : ndarray, shape (K, L) — the direction seen from the box centre [rad]
    lower, upper : ndarray, shape (K, L) — the range is ``[centre + lower, centre + upper]`` (unwrapped)
    full : ndarray of bool, shape (K, L) — the box holds the landmark: every direction
    """
    a, b = check_last_axis("lo", lo, 2), check_last_axis("hi", hi, 2)
    m = check_last_axis("landmarks", landmarks, 2)
    c = 0.5 * (a + b)
    centre = np.arctan2(m[:, 1] - c[:, None, 1], m[:, 0] - c[:, None, 0])
    corners = [(a[:, 0], a[:, 1]), (a[:, 0], b[:, 1]), (b[:, 0], a[:, 1]), (b[:, 0], b[:, 1])]
    rel = np.stack([wrap_angle(np.arctan2(m[:, 1] - y[:, None], m[:, 0] - x[:, None]) - centre)
                    for x, y in corners])  # fmt: skip
    full = np.all((a[:, None, :] <= m) & (m <= b[:, None, :]), axis=-1)
    return np.asarray(centre, dtype=np.float64), rel.min(axis=0), rel.max(axis=0), np.asarray(full, dtype=bool)


def _classify(lo: Array, hi: Array, z: Array, landmarks: Array, d_r: float, d_phi: float,
              use_range: bool, use_bearing: bool) -> tuple[BoolArray, BoolArray]:  # fmt: skip
    """(possibly feasible, surely feasible) of every box (K,) against every measurement."""
    possible = np.ones(lo.shape[0], dtype=bool)
    sure = np.ones(lo.shape[0], dtype=bool)
    if use_range:
        r_lo, r_hi = range_image(lo[:, :2], hi[:, :2], landmarks)
        possible &= np.all((r_hi >= z[:, 0] - d_r) & (r_lo <= z[:, 0] + d_r), axis=1)
        sure &= np.all((r_lo >= z[:, 0] - d_r) & (r_hi <= z[:, 0] + d_r), axis=1)
    if use_bearing:
        centre, lower, upper, full = bearing_image(lo[:, :2], hi[:, :2], landmarks)
        # predicted − measured bearing: [centre + lower − θ_hi, centre + upper − θ_lo] − φ, wrapped about its middle
        mid = wrap_angle(centre + 0.5 * (lower + upper) - 0.5 * (lo[:, 2:3] + hi[:, 2:3]) - z[:, 1])
        half = 0.5 * (upper - lower) + 0.5 * (hi[:, 2:3] - lo[:, 2:3])
        wide = full | (half >= math.pi)
        possible &= np.all(wide | (np.abs(mid) - half <= d_phi), axis=1)
        sure &= np.all(~wide & (np.abs(mid) + half <= d_phi), axis=1)
    return possible, sure & possible


def sivia(
    z: ArrayLike, landmarks: ArrayLike, bounds: tuple[float, float, float, float], *,
    range_bound: float | None = None, bearing_bound: float | None = None,
    eps: tuple[float, float] = (0.05, 0.05), max_boxes: int = 200_000,
) -> BoxSet:  # fmt: skip
    """Every pose consistent with bounded-error range and/or bearing measurements (module docs).

    Parameters
    ----------
    z : array_like, shape (L, 2) — measured ``(r [m], φ [rad])`` of each landmark (a column unused
        when its bound is None)
    landmarks : array_like, shape (L, 2) [m] — the landmark of each measurement
    bounds : (x_min, x_max, y_min, y_max) [m] — the region searched; θ in [−π, π]
    range_bound : float [m], optional — δ_r; None: ranges not used
    bearing_bound : float [rad], optional — δ_φ; None: bearings not used (θ is then not bisected)
    eps : (float [m], float [rad]) — boxes smaller than this in position and heading are not bisected
    max_boxes : int — bisection stops when the next depth would hold more boxes (``complete`` False)

    Returns
    -------
    BoxSet — inner and boundary boxes
    """
    zz = check_finite("z", check_last_axis("z", z, 2)).reshape(-1, 2)
    m = check_finite("landmarks", check_last_axis("landmarks", landmarks, 2)).reshape(-1, 2)
    if m.shape != zz.shape:
        raise ValueError(f"landmarks must match z (allowed: shape {zz.shape}), got shape {m.shape}")
    if range_bound is None and bearing_bound is None:
        raise ValueError("range_bound or bearing_bound must be given (allowed: a bound for some measurement)")
    d_r = float(check_nonnegative("range_bound", range_bound)) if range_bound is not None else 0.0
    d_phi = float(check_nonnegative("bearing_bound", bearing_bound)) if bearing_bound is not None else 0.0
    e = check_positive("eps", eps)
    cap = check_positive_int("max_boxes", max_boxes)
    scale = np.array([e[0], e[0], e[1] if bearing_bound is not None else np.inf])
    lo = np.array([[bounds[0], bounds[2], -math.pi]])
    hi = np.array([[bounds[1], bounds[3], math.pi]])
    kept_lo: list[Array] = []
    kept_hi: list[Array] = []
    kept_inner: list[BoolArray] = []
    complete = True
    while lo.shape[0]:  # one bisection depth per pass, every box of it at once
        possible, sure = _classify(lo, hi, zz, m, d_r, d_phi, range_bound is not None, bearing_bound is not None)
        rel = (hi - lo) / scale
        small = rel.max(axis=1) <= 1.0
        stop = possible & (sure | small)
        split = possible & ~stop
        if 2 * int(split.sum()) + sum(a.shape[0] for a in kept_lo) > cap:
            stop, split, complete = possible, np.zeros_like(possible), False
        kept_lo.append(lo[stop])
        kept_hi.append(hi[stop])
        kept_inner.append(sure[stop])
        lo, hi = _bisect(lo[split], hi[split], rel[split])
    return BoxSet(np.concatenate(kept_lo), np.concatenate(kept_hi), np.concatenate(kept_inner), complete)


def _bisect(lo: Array, hi: Array, rel: Array) -> tuple[Array, Array]:
    """Halve every box (K, 3) across its widest side in units of ``eps`` (``rel``): (2K, 3) boxes."""
    k = np.argmax(rel, axis=1)
    rows = np.arange(lo.shape[0])
    mid = 0.5 * (lo[rows, k] + hi[rows, k])
    hi_a, lo_b = hi.copy(), lo.copy()
    hi_a[rows, k] = mid
    lo_b[rows, k] = mid
    return np.concatenate([lo, lo_b]), np.concatenate([hi_a, hi])
