"""Localization run logs: one MCAP file per run, to watch the filters in Foxglove and to replay them.

The container, compression, CRCs, atomic write and byte-level determinism are those of
the dead-reckoning run logs (:mod:`pose_uncertainty.records.run`); the metadata record
``pose_uncertainty.run`` carries ``format: pose-uncertainty-localization``, and
:func:`pose_uncertainty.records.run.open_run` hands such a file to :func:`assemble` here
(registered in :data:`~pose_uncertainty.records.run.LOG_KINDS`), ``verify_run`` to
:func:`verify_localization`. Log time = simulated time (ns); frame ``world``.

==================================  ==================================  ===========================================
topic                               schema                              content
==================================  ==================================  ===========================================
``/world``                          foxglove.SceneUpdate                walls (black lines), landmarks (spheres, ids), t=0
``/world/occupancy``                foxglove.Grid                       the occupancy grid (occupied dark), t=0
``/truth/path``                     foxglove.SceneUpdate                the whole true path (black), t=0
``/odometry/path``                  foxglove.SceneUpdate                dead reckoning from the odometry (grey), t=0
``/tf``                             foxglove.FrameTransform             world → base_link at the true pose, per step
``/truth/pose``                     foxglove.PoseInFrame                true pose per step
``/measurements/landmarks``         foxglove.SceneUpdate                range–bearing measurements: lines from the true pose
``/measurements/beams``             foxglove.SceneUpdate                laser beams: rays from the true pose
``/filters/<f>/pose``               foxglove.PoseInFrame                filter ``<f>``'s estimate per step
``/filters/<f>/ellipse``            foxglove.SceneUpdate                its 98.89 % ellipse per step
``/filters/<f>/particles``          foxglove.PointCloud                 particles (x, y, theta, weight; float64), subsampled
``/filters/<f>/grid``               foxglove.Grid                       the histogram filter's θ-marginal (mass float64)
``/filters/<f>/state``              pose_uncertainty.PoseCovariance2D   exact mean and 3×3 covariance per step
``/filters/<f>/series``             pose_uncertainty.NamedArrays        per-step series (errors, σ, NEES, …), at the end
``/localization/data``              pose_uncertainty.NamedArrays        the simulated data and the world, exact, t=0
``/metrics``                        pose_uncertainty.Metrics            every measure: value, unit, definition
``/timings``                        pose_uncertainty.Metrics            wall-clock timings (opt-in)
==================================  ==================================  ===========================================

Filters ``<f>``: ``ekf`` (blue), ``histogram`` (green), ``particle`` (orange), those configured.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.Grid_pb2 import Grid
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.message import DecodeError
from mcap.records import Channel, Message, Schema
from numpy.typing import NDArray

from .. import __version__
from ..analysis.localization import SERIES_UNITS
from ..core.atomic import atomic_write
from ..core.provenance import PROVENANCE_KEYS
from ..core.stats import PR_3SIGMA
from ..experiments.localization import (
    FilterTrack,
    LocalizationConfig,
    LocalizationResult,
    execute_localization,
)
from ..localization.world import OccupancyGrid, World
from ..methods.covariance import ellipse_polyline
from . import run as runlog
from .reproducibility import MISMATCH, Comparison
from .run import (
    _F64,
    BASE,
    METADATA_NAME,
    WORLD,
    Float64Array,
    LogKind,
    PoseCovariance2D,
    RunLogError,
    _color,
    _diff,
    _fields,
    _flatten,
    _grid_msg,
    _Log,
    _metrics_msg,
    _ns,
    _stamp,
    _yaw,
    stream_bytes,
)

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "LocalizationLog",
    "assemble",
    "compare_localization",
    "format_localization_summary",
    "localization_log_bytes",
    "verify_localization",
    "write_localization",
]

FORMAT = "pose-uncertainty-localization"
FORMAT_VERSION = "1"
_COLORS: dict[str, tuple[float, float, float, float]] = {
    "ekf": (0.0, 0.3, 1.0, 1.0), "histogram": (0.0, 0.6, 0.2, 1.0), "particle": (1.0, 0.5, 0.0, 1.0),
}  # fmt: skip
_BLACK = (0.0, 0.0, 0.0, 1.0)
_GREY = (0.55, 0.55, 0.55, 1.0)
_RAY = (0.8, 0.0, 0.6, 0.8)
_ELLIPSE_POINTS = 48
T_DATA = "/localization/data"
Array = NDArray[np.float64]


# ============================================================================= schema


def _schemas() -> dict[str, Any]:
    """The ``pose_uncertainty.NamedArrays`` schema (named float64 arrays with unit and definition)."""
    F = descriptor_pb2.FieldDescriptorProto
    fdp = descriptor_pb2.FileDescriptorProto(
        name="pose_uncertainty/localization.proto", package="pose_uncertainty", syntax="proto3"
    )
    fdp.dependency.extend(["google/protobuf/timestamp.proto", "pose_uncertainty/runlog.proto"])
    one, many = F.LABEL_OPTIONAL, F.LABEL_REPEATED
    m = fdp.message_type.add(name="NamedArray")
    for i, (name, ftype, label, tname) in enumerate(
        [("name", F.TYPE_STRING, one, None), ("unit", F.TYPE_STRING, one, None),
         ("definition", F.TYPE_STRING, one, None),
         ("values", F.TYPE_MESSAGE, one, ".pose_uncertainty.Float64Array")], start=1):  # fmt: skip
        f = m.field.add(name=name, number=i, type=ftype, label=label)  # type: ignore[arg-type]
        if tname:
            f.type_name = tname
    m = fdp.message_type.add(name="NamedArrays")
    m.field.add(name="timestamp", number=1, type=F.TYPE_MESSAGE, label=one, type_name=".google.protobuf.Timestamp")
    m.field.add(name="arrays", number=2, type=F.TYPE_MESSAGE, label=many, type_name=".pose_uncertainty.NamedArray")
    pool = descriptor_pool.Default()
    try:
        pool.FindFileByName(fdp.name)
    except KeyError:
        pool.Add(fdp)
    return {n: message_factory.GetMessageClass(pool.FindMessageTypeByName(f"pose_uncertainty.{n}"))
            for n in ("NamedArray", "NamedArrays")}  # fmt: skip


NamedArrays = _schemas()["NamedArrays"]
_ = Float64Array  # the dependency of NamedArray, registered by runlog


# ============================================================================= writing


def _arrays_msg(arrays: dict[str, Array], t_ns: int, units: dict[str, str] | None = None) -> Any:
    msg = NamedArrays()
    _stamp(msg, t_ns)
    for name, a in arrays.items():
        v = np.ascontiguousarray(a, dtype="<f8")
        item = msg.arrays.add(name=name, unit=(units or {}).get(name, ""))
        item.values.shape.extend(v.shape)
        item.values.data = v.tobytes()
    return msg


def _line_entity(upd: Any, eid: str, t_ns: int, kind: int, pts: Array, rgba: tuple[float, ...], width: float) -> Any:
    e = upd.entities.add(frame_id=WORLD, id=eid)
    _stamp(e, t_ns)
    line = e.lines.add(type=kind, thickness=width)  # type: ignore[arg-type]
    _yaw(line.pose.orientation, 0.0)
    _color(line.color, rgba)  # type: ignore[arg-type]
    line.points.extend([Point3(x=float(x), y=float(y)) for x, y in pts])
    return e


def _world_scene(world: World, t_ns: int) -> Any:
    """Walls as black line segments (the world's bounds when it has none), landmarks as spheres with their ids."""
    upd = SceneUpdate()
    if world.segments.shape[0]:
        pts = world.segments.reshape(-1, 2)
    else:
        x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
        pts = np.array([[x0, y0], [x1, y0], [x1, y0], [x1, y1], [x1, y1], [x0, y1], [x0, y1], [x0, y0]])
    _line_entity(upd, "walls", t_ns, LinePrimitive.LINE_LIST, pts, _BLACK, 0.03)
    e = upd.entities.add(frame_id=WORLD, id="landmarks")
    _stamp(e, t_ns)
    for (x, y), i in zip(world.landmarks, world.landmark_ids, strict=True):
        s = e.spheres.add()
        s.pose.position.x, s.pose.position.y = float(x), float(y)
        _yaw(s.pose.orientation, 0.0)
        s.size.x = s.size.y = s.size.z = 0.15
        _color(s.color, (0.85, 0.1, 0.1, 1.0))
        t = e.texts.add(billboard=True, font_size=12.0, scale_invariant=True, text=str(int(i)))
        t.pose.position.x, t.pose.position.y, t.pose.position.z = float(x), float(y), 0.2
        _yaw(t.pose.orientation, 0.0)
        _color(t.color, _BLACK)
    return upd


def _path_scene(eid: str, poses: Array, rgba: tuple[float, ...], t_ns: int) -> Any:
    upd = SceneUpdate()
    _line_entity(upd, eid, t_ns, LinePrimitive.LINE_STRIP, poses[:, :2], rgba, 0.02)
    return upd


def _rays(eid: str, origin: Array, ends: Array, t_ns: int) -> Any:
    """Rays from ``origin`` (x, y) to each of ``ends`` (m, 2) as a line list (no rays: an empty entity)."""
    pts = np.empty((2 * ends.shape[0], 2))
    pts[0::2], pts[1::2] = origin, ends
    upd = SceneUpdate()
    _line_entity(upd, eid, t_ns, LinePrimitive.LINE_LIST, pts, _RAY, 0.01)
    return upd


def _pose_msg(pose: Array, t_ns: int) -> Any:
    msg = PoseInFrame(frame_id=WORLD)
    _stamp(msg, t_ns)
    msg.pose.position.x, msg.pose.position.y = float(pose[0]), float(pose[1])
    _yaw(msg.pose.orientation, float(pose[2]))
    return msg


def _particle_cloud(p: Array, t_ns: int) -> Any:
    """foxglove.PointCloud of (x, y, theta, weight) float64 rows: exact, and Foxglove can colour by weight."""
    msg = PointCloud(frame_id=WORLD, point_stride=32,
                     fields=_fields([("x", 0, _F64), ("y", 8, _F64), ("theta", 16, _F64), ("weight", 24, _F64)]),
                     data=np.ascontiguousarray(p, dtype="<f8").tobytes())  # fmt: skip
    _stamp(msg, t_ns)
    _yaw(msg.pose.orientation, 0.0)
    return msg


def _data_arrays(res: LocalizationResult) -> dict[str, Array]:
    """The simulated data and the world as named float64 arrays (bools as 0/1, ids as floats)."""
    w = res.world
    out: dict[str, Array] = {
        "times": res.times, "true_poses": res.true_poses, "odometry": res.odometry, "ds_r": res.ds_r,
        "ds_l": res.ds_l, "landmark_z": res.landmark_z, "landmark_valid": res.landmark_valid.astype(np.float64),
        "beam_valid": res.beam_valid.astype(np.float64), "world_landmarks": w.landmarks,
        "world_landmark_ids": w.landmark_ids.astype(np.float64), "world_segments": w.segments,
        "world_bounds": np.asarray(w.bounds, dtype=np.float64),
    }  # fmt: skip
    if res.beam_z is not None:
        out["beam_z"] = res.beam_z
    if w.grid is not None:
        out |= {"grid_occupied": w.grid.occupied.astype(np.float64), "grid_free": w.grid.free.astype(np.float64),
                "grid_origin": w.grid.origin, "grid_resolution": np.array([w.grid.resolution])}  # fmt: skip
    for k, v in res.series.items():
        out[f"series_{k}"] = v
    return out


def _localization_metadata(res: LocalizationResult) -> dict[str, str]:
    cfg = res.config
    meta = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "kind": "localization",
        "config": json.dumps(cfg.to_dict(), sort_keys=True, separators=(",", ":")),
        "config_units": json.dumps(cfg.units(), sort_keys=True, separators=(",", ":")),
        "seed": str(cfg.seed), "n_steps": str(res.n_steps), "filters": json.dumps(list(res.filters)),
    }  # fmt: skip
    for key, value in sorted(res.provenance.items()):
        meta[key] = str(value)
    meta.setdefault("package_version", __version__)
    return meta


