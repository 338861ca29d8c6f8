"""Trajectory builders: geometry of every path of Němec 2012 ch. 3–4, speed profiles, bad input."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.trajectories import Trajectory


@pytest.mark.parametrize(
    ("name", "params", "end"),
    [
        ("straight", {"length": 1.0}, (1.0, 0.0, 0.0)),
        ("straight", {"length": -0.5}, (-0.5, 0.0, 0.0)),
        ("arc", {"radius": 1.0, "angle": math.pi / 2}, (1.0, 1.0, math.pi / 2)),
        ("arc", {"radius": 2.0, "angle": -math.pi}, (0.0, -4.0, -math.pi)),
        ("circle", {"radius": 1.0}, (0.0, 0.0, 2 * math.pi)),
        ("circle", {"radius": 1.0, "laps": 3, "direction": -1}, (0.0, 0.0, -6 * math.pi)),
        ("rotation", {"angle": 2 * math.pi}, (0.0, 0.0, 2 * math.pi)),
        ("s_curve", {"radius": 1.0}, (2.0, 2.0, 0.0)),
        ("right_angles", {}, (2.0, 2.0, 0.0)),
        ("direct", {}, (2.0, 2.0, 0.0)),
    ],
)
@pytest.mark.parametrize("profile", ["constant", "ramp"])
def test_builders_end_where_geometry_says(name, params, end, profile):
    t = tr.build(name, profile=profile, **params)
    assert_allclose(t.poses[-1], end, atol=1e-9)
    assert_allclose(t.poses[0], [0.0, 0.0, 0.0])


def test_three_ways_lengths():
    assert_allclose(tr.s_curve().length, math.pi)
    assert_allclose(tr.right_angles().length, 4.0)
    assert_allclose(tr.direct().length, 2 * math.sqrt(2))


def test_controls_and_wheel_speeds_agree():
    t = tr.arc(radius=0.5, angle=1.0, speed=0.4, track=0.3, dt=0.02)
    assert_allclose(t.V, (t.v_r + t.v_l) / 2)
    assert_allclose(t.omega, (t.v_r - t.v_l) / 0.3)
    assert_allclose(t.V, 0.4, rtol=0.02)  # duration rounded to whole steps
    assert_allclose(t.V / t.omega, 0.5)  # R = V/ω
    assert t.controls.shape == (t.n_steps, 2)
    assert_allclose(t.times[-1], t.duration)


def test_ramp_profile():
    const = tr.straight(2.0, speed=1.0, dt=0.01)
    ramp = tr.straight(2.0, speed=1.0, dt=0.01, profile="ramp")
    assert ramp.n_steps == const.n_steps == 200
    assert_allclose(ramp.ds.sum(), 2.0)
    # per-step mean speed rises linearly to twice the nominal speed at half time
    v = ramp.V
    assert_allclose(v.max(), 2.0, rtol=0.01)
    assert_allclose(np.diff(v[:100]), np.diff(v[:100])[0], rtol=1e-9)
    assert_allclose(v[:100], v[::-1][:100])


def test_rotation_speed_and_track():
    t = tr.rotation(math.pi, angular_speed=0.5, track=0.4, dt=0.01)
    assert_allclose(t.duration, 2 * math.pi, atol=0.01)
    assert_allclose(t.ds_r, -t.ds_l)
    assert_allclose(t.ds_r.sum(), math.pi * 0.2)
    assert t.length == 0.0


def test_segment_composition_is_concatenation():
    a = tr.from_segments([tr.Line(1.0)], dt=0.01)
    b = tr.from_segments([tr.Turn(1.0)], dt=0.01)
    ab = tr.from_segments([tr.Line(1.0), tr.Turn(1.0)], dt=0.01)
    assert_allclose(ab.ds_r, np.concatenate([a.ds_r, b.ds_r]))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"dt": 0.0}, r"dt must be > 0.*got 0\.0"),
        ({"dt": -1.0}, r"dt must be > 0"),
        ({"track": 0.0}, r"track must be > 0"),
        ({"speed": -1.0}, r"speed must be > 0"),
        ({"profile": "sine"}, r"profile must be one of 'constant', 'ramp', got 'sine'"),
        ({"length": float("nan")}, r"length must be finite"),
    ],
)
def test_bad_builder_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        tr.straight(**kwargs)


def test_bad_trajectory():
    with pytest.raises(ValueError, match=r"at least one step.*N=0"):
        Trajectory(np.array([]), np.array([]), 0.01, 0.2)
    with pytest.raises(ValueError, match="equal length"):
        Trajectory(np.zeros(3), np.zeros(2), 0.01, 0.2)
    with pytest.raises(ValueError, match="trajectory must be one of"):
        tr.build("spiral")
    with pytest.raises(ValueError, match="bad parameters for trajectory 'straight'"):
        tr.build("straight", radius=1.0)
    with pytest.raises(ValueError, match="segments must not be empty"):
        tr.from_segments([])
    with pytest.raises(ValueError, match=r"radius must be > 0"):
        tr.arc(radius=0.0)


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.parametrize("laps", [1, 2])
def test_square_returns_to_its_start(direction, laps):
    t = tr.square(side=2.0, direction=direction, laps=laps, dt=0.05, track=0.3)
    assert_allclose(t.poses[-1], [0.0, 0.0, direction * 2 * math.pi * laps], atol=1e-12)
    assert_allclose(t.length, 8.0 * laps)
    # legs of 40 steps (2 m at 1 m/s), turns of 31 (π/2 at 1 rad/s, dt 0.05): the corners
    # (2, 0) then (2, 2) for ccw (left), (2, −2) for cw (right)
    assert t.n_steps == 4 * laps * (40 + 31)
    assert_allclose(t.poses[40], [2.0, 0.0, 0.0], atol=1e-12)
    assert_allclose(t.poses[40 + 31 + 40, :2], [2.0, 2.0 * direction], atol=1e-12)


def test_square_bad_input():
    with pytest.raises(ValueError, match=r"^direction must be 1 or -1"):
        tr.square(direction="cw")
    with pytest.raises(ValueError, match=r"^laps must be an integer >= 1"):
        tr.square(laps=0)
    with pytest.raises(ValueError, match=r"^side must be > 0"):
        tr.square(side=-1.0)
