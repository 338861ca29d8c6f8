"""Method C — the unscented transform along a trajectory (Julier & Uhlmann 2004; van der Merwe 2004).

Same inputs as Method A (:func:`pose_uncertainty.methods.covariance.propagate`:
a trajectory, ``k_r``, ``k_l`` and ``cov0``, batched over parameter sets) and
the same outputs (poses and covariances along the path). Two variants:

Cartesian UT (:func:`propagate`)
    Per step, the state is augmented with the step's two wheel travels,
    ``z = (x, y, θ, Δs_r, Δs_l)`` with mean ``(p̄, Δs_r, Δs_l)`` and covariance
    ``blockdiag(Σ_p, Σ_Δ)``, ``Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|)``. Its ``2n+1 = 11``
    sigma points go through the midpoint step of Method A (Němec 2012 §2.1)
    (:func:`pose_uncertainty.core.kinematics.step`, the step Method A linearises),
    so that where that step is linear on the sigma points, C equals A exactly.
    The heading mean is circular (about the propagated central point, so the
    path's heading stays unwrapped) and the heading residuals are wrapped.

UT on SE(2) (:func:`propagate_se2`)
    Sigma points in the exponential coordinates of the pose about the noiseless
    mean, ``g_i = μ exp(ε_i)`` (right perturbation, as
    :mod:`pose_uncertainty.methods.expcoords`), augmented with the wheel noise;
    each goes through the exact arc ``exp(δ + M e_i)`` and is mapped back by
    ``ε'_i = log(μ'⁻¹ g'_i)``. The mean stays the noiseless pose and the
    covariance is that of the concentrated Gaussian ``g = μ exp(ε)`` (an
    :class:`~pose_uncertainty.methods.expcoords.ExpGaussian`), so it bends like
    the banana and equals :func:`expcoords.propagate` in the small-noise limit.
    In fact it stays close to it well beyond that limit: the augmented square
    root is block-diagonal, so each sigma point perturbs either ε or the wheel
    travels, and ``exp(−δ) exp(ε) exp(δ) = exp(Ad_{exp(−δ)} ε)`` makes the ε points
    propagate exactly linearly; only the wheel-noise points see the curvature of
    one step's exponential, a relative difference O(k) with a small constant
    (4·10⁻⁹ for k = 10⁻² on a half circle of radius 1 m, b = 0.2 m).

What the Cartesian UT gets right, and what it cannot
-----------------------------------------------------
Its mean carries the second-order shift the heading noise causes (``E[cos φ] ≈ 1 − σ²/2``):
back along a straight line, inwards on an arc — Method A's mean, the noiseless path, has
none. Its covariance across the path and its mean hardly depend on the step (2·10⁻³ between
Δt = 0.1 and 0.002 s on a 20 m line). Its along-track variance beyond Method A's does: the
Gaussian it keeps after every step cannot hold the correlation of the along-track error
with ``θ²`` (the banana's bend), so each step adds ``Var(Δs cos θ)`` afresh and the excess
is proportional to the step length (0.0712, 0.0357, 0.0072, 0.0014 m² for Δt = 0.1, 0.05,
0.01, 0.002 s at 1 m/s, k = 5·10⁻⁴ m, b = 0.2 m, 20 m): it vanishes as Δt → 0 and is not
the Monte Carlo's spread along the path, which grows about as ``L^1.8`` there.

Scaled sigma points (van der Merwe)
-----------------------------------
With ``n`` the augmented dimension, ``λ = α²(n+κ) − n`` and a square root
``L Lᵀ = P``: ``χ_0 = z̄``, ``χ_{±j} = z̄ ± √(n+λ) L_j``, and weights

    W₀ᵐ = λ/(n+λ),   W₀ᶜ = W₀ᵐ + 1 − α² + β,   Wⱼ = 1/(2(n+λ)).

For small α, ``W₀ = 1 − n/(α²(n+κ)) → −n/α²`` (−10⁶ for α = 10⁻³, κ = 0): the
mean and the covariance become small differences of terms ``n/α²`` times larger
(round-off grows like ``n/α²·10⁻¹⁶``), the covariance is no longer a positive
combination of outer products, so nothing keeps it positive semi-definite once
the step is not quadratic on the sigma points (a heading uncertainty of order
one), and as α → 0 the transform collapses to a second-order Taylor expansion
about the mean — the wrong local picture for a wide heading distribution.
The defaults here, **α = 1, β = 0, κ = 0**, give
``λ = 0``, ``W₀ᵐ = W₀ᶜ = 0`` and ``Wⱼ = 1/(2n)``: every weight is ≥ 0, so the
covariance is a positive combination of outer products (PSD by construction)
and the circular mean is a plain weighted resultant. (This is the third-degree
spherical–radial cubature rule of Arasaratnam & Haykin's cubature Kalman
filter.) Its costs: sigma points at ``√n = √5 ≈ 2.24`` standard deviations
(the wrapped heading residuals are meaningful while ``√5 σ_θ < π``, i.e.
``σ_θ ≲ 1.4 rad``) and a fourth moment ``5σ⁴`` instead of a Gaussian's ``3σ⁴``:
the mean and covariance are right to second order, and the fourth-order terms
of the covariance are overestimated (e.g. ``Var(cos θ)`` ≈ ``σ⁴`` instead of
``σ⁴/2``). No choice of (α, β, κ) with all weights ≥ 0 matches the fourth
moment for ``n = 5`` (that needs ``n+λ = 3``, hence ``W₀ = 1 − n/3 < 0``).

The square root is a positive-semi-definite Cholesky factor (zero pivots, as at
the start of a path, give zero columns), in closed form over the batch.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import _translation_twist, integrate, wrap_angle
from ..core.se2 import adjoint, compose, exp, inverse, log
from ..core.trajectories import Trajectory
from ..core.validation import check_choice, check_finite, check_positive
from .covariance import CovarianceResult, _check_inputs
from .expcoords import ExpGaussian

__all__ = [
    "PERTURBATIONS",
    "SigmaWeights",
    "propagate",
    "propagate_se2",
    "psd_cholesky",
    "sigma_points",
    "sigma_weights",
    "ut_step",
    "ut_step_se2",
]

PERTURBATIONS: tuple[str, ...] = ("right", "left")
#: dimension of the augmented state (pose, two wheel travels)
_N_AUG = 5


class SigmaWeights(NamedTuple):
    """Scaled-UT weights: ``lam`` = λ, ``Wm``, ``Wc`` shape (2n+1,), sum of ``Wm`` = 1."""

    lam: float
    Wm: NDArray[np.float64]
    Wc: NDArray[np.float64]


def sigma_weights(n: int, alpha: float = 1.0, beta: float = 0.0, kappa: float = 0.0) -> SigmaWeights:
    """Weights of the scaled unscented transform (van der Merwe).

    ``λ = α²(n+κ) − n``, ``W₀ᵐ = λ/(n+λ)``, ``W₀ᶜ = W₀ᵐ + 1 − α² + β``,
    ``Wⱼ = 1/(2(n+λ))`` for the other 2n points (module docstring for the defaults).

    Parameters
    ----------
    n : int ≥ 1 — state dimension
    alpha : float > 0 — spread; beta : float — prior-kurtosis term; kappa : float, n+κ > 0

    Returns
    -------
    SigmaWeights
    """
    a = float(check_positive("alpha", alpha))
    b = float(check_finite("beta", beta))
    k = float(check_finite("kappa", kappa))
    if n + k <= 0:
        raise ValueError(f"kappa must make n + kappa > 0 (allowed: kappa > {-n}), got {k!r}")
    c2 = a * a * (n + k)  # n + λ, the squared spread
    Wm = np.full(2 * n + 1, 0.5 / c2)
    Wc = Wm.copy()
    Wm[0] = 1.0 - n / c2  # = λ/(n+λ), without the cancellation in λ = c² − n
    Wc[0] = Wm[0] + 1.0 - a * a + b
    lam = c2 - n
    return SigmaWeights(lam, Wm, Wc)


def psd_cholesky(P: ArrayLike) -> NDArray[np.float64]:
    """Lower-triangular ``L`` with ``L Lᵀ = P`` for symmetric PSD ``P``, singular allowed.

    Column by column (a loop over the matrix dimension, not the batch); a pivot
    ``≤ 1e-14·max|P|`` (zero, up to rounding) gives a zero column.

    Parameters
    ----------
    P : array_like, shape (..., n, n)

    Returns
    -------
    ndarray, shape (..., n, n)
    """
    A = np.asarray(P, dtype=np.float64)
    n = A.shape[-1]
    L = np.zeros_like(A)
    tol = 1e-14 * np.abs(A).max(axis=(-1, -2))
    for j in range(n):
        # d = A_jj − Σ_k L_jk², below_i = A_ij − Σ_k L_ik L_jk (k < j): up to two terms added
        # elementwise, as einsum adds them (without its dispatch: a 3×3 factor is every step of
        # Method C), more by einsum
        d = A[..., j, j]
        below = A[..., j + 1 :, j]
        if 0 < j <= 2:
            acc = L[..., j, 0] * L[..., j, 0] if j == 1 else L[..., j, 0] * L[..., j, 0] + L[..., j, 1] * L[..., j, 1]
            d = d - acc
            if j + 1 < n:
                lo = L[..., j + 1 :, 0] * L[..., j, 0, None]
                below = below - (lo if j == 1 else lo + L[..., j + 1 :, 1] * L[..., j, 1, None])
        elif j:
            d = d - np.einsum("...k,...k->...", L[..., j, :j], L[..., j, :j])
            below = below - np.einsum("...ik,...k->...i", L[..., j + 1 :, :j], L[..., j, :j])
        ok = d > tol
        root = np.sqrt(np.where(ok, d, 1.0))
        L[..., j, j] = np.where(ok, root, 0.0)
        if j + 1 < n:
            L[..., j + 1 :, j] = np.where(ok[..., None], below / root[..., None], 0.0)
    return L


def sigma_points(mean: ArrayLike, L: ArrayLike, lam: float) -> NDArray[np.float64]:
    """Sigma points ``χ_0 = z̄``, ``χ_j = z̄ + √(n+λ) L_j``, ``χ_{n+j} = z̄ − √(n+λ) L_j``.

    Parameters
    ----------
    mean : array_like, shape (..., n); L : array_like, shape (..., n, n) — a square root
    lam : float — λ of :func:`sigma_weights`

    Returns
    -------
    ndarray, shape (..., 2n+1, n)
    """
    m = np.asarray(mean, dtype=np.float64)
    n = m.shape[-1]
    S = np.sqrt(n + lam) * np.swapaxes(np.asarray(L, dtype=np.float64), -1, -2)  # rows = columns of L
    out = np.empty((*np.broadcast_shapes(m.shape[:-1], S.shape[:-2]), 2 * n + 1, n))
    out[..., 0, :] = m
    np.add(m[..., None, :], S, out=out[..., 1 : n + 1, :])
    np.subtract(m[..., None, :], S, out=out[..., n + 1 :, :])
    return out


def _augmented_sqrt(L_p: NDArray, var_r: NDArray, var_l: NDArray) -> NDArray:
    """``blockdiag(L_p, √var_r, √var_l)``, shape (..., 5, 5)."""
    shape = np.broadcast_shapes(L_p.shape[:-2], np.shape(var_r), np.shape(var_l))
    out = np.zeros((*shape, _N_AUG, _N_AUG))
    out[..., :3, :3] = L_p
    out[..., 3, 3] = np.sqrt(var_r)
    out[..., 4, 4] = np.sqrt(var_l)
    return out


def _circular_mean_heading(theta: NDArray, Wm: NDArray) -> NDArray:
    """Weighted circular mean of sigma-point headings (..., 2n+1), about the central point.

    ``θ̄ = θ_0 + atan2(Σ W sin(θ_i − θ_0), Σ W cos(θ_i − θ_0))``: unwrapped like the
    path's heading. Where the resultant vanishes (headings spread evenly round the
    circle) ``atan2(0, 0) = 0`` gives the central point's heading.
    """
    d = wrap_angle(theta - theta[..., :1])
    return theta[..., 0] + np.arctan2(np.sin(d) @ Wm, np.cos(d) @ Wm)


def _cartesian_recombine(points: NDArray, w: SigmaWeights) -> tuple[NDArray, NDArray]:
    """Mean (..., 3) and covariance (..., 3, 3) of propagated sigma poses (..., 2n+1, 3)."""
    xy = points[..., :2].swapaxes(-1, -2) @ w.Wm
    th = _circular_mean_heading(points[..., 2], w.Wm)
    mean = np.concatenate([xy, th[..., None]], axis=-1)
    d = points - mean[..., None, :]
    d[..., 2] = wrap_angle(d[..., 2])  # heading residuals wrapped
    # Σ' = Σ_i W_iᶜ d_i d_iᵀ
    cov = np.swapaxes(d * w.Wc[:, None], -1, -2) @ d
    return mean, 0.5 * (cov + np.swapaxes(cov, -1, -2))


def ut_step(
    pose: ArrayLike,
    cov: ArrayLike,
    ds_r: ArrayLike,
    ds_l: ArrayLike,
    k_r: ArrayLike,
    k_l: ArrayLike,
    track: ArrayLike,
    weights: SigmaWeights | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One Cartesian-UT step of the mean pose and its covariance, batched.

    Parameters
    ----------
    pose : array_like, shape (..., 3) [m, m, rad]; cov : array_like, shape (..., 3, 3), PSD
    ds_r, ds_l : array_like, shape (...) — nominal wheel travels of the step [m]
    k_r, k_l : array_like, shape (...) [m], ≥ 0; track : array_like, shape (...) [m], > 0
    weights : SigmaWeights for n = 5, optional (default α = 1, β = 0, κ = 0)

    Returns
    -------
    pose' : ndarray, shape (..., 3); cov' : ndarray, shape (..., 3, 3)
    """
    w = sigma_weights(_N_AUG) if weights is None else weights
    p = np.asarray(pose, dtype=np.float64)
    sr, sl, b = np.asarray(ds_r, float), np.asarray(ds_l, float), np.asarray(track, float)
    # z = (x, y, θ, Δs_r, Δs_l),  Cov z = blockdiag(Σ_p, k_r|Δs_r|, k_l|Δs_l|): the sigma points of
    # sigma_points(z, blockdiag(L_p, √(k_r|Δs_r|), √(k_l|Δs_l|)), λ), built block by block (each
    # point moves the pose or one wheel only; the same numbers, fewer operations a step)
    shape = np.broadcast_shapes(p.shape[:-1], sr.shape, sl.shape)
    spread = np.sqrt(_N_AUG + w.lam)
    cols = spread * np.swapaxes(psd_cholesky(cov), -1, -2)  # row j: √(n+λ) L_p[:, j]
    pose_pts = np.empty((*shape, 2 * _N_AUG + 1, 3))
    pose_pts[...] = p[..., None, :]
    pose_pts[..., 1:4, :] += cols
    pose_pts[..., 6:9, :] -= cols
    wheel = np.empty((*shape, 2, 2 * _N_AUG + 1))  # Δs_r, Δs_l of each point
    wheel[..., 0, :], wheel[..., 1, :] = sr[..., None], sl[..., None]
    for row, var, at in ((0, np.asarray(k_r) * np.abs(sr), 4), (1, np.asarray(k_l) * np.abs(sl), 5)):
        dev = spread * np.sqrt(var)
        wheel[..., row, at] += dev
        wheel[..., row, at + _N_AUG] -= dev
    r, l_ = wheel[..., 0, :], wheel[..., 1, :]
    # the midpoint step of kinematics.step (its translation, without re-checking the points)
    ds, dth = (r + l_) / 2.0, (r - l_) / b[..., None]
    th = pose_pts[..., 2]
    dx, dy = _translation_twist(th, ds, 0.0, dth, "midpoint")  # type: ignore[arg-type]
    moved = np.stack([pose_pts[..., 0] + dx, pose_pts[..., 1] + dy, th + dth], axis=-1)
    return _cartesian_recombine(moved, w)


