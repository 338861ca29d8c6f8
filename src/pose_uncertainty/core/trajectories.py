"""Trajectories: per-step wheel travels at a fixed step, with controls and noiseless poses.

A :class:`Trajectory` is the sequence of per-step wheel travels ``(Δs_r, Δs_l)``
at step ``dt`` on a robot of track ``b``. Everything else — body travel
``Δs = (Δs_r+Δs_l)/2``, turn ``Δθ = (Δs_r−Δs_l)/b``, the controls ``(V, ω)``
and the noiseless poses (exact arcs) — is derived from them.

Builders cover every path of Němec 2012 ch. 3–4 and compose from segments:

>>> from pose_uncertainty import trajectories as tr
>>> t = tr.straight(length=1.0, speed=1.0, dt=0.01, track=0.2)
>>> t.n_steps, t.poses[-1].round(12).tolist()
(100, [1.0, 0.0, 0.0])

Speed profiles (per segment — the robot stops between segments):

* ``"constant"`` — constant speed;
* ``"ramp"`` — speed rises linearly from 0 for the first half of the segment
  and falls back to 0 in the second half; the peak is twice the nominal speed,
  so the segment takes the same time as at constant speed.

Each segment's duration is rounded to a whole number of steps (at least one);
the travel of every segment is exact.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .kinematics import integrate
from .validation import (
    check_choice,
    check_finite,
    check_last_axis,
    check_positive,
)

__all__ = [
    "BUILDERS",
    "DRIVE_KEYS",
    "PROFILES",
    "Arc",
    "Line",
    "Trajectory",
    "Turn",
    "arc",
    "build",
    "circle",
    "direct",
    "from_config",
    "from_segments",
    "n_steps",
    "right_angles",
    "rotation",
    "s_curve",
    "square",
    "straight",
    "tour",
]

PROFILES: tuple[str, ...] = ("constant", "ramp")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Per-step wheel travels of a differential-drive robot.

    Attributes
    ----------
    ds_r, ds_l : ndarray, shape (N,)
        Travel of the right and left wheel during each step [m].
    dt : float
        Step duration [s].
    track : float
        Wheel separation ``b`` [m].
    start : ndarray, shape (3,)
        Start pose ``(x, y, θ)`` [m, m, rad].
    name : str
        Human-readable name.
    """

    ds_r: NDArray[np.float64]
    ds_l: NDArray[np.float64]
    dt: float
    track: float
    start: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    name: str = ""

    def __post_init__(self) -> None:
        ds_r = check_finite("ds_r", self.ds_r)
        ds_l = check_finite("ds_l", self.ds_l)
        if ds_r.ndim != 1 or ds_r.shape != ds_l.shape:
            raise ValueError(
                "ds_r and ds_l must be 1-D arrays of equal length (allowed: shape (N,)), "
                f"got shapes {ds_r.shape} and {ds_l.shape}"
            )
        if ds_r.size == 0:
            raise ValueError("trajectory must have at least one step (allowed: N >= 1), got N=0")
        dt = float(check_positive("dt", self.dt))
        track = float(check_positive("track", self.track))
        start = check_last_axis("start", self.start, 3)
        if start.shape != (3,):
            raise ValueError(f"start must have shape (3,), got shape {start.shape}")
        check_finite("start", start)
        for arr in (ds_r, ds_l, start):
            arr.setflags(write=False)
        object.__setattr__(self, "ds_r", ds_r)
        object.__setattr__(self, "ds_l", ds_l)
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "track", track)
        object.__setattr__(self, "start", start)

    @property
    def n_steps(self) -> int:
        """Number of steps ``N``."""
        return int(self.ds_r.size)

    @property
    def duration(self) -> float:
        """Total time ``N·dt`` [s]."""
        return self.n_steps * self.dt

    @property
    def ds(self) -> NDArray[np.float64]:
        """Per-step travel of the axle centre ``Δs = (Δs_r+Δs_l)/2`` [m], shape (N,)."""
        return (self.ds_r + self.ds_l) / 2.0

    @property
    def dtheta(self) -> NDArray[np.float64]:
        """Per-step turn ``Δθ = (Δs_r−Δs_l)/b`` [rad], shape (N,)."""
        return (self.ds_r - self.ds_l) / self.track

    @property
    def V(self) -> NDArray[np.float64]:
        """Body speed per step [m/s], shape (N,)."""
        return self.ds / self.dt

    @property
    def omega(self) -> NDArray[np.float64]:
        """Turn rate per step [rad/s], shape (N,)."""
        return self.dtheta / self.dt

    @property
    def v_r(self) -> NDArray[np.float64]:
        """Right wheel speed per step [m/s], shape (N,)."""
        return self.ds_r / self.dt

    @property
    def v_l(self) -> NDArray[np.float64]:
        """Left wheel speed per step [m/s], shape (N,)."""
        return self.ds_l / self.dt

    @property
    def controls(self) -> NDArray[np.float64]:
        """Velocity-model controls ``(V, ω)`` per step [m/s, rad/s], shape (N, 2)."""
        return np.stack([self.V, self.omega], axis=-1)

    @property
    def times(self) -> NDArray[np.float64]:
        """Times of the poses ``0, dt, …, N·dt`` [s], shape (N+1,)."""
        return np.arange(self.n_steps + 1, dtype=np.float64) * self.dt

    @property
    def length(self) -> float:
        """Path length of the axle centre ``Σ|Δs|`` [m]."""
        return float(np.abs(self.ds).sum())

    @property
    def wheel_travel(self) -> tuple[float, float]:
        """Total absolute travel of the right and left wheel ``(Σ|Δs_r|, Σ|Δs_l|)`` [m]."""
        return float(np.abs(self.ds_r).sum()), float(np.abs(self.ds_l).sum())

    def poses_by(self, method: str = "exact") -> NDArray[np.float64]:
        """Noiseless poses by one integration method (Šafránek 2022 §2.2.2), shape (N+1, 3)."""
        return integrate(self.ds, self.dtheta, self.start, method=method)  # type: ignore[arg-type]

    @property
    def poses(self) -> NDArray[np.float64]:
        """Noiseless poses by exact arcs [m, m, rad], shape (N+1, 3)."""
        return self.poses_by("exact")

    def __repr__(self) -> str:
        end = self.poses[-1]
        return (
            f"Trajectory(name={self.name!r}, n_steps={self.n_steps}, dt={self.dt}, "
            f"track={self.track}, length={self.length:.6g} m, "
            f"end=({end[0]:.6g}, {end[1]:.6g}, {end[2]:.6g}))"
        )


