"""Noise models: wheel error sources mapped to ``k``, and per-run against per-step errors.

:func:`error_sources_vs_monte_carlo` maps Šafránek 2022's error sources to the
equivalent ``k`` (:mod:`pose_uncertainty.methods.wheel_noise`) and checks it against
Monte Carlo; :func:`regime_growth` compares systematic (per-run) with random
(per-step) errors and their growth with distance.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core import trajectories as tr
from ...core.stats import fit_growth, path_spreads
from ...methods import covariance as cv
from ...methods import sampling as sp
from ...methods import wheel_noise as wn
from .arcs import constant_speed_trajectory


def error_sources_vs_monte_carlo(
    sources: wn.WheelErrorSources = wn.SAFRANEK_2022_CHASSIS,
    *,
    speed: float = 1.0,
    duration: float = 1.0,
    dt: float = 0.01,
    track: float = 0.1,
    n: int = 100_000,
    seed: int = 1,
) -> dict[str, float]:
    """Šafránek 2022's error sources → equivalent ``k`` → Method A, against Monte Carlo of the sources.

    Straight run at ``speed``; per-step regime.

    Returns
    -------
    dict: ``k_equivalent`` [m], ``k_thesis_factor`` (Šafránek 2022's
    ``0.01·σ_v²``), the Monte Carlo total-travel variance per metre of the
    right wheel ``k_mc_travel`` [m], and Method A's against the Monte Carlo
    end-pose variances ``var_<x|y|theta>_method_a`` / ``_mc``.
    """
    t = constant_speed_trajectory(speed, speed, duration, dt, track)
    rng = np.random.default_rng(seed)
    k = float(wn.k_equivalent(sources, speed, dt))
    ds_r, ds_l = wn.sample_wheel_travels(t, sources, n, rng, "per_step")
    L = t.wheel_travel[0]
    ends = sp.integrate_end(ds_r, ds_l, track)[:, 0, :]
    A = cv.propagate(t, k, k).covs[-1]
    C = np.cov(ends.T)
    out = {
        "speed_variance": float(wn.speed_variance(sources, speed)),
        "k_equivalent": k,
        "k_thesis_factor": 0.01 * float(wn.speed_variance(sources, speed)),
        "k_mc_travel": float(ds_r.sum(axis=1).var(ddof=1) / L),
        "n_samples": float(n),
    }
    for i, name in enumerate(("x", "y", "theta")):
        out[f"var_{name}_method_a"] = float(A[i, i])
        out[f"var_{name}_mc"] = float(C[i, i])
    return out


def regime_growth(
    trajectory: tr.Trajectory,
    k_r: float,
    k_l: float,
    n: int,
    seed: int,
    n_checkpoints: int = 10,
) -> dict[str, Any]:
    """Per-step (random) against per-run (systematic) errors: spreads against distance.

    Both regimes have the same total-travel variance at the end of the path
    (:mod:`pose_uncertainty.methods.sampling`); along the way the per-run spread grows
    faster. Spreads are Monte Carlo standard deviations along/across the
    nominal heading.

    Returns
    -------
    dict: ``distance`` (C,), per regime ``sigma_along``, ``sigma_across``,
    ``sigma_theta`` lists and ``fits`` (:func:`fit_growth` of each).
    """
    N = trajectory.n_steps
    steps = sorted({max(1, round(N * (i + 1) / n_checkpoints)) for i in range(n_checkpoints)})
    dist = np.concatenate([[0.0], np.cumsum(np.abs(trajectory.ds))])[steps]
    nominal = trajectory.poses[steps]
    out: dict[str, Any] = {"distance": dist.tolist()}
    for regime in ("per_step", "per_run"):
        clouds = sp.sample_end_poses(
            trajectory, k_r, k_l, n, np.random.default_rng(seed), regime=regime, checkpoints=steps
        )
        covs = np.stack([np.cov(clouds[:, i, :].T) for i in range(len(steps))])
        aa = path_spreads(nominal, covs)
        row: dict[str, Any] = {k: v.tolist() for k, v in aa.items() if k != "area"}
        row["fits"] = {k: fit_growth(dist, aa[k]) for k in ("sigma_along", "sigma_across", "sigma_theta")}
        out[regime] = row
    return out


def error_sources_study(
    speed: float = 1.0, duration: float = 1.0, dt: float = 0.01, track: float = 0.1,
    n: int = 100_000, seed: int = 1,
) -> dict[str, float]:
    """:func:`error_sources_vs_monte_carlo` with Šafránek 2022's error sources."""
    return error_sources_vs_monte_carlo(wn.SAFRANEK_2022_CHASSIS, speed=speed, duration=duration, dt=dt, track=track,
                                        n=n, seed=seed)  # fmt: skip


_STRAIGHT_5M = {"name": "straight", "length": 5.0, "dt": 0.01, "track": 0.2}


def regime_growth_study(
    trajectory: dict[str, Any] = _STRAIGHT_5M, k: float = 5e-4, n: int = 20_000, seed: int = 4,
    n_checkpoints: int = 10,
) -> dict[str, Any]:
    """:func:`regime_growth` along a configured trajectory."""
    return regime_growth(tr.from_config(trajectory), k, k, n, seed, n_checkpoints)
