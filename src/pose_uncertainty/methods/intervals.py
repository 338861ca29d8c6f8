"""Guaranteed dead reckoning with bounded wheel errors: interval arithmetic (Skalka 2011 §2.8).

Skalka 2011 §2.8 presents interval calculus as the alternative to probabilities: every quantity is
an interval that surely holds it (no distribution assumed, "not even uniform"), e.g. the finite
resolution of a quantised sensor; the result surely holds the robot, but is often too pessimistic
to be useful. This module measures how pessimistic, for wheel odometry (Jaulin et al. 2001,
*Applied Interval Analysis*, for the arithmetic).

Bounded errors
--------------
Each step ``k`` measures the wheel travels ``Δs_r, Δs_l`` with errors ``|e_r| ≤ w_r``,
``|e_l| ≤ w_l``, ``w = pulse/2 + slip_rel·|Δs|`` (encoder quantisation ± half a pulse, bounded
slip; :class:`BoundedWheelErrors`), independently per step. In body travel and turn the errors
``(e_s, e_θ) = ((e_r + e_l)/2, (e_r − e_l)/b)`` form the zonotope ``A_k η``, ``η ∈ [−1, 1]^m``
(:func:`wheel_error_generators`: ``m = 2`` columns ``(w_r/2, w_r/b)`` and ``(w_l/2, −w_l/b)``);
any other per-step error set of this form is allowed (e.g. ``A_k = (w_s, 0)ᵀ``: travel errors with
the heading known exactly). The true step is the midpoint step of :mod:`pose_uncertainty.core.kinematics`::

    x' = x + (Δs + e_s) cos(θ + (Δθ + e_θ)/2),   y' likewise with sin,   θ' = θ + Δθ + e_θ

Interval boxes (:func:`interval_dead_reckoning`)
------------------------------------------------
The natural interval extension of that step: ``[θ_k]`` is exact (a sum of independent errors,
radius ``R_k = r_θ0 + Σ_{j<k} r_θ,j``), and ``[x_{k+1}] = [x_k] + [Δs_k ± r_s,k]·cos([φ_k])``.
Because ``x`` enters only its own update, stepping box by box and summing the per-step
intervals in one cumulative sum give the same box; the sum is what this module computes (no
loop over steps). The overestimation is the dependency effect (the same heading errors appear
in every later step's ``cos``, which interval arithmetic treats as independent); the zonotopes
of :mod:`pose_uncertainty.methods.zonotopes` keep that dependency.

Every bound is widened outward by the rounding guard of its sum (:func:`rounding_guard`, Higham's
bound), so the enclosures hold in floating point too: the end box of the tests' S-curve contains the
box of codac 2.1.2's outward-rounded interval arithmetic, stepped one step at a time (8·10⁻¹⁴ m apart).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import (
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_positive,
    check_positive_int,
)

__all__ = [
    "BoundedPath",
    "BoundedWheelErrors",
    "IntervalBox",
    "bounded_path",
    "box_area",
    "check_error_generators",
    "check_path_inputs",
    "interval_cos",
    "interval_dead_reckoning",
    "interval_mul",
    "interval_sin",
    "midpoint_nominal",
    "rounding_guard",
    "sample_bounded_poses",
    "wheel_error_generators",
]

Array = NDArray[np.float64]
_TWO_PI = 2.0 * math.pi
#: Units in the last place allowed per term of a sum beyond the sum's own (n − 1)·u (Higham 2002, §4.2).
_ULPS_PER_TERM = 8.0


@dataclass(frozen=True)
class BoundedWheelErrors:
    """Bounds of the per-step wheel-travel errors: ``|e| ≤ pulse/2 + slip_rel·|Δs|`` for each wheel.

    Attributes
    ----------
    pulse : float [m], ≥ 0 — wheel travel of one encoder pulse (``πD/N``)
    slip_rel : float [1], ≥ 0 — bound of the slip relative to the step's travel
    """

    pulse: float = 0.0
    slip_rel: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "pulse", float(check_nonnegative("pulse", self.pulse)))
        object.__setattr__(self, "slip_rel", float(check_nonnegative("slip_rel", self.slip_rel)))

    @classmethod
    def encoder(cls, pulses_per_rev: int, wheel_diameter: float, slip_rel: float = 0.0) -> BoundedWheelErrors:
        """Bounds of an encoder of ``pulses_per_rev`` [1/rev] on wheels of ``wheel_diameter`` [m]."""
        n = check_positive_int("pulses_per_rev", pulses_per_rev)
        return cls(math.pi * float(check_positive("wheel_diameter", wheel_diameter)) / n, slip_rel)

    def half_width(self, ds: ArrayLike) -> Array:
        """Half-width ``pulse/2 + slip_rel·|Δs|`` [m] of a wheel's error for travels ``ds`` (any shape)."""
        return 0.5 * self.pulse + self.slip_rel * np.abs(check_finite("ds", ds))


