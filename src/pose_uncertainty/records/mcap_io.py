"""The MCAP container of every log kind: writing it deterministically, reading it with every CRC checked.

Writing
-------
:class:`LogWriter` wraps ``mcap.Writer``: chunked, zstd-compressed, with chunk, data-section
and summary CRCs, a fixed header ``library`` string (:data:`LIBRARY`), one schema per message
type and one channel per topic, deterministic protobuf serialisation. The same messages give
the same bytes.

Reading
-------
:func:`read_container` checks the kind of file, its size and its magic before reading anything
else, then reads it record by record (never whole), validates every chunk CRC, the
data-section CRC and the summary CRC (:func:`scan`), and checks that pose-uncertainty wrote it
(the header's library and the ``pose_uncertainty.run`` metadata record). It raises
:class:`RunLogError` (a ``ValueError`` with one line: ``"<path>: <problem>"``) for an empty,
truncated, corrupted or foreign file; with ``recover=True`` it keeps what an incomplete file
holds (whole, CRC-checked chunks only). :class:`Records` decodes the messages by topic against
their expected schemas.
"""

from __future__ import annotations

import io
import json
import os
import stat
import zlib
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
from google.protobuf.message import DecodeError
from mcap.opcode import Opcode
from mcap.records import Channel, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import build_file_descriptor_set
from numpy.typing import NDArray

from .. import __version__
from ..core.atomic import atomic_write
from .foxglove import F64, GRID_CELL, Metrics, NamedArrays

__all__ = [
    "LIBRARY",
    "MAGIC",
    "METADATA_NAME",
    "Container",
    "LogWriter",
    "PartialLogWarning",
    "Records",
    "RunLogError",
    "message_ns",
    "metadata_record",
    "read_container",
    "scan",
    "stream_bytes",
    "write_atomically",
]

LIBRARY = f"pose-uncertainty/{__version__}"
#: The metadata record of every log kind: its ``format``, configuration and provenance.
METADATA_NAME = "pose_uncertainty.run"
MAGIC = b"\x89MCAP0\r\n"
_FOOTER_RECORD = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, crc
#: Chunk size [bytes]: small enough that a partial file keeps most of its steps
#: (recovery reads whole chunks only), large enough for good zstd compression.
CHUNK_SIZE = 256 * 1024


class RunLogError(ValueError):
    """A run log cannot be read; the message is one line: ``"<path>: <problem>"``."""


class PartialLogWarning(UserWarning):
    """Issued when :func:`~pose_uncertainty.records.formats.open_run` recovers data from an incomplete log."""


# --- writing -----------------------------------------------------------------------------


class LogWriter:
    """Thin wrapper over mcap.Writer: one schema per message type, one channel per topic.

    ``LogWriter(stream, metadata)`` starts the file and writes the ``pose_uncertainty.run``
    metadata record; :meth:`put` adds one message; :meth:`finish` writes the summary.
    """

    def __init__(self, stream: Any, metadata: dict[str, str]) -> None:
        self.w = McapWriter(
            stream,
            chunk_size=CHUNK_SIZE,
            compression=CompressionType.ZSTD,
            enable_crcs=True,
            enable_data_crcs=True,
        )
        self.w.start(profile="", library=LIBRARY)
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        self.seq: Counter[str] = Counter()
        self.w.add_metadata(METADATA_NAME, metadata)

    def channel(self, topic: str, cls: Any) -> int:
        if topic not in self.channels:
            name = cls.DESCRIPTOR.full_name
            if name not in self.schemas:
                fds = build_file_descriptor_set(cls)
                self.schemas[name] = self.w.register_schema(
                    name=name, encoding="protobuf", data=fds.SerializeToString(deterministic=True)
                )
            self.channels[topic] = self.w.register_channel(
                topic=topic, message_encoding="protobuf", schema_id=self.schemas[name]
            )
        return self.channels[topic]

    def put(self, topic: str, msg: Any, t_ns: int) -> None:
        cid = self.channel(topic, type(msg))
        self.w.add_message(
            channel_id=cid,
            log_time=t_ns,
            publish_time=t_ns,
            sequence=self.seq[topic],
            data=msg.SerializeToString(deterministic=True),
        )
        self.seq[topic] += 1

    def finish(self) -> None:
        self.w.finish()


