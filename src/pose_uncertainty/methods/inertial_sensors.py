"""Inertial sensor error models and the kernels the inertial dead-reckoning schemes share.

Skalka 2011 §3.4 (inertial navigation) and §3.3 (other relative sensors). Error models (one draw
per run for ``bias_std`` and ``scale_std``; every step otherwise)::

    gyroscope        ω_m = (1 + s_g) ω + b_g + n_g,   n_g ~ N(0, σ_g²/Δt),   b_g' = b_g + w_g,  w_g ~ N(0, σ_bg² Δt)
    accelerometers   f_m = f + b_a + n_a,             n_a ~ N(0, σ_a²/Δt·I), b_a' = b_a + w_a,  w_a ~ N(0, σ_ba² Δt·I)

with ``s_g ~ N(0, scale_std²)``, ``b_g ~ N(0, bias_std²)`` (likewise ``b_a``) at the start.
``white_std`` is the noise density (σ_g [rad/√s]: angle random walk, the heading variance grows as
σ_g² t; σ_a [m/s/√s]: velocity random walk), ``bias_rw_std`` the bias random-walk density.

The schemes are :mod:`pose_uncertainty.methods.inertial` (strapdown INS) and
:mod:`pose_uncertainty.methods.gyro_odometry` (gyro-aided odometry); each has a Method A
covariance propagation (:func:`propagate_linearised` of its own Jacobians) and a Monte Carlo
sampler; :func:`position_growth` fits growth laws to the propagated position error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.stats import fit_growth
from ..core.validation import check_finite, check_nonnegative

__all__ = [
    "AccelErrors",
    "GyroErrors",
    "exclusive_cumsum",
    "initial_covariance",
    "position_growth",
    "propagate_linearised",
    "sample_gyro_errors",
    "step_indices",
]

Array = NDArray[np.float64]


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


def exclusive_cumsum(a: Array) -> Array:
    """``out[..., k] = Σ_{j<k} a[..., j]``, same shape as ``a``."""
    out = np.zeros_like(a)
    np.cumsum(a[..., :-1], axis=-1, out=out[..., 1:])
    return out



def propagate_linearised(F: Array, G: Array, Q: Array, S0: Array) -> Array:
    """``Σ_{k+1} = F_k Σ_k F_kᵀ + G_k diag(Q_k) G_kᵀ`` for F (N, d, d), G (N, d, m), Q (N, m): (N+1, d, d)."""
    n, d = F.shape[0], F.shape[-1]
    noise = (G * Q[:, None, :]) @ np.swapaxes(G, -1, -2)  # every step's G Q Gᵀ at once
    covs = np.empty((n + 1, d, d))
    covs[0] = S0
    for k in range(n):  # the recursion itself (9×9 per step)
        covs[k + 1] = F[k] @ covs[k] @ F[k].T + noise[k]
    return covs


def initial_covariance(d: int, per_run: dict[int, float], cov0: ArrayLike | None, n_pose: int) -> Array:
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


def step_indices(checkpoints: ArrayLike | None, n_steps: int) -> NDArray[np.intp]:
    """Checkpoints as step indices in [0, N], shape (C,) (None: the end only); ValueError naming them otherwise."""
    idx = np.array([n_steps] if checkpoints is None else checkpoints, dtype=np.intp).reshape(-1)
    if idx.size == 0 or idx.min() < 0 or idx.max() > n_steps:
        raise ValueError(f"checkpoints must be step indices in [0, {n_steps}] (allowed: 0..N), got {idx.tolist()}")
    return idx


def sample_gyro_errors(gyro: GyroErrors, n: int, n_steps: int, dt: float,
                rng: np.random.Generator) -> tuple[Array, Array, Array]:  # fmt: skip
    """Draw ``n`` runs of gyro errors over ``n_steps`` steps of ``dt`` [s].

    Returns
    -------
    bias : ndarray, shape (n, N+1) — ``b_g`` before each step and after the last [rad/s]
    scale : ndarray, shape (n,) — ``s_g`` [1]; white : ndarray, shape (n, N) — ``n_g`` of each step [rad/s]
    """
    b0 = gyro.bias_std * rng.standard_normal(n)
    scale = gyro.scale_std * rng.standard_normal(n)
    white = (gyro.white_std / np.sqrt(dt)) * rng.standard_normal((n, n_steps))
    walk = (gyro.bias_rw_std * np.sqrt(dt)) * rng.standard_normal((n, n_steps))
    bias = b0[:, None] + np.concatenate([np.zeros((n, 1)), np.cumsum(walk, axis=1)], axis=1)
    return bias, scale, white



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