def _static(log: _Log, res: LocalizationResult, t0: int) -> None:
    """What does not move: the world, the true and dead-reckoned paths, the exact data."""
    log.put("/world", _world_scene(res.world, t0), t0)
    g = res.world.grid
    if g is not None:
        h = g.resolution
        log.put("/world/occupancy", _grid_msg(g.occupied.astype(np.float64), float(g.origin[0]) + h / 2,
                                              float(g.origin[1]) + h / 2, h, h, t0), t0)  # fmt: skip
    log.put("/truth/path", _path_scene("truth", res.true_poses, _BLACK, t0), t0)
    log.put("/odometry/path", _path_scene("odometry", res.odometry, _GREY, t0), t0)
    log.put(T_DATA, _arrays_msg(_data_arrays(res), t0), t0)


def _measurements(log: _Log, res: LocalizationResult, beam_angles: Array | None, k: int, tk: int) -> None:
    """The measurements of step ``k`` drawn from the true pose (rays are replaced every step)."""
    x, y, th = res.true_poses[k]
    if "landmarks" in res.config.sensors:
        z = res.landmark_z[k][res.landmark_valid[k]]
        ends = np.column_stack([x + z[:, 0] * np.cos(th + z[:, 1]), y + z[:, 0] * np.sin(th + z[:, 1])])
        log.put("/measurements/landmarks", _rays("landmarks", np.array([x, y]), ends, tk), tk)
    if res.beam_z is not None and beam_angles is not None:
        ends = np.zeros((0, 2))
        if res.beam_valid[k]:
            a = th + beam_angles
            ends = np.column_stack([x + res.beam_z[k] * np.cos(a), y + res.beam_z[k] * np.sin(a)])
        log.put("/measurements/beams", _rays("beams", np.array([x, y]), ends, tk), tk)


