"""UMBmark squares found in recorded bags: every lap, at its commanded corners, on noisy simulated bags.

A simulated robot drives ``laps`` squares clockwise, as many counter-clockwise and S-bends on
its own odometry (:func:`pose_uncertainty.robot.simulate.calibration_drive`); the bag is written
with rosbags and read back. The wheel noise is five times the default robot's, the encoder
ticks quantise each sample's travel (1024 or 4096 per revolution: at the ramps' slow samples a
one-tick difference between the wheels is a turn of the wrong class), and the ground truth
starts 3.7 ms after the wheels. The laps must all be found, each starting and ending at the
commanded corners (the segments' own sample counts: a second route to the boundaries), and
UMBmark must use every one of them.
"""

from __future__ import annotations

import numpy as np
import pytest

from pose_uncertainty.core.trajectories import from_segments
from pose_uncertainty.robot.align import align
from pose_uncertainty.robot.bag import read_bag
from pose_uncertainty.robot.config import RobotConfig
from pose_uncertainty.robot.laps import find_laps, umbmark_from_recording
from pose_uncertainty.robot.simulate import SimulatedRobot, calibration_drive, write_simulated_bag

LAPS = 3


def _corners(robot: SimulatedRobot, segments: list) -> np.ndarray:
    """Wheel-sample index at the end of each commanded segment (each segment discretised on its own)."""
    n = [from_segments([s], speed=robot.speed, angular_speed=robot.angular_speed, dt=1.0 / robot.wheel_rate,
                       track=robot.nominal_track, profile="ramp").ds_l.size for s in segments]  # fmt: skip
    return np.cumsum([0, *n])


@pytest.mark.slow
@pytest.mark.parametrize(("ticks", "seed"), [(None, 1), (1024, 2), (4096, 3)])
def test_every_lap_is_found_at_its_corners(tmp_path, ticks: int | None, seed: int) -> None:
    robot = SimulatedRobot(k_r=6e-4, k_l=4e-4, ticks_per_revolution=ticks, tick_offset=2**31 - 5000)
    segments = calibration_drive(side=2.0, laps=LAPS, arcs=2)
    bag = write_simulated_bag(tmp_path / "b.mcap", robot, np.random.default_rng(seed), segments, storage="mcap-file")
    rec = align(read_bag(bag, RobotConfig(ticks_per_revolution=ticks)), RobotConfig(ticks_per_revolution=ticks))
    nominal = (robot.nominal_radius, robot.nominal_radius, robot.nominal_track)
    laps = find_laps(rec, nominal)
    assert [lap["direction"] for lap in laps] == ["cw"] * LAPS + ["ccw"] * LAPS
    corners = _corners(robot, segments)[0 : 8 * 2 * LAPS + 1 : 8]  # every fourth corner: the laps' ends
    # a lap starts where its first leg starts moving and ends where its last turn stops: within the
    # ramp's few slow samples of the commanded corner (a tick's worth of motion at most is dropped)
    np.testing.assert_allclose([lap["start"] for lap in laps], corners[:-1], atol=3)
    np.testing.assert_allclose([lap["end"] for lap in laps], corners[1:], atol=3)
    np.testing.assert_allclose([lap["side"] for lap in laps], 2.0, rtol=1e-3)  # ticks: 2π r / N per sample at most
    um = umbmark_from_recording(rec, nominal)
    assert um is not None
    assert um["laps"] == um["laps_found"] == {"cw": LAPS, "ccw": LAPS}  # the first lap too, truth starting late
    assert um["E_d"]["ci95"][0] < um["E_d"]["value"] < um["E_d"]["ci95"][1]


def test_a_drive_without_squares_has_no_laps() -> None:
    from pose_uncertainty.core.trajectories import Arc, Line
    from pose_uncertainty.robot.simulate import simulate_recording

    robot = SimulatedRobot()
    rec = align(simulate_recording(robot, np.random.default_rng(4), [Line(2.0), Arc(1.0, 1.5), Line(1.0), Arc(1.0, -1.5)] * 3))
    assert find_laps(rec, (0.05, 0.05, 0.3)) == []
    um = umbmark_from_recording(rec, (0.05, 0.05, 0.3))
    assert um is not None
    assert um["result"] is None
    assert um["laps"] == {"cw": 0, "ccw": 0}
