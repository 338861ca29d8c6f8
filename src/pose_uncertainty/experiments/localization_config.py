"""The configuration of a localization run: its key tables, its checks, and :class:`LocalizationConfig`.

The run itself (execution, results, the pipeline's sets) is :mod:`pose_uncertainty.experiments.localization`.

A *localization run* simulates a robot driving a path in a world of landmarks and walls
with noisy wheels and sensors (:mod:`pose_uncertainty.localization.simulate`), runs each
configured Bayes filter — the EKF (Method A's prediction), the histogram filter (Method B's)
and the particle filter (Monte Carlo's) — on the same data, and measures them against the
true path. :func:`execute_localization` turns a :class:`LocalizationConfig` into a
:class:`LocalizationResult`; :mod:`pose_uncertainty.records.localization` writes and reads
it as one MCAP log, :mod:`pose_uncertainty.present.localization` draws it.

A configuration is a plain mapping (YAML or JSON; numbers such as ``1e-3`` may be written
as YAML reads them, as strings)::

    kind: localization
    name: room_tour
    seed: 7
    repeat: 10                       # R simulated runs: NEES averaged over them, success rates
    world: {file: config/worlds/room.yaml}   # or inline world keys; plus random_landmarks
    trajectory: {name: tour, segments: [[line, 5.0], [turn, 1.5708], ...], speed: 0.5, dt: 0.1}
    truth: {k_r: 1.0e-3, k_l: 1.0e-3, regime: per_step, path: commanded}
    sensors:
      landmarks: {range_std: 0.1, bearing_std: 0.05, max_range: 6.0, fov: 6.2832, period: 0.5}
      beams: {n_beams: 8, max_range: 8.0, sigma_hit: 0.05, period: 0.5}
    scenario: {kind: tracking, start_std: [0.05, 0.05, 0.02]}   # or global, kidnapped
    filters:
      ekf: {motion: {model: wheels}}
      histogram: {sensor: landmarks, resolution: 0.2, ntheta: 36}
      particle: {n_particles: 2000, resampling: systematic}
    success: {pos_tol: 0.5, head_tol: 0.25}
    log: {particles_every: 1, max_particles_logged: 500, grid_every: 5}

:meth:`LocalizationConfig.to_dict` returns every parameter, defaults included (a world
file is read in and logged inline, so the log holds the world it was run in);
:meth:`LocalizationConfig.units` gives the unit of each key. Each filter's ``motion``
defaults to the truth's own noise model (the filter knows the robot): the wheel model
with the truth's ``k_r, k_l`` for the EKF and the particle filter, the velocity model
with the matching α's (:func:`~pose_uncertainty.localization.motion.velocity_alphas_for_wheels`,
``scaling: abs``) for the histogram filter.

Seeds: run ``r`` of the ``R`` draws its truth and measurements from
``default_rng([seed, 0, r])`` and the particle filter from ``default_rng([seed, 1, r])``,
so every filter sees the same data and a result is a deterministic function of the
configuration.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import math
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis import localization as lm
from ..core import trajectories
from ..core.input_files import InputFileError, parse_mapping, read_text_file
from ..core.table_io import jsonable
from ..core.validation import check_choice, parse_numbers
from ..localization import particle, simulate
from ..localization.motion import K_WHEEL, MOTION_MODELS, Motion, velocity_alphas_for_wheels
from ..localization.resampling import SCHEMES
from ..localization.result import ASSOCIATIONS, SCENARIOS, Start
from ..localization.sensors import BeamSensor, RangeBearingSensor
from ..localization.world import World, world_from_dict
from ..methods.sampling import REGIMES
from .config import MAX_PARTICLES, MAX_SEED, TRAJECTORY_KEYS, _by_json
from .config_checks import ConfigWarning, builder_keywords
from .config_checks import check_keys as _check_keys
from .config_checks import fail as _fail
from .config_keys import FROM_CODE, Key, key_of, section_values, vector

__all__ = [
    "KIND",
    "LOCALIZATION_KEYS",
    "TRAJECTORY_BUILDERS",
    "LocalizationConfig",
    "build_world",
    "code_defaults",
    "is_localization_config",
]

#: The value of a localization configuration's ``kind`` key.
KIND = "localization"

#: Path builders a localization run offers: the dead-reckoning runs' and a room tour, a square.
TRAJECTORY_BUILDERS: dict[str, Callable[..., trajectories.Trajectory]] = {
    **trajectories.BUILDERS, "square": trajectories.square, "tour": trajectories.tour,
}  # fmt: skip

Array = NDArray[np.float64]


# ============================================================================= validation helpers


def is_localization_config(data: Any) -> bool:
    """Whether a run-configuration mapping is a localization run's (``kind: localization``)."""
    return isinstance(data, Mapping) and data.get("kind") == KIND


# ============================================================================= key tables

#: Largest number of landmarks of a world (listed and random) [1].
MAX_LANDMARKS: int = 100_000
#: Largest number of simulated runs R [1].
MAX_REPEAT: int = 10_000
#: Largest heading count of the histogram filter, beams of the laser [1].
MAX_NTHETA: int = 3600
MAX_BEAMS: int = 100_000
#: Largest thread count a filter may be given [1].
MAX_WORKERS: int = 256
#: Largest interval [step] of the logged particles and grids, and particles logged a step [1].
MAX_EVERY: int = 1_000_000_000
MAX_LOGGED: int = 1_000_000


#: The keys of ``world.random_landmarks``.
RANDOM_LANDMARK_KEYS: tuple[Key, ...] = (
    Key("count", "integer", "1", "Number of random landmarks drawn uniformly in the free space [1].", 0, lo=0,
        hi=MAX_LANDMARKS),
    Key("seed", "integer", "1", "Seed of their numpy Generator [1].", 0, lo=0, hi=MAX_SEED),
    Key("margin", "number", "m", "Distance from the world's bounds [m].", 0.5, lo=0.0),
)

