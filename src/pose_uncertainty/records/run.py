"""Run logs: one MCAP file per run, readable by Foxglove and by :func:`open_run`.

Format
------
MCAP (https://mcap.dev), chunked, zstd-compressed, with chunk, data-section and
summary CRCs. Messages are protobuf: Foxglove's well-known schemas for what the
3D panel draws, and four schemas of ours (package ``pose_uncertainty``) for the
exact float64 data. Log time = publish time = message timestamp = simulated time
(ns since the start of the run). Every message is in frame ``world``.

=================================  ==================================  ==========================
topic                              schema                              content
=================================  ==================================  ==========================
``/tf``                            foxglove.FrameTransform             world → base_link per step
``/robot/pose``                    foxglove.PoseInFrame                nominal pose per step
``/robot/path``                    foxglove.SceneUpdate                whole nominal path (black), t=0
``/covariance``                    pose_uncertainty.PoseCovariance2D   exact pose, time, 3×3 Σ per step
``/covariance/ellipse``            foxglove.SceneUpdate                Pr-ellipse per step (line loop)
``/monte_carlo/end_poses``         foxglove.PointCloud                 end poses, float64 x, y, theta
``/monte_carlo/checkpoints``       foxglove.PointCloud                 clouds at checkpoint steps
``/maps/<name>/grid``              foxglove.Grid                       θ-marginal mass + grey RGBA
``/maps/<name>/volume``            pose_uncertainty.ProbabilityMap3D   the full (x, y, θ) array
``/maps/<name>/sampler``           foxglove.PointCloud                 the map's own sampler's draws
``/metrics``                       pose_uncertainty.Metrics            every measure: value, unit, definition
``/timings``                       pose_uncertainty.Metrics            wall-clock timings (opt-in)
=================================  ==================================  ==========================

A metadata record ``pose_uncertainty.run`` holds the full configuration (JSON,
every parameter) with its units, the package version, the sha256 of
``environment.lock``, the seed and the git commit.

Determinism
-----------
The same result gives the same bytes: fixed header ``library`` string, times
from the simulation, deterministic protobuf serialisation, single-threaded zstd.
Timings are the only non-deterministic quantity; they are written (to
``/timings``) only when asked (``include_timings=True``, ``run --timings``). A
log written without timings is byte-identical for the same config, seed,
package version, environment, commit and machine. On another machine it agrees
within the reproducibility contract (:mod:`pose_uncertainty.records.reproducibility`),
which :func:`verify_run` checks record by record.

Reading
-------
:func:`open_run` reads the whole file, validates the magic, every chunk CRC, the
data-section CRC and the summary CRC, and raises :class:`RunLogError` (a
``ValueError`` with one line: ``"<path>: <problem>"``) for an empty, truncated,
corrupted or foreign file. ``open_run(path, recover=True)`` returns what an
incomplete file holds (whole, CRC-checked chunks only) and warns with
:class:`PartialLogWarning`.

Length
------
One module of about 1150 lines on purpose: it is the one interface of one log kind
(write, read, summary, verify). Writer and reader share the topic table, the message
schemas and the field conventions defined here; split apart, each half would import the
other's private message builders.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import io
import json
import math
import os
import warnings
import zlib
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.Grid_pb2 import Grid
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf import timestamp_pb2 as _timestamp_pb2  # registers the dependency
from google.protobuf.message import DecodeError
from mcap.records import Channel, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import build_file_descriptor_set
from numpy.typing import NDArray

from .. import __version__
from ..core.atomic import atomic_write
from ..core.provenance import PROVENANCE_KEYS, provenance
from ..experiments.config import RunConfig
from ..experiments.run import RunResult, execute
from ..methods import covariance
from ..methods.maps import ProbabilityMap
from .reproducibility import MISMATCH, Comparison, compare_log_bytes, environment_notes

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "LOG_KINDS",
    "TOPICS",
    "LogKind",
    "PartialLogWarning",
    "RunLog",
    "RunLogError",
    "compare_results",
    "format_summary",
    "log_bytes",
    "log_kind",
    "open_run",
    "recomputable",
    "stream_bytes",
    "verify_log",
    "verify_run",
    "write_run",
]

FORMAT = "pose-uncertainty-runlog"
FORMAT_VERSION = "2"
LIBRARY = f"pose-uncertainty/{__version__}"
METADATA_NAME = "pose_uncertainty.run"
WORLD, BASE = "world", "base_link"
MAGIC = b"\x89MCAP0\r\n"
_FOOTER_RECORD = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, crc

T_TF = "/tf"
T_POSE = "/robot/pose"
T_PATH = "/robot/path"
T_COV = "/covariance"
T_ELLIPSE = "/covariance/ellipse"
T_END = "/monte_carlo/end_poses"
T_CHECK = "/monte_carlo/checkpoints"
T_METRICS = "/metrics"
T_TIMINGS = "/timings"

#: Fixed topics and their schemas; per-map topics are ``/maps/<name>/grid`` and ``/volume``.
TOPICS: dict[str, str] = {
    T_TF: "foxglove.FrameTransform",
    T_POSE: "foxglove.PoseInFrame",
    T_PATH: "foxglove.SceneUpdate",
    T_COV: "pose_uncertainty.PoseCovariance2D",
    T_ELLIPSE: "foxglove.SceneUpdate",
    T_END: "foxglove.PointCloud",
    T_CHECK: "foxglove.PointCloud",
    T_METRICS: "pose_uncertainty.Metrics",
    T_TIMINGS: "pose_uncertainty.Metrics",
}

_ELLIPSE_POINTS = 48
#: Chunk size [bytes]: small enough that a partial file keeps most of its steps
#: (recovery reads whole chunks only), large enough for good zstd compression.
_CHUNK_SIZE = 256 * 1024
_BLUE = (0.0, 0.25, 1.0, 1.0)
_RED = (0.9, 0.0, 0.0, 1.0)
_GREY = (0.5, 0.5, 0.5, 0.8)
_BLACK = (0.0, 0.0, 0.0, 1.0)


class LogKind(NamedTuple):
    """Another kind of log in the same container (e.g. a localization run's), registered by its module.

    ``assemble(path, records, meta, library, partial, problem)`` builds the log object from the
    CRC-checked records and the metadata record; ``verify(log)`` recomputes it and returns the
    :class:`~pose_uncertainty.records.reproducibility.Comparison` as :func:`verify_run` does.
    """

    assemble: Callable[..., Any]
    verify: Callable[[Any], Comparison]


#: Log kinds beside the dead-reckoning run, by the ``format`` of their metadata record
#: (``pose_uncertainty.records.localization`` registers the localization runs).
LOG_KINDS: dict[str, LogKind] = {}

#: The module that registers each kind in :data:`LOG_KINDS`, imported the first time a log of
#: that kind is read (so that a job that only writes dead-reckoning runs never imports it).
_KIND_MODULES = {"pose-uncertainty-localization": "pose_uncertainty.records.localization"}


def log_kind(fmt: object) -> LogKind | None:
    """The reader of logs whose metadata ``format`` is ``fmt``, or ``None`` for a dead-reckoning run."""
    key = str(fmt)
    if key not in LOG_KINDS and key in _KIND_MODULES:
        importlib.import_module(_KIND_MODULES[key])  # registers LOG_KINDS[key]
    return LOG_KINDS.get(key)


class RunLogError(ValueError):
    """A run log cannot be read; the message is one line: ``"<path>: <problem>"``."""


class PartialLogWarning(UserWarning):
    """Issued when :func:`open_run` recovers data from an incomplete or damaged log."""


# --- our schemas -------------------------------------------------------------------------


#: Our messages: name → fields ``(name, type, repeated)``; a type is ``double``, ``string``,
#: ``uint32``, ``uint64``, ``bytes``, ``timestamp`` or another of these messages. Field numbers
#: follow the order (changing it changes the log format).
_MESSAGES: dict[str, list[tuple[str, str, bool]]] = {
    # exact pose and 3x3 covariance (row-major over x [m], y [m], theta [rad]) of one step
    "PoseCovariance2D": [("timestamp", "timestamp", False), ("frame_id", "string", False),
                         ("step", "uint32", False), ("time", "double", False), ("x", "double", False),
                         ("y", "double", False), ("theta", "double", False), ("covariance", "double", True)],
    # n-d float64 array: little-endian IEEE-754 bytes in C order
    "Float64Array": [("shape", "uint64", True), ("data", "bytes", False)],
    "ProbabilityMap3D": [("timestamp", "timestamp", False), ("frame_id", "string", False),
                         ("name", "string", False), ("model", "string", False), ("x", "double", True),
                         ("y", "double", True), ("theta", "double", True), ("values", "Float64Array", False),
                         ("lost_mass", "double", False), ("params_json", "string", False),
                         ("info_json", "string", False), ("center", "double", True)],
    "Metric": [("name", "string", False), ("value", "double", False), ("unit", "string", False),
               ("definition", "string", False)],
    "Metrics": [("timestamp", "timestamp", False), ("metrics", "Metric", True)],
}  # fmt: skip


def _our_schemas() -> dict[str, Any]:
    """Build (once) the protobuf classes of the ``pose_uncertainty`` schemas (:data:`_MESSAGES`)."""
    F = descriptor_pb2.FieldDescriptorProto
    scalars = {"double": F.TYPE_DOUBLE, "string": F.TYPE_STRING, "uint32": F.TYPE_UINT32,
               "uint64": F.TYPE_UINT64, "bytes": F.TYPE_BYTES}  # fmt: skip
    fdp = descriptor_pb2.FileDescriptorProto(
        name="pose_uncertainty/runlog.proto", package="pose_uncertainty", syntax="proto3"
    )
    fdp.dependency.append("google/protobuf/timestamp.proto")
    for name, fields in _MESSAGES.items():
        m = fdp.message_type.add(name=name)
        for number, (fname, ftype, repeated) in enumerate(fields, start=1):
            label = F.LABEL_REPEATED if repeated else F.LABEL_OPTIONAL
            f = m.field.add(name=fname, number=number, type=scalars.get(ftype, F.TYPE_MESSAGE), label=label)  # type: ignore[arg-type]
            if ftype not in scalars:
                f.type_name = ".google.protobuf.Timestamp" if ftype == "timestamp" else f".pose_uncertainty.{ftype}"
    pool = descriptor_pool.Default()
    try:
        pool.FindFileByName(fdp.name)
    except KeyError:
        pool.Add(fdp)
    return {n: message_factory.GetMessageClass(pool.FindMessageTypeByName(f"pose_uncertainty.{n}")) for n in _MESSAGES}


_S = _our_schemas()
PoseCovariance2D = _S["PoseCovariance2D"]
Float64Array = _S["Float64Array"]
ProbabilityMap3D = _S["ProbabilityMap3D"]
Metrics = _S["Metrics"]
_ = _timestamp_pb2

_CLASSES: dict[str, Any] = {
    cls.DESCRIPTOR.full_name: cls
    for cls in (
        FrameTransform,
        PoseInFrame,
        SceneUpdate,
        PointCloud,
        Grid,
        PoseCovariance2D,
        ProbabilityMap3D,
        Metrics,
    )
}


# --- small helpers -----------------------------------------------------------------------


def _ns(t: float) -> int:
    """Simulated time [s] → integer nanoseconds (≥ 0)."""
    return max(0, round(float(t) * 1e9))


def _stamp(msg: Any, t_ns: int) -> None:
    msg.timestamp.seconds, msg.timestamp.nanos = divmod(t_ns, 1_000_000_000)


def _color(c: Any, rgba: tuple[float, float, float, float]) -> None:
    c.r, c.g, c.b, c.a = rgba


def _yaw(q: Any, theta: float) -> None:
    """Set quaternion ``q`` to a rotation by ``theta`` [rad] about +z."""
    q.x, q.y = 0.0, 0.0
    q.z, q.w = math.sin(theta / 2.0), math.cos(theta / 2.0)


def _fields(names: Iterable[tuple[str, int, int]]) -> list[Any]:
    return [PackedElementField(name=n, offset=o, type=t) for n, o, t in names]  # type: ignore[arg-type]


_F64 = PackedElementField.FLOAT64
_U8 = PackedElementField.UINT8


def _cloud(poses: NDArray[np.float64], t_ns: int) -> Any:
    """A foxglove.PointCloud holding (x, y, theta) exactly as float64."""
    data = np.ascontiguousarray(poses, dtype="<f8")
    msg = PointCloud(
        frame_id=WORLD,
        point_stride=24,
        fields=_fields([("x", 0, _F64), ("y", 8, _F64), ("theta", 16, _F64)]),
        data=data.tobytes(),
    )
    _stamp(msg, t_ns)
    _yaw(msg.pose.orientation, 0.0)
    return msg


def _grid(mp: ProbabilityMap, t_ns: int) -> Any:
    """foxglove.Grid: θ-marginal mass per cell (float64, exact) and a grey RGBA, darker = more probable."""
    marg = mp.marginal_xy()  # (nx, ny) [1]
    nx, ny = marg.shape
    dx = float(mp.x[1] - mp.x[0]) if nx > 1 else 0.01
    dy = float(mp.y[1] - mp.y[0]) if ny > 1 else 0.01
    return _grid_msg(marg, float(mp.x[0]), float(mp.y[0]), dx, dy, t_ns)


def _grid_msg(marg: NDArray[np.float64], x0: float, y0: float, dx: float, dy: float, t_ns: int) -> Any:
    """foxglove.Grid of a mass per cell ``marg`` (nx, ny), cell ``[0, 0]`` centred at ``(x0, y0)``."""
    nx, ny = marg.shape
    peak = float(marg.max()) if marg.size and marg.max() > 0 else 1.0
    rel = np.clip(marg / peak, 0.0, 1.0)
    cell = np.dtype(
        [("mass", "<f8"), ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("alpha", "u1")]
    )
    rows = np.zeros((ny, nx), dtype=cell)  # row-major (y-major) order
    grey = np.round(255.0 * (1.0 - rel)).astype(np.uint8).T
    rows["mass"] = marg.T
    rows["red"] = rows["green"] = rows["blue"] = grey
    rows["alpha"] = np.where(rel.T > 1e-3, 255, 0).astype(np.uint8)
    msg = Grid(
        frame_id=WORLD,
        column_count=nx,
        row_stride=cell.itemsize * nx,
        cell_stride=cell.itemsize,
        fields=_fields(
            [
                ("mass", 0, _F64),
                ("red", 8, _U8),
                ("green", 9, _U8),
                ("blue", 10, _U8),
                ("alpha", 11, _U8),
            ]
        ),
        data=rows.tobytes(),
    )
    _stamp(msg, t_ns)
    msg.pose.position.x = x0 - dx / 2.0
    msg.pose.position.y = y0 - dy / 2.0
    _yaw(msg.pose.orientation, 0.0)
    msg.cell_size.x, msg.cell_size.y = dx, dy
    return msg


#: ``info`` key of a logged map read back without its full array: the sha256 of that array.
VOLUME_SHA256 = "volume_sha256"


def volume_sha256(values: NDArray[np.float64]) -> str:
    """sha256 (hex) of a map's full ``(x, y, θ)`` array as little-endian float64 in C order."""
    return hashlib.sha256(np.ascontiguousarray(values, dtype="<f8").tobytes()).hexdigest()


def logged_form(mp: ProbabilityMap) -> ProbabilityMap:
    """The map as its log holds it: itself with ``log_volume``, else its θ-marginal and digest.

    Without ``log_volume`` (the default) the log keeps the exact θ-marginal (one heading
    cell, ``theta = [nan]``) and the sha256 of the full array in ``info``; a map already
    in that form is returned as it is.
    """
    if mp.params.get("log_volume", False) or VOLUME_SHA256 in mp.info:
        return mp
    info = {**mp.info, VOLUME_SHA256: volume_sha256(mp.values), "theta_cells": int(mp.theta.size)}
    return dataclasses.replace(mp, values=mp.marginal_xy()[:, :, None], theta=np.array([np.nan]), info=info)


def _volume(mp: ProbabilityMap, t_ns: int) -> Any:
    mp = logged_form(mp)
    msg = ProbabilityMap3D(
        frame_id=WORLD,
        name=mp.name,
        model=mp.model,
        x=mp.x.tolist(),
        y=mp.y.tolist(),
        theta=mp.theta.tolist(),
        lost_mass=float(mp.lost_mass),
        params_json=json.dumps(mp.params, sort_keys=True, separators=(",", ":")),
        info_json=json.dumps(mp.info, sort_keys=True, separators=(",", ":")),
        center=mp.center.tolist(),
    )
    _stamp(msg, t_ns)
    msg.values.shape.extend(mp.values.shape)
    msg.values.data = np.ascontiguousarray(mp.values, dtype="<f8").tobytes()
    return msg


def _metrics_msg(
    values: dict[str, float], units: dict[str, str], t_ns: int, definitions: dict[str, str] | None = None
) -> Any:
    msg = Metrics()
    _stamp(msg, t_ns)
    defs = definitions or {}
    for key in sorted(values):
        msg.metrics.add(
            name=key, value=float(values[key]), unit=units.get(key, ""), definition=defs.get(key, "")
        )
    return msg


# --- writing -----------------------------------------------------------------------------


class _Log:
    """Thin wrapper over mcap.Writer: one schema per message type, one channel per topic."""

    def __init__(self, stream: Any) -> None:
        self.w = McapWriter(
            stream,
            chunk_size=_CHUNK_SIZE,
            compression=CompressionType.ZSTD,
            enable_crcs=True,
            enable_data_crcs=True,
        )
        self.w.start(profile="", library=LIBRARY)
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        self.seq: Counter[str] = Counter()

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


def _metadata(result: RunResult) -> dict[str, str]:
    cfg = result.config
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "config": json.dumps(cfg.to_dict(), sort_keys=True, separators=(",", ":")),
        "config_units": json.dumps(cfg.units(), sort_keys=True, separators=(",", ":")),
        "seed": str(cfg.seed),
        "n_steps": str(result.n_steps),
        "checkpoints": json.dumps(sorted(result.checkpoints)),
        "maps": json.dumps([m.name for m in result.maps]),
    }
    for key, value in sorted(result.provenance.items()):
        meta[key] = str(value)
    meta.setdefault("package_version", __version__)
    return meta


