"""What every command shares: exit statuses, the one-line error type, config files."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..core.input_files import InputFileError, read_mapping_file

__all__ = ["EXIT_INPUT", "EXIT_MISMATCH", "EXIT_OK", "CommandError", "load_config_file"]

EXIT_OK, EXIT_MISMATCH, EXIT_INPUT = 0, 1, 2


class CommandError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


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
