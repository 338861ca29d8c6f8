"""The ``drive`` section of a run configuration: which drive, its geometry, its odometry errors.

Without a ``drive`` section a run is the differential drive of the trajectory's
track with the wheel constants ``k_r``, ``k_l``: the trajectory's own wheel travels as a
:class:`~pose_uncertainty.core.drives.Differential` path
(:func:`~pose_uncertainty.core.drives.wheel_path`) through the same drive stack, logged
as before (no ``drive`` key, Method C included). With one, the trajectory is the geometric path that the drive follows
(:func:`pose_uncertainty.core.drives.follow`), and Method A, Monte Carlo and
the exponential-coordinates Gaussian are those of the drive
(:mod:`pose_uncertainty.experiments.drive_run`)::

    drive:
      type: tricycle          # differential | skid_steer | tricycle | ackermann | two_axle
                              # | synchro | mdof | omni3
      wheelbase: 0.2          # m
      max_steering: 1.5708    # rad, in (0, π/2]
      errors:
        k: null               # m per metre of travel of every travel channel (null: k_r, k_l)
        steer_var: 0.02       # rad², per step, on every steering angle
        steer_bias: 0.0       # rad, true minus reported
        encoder: null         # Šafránek 2022's encoder sources instead of k (mapping, see below)
        slip: null            # skid_steer only: {chi_var [1], x_icr_var [m²]}

Geometry keys per type (:data:`GEOMETRY`; a key of another type is rejected):
``differential`` track; ``skid_steer`` track, chi, x_icr; ``tricycle`` wheelbase,
max_steering; ``ackermann`` wheelbase, track, max_steering; ``two_axle``
wheelbase, max_steering; ``synchro`` none; ``mdof`` wheels; ``omni3`` radius.
``track: null`` (the default) is the trajectory's track; every other key left
out takes the drive class's default (:mod:`pose_uncertainty.core.drives`), and
:meth:`DriveConfig.to_dict` writes it out.

Errors (:class:`pose_uncertainty.methods.drive_noise.DriveErrorModel`): ``k``
null takes the run's ``k_r``, ``k_l`` — one ``k`` for every travel channel when
they are equal, else ``k_r`` on the right and ``k_l`` on the left channel of a
drive that has them (differential, skid_steer, ackermann); a number or one
number per travel channel sets it directly. ``steer_var`` and ``steer_bias`` act
on the steering angles and must be 0 for a drive without any.
``encoder`` takes the keys of :class:`pose_uncertainty.methods.wheel_noise.WheelErrorSources`
(defaults: Šafránek 2022's chassis) and replaces ``k``.

A drive that cannot follow the configured path (a rotation in place with
limited steering, a sideways step of a car) is rejected when the configuration
is read, with the one-line error of :func:`~pose_uncertainty.core.drives.follow`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from ..core import trajectories
from ..core.drives import DRIVES, Drive, follow
from ..core.table_io import jsonable
from ..methods.drive_noise import DriveErrorModel, IcrSlip, channels
from ..methods.wheel_noise import WheelErrorSources
from .config_checks import check_keys, fail, real
from .config_keys import FROM_CODE, Key, units

__all__ = ["DRIVE_KEYS", "GEOMETRY", "DriveConfig", "DriveErrors", "check_path"]

#: Geometry keys of each drive type (the fields of its class in ``core.drives``).
GEOMETRY: dict[str, tuple[str, ...]] = {
    kind: tuple(f.name for f in fields(cls))  # type: ignore[arg-type]
    for kind, cls in DRIVES.items()
}

_NUMBERS = {"items": {"type": "number", "minimum": 0}}  # one number per channel

#: The keys of ``drive.errors.encoder``: the fields of WheelErrorSources, whose defaults (the
#: chassis of Němec 2012) they take.
ENCODER_KEYS: tuple[Key, ...] = (
    Key("pulses_per_rev", "integer", "1/rev", "Encoder pulses per wheel revolution [1/rev].", FROM_CODE, lo=1,
        hi=10_000_000),
    Key("wheel_diameter", "number", "m", "Wheel diameter [m].", FROM_CODE, lo=0.0, lo_open=True),
    Key("integration_time", "number", "s", "Time over which pulses are counted [s].", FROM_CODE, lo=0.0, lo_open=True),
    Key("surface_rel_std", "number", "1 (relative to the speed)",
        "Surface irregularity, std relative to the speed [1].", FROM_CODE, lo=0.0),
    Key("additive_std", "number", "m/s", "Additive white speed noise std [m/s].", FROM_CODE, lo=0.0),
    Key("quantisation", "boolean", "- (bool)", "Include the encoder quantisation.", FROM_CODE),
)

#: The keys of ``drive.errors.slip``.
SLIP_KEYS: tuple[Key, ...] = (
    Key("chi_var", "number", "1 (variance of chi)", "Variance of chi [1].", 0.0, lo=0.0),
    Key("x_icr_var", "number", "m^2 (variance of x_icr)", "Variance of x_icr [m^2].", 0.0, lo=0.0),
)

#: The keys of ``drive.errors`` (:class:`DriveErrors`).
ERROR_KEYS: tuple[Key, ...] = (
    Key("k", "number", "m (travel variance per metre of each travel channel; null = k_r, k_l)",
        "Travel variance per metre [m] of every travel channel (wheel, track, steering wheel, omni wheel), one "
        "number or one per travel channel; null = k_r, k_l (k_r on the right, k_l on the left channel; equal "
        "k_r, k_l for drives without right and left).", None, lo=0.0, nullable=True,
        extra={"type": ["number", "array", "null"], **_NUMBERS}),
    Key("steer_var", "number", "rad^2 (per-step variance of each steering angle)",
        "Per-step variance [rad^2] of every steering angle (one number or one per angle); must be 0 for a drive "
        "without steering.", 0.0, lo=0.0, extra={"type": ["number", "array"], **_NUMBERS}),
    Key("steer_bias", "number", "rad (steering bias, true minus reported)",
        "Steering-angle bias [rad], true minus reported (one number or one per angle).", 0.0,
        extra={"type": ["number", "array"], "items": {"type": "number"}}),
    Key("encoder", "section", "-",
        "The encoder, surface and additive errors of every travel channel (Němec 2012), in place of k "
        "(pose_uncertainty.methods.wheel_noise.WheelErrorSources); null = none.", None, nullable=True,
        keys=ENCODER_KEYS),
    Key("slip", "section", "-",
        "Random ICR of a skid_steer drive (its chi and x_icr are the means); null = none.", None, nullable=True,
        keys=SLIP_KEYS),
)

#: The keys of a ``drive`` section (:class:`DriveConfig`; geometry keys apply to some types only,
#: :data:`GEOMETRY`, and a geometry key left out takes the drive class's default).
DRIVE_KEYS: tuple[Key, ...] = (
    Key("type", "choice", "- (" + " | ".join(DRIVES) + ")",
        "Drive type: differential, skid_steer (tracks or skid-steered wheels, ICR model), tricycle, ackermann, "
        "two_axle (both axles steered), synchro, mdof (independently driven and steered wheels), omni3 (three "
        "omni wheels).", "differential", allowed=tuple(DRIVES)),
    Key("track", "number", "m (null = trajectory.track)",
        "Wheel or track separation b [m] (differential, skid_steer, ackermann's steered axle); null = "
        "trajectory.track.", None, nullable=True, lo=0.0, lo_open=True),
    Key("wheelbase", "number", "m",
        "Wheelbase [m] (tricycle, ackermann - rear axle to steered wheel(s); two_axle - between the axles); "
        "null = the drive's default, 0.3 m.", None, nullable=True, lo=0.0, lo_open=True),
    Key("max_steering", "number", "rad",
        "Largest steering angle [rad] in (0, pi/2] (tricycle, ackermann, two_axle); null = the drive's default, "
        "pi/3; pi/2 lets a tricycle rotate in place.", None, nullable=True, lo=0.0, hi=math.pi / 2, lo_open=True,
        rule=f"in (0, π/2] rad (allowed: steering up to ±90° = {math.pi / 2!r} rad)"),
    Key("chi", "number", "1 (ICR expansion factor)",
        "ICR expansion factor chi [1] of a skid_steer drive (the tracks' ICRs at +-chi b/2; 1 = no slip); "
        "null = 1.", None, nullable=True, lo=0.0, lo_open=True),
    Key("x_icr", "number", "m (longitudinal ICR offset)",
        "Longitudinal ICR offset [m] of a skid_steer drive (lateral slip -x_icr dtheta per step); null = 0 (a "
        "path with turns needs 0).", None, nullable=True),
    Key("radius", "number", "m (omni wheels from the centre)",
        "Distance R [m] of the three omni wheels from the centre (omni3); null = 0.15 m.", None, nullable=True,
        lo=0.0, lo_open=True),
    Key("wheels", "array", "m (body positions [x, y] of the wheels)",
        "Body positions [x, y] [m] of the wheels of an mdof drive (n >= 2, two distinct); null = the corners of "
        "a 0.3 m x 0.2 m rectangle.", None, nullable=True,
        extra={"minItems": 2, "items": {"type": "array", "items": {"type": "number"}, "minItems": 2,
                                        "maxItems": 2}}),
    Key("errors", "section", "-", "Odometry error sources of the drive "
        "(pose_uncertainty.methods.drive_noise.DriveErrorModel).", None, keys=ERROR_KEYS),
)

#: Keys of a ``drive`` section (geometry keys apply to some types only).
KEYS: tuple[str, ...] = tuple(k.name for k in DRIVE_KEYS)
_KEY = {k.name: k for k in DRIVE_KEYS}
_ERROR_KEYS = tuple(k.name for k in ERROR_KEYS)
_ENCODER_KEYS = tuple(k.name for k in ENCODER_KEYS)
_SLIP_KEYS = tuple(k.name for k in SLIP_KEYS)

#: Right and left travel channels, for ``k`` taken from ``k_r``, ``k_l``.
_RIGHT, _LEFT = ("ds_r", "ds_right"), ("ds_l", "ds_left")


def _numbers(key: str, value: Any, *, nonneg: bool) -> float | tuple[float, ...]:
    """One real number or a non-empty list of them."""
    if isinstance(value, list | tuple):
        if not value:
            raise fail(key, "a number or a non-empty list of numbers", value)
        return tuple(real(f"{key}[{i}]", v, nonneg=nonneg) for i, v in enumerate(value))
    return real(key, value, nonneg=nonneg)


def _plain(value: float | tuple[float, ...] | None) -> Any:
    return list(value) if isinstance(value, tuple) else value


@dataclass(frozen=True)
class DriveErrors:
    """The ``drive.errors`` section (module docstring); units: k [m], steer_var [rad²], steer_bias [rad].

    Attributes
    ----------
    k : float, tuple of float or None — travel variance per metre; None = the run's k_r, k_l
    steer_var, steer_bias : float or tuple of float — per steering channel or one for all
    encoder : dict or None — every field of WheelErrorSources
    slip : dict or None — ``chi_var`` [1], ``x_icr_var`` [m²]
    """

    k: float | tuple[float, ...] | None = None
    steer_var: float | tuple[float, ...] = 0.0
    steer_bias: float | tuple[float, ...] = 0.0
    encoder: dict[str, Any] | None = None
    slip: dict[str, float] | None = None

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> DriveErrors:
        """Validate ``drive.errors``; unknown keys and bad values raise a one-line ValueError."""
        check_keys("drive.errors", data, _ERROR_KEYS)
        k = data.get("k")
        encoder = data.get("encoder")
        slip = data.get("slip")
        return cls(
            k=None if k is None else _numbers("drive.errors.k", k, nonneg=True),
            steer_var=_numbers("drive.errors.steer_var", data.get("steer_var", 0.0), nonneg=True),
            steer_bias=_numbers("drive.errors.steer_bias", data.get("steer_bias", 0.0), nonneg=False),
            encoder=None if encoder is None else _encoder(encoder),
            slip=None if slip is None else _slip(slip),
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping with every parameter."""
        return {
            "k": _plain(self.k),
            "steer_var": _plain(self.steer_var),
            "steer_bias": _plain(self.steer_bias),
            "encoder": None if self.encoder is None else dict(self.encoder),
            "slip": None if self.slip is None else dict(self.slip),
        }


