"""Method A — first-order covariance propagation (Siegwart & Nourbakhsh 2004; Němec 2012 §2.1).

Midpoint step with ``Δs = (Δs_r+Δs_l)/2``, ``Δθ = (Δs_r−Δs_l)/b`` and
``φ = θ + Δθ/2``::

    Σ_p' = J_p Σ_p J_pᵀ + J_Δ Σ_Δ J_Δᵀ,        Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|)

The differential drive is one drive among the others: the functions here are
the front doors of Method A for every drive (:mod:`.drive_covariance`), with the
differential drive's twist ``ξ = (Δs, 0, Δθ)`` and Jacobian ``∂ξ/∂(Δs_r, Δs_l)``
(:func:`~pose_uncertainty.core.drives.differential_twist`, array-valued track
allowed) and ``Σ_Δ`` as the measurement covariance. Two routes compute the same
covariances:

* :func:`propagate_recursive` — the recursion above, one step at a time
  (batched over parameter sets; :func:`.drive_covariance.step`); the reference.
* :func:`propagate` — closed form, no loop over steps
  (:func:`.drive_covariance.propagate_steps`: the step Jacobians ``J_p = I + c e₃ᵀ``
  telescope into prefix sums). The covariance is linear in ``(k_r, k_l)``, so for
  many parameter sets it is computed once per geometry for unit constants and
  combined for every set.

Error ellipses (Němec 2012 §2.1.1) come from :func:`ellipse` (closed form) and
:func:`ellipse_polyline` (transformed circle).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import differential_twist, differential_twist_jacobian
from ..core.kinematics import step_twist
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
from .drive_covariance import (
    CovarianceResult,
    propagate_steps,
    start_covariance,
    step_covariance,
    twist_step_jacobians,
)

__all__ = [
    "ELLIPSE_ROUNDING",
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
    J_p, J_xi = twist_step_jacobians(th, differential_twist(sr, sl, b), "midpoint")
    return J_p, J_xi @ differential_twist_jacobian(b)


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
    new_pose = step_twist(p, differential_twist(sr, sl, b), "midpoint")
    # Σ' = J_p Σ J_pᵀ + J_Δ Σ_Δ J_Δᵀ
    return new_pose, step_covariance(J_p, S, J_d, _sigma_delta(sr, sl, kr, kl))


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
    b = np.broadcast_to(b, geo)[..., None]
    twists, jac = differential_twist(sr, sl, b), differential_twist_jacobian(b, sr.shape)
    if kr.ndim == 0 and kl.ndim == 0:  # one parameter set: Σ_Δ itself
        return propagate_steps(twists, jac, _sigma_delta(sr, sl, kr, kl), cov0=S0, start=p0, method="midpoint")
    # unit constants (k_r, k_l) = (1, 0) and (0, 1), combined for every parameter set
    one = np.array([1.0, 0.0]).reshape((2,) + (1,) * sr.ndim)
    poses, G = propagate_steps(twists, jac, _sigma_delta(sr, sl, one, 1.0 - one), start=p0, method="midpoint")
    covs = kr[..., None, None, None] * G[0] + kl[..., None, None, None] * G[1]
    if np.any(S0):
        covs = covs + start_covariance(poses[0], S0)
    batch = covs.shape[:-3]
    return np.broadcast_to(poses[0], batch + poses.shape[-2:]).copy(), covs


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


#: Relative size [1] below which an ellipse's axis difference (a circle) or its minor axis (a
#: segment) is rounding: 1e-9 of the trace, far above what 10⁴ steps of float64 recursion
#: accumulate (~1e-11, the reproducibility contract) and far below any width a run resolves.
ELLIPSE_ROUNDING = 1e-9


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
    ``α = ½ atan2(2σxy, σx² − σy²)``, ``a = √(k/2 (σx²+σy² ± τ))``. A circle within
    :data:`ELLIPSE_ROUNDING` of the trace gets ``α = 0``, a segment a zero minor axis.

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
    # Within rounding of the trace, a circle has no orientation and a segment no width: their
    # α and minor axis would be rounding noise (a rotation in place gives an exact circle), so
    # they are set to 0, and the result moves by rounding only, as its inputs do.
    rounding = ELLIPSE_ROUNDING * np.abs(sxx + syy)
    circular = tau <= rounding
    tau = np.where(circular, 0.0, tau)
    alpha = np.where(circular, 0.0, 0.5 * np.arctan2(2.0 * sxy, sxx - syy))
    minor_sq = sxx + syy - tau
    a_major = np.sqrt(np.maximum(k / 2.0 * (sxx + syy + tau), 0.0))
    a_minor = np.sqrt(np.where(minor_sq <= rounding, 0.0, k / 2.0 * minor_sq))
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
    w = np.where(w <= ELLIPSE_ROUNDING * w[..., -1:], 0.0, w)  # a width within rounding is none
    sym = (V * np.sqrt(w)[..., None, :]) @ np.swapaxes(V, -1, -2)
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
