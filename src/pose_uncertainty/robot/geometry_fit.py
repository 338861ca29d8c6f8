"""Systematic errors: each wheel's radius and the track, by least squares on segment increments.

Parameters ``θ = (r_l, r_r, b)`` [m]. The odometry relative pose ``g_j(θ)`` of each
segment (:func:`.segments.predict`) is fitted to the ground truth's ``z_j`` by
generalised least squares, weighting each residual by the inverse of its covariance
under the noise model (:mod:`.noise_fit`)::

    θ̂ = argmin Σ_j r_j(θ)ᵀ Σ_j⁻¹ r_j(θ),      r_j = z_j − g_j(θ)

(Gauss–Newton, the Jacobian by central differences in one batched call). Straight
driving fixes the mean radius, heading changes fix ``(r_r Δφ_r − r_l Δφ_l)/b``, and the
curvature of straight legs ``(r_r − r_l)/b``: a path with both (a UMBmark square does)
identifies all three. The covariance of ``θ̂`` is ``(Σ_j J_jᵀ Σ_j⁻¹ J_j)⁻¹`` (the
Fisher information of the mean parameters; asymptotically independent of the noise
parameters'), and Borenstein & Feng's ratios follow by the delta method::

    E_d = D_R/D_L = r_r/r_l,        E_b = b / b_nominal

with 95 % intervals ``value ± 1.96 se``.

The nominal geometry
--------------------
``E_b`` and the controller's multipliers are relative to what the robot's odometry
assumes. Given in the robot file, or else read off the robot's own odometry topic
(:func:`nominal_from_odometry`): its increments are exactly the nominal geometry applied
to the wheel angles, ``Δs = (r_r Δφ_r + r_l Δφ_l)/2`` (the arc length, from the chord of
each step ``c = Δs·sinc(Δθ/2)``) and ``Δθ = (r_r Δφ_r − r_l Δφ_l)/b`` — linear least
squares.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core import se2
from ..core.kinematics import sinc
from .align import AlignedRecording
from .segments import Segments, predict, residuals

__all__ = ["GEOMETRY_NAMES", "GeometryFit", "fit_geometry", "geometry_jacobian", "nominal_from_odometry"]

GEOMETRY_NAMES: tuple[str, ...] = ("wheel_radius_left", "wheel_radius_right", "track")


@dataclass(frozen=True)
class GeometryFit:
    """``θ̂ = (r_l, r_r, b)`` [m], its covariance (3, 3), the nominal geometry and the ratios."""

    theta: NDArray[np.float64]
    cov: NDArray[np.float64]
    nominal: tuple[float, float, float]
    iterations: int

    def quantities(self, level: float = 0.95) -> dict[str, dict[str, Any]]:
        """E_d, E_b and the three lengths, each ``{value, ci95, std_error, unit}``."""
        from scipy.special import ndtri  # imported where used (0.2 s)

        z = float(ndtri(0.5 + level / 2.0))
        rl, rr, b = (float(v) for v in self.theta)
        b_nom = self.nominal[2]
        # gradients of E_d = r_r/r_l and E_b = b/b_nom with respect to (r_l, r_r, b)
        grads = {
            "E_d": (rr / rl, np.array([-rr / rl**2, 1.0 / rl, 0.0]), "1"),
            "E_b": (b / b_nom, np.array([0.0, 0.0, 1.0 / b_nom]), "1"),
            "wheel_radius_left": (rl, np.array([1.0, 0.0, 0.0]), "m"),
            "wheel_radius_right": (rr, np.array([0.0, 1.0, 0.0]), "m"),
            "track": (b, np.array([0.0, 0.0, 1.0]), "m"),
        }
        out = {}
        for name, (value, g, unit) in grads.items():
            se = math.sqrt(max(float(g @ self.cov @ g), 0.0))
            out[name] = {"value": value, "ci95": [value - z * se, value + z * se], "std_error": se, "unit": unit}
        return out


def geometry_jacobian(seg: Segments, theta: NDArray) -> tuple[NDArray, NDArray]:
    """g(θ) (J, 3) and ∂r/∂θ = −∂g/∂θ (J, 3, 3) by central differences (step 10⁻⁶ θ)."""
    h = 1e-6 * np.asarray(theta, dtype=np.float64)
    probes = np.concatenate([theta[None], theta + np.diag(h), theta - np.diag(h)])  # (7, 3)
    g = predict(seg, probes[:, 0], probes[:, 1], probes[:, 2])  # (7, J, 3)
    dg = (g[1:4] - g[4:7]) / (2.0 * h[:, None, None])  # (3, J, 3)
    return g[0], -np.moveaxis(dg, 0, -1)


def fit_geometry(
    seg: Segments,
    start: tuple[float, float, float],
    Sigma: NDArray[np.float64],
    nominal: tuple[float, float, float],
    max_iter: int = 20,
) -> GeometryFit:
    """GLS ``(r_l, r_r, b)`` from the segments (module docstring).

    Parameters
    ----------
    seg : Segments; start : (r_l, r_r, b) [m] — the first guess
    Sigma : (J, 3, 3) — residual covariances (the weights are their inverses)
    nominal : (r_l, r_r, b) [m] — what the robot's odometry assumes (for E_b)
    """
    theta = np.array(start, dtype=np.float64)
    W = np.linalg.inv(Sigma)
    info = np.eye(3)
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is reported
        g, Jr = geometry_jacobian(seg, theta)
        r = residuals(seg, g)
        info = np.einsum("jai,jab,jbk->ik", Jr, W, Jr)  # Σ Jᵀ W J
        grad = np.einsum("jai,jab,jb->i", Jr, W, r)  # Σ Jᵀ W r
        step = -np.linalg.solve(info, grad)
        theta = theta + step
        if np.all(np.abs(step) < 1e-12 + 1e-10 * np.abs(theta)):
            break
    _, Jr = geometry_jacobian(seg, theta)
    info = np.einsum("jai,jab,jbk->ik", Jr, W, Jr)
    return GeometryFit(theta=theta, cov=np.linalg.inv(info), nominal=nominal, iterations=it)


def nominal_from_odometry(rec: AlignedRecording) -> tuple[float, float, float] | None:
    """The geometry the robot's own odometry uses, from its increments (module docstring).

    Odometry stamps are matched to wheel stamps (exactly equal, as a controller publishes
    them); None when fewer than 10 match or the drive does not identify the geometry.
    """
    if rec.odom_t is None or rec.odom_poses is None:
        return None
    idx = np.searchsorted(rec.t, rec.odom_t)
    idx = np.clip(idx, 0, rec.t.size - 1)
    same = np.abs(rec.t[idx] - rec.odom_t) < 1e-6
    if np.count_nonzero(same) < 10:
        return None
    wi, p = idx[same], rec.odom_poses[same]
    rel = se2.compose(se2.inverse(p[:-1]), p[1:])
    dth = np.diff(p[:, 2])
    chord = np.copysign(np.hypot(rel[:, 0], rel[:, 1]), rel[:, 0])
    ds = chord / sinc(dth / 2.0)
    dl, dr = np.diff(rec.phi_l[wi]), np.diff(rec.phi_r[wi])
    A = np.stack([dl / 2.0, dr / 2.0], axis=-1)
    moving = np.abs(ds) > 0
    if np.count_nonzero(moving) < 10:
        return None
    (rl, rr), *_ = np.linalg.lstsq(A[moving], ds[moving], rcond=None)
    turn = rr * dr - rl * dl
    turning = np.abs(dth) > 1e-9
    if np.count_nonzero(turning) < 5 or rl <= 0 or rr <= 0:
        return None
    b = float(np.sum(turn[turning] * dth[turning]) / np.sum(dth[turning] ** 2))
    return (float(rl), float(rr), b) if b > 0 else None
