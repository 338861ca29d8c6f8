"""Accuracy measures: each checked where the right answer is known, and by two routes."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.analysis import accuracy as ac
from pose_uncertainty.core import stats
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import covariance as cv
from pose_uncertainty.methods import expcoords as ec
from pose_uncertainty.methods import sampling as sp
from pose_uncertainty.methods.maps import ProbabilityMap

N = 40_000
MU = np.array([1.0, 0.2, 0.4])
SIGMA = np.array([[4e-4, 1e-4, 0.0], [1e-4, 6e-3, 8e-3], [0.0, 8e-3, 2e-2]])


def _se(pr, n=N):
    return math.sqrt(pr * (1 - pr) / n)


def test_pr_labels():
    assert [ac.pr_label(p) for p in ac.PRS] == ["50", "90", "98.89"]


def test_hellinger_and_kl_known_values():
    p = np.array([0.5, 0.5, 0.0])
    q = np.array([0.25, 0.25, 0.5])
    assert ac.hellinger(p, p) == 0.0
    assert_allclose(ac.hellinger(p, np.array([0.0, 0.0, 1.0])), 1.0)
    assert_allclose(ac.hellinger(p, q), math.sqrt(1 - 2 * math.sqrt(0.125)))
    assert_allclose(ac.kl_divergence(p, q), math.log(2.0))
    assert_allclose(ac.kl_divergence(p, p), 0.0)


def test_cartesian_measures_on_exact_gaussian_samples():
    rng = np.random.default_rng(123)
    s = rng.multivariate_normal(MU, SIGMA, size=N)
    r = ac.evaluate_cartesian(s, MU, SIGMA)
    for pr in ac.PRS:
        lab = ac.pr_label(pr)
        assert abs(r[f"coverage_xy_{lab}"] - pr) < 4 * _se(pr)
        assert abs(r[f"coverage_pose_{lab}"] - pr) < 4 * _se(pr)
    # NEES has mean d and variance 2d/n
    assert abs(r["nees_pose"] - 3) < 4 * math.sqrt(6 / N)
    assert abs(r["nees_xy"] - 2) < 4 * math.sqrt(4 / N)
    # mean log-likelihood → minus the entropy −½ log det(2πe Σ); its s.e. is √(d/2)/√n
    ent3 = 0.5 * np.log(np.linalg.det(2 * np.pi * np.e * SIGMA))
    assert abs(r["loglik_pose"] + ent3) < 4 * math.sqrt(1.5 / N)
    assert_allclose(r["model_mass_on_grid"], 1.0, atol=2e-3)


def test_distance_of_a_model_to_its_own_samples_is_the_floor():
    rng = np.random.default_rng(5)
    s = rng.multivariate_normal(MU, SIGMA, size=N)
    res = ac.compare_methods(s, (MU, SIGMA), None, rng)
    # both are histograms of N draws from the same law against that law: same expected distance
    # (Hellinger² of a histogram ≈ (cells − 1)/(8N); relative spread between two draws ≲ 10 %)
    assert_allclose(res["cartesian"]["hellinger"], res["monte_carlo"]["hellinger_floor"], rtol=0.15)
    assert res["grid"]["nx"] == 60


def test_expcoords_measures_on_exact_banana_samples():
    rng = np.random.default_rng(7)
    s = ec.sample(MU, SIGMA, N, rng)
    r = ac.evaluate_expcoords(s, MU, SIGMA, rng, n_threshold=100_000)
    for pr in ac.PRS:
        lab = ac.pr_label(pr)
        # + threshold s.e. from the 1e5 draws
        tol = 4 * math.hypot(_se(pr), _se(pr, 100_000))
        assert abs(r[f"coverage_xy_{lab}"] - pr) < tol
        assert abs(r[f"coverage_pose_{lab}"] - pr) < 4 * _se(pr)
    assert abs(r["nees_pose"] - 3) < 4 * math.sqrt(6 / N)
    # and the Cartesian Gaussian fitted to the same banana by moments misses it
    m, C = s.mean(0), np.cov(s.T)
    rc = ac.evaluate_cartesian(s, m, C)
    assert rc["loglik_xy"] < r["loglik_xy"]


def test_gridded_route_agrees_with_ellipse_route():
    # the HDR of a finely gridded Gaussian is its ellipse: two routes to one coverage
    rng = np.random.default_rng(9)
    C2 = SIGMA[:2, :2]
    s = rng.multivariate_normal(MU, SIGMA, size=N)
    x = np.linspace(MU[0] - 0.15, MU[0] + 0.15, 301)
    y = np.linspace(MU[1] - 0.5, MU[1] + 0.5, 401)
    X, Y = np.meshgrid(x, y, indexing="ij")
    d = np.stack([X - MU[0], Y - MU[1]], -1)
    v = np.exp(-0.5 * np.einsum("...i,ij,...j", d, np.linalg.inv(C2), d)) / (
        2 * np.pi * math.sqrt(np.linalg.det(C2))
    )
    dens = ProbabilityMap.from_density_xy(x, y, v)
    grid_cov = ac.coverage_gridded(dens, s[:, :2])
    ell_cov = ac.coverage_ellipse(s[:, :2], MU[:2], C2)
    for lab in ell_cov:
        # the cell discretisation moves the boundary by ≲ half a cell: ≤ 0.4 % of the mass here
        assert abs(grid_cov[lab] - ell_cov[lab]) < 0.004
    g = ac.evaluate_gridded(dens, s)
    c = ac.evaluate_cartesian(s, MU, SIGMA)
    assert_allclose(g["loglik_xy"], c["loglik_xy"], atol=0.01)
    assert_allclose(g["hellinger"], c["hellinger"], atol=0.01)
    assert g["fraction_off_map"] == 0.0


@pytest.mark.slow
def test_the_cartesian_gaussian_already_fails_on_the_1m_line():
    # the lead's measurement: 96.6 % of the particles inside the 98.89 % ellipse (1e6 particles);
    # with 4e4 particles the s.e. of a coverage near 0.97 is 0.0009
    t = tr.straight(1.0, dt=0.01, track=0.2)
    s = sp.sample_end_poses(t, 5e-4, 5e-4, N, np.random.default_rng(1))
    A = cv.propagate(t, 5e-4, 5e-4)
    E = ec.propagate(t, 5e-4, 5e-4)
    res = ac.compare_methods(s, (A.poses[-1], A.covs[-1]), (E.poses[-1], E.covs[-1]),
                             np.random.default_rng(2))
    lab = ac.pr_label(cv.PR_3SIGMA)
    assert abs(res["cartesian"][f"coverage_xy_{lab}"] - 0.966) < 0.004
    assert abs(res["expcoords"][f"coverage_xy_{lab}"] - cv.PR_3SIGMA) < 0.004
    assert res["expcoords"]["hellinger"] < res["cartesian"]["hellinger"]
    assert res["expcoords"]["loglik_pose"] > res["cartesian"]["loglik_pose"]
    flat = ac.flatten(res)
    assert "accuracy_cartesian_coverage_xy_98_89" in flat


@pytest.mark.slow
def test_accuracy_vs_distance_rows():
    t = tr.straight(2.0, dt=0.02, track=0.2)
    rows = ac.accuracy_vs_distance(t, 5e-4, 5e-4, 5000, np.random.default_rng(3), n_checkpoints=2)
    assert [r["step"] for r in rows] == [50, 100]
    assert_allclose([r["distance"] for r in rows], [1.0, 2.0])
    assert set(rows[0]) >= {"grid", "monte_carlo", "cartesian", "expcoords"}


def test_bad_input():
    with pytest.raises(ValueError, match=r"samples must have shape \(n, 3\)"):
        ac.evaluate_cartesian(np.zeros((1, 3)), MU, SIGMA)
    with pytest.raises(ValueError, match=r"density must have shape \(nx, ny\) = \(3, 4\)"):
        ProbabilityMap.from_density_xy(np.arange(3.0), np.arange(4.0), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="pr must be a probability"):
        stats.hdr_region(np.ones(4) / 4, 1.5)


def test_a_gaussian_with_no_mass_on_the_clouds_grid_gives_undefined_distances_not_an_error() -> None:
    # A long path's cloud can lie where Method A's Gaussian has no mass at all (a 400 m straight
    # with 100 particles did): the shape distances on the cells are undefined (NaN), the model's
    # mass on the grid says why, and the coverage is still measured (0: no point inside).
    rng = np.random.default_rng(5)
    cloud = np.column_stack([rng.normal(100.0, 0.01, 200), rng.normal(50.0, 0.01, 200), np.zeros(200)])
    res = ac.compare_methods(cloud, (np.zeros(3), np.diag([1e-4, 1e-4, 1e-4])), None, rng, prs=(0.9,))
    assert res["cartesian"]["model_mass_on_grid"] == 0.0
    assert math.isnan(res["cartesian"]["hellinger"])
    assert math.isnan(res["cartesian"]["kl"])
    assert math.isnan(res["monte_carlo"]["hellinger_floor"])
    assert res["cartesian"]["coverage_xy_90"] == 0.0
    # where both have mass the distance is defined and in [0, 1]
    near = ac.compare_methods(cloud, (np.array([100.0, 50.0, 0.0]), np.diag([1e-4, 1e-4, 1e-4])), None, rng,
                              prs=(0.9,))
    assert 0.0 <= near["cartesian"]["hellinger"] <= 1.0


def test_a_one_step_covariance_has_no_planar_banana_density_and_says_so() -> None:
    # One step of a two-wheel drive: Σ of the exponential coordinates has rank 2, its (x, y) block
    # given θ is singular, and the banana's planar density (by conditioning on θ) does not exist.
    # The planar measures are NaN; the pose-space ones are still measured. (The thesis's one-step
    # arc with Monte Carlo crashed the run before.)
    t = tr.arc(radius=1.0, angle=1.0, speed=1.0, angular_speed=1.0, dt=1.0)
    cloud = sp.sample_end_poses(t, 5e-4, 5e-4, 2000, np.random.default_rng(2))
    g = ec.propagate(t, 5e-4, 5e-4)
    with pytest.raises(ec.SingularConditionalError, match="positive definite in"):
        ec.pdf_xy(cloud[:, :2], g.poses[-1], g.covs[-1])
    res = ac.evaluate_expcoords(cloud, g.poses[-1], g.covs[-1], np.random.default_rng(3), prs=(0.9,))
    assert math.isnan(res["coverage_xy_90"])
    assert math.isnan(res["hellinger"])
    assert math.isnan(res["loglik_xy"])
    assert 0.0 <= res["coverage_pose_90"] <= 1.0