def _filter_step(log: _Log, name: str, tr: FilterTrack, ell: Array, k: int, t: float, tk: int) -> None:
    base = f"/filters/{name}"
    log.put(f"{base}/pose", _pose_msg(tr.mean[k], tk), tk)
    mu = tr.mean[k]
    pc = PoseCovariance2D(frame_id=WORLD, step=k, time=float(t), x=float(mu[0]), y=float(mu[1]),
                          theta=float(mu[2]), covariance=tr.cov[k].reshape(9).tolist())  # fmt: skip
    _stamp(pc, tk)
    log.put(f"{base}/state", pc, tk)
    upd = SceneUpdate()
    e = _line_entity(upd, f"{name}/ellipse", tk, LinePrimitive.LINE_LOOP, ell[k], _COLORS[name], 0.015)
    e.metadata.add(key="pr", value=repr(PR_3SIGMA))
    log.put(f"{base}/ellipse", upd, tk)
    if k in tr.particles:
        log.put(f"{base}/particles", _particle_cloud(tr.particles[k], tk), tk)
    if k in tr.grids and tr.grid_geometry is not None:
        x0, y0, h, _ = (float(v) for v in tr.grid_geometry)
        log.put(f"{base}/grid", _grid_msg(tr.grids[k], x0, y0, h, h, tk), tk)


