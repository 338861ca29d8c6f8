"""The jobs of the pipeline's ``robots`` section as commands: ``python -m pose_uncertainty.cli.robot_job KIND ...``.

Apart from :mod:`pose_uncertainty.cli.job` so that each rule's ``source`` (the import closure of
the code it runs) holds only its own code: an edit of the robot code reruns the robot jobs,
not the runs. The robot's entry of the config comes as one JSON argument (the rule's
``params``); outputs are written atomically; progress goes to stderr (the rule's log).

Commands
--------
``simulate ROBOT_JSON BAG.mcap TRUTH.json``
    :func:`pose_uncertainty.pipeline.robots.simulate_robot`.
``calibrate ROBOT_JSON BAG OUTDIR [--truth TRUTH.json]``
    :func:`pose_uncertainty.pipeline.robots.calibrate_robot`.

Exit status and errors are those of the ``pose-uncertainty`` command
(``pose_uncertainty.cli._common.one_line_errors``): 0 success, 2 a bad bag, robot file or
configuration (one line naming it), 1 a defect of the program. ``--debug`` (before KIND)
adds the full traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from ._common import json_object, one_line_errors

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m pose_uncertainty.cli.robot_job", description=__doc__.split("\n")[0])
    parser.add_argument("--debug", action="store_true", help="print the full traceback after an error's line")
    sub = parser.add_subparsers(dest="kind", required=True, metavar="KIND")
    p = sub.add_parser("simulate", help="write a simulated robot's bag and its true parameters")
    p.add_argument("spec", type=json_object, help="one entry of the config's robots.runs as a JSON object")
    p.add_argument("bag", help="output bag, *.mcap")
    p.add_argument("truth", help="output true parameters, *.json")
    p = sub.add_parser("calibrate", help="calibrate one robot of the config's robots section")
    p.add_argument("spec", type=json_object, help="one entry of the config's robots.runs as a JSON object")
    p.add_argument("bag", help="the bag (rosbag2 folder, .mcap, .db3 or ROS 1 .bag)")
    p.add_argument("outdir", help="folder of the outputs")
    p.add_argument("--truth", help="a simulated robot's true parameters (the simulate command's output)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one robot job; returns the exit status (see the module docstring)."""
    args = _parser().parse_args(argv)
    return one_line_errors(lambda: _dispatch(args), debug=args.debug)


def _dispatch(args: argparse.Namespace) -> int:
    from ..experiments.environment import check_environment
    from ..pipeline import robots

    check_environment()  # every variable the package reads, before any work (as the CLI)
    if args.kind == "simulate":
        robots.simulate_robot(args.spec, args.bag, args.truth)
    else:
        robots.calibrate_robot(args.spec, args.bag, args.outdir, args.truth)
    return 0


if __name__ == "__main__":
    sys.exit(main())
