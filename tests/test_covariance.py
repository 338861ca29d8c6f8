"""Method A: Jacobians, closed form on the straight line, two propagation routes, ellipses."""


import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import kinematics as kin
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import covariance as cv


def _f(p, ds_r, ds_l, b):
    return kin.step(p, (ds_r + ds_l) / 2, (ds_r - ds_l) / b, method="midpoint")


def test_jacobians_equal_finite_differences(rng):
    h = 1e-6
    for _ in range(20):
        p = rng.normal(size=3) * [1, 1, 3]
        sr, sl = rng.uniform(-0.5, 0.5, 2)
        b = rng.uniform(0.05, 0.6)
        J_p, J_d = cv.jacobians(p[2], sr, sl, b)
        num_p = np.stack(
            [(_f(p + h * e, sr, sl, b) - _f(p - h * e, sr, sl, b)) / (2 * h) for e in np.eye(3)], -1
        )
        num_d = np.stack(
            [
                (_f(p, sr + h, sl, b) - _f(p, sr - h, sl, b)) / (2 * h),
                (_f(p, sr, sl + h, b) - _f(p, sr, sl - h, b)) / (2 * h),
            ],
            -1,
        )
        assert_allclose(J_p, num_p, atol=1e-8)
        assert_allclose(J_d, num_d, atol=1e-8)


def test_jacobians_batched_equal_single(rng):
    th, sr, sl = rng.normal(size=(3, 7, 5))
    J_p, J_d = cv.jacobians(th, sr, sl, 0.2)
    assert J_p.shape == (7, 5, 3, 3)
    assert J_d.shape == (7, 5, 3, 2)
    one_p, one_d = cv.jacobians(th[3, 2], sr[3, 2], sl[3, 2], 0.2)
    assert_allclose(J_p[3, 2], one_p)
    assert_allclose(J_d[3, 2], one_d)


