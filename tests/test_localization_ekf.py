"""EKF localization: the linear-Gaussian limit, Jacobians, masking, NEES consistency."""


import math

import numpy as np
import pytest

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.localization import ekf as E
from pose_uncertainty.localization import evaluation as MS
from pose_uncertainty.localization import sensors as S
from pose_uncertainty.localization import simulate as SIM
from pose_uncertainty.localization import world as W
from pose_uncertainty.localization.motion import Motion
from pose_uncertainty.localization.result import Start
from pose_uncertainty.methods import motion_models as mm


def _linear_system(rng, T=6):
    dt = 0.5
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt  # constant velocity in the plane
    Q = np.diag([1e-3, 2e-3, 5e-3, 4e-3])
    C = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [1.0, -1.0, 0.5, 0]])
    Rm = np.diag([0.04, 0.09, 0.02])
    b = np.array([0.01, -0.02, 0.0, 0.03])
    m0, P0 = np.array([0.0, 1.0, 0.5, -0.2]), np.diag([0.5, 0.3, 0.1, 0.2])
    x = rng.multivariate_normal(m0, P0)
    zs = []
    for _ in range(T):
        x = F @ x + b + rng.multivariate_normal(np.zeros(4), Q)
        zs.append(C @ x + rng.multivariate_normal(np.zeros(3), Rm))
    return F, Q, C, Rm, b, m0, P0, np.array(zs)


def _closed_form(F, Q, C, Rm, b, m0, P0, zs):
    """Posterior of x_T given z_1..z_T by conditioning the joint Gaussian (no recursion)."""
    T, n = zs.shape[0], 4
    # x_t = F^t x_0 + Σ_{s≤t} F^{t−s} (b + w_s): linear in ξ = (x_0, w_1..w_T)
    A = np.zeros((T, n, n * (T + 1)))
    mean_x = np.zeros((T, n))
    for t in range(1, T + 1):
        A[t - 1][:, :n] = np.linalg.matrix_power(F, t)
        mean_x[t - 1] = np.linalg.matrix_power(F, t) @ m0
        for s in range(1, t + 1):
            Fp = np.linalg.matrix_power(F, t - s)
            A[t - 1][:, n * s : n * (s + 1)] = Fp
            mean_x[t - 1] += Fp @ b
    Xi = np.zeros((n * (T + 1), n * (T + 1)))
    Xi[:n, :n] = P0
    for s in range(1, T + 1):
        Xi[n * s : n * (s + 1), n * s : n * (s + 1)] = Q
    Z = np.concatenate([C @ A[t] for t in range(T)])  # z = Z ξ + v
    Szz = Z @ Xi @ Z.T + np.kron(np.eye(T), Rm)
    Sxz = A[-1] @ Xi @ Z.T
    mz = np.concatenate([C @ mean_x[t] for t in range(T)])
    mean = mean_x[-1] + Sxz @ np.linalg.solve(Szz, zs.ravel() - mz)
    cov = A[-1] @ Xi @ A[-1].T - Sxz @ np.linalg.solve(Szz, Sxz.T)
    return mean, cov


