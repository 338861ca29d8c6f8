"""Method A for every drive: first-order propagation through the drive's own Jacobians.

A step of any drive is ``p' = f(p, ξ(u))`` (:func:`~pose_uncertainty.core.kinematics.step_twist`)
with the drive's twist ``ξ(u)`` (:mod:`pose_uncertainty.core.drives`). With
``(Δx, Δy) = s(Δθ) R(θ + cΔθ)(v₁, v₂)`` (``c`` = ½ midpoint/exact, 0 Euler,
1 Euler-end; ``s = sin(Δθ/2)/(Δθ/2)`` exact, 1 otherwise)::

    J_p = ∂p'/∂p = [[1, 0, −Δy], [0, 1, Δx], [0, 0, 1]]
    J_ξ = ∂p'/∂ξ = [[s R(φ) e₁, s R(φ) e₂, s' R(φ)(v₁, v₂) + c(−Δy, Δx)], [0, 0, 1]]
    J_u = ∂p'/∂u = J_ξ · ∂ξ/∂u

    Σ' = J_p Σ J_pᵀ + J_u Σ_u J_uᵀ + J_ξ Q_ξ J_ξᵀ

``Σ_u`` is the per-step covariance of the measurement errors and ``Q_ξ`` of
errors acting on the twist directly (the skid-steer's slip), both from
:mod:`.drive_noise`. For the differential drive with the midpoint rule this
is Method A (:mod:`.covariance`).

The per-run (systematic) regime has errors ``δξ_i = T_i ε`` fixed for the run
(:func:`.drive_noise.per_run_sensitivity`); to first order the pose error is
``S_n ε`` with ``S_{i+1} = J_p S_i + J_ξ T_i``, so ``Σ_n = S_n diag(var) S_nᵀ``
(:func:`propagate_per_run`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import Drive, DrivePath
from ..core.kinematics import HEADING_OFFSET, METHODS, Method, step_twist
from ..core.validation import check_choice, check_finite, check_last_axis, check_pose_cov
from . import drive_noise as dn
from .covariance import CovarianceResult
from .expcoords import ExpGaussian, propagate_twists

__all__ = [
    "expcoords",
    "propagate",
    "propagate_path",
    "propagate_path_per_run",
    "propagate_per_run",
    "step_jacobians",
    "twist_step_jacobians",
]


def _sinc_half_and_derivative(w: NDArray) -> tuple[NDArray, NDArray]:
    """``s(w) = sin(w/2)/(w/2)`` and ``s'(w) = ½(h cos h − sin h)/h²``, ``h = w/2`` (series near 0)."""
    h = 0.5 * w
    small = np.abs(h) < 1e-3
    hs = np.where(small, 1.0, h)
    s = np.sinc(h / np.pi)
    ds = np.where(
        small, 0.5 * (-h / 3.0 + h**3 / 30.0), 0.5 * (hs * np.cos(hs) - np.sin(hs)) / hs**2
    )
    return s, ds


