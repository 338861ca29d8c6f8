"""Method B's region in the report's headline figure (``expcoords_regions``): its cells, its boundary, its coverage.

Two routes to each number: the share of draws *from the map itself* that the cell lookup puts in the
region equals the region's own mass (binomial tolerance); the contour drawn round the region holds
exactly the cell centres whose mass passes the level; the logged area is the region's cells.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pose_uncertainty.analysis.studies import gaussian_methods as gm
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.stats import PR_3SIGMA
from pose_uncertainty.localization.motion import velocity_alphas_for_wheels
from pose_uncertainty.methods import maps

K, TRACK, STEP = 5e-4, 0.2, 0.25
ARC = {"name": "arc", "radius": 1.0, "angle": 1.0}


@pytest.fixture(scope="module")
def arc_map() -> maps.ProbabilityMap:
    t = tr.from_config({**ARC, "dt": STEP, "track": TRACK})
    return maps.multi_step_map("velocity", t.controls, t.dt, alphas=velocity_alphas_for_wheels(K, K, TRACK, STEP),
                               start=t.start, scaling="abs", resolution=0.02, theta_resolution=0.1)  # fmt: skip


def _draws(pm: maps.ProbabilityMap, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points from the map's θ-marginal: a cell by its mass, then uniform in the cell."""
    mass = pm.marginal_xy()
    cells = rng.choice(mass.size, size=n, p=(mass / mass.sum()).ravel())
    ix, iy = np.unravel_index(cells, mass.shape)
    h = float(pm.x[1] - pm.x[0])
    return np.column_stack([pm.x[ix], pm.y[iy]]) + rng.uniform(-h / 2, h / 2, size=(n, 2))


def test_the_cell_lookup_holds_the_regions_mass(arc_map: maps.ProbabilityMap) -> None:
    level, _ = arc_map.region_xy(PR_3SIGMA)
    mass = arc_map.marginal_xy()
    region_mass = float(mass[mass >= level].sum() / mass.sum())
    assert PR_3SIGMA <= region_mass < PR_3SIGMA + float(mass.max())  # the region's own definition
    n = 40_000
    share = float(gm._in_region(arc_map, level, _draws(arc_map, n, np.random.default_rng(3))).mean())
    # binomial: standard error √(p(1−p)/n) ≈ 5e-4 at n = 40 000; 5 of them
    assert share == pytest.approx(region_mass, abs=5 * math.sqrt(region_mass * (1 - region_mass) / n))
    far = np.array([[arc_map.x[0] - 1.0, arc_map.y[0]], [arc_map.x[-1] + 1.0, arc_map.y[-1] + 1.0]])
    assert not gm._in_region(arc_map, level, far).any()  # off the grid: outside


def test_the_boundary_encloses_exactly_the_regions_cells(arc_map: maps.ProbabilityMap) -> None:
    level, area = arc_map.region_xy(PR_3SIGMA)
    lines = gm._region_boundary(arc_map, level)
    assert lines
    assert all(np.allclose(line[0], line[-1]) for line in lines)  # closed
    mass = arc_map.marginal_xy()
    X, Y = np.meshgrid(arc_map.x, arc_map.y, indexing="ij")
    clear = mass != level  # a centre at the level lies on the contour itself
    centres = np.column_stack([X[clear], Y[clear]])
    from matplotlib.path import Path  # a second point-in-polygon route

    inside = np.logical_or.reduce([Path(line).contains_points(centres) for line in lines])
    assert np.array_equal(inside, mass[clear] > level)
    h = float(arc_map.x[1] - arc_map.x[0])
    assert area == pytest.approx(np.count_nonzero(mass >= level) * h * h, abs=h * h)  # the last cell in part


@pytest.mark.slow
def test_the_study_logs_the_map_region_and_its_coverage() -> None:
    case = {"label": "arc", "trajectory": ARC, "map": {"resolution": 0.02, "theta_resolution": 0.1, "dt": STEP}}
    out = gm.expcoords_regions([case], n=400, dt=0.05, seed=1)
    c = out["cases"][0]
    assert 0.0 <= c["inside_map"] <= 1.0
    m = c["map"]
    assert m["model"] == "velocity"
    assert m["alphas"] == pytest.approx(velocity_alphas_for_wheels(K, K, TRACK, STEP))
    assert m["n_steps"] == 4
    assert m["lost_mass"] < 1e-9
    assert m["boundary_xy"]
    # the region covers the cloud about as the Pr level says: the map's noise has the wheels' variances
    # (not their travel-turn correlation) and its cells add spread; 400 draws: a standard error of 0.5 %
    assert c["inside_map"] >= PR_3SIGMA - 0.03