#: The keys of ``world`` (the inline keys are those of a world file,
#: :data:`pose_uncertainty.localization.world.WORLD_SCHEMA`, which checks them further).
WORLD_KEYS: tuple[Key, ...] = (
    Key("file", "string", "- (path)", "World file (YAML or JSON), relative to the working directory; null = inline "
        "only.", None, nullable=True),
    Key("source", "string", "- (path)", "The file the world was read from (set by the run; informational).", ""),
    Key("name", "string", "-", "Name of the world.", ""),
    Key("bounds", "array", "m", "[x_min, x_max, y_min, y_max] [m] of a world without walls or image.", None,
        nullable=True, extra={"items": {"type": "number"}, "minItems": 4, "maxItems": 4}),
    Key("landmarks", "array", {"id": "1", "x": "m", "y": "m"},
        f"Point landmarks with unique integer ids [m] (at most {MAX_LANDMARKS:,}).", (),
        extra={"maxItems": MAX_LANDMARKS, "items": {
            "type": "object", "additionalProperties": False,
            "properties": {"id": {"description": "Landmark id.", "type": "integer", "minimum": 0, "default": 0},
                           "x": {"description": "x [m].", "type": "number", "default": 0.0},
                           "y": {"description": "y [m].", "type": "number", "default": 0.0}}}}),
    Key("walls", "section", {"segments": "m", "resolution": "m", "thickness": "m", "margin": "m"},
        "Occupancy grid rasterised from wall segments.", None, nullable=True, keys=(
            Key("segments", "array", "m", "Wall segments [x1, y1, x2, y2] [m].", (),
                extra={"items": {"type": "array", "items": {"type": "number"}, "minItems": 4, "maxItems": 4}}),
            Key("resolution", "number", "m", "Cell side [m].", 0.1, lo=0.0, lo_open=True),
            Key("thickness", "number", "m", "Wall thickness [m].", 0.0, lo=0.0),
            Key("margin", "number", "m", "Grid margin around the segments [m] (null = one cell).", None,
                nullable=True, lo=0.0))),
    Key("image", "section", {"path": "- (path)", "resolution": "m", "origin": "m", "occupied_thresh": "1",
                             "free_thresh": "1", "negate": "- (bool)", "sha256": "-"},
        "Occupancy grid read from a PGM or PNG image (ROS map_server conventions).", None, nullable=True, keys=(
            Key("path", "string", "- (path)", "The image file.", ""),
            Key("resolution", "number", "m", "Cell side [m].", 0.05, lo=0.0, lo_open=True),
            Key("origin", "array", "m", "World position [x, y] [m] of the lower-left pixel.", (0.0, 0.0),
                extra={"items": {"type": "number"}, "minItems": 2, "maxItems": 2}),
            Key("occupied_thresh", "number", "1", "Occupancy above which a cell is a wall [1].", 0.65,
                lo=0.0, hi=1.0),
            Key("free_thresh", "number", "1", "Occupancy below which a cell is free [1].", 0.196, lo=0.0, hi=1.0),
            Key("negate", "boolean", "- (bool)", "Whether white means occupied.", False),
            Key("sha256", "string", "-", "sha256 of the image (set by the run; a mismatch is refused).", ""))),
    Key("random_landmarks", "section", "-", "Landmarks drawn at random in the free space, after the listed ones.",
        None, keys=RANDOM_LANDMARK_KEYS),
)

#: The keys of ``trajectory``: the dead-reckoning runs' and those of a room tour and a square.
LOC_TRAJECTORY_KEYS: tuple[Key, ...] = (
    Key("name", "choice", "-", "Path builder (required): a dead-reckoning builder, square or tour.",
        allowed=tuple(TRAJECTORY_BUILDERS)),
    Key("side", "number", "m", "Side of a square [m].", FROM_CODE, lo=0.0, lo_open=True),
    *TRAJECTORY_KEYS[1:],
)

#: The keys of ``truth`` (the simulated robot).
TRUTH_KEYS: tuple[Key, ...] = (
    Key("k_r", "number", "m", "Right-wheel error constant of the simulated robot [m] (wheel-travel variance per "
        "metre).", K_WHEEL, lo=0.0),
    Key("k_l", "number", "m", "Left-wheel error constant of the simulated robot [m].", K_WHEEL, lo=0.0),
    Key("regime", "choice", "- (per_step | per_run)", "Wheel noise drawn every step or once per run.", "per_step",
        allowed=REGIMES),
    Key("path", "choice", "- (commanded | drifts)",
        "commanded: the robot follows the path and its odometry drifts; drifts: the reverse.", "commanded",
        allowed=simulate.TRUTHS),
)

#: The keys of ``sensors.landmarks`` (the fields of RangeBearingSensor, whose defaults they take).
LANDMARK_SENSOR_KEYS: tuple[Key, ...] = (
    Key("range_std", "number", "m", "Range noise std [m].", FROM_CODE, lo=0.0, lo_open=True),
    Key("bearing_std", "number", "rad", "Bearing noise std [rad].", FROM_CODE, lo=0.0, lo_open=True),
    Key("max_range", "number", "m", "Largest range measured [m].", FROM_CODE, lo=0.0, lo_open=True),
    Key("fov", "number", "rad", "Field of view [rad].", FROM_CODE, lo=0.0, lo_open=True),
    Key("period", "number", "s", "Time between measurements [s].", FROM_CODE, lo=0.0, lo_open=True),
)