def twist_step_jacobians(
    theta: ArrayLike, twist: ArrayLike, method: Method = "midpoint"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Jacobians of one twist step w.r.t. the pose and the twist (module docstring).

    Parameters
    ----------
    theta : array_like, shape (...) — heading before the step [rad]
    twist : array_like, shape (..., 3) — ``(v₁, v₂, Δθ)`` [m, m, rad]
    method : {"exact", "euler", "euler_end", "midpoint"}

    Returns
    -------
    J_p : ndarray, shape (..., 3, 3); J_xi : ndarray, shape (..., 3, 3)
    """
    check_choice("method", method, METHODS)
    th = check_finite("theta", theta)
    xi = check_finite("twist", check_last_axis("twist", twist, 3))
    v1, v2, w = xi[..., 0], xi[..., 1], xi[..., 2]
    c_off = HEADING_OFFSET[method]
    phi = th + c_off * w
    s, ds = (
        _sinc_half_and_derivative(w) if method == "exact" else (np.ones_like(w), np.zeros_like(w))
    )
    c, sn = np.cos(phi), np.sin(phi)
    rx, ry = v1 * c - v2 * sn, v1 * sn + v2 * c  # R(φ)(v₁, v₂)
    dx, dy = s * rx, s * ry
    one, zero = np.ones_like(dx), np.zeros_like(dx)
    J_p = np.stack(
        [
            np.stack([one, zero, -dy], -1),
            np.stack([zero, one, dx], -1),
            np.stack([zero, zero, one], -1),
        ],
        axis=-2,
    )
    J_xi = np.stack(
        [
            np.stack([s * c, -s * sn, ds * rx - c_off * dy], -1),
            np.stack([s * sn, s * c, ds * ry + c_off * dx], -1),
            np.stack([zero, zero, one], -1),
        ],
        axis=-2,
    )
    return J_p, J_xi


def step_jacobians(
    drive: Drive, pose: ArrayLike, u: ArrayLike, method: Method = "midpoint"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``J_p = ∂p'/∂p`` (..., 3, 3) and ``J_u = ∂p'/∂u`` (..., 3, m) of one step of ``drive``.

    Parameters
    ----------
    drive : Drive; pose : array_like, shape (..., 3); u : array_like, shape (..., m)
    method : {"exact", "euler", "euler_end", "midpoint"}
    """
    p = check_last_axis("pose", pose, 3)
    J_p, J_xi = twist_step_jacobians(p[..., 2], drive.twist(u), method)
    return J_p, J_xi @ drive.twist_jacobian(u)


def _check_sequence(
    drive: Drive, u: ArrayLike, cov: ArrayLike, name: str, d: int
) -> tuple[NDArray, NDArray]:
    a = check_finite("u", check_last_axis("u", u, drive.n_channels))
    C = check_finite(name, cov)
    if a.ndim < 2 or a.shape[-2] == 0:
        raise ValueError(
            f"u must have shape (..., N, {drive.n_channels}) with N >= 1, got {a.shape}"
        )
    if C.shape[-3:] != (a.shape[-2], d, d):
        raise ValueError(
            f"{name} must have shape (..., {a.shape[-2]}, {d}, {d}), got shape {C.shape}"
        )
    return a, C


def propagate(
    drive: Drive,
    u: ArrayLike,
    meas_cov: ArrayLike,
    *,
    twist_cov: ArrayLike | None = None,
    cov0: ArrayLike | None = None,
    start: ArrayLike = (0.0, 0.0, 0.0),
    method: Method = "midpoint",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Method A for any drive: the recursion ``Σ' = J_p Σ J_pᵀ + J_u Σ_u J_uᵀ + J_ξ Q_ξ J_ξᵀ``.

    Loops over steps, vectorised over the batch.

    Parameters
    ----------
    drive : Drive
    u : array_like, shape (B..., N, m) — mean measurements per step (the
        Jacobians are taken there; add any bias before)
    meas_cov : array_like, shape (B..., N, m, m) — Σ_u per step
    twist_cov : array_like, shape (B..., N, 3, 3), optional — Q_ξ per step
    cov0 : array_like, shape (B..., 3, 3), optional — initial covariance (default 0)
    start : array_like, shape (B..., 3) — start pose
    method : {"exact", "euler", "euler_end", "midpoint"} — integration of the mean

    Returns
    -------
    poses : ndarray, shape (B..., N+1, 3); covs : ndarray, shape (B..., N+1, 3, 3)
    """
    check_choice("method", method, METHODS)
    a, Su = _check_sequence(drive, u, meas_cov, "meas_cov", drive.n_channels)
    Qx = None if twist_cov is None else _check_sequence(drive, a, twist_cov, "twist_cov", 3)[1]
    S0 = check_pose_cov("cov0", cov0)
    p0 = check_finite("start", check_last_axis("start", start, 3))
    shapes = [a.shape[:-2], Su.shape[:-3], S0.shape[:-2], p0.shape[:-1]]
    batch = np.broadcast_shapes(*shapes, *([] if Qx is None else [Qx.shape[:-3]]))
    n = a.shape[-2]
    xi = drive.twist(a)
    Jxu = drive.twist_jacobian(a)
    poses = np.empty((*batch, n + 1, 3))
    covs = np.empty((*batch, n + 1, 3, 3))
    poses[..., 0, :] = p0
    covs[..., 0, :, :] = S0
    for i in range(n):
        J_p, J_xi = twist_step_jacobians(poses[..., i, 2], xi[..., i, :], method)
        J_u = J_xi @ Jxu[..., i, :, :]
        S = J_p @ covs[..., i, :, :] @ np.swapaxes(J_p, -1, -2)
        S = S + J_u @ Su[..., i, :, :] @ np.swapaxes(J_u, -1, -2)
        if Qx is not None:
            S = S + J_xi @ Qx[..., i, :, :] @ np.swapaxes(J_xi, -1, -2)
        covs[..., i + 1, :, :] = S
        poses[..., i + 1, :] = step_twist(poses[..., i, :], xi[..., i, :], method)
    return poses, covs


def propagate_path(
    path: DrivePath,
    model: dn.DriveErrorModel,
    *,
    cov0: ArrayLike | None = None,
    method: Method = "midpoint",
) -> CovarianceResult:
    """Method A along a drive's path under an error model (regime ``per_step``).

    The mean is the path of ``u + bias``; ``Σ_u`` from :func:`.drive_noise.measurement_cov`,
    the skid-steer slip from :func:`.drive_noise.slip_twist_cov`.
    """
    mean = dn.measurement_mean(path.drive, path.u, model)
    Su = dn.measurement_cov(path.drive, path.u, path.dt, model)
    Qx = dn.slip_twist_cov(path.drive, mean, model)
    poses, covs = propagate(
        path.drive, mean, Su, twist_cov=Qx, cov0=cov0, start=path.start, method=method
    )
    return CovarianceResult(poses=poses, covs=covs, times=path.times)


def propagate_per_run(
    drive: Drive,
    u: ArrayLike,
    sensitivity: dn.PerRunSensitivity,
    *,
    cov0: ArrayLike | None = None,
    start: ArrayLike = (0.0, 0.0, 0.0),
    method: Method = "midpoint",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """First-order covariance of the per-run regime: ``S_{i+1} = J_p S_i + J_ξ T_i``, ``Σ = S W Sᵀ``.

    Parameters
    ----------
    drive : Drive; u : array_like, shape (N, m) — mean measurements
    sensitivity : PerRunSensitivity — ``T`` (N, 3, r), ``var`` (r,)
    cov0 : array_like, shape (3, 3), optional — carried by ``Φ_{i+1} = J_p Φ_i``
    start : array_like, shape (3,); method : integration of the mean

    Returns
    -------
    poses : ndarray, shape (N+1, 3); covs : ndarray, shape (N+1, 3, 3)
    """
    check_choice("method", method, METHODS)
    a = check_finite("u", check_last_axis("u", u, drive.n_channels))
    T, var = sensitivity
    S0 = check_pose_cov("cov0", cov0)
    n = a.shape[-2]
    xi = drive.twist(a)
    poses = np.empty((n + 1, 3))
    covs = np.empty((n + 1, 3, 3))
    poses[0] = check_last_axis("start", start, 3)
    covs[0] = S0
    S = np.zeros((3, T.shape[-1]))
    Phi = np.eye(3)
    for i in range(n):
        J_p, J_xi = twist_step_jacobians(poses[i, 2], xi[i], method)
        S = J_p @ S + J_xi @ T[i]
        Phi = J_p @ Phi
        covs[i + 1] = (S * var) @ S.T + Phi @ S0 @ Phi.T
        poses[i + 1] = step_twist(poses[i], xi[i], method)
    return poses, covs


def propagate_path_per_run(
    path: DrivePath,
    model: dn.DriveErrorModel,
    *,
    cov0: ArrayLike | None = None,
    method: Method = "midpoint",
) -> CovarianceResult:
    """First-order covariance of the per-run regime along a drive's path (:func:`propagate_per_run`)."""
    mean = dn.measurement_mean(path.drive, path.u, model)
    sens = dn.per_run_sensitivity(path.drive, path.u, path.dt, model)
    poses, covs = propagate_per_run(
        path.drive, mean, sens, cov0=cov0, start=path.start, method=method
    )
    return CovarianceResult(poses=poses, covs=covs, times=path.times)


def expcoords(
    path: DrivePath, model: dn.DriveErrorModel, *, cov0: ArrayLike | None = None
) -> ExpGaussian:
    """The exponential-coordinates Gaussian along a drive's path (regime ``per_step``).

    Twist noise ``Q_ξ = (∂ξ/∂u) Σ_u (∂ξ/∂u)ᵀ`` (+ slip) at the mean measurements,
    propagated by :func:`.expcoords.propagate_twists`; the mean is the exact path of ``u + bias``.
    """
    mean = dn.measurement_mean(path.drive, path.u, model)
    Su = dn.measurement_cov(path.drive, path.u, path.dt, model)
    J = path.drive.twist_jacobian(mean)
    Q = J @ Su @ np.swapaxes(J, -1, -2)
    slip = dn.slip_twist_cov(path.drive, mean, model)
    if slip is not None:
        Q = Q + slip
    return propagate_twists(
        path.drive.twist(mean), Q, start=path.start, cov0=cov0, times=path.times
    )
