"""Flat tables of numbers as CSV (one row per run, one column per measure), and plain values.

The one table format of the package: :func:`write_table` writes rows (mappings
of column to value) with floats in ``repr`` (round-trip exact) and missing
values empty; :func:`read_table` reads them back with numbers parsed and empty
cells as None.
"""

from __future__ import annotations

import copy
import csv
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .atomic import atomic_write

__all__ = ["jsonable", "plain_copy", "read_table", "write_table"]

#: The types :func:`jsonable` and :func:`plain_copy` return as they are (tested first: the common case).
_SCALARS = (str, float, int, bool, type(None))


def jsonable(value: Any) -> Any:
    """Tuples, numpy scalars and arrays → JSON lists and Python numbers (mappings recursively)."""
    if type(value) in _SCALARS:
        return value
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple | np.ndarray):
        return [jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def plain_copy(value: Any) -> Any:
    """A deep copy of configuration data (dicts, lists, scalars): what ``copy.deepcopy`` gives, several
    times faster on it (no memo; a sweep copies its base once per run); any other object by ``deepcopy``."""
    kind = type(value)
    if kind is dict:
        return {k: plain_copy(v) for k, v in value.items()}
    if kind is list:
        return [plain_copy(v) for v in value]
    return value if isinstance(value, _SCALARS) else copy.deepcopy(value)


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    return repr(value) if isinstance(value, float) else value


def write_table(
    rows: Sequence[Mapping[str, Any]], out: str | os.PathLike[str], first: Sequence[str] = ()
) -> Path:
    """Write rows as CSV: the columns ``first`` (those present), then every other key sorted.

    Parameters
    ----------
    rows : sequence of mappings column → value (str, int, float or None)
    out : path of the CSV file (parent folders are created)
    first : column names to put first, in this order
    """
    keys = sorted({k for r in rows for k in r})
    cols = [k for k in first if k in keys] + [k for k in keys if k not in first]
    p = Path(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(p, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        for r in rows:
            w.writerow([_cell(r.get(k)) for k in cols])
    return p


def _parse_cell(text: str) -> Any:
    if text == "":
        return None
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def read_table(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """Read a CSV written by :func:`write_table` (numbers parsed, empty cells as None)."""
    with open(path, newline="", encoding="utf-8") as fh:
        return [{k: _parse_cell(v) for k, v in row.items()} for row in csv.DictReader(fh)]
