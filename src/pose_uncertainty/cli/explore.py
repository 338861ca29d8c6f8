"""``pose-uncertainty explore [--host HOST] [--port PORT]``: the interactive explorer in a browser."""

from __future__ import annotations

import argparse
from typing import Any

from ._common import EXIT_OK

__all__ = ["add_parser", "cmd_explore"]


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "explore",
        help="start the interactive explorer (a local web page) and print its address",
        description="Move a control, see every method's region and its coverage against Monte Carlo. "
        "Binds 127.0.0.1 (this machine only) unless --host is given.",
    )
    p.add_argument(
        "--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)"
    )
    p.add_argument("--port", type=int, default=0, help="TCP port (default 0: a free one)")
    p.set_defaults(func=cmd_explore)


def cmd_explore(args: argparse.Namespace) -> int:
    """``explore``: serve the explorer until interrupted."""
    from ..present.explore import serve

    if not 0 <= args.port <= 65535:
        raise ValueError(
            f"--port {args.port} is not a TCP port (allowed: 0..65535, 0 = a free one)"
        )
    serve(args.host, args.port, announce=lambda line: print(line, flush=True))
    return EXIT_OK
