"""Figures of a run, drawn from a :class:`~pose_uncertainty.experiments.run.RunResult` alone.

These are the functions the pipeline calls and ``pose-uncertainty replay
--figures`` calls on a run read back from its log; since the log is lossless,
both give the same bytes.

* :func:`trajectory_figure` — the nominal path in black, Pr-ellipses at regular
  intervals in blue and the final one in red (98.89 % by default, as in Němec 2012 ch. 3),
  with Method C's final ellipse (green, about its own mean) beside it;
* :func:`cloud_figure` — the Monte Carlo end poses over the final ellipses (A's, C's);
* :func:`map_figure` — a probability map (θ marginalised), 1 m × 1 m around the
  noiseless end point, darker = more probable (as in Němec 2012 ch. 4).

Figures are built on :class:`matplotlib.figure.Figure` with the Agg canvas (no
pyplot, no global backend switch) and saved by :func:`save_figure` with fixed
metadata and SVG hash salt, so PNG and SVG bytes are deterministic.
"""

from __future__ import annotations

import functools
import io
import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text
from PIL import Image, PngImagePlugin

from .. import __version__
from ..core.atomic import atomic_write_bytes
from ..core.figure_style import CRISP_RC
from ..experiments.run import RunResult
from ..methods import covariance
from ..methods.maps import ProbabilityMap

__all__ = [
    "CRISP_RC",
    "FORMATS",
    "HIDPI",
    "METHOD_COLOURS",
    "Margins",
    "cloud_figure",
    "figure_set",
    "fit_title",
    "map_figure",
    "map_window",
    "new_figure",
    "render_figures",
    "save_figure",
    "save_figure_of_kind",
    "trajectory_figure",
    "wrap_title",
]

FORMATS: tuple[str, ...] = ("png", "svg", "pdf")
#: Per-run figures at 72 dpi: a 6-inch figure is 432 px wide, the width the report shows it at (430 px);
#: the report embeds several hundred of them (its size budget is 10 MB)
_DPI = 72
#: Set and study figures, which the report shows up to 900 px wide, at 90 dpi (a 6-inch figure is 540 px)
WIDE_DPI = 90
#: A PNG holds HIDPI × its figure's dpi pixels per inch and is shown at its dpi in CSS pixels (the
#: report's ``<img>`` width and height): sharp on a 2× (HiDPI) screen and in print
HIDPI = 2
#: Colours of a saved PNG's palette (:func:`_palette_png`): 64 keep the colour maps' steps below
#: what the eye separates and make the files 20 % smaller than 256 (the report's size budget)
PNG_COLOURS = 64
_CREATOR = f"pose-uncertainty {__version__}"
_RC: dict[str, Any] = {
    "svg.hashsalt": "pose-uncertainty",
    "svg.fonttype": "path",
    "pdf.fonttype": 42,
    "path.simplify": False,
}
#: One colour per method in every figure and in the report's text (Okabe–Ito: told apart with any
#: colour vision): Method A vermillion, Method B bluish green, Method C reddish purple, the
#: exponential-coordinates Gaussian blue, Monte Carlo grey; sky blue for what a sample itself gives
METHOD_COLOURS: dict[str, str] = {"A": "#D55E00", "B": "#009E73", "C": "#CC79A7", "expcoords": "#0072B2",
                                  "MC": "#555555", "sample": "#56B4E9"}  # fmt: skip
_BLUE, _RED, _BLACK = METHOD_COLOURS["sample"], METHOD_COLOURS["A"], "black"
_MAP_WINDOW = 1.0  # [m], side of the map window (the thesis's 1 m × 1 m)


@dataclass(frozen=True)
class Margins:
    """Fixed geometry of a figure's grid of axes, in inches (a cheap replacement of constrained layout).

    Constrained layout measures every tick label at every draw (2 passes), 10-20 % of a per-run
    figure's time; the per-run figures have a known set of texts, so their margins are fixed
    instead, wide enough for the widest tick labels the pipeline's runs draw.

    Attributes
    ----------
    left, bottom, right, top : float [inch] — from the figure's edges to the grid of axes
    wspace, hspace : float [inch] — between columns and between rows of the grid
    """

    left: float
    bottom: float
    right: float
    top: float
    wspace: float = 0.0
    hspace: float = 0.0


