"""The group SE(2): exp ∘ log = id, group axioms, the adjoint identity, the right Jacobian vs finite differences."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import se2
from pose_uncertainty.core import trajectories as tr


def _wrapped(a, b):
    """Poses equal with the heading compared on the circle."""
    assert_allclose(a[..., :2], b[..., :2], atol=1e-12)
    assert_allclose(np.cos(a[..., 2] - b[..., 2]), 1.0, atol=1e-12)


def test_exp_log_round_trip_and_limits():
    rng = np.random.default_rng(123)
    xi = rng.normal(size=(200, 3))
    xi[:5, 2] = [0.0, 1e-9, -1e-7, 1e-5, 2e-4]  # the w → 0 limit and both series branches
    assert_allclose(se2.log(se2.exp(xi)), xi, atol=1e-12)
    # straight twist: exp((s, 0, 0)) = (s, 0, 0); quarter arc of radius 1: (1, 1, π/2)
    assert_allclose(se2.exp([2.0, 0.0, 0.0]), [2.0, 0.0, 0.0])
    assert_allclose(se2.exp([np.pi / 2, 0.0, np.pi / 2]), [1.0, 1.0, np.pi / 2], atol=1e-15)


def test_exp_of_step_twist_is_the_exact_arc():
    t = tr.arc(radius=0.7, angle=1.3, dt=0.05, track=0.2)
    mu = np.zeros(3)
    for ds, dth in zip(t.ds, t.dtheta, strict=True):
        mu = se2.compose(mu, se2.exp([ds, 0.0, dth]))
    assert_allclose(mu, t.poses[-1], atol=1e-12)


def test_adjoint_identity():
    rng = np.random.default_rng(7)
    g = rng.normal(size=(50, 3))
    e = 0.3 * rng.normal(size=(50, 3))
    lhs = se2.compose(se2.compose(g, se2.exp(e)), se2.inverse(g))
    rhs = se2.exp(np.einsum("nij,nj->ni", se2.adjoint(g), e))
    # compare poses with wrapped heading
    assert_allclose(lhs[:, :2], rhs[:, :2], atol=1e-12)
    assert_allclose(np.cos(lhs[:, 2] - rhs[:, 2]), 1.0, atol=1e-12)


@pytest.mark.parametrize("xi", [[0.4, -0.3, 0.9], [1.0, 0.2, 1e-6], [0.5, 0.5, 0.0], [-2, 1, 3.0]])
def test_right_jacobian_against_finite_differences(xi):
    xi = np.asarray(xi, dtype=float)
    g_inv = se2.inverse(se2.exp(xi))
    h = 1e-6
    Jn = np.empty((3, 3))
    for j in range(3):
        d = np.zeros(3)
        d[j] = h
        plus = se2.log(se2.compose(g_inv, se2.exp(xi + d)))
        minus = se2.log(se2.compose(g_inv, se2.exp(xi - d)))
        Jn[:, j] = (plus - minus) / (2 * h)
    # central differences: error O(h²) ≈ 1e-12 plus rounding ≈ 1e-16/h
    assert_allclose(se2.right_jacobian(xi), Jn, atol=1e-8)


def test_exp_of_log_is_the_identity_on_unwrapped_poses():
    rng = np.random.default_rng(123)
    g = rng.normal(size=(200, 3)) * [2.0, 2.0, 2.5]  # |θ| < 2π: one-to-one with the twist
    g[:4, 2] = [0.0, 1e-9, 5e-5, -3e-4]  # both sides of the series threshold
    assert_allclose(se2.exp(se2.log(g)), g, atol=1e-12)


def test_compose_is_associative_with_identity_and_inverse():
    rng = np.random.default_rng(123)
    a, b, c = rng.normal(size=(3, 100, 3))
    assert_allclose(se2.compose(se2.compose(a, b), c), se2.compose(a, se2.compose(b, c)), atol=1e-12)
    assert_allclose(se2.compose(a, np.zeros(3)), a)
    assert_allclose(se2.compose(a, se2.inverse(a)), np.zeros((100, 3)), atol=1e-12)
    assert_allclose(se2.compose(se2.inverse(a), a), np.zeros((100, 3)), atol=1e-12)


def test_adjoint_is_a_homomorphism_and_its_inverse_is_the_adjoint_of_the_inverse():
    rng = np.random.default_rng(123)
    a, b = rng.normal(size=(2, 50, 3))
    assert_allclose(se2.adjoint(se2.compose(a, b)), se2.adjoint(a) @ se2.adjoint(b), atol=1e-12)
    assert_allclose(se2.adjoint_inverse(a), np.linalg.inv(se2.adjoint(a)), atol=1e-12)
    assert se2.adjoint(a).shape == (50, 3, 3)


def test_cosc_matches_its_closed_form_and_vanishes_at_zero():
    w = np.array([1e-3, 0.1, 1.0, 3.0, -2.0])
    assert_allclose(se2.cosc(w), 2.0 * np.sin(0.5 * w) ** 2 / w, rtol=1e-12)  # 1 − cos w = 2 sin²(w/2)
    assert se2.cosc(np.array(0.0)) == 0.0


def test_a_wrong_last_axis_is_refused():
    with pytest.raises(ValueError, match=r"xi must have shape \(\.\.\., 3\)"):
        se2.exp([1.0, 2.0])
    with pytest.raises(ValueError, match=r"pose must have shape \(\.\.\., 3\)"):
        se2.log(np.zeros((4, 2)))
    with pytest.raises(ValueError, match=r"b must have shape \(\.\.\., 3\)"):
        se2.compose(np.zeros(3), np.zeros(4))
