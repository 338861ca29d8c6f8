"""The robot file: what a bag does not say about the robot.

A small YAML mapping; every key is optional (a bag with the robot's own odometry
topic gives the nominal geometry, topics are found by message type when only one
topic has the type) and an unknown key is an error naming it and the allowed keys.

Keys
----
``wheel_radius`` [m]
    Nominal radius of both wheels; or ``wheel_radius_left`` and ``wheel_radius_right``.
``track`` [m]
    Nominal wheel separation ``b``.
``ticks_per_revolution`` [1]
    Encoder counts per wheel revolution; needed when the wheels come as raw ticks.
``joints``
    ``{left: NAME, right: NAME}``: the joint names in ``sensor_msgs/msg/JointState``,
    or the indices (0, 1, ...) into the ``data`` of an integer ``*MultiArray`` of ticks.
``topics``
    ``{wheels: /topic, truth: /topic, odometry: /topic}``; ``wheels`` may also be
    ``{left: /topic, right: /topic}`` for two scalar tick topics (``std_msgs/msg/Int32``,
    ``Int64``, ...). ``truth: none`` says the bag has no ground truth.
``truth_frame``
    With ``tf2_msgs/msg/TFMessage`` ground truth: the ``child_frame_id`` of the robot's
    transform (default: the only child frame).
``truth_std``
    ``{position: m, heading: rad}``: the ground truth's own noise per sample, given
    instead of estimated.
``nominal_speed`` [m/s], ``update_rate`` [Hz]
    The speed and odometry publishing rate at which the exported twist covariances hold
    (default 0.5 m/s, 50 Hz).
``covariance_distance`` [m]
    The straight distance at which the exported (constant) pose covariance is given
    (default 1 m).
``update_min_d`` [m], ``update_min_a`` [rad]
    AMCL's update thresholds for which its alphas are fitted (nav2's defaults 0.25, 0.2).
``horizon_thresholds`` [m]
    95 % position error radii of the uncertainty horizon (default [0.05, 0.10, 0.50]).
``turn_radius`` [m]
    Radius of the turning path of the horizon (default 1 m).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.input_files import read_mapping_file

__all__ = ["ROBOT_KEYS", "RobotConfig", "read_robot_file", "robot_from_mapping"]

#: Every key of the robot file.
ROBOT_KEYS: tuple[str, ...] = (
    "wheel_radius", "wheel_radius_left", "wheel_radius_right", "track", "ticks_per_revolution",
    "joints", "topics", "truth_frame", "truth_std", "nominal_speed", "update_rate",
    "covariance_distance", "update_min_d", "update_min_a", "horizon_thresholds", "turn_radius",
)  # fmt: skip
_TOPIC_KEYS = ("wheels", "truth", "odometry")
_SIDES = ("left", "right")
_STD_KEYS = ("position", "heading")


@dataclass(frozen=True)
class RobotConfig:
    """The robot file, checked (module docstring for the keys and units).

    ``radius_left``, ``radius_right``, ``track`` and ``ticks_per_revolution`` are None when
    not given; ``joints`` maps ``left``/``right`` to a joint name or an array index;
    ``topics`` maps ``wheels``/``truth``/``odometry`` to a topic (``wheels`` may map to
    ``{left, right}``); ``truth_std`` is ``(position [m], heading [rad])`` or None.
    """

    radius_left: float | None = None
    radius_right: float | None = None
    track: float | None = None
    ticks_per_revolution: float | None = None
    joints: dict[str, str | int] = field(default_factory=dict)
    topics: dict[str, Any] = field(default_factory=dict)
    truth_frame: str | None = None
    truth_std: tuple[float, float] | None = None
    nominal_speed: float = 0.5
    update_rate: float = 50.0
    covariance_distance: float = 1.0
    update_min_d: float = 0.25
    update_min_a: float = 0.2
    horizon_thresholds: tuple[float, ...] = (0.05, 0.10, 0.50)
    turn_radius: float = 1.0

    @property
    def has_geometry(self) -> bool:
        """Whether the nominal radii and track are given."""
        return None not in (self.radius_left, self.radius_right, self.track)


def _positive(where: str, value: Any) -> float:
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not ok or not math.isfinite(float(value)) or float(value) <= 0:
        raise ValueError(f"{where} must be a positive number (allowed: > 0), got {value!r}")
    return float(value)


def _mapping(where: str, value: Any, allowed: tuple[str, ...]) -> dict[str, Any]:
    if not isinstance(value, Mapping):
        # a bad robot file is a ValueError like every other bad value (one line, exit status 2)
        raise ValueError(f"{where} must be a mapping with keys {list(allowed)}, got {value!r}")  # noqa: TRY004
    unknown = [k for k in value if k not in allowed]
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r} (allowed: {', '.join(allowed)})")
    return dict(value)


def _topic(where: str, value: Any) -> str | None:
    if value is None or (isinstance(value, str) and value.lower() == "none"):
        return None
    if not isinstance(value, str) or not value.startswith("/"):
        raise ValueError(f"{where} must be a topic name starting with '/', got {value!r}")
    return value


def _topics(value: Any) -> dict[str, Any]:
    raw = _mapping("topics", value, _TOPIC_KEYS)
    out: dict[str, Any] = {}
    for key, v in raw.items():
        if key == "wheels" and isinstance(v, Mapping):
            pair = _mapping("topics.wheels", v, _SIDES)
            if set(pair) != set(_SIDES):
                raise ValueError(f"topics.wheels must name both left and right topics, got {dict(v)!r}")
            out[key] = {s: _topic(f"topics.wheels.{s}", pair[s]) for s in _SIDES}
        else:
            out[key] = _topic(f"topics.{key}", v)
    return out


def _joints(value: Any) -> dict[str, str | int]:
    raw = _mapping("joints", value, _SIDES)
    for side, v in raw.items():
        if isinstance(v, bool) or not isinstance(v, str | int) or (isinstance(v, int) and v < 0):
            raise ValueError(
                f"joints.{side} must be a joint name or an array index >= 0, got {v!r}"
            )
    return raw


def robot_from_mapping(data: Mapping[str, Any], where: str = "robot file") -> RobotConfig:
    """A :class:`RobotConfig` from a mapping; ValueError naming the key at fault."""
    if not isinstance(data, Mapping):
        raise ValueError(f"{where} must be a mapping, got {type(data).__name__}")  # noqa: TRY004
    unknown = [k for k in data if k not in ROBOT_KEYS]
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r} (allowed: {', '.join(ROBOT_KEYS)})")
    kw: dict[str, Any] = {}
    if "wheel_radius" in data:
        if "wheel_radius_left" in data or "wheel_radius_right" in data:
            raise ValueError(
                f"{where}: give wheel_radius or wheel_radius_left and wheel_radius_right, not both"
            )
        kw["radius_left"] = kw["radius_right"] = _positive("wheel_radius", data["wheel_radius"])
    elif ("wheel_radius_left" in data) != ("wheel_radius_right" in data):
        raise ValueError(f"{where}: wheel_radius_left and wheel_radius_right go together")
    elif "wheel_radius_left" in data:
        kw["radius_left"] = _positive("wheel_radius_left", data["wheel_radius_left"])
        kw["radius_right"] = _positive("wheel_radius_right", data["wheel_radius_right"])
    for key in ("track", "ticks_per_revolution", "nominal_speed", "update_rate",
                "covariance_distance", "update_min_d", "update_min_a", "turn_radius"):  # fmt: skip
        if key in data:
            kw[key] = _positive(key, data[key])
    if "joints" in data:
        kw["joints"] = _joints(data["joints"])
    if "topics" in data:
        kw["topics"] = _topics(data["topics"])
    if "truth_frame" in data:
        if not isinstance(data["truth_frame"], str) or not data["truth_frame"]:
            raise ValueError(f"truth_frame must be a frame name, got {data['truth_frame']!r}")
        kw["truth_frame"] = data["truth_frame"]
    if "truth_std" in data:
        std = _mapping("truth_std", data["truth_std"], _STD_KEYS)
        if set(std) != set(_STD_KEYS):
            raise ValueError(f"truth_std must give both position [m] and heading [rad], got {std!r}")
        kw["truth_std"] = tuple(_positive(f"truth_std.{k}", std[k]) for k in _STD_KEYS)
    if "horizon_thresholds" in data:
        th = data["horizon_thresholds"]
        if not isinstance(th, list | tuple) or not th:
            raise ValueError(f"horizon_thresholds must be a list of radii [m], got {th!r}")
        kw["horizon_thresholds"] = tuple(_positive("horizon_thresholds", v) for v in th)
    return RobotConfig(**kw)


def read_robot_file(path: str | Path) -> RobotConfig:
    """Read and check a robot YAML file; ValueError (one line, naming the file) when it is bad."""
    p = Path(path)
    data = read_mapping_file(p, "robot", empty_ok=True)  # kind and size checked first, a repeated key refused
    try:
        return robot_from_mapping(data if data is not None else {}, str(p))
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg if msg.startswith(str(p)) else f"{p}: {msg}") from None
