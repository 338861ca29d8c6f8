"""The calibration's figures (matplotlib, Agg): path, residual growth, horizon; PNG bytes."""

from __future__ import annotations

import io
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import NDArray
from PIL import Image

__all__ = ["DPI", "growth_figure", "horizon_figure", "path_figure"]


#: Resolution of the figures [dots per inch]; a page showing them at half their pixels (a report for
#: high-density screens) asks for twice this.
DPI = 110
#: Colours of a figure's palette, as the pipeline's figures have (``present.figures.PNG_COLOURS``): line
#: figures on white need no more, and a palette PNG is about half the bytes of a true-colour one (the
#: comparison report inlines these figures: its first paint waits for every byte of it)
PNG_COLOURS = 64


def _png(fig: Any, dpi: int = DPI) -> bytes:
    """The figure as a PNG with an adaptive palette of :data:`PNG_COLOURS` (median cut, no dithering: deterministic)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    with Image.open(buf) as image:
        palette = image.convert("RGB").quantize(colors=PNG_COLOURS, method=Image.Quantize.MEDIANCUT,
                                                dither=Image.Dither.NONE)  # fmt: skip
    out = io.BytesIO()
    palette.save(out, format="PNG", compress_level=6)
    return out.getvalue()


def path_figure(paths: dict[str, NDArray[np.float64]], dpi: int = DPI) -> bytes:
    """The drive: each named path (n, 3) in (x, y) [m]."""
    fig, ax = plt.subplots(figsize=(6.0, 5.0), layout="constrained")
    for name, p in paths.items():
        ax.plot(p[:, 0], p[:, 1], lw=1.0, label=name)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Recorded drive: ground truth, robot odometry, calibrated odometry", fontsize=9)
    ax.legend(fontsize=8)
    return _png(fig, dpi)


def growth_figure(travel: NDArray, r: NDArray, Sigma: NDArray, dpi: int = DPI) -> bytes:
    """Squared residuals of the segments against Method A's variances, by segment travel."""
    fig, axes = plt.subplots(1, 3, figsize=(10.0, 3.4), layout="constrained")
    labels = ("x [m²]", "y [m²]", "θ [rad²]")
    for i, ax in enumerate(axes):
        ax.scatter(travel, r[:, i] ** 2, s=8, alpha=0.6, label="residual²")
        order = np.argsort(travel)
        ax.plot(travel[order], Sigma[order, i, i], "k.", ms=3, label="model variance")
        ax.set_yscale("log")
        ax.set_xlabel("segment travel [m]")
        ax.set_ylabel(labels[i])
    axes[0].legend(fontsize=7)
    fig.suptitle("Segment residuals against the calibrated model (Method A + ground-truth noise)", fontsize=9)
    return _png(fig, dpi)


def horizon_figure(h: dict[str, Any], dpi: int = DPI) -> bytes:
    """95 % position error radius against distance, straight and turning, with the thresholds."""
    fig, ax = plt.subplots(figsize=(6.0, 4.0), layout="constrained")
    for kind in ("straight", "turning"):
        c = h[kind]["curve"]
        ax.plot(c["distance"], c["r95"], label=kind)
        pts = [t for t in h[kind]["thresholds"] if t["mc_r95"] is not None]
        ax.plot([t["distance"] for t in pts], [t["mc_r95"] for t in pts], "o", mfc="none", label=f"{kind}: Monte Carlo")
    for t in h["straight"]["thresholds"]:
        ax.axhline(t["radius"], color="grey", lw=0.6, ls=":")
    ax.set_xlabel("distance [m]")
    ax.set_ylabel("95 % position error radius [m]")
    ax.set_title("Uncertainty horizon (Method A with the calibrated constants)", fontsize=9)
    ax.legend(fontsize=8)
    return _png(fig, dpi)
