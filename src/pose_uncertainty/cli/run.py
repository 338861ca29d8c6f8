"""``pose-uncertainty run CONFIG -o OUT.mcap``: execute one run and write its log."""

from __future__ import annotations

import argparse
from typing import Any

from ..core.atomic import check_destination
from ..experiments.config import RunConfig
from ..experiments.localization import (
    LocalizationConfig,
    execute_localization,
    is_localization_config,
)
from ..experiments.progress import Progress
from ..experiments.run import execute
from ..present.figures import render_figures
from ..present.localization import render_localization_figures
from ..records.localization import write_localization
from ..records.run import write_run
from ._common import EXIT_OK, CommandError, add_follow_symlink, load_config_file

__all__ = ["add_parser", "cmd_run"]


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "run",
        help="execute one run and write its MCAP log",
        description="Execute one run: a dead-reckoning run, or a localization run (kind: localization).",
    )
    p.add_argument("config", help="run configuration, YAML or JSON")
    p.add_argument("-o", "--output", required=True, help="output log, *.mcap (written atomically)")
    p.add_argument(
        "--timings",
        action="store_true",
        help="also log wall-clock timings (topic /timings); the file is then not byte-reproducible",
    )
    p.add_argument("--figures", metavar="DIR", help="also render the run's figures into DIR")
    add_follow_symlink(p)
    p.set_defaults(func=cmd_run)


def cmd_run(args: argparse.Namespace) -> int:
    """``run``: config file → execute → write log (→ figures)."""
    # refuse a special file or an unchosen link at OUT before the run costs anything
    args.output = check_destination(args.output, follow_symlinks=args.follow_symlink)
    data = load_config_file(args.config)
    if is_localization_config(data):  # kind: localization
        return _run_localization(args, data)
    try:
        config = RunConfig.from_dict(data)
    except ValueError as exc:
        raise CommandError(f"{args.config}: {exc}") from None
    result = execute(config)
    path = write_run(
        args.output, result, include_timings=args.timings,
        progress=Progress(f"{config.name}: writing the log"),
    )  # fmt: skip
    print(f"wrote {path} ({path.stat().st_size} bytes, {result.n_steps} steps)")
    if args.figures:
        for fig in render_figures(result, args.figures):
            print(f"wrote {fig}")
    return EXIT_OK


def _run_localization(args: argparse.Namespace, data: dict[str, Any]) -> int:
    """``run`` of a localization configuration (``kind: localization``)."""
    try:
        config = LocalizationConfig.from_dict(data)
    except ValueError as exc:
        raise CommandError(f"{args.config}: {exc}") from None
    result = execute_localization(config)
    path = write_localization(args.output, result, include_timings=args.timings)
    print(f"wrote {path} ({path.stat().st_size} bytes, {result.n_steps} steps, filters {', '.join(result.filters)})")
    if args.figures:
        for fig in render_localization_figures(result, args.figures):
            print(f"wrote {fig}")
    return EXIT_OK
