"""The interactive explorer: controls → a run configuration → the run's own numbers, drawn live.

One source of truth: the explorer builds a run configuration mapping from its controls
(:func:`run_config`), validates it with :meth:`RunConfig.from_dict` and the cost guard
(:func:`pose_uncertainty.experiments.cost.check`) exactly as ``pose-uncertainty run`` does, and
computes it with :func:`pose_uncertainty.experiments.run.execute`, the function that writes a
run's log. Every number on the page is a measure of that result (its ``metrics``); every
region is drawn from its covariances by the methods' own functions
(:func:`pose_uncertainty.methods.covariance.ellipse_polyline`,
:func:`pose_uncertainty.methods.expcoords.pr_region_xy`). The browser only draws.

:func:`compute` is the settings → numbers function (no web library needed);
:func:`make_document` builds the Bokeh page; :func:`serve` runs the Bokeh server on
127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import html
import math
import socket
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis.accuracy import PRS, coverage_gridded, pr_label
from ..core.drives import DRIVES as _DRIVES
from ..core.stats import fit_growth, path_spreads, wilson_interval
from ..core.trajectories import PROFILES
from ..experiments import cost
from ..experiments.config import RunConfig
from ..experiments.drive_config import DriveConfig
from ..experiments.run import RunResult, execute
from ..methods import covariance, expcoords
from ..methods.maps import ProbabilityMap
from ..methods.particles import DrawCache

__all__ = [
    "DEFAULTS",
    "DRIVES",
    "MAP_MODELS",
    "METHODS",
    "PATHS",
    "View",
    "compute",
    "drive_geometry",
    "load_log_settings",
    "make_document",
    "run_config",
    "save_run_config",
    "serve",
]

#: The paths offered (names of :data:`pose_uncertainty.core.trajectories.BUILDERS`).
PATHS: tuple[str, ...] = (
    "straight",
    "arc",
    "circle",
    "s_curve",
    "right_angles",
    "direct",
    "rotation",
    "tour",
)

#: The methods that can be shown: key → label.
METHODS: dict[str, str] = {
    "mc": "Monte Carlo cloud",
    "a": "Method A (covariance propagation)",
    "c": "Method C (sigma points)",
    "e": "exponential-coordinates Gaussian (banana)",
    "map": "probability map (Method B)",
}

#: The drives offered (:data:`pose_uncertainty.core.drives.DRIVES`); "differential" is the run
#: without a ``drive`` section (the two-wheel model of Methods A and C).
DRIVES: tuple[str, ...] = tuple(_DRIVES)

#: The optional probability map's motion models ("none": no map).
MAP_MODELS: tuple[str, ...] = ("none", "velocity", "odometry")

#: The explorer's settings at start (text, as typed into the page's fields).
DEFAULTS: dict[str, str] = {
    "drive": "differential",
    "geometry": "",
    "k_r": "5e-4",
    "k_l": "5e-4",
    "error_sources": "",
    "track": "0.2",
    "path": "straight",
    "segments": "[[line, 1.0], [turn, 1.5708], [arc, 0.5, 1.5708], [line, 0.5]]",
    "profile": "constant",
    "size": "2.5",
    "speed": "0.5",
    "dt": "0.01",
    "pr": pr_label(PRS[-1]),
    "n_particles": "5000",
    "regime": "per_step",
    "seed": "1",
    "map": "none",
    "map_resolution": "0.02",
    "map_alphas": "",
}

#: CSS of a control: its title wraps within the control's width (Bokeh keeps a title on one line).
_WRAPPED_TITLE = ":host label { white-space: normal; overflow-wrap: anywhere; max-width: 290px; }"

#: Grid points per axis of the banana's drawn boundary (its level is the run's logged one).
_BANANA_GRID = 48
#: Draws and grid points of the banana's boundary without a Monte Carlo (no logged level).
_BANANA_DRAWS = 5_000


def _pr_of(label: str) -> float:
    """The probability of a label of :data:`PRS` ("50", "90", "98.89")."""
    for pr in PRS:
        if pr_label(pr) == str(label):
            return pr
    allowed = ", ".join(pr_label(p) for p in PRS)
    raise ValueError(f"probability level {label!r} is not offered (allowed: {allowed} %)")


def drive_geometry(kind: str) -> str:
    """The default geometry of a drive as the text of the page's geometry field (``key: value, …``)."""
    if kind == "differential":
        return ""
    d = DriveConfig.from_dict({"type": kind}).to_dict()
    return ", ".join(f"{k}: {v}" for k, v in d.items() if k not in ("type", "errors") and v is not None)


def _field(text: str, brackets: str, kind: type, message: str) -> Any:
    """A page field parsed as the YAML flow collection ``brackets[0] text brackets[1]`` of type ``kind``;
    ``ValueError(message)`` when it is not one (the run configuration validates its contents)."""
    import yaml

    try:
        out = yaml.safe_load(brackets[0] + text + brackets[1])
    except yaml.YAMLError:
        out = None
    if isinstance(out, kind):
        return out
    raise ValueError(message)


def _geometry(text: str) -> dict[str, Any]:
    """The geometry field ``key: value, …`` as a mapping (the run configuration validates it)."""
    if not text.strip():
        return {}
    return _field(text, "{}", dict,  # type: ignore[no-any-return]
                  f"drive geometry {text!r} is not a list of 'key: value' (e.g. 'wheelbase: 0.3')")  # fmt: skip


