"""The three Bayes filters on the same simulated data: agreement, global localization, kidnapping."""

import math

import numpy as np
import pytest

from pose_uncertainty.core import stats
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.grids import Grid
from pose_uncertainty.core.kinematics import step
from pose_uncertainty.localization import ekf as E
from pose_uncertainty.localization import histogram as HF
from pose_uncertainty.localization import particle as PF
from pose_uncertainty.localization import sensors as S
from pose_uncertainty.localization import simulate as SIM
from pose_uncertainty.localization import world as W
from pose_uncertainty.localization.evaluation import weighted_mean_cov
from pose_uncertainty.localization.motion import Motion, sample_motion, velocity_alphas_for_wheels
from pose_uncertainty.localization.result import Start, evaluate
from pose_uncertainty.methods import maps as M

LM = np.array([[2.5, 1.5], [-1.0, 3.0], [3.0, -2.0]])


def _benign_run(k=1e-3, n_steps=1, range_std=0.05, bearing_std=0.03):
    world = W.World(LM, np.arange(3), bounds=(-0.5, 0.5, -0.5, 0.5))
    sen = S.RangeBearingSensor(range_std=range_std, bearing_std=bearing_std, max_range=20, period=0.1)
    traj = tr.straight(0.05 * n_steps, speed=0.5, dt=0.1)
    run = SIM.simulate(traj, world, np.random.default_rng(31), k_r=k, k_l=k, landmark_sensor=sen)
    return world, sen, run


def test_particle_filter_posterior_agrees_with_the_ekf_on_a_benign_case():
    # Same model (wheel noise, prior N(0, diag(2 cm, 2 cm, 0.02 rad)²)), two corrections and one
    # prediction; the PF keeps its weights (no resampling) so its error is that of an importance
    # sample of effective size ESS: the weighted mean is within 5 √(Σ_ii/ESS) of the EKF's and a
    # variance within 5 √(2/ESS) relatively (Gaussian SE of a variance); the EKF's linearisation
    # error at these scales (σ/r ≈ 2 %) is orders of magnitude below.
    world, sen, run = _benign_run(range_std=0.1, bearing_std=0.05)
    start = Start(pose=(0.0, 0.0, 0.0), std=(0.02, 0.02, 0.02))
    ekf = E.run_ekf(run, world, sen, E.EKFConfig(motion=Motion(k_r=1e-3, k_l=1e-3)), start)
    cfg = PF.ParticleFilterConfig(n_particles=100_000, motion=Motion(k_r=1e-3, k_l=1e-3), ess_threshold=1e-9)
    pf = PF.run_particle(run, world, sen, np.random.default_rng(7), cfg, start)
    ess = pf.diagnostics["ess"][-1]
    assert ess > 2000
    assert pf.diagnostics["resampled"].sum() == 0
    sd = np.sqrt(np.diag(ekf.cov[-1]))
    assert np.all(np.abs(pf.mean[-1] - ekf.mean[-1]) <= 5 * sd / math.sqrt(ess)), (pf.mean[-1], ekf.mean[-1])
    rel = np.diag(pf.cov[-1]) / np.diag(ekf.cov[-1]) - 1
    assert np.all(np.abs(rel) <= 5 * math.sqrt(2 / ess)), rel
    # the correlations agree too (SE of a correlation ≈ (1 − ρ²)/√ESS)
    corr = lambda C: C / np.sqrt(np.outer(np.diag(C), np.diag(C)))
    assert np.all(np.abs(corr(pf.cov[-1]) - corr(ekf.cov[-1])) <= 5 / math.sqrt(ess))


