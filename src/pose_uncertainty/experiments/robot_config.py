"""The pipeline's ``robots`` section: the bags it calibrates, each as logged jobs (key tables, checks).

Each entry of ``robots.runs`` is one robot: either a recorded bag (key ``bag``, with an
optional robot file ``robot_file``, :mod:`pose_uncertainty.robot.config`) or, when ``bag``
is null, a bag the pipeline writes itself from a simulated robot with known wheel radii,
track and wheel error constants (keys ``simulate`` and ``drive``:
:class:`pose_uncertainty.robot.simulate.SimulatedRobot` and
:func:`pose_uncertainty.robot.simulate.calibration_drive`). The calibration job writes
what ``pose-uncertainty robot calibrate`` writes; a simulated robot's true values are
logged beside its bag, and the recovered values are checked against them in the job.

The key tables below are the one definition of these keys: the value checks
(:func:`robots_config`), the defaults (the simulated robot's and the drive's are read from
their code) and the JSON Schema of ``workflow/schemas/config.schema.yaml``
(:func:`pose_uncertainty.experiments.schema.robots_schema`) come from them.
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Mapping
from typing import Any

from ..robot.simulated import SimulatedRobot, calibration_drive
from .config_checks import fail
from .config_keys import FROM_CODE, Key, section_values

__all__ = ["DRIVE_KEYS", "ROBOTS_KEYS", "ROBOT_KEYS", "SIMULATED_ROBOT_KEYS", "code_defaults", "robots_config"]


def _code_number(name: str, unit: str, doc: str, *, positive: bool = True) -> Key:
    """A number key whose default is its code's, > 0 (``positive``) or >= 0."""
    return Key(name, "number", unit, doc, FROM_CODE, lo=0.0, lo_open=positive)


#: The simulated robot (:class:`~pose_uncertainty.robot.simulate.SimulatedRobot`): its truth and its recording.
SIMULATED_ROBOT_KEYS: tuple[Key, ...] = (
    _code_number("radius_left", "m", "True radius of the left wheel."),
    _code_number("radius_right", "m", "True radius of the right wheel."),
    _code_number("track", "m", "True wheel separation b."),
    _code_number("nominal_radius", "m", "Wheel radius the robot's own odometry assumes (both wheels)."),
    _code_number("nominal_track", "m", "Wheel separation the robot's own odometry assumes."),
    _code_number("k_r", "m", "True right-wheel error constant: travel variance per metre travelled (Method A).", positive=False),
    _code_number("k_l", "m", "True left-wheel error constant: travel variance per metre travelled (Method A).", positive=False),
    _code_number("truth_position_std", "m", "Noise of each ground-truth position sample (x and y).", positive=False),
    _code_number("truth_heading_std", "rad", "Noise of each ground-truth heading sample.", positive=False),
    Key("wheel_rate", "number", "Hz", "Rate of the wheel (joint state) messages.", FROM_CODE, lo=0.0, hi=10000.0,
        lo_open=True),
    Key("truth_rate", "number", "Hz", "Rate of the ground-truth messages.", FROM_CODE, lo=0.0, hi=10000.0, lo_open=True),
    _code_number("truth_offset", "s", "Offset of the ground-truth stamps from the wheel stamps.", positive=False),
    _code_number("speed", "m/s", "Mean speed of the straight legs and arcs."),
    _code_number("angular_speed", "rad/s", "Mean angular speed of the turns in place."),
)

#: The commanded drive (:func:`~pose_uncertainty.robot.simulate.calibration_drive`).
DRIVE_KEYS: tuple[Key, ...] = (
    Key("side", "number", "m", "Side of the UMBmark squares (Borenstein & Feng 1996).", FROM_CODE, lo=0.0, hi=1000.0,
        lo_open=True),
    Key("laps", "integer", "1", "Squares driven clockwise, then as many counter-clockwise.", FROM_CODE, lo=1, hi=50),
    Key("arcs", "integer", "1", "S-bends (a quarter arc of radius 1 m left, one right) after the squares.", FROM_CODE,
        lo=0, hi=50),
)

