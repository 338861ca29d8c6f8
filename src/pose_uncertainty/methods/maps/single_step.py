"""The exact single-step map: the motion-model density at every cell of the grid.

:func:`single_step_map` evaluates the density of one motion from a known start at
every cell centre, the thesis's ``O(n³)`` case (Němec 2012): Thrun's density of the
control noise, normalised to relative probability (``corrected=False``, the thesis),
or the pose-space density of the sampler averaged over each cell, with the cells within
:data:`EXACT_RADIUS` of the start integrated exactly (``corrected=True``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ...core.grids import Grid
from ...core.validation import (
    check_finite,
    check_last_axis,
    check_positive,
)
from ..motion_models import (
    noiseless_velocity_poses,
)
from .container import ProbabilityMap
from .kernels import Array, _deposit
from .step import _make_step, _noise_args, _Step

#: Corrected single-step maps integrate the cells within this many cells of the start exactly.
EXACT_RADIUS: int = 2


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
        noiseless velocity motion ``start → end`` (as Němec 2012), unless ``odometry``
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
    """Check the control of :func:`single_step_map` and make its step (odometry: given or as Němec 2012)."""
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
