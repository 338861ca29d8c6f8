"""Every drive's error models, Method A, Monte Carlo and exponential-coordinates Gaussian."""

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from pose_uncertainty.core import drives as dr
from pose_uncertainty.core import kinematics as kin
from pose_uncertainty.core import stats
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import drive_covariance as dc
from pose_uncertainty.methods import drive_noise as dn
from pose_uncertainty.methods import drive_sampling as ds
from pose_uncertainty.methods import expcoords as ec
from pose_uncertainty.methods.wheel_noise import SAFRANEK_2022_CHASSIS

ALL_DRIVES = [
    dr.Differential(0.2),
    dr.SkidSteer(0.2, chi=1.5),
    dr.Tricycle(0.3),
    dr.Ackermann(0.3, 0.2),
    dr.TwoAxleSteering(0.4),
    dr.SynchroDrive(),
    dr.MultiDof(),
    dr.Omni3(0.15),
]
IDS = [d.kind for d in ALL_DRIVES]
N_MC = 50_000


def _cov_tolerance(S, n, z=5.0):
    """z standard errors of each sample-covariance entry for a Gaussian: √((ΣiiΣjj + Σij²)/n)."""
    d = np.diag(S)
    return z * np.sqrt((np.outer(d, d) + S**2) / n)


def _small_model(drive):
    """Error levels at which first order is exact to well within the Monte Carlo error.

    k = 1e-6 m and 0.1° of steering noise keep the heading spread below 0.01 rad, so
    second-order terms (∝ σθ²) are ~1e-4 relative: far below the standard error of a
    covariance at n = 5e4 (√(2/n) ≈ 0.6 %). The slip's mean effect is second order in
    χ (E[1/χ] − 1/χ̄ ≈ σ_χ²/χ̄³): at σ_χ² = 1e-5 it moves the heading by ~3e-6 rad,
    a fifth of the standard error of the mean heading. The steering bias only moves the mean.
    """
    slip = dn.IcrSlip(chi_var=1e-5, x_icr_var=1e-6) if drive.kind == "skid_steer" else None
    return dn.DriveErrorModel(k=1e-6, steer_var=math.radians(0.1) ** 2, steer_bias=0.01, slip=slip)


SHORT_ARC = tr.arc(0.5, 1.0, dt=0.02)


def _assert_agree(mean_mc, cov_mc, mean_a, cov_a, n):
    assert np.all(np.abs(cov_mc - cov_a) <= _cov_tolerance(cov_a, n))
    # 5 standard errors of the mean, plus rounding
    assert np.all(np.abs(mean_mc - mean_a) <= 5 * np.sqrt(np.diag(cov_a) / n) + 1e-12)


# --- the differential drive is one drive among the others ----------------------------------


def test_wheel_path_is_the_trajectorys_wheel_travels_bit_for_bit():
    t = tr.s_curve(0.5, dt=0.01, track=0.2)
    path = dr.wheel_path(t)
    assert path.drive == dr.Differential(0.2)
    assert_array_equal(path.u, np.stack([t.ds_r, t.ds_l], -1))
    for method in kin.METHODS:
        assert_array_equal(path.poses_by(method), t.poses_by(method))
    # follow() recomputes the travels from the arcs: the same up to rounding
    assert_allclose(dr.follow(dr.Differential(0.2), t).u, path.u, rtol=0, atol=1e-15)