#: The keys of ``sensors.beams`` (the fields of BeamSensor, whose defaults they take).
BEAM_SENSOR_KEYS: tuple[Key, ...] = (
    Key("n_beams", "integer", "1", "Beams per scan [1].", FROM_CODE, lo=1, hi=MAX_BEAMS),
    Key("fov", "number", "rad", "Field of view [rad].", FROM_CODE, lo=0.0, lo_open=True),
    Key("max_range", "number", "m", "Largest range measured [m].", FROM_CODE, lo=0.0, lo_open=True),
    Key("sigma_hit", "number", "m", "Std of a hit [m].", FROM_CODE, lo=0.0, lo_open=True),
    Key("lambda_short", "number", "1/m", "Rate of short readings [1/m].", FROM_CODE, lo=0.0, lo_open=True),
    Key("z_hit", "number", "1", "Weight of hits [1].", FROM_CODE, lo=0.0),
    Key("z_short", "number", "1", "Weight of short readings [1].", FROM_CODE, lo=0.0),
    Key("z_max", "number", "1", "Weight of max-range readings [1].", FROM_CODE, lo=0.0),
    Key("z_rand", "number", "1", "Weight of random readings [1].", FROM_CODE, lo=0.0),
    Key("period", "number", "s", "Time between scans [s].", FROM_CODE, lo=0.0, lo_open=True),
)

#: The keys of ``sensors``.
SENSOR_KEYS: tuple[Key, ...] = (
    Key("landmarks", "section", "-", "Range-bearing sensor of point landmarks.", None, nullable=True,
        keys=LANDMARK_SENSOR_KEYS),
    Key("beams", "section", "-", "Laser scanner (the beam model).", None, nullable=True, keys=BEAM_SENSOR_KEYS),
)

#: The keys of ``scenario``.
SCENARIO_KEYS: tuple[Key, ...] = (
    Key("kind", "choice", "- (tracking | global | kidnapped)", "What the filters know of the start.", "tracking",
        allowed=SCENARIOS),
    Key("start_std", "array", "(m, m, rad)", "Std of the filters' initial belief about the start (tracking).",
        (0.05, 0.05, 0.02), extra={"items": {"type": "number", "minimum": 0}, "minItems": 3, "maxItems": 3}),
    Key("kidnap_step", "integer", "step", "Step at which the robot is carried away (kidnapped; default N/2).",
        None, nullable=True, lo=1, hi=MAX_EVERY),
    Key("kidnap_pose", "array", "(m, m, rad)", "Where it is carried (kidnapped).", None, nullable=True,
        extra={"items": {"type": "number"}, "minItems": 3, "maxItems": 3}),
)

#: The keys of a filter's ``motion`` (Motion); null = the truth's own model.
MOTION_KEYS: tuple[Key, ...] = (
    Key("model", "choice", "- (wheels | velocity | odometry)", "Motion model (default: the truth's).", None,
        allowed=MOTION_MODELS, nullable=True),
    Key("k_r", "number", "m", "Right-wheel error constant [m]; null = the truth's.", None, nullable=True, lo=0.0),
    Key("k_l", "number", "m", "Left-wheel error constant [m]; null = the truth's.", None, nullable=True, lo=0.0),
    Key("alphas", "array", "1", "Error constants [1]: 6 (velocity) or 4 (odometry); null = matched to the truth "
        "(velocity) or 0.05 each.", None, nullable=True, extra={"items": {"type": "number", "minimum": 0}}),
    Key("noise", "choice", "- (normal | triangular)", "Noise density.", None, allowed=("normal", "triangular"),
        nullable=True),
    Key("scaling", "choice", "- (squared | abs)", "Variance scaling: alpha*u^2 (squared) or alpha*|u| (abs).", None,
        allowed=("squared", "abs"), nullable=True),
)

_MOTION = Key("motion", "section", {k.name: k.unit for k in MOTION_KEYS},
              "The filter's motion model; left out, the truth's own.", None, nullable=True, keys=MOTION_KEYS)
_ASSOCIATION = Key("association", "choice", "- (known | ml)",
                   "Landmark association: known ids or maximum likelihood.", "known", allowed=ASSOCIATIONS)
_WORKERS = Key("workers", "integer", "1", "Threads [1] (results do not depend on it).", 1, lo=1, hi=MAX_WORKERS)

#: The keys of ``filters.ekf``.
EKF_KEYS: tuple[Key, ...] = (
    Key("sensor", "choice", "-", "Sensor the filter uses.", "landmarks", allowed=("landmarks",)),
    _MOTION, _ASSOCIATION,
)

#: The keys of ``filters.histogram``.
HISTOGRAM_KEYS: tuple[Key, ...] = (
    Key("sensor", "choice", "-", "Sensor the filter uses (default: the first configured).", "landmarks",
        allowed=("landmarks", "beams")),
    _MOTION,
    Key("resolution", "number", "m", "Cell side [m] (null = the world's grid).", None, nullable=True, lo=0.0, lo_open=True),
    Key("ntheta", "integer", "1", "Heading cells [1].", 36, lo=1, hi=MAX_NTHETA),
    Key("mask_occupied", "boolean", "- (bool)", "No belief in occupied cells.", True),
    _ASSOCIATION, _WORKERS,
)

#: The keys of ``filters.particle`` (the fields of ParticleFilterConfig, whose defaults they take).
PARTICLE_KEYS: tuple[Key, ...] = (
    Key("sensor", "choice", "-", "Sensor the filter uses (default: the first configured).", "landmarks",
        allowed=("landmarks", "beams")),
    _MOTION,
    Key("n_particles", "integer", "1", "Particles [1].", FROM_CODE, lo=1, hi=MAX_PARTICLES),
    Key("resampling", "choice", "-", "Resampling scheme.", FROM_CODE, allowed=tuple(SCHEMES)),
    Key("ess_threshold", "number", "1 (fraction of n)", "Resample when the effective sample size falls below this "
        "fraction of n [1].", FROM_CODE, lo=0.0, hi=1.0, lo_open=True),
    Key("injection", "choice", "- (none | fixed | augmented)", "Random particles injected.", FROM_CODE,
        allowed=("none", "fixed", "augmented")),
    Key("injection_fraction", "number", "1", "Fraction injected (fixed) [1].", FROM_CODE, lo=0.0, hi=1.0),
    Key("alpha_slow", "number", "1", "Slow average rate (augmented) [1].", FROM_CODE, lo=0.0, lo_open=True),
    Key("alpha_fast", "number", "1", "Fast average rate (augmented) [1].", FROM_CODE, lo=0.0, lo_open=True),
    _ASSOCIATION,
    Key("dtype", "choice", "-", "Floating type of the particles.", FROM_CODE, allowed=("float64", "float32")),
    Key("hdr_resolution", "number", "m", "Cell of the highest-density region measure [m].", FROM_CODE,
        lo=0.0, lo_open=True),
    _WORKERS,
)

