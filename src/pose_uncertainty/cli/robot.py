"""``pose-uncertainty robot ...``: your robot from a ROS bag (calibrate, predict, simulate)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np

from ..robot.calibrate import calibrate_bag, predict
from ..robot.config import RobotConfig, read_robot_file
from ..robot.simulate import SimulatedRobot, write_simulated_bag
from ._common import EXIT_OK, CommandError

__all__ = ["add_parser", "cmd_calibrate", "cmd_predict", "cmd_simulate"]


def add_parser(sub: Any) -> None:
    p = sub.add_parser("robot", help="calibrate your robot from a ROS bag", description=__doc__)
    rsub = p.add_subparsers(dest="robot_command", required=True, metavar="ROBOT_COMMAND")
    c = rsub.add_parser("calibrate", help="bag → calibration.json, ros2_control/nav2/robot_localization YAML")
    c.add_argument("bag", help="rosbag2 folder, .mcap, .db3 or ROS 1 .bag")
    c.add_argument("--robot", metavar="ROBOT.yaml", help="robot file (radii, track, ticks, joints, topics)")
    c.add_argument("-o", "--outdir", required=True, metavar="OUTDIR",
                   help="folder for calibration.json and the parameter files (created)")
    c.add_argument("--seed", type=int, default=0, help="seed of the Monte Carlo parts (default 0)")
    c.set_defaults(func=cmd_calibrate)
    q = rsub.add_parser("predict", help="uncertainty horizon from known constants (no ground truth needed)")
    q.add_argument("--k-r", type=float, required=True, help="right wheel error constant [m]")
    q.add_argument("--k-l", type=float, required=True, help="left wheel error constant [m]")
    q.add_argument("--robot", metavar="ROBOT.yaml", help="robot file (track, nominal_speed, thresholds)")
    q.add_argument("--track", type=float, help="track [m] (default: the robot file's)")
    q.add_argument("-o", "--outdir", required=True, metavar="OUTDIR",
                   help="folder for horizon.json and report.html (created)")
    q.add_argument("--seed", type=int, default=0, help="seed of the horizon's Monte Carlo (default 0)")
    q.set_defaults(func=cmd_predict)
    s = rsub.add_parser("simulate", help="write a bag of a simulated robot with known radii, track and k")
    s.add_argument("-o", "--out", required=True, metavar="BAG", help="the bag to write")
    s.add_argument("--storage", choices=("mcap", "sqlite3", "mcap-file", "ros1"), default="mcap",
                   help="bag storage: rosbag2 mcap folder, rosbag2 sqlite3 folder, one .mcap file, ROS 1 .bag")
    s.add_argument("--seed", type=int, default=0, help="seed of the simulated noise (default 0)")
    s.set_defaults(func=cmd_simulate)


def _robot(path: str | None) -> RobotConfig:
    if path is None:
        return RobotConfig()
    try:
        return read_robot_file(path)
    except ValueError as exc:
        raise CommandError(str(exc)) from None


def _progress(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """``robot calibrate BAG [--robot ROBOT.yaml] -o OUTDIR``."""
    cal = calibrate_bag(args.bag, _robot(args.robot), args.outdir, seed=args.seed, progress=_progress)
    for k in ("E_d", "E_b", "wheel_radius_left", "wheel_radius_right", "track", "k_r", "k_l"):
        v = cal[k]
        print(f"{k:<20} {v['value']:.6g}  95 % [{v['ci95'][0]:.6g}, {v['ci95'][1]:.6g}] {v['unit']}")
    return EXIT_OK


def cmd_predict(args: argparse.Namespace) -> int:
    """``robot predict --k-r K --k-l K [--robot ROBOT.yaml] [--track B] -o OUTDIR``."""
    robot = _robot(args.robot)
    track = args.track if args.track is not None else robot.track
    if track is None:
        raise CommandError("the track is unknown: give --track or a robot file with track")
    for name, v in (("--k-r", args.k_r), ("--k-l", args.k_l), ("--track", track)):
        if not np.isfinite(v) or v < 0 or (name == "--track" and v == 0):
            raise CommandError(f"{name} must be a {'positive' if name == '--track' else 'non-negative'} number, got {v!r}")
    hz = predict(args.k_r, args.k_l, track, robot, args.outdir, seed=args.seed)
    for kind in ("straight", "turning"):
        for t in hz[kind]["thresholds"]:
            d = "not reached" if t["distance"] is None else f"{t['distance']:.4g} m, {t['time']:.4g} s"
            print(f"{kind:<9} r95 = {t['radius']:g} m: {d}")
    return EXIT_OK


def cmd_simulate(args: argparse.Namespace) -> int:
    """``robot simulate -o BAG``: the default simulated robot (module :mod:`..robot.simulate`)."""
    path = write_simulated_bag(args.out, SimulatedRobot(), np.random.default_rng(args.seed), storage=args.storage)
    print(f"wrote {path}")
    return EXIT_OK