@pytest.mark.parametrize(("k_r", "k_l", "b"), [(5e-4, 5e-4, 0.2), (9e-4, 1e-4, 0.1)])
def test_differential_method_a_on_a_straight_line_is_the_closed_form(k_r, k_l, b):
    """The exact discrete closed form of the straight line (s = nΔ, K = k_r+k_l, D = k_r−k_l):
    σx² = K s/4, σy² = K/b² (s³/3 − sΔ²/12), σθ² = K s/b², σxy = D s²/(4b), σxθ = D s/(2b),
    σyθ = K s²/(2b²) — midpoint and exact steps (on a straight line their Jacobians coincide)."""
    t = tr.straight(2.0, dt=0.01, speed=1.0, track=b)
    K, D, delta = k_r + k_l, k_r - k_l, t.ds[0]
    for method in ("midpoint", "exact"):
        res = dc.propagate_path(dr.wheel_path(t), dn.DriveErrorModel(k=(k_r, k_l)), method=method)
        for n in (1, t.n_steps // 3, t.n_steps):
            s = n * delta
            expected = np.array([
                [K * s / 4, D * s**2 / (4 * b), D * s / (2 * b)],
                [D * s**2 / (4 * b), K / b**2 * (s**3 / 3 - s * delta**2 / 12), K * s**2 / (2 * b**2)],
                [D * s / (2 * b), K * s**2 / (2 * b**2), K * s / b**2],
            ])  # fmt: skip
            assert_allclose(res.covs[n], expected, rtol=1e-10, atol=1e-18)


def test_differential_per_run_on_a_straight_line_is_the_closed_form():
    """Per run, wheel scale errors ε_j ~ N(0, k_j/L) (L = s at the end): to first order the heading
    error after s is (ε_r − ε_l)s/b and the lateral error ∫ heading = (ε_r − ε_l)s²/(2b), so
    σθ² = K s²/(L b²), σy² = K s⁴/(4 L b²), σyθ = K s³/(2 L b²), σx² = K s²/(4L)."""
    k_r, k_l, b = 9e-4, 1e-4, 0.2
    t = tr.straight(2.0, dt=0.01, speed=1.0, track=b)
    res = dc.propagate_path_per_run(dr.wheel_path(t), dn.DriveErrorModel(k=(k_r, k_l)))
    K, D, L = k_r + k_l, k_r - k_l, 2.0
    for n in (t.n_steps // 4, t.n_steps):
        s = n * t.ds[0]
        expected = np.array([
            [K * s**2 / (4 * L), D * s**3 / (4 * L * b), D * s**2 / (2 * L * b)],
            [D * s**3 / (4 * L * b), K * s**4 / (4 * L * b**2), K * s**3 / (2 * L * b**2)],
            [D * s**2 / (2 * L * b), K * s**3 / (2 * L * b**2), K * s**2 / (L * b**2)],
        ])  # fmt: skip
        assert_allclose(res.covs[n], expected, rtol=1e-9, atol=1e-18)


def _recursion(drive, u, Su, Qx, S0, start, method):
    """The step recursion of Method A with numpy's matmul: the route the closed form is not."""
    xi = drive.twist(u)
    p, S = np.asarray(start, float), np.asarray(S0, float)
    poses, covs = [p], [S]
    for i in range(len(u)):
        J_p, J_xi = dc.twist_step_jacobians(p[2], xi[i], method)
        J_u = J_xi @ drive.twist_jacobian(u[i])
        S = J_p @ S @ J_p.T + J_u @ Su[i] @ J_u.T + (0 if Qx is None else J_xi @ Qx[i] @ J_xi.T)
        p = kin.step_twist(p, xi[i], method)
        poses.append(p)
        covs.append(S)
    return np.array(poses), np.array(covs)


@pytest.mark.parametrize("method", ["midpoint", "exact", "euler"])
@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_method_a_closed_form_equals_the_step_recursion(drive, method):
    path = dr.follow(drive, tr.s_curve(0.5, dt=0.02, track=0.2))
    model = _small_model(drive)
    mean = dn.measurement_mean(drive, path.u, model)
    Su = dn.measurement_cov(drive, path.u, path.dt, model)
    Qx = dn.slip_twist_cov(drive, mean, model)
    S0 = np.array([[1e-4, 2e-5, 0.0], [2e-5, 3e-4, 1e-5], [0.0, 1e-5, 2e-4]])
    start = (0.3, -0.2, 0.4)
    poses, covs = dc.propagate(drive, mean, Su, twist_cov=Qx, cov0=S0, start=start, method=method)
    P1, C1 = _recursion(drive, mean, Su, Qx, S0, start, method)
    assert_allclose(poses, P1, rtol=0, atol=1e-12)
    assert_allclose(covs, C1, rtol=0, atol=1e-12 * np.abs(C1).max())
    # the one-step recursion of the module agrees too
    p1, c1 = dc.step(drive, P1[5], C1[5], mean[5], Su[5], method)
    assert_allclose(p1, P1[6], atol=1e-14)
    if Qx is None:
        assert_allclose(c1, C1[6], rtol=0, atol=1e-13 * np.abs(C1[6]).max())


@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_per_run_closed_form_equals_the_sensitivity_recursion(drive):
    path = dr.follow(drive, tr.s_curve(0.5, dt=0.02, track=0.2))
    model = _small_model(drive)
    mean = dn.measurement_mean(drive, path.u, model)
    sens = dn.per_run_sensitivity(drive, path.u, path.dt, model)
    S0 = np.diag([1e-4, 2e-4, 3e-4])
    poses, covs = dc.propagate_per_run(drive, mean, sens, cov0=S0, method="exact")
    # S_{i+1} = J_p S_i + J_ξ T_i, Φ_{i+1} = J_p Φ_i, Σ = S W Sᵀ + Φ Σ_0 Φᵀ, step by step
    xi, S, Phi = drive.twist(mean), np.zeros((3, sens.T.shape[-1])), np.eye(3)
    for i in range(path.n_steps):
        J_p, J_xi = dc.twist_step_jacobians(poses[i, 2], xi[i], "exact")
        S, Phi = J_p @ S + J_xi @ sens.T[i], J_p @ Phi
        want = (S * sens.var) @ S.T + Phi @ S0 @ Phi.T
        assert_allclose(covs[i + 1], want, rtol=0, atol=1e-12 * np.abs(want).max())


@pytest.mark.parametrize("method", kin.METHODS)
@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_monte_carlo_end_poses_equal_the_integrated_particles(drive, method):
    # two routes: the perturbation kernel of the end poses vs integrate_twist at a checkpoint at N
    path = dr.follow(drive, SHORT_ARC)
    model = _small_model(drive)
    kw = {"method": method, "cov0": np.diag([1e-4, 2e-4, 1e-3])}
    for regime in ("per_step", "per_run"):
        a = ds.sample_poses(path, model, 2000, np.random.default_rng(4), regime=regime, **kw)
        b = ds.sample_poses(path, model, 2000, np.random.default_rng(4), regime=regime,
                            checkpoints=[path.n_steps], **kw)  # fmt: skip
        assert_allclose(a, b[:, 0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_kept_normals_give_every_drive_the_same_particles(drive):
    """A DrawCache (the explorer's) keeps the Gaussian channels' normals: the next call with other
    error levels reads them, draws the rest (encoders, the ICR slip) after them from the same
    stream, and gives the particles drawn afresh, bit for bit; the kept normals stay untouched."""
    from pose_uncertainty.methods.particles import DrawCache

    path = dr.follow(drive, SHORT_ARC)
    cache = DrawCache()
    for scale in (1.0, 3.0, 1.0):
        model = _small_model(drive)
        model = dataclasses.replace(model, k=1e-6 * scale, steer_var=model.steer_var * scale)
        for regime in ("per_step", "per_run"):
            kept = ds.sample_poses(path, model, 600, np.random.default_rng(7), regime=regime, cache=cache)
            fresh = ds.sample_poses(path, model, 600, np.random.default_rng(7), regime=regime)
            assert_array_equal(kept, fresh)


# --- Jacobians of the step ----------------------------------------------------------------


def _numeric_jacobian(f, x, h=1e-6):
    return np.stack([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(x.shape[-1])], -1)


@pytest.mark.parametrize("method", kin.METHODS)
def test_twist_step_jacobians_equal_finite_differences(method, rng):
    p = rng.normal(size=(30, 3))
    xi = rng.normal(scale=0.3, size=(30, 3))
    xi[:4, 2] = [0.0, 1e-9, -3e-4, 2e-3]  # through the series of sin(h)/h near Δθ = 0
    J_p, J_xi = dc.twist_step_jacobians(p[:, 2], xi, method)
    assert_allclose(J_p, _numeric_jacobian(lambda q: kin.step_twist(q, xi, method), p), atol=1e-8)
    assert_allclose(J_xi, _numeric_jacobian(lambda q: kin.step_twist(p, q, method), xi), atol=1e-8)


@pytest.mark.parametrize("method", ["midpoint", "exact"])
@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_step_jacobians_equal_finite_differences(drive, method, rng):
    u = dr.follow(drive, SHORT_ARC).u[::5] * rng.uniform(0.5, 1.5, size=(1, drive.n_channels))
    p = rng.normal(size=(len(u), 3))
    J_p, J_u = dc.step_jacobians(drive, p, u, method)
    assert J_u.shape == (len(u), 3, drive.n_channels)
    assert_allclose(J_p, _numeric_jacobian(lambda q: drive.step(q, u, method), p), atol=1e-8)
    assert_allclose(J_u, _numeric_jacobian(lambda q: drive.step(p, q, method), u), atol=1e-8)


def test_method_a_batch_equals_single_runs(rng):
    drive = dr.Tricycle(0.3)
    path = dr.follow(drive, SHORT_ARC)
    k = np.array([1e-6, 5e-4, 2e-3])
    models = [dn.DriveErrorModel(k=kk, steer_var=kk) for kk in k]
    Su = np.stack([dn.measurement_cov(drive, path.u, path.dt, m) for m in models])
    poses, covs = dc.propagate(drive, path.u, Su)
    for i, m in enumerate(models):
        one = dc.propagate_path(path, m)
        assert_allclose(covs[i], one.covs, rtol=1e-13, atol=1e-20)
        assert_allclose(poses[i], one.poses, atol=1e-15)


# --- Method A and the exponential-coordinates Gaussian against Monte Carlo ----------------


@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_method_a_matches_monte_carlo_per_step(drive):
    path = dr.follow(drive, SHORT_ARC)
    model = _small_model(drive)
    res = dc.propagate_path(path, model)
    end = ds.sample_poses(path, model, N_MC, np.random.default_rng(1))
    _assert_agree(*stats.mean_cov(end), res.poses[-1], res.covs[-1], N_MC)


@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_method_a_matches_monte_carlo_per_run(drive):
    path = dr.follow(drive, SHORT_ARC)
    model = _small_model(drive)
    res = dc.propagate_path_per_run(path, model)
    end = ds.sample_poses(path, model, N_MC, np.random.default_rng(2), regime="per_run")
    _assert_agree(*stats.mean_cov(end), res.poses[-1], res.covs[-1], N_MC)


@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_expcoords_gaussian_matches_monte_carlo(drive):
    # the cloud's exponential coordinates about the exact mean path are N(0, Σ)
    path = dr.follow(drive, SHORT_ARC)
    model = _small_model(drive)
    g = dc.expcoords(path, model)
    end = ds.sample_poses(path, model, N_MC, np.random.default_rng(3), method="exact")
    mean, C = stats.mean_cov(ec.coordinates(end, g.poses[-1]))
    _assert_agree(mean, C, np.zeros(3), g.covs[-1], N_MC)


@pytest.mark.parametrize("regime", ["per_step", "per_run"])
@pytest.mark.parametrize(
    "drive", [dr.Omni3(0.15), dr.Ackermann(0.3, 0.2)], ids=["omni3", "ackermann"]
)
def test_encoder_sources_of_safranek_2022_match_monte_carlo(drive, regime):
    # quantisation (uniform), surface and additive errors: Method A uses only their variance,
    # the Monte Carlo draws them; at 20 ms steps the per-step variance is ~1e-7 m² per wheel
    path = dr.follow(drive, SHORT_ARC)
    model = dn.DriveErrorModel(encoder=SAFRANEK_2022_CHASSIS, steer_var=math.radians(0.1) ** 2)
    res = (
        dc.propagate_path(path, model)
        if regime == "per_step"
        else dc.propagate_path_per_run(path, model)
    )
    end = ds.sample_poses(path, model, N_MC, np.random.default_rng(4), regime=regime)
    _assert_agree(*stats.mean_cov(end), res.poses[-1], res.covs[-1], N_MC)


def test_lateral_path_of_the_omni_drive_matches_monte_carlo():
    # sideways and turning at once: twists with v₂ ≠ 0 and Δθ ≠ 0
    drive = dr.Omni3(0.15)
    xi = np.tile([0.01, 0.015, 0.02], (50, 1))
    path = dr.DrivePath(drive, drive.measurements(xi), 0.02)
    model = dn.DriveErrorModel(k=1e-6)
    res = dc.propagate_path(path, model)
    end = ds.sample_poses(path, model, N_MC, np.random.default_rng(5))
    _assert_agree(*stats.mean_cov(end), res.poses[-1], res.covs[-1], N_MC)


# --- drive-specific facts -----------------------------------------------------------------


def test_synchro_cloud_keeps_its_heading():
    path = dr.follow(dr.SynchroDrive(), tr.s_curve(0.5, dt=0.02, start=(0.0, 0.0, 0.4)))
    model = dn.DriveErrorModel(k=5e-4, steer_var=0.01, steer_bias=0.05)
    for regime in ("per_step", "per_run"):
        end = ds.sample_poses(path, model, 2000, np.random.default_rng(6), regime=regime)
        assert_array_equal(end[:, 2], 0.4)
    assert_array_equal(dc.propagate_path(path, model).covs[:, 2, :], 0.0)


@pytest.mark.parametrize("path_name", ["straight", "arc"])
def test_plain_odometry_on_a_skid_steer_is_biased_in_turns_only(path_name):
    # the skid-steer truly turns with its tracks' ICRs at ±χb/2 (χ = 1.5, random per step);
    # plain differential odometry assumes χ = 1
    skid = dr.SkidSteer(0.2, chi=1.5)
    t = tr.straight(1.0, dt=0.02) if path_name == "straight" else tr.arc(0.5, 1.0, dt=0.02)
    path = dr.follow(skid, t)
    model = dn.DriveErrorModel(k=1e-5, slip=dn.IcrSlip(chi_var=0.01, x_icr_var=1e-4))
    truth = ds.sample_poses(path, model, 20_000, np.random.default_rng(7), method="exact")
    reported = dr.Differential(0.2).integrate(path.u)[-1]
    error = reported - truth  # per particle: odometry minus truth
    mean, C = stats.mean_cov(error)
    se = np.sqrt(np.diag(C) / len(error))
    deterministic = dn.plain_odometry_error(skid, path.u)[-1]
    if path_name == "straight":
        # slip does not act when Δs_r = Δs_l: unbiased within 5 standard errors
        assert np.all(np.abs(mean) <= 5 * se)
        assert_array_equal(deterministic, 0.0)
    else:
        # the odometry reports χ = 1.5 times the true turn of 1 rad: 0.5 rad too much
        assert abs(mean[2] - 0.5) <= 0.5 * 0.01 + 5 * se[2]  # E[χ̄/χ] − 1 ≈ σ²/χ̄² ≈ 0.4 %
        assert np.all(np.abs(mean) > 50 * se)
        assert_allclose(deterministic[2], 0.5, rtol=1e-12)


def test_same_seed_bit_identical_and_thread_count_free():
    path = dr.follow(dr.Ackermann(), SHORT_ARC)
    model = dn.DriveErrorModel(k=5e-4, steer_var=1e-3, encoder=None)
    a = ds.sample_poses(path, model, 5000, np.random.default_rng(9), workers=1)
    b = ds.sample_poses(path, model, 5000, np.random.default_rng(9), workers=2)
    c = ds.sample_poses(path, model, 5000, np.random.default_rng(10), workers=2)
    assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_steering_noise_of_the_tricycle_on_a_straight_has_its_closed_form():
    # straight, ω = 0: Δθ_i = ΔS δω_i / d to first order, so σθ² = N (ΔS/d)² steer_var,
    # and the travel noise k does not turn the tricycle
    d, dS, N, var = 0.3, 0.02, 50, 1e-4
    path = dr.follow(dr.Tricycle(d), tr.straight(dS * N, dt=0.02))
    res = dc.propagate_path(path, dn.DriveErrorModel(k=5e-4, steer_var=var))
    assert_allclose(res.covs[-1, 2, 2], N * (dS / d) ** 2 * var, rtol=1e-12)
    assert_allclose(res.covs[-1, 0, 0], 5e-4 * dS * N, rtol=1e-9)


# --- error-model checks -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("drive", "model", "match"),
    [
        (
            dr.Tricycle(),
            dn.DriveErrorModel(k=(1e-4, 2e-4)),
            r"k must be one number or one per channel \['ds'\]",
        ),
        (
            dr.MultiDof(),
            dn.DriveErrorModel(steer_var=(1e-4, 1e-4)),
            r"steer_var must be one number or one per channel",
        ),
        (
            dr.Differential(),
            dn.DriveErrorModel(slip=dn.IcrSlip(0.1)),
            r"slip applies to a skid_steer drive only",
        ),
    ],
)
def test_error_model_mismatch_gives_a_one_line_error(drive, model, match):
    with pytest.raises(ValueError, match=match) as e:
        dn.channels(drive, model)
    assert "\n" not in str(e.value)


def test_error_model_values_are_checked():
    with pytest.raises(ValueError, match=r"k must be >= 0"):
        dn.DriveErrorModel(k=-1e-4)
    with pytest.raises(ValueError, match=r"chi_var must be >= 0"):
        dn.IcrSlip(chi_var=-1.0)


def test_per_channel_values_land_on_their_channels():
    ch = dn.channels(
        dr.Ackermann(), dn.DriveErrorModel(k=(1e-4, 2e-4), steer_var=3e-4, steer_bias=0.1)
    )
    assert_array_equal(ch.k, [1e-4, 2e-4, 0.0])
    assert_array_equal(ch.angle_var, [0.0, 0.0, 3e-4])
    assert_array_equal(ch.bias, [0.0, 0.0, 0.1])