@pytest.mark.parametrize(("k_r", "k_l", "b"), [(5e-4, 5e-4, 0.2), (9e-4, 1e-4, 0.1), (1e-4, 9e-4, 0.5)])
@pytest.mark.parametrize("length", [0.3, 1.0, 5.0])
def test_straight_line_closed_form(k_r, k_l, b, length):
    """Exact discrete closed form of the straight line (s = nΔ, K = k_r+k_l, D = k_r−k_l):

    σx² = K s/4, σy² = K/b² (s³/3 − sΔ²/12), σθ² = K s/b²,
    σxy = D s²/(4b), σxθ = D s/(2b), σyθ = K s²/(2b²).
    """
    t = tr.straight(length, dt=0.01, speed=1.0, track=b)
    res = cv.propagate(t, k_r, k_l)
    delta = t.ds[0]
    K, D = k_r + k_l, k_r - k_l
    for n in (1, t.n_steps // 2, t.n_steps):
        s = n * delta
        expected = np.array(
            [
                [K * s / 4, D * s**2 / (4 * b), D * s / (2 * b)],
                [D * s**2 / (4 * b), K / b**2 * (s**3 / 3 - s * delta**2 / 12), K * s**2 / (2 * b**2)],
                [D * s / (2 * b), K * s**2 / (2 * b**2), K * s / b**2],
            ]
        )
        assert_allclose(res.covs[n], expected, rtol=1e-10, atol=1e-18)


def test_across_track_outgrows_along_track():
    # claim 1: σy²/σx² = 4s²/(3b²) (from the closed form) — above 1 once s > (√3/2) b
    t = tr.straight(1.0, track=0.2)
    covs = cv.propagate(t, 5e-4, 5e-4).covs
    s = np.cumsum(t.ds)
    ratio = covs[1:, 1, 1] / covs[1:, 0, 0]
    assert_allclose(ratio, 4 * s**2 / (3 * 0.2**2) - 1 / 3 * (t.ds[0] / 0.2) ** 2, rtol=1e-9)
    assert ratio[-1] > 30


@pytest.mark.parametrize("name", ["arc", "circle", "rotation", "s_curve", "right_angles", "direct"])
def test_closed_form_equals_recursion(name):
    t = tr.build(name, dt=0.02, profile="ramp")
    k_r = np.array([5e-4, 9e-4, 1e-5])
    k_l = np.array([5e-4, 1e-4, 3e-5])
    S0 = np.array([[1e-4, 2e-5, 0.0], [2e-5, 3e-4, 1e-5], [0.0, 1e-5, 2e-4]])
    P1, C1 = cv.propagate_recursive(t.ds_r, t.ds_l, t.track, k_r, k_l, cov0=S0)
    res = cv.propagate(t, k_r, k_l, cov0=S0)
    assert res.covs.shape == (3, t.n_steps + 1, 3, 3)
    assert_allclose(res.poses, P1, rtol=0, atol=1e-12)
    scale = np.abs(C1).max(axis=(-1, -2), keepdims=True)
    assert_allclose(res.covs / scale, C1 / scale, rtol=0, atol=1e-12)


def test_batch_over_track_equals_single_calls():
    t = tr.arc(radius=1.0, angle=1.0, dt=0.05)
    tracks = np.array([0.1, 0.2, 0.5])
    res = cv.propagate(t, 5e-4, [1e-4, 5e-4, 9e-4], track=tracks)
    for i, b in enumerate(tracks):
        one = cv.propagate_travels(t.ds_r, t.ds_l, b, 5e-4, [1e-4, 5e-4, 9e-4][i])
        assert_allclose(res.covs[i], one[1], rtol=1e-12, atol=1e-20)


def test_covariance_linear_in_k_and_symmetric_psd():
    t = tr.s_curve(dt=0.02)
    a = cv.propagate(t, 2e-4, 0.0).covs
    b = cv.propagate(t, 0.0, 3e-4).covs
    ab = cv.propagate(t, 2e-4, 3e-4).covs
    assert_allclose(ab, a + b, rtol=1e-12, atol=1e-20)
    assert_allclose(ab, np.swapaxes(ab, -1, -2))
    assert np.linalg.eigvalsh(ab[1:]).min() > -1e-15


def test_speed_profile_has_no_effect_in_the_limit():
    # claim 3: final covariance depends on the travels, not on how fast they are driven
    for name in ("straight", "circle", "rotation"):
        c = cv.propagate(tr.build(name, dt=0.001), 5e-4, 5e-4).covs[-1]
        r = cv.propagate(tr.build(name, dt=0.001, profile="ramp"), 5e-4, 5e-4).covs[-1]
        assert_allclose(r, c, rtol=1e-5, atol=1e-6 * np.abs(c).max())


def test_wider_track_shrinks_across_track_and_unequal_k_tilts():
    # claim 4, on the straight line
    covs = cv.propagate(tr.straight(1.0), 5e-4, 5e-4, track=np.array([0.1, 0.2, 0.5])).covs[:, -1]
    assert covs[0, 1, 1] > covs[1, 1, 1] > covs[2, 1, 1]
    tilt = cv.propagate(tr.straight(1.0), [9e-4, 1e-4], [1e-4, 9e-4]).covs[:, -1]
    assert tilt[0, 0, 1] > 0 > tilt[1, 0, 1]
    alpha = cv.ellipse(tilt[:, :2, :2]).alpha
    assert_allclose(alpha[0], -alpha[1])


# --- ellipses ---------------------------------------------------------------------------


def _random_cov2(rng, n):
    A = rng.normal(size=(n, 2, 2))
    return A @ np.swapaxes(A, -1, -2) + 1e-3 * np.eye(2)


@pytest.mark.parametrize("pr", [0.5, 0.9, cv.PR_3SIGMA, 0.999])
def test_two_ellipse_methods_agree(rng, pr):
    S = _random_cov2(rng, 50)
    e = cv.ellipse(S, pr)
    pts = cv.ellipse_polyline(S, pr, center=np.zeros(2), n=20000)
    d = pts - 0.0
    # every polyline vertex lies on the Mahalanobis contour k
    m2 = np.einsum("...i,...ij,...j->...", d, np.linalg.inv(S)[:, None], d)
    assert_allclose(m2, cv.pr_to_k(pr), rtol=1e-10)
    r = np.linalg.norm(d, axis=-1)
    assert_allclose(r.max(axis=-1), e.a_major, rtol=1e-5)
    assert_allclose(r.min(axis=-1), e.a_minor, rtol=1e-5)
    far = d[np.arange(50), r.argmax(axis=-1)]
    ang = np.arctan2(far[:, 1], far[:, 0])
    assert_allclose(np.cos(2 * (ang - e.alpha)), 1.0, atol=1e-5)  # axis direction, mod π


def test_pr_98_89_is_three_sigma():
    assert_allclose(cv.PR_3SIGMA, 0.98889, atol=1e-5)
    assert_allclose(cv.pr_to_k(cv.PR_3SIGMA), 9.0)
    e = cv.ellipse(np.diag([4.0, 1.0]), cv.PR_3SIGMA)
    assert_allclose([e.a_major, e.a_minor, e.alpha], [6.0, 3.0, 0.0], atol=1e-12)
    assert_allclose(cv.k_to_pr(cv.pr_to_k(0.37)), 0.37)


def test_singular_covariance_polyline():
    # at the start of a path Σ = 0; on a rotation in place Σ_xy is rank-1 or 0
    for S in (np.zeros((2, 2)), np.array([[1.0, 1.0], [1.0, 1.0]]), np.diag([0.0, 2.0])):
        pts = cv.ellipse_polyline(S, 0.9, center=[1.0, 2.0], n=64)
        assert np.all(np.isfinite(pts))
        e = cv.ellipse(S, 0.9)
        r = np.linalg.norm(pts - [1.0, 2.0], axis=-1)
        assert_allclose(r.max(), e.a_major, rtol=1e-3, atol=1e-12)
        assert_allclose(e.a_minor, 0.0, atol=1e-7)


@pytest.mark.parametrize("pr", [0.0, 1.0, -0.1, 1.5, float("nan")])
def test_bad_probability(pr):
    with pytest.raises(ValueError, match=r"pr must be .*\(0, 1\)|pr must be finite"):
        cv.ellipse(np.eye(2), pr)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"k_r": -1e-4}, r"k_r must be >= 0 \(allowed: \[0, inf\)\), got -0\.0001"),
        ({"k_l": float("inf")}, r"k_l must be finite"),
        ({"track": 0.0}, r"track must be > 0 \(allowed: \(0, inf\)\), got 0\.0"),
        ({"track": -0.2}, r"track must be > 0"),
        ({"cov0": np.diag([1.0, -1.0, 1.0])}, r"cov0 must be positive semi-definite"),
        ({"cov0": np.eye(2)}, r"cov0 must have shape \(\.\.\., 3, 3\)"),
    ],
)
def test_bad_propagation_input(kwargs, match):
    args = {"k_r": 5e-4, "k_l": 5e-4}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        cv.propagate(tr.straight(1.0), **args)