def _write_localization_stream(stream: Any, res: LocalizationResult, include_timings: bool) -> None:
    log = _Log(stream)
    log.w.add_metadata(METADATA_NAME, _localization_metadata(res))
    t_ns = [_ns(t) for t in res.times]
    _static(log, res, t_ns[0])
    ellipses = {f: ellipse_polyline(tr.cov[:, :2, :2], PR_3SIGMA, tr.mean[:, :2], _ELLIPSE_POINTS)[:, :-1]
                for f, tr in res.filters.items()}  # fmt: skip
    beams = res.config.beam_sensor()
    beam_angles = None if beams is None else beams.angles
    for k, tk in enumerate(t_ns):
        x, y, th = (float(v) for v in res.true_poses[k])
        tf = FrameTransform(parent_frame_id=WORLD, child_frame_id=BASE)
        _stamp(tf, tk)
        tf.translation.x, tf.translation.y = x, y
        _yaw(tf.rotation, th)
        log.put("/tf", tf, tk)
        log.put("/truth/pose", _pose_msg(res.true_poses[k], tk), tk)
        _measurements(log, res, beam_angles, k, tk)
        for name, tr in res.filters.items():
            _filter_step(log, name, tr, ellipses[name], k, float(res.times[k]), tk)
    t_end = t_ns[-1]
    for name, tr in res.filters.items():
        arrays = dict(tr.series)
        if tr.grid_geometry is not None:
            arrays["grid_geometry"] = tr.grid_geometry
        log.put(f"/filters/{name}/series", _arrays_msg(arrays, t_end, SERIES_UNITS), t_end)
    log.put("/metrics", _metrics_msg(res.metrics, res.metric_units, t_end, res.metric_definitions), t_end)
    if include_timings:
        log.put("/timings", _metrics_msg(res.timings, {k: "s" for k in res.timings}, t_end), t_end)
    log.w.finish()


