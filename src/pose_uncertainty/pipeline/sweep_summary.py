"""The summary of a large sweep, from its table alone: its axes, and per measure the sensitivity
indices, partial dependence and a response surface (what the report shows instead of per-run figures).

A set with more runs than the config key ``report.summary_above`` is summarised here
(:func:`summarize_sweep`), reading nothing but its CSV (:func:`pose_uncertainty.pipeline.tables.collect_table`):

* **the axes** (:func:`sweep_axes`) are found in the ``param.*`` columns that vary: two columns
  belong to one axis when they are not crossed (some pair of their values never occurs together),
  as the keys of one zipped sweep axis (``trajectory.name`` with ``trajectory.length``); the
  levels of an axis are the distinct tuples of its columns;
* **the measures** are the logged numeric columns (not ``param.*``, ``provenance.*``, timings or
  the run's identity) with a finite value in every row and some spread;
* per measure, :mod:`pose_uncertainty.analysis.sensitivity`: the first-order and total Sobol indices of
  each axis (exact on a full factorial; on any other design only the first-order index, as the
  correlation ratio, and no total), the partial dependence on each axis, and the response surface
  over the two axes of largest index.

The output is one JSON document (``reports/tables/<set>.sweep.json``); the figures and the report
format it (:func:`pose_uncertainty.present.pipeline_figures.render_sweep_figures`).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..analysis import measures as measure_defs
from ..analysis.sensitivity import grid_array, partial_dependence, sobol_indices, surface
from ..core.atomic import atomic_write_text
from ..core.table_io import read_table

__all__ = ["summarize_sweep", "sweep_axes", "sweep_summary"]

#: Columns of a run's identity and derived counts: neither an axis nor a measure.
_IDENTITY = ("set", "run", "seed", "n_steps")


def _key(value: Any) -> str:
    return json.dumps(value, sort_keys=True)


def _codes(values: Sequence[Any]) -> tuple[np.ndarray, list[Any]]:
    """Each value's level index, levels in sorted order when all are numbers (else first appearance)."""
    keys = [_key(v) for v in values]
    distinct = list(dict.fromkeys(keys))
    firsts = {k: values[keys.index(k)] for k in distinct}
    if all(isinstance(firsts[k], int | float) and not isinstance(firsts[k], bool) for k in distinct):
        distinct.sort(key=lambda k: float(firsts[k]))
    index = {k: i for i, k in enumerate(distinct)}
    return np.array([index[k] for k in keys], dtype=np.int64), [firsts[k] for k in distinct]