def test_empty_travels_rejected():
    with pytest.raises(ValueError, match="N >= 1"):
        cv.propagate_travels(np.array([]), np.array([]), 0.2, 1e-4, 1e-4)


def test_a_circle_within_rounding_has_no_orientation_and_a_segment_no_width() -> None:
    # A rotation in place gives an exactly circular (x, y) covariance, computed with rounding:
    # its orientation is then rounding noise (0.135 vs 0.148 rad between two exact-equal
    # programs). Every perturbation of a circle at the last bits gives α = 0 and equal axes.
    rng = np.random.default_rng(3)
    a = 7.0e-5
    for _ in range(20):
        S = a * np.eye(2) + a * 1e-15 * rng.standard_normal((2, 2))
        S = 0.5 * (S + S.T)
        e = cv.ellipse(S)
        assert e.alpha == 0.0
        assert e.a_major == e.a_minor
    # a segment (rank 1) perturbed at the last bits: no width, and its polyline moves by
    # rounding only (without the cut, √ of a ±1e-20 eigenvalue made it move by 1e-9 of its size)
    u = np.array([np.cos(0.5), np.sin(0.5)])
    base = 2.5e-5 * np.outer(u, u)
    ref = cv.ellipse_polyline(base)
    for _ in range(20):
        S = base + 2.5e-5 * 1e-15 * rng.standard_normal((2, 2))
        S = 0.5 * (S + S.T)
        assert cv.ellipse(S).a_minor == 0.0
        assert np.max(np.abs(cv.ellipse_polyline(S) - ref)) <= 1e-13 * np.max(np.abs(ref))
    # a genuine ellipse keeps its orientation and both axes
    e = cv.ellipse(np.array([[4.0, 1.0], [1.0, 2.0]]))
    assert e.alpha == pytest.approx(0.5 * np.arctan2(2.0, 2.0))
    assert e.a_minor > 0.0
