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

This module imports nothing heavy: the workflow reads it while it builds its graph.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar

__all__ = ["chunk_runs", "chunk_spec", "config_delta", "run_configs"]

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


def _delta(a: _Leaves, b: _Leaves) -> list[list[Any]] | None:
    if a.keys() != b.keys():
        return None
    return [[*p, v] for p, v in b.items() if a[p] != v or type(a[p]) is not type(v)]


def config_delta(base: Mapping[str, Any], config: Mapping[str, Any]) -> list[list[Any]] | None:
    """The leaves of ``config`` that differ from ``base``: ``[[key, ..., value], ...]``.

    A leaf is a value that is not a non-empty mapping (a number, a string, a list, ``{}``).
    ``None`` when the two configurations do not have the same leaves (then the run is given in full).
    """
    return _delta(_leaves(base, (), {}), _leaves(config, (), {}))


def chunk_spec(configs: Sequence[Mapping[str, Any]], logs: Sequence[str], timings: Sequence[str],
               kind: str = "run") -> dict[str, Any]:  # fmt: skip
    """The JSON argument of a chunk job: its runs' configurations and their output files.

    Each run is given as :func:`config_delta` from a *base*: the first run of the chunk with the same
    leaves (a straight line and an arc have different trajectory keys, so a chunk over several path
    shapes has one base per shape).

    Parameters
    ----------
    configs : sequence of mappings — the runs' full configurations, in the chunk's order
    logs, timings : sequences of str — each run's log (``.mcap``) and timings (``.json``) file
    kind : str — ``"run"`` (dead reckoning) or ``"localization"``

    Returns
    -------
    dict — ``{"kind", "bases": [config, ...], "runs": [{"log", "timings", "base": index, "delta"}, ...]}``
    """
    if not configs or not len(configs) == len(logs) == len(timings):
        raise ValueError(f"a chunk needs one log and one timings file per run, got {len(configs)} runs, "
                         f"{len(logs)} logs and {len(timings)} timings files")  # fmt: skip
    bases: list[dict[str, Any]] = []
    base_leaves: list[_Leaves] = []  # each base's leaves, found once
    runs: list[dict[str, Any]] = []
    for config, log, tim in zip(configs, logs, timings, strict=True):
        leaves = _leaves(config, (), {})
        found = next(((b, d) for b, d in ((b, _delta(a, leaves)) for b, a in enumerate(base_leaves)) if d is not None),
                     None)  # fmt: skip
        if found is None:
            found = (len(bases), [])
            bases.append(dict(config))
            base_leaves.append(leaves)
        runs.append({"log": log, "timings": tim, "base": found[0], "delta": found[1]})
    return {"kind": kind, "bases": bases, "runs": runs}


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
