"""The drives of Skalka 2011 §3.2.2: per-step odometry measurements ↔ body twist increments.

Every drive maps its own per-step odometry measurements ``u`` (shape (..., m)) to
the body-frame twist increment of its reference point ``ξ = (v₁, v₂, Δθ)`` —
travel forward, travel to the left, change of heading, in the body frame at the
start of the step [m, m, rad] — and back (:meth:`Drive.measurements`, the
inverse kinematics), with the Jacobian ``∂ξ/∂u``. A step with constant wheel
speeds and steering angles moves the robot by the SE(2) exponential of ``ξ``,
so the ``exact`` integration of :func:`pose_uncertainty.core.kinematics.integrate_twist`
is exact for every drive; ``euler``/``midpoint`` are its approximations.

Each equation below was re-derived from rigid-body kinematics (the velocity of a
body point ``r`` is ``v + Ω × r``; a wheel rolls along its heading and does not
slide sideways) and agrees with the thesis unless a note says otherwise.

``differential`` (§3.2.2.1) — ``u = (Δs_r, Δs_l)``, track ``b``::

    ξ = ((Δs_r + Δs_l)/2, 0, (Δs_r − Δs_l)/b)

``skid_steer`` (§3.2.2.2) — ``u = (Δs_r, Δs_l)``, track ``b``, ICR expansion ``χ``,
longitudinal ICR offset ``x_ICR`` (Martínez, Mandow, Morales, Pedraza &
García-Cerezo, "Approximating kinematics for tracked mobile robots", IJRR 2005;
Mandow et al., IROS 2007). The instantaneous centres of rotation of the left
and right track lie at lateral ``y_l = χb/2``, ``y_r = −χb/2`` and longitudinal
``x_ICR``; the body's ICR at ``(x_ICR, y_ICR)`` gives ``v = Ω(y_ICR, −x_ICR)``::

    ξ = ((Δs_r y_l − Δs_l y_r)/(y_l − y_r), −x_ICR Δθ, (Δs_r − Δs_l)/(y_l − y_r))
      = ((Δs_r + Δs_l)/2, −x_ICR (Δs_r − Δs_l)/(χb), (Δs_r − Δs_l)/(χb))

``χ = 1, x_ICR = 0`` is the differential drive. The thesis says that odometry of
a skid-steered vehicle is unusable because the centre of rotation cannot be
determined; with a slip model (``χ``, ``x_ICR`` random, see
:mod:`pose_uncertainty.methods.drive_noise`) it is usable on straights — the
slip terms vanish when ``Δs_r = Δs_l`` — and biased or uncertain in turns.

``tricycle`` (§3.2.2.3) — ``u = (ΔS, ω)``: travel of the steering wheel and its
angle (``ω > 0`` left), wheelbase ``d`` from the rear-axle centre (the reference
point) to the steering wheel. The steering wheel moves along ``(cos ω, sin ω)``;
the rear-axle centre moves along the body x axis: ``(v₀, 0) + Ω × (d, 0) =
ΔS (cos ω, sin ω)`` gives::

    ξ = (ΔS cos ω, 0, ΔS sin ω / d)

equal to the thesis's ``s₀ = ΔS cos ω``, ``Δθ = ΔS/r_s`` with ``r_s = d/sin ω``.
At ``ω = ±90°`` it turns in place about the rear-axle centre; ``max_steering``
(≤ 90°) bounds what :meth:`measurements` may ask for.

``ackermann`` (§3.2.2.4) — ``u = (ΔS_L, ΔS_R, ω)``: travels of the left and right
steered wheels and the steering angle ``ω`` of the virtual wheel at the middle
of the steered axle (the linkage's input), wheelbase ``d``, steered-axle track
``b``. The wheel at ``(d, ±b/2)`` rolls without sliding only if it points along
its velocity ``ΔS(cos ω ∓ (b/2d) sin ω, sin ω)``, so ``cot ω_L = cot ω − b/(2d)``,
``cot ω_R = cot ω + b/(2d)`` — the Ackermann condition of the thesis
(``cotg ω_L + b/2d = cotg ω = cotg ω_R − b/2d``), signed, correct — and each
wheel travels ``g_L,R ΔS`` with ``g = |(cos ω ∓ (b/2d) sin ω, sin ω)|``. The
mid-axle travel is the mean of the two wheels' estimates,
``ΔS = (ΔS_L/g_L + ΔS_R/g_R)/2``, and then ``ξ`` is the tricycle's (the bicycle
model).

``two_axle`` (§3.2.2.5) — ``u = (ΔS, ω)`` of the virtual middle wheel of the front
axle; the rear axle is steered by ``−ω``; the reference point is the vehicle
centre, half the wheelbase ``L`` from each axle. By symmetry the ICR lies on the
transverse line through the centre; as in the thesis it is the tricycle with
``d = L/2``: ``ξ = (ΔS cos ω, 0, 2ΔS sin ω / L)``.

``synchro`` (§3.2.2.6) — ``u = (ΔS, ψ)``: drive travel and steering angle of the
coupled wheels relative to the chassis. The chassis never turns::

    ξ = (ΔS cos ψ, ΔS sin ψ, 0)

``mdof`` (§3.2.2.7) — ``u = (Δs_1 … Δs_n, ψ_1 … ψ_n)``: travel and steering angle of
each of ``n`` independently driven and steered wheels at body positions
``(x_j, y_j)``. Rolling without sliding asks ``A ξ = w`` with wheel ``j``'s rows
``[1, 0, −y_j]``, ``[0, 1, x_j]`` and ``w_j = Δs_j (cos ψ_j, sin ψ_j)``; the
``2n > 3`` equations are solved by least squares, ``ξ = (AᵀA)⁻¹Aᵀ w`` (equal
weights: each wheel's velocity counts the same). The thesis gives no formulas.

``omni3`` (§3.2.2.8) — ``u = (s_a, s_b, s_c)``: travels of three omni wheels at 0°,
120°, 240° around the centre at distance ``R``, each driving along the clockwise
tangent ``(sin α, −cos α)``; its contact point moves with ``v + Ω × r``::

    s_i = sin α_i v₁ − cos α_i v₂ − R Δθ
    v₁ = (s_b − s_c)/√3,  v₂ = (s_b + s_c − 2 s_a)/3,  Δθ = −(s_a + s_b + s_c)/(3R)

(the thesis's equations, correct). The thesis then moves the robot by
``s₀ = |(v₁, v₂)|`` in the direction ``θ + atan2(v₂, v₁)``: that is the Euler
step. With constant wheel speeds the robot turns while it moves, and the exact
step (the SE(2) exponential) goes ``s₀·sin(Δθ/2)/(Δθ/2)`` in the direction
``θ + Δθ/2 + atan2(v₂, v₁)`` (``exact`` integration here).

Paths
-----
:func:`follow` drives a geometric path (a :class:`~pose_uncertainty.core.trajectories.Trajectory`,
whose per-step twists are ``(Δs, 0, Δθ)`` of exact arcs) with any drive: the
drive's inverse kinematics gives its measurements, and a step the drive cannot
make (a sideways step of a car-like drive, a turn beyond its steering limit, a
rotation in place of a tricycle with ``max_steering < 90°``) raises a one-line
ValueError naming the step. The synchro drive cannot turn: it follows the
path's positions (its turret takes the path's heading) with its chassis heading
fixed at the start heading.

Length
------
One module of about 850 lines on purpose: the derivation above (a hundred lines) covers
every drive, and the drives share one abstract :class:`Drive` with its checks; each drive
is a class of 30–100 lines. Split by drive, the derivations would be apart from the code
they derive.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .kinematics import METHODS, Method, integrate_twist, step_twist
from .trajectories import BUILDERS, Trajectory, build
from .validation import check_choice, check_finite, check_last_axis, check_positive

__all__ = [
    "DRIVES",
    "Ackermann",
    "Differential",
    "Drive",
    "DrivePath",
    "MultiDof",
    "Omni3",
    "SkidSteer",
    "SynchroDrive",
    "Tricycle",
    "TwoAxleSteering",
    "differential_twist",
    "differential_twist_jacobian",
    "drive_path",
    "follow",
    "make_drive",
    "wheel_path",
]

#: relative tolerance of the inverse kinematics for motion a drive cannot make
_TOL = 1e-9


def _check_steering_limit(name: str, value: float) -> float:
    """A steering limit in (0, π/2] rad."""
    v = float(check_finite(name, value))
    if not 0.0 < v <= math.pi / 2:
        raise ValueError(
            f"{name} must be in (0, π/2] rad (allowed: steering up to ±90°), "
            f"got {v!r} rad = {math.degrees(v):.6g}°"
        )
    return v


def _stack_cols(*cols: NDArray) -> NDArray:
    """Columns (each shape (..., 3)) into a Jacobian of shape (..., 3, len(cols))."""
    return np.stack(cols, axis=-1)


def _vec(a: NDArray, b: NDArray, c: NDArray) -> NDArray:
    a, b, c = np.broadcast_arrays(a, b, c)
    return np.stack([a, b, c], axis=-1)


def _step_index(mask: NDArray) -> str:
    """First offending index of a boolean mask over (..., N), as text."""
    idx = np.argwhere(mask)[0]
    return str(int(idx[-1])) if idx.size == 1 else str(tuple(int(i) for i in idx))


class Drive(ABC):
    """A drive: per-step measurements ``u`` (..., m) ↔ body twist ``ξ`` (..., 3).

    Class attributes: ``kind`` (the name in :data:`DRIVES`), ``channels`` (the
    measurement names), ``kinds`` (``"travel"`` [m] or ``"angle"`` [rad] per
    channel), ``fixed_heading`` (True for a drive whose chassis cannot turn).
    """

    kind: ClassVar[str]
    fixed_heading: ClassVar[bool] = False

    @property
    @abstractmethod
    def channels(self) -> tuple[str, ...]:
        """Names of the measurement channels, in the order of the last axis of ``u``."""

    @property
    @abstractmethod
    def kinds(self) -> tuple[str, ...]:
        """``"travel"`` or ``"angle"`` for each channel."""

    @property
    def n_channels(self) -> int:
        """Number of measurements per step ``m``."""
        return len(self.channels)

    @property
    def steering_limit(self) -> float | None:
        """Largest absolute steering angle the inverse kinematics may use [rad], or None (unlimited)."""
        return None

    def _u(self, u: ArrayLike) -> NDArray[np.float64]:
        return check_finite("u", check_last_axis("u", u, self.n_channels))

    def _xi(self, twist: ArrayLike) -> NDArray[np.float64]:
        return check_finite("twist", check_last_axis("twist", twist, 3))

    @abstractmethod
    def twist(self, u: ArrayLike) -> NDArray[np.float64]:
        """Body twist increment ``ξ = (v₁, v₂, Δθ)`` [m, m, rad], shape (..., 3), of measurements (..., m)."""

    @abstractmethod
    def twist_jacobian(self, u: ArrayLike) -> NDArray[np.float64]:
        """``∂ξ/∂u``, shape (..., 3, m)."""

    @abstractmethod
    def measurements(self, twist: ArrayLike) -> NDArray[np.float64]:
        """Inverse kinematics: measurements (..., m) that make the twist (..., 3).

        Raises ValueError naming the first step the drive cannot make.
        """

    def step(
        self, pose: ArrayLike, u: ArrayLike, method: Method = "midpoint"
    ) -> NDArray[np.float64]:
        """One step ``p' = f(p, ξ(u))`` (:func:`~pose_uncertainty.core.kinematics.step_twist`)."""
        return step_twist(pose, self.twist(u), method)

    def integrate(
        self, u: ArrayLike, start: ArrayLike = (0.0, 0.0, 0.0), method: Method = "exact"
    ) -> NDArray[np.float64]:
        """Poses (..., N+1, 3) from measurements (..., N, m) (:func:`~pose_uncertainty.core.kinematics.integrate_twist`)."""
        return integrate_twist(self.twist(u), start, method)

    def twist_perturbation(
        self, u: NDArray[np.float64], du: list[NDArray[np.float64]]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64]]:
        """``δξ = ξ(u + δu) − ξ(u)`` as ``(δv₁, δv₂, δΔθ)``, each shape (n, N) — the Monte Carlo's input.

        Parameters
        ----------
        u : ndarray, shape (N, m) — nominal measurements
        du : list of m ndarrays, shape (n, N) — each channel's errors; the arrays may be
            overwritten (a drive linear in ``u`` computes ``δξ`` in place)

        Returns
        -------
        δv₁, δv₂, δΔθ : ndarray, shape (n, N) [m, m, rad]; ``δv₂`` is None for a drive whose
        errors never move it sideways (the particles' lateral travel is the nominal one).
        This default takes the difference of :meth:`twist`; a drive may give a fast path.
        """
        d = self.twist(u + np.stack(du, axis=-1)) - self.twist(u)
        return d[..., 0], d[..., 1], d[..., 2]

    def _no_sideways(self, xi: NDArray) -> None:
        scale = np.maximum(1.0, np.abs(xi).max(axis=-1))
        bad = np.abs(xi[..., 1]) > _TOL * scale
        if np.any(bad):
            i = _step_index(bad)
            raise ValueError(
                f"twist: the {self.kind} drive cannot move sideways, step {i} needs lateral travel "
                f"{xi[..., 1][bad].ravel()[0]!r} m (allowed: 0; the holonomic drives omni3, mdof "
                "and synchro move sideways)"
            )

    def _check_steering(self, angle: NDArray) -> None:
        limit = self.steering_limit
        if limit is None:
            return
        bad = np.abs(angle) > limit * (1.0 + _TOL)
        if np.any(bad):
            i = _step_index(bad)
            a = float(angle[bad].ravel()[0])
            raise ValueError(
                f"steering: the {self.kind} drive cannot make step {i}, it needs steering angle "
                f"{math.degrees(a):.6g}° beyond max_steering={math.degrees(limit):.6g}° (allowed: "
                "|angle| <= max_steering; a rotation in place needs ±90°)"
            )