def sweep_axes(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The axes of a sweep found in its table's varying ``param.*`` columns (see the module docstring).

    Returns
    -------
    list of ``{"name", "columns", "levels" (text per level), "codes" (array: each row's level)}``,
    in the order of the columns' first appearance
    """
    columns = [c for c in (rows[0] if rows else {}) if c.startswith("param.")]
    varying = {}
    for c in columns:
        codes, levels = _codes([r.get(c) for r in rows])
        if len(levels) > 1:
            varying[c] = (codes, levels)
    names = list(varying)
    parent = {c: c for c in names}

    def root(c: str) -> str:
        while parent[c] != c:
            c = parent[c]
        return c

    for i, a in enumerate(names):  # a few columns: the pairs, not the rows, are looped over
        for b in names[i + 1:]:
            ca, la = varying[a]
            cb, lb = varying[b]
            pairs = np.unique(ca * len(lb) + cb).size
            if pairs < len(la) * len(lb):  # not crossed: one axis
                parent[root(b)] = root(a)
    groups: dict[str, list[str]] = {}
    for c in names:
        groups.setdefault(root(c), []).append(c)
    axes = []
    for cols in groups.values():
        if len(cols) == 1:
            codes, levels = varying[cols[0]]
            texts = [_level_text(v) for v in levels]
        else:
            tuples = [tuple(_key(r.get(c)) for c in cols) for r in rows]
            codes, levels = _codes(["|".join(t) for t in tuples])
            texts = [_tuple_text(cols, rows[int(np.argmax(codes == i))]) for i in range(len(levels))]
        axes.append({"name": _axis_name(cols), "columns": cols, "levels": texts, "codes": codes})
    return axes


def _level_text(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _tuple_text(cols: Sequence[str], row: Mapping[str, Any]) -> str:
    return ", ".join(f"{c.rsplit('.', 1)[-1]} {_level_text(row[c])}" for c in cols if row.get(c) not in (None, ""))


def _axis_name(cols: Sequence[str]) -> str:
    keys = [c.removeprefix("param.") for c in cols]
    if len(keys) == 1:
        return keys[0]
    prefix = []
    for level in zip(*(k.split(".") for k in keys), strict=False):  # the dotted parts all keys share
        if len(set(level)) > 1:
            break
        prefix.append(level[0])
    return ".".join(prefix) if prefix else ", ".join(keys)


def _measure_columns(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    out = []
    for c in rows[0] if rows else {}:
        if c in _IDENTITY or c.startswith(("param.", "provenance.", "time_")):
            continue
        vals = [r.get(c) for r in rows]
        if not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in vals):
            continue
        numbers = [float(v) for v in vals if v is not None]
        if max(numbers) > min(numbers):
            out.append(c)
    return out


def _group_means(y: np.ndarray, codes: np.ndarray, n: int) -> np.ndarray:
    counts = np.bincount(codes, minlength=n)
    return np.bincount(codes, weights=y, minlength=n) / np.where(counts > 0, counts, 1)


def _unit(name: str) -> str:
    try:
        return measure_defs.describe(name)[0]
    except KeyError:
        return ""


def _finite(values: Any) -> list[float | None]:
    return [None if not math.isfinite(float(v)) else float(v) for v in np.ravel(values)]


def sweep_summary(rows: Sequence[Mapping[str, Any]], set_name: str = "") -> dict[str, Any]:
    """The summary of a sweep from its table rows (see the module docstring for what it holds).

    Returns
    -------
    dict — ``{"set", "n_runs", "full_factorial", "axes": [{"name", "columns", "levels"}],
    "measures": [{"name", "unit", "first", "total", "dependence", "surface": {"axes", "z"}}]}``;
    an index is null where it is not defined (a constant measure; the total off a full factorial)
    """
    axes = sweep_axes(rows)
    shape = tuple(len(a["levels"]) for a in axes)
    codes = np.stack([a["codes"] for a in axes], axis=1) if axes else np.zeros((len(rows), 0), dtype=np.int64)
    n = len(rows)
    full = bool(axes) and math.prod(shape) == n and np.unique(np.ravel_multi_index(tuple(codes.T), shape)).size == n
    out_measures = []
    for name in _measure_columns(rows):
        y = np.array([float(r[name]) for r in rows])
        if full:
            grid = grid_array(y, codes, shape)
            first, total = sobol_indices(grid)
            dependence = [partial_dependence(grid, i) for i in range(len(axes))]
        else:  # the correlation ratio: the first-order index of any design; no total
            v = float(y.var())
            dependence = [_group_means(y, a["codes"], len(a["levels"])) for a in axes]
            first = np.array([float(np.average((d[a["codes"]] - y.mean()) ** 2)) / v for d, a in zip(dependence, axes,
                                                                                                 strict=True)])  # fmt: skip
            total = np.full(len(axes), np.nan)
        entry: dict[str, Any] = {"name": name, "unit": _unit(name), "first": _finite(first), "total": _finite(total),
                                 "dependence": [_finite(d) for d in dependence]}  # fmt: skip
        if len(axes) >= 2:
            rank = np.nan_to_num(total if full else first, nan=-1.0)
            i, j = sorted(int(k) for k in np.argsort(-rank, kind="stable")[:2])
            if full:
                z = surface(grid, i, j)
            else:
                pair = axes[i]["codes"] * shape[j] + axes[j]["codes"]
                counts = np.bincount(pair, minlength=shape[i] * shape[j])
                z = np.where(counts > 0, _group_means(y, pair, shape[i] * shape[j]), np.nan).reshape(shape[i], shape[j])
            entry["surface"] = {"axes": [i, j], "z": [_finite(row) for row in z]}
        out_measures.append(entry)
    return {
        "set": set_name,
        "n_runs": n,
        "full_factorial": full,
        "axes": [{k: a[k] for k in ("name", "columns", "levels")} for a in axes],
        "measures": out_measures,
    }


def summarize_sweep(set_name: str, table: str | os.PathLike[str], out: str | os.PathLike[str]) -> Path:
    """Write :func:`sweep_summary` of a set's table (its CSV alone) as JSON to ``out`` (atomically)."""
    Path(out).parent.mkdir(parents=True, exist_ok=True)  # the tables' folder: made by the set's table
    return atomic_write_text(out, json.dumps(sweep_summary(read_table(table), set_name), indent=1, allow_nan=False) + "\n")