def _segments(text: str) -> Any:
    """The segments field: a YAML flow list ``[[line, L], [arc, r, angle], [turn, angle]]`` as the
    run configuration's ``trajectory.segments`` (the run configuration validates its items)."""
    import yaml

    try:
        out = yaml.safe_load(text)
    except yaml.YAMLError:
        out = None
    if isinstance(out, list):
        return out
    raise ValueError(f"segments {text!r} is not a list of segments "
                     "(e.g. '[[line, 1.0], [turn, 1.5708], [arc, 0.5, 1.5708]]')")  # fmt: skip


def _error_sources(text: str) -> dict[str, Any]:
    """The error-sources field ``key: value, …`` (the wheel-noise model's sources, Šafránek 2022) as
    the mapping of ``drive.errors.encoder`` (the run configuration validates it)."""
    return _field(text, "{}", dict,  # type: ignore[no-any-return]
                  f"error sources {text!r} is not a list of 'key: value' (e.g. 'pulses_per_rev: 400, "
                  "wheel_diameter: 0.065')")  # fmt: skip


def _alphas(text: str) -> Any:
    """The map-alphas field ``a, b, …`` as a list (the run configuration validates its count and values)."""
    return _field(text, "[]", list, f"map alphas {text!r} is not a list of numbers separated by commas "
                                    "(e.g. '0.05, 0.05, 0.05, 0.05')")  # fmt: skip


def run_config(
    settings: Mapping[str, str], base: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """The run configuration mapping of the explorer's settings (not yet validated).

    Parameters
    ----------
    settings : mapping of str to str
        The fields of :data:`DEFAULTS`, as typed (numbers as text: the run configuration
        reads ``"5e-4"`` as a number). ``size`` is the path's length [m] (straight), radius
        [m] (arc, circle, S-curve), target offset ``dx = dy`` [m] (right angles, direct) or
        angle [rad] (rotation: turning in place); ``tour`` drives ``segments`` (the YAML flow list
        ``[[line, L], [arc, r, angle], [turn, angle]]``), with the speed ``profile``
        (:data:`pose_uncertainty.core.trajectories.PROFILES`). ``error_sources`` (``key: value, …``
        of :class:`pose_uncertainty.methods.wheel_noise.WheelErrorSources`; empty: ``k_r``, ``k_l``)
        puts the wheel-noise model's error sources in place of k (a ``drive`` section's
        ``errors.encoder``, on the differential drive too). ``drive`` (one of :data:`DRIVES`) with its
        ``geometry`` (``key: value, …``; empty = the drive's defaults); ``map`` (one of
        :data:`MAP_MODELS`) with its cell ``map_resolution`` [m] and its motion model's error
        constants ``map_alphas`` (``a, b, …``: 6 velocity, 4 odometry; empty = the model's defaults).
    base : mapping, optional
        A full run configuration (e.g. a logged run's) whose other keys (``cov0``,
        ``n_ellipses``, ``name``, the trajectory's start and profile) are kept.

    Returns
    -------
    dict — accepted unchanged by ``pose-uncertainty run`` when valid.
    """
    s = {**DEFAULTS, **settings}
    out: dict[str, Any] = {k: v for k, v in (base or {}).items() if k not in ("drive", "maps")}
    path = s["path"]
    size_key = {
        "straight": ("length",),
        "arc": ("radius",),
        "circle": ("radius",),
        "s_curve": ("radius",),
        "right_angles": ("dx", "dy"),
        "direct": ("dx", "dy"),
        "rotation": ("angle",),
    }.get(path, ())
    traj: dict[str, Any] = {"name": path, "dt": s["dt"], "track": s["track"], "profile": s["profile"]}
    traj["angular_speed" if path == "rotation" else "speed"] = s["speed"]
    traj.update({k: s["size"] for k in size_key})
    if path == "tour":
        traj["segments"] = _segments(s["segments"])
    old = (base or {}).get("trajectory")
    if isinstance(old, Mapping) and old.get("name") == path:
        traj = {**{k: v for k, v in old.items() if k in ("start", "laps", "direction")}, **traj}
    out.update({
        "name": str(out.get("name", "explore")),
        "seed": s["seed"],
        "trajectory": traj,
        "k_r": s["k_r"],
        "k_l": s["k_l"],
        "pr": _pr_of(s["pr"]),
        "monte_carlo": {"n_particles": s["n_particles"], "regime": s["regime"]},
        "maps": [],
    })  # fmt: skip
    if s["drive"] != "differential" or s["error_sources"].strip():
        out["drive"] = {"type": s["drive"], **_geometry(s["geometry"])}
        if s["error_sources"].strip():
            out["drive"]["errors"] = {"encoder": _error_sources(s["error_sources"])}
    if s["map"] != "none":
        out["maps"] = [{"name": s["map"], "model": s["map"], "resolution": s["map_resolution"]}]
        if s["map_alphas"].strip():
            out["maps"][0]["alphas"] = _alphas(s["map_alphas"])
    return out


@dataclass(frozen=True, eq=False)
class View:
    """What the page shows for one setting; every number from the run's own computation.

    Attributes
    ----------
    config : RunConfig — the validated configuration
    result : RunResult — :func:`pose_uncertainty.experiments.run.execute` of it
    regions : dict of str to list of ndarray (m, 2) — the Pr-region boundaries [m] by method key
    coverage : dict of str to dict — per method key: ``fraction`` [1] of the cloud inside its
        region, the 95 % Wilson interval ``low``, ``high`` [1], and ``n`` [1]
    distance : ndarray (N+1,) — distance along the path [m]
    spreads : dict of str to dict of str to ndarray — per method key (``a``; ``c`` without a
        drive): ``sigma_along``, ``sigma_across`` [m] at every pose
    growth : dict of str to dict of str to dict — per method key and spread, :func:`fit_growth`
        against distance
    """

    config: RunConfig
    result: RunResult
    regions: dict[str, list[NDArray[np.float64]]] = field(default_factory=dict)
    coverage: dict[str, dict[str, float]] = field(default_factory=dict)
    distance: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    spreads: dict[str, dict[str, NDArray[np.float64]]] = field(default_factory=dict)
    growth: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)


