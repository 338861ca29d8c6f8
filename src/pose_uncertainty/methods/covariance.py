"""Method A — first-order covariance propagation (Siegwart & Nourbakhsh 2004; Němec 2012 §2.1).

Midpoint step with ``Δs = (Δs_r+Δs_l)/2``, ``Δθ = (Δs_r−Δs_l)/b`` and
``φ = θ + Δθ/2``::

    Σ_p' = J_p Σ_p J_pᵀ + J_Δ Σ_Δ J_Δᵀ,        Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|)

Two routes compute the same covariances:

* :func:`propagate_recursive` — the recursion above, one step at a time
  (batched over parameter sets); the reference.
* :func:`propagate` — closed form, no loop over steps. The midpoint ``J_p`` is
  ``I + c e₃ᵀ`` with ``c = (−Δy, Δx, 0)``, so a product of them from step ``m``
  to ``n`` is ``A(p_n − p_m) = I + (−(y_n−y_m), x_n−x_m, 0)ᵀ e₃ᵀ``; hence
  ``Σ_n = A Σ_0 Aᵀ + Σ_{i<n} A(p_n − p_{i+1}) Q_i A(·)ᵀ`` with
  ``Q_i = J_Δ Σ_Δ J_Δᵀ``, which expands into prefix sums. The covariance is
  linear in ``(k_r, k_l)``, so the prefix sums are computed once per geometry
  for unit constants and combined for every parameter set.

Error ellipses (Němec 2012 §2.1.1) come from :func:`ellipse` (closed form) and
:func:`ellipse_polyline` (transformed circle).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import integrate
from ..core.stats import PR_3SIGMA, k_to_pr, pr_to_k
from ..core.trajectories import Trajectory
from ..core.validation import (
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_pose_cov,
    check_positive,
    check_positive_int,
)

__all__ = [
    "PR_3SIGMA",
    "CovarianceResult",
    "Ellipse",
    "ellipse",
    "ellipse_polyline",
    "jacobians",
    "k_to_pr",
    "pr_to_k",
    "propagate",
    "propagate_recursive",
    "propagate_travels",
    "step",
]



@dataclass(frozen=True, eq=False)
class CovarianceResult:
    """Poses and covariances along a trajectory.

    Attributes
    ----------
    poses : ndarray, shape (B..., N+1, 3) — midpoint-integrated mean poses [m, m, rad]
    covs : ndarray, shape (B..., N+1, 3, 3) — pose covariances [m², m·rad, rad²]
    times : ndarray, shape (N+1,) — [s]
    """

    poses: NDArray[np.float64]
    covs: NDArray[np.float64]
    times: NDArray[np.float64]


def jacobians(
    theta: ArrayLike, ds_r: ArrayLike, ds_l: ArrayLike, track: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Jacobians of the midpoint step with respect to the pose and the wheel travels.

    Parameters
    ----------
    theta : array_like, shape (...) — heading before the step [rad]
    ds_r, ds_l : array_like, shape (...) — wheel travels of the step [m]
    track : array_like, shape (...) — wheel separation b [m], > 0

    Returns
    -------
    J_p : ndarray, shape (..., 3, 3) — ∂p'/∂p
    J_delta : ndarray, shape (..., 3, 2) — ∂p'/∂(Δs_r, Δs_l)
    """
    th = check_finite("theta", theta)
    sr = check_finite("ds_r", ds_r)
    sl = check_finite("ds_l", ds_l)
    b = check_positive("track", track)
    th, sr, sl, b = np.broadcast_arrays(th, sr, sl, b)
    ds = (sr + sl) / 2.0
    phi = th + (sr - sl) / (2.0 * b)
    c, s = np.cos(phi), np.sin(phi)
    one, zero = np.ones_like(th), np.zeros_like(th)
    J_p = np.stack(
        [
            np.stack([one, zero, -ds * s], axis=-1),
            np.stack([zero, one, ds * c], axis=-1),
            np.stack([zero, zero, one], axis=-1),
        ],
        axis=-2,
    )
    h = ds / (2.0 * b)
    J_delta = np.stack(
        [
            np.stack([0.5 * c - h * s, 0.5 * c + h * s], axis=-1),
            np.stack([0.5 * s + h * c, 0.5 * s - h * c], axis=-1),
            np.stack([1.0 / b, -1.0 / b], axis=-1),
        ],
        axis=-2,
    )
    return J_p, J_delta


