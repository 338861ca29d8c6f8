"""A Gaussian in the exponential coordinates of SE(2): the banana distribution.

Long, Wolfe, Mashner & Chirikjian, "The Banana Distribution is Gaussian: A
Localization Study with Exponential Coordinates", RSS 2012.

A pose ``g = (x, y, θ)`` is the matrix ``[[R(θ), t], [0, 1]]``; a twist
``ξ = (v₁, v₂, w)`` (body-frame velocity times time) maps to a pose by the
exponential of SE(2) and back by its logarithm (the group operations are in
:mod:`pose_uncertainty.core.se2`). The exponential-coordinates
Gaussian with mean pose ``μ`` and covariance ``Σ`` is the law of

    g = μ · exp(ε),   ε ~ N(0, Σ)

(a "concentrated Gaussian" in the body frame of ``μ``). It is drawn in the
plane as a banana, not an ellipse.

Propagation along a trajectory
------------------------------
One step of the robot with wheel travels ``(Δs_r, Δs_l)`` is exactly the twist
``δ = (Δs, 0, Δθ)`` (the exact arc of the differential drive is ``exp(δ)``). With noisy
travels the step is ``exp(δ + n)``, ``n = M (e_r, e_l)``,
``M = [[½, ½], [0, 0], [1/b, −1/b]]``, ``Cov(e) = Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|)``.
Writing ``g_i = μ_i exp(ε_i)`` with the noiseless ``μ_{i+1} = μ_i exp(δ_i)``:

    exp(ε_{i+1}) = exp(−δ_i) exp(ε_i) exp(δ_i + n_i)
                 ≈ exp(Ad_{exp(−δ_i)} ε_i + J_r(δ_i) n_i)           (first order)

    Σ_{i+1} = Ad_{exp(−δ_i)} Σ_i Ad_{exp(−δ_i)}ᵀ + J_r(δ_i) M Σ_Δ Mᵀ J_r(δ_i)ᵀ

where ``Ad_g = [[R, (t_y, −t_x)ᵀ], [0, 1]]`` (``g exp(ξ) g⁻¹ = exp(Ad_g ξ)``) and
``J_r`` is the right Jacobian of SE(2) (``exp(ξ + dξ) ≈ exp(ξ) exp(J_r(ξ) dξ)``).
Because ``Ad`` is a homomorphism, the product of the step adjoints from step
``i+1`` to ``n`` is ``Ad_{μ_n}⁻¹ Ad_{μ_{i+1}}``, so

    Σ_n = Ad_{μ_n}⁻¹ [ Ad_{μ_0} Σ_0 Ad_{μ_0}ᵀ + Σ_{i<n} Ad_{μ_{i+1}} Q_i Ad_{μ_{i+1}}ᵀ ] Ad_{μ_n}⁻ᵀ

with ``Q_i = J_r M Σ_Δ Mᵀ J_rᵀ``: a prefix sum, no loop over steps
(:func:`propagate_twists`, for the twists and twist noise of any drive);
:func:`propagate_recursive` is the step recursion, kept to test it. The
differential drive is one drive among the others: :func:`propagate` is its front
door (``M`` = :func:`~pose_uncertainty.core.drives.differential_twist_jacobian`).

Headings
--------
The heading of ``μ`` along a path is unwrapped (several laps of a circle reach
``θ = 6π``); the heading part of ``ε`` is taken *unwrapped* too
(``ε_θ = θ − θ_μ`` without wrapping, for clouds with unwrapped headings as the
samplers return them), which makes ``(x, y, θ_unwrapped) ↔ ε`` one-to-one
except where ``ε_θ`` is a non-zero multiple of 2π.

Densities
---------
``g = μ exp(ε)`` has density ``N(ε; 0, Σ) / |det J(ε)|`` with respect to
``dx dy dθ``, ``det J(ε) = (sin(ε_θ/2)/(ε_θ/2))²`` (:func:`pdf_pose`). For fixed
``ε_θ = w`` the map ``ε_v ↦ (x, y)`` is affine, so ``(x, y) | w`` is Gaussian
and the planar marginal is a one-dimensional integral over ``w``, computed by
Gauss–Hermite quadrature (:func:`pdf_xy`) — no grid over θ is needed.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import differential_twist, differential_twist_jacobian
from ..core.kinematics import integrate_twist, sinc
from ..core.se2 import adjoint, adjoint_inverse, compose, cosc, exp, inverse, log, right_jacobian
from ..core.trajectories import Trajectory
from ..core.validation import (
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_pose_cov,
    check_positive_int,
    check_probability,
)

__all__ = [
    "ExpGaussian",
    "SingularConditionalError",
    "at_least",
    "coordinates",
    "density_quantiles",
    "hdr_threshold",
    "logpdf_pose",
    "marginal_xy_grid",
    "pdf_pose",
    "pdf_xy",
    "pr_region_xy",
    "propagate",
    "propagate_recursive",
    "propagate_twists",
    "region_xy_at",
    "sample",
    "to_cartesian_cov",
]


# --- propagation ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ExpGaussian:
    """Exponential-coordinates Gaussians along a trajectory: ``g_n = μ_n exp(ε_n)``, ``ε_n ~ N(0, Σ_n)``.

    Attributes
    ----------
    poses : ndarray, shape (B..., N+1, 3) — noiseless poses μ_n (exact arcs) [m, m, rad]
    covs : ndarray, shape (B..., N+1, 3, 3) — Σ_n of the body-frame exponential
        coordinates [m², m·rad, rad²]
    times : ndarray, shape (N+1,) [s]
    """

    poses: NDArray[np.float64]
    covs: NDArray[np.float64]
    times: NDArray[np.float64]


def _step_noise(traj: Trajectory) -> tuple[NDArray, NDArray]:
    """Twists δ_i (N, 3) of the wheel travels and the wheels' unit twist covariances (2, N, 3, 3):
    ``|Δs_r| M e_r e_rᵀ Mᵀ`` and ``|Δs_l| M e_l e_lᵀ Mᵀ``."""
    delta = differential_twist(traj.ds_r, traj.ds_l, traj.track)
    M = differential_twist_jacobian(traj.track)  # (3, 2)
    unit = np.stack([np.abs(traj.ds_r), np.abs(traj.ds_l)])[..., None, None]
    cols = np.stack([np.outer(M[:, 0], M[:, 0]), np.outer(M[:, 1], M[:, 1])])[:, None]
    return delta, unit * cols


def _check_k(k_r: ArrayLike, k_l: ArrayLike) -> tuple[NDArray, NDArray]:
    """The wheels' travel-noise constants ``k_r, k_l`` [m] (scalars or per step), checked ≥ 0."""
    kr = check_nonnegative("k_r", k_r)
    kl = check_nonnegative("k_l", k_l)
    return kr, kl


