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
:func:`open_run` (:func:`pose_uncertainty.records.formats.open_run`, which reads every
kind of log) reads the whole file, validates the magic, every chunk CRC, the
data-section CRC and the summary CRC (:mod:`pose_uncertainty.records.mcap_io`), and raises
:class:`RunLogError` (a ``ValueError`` with one line: ``"<path>: <problem>"``) for an empty,
truncated, corrupted or foreign file. ``open_run(path, recover=True)`` returns what an
incomplete file holds (whole, CRC-checked chunks only) and warns with
:class:`PartialLogWarning`.

The messages are built by :mod:`pose_uncertainty.records.foxglove`; :data:`RUN_LOG` is this
kind's :class:`~pose_uncertainty.records.formats.LogFormat` (write / read / summary / verify).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from numpy.typing import NDArray

from ..experiments.config import RunConfig
from ..experiments.run import RunResult, execute
from ..methods import covariance
from ..methods.maps import ProbabilityMap
from . import foxglove as fg
from .formats import (
    LogFile,
    LogFormat,
    check_version,
    compare_measures,
    diff,
    file_fields,
    open_run,
    recomputable,
    register,
    step_at,
    summary_head,
    summary_measures,
    verify_log,
    verify_recomputed,
    verify_run,
)
from .mcap_io import (
    Container,
    LogWriter,
    PartialLogWarning,
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
    "READABLE_VERSIONS",
    "RUN_LOG",
    "TOPICS",
    "PartialLogWarning",
    "RunLog",
    "RunLogError",
    "compare_results",
    "format_summary",
    "log_bytes",
    "open_run",
    "recomputable",
    "stream_bytes",
    "verify_log",
    "verify_run",
    "write_run",
]

FORMAT = "pose-uncertainty-runlog"

#: The version of the run-log format (the ``format_version`` of the metadata record).
#:
#: * ``1`` — the first MCAP run log.
#: * ``2`` — every measure computed once in the run and logged on ``/metrics`` with its unit and
#:   definition (read back, never recomputed, by tables, claims and the report).
#: * ``3`` — one drive stack: the differential drive is computed by the common drive stack
#:   (:class:`pose_uncertainty.core.drives.Differential`: Method A of
#:   :mod:`pose_uncertainty.methods.drive_covariance` in closed form, the Monte Carlo of
#:   :mod:`pose_uncertainty.methods.drive_sampling`, the exponential-coordinates Gaussian of
#:   :func:`pose_uncertainty.methods.expcoords.propagate_twists`). Topics, messages and metadata keys
#:   are those of version 2. A run without a ``drive`` section logs what it logged in version 2 —
#:   its configuration without a ``drive`` key, Method C's measures — with numbers from the
#:   trajectory's wheel travels as a ``Differential`` path: the Monte Carlo clouds bit for bit,
#:   Method A's and the banana's covariances within rounding (about 10⁻¹⁵ of their scale).
#:
#: Logs of the versions in :data:`READABLE_VERSIONS` are read, summarised and verified. Verifying
#: recomputes with the current code and writes the fresh log under the logged version (the
#: layout is the same), so a version-2 log verifies ``identical`` where the numbers are the same
#: bits and ``equal within tolerance`` where they moved by rounding — the expected result.
FORMAT_VERSION = "3"
#: Versions of the run-log format this code reads and verifies (same topics and metadata keys).
READABLE_VERSIONS: tuple[str, ...] = ("2", "3")

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

#: The columns of a pose cloud (Monte Carlo end poses, checkpoints, a map's sampler draws).
POSE_COLUMNS = ("x", "y", "theta")
_ELLIPSE_POINTS = 48
_BLUE = (0.0, 0.25, 1.0, 1.0)  # an ellipse kept at a mark
_RED = (0.9, 0.0, 0.0, 1.0)  # the final ellipse
_GREY = (0.5, 0.5, 0.5, 0.8)  # the current ellipse


# --- maps --------------------------------------------------------------------------------


