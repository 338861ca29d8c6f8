"""Figures the pipeline draws beyond a single run's (those are in :mod:`pose_uncertainty.present.figures`).

* :func:`render_run_figure` — one figure of one run log, by kind (``trajectory``,
  ``cloud``, ``map_<name>``), drawn by the same functions ``replay --figures`` uses;
* :func:`growth_figure` — how each uncertainty measure grows with distance (log-log),
  over the runs of a set;
* :func:`cloud_polar_figure` — Šafránek 2022's Cartesian and polar views of the end-pose clouds;
* :func:`expcoords_figure` — long-path Monte Carlo clouds with Method A's ellipse and the
  exponential-coordinates Gaussian's region (the banana) drawn over them;
* :func:`umbmark_figure` — the classic UMBmark figure: the cw and ccw return-position
  errors before and after the correction, with their centres of gravity;
* :func:`render_study_figure` — a study's figure from its log alone, by the study's kind
  (:data:`STUDY_FIGURES`).
* :func:`drives_figure` — σ along and across the path per drive, one panel per path, from the
  logged measures of runs with a drive.
* :func:`sweep_heatmaps_figure`, :func:`sweep_dependence_figure` — a large sweep's response
  surfaces and partial dependence, from its summary alone (:mod:`pose_uncertainty.pipeline.sweep_summary`).

Every figure is saved by :func:`pose_uncertainty.present.figures.save_figure` (deterministic bytes).
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..core.drives import DRIVES
from ..core.stats import COVERAGE_LEVELS
from ..experiments.study import read_study
from ..methods.covariance import ellipse_polyline
from ..records.run import open_run
from . import figures
from .study_figures import STUDY_FIGURE_KEYS

__all__ = [
    "STUDY_FIGURES",
    "cloud_polar_figure",
    "drives_figure",
    "expcoords_figure",
    "growth_figure",
    "map_cloud_figure",
    "render_run_figure",
    "render_run_figures",
    "render_set_figure",
    "render_study_figure",
    "render_sweep_figures",
    "sweep_dependence_figure",
    "sweep_heatmaps_figure",
    "umbmark_figure",
]

#: Margins [inch] of the map-vs-sampler figure (6 × 6 in, equal aspect): y tick labels up to "−0.010"
_MAP_CLOUD_MARGINS = figures.Margins(left=0.8, bottom=0.55, right=0.2, top=0.35)


def render_run_figure(log: str | os.PathLike[str], kind: str, out: str | os.PathLike[str]) -> Path:
    """Draw one figure of a run log and save it.

    Parameters
    ----------
    log : path — run log (``*.mcap``)
    kind : {"trajectory", "cloud", "map_<name>", "mapcloud_<name>"}
    out : path — ``*.png`` / ``*.svg`` / ``*.pdf``

    Raises
    ------
    ValueError if the kind is unknown or the run lacks what the figure draws.
    """
    return render_run_figures(log, [kind], [out])[0]


def render_run_figures(
    log: str | os.PathLike[str], kinds: Sequence[str], outs: Sequence[str | os.PathLike[str]]
) -> list[Path]:
    """Draw several figures of one run log (read once); see :func:`render_run_figure` for the kinds."""
    if len(kinds) != len(outs):
        raise ValueError(f"kinds and outs must have equal length, got {len(kinds)} and {len(outs)}")
    run = open_run(log)
    return [_render(run, log, kind, out) for kind, out in zip(kinds, outs, strict=True)]


def _render(run: Any, log: str | os.PathLike[str], kind: str, out: str | os.PathLike[str]) -> Path:
    fig: Figure | None
    if kind == "trajectory":
        fig = figures.trajectory_figure(run)
    elif kind == "cloud":
        fig = figures.cloud_figure(run)
        if fig is None:
            raise ValueError(f"{log}: kind 'cloud' needs Monte Carlo end poses (monte_carlo.n_particles > 0)")
    elif kind.startswith("mapcloud_"):
        name = kind[len("mapcloud_"):]
        maps = {m.name: m for m in run.maps}
        if name not in maps:
            raise ValueError(f"{log}: map {name!r} not in the run (allowed: {', '.join(maps) or 'none'})")
        fig = map_cloud_figure(run, maps[name])
    elif kind.startswith("map_"):
        name = kind[4:]
        maps = {m.name: m for m in run.maps}
        if name not in maps:
            raise ValueError(f"{log}: map {name!r} not in the run (allowed: {', '.join(maps) or 'none'})")
        fig = figures.map_figure(run, maps[name])
    else:
        raise ValueError(
            f"figure kind must be 'trajectory', 'cloud', 'map_<name>' or 'mapcloud_<name>', got {kind!r}"
        )
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    return figures.save_figure(fig, out)


def map_cloud_figure(run: Any, mp: Any) -> Figure:
    """The map's own sampler's logged draws over the map's 39 / 86 / 98.89 % contours.

    Parameters
    ----------
    run : RunResult — with ``map_samplers`` (logged with the run)
    mp : ProbabilityMap — one of ``run.maps``
    """
    marg = mp.marginal_xy()
    end = run.poses[-1]
    title, margins = figures.fit_title(f"{run.config.name}: {mp.model} model, map contours vs its sampler",
                                       (6.0, 6.0), _MAP_CLOUD_MARGINS, "medium")  # fmt: skip
    fig = figures.new_figure((6.0, 6.0), margins=margins)
    ax = fig.add_subplot()
    cloud = run.map_samplers.get(mp.name, np.zeros((0, 3)))
    if cloud.shape[0]:
        ax.scatter(cloud[:, 0], cloud[:, 1], s=1.0, color="0.35", alpha=0.3, linewidths=0, rasterized=True,
                   label=f"sampler end poses (n = {cloud.shape[0]})")
    prs = tuple(COVERAGE_LEVELS.values())
    levels = [mp.region_xy(pr)[0] for pr in prs]
    colors = ("tab:blue", "tab:purple", "red")
    for lvl, pr, col in sorted(zip(levels, prs, colors, strict=True)):
        if math.isfinite(lvl) and marg.max() > lvl > 0:
            ax.contour(mp.x, mp.y, marg.T, levels=[lvl], colors=[col], linewidths=1.0)
            ax.plot([], [], color=col, lw=1.0, label=f"map region {100 * pr:.2f} %")
    ax.plot(*end[:2], marker="+", color="red", ms=10, ls="none", label="noiseless end point")
    ax.plot(*run.poses[0, :2], marker="o", color="k", ms=3, ls="none", label="start")
    ax.set_xlim(float(mp.x[0]), float(mp.x[-1]))
    ax.set_ylim(float(mp.y[0]), float(mp.y[-1]))
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize="medium")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(loc="upper right", fontsize="x-small")
    return fig


def growth_figure(logs: Sequence[str | os.PathLike[str]], title: str = "") -> Figure:
    """Uncertainty measures against path length, log-log, with reference slopes.

    Draws, for every run of the set (sorted by path length), its logged measures:
    Method A's standard deviations along and across the end heading and of θ, the
    semi-axes of the Pr-ellipse, Method C's and the Monte Carlo sample's along/across
    standard deviations (:mod:`pose_uncertainty.analysis.measures`).

    Parameters
    ----------
    logs : sequence of paths to run logs
    title : str
    """
    measures = {"L": "path_length", "A: σ along": "A_sigma_along", "A: σ across": "A_sigma_across",
                "A: σ_θ [rad]": "A_sigma_theta", "A: ellipse major": "A_ellipse_major",
                "A: ellipse minor": "A_ellipse_minor", "MC: σ along": "MC_sigma_along",
                "MC: σ across": "MC_sigma_across", "C: σ along": "C_sigma_along",
                "C: σ across": "C_sigma_across"}  # fmt: skip
    rows = []
    for p in logs:
        logged = open_run(p).metrics
        rows.append({label: logged.get(key, math.nan) for label, key in measures.items()})
    rows.sort(key=lambda r: r["L"])
    L = np.array([r["L"] for r in rows])
    fig = figures.new_figure((6.4, 5.2), dpi=figures.WIDE_DPI)
    ax = fig.add_subplot()
    styles = {
        "A: σ along": ("#0072B2", "-", "o"),
        "A: σ across": ("#D55E00", "-", "o"),
        "A: σ_θ [rad]": ("tab:green", "-", "s"),
        "A: ellipse major": ("0.3", ":", "^"),
        "A: ellipse minor": ("0.6", ":", "v"),
        "MC: σ along": ("#0072B2", "none", "x"),
        "MC: σ across": ("#D55E00", "none", "x"),
        "C: σ along": ("#0072B2", "none", "+"),
        "C: σ across": ("#D55E00", "none", "+"),
    }
    for key, (color, ls, marker) in styles.items():
        vals = np.array([r.get(key, np.nan) for r in rows])
        ok = np.isfinite(vals) & (vals > 0)
        if ok.sum() == 0:
            continue
        ax.loglog(L[ok], vals[ok], color=color, ls=ls, marker=marker, ms=4, lw=1.0, label=key)
    if L.size >= 2:
        # reference slopes through the first point of the curve they describe, offset below it
        ref = np.array([L.min(), L.max()])
        for slope, key, dash in ((0.5, "A: σ along", (0, (2, 2))), (1.5, "A: σ across", (0, (6, 2)))):
            y0 = 0.5 * float(rows[0][key])
            ax.loglog(ref, y0 * (ref / ref[0]) ** slope, color="k", lw=0.6, ls=dash,
                      label=f"slope {slope:g} (∝ L^{slope:g})")
    ax.set_xlabel("path length L [m]")
    ax.set_ylabel("uncertainty [m] (σ_θ in rad)")
    ax.set_title(title or "growth of the uncertainty with distance")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize="x-small", loc="upper left")
    return fig


#: Columns of :func:`cloud_polar_figure`'s grid, and the side of one of its square panels [inch]: 4 runs a row
#: (each run's Cartesian view over its polar one) keep the figure under 900 CSS px wide at its dpi, so the report
#: shows it at its own size (text at its size in points) with 2× the pixels, not shrunk from a row of 8
CLOUD_POLAR_COLUMNS = 4
CLOUD_POLAR_PANEL = 2.4
#: The end poses drawn of each run's cloud at most (every k-th, in the logged order, which is the particles'
#: index order): 500 show each cloud's shape, bent or not, as 1000 do, in 40 % fewer bytes of the figure
CLOUD_POLAR_POINTS = 500


def cloud_polar_figure(logs: Sequence[str | os.PathLike[str]], title: str = "") -> Figure:
    """Šafránek 2022's two views of the end-pose clouds: Cartesian (x, y) and polar (bearing, range).

    One run a column, :data:`CLOUD_POLAR_COLUMNS` runs a row (at most 8 runs: the caller selects them), each run
    as two panels: above, the cloud in the plane with Method A's Pr-ellipse; below, the same cloud as bearing
    ``atan2(y, x)`` [deg] against range ``√(x²+y²)`` [m] from the start, with the ellipse mapped alike. Of a
    cloud of more than :data:`CLOUD_POLAR_POINTS` end poses every k-th is drawn, k the smallest that keeps at
    most that many.

    Parameters
    ----------
    logs : sequence of paths to run logs (the first 8 are drawn)
    title : str
    """
    runs = [open_run(p) for p in list(logs)[:8]]
    cols = min(max(len(runs), 1), CLOUD_POLAR_COLUMNS)
    rows = 2 * max(math.ceil(len(runs) / cols), 1)
    side = CLOUD_POLAR_PANEL
    fig = figures.new_figure((side * cols + 0.3, side * rows + (0.4 if title else 0.0)), dpi=figures.WIDE_DPI)
    for j, run in enumerate(runs):
        top = 2 * (j // cols) * cols + j % cols + 1
        ax = fig.add_subplot(rows, cols, top)
        axp = fig.add_subplot(rows, cols, top + cols)
        end, cov = run.poses[-1], run.covs[-1]
        cloud = run.end_poses if run.end_poses is not None else np.zeros((0, 3))
        cloud = cloud[:: max(1, math.ceil(len(cloud) / CLOUD_POLAR_POINTS))]
        ax.scatter(cloud[:, 0], cloud[:, 1], s=1.0, color="0.3", alpha=0.4, linewidths=0, rasterized=True)
        pts = ellipse_polyline(cov[:2, :2], run.config.pr, end[:2], 200)
        ax.plot(pts[:, 0], pts[:, 1], color="red", lw=1.0)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_title(run.config.name, fontsize="small")
        start = run.poses[0]
        rel = cloud[:, :2] - start[:2]
        bearing = np.degrees(np.arctan2(rel[:, 1], rel[:, 0]))
        rng = np.hypot(rel[:, 0], rel[:, 1])
        axp.scatter(bearing, rng, s=1.0, color="0.3", alpha=0.4, linewidths=0, rasterized=True)
        erel = pts - start[:2]
        axp.plot(np.degrees(np.arctan2(erel[:, 1], erel[:, 0])), np.hypot(erel[:, 0], erel[:, 1]), color="red", lw=1.0)
        axp.set_xlabel("bearing from start [deg]")
        if j % cols == 0:  # the row's labels once, at its left
            ax.set_ylabel("y [m]")
            axp.set_ylabel("range from start [m]")
        for a in (ax, axp):
            a.xaxis.set_major_locator(MaxNLocator(3))
            a.yaxis.set_major_locator(MaxNLocator(5))
    if title:
        fig.suptitle(title)
    return fig


def expcoords_figure(data: Mapping[str, Any]) -> Figure:
    """Monte Carlo end positions with every method's Pr region over them: the report's headline figure.

    Draws the logged results of the ``expcoords_regions`` study
    (:func:`pose_uncertainty.analysis.studies.expcoords_regions`), one axes per case: the
    cloud, Method A's Pr-ellipse, the boundary of the exponential-coordinates Gaussian's
    planar Pr highest-density region, Method C's Pr-ellipse about its mean (dash-dot),
    Method B's map region (dotted, in logs that have it) and the nominal path, in the
    methods' colours (:data:`pose_uncertainty.present.figures.METHOD_COLOURS`); the legend
    gives the logged share of the cloud inside each region.
    """
    cases = data["cases"]
    pr, n = float(data["pr"]), int(data["n"])
    fig = figures.new_figure((5.2 * len(cases), 5.0), dpi=figures.WIDE_DPI)
    colour = figures.METHOD_COLOURS
    for j, case in enumerate(cases):
        cloud, path = np.asarray(case["cloud_xy"]), np.asarray(case["path_xy"])
        ell, end = np.asarray(case["ellipse_xy"]), case["end"]
        ax = fig.add_subplot(1, len(cases), j + 1)
        ax.scatter(cloud[:, 0], cloud[:, 1], s=1.0, color=colour["MC"], alpha=0.35, linewidths=0,
                   rasterized=True, label=f"Monte Carlo, {n} runs")  # fmt: skip
        ax.plot(ell[:, 0], ell[:, 1], color=colour["A"], lw=1.4, label=f"A: ellipse, holds {100 * case['inside_ellipse']:.1f} %")
        if "map" in case:  # Method B, in logs that have it
            for i, line in enumerate(case["map"]["boundary_xy"]):
                line = np.asarray(line)
                ax.plot(line[:, 0], line[:, 1], color=colour["B"], lw=1.6, ls=":",
                        label=f"B: map region, holds {100 * case['inside_map']:.1f} %" if i == 0 else None)  # fmt: skip
        if "c_ellipse_xy" in case:  # Method C, in logs that have it
            cel, cm = np.asarray(case["c_ellipse_xy"]), case["c_mean"]
            ax.plot(cel[:, 0], cel[:, 1], color=colour["C"], lw=1.4, ls="-.",
                    label=f"C: ellipse, holds {100 * case['inside_c']:.1f} %")
            ax.plot([cm[0]], [cm[1]], marker="x", color=colour["C"], ms=7, ls="none")
        for i, poly in enumerate(case["banana_xy"]):
            poly = np.asarray(poly)
            ax.plot(poly[:, 0], poly[:, 1], color=colour["expcoords"], lw=1.4,
                    label=f"exp. coords: region, holds {100 * case['inside_banana']:.1f} %" if i == 0 else None)  # fmt: skip
        ax.plot(path[:, 0], path[:, 1], color="k", lw=0.6, ls="--", label="noiseless path")
        ax.plot([end[0]], [end[1]], marker="+", color="k", ms=8)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"{case['label']}: {100 * pr:.2f} % regions; k = {data['k']:g} m, b = {data['track']:g} m",
                     fontsize="medium")  # fmt: skip
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize="small", loc="best", framealpha=0.9)
    return fig


def drives_figure(logs: Sequence[str | os.PathLike[str]], title: str = "") -> Figure:
    """σ along and across the path at its end, per drive, one panel per path (log scale).

    Filled markers: Method A's logged ``A_sigma_along`` (blue circles) and ``A_sigma_across``
    (red squares); crosses: the Monte Carlo's ``MC_sigma_along`` / ``MC_sigma_across``
    (:mod:`pose_uncertainty.analysis.measures`). Runs without a drive section are drawn as
    ``differential``. Drives in the order of :data:`pose_uncertainty.core.drives.DRIVES`; paths
    in the order they first appear.

    Parameters
    ----------
    logs : sequence of paths to run logs
    title : str
    """
    panels: dict[str, dict[str, dict[str, float]]] = {}
    for p in logs:
        run = open_run(p)
        m = run.metrics
        label = f"{run.config.trajectory['name']}, {m.get('path_length', math.nan):.3g} m"
        kind = "differential" if run.config.drive is None else run.config.drive.type
        panels.setdefault(label, {})[kind] = m
    fig = figures.new_figure((3.4 * max(len(panels), 1) + 0.6, 4.8), dpi=figures.WIDE_DPI)
    series = (("A_sigma_along", "tab:blue", "o", "Method A: σ along"),
              ("A_sigma_across", "tab:red", "s", "Method A: σ across"),
              ("MC_sigma_along", "tab:blue", "x", "Monte Carlo: σ along"),
              ("MC_sigma_across", "tab:red", "x", "Monte Carlo: σ across"))  # fmt: skip
    for j, (label, runs) in enumerate(panels.items()):
        ax = fig.add_subplot(1, len(panels), j + 1)
        order = [k for k in DRIVES if k in runs]
        for key, color, marker, name in series:
            filled = marker != "x"
            ax.plot(range(len(order)), [runs[k].get(key, math.nan) for k in order], ls="none", marker=marker,
                    ms=7 if filled else 9, color=color, alpha=0.6 if filled else 1.0,
                    label=name if j == 0 else None)  # fmt: skip
        ax.set_yscale("log")
        ax.set_xlim(-0.6, len(order) - 0.4)
        ax.set_xticks(range(len(order)), order, rotation=45, ha="right", fontsize="small")
        ax.set_title(label, fontsize="medium")
        if j == 0:
            ax.set_ylabel("standard deviation at the end [m]")
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
    fig.legend(loc="outside lower center", ncols=4, fontsize="x-small")
    if title:
        fig.suptitle(title)
    return fig


def render_set_figure(
    kind: str, logs: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str], title: str = ""
) -> Path:
    """Draw a set-level figure (``growth``, ``cloud_polar`` or ``drives``) and save it."""
    draw = {"growth": growth_figure, "cloud_polar": cloud_polar_figure, "drives": drives_figure}
    return figures.save_figure_of_kind(kind, {k: functools.partial(f, logs, title) for k, f in draw.items()}, out)


# --- the UMBmark figure, and a study's figure by its kind -----------------------------------------


def umbmark_figure(data: Mapping[str, Any]) -> Figure:
    """The classic UMBmark figure from the logged results of an ``umbmark`` study.

    Return-position errors ε = (x_abs − x_calc, y_abs − y_calc) [m] of the cw (blue) and
    ccw (red) squares before the correction (filled) and after it (hollow), with each
    cluster's centre of gravity (large markers) and the circles of radius E_max,syst
    before and after (:func:`pose_uncertainty.analysis.umbmark.umbmark_experiment`).
    """
    umb = data["umbmark"]
    e_before = umb["estimates"]["E_max_before"]["value"]
    e_after = umb["E_max_after_measured"]["value"]
    fig = figures.new_figure((6.4, 6.0), dpi=figures.WIDE_DPI)
    ax = fig.add_subplot()
    colours = {"cw": "tab:blue", "ccw": "tab:red"}
    for d, col in colours.items():
        b, a = np.asarray(data["before"][d]), np.asarray(data["after"][d])
        cb, ca = data["centres_before"][d], data["centres_after"][d]
        ax.scatter(b[:, 0], b[:, 1], s=22, color=col, marker="o", label=f"{d}, before ({b.shape[0]} runs)")
        ax.scatter(a[:, 0], a[:, 1], s=22, facecolors="none", edgecolors=col, marker="o",
                   label=f"{d}, after correction")  # fmt: skip
        ax.plot([cb[0]], [cb[1]], marker="X", color=col, ms=11, mec="k", ls="none",
                label=f"{d} centre of gravity, before")  # fmt: skip
        ax.plot([ca[0]], [ca[1]], marker="X", color="white", ms=11, mec=col, ls="none",
                label=f"{d} centre of gravity, after")  # fmt: skip
    t = np.linspace(0.0, 2.0 * math.pi, 361)
    for r, ls, what in ((e_before, "--", "before"), (e_after, ":", "after")):
        ax.plot(r * np.cos(t), r * np.sin(t), color="0.4", lw=0.8, ls=ls,
                label=f"E_max,syst {what} = {100 * r:.3g} cm")  # fmt: skip
    ax.axhline(0.0, color="k", lw=0.5)
    ax.axvline(0.0, color="k", lw=0.5)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("return error x [m] (along the first leg)")
    ax.set_ylabel("return error y [m] (to its left)")
    tr_ = data["true"]
    ax.set_title(f"UMBmark, {data['side']:g} m square: true E_d = {tr_['E_d']:g}, E_b = {tr_['E_b']:g}, "
                 f"k = {data['k']:g} m", fontsize="medium")  # fmt: skip
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize="x-small", loc="best")
    return fig


_FIGURE_OF_STUDY = {"expcoords_regions": expcoords_figure, "umbmark": umbmark_figure}

#: The figure of a study by the study's kind (a key of pose_uncertainty.analysis.studies.STUDIES):
#: the key the report shows it under (:data:`pose_uncertainty.present.study_figures.STUDY_FIGURE_KEYS`,
#: which the workflow reads without importing matplotlib) and the function drawing it from the
#: study's logged results.
STUDY_FIGURES: dict[str, tuple[str, Any]] = {kind: (key, _FIGURE_OF_STUDY[kind]) for kind, key in STUDY_FIGURE_KEYS.items()}


def render_study_figure(study_log: str | os.PathLike[str], out: str | os.PathLike[str]) -> Path:
    """Draw a study's figure from its log alone (the function of :data:`STUDY_FIGURES` for its kind)."""
    doc = read_study(study_log)
    kind = doc["study"]
    if kind not in STUDY_FIGURES:
        raise ValueError(
            f"{study_log}: a {kind!r} study has no figure (allowed: {', '.join(sorted(STUDY_FIGURES))})"
        )
    with mpl.rc_context(figures.CRISP_RC):  # type: ignore[arg-type]  # as the set figures: the report shows it at half its pixels
        fig = STUDY_FIGURES[kind][1](doc["results"])
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    return figures.save_figure(fig, out)


