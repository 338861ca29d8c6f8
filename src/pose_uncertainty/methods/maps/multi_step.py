"""The multi-step map: the histogram filter's prediction repeated along a trajectory.

:func:`multi_step_map` normalises the trajectory (controls, step durations, odometry
poses), starts a grid at the start cell, and takes one :func:`predict_on_grid` step
per control, growing the grid to hold the spread (up to a cell budget; mass that
leaves the grid is counted exactly) and coarsening an oversampled grid at the end.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ...core.grids import Grid
from ...core.noise import check_noise, check_scaling
from ...core.threads import default_workers
from ...core.validation import (
    check_choice,
    check_finite,
    check_last_axis,
    check_positive,
    check_positive_int,
)
from ..motion_models import (
    check_alphas,
    noiseless_velocity_poses,
)
from .container import ProbabilityMap
from .kernels import AnyArray, Array, _deposit
from .prediction import _convolve_step, _drop_negligible_slices
from .step import MODELS, _make_step, _Step
from .transition import _kernel_windows, _quadrature_kernel


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