def wheel_error_generators(ds_r: ArrayLike, ds_l: ArrayLike, track: float, errors: BoundedWheelErrors) -> Array:
    """Per-step error generators ``A_k`` in ``(Δs, Δθ)`` of bounded wheel errors, shape (N, 2, 2).

    Column 0 is the right wheel ``(w_r/2, w_r/b)``, column 1 the left ``(w_l/2, −w_l/b)``.
    """
    b = float(check_positive("track", track))
    wr, wl = errors.half_width(ds_r), errors.half_width(ds_l)
    return np.stack([np.stack([wr / 2, wl / 2], -1), np.stack([wr / b, -wl / b], -1)], -2)


def check_error_generators(gens: ArrayLike, n_steps: int) -> Array:
    """Per-step error generators as float64, shape (N, 2, m) (ValueError naming the shape otherwise)."""
    A = check_finite("error_generators", gens)
    if A.ndim != 3 or A.shape[0] != n_steps or A.shape[1] != 2:
        raise ValueError(f"error_generators must have shape ({n_steps}, 2, m), got shape {A.shape}")
    return A


# ============================================================================= interval arithmetic


def interval_mul(a_lo: ArrayLike, a_hi: ArrayLike, b_lo: ArrayLike, b_hi: ArrayLike) -> tuple[Array, Array]:
    """Product of intervals ``[a]·[b]`` (the extremes of the four end products), broadcast shapes."""
    p = np.stack(np.broadcast_arrays(*(np.multiply(u, v) for u in (a_lo, a_hi) for v in (b_lo, b_hi))))
    return p.min(axis=0), p.max(axis=0)


def interval_cos(lo: ArrayLike, hi: ArrayLike) -> tuple[Array, Array]:
    """Exact range of ``cos`` over ``[lo, hi]`` (lo ≤ hi, any shape) [rad → 1].

    The ends' values, raised to 1 where the interval holds a multiple of 2π and lowered to −1
    where it holds an odd multiple of π; ``[−1, 1]`` for an interval of width ≥ 2π.
    """
    a, b = check_finite("lo", lo), check_finite("hi", hi)
    ca, cb = np.cos(a), np.cos(b)
    top = np.ceil(a / _TWO_PI) <= np.floor(b / _TWO_PI)
    bottom = np.ceil((a - math.pi) / _TWO_PI) <= np.floor((b - math.pi) / _TWO_PI)
    wide = (b - a) >= _TWO_PI
    return np.where(bottom | wide, -1.0, np.minimum(ca, cb)), np.where(top | wide, 1.0, np.maximum(ca, cb))


def interval_sin(lo: ArrayLike, hi: ArrayLike) -> tuple[Array, Array]:
    """Exact range of ``sin`` over ``[lo, hi]``: :func:`interval_cos` of ``[lo − π/2, hi − π/2]``."""
    return interval_cos(check_finite("lo", lo) - 0.5 * math.pi, check_finite("hi", hi) - 0.5 * math.pi)


def rounding_guard(scale: ArrayLike, n_terms: ArrayLike) -> Array:
    """Outward widening [same unit] of a bound summed from ``n_terms`` terms of total magnitude ``scale``.

    A floating-point sum of ``n`` terms errs by at most ``(n − 1)·u·Σ|a_i|`` (``u = ε/2``, Higham 2002
    §4.2), and each term (a product of a cosine and a travel) by a few ulps of itself: the guard is
    ``(n + 8)·ε·scale``, for any shape of ``scale`` and ``n_terms``.
    """
    n = np.asarray(n_terms, dtype=np.float64)
    return (n + _ULPS_PER_TERM) * np.finfo(np.float64).eps * np.abs(check_finite("scale", scale)) + 1e-300


