"""Figures of localization runs, drawn from their logs alone (:mod:`pose_uncertainty.records.localization`).

Per run (a :class:`~pose_uncertainty.experiments.localization.LocalizationResult` or the log read back):

* :func:`paths_figure` — the world, the true path, dead reckoning and each filter's estimate
  with its final 98.89 % ellipse: from dead reckoning to localization at a glance;
* :func:`errors_figure` — each filter's x, y and θ errors over time inside its own ±3σ band
  (the logged errors and σ's of the first run);
* :func:`nees_figure` — each filter's NEES averaged over the R runs, with the χ² band.

Per set (the logs of its runs, and the wall-clock timings side files):

* :func:`accuracy_time_figure` — RMS position error against compute time per step;
* :func:`success_figure` — global-localization success rate against the particle count,
  with the logged 95 % Wilson intervals.

Every number drawn is a logged one (series, metrics, config; compute times from the runs'
``*.timings.json``); saved by :func:`pose_uncertainty.present.figures.save_figure`, so the
same log gives the same bytes.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.figure import Figure

from ..analysis.localization import FILTERS
from ..core.stats import PR_3SIGMA
from ..experiments.localization import LocalizationResult
from ..methods.covariance import ellipse_polyline
from ..pipeline.chunks import read_timings
from ..records.run import open_run
from . import figures

__all__ = [
    "RUN_FIGURES",
    "SET_FIGURES",
    "accuracy_time_figure",
    "errors_figure",
    "localization_figure_set",
    "nees_figure",
    "paths_figure",
    "render_localization_figures",
    "render_localization_run_figures",
    "render_localization_set_figure",
    "success_figure",
]

#: Per-run figure kinds, and per-set ones (config key ``localization.sets.<set>.plots``).
RUN_FIGURES: tuple[str, ...] = ("paths", "errors", "nees")
SET_FIGURES: tuple[str, ...] = ("accuracy_time", "success")
#: each filter in the colour of the method whose prediction it runs (EKF: A, histogram: B, particles: Monte Carlo)
COLORS: dict[str, str] = {"ekf": figures.METHOD_COLOURS["A"], "histogram": figures.METHOD_COLOURS["B"],
                          "particle": "#000000"}
LABELS: dict[str, str] = {"ekf": "EKF", "histogram": "histogram filter", "particle": "particle filter"}
#: Fixed margins [inch] of the per-run figures (no layout engine at draw): room for the widest tick
#: labels the pipeline's runs draw (NEES: "6 × 10⁻¹"; errors: "−0.050"), the axis labels and the titles;
#: the errors figure's columns are as far apart as its left margin (each has its own y labels)
_PATHS_MARGINS = figures.Margins(left=0.6, bottom=0.5, right=0.15, top=0.3)
_ERRORS_MARGINS = figures.Margins(left=0.85, bottom=0.5, right=0.15, top=0.55, wspace=0.85, hspace=0.35)
_NEES_MARGINS = figures.Margins(left=0.95, bottom=0.5, right=0.1, top=0.3)


def _title(res: LocalizationResult) -> str:
    c = res.config
    return f"{c.name}: {c.scenario['kind']}, R = {c.repeat}"


def paths_figure(res: LocalizationResult) -> Figure:
    """The world with the true path, dead reckoning, every filter's path and final 98.89 % ellipse."""
    title, margins = figures.fit_title(f"{_title(res)} — paths, final 98.89 % ellipses", (7.0, 6.0),
                                       _PATHS_MARGINS, "medium")  # fmt: skip
    fig = figures.new_figure((7.0, 6.0), margins=margins)
    ax = fig.add_subplot()
    w = res.world
    for x1, y1, x2, y2 in w.segments:
        ax.plot([x1, x2], [y1, y2], color="k", lw=2.0, solid_capstyle="butt")
    if w.n_landmarks:
        ax.plot(w.landmarks[:, 0], w.landmarks[:, 1], ls="none", marker="*", ms=8, color="tab:red",
                label=f"landmarks ({w.n_landmarks})")  # fmt: skip
    ax.plot(res.odometry[:, 0], res.odometry[:, 1], color="0.55", lw=1.0, ls="--", label="dead reckoning")
    truth = res.true_poses[:, :2]
    ks = res.config.scenario.get("kidnap_step")
    if ks:  # the robot is carried away between two steps: no line between them
        truth = np.concatenate([truth[:ks], np.full((1, 2), np.nan), truth[ks:]])
    ax.plot(truth[:, 0], truth[:, 1], color="k", lw=1.4, label="true path" + (" (kidnapped)" if ks else ""))
    for name, tr in res.filters.items():
        ax.plot(tr.mean[:, 0], tr.mean[:, 1], color=COLORS[name], lw=0.9, label=LABELS[name])
        pts = ellipse_polyline(tr.cov[-1, :2, :2], PR_3SIGMA, tr.mean[-1, :2], 100)
        ax.plot(pts[:, 0], pts[:, 1], color=COLORS[name], lw=1.2)
    ax.plot(*res.true_poses[0, :2], marker="o", color="k", ms=4, ls="none")
    ax.plot(*res.true_poses[-1, :2], marker="+", color="k", ms=10, ls="none")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize="medium")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(loc="best", fontsize="x-small")
    return fig