def _check_result(result: RunResult) -> None:
    """Shapes of the arrays to log; ValueError naming the bad one."""
    times, poses, covs = result.times, result.poses, result.covs
    n = times.size
    if poses.shape != (n, 3) or covs.shape != (n, 3, 3):
        raise ValueError(
            f"result arrays must have shapes times (N+1,), poses (N+1, 3), covs (N+1, 3, 3), "
            f"got {times.shape}, {poses.shape}, {covs.shape}"
        )
    clouds = {"end_poses": result.end_poses, **{f"checkpoints[{k}]": v for k, v in result.checkpoints.items()}}
    for name, cloud in clouds.items():
        if cloud is not None and (cloud.ndim != 2 or cloud.shape[1] != 3):
            raise ValueError(f"{name} must have shape (n, 3), got shape {cloud.shape}")
    bad_steps = [k for k in result.checkpoints if not 0 <= k < n]
    if bad_steps:
        raise ValueError(f"checkpoint steps must be in [0, {n - 1}], got {bad_steps}")


def _path_msg(poses: NDArray[np.float64], t_ns: int) -> Any:
    """The whole nominal path as one black line strip."""
    path = SceneUpdate()
    ent = path.entities.add(frame_id=WORLD, id="path")
    _stamp(ent, t_ns)
    line = ent.lines.add(type=LinePrimitive.LINE_STRIP, thickness=0.005)
    _yaw(line.pose.orientation, 0.0)
    _color(line.color, _BLACK)
    line.points.extend([Point3(x=float(x), y=float(y)) for x, y in poses[:, :2]])
    return path


