"""Differential-drive kinematics (Šafránek 2022 §2.2.2–2.2.3), batched over leading dimensions.

One implementation for every drive: :func:`step_twist` and :func:`integrate_twist`
take a body-frame twist increment ``(v₁, v₂, Δθ)`` per step (forward, left,
turn; holonomic drives also move sideways) with four integration methods;
:func:`step` and :func:`integrate` are their front doors for steps without
lateral motion, ``(Δs, Δθ)`` → ``(Δs, 0, Δθ)``.

Conventions: SI units; a pose is ``(x, y, θ)`` with θ counter-clockwise from
the x axis; headings along a path are kept *unwrapped* (cumulative), only
differences of angles are wrapped to (−π, π].

    V = (v_r + v_l)/2        ω = (v_r − v_l)/b        R = V/ω
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .validation import check_choice, check_finite, check_last_axis, check_positive

__all__ = [
    "METHODS",
    "body_to_wheel",
    "integrate",
    "integrate_twist",
    "inverse_arc",
    "sinc",
    "step",
    "step_twist",
    "wheel_to_body",
    "wrap_angle",
]

Method = Literal["exact", "euler", "euler_end", "midpoint"]
METHODS: tuple[str, ...] = ("exact", "euler", "euler_end", "midpoint")


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles to the half-open interval (−π, π].

    Parameters
    ----------
    angle : array_like, any shape [rad]
    """
    a = np.asarray(angle, dtype=np.float64)
    t = a + np.pi
    # mod(t, 2π) is t itself, bit for bit, for t in [0, 2π) (fmod is exact there): a large array
    # already in range (a particle cloud wrapped a step ago) skips the division
    in_range = t.size > _WRAP_CHECK and t.min() >= 0.0 and t.max() < 2.0 * np.pi  # (NaN: not in range)
    wrapped = t if in_range else np.mod(t, 2.0 * np.pi)
    wrapped -= np.pi
    # mod maps +π to −π; the convention here is (−π, π]
    return np.where(wrapped == -np.pi, np.pi, wrapped)


#: Size above which :func:`wrap_angle` first checks whether its angles are already in range.
_WRAP_CHECK = 64


