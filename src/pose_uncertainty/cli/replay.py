"""``pose-uncertainty replay RUN.mcap``: summary, state at a time, figures, verification."""

from __future__ import annotations

import argparse
import sys
import warnings
from typing import Any

import numpy as np

from ..core.provenance import MACHINE_KEYS, provenance
from ..present.figures import render_figures
from ..present.localization import render_localization_figures
from ..records.localization import LocalizationLog
from ..records.reproducibility import IDENTICAL, MISMATCH, Comparison
from ..records.run import PartialLogWarning, open_run, verify_run
from ..robot.run_bag import write_run_bag
from ._common import EXIT_MISMATCH, EXIT_OK, CommandError

__all__ = ["add_parser", "cmd_replay"]


def add_parser(sub: Any) -> None:
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
        help="recompute the run from the logged config and seed and compare every record: identical, "
        "equal within the reproducibility tolerance (another machine), or a mismatch (exit 1)",
    )
    p.add_argument(
        "--at", type=float, metavar="TIME", help="print the state at simulated time TIME [s]"
    )
    p.add_argument(
        "--recover",
        action="store_true",
        help="read what an incomplete or damaged log holds (with a warning) instead of failing",
    )
    p.add_argument("--to-rosbag", metavar="DIR", help="export the run as a ROS 2 bag folder DIR")
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


def _print_localization_state(state: dict[str, Any]) -> None:
    np.set_printoptions(precision=9)
    print(f"state at step {state['step']}, t = {state['time']:.9g} s")
    print(f"  truth (x [m], y [m], theta [rad]) = {np.array2string(state['truth'], separator=', ')}")
    for name, s in state.items():
        if isinstance(s, dict):
            sd = np.sqrt(np.maximum(np.diag(s["cov"]), 0.0))
            print(f"  {name}: mean {np.array2string(s['mean'], separator=', ')}, σ (x, y, θ) "
                  f"{np.array2string(sd, precision=4, separator=', ')}, position error {s['position_error']:.6g} m, "
                  f"heading error {s['heading_error']:.6g} rad")  # fmt: skip


def _report_verification(log: Any, comparison: Comparison) -> int:
    """Print the outcome of ``--verify`` (one of the contract's three) and return the exit status.

    "identical" is said only when everything the log holds was compared and its bytes equal a
    recomputation's; otherwise the lines say what was compared and what was not (and why).
    """
    for line in comparison.mismatches:
        print(f"MISMATCH {line}")
    for line in comparison.notes:
        print(f"note: {line}")
    what = ", ".join(f"{k} {v}" for k, v in sorted(comparison.compared.items()))
    skipped = "; ".join(f"{k} ({why})" for k, why in sorted(comparison.not_compared.items()))
    if comparison.status == MISMATCH:
        print(f"verify: MISMATCH, {len(comparison.mismatches)} difference(s) beyond the reproducibility "
              f"contract between the log and a recomputation")  # fmt: skip
        return EXIT_MISMATCH
    if comparison.status == IDENTICAL and not skipped:
        print("verify: identical, the log's bytes equal those of a recomputation")
        return EXIT_OK
    if comparison.status == IDENTICAL or comparison.worst == 0.0:
        print("verify: equal in everything compared: every record compared equals a recomputation's exactly, "
              "but not everything was compared")  # fmt: skip
    else:
        print(f"verify: equal within tolerance; largest relative difference {comparison.worst:.2e} of the "
              f"quantity's scale, in {comparison.worst_at}; tolerance {comparison.tolerance:.2e} "
              f"for {log.n_steps} steps")  # fmt: skip
    print(f"  compared: {what or 'every other record, byte for byte'}")
    if skipped:
        print(f"  not compared: {skipped}")
    here = provenance()
    for key in (*MACHINE_KEYS, "numpy_version", "scipy_version"):
        print(f"  {key}: log {log.provenance.get(key, 'not recorded')}; this machine {here[key]}")
    return EXIT_OK


def cmd_replay(args: argparse.Namespace) -> int:
    """``replay``: summary, figures, state at a time, verification."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PartialLogWarning)
        log = open_run(args.log, recover=args.recover)
    for w in caught:
        if issubclass(w.category, PartialLogWarning):
            print(f"warning: {w.message}", file=sys.stderr)
        else:  # pragma: no cover - re-emit anything else unchanged
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    print(log.summary())
    localization = isinstance(log, LocalizationLog)
    if args.at is not None:
        try:
            state = log.state_at(args.at)
        except ValueError as exc:
            raise CommandError(f"--at: {exc}") from None
        if localization:
            _print_localization_state(state)
        else:
            _print_state(state, log.config.pr)
    if args.figures:
        formats = args.formats or ("png", "svg")
        if isinstance(log, LocalizationLog):
            paths = render_localization_figures(log, args.figures, formats)
        else:
            paths = render_figures(log, args.figures, formats)
        for path in paths:
            print(f"wrote {path}")
    if args.to_rosbag:
        print(f"wrote {write_run_bag(log, args.to_rosbag)}")
    if args.verify:
        return _report_verification(log, verify_run(log))
    return EXIT_OK