def localization_log_bytes(result: LocalizationResult, *, include_timings: bool = False) -> bytes:
    """The bytes :func:`write_localization` would write, without touching the file system."""
    return stream_bytes(_write_localization_stream, result, include_timings)


def write_localization(path: str | os.PathLike[str], result: LocalizationResult, *,
                       include_timings: bool = False) -> Path:  # fmt: skip
    """Write a localization log atomically (as :func:`pose_uncertainty.records.run.write_run`).

    Without timings (the default) the same configuration and seed give a byte-identical file.
    """
    with atomic_write(path, "wb") as fh:
        _write_localization_stream(fh, result, include_timings)
    return Path(path)


# ============================================================================= reading


@dataclass(frozen=True, eq=False)
class LocalizationLog(LocalizationResult):
    """A localization run read back from its log (a :class:`LocalizationResult` plus what the file says).

    Attributes (beyond LocalizationResult's)
    ----------------------------------------
    path : Path; metadata : dict — the ``pose_uncertainty.run`` record; library : str
    topics : dict of str to (schema name, message count)
    partial : bool; problems : tuple of str — as :class:`pose_uncertainty.records.run.RunLog`
    """

    path: Path = Path()
    metadata: dict[str, str] = field(default_factory=dict)
    library: str = ""
    topics: dict[str, tuple[str, int]] = field(default_factory=dict)
    partial: bool = False
    problems: tuple[str, ...] = ()

    def state_at(self, t: float) -> dict[str, Any]:
        """State at simulated time ``t`` [s] (the last logged step at or before it).

        Returns
        -------
        dict with ``step``, ``time`` [s], ``truth`` (3,), and per filter name a dict with
        ``mean`` (3,), ``cov`` (3, 3), ``position_error`` [m] and ``heading_error`` [rad].
        """
        if not math.isfinite(t) or self.times.size == 0:
            raise ValueError(f"time must be finite, got {t!r}")
        t0, t1 = float(self.times[0]), float(self.times[-1])
        if not t0 <= t <= t1 + 1e-12:
            raise ValueError(f"time must be within the run (allowed: [{t0:g}, {t1:g}] s), got {t!r}")
        i = int(np.searchsorted(self.times, t + 1e-12, side="right") - 1)
        out: dict[str, Any] = {"step": i, "time": float(self.times[i]), "truth": self.true_poses[i]}
        for name, tr in self.filters.items():
            if i < tr.mean.shape[0]:
                d = tr.mean[i] - self.true_poses[i]
                out[name] = {"mean": tr.mean[i], "cov": tr.cov[i], "position_error": float(math.hypot(d[0], d[1])),
                             "heading_error": float(abs(math.remainder(float(d[2]), 2 * math.pi)))}  # fmt: skip
        return out

    def summary(self) -> str:
        """Human-readable summary (see :func:`format_localization_summary`)."""
        return format_localization_summary(self)