def new_figure(
    size: tuple[float, float] = (6.0, 6.0),
    dpi: int = _DPI,
    margins: Margins | None = None,
    grid: tuple[int, int] = (1, 1),
) -> Figure:
    """An empty figure on the Agg canvas, saved at its own dpi: fixed margins, or constrained layout.

    Parameters
    ----------
    size : (width, height) [inch]
    dpi : dots per inch — 72 (per-run figures, the default) or :data:`WIDE_DPI` (set and study figures)
    margins : Margins or None — fixed subplot geometry for ``fig.add_subplot(nrows, ncols, k)``;
        None: constrained layout (sized at every draw)
    grid : (nrows, ncols) — the grid ``margins.wspace`` / ``margins.hspace`` separate
    """
    if margins is None:
        fig = Figure(figsize=size, dpi=dpi, layout="constrained")
    else:
        fig = Figure(figsize=size, dpi=dpi, layout=None)
        fig.subplots_adjust(**_subplot_params(size, margins, grid))
    FigureCanvasAgg(fig)
    return fig


def _subplot_params(size: tuple[float, float], m: Margins, grid: tuple[int, int]) -> dict[str, float]:
    """``Figure.subplots_adjust`` arguments (fractions of the figure; gaps as fractions of an axes) of ``m``."""
    (width, height), (nrows, ncols) = size, grid
    ax_w = (width - m.left - m.right - (ncols - 1) * m.wspace) / ncols  # [inch]
    ax_h = (height - m.bottom - m.top - (nrows - 1) * m.hspace) / nrows  # [inch]
    if ax_w <= 0 or ax_h <= 0:
        raise ValueError(f"margins {m} leave no room for a {nrows}x{ncols} grid in a {width}x{height} in figure")
    return {"left": m.left / width, "right": 1.0 - m.right / width, "bottom": m.bottom / height,
            "top": 1.0 - m.top / height, "wspace": m.wspace / ax_w, "hspace": m.hspace / ax_h}  # fmt: skip


_new_figure = new_figure  # kept for callers of the earlier private name

_TITLE_PAD = 0.05  # [inch] kept free between a title's ends and the figure's edges
#: A line preferably ends after one of these or before a dash, else after a colon (not between "inside:"
#: and its value when a comma or semicolon break fits)
_BREAK_AFTER, _BREAK_AFTER_COLON = (",", ";"), (",", ";", ":")


def wrap_title(
    text: str,
    fig_width: float,
    span: tuple[float, float] | None = None,
    fontsize: float | str = "large",
    dpi: int = _DPI,
) -> tuple[str, float]:
    """``text`` broken into lines that fit the figure's width when centred on ``span``, and their extra height.

    A line ends at the last punctuation break (after ``,`` or ``;``, before ``—``; else after ``:``) that
    fits and fills at least half the width, else at the last space that fits; a single word wider than the
    width stays whole. Explicit line breaks are kept. Widths and heights are measured with a
    :class:`~matplotlib.text.Text` of the given size on the Agg canvas at ``dpi``, as the title is drawn.

    Parameters
    ----------
    text : str — the title (may contain ``\\n``)
    fig_width : float [inch] — the figure's width
    span : (x0, x1) [inch] or None — the axes the title is centred over, from the figure's left edge;
        None: the whole width (a suptitle)
    fontsize : float [pt] or str — the title's font size (matplotlib's ``axes.titlesize`` is "large")
    dpi : int — the figure's dots per inch

    Returns
    -------
    wrapped : str
    extra : float [inch] — the wrapped title's height minus one line's: what a top margin sized for a
        one-line title needs in addition
    """
    x0, x1 = (0.0, fig_width) if span is None else span
    centre = (x0 + x1) / 2.0
    width = 2.0 * min(centre, fig_width - centre) - 2.0 * _TITLE_PAD  # [inch]
    lines: list[str] = []
    for line in text.split("\n"):
        lines.extend(_wrap_line(line, width, fontsize, dpi))
    wrapped = "\n".join(lines)
    extra = _text_size(wrapped, fontsize, dpi)[1] - _text_size(lines[0], fontsize, dpi)[1]
    return wrapped, extra