def _pose_msgs(i: int, t_ns: int, time: float, pose: NDArray, cov: NDArray) -> tuple[Any, Any, Any]:
    """The robot frame, the nominal pose and the exact covariance of step ``i``."""
    x, y, th = (float(v) for v in pose)
    tf = FrameTransform(parent_frame_id=WORLD, child_frame_id=BASE)
    _stamp(tf, t_ns)
    tf.translation.x, tf.translation.y = x, y
    _yaw(tf.rotation, th)
    msg = PoseInFrame(frame_id=WORLD)
    _stamp(msg, t_ns)
    msg.pose.position.x, msg.pose.position.y = x, y
    _yaw(msg.pose.orientation, th)
    pc = PoseCovariance2D(frame_id=WORLD, step=i, time=time, x=x, y=y, theta=th, covariance=cov.ravel().tolist())
    _stamp(pc, t_ns)
    return tf, msg, pc


def _ellipse_msg(i: int, t_ns: int, ring: NDArray, pr: float, marked: bool, final: bool) -> Any:
    """The Pr-ellipse of step ``i``: the current one (grey, red at the end) and, at marks, a kept one (blue)."""
    upd = SceneUpdate()
    for eid in ["ellipse/current"] + ([f"ellipse/{i:06d}"] if marked else []):
        e = upd.entities.add(frame_id=WORLD, id=eid)
        _stamp(e, t_ns)
        e.metadata.add(key="pr", value=repr(pr))
        e.metadata.add(key="step", value=str(i))
        lp = e.lines.add(type=LinePrimitive.LINE_LOOP, thickness=0.004)
        _yaw(lp.pose.orientation, 0.0)
        _color(lp.color, _RED if final else (_BLUE if eid != "ellipse/current" else _GREY))
        lp.points.extend([Point3(x=float(a), y=float(b)) for a, b in ring])
    return upd


