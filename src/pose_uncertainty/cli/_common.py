"""What every command shares: exit statuses, the one-line error type and handler, config files."""

from __future__ import annotations

import argparse
import errno
import os
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..core.atomic import OutputError, Terminated, termination_as_exception
from ..core.input_files import InputFileError, read_mapping_file
from ..core.validation import first_line

__all__ = [
    "EXIT_INPUT",
    "EXIT_INTERNAL",
    "EXIT_MISMATCH",
    "EXIT_OK",
    "CommandError",
    "add_follow_symlink",
    "job_parser",
    "json_object",
    "load_config_file",
    "one_line_errors",
]

#: exit statuses: success; ``--verify`` found a mismatch; bad input or an I/O error;
#: an error of the program itself (a bug: one line, the traceback with ``--debug``)
EXIT_OK, EXIT_MISMATCH, EXIT_INPUT, EXIT_INTERNAL = 0, 1, 2, 1


class CommandError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def add_follow_symlink(parser: Any) -> None:
    """The explicit choice to write through a symbolic link at OUT (``--follow-symlink``)."""
    parser.add_argument("--follow-symlink", action="store_true",
                        help="if OUT is a symbolic link, write to its target (a regular file or a new path) "
                        "instead of refusing")  # fmt: skip


def _os_error_line(exc: OSError) -> str:
    """``"<file>: <what> (<ERRNO>)"``: the file the error is about, never a temporary one."""
    if isinstance(exc, OutputError):
        return str(exc)
    where = f"{exc.filename}: " if exc.filename else ""
    what = exc.strerror or first_line(exc)
    code = errno.errorcode.get(exc.errno or 0)
    return f"{where}{what}{f' ({code})' if code and code not in what else ''}"


def json_object(text: str) -> dict[str, Any]:
    """An argparse type: one JSON object given as a command-line argument (a job's configuration)."""
    import json

    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not valid JSON ({exc.msg} at character {exc.pos})") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"must be a JSON object, got {type(value).__name__}")
    return value


def job_parser(prog: str, description: str) -> tuple[argparse.ArgumentParser, Any]:
    """The parser of a pipeline job runner (``--debug``, then one ``KIND`` subcommand) and its subparsers."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("--debug", action="store_true", help="print the full traceback after an error's line")
    return parser, parser.add_subparsers(dest="kind", required=True, metavar="KIND")


def one_line_errors(func: Callable[[], int], *, debug: bool = False) -> int:
    """Run ``func()`` and turn every error into one line on stderr and an exit status.

    Bad input (a :class:`CommandError`, a ``ValueError`` such as a config, log or cost-guard
    error) and I/O errors (``OSError``, naming the file: a full disk, a read-only file system,
    a special file as output) exit 2; SIGINT exits 130, SIGTERM and SIGHUP 128 + their number,
    after the temporary file of a write in progress is removed
    (:func:`~pose_uncertainty.core.atomic.termination_as_exception`); any other exception is a
    defect of the program: one line, exit 1. With ``debug`` the full traceback follows the line
    (on stderr: a pipeline job's log).

    Returns
    -------
    int — ``func``'s status, or the error's
    """

    def fail(line: str, status: int) -> int:
        print(f"error: {line}", file=sys.stderr)
        if debug:
            traceback.print_exc(file=sys.stderr)
        return status

    try:
        with termination_as_exception():
            return int(func())
    except (CommandError, ValueError) as exc:
        return fail(first_line(exc), EXIT_INPUT)
    except BrokenPipeError:  # e.g. `pose-uncertainty replay RUN.mcap | head`
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except OSError as exc:
        return fail(_os_error_line(exc), EXIT_INPUT)
    except MemoryError:
        return fail("out of memory (the run's estimate did not foresee it; "
                    "POSE_UNCERTAINTY_MAX_MEMORY sets the guard's limit)", EXIT_INTERNAL)  # fmt: skip
    except KeyboardInterrupt:
        return fail("interrupted (SIGINT); nothing half-written was left", 130)
    except Terminated as exc:
        return fail(f"{exc} (signal {exc.signum}); nothing half-written was left", 128 + exc.signum)
    except Exception as exc:  # noqa: BLE001 - the last resort: one line, not a traceback
        hint = "" if debug else "; --debug shows the traceback"
        return fail(f"internal error: {type(exc).__name__}: {first_line(exc)}{hint}", EXIT_INTERNAL)


def load_config_file(path: str | Path) -> dict[str, Any]:
    """Read a run configuration mapping from a YAML or JSON file (by suffix; YAML otherwise).

    The file's kind and size are checked before it is read and a repeated key is refused
    (:func:`pose_uncertainty.core.input_files.read_mapping_file`); CommandError (one line
    naming the file) otherwise.
    """
    try:
        return read_mapping_file(path)
    except InputFileError as exc:
        raise CommandError(str(exc)) from None
