"""The transition kernel of one step of the multi-step map, by quadrature of the control noise.

The noise of ``(V̂, ω̂)`` (velocity) or ``(δrot1, δtrans)`` (odometry) is cut into
nodes carrying the exact mass of their control interval (:func:`_node_masses`), each
node is moved by the model's kinematics and splatted on the cells by exact overlap;
the heading-only noise is a 1-D circular kernel whose width is moment-matched so that
the step's heading variance is exact (:func:`_matched_heading_std`). The kernel, with
its window for every source heading, is a :class:`GridTransition` (:func:`grid_transition`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ...core.grids import Grid
from ...core.noise import cdf, noise_reach
from ...core.validation import (
    check_choice,
    check_finite,
    check_positive,
)
from ..motion_models import (
    odometry_forward,
    velocity_forward,
)
from .kernels import AnyArray, Array, _axis_parts
from .step import MODELS, _make_step, _noise_args, _Step


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


def _control_nodes(
    stp: _Step,
    sd: Array,
    h: float,
    ht: float,
    n_max: int,
    *,
    trans: int,
    per: float,
    lever_of: Callable[[float], float],
    forward: Callable[[Array, Array], Array],
    head: tuple[float, float],
    clip: float = math.inf,
) -> _ControlNodes:
    """Nodes of the two noisy controls on a product grid, spaced ≤ a quarter cell in pose space.

    The translation-like control ``u[trans]`` (``V`` or ``δtrans``) is spaced ≤ ``h/4`` per
    ``per`` (the step's duration for rates, 1 for increments); the rotation-like one
    ``u[1 − trans]`` (``ω`` or ``δrot1``) ≤ ``h_θ/4`` per ``per`` and ≤ ``h/4`` at the lever
    ``lever_of(|translation| + reach)`` [m per unit of rotation], then clipped to ``±clip``.
    ``forward(a, b)`` moves the nodes (first axis ``u[0]``) to local pose changes; ``head`` is
    the heading-only noise's (mean, std) [rad].
    """
    t_mean, t_sd = float(stp.u[trans]), float(sd[trans])
    r_mean, r_sd = float(stp.u[1 - trans]), float(sd[1 - trans])
    t_n, t_w = _node_masses(t_mean, t_sd, stp.noise, 0.25 * h / per, n_max)
    lever = lever_of(abs(t_mean) + noise_reach(stp.noise) * t_sd)
    r_sp = min(0.25 * ht / per, 0.25 * h / lever if lever > 0 else math.inf)
    r_n, r_w = _node_masses(r_mean, r_sd, stp.noise, r_sp, n_max)
    r_n = np.clip(r_n, -clip, clip)
    (a_n, a_w), (b_n, b_w) = ((t_n, t_w), (r_n, r_w)) if trans == 0 else ((r_n, r_w), (t_n, t_w))
    A, B = np.meshgrid(a_n, b_n, indexing="ij")
    return _ControlNodes(A.shape, forward(A.ravel(), B.ravel()), np.outer(a_w, b_w).ravel(), *head)


def _velocity_nodes(stp: _Step, sd: Array, h: float, ht: float, n_max: int) -> _ControlNodes:
    """Nodes of ``(V̂, ω̂)``: along-track ``dx = dV·Δt·sinc ≤ dV·Δt``, across ``≈ |V|Δt²/2·dω``, heading ``Δt·dω``."""
    dt = stp.dt
    return _control_nodes(
        stp, sd, h, ht, n_max, trans=0, per=dt, lever_of=lambda a: a * dt * dt / 2.0,
        forward=lambda a, b: velocity_forward(np.zeros(3), a, b, 0.0, dt), head=(0.0, float(sd[2]) * dt),
        clip=math.pi / dt,
    )  # fmt: skip


def _odometry_nodes(stp: _Step, sd: Array, h: float, ht: float, n_max: int) -> _ControlNodes:
    """Nodes of ``(δ̂rot1, δ̂trans)``: across ``≈ |δtrans|·dδrot1``; ``δrot2`` is the heading-only noise."""
    return _control_nodes(
        stp, sd, h, ht, n_max, trans=1, per=1.0, lever_of=lambda a: a,
        forward=lambda a, b: odometry_forward(np.zeros(3), a, b, 0.0), head=(float(stp.u[2]), float(sd[2])),
    )  # fmt: skip


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


def _rotated_cells(kern: _Kernel, theta: Array, h: float, idx: Array | None = None) -> tuple[Array, Array]:
    """World offsets in cell units of the kernel's position nodes for source headings ``theta``."""
    loc = kern.local if idx is None else kern.local[idx]
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    fx = (c * loc[None, :, 0] - s * loc[None, :, 1]) / h
    fy = (s * loc[None, :, 0] + c * loc[None, :, 1]) / h
    return fx, fy


def _kernel_windows(kern: _Kernel, thetas: Array, h: float) -> tuple[AnyArray, AnyArray, int, int]:
    """Window of a step's kernel per source heading [cells]: offsets ``ax, ay`` (nθ,), sizes ``wx, wy``."""
    # kernel windows per source heading (cells), from the control box perimeter (+1 for CIC)
    px, py = _rotated_cells(kern, thetas, h, kern.perimeter)
    ax = np.floor(px.min(axis=1)).astype(np.int64) - 2
    ay = np.floor(py.min(axis=1)).astype(np.int64) - 2
    wx = int((np.floor(px.max(axis=1)).astype(np.int64) + 4 - ax).max()) + 1
    wy = int((np.floor(py.max(axis=1)).astype(np.int64) + 4 - ay).max()) + 1
    return ax, ay, wx, wy


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