# --- differential and skid-steer ---------------------------------------------------------


def differential_twist(ds_r: ArrayLike, ds_l: ArrayLike, track: ArrayLike) -> NDArray[np.float64]:
    """The differential drive's twist ``((Δs_r + Δs_l)/2, 0, (Δs_r − Δs_l)/b)``, shape (..., 3).

    Parameters
    ----------
    ds_r, ds_l : array_like, shape (...) — wheel travels [m]
    track : array_like, broadcast with them — wheel separation b [m], > 0 (not checked here)
    """
    r = np.asarray(ds_r, dtype=np.float64)
    l = np.asarray(ds_l, dtype=np.float64)
    b = np.asarray(track, dtype=np.float64)
    return _vec((r + l) / 2.0, np.zeros_like(r + l), (r - l) / b)


def differential_twist_jacobian(track: ArrayLike, shape: tuple[int, ...] = ()) -> NDArray[np.float64]:
    """``∂ξ/∂(Δs_r, Δs_l) = [[½, ½], [0, 0], [1/b, −1/b]]``, shape ``(*shape, 3, 2)`` (track broadcast)."""
    inv = 1.0 / np.asarray(track, dtype=np.float64)
    half = np.full(np.broadcast_shapes(shape, inv.shape), 0.5)
    zero = np.zeros_like(half)
    inv = np.broadcast_to(inv, half.shape)
    return np.stack([np.stack([half, half], -1), np.stack([zero, zero], -1), np.stack([inv, -inv], -1)], -2)