# ============================================================================= interval dead reckoning


@dataclass(frozen=True, eq=False)
class IntervalBox:
    """Guaranteed boxes of the pose along a path.

    Attributes
    ----------
    lo, hi : ndarray, shape (C, 3) — bounds of ``(x, y, θ)`` at each checkpoint [m, m, rad]
    steps : ndarray of int, shape (C,) — the checkpoints (step indices)
    """

    lo: Array
    hi: Array
    steps: NDArray[np.intp]

    def contains(self, poses: ArrayLike) -> NDArray[np.bool_]:
        """Whether poses (shape (..., C, 3), θ unwrapped as the path's) lie in the boxes, shape (..., C)."""
        p = check_last_axis("poses", poses, 3)
        return np.all((p >= self.lo) & (p <= self.hi), axis=-1)


def midpoint_nominal(ds: Array, dtheta: Array, start: Array) -> tuple[Array, Array, Array]:
    """Midpoint nominal path: heading before each step θ̄_k (N,), step heading φ̄_k (N,), poses (N+1, 3)."""
    theta = start[2] + np.concatenate([[0.0], np.cumsum(dtheta)])
    phi = theta[:-1] + 0.5 * dtheta
    x = start[0] + np.concatenate([[0.0], np.cumsum(ds * np.cos(phi))])
    y = start[1] + np.concatenate([[0.0], np.cumsum(ds * np.sin(phi))])
    return theta[:-1], phi, np.stack([x, y, theta], axis=-1)


def check_path_inputs(ds: ArrayLike, dtheta: ArrayLike, start: ArrayLike, start_radius: ArrayLike,
                 checkpoints: ArrayLike | None) -> tuple[Array, Array, Array, Array, NDArray[np.intp]]:  # fmt: skip
    """Validated ``Δs`` (N,), ``Δθ`` (N,), start (3,), start half-widths (3,) and checkpoints (C,)."""
    d = check_finite("ds", ds).reshape(-1)
    dth = check_finite("dtheta", dtheta).reshape(-1)
    if d.shape != dth.shape or d.size == 0:
        raise ValueError(f"ds and dtheta must have one shape (N,), N >= 1, got {d.shape} and {dth.shape}")
    p0 = check_finite("start", check_last_axis("start", start, 3))
    r0 = check_nonnegative("start_radius", check_last_axis("start_radius", start_radius, 3))
    idx = np.array([d.size] if checkpoints is None else checkpoints, dtype=np.intp).reshape(-1)
    if idx.size == 0 or idx.min() < 0 or idx.max() > d.size:
        raise ValueError(f"checkpoints must be step indices in [0, {d.size}] (allowed: 0..N), got {idx.tolist()}")
    return d, dth, p0, r0, idx


class BoundedPath(NamedTuple):
    """A path under bounded per-step errors: what both set methods (boxes, zonotopes) start from.

    ``ds, dtheta`` (N,) [m, rad], ``start, start_radius`` (3,), ``checkpoints`` (C,) as validated
    by :func:`check_path_inputs`; ``generators`` (N, 2, m) the ``A_k``; ``r_s, r_th`` (N,) the
    per-step error radii ``Σ_j |A_k[i, j]|`` of ``Δs`` and ``Δθ``; ``phi`` (N,) and ``nominal``
    (N+1, 3) from :func:`midpoint_nominal`; ``R`` (N+1,) the exact radius of the heading
    interval ``[θ_k]`` [rad] and ``R_phi`` (N,) that of the midpoint heading; ``travelled`` and
    ``turned`` (N+1,) the prefix sums of ``|Δs| + r_s`` and ``|Δθ| + r_th`` (the terms of the
    position and heading sums, for :func:`rounding_guard`).
    """

    ds: Array
    dtheta: Array
    start: Array
    start_radius: Array
    checkpoints: NDArray[np.intp]
    generators: Array
    r_s: Array
    r_th: Array
    phi: Array
    nominal: Array
    R: Array
    R_phi: Array
    travelled: Array
    turned: Array


