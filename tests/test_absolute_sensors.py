"""Absolute sensors (Skalka 2011 §4.1, §4.3): Jacobians, samplers against their densities, and each
model in the EKF, the histogram and the particle filter against closed forms."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core.grids import Grid
from pose_uncertainty.core.kinematics import wrap_angle
from pose_uncertainty.core.stats import chi2_ppf
from pose_uncertainty.localization.absolute_sensors import (
    BearingBeacons,
    Compass,
    Gnss,
    RangeBeacons,
    ekf_update_absolute,
    grid_log_likelihood,
)
from pose_uncertainty.localization.evaluation import weighted_mean_cov
from pose_uncertainty.localization.histogram import hf_correct, hf_estimate, initial_belief
from pose_uncertainty.localization.particle import pf_correct
from pose_uncertainty.localization.resampling import effective_sample_size
from pose_uncertainty.localization.result import Start
from pose_uncertainty.localization.world import World

BEACONS = np.array([[3.0, 1.0], [-2.0, 4.0], [0.5, -3.0]])
SENSORS = {
    "range": RangeBeacons(BEACONS, 0.1),
    "bearing": BearingBeacons(BEACONS, 0.03),
    "gnss": Gnss(0.5, bias=np.array([0.3, -0.2]), outlier_prob=0.1, outlier_std=5.0),
    "compass": Compass(0.05, bias=0.1, disturbances=np.array([[1.0, 1.0, 0.3, 0.8], [-1.0, 0.5, -0.2, 0.5]])),
}
POSE = np.array([0.4, 0.7, 0.3])


@pytest.mark.parametrize("name", sorted(SENSORS))
def test_jacobian_matches_finite_differences(name, rng):
    s = SENSORS[name]
    poses = POSE + 0.3 * rng.standard_normal((4, 3))
    J = s.jacobian(poses)
    eps = 1e-6
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        fd = wrap_angle(s.h(poses + d) - s.h(poses - d)) / (2 * eps)
        assert_allclose(J[..., i], fd, atol=1e-7, rtol=1e-6)


def _chi2_check(counts, probs, n):
    """Pearson χ² of binned samples against the model's bin probabilities, at the 10⁻³ level."""
    E = n * probs
    keep = E > 5
    stat = float(np.sum((counts[keep] - E[keep]) ** 2 / E[keep]))
    assert stat < float(chi2_ppf(0.999, int(keep.sum()) - 1)), stat


def _bin_probs(edges, density, sub=200):
    """∫ density over each bin (midpoint rule on ``sub`` points per bin)."""
    t = (np.arange(sub) + 0.5) / sub
    pts = edges[:-1, None] + np.diff(edges)[:, None] * t
    return density(pts).mean(axis=1) * np.diff(edges)


@pytest.mark.parametrize("name", ["range", "bearing", "compass"])
def test_sampler_follows_the_density_1d(name, rng):
    s = SENSORS[name]
    if name != "compass":  # one beacon: the density of one component
        s = type(s)(BEACONS[:1], s.range_std if name == "range" else s.bearing_std)
    n = 40_000
    z = s.sample(np.broadcast_to(POSE, (n, 3)), rng)[:, 0]
    h = float(s.h(POSE)[0])
    sd = float(np.sqrt(s.R[0, 0]))
    edges = h + sd * np.linspace(-5, 5, 41)
    e = wrap_angle(z - h) + h if name != "range" else z
    counts = np.histogram(e, edges)[0]

    def density(v):
        return np.exp(s.log_likelihood(POSE, v[..., None]))

    probs = _bin_probs(edges, density)
    assert probs.sum() == pytest.approx(1.0, abs=1e-5)  # the density integrates to 1
    _chi2_check(counts, probs, n)


def test_gnss_sampler_follows_the_density(rng):
    s = SENSORS["gnss"]
    n = 40_000
    z = s.sample(np.broadcast_to(POSE, (n, 3)), rng)
    d = z - s.h(POSE)
    r = np.hypot(d[:, 0], d[:, 1])
    edges = np.concatenate([np.linspace(0, 2.5, 26), np.linspace(3, 25, 12)])
    counts = np.histogram(r, edges)[0]

    def radial(v):  # the density of the radius: 2πr p(h + (r, 0))
        pts = s.h(POSE) + np.stack([v, np.zeros_like(v)], axis=-1)
        return 2 * np.pi * v * np.exp(s.log_likelihood(POSE, pts))

    probs = _bin_probs(edges, radial)
    assert probs.sum() == pytest.approx(1.0, abs=1e-4)
    _chi2_check(counts, probs, n)
    # isotropic: the direction is uniform
    _chi2_check(np.histogram(np.arctan2(d[:, 1], d[:, 0]), np.linspace(-np.pi, np.pi, 9))[0], np.full(8, 1 / 8), n)


