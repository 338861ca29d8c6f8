"""The one grid type of the package: a regular grid over ``(x, y)``, optionally with headings.

A :class:`Grid` is given by the centre ``(x0, y0)`` of its first cell, its cell
counts ``nx, ny``, its cell sides ``dx, dy`` [m] and, for pose grids, ``ntheta``
heading cells of width ``2π/ntheta`` whose first centre is ``theta0`` (one
heading cell, the default, is a planar grid). Cell ``(i, j)`` holds the points
with ``x0 + (i − ½) dx ≤ x < x0 + (i + ½) dx`` (likewise ``y``).

Probability maps (:mod:`pose_uncertainty.methods.maps`) use square cells
(:meth:`Grid.centered`); the accuracy comparisons bin a Monte Carlo cloud on
:meth:`Grid.covering`. Histograms of samples are :meth:`Grid.histogram_xy`
(planar) and :meth:`Grid.histogram` (poses).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .validation import check_finite, check_last_axis, check_positive, check_positive_int

__all__ = ["Grid"]

Array = NDArray[np.float64]


def _first_heading(theta0: float, ntheta: int) -> float:
    """The centre in ``[−π, −π + h_θ)`` of the heading cell of ``theta0`` (idempotent).

    A remainder within rounding of a whole cell counts as 0, so that normalising
    an already normalised ``theta0`` (e.g. ``−π + h_θ·k`` computed in floating point)
    never moves the heading labels by one cell.
    """
    ht = 2.0 * math.pi / ntheta
    r = math.fmod(math.fmod(theta0 + math.pi, ht) + ht, ht)
    if r > ht * (1.0 - 1e-9):
        r = 0.0
    return -math.pi + r


@dataclass(frozen=True)
class Grid:
    """A regular ``(x, y[, θ])`` grid.

    Attributes
    ----------
    x0, y0 : float [m]
        Centre of the first cell along x and y.
    nx, ny : int
        Number of cells along x and y.
    dx, dy : float [m], > 0
        Cell sides.
    ntheta : int
        Number of heading cells; their width is ``2π/ntheta`` (1: a planar grid).
    theta0 : float [rad]
        Centre of the first heading cell, normalised into ``[−π, −π + 2π/ntheta)``.
    """

    x0: float
    y0: float
    nx: int
    ny: int
    dx: float
    dy: float
    ntheta: int = 1
    theta0: float = -math.pi

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "dx", float(check_positive("dx", self.dx)))
        set_(self, "dy", float(check_positive("dy", self.dy)))
        set_(self, "nx", check_positive_int("nx", self.nx))
        set_(self, "ny", check_positive_int("ny", self.ny))
        set_(self, "ntheta", check_positive_int("ntheta", self.ntheta))
        set_(self, "x0", float(check_finite("x0", self.x0)))
        set_(self, "y0", float(check_finite("y0", self.y0)))
        set_(self, "theta0", _first_heading(float(check_finite("theta0", self.theta0)), self.ntheta))

    # --- construction -----------------------------------------------------------------------

    @classmethod
    def square(
        cls, x0: float, y0: float, nx: int, ny: int, resolution: float, ntheta: int = 1,
        theta0: float = -math.pi,
    ) -> Grid:
        """A grid of square cells of side ``resolution`` [m]."""
        return cls(x0, y0, nx, ny, resolution, resolution, ntheta, theta0)

    @classmethod
    def centered(
        cls,
        center: ArrayLike = (0.0, 0.0, 0.0),
        size: float = 1.0,
        resolution: float = 0.01,
        theta_resolution: float = math.radians(2.0),
    ) -> Grid:
        """Square pose grid of side about ``size`` [m] whose middle cell is centred on ``center``.

        The number of cells per side is ``round(size/resolution)`` made odd, so
        ``center`` (the noiseless end pose) is a cell centre; the default is the
        thesis map, 1 m × 1 m at 1 cm (101 × 101 cells). Heading cells are at most
        ``theta_resolution`` wide (default 2° → 180 cells), one centred on ``center[2]``.
        """
        c = check_finite("center", check_last_axis("center", center, 3))
        side = float(check_positive("size", size))
        h = float(check_positive("resolution", resolution))
        htr = float(check_positive("theta_resolution", theta_resolution))
        n = max(1, round(side / h))
        n += 1 - n % 2
        nt = max(1, math.ceil(2.0 * math.pi / htr - 1e-9))
        half = (n - 1) / 2 * h
        return cls.square(float(c[0]) - half, float(c[1]) - half, n, n, h, nt, float(c[2]))

    @classmethod
    def covering(cls, xy: ArrayLike, n_bins: int = 60, pad: float = 0.05) -> Grid:
        """Planar ``n_bins × n_bins`` grid over the bounding box of ``xy``, widened by ``pad``.

        The box is widened by ``pad`` of its extent on each side, so every point
        falls in a cell (the stated grid of the density comparisons).

        Parameters
        ----------
        xy : array_like, shape (n, 2) [m]; n_bins : int; pad : float ≥ 0
        """
        p = check_last_axis("xy", xy, 2).reshape(-1, 2)
        n_bins = check_positive_int("n_bins", n_bins)
        lo, hi = p.min(axis=0), p.max(axis=0)
        span = np.maximum(hi - lo, 1e-9)
        lo, hi = lo - pad * span, hi + pad * span
        d = (hi - lo) / n_bins
        return cls(float(lo[0] + d[0] / 2), float(lo[1] + d[1] / 2), n_bins, n_bins, float(d[0]), float(d[1]))

    # --- geometry ---------------------------------------------------------------------------

    @property
    def resolution(self) -> float:
        """Cell side [m] of a square-celled grid (``dx``; ``dx == dy`` for maps)."""
        return self.dx

    @property
    def theta_resolution(self) -> float:
        """Heading cell width [rad]."""
        return 2.0 * math.pi / self.ntheta

    @property
    def x(self) -> Array:
        """Cell-centre x, shape (nx,) [m]."""
        return np.asarray(self.x0 + self.dx * np.arange(self.nx), dtype=np.float64)

    @property
    def y(self) -> Array:
        """Cell-centre y, shape (ny,) [m]."""
        return np.asarray(self.y0 + self.dy * np.arange(self.ny), dtype=np.float64)

    @property
    def theta(self) -> Array:
        """Cell-centre heading, shape (ntheta,) [rad], ascending in ``[−π, π)``."""
        return np.asarray(self.theta0 + self.theta_resolution * np.arange(self.ntheta), np.float64)

    @property
    def x_edges(self) -> Array:
        """Cell walls along x, shape (nx+1,) [m]."""
        return np.asarray(self.x0 + self.dx * (np.arange(self.nx + 1) - 0.5), dtype=np.float64)

    @property
    def y_edges(self) -> Array:
        """Cell walls along y, shape (ny+1,) [m]."""
        return np.asarray(self.y0 + self.dy * (np.arange(self.ny + 1) - 0.5), dtype=np.float64)

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(nx, ny, ntheta)``."""
        return self.nx, self.ny, self.ntheta

    @property
    def cell_area(self) -> float:
        """``dx · dy`` [m²]."""
        return self.dx * self.dy

    @property
    def cell_volume(self) -> float:
        """``dx · dy · h_θ`` [m²·rad]."""
        return self.cell_area * self.theta_resolution

    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the cell walls [m]."""
        return (
            self.x0 - self.dx / 2,
            self.x0 + (self.nx - 0.5) * self.dx,
            self.y0 - self.dy / 2,
            self.y0 + (self.ny - 0.5) * self.dy,
        )

    def contains(self, pose: ArrayLike) -> bool:
        """Whether the position of ``pose`` (shape (3,) or (2,)) lies inside the grid's cells."""
        p = np.asarray(pose, dtype=np.float64)
        x_lo, x_hi, y_lo, y_hi = self.extent()
        return bool(x_lo <= p[0] < x_hi and y_lo <= p[1] < y_hi)

    def describe(self) -> dict[str, float]:
        """The planar binning, as floats: cell counts, sides and the covered rectangle [m]."""
        x_lo, x_hi, y_lo, y_hi = self.extent()
        return {
            "nx": float(self.nx), "ny": float(self.ny), "dx": self.dx, "dy": self.dy,
            "x_min": x_lo, "x_max": x_hi, "y_min": y_lo, "y_max": y_hi,
        }  # fmt: skip

    # --- binning ----------------------------------------------------------------------------

    def index_xy(self, points: ArrayLike) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_]]:
        """Cell indices ``(i, j)`` of points (shape (n, 2+)) and whether each lies on the grid.

        Indices of points off the grid are clipped to the nearest cell; use the mask.
        """
        p = check_finite("points", points)
        if p.ndim != 2 or p.shape[1] < 2:
            raise ValueError(f"points must have shape (n, 2) or (n, 3), got shape {p.shape}")
        i = np.floor((p[:, 0] - self.x0) / self.dx + 0.5).astype(np.intp)
        j = np.floor((p[:, 1] - self.y0) / self.dy + 0.5).astype(np.intp)
        inside = (i >= 0) & (i < self.nx) & (j >= 0) & (j < self.ny)
        return np.clip(i, 0, self.nx - 1), np.clip(j, 0, self.ny - 1), inside

    def index_theta(self, theta: ArrayLike) -> NDArray[np.intp]:
        """Heading-cell index of headings [rad] (wrapped onto the grid's circle)."""
        t = check_finite("theta", theta)
        k = np.floor((t - self.theta0) / self.theta_resolution + 0.5).astype(np.intp)
        return np.asarray(np.mod(k, self.ntheta), dtype=np.intp)

    def histogram_xy(self, samples: ArrayLike) -> Array:
        """Fraction of ``samples`` (shape (n, 2+)) in each ``(x, y)`` cell, shape (nx, ny).

        Samples off the grid are not counted, so the sum is the fraction on the grid.
        """
        s = np.asarray(samples, dtype=np.float64)
        i, j, ok = self.index_xy(s)
        flat = np.bincount(i[ok] * self.ny + j[ok], minlength=self.nx * self.ny)
        return flat.reshape(self.nx, self.ny) / max(s.shape[0], 1)

    def histogram(self, samples: ArrayLike) -> Array:
        """Fraction of pose samples (shape (n, 3)) in each ``(x, y, θ)`` cell, shape (nx, ny, nθ)."""
        s = check_last_axis("samples", samples, 3).reshape(-1, 3)
        i, j, ok = self.index_xy(s)
        k = self.index_theta(s[:, 2])
        flat = np.bincount(
            (i[ok] * self.ny + j[ok]) * self.ntheta + k[ok], minlength=self.nx * self.ny * self.ntheta
        )
        return flat.reshape(self.shape) / max(s.shape[0], 1)