@dataclass(frozen=True)
class Differential(Drive):
    """Differential drive (§3.2.2.1): ``u = (Δs_r, Δs_l)``; ``track`` b [m] > 0."""

    track: float = 0.2
    kind: ClassVar[str] = "differential"

    def __post_init__(self) -> None:
        object.__setattr__(self, "track", float(check_positive("track", self.track)))

    @property
    def channels(self) -> tuple[str, ...]:
        return ("ds_r", "ds_l")

    @property
    def kinds(self) -> tuple[str, ...]:
        return ("travel", "travel")

    def twist(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        return differential_twist(a[..., 0], a[..., 1], self.track)

    def twist_jacobian(self, u: ArrayLike) -> NDArray[np.float64]:
        return differential_twist_jacobian(self.track, self._u(u).shape[:-1])

    def twist_perturbation(
        self, u: NDArray[np.float64], du: list[NDArray[np.float64]]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64]]:
        """Linear, in place: ``δv₁ = (δs_r + δs_l)/2``, no lateral error, ``δΔθ = (δs_r − δs_l)/b`` (in ``du[0]``)."""
        dr, dl = du
        dv = dr + dl
        dv *= 0.5
        dr -= dl
        dr /= self.track
        return dv, None, dr

    def measurements(self, twist: ArrayLike) -> NDArray[np.float64]:
        xi = self._xi(twist)
        self._no_sideways(xi)
        half = xi[..., 2] * self.track / 2.0
        return np.stack([xi[..., 0] + half, xi[..., 0] - half], axis=-1)


