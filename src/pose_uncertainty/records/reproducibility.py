"""The reproducibility contract: what a log recomputed on another machine must equal.

The contract
------------
*Same machine, same* ``environment.lock``: a run's log is byte-identical, and so are the
tables, claims and figures made from it.

*Another machine, same lock*: every logged number equals its recomputation within
:func:`relative_tolerance` of the quantity's scale, every non-numeric field (strings,
integers, counts, verdicts, topic and message layout) is identical.

Why the bytes differ between machines
-------------------------------------
IEEE-754 makes ``+ − × ÷ √`` correctly rounded, so every machine gets the same bits from
them. It does not do so for the transcendental functions: numpy sends ``sin``, ``cos``,
``exp``, ``log`` (and ``tan``, ``arctan2``, ``expm1``, ``log1p``, …) to AVX-512 vector kernels
on a CPU that has them (numpy's dispatch targets ``X86_V4``, ``AVX512_SKX``…) and to the
C library's scalar ``libm`` elsewhere. Both are within 1 ulp of the true value (numpy's own
accuracy tests, ``umath-validation-set-*.csv``; ``tanh`` 2 ulp), but not the *same* ulp, so
two machines can differ by up to 2 ulp, i.e. a relative 2⁻⁵¹ ≈ 4.4·10⁻¹⁶, per call. OpenBLAS
picks its kernels by CPU too (``Haswell``, ``SkylakeX``, …), which can change the order of the
few additions in a 3×3 product, a difference of the same size. A different glibc ``libm``
differs the same way.

How the tolerance follows from the computation
----------------------------------------------
Every quantity a run logs is computed by a recursion over its ``n`` steps (the pose and
covariance propagation, a filter's predict/correct, a map's convolutions), or from the
state after them. A step perturbs its state by at most ``c`` units of the unit round-off
``u = 2⁻⁵³`` relative to the state's scale (the per-call difference above, times the few
transcendental terms a step combines: ``c ≤ 8``), and the recursions are *linear* in such
perturbations and non-expanding at the scale of the quantity (a covariance recursion
``Σ' = J Σ Jᵀ + Q`` propagates an error ``δΣ`` as ``J δΣ Jᵀ``; the heading is a sum and so
the position error it causes is at most the path length times the heading error). The
perturbations therefore add up at most linearly: after ``n`` steps the relative error is at
most ``c·u·n``. What a run does once, whatever its steps, adds a fixed depth: sums over
up to 10⁷ particles or cells (numpy's pairwise summation: ``log₂ 10⁷ ≈ 23`` levels), a map's
FFTs over up to 2²⁰ cells (20 levels), the eigen-decompositions of 3×3 matrices; ``D = 64``
covers them. The tolerance takes ``c = GROWTH = 64``, a factor 8 of margin over ``c ≤ 8``::

    rtol(n) = 64 · 2⁻⁵³ · (n + 64)      (1.1·10⁻¹² at 100 steps, 7.1·10⁻¹¹ at 10⁴ steps)

compared against the *quantity's scale*: the largest magnitude of that field over the whole
topic (the 3×3 covariances of all steps, the x and y of a path together, a point cloud's
x and y columns, all metrics of one unit), and at least 1 for a heading (rad) or a
dimensionless measure. A relative measure of a value near zero (``y`` of a straight path,
an off-diagonal covariance) is thus judged at the scale of its neighbours, not of itself.

Monte Carlo runs draw the same noise on every machine: numpy's generators are
integer-exact, so the particles differ only through the arithmetic above, ~10⁻¹⁴ of the
cloud's extent (measured: see the closing table of ``tests/test_reproducibility.py``).

What the tolerance cannot cover
-------------------------------
A discrete decision taken on a value within the tolerance of its threshold — a particle
exactly on an HDR region's boundary, a resampling draw on the edge between two particles'
cumulative weights, a grey level rounding at one half — can come out the other way. Its
probability is the number of such decisions times the relative width ``rtol`` of the band
around the threshold: for 10⁴ particles and 10³ steps, 10⁷ decisions × 10⁻¹² ≈ 10⁻⁵. Such a
flip shows as a *mismatch* (a count, a verdict, or everything a resampled particle filter
does after the flip), never as a silent pass.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from mcap.records import Channel, Header, Message, Metadata, Schema
from mcap_protobuf.decoder import DecoderFactory

from ..core.provenance import MACHINE_KEYS
from .mcap_io import scan

__all__ = [
    "FIXED_DEPTH",
    "GROWTH",
    "IDENTICAL",
    "MISMATCH",
    "UNIT_ROUNDOFF",
    "WITHIN_TOLERANCE",
    "Comparison",
    "compare_log_bytes",
    "environment_notes",
    "relative_tolerance",
]

#: The unit round-off of IEEE-754 binary64, 2⁻⁵³.
UNIT_ROUNDOFF = 2.0**-53
#: Relative perturbation per step, in units of :data:`UNIT_ROUNDOFF`, that the tolerance allows
#: (8 × the ≤ 8 a step's transcendental terms can differ by between two machines).
GROWTH = 64
#: Steps' worth of depth of what a run computes once (sums over particles and cells, FFTs).
FIXED_DEPTH = 64

IDENTICAL, WITHIN_TOLERANCE, MISMATCH = "identical", "equal within tolerance", "mismatch"

#: Field names whose scale is at least 1: headings and angles [rad].
_ANGLE_FIELDS = frozenset({"theta", "yaw", "alpha", "heading"})
#: Sibling fields judged at a common scale (a point's coordinates).
_VECTOR_FIELDS = frozenset({"x", "y", "z"})
#: Metrics in these units are judged at a scale of at least 1.
_UNIT_ONE = frozenset({"", "1", "-", "rad", "rad^2"})


def relative_tolerance(n_steps: int) -> float:
    """The largest relative difference the contract allows after ``n_steps`` steps.

    ``GROWTH · 2⁻⁵³ · (n_steps + FIXED_DEPTH)``: the per-step difference between two
    machines' transcendental functions, added up linearly over the steps, plus the fixed
    depth of what a run computes once (see the module's text).

    Parameters
    ----------
    n_steps : int
        Steps of the run (its recursion depth), ``>= 0``.

    Returns
    -------
    float — relative to the quantity's scale [1]
    """
    if n_steps < 0:
        raise ValueError(f"n_steps must be >= 0, got {n_steps}")
    return GROWTH * UNIT_ROUNDOFF * (n_steps + FIXED_DEPTH)


# --- the comparison ---------------------------------------------------------------------------


@dataclass
class Comparison:
    """The outcome of comparing a log with a fresh log of its recomputation.

    Attributes
    ----------
    status : str
        :data:`IDENTICAL` (the bytes are equal), :data:`WITHIN_TOLERANCE` (every record
        compared; numbers within ``tolerance``) or :data:`MISMATCH`.
    tolerance : float
        The relative tolerance used [1].
    worst : float
        The largest relative difference of any number, of its quantity's scale [1].
    worst_at : str
        Where ``worst`` occurs (topic, field, message).
    mismatches, notes : list of str
        One line each: differences beyond the contract; facts that are not differences.
    compared : dict of str to int
        What was compared: messages per topic, metadata keys.
    not_compared : dict of str to str
        What the log holds that was not compared, and why (the header's library string of
        another version, wall-clock timings). An outcome with anything here is never reported
        as identical.
    """

    status: str = IDENTICAL
    tolerance: float = 0.0
    worst: float = 0.0
    worst_at: str = ""
    mismatches: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    compared: dict[str, int] = field(default_factory=dict)
    not_compared: dict[str, str] = field(default_factory=dict)


@dataclass
class _Group:
    """Numbers of one quantity (they share a scale): (label, logged, fresh) triples."""

    floor: float
    items: list[tuple[str, np.ndarray, np.ndarray]] = field(default_factory=list)


class _Walk:
    """Collects the numbers of two decoded messages by quantity; other fields must be equal."""

    def __init__(self) -> None:
        self.groups: dict[str, _Group] = {}
        self.mismatches: list[str] = []
        self.digests: list[str] = []

    def number(self, group: str, label: str, a: Any, b: Any, floor: float = 0.0) -> None:
        g = self.groups.setdefault(group, _Group(floor))
        g.items.append((label, np.asarray(a, dtype=np.float64).ravel(), np.asarray(b, dtype=np.float64).ravel()))

    def exact(self, label: str, a: Any, b: Any) -> None:
        if a != b:
            self.mismatches.append(f"{label}: logged {_short(a)}, recomputed {_short(b)}")

    # -- protobuf messages --

    def message(self, topic: str, path: str, label: str, a: Any, b: Any) -> None:
        fields = {f.name for f in a.DESCRIPTOR.fields}
        if "data" in fields and "fields" in fields and ("point_stride" in fields or "cell_stride" in fields):
            self._packed(topic, path, label, a, b)
            fields -= {"data"}
        elif {"shape", "data"} == fields:  # pose_uncertainty.Float64Array
            self.exact(f"{label}.shape", list(a.shape), list(b.shape))
            self.number(f"{topic} {path}", label, _f64(a.data), _f64(b.data))
            return
        for f in a.DESCRIPTOR.fields:
            if f.name not in fields:
                continue
            self.value(topic, f"{path}.{f.name}" if path else f.name, f"{label}.{f.name}", f,
                       getattr(a, f.name), getattr(b, f.name), parent=a)  # fmt: skip

    def value(self, topic: str, path: str, label: str, f: Any, a: Any, b: Any, parent: Any) -> None:
        repeated = f.is_repeated
        if f.type == f.TYPE_MESSAGE:
            if repeated:
                if len(a) != len(b):
                    self.mismatches.append(f"{label}: {len(a)} entries logged, {len(b)} recomputed")
                    return
                if f.message_type.name == "Metric":
                    for ma, mb in zip(a, b, strict=True):
                        self._metric(topic, label, ma, mb)
                    return
                for i, (ma, mb) in enumerate(zip(a, b, strict=True)):
                    self.message(topic, path, f"{label}[{i}]", ma, mb)
            else:
                self.message(topic, path, label, a, b)
        elif f.type in (f.TYPE_DOUBLE, f.TYPE_FLOAT):
            if repeated and len(a) != len(b):
                self.mismatches.append(f"{label}: {len(a)} values logged, {len(b)} recomputed")
                return
            name = f.name
            if name in _VECTOR_FIELDS and not repeated:
                group = f"{topic} {path.rsplit('.', 1)[0]}.(x,y,z)" if "." in path else f"{topic} (x,y,z)"
                if _is_quaternion(parent):
                    group = f"{topic} {path.rsplit('.', 1)[0]}.(quaternion)"
                self.number(group, label, a, b)
            elif name == "w" and _is_quaternion(parent):
                self.number(f"{topic} {path.rsplit('.', 1)[0]}.(quaternion)", label, a, b)
            else:
                self.number(f"{topic} {path}", label, list(a) if repeated else a, list(b) if repeated else b,
                            floor=1.0 if name in _ANGLE_FIELDS else 0.0)  # fmt: skip
        elif f.type == f.TYPE_STRING and f.name.endswith("_json") and not repeated:
            self._json(topic, path, label, a, b)
        else:
            self.exact(label, list(a) if repeated else a, list(b) if repeated else b)

    def _metric(self, topic: str, label: str, a: Any, b: Any) -> None:
        where = f"{label}[{a.name}]"
        self.exact(f"{where}.name", a.name, b.name)
        self.exact(f"{where}.unit", a.unit, b.unit)
        self.exact(f"{where}.definition", a.definition, b.definition)
        self.number(f"{topic} metrics in {a.unit or '1'}", f"{topic} metric {a.name} [{a.unit or '1'}]",
                    a.value, b.value, floor=1.0 if a.unit in _UNIT_ONE else 0.0)  # fmt: skip

    def _packed(self, topic: str, path: str, label: str, a: Any, b: Any) -> None:
        """A Foxglove PointCloud or Grid: its packed ``data`` decoded column by column."""
        stride = a.point_stride if hasattr(a, "point_stride") else a.cell_stride
        layout = [(f.name, f.offset, f.type) for f in a.fields]
        if layout != [(f.name, f.offset, f.type) for f in b.fields] or len(a.data) != len(b.data):
            self.mismatches.append(f"{label}: packed layout or size differs")
            return
        ca, cb = _columns(a.data, layout, stride), _columns(b.data, layout, stride)
        if ca is None or cb is None:
            self.exact(f"{label}.data", a.data, b.data)
            return
        for name, col in ca.items():
            other = cb[name]
            if col.dtype.kind == "f":
                group = f"{topic} {path}.(x,y)" if name in ("x", "y") else f"{topic} {path}.{name}"
                self.number(group, f"{label}.{name}", col, other, floor=1.0 if name in _ANGLE_FIELDS else 0.0)
            elif not np.array_equal(col, other):
                k = int(np.count_nonzero(col != other))
                self.mismatches.append(f"{label}.{name}: {k} of {col.size} values differ")

    def _json(self, topic: str, path: str, label: str, a: str, b: str) -> None:
        try:
            ja, jb = json.loads(a) if a else None, json.loads(b) if b else None
        except ValueError:
            self.exact(label, a, b)
            return
        self._tree(f"{topic} {path}", label, ja, jb)

    def _tree(self, group: str, label: str, a: Any, b: Any) -> None:
        if isinstance(a, dict) and isinstance(b, dict):
            if sorted(a) != sorted(b):
                self.mismatches.append(f"{label}: keys {sorted(a)} logged, {sorted(b)} recomputed")
                return
            for k in sorted(a):
                if k.endswith("sha256") and a[k] != b[k]:
                    self.digests.append(f"{label}[{k}]")
                    continue
                self._tree(f"{group}.{k}", f"{label}[{k}]", a[k], b[k])
        elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            for i, (x, y) in enumerate(zip(a, b, strict=True)):
                self._tree(group, f"{label}[{i}]", x, y)
        elif isinstance(a, float) and isinstance(b, float):
            self.number(group, label, a, b)
        else:
            self.exact(label, a, b)


def _is_quaternion(msg: Any) -> bool:
    return msg is not None and {f.name for f in msg.DESCRIPTOR.fields} == {"x", "y", "z", "w"}


def _f64(data: bytes) -> np.ndarray:
    return np.frombuffer(data, dtype="<f8") if len(data) % 8 == 0 else np.frombuffer(data, dtype=np.uint8)


#: foxglove.PackedElementField numeric types → numpy dtypes
_PACKED = {1: "u1", 2: "i1", 3: "<u2", 4: "<i2", 5: "<u4", 6: "<i4", 7: "<f4", 8: "<f8"}


def _columns(data: bytes, layout: list[tuple[str, int, int]], stride: int) -> dict[str, np.ndarray] | None:
    if stride <= 0 or len(data) % stride or any(t not in _PACKED for _, _, t in layout):
        return None
    dt = np.dtype({"names": [n for n, _, _ in layout], "formats": [_PACKED[t] for _, _, t in layout],
                   "offsets": [o for _, o, _ in layout], "itemsize": stride})  # fmt: skip
    rows = np.frombuffer(data, dtype=dt)
    return {n: np.asarray(rows[n]) for n, _, _ in layout}


def _short(v: Any) -> str:
    s = repr(v)
    return s if len(s) <= 80 else s[:77] + "..."


def _records(data: bytes) -> list[Any]:
    records, problem = scan(data)
    if problem is not None:
        raise ValueError(problem)
    return records


def _messages(records: Iterable[Any]) -> tuple[dict[str, tuple[Any, Any]], dict[str, list[Any]]]:
    """``topic → (channel, schema)`` and ``topic → messages`` in file order."""
    schemas = {r.id: r for r in records if isinstance(r, Schema)}
    channels = {r.id: r for r in records if isinstance(r, Channel)}
    by_topic: dict[str, list[Any]] = {ch.topic: [] for ch in channels.values()}
    for r in records:
        if isinstance(r, Message) and r.channel_id in channels:
            by_topic[channels[r.channel_id].topic].append(r)
    return ({ch.topic: (ch, schemas.get(ch.schema_id)) for ch in channels.values()}, by_topic)


def _compare_metadata(walk: _Walk, a: list[Any], b: list[Any], skip: frozenset[str], out: Comparison) -> None:
    ma = {r.name: dict(r.metadata) for r in a if isinstance(r, Metadata)}
    mb = {r.name: dict(r.metadata) for r in b if isinstance(r, Metadata)}
    walk.exact("metadata records", sorted(ma), sorted(mb))
    for name in sorted(set(ma) & set(mb)):
        ka, kb = set(ma[name]) - skip, set(mb[name]) - skip
        walk.exact(f"metadata {name} keys", sorted(ka), sorted(kb))
        for k in sorted(ka & kb):
            walk.exact(f"metadata {name}[{k}]", ma[name][k], mb[name][k])
        out.compared["metadata keys"] = out.compared.get("metadata keys", 0) + len(ka)


def _compare_topic(walk: _Walk, topic: str, ours: tuple[Any, Any], theirs: tuple[Any, Any],
                   ma: list[Any], mb: list[Any], decoders: DecoderFactory) -> None:  # fmt: skip
    (cha, sa), (chb, sb) = ours, theirs
    walk.exact(f"{topic}: message encoding", cha.message_encoding, chb.message_encoding)
    walk.exact(f"{topic}: channel metadata", dict(cha.metadata), dict(chb.metadata))
    if sa is None or sb is None or (sa.name, sa.encoding, sa.data) != (sb.name, sb.encoding, sb.data):
        walk.mismatches.append(
            f"{topic}: schema {sa.name if sa else None!r} differs from the recomputation's "
            f"{sb.name if sb else None!r}; its messages were not compared"
        )
        return
    if len(ma) != len(mb):
        walk.mismatches.append(f"{topic}: {len(ma)} messages logged, {len(mb)} recomputed")
        return
    decode = None
    for i, (x, y) in enumerate(zip(ma, mb, strict=True)):
        label = f"{topic}[{i}]"
        walk.exact(f"{label} time", (x.log_time, x.publish_time, x.sequence), (y.log_time, y.publish_time, y.sequence))
        if x.data == y.data:
            continue
        decode = decode or decoders.decoder_for(cha.message_encoding, sa)
        if decode is None:
            walk.mismatches.append(f"{label}: bytes differ (encoding {cha.message_encoding!r} not decodable)")
            continue
        try:
            a, b = decode(x.data), decode(y.data)
        except Exception as exc:  # noqa: BLE001 - undecodable bytes are a difference, named
            walk.mismatches.append(f"{label}: not a valid {sa.name} ({type(exc).__name__})")
            continue
        walk.message(topic, "", label, a, b)


def _judge(walk: _Walk, rtol: float, out: Comparison) -> None:
    """Each quantity's numbers against ``rtol`` of its scale; the worst difference overall."""
    for group, g in walk.groups.items():
        scale = max([g.floor] + [float(np.max(np.abs(a[np.isfinite(a)]), initial=0.0)) for _, a, _ in g.items])
        for label, a, b in g.items:
            same = (a == b) | (np.isnan(a) & np.isnan(b))
            if same.all():
                continue
            if a.shape != b.shape or not np.array_equal(np.isfinite(a), np.isfinite(b)):
                out.mismatches.append(f"{label}: non-finite values differ")
                continue
            d = float(np.max(np.abs(a - b)[~same]))
            rel = d / scale if scale > 0 else float("inf")
            if rel > out.worst:
                out.worst, out.worst_at = rel, f"{label} (quantity {group}, scale {scale:.3g})"
            if rel > rtol:
                k = int(np.count_nonzero(~same))
                out.mismatches.append(
                    f"{label}: {k} of {a.size} values differ by up to {d:.3e}, {rel:.2e} of the "
                    f"quantity's scale {scale:.3g} (tolerance {rtol:.2e})"
                )


def compare_log_bytes(logged: bytes, fresh: bytes, *, n_steps: int,
                      skip_metadata: Iterable[str] = ()) -> Comparison:  # fmt: skip
    """Compare a log's bytes with those of a fresh log of the recomputation, record by record.

    Every metadata key (except ``skip_metadata``), every topic with its schema, channel and
    message count, and every field of every message is compared: strings, integers and
    layouts exactly; numbers within :func:`relative_tolerance` ``(n_steps)`` of their
    quantity's scale (packed point clouds and grids column by column, JSON parameters key by
    key, metrics by unit). A digest (a ``*sha256`` key) that differs while the numbers it
    summarises agree within tolerance is a note: it is of numbers, and the numbers it stands
    for are compared through the log's other topics.

    Parameters
    ----------
    logged, fresh : bytes
        Two complete, CRC-valid MCAP logs.
    n_steps : int
        The run's number of steps (its recursion depth), for the tolerance.
    skip_metadata : iterable of str
        Metadata keys not compared (provenance: it says where each was made).

    Returns
    -------
    Comparison
    """
    out = Comparison(tolerance=relative_tolerance(n_steps))
    if logged == fresh:
        return out
    a, b = _records(logged), _records(fresh)
    walk = _Walk()
    ha = next((r for r in a if isinstance(r, Header)), None)
    hb = next((r for r in b if isinstance(r, Header)), None)
    if ha is not None and hb is not None and ha.library != hb.library:
        out.notes.append(f"written by {ha.library}, recomputed by {hb.library}")
        out.not_compared["the header's library"] = f"written by {ha.library}, recomputed by {hb.library}"
    _compare_metadata(walk, a, b, frozenset(skip_metadata), out)
    ta, ma = _messages(a)
    tb, mb = _messages(b)
    walk.exact("topics", sorted(ta), sorted(tb))
    decoders = DecoderFactory()
    for topic in sorted(set(ta) & set(tb)):
        _compare_topic(walk, topic, ta[topic], tb[topic], ma[topic], mb[topic], decoders)
        out.compared[topic] = len(ma[topic])
    out.mismatches.extend(walk.mismatches)
    _judge(walk, out.tolerance, out)
    if walk.digests:
        what = ", ".join(walk.digests)
        if out.mismatches:
            out.mismatches.append(f"{what}: digest differs")
        else:
            out.notes.append(
                f"{what}: the digest of a full (x, y, θ) array differs, as it must when its numbers differ "
                "in the last bits; the array's θ-marginal and every measure of it agree within tolerance"
            )
    out.status = MISMATCH if out.mismatches else WITHIN_TOLERANCE
    return out


def environment_notes(logged: Mapping[str, str], here: Mapping[str, str]) -> list[str]:
    """One line per machine or library key whose logged value differs from this machine's."""
    keys = (*MACHINE_KEYS, "python_version", "numpy_version", "scipy_version", "environment_lock_sha256")
    return [f"{k}: log {logged.get(k, 'not recorded')!r}, this machine {here.get(k)!r}"
            for k in keys if logged.get(k) != here.get(k)]  # fmt: skip