@pytest.mark.parametrize(
    "motion",
    [Motion(model="velocity", alphas=(0.02, 0.0, 0.05, 0.0, 0.0, 0.0)),
     Motion(model="odometry", alphas=(0.05, 0.02, 0.02, 0.05))],
    ids=["velocity", "odometry"],
)  # fmt: skip
def test_histogram_filter_posterior_agrees_with_the_particle_filter(motion):
    # One motion model on both (velocity or odometry), 1 cm × 5° cells, one prediction
    # between two corrections.
    # The PF's (x, y) histogram of 2·10⁵ weighted particles is compared with the grid filter's
    # marginal by the Hellinger distance; a finite weighted sample is never at distance 0:
    # its sampling floor is that of ESS draws (hellinger_noise_floor(p, ESS), an
    # approximation for importance weights). The excess over the floor must be ≤ 0.05, the
    # target the multi-step maps meet against Monte Carlo.
    world, sen, run = _benign_run(range_std=0.1, bearing_std=0.1)
    start = Start(pose=(0.0, 0.0, 0.0), std=(0.03, 0.03, 0.05))
    hf = HF.run_histogram(run, world, sen, HF.HistogramFilterConfig(motion=motion, resolution=0.01, ntheta=72),
                          start, keep=[1])  # fmt: skip
    cfg = PF.ParticleFilterConfig(n_particles=200_000, motion=motion, ess_threshold=1e-9)
    pf = PF.run_particle(run, world, sen, np.random.default_rng(8), cfg, start, keep=[1])
    grid = HF.pose_grid_for(world, 0.01, 72)
    P, w = pf.snapshots[1]["particles"], pf.snapshots[1]["weights"]
    i = np.floor((P[:, 0] - grid.x0) / grid.resolution + 0.5).astype(int)
    j = np.floor((P[:, 1] - grid.y0) / grid.resolution + 0.5).astype(int)
    ok = (i >= 0) & (i < grid.nx) & (j >= 0) & (j < grid.ny)
    hist = np.bincount(i[ok] * grid.ny + j[ok], w[ok], minlength=grid.nx * grid.ny).reshape(grid.nx, grid.ny)
    assert hist.sum() > 1 - 1e-6
    p = hf.snapshots[1]["belief_xy"]
    ess = pf.diagnostics["ess"][1]
    h = stats.hellinger(p, hist)
    floor = stats.hellinger_noise_floor(p, int(ess))
    assert h * h - floor * floor <= 0.05**2, (h, floor, ess)
    assert hf.diagnostics["lost_mass"].sum() < 1e-9


def test_mass_leaving_the_grid_is_counted():
    g = Grid.square(0.0, 0.0, 20, 20, 0.01, 36)
    b = np.zeros(g.shape)
    b[17, 10, 18] = 1.0  # heading cell 18 is θ = 0: driving towards the x edge
    t = M.grid_transition("velocity", g, (0.5, 0.0), 0.1, (0.05, 0.0, 0.05, 0.0, 0.0, 0.0))
    new, info = M.predict_on_grid(b, t)
    assert info["lost_mass"] > 0.3
    assert new.sum() + info["lost_mass"] == pytest.approx(1.0, abs=1e-12)


def test_same_seed_same_particles():
    world, sen, run = _benign_run(n_steps=3)
    cfg = PF.ParticleFilterConfig(n_particles=500, resampling="linear_time", injection="augmented")
    a = PF.run_particle(run, world, sen, np.random.default_rng(5), cfg, keep=[3])
    b = PF.run_particle(run, world, sen, np.random.default_rng(5), cfg, keep=[3])
    np.testing.assert_array_equal(a.snapshots[3]["particles"], b.snapshots[3]["particles"])
    np.testing.assert_array_equal(a.mean, b.mean)


def test_simulated_measurements_have_the_sensor_noise():
    lm = np.array([[1.0, 1.0], [4.0, -1.0], [6.0, 2.0]])
    world = W.World(lm, np.arange(3))
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05, max_range=5.0, fov=math.pi, period=0.3)
    traj = tr.from_segments([tr.Line(3.0), tr.Arc(1.0, 2.0)], speed=0.5, dt=0.1)
    run = SIM.simulate(traj, world, np.random.default_rng(2), k_r=1e-3, k_l=1e-3, landmark_sensor=sen)
    obs = SIM.observation_steps(run.n_steps, 0.1, 0.3)
    assert obs[:7].tolist() == [True, False, False, True, False, False, True]
    zt = S.landmark_h(run.true_poses, lm)
    vis = S.landmark_visible(run.true_poses, lm, sen)
    np.testing.assert_array_equal(run.landmark_valid, vis & obs[:, None])
    e = run.landmark_z - zt
    e[..., 1] = np.angle(np.exp(1j * e[..., 1]))
    en = (e / [0.1, 0.05]).reshape(-1, 2)  # all draws, seen or not: N(0, 1) each
    assert np.all(np.abs(en.mean(axis=0)) <= 5 / math.sqrt(en.shape[0]))
    assert np.all(np.abs(en.var(axis=0) - 1) <= 5 * math.sqrt(2 / en.shape[0]))


def test_kidnapping_moves_the_rest_of_the_path_rigidly():
    traj = tr.from_segments([tr.Line(1.0), tr.Arc(1.0, 1.0)], speed=0.5, dt=0.1)
    world = W.World(LM, np.arange(3))
    a = SIM.simulate(traj, world, np.random.default_rng(3))
    b = SIM.simulate(traj, world, np.random.default_rng(3), kidnap_step=10, kidnap_pose=(5.0, -2.0, 2.0))
    np.testing.assert_array_equal(a.true_poses[:10], b.true_poses[:10])
    np.testing.assert_allclose(b.true_poses[10], [5.0, -2.0, 2.0])
    # relative motions are unchanged: step lengths and turns
    da, db = np.diff(a.true_poses[10:], axis=0), np.diff(b.true_poses[10:], axis=0)
    np.testing.assert_allclose(np.hypot(db[:, 0], db[:, 1]), np.hypot(da[:, 0], da[:, 1]), atol=1e-12)
    np.testing.assert_allclose(db[:, 2], da[:, 2], atol=1e-12)


