"""Probability maps from the velocity and odometry motion models (SPEC §3, Method B).

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

Discretisation rules (both maps)
--------------------------------
* Cells are evaluated at their centres; every variance is raised to the
  grid floor of :mod:`pose_uncertainty.motion_models` (``cell_floor`` cells), so a
  degenerate (zero-variance) term spreads over about one cell. A control with
  *all* variances exactly zero is a deterministic move and is deposited
  trilinearly (mean-preserving) instead.
* The corrected densities have an integrable ``1/r`` singularity at the start
  pose (every turn rate reaches it with zero speed). The cell holding the start
  is therefore integrated exactly: in control space, a 1-D quadrature over
  ``ω̂`` (velocity) or ``δ̂rot1`` (odometry) of the CDF of ``V̂`` (``δ̂trans``)
  between the cell walls.
* Headings cover the full circle ``[−π, π)`` in ``n_θ`` cells.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.fft as sfft
from numpy.typing import ArrayLike, NDArray

from .kinematics import wrap_angle
from .motion_models import (
    DEFAULT_CELL_FLOOR,
    check_alphas,
    noiseless_velocity_poses,
    odometry_deltas,
    odometry_density,
    odometry_floors,
    odometry_forward,
    odometry_variances,
    velocity_floors,
    velocity_forward,
    velocity_separable,
    velocity_variances,
)
from .noise import cdf, check_noise, check_scaling, noise_reach, prob
from .validation import (
    check_choice,
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_positive,
    check_positive_int,
    check_probability,
)

__all__ = [
    "MODELS",
    "MULTI_STEP_CELL_FLOOR",
    "MapGrid",
    "ProbabilityMap",
    "hellinger",
    "hellinger_noise_floor",
    "histogram",
    "histogram_xy",
    "multi_step_map",
    "single_step_map",
]

MODELS: tuple[str, ...] = ("velocity", "odometry")
#: Grid floor (cells) of the multi-step kernels: a kernel at least half a cell wide keeps
#: the mean of a sub-cell step (point sampling of a narrower one is biased to cell centres).
MULTI_STEP_CELL_FLOOR: float = 0.5

Array = NDArray[np.float64]


# ============================================================================= grid


@dataclass(frozen=True)
class MapGrid:
    """A regular ``(x, y, θ)`` grid: square cells of ``resolution`` [m], headings on the full circle.

    Attributes
    ----------
    x0, y0 : float [m]
        Centre of the first cell along x and y.
    nx, ny : int
        Number of cells along x and y.
    resolution : float [m], > 0
        Cell side.
    ntheta : int
        Number of heading cells; their width is ``2π/ntheta``.
    theta0 : float [rad]
        Centre of the first heading cell, in ``[−π, −π + 2π/ntheta)``.
    """

    x0: float
    y0: float
    nx: int
    ny: int
    resolution: float
    ntheta: int
    theta0: float = -math.pi

    def __post_init__(self) -> None:
        object.__setattr__(self, "resolution", float(check_positive("resolution", self.resolution)))
        object.__setattr__(self, "nx", check_positive_int("nx", self.nx))
        object.__setattr__(self, "ny", check_positive_int("ny", self.ny))
        object.__setattr__(self, "ntheta", check_positive_int("ntheta", self.ntheta))
        x0 = float(check_finite("x0", self.x0))
        y0 = float(check_finite("y0", self.y0))
        ht = 2.0 * math.pi / self.ntheta
        t0 = float(check_finite("theta0", self.theta0))
        t0 = -math.pi + math.fmod(math.fmod(t0 + math.pi, ht) + ht, ht)
        object.__setattr__(self, "x0", x0)
        object.__setattr__(self, "y0", y0)
        object.__setattr__(self, "theta0", t0)

    @classmethod
    def centered(
        cls,
        center: ArrayLike = (0.0, 0.0, 0.0),
        size: float = 1.0,
        resolution: float = 0.01,
        theta_resolution: float = math.radians(2.0),
    ) -> MapGrid:
        """Square grid of side about ``size`` [m] whose middle cell is centred on ``center``.

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
        return cls(float(c[0]) - half, float(c[1]) - half, n, n, h, nt, float(c[2]))

    @property
    def theta_resolution(self) -> float:
        """Heading cell width [rad]."""
        return 2.0 * math.pi / self.ntheta

    @property
    def x(self) -> Array:
        """Cell-centre x, shape (nx,) [m]."""
        return self.x0 + self.resolution * np.arange(self.nx)

    @property
    def y(self) -> Array:
        """Cell-centre y, shape (ny,) [m]."""
        return self.y0 + self.resolution * np.arange(self.ny)

    @property
    def theta(self) -> Array:
        """Cell-centre heading, shape (ntheta,) [rad], ascending in ``[−π, π)``."""
        return self.theta0 + self.theta_resolution * np.arange(self.ntheta)

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(nx, ny, ntheta)``."""
        return self.nx, self.ny, self.ntheta

    @property
    def cell_volume(self) -> float:
        """``h² · h_θ`` [m²·rad]."""
        return self.resolution**2 * self.theta_resolution

    def contains(self, pose: ArrayLike) -> bool:
        """Whether the position of ``pose`` (shape (3,) or (2,)) lies inside the grid's cells."""
        p = np.asarray(pose, dtype=np.float64)
        h = self.resolution
        return bool(
            self.x0 - h / 2 <= p[0] < self.x0 + (self.nx - 0.5) * h
            and self.y0 - h / 2 <= p[1] < self.y0 + (self.ny - 0.5) * h
        )

    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the cell walls [m]."""
        h = self.resolution
        return (
            self.x0 - h / 2,
            self.x0 + (self.nx - 0.5) * h,
            self.y0 - h / 2,
            self.y0 + (self.ny - 0.5) * h,
        )


# ============================================================================= map


@dataclass(frozen=True)
class ProbabilityMap:
    """Probability mass per cell of an ``(x, y, θ)`` grid.

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
    grid : MapGrid, optional
        The grid the map lives on.
    info : dict
        Diagnostics (kernel sums, grid growth, settings).
    """

    x: Array
    y: Array
    theta: Array
    values: Array
    lost_mass: float
    model: str
    grid: MapGrid | None = None
    info: dict[str, Any] = field(default_factory=dict)

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

    def credible_area(self, pr: float) -> float:
        """Area [m²] of the smallest set of ``(x, y)`` cells holding probability ``pr``.

        Cells of the θ-marginal are taken from the most probable down; the last
        cell counts in proportion to the mass still needed. ``pr`` is a fraction
        of the whole distribution (lost mass included).

        Raises
        ------
        ValueError
            If ``pr`` is not in (0, 1) or the grid holds less than ``pr``.
        """
        p = float(check_probability("pr", pr))
        m = np.sort(self.marginal_xy().ravel())[::-1]
        c = np.cumsum(m)
        if c[-1] < p:
            raise ValueError(
                f"pr must not exceed the mass held by the grid (allowed: (0, {c[-1]:.6g}]), got {p}"
            )
        k = int(np.searchsorted(c, p))
        before = c[k - 1] if k > 0 else 0.0
        frac = (p - before) / m[k] if m[k] > 0 else 1.0
        return (k + frac) * self.resolution**2

    def _weights(self) -> Array:
        v = self.values
        return v / v.sum()

    def mean(self) -> Array:
        """Mean ``(x, y, θ)`` of the in-grid mass (θ: circular mean), shape (3,)."""
        w = self._weights()
        wx, wy, wt = w.sum(axis=(1, 2)), w.sum(axis=(0, 2)), w.sum(axis=(0, 1))
        th = math.atan2(float(wt @ np.sin(self.theta)), float(wt @ np.cos(self.theta)))
        return np.array([float(wx @ self.x), float(wy @ self.y), th])

    def cov(self) -> Array:
        """Covariance of ``(x, y, θ)`` over the in-grid mass, shape (3, 3).

        θ deviations are wrapped around the circular mean. Moments use cell
        centres (no Sheppard correction: a continuous density's variance is
        about ``h²/12`` smaller per axis).
        """
        w = self._weights()
        mu = self.mean()
        dx = (self.x - mu[0])[:, None, None]
        dy = (self.y - mu[1])[None, :, None]
        dt = wrap_angle(self.theta - mu[2])[None, None, :]
        d = [dx, dy, dt]
        out = np.empty((3, 3))
        for a in range(3):
            for b in range(a, 3):
                out[a, b] = out[b, a] = float(np.sum(w * d[a] * d[b]))
        return out


# ============================================================================= helpers


def hellinger(p: ArrayLike, q: ArrayLike) -> float:
    """Hellinger distance ``√(1 − Σ √(p̃ q̃))`` between two arrays of the same shape.

    Both are normalised to sum 1 first (so maps with lost mass compare by shape).
    0 for identical distributions, 1 for disjoint supports.
    """
    a = check_nonnegative("p", p)
    b = check_nonnegative("q", q)
    if a.shape != b.shape:
        raise ValueError(f"p and q must have the same shape, got {a.shape} and {b.shape}")
    sa, sb = a.sum(), b.sum()
    if sa <= 0 or sb <= 0:
        raise ValueError(f"p and q must have positive total mass, got {sa} and {sb}")
    bc = float(np.sum(np.sqrt(a / sa * (b / sb))))
    return math.sqrt(max(0.0, 1.0 - bc))


def hellinger_noise_floor(p: ArrayLike, n: int) -> float:
    """Expected Hellinger distance between ``p`` and a histogram of ``n`` samples drawn from it.

    With ``X_i ~ Poisson(λ_i = n p_i)``: ``E[H²] = ½ Σ E[(√(X_i/n) − √p_i)²]
    = Σ (λ_i − √λ_i E√X_i)/n``; ``E√X`` by direct summation for ``λ ≤ 50`` and
    by its asymptotic series above. Returns ``√E[H²]``. A map that is the exact
    density of the sampler sits at this value; anything above it is model or
    discretisation error.
    """
    w = check_nonnegative("p", p).ravel()
    n = check_positive_int("n", n)
    w = w / w.sum()
    lam = n * w[w > 0]
    small = lam <= 50.0
    e_sqrt = np.empty_like(lam)
    big = lam[~small]
    e_sqrt[~small] = np.sqrt(big) * (1 - 1 / (8 * big) - 7 / (128 * big**2))
    if np.any(small):
        ls = lam[small][:, None]
        k = np.arange(0, 151)[None, :]
        from scipy.special import gammaln

        logpmf = k * np.log(ls) - ls - gammaln(k + 1)
        e_sqrt[small] = np.sum(np.sqrt(k) * np.exp(logpmf), axis=1)
    eh2 = float(np.sum(lam - np.sqrt(lam) * e_sqrt)) / n
    return math.sqrt(max(0.0, eh2))


def _cell_index(values: Array, origin: float, h: float, n: int) -> tuple[Array, Array]:
    idx = np.floor((values - origin) / h + 0.5).astype(np.int64)
    ok = (idx >= 0) & (idx < n)
    return idx, ok


def histogram_xy(samples: ArrayLike, grid: MapGrid) -> Array:
    """Fraction of ``samples`` (shape (n, 2+)) in each ``(x, y)`` cell, shape (nx, ny).

    Samples outside the grid are not counted, so the sum is the fraction inside.
    """
    s = check_finite("samples", samples)
    if s.ndim != 2 or s.shape[1] < 2:
        raise ValueError(f"samples must have shape (n, 2) or (n, 3), got shape {s.shape}")
    ix, okx = _cell_index(s[:, 0], grid.x0, grid.resolution, grid.nx)
    iy, oky = _cell_index(s[:, 1], grid.y0, grid.resolution, grid.ny)
    ok = okx & oky
    flat = np.bincount(ix[ok] * grid.ny + iy[ok], minlength=grid.nx * grid.ny)
    return flat.reshape(grid.nx, grid.ny) / s.shape[0]


def histogram(samples: ArrayLike, grid: MapGrid) -> Array:
    """Fraction of pose samples (shape (n, 3)) in each ``(x, y, θ)`` cell, shape (nx, ny, nθ).

    Headings are wrapped onto the grid's circle.
    """
    s = check_finite("samples", check_last_axis("samples", samples, 3))
    s = s.reshape(-1, 3)
    ix, okx = _cell_index(s[:, 0], grid.x0, grid.resolution, grid.nx)
    iy, oky = _cell_index(s[:, 1], grid.y0, grid.resolution, grid.ny)
    it = np.mod(
        np.floor((s[:, 2] - grid.theta0) / grid.theta_resolution + 0.5).astype(np.int64),
        grid.ntheta,
    )
    ok = okx & oky
    flat = np.bincount(
        (ix[ok] * grid.ny + iy[ok]) * grid.ntheta + it[ok], minlength=int(np.prod(grid.shape))
    )
    return flat.reshape(grid.shape) / s.shape[0]


def _ray_to_walls(beta: Array, s: Array, lo: Array, hi: Array) -> Array:
    """Distance from point ``s`` (inside the box [lo, hi]) along direction ``beta`` to the box wall."""
    c, sn = np.cos(beta), np.sin(beta)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (hi[0] - s[0]) / np.where(c > 0, c, 1.0), np.inf)
        tx = np.where(c < 0, (lo[0] - s[0]) / np.where(c < 0, c, -1.0), tx)
        ty = np.where(sn > 0, (hi[1] - s[1]) / np.where(sn > 0, sn, 1.0), np.inf)
        ty = np.where(sn < 0, (lo[1] - s[1]) / np.where(sn < 0, sn, -1.0), ty)
    return np.minimum(tx, ty)


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
        self, xy: Array, theta_dst: Array, start: Array, cell: tuple[float, float], floor: float
    ) -> Array:
        """Density at positions ``xy`` (..., 2) × headings ``theta_dst`` (M,) → (..., M)."""
        if self.model == "velocity":
            p_xy, phi, v3 = velocity_separable(
                xy, self.u, start, self.dt, self.alphas, self.noise, self.scaling,
                self.corrected, cell, floor,
            )  # fmt: skip
            g = wrap_angle(theta_dst - start[2] - phi[..., None]) / self.dt
            return np.asarray(p_xy[..., None] * prob(g, v3[..., None], self.noise))
        assert self.odom is not None
        pos = np.broadcast_to(xy[..., None, :], (*xy.shape[:-1], theta_dst.size, 2))
        th = np.broadcast_to(theta_dst, pos.shape[:-1])[..., None]
        hyp = np.concatenate([pos, th], axis=-1)
        return odometry_density(
            hyp, self.odom[0], self.odom[1], start, self.alphas, self.noise, self.scaling,
            self.corrected, self.variance_from, cell, floor,
        )  # fmt: skip

    def effective_std(self, cell: tuple[float, float], floor: float) -> Array:
        """Standard deviations of the three control noises at the noiseless control, floored."""
        var = self.variances()
        if self.model == "velocity":
            f = velocity_floors(self.u[0], self.u[1], self.dt, cell, floor)
        else:
            f = odometry_floors(self.u[1], cell, floor)
        return np.sqrt(np.maximum(var, [float(x) for x in f]))

    def local_cloud(self, cell: tuple[float, float], floor: float, n: int = 25) -> Array:
        """Local displacements ``(f, l, dθ)`` of a box of controls ±reach·σ, shape (n³, 3)."""
        sd = self.effective_std(cell, floor) * noise_reach(self.noise)
        t = np.linspace(-1.0, 1.0, n)
        a, b, c = np.meshgrid(t, t, t, indexing="ij")
        zero = np.zeros(3)
        if self.model == "velocity":
            V = self.u[0] + sd[0] * a
            w = np.clip(self.u[1] + sd[1] * b, -math.pi / self.dt, math.pi / self.dt)
            g = sd[2] * c
            out = velocity_forward(zero, V.ravel(), w.ravel(), g.ravel(), self.dt)
        else:
            r1 = self.u[0] + sd[0] * a
            tr = self.u[1] + sd[1] * b
            r2 = self.u[2] + sd[2] * c
            out = odometry_forward(zero, r1.ravel(), tr.ravel(), r2.ravel())
        return np.asarray(out)

    def singular_cell(
        self,
        s: Array,
        lo: Array,
        hi: Array,
        start_theta: float,
        theta_dst: Array,
        cell: tuple[float, float],
        floor: float,
        n_nodes: int = 4001,
    ) -> Array:
        """Exact ``∫_cell p(x, y, θ') dx dy`` for the cell [lo, hi] holding the start ``s``.

        Returns shape (M,) [1/rad]. 1-D quadrature (midpoint, ``n_nodes``) over
        ``ω̂`` (velocity) or ``δ̂rot1`` (odometry) of the CDF of ``V̂`` (``δ̂trans``)
        between the cell walls along the ray of motion.
        """
        sd = self.effective_std(cell, floor)
        reach = noise_reach(self.noise)
        if self.model == "velocity":
            var = self.variances()
            dt = self.dt
            w_lo = max(self.u[1] - reach * sd[1], -math.pi / dt)
            w_hi = min(self.u[1] + reach * sd[1], math.pi / dt)
            step = (w_hi - w_lo) / n_nodes
            w = w_lo + step * (np.arange(n_nodes) + 0.5)
            zero = np.zeros_like(w)
            f1, f2, f3 = velocity_floors(zero, w, dt, cell, floor)
            v1, v2, v3 = np.maximum(var[0], f1), np.maximum(var[1], f2), np.maximum(var[2], f3)
            phi = w * dt
            sinc = np.sinc(phi / (2 * math.pi))
            beta = start_theta + phi / 2
            r_fwd = _ray_to_walls(beta, s, lo, hi)
            r_back = _ray_to_walls(beta + math.pi, s, lo, hi)
            pv = cdf(r_fwd / (dt * sinc) - self.u[0], v1, self.noise) - cdf(
                -r_back / (dt * sinc) - self.u[0], v1, self.noise
            )
            pw = prob(self.u[1] - w, v2, self.noise)
            g = wrap_angle(theta_dst[None, :] - start_theta - phi[:, None]) / dt
            pg = prob(g, v3[:, None], self.noise) / dt
            return np.asarray(step * np.sum((pv * pw)[:, None] * pg, axis=0))
        r1u, tru, r2u = self.u
        r_lo, r_hi = r1u - reach * sd[0], r1u + reach * sd[0]
        if r_hi - r_lo > 2 * math.pi:
            r_lo, r_hi = r1u - math.pi, r1u + math.pi
        step = (r_hi - r_lo) / n_nodes
        r1 = r_lo + step * (np.arange(n_nodes) + 0.5)
        r2 = wrap_angle(theta_dst[None, :] - start_theta - r1[:, None])
        if self.variance_from == "hypothesis" or (
            self.variance_from is None and not self.corrected
        ):
            v1, v2, v3 = odometry_variances(r1[:, None], 0.0, r2, self.alphas, self.scaling)
        else:
            var = self.variances()
            v1, v2, v3 = (np.full(r2.shape, var[i]) for i in range(3))
        f1, f2, f3 = odometry_floors(np.zeros(1), cell, floor)
        v1, v2, v3 = np.maximum(v1, f1), np.maximum(v2, f2), np.maximum(v3, f3)
        beta = start_theta + r1
        r_fwd = _ray_to_walls(beta, s, lo, hi)[:, None]
        r_back = _ray_to_walls(beta + math.pi, s, lo, hi)[:, None]
        pt = cdf(tru - (-r_back), v2, self.noise) - cdf(tru - r_fwd, v2, self.noise)
        p1 = prob(wrap_angle(r1u - r1)[:, None], v1, self.noise)
        p3 = prob(wrap_angle(r2u - r2), v3, self.noise)
        return np.asarray(step * np.sum(p1 * pt * p3, axis=0))


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


def _deposit(values: Array, grid: MapGrid, pose: Array, mass: float = 1.0) -> None:
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
    grid: MapGrid | None = None,
    noise: str = "normal",
    scaling: str = "squared",
    corrected: bool = False,
    *,
    odometry: ArrayLike | None = None,
    variance_from: str | None = None,
    cell_floor: float = DEFAULT_CELL_FLOOR,
) -> ProbabilityMap:
    """Map after one motion from a known start (the thesis's ``O(n³)`` case).

    Parameters
    ----------
    model : {"velocity", "odometry"}
    start : array_like, shape (3,)
        Known start pose.
    control : array_like, shape (2,)
        ``(V, ω)`` [m/s, rad/s]. For the odometry model the odometry ``u`` is the
        noiseless velocity motion ``start → end`` (as seed 000), unless ``odometry``
        is given.
    dt : float [s], > 0
    alphas : array_like, shape (6,) velocity or (4,) odometry, >= 0
    grid : MapGrid, optional
        Default :meth:`MapGrid.centered` on the noiseless end pose (1 m × 1 m, 1 cm, 2°).
    noise : {"normal", "triangular"}
    scaling : {"squared", "abs"}
    corrected : bool
        False: Thrun's density normalised to relative probability (``lost_mass = 0``).
        True: pose-space density of the sampler; cell mass ``p·ΔV``, the start cell
        integrated exactly, ``lost_mass = max(0, 1 − Σ)``.
    odometry : array_like, shape (2, 3), optional
        Odometry poses ``(x̄, x̄')`` for the odometry model.
    variance_from : {"hypothesis", "odometry"}, optional
        Odometry model only; see :func:`~pose_uncertainty.motion_models.odometry_density`.
    cell_floor : float
        Variance floor in cells (see module docs).

    Returns
    -------
    ProbabilityMap
    """
    a = _noise_args(model, noise, scaling, alphas)
    x0 = check_finite("start", check_last_axis("start", start, 3))
    if x0.shape != (3,):
        raise ValueError(f"start must have shape (3,), got shape {x0.shape}")
    step_dt = float(check_positive("dt", dt))
    u = check_finite("control", control)
    if u.shape != (2,):
        raise ValueError(f"control must have shape (2,) (allowed: (V, omega)), got shape {u.shape}")
    check_nonnegative("cell_floor", cell_floor)
    if model == "odometry":
        if odometry is None:
            od = noiseless_velocity_poses(x0, u[None, :], step_dt)
        else:
            od = check_finite("odometry", check_last_axis("odometry", odometry, 3))
            if od.shape != (2, 3):
                raise ValueError(f"odometry must have shape (2, 3), got shape {od.shape}")
        stp = _make_step(model, None, step_dt, a, noise, scaling, corrected, variance_from,
                         (od[0], od[1]))  # fmt: skip
    else:
        stp = _make_step(model, u, step_dt, a, noise, scaling, corrected, None, None)
    end = stp.noiseless(x0)
    g = grid if grid is not None else MapGrid.centered(end)
    cell = (g.resolution, g.theta_resolution)
    info: dict[str, Any] = {"corrected": corrected, "noise": noise, "scaling": scaling,
                            "end_pose": end.tolist()}  # fmt: skip
    if np.all(stp.variances() == 0):
        values = np.zeros(g.shape)
        _deposit(values, g, end)
        info["deterministic"] = True
        lost = 1.0 - float(values.sum())
        return ProbabilityMap(g.x, g.y, g.theta, values, lost, model, g, info)
    X, Y = np.meshgrid(g.x, g.y, indexing="ij")
    xy = np.stack([X, Y], axis=-1)
    dens = stp.density(xy, g.theta, x0, cell, cell_floor)
    values = dens * g.cell_volume
    if corrected and g.contains(x0):
        h = g.resolution
        ix = int(np.floor((x0[0] - g.x0) / h + 0.5))
        iy = int(np.floor((x0[1] - g.y0) / h + 0.5))
        lo = np.array([g.x[ix] - h / 2, g.y[iy] - h / 2])
        hi = lo + h
        values[ix, iy, :] = (
            stp.singular_cell(x0[:2], lo, hi, float(x0[2]), g.theta, cell, cell_floor)
            * g.theta_resolution
        )
    raw = float(values.sum())
    info["raw_sum"] = raw
    if corrected:
        lost = max(0.0, 1.0 - raw)
        values *= (1.0 - lost) / raw
    else:
        lost = 0.0
        values /= raw
    return ProbabilityMap(g.x, g.y, g.theta, values, lost, model, g, info)