#: One robot of ``robots.runs``.
ROBOT_KEYS: tuple[Key, ...] = (
    Key("title", "string", "-", "Title of the robot in the report (default: its name).", ""),
    Key("source", "string", "-", "Where the robot or its recording comes from, cited in the report.", ""),
    Key("description", "string", "-", "One or two sentences on the robot shown in the report.", ""),
    Key("bag", "string", "-", ("A recorded bag to calibrate (rosbag2 folder, .mcap, .db3 or ROS 1 .bag), relative to "
        "the working directory; null: the pipeline writes one from the simulated robot (keys simulate, drive)."),
        None, nullable=True),
    Key("robot_file", "string", "-", ("A robot file (radii, track, ticks, joints, topics; pose_uncertainty.robot.config) "
        "for a recorded bag; null: topics found by type, nominal geometry from the robot's odometry topic."),
        None, nullable=True),
    Key("seed", "integer", "1", ("Seed of the simulated robot's noise and of the calibration's Monte Carlo parts "
        "(nav2 fit, horizon check); null: the config's top-level seed."), None, nullable=True, lo=0, hi=2**32 - 1),
    Key("simulate", "section", "-", "The simulated robot (used when bag is null).", keys=SIMULATED_ROBOT_KEYS),
    Key("drive", "section", "-", "The simulated robot's commanded drive (used when bag is null).", keys=DRIVE_KEYS),
)

#: The ``robots`` section itself (``runs`` is the mapping of names to :data:`ROBOT_KEYS` entries).
ROBOTS_KEYS: tuple[Key, ...] = (
    Key("enabled", "boolean", "-", "Calibrate the robots and add the section \"Your robot\" to the report.", True),
)


def code_defaults() -> dict[str, Any]:
    """The defaults the robot keys take from the code they configure (the simulated robot, the drive)."""
    sim = {f.name: f.default for f in dataclasses.fields(SimulatedRobot)}
    drive = {p.name: p.default for p in inspect.signature(calibration_drive).parameters.values()}
    return {"simulate": {k.name: sim[k.name] for k in SIMULATED_ROBOT_KEYS},
            "drive": {k.name: drive[k.name] for k in DRIVE_KEYS}}  # fmt: skip


def _text(where: str, value: Any, nullable: bool) -> str | None:
    if value is None and nullable:
        return None
    if not isinstance(value, str) or (nullable and not value.strip()):
        raise fail(where, "a path" if nullable else "text", value)
    return value


def robots_config(config: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Every robot of the config's ``robots`` section, checked, with every default filled in.

    Returns ``{name: entry}`` (empty when the section is disabled or absent); an entry holds
    every key of :data:`ROBOT_KEYS`, ``seed`` resolved (the config's ``seed`` when null).
    ValueError naming the dotted key at fault.
    """
    section = config.get("robots") or {}
    top = section_values("robots", ROBOTS_KEYS, {k: v for k, v in section.items() if k != "runs"})
    if not top["enabled"]:
        return {}
    code = code_defaults()
    out: dict[str, dict[str, Any]] = {}
    for name, spec in (section.get("runs") or {}).items():
        where = f"robots.runs.{name}"
        if not isinstance(spec, Mapping):
            raise fail(where, "a mapping of robot keys", spec)
        entry = section_values(where, ROBOT_KEYS, spec, code)
        for key in ("title", "source", "description"):
            entry[key] = _text(f"{where}.{key}", entry[key], False)
        for key in ("bag", "robot_file"):
            entry[key] = _text(f"{where}.{key}", entry[key], True)
        entry["title"] = entry["title"] or name
        for sub, keys in (("simulate", SIMULATED_ROBOT_KEYS), ("drive", DRIVE_KEYS)):
            entry[sub] = section_values(f"{where}.{sub}", keys, entry[sub], code[sub])
        if entry["seed"] is None:
            entry["seed"] = int(config.get("seed", 0))
        out[str(name)] = entry
    return out