def test_ml_association_failures_are_counted():
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05, max_range=20, period=0.1)
    traj = tr.straight(1.0, speed=0.5, dt=0.1)
    for lm, expect_wrong in ((np.array([[3.0, 1.0], [3.05, 1.0], [-1.0, 4.0]]), True), (LM, False)):
        world = W.World(lm, np.arange(3))
        run = SIM.simulate(traj, world, np.random.default_rng(4), landmark_sensor=sen)
        res = E.run_ekf(run, world, sen, E.EKFConfig(association="ml"))
        assert (res.diagnostics["wrong_associations"].sum() > 0) == expect_wrong
        assert res.diagnostics["n_measurements"].sum() == run.landmark_valid.sum()


def _global_world():
    lm = np.array([[1.0, 1.0], [6.5, 0.8], [3.5, 4.5], [0.8, 4.2], [5.2, 2.6], [7.0, 5.0]])
    seg = W.rectangle_segments(0, 8, 0, 6)
    return W.World(lm, np.arange(6), W.grid_from_segments(seg, 0.1), seg)


@pytest.mark.slow
def test_global_localization_particle_filter_succeeds_the_ekf_cannot():
    # Unknown start (uniform over the room), indistinguishable landmarks (ML association), a
    # sensor with a 180° field of view; one lap of a 1 m circle (12.6 s) from 10 seeded starts.
    # Success: final errors ≤ 0.5 m and 0.25 rad. The particle filter (4000 particles, each
    # associating for itself) succeeds in ≥ 8 of 10; the EKF, whose unimodal belief starts as
    # the moment-matched Gaussian of the room and associates from its mean, in ≤ 5 of 10
    # (seeded: PF 9/10, EKF 4/10).
    world = _global_world()
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05, max_range=5, fov=math.pi, period=0.5)
    start = Start("global")
    ok_pf = ok_ekf = 0
    for seed in range(10):
        rng = np.random.default_rng(seed)
        pose = (rng.uniform(2, 6), rng.uniform(2, 4), rng.uniform(-math.pi, math.pi))
        traj = tr.from_segments([tr.Arc(1.0, 2 * math.pi)], speed=0.5, dt=0.1, start=pose)
        run = SIM.simulate(traj, world, rng, k_r=1e-3, k_l=1e-3, landmark_sensor=sen)
        cfg = PF.ParticleFilterConfig(n_particles=4000, motion=Motion(k_r=1e-3, k_l=1e-3), association="ml")
        pf = PF.run_particle(run, world, sen, np.random.default_rng(100 + seed), cfg, start)
        ekf = E.run_ekf(run, world, sen, E.EKFConfig(motion=Motion(k_r=1e-3, k_l=1e-3), association="ml"), start)
        ok_pf += evaluate(pf, run)["success"]
        ok_ekf += evaluate(ekf, run)["success"]
    assert ok_pf >= 8, ok_pf
    assert ok_ekf <= 5, ok_ekf


def test_histogram_filter_solves_global_localization():
    world = _global_world()
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05, max_range=5, fov=math.pi, period=0.5)
    rng = np.random.default_rng(1)
    traj = tr.from_segments([tr.Arc(1.0, math.pi)], speed=0.5, dt=0.1, start=(3.0, 2.5, 0.5))
    run = SIM.simulate(traj, world, rng, k_r=1e-3, k_l=1e-3, landmark_sensor=sen)
    motion = Motion(model="velocity", alphas=(0.01, 0.0, 0.05, 0.0, 0.0, 0.0), scaling="abs")
    res = HF.run_histogram(run, world, sen, HF.HistogramFilterConfig(motion=motion, ntheta=36), Start("global"))
    ev = evaluate(res, run)
    assert ev["success"], ev["position_error"][-5:]
    assert res.diagnostics["masked_mass"].max() < 0.5