#: The keys of ``filters``.
FILTER_KEYS: tuple[Key, ...] = (
    Key("ekf", "section", "-", "The extended Kalman filter (Method A's prediction).", None, nullable=True,
        keys=EKF_KEYS),
    Key("histogram", "section", "-", "The histogram filter (Method B's).", None, nullable=True,
        keys=HISTOGRAM_KEYS),
    Key("particle", "section", "-", "The particle filter (Monte Carlo's).", None, nullable=True,
        keys=PARTICLE_KEYS),
)

#: The keys of ``success``.
SUCCESS_KEYS: tuple[Key, ...] = (
    Key("pos_tol", "number", "m", "Position error of a success [m].", 0.5, lo=0.0, lo_open=True),
    Key("head_tol", "number", "rad", "Heading error of a success [rad].", 0.25, lo=0.0, hi=math.pi, lo_open=True),
)

#: The keys of ``log``.
LOG_KEYS: tuple[Key, ...] = (
    Key("particles_every", "integer", "step", "Particles logged every this many steps (0: none) [step].", 1, lo=0,
        hi=MAX_EVERY),
    Key("max_particles_logged", "integer", "1", "Particles logged a step, at most [1].", 500, lo=1,
        hi=MAX_LOGGED),
    Key("grid_every", "integer", "step", "Histogram grids logged every this many steps (0: none) [step].", 10,
        lo=0, hi=MAX_EVERY),
)

#: The keys of a localization run configuration (:class:`LocalizationConfig`), in the order of its log.
LOCALIZATION_KEYS: tuple[Key, ...] = (
    Key("kind", "choice", "-", "The run kind (a run configuration file with kind localization is a localization "
        "run).", KIND, allowed=(KIND,)),
    Key("name", "name", "-", "Run name; set by the sweep to the run id.", "localization"),
    Key("seed", "integer", "1", "Seed of the run [1]; run r of R draws its data from default_rng([seed, 0, r]), "
        "the particle filter from [seed, 1, r].", 0, lo=0, hi=MAX_SEED),
    Key("repeat", "integer", "1", "Number R of simulated runs (independent noise) the measures cover; the NEES is "
        "averaged over them, success is counted in them [1].", 1, lo=1, hi=MAX_REPEAT),
    Key("world", "section", "-", "The world: {file: PATH} (YAML/JSON, read in and logged inline) and/or inline "
        "keys of a world file, plus random landmarks (required).", None, keys=WORLD_KEYS),
    Key("trajectory", "section", "-", "The commanded path: a builder and its parameters (required).", None,
        keys=LOC_TRAJECTORY_KEYS),
    Key("truth", "section", "-", "The simulated robot's wheel noise and which path it follows.", None,
        keys=TRUTH_KEYS),
    Key("sensors", "section", "-", "The sensors (required: landmarks, beams or both).", None, keys=SENSOR_KEYS),
    Key("scenario", "section", "-", "What the filters know of the start: tracking, global or kidnapped.", None,
        keys=SCENARIO_KEYS),
    Key("filters", "section", "-", "The filters run on the same data (required: at least one).", None,
        keys=FILTER_KEYS),
    Key("success", "section", "-", "When a filter's estimate counts as a success.", None, keys=SUCCESS_KEYS),
    Key("log", "section", "-", "What the log keeps of the filters' beliefs.", None, keys=LOG_KEYS),
)


def code_defaults() -> dict[str, Any]:
    """The defaults the localization keys take from the code they configure (builders, dataclasses)."""
    traj: dict[str, Any] = {}
    for name, fn in TRAJECTORY_BUILDERS.items():
        for k, v in builder_keywords("trajectory", fn, {"name": name})[0].items():
            traj.setdefault(k, v)
    def fields_of(cls: Any) -> dict[str, Any]:
        return {f.name: f.default for f in dataclasses.fields(cls) if f.default is not dataclasses.MISSING}
    return {"trajectory": jsonable(traj), "sensors": {"landmarks": fields_of(RangeBearingSensor),
                                                      "beams": fields_of(BeamSensor)},
            "filters": {"particle": fields_of(particle.ParticleFilterConfig)}}  # fmt: skip



def _build(where: str, cls: Any, params: Mapping[str, Any]) -> Any:
    """``cls(**params)``, its ValueError re-worded to name the full config key."""
    try:
        return cls(**params)
    except ValueError as exc:
        msg = str(exc)
        head = msg.split(" ", 1)[0]
        if head in params:
            raise ValueError(f"config key '{where}.{head}'{msg[len(head):]}") from None
        raise ValueError(f"config key '{where}': {msg}") from None


def _dataclass_params(where: str, cls: Any, keys: tuple[Key, ...], data: Any) -> dict[str, Any]:
    """A section configuring a frozen dataclass: checked by its key table, the dataclass's defaults
    filled in, then the dataclass's own checks (with the full key in the message)."""
    code = {f.name: f.default for f in dataclasses.fields(cls) if f.default is not dataclasses.MISSING}
    out = section_values(where, keys, data, code)
    _build(where, cls, out)
    return out


def _builder_params(where: str, fn: Callable[..., Any], data: Mapping[str, Any]) -> dict[str, Any]:
    """Every keyword parameter of ``fn`` (and of from_segments it forwards to), defaults filled in."""
    defaults, params = builder_keywords(where, fn, data)
    return jsonable({**defaults, **params})


# ============================================================================= sections