def _wrap_line(line: str, width: float, fontsize: float | str, dpi: int) -> list[str]:
    """One line of a title broken greedily into lines no wider than ``width`` [inch] (see :func:`wrap_title`)."""
    words = line.split(" ")
    out: list[str] = []
    while words:
        fits = [k for k in range(1, len(words) + 1)
                if k == 1 or _text_size(" ".join(words[:k]), fontsize, dpi)[0] <= width]  # fmt: skip
        k = fits[-1]
        if k < len(words):  # prefer a punctuation break that fills half the line
            half = [j for j in fits if _text_size(" ".join(words[:j]), fontsize, dpi)[0] >= width / 2.0]
            for marks in (_BREAK_AFTER, _BREAK_AFTER_COLON):
                nice = [j for j in half if words[j - 1].endswith(marks) or words[j] == "—"]
                if nice:
                    k = nice[-1]
                    break
        out.append(" ".join(words[:k]))
        words = words[k:]
    return out


def fit_title(
    title: str,
    size: tuple[float, float],
    margins: Margins,
    fontsize: float | str = "large",
    span: tuple[float, float] | None = None,
) -> tuple[str, Margins]:
    """A title wrapped to the figure's width (:func:`wrap_title`) and ``margins`` with room for its lines.

    Parameters
    ----------
    title : str
    size : (width, height) [inch] — the figure's size
    margins : Margins — with a top margin for a one-line title
    fontsize : float [pt] or str
    span : (x0, x1) [inch] or None — the axes the title is centred over; None: the grid ``margins`` leave

    Returns
    -------
    wrapped : str
    margins : Margins — ``margins`` with the top margin grown by the lines beyond the first
    """
    span = (margins.left, size[0] - margins.right) if span is None else span
    wrapped, extra = wrap_title(title, size[0], span, fontsize)
    return wrapped, replace(margins, top=margins.top + extra)


@functools.lru_cache(maxsize=4096)
def _text_size(s: str, fontsize: float | str, dpi: int) -> tuple[float, float]:
    """(width, height) [inch] of the text ``s`` (lines separated by ``\\n``) as drawn at ``dpi``."""
    probe = _probe(fontsize, dpi)
    probe.set_text(s)
    box = probe.get_window_extent()
    return float(box.width) / dpi, float(box.height) / dpi


@functools.lru_cache(maxsize=8)
def _probe(fontsize: float | str, dpi: int) -> Text:
    """A text of the given size on a figure drawn on the Agg canvas at ``dpi``, for measuring."""
    fig = Figure(dpi=dpi)
    FigureCanvasAgg(fig)
    text: Text = fig.text(0.0, 0.0, "", fontsize=fontsize)
    return text

#: Margins [inch] of the trajectory and cloud figures (6 × 6 in): left for y tick labels up to
#: "−0.010" and the y label, right for the last x tick label's overhang, top for a one-line title
#: (:func:`fit_title` adds the height of the further lines of a long title)
_PLANE_MARGINS = Margins(left=0.85, bottom=0.5, right=0.15, top=0.3)
#: The map figure (6.4 × 5.6 in): square axes, then a gap, the colour bar and its tick labels and label
_MAP_MARGINS = Margins(left=0.75, bottom=0.55, right=0.2 + 0.2 + 0.9, top=0.35)
_CBAR_GAP, _CBAR_WIDTH = 0.2, 0.2  # [inch]


def _pct(pr: float) -> str:
    return f"{100.0 * pr:.2f} %"


def _polyline(cov_xy: np.ndarray, center: np.ndarray, pr: float) -> np.ndarray:
    return covariance.ellipse_polyline(cov_xy, pr, center, 200)


def trajectory_figure(run: RunResult) -> Figure:
    """Nominal path (black), Pr-ellipses at regular intervals (blue), final ellipse (red).

    Parameters
    ----------
    run : RunResult (or a RunLog read back from a file)
    """
    cfg = run.config
    if cfg.drive is None:
        title = f"{cfg.name}: {cfg.trajectory['name']}, Pr = {_pct(cfg.pr)}, k_r = {cfg.k_r:g} m, k_l = {cfg.k_l:g} m"
        fontsize = "large"
    else:  # name the drive (its geometry in a second line), in 10 pt
        title = (f"{cfg.name}: {cfg.drive.type} drive on {cfg.trajectory['name']}, Pr = {_pct(cfg.pr)}\n"
                 f"{cfg.drive.describe()}")  # fmt: skip
        fontsize = "medium"
    title, margins = fit_title(title, (6.0, 6.0), _PLANE_MARGINS, fontsize)
    fig = _new_figure(margins=margins)
    ax = fig.add_subplot()
    ax.plot(run.poses[:, 0], run.poses[:, 1], color=_BLACK, lw=1.2, label="nominal path")
    steps = run.ellipse_steps()
    for j, i in enumerate(steps[:-1]):
        pts = _polyline(run.covs[i, :2, :2], run.poses[i, :2], cfg.pr)
        ax.plot(
            pts[:, 0],
            pts[:, 1],
            color=_RED,
            lw=0.7,
            alpha=0.55,
            label="ellipses along the path" if j == 0 else None,
        )
    n = run.n_steps
    pts = _polyline(run.covs[n, :2, :2], run.poses[n, :2], cfg.pr)
    ax.plot(
        pts[:, 0], pts[:, 1], color=_RED, lw=1.4, label=f"Method A: final ellipse (t = {run.times[n]:.3g} s)"
    )
    _method_c_ellipse(ax, run)
    ax.plot(*run.poses[0, :2], marker="o", color=_BLACK, ms=4, ls="none")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=fontsize)
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(loc="best", fontsize="small")
    return fig


