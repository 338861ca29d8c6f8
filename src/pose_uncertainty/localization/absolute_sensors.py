"""Absolute sensing (Skalka 2011 §4.1, §4.3) as measurement models for the EKF, the histogram and the particle filter.

Four sensors, each a frozen dataclass with the same five members, so one model serves every filter:

* ``h(poses)`` — the noiseless measurement, poses (..., 3) → (..., m);
* ``jacobian(poses)`` — ``∂h/∂(x, y, θ)``, (..., m, 3) (for the EKF);
* ``log_likelihood(poses, z)`` — ``log p(z | x)`` of one measurement ``z`` (m,) at a batch of poses,
  (...,) (for the grid cells of the histogram filter and the particles of the particle filter);
* ``sample(poses, rng)`` — measurements drawn from ``p(z | x)``, (..., m);
* ``R`` and ``angular`` — the Gaussian noise covariance (m, m) the EKF assumes and which components
  are angles (their innovations wrapped).

Models (Skalka 2011 §4.1.1: active beacons, trilateration from ranges gives no heading, triangulation
from bearings; §4.1.1.1 satellite systems; §4.3 the compass, referred to magnetic north and disturbed
near iron and electric machines)::

    RangeBeacons     h_j = ‖b_j − (x, y)‖                                    + N(0, σ_r²)
    BearingBeacons   h_j = wrap(atan2(b_jy − y, b_jx − x) − θ)               + wrapped N(0, σ_φ²)
    Gnss             h   = (x, y) + β                                        + N(0, σ²I) w.p. 1 − ε, N(0, σ_o²I) w.p. ε
    Compass          h   = wrap(θ + β_θ + Σ_i a_i exp(−‖(x, y) − c_i‖²/(2 s_i²)))  + wrapped N(0, σ_c²)

``β`` is the receiver's systematic offset (e.g. a datum or multipath error common to the run), ``ε`` the
share of outliers (reflected signals, Skalka 2011 §4.1.1); the compass's local disturbances are
Gaussian bumps of the deviation with amplitude ``a_i`` [rad] and radius ``s_i`` [m]. A filter given a
model without the bias or the disturbances is the mis-modelled filter. Angular densities are the
wrapped normal (three images of the normal: for σ ≤ 1 rad the next ones weigh below e⁻⁴⁴ of the sum).

In the filters
--------------
* EKF: :func:`ekf_update_absolute` (an :func:`~pose_uncertainty.localization.ekf.ekf_update` with the
  model's ``h``, ``jacobian``, ``R``; optional χ² gate on the innovation, which rejects outliers);
* histogram: :func:`grid_log_likelihood` at every cell centre, then
  :func:`~pose_uncertainty.localization.histogram.hf_correct`;
* particle: ``sensor.log_likelihood(particles, z)``, then
  :func:`~pose_uncertainty.localization.particle.pf_correct`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.grids import Grid
from ..core.kinematics import wrap_angle
from ..core.stats import chi2_ppf
from ..core.validation import check_finite, check_last_axis, check_nonnegative, check_positive
from .ekf import ekf_update

__all__ = [
    "AbsoluteSensor",
    "BearingBeacons",
    "Compass",
    "Gnss",
    "RangeBeacons",
    "ekf_update_absolute",
    "grid_log_likelihood",
    "wrapped_normal_logpdf",
]

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
_LOG_2PI = math.log(2.0 * math.pi)
_TWO_PI = 2.0 * math.pi


class AbsoluteSensor(Protocol):
    """The members every absolute sensor model has (module docs)."""

    @property
    def R(self) -> Array:
        """The Gaussian noise covariance the EKF assumes, shape (m, m)."""

    @property
    def angular(self) -> BoolArray:
        """Which of the m components are angles, shape (m,)."""

    def h(self, poses: ArrayLike) -> Array:
        """Noiseless measurement, (..., 3) → (..., m)."""

    def jacobian(self, poses: ArrayLike) -> Array:
        """``∂h/∂(x, y, θ)``, (..., 3) → (..., m, 3)."""

    def log_likelihood(self, poses: ArrayLike, z: ArrayLike) -> Array:
        """``log p(z | x)`` of one measurement (m,) at poses (..., 3), shape (...)."""

    def sample(self, poses: ArrayLike, rng: np.random.Generator) -> Array:
        """Measurements drawn from ``p(z | x)``, shape (..., m)."""


def wrapped_normal_logpdf(e: ArrayLike, std: float) -> Array:
    """``log Σ_k N(e + 2πk; 0, σ²)`` over the images ``k = −1, 0, 1`` [1/rad], any shape of ``e`` [rad], σ ≤ 1."""
    a = wrap_angle(e)[..., None] + _TWO_PI * np.arange(-1, 2)
    q = -0.5 * (a / std) ** 2
    top = q.max(axis=-1)
    return np.asarray(top + np.log(np.exp(q - top[..., None]).sum(axis=-1)) - 0.5 * _LOG_2PI - math.log(std))


def _beacons(b: ArrayLike) -> Array:
    arr = check_finite("beacons", check_last_axis("beacons", b, 2)).reshape(-1, 2)
    if arr.shape[0] == 0:
        raise ValueError("beacons must hold at least one beacon (allowed: shape (B, 2), B >= 1)")
    return arr


def _offsets(poses: ArrayLike, beacons: Array) -> tuple[Array, Array, Array]:
    """``(dx, dy, q)`` of every beacon from every pose, each (..., B); ``q`` floored at 10⁻¹⁸ m²."""
    p = check_last_axis("poses", poses, 3)
    dx = beacons[:, 0] - p[..., 0, None]
    dy = beacons[:, 1] - p[..., 1, None]
    return dx, dy, np.maximum(dx * dx + dy * dy, 1e-18)


def _measurement(z: ArrayLike, m: int) -> Array:
    return check_finite("z", check_last_axis("z", z, m))


@dataclass(frozen=True, eq=False)
class RangeBeacons:
    """Ranges to beacons at known positions (trilateration: the heading is not observed).

    Attributes
    ----------
    beacons : ndarray, shape (B, 2) [m]; range_std : float [m], > 0
    """

    beacons: Array
    range_std: float = 0.1

    def __post_init__(self) -> None:
        object.__setattr__(self, "beacons", _beacons(self.beacons))
        object.__setattr__(self, "range_std", float(check_positive("range_std", self.range_std)))

    @property
    def R(self) -> Array:
        """``σ_r² I``, shape (B, B)."""
        return np.eye(self.beacons.shape[0]) * self.range_std**2

    @property
    def angular(self) -> BoolArray:
        """No angular component, shape (B,)."""
        return np.zeros(self.beacons.shape[0], dtype=bool)

    def h(self, poses: ArrayLike) -> Array:
        """Ranges, shape (..., B) [m]."""
        dx, dy, _ = _offsets(poses, self.beacons)
        return np.asarray(np.hypot(dx, dy))

    def jacobian(self, poses: ArrayLike) -> Array:
        """Rows ``(−Δx/r, −Δy/r, 0)``, shape (..., B, 3)."""
        dx, dy, q = _offsets(poses, self.beacons)
        r = np.sqrt(q)
        return np.stack([-dx / r, -dy / r, np.zeros_like(r)], axis=-1)

    def log_likelihood(self, poses: ArrayLike, z: ArrayLike) -> Array:
        """``Σ_j log N(z_j; h_j, σ_r²)``, shape (...)."""
        e = _measurement(z, self.beacons.shape[0]) - self.h(poses)
        s = self.range_std
        return np.asarray(np.sum(-0.5 * (e / s) ** 2 - 0.5 * _LOG_2PI - math.log(s), axis=-1))

    def sample(self, poses: ArrayLike, rng: np.random.Generator) -> Array:
        """Noisy ranges, shape (..., B) (may be negative for a robot next to a beacon, as the model)."""
        r = self.h(poses)
        return r + self.range_std * rng.standard_normal(r.shape)


@dataclass(frozen=True, eq=False)
class BearingBeacons:
    """Bearings to beacons at known positions, relative to the heading (triangulation).

    Attributes
    ----------
    beacons : ndarray, shape (B, 2) [m]; bearing_std : float [rad], in (0, 1]
    """

    beacons: Array
    bearing_std: float = 0.02

    def __post_init__(self) -> None:
        object.__setattr__(self, "beacons", _beacons(self.beacons))
        s = float(check_positive("bearing_std", self.bearing_std))
        if s > 1.0:
            raise ValueError(f"bearing_std must be <= 1 rad (allowed: (0, 1]), got {s}")
        object.__setattr__(self, "bearing_std", s)

    @property
    def R(self) -> Array:
        """``σ_φ² I``, shape (B, B)."""
        return np.eye(self.beacons.shape[0]) * self.bearing_std**2

    @property
    def angular(self) -> BoolArray:
        """Every component is an angle, shape (B,)."""
        return np.ones(self.beacons.shape[0], dtype=bool)

    def h(self, poses: ArrayLike) -> Array:
        """Bearings, shape (..., B) [rad], in (−π, π]."""
        dx, dy, _ = _offsets(poses, self.beacons)
        return wrap_angle(np.arctan2(dy, dx) - check_last_axis("poses", poses, 3)[..., 2, None])

    def jacobian(self, poses: ArrayLike) -> Array:
        """Rows ``(Δy/q, −Δx/q, −1)``, shape (..., B, 3)."""
        dx, dy, q = _offsets(poses, self.beacons)
        return np.stack([dy / q, -dx / q, -np.ones_like(q)], axis=-1)

    def log_likelihood(self, poses: ArrayLike, z: ArrayLike) -> Array:
        """``Σ_j log WN(z_j − h_j; σ_φ)``, shape (...)."""
        e = _measurement(z, self.beacons.shape[0]) - self.h(poses)
        return np.asarray(wrapped_normal_logpdf(e, self.bearing_std).sum(axis=-1))

    def sample(self, poses: ArrayLike, rng: np.random.Generator) -> Array:
        """Noisy bearings, shape (..., B), wrapped."""
        b = self.h(poses)
        return wrap_angle(b + self.bearing_std * rng.standard_normal(b.shape))


@dataclass(frozen=True, eq=False)
class Gnss:
    """An absolute position fix with a systematic offset and outliers.

    Attributes
    ----------
    position_std : float [m], > 0 — σ of each axis (inliers)
    bias : ndarray, shape (2,) [m] — systematic offset β
    outlier_prob : float in [0, 1) — ε
    outlier_std : float [m], > 0 — σ_o of each axis (outliers)
    """

    position_std: float = 1.0
    bias: Array = field(default_factory=lambda: np.zeros(2))
    outlier_prob: float = 0.0
    outlier_std: float = 20.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "position_std", float(check_positive("position_std", self.position_std)))
        object.__setattr__(self, "outlier_std", float(check_positive("outlier_std", self.outlier_std)))
        object.__setattr__(self, "bias", check_finite("bias", check_last_axis("bias", self.bias, 2)).reshape(2))
        eps = float(check_nonnegative("outlier_prob", self.outlier_prob))
        if eps >= 1.0:
            raise ValueError(f"outlier_prob must be < 1 (allowed: [0, 1)), got {eps}")
        object.__setattr__(self, "outlier_prob", eps)

    @property
    def R(self) -> Array:
        """The inliers' ``σ² I``, shape (2, 2)."""
        return np.eye(2) * self.position_std**2

    @property
    def angular(self) -> BoolArray:
        """No angular component, shape (2,)."""
        return np.zeros(2, dtype=bool)

    def h(self, poses: ArrayLike) -> Array:
        """``(x, y) + β``, shape (..., 2) [m]."""
        return check_last_axis("poses", poses, 3)[..., :2] + self.bias

    def jacobian(self, poses: ArrayLike) -> Array:
        """``[[1, 0, 0], [0, 1, 0]]``, shape (..., 2, 3)."""
        p = check_last_axis("poses", poses, 3)
        return np.broadcast_to(np.eye(2, 3), (*p.shape[:-1], 2, 3)).copy()

    def log_likelihood(self, poses: ArrayLike, z: ArrayLike) -> Array:
        """``log[(1 − ε) N(z; h, σ²I) + ε N(z; h, σ_o²I)]``, shape (...)."""
        d2 = np.sum((_measurement(z, 2) - self.h(poses)) ** 2, axis=-1)
        s, so, eps = self.position_std, self.outlier_std, self.outlier_prob
        inlier = math.log1p(-eps) - d2 / (2 * s * s) - _LOG_2PI - 2 * math.log(s)
        if eps == 0.0:
            return np.asarray(inlier)
        outlier = math.log(eps) - d2 / (2 * so * so) - _LOG_2PI - 2 * math.log(so)
        return np.asarray(np.logaddexp(inlier, outlier))

    def sample(self, poses: ArrayLike, rng: np.random.Generator) -> Array:
        """Fixes, shape (..., 2): inliers with probability 1 − ε, outliers otherwise."""
        c = self.h(poses)
        out = rng.random(c.shape[:-1]) < self.outlier_prob
        std = np.where(out, self.outlier_std, self.position_std)[..., None]
        return c + std * rng.standard_normal(c.shape)