def _trajectory(data: Any) -> tuple[dict[str, Any], trajectories.Trajectory]:
    if not isinstance(data, Mapping) or "name" not in data:
        raise _fail("trajectory", "a mapping with a 'name' key (e.g. {name: tour, segments: [[line, 5.0]]})", data)
    name = key_of(LOC_TRAJECTORY_KEYS, "name").check("trajectory.name", data["name"])
    full = {"name": name, **_builder_params("trajectory", TRAJECTORY_BUILDERS[name], data)}
    try:
        traj = TRAJECTORY_BUILDERS[name](**{k: v for k, v in full.items() if k != "name"})
    except (ValueError, TypeError) as exc:
        raise ValueError(f"config key 'trajectory' ({name}): {exc}") from None
    return full, traj


def _read_world_file(path: str) -> tuple[dict[str, Any], Path]:
    p = Path(path)
    try:  # kind and size checked before reading, a repeated key refused
        text = read_text_file(p, "world")
        data = copy.deepcopy(_parse_mapping(text, str(p), p.suffix.lower() == ".json"))  # (a copy: the caller may change it)
    except InputFileError as exc:
        raise ValueError(f"config key 'world.file': {exc}") from None
    return dict(data), p.parent


@functools.lru_cache(maxsize=16)
def _parse_mapping(text: str, name: str, json_syntax: bool) -> dict[str, Any]:
    """The mapping of a world file's text, once per text: every run of a sweep reads the same file."""
    return parse_mapping(text, name, json_syntax, "world")


def _random_landmarks(data: Any) -> dict[str, Any]:
    return section_values("world.random_landmarks", RANDOM_LANDMARK_KEYS, data)


def _world(data: Any) -> dict[str, Any]:
    """The world section, normalised: a file read in, an image pinned by its sha256, random landmarks kept as a spec."""
    if not isinstance(data, Mapping):
        raise _fail("world", "a mapping (world keys, or {file: PATH})", data)
    data = {k: v for k, v in data.items() if v is not None}  # null = not given
    base = Path(".")
    out: dict[str, Any] = {}
    if "file" in data:
        src = data.pop("file")
        if not isinstance(src, str):
            raise _fail("world.file", "a path", src)
        inline, base = _read_world_file(src)
        out["source"] = src
        data = {**parse_numbers(inline), **data}
    if "source" in data:
        src_given = str(data.pop("source"))
        out.setdefault("source", src_given)
    rnd = _random_landmarks(data.pop("random_landmarks", {"count": 0}))
    listed = data.get("landmarks") or []
    if isinstance(listed, list | tuple) and len(listed) + rnd["count"] > MAX_LANDMARKS:
        raise _fail("world.landmarks", f"at most {MAX_LANDMARKS:,} landmarks, listed and random",
                    f"{len(listed):,} listed and {rnd['count']:,} random")  # fmt: skip
    sha = None
    if isinstance(data.get("image"), Mapping):
        img = dict(data["image"])
        sha = img.pop("sha256", None)
        if isinstance(img.get("path"), str):
            img["path"] = str(base / img["path"]) if sha is None else img["path"]
        data["image"] = img
    try:
        _validated_world(data)  # validated against the world schema (one line naming key, value, range)
    except ValueError as exc:
        raise ValueError(f"config key 'world': {exc}") from None
    if "image" in data:
        digest = hashlib.sha256(Path(data["image"]["path"]).read_bytes()).hexdigest()
        if sha is not None and sha != digest:
            raise _fail("world.image.sha256", f"the sha256 of {data['image']['path']} ({digest})", sha)
        data["image"] = {**data["image"], "sha256": digest}
    out.update(jsonable(data))
    out["random_landmarks"] = rnd
    return out


def _outside(xy: Array, bounds: tuple[float, float, float, float]) -> Array:
    """Distance [m] of each point (..., 2) outside the box ``bounds`` (0 inside)."""
    x0, x1, y0, y1 = bounds
    dx = np.maximum(np.maximum(x0 - xy[..., 0], xy[..., 0] - x1), 0.0)
    dy = np.maximum(np.maximum(y0 - xy[..., 1], xy[..., 1] - y1), 0.0)
    return np.asarray(np.hypot(dx, dy), dtype=np.float64)


def _check_world(w: World, tr: trajectories.Trajectory, sensors: Mapping[str, Any]) -> None:
    """Refuse a world the run cannot work in; warn (:class:`ConfigWarning`) of one that is unusual.

    Refused (ValueError, one line): a listed landmark outside the world's bounds; a start pose
    outside them; a landmark sensor in a world without landmarks (its association rates would be
    0/0). Warned: a path that leaves the bounds (measure: the largest distance [m] of a path pose
    outside them), a path through occupied cells (measure: the fraction of its poses in them).
    """
    b = w.bounds
    assert b is not None  # World fills its bounds in
    box = f"[{b[0]:g}, {b[1]:g}] x [{b[2]:g}, {b[3]:g}] m"
    far = _outside(w.landmarks, b)
    if far.size and far.max() > 0:
        i = int(np.argmax(far))
        raise _fail(f"world.landmarks[{i}]", f"inside the world's bounds {box}",
                    {"id": int(w.landmark_ids[i]), "x": float(w.landmarks[i, 0]), "y": float(w.landmarks[i, 1])})
    start = np.asarray(tr.start, dtype=np.float64)
    if _outside(start[:2], b) > 0:
        raise _fail("trajectory.start", f"a pose inside the world's bounds {box}", [float(v) for v in start])
    if "landmarks" in sensors and w.n_landmarks == 0:
        raise ValueError("config key 'world.landmarks' holds no landmark (nor world.random_landmarks.count), "
                         "but sensors.landmarks is configured; allowed: at least one landmark, or no "
                         "sensors.landmarks")  # fmt: skip
    out = float(_outside(tr.poses[:, :2], b).max())
    if out > 0:
        warnings.warn(f"config key 'trajectory': the path leaves the world's bounds {box} by up to {out:.3g} m "
                      "(the largest distance of a path pose outside them)", ConfigWarning, stacklevel=3)  # fmt: skip
    if w.grid is not None:
        inside = _outside(tr.poses[:, :2], b) == 0
        occ = float(np.mean(w.grid.is_occupied(tr.poses[inside, :2]))) * inside.mean() if inside.any() else 0.0
        if occ > 0:
            warnings.warn(f"config key 'trajectory': {100 * occ:.3g} % of the path's poses lie in occupied cells "
                          "(walls) of the world", ConfigWarning, stacklevel=3)  # fmt: skip