def cloud_figure(run: RunResult) -> Figure | None:
    """Monte Carlo end poses over the final Pr-ellipse; None without Monte Carlo.

    Parameters
    ----------
    run : RunResult
    """
    if run.end_poses is None or run.end_poses.shape[0] == 0:
        return None
    cfg = run.config
    n = run.n_steps
    end, cov = run.poses[n], run.covs[n]
    cloud = run.end_poses
    cov_note = ""
    if "MC_coverage_pr" in run.metrics:
        cov_note = f"; inside: {100.0 * run.metrics['MC_coverage_pr']:.2f} %"
    drive = "" if cfg.drive is None else f" ({cfg.drive.type} drive)"
    title, margins = fit_title(f"{cfg.name}{drive}: end poses, {cfg.monte_carlo.regime}{cov_note}", (6.0, 6.0),
                               _PLANE_MARGINS)  # fmt: skip
    fig = _new_figure(margins=margins)
    ax = fig.add_subplot()
    ax.scatter(
        cloud[:, 0],
        cloud[:, 1],
        s=1.0,
        color="0.35",
        alpha=0.35,
        linewidths=0,
        rasterized=True,
        label=f"Monte Carlo end poses (n = {cloud.shape[0]})",
    )
    pts = _polyline(cov[:2, :2], end[:2], cfg.pr)
    ax.plot(
        pts[:, 0], pts[:, 1], color=_RED, lw=1.4, label=f"Method A (covariance) ellipse, Pr = {_pct(cfg.pr)}"
    )
    m = run.metrics
    if all(k in m for k in ("MC_mean_x", "MC_mean_y", "MC_cov_xx", "MC_cov_xy", "MC_cov_yy")):
        # the logged sample mean and covariance of the cloud
        mc_cov = np.array([[m["MC_cov_xx"], m["MC_cov_xy"]], [m["MC_cov_xy"], m["MC_cov_yy"]]])
        mpts = _polyline(mc_cov, np.array([m["MC_mean_x"], m["MC_mean_y"]]), cfg.pr)
        ax.plot(
            mpts[:, 0],
            mpts[:, 1],
            color=_BLUE,
            lw=1.0,
            ls="--",
            label="ellipse of the sample covariance",
        )
    _method_c_ellipse(ax, run)
    ax.plot(*end[:2], marker="+", color=_RED, ms=10, ls="none", label="noiseless end pose")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title)
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(loc="best", fontsize="small")
    return fig


# --- Method C, the unscented transform ---------------------------------------------------------

_GREEN = METHOD_COLOURS["C"]
_C_KEYS = ("C_mean_x", "C_mean_y", "C_cov_xx", "C_cov_xy", "C_cov_yy")


def _method_c_ellipse(ax: Any, run: RunResult) -> None:
    """Method C's final Pr-ellipse about its own mean, and that mean, from the logged ``C_*`` measures.

    Nothing is drawn for a run that has not logged them (a log written before Method C).
    """
    m = run.metrics
    if not all(k in m for k in _C_KEYS):
        return
    cov = np.array([[m["C_cov_xx"], m["C_cov_xy"]], [m["C_cov_xy"], m["C_cov_yy"]]])
    mean = np.array([m["C_mean_x"], m["C_mean_y"]])
    pts = _polyline(cov, mean, run.config.pr)
    ax.plot(pts[:, 0], pts[:, 1], color=_GREEN, lw=1.2, ls="-.",
            label=f"Method C (sigma points) ellipse, Pr = {_pct(run.config.pr)}")  # fmt: skip
    ax.plot(*mean, marker="x", color=_GREEN, ms=8, ls="none", label="Method C's mean")


