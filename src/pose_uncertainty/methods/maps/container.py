"""The probability map: mass per cell of an ``(x, y, θ)`` grid, and its reductions.

:class:`ProbabilityMap` is what both constructions return, what a run logs and what is
read back: marginals, most probable cell, highest-density regions, credible areas and
moments (the mean and covariance with the heading wrapped about the circular mean).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ...core.grids import Grid
from ...core.kinematics import wrap_angle
from ...core.stats import hdr_region
from ...core.validation import (
    check_finite,
    check_nonnegative,
)
from .kernels import Array


@dataclass(frozen=True, eq=False)
class ProbabilityMap:
    """Probability mass per cell of an ``(x, y, θ)`` grid — computed, logged and read back.

    Attributes
    ----------
    x : ndarray, shape (nx,)
        Cell-centre x [m].
    y : ndarray, shape (ny,)
        Cell-centre y [m].
    theta : ndarray, shape (nθ,)
        Cell-centre heading [rad].
    values : ndarray, shape (nx, ny, nθ)
        Probability mass per cell; sums to ``1 − lost_mass``.
    lost_mass : float
        Mass that left the grid (multi-step) or lies outside it (corrected single
        step, estimated as ``1 − Σ p·ΔV``); 0 for Thrun's (relative) map.
    model : str
        ``"velocity"`` or ``"odometry"``.
    grid : Grid, optional
        The grid the map lives on (None for a map read back from a log).
    info : dict
        Diagnostics (kernel sums, grid growth, settings), JSON-compatible.
    name : str
        The map's name in its run ("" for a map not made by a run).
    params : dict
        The map's configuration parameters in its run.
    center : ndarray, shape (3,)
        The noiseless end pose the map is about [m, m, rad] (``nan`` if unknown):
        the reference point of every distance measured on the map.
    """

    x: Array
    y: Array
    theta: Array
    values: Array
    lost_mass: float
    model: str
    grid: Grid | None = None
    info: dict[str, Any] = field(default_factory=dict)
    name: str = ""
    params: dict[str, Any] = field(default_factory=dict)
    center: Array = field(default_factory=lambda: np.full(3, np.nan))

    #: Units of the axes and of the values.
    UNITS: ClassVar[dict[str, str]] = {"x": "m", "y": "m", "theta": "rad", "values": "probability"}

    def __post_init__(self) -> None:
        for key in ("x", "y", "theta", "values", "center"):
            object.__setattr__(self, key, np.ascontiguousarray(getattr(self, key), np.float64))
        shape = (self.x.size, self.y.size, self.theta.size)
        if self.values.shape != shape:
            raise ValueError(
                f"map values must have shape {shape} (nx, ny, ntheta), got {self.values.shape}"
            )
        object.__setattr__(self, "lost_mass", float(self.lost_mass))

    @property
    def resolution(self) -> float:
        """Cell side [m]."""
        if self.grid is not None:
            return self.grid.resolution
        return float(self.x[1] - self.x[0]) if self.x.size > 1 else float(self.y[1] - self.y[0])

    def marginal_xy(self) -> Array:
        """Mass per ``(x, y)`` cell with θ summed out, shape (nx, ny)."""
        return np.asarray(self.values.sum(axis=2))

    def marginal_theta(self) -> Array:
        """Mass per heading cell, shape (nθ,)."""
        return np.asarray(self.values.sum(axis=(0, 1)))

    def most_probable(self) -> Array:
        """Centre ``(x, y, θ)`` of the most probable cell of the 3-D map, shape (3,)."""
        i, j, k = np.unravel_index(int(np.argmax(self.values)), self.values.shape)
        return np.array([self.x[i], self.y[j], self.theta[k]])

    def most_probable_xy(self) -> Array:
        """Centre ``(x, y)`` of the most probable cell of the θ-marginal, shape (2,)."""
        i, j = np.unravel_index(int(np.argmax(self.marginal_xy())), (self.x.size, self.y.size))
        return np.array([self.x[i], self.y[j]])

    @classmethod
    def from_density_xy(cls, x: ArrayLike, y: ArrayLike, density: ArrayLike, model: str = "density") -> ProbabilityMap:
        """A planar map (one heading cell) from a density [1/m²] on cell centres ``x`` (nx,), ``y`` (ny,).

        The mass of a cell is the density at its centre times the cell area;
        ``lost_mass`` is what that leaves of 1 (clipped at 0).
        """
        xx, yy = check_finite("x", x), check_finite("y", y)
        d = check_nonnegative("density", density)
        if d.shape != (xx.size, yy.size) or xx.size < 2 or yy.size < 2:
            raise ValueError(
                f"density must have shape (nx, ny) = ({xx.size}, {yy.size}) with at least 2 cells "
                f"per axis, got {d.shape}"
            )
        mass = d * float((xx[1] - xx[0]) * (yy[1] - yy[0]))
        lost = max(0.0, 1.0 - float(mass.sum()))
        return cls(xx, yy, np.zeros(1), mass[:, :, None], lost, model)

    def region_xy(self, pr: float) -> tuple[float, float]:
        """The planar Pr highest-density region: ``(level, area)``.

        :func:`pose_uncertainty.core.stats.hdr_region` of the θ-marginal with
        ``pr`` a fraction of the whole distribution (lost mass included): ``level``
        is the mass-per-cell threshold (region = cells of mass ≥ level) and
        ``area`` [m²] counts the last cell in proportion; both ``nan`` when the
        grid holds less than ``pr``.
        """
        level, n_cells = hdr_region(self.marginal_xy(), pr, total=1.0)
        return level, n_cells * self.resolution**2

    def credible_area(self, pr: float) -> float:
        """Area [m²] of the planar Pr highest-density region (:meth:`region_xy`).

        Raises
        ------
        ValueError
            If ``pr`` is not in (0, 1) or the grid holds less than ``pr``.
        """
        area = self.region_xy(pr)[1]
        if not math.isfinite(area):
            held = float(self.values.sum())
            raise ValueError(
                f"pr must not exceed the mass held by the grid (allowed: (0, {held:.6g}]), got {pr}"
            )
        return area

    def mean(self) -> Array:
        """Mean ``(x, y, θ)`` of the in-grid mass (θ: circular mean), shape (3,)."""
        return self.moments()[0]

    def cov(self) -> Array:
        """Covariance of ``(x, y, θ)`` over the in-grid mass, shape (3, 3).

        θ deviations are wrapped around the circular mean. Moments use cell
        centres (no Sheppard correction: a continuous density's variance is
        about ``h²/12`` smaller per axis).
        """
        return self.moments()[1]

    def moments(self) -> tuple[Array, Array]:
        """:meth:`mean` and :meth:`cov` at once, shapes (3,), (3, 3).

        Each product of deviations depends on two axes only, so its sum over the
        grid is taken on the 2-D marginals of the mass.
        """
        v = self.values
        total = float(v.sum())
        # (einsum: a sum over the short last axis without a per-row reduction)
        m2 = {(0, 1): np.einsum("ijk->ij", v) / total, (0, 2): np.einsum("ijk->ik", v) / total,
              (1, 2): v.sum(axis=0) / total}  # fmt: skip
        m1 = (m2[0, 1].sum(axis=1), m2[0, 1].sum(axis=0), m2[1, 2].sum(axis=0))
        th = math.atan2(float(m1[2] @ np.sin(self.theta)), float(m1[2] @ np.cos(self.theta)))
        mu = np.array([float(m1[0] @ self.x), float(m1[1] @ self.y), th])
        d = (self.x - mu[0], self.y - mu[1], wrap_angle(self.theta - mu[2]))
        cov = np.empty((3, 3))
        for a in range(3):
            cov[a, a] = float(m1[a] @ (d[a] * d[a]))  # Σ w d_a²
            for b in range(a + 1, 3):  # Σ w d_a d_b, elementwise (a matrix product rounds by threads)
                cov[a, b] = cov[b, a] = float(np.sum(m2[a, b] * np.multiply.outer(d[a], d[b])))
        return mu, cov
