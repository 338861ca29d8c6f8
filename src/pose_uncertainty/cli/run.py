"""``pose-uncertainty run CONFIG -o OUT.mcap``: execute one run and write its log."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

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


class _Kind(NamedTuple):
    """What ``run`` does with one kind of configuration: read it, execute it, log it, draw it."""

    parse: Callable[[dict[str, Any]], Any]
    execute: Callable[[Any], Any]
    write: Callable[[str, Any, bool, Any], Path]  # (out, result, timings, config) -> the log
    describe: Callable[[Any], str]  # what the summary line says of the result
    render: Callable[[Any, str], list[Path]]


_DEAD_RECKONING = _Kind(
    parse=RunConfig.from_dict,
    execute=execute,
    write=lambda out, result, timings, config: write_run(
        out, result, include_timings=timings, progress=Progress(f"{config.name}: writing the log")),
    describe=lambda result: f"{result.n_steps} steps",
    render=render_figures,
)
_LOCALIZATION = _Kind(
    parse=LocalizationConfig.from_dict,
    execute=execute_localization,
    write=lambda out, result, timings, config: write_localization(out, result, include_timings=timings),
    describe=lambda result: f"{result.n_steps} steps, filters {', '.join(result.filters)}",
    render=render_localization_figures,
)


def cmd_run(args: argparse.Namespace) -> int:
    """``run``: config file → execute → write log (→ figures); a dead-reckoning run, or a
    localization run (``kind: localization``)."""
    # refuse a special file or an unchosen link at OUT before the run costs anything
    args.output = check_destination(args.output, follow_symlinks=args.follow_symlink)
    data = load_config_file(args.config)
    kind = _LOCALIZATION if is_localization_config(data) else _DEAD_RECKONING
    try:
        config = kind.parse(data)
    except ValueError as exc:
        raise CommandError(f"{args.config}: {exc}") from None
    result = kind.execute(config)
    path = kind.write(args.output, result, args.timings, config)
    print(f"wrote {path} ({path.stat().st_size} bytes, {kind.describe(result)})")
    if args.figures:
        for fig in kind.render(result, args.figures):
            print(f"wrote {fig}")
    return EXIT_OK
