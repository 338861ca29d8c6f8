"""nav2's differential motion model: the fitted alphas reproduce the wheel model's spread.

The test carries its own implementation of navigation2's sampler
(nav2_amcl/src/motion_model/differential_motion_model.cpp) and of its density, and
draws the wheel model's motions with methods.sampling (the Monte Carlo of Method A).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pose_uncertainty.core.trajectories import Trajectory
from pose_uncertainty.methods.sampling import sample_end_poses
from pose_uncertainty.robot import nav2
from pose_uncertainty.robot.align import align
from pose_uncertainty.robot.simulate import SimulatedRobot, simulate_recording

ROBOT = SimulatedRobot()
GEOMETRY = (ROBOT.radius_left, ROBOT.radius_right, ROBOT.track)


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def amcl_sample(delta, theta_old, alphas, n, rng):
    """nav2 differential_motion_model.cpp, transcribed: n particles from the origin."""
    a1, a2, a3, a4 = alphas
    dx, dy, dth = delta
    rot1 = 0.0 if math.sqrt(dx * dx + dy * dy) < 0.01 else float(_wrap(math.atan2(dy, dx) - theta_old))
    trans = math.sqrt(dx * dx + dy * dy)
    rot2 = float(_wrap(dth - rot1))
    n1 = min(abs(float(_wrap(rot1))), abs(float(_wrap(rot1 - math.pi))))
    n2 = min(abs(float(_wrap(rot2))), abs(float(_wrap(rot2 - math.pi))))
    r1 = _wrap(rot1 - rng.normal(0.0, math.sqrt(a1 * n1 * n1 + a2 * trans * trans), n))
    tr = trans - rng.normal(0.0, math.sqrt(a3 * trans * trans + a4 * n1 * n1 + a4 * n2 * n2), n)
    r2 = _wrap(rot2 - rng.normal(0.0, math.sqrt(a1 * n2 * n2 + a2 * trans * trans), n))
    return np.stack([tr * np.cos(r1), tr * np.sin(r1), r1 + r2], axis=-1)


def test_the_library_sampler_is_navigation2s() -> None:
    delta, th0, alphas = np.array([0.2, -0.15, 0.3]), 0.4, (0.01, 0.02, 0.03, 0.04)
    parts = nav2.nav2_deltas(delta[None], np.array([th0]))
    a = nav2.sample_nav2(parts, alphas, 20000, np.random.default_rng(1))[0]
    b = amcl_sample(delta, th0, alphas, 20000, np.random.default_rng(2))
    # two samplers, one distribution: means and covariances within 5 standard errors of
    # their difference (se of a covariance entry ≈ √(C_aa C_bb / n) for near-Gaussian draws)
    n = 20000
    se = b.std(axis=0) / math.sqrt(n)
    assert np.all(np.abs(a.mean(axis=0) - b.mean(axis=0)) < 5 * math.sqrt(2) * se)
    Cb = np.cov(b.T)
    se_cov = np.sqrt(np.outer(np.diag(Cb), np.diag(Cb)) / n)
    assert np.all(np.abs(np.cov(a.T) - Cb) < 5 * math.sqrt(2) * se_cov)


def test_in_place_rotation_uses_navigation2s_small_translation_rule() -> None:
    parts = nav2.nav2_deltas(np.array([[0.003, 0.004, 0.5]]), np.array([1.0]))
    assert parts["rot1"][0] == 0.0
    assert math.isclose(parts["rot2"][0], 0.5)
    back = nav2.nav2_deltas(np.array([[-0.3, 0.0, 0.0]]), np.array([0.0]))
    # backward motion: δrot1 = π, folded to 0 for the noise
    assert math.isclose(abs(back["rot1"][0]), math.pi)
    assert back["n1"][0] < 1e-12


@pytest.fixture(scope="module")
def fitted() -> tuple[nav2.Nav2Fit, object]:
    rec = align(simulate_recording(ROBOT, np.random.default_rng(3)))
    fit = nav2.fit_nav2_alphas(rec.phi_l, rec.phi_r, GEOMETRY, (ROBOT.k_r, ROBOT.k_l), np.random.default_rng(4))
    return fit, rec


def _straight(d: float) -> Trajectory:
    n = 25
    return Trajectory(ds_r=np.full(n, d / n), ds_l=np.full(n, d / n), dt=0.02, track=ROBOT.track)


def _turn(a: float) -> Trajectory:
    n = 25
    s = 0.5 * ROBOT.track * a / n
    return Trajectory(ds_r=np.full(n, s), ds_l=np.full(n, -s), dt=0.02, track=ROBOT.track)


@pytest.mark.parametrize(("kind", "traj"), [("straight", _straight(0.26)), ("turn", _turn(0.21))])
def test_fitted_alphas_reproduce_the_wheel_models_spread(fitted, kind, traj) -> None:
    """Coverage of wheel-model draws by the test's own nav2 sampler's 95 % region.

    The region: the 95 % Mahalanobis ellipsoid of the nav2 draws' own mean and covariance
    in (x, y, θ) (turns in place: in (x, θ), nav2's direction of a sub-centimetre
    translation being arbitrary). n = 4000 wheel draws: the binomial standard error of a
    95 % coverage is 0.0034; the band is 4 of them plus 0.02 for the model's structure
    (nav2 draws rot1 and rot2 independently where the wheels tie the lateral drift to the
    heading). Also the library's own coverage figure for the class lies in the band.
    """
    from scipy.stats import chi2

    fit, _ = fitted
    n = 4000
    wheel = sample_end_poses(traj, ROBOT.k_r, ROBOT.k_l, n, np.random.default_rng(8), method="exact")
    end = traj.poses[-1]
    ours = amcl_sample(end, 0.0, fit.alphas, 40000, np.random.default_rng(9))
    dims = [0, 2] if kind == "turn" else [0, 1, 2]
    mu, C = ours[:, dims].mean(axis=0), np.cov(ours[:, dims].T)
    d = wheel[:, dims] - mu
    d[:, -1] = _wrap(d[:, -1])
    inside = np.einsum("ia,ab,ib->i", d, np.linalg.inv(C), d) <= chi2.ppf(0.95, len(dims))
    band = 4 * math.sqrt(0.95 * 0.05 / n) + 0.02
    assert abs(inside.mean() - 0.95) <= band, inside.mean()
    lib = fit.coverage["translation" if kind == "straight" else "rotation"]["coverage"]
    assert abs(lib - 0.95) <= band + 4 * math.sqrt(0.95 * 0.05 / (fit.n_samples * 60)), lib


def test_update_rule_is_amcls() -> None:
    odom = np.array([[0, 0, 0], [0.2, 0, 0], [0.26, 0, 0], [0.3, 0.1, 0], [0.3, 0.1, 0.25]], float)
    np.testing.assert_array_equal(nav2.amcl_update_indices(odom, 0.25, 0.2), [0, 2, 4])
