"""Exponential coordinates of SE(2): propagation and densities (the group itself: test_se2.py)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import se2
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import covariance as cv
from pose_uncertainty.methods import expcoords as ec
from pose_uncertainty.methods import sampling as sp


def test_closed_form_equals_recursion():
    t = tr.s_curve(radius=1.0, dt=0.02, track=0.2)
    a = ec.propagate(t, 4e-4, 9e-4, cov0=np.diag([1e-4, 2e-4, 1e-3]))
    b = ec.propagate_recursive(t, 4e-4, 9e-4, cov0=np.diag([1e-4, 2e-4, 1e-3]))
    assert_allclose(a.covs, b.covs, rtol=1e-10, atol=1e-16)
    # batched constants broadcast
    c = ec.propagate(t, np.array([4e-4, 1e-4]), np.array([9e-4, 1e-4]))
    assert c.covs.shape == (2, t.n_steps + 1, 3, 3)
    assert_allclose(c.covs[0], ec.propagate(t, 4e-4, 9e-4).covs, rtol=1e-12)


@pytest.mark.parametrize("name", ["straight", "circle", "right_angles"])
def test_first_order_agrees_with_method_a(name):
    # to first order μ exp(ε) ≈ μ + (R ε_v, ε_θ): both linearise the same model about the same
    # path; they differ only by midpoint vs exact steps and J_r ≠ I, both O(dt) at dt = 0.005.
    t = tr.build(name, dt=0.005, track=0.2)
    e = ec.propagate(t, 5e-4, 3e-4)
    a = cv.propagate(t, 5e-4, 3e-4)
    cart = ec.to_cartesian_cov(e.poses[-1], e.covs[-1])
    assert_allclose(cart, a.covs[-1], rtol=1e-2, atol=1e-3 * np.abs(a.covs[-1]).max())


def test_covariance_matches_log_mapped_monte_carlo():
    # short path, small noise: the sample covariance of ε = log(μ⁻¹ g) of exact-arc Monte Carlo
    # matches Σ. Sample covariance entries have relative s.e. ≈ √(2/n) ≈ 0.6 % at n = 5·10⁴;
    # the first-order (BCH) error is O(σ_θ²) ≈ 1 % at σ_θ ≈ 0.07 rad. Tolerance 5 %.
    t = tr.arc(radius=1.0, angle=0.5, dt=0.01, track=0.2)
    k = 2e-4
    e = ec.propagate(t, k, k)
    cloud = sp.sample_end_poses(t, k, k, 50_000, np.random.default_rng(11), method="exact")
    eps = ec.coordinates(cloud, e.poses[-1])
    S = e.covs[-1]
    emp = np.cov(eps.T)
    scale = np.sqrt(np.outer(np.diag(S), np.diag(S)))
    assert_allclose(emp / scale, S / scale, atol=0.05)


def test_planar_marginal_integrates_to_one_and_matches_samples():
    mu = np.array([1.0, 0.5, 0.3])
    S = np.array([[4e-4, 0.0, 0.0], [0.0, 8e-3, 1.2e-2], [0.0, 1.2e-2, 2.5e-2]])
    rng = np.random.default_rng(5)
    draws = ec.sample(mu, S, 200_000, rng)
    lo, hi = draws[:, :2].min(0) - 0.05, draws[:, :2].max(0) + 0.05
    x = np.linspace(lo[0], hi[0], 301)
    y = np.linspace(lo[1], hi[1], 301)
    Z = ec.marginal_xy_grid(x, y, mu, S)
    mass = np.trapezoid(np.trapezoid(Z, y, axis=1), x)
    assert_allclose(mass, 1.0, atol=2e-3)
    # route 2: P(region) from the density vs the fraction of draws (binomial s.e. ≈ 1.1e-3)
    inside = (draws[:, 0] > 0.95) & (draws[:, 1] > 0.5)
    sel_x, sel_y = x > 0.95, y > 0.5
    p_region = np.trapezoid(np.trapezoid(Z[np.ix_(sel_x, sel_y)], y[sel_y], axis=1), x[sel_x])
    assert abs(p_region - inside.mean()) < 5 * 1.2e-3 + 5e-3  # + grid edge error


def test_pose_density_integrates_to_one_in_exp_coordinates():
    # ∫ p(g) dx dy dθ = 1: E over draws of 1/p(g) must equal the support volume — instead
    # check the change of variables: p(g)·|det J(ε)| = N(ε; 0, Σ) pointwise.
    mu = np.array([0.2, -0.1, 2.0])
    S = np.diag([1e-3, 2e-3, 0.3])
    eps = np.random.default_rng(9).multivariate_normal(np.zeros(3), S, size=100)
    g = se2.compose(mu, se2.exp(eps))
    lp = ec.logpdf_pose(g, mu, S)
    ln = -0.5 * np.einsum("ni,ij,nj->n", eps, np.linalg.inv(S), eps) - 0.5 * np.log(
        (2 * np.pi) ** 3 * np.linalg.det(S)
    )
    jac = (np.sin(eps[:, 2] / 2) / (eps[:, 2] / 2)) ** 2
    assert_allclose(lp + np.log(jac), ln, rtol=1e-10)


def test_pr_region_is_a_banana_with_the_right_mass():
    t = tr.straight(1.0, dt=0.01, track=0.2)
    e = ec.propagate(t, 5e-4, 5e-4)
    mu, S = e.poses[-1], e.covs[-1]
    rng = np.random.default_rng(2)
    lines = ec.pr_region_xy(mu, S, cv.PR_3SIGMA, rng, n=50_000)
    assert len(lines) >= 1
    line = max(lines, key=len)
    # the banana bends back: Method A's ellipse here has σ_xy = 0, so its across-track tips lie
    # at x = μ_x; the banana's tips (extreme y) lie 5 cm behind (≈ 3σ_x)
    tips = line[[line[:, 1].argmax(), line[:, 1].argmin()], 0]
    assert np.all(tips < mu[0] - 0.03)
    # points of fresh draws inside the contour polygon ≈ Pr (s.e. ≈ 5e-4 at n = 5·10⁴)
    from matplotlib.path import Path

    draws = ec.sample(mu, S, 50_000, np.random.default_rng(3))
    frac = Path(line).contains_points(draws[:, :2]).mean()
    assert abs(frac - cv.PR_3SIGMA) < 3e-3


def test_bad_input():
    with pytest.raises(ValueError, match="k_r must be >= 0"):
        ec.propagate(tr.straight(1.0), -1.0, 1e-4)
    with pytest.raises(ValueError, match="cov must have shape"):
        ec.pdf_xy([[0.0, 0.0]], [0, 0, 0], np.eye(2))


@pytest.mark.slow
def test_planar_density_resolves_a_thin_banana():
    # 20 m straight: the banana is far thinner than its length; the quadrature in the heading
    # must resolve it (a fixed 64-node rule left ripples that moved the 98.89 % coverage by 4 %)
    t = tr.straight(20.0, dt=0.01, track=0.2)
    E = ec.propagate(t, 5e-4, 5e-4)
    mu, S = E.poses[-1], E.covs[-1]
    pts = ec.sample(mu, S, 5000, np.random.default_rng(1))[:, :2]
    auto = ec.pdf_xy(pts, mu, S)
    finest = ec.pdf_xy(pts, mu, S, n_quad=8192)
    assert_allclose(auto, finest, rtol=1e-8)
    # and it is a density: integrates to 1 over a grid around the banana
    x = np.linspace(pts[:, 0].min() - 1, pts[:, 0].max() + 1, 400)
    y = np.linspace(pts[:, 1].min() - 1, pts[:, 1].max() + 1, 400)
    Z = ec.marginal_xy_grid(x, y, mu, S)
    assert_allclose(Z.sum() * (x[1] - x[0]) * (y[1] - y[0]), 1.0, atol=2e-3)