#: The Monte Carlo's standard normals, kept from one move of a control to the next (the same
#: cloud, drawn once per seed, particles and steps).
_DRAWS = DrawCache()

#: The last computed result: a move of the probability level alone reuses its clouds, maps and
#: accuracy comparison (``execute(..., reuse=…)``, the same numbers).
_LAST: list[RunResult] = []
_LOCK = threading.Lock()

#: Method key → the prefix of its coverage in the run's accuracy measures.
_ACCURACY = {"a": "accuracy_cartesian", "c": "accuracy_unscented", "e": "accuracy_expcoords"}


def _banana(config: RunConfig, res: RunResult) -> list[NDArray[np.float64]]:
    """The banana's boundary at the run's Pr: contoured at the level whose coverage the run measured
    (:attr:`RunResult.expcoords_levels`) on a grid over the cloud, or (no Monte Carlo, no level)
    :func:`expcoords.pr_region_xy` with its own draws."""
    from ..core import trajectories
    from ..experiments import drive_run

    if config.cov0 is not None:
        return []  # the run's banana then starts from Σ_0 in exponential coordinates: not drawn
    traj = trajectories.from_config(config.trajectory)
    if config.drive is None:
        E = expcoords.propagate(traj, config.k_r, config.k_l)
    else:
        E = drive_run.expcoords(drive_run.setup(config.drive, traj, config.k_r, config.k_l), None)
    level = res.expcoords_levels.get(pr_label(config.pr).replace(".", "_"), math.nan)
    try:
        if math.isfinite(level) and res.end_poses is not None and len(res.end_poses):
            lo, hi = res.end_poses[:, :2].min(axis=0), res.end_poses[:, :2].max(axis=0)
            pad = 0.15 * (hi - lo) + 1e-9
            x = np.linspace(lo[0] - pad[0], hi[0] + pad[0], _BANANA_GRID)
            y = np.linspace(lo[1] - pad[1], hi[1] + pad[1], _BANANA_GRID)
            return expcoords.region_xy_at(x, y, E.poses[-1], E.covs[-1], level)
        return expcoords.pr_region_xy(E.poses[-1], E.covs[-1], config.pr, np.random.default_rng([config.seed, 3]),
                                      n_grid=_BANANA_GRID, n=_BANANA_DRAWS)  # fmt: skip
    except (ValueError, np.linalg.LinAlgError):
        return []  # a degenerate banana (no heading spread) has no planar density to contour


def map_region(mp: ProbabilityMap, pr: float) -> list[NDArray[np.float64]]:
    """The boundary of a map's planar Pr highest-density region (its cells of mass ≥ the level of
    :meth:`ProbabilityMap.region_xy`), contoured on its cell centres; empty when its grid holds less."""
    import contourpy

    level, _ = mp.region_xy(pr)
    if not math.isfinite(level):
        return []
    gen = contourpy.contour_generator(mp.x, mp.y, mp.marginal_xy().T)
    return [np.asarray(ln) for ln in gen.lines(level)]


def map_coverage(mp: ProbabilityMap, cloud: NDArray[np.float64] | None, pr: float) -> dict[str, float] | None:
    """The share of the cloud's positions inside the map's Pr region
    (:func:`pose_uncertainty.analysis.accuracy.coverage_gridded`) with its 95 % interval."""
    if cloud is None or not len(cloud):
        return None
    frac = coverage_gridded(mp, cloud[:, :2], [pr])[pr_label(pr)]
    return _interval(frac, len(cloud)) if math.isfinite(frac) else None


def _interval(frac: float, n: int) -> dict[str, float]:
    lo, hi = wilson_interval(round(frac * n), n)
    return {"fraction": float(frac), "low": lo, "high": hi, "n": float(n)}


