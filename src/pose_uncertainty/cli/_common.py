"""What every command shares: exit statuses, the one-line error type, config files."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

__all__ = ["EXIT_INPUT", "EXIT_MISMATCH", "EXIT_OK", "CommandError", "load_config_file"]

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
            data = yaml.safe_load(text)
    except Exception as exc:  # noqa: BLE001 - any parser error is a bad file
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CommandError(
            f"{p}: not valid {'JSON' if p.suffix.lower() == '.json' else 'YAML'} ({first})"
        ) from None
    if not isinstance(data, dict):
        raise CommandError(f"{p}: the config must be a mapping, got {type(data).__name__}")
    return data