def _encoder(data: Any) -> dict[str, Any]:
    """``drive.errors.encoder``: every WheelErrorSources field, Šafránek 2022's defaults filled in."""
    check_keys("drive.errors.encoder", data, _ENCODER_KEYS)
    full = {f.name: data.get(f.name, f.default) for f in fields(WheelErrorSources)}
    return {k.name: k.check(f"drive.errors.encoder.{k.name}", full[k.name]) for k in ENCODER_KEYS}


def _slip(data: Any) -> dict[str, float]:
    check_keys("drive.errors.slip", data, _SLIP_KEYS)
    return {k.name: k.get("drive.errors.slip", data) for k in SLIP_KEYS}


def _geometry_value(key: str, value: Any) -> Any:
    """One geometry value, checked; ``track`` may be None (the trajectory's)."""
    where = f"drive.{key}"
    if key == "track" and value is None:
        return None
    if key != "wheels":
        return _KEY[key].check(where, value)
    # wheels: (x, y) body positions [m]
    if not isinstance(value, list | tuple) or len(value) < 2:
        raise fail(where, "a list of n >= 2 wheel positions [x, y] [m]", value)
    out = []
    for i, p in enumerate(value):
        if not isinstance(p, list | tuple) or len(p) != 2:
            raise fail(f"{where}[{i}]", "a position [x, y] [m]", p)
        out.append([real(f"{where}[{i}][0]", p[0]), real(f"{where}[{i}][1]", p[1])])
    return out