def metadata_record(head: dict[str, str], config: Any, n_steps: int, extra: dict[str, str],
                    provenance: dict[str, Any]) -> dict[str, str]:  # fmt: skip
    """The ``pose_uncertainty.run`` record: ``head`` (format, version), the config with its units, seed,
    number of steps, the kind's ``extra`` keys, then the provenance (sorted) and the package version."""
    meta = {
        **head,
        "config": json.dumps(config.to_dict(), sort_keys=True, separators=(",", ":")),
        "config_units": json.dumps(config.units(), sort_keys=True, separators=(",", ":")),
        "seed": str(config.seed),
        "n_steps": str(n_steps),
        **extra,
    }
    for key, value in sorted(provenance.items()):
        meta[key] = str(value)
    meta.setdefault("package_version", __version__)
    return meta


def stream_bytes(write: Callable[..., None], *args: Any) -> bytes:
    """The bytes ``write(stream, *args)`` writes, in memory (a log's bytes without a file)."""
    buf = io.BytesIO()
    write(buf, *args)
    return buf.getvalue()


def write_atomically(path: str | os.PathLike[str], write: Callable[..., None], *args: Any) -> Path:
    """Run ``write(stream, *args)`` into ``path`` atomically; return ``path``.

    The log is written to a hidden temporary file beside ``path``
    (``.<name>.<host>-<pid>-<random>.part``), flushed and fsynced, then renamed over ``path``
    (:func:`pose_uncertainty.core.atomic.atomic_write`; the parent directory is created if
    missing). An interrupted write never leaves a file at ``path``: on an exception the
    temporary file is removed; a killed process leaves only the ``.part`` file, which
    :func:`read_container` rejects as truncated and ``recover=True`` can read.
    """
    with atomic_write(path, "wb") as fh:
        write(fh, *args)
    return Path(path)


# --- reading -----------------------------------------------------------------------------


def _size(stream: IO[bytes]) -> int:
    here = stream.tell()
    size = stream.seek(0, os.SEEK_END)
    stream.seek(here)
    return size


def _read_at(stream: IO[bytes], offset: int, n: int) -> bytes:
    stream.seek(offset)
    return stream.read(n)


class _StrictReader(StreamReader):
    """The MCAP stream reader, refusing record opcodes the format does not define.

    ``mcap``'s reader skips an unknown record; a run of zero bytes would then be read as
    millions of empty records (a file of zeros after a valid start never ends). This
    project's writer writes only the format's records.
    """

    def _read_record(self, opcode: int, length: int) -> Any:
        if opcode not in _OPCODES:
            raise ValueError(f"record opcode {opcode:#04x} is not an MCAP record")
        return super()._read_record(opcode, length)


_OPCODES = frozenset(int(o) for o in Opcode)


def scan(data: bytes | IO[bytes]) -> tuple[list[Any], str | None]:
    """Read every record, validating chunk and data-section CRCs; stop at the first problem.

    Parameters
    ----------
    data : the file's bytes, or a seekable binary file object (read record by record: the file
        is never held whole in memory)

    Returns the records read so far (chunk contents only for whole, CRC-valid
    chunks) and a description of the problem, or None if the file is complete.
    """
    stream: IO[bytes] = io.BytesIO(data) if isinstance(data, (bytes, bytearray, memoryview)) else data
    size = _size(stream)
    reader = _StrictReader(stream, validate_crcs=True, record_size_limit=size)
    records: list[Any] = []
    try:
        for rec in reader.records:  # one by one: keep what precedes a failure
            records.append(rec)  # noqa: PERF402
    except CRCValidationError as exc:
        what = type(exc.record).__name__
        return (
            records,
            f"corrupted: CRC mismatch in {what} record (stored {exc.expected:#010x}, computed {exc.actual:#010x})",
        )
    except Exception as exc:  # noqa: BLE001 - any parse failure of foreign bytes is a damaged file
        return records, _parse_failure(stream, size, stream.tell(), exc)
    return records, _summary_problem(stream, size, records)


def _parse_failure(stream: IO[bytes], size: int, pos: int, exc: Exception) -> str:
    """What an unreadable record at byte ``pos`` means: a damaged magic, a truncation or corruption."""
    tail = _read_at(stream, max(0, size - len(MAGIC)), len(MAGIC))
    if len(tail) == len(MAGIC) and 0 < sum(a != b for a, b in zip(tail, MAGIC, strict=True)) <= 2:
        return "corrupted: damaged MCAP magic at the end of the file"
    if tail != MAGIC:
        return f"truncated: the file ends at byte {size} inside an MCAP record (no footer)"
    detail = "a record runs past the end of the file" if pos >= size else (str(exc) or type(exc).__name__)
    return f"corrupted: unreadable MCAP record near byte {pos} ({detail})"


