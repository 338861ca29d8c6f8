"""The Kalman filter and EKF localization with range–bearing landmarks (Thrun §3.2–3.3, §7.4; Kulich 2014).

Pure, batched functions over leading dimensions (``mean (..., 3)``, ``cov (..., 3, 3)``).

Linear Kalman filter (Kulich 2014, "Kalman_filter")::

    predict:  x̄ = F x + b,          P̄ = F P Fᵀ + Q
    update:   S = H P̄ Hᵀ + R,       K = P̄ Hᵀ S⁻¹,     x = x̄ + K ν,   ν = z − H x̄
              P = (I − K H) P̄ (I − K H)ᵀ + K R Kᵀ        (Joseph form)

Kulich 2014 prints ``P = (I − K H) P̄``, equal in exact arithmetic; the Joseph form
stays symmetric positive semi-definite under round-off and for any gain.

EKF: the same update with ``ν = z − h(x̄)`` (bearing components wrapped) and
``H = ∂h/∂x`` at ``x̄`` — :func:`ekf_update` reduces to :func:`kf_update` exactly
when ``h`` is linear. Two predictions:

* :func:`ekf_predict_wheels` — Method A (:func:`pose_uncertainty.methods.covariance.step`):
  midpoint step, ``Σ' = J_p Σ J_pᵀ + J_Δ Σ_Δ J_Δᵀ``, ``Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|)``;
* :func:`ekf_predict_velocity` — the velocity motion model linearised (Thrun Table 7.2)::

      x' = x + VΔt·sinc(ωΔt/2)·cos(θ + ωΔt/2),  y' likewise with sin,  θ' = θ + ωΔt + γΔt
      Σ' = G Σ Gᵀ + V M Vᵀ,   M = diag(α1V²+α2ω², α3V²+α4ω², α5V²+α6ω²)

  with ``G = ∂(x', y', θ')/∂(x, y, θ)`` and ``V = ∂(x', y', θ')/∂(V, ω, γ)`` in the
  sinc form, so ``ω → 0`` (straight driving) needs no special case. Kulich 2014
  prints ``V[0, 0] = −(sin θ + sin(θ+ωΔt))/ω``: the first sine has the wrong
  sign (it is ``(−sin θ + sin(θ+ωΔt))/ω``), and ``y' = y_c + (v/ω) cos(θ+ωΔt)``
  where it is ``y_c − …``. The γ term (heading drift of the sampler, α5, α6) is
  included so the EKF and the particle filter share one model.

Range–bearing correction (:func:`ekf_update_landmarks`): all measurements of a
step stacked into one update of dimension ``2L``; unseen landmarks (``valid``
False) get zero rows in ``H`` and zero innovation, which leaves mean and
covariance exactly unchanged.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import dsinc, sinc, wrap_angle
from ..core.noise import check_scaling
from ..core.validation import check_choice, check_finite, check_last_axis, check_positive
from ..methods.covariance import step as covariance_step
from ..methods.motion_models import velocity_forward, velocity_variances
from .evaluation import gaussian_region_flags
from .motion import Motion
from .result import (
    ASSOCIATIONS,
    FilterResult,
    Start,
    StepCallback,
    StepRecorder,
    check_keep,
    landmark_measurements,
)
from .sensors import RangeBearingSensor, landmark_h, landmark_jacobian
from .simulate import SimulatedRun
from .world import World

__all__ = [
    "EKFConfig",
    "ekf_predict_velocity",
    "ekf_predict_wheels",
    "ekf_update",
    "ekf_update_landmarks",
    "kf_predict",
    "kf_update",
    "run_ekf",
    "run_ekf_batch",
    "velocity_jacobians",
]

Array = NDArray[np.float64]


def _T(a: Array) -> Array:
    return np.swapaxes(a, -1, -2)


def kf_predict(x: ArrayLike, P: ArrayLike, F: ArrayLike, Q: ArrayLike, b: ArrayLike | None = None) -> tuple[Array, Array]:
    """Kalman prediction ``x̄ = F x + b``, ``P̄ = F P Fᵀ + Q``.

    Parameters
    ----------
    x : array_like, shape (..., n); P : array_like, shape (..., n, n)
    F : array_like, shape (..., n, n); Q : array_like, shape (..., n, n)
    b : array_like, shape (..., n), optional — control term ``B u``
    """
    xx = check_finite("x", x)
    PP, FF, QQ = (check_finite(k, v) for k, v in (("P", P), ("F", F), ("Q", Q)))
    xn = (FF @ xx[..., None])[..., 0]
    if b is not None:
        xn = xn + check_finite("b", b)
    return xn, FF @ PP @ _T(FF) + QQ


def _correct(x: Array, P: Array, nu: Array, H: Array, R: Array) -> tuple[Array, Array, Array]:
    """Gain step shared by the KF and the EKF: (x, P, S) after the innovation ``ν``, Joseph form."""
    S = H @ P @ _T(H) + R
    # K = P Hᵀ S⁻¹, from S Kᵀ = H P (S and P symmetric)
    K = _T(np.asarray(np.linalg.solve(S, H @ P), dtype=np.float64))
    xn = x + (K @ nu[..., None])[..., 0]
    A = np.eye(P.shape[-1]) - K @ H
    Pn = A @ P @ _T(A) + K @ R @ _T(K)
    return xn, 0.5 * (Pn + _T(Pn)), S


def kf_update(x: ArrayLike, P: ArrayLike, z: ArrayLike, H: ArrayLike, R: ArrayLike) -> tuple[Array, Array]:
    """Kalman update with a linear measurement ``z = H x + N(0, R)`` (Joseph form).

    Parameters
    ----------
    x : (..., n); P : (..., n, n); z : (..., m); H : (..., m, n); R : (..., m, m)

    Returns
    -------
    x : ndarray, shape (..., n); P : ndarray, shape (..., n, n)
    """
    xx, PP, zz, HH, RR = (check_finite(k, v) for k, v in (("x", x), ("P", P), ("z", z), ("H", H), ("R", R)))
    nu = zz - (HH @ xx[..., None])[..., 0]
    xn, Pn, _ = _correct(xx, PP, nu, HH, RR)
    return xn, Pn


def ekf_update(
    x: ArrayLike,
    P: ArrayLike,
    z: ArrayLike,
    h: Callable[[Array], Array],
    H_of: Callable[[Array], Array],
    R: ArrayLike,
    angular: ArrayLike | None = None,
) -> tuple[Array, Array, Array, Array]:
    """EKF update: ``ν = z − h(x̄)`` (wrapped where ``angular``), ``H = H_of(x̄)``, then as :func:`kf_update`.

    Parameters
    ----------
    x : (..., n); P : (..., n, n); z : (..., m)
    h : callable (..., n) → (..., m); H_of : callable (..., n) → (..., m, n)
    R : (..., m, m)
    angular : array_like of bool, shape (m,), optional — components that are angles

    Returns
    -------
    x, P : the posterior; nu : ndarray, shape (..., m) — innovation; S : ndarray, shape (..., m, m)
    """
    xx, PP, zz, RR = (check_finite(k, v) for k, v in (("x", x), ("P", P), ("z", z), ("R", R)))
    nu = zz - h(xx)
    if angular is not None:
        nu = np.where(np.asarray(angular, dtype=bool), wrap_angle(nu), nu)
    xn, Pn, S = _correct(xx, PP, nu, H_of(xx), RR)
    return xn, Pn, nu, S


def ekf_predict_wheels(
    mean: ArrayLike, cov: ArrayLike, ds_r: ArrayLike, ds_l: ArrayLike,
    k_r: ArrayLike, k_l: ArrayLike, track: ArrayLike,
) -> tuple[Array, Array]:  # fmt: skip
    """EKF prediction by Method A (the covariance method's midpoint step), batched.

    Parameters
    ----------
    mean : (..., 3); cov : (..., 3, 3); ds_r, ds_l : (...) measured wheel travels [m]
    k_r, k_l : (...) [m] — wheel-travel variance per metre; track : (...) [m]
    """
    return covariance_step(mean, cov, ds_r, ds_l, k_r, k_l, track)


def velocity_jacobians(mean: ArrayLike, control: ArrayLike, dt: float) -> tuple[Array, Array]:
    """Jacobians of the velocity model's step with respect to the pose and to ``(V, ω, γ)``.

    Parameters
    ----------
    mean : array_like, shape (..., 3); control : array_like, shape (..., 2) — ``(V, ω)``; dt : float [s]

    Returns
    -------
    G : ndarray, shape (..., 3, 3) — ``∂(x', y', θ')/∂(x, y, θ)``
    V : ndarray, shape (..., 3, 3) — ``∂(x', y', θ')/∂(V, ω, γ)``
    """
    p = check_last_axis("mean", mean, 3)
    u = check_last_axis("control", control, 2)
    step = float(check_positive("dt", dt))
    Vv, w = u[..., 0], u[..., 1]
    half = w * step / 2.0
    s, ds = sinc(half), dsinc(half)
    phi = p[..., 2] + half
    c, sn = np.cos(phi), np.sin(phi)
    chord = Vv * step * s
    one, zero = np.ones_like(phi), np.zeros_like(phi)
    G = np.stack([np.stack([one, zero, -chord * sn], -1), np.stack([zero, one, chord * c], -1),
                  np.stack([zero, zero, one], -1)], -2)  # fmt: skip
    k = Vv * step * step / 2.0  # ∂(chord)/∂ω = VΔt² s′/2, ∂φ/∂ω = Δt/2
    dx_dw = k * (ds * c - s * sn)
    dy_dw = k * (ds * sn + s * c)
    Vj = np.stack([np.stack([step * s * c, dx_dw, zero], -1), np.stack([step * s * sn, dy_dw, zero], -1),
                   np.stack([zero, zero + step, zero + step], -1)], -2)  # fmt: skip
    return G, Vj


def ekf_predict_velocity(
    mean: ArrayLike, cov: ArrayLike, control: ArrayLike, dt: float, alphas: ArrayLike,
    scaling: str = "squared",
) -> tuple[Array, Array]:  # fmt: skip
    """EKF prediction with the velocity motion model: ``Σ' = G Σ Gᵀ + V M Vᵀ`` (module docs).

    Parameters
    ----------
    mean : (..., 3); cov : (..., 3, 3); control : (2,) ``(V, ω)`` [m/s, rad/s]; dt : float [s]
    alphas : (6,) error constants (α5, α6: heading drift γ); scaling : {"squared", "abs"}
    """
    check_scaling(scaling)
    p = check_last_axis("mean", mean, 3)
    S = check_finite("cov", cov)
    u = check_finite("control", control)
    M = velocity_variances(u, alphas, scaling)  # (σ_V², σ_ω², σ_γ²)
    G, Vj = velocity_jacobians(p, u, dt)
    new_mean = velocity_forward(p, u[0], u[1], 0.0, dt)
    new_cov = G @ S @ _T(G) + (Vj * M[..., None, :]) @ _T(Vj)
    return new_mean, new_cov


def ekf_update_landmarks(
    mean: ArrayLike,
    cov: ArrayLike,
    z: ArrayLike,
    valid: ArrayLike,
    landmarks: ArrayLike,
    sensor: RangeBearingSensor,
) -> tuple[Array, Array, Array, Array]:
    """EKF correction with all range–bearing measurements of one step (stacked, Joseph form).

    Parameters
    ----------
    mean : (..., 3); cov : (..., 3, 3)
    z : (..., L, 2) — measured ``(r, φ)`` of landmark ``j`` in row ``j`` (after association)
    valid : (..., L) bool — which rows are measurements
    landmarks : (L, 2) [m]; sensor : RangeBearingSensor (σ_r, σ_φ)

    Returns
    -------
    mean, cov : the posterior
    nis : ndarray, shape (...) — normalised innovation squared ``νᵀ S⁻¹ ν`` over the valid rows
        (χ² with ``2·n_valid`` degrees of freedom for a consistent filter)
    n_valid : ndarray of int, shape (...)
    """
    p = check_last_axis("mean", mean, 3)
    zz = check_finite("z", z)
    ok = np.asarray(valid, dtype=bool)
    L = zz.shape[-2]
    okf = np.repeat(ok, 2, axis=-1)  # (..., 2L)
    zf = np.where(okf, zz.reshape(*zz.shape[:-2], 2 * L), 0.0)
    R = np.where(okf, np.tile([sensor.range_std**2, sensor.bearing_std**2], L), 1.0)
    R = R[..., :, None] * np.eye(2 * L)

    def h(x: Array) -> Array:
        return np.where(okf, landmark_h(x, landmarks).reshape(*x.shape[:-1], 2 * L), 0.0)

    def H_of(x: Array) -> Array:
        return np.where(okf[..., None], landmark_jacobian(x, landmarks).reshape(*x.shape[:-1], 2 * L, 3), 0.0)

    angular = np.tile([False, True], L)
    xn, Pn, nu, S = ekf_update(p, cov, zf, h, H_of, R, angular)
    nis = (nu[..., None, :] @ np.linalg.solve(S, nu[..., None]))[..., 0, 0]
    return xn, Pn, nis, ok.sum(axis=-1)


# ============================================================================= runner


@dataclass(frozen=True)
class EKFConfig:
    """Options of EKF localization.

    Attributes
    ----------
    motion : Motion — ``"wheels"`` (Method A) or ``"velocity"`` (linearised velocity model)
    association : {"known", "ml"} — true correspondences or maximum likelihood
    """

    motion: Motion = field(default_factory=Motion)
    association: str = "known"

    def __post_init__(self) -> None:
        check_choice("ekf.motion.model", self.motion.model, ("wheels", "velocity"))
        check_choice("association", self.association, ASSOCIATIONS)


def _ekf_predict(mean: Array, cov: Array, run: SimulatedRun, k: int, m: Motion) -> tuple[Array, Array]:
    """Prediction of step ``k → k+1`` with the configured model."""
    if m.model == "wheels":
        return ekf_predict_wheels(mean, cov, run.ds_r[k], run.ds_l[k], m.k_r, m.k_l, run.track)
    return ekf_predict_velocity(mean, cov, run.controls[k], run.dt, m.alpha_array, m.scaling)


def run_ekf(
    run: SimulatedRun,
    world: World,
    sensor: RangeBearingSensor,
    config: EKFConfig | None = None,
    start: Start | None = None,
    *,
    keep: Sequence[int] = (),
    on_step: StepCallback | None = None,
) -> FilterResult:
    """EKF localization along a simulated run (landmark sensor).

    At step 0 the belief is ``start``'s Gaussian, corrected by the measurements of
    step 0; every later step predicts with the measured travels of the step before
    and corrects with the step's measurements. Diagnostics: ``nis``, ``n_measurements``,
    ``wrong_associations``. The state passed to ``on_step`` is the mean and covariance.
    """
    cfg = config or EKFConfig()
    st = start or Start(pose=tuple(run.true_poses[0]))  # type: ignore[arg-type]
    rec = StepRecorder("ekf", run, check_keep(keep, run.n_steps), on_step)
    mean, cov = st.gaussian(world)
    for k in range(run.n_steps + 1):
        rec.tic()
        if k > 0:
            mean, cov = _ekf_predict(mean, cov, run, k - 1, cfg.motion)
        z, lm, wrong = landmark_measurements(run, world, sensor, k, cfg.association, mean, cov)
        nis = 0.0
        if z.shape[0]:
            mean, cov, nis_, _ = ekf_update_landmarks(mean, cov, z, np.ones(z.shape[0], bool), lm, sensor)
            nis = float(nis_)
        rec.toc(k)
        shown = np.array([mean[0], mean[1], wrap_angle(mean[2])])
        rec.record(k, shown, cov, None, {}, nis=nis, n_measurements=z.shape[0], wrong_associations=wrong)
    return rec.result(gaussian_region_flags(rec.mean, rec.cov, run.true_poses))  # every step at once


def run_ekf_batch(
    runs: Sequence[SimulatedRun],
    world: World,
    sensor: RangeBearingSensor,
    config: EKFConfig | None = None,
    start: Start | None = None,
) -> tuple[Array, Array]:
    """EKF localization of many runs at once (known correspondences), batched over the runs.

    The runs must have the same number of steps and Δt (e.g. the seeded repetitions of
    one experiment, for the NEES averaged over runs). Every step is one batched
    prediction and one stacked, masked update for all runs.

    Returns
    -------
    mean : ndarray, shape (R, N+1, 3) — θ unwrapped; cov : ndarray, shape (R, N+1, 3, 3)
    """
    cfg = config or EKFConfig()
    if cfg.association != "known":
        raise ValueError(f"association must be 'known' for the batched EKF (allowed: 'known'), got {cfg.association!r}")
    n_steps = {r.n_steps for r in runs}
    if len(n_steps) != 1 or len({r.dt for r in runs}) != 1:
        raise ValueError(f"runs must share the number of steps and dt (allowed: one N, one dt), got N in {sorted(n_steps)}")
    N, R = runs[0].n_steps, len(runs)
    m0, c0 = (start or Start(pose=tuple(runs[0].true_poses[0]))).gaussian(world)  # type: ignore[arg-type]
    mean, cov = np.empty((R, N + 1, 3)), np.empty((R, N + 1, 3, 3))
    m, c = np.broadcast_to(m0, (R, 3)).copy(), np.broadcast_to(c0, (R, 3, 3)).copy()
    z = np.stack([r.landmark_z for r in runs])  # (R, N+1, L, 2)
    valid = np.stack([r.landmark_valid for r in runs])
    sr, sl = np.stack([r.ds_r for r in runs]), np.stack([r.ds_l for r in runs])
    u = np.stack([r.controls for r in runs])
    mo = cfg.motion
    for k in range(N + 1):
        if k > 0:
            if mo.model == "wheels":
                m, c = ekf_predict_wheels(m, c, sr[:, k - 1], sl[:, k - 1], mo.k_r, mo.k_l, runs[0].track)
            else:
                G, Vj = velocity_jacobians(m, u[:, k - 1], runs[0].dt)
                M = velocity_variances(u[:, k - 1], mo.alpha_array, mo.scaling)
                m = velocity_forward(m, u[:, k - 1, 0], u[:, k - 1, 1], 0.0, runs[0].dt)
                c = G @ c @ _T(G) + (Vj * M[:, None, :]) @ _T(Vj)
        if valid[:, k].any():
            m, c, _, _ = ekf_update_landmarks(m, c, z[:, k], valid[:, k], world.landmarks, sensor)
        mean[:, k], cov[:, k] = m, c
    return mean, cov