@dataclass(frozen=True)
class SkidSteer(Drive):
    """Skid-steered wheeled or tracked vehicle (§3.2.2.2) with the ICR model of Martínez et al.

    ``u = (Δs_r, Δs_l)``. Attributes: ``track`` b [m] > 0; ``chi`` — ICR
    expansion factor χ > 0 (the tracks' ICRs at ``±χb/2``; typically 1.2–2 on
    real ground, 1 = no slip); ``x_icr`` — longitudinal ICR offset [m] (lateral
    slip in turns, ``v₂ = −x_ICR Δθ``).
    """

    track: float = 0.2
    chi: float = 1.0
    x_icr: float = 0.0
    kind: ClassVar[str] = "skid_steer"

    def __post_init__(self) -> None:
        object.__setattr__(self, "track", float(check_positive("track", self.track)))
        object.__setattr__(self, "chi", float(check_positive("chi", self.chi)))
        object.__setattr__(self, "x_icr", float(check_finite("x_icr", self.x_icr)))

    @property
    def channels(self) -> tuple[str, ...]:
        return ("ds_r", "ds_l")

    @property
    def kinds(self) -> tuple[str, ...]:
        return ("travel", "travel")

    def twist_icr(self, u: ArrayLike, chi: ArrayLike, x_icr: ArrayLike) -> NDArray[np.float64]:
        """Twist with the ICR parameters given per step or per particle (broadcast with u[..., 0])."""
        a = self._u(u)
        r, l = a[..., 0], a[..., 1]
        w = (r - l) / (np.asarray(chi) * self.track)
        return _vec((r + l) / 2.0, -np.asarray(x_icr) * w, w)

    def twist(self, u: ArrayLike) -> NDArray[np.float64]:
        return self.twist_icr(u, self.chi, self.x_icr)

    def twist_jacobian(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        cb = self.chi * self.track
        J = np.array([[0.5, 0.5], [-self.x_icr / cb, self.x_icr / cb], [1.0 / cb, -1.0 / cb]])
        return np.broadcast_to(J, (*a.shape[:-1], 3, 2)).copy()

    def icr_jacobian(self, u: ArrayLike) -> NDArray[np.float64]:
        """``∂ξ/∂(χ, x_ICR)``, shape (..., 3, 2): zero on straights (``Δs_r = Δs_l``)."""
        a = self._u(u)
        w = (a[..., 0] - a[..., 1]) / (self.chi * self.track)
        zero = np.zeros_like(w)
        d_chi = _vec(zero, self.x_icr * w / self.chi, -w / self.chi)
        d_x = _vec(zero, -w, zero)
        return _stack_cols(d_chi, d_x)

    def measurements(self, twist: ArrayLike) -> NDArray[np.float64]:
        xi = self._xi(twist)
        slide = xi[..., 1] + self.x_icr * xi[..., 2]
        scale = np.maximum(1.0, np.abs(xi).max(axis=-1))
        bad = np.abs(slide) > _TOL * scale
        if np.any(bad):
            raise ValueError(
                f"twist: the skid_steer drive with x_icr={self.x_icr!r} m slides sideways by −x_icr·Δθ, "
                f"step {_step_index(bad)} asks for lateral travel {xi[..., 1][bad].ravel()[0]!r} m "
                "(allowed: v₂ = −x_icr·Δθ; use x_icr=0 to follow a path with no lateral slip)"
            )
        half = xi[..., 2] * self.chi * self.track / 2.0
        return np.stack([xi[..., 0] + half, xi[..., 0] - half], axis=-1)


# --- steered drives -----------------------------------------------------------------------


def _bicycle_twist(ds: NDArray, omega: NDArray, d: float) -> NDArray:
    """ξ = (ΔS cos ω, 0, ΔS sin ω / d)."""
    return _vec(ds * np.cos(omega), np.zeros_like(ds), ds * np.sin(omega) / d)


def _bicycle_jacobian(ds: NDArray, omega: NDArray, d: float) -> NDArray:
    """∂ξ/∂(ΔS, ω) of the bicycle model, shape (..., 3, 2)."""
    c, s = np.cos(omega), np.sin(omega)
    zero = np.zeros_like(c)
    return _stack_cols(_vec(c, zero, s / d), _vec(-ds * s, zero, ds * c / d))


def _bicycle_inverse(xi: NDArray, d: float) -> tuple[NDArray, NDArray]:
    """(ΔS, ω) with |ω| ≤ 90° making (v₁, 0, Δθ): ω = atan2(σ d Δθ, σ v₁), ΔS = σ·hypot(v₁, d Δθ).

    ``σ = sign(v₁)`` (+1 at v₁ = 0), so reversing keeps the wheel within ±90°;
    ``v₁ = Δθ = 0`` gives ``ω = 0`` (atan2(0, 0) = 0).
    """
    v1, w = xi[..., 0], xi[..., 2]
    sgn = np.where(v1 < 0, -1.0, 1.0)
    omega = np.arctan2(sgn * d * w, sgn * v1)
    return sgn * np.hypot(v1, d * w), omega


@dataclass(frozen=True)
class Tricycle(Drive):
    """Tricycle (§3.2.2.3): ``u = (ΔS, ω)``; ``wheelbase`` d [m] > 0; ``max_steering`` in (0, π/2] rad.

    Reference point: the centre of the fixed (rear) axle.
    """

    wheelbase: float = 0.3
    max_steering: float = math.pi / 3
    kind: ClassVar[str] = "tricycle"

    def __post_init__(self) -> None:
        object.__setattr__(self, "wheelbase", float(check_positive("wheelbase", self.wheelbase)))
        object.__setattr__(
            self, "max_steering", _check_steering_limit("max_steering", self.max_steering)
        )

    @property
    def channels(self) -> tuple[str, ...]:
        return ("ds", "omega")

    @property
    def kinds(self) -> tuple[str, ...]:
        return ("travel", "angle")

    @property
    def steering_limit(self) -> float | None:
        return self.max_steering

    @property
    def _d(self) -> float:
        return self.wheelbase

    def twist(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        return _bicycle_twist(a[..., 0], a[..., 1], self._d)

    def twist_jacobian(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        return _bicycle_jacobian(a[..., 0], a[..., 1], self._d)

    def measurements(self, twist: ArrayLike) -> NDArray[np.float64]:
        xi = self._xi(twist)
        self._no_sideways(xi)
        ds, omega = _bicycle_inverse(xi, self._d)
        self._check_steering(omega)
        return np.stack([ds, omega], axis=-1)


@dataclass(frozen=True)
class TwoAxleSteering(Tricycle):
    """Both axles steered symmetrically (§3.2.2.5): ``u = (ΔS, ω)`` of the front axle's middle.

    ``wheelbase`` L [m] > 0 between the axles; the rear axle steers by ``−ω``;
    reference point: the vehicle centre. It is the tricycle with ``d = L/2``.
    """

    kind: ClassVar[str] = "two_axle"

    @property
    def _d(self) -> float:
        return self.wheelbase / 2.0


@dataclass(frozen=True)
class Ackermann(Drive):
    """Ackermann steering (§3.2.2.4): ``u = (ΔS_L, ΔS_R, ω)``.

    Attributes: ``wheelbase`` d [m] > 0 (fixed rear axle to steered front axle);
    ``track`` b [m] > 0 of the steered axle; ``max_steering`` in (0, π/2] rad,
    the limit of the mid-axle angle ω, such that the inner wheel stays within
    90° (``tan(max_steering) ≤ 2d/b``). Reference point: the rear-axle centre.
    """

    wheelbase: float = 0.3
    track: float = 0.2
    max_steering: float = math.pi / 3
    kind: ClassVar[str] = "ackermann"

    def __post_init__(self) -> None:
        d = float(check_positive("wheelbase", self.wheelbase))
        b = float(check_positive("track", self.track))
        limit = _check_steering_limit("max_steering", self.max_steering)
        if d * math.cos(limit) < b / 2.0 * math.sin(limit) * (1.0 - 1e-12):
            raise ValueError(
                f"max_steering={limit!r} rad turns the inner wheel beyond 90° (allowed: "
                f"tan(max_steering) <= 2·wheelbase/track = {2.0 * d / b:.6g}, i.e. max_steering <= "
                f"{math.atan2(2.0 * d, b):.6g} rad)"
            )
        object.__setattr__(self, "wheelbase", d)
        object.__setattr__(self, "track", b)
        object.__setattr__(self, "max_steering", limit)

    @property
    def channels(self) -> tuple[str, ...]:
        return ("ds_left", "ds_right", "omega")

    @property
    def kinds(self) -> tuple[str, ...]:
        return ("travel", "travel", "angle")

    @property
    def steering_limit(self) -> float | None:
        return self.max_steering

    def _wheel_velocity(self, omega: NDArray, side: float) -> tuple[NDArray, NDArray]:
        """Velocity of the wheel at (d, side·b/2) per unit mid-axle travel: (cos ω − side·β sin ω, sin ω)."""
        beta = self.track / (2.0 * self.wheelbase)
        return np.cos(omega) - side * beta * np.sin(omega), np.sin(omega)

    def wheel_angles(self, omega: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Left and right wheel angles ``(ω_L, ω_R)`` [rad] for the mid-axle angle ω (Ackermann condition)."""
        w = check_finite("omega", omega)
        (xl, yl), (xr, yr) = self._wheel_velocity(w, 1.0), self._wheel_velocity(w, -1.0)
        return np.arctan2(yl, xl), np.arctan2(yr, xr)

    def wheel_ratios(self, omega: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(g_L, g_R)``: each front wheel's travel per unit mid-axle travel ΔS."""
        w = check_finite("omega", omega)
        return np.hypot(*self._wheel_velocity(w, 1.0)), np.hypot(*self._wheel_velocity(w, -1.0))

    def mid_axle(self, u: ArrayLike) -> NDArray[np.float64]:
        """Mid-axle (bicycle-model) measurements ``(ΔS, ω)`` with ``ΔS = (ΔS_L/g_L + ΔS_R/g_R)/2``."""
        a = self._u(u)
        gl, gr = self.wheel_ratios(a[..., 2])
        return np.stack([(a[..., 0] / gl + a[..., 1] / gr) / 2.0, a[..., 2]], axis=-1)

    def twist(self, u: ArrayLike) -> NDArray[np.float64]:
        m = self.mid_axle(u)
        return _bicycle_twist(m[..., 0], m[..., 1], self.wheelbase)

    def _ratio_derivatives(self, omega: NDArray) -> tuple[NDArray, NDArray]:
        """``dg/dω = (β² sin 2ω ∓ 2β cos 2ω)/(2g)`` for the left (−) and right (+) wheel."""
        beta = self.track / (2.0 * self.wheelbase)
        gl, gr = self.wheel_ratios(omega)
        a, b = beta**2 * np.sin(2.0 * omega), 2.0 * beta * np.cos(2.0 * omega)
        return (a - b) / (2.0 * gl), (a + b) / (2.0 * gr)

    def twist_jacobian(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        m = self.mid_axle(a)
        B = _bicycle_jacobian(m[..., 0], m[..., 1], self.wheelbase)  # ∂ξ/∂(ΔS, ω)
        gl, gr = self.wheel_ratios(a[..., 2])
        dgl, dgr = self._ratio_derivatives(a[..., 2])
        # ∂ΔS/∂ω = −½ (ΔS_L g_L'/g_L² + ΔS_R g_R'/g_R²)
        dS_dw = -0.5 * (a[..., 0] * dgl / gl**2 + a[..., 1] * dgr / gr**2)
        col_s = B[..., :, 0]
        return _stack_cols(
            col_s / (2.0 * gl)[..., None],
            col_s / (2.0 * gr)[..., None],
            B[..., :, 1] + col_s * dS_dw[..., None],
        )

    def measurements(self, twist: ArrayLike) -> NDArray[np.float64]:
        xi = self._xi(twist)
        self._no_sideways(xi)
        ds, omega = _bicycle_inverse(xi, self.wheelbase)
        self._check_steering(omega)
        gl, gr = self.wheel_ratios(omega)
        return np.stack([gl * ds, gr * ds, omega], axis=-1)


# --- holonomic drives ---------------------------------------------------------------------


@dataclass(frozen=True)
class SynchroDrive(Drive):
    """Synchro drive (§3.2.2.6): ``u = (ΔS, ψ)``, drive travel and steering angle; the chassis never turns."""

    kind: ClassVar[str] = "synchro"
    fixed_heading: ClassVar[bool] = True

    @property
    def channels(self) -> tuple[str, ...]:
        return ("ds", "psi")

    @property
    def kinds(self) -> tuple[str, ...]:
        return ("travel", "angle")

    def twist(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        ds, psi = a[..., 0], a[..., 1]
        return _vec(ds * np.cos(psi), ds * np.sin(psi), np.zeros_like(ds))

    def twist_jacobian(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        ds, psi = a[..., 0], a[..., 1]
        c, s, zero = np.cos(psi), np.sin(psi), np.zeros_like(ds)
        return _stack_cols(_vec(c, s, zero), _vec(-ds * s, ds * c, zero))

    def measurements(self, twist: ArrayLike) -> NDArray[np.float64]:
        xi = self._xi(twist)
        scale = np.maximum(1.0, np.abs(xi).max(axis=-1))
        bad = np.abs(xi[..., 2]) > _TOL * scale
        if np.any(bad):
            raise ValueError(
                f"twist: the synchro drive cannot turn its chassis, step {_step_index(bad)} asks for "
                f"Δθ = {xi[..., 2][bad].ravel()[0]!r} rad (allowed: 0; follow() keeps the heading "
                "and follows the positions)"
            )
        # ψ = atan2(v₂, v₁) in (−π, π], ΔS ≥ 0; a step without travel gets ψ = 0
        return np.stack([np.hypot(xi[..., 0], xi[..., 1]), np.arctan2(xi[..., 1], xi[..., 0])], -1)


def _default_wheels() -> tuple[tuple[float, float], ...]:
    return ((0.15, 0.1), (0.15, -0.1), (-0.15, 0.1), (-0.15, -0.1))


@dataclass(frozen=True)
class MultiDof(Drive):
    """Multi-degree-of-freedom drive (§3.2.2.7): independently driven and steered wheels.

    ``u = (Δs_1 … Δs_n, ψ_1 … ψ_n)``; ``wheels`` — body positions ``(x_j, y_j)`` [m]
    of n ≥ 2 wheels, at least two distinct (default: the corners of a 0.3 × 0.2 m
    rectangle about the centre). The twist is the least-squares fit of the
    wheels' velocities (module docstring).
    """

    wheels: tuple[tuple[float, float], ...] = field(default_factory=_default_wheels)
    kind: ClassVar[str] = "mdof"

    def __post_init__(self) -> None:
        w = check_finite("wheels", self.wheels)
        if w.ndim != 2 or w.shape[1] != 2 or w.shape[0] < 2:
            raise ValueError(
                f"wheels must be a list of n >= 2 positions (x, y) [m] (allowed: shape (n, 2)), "
                f"got shape {w.shape}"
            )
        if np.ptp(w, axis=0).max() <= 0:
            raise ValueError(
                f"wheels must hold at least two distinct positions (allowed: not all equal), got {w.tolist()}"
            )
        object.__setattr__(self, "wheels", tuple((float(x), float(y)) for x, y in w))

    @property
    def n_wheels(self) -> int:
        return len(self.wheels)

    @property
    def channels(self) -> tuple[str, ...]:
        n = self.n_wheels
        return tuple(f"ds_{j + 1}" for j in range(n)) + tuple(f"psi_{j + 1}" for j in range(n))

    @property
    def kinds(self) -> tuple[str, ...]:
        return ("travel",) * self.n_wheels + ("angle",) * self.n_wheels

    def _A(self) -> NDArray:
        """Rolling constraints A (2n, 3): rows [1, 0, −y_j], [0, 1, x_j] per wheel."""
        rows = []
        for x, y in self.wheels:
            rows += [[1.0, 0.0, -y], [0.0, 1.0, x]]
        return np.array(rows)

    def _pinv(self) -> NDArray:
        A = self._A()
        return np.linalg.solve(A.T @ A, A.T)  # (AᵀA)⁻¹Aᵀ, shape (3, 2n)

    def twist(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        n = self.n_wheels
        ds, psi = a[..., :n], a[..., n:]
        w = np.stack([ds * np.cos(psi), ds * np.sin(psi)], axis=-1).reshape(*a.shape[:-1], 2 * n)
        return w @ self._pinv().T

    def twist_jacobian(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        n = self.n_wheels
        ds, psi = a[..., :n], a[..., n:]
        c, s = np.cos(psi), np.sin(psi)
        P = self._pinv().reshape(3, n, 2)  # P[:, j, 0] multiplies w_jx, P[:, j, 1] w_jy
        d_ds = P[:, :, 0] * c[..., None, :] + P[:, :, 1] * s[..., None, :]  # (..., 3, n)
        d_psi = ds[..., None, :] * (-P[:, :, 0] * s[..., None, :] + P[:, :, 1] * c[..., None, :])
        return np.concatenate([d_ds, d_psi], axis=-1)

    def measurements(self, twist: ArrayLike) -> NDArray[np.float64]:
        xi = self._xi(twist)
        w = (xi @ self._A().T).reshape(*xi.shape[:-1], self.n_wheels, 2)
        vx, vy = w[..., 0], w[..., 1]
        # each wheel within (−90°, 90°], reversing its drive when needed
        sgn = np.where((vx < 0) | ((vx == 0) & (vy < 0)), -1.0, 1.0)
        return np.concatenate([sgn * np.hypot(vx, vy), np.arctan2(sgn * vy, sgn * vx)], axis=-1)


_SQRT3 = math.sqrt(3.0)


@dataclass(frozen=True)
class Omni3(Drive):
    """Three-wheel omnidirectional drive (§3.2.2.8): ``u = (s_a, s_b, s_c)``; ``radius`` R [m] > 0."""

    radius: float = 0.15
    kind: ClassVar[str] = "omni3"

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius", float(check_positive("radius", self.radius)))

    @property
    def channels(self) -> tuple[str, ...]:
        return ("s_a", "s_b", "s_c")

    @property
    def kinds(self) -> tuple[str, ...]:
        return ("travel", "travel", "travel")

    def _M(self) -> NDArray:
        """ξ = M u: the inverse of the thesis's wheel equations."""
        R = self.radius
        return np.array(
            [
                [0.0, 1.0 / _SQRT3, -1.0 / _SQRT3],
                [-2.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
                [-1.0 / (3.0 * R), -1.0 / (3.0 * R), -1.0 / (3.0 * R)],
            ]
        )

    def twist(self, u: ArrayLike) -> NDArray[np.float64]:
        return self._u(u) @ self._M().T

    def twist_jacobian(self, u: ArrayLike) -> NDArray[np.float64]:
        a = self._u(u)
        return np.broadcast_to(self._M(), (*a.shape[:-1], 3, 3)).copy()

    def measurements(self, twist: ArrayLike) -> NDArray[np.float64]:
        xi = self._xi(twist)
        v1, v2, w = xi[..., 0], xi[..., 1], xi[..., 2]
        rw = self.radius * w
        # s_i = sin α_i v₁ − cos α_i v₂ − R Δθ, α = 0°, 120°, 240°
        return np.stack(
            [-v2 - rw, _SQRT3 / 2.0 * v1 + v2 / 2.0 - rw, -_SQRT3 / 2.0 * v1 + v2 / 2.0 - rw], -1
        )


#: the drives by name (the ``type`` of a run's ``drive`` section)
DRIVES: dict[str, type[Drive]] = {
    cls.kind: cls
    for cls in (
        Differential,
        SkidSteer,
        Tricycle,
        Ackermann,
        TwoAxleSteering,
        SynchroDrive,
        MultiDof,
        Omni3,
    )
}


def make_drive(kind: str, **geometry: Any) -> Drive:
    """A drive by name (:data:`DRIVES`) with its geometry keywords; unknown keys raise ValueError."""
    check_choice("drive", kind, tuple(DRIVES))
    cls = DRIVES[kind]
    allowed = tuple(f.name for f in fields(cls))  # type: ignore[arg-type]
    for key in geometry:
        if key not in allowed:
            raise ValueError(
                f"drive {kind!r} has no geometry key {key!r} (allowed: {', '.join(allowed) or 'none'})"
            )
    if kind == "mdof" and "wheels" in geometry:
        geometry = {**geometry, "wheels": tuple(tuple(p) for p in geometry["wheels"])}
    return cls(**geometry)


# --- paths ----------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class DrivePath:
    """A drive's per-step measurements at a fixed step: what its odometry reads along a path.

    Attributes
    ----------
    drive : Drive
    u : ndarray, shape (N, m) — measurements per step [m or rad per channel]
    dt : float — step [s], > 0
    start : ndarray, shape (3,) — start pose [m, m, rad]
    name : str
    """

    drive: Drive
    u: NDArray[np.float64]
    dt: float
    start: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    name: str = ""

    def __post_init__(self) -> None:
        u = self.drive._u(self.u)
        if u.ndim != 2 or u.shape[0] == 0:
            raise ValueError(
                f"u must have shape (N, {self.drive.n_channels}) with N >= 1, got shape {u.shape}"
            )
        limit = self.drive.steering_limit
        angles = u[:, [k == "angle" for k in self.drive.kinds]]
        if limit is not None and angles.size:
            # per step, the angle of largest magnitude, so that the error names the step
            self.drive._check_steering(angles[np.arange(len(u)), np.abs(angles).argmax(axis=-1)])
        start = check_finite("start", check_last_axis("start", self.start, 3))
        if start.shape != (3,):
            raise ValueError(f"start must have shape (3,), got shape {start.shape}")
        for arr in (u, start):
            arr.setflags(write=False)
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "dt", float(check_positive("dt", self.dt)))

    @property
    def n_steps(self) -> int:
        return int(self.u.shape[0])

    @property
    def times(self) -> NDArray[np.float64]:
        """Times of the poses ``0, dt, …, N·dt`` [s], shape (N+1,)."""
        return np.arange(self.n_steps + 1, dtype=np.float64) * self.dt

    @property
    def twists(self) -> NDArray[np.float64]:
        """Per-step body twists ``ξ(u)`` [m, m, rad], shape (N, 3)."""
        return self.drive.twist(self.u)

    def poses_by(self, method: str = "exact") -> NDArray[np.float64]:
        """Noiseless poses by one integration method, shape (N+1, 3)."""
        check_choice("method", method, METHODS)
        return integrate_twist(self.twists, self.start, method)  # type: ignore[arg-type]

    @property
    def poses(self) -> NDArray[np.float64]:
        """Noiseless poses by exact steps (the SE(2) exponential), shape (N+1, 3)."""
        return self.poses_by("exact")

    @property
    def length(self) -> float:
        """Path length of the reference point ``Σ|(v₁, v₂)|`` [m]."""
        xi = self.twists
        return float(np.hypot(xi[:, 0], xi[:, 1]).sum())


def _path_twists(drive: Drive, trajectory: Trajectory) -> NDArray[np.float64]:
    """Per-step twists that drive the trajectory's path: its exact arcs, or for a drive that
    cannot turn, the chords between its poses in the fixed chassis frame."""
    if not drive.fixed_heading:
        ds = trajectory.ds
        return np.stack([ds, np.zeros_like(ds), trajectory.dtheta], axis=-1)
    p = trajectory.poses
    d = np.diff(p[:, :2], axis=0)
    c, s = math.cos(trajectory.start[2]), math.sin(trajectory.start[2])
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], np.zeros(len(d))], -1)


def follow(drive: Drive, trajectory: Trajectory) -> DrivePath:
    """Drive a geometric path with ``drive``: its measurements from the inverse kinematics.

    The path is the trajectory's exact arcs (its wheel travels and track only
    define the geometry). Integrated exactly, the result passes through the
    trajectory's poses; a drive with a fixed heading (synchro) passes through
    its positions and keeps the start heading.

    Raises ValueError (one line, naming the step) where the drive cannot follow.
    """
    u = drive.measurements(_path_twists(drive, trajectory))
    return DrivePath(drive, u, trajectory.dt, trajectory.start, trajectory.name)


def wheel_path(trajectory: Trajectory) -> DrivePath:
    """The trajectory's own wheel travels as the path of a :class:`Differential` drive of its track.

    Unlike :func:`follow` (which recomputes the travels from the arcs), the measurements are the
    trajectory's ``(Δs_r, Δs_l)`` bit for bit: the route of every run without a ``drive`` section.
    """
    u = np.stack([trajectory.ds_r, trajectory.ds_l], axis=-1)
    return DrivePath(Differential(trajectory.track), u, trajectory.dt, trajectory.start, trajectory.name)


def drive_path(drive: Drive, path: str, **params: Any) -> DrivePath:
    """:func:`follow` a path built by name (``trajectories.BUILDERS``) with keyword parameters."""
    check_choice("path", path, tuple(BUILDERS))
    return follow(drive, build(path, **params))
