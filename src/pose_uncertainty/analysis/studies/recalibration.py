"""Calibration: the travel-noise constants ``k`` fitted back from Monte Carlo end poses, with both models.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core import trajectories as tr
from ...methods import sampling as sp
from .. import calibration as cb


def calibration_demo(
    n: int = 20_000, seed: int = 11, k: float = 5e-4, track: float = 0.2, dt: float = 0.02,
    length: float = 1.0,
) -> dict[str, Any]:
    """Fit ``k`` back from Monte Carlo end poses of a straight line, with both models.

    ``n`` per-step Monte Carlo runs of a straight line of ``length`` [m] with
    true ``k_r = k_l = k`` [m]; :func:`pose_uncertainty.analysis.calibration.fit_k` with
    ``coords`` "expcoords" and "cartesian", each with one constant (``equal``)
    and with separate ``k_r, k_l``; 95 % profile-likelihood intervals.

    Returns
    -------
    dict: ``true_k``, ``n``, ``trajectory`` (its parameters) and ``rows`` — list
    of {``coords``, ``equal``, ``parameter``, ``estimate``, ``ci_low``,
    ``ci_high``, ``contains_true``, ``relative_bias``}
    """
    t = tr.straight(length, dt=dt, track=track)
    cloud = sp.sample_end_poses(t, k, k, n, np.random.default_rng(seed))
    rows = []
    for coords in ("expcoords", "cartesian"):
        for equal in (True, False):
            r = cb.fit_k(cloud, t, coords=coords, equal=equal)
            for name, est, lo, hi in zip(r.names, r.estimate, r.ci_low, r.ci_high, strict=True):
                rows.append({
                    "coords": coords, "equal": equal, "parameter": name, "estimate": est,
                    "ci_low": lo, "ci_high": hi, "level": r.level,
                    "contains_true": bool(lo <= k <= hi), "relative_bias": est / k - 1.0,
                })
    return {"true_k": k, "n": n, "seed": seed,
            "trajectory": {"name": "straight", "length": length, "dt": dt, "track": track},
            "rows": rows}