def _sigma_delta(ds_r: NDArray, ds_l: NDArray, k_r: NDArray, k_l: NDArray) -> NDArray:
    """Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|), shape (..., 2, 2)."""
    zero = np.zeros(np.broadcast_shapes(np.shape(ds_r), np.shape(k_r), np.shape(k_l)))
    return np.stack(
        [
            np.stack([k_r * np.abs(ds_r) + zero, zero], axis=-1),
            np.stack([zero, k_l * np.abs(ds_l) + zero], axis=-1),
        ],
        axis=-2,
    )


def step(
    pose: ArrayLike,
    cov: ArrayLike,
    ds_r: ArrayLike,
    ds_l: ArrayLike,
    k_r: ArrayLike,
    k_l: ArrayLike,
    track: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One midpoint step of the mean and the covariance, batched.

    ``Σ' = J_p Σ J_pᵀ + J_Δ Σ_Δ J_Δᵀ``.

    Parameters
    ----------
    pose : array_like, shape (..., 3); cov : array_like, shape (..., 3, 3)
    ds_r, ds_l : array_like, shape (...) [m]
    k_r, k_l : array_like, shape (...) [m] — error constants, ≥ 0
    track : array_like, shape (...) [m], > 0

    Returns
    -------
    pose' : ndarray, shape (..., 3); cov' : ndarray, shape (..., 3, 3)
    """
    p = check_last_axis("pose", pose, 3)
    S = check_last_axis("cov", cov, 3)
    kr = check_nonnegative("k_r", k_r)
    kl = check_nonnegative("k_l", k_l)
    sr = check_finite("ds_r", ds_r)
    sl = check_finite("ds_l", ds_l)
    b = check_positive("track", track)
    J_p, J_d = jacobians(p[..., 2], sr, sl, b)
    ds = (sr + sl) / 2.0
    dth = (sr - sl) / b
    phi = p[..., 2] + dth / 2.0
    new_pose = np.stack(
        [p[..., 0] + ds * np.cos(phi), p[..., 1] + ds * np.sin(phi), p[..., 2] + dth], axis=-1
    )
    S_d = _sigma_delta(sr, sl, kr, kl)
    # Σ' = J_p Σ J_pᵀ + J_Δ Σ_Δ J_Δᵀ
    new_cov = J_p @ S @ np.swapaxes(J_p, -1, -2) + J_d @ S_d @ np.swapaxes(J_d, -1, -2)
    return new_pose, new_cov


def _check_travels(ds_r: ArrayLike, ds_l: ArrayLike) -> tuple[NDArray, NDArray]:
    sr = check_finite("ds_r", ds_r)
    sl = check_finite("ds_l", ds_l)
    sr, sl = np.broadcast_arrays(sr, sl)
    if sr.ndim == 0 or sr.shape[-1] == 0:
        raise ValueError(
            f"ds_r, ds_l must have shape (..., N) with N >= 1 (allowed: N >= 1), got {sr.shape}"
        )
    return sr, sl


def _check_inputs(
    ds_r: ArrayLike,
    ds_l: ArrayLike,
    track: ArrayLike,
    k_r: ArrayLike,
    k_l: ArrayLike,
    cov0: ArrayLike | None,
    start: ArrayLike,
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray, NDArray, NDArray]:
    """Validate the arguments shared by both propagation routes."""
    sr, sl = _check_travels(ds_r, ds_l)
    return (
        sr,
        sl,
        check_positive("track", track),
        check_nonnegative("k_r", k_r),
        check_nonnegative("k_l", k_l),
        check_pose_cov("cov0", cov0),
        check_last_axis("start", start, 3),
    )


def propagate_recursive(
    ds_r: ArrayLike,
    ds_l: ArrayLike,
    track: ArrayLike,
    k_r: ArrayLike,
    k_l: ArrayLike,
    cov0: ArrayLike | None = None,
    start: ArrayLike = (0.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reference propagation: the recursion of Němec 2012 §2.1, one step at a time.

    Parameters as :func:`propagate_travels`. Loops over steps (not over
    parameter sets); used to test :func:`propagate_travels`.

    Returns
    -------
    poses : ndarray, shape (B..., N+1, 3); covs : ndarray, shape (B..., N+1, 3, 3)
    """
    sr, sl, b, kr, kl, S0, p0 = _check_inputs(ds_r, ds_l, track, k_r, k_l, cov0, start)
    batch = np.broadcast_shapes(sr.shape[:-1], b.shape, kr.shape, kl.shape, S0.shape[:-2], p0.shape[:-1])
    n = sr.shape[-1]
    poses = np.empty((*batch, n + 1, 3))
    covs = np.empty((*batch, n + 1, 3, 3))
    poses[..., 0, :] = p0
    covs[..., 0, :, :] = S0
    for i in range(n):
        poses[..., i + 1, :], covs[..., i + 1, :, :] = step(
            poses[..., i, :], covs[..., i, :, :], sr[..., i], sl[..., i], kr, kl, b
        )
    return poses, covs


def _prefix(x: NDArray) -> NDArray:
    """Prefix sums over the last axis with a leading 0: out[..., n] = Σ_{i<n} x[..., i]."""
    out = np.zeros((*x.shape[:-1], x.shape[-1] + 1))
    np.cumsum(x, axis=-1, out=out[..., 1:])
    return out


_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _unit_responses(
    poses: NDArray, sr: NDArray, sl: NDArray, b: NDArray
) -> tuple[NDArray, NDArray]:
    """Covariances along the path for (k_r, k_l) = (1, 0) and (0, 1), with Σ_0 = 0.

    Shapes (G..., N+1, 3, 3) where G is the geometry batch shape.

    With the lever arm ``m(p) = (−y, x, 0)``, the propagated noise of step i seen
    at step n is ``A j = j + j₃ (m_n − m_{i+1}) = a_i + g_i m_n`` for each column
    ``j`` of ``J_Δ`` (``a_i = j − j₃ m_{i+1}``, ``g_i = j₃``), so
    ``Σ_n = Σ_{i<n} w_i (a_i + g_i m_n)(a_i + g_i m_n)ᵀ`` with ``w_i = |Δs_i|``:
    prefix sums of ``w a aᵀ``, ``w g a`` and ``w g²``.
    """
    _, J_d = jacobians(poses[..., :-1, 2], sr, sl, b[..., None])
    m = (-poses[..., 1], poses[..., 0])  # m(p) = (−y, x, 0), the zero entry left implicit
    shape = (*poses.shape[:-1], 3, 3)
    out = []
    for col, travel in ((0, sr), (1, sl)):
        w = np.abs(travel)
        g = J_d[..., 2, col]
        a = [J_d[..., 0, col] - g * m[0][..., 1:], J_d[..., 1, col] - g * m[1][..., 1:], g]
        P_gg = _prefix(w * g * g)
        P_ga = [_prefix(w * g * a[r]) for r in range(3)]
        m_full = (m[0], m[1], np.zeros_like(m[0]))
        S = np.empty(shape)
        for r, c in _PAIRS:
            # Σ w a_r a_c + m_r Σ w g a_c + m_c Σ w g a_r + m_r m_c Σ w g²
            e = _prefix(w * a[r] * a[c])
            if r < 2:
                e += m_full[r] * P_ga[c]
            if c < 2:
                e += m_full[c] * P_ga[r]
            if r < 2 and c < 2:
                e += m_full[r] * m_full[c] * P_gg
            S[..., r, c] = e
            S[..., c, r] = e
        out.append(S)
    return out[0], out[1]


def propagate_travels(
    ds_r: ArrayLike,
    ds_l: ArrayLike,
    track: ArrayLike,
    k_r: ArrayLike,
    k_l: ArrayLike,
    cov0: ArrayLike | None = None,
    start: ArrayLike = (0.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Covariance propagation from wheel travels, closed form (no loop over steps or sets).

    Parameters
    ----------
    ds_r, ds_l : array_like, shape (G..., N) — per-step wheel travels [m]
    track : array_like, shape (G...) — wheel separation b [m], > 0
    k_r, k_l : array_like, shape (B...) — error constants [m] (variance of wheel
        travel per metre travelled), ≥ 0; broadcast with the geometry batch
    cov0 : array_like, shape (B..., 3, 3), optional — initial covariance (default 0)
    start : array_like, shape (3,) — start pose

    Returns
    -------
    poses : ndarray, shape (B..., N+1, 3) — midpoint-integrated means
    covs : ndarray, shape (B..., N+1, 3, 3)
    """
    sr, sl, b, kr, kl, S0, p0 = _check_inputs(ds_r, ds_l, track, k_r, k_l, cov0, start)
    geo = np.broadcast_shapes(sr.shape[:-1], b.shape)
    sr = np.broadcast_to(sr, geo + sr.shape[-1:])
    sl = np.broadcast_to(sl, geo + sl.shape[-1:])
    b = np.broadcast_to(b, geo)
    poses = integrate((sr + sl) / 2.0, (sr - sl) / b[..., None], p0, method="midpoint")
    G_r, G_l = _unit_responses(poses, sr, sl, b)
    covs = kr[..., None, None, None] * G_r + kl[..., None, None, None] * G_l
    if np.any(S0):
        m = np.stack([-poses[..., 1], poses[..., 0], np.zeros_like(poses[..., 0])], axis=-1)
        c = m - m[..., :1, :]
        A = np.broadcast_to(np.eye(3), (*c.shape[:-1], 3, 3)).copy()
        A[..., :, 2] += c
        covs = covs + A @ S0[..., None, :, :] @ np.swapaxes(A, -1, -2)
    batch = covs.shape[:-3]
    return np.broadcast_to(poses, batch + poses.shape[-2:]).copy(), covs


def propagate(
    trajectory: Trajectory,
    k_r: ArrayLike,
    k_l: ArrayLike,
    *,
    track: ArrayLike | None = None,
    cov0: ArrayLike | None = None,
) -> CovarianceResult:
    """Propagate the pose covariance along a trajectory (Němec 2012 §2.1), for many parameter sets.

    Parameters
    ----------
    trajectory : Trajectory — wheel travels, step and start pose
    k_r, k_l : array_like, shape (B...) — error constants [m], ≥ 0 (e.g. 5e-4)
    track : array_like, shape (B...), optional — wheel separation [m] per set;
        default the trajectory's. The wheel travels are kept, so a different
        track turns the same wheel travels into a different path.
    cov0 : array_like, shape (B..., 3, 3), optional — initial covariance (default 0)

    Returns
    -------
    CovarianceResult with poses (B..., N+1, 3) and covs (B..., N+1, 3, 3)
    """
    b = trajectory.track if track is None else track
    poses, covs = propagate_travels(
        trajectory.ds_r, trajectory.ds_l, b, k_r, k_l, cov0=cov0, start=trajectory.start
    )
    return CovarianceResult(poses=poses, covs=covs, times=trajectory.times)


# --- ellipses ---------------------------------------------------------------------------


class Ellipse(NamedTuple):
    """A Pr-ellipse: orientation ``alpha`` [rad] of the major axis and semi-axes [m]."""

    alpha: NDArray[np.float64]
    a_major: NDArray[np.float64]
    a_minor: NDArray[np.float64]


def _check_cov2(cov_xy: ArrayLike) -> NDArray[np.float64]:
    S = check_finite("cov_xy", cov_xy)
    if S.shape[-2:] != (2, 2):
        raise ValueError(f"cov_xy must have shape (..., 2, 2), got shape {S.shape}")
    return S


def ellipse(cov_xy: ArrayLike, pr: ArrayLike = PR_3SIGMA) -> Ellipse:
    """Closed-form Pr-ellipse of a 2-D covariance (Němec 2012 §2.1.1).

    ``k = −2 ln(1 − Pr)``, ``τ = √((σx² − σy²)² + 4σxy²)``,
    ``α = ½ atan2(2σxy, σx² − σy²)``, ``a = √(k/2 (σx²+σy² ± τ))``.

    Parameters
    ----------
    cov_xy : array_like, shape (..., 2, 2) — the (x, y) block [m²]
    pr : float or array_like, in (0, 1) — probability inside the ellipse

    Returns
    -------
    Ellipse(alpha, a_major, a_minor), each shape (...)
    """
    S = _check_cov2(cov_xy)
    k = pr_to_k(pr)
    sxx, syy, sxy = S[..., 0, 0], S[..., 1, 1], S[..., 0, 1]
    tau = np.sqrt((sxx - syy) ** 2 + 4.0 * sxy**2)
    alpha = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    a_major = np.sqrt(np.maximum(k / 2.0 * (sxx + syy + tau), 0.0))
    a_minor = np.sqrt(np.maximum(k / 2.0 * (sxx + syy - tau), 0.0))  # rounding can dip below 0
    return Ellipse(alpha, a_major, a_minor)


def _sqrt_factor(S: NDArray) -> NDArray:
    """A with A Aᵀ = S for 2×2 PSD S: Cholesky, or the symmetric square root where singular."""
    a, b, c = S[..., 0, 0], S[..., 0, 1], S[..., 1, 1]
    scale = np.maximum(np.abs(S).max(axis=(-1, -2)), np.finfo(float).tiny)
    det = a * c - b * b
    regular = (a > 1e-12 * scale) & (det > 1e-12 * scale**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        l11 = np.sqrt(np.where(regular, a, 1.0))
        l21 = np.where(regular, b / l11, 0.0)
        l22 = np.sqrt(np.where(regular, det / np.where(regular, a, 1.0), 1.0))
    chol = np.zeros(S.shape)
    chol[..., 0, 0], chol[..., 1, 0], chol[..., 1, 1] = l11, l21, l22
    w, V = np.linalg.eigh(S)
    sym = (V * np.sqrt(np.maximum(w, 0.0))[..., None, :]) @ np.swapaxes(V, -1, -2)
    return np.where(regular[..., None, None], chol, sym)


def ellipse_polyline(
    cov_xy: ArrayLike,
    pr: ArrayLike = PR_3SIGMA,
    center: ArrayLike = (0.0, 0.0),
    n: int = 100,
) -> NDArray[np.float64]:
    """The Pr-ellipse as a closed polyline: the circle of radius √k transformed by A, AAᵀ = Σ.

    Uses the Cholesky factor; where Σ is singular (e.g. at the start of a
    path) the symmetric square root from an eigen-decomposition instead, so a
    degenerate ellipse becomes a segment or a point.

    Parameters
    ----------
    cov_xy : array_like, shape (..., 2, 2) [m²]
    pr : float in (0, 1)
    center : array_like, shape (..., 2) [m]
    n : int ≥ 3 — number of vertices (the first is repeated at the end)

    Returns
    -------
    ndarray, shape (..., n+1, 2)
    """
    S = _check_cov2(cov_xy)
    n = check_positive_int("n", n)
    if n < 3:
        raise ValueError(f"n must be >= 3 (allowed: 3, 4, ...), got {n}")
    c = check_last_axis("center", center, 2)
    r = np.sqrt(pr_to_k(pr))
    t = np.linspace(0.0, 2.0 * np.pi, n + 1)
    circle = np.stack([np.cos(t), np.sin(t)], axis=0)  # (2, n+1)
    A = _sqrt_factor(S)
    pts = r[..., None, None] * np.swapaxes(A @ circle, -1, -2)  # (..., n+1, 2)
    return pts + c[..., None, :]
