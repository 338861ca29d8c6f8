"""Probability maps from the velocity and odometry motion models (Method B; Thrun ch. 5; Němec 2012 §2.2).

A map is the probability mass of each cell of a discretised ``(x, y, θ)`` grid
after motion from a known start. Two constructions:

* :func:`single_step_map` — one motion from a known start, the thesis's ``O(n³)``
  case: the motion-model density is evaluated at every cell centre
  (``mass = p · h² · h_θ``). With ``corrected=False`` (default, as the thesis) it is
  Thrun's density — a density of the *control* noise — normalised to relative
  probability; with ``corrected=True`` the pose-space density of the sampler.
* :func:`multi_step_map` — the prediction step of a histogram filter repeated
  along a trajectory, which the thesis could not compute (``O(n⁶)`` per step by
  brute force). The transition kernel depends on ``x_t − x_{t−1}`` rotated by the
  source heading ``θ_k`` only, so a step is, for every source heading slice, one
  2-D FFT convolution of that slice with a compact kernel that carries every
  destination heading (accumulated in the Fourier domain, one inverse FFT per
  destination slice). Mass that leaves the grid is measured exactly
  (``lost_mass``), and by default the grid grows to hold the spread.

Discretisation
--------------
* Single step: with ``corrected=True`` every cell holds the density *averaged
  over the cell* (each noise factor averaged over the control interval one cell
  spans, see :mod:`pose_uncertainty.methods.motion_models`), so structure thinner than a
  cell (rotation in place, zero variances) is integrated, not aliased. The
  corrected densities have an integrable ``1/r`` singularity at the start pose
  (every turn rate reaches it with zero speed), so the cells within
  :data:`EXACT_RADIUS` of the start are integrated exactly: in control space, a
  1-D quadrature over ``ω̂`` (velocity) or ``δ̂rot1`` (odometry) of the CDF of
  ``V̂`` (``δ̂trans``) between the points where the ray of motion crosses the cell.
  With ``corrected=False`` (Thrun's density, the thesis) cells hold point values.
  A control with *all* variances zero is a deterministic move, deposited
  trilinearly.
* Multi step: the transition kernel is the push-forward of the control noise by
  quadrature (see :func:`multi_step_map`); source mass sits at cell centres.
* Headings cover the full circle ``[−π, π)`` in ``n_θ`` cells.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.grids import Grid
from ..core.kinematics import wrap_angle
from ..core.noise import cdf, check_noise, check_scaling, noise_reach, prob, prob_cell
from ..core.stats import hdr_region
from ..core.threads import default_workers
from ..core.validation import (
    check_choice,
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_positive,
    check_positive_int,
)
from .motion_models import (
    check_alphas,
    noiseless_velocity_poses,
    odometry_deltas,
    odometry_density,
    odometry_forward,
    odometry_variances,
    velocity_forward,
    velocity_separable,
    velocity_variances,
)

__all__ = [
    "EXACT_RADIUS",
    "MODELS",
    "GridTransition",
    "ProbabilityMap",
    "grid_transition",
    "multi_step_map",
    "predict_on_grid",
    "single_step_map",
]

MODELS: tuple[str, ...] = ("velocity", "odometry")
#: Corrected single-step maps integrate the cells within this many cells of the start exactly.
EXACT_RADIUS: int = 2

Array = NDArray[np.float64]
AnyArray = NDArray[Any]  # index and mask arrays


# ============================================================================= grid


# ============================================================================= map


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


# ============================================================================= helpers


def _ray_box(beta: Array, s: Array, lo: Array, hi: Array) -> tuple[Array, Array]:
    """Distances ``t0 ≤ t1`` (≥ 0) at which the ray from ``s`` along ``beta`` is inside the box.

    Slab method; an empty intersection gives ``t0 = t1 = 0``.
    """
    t0 = np.zeros_like(beta)
    t1 = np.full_like(beta, np.inf)
    for axis, d in ((0, np.cos(beta)), (1, np.sin(beta))):
        flat = np.abs(d) < 1e-300
        safe = np.where(flat, 1.0, d)
        ta, tb = (lo[axis] - s[axis]) / safe, (hi[axis] - s[axis]) / safe
        inside = (lo[axis] <= s[axis]) & (s[axis] <= hi[axis])
        t0 = np.maximum(t0, np.where(flat, np.where(inside, 0.0, np.inf), np.minimum(ta, tb)))
        t1 = np.minimum(t1, np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(ta, tb)))
    empty = ~(t1 > t0)
    return np.where(empty, 0.0, t0), np.where(empty, 0.0, t1)


# ============================================================================= per-step models


@dataclass(frozen=True)
class _Step:
    """One motion step of a model, in the start frame (translation invariant)."""

    model: str
    u: Array  # velocity: (V, ω); odometry: (δrot1, δtrans, δrot2)
    dt: float
    alphas: Array
    noise: str
    scaling: str
    corrected: bool
    variance_from: str | None
    odom: tuple[Array, Array] | None  # odometry poses (prev, next)

    def variances(self) -> Array:
        if self.model == "velocity":
            return velocity_variances(self.u, self.alphas, self.scaling)
        v = odometry_variances(self.u[0], self.u[1], self.u[2], self.alphas, self.scaling)
        return np.array([float(x) for x in v])

    def noiseless(self, start: Array) -> Array:
        if self.model == "velocity":
            return velocity_forward(start, self.u[0], self.u[1], 0.0, self.dt)
        return odometry_forward(start, self.u[0], self.u[1], self.u[2])

    def density(
        self, xy: Array, theta_dst: Array, start: Array, cell: tuple[float, float] | None
    ) -> Array:
        """Cell-averaged (or, with ``cell=None``, point) density at positions ``xy`` (..., 2) × headings ``theta_dst`` (M,) → (..., M)."""
        if self.model == "velocity":
            p_xy, phi, v3, wg = velocity_separable(
                xy, self.u, start, self.dt, self.alphas, self.noise, self.scaling,
                self.corrected, cell,
            )  # fmt: skip
            g = wrap_angle(theta_dst - start[2] - phi[..., None]) / self.dt
            if cell is None:
                return np.asarray(p_xy[..., None] * prob(g, v3[..., None], self.noise))
            return np.asarray(
                p_xy[..., None] * prob_cell(g, v3[..., None], wg[..., None], self.noise)
            )
        assert self.odom is not None
        pos = np.broadcast_to(xy[..., None, :], (*xy.shape[:-1], theta_dst.size, 2))
        th = np.broadcast_to(theta_dst, pos.shape[:-1])[..., None]
        hyp = np.concatenate([pos, th], axis=-1)
        return odometry_density(
            hyp, self.odom[0], self.odom[1], start, self.alphas, self.noise, self.scaling,
            self.corrected, self.variance_from, cell,
        )  # fmt: skip

    def exact_cell(
        self,
        s: Array,
        lo: Array,
        hi: Array,
        start_theta: float,
        theta_dst: Array,
        cell: tuple[float, float],
        n_nodes: int = 2001,
    ) -> Array:
        """Exact ``∫_cell p(x, y, θ') dx dy`` of the sampler's density over the cell [lo, hi].

        Returns shape (M,) [1/rad]. 1-D quadrature (midpoint, ``n_nodes``) over
        ``ω̂`` (velocity) or ``δ̂rot1`` (odometry) of the CDF of ``V̂`` (``δ̂trans``)
        between the points where the ray of motion from the start ``s`` (forwards
        and backwards) enters and leaves the cell; the heading-only factor is
        averaged over the heading cell. Used near the start, where the corrected
        density has its ``1/r`` singularity.
        """
        var = self.variances()
        if self.model == "velocity":
            return self._exact_cell_velocity(var, s, lo, hi, start_theta, theta_dst, cell[1], n_nodes)
        return self._exact_cell_odometry(var, s, lo, hi, start_theta, theta_dst, cell[1], n_nodes)

    def _exact_cell_velocity(
        self, var: Array, s: Array, lo: Array, hi: Array, start_theta: float, theta_dst: Array,
        ht: float, n_nodes: int,
    ) -> Array:
        """:meth:`exact_cell`, velocity model: quadrature over ``ω̂`` of the CDF of ``V̂``."""
        sd = np.sqrt(var)
        dt = self.dt
        w, step = _midpoint_nodes(float(self.u[1]), float(sd[1]), -math.pi / dt, math.pi / dt,
                                  noise_reach(self.noise), n_nodes)  # fmt: skip
        phi = w * dt
        sinc = np.sinc(phi / (2 * math.pi))
        beta = start_theta + phi / 2
        f0, f1 = _ray_box(beta, s, lo, hi)
        b0, b1 = _ray_box(beta + math.pi, s, lo, hi)
        scale = dt * sinc
        V = self.u[0]
        pv = (
            cdf(f1 / scale - V, var[0], self.noise)
            - cdf(f0 / scale - V, var[0], self.noise)
            + cdf(-b0 / scale - V, var[0], self.noise)
            - cdf(-b1 / scale - V, var[0], self.noise)
        )
        pw = prob(self.u[1] - w, var[1], self.noise) if sd[1] > 0 else np.ones(1)
        g = wrap_angle(theta_dst[None, :] - start_theta - phi[:, None]) / dt
        pg = prob_cell(g, var[2], ht / dt, self.noise) / dt
        return np.asarray(step * np.sum((pv * pw)[:, None] * pg, axis=0))

    def _exact_cell_odometry(
        self, var: Array, s: Array, lo: Array, hi: Array, start_theta: float, theta_dst: Array,
        ht: float, n_nodes: int,
    ) -> Array:
        """:meth:`exact_cell`, odometry model: quadrature over ``δ̂rot1`` of the CDF of ``δ̂trans``."""
        sd = np.sqrt(var)
        r1u, tru, r2u = (float(v) for v in self.u)
        r1, step = _midpoint_nodes(r1u, float(sd[0]), r1u - math.pi, r1u + math.pi,
                                   noise_reach(self.noise), n_nodes)  # fmt: skip
        r2 = wrap_angle(theta_dst[None, :] - start_theta - r1[:, None])
        if self.variance_from == "hypothesis" or (
            self.variance_from is None and not self.corrected
        ):
            v1, v2, v3 = odometry_variances(r1[:, None], 0.0, r2, self.alphas, self.scaling)
        else:
            v1, v2, v3 = (np.full(r2.shape, var[i]) for i in range(3))
        beta = start_theta + r1
        f0, f1 = (t[:, None] for t in _ray_box(beta, s, lo, hi))
        b0, b1 = (t[:, None] for t in _ray_box(beta + math.pi, s, lo, hi))
        # δ'trans = δtrans − noise ∈ [a, b]  ⇔  noise ∈ [δtrans − b, δtrans − a]
        pt = (
            cdf(tru - f0, v2, self.noise)
            - cdf(tru - f1, v2, self.noise)
            + cdf(tru + b1, v2, self.noise)
            - cdf(tru + b0, v2, self.noise)
        )
        if sd[0] > 0:
            p1 = prob(wrap_angle(r1u - r1)[:, None], v1, self.noise)
        else:
            p1 = np.ones((1, 1))
        p3 = prob_cell(wrap_angle(r2u - r2), v3, ht, self.noise)
        return np.asarray(step * np.sum(p1 * pt * p3, axis=0))


def _midpoint_nodes(
    mean: float, std: float, lo: float, hi: float, reach: float, n_nodes: int
) -> tuple[Array, float]:
    """Midpoint rule on ``mean ± reach·std`` clipped to ``[lo, hi]``: (nodes, their spacing).

    A zero ``std`` gives the single node ``mean`` with weight 1.
    """
    if std <= 0.0:
        return np.array([mean]), 1.0
    a_, b_ = max(mean - reach * std, lo), min(mean + reach * std, hi)
    step = (b_ - a_) / n_nodes
    return np.asarray(a_ + step * (np.arange(n_nodes) + 0.5), dtype=np.float64), step


def _make_step(
    model: str,
    control: Array | None,
    dt: float,
    alphas: Array,
    noise: str,
    scaling: str,
    corrected: bool,
    variance_from: str | None,
    odom: tuple[Array, Array] | None,
) -> _Step:
    if model == "velocity":
        assert control is not None
        return _Step(model, control, dt, alphas, noise, scaling, corrected, variance_from, None)
    assert odom is not None
    r1, tr, r2 = odometry_deltas(odom[0], odom[1])
    u = np.array([float(r1), float(tr), float(r2)])
    return _Step(model, u, dt, alphas, noise, scaling, corrected, variance_from, odom)


def _deposit(values: Array, grid: Grid, pose: Array, mass: float = 1.0) -> None:
    """Trilinear (mean-preserving) deposit of ``mass`` at ``pose`` into ``values`` (in place)."""
    h, ht = grid.resolution, grid.theta_resolution
    fx = (pose[0] - grid.x0) / h
    fy = (pose[1] - grid.y0) / h
    ft = (pose[2] - grid.theta0) / ht
    ix, iy, it = math.floor(fx), math.floor(fy), math.floor(ft)
    ax, ay, at = fx - ix, fy - iy, ft - it
    for dx_, wx in ((0, 1 - ax), (1, ax)):
        for dy_, wy in ((0, 1 - ay), (1, ay)):
            for dt_, wt in ((0, 1 - at), (1, at)):
                w = wx * wy * wt
                if w <= 0:
                    continue
                jx, jy = ix + dx_, iy + dy_
                if 0 <= jx < grid.nx and 0 <= jy < grid.ny:
                    values[jx, jy, (it + dt_) % grid.ntheta] += mass * w


# ============================================================================= single step


def _noise_args(model: str, noise: str, scaling: str, alphas: ArrayLike) -> Array:
    check_choice("model", model, MODELS)
    check_noise(noise)
    check_scaling(scaling)
    return check_alphas(alphas, 6 if model == "velocity" else 4)


def single_step_map(
    model: str,
    start: ArrayLike,
    control: ArrayLike,
    dt: float,
    alphas: ArrayLike,
    grid: Grid | None = None,
    noise: str = "normal",
    scaling: str = "squared",
    corrected: bool = False,
    *,
    odometry: ArrayLike | None = None,
    variance_from: str | None = None,
    cell_average: bool | None = None,
) -> ProbabilityMap:
    """Map after one motion from a known start (the thesis's ``O(n³)`` case).

    Parameters
    ----------
    model : {"velocity", "odometry"}
    start : array_like, shape (3,)
        Known start pose.
    control : array_like, shape (2,)
        ``(V, ω)`` [m/s, rad/s]. For the odometry model the odometry ``u`` is the
        noiseless velocity motion ``start → end`` (as Němec 2012 §4.2), unless ``odometry``
        is given.
    dt : float [s], > 0
    alphas : array_like, shape (6,) velocity or (4,) odometry, >= 0
    grid : Grid, optional
        Default :meth:`Grid.centered` on the noiseless end pose (1 m × 1 m, 1 cm, 2°).
    noise : {"normal", "triangular"}
    scaling : {"squared", "abs"}
    corrected : bool
        False: Thrun's density normalised to relative probability (``lost_mass = 0``).
        True: pose-space density of the sampler; cell mass ``p·ΔV``, the start cell
        integrated exactly, ``lost_mass = max(0, 1 − Σ)``.
    odometry : array_like, shape (2, 3), optional
        Odometry poses ``(x̄, x̄')`` for the odometry model.
    variance_from : {"hypothesis", "odometry"}, optional
        Odometry model only; see :func:`~pose_uncertainty.methods.motion_models.odometry_density`.
    cell_average : bool, optional
        True: each cell holds the density averaged over the cell (see
        :mod:`~pose_uncertainty.methods.motion_models`, "Cell averaging") — needed when the
        distribution has structure thinner than a cell (rotation in place, zero
        variances). False: the value at the cell centre, as the thesis computed it.
        Default: ``corrected`` (the corrected map averages, the thesis map does not).

    Returns
    -------
    ProbabilityMap
    """
    a = _noise_args(model, noise, scaling, alphas)
    x0 = check_finite("start", check_last_axis("start", start, 3))
    if x0.shape != (3,):
        raise ValueError(f"start must have shape (3,), got shape {x0.shape}")
    stp = _single_step(model, x0, control, dt, a, noise, scaling, corrected, variance_from, odometry)
    end = stp.noiseless(x0)
    g = grid if grid is not None else Grid.centered(end)
    cell = (g.resolution, g.theta_resolution)
    averaged = corrected if cell_average is None else bool(cell_average)
    info: dict[str, Any] = {"corrected": corrected, "cell_average": averaged, "noise": noise, "scaling": scaling,
                            "end_pose": end.tolist()}  # fmt: skip
    if np.all(stp.variances() == 0):
        values = np.zeros(g.shape)
        _deposit(values, g, end)
        info["deterministic"] = True
        lost = 1.0 - float(values.sum())
        return ProbabilityMap(g.x, g.y, g.theta, values, lost, model, g, info)
    X, Y = np.meshgrid(g.x, g.y, indexing="ij")
    xy = np.stack([X, Y], axis=-1)
    dens = stp.density(xy, g.theta, x0, cell if averaged else None)
    values = dens * g.cell_volume
    if corrected and g.contains(x0):
        _integrate_start_cells(values, stp, g, x0)
    raw = float(values.sum())
    info["raw_sum"] = raw
    lost = _normalise_single(values, raw, corrected)
    return ProbabilityMap(g.x, g.y, g.theta, values, lost, model, g, info)


def _single_step(
    model: str,
    x0: Array,
    control: ArrayLike,
    dt: float,
    alphas: Array,
    noise: str,
    scaling: str,
    corrected: bool,
    variance_from: str | None,
    odometry: ArrayLike | None,
) -> _Step:
    """Check the control of :func:`single_step_map` and make its step (odometry: given or Němec 2012's)."""
    step_dt = float(check_positive("dt", dt))
    u = check_finite("control", control)
    if u.shape != (2,):
        raise ValueError(f"control must have shape (2,) (allowed: (V, omega)), got shape {u.shape}")
    if model != "odometry":
        return _make_step(model, u, step_dt, alphas, noise, scaling, corrected, None, None)
    if odometry is None:
        od = noiseless_velocity_poses(x0, u[None, :], step_dt)
    else:
        od = check_finite("odometry", check_last_axis("odometry", odometry, 3))
        if od.shape != (2, 3):
            raise ValueError(f"odometry must have shape (2, 3), got shape {od.shape}")
    return _make_step(model, None, step_dt, alphas, noise, scaling, corrected, variance_from,
                      (od[0], od[1]))  # fmt: skip


def _integrate_start_cells(values: Array, stp: _Step, g: Grid, x0: Array) -> None:
    """Overwrite the cells within :data:`EXACT_RADIUS` cells of the start by their exact mass (in place).

    The corrected density has an integrable ``1/r`` singularity at the start
    (:meth:`_Step.exact_cell`).
    """
    h = g.resolution
    cell = (h, g.theta_resolution)
    ix = int(np.floor((x0[0] - g.x0) / h + 0.5))
    iy = int(np.floor((x0[1] - g.y0) / h + 0.5))
    for jx in range(max(0, ix - EXACT_RADIUS), min(g.nx, ix + EXACT_RADIUS + 1)):
        for jy in range(max(0, iy - EXACT_RADIUS), min(g.ny, iy + EXACT_RADIUS + 1)):
            lo = np.array([g.x[jx] - h / 2, g.y[jy] - h / 2])
            values[jx, jy, :] = (
                stp.exact_cell(x0[:2], lo, lo + h, float(x0[2]), g.theta, cell)
                * g.theta_resolution
            )


def _normalise_single(values: Array, raw: float, corrected: bool) -> float:
    """Scale a single-step map of sum ``raw`` in place; return its lost mass.

    Corrected: to ``1 − lost``, ``lost = max(0, 1 − raw)``. Thrun's: to 1 (relative
    probability, nothing lost).
    """
    if corrected:
        lost = max(0.0, 1.0 - raw)
        values *= (1.0 - lost) / raw
        return lost
    values /= raw
    return 0.0


# ============================================================================= multi step


def _node_masses(mean: float, std: float, noise: str, spacing: float, n_max: int) -> tuple[Array, Array]:
    """Quadrature of a 1-D noise ``mean + N(0, std²)``: nodes and their exact interval masses.

    The range ``mean ± reach·std`` is cut into intervals of width ≤ ``spacing``; each
    node (interval midpoint) carries the exact probability of its interval (CDF
    differences), renormalised to 1 (the truncated tails are ≤ 2·10⁻⁹ for the normal).
    A zero ``std`` gives the single node ``mean``.
    """
    if std <= 0.0:
        return np.array([mean]), np.array([1.0])
    reach = noise_reach(noise) * std
    n = int(min(max(math.ceil(2.0 * reach / spacing), 1), n_max))
    n += 1 - n % 2  # odd: one node on the mean
    edges = np.linspace(-reach, reach, n + 1)
    mass = np.diff(cdf(edges, std * std, noise))
    return mean + 0.5 * (edges[1:] + edges[:-1]), mass / mass.sum()


@dataclass(frozen=True)
class _Kernel:
    """Control-space quadrature of one step.

    ``local`` (Q, 2) forward/left displacement [m] and ``dtheta`` (Q,) heading change
    [rad] of the position nodes, ``weight`` (Q,) their masses (exact probabilities
    of their control intervals); ``step_a``/``step_b`` the local pose change across
    one node interval along each control axis (a node stands for that little
    parallelogram, deposited as a box of the same extent);
    ``head_lo, head_kernel``: the heading-only noise (``γΔt`` or ``δrot2``) as
    masses on heading offsets ``head_lo, head_lo+1, …`` [cells].
    """

    local: Array
    dtheta: Array
    weight: Array
    step_a: Array  # (Q, 3) pose change between neighbouring nodes along the first control axis
    step_b: Array  # (Q, 3) … along the second control axis
    heading_variance_mismatch: float  # discrete − continuous heading variance per step [rad²]
    head_parts: tuple[AnyArray, Array]  # (S, Q) heading cells (offsets from head_m_lo) of the nodes, factors
    head_m_lo: int
    head_mp: int
    head_lo: int
    head_kernel: Array
    perimeter: AnyArray  # indices of nodes on the boundary of the control box


def _discrete_var(mass: Array) -> float:
    """Variance [cells²] of masses on consecutive integer offsets."""
    m = mass / mass.sum()
    k = np.arange(m.size)
    mu = float(m @ k)
    return float(m @ (k - mu) ** 2)


def _heading_kernel(mean: float, std: float, noise: str, ht: float) -> tuple[int, Array]:
    """Masses of ``mean + noise`` on heading-cell offsets: (first offset, masses).

    A noise at least half a cell wide is integrated exactly over each cell
    ``[(m−½)h_θ, (m+½)h_θ]`` (mean kept, ``h_θ²/12`` of variance added). A narrower
    one is split: its mean linearly between the two neighbouring offsets
    (mean-preserving), its zero-mean noise integrated over cells centred on 0.
    """
    f = mean / ht
    if std >= 0.5 * ht:  # wide: integrate mean + noise over the cells directly (keeps the mean)
        lo_ = math.floor(f - noise_reach(noise) * std / ht - 0.5)
        hi_ = math.ceil(f + noise_reach(noise) * std / ht + 0.5)
        edges = (np.arange(lo_, hi_ + 2) - 0.5) * ht - mean
        masses = np.diff(cdf(edges, std * std, noise))
        return lo_, masses / masses.sum()
    i0 = math.floor(f)
    frac = f - i0
    split = np.array([1.0 - frac, frac])
    if std <= 0.0:
        return i0, split
    L = math.ceil(noise_reach(noise) * std / ht + 0.5)
    edges = (np.arange(-L, L + 2) - 0.5) * ht
    box = np.diff(cdf(edges, std * std, noise))
    box /= box.sum()
    return i0 - L, np.convolve(split, box)


class _ControlNodes(NamedTuple):
    """Quadrature nodes of one step's control noise, moved to local pose changes."""

    shape: tuple[int, int]  # nodes along the first and the second control axis
    pose: Array  # (Q, 3) local pose change of each node [m, m, rad], Q = shape[0]·shape[1]
    weight: Array  # (Q,) exact probability of each node's control interval
    head_mean: float  # mean of the heading-only noise (γΔt or δrot2) [rad]
    head_std: float  # its standard deviation [rad]


def _velocity_nodes(stp: _Step, sd: Array, h: float, ht: float, n_max: int) -> _ControlNodes:
    """Nodes of ``(V̂, ω̂)``, spaced ≤ a quarter cell in pose space."""
    V, w = float(stp.u[0]), float(stp.u[1])
    dt = stp.dt
    # along-track: dx = dV·Δt·sinc ≤ dV·Δt; across: ≈ |V|Δt²/2·dω; heading: Δt·dω
    Vn, Vw = _node_masses(V, float(sd[0]), stp.noise, 0.25 * h / dt, n_max)
    lever = (abs(V) + noise_reach(stp.noise) * float(sd[0])) * dt * dt / 2.0
    w_sp = min(0.25 * ht / dt, 0.25 * h / lever if lever > 0 else math.inf)
    wn, ww = _node_masses(w, float(sd[1]), stp.noise, w_sp, n_max)
    wn = np.clip(wn, -math.pi / dt, math.pi / dt)
    A, B = np.meshgrid(Vn, wn, indexing="ij")
    pose = velocity_forward(np.zeros(3), A.ravel(), B.ravel(), 0.0, dt)
    return _ControlNodes(A.shape, pose, np.outer(Vw, ww).ravel(), 0.0, float(sd[2]) * dt)


def _odometry_nodes(stp: _Step, sd: Array, h: float, ht: float, n_max: int) -> _ControlNodes:
    """Nodes of ``(δ̂rot1, δ̂trans)``, spaced ≤ a quarter cell in pose space."""
    r1, tr, r2 = (float(v) for v in stp.u)
    tr_n, tr_w = _node_masses(tr, float(sd[1]), stp.noise, 0.25 * h, n_max)
    lever = abs(tr) + noise_reach(stp.noise) * float(sd[1])
    r1_sp = min(0.25 * ht, 0.25 * h / lever if lever > 0 else math.inf)
    r1_n, r1_w = _node_masses(r1, float(sd[0]), stp.noise, r1_sp, n_max)
    A, B = np.meshgrid(r1_n, tr_n, indexing="ij")
    pose = odometry_forward(np.zeros(3), A.ravel(), B.ravel(), 0.0)
    return _ControlNodes(A.shape, pose, np.outer(r1_w, tr_w).ravel(), r2, float(sd[2]))


def _node_heading_variances(
    t_parts: tuple[AnyArray, Array], mp: int, weight: Array, fth: Array, wth: Array
) -> tuple[float, float]:
    """Heading variance [cells²] the position nodes carry: (deposited on the cells, continuous).

    ``fth`` (Q,) are the nodes' heading changes and ``wth`` (Q,) the widths of
    their intervals [cells]; ``t_parts`` their deposit (:func:`_axis_parts`) on
    ``mp`` heading offsets.
    """
    phi_mass = np.zeros(mp)
    for i_, w_ in zip(*t_parts, strict=True):
        phi_mass += np.bincount(i_, weight * w_, minlength=mp)
    var_phi_disc = _discrete_var(phi_mass)
    mu = float(weight @ fth)
    var_phi_true = float(weight @ (fth - mu) ** 2 + weight @ (wth**2) / 12.0)
    return var_phi_disc, var_phi_true


def _matched_heading_std(
    head_mean: float, head_std: float, target: float, noise: str, ht: float, compensate: bool
) -> float:
    """Width [rad] of the heading-only noise: ``head_std``, or moment-matched to ``target`` [cells²].

    Moment matching of the heading (diffusion compensation). Each step's cell
    integration/linear split changes the heading variance of the discrete kernel
    (Sheppard's +h_θ²/12 for a spread-out kernel, +frac(1−frac)·h_θ² for a split
    mean, −σ² for a noise narrower than a cell that is rounded away), and the next
    step inherits the change, so it accumulates over the steps. The width of the
    heading-only noise is therefore chosen (by bisection) so that the discrete
    kernel's heading variance equals the continuous one, σ_φ² + σ_head², whenever
    it can be: ``target`` is what the heading-only kernel must add.
    """
    if not (compensate and head_std > 0.0):
        return float(head_std)

    def head_var(sd_bins: float) -> float:
        return _discrete_var(_heading_kernel(head_mean, sd_bins * ht, noise, ht)[1])

    lo_, hi_ = 0.0, math.sqrt(max(target, 0.0)) + 1.0
    if head_var(lo_) >= target:
        sd_bins = 0.0
    else:
        while head_var(hi_) < target:
            hi_ *= 2.0
        for _ in range(50):
            mid = 0.5 * (lo_ + hi_)
            lo_, hi_ = (mid, hi_) if head_var(mid) < target else (lo_, mid)
        sd_bins = 0.5 * (lo_ + hi_)
    return sd_bins * ht


def _quadrature_kernel(
    stp: _Step, h: float, ht: float, n_max: int = 1500, compensate: bool = True
) -> _Kernel:
    """Build the quadrature of one step's control noise, spaced ≤ half a cell in pose space."""
    sd = np.sqrt(stp.variances())
    nodes_of = _velocity_nodes if stp.model == "velocity" else _odometry_nodes
    (na, nb), pose, weight, head_mean, head_std = nodes_of(stp, sd, h, ht, n_max)
    grid_pose = pose.reshape(na, nb, 3)
    step_a: Array = np.asarray(np.gradient(grid_pose, axis=0)) if na > 1 else np.zeros_like(grid_pose)
    step_b: Array = np.asarray(np.gradient(grid_pose, axis=1)) if nb > 1 else np.zeros_like(grid_pose)
    # heading cells of the position nodes (same rule as the x, y axes)
    fth = pose[:, 2] / ht
    wth = np.minimum((np.abs(step_a[..., 2]) + np.abs(step_b[..., 2])).ravel() / ht, 1.0)
    jt, vt = (a_[0] for a_ in _axis_parts(fth[None], wth[None], weight))
    m_lo_p = int(jt.min())
    mp = int(jt.max()) - m_lo_p + 1
    t_parts = (jt - m_lo_p, vt)
    var_phi_disc, var_phi_true = _node_heading_variances(t_parts, mp, weight, fth, wth)
    target = var_phi_true + (head_std / ht) ** 2 - var_phi_disc  # bins²
    head_sd = _matched_heading_std(head_mean, head_std, target, stp.noise, ht, compensate)
    head_lo, head_kernel = _heading_kernel(head_mean, head_sd, stp.noise, ht)
    mismatch = (var_phi_disc + _discrete_var(head_kernel) - var_phi_true - (head_std / ht) ** 2) * ht**2
    ia, ib = np.meshgrid(np.arange(na), np.arange(nb), indexing="ij")
    edge = ((ia == 0) | (ia == na - 1) | (ib == 0) | (ib == nb - 1)).ravel()
    return _Kernel(
        local=pose[:, :2],
        dtheta=pose[:, 2],
        weight=weight,
        step_a=step_a.reshape(-1, 3),
        step_b=step_b.reshape(-1, 3),
        heading_variance_mismatch=mismatch,
        head_parts=t_parts,
        head_m_lo=m_lo_p,
        head_mp=mp,
        head_lo=head_lo,
        head_kernel=head_kernel,
        perimeter=np.flatnonzero(edge),
    )


def _splat(f: Array, width: Array) -> tuple[AnyArray, Array]:
    """Deposit segments ``[f − w/2, f + w/2]`` (cell units, ``w ≤ 1``) by exact overlap with cells.

    Returns the first cell ``i`` and the fraction ``first`` of the segment in it (the rest
    is in ``i + 1``), both of the shape of ``f``.
    """
    left = f - width / 2.0
    i = np.floor(left + 0.5).astype(np.int64)
    safe = np.where(width > 0, width, 1.0)
    first = np.where(width > 0, np.clip((i + 0.5 - left) / safe, 0.0, 1.0), 1.0)
    return i, first


def _axis_parts(f: Array, width: Array, weight: Array) -> tuple[AnyArray, Array]:
    """How the nodes at continuous cell coordinates ``f`` are deposited on one axis.

    Parameters
    ----------
    f, width : ndarray, shape (K, Q) — K rows (source headings) of the Q nodes [cells]
    weight : ndarray, shape (Q,) — the nodes' masses (for each row's mean and spread)

    Returns
    -------
    index : ndarray of int64, shape (K, S, Q) — cell of each node in each of the S parts
    factor : ndarray, shape (K, S, Q) — the share of the node's mass that part carries

    Each node stands for a segment of ``width`` cells (its control interval seen on
    this axis) and is deposited by exact overlap with the cells: with nodes ≤ ½ cell
    apart this integrates the kernel over the cells, as a histogram of samples does,
    without the aliasing of nearest-cell rounding and with only ``w²/12`` of spread
    (two parts: the first cell and the next). When the kernel of a row is narrower
    than half a cell (weighted standard deviation < ½) it is split into its mean
    ``μ`` and the deviations ``f − μ``: the deviations are deposited as above (exact
    for a thin centred ridge) and the mean is shared linearly between ``⌊μ⌋`` and
    ``⌊μ⌋+1`` (cloud-in-cell), so a sub-cell drift is kept, not rounded away, at the
    price of ``frac(1−frac)`` cell² (four parts). When some rows are split and others
    not, S = 4 and the unsplit rows carry two parts of zero mass (an exact no-op in
    any sum).
    """
    mean, split = _split_rows(f, weight)
    dev = f - mean[:, None]
    i, first = _splat(np.where(split[:, None], dev, f), width)
    rest = 1.0 - first
    if not split.any():
        return np.stack([i, i + 1], axis=1), np.stack([first, rest], axis=1)
    base = np.where(split, np.floor(mean), 0.0)
    frac = mean - base
    lo, hi = np.where(split, 1.0 - frac, 1.0)[:, None], np.where(split, frac, 0.0)[:, None]
    ib = i + base.astype(np.int64)[:, None]
    return (np.stack([ib, ib + split[:, None], ib + 1, ib + 1 + split[:, None]], axis=1),
            np.stack([first * lo, first * hi, rest * lo, rest * hi], axis=1))  # fmt: skip


def _split_rows(f: Array, weight: Array) -> tuple[Array, AnyArray]:
    """Which rows of ``f`` (K, Q) :func:`_axis_parts` splits (spread < ½ cell), and their weighted means.

    Returns ``(mean, split)``, shapes (K,): ``mean`` is exact (the dot product of one row,
    as for a single row) where ``split``, else only an estimate (unused). The decision is
    taken on vectorised estimates of the spread, which differ from the row-by-row value
    by round-off only: rows within 10⁻⁹ of ½ are decided row by row.
    """
    mean = f @ weight
    std = np.sqrt(np.maximum(((f - mean[:, None]) ** 2) @ weight, 0.0))
    split = std < 0.5
    for r in np.flatnonzero(np.abs(std - 0.5) <= 1e-9):  # a spread at the threshold: as one row
        m = float(weight @ f[r])
        split[r] = not math.sqrt(max(float(weight @ (f[r] - m) ** 2), 0.0)) >= 0.5
    for r in np.flatnonzero(split):
        mean[r] = float(weight @ f[r])
    return mean, split


def _rotated_cells(kern: _Kernel, theta: Array, h: float, idx: Array | None = None) -> tuple[Array, Array]:
    """World offsets in cell units of the kernel's position nodes for source headings ``theta``."""
    loc = kern.local if idx is None else kern.local[idx]
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    fx = (c * loc[None, :, 0] - s * loc[None, :, 1]) / h
    fy = (s * loc[None, :, 0] + c * loc[None, :, 1]) / h
    return fx, fy


def _grow_bounds(
    lo: tuple[int, int], hi: tuple[int, int], need_lo: tuple[int, int], need_hi: tuple[int, int],
    max_side: int, slack: int,
) -> tuple[tuple[int, int], tuple[int, int]]:
    """New index bounds (inclusive) covering ``need``, padded by ``slack``, at most ``max_side`` wide."""
    new_lo, new_hi = [], []
    for a in range(2):
        l_ = min(lo[a], need_lo[a] - slack) if need_lo[a] < lo[a] else lo[a]
        h_ = max(hi[a], need_hi[a] + slack) if need_hi[a] > hi[a] else hi[a]
        if h_ - l_ + 1 > max_side:
            centre = (need_lo[a] + need_hi[a]) / 2.0
            l_ = math.floor(centre - max_side / 2.0)
            h_ = l_ + max_side - 1
        new_lo.append(l_)
        new_hi.append(h_)
    return (new_lo[0], new_lo[1]), (new_hi[0], new_hi[1])


def _coarsen(fine: ProbabilityMap, over: int) -> ProbabilityMap:
    """Sum blocks of ``over × over`` cells of a map whose start is a cell centre.

    Blocks are aligned so that the start cell lies in the middle of its block
    (exactly, for odd ``over``).
    """
    assert fine.grid is not None
    g = fine.grid
    start = fine.info["start"]
    ix = round((start[0] - g.x0) / g.resolution)
    iy = round((start[1] - g.y0) / g.resolution)
    mid = (over - 1) // 2
    pad_x = (mid - ix) % over
    pad_y = (mid - iy) % over
    nx = -(-(g.nx + pad_x) // over)
    ny = -(-(g.ny + pad_y) // over)
    v = np.zeros((nx * over, ny * over, g.ntheta))
    v[pad_x : pad_x + g.nx, pad_y : pad_y + g.ny] = fine.values
    v = v.reshape(nx, over, ny, over, g.ntheta).sum(axis=(1, 3))
    h = g.resolution * over
    x0 = g.x0 - pad_x * g.resolution + (over - 1) / 2 * g.resolution
    y0 = g.y0 - pad_y * g.resolution + (over - 1) / 2 * g.resolution
    cg = Grid.square(x0, y0, nx, ny, h, g.ntheta, g.theta0)
    info = dict(fine.info, oversample=over, fine_grid=g.shape)
    return ProbabilityMap(cg.x, cg.y, cg.theta, v, fine.lost_mass, fine.model, cg, info)


def _kernel_windows(kern: _Kernel, thetas: Array, h: float) -> tuple[AnyArray, AnyArray, int, int]:
    """Window of a step's kernel per source heading [cells]: offsets ``ax, ay`` (nθ,), sizes ``wx, wy``."""
    # kernel windows per source heading (cells), from the control box perimeter (+1 for CIC)
    px, py = _rotated_cells(kern, thetas, h, kern.perimeter)
    ax = np.floor(px.min(axis=1)).astype(np.int64) - 2
    ay = np.floor(py.min(axis=1)).astype(np.int64) - 2
    wx = int((np.floor(px.max(axis=1)).astype(np.int64) + 4 - ax).max()) + 1
    wy = int((np.floor(py.max(axis=1)).astype(np.int64) + 4 - ay).max()) + 1
    return ax, ay, wx, wy


def _drop_negligible_slices(belief: Array, copy: bool = False) -> tuple[Array, float, AnyArray]:
    """Zero the heading slices holding < 1e-14: (belief, mass dropped, indices of the others).

    In place, or with ``copy`` on a copy made only when a slice has to be zeroed.
    """
    mass_k = belief.sum(axis=(0, 1))
    tiny = mass_k < 1e-14
    dropped = 0.0
    drop = np.flatnonzero(tiny & (mass_k != 0.0))  # (the other tiny slices hold zeros only)
    if drop.size:
        dropped = float(mass_k[tiny].sum())
        belief = belief.copy() if copy else belief
        belief[:, :, drop] = 0.0
    return belief, dropped, np.flatnonzero(~tiny)


#: Scratch bytes of :func:`_source_windows` per batch of headings (the cells and masses of
#: every part of every node: a cache-sized block).
_WINDOW_BATCH_BYTES = 1 << 20


def _source_windows(
    kern: _Kernel,
    ks: AnyArray,
    thetas: Array,
    h: float,
    windows: tuple[AnyArray, AnyArray, int, int],
) -> Array:
    """Kernels of the source headings ``ks`` (K,) on their windows: mass per (x, y, heading offset).

    Returns shape (K, wx, wy, mp). Every node is deposited on the three axes
    (:func:`_axis_parts`: ``S_x · S_y · S_t`` parts), summed by :func:`_sum_parts`; a
    heading's window does not depend on which other headings share its batch.
    """
    ax, ay, wx, wy = windows
    # heading offsets carried by the position nodes (CIC); the heading-only noise
    # (γΔt or δrot2) is applied afterwards as a circular convolution along θ
    jt, vt = kern.head_parts
    mp, n_q = kern.head_mp, kern.weight.size
    batch = max(1, _WINDOW_BATCH_BYTES // (16 * 16 * jt.shape[0] * n_q))  # ≤ 4 × 4 × S_t parts
    fxy = _rotated_cells(kern, thetas, h)
    out = np.empty((ks.size, wx * wy * mp))
    for a in range(0, ks.size, batch):
        k = ks[a : a + batch]
        jx, vx, jy, vy = _position_parts(kern, k, fxy, thetas, h)
        jx -= ax[k][:, None, None]
        jy -= ay[k][:, None, None]
        if jx.min() < 0 or jy.min() < 0 or jx.max() >= wx or jy.max() >= wy:
            raise RuntimeError("kernel node outside its window (internal error)")
        # cell of every (heading, x part, y part, θ part, node) in its window, and its mass
        cell = (jx[:, :, None, None, :] * wy + jy[:, None, :, None, :]) * mp + jt[None, None, None]
        mass = ((kern.weight * vx)[:, :, None, None, :] * vy[:, None, :, None, :]) * vt[None, None, None]
        out[a : a + k.size] = _sum_parts(cell.reshape(k.size, -1, n_q), mass.reshape(k.size, -1, n_q), out.shape[1])
    return out.reshape(ks.size, wx, wy, mp)


def _sum_parts(cell: AnyArray, mass: Array, size: int) -> Array:
    """Deposit the parts of the nodes: ``Σ_p (Σ_q mass[k, p, q] at cell[k, p, q])``, shape (K, size).

    ``cell``, ``mass`` (K, P, Q): the cell (of ``size``) and the mass of node q's part p
    for heading k. As one deposit per part, added one after the other: each part's
    sum over the nodes in node order, then the parts in part order (two sequential
    ``bincount``), without a (K, P, size) array. Every part of a heading is its first part
    moved by one cell offset (:func:`_axis_parts` shifts whole rows), so the nodes that
    share a cell share it in every part and are grouped once.
    """
    n_k, n_p, n_q = cell.shape
    first, group = np.unique((cell[:, 0] + size * np.arange(n_k)[:, None]).ravel(), return_inverse=True)
    group = group.reshape(n_k, 1, n_q)
    # Σ over the nodes of each (part, group), in node order
    per_group = np.bincount((np.arange(n_p)[:, None] * first.size + group).ravel(), mass.ravel(),
                            minlength=n_p * first.size)  # fmt: skip
    # Σ over the parts of each cell, in part order
    shift = cell[:, :, 0] - cell[:, :1, 0]  # (K, P) the parts' offsets
    target = first + shift[first // size].T  # (P, groups)
    return np.asarray(np.bincount(target.ravel(), per_group, minlength=n_k * size), np.float64).reshape(n_k, size)


def _position_parts(
    kern: _Kernel, ks: AnyArray, fxy: tuple[Array, Array], thetas: Array, h: float
) -> tuple[AnyArray, Array, AnyArray, Array]:
    """The nodes' deposits on the x and the y axis for source headings ``ks`` (K,).

    ``fxy``: the nodes' world offsets [cells] for every heading of ``thetas``, (nθ, Q) each
    (:func:`_rotated_cells`). Returns ``(jx, vx, jy, vy)``, each of shape (K, S, Q)
    (:func:`_axis_parts`).
    """
    fx, fy = fxy[0][ks], fxy[1][ks]
    c_ = np.array([math.cos(thetas[k]) for k in ks])[:, None]
    s_ = np.array([math.sin(thetas[k]) for k in ks])[:, None]
    sa, sb = kern.step_a, kern.step_b
    # extent of each node's interval on the world axes [cells]
    wdx = (np.abs(c_ * sa[:, 0] - s_ * sa[:, 1]) + np.abs(c_ * sb[:, 0] - s_ * sb[:, 1])) / h
    wdy = (np.abs(s_ * sa[:, 0] + c_ * sa[:, 1]) + np.abs(s_ * sb[:, 0] + c_ * sb[:, 1])) / h
    jx, vx = _axis_parts(fx, np.minimum(wdx, 1.0), kern.weight)
    jy, vy = _axis_parts(fy, np.minimum(wdy, 1.0), kern.weight)
    return jx, vx, jy, vy


def _heading_noise(
    planes: Array, headings: AnyArray, kern: _Kernel, new: Array, workers: int
) -> tuple[Array, float]:
    """Heading-only noise, then the round-off clipped: (belief, sum of the negatives clipped).

    ``planes`` (T, nx, ny) are the belief's slices at ``headings`` (T,), the other slices
    empty; the result is written into ``new`` (nx, ny, nθ). Circular convolution along θ
    with the CIC-deposited γΔt / δrot2 (FFT along θ), on blocks of x rows that stay in
    cache (each θ line is transformed as a whole, so the blocks do not change a value);
    negative round-off is set to zero.
    """
    import scipy.fft as sfft  # imported where used: a run without a map never pays its 0.15 s

    nx, ny, nt = new.shape
    g_circ = np.bincount((kern.head_lo + np.arange(kern.head_kernel.size)) % nt, kern.head_kernel, minlength=nt)
    g_hat = sfft.rfft(g_circ)
    rows = max(1, _BLOCK // (ny * nt))
    block = np.zeros((nt, rows, ny))  # θ first: the slices are copied as planes; empty headings stay 0
    negatives = []
    for i0 in range(0, nx, rows):
        r = min(rows, nx - i0)
        block[headings, :r] = planes[:, i0 : i0 + r]
        spectrum = sfft.rfft(np.moveaxis(block[:, :r], 0, 2), axis=2, workers=workers)
        spectrum *= g_hat
        out = new[i0 : i0 + r]
        out[...] = sfft.irfft(spectrum, n=nt, axis=2, workers=workers, overwrite_x=True)
        flat = out.reshape(-1)
        neg = np.flatnonzero(flat < 0.0)  # (indices: a boolean mask of ~½ density is slow to apply)
        negatives.append(flat[neg])
        flat[neg] = 0.0
    return new, float(-np.concatenate(negatives).sum())


#: Elements of a block of :func:`_heading_noise` (256 kB of float64: its temporaries stay in
#: cache and are reused by the allocator instead of being mapped afresh at every step).
_BLOCK = 1 << 15


def _convolve_step(
    belief: Array,
    g: Grid,
    kern: _Kernel,
    active: AnyArray,
    windows: tuple[AnyArray, AnyArray, int, int],
    thetas: Array,
    workers: int,
    cache: dict[int, Array] | None = None,
    out: Array | None = None,
) -> tuple[Array, float, float]:
    """One prediction step on a fixed grid: (new belief, round-off clipped, mass lost off the grid).

    Every active source-heading slice is convolved (2-D FFT) with its kernel
    window, the kernels of all destination headings accumulated in the Fourier domain.
    ``thetas`` (nθ,) are the source headings of the belief's slices [rad]. ``cache``
    (a transition's own) keeps each heading's window for the next step with the same kernel.
    ``out``: a C-contiguous array of the belief's shape for the new belief (``belief`` itself
    may be given: it is read before ``out`` is written); default a new array.
    """
    import scipy.fft as sfft  # imported where used: a run without a map never pays its 0.15 s

    ax, ay, wx, wy = windows
    nx, ny, nt = g.nx, g.ny, g.ntheta
    # FFT sizes: linear convolution of every slice with its shifted window, no wrap-around
    sx0, sy0 = min(int(ax.min()), 0), min(int(ay.min()), 0)
    ex, ey = max(int((ax + wx - 1).max()), 0), max(int((ay + wy - 1).max()), 0)
    Px = sfft.next_fast_len(nx + ex - sx0, real=True)
    Py = sfft.next_fast_len(ny + ey - sy0, real=True)
    mass_before = float(belief.sum())
    kernels, dest = _heading_kernels(kern, active, thetas, g.resolution, windows, nt, cache)
    # the spectra of the destination headings that receive mass, accumulated over the sources
    touched = np.unique(dest)
    row = np.zeros(nt, dtype=np.int64)
    row[touched] = np.arange(touched.size)
    dest = row[dest]
    acc = np.zeros((touched.size, Px, Py // 2 + 1), dtype=np.complex128)
    plane, m = Px * (Py // 2 + 1), kernels.shape[1]
    per_heading = 16 * ((m + 1) * plane + m * wx * Py)  # the spectra and the row transforms
    batch = max(1, _SPECTRA_BATCH_BYTES // per_heading)
    for a in range(0, active.size, batch):
        b = min(active.size, a + batch)
        # offsets of the windows in the padded plane
        offsets = (ax[active[a:b]] - sx0, ay[active[a:b]] - sy0)
        khat = _kernel_spectra(kernels[a:b], offsets, (Px, Py), workers)
        khat *= sfft.rfftn(np.moveaxis(belief[:, :, active[a:b]], 2, 0), s=(Px, Py), axes=(1, 2),
                           workers=workers)[:, None]  # fmt: skip
        for i in range(b - a):  # in the order of the headings: the sums do not depend on the batches
            d = dest[a + i]
            if d[-1] - d[0] == m - 1:  # consecutive rows
                acc[d[0] : d[-1] + 1] += khat[i]
            else:
                acc[d] += khat[i]
    planes = sfft.irfft2(acc, s=(Px, Py), workers=workers, overwrite_x=True)[:, -sx0 : -sx0 + nx, -sy0 : -sy0 + ny]
    new, roundoff = _heading_noise(planes, touched, kern, np.empty((nx, ny, nt)) if out is None else out, workers)
    lost_step = max(0.0, mass_before - float(new.sum()))
    return new, roundoff, lost_step


#: Bytes of the FFT buffers of one batch of source headings in :func:`_convolve_step` (a batch
#: shares the FFT calls; its size changes no value).
_SPECTRA_BATCH_BYTES = 1 << 20


def _heading_kernels(
    kern: _Kernel,
    active: AnyArray,
    thetas: Array,
    h: float,
    windows: tuple[AnyArray, AnyArray, int, int],
    nt: int,
    cache: dict[int, Array] | None,
) -> tuple[Array, AnyArray]:
    """Kernels of the active source headings by destination: (K, M, wx, wy), and their destinations (K, M).

    ``M`` is the kernel's number of heading offsets, or ``nθ`` when they wrap round the
    circle (then folded onto the ``nθ`` shifts). Windows missing from ``cache`` are
    built (:func:`_source_windows`) and stored in it.
    """
    m_lo_p, mp = kern.head_m_lo, kern.head_mp
    cache = {} if cache is None else cache
    missing = np.array([k for k in active if int(k) not in cache], dtype=np.int64)
    if missing.size:
        cache.update(zip(missing.tolist(), _source_windows(kern, missing, thetas, h, windows), strict=True))
    win = np.stack([cache[int(k)] for k in active])
    if mp > nt:  # heading offsets wrap round the circle: fold them onto nθ shifts
        folded = np.zeros((*win.shape[:3], nt))
        for j in range(mp):
            folded[..., (m_lo_p + j) % nt] += win[..., j]
        return np.moveaxis(folded, 3, 1), (active[:, None] + np.arange(nt)) % nt
    return np.moveaxis(win, 3, 1), (active[:, None] + m_lo_p + np.arange(mp)) % nt


def _kernel_spectra(
    kernels: Array, offsets: tuple[AnyArray, AnyArray], shape: tuple[int, int], workers: int
) -> Array:
    """2-D real FFT of each kernel window placed at its offset in a zero plane of ``shape``.

    ``kernels`` (K, M, wx, wy), ``offsets`` (K,) each [cells]; returns (K, M, Px, Py//2+1).
    Two passes, so that the rows outside the windows are never transformed.
    """
    import scipy.fft as sfft  # imported where used: a run without a map never pays its 0.15 s

    n_k, m, wx, wy = kernels.shape
    Px, Py = shape
    rows = np.zeros((n_k, m, wx, Py))
    for i, oy_ in enumerate(offsets[1]):
        rows[i, :, :, oy_ : oy_ + wy] = kernels[i]
    khat_y = sfft.rfft(rows, axis=3, workers=workers)
    cols = np.zeros((n_k, m, Px, Py // 2 + 1), dtype=np.complex128)
    for i, ox_ in enumerate(offsets[0]):
        cols[i, :, ox_ : ox_ + wx] = khat_y[i]
    return np.asarray(sfft.fft(cols, axis=2, workers=workers, overwrite_x=True))


@dataclass(frozen=True, eq=False)
class GridTransition:
    """The transition of one motion step on the cells of one grid (build with :func:`grid_transition`).

    Attributes
    ----------
    grid : Grid — the grid it was built for (cell sizes and headings must match at use)
    heading_variance_mismatch : float [rad²] — see :func:`multi_step_map`
    """

    grid: Grid
    kernel: _Kernel
    windows: tuple[AnyArray, AnyArray, int, int]
    #: each source heading's kernel window, filled at first use (a transition reused, e.g. the
    #: histogram filter's cached one for a repeated control, skips recomputing them)
    source_windows: dict[int, Array] = field(default_factory=dict, repr=False)

    @property
    def heading_variance_mismatch(self) -> float:
        """Discrete − continuous heading variance of the step [rad²]."""
        return float(self.kernel.heading_variance_mismatch)


def grid_transition(
    model: str,
    grid: Grid,
    control: ArrayLike | None = None,
    dt: float = 1.0,
    alphas: ArrayLike | None = None,
    *,
    odometry: ArrayLike | None = None,
    noise: str = "normal",
    scaling: str = "squared",
    n_nodes_max: int = 1500,
    diffusion_compensation: bool = True,
) -> GridTransition:
    """The kernel of one step of :func:`multi_step_map` on ``grid``, for :func:`predict_on_grid`.

    Parameters
    ----------
    model : {"velocity", "odometry"}
    grid : Grid
    control : array_like, shape (2,) — ``(V, ω)`` [m/s, rad/s] (velocity model)
    dt : float [s], > 0 (velocity model)
    alphas : array_like, shape (6,) or (4,), >= 0 — default 0.05 each
    odometry : array_like, shape (2, 3) — odometry poses ``(x̄, x̄')`` (odometry model)
    noise, scaling, n_nodes_max, diffusion_compensation : as :func:`multi_step_map`
    """
    check_choice("model", model, MODELS)
    n_alpha = 6 if model == "velocity" else 4
    a = _noise_args(model, noise, scaling, np.full(n_alpha, 0.05) if alphas is None else alphas)
    step_dt = float(check_positive("dt", dt))
    if model == "velocity":
        if control is None:
            raise ValueError("control must be given for the velocity model (allowed: (V, omega)), got None")
        u = check_finite("control", control)
        if u.shape != (2,):
            raise ValueError(f"control must have shape (2,) (allowed: (V, omega)), got shape {u.shape}")
        stp = _make_step(model, u, step_dt, a, noise, scaling, True, None, None)
    else:
        od = check_finite("odometry", np.zeros((0,)) if odometry is None else odometry)
        if od.shape != (2, 3):
            raise ValueError(f"odometry must have shape (2, 3) (allowed: two poses), got shape {od.shape}")
        stp = _make_step(model, None, step_dt, a, noise, scaling, True, None, (od[0], od[1]))
    kern = _quadrature_kernel(stp, grid.resolution, grid.theta_resolution, n_nodes_max,
                              diffusion_compensation)  # fmt: skip
    return GridTransition(grid, kern, _kernel_windows(kern, grid.theta, grid.resolution))


def predict_on_grid(
    belief: ArrayLike, transition: GridTransition, workers: int | None = None, *, overwrite_belief: bool = False
) -> tuple[Array, dict[str, float]]:
    """One histogram-filter prediction step on a fixed grid (the step of :func:`multi_step_map`).

    Parameters
    ----------
    belief : array_like, shape (nx, ny, nθ) — probability mass per cell of ``transition.grid``
    transition : GridTransition
    workers : int, optional — FFT threads (default: :func:`~pose_uncertainty.core.threads.default_workers`;
        the result does not depend on it)
    overwrite_belief : bool — ``belief`` (a float64 array the caller no longer needs) may be
        overwritten: its negligible heading slices zeroed in place, and the new belief
        written into it (then returned) instead of into a new array

    Returns
    -------
    belief' : ndarray, shape (nx, ny, nθ) — sums to ``Σ belief − lost_mass``
    info : dict — ``lost_mass`` (left the grid, including negligible heading slices
        dropped), ``roundoff`` (negative round-off clipped), ``negligible_slices``
    """
    g = transition.grid
    b = check_nonnegative("belief", belief)
    if b.shape != g.shape:
        raise ValueError(f"belief must have the grid's shape {g.shape}, got shape {b.shape}")
    own = overwrite_belief or not b.flags.c_contiguous  # (a C-ordered copy is ours; sums run in C order)
    workers = default_workers() if workers is None else workers
    b, dropped, active = _drop_negligible_slices(np.ascontiguousarray(b), copy=not own)
    if active.size == 0:
        return np.zeros(g.shape), {"lost_mass": dropped, "roundoff": 0.0, "negligible_slices": dropped}
    new, roundoff, lost = _convolve_step(
        b, g, transition.kernel, active, transition.windows, g.theta, workers, transition.source_windows,
        b if own else None,
    )  # fmt: skip
    return new, {"lost_mass": lost + dropped, "roundoff": roundoff, "negligible_slices": dropped}


def multi_step_map(
    model: str,
    controls: Any,
    dt: ArrayLike | None = None,
    alphas: ArrayLike | None = None,
    start: ArrayLike | None = None,
    grid: Grid | None = None,
    noise: str = "normal",
    scaling: str = "squared",
    odometry: ArrayLike | None = None,
    *,
    resolution: float = 0.01,
    theta_resolution: float = math.radians(2.0),
    oversample: int = 1,
    max_cells: int = 20_000_000,
    n_nodes_max: int = 1500,
    diffusion_compensation: bool = True,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> ProbabilityMap:
    """Histogram-filter prediction of the pose distribution along a whole trajectory.

    Every step convolves each source-heading slice of the belief with that
    heading's transition kernel (2-D FFT, kernels of all destination headings
    accumulated in the Fourier domain): ``O(n_θ · (M+2) · P² log P)`` per step
    for ``P²`` padded cells and ``M`` destination heading offsets, instead of the
    ``O(n⁶)`` sum over all pairs of cells.

    The kernel of a step is the push-forward of the control noise, computed by
    quadrature: the noise of ``(V̂, ω̂)`` (velocity) or ``(δrot1, δtrans)``
    (odometry) on nodes spaced at most a quarter cell apart in pose space, each
    node carrying the exact probability of its control interval, moved by the
    model's kinematics and deposited on the grid by exact overlap of its little
    interval with the cells (a kernel narrower than half a cell on an axis keeps
    its mean by a linear split instead; see ``_axis_parts``); the heading-only
    noise (``γΔt`` or ``δrot2``) is a 1-D circular convolution along θ whose
    width is moment-matched so that the step's heading variance is exact. The
    source mass of a cell sits at its centre. This is the sampler of the same
    model made deterministic, so the map converges to the Monte Carlo histogram
    as the cells shrink; the price of the grid is that the position of the mass
    inside a cell is forgotten at every step (a diffusion of order h²/12 per axis
    per step, noticeable for distributions thinner than a cell — use
    ``oversample``).

    Parameters
    ----------
    model : {"velocity", "odometry"}
    controls : array_like, shape (N, 2), or a Trajectory
        ``(V, ω)`` per step [m/s, rad/s]. A ``Trajectory`` (anything with
        ``.controls``, ``.dt`` and ``.start``) supplies ``controls``, ``dt`` and the start.
        For the odometry model ``controls`` may be None when ``odometry`` is given.
    dt : float or array_like, shape (N,) [s]
    alphas : array_like, shape (6,) velocity or (4,) odometry, >= 0, optional
        Default: the thesis's 0.05 for every constant.
    start : array_like, shape (3,), optional
        Known start pose (default the trajectory's start, else (0, 0, 0)).
    grid : Grid, optional
        Fixed grid (must contain the start); mass leaving it is counted in
        ``lost_mass``. Default: a grid of ``resolution`` × ``theta_resolution`` that
        starts at the start cell and grows to hold the spread (up to ``max_cells``
        cells in total; beyond that mass is lost and counted).
    noise : {"normal", "triangular"}
    scaling : {"squared", "abs"}
    odometry : array_like, shape (N+1, 3), optional
        Odometry model: noiseless odometry poses; step ``i`` is ``odometry[i] → odometry[i+1]``.
        Default: the noiseless poses of the velocity model along ``controls`` (as Němec 2012).
    resolution, theta_resolution : float [m, rad], > 0
        Cell size of the automatic grid.
    oversample : int, >= 1
        Automatic grid only: compute on cells ``oversample`` times smaller in x and y
        and sum them into cells of ``resolution`` at the end (odd values keep the
        start at a cell centre). The histogram filter forgets where in its cell the
        mass sits at every step; finer cells make that diffusion smaller (it matters
        for distributions thinner than a cell, e.g. rotation in place).
    max_cells : int
        Cap on ``nx·ny·nθ`` of the growing grid.
    n_nodes_max : int
        Cap on the quadrature nodes per control axis.
    diffusion_compensation : bool
        Moment-match the heading: choose the width of the heading-only noise so that
        each step's discrete kernel has the heading variance of the continuous one
        (the cell integration otherwise adds ``h_θ²/12``, Sheppard, per step, and a
        split mean ``frac(1−frac)·h_θ²``, and they accumulate). Default on; the
        remainder that cannot be matched is ``info["heading_variance_mismatch_total"]``.
        Off: every step's kernel is the cell integral of that step's density.
    workers : int, optional
        FFT threads (``scipy.fft``; default :func:`~pose_uncertainty.core.threads.default_workers`);
        results do not depend on it.
    progress : callable, optional
        ``progress(done, N)`` after each step (default None: nothing).

    Returns
    -------
    ProbabilityMap
        ``values.sum() + lost_mass == 1`` (to round-off). ``info`` holds
        ``lost_per_step``, ``grid_growths``, ``roundoff`` and the final grid.
    """
    check_choice("model", model, MODELS)
    over = check_positive_int("oversample", oversample)
    if over > 1:
        if grid is not None:
            raise ValueError(
                f"oversample must be 1 with a fixed grid (allowed: 1), got {over}"
            )
        fine = multi_step_map(
            model, controls, dt, alphas, start, None, noise, scaling, odometry,
            resolution=float(check_positive("resolution", resolution)) / over,
            theta_resolution=theta_resolution, oversample=1, max_cells=max_cells * over * over,
            n_nodes_max=n_nodes_max, diffusion_compensation=diffusion_compensation,
            workers=workers, progress=progress,
        )  # fmt: skip
        return _coarsen(fine, over)
    x0, a, u, dts, od = _normalise_path(model, controls, dt, alphas, start, noise, scaling, odometry)
    max_cells = check_positive_int("max_cells", max_cells)
    steps = _path_steps(model, u, dts, a, noise, scaling, od)
    g, grow = _start_grid(grid, x0, resolution, theta_resolution)
    belief, g, lost_total, diagnostics = _predict_path(
        steps, g, grow, x0, max_cells, n_nodes_max, diffusion_compensation,
        default_workers() if workers is None else workers, progress,
    )  # fmt: skip
    info = {
        **diagnostics,
        "n_steps": len(steps),
        "start": x0.tolist(),
        "noise": noise,
        "scaling": scaling,
        "method": "histogram filter, quadrature kernels, FFT per source heading",
    }
    return ProbabilityMap(g.x, g.y, g.theta, belief, max(0.0, float(lost_total)), model, g, info)


def _normalise_path(
    model: str,
    controls: Any,
    dt: ArrayLike | None,
    alphas: ArrayLike | None,
    start: ArrayLike | None,
    noise: str,
    scaling: str,
    odometry: ArrayLike | None,
) -> tuple[Array, Array, Array | None, Array, Array | None]:
    """Check the path inputs of :func:`multi_step_map`.

    Returns
    -------
    x0 : (3,) start pose; alphas : (6,) or (4,); u : (N, 2) controls or None
    (odometry given instead); dts : (N,) step durations [s]; od : (N+1, 3)
    odometry poses of the odometry model, None for the velocity model
    """
    controls, dt, start = _unpack_trajectory(controls, dt, start)
    x0 = check_finite("start", (0.0, 0.0, 0.0) if start is None else start)
    if x0.shape != (3,):
        raise ValueError(f"start must have shape (3,), got shape {x0.shape}")
    check_noise(noise)
    check_scaling(scaling)
    n_alpha = 6 if model == "velocity" else 4
    a = check_alphas(np.full(n_alpha, 0.05) if alphas is None else alphas, n_alpha)
    u, n_steps = _check_controls(model, controls, odometry)
    dts = _check_step_durations(model, dt, odometry, n_steps)
    od = _odometry_path(model, odometry, x0, u, dts, n_steps)
    return x0, a, u, dts, od


def _unpack_trajectory(controls: Any, dt: Any, start: Any) -> tuple[Any, Any, Any]:
    """``(controls, dt, start)`` of a Trajectory-like ``controls``; other inputs unchanged.

    An explicit ``dt`` or ``start`` wins over the trajectory's.
    """
    if controls is not None and hasattr(controls, "controls") and hasattr(controls, "dt"):
        traj = controls
        controls = np.asarray(traj.controls, dtype=np.float64)
        dt = traj.dt if dt is None else dt
        if start is None and hasattr(traj, "start"):
            start = traj.start
    return controls, dt, start


def _check_controls(model: str, controls: Any, odometry: ArrayLike | None) -> tuple[Array | None, int]:
    """Controls (N, 2) — None when the odometry model is given only its poses — and N."""
    if controls is not None:
        u = check_finite("controls", check_last_axis("controls", controls, 2))
        if u.ndim != 2 or u.shape[0] < 1:
            raise ValueError(f"controls must have shape (N, 2) with N >= 1, got shape {u.shape}")
        return u, u.shape[0]
    if model == "odometry" and odometry is not None:
        return None, int(np.shape(odometry)[0]) - 1
    raise ValueError("controls must be given (allowed: array of shape (N, 2) or a Trajectory), got None")


def _check_step_durations(
    model: str, dt: ArrayLike | None, odometry: ArrayLike | None, n_steps: int
) -> Array:
    """Step durations (N,) [s]; the odometry model given its poses needs none (1 s each)."""
    if dt is None:
        if model == "velocity" or odometry is None:
            raise ValueError("dt must be given (allowed: > 0), got None")
        dt = 1.0
    dts = check_positive("dt", dt)
    dts = np.full(n_steps, float(dts)) if dts.ndim == 0 else dts
    if dts.shape != (n_steps,):
        raise ValueError(f"dt must be a scalar or have shape ({n_steps},), got shape {dts.shape}")
    return dts


def _odometry_path(
    model: str, odometry: ArrayLike | None, x0: Array, u: Array | None, dts: Array, n_steps: int
) -> Array | None:
    """Odometry poses (N+1, 3) of the odometry model; None for the velocity model.

    Given, or the noiseless velocity poses along ``u`` (as Němec 2012).
    """
    if model != "odometry":
        return None
    if odometry is None:
        assert u is not None
        return noiseless_velocity_poses(x0, u, dts)
    od = check_finite("odometry", check_last_axis("odometry", odometry, 3))
    if od.shape != (n_steps + 1, 3):
        raise ValueError(
            f"odometry must have shape (N+1, 3) = ({n_steps + 1}, 3), got shape {od.shape}"
        )
    return od


def _path_steps(
    model: str, u: Array | None, dts: Array, alphas: Array, noise: str, scaling: str, od: Array | None
) -> list[_Step]:
    """One corrected-density :class:`_Step` per control (velocity) or odometry pair (odometry)."""
    return [
        _make_step(
            model,
            None if u is None else u[i],
            float(dts[i]),
            alphas,
            noise,
            scaling,
            True,
            None,
            None if od is None else (od[i], od[i + 1]),
        )
        for i in range(dts.shape[0])
    ]


def _start_grid(
    grid: Grid | None, x0: Array, resolution: float, theta_resolution: float
) -> tuple[Grid, bool]:
    """The grid to start on and whether it grows.

    The fixed ``grid`` (which must hold the start), or a growing grid of one cell
    centred on the start.
    """
    if grid is not None:
        if not grid.contains(x0):
            xa, xb, ya, yb = grid.extent()
            raise ValueError(
                f"start must lie inside the grid (allowed: x in [{xa:g}, {xb:g}), "
                f"y in [{ya:g}, {yb:g})), got ({x0[0]:g}, {x0[1]:g})"
            )
        return grid, False
    h_ = float(check_positive("resolution", resolution))
    htr = float(check_positive("theta_resolution", theta_resolution))
    nt = max(1, math.ceil(2.0 * math.pi / htr - 1e-9))
    return Grid.square(float(x0[0]), float(x0[1]), 1, 1, h_, nt, float(x0[2])), True


def _predict_path(
    steps: list[_Step],
    g: Grid,
    grow: bool,
    x0: Array,
    max_cells: int,
    n_nodes_max: int,
    compensate: bool,
    workers: int,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[Array, Grid, float, dict[str, Any]]:
    """The histogram filter's prediction along ``steps`` from a Dirac at ``x0`` (``progress(done, N)``).

    Per step: build the kernel, drop negligible heading slices, grow the grid (if
    ``grow``) to hold the support plus the kernel's reach, take the step.

    Returns
    -------
    belief : (nx, ny, nθ) on the final grid; g : the final grid; lost : mass
    lost in total; diagnostics : ``lost_per_step``, ``grid_growths``,
    ``roundoff``, ``negligible_slices``, ``heading_variance_mismatch_total``
    """
    h, ht, nt = g.resolution, g.theta_resolution, g.ntheta
    belief = np.zeros(g.shape)
    _deposit(belief, g, x0)
    lost_total = 1.0 - float(belief.sum())  # nonzero only if the start is on the grid's edge
    max_side = max(1, math.isqrt(max_cells // nt))
    lost_per_step: list[float] = []
    growths = 0
    mismatch: list[float] = []
    roundoff = 0.0
    negligible = 0.0
    thetas = g.theta
    for i_step, stp in enumerate(steps):
        if progress is not None and i_step:
            progress(i_step, len(steps))
        kern = _quadrature_kernel(stp, h, ht, n_nodes_max, compensate)
        windows = _kernel_windows(kern, thetas, h)
        mismatch.append(kern.heading_variance_mismatch)
        # heading slices holding less than 1e-14 are not propagated: their mass is
        # counted as lost (reported as ``negligible_slices`` in ``info``)
        belief, dropped, active = _drop_negligible_slices(belief)
        negligible += dropped
        lost_total += dropped
        if grow and active.size:
            grown = _grow_grid(belief, g, x0, active, windows, max_side)
            if grown is not None:
                belief, g, cut = grown
                lost_total += cut
                growths += 1
        # ``thetas`` are the headings of the first grid: a grown grid re-normalises theta0,
        # which can relabel the slices by one cell (see core.grids.Grid); the kernels keep the first
        belief, step_roundoff, lost_step = _convolve_step(
            belief, g, kern, active, windows, thetas, workers, out=belief
        )
        roundoff += step_roundoff
        lost_per_step.append(lost_step)
        lost_total += lost_step
    if progress is not None:
        progress(len(steps), len(steps))
    diagnostics = {
        "lost_per_step": lost_per_step,
        "grid_growths": growths,
        "roundoff": roundoff,
        "negligible_slices": negligible,
        "heading_variance_mismatch_total": float(np.sum(mismatch)),
    }
    return belief, g, lost_total, diagnostics


def _needed_bounds(
    belief: Array, g: Grid, x0: Array, active: AnyArray, windows: tuple[AnyArray, AnyArray, int, int]
) -> tuple[tuple[int, int], tuple[int, int], tuple[int, int], tuple[int, int]]:
    """Cell-index bounds (inclusive, from the start cell) of the grid and of what the step needs.

    Returns ``(cur_lo, cur_hi, need_lo, need_hi)``: the grid's, and the belief's
    support (active heading slices) widened by the kernel windows of those headings.
    """
    ax, ay, wx, wy = windows
    h = g.resolution
    thr = 1e-14 * float(belief.max())
    sx = np.flatnonzero((belief[:, :, active] > thr).any(axis=(1, 2)))
    sy = np.flatnonzero((belief[:, :, active] > thr).any(axis=(0, 2)))
    ix0 = round((g.x0 - x0[0]) / h)
    iy0 = round((g.y0 - x0[1]) / h)
    need_lo = (ix0 + int(sx[0]) + int(ax[active].min()), iy0 + int(sy[0]) + int(ay[active].min()))
    need_hi = (
        ix0 + int(sx[-1]) + int((ax[active] + wx - 1).max()),
        iy0 + int(sy[-1]) + int((ay[active] + wy - 1).max()),
    )
    return (ix0, iy0), (ix0 + g.nx - 1, iy0 + g.ny - 1), need_lo, need_hi


def _grow_grid(
    belief: Array,
    g: Grid,
    x0: Array,
    active: AnyArray,
    windows: tuple[AnyArray, AnyArray, int, int],
    max_side: int,
) -> tuple[Array, Grid, float] | None:
    """Grow the grid to hold what the step needs (:func:`_needed_bounds`), ≤ ``max_side`` a side.

    Returns (belief copied onto the new grid, the new grid, mass cut off by
    the cap), or None when the grid already holds it.
    """
    cur_lo, cur_hi, need_lo, need_hi = _needed_bounds(belief, g, x0, active, windows)
    if not any(need_lo[i] < cur_lo[i] or need_hi[i] > cur_hi[i] for i in range(2)):
        return None
    h = g.resolution
    slack = max(4, (windows[2] + windows[3]) // 4)
    new_lo, new_hi = _grow_bounds(cur_lo, cur_hi, need_lo, need_hi, max_side, slack)
    ng = Grid.square(
        float(x0[0]) + new_lo[0] * h, float(x0[1]) + new_lo[1] * h,
        new_hi[0] - new_lo[0] + 1, new_hi[1] - new_lo[1] + 1, h, g.ntheta, g.theta0,
    )  # fmt: skip
    nb = np.zeros(ng.shape)
    # copy the overlap
    ox, oy = cur_lo[0] - new_lo[0], cur_lo[1] - new_lo[1]
    sxa, sxb = max(0, -ox), min(g.nx, ng.nx - ox)
    sya, syb = max(0, -oy), min(g.ny, ng.ny - oy)
    before = float(belief.sum())
    if sxa < sxb and sya < syb:
        nb[sxa + ox : sxb + ox, sya + oy : syb + oy] = belief[sxa:sxb, sya:syb]
    return nb, ng, before - float(nb.sum())