def _summary_problem(stream: IO[bytes], size: int, records: list[Any]) -> str | None:
    """The footer, the data end and the summary CRC of a file whose records all parsed."""
    footer = records[-1] if records else None
    if not isinstance(footer, Footer):
        return "corrupted: no MCAP footer record"
    if not any(isinstance(r, DataEnd) for r in records):
        return "corrupted: no DataEnd record (the data section is damaged)"
    if footer.summary_crc != 0:
        footer_at = size - len(MAGIC) - _FOOTER_RECORD
        start = footer.summary_start or footer_at
        if not 0 < start <= footer_at:
            return f"corrupted: summary offset {footer.summary_start} is outside the file"
        stream.seek(start)
        crc, left = 0, footer_at - start
        while left > 0:
            block = stream.read(min(left, 1 << 20))
            if not block:
                return "truncated: the summary section ends early"
            crc, left = zlib.crc32(block, crc), left - len(block)
        crc = zlib.crc32(_read_at(stream, footer_at, 1 + 8 + 16), crc)
        if crc != footer.summary_crc:
            return (
                f"corrupted: CRC mismatch in the summary section "
                f"(stored {footer.summary_crc:#010x}, computed {crc:#010x})"
            )
    return None


def _describe_start(data: bytes) -> str:
    head = data[:24]
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        return f"starts with bytes {head[:8].hex(' ')}"
    if text.isprintable() or all(c.isprintable() or c.isspace() for c in text):
        return f"starts with text {text.strip()[:20]!r}"
    return f"starts with bytes {head[:8].hex(' ')}"


@dataclass(frozen=True)
class Container:
    """The CRC-checked records of a pose-uncertainty log, its header's library and its metadata record."""

    path: Path
    records: list[Any]
    library: str
    metadata: dict[str, str]
    partial: bool
    problem: str | None


_KINDS = ((stat.S_ISDIR, "is a directory"), (stat.S_ISFIFO, "is a FIFO (named pipe)"),
          (stat.S_ISSOCK, "is a socket"), (stat.S_ISCHR, "is a character device"),
          (stat.S_ISBLK, "is a block device"))  # fmt: skip


def _open_log(p: Path) -> IO[bytes]:
    """Open a log for reading after checking, without reading it, that it can be one.

    The kind of file (a regular file: a FIFO or a device such as ``/dev/zero`` would never end),
    its size (empty, shorter than the magic) and the MCAP magic at its start (24 bytes read) are
    checked first; the file is then read record by record by :func:`scan`.
    """
    try:
        st = p.stat()
    except FileNotFoundError:
        raise RunLogError(f"{p}: no such file") from None
    except OSError as exc:
        raise RunLogError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        what = next((w for test, w in _KINDS if test(st.st_mode)), "is not a regular file")
        raise RunLogError(f"{p}: {what}, not a run log (a run log is a regular *.mcap file)")
    if st.st_size == 0:
        raise RunLogError(f"{p}: empty file (0 bytes), not a run log")
    try:
        fh = p.open("rb")
    except OSError as exc:
        raise RunLogError(f"{p}: cannot read ({exc.strerror or exc})") from None
    try:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):  # replaced since the check
            raise RunLogError(f"{p}: not a regular file, not a run log")
        head = fh.read(24)
        if not head.startswith(MAGIC):
            if MAGIC.startswith(head):
                raise RunLogError(f"{p}: truncated: only {len(head)} bytes of the MCAP magic")
            raise RunLogError(f"{p}: not an MCAP file (no MCAP magic; {_describe_start(head)})")
        fh.seek(0)
    except BaseException:
        fh.close()
        raise
    return fh


def read_container(path: str | os.PathLike[str], *, recover: bool = False) -> Container:
    """Read and validate the MCAP container of a log (any kind); :class:`RunLogError` if it cannot be read.

    With ``recover`` an incomplete or damaged file gives what precedes the damage (whole,
    CRC-valid chunks only; ``partial=True``, ``problem`` says what is wrong) instead of raising.
    """
    p = Path(path)
    with _open_log(p) as fh:
        records, problem = scan(fh)
    if problem is not None and not recover:
        n_msgs = sum(isinstance(r, Message) for r in records)
        hint = f"; {n_msgs} messages before it can be recovered (replay --recover)" if n_msgs else ""
        raise RunLogError(f"{p}: {problem}{hint}")
    header = next((r for r in records if isinstance(r, Header)), None)
    if header is None:
        raise RunLogError(f"{p}: {problem or 'corrupted: no MCAP header'}; nothing recoverable")
    meta_rec = next((r for r in records if isinstance(r, Metadata) and r.name == METADATA_NAME), None)
    if not header.library.startswith("pose-uncertainty/") or meta_rec is None:
        if problem is not None and header.library.startswith("pose-uncertainty/"):
            raise RunLogError(f"{p}: {problem}; the run metadata is missing, nothing recoverable")
        raise RunLogError(
            f"{p}: not a pose-uncertainty run log (written by {header.library or 'an unnamed writer'!r}, "
            f"no {METADATA_NAME!r} metadata)"
        )
    return Container(p, records, header.library, dict(meta_rec.metadata), problem is not None, problem)