def bounded_path(
    ds: ArrayLike, dtheta: ArrayLike, error_generators: ArrayLike, start: ArrayLike, start_radius: ArrayLike,
    checkpoints: ArrayLike | None,
) -> BoundedPath:  # fmt: skip
    """The validated inputs of a bounded-error dead reckoning with their radii and sums (:class:`BoundedPath`)."""
    d, dth, p0, r0, idx = check_path_inputs(ds, dtheta, start, start_radius, checkpoints)
    A = check_error_generators(error_generators, d.size)
    r_s, r_th = np.abs(A[:, 0]).sum(axis=-1), np.abs(A[:, 1]).sum(axis=-1)
    _, phi, nominal = midpoint_nominal(d, dth, p0)
    R = r0[2] + np.concatenate([[0.0], np.cumsum(r_th)])  # exact radius of [θ_k]
    travelled = np.concatenate([[0.0], np.cumsum(np.abs(d) + r_s)])
    turned = np.concatenate([[0.0], np.cumsum(np.abs(dth) + r_th)])  # Σ|Δθ| + R: the heading sum's terms
    return BoundedPath(d, dth, p0, r0, idx, A, r_s, r_th, phi, nominal, R, R[:-1] + 0.5 * r_th, travelled, turned)


def interval_dead_reckoning(
    ds: ArrayLike, dtheta: ArrayLike, error_generators: ArrayLike, *,
    start: ArrayLike = (0.0, 0.0, 0.0), start_radius: ArrayLike = (0.0, 0.0, 0.0),
    checkpoints: ArrayLike | None = None,
) -> IntervalBox:  # fmt: skip
    """Interval boxes of the pose under bounded per-step errors (module docs), no loop over steps.

    Parameters
    ----------
    ds, dtheta : array_like, shape (N,) — measured travel [m] and turn [rad] of each step
    error_generators : array_like, shape (N, 2, m) — ``A_k`` of the per-step errors in ``(Δs, Δθ)``
    start : array_like, shape (3,); start_radius : array_like, shape (3,) — half-widths of the start box
    checkpoints : sequence of int in [0, N], optional — default the end

    Returns
    -------
    IntervalBox with bounds (C, 3)
    """
    b = bounded_path(ds, dtheta, error_generators, start, start_radius, checkpoints)
    d, r_s, p0, r0, idx, R = b.ds, b.r_s, b.start, b.start_radius, b.checkpoints, b.R
    c_lo, c_hi = interval_cos(b.phi - b.R_phi, b.phi + b.R_phi)
    s_lo, s_hi = interval_sin(b.phi - b.R_phi, b.phi + b.R_phi)
    x_lo, x_hi = interval_mul(d - r_s, d + r_s, c_lo, c_hi)
    y_lo, y_hi = interval_mul(d - r_s, d + r_s, s_lo, s_hi)
    zero = np.zeros(1)
    cum = {k: np.concatenate([zero, np.cumsum(v)]) for k, v in
           (("xl", x_lo), ("xh", x_hi), ("yl", y_lo), ("yh", y_hi))}  # fmt: skip
    g = rounding_guard(np.abs(p0[:2]).sum() + r0.sum() + b.travelled[idx], idx)
    g_th = rounding_guard(abs(p0[2]) + r0[2] + b.turned[idx], idx)
    lo = np.stack([p0[0] - r0[0] + cum["xl"][idx] - g, p0[1] - r0[1] + cum["yl"][idx] - g,
                   b.nominal[idx, 2] - R[idx] - g_th], -1)  # fmt: skip
    hi = np.stack([p0[0] + r0[0] + cum["xh"][idx] + g, p0[1] + r0[1] + cum["yh"][idx] + g,
                   b.nominal[idx, 2] + R[idx] + g_th], -1)  # fmt: skip
    return IntervalBox(lo, hi, idx)


def box_area(box: IntervalBox) -> Array:
    """Area of the ``(x, y)`` face of each box, shape (C,) [m²]."""
    return (box.hi[:, 0] - box.lo[:, 0]) * (box.hi[:, 1] - box.lo[:, 1])


# ============================================================================= sampling


