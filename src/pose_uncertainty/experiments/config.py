"""A run's configuration: typed, validated, every default filled in, with units.

A *run* is one parameter point of a sweep (:mod:`pose_uncertainty.experiments.run` executes
it). A configuration is written as a plain mapping (YAML or JSON)::

    name: circle_a4
    seed: 7
    trajectory: {name: circle, radius: 1.0, speed: 0.5, dt: 0.01, track: 0.2}
    k_r: 5.0e-4            # m   (Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|))
    k_l: 5.0e-4            # m
    pr: 0.98889            # probability inside the drawn ellipse
    n_ellipses: 10         # blue ellipses along the path
    monte_carlo: {n_particles: 1000, regime: per_step, method: midpoint, checkpoints: [100]}
    maps:
      - {name: velocity, model: velocity, alpha: [0.05, 0.05, 0.05, 0.05, 0.05, 0.05]}

An optional ``drive`` section (:mod:`pose_uncertainty.experiments.drive_config`) makes the
robot any drive of Skalka 2011 §3.2.2; the trajectory is then the path it follows. Without it
the run is the differential drive of ``k_r``, ``k_l``.

:meth:`RunConfig.to_dict` returns *every* parameter, defaults included (the
trajectory builder's defaults too), so that a logged configuration re-runs the
same computation; :meth:`RunConfig.units` gives the unit of each key. Numbers
written as text (``1e9``, ``5e-4``: YAML 1.1 reads them as strings) are read as
numbers; trajectories are validated and counted without being built, so a
configuration can be costed (:mod:`pose_uncertainty.experiments.cost`) before anything
is allocated.
"""

from __future__ import annotations

import inspect
import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core import trajectories
from ..core.grids import Grid
from ..core.stats import PR_3SIGMA
from ..core.table_io import jsonable, plain_copy
from ..core.validation import parse_numbers
from ..localization.motion import K_WHEEL
from ..methods import maps, motion_models
from ..methods.sampling import REGIMES
from .config_checks import builder_keywords
from .config_checks import check_keys as _check_keys
from .config_checks import fail as _fail
from .config_checks import integer as _int
from .config_checks import name as _name
from .config_keys import FROM_CODE, Key, key_of, units
from .drive_config import DRIVE_KEYS, DriveConfig, check_path

__all__ = [
    "MAP_KEYS",
    "MAP_SAMPLES",
    "MAX_CELLS",
    "MAX_MAPS",
    "MAX_PARTICLES",
    "MAX_SEED",
    "MONTE_CARLO_KEYS",
    "RUN_KEYS",
    "TRAJECTORY_KEYS",
    "TRAJECTORY_UNITS",
    "MapConfig",
    "MonteCarloConfig",
    "RunConfig",
    "map_kind",
]



#: Largest count of sampled poses (Monte Carlo particles, a map's sampler draws) [1]; the cost
#: guard refuses far fewer on most machines (140 B each).
MAX_PARTICLES: int = 1_000_000_000
#: Largest number of cells of a map grid [1].
MAX_CELLS: int = 10_000_000_000
#: Largest seed [1] (numpy takes any non-negative integer; 64 bits are plenty).
MAX_SEED: int = 2**64 - 1
#: Largest number of maps of one run [1].
MAX_MAPS: int = 100