def _decoder(p: Path, records: list[Any]) -> tuple[Any, dict[str, tuple[str, int]]]:
    """``decode(topic, cls)`` over the records, and the topics with their schema and message count."""
    schemas = {r.id: r for r in records if isinstance(r, Schema)}
    channels = {r.id: r for r in records if isinstance(r, Channel)}
    by_topic: dict[str, list[Message]] = {}
    for r in records:
        if isinstance(r, Message):
            ch = channels.get(r.channel_id)
            if ch is None:
                raise RunLogError(f"{p}: message on unknown channel {r.channel_id}")
            by_topic.setdefault(ch.topic, []).append(r)
    topic_schema = {ch.topic: (schemas[ch.schema_id].name if ch.schema_id in schemas else "") for ch in channels.values()}
    topics = {t: (topic_schema.get(t, ""), len(m)) for t, m in sorted(by_topic.items())}

    def decode(topic: str, cls: Any) -> list[Any]:
        msgs = by_topic.get(topic, [])
        expected = cls.DESCRIPTOR.full_name
        if msgs and topic_schema.get(topic) != expected:
            raise RunLogError(f"{p}: topic {topic} has schema {topic_schema.get(topic)!r}, expected {expected!r}")
        try:
            return [cls.FromString(m.data) for m in msgs]
        except DecodeError as exc:
            raise RunLogError(f"{p}: a message on {topic} is not a valid {expected} ({exc})") from None

    return decode, topics


def _arrays_of(p: Path, msg: Any) -> dict[str, Array]:
    out: dict[str, Array] = {}
    for item in msg.arrays:
        shape = tuple(int(s) for s in item.values.shape)
        v = np.frombuffer(item.values.data, dtype="<f8")
        if v.size != int(np.prod(shape)):
            raise RunLogError(f"{p}: array {item.name!r} holds {v.size} values, its shape says {shape}")
        out[item.name] = v.reshape(shape).astype(np.float64)
    return out


def _t_ns(msg: Any) -> int:
    return int(msg.timestamp.seconds) * 1_000_000_000 + int(msg.timestamp.nanos)


def _world_of(data: dict[str, Array], config: LocalizationConfig) -> World:
    grid = None
    if "grid_occupied" in data:
        grid = OccupancyGrid(data["grid_occupied"] > 0.5, data["grid_free"] > 0.5, float(data["grid_resolution"][0]),
                             data["grid_origin"])  # fmt: skip
    b = data["world_bounds"]
    return World(data["world_landmarks"].reshape(-1, 2), data["world_landmark_ids"].astype(np.int64), grid,
                 data["world_segments"].reshape(-1, 4), (float(b[0]), float(b[1]), float(b[2]), float(b[3])),
                 str(config.world.get("name", "")))  # fmt: skip


def _track(p: Path, name: str, decode: Any, step_of_ns: dict[int, int]) -> FilterTrack:
    base = f"/filters/{name}"
    states = sorted(decode(f"{base}/state", PoseCovariance2D), key=lambda m: m.step)
    steps = [m.step for m in states]
    if steps != list(range(len(steps))):
        raise RunLogError(f"{p}: {base}/state holds steps {steps[:3]}… (count {len(steps)}), expected 0, 1, 2, …")
    mean = np.array([[m.x, m.y, m.theta] for m in states], dtype=np.float64).reshape(-1, 3)
    cov = np.array([list(m.covariance) for m in states], dtype=np.float64).reshape(-1, 3, 3)
    series_msgs = decode(f"{base}/series", NamedArrays)
    series = _arrays_of(p, series_msgs[-1]) if series_msgs else {}
    geometry = series.pop("grid_geometry", None)

    def step(msg: Any, what: str) -> int:
        t = _t_ns(msg)
        if t not in step_of_ns:
            raise RunLogError(f"{p}: {base}/{what} at {t} ns matches no logged step")
        return step_of_ns[t]

    particles: dict[int, Array] = {}
    for msg in decode(f"{base}/particles", PointCloud):
        layout = [(f.name, f.offset, f.type) for f in msg.fields]
        if msg.point_stride != 32 or [x[0] for x in layout] != ["x", "y", "theta", "weight"]:
            raise RunLogError(f"{p}: particle cloud layout {layout} is not (x, y, theta, weight) float64")
        particles[step(msg, "particles")] = np.frombuffer(msg.data, dtype="<f8").reshape(-1, 4).astype(np.float64)
    grids: dict[int, Array] = {}
    cell = np.dtype([("mass", "<f8"), ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("alpha", "u1")])
    for msg in decode(f"{base}/grid", Grid):
        nx = int(msg.column_count)
        rows = np.frombuffer(msg.data, dtype=cell).reshape(-1, nx)
        grids[step(msg, "grid")] = np.ascontiguousarray(rows["mass"].T, dtype=np.float64)
    return FilterTrack(name, mean, cov, series, particles, grids, geometry)