def errors_figure(res: LocalizationResult) -> Figure:
    """Rows x, y, θ; one column per filter: the error (estimate − truth) inside ±3σ of the filter's covariance."""
    names = list(res.filters)
    size = (3.6 * max(len(names), 1) + 0.6, 6.4)
    title, margins = figures.fit_title(f"{_title(res)} — errors of the first run with ±3σ of each filter", size,
                                       _ERRORS_MARGINS, "medium", span=(0.0, size[0]))  # fmt: skip
    fig = figures.new_figure(size, margins=margins, grid=(3, max(len(names), 1)))
    t = res.times
    rows = (("x", "m"), ("y", "m"), ("theta", "rad"))
    for j, name in enumerate(names):
        s = res.filters[name].series
        for i, (var, unit) in enumerate(rows):
            ax = fig.add_subplot(3, len(names), i * len(names) + j + 1)
            band = 3.0 * s[f"sigma_{var}"]
            ax.fill_between(t, -band, band, color=COLORS[name], alpha=0.2, lw=0, label="±3σ")
            ax.plot(t, s[f"error_{var}"], color=COLORS[name], lw=0.8, label="error")
            ax.axhline(0.0, color="k", lw=0.4)
            inside = float(np.mean(np.abs(s[f"error_{var}"]) <= band))
            ax.set_ylabel(f"{'θ' if var == 'theta' else var} error [{unit}]", fontsize="small")
            ax.text(0.98, 0.04, f"inside ±3σ: {100 * inside:.1f} %", transform=ax.transAxes, ha="right",
                    fontsize="x-small")  # fmt: skip
            if i == 0:
                ax.set_title(LABELS[name], fontsize="medium")
            if i == 2:
                ax.set_xlabel("t [s]")
            lim = float(np.nanmax(np.abs(s[f"error_{var}"]))) if s[f"error_{var}"].size else 1.0
            ax.set_ylim(-1.5 * lim - 1e-9, 1.5 * lim + 1e-9)
            ax.grid(True, lw=0.3, alpha=0.5)
            if i == 0 and j == 0:
                ax.legend(fontsize="x-small", loc="upper left")
    fig.suptitle(title, fontsize="medium")
    return fig