# --- end Method C ---


def map_window(mp: ProbabilityMap, center: tuple[float, float], hold: float = 0.99) -> float:
    """Side [m] of the square map window around ``center``: 1 m (the thesis), or larger.

    The smallest square centred on ``center`` holding ``hold`` of the grid's
    mass, rounded up to 0.5 m, when that exceeds 1 m (multi-step maps spread further).
    """
    marg = mp.marginal_xy()
    total = float(marg.sum())
    if total <= 0:
        return _MAP_WINDOW
    dist = np.maximum(np.abs(mp.x - center[0])[:, None], np.abs(mp.y - center[1])[None, :])
    order = np.argsort(dist, axis=None, kind="stable")
    cum = np.cumsum(marg.ravel()[order])
    k = int(np.searchsorted(cum, hold * total))
    half = float(dist.ravel()[order][min(k, order.size - 1)]) + mp.resolution / 2.0
    return max(_MAP_WINDOW, 0.5 * np.ceil(2.0 * half / 0.5))


def map_figure(run: RunResult, mp: ProbabilityMap) -> Figure:
    """Probability map (θ marginalised) around the noiseless end pose, darker = more probable.

    The window is 1 m × 1 m as in the thesis (larger when the map spreads
    further, see :func:`map_window`), centred on the map's noiseless
    (exact-arc) end pose ``mp.center``.

    Parameters
    ----------
    run : RunResult — gives the run's name
    mp : ProbabilityMap — one of ``run.maps``
    """
    marg = mp.marginal_xy()  # (nx, ny) mass per cell [1]
    dx = dy = mp.resolution
    extent = (mp.x[0] - dx / 2, mp.x[-1] + dx / 2, mp.y[0] - dy / 2, mp.y[-1] + dy / 2)
    if np.all(np.isfinite(mp.center)):
        mid = (float(mp.center[0]), float(mp.center[1]))
    else:
        mid = ((mp.x[0] + mp.x[-1]) / 2.0, (mp.y[0] + mp.y[-1]) / 2.0)
    side = map_window(mp, mid)
    m = _MAP_MARGINS
    title, margins = fit_title(f"{run.config.name}: map {mp.name!r} ({mp.model} model), lost mass {mp.lost_mass:.2g}",
                               (6.4, 5.6), m, span=(m.left, m.left + _map_side((6.4, 5.6), m)))  # fmt: skip
    fig = _new_figure((6.4, 5.6), margins=margins)
    ax, cax = _map_axes(fig, margins)
    img = ax.imshow(
        marg.T,
        origin="lower",
        extent=extent,
        cmap="Greys",
        vmin=0.0,
        vmax=float(marg.max()) if marg.max() > 0 else 1.0,
        interpolation="nearest",
    )
    ax.plot(*mid, marker="+", color=_RED, ms=10, ls="none", label="noiseless end point (exact arc)")
    ax.set_xlim(mid[0] - side / 2, mid[0] + side / 2)
    ax.set_ylim(mid[1] - side / 2, mid[1] + side / 2)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize="small")
    cm = f"{100 * dx:.3g} cm"
    fig.colorbar(img, cax=cax, label=f"probability per {cm} × {cm} cell (θ summed)")
    return fig


def _map_side(size: tuple[float, float], m: Margins) -> float:
    """Side [inch] of the map figure's square axes: the largest square the margins ``m`` leave."""
    return min(size[0] - m.left - m.right, size[1] - m.bottom - m.top)


def _map_axes(fig: Figure, m: Margins) -> tuple[Any, Any]:
    """The map figure's square axes (centred in the height the margins ``m`` leave) and colour-bar axes."""
    width, height = fig.get_size_inches()
    free_h = height - m.bottom - m.top
    side = _map_side((width, height), m)  # [inch]
    y0 = m.bottom + (free_h - side) / 2.0
    ax = fig.add_axes((m.left / width, y0 / height, side / width, side / height))
    x_bar = m.left + side + _CBAR_GAP
    cax = fig.add_axes((x_bar / width, y0 / height, _CBAR_WIDTH / width, side / height))
    return ax, cax


def figure_set(run: RunResult) -> dict[str, Figure]:
    """Every figure of a run, by file stem: ``trajectory``, ``cloud``, ``map_<name>``."""
    figs: dict[str, Figure] = {"trajectory": trajectory_figure(run)}
    cloud = cloud_figure(run)
    if cloud is not None:
        figs["cloud"] = cloud
    for mp in run.maps:
        figs[f"map_{mp.name}"] = map_figure(run, mp)
    return figs