def assemble(p: Path, records: list[Any], meta: dict[str, str], library: str, partial: bool,
             problem: str | None) -> LocalizationLog:  # fmt: skip
    """Build a :class:`LocalizationLog` from the CRC-checked records of a file (called by ``open_run``)."""
    if meta.get("format_version") != FORMAT_VERSION:
        raise RunLogError(f"{p}: localization log format version {meta.get('format_version')!r} is not supported "
                          f"(this reader: {FORMAT_VERSION})")  # fmt: skip
    try:
        config = LocalizationConfig.from_dict(json.loads(meta["config"]))
    except (KeyError, ValueError) as exc:
        raise RunLogError(f"{p}: the logged localization config is invalid ({exc})") from None
    decode, topics = _decoder(p, records)
    data_msgs = decode(T_DATA, NamedArrays)
    if not data_msgs:
        raise RunLogError(f"{p}: {T_DATA} is missing; nothing to read")
    data = _arrays_of(p, data_msgs[0])
    times = data["times"]
    step_of_ns = {_ns(t): i for i, t in enumerate(times)}
    filters = {name: _track(p, name, decode, step_of_ns) for name in json.loads(meta.get("filters", "[]"))}
    for name, tr in filters.items():
        if not partial and tr.mean.shape[0] != times.size:
            raise RunLogError(f"{p}: /filters/{name}/state holds {tr.mean.shape[0]} steps, expected {times.size}")
    mets = decode("/metrics", runlog.Metrics)
    last = mets[-1].metrics if mets else []
    tims = decode("/timings", runlog.Metrics)
    return LocalizationLog(
        config=config, world=_world_of(data, config), times=times, true_poses=data["true_poses"],
        odometry=data["odometry"], ds_r=data["ds_r"], ds_l=data["ds_l"], landmark_z=data["landmark_z"],
        landmark_valid=data["landmark_valid"] > 0.5, beam_z=data.get("beam_z"), beam_valid=data["beam_valid"] > 0.5,
        filters=filters, series={k[len("series_"):]: v for k, v in data.items() if k.startswith("series_")},
        metrics={m.name: float(m.value) for m in last}, metric_units={m.name: m.unit for m in last},
        metric_definitions={m.name: m.definition for m in last},
        timings={m.name: float(m.value) for m in (tims[-1].metrics if tims else [])},
        provenance={k: meta[k] for k in PROVENANCE_KEYS if k in meta}, path=p, metadata=meta, library=library,
        topics=topics, partial=partial, problems=(problem,) if problem else (),
    )  # fmt: skip


# ============================================================================= summary, verification


def format_localization_summary(log: LocalizationLog) -> str:
    """Summary of a localization log: config, topics, world, each filter's final state and measures."""
    lines = [f"localization log {log.path}"]
    if log.partial:
        lines.append(f"PARTIAL   {'; '.join(log.problems)}")
    lines.append(f"written by {log.library}; format {log.metadata.get('format')} v{log.metadata.get('format_version')}")
    lines.extend(f"  {k}: {log.provenance[k]}" for k in PROVENANCE_KEYS if k in log.provenance)
    lines.append("config")
    lines.extend(f"  {ln}" for ln in _flatten(log.config.to_dict(), log.config.units()))
    lines.append("topics")
    width = max((len(t) for t in log.topics), default=0)
    lines.extend(f"  {t:<{width}}  {c:>7}  {s}" for t, (s, c) in log.topics.items())
    w = log.world
    grid = f"; occupancy grid {w.grid.shape} cells of {w.grid.resolution:g} m" if w.grid is not None else ""
    lines.append(f"world: {w.n_landmarks} landmarks, {w.segments.shape[0]} wall segments, bounds {w.bounds}{grid}")
    if log.times.size:
        i = log.times.size - 1
        lines.append(f"final state (step {i}, t = {log.times[i]:.9g} s), truth {np.array2string(log.true_poses[i], precision=6, separator=', ')}")
        for name, tr in log.filters.items():
            if tr.mean.shape[0] > i:
                sd = np.sqrt(np.maximum(np.diag(tr.cov[i]), 0.0))
                lines.append(f"  {name:<9} mean {np.array2string(tr.mean[i], precision=6, separator=', ')}  "
                             f"σ (x, y, θ) {np.array2string(sd, precision=4, separator=', ')}")  # fmt: skip
    if log.metrics:
        lines.append("metrics")
        lines.extend(f"  {k} = {log.metrics[k]:.9g} {log.metric_units.get(k, '')}".rstrip() for k in sorted(log.metrics))
    if log.timings:
        lines.append("timings (wall clock, not reproducible)")
        lines.extend(f"  {k} = {log.timings[k]:.4g} s" for k in sorted(log.timings))
    return "\n".join(lines)


