"""Relative sensing beyond the wheels (Skalka 2011 §3.3–3.4): odometry, a strapdown INS and gyro-aided odometry.

:func:`relative_sensing_study` carries the three dead-reckoning schemes along one configured path, each
with Method A (its own Jacobians) and Monte Carlo, and measures how the rms position error
``σ_pos = √(Σ_xx + Σ_yy)`` grows: power laws against the distance travelled and against the time
(:func:`pose_uncertainty.methods.inertial_sensors.position_growth`). The schemes:

* wheel odometry alone — :mod:`pose_uncertainty.methods.covariance` and :mod:`pose_uncertainty.methods.sampling`
  (wheel-travel variance ``k`` per metre);
* the INS alone — :mod:`pose_uncertainty.methods.inertial` (gyro heading, accelerometers integrated twice);
* gyro-aided odometry — :mod:`pose_uncertainty.methods.gyro_odometry` (the gyro for the heading, the wheels
  for the distance).

The sensor errors default to a mid-range MEMS inertial unit (bias left after a start-up calibration,
noise densities of its data sheet class); the path's largest specific force is logged beside the
accelerometer bias, the ratio that decides how useful the INS is at a robot's accelerations.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core import trajectories as tr
from ...core.validation import check_positive_int
from ...methods import covariance as cv
from ...methods import sampling as sp
from ...methods.gyro_odometry import (
    odometry_gyro_path,
    propagate_odometry_gyro,
    sample_odometry_gyro,
)
from ...methods.inertial import InertialPath, propagate_ins, sample_ins
from ...methods.inertial_sensors import AccelErrors, GyroErrors, position_growth

__all__ = ["SCHEMES", "relative_sensing_study"]

#: The dead-reckoning schemes of the study, in the order the report shows them.
SCHEMES: tuple[str, ...] = ("odometry", "ins", "gyro_odometry")

_GYRO = {"bias_std": 1e-3, "bias_rw_std": 1e-4, "white_std": 1e-3, "scale_std": 5e-3}
_ACCEL = {"bias_std": 0.01, "bias_rw_std": 1e-4, "white_std": 2e-3}


def _sigma_pos(covs: np.ndarray) -> np.ndarray:
    return np.sqrt(np.maximum(covs[:, 0, 0] + covs[:, 1, 1], 0.0))


def _sample_covs(samples: np.ndarray) -> np.ndarray:
    """Sample covariances of the (x, y) columns at each checkpoint: samples (n, C, d) → (C, 2, 2)."""
    d = samples[..., :2] - samples[..., :2].mean(axis=0)
    return np.einsum("nci,ncj->cij", d, d) / (samples.shape[0] - 1)


def relative_sensing_study(
    trajectory: dict[str, Any] = {"name": "straight", "length": 20.0, "dt": 0.05, "track": 0.2},  # noqa: B006
    k: float = 5e-4,
    gyro: dict[str, float] = _GYRO,
    accel: dict[str, float] = _ACCEL,
    n: int = 2000,
    n_points: int = 20,
    seed: int = 11,
) -> dict[str, Any]:
    """Odometry, INS and gyro-aided odometry along one path: σ_pos with Method A and Monte Carlo, growth laws.

    Parameters
    ----------
    trajectory : trajectory configuration (:func:`pose_uncertainty.core.trajectories.from_config`)
    k : float [m] — wheel-travel variance per metre (both wheels)
    gyro : keyword arguments of :class:`~pose_uncertainty.methods.inertial_sensors.GyroErrors`
    accel : keyword arguments of :class:`~pose_uncertainty.methods.inertial_sensors.AccelErrors`
    n : int — Monte Carlo runs per scheme; n_points : int — checkpoints along the path; seed : int

    Returns
    -------
    dict: ``distance`` [m] and ``time`` [s] of the checkpoints; ``path_length`` [m], ``duration`` [s];
    ``max_specific_force`` [m/s²] (the largest magnitude of the path's specific force) and ``accel_bias_std`` [m/s²];
    per scheme (:data:`SCHEMES`): ``sigma_a``, ``sigma_mc`` [m] at the checkpoints, ``final_a``,
    ``final_mc`` [m], ``mc_over_a`` [1] at the end, ``fits_a`` {``time``, ``distance``} of
    :func:`~pose_uncertainty.methods.inertial_sensors.position_growth`; ``best`` — the scheme with the
    smallest final Method A error, ``ins_over_odometry`` and ``gyro_over_odometry`` [1] — final ratios
    """
    t = tr.from_config(trajectory)
    g, a = GyroErrors(**gyro), AccelErrors(**accel)
    n = check_positive_int("n", n)
    N = t.n_steps
    dist = np.concatenate([[0.0], np.cumsum(np.abs(t.ds))])
    idx = np.unique(np.linspace(0, N, check_positive_int("n_points", n_points) + 1).round().astype(int)[1:])
    times = t.dt * idx
    rng = np.random.default_rng(seed)
    g_odo, g_ins, g_gyr = rng.spawn(3)
    A_odo = cv.propagate(t, k, k).covs[idx]
    mc_odo = _sample_covs(sp.sample_end_poses(t, k, k, n, g_odo, checkpoints=idx.tolist()))
    ins_path = InertialPath.from_trajectory(t)
    A_ins = propagate_ins(ins_path, g, a)[1][idx]
    mc_ins = _sample_covs(sample_ins(ins_path, g, a, n, g_ins, checkpoints=idx))
    gp = odometry_gyro_path(t, k, k)
    A_gyr = propagate_odometry_gyro(gp, g)[1][idx]
    mc_gyr = _sample_covs(sample_odometry_gyro(gp, g, n, g_gyr, checkpoints=idx))
    out: dict[str, Any] = {
        "distance": dist[idx].tolist(), "time": times.tolist(), "path_length": float(dist[-1]),
        "duration": float(t.dt * N), "max_specific_force": float(np.max(np.hypot(*ins_path.accel.T))),
        "accel_bias_std": a.bias_std, "n": n,
    }  # fmt: skip
    for name, A, M in (("odometry", A_odo, mc_odo), ("ins", A_ins, mc_ins), ("gyro_odometry", A_gyr, mc_gyr)):
        sa, sm = _sigma_pos(A), _sigma_pos(M)
        out[name] = {
            "sigma_a": sa.tolist(), "sigma_mc": sm.tolist(), "final_a": float(sa[-1]), "final_mc": float(sm[-1]),
            "mc_over_a": float(sm[-1] / sa[-1]), "fits_a": position_growth(times, dist[idx], A),
        }  # fmt: skip
    out["best"] = min(SCHEMES, key=lambda s: out[s]["final_a"])
    out["ins_over_odometry"] = out["ins"]["final_a"] / out["odometry"]["final_a"]
    out["gyro_over_odometry"] = out["gyro_odometry"]["final_a"] / out["odometry"]["final_a"]
    return out
