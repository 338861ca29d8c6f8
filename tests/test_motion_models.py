"""Velocity and odometry motion models: densities against samplers, inverses, Jacobians, limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import noise as nz
from pose_uncertainty.core import stats
from pose_uncertainty.core.grids import Grid
from pose_uncertainty.methods import maps as M
from pose_uncertainty.methods import motion_models as mm

A6 = np.full(6, 0.05)  # thesis error constants (Němec 2012 ch. 4, Method B)
A4 = np.full(4, 0.05)
THESIS = {"straight": (1.0, 0.0), "arc": (1.0, 1.0), "rotation": (0.0, 1.0)}


# ----------------------------------------------------------------------------- noise


@pytest.mark.parametrize("noise", ["normal", "triangular"])
def test_noise_density_is_normalised_with_the_stated_variance(noise):
    var = 0.37
    a = np.linspace(-6, 6, 120_001)
    p = nz.prob(a, var, noise)
    da = a[1] - a[0]
    assert_allclose(p.sum() * da, 1.0, rtol=1e-6)
    assert_allclose((a * a * p).sum() * da, var, rtol=1e-6)
    # the CDF is the integral of the density
    assert_allclose(np.gradient(nz.cdf(a, var, noise), da), p, atol=2e-4)


@pytest.mark.parametrize("noise", ["normal", "triangular"])
def test_noise_sampler_has_the_variance_of_its_density(noise):
    rng = np.random.default_rng(123)
    var, n = 0.8, 400_000
    x = nz.sample(var, rng, noise, n)
    # standard error of a sample variance: var·√((κ−1)/n), κ = 3 (normal) or 2.4 (triangular)
    kappa = 3.0 if noise == "normal" else 2.4
    se = var * math.sqrt((kappa - 1) / n)
    assert abs(x.var() - var) < 5 * se
    assert abs(x.mean()) < 5 * math.sqrt(var / n)
    if noise == "triangular":  # support |a| ≤ √6 b
        assert np.abs(x).max() <= math.sqrt(6 * var)


def test_zero_variance_is_finite_and_the_cell_average_integrates_a_dirac():
    assert np.isfinite(nz.prob_normal(0.0, 0.0))
    assert nz.prob_normal(1e-3, 0.0) == 0.0
    assert nz.sample_normal(0.0, np.random.default_rng(0), 5).tolist() == [0.0] * 5
    # a zero-variance term averaged over a cell of width w is 1/w inside, 0 outside
    a = np.array([-0.6, -0.4, 0.0, 0.4, 0.6])
    assert_allclose(nz.prob_cell(a, 0.0, 1.0), [0, 1, 1, 1, 0])
    # and a wide one is the density itself to second order
    assert_allclose(nz.prob_cell(0.3, 1.0, 1e-2), nz.prob_normal(0.3, 1.0), rtol=1e-5)


def test_variance_scalings():
    assert_allclose(nz.scaled_variance(0.1, 0.2, -2.0, 3.0, "squared"), 0.1 * 4 + 0.2 * 9)
    assert_allclose(nz.scaled_variance(0.1, 0.2, -2.0, 3.0, "abs"), 0.1 * 2 + 0.2 * 3)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: nz.prob(0.0, 1.0, "gauss"), r"noise must be one of 'normal', 'triangular', got 'gauss'"),
        (lambda: nz.scaled_variance(1, 1, 1, 1, "cube"), r"scaling must be one of 'squared', 'abs'"),
        (lambda: nz.prob_normal(0.0, -1.0), r"var must be >= 0 .*got -1.0"),
        (lambda: mm.velocity_variances((1, 0), [0.1, -0.05, 0, 0, 0, 0]), r"alphas must be >= 0 .*-0.05"),
        (lambda: mm.velocity_variances((1, 0), [0.1] * 4), r"alphas must hold 6 error constants"),
        (
            lambda: mm.sample_velocity((0, 0, 0), (1, 0), 1.0, A6, 10, np.random.default_rng(0), "uniform"),
            r"noise must be one of",
        ),
        (lambda: mm.velocity_inverse((1, 0, 0), (0, 0, 0), 0.0), r"dt must be > 0 .*got 0.0"),
    ],
)
def test_bad_input_names_the_value_and_what_is_allowed(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ----------------------------------------------------------------------------- velocity


def _thrun_inverse(x_t, x_prev, dt):
    """The printed construction (μ, x*, y*, r*, Δφ; Thrun §5.3, Němec 2012 §2.2.1) for non-straight points."""
    x, y, th = x_prev
    xp, yp = x_t[:, 0], x_t[:, 1]
    mu = 0.5 * ((x - xp) * np.cos(th) + (y - yp) * np.sin(th)) / (
        (y - yp) * np.cos(th) - (x - xp) * np.sin(th)
    )
    xs = (x + xp) / 2 + mu * (y - yp)
    ys = (y + yp) / 2 + mu * (xp - x)
    rs = np.hypot(x - xs, y - ys)
    dphi = np.arctan2(yp - ys, xp - xs) - np.arctan2(y - ys, x - xs)
    dphi = (dphi + np.pi) % (2 * np.pi) - np.pi
    return dphi / dt * rs, dphi / dt


def test_velocity_inverse_agrees_with_the_printed_construction_and_inverts_the_motion():
    rng = np.random.default_rng(7)
    x0, dt = np.array([0.3, -0.2, 0.7]), 0.8
    V = rng.normal(0, 1, 2000)
    w = rng.uniform(-0.95, 0.95, 2000) * math.pi / dt  # principal branch |ωΔt| < π
    g = rng.uniform(-0.95, 0.95, 2000) * math.pi / dt  # the heading drift is an angle: |γΔt| < π
    xt = mm.velocity_forward(x0, V, w, g, dt)
    Vh, wh, gh = mm.velocity_inverse(xt, x0, dt)
    assert_allclose(Vh, V, atol=1e-9)
    assert_allclose(wh, w, atol=1e-9)
    assert_allclose(gh, g, atol=1e-9)
    # the printed μ construction gives the same ω̂ and |V̂| (it has no sign for reverse motion)
    V_thrun, w_thrun = _thrun_inverse(xt, x0, dt)
    assert_allclose(w_thrun, wh, atol=1e-9)
    assert_allclose(np.abs(V_thrun), np.abs(Vh), atol=1e-9)


def test_velocity_inverse_limits_straight_reverse_turns_and_zero_displacement():
    x0 = np.zeros(3)
    # straight ahead and straight back: ω̂ = 0, V̂ = signed distance / Δt, no warnings
    Vh, wh, gh = mm.velocity_inverse(np.array([[2.0, 0, 0], [-2.0, 0, 0]]), x0, 0.5)
    assert_allclose(Vh, [4.0, -4.0])
    assert_allclose(wh, [0.0, 0.0], atol=1e-15)
    # mirrored hypotheses turn the other way with the same speed
    pts = np.array([[0.8, 0.3, 0.5], [0.8, -0.3, -0.5]])
    Vh, wh, gh = mm.velocity_inverse(pts, x0, 1.0)
    assert_allclose(Vh[0], Vh[1])
    assert_allclose(wh[0], -wh[1])
    assert_allclose(gh[0], -gh[1])
    # zero displacement: finite (the convention atan2(0, 0) = 0)
    Vh, wh, gh = mm.velocity_inverse(np.array([0.0, 0.0, 0.3]), x0, 1.0)
    assert (Vh, wh) == (0.0, 0.0)
    assert_allclose(gh, 0.3)


def test_velocity_jacobian_matches_finite_differences():
    rng = np.random.default_rng(3)
    x0, dt, eps = np.array([0.1, 0.2, -0.4]), 0.7, 1e-6
    for V, w, g in zip(rng.normal(0, 1, 8), rng.uniform(-3, 3, 8), rng.normal(0, 1, 8), strict=True):
        c = np.array([V, w, g])
        J = np.empty((3, 3))
        for j in range(3):
            e = np.zeros(3)
            e[j] = eps
            J[:, j] = (mm.velocity_forward(x0, *(c + e), dt) - mm.velocity_forward(x0, *(c - e), dt)) / (2 * eps)
        assert_allclose(abs(np.linalg.det(J)), mm.velocity_jacobian_det(V, w, dt), rtol=1e-6)


@pytest.mark.parametrize("noise", ["normal", "triangular"])
@pytest.mark.parametrize("scaling", ["squared", "abs"])
def test_densities_are_finite_and_nonnegative_everywhere(noise, scaling):
    rng = np.random.default_rng(11)
    hyp = np.concatenate(
        [rng.uniform(-2, 2, (4000, 3)), np.zeros((1, 3)), [[1.0, 0, 0], [-1.0, 0, 0], [0, 0, 1.0]]]
    )
    controls = [(1, 0), (1, 1), (0, 1), (0, 0), (-1, 0.5), (1, -1)]
    for u in controls:
        for alphas in (A6, np.zeros(6), [0.05, 0, 0.05, 0, 0, 0]):
            for corrected in (False, True):
                for cell in (None, (0.01, math.radians(2))):
                    p = mm.velocity_density(hyp, u, (0, 0, 0), 1.0, alphas, noise, scaling, corrected, cell)
                    assert np.all(np.isfinite(p))
                    assert np.all(p >= 0)
    od = [((0, 0, 0), (1, 0, 0)), ((0, 0, 0), (0, 0, 1)), ((0, 0, 0), (0, 0, 0)), ((0, 0, 0), (-1, 0.1, 0))]
    for op, on in od:
        for alphas in (A4, np.zeros(4)):
            for corrected in (False, True):
                for cell in (None, (0.01, math.radians(2))):
                    p = mm.odometry_density(hyp, op, on, (0, 0, 0), alphas, noise, scaling, corrected, None, cell)
                    assert np.all(np.isfinite(p))
                    assert np.all(p >= 0)


def _integral(density, half, h, ht):
    """Σ p ΔV over a cube grid covering the density (midpoint rule).

    The grid is shifted by a third of a cell so that no cell centre sits on the
    start pose, where the corrected densities have their integrable 1/r singularity.
    """
    xs = np.arange(-half, half, h) + h / 3
    ts = np.arange(-math.pi, math.pi, ht) + ht / 2
    X, Y, T = np.meshgrid(xs, xs, ts, indexing="ij")
    return float(density(np.stack([X, Y, T], -1)).sum() * h * h * ht)


@pytest.mark.parametrize("noise", ["normal", "triangular"])
@pytest.mark.parametrize("name", ["straight", "arc"])
def test_corrected_densities_integrate_to_one(noise, name):
    # Corrected = pose-space density of the sampler: ∫ p dx dy dθ = 1 over a covering grid.
    # Midpoint rule at 4 cm / 6° on a density of width ~0.3 m: error ≲ 1e-3.
    u = THESIS[name]
    start = np.array([0.0, 0.0, 0.0])
    end = mm.velocity_forward(start, *u, 0.0, 1.0)

    def vel(h):
        return mm.velocity_density(h + np.array([*end[:2], 0.0]), u, start, 1.0, A6, noise, corrected=True)

    def odo(h):
        return mm.odometry_density(h + np.array([*end[:2], 0.0]), start, end, start, A4, noise, corrected=True)

    for dens in (vel, odo):
        assert_allclose(_integral(dens, 2.5, 0.04, math.radians(6)), 1.0, atol=1e-3)


@pytest.mark.parametrize("model", ["velocity", "odometry"])
def test_rotation_in_place_corrected_map_integrates_to_one(model):
    # 1/r singularity at the start: the start cell is integrated exactly (CDF along the ray)
    g = Grid.centered((0, 0, 0), size=3.0, resolution=0.02, theta_resolution=math.radians(4))
    m = M.single_step_map(model, (0, 0, 0), (0.0, 1.0), 1.0, A6 if model == "velocity" else A4, g, corrected=True)
    assert_allclose(m.info["raw_sum"], 1.0, atol=3e-3)


# ----------------------------------------------------------------------------- density vs sampler

N_SAMPLES = 1_000_000
#: Allowance for discretisation error beyond sampling noise, as a Hellinger distance: a map
#: that is the density of the sampler must satisfy H² − E[H²_noise] ≤ DELTA² (E from the
#: Poisson sampling formula of ``hellinger_noise_floor``; its own s.d. is ~1e-5, negligible).
DELTA = 0.02


def _sampler(model, u, n, rng, noise="normal"):
    if model == "velocity":
        return mm.sample_velocity((0, 0, 0), u, 1.0, A6, n, rng, noise)
    od = mm.noiseless_velocity_poses((0, 0, 0), np.array([u]), 1.0)
    return mm.sample_odometry((0, 0, 0), od[0], od[1], A4, n, rng, noise)


@pytest.mark.parametrize("model", ["velocity", "odometry"])
@pytest.mark.parametrize("name", ["straight", "arc", "rotation"])
def test_corrected_map_agrees_with_its_sampler_and_thrun_map_does_not(model, name):
    u = THESIS[name]
    alphas = A6 if model == "velocity" else A4
    grid = Grid.centered(
        mm.velocity_forward(np.zeros(3), *u, 0.0, 1.0), size=1.0, resolution=0.01, theta_resolution=math.radians(6)
    )
    samples = _sampler(model, u, N_SAMPLES, np.random.default_rng(2024))
    hist = grid.histogram_xy(samples)
    corrected = M.single_step_map(model, (0, 0, 0), u, 1.0, alphas, grid, corrected=True)
    thrun = M.single_step_map(model, (0, 0, 0), u, 1.0, alphas, grid, corrected=False)
    floor2 = stats.hellinger_noise_floor(corrected.marginal_xy(), N_SAMPLES) ** 2
    h_corr = stats.hellinger(corrected.marginal_xy(), hist)
    h_thrun = stats.hellinger(thrun.marginal_xy(), hist)
    assert h_corr**2 - floor2 <= DELTA**2, (h_corr, math.sqrt(floor2))
    assert h_thrun**2 - floor2 > (2 * DELTA) ** 2, (h_thrun, math.sqrt(floor2))
    # the corrected map's lost mass is the fraction of samples outside the grid
    # (binomial s.e. √(q(1−q)/n) ≤ 5e-4, plus quadrature error ~1e-3)
    assert_allclose(corrected.lost_mass, 1.0 - hist.sum(), atol=3e-3)


def test_triangular_noise_map_agrees_with_its_sampler():
    u = THESIS["arc"]
    grid = Grid.centered(
        mm.velocity_forward(np.zeros(3), *u, 0.0, 1.0), size=1.0, resolution=0.01, theta_resolution=math.radians(6)
    )
    samples = _sampler("velocity", u, N_SAMPLES, np.random.default_rng(5), "triangular")
    m = M.single_step_map("velocity", (0, 0, 0), u, 1.0, A6, grid, noise="triangular", corrected=True)
    hist = grid.histogram_xy(samples)
    floor2 = stats.hellinger_noise_floor(m.marginal_xy(), N_SAMPLES) ** 2
    assert stats.hellinger(m.marginal_xy(), hist) ** 2 - floor2 <= DELTA**2


# ----------------------------------------------------------------------------- odometry


def test_odometry_conventions_rotation_in_place_and_reverse():
    r1, tr, r2 = mm.odometry_deltas((1, 2, 0.3), (1, 2, 1.3))
    assert (float(r1), float(tr)) == (0.0, 0.0)
    assert_allclose(r2, 1.0)
    # driving backwards 1 m: no turn, negative translation (not turn round, drive, turn back)
    r1, tr, r2 = mm.odometry_deltas((0, 0, 0), (-1, 0, 0))
    assert_allclose([r1, tr, r2], [0.0, -1.0, 0.0], atol=1e-15)
    # decomposition and composition are inverse, angles wrapped
    rng = np.random.default_rng(9)
    a = rng.uniform(-3, 3, (500, 3))
    b = rng.uniform(-3, 3, (500, 3))
    d = mm.odometry_deltas(a, b)
    back = mm.odometry_forward(a, *d)
    assert_allclose(back[:, :2], b[:, :2], atol=1e-12)
    assert_allclose(np.cos(back[:, 2] - b[:, 2]), 1.0, atol=1e-12)


def test_odometry_jacobian_is_the_translation():
    # |det ∂(x', y', θ')/∂(δrot1, δtrans, δrot2)| = |δtrans|
    x0, c, eps = np.array([0.2, -0.1, 0.4]), np.array([0.3, 0.7, -0.2]), 1e-6
    J = np.empty((3, 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = eps
        J[:, j] = (mm.odometry_forward(x0, *(c + e)) - mm.odometry_forward(x0, *(c - e))) / (2 * eps)
    assert_allclose(abs(np.linalg.det(J)), 0.7, rtol=1e-8)


def test_noiseless_samplers_return_the_noiseless_motion():
    rng = np.random.default_rng(0)
    s = mm.sample_velocity((0, 0, 0), (1.0, 1.0), 1.0, np.zeros(6), 3, rng)
    assert_allclose(s, np.tile([math.sin(1), 1 - math.cos(1), 1.0], (3, 1)), atol=1e-15)
    s = mm.sample_odometry((1, 1, 0.5), (0, 0, 0), (1, 0, 0.2), np.zeros(4), 2, rng)
    assert_allclose(s, np.tile([1 + math.cos(0.5), 1 + math.sin(0.5), 0.7], (2, 1)), atol=1e-15)