# --- the summary views of a large sweep (pose_uncertainty.pipeline.sweep_summary) ---------------------


def _panels(n: int, width: float = 3.2, height: float = 2.6) -> tuple[Figure, int, int]:
    cols = min(4, max(1, n))
    rows = max(1, math.ceil(n / cols))
    return figures.new_figure((width * cols, height * rows), dpi=figures.WIDE_DPI), rows, cols


def _clipped(text: str, n: int = 18) -> str:
    return text if len(text) <= n else text[: n - 1] + "…"


def sweep_heatmaps_figure(summary: Mapping[str, Any], title: str = "") -> Figure:
    """Each measure's response surface over the two axes it depends on most (the summary's ``surface``).

    One panel per measure: the mean of the measure over every other axis at each pair of levels
    (colour, relative to the panel's own range), both axes by level.
    """
    axes = summary["axes"]
    ms = [m for m in summary["measures"] if "surface" in m]
    fig, rows, cols = _panels(len(ms), 3.6, 3.0)
    for k, m in enumerate(ms):
        ax = fig.add_subplot(rows, cols, k + 1)
        i, j = m["surface"]["axes"]
        z = np.array([[np.nan if v is None else v for v in row] for row in m["surface"]["z"]], dtype=float)
        im = ax.imshow(z, origin="lower", aspect="auto", cmap="viridis", interpolation="nearest")
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02).ax.tick_params(labelsize=5)
        for setter, a, n_lev in ((ax.set_yticks, axes[i], z.shape[0]), (ax.set_xticks, axes[j], z.shape[1])):
            step = max(1, math.ceil(n_lev / 8))
            setter(range(0, n_lev, step), [_clipped(t) for t in a["levels"][::step]], fontsize=5)
        ax.tick_params(axis="x", labelrotation=45)
        ax.set_ylabel(_clipped(axes[i]["name"], 24), fontsize=6)
        ax.set_xlabel(_clipped(axes[j]["name"], 24), fontsize=6)
        unit = f" [{m['unit']}]" if m["unit"] and m["unit"] != "1" else ""
        ax.set_title(f"{m['name']}{unit}", fontsize=7)
    fig.suptitle(title or f"response surfaces of the {summary['n_runs']} runs (mean over the other axes)", fontsize=9)
    return fig


