"""One interface for every log kind: write / read / summary / verify, and the reader of them all.

Each kind of log (the dead-reckoning runs of :mod:`.run`, the localization runs of
:mod:`.localization`) is a :class:`LogFormat`, registered in :data:`FORMATS` under the
``format`` its metadata record carries. :func:`open_run` reads any log: it validates the
container (:func:`~.mcap_io.read_container`) and hands the records to the kind named in the
metadata, importing that kind's module the first time it meets one (so a job that writes one
dead-reckoning run does not pay for importing the localization code). :func:`verify_run`
recomputes any log under the reproducibility contract (:mod:`.reproducibility`).

The helpers below the registry are those every kind's summary and comparison share.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import math
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.provenance import PROVENANCE_KEYS, provenance
from .mcap_io import Container, PartialLogWarning, RunLogError, read_container
from .reproducibility import MISMATCH, Comparison, compare_log_bytes, environment_notes

__all__ = [
    "FORMATS",
    "LogFile",
    "LogFormat",
    "compare_dicts",
    "compare_measures",
    "diff",
    "flatten",
    "log_format",
    "open_run",
    "read_log",
    "recomputable",
    "register",
    "step_at",
    "summary_head",
    "summary_measures",
    "verify_log",
    "verify_recomputed",
    "verify_run",
]


@dataclass(frozen=True)
class LogFormat:
    """A kind of log: how it writes, reads back, summarises and verifies a result.

    Attributes
    ----------
    format, version : str
        The ``format`` and ``format_version`` of its metadata record.
    write : callable
        ``write(path, result, *, include_timings=False) -> Path``: atomically; the same result
        gives the same bytes.
    log_bytes : callable
        ``log_bytes(result, *, include_timings=False) -> bytes``: what ``write`` would write.
    assemble : callable
        ``assemble(container) -> log``: the log object of a validated container of this kind.
    summary : callable
        ``summary(log) -> str``: human-readable.
    verify : callable
        ``verify(log) -> Comparison``: recompute a complete log and compare every record.
    readable : tuple of str
        The ``format_version`` values read (default: ``version`` only); older ones are those
        whose records the current code still reads (the kind's module documents each version).
    """

    format: str
    version: str
    write: Callable[..., Path]
    log_bytes: Callable[..., bytes]
    assemble: Callable[[Container], Any]
    summary: Callable[[Any], str]
    verify: Callable[[Any], Comparison]
    readable: tuple[str, ...] = ()

    def read(self, path: str | os.PathLike[str], *, recover: bool = False) -> Any:
        """Read and validate a log of this kind (:func:`read_log`)."""
        return read_log(path, recover=recover, kind=self)


#: The log kinds, by the ``format`` of their metadata record (each module registers its own).
FORMATS: dict[str, LogFormat] = {}

#: The module that registers each kind, imported the first time a log of that kind is read.
_FORMAT_MODULES = {
    "pose-uncertainty-runlog": "pose_uncertainty.records.run",
    "pose-uncertainty-localization": "pose_uncertainty.records.localization",
}


def register(kind: LogFormat) -> LogFormat:
    """Add ``kind`` to :data:`FORMATS` (called once by the module that defines it)."""
    FORMATS[kind.format] = kind
    return kind


def log_format(fmt: object) -> LogFormat | None:
    """The kind of the logs whose metadata ``format`` is ``fmt`` (importing its module), or None."""
    key = str(fmt)
    if key not in FORMATS and key in _FORMAT_MODULES:
        importlib.import_module(_FORMAT_MODULES[key])  # registers FORMATS[key]
    return FORMATS.get(key)


def open_run(path: str | os.PathLike[str], *, recover: bool = False) -> Any:
    """Read and validate a log of any kind (:func:`read_log`).

    Parameters
    ----------
    path : path-like
    recover : bool
        If the file is incomplete (no footer, e.g. a ``.part`` file left by a
        killed run) or damaged, return what precedes the damage — whole,
        CRC-valid chunks only — and warn with :class:`PartialLogWarning`,
        instead of raising.

    Returns
    -------
    RunLog or LocalizationLog — by the ``format`` of the log's metadata

    Raises
    ------
    RunLogError
        One line, ``"<path>: <problem>"``: missing, empty, not MCAP, truncated,
        corrupted (CRC mismatch), or an MCAP not written by pose-uncertainty.
    """
    return read_log(path, recover=recover)


def read_log(path: str | os.PathLike[str], *, recover: bool = False, kind: LogFormat | None = None) -> Any:
    """Read and validate a log: of the kind its metadata names, which must be ``kind`` when given."""
    c = read_container(path, recover=recover)
    found = log_format(c.metadata.get("format"))
    if found is None or (kind is not None and found is not kind):
        raise RunLogError(f"{c.path}: not a pose-uncertainty run log (format {c.metadata.get('format')!r})")
    try:
        log = found.assemble(c)
    except RunLogError:
        raise
    except Exception as exc:  # noqa: BLE001 - a CRC-valid file with content we cannot decode
        raise RunLogError(
            f"{c.path}: not a valid pose-uncertainty run log ({type(exc).__name__}: {exc})"
        ) from None
    if c.problem is not None:
        counts = ", ".join(f"{t} {n}" for t, (_, n) in sorted(log.topics.items()))
        warnings.warn(
            f"{c.path}: partial log ({c.problem}); recovered {log.n_steps + 1} steps ({counts})",
            PartialLogWarning,
            stacklevel=3,
        )
    return log


def check_version(c: Container, kind: LogFormat, what: str) -> None:
    """:class:`RunLogError` unless the container's ``format_version`` is one ``kind`` reads (``what``: the log's name)."""
    readable = kind.readable or (kind.version,)
    if c.metadata.get("format_version") not in readable:
        raise RunLogError(
            f"{c.path}: {what} format version {c.metadata.get('format_version')!r} is not supported "
            f"(this reader: {', '.join(readable)})"
        )


def recomputable(log: Any) -> None:
    """Raise :class:`RunLogError` (one line) if this machine cannot recompute ``log`` to compare.

    A log made with another *major* version of numpy is refused: a major version may change
    numpy's semantics (type promotion, the random distributions' algorithms), so a
    recomputation here would differ for reasons the reproducibility contract does not cover.
    """
    logged = log.provenance.get("numpy_version", "")
    if logged and logged.split(".")[0] != np.__version__.split(".")[0]:
        lock = log.provenance.get("environment_lock_sha256", "unknown")
        raise RunLogError(
            f"{log.path}: written with numpy {logged}, this machine has numpy {np.__version__}; a "
            f"different major version changes numpy's semantics, so the run is not recomputed here "
            f"(verify it in the environment of its lock, sha256 {lock[:12]})"
        )


def verify_run(log: Any) -> Comparison:
    """Recompute a logged run (any kind) from its config and seed and compare every record of its log.

    The fresh log is written with the logged provenance and timings, so that on the machine
    that made the log the bytes are identical; on another machine every message of every
    topic is decoded and compared field by field within the contract's tolerance
    (:func:`~pose_uncertainty.records.reproducibility.compare_log_bytes`).

    Returns
    -------
    Comparison — ``status`` identical, equal within tolerance, or mismatch

    Raises
    ------
    RunLogError
        The log cannot be recomputed here (another numpy major version).
    """
    if log.partial:
        return Comparison(status=MISMATCH, mismatches=["the log is partial; a partial log cannot be verified"])
    recomputable(log)
    kind = log_format(log.metadata.get("format"))
    if kind is None:
        raise RunLogError(f"{log.path}: not a pose-uncertainty run log (format {log.metadata.get('format')!r})")
    return kind.verify(log)


def verify_recomputed(log: Any, fresh: Any, log_bytes: Callable[..., bytes]) -> Comparison:
    """Compare ``log`` with ``fresh``, its recomputation, logged by ``log_bytes`` as ``log`` was.

    The fresh log is written with the logged provenance and timings, so that on the machine
    that made the log the bytes are identical (:func:`verify_log`). A partial log is a mismatch.
    """
    if log.partial:
        return Comparison(status=MISMATCH, mismatches=["the log is partial; a partial log cannot be verified"])
    same = dataclasses.replace(fresh, provenance=dict(log.provenance), timings=dict(log.timings))
    return verify_log(log, log_bytes(same, include_timings=bool(log.timings)))


def verify_log(log: Any, fresh_bytes: bytes) -> Comparison:
    """Compare ``log``'s file with ``fresh_bytes``, a fresh log of its recomputation.

    The three outcomes of the reproducibility contract
    (:mod:`pose_uncertainty.records.reproducibility`): identical bytes; every record equal
    within tolerance; a mismatch. Notes say what differs in the machine and libraries
    (the log's provenance against this machine's) and what is not compared (timings).
    """
    comparison = compare_log_bytes(log.path.read_bytes(), fresh_bytes, n_steps=log.n_steps)
    if log.timings:
        comparison.notes.append("the wall-clock timings (/timings) are not reproducible: not compared")
        comparison.compared.pop("/timings", None)
        comparison.not_compared["/timings"] = "wall-clock, not reproducible; the recomputation reuses the logged ones"
    comparison.notes.extend(environment_notes(log.provenance, provenance()))
    return comparison


# --- what every log object holds ----------------------------------------------------------


@dataclass(frozen=True, eq=False, kw_only=True)
class LogFile:
    """What a log read back says beyond its result (a base of every kind's log class).

    Attributes
    ----------
    path : Path
    metadata : dict of str to str — the ``pose_uncertainty.run`` metadata record
    library : str — the MCAP header's library string
    topics : dict of str to (schema name, message count)
    partial : bool — True when recovered from an incomplete or damaged file
    problems : tuple of str — what recovery found wrong
    """

    path: Path = Path()
    metadata: dict[str, str] = field(default_factory=dict)
    library: str = ""
    topics: dict[str, tuple[str, int]] = field(default_factory=dict)
    partial: bool = False
    problems: tuple[str, ...] = ()


def file_fields(c: Container, topics: dict[str, tuple[str, int]]) -> dict[str, Any]:
    """The :class:`LogFile` fields of a log read from ``c``, and its provenance."""
    return {"provenance": {k: c.metadata[k] for k in PROVENANCE_KEYS if k in c.metadata}, "path": c.path,
            "metadata": c.metadata, "library": c.library, "topics": topics, "partial": c.partial,
            "problems": (c.problem,) if c.problem else ()}  # fmt: skip


def step_at(times: np.ndarray, t: float) -> int:
    """The last step of ``times`` (N+1,) at or before simulated time ``t`` [s]; ValueError outside the run."""
    if not math.isfinite(t) or times.size == 0:
        raise ValueError(f"time must be finite, got {t!r}")
    t0, t1 = float(times[0]), float(times[-1])
    if not t0 <= t <= t1 + 1e-12:
        raise ValueError(f"time must be within the run (allowed: [{t0:g}, {t1:g}] s), got {t!r}")
    return int(np.searchsorted(times, t + 1e-12, side="right") - 1)


# --- summaries --------------------------------------------------------------------------------


def flatten(value: Any, units: Any, prefix: str = "") -> list[str]:
    """``key.sub = value [unit]`` lines of a nested config mapping."""
    if isinstance(value, dict):
        out: list[str] = []
        for key in value:
            sub_units = units.get(key, "") if isinstance(units, dict) else ""
            out.extend(flatten(value[key], sub_units, f"{prefix}{key}."))
        return out
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        out = []
        for i, v in enumerate(value):
            out.extend(flatten(v, units, f"{prefix[:-1]}[{i}]."))
        return out
    unit = units if isinstance(units, str) and units not in ("", "-") else ""
    text = json.dumps(value)
    return [f"{prefix[:-1]} = {text}" + (f"  [{unit}]" if unit else "")]


def summary_head(log: Any, title: str, extra: Sequence[str] = ()) -> list[str]:
    """First lines of every summary: ``title`` and path, partial, writer, provenance, ``extra``, config, topics."""
    lines = [f"{title} {log.path}"]
    if log.partial:
        lines.append(f"PARTIAL   {'; '.join(log.problems)}")
    lines.append(f"written by {log.library}; format {log.metadata.get('format')} v{log.metadata.get('format_version')}")
    lines.extend(f"  {k}: {log.provenance[k]}" for k in PROVENANCE_KEYS if k in log.provenance)
    lines.extend(extra)
    lines.append("config")
    lines.extend(f"  {ln}" for ln in flatten(log.config.to_dict(), log.config.units()))
    lines.append("topics")
    width = max((len(t) for t in log.topics), default=0)
    lines.extend(f"  {t:<{width}}  {c:>7}  {s}" for t, (s, c) in log.topics.items())
    return lines


def summary_measures(log: Any) -> list[str]:
    """Last lines of every summary: the metrics with their units, the timings."""
    lines = []
    if log.metrics:
        lines.append("metrics")
        lines.extend(f"  {k} = {log.metrics[k]:.9g} {log.metric_units.get(k, '')}".rstrip() for k in sorted(log.metrics))
    if log.timings:
        lines.append("timings (wall clock, not reproducible)")
        lines.extend(f"  {k} = {log.timings[k]:.4g} s" for k in sorted(log.timings))
    return lines


# --- comparisons ------------------------------------------------------------------------------


def diff(name: str, a: Any, b: Any) -> str | None:
    """One line saying how arrays ``a`` and ``b`` differ (NaN equals NaN), or None when equal."""
    if a is None or b is None:
        return None if a is None and b is None else f"{name}: present in one, missing in the other"
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        return f"{name}: shape {a.shape} != {b.shape}"
    if np.array_equal(a, b, equal_nan=True):
        return None
    if a.dtype.kind == "f" and b.dtype.kind == "f":
        d = np.abs(a - b)
        k = int(np.count_nonzero(~((a == b) | (np.isnan(a) & np.isnan(b)))))
        return f"{name}: {k} of {a.size} values differ (max |diff| {np.nanmax(d):.3e})"
    return f"{name}: differs"


def compare_dicts(what: str, a: dict[Any, Any], b: dict[Any, Any]) -> list[str]:
    """:func:`diff` of two dicts of arrays, key by key (one line when the keys differ)."""
    if sorted(a) != sorted(b):
        return [f"{what}: keys {sorted(a)} != {sorted(b)}"]
    return [d for k in sorted(a) if (d := diff(f"{what}[{k}]", a[k], b[k]))]


def compare_measures(logged: Any, fresh: Any) -> list[str]:
    """The metrics (bit-exact, NaN equals NaN) and, as ``"note: "`` lines, the provenance of two results."""
    out: list[str] = []
    if sorted(logged.metrics) != sorted(fresh.metrics):
        out.append(f"metrics: keys {sorted(logged.metrics)} != {sorted(fresh.metrics)}")
    else:
        for key in sorted(logged.metrics):
            va, vb = logged.metrics[key], fresh.metrics[key]
            if not (va == vb or (math.isnan(va) and math.isnan(vb))):
                out.append(f"metric {key}: logged {va!r} != recomputed {vb!r}")
    for key in sorted(set(logged.provenance) | set(fresh.provenance)):
        pa, pb = logged.provenance.get(key), fresh.provenance.get(key)
        if pa != pb:
            out.append(f"note: {key} logged {pa!r}, now {pb!r}")
    return out
