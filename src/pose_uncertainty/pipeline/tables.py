"""One table per experiment set: the runs' logs flattened, one row per run, computing nothing.

Every column of a row comes from one logged source of its run:

* ``set``, ``run``, ``seed``, ``n_steps`` — the run's identity (config and data);
* ``param.<key>`` — the logged run configuration (nested keys joined by dots,
  lists as JSON, so ``param.maps`` is the list of the run's maps; ``param.drive.*`` for a run
  with a drive section);
* ``provenance.<key>`` — the log's provenance (package version, git commit,
  environment.lock sha256, ...);
* ``<measure>`` — every metric logged on ``/metrics`` under its own name, e.g.
  ``A_sigma_across``, ``MC_coverage_3s``, ``map_odometry_peak_offset``
  (units and definitions: :mod:`pose_uncertainty.analysis.measures`);
* ``time_<part>`` — the run's wall-clock timings [s] from its ``*.timings.json``
  side file, or from its chunk's timings file when a job ran a chunk of runs
  (:func:`pose_uncertainty.pipeline.chunks.read_timings`; not reproducible, so not in the log itself).

A localization run's row (:mod:`pose_uncertainty.records.localization`) has the same
columns, its ``param.*`` from :data:`LOCALIZATION_PARAMS` and its world's source and random
landmarks, its measures ``loc_*`` and its timings ``time_<filter>_step`` [s per step].
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..core.table_io import write_table
from ..records.localization import LocalizationLog
from ..records.run import RunLog, open_run
from .chunks import read_timings

__all__ = ["FIRST_COLUMNS", "LOCALIZATION_PARAMS", "collect_table", "run_row"]

#: Columns written first, in this order.
FIRST_COLUMNS: tuple[str, ...] = ("set", "run", "seed", "n_steps")


def _flat(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, Mapping):
        for k, v in value.items():
            _flat(f"{prefix}.{k}", v, out)
    else:
        out[prefix] = json.dumps(value) if isinstance(value, list | tuple) else value


#: The configuration keys a localization run's row flattens (the world by its source and random landmarks).
LOCALIZATION_PARAMS: tuple[str, ...] = ("repeat", "trajectory", "truth", "sensors", "scenario", "filters", "success")


def run_row(
    log: str | os.PathLike[str] | RunLog | LocalizationLog, timings: str | os.PathLike[str] | None = None
) -> dict[str, Any]:
    """The table row of one run log (see the module docstring for the columns)."""
    run = log if isinstance(log, RunLog | LocalizationLog) else open_run(log)
    cfg = run.config.to_dict()
    row: dict[str, Any] = {"run": run.config.name, "seed": run.config.seed, "n_steps": run.n_steps}
    if isinstance(run, LocalizationLog):  # a localization run: its own configuration keys
        world = cfg["world"]
        row["param.world.source"] = world.get("source", "")
        _flat("param.world.random_landmarks", world["random_landmarks"], row)
        keys: tuple[str, ...] = LOCALIZATION_PARAMS
    else:  # ``drive`` only when the run configures one
        keys = ("trajectory", "k_r", "k_l", "cov0", "pr", "n_ellipses", "monte_carlo", "maps", "drive")
    for key in keys:
        if key in cfg:
            _flat(f"param.{key}", cfg[key], row)
    for key, value in sorted(run.provenance.items()):
        row[f"provenance.{key}"] = value
    row.update({k: float(v) for k, v in sorted(run.metrics.items())})
    for k, v in (read_timings(timings, run.path) or {}).items():
        row[f"time_{k.removesuffix('_s')}"] = float(v)
    return row


def collect_table(
    set_name: str,
    logs: Sequence[str | os.PathLike[str]],
    timings: Sequence[str | os.PathLike[str] | None] | None,
    out: str | os.PathLike[str],
) -> Path:
    """Write the CSV of a set: :func:`run_row` of each log, plus the ``set`` column.

    Floats are written with ``repr`` (round-trip exact), so a cell equals the
    logged value bit for bit; a value a run does not have is empty.
    """
    tims = list(timings) if timings is not None else [None] * len(logs)
    rows = [{"set": set_name, **run_row(log, tim)} for log, tim in zip(logs, tims, strict=True)]
    return write_table(rows, out, FIRST_COLUMNS)
