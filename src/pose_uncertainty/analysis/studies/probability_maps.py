"""Probability maps against their own sampler: the single-step map vs the model's Monte Carlo histogram.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...core.grids import Grid
from ...core.validation import check_choice
from ...methods import maps
from ...methods import motion_models as mm
from .. import accuracy as ac


def map_vs_sampler(
    model: str = "velocity",
    control: Sequence[float] = (1.0, 1.0),
    alphas: Sequence[float] | None = None,
    n: int = 100_000,
    seed: int = 0,
    size: float = 3.0,
    resolution: float = 0.02,
) -> dict[str, dict[str, float]]:
    """Single-step probability maps (thesis's and corrected) against the model's own sampler.

    The Monte Carlo truth is ``motion_models.sample_velocity`` (or
    ``sample_odometry``, with the odometry ``u`` the noiseless velocity motion)
    from (0, 0, 0) for ``Δt = 1``; the maps are
    ``maps.single_step_map(corrected=False)`` (Thrun's density, as the thesis)
    and ``corrected=True`` (the sampler's pose-space density), on a square
    grid of side ``size`` [m] centred on the noiseless end pose. Measures as
    :func:`pose_uncertainty.analysis.accuracy.evaluate_gridded`.

    Returns
    -------
    dict: ``thesis_map``, ``corrected_map`` → measures (plus ``lost_mass``)
    """
    check_choice("model", model, ("velocity", "odometry"))
    al = np.full(6 if model == "velocity" else 4, 0.05) if alphas is None else np.asarray(alphas)
    u = np.asarray(control, dtype=float)
    start = np.zeros(3)
    end = mm.noiseless_velocity_poses(start, u[None, :], 1.0)[-1]
    grid = Grid.centered(end, size=size, resolution=resolution)
    rng = np.random.default_rng(seed)
    if model == "velocity":
        samples = mm.sample_velocity(start, u, 1.0, al, n, rng)
    else:
        samples = mm.sample_odometry(start, start, end, al, n, rng)
    out = {}
    for name, corrected in (("thesis_map", False), ("corrected_map", True)):
        pm = maps.single_step_map(model, start, u, 1.0, al, grid=grid, corrected=corrected)
        res = ac.evaluate_gridded(pm, samples)
        res["lost_mass"] = float(pm.lost_mass)
        out[name] = res
    return out