def _check_batch(
    trajectory: Trajectory,
    k_r: ArrayLike,
    k_l: ArrayLike,
    track: ArrayLike | None,
    cov0: ArrayLike | None,
) -> tuple[NDArray, NDArray, NDArray, NDArray, tuple[int, ...]]:
    """Validated k_r, k_l, track, cov0 and their common batch shape."""
    b = trajectory.track if track is None else track
    _, _, b_, kr, kl, S0, _ = _check_inputs(
        trajectory.ds_r, trajectory.ds_l, b, k_r, k_l, cov0, trajectory.start
    )
    batch = np.broadcast_shapes(kr.shape, kl.shape, b_.shape, S0.shape[:-2])
    return kr, kl, b_, S0, batch


def _march(
    trajectory: Trajectory,
    k_r: ArrayLike,
    k_l: ArrayLike,
    track: ArrayLike | None,
    cov0: ArrayLike | None,
    ut_params: tuple[float, float, float],
    start: Callable[[NDArray, NDArray, tuple[int, ...], int], tuple[NDArray, ...]],
    step: Callable[..., None],
) -> tuple[NDArray, tuple[NDArray, ...]]:
    """Method C's loop over the steps of a trajectory, every set of the batch at once.

    Checks the inputs (:func:`_check_batch`), makes the scaled-UT weights of ``ut_params``
    ``(alpha, beta, kappa)``, and calls ``step(i, covs, *extra, k_r, k_l, b, w)`` for each step
    ``i``, which fills ``covs[i + 1]`` (time-major while stepping: each step writes one contiguous
    block) and whatever else it carries in ``extra = start(Σ_0, b, batch, N)``.

    Returns
    -------
    (covs, extra) — covs batch-major, shape (B..., N+1, 3, 3); extra as ``step`` left it
    """
    w = sigma_weights(_N_AUG, *ut_params)
    kr, kl, b, S0, batch = _check_batch(trajectory, k_r, k_l, track, cov0)
    n = trajectory.n_steps
    covs = np.empty((n + 1, *batch, 3, 3))
    covs[0] = S0
    extra = start(S0, b, batch, n)
    for i in range(n):
        step(i, covs, *extra, kr, kl, b, w)
    return np.moveaxis(covs, 0, -3).copy(), extra


