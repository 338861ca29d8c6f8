"""Calibration of simulated robots with known radii, track and k: the 95 % intervals cover the truth.

Each repeat simulates the robot (its own seed), calibrates, and counts for each of the
seven quantities whether its interval holds the true value. With intervals of exact 95 %
coverage the count over R repeats is Binomial(R, 0.95); the acceptance band is that
distribution's central interval of probability 1 − 0.001/7 (so that a right procedure
fails one of the seven checks with probability about 0.001), and the pooled count over
all 7R intervals must lie in Binomial(7R, 0.95)'s band of probability 0.999 (the pooled
test is approximate: the seven intervals of one repeat are correlated).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from scipy.stats import binom

from pose_uncertainty.robot.align import align
from pose_uncertainty.robot.bag import read_bag
from pose_uncertainty.robot.fit import CALIBRATION_KEYS, calibrate_segments
from pose_uncertainty.robot.geometry_fit import nominal_from_odometry
from pose_uncertainty.robot.noise_fit import held_out_check
from pose_uncertainty.robot.segments import cut_segments
from pose_uncertainty.robot.simulate import SimulatedRobot, simulate_recording, write_simulated_bag

ROBOT = SimulatedRobot()
TRUE = {
    "E_d": ROBOT.radius_right / ROBOT.radius_left, "E_b": ROBOT.track / ROBOT.nominal_track,
    "wheel_radius_left": ROBOT.radius_left, "wheel_radius_right": ROBOT.radius_right, "track": ROBOT.track,
    "k_r": ROBOT.k_r, "k_l": ROBOT.k_l,
}  # fmt: skip
NOMINAL = (ROBOT.nominal_radius, ROBOT.nominal_radius, ROBOT.nominal_track)


def _band(n: int, alpha: float) -> tuple[int, int]:
    """Central interval of Binomial(n, 0.95) with probability 1 − alpha (counts)."""
    return int(binom.ppf(alpha / 2, n, 0.95)), int(binom.isf(alpha / 2, n, 0.95))


@functools.cache
def _covered_by_repeat(s: int) -> tuple[bool, ...]:
    """Repeat ``s`` (its own seed): for each quantity, whether its interval holds the truth (computed
    once a session: the few repeats are the first of the hundred)."""
    seg = cut_segments(align(simulate_recording(ROBOT, np.random.default_rng(1000 + s))), ROBOT.nominal_radius)
    geo, noise, _, _ = calibrate_segments(seg, NOMINAL)
    q = {**geo.quantities(), **noise.as_dict()}
    return tuple(q[k]["ci95"][0] <= TRUE[k] <= q[k]["ci95"][1] for k in CALIBRATION_KEYS)


def _covered(seeds: range) -> np.ndarray:
    """(R, 7) booleans: interval holds the truth."""
    return np.array([_covered_by_repeat(s) for s in seeds])


def _check(cov: np.ndarray) -> None:
    R = cov.shape[0]
    lo, hi = _band(R, 0.001 / len(CALIBRATION_KEYS))
    counts = dict(zip(CALIBRATION_KEYS, cov.sum(axis=0).tolist(), strict=True))
    assert all(lo <= c <= hi for c in counts.values()), (counts, (lo, hi))
    plo, phi = _band(cov.size, 0.001)
    assert plo <= int(cov.sum()) <= phi, (int(cov.sum()), (plo, phi))


@pytest.mark.slow
def test_intervals_cover_the_truth_in_a_few_repeats() -> None:
    # 4 repeats: each quantity must be covered at least 2 times (band of Binomial(4, 0.95))
    _check(_covered(range(4)))


@pytest.mark.slow
def test_intervals_cover_the_truth_in_95_percent_of_100_repeats() -> None:
    # band per quantity [89, 99] of 100, pooled [650, 680] of 700 (module docstring)
    _check(_covered(range(100)))


@pytest.mark.slow
def test_a_bag_gives_the_arrays_streams(tmp_path) -> None:
    """Two routes: bag written and read back with rosbags, and the simulated arrays directly."""
    bag = write_simulated_bag(tmp_path / "b", ROBOT, np.random.default_rng(5))
    from_bag = align(read_bag(bag))
    direct = align(simulate_recording(ROBOT, np.random.default_rng(5)))
    for name in ("t", "phi_l", "phi_r", "truth_t", "odom_t"):
        np.testing.assert_array_equal(getattr(from_bag, name), getattr(direct, name))
    np.testing.assert_allclose(from_bag.truth_poses, direct.truth_poses, atol=1e-12)  # via quaternions
    nominal = nominal_from_odometry(from_bag)
    assert nominal is not None
    np.testing.assert_allclose(nominal, NOMINAL, rtol=1e-9)


def test_held_out_check_of_residuals_drawn_from_their_model() -> None:
    """NEES and ellipse coverage of Gaussian residuals drawn with known covariances.

    J = 4000 draws: the mean NEES lies in its χ²(3J)/J band and the coverage in its
    Wilson interval, each with probability 0.95 — the seeds are fixed, so the test
    checks the two formulas against the distribution they describe.
    """
    rng = np.random.default_rng(21)
    J = 4000
    A = rng.standard_normal((J, 3, 3)) * np.array([0.01, 0.01, 0.03])[:, None]
    Sigma = A @ np.swapaxes(A, -1, -2) + 1e-6 * np.eye(3)
    r = np.einsum("jab,jb->ja", np.linalg.cholesky(Sigma), rng.standard_normal((J, 3)))
    check = held_out_check(r, Sigma)
    assert check["nees_band95"][0] <= check["nees_mean"] <= check["nees_band95"][1]
    lo, hi = check["ellipse_coverage_ci95"]
    assert lo <= 0.95 <= hi
    # a covariance too small by half is caught by both
    bad = held_out_check(r, 0.5 * Sigma)
    assert not bad["nees_ok"]
    assert not bad["ellipse_ok"]
