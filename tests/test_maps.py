"""Probability maps: grid, map statistics, single-step maps, multi-step histogram filter vs Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import stats
from pose_uncertainty.core.grids import Grid
from pose_uncertainty.methods import maps as M
from pose_uncertainty.methods import motion_models as mm

A6 = np.full(6, 0.05)
A4 = np.full(4, 0.05)
N_PARTICLES = 1_000_000
#: Hellinger target for multi-step maps vs Monte Carlo of the same model, applied
#: to the model/discretisation part: H² − E[H²_noise] ≤ TARGET² (E from the Poisson formula
#: of ``hellinger_noise_floor``; its standard deviation at 10⁶ particles is ~1e-5 in H²).
TARGET = 0.05


# ----------------------------------------------------------------------------- grid & map


def test_default_grid_is_the_thesis_map_centred_on_the_end_pose():
    g = Grid.centered((1.0, 0.5, 0.3))
    assert g.shape == (101, 101, 180)
    assert_allclose(g.x[50], 1.0)
    assert_allclose(g.y[50], 0.5)
    assert_allclose(g.resolution, 0.01)
    assert g.theta_resolution <= math.radians(2.0) + 1e-12
    assert np.min(np.abs(g.theta - 0.3)) < 1e-12  # a heading cell is centred on the end heading
    assert g.theta.min() >= -math.pi
    assert g.theta.max() < math.pi
    assert g.contains((1.0, 0.5, 0.0))
    assert not g.contains((1.6, 0.5, 0.0))


TWO_DEG = math.radians(2)


def _gaussian_map(cov, mean=(0.1, -0.2, 0.3), h=0.01, ht=TWO_DEG):
    g = Grid.centered(mean, size=1.5, resolution=h, theta_resolution=ht)
    X, Y, T = np.meshgrid(g.x, g.y, g.theta, indexing="ij")
    d = np.stack([X - mean[0], Y - mean[1], (T - mean[2] + np.pi) % (2 * np.pi) - np.pi], -1)
    q = np.einsum("...i,ij,...j->...", d, np.linalg.inv(cov), d)
    v = np.exp(-0.5 * q)
    return M.ProbabilityMap(g.x, g.y, g.theta, v / v.sum(), 0.0, "velocity", g), g


def test_map_statistics_of_a_known_gaussian():
    cov = np.array([[0.010, 0.003, 0.001], [0.003, 0.005, 0.0], [0.001, 0.0, 0.02]])
    m, _ = _gaussian_map(cov)
    # the map holds the density sampled at cell centres: its cell-centre moments are those of
    # the Gaussian to exponential accuracy (Poisson summation, σ ≫ cell)
    assert_allclose(m.mean(), [0.1, -0.2, 0.3], atol=1e-9)
    assert_allclose(m.cov(), cov, atol=1e-9)
    assert_allclose(m.marginal_xy().sum(), 1.0)
    assert_allclose(m.marginal_theta().sum(), 1.0)
    assert_allclose(m.most_probable(), [0.1, -0.2, 0.3], atol=1e-9)
    # credible region of a 2-D Gaussian is an ellipse of area π k √det Σ, k = −2 ln(1 − Pr)
    for pr in (0.5, 0.9, 1 - math.exp(-4.5)):
        area = math.pi * -2 * math.log(1 - pr) * math.sqrt(np.linalg.det(cov[:2, :2]))
        assert_allclose(m.credible_area(pr), area, rtol=0.01)


# ----------------------------------------------------------------------------- single step


def test_claim6_rotation_in_place_peak():
    # Němec 2012 §4.1.1 (claim 6): Thrun's map of a rotation in place peaks ~2 cm from the start
    # on the line at 0.5 rad. Point values at cell centres reproduce it: cell (±2, ±1) cm.
    thrun = M.single_step_map("velocity", (0, 0, 0), (0.0, 1.0), 1.0, A6)
    peak = thrun.most_probable_xy()
    assert_allclose(np.abs(peak), [0.02, 0.01], atol=1e-12)
    assert_allclose(math.atan2(peak[1], peak[0]) % math.pi, math.atan2(1, 2), atol=1e-12)
    # ... but it is an artefact: the density of the sampler peaks at the start itself
    # (1/r singularity), and so does the histogram of its samples.
    corrected = M.single_step_map("velocity", (0, 0, 0), (0.0, 1.0), 1.0, A6, corrected=True)
    assert_allclose(corrected.most_probable_xy(), [0.0, 0.0], atol=1e-12)
    s = mm.sample_velocity((0, 0, 0), (0.0, 1.0), 1.0, A6, 200_000, np.random.default_rng(6))
    hist = corrected.grid.histogram_xy(s)
    i, j = np.unravel_index(np.argmax(hist), hist.shape)
    assert_allclose([corrected.grid.x[i], corrected.grid.y[j]], [0.0, 0.0], atol=1e-12)


def test_zero_control_is_a_dirac_and_single_step_deposits_it():
    m = M.single_step_map("velocity", (0, 0, 0), (0.0, 0.0), 1.0, A6, corrected=True)
    assert_allclose(m.values.max(), 1.0)
    assert_allclose(m.most_probable(), [0, 0, 0], atol=1e-12)
    mm_ = M.multi_step_map("velocity", np.zeros((3, 2)), 1.0, A6)
    assert_allclose(mm_.values.max(), 1.0)
    assert mm_.lost_mass < 1e-12  # FFT round-off only


# ----------------------------------------------------------------------------- multi step


def _coarse_grid(center=(0.5, 0.24, 0.0), size=2.4):
    # 2 cm × 4°, the start (0, 0, 0) is a cell centre
    return Grid.centered(center, size=size, resolution=0.02, theta_resolution=math.radians(4))


@pytest.mark.slow
@pytest.mark.parametrize("u", [(1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])
def test_one_step_multi_step_map_equals_the_single_step_map(u):
    # Two independent routes to one map: the histogram filter (control-noise quadrature,
    # FFT per heading slice) from a Dirac start vs the cell-averaged density evaluated at
    # every cell; and a third, the histogram of 10⁶ samples. Both maps converge to the cell
    # integrals of the same density; their discretisation differences are ≲ 5e-3 (xy).
    g = _coarse_grid()
    multi = M.multi_step_map(
        "velocity", np.array([u]), 1.0, A6, start=(0, 0, 0), grid=g, diffusion_compensation=False
    )
    single = M.single_step_map("velocity", (0, 0, 0), u, 1.0, A6, g, corrected=True)
    assert stats.hellinger(multi.marginal_xy(), single.marginal_xy()) < 5e-3
    assert_allclose(multi.values.sum() + multi.lost_mass, 1.0, atol=1e-12)
    assert_allclose(multi.lost_mass, single.lost_mass, atol=2e-3)
    # the full (x, y, θ) multi-step map is the sampler's distribution up to sampling noise
    samples = mm.sample_velocity((0, 0, 0), u, 1.0, A6, N_PARTICLES, np.random.default_rng(8))
    hist3 = g.histogram(samples)
    floor = stats.hellinger_noise_floor(multi.values, N_PARTICLES)
    assert stats.hellinger(multi.values, hist3) ** 2 - floor**2 <= 0.02**2


@pytest.mark.slow
def test_one_step_odometry_multi_step_equals_single_step():
    g = _coarse_grid()
    od = mm.noiseless_velocity_poses((0, 0, 0), np.array([[1.0, 1.0]]), 1.0)
    multi = M.multi_step_map("odometry", None, None, A4, grid=g, odometry=od, diffusion_compensation=False)
    single = M.single_step_map("odometry", (0, 0, 0), (1.0, 1.0), 1.0, A4, g, corrected=True)
    assert stats.hellinger(multi.marginal_xy(), single.marginal_xy()) < 0.01


def test_mass_leaving_a_fixed_grid_is_counted():
    # a 0.62 m grid cannot hold 3 steps of the thesis arc: the lost mass equals the fraction
    # of Monte Carlo particles outside (binomial s.e. √(q(1−q)/n) < 1e-3 at n = 2·10⁵,
    # plus the map's discretisation ~1e-3)
    ctr = np.tile([1.0, 1.0], (3, 1))
    g = Grid.centered((0.3, 0.2, 0.0), size=0.62, resolution=0.02, theta_resolution=math.radians(10))
    m = M.multi_step_map("velocity", ctr, 0.3, A6, grid=g)
    s = mm.sample_velocity_path((0, 0, 0), ctr, 0.3, A6, 200_000, np.random.default_rng(4))
    outside = 1.0 - g.histogram_xy(s).sum()
    assert 0.05 < m.lost_mass < 0.95
    assert_allclose(m.values.sum() + m.lost_mass, 1.0, atol=1e-12)
    assert_allclose(m.lost_mass, outside, atol=5e-3)
    assert len(m.info["lost_per_step"]) == 3


def _mc_end_poses(model, ctr, dt, n, seed):
    rng = np.random.default_rng(seed)
    if model == "velocity":
        return mm.sample_velocity_path((0, 0, 0), ctr, dt, A6, n, rng)
    od = mm.noiseless_velocity_poses((0, 0, 0), ctr, dt)
    return mm.sample_odometry_path((0, 0, 0), od, A4, n, rng)


@pytest.mark.parametrize(
    ("model", "u"),
    [("velocity", (1.0, 0.0)), ("velocity", (1.0, 1.0)), ("odometry", (1.0, 1.0))],
)
@pytest.mark.slow
def test_multi_step_map_matches_monte_carlo_at_default_resolution(model, u):
    # Thesis B1 motion (α = 0.05, 1 s) driven as 10 steps of 0.1 s; default 1 cm × 2° grid that
    # grows to hold the spread; 10⁶ particles of the same model along the same trajectory.
    ctr = np.tile(u, (10, 1))
    m = M.multi_step_map(model, ctr, 0.1, A6 if model == "velocity" else A4)
    assert m.lost_mass < 1e-9  # the grid grew to hold everything
    s = _mc_end_poses(model, ctr, 0.1, N_PARTICLES, seed=77)
    hist = m.grid.histogram_xy(s)
    assert hist.sum() > 1 - 1e-5
    h = stats.hellinger(m.marginal_xy(), hist)
    floor = stats.hellinger_noise_floor(m.marginal_xy(), N_PARTICLES)
    assert h**2 - floor**2 <= TARGET**2, (h, floor)
    # first and second moments: Monte Carlo s.e. of a variance ≈ var·√(2/n) ≈ 0.14 %;
    # the map's cell-centre moments carry the histogram filter's diffusion (≤ 10 %)
    assert_allclose(m.mean()[:2], s[:, :2].mean(axis=0), atol=2e-3)
    assert_allclose(np.diag(m.cov())[:2], s[:, :2].var(axis=0), rtol=0.1)


@pytest.mark.slow
def test_rotation_in_place_multi_step_needs_sub_cell_resolution():
    # Rotation in place spreads the robot along thin lines; the histogram filter forgets
    # where in its cell the mass sits at every step, which at 1 cm costs H ≈ 0.055. Computed
    # on 3× finer cells and summed into the default 1 cm cells it meets the target.
    ctr = np.tile([0.0, 1.0], (10, 1))
    m = M.multi_step_map("velocity", ctr, 0.1, A6, oversample=3)
    assert m.grid.resolution == pytest.approx(0.01)
    assert np.min(np.abs(m.grid.x)) < 1e-12  # the start is a cell centre
    assert np.min(np.abs(m.grid.y)) < 1e-12
    s = _mc_end_poses("velocity", ctr, 0.1, N_PARTICLES, seed=78)
    hist = m.grid.histogram_xy(s)
    h = stats.hellinger(m.marginal_xy(), hist)
    floor = stats.hellinger_noise_floor(m.marginal_xy(), N_PARTICLES)
    assert h**2 - floor**2 <= TARGET**2, (h, floor)


def test_multi_step_accepts_a_trajectory_object():
    from pose_uncertainty.core import trajectories as tr

    t = tr.arc(radius=1.0, angle=0.4, dt=0.1, start=(0.1, 0.2, 0.3))
    kw = {"resolution": 0.02, "theta_resolution": math.radians(10)}
    a = M.multi_step_map("velocity", t, alphas=A6, **kw)
    b = M.multi_step_map("velocity", t.controls, t.dt, A6, start=t.start, **kw)
    assert_allclose(a.values, b.values)
    # the map follows the noiseless path of the trajectory (exact arcs = velocity model)
    assert_allclose(a.mean()[:2], t.poses[-1, :2], atol=0.01)


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: Grid.centered((0, 0, 0), resolution=0.0), r"resolution must be > 0 .*got 0.0"),
        (lambda: Grid.centered((0, 0, 0), resolution=-0.01), r"resolution must be > 0 .*got -0.01"),
        (
            lambda: M.multi_step_map("velocity", [[1, 0]], 1.0, A6, resolution=-1.0),
            r"resolution must be > 0 \(allowed: \(0, inf\)\), got -1.0",
        ),
        (
            lambda: M.multi_step_map("velocity", [[1, 0]], 1.0, A6, start=(5, 5, 0), grid=Grid.centered()),
            r"start must lie inside the grid \(allowed: x in \[-0.505, 0.505\), y in \[-0.505, 0.505\)\), got \(5, 5\)",
        ),
        (
            lambda: M.single_step_map("velocity", (0, 0, 0), (1, 0), 1.0, [0.05, 0.05, -0.01, 0.05, 0.05, 0.05]),
            r"alphas must be >= 0 .*-0.01",
        ),
        (
            lambda: M.multi_step_map("velocity", [[1, 0]], 1.0, A6, noise="laplace"),
            r"noise must be one of 'normal', 'triangular', got 'laplace'",
        ),
        (lambda: M.single_step_map("kinematic", (0, 0, 0), (1, 0), 1.0, A6), r"model must be one of"),
        (lambda: M.single_step_map("velocity", (0, 0, 0), (1, 0), 1.0, A6, scaling="cubic"), r"scaling must be"),
        (lambda: M.multi_step_map("velocity", [[1, 0]], -1.0, A6), r"dt must be > 0"),
        (
            lambda: M.multi_step_map("velocity", [[1, 0]], 1.0, A6, grid=Grid.centered(), oversample=3),
            r"oversample must be 1 with a fixed grid \(allowed: 1\), got 3",
        ),
        (lambda: M.ProbabilityMap(*_gaussian_map(np.eye(3) * 0.01)[0].__dict__.values()).credible_area(1.5),
         r"pr must be a probability"),
    ],
)
def test_bad_input_raises_value_error_naming_value_and_allowed(call, match):
    with pytest.raises(ValueError, match=match):
        call()
