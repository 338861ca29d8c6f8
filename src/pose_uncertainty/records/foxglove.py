"""Message builders of every log kind: Foxglove's well-known schemas and ours, one of each.

Every log kind (:mod:`.run`, :mod:`.localization`) draws with these builders, so that a point
cloud, a path, a grid or a pose is the same message in every log. All messages are in frame
:data:`WORLD`; times are integer nanoseconds of simulated time (:func:`ns`).

Our schemas (package ``pose_uncertainty``) carry the exact float64 data: ``PoseCovariance2D``,
``Float64Array``, ``ProbabilityMap3D``, ``Metric``/``Metrics`` (file ``runlog.proto``) and
``NamedArray``/``NamedArrays`` (file ``localization.proto``). Their field numbers follow the
order of :data:`RUNLOG_MESSAGES` and :data:`LOCALIZATION_MESSAGES`: changing either changes
the log format.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

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
from numpy.typing import NDArray

__all__ = [
    "BASE",
    "BLACK",
    "CLASSES",
    "F64",
    "GRID_CELL",
    "LINE_LIST",
    "LINE_LOOP",
    "LINE_STRIP",
    "LOCALIZATION_MESSAGES",
    "RUNLOG_MESSAGES",
    "WORLD",
    "Float64Array",
    "Metrics",
    "NamedArrays",
    "PoseCovariance2D",
    "ProbabilityMap3D",
    "arrays_msg",
    "color",
    "float64_cloud",
    "frame_transform",
    "grid_msg",
    "line_entity",
    "line_scene",
    "metrics_msg",
    "ns",
    "packed_fields",
    "pose_covariance",
    "pose_in_frame",
    "stamp",
    "yaw",
]

WORLD, BASE = "world", "base_link"
RGBA = tuple[float, float, float, float]
BLACK: RGBA = (0.0, 0.0, 0.0, 1.0)
LINE_STRIP, LINE_LOOP, LINE_LIST = LinePrimitive.LINE_STRIP, LinePrimitive.LINE_LOOP, LinePrimitive.LINE_LIST
F64 = PackedElementField.FLOAT64
U8 = PackedElementField.UINT8
#: One cell of a logged grid: the exact mass (float64) and a grey RGBA, darker = more probable.
GRID_CELL = np.dtype([("mass", "<f8"), ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("alpha", "u1")])


# --- our schemas -------------------------------------------------------------------------

#: A message: name → fields ``(name, type, repeated)``; a type is ``double``, ``string``,
#: ``uint32``, ``uint64``, ``bytes``, ``timestamp`` or another message of ours.
MessageSpec = dict[str, list[tuple[str, str, bool]]]

#: ``pose_uncertainty/runlog.proto``.
RUNLOG_MESSAGES: MessageSpec = {
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

#: ``pose_uncertainty/localization.proto``: named float64 arrays with unit and definition.
LOCALIZATION_MESSAGES: MessageSpec = {
    "NamedArray": [("name", "string", False), ("unit", "string", False), ("definition", "string", False),
                   ("values", "Float64Array", False)],
    "NamedArrays": [("timestamp", "timestamp", False), ("arrays", "NamedArray", True)],
}  # fmt: skip


def _message_classes(file: str, messages: MessageSpec, dependencies: Sequence[str]) -> dict[str, Any]:
    """Register (once) the proto file ``file`` of ``messages`` and return their protobuf classes."""
    F = descriptor_pb2.FieldDescriptorProto
    scalars = {"double": F.TYPE_DOUBLE, "string": F.TYPE_STRING, "uint32": F.TYPE_UINT32,
               "uint64": F.TYPE_UINT64, "bytes": F.TYPE_BYTES}  # fmt: skip
    fdp = descriptor_pb2.FileDescriptorProto(name=file, package="pose_uncertainty", syntax="proto3")
    fdp.dependency.extend(dependencies)
    for name, fields in messages.items():
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
    return {n: message_factory.GetMessageClass(pool.FindMessageTypeByName(f"pose_uncertainty.{n}")) for n in messages}


_ = _timestamp_pb2
_RUNLOG = _message_classes("pose_uncertainty/runlog.proto", RUNLOG_MESSAGES, ["google/protobuf/timestamp.proto"])
_LOCALIZATION = _message_classes("pose_uncertainty/localization.proto", LOCALIZATION_MESSAGES,
                                 ["google/protobuf/timestamp.proto", "pose_uncertainty/runlog.proto"])  # fmt: skip
PoseCovariance2D = _RUNLOG["PoseCovariance2D"]
Float64Array = _RUNLOG["Float64Array"]
ProbabilityMap3D = _RUNLOG["ProbabilityMap3D"]
Metrics = _RUNLOG["Metrics"]
NamedArrays = _LOCALIZATION["NamedArrays"]

#: Every message class a log holds, by its full schema name.
CLASSES: dict[str, Any] = {
    cls.DESCRIPTOR.full_name: cls
    for cls in (FrameTransform, PoseInFrame, SceneUpdate, PointCloud, Grid, PoseCovariance2D, ProbabilityMap3D,
                Metrics, NamedArrays)
}  # fmt: skip


# --- small helpers -----------------------------------------------------------------------


def ns(t: float) -> int:
    """Simulated time [s] → integer nanoseconds (≥ 0)."""
    return max(0, round(float(t) * 1e9))


def stamp(msg: Any, t_ns: int) -> None:
    """Set ``msg.timestamp`` to ``t_ns`` nanoseconds."""
    msg.timestamp.seconds, msg.timestamp.nanos = divmod(t_ns, 1_000_000_000)


def color(c: Any, rgba: Sequence[float]) -> None:
    """Set a foxglove.Color from ``(r, g, b, a)`` in [0, 1]."""
    c.r, c.g, c.b, c.a = rgba


def yaw(q: Any, theta: float) -> None:
    """Set quaternion ``q`` to a rotation by ``theta`` [rad] about +z."""
    q.x, q.y = 0.0, 0.0
    q.z, q.w = math.sin(theta / 2.0), math.cos(theta / 2.0)


def packed_fields(names: Iterable[tuple[str, int, int]]) -> list[Any]:
    """foxglove.PackedElementField of each ``(name, offset [bytes], type)``."""
    return [PackedElementField(name=n, offset=o, type=t) for n, o, t in names]  # type: ignore[arg-type]


# --- builders ----------------------------------------------------------------------------


def float64_cloud(rows: NDArray[np.float64], columns: Sequence[str], t_ns: int) -> Any:
    """foxglove.PointCloud of ``rows`` (n, len(columns)) exactly as float64, one named field per column."""
    data = np.ascontiguousarray(rows, dtype="<f8").tobytes()
    msg = PointCloud(frame_id=WORLD, point_stride=8 * len(columns),
                     fields=packed_fields([(c, 8 * i, F64) for i, c in enumerate(columns)]), data=data)  # fmt: skip
    stamp(msg, t_ns)
    yaw(msg.pose.orientation, 0.0)
    return msg


def grid_msg(marg: NDArray[np.float64], x0: float, y0: float, dx: float, dy: float, t_ns: int) -> Any:
    """foxglove.Grid of a mass per cell ``marg`` (nx, ny), cell ``[0, 0]`` centred at ``(x0, y0)``.

    Each cell holds the exact mass (float64) and a grey RGBA, darker = more probable
    (:data:`GRID_CELL`); cells below 1e-3 of the peak are transparent.
    """
    nx, ny = marg.shape
    peak = float(marg.max()) if marg.size and marg.max() > 0 else 1.0
    rel = np.clip(marg / peak, 0.0, 1.0)
    rows = np.zeros((ny, nx), dtype=GRID_CELL)  # row-major (y-major) order
    grey = np.round(255.0 * (1.0 - rel)).astype(np.uint8).T
    rows["mass"] = marg.T
    rows["red"] = rows["green"] = rows["blue"] = grey
    rows["alpha"] = np.where(rel.T > 1e-3, 255, 0).astype(np.uint8)
    layout = [("mass", 0, F64), ("red", 8, U8), ("green", 9, U8), ("blue", 10, U8), ("alpha", 11, U8)]
    msg = Grid(frame_id=WORLD, column_count=nx, row_stride=GRID_CELL.itemsize * nx, cell_stride=GRID_CELL.itemsize,
               fields=packed_fields(layout), data=rows.tobytes())  # fmt: skip
    stamp(msg, t_ns)
    msg.pose.position.x = x0 - dx / 2.0
    msg.pose.position.y = y0 - dy / 2.0
    yaw(msg.pose.orientation, 0.0)
    msg.cell_size.x, msg.cell_size.y = dx, dy
    return msg


def line_entity(upd: Any, eid: str, t_ns: int, kind: int, pts: NDArray[np.float64], rgba: Sequence[float],
                width: float) -> Any:  # fmt: skip
    """Add to SceneUpdate ``upd`` an entity ``eid`` with one line of ``kind`` through ``pts`` (m, 2); return it."""
    e = upd.entities.add(frame_id=WORLD, id=eid)
    stamp(e, t_ns)
    line = e.lines.add(type=kind, thickness=width)  # type: ignore[arg-type]
    yaw(line.pose.orientation, 0.0)
    color(line.color, rgba)
    # the rows as Python floats in one call (what float() of each element gives, without a numpy scalar each)
    line.points.extend([Point3(x=x, y=y) for x, y in np.asarray(pts, dtype=np.float64).tolist()])
    return e


def line_scene(eid: str, pts: NDArray[np.float64], kind: int, rgba: Sequence[float], width: float, t_ns: int) -> Any:
    """foxglove.SceneUpdate of one entity ``eid`` with one line through ``pts`` (m, 2) (a path, rays, walls)."""
    upd = SceneUpdate()
    line_entity(upd, eid, t_ns, kind, pts, rgba, width)
    return upd


def frame_transform(pose: NDArray[np.float64], t_ns: int) -> Any:
    """foxglove.FrameTransform world → base_link at ``pose`` (x [m], y [m], theta [rad])."""
    x, y, th = (float(v) for v in pose)
    tf = FrameTransform(parent_frame_id=WORLD, child_frame_id=BASE)
    stamp(tf, t_ns)
    tf.translation.x, tf.translation.y = x, y
    yaw(tf.rotation, th)
    return tf


def pose_in_frame(pose: NDArray[np.float64], t_ns: int) -> Any:
    """foxglove.PoseInFrame at ``pose`` (x [m], y [m], theta [rad])."""
    msg = PoseInFrame(frame_id=WORLD)
    stamp(msg, t_ns)
    msg.pose.position.x, msg.pose.position.y = float(pose[0]), float(pose[1])
    yaw(msg.pose.orientation, float(pose[2]))
    return msg


def pose_covariance(step: int, time: float, pose: NDArray[np.float64], cov: NDArray[np.float64], t_ns: int) -> Any:
    """pose_uncertainty.PoseCovariance2D: the exact pose (3,) and covariance (3, 3) of ``step`` at ``time`` [s]."""
    x, y, th = (float(v) for v in pose)
    pc = PoseCovariance2D(frame_id=WORLD, step=step, time=float(time), x=x, y=y, theta=th,
                          covariance=np.asarray(cov).reshape(9).tolist())  # fmt: skip
    stamp(pc, t_ns)
    return pc


def metrics_msg(values: dict[str, float], units: dict[str, str], t_ns: int,
                definitions: dict[str, str] | None = None) -> Any:  # fmt: skip
    """pose_uncertainty.Metrics: every measure (sorted by name) with its unit and definition."""
    msg = Metrics()
    stamp(msg, t_ns)
    defs = definitions or {}
    for key in sorted(values):
        msg.metrics.add(name=key, value=float(values[key]), unit=units.get(key, ""), definition=defs.get(key, ""))
    return msg


def arrays_msg(arrays: dict[str, NDArray[np.float64]], t_ns: int, units: dict[str, str] | None = None) -> Any:
    """pose_uncertainty.NamedArrays: each array exactly (little-endian float64, C order) with its unit."""
    msg = NamedArrays()
    stamp(msg, t_ns)
    for name, a in arrays.items():
        v = np.ascontiguousarray(a, dtype="<f8")
        item = msg.arrays.add(name=name, unit=(units or {}).get(name, ""))
        item.values.shape.extend(v.shape)
        item.values.data = v.tobytes()
    return msg
