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
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis.accuracy import PRS, pr_label
from ..core.stats import fit_growth, path_spreads, wilson_interval
from ..experiments import cost
from ..experiments.config import RunConfig
from ..experiments.run import RunResult, execute
from ..methods import covariance, expcoords

__all__ = [
    "DEFAULTS",
    "METHODS",
    "PATHS",
    "View",
    "compute",
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
)

#: The methods that can be shown: key → label.
METHODS: dict[str, str] = {
    "mc": "Monte Carlo cloud",
    "a": "Method A (covariance propagation)",
    "c": "Method C (sigma points)",
    "e": "exponential-coordinates Gaussian (banana)",
}

#: The explorer's settings at start (text, as typed into the page's fields).
DEFAULTS: dict[str, str] = {
    "k_r": "5e-4",
    "k_l": "5e-4",
    "track": "0.2",
    "path": "straight",
    "size": "2.5",
    "speed": "0.5",
    "dt": "0.01",
    "pr": pr_label(PRS[-1]),
    "n_particles": "5000",
    "regime": "per_step",
    "seed": "1",
}

#: Draws and grid cells for the banana's drawn boundary (its coverage is the run's measure).
_BANANA_DRAWS, _BANANA_GRID = 20_000, 80


def _pr_of(label: str) -> float:
    """The probability of a label of :data:`PRS` ("50", "90", "98.89")."""
    for pr in PRS:
        if pr_label(pr) == str(label):
            return pr
    allowed = ", ".join(pr_label(p) for p in PRS)
    raise ValueError(f"probability level {label!r} is not offered (allowed: {allowed} %)")


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
        angle [rad] (rotation: turning in place).
    base : mapping, optional
        A full run configuration (e.g. a logged run's) whose other keys (``cov0``,
        ``n_ellipses``, ``name``, the trajectory's start and profile) are kept; its ``drive``
        and ``maps`` are not (the explorer shows the differential drive, without maps).

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
    traj: dict[str, Any] = {"name": path, "dt": s["dt"], "track": s["track"]}
    traj["angular_speed" if path == "rotation" else "speed"] = s["speed"]
    traj.update({k: s["size"] for k in size_key})
    old = (base or {}).get("trajectory")
    if isinstance(old, Mapping) and old.get("name") == path:
        traj = {
            **{k: v for k, v in old.items() if k in ("start", "profile", "laps", "direction")},
            **traj,
        }
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
    spreads : dict of str to ndarray (N+1,) — Method A's ``sigma_along``, ``sigma_across`` [m]
    growth : dict of str to dict — fit_growth of each spread against distance
    """

    config: RunConfig
    result: RunResult
    regions: dict[str, list[NDArray[np.float64]]] = field(default_factory=dict)
    coverage: dict[str, dict[str, float]] = field(default_factory=dict)
    distance: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    spreads: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    growth: dict[str, dict[str, float]] = field(default_factory=dict)


#: Method key → the prefix of its coverage in the run's accuracy measures.
_ACCURACY = {"a": "accuracy_cartesian", "c": "accuracy_unscented", "e": "accuracy_expcoords"}


def compute(data: Mapping[str, Any]) -> View:
    """Validate a run configuration mapping as ``pose-uncertainty run`` does, execute it, and
    collect what the page draws.

    Raises
    ------
    ValueError
        One line: a bad key or value (:meth:`RunConfig.from_dict`), or an estimated cost over
        the limits (:class:`pose_uncertainty.experiments.cost.CostError`).
    """
    config = RunConfig.from_dict(data)
    cost.check(config)
    res = execute(config)
    m, pr, n_end = res.metrics, config.pr, res.n_steps
    regions: dict[str, list[NDArray[np.float64]]] = {
        "a": [covariance.ellipse_polyline(res.covs[n_end, :2, :2], pr, res.poses[n_end, :2])]
    }
    if all(f"C_{k}" in m for k in ("mean_x", "mean_y", "cov_xx", "cov_xy", "cov_yy")):
        c_cov = np.array([[m["C_cov_xx"], m["C_cov_xy"]], [m["C_cov_xy"], m["C_cov_yy"]]])
        regions["c"] = [covariance.ellipse_polyline(c_cov, pr, (m["C_mean_x"], m["C_mean_y"]))]
    traj_cov0 = None if config.cov0 is None else np.asarray(config.cov0)
    if traj_cov0 is None and config.drive is None:
        from ..core import trajectories

        E = expcoords.propagate(trajectories.from_config(config.trajectory), config.k_r, config.k_l)
        try:
            regions["e"] = expcoords.pr_region_xy(E.poses[-1], E.covs[-1], pr, np.random.default_rng([config.seed, 3]),
                                                  n_grid=_BANANA_GRID, n=_BANANA_DRAWS)  # fmt: skip
        except (ValueError, np.linalg.LinAlgError):
            pass  # a degenerate banana (no heading spread) has no planar density to contour
    coverage: dict[str, dict[str, float]] = {}
    n = int(m.get("accuracy_grid_n_samples", 0))
    for key, prefix in _ACCURACY.items():
        frac = m.get(f"{prefix}_coverage_xy_{pr_label(pr)}".replace(".", "_"))
        if frac is None or n == 0:
            continue
        lo, hi = wilson_interval(round(frac * n), n)
        coverage[key] = {"fraction": float(frac), "low": lo, "high": hi, "n": float(n)}
    ds = np.hypot(*np.diff(res.poses[:, :2], axis=0).T)
    distance = np.concatenate([[0.0], np.cumsum(ds)])
    sp = path_spreads(res.poses, res.covs)
    spreads = {k: sp[k] for k in ("sigma_along", "sigma_across")}
    growth = {}
    for k, v in spreads.items():
        try:
            growth[k] = fit_growth(distance, v)
        except ValueError:  # turning in place: no distance to grow over
            pass
    return View(config, res, regions, coverage, distance, spreads, growth)


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
    settings = {
        "k_r": repr(cfg["k_r"]), "k_l": repr(cfg["k_l"]), "track": repr(t.get("track")),
        "path": name, "size": repr(t.get(size)) if size else DEFAULTS["size"],
        "speed": repr(t.get("angular_speed" if name == "rotation" else "speed")),
        "dt": repr(t.get("dt")), "pr": pr, "n_particles": str(cfg["monte_carlo"]["n_particles"]),
        "regime": str(cfg["monte_carlo"]["regime"]), "seed": str(cfg["seed"]),
    }  # fmt: skip
    return settings, cfg


# --- the page ------------------------------------------------------------------------------------

_COLOURS = {"mc": "#555555", "a": "#d62728", "c": "#2ca02c", "e": "#1f77b4"}


def _number(x: float) -> str:
    return "nan" if not math.isfinite(x) else f"{x:.4g}"


def coverage_html(view: View) -> str:
    """The coverage table: each region's fraction of the cloud with its 95 % interval."""
    pr = view.config.pr
    rows = []
    for key in ("a", "c", "e"):
        c = view.coverage.get(key)
        if c is None:
            continue
        rows.append(
            f'<tr><td>{html.escape(METHODS[key])}</td><td id="coverage-{key}">{100 * c["fraction"]:.2f}</td>'
            f"<td>[{100 * c['low']:.2f}, {100 * c['high']:.2f}]</td></tr>"
        )
    n = int(view.result.metrics.get("MC_n", 0))
    return (
        f"<p>Coverage: the share of the {n} Monte Carlo end poses inside each method's "
        f"{100 * pr:.4g} % region (nominal {100 * pr:.4g} %), with its 95 % Wilson interval.</p>"
        "<table><tr><th>region</th><th>inside [%]</th><th>95 % interval [%]</th></tr>"
        + "".join(rows)
        + "</table>"
    )


def growth_html(view: View) -> str:
    """The growth exponents of Method A's σ along and across the path."""
    rows = []
    for k, g in view.growth.items():
        rows.append(f'<tr><td>{k.replace("_", " ")}</td><td id="growth-{k}">{_number(g["power_exponent"])}</td>'
                    f"<td>{_number(g['local_exponent_end'])}</td></tr>")  # fmt: skip
    return (
        "<p>Growth exponents: p of σ ∝ s^p (Method A, fitted log-log over the path) and its "
        "local value over the last fifth.</p><table><tr><th>spread</th><th>p</th><th>p at the end</th></tr>"
        + "".join(rows)
        + "</table>"
    )


def _options(values: Iterable[str]) -> list[str | tuple[Any, str]]:
    """A Select's options (the type its stubs ask for)."""
    return list(values)


def make_document(doc: Any, initial: Mapping[str, str] | None = None) -> None:
    """Build the explorer's Bokeh document: controls, the x–y overlay, coverage, σ vs distance."""
    from bokeh.layouts import column, row
    from bokeh.models import ColumnDataSource
    from bokeh.models.widgets import Button, CheckboxGroup, Div, Select, TextInput
    from bokeh.plotting import figure

    settings = {**DEFAULTS, **(initial or {})}
    state: dict[str, Any] = {"base": None}
    fields: dict[str, Any] = {}
    for key, title in (("k_r", "k_r [m]"), ("k_l", "k_l [m]"), ("track", "track b [m]"),
                       ("size", "size [m] (length, radius or offset; rotation: angle [rad])"),
                       ("speed", "speed [m/s] (rotation: [rad/s])"), ("dt", "step dt [s]"),
                       ("n_particles", "Monte Carlo particles"), ("seed", "seed")):  # fmt: skip
        fields[key] = TextInput(title=title, value=settings[key], name=f"field-{key}")
    path_options: list[str | tuple[Any, str]] = [*PATHS]
    fields["path"] = Select(
        title="path", value=settings["path"], options=path_options, name="field-path"
    )
    fields["pr"] = Select(title="probability level [%]", value=settings["pr"],
                          options=_options(pr_label(p) for p in PRS), name="field-pr")  # fmt: skip
    fields["regime"] = Select(title="Monte Carlo regime", value=settings["regime"],
                              options=_options(("per_step", "per_run")), name="field-regime")  # fmt: skip
    shown = CheckboxGroup(
        labels=list(METHODS.values()), active=list(range(len(METHODS))), name="methods"
    )
    error = Div(text="", name="error", styles={"color": "#b00"})
    status = Div(text="", name="status")
    cov_div = Div(text="", name="coverage")
    growth_div = Div(text="", name="growth")

    xy = figure(title="x–y overlay: Monte Carlo end poses and each method's region at the chosen level",
                match_aspect=True, width=620, height=560, x_axis_label="x [m]", y_axis_label="y [m]",
                output_backend="webgl")  # fmt: skip
    src: dict[str, ColumnDataSource] = {
        "path": ColumnDataSource({"x": [], "y": []}),
        "mc": ColumnDataSource({"x": [], "y": []}),
        **{k: ColumnDataSource({"xs": [], "ys": []}) for k in ("a", "c", "e")},
    }
    xy.line("x", "y", source=src["path"], color="#999999", legend_label="nominal path")
    glyphs: dict[str, Any] = {"mc": xy.scatter("x", "y", source=src["mc"], size=2, alpha=0.3, color=_COLOURS["mc"],
                               legend_label=METHODS["mc"])}  # fmt: skip
    for k in ("a", "c", "e"):
        glyphs[k] = xy.multi_line(
            "xs", "ys", source=src[k], color=_COLOURS[k], line_width=2, legend_label=METHODS[k]
        )
    xy.legend.location = "top_left"
    xy.legend.label_text_font_size = "8pt"
    spread_fig = figure(title="σ along and across the path against distance (Method A)", width=620, height=300,
                        x_axis_label="distance s [m]", y_axis_label="σ [m]")  # fmt: skip
    sp_src = ColumnDataSource({"s": [], "along": [], "across": []})
    spread_fig.line("s", "along", source=sp_src, color="#d62728", legend_label="σ along")
    spread_fig.line("s", "across", source=sp_src, color="#1f77b4", legend_label="σ across")
    spread_fig.legend.location = "top_left"

    def settings_now() -> dict[str, str]:
        return {k: str(w.value) for k, w in fields.items()}

    def draw(view: View) -> None:
        res = view.result
        src["path"].data = {"x": res.poses[:, 0], "y": res.poses[:, 1]}
        cloud = res.end_poses if res.end_poses is not None else np.zeros((0, 3))
        src["mc"].data = {"x": cloud[:, 0], "y": cloud[:, 1]}
        for k in ("a", "c", "e"):
            lines = view.regions.get(k, [])
            src[k].data = {"xs": [ln[:, 0] for ln in lines], "ys": [ln[:, 1] for ln in lines]}
        sp_src.data = {
            "s": view.distance,
            "along": view.spreads["sigma_along"],
            "across": view.spreads["sigma_across"],
        }
        cov_div.text = coverage_html(view)
        growth_div.text = growth_html(view)
        show(None, None, None)

    def show(attr: Any, old: Any, new: Any) -> None:
        keys = list(METHODS)
        for i, k in enumerate(keys):
            glyphs[k].visible = i in shown.active

    def update(attr: Any, old: Any, new: Any) -> None:
        try:
            view = compute(run_config(settings_now(), state["base"]))
        except ValueError as exc:  # the one-line error; the last good picture stays
            error.text = html.escape(str(exc).splitlines()[0])
            return
        error.text = ""
        draw(view)
        m = view.result.metrics
        status.text = (f"{view.result.n_steps} steps, path {m['path_length']:.3g} m, "
                       f"{int(m.get('MC_n', 0))} particles")  # fmt: skip

    for w in fields.values():
        w.on_change("value", update)
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
        for k, v in new_settings.items():
            if k in fields:
                fields[k].remove_on_change("value", update)
                fields[k].value = v
                fields[k].on_change("value", update)
        update(None, None, None)

    save_btn.on_click(on_save)
    open_btn.on_click(on_open)
    controls = column(*fields.values(), shown, save_path, save_btn, open_path, open_btn, width=300)
    views = column(error, status, xy, cov_div, spread_fig, growth_div)
    doc.add_root(row(controls, views))
    doc.title = "pose-uncertainty explorer"
    update(None, None, None)


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
    shown_host = f"[{host}]" if ":" in host else host
    server = Server({"/": Application(FunctionHandler(make_document))}, address=host, port=port,
                    allow_websocket_origin=[f"{shown_host}:{port}", f"localhost:{port}"],
                    num_procs=1)  # fmt: skip
    server.start()
    announce(f"pose-uncertainty explorer at http://{shown_host}:{server.port}/ (Ctrl-C to stop)")
    server.io_loop.start()
    return server
