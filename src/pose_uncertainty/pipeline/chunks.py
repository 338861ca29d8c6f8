"""Batched jobs: the runs of a set cut into chunks, each chunk one pipeline job (one interpreter).

A sweep of thousands of runs as one job per run pays the interpreter and its imports (about
0.8 CPU-s) thousands of times, and submits thousands of cluster jobs. With the config key
``runs_per_job`` above 1 the pipeline cuts each set's runs, in their order, into chunks of at
most that many runs (:func:`chunk_runs`); one job executes a chunk in one process
(:func:`pose_uncertainty.pipeline.jobs.simulate_chunk`), each run exactly as a job of its own
would, so its log is byte-identical.

The job's command carries the chunk as one JSON argument (:func:`chunk_spec`): one configuration
in full per shape of configuration (its leaves) and, for every run, only the leaves of its
configuration that differ from its shape's (:func:`config_delta`); :func:`run_configs` rebuilds
every configuration from it.
A sweep's runs differ in a few values, so a chunk of 100 runs stays far below the operating
system's limit on one argument (128 KiB on Linux).

A chunk's job writes its runs' wall-clock timings into one file, the chunk's timings file
(``{"runs": {<log file name>: {<part>_s: seconds}}}``), after every log of the chunk: one file per
chunk for the workflow to track instead of one per run (the DAG of a 10⁴-run sweep then holds half
as many files), and what the readers of a chunked set wait for. :func:`read_timings` reads a run's
timings from either file, its own (one run per job) or its chunk's.

This module imports nothing heavy: the workflow reads it while it builds its graph.
"""

from __future__ import annotations

import copy
import functools
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

__all__ = ["chunk_runs", "chunk_spec", "config_delta", "read_timings", "run_configs", "timings_key"]

T = TypeVar("T")

#: The most runs one chunk may hold (the config key ``runs_per_job`` has the same upper bound).
MAX_RUNS_PER_JOB = 10_000


def chunk_runs(runs: Sequence[T], runs_per_job: int) -> list[list[T]]:
    """``runs`` cut, in order, into consecutive chunks of at most ``runs_per_job``.

    Parameters
    ----------
    runs : sequence — the runs of one set, in the set's order
    runs_per_job : int — the most runs one job executes (1 ≤ runs_per_job ≤ 10 000)

    Returns
    -------
    list of lists — every run exactly once; a run's chunk depends only on its position in the set

    Raises
    ------
    ValueError — ``runs_per_job`` out of its range
    """
    if isinstance(runs_per_job, bool) or not isinstance(runs_per_job, int) or not 1 <= runs_per_job <= MAX_RUNS_PER_JOB:
        raise ValueError(f"runs_per_job must be an integer in [1, {MAX_RUNS_PER_JOB}], got {runs_per_job!r}")
    return [list(runs[i:i + runs_per_job]) for i in range(0, len(runs), runs_per_job)]


_Leaves = dict[tuple[str, ...], Any]


def _leaves(value: Mapping[str, Any], path: tuple[str, ...], out: _Leaves) -> _Leaves:
    """The leaves of a mapping into ``out``, by their key paths (a function call per mapping, not per leaf)."""
    for k, v in value.items():
        p = (*path, str(k))
        if v and (type(v) is dict or isinstance(v, Mapping)):
            _leaves(v, p, out)
        else:
            out[p] = v
    return out


def _leaf_delta(a: _Leaves, b: _Leaves) -> list[list[Any]] | None:
    if a.keys() != b.keys():
        return None
    return [[*p, v] for p, v in b.items() if a[p] != v or type(a[p]) is not type(v)]


def config_delta(base: Mapping[str, Any], config: Mapping[str, Any]) -> list[list[Any]] | None:
    """The leaves of ``config`` that differ from ``base``: ``[[key, ..., value], ...]``.

    A leaf is a value that is not a non-empty mapping (a number, a string, a list, ``{}``).
    ``None`` when the two configurations do not have the same leaves (then the run is given in full).
    """
    return _leaf_delta(_leaves(base, (), {}), _leaves(config, (), {}))


