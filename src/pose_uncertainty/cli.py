"""Command line: ``pose-uncertainty <command> ...``.

Commands
--------
``run CONFIG.(yaml|json) -o OUT.mcap [--timings] [--figures DIR]``
    Execute one run and write its log atomically.
``replay RUN.mcap [--figures DIR] [--verify] [--at TIME] [--recover]``
    Summarise a log; re-render its figures from the log alone; recompute and
    compare; print the state at a simulated time.

Exit status: 0 success; 1 ``--verify`` found a mismatch; 2 bad input (usage,
unreadable/invalid config or log). Errors are one line on stderr, never a
traceback.

New commands register themselves in :data:`COMMANDS` with a function that adds
their sub-parser (see :func:`_add_run`); ``calibrate`` and others plug in the same way.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .calibration import add_calibrate_parser as _add_calibrate

__all__ = ["COMMANDS", "build_parser", "load_config_file", "main"]

EXIT_OK, EXIT_MISMATCH, EXIT_INPUT = 0, 1, 2


class CommandError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def load_config_file(path: str | Path) -> dict[str, Any]:
    """Read a run configuration mapping from a YAML or JSON file (by suffix; YAML otherwise)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CommandError(f"{p}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CommandError(f"{p}: cannot read ({exc})") from None
    try:
        if p.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            import yaml

            data = yaml.safe_load(text)
    except Exception as exc:  # noqa: BLE001 - any parser error is a bad file
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CommandError(
            f"{p}: not valid {'JSON' if p.suffix.lower() == '.json' else 'YAML'} ({first})"
        ) from None
    if not isinstance(data, dict):
        raise CommandError(f"{p}: the config must be a mapping, got {type(data).__name__}")
    return data


# --- run ------------------------------------------------------------------------------------


def _add_run(sub: Any) -> None:
    p = sub.add_parser(
        "run", help="execute one run and write its MCAP log", description="Execute one run."
    )
    p.add_argument("config", help="run configuration, YAML or JSON")
    p.add_argument("-o", "--output", required=True, help="output log, *.mcap (written atomically)")
    p.add_argument(
        "--timings",
        action="store_true",
        help="also log wall-clock timings (topic /timings); the file is then not byte-reproducible",
    )
    p.add_argument("--figures", metavar="DIR", help="also render the run's figures into DIR")
    p.set_defaults(func=cmd_run)


def cmd_run(args: argparse.Namespace) -> int:
    """``run``: config file → execute → write log (→ figures)."""
    from .run import RunConfig, execute
    from .runlog import write_run

    data = load_config_file(args.config)
    try:
        config = RunConfig.from_dict(data)
    except ValueError as exc:
        raise CommandError(f"{args.config}: {exc}") from None
    result = execute(config)
    path = write_run(args.output, result, include_timings=args.timings)
    print(f"wrote {path} ({path.stat().st_size} bytes, {result.n_steps} steps)")
    if args.figures:
        from .figures import render_figures

        for fig in render_figures(result, args.figures):
            print(f"wrote {fig}")
    return EXIT_OK


# --- replay ---------------------------------------------------------------------------------


def _add_replay(sub: Any) -> None:
    p = sub.add_parser(
        "replay",
        help="summarise, re-render or re-verify a run log",
        description="Read a run log (validating its CRCs) and print a summary.",
    )
    p.add_argument("log", help="run log, *.mcap")
    p.add_argument(
        "--figures", metavar="DIR", help="re-render the run's figures from the log alone into DIR"
    )
    p.add_argument(
        "--format",
        dest="formats",
        action="append",
        choices=("png", "svg", "pdf"),
        help="figure format (repeatable; default png and svg)",
    )
    p.add_argument(
        "--verify",
        action="store_true",
        help="recompute the run from the logged config and seed; exit 1 on any difference",
    )
    p.add_argument(
        "--at", type=float, metavar="TIME", help="print the state at simulated time TIME [s]"
    )
    p.add_argument(
        "--recover",
        action="store_true",
        help="read what an incomplete or damaged log holds (with a warning) instead of failing",
    )
    p.set_defaults(func=cmd_replay)


def _print_state(state: dict[str, Any], pr: float) -> None:
    np.set_printoptions(precision=9)
    print(f"state at step {state['step']}, t = {state['time']:.9g} s")
    print(f"  pose (x [m], y [m], theta [rad]) = {np.array2string(state['pose'], separator=', ')}")
    print("  covariance [m^2, m*rad, rad^2] =")
    for line in np.array2string(state["cov"], separator=", ").splitlines():
        print("    " + line)
    print(
        f"  ellipse at Pr = {100 * pr:.2f} %: a_major = {state['a_major']:.6g} m, "
        f"a_minor = {state['a_minor']:.6g} m, alpha = {state['alpha']:.6g} rad"
    )
    cloud = state.get("cloud")
    if cloud is not None:
        mean = cloud.mean(axis=0)
        print(
            f"  Monte Carlo cloud: {cloud.shape[0]} poses, mean {np.array2string(mean, separator=', ')}"
        )


def cmd_replay(args: argparse.Namespace) -> int:
    """``replay``: summary, figures, state at a time, verification."""
    from .runlog import PartialLogWarning, open_run, verify_run

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PartialLogWarning)
        log = open_run(args.log, recover=args.recover)
    for w in caught:
        if issubclass(w.category, PartialLogWarning):
            print(f"warning: {w.message}", file=sys.stderr)
        else:  # pragma: no cover - re-emit anything else unchanged
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    print(log.summary())
    if args.at is not None:
        try:
            state = log.state_at(args.at)
        except ValueError as exc:
            raise CommandError(f"--at: {exc}") from None
        _print_state(state, log.config.pr)
    if args.figures:
        from .figures import render_figures

        for path in render_figures(log, args.figures, args.formats or ("png", "svg")):
            print(f"wrote {path}")
    if args.verify:
        diffs = verify_run(log)
        mismatches = [d for d in diffs if not d.startswith("note: ")]
        for d in diffs:
            print(("MISMATCH " if d in mismatches else "") + d)
        if mismatches:
            print(
                f"verify: FAILED, {len(mismatches)} difference(s) between the log and a recomputation"
            )
            return EXIT_MISMATCH
        print("verify: OK, the recomputed run is identical to the log")
    return EXIT_OK


# --- wiring ---------------------------------------------------------------------------------

#: Sub-command name → function adding its parser (which sets ``func``).
COMMANDS: dict[str, Callable[[Any], None]] = {
    "run": _add_run,
    "replay": _add_replay,
    "calibrate": _add_calibrate,
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every command of :data:`COMMANDS`."""
    parser = argparse.ArgumentParser(
        prog="pose-uncertainty",
        description="Pose uncertainty of a differential-drive robot: runs, logs and replays.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in COMMANDS.values():
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pose-uncertainty`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from .runlog import RunLogError

    try:
        return int(args.func(args))
    except (CommandError, RunLogError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except ValueError as exc:  # bad parameters surfaced by the computation
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except BrokenPipeError:  # e.g. `pose-uncertainty replay RUN.mcap | head`
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