def compare_localization(logged: LocalizationResult, fresh: LocalizationResult) -> list[str]:
    """Bit-exact comparison of two localization results; one line per difference (empty = identical).

    Timings are not compared; provenance differences are ``"note: "`` lines, not mismatches.
    """
    out: list[str] = []
    if logged.config != fresh.config:
        out.append("config differs")
    for name in ("times", "true_poses", "odometry", "ds_r", "ds_l", "landmark_z", "landmark_valid", "beam_z",
                 "beam_valid"):  # fmt: skip
        d = _diff(name, getattr(logged, name), getattr(fresh, name))
        if d:
            out.append(d)
    for name in ("landmarks", "landmark_ids", "segments"):
        d = _diff(f"world.{name}", getattr(logged.world, name), getattr(fresh.world, name))
        if d:
            out.append(d)
    ga, gb = logged.world.grid, fresh.world.grid
    if (ga is None) != (gb is None) or (ga is not None and gb is not None and not (
            np.array_equal(ga.occupied, gb.occupied) and np.array_equal(ga.free, gb.free)
            and ga.resolution == gb.resolution and np.array_equal(ga.origin, gb.origin))):  # fmt: skip
        out.append("world.grid differs")
    out.extend(_compare_dicts("series", logged.series, fresh.series))
    if list(logged.filters) != list(fresh.filters):
        out.append(f"filters: {list(logged.filters)} != {list(fresh.filters)}")
    else:
        for name, a in logged.filters.items():
            b = fresh.filters[name]
            for attr in ("mean", "cov", "grid_geometry"):
                d = _diff(f"{name}.{attr}", getattr(a, attr), getattr(b, attr))
                if d:
                    out.append(d)
            for attr in ("series", "particles", "grids"):
                out.extend(_compare_dicts(f"{name}.{attr}", getattr(a, attr), getattr(b, attr)))
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


def _compare_dicts(what: str, a: dict[Any, Array], b: dict[Any, Array]) -> list[str]:
    if sorted(a) != sorted(b):
        return [f"{what}: keys {sorted(a)} != {sorted(b)}"]
    return [d for k in sorted(a) if (d := _diff(f"{what}[{k}]", a[k], b[k]))]


def verify_localization(log: LocalizationLog) -> Comparison:
    """Recompute a logged localization run from its config and seed and compare (as ``verify_run``).

    The fresh log is written with the logged provenance and timings; every record of the two
    logs is compared within the reproducibility contract
    (:func:`~pose_uncertainty.records.run.verify_log`).
    """
    if log.partial:
        return Comparison(status=MISMATCH, mismatches=["the log is partial; a partial log cannot be verified"])
    fresh = execute_localization(log.config)
    same = LocalizationResult(**{f: getattr(fresh, f) for f in LocalizationResult.__dataclass_fields__
                                 if f not in ("provenance", "timings")},
                              provenance=dict(log.provenance), timings=dict(log.timings))  # fmt: skip
    return runlog.verify_log(log, localization_log_bytes(same, include_timings=bool(log.timings)))


runlog.LOG_KINDS[FORMAT] = LogKind(assemble, verify_localization)