@dataclass(frozen=True)
class DriveConfig:
    """A run's drive: type, geometry (every parameter of the type) and error sources.

    Attributes
    ----------
    type : str — a key of :data:`pose_uncertainty.core.drives.DRIVES`
    geometry : dict — the type's geometry keys (:data:`GEOMETRY`) with their values
        [m, rad, 1]; ``track`` None = the trajectory's track
    errors : DriveErrors
    """

    type: str
    geometry: dict[str, Any] = field(default_factory=dict)
    errors: DriveErrors = field(default_factory=DriveErrors)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> DriveConfig:
        """Validate a ``drive`` mapping and fill in every default of its type.

        Raises
        ------
        ValueError — one line naming the key (``drive.wheelbase``), the value and what is allowed.
        """
        check_keys("drive", data, KEYS)
        kind = _KEY["type"].get("drive", data)
        allowed = GEOMETRY[kind]
        extra = sorted(k for k in data if k not in ("type", "errors", *allowed))
        if extra:
            raise ValueError(
                f"config key 'drive.{extra[0]}' does not apply to a {kind} drive "
                f"(allowed for {kind}: type, {', '.join((*allowed, 'errors'))})"
            )
        proto = DRIVES[kind]()  # the class's defaults (every drive has them)
        geometry: dict[str, Any] = {}
        for key in allowed:
            default = None if key == "track" else jsonable(getattr(proto, key))
            value = data.get(key)  # null = the class's default (the trajectory's track)
            geometry[key] = _geometry_value(key, default if value is None else value)
        out = cls(type=kind, geometry=geometry, errors=DriveErrors.from_dict(data.get("errors") or {}))
        if geometry.get("track", 0.0) is not None:  # else the trajectory's track: check_path checks it
            out.drive(math.nan)  # the geometry as a whole (e.g. Ackermann's steering limit)
        return out

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping with every parameter (round-trips via :meth:`from_dict`)."""
        return {"type": self.type, **jsonable(self.geometry), "errors": self.errors.to_dict()}

    def drive(self, track: float) -> Drive:
        """The drive; ``track`` [m] is used where the configured track is None (the trajectory's)."""
        geometry = dict(self.geometry)
        if "track" in geometry and geometry["track"] is None:
            geometry["track"] = track
        if "wheels" in geometry:
            geometry["wheels"] = tuple(tuple(p) for p in geometry["wheels"])
        try:
            return DRIVES[self.type](**geometry)
        except ValueError as exc:
            raise ValueError(f"config key 'drive' ({self.type}): {exc}") from None

    def error_model(self, drive: Drive, k_r: float, k_l: float) -> DriveErrorModel:
        """The drive's error model; ``k`` None takes ``k_r``, ``k_l`` (module docstring)."""
        e = self.errors
        k = _k_of(drive, e.k, k_r, k_l)
        has_angle = "angle" in drive.kinds
        for key in ("steer_var", "steer_bias"):
            if not has_angle and any(v != 0 for v in _as_tuple(getattr(e, key))):
                raise fail(f"drive.errors.{key}", f"0: the {drive.kind} drive has no steering angle",
                           _plain(getattr(e, key)))  # fmt: skip
        if e.slip is not None and drive.kind != "skid_steer":
            raise fail("drive.errors.slip", f"null: slip applies to a skid_steer drive, not {drive.kind}",
                       e.slip)  # fmt: skip
        model = DriveErrorModel(
            k=k, steer_var=e.steer_var, steer_bias=e.steer_bias,
            encoder=None if e.encoder is None else WheelErrorSources(**e.encoder),
            slip=None if e.slip is None else IcrSlip(**e.slip),
        )  # fmt: skip
        try:
            channels(drive, model)
        except ValueError as exc:
            raise ValueError(f"config key 'drive.errors' ({drive.kind}): {exc}") from None
        return model

    def describe(self) -> str:
        """One line for summaries and figure titles: the type and its geometry with units."""
        unit = {"track": "m", "wheelbase": "m", "max_steering": "rad", "chi": "", "x_icr": "m",
                "radius": "m", "wheels": "m"}  # fmt: skip
        parts = []
        for key, value in self.geometry.items():
            text = "trajectory's" if value is None else (f"{value:g}" if isinstance(value, float) else str(value))
            parts.append(f"{key} {text} {unit[key]}".rstrip())
        return f"{self.type} drive" + (f" ({', '.join(parts)})" if parts else "")

    @staticmethod
    def units() -> dict[str, Any]:
        """Unit of every key of a ``drive`` section."""
        return units(DRIVE_KEYS)


def _as_tuple(value: float | tuple[float, ...]) -> tuple[float, ...]:
    return value if isinstance(value, tuple) else (value,)


def _k_of(
    drive: Drive, k: float | tuple[float, ...] | None, k_r: float, k_l: float
) -> float | tuple[float, ...]:
    """``k`` as configured, or from the run's ``k_r``, ``k_l`` when it is None."""
    if k is not None:
        return k
    if k_r == k_l:
        return k_r
    travel = [c for c, kind in zip(drive.channels, drive.kinds, strict=True) if kind == "travel"]
    if len(travel) == 2 and {travel[0], travel[1]} & set(_RIGHT) and {travel[0], travel[1]} & set(_LEFT):
        return tuple(k_r if c in _RIGHT else k_l for c in travel)
    raise ValueError(
        f"config key 'drive.errors.k' is null and k_r = {k_r!r} != k_l = {k_l!r}, but the "
        f"{drive.kind} drive's travel channels {', '.join(travel)} have no right and left "
        "(allowed: k_r == k_l, or drive.errors.k)"
    )


def check_path(config: DriveConfig, trajectory: Mapping[str, Any], k_r: float, k_l: float) -> None:
    """Raise a one-line ValueError if the drive cannot follow the trajectory or its errors do not fit.

    Parameters
    ----------
    config : DriveConfig
    trajectory : mapping — the run's trajectory parameters (every default filled in)
    k_r, k_l : float — the run's wheel constants [m] (for ``errors.k`` None)
    """
    traj = trajectories.from_config(trajectory)
    drive = config.drive(traj.track)
    config.error_model(drive, k_r, k_l)
    try:
        follow(drive, traj)
    except ValueError as exc:
        raise ValueError(
            f"config key 'drive' ({config.type} on trajectory {trajectory['name']!r}): {exc}"
        ) from None