def compute(
    data: Mapping[str, Any], progress: Callable[[str], Callable[[int, int], None]] | None = None
) -> View:
    """Validate a run configuration mapping as ``pose-uncertainty run`` does, execute it, and
    collect what the page draws.

    The run is executed with the accuracy comparison's planar coverages only (``execute(config,
    distances=False, coverage_only=True)``, the same numbers a run logs) and with the compiled
    loops (``kernel="compiled"``: Method C and the Monte Carlo equal a logged run's up to rounding,
    within the reproducibility contract; the coverages shown are counts, the run's). A change of
    the probability level alone reuses the last result's clouds, maps and accuracy comparison
    (``execute``'s ``reuse``, the same numbers). The Monte Carlo's standard normals are kept
    between calls (:class:`~pose_uncertainty.methods.particles.DrawCache`): a move of a control
    other than the seed, the particles or the path's steps draws none, and the cloud is the same.

    Parameters
    ----------
    data : mapping — a run configuration (:func:`run_config`)
    progress : callable, optional — ``progress(label)`` → ``(done, total)`` callback of the long
        loops (the map); default silent. An exception it raises abandons the computation.

    Raises
    ------
    ValueError
        One line: a bad key or value (:meth:`RunConfig.from_dict`), or an estimated cost over
        the limits (:class:`pose_uncertainty.experiments.cost.CostError`).
    """
    config = RunConfig.from_dict(data)
    cost.check(config)
    with _LOCK:
        last = _LAST[0] if _LAST else None
    same_but_pr = last is not None and last.config == replace(config, pr=last.config.pr)
    res = execute(config, distances=False, coverage_only=True, progress=progress or (lambda label: _silent),
                  kernel="compiled", cache=_DRAWS, reuse=last if same_but_pr else None)  # fmt: skip
    with _LOCK:
        _LAST[:] = [res]
    m, pr, n_end = res.metrics, config.pr, res.n_steps
    regions: dict[str, list[NDArray[np.float64]]] = {
        "a": [covariance.ellipse_polyline(res.covs[n_end, :2, :2], pr, res.poses[n_end, :2])]
    }
    if all(f"C_{k}" in m for k in ("mean_x", "mean_y", "cov_xx", "cov_xy", "cov_yy")):
        c_cov = np.array([[m["C_cov_xx"], m["C_cov_xy"]], [m["C_cov_xy"], m["C_cov_yy"]]])
        regions["c"] = [covariance.ellipse_polyline(c_cov, pr, (m["C_mean_x"], m["C_mean_y"]))]
    regions["e"] = _banana(config, res)
    if res.maps:
        regions["map"] = map_region(res.maps[0], pr)
    coverage: dict[str, dict[str, float]] = {}
    n = int(m.get("accuracy_grid_n_samples", 0))
    for key, prefix in _ACCURACY.items():
        frac = m.get(f"{prefix}_coverage_xy_{pr_label(pr)}".replace(".", "_"))
        if frac is None or n == 0 or not math.isfinite(frac):
            continue
        coverage[key] = _interval(frac, n)
    got = map_coverage(res.maps[0], res.end_poses, pr) if res.maps else None
    if got is not None:
        coverage["map"] = got
    ds = np.hypot(*np.diff(res.poses[:, :2], axis=0).T)
    distance = np.concatenate([[0.0], np.cumsum(ds)])
    spreads: dict[str, dict[str, NDArray[np.float64]]] = {"a": _along_across(res.poses, res.covs)}
    if res.unscented_covs is not None:
        spreads["c"] = _along_across(res.poses, res.unscented_covs)
    growth: dict[str, dict[str, dict[str, float]]] = {}
    for key, sp in spreads.items():
        for k in ("sigma_along", "sigma_across"):
            try:
                growth.setdefault(key, {})[k] = fit_growth(distance, sp[k])
            except ValueError:  # turning in place: no distance to grow over
                pass
    return View(config, res, regions, coverage, distance, spreads, growth)


def _silent(done: int, total: int) -> None:
    """A progress callback that shows nothing."""


