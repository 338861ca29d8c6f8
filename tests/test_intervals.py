"""Guaranteed dead reckoning (Skalka 2011 §2.8): interval boxes and zonotopes contain every sampled
bounded-error trajectory, are exact where the reachable set is known, and the zonotope avoids the
boxes' dependency effect."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods.intervals import (
    BoundedWheelErrors,
    box_area,
    interval_cos,
    interval_dead_reckoning,
    interval_mul,
    interval_sin,
    sample_bounded_poses,
    wheel_error_generators,
)
from pose_uncertainty.methods.zonotopes import (
    Zonotope,
    hull_area,
    support,
    zonotope_area,
    zonotope_contains_xy,
    zonotope_dead_reckoning,
    zonotope_polygon,
)


def test_interval_functions_enclose_and_attain_the_range(rng):
    lo = rng.uniform(-10, 10, 500)
    hi = lo + rng.exponential(1.5, 500)
    t = np.linspace(0.0, 1.0, 4001)
    pts = lo[:, None] + (hi - lo)[:, None] * t  # dense points of each interval
    for fun, ref in ((interval_cos, np.cos), (interval_sin, np.sin)):
        a, b = fun(lo, hi)
        v = ref(pts)
        assert np.all(v >= a[:, None] - 1e-15)
        assert np.all(v <= b[:, None] + 1e-15)
        # exact: the dense grid comes within (h²/2) of the extremes (h = grid spacing ≤ 2.5e-3)
        assert_allclose(v.min(axis=1), a, atol=5e-6)
        assert_allclose(v.max(axis=1), b, atol=5e-6)
    c_lo, c_hi = rng.uniform(-2, 2, (2, 500))
    c_hi = c_lo + np.abs(c_hi)
    m_lo, m_hi = interval_mul(lo, hi, c_lo, c_hi)
    prod = pts[:, ::40, None] * (c_lo[:, None, None] + (c_hi - c_lo)[:, None, None] * t[None, None, ::40])
    assert np.all(prod.min(axis=(1, 2)) >= m_lo - 1e-12)
    assert np.all(prod.max(axis=(1, 2)) <= m_hi + 1e-12)
    assert_allclose(prod.min(axis=(1, 2)), m_lo, atol=1e-12)  # the end products are attained


def _curvy():
    return tr.s_curve(radius=1.0, speed=0.5, dt=0.06, track=0.2)


def _box_by_steps(ds, dth, A):
    """Reference: the box stepped one step at a time with the interval operations."""
    r_s, r_th = np.abs(A[:, 0]).sum(-1), np.abs(A[:, 1]).sum(-1)
    x, y, th = [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]
    for k in range(ds.size):
        p_lo, p_hi = th[0] + 0.5 * (dth[k] - r_th[k]), th[1] + 0.5 * (dth[k] + r_th[k])
        c = interval_cos(p_lo, p_hi)
        s = interval_sin(p_lo, p_hi)
        tx = interval_mul(ds[k] - r_s[k], ds[k] + r_s[k], *c)
        ty = interval_mul(ds[k] - r_s[k], ds[k] + r_s[k], *s)
        x = [x[0] + float(tx[0]), x[1] + float(tx[1])]
        y = [y[0] + float(ty[0]), y[1] + float(ty[1])]
        th = [th[0] + dth[k] - r_th[k], th[1] + dth[k] + r_th[k]]
    return np.array([x[0], y[0], th[0]]), np.array([x[1], y[1], th[1]])


# 1000 pulses per revolution of a 65 mm wheel (±0.1 mm a step) and slip within 0.5 % of the travel
ERRORS = BoundedWheelErrors.encoder(pulses_per_rev=1000, wheel_diameter=0.065, slip_rel=0.005)


def test_interval_box_equals_stepping_box_by_box():
    traj = _curvy()
    A = wheel_error_generators(traj.ds_r, traj.ds_l, traj.track, ERRORS)
    box = interval_dead_reckoning(traj.ds, traj.dtheta, A)
    lo, hi = _box_by_steps(traj.ds, traj.dtheta, A)
    assert_allclose(box.lo[0], lo, atol=1e-12)
    assert_allclose(box.hi[0], hi, atol=1e-12)


@pytest.mark.slow
def test_box_and_zonotope_contain_every_sampled_trajectory(rng):
    traj = _curvy()
    A = wheel_error_generators(traj.ds_r, traj.ds_l, traj.track, ERRORS)
    steps = [10, 25, traj.n_steps]
    kw = {"start_radius": (0.01, 0.01, 0.01), "checkpoints": steps}
    box = interval_dead_reckoning(traj.ds, traj.dtheta, A, **kw)
    zs = zonotope_dead_reckoning(traj.ds, traj.dtheta, A, **kw)
    ang = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    poses = sample_bounded_poses(traj.ds, traj.dtheta, A, 100_000, rng, vertex_fraction=0.6,
                                 directions=np.stack([np.cos(ang), np.sin(ang)], -1), **kw)  # fmt: skip
    assert poses.shape == (100_000, 3, 3)
    assert box.contains(poses).all()
    for c, z in enumerate(zs):
        assert zonotope_contains_xy(z, poses[:, c, :2]).all()
        assert np.all(np.abs(poses[:, c, 2] - z.center[2]) <= z.radius[2])
    end = zs[-1]
    area_z, area_b = zonotope_area(end), box_area(box)[-1]
    area_mc = hull_area(poses[:, -1, :2])
    assert area_mc <= area_z < area_b


def test_exact_on_a_straight_line_with_the_heading_known():
    # travel errors only (A_k = (w, 0)ᵀ): the reachable x is exactly [L − Σw, L + Σw], y = 0
    n, w = 200, 1e-3
    ds, dth = np.full(n, 0.01), np.zeros(n)
    A = np.zeros((n, 2, 1))
    A[:, 0, 0] = w
    box = interval_dead_reckoning(ds, dth, A, checkpoints=[100, n])
    zs = zonotope_dead_reckoning(ds, dth, A, checkpoints=[100, n])
    for c, k in enumerate((100, n)):
        exact = (0.01 * k - k * w, 0.01 * k + k * w)
        assert_allclose([box.lo[c, 0], box.hi[c, 0]], exact, rtol=1e-13)
        assert_allclose([zs[c].center[0] - zs[c].radius[0], zs[c].center[0] + zs[c].radius[0]], exact, rtol=1e-13)
        # y = 0 exactly, up to the rounding guard ((n + 8) ulps of the path length)
        assert abs(box.hi[c, 1] - box.lo[c, 1]) < 1e-12
        assert zs[c].radius[1] < 1e-12
        assert zonotope_area(zs[c]) < 1e-12
    # the extreme trajectories (every error at +w or −w) reach the bounds
    hi = sample_bounded_poses(ds + w, dth, np.zeros((n, 2, 0)), 1, np.random.default_rng(0))
    assert hi[0, 0, 0] == pytest.approx(box.hi[-1, 0], rel=1e-13)


def test_zonotope_is_tight_for_small_errors(rng):
    # the remainder is second order: the support-probing trajectories reach the zonotope's support in
    # every direction up to a relative gap that shrinks in proportion to the error bound
    traj = _curvy()
    ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    U = np.stack([np.cos(ang), np.sin(ang)], -1)
    gaps = []
    for slip in (4e-4, 1e-4):
        A = wheel_error_generators(traj.ds_r, traj.ds_l, traj.track, BoundedWheelErrors(1e-6, slip))
        z = zonotope_dead_reckoning(traj.ds, traj.dtheta, A)[0].xy()
        poses = sample_bounded_poses(traj.ds, traj.dtheta, A, 16, rng, vertex_fraction=1.0, directions=U)
        reached = np.einsum("nd,nd->n", poses[:, 0, :2] - z.center, U)
        h = support(z, U) - U @ z.center
        assert np.all(reached <= h)
        gaps.append(float(np.max(1 - reached / h)))
    assert gaps[1] < 0.02  # measured 1.7 % in the thinnest direction, < 0.3 % in most
    assert 2.5 < gaps[0] / gaps[1] < 5.0  # first order in the bound (4× smaller bound: ~3.5× smaller gap)


def test_polygon_area_equals_the_determinant_formula(rng):
    G = rng.normal(size=(2, 7))
    z = Zonotope(np.array([0.3, -1.0]), G)
    dets = np.abs(G[0][:, None] * G[1][None, :] - G[1][:, None] * G[0][None, :])
    assert zonotope_area(z) == pytest.approx(4 * np.triu(dets, 1).sum(), rel=1e-12)
    v = zonotope_polygon(z)
    assert v.shape == (14, 2)
    assert zonotope_contains_xy(z, v * (1 - 1e-9) + z.center * 1e-9).all()
    assert not zonotope_contains_xy(z, z.center + 1.01 * (v - z.center)).any()
    assert hull_area(v) == pytest.approx(zonotope_area(z), rel=1e-12)


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="error_generators must have shape"):
        interval_dead_reckoning(np.ones(3), np.zeros(3), np.zeros((2, 2, 1)))
    with pytest.raises(ValueError, match="checkpoints"):
        zonotope_dead_reckoning(np.ones(3), np.zeros(3), np.zeros((3, 2, 1)), checkpoints=[4])
    with pytest.raises(ValueError, match="pulse must be >= 0"):
        BoundedWheelErrors(-1.0)
    assert math.isclose(BoundedWheelErrors.encoder(400, 0.065).pulse, math.pi * 0.065 / 400)
