"""The robot commands and replay --to-rosbag: outputs written, errors one line with exit 2, bags read back."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from default_runs import CONFIGS
from rosbags.highlevel import AnyReader

from pose_uncertainty.cli import main
from pose_uncertainty.experiments.run import RunConfig, execute
from pose_uncertainty.records.run import open_run, write_run
from pose_uncertainty.robot.calibrate import OUTPUT_FILES
from pose_uncertainty.robot.messages import cov3_from_6, yaw_of
from pose_uncertainty.robot.simulate import SimulatedRobot, calibration_drive, write_simulated_bag

DRIVE = calibration_drive(side=2.0, laps=2, arcs=1)


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("robot")
    robot = SimulatedRobot()
    return {
        "good": write_simulated_bag(d / "good", robot, np.random.default_rng(11), DRIVE),
        "no_truth": write_simulated_bag(d / "nt.mcap", robot, np.random.default_rng(12), DRIVE[:4],
                                        storage="mcap-file", truth=False),
    }  # fmt: skip


def _one_line_error(argv: list[str], capsys: pytest.CaptureFixture[str], match: str) -> None:
    assert main(argv) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]
    assert len(err) == 1, err
    assert match in err[0], err


@pytest.mark.slow
def test_calibrate_writes_every_file(bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["robot", "calibrate", str(bags["good"]), "-o", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUT_FILES)
    cal = json.loads((out / "calibration.json").read_text())
    for key in ("E_d", "E_b", "wheel_radius_left", "wheel_radius_right", "track", "k_r", "k_l"):
        lo, hi = cal[key]["ci95"]
        assert lo <= cal[key]["value"] <= hi
        assert cal[key]["unit"] in ("1", "m")
    assert cal["nominal"]["source"] == "the robot's odometry topic"
    assert math.isclose(cal["nominal"]["track"], 0.30, rel_tol=1e-9)
    amcl = yaml.safe_load((out / "nav2_amcl.yaml").read_text())["amcl"]["ros__parameters"]
    assert amcl["robot_model_type"] == "nav2_amcl::DifferentialMotionModel"
    assert all(amcl[f"alpha{i}"] > 0 for i in range(1, 5))
    ctrl = yaml.safe_load((out / "ros2_control.yaml").read_text())["diff_drive_controller"]["ros__parameters"]
    assert math.isclose(ctrl["wheel_separation_multiplier"], cal["E_b"]["value"], rel_tol=1e-5)
    assert len(ctrl["twist_covariance_diagonal"]) == 6
    assert len(ctrl["pose_covariance_diagonal"]) == 6
    assert "ekf_filter_node" in yaml.safe_load((out / "robot_localization.yaml").read_text())
    assert "data:image/png;base64," in (out / "report.html").read_text()
    assert "%" in capsys.readouterr().err  # progress on stderr


def test_bad_input_is_one_line_with_exit_2(bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _one_line_error(["robot", "calibrate", str(bags["no_truth"]), "-o", str(tmp_path / "o")], capsys,
                    "no ground truth in the bag")  # fmt: skip
    _one_line_error(["robot", "calibrate", str(tmp_path / "none.mcap"), "-o", str(tmp_path / "o")], capsys, "no such bag")
    bad = tmp_path / "robot.yaml"
    bad.write_text("wheel_radius: 0.05\ntrak: 0.3\n")
    _one_line_error(["robot", "calibrate", str(bags["good"]), "--robot", str(bad), "-o", str(tmp_path / "o")], capsys,
                    "unknown key 'trak' (allowed: wheel_radius,")  # fmt: skip
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text("topics: {truth: /joint_states}\n")
    _one_line_error(["robot", "calibrate", str(bags["good"]), "--robot", str(wrong), "-o", str(tmp_path / "o")], capsys,
                    "topic /joint_states for truth has type sensor_msgs/msg/JointState")  # fmt: skip
    assert not (tmp_path / "o").exists()


def test_predict_without_ground_truth(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["robot", "predict", "--k-r", "1e-4", "--k-l", "1e-4", "--track", "0.3", "-o", str(tmp_path)]) == 0
    hz = json.loads((tmp_path / "horizon.json").read_text())
    assert [t["radius"] for t in hz["straight"]["thresholds"]] == [0.05, 0.10, 0.50]
    _one_line_error(["robot", "predict", "--k-r", "-1", "--k-l", "1e-4", "--track", "0.3", "-o", str(tmp_path)],
                    capsys, "--k-r must be a non-negative number")  # fmt: skip


def test_a_run_exported_as_a_bag_reads_back_the_same(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = dict(CONFIGS["map_arc"], monte_carlo={"n_particles": 200})
    log = open_run(write_run(tmp_path / "run.mcap", execute(RunConfig.from_dict(cfg))))
    dest = tmp_path / "bag"
    assert main(["replay", str(tmp_path / "run.mcap"), "--to-rosbag", str(dest)]) == 0
    with AnyReader([dest]) as reader:
        by_topic: dict[str, list] = {}
        for conn, t, raw in reader.messages():
            by_topic.setdefault(conn.topic, []).append((t, reader.deserialize(raw, conn.msgtype)))
    odo = by_topic["/odometry"]
    poses = np.array([[m.pose.pose.position.x, m.pose.pose.position.y, yaw_of(m.pose.pose.orientation)] for _, m in odo])
    np.testing.assert_array_equal(poses[:, :2], log.poses[:, :2])
    np.testing.assert_allclose(np.mod(poses[:, 2] - log.poses[:, 2] + np.pi, 2 * np.pi) - np.pi, 0.0, atol=1e-12)
    np.testing.assert_array_equal(np.stack([cov3_from_6(m.pose.covariance) for _, m in odo]), log.covs)
    np.testing.assert_array_equal([t for t, _ in odo], np.round(log.times * 1e9).astype(np.int64))
    (_, cloud), = by_topic["/monte_carlo/particles"]
    assert log.end_poses is not None
    np.testing.assert_array_equal([[p.position.x, p.position.y] for p in cloud.poses], log.end_poses[:, :2])
    grids = {k: v for k, v in by_topic.items() if k.startswith("/maps/")}
    assert sorted(grids) == ["/maps/odometry", "/maps/velocity"]
    for mp in log.maps:
        (_, g), = grids[f"/maps/{mp.name}"]
        nx, ny = mp.marginal_xy().shape
        assert (g.info.width, g.info.height) == (nx, ny)
        assert int(g.data.max()) == 100
        # row-major over y then x, 100 at the peak of the θ-marginal
        expect = np.round(100.0 * mp.marginal_xy() / mp.marginal_xy().max()).T.ravel()
        np.testing.assert_array_equal(g.data, expect.astype(np.int8))
        assert math.isclose(g.info.resolution, float(mp.x[1] - mp.x[0]), rel_tol=1e-7)  # float32 field