def sample_bounded_poses(
    ds: ArrayLike, dtheta: ArrayLike, error_generators: ArrayLike, n: int, rng: np.random.Generator, *,
    start: ArrayLike = (0.0, 0.0, 0.0), start_radius: ArrayLike = (0.0, 0.0, 0.0),
    checkpoints: ArrayLike | None = None, vertex_fraction: float = 0.5, directions: ArrayLike | None = None,
    chunk: int = 8192,
) -> Array:  # fmt: skip
    """Poses of ``n`` bounded-error trajectories, vectorised over particles (in chunks of particles).

    Every trajectory draws its per-step ``η`` (and its start in the start box): uniformly in
    ``[−1, 1]`` for a share ``1 − vertex_fraction``, at the vertices ``±1`` for ``vertex_fraction``
    (the extremes of the error set, where reachable sets have their boundary). With
    ``directions`` (D, 2), trajectory ``i`` of the vertex share instead takes
    ``η_{k} = sign(u·∂p_n/∂η_k)`` for the direction ``u = directions[i mod D]`` (to first order the
    trajectory reaching farthest along ``u`` at the end), probing the support of the reachable set.

    Returns
    -------
    ndarray, shape (n, C, 3) — ``(x, y, θ)`` at the checkpoints (θ unwrapped)
    """
    d, dth, p0, r0, idx = check_path_inputs(ds, dtheta, start, start_radius, checkpoints)
    A = check_error_generators(error_generators, d.size)
    n = check_positive_int("n", n)
    frac = float(check_nonnegative("vertex_fraction", vertex_fraction))
    U = None if directions is None else check_finite("directions", check_last_axis("directions", directions, 2))
    lever = _lever_arms(d, dth, p0, A) if U is not None else None
    out = np.empty((n, idx.size, 3))
    for a in range(0, n, check_positive_int("chunk", chunk)):  # chunks of particles bound the memory
        b = min(n, a + chunk)
        eta = rng.uniform(-1.0, 1.0, (b - a, d.size, A.shape[2]))
        z0 = rng.uniform(-1.0, 1.0, (b - a, 3))
        vert = rng.random(b - a) < frac
        eta[vert] = np.sign(eta[vert])
        z0[vert] = np.sign(z0[vert])
        if U is not None and lever is not None:
            u = U[np.arange(a, b)[vert] % U.shape[0]]  # (v, 2)
            eta[vert] = np.where(np.einsum("vc,kcm->vkm", u, lever) >= 0, 1.0, -1.0)
        e = np.einsum("cnm,nim->cni", eta, A)  # (e_s, e_θ) of every step, (c, N, 2)
        out[a:b] = _integrate_midpoint(d + e[..., 0], dth + e[..., 1], p0 + r0 * z0, idx)
    return out


def _integrate_midpoint(ds: Array, dtheta: Array, start: Array, idx: NDArray[np.intp]) -> Array:
    """Midpoint integration of travels and turns (c, N) from starts (c, 3), poses at ``idx``: (c, C, 3)."""
    zero = np.zeros((ds.shape[0], 1))
    theta = np.concatenate([zero, np.cumsum(dtheta, axis=1)], axis=1) + start[:, 2:3]
    phi = theta[:, :-1] + 0.5 * dtheta
    x = np.concatenate([zero, np.cumsum(ds * np.cos(phi), axis=1)], axis=1) + start[:, 0:1]
    y = np.concatenate([zero, np.cumsum(ds * np.sin(phi), axis=1)], axis=1) + start[:, 1:2]
    return np.stack([x[:, idx], y[:, idx], theta[:, idx]], axis=-1)


def _lever_arms(ds: Array, dtheta: Array, start: Array, A: Array) -> Array:
    """``∂(x_N, y_N)/∂η_k`` to first order along the nominal path, shape (N, 2, m).

    ``e_s`` moves the end by ``(cos φ̄_k, sin φ̄_k)``; ``e_θ`` turns the rest of the path:
    ``(−(ȳ_N − ȳ_{k+1}) − Δȳ_k/2, (x̄_N − x̄_{k+1}) + Δx̄_k/2)``.
    """
    _, phi, nom = midpoint_nominal(ds, dtheta, start)
    dx, dy = np.diff(nom[:, 0]), np.diff(nom[:, 1])
    turn = np.stack([-(nom[-1, 1] - nom[1:, 1]) - 0.5 * dy, (nom[-1, 0] - nom[1:, 0]) + 0.5 * dx], -1)
    travel = np.stack([np.cos(phi), np.sin(phi)], -1)
    return travel[:, :, None] * A[:, 0, None, :] + turn[:, :, None] * A[:, 1, None, :]