def nees_figure(res: LocalizationResult) -> Figure:
    """NEES averaged over the R runs per step and filter, with the 95 % χ² band of R runs (log scale)."""
    title, margins = figures.fit_title(f"{_title(res)} — consistency", (7.0, 4.4), _NEES_MARGINS, "medium")
    fig = figures.new_figure((7.0, 4.4), margins=margins)
    ax = fig.add_subplot()
    m = res.metrics
    lo, hi = m["loc_nees_band_low"], m["loc_nees_band_high"]
    t = res.times
    ax.fill_between(t, lo, hi, color="0.85", lw=0, label=f"95 % band, χ²(3R)/R, R = {res.config.repeat}")
    ax.axhline(3.0, color="k", lw=0.6, ls=":", label="3 (consistent)")
    for name, tr in res.filters.items():
        v = tr.series["nees_avg"]
        inside = m.get(f"loc_{name}_nees_in_band", math.nan)
        ax.plot(t, np.where(v > 0, v, np.nan), color=COLORS[name], lw=0.9,
                label=f"{LABELS[name]} (in band {100 * inside:.1f} % of steps)")  # fmt: skip
    ax.set_yscale("log")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("NEES averaged over the runs")
    ax.set_title(title, fontsize="medium")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize="x-small", loc="upper right")
    return fig


def localization_figure_set(res: LocalizationResult) -> dict[str, Figure]:
    """Every per-run figure, by kind (:data:`RUN_FIGURES`)."""
    return {"paths": paths_figure(res), "errors": errors_figure(res), "nees": nees_figure(res)}


def render_localization_figures(res: LocalizationResult, outdir: str | os.PathLike[str],
                                formats: Iterable[str] = ("png", "svg")) -> list[Path]:  # fmt: skip
    """Render every per-run figure into ``outdir`` as ``<kind>.<format>``; return the paths."""
    fmts = list(formats)
    for fmt in fmts:
        if fmt not in figures.FORMATS:
            raise ValueError(f"figure format must be one of {figures.FORMATS}, got {fmt!r}")
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    with mpl.rc_context(figures._RC):  # type: ignore[arg-type]
        return [figures.save_figure(fig, out / f"{kind}.{fmt}")
                for kind, fig in localization_figure_set(res).items() for fmt in fmts]  # fmt: skip


def render_localization_run_figures(log: str | os.PathLike[str], kinds: Sequence[str],
                                    outs: Sequence[str | os.PathLike[str]]) -> list[Path]:  # fmt: skip
    """Draw per-run figures (kinds of :data:`RUN_FIGURES`) of one localization log, read once."""
    if len(kinds) != len(outs):
        raise ValueError(f"kinds and outs must have equal length, got {len(kinds)} and {len(outs)}")
    res = open_run(log)
    if not isinstance(res, LocalizationResult):
        raise ValueError(f"{log}: not a localization log (format {res.metadata.get('format')!r})")  # noqa: TRY004
    draw = {"paths": paths_figure, "errors": errors_figure, "nees": nees_figure}
    paths = []
    for kind, out in zip(kinds, outs, strict=True):
        if kind not in draw:
            raise ValueError(f"figure kind must be one of {RUN_FIGURES}, got {kind!r}")
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        paths.append(figures.save_figure(draw[kind](res), out))
    return paths


# ----------------------------------------------------------------------------- set figures


def _read(logs: Sequence[str | os.PathLike[str]]) -> list[Any]:
    return [open_run(p) for p in logs]


def accuracy_time_figure(logs: Sequence[str | os.PathLike[str]], timings: Sequence[str | os.PathLike[str]],
                         title: str = "") -> Figure:  # fmt: skip
    """RMS position error against compute time per step, one point per run and filter (log-log).

    The error is the logged ``loc_<f>_rms_position_error``; the time the run's
    ``<f>_step_s`` from its timings side file or its chunk's (wall clock: not reproducible).
    """
    fig = figures.new_figure((6.6, 5.0), dpi=figures.WIDE_DPI)
    ax = fig.add_subplot()
    seen: set[str] = set()
    runs = _read(logs)
    for log, tpath in zip(runs, timings, strict=True):
        tim = read_timings(tpath, log.path)
        if tim is None:
            raise FileNotFoundError(f"no timings file {os.fspath(tpath)!r} for the run {log.config.name!r}")
        for name in log.filters:
            err = log.metrics.get(f"loc_{name}_rms_position_error", math.nan)
            sec = tim.get(f"{name}_step_s", math.nan)
            ax.plot([1e3 * sec], [err], ls="none", marker="o", ms=7, color=COLORS[name],
                    label=None if name in seen else LABELS[name])  # fmt: skip
            ax.annotate(log.config.name, (1e3 * sec, err), fontsize=9, color="0.25", xytext=(4, 2),
                        textcoords="offset points")  # fmt: skip
            seen.add(name)
    dr = [lg.metrics.get("loc_dead_reckoning_rms_position_error", math.nan) for lg in runs]
    if dr and np.isfinite(dr).any():  # named, not drawn: far above the filters, it would flatten them
        ax.plot([], [], ls="none", label=f"dead reckoning: {float(np.nanmedian(dr)):.3g} m (median over the runs)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    _fit_log_limits(ax)
    ax.set_xlabel("compute time per step [ms] (wall clock)")
    ax.set_ylabel("RMS position error [m]")
    ax.set_title(title or "accuracy against compute time", fontsize="medium")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize="small", loc="best")
    return fig


