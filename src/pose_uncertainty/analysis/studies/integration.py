"""Integration methods: end-pose error against step size, and whether the cloud depends on the method.

:func:`integration_vs_step` measures the error of the Euler, end-point Euler, midpoint
and exact-arc steps from the closed-form arc and fits their order;
:func:`method_cloud_spread` integrates the same wheel-travel draws by each method
(Šafránek 2022's question: does the end-pose cloud depend on the forward kinematics?).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ...core import trajectories as tr
from ...core.kinematics import METHODS
from ...core.validation import check_choice
from ...methods import sampling as sp
from .arcs import constant_speed_trajectory, exact_constant_arc


def integration_vs_step(
    dts: Sequence[float] = (0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001),
    *,
    v_r: float = 1.0,
    v_l: float = 0.95,
    duration: float = 1.0,
    track: float = 0.1,
    methods: Sequence[str] = ("euler", "euler_end", "midpoint", "exact"),
) -> dict[str, Any]:
    """End-pose error of each integration method against the exact arc, for several steps.

    Wheel speeds are constant (Šafránek 2022's arc: 1 and 0.95 m/s, b = 0.1 m,
    1 s), so the exact arc is the truth for every step size.

    Returns
    -------
    dict: ``rows`` — one per (dt, method): ``dt`` [s], ``method``,
    ``position_error`` [m], ``heading_error`` [rad]; ``order`` — per method the
    log-log slope of the position error against dt (1 for Euler, 2 for the
    midpoint rule; the exact arc is at rounding level).
    """
    truth = exact_constant_arc(v_r, v_l, duration, track, np.float64)
    rows = []
    for dt in dts:
        t = constant_speed_trajectory(v_r, v_l, duration, dt, track)
        for m in methods:
            check_choice("method", m, METHODS)
            end = t.poses_by(m)[-1]
            rows.append(
                {
                    "dt": float(dt),
                    "method": m,
                    "position_error": float(math.hypot(end[0] - truth[0], end[1] - truth[1])),
                    "heading_error": float(abs(end[2] - truth[2])),
                }
            )
    order = {}
    for m in methods:
        e = np.array([r["position_error"] for r in rows if r["method"] == m])
        d = np.array([r["dt"] for r in rows if r["method"] == m])
        ok = e > 1e-13
        order[m] = float(np.polyfit(np.log(d[ok]), np.log(e[ok]), 1)[0]) if ok.sum() >= 2 else 0.0
    return {"rows": rows, "order": order}


def method_cloud_spread(
    trajectory: tr.Trajectory,
    k_r: float,
    k_l: float,
    n: int,
    seed: int,
    methods: Sequence[str] = ("euler", "euler_end", "midpoint", "exact"),
) -> dict[str, Any]:
    """Does the cloud depend on the integration method? Same noise, four methods.

    The same wheel-travel draws (same seed) are integrated by each method.

    Returns
    -------
    dict: per method ``mean`` (3,) and ``cov`` (3, 3) of the cloud, and
    ``max_rel_cov_difference`` — the largest relative difference of a
    covariance entry (x, y, θ diagonal) from the exact-arc cloud.
    """
    out: dict[str, Any] = {}
    clouds = {
        m: sp.sample_end_poses(trajectory, k_r, k_l, n, np.random.default_rng(seed), method=m)
        for m in methods
    }
    ref = np.cov(clouds["exact"].T) if "exact" in clouds else None
    for m, c in clouds.items():
        C = np.cov(c.T)
        row = {"mean": c.mean(0).tolist(), "cov": C.tolist()}
        if ref is not None:
            row["max_rel_cov_difference"] = float(np.max(np.abs(np.diag(C) / np.diag(ref) - 1)))
        out[m] = row
    return out


def method_cloud_spread_study(
    v_r: float = 1.0, v_l: float = 0.95, duration: float = 1.0, dt: float = 0.01, track: float = 0.1,
    k: float = 4.17e-6, n: int = 100_000, seed: int = 7,
) -> dict[str, Any]:
    """:func:`method_cloud_spread` on Šafránek 2022's constant-speed arc."""
    return method_cloud_spread(constant_speed_trajectory(v_r, v_l, duration, dt, track), k, k, n, seed)