def sweep_dependence_figure(summary: Mapping[str, Any], title: str = "") -> Figure:
    """Partial dependence: per axis, each measure's mean at each level over its mean over the sweep.

    One panel per axis, one line per measure (relative to its mean over all runs, so that the
    measures share one scale), the levels in the summary's order.
    """
    axes = summary["axes"]
    fig, rows, cols = _panels(len(axes), 3.6, 3.0)
    for a, axis in enumerate(axes):
        ax = fig.add_subplot(rows, cols, a + 1)
        for m in summary["measures"]:
            d = np.array([np.nan if v is None else v for v in m["dependence"][a]], dtype=float)
            mean = float(np.nanmean(d))
            if mean != 0.0 and np.isfinite(mean):
                ax.plot(range(d.size), d / mean, lw=0.8, marker=".", ms=3, label=m["name"])
        n_lev = len(axis["levels"])
        step = max(1, math.ceil(n_lev / 8))
        ax.set_xticks(range(0, n_lev, step), [_clipped(t) for t in axis["levels"][::step]], fontsize=5, rotation=45)
        ax.tick_params(axis="y", labelsize=6)
        ax.set_title(_clipped(axis["name"], 30), fontsize=7)
        ax.set_ylabel("mean / overall mean", fontsize=6)
        ax.grid(True, lw=0.3, alpha=0.5)
    if axes:
        fig.axes[0].legend(fontsize=4, loc="best", ncol=2)
    fig.suptitle(title or "partial dependence of each measure on each axis", fontsize=9)
    return fig


#: The figures of a summarised sweep, by kind.
SWEEP_FIGURES = {"sweep_heatmaps": sweep_heatmaps_figure, "sweep_dependence": sweep_dependence_figure}


def render_sweep_figures(summary_path: str | os.PathLike[str], outs: Mapping[str, str | os.PathLike[str]],
                         title: str = "") -> list[Path]:  # fmt: skip
    """Draw the figures of a sweep's summary (:data:`SWEEP_FIGURES`, by kind) from its JSON alone."""
    import json

    summary = json.loads(Path(summary_path).read_text(encoding="utf-8"))
    draw = {k: functools.partial(f, summary, title) for k, f in SWEEP_FIGURES.items()}
    return [figures.save_figure_of_kind(kind, draw, out) for kind, out in outs.items()]