def _fit_log_limits(ax: Any, pad: float = 1.6) -> None:
    """Log axes that show every finite positive point of the axes' lines, with a factor ``pad`` of room on
    each side (so a point and its label are never on or beyond the frame)."""
    xy = np.array([(float(x), float(y)) for line in ax.lines
                   for x, y in zip(np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float), strict=True)],
                  dtype=float).reshape(-1, 2)  # fmt: skip
    xy = xy[np.isfinite(xy).all(axis=1) & (xy > 0).all(axis=1)]
    if xy.size:
        ax.set_xlim(xy[:, 0].min() / pad, xy[:, 0].max() * pad * 1.5)  # labels extend to the right
        ax.set_ylim(xy[:, 1].min() / pad, xy[:, 1].max() * pad)


def success_figure(logs: Sequence[str | os.PathLike[str]], title: str = "") -> Figure:
    """Success rate against the particle count (``filters.particle.n_particles``), with 95 % Wilson intervals.

    Filters without particles are drawn at the same abscissae (their success does not depend on it).
    """
    runs = sorted(_read(logs), key=lambda lg: lg.config.filters.get("particle", {}).get("n_particles", 0))
    fig = figures.new_figure((6.6, 4.6), dpi=figures.WIDE_DPI)
    ax = fig.add_subplot()
    n = np.array([lg.config.filters.get("particle", {}).get("n_particles", 0) for lg in runs], dtype=float)
    for k, name in enumerate(FILTERS):
        have = [lg for lg in runs if name in lg.filters]
        if not have:
            continue
        x = np.array([lg.config.filters.get("particle", {}).get("n_particles", 0) for lg in have], dtype=float)
        x = x * (1.0 + 0.03 * (k - 1))  # side by side
        rate = np.array([lg.metrics[f"loc_{name}_success_rate"] for lg in have])
        lo = np.array([lg.metrics[f"loc_{name}_success_low"] for lg in have])
        hi = np.array([lg.metrics[f"loc_{name}_success_high"] for lg in have])
        yerr = np.maximum(0.0, [rate - lo, hi - rate])
        ax.errorbar(x, rate, yerr=yerr, color=COLORS[name], marker="o", ms=4, lw=1.0, capsize=3,
                    label=f"{LABELS[name]} ({have[0].config.repeat} runs each)")  # fmt: skip
    if n.size and n.max() > 0:
        ax.set_xscale("log")
    ax.set_ylim(-0.05, 1.05)
    ax.set_xlabel("particles of the particle filter")
    ax.set_ylabel("success rate (final error within tolerance)")
    ax.set_title(title or "global localization: success against particle count", fontsize="medium")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize="x-small", loc="lower right")
    return fig


def render_localization_set_figure(kind: str, logs: Sequence[str | os.PathLike[str]],
                                   timings: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str],
                                   title: str = "") -> Path:  # fmt: skip
    """Draw a set figure (``accuracy_time`` or ``success``) and save it."""
    builders = {"accuracy_time": functools.partial(accuracy_time_figure, logs, timings, title),
                "success": functools.partial(success_figure, logs, title)}  # fmt: skip
    return figures.save_figure_of_kind(kind, builders, out)