#: The worlds checked while configurations are read, by their JSON text (a sweep's runs share one world:
#: building it once, not once per run, is most of the time the workflow takes to read a localization set).
#: Used to check a configuration only; a run builds its own (:meth:`LocalizationConfig.build_world`).
_CHECKED_WORLDS: dict[bool, dict[str, Any]] = {}


def _validated_world(data: Mapping[str, Any], build: bool = False) -> World:
    """:func:`world_from_dict` of a world section (``build``: :func:`build_world` of a normalised one), each
    distinct section built once; a world with an image file is built every time (the file may change)."""
    make = build_world if build else world_from_dict
    if "image" in data:
        return make(data)
    return _by_json(_CHECKED_WORLDS.setdefault(build, {}), data, make)  # type: ignore[no-any-return]


def build_world(spec: Mapping[str, Any]) -> World:
    """The :class:`World` of a normalised world section (random landmarks drawn from their seed).

    Random landmarks are uniform over the world's bounds shrunk by ``margin`` [m], outside
    occupied cells, with ids after the listed ones (``default_rng(seed)``, drawn in batches).
    """
    data = {k: v for k, v in spec.items() if k not in ("source", "random_landmarks")}
    if "image" in data:
        data["image"] = {k: v for k, v in data["image"].items() if k != "sha256"}
    w = world_from_dict(data)
    rnd = spec.get("random_landmarks", {"count": 0})
    n = int(rnd["count"])
    if n == 0:
        return w
    x0, x1, y0, y1 = w.bounds  # type: ignore[misc]
    mg = float(rnd["margin"])
    if not (x1 - x0 > 2 * mg and y1 - y0 > 2 * mg):
        raise _fail("world.random_landmarks.margin", f"less than half the world's size ({x1 - x0:g} x {y1 - y0:g} m)", mg)
    rng = np.random.default_rng(int(rnd["seed"]))
    pts = np.zeros((0, 2))
    for _ in range(1000):
        cand = np.stack([rng.uniform(x0 + mg, x1 - mg, 2 * n), rng.uniform(y0 + mg, y1 - mg, 2 * n)], axis=-1)
        if w.grid is not None:
            cand = cand[~w.grid.is_occupied(cand)]
        pts = np.concatenate([pts, cand])[:n]
        if pts.shape[0] == n:
            break
    else:  # pragma: no cover - a world that is (almost) all walls
        raise _fail("world.random_landmarks.count", "reachable in the free space", n)
    first = int(w.landmark_ids.max()) + 1 if w.n_landmarks else 0
    return World(np.concatenate([w.landmarks, pts]), np.concatenate([w.landmark_ids, first + np.arange(n)]),
                 w.grid, w.segments, w.bounds, w.name)  # fmt: skip


def _truth(data: Any) -> dict[str, Any]:
    return section_values("truth", TRUTH_KEYS, data)


def _sensors(data: Any) -> dict[str, Any]:
    _check_keys("sensors", data, tuple(k.name for k in SENSOR_KEYS))
    out: dict[str, Any] = {}
    if data.get("landmarks") is not None:
        out["landmarks"] = _dataclass_params("sensors.landmarks", RangeBearingSensor, LANDMARK_SENSOR_KEYS,
                                             data["landmarks"])  # fmt: skip
    if data.get("beams") is not None:
        out["beams"] = _dataclass_params("sensors.beams", BeamSensor, BEAM_SENSOR_KEYS, data["beams"])
    if not out:
        raise ValueError("config key 'sensors' must configure landmarks or beams (allowed: one or both), got none")
    return out


