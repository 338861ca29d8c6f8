"""One study (a study of Šafránek 2022, a growth law, an accuracy case, ...) as a configured, logged job.

A study is configured by a kind (a key of
:data:`pose_uncertainty.analysis.studies.STUDIES`) and keyword parameters;
:func:`study_params` validates them against the study function and fills in
every default, so that the log holds everything that determines the result.
:func:`run_study` executes it and writes a *study log*: a JSON document ::

    {"format": "pose-uncertainty-study", "format_version": "1", "name": ..., "study": ...,
     "params": {...every parameter...}, "provenance": {...}, "results": {...}}

written atomically (a temporary file, then a rename). The same parameters give
the same results (every study seeds its own generators from its ``seed``).
"""

from __future__ import annotations

import inspect
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..analysis.studies import STUDIES, summarize
from ..core.atomic import atomic_write_text
from ..core.provenance import provenance
from ..core.table_io import jsonable
from .cost import check_study

__all__ = ["FORMAT", "collect_studies", "read_study", "run_study", "study_params"]

FORMAT = "pose-uncertainty-study"
FORMAT_VERSION = "1"


def study_params(name: str, spec: Mapping[str, Any]) -> tuple[str, dict[str, Any]]:
    """Validate a study's configuration ``{"study": kind, **params}``; return ``(kind, every param)``.

    Raises
    ------
    ValueError — naming the study, the bad key or kind, and what is allowed.
    """
    if not isinstance(spec, Mapping) or "study" not in spec:
        raise ValueError(f"config key 'studies.{name}' must be a mapping with a 'study' key, got {spec!r}")
    kind = spec["study"]
    if kind not in STUDIES:
        raise ValueError(f"config key 'studies.{name}.study' must be one of {sorted(STUDIES)}, got {kind!r}")
    sig = inspect.signature(STUDIES[kind])
    defaults = {p.name: p.default for p in sig.parameters.values() if p.default is not inspect.Parameter.empty}
    params = {k: v for k, v in spec.items() if k != "study"}
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ValueError(
            f"unknown config key(s) {', '.join(repr(f'studies.{name}.{k}') for k in unknown)} "
            f"(allowed for a {kind} study: study, {', '.join(sorted(defaults))})"
        )
    return kind, jsonable({**defaults, **params})


def run_study(name: str, spec: Mapping[str, Any], out: str | os.PathLike[str]) -> Path:
    """Run one configured study and write its log (JSON, atomically) to ``out``."""
    kind, params = study_params(name, spec)
    check_study(name, kind, params)  # the cost guard: one line over the memory or time limit
    results = STUDIES[kind](**params)
    doc = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "name": name, "study": kind,
        "params": params, "provenance": provenance(), "results": jsonable(results),
    }  # fmt: skip
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(doc, indent=1, sort_keys=True, allow_nan=True) + "\n")
    return path


def read_study(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a study log; ``ValueError`` naming the file if it is not one."""
    p = Path(path)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{p}: not a readable study log ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"{p}: not a pose-uncertainty study log")
    return doc


def collect_studies(paths: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str]) -> Path:
    """Read study logs (in config order) and write what the report shows of them as JSON.

    The file holds :func:`pose_uncertainty.analysis.studies.summarize` of the logs:
    ``{"studies": {name: results, ...}, "summary": {...}}``.
    """
    docs = [read_study(p) for p in paths]
    doc = summarize({d["name"]: {"study": d["study"], "results": d["results"]} for d in docs})
    p = Path(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write_text(p, json.dumps(doc, indent=1, sort_keys=True) + "\n")
