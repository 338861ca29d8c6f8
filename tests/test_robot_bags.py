"""Reading robot bags: every format, every wheel encoding, and messy recordings counted and handled."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from pose_uncertainty.core.trajectories import Line, Turn
from pose_uncertainty.robot.align import align, interpolate_poses
from pose_uncertainty.robot.bag import BagError, PoseStream, Recording, WheelStream, read_bag
from pose_uncertainty.robot.bag_write import open_bag, write_recording
from pose_uncertainty.robot.calibrate import stream_warnings
from pose_uncertainty.robot.config import RobotConfig, robot_from_mapping
from pose_uncertainty.robot.messages import ODOMETRY, TF_MESSAGE
from pose_uncertainty.robot.simulate import SimulatedRobot, simulate_recording

SHORT = [Line(1.0), Turn(math.pi / 2), Line(1.0), Turn(-math.pi / 2)]


@pytest.fixture(scope="module")
def rec() -> Recording:
    return simulate_recording(SimulatedRobot(), np.random.default_rng(7), SHORT)


@pytest.mark.parametrize(("storage", "name"), [("mcap", "bag"), ("sqlite3", "db"), ("mcap-file", "b.mcap"), ("ros1", "b.bag")])
def test_every_format_reads_back_the_recorded_streams(rec: Recording, tmp_path: Path, storage: str, name: str) -> None:
    got = read_bag(write_recording(rec, tmp_path / name, storage=storage))
    assert got.topics == {"wheels": "/joint_states", "truth": "/ground_truth", "odometry": "/odom"}
    np.testing.assert_array_equal(got.wheels.t_ns, rec.wheels.t_ns)
    np.testing.assert_array_equal(got.wheels.left, rec.wheels.left)
    assert rec.truth is not None
    assert got.truth is not None
    np.testing.assert_array_equal(got.truth.t_ns, rec.truth.t_ns)
    # the heading goes through a quaternion: equal to rounding
    np.testing.assert_allclose(got.truth.poses, rec.truth.poses, atol=1e-12)


@pytest.mark.parametrize("truth_type", [ODOMETRY, TF_MESSAGE])
def test_truth_as_odometry_or_tf_is_found(rec: Recording, tmp_path: Path, truth_type: str) -> None:
    got = read_bag(write_recording(rec, tmp_path / "b", truth_type=truth_type))
    assert got.topics["truth"] == "/ground_truth"
    assert got.topics["odometry"] == "/odom"
    assert got.truth is not None
    assert rec.truth is not None
    np.testing.assert_allclose(got.truth.poses, rec.truth.poses, atol=1e-12)


def test_velocities_integrate_to_the_positions(tmp_path: Path) -> None:
    # constant wheel speeds: the trapezoid rule is exact
    t = np.arange(200) * 0.02
    w = WheelStream((t * 1e9).astype(np.int64), np.full(200, 3.0), np.full(200, 5.0), "velocity")
    al = align(read_bag(write_recording(Recording(w), tmp_path / "v", wheel_format="joint_velocity")))
    np.testing.assert_allclose(al.phi_l, 3.0 * t, atol=1e-12)
    np.testing.assert_allclose(al.phi_r, 5.0 * t, atol=1e-12)


def test_ticks_wrap_around_is_undone_and_counted(tmp_path: Path) -> None:
    robot = SimulatedRobot(ticks_per_revolution=4096, tick_offset=2**31 - 3000)
    rec = simulate_recording(robot, np.random.default_rng(1), SHORT)
    assert rec.wheels.left.max() - rec.wheels.left.min() > 2**31  # it wrapped
    al = align(read_bag(write_recording(rec, tmp_path / "t", wheel_format="ticks")), RobotConfig(ticks_per_revolution=4096))
    assert al.counts["wheels"].wraps == 2
    clean = align(simulate_recording(SimulatedRobot(), np.random.default_rng(1), SHORT))
    # ticks quantise the angle to one tick
    np.testing.assert_allclose(al.phi_l, clean.phi_l - clean.phi_l[0], atol=2 * math.pi / 4096 + 1e-12)


def _messy(rec: Recording) -> Recording:
    w = rec.wheels
    n = w.t_ns.size
    keep = np.ones(n, bool)
    keep[[100, 101, 102, 300]] = False  # drops: one gap of 3, one of 1
    order = np.flatnonzero(keep)
    order = np.concatenate([order[:50], order[50:52][::-1], order[52:]])  # one swap: 1 out of order
    order = np.concatenate([order, order[[10, 20]]])  # 2 duplicates, appended out of order
    messy = WheelStream(w.t_ns[order], w.left[order], w.right[order], w.kind)
    return dataclasses.replace(rec, wheels=messy)


def test_messy_wheels_are_sorted_deduplicated_and_counted(rec: Recording, tmp_path: Path) -> None:
    al = align(read_bag(write_recording(_messy(rec), tmp_path / "m")))
    c = al.counts["wheels"]
    assert (c.duplicates, c.gaps, c.dropped) == (2, 2, 4)
    assert c.out_of_order == 2  # stamps earlier than the one before: the swap, the first appended copy
    # the counts reach the user: calibration.json's warnings and the progress lines are these
    (line,) = stream_warnings(al)
    assert line.startswith("wheels: ")
    for what in ("2 duplicates", "2 out of order", "4 dropped"):
        assert what in line, line
    clean = align(rec)
    keep = np.ones(rec.wheels.t_ns.size, bool)
    keep[[100, 101, 102, 300]] = False
    np.testing.assert_array_equal(al.phi_l, clean.phi_l[keep])


def test_se2_interpolation_follows_an_arc_and_the_short_way_round() -> None:
    # a constant-twist arc sampled every 0.1 s, queried in between: exact
    t = np.arange(11) * 0.1
    v, w = 1.0, 2.0
    th = w * t
    poses = np.stack([v / w * np.sin(th), v / w * (1 - np.cos(th)), np.mod(th + np.pi, 2 * np.pi) - np.pi], -1)
    q = np.array([0.05, 0.33, 0.97])
    got, ok, _, _ = interpolate_poses(t, poses, q)
    exact = np.stack([v / w * np.sin(w * q), v / w * (1 - np.cos(w * q)), w * q], -1)
    assert ok.all()
    np.testing.assert_allclose(got[:, :2], exact[:, :2], atol=1e-12)
    np.testing.assert_allclose(np.mod(got[:, 2] - exact[:, 2] + np.pi, 2 * np.pi) - np.pi, 0.0, atol=1e-12)
    _, ok_out, _, _ = interpolate_poses(t, poses, np.array([-0.1, 1.2]))
    assert not ok_out.any()


def test_missing_truth_wrong_type_empty_and_truncated_bags(rec: Recording, tmp_path: Path) -> None:
    no_truth = read_bag(write_recording(dataclasses.replace(rec, truth=None), tmp_path / "nt"))
    assert no_truth.truth is None
    assert "truth" not in no_truth.topics
    bag = write_recording(rec, tmp_path / "ok")
    wrong = robot_from_mapping({"topics": {"wheels": "/odom"}})
    with pytest.raises(BagError, match=r"topic /odom for wheels has type nav_msgs/msg/Odometry \(allowed: "):
        read_bag(bag, wrong)
    with open_bag(tmp_path / "empty") as _:
        pass
    with pytest.raises(BagError, match="the bag is empty"):
        read_bag(tmp_path / "empty")
    whole = write_recording(rec, tmp_path / "f.mcap", storage="mcap-file").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(whole[: len(whole) // 2])
    with pytest.raises(BagError, match=r"cut\.mcap: cannot read the bag, truncated or damaged \("):
        read_bag(tmp_path / "cut.mcap")
    with pytest.raises(BagError, match="no such bag"):
        read_bag(tmp_path / "nope.mcap")


def test_robot_file_errors_name_the_key() -> None:
    with pytest.raises(ValueError, match=r"unknown key 'wheel_diameter' \(allowed: wheel_radius, "):
        robot_from_mapping({"wheel_diameter": 0.1})
    with pytest.raises(ValueError, match=r"track must be a positive number \(allowed: > 0\), got -1"):
        robot_from_mapping({"track": -1})
    with pytest.raises(ValueError, match=r"topics: unknown key 'imu'"):
        robot_from_mapping({"topics": {"imu": "/imu"}})
    r = robot_from_mapping({"wheel_radius": 0.05, "track": 0.3, "joints": {"left": "l", "right": "r"}})
    assert (r.radius_left, r.radius_right, r.track, r.has_geometry) == (0.05, 0.05, 0.3, True)


def test_odometry_truth_and_poses_streams_keep_their_order(rec: Recording) -> None:
    assert isinstance(rec.odometry, PoseStream)
    al = align(rec)
    assert al.truth_t is not None
    assert np.all(np.diff(al.truth_t) > 0)
