"""Correlative scan-to-map matching (Skalka 2011 §4.2.2) and its EKF update, against second routes.

* a noiseless scan from a known pose, matched from a prior offset by a whole number of search steps,
  lies within one map cell of it (the map's walls are cells); with beam noise too;
* the vectorised best score equals a loop that projects each candidate's endpoints itself and
  interpolates the field by hand;
* the likelihood field equals −min(d, 3σ)²/(2σ²) with d, the distance to the nearest wall face, measured by
  brute force to every cell centre of the other kind (less half a cell);
* in a long corridor whose ends are out of range the match is ambiguous along it: its covariance along
  the corridor is the window's (uniform scores), across it the cell size's;
* the EKF update with the pose measurement equals the linear Kalman update with H = I.
"""

from __future__ import annotations

import numpy as np
import pytest

from pose_uncertainty.localization.ekf import kf_update
from pose_uncertainty.localization.scan_matching import (
    correlative_match,
    ekf_update_pose,
    likelihood_field,
)
from pose_uncertainty.localization.sensors import (
    BeamSensor,
    expected_ranges,
    sample_beam_measurements,
)
from pose_uncertainty.localization.world import grid_from_segments, load_world

ROOM = load_world("config/worlds/room.yaml")
LASER = BeamSensor(n_beams=36, max_range=8.0, sigma_hit=0.02)


def test_likelihood_field_is_the_brute_force_distance():
    g = ROOM.grid
    f = likelihood_field(g, 0.1)
    h = g.resolution
    occ, free = np.argwhere(g.occupied) * h, np.argwhere(~g.occupied) * h
    rng = np.random.default_rng(2)
    cells = [*zip(rng.integers(0, g.shape[0], 20), rng.integers(0, g.shape[1], 20), strict=True),
             *map(tuple, np.argwhere(g.occupied)[:5])]  # fmt: skip
    for i, j in cells:  # the nearest centre of the other kind, by brute force, less half a cell
        other = free if g.occupied[i, j] else occ
        d = max(np.min(np.hypot(*(other - np.array([i, j]) * h).T)) - h / 2, 0.0)
        assert f[i, j] == pytest.approx(-0.5 * min(d / 0.1, 3.0) ** 2, rel=1e-12, abs=1e-12)


def test_a_noiseless_scan_recovers_a_known_offset():
    truth = np.array([3.0, 2.0, 0.4])
    z = expected_ranges(ROOM.grid, truth, LASER)
    field = likelihood_field(ROOM.grid, 0.05)
    m = correlative_match(field, ROOM.grid, z, LASER, truth + np.array([0.2, -0.15, 0.05]))
    assert np.all(np.abs(m.pose[:2] - truth[:2]) <= ROOM.grid.resolution + 1e-9)
    assert abs(m.pose[2] - truth[2]) <= 0.02 + 1e-9
    assert m.n_endpoints == LASER.n_beams


def test_a_noisy_scan_recovers_the_pose_within_a_step():
    truth = np.array([7.0, 5.5, -2.0])
    rng = np.random.default_rng(4)
    pure = BeamSensor(n_beams=36, max_range=8.0, sigma_hit=0.02, z_hit=1.0, z_short=0.0, z_max=0.0, z_rand=0.0)
    z = sample_beam_measurements(expected_ranges(ROOM.grid, truth, pure), pure, rng)
    m = correlative_match(likelihood_field(ROOM.grid, 0.05), ROOM.grid, z, pure, truth + np.array([-0.3, 0.25, -0.1]))
    assert np.all(np.abs(m.pose[:2] - truth[:2]) <= ROOM.grid.resolution + 1e-9)
    assert abs(m.pose[2] - truth[2]) <= 0.02 + 1e-9
    assert np.all(np.sqrt(np.diag(m.cov)[:2]) < 0.1)