@dataclass(frozen=True, eq=False)
class Compass:
    """A magnetic compass: absolute heading with a bias and local disturbances.

    Attributes
    ----------
    heading_std : float [rad], in (0, 1]
    bias : float [rad] — offset of magnetic from map north (declination, mounting)
    disturbances : ndarray, shape (D, 4) — rows ``(c_x [m], c_y [m], a [rad], s [m])``, s > 0
    """

    heading_std: float = 0.05
    bias: float = 0.0
    disturbances: Array = field(default_factory=lambda: np.zeros((0, 4)))

    def __post_init__(self) -> None:
        s = float(check_positive("heading_std", self.heading_std))
        if s > 1.0:
            raise ValueError(f"heading_std must be <= 1 rad (allowed: (0, 1]), got {s}")
        object.__setattr__(self, "heading_std", s)
        object.__setattr__(self, "bias", float(check_finite("bias", self.bias)))
        d = check_finite("disturbances", self.disturbances).reshape(-1, 4)
        if d.shape[0]:
            check_positive("disturbances radius", d[:, 3])
        object.__setattr__(self, "disturbances", d)

    @property
    def R(self) -> Array:
        """``[[σ_c²]]``, shape (1, 1)."""
        return np.array([[self.heading_std**2]])

    @property
    def angular(self) -> BoolArray:
        """The one component is an angle, shape (1,)."""
        return np.ones(1, dtype=bool)

    def deviation(self, poses: ArrayLike) -> tuple[Array, Array]:
        """Local deviation ``δ(x, y)`` [rad], shape (...), and its gradient ``∂δ/∂(x, y)``, shape (..., 2)."""
        p = check_last_axis("poses", poses, 3)
        d = self.disturbances
        ex = p[..., 0, None] - d[:, 0]
        ey = p[..., 1, None] - d[:, 1]
        bump = d[:, 2] * np.exp(-(ex * ex + ey * ey) / (2 * d[:, 3] ** 2))  # (..., D)
        grad = np.stack([-(bump * ex / d[:, 3] ** 2).sum(-1), -(bump * ey / d[:, 3] ** 2).sum(-1)], -1)
        return np.asarray(bump.sum(axis=-1)), grad

    def h(self, poses: ArrayLike) -> Array:
        """Heading reading, shape (..., 1) [rad], in (−π, π]."""
        delta, _ = self.deviation(poses)
        return wrap_angle(check_last_axis("poses", poses, 3)[..., 2] + self.bias + delta)[..., None]

    def jacobian(self, poses: ArrayLike) -> Array:
        """``[∂δ/∂x, ∂δ/∂y, 1]``, shape (..., 1, 3)."""
        _, grad = self.deviation(poses)
        return np.concatenate([grad, np.ones((*grad.shape[:-1], 1))], axis=-1)[..., None, :]

    def log_likelihood(self, poses: ArrayLike, z: ArrayLike) -> Array:
        """``log WN(z − h; σ_c)``, shape (...)."""
        e = _measurement(z, 1)[..., 0] - self.h(poses)[..., 0]
        return wrapped_normal_logpdf(e, self.heading_std)

    def sample(self, poses: ArrayLike, rng: np.random.Generator) -> Array:
        """Noisy headings, shape (..., 1), wrapped."""
        c = self.h(poses)
        return wrap_angle(c + self.heading_std * rng.standard_normal(c.shape))