def chunk_spec(configs: Sequence[Mapping[str, Any]], logs: Sequence[str], timings: Sequence[str] | None,
               kind: str = "run", chunk_timings: str | None = None) -> dict[str, Any]:  # fmt: skip
    """The JSON argument of a chunk job: its runs' configurations and their output files.

    Each run is given as :func:`config_delta` from a *base*: the first run of the chunk with the same
    leaves (a straight line and an arc have different trajectory keys, so a chunk over several path
    shapes has one base per shape).

    Parameters
    ----------
    configs : sequence of mappings — the runs' full configurations, in the chunk's order
    logs : sequence of str — each run's log (``.mcap``)
    timings : sequence of str, or None — each run's own timings file (``.json``); None: none
    kind : str — ``"run"`` (dead reckoning) or ``"localization"``
    chunk_timings : str, optional — the chunk's timings file (every run's timings, by :func:`timings_key`)

    Returns
    -------
    dict — ``{"kind", "timings" (with ``chunk_timings``), "bases": [config, ...],
    "runs": [{"log", "timings" (with ``timings``), "base": index, "delta"}, ...]}``
    """
    if not configs or len(configs) != len(logs) or (timings is not None and len(timings) != len(logs)):
        raise ValueError(f"a chunk needs one log (and one timings file, if any) per run, got {len(configs)} runs, "
                         f"{len(logs)} logs and {'no' if timings is None else len(timings)} timings files")  # fmt: skip
    bases: list[dict[str, Any]] = []
    base_leaves: list[_Leaves] = []  # each base's leaves, found once
    runs: list[dict[str, Any]] = []
    for i, (config, log) in enumerate(zip(configs, logs, strict=True)):
        leaves = _leaves(config, (), {})
        found = next(((b, d) for b, d in ((b, _leaf_delta(a, leaves)) for b, a in enumerate(base_leaves)) if d is not None),
                     None)  # fmt: skip
        if found is None:
            found = (len(bases), [])
            bases.append(dict(config))
            base_leaves.append(leaves)
        runs.append({"log": log, **({} if timings is None else {"timings": timings[i]}), "base": found[0],
                     "delta": found[1]})  # fmt: skip
    return {"kind": kind, **({} if chunk_timings is None else {"timings": chunk_timings}), "bases": bases, "runs": runs}


def timings_key(log: str | os.PathLike[str]) -> str:
    """A run's key in its chunk's timings file: its log's file name (``<run id>.mcap``; a chunk holds
    runs of one set, whose ids differ)."""
    return Path(log).name


def read_timings(path: str | os.PathLike[str] | None, log: str | os.PathLike[str]) -> dict[str, float] | None:
    """The wall-clock timings [s] of the run logged in ``log``, from ``path``: the run's own timings file
    (``{<part>_s: seconds}``) or its chunk's (``{"runs": {<log file name>: {...}}}``).

    None when ``path`` is None or not a file; KeyError when a chunk's file does not hold the run. A chunk's
    file is read once for all its runs (kept while its size and modification time are unchanged).
    """
    if path is None or not Path(path).is_file():
        return None
    st = os.stat(path)
    data = _read_json_cached(os.fspath(path), st.st_mtime_ns, st.st_size)
    if isinstance(data.get("runs"), dict):
        try:
            return dict(data["runs"][timings_key(log)])
        except KeyError:
            raise KeyError(f"the chunk's timings file {os.fspath(path)!r} holds no run {timings_key(log)!r}") from None
    return dict(data)


@functools.lru_cache(maxsize=64)
def _read_json_cached(path: str, mtime_ns: int, size: int) -> dict[str, Any]:
    return json.loads(Path(path).read_text(encoding="utf-8"))  # type: ignore[no-any-return]


def run_configs(spec: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Every run's full configuration from a :func:`chunk_spec` (its inverse, in order)."""
    out: list[dict[str, Any]] = []
    for run in spec["runs"]:
        config = copy.deepcopy(dict(spec["bases"][run["base"]]))
        for *path, value in run["delta"]:
            node = config
            for key in path[:-1]:
                node = node[key]
            node[path[-1]] = copy.deepcopy(value)
        out.append(config)
    return out