#: The keys of ``trajectory``: the keyword parameters of the builders of
#: :data:`pose_uncertainty.core.trajectories.BUILDERS`, whose defaults they take.
TRAJECTORY_KEYS: tuple[Key, ...] = (
    Key("name", "choice", "-", "Builder name (required; pose_uncertainty.core.trajectories.BUILDERS).",
        allowed=tuple(trajectories.BUILDERS)),
    Key("length", "number", "m", "Line length [m].", FROM_CODE),
    Key("radius", "number", "m", "Arc/circle radius [m].", FROM_CODE, lo=0.0, lo_open=True),
    Key("angle", "number", "rad", "Arc or rotation angle [rad] (default: the builder's).", FROM_CODE),
    Key("laps", "number", "1", "Circle or tour laps [1].", FROM_CODE, lo=0.0, lo_open=True),
    Key("direction", "choice", "1 (+1 left, -1 right)", "Circle direction (+1 left, -1 right).", FROM_CODE,
        allowed=(1, -1)),
    Key("dx", "number", "m", "Target x of right_angles/direct [m].", FROM_CODE),
    Key("dy", "number", "m", "Target y of right_angles/direct [m].", FROM_CODE),
    Key("segments", "array", "[kind, m or rad ...]",
        "Segments of a tour: [line, L], [turn, angle], [arc, radius, angle] (m, rad).", FROM_CODE,
        extra={"maxItems": 100_000}),
    Key("speed", "number", "m/s", "Axle-centre speed [m/s].", FROM_CODE, lo=0.0, lo_open=True),
    Key("angular_speed", "number", "rad/s", "Rotation-in-place rate [rad/s].", FROM_CODE, lo=0.0, lo_open=True),
    Key("dt", "number", "s", "Step [s].", FROM_CODE, lo=0.0, lo_open=True),
    Key("track", "number", "m", "Wheel separation b [m].", FROM_CODE, lo=0.0, lo_open=True),
    Key("profile", "choice", "- (constant | ramp)", "Speed profile of each segment.", FROM_CODE,
        allowed=("constant", "ramp")),
    Key("start", "array", "(m, m, rad)", "Start pose (x [m], y [m], theta [rad]).", FROM_CODE,
        extra={"items": {"type": "number"}, "minItems": 3, "maxItems": 3}),
)

#: Units of the trajectory builder parameters (pose_uncertainty.core.trajectories).
TRAJECTORY_UNITS: dict[str, str] = units(TRAJECTORY_KEYS)

#: The keys of ``monte_carlo`` (:class:`MonteCarloConfig`).
MONTE_CARLO_KEYS: tuple[Key, ...] = (
    Key("n_particles", "integer", "1", "Number of sampled runs [1]; 0 disables Monte Carlo.", 1000, lo=0,
        hi=MAX_PARTICLES),
    Key("regime", "choice", "- (per_step | per_run)",
        "per_step (random walk, Method A's model) or per_run (systematic, as Němec 2012).", "per_step",
        allowed=REGIMES),
    Key("method", "choice", "- (exact | euler | euler_end | midpoint)",
        "Forward-kinematics step of the sampler (pose_uncertainty.core.kinematics.METHODS).", "midpoint",
        allowed=("exact", "euler", "euler_end", "midpoint")),
    Key("checkpoints", "array", "step index", "Step indices (1..N) at which the whole cloud is also kept [step].",
        (), extra={"items": {"type": "integer", "minimum": 1}}),
)