# --- linear-Gaussian closed forms ---------------------------------------------------------------

MU = np.array([0.2, -0.1, 0.3])
STD = np.array([0.3, 0.2, 0.08])


def _information_form(mu, P, H, R, z_minus_offset):
    """The Kalman posterior by the information form (another route than the gain form)."""
    Pi = np.linalg.inv(np.linalg.inv(P) + H.T @ np.linalg.inv(R) @ H)
    return Pi @ (np.linalg.solve(P, mu) + H.T @ np.linalg.solve(R, z_minus_offset)), Pi


def _closed(sensor, z):
    H = sensor.jacobian(MU)  # constant: the models are linear here
    offset = sensor.h(MU) - H @ MU
    return _information_form(MU, np.diag(STD**2), H, sensor.R, z - offset)


LINEAR = {"gnss": Gnss(0.25, bias=np.array([0.1, 0.05])), "compass": Compass(0.05, bias=0.1)}
Z = {"gnss": np.array([0.5, 0.1]), "compass": np.array([0.45])}


@pytest.mark.parametrize("name", sorted(LINEAR))
def test_ekf_equals_the_kalman_closed_form(name):
    s = LINEAR[name]
    mean, cov, nis, ok = ekf_update_absolute(MU, np.diag(STD**2), Z[name], s)
    m_ref, P_ref = _closed(s, Z[name])
    assert_allclose(mean, m_ref, rtol=1e-12, atol=1e-14)
    assert_allclose(cov, P_ref, rtol=1e-12, atol=1e-16)
    H, nu = s.jacobian(MU), wrap_angle(Z[name] - s.h(MU))
    assert nis == pytest.approx(nu @ np.linalg.solve(H @ np.diag(STD**2) @ H.T + s.R, nu), rel=1e-12)
    assert ok
    # batched over priors: each the same as alone
    mb, _, _, _ = ekf_update_absolute(np.stack([MU, MU + 0.1]), np.stack([np.diag(STD**2)] * 2), Z[name], s)
    assert_allclose(mb[0], mean, rtol=1e-13)


def test_ekf_gate_rejects_an_outlier():
    s = LINEAR["gnss"]
    P = np.diag(STD**2)
    mean, cov, nis, ok = ekf_update_absolute(MU, P, MU[:2] + 5.0, s, gate=0.999)
    assert not ok
    assert nis > chi2_ppf(0.999, 2)
    assert_allclose(mean, MU)
    assert_allclose(cov, P)


def _grid_posterior(sensor, z, grid):
    world = World(np.zeros((0, 2)), np.zeros(0, dtype=np.int64), bounds=(-5.0, 5.0, -5.0, 5.0))
    prior = initial_belief(Start(pose=tuple(MU), std=tuple(STD)), world, grid)
    post, _ = hf_correct(prior, grid_log_likelihood(sensor, grid, z))
    mean, cov = hf_estimate(post, grid)
    # the cell-centre moments (hf_estimate adds the piecewise-uniform cells' h²/12)
    return mean, cov - np.diag([grid.dx**2, grid.dy**2, grid.theta_resolution**2]) / 12