def message_ns(msg: Any) -> int:
    """A message's ``timestamp`` in integer nanoseconds."""
    return int(msg.timestamp.seconds) * 1_000_000_000 + int(msg.timestamp.nanos)


class Records:
    """The messages of a log by topic, decoded on demand against their expected schema."""

    def __init__(self, c: Container) -> None:
        self.p = p = c.path
        schemas = {r.id: r for r in c.records if isinstance(r, Schema)}
        channels = {r.id: r for r in c.records if isinstance(r, Channel)}
        self.by_topic: dict[str, list[Message]] = {}
        for r in c.records:
            if isinstance(r, Message):
                if r.channel_id not in channels:
                    raise RunLogError(f"{p}: message on unknown channel {r.channel_id}")
                self.by_topic.setdefault(channels[r.channel_id].topic, []).append(r)
        self.schema = {ch.topic: (schemas[ch.schema_id].name if ch.schema_id in schemas else "")
                       for ch in channels.values()}  # fmt: skip
        #: topic → (schema name, message count)
        self.topics = {t: (self.schema.get(t, ""), len(m)) for t, m in sorted(self.by_topic.items())}

    def decode(self, topic: str, cls: Any) -> list[Any]:
        """Every message on ``topic`` as a ``cls`` (a protobuf class); the topic's schema must be ``cls``'s."""
        msgs = self.by_topic.get(topic, [])
        expected = cls.DESCRIPTOR.full_name
        if msgs and self.schema.get(topic) != expected:
            raise RunLogError(f"{self.p}: topic {topic} has schema {self.schema.get(topic)!r}, expected {expected!r}")
        try:
            return [cls.FromString(m.data) for m in msgs]
        except DecodeError as exc:
            raise RunLogError(f"{self.p}: a message on {topic} is not a valid {expected} ({exc})") from None

    def cloud(self, msg: Any, columns: Sequence[str]) -> NDArray[np.float64]:
        """The rows (n, len(columns)) of a float64 point cloud (:func:`~.foxglove.float64_cloud`)."""
        layout = [(f.name, f.offset, f.type) for f in msg.fields]
        if msg.point_stride != 8 * len(columns) or layout != [(c, 8 * i, F64) for i, c in enumerate(columns)]:
            raise RunLogError(f"{self.p}: point cloud layout {layout} is not ({', '.join(columns)}) float64")
        return np.frombuffer(msg.data, dtype="<f8").reshape(-1, len(columns)).astype(np.float64)

    def grid_mass(self, msg: Any) -> NDArray[np.float64]:
        """The mass per cell (nx, ny) of a grid (:func:`~.foxglove.grid_msg`)."""
        rows = np.frombuffer(msg.data, dtype=GRID_CELL).reshape(-1, int(msg.column_count))
        return np.ascontiguousarray(rows["mass"].T, dtype=np.float64)

    def arrays(self, msg: Any) -> dict[str, NDArray[np.float64]]:
        """The named arrays of a ``pose_uncertainty.NamedArrays`` message (:func:`~.foxglove.arrays_msg`)."""
        out: dict[str, NDArray[np.float64]] = {}
        for item in msg.arrays:
            shape = tuple(int(s) for s in item.values.shape)
            v = np.frombuffer(item.values.data, dtype="<f8")
            if v.size != int(np.prod(shape)):
                raise RunLogError(f"{self.p}: array {item.name!r} holds {v.size} values, its shape says {shape}")
            out[item.name] = v.reshape(shape).astype(np.float64)
        return out

    def last_arrays(self, topic: str) -> dict[str, NDArray[np.float64]] | None:
        """The named arrays of the last message on ``topic``, or None when it has none."""
        msgs = self.decode(topic, NamedArrays)
        return self.arrays(msgs[-1]) if msgs else None

    def metrics(self, topic: str) -> tuple[dict[str, float], dict[str, str], dict[str, str]]:
        """Values, units and definitions of the last ``pose_uncertainty.Metrics`` on ``topic``."""
        msgs = self.decode(topic, Metrics)
        last = msgs[-1].metrics if msgs else []
        return ({m.name: float(m.value) for m in last}, {m.name: m.unit for m in last},
                {m.name: m.definition for m in last})  # fmt: skip
