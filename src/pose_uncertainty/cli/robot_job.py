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

from ._common import job_parser, json_object, one_line_errors

__all__ = ["main", "parser"]


_SPEC = "one entry of the config's robots.runs as a JSON object"

#: Each command: its help and its arguments (name, help; the first is the robot's entry as JSON).
_COMMANDS: tuple[tuple[str, str, tuple[tuple[str, str], ...]], ...] = (
    ("simulate", "write a simulated robot's bag and its true parameters",
     (("spec", _SPEC), ("bag", "output bag, *.mcap"), ("truth", "output true parameters, *.json"))),
    ("calibrate", "calibrate one robot of the config's robots section",
     (("spec", _SPEC), ("bag", "the bag (rosbag2 folder, .mcap, .db3 or ROS 1 .bag)"), ("outdir", "folder of the outputs"),
      ("--truth", "a simulated robot's true parameters (the simulate command's output)"))),
)  # fmt: skip


def parser() -> argparse.ArgumentParser:
    """The argument parser of the robot jobs (module docstring)."""
    out, sub = job_parser("python -m pose_uncertainty.cli.robot_job", __doc__.split("\n")[0])
    for kind, what, arguments in _COMMANDS:
        command = sub.add_parser(kind, help=what)
        for name, text in arguments:
            command.add_argument(name, type=json_object if name == "spec" else str, help=text)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Run one robot job; returns the exit status (see the module docstring)."""
    args = parser().parse_args(argv)
    return one_line_errors(lambda: _run_robot_job(args), debug=args.debug)


def _run_robot_job(args: argparse.Namespace) -> int:
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
