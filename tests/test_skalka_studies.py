"""The studies of Skalka 2011's localization techniques against independent routes to their numbers.

* relative sensing: the INS under a constant accelerometer bias alone has the closed form
  σ_pos = √2·b·t²/2 (exact for the constant-acceleration step), so its fitted time exponent is 2;
  Method A and Monte Carlo agree for the INS and gyro-aided odometry;
* guaranteed bounds: every sampled bounded-error trajectory lies in the box and the zonotope; Method A's
  99 % ellipse equals the covariance method's (:func:`pose_uncertainty.methods.covariance.propagate`)
  with the uniform errors' variance w²/3 per step written as k = w²/(3|Δs|);
* absolute sensing: the EKF's posterior heading σ from a compass is the linear-Gaussian closed form
  (1/σ₀² + M/σ_c²)^(−½); the particle filter's agrees within its Monte Carlo error;
* the representations: the hypothesis count of known masses; the topological track of a path along the
  graph's edges; the memory of the beliefs from their sizes;
* active localization: the share localized by each step never falls.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pose_uncertainty.analysis.studies.absolute_sensing import absolute_sensing_study
from pose_uncertainty.analysis.studies.active_localization import active_localization_study
from pose_uncertainty.analysis.studies.guaranteed_bounds import guaranteed_bounds_study
from pose_uncertainty.analysis.studies.relative_sensing import relative_sensing_study
from pose_uncertainty.analysis.studies.representations import (
    _place_track,
    hypothesis_count,
    representations_study,
)
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.stats import chi2_ppf
from pose_uncertainty.localization import topological as tp
from pose_uncertainty.localization.world import load_world
from pose_uncertainty.methods import covariance as cv
from pose_uncertainty.methods.intervals import BoundedWheelErrors

STRAIGHT = {"name": "straight", "length": 4.0, "dt": 0.1, "track": 0.2, "speed": 0.5}
ZERO_GYRO = {"bias_std": 0.0, "bias_rw_std": 0.0, "white_std": 0.0, "scale_std": 0.0}


def test_ins_under_an_accelerometer_bias_alone_is_the_closed_form_t_squared():
    b = 0.01
    r = relative_sensing_study(trajectory=STRAIGHT, gyro=ZERO_GYRO, accel={"bias_std": b}, n=200, n_points=8)
    t = np.asarray(r["time"])
    np.testing.assert_allclose(r["ins"]["sigma_a"], math.sqrt(2.0) * b * t**2 / 2.0, rtol=1e-9)
    assert r["ins"]["fits_a"]["time"]["power_exponent"] == pytest.approx(2.0, abs=1e-9)


def test_method_a_and_monte_carlo_agree_for_the_ins_and_gyro_aided_odometry():
    n = 4000
    r = relative_sensing_study(trajectory=STRAIGHT, n=n, n_points=4, seed=3)
    # relative standard error of a sample σ is 1/√(2(n−1)); 5 of them (the schemes are near linear here)
    tol = 5.0 / math.sqrt(2.0 * (n - 1))
    for scheme in ("ins", "gyro_odometry"):
        assert r[scheme]["mc_over_a"] == pytest.approx(1.0, abs=tol), scheme
    assert r["best"] == "gyro_odometry"


def test_the_guaranteed_sets_hold_every_sample_and_the_ellipse_is_the_covariance_methods():
    pulses, diameter = 500, 0.1
    r = guaranteed_bounds_study(trajectory=STRAIGHT, pulses_per_rev=pulses, wheel_diameter=diameter, slip_rel=0.0,
                                n=4000, n_points=4)  # fmt: skip
    assert r["box_contains"] == 1.0
    assert r["zonotope_contains"] == 1.0
    t = tr.from_config(STRAIGHT)
    w = BoundedWheelErrors.encoder(pulses, diameter).half_width(0.0)  # pulse/2 on every step (no slip)
    k = float(w**2 / (3.0 * abs(t.ds_r[0])))  # the uniform errors' variance w²/3 per step as Method A's k
    covs = cv.propagate(t, k, k).covs
    steps = np.linspace(0, t.n_steps, 5).round().astype(int)[1:]
    want = [math.pi * float(chi2_ppf(0.99, 2.0)) * math.sqrt(np.linalg.det(covs[s, :2, :2])) for s in steps]
    np.testing.assert_allclose(r["ellipse_area"], want, rtol=1e-6)
    # the support is an inner estimate of the reachable set, the guaranteed regions outer ones
    assert all(b >= s and z >= s for b, z, s in zip(r["box_area"], r["zonotope_area"], r["support_area"], strict=True))


def test_compass_heading_in_the_ekf_is_the_closed_form_and_the_particles_agree():
    s0, sc, m, n = 0.5, 0.05, 5, 20_000
    r = absolute_sensing_study(compass_bias=0.0, disturbance=0.0, n_trials=2, n_particles=n, grid_resolution=0.5,
                               grid_ntheta=12, n_measurements=m)  # fmt: skip
    want = (1.0 / s0**2 + m / sc**2) ** -0.5
    assert r["sensors"]["compass"]["ekf"]["sigma"]["theta"] == pytest.approx(want, rel=1e-9)
    # effective sample size ≈ n·σ/σ₀ (one dimension sharpened); 5 relative standard errors 1/√(2·ESS)
    ess = n * want / s0
    assert r["sensors"]["compass"]["particle"]["sigma"]["theta"] == pytest.approx(want, rel=5.0 / math.sqrt(2 * ess))
    assert r["sensors"]["compass"]["ekf"]["fixes"] == {"x": False, "y": False, "theta": True}
    assert r["sensors"]["range"]["ekf"]["fixes"] == {"x": True, "y": True, "theta": False}


def test_hypothesis_count_of_known_masses():
    m = np.zeros((10, 8))
    assert hypothesis_count(np.ones((20, 20))) == 0  # uniform on 400 cells: each 0.25 %, below 0.5 %
    assert hypothesis_count(np.ones((10, 8))) == 1  # uniform on 80 cells: each 1.25 %, one connected group
    m[1, 1] = m[1, 2] = 1.0
    assert hypothesis_count(m) == 1
    m[7, 6] = 1.0
    assert hypothesis_count(m) == 2
    m[4, 4] = 0.001  # below 0.5 % of the mass: no hypothesis
    assert hypothesis_count(m) == 2


def test_a_path_along_the_graphs_edges_moves_only_along_edges():
    g = tp.place_graph(load_world("config/worlds/room.yaml"), 1.0)
    xs = np.linspace(2.0, 8.0, 61)
    poses = np.stack([xs, np.ones_like(xs), np.zeros_like(xs)], -1)
    nodes, actions, off = _place_track(g, poses)
    assert off == 0
    assert np.sum(actions >= 0) == 6
    assert set(actions[actions >= 0].tolist()) == {0}
    np.testing.assert_allclose(g.positions[nodes[-1]], [8.0, 1.0])


def test_the_share_localized_never_falls():
    r = active_localization_study(n_runs=40, n_steps=8)
    for p in ("entropy", "random", "fixed"):
        by = r[p]["localized_by_step"]
        assert all(a <= b for a, b in itertools.pairwise(by))
        assert r[p]["success_low"] <= r[p]["success_rate"]


@pytest.mark.slow
def test_the_representations_table_on_one_short_run():
    tour = [["line", 3.0], ["turn", 1.5707963267948966], ["line", 2.0]]
    r = representations_study(tour=tour, repeat=1, n_particles=200, grid_ntheta=12, grid_resolution=0.5, n_sivia=2)
    t = r["table"]
    assert t["grid"]["memory_bytes"] == r["grid_cells"] * 8
    assert t["kalman"]["memory_bytes"] == 96
    assert t["topological"]["memory_bytes"] == r["n_places"] * 8
    assert t["topological"]["assumption_violated"] == 0.0  # the tour runs along the graph's edges
    if t["intervals"]["assumption_violated"] == 0.0:  # no error beyond its bound: the set holds the truth
        assert t["intervals"]["coverage_3s"] == 1.0
    assert t["kalman"]["hypotheses"] <= 1  # a Gaussian's superlevel sets are one ellipse