#: The keys of one map of ``maps`` (:class:`MapConfig`); the defaults are its builder's
#: (:func:`_map_defaults`: ``single_step_map`` for a one-step trajectory, else ``multi_step_map``).
MAP_KEYS: tuple[Key, ...] = (
    Key("name", "name", "-", "Map identifier (figure and topic names); default: the model.", FROM_CODE),
    Key("model", "choice", "- (velocity | odometry)", "Motion model (required).", allowed=("velocity", "odometry")),
    Key("alphas", "array", "1 (error constants)",
        "Error constants alpha_1..alpha_6 (velocity) or alpha_1..alpha_4 (odometry) [1]; default 0.05 each.",
        FROM_CODE, extra={"items": {"type": "number", "minimum": 0}, "minItems": 4, "maxItems": 6}),
    Key("noise", "choice", "- (normal | triangular)", "Noise density of the model.", FROM_CODE,
        allowed=("normal", "triangular")),
    Key("scaling", "choice", "- (squared | abs)",
        "Variance scaling: alpha*u^2 (squared, the book) or alpha*|u| (abs, the Kulich 2014 lecture).", FROM_CODE,
        allowed=("squared", "abs")),
    Key("corrected", "boolean", "- (bool)",
        "Single-step map. False: Thrun's density as printed (relative); true: the sampler's pose-space density.",
        FROM_CODE),
    Key("cell_average", "boolean", "- (bool | null = automatic)",
        "Single-step map: average the density over each cell (null = automatic).", FROM_CODE, nullable=True),
    Key("oversample", "integer", "1 (integer factor)",
        "Multi-step map: compute on cells this many times finer, summed back (for distributions thinner than "
        "a cell, at about 15-20x the cost for 3) [1].", FROM_CODE, lo=1, hi=16),
    Key("diffusion_compensation", "boolean", "- (bool)", "Multi-step map: compensate the numerical diffusion.",
        FROM_CODE),
    Key("max_cells", "integer", "1", "Multi-step map: largest number of grid cells [1].", FROM_CODE, lo=1,
        hi=MAX_CELLS),
    Key("n_nodes_max", "integer", "1", "Multi-step map: largest number of quadrature nodes [1].", FROM_CODE, lo=1,
        hi=1_000_000),
    Key("variance_from", "choice", "- (hypothesis | odometry | null)",
        "Odometry model: variances from the hypothesis or from the odometry deltas (null = the module default).",
        FROM_CODE, allowed=("hypothesis", "odometry"), nullable=True),
    Key("n_sampler", "integer", "1 (draws of the model's own sampler)",
        "Draws of the model's own sampler along the run's controls, logged with the map and compared with it "
        "(0 = none) [1].", FROM_CODE, lo=0, hi=MAX_PARTICLES),
    Key("log_volume", "boolean", "- (bool: the full (x, y, theta) array in the log)",
        "Log the full (x, y, theta) array (lossless, nx*ny*ntheta*8 bytes); false: its exact theta-marginal and "
        "the sha256 of the full array, which replay --verify compares.", FROM_CODE),
    Key("size", "number", "m",
        "Side of the square grid [m]: single-step map centred on the noiseless end (the thesis: 1 m); "
        "multi-step map null = a grid that grows with the spread.", FROM_CODE, nullable=True, lo=0.0, lo_open=True),
    Key("resolution", "number", "m", "Cell side [m] (the thesis: 1 cm).", FROM_CODE, lo=0.0, lo_open=True),
    Key("theta_resolution", "number", "rad", "Heading cell width [rad] (default 2 degrees).", FROM_CODE,
        lo=0.0, hi=2 * math.pi, lo_open=True),
)