# --- segments ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Line:
    """Straight segment of signed ``length`` [m] (negative = reverse)."""

    length: float


@dataclass(frozen=True)
class Arc:
    """Arc of ``radius`` [m] > 0 turning by signed ``angle`` [rad] (positive = left, CCW)."""

    radius: float
    angle: float


@dataclass(frozen=True)
class Turn:
    """Rotation in place by signed ``angle`` [rad] (positive = CCW)."""

    angle: float


Segment = Line | Arc | Turn


def _profile_fractions(n: int, profile: str) -> NDArray[np.float64]:
    """Fraction of a segment's travel covered in each of its ``n`` steps (sums to 1)."""
    u = np.linspace(0.0, 1.0, n + 1)
    if profile == "constant":
        s = u
    else:  # linear ramp up to twice the mean speed at half time, then down: s(u) piecewise quadratic
        s = np.where(u <= 0.5, 2.0 * u**2, 1.0 - 2.0 * (1.0 - u) ** 2)
    return np.diff(s)


def _segment_travel(seg: Segment, track: float) -> tuple[float, float, float]:
    """Return (total right travel, total left travel, nominal duration factor numerator)."""
    if isinstance(seg, Line):
        length = float(check_finite("length", seg.length))
        return length, length, abs(length)
    if isinstance(seg, Arc):
        radius = float(check_positive("radius", seg.radius))
        angle = float(check_finite("angle", seg.angle))
        length = radius * abs(angle)
        return length + angle * track / 2.0, length - angle * track / 2.0, length
    if isinstance(seg, Turn):
        angle = float(check_finite("angle", seg.angle))
        return angle * track / 2.0, -angle * track / 2.0, abs(angle)
    raise ValueError(f"segment must be Line, Arc or Turn, got {seg!r}")


#: keywords of :func:`from_segments` (the driving, not the geometry, of a path)
DRIVE_KEYS: tuple[str, ...] = ("speed", "angular_speed", "dt", "track", "profile", "start", "name")

#: above this many steps a trajectory is refused before any allocation (8 bytes × 2 × 10¹⁵)
_MAX_STEPS = 10**15


