"""The pipeline's computing jobs as commands: ``python -m pose_uncertainty.cli.job KIND ...``.

Snakemake runs each dead-reckoning run, localization run and study as a shell command of
this module rather than as a ``script:``: a script job first imports Snakemake itself to read
its parameters (0.1 s of CPU), which the pipeline's ~200 such jobs would each pay. The
configuration comes as one JSON argument (what the rule's ``params`` hold); the outputs are
written atomically by the functions called; progress goes to stderr (the rule's log).

Commands
--------
``simulate-run CONFIG_JSON LOG.mcap TIMINGS.json``
    :func:`pose_uncertainty.pipeline.jobs.simulate_run`.
``simulate-localization CONFIG_JSON LOG.mcap TIMINGS.json``
    :func:`pose_uncertainty.pipeline.jobs.simulate_localization`.
``simulate-chunk CHUNK_JSON``
    :func:`pose_uncertainty.pipeline.jobs.simulate_chunk`: the runs of one chunk
    (:func:`pose_uncertainty.pipeline.chunks.chunk_spec`) in this one process.
``run-study NAME STUDY_JSON OUT.json``
    :func:`pose_uncertainty.pipeline.jobs.run_study`.

Exit status and errors are those of the ``pose-uncertainty`` command
(``pose_uncertainty.cli._common.one_line_errors``): 0 success; 2 bad usage, a bad
configuration, a run over the cost guard's limits or an I/O error (one line on stderr, the
rule's log, naming the key or the file); 1 a defect of the program (one line); 128 + the signal's
number for SIGTERM and SIGHUP (a cluster's time limit), 130 for SIGINT, with no ``.part`` file
left. ``--debug`` (before KIND) adds the full traceback to the log.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from ._common import job_parser, json_object, one_line_errors

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    parser, sub = job_parser("python -m pose_uncertainty.cli.job", __doc__.split("\n")[0])
    for kind, what in (("simulate-run", "a dead-reckoning run"), ("simulate-localization", "a localization run")):
        p = sub.add_parser(kind, help=f"execute {what} and write its log and timings")
        p.add_argument("config", type=json_object, help="the run configuration as a JSON object")
        p.add_argument("log", help="output log, *.mcap")
        p.add_argument("timings", help="output timings, *.json")
    p = sub.add_parser("simulate-chunk", help="execute the runs of one chunk in this process, each as its own job would")
    p.add_argument("spec", type=json_object, help="the chunk as a JSON object (pose_uncertainty.pipeline.chunks.chunk_spec)")
    p = sub.add_parser("run-study", help="run one study and write its results")
    p.add_argument("name", help="the study's name")
    p.add_argument("spec", type=json_object, help='its configuration as a JSON object ({"study": kind, ...})')
    p.add_argument("out", help="output, *.json")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one job; returns the exit status (see the module docstring)."""
    args = _parser().parse_args(argv)
    return one_line_errors(lambda: _dispatch(args), debug=args.debug)


def _dispatch(args: argparse.Namespace) -> int:
    from ..experiments.environment import check_environment
    from ..pipeline import jobs

    check_environment()  # every variable the package reads, before any work (as the CLI)

    if args.kind == "simulate-run":
        jobs.simulate_run(args.config, args.log, args.timings)
    elif args.kind == "simulate-chunk":
        jobs.simulate_chunk(args.spec)
    elif args.kind == "simulate-localization":
        jobs.simulate_localization(args.config, args.log, args.timings)
    else:
        jobs.run_study(args.name, args.spec, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
