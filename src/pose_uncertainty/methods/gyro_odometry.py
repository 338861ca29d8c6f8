"""Gyro-aided odometry: the heading from a gyroscope, the distance from the wheels (Skalka 2011 §3.3–3.4).

State ``(x, y, θ, b_g, s_g)``; the travel ``Δs`` of the axle centre from the wheels with variance
``(k_r|Δs_r| + k_l|Δs_l|)/4`` (Method A's wheel model), the gyro of
:mod:`pose_uncertainty.methods.inertial_sensors`::

    θ' = θ + ω_m Δt,   φ = θ + ω_m Δt/2,   x' = x + (Δs + n_s) cos φ,   y' = y + (Δs + n_s) sin φ

Method A (:func:`propagate_odometry_gyro`, Jacobians :func:`odometry_gyro_jacobians`) and Monte Carlo
(:func:`sample_odometry_gyro`, vectorised over particles). Known growth laws: constant gyro bias →
heading error ∝ t (position across a straight ∝ t²); gyro white noise → heading ∝ t^½. Wheel
odometry alone is :mod:`pose_uncertainty.methods.covariance` and :mod:`pose_uncertainty.methods.sampling`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.trajectories import Trajectory
from ..core.validation import (
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_positive,
    check_positive_int,
)
from .inertial_sensors import (
    GyroErrors,
    exclusive_cumsum,
    initial_covariance,
    propagate_linearised,
    sample_gyro_errors,
    step_indices,
)

__all__ = [
    "ODO_STATE",
    "OdometryGyroPath",
    "odometry_gyro_jacobians",
    "odometry_gyro_path",
    "odometry_gyro_step",
    "propagate_odometry_gyro",
    "sample_odometry_gyro",
]

Array = NDArray[np.float64]

#: Names of the gyro-aided odometry state components, in order.
ODO_STATE: tuple[str, ...] = ("x", "y", "theta", "b_g", "s_g")


@dataclass(frozen=True, eq=False)
class OdometryGyroPath:
    """Inputs of gyro-aided odometry: the axle centre's travel per step and the true yaw rate.

    Attributes
    ----------
    ds : ndarray, shape (N,) [m]; ds_var : ndarray, shape (N,) [m²] — variance of each step's travel
    omega : ndarray, shape (N,) [rad/s]; dt : float [s]; start : ndarray, shape (3,)
    """

    ds: Array
    ds_var: Array
    omega: Array
    dt: float
    start: Array

    @property
    def n_steps(self) -> int:
        """Number of steps N."""
        return int(self.ds.shape[0])


def odometry_gyro_path(trajectory: Trajectory, k_r: float, k_l: float) -> OdometryGyroPath:
    """The inputs of gyro-aided odometry along a trajectory: ``Δs`` with variance ``(k_r|Δs_r| + k_l|Δs_l|)/4``.

    Parameters
    ----------
    trajectory : Trajectory; k_r, k_l : float [m] — wheel-travel variance per metre (Method A's)
    """
    kr, kl = float(check_nonnegative("k_r", k_r)), float(check_nonnegative("k_l", k_l))
    var = (kr * np.abs(trajectory.ds_r) + kl * np.abs(trajectory.ds_l)) / 4.0
    return OdometryGyroPath(np.asarray(trajectory.ds, dtype=np.float64), var,
                            np.asarray(trajectory.dtheta, dtype=np.float64) / trajectory.dt,
                            trajectory.dt, np.asarray(trajectory.start, dtype=np.float64))  # fmt: skip


def odometry_gyro_step(state: ArrayLike, ds: ArrayLike, omega: ArrayLike, noise: ArrayLike, dt: float) -> Array:
    """One step of gyro-aided odometry, state ``(x, y, θ, b_g, s_g)`` (module docs).

    Parameters
    ----------
    state : array_like, shape (..., 5); ds : (...) [m]; omega : (...) [rad/s]
    noise : array_like, shape (..., 3) — ``(n_s [m], n_g [rad/s], w_g [rad/s])``; dt : float [s]

    Returns
    -------
    ndarray, shape (..., 5)
    """
    s = check_last_axis("state", state, 5)
    e = check_last_axis("noise", noise, 3)
    h = float(check_positive("dt", dt))
    w_m = (1.0 + s[..., 4]) * check_finite("omega", omega) + s[..., 3] + e[..., 1]
    phi = s[..., 2] + 0.5 * w_m * h
    travel = check_finite("ds", ds) + e[..., 0]
    out = np.array(s, copy=True)
    out[..., 0] = s[..., 0] + travel * np.cos(phi)
    out[..., 1] = s[..., 1] + travel * np.sin(phi)
    out[..., 2] = s[..., 2] + w_m * h
    out[..., 3] = s[..., 3] + e[..., 2]
    return out


def odometry_gyro_jacobians(state: ArrayLike, ds: ArrayLike, omega: ArrayLike, dt: float) -> tuple[Array, Array]:
    """Jacobians of :func:`odometry_gyro_step` at zero noise, batched over steps.

    Returns
    -------
    F : ndarray, shape (..., 5, 5) — ∂s'/∂s; G : ndarray, shape (..., 5, 3) — ∂s'/∂(n_s, n_g, w_g)
    """
    s = check_last_axis("state", state, 5)
    d, w = check_finite("ds", ds), check_finite("omega", omega)
    h = float(check_positive("dt", dt))
    batch = np.broadcast_shapes(s.shape[:-1], d.shape, w.shape)
    s, d, w = np.broadcast_to(s, (*batch, 5)), np.broadcast_to(d, batch), np.broadcast_to(w, batch)
    w_m = (1.0 + s[..., 4]) * w + s[..., 3]
    phi = s[..., 2] + 0.5 * w_m * h
    c, sn = np.cos(phi), np.sin(phi)
    dx_dphi, dy_dphi = -d * sn, d * c
    F = np.broadcast_to(np.eye(5), (*batch, 5, 5)).copy()
    # ∂φ/∂(θ, b_g, s_g) = (1, Δt/2, ωΔt/2)
    for col, dphi in ((2, 1.0), (3, 0.5 * h), (4, 0.5 * w * h)):
        F[..., 0, col] = dx_dphi * dphi
        F[..., 1, col] = dy_dphi * dphi
    F[..., 2, 3] = h
    F[..., 2, 4] = w * h
    G = np.zeros((*batch, 5, 3))
    G[..., 0, 0], G[..., 1, 0] = c, sn
    G[..., 0, 1], G[..., 1, 1] = dx_dphi * 0.5 * h, dy_dphi * 0.5 * h
    G[..., 2, 1] = h
    G[..., 3, 2] = 1.0
    return F, G


def _odometry_gyro_nominal(path: OdometryGyroPath) -> Array:
    """Nominal states (N+1, 5) of gyro-aided odometry (no error), by cumulative sums."""
    h = path.dt
    theta = path.start[2] + exclusive_cumsum(path.omega * h)
    phi = theta + 0.5 * path.omega * h
    out = np.zeros((path.n_steps + 1, 5))
    out[:, 0] = path.start[0] + np.concatenate([[0.0], np.cumsum(path.ds * np.cos(phi))])
    out[:, 1] = path.start[1] + np.concatenate([[0.0], np.cumsum(path.ds * np.sin(phi))])
    out[:, 2] = path.start[2] + np.concatenate([[0.0], np.cumsum(path.omega * h)])
    return out


def propagate_odometry_gyro(path: OdometryGyroPath, gyro: GyroErrors,
                            cov0: ArrayLike | None = None) -> tuple[Array, Array]:  # fmt: skip
    """Method A for gyro-aided odometry: nominal states and covariances.

    Parameters
    ----------
    path : OdometryGyroPath; gyro : GyroErrors
    cov0 : array_like, shape (3, 3), optional — initial pose covariance

    Returns
    -------
    states : ndarray, shape (N+1, 5); covs : ndarray, shape (N+1, 5, 5) [SI units of :data:`ODO_STATE`]
    """
    h = path.dt
    states = _odometry_gyro_nominal(path)
    F, G = odometry_gyro_jacobians(states[:-1], path.ds, path.omega, h)
    q = np.stack([path.ds_var, np.full(path.n_steps, gyro.white_std**2 / h),
                  np.full(path.n_steps, gyro.bias_rw_std**2 * h)], axis=-1)  # fmt: skip
    S0 = initial_covariance(5, {3: gyro.bias_std**2, 4: gyro.scale_std**2}, cov0, 3)
    return states, propagate_linearised(F, G, q, S0)


def sample_odometry_gyro(path: OdometryGyroPath, gyro: GyroErrors, n: int, rng: np.random.Generator,
                         checkpoints: ArrayLike | None = None) -> Array:  # fmt: skip
    """Monte Carlo of gyro-aided odometry, vectorised over particles (cumulative sums over steps).

    Returns
    -------
    ndarray, shape (n, C, 5) — the full state (:data:`ODO_STATE`) at every checkpoint
    """
    n = check_positive_int("n", n)
    idx = step_indices(checkpoints, path.n_steps)
    h = path.dt
    bg, sg, ng = sample_gyro_errors(gyro, n, path.n_steps, h, rng)
    travel = path.ds + np.sqrt(path.ds_var) * rng.standard_normal((n, path.n_steps))
    w_m = (1.0 + sg[:, None]) * path.omega + bg[:, :-1] + ng
    theta = path.start[2] + exclusive_cumsum(w_m * h)
    phi = theta + 0.5 * w_m * h
    zero = np.zeros((n, 1))
    x = path.start[0] + np.concatenate([zero, np.cumsum(travel * np.cos(phi), axis=1)], axis=1)
    y = path.start[1] + np.concatenate([zero, np.cumsum(travel * np.sin(phi), axis=1)], axis=1)
    th = path.start[2] + np.concatenate([zero, np.cumsum(w_m * h, axis=1)], axis=1)
    out = np.empty((n, idx.size, 5))
    out[..., 0], out[..., 1], out[..., 2] = x[:, idx], y[:, idx], th[:, idx]
    out[..., 3], out[..., 4] = bg[:, idx], sg[:, None]
    return out