@pytest.mark.parametrize("name", sorted(LINEAR))
def test_histogram_posterior_equals_the_closed_form(name):
    s = LINEAR[name]
    m_ref, P_ref = _closed(s, Z[name])
    if name == "gnss":  # (x, y) only: one heading cell; ±6σ of the prior at 1/20 of the posterior σ
        grid = Grid.square(MU[0] - 1.8, MU[1] - 1.2, 361, 241, 0.01, 1)
        sl = slice(0, 2)
    else:  # θ only: one position cell, 720 heading cells of 0.5°
        grid = Grid.square(MU[0], MU[1], 1, 1, 0.01, 720)
        sl = slice(2, 3)
    mean, cov = _grid_posterior(s, Z[name], grid)
    # lattice moments of a Gaussian: error ~ e^{−2π²σ²/h²} (≪ 10⁻⁹ here) plus the ±6σ truncation
    assert_allclose(mean[sl], m_ref[sl], atol=1e-7)
    assert_allclose(cov[sl, sl], P_ref[sl, sl], rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize("name", sorted(LINEAR))
def test_particle_posterior_equals_the_closed_form(name, rng):
    s = LINEAR[name]
    m_ref, P_ref = _closed(s, Z[name])
    n = 40_000
    P = MU + STD * rng.standard_normal((n, 3))
    w, _ = pf_correct(np.full(n, 1 / n), s.log_likelihood(P, Z[name]))
    mean, cov = weighted_mean_cov(P, w)
    ess = effective_sample_size(w)
    # self-normalised importance sampling: mean error sd ≈ √(P⁺/ESS), variance's ≈ √(2/ESS)·P⁺
    sd = np.sqrt(np.diag(P_ref) / ess)
    assert np.all(np.abs(mean - m_ref) < 5 * sd)
    assert np.all(np.abs(np.diag(cov) - np.diag(P_ref)) < 5 * math.sqrt(2 / ess) * np.diag(P_ref))


# --- the non-linear beacons: nearly linear far away; three filters agree ------------------------


FAR = {"range": 40.0, "bearing": 10.0}  # beacon distance [m]


def _far(name):
    d = FAR[name]
    far = np.array([[d, 0.0], [0.0, d], [-d * 0.7, -d * 0.7]])
    # bearing σ of 0.05 rad: the posterior heading σ (≈ 0.03 rad) spans two 1° heading cells
    return RangeBeacons(far, 0.1) if name == "range" else BearingBeacons(far, 0.05)


@pytest.mark.parametrize("name", ["range", "bearing"])
def test_beacons_agree_in_the_three_filters(name, rng):
    s = _far(name)
    true = MU + np.array([0.1, -0.15, 0.05])
    z = s.h(true)
    m_ekf, P_ekf, _, _ = ekf_update_absolute(MU, np.diag(STD**2), z, s)
    nt = 1 if name == "range" else 360
    grid = Grid.square(MU[0] - 1.8, MU[1] - 1.2, 73, 49, 0.05, nt)
    m_hf, P_hf = _grid_posterior(s, z, grid)
    n = 40_000
    P = MU + STD * rng.standard_normal((n, 3))
    w, _ = pf_correct(np.full(n, 1 / n), s.log_likelihood(P, z))
    m_pf, P_pf = weighted_mean_cov(P, w)
    ess = effective_sample_size(w)
    dims = slice(0, 2) if name == "range" else slice(0, 3)
    # the measurement's curvature over the prior (σ²/d for a range, σ²/d² for a bearing, seen at the
    # distance d: σ²/d either way) bounds the non-linear part of the posterior; the particle filter
    # adds its sampling error √(P/ESS)
    curv = 0.3**2 / FAR[name]
    sd = np.sqrt(np.diag(P_ekf) / ess)[dims]
    assert np.all(np.abs(m_hf[dims] - m_ekf[dims]) < curv), (m_hf, m_ekf)  # measured ≤ 8·10⁻⁴ m
    assert np.all(np.abs(m_pf[dims] - m_ekf[dims]) < curv + 5 * sd), (m_pf, m_ekf)
    # variances: relative non-linear part ~ σ/d ≤ 3 % bounds them (measured ≤ 0.2 %)
    assert_allclose(np.diag(P_hf)[dims], np.diag(P_ekf)[dims], rtol=0.3 / FAR[name])
    assert_allclose(np.diag(P_pf)[dims], np.diag(P_ekf)[dims], rtol=0.3 / FAR[name] + 5 * math.sqrt(2 / ess))


def test_models_refuse_bad_parameters():
    with pytest.raises(ValueError, match="outlier_prob must be < 1"):
        Gnss(outlier_prob=1.0)
    with pytest.raises(ValueError, match="bearing_std must be <= 1"):
        BearingBeacons(BEACONS, 2.0)
    with pytest.raises(ValueError, match="beacons must hold"):
        RangeBeacons(np.zeros((0, 2)))
    with pytest.raises(ValueError, match="z must have shape"):
        SENSORS["range"].log_likelihood(POSE, np.zeros(2))