def test_kidnapped_robot_recovers_with_random_particles():
    # tracking from the known start; at step 60 (6 s) the robot is carried 3 m away. With 1 %
    # random particles at every correction (the remedy of Skalka 2011 §2.7.1.3), or with Augmented MCL
    # (α_slow = 0.05, α_fast = 0.5), the filter relocalizes within 5 s; without injection the
    # particles never find the new pose. (With landmark measurements the per-step likelihood
    # fluctuates by O(1) in its logarithm, so Augmented MCL also injects during tracking.)
    world = _global_world()
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05, max_range=6, period=0.3)
    traj = tr.from_segments([tr.Arc(1.0, 2 * math.pi)], speed=0.5, dt=0.1, start=(2.5, 2.0, 0.0))
    run = SIM.simulate(traj, world, np.random.default_rng(6), k_r=1e-3, k_l=1e-3, landmark_sensor=sen,
                       kidnap_step=60, kidnap_pose=(5.5, 3.5, 2.0))  # fmt: skip
    motion = Motion(k_r=1e-3, k_l=1e-3)
    options = {"fixed": {"injection": "fixed", "injection_fraction": 0.01},
               "augmented": {"injection": "augmented", "alpha_slow": 0.05, "alpha_fast": 0.5},
               "none": {"injection": "none"}}  # fmt: skip
    results = {}
    for name, opts in options.items():
        cfg = PF.ParticleFilterConfig(n_particles=3000, motion=motion, **opts)
        res = PF.run_particle(run, world, sen, np.random.default_rng(9), cfg, Start(pose=(2.5, 2.0, 0.0)))
        results[name] = evaluate(res, run, from_step=60)
        assert evaluate(res, run)["position_error"][55] < 0.3  # tracked before the kidnapping
    for name in ("fixed", "augmented"):
        assert results[name]["success"], name
        assert results[name]["time_to_converge"] < 5.0, name
    assert not results["none"]["success"]


def test_weighted_moments_wrap_the_heading():
    P = np.array([[0.0, 0.0, math.pi - 0.1], [2.0, 0.0, -math.pi + 0.1]])
    mean, cov = weighted_mean_cov(P, np.array([0.5, 0.5]))
    assert abs(abs(mean[2]) - math.pi) < 1e-12
    np.testing.assert_allclose(cov[2, 2], 0.01, rtol=1e-12)
    np.testing.assert_allclose(cov[0, 0], 1.0)


def test_wheel_sampler_is_the_midpoint_step_of_noisy_wheel_travels():
    # vectorised sampler against kinematics.step fed with the same draws
    _, _, run = _benign_run(n_steps=2)
    m = Motion(k_r=2e-3, k_l=5e-4)
    P = np.random.default_rng(1).normal(0, 0.1, (1000, 3))
    got = sample_motion(P, m, run, 1, np.random.default_rng(2))
    z = np.random.default_rng(2).standard_normal((2, 1000))
    dr = run.ds_r[1] + math.sqrt(2e-3 * abs(run.ds_r[1])) * z[0]
    dl = run.ds_l[1] + math.sqrt(5e-4 * abs(run.ds_l[1])) * z[1]
    ref = step(P, (dr + dl) / 2, (dr - dl) / run.track, method="midpoint")
    np.testing.assert_allclose(got, ref, rtol=1e-14, atol=1e-15)


@pytest.mark.slow
def test_grid_and_particle_filters_track_with_the_beam_model():
    # a 4 m × 3 m room with an inner wall; 8-beam scans every 0.2 s; both filters keep the
    # robot within 0.25 m around a 5.7 m circle, with half the RMS error of dead reckoning or less
    seg = np.vstack([W.rectangle_segments(0, 4, 0, 3), [[2.5, 0.0, 2.5, 1.2]]])
    world = W.World(np.zeros((0, 2)), np.zeros(0, dtype=int), W.grid_from_segments(seg, 0.1), seg)
    beams = S.BeamSensor(n_beams=8, max_range=5.0, sigma_hit=0.05, period=0.2)
    traj = tr.from_segments([tr.Arc(0.9, 2 * math.pi)], speed=0.5, dt=0.1, start=(1.3, 0.8, 0.0))
    run = SIM.simulate(traj, world, np.random.default_rng(12), k_r=5e-3, k_l=5e-3, beam_sensor=beams)
    start = Start(pose=(1.3, 0.8, 0.0), std=(0.05, 0.05, 0.03))
    pf = PF.run_particle(run, world, beams, np.random.default_rng(2),
                         PF.ParticleFilterConfig(n_particles=1000, motion=Motion(k_r=5e-3, k_l=5e-3)), start)  # fmt: skip
    alphas = velocity_alphas_for_wheels(5e-3, 5e-3, run.track, run.dt)  # the truth's wheel noise
    motion = Motion(model="velocity", alphas=alphas, scaling="abs")
    hf = HF.run_histogram(run, world, beams, HF.HistogramFilterConfig(motion=motion, ntheta=36), start)
    dead_reckoning = np.hypot(*(run.odometry[:, :2] - run.true_poses[:, :2]).T)
    for res in (pf, hf):
        err = evaluate(res, run)["position_error"]
        assert err.max() < 0.25, (res.filter, err.max())
        # the scans keep the error below half of dead reckoning's (RMS over the run)
        assert np.sqrt(np.mean(err**2)) < 0.5 * np.sqrt(np.mean(dead_reckoning**2)), res.filter
    assert pf.diagnostics["n_measurements"].sum() == 8 * run.beam_valid.sum()
