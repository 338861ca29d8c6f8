"""``pose-uncertainty calibrate DATA``: error constants with confidence intervals."""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

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
from ..core import trajectories
from ..core.trajectories import Trajectory
from ..core.validation import check_probability
from ..logs.run import RunConfig
from ..logs.runlog import open_run
from ._common import load_config_file

__all__ = ["add_parser", "cmd_calibrate"]



def add_parser(subparsers: Any) -> None:
    """Add the ``calibrate`` sub-command to an argparse sub-parser collection (sets ``func``)."""
    p = subparsers.add_parser(
        "calibrate",
        help="estimate error constants (k_r, k_l or motion-model alphas) with confidence intervals",
        description=(
            "Maximum-likelihood error constants with confidence intervals. DATA is a CSV "
            "(end poses x,y,theta of repeated runs of a known trajectory; or single-step "
            "samples for --model velocity/odometry) or a run log *.mcap (its Monte Carlo "
            "end poses and its trajectory)."
        ),
    )
    p.add_argument("data", help="CSV file or run log (*.mcap)")
    p.add_argument(
        "--model", choices=("k", "velocity", "odometry"), default="k",
        help="what to fit: wheel-noise k_r, k_l (default) or a motion model's alphas",
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
    p.add_argument("--ci", choices=CI_METHODS, default="profile", help="interval method")
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


def cmd_calibrate(args: argparse.Namespace) -> int:
    """``calibrate``: read the data, fit, print the estimates and intervals; returns 0."""
    level = float(check_probability("level", args.level))
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
        res = fit_k(poses, traj, coords=args.coords, equal=args.equal, level=level, ci_method=args.ci)
        results = {"k": res}
    else:
        d = read_motion_samples_csv(path, args.model)
        if args.model == "velocity":
            results = fit_alphas_velocity(
                d["samples"], d["controls"], d["dt"], d["starts"], scaling=args.scaling,
                level=level, ci_method=args.ci,
            )
        else:
            results = fit_alphas_odometry(
                d["samples"], d["odom_prev"], d["odom_next"], d["starts"], scaling=args.scaling,
                level=level, ci_method=args.ci,
            )
    if args.json:
        print(json.dumps({k: r.as_dict() for k, r in results.items()}, indent=2))
    else:
        print("\n\n".join(r.format() for r in results.values()))
    return 0
