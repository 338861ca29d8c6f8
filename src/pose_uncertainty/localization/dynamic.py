"""Dynamic environments (Skalka 2011 §5.1): people and boxes that are not on the map, and the distance filter.

Skalka 2011 §5.1 (after Fox, Burgard, Thrun & Cremers 1998): in a room with people the laser often sees an
object the map does not hold, so its reading is *shorter* than the map predicts. Two remedies: the beam
model's short-reading and random components (:class:`~pose_uncertainty.localization.sensors.BeamSensor`,
``z_short`` and ``z_rand``), and a measurement filter that discards the readings the map cannot explain.

Unmapped obstacles (:func:`disc_ranges`, :func:`occluded_ranges`)
------------------------------------------------------------------
Obstacles are discs ``(c_x, c_y, r)`` (a person seen from above, a box's circumscribed circle). The range
along a ray from ``o`` in the direction ``u`` to a disc is the smaller root of ``‖o + t u − c‖ = r``::

    t = b − √(b² − (‖o − c‖² − r²)),   b = u·(c − o)

where the discriminant is non-negative and the root positive (a ray starting inside a disc sees it at 0).
A scan of a map with obstacles is the elementwise minimum of the map's ranges and every disc's.

The distance filter (:func:`distance_filter`)
----------------------------------------------
With the beam model's mixture ``p(z | z*) = z_hit p_hit + z_short p_short + z_max p_max + z_rand p_rand``,
the probability that a reading ``z`` was caused by an unexpected obstacle (the short component) given the
belief over poses (particles or cells ``x_i`` with weights ``w_i``, expected ranges ``z*_i``) is::

    P(short | z) = Σ_i w_i · z_short p_short(z | z*_i) / p(z | z*_i)

and the filter keeps the readings with ``P(short | z) < threshold`` (Fox et al. 1999 use 0.99). Vectorised
over beams and poses; no loop.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import check_finite, check_last_axis, check_positive
from .sensors import BeamSensor, beam_probability, beam_terms

__all__ = ["disc_ranges", "distance_filter", "occluded_ranges", "short_probability"]

Array = NDArray[np.float64]


def disc_ranges(origins: ArrayLike, angles: ArrayLike, discs: ArrayLike, max_range: float) -> Array:
    """Range from each ray's origin to the nearest disc along it, ``max_range`` where none is hit.

    Parameters
    ----------
    origins : array_like, shape (..., 2) [m] — ray origins
    angles : array_like, shape (..., B) [rad] — ray directions (world frame), B rays per origin
    discs : array_like, shape (D, 3) — ``(c_x, c_y, r)`` [m] of every disc (D may be 0)
    max_range : float [m], > 0

    Returns
    -------
    ndarray, shape (..., B) [m] — in ``[0, max_range]``
    """
    o = check_finite("origins", check_last_axis("origins", origins, 2))
    a = check_finite("angles", angles)
    d = check_finite("discs", check_last_axis("discs", discs, 3)).reshape(-1, 3)
    zm = float(check_positive("max_range", max_range))
    out = np.full(np.broadcast_shapes((*o.shape[:-1], 1), a.shape), zm)
    if d.shape[0] == 0:
        return out
    u = np.stack([np.cos(a), np.sin(a)], axis=-1)[..., None, :]  # (..., B, 1, 2)
    oc = d[:, :2] - o[..., None, None, :]  # (..., 1, D, 2): c − o
    b = np.sum(u * oc, axis=-1)  # (..., B, D)
    c = np.sum(oc * oc, axis=-1) - d[:, 2] ** 2  # ‖o − c‖² − r², (..., 1, D)
    disc = b * b - c
    with np.errstate(invalid="ignore"):
        t = np.where(c <= 0, 0.0, b - np.sqrt(disc))  # inside a disc: seen at 0
    hit = (disc >= 0) & (t >= 0) & ((c <= 0) | (b > 0))
    return np.asarray(np.minimum(out, np.min(np.where(hit, t, np.inf), axis=-1)), dtype=np.float64)


def occluded_ranges(z_map: ArrayLike, poses: ArrayLike, sensor: BeamSensor, discs: ArrayLike) -> Array:
    """The ranges a scan measures with unmapped discs in the room: ``min(z_map, disc range)`` per beam.

    Parameters
    ----------
    z_map : array_like, shape (..., n_beams) [m] — the map's expected ranges at ``poses``
        (:func:`~pose_uncertainty.localization.sensors.expected_ranges`)
    poses : array_like, shape (..., 3) — the poses the scans are taken from [m, m, rad]
    sensor : BeamSensor — the laser
    discs : array_like, shape (D, 3) — ``(c_x, c_y, r)`` [m] of the unmapped obstacles

    Returns
    -------
    ndarray, shape (..., n_beams) [m]
    """
    p = check_finite("poses", check_last_axis("poses", poses, 3))
    ang = p[..., 2:3] + sensor.angles
    return np.minimum(check_finite("z_map", z_map), disc_ranges(p[..., :2], ang, discs, sensor.max_range))


def short_probability(z: ArrayLike, z_star: ArrayLike, w: ArrayLike, sensor: BeamSensor) -> Array:
    """``P(short | z)`` of every beam under a belief: ``Σ_i w_i z_short p_short(z | z*_i) / p(z | z*_i)``.

    Parameters
    ----------
    z : array_like, shape (B,) [m] — one scan
    z_star : array_like, shape (n, B) [m] — expected ranges of the n poses of the belief
    w : array_like, shape (n,) — their normalised weights

    Returns
    -------
    ndarray, shape (B,) in [0, 1]
    """
    zz = check_finite("z", z)
    zs = check_finite("z_star", z_star)
    ww = check_finite("w", w)
    terms = beam_terms(zs, sensor)
    total = beam_probability(zz, zs, sensor, terms)
    lam = sensor.lambda_short
    short = np.where((zz >= 0) & (zz <= zs) & (zs > 0), terms[1] * lam * np.exp(-lam * zz), 0.0) * sensor.z_short
    share = np.divide(short, total, out=np.zeros_like(total), where=total > 0)
    return np.asarray(ww @ share, dtype=np.float64)


def distance_filter(z: ArrayLike, z_star: ArrayLike, w: ArrayLike, sensor: BeamSensor,
                    threshold: float = 0.99) -> NDArray[np.bool_]:  # fmt: skip
    """The beams to keep: those whose :func:`short_probability` is below ``threshold`` (module docs), shape (B,)."""
    t = float(threshold)
    if not 0.0 < t <= 1.0:
        raise ValueError(f"threshold must be in (0, 1] (allowed: (0, 1]), got {t}")
    return np.asarray(short_probability(z, z_star, w, sensor) < t)