def _put_steps(
    log: _Log, result: RunResult, t_ns: list[int], progress: Callable[[int, int], None] | None = None
) -> None:
    """Every step: frame, pose, covariance, ellipse, and the checkpoint clouds (``progress(i, N+1)``)."""
    poses, covs, n = result.poses, result.covs, result.times.size
    # closed polylines (first vertex repeated): drop the repeat for a LINE_LOOP
    ell = covariance.ellipse_polyline(covs[:, :2, :2], result.config.pr, poses[:, :2], _ELLIPSE_POINTS)[:, :-1]
    marks = set(result.ellipse_steps())
    for i in range(n):
        for topic, msg in zip((T_TF, T_POSE, T_COV),
                              _pose_msgs(i, t_ns[i], float(result.times[i]), poses[i], covs[i]), strict=True):
            log.put(topic, msg, t_ns[i])
        log.put(T_ELLIPSE, _ellipse_msg(i, t_ns[i], ell[i], result.config.pr, i in marks, i == n - 1), t_ns[i])
        if i in result.checkpoints:
            log.put(T_CHECK, _cloud(result.checkpoints[i], t_ns[i]), t_ns[i])
        if progress is not None:
            progress(i + 1, n)


def _put_end(log: _Log, result: RunResult, t_end: int, include_timings: bool) -> None:
    """What belongs to the end of the run: clouds, maps and their samplers, metrics, timings."""
    if result.end_poses is not None:
        log.put(T_END, _cloud(result.end_poses, t_end), t_end)
    for mp in result.maps:
        log.put(f"/maps/{mp.name}/grid", _grid(mp, t_end), t_end)
        log.put(f"/maps/{mp.name}/volume", _volume(mp, t_end), t_end)
        sampler = result.map_samplers.get(mp.name)
        if sampler is not None and len(sampler):
            log.put(f"/maps/{mp.name}/sampler", _cloud(sampler, t_end), t_end)
    log.put(T_METRICS, _metrics_msg(result.metrics, result.metric_units, t_end, result.metric_definitions), t_end)
    if include_timings:
        log.put(T_TIMINGS, _metrics_msg(result.timings, {k: "s" for k in result.timings}, t_end), t_end)


