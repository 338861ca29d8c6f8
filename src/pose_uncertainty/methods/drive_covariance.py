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

Closed form, no loop over steps
-------------------------------
For every drive and every integration method ``J_p = I + c e₃ᵀ`` with
``c = (−Δy, Δx, 0) = m(p') − m(p)``, ``m(p) = (−y, x, 0)``, and
``(I + a e₃ᵀ)(I + b e₃ᵀ) = I + (a + b) e₃ᵀ`` (``e₃ᵀ a = 0``): the product of the
step Jacobians from pose ``k`` to pose ``n`` is ``A_{n,k} = I + (m_n − m_k) e₃ᵀ``. So::

    Σ_n = A_{n,0} Σ_0 A_{n,0}ᵀ + Σ_{i<n} A_{n,i+1} Q_i A_{n,i+1}ᵀ,   Q_i = J_u Σ_u J_uᵀ + J_ξ Q_ξ J_ξᵀ

and with ``d = m_n − m_{i+1}``, ``A Q Aᵀ = Q + d qᵀ + q dᵀ + s d dᵀ`` (``q = Q e₃``,
``s = Q₃₃``) expands into prefix sums over the steps (:func:`transport`); likewise
``S_n = Σ_{i<n} A_{n,i+1} J_ξ T_i`` of the per-run regime. ``m`` is taken relative
to the start (the result does not depend on the origin). :func:`step` is the
recursion itself, one step at a time (the reference the closed form is tested against).

The differential drive is one drive among the others: Method A of
:mod:`.covariance` (``propagate``, ``propagate_travels``, ``step``, ``jacobians``) is
its front door, with ``ξ = ((Δs_r + Δs_l)/2, 0, (Δs_r − Δs_l)/b)`` and
``Σ_u = diag(k_r|Δs_r|, k_l|Δs_l|)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import Drive, DrivePath
from ..core.kinematics import HEADING_OFFSET, METHODS, Method, integrate_twist, step_twist
from ..core.validation import check_choice, check_finite, check_last_axis, check_pose_cov
from . import drive_noise as dn
from .expcoords import ExpGaussian, propagate_twists
from .particles import REGIMES

__all__ = [
    "CovarianceResult",
    "expcoords",
    "propagate",
    "propagate_path",
    "propagate_path_per_run",
    "propagate_per_run",
    "propagate_steps",
    "start_covariance",
    "step",
    "step_covariance",
    "step_jacobians",
    "transport",
    "twist_step_jacobians",
]


@dataclass(frozen=True, eq=False)
class CovarianceResult:
    """Poses and covariances along a trajectory.

    Attributes
    ----------
    poses : ndarray, shape (B..., N+1, 3) — mean poses [m, m, rad]
    covs : ndarray, shape (B..., N+1, 3, 3) — pose covariances [m², m·rad, rad²]
    times : ndarray, shape (N+1,) — [s]
    """

    poses: NDArray[np.float64]
    covs: NDArray[np.float64]
    times: NDArray[np.float64]


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
    J_p, J_xi = _twist_jacobians_soa(th, xi, method)
    return np.moveaxis(J_p, (0, 1), (-2, -1)), np.moveaxis(J_xi, (0, 1), (-2, -1))


def _twist_jacobians_soa(th: NDArray, xi: NDArray, method: str) -> tuple[NDArray, NDArray]:
    """:func:`twist_step_jacobians` stored entry by entry, shapes (3, 3, ...) (:func:`_mm_soa`)."""
    v1, v2, w = xi[..., 0], xi[..., 1], xi[..., 2]
    c_off = HEADING_OFFSET[method]
    phi = th + c_off * w
    s, ds = (
        _sinc_half_and_derivative(w) if method == "exact" else (np.ones_like(w), np.zeros_like(w))
    )
    c, sn = np.cos(phi), np.sin(phi)
    rx, ry = v1 * c - v2 * sn, v1 * sn + v2 * c  # R(φ)(v₁, v₂)
    dx, dy = s * rx, s * ry
    eye = np.eye(3).reshape(3, 3, *([1] * dx.ndim))
    J_p = np.broadcast_to(eye, (3, 3, *dx.shape)).copy()
    J_p[0, 2], J_p[1, 2] = -dy, dx
    J_xi = J_p * 0.0 + eye
    J_xi[0, 0], J_xi[0, 1], J_xi[0, 2] = s * c, -s * sn, ds * rx - c_off * dy
    J_xi[1, 0], J_xi[1, 1], J_xi[1, 2] = s * sn, s * c, ds * ry + c_off * dx
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
    return J_p, _mm(J_xi, drive.twist_jacobian(u))


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


def _mm(A: NDArray, B: NDArray) -> NDArray:
    """``A B`` over the last two axes, broadcast."""
    return np.moveaxis(_mm_soa(_soa(A), _soa(B)), (0, 1), (-2, -1))


def _sandwich(J: NDArray, S: NDArray) -> NDArray:
    """``J S Jᵀ`` over the last two axes, broadcast."""
    return np.moveaxis(_sandwich_soa(_soa(J), _soa(S)), (0, 1), (-2, -1))


def _soa(A: ArrayLike) -> NDArray:
    """Matrices (..., r, c) as one contiguous array per entry, shape (r, c, ...)."""
    return np.ascontiguousarray(np.moveaxis(np.asarray(A, dtype=np.float64), (-2, -1), (0, 1)))


def _mm_soa(A: NDArray, B: NDArray) -> NDArray:
    """``A B`` of matrices stored entry by entry, (r, k, ...) × (k, c, ...) → (r, c, ...): whole
    arrays per entry (``np.matmul`` over many 3×3 matrices calls a kernel per matrix)."""
    out = np.empty((A.shape[0], B.shape[1], *np.broadcast_shapes(A.shape[2:], B.shape[2:])))
    for r in range(A.shape[0]):
        for c in range(B.shape[1]):
            acc = A[r, 0] * B[0, c]
            for k in range(1, A.shape[1]):
                acc = acc + A[r, k] * B[k, c]
            out[r, c] = acc
    return out


def _sandwich_soa(J: NDArray, S: NDArray) -> NDArray:
    """``J S Jᵀ`` of matrices stored entry by entry (:func:`_mm_soa`)."""
    return _mm_soa(_mm_soa(J, S), np.swapaxes(J, 0, 1))


def step_covariance(
    J_p: ArrayLike, cov: ArrayLike, J_u: ArrayLike, meas_cov: ArrayLike
) -> NDArray[np.float64]:
    """One step of the covariance recursion ``Σ' = J_p Σ J_pᵀ + J_u Σ_u J_uᵀ``, batched.

    Parameters
    ----------
    J_p : array_like, shape (..., 3, 3); cov : array_like, shape (..., 3, 3)
    J_u : array_like, shape (..., 3, m); meas_cov : array_like, shape (..., m, m)
    """
    return _sandwich(np.asarray(J_p, dtype=np.float64), np.asarray(cov, dtype=np.float64)) + _sandwich(
        np.asarray(J_u, dtype=np.float64), np.asarray(meas_cov, dtype=np.float64)
    )


def step(
    drive: Drive,
    pose: ArrayLike,
    cov: ArrayLike,
    u: ArrayLike,
    meas_cov: ArrayLike,
    method: Method = "midpoint",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One step of the recursion ``p' = f(p, ξ(u))``, ``Σ' = J_p Σ J_pᵀ + J_u Σ_u J_uᵀ``, batched.

    Parameters
    ----------
    drive : Drive; pose : array_like, shape (..., 3); cov : array_like, shape (..., 3, 3)
    u : array_like, shape (..., m); meas_cov : array_like, shape (..., m, m)
    method : {"exact", "euler", "euler_end", "midpoint"}

    Returns
    -------
    pose' : ndarray, shape (..., 3); cov' : ndarray, shape (..., 3, 3)
    """
    p = check_last_axis("pose", pose, 3)
    J_p, J_u = step_jacobians(drive, p, u, method)
    S = step_covariance(J_p, check_finite("cov", cov), J_u, check_finite("meas_cov", meas_cov))
    return step_twist(p, drive.twist(u), method), S


def _prefix(x: NDArray) -> NDArray:
    """Prefix sums over the last axis (the steps) with a leading 0: ``out[..., n] = Σ_{i<n} x[..., i]``."""
    out = np.zeros((*x.shape[:-1], x.shape[-1] + 1))
    np.cumsum(x, axis=-1, out=out[..., 1:])
    return out


def _levers(poses: NDArray) -> tuple[NDArray, NDArray]:
    """The planar part of ``m(p) − m(p_0)``, ``m(p) = (−y, x, 0)``: two arrays (..., N+1), the heading's lever arms."""
    return poses[..., :1, 1] - poses[..., 1], poses[..., 0] - poses[..., :1, 0]


_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def transport(poses: ArrayLike, noise: ArrayLike) -> NDArray[np.float64]:
    """``Σ_n = Σ_{i<n} A_{n,i+1} Q_i A_{n,i+1}ᵀ`` for every ``n``, closed form (module docstring).

    ``A Q Aᵀ = Q + d qᵀ + q dᵀ + s d dᵀ`` with ``d = m_n − m_{i+1}`` (zero heading
    entry), ``q = Q e₃``, ``s = Q₃₃``, summed over ``i < n`` by prefix sums, entry by entry:
    ``Σ_rc = ΣQ_rc + X_rc + X_cr + [r, c < 2] (Σ s m_r m_c + m_r m_c Σ s)`` with
    ``X_rc = m_r (Σ q_c − [c < 2] Σ s m_c) − Σ m_r q_c`` for ``r < 2`` (``m`` at ``n`` outside
    the sums, at ``i+1`` inside).

    Parameters
    ----------
    poses : array_like, shape (B..., N+1, 3) — the mean path [m, m, rad]
    noise : array_like, shape (B..., N, 3, 3) — ``Q_i``, the pose noise step ``i`` adds [m², m·rad, rad²]

    Returns
    -------
    ndarray, shape (B..., N+1, 3, 3) — symmetric; ``Σ_0 = 0``
    """
    return _transport_soa(np.asarray(poses, dtype=np.float64), _soa(noise))


def _transport_soa(poses: NDArray, Q: NDArray) -> NDArray:
    """:func:`transport` with ``Q`` stored entry by entry, shape (3, 3, B..., N)."""
    m = _levers(poses)  # (..., N+1) each
    mi = (m[0][..., 1:], m[1][..., 1:])  # m_{i+1}
    s = Q[2, 2]
    q = [0.5 * (Q[c, 2] + Q[2, c]) for c in range(3)]  # Q e₃, symmetrised
    P_s = _prefix(s)
    P_sm = [_prefix(s * mi[r]) for r in range(2)]
    lin = [_prefix(q[c]) - (P_sm[c] if c < 2 else 0.0) for c in range(3)]

    # X_rc for the rows of x, y (r < 2), each once
    X = {(r, c): m[r] * lin[c] - _prefix(mi[r] * q[c]) for r in range(2) for c in range(3)}
    S = np.empty((*np.broadcast_shapes(P_s.shape, m[0].shape), 3, 3))
    for r, c in _PAIRS:
        e = _prefix(0.5 * (Q[r, c] + Q[c, r]))
        if r < 2:
            e = e + X[r, c]
        if c < 2:
            e = e + X[c, r]
        if r < 2 and c < 2:
            e = e + _prefix(s * mi[r] * mi[c]) + m[r] * m[c] * P_s
        S[..., r, c] = e
        S[..., c, r] = e
    return S


def start_covariance(poses: ArrayLike, cov0: ArrayLike) -> NDArray[np.float64]:
    """The start covariance carried along the path: ``A_{n,0} Σ_0 A_{n,0}ᵀ``, shape (B..., N+1, 3, 3).

    Parameters
    ----------
    poses : array_like, shape (B..., N+1, 3); cov0 : array_like, shape (B..., 3, 3)
    """
    A = np.broadcast_to(np.eye(3), (*np.shape(poses)[:-1], 3, 3)).copy()
    A[..., 0, 2], A[..., 1, 2] = _levers(np.asarray(poses, dtype=np.float64))
    return _sandwich(A, np.asarray(cov0, dtype=np.float64)[..., None, :, :])


def propagate_steps(
    twists: ArrayLike,
    twist_jacobian: ArrayLike,
    meas_cov: ArrayLike,
    *,
    twist_cov: ArrayLike | None = None,
    cov0: ArrayLike | None = None,
    start: ArrayLike = (0.0, 0.0, 0.0),
    method: Method = "midpoint",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Method A from per-step twists and their Jacobians, closed form (the kernel of every drive).

    Parameters
    ----------
    twists : array_like, shape (B..., N, 3) — mean twists ``ξ(u)`` [m, m, rad]
    twist_jacobian : array_like, shape (B..., N, 3, m) — ``∂ξ/∂u`` there
    meas_cov : array_like, shape (B..., N, m, m) — ``Σ_u`` per step
    twist_cov : array_like, shape (B..., N, 3, 3), optional — ``Q_ξ`` per step
    cov0 : array_like, shape (B..., 3, 3), optional — initial covariance (default 0)
    start : array_like, shape (B..., 3); method : integration of the mean

    Returns
    -------
    poses : ndarray, shape (B..., N+1, 3); covs : ndarray, shape (B..., N+1, 3, 3)
    """
    xi = np.asarray(twists, dtype=np.float64)
    poses = integrate_twist(xi, start, method)
    _, Jx = _twist_jacobians_soa(poses[..., :-1, 2], xi, method)
    Q = _sandwich_soa(_mm_soa(Jx, _soa(twist_jacobian)), _soa(meas_cov))
    if twist_cov is not None:
        Q = Q + _sandwich_soa(Jx, _soa(twist_cov))
    covs = _transport_soa(poses, Q)
    S0 = check_pose_cov("cov0", cov0)
    if np.any(S0):
        covs = covs + start_covariance(poses, S0)
    batch = covs.shape[:-3]
    return np.broadcast_to(poses, batch + poses.shape[-2:]).copy(), covs


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
    """Method A for any drive: ``Σ' = J_p Σ J_pᵀ + J_u Σ_u J_uᵀ + J_ξ Q_ξ J_ξᵀ`` in closed form.

    No loop over steps or over the batch (:func:`propagate_steps`).

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
    p0 = check_finite("start", check_last_axis("start", start, 3))
    return propagate_steps(
        drive.twist(a), drive.twist_jacobian(a), Su, twist_cov=Qx, cov0=cov0, start=p0, method=method
    )


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

    Closed form: ``S_n = Σ_{i<n} (t_i + (m_n − m_{i+1}) g_iᵀ)`` with ``t_i = J_ξ T_i`` and
    ``g_i`` its heading row (module docstring).

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
    xi = drive.twist(a)
    poses = integrate_twist(xi, check_last_axis("start", start, 3), method)
    _, Jx = _twist_jacobians_soa(poses[..., :-1, 2], xi, method)
    t = np.moveaxis(_mm_soa(Jx, _soa(T)), (0, 1), (-2, -1))  # (N, 3, r)
    m = _levers(poses)
    S = np.empty((poses.shape[0], 3, t.shape[-1]))
    for j in range(t.shape[-1]):
        g = t[:, 2, j]  # S_n = Σ t + (m_n − m_{i+1}) g for the x, y rows
        for r in range(3):
            e = _prefix(t[:, r, j])
            S[:, r, j] = e + m[r] * _prefix(g) - _prefix(m[r][1:] * g) if r < 2 else e
    covs = _sandwich(S, var[..., None, :] * np.eye(var.shape[-1]))
    if np.any(S0):
        covs = covs + start_covariance(poses, S0)
    return poses, covs


def propagate_path(
    path: DrivePath,
    model: dn.DriveErrorModel,
    *,
    cov0: ArrayLike | None = None,
    method: Method = "midpoint",
    regime: str = "per_step",
) -> CovarianceResult:
    """Method A along a drive's path under an error model.

    The mean is the path of ``u + bias``. ``per_step``: ``Σ_u`` from
    :func:`.drive_noise.measurement_cov`, the skid-steer slip from
    :func:`.drive_noise.slip_twist_cov` (:func:`propagate`); ``per_run``: the
    sensitivities of :func:`.drive_noise.per_run_sensitivity` (:func:`propagate_per_run`).
    """
    check_choice("regime", regime, REGIMES)
    mean = dn.measurement_mean(path.drive, path.u, model)
    if regime == "per_step":
        Su = dn.measurement_cov(path.drive, path.u, path.dt, model)
        Qx = dn.slip_twist_cov(path.drive, mean, model)
        poses, covs = propagate(
            path.drive, mean, Su, twist_cov=Qx, cov0=cov0, start=path.start, method=method
        )
    else:
        sens = dn.per_run_sensitivity(path.drive, path.u, path.dt, model)
        poses, covs = propagate_per_run(
            path.drive, mean, sens, cov0=cov0, start=path.start, method=method
        )
    return CovarianceResult(poses=poses, covs=covs, times=path.times)


def propagate_path_per_run(
    path: DrivePath,
    model: dn.DriveErrorModel,
    *,
    cov0: ArrayLike | None = None,
    method: Method = "midpoint",
) -> CovarianceResult:
    """:func:`propagate_path` in the per-run regime (:func:`propagate_per_run`)."""
    return propagate_path(path, model, cov0=cov0, method=method, regime="per_run")


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