def _plan(
    segments: Sequence[Segment],
    speed: float,
    angular_speed: float,
    dt: float,
    track: float,
    profile: str,
    start: ArrayLike,
) -> tuple[list[tuple[float, float, int]], float, float]:
    """Validate the driving of ``segments``: per segment (right travel, left travel, steps).

    Allocates nothing of the size of the trajectory; returns ``(plan, dt, track)``.
    """
    v = float(check_positive("speed", speed))
    w = float(check_positive("angular_speed", angular_speed))
    step = float(check_positive("dt", dt))
    b = float(check_positive("track", track))
    check_choice("profile", profile, PROFILES)
    p0 = check_finite("start", check_last_axis("start", start, 3))
    if p0.shape != (3,):
        raise ValueError(f"start must have shape (3,), got shape {p0.shape}")
    if len(segments) == 0:
        raise ValueError("segments must not be empty (allowed: at least one segment), got []")
    plan = []
    for seg in segments:
        total_r, total_l, amount = _segment_travel(seg, b)
        n_float = amount / (w if isinstance(seg, Turn) else v) / step
        if not n_float < _MAX_STEPS:
            raise ValueError(
                f"dt must give fewer than {_MAX_STEPS:.0e} steps per segment "
                f"(allowed: duration / dt < {_MAX_STEPS:.0e}), got dt = {step!r} for a segment "
                f"of {amount!r} {'rad' if isinstance(seg, Turn) else 'm'}"
            )
        plan.append((total_r, total_l, max(1, round(n_float))))
    return plan, step, b


def from_segments(
    segments: Sequence[Segment],
    *,
    speed: float = 1.0,
    angular_speed: float = 1.0,
    dt: float = 0.01,
    track: float = 0.2,
    profile: str = "constant",
    start: ArrayLike = (0.0, 0.0, 0.0),
    name: str = "",
) -> Trajectory:
    """Compose a trajectory from segments driven one after another.

    Parameters
    ----------
    segments : sequence of Line, Arc, Turn
    speed : float [m/s], > 0 — nominal speed of the axle centre on lines and arcs
    angular_speed : float [rad/s], > 0 — nominal turn rate of rotations in place
    dt : float [s], > 0 — step
    track : float [m], > 0 — wheel separation
    profile : {"constant", "ramp"} — speed profile applied to each segment
    start : array_like, shape (3,) — start pose
    name : str

    Returns
    -------
    Trajectory
    """
    plan, step, b = _plan(segments, speed, angular_speed, dt, track, profile, start)
    parts_r, parts_l = [], []
    for total_r, total_l, n in plan:
        frac = _profile_fractions(n, profile)
        parts_r.append(total_r * frac)
        parts_l.append(total_l * frac)
    return Trajectory(
        ds_r=np.concatenate(parts_r),
        ds_l=np.concatenate(parts_l),
        dt=step,
        track=b,
        start=np.asarray(start, dtype=np.float64),
        name=name,
    )


# --- the paths of Němec 2012 ch. 3–4 --------------------------------------------------
# Each path is its segments (a function of the geometric parameters) driven by from_segments.


def _number_text(value: Any) -> str:
    """A number for a trajectory's name (``%g``); anything else as its repr (validated later)."""
    if isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool):
        return f"{value:g}"
    return repr(value)


def _straight(length: float = 1.0) -> list[Segment]:
    return [Line(length)]


def _arc(radius: float = 1.0, angle: float = math.pi / 2) -> list[Segment]:
    return [Arc(radius, angle)]


def _circle(radius: float = 1.0, laps: float = 1.0, direction: int = 1) -> list[Segment]:
    if direction not in (1, -1):
        raise ValueError(f"direction must be 1 or -1 (allowed: 1 = left, -1 = right), got {direction!r}")
    laps_ = float(check_positive("laps", laps))
    return [Arc(radius, direction * 2.0 * math.pi * laps_)]


def _rotation(angle: float = 2.0 * math.pi) -> list[Segment]:
    return [Turn(angle)]


def _s_curve(radius: float = 1.0) -> list[Segment]:
    return [Arc(radius, math.pi / 2), Arc(radius, -math.pi / 2)]


def _right_angles(dx: float = 2.0, dy: float = 2.0) -> list[Segment]:
    return [Line(dx), Turn(math.pi / 2), Line(dy), Turn(-math.pi / 2)]


def _direct(dx: float = 2.0, dy: float = 2.0) -> list[Segment]:
    x, y = (float(v) for v in check_finite("(dx, dy)", (dx, dy)))
    heading = math.atan2(y, x)
    return [Turn(heading), Line(math.hypot(x, y)), Turn(-heading)]


