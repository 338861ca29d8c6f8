"""Šafránek 2022's wheel-speed error sources and their equivalent k, checked against Monte Carlo."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import covariance as cv
from pose_uncertainty.methods import wheel_noise as wn


def test_safranek_2022_numbers():
    s = wn.SAFRANEK_2022_CHASSIS
    # one pulse: π·0.065 m / (400 · 0.01 s) = 0.05105 m/s; uniform ±½ pulse: q²/12
    assert_allclose(s.pulse_speed, math.pi * 0.065 / 4.0)
    assert_allclose(s.quantisation_var, s.pulse_speed**2 / 12)
    assert_allclose(wn.speed_variance(s, 1.0), s.pulse_speed**2 / 12 + 1e-4 + 1e-4)
    # k = σ_v² dt/|v|; for dt/|v| = 0.01 it coincides with Šafránek 2022's empirical 0.01·σ_v²
    assert_allclose(wn.k_equivalent(s, 1.0, 0.01), 0.01 * wn.speed_variance(s, 1.0))
    assert_allclose(wn.k_equivalent(s, 2.0, 0.01), wn.speed_variance(s, 2.0) * 0.005)


def test_speed_error_variance_by_monte_carlo():
    # the sample variance of n draws has relative s.e. ≈ √((κ−1)/n) ≲ √(2/n) = 0.3 % at n = 2e5
    rng = np.random.default_rng(123)
    v = np.array([0.5, 1.0, 2.0])
    e = wn.sample_speed_errors(wn.SAFRANEK_2022_CHASSIS, v, 200_000, rng)
    assert_allclose(e.var(axis=0), wn.speed_variance(wn.SAFRANEK_2022_CHASSIS, v), rtol=0.015)
    se = np.sqrt(wn.speed_variance(wn.SAFRANEK_2022_CHASSIS, v) / 2e5)
    assert np.all(np.abs(e.mean(axis=0)) < 5 * se)
    # quantisation alone is uniform on ±q/2
    q_only = wn.WheelErrorSources(surface_rel_std=0.0, additive_std=0.0)
    eq = wn.sample_speed_errors(q_only, v, 10_000, rng)
    assert np.all(np.abs(eq) <= q_only.pulse_speed / 2)


@pytest.mark.parametrize("regime", ["per_step", "per_run"])
def test_total_travel_variance_growth(regime):
    # a wheel's total travel variance: per-step n σ² dt² = k L (linear), per-run (n dt)² σ² (square)
    t = tr.straight(2.0, speed=1.0, dt=0.01, track=0.1)
    n = 40_000
    ds_r, _ = wn.sample_wheel_travels(t, wn.SAFRANEK_2022_CHASSIS, n, np.random.default_rng(5), regime)
    steps = np.array([50, 100, 200])
    total = np.cumsum(ds_r, axis=1)[:, steps - 1]
    expect = wn.travel_variance(wn.SAFRANEK_2022_CHASSIS, 1.0, 0.01, steps, regime)
    # s.e. of a sample variance ≈ √(2/n) = 0.7 %; 5 s.e.
    assert_allclose(total.var(axis=0), expect, rtol=0.035)
    if regime == "per_step":
        k = wn.k_equivalent(wn.SAFRANEK_2022_CHASSIS, 1.0, 0.01)
        assert_allclose(expect, k * steps * 0.01, rtol=1e-12)


def test_end_pose_covariance_matches_method_a_with_equivalent_k():
    # Šafránek 2022: 1 m/s, track 0.1 m, 10 ms, 1 s. Route 1: Monte Carlo with the physical error
    # sources per step; route 2: Method A with k = σ_v² dt/|v|. σ_θ ≈ 0.03 rad, so the
    # linearisation error is ~σ_θ² ≈ 0.1 %; sample-covariance s.e. √(2/n) ≈ 0.6 % at n = 5e4.
    t = tr.straight(1.0, speed=1.0, dt=0.01, track=0.1)
    e = wn.sample_end_poses(t, wn.SAFRANEK_2022_CHASSIS, 50_000, np.random.default_rng(9))
    k = float(wn.k_equivalent(wn.SAFRANEK_2022_CHASSIS, 1.0, 0.01))
    A = cv.propagate(t, k, k).covs[-1]
    C = np.cov(e.T)
    for i, j in [(0, 0), (1, 1), (2, 2), (1, 2)]:
        assert_allclose(C[i, j], A[i, j], rtol=0.04)


def test_bad_input():
    with pytest.raises(ValueError, match="pulses_per_rev must be an integer >= 1"):
        wn.WheelErrorSources(pulses_per_rev=0)
    with pytest.raises(ValueError, match="wheel_diameter must be > 0"):
        wn.WheelErrorSources(wheel_diameter=-0.1)
    with pytest.raises(ValueError, match="v must be nonzero"):
        wn.k_equivalent(wn.SAFRANEK_2022_CHASSIS, 0.0, 0.01)
    with pytest.raises(ValueError, match="regime must be one of"):
        wn.sample_speed_errors(wn.SAFRANEK_2022_CHASSIS, [1.0], 3, np.random.default_rng(0), regime="weekly")
