"""Unmapped obstacles and the distance filter (Skalka 2011 §5.1), against second routes.

* the range to a disc along a ray equals the first point of a fine march along the ray inside a disc
  (to the march's step);
* ``P(short | z)`` equals the short component computed by the beam model itself (a sensor whose mixture is
  the short component alone), weighted and normalised by the full mixture;
* the distance filter drops a reading far shorter than the map predicts and keeps one the map explains.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pose_uncertainty.localization.dynamic import (
    disc_ranges,
    distance_filter,
    occluded_ranges,
    short_probability,
)
from pose_uncertainty.localization.sensors import BeamSensor, beam_probability


def test_disc_ranges_equal_a_fine_march_along_each_ray():
    rng = np.random.default_rng(5)
    origins = rng.uniform(0.0, 4.0, (12, 2))
    angles = rng.uniform(-math.pi, math.pi, (12, 8))
    discs = np.array([[2.0, 2.0, 0.5], [3.5, 1.0, 0.3], [0.5, 3.0, 0.4]])
    zm, h = 6.0, 1e-4
    got = disc_ranges(origins, angles, discs, zm)
    t = np.arange(0.0, zm, h)
    pts = origins[:, None, None, :] + t[None, None, :, None] * np.stack([np.cos(angles), np.sin(angles)], -1)[:, :, None, :]
    inside = np.any(np.hypot(*(pts[..., None, :] - discs[:, :2]).transpose(4, 0, 1, 2, 3)) <= discs[:, 2], axis=-1)
    first = np.where(inside.any(axis=-1), t[np.argmax(inside, axis=-1)], zm)
    np.testing.assert_allclose(got, first, atol=h)  # the march finds the boundary to one step
    assert np.any(got < zm)
    assert np.any(got == zm)


def test_a_ray_from_inside_a_disc_sees_it_at_zero_and_one_behind_not_at_all():
    discs = np.array([[0.0, 0.0, 1.0], [-3.0, 0.0, 0.5]])
    assert disc_ranges(np.array([0.2, 0.0]), np.array([0.0]), discs, 5.0)[0] == 0.0
    assert disc_ranges(np.array([2.0, 0.0]), np.array([0.0]), discs, 5.0)[0] == 5.0  # both discs behind
    assert disc_ranges(np.array([2.0, 0.0]), np.array([math.pi]), discs, 5.0)[0] == pytest.approx(1.0)
    assert disc_ranges(np.array([2.0, 0.0]), np.array([math.pi]), np.zeros((0, 3)), 5.0)[0] == 5.0


def test_occluded_ranges_are_the_nearer_of_map_and_obstacle():
    s = BeamSensor(n_beams=4, max_range=8.0)
    pose = np.array([0.0, 0.0, 0.0])
    z_map = np.full(4, 5.0)
    z = occluded_ranges(z_map, pose, s, np.array([[2.0, 0.0, 0.5]]))
    beams = s.angles  # −π, −π/2, 0, π/2: only the beam along +x meets the disc, at 1.5 m
    np.testing.assert_allclose(z, np.where(np.isclose(beams, 0.0), 1.5, 5.0))


def test_short_probability_is_the_beam_models_own_short_component():
    s = BeamSensor(n_beams=3, max_range=8.0, z_hit=0.7, z_short=0.2, z_max=0.05, z_rand=0.05)
    pure_short = BeamSensor(n_beams=3, max_range=8.0, z_hit=0.0, z_short=1.0, z_max=0.0, z_rand=0.0)
    z = np.array([1.0, 4.0, 5.5])
    zs = np.array([[4.0, 4.0, 5.0], [3.0, 4.1, 6.0]])
    w = np.array([0.25, 0.75])
    want = w @ (s.z_short * beam_probability(z, zs, pure_short) / beam_probability(z, zs, s))
    np.testing.assert_allclose(short_probability(z, zs, w, s), want, rtol=1e-12)
    assert np.all((want >= 0) & (want <= 1))


def test_the_distance_filter_drops_what_the_map_cannot_explain():
    # no random component: a reading far short of the wall is the short component's alone
    s = BeamSensor(n_beams=2, max_range=8.0, z_hit=0.75, z_short=0.2, z_max=0.05, z_rand=0.0)
    zs = np.array([[5.0, 5.0]])
    keep = distance_filter(np.array([1.0, 5.02]), zs, np.array([1.0]), s)
    assert keep.tolist() == [False, True]  # 4 m short: a person; at the wall: the map's
    # with the default random component the same short reading is explained by it in part: P(short) < 0.99
    d = BeamSensor(n_beams=2, max_range=8.0)
    p = short_probability(np.array([1.0, 5.02]), zs, np.array([1.0]), d)
    assert 0.5 < p[0] < 0.99
    assert p[1] < 0.01
    with pytest.raises(ValueError, match="threshold"):
        distance_filter(np.array([1.0, 5.0]), zs, np.array([1.0]), s, threshold=0.0)