def save_figure(fig: Figure, path: str | os.PathLike[str]) -> Path:
    """Save with deterministic bytes: fixed metadata (no dates), fixed SVG ids, the figure's own dpi.

    The format is taken from the suffix (png, svg or pdf).
    """
    p = Path(path)
    fmt = p.suffix.lstrip(".").lower()
    if fmt not in FORMATS:
        raise ValueError(f"figure format must be one of {FORMATS}, got {fmt!r} ({p})")
    by_format: dict[str, dict[str, str | None]] = {
        "png": {"Software": _CREATOR},
        "svg": {"Creator": _CREATOR, "Date": None},
        "pdf": {"Creator": _CREATOR, "Producer": _CREATOR, "CreationDate": None, "ModDate": None},
    }
    metadata = by_format[fmt]
    with mpl.rc_context(_RC):  # type: ignore[arg-type]
        if fmt == "png":  # drawn once on the Agg canvas, encoded once (as a palette PNG)
            data = _palette_png(fig, metadata)
        else:
            buf = io.BytesIO()
            fig.savefig(buf, format=fmt, dpi=fig.dpi, metadata=metadata)
            data = buf.getvalue()
    atomic_write_bytes(p, data)
    return p


def save_figure_of_kind(
    kind: str, builders: Mapping[str, Callable[[], Figure]], out: str | os.PathLike[str]
) -> Path:
    """Draw the figure of ``kind`` with its builder (without anti-aliasing, :data:`CRISP_RC`) and save it to
    ``out`` (its folder created).

    ``builders`` maps each allowed kind to a function drawing that figure; another ``kind``
    is a ValueError naming it and the allowed kinds.
    """
    if kind not in builders:
        raise ValueError(f"set figure kind must be one of {tuple(builders)}, got {kind!r}")
    with mpl.rc_context(CRISP_RC):  # type: ignore[arg-type]  # artists take their anti-aliasing from rcParams when they are made
        fig = builders[kind]()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, out)


def _palette_png(fig: Figure, metadata: dict[str, str | None]) -> bytes:
    """The figure drawn at :data:`HIDPI` × its dpi as a PNG with an adaptive palette of :data:`PNG_COLOURS` (no dithering).

    Deterministic (median cut); about a third of the bytes of the true-colour PNG for
    our figures, so the self-contained report stays small. zlib level 6: level 9 saves 8 %
    of the bytes at 6× the time (the report re-encodes the figures as WebP anyway).
    ``metadata``: the PNG's text chunks (``Software``, as in matplotlib's own PNGs).
    """
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    dpi = fig.dpi
    fig.set_dpi(dpi * HIDPI)  # HiDPI: the same figure, twice the pixels per inch
    try:
        rgba, size = canvas.print_to_buffer()
    finally:
        fig.set_dpi(dpi)
    image = Image.frombuffer("RGBA", size, rgba, "raw", "RGBA", 0, 1)
    info = PngImagePlugin.PngInfo()
    for key, value in metadata.items():
        if value is not None:
            info.add_text(key, value)
    palette = image.convert("RGB").quantize(
        colors=PNG_COLOURS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE
    )
    out = io.BytesIO()
    palette.save(out, format="PNG", compress_level=6, pnginfo=info)
    return out.getvalue()


def render_figures(
    run: RunResult, outdir: str | os.PathLike[str], formats: Iterable[str] = ("png", "svg")
) -> list[Path]:
    """Render every figure of ``run`` into ``outdir`` as ``<stem>.<format>``; return the paths.

    Parameters
    ----------
    run : RunResult or RunLog
    outdir : path-like — created if missing
    formats : iterable of {"png", "svg", "pdf"}
    """
    if run.times.size == 0:
        raise ValueError(
            "the run has no steps (e.g. a partial log recovered nothing): no figures to draw"
        )
    fmts = list(formats)
    for fmt in fmts:
        if fmt not in FORMATS:
            raise ValueError(f"figure format must be one of {FORMATS}, got {fmt!r}")
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    with mpl.rc_context(_RC):  # type: ignore[arg-type]
        for stem, fig in figure_set(run).items():
            for fmt in fmts:
                paths.append(save_figure(fig, out / f"{stem}.{fmt}"))
    return paths
