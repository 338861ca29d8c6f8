"""The pipeline's job entry points: execute one run of each kind and write its log and timings.

Each is what one Snakemake job runs (through ``python -m pose_uncertainty.cli.job``): the
execution of :mod:`pose_uncertainty.experiments`, then the log of :mod:`pose_uncertainty.records`,
written atomically and byte-reproducible (no timings inside; they go to a JSON file beside it).
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ..core.atomic import atomic_write_text
from ..experiments.config import RunConfig
from ..experiments.localization import LocalizationConfig, execute_localization
from ..experiments.progress import Progress
from ..experiments.run import execute
from ..experiments.study import run_study
from ..records.localization import write_localization
from ..records.run import write_run
from .chunks import run_configs, timings_key

__all__ = ["run_study", "simulate_chunk", "simulate_localization", "simulate_run"]


def _timings_json(timings: Mapping[str, float]) -> dict[str, float]:
    return {k: float(v) for k, v in sorted(timings.items())}


def _write_timings(timings: Mapping[str, float], out: str | os.PathLike[str] | None) -> None:
    if out is not None:
        atomic_write_text(out, json.dumps(_timings_json(timings), indent=1) + "\n")


def _write_run(out: str | os.PathLike[str], result: Any) -> Path:
    """A dead-reckoning run's log, its progress shown under the run's name."""
    return write_run(out, result, progress=Progress(f"{result.config.name}: writing the log"))


#: Each job kind: its configuration from the mapping, its execution, the writer of its log.
_KINDS: dict[str, tuple[Callable[[Mapping[str, Any]], Any], Callable[[Any], Any], Callable[..., Path]]] = {
    "run": (RunConfig.from_dict, execute, _write_run),
    "localization": (lambda c: LocalizationConfig.from_dict(dict(c)), execute_localization, write_localization),
}


def _simulate(kind: str, config: Mapping[str, Any], out: str | os.PathLike[str],
              timings_out: str | os.PathLike[str] | None) -> tuple[Path, Mapping[str, float]]:  # fmt: skip
    """Execute one run of ``kind`` (a key of :data:`_KINDS`), write its log to ``out`` and its timings;
    return the log's path and the timings."""
    parse, run, write = _KINDS[kind]
    result = run(parse(config))
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    path = write(out, result)
    _write_timings(result.timings, timings_out)
    return path, result.timings


def simulate_run(config: Mapping[str, Any], out: str | os.PathLike[str],
                 timings_out: str | os.PathLike[str] | None = None) -> Path:  # fmt: skip
    """Execute one dead-reckoning run and write its log (and, optionally, its timings as JSON).

    Parameters
    ----------
    config : mapping — a run configuration (``RunConfig.from_dict`` input)
    out : path — destination ``.mcap`` (written atomically, byte-reproducible: no timings inside)
    timings_out : path, optional — JSON file with the run's timings [s]

    Returns
    -------
    Path — ``out``
    """
    return _simulate("run", config, out, timings_out)[0]


def simulate_localization(config: Mapping[str, Any], out: str | os.PathLike[str],
                          timings_out: str | os.PathLike[str] | None = None) -> Path:  # fmt: skip
    """Execute one localization run and write its log (and, optionally, its timings as JSON).

    Parameters and return as :func:`simulate_run`, for a ``kind: localization`` configuration.
    """
    return _simulate("localization", config, out, timings_out)[0]


def simulate_chunk(spec: Mapping[str, Any]) -> list[Path]:
    """Execute the runs of one chunk in this process, each as :func:`simulate_run` (or
    :func:`simulate_localization`) would in a job of its own, and write their logs and timings.

    Parameters
    ----------
    spec : mapping — :func:`pose_uncertainty.pipeline.chunks.chunk_spec`: ``kind`` (``"run"`` or
        ``"localization"``), the runs' configurations and their output files; with ``timings``, the
        chunk's timings file, written after the last log (every run's timings by
        :func:`pose_uncertainty.pipeline.chunks.timings_key`)

    Returns
    -------
    list of Path — the logs written, in the chunk's order

    Raises
    ------
    ValueError — an unknown kind; the first run whose configuration is refused (no later run is executed)
    """
    kind = spec.get("kind")
    if kind not in _KINDS:
        raise ValueError(f"chunk kind must be one of {sorted(_KINDS)}, got {kind!r}")
    runs = spec["runs"]
    out = []
    timings: dict[str, dict[str, float]] = {}
    for i, (config, run) in enumerate(zip(run_configs(spec), runs, strict=True)):
        print(f"chunk: run {i + 1} of {len(runs)}: {run['log']}", file=sys.stderr, flush=True)
        path, tim = _simulate(kind, config, run["log"], run.get("timings"))
        out.append(path)
        timings[timings_key(run["log"])] = _timings_json(tim)
    if spec.get("timings") is not None:
        Path(spec["timings"]).parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(spec["timings"], json.dumps({"runs": timings}, indent=1) + "\n")
    return out