def wheel_to_body(
    v_r: ArrayLike, v_l: ArrayLike, track: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Wheel speeds (or travels) to body speed (or travel) and turn rate (or turn).

    ``V = (v_r + v_l)/2``, ``ω = (v_r − v_l)/b``. Works equally for per-step
    travels ``(Δs_r, Δs_l) → (Δs, Δθ)``.

    Parameters
    ----------
    v_r, v_l : array_like [m/s or m], broadcastable
    track : array_like [m], > 0 — wheel separation b
    """
    b = check_positive("track", track)
    vr = check_finite("v_r", v_r)
    vl = check_finite("v_l", v_l)
    return (vr + vl) / 2.0, (vr - vl) / b


def body_to_wheel(
    V: ArrayLike, omega: ArrayLike, track: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Body speed and turn rate to wheel speeds: ``v_r = V + ωb/2``, ``v_l = V − ωb/2``.

    Parameters
    ----------
    V : array_like [m/s]; omega : array_like [rad/s]; track : array_like [m], > 0
    """
    b = check_positive("track", track)
    v = check_finite("V", V)
    w = check_finite("omega", omega)
    return v + w * b / 2.0, v - w * b / 2.0


def sinc(u: ArrayLike) -> NDArray[np.float64]:
    """``sin u / u``, 1 at ``u = 0`` (numpy's normalised ``np.sinc(u/π)``)."""
    return np.sinc(np.asarray(u, dtype=np.float64) / np.pi)


def dsinc(u: ArrayLike) -> NDArray[np.float64]:
    """Derivative of ``sin u / u`` with respect to ``u`` (``−u/3`` near 0)."""
    v = np.asarray(u, dtype=np.float64)
    small = np.abs(v) < 1e-4
    safe = np.where(small, 1.0, v)
    return np.where(small, -v / 3.0, (safe * np.cos(safe) - np.sin(safe)) / (safe * safe))


def _sinc_half(dtheta: NDArray[np.float64]) -> NDArray[np.float64]:
    # sin(Δθ/2)/(Δθ/2), equal to 1 at Δθ = 0 (np.sinc(x) = sin(πx)/(πx))
    return np.sinc(dtheta / (2.0 * np.pi))


def step(pose: ArrayLike, ds: ArrayLike, dtheta: ArrayLike, method: Method = "midpoint") -> NDArray:
    """One forward-kinematics step ``p' = f(p, Δs, Δθ)``.

    Parameters
    ----------
    pose : array_like, shape (..., 3) — ``(x, y, θ)`` [m, m, rad]
    ds : array_like, shape (...) — travel of the axle centre [m]
    dtheta : array_like, shape (...) — change of heading [rad]
    method : {"exact", "euler", "euler_end", "midpoint"}
        ``exact`` rotates about the instantaneous centre of curvature (straight
        motion is its continuous limit); ``euler`` uses the start heading,
        ``euler_end`` the end heading, ``midpoint`` the mean heading.

    Returns
    -------
    ndarray, shape (..., 3)
    """
    return step_twist(pose, _twists(ds, dtheta), method)


def integrate(
    ds: ArrayLike,
    dtheta: ArrayLike,
    start: ArrayLike = (0.0, 0.0, 0.0),
    method: Method = "exact",
) -> NDArray[np.float64]:
    """Integrate per-step motions into a path, vectorised with cumulative sums.

    Parameters
    ----------
    ds : array_like, shape (..., N) — per-step travel of the axle centre [m]
    dtheta : array_like, shape (..., N) — per-step change of heading [rad]
    start : array_like, shape (..., 3) — start pose, broadcast against the batch
    method : {"exact", "euler", "euler_end", "midpoint"} — see :func:`step`

    Returns
    -------
    poses : ndarray, shape (..., N+1, 3) — the start pose followed by the pose
        after each step (heading unwrapped).
    """
    xi = _twists(ds, dtheta)
    if xi.ndim == 1:
        raise ValueError(f"ds must have shape (..., N), got shape {xi.shape[:-1]}")
    return integrate_twist(xi, start, method)


def _twists(ds: ArrayLike, dtheta: ArrayLike) -> NDArray[np.float64]:
    """Body twists ``(Δs, 0, Δθ)`` (..., 3) of steps without lateral motion (``ds``, ``dtheta`` broadcast)."""
    d, dth = np.broadcast_arrays(check_finite("ds", ds), check_finite("dtheta", dtheta))
    return np.stack([d, np.zeros_like(d), dth], axis=-1)


def inverse_arc(
    x: ArrayLike, y: ArrayLike, t: ArrayLike, track: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Wheel speeds that reach ``(x, y)`` from ``(0, 0, 0)`` in time ``t`` on one arc.

    The arc is tangent to the start heading and passes through the target:
    chord ``c = √(x²+y²)``, turn ``Δθ = 2·atan2(y, x)``, arc length
    ``c·(Δθ/2)/sin(Δθ/2)`` (``c`` when ``Δθ = 0``). Targets on the negative x
    axis cannot be reached by a forward arc tangent to the start heading.

    Parameters
    ----------
    x, y : array_like [m]; t : array_like [s], > 0; track : array_like [m], > 0

    Returns
    -------
    v_r, v_l : ndarray [m/s]
    """
    xx = check_finite("x", x)
    yy = check_finite("y", y)
    tt = check_positive("t", t)
    b = check_positive("track", track)
    if np.any((yy == 0) & (xx < 0)):
        raise ValueError(
            "x, y: a target on the negative x axis cannot be reached by one forward arc "
            f"tangent to the start heading (allowed: any other point), got x={xx}, y={yy}"
        )
    half = np.arctan2(yy, xx)  # Δθ/2
    chord = np.hypot(xx, yy)
    length = chord / _sinc_half(2.0 * half)
    V = length / tt
    omega = 2.0 * half / tt
    return V + omega * b / 2.0, V - omega * b / 2.0


# --- body-frame twists (forward, left, turn): holonomic drives move sideways ---------------

#: heading offset c of each method within the step: the step translation is applied at θ + c·Δθ
HEADING_OFFSET: dict[str, float] = {"exact": 0.5, "midpoint": 0.5, "euler": 0.0, "euler_end": 1.0}


def _translation_twist(
    theta: NDArray[np.float64],
    v1: NDArray[np.float64],
    v2: NDArray[np.float64],
    dtheta: NDArray[np.float64],
    method: str,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-step (Δx, Δy) of the body twist (v₁, v₂, Δθ) from the heading θ at the start of the step.

    ``(Δx, Δy) = s(Δθ) R(θ + cΔθ) (v₁, v₂)`` with ``c`` from :data:`HEADING_OFFSET` and
    ``s = sin(Δθ/2)/(Δθ/2)`` for ``exact`` (then the step is the SE(2) exponential
    ``exp(v₁, v₂, Δθ)``, continuous through Δθ = 0), ``s = 1`` otherwise.
    """
    phi = theta + HEADING_OFFSET[method] * dtheta
    if method == "exact":
        scale = _sinc_half(dtheta)
        a, b = v1 * scale, v2 * scale
    else:
        a, b = v1, v2
    c, s = np.cos(phi), np.sin(phi)
    return a * c - b * s, a * s + b * c


def step_twist(pose: ArrayLike, twist: ArrayLike, method: Method = "midpoint") -> NDArray[np.float64]:
    """One step ``p' = f(p, ξ)`` by a body-frame twist increment ``ξ = (v₁, v₂, Δθ)``.

    Parameters
    ----------
    pose : array_like, shape (..., 3) — ``(x, y, θ)`` [m, m, rad]
    twist : array_like, shape (..., 3) — travel forward and to the left in the body
        frame at the start of the step and change of heading [m, m, rad]
    method : {"exact", "euler", "euler_end", "midpoint"} — as :func:`step`

    Returns
    -------
    ndarray, shape (..., 3)
    """
    check_choice("method", method, METHODS)
    p = check_last_axis("pose", pose, 3)
    xi = check_finite("twist", check_last_axis("twist", twist, 3))
    dx, dy = _translation_twist(p[..., 2], xi[..., 0], xi[..., 1], xi[..., 2], method)
    return np.stack([p[..., 0] + dx, p[..., 1] + dy, p[..., 2] + xi[..., 2]], axis=-1)


def integrate_twist(
    twists: ArrayLike, start: ArrayLike = (0.0, 0.0, 0.0), method: Method = "exact"
) -> NDArray[np.float64]:
    """Integrate per-step body twists into a path, vectorised with cumulative sums.

    Parameters
    ----------
    twists : array_like, shape (..., N, 3) — per-step ``(v₁, v₂, Δθ)`` [m, m, rad]
    start : array_like, shape (..., 3) — start pose, broadcast against the batch
    method : {"exact", "euler", "euler_end", "midpoint"} — see :func:`step`

    Returns
    -------
    poses : ndarray, shape (..., N+1, 3) — start pose and the pose after each step
        (heading unwrapped); with ``v₂ = 0`` equal to :func:`integrate` of ``(v₁, Δθ)``.
    """
    check_choice("method", method, METHODS)
    xi = check_finite("twists", check_last_axis("twists", twists, 3))
    if xi.ndim < 2:
        raise ValueError(f"twists must have shape (..., N, 3), got shape {xi.shape}")
    p0 = check_last_axis("start", start, 3)
    theta0 = p0[..., 2, None]
    dth = xi[..., 2]
    cum = np.cumsum(dth, axis=-1)
    theta_before = theta0 + np.concatenate([np.zeros_like(cum[..., :1]), cum[..., :-1]], axis=-1)
    dx, dy = _translation_twist(theta_before, xi[..., 0], xi[..., 1], dth, method)
    zero = np.zeros((*dth.shape[:-1], 1))
    x = p0[..., 0, None] + np.concatenate([zero, np.cumsum(dx, axis=-1)], axis=-1)
    y = p0[..., 1, None] + np.concatenate([zero, np.cumsum(dy, axis=-1)], axis=-1)
    th = theta0 + np.concatenate([zero, cum], axis=-1)
    x, y, th = np.broadcast_arrays(x, y, th)
    return np.stack([x, y, th], axis=-1)
