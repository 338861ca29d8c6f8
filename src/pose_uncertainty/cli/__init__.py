"""Command line: ``pose-uncertainty <command> ...``.

Commands
--------
``run CONFIG.(yaml|json) -o OUT.mcap [--timings] [--figures DIR]``
    Execute one run and write its log atomically.
``replay RUN.mcap [--figures DIR] [--verify] [--at TIME] [--recover] [--to-rosbag DIR]``
    Summarise a log; re-render its figures from the log alone; recompute and
    compare; print the state at a simulated time; export it as a ROS 2 bag.
``explore [--host HOST] [--port PORT]``
    Start the interactive explorer (a local web page) and print its address.
``robot calibrate BAG [--robot ROBOT.yaml] -o OUTDIR``
    Calibrate a robot from a ROS bag: constants, nav2 and ros2_control parameters.

Exit status: 0 success; 1 ``--verify`` found a mismatch (or a defect of the program); 2 bad
input (usage, unreadable/invalid config or log, a run over the cost guard's limits) or an I/O
error (naming the file); 130 SIGINT, 143 SIGTERM, 129 SIGHUP (a write in progress leaves
nothing behind). Errors are one line on stderr, never a traceback (``--debug`` adds it).

Outputs (``-o``, ``--figures``, ``--to-rosbag``) replace only a regular file or a new path: a
directory, FIFO, socket or device node is refused, and so is a symbolic link unless
``--follow-symlink`` (``run``) writes to its regular target.

New commands register themselves in :data:`COMMANDS` by the name of their module
(a module of this package with ``add_parser``), imported when the parser is built, so that
importing this package (e.g. :mod:`.job`, the pipeline's jobs) does not import every command's
dependencies (matplotlib for ``--figures``).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
from collections.abc import Sequence
from typing import Any

from .. import __version__
from ._common import CommandError, load_config_file, one_line_errors

__all__ = ["COMMANDS", "CommandError", "build_parser", "load_config_file", "main"]


# --- wiring ---------------------------------------------------------------------------------

#: Sub-command name → the module of this package whose ``add_parser(sub)`` adds its parser
#: (which sets ``func``).
COMMANDS: dict[str, str] = {
    "run": "run",
    "replay": "replay",
    "calibrate": "calibrate",
    "robot": "robot",
    "explore": "explore",
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every command of :data:`COMMANDS`."""
    parser = argparse.ArgumentParser(
        prog="pose-uncertainty",
        description="Pose uncertainty of a differential-drive robot: runs, logs and replays.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--debug", action="store_true", help="print the full traceback after an error's line")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMANDS.values():
        importlib.import_module(f"{__name__}.{module}").add_parser(sub)
    return parser


def _one_line_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                      file: Any = None, line: str | None = None) -> None:
    """A configuration warning as one line on stderr (``warning: ...``); others as Python shows them."""
    from ..experiments.config_checks import ConfigWarning

    if issubclass(category, ConfigWarning):
        print(f"warning: {message}", file=sys.stderr if file is None else file)
    else:
        _SHOW_WARNING(message, category, filename, lineno, file, line)


_SHOW_WARNING = warnings.showwarning


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pose-uncertainty`` console script; returns the exit status.

    Every environment variable the package reads is checked first; every error is one line on
    stderr (``cli._common.one_line_errors``), ``--debug`` adds the traceback; configuration
    warnings are one line each.
    """
    warnings.showwarning = _one_line_warning
    parser = build_parser()
    args = parser.parse_args(argv)

    def run() -> int:
        from ..experiments.environment import check_environment

        check_environment()  # every variable the package reads, before any work
        return int(args.func(args))

    return one_line_errors(run, debug=args.debug)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