def straight(length: float = 1.0, **kw: Any) -> Trajectory:
    """Straight line of ``length`` [m] (negative = reverse). Keywords as :func:`from_segments`."""
    return from_segments(_straight(length), name=kw.pop("name", f"straight {_number_text(length)} m"), **kw)


def arc(radius: float = 1.0, angle: float = math.pi / 2, **kw: Any) -> Trajectory:
    """Arc of ``radius`` [m] turning by ``angle`` [rad] (positive = left)."""
    return from_segments(
        _arc(radius, angle), name=kw.pop("name", f"arc r={_number_text(radius)} m {_number_text(angle)} rad"), **kw
    )


def circle(radius: float = 1.0, laps: float = 1.0, direction: int = 1, **kw: Any) -> Trajectory:
    """Full circle(s) of ``radius`` [m]; ``laps`` may be fractional; ``direction`` +1 left, −1 right."""
    segments = _circle(radius, laps, direction)
    return from_segments(
        segments, name=kw.pop("name", f"circle r={_number_text(radius)} m x{float(laps):g}"), **kw
    )


def rotation(angle: float = 2.0 * math.pi, **kw: Any) -> Trajectory:
    """Rotation in place by ``angle`` [rad] at ``angular_speed``."""
    return from_segments(_rotation(angle), name=kw.pop("name", f"rotation {_number_text(angle)} rad"), **kw)


def s_curve(radius: float = 1.0, **kw: Any) -> Trajectory:
    """Two quarter circles, left then right: (0,0,0) → (2r, 2r, 0)."""
    return from_segments(_s_curve(radius), name=kw.pop("name", "two quarter circles"), **kw)


def right_angles(dx: float = 2.0, dy: float = 2.0, **kw: Any) -> Trajectory:
    """Straight ``dx``, turn +90°, straight ``dy``, turn −90°: (0,0,0) → (dx, dy, 0)."""
    return from_segments(_right_angles(dx, dy), name=kw.pop("name", "right angles"), **kw)


def direct(dx: float = 2.0, dy: float = 2.0, **kw: Any) -> Trajectory:
    """Turn towards the target, drive straight, turn back: (0,0,0) → (dx, dy, 0)."""
    return from_segments(_direct(dx, dy), name=kw.pop("name", "direct"), **kw)


def square(side: float = 4.0, direction: int = 1, laps: int = 1, **kw: Any) -> Trajectory:
    """The UMBmark square (Borenstein & Feng 1996): ``4·laps`` × (straight ``side`` [m], turn 90°).

    The first leg runs along the start heading; at each corner the robot turns
    in place by +π/2 (``direction`` +1, counter-clockwise, left) or −π/2 (−1,
    clockwise, right). After each lap the noiseless robot is back at its start
    pose, heading included. Keywords as :func:`from_segments`. (Not in
    :data:`BUILDERS` yet: run configs do not offer it.)
    """
    if direction not in (1, -1):
        raise ValueError(f"direction must be 1 or -1 (allowed: 1 = left/ccw, -1 = right/cw), got {direction!r}")
    if isinstance(laps, bool) or not isinstance(laps, int | np.integer) or laps < 1:
        raise ValueError(f"laps must be an integer >= 1 (allowed: 1, 2, 3, ...), got {laps!r}")
    side_ = float(check_positive("side", side))
    return from_segments(
        [Line(side_), Turn(direction * math.pi / 2)] * (4 * int(laps)),
        name=kw.pop("name", f"square {side_:g} m {'ccw' if direction == 1 else 'cw'} x{laps}"),
        **kw,
    )


def _tour(segments: Sequence[Sequence[Any]] = (("line", 1.0),), laps: int = 1) -> list[Segment]:
    """The segments of :func:`tour`, validated (one-line errors naming the bad item)."""
    if isinstance(laps, bool) or not isinstance(laps, int | np.integer) or laps < 1:
        raise ValueError(f"laps must be an integer >= 1 (allowed: 1, 2, 3, ...), got {laps!r}")
    if isinstance(segments, str) or not isinstance(segments, Sequence):
        raise ValueError(  # noqa: TRY004 (a configuration's one-line error is a ValueError)
            "segments must be a list of [kind, numbers...] (allowed: [['line', L], ['arc', r, angle], "
            f"['turn', angle]]), got {segments!r}"
        )
    kinds = {"line": (Line, 1), "arc": (Arc, 2), "turn": (Turn, 1)}
    segs: list[Segment] = []
    for i, item in enumerate(segments):
        if isinstance(item, str) or not isinstance(item, Sequence) or not item or item[0] not in kinds:
            raise ValueError(
                f"segments[{i}] must be [kind, numbers...] with kind line, arc or turn "
                f"(allowed: ['line', L], ['arc', r, angle], ['turn', angle]), got {item!r}"
            )
        cls, n_args = kinds[str(item[0])]
        args = list(item[1:])
        if len(args) != n_args or any(isinstance(a, bool) or not isinstance(a, int | float) for a in args):
            raise ValueError(f"segments[{i}] ({item[0]}) must have {n_args} number(s) after the kind, got {item!r}")
        segs.append(cls(*(float(a) for a in args)))
    return segs * int(laps)