def _scenario(data: Any, n_steps: int) -> dict[str, Any]:
    given = section_values("scenario", SCENARIO_KEYS, data)
    kind = given["kind"]
    out: dict[str, Any] = {"kind": kind, "start_std": vector("scenario.start_std", given["start_std"], 3, nonneg=True)}
    step, pose = given["kidnap_step"], given["kidnap_pose"]
    if kind == "kidnapped":
        out["kidnap_step"] = key_of(SCENARIO_KEYS, "kidnap_step").check("scenario.kidnap_step",
                                                                      n_steps // 2 if step is None else step)
        if out["kidnap_step"] > n_steps:
            raise _fail("scenario.kidnap_step", f"a step in 1..{n_steps} (the trajectory's N)", step)
        if pose is None:
            raise ValueError("config key 'scenario.kidnap_pose' is missing (allowed: [x, y, theta] for kind kidnapped)")
        out["kidnap_pose"] = vector("scenario.kidnap_pose", pose, 3)
    else:
        for key, value in (("kidnap_step", step), ("kidnap_pose", pose)):
            if value is not None:
                raise _fail(f"scenario.{key}", "null unless scenario.kind is 'kidnapped'", value)
        out["kidnap_step"], out["kidnap_pose"] = None, None
    return out


def _motion(where: str, data: Any, models: tuple[str, ...], default: dict[str, Any]) -> dict[str, Any]:
    """A filter's motion model, its defaults from the truth (``default``)."""
    data = {k: v for k, v in section_values(where, MOTION_KEYS, data).items() if v is not None}  # null: not given
    model = check_choice(f"config key '{where}.model'", data.get("model", default["model"]), models)
    base = default if model == default["model"] else {"model": model, "k_r": default["k_r"], "k_l": default["k_l"]}
    if model == "velocity" and "alphas" not in data and "alphas" not in base:
        base = {**base, "alphas": default["velocity_alphas"], "scaling": "abs"}
    out = {"model": model, "k_r": data.get("k_r", base["k_r"]), "k_l": data.get("k_l", base["k_l"]),  # the truth's
           "noise": data.get("noise", base.get("noise", "normal")),
           "scaling": data.get("scaling", base.get("scaling", "squared"))}  # fmt: skip
    alphas = data.get("alphas", base.get("alphas"))
    if alphas is not None:
        if not isinstance(alphas, list | tuple):
            raise _fail(f"{where}.alphas", "a list of numbers >= 0", alphas)
        alphas = vector(f"{where}.alphas", alphas, len(alphas), nonneg=True)
    m = _build(where, Motion, {**out, "alphas": None if alphas is None else tuple(alphas)})
    out["alphas"] = None if m.alphas is None else list(m.alphas)
    return out


def _sensor_choice(where: str, data: Mapping[str, Any], sensors: Mapping[str, Any], allowed: tuple[str, ...]) -> str:
    have = [s for s in allowed if s in sensors]
    if not have:
        raise _fail(f"{where}.sensor", f"a configured sensor among {allowed} (configure sensors.{allowed[0]})", None)
    s = check_choice(f"config key '{where}.sensor'", data.get("sensor", have[0]), allowed)
    if s not in sensors:
        raise _fail(f"{where}.sensor", f"a configured sensor (configured: {', '.join(sensors)})", s)
    return s


def _filters(data: Any, sensors: Mapping[str, Any], defaults: Mapping[str, Any]) -> dict[str, Any]:
    _check_keys("filters", data, lm.FILTERS)
    if not data:
        raise ValueError(f"config key 'filters' must configure at least one filter (allowed: {', '.join(lm.FILTERS)})")
    out: dict[str, Any] = {}
    if data.get("ekf") is not None:
        d = section_values("filters.ekf", EKF_KEYS, {"sensor": "landmarks", **data["ekf"]})
        out["ekf"] = {"sensor": _sensor_choice("filters.ekf", data["ekf"], sensors, ("landmarks",)),
                      "motion": _motion("filters.ekf.motion", d["motion"], ("wheels", "velocity"), dict(defaults)),
                      "association": d["association"]}  # fmt: skip
    if data.get("histogram") is not None:
        d = section_values("filters.histogram", HISTOGRAM_KEYS, {"sensor": "landmarks", **data["histogram"]})
        out["histogram"] = {
            "sensor": _sensor_choice("filters.histogram", data["histogram"], sensors, ("landmarks", "beams")),
            "motion": _motion("filters.histogram.motion", d["motion"], ("velocity", "odometry"),
                              {**defaults, "model": "velocity", "alphas": defaults["velocity_alphas"], "scaling": "abs"}),
            **{k: d[k] for k in ("resolution", "ntheta", "mask_occupied", "association", "workers")},
        }  # fmt: skip
    if data.get("particle") is not None:
        d = dict(data["particle"])
        where = "filters.particle"
        sensor = _sensor_choice(where, d, sensors, ("landmarks", "beams"))
        motion = _motion(f"{where}.motion", d.pop("motion", None), MOTION_MODELS, dict(defaults))
        d.pop("sensor", None)
        opts = _dataclass_params(where, particle.ParticleFilterConfig,
                                 tuple(k for k in PARTICLE_KEYS if k.name not in ("sensor", "motion")), d)
        out["particle"] = {"sensor": sensor, "motion": motion, **opts}
    return out


# ============================================================================= the configuration


@dataclass(frozen=True)
class LocalizationConfig:
    """Everything that determines one localization run (normalised plain mappings, every default filled in).

    Attributes
    ----------
    name : str; seed : int [1]; repeat : int [1] — simulated runs R
    world : dict — the world, inline (WORLD_SCHEMA keys) with ``random_landmarks`` {count, seed,
        margin [m]} and the ``source`` file it was read from
    trajectory : dict — builder name (:data:`TRAJECTORY_BUILDERS`) and parameters
    truth : dict — ``k_r``, ``k_l`` [m] (wheel-travel variance per metre), ``regime`` and ``path``
        (``commanded``: the robot follows the path and its odometry drifts; ``drifts``: the reverse)
    sensors : dict — ``landmarks`` (RangeBearingSensor fields) and/or ``beams`` (BeamSensor fields)
    scenario : dict — ``kind`` (tracking | global | kidnapped), ``start_std`` [m, m, rad],
        ``kidnap_step`` [step], ``kidnap_pose`` [m, m, rad]
    filters : dict — ``ekf``, ``histogram``, ``particle``: each its ``sensor``, ``motion`` and options
    success : dict — ``pos_tol`` [m], ``head_tol`` [rad]
    log : dict — ``particles_every`` [step] (0: none), ``max_particles_logged`` [1], ``grid_every`` [step] (0: none)
    """

    name: str
    seed: int
    repeat: int
    world: dict[str, Any]
    trajectory: dict[str, Any]
    truth: dict[str, Any]
    sensors: dict[str, Any]
    scenario: dict[str, Any]
    filters: dict[str, Any]
    success: dict[str, Any]
    log: dict[str, Any]

    KEYS = ("kind", "name", "seed", "repeat", "world", "trajectory", "truth", "sensors", "scenario", "filters",
            "success", "log")  # fmt: skip

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> LocalizationConfig:
        """Validate a plain mapping and build the configuration.

        Raises
        ------
        ValueError
            One line naming the bad key (dotted path, e.g. ``filters.particle.n_particles``),
            the bad value and what is allowed; unknown keys are rejected.
        """
        if not isinstance(data, Mapping):
            raise _fail("config", "a mapping", data)
        data = parse_numbers(data)
        top = section_values("", tuple(k for k in LOCALIZATION_KEYS if k.kind != "section"),
                             {k: v for k, v in data.items() if k not in cls.KEYS[4:]})
        for key in ("world", "trajectory", "sensors", "filters"):
            if key not in data:
                raise ValueError(f"config key {key!r} is missing (a localization run needs world, trajectory, "
                                 "sensors and filters)")  # fmt: skip
        world = _world(data["world"])
        try:
            built = _validated_world(world, build=True)
        except ValueError as exc:
            msg = str(exc)
            raise ValueError(msg if msg.startswith("config key") else f"config key 'world': {msg}") from None
        traj, tr = _trajectory(data["trajectory"])
        truth = _truth(data.get("truth", {}))
        sensors = _sensors(data["sensors"])
        _check_world(built, tr, sensors)
        scenario = _scenario(data.get("scenario", {}), tr.n_steps)
        defaults = {"model": "wheels", "k_r": truth["k_r"], "k_l": truth["k_l"],
                    "velocity_alphas": list(velocity_alphas_for_wheels(truth["k_r"], truth["k_l"], tr.track, tr.dt))}
        filters = _filters(data["filters"], sensors, defaults)
        success = section_values("success", SUCCESS_KEYS, data.get("success"))
        log = section_values("log", LOG_KEYS, data.get("log"))
        return cls(
            name=top["name"], seed=top["seed"], repeat=top["repeat"], world=world, trajectory=traj,
            truth=truth, sensors=sensors, scenario=scenario, filters=filters, success=success, log=log,
        )  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-serialisable mapping with every parameter (round-trips via from_dict)."""
        return {"kind": KIND, "name": self.name, "seed": self.seed, "repeat": self.repeat,
                **copy.deepcopy({k: getattr(self, k) for k in self.KEYS[4:]})}  # fmt: skip

    @staticmethod
    def units() -> dict[str, Any]:
        """Unit of every configuration key (``"1"`` = dimensionless, ``"-"`` = not a number)."""
        motion = {"model": "- (wheels | velocity | odometry)", "k_r": "m", "k_l": "m", "alphas": "1",
                  "noise": "- (normal | triangular)", "scaling": "- (squared | abs)"}  # fmt: skip
        return {
            "kind": "-", "name": "-", "seed": "1", "repeat": "1 (simulated runs)",
            "world": {"source": "- (path)", "name": "-", "bounds": "m", "landmarks": {"id": "1", "x": "m", "y": "m"},
                      "walls": {"segments": "m", "resolution": "m", "thickness": "m", "margin": "m"},
                      "image": {"path": "- (path)", "resolution": "m", "origin": "m", "occupied_thresh": "1",
                                "free_thresh": "1", "negate": "- (bool)", "sha256": "-"},
                      "random_landmarks": {"count": "1", "seed": "1", "margin": "m"}},
            "trajectory": {"name": "-", "length": "m", "radius": "m", "angle": "rad", "laps": "1", "side": "m",
                           "segments": "[kind, m or rad ...]", "direction": "1", "dx": "m", "dy": "m",
                           "speed": "m/s", "angular_speed": "rad/s", "dt": "s", "track": "m", "profile": "-",
                           "start": "(m, m, rad)"},
            "truth": {"k_r": "m", "k_l": "m", "regime": "- (per_step | per_run)", "path": "- (commanded | drifts)"},
            "sensors": {"landmarks": {"range_std": "m", "bearing_std": "rad", "max_range": "m", "fov": "rad",
                                      "period": "s"},
                        "beams": {"n_beams": "1", "fov": "rad", "max_range": "m", "sigma_hit": "m",
                                  "lambda_short": "1/m", "z_hit": "1", "z_short": "1", "z_max": "1", "z_rand": "1",
                                  "period": "s"}},
            "scenario": {"kind": "- (tracking | global | kidnapped)", "start_std": "(m, m, rad)",
                         "kidnap_step": "step", "kidnap_pose": "(m, m, rad)"},
            "filters": {"ekf": {"sensor": "-", "motion": motion, "association": "- (known | ml)"},
                        "histogram": {"sensor": "-", "motion": motion, "resolution": "m", "ntheta": "1",
                                      "mask_occupied": "- (bool)", "association": "- (known | ml)", "workers": "1"},
                        "particle": {"sensor": "-", "motion": motion, "n_particles": "1", "resampling": "-",
                                     "ess_threshold": "1 (fraction of n)", "injection": "- (none | fixed | augmented)",
                                     "injection_fraction": "1", "alpha_slow": "1", "alpha_fast": "1",
                                     "association": "- (known | ml)", "dtype": "-", "hdr_resolution": "m",
                                     "workers": "1"}},
            "success": {"pos_tol": "m", "head_tol": "rad"},
            "log": {"particles_every": "step", "max_particles_logged": "1", "grid_every": "step"},
        }  # fmt: skip

    # --- the objects the run is made of -------------------------------------------------------

    def build_world(self) -> World:
        """The world (random landmarks drawn)."""
        return build_world(self.world)

    def build_trajectory(self) -> trajectories.Trajectory:
        """The commanded path."""
        t = self.trajectory
        return TRAJECTORY_BUILDERS[t["name"]](**{k: v for k, v in t.items() if k != "name"})

    def landmark_sensor(self) -> RangeBearingSensor | None:
        """The range–bearing sensor, if configured."""
        s = self.sensors.get("landmarks")
        return None if s is None else RangeBearingSensor(**s)

    def beam_sensor(self) -> BeamSensor | None:
        """The laser's beam model, if configured."""
        s = self.sensors.get("beams")
        return None if s is None else BeamSensor(**s)

    def start(self, trajectory: trajectories.Trajectory) -> Start:
        """The filters' initial belief: the path's start with ``start_std``, or uniform (global)."""
        sc = self.scenario
        return Start(sc["kind"], tuple(float(v) for v in trajectory.start), tuple(sc["start_std"]))  # type: ignore[arg-type]

    def motion(self, name: str) -> Motion:
        """The motion model of filter ``name``."""
        m = self.filters[name]["motion"]
        return Motion(m["model"], m["k_r"], m["k_l"], None if m["alphas"] is None else tuple(m["alphas"]),
                      m["noise"], m["scaling"])  # fmt: skip


