"""What the pipeline ran, from its logs: provenance across all logs, and the time of each rule.

:func:`summarize_pipeline` reads the per-set tables (whose ``provenance.*``
columns come from each run log), the study logs and Snakemake's ``benchmark:``
files, and writes one JSON document the report shows as it is:

* ``provenance`` — per key of :data:`pose_uncertainty.core.provenance.PROVENANCE_KEYS`,
  the value most logs hold (``value``), how many logs hold each value
  (``counts``) and every log whose value differs (``differs``: set/study, run, value);
* ``seeds`` — per set, the seed of every run;
* ``rule_times`` — per rule, the number of jobs and their total, mean and largest
  wall-clock time [s] (Snakemake's ``s`` column), and ``total_s``.
"""

from __future__ import annotations

import json
import os
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.atomic import atomic_write_text
from ..core.provenance import PROVENANCE_KEYS
from ..core.table_io import read_table
from ..experiments.study import read_study

__all__ = ["provenance_summary", "rule_times", "summarize_pipeline"]


def provenance_summary(records: Sequence[tuple[str, str, Mapping[str, Any]]]) -> dict[str, Any]:
    """Per provenance key: the majority value, the counts, and the records that differ.

    Parameters
    ----------
    records : sequence of ``(group, name, provenance mapping)`` — one per log
    """
    out: dict[str, Any] = {}
    for key in PROVENANCE_KEYS:
        values = [(g, n, str(p.get(key, "missing"))) for g, n, p in records]
        counts = Counter(v for _, _, v in values)
        if not counts:
            continue
        value = counts.most_common(1)[0][0]
        out[key] = {
            "value": value,
            "counts": dict(counts),
            "differs": [{"group": g, "name": n, "value": v} for g, n, v in values if v != value],
        }
    return out


def rule_times(paths: Sequence[str | os.PathLike[str]]) -> dict[str, Any]:
    """Per-rule wall-clock statistics from Snakemake ``benchmark:`` files.

    The rule is the first directory under ``benchmarks/`` (``data/benchmarks/<rule>/...tsv``).
    """
    per: dict[str, list[float]] = {}
    for p in paths:
        parts = Path(p).parts
        rule = parts[parts.index("benchmarks") + 1] if "benchmarks" in parts else Path(p).parent.name
        lines = Path(p).read_text(encoding="utf-8").strip().splitlines()
        if len(lines) < 2:
            continue
        head, vals = lines[0].split("\t"), lines[1].split("\t")
        try:
            per.setdefault(rule, []).append(float(vals[head.index("s")]))
        except (ValueError, IndexError):
            continue
    rules = {
        rule: {"jobs": len(v), "total_s": float(sum(v)), "mean_s": float(np.mean(v)), "max_s": float(max(v))}
        for rule, v in sorted(per.items())
    }
    return {"rules": rules, "total_s": float(sum(r["total_s"] for r in rules.values()))}


def summarize_pipeline(
    tables: Mapping[str, str | os.PathLike[str]],
    studies: Sequence[str | os.PathLike[str]],
    benchmarks: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str],
) -> Path:
    """Write the pipeline summary (see the module docstring) as JSON to ``out``."""
    records: list[tuple[str, str, dict[str, Any]]] = []
    seeds: dict[str, dict[str, Any]] = {}
    for set_name, path in tables.items():
        for row in read_table(path):
            prov = {k[len("provenance."):]: v for k, v in row.items() if k.startswith("provenance.")}
            records.append((set_name, str(row["run"]), prov))
            seeds.setdefault(set_name, {})[str(row["run"])] = row.get("seed")
    for path in studies:
        doc = read_study(path)
        records.append(("studies", doc["name"], doc.get("provenance", {})))
    doc = {"provenance": provenance_summary(records), "seeds": seeds, "rule_times": rule_times(benchmarks),
           "n_logs": len(records)}  # fmt: skip
    p = Path(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write_text(p, json.dumps(doc, indent=1, sort_keys=True) + "\n")
