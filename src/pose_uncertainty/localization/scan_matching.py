"""Laser scan-to-map matching as a pose measurement for the EKF (Skalka 2011 §4.2.2).

Correlative matching (Olson 2009) on a likelihood field of the occupancy grid:

* the field (:func:`likelihood_field`): at every cell, ``−min(d, 3σ)²/(2σ²)`` with ``d`` the distance from
  the cell's centre to the nearest wall face (exact Euclidean distance transforms), so a scan endpoint
  on a wall scores 0 and one ``d`` metres off scores as a Gaussian of σ would, up to a cap;
* the search (:func:`correlative_match`): every candidate pose of a window about the prior —
  ``(x̄ + i·δ, ȳ + j·δ, θ̄ + k·δ_θ)`` — projects the scan's endpoints (readings below the maximum range) and
  sums the field at them (readings within 3σ_hit of the maximum range are no endpoints: the beam saw nothing) (interpolated bilinearly between cell centres): one vectorised gather over
  candidates × beams, no loop over candidates;
* the measurement: treating ``exp(score)`` as the likelihood of each candidate, their weighted mean and
  covariance ``R = Σ_c p_c (x_c − x̄_p)(x_c − x̄_p)ᵀ + diag(δ², δ², δ_θ²)/12`` (the
  candidates' spread plus the window's cell size): wide along a corridor where many candidates score alike,
  which is how an ambiguous scan shows;
* the update (:func:`ekf_update_pose`): the EKF's update with the direct pose measurement ``z = x + N(0, R)``
  (``H = I``, the heading's innovation wrapped) — a linear Kalman update.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import wrap_angle
from ..core.validation import check_finite, check_positive
from .ekf import ekf_update
from .sensors import BeamSensor
from .world import OccupancyGrid

__all__ = ["ScanMatch", "correlative_match", "ekf_update_pose", "likelihood_field"]

Array = NDArray[np.float64]


def likelihood_field(grid: OccupancyGrid, sigma: float, cap: float = 3.0) -> Array:
    """``−min(d, cap·σ)²/(2σ²)`` at every cell, ``d`` [m] the distance from its centre to the nearest wall face.

    ``d`` is the distance to the nearest cell centre of the other kind (occupied for a free cell, free for an
    occupied one) less half a cell: the face lies halfway between them.

    The cap keeps a reading that hit no wall of the map (a random reading, a person) from outweighing the
    others: it costs at most ``cap²/2``, as the likelihood-field model's random component bounds it.

    Parameters
    ----------
    grid : OccupancyGrid — the map (with at least one occupied cell)
    sigma : float [m], > 0 — σ of an endpoint about the wall
    cap : float, > 0 — the largest distance counted, in σ

    Returns
    -------
    ndarray, shape (nx, ny) — ≤ 0, 0 on occupied cells
    """
    s = float(check_positive("sigma", sigma))
    if not grid.occupied.any():
        raise ValueError("the grid must have an occupied cell to match against (allowed: a map with walls), got none")
    from scipy import ndimage  # imported where used (0.2 s)

    occ, h = grid.occupied, grid.resolution
    # distance to the walls' faces: half a cell less than to the nearest cell centre across them, on either side
    # (a ray-cast range ends at a face; measured to the centres the field would pull endpoints into the walls)
    across = np.where(occ, ndimage.distance_transform_edt(occ), ndimage.distance_transform_edt(~occ))
    d = np.maximum(across * h - h / 2, 0.0)
    return np.asarray(-0.5 * np.minimum(d / s, float(check_positive("cap", cap))) ** 2, dtype=np.float64)


def _bilinear(f: Array, grid: OccupancyGrid, ex: Array, ey: Array) -> Array:
    """The field interpolated bilinearly between the cell centres at the endpoints; off the map, its lowest value.

    Continuous in the endpoint, so candidates a round-off apart score alike (a field read per cell jumps at the
    cells' walls, where the ray-cast ranges of the map end). An endpoint off the map saw no wall of it: it scores
    as the farthest cell (clamped to the edge instead, it would score as the map's outer wall).
    """
    nx, ny = grid.shape
    u = np.clip((ex - grid.origin[0]) / grid.resolution - 0.5, 0.0, nx - 1.0)
    v = np.clip((ey - grid.origin[1]) / grid.resolution - 0.5, 0.0, ny - 1.0)
    i, j = np.minimum(np.floor(u).astype(np.intp), nx - 2), np.minimum(np.floor(v).astype(np.intp), ny - 2)
    a, b = u - i, v - j
    x0, x1, y0, y1 = grid.extent()
    off = (ex < x0) | (ex > x1) | (ey < y0) | (ey > y1)
    flat, k = f.ravel(), i * ny + j  # the four corners by flat indices, each weight's factors formed once
    a1, b1 = 1 - a, 1 - b
    val = a1 * b1 * flat[k] + a * b1 * flat[k + ny] + a1 * b * flat[k + 1] + a * b * flat[k + ny + 1]
    return np.asarray(np.where(off, f.min(), val), dtype=np.float64)


@dataclass(frozen=True)
class ScanMatch:
    """The result of a correlative scan match.

    Attributes
    ----------
    pose : ndarray, shape (3,) — the best candidate [m, m, rad]
    mean : ndarray, shape (3,) — the candidates' mean weighted by ``exp(score)``: the measurement (where several
        candidates tie, as along a corridor, it lies between them, not at the first of them)
    cov : ndarray, shape (3, 3) — the measurement covariance ``R`` about ``mean`` (module docs)
    score : float — the best candidate's summed field
    n_endpoints : int — the readings below the maximum range that were matched
    """

    pose: Array
    mean: Array
    cov: Array
    score: float
    n_endpoints: int


def correlative_match(field: ArrayLike, grid: OccupancyGrid, z: ArrayLike, sensor: BeamSensor, prior: ArrayLike,
                      window: tuple[float, float] = (0.5, 0.2), step: tuple[float, float] = (0.05, 0.01),
                      ) -> ScanMatch:  # fmt: skip
    """Match one scan to the map over a window of poses about ``prior`` (module docs).

    Parameters
    ----------
    field : array_like, shape (nx, ny) — :func:`likelihood_field` of ``grid``
    grid : OccupancyGrid — the map
    z : array_like, shape (n_beams,) [m] — the scan
    sensor : BeamSensor — its beam angles and maximum range
    prior : array_like, shape (3,) — the window's centre [m, m, rad]
    window : (half-width in x and y [m], half-width in θ [rad]), each > 0
    step : (δ [m], δ_θ [rad]), each > 0 — the candidates' spacing

    Returns
    -------
    ScanMatch
    """
    f = check_finite("field", field)
    zz = check_finite("z", z)
    p0 = check_finite("prior", prior)
    w_xy, w_th = (float(check_positive(n, v)) for n, v in zip(("window xy", "window theta"), window, strict=True))
    d_xy, d_th = (float(check_positive(n, v)) for n, v in zip(("step xy", "step theta"), step, strict=True))
    if zz.shape != (sensor.n_beams,):
        raise ValueError(f"z must have shape ({sensor.n_beams},) (one range per beam), got {zz.shape}")
    hit = zz < sensor.max_range - 3.0 * sensor.sigma_hit  # a reading at the range's end saw no wall
    if not hit.any():
        raise ValueError("the scan has no reading below the maximum range (allowed: at least one endpoint), got none")
    off_xy = np.arange(-round(w_xy / d_xy), round(w_xy / d_xy) + 1) * d_xy
    off_th = np.arange(-round(w_th / d_th), round(w_th / d_th) + 1) * d_th
    X, Y, T = np.meshgrid(p0[0] + off_xy, p0[1] + off_xy, p0[2] + off_th, indexing="ij")
    cand = np.stack([X.ravel(), Y.ravel(), T.ravel()], axis=-1)  # (C, 3)
    # the beams' offsets depend on the candidate's θ only: formed once per θ (K, B), then repeated over the
    # candidates (θ is the fastest axis of cand), the same numbers as per candidate
    ang = (p0[2] + off_th)[:, None] + sensor.angles[hit]  # (K, B)
    reps = (cand.shape[0] // off_th.size, 1)
    ex = cand[:, 0:1] + np.tile(zz[hit] * np.cos(ang), reps)
    ey = cand[:, 1:2] + np.tile(zz[hit] * np.sin(ang), reps)
    score = _bilinear(f, grid, ex, ey).sum(axis=1)
    best = int(np.argmax(score))
    p = np.exp(score - score[best])
    p /= p.sum()
    d = cand - cand[best]
    d[:, 2] = wrap_angle(d[:, 2])
    mean = p @ d
    c = d - mean
    cov = (c * p[:, None]).T @ c + np.diag([d_xy**2, d_xy**2, d_th**2]) / 12.0
    return ScanMatch(pose=cand[best], mean=cand[best] + mean, cov=0.5 * (cov + cov.T), score=float(score[best]),
                     n_endpoints=int(hit.sum()))  # fmt: skip


def ekf_update_pose(mean: ArrayLike, cov: ArrayLike, z: ArrayLike, R: ArrayLike) -> tuple[Array, Array]:
    """The EKF update with a direct pose measurement ``z = x + N(0, R)`` (``H = I``, θ's innovation wrapped).

    Parameters
    ----------
    mean : array_like, shape (3,); cov : array_like, shape (3, 3); z : array_like, shape (3,); R : array_like, shape (3, 3)

    Returns
    -------
    mean : ndarray, shape (3,); cov : ndarray, shape (3, 3)
    """
    eye = np.eye(3)
    x, P, _, _ = ekf_update(mean, cov, z, lambda m: m, lambda m: np.broadcast_to(eye, (*m.shape[:-1], 3, 3)), R,
                            angular=[False, False, True])  # fmt: skip
    return x, P
