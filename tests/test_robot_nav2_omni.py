"""nav2's omni motion model: the fitted alphas reproduce an omni drive's wheel-model spread.

The test carries its own transcription of navigation2's sampler
(nav2_amcl/src/motion_model/omni_motion_model.cpp, ``OmniMotionModel::odometryUpdate``),
builds the model's Gaussian density from its covariance with scipy, and draws the wheel
model's motions with methods.drive_sampling (the Monte Carlo of every drive).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2, multivariate_normal

from pose_uncertainty.core.drives import DrivePath, MultiDof, Omni3
from pose_uncertainty.methods.drive_noise import DriveErrorModel
from pose_uncertainty.methods.drive_sampling import sample_poses
from pose_uncertainty.robot import nav2, nav2_omni
from pose_uncertainty.robot.exports import nav2_amcl_yaml

STEP = 0.01  # m per odometry step
DRIVES = {"omni3": (Omni3(), DriveErrorModel(k=5e-4)), "mdof": (MultiDof(), DriveErrorModel(k=5e-4, steer_var=1e-4))}


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def omni_amcl_sample(pose, delta, particle, alphas, n, rng):
    """omni_motion_model.cpp, transcribed: ``n`` copies of ``particle`` moved by the odometry ``delta``.

    ``pose`` is the odometry pose now, ``delta`` its change since the last update (Δθ wrapped).
    """
    a1, a2, a3, a4, a5 = alphas
    old_pose = np.asarray(pose, float) - np.asarray(delta, float)  # pf_vector_sub(pose, delta)
    delta_trans = math.sqrt(delta[0] * delta[0] + delta[1] * delta[1])
    delta_rot = delta[2]
    trans_hat_stddev = math.sqrt(a3 * (delta_trans * delta_trans) + a4 * (delta_rot * delta_rot))
    rot_hat_stddev = math.sqrt(a1 * (delta_rot * delta_rot) + a2 * (delta_trans * delta_trans))
    strafe_hat_stddev = math.sqrt(a4 * (delta_rot * delta_rot) + a5 * (delta_trans * delta_trans))
    p = np.tile(np.asarray(particle, float), (n, 1))
    delta_bearing = float(_wrap(math.atan2(delta[1], delta[0]) - old_pose[2])) + p[:, 2]
    cs_bearing, sn_bearing = np.cos(delta_bearing), np.sin(delta_bearing)
    delta_trans_hat = delta_trans + rng.normal(0.0, trans_hat_stddev, n)
    delta_rot_hat = delta_rot + rng.normal(0.0, rot_hat_stddev, n)
    delta_strafe_hat = 0 + rng.normal(0.0, strafe_hat_stddev, n)
    p[:, 0] += delta_trans_hat * cs_bearing + delta_strafe_hat * sn_bearing
    p[:, 1] += delta_trans_hat * sn_bearing - delta_strafe_hat * cs_bearing
    p[:, 2] += delta_rot_hat
    return p


def _parts(delta, theta_old):
    return nav2_omni.nav2_omni_deltas(np.asarray(delta, float)[None], np.array([theta_old]))


def test_the_library_sampler_is_navigation2s() -> None:
    pose, delta, alphas = np.array([1.0, 2.0, 0.9]), np.array([0.2, -0.15, 0.3]), (0.01, 0.02, 0.03, 0.04, 0.05)
    a = nav2_omni.sample_nav2_omni(_parts(delta, pose[2] - delta[2]), alphas, 20000, np.random.default_rng(1))[0]
    b = omni_amcl_sample(pose, delta, (0.0, 0.0, 0.0), alphas, 20000, np.random.default_rng(2))
    # two samplers, one distribution: means and covariances within 5 standard errors of
    # their difference (se of a covariance entry ≈ √(C_aa C_bb / n) for Gaussian draws)
    n = 20000
    se = b.std(axis=0) / math.sqrt(n)
    assert np.all(np.abs(a.mean(axis=0) - b.mean(axis=0)) < 5 * math.sqrt(2) * se)
    Cb = np.cov(b.T)
    se_cov = np.sqrt(np.outer(np.diag(Cb), np.diag(Cb)) / n)
    assert np.all(np.abs(np.cov(a.T) - Cb) < 5 * math.sqrt(2) * se_cov)


def _omni_cov(delta, theta_old, alphas):
    """The model's covariance in (x, y, θ) from the transcription's terms: the travel along the
    bearing b = (cos β, sin β), the strafe along (sin β, −cos β), the rotation on θ."""
    a1, a2, a3, a4, a5 = alphas
    t2, r2 = delta[0] ** 2 + delta[1] ** 2, delta[2] ** 2
    beta = math.atan2(delta[1], delta[0]) - theta_old
    along, side = np.array([math.cos(beta), math.sin(beta), 0.0]), np.array([math.sin(beta), -math.cos(beta), 0.0])
    return ((a3 * t2 + a4 * r2) * np.outer(along, along) + (a4 * r2 + a5 * t2) * np.outer(side, side)
            + np.diag([0.0, 0.0, a1 * r2 + a2 * t2])), along * math.sqrt(t2)  # fmt: skip


@pytest.mark.parametrize("delta", [(0.2, -0.15, 0.3), (0.0, 0.0, 0.21), (-0.26, 0.0, 0.0)])
def test_density_is_the_gaussian_of_the_sampler(delta) -> None:
    """Exact: the library's density equals the normal density of the sampler's covariance."""
    alphas, theta_old = (0.01, 0.02, 0.03, 0.04, 0.05), 0.7
    C, mean_xy = _omni_cov(delta, theta_old, alphas)
    mean = mean_xy + np.array([0.0, 0.0, delta[2]])
    pts = omni_amcl_sample((0.0, 0.0, theta_old + delta[2]), delta, (0, 0, 0), alphas, 50, np.random.default_rng(3))
    got = nav2_omni.nav2_omni_logpdf(pts[None], _parts(delta, theta_old), alphas)[0]
    np.testing.assert_allclose(got, multivariate_normal(mean, C).logpdf(pts), rtol=1e-9, atol=1e-9)


def test_fit_recovers_known_alphas_from_navigation2s_own_draws() -> None:
    """Second route: increments drawn by the transcribed sampler itself; the ML fit returns its alphas.

    Tolerance: 5 standard errors from the Fisher information of the three independent normal
    variances ``v = A α`` per increment (I = ½ n Σ_m A_mᵀ diag(1/v_m²) A_m), plus Nelder–Mead's
    ``xatol`` 1e-3 in log α (0.1 %).
    """
    rng = np.random.default_rng(5)
    alphas, n = (0.02, 0.05, 0.01, 0.004, 0.008), 200
    M = 120
    trans = rng.uniform(0.0, 0.35, M) * (rng.random(M) < 0.8)
    rot = rng.uniform(-0.3, 0.3, M) * (rng.random(M) < 0.7)
    rot[trans == 0] = rng.uniform(0.21, 0.4, int((trans == 0).sum()))
    direction, theta_old = rng.uniform(-np.pi, np.pi, M), rng.uniform(-np.pi, np.pi, M)
    deltas = np.stack([trans * np.cos(direction), trans * np.sin(direction), rot], -1)
    draws = np.stack([omni_amcl_sample((0.0, 0.0, th + d[2]), d, (0, 0, 0), alphas, n, rng)
                      for d, th in zip(deltas, theta_old, strict=True)])  # fmt: skip
    fitted = np.array(nav2_omni.ml_omni_alphas(draws, nav2_omni.nav2_omni_deltas(deltas, theta_old)))
    t2, r2, z = trans**2, rot**2, np.zeros(M)
    A = np.stack([np.stack([r2, t2, z, z, z], -1), np.stack([z, z, t2, r2, z], -1), np.stack([z, z, z, r2, t2], -1)], 1)
    v = A @ np.array(alphas)  # (M, 3)
    info = 0.5 * n * np.einsum("mja,mj,mjb->ab", A, 1.0 / v**2, A)
    se = np.sqrt(np.diag(np.linalg.inv(info)))
    assert np.all(np.abs(fitted - alphas) <= 5 * se + 1e-3 * np.array(alphas)), (fitted, alphas, se)


def omni_path(drive, step: float = STEP) -> DrivePath:
    """Forward, sideways, diagonal, turns in place, arcs, backward: every kind of increment, twice."""
    segs = []
    for _ in range(2):
        for twist, n in (((step, 0, 0), 150), ((0, step, 0), 100), ((0.7 * step, -0.7 * step, 0), 100),
                         ((0, 0, 0.01), 157), ((step, 0, 0.01), 157), ((-step, 0, 0), 60),
                         ((0.5 * step, 0.5 * step, -0.008), 150)):  # fmt: skip
            segs.append(np.tile(twist, (n, 1)))
    return DrivePath(drive, drive.measurements(np.concatenate(segs)), 0.02)


@pytest.fixture(scope="module", params=sorted(DRIVES))
def fitted(request):
    drive, model = DRIVES[request.param]
    return nav2_omni.fit_nav2_omni_alphas(omni_path(drive), model, np.random.default_rng(4)), drive, model


def test_fitted_alphas_reproduce_the_wheel_models_spread(fitted) -> None:
    """Coverage of wheel-model draws by the test's own nav2 omni sampler's 95 % regions.

    Every AMCL increment of the drive the alphas were fitted on (forward, sideways,
    diagonal, backward, in place, arcs): per increment, n = 300 wheel-model draws
    (methods.drive_sampling, from the odometry pose at the last update) and the 95 %
    region of the transcribed sampler's 4000 draws from that pose — the omni model is
    Gaussian in (x, y, θ), so the region is the Mahalanobis ellipsoid of their mean and
    covariance. The draws are independent: the binomial standard error of a 95 % coverage
    of M·n draws is √(0.95·0.05/(M n)) ≈ 0.0015; the band is 4 of them plus 0.025 for the
    model's structure (nav2 gives every direction of travel the same spread and draws the
    strafe and the rotation independently, where an omni drive's wheels spread a forward
    and a sideways move differently and turn the body as they push it: single increments
    are covered from 0.88 sideways to 0.99 forward, the drive's mix 0.93). The band is
    narrow enough that alphas off by a factor of 2 either way fall out of it (0.76, 0.986).
    Also the library's own overall coverage figure lies in the band (its own binomial
    error added).
    """
    fit, drive, model = fitted
    path, n = omni_path(drive), 300
    odom = path.poses
    pairs = nav2.update_pairs(odom, fit.update_min_d, fit.update_min_a, 200)
    rng_wheel, rng_nav2 = np.random.default_rng(8), np.random.default_rng(9)
    inside = []
    for a, c in pairs:
        sub = DrivePath(drive, path.u[a:c], path.dt, start=odom[a])
        wheel = sample_poses(sub, model, n, rng_wheel, method="exact", workers=1)
        delta = odom[c] - odom[a]
        delta[2] = float(_wrap(delta[2]))
        ours = omni_amcl_sample(odom[c], delta, odom[a], fit.alphas, 4000, rng_nav2)
        mu, C = ours.mean(axis=0), np.cov(ours.T)
        d = wheel - mu
        d[:, 2] = _wrap(d[:, 2])
        inside.append(np.einsum("ia,ab,ib->i", d, np.linalg.inv(C), d) <= chi2.ppf(0.95, 3))
    cover = float(np.mean(inside))
    band = 4 * math.sqrt(0.95 * 0.05 / (len(pairs) * n)) + 0.025
    assert abs(cover - 0.95) <= band, cover
    lib = fit.coverage["overall"]
    assert abs(lib - 0.95) <= band + 4 * math.sqrt(0.95 * 0.05 / fit.coverage["n_draws"]), lib


def test_export_writes_the_omni_model(fitted, tmp_path) -> None:
    fit, drive, model = fitted
    text = nav2_amcl_yaml(fit.as_dict())
    assert 'robot_model_type: "nav2_amcl::OmniMotionModel"' in text
    for i, a in enumerate(fit.alphas, start=1):
        assert f"alpha{i}: {a:.6g}" in text
    assert len(fit.alphas) == 5
    out = nav2_omni.write_nav2_omni_yaml(omni_path(drive), model, tmp_path / "nav2_amcl.yaml", seed=4)
    assert (tmp_path / "nav2_amcl.yaml").read_text() == nav2_amcl_yaml(out)
    assert out["alpha5"] == fit.alphas[4]  # the same seed, the same fit


def test_only_holonomic_drives() -> None:
    from pose_uncertainty.core.drives import Differential

    path = DrivePath(Differential(0.3), np.tile([0.01, 0.01], (200, 1)), 0.02)
    with pytest.raises(ValueError, match="omni3"):
        nav2_omni.fit_nav2_omni_alphas(path, DriveErrorModel(), np.random.default_rng(0))