def _grid(mp: ProbabilityMap, t_ns: int) -> Any:
    """foxglove.Grid: θ-marginal mass per cell (float64, exact) and a grey RGBA, darker = more probable."""
    marg = mp.marginal_xy()  # (nx, ny) [1]
    nx, ny = marg.shape
    dx = float(mp.x[1] - mp.x[0]) if nx > 1 else 0.01
    dy = float(mp.y[1] - mp.y[0]) if ny > 1 else 0.01
    return fg.grid_msg(marg, float(mp.x[0]), float(mp.y[0]), dx, dy, t_ns)


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
    msg = fg.ProbabilityMap3D(
        frame_id=fg.WORLD,
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
    fg.stamp(msg, t_ns)
    msg.values.shape.extend(mp.values.shape)
    msg.values.data = np.ascontiguousarray(mp.values, dtype="<f8").tobytes()
    return msg


# --- writing -----------------------------------------------------------------------------


def _metadata(result: RunResult, version: str = FORMAT_VERSION) -> dict[str, str]:
    extra = {"checkpoints": json.dumps(sorted(result.checkpoints)), "maps": json.dumps([m.name for m in result.maps])}
    return metadata_record({"format": FORMAT, "format_version": version}, result.config, result.n_steps,
                           extra, result.provenance)  # fmt: skip


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


def _ellipse_msg(i: int, t_ns: int, ring: NDArray, pr: float, marked: bool, final: bool) -> Any:
    """The Pr-ellipse of step ``i``: the current one (grey, red at the end) and, at marks, a kept one (blue)."""
    upd = SceneUpdate()
    for eid in ["ellipse/current"] + ([f"ellipse/{i:06d}"] if marked else []):
        rgba = _RED if final else (_BLUE if eid != "ellipse/current" else _GREY)
        e = fg.line_entity(upd, eid, t_ns, fg.LINE_LOOP, ring, rgba, 0.004)
        e.metadata.add(key="pr", value=repr(pr))
        e.metadata.add(key="step", value=str(i))
    return upd


def _put_steps(
    log: LogWriter, result: RunResult, t_ns: list[int], progress: Callable[[int, int], None] | None = None
) -> None:
    """Every step: frame, pose, covariance, ellipse, and the checkpoint clouds (``progress(i, N+1)``)."""
    poses, covs, n = result.poses, result.covs, result.times.size
    # closed polylines (first vertex repeated): drop the repeat for a LINE_LOOP
    ell = covariance.ellipse_polyline(covs[:, :2, :2], result.config.pr, poses[:, :2], _ELLIPSE_POINTS)[:, :-1]
    marks = set(result.ellipse_steps())
    for i in range(n):
        tk = t_ns[i]
        log.put(T_TF, fg.frame_transform(poses[i], tk), tk)
        log.put(T_POSE, fg.pose_in_frame(poses[i], tk), tk)
        log.put(T_COV, fg.pose_covariance(i, float(result.times[i]), poses[i], covs[i], tk), tk)
        log.put(T_ELLIPSE, _ellipse_msg(i, tk, ell[i], result.config.pr, i in marks, i == n - 1), tk)
        if i in result.checkpoints:
            log.put(T_CHECK, fg.float64_cloud(result.checkpoints[i], POSE_COLUMNS, tk), tk)
        if progress is not None:
            progress(i + 1, n)


def _put_end(log: LogWriter, result: RunResult, t_end: int, include_timings: bool) -> None:
    """What belongs to the end of the run: clouds, maps and their samplers, metrics, timings."""
    if result.end_poses is not None:
        log.put(T_END, fg.float64_cloud(result.end_poses, POSE_COLUMNS, t_end), t_end)
    for mp in result.maps:
        log.put(f"/maps/{mp.name}/grid", _grid(mp, t_end), t_end)
        log.put(f"/maps/{mp.name}/volume", _volume(mp, t_end), t_end)
        sampler = result.map_samplers.get(mp.name)
        if sampler is not None and len(sampler):
            log.put(f"/maps/{mp.name}/sampler", fg.float64_cloud(sampler, POSE_COLUMNS, t_end), t_end)
    log.put(T_METRICS, fg.metrics_msg(result.metrics, result.metric_units, t_end, result.metric_definitions), t_end)
    if include_timings:
        log.put(T_TIMINGS, fg.metrics_msg(result.timings, {k: "s" for k in result.timings}, t_end), t_end)


def _write_stream(
    stream: Any,
    result: RunResult,
    include_timings: bool,
    progress: Callable[[int, int], None] | None = None,
    version: str = FORMAT_VERSION,
) -> None:
    _check_result(result)
    log = LogWriter(stream, _metadata(result, version))
    t_ns = [fg.ns(t) for t in result.times]
    # the whole nominal path, once, at t = 0, as one black line strip
    path = fg.line_scene("path", result.poses[:, :2], fg.LINE_STRIP, fg.BLACK, 0.005, t_ns[0])
    log.put(T_PATH, path, t_ns[0])
    _put_steps(log, result, t_ns, progress)
    _put_end(log, result, t_ns[-1], include_timings)
    log.finish()


def log_bytes(result: RunResult, *, include_timings: bool = False, format_version: str = FORMAT_VERSION) -> bytes:
    """The bytes :func:`write_run` would write, without touching the file system.

    ``format_version`` — one of :data:`READABLE_VERSIONS`: the version the metadata record
    states (an older one only to compare with a log of that version: the layout is the same).
    """
    if format_version not in READABLE_VERSIONS:
        raise ValueError(
            f"format_version must be one of {', '.join(READABLE_VERSIONS)} (allowed: the readable run-log "
            f"versions), got {format_version!r}"
        )
    return stream_bytes(_write_stream, result, include_timings, None, format_version)


def write_run(
    path: str | os.PathLike[str],
    result: RunResult,
    *,
    include_timings: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Write a run log atomically.

    The log is written to a hidden temporary file beside ``path`` and renamed over it
    (:func:`pose_uncertainty.records.mcap_io.write_atomically`): an interrupted write never
    leaves a file at ``path``; a killed process leaves only the ``.part`` file, which
    :func:`open_run` rejects as truncated and ``open_run(..., recover=True)`` can read.

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
    return write_atomically(path, _write_stream, result, include_timings, progress)


# --- reading -----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class RunLog(RunResult, LogFile):
    """A run read back from its log: a :class:`RunResult` plus what the file says.

    Attributes (beyond RunResult's): those of :class:`~pose_uncertainty.records.formats.LogFile`
    (path, metadata, library, topics, partial, problems).
    """

    def state_at(self, t: float) -> dict[str, Any]:
        """State at simulated time ``t`` [s]: the last logged step at or before ``t``.

        Returns
        -------
        dict with ``step``, ``time`` [s], ``pose`` (3,), ``cov`` (3, 3), the
        ellipse ``alpha`` [rad], ``a_major``, ``a_minor`` [m] at ``config.pr``, and
        ``cloud`` (n, 3) when a Monte Carlo cloud was logged at that step.
        """
        i = step_at(self.times, t)
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


def _read_steps(rec: Records, n_expected: int, partial: bool) -> tuple[NDArray, NDArray, NDArray]:
    """Times (N+1,), poses (N+1, 3) and covariances (N+1, 3, 3) of every logged step."""
    covmsgs = sorted(rec.decode(T_COV, fg.PoseCovariance2D), key=lambda m: m.step)
    steps = [m.step for m in covmsgs]
    if steps != list(range(len(steps))) or (not partial and len(steps) != n_expected):
        raise RunLogError(
            f"{rec.p}: {T_COV} holds steps {steps[:3]}…(count {len(steps)}), expected 0..{n_expected - 1}"
        )
    times = np.array([m.time for m in covmsgs], dtype=np.float64)
    poses = np.array([[m.x, m.y, m.theta] for m in covmsgs], dtype=np.float64).reshape(-1, 3)
    covs = np.array([list(m.covariance) for m in covmsgs], dtype=np.float64).reshape(-1, 3, 3)
    return times, poses, covs


def _read_checkpoints(rec: Records, times: NDArray) -> dict[int, NDArray[np.float64]]:
    step_of_ns = {fg.ns(t): i for i, t in enumerate(times)}
    out: dict[int, NDArray[np.float64]] = {}
    for msg in rec.decode(T_CHECK, fg.PointCloud):
        t_ns = message_ns(msg)
        if t_ns not in step_of_ns:
            raise RunLogError(f"{rec.p}: checkpoint cloud at {t_ns} ns matches no logged step")
        out[step_of_ns[t_ns]] = rec.cloud(msg, POSE_COLUMNS)
    return out


def _last_cloud(rec: Records, topic: str) -> NDArray[np.float64] | None:
    msgs = rec.decode(topic, fg.PointCloud)
    return rec.cloud(msgs[-1], POSE_COLUMNS) if msgs else None


def _read_map(rec: Records, name: str) -> ProbabilityMap | None:
    vols = rec.decode(f"/maps/{name}/volume", fg.ProbabilityMap3D)
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


def _read_run(c: Container) -> RunLog:
    """Build a :class:`RunLog` from the validated container of a dead-reckoning run's log."""
    check_version(c, RUN_LOG, "run log")
    meta = c.metadata
    try:
        config = RunConfig.from_dict(json.loads(meta["config"]))
    except (KeyError, ValueError) as exc:
        raise RunLogError(f"{c.path}: the logged run config is invalid ({exc})") from None
    rec = Records(c)
    times, poses, covs = _read_steps(rec, int(meta.get("n_steps", "-1")) + 1, c.partial)
    maps = [m for m in (_read_map(rec, name) for name in json.loads(meta.get("maps", "[]"))) if m is not None]
    samplers = {m.name: s for m in maps if (s := _last_cloud(rec, f"/maps/{m.name}/sampler")) is not None}
    metrics, units, definitions = rec.metrics(T_METRICS)
    return RunLog(
        config=config, times=times, poses=poses, covs=covs, end_poses=_last_cloud(rec, T_END),
        checkpoints=_read_checkpoints(rec, times), maps=tuple(maps), map_samplers=samplers, metrics=metrics,
        metric_units=units, metric_definitions=definitions, timings=rec.metrics(T_TIMINGS)[0],
        **file_fields(c, rec.topics),
    )  # fmt: skip


# --- summary, comparison, verification ------------------------------------------------------


def _fmt_array(a: NDArray[np.float64]) -> str:
    return np.array2string(np.asarray(a), precision=6, separator=", ", max_line_width=120)


def format_summary(log: RunLog) -> str:
    """Summary of a run log: config, topics with counts, final pose and covariance, metrics."""
    drive = [f"drive     {log.config.drive.describe()}"] if log.config.drive is not None else []
    lines = summary_head(log, "run log  ", drive)
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
    return "\n".join(lines + summary_measures(log))


def _compare_maps(logged: RunResult, fresh: RunResult) -> list[str]:
    """The logged forms of the maps, attribute by attribute, and their samplers' draws."""
    if [m.name for m in logged.maps] != [m.name for m in fresh.maps]:
        return [f"maps: {[m.name for m in logged.maps]} != {[m.name for m in fresh.maps]}"]
    out: list[str] = []
    for a, b in zip(map(logged_form, logged.maps), map(logged_form, fresh.maps), strict=True):
        out.extend(d for attr in ("x", "y", "theta", "values", "center")
                   if (d := diff(f"map {a.name}.{attr}", getattr(a, attr), getattr(b, attr))))  # fmt: skip
        if (a.lost_mass, a.model, a.params, a.info) != (b.lost_mass, b.model, b.params, b.info):
            out.append(f"map {a.name}: model/lost_mass/params/info differ")
        d = diff(f"map {a.name} sampler", logged.map_samplers.get(a.name), fresh.map_samplers.get(a.name))
        if d:
            out.append(d)
    return out


def compare_results(logged: RunResult, fresh: RunResult) -> list[str]:
    """Bit-exact comparison of two results; one line per difference (empty = identical).

    Timings are not compared (they are not reproducible); provenance
    differences are reported with a leading ``"note: "`` and are not mismatches.
    """
    out: list[str] = []
    if logged.config != fresh.config:
        out.append("config differs")
    out.extend(d for name in ("times", "poses", "covs", "end_poses")
               if (d := diff(name, getattr(logged, name), getattr(fresh, name))))  # fmt: skip
    if sorted(logged.checkpoints) != sorted(fresh.checkpoints):
        out.append(f"checkpoints: steps {sorted(logged.checkpoints)} != {sorted(fresh.checkpoints)}")
    else:
        out.extend(d for step in sorted(logged.checkpoints)
                   if (d := diff(f"checkpoint[{step}]", logged.checkpoints[step], fresh.checkpoints[step])))  # fmt: skip
    return out + _compare_maps(logged, fresh) + compare_measures(logged, fresh)


def _verify(log: RunLog) -> Comparison:
    """Recompute a complete run log from its config and seed and compare every record of the two logs.

    The fresh log states the logged format version (:data:`FORMAT_VERSION`'s notes): a log of
    an older readable version is compared record by record with the current code's numbers.
    """
    version = log.metadata.get("format_version", FORMAT_VERSION)

    def fresh_bytes(result: RunResult, *, include_timings: bool = False) -> bytes:
        return log_bytes(result, include_timings=include_timings, format_version=version)

    comparison = verify_recomputed(log, execute(log.config), fresh_bytes)
    if version != FORMAT_VERSION:
        comparison.notes.append(
            f"the log is of run-log format version {version}; recomputed by this code (version {FORMAT_VERSION}, "
            "same records): equal within tolerance is the expected result"
        )
    return comparison


#: The dead-reckoning run log's write / read / summary / verify.
RUN_LOG = register(LogFormat(FORMAT, FORMAT_VERSION, write_run, log_bytes, _read_run, format_summary, _verify,
                             readable=READABLE_VERSIONS))  # fmt: skip