def _nominal_poses(trajectory: Trajectory, b: NDArray, method: str) -> NDArray:
    """Noiseless poses (B..., N+1, 3) for the trajectory's wheel travels and track(s) ``b``."""
    sr, sl = trajectory.ds_r, trajectory.ds_l
    return integrate((sr + sl) / 2.0, (sr - sl) / b[..., None], trajectory.start, method=method)  # type: ignore[arg-type]


def propagate(
    trajectory: Trajectory,
    k_r: ArrayLike,
    k_l: ArrayLike,
    *,
    track: ArrayLike | None = None,
    cov0: ArrayLike | None = None,
    alpha: float = 1.0,
    beta: float = 0.0,
    kappa: float = 0.0,
    kernel: str = "numpy",
) -> CovarianceResult:
    """Method C, Cartesian: the unscented transform of the midpoint step along a trajectory.

    Parameters
    ----------
    trajectory : Trajectory — wheel travels, step and start pose
    k_r, k_l : array_like, shape (B...) — error constants [m], ≥ 0
    track : array_like, shape (B...), optional — wheel separation [m] per set
        (default the trajectory's; the wheel travels are kept)
    cov0 : array_like, shape (B..., 3, 3), optional — initial covariance (default 0)
    alpha, beta, kappa : float — scaled-UT parameters (module docstring; defaults
        keep every weight ≥ 0)
    kernel : {"numpy", "compiled"} — the loop over the steps by numpy (the reference, batched) or,
        for one set (scalar k_r, k_l, track), by the compiled loop of :mod:`.mc_kernel` (the same
        arithmetic in another order: equal up to rounding, within the reproducibility contract)

    Returns
    -------
    CovarianceResult with poses (B..., N+1, 3) — UT means, heading unwrapped —
    and covs (B..., N+1, 3, 3)
    """
    check_choice("kernel", kernel, ("numpy", "compiled"))
    if kernel == "compiled":
        kr, kl, b_, S0, batch = _check_batch(trajectory, k_r, k_l, track, cov0)
        if batch:
            raise ValueError(f"kernel 'compiled' takes one set (scalar k_r, k_l, track, cov0), got batch shape {batch}")
        from .mc_kernel import jit_module

        w = sigma_weights(_N_AUG, alpha, beta, kappa)
        n = trajectory.n_steps
        poses, covs = np.empty((n + 1, 3)), np.empty((n + 1, 3, 3))
        poses[0], covs[0] = trajectory.start, S0
        jit_module().ut_march(np.ascontiguousarray(trajectory.ds_r, dtype=np.float64),
                              np.ascontiguousarray(trajectory.ds_l, dtype=np.float64), float(kr), float(kl),
                              float(b_), w.Wm, w.Wc, float(np.sqrt(_N_AUG + w.lam)), poses, covs)  # fmt: skip
        return CovarianceResult(poses=poses, covs=covs, times=trajectory.times)
    def start(S0: NDArray, b: NDArray, batch: tuple[int, ...], n: int) -> tuple[NDArray, ...]:
        poses = np.empty((n + 1, *batch, 3))
        poses[0] = trajectory.start
        return (poses,)

    def step(i: int, covs: NDArray, poses: NDArray, kr: NDArray, kl: NDArray, b: NDArray, w: SigmaWeights) -> None:
        poses[i + 1], covs[i + 1] = ut_step(poses[i], covs[i], trajectory.ds_r[i], trajectory.ds_l[i], kr, kl, b, w)

    covs, (poses,) = _march(trajectory, k_r, k_l, track, cov0, (alpha, beta, kappa), start, step)
    return CovarianceResult(
        poses=np.moveaxis(poses, 0, -2).copy(), covs=covs, times=trajectory.times,
    )


