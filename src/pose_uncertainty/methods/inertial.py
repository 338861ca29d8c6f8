"""A 2-D strapdown inertial navigation system (Skalka 2011 §3.4.2): Method A and Monte Carlo.

Skalka 2011 §3.4 describes inertial navigation (accelerometers, gyroscopes, the strapdown layout)
and says that its error grows with *time*, where odometry's grows with *distance*. State
``(x, y, v_x, v_y, θ, b_g, s_g, b_ax, b_ay)``, sensor errors of
:mod:`pose_uncertainty.methods.inertial_sensors`, midpoint heading::

    θ' = θ + ω_m Δt,   φ = θ + ω_m Δt/2,   u = R(φ) f_m,   v' = v + u Δt,   p' = p + v Δt + u Δt²/2

The navigation integrates the measured signals as they are (dead reckoning: nothing estimates the
errors). Method A: ``Σ' = F Σ Fᵀ + G Q Gᵀ`` with the Jacobians of :func:`ins_jacobians` (every step's
at once); Monte Carlo: :func:`sample_ins`, vectorised over particles with cumulative sums over
steps. Known growth laws, recovered by the tests: constant accelerometer bias → position error ∝ t²;
accelerometer white noise → ∝ t^{3/2}; a heading error moves the position only under a specific force.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.trajectories import Trajectory
from ..core.validation import check_finite, check_last_axis, check_positive, check_positive_int
from .inertial_sensors import (
    AccelErrors,
    GyroErrors,
    exclusive_cumsum,
    initial_covariance,
    propagate_linearised,
    sample_gyro_errors,
    step_indices,
)

__all__ = [
    "INS_STATE",
    "InertialPath",
    "ins_integrate",
    "ins_jacobians",
    "ins_step",
    "propagate_ins",
    "sample_ins",
]

Array = NDArray[np.float64]

#: Names of the INS state components, in order.
INS_STATE: tuple[str, ...] = ("x", "y", "vx", "vy", "theta", "b_g", "s_g", "b_ax", "b_ay")


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

    @classmethod
    def from_trajectory(cls, trajectory: Trajectory) -> InertialPath:
        """The true inputs of an INS carried along a trajectory (vectorised over steps).

        Yaw rate ``ω_k = Δθ_k/Δt``; the speed at each step boundary is the mean of the adjacent
        steps' ``Δs/Δt`` (the first and last step's own at the ends), along the heading there, and
        the specific force is the one that turns and changes the velocity between boundaries:
        ``f_k = R(φ_k)ᵀ (v_{k+1} − v_k)/Δt``. The navigated headings are the trajectory's exactly; the
        positions follow its path to O(Δt²) (the trapezoid of the boundary velocities; 6·10⁻⁶ m over
        the S-curve of radius 1 m at Δt = 10 ms).
        """
        h = trajectory.dt
        omega = np.asarray(trajectory.dtheta, dtype=np.float64) / h
        speed = np.asarray(trajectory.ds, dtype=np.float64) / h
        boundary = np.concatenate([speed[:1], 0.5 * (speed[:-1] + speed[1:]), speed[-1:]])
        start = np.asarray(trajectory.start, dtype=np.float64)
        theta = start[2] + np.concatenate([[0.0], np.cumsum(omega * h)])
        v = boundary[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=-1)
        accel = _rot(-(theta[:-1] + 0.5 * omega * h), np.diff(v, axis=0) / h)
        return cls(omega, accel, h, start, v[0])


def _rot(phi: Array, v: Array) -> Array:
    """``R(φ) v`` for angles (...) and vectors (..., 2)."""
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


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
    theta = p0[2] + exclusive_cumsum(w * h)  # heading before each step
    u = _rot(theta + 0.5 * w * h, f)  # world-frame acceleration of each step
    dv = u * h
    v_before = v_0 + np.moveaxis(exclusive_cumsum(np.moveaxis(dv, -1, 0)), 0, -1)
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
    S0 = initial_covariance(9, per_run, cov0, 5)
    return states, propagate_linearised(F, G, np.broadcast_to(q, (path.n_steps, 6)), S0)


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
    idx = step_indices(checkpoints, path.n_steps)
    N, h = path.n_steps, path.dt
    bg, sg, ng = sample_gyro_errors(gyro, n, N, h, rng)
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
