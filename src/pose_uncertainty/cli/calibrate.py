"""``pose-uncertainty calibrate DATA``: error constants with confidence intervals.

``--method ml`` (default): maximum-likelihood random-error constants (``k_r, k_l`` or a
motion model's alphas). ``--method umbmark``: systematic errors (wheel-diameter
ratio E_d, track error E_b) from the return-position errors of UMBmark squares.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis.calibration import (
    CI_METHODS,
    COORDS,
    CalibrationResult,
    fit_alphas_odometry,
    fit_alphas_velocity,
    fit_k,
    read_end_poses_csv,
    read_motion_samples_csv,
)
from ..analysis.umbmark import read_returns_csv, umbmark
from ..core import trajectories
from ..core.trajectories import Trajectory
from ..core.validation import check_probability
from ..experiments.config import RunConfig
from ..records.run import open_run
from ._common import load_config_file

__all__ = ["METHODS", "add_parser", "cmd_calibrate"]



METHODS: tuple[str, ...] = ("ml", "umbmark")


def add_parser(subparsers: Any) -> None:
    """Add the ``calibrate`` sub-command to an argparse sub-parser collection (sets ``func``)."""
    p = subparsers.add_parser(
        "calibrate",
        help="estimate error constants (k_r, k_l, motion-model alphas, or UMBmark's E_d, E_b) "
        "with confidence intervals",
        description=(
            "--method ml (default): maximum-likelihood error constants with confidence intervals. "
            "DATA is a CSV (end poses x,y,theta of repeated runs of a known trajectory; or "
            "single-step samples for --model velocity/odometry) or a run log *.mcap (its Monte "
            "Carlo end poses and its trajectory). --method umbmark: systematic errors from UMBmark "
            "squares; DATA is a CSV with columns direction (cw/ccw), x, y (return-position error "
            "true minus odometry, start frame, m), with --side and --track."
        ),
    )
    p.add_argument("data", help="CSV file or run log (*.mcap)")
    p.add_argument("--method", choices=METHODS, default="ml", help="ml (default) or umbmark")
    p.add_argument(
        "--model", choices=("k", "velocity", "odometry"), default="k",
        help="ml: what to fit: wheel-noise k_r, k_l (default) or a motion model's alphas",
    )
    p.add_argument("--config", metavar="FILE", help="run config (YAML/JSON) whose trajectory was driven")
    p.add_argument(
        "--trajectory", metavar="NAME",
        help="trajectory builder name (straight, arc, circle, ...), instead of --config",
    )
    p.add_argument(
        "--param", action="append", default=[], metavar="KEY=VALUE",
        help="trajectory parameter, repeatable (e.g. --param length=1 --param dt=0.01)",
    )
    p.add_argument("--coords", choices=COORDS, default="expcoords", help="model coordinates for k")
    p.add_argument("--equal", action="store_true", help="fit one k = k_r = k_l")
    p.add_argument("--scaling", choices=("squared", "abs"), default="squared", help="alpha variance form")
    p.add_argument("--level", type=float, default=0.95, help="confidence level (default 0.95)")
    p.add_argument("--ci", choices=CI_METHODS, default=None, help="ml: interval method (default profile)")
    p.add_argument("--side", type=float, metavar="L", help="umbmark: side of the square [m]")
    p.add_argument("--track", type=float, metavar="B", help="umbmark: nominal track [m]")
    p.add_argument("--diameter", type=float, metavar="D", help="umbmark: nominal wheel diameter [m], optional")
    p.add_argument("--after", metavar="CSV", help="umbmark: return errors after the correction, optional")
    p.add_argument("--n-boot", type=int, default=2000, help="umbmark: bootstrap resamples (default 2000, 0: none)")
    p.add_argument("--seed", type=int, default=0, help="umbmark: seed of the bootstrap (default 0)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=cmd_calibrate)


def _parse_params(items: Sequence[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"--param must be KEY=VALUE, got {item!r}")
        key, val = item.split("=", 1)
        try:
            out[key.strip()] = int(val) if val.strip().lstrip("-").isdigit() else float(val)
        except ValueError:
            out[key.strip()] = val.strip()
    return out


def _trajectory_from_args(args: argparse.Namespace) -> Trajectory:
    if args.config and args.trajectory:
        raise ValueError("give either --config or --trajectory, not both")
    if args.config:
        cfg = RunConfig.from_dict(load_config_file(args.config))
        return trajectories.from_config(cfg.trajectory)
    if args.trajectory:
        return trajectories.build(args.trajectory, **_parse_params(args.param))
    raise ValueError(
        "calibrating k from a CSV needs the trajectory: --config RUN.yaml or --trajectory NAME "
        "[--param KEY=VALUE ...]"
    )


def _cmd_umbmark(args: argparse.Namespace, level: float) -> int:
    """``calibrate --method umbmark``: read the return errors, compute, print."""
    if args.side is None or args.track is None:
        raise ValueError(
            "--method umbmark needs --side L (the square's side [m]) and --track B (the nominal track [m])"
        )
    if args.ci is not None:
        raise ValueError(f"--ci {args.ci} is for --method ml (umbmark reports delta and bootstrap intervals)")
    res = umbmark(
        read_returns_csv(args.data), args.side, args.track, np.random.default_rng(args.seed),
        level=level, n_boot=args.n_boot,
        after=None if args.after is None else read_returns_csv(args.after),
    )
    if args.json:
        print(json.dumps(res.as_dict(), indent=2))
    else:
        print(res.format(diameter=args.diameter))
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    """``calibrate``: read the data, fit, print the estimates and intervals; returns 0."""
    level = float(check_probability("level", args.level))
    if args.method == "umbmark":
        return _cmd_umbmark(args, level)
    ci = "profile" if args.ci is None else args.ci
    path = Path(args.data)
    results: dict[str, CalibrationResult]
    if args.model == "k":
        if path.suffix.lower() == ".mcap":
            log = open_run(path)
            if log.end_poses is None or len(log.end_poses) == 0:
                raise ValueError(f"{path}: the run log holds no Monte Carlo end poses")
            traj = trajectories.from_config(log.config.trajectory)
            poses = log.end_poses
        else:
            traj = _trajectory_from_args(args)
            poses = read_end_poses_csv(path)
        res = fit_k(poses, traj, coords=args.coords, equal=args.equal, level=level, ci_method=ci)
        results = {"k": res}
    else:
        d = read_motion_samples_csv(path, args.model)
        if args.model == "velocity":
            results = fit_alphas_velocity(
                d["samples"], d["controls"], d["dt"], d["starts"], scaling=args.scaling,
                level=level, ci_method=ci,
            )
        else:
            results = fit_alphas_odometry(
                d["samples"], d["odom_prev"], d["odom_next"], d["starts"], scaling=args.scaling,
                level=level, ci_method=ci,
            )
    if args.json:
        print(json.dumps({k: r.as_dict() for k, r in results.items()}, indent=2))
    else:
        print("\n\n".join(r.format() for r in results.values()))
    return 0