def _write_stream(
    stream: Any,
    result: RunResult,
    include_timings: bool,
    progress: Callable[[int, int], None] | None = None,
) -> None:
    _check_result(result)
    log = _Log(stream)
    log.w.add_metadata(METADATA_NAME, _metadata(result))
    t_ns = [_ns(t) for t in result.times]
    log.put(T_PATH, _path_msg(result.poses, t_ns[0]), t_ns[0])  # the whole nominal path, once, at t = 0
    _put_steps(log, result, t_ns, progress)
    _put_end(log, result, t_ns[-1], include_timings)
    log.w.finish()


def stream_bytes(write: Callable[..., None], *args: Any) -> bytes:
    """The bytes ``write(stream, *args)`` writes, in memory (a log's bytes without a file)."""
    buf = io.BytesIO()
    write(buf, *args)
    return buf.getvalue()


def log_bytes(result: RunResult, *, include_timings: bool = False) -> bytes:
    """The bytes :func:`write_run` would write, without touching the file system."""
    return stream_bytes(_write_stream, result, include_timings)


def write_run(
    path: str | os.PathLike[str],
    result: RunResult,
    *,
    include_timings: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Write a run log atomically.

    The log is written to a hidden temporary file beside ``path``
    (``.<name>.<host>-<pid>-<random>.part``), flushed and fsynced, then renamed over
    ``path`` (:func:`pose_uncertainty.core.atomic.atomic_write`; the parent directory
    is created if missing). An interrupted write never
    leaves a file at ``path``: on an exception the temporary file is removed; a
    killed process leaves only the ``.part`` file, which :func:`open_run`
    rejects as truncated and ``open_run(..., recover=True)`` can read.

    Parameters
    ----------
    path : path-like — destination ``*.mcap``
    result : RunResult
    include_timings : bool
        Also write the wall-clock timings (topic ``/timings``). They differ from
        run to run, so a log with timings is not byte-reproducible; without them
        (the default) the same config and seed give a byte-identical file.
    progress : callable, optional
        ``progress(done, N+1)`` after each step's messages (default None: nothing).

    Returns
    -------
    Path — ``path``
    """
    with atomic_write(path, "wb") as fh:
        _write_stream(fh, result, include_timings, progress)
    return Path(path)


# --- reading -----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class RunLog(RunResult):
    """A run read back from its log: a :class:`RunResult` plus what the file says.

    Attributes (beyond RunResult's)
    -------------------------------
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

    def state_at(self, t: float) -> dict[str, Any]:
        """State at simulated time ``t`` [s]: the last logged step at or before ``t``.

        Returns
        -------
        dict with ``step``, ``time`` [s], ``pose`` (3,), ``cov`` (3, 3), the
        ellipse ``alpha`` [rad], ``a_major``, ``a_minor`` [m] at ``config.pr``, and
        ``cloud`` (n, 3) when a Monte Carlo cloud was logged at that step.
        """
        if not math.isfinite(t) or self.times.size == 0:
            raise ValueError(f"time must be finite, got {t!r}")
        t0, t1 = float(self.times[0]), float(self.times[-1])
        if not t0 <= t <= t1 + 1e-12:
            raise ValueError(
                f"time must be within the run (allowed: [{t0:g}, {t1:g}] s), got {t!r}"
            )
        i = int(np.searchsorted(self.times, t + 1e-12, side="right") - 1)
        cov = self.covs[i]
        alpha, a_major, a_minor = (
            float(v) for v in covariance.ellipse(cov[:2, :2], self.config.pr)
        )
        cloud = self.checkpoints.get(i)
        if cloud is None and i == self.n_steps:
            cloud = self.end_poses
        return {
            "step": i,
            "time": float(self.times[i]),
            "pose": self.poses[i],
            "cov": cov,
            "alpha": alpha,
            "a_major": a_major,
            "a_minor": a_minor,
            "cloud": cloud,
        }

    def summary(self) -> str:
        """Human-readable summary (see :func:`format_summary`)."""
        return format_summary(self)


def _scan(data: bytes) -> tuple[list[Any], str | None]:
    """Read every record, validating chunk and data-section CRCs; stop at the first problem.

    Returns the records read so far (chunk contents only for whole, CRC-valid
    chunks) and a description of the problem, or None if the file is complete.
    """
    stream = io.BytesIO(data)
    reader = StreamReader(stream, validate_crcs=True, record_size_limit=len(data))
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
        pos = stream.tell()
        tail = data[-len(MAGIC) :]
        if (
            len(tail) == len(MAGIC)
            and 0 < sum(a != b for a, b in zip(tail, MAGIC, strict=True)) <= 2
        ):
            return records, "corrupted: damaged MCAP magic at the end of the file"
        if not data.endswith(MAGIC):
            return (
                records,
                f"truncated: the file ends at byte {len(data)} inside an MCAP record (no footer)",
            )
        if pos >= len(data):
            detail = "a record runs past the end of the file"
        else:
            detail = str(exc) or type(exc).__name__
        return records, f"corrupted: unreadable MCAP record near byte {pos} ({detail})"
    footer = records[-1] if records else None
    if not isinstance(footer, Footer):
        return records, "corrupted: no MCAP footer record"
    if not any(isinstance(r, DataEnd) for r in records):
        return records, "corrupted: no DataEnd record (the data section is damaged)"
    if footer.summary_crc != 0:
        footer_at = len(data) - len(MAGIC) - _FOOTER_RECORD
        start = footer.summary_start or footer_at
        if not 0 < start <= footer_at:
            return records, f"corrupted: summary offset {footer.summary_start} is outside the file"
        crc = zlib.crc32(data[start:footer_at])
        crc = zlib.crc32(data[footer_at : footer_at + 1 + 8 + 16], crc)
        if crc != footer.summary_crc:
            return records, (
                f"corrupted: CRC mismatch in the summary section "
                f"(stored {footer.summary_crc:#010x}, computed {crc:#010x})"
            )
    return records, None


def _describe_start(data: bytes) -> str:
    head = data[:24]
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        return f"starts with bytes {head[:8].hex(' ')}"
    if text.isprintable() or all(c.isprintable() or c.isspace() for c in text):
        return f"starts with text {text.strip()[:20]!r}"
    return f"starts with bytes {head[:8].hex(' ')}"


def open_run(path: str | os.PathLike[str], *, recover: bool = False) -> RunLog:
    """Read and validate a run log.

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
    RunLog

    Raises
    ------
    RunLogError
        One line, ``"<path>: <problem>"``: missing, empty, not MCAP, truncated,
        corrupted (CRC mismatch), or an MCAP not written by pose-uncertainty.
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise RunLogError(f"{p}: no such file") from None
    except IsADirectoryError:
        raise RunLogError(f"{p}: is a directory, not a run log") from None
    except OSError as exc:
        raise RunLogError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if not data:
        raise RunLogError(f"{p}: empty file (0 bytes), not a run log")
    if not data.startswith(MAGIC):
        if MAGIC.startswith(data):
            raise RunLogError(f"{p}: truncated: only {len(data)} bytes of the MCAP magic")
        raise RunLogError(f"{p}: not an MCAP file (no MCAP magic; {_describe_start(data)})")
    records, problem = _scan(data)
    if problem is not None and not recover:
        n_msgs = sum(isinstance(r, Message) for r in records)
        hint = (
            f"; {n_msgs} messages before it can be recovered (replay --recover)" if n_msgs else ""
        )
        raise RunLogError(f"{p}: {problem}{hint}")
    try:
        log = _assemble(p, records, partial=problem is not None, problem=problem)
    except RunLogError:
        raise
    except Exception as exc:  # noqa: BLE001 - a CRC-valid file with content we cannot decode
        raise RunLogError(
            f"{p}: not a valid pose-uncertainty run log ({type(exc).__name__}: {exc})"
        ) from None
    if problem is not None:
        counts = ", ".join(f"{t} {c}" for t, (_, c) in sorted(log.topics.items()))
        warnings.warn(
            f"{p}: partial log ({problem}); recovered {log.n_steps + 1} steps ({counts})",
            PartialLogWarning,
            stacklevel=2,
        )
    return log


def _run_metadata(p: Path, records: list[Any], partial: bool, problem: str | None) -> tuple[Any, dict[str, str]]:
    """The MCAP header and the run's metadata record, checked for format and version."""
    header = next((r for r in records if isinstance(r, Header)), None)
    if header is None:
        raise RunLogError(f"{p}: {problem or 'corrupted: no MCAP header'}; nothing recoverable")
    meta_rec = next((r for r in records if isinstance(r, Metadata) and r.name == METADATA_NAME), None)
    if not header.library.startswith("pose-uncertainty/") or meta_rec is None:
        if partial and header.library.startswith("pose-uncertainty/"):
            raise RunLogError(f"{p}: {problem}; the run metadata is missing, nothing recoverable")
        raise RunLogError(
            f"{p}: not a pose-uncertainty run log (written by {header.library or 'an unnamed writer'!r}, "
            f"no {METADATA_NAME!r} metadata)"
        )
    meta = dict(meta_rec.metadata)
    if log_kind(meta.get("format")) is not None:  # another kind of run (e.g. localization): its own reader
        return header, meta
    if meta.get("format") != FORMAT:
        raise RunLogError(f"{p}: not a pose-uncertainty run log (format {meta.get('format')!r})")
    if meta.get("format_version") != FORMAT_VERSION:
        raise RunLogError(
            f"{p}: run log format version {meta.get('format_version')!r} is not supported "
            f"(this reader: {FORMAT_VERSION})"
        )
    return header, meta


class _Records:
    """The messages of a log by topic, decoded on demand against their expected schema."""

    def __init__(self, p: Path, records: list[Any]) -> None:
        self.p = p
        schemas = {r.id: r for r in records if isinstance(r, Schema)}
        channels = {r.id: r for r in records if isinstance(r, Channel)}
        self.by_topic: dict[str, list[Message]] = {}
        for r in records:
            if isinstance(r, Message):
                if r.channel_id not in channels:
                    raise RunLogError(f"{p}: message on unknown channel {r.channel_id}")
                self.by_topic.setdefault(channels[r.channel_id].topic, []).append(r)
        self.schema = {ch.topic: (schemas[ch.schema_id].name if ch.schema_id in schemas else "")
                       for ch in channels.values()}  # fmt: skip
        self.topics = {t: (self.schema.get(t, ""), len(m)) for t, m in sorted(self.by_topic.items())}

    def decode(self, topic: str, expected: str) -> list[Any]:
        msgs = self.by_topic.get(topic, [])
        if msgs and self.schema.get(topic) != expected:
            raise RunLogError(f"{self.p}: topic {topic} has schema {self.schema.get(topic)!r}, expected {expected!r}")
        try:
            return [_CLASSES[expected].FromString(m.data) for m in msgs]
        except DecodeError as exc:
            raise RunLogError(f"{self.p}: a message on {topic} is not a valid {expected} ({exc})") from None

    def cloud(self, msg: Any) -> NDArray[np.float64]:
        layout = [(f.name, f.offset, f.type) for f in msg.fields]
        if msg.point_stride != 24 or layout != [("x", 0, _F64), ("y", 8, _F64), ("theta", 16, _F64)]:
            raise RunLogError(f"{self.p}: point cloud layout {layout} is not (x, y, theta) float64")
        return np.frombuffer(msg.data, dtype="<f8").reshape(-1, 3).astype(np.float64)

    def last_cloud(self, topic: str) -> NDArray[np.float64] | None:
        msgs = self.decode(topic, TOPICS[T_END])
        return self.cloud(msgs[-1]) if msgs else None

    def metrics(self, topic: str) -> tuple[dict[str, float], dict[str, str], dict[str, str]]:
        msgs = self.decode(topic, TOPICS[topic])
        last = msgs[-1].metrics if msgs else []
        return ({m.name: float(m.value) for m in last}, {m.name: m.unit for m in last},
                {m.name: m.definition for m in last})  # fmt: skip


def _read_steps(rec: _Records, n_expected: int, partial: bool) -> tuple[NDArray, NDArray, NDArray]:
    """Times (N+1,), poses (N+1, 3) and covariances (N+1, 3, 3) of every logged step."""
    covmsgs = sorted(rec.decode(T_COV, TOPICS[T_COV]), key=lambda m: m.step)
    steps = [m.step for m in covmsgs]
    if steps != list(range(len(steps))) or (not partial and len(steps) != n_expected):
        raise RunLogError(
            f"{rec.p}: {T_COV} holds steps {steps[:3]}…(count {len(steps)}), expected 0..{n_expected - 1}"
        )
    times = np.array([m.time for m in covmsgs], dtype=np.float64)
    poses = np.array([[m.x, m.y, m.theta] for m in covmsgs], dtype=np.float64).reshape(-1, 3)
    covs = np.array([list(m.covariance) for m in covmsgs], dtype=np.float64).reshape(-1, 3, 3)
    return times, poses, covs


def _read_checkpoints(rec: _Records, times: NDArray) -> dict[int, NDArray[np.float64]]:
    step_of_ns = {_ns(t): i for i, t in enumerate(times)}
    out: dict[int, NDArray[np.float64]] = {}
    for msg in rec.decode(T_CHECK, TOPICS[T_CHECK]):
        t_ns = msg.timestamp.seconds * 1_000_000_000 + msg.timestamp.nanos
        if t_ns not in step_of_ns:
            raise RunLogError(f"{rec.p}: checkpoint cloud at {t_ns} ns matches no logged step")
        out[step_of_ns[t_ns]] = rec.cloud(msg)
    return out


def _read_map(rec: _Records, name: str) -> ProbabilityMap | None:
    vols = rec.decode(f"/maps/{name}/volume", "pose_uncertainty.ProbabilityMap3D")
    if not vols:
        return None
    v = vols[-1]
    shape = tuple(int(s) for s in v.values.shape)
    values = np.frombuffer(v.values.data, dtype="<f8")
    if values.size != int(np.prod(shape)):
        raise RunLogError(f"{rec.p}: map {name!r} holds {values.size} values, shape says {shape}")
    return ProbabilityMap(
        name=v.name, model=v.model, x=np.array(v.x, dtype=np.float64), y=np.array(v.y, dtype=np.float64),
        theta=np.array(v.theta, dtype=np.float64), values=values.reshape(shape).astype(np.float64),
        lost_mass=float(v.lost_mass), params=json.loads(v.params_json) if v.params_json else {},
        info=json.loads(v.info_json) if v.info_json else {},
        center=np.array(v.center, dtype=np.float64) if len(v.center) == 3 else np.full(3, np.nan),
    )  # fmt: skip


def _assemble(p: Path, records: list[Any], *, partial: bool, problem: str | None) -> RunLog:
    header, meta = _run_metadata(p, records, partial, problem)
    kind = log_kind(meta.get("format"))
    if kind is not None:  # another kind of run (e.g. localization): its own reader
        return kind.assemble(p, records, meta, header.library, partial, problem)  # type: ignore[no-any-return]
    try:
        config = RunConfig.from_dict(json.loads(meta["config"]))
    except (KeyError, ValueError) as exc:
        raise RunLogError(f"{p}: the logged run config is invalid ({exc})") from None
    rec = _Records(p, records)
    times, poses, covs = _read_steps(rec, int(meta.get("n_steps", "-1")) + 1, partial)
    maps = [m for m in (_read_map(rec, name) for name in json.loads(meta.get("maps", "[]"))) if m is not None]
    samplers = {m.name: c for m in maps if (c := rec.last_cloud(f"/maps/{m.name}/sampler")) is not None}
    metrics, units, definitions = rec.metrics(T_METRICS)
    return RunLog(
        config=config, times=times, poses=poses, covs=covs, end_poses=rec.last_cloud(T_END),
        checkpoints=_read_checkpoints(rec, times), maps=tuple(maps), map_samplers=samplers, metrics=metrics,
        metric_units=units, metric_definitions=definitions, timings=rec.metrics(T_TIMINGS)[0],
        provenance={k: meta[k] for k in PROVENANCE_KEYS if k in meta}, path=p, metadata=meta,
        library=header.library, topics=rec.topics, partial=partial, problems=(problem,) if problem else (),
    )  # fmt: skip


# --- summary, comparison, verification ------------------------------------------------------


def _fmt_array(a: NDArray[np.float64]) -> str:
    return np.array2string(np.asarray(a), precision=6, separator=", ", max_line_width=120)


def _flatten(value: Any, units: Any, prefix: str = "") -> list[str]:
    """``key.sub = value [unit]`` lines of a nested config mapping."""
    if isinstance(value, dict):
        out: list[str] = []
        for key in value:
            sub_units = units.get(key, "") if isinstance(units, dict) else ""
            out.extend(_flatten(value[key], sub_units, f"{prefix}{key}."))
        return out
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        out = []
        for i, v in enumerate(value):
            out.extend(_flatten(v, units, f"{prefix[:-1]}[{i}]."))
        return out
    unit = units if isinstance(units, str) and units not in ("", "-") else ""
    text = json.dumps(value)
    return [f"{prefix[:-1]} = {text}" + (f"  [{unit}]" if unit else "")]


def format_summary(log: RunLog) -> str:
    """Summary of a run log: config, topics with counts, final pose and covariance, metrics."""
    lines = [f"run log   {log.path}"]
    if log.partial:
        lines.append(f"PARTIAL   {'; '.join(log.problems)}")
    lines.append(
        f"written by {log.library}; format {log.metadata.get('format')} v{log.metadata.get('format_version')}"
    )
    for key in PROVENANCE_KEYS:
        if key in log.provenance:
            lines.append(f"  {key}: {log.provenance[key]}")
    if log.config.drive is not None:
        lines.append(f"drive     {log.config.drive.describe()}")
    lines.append("config")
    lines.extend(f"  {ln}" for ln in _flatten(log.config.to_dict(), log.config.units()))
    lines.append("topics")
    width = max((len(t) for t in log.topics), default=0)
    for topic, (schema, count) in log.topics.items():
        lines.append(f"  {topic:<{width}}  {count:>7}  {schema}")
    if log.times.size:
        i = log.times.size - 1
        lines.append(f"final state (step {i}, t = {log.times[i]:.9g} s)")
        lines.append(f"  pose (x [m], y [m], theta [rad]) = {_fmt_array(log.poses[i])}")
        lines.append("  covariance [m^2, m*rad, rad^2] =")
        lines.extend("    " + ln for ln in _fmt_array(log.covs[i]).splitlines())
    if log.end_poses is not None:
        lines.append(
            f"monte carlo: {log.end_poses.shape[0]} end poses; checkpoints at steps {sorted(log.checkpoints)}"
        )
    for mp in log.maps:
        lines.append(
            f"map {mp.name}: model {mp.model}, grid {mp.values.shape} (x, y, theta), lost mass {mp.lost_mass:.3g}"
        )
    if log.metrics:
        lines.append("metrics")
        for key in sorted(log.metrics):
            lines.append(
                f"  {key} = {log.metrics[key]:.9g} {log.metric_units.get(key, '')}".rstrip()
            )
    if log.timings:
        lines.append("timings (wall clock, not reproducible)")
        for key in sorted(log.timings):
            lines.append(f"  {key} = {log.timings[key]:.4g} s")
    return "\n".join(lines)


def _diff(name: str, a: Any, b: Any) -> str | None:
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


def compare_results(logged: RunResult, fresh: RunResult) -> list[str]:
    """Bit-exact comparison of two results; one line per difference (empty = identical).

    Timings are not compared (they are not reproducible); provenance
    differences are reported with a leading ``"note: "`` and are not mismatches.
    """
    out: list[str] = []
    if logged.config != fresh.config:
        out.append("config differs")
    for name in ("times", "poses", "covs", "end_poses"):
        d = _diff(name, getattr(logged, name), getattr(fresh, name))
        if d:
            out.append(d)
    if sorted(logged.checkpoints) != sorted(fresh.checkpoints):
        out.append(
            f"checkpoints: steps {sorted(logged.checkpoints)} != {sorted(fresh.checkpoints)}"
        )
    else:
        for step in sorted(logged.checkpoints):
            d = _diff(f"checkpoint[{step}]", logged.checkpoints[step], fresh.checkpoints[step])
            if d:
                out.append(d)
    if [m.name for m in logged.maps] != [m.name for m in fresh.maps]:
        out.append(f"maps: {[m.name for m in logged.maps]} != {[m.name for m in fresh.maps]}")
    else:
        for a, b in zip(map(logged_form, logged.maps), map(logged_form, fresh.maps), strict=True):
            for attr in ("x", "y", "theta", "values", "center"):
                d = _diff(f"map {a.name}.{attr}", getattr(a, attr), getattr(b, attr))
                if d:
                    out.append(d)
            if (a.lost_mass, a.model, a.params, a.info) != (b.lost_mass, b.model, b.params, b.info):
                out.append(f"map {a.name}: model/lost_mass/params/info differ")
            d = _diff(f"map {a.name} sampler", logged.map_samplers.get(a.name), fresh.map_samplers.get(a.name))
            if d:
                out.append(d)
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


def recomputable(log: RunLog) -> None:
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


def verify_log(log: RunLog | Any, fresh_bytes: bytes) -> Comparison:
    """Compare ``log``'s file with ``fresh_bytes``, a fresh log of its recomputation.

    The three outcomes of the reproducibility contract
    (:mod:`pose_uncertainty.records.reproducibility`): identical bytes; every record equal
    within tolerance; a mismatch. Notes say what differs in the machine and libraries
    (the log's provenance against this machine's) and what is not compared (timings).
    """
    comparison = compare_log_bytes(log.path.read_bytes(), fresh_bytes, n_steps=log.n_steps)
    if log.timings:
        comparison.notes.append("the wall-clock timings (/timings) are not reproducible: not compared")
    comparison.notes.extend(environment_notes(log.provenance, provenance()))
    return comparison


def verify_run(log: RunLog) -> Comparison:
    """Recompute a logged run from its config and seed and compare every record of its log.

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
    kind = log_kind(log.metadata.get("format"))
    if kind is not None:  # another kind of run: its own recomputation
        return kind.verify(log)
    fresh = execute(log.config)
    same = RunResult(**{**_fields_of(fresh), "provenance": dict(log.provenance), "timings": dict(log.timings)})
    return verify_log(log, log_bytes(same, include_timings=bool(log.timings)))


def _fields_of(result: RunResult) -> dict[str, Any]:
    return {f: getattr(result, f) for f in RunResult.__dataclass_fields__}