def test_the_score_equals_a_loop_over_candidates():
    truth = np.array([2.0, 6.0, 1.0])
    z = expected_ranges(ROOM.grid, truth, LASER)
    g = ROOM.grid
    field = likelihood_field(g, 0.05)
    m = correlative_match(field, g, z, LASER, truth, window=(0.1, 0.02), step=(0.05, 0.01))
    best = -np.inf
    for dx in (-0.1, -0.05, 0.0, 0.05, 0.1):
        for dy in (-0.1, -0.05, 0.0, 0.05, 0.1):
            for dt in (-0.02, -0.01, 0.0, 0.01, 0.02):
                x, y, t = truth + np.array([dx, dy, dt])
                s = 0.0
                for r, a in zip(z, LASER.angles, strict=True):
                    if r >= LASER.max_range - 3 * LASER.sigma_hit:  # no endpoint: nothing was hit
                        continue
                    ex, ey = x + r * np.cos(t + a), y + r * np.sin(t + a)
                    x0, x1, y0, y1 = g.extent()
                    if not (x0 <= ex <= x1 and y0 <= ey <= y1):  # off the map: the farthest cell's value
                        s += field.min()
                        continue
                    u = (ex - g.origin[0]) / g.resolution - 0.5  # fractional cell-centre index
                    v = (ey - g.origin[1]) / g.resolution - 0.5
                    nx, ny = g.shape  # clamped at the map's edge, as the matcher does
                    u, v = min(max(u, 0.0), nx - 1.0), min(max(v, 0.0), ny - 1.0)
                    i, j = min(int(u), nx - 2), min(int(v), ny - 2)
                    fu, fv = u - i, v - j
                    s += ((1 - fu) * (1 - fv) * field[i, j] + fu * (1 - fv) * field[i + 1, j]
                          + (1 - fu) * fv * field[i, j + 1] + fu * fv * field[i + 1, j + 1])
                best = max(best, s)
    assert m.score == pytest.approx(best, rel=1e-9, abs=1e-9)


def test_a_corridor_is_ambiguous_along_it():
    walls = np.array([[0.0, 0.0, 40.0, 0.0], [0.0, 2.0, 40.0, 2.0]])
    grid = grid_from_segments(walls, 0.05)
    laser = BeamSensor(n_beams=36, max_range=5.0, sigma_hit=0.02)
    truth = np.array([20.0, 1.0, 0.0])
    z = expected_ranges(grid, truth, laser)
    m = correlative_match(likelihood_field(grid, 0.05), grid, z, laser, truth + np.array([0.2, 0.1, 0.0]),
                          window=(0.5, 0.05), step=(0.05, 0.01))  # fmt: skip
    sx, sy = np.sqrt(np.diag(m.cov)[:2])
    # along: scores equal over the 21 x offsets, a uniform spread of σ = 0.05·√((21² − 1)/12) ≈ 0.30 m
    assert sx == pytest.approx(0.05 * np.sqrt((21**2 - 1) / 12 + 1 / 12), rel=0.05)
    assert sy < 0.05  # across: fixed by the walls
    assert abs(m.pose[1] - truth[1]) < 1e-9


def test_the_pose_update_is_the_linear_kalman_update():
    rng = np.random.default_rng(6)
    A = rng.normal(size=(3, 3))
    P, R = A @ A.T + np.eye(3) * 0.1, np.diag([0.01, 0.02, 0.003])
    x, z = np.array([1.0, 2.0, 0.3]), np.array([1.1, 1.9, 0.35])
    got = ekf_update_pose(x, P, z, R)
    want = kf_update(x, P, z, np.eye(3), R)
    np.testing.assert_allclose(got[0], want[0], rtol=1e-12)
    np.testing.assert_allclose(got[1], want[1], rtol=1e-12)
    # across ±π the heading's innovation is wrapped: z at −π + 0.05 pulls a mean at π − 0.05 through π
    x2, _ = ekf_update_pose(np.array([0.0, 0.0, np.pi - 0.05]), np.eye(3), np.array([0.0, 0.0, -np.pi + 0.05]),
                            np.eye(3))  # fmt: skip
    assert x2[2] == pytest.approx(np.pi, abs=1e-12)


def test_matches_of_noisy_scans_along_a_wall_are_unbiased():
    # scans of the full beam mixture (short and random readings, max readings at 5 m) from the true poses of a
    # straight 1 m from the wall: the matches' mean error across the wall is within 3σ/√n of zero (σ the matches'
    # own, n = 10 scans); a field measured to the cell centres or clamping off-map endpoints biases it by ≥ 0.05 m
    laser = BeamSensor(n_beams=24, max_range=5.0, sigma_hit=0.05)
    rng = np.random.default_rng(1)
    truths = np.stack([np.linspace(2.0, 7.5, 10), np.ones(10), np.zeros(10)], axis=-1)
    z = sample_beam_measurements(expected_ranges(ROOM.grid, truths, laser), laser, rng)
    field = likelihood_field(ROOM.grid, 0.1)
    m = [correlative_match(field, ROOM.grid, zk, laser, t) for zk, t in zip(z, truths, strict=True)]
    dy = np.array([mk.mean[1] - t[1] for mk, t in zip(m, truths, strict=True)])
    sy = np.sqrt(np.mean([mk.cov[1, 1] for mk in m]))
    assert abs(dy.mean()) <= 3 * sy / np.sqrt(dy.size)
