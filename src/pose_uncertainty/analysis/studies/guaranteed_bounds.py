"""Guaranteed bounds as a fourth dead-reckoning method (Skalka 2011 §2.8): boxes and zonotopes against the truth.

:func:`guaranteed_bounds_study` drives one configured path with bounded wheel errors (encoder
quantisation ± half a pulse and bounded slip, :class:`~pose_uncertainty.methods.intervals.BoundedWheelErrors`)
and measures, at checkpoints along it, the ``(x, y)`` area of

* the interval box (:func:`~pose_uncertainty.methods.intervals.interval_dead_reckoning`),
* the zonotope (:func:`~pose_uncertainty.methods.zonotopes.zonotope_dead_reckoning`),
* the Monte Carlo support: the convex hull of sampled bounded-error trajectories, half of them at the
  vertices of the error set and steered towards the boundary
  (:func:`~pose_uncertainty.methods.intervals.sample_bounded_poses`) — an inner estimate of the reachable set,
* Method A's 99 % ellipse: the first-order covariance of the same errors taken as uniform (variance
  ``w²/3`` per wheel and step) through the lever arms of the path (the zonotope's step generators are
  those lever arms), area ``π χ²₂(0.99) √det Σ_xy``,

and how many sampled poses each region holds (the guaranteed ones must hold all of them; the ellipse's
share is read on errors drawn uniformly, as a probability).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...core import trajectories as tr
from ...core.stats import chi2_ppf
from ...core.validation import check_positive_int
from ...methods import intervals as iv
from ...methods import zonotopes as zt

__all__ = ["guaranteed_bounds_study"]

#: Probability of Method A's ellipse in this study.
ELLIPSE_PR = 0.99


def guaranteed_bounds_study(
    trajectory: dict[str, Any] = {"name": "straight", "length": 10.0, "dt": 0.1, "track": 0.2},  # noqa: B006
    pulses_per_rev: int = 500,
    wheel_diameter: float = 0.1,
    slip_rel: float = 0.001,
    n: int = 20_000,
    n_points: int = 10,
    n_directions: int = 64,
    seed: int = 13,
) -> dict[str, Any]:
    """Box, zonotope, Monte Carlo support and Method A's 99 % ellipse along one path (module docs).

    Parameters
    ----------
    trajectory : trajectory configuration (:func:`pose_uncertainty.core.trajectories.from_config`)
    pulses_per_rev : int — encoder resolution; wheel_diameter : float [m]; slip_rel : float [1] — slip bound
    n : int — sampled bounded-error trajectories; n_points : int — checkpoints; n_directions : int —
        boundary directions the vertex samples are steered to; seed : int

    Returns
    -------
    dict: ``distance`` [m] of the checkpoints; ``box_area``, ``zonotope_area``, ``support_area``,
    ``ellipse_area`` [m²] per checkpoint; ``box_over_support``, ``zonotope_over_support``,
    ``ellipse_over_support``, ``box_over_zonotope`` [1] per checkpoint; ``box_contains``,
    ``zonotope_contains`` [1] — the fraction of the n sampled poses inside at the end (1 for a guaranteed
    region); ``ellipse_contains`` [1] — the fraction of n poses with uniformly drawn errors inside the 99 %
    ellipse at the end; ``zonotope_tighter`` — the checkpoints' distances where the zonotope is smaller
    than the box; ``final`` — the last checkpoint's areas and ratios; ``pulse`` [m]
    """
    t = tr.from_config(trajectory)
    err = iv.BoundedWheelErrors.encoder(pulses_per_rev, wheel_diameter, slip_rel)
    N = t.n_steps
    idx = np.unique(np.linspace(0, N, check_positive_int("n_points", n_points) + 1).round().astype(int)[1:])
    A = iv.wheel_error_generators(t.ds_r, t.ds_l, t.track, err)
    ds, dth = np.asarray(t.ds, dtype=float), np.asarray(t.dtheta, dtype=float)
    box = iv.interval_dead_reckoning(ds, dth, A, start=t.start, checkpoints=idx)
    zons = zt.zonotope_dead_reckoning(ds, dth, A, start=t.start, checkpoints=idx)
    ang = np.linspace(0.0, 2.0 * math.pi, check_positive_int("n_directions", n_directions), endpoint=False)
    dirs = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
    g_edge, g_uniform = np.random.default_rng(seed).spawn(2)
    samples = iv.sample_bounded_poses(ds, dth, A, n, g_edge, start=t.start, checkpoints=idx, directions=dirs)
    # the ellipse's coverage is a probability: read it on errors drawn uniformly (no vertex share)
    uniform = iv.sample_bounded_poses(ds, dth, A, n, g_uniform, start=t.start, checkpoints=idx[-1:],
                                      vertex_fraction=0.0)[:, 0, :2]  # fmt: skip
    m = A.shape[2]
    k99 = float(chi2_ppf(ELLIPSE_PR, 2.0))
    box_a, zon_a, sup_a, ell_a = [], [], [], []
    for c, (n_c, z) in enumerate(zip(idx, zons, strict=True)):
        steps = z.generators[:2, 3 : 3 + m * int(n_c)]  # the first-order lever arms of every step's errors
        S = steps @ steps.T / 3.0  # uniform on [-1, 1]: variance 1/3
        box_a.append(float(iv.box_area(box)[c]))
        zon_a.append(zt.zonotope_area(z))
        sup_a.append(zt.hull_area(samples[:, c, :2]))
        ell_a.append(math.pi * k99 * math.sqrt(max(float(np.linalg.det(S)), 0.0)))
        if c == idx.size - 1:
            d = uniform - z.center[:2]
            inside_ell = np.einsum("ni,ij,nj->n", d, np.linalg.inv(S), d) <= k99
    dist = np.concatenate([[0.0], np.cumsum(np.abs(ds))])[idx]
    box_a_, zon_a_, sup_a_, ell_a_ = (np.array(v) for v in (box_a, zon_a, sup_a, ell_a))
    out: dict[str, Any] = {
        "distance": dist.tolist(), "pulse": err.pulse, "n": int(samples.shape[0]),
        "box_area": box_a, "zonotope_area": zon_a, "support_area": sup_a, "ellipse_area": ell_a,
        "box_over_support": (box_a_ / sup_a_).tolist(), "zonotope_over_support": (zon_a_ / sup_a_).tolist(),
        "ellipse_over_support": (ell_a_ / sup_a_).tolist(), "box_over_zonotope": (box_a_ / zon_a_).tolist(),
        "box_contains": float(np.mean(box.contains(samples)[:, -1])),
        "zonotope_contains": float(np.mean(zt.zonotope_contains_xy(zons[-1], samples[:, -1, :2]))),
        "ellipse_contains": float(np.mean(inside_ell)),
        "zonotope_tighter": dist[zon_a_ < box_a_].tolist(),
    }  # fmt: skip
    out["final"] = {k: out[k][-1] for k in ("distance", "box_area", "zonotope_area", "support_area", "ellipse_area",
                                           "box_over_support", "zonotope_over_support", "ellipse_over_support",
                                           "box_over_zonotope")}  # fmt: skip
    return out
