"""Relative sensing beyond wheels: a gyroscope, a 2-D strapdown INS and gyro-aided odometry.

Skalka 2011 §3.3–3.4 describes inertial navigation (accelerometers, gyroscopes, the strapdown
layout) and says that its error grows with *time*, where odometry's grows with *distance*.
This module makes that measurable: each dead-reckoning scheme has a Method A covariance
propagation (its own Jacobians, Σ' = F Σ Fᵀ + G Q Gᵀ) and a Monte Carlo sampler
(vectorised over particles, cumulative sums over steps), and :func:`position_growth` fits
``σ ∝ t^p`` and ``σ ∝ s^p`` to the propagated position error.

Sensor error models (one draw per run for ``bias_std`` and ``scale_std``; every step otherwise)
----------------------------------------------------------------------------------------------
Gyroscope, true rate ω [rad/s], step Δt::

    ω_m = (1 + s_g) ω + b_g + n_g,      n_g ~ N(0, σ_g²/Δt),   b_g' = b_g + w_g,  w_g ~ N(0, σ_bg² Δt)

with ``s_g ~ N(0, scale_std²)`` and ``b_g ~ N(0, bias_std²)`` at the start. ``white_std`` σ_g is the
noise density [rad/√s] (angle random walk: the heading variance grows as σ_g² t), ``bias_rw_std``
σ_bg [rad/s/√s]. Accelerometers (two axes of the body frame, specific force f [m/s²]) likewise::

    f_m = f + b_a + n_a,   n_a ~ N(0, σ_a²/Δt · I),   b_a' = b_a + w_a,  w_a ~ N(0, σ_ba² Δt · I)

The navigation integrates the measured signals as they are (dead reckoning: nothing estimates
the errors). Known growth laws, each recovered by the tests: constant gyro bias → heading error
∝ t; gyro white noise → ∝ t^½; constant accelerometer bias → position error ∝ t²; accelerometer
white noise → ∝ t^{3/2}.

Strapdown INS, state ``(x, y, v_x, v_y, θ, b_g, s_g, b_ax, b_ay)`` (midpoint heading)::

    θ' = θ + ω_m Δt,   φ = θ + ω_m Δt/2,   u = R(φ) f_m,   v' = v + u Δt,   p' = p + v Δt + u Δt²/2

Gyro-aided odometry, state ``(x, y, θ, b_g, s_g)``: the heading from the gyro, the travel
``Δs`` of the axle centre from the wheels (variance ``(k_r|Δs_r| + k_l|Δs_l|)/4``)::

    θ' = θ + ω_m Δt,   φ = θ + ω_m Δt/2,   x' = x + (Δs + n_s) cos φ,   y' = y + (Δs + n_s) sin φ

Wheel odometry alone is :mod:`pose_uncertainty.methods.covariance` (Method A) and
:mod:`pose_uncertainty.methods.sampling` (Monte Carlo).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.stats import fit_growth
from ..core.trajectories import Trajectory
from ..core.validation import (
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_positive,
    check_positive_int,
)

__all__ = [
    "INS_STATE",
    "ODO_STATE",
    "AccelErrors",
    "GyroErrors",
    "InertialPath",
    "OdometryGyroPath",
    "ins_integrate",
    "ins_jacobians",
    "ins_step",
    "odometry_gyro_jacobians",
    "odometry_gyro_path",
    "odometry_gyro_step",
    "position_growth",
    "propagate_ins",
    "propagate_odometry_gyro",
    "sample_ins",
    "sample_odometry_gyro",
]

Array = NDArray[np.float64]

#: Names of the INS state components, in order.
INS_STATE: tuple[str, ...] = ("x", "y", "vx", "vy", "theta", "b_g", "s_g", "b_ax", "b_ay")
#: Names of the gyro-aided odometry state components, in order.
ODO_STATE: tuple[str, ...] = ("x", "y", "theta", "b_g", "s_g")


@dataclass(frozen=True)
class GyroErrors:
    """Error sources of a yaw-rate gyroscope (module docs).

    Attributes
    ----------
    bias_std : float [rad/s] — std of the constant (per-run) bias
    bias_rw_std : float [rad/s/√s] — bias random-walk density
    white_std : float [rad/√s] — white-noise density (angle random walk)
    scale_std : float [1] — std of the (per-run) scale-factor error
    """

    bias_std: float = 0.0
    bias_rw_std: float = 0.0
    white_std: float = 0.0
    scale_std: float = 0.0

    def __post_init__(self) -> None:
        for name in ("bias_std", "bias_rw_std", "white_std", "scale_std"):
            object.__setattr__(self, name, float(check_nonnegative(name, getattr(self, name))))


@dataclass(frozen=True)
class AccelErrors:
    """Error sources of each of the two body-frame accelerometer axes (module docs).

    Attributes
    ----------
    bias_std : float [m/s²] — std of the constant (per-run) bias of each axis
    bias_rw_std : float [m/s²/√s] — bias random-walk density
    white_std : float [m/s/√s] — white-noise density (velocity random walk)
    """

    bias_std: float = 0.0
    bias_rw_std: float = 0.0
    white_std: float = 0.0

    def __post_init__(self) -> None:
        for name in ("bias_std", "bias_rw_std", "white_std"):
            object.__setattr__(self, name, float(check_nonnegative(name, getattr(self, name))))


@dataclass(frozen=True, eq=False)
class InertialPath:
    """True inputs of a strapdown INS: yaw rate and body-frame specific force per step.

    Attributes
    ----------
    omega : ndarray, shape (N,) [rad/s]; accel : ndarray, shape (N, 2) [m/s²] (forward, left)
    dt : float [s]; start : ndarray, shape (3,) — pose [m, m, rad]; v0 : ndarray, shape (2,) [m/s], world frame
    """

    omega: Array
    accel: Array
    dt: float
    start: Array
    v0: Array

    def __post_init__(self) -> None:
        w = check_finite("omega", self.omega).reshape(-1)
        a = check_finite("accel", check_last_axis("accel", self.accel, 2)).reshape(-1, 2)
        if a.shape[0] != w.shape[0] or w.size == 0:
            raise ValueError(f"accel must have shape (N, 2) with N = len(omega) >= 1, got {a.shape} and {w.shape}")
        object.__setattr__(self, "omega", w)
        object.__setattr__(self, "accel", a)
        object.__setattr__(self, "dt", float(check_positive("dt", self.dt)))
        object.__setattr__(self, "start", check_finite("start", check_last_axis("start", self.start, 3)))
        object.__setattr__(self, "v0", check_finite("v0", check_last_axis("v0", self.v0, 2)))

    @property
    def n_steps(self) -> int:
        """Number of steps N."""
        return int(self.omega.shape[0])

    @property
    def times(self) -> Array:
        """Times of the N+1 states, shape (N+1,) [s]."""
        return self.dt * np.arange(self.n_steps + 1, dtype=np.float64)

    @classmethod
    def constant(cls, n_steps: int, dt: float, speed: float = 0.0, omega: float = 0.0,
                 accel: tuple[float, float] = (0.0, 0.0)) -> InertialPath:  # fmt: skip
        """Constant inputs from the pose (0, 0, 0) at velocity ``(speed, 0)`` [m/s]."""
        n = check_positive_int("n_steps", n_steps)
        return cls(np.full(n, float(omega)), np.tile(np.asarray(accel, dtype=np.float64), (n, 1)),
                   dt, np.zeros(3), np.array([float(speed), 0.0]))  # fmt: skip


def _rot(phi: Array, v: Array) -> Array:
    """``R(φ) v`` for angles (...) and vectors (..., 2)."""
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def _exclusive_cumsum(a: Array) -> Array:
    """``out[..., k] = Σ_{j<k} a[..., j]``, same shape as ``a``."""
    out = np.zeros_like(a)
    np.cumsum(a[..., :-1], axis=-1, out=out[..., 1:])
    return out


def ins_integrate(omega_m: ArrayLike, f_m: ArrayLike, dt: float, start: ArrayLike, v0: ArrayLike) -> Array:
    """Integrate measured yaw rates and specific forces (module docs), vectorised over steps.

    Parameters
    ----------
    omega_m : array_like, shape (..., N) [rad/s]; f_m : array_like, shape (..., N, 2) [m/s²], body frame
    dt : float [s]; start : array_like, shape (3,) [m, m, rad]; v0 : array_like, shape (2,) [m/s]

    Returns
    -------
    ndarray, shape (..., N+1, 5) — ``(x, y, v_x, v_y, θ)`` at every step (θ unwrapped)
    """
    w = check_finite("omega_m", omega_m)
    f = check_finite("f_m", check_last_axis("f_m", f_m, 2))
    h = float(check_positive("dt", dt))
    p0 = check_last_axis("start", start, 3)
    v_0 = check_last_axis("v0", v0, 2)
    theta = p0[2] + _exclusive_cumsum(w * h)  # heading before each step
    u = _rot(theta + 0.5 * w * h, f)  # world-frame acceleration of each step
    dv = u * h
    v_before = v_0 + np.moveaxis(_exclusive_cumsum(np.moveaxis(dv, -1, 0)), 0, -1)
    dp = v_before * h + 0.5 * u * h * h
    zero = np.zeros((*w.shape[:-1], 1))
    x = p0[0] + np.concatenate([zero, np.cumsum(dp[..., 0], axis=-1)], axis=-1)
    y = p0[1] + np.concatenate([zero, np.cumsum(dp[..., 1], axis=-1)], axis=-1)
    vx = v_0[0] + np.concatenate([zero, np.cumsum(dv[..., 0], axis=-1)], axis=-1)
    vy = v_0[1] + np.concatenate([zero, np.cumsum(dv[..., 1], axis=-1)], axis=-1)
    th = p0[2] + np.concatenate([zero, np.cumsum(w * h, axis=-1)], axis=-1)
    return np.stack([x, y, vx, vy, th], axis=-1)


def ins_step(state: ArrayLike, omega: ArrayLike, f: ArrayLike, noise: ArrayLike, dt: float) -> Array:
    """One INS step of the full state ``(x, y, v_x, v_y, θ, b_g, s_g, b_ax, b_ay)``.

    Parameters
    ----------
    state : array_like, shape (..., 9); omega : array_like, shape (...) — true yaw rate [rad/s]
    f : array_like, shape (..., 2) — true specific force, body frame [m/s²]
    noise : array_like, shape (..., 6) — ``(n_g, n_ax, n_ay, w_g, w_ax, w_ay)``: white noises of
        the step [rad/s, m/s², m/s²] and bias increments [rad/s, m/s², m/s²]
    dt : float [s]

    Returns
    -------
    ndarray, shape (..., 9)
    """
    s = check_last_axis("state", state, 9)
    e = check_last_axis("noise", noise, 6)
    w = check_finite("omega", omega)
    ff = check_last_axis("f", f, 2)
    h = float(check_positive("dt", dt))
    w_m = (1.0 + s[..., 6]) * w + s[..., 5] + e[..., 0]
    f_m = ff + s[..., 7:9] + e[..., 1:3]
    u = _rot(s[..., 4] + 0.5 * w_m * h, f_m)
    v = s[..., 2:4]
    out = np.array(s, copy=True)
    out[..., 0:2] = s[..., 0:2] + v * h + 0.5 * u * h * h
    out[..., 2:4] = v + u * h
    out[..., 4] = s[..., 4] + w_m * h
    out[..., 5] = s[..., 5] + e[..., 3]
    out[..., 7:9] = s[..., 7:9] + e[..., 4:6]
    return out


def ins_jacobians(state: ArrayLike, omega: ArrayLike, f: ArrayLike, dt: float) -> tuple[Array, Array]:
    """Jacobians of :func:`ins_step` at zero noise, batched over steps.

    Parameters
    ----------
    state : array_like, shape (..., 9) — the state before the step; omega : (...); f : (..., 2); dt : float [s]

    Returns
    -------
    F : ndarray, shape (..., 9, 9) — ∂s'/∂s; G : ndarray, shape (..., 9, 6) — ∂s'/∂(noise)
    """
    s = check_last_axis("state", state, 9)
    w = check_finite("omega", omega)
    ff = check_last_axis("f", f, 2)
    h = float(check_positive("dt", dt))
    batch = np.broadcast_shapes(s.shape[:-1], w.shape, ff.shape[:-1])
    s, w, ff = np.broadcast_to(s, (*batch, 9)), np.broadcast_to(w, batch), np.broadcast_to(ff, (*batch, 2))
    w_m = (1.0 + s[..., 6]) * w + s[..., 5]
    f_m = ff + s[..., 7:9]
    phi = s[..., 4] + 0.5 * w_m * h
    du_dphi = _rot(phi + 0.5 * np.pi, f_m)  # ∂(R(φ) f)/∂φ = R(φ + π/2) f
    c, sn = np.cos(phi), np.sin(phi)
    R = np.stack([np.stack([c, -sn], -1), np.stack([sn, c], -1)], -2)  # (..., 2, 2)
    # ∂φ/∂(θ, b_g, s_g, n_g) = (1, Δt/2, ωΔt/2, Δt/2)
    dphi = {4: np.ones(batch), 5: np.full(batch, 0.5 * h), 6: 0.5 * w * h}
    F = np.broadcast_to(np.eye(9), (*batch, 9, 9)).copy()
    F[..., 0, 2] = F[..., 1, 3] = h
    for col, d in dphi.items():
        F[..., 0:2, col] = 0.5 * h * h * du_dphi * d[..., None]
        F[..., 2:4, col] = h * du_dphi * d[..., None]
    F[..., 0:2, 7:9] = 0.5 * h * h * R
    F[..., 2:4, 7:9] = h * R
    F[..., 4, 5] = h
    F[..., 4, 6] = w * h
    G = np.zeros((*batch, 9, 6))
    G[..., 0:2, 0] = 0.25 * h**3 * du_dphi
    G[..., 2:4, 0] = 0.5 * h * h * du_dphi
    G[..., 4, 0] = h
    G[..., 0:2, 1:3] = 0.5 * h * h * R
    G[..., 2:4, 1:3] = h * R
    G[..., 5, 3] = 1.0
    G[..., 7, 4] = G[..., 8, 5] = 1.0
    return F, G


def _recursion(F: Array, G: Array, Q: Array, S0: Array) -> Array:
    """``Σ_{k+1} = F_k Σ_k F_kᵀ + G_k diag(Q_k) G_kᵀ`` for F (N, d, d), G (N, d, m), Q (N, m): (N+1, d, d)."""
    n, d = F.shape[0], F.shape[-1]
    noise = (G * Q[:, None, :]) @ np.swapaxes(G, -1, -2)  # every step's G Q Gᵀ at once
    covs = np.empty((n + 1, d, d))
    covs[0] = S0
    for k in range(n):  # the recursion itself (9×9 per step)
        covs[k + 1] = F[k] @ covs[k] @ F[k].T + noise[k]
    return covs


def _initial_cov(d: int, per_run: dict[int, float], cov0: ArrayLike | None, n_pose: int) -> Array:
    """Initial covariance: ``cov0`` on the first ``n_pose`` components, per-run variances on the others."""
    S0 = np.zeros((d, d))
    if cov0 is not None:
        C = check_finite("cov0", cov0)
        if C.shape != (n_pose, n_pose):
            raise ValueError(f"cov0 must have shape ({n_pose}, {n_pose}), got shape {C.shape}")
        S0[:n_pose, :n_pose] = C
    for i, var in per_run.items():
        S0[i, i] = var
    return S0


def propagate_ins(path: InertialPath, gyro: GyroErrors, accel: AccelErrors,
                  cov0: ArrayLike | None = None) -> tuple[Array, Array]:  # fmt: skip
    """Method A for the strapdown INS: the nominal states and their covariances.

    Parameters
    ----------
    path : InertialPath; gyro : GyroErrors; accel : AccelErrors
    cov0 : array_like, shape (5, 5), optional — initial covariance of ``(x, y, v_x, v_y, θ)``

    Returns
    -------
    states : ndarray, shape (N+1, 9) — nominal states (biases and scale 0)
    covs : ndarray, shape (N+1, 9, 9) [SI units of :data:`INS_STATE`]
    """
    h = path.dt
    nav = ins_integrate(path.omega, path.accel, h, path.start, path.v0)
    states = np.zeros((path.n_steps + 1, 9))
    states[:, :5] = nav
    F, G = ins_jacobians(states[:-1], path.omega, path.accel, h)
    q = np.array([gyro.white_std**2 / h, accel.white_std**2 / h, accel.white_std**2 / h,
                  gyro.bias_rw_std**2 * h, accel.bias_rw_std**2 * h, accel.bias_rw_std**2 * h])  # fmt: skip
    per_run = {5: gyro.bias_std**2, 6: gyro.scale_std**2, 7: accel.bias_std**2, 8: accel.bias_std**2}
    S0 = _initial_cov(9, per_run, cov0, 5)
    return states, _recursion(F, G, np.broadcast_to(q, (path.n_steps, 6)), S0)


def _step_indices(checkpoints: ArrayLike | None, n_steps: int) -> NDArray[np.intp]:
    idx = np.array([n_steps] if checkpoints is None else checkpoints, dtype=np.intp).reshape(-1)
    if idx.size == 0 or idx.min() < 0 or idx.max() > n_steps:
        raise ValueError(f"checkpoints must be step indices in [0, {n_steps}] (allowed: 0..N), got {idx.tolist()}")
    return idx


def _gyro_draws(gyro: GyroErrors, n: int, n_steps: int, dt: float,
                rng: np.random.Generator) -> tuple[Array, Array, Array]:  # fmt: skip
    """Per-particle gyro errors: bias before each step and after the last (n, N+1), scale (n,), white (n, N)."""
    b0 = gyro.bias_std * rng.standard_normal(n)
    scale = gyro.scale_std * rng.standard_normal(n)
    white = (gyro.white_std / np.sqrt(dt)) * rng.standard_normal((n, n_steps))
    walk = (gyro.bias_rw_std * np.sqrt(dt)) * rng.standard_normal((n, n_steps))
    bias = b0[:, None] + np.concatenate([np.zeros((n, 1)), np.cumsum(walk, axis=1)], axis=1)
    return bias, scale, white


def sample_ins(path: InertialPath, gyro: GyroErrors, accel: AccelErrors, n: int, rng: np.random.Generator,
               checkpoints: ArrayLike | None = None) -> Array:  # fmt: skip
    """Monte Carlo of the strapdown INS: ``n`` navigated states, vectorised (cumulative sums over steps).

    Parameters
    ----------
    path, gyro, accel : as :func:`propagate_ins`; n : int ≥ 1; rng : numpy.random.Generator
    checkpoints : sequence of int in [0, N], optional — step indices to return (default: the end)

    Returns
    -------
    ndarray, shape (n, C, 9) — the full state (:data:`INS_STATE`) of every particle at every checkpoint
    """
    n = check_positive_int("n", n)
    idx = _step_indices(checkpoints, path.n_steps)
    N, h = path.n_steps, path.dt
    bg, sg, ng = _gyro_draws(gyro, n, N, h, rng)
    ba0 = accel.bias_std * rng.standard_normal((n, 1, 2))
    na = (accel.white_std / np.sqrt(h)) * rng.standard_normal((n, N, 2))
    walk = (accel.bias_rw_std * np.sqrt(h)) * rng.standard_normal((n, N, 2))
    ba = ba0 + np.concatenate([np.zeros((n, 1, 2)), np.cumsum(walk, axis=1)], axis=1)  # (n, N+1, 2)
    w_m = (1.0 + sg[:, None]) * path.omega + bg[:, :-1] + ng
    f_m = path.accel + ba[:, :-1] + na
    nav = ins_integrate(w_m, f_m, h, path.start, path.v0)  # (n, N+1, 5)
    out = np.empty((n, idx.size, 9))
    out[..., :5] = nav[:, idx]
    out[..., 5] = bg[:, idx]
    out[..., 6] = sg[:, None]
    out[..., 7:9] = ba[:, idx]
    return out


# ============================================================================= gyro-aided odometry


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
    theta = path.start[2] + _exclusive_cumsum(path.omega * h)
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
    S0 = _initial_cov(5, {3: gyro.bias_std**2, 4: gyro.scale_std**2}, cov0, 3)
    return states, _recursion(F, G, q, S0)


def sample_odometry_gyro(path: OdometryGyroPath, gyro: GyroErrors, n: int, rng: np.random.Generator,
                         checkpoints: ArrayLike | None = None) -> Array:  # fmt: skip
    """Monte Carlo of gyro-aided odometry, vectorised over particles (cumulative sums over steps).

    Returns
    -------
    ndarray, shape (n, C, 5) — the full state (:data:`ODO_STATE`) at every checkpoint
    """
    n = check_positive_int("n", n)
    idx = _step_indices(checkpoints, path.n_steps)
    h = path.dt
    bg, sg, ng = _gyro_draws(gyro, n, path.n_steps, h, rng)
    travel = path.ds + np.sqrt(path.ds_var) * rng.standard_normal((n, path.n_steps))
    w_m = (1.0 + sg[:, None]) * path.omega + bg[:, :-1] + ng
    theta = path.start[2] + _exclusive_cumsum(w_m * h)
    phi = theta + 0.5 * w_m * h
    zero = np.zeros((n, 1))
    x = path.start[0] + np.concatenate([zero, np.cumsum(travel * np.cos(phi), axis=1)], axis=1)
    y = path.start[1] + np.concatenate([zero, np.cumsum(travel * np.sin(phi), axis=1)], axis=1)
    th = path.start[2] + np.concatenate([zero, np.cumsum(w_m * h, axis=1)], axis=1)
    out = np.empty((n, idx.size, 5))
    out[..., 0], out[..., 1], out[..., 2] = x[:, idx], y[:, idx], th[:, idx]
    out[..., 3], out[..., 4] = bg[:, idx], sg[:, None]
    return out


# ============================================================================= growth laws


def position_growth(times: ArrayLike, distance: ArrayLike, covs: ArrayLike) -> dict[str, dict[str, float]]:
    """Fit ``σ = a·t^p`` and ``σ = a·s^p`` (least squares on log-log) to the position error.

    ``σ_pos = √(Σ_xx + Σ_yy)`` (the rms position error); the fits are
    :func:`pose_uncertainty.core.stats.fit_growth` (points with t, s or σ equal to 0 left out).

    Parameters
    ----------
    times : array_like, shape (M,) [s]; distance : array_like, shape (M,) [m] — travelled so far
    covs : array_like, shape (M, d, d), d ≥ 2 — covariances whose first two components are (x, y)

    Returns
    -------
    dict — ``"time"`` and ``"distance"``: each the dict of :func:`~pose_uncertainty.core.stats.fit_growth`
    (``power_exponent`` p among others); ``"distance"`` is omitted when the robot does not move
    """
    C = check_finite("covs", covs)
    if C.ndim != 3 or C.shape[-1] < 2 or C.shape[-1] != C.shape[-2]:
        raise ValueError(f"covs must have shape (M, d, d) with d >= 2, got shape {C.shape}")
    sigma = np.sqrt(np.maximum(C[:, 0, 0] + C[:, 1, 1], 0.0))
    out = {"time": fit_growth(check_finite("times", times), sigma)}
    s = check_finite("distance", distance)
    if np.count_nonzero(s > 0) >= 3:
        out["distance"] = fit_growth(s, sigma)
    return out
