"""The one grid type and the one convention of each statistic (core.grids, core.stats)."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import stats
from pose_uncertainty.core.grids import Grid


@pytest.mark.parametrize("ntheta", [1, 7, 18, 36, 72, 90, 180, 360])
@pytest.mark.parametrize("theta0", [0.0, 0.3, -math.pi, math.pi, 1.0, -2.5])
def test_heading_normalisation_is_idempotent(ntheta, theta0):
    # normalising an already normalised first heading must not move the labels by a cell
    g = Grid(0.0, 0.0, 2, 2, 0.1, 0.1, ntheta, theta0)
    assert Grid(0.0, 0.0, 2, 2, 0.1, 0.1, ntheta, g.theta0).theta0 == g.theta0
    assert -math.pi <= g.theta0 < -math.pi + 2 * math.pi / ntheta
    # theta0 is still a cell centre: some cell's heading equals theta0 modulo 2π
    d = np.angle(np.exp(1j * (g.theta - theta0)))
    assert np.min(np.abs(d)) < 1e-9


def test_planar_histogram_equals_numpy_histogram2d():
    rng = np.random.default_rng(3)
    xy = rng.normal(size=(20_000, 2)) * [0.3, 1.2] + [1.0, -2.0]
    g = Grid.covering(xy, n_bins=37)
    h, _, _ = np.histogram2d(xy[:, 0], xy[:, 1], bins=(g.x_edges, g.y_edges))
    assert_allclose(g.histogram_xy(xy), h / len(xy), atol=1e-12)
    assert g.histogram_xy(xy).sum() == pytest.approx(1.0)  # the covering grid holds every point


def test_pose_histogram_marginalises_to_the_planar_one():
    rng = np.random.default_rng(4)
    poses = np.column_stack([rng.normal(size=5000), rng.normal(size=5000), rng.uniform(-9, 9, 5000)])
    g = Grid.centered((0.0, 0.0, 0.0), size=4.0, resolution=0.25, theta_resolution=math.radians(30))
    assert_allclose(g.histogram(poses).sum(axis=2), g.histogram_xy(poses), atol=1e-15)
    assert_allclose(g.histogram(poses).sum(axis=(0, 1)).sum(), g.histogram_xy(poses).sum())


def test_hdr_region_of_a_gaussian_is_its_ellipse():
    # two routes to one area: the HDR of a finely gridded Gaussian and π k √det Σ
    h = 0.01
    x = np.arange(-1.5, 1.5, h)
    X, Y = np.meshgrid(x, x, indexing="ij")
    C = np.array([[0.04, 0.01], [0.01, 0.09]])
    P = np.linalg.inv(C)
    mass = np.exp(-0.5 * (P[0, 0] * X**2 + 2 * P[0, 1] * X * Y + P[1, 1] * Y**2)) * h * h
    mass /= 2 * math.pi * math.sqrt(np.linalg.det(C))
    for pr in (0.5, 0.9, stats.PR_3SIGMA):
        _, n_cells = stats.hdr_region(mass, pr, total=1.0)
        area = math.pi * float(stats.pr_to_k(pr)) * math.sqrt(np.linalg.det(C))
        assert n_cells * h * h == pytest.approx(area, rel=0.01)
    levels, cells = stats.hdr_region(mass, [0.5, 0.9])  # one sort, several levels
    assert levels[0] > levels[1]
    assert cells[0] < cells[1]
    assert math.isnan(stats.hdr_region(mass * 0.5, 0.9, total=1.0)[0])  # the grid holds less


def test_hdr_region_known_values_and_fractional_last_cell():
    m = np.array([0.05, 0.5, 0.15, 0.3])
    assert stats.hdr_region(m, 0.8) == (0.3, 2.0)  # 0.5 + 0.3 reaches 0.8 exactly
    level, n = stats.hdr_region(m, 0.875)  # half of the 0.15 cell still needed
    assert level == 0.15
    assert n == pytest.approx(2.5)


def test_hellinger_properties_and_convention():
    p = np.array([0.2, 0.3, 0.5, 0.0])
    q = np.array([0.0, 0.0, 0.0, 1.0])
    assert stats.hellinger(p, p) == 0.0
    assert_allclose(stats.hellinger(p, q), 1.0)
    r = np.array([0.25, 0.25, 0.25, 0.25])
    assert_allclose(stats.hellinger(p, r), stats.hellinger(r, p))
    # the convention: compared by shape on the cells (each side normalised)
    assert_allclose(stats.hellinger(p, 3 * r), stats.hellinger(p, r))
    with pytest.raises(ValueError, match="same shape"):
        stats.hellinger(p, p[:3])
    with pytest.raises(ValueError, match="positive total mass"):
        stats.hellinger(p, np.zeros(4))


def test_noise_floor_predicts_the_distance_of_a_histogram_from_its_own_distribution():
    rng = np.random.default_rng(1)
    p = rng.dirichlet(np.full(400, 0.5))
    n = 20_000
    hs = [stats.hellinger(p, rng.multinomial(n, p) / n) for _ in range(40)]
    # mean of 40 draws of H²: relative s.e. ≈ √(2/400)/√40 ≈ 1 %; allow 5 %
    assert_allclose(np.mean(np.square(hs)), stats.hellinger_noise_floor(p, n) ** 2, rtol=0.05)


def test_along_across_rotates_with_the_heading():
    C = np.array([[4.0, 0.0], [0.0, 1.0]])
    assert_allclose(stats.along_across(C, 0.0), [2.0, 1.0])
    assert_allclose(stats.along_across(C, math.pi / 2), [1.0, 2.0], atol=1e-12)
    # batch: a rotated covariance seen from the rotated heading is unchanged
    th = np.linspace(-3, 3, 7)
    R = np.stack([np.stack([np.cos(th), -np.sin(th)], -1), np.stack([np.sin(th), np.cos(th)], -1)], -2)
    rotated = R @ C @ np.swapaxes(R, -1, -2)
    assert_allclose(stats.along_across(rotated, th), np.tile([2.0, 1.0], (7, 1)), atol=1e-12)


def test_fit_growth_recovers_each_law():
    x = np.array([1.0, 2.0, 4.0, 8.0, 16.0])
    fit = stats.fit_growth(x, 3.0 * x**1.5)
    assert fit["power_exponent"] == pytest.approx(1.5, abs=1e-12)
    assert fit["power_rms_log_residual"] < 1e-12 < fit["exp_rms_log_residual"]
    fit = stats.fit_growth(x, 2.0 * np.exp(0.3 * x))
    assert fit["exp_rate"] == pytest.approx(0.3, abs=1e-12)
    assert fit["exp_rms_log_residual"] < 1e-12 < fit["power_rms_log_residual"]
    with pytest.raises(ValueError, match="at least 3 positive points"):
        stats.fit_growth([1.0, 2.0], [1.0, 2.0])


def test_chi2_ppf_table_holds_scipys_values_bit_for_bit():
    from scipy.special import chdtri

    from pose_uncertainty.core.stats import _CHI2_PPF

    for (pr, dof), value in _CHI2_PPF.items():
        assert float(chdtri(dof, 1.0 - pr)) == value, (pr, dof)


@pytest.mark.parametrize("dof", [1, 2, 3, 7.5])
@pytest.mark.parametrize("pr", [0.5, 0.9, 0.95, stats.PR_3SIGMA, 0.7])
def test_chi2_ppf_equals_scipy_stats(pr, dof):
    from scipy.stats import chi2

    assert stats.chi2_ppf(pr, dof) == pytest.approx(chi2.ppf(pr, dof), rel=1e-12)
    many = stats.chi2_ppf(np.array([pr, 0.25]), dof)  # arrays: computed, not looked up
    assert many == pytest.approx(chi2.ppf([pr, 0.25], dof), rel=1e-12)