# --- UT on SE(2) ----------------------------------------------------------------------------


def ut_step_se2(
    cov: ArrayLike,
    ds_r: ArrayLike,
    ds_l: ArrayLike,
    k_r: ArrayLike,
    k_l: ArrayLike,
    track: ArrayLike,
    weights: SigmaWeights | None = None,
    root: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """One SE(2)-UT step of the body-frame exponential-coordinates covariance, batched.

    Sigma points ``(ε_i, e_i)`` of ``N(0, blockdiag(Σ, Σ_Δ))``; with the nominal
    twist ``δ = (Δs, 0, Δθ)`` and ``M e = ((e_r+e_l)/2, 0, (e_r−e_l)/b)``:

        ε'_i = log(exp(−δ) exp(ε_i) exp(δ + M e_i))      (heading wrapped),
        Σ'   = Σ_i W_iᶜ ε'_i ε'_iᵀ

    (the second moment about the noiseless mean ``μ' = μ exp(δ)``; it does not
    depend on ``μ``).

    Parameters
    ----------
    cov : array_like, shape (..., 3, 3) — Σ of ε [m², m·rad, rad²], PSD
    ds_r, ds_l : array_like, shape (...) [m]; k_r, k_l : array_like [m]; track : array_like [m]
    weights : SigmaWeights for n = 5, optional
    root : array_like, shape (..., 3, 3), optional — a square root of ``cov`` to
        place the ε sigma points (default its PSD Cholesky factor)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    w = sigma_weights(_N_AUG) if weights is None else weights
    sr, sl, b = np.asarray(ds_r, float), np.asarray(ds_l, float), np.asarray(track, float)
    L_eps = psd_cholesky(cov) if root is None else np.asarray(root, dtype=np.float64)
    L = _augmented_sqrt(L_eps, np.asarray(k_r) * np.abs(sr), np.asarray(k_l) * np.abs(sl))
    chi = sigma_points(np.zeros(L.shape[:-1]), L, w.lam)  # (..., 11, 5)
    ds, dth = (sr + sl) / 2.0, (sr - sl) / b
    delta = np.stack(np.broadcast_arrays(ds, np.zeros_like(ds), dth), axis=-1)[..., None, :]
    e_r, e_l = chi[..., 3], chi[..., 4]
    twist = delta + np.stack([(e_r + e_l) / 2.0, np.zeros_like(e_r), (e_r - e_l) / b[..., None]], -1)
    rel = compose(compose(exp(-delta), exp(chi[..., :3])), exp(twist))
    rel[..., 2] = wrap_angle(rel[..., 2])
    eps = log(rel)
    out = np.swapaxes(eps * w.Wc[:, None], -1, -2) @ eps  # Σ_i W_iᶜ ε'_i ε'_iᵀ
    return 0.5 * (out + np.swapaxes(out, -1, -2))


def _left_root(pose: NDArray, cov: NDArray) -> NDArray:
    """Square root placing left-perturbation sigma points, expressed in body-frame coordinates.

    ``exp(ε_L) μ = μ exp(Ad_μ⁻¹ ε_L)`` exactly, so sigma points ``ε_L = √(n+λ) L_L``
    of ``Σ_L = Ad_μ Σ Ad_μᵀ`` are the body-frame points ``√(n+λ) Ad_μ⁻¹ L_L``.
    """
    Ad = adjoint(pose)
    Ad_inv = adjoint(inverse(pose))
    return Ad_inv @ psd_cholesky(Ad @ cov @ np.swapaxes(Ad, -1, -2))


def propagate_se2(
    trajectory: Trajectory,
    k_r: ArrayLike,
    k_l: ArrayLike,
    *,
    track: ArrayLike | None = None,
    cov0: ArrayLike | None = None,
    perturbation: str = "right",
    alpha: float = 1.0,
    beta: float = 0.0,
    kappa: float = 0.0,
) -> ExpGaussian:
    """Method C on SE(2): the unscented transform in exponential coordinates along a trajectory.

    ``perturbation`` places the sigma points: ``"right"`` as ``μ exp(ε_i)`` (body
    frame, the coordinates of the result), ``"left"`` as ``exp(ε_i^L) μ`` with
    ``ε^L`` the sigma points of the world-frame covariance ``Ad_μ Σ Ad_μᵀ``. Since
    ``exp(ε^L) μ = μ exp(Ad_μ⁻¹ ε^L)`` and ``log(g μ'⁻¹) = Ad_μ' log(μ'⁻¹ g)``
    exactly, the two differ only in the square root of Σ that spreads the
    points, and the result is reported in body-frame coordinates either way
    (``Σ_L = Ad_μ Σ Ad_μᵀ`` converts).

    Parameters
    ----------
    trajectory : Trajectory
    k_r, k_l : array_like, shape (B...) [m], ≥ 0
    track : array_like, shape (B...), optional [m] — default the trajectory's
    cov0 : array_like, shape (B..., 3, 3), optional — Σ_0 of the body-frame exponential
        coordinates at the start (default 0)
    perturbation : {"right", "left"}
    alpha, beta, kappa : float — scaled-UT parameters (module docstring)

    Returns
    -------
    ExpGaussian with poses (B..., N+1, 3) — noiseless exact-arc poses — and the
    body-frame covs (B..., N+1, 3, 3)
    """
    check_choice("perturbation", perturbation, PERTURBATIONS)

    def start(S0: NDArray, b: NDArray, batch: tuple[int, ...], n: int) -> tuple[NDArray, ...]:
        return (np.broadcast_to(_nominal_poses(trajectory, b, "exact"), (*batch, n + 1, 3)),)

    def step(i: int, covs: NDArray, mu: NDArray, kr: NDArray, kl: NDArray, b: NDArray, w: SigmaWeights) -> None:
        root = _left_root(mu[..., i, :], covs[i]) if perturbation == "left" else None
        covs[i + 1] = ut_step_se2(covs[i], trajectory.ds_r[i], trajectory.ds_l[i], kr, kl, b, w, root)

    covs, (mu,) = _march(trajectory, k_r, k_l, track, cov0, (alpha, beta, kappa), start, step)
    return ExpGaussian(poses=mu.copy(), covs=covs, times=trajectory.times)