def tour(segments: Sequence[Sequence[Any]] = (("line", 1.0),), laps: int = 1, **kw: Any) -> Trajectory:
    """A path of segments written as lists: ``["line", L]``, ``["arc", r, angle]``, ``["turn", angle]``.

    The configuration form of :func:`from_segments` (lengths and radii [m], angles [rad],
    positive = left), driven ``laps`` times, e.g. a lap of a room:
    ``[["line", 5], ["arc", 0.5, 1.5708], ...]`` (in a run configuration
    ``trajectory: {name: tour, segments: [[line, 1.0], [turn, 1.5708]]}``). Keywords as
    :func:`from_segments`.
    """
    return from_segments(_tour(segments, laps), name=kw.pop("name", "tour"), **kw)


BUILDERS: dict[str, Callable[..., Trajectory]] = {
    "straight": straight,
    "arc": arc,
    "circle": circle,
    "rotation": rotation,
    "s_curve": s_curve,
    "right_angles": right_angles,
    "direct": direct,
    "tour": tour,
}

#: the segments of each builder, from its geometric parameters
_SEGMENTS: dict[str, Callable[..., list[Segment]]] = {
    "straight": _straight,
    "arc": _arc,
    "circle": _circle,
    "rotation": _rotation,
    "s_curve": _s_curve,
    "right_angles": _right_angles,
    "direct": _direct,
    "tour": _tour,
}


@functools.cache
def _signature(fn: Callable[..., Any]) -> inspect.Signature:
    return inspect.signature(fn)


def _parameters(fn: Callable[..., Any]) -> frozenset[str]:
    return frozenset(_signature(fn).parameters)


def n_steps(name: str, **params: Any) -> int:
    """Number of steps N of ``build(name, **params)``, without building it (nothing of size N).

    Validates the parameters as the builder does (same ValueError messages), so a
    configuration can be checked and costed before anything is allocated.
    """
    check_choice("trajectory", name, tuple(BUILDERS))
    geometry = _parameters(_SEGMENTS[name])
    unknown = sorted(set(params) - geometry - set(DRIVE_KEYS))
    if unknown:
        raise ValueError(
            f"bad parameters for trajectory {name!r}: unexpected keyword(s) {', '.join(unknown)} "
            f"(allowed: {', '.join(sorted(geometry | set(DRIVE_KEYS)))})"
        )
    segments = _SEGMENTS[name](**{k: v for k, v in params.items() if k in geometry})
    drive = {k: v for k, v in params.items() if k in DRIVE_KEYS and k != "name"}
    defaults = _signature(from_segments).parameters
    kw = {k: drive.get(k, defaults[k].default) for k in DRIVE_KEYS if k != "name"}
    plan, _, _ = _plan(segments, **kw)
    return sum(n for _, _, n in plan)


def build(name: str, **params: Any) -> Trajectory:
    """Build a trajectory by builder name (``BUILDERS``) with keyword parameters.

    Raises ValueError naming the builder and listing the allowed names.
    """
    check_choice("trajectory", name, tuple(BUILDERS))
    try:
        return BUILDERS[name](**params)
    except TypeError as exc:
        raise ValueError(f"bad parameters for trajectory {name!r}: {exc}") from exc


def from_config(params: Mapping[str, Any]) -> Trajectory:
    """Build a trajectory from its configuration mapping: ``{"name": <builder>, **parameters}``.

    The one route from a configuration (a run's ``trajectory`` key, a study's
    parameters, a logged run) to a :class:`Trajectory`.
    """
    if not isinstance(params, Mapping) or "name" not in params:
        raise ValueError(f"trajectory must be a mapping with a 'name' key (e.g. {{name: straight}}), got {params!r}")
    return build(str(params["name"]), **{k: v for k, v in params.items() if k != "name"})