def propagate(
    trajectory: Trajectory,
    k_r: ArrayLike,
    k_l: ArrayLike,
    cov0: ArrayLike | None = None,
) -> ExpGaussian:
    """Propagate the exponential-coordinates Gaussian along a trajectory (closed form).

    ``Σ_n = Ad_{μ_n}⁻¹ [Ad_{μ_0} Σ_0 Ad_{μ_0}ᵀ + Σ_{i<n} Ad_{μ_{i+1}} Q_i Ad_{μ_{i+1}}ᵀ] Ad_{μ_n}⁻ᵀ``
    (module docstring). The covariance is linear in ``(k_r, k_l)``.

    Parameters
    ----------
    trajectory : Trajectory
    k_r, k_l : array_like, shape (B...) — error constants [m] (wheel-travel
        variance per metre), ≥ 0
    cov0 : array_like, shape (B..., 3, 3), optional — Σ_0 in the body-frame
        exponential coordinates of the start pose (default 0)

    Returns
    -------
    ExpGaussian with poses (N+1, 3) broadcast to (B..., N+1, 3) and covs (B..., N+1, 3, 3)
    """
    kr, kl = _check_k(k_r, k_l)
    S0 = check_pose_cov("cov0", cov0)
    delta, unit = _step_noise(trajectory)
    start, times = trajectory.start, trajectory.times
    if kr.ndim == 0 and kl.ndim == 0:  # one parameter set: its twist covariance itself
        return propagate_twists(delta, kr * unit[0] + kl * unit[1], start=start, cov0=S0, times=times)
    G = propagate_twists(delta, unit, start=start, times=times).covs  # (k_r, k_l) = (1, 0), (0, 1)
    covs = kr[..., None, None, None] * G[0] + kl[..., None, None, None] * G[1]
    if np.any(S0):
        covs = covs + propagate_twists(delta, np.zeros_like(unit[0]), start=start, cov0=S0).covs
    mu = trajectory.poses
    poses = np.broadcast_to(mu, covs.shape[:-3] + mu.shape).copy()
    return ExpGaussian(poses=poses, covs=covs, times=times)


def propagate_twists(
    twists: ArrayLike,
    twist_covs: ArrayLike,
    *,
    start: ArrayLike = (0.0, 0.0, 0.0),
    cov0: ArrayLike | None = None,
    times: ArrayLike | None = None,
) -> ExpGaussian:
    """The exponential-coordinates Gaussian of any drive: steps ``exp(δ_i + n_i)``, ``n_i ~ N(0, Q_ξ,i)``.

    The body-twist-noise form of :func:`propagate`: step ``i`` is the twist
    ``δ_i = (v₁, v₂, Δθ)`` of the drive's mean measurements and ``n_i`` its twist
    noise (for a drive, ``Q_ξ = (∂ξ/∂u) Σ_u (∂ξ/∂u)ᵀ`` plus any noise acting on
    the twist directly). As in the module docstring, with
    ``Q_i = J_r(δ_i) Q_ξ,i J_r(δ_i)ᵀ``::

        Σ_n = Ad_{μ_n}⁻¹ [Ad_{μ_0} Σ_0 Ad_{μ_0}ᵀ + Σ_{i<n} Ad_{μ_{i+1}} Q_i Ad_{μ_{i+1}}ᵀ] Ad_{μ_n}⁻ᵀ

    For the differential drive ``Q_ξ = M Σ_Δ Mᵀ`` gives :func:`propagate` (its front door).

    Parameters
    ----------
    twists : array_like, shape (N, 3) — mean per-step body twists [m, m, rad]
    twist_covs : array_like, shape (B..., N, 3, 3) — covariance of the twist noise per step
    start : array_like, shape (3,) — start pose μ_0
    cov0 : array_like, shape (B..., 3, 3), optional — Σ_0 (default 0)
    times : array_like, shape (N+1,), optional — [s] (default the step index)

    Returns
    -------
    ExpGaussian with poses (B..., N+1, 3) (exact steps) and covs (B..., N+1, 3, 3)
    """
    xi = check_last_axis("twists", twists, 3)
    Qxi = check_finite("twist_covs", twist_covs)
    if xi.ndim != 2 or Qxi.shape[-3:] != (xi.shape[0], 3, 3):
        raise ValueError(
            f"twists must have shape (N, 3) and twist_covs (..., N, 3, 3), got {xi.shape} and {Qxi.shape}"
        )
    S0 = check_pose_cov("cov0", cov0)
    mu = integrate_twist(xi, start, "exact")
    Jr = right_jacobian(xi)
    Ad_next = adjoint(mu[1:])
    U = Ad_next @ Jr  # (N, 3, 3): Ad_{μ_{i+1}} J_r(δ_i)
    terms = U @ Qxi @ np.swapaxes(U, -1, -2)  # (B..., N, 3, 3)
    P = np.zeros((*terms.shape[:-3], xi.shape[0] + 1, 3, 3))
    np.cumsum(terms, axis=-3, out=P[..., 1:, :, :])
    Ad_inv = adjoint_inverse(mu)
    covs = Ad_inv @ P @ np.swapaxes(Ad_inv, -1, -2)
    if np.any(S0):
        T = Ad_inv @ adjoint(mu[0])
        covs = covs + T @ S0[..., None, :, :] @ np.swapaxes(T, -1, -2)
    covs = 0.5 * (covs + np.swapaxes(covs, -1, -2))
    t = np.arange(xi.shape[0] + 1, dtype=np.float64) if times is None else check_finite("times", times)
    poses = np.broadcast_to(mu, covs.shape[:-3] + mu.shape).copy()
    return ExpGaussian(poses=poses, covs=covs, times=t)


def propagate_recursive(
    trajectory: Trajectory, k_r: float, k_l: float, cov0: ArrayLike | None = None
) -> ExpGaussian:
    """Reference: the step recursion ``Σ' = Ad_{exp(−δ)} Σ Adᵀ + J_r M Σ_Δ Mᵀ J_rᵀ``.

    Loops over steps; used to test :func:`propagate`. Parameters as there
    (scalar constants).
    """
    kr, kl = (float(v) for v in _check_k(k_r, k_l))
    S = check_pose_cov("cov0", cov0).astype(float)
    delta, unit = _step_noise(trajectory)
    Jr = right_jacobian(delta)
    A = adjoint(exp(-delta))
    n = trajectory.n_steps
    covs = np.empty((n + 1, 3, 3))
    covs[0] = S
    for i in range(n):
        Q = Jr[i] @ (kr * unit[0, i] + kl * unit[1, i]) @ Jr[i].T
        S = A[i] @ S @ A[i].T + Q
        covs[i + 1] = S
    return ExpGaussian(poses=trajectory.poses, covs=covs, times=trajectory.times)


def to_cartesian_cov(pose: ArrayLike, cov: ArrayLike) -> NDArray[np.float64]:
    """First-order Cartesian covariance of ``μ exp(ε)``: ``T Σ Tᵀ``, ``T = blockdiag(R(θ_μ), 1)``.

    To first order ``μ exp(ε) ≈ μ + (R ε_v, ε_θ)``; this is the covariance
    Method A should agree with (up to its midpoint integration).

    Parameters
    ----------
    pose : array_like, shape (..., 3); cov : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    p = check_last_axis("pose", pose, 3)
    S = check_finite("cov", cov)
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    one, zero = np.ones_like(c), np.zeros_like(c)
    T = np.stack(
        [
            np.stack([c, -s, zero], axis=-1),
            np.stack([s, c, zero], axis=-1),
            np.stack([zero, zero, one], axis=-1),
        ],
        axis=-2,
    )
    return T @ S @ np.swapaxes(T, -1, -2)


# --- sampling and densities ----------------------------------------------------------------


def coordinates(samples: ArrayLike, mean_pose: ArrayLike) -> NDArray[np.float64]:
    """Exponential coordinates ``ε = log(μ⁻¹ g)`` of poses ``g`` about ``μ`` (heading unwrapped).

    Parameters
    ----------
    samples : array_like, shape (..., 3) — poses with unwrapped headings
    mean_pose : array_like, shape (3,)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    g = check_last_axis("samples", samples, 3)
    mu = check_last_axis("mean_pose", mean_pose, 3)
    rel = compose(inverse(mu), g)  # heading θ − θ_μ, unwrapped
    return log(rel)


