"""Writing bags with rosbags: a :class:`~.bag.Recording`, or any topics, atomically.

Formats (``storage``): ``"mcap"`` — a rosbag2 folder with MCAP storage (what ``ros2 bag
record`` writes by default since Iron); ``"sqlite3"`` — a rosbag2 folder with ``.db3``
storage; ``"mcap-file"`` — a bare ROS 2 ``.mcap`` file; ``"ros1"`` — a ROS 1 ``.bag``.
Every destination appears complete or not at all (:mod:`..core.atomic`).
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2

from ..core.atomic import atomic_directory, atomic_write_bytes
from .bag import Recording
from .messages import INT_ARRAY_BITS, JOINT_STATE, ODOMETRY, POSE_STAMPED, TF_MESSAGE, MessageKit

__all__ = ["STORAGES", "WHEEL_FORMATS", "BagSink", "open_bag", "write_recording"]

STORAGES: tuple[str, ...] = ("mcap", "sqlite3", "mcap-file", "ros1")
#: How wheel readings are written: JointState positions or velocities, or an Int32MultiArray of ticks.
WHEEL_FORMATS: tuple[str, ...] = ("joint_state", "joint_velocity", "ticks")


class BagSink:
    """An open bag being written: ``add(topic, msgtype)`` once per topic, then ``write``."""

    def __init__(self, writer: Any, kit: MessageKit) -> None:
        self.writer, self.kit = writer, kit
        self._conns: dict[str, Any] = {}

    def add(self, topic: str, msgtype: str) -> None:
        self._conns[topic] = self.writer.add_connection(topic, msgtype, typestore=self.kit.typestore)

    def write(self, topic: str, t_ns: int, msg: Any) -> None:
        conn = self._conns[topic]
        self.writer.write(conn, int(t_ns), self.kit.serialize(msg, conn.msgtype))


@contextlib.contextmanager
def open_bag(dest: str | Path, storage: str = "mcap") -> Iterator[BagSink]:
    """A :class:`BagSink` whose bag replaces ``dest`` atomically on a clean exit."""
    if storage not in STORAGES:
        raise ValueError(f"storage must be one of {STORAGES}, got {storage!r}")
    dest = Path(dest)
    kit = MessageKit("ros1" if storage == "ros1" else "ros2")
    if storage in ("mcap", "sqlite3"):
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        with atomic_directory(dest) as part:
            part.rmdir()  # rosbags creates the folder itself
            with Writer2(part, version=9, storage_plugin=plugin) as w2:
                yield BagSink(w2, kit)
        return
    with tempfile.TemporaryDirectory(dir=dest.parent if dest.parent.exists() else None) as tmp:
        if storage == "ros1":
            inner = Path(tmp) / "bag.bag"
            with Writer1(inner) as w1:
                yield BagSink(w1, kit)
        else:
            folder = Path(tmp) / "bag"
            with Writer2(folder, version=9, storage_plugin=StoragePlugin.MCAP) as w2:
                yield BagSink(w2, kit)
            inner = next(folder.glob("*.mcap"))
        dest.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(dest, inner.read_bytes())
        shutil.rmtree(tmp, ignore_errors=True)


def _wheel_messages(rec: Recording, kit: MessageKit, wheel_format: str) -> Iterable[tuple[int, Any, str]]:
    w = rec.wheels
    if wheel_format == "ticks":
        if w.kind != "ticks":
            raise ValueError(f"wheel_format 'ticks' needs a recording of ticks, got {w.kind!r}")
        msgtype = {16: "std_msgs/msg/Int16MultiArray", 32: "std_msgs/msg/Int32MultiArray"}.get(
            w.bits or 64, "std_msgs/msg/Int64MultiArray"
        )
        assert msgtype in INT_ARRAY_BITS
        for t, a, b in zip(w.t_ns, w.left, w.right, strict=True):
            yield int(t), kit.int_array(msgtype, np.array([a, b])), msgtype
        return
    want = "position" if wheel_format == "joint_state" else "velocity"
    if w.kind != want:
        raise ValueError(f"wheel_format {wheel_format!r} needs a recording of {want}s, got {w.kind!r}")
    names = list(w.names)
    for t, a, b in zip(w.t_ns, w.left, w.right, strict=True):
        vals = np.array([a, b])
        msg = kit.joint_state(int(t), names, position=vals) if want == "position" else kit.joint_state(
            int(t), names, velocity=vals
        )
        yield int(t), msg, JOINT_STATE


def write_recording(
    rec: Recording,
    dest: str | Path,
    *,
    storage: str = "mcap",
    wheel_format: str = "joint_state",
    truth_type: str = POSE_STAMPED,
    topics: dict[str, str] | None = None,
    odometry_cov: Any = None,
) -> Path:
    """Write a recording as a bag; returns ``Path(dest)``.

    Parameters
    ----------
    rec : Recording — wheels (positions, velocities or ticks), truth and odometry (optional)
    dest : the bag folder (``mcap``, ``sqlite3``) or file (``mcap-file``, ``ros1``)
    storage : one of :data:`STORAGES`; wheel_format : one of :data:`WHEEL_FORMATS`
    truth_type : ``geometry_msgs/msg/PoseStamped``, ``nav_msgs/msg/Odometry`` (frame ``map``)
        or ``tf2_msgs/msg/TFMessage`` (``map`` → ``base_link_truth``)
    topics : role → topic (default ``/joint_states`` or ``/wheel_ticks``, ``/ground_truth``, ``/odom``)
    odometry_cov : array (3, 3), optional — the robot odometry's (constant) pose covariance
    """
    if wheel_format not in WHEEL_FORMATS:
        raise ValueError(f"wheel_format must be one of {WHEEL_FORMATS}, got {wheel_format!r}")
    names = {
        "wheels": "/wheel_ticks" if wheel_format == "ticks" else "/joint_states",
        "truth": "/ground_truth", "odometry": "/odom", **(topics or {}),
    }  # fmt: skip
    cov = np.zeros((3, 3)) if odometry_cov is None else np.asarray(odometry_cov, dtype=np.float64)
    with open_bag(dest, storage) as sink:
        kit = sink.kit
        wheel_msgs = list(_wheel_messages(rec, kit, wheel_format))
        if wheel_msgs:
            sink.add(names["wheels"], wheel_msgs[0][2])
        truth_msgs = odom_msgs = None
        if rec.truth is not None:
            sink.add(names["truth"], truth_type)
            truth_msgs = _truth_messages(rec, kit, truth_type)
        if rec.odometry is not None:
            sink.add(names["odometry"], ODOMETRY)
            odom_msgs = [
                (int(t), kit.odometry(int(t), p, cov)) for t, p in zip(rec.odometry.t_ns, rec.odometry.poses, strict=True)
            ]
        # messages are received in the order recorded: the receive time is the latest stamp
        # so far (a stamp earlier than an earlier message's stays out of order in the bag)
        for topic, msgs in (("wheels", wheel_msgs), ("truth", truth_msgs), ("odometry", odom_msgs)):
            latest = 0
            for t, msg, *_ in msgs or []:
                latest = max(latest, t)
                sink.write(names[topic], latest, msg)
    return Path(dest)


def _truth_messages(rec: Recording, kit: MessageKit, truth_type: str) -> list[tuple[int, Any]]:
    assert rec.truth is not None
    out = []
    for t, p in zip(rec.truth.t_ns, rec.truth.poses, strict=True):
        if truth_type == POSE_STAMPED:
            msg = kit.pose_stamped(int(t), p, "map")
        elif truth_type == ODOMETRY:
            msg = kit.odometry(int(t), p, np.zeros((3, 3)), frame_id="map", child_frame_id="base_link_truth")
        elif truth_type == TF_MESSAGE:
            msg = kit.tf_message(int(t), p, "map", "base_link_truth")
        else:
            raise ValueError(f"truth_type must be PoseStamped, Odometry or TFMessage, got {truth_type!r}")
        out.append((int(t), msg))
    return out