def ekf_update_absolute(
    mean: ArrayLike, cov: ArrayLike, z: ArrayLike, sensor: AbsoluteSensor, gate: float | None = None
) -> tuple[Array, Array, Array, BoolArray]:
    """EKF correction with one absolute measurement, batched over leading dimensions.

    Parameters
    ----------
    mean : (..., 3); cov : (..., 3, 3); z : (..., m); sensor : an absolute sensor model
    gate : float in (0, 1), optional — reject the measurement when its normalised innovation
        ``νᵀ S⁻¹ ν`` exceeds the χ² quantile of ``gate`` with ``m`` degrees of freedom (outliers)

    Returns
    -------
    mean, cov : the posterior (the prior where rejected)
    nis : ndarray, shape (...) — ``νᵀ S⁻¹ ν``; accepted : ndarray of bool, shape (...)
    """
    mu, P = check_last_axis("mean", mean, 3), check_finite("cov", cov)
    xn, Pn, nu, S = ekf_update(mu, P, z, sensor.h, sensor.jacobian, sensor.R, sensor.angular)
    nis = (nu[..., None, :] @ np.linalg.solve(S, nu[..., None]))[..., 0, 0]
    ok = np.ones(nis.shape, dtype=bool) if gate is None else nis <= chi2_ppf(gate, nu.shape[-1])
    return (np.where(ok[..., None], xn, mu), np.where(ok[..., None, None], Pn, P), np.asarray(nis),
            np.asarray(ok))  # fmt: skip


def grid_log_likelihood(sensor: AbsoluteSensor, grid: Grid, z: ArrayLike) -> Array:
    """``log p(z | x)`` at every cell centre of a pose grid, shape (nx, ny, nθ) (for ``hf_correct``).

    Evaluated on blocks of x rows of about 2¹⁶ cells (the model's temporaries stay small).
    """
    Y, TH = np.meshgrid(grid.y, grid.theta, indexing="ij")
    out = np.empty(grid.shape)
    rows = max(1, (1 << 16) // (grid.ny * grid.ntheta))
    for i0 in range(0, grid.nx, rows):  # blocks of rows, every cell of a block at once
        x = grid.x[i0 : i0 + rows, None, None]
        poses = np.stack(np.broadcast_arrays(x, Y[None], TH[None]), axis=-1)
        out[i0 : i0 + rows] = sensor.log_likelihood(poses, z)
    return out