def sample(
    mean_pose: ArrayLike, cov: ArrayLike, n: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """Draw ``n`` poses ``μ exp(ε)``, ``ε ~ N(0, Σ)``.

    Parameters
    ----------
    mean_pose : array_like, shape (3,); cov : array_like, shape (3, 3), PSD
    n : int ≥ 1; rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (n, 3) — headings unwrapped about θ_μ
    """
    n = check_positive_int("n", n)
    mu = check_last_axis("mean_pose", mean_pose, 3)
    S = _check_cov3(cov)
    eps = rng.multivariate_normal(np.zeros(3), S, size=n, method="eigh")
    return compose(mu, exp(eps))


def _check_cov3(cov: ArrayLike) -> NDArray:
    """A finite 3×3 covariance of exponential coordinates [m², m², rad²]; ``ValueError`` otherwise."""
    S = check_finite("cov", cov)
    if S.shape != (3, 3):
        raise ValueError(f"cov must have shape (3, 3), got shape {S.shape}")
    return S


def logpdf_pose(points: ArrayLike, mean_pose: ArrayLike, cov: ArrayLike) -> NDArray[np.float64]:
    """Log-density of the exponential-coordinates Gaussian w.r.t. ``dx dy dθ``.

    ``log p = log N(ε; 0, Σ) − 2 log|sin(ε_θ/2)/(ε_θ/2)|``, ``ε = log(μ⁻¹ g)``.

    Parameters
    ----------
    points : array_like, shape (..., 3) — poses, unwrapped headings
    mean_pose : array_like, shape (3,); cov : array_like, shape (3, 3), positive definite

    Returns
    -------
    ndarray, shape (...) [log(1/(m² rad))]
    """
    S = _check_cov3(cov)
    eps = coordinates(points, mean_pose)
    L = np.linalg.cholesky(S)
    z = np.linalg.solve(L, eps.reshape(-1, 3).T).T.reshape(eps.shape)
    logdet = 2.0 * np.log(np.diag(L)).sum()
    with np.errstate(divide="ignore"):
        log_jac = 2.0 * np.log(np.abs(sinc(0.5 * eps[..., 2])))
    return -0.5 * (z**2).sum(axis=-1) - 0.5 * logdet - 1.5 * np.log(2.0 * np.pi) - log_jac


def pdf_pose(points: ArrayLike, mean_pose: ArrayLike, cov: ArrayLike) -> NDArray[np.float64]:
    """Density w.r.t. ``dx dy dθ`` (``exp`` of :func:`logpdf_pose`); shape (...)."""
    return np.exp(logpdf_pose(points, mean_pose, cov))


class _Conditional(NamedTuple):
    """The planar marginal as a quadrature over the heading deviation ``w = ε_θ``.

    Node ``q`` carries the Gaussian ``(x, y) | w_q`` (mean, precision, log-normaliser)
    and its weight; ``pdf_xy(p) = Σ_q weights_q · exp(log_norm_q − ½ m2_q(p))`` with the
    Mahalanobis distance ``m2_q(p) = (p − μ_q)ᵀ P_q (p − μ_q)``. Built by :func:`_conditional`.
    """

    nodes: NDArray  # (q,) heading deviation w
    weights: NDArray  # (q,) quadrature weights, sum 1
    means: NDArray  # (q, 2) mean of (x, y) given w
    prec: NDArray  # (q, 2, 2) precision of (x, y) given w
    log_norm: NDArray  # (q,) −log(2π) − ½ log det C_xy(w)


#: the w integral runs over ±_W_RANGE standard deviations (the Gaussian tail beyond is < 1e-16)
_W_RANGE = 8.5
#: at most this many quadrature nodes (a banana thinner than that allows is under-resolved)
_MAX_NODES = 8192


def _conditional_means(mean_pose: NDArray, S: NDArray, w: NDArray) -> tuple[NDArray, NDArray]:
    """Means t_μ + R V(w) m(w) of (x, y) | ε_θ = w, and the maps A = R V(w); shapes (q, 2), (q, 2, 2)."""
    s_ww = S[2, 2]
    s_vw = S[:2, 2]
    m = (s_vw / s_ww)[None, :] * w[:, None] if s_ww > 0 else np.zeros((w.size, 2))
    s, c = sinc(w), cosc(w)
    V = np.stack([np.stack([s, -c], -1), np.stack([c, s], -1)], -2)  # (q, 2, 2)
    th = mean_pose[2]
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    A = R @ V  # (q, 2, 2)
    return mean_pose[:2] + np.einsum("qij,qj->qi", A, m), A


class SingularConditionalError(ValueError):
    """Σ whose (x, y) block given θ is singular (e.g. one step of a two-wheel drive: Σ of rank 2):
    the planar density is not computed by conditioning on θ, and its measures are undefined."""


def _conditional(mean_pose: NDArray, S: NDArray, n_quad: int) -> _Conditional:
    """:func:`_build_conditional`, kept for the next call with the same numbers (a run and the
    explorer ask for one banana's several times: its levels, coverage and contour)."""
    key = (np.asarray(mean_pose, dtype=np.float64).tobytes(), np.asarray(S, dtype=np.float64).tobytes(), int(n_quad))
    with _KEPT_LOCK:
        got = _KEPT_CONDITIONALS.get(key)
    if got is None:
        got = _build_conditional(mean_pose, S, n_quad)
        with _KEPT_LOCK:
            _KEPT_CONDITIONALS[key] = got
            while len(_KEPT_CONDITIONALS) > _KEPT:
                _KEPT_CONDITIONALS.popitem(last=False)
    return got


#: How many conditionals and range trees are kept (the last few bananas).
_KEPT = 8
_KEPT_LOCK = threading.Lock()
_KEPT_CONDITIONALS: OrderedDict[tuple[bytes, bytes, int], _Conditional] = OrderedDict()
#: range trees by (id of their conditional, truncation), with the conditional (so its id stays its own)
_KEPT_TREES: OrderedDict[tuple[int, float], tuple[_Conditional, _RangeTree]] = OrderedDict()


def _build_conditional(mean_pose: NDArray, S: NDArray, n_quad: int) -> _Conditional:
    """(x, y) | ε_θ = w: Gaussian with mean t_μ + R V(w) m(w), cov R V(w) C Vᵀ Rᵀ.

    Quadrature in w: the trapezoid rule on a uniform grid over ±8.5 σ_θ with
    Gaussian weights, which converges geometrically for this smooth integrand
    once the grid resolves it. At least ``n_quad`` nodes, and as many as it takes
    for the conditional means of neighbouring nodes to lie within half a
    conditional standard deviation of each other (a thin banana needs many),
    at most 8192.
    """
    s_ww = S[2, 2]
    s_vw = S[:2, 2]
    C = S[:2, :2] - (np.outer(s_vw, s_vw) / s_ww if s_ww > 0 else 0.0)
    sd = np.sqrt(max(s_ww, 0.0))
    n = max(int(n_quad), 3)
    if sd > 0:
        # length of the curve of conditional means, against the thinnest conditional spread
        probe, _ = _conditional_means(mean_pose, S, sd * np.linspace(-_W_RANGE, _W_RANGE, 2049))
        length = float(np.linalg.norm(np.diff(probe, axis=0), axis=1).sum())
        thin = math.sqrt(max(float(np.linalg.eigvalsh(C)[0]), 1e-300))
        n = min(max(n, math.ceil(2.0 * length / thin) + 1), _MAX_NODES)
    t = np.linspace(-_W_RANGE, _W_RANGE, n) if sd > 0 else np.zeros(1)
    h = np.exp(-0.5 * t**2)
    weights = h / h.sum()
    w = sd * t
    means, A = _conditional_means(mean_pose, S, w)
    Cxy = A @ C @ np.swapaxes(A, -1, -2)
    det = Cxy[:, 0, 0] * Cxy[:, 1, 1] - Cxy[:, 0, 1] ** 2
    if np.any(det <= 0):
        raise SingularConditionalError(
            "cov must be positive definite in (x, y) given θ (allowed: Σ with a non-singular "
            f"conditional (x, y) block), got conditional determinant {det.min()!r}"
        )
    prec = np.linalg.inv(Cxy)
    log_norm = -np.log(2.0 * np.pi) - 0.5 * np.log(det)
    return _Conditional(w, weights, means, prec, log_norm)


#: truncation of :func:`pdf_xy`: a node's term is dropped where it is below e^-T/n of the
#: largest node peak (n nodes), so the dropped terms add up to at most e^-T·max p
_TRUNC = 50.0
#: :func:`pdf_xy` sums densely up to this many nodes
_DENSE_NODES = 64
#: target number of (point, node-range) pairs (or terms) held at once by :func:`pdf_xy`: each
#: array of them is 8 MiB, a few live at once (a run's peak memory: experiments/cost.py)
_PAIRS_PER_CHUNK = 1 << 20
#: :func:`pdf_xy` sums blocks of this many consecutive nodes densely (a power of 2)
_BLOCK = 32


def _pdf_xy_dense(flat: NDArray, cond: _Conditional) -> NDArray:
    """The full quadrature sum at points (m, 2): a loop over nodes, vectorised over points."""
    out = np.zeros(flat.shape[0])
    for q in range(cond.nodes.size):
        d = flat - cond.means[q]
        P = cond.prec[q]
        m2 = P[0, 0] * d[:, 0] ** 2 + 2.0 * P[0, 1] * d[:, 0] * d[:, 1] + P[1, 1] * d[:, 1] ** 2
        out += cond.weights[q] * np.exp(cond.log_norm[q] - 0.5 * m2)
    return out


class _RangeTree(NamedTuple):
    """Bounds on the quadrature terms of nested ranges of consecutive nodes, coarse to fine.

    Level ``l`` splits the node sequence into ranges of ``2^(L−l)`` consecutive
    nodes, down to blocks of ``_BLOCK``. For a range ``G`` with centre ``c`` (the
    conditional mean of its middle node ``k``) and metric ``M = β P_k``,
    ``β = min_{q∈G} λ_min(P_k⁻¹ P_q)`` (so ``P_q ⪰ M`` on ``G``), every ``q ∈ G`` has

        √m2_q(p) = ‖p − μ_q‖_{P_q} ≥ ‖p − μ_q‖_M ≥ ‖p − c‖_M − ‖μ_q − c‖_M,

    so ``‖p − c‖²_M > (ρ + R)²`` with ``ρ = max_G ‖μ_q − c‖_M`` and ``R = max_G √r2_q``
    proves ``m2_q(p) > r2_q`` (the term is dropped) for the whole range.
    """

    cx: list[NDArray]  # per level (g,): centres
    cy: list[NDArray]
    m00: list[NDArray]  # per level (g,): metric M
    m01: list[NDArray]
    m11: list[NDArray]
    bound: list[NDArray]  # per level (g,): (ρ + R)², −1 for a range without a kept node
    r2: NDArray  # (n,) per-node threshold on m2 (−1: the node is dropped everywhere)
    frame: NDArray  # (blocks, 2, 2): principal axes U of the block's middle precision (columns)
    # (blocks, 6, _BLOCK): log of the terms = [1, d₀, d₁, d₀², d₀d₁, d₁²] @ coef, d = Uᵀ(p − c)
    coef: NDArray
    log_floor: float  # terms below e^log_floor are dropped (⇔ m2_q > r2_q)


def _gen_eig_min(A: NDArray, B: NDArray) -> NDArray:
    """Smallest λ with det(A − λB) = 0 for symmetric positive definite 2×2 A, B (broadcast)."""
    dA = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] ** 2
    dB = B[..., 0, 0] * B[..., 1, 1] - B[..., 0, 1] ** 2
    tr = (
        A[..., 0, 0] * B[..., 1, 1]
        + A[..., 1, 1] * B[..., 0, 0]
        - 2.0 * A[..., 0, 1] * B[..., 0, 1]
    )
    disc = np.sqrt(np.maximum(tr**2 - 4.0 * dA * dB, 0.0))
    return 2.0 * dA / (tr + disc)  # the small root, without cancellation