def test_ekf_in_the_linear_gaussian_limit_is_the_kalman_filter_closed_form(rng):
    F, Q, C, Rm, b, m0, P0, zs = _linear_system(rng)
    x_kf, P_kf = m0, P0
    x_ekf, P_ekf = m0, P0
    for z in zs:
        x_kf, P_kf = E.kf_predict(x_kf, P_kf, F, Q, b)
        x_kf, P_kf = E.kf_update(x_kf, P_kf, z, C, Rm)
        x_ekf, P_ekf = E.kf_predict(x_ekf, P_ekf, F, Q, b)
        x_ekf, P_ekf, _, _ = E.ekf_update(x_ekf, P_ekf, z, lambda x: (C @ x[..., None])[..., 0],
                                          lambda x: C, Rm)  # fmt: skip
    np.testing.assert_allclose(x_ekf, x_kf, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(P_ekf, P_kf, rtol=1e-13, atol=1e-15)
    mean, cov = _closed_form(F, Q, C, Rm, b, m0, P0, zs)
    np.testing.assert_allclose(x_kf, mean, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(P_kf, cov, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("omega", [0.0, 1e-9, 0.7, -2.5])
def test_velocity_model_jacobians_equal_finite_differences(omega):
    mean, u, dt = np.array([0.3, -0.2, 1.1]), np.array([0.8, omega]), 0.4
    G, V = E.velocity_jacobians(mean, u, dt)

    def f(p, c):  # (V, ω, γ) → pose
        return mm.velocity_forward(p, c[0], c[1], c[2], dt)

    eps = 1e-6
    c0 = np.array([u[0], u[1], 0.0])
    for a in range(3):
        d = np.zeros(3)
        d[a] = eps
        np.testing.assert_allclose(G[:, a], (f(mean + d, c0) - f(mean - d, c0)) / (2 * eps), atol=1e-8)
        np.testing.assert_allclose(V[:, a], (f(mean, c0 + d) - f(mean, c0 - d)) / (2 * eps), atol=1e-8)


def test_velocity_prediction_covariance_matches_monte_carlo():
    # small noise: the linearisation is accurate to far below the Monte Carlo error.
    # Sample covariance of n = 2·10⁵ draws: each entry within 5 standard errors
    # (SE of a covariance entry ≈ √((Σ_aa Σ_bb + Σ_ab²)/n)).
    mean, cov = np.array([1.0, 2.0, 0.3]), np.diag([1e-4, 2e-4, 1e-4])
    u, dt, alphas = np.array([0.5, 0.4]), 0.5, np.array([0.01, 0.005, 0.02, 0.01, 0.002, 0.001])
    m_pred, c_pred = E.ekf_predict_velocity(mean, cov, u, dt, alphas)
    rng = np.random.default_rng(9)
    n = 200_000
    start = rng.multivariate_normal(mean, cov, n)
    s = mm.sample_velocity(start, u, dt, alphas, n, rng)
    assert np.all(np.abs(s.mean(axis=0) - m_pred) <= 5 * np.sqrt(np.diag(c_pred) / n) + 1e-6)
    se = np.sqrt((np.outer(np.diag(c_pred), np.diag(c_pred)) + c_pred**2) / n)
    assert np.all(np.abs(np.cov(s.T) - c_pred) <= 5 * se + 2e-7)


def test_unseen_landmarks_leave_the_belief_unchanged(rng):
    sen = S.RangeBearingSensor()
    lm = np.array([[2.0, 1.0], [0.0, 3.0]])
    mean, cov = np.array([0.1, 0.2, 0.3]), np.diag([0.01, 0.02, 0.005])
    z = S.landmark_h(mean, lm) + 0.1
    m1, c1, nis, n = E.ekf_update_landmarks(mean, cov, z, [False, False], lm, sen)
    np.testing.assert_array_equal(m1, mean)
    np.testing.assert_allclose(c1, cov, rtol=1e-15, atol=1e-18)
    assert nis == 0.0
    assert n == 0
    # one valid row equals the update with that landmark alone
    m2, c2, _, _ = E.ekf_update_landmarks(mean, cov, z, [True, False], lm, sen)
    m3, c3, _, _ = E.ekf_update_landmarks(mean, cov, z[:1], [True], lm[:1], sen)
    np.testing.assert_allclose(m2, m3, rtol=1e-14)
    np.testing.assert_allclose(c2, c3, rtol=1e-12, atol=1e-16)


@pytest.mark.slow
def test_averaged_nees_of_the_ekf_lies_in_its_chi2_band():
    # near-linear case: small wheel noise, precise sensor, landmarks a few metres away; the
    # true start is drawn from the filter's prior so the filter's model is right (per-step wheel
    # noise; the truth integrates exact arcs, the EKF midpoint steps: a negligible mismatch).
    # The NEES averaged over R runs at step k is χ²(3R)/R: 95 % band from nees_band. Of the
    # K (correlated) steps ≥ 85 % must lie in the band (nominally 95 %); the grand mean over
    # runs and steps must lie in the per-step band too (a looser check than its own band).
    R_runs, std = 60, np.array([0.02, 0.02, 0.01])
    lm = np.array([[3.0, 2.0], [0.0, 4.0], [5.0, -1.0], [-2.0, 1.0]])
    world = W.World(lm, np.arange(4))
    sen = S.RangeBearingSensor(range_std=0.05, bearing_std=0.02, max_range=20, period=0.4)
    lo, hi = MS.nees_band(3, R_runs, 0.95)
    nees = []
    for r in range(R_runs):
        rng = np.random.default_rng(1000 + r)
        start = np.array([0.0, 0.0, 0.2]) + std * rng.standard_normal(3)
        traj = tr.from_segments([tr.Arc(2.0, 1.0)], speed=0.5, dt=0.1, start=start)
        run = SIM.simulate(traj, world, rng, k_r=2e-4, k_l=2e-4, landmark_sensor=sen)
        cfg = E.EKFConfig(motion=Motion(k_r=2e-4, k_l=2e-4))  # the truth's wheel noise
        res = E.run_ekf(run, world, sen, cfg, Start(pose=(0.0, 0.0, 0.2), std=tuple(std)))
        nees.append(MS.nees(res.mean, res.cov, run.true_poses))
    avg = np.mean(nees, axis=0)
    inside = (avg >= lo) & (avg <= hi)
    assert inside.mean() >= 0.85, (inside.mean(), lo, hi, avg.min(), avg.max())
    assert lo <= avg.mean() <= hi


@pytest.mark.parametrize("model", ["wheels", "velocity"])
def test_batched_ekf_equals_one_run_at_a_time(model):
    lm = np.array([[3.0, 2.0], [0.0, 4.0], [5.0, -1.0]])
    world = W.World(lm, np.arange(3))
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05, max_range=4.5, fov=math.pi, period=0.3)
    traj = tr.from_segments([tr.Line(1.0), tr.Arc(1.5, 1.5)], speed=0.5, dt=0.1)
    runs = [SIM.simulate(traj, world, np.random.default_rng(s), k_r=1e-3, k_l=1e-3, landmark_sensor=sen)
            for s in range(4)]  # fmt: skip
    motion = Motion(model=model) if model == "wheels" else Motion(model="velocity", alphas=(0.01,) * 6)
    cfg = E.EKFConfig(motion=motion)
    mean, cov = E.run_ekf_batch(runs, world, sen, cfg)
    for r, run in enumerate(runs):
        one = E.run_ekf(run, world, sen, cfg)
        np.testing.assert_allclose(mean[r, :, :2], one.mean[:, :2], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.angle(np.exp(1j * (mean[r, :, 2] - one.mean[:, 2]))), 0, atol=1e-12)
        np.testing.assert_allclose(cov[r], one.cov, rtol=1e-10, atol=1e-15)
