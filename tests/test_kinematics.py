"""Kinematics: the three integration methods, continuity at ω = 0, inverse kinematics."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import kinematics as kin


def test_wheel_body_round_trip(rng):
    v_r, v_l = rng.normal(size=(2, 50))
    b = rng.uniform(0.05, 1.0, size=50)
    V, w = kin.wheel_to_body(v_r, v_l, b)
    assert_allclose(kin.body_to_wheel(V, w, b), (v_r, v_l), rtol=1e-14, atol=1e-15)


def test_exact_arc_equals_icc_rotation(rng):
    # route 1: x' = x + R(sin(θ+Δθ) − sin θ), y' = y − R(cos(θ+Δθ) − cos θ); route 2: the kernel
    pose = rng.normal(size=(200, 3))
    ds = rng.uniform(-1, 1, 200)
    dth = rng.uniform(-3, 3, 200)
    R = ds / dth
    x = pose[:, 0] + R * (np.sin(pose[:, 2] + dth) - np.sin(pose[:, 2]))
    y = pose[:, 1] - R * (np.cos(pose[:, 2] + dth) - np.cos(pose[:, 2]))
    got = kin.step(pose, ds, dth, method="exact")
    assert_allclose(got[:, 0], x, rtol=1e-12, atol=1e-12)
    assert_allclose(got[:, 1], y, rtol=1e-12, atol=1e-12)
    assert_allclose(got[:, 2], pose[:, 2] + dth)


@pytest.mark.parametrize("eps", [1e-4, 1e-8, 1e-12, 0.0, -1e-12, -1e-8])
def test_exact_arc_continuous_through_zero_turn(eps):
    pose = np.array([0.3, -0.2, 0.7])
    got = kin.step(pose, 1.0, eps, method="exact")
    straight = pose + np.array([math.cos(0.7), math.sin(0.7), 0.0])
    # deviation from the straight line is ~ Δs·Δθ/2
    assert_allclose(got[:2], straight[:2], atol=abs(eps) + 1e-15)
    assert np.all(np.isfinite(got))


def test_exact_circle_closes_for_any_step_count():
    for n in (1, 3, 17, 1000):
        dth = np.full(n, 2 * math.pi / n)
        ds = dth * 1.5  # radius 1.5
        end = kin.integrate(ds, dth, method="exact")[-1]
        assert_allclose(end[:2], [0.0, 0.0], atol=1e-12)
        assert_allclose(end[2], 2 * math.pi)


def test_integration_orders_against_exact_arc():
    # quarter circle of radius 1: Euler is first order, midpoint second order in the step
    errs = {m: [] for m in ("euler", "euler_end", "midpoint")}
    for n in (50, 100, 200):
        dth = np.full(n, math.pi / 2 / n)
        exact = kin.integrate(dth, dth, method="exact")[-1, :2]
        for m, err in errs.items():
            err.append(np.linalg.norm(kin.integrate(dth, dth, method=m)[-1, :2] - exact))
    for m in ("euler", "euler_end"):
        assert_allclose(errs[m][0] / errs[m][1], 2.0, rtol=0.02)
        assert_allclose(errs[m][1] / errs[m][2], 2.0, rtol=0.02)
    assert_allclose(errs["midpoint"][0] / errs["midpoint"][1], 4.0, rtol=0.02)


def test_integrate_matches_stepwise(rng):
    ds = rng.uniform(-0.1, 0.2, 40)
    dth = rng.uniform(-0.3, 0.3, 40)
    for method in kin.METHODS:
        poses = kin.integrate(ds, dth, (1.0, 2.0, 0.5), method=method)
        p = np.array([1.0, 2.0, 0.5])
        for i in range(40):
            p = kin.step(p, ds[i], dth[i], method=method)
            assert_allclose(poses[i + 1], p, rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize(
    ("x", "y"), [(1.0, 0.0), (1.0, 0.5), (0.2, 1.0), (-0.5, 0.5), (1.0, -2.0), (-1.0, -1e-3)]
)
def test_inverse_then_forward_lands_on_target(x, y):
    t, b = 2.0, 0.2
    v_r, v_l = kin.inverse_arc(x, y, t, b)
    V, w = kin.wheel_to_body(v_r, v_l, b)
    for n in (1, 10, 1000):  # the exact arc is exact for any number of steps
        end = kin.integrate(np.full(n, V * t / n), np.full(n, w * t / n), method="exact")[-1]
        assert_allclose(end[:2], [x, y], atol=1e-12)


def test_inverse_arc_batched(rng):
    x, y = rng.uniform(0.1, 2, 20), rng.uniform(-2, 2, 20)
    v_r, v_l = kin.inverse_arc(x, y, 1.0, 0.3)
    V, w = kin.wheel_to_body(v_r, v_l, 0.3)
    end = kin.integrate(V[:, None], w[:, None], np.zeros(3), method="exact")[:, -1]
    assert_allclose(end[:, :2], np.stack([x, y], -1), atol=1e-12)


def test_wrap_angle_range():
    a = np.linspace(-20, 20, 10001)
    w = kin.wrap_angle(a)
    assert np.all(w > -math.pi)
    assert np.all(w <= math.pi)
    assert_allclose(np.cos(w), np.cos(a), atol=1e-12)
    assert kin.wrap_angle(math.pi) == math.pi
    assert kin.wrap_angle(-math.pi) == math.pi


def test_wrap_angle_of_angles_in_range_is_the_modulo_bit_for_bit():
    # the shortcut for large arrays already in (−π, π] (no division) against mod, with the edges:
    # ±π, the neighbours of ±π, ±0, tiny and random angles; one angle out of range (or NaN) takes mod for all
    edges = [math.pi, -math.pi, np.nextafter(math.pi, 0), np.nextafter(-math.pi, 0), 0.0, -0.0, 1e-300, -1e-300]
    a = np.concatenate([edges, np.random.default_rng(3).uniform(-math.pi, math.pi, 1000)])
    for angles in (a, np.append(a, 7.0), np.append(a, np.nan)):
        want = np.where(np.mod(angles + np.pi, 2 * np.pi) - np.pi == -np.pi, np.pi, np.mod(angles + np.pi, 2 * np.pi) - np.pi)
        got = kin.wrap_angle(angles)
        np.testing.assert_array_equal(got, want)  # (NaN where NaN)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(want))


@pytest.mark.parametrize(
    ("track", "match"),
    [(0.0, r"track must be > 0.*got 0\.0"), (-0.1, r"track must be > 0.*-0\.1"),
     (float("nan"), "track must be finite"), (float("inf"), "track must be finite")],
)
def test_bad_track(track, match):
    with pytest.raises(ValueError, match=match):
        kin.wheel_to_body(1.0, 1.0, track)
    with pytest.raises(ValueError, match=match):
        kin.inverse_arc(1.0, 1.0, 1.0, track)


def test_bad_inputs():
    with pytest.raises(ValueError, match=r"t must be > 0"):
        kin.inverse_arc(1.0, 1.0, 0.0, 0.2)
    with pytest.raises(ValueError, match="negative x axis"):
        kin.inverse_arc(-1.0, 0.0, 1.0, 0.2)
    with pytest.raises(ValueError, match="method must be one of"):
        kin.integrate([1.0], [0.0], method="rk4")
    with pytest.raises(ValueError, match=r"pose must have shape \(\.\.\., 3\)"):
        kin.step([0.0, 0.0], 1.0, 0.0)
    with pytest.raises(ValueError, match="ds must be finite"):
        kin.integrate([np.nan], [0.0])