def _along_across(poses: NDArray[np.float64], covs: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
    sp = path_spreads(poses, covs)
    return {k: sp[k] for k in ("sigma_along", "sigma_across")}


def save_run_config(path: str | Path, data: Mapping[str, Any]) -> Path:
    """Write a validated run configuration as YAML that ``pose-uncertainty run`` accepts.

    Writes :meth:`RunConfig.to_dict` (every default filled in) atomically to the file the
    user named. Raises ValueError (one line) for an invalid configuration.
    """
    import yaml

    from ..core.atomic import atomic_write_text, check_destination

    if not str(path).strip():
        raise ValueError("save as run config: no file named (type a path ending in .yaml)")
    dest = check_destination(path)  # a regular file or a new path only
    config = RunConfig.from_dict(data)
    text = yaml.safe_dump(config.to_dict(), sort_keys=False)
    return Path(atomic_write_text(dest, text))


def _flow(value: Any) -> str:
    """A value as YAML flow text on one line (``[[line, 1.0], [turn, 1.5708]]``)."""
    import yaml

    return str(yaml.safe_dump(value, default_flow_style=True, width=1 << 30)).strip().removesuffix("...").strip()


def load_log_settings(path: str | Path) -> tuple[dict[str, str], dict[str, Any]]:
    """The explorer's settings and the full configuration of a logged run (``.mcap``).

    Returns
    -------
    (settings, config mapping) — the settings of :data:`DEFAULTS` read from the log's
    configuration; the mapping keeps the keys the controls do not show.
    """
    from ..records.formats import open_run

    log = open_run(path)
    cfg = log.config.to_dict()
    t = cfg["trajectory"]
    name = str(t["name"])
    size = {"straight": "length", "arc": "radius", "circle": "radius", "s_curve": "radius",
            "right_angles": "dx", "direct": "dx", "rotation": "angle"}.get(name)  # fmt: skip
    labels = [pr_label(p) for p in PRS]
    pr = pr_label(cfg["pr"]) if pr_label(cfg["pr"]) in labels else DEFAULTS["pr"]
    drive = cfg.get("drive") or {}
    encoder = (drive.get("errors") or {}).get("encoder") or {}
    maps = [m for m in cfg.get("maps") or [] if m.get("model") in MAP_MODELS]
    settings = {
        "k_r": repr(cfg["k_r"]), "k_l": repr(cfg["k_l"]), "track": repr(t.get("track")),
        "path": name, "size": repr(t.get(size)) if size else DEFAULTS["size"],
        "speed": repr(t.get("angular_speed" if name == "rotation" else "speed")),
        "dt": repr(t.get("dt")), "pr": pr, "n_particles": str(cfg["monte_carlo"]["n_particles"]),
        "regime": str(cfg["monte_carlo"]["regime"]), "seed": str(cfg["seed"]),
        "drive": str(drive.get("type", "differential")),
        "profile": str(t.get("profile", DEFAULTS["profile"])),
        "segments": _flow(t["segments"]) if name == "tour" else DEFAULTS["segments"],
        "error_sources": ", ".join(f"{k}: {_flow(v)}" for k, v in encoder.items()),
        "geometry": ", ".join(f"{k}: {v}" for k, v in drive.items() if k not in ("type", "errors") and v is not None),
        "map": str(maps[0]["model"]) if maps else "none",
        "map_resolution": repr(maps[0].get("resolution")) if maps else DEFAULTS["map_resolution"],
        "map_alphas": ", ".join(repr(a) for a in maps[0].get("alphas") or []) if maps else DEFAULTS["map_alphas"],
    }  # fmt: skip
    return settings, cfg


# --- the page ------------------------------------------------------------------------------------

_COLOURS = {"mc": "#555555", "a": "#d62728", "c": "#2ca02c", "e": "#1f77b4", "map": "#9467bd"}

#: One line per view: what it shows.
STATEMENTS: dict[str, str] = {
    "xy": ("x–y overlay: the Monte Carlo end positions (grey dots) and each method's region that "
           "should hold the chosen share of them, drawn from the run's own covariances."),
    "coverage": ("Coverage: the share of the Monte Carlo end positions inside each method's region, "
                 "with its 95 % Wilson interval; a good method is at the nominal level."),
    "spread": ("σ along and across the path against the distance travelled, for Method A (solid) "
               "and Method C (dashed), in the frame of the nominal heading."),
    "growth": ("Growth exponents: p of σ ∝ s^p fitted log-log over the path, and its local value "
               "over the last fifth (1/2: random-walk growth, 3/2: heading-driven growth)."),
    "map": ("Probability map (Method B, Němec 2012): the velocity or odometry motion model's "
            "histogram along the same controls, computed in the background."),
}


def _number(x: float) -> str:
    return "nan" if not math.isfinite(x) else f"{x:.4g}"


def coverage_html(view: View) -> str:
    """The coverage table: each region's fraction of the cloud with its 95 % interval."""
    pr = view.config.pr
    rows = []
    for key in ("a", "c", "e", "map"):
        c = view.coverage.get(key)
        if c is None:
            continue
        rows.append(
            f'<tr><td>{html.escape(METHODS[key])}</td><td id="coverage-{key}">{100 * c["fraction"]:.2f}</td>'
            f"<td>[{100 * c['low']:.2f}, {100 * c['high']:.2f}]</td></tr>"
        )
    n = int(view.result.metrics.get("MC_n", 0))
    return (
        f"<p>{html.escape(STATEMENTS['coverage'])} {n} end positions, "
        f"nominal {100 * pr:.4g} %.</p>"
        "<table><tr><th>region</th><th>inside [%]</th><th>95 % interval [%]</th></tr>"
        + "".join(rows)
        + "</table>"
    )


def growth_html(view: View) -> str:
    """The growth exponents of each method's σ along and across the path."""
    names = {"a": "Method A", "c": "Method C"}
    rows = []
    for key, fits in view.growth.items():
        for k, g in fits.items():
            rows.append(f'<tr><td>{names.get(key, key)}</td><td>{k.replace("_", " ")}</td>'
                        f'<td id="growth-{key}-{k}">{_number(g["power_exponent"])}</td>'
                        f"<td>{_number(g['local_exponent_end'])}</td></tr>")  # fmt: skip
    if not rows:
        rows.append('<tr><td colspan="4">no distance travelled: nothing to fit</td></tr>')
    return (
        f"<p>{html.escape(STATEMENTS['growth'])}</p><table><tr><th>method</th><th>spread</th>"
        "<th>p</th><th>p at the end</th></tr>" + "".join(rows) + "</table>"
    )


def map_html(mp: ProbabilityMap, model: str, coverage: dict[str, float] | None, pr: float) -> str:
    """The map's line: its model and cell, and its coverage of the cloud."""
    what = (f'<span id="coverage-map">{100 * coverage["fraction"]:.2f}</span> % of the Monte Carlo end '
            f"positions inside its {100 * pr:.4g} % region "
            f"[{100 * coverage['low']:.2f}, {100 * coverage['high']:.2f}]" if coverage else
            f"its {100 * pr:.4g} % region is not on its grid (or no Monte Carlo)")  # fmt: skip
    return (f'<span id="map-done">map ({html.escape(model)} model, {100 * mp.resolution:.3g} cm cells)</span>: '
            f"{what}.")  # fmt: skip


def _options(values: Iterable[str]) -> list[str | tuple[Any, str]]:
    """A Select's options (the type its stubs ask for)."""
    return list(values)


class Superseded(Exception):
    """Raised by a background computation's progress callback when a newer setting replaced it."""


def make_document(doc: Any, initial: Mapping[str, str] | None = None, background: bool | None = None) -> None:
    """Build the explorer's Bokeh document: controls, the x–y overlay, coverage, σ vs distance.

    Parameters
    ----------
    doc : bokeh.document.Document
    initial : mapping, optional — settings of :data:`DEFAULTS` to start from
    background : bool, optional — compute in worker threads and draw on the server's next tick
        (a served page: the controls stay live, a newer setting supersedes an older one); default
        True when the document belongs to a server session, else everything runs synchronously
    """
    import threading
    from concurrent.futures import ThreadPoolExecutor
    from functools import partial

    from bokeh.layouts import column, row
    from bokeh.models import ColumnDataSource
    from bokeh.models.widgets import Button, CheckboxGroup, Div, Select, Slider, TextInput
    from bokeh.plotting import figure

    threaded = (doc.session_context is not None) if background is None else background
    settings = {**DEFAULTS, **(initial or {})}
    state: dict[str, Any] = {"base": None, "want": None, "busy": False, "map_gen": 0}
    lock = threading.Lock()
    fields: dict[str, Any] = {}
    fields["drive"] = Select(title="drive", value=settings["drive"], options=_options(DRIVES), name="field-drive")
    fields["geometry"] = TextInput(title="drive geometry (key: value, …; empty: the drive's defaults)",
                                   value=settings["geometry"] or drive_geometry(settings["drive"]),
                                   name="field-geometry")  # fmt: skip
    for key, title in (("k_r", "k_r [m]"), ("k_l", "k_l [m]"), ("track", "track b [m]"),
                       ("size", "size [m] (length, radius or offset; rotation: angle [rad])"),
                       ("speed", "speed [m/s] (rotation: [rad/s])"), ("dt", "step dt [s]"),
                       ("n_particles", "Monte Carlo particles"), ("seed", "seed")):  # fmt: skip
        fields[key] = TextInput(title=title, value=settings[key], name=f"field-{key}")
    fields["path"] = Select(title="path (tour: the segments below)", value=settings["path"], options=_options(PATHS),
                            name="field-path")  # fmt: skip
    fields["segments"] = TextInput(title="segments of a tour ([line, L], [arc, r, angle], [turn, angle]; m, rad)",
                                   value=settings["segments"], name="field-segments")  # fmt: skip
    fields["profile"] = Select(title="speed profile (per segment)", value=settings["profile"],
                               options=_options(PROFILES), name="field-profile")  # fmt: skip
    fields["error_sources"] = TextInput(
        title="wheel error sources instead of k_r, k_l (key: value, …; e.g. pulses_per_rev: 400)",
        value=settings["error_sources"], name="field-error_sources")  # fmt: skip
    fields["pr"] = Select(title="probability level [%]", value=settings["pr"],
                          options=_options(pr_label(p) for p in PRS), name="field-pr")  # fmt: skip
    fields["regime"] = Select(title="Monte Carlo regime", value=settings["regime"],
                              options=_options(("per_step", "per_run")), name="field-regime")  # fmt: skip
    fields["map"] = Select(title="probability map (computed in the background)", value=settings["map"],
                           options=_options(MAP_MODELS), name="field-map")  # fmt: skip
    fields["map_resolution"] = TextInput(title="map cell [m]", value=settings["map_resolution"],
                                         name="field-map_resolution")  # fmt: skip
    fields["map_alphas"] = TextInput(title="map alphas (6 velocity, 4 odometry; empty: 0.05 each)",
                                     value=settings["map_alphas"], name="field-map_alphas")  # fmt: skip
    sliders = {
        k: Slider(title=f"log10 {k}", start=-5.0, end=-1.5, step=0.05, name=f"slider-{k}",
                  value=_log10_or(settings[k], -3.3))
        for k in ("k_r", "k_l")
    }  # fmt: skip
    shown = CheckboxGroup(
        labels=list(METHODS.values()), active=list(range(len(METHODS))), name="methods"
    )
    error = Div(text="", name="error", styles={"color": "#b00"})
    status = Div(text="", name="status")
    map_status = Div(text="", name="map-status")
    cov_div = Div(text="", name="coverage")
    growth_div = Div(text="", name="growth")

    xy = figure(title="x–y overlay", match_aspect=True, width=620, height=520,
                x_axis_label="x [m]", y_axis_label="y [m]")  # fmt: skip
    src: dict[str, ColumnDataSource] = {
        "path": ColumnDataSource({"x": [], "y": []}),
        "mc": ColumnDataSource({"x": [], "y": []}, name="source-mc"),
        **{k: ColumnDataSource({"xs": [], "ys": []}, name=f"source-{k}") for k in ("a", "c", "e", "map")},
    }
    xy.line("x", "y", source=src["path"], color="#999999", legend_label="nominal path")
    glyphs: dict[str, Any] = {"mc": xy.scatter("x", "y", source=src["mc"], size=2, alpha=0.3, marker="square",
                               line_color=None, fill_color=_COLOURS["mc"],
                               legend_label=METHODS["mc"])}  # fmt: skip
    for k in ("a", "c", "e", "map"):
        glyphs[k] = xy.multi_line(
            "xs", "ys", source=src[k], color=_COLOURS[k], line_width=2, legend_label=METHODS[k]
        )
    xy.legend.location = "top_left"
    xy.legend.label_text_font_size = "8pt"
    spread_fig = figure(title="σ along and across the path against distance", width=620, height=300,
                        x_axis_label="distance s [m]", y_axis_label="σ [m]")  # fmt: skip
    sp_src = ColumnDataSource({"s": [], "a_along": [], "a_across": [], "c_along": [], "c_across": []})
    for key, dash in (("a", "solid"), ("c", "dashed")):
        name = {"a": "Method A", "c": "Method C"}[key]
        spread_fig.line("s", f"{key}_along", source=sp_src, color="#d62728", line_dash=dash,
                        legend_label=f"σ along, {name}")  # fmt: skip
        spread_fig.line("s", f"{key}_across", source=sp_src, color="#1f77b4", line_dash=dash,
                        legend_label=f"σ across, {name}")  # fmt: skip
    spread_fig.legend.location = "top_left"
    spread_fig.legend.label_text_font_size = "8pt"

    def settings_now() -> dict[str, str]:
        return {k: str(w.value) for k, w in fields.items()}

    def put(source: ColumnDataSource, data: dict[str, NDArray[Any]]) -> None:
        """Send the columns of a source that changed, in one message (a k_r move keeps the nominal
        path and the distances along it)."""
        old = source.data
        if set(old) != set(data) or any(len(old[k]) != len(v) for k, v in data.items()):
            source.data = data
            return
        changed = {k: v for k, v in data.items() if not np.array_equal(np.asarray(old[k]), v, equal_nan=True)}
        if changed:
            source.data.update(changed)

    def draw(view: View) -> None:
        res = view.result
        put(src["path"], {"x": res.poses[:, 0], "y": res.poses[:, 1]})
        cloud = res.end_poses if res.end_poses is not None else np.zeros((0, 3))
        # the cloud and the σ curves are only drawn: single precision halves what is sent
        put(src["mc"], {"x": cloud[:, 0].astype(np.float32), "y": cloud[:, 1].astype(np.float32)})
        for k in ("a", "c", "e"):
            lines = view.regions.get(k, [])
            src[k].data = {"xs": [ln[:, 0] for ln in lines], "ys": [ln[:, 1] for ln in lines]}
        nan = np.full(view.distance.shape, np.nan)
        sp = view.spreads
        put(sp_src, {"s": view.distance.astype(np.float32),
                     **{f"{k}_{w}": (sp[k][f"sigma_{w}"] if k in sp else nan).astype(np.float32)
                        for k in ("a", "c") for w in ("along", "across")}})  # fmt: skip
        cov_div.text = coverage_html(view)
        growth_div.text = growth_html(view)
        show(None, None, None)

    def draw_map() -> None:
        """The finished map's region at the shown Pr and its coverage of the shown cloud."""
        got = state.get("map")
        if got is None:
            return
        mp, model = got
        pr = _pr_of(fields["pr"].value) if fields["pr"].value in (pr_label(p) for p in PRS) else PRS[-1]
        lines = map_region(mp, pr)
        src["map"].data = {"xs": [ln[:, 0] for ln in lines], "ys": [ln[:, 1] for ln in lines]}
        map_status.text = map_html(mp, model, map_coverage(mp, state.get("cloud"), pr), pr)

    def show(attr: Any, old: Any, new: Any) -> None:
        for i, k in enumerate(METHODS):
            glyphs[k].visible = i in shown.active

    def shown_error(msg: str, s: dict[str, str] | None = None) -> None:
        error.text = html.escape(msg)
        newer = s is not None and s != state.get("requested")
        status.text = state.get("status", "") + ("; computing the newest setting…" if newer else "")

    def finish(view: View, seconds: float, s: dict[str, str]) -> None:
        error.text = ""
        state["drawn"] = _move_settings(s)
        state["cloud"] = view.result.end_poses
        draw(view)
        draw_map()
        m = view.result.metrics
        newer = s != state.get("requested")  # a newer setting is being computed: this one is not the last
        state["status"] = (f"{view.result.n_steps} steps, path {m['path_length']:.3g} m, "
                           f"{int(m.get('MC_n', 0))} particles, k_r {html.escape(s['k_r'])}, "
                           f"k_l {html.escape(s['k_l'])}; computed in {1000 * seconds:.0f} ms")  # fmt: skip
        status.text = state["status"] + ("; computing the newest setting…" if newer else "")

    def one(s: dict[str, str]) -> tuple[View | None, str, float]:
        t0 = time.perf_counter()
        try:
            view = compute(run_config({**s, "map": "none"}, state["base"]))
        except ValueError as exc:  # the one-line error; the last good picture stays
            return None, str(exc).splitlines()[0], 0.0
        return view, "", time.perf_counter() - t0

    def worker() -> None:
        while True:
            with lock:
                s, state["want"] = state["want"], None
                if s is None:
                    state["busy"] = False
                    return
            view, msg, seconds = one(s)
            if view is None:
                doc.add_next_tick_callback(partial(shown_error, msg, s))
            else:
                doc.add_next_tick_callback(partial(finish, view, seconds, s))

    moves = ThreadPoolExecutor(1, thread_name_prefix="explore-move") if threaded else None
    maps = ThreadPoolExecutor(1, thread_name_prefix="explore-map") if threaded else None

    def later(fn: Callable[..., None], *args: Any) -> None:
        """Call ``fn`` on the server's next tick (from a worker thread), or now without a server."""
        if threaded:
            doc.add_next_tick_callback(partial(fn, *args))
        else:
            fn(*args)

    def map_job(gen: int, s: dict[str, str]) -> None:
        last = [0.0]

        def progress(label: str) -> Callable[[int, int], None]:
            def tick(done: int, total: int) -> None:
                if state["map_gen"] != gen:
                    raise Superseded(label)  # a newer map setting: abandon this one
                now = time.monotonic()
                if now - last[0] > 0.25 or done >= total:
                    last[0] = now
                    text = (f'<span id="map-progress">map: computing, {html.escape(label)} '
                            f"{100 * done / max(total, 1):.0f} % ({done}/{total})</span>")  # fmt: skip
                    later(map_text, gen, text)

            return tick

        try:
            view = compute(run_config(s, state["base"]), progress=progress)
        except Superseded:
            return
        except ValueError as exc:
            later(map_text, gen, f"map: {html.escape(str(exc).splitlines()[0])}")
            return
        later(map_done, gen, view.result.maps[0], s["map"])

    def map_text(gen: int, text: str) -> None:
        if state["map_gen"] == gen:  # else a newer setting's map is on its way
            map_status.text = text

    def map_done(gen: int, mp: ProbabilityMap, model: str) -> None:
        if state["map_gen"] == gen:
            state["map"] = (mp, model)
            draw_map()

    def start_map(s: dict[str, str]) -> None:
        """Start the map of these settings unless it is the one computed or computing: a map
        depends on the path and its own settings only (its coverage is redrawn on each move)."""
        try:
            key = (repr(run_config(s)["trajectory"]), s["map"], s["map_resolution"], s["map_alphas"])
        except ValueError:
            return  # a field that is not even a list or mapping: the move shows its error
        if key == state.get("map_key"):
            return
        state["map_key"] = key
        state["map_gen"] += 1
        state["map"] = None
        src["map"].data = {"xs": [], "ys": []}  # the old map's region is not this setting's
        if s["map"] == "none":
            map_status.text = ""
            return
        map_status.text = '<span id="map-progress">map: queued</span>'
        if maps is not None:
            maps.submit(map_job, state["map_gen"], s)
        else:
            map_job(state["map_gen"], s)

    def update(attr: Any, old: Any, new: Any) -> None:
        s = settings_now()
        state["requested"] = s
        start_map(s)
        with lock:  # a change of the map's fields only (or back to the picture shown): nothing to recompute
            same = not state["busy"] and _move_settings(s) == state.get("drawn")
        if same:
            error.text = ""
            status.text = state.get("status", "")
            return
        if moves is None:
            view, msg, seconds = one(s)
            if view is None:
                shown_error(msg)
            else:
                finish(view, seconds, s)
            return
        status.text = "computing…"
        with lock:
            state["want"] = s
            if state["busy"]:
                return  # the running worker takes the newest setting next (older ones are skipped)
            state["busy"] = True
        moves.submit(worker)

    def on_drive(attr: Any, old: Any, new: Any) -> None:
        fields["geometry"].remove_on_change("value", update)
        fields["geometry"].value = drive_geometry(new)
        fields["geometry"].on_change("value", update)
        update(None, None, None)

    def on_slider(key: str, attr: Any, old: Any, new: Any) -> None:
        fields[key].value = f"{10.0 ** float(new):.3g}"

    for k, w in fields.items():
        if k != "drive":
            w.on_change("value", update)
    fields["drive"].on_change("value", on_drive)
    for k, sl in sliders.items():  # on release (a drag does not queue a computation per pixel)
        sl.on_change("value_throttled", partial(on_slider, k))
    shown.on_change("active", show)

    save_path = TextInput(title="save as run config (YAML file)", value="", name="save-path")
    save_btn = Button(label="Save as run config", name="save")
    open_path = TextInput(title="open a log (.mcap)", value="", name="open-path")
    open_btn = Button(label="Open a log", name="open")

    def on_save() -> None:
        try:
            path = save_run_config(save_path.value, run_config(settings_now(), state["base"]))
        except (ValueError, OSError) as exc:
            error.text = html.escape(str(exc).splitlines()[0])
            return
        error.text = ""
        status.text = html.escape(f"wrote {path}")

    def on_open() -> None:
        try:
            new_settings, cfg = load_log_settings(open_path.value)
        except (ValueError, OSError) as exc:
            error.text = html.escape(str(exc).splitlines()[0])
            return
        state["base"] = cfg
        state["drawn"] = None  # the log's other keys may differ: recompute
        for k, v in new_settings.items():
            if k in fields:
                handler = on_drive if k == "drive" else update
                fields[k].remove_on_change("value", handler)
                fields[k].value = v
                fields[k].on_change("value", handler)
        update(None, None, None)

    save_btn.on_click(on_save)
    open_btn.on_click(on_open)

    for f in fields.values():  # a long title wraps inside the controls' column, not over the views
        f.stylesheets = [_WRAPPED_TITLE]

    def said(key: str) -> Any:
        return Div(text=f"<i>{html.escape(STATEMENTS[key])}</i>", name=f"statement-{key}", width=620)

    controls = column(fields["drive"], fields["geometry"], sliders["k_r"], fields["k_r"], sliders["k_l"],
                      fields["k_l"], *(fields[k] for k in ("error_sources", "track", "path", "segments", "size",
                                                           "speed", "profile", "dt", "pr", "n_particles", "regime",
                                                           "seed")),
                      shown, fields["map"], fields["map_resolution"], fields["map_alphas"], save_path, save_btn,
                      open_path, open_btn,
                      width=300)  # fmt: skip
    views = column(error, status, said("xy"), xy, map_status, cov_div, said("spread"), spread_fig, growth_div)
    doc.add_root(row(controls, views))
    doc.title = "pose-uncertainty explorer"
    update(None, None, None)


def _move_settings(s: Mapping[str, str]) -> dict[str, str]:
    """The settings a move computes (the map's own fields drive the background map only)."""
    return {k: v for k, v in s.items() if k not in ("map", "map_resolution", "map_alphas")}


def _log10_or(text: str, default: float) -> float:
    try:
        v = float(text)
    except ValueError:
        return default
    return min(max(math.log10(v), -5.0), -1.5) if v > 0 else default


def free_port(host: str) -> int:
    """A free TCP port on ``host`` (bound and released; the server binds it next)."""
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def serve(host: str = "127.0.0.1", port: int = 0, announce: Callable[[str], None] = print) -> Any:
    """Start the explorer's Bokeh server (BokehJS served from the package, no CDN) and run it.

    Parameters
    ----------
    host : str — address to bind (default the loopback only)
    port : int — TCP port; 0 = a free one
    announce : callable — receives the page's address once the server listens
    """
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server

    port = port or free_port(host)
    from ..methods import mc_kernel

    # numba's import and the load of the compiled loops (~1.5 CPU-s), before the first page asks
    threading.Thread(target=mc_kernel.jit_module, name="explore-jit", daemon=True).start()
    shown_host = f"[{host}]" if ":" in host else host
    server = Server({"/": Application(FunctionHandler(make_document))}, address=host, port=port,
                    allow_websocket_origin=[f"{shown_host}:{port}", f"localhost:{port}"],
                    num_procs=1)  # fmt: skip
    server.start()
    announce(f"pose-uncertainty explorer at http://{shown_host}:{server.port}/ (Ctrl-C to stop)")
    server.io_loop.start()
    return server