def _range_tree(cond: _Conditional, prune: float = _TRUNC) -> _RangeTree:
    """:func:`_build_range_tree`, kept for the next call on the same conditional and truncation."""
    key = (id(cond), float(prune))
    with _KEPT_LOCK:
        got = _KEPT_TREES.get(key)
    if got is not None and got[0] is cond:
        return got[1]
    tree = _build_range_tree(cond, prune)
    with _KEPT_LOCK:
        _KEPT_TREES[key] = (cond, tree)
        while len(_KEPT_TREES) > 2 * _KEPT:
            _KEPT_TREES.popitem(last=False)
    return tree


def _build_range_tree(cond: _Conditional, prune: float = _TRUNC) -> _RangeTree:
    """The :class:`_RangeTree` of the quadrature nodes of ``cond`` (see :func:`_pdf_xy_pruned`).

    Each node's term gets a truncation threshold ``r2_q`` on its Mahalanobis distance
    (the term is dropped below ``e^-T/n`` of the largest peak, ``T = _TRUNC``); the
    ranges of nodes, halved level by level from one range down to blocks of ``_BLOCK``,
    get the centre, metric and bound that prove a whole range dropped at a point; the
    blocks finally get the log of each term as a quadratic polynomial in the block's
    principal frame, for the dense sum.
    """
    n = cond.nodes.size
    with np.errstate(divide="ignore"):
        la = np.log(cond.weights) + cond.log_norm  # log of the peak of each node's term
    # drop the term of node q at p where w_q N_q(p) < e^-T · max_k(w_k N_k(μ_k)) / n,
    # i.e. where m2_q(p) > r2_q
    r2 = 2.0 * (prune + math.log(n) + la - la.max())
    r2 = np.where(np.isfinite(r2) & (r2 > 0.0), r2, -1.0)
    R = np.where(r2 >= 0.0, np.sqrt(np.maximum(r2, 0.0)), -1.0)
    top = max(int(n - 1).bit_length(), _BLOCK.bit_length() - 1)
    idx = np.arange(n)
    tree: dict[str, list[NDArray]] = {k: [] for k in ("cx", "cy", "m00", "m01", "m11", "bound")}
    for lev in range(top, _BLOCK.bit_length() - 2, -1):  # range sizes 2^top … _BLOCK
        size = 1 << lev
        g = -(-n // size)
        grp = idx // size
        mid = np.minimum(np.arange(g) * size + size // 2, n - 1)
        Pk = cond.prec[mid]  # (g, 2, 2)
        beta = np.full(g, np.inf)
        np.minimum.at(beta, grp, _gen_eig_min(cond.prec, Pk[grp]))
        M = (beta * (1.0 - 1e-9))[:, None, None] * Pk  # margin for rounding: stays a lower bound
        c = cond.means[mid]
        dc = cond.means - c[grp]
        Mg = M[grp]
        rho2 = (
            Mg[:, 0, 0] * dc[:, 0] ** 2
            + 2.0 * Mg[:, 0, 1] * dc[:, 0] * dc[:, 1]
            + Mg[:, 1, 1] * dc[:, 1] ** 2
        )
        rho = np.zeros(g)
        np.maximum.at(rho, grp, np.sqrt(np.maximum(rho2, 0.0)))
        Rg = np.full(g, -1.0)
        np.maximum.at(Rg, grp, R)
        tree["cx"].append(c[:, 0].copy())
        tree["cy"].append(c[:, 1].copy())
        tree["m00"].append(M[:, 0, 0].copy())
        tree["m01"].append(M[:, 0, 1].copy())
        tree["m11"].append(M[:, 1, 1].copy())
        tree["bound"].append(np.where(Rg >= 0.0, ((rho + Rg) * (1.0 + 1e-9)) ** 2, -1.0))
    # the last level's ranges are the blocks: the log of each term as a quadratic polynomial in
    # the block's principal frame, where the expansion loses little to cancellation
    nb = tree["cx"][-1].size
    c = np.stack([tree["cx"][-1], tree["cy"][-1]], axis=-1)
    mid = np.minimum(np.arange(nb) * _BLOCK + _BLOCK // 2, n - 1)
    _, U = np.linalg.eigh(cond.prec[mid])  # (nb, 2, 2)
    grp = idx // _BLOCK
    Ug = U[grp]
    e = np.einsum("nji,nj->ni", Ug, cond.means - c[grp])  # Uᵀ(μ_q − c)
    Pr = np.swapaxes(Ug, -1, -2) @ cond.prec @ Ug  # UᵀP_qU
    Pe = np.einsum("nij,nj->ni", Pr, e)
    k = np.stack(
        [
            la - 0.5 * np.einsum("ni,ni->n", e, Pe),
            Pe[:, 0],
            Pe[:, 1],
            -0.5 * Pr[:, 0, 0],
            -Pr[:, 0, 1],
            -0.5 * Pr[:, 1, 1],
        ],
        axis=-1,
    )  # (n, 6)
    coef = np.zeros((nb * _BLOCK, 6))
    coef[:, 0] = -1e300  # padding nodes: a term of 0
    coef[:n] = np.where(np.isfinite(k), k, coef[:n])
    coef = np.ascontiguousarray(coef.reshape(nb, _BLOCK, 6).transpose(0, 2, 1))
    log_floor = float(la.max() - _TRUNC - math.log(n))
    return _RangeTree(r2=r2, frame=U, coef=coef, log_floor=log_floor, **tree)


def _block_sum(
    tree: _RangeTree, b: int, x: NDArray, y: NDArray, buf: NDArray, single: float | None = None
) -> NDArray:
    """The sum of the terms of block ``b`` above ``e^log_floor`` at the points ``(x, y)`` (m,).

    The log of each term, ``E = k₀ + d₀k₁ + d₁k₂ + d₀²k₃ + d₀d₁k₄ + d₁²k₅`` with ``d = Uᵀ(p − c)``,
    is formed term by term, elementwise (a matrix product's rounding would depend on the BLAS
    kernel, its threads and the rows), node-major in ``buf`` (2, _BLOCK, m) so that each
    operation runs over the points; the _BLOCK terms of a point are then added in numpy's
    pairwise order of a contiguous sum (eight running sums, then a tree), the order of
    ``terms.sum(axis=-1)`` on point-major terms.

    With ``single`` (a log level, e.g. the largest node peak's) the terms are
    ``exp(E − single)`` in single precision (numpy's vectorised float32 ``exp``), added in
    single precision, times ``e^single``: within a relative ``2·10⁻⁵`` of the double-precision
    sum (``E − single`` ≥ −log-floor range ≈ −60 rounds by ≤ 60·2⁻²⁴ = 4·10⁻⁶, the float32
    ``exp`` is within a few ulp, 32 float32 additions within 32·2⁻²⁴), what a bracket needs.
    """
    U = tree.frame[b]
    dx = x - tree.cx[-1][b]
    dy = y - tree.cy[-1][b]
    d0 = U[0, 0] * dx + U[1, 0] * dy
    d1 = U[0, 1] * dx + U[1, 1] * dy
    k = tree.coef[b][:, :, None]  # (6, _BLOCK, 1)
    E, T = buf[0], buf[1]
    np.multiply(d0, k[1], out=E)
    E += k[0]
    for j, f in ((2, d1), (3, d0 * d0), (4, d0 * d1), (5, d1 * d1)):
        np.multiply(f, k[j], out=T)
        E += T
    kept = E >= tree.log_floor
    if single is not None:
        E -= single
        with np.errstate(over="ignore"):  # a term far below the floor may cast to -inf: it is 0 anyway
            E = E.astype(np.float32)
    np.exp(E, out=E)
    E *= kept  # a term below e^log_floor is 0 (exp(E)·1 is exp(E) bit for bit)
    r = E[0:8] + E[8:16]
    for i in range(16, _BLOCK, 8):
        r += E[i : i + 8]
    out = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    return out if single is None else out.astype(np.float64) * math.exp(single)


def _pdf_xy_pruned(flat: NDArray, cond: _Conditional, prune: float = _TRUNC, single: bool = False) -> NDArray:
    """The quadrature sum over the terms with ``m2_q(p) ≤ r2_q`` (see :func:`pdf_xy`).

    Per chunk of points, (point, node range) pairs are refined level by level
    through :func:`_range_tree`, a pair kept unless its bound proves every term
    of the range dropped. Each surviving (point, block of ``_BLOCK`` nodes) pair
    is then summed densely over the block: the log of each term,
    ``log w_q + log_norm_q − ½ m2_q``, is a quadratic polynomial in the point's
    offset ``d = Uᵀ(p − c)`` from the block centre in the principal frame ``U``
    of the block (where the expansion loses only ~1e-13 relative to cancellation),
    evaluated for all pairs of a block elementwise (no BLAS: bit-identical on any
    thread count); terms below
    ``e^log_floor`` (⇔ ``m2_q > r2_q``) are set to 0. The block sums are added per
    point in ascending block order with ``np.bincount``. Every value depends on its
    point only (the loop runs over chunks of points and over blocks of nodes), so
    the result is deterministic and does not depend on the chunking.
    """
    tree = _range_tree(cond, prune)
    shift = tree.log_floor + _TRUNC + math.log(cond.nodes.size) if single else None  # the largest node peak
    m = flat.shape[0]
    x_all = np.ascontiguousarray(flat[:, 0])
    y_all = np.ascontiguousarray(flat[:, 1])
    counts = [c.size for c in tree.cx[1:]]
    n_blocks = tree.cx[-1].size
    out = np.empty(m)
    start = 0
    # pairs per point (an upper bound at first, then as seen in the last chunk): sizes the
    # next chunk only, so that the arrays stay in cache; the result does not depend on it
    per_point = float(n_blocks * _BLOCK)
    while start < m:
        size = int(min(m - start, max(64, _PAIRS_PER_CHUNK / per_point)))
        x, y = x_all[start : start + size], y_all[start : start + size]
        pt = np.arange(size)
        rg = np.zeros(size, dtype=np.intp)
        peak = size
        for lev in range(len(tree.cx)):
            dx = x[pt] - tree.cx[lev][rg]
            dy = y[pt] - tree.cy[lev][rg]
            q = (
                tree.m00[lev][rg] * dx**2
                + 2.0 * tree.m01[lev][rg] * dx * dy
                + tree.m11[lev][rg] * dy**2
            )
            keep = q <= tree.bound[lev][rg]
            pt, rg = pt[keep], rg[keep]
            if lev + 1 < len(tree.cx):  # split each kept range into its children, in order
                pt = np.repeat(pt, 2)
                rg = (2 * rg[:, None] + np.array([0, 1])).ravel()
                valid = rg < counts[lev]  # the last range may have one child only
                if not valid.all():
                    pt, rg = pt[valid], rg[valid]
                peak = max(peak, pt.size)
        # dense sums over the surviving blocks, grouped by block (pairs stay in (point, block) order)
        order = np.argsort(rg, kind="stable")
        edges = np.searchsorted(rg[order], np.arange(n_blocks + 1))
        block_sum = np.zeros(pt.size)
        most = int(np.diff(edges).max(initial=0))
        buf = np.empty((2, _BLOCK, most))
        for b in np.flatnonzero(np.diff(edges)):
            sel = order[edges[b] : edges[b + 1]]
            block_sum[sel] = _block_sum(tree, int(b), x[pt[sel]], y[pt[sel]], buf[:, :, : sel.size], shift)
        out[start : start + size] = np.bincount(pt, weights=block_sum, minlength=size)
        # the dense stage holds _BLOCK terms a pair
        per_point = 1.25 * max(peak, _BLOCK * pt.size) / size
        start += size
    return out


def pdf_xy(
    xy: ArrayLike, mean_pose: ArrayLike, cov: ArrayLike, n_quad: int = 64
) -> NDArray[np.float64]:
    """Planar (x, y) marginal density of the exponential-coordinates Gaussian.

    ``p(x, y) = ∫ N(w; 0, Σ_θθ) N((x, y); t_μ + R V(w) m(w), R V(w) C V(w)ᵀ Rᵀ) dw``
    with ``m(w) = Σ_vθ w / Σ_θθ``, ``C = Σ_vv − Σ_vθ Σ_θvᵀ/Σ_θθ``; Gauss–Hermite
    quadrature in ``w`` with ``n_quad`` nodes (the integrand is smooth in ``w``).

    Truncation: the quadrature sum ``Σ_q w_q N_q(p)`` has up to 8192 terms, of
    which a point of a thin banana feels only a few. With more than 64 nodes
    the term of node ``q`` is left out at ``p`` where
    ``w_q N_q(p) < e^{−T} max_k(w_k N_k(μ_k)) / n`` (``T = 50``, ``n`` nodes, ``μ_k``
    the conditional means), i.e. where its squared Mahalanobis distance exceeds
    ``2(T + log n + log(w_q N_q(μ_q)) − log max_k w_k N_k(μ_k))``. Since
    ``max_k w_k N_k(μ_k) ≤ max p``, the dropped terms add up at any point to at
    most ``e^{−50} max p ≈ 2·10⁻²² max p``: a relative error below ``2·10⁻¹²``
    wherever ``p ≥ 10⁻¹⁰ max p`` (rounding adds ~10⁻¹³). The kept (point, node)
    pairs are found by bounding whole ranges of consecutive nodes
    (:func:`_range_tree`, :func:`_pdf_xy_pruned`), without a loop over points or
    nodes; the result is deterministic. With at most 64 nodes the full sum is taken.

    Parameters
    ----------
    xy : array_like, shape (..., 2) [m]
    mean_pose : array_like, shape (3,); cov : array_like, shape (3, 3)
    n_quad : int — quadrature nodes

    Returns
    -------
    ndarray, shape (...) [1/m²]
    """
    p = check_last_axis("xy", xy, 2)
    mu = check_last_axis("mean_pose", mean_pose, 3)
    S = _check_cov3(cov)
    cond = _conditional(mu, S, check_positive_int("n_quad", n_quad))
    flat = p.reshape(-1, 2)
    if cond.nodes.size <= _DENSE_NODES:
        out = _pdf_xy_dense(flat, cond)
    else:
        out = _pdf_xy_pruned(flat, cond)
        out[np.isnan(flat).any(axis=1)] = np.nan  # as the full sum gives
    return out.reshape(p.shape[:-1])


def marginal_xy_grid(
    x: ArrayLike, y: ArrayLike, mean_pose: ArrayLike, cov: ArrayLike, n_quad: int = 64
) -> NDArray[np.float64]:
    """Planar density on a grid of cell centres, shape (nx, ny) [1/m²] (``values[i, j]`` at ``(x_i, y_j)``)."""
    xx = check_finite("x", x)
    yy = check_finite("y", y)
    X, Y = np.meshgrid(xx, yy, indexing="ij")
    return pdf_xy(np.stack([X, Y], axis=-1), mean_pose, cov, n_quad=n_quad)


def hdr_threshold(
    mean_pose: ArrayLike,
    cov: ArrayLike,
    pr: ArrayLike,
    rng: np.random.Generator,
    n: int = 200_000,
    n_quad: int = 64,
) -> NDArray[np.float64]:
    """Density level ``c`` of the planar highest-density region with probability Pr.

    ``{(x, y): p(x, y) ≥ c}`` holds probability Pr: ``c`` is the (1−Pr)-quantile
    of ``p(X)`` for ``X`` drawn from the distribution itself (Hyndman 1996),
    estimated from ``n`` draws. Its Monte Carlo error in probability is
    ``√(Pr(1−Pr)/n)`` (≈ 0.001 for the default ``n``).

    Parameters
    ----------
    mean_pose : array_like, shape (3,); cov : array_like, shape (3, 3)
    pr : float or array_like in (0, 1)
    rng : numpy.random.Generator; n : int — draws; n_quad : int — see :func:`pdf_xy`

    Returns
    -------
    ndarray, shape of ``pr`` [1/m²]
    """
    p = check_probability("pr", pr)
    draws = sample(mean_pose, cov, n, rng)
    return density_quantiles(draws[:, :2], mean_pose, cov, 1.0 - p, n_quad=n_quad)


#: :func:`density_quantiles` bounds each point's density by the pruned sum at this truncation
#: (the terms it leaves out add up to at most e^-T of the largest node peak)
_BOUND_TRUNC = 5.0
#: relative margin of that sum taken in single precision (its error is below 2·10⁻⁵: _block_sum)
_SINGLE_MARGIN = 1e-4


def _compiled_loaded() -> bool:
    """Whether this process has loaded the compiled loops (numba) of :mod:`.mc_kernel` already."""
    from . import mc_kernel

    return bool(mc_kernel._JIT)


def _density_brackets(pts: NDArray, cond: _Conditional, compiled: bool | None = None) -> tuple[NDArray, NDArray]:
    """Lower and upper bounds (n,) of :func:`pdf_xy` at points (n, 2) (:func:`density_quantiles`).

    The sum over the terms kept at the truncation :data:`_BOUND_TRUNC`, by numpy in single precision,
    or (``compiled``; default: when the process has loaded the compiled loops already, so that a
    run does not import numba for it) by the compiled loop ``_mc_jit.truncated_density`` in double
    precision, its terms from each node's own Mahalanobis distance. Either sum holds only terms of
    :func:`pdf_xy` and leaves out only terms below ``e^-T/n`` of the largest node peak; the margins
    cover both roundings. What :func:`density_quantiles` returns does not depend on the route.
    """
    with np.errstate(divide="ignore"):
        la = np.log(cond.weights) + cond.log_norm
        la_max = float(np.max(la))
    if compiled is None:
        compiled = _compiled_loaded()
    if compiled:
        from .mc_kernel import jit_module

        tree = _range_tree(cond, _BOUND_TRUNC)
        n, padded = la.size, tree.cx[-1].size * _BLOCK

        def pad(v: NDArray, fill: float) -> NDArray:
            out = np.full(padded, fill)
            out[:n] = v
            return out

        kept = np.empty(pts.shape[0])
        jit_module().truncated_density(
            np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1]), pad(cond.means[:, 0], 0.0),
            pad(cond.means[:, 1], 0.0), pad(cond.prec[:, 0, 0], 0.0), pad(cond.prec[:, 0, 1], 0.0),
            pad(cond.prec[:, 1, 1], 0.0), pad(la, -np.inf), tree.log_floor, tree.cx[-1], tree.cy[-1],
            tree.m00[-1], tree.m01[-1], tree.m11[-1], tree.bound[-1], _BLOCK, kept,
        )  # fmt: skip
    else:
        kept = _pdf_xy_pruned(pts, cond, _BOUND_TRUNC, single=True)
    lo = kept * (1.0 - _SINGLE_MARGIN)
    hi = kept * (1.0 + _SINGLE_MARGIN) + math.exp(la_max - _BOUND_TRUNC) * (1.0 + 1e-6)
    return lo, hi


def density_quantiles(
    xy: ArrayLike, mean_pose: ArrayLike, cov: ArrayLike, q: ArrayLike, n_quad: int = 64
) -> NDArray[np.float64]:
    """``np.quantile(pdf_xy(xy, …), q)``, the same numbers, with the density of few points.

    A quantile of the densities needs the exact density of the points whose rank is near
    it only. With more than 64 quadrature nodes every point's density is first bracketed:
    the quadrature sum ``s`` over the node blocks kept at the truncation ``T = 5`` holds a
    subset of the positive terms :func:`pdf_xy` adds, and the terms it leaves out add up to
    at most ``e^{−5}`` of the largest node peak ``max_k w_k N_k(μ_k)``. Taken in single
    precision (``exp`` of float32 is several times faster; within ``2·10⁻⁵`` of the double
    sum), ``lo = s (1 − 10⁻⁴)`` is below the density and ``hi = s (1 + 10⁻⁴) + e^{−5} max_k
    w_k N_k(μ_k)`` above it. The ``j``-th smallest density lies
    between the ``j``-th smallest ``lo`` and ``hi``; the points whose brackets meet that
    range are the only ones it can be, and their exact densities (:func:`pdf_xy`: every
    value depends on its own point only) with the count of points certainly below give it
    exactly. The order statistics numpy's linear interpolation reads (and their
    neighbours) are found so, and ``np.quantile`` interpolates them: the result is the
    same as ``np.quantile(pdf_xy(xy, mean_pose, cov, n_quad), q)``, bit for bit.

    Parameters
    ----------
    xy : array_like, shape (n, 2) [m] — points, n ≥ 1 (with a NaN, every quantile is NaN)
    mean_pose : array_like, shape (3,); cov : array_like, shape (3, 3)
    q : float or array_like in [0, 1] — probabilities of the quantiles
    n_quad : int — see :func:`pdf_xy`

    Returns
    -------
    ndarray, shape of ``q`` [1/m²]
    """
    pts = check_last_axis("xy", xy, 2)
    if pts.ndim != 2 or pts.shape[0] < 1:
        raise ValueError(f"xy must have shape (n, 2) with n >= 1, got shape {pts.shape}")
    qq = check_finite("q", q)
    if np.any((qq < 0.0) | (qq > 1.0)):
        raise ValueError(f"q must be in [0, 1], got {qq.tolist()}")
    mu = check_last_axis("mean_pose", mean_pose, 3)
    S = _check_cov3(cov)
    cond = _conditional(mu, S, check_positive_int("n_quad", n_quad))
    if cond.nodes.size <= _DENSE_NODES or not np.isfinite(pts).all():  # (a NaN point: NaN quantiles)
        return np.quantile(pdf_xy(pts, mu, S, n_quad=n_quad), qq)
    n = pts.shape[0]
    lo, hi = _density_brackets(pts, cond)
    slo, shi = np.sort(lo), np.sort(hi)
    # the positions numpy's linear interpolation reads, ⌊(n−1)q⌋ and the next, with a neighbour
    # each side against a rounding of (n−1)q different from numpy's
    base = np.floor((n - 1) * np.atleast_1d(qq)).astype(np.intp)
    need = np.unique(np.clip(base[:, None] + np.arange(-1, 3), 0, n - 1))
    cand = np.zeros(n, dtype=bool)
    for j in need:
        cand |= (hi >= slo[j]) & (lo <= shi[j])
    idx = np.flatnonzero(cand)
    exact = _pdf_xy_pruned(pts[idx], cond)
    stats = np.empty(need.size)
    for i, j in enumerate(need):
        mine = (hi[idx] >= slo[j]) & (lo[idx] <= shi[j])
        below = int(np.count_nonzero(hi < slo[j]))  # certainly smaller than the j-th
        stats[i] = np.sort(exact[mine])[j - below]
    # a sorted array holding the exact order statistics at their positions (and copies of them
    # between): np.quantile reads those positions only, and interpolates as it would the full array
    filled = np.full(n, stats[0])
    for i, j in enumerate(need):
        filled[j:] = stats[i]
    return np.quantile(filled, qq)


def at_least(
    xy: ArrayLike, mean_pose: ArrayLike, cov: ArrayLike, levels: ArrayLike, n_quad: int = 64
) -> NDArray[np.bool_]:
    """``pdf_xy(xy, …) >= level`` for each level, the same booleans, with the density of few points.

    Whether a point is in the region ``{p ≥ c}`` needs its exact density only where the
    brackets of :func:`density_quantiles` (``lo ≤ pdf_xy ≤ hi``) straddle ``c``: ``lo ≥ c``
    proves it in, ``hi < c`` proves it out; the others get :func:`pdf_xy`'s own value (every
    value depends on its own point only). The coverage of a region, ``np.mean(at_least(…)[i])``,
    is then the same number as ``np.mean(pdf_xy(xy, …) >= c)``, bit for bit.

    Parameters
    ----------
    xy : array_like, shape (n, 2) [m]
    mean_pose : array_like, shape (3,); cov : array_like, shape (3, 3)
    levels : array_like, shape (k,) — density levels [1/m²]
    n_quad : int — see :func:`pdf_xy`

    Returns
    -------
    ndarray of bool, shape (k, n)
    """
    pts = check_last_axis("xy", xy, 2)
    if pts.ndim != 2:
        raise ValueError(f"xy must have shape (n, 2), got shape {pts.shape}")
    c = np.atleast_1d(np.asarray(levels, dtype=np.float64))
    mu = check_last_axis("mean_pose", mean_pose, 3)
    S = _check_cov3(cov)
    cond = _conditional(mu, S, check_positive_int("n_quad", n_quad))
    if cond.nodes.size <= _DENSE_NODES or not np.isfinite(pts).all() or pts.shape[0] == 0:
        return pdf_xy(pts, mu, S, n_quad=n_quad)[None, :] >= c[:, None]
    lo, hi = _density_brackets(pts, cond)
    inside = lo[None, :] >= c[:, None]
    unsure = ~inside & (hi[None, :] >= c[:, None])
    idx = np.flatnonzero(unsure.any(axis=0))
    if idx.size:
        exact = _pdf_xy_pruned(pts[idx], cond)
        inside[:, idx] = exact[None, :] >= c[:, None]
    return inside


def pr_region_xy(
    mean_pose: ArrayLike,
    cov: ArrayLike,
    pr: float,
    rng: np.random.Generator,
    n_grid: int = 200,
    n: int = 200_000,
) -> list[NDArray[np.float64]]:
    """Boundary of the planar Pr highest-density region (the banana) as polylines.

    The region ``{p(x, y) ≥ c}`` (:func:`hdr_threshold`) contoured on a square
    grid of ``n_grid²`` cells covering the draws used for the threshold.

    Parameters
    ----------
    mean_pose : array_like, shape (3,); cov : array_like, shape (3, 3)
    pr : float in (0, 1); rng : numpy.random.Generator
    n_grid : int — grid cells per axis; n : int — draws for the threshold

    Returns
    -------
    list of ndarray, each shape (m, 2) [m] — closed polylines (usually one)
    """
    pr_ = float(check_probability("pr", pr))
    mu = check_last_axis("mean_pose", mean_pose, 3)
    S = _check_cov3(cov)
    n_grid = check_positive_int("n_grid", n_grid)
    draws = sample(mu, S, n, rng)
    dens = pdf_xy(draws[:, :2], mu, S)
    level = float(np.quantile(dens, 1.0 - pr_))
    inside = draws[dens >= level, :2]
    lo, hi = inside.min(axis=0), inside.max(axis=0)
    pad = 0.1 * (hi - lo) + 1e-12
    x = np.linspace(lo[0] - pad[0], hi[0] + pad[0], n_grid)
    y = np.linspace(lo[1] - pad[1], hi[1] + pad[1], n_grid)
    return region_xy_at(x, y, mu, S, level)


def _grid_for_contour(x: NDArray, y: NDArray, mean_pose: ArrayLike, cov: ArrayLike, level: float) -> NDArray:
    """The density on the grid ``x × y`` (nx, ny) as its contour at ``level`` reads it.

    Marching squares draws a line through a cell only where its corners lie on both sides of
    the level, interpolating between those corners' values. A point whose brackets
    (:func:`density_quantiles`) put it strictly above or below the level keeps its bracket; the
    corners of every cell not certainly all on one side get :func:`marginal_xy_grid`'s exact
    values. The contour is the one of the exact grid, line for line.
    """
    mu = check_last_axis("mean_pose", mean_pose, 3)
    S = _check_cov3(cov)
    cond = _conditional(mu, S, 64)
    if cond.nodes.size <= _DENSE_NODES or not math.isfinite(level) or x.size < 2 or y.size < 2:
        return marginal_xy_grid(x, y, mu, S)
    X, Y = np.meshgrid(x, y, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel()], axis=-1)
    lo, hi = _density_brackets(pts, cond)
    above, below = (lo > level).reshape(X.shape), (hi < level).reshape(X.shape)
    Z = np.where(above, lo.reshape(X.shape), hi.reshape(X.shape))

    def all4(m: NDArray) -> NDArray:  # per cell: all four corners
        return m[:-1, :-1] & m[1:, :-1] & m[:-1, 1:] & m[1:, 1:]

    open_cell = ~(all4(above) | all4(below))
    need = np.zeros(X.shape, dtype=bool)
    for di in (0, 1):
        for dj in (0, 1):
            need[di : di + open_cell.shape[0], dj : dj + open_cell.shape[1]] |= open_cell
    idx = np.flatnonzero(need.ravel())
    if idx.size:
        Z.ravel()[idx] = _pdf_xy_pruned(pts[idx], cond)
    return Z


def region_xy_at(
    x: ArrayLike, y: ArrayLike, mean_pose: ArrayLike, cov: ArrayLike, level: float
) -> list[NDArray[np.float64]]:
    """Boundary of the planar region ``{p(x, y) ≥ level}`` contoured on the grid ``x × y``.

    :func:`pr_region_xy` with a known level (e.g. the threshold a run's coverage used,
    ``RunResult.expcoords_levels``): the density on the grid's points
    (:func:`marginal_xy_grid`) and its contour at ``level``.

    Parameters
    ----------
    x : array_like, shape (nx,); y : array_like, shape (ny,) — increasing grid points [m]
    mean_pose : array_like, shape (3,); cov : array_like, shape (3, 3)
    level : float — density level [1/m²]

    Returns
    -------
    list of ndarray, each shape (m, 2) [m] — polylines (closed unless cut by the grid's edge)
    """
    xx, yy = check_finite("x", x), check_finite("y", y)
    Z = _grid_for_contour(xx, yy, mean_pose, cov, float(level))
    import contourpy  # imported where used: only these contours need it

    gen = contourpy.contour_generator(xx, yy, Z.T)
    return [np.asarray(line) for line in gen.lines(float(level))]
