"""Gyroscope, strapdown INS and gyro-aided odometry (Skalka 2011 §3.3–3.4): Jacobians, Method A
against Monte Carlo, and the known growth laws of the errors."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.stats import fit_growth
from pose_uncertainty.methods import covariance
from pose_uncertainty.methods.gyro_odometry import (
    odometry_gyro_jacobians,
    odometry_gyro_path,
    odometry_gyro_step,
    propagate_odometry_gyro,
    sample_odometry_gyro,
)
from pose_uncertainty.methods.inertial import (
    InertialPath,
    ins_integrate,
    ins_jacobians,
    ins_step,
    propagate_ins,
    sample_ins,
)
from pose_uncertainty.methods.inertial_sensors import AccelErrors, GyroErrors, position_growth


def _fd(fun, x0, eps=1e-6):
    """Central finite differences of fun: (d,) → (m,), shape (m, d)."""
    cols = []
    for i in range(x0.size):
        e = np.zeros_like(x0)
        e[i] = eps
        cols.append((fun(x0 + e) - fun(x0 - e)) / (2 * eps))
    return np.stack(cols, axis=-1)


def assert_cov_matches(samples, mean, cov, n_sigma=5.0):
    """Sample moments against (mean, cov): the whitened sample covariance ``L⁻¹ S L⁻ᵀ`` is I within
    the Wishart spread (diagonal sd √(2/(n−1)), off-diagonal 1/√(n−1)) and the whitened mean
    within 1/√n, each to ``n_sigma`` standard deviations."""
    n = samples.shape[0]
    L = np.linalg.cholesky(cov)
    z = np.linalg.solve(L, (samples - mean).T).T
    m = z.mean(axis=0)
    assert np.all(np.abs(m) < n_sigma / math.sqrt(n)), m
    W = np.cov(z.T)
    sd = np.full(W.shape, 1.0 / math.sqrt(n - 1))
    np.fill_diagonal(sd, math.sqrt(2.0 / (n - 1)))
    dev = np.abs(W - np.eye(W.shape[0])) / sd
    assert dev.max() < n_sigma, (dev.max(), W)


GYRO = GyroErrors(bias_std=2e-3, bias_rw_std=5e-4, white_std=3e-3, scale_std=1e-2)
ACCEL = AccelErrors(bias_std=5e-3, bias_rw_std=1e-3, white_std=4e-3)


def _turning_path(n_steps=60, dt=0.05):
    t = dt * np.arange(n_steps)
    omega = 0.6 * np.sin(0.5 * t) + 0.2
    accel = np.stack([0.3 * np.cos(0.7 * t), 0.5 * omega], axis=-1)
    return InertialPath(omega, accel, dt, np.array([0.5, -0.2, 0.3]), np.array([0.8, 0.1]))


def test_ins_jacobians_match_finite_differences(rng):
    state = rng.normal(size=9) * np.array([1, 1, 1, 1, 1, 0.01, 0.02, 0.05, 0.05])
    omega, f, dt = 0.7, np.array([0.4, -0.9]), 0.1
    F, G = ins_jacobians(state, omega, f, dt)
    assert_allclose(F, _fd(lambda s: ins_step(s, omega, f, np.zeros(6), dt), state), atol=1e-8)
    assert_allclose(G, _fd(lambda e: ins_step(state, omega, f, e, dt), np.zeros(6)), atol=1e-8)


def test_odometry_gyro_jacobians_match_finite_differences(rng):
    state = np.array([0.3, -1.0, 2.1, 0.01, 0.03])
    ds, omega, dt = 0.05, -0.8, 0.1
    F, G = odometry_gyro_jacobians(state, ds, omega, dt)
    assert_allclose(F, _fd(lambda s: odometry_gyro_step(s, ds, omega, np.zeros(3), dt), state), atol=1e-9)
    assert_allclose(G, _fd(lambda e: odometry_gyro_step(state, ds, omega, e, dt), np.zeros(3)), atol=1e-9)
    # batched over steps: the same as one at a time
    Fb, _ = odometry_gyro_jacobians(np.tile(state, (4, 1)), np.full(4, ds), np.linspace(-1, 1, 4), dt)
    assert_allclose(Fb[1], odometry_gyro_jacobians(state, ds, np.linspace(-1, 1, 4)[1], dt)[0])


def test_ins_integrate_equals_the_step_recursion(rng):
    path = _turning_path(25)
    w_m = path.omega + 0.01 * rng.standard_normal(path.n_steps)
    f_m = path.accel + 0.02 * rng.standard_normal((path.n_steps, 2))
    nav = ins_integrate(w_m, f_m, path.dt, path.start, path.v0)
    s = np.zeros(9)
    s[[0, 1, 4]], s[2:4] = path.start, path.v0
    for k in range(path.n_steps):  # the measured signals as noise on the true ones
        e = np.array([w_m[k] - path.omega[k], *(f_m[k] - path.accel[k]), 0, 0, 0])
        s = ins_step(s, path.omega[k], path.accel[k], e, path.dt)
        assert_allclose(s[:5], nav[k + 1], atol=1e-12)


def test_ins_path_from_a_trajectory_follows_it():
    errors = []
    for dt in (0.01, 0.005):
        traj = tr.s_curve(radius=1.0, speed=0.5, dt=dt, track=0.2)
        path = InertialPath.from_trajectory(traj)
        nav = ins_integrate(path.omega, path.accel, path.dt, path.start, path.v0)
        assert_allclose(nav[:, 4], traj.poses[:, 2], atol=1e-12)  # the headings exactly
        assert_allclose(np.hypot(nav[-1, 2], nav[-1, 3]), traj.ds[-1] / traj.dt, rtol=1e-12)
        errors.append(np.max(np.hypot(*(nav[:, :2] - traj.poses[:, :2]).T)))
    # the positions to O(Δt²): 5.9·10⁻⁶ m at Δt = 10 ms, four times less at half the step
    assert errors[0] < 0.1 * 0.01**2
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.1)


def test_ins_method_a_matches_monte_carlo(rng):
    path = _turning_path()
    states, covs = propagate_ins(path, GYRO, ACCEL)
    n = 20000
    mc = sample_ins(path, GYRO, ACCEL, n, rng, checkpoints=[30, path.n_steps])
    assert mc.shape == (n, 2, 9)
    for c, k in enumerate((30, path.n_steps)):
        assert_cov_matches(mc[:, c], states[k], covs[k])
    # a start covariance adds the start's own propagation F…F Σ₀ (F…F)ᵀ (the recursion is linear in Σ)
    S0 = np.diag([1e-4, 1e-4, 1e-5, 1e-5, 1e-4])
    _, with_start = propagate_ins(path, GYRO, ACCEL, cov0=S0)
    _, start_only = propagate_ins(path, GyroErrors(), AccelErrors(), cov0=S0)
    assert_allclose(with_start, covs + start_only, rtol=1e-12, atol=1e-18)


@pytest.mark.slow
def test_odometry_gyro_method_a_matches_monte_carlo(rng):
    traj = tr.circle(radius=1.0, speed=0.5, dt=0.05, track=0.2)
    # errors small enough that the second-order bias of the linearisation (∝ σ_θ², a whitened
    # shift ∝ σ_θ ≈ 3·10⁻³ here) stays far below the sampling tolerance 5/√n = 0.035
    gyro = GyroErrors(bias_std=5e-4, bias_rw_std=1e-4, white_std=1e-3, scale_std=3e-3)
    path = odometry_gyro_path(traj, 4e-5, 2e-5)
    states, covs = propagate_odometry_gyro(path, gyro)
    mc = sample_odometry_gyro(path, gyro, 20000, rng, checkpoints=[path.n_steps // 2, path.n_steps])
    for c, k in enumerate((path.n_steps // 2, path.n_steps)):
        assert_cov_matches(mc[:, c], states[k], covs[k])
    # the noiseless path is the trajectory's own midpoint path
    assert_allclose(states[:, :3], covariance.propagate(traj, 0.0, 0.0).poses, atol=1e-12)


def test_ins_accelerometer_bias_grows_with_t_squared():
    path = InertialPath.constant(400, 0.05, speed=1.0)
    _, covs = propagate_ins(path, GyroErrors(), AccelErrors(bias_std=0.01))
    fit = position_growth(path.times, path.times * 1.0, covs[:, :2, :2])
    assert fit["time"]["power_exponent"] == pytest.approx(2.0, abs=1e-9)
    # σ_x = σ_b t²/2 exactly (the integrator is exact for a constant acceleration)
    assert math.sqrt(covs[-1, 0, 0]) == pytest.approx(0.01 * path.times[-1] ** 2 / 2, rel=1e-12)


def test_ins_accelerometer_white_noise_grows_with_t_three_halves():
    path = InertialPath.constant(2000, 0.05, speed=1.0)
    _, covs = propagate_ins(path, GyroErrors(), AccelErrors(white_std=0.01))
    late = slice(200, None)  # t ≥ 10 s: the discrete sum is σ²t³/3 (1 + O(Δt/t))
    fit = position_growth(path.times[late], path.times[late], covs[late])
    assert fit["time"]["power_exponent"] == pytest.approx(1.5, abs=5e-3)
    assert covs[-1, 0, 0] == pytest.approx(0.01**2 * path.times[-1] ** 3 / 3, rel=1e-2)


def test_gyro_growth_laws_in_heading_and_position():
    traj = tr.straight(length=50.0, speed=0.5, dt=0.05, track=0.2)
    path = odometry_gyro_path(traj, 0.0, 0.0)
    t = path.dt * np.arange(path.n_steps + 1)
    _, c_bias = propagate_odometry_gyro(path, GyroErrors(bias_std=1e-3))
    _, c_white = propagate_odometry_gyro(path, GyroErrors(white_std=1e-3))
    assert fit_growth(t, np.sqrt(c_bias[:, 2, 2]))["power_exponent"] == pytest.approx(1.0, abs=1e-9)
    assert fit_growth(t, np.sqrt(c_white[:, 2, 2]))["power_exponent"] == pytest.approx(0.5, abs=1e-9)
    # heading error θ = b t across a straight at speed V: y = V b t²/2 → position ∝ t² (and ∝ s²)
    fit = position_growth(t[20:], 0.5 * t[20:], c_bias[20:])
    assert fit["time"]["power_exponent"] == pytest.approx(2.0, abs=2e-3)
    assert fit["distance"]["power_exponent"] == pytest.approx(2.0, abs=2e-3)


def test_wheel_odometry_grows_with_distance_not_time():
    # the same straight at two speeds: Method A's σ depends on the distance only (Skalka 2011 §3.5)
    slow = tr.straight(length=20.0, speed=0.2, dt=0.1, track=0.2)
    fast = tr.straight(length=20.0, speed=1.0, dt=0.02, track=0.2)
    c_slow = covariance.propagate(slow, 5e-4, 5e-4).covs
    c_fast = covariance.propagate(fast, 5e-4, 5e-4).covs
    assert_allclose(c_slow[-1], c_fast[-1], rtol=1e-9, atol=1e-15)
    s = np.concatenate([[0.0], np.cumsum(slow.ds)])
    fit = position_growth(slow.times[100:], s[100:], c_slow[100:])
    assert fit["distance"]["power_exponent"] == pytest.approx(1.5, abs=0.03)  # across-track ∝ s^{3/2}


def test_checkpoints_and_shapes_are_checked(rng):
    path = InertialPath.constant(10, 0.1)
    with pytest.raises(ValueError, match="checkpoints"):
        sample_ins(path, GYRO, ACCEL, 5, rng, checkpoints=[11])
    with pytest.raises(ValueError, match="accel must have shape"):
        InertialPath(np.zeros(3), np.zeros((4, 2)), 0.1, np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match="bias_std must be >= 0"):
        GyroErrors(bias_std=-1.0)
    with pytest.raises(ValueError, match="covs must have shape"):
        position_growth([1, 2, 3], [1, 2, 3], np.zeros((3, 1, 1)))
