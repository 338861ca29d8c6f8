"""Set-membership localization (box SIVIA) with bounded range and bearing errors."""

import itertools
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core.kinematics import wrap_angle
from pose_uncertainty.localization.sensors import landmark_h
from pose_uncertainty.localization.set_membership import bearing_image, range_image, sivia
from pose_uncertainty.localization.world import load_world, sample_free_poses

ROOM = load_world("config/worlds/room.yaml")
D_R, D_PHI = 0.1, 0.05  # error bounds [m], [rad]


def test_inclusion_functions_are_the_exact_images(rng):
    lo = rng.uniform(0, 8, (200, 2))
    hi = lo + rng.uniform(0.01, 1.5, (200, 2))
    m = rng.uniform(0, 9, (3, 2))
    t = np.linspace(0, 1, 61)
    gx = lo[:, None, None, 0] + (hi - lo)[:, None, None, 0] * t[None, :, None]
    gy = lo[:, None, None, 1] + (hi - lo)[:, None, None, 1] * t[None, None, :]
    gx, gy = np.broadcast_arrays(gx, gy)  # (K, 61, 61): a dense grid of each box
    d = np.hypot(m[:, 0] - gx[..., None], m[:, 1] - gy[..., None])  # (K, 61, 61, L)
    r_lo, r_hi = range_image(lo, hi, m)
    assert np.all(d.min(axis=(1, 2)) >= r_lo - 1e-12)
    # the nearest point is within half a grid diagonal of a grid point (grid spacing ≤ 1.51/60 m)
    assert_allclose(d.min(axis=(1, 2)), r_lo, atol=1.51 / 60 * math.sqrt(0.5))
    assert_allclose(d.max(axis=(1, 2)), r_hi, atol=1e-12)  # the farthest corner is on the grid
    centre, lower, upper, full = bearing_image(lo, hi, m)
    a = wrap_angle(np.arctan2(m[:, 1] - gy[..., None], m[:, 0] - gx[..., None]) - centre[:, None, None, :])
    ok = ~full
    assert np.all(a.min(axis=(1, 2))[ok] >= lower[ok] - 1e-12)
    assert np.all(a.max(axis=(1, 2))[ok] <= upper[ok] + 1e-12)
    assert_allclose(a.min(axis=(1, 2))[ok], lower[ok], atol=1e-12)  # attained at corners


def _measure(true, lm, rng, at_bounds=False):
    u = rng.choice([-1.0, 1.0], lm.shape) if at_bounds else rng.uniform(-1, 1, lm.shape)
    z = landmark_h(true, lm) + u * [D_R, D_PHI]
    z[:, 1] = wrap_angle(z[:, 1])
    return z


@pytest.mark.parametrize("at_bounds", [False, True])
def test_the_set_always_contains_the_true_pose(at_bounds):
    rng = np.random.default_rng(7 + at_bounds)
    truths = sample_free_poses(ROOM, 12, rng)
    for true in truths:
        lm = ROOM.landmarks[rng.permutation(ROOM.n_landmarks)[:3]]
        z = _measure(true, lm, rng, at_bounds)
        both = sivia(z, lm, ROOM.bounds, range_bound=D_R, bearing_bound=D_PHI)
        ranges = sivia(z, lm, ROOM.bounds, range_bound=D_R)
        bearings = sivia(z, lm, ROOM.bounds, bearing_bound=D_PHI)
        for s in (both, ranges, bearings):
            assert s.complete
            assert s.contains(true)
        assert both.volume <= min(ranges.volume, bearings.volume)


def test_the_set_shrinks_with_more_landmarks(rng):
    true = np.array([3.0, 2.5, 0.7])
    order = rng.permutation(ROOM.n_landmarks)
    z_all = _measure(true, ROOM.landmarks[order], rng)
    volumes, areas = [], []
    for n in (2, 3, 6, 12):  # nested subsets of the same measurements
        s = sivia(z_all[:n], ROOM.landmarks[order[:n]], ROOM.bounds, range_bound=D_R, bearing_bound=D_PHI)
        assert s.contains(true)
        x0, x1, y0, y1 = s.xy_extent()
        volumes.append(s.volume)
        areas.append((x1 - x0) * (y1 - y0))
    assert all(b < a for a, b in itertools.pairwise(volumes)), volumes
    assert all(b <= a for a, b in itertools.pairwise(areas)), areas
    # range-only trilateration leaves the heading free: every kept box spans the whole circle
    s = sivia(z_all[:3], ROOM.landmarks[order[:3]], ROOM.bounds, range_bound=D_R)
    assert_allclose(s.hi[:, 2] - s.lo[:, 2], 2 * math.pi)


def test_inconsistent_measurements_give_the_empty_set():
    lm = ROOM.landmarks[:2]
    z = np.array([[1.0, 0.0], [1.0, 0.0]])  # two landmarks 3 m apart both at 1 m: impossible
    s = sivia(z, lm, ROOM.bounds, range_bound=D_R)
    assert s.lo.shape[0] == 0
    assert s.volume == 0.0
    with pytest.raises(ValueError, match="range_bound or bearing_bound"):
        sivia(z, lm, ROOM.bounds)