@dataclass(frozen=True)
class MonteCarloConfig:
    """Monte Carlo sampling of end poses under Method A's noise model (Němec 2012 §2.1.2).

    Attributes
    ----------
    n_particles : int
        Number of sampled runs [1]; 0 disables Monte Carlo.
    regime : {"per_step", "per_run"}
        Wheel-travel noise drawn every step (random walk) or once per run (systematic).
    method : str
        Forward-kinematics step used by the sampler (``pose_uncertainty.core.kinematics.METHODS``).
    checkpoints : tuple of int
        Step indices (1..N) at which the whole cloud is also kept [step].
    """

    n_particles: int = key_of(MONTE_CARLO_KEYS, "n_particles").default
    regime: str = key_of(MONTE_CARLO_KEYS, "regime").default
    method: str = key_of(MONTE_CARLO_KEYS, "method").default
    checkpoints: tuple[int, ...] = key_of(MONTE_CARLO_KEYS, "checkpoints").default

    KEYS = tuple(k.name for k in MONTE_CARLO_KEYS)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> MonteCarloConfig:
        """Validate and build from a mapping; unknown keys raise ValueError naming them."""
        return _by_json(_MONTE_CARLO, data, cls._from_dict)  # type: ignore[no-any-return]  # frozen: shared

    @classmethod
    def _from_dict(cls, data: Mapping[str, Any]) -> MonteCarloConfig:
        _check_keys("monte_carlo", data, cls.KEYS)
        n, regime, method, cps = (k.get("monte_carlo", data) for k in MONTE_CARLO_KEYS)
        if not isinstance(cps, list | tuple):
            raise _fail("monte_carlo.checkpoints", "a list of step indices", cps)
        checkpoints = tuple(sorted({_int("monte_carlo.checkpoints[]", c, minimum=1) for c in cps}))
        return cls(n_particles=n, regime=regime, method=method, checkpoints=checkpoints)

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping with every parameter."""
        return {
            "n_particles": self.n_particles,
            "regime": self.regime,
            "method": self.method,
            "checkpoints": list(self.checkpoints),
        }


#: :meth:`MonteCarloConfig.from_dict` of each mapping seen, by its JSON text.
_MONTE_CARLO: dict[str, MonteCarloConfig] = {}


@dataclass(frozen=True)
class MapConfig:
    """One probability map (Method B, Němec 2012 §2.2) computed for the run.

    Attributes
    ----------
    name : str
        Identifier, used in topic and figure names.
    model : {"velocity", "odometry"}
        Motion model.
    params : dict
        Parameters of the map (every one filled in by :meth:`from_dict`):
        ``alphas`` [1] (6 velocity / 4 odometry error constants, default 0.05 each
        as the thesis), ``noise`` (normal | triangular), ``scaling`` (squared | abs),
        ``resolution`` [m] (cell, default 0.01 m), ``theta_resolution`` [rad]
        (default 2°). A one-step trajectory gives the thesis's single-step map
        (``pose_uncertainty.methods.maps.single_step_map``: also ``corrected`` (the
        change-of-variables-corrected pose-space density instead of Thrun's
        control-space one), ``cell_average``, ``variance_from``, ``size`` [m], the
        side of the grid centred on the noiseless end pose, default 1 m); a longer
        one the multi-step map along the whole trajectory (``multi_step_map``:
        also ``oversample`` (compute on cells that many times finer, summed back;
        for distributions thinner than a cell such as rotation in place, at about
        15–20× the cost for 3), ``diffusion_compensation``, ``max_cells``,
        ``n_nodes_max``, and ``size`` [m]: None = a grid that grows with the
        spread, a number = a fixed square grid of that side centred between the
        start and the noiseless end). Every map also has ``n_sampler`` [1]
        (default :data:`MAP_SAMPLES`): draws of the model's own sampler along the
        same controls, logged with the map and compared with it (0: none); and
        ``log_volume`` (default false): log the full ``(x, y, θ)`` array, lossless but
        large (``nx·ny·nθ·8`` bytes); otherwise the log holds the exact θ-marginal
        and the sha256 of the full array, which ``replay --verify`` compares.
    """

    name: str
    model: str
    params: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], index: int = 0, n_steps: int = 1) -> MapConfig:
        """Validate and build from a mapping with keys ``name``, ``model`` and map parameters.

        ``n_steps`` (the trajectory's N) selects the builder whose parameters apply.
        """
        where = f"maps[{index}]"
        if not isinstance(data, Mapping):
            raise _fail(where, "a mapping", data)
        if "model" not in data:
            raise ValueError(f"config key '{where}.model' is missing (allowed: velocity, odometry)")
        model = data["model"]
        if model not in ("velocity", "odometry"):
            raise _fail(f"{where}.model", "one of 'velocity', 'odometry'", model)
        name = _name(f"{where}.name", data.get("name", model))
        params = {k: v for k, v in data.items() if k not in ("name", "model")}
        return cls(name=name, model=model, params=_map_params(where, model, params, n_steps))

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping with every parameter."""
        return {"name": self.name, "model": self.model, **jsonable(self.params)}


#: Paths up to this many steps are checked against their drive when the config is read (a
#: longer one when the run executes, after the cost guard: the check builds the path).
_CHECK_PATH_STEPS: int = 1_000_000

#: Default number of draws of a map's own motion-model sampler (its Monte Carlo truth).
MAP_SAMPLES: int = 20_000

#: Parameters of the map builders that the run supplies itself (not configurable).
_MAP_SUPPLIED = (
    "model", "start", "control", "controls", "dt", "grid", "odometry", "workers", "progress",
)  # fmt: skip


def map_kind(n_steps: int) -> str:
    """``"single"`` (the thesis's one-step map) for a one-step trajectory, else ``"multi"``."""
    return "single" if n_steps == 1 else "multi"


def _map_defaults(model: str, kind: str) -> dict[str, Any]:
    """Every configurable parameter of a map builder with its default."""
    defaults: dict[str, Any] = {
        "alphas": [0.05] * (6 if model == "velocity" else 4),
        # draws of the model's own sampler along the run's controls (the map's Monte Carlo truth)
        "n_sampler": MAP_SAMPLES,
        # the full (x, y, θ) array in the log (else its exact θ-marginal and its sha256)
        "log_volume": False,
    }
    if kind == "single":
        fns: tuple[Any, ...] = (maps.single_step_map, Grid.centered)
    else:
        fns = (maps.multi_step_map,)
        defaults["size"] = None  # None: the growing grid; a number: a fixed square grid [m]
    for fn in fns:
        for p in inspect.signature(fn).parameters.values():
            if p.name in _MAP_SUPPLIED or p.name in ("center", "self", "cls"):
                continue
            if p.default is not inspect.Parameter.empty:
                defaults.setdefault(p.name, p.default)
    return defaults


def _map_params(where: str, model: str, params: dict[str, Any], n_steps: int) -> dict[str, Any]:
    """Validate a map's parameters against its builder and fill in the builder's defaults."""
    kind = map_kind(n_steps)
    defaults = _map_defaults(model, kind)
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ValueError(
            f"unknown config key(s) {', '.join(repr(f'{where}.{k}') for k in unknown)} "
            f"(allowed for a {kind}-step {model} map: name, model, {', '.join(sorted(defaults))})"
        )
    params = {k: parse_numbers(v, defaults[k]) for k, v in params.items()}
    full = jsonable({**defaults, **params})
    for key in MAP_KEYS:  # every parameter by its table (alphas below, by the model)
        if key.name in full and key.name != "alphas":
            full[key.name] = key.check(f"{where}.{key.name}", full[key.name])
    try:
        motion_models.check_alphas(full["alphas"], 6 if model == "velocity" else 4)
    except ValueError as exc:
        raise ValueError(f"config key '{where}.alphas': {exc}") from None
    return full


def _trajectory_params(data: Any) -> tuple[dict[str, Any], int]:
    """Validate the trajectory mapping, fill in every default of its builder; also return N.

    A sweep's runs share a few trajectories: each distinct mapping is checked and counted once
    (kept by its JSON text), and every call gets its own copy.
    """
    full, n = _by_json(_TRAJECTORIES, data, _trajectory_params_of)
    return plain_copy(full), n


#: :func:`_trajectory_params` of each trajectory mapping seen, by its JSON text.
_TRAJECTORIES: dict[str, tuple[dict[str, Any], int]] = {}


def _by_json(cache: dict[str, Any], data: Any, make: Callable[[Any], Any]) -> Any:
    """``make(data)``, kept in ``cache`` by the JSON text of ``data`` (a sweep repeats a few sections over
    thousands of runs): the result must not be changed by its users. ``data`` that is not plain JSON is
    made (checked, refused) every time, never kept; a failure is not kept either."""
    try:
        key = json.dumps(data, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError):
        return make(data)
    hit = cache.get(key)
    if hit is None:
        if len(cache) >= 4096:
            cache.clear()
        hit = cache[key] = make(data)
    return hit


def _trajectory_params_of(data: Any) -> tuple[dict[str, Any], int]:
    if not isinstance(data, Mapping):
        raise _fail("trajectory", "a mapping with a 'name' key", data)
    if "name" not in data:
        raise ValueError("config key 'trajectory.name' is missing (e.g. straight, circle)")
    name = data["name"]
    if name not in trajectories.BUILDERS:
        raise _fail("trajectory.name", f"one of {tuple(trajectories.BUILDERS)}", name)
    defaults, params = builder_keywords("trajectory", trajectories.BUILDERS[name], data)
    params = {k: parse_numbers(v, defaults[k]) for k, v in params.items()}
    full = {"name": name, **jsonable({**defaults, **params})}
    try:  # validated and counted without building it (the cost guard comes first)
        n = trajectories.n_steps(name, **{k: v for k, v in full.items() if k != "name"})
    except ValueError as exc:
        raise ValueError(f"config key 'trajectory' ({name}): {exc}") from None
    return full, n


#: The keys of a run configuration (:class:`RunConfig`), in the order of its log.
RUN_KEYS: tuple[Key, ...] = (
    Key("name", "name", "-", "Run name; set by the sweep to the run id.", "run"),
    Key("seed", "integer", "1", "Seed of the run's numpy Generator [1].", 0, lo=0, hi=MAX_SEED),
    Key("trajectory", "section", "-",
        "Trajectory builder (pose_uncertainty.core.trajectories.BUILDERS) and its parameters: lengths [m], "
        "angles [rad], speed [m/s], angular_speed [rad/s], dt [s], track [m]; a parameter left out takes the "
        "builder's default.", None, keys=TRAJECTORY_KEYS),
    Key("k_r", "number", "m (wheel-travel variance per metre of travel)",
        "Right-wheel error constant k_r [m] (Sigma_Delta = diag(k_r|ds_r|, k_l|ds_l|)).", K_WHEEL, lo=0.0),
    Key("k_l", "number", "m (wheel-travel variance per metre of travel)", "Left-wheel error constant k_l [m].",
        K_WHEEL, lo=0.0),
    Key("cov0", "array", "3x3 over (x [m], y [m], theta [rad]): m^2, m*rad, rad^2",
        "Initial pose covariance, 3x3 over (x [m], y [m], theta [rad]), symmetric positive semi-definite; "
        "null = zero.", None, nullable=True),
    Key("pr", "number", "1 (probability inside the ellipse)",
        "Probability inside the drawn ellipses [1]; 0.98889 = radius 3.", PR_3SIGMA,
        lo=0.0, hi=1.0, lo_open=True, hi_open=True, rule="a probability in (0, 1)"),
    Key("n_ellipses", "integer", "1", "Number of blue ellipses along the path [1] (a figure shows at most "
        "10,000).", 10, lo=1, hi=10_000),
    Key("monte_carlo", "section", "-", "Monte Carlo sampling under Method A's noise model.", None,
        keys=MONTE_CARLO_KEYS),
    Key("maps", "sections", "-", "Probability maps (Method B) computed for the run.", (),
        extra={"items": {"required": ["model"]}}, keys=MAP_KEYS),
    Key("drive", "section", "-",
        "The robot's drive (Šafránek 2022, section 3.2.2): type, geometry and odometry errors; the trajectory is "
        "then the geometric path the drive follows (pose_uncertainty.core.drives.follow), and Method A, Monte "
        "Carlo and the exponential-coordinates Gaussian are the drive's. Null or absent = the differential "
        "drive of trajectory.track with k_r, k_l (runs logged as before). A geometry key of another type is "
        "rejected; a drive that cannot follow the path (e.g. a rotation in place with max_steering below 90 "
        "degrees) is rejected when the config is read.", None, nullable=True, keys=DRIVE_KEYS),
)

#: The keys of :data:`RUN_KEYS` by name.
_RUN_KEY: dict[str, Key] = {k.name: k for k in RUN_KEYS}


@dataclass(frozen=True)
class RunConfig:
    """Everything that determines one run (with the package version and environment).

    Attributes
    ----------
    trajectory : dict
        ``name`` of a builder in ``pose_uncertainty.core.trajectories.BUILDERS`` and its
        parameters (units in :data:`TRAJECTORY_UNITS`: lengths m, angles rad,
        speed m/s, angular_speed rad/s, dt s, track m).
    k_r, k_l : float
        Odometry error constants [m]: per-step wheel-travel variance per metre of
        travel, ``Σ_Δ = diag(k_r|Δs_r|, k_l|Δs_l|)`` (Němec 2012 §2.1).
    cov0 : tuple of tuple of float or None
        Initial pose covariance, 3×3 over (x [m], y [m], θ [rad]); None = zero.
    pr : float
        Probability inside the drawn error ellipses [1], in (0, 1); default 98.89 %.
    n_ellipses : int
        Number of ellipses drawn at regular intervals along the path [1].
    seed : int
        Seed of the ``numpy.random.Generator`` used for Monte Carlo [1].
    monte_carlo : MonteCarloConfig
    maps : tuple of MapConfig
    name : str
        Run identifier.
    drive : DriveConfig or None
        The robot's drive (:mod:`pose_uncertainty.experiments.drive_config`): its type,
        geometry and odometry errors; the trajectory is then the path it follows.
        None (no ``drive`` key) = the differential drive of ``trajectory.track``
        with ``k_r``, ``k_l``, logged exactly as before the drives existed.
    """

    trajectory: dict[str, Any]
    k_r: float = key_of(RUN_KEYS, "k_r").default
    k_l: float = key_of(RUN_KEYS, "k_l").default
    cov0: tuple[tuple[float, float, float], ...] | None = None
    pr: float = key_of(RUN_KEYS, "pr").default
    n_ellipses: int = key_of(RUN_KEYS, "n_ellipses").default
    seed: int = key_of(RUN_KEYS, "seed").default
    monte_carlo: MonteCarloConfig = field(default_factory=MonteCarloConfig)
    maps: tuple[MapConfig, ...] = ()
    name: str = key_of(RUN_KEYS, "name").default
    drive: DriveConfig | None = None

    KEYS = tuple(k.name for k in RUN_KEYS)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunConfig:
        """Validate a plain mapping and build the configuration.

        Raises
        ------
        ValueError
            Naming the bad key (dotted path, e.g. ``monte_carlo.regime``), the bad
            value and what is allowed; unknown keys are rejected.
        """
        _check_keys("", data, cls.KEYS)
        if "trajectory" not in data:
            raise ValueError("config key 'trajectory' is missing (e.g. {name: straight})")
        traj, n_steps = _trajectory_params(data["trajectory"])
        k_r, k_l = _RUN_KEY["k_r"].get("", data), _RUN_KEY["k_l"].get("", data)
        cov0_raw = data.get("cov0")
        cov0 = None
        if cov0_raw is not None:
            try:
                arr = np.asarray(cov0_raw, dtype=np.float64)
            except (TypeError, ValueError):
                raise _fail("cov0", "a 3x3 matrix of numbers", cov0_raw) from None
            if arr.shape != (3, 3) or not np.all(np.isfinite(arr)):
                raise _fail("cov0", "a finite 3x3 matrix", cov0_raw)
            if not np.array_equal(arr, arr.T) or np.linalg.eigvalsh(arr).min() < -1e-15:
                raise _fail("cov0", "symmetric positive semi-definite", cov0_raw)
            cov0 = tuple((float(r[0]), float(r[1]), float(r[2])) for r in arr)
        pr, n_ell, seed = _RUN_KEY["pr"].get("", data), _RUN_KEY["n_ellipses"].get("", data), _RUN_KEY["seed"].get("", data)
        mc = MonteCarloConfig.from_dict(data.get("monte_carlo", {}))
        late = [c for c in mc.checkpoints if c > n_steps]
        if late:
            raise _fail(
                "monte_carlo.checkpoints",
                f"step indices in 1..{n_steps} (the trajectory's N)",
                late,
            )
        maps_raw = data.get("maps", ())
        if not isinstance(maps_raw, list | tuple) or len(maps_raw) > MAX_MAPS:
            raise _fail("maps", f"a list of at most {MAX_MAPS} map mappings", maps_raw)
        maps = tuple(MapConfig.from_dict(m, i, n_steps) for i, m in enumerate(maps_raw))
        names = [m.name for m in maps]
        if len(set(names)) != len(names):
            raise _fail("maps[].name", "unique", names)
        name = _RUN_KEY["name"].get("", data)
        drive = None
        if data.get("drive") is not None:
            drive = DriveConfig.from_dict(data["drive"])
            if n_steps <= _CHECK_PATH_STEPS:  # a longer path is checked when the run executes
                check_path(drive, traj, k_r, k_l)  # the drive can follow the path (vectorised, cheap)
        return cls(
            trajectory=traj,
            k_r=k_r,
            k_l=k_l,
            cov0=cov0,
            pr=pr,
            n_ellipses=n_ell,
            seed=seed,
            monte_carlo=mc,
            maps=maps,
            name=name,
            drive=drive,
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-serialisable mapping with every parameter (round-trips via from_dict)."""
        return {
            "name": self.name,
            "seed": self.seed,
            "trajectory": jsonable(self.trajectory),
            "k_r": self.k_r,
            "k_l": self.k_l,
            "cov0": None if self.cov0 is None else [list(r) for r in self.cov0],
            "pr": self.pr,
            "n_ellipses": self.n_ellipses,
            "monte_carlo": self.monte_carlo.to_dict(),
            "maps": [m.to_dict() for m in self.maps],
            # only when configured: a run without a drive logs exactly what it logged before
            **({} if self.drive is None else {"drive": self.drive.to_dict()}),
        }

    def units(self) -> dict[str, Any]:
        """Unit of every configuration key (``"1"`` = dimensionless, ``"-"`` = not a number)."""
        units_ = units(RUN_KEYS)
        drive_units = units_.pop("drive")
        if self.drive is not None:  # only when configured (the logged units of other runs are unchanged)
            units_["drive"] = drive_units
        if "segments" not in self.trajectory:  # a tour's only, likewise
            units_["trajectory"] = {k: u for k, u in units_["trajectory"].items() if k != "segments"}
        return units_
