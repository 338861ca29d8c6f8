"""Localization run logs: one MCAP file per run, to watch the filters in Foxglove and to replay them.

The container, compression, CRCs, atomic write and byte-level determinism are those of
every log kind (:mod:`pose_uncertainty.records.mcap_io`), the messages those of
:mod:`pose_uncertainty.records.foxglove`; the metadata record ``pose_uncertainty.run``
carries ``format: pose-uncertainty-localization``, and
:func:`pose_uncertainty.records.formats.open_run` hands such a file to
:data:`LOCALIZATION_LOG` (this kind's write / read / summary / verify, registered in
:data:`~pose_uncertainty.records.formats.FORMATS`). Log time = simulated time (ns); frame ``world``.

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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.Grid_pb2 import Grid
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from numpy.typing import NDArray

from ..analysis.localization import SERIES_UNITS
from ..core.stats import PR_3SIGMA
from ..experiments.localization import (
    FilterTrack,
    LocalizationConfig,
    LocalizationResult,
    execute_localization,
)
from ..localization.world import OccupancyGrid, World
from ..methods.covariance import ellipse_polyline
from . import foxglove as fg
from .formats import (
    LogFile,
    LogFormat,
    check_version,
    compare_dicts,
    compare_measures,
    diff,
    file_fields,
    register,
    step_at,
    summary_head,
    summary_measures,
    verify_recomputed,
)
from .mcap_io import (
    Container,
    LogWriter,
    Records,
    RunLogError,
    message_ns,
    metadata_record,
    stream_bytes,
    write_atomically,
)
from .reproducibility import Comparison

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "LOCALIZATION_LOG",
    "LocalizationLog",
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
_GREY = (0.55, 0.55, 0.55, 1.0)  # the dead-reckoned path
_RAY = (0.8, 0.0, 0.6, 0.8)  # measurements
_LANDMARK = (0.85, 0.1, 0.1, 1.0)
_ELLIPSE_POINTS = 48
#: The columns of a particle cloud: Foxglove can colour the particles by weight.
PARTICLE_COLUMNS = ("x", "y", "theta", "weight")
T_DATA = "/localization/data"
Array = NDArray[np.float64]


# ============================================================================= writing


def _world_scene(world: World, t_ns: int) -> Any:
    """Walls as black line segments (the world's bounds when it has none), landmarks as spheres with their ids."""
    upd = SceneUpdate()
    if world.segments.shape[0]:
        pts = world.segments.reshape(-1, 2)
    else:
        x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
        pts = np.array([[x0, y0], [x1, y0], [x1, y0], [x1, y1], [x1, y1], [x0, y1], [x0, y1], [x0, y0]])
    fg.line_entity(upd, "walls", t_ns, fg.LINE_LIST, pts, fg.BLACK, 0.03)
    e = upd.entities.add(frame_id=fg.WORLD, id="landmarks")
    fg.stamp(e, t_ns)
    for (x, y), i in zip(world.landmarks, world.landmark_ids, strict=True):
        s = e.spheres.add()
        s.pose.position.x, s.pose.position.y = float(x), float(y)
        fg.yaw(s.pose.orientation, 0.0)
        s.size.x = s.size.y = s.size.z = 0.15
        fg.color(s.color, _LANDMARK)
        t = e.texts.add(billboard=True, font_size=12.0, scale_invariant=True, text=str(int(i)))
        t.pose.position.x, t.pose.position.y, t.pose.position.z = float(x), float(y), 0.2
        fg.yaw(t.pose.orientation, 0.0)
        fg.color(t.color, fg.BLACK)
    return upd


def _rays(eid: str, origin: Array, ends: Array, t_ns: int) -> Any:
    """Rays from ``origin`` (x, y) to each of ``ends`` (m, 2) as a line list (no rays: an empty entity)."""
    pts = np.empty((2 * ends.shape[0], 2))
    pts[0::2], pts[1::2] = origin, ends
    return fg.line_scene(eid, pts, fg.LINE_LIST, _RAY, 0.01, t_ns)


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
    head = {"format": FORMAT, "format_version": FORMAT_VERSION, "kind": "localization"}
    return metadata_record(head, res.config, res.n_steps, {"filters": json.dumps(list(res.filters))}, res.provenance)


def _static(log: LogWriter, res: LocalizationResult, t0: int) -> None:
    """What does not move: the world, the true and dead-reckoned paths, the exact data."""
    log.put("/world", _world_scene(res.world, t0), t0)
    g = res.world.grid
    if g is not None:
        h = g.resolution
        log.put("/world/occupancy", fg.grid_msg(g.occupied.astype(np.float64), float(g.origin[0]) + h / 2,
                                                float(g.origin[1]) + h / 2, h, h, t0), t0)  # fmt: skip
    log.put("/truth/path", fg.line_scene("truth", res.true_poses[:, :2], fg.LINE_STRIP, fg.BLACK, 0.02, t0), t0)
    log.put("/odometry/path", fg.line_scene("odometry", res.odometry[:, :2], fg.LINE_STRIP, _GREY, 0.02, t0), t0)
    log.put(T_DATA, fg.arrays_msg(_data_arrays(res), t0), t0)


def _measurements(log: LogWriter, res: LocalizationResult, beam_angles: Array | None, k: int, tk: int) -> None:
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


def _filter_step(log: LogWriter, name: str, tr: FilterTrack, ell: Array, k: int, t: float, tk: int) -> None:
    base = f"/filters/{name}"
    log.put(f"{base}/pose", fg.pose_in_frame(tr.mean[k], tk), tk)
    log.put(f"{base}/state", fg.pose_covariance(k, t, tr.mean[k], tr.cov[k], tk), tk)
    upd = SceneUpdate()
    e = fg.line_entity(upd, f"{name}/ellipse", tk, fg.LINE_LOOP, ell[k], _COLORS[name], 0.015)
    e.metadata.add(key="pr", value=repr(PR_3SIGMA))
    log.put(f"{base}/ellipse", upd, tk)
    if k in tr.particles:
        log.put(f"{base}/particles", fg.float64_cloud(tr.particles[k], PARTICLE_COLUMNS, tk), tk)
    if k in tr.grids and tr.grid_geometry is not None:
        x0, y0, h, _ = (float(v) for v in tr.grid_geometry)
        log.put(f"{base}/grid", fg.grid_msg(tr.grids[k], x0, y0, h, h, tk), tk)


def _put_series_and_measures(log: LogWriter, res: LocalizationResult, t_end: int, include_timings: bool) -> None:
    """What belongs to the end of the run: each filter's series, the metrics, the timings."""
    for name, tr in res.filters.items():
        arrays = dict(tr.series)
        if tr.grid_geometry is not None:
            arrays["grid_geometry"] = tr.grid_geometry
        log.put(f"/filters/{name}/series", fg.arrays_msg(arrays, t_end, SERIES_UNITS), t_end)
    log.put("/metrics", fg.metrics_msg(res.metrics, res.metric_units, t_end, res.metric_definitions), t_end)
    if include_timings:
        log.put("/timings", fg.metrics_msg(res.timings, {k: "s" for k in res.timings}, t_end), t_end)


def _write_localization_stream(stream: Any, res: LocalizationResult, include_timings: bool) -> None:
    log = LogWriter(stream, _localization_metadata(res))
    t_ns = [fg.ns(t) for t in res.times]
    _static(log, res, t_ns[0])
    ellipses = {f: ellipse_polyline(tr.cov[:, :2, :2], PR_3SIGMA, tr.mean[:, :2], _ELLIPSE_POINTS)[:, :-1]
                for f, tr in res.filters.items()}  # fmt: skip
    beams = res.config.beam_sensor()
    beam_angles = None if beams is None else beams.angles
    for k, tk in enumerate(t_ns):
        log.put("/tf", fg.frame_transform(res.true_poses[k], tk), tk)
        log.put("/truth/pose", fg.pose_in_frame(res.true_poses[k], tk), tk)
        _measurements(log, res, beam_angles, k, tk)
        for name, tr in res.filters.items():
            _filter_step(log, name, tr, ellipses[name], k, float(res.times[k]), tk)
    _put_series_and_measures(log, res, t_ns[-1], include_timings)
    log.finish()


def localization_log_bytes(result: LocalizationResult, *, include_timings: bool = False) -> bytes:
    """The bytes :func:`write_localization` would write, without touching the file system."""
    return stream_bytes(_write_localization_stream, result, include_timings)


def write_localization(path: str | os.PathLike[str], result: LocalizationResult, *,
                       include_timings: bool = False) -> Path:  # fmt: skip
    """Write a localization log atomically (as :func:`pose_uncertainty.records.run.write_run`).

    Without timings (the default) the same configuration and seed give a byte-identical file.
    """
    return write_atomically(path, _write_localization_stream, result, include_timings)


# ============================================================================= reading


@dataclass(frozen=True, eq=False)
class LocalizationLog(LocalizationResult, LogFile):
    """A localization run read back from its log (a :class:`LocalizationResult` plus what the file says).

    Attributes (beyond LocalizationResult's): those of
    :class:`~pose_uncertainty.records.formats.LogFile` (path, metadata, library, topics, partial, problems).
    """

    def state_at(self, t: float) -> dict[str, Any]:
        """State at simulated time ``t`` [s] (the last logged step at or before it).

        Returns
        -------
        dict with ``step``, ``time`` [s], ``truth`` (3,), and per filter name a dict with
        ``mean`` (3,), ``cov`` (3, 3), ``position_error`` [m] and ``heading_error`` [rad].
        """
        i = step_at(self.times, t)
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


def _world_of(data: dict[str, Array], config: LocalizationConfig) -> World:
    grid = None
    if "grid_occupied" in data:
        grid = OccupancyGrid(data["grid_occupied"] > 0.5, data["grid_free"] > 0.5, float(data["grid_resolution"][0]),
                             data["grid_origin"])  # fmt: skip
    b = data["world_bounds"]
    return World(data["world_landmarks"].reshape(-1, 2), data["world_landmark_ids"].astype(np.int64), grid,
                 data["world_segments"].reshape(-1, 4), (float(b[0]), float(b[1]), float(b[2]), float(b[3])),
                 str(config.world.get("name", "")))  # fmt: skip


def _track(rec: Records, name: str, step_of_ns: dict[int, int]) -> FilterTrack:
    base = f"/filters/{name}"
    states = sorted(rec.decode(f"{base}/state", fg.PoseCovariance2D), key=lambda m: m.step)
    steps = [m.step for m in states]
    if steps != list(range(len(steps))):
        raise RunLogError(f"{rec.p}: {base}/state holds steps {steps[:3]}… (count {len(steps)}), expected 0, 1, 2, …")
    mean = np.array([[m.x, m.y, m.theta] for m in states], dtype=np.float64).reshape(-1, 3)
    cov = np.array([list(m.covariance) for m in states], dtype=np.float64).reshape(-1, 3, 3)
    series = rec.last_arrays(f"{base}/series") or {}
    geometry = series.pop("grid_geometry", None)

    def step(msg: Any, what: str) -> int:
        t = message_ns(msg)
        if t not in step_of_ns:
            raise RunLogError(f"{rec.p}: {base}/{what} at {t} ns matches no logged step")
        return step_of_ns[t]

    particles = {step(m, "particles"): rec.cloud(m, PARTICLE_COLUMNS) for m in rec.decode(f"{base}/particles", PointCloud)}
    grids = {step(m, "grid"): rec.grid_mass(m) for m in rec.decode(f"{base}/grid", Grid)}
    return FilterTrack(name, mean, cov, series, particles, grids, geometry)


def _read_localization(c: Container) -> LocalizationLog:
    """Build a :class:`LocalizationLog` from the validated container of a localization run's log."""
    check_version(c, LOCALIZATION_LOG, "localization log")
    meta = c.metadata
    try:
        config = LocalizationConfig.from_dict(json.loads(meta["config"]))
    except (KeyError, ValueError) as exc:
        raise RunLogError(f"{c.path}: the logged localization config is invalid ({exc})") from None
    rec = Records(c)
    data_msgs = rec.decode(T_DATA, fg.NamedArrays)
    if not data_msgs:
        raise RunLogError(f"{c.path}: {T_DATA} is missing; nothing to read")
    data = rec.arrays(data_msgs[0])
    times = data["times"]
    step_of_ns = {fg.ns(t): i for i, t in enumerate(times)}
    filters = {name: _track(rec, name, step_of_ns) for name in json.loads(meta.get("filters", "[]"))}
    for name, tr in filters.items():
        if not c.partial and tr.mean.shape[0] != times.size:
            raise RunLogError(f"{c.path}: /filters/{name}/state holds {tr.mean.shape[0]} steps, expected {times.size}")
    metrics, units, definitions = rec.metrics("/metrics")
    return LocalizationLog(
        config=config, world=_world_of(data, config), times=times, true_poses=data["true_poses"],
        odometry=data["odometry"], ds_r=data["ds_r"], ds_l=data["ds_l"], landmark_z=data["landmark_z"],
        landmark_valid=data["landmark_valid"] > 0.5, beam_z=data.get("beam_z"), beam_valid=data["beam_valid"] > 0.5,
        filters=filters, series={k[len("series_"):]: v for k, v in data.items() if k.startswith("series_")},
        metrics=metrics, metric_units=units, metric_definitions=definitions, timings=rec.metrics("/timings")[0],
        **file_fields(c, rec.topics),
    )  # fmt: skip


# ============================================================================= summary, verification


def format_localization_summary(log: LocalizationLog) -> str:
    """Summary of a localization log: config, topics, world, each filter's final state and measures."""
    lines = summary_head(log, "localization log")
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
    return "\n".join(lines + summary_measures(log))


def _same_grid(ga: OccupancyGrid | None, gb: OccupancyGrid | None) -> bool:
    if ga is None or gb is None:
        return ga is gb
    return (np.array_equal(ga.occupied, gb.occupied) and np.array_equal(ga.free, gb.free)
            and ga.resolution == gb.resolution and np.array_equal(ga.origin, gb.origin))  # fmt: skip


def compare_localization(logged: LocalizationResult, fresh: LocalizationResult) -> list[str]:
    """Bit-exact comparison of two localization results; one line per difference (empty = identical).

    Timings are not compared; provenance differences are ``"note: "`` lines, not mismatches.
    """
    out: list[str] = []
    if logged.config != fresh.config:
        out.append("config differs")
    out.extend(d for name in ("times", "true_poses", "odometry", "ds_r", "ds_l", "landmark_z", "landmark_valid",
                              "beam_z", "beam_valid") if (d := diff(name, getattr(logged, name), getattr(fresh, name))))
    out.extend(d for name in ("landmarks", "landmark_ids", "segments")
               if (d := diff(f"world.{name}", getattr(logged.world, name), getattr(fresh.world, name))))  # fmt: skip
    if not _same_grid(logged.world.grid, fresh.world.grid):
        out.append("world.grid differs")
    out.extend(compare_dicts("series", logged.series, fresh.series))
    if list(logged.filters) != list(fresh.filters):
        out.append(f"filters: {list(logged.filters)} != {list(fresh.filters)}")
    else:
        for name, a in logged.filters.items():
            b = fresh.filters[name]
            out.extend(d for attr in ("mean", "cov", "grid_geometry")
                       if (d := diff(f"{name}.{attr}", getattr(a, attr), getattr(b, attr))))  # fmt: skip
            for attr in ("series", "particles", "grids"):
                out.extend(compare_dicts(f"{name}.{attr}", getattr(a, attr), getattr(b, attr)))
    return out + compare_measures(logged, fresh)


def verify_localization(log: LocalizationLog) -> Comparison:
    """Recompute a logged localization run from its config and seed and compare (as ``verify_run``).

    The fresh log is written with the logged provenance and timings; every record of the two
    logs is compared within the reproducibility contract
    (:func:`~pose_uncertainty.records.formats.verify_recomputed`).
    """
    return verify_recomputed(log, execute_localization(log.config), localization_log_bytes)


#: The localization run log's write / read / summary / verify.
LOCALIZATION_LOG = register(LogFormat(FORMAT, FORMAT_VERSION, write_localization, localization_log_bytes,
                                      _read_localization, format_localization_summary, verify_localization))
