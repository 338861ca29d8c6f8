"""Reading a robot's bag without ROS: wheels, ground truth and the robot's own odometry.

Inputs (rosbags' ``AnyReader``): a rosbag2 folder (``metadata.yaml`` with ``.mcap`` or
``.db3`` storage), a bare ROS 2 ``.mcap`` file, a bare ``.db3`` file or a ROS 1 ``.bag``.

What is read, by message type
-----------------------------
* wheels: ``sensor_msgs/msg/JointState`` — positions [rad] of the two wheel joints,
  or their velocities [rad/s] when the positions are empty; or raw encoder ticks: one
  integer ``std_msgs/msg/{Int16,Int32,Int64,UInt16,UInt32,UInt64}MultiArray`` whose
  ``data`` holds both counters (indices ``joints: {left: 0, right: 1}`` by default), or
  two scalar topics ``std_msgs/msg/Int32`` (etc.) named in ``topics.wheels.left/right``.
  The counter width follows from the type (16, 32 or 64 bits), for wrap-around. Tick
  messages have no header: their time is the bag's receive time.
* ground truth: ``geometry_msgs/msg/PoseStamped``, ``nav_msgs/msg/Odometry`` or
  ``tf2_msgs/msg/TFMessage`` (the transform whose child frame is ``truth_frame``);
* the robot's own odometry: ``nav_msgs/msg/Odometry``.

Times are the header stamps. A role's topic is the one named in the robot file, or else
the only topic of a suitable type; two Odometry topics without names are told apart by
their frames (``odom`` parent: the robot's odometry; ``map``/``world`` parent: truth).
Every problem is a one-line :class:`BagError` naming the bag and what is wrong.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader

from ..core.validation import first_line
from .config import RobotConfig
from .messages import (
    INT_ARRAY_BITS,
    INT_SCALAR_BITS,
    JOINT_STATE,
    ODOMETRY,
    POSE_STAMPED,
    TF_MESSAGE,
    stamp_ns,
    yaw_of,
)

__all__ = [
    "TRUTH_TYPES",
    "WHEEL_KINDS",
    "BagError",
    "PoseStream",
    "Recording",
    "WheelStream",
    "bag_paths",
    "read_bag",
]

TRUTH_TYPES: tuple[str, ...] = (POSE_STAMPED, ODOMETRY, TF_MESSAGE)
WHEEL_KINDS: tuple[str, ...] = ("position", "velocity", "ticks")
_WHEEL_TYPES = (JOINT_STATE, *INT_ARRAY_BITS)
Progress = Callable[[int, int], None]


class BagError(ValueError):
    """A bag that cannot be used: the message is one line naming the bag and the problem."""


@dataclass(frozen=True, eq=False)
class WheelStream:
    """Both wheels' readings, in the order recorded (not yet cleaned).

    Attributes
    ----------
    t_ns : ndarray, shape (n,), int64 — stamps [ns]
    left, right : ndarray, shape (n,) — positions [rad], velocities [rad/s] or ticks [1]
    kind : {"position", "velocity", "ticks"}
    bits : int or None — counter width of ticks (wrap-around at 2**bits)
    names : (str, str) — the left and right joint names (or array indices, as text)
    """

    t_ns: NDArray[np.int64]
    left: NDArray[np.float64]
    right: NDArray[np.float64]
    kind: str
    bits: int | None = None
    names: tuple[str, str] = ("left_wheel_joint", "right_wheel_joint")


@dataclass(frozen=True, eq=False)
class PoseStream:
    """Planar poses in the order recorded: ``t_ns`` (n,) [ns], ``poses`` (n, 3) [m, m, rad]."""

    t_ns: NDArray[np.int64]
    poses: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Recording:
    """What a bag holds for calibration: wheels, optional ground truth and robot odometry.

    ``topics`` maps each role found (``wheels``, ``truth``, ``odometry``) to its topic;
    ``source`` names the bag.
    """

    wheels: WheelStream
    truth: PoseStream | None = None
    odometry: PoseStream | None = None
    topics: dict[str, str] = field(default_factory=dict)
    source: str = ""


def bag_paths(path: str | Path) -> list[Path]:
    """The paths ``AnyReader`` opens for ``path``; BagError when it is not a bag."""
    p = Path(path)
    if not p.exists():
        raise BagError(f"{p}: no such bag")
    if p.is_dir():
        if not (p / "metadata.yaml").exists():
            raise BagError(f"{p}: not a rosbag2 folder (no metadata.yaml)")
        return [p]
    if p.suffix not in (".mcap", ".db3", ".bag"):
        raise BagError(
            f"{p}: unknown bag format {p.suffix!r} (allowed: a rosbag2 folder, .mcap, .db3, .bag)"
        )
    return [p]


def _decode(reader: AnyReader, raw: bytes, msgtype: str) -> Any:
    """A deserialised message (rosbags types it as ``object``)."""
    return reader.deserialize(raw, msgtype)


# --- choosing the topics ------------------------------------------------------------------


def _named(role: str, topic: str, types: dict[str, str], allowed: tuple[str, ...], src: str) -> str:
    if topic not in types:
        raise BagError(f"{src}: topic {topic} for {role} is not in the bag (topics: {sorted(types)})")
    if types[topic] not in allowed:
        raise BagError(
            f"{src}: topic {topic} for {role} has type {types[topic]} (allowed: {', '.join(allowed)})"
        )
    return topic


def _pick(role: str, candidates: list[str], src: str, hint: str) -> str | None:
    if len(candidates) > 1:
        raise BagError(
            f"{src}: several topics could be the {role} ({', '.join(sorted(candidates))}); "
            f"name one in the robot file's topics.{hint}"
        )
    return candidates[0] if candidates else None


def _odometry_frames(reader: AnyReader, topic: str) -> str:
    """The parent frame of the first message of an Odometry topic."""
    conns = [c for c in reader.connections if c.topic == topic]
    for conn, _, raw in reader.messages(connections=conns):
        return str(_decode(reader, raw, conn.msgtype).header.frame_id).lstrip("/")
    return ""


def _choose_topics(reader: AnyReader, robot: RobotConfig, src: str) -> dict[str, Any]:
    """Role → topic (wheels may be a {left, right} pair); truth and odometry may be None."""
    types = {c.topic: c.msgtype for c in reader.connections}
    named = robot.topics
    out: dict[str, Any] = {}
    wheels = named.get("wheels")
    if isinstance(wheels, dict):
        out["wheels"] = {s: _named("wheels", wheels[s], types, tuple(INT_SCALAR_BITS), src) for s in wheels}
    elif wheels is not None:
        out["wheels"] = _named("wheels", wheels, types, _WHEEL_TYPES, src)
    else:
        cands = [t for t, m in types.items() if m in _WHEEL_TYPES]
        out["wheels"] = _pick("wheel readings", cands, src, "wheels")
        if out["wheels"] is None:
            raise BagError(
                f"{src}: no wheel topic (allowed types: {', '.join(_WHEEL_TYPES)}, or two scalar "
                f"tick topics named in topics.wheels); topics: {sorted(types) or 'none'}"
            )
    for role, allowed in (("truth", TRUTH_TYPES), ("odometry", (ODOMETRY,))):
        if role in named:
            out[role] = None if named[role] is None else _named(role, named[role], types, allowed, src)
    odoms = [t for t, m in types.items() if m == ODOMETRY and t not in out.values()]
    if "odometry" not in out or "truth" not in out:
        frames = {t: _odometry_frames(reader, t) for t in odoms}
        if "odometry" not in out:
            own = [t for t in odoms if frames[t] not in ("map", "world")]
            out["odometry"] = _pick("robot's odometry", own, src, "odometry")
        if "truth" not in out:
            cands = [t for t, m in types.items() if m in (POSE_STAMPED, TF_MESSAGE)]
            cands += [t for t in odoms if frames[t] in ("map", "world") and t != out.get("odometry")]
            out["truth"] = _pick("ground truth", cands, src, "truth")
    return out


# --- decoding ---------------------------------------------------------------------------------


def _truth_pose(msg: Any, msgtype: str, frame: str | None, src: str) -> tuple[int, NDArray] | None:
    if msgtype == TF_MESSAGE:
        for tf in msg.transforms:
            child = str(tf.child_frame_id).lstrip("/")
            if frame is None or child == frame.lstrip("/"):
                tr, q = tf.transform.translation, tf.transform.rotation
                return stamp_ns(tf.header.stamp), np.array([tr.x, tr.y, yaw_of(q)])
        return None
    pose = msg.pose.pose if msgtype == ODOMETRY else msg.pose
    return stamp_ns(msg.header.stamp), np.array([pose.position.x, pose.position.y, yaw_of(pose.orientation)])


def _wheel_indices(names: list[str], robot: RobotConfig, src: str) -> tuple[int, int]:
    want = robot.joints
    if want:
        idx = []
        for side in ("left", "right"):
            if side not in want:
                raise BagError(f"{src}: joints must name both left and right, got {want}")
            name = want[side]
            if isinstance(name, int):
                raise BagError(f"{src}: joints.{side} must be a joint name for JointState, got {name}")
            if name not in names:
                raise BagError(f"{src}: joint {name!r} (joints.{side}) is not in the JointState names {names}")
            idx.append(names.index(name))
        return idx[0], idx[1]
    left = [i for i, n in enumerate(names) if "left" in n.lower()]
    right = [i for i, n in enumerate(names) if "right" in n.lower()]
    if len(left) != 1 or len(right) != 1:
        raise BagError(
            f"{src}: cannot tell the left and right wheel joints among {names}; "
            "name them in the robot file's joints: {left: NAME, right: NAME}"
        )
    return left[0], right[0]


class _Counter:
    """Progress over the messages of the chosen topics (calls ``progress(done, total)``)."""

    def __init__(self, total: int, progress: Progress | None) -> None:
        self.total, self.done, self.progress = total, 0, progress
        self.every = max(1, total // 10)

    def tick(self) -> None:
        self.done += 1
        if self.progress is not None and (self.done % self.every == 0 or self.done == self.total):
            self.progress(self.done, self.total)


def _read_joint_states(reader: AnyReader, topic: str, robot: RobotConfig, src: str, count: _Counter) -> WheelStream:
    conns = [c for c in reader.connections if c.topic == topic]
    t, a, b = [], [], []
    kind, names = None, ("", "")
    for conn, _, raw in reader.messages(connections=conns):
        msg = _decode(reader, raw, conn.msgtype)
        count.tick()
        msg_names = [str(n) for n in msg.name]
        i, j = _wheel_indices(msg_names, robot, src)
        use_pos = len(msg.position) > max(i, j)
        this = "position" if use_pos else "velocity"
        if not use_pos and len(msg.velocity) <= max(i, j):
            raise BagError(f"{src}: a JointState on {topic} has neither positions nor velocities of its wheels")
        kind = kind or this
        if this != kind:
            raise BagError(f"{src}: JointState on {topic} switches between positions and velocities")
        values = msg.position if use_pos else msg.velocity
        t.append(stamp_ns(msg.header.stamp))
        a.append(float(values[i]))
        b.append(float(values[j]))
        names = (msg_names[i], msg_names[j])
    return WheelStream(np.asarray(t, np.int64), np.asarray(a), np.asarray(b), kind or "position", None, names)


def _read_tick_array(reader: AnyReader, topic: str, robot: RobotConfig, count: _Counter) -> WheelStream:
    conns = [c for c in reader.connections if c.topic == topic]
    il = robot.joints.get("left", 0)
    ir = robot.joints.get("right", 1)
    if not isinstance(il, int) or not isinstance(ir, int):
        raise BagError(f"{topic}: joints must be array indices (0, 1, ...) for tick arrays, got {robot.joints}")
    t, a, b = [], [], []
    bits = 64
    for conn, t_bag, raw in reader.messages(connections=conns):
        msg = _decode(reader, raw, conn.msgtype)
        count.tick()
        bits = INT_ARRAY_BITS[conn.msgtype]
        if len(msg.data) <= max(il, ir):
            raise BagError(f"{topic}: a tick array has {len(msg.data)} values, need index {max(il, ir)}")
        t.append(t_bag)
        a.append(float(msg.data[il]))
        b.append(float(msg.data[ir]))
    return WheelStream(np.asarray(t, np.int64), np.asarray(a), np.asarray(b), "ticks", bits, (str(il), str(ir)))


def _read_tick_pair(reader: AnyReader, topics: dict[str, str], count: _Counter, src: str) -> WheelStream:
    """Two scalar tick topics, paired by receive time (each left reading with the nearest right one)."""
    series = {}
    bits = 64
    for side, topic in topics.items():
        conns = [c for c in reader.connections if c.topic == topic]
        t, v = [], []
        for conn, t_bag, raw in reader.messages(connections=conns):
            count.tick()
            bits = INT_SCALAR_BITS[conn.msgtype]
            t.append(t_bag)
            v.append(float(_decode(reader, raw, conn.msgtype).data))
        series[side] = (np.asarray(t, np.int64), np.asarray(v))
    (tl, vl), (tr, vr) = series["left"], series["right"]
    if tl.size == 0 or tr.size == 0:
        return WheelStream(np.zeros(0, np.int64), np.zeros(0), np.zeros(0), "ticks", bits, (topics["left"], topics["right"]))
    j = np.clip(np.searchsorted(tr, tl), 1, tr.size - 1) if tr.size > 1 else np.zeros(tl.size, int)
    if tr.size > 1:
        j = np.where(np.abs(tr[j - 1] - tl) <= np.abs(tr[j] - tl), j - 1, j)
    return WheelStream(tl, vl, vr[j], "ticks", bits, (topics["left"], topics["right"]))


def _read_poses(
    reader: AnyReader, topic: str, robot: RobotConfig, src: str, count: _Counter
) -> PoseStream:
    conns = [c for c in reader.connections if c.topic == topic]
    t, p = [], []
    for conn, _, raw in reader.messages(connections=conns):
        count.tick()
        got = _truth_pose(_decode(reader, raw, conn.msgtype), conn.msgtype, robot.truth_frame, src)
        if got is not None:
            t.append(got[0])
            p.append(got[1])
    poses = np.asarray(p, dtype=np.float64).reshape(-1, 3)
    return PoseStream(np.asarray(t, np.int64), poses)


def _check_tf_frames(reader: AnyReader, topic: str, robot: RobotConfig, src: str) -> None:
    """With TF ground truth and no truth_frame: the transforms must have one child frame."""
    if robot.truth_frame is not None:
        return
    conns = [c for c in reader.connections if c.topic == topic]
    children: set[str] = set()
    for n, (conn, _, raw) in enumerate(reader.messages(connections=conns)):
        children |= {str(tf.child_frame_id) for tf in _decode(reader, raw, conn.msgtype).transforms}
        if n > 50:
            break
    if len(children) > 1:
        raise BagError(f"{src}: {topic} holds transforms of several frames {sorted(children)}; name one as truth_frame")


def _read_recording(reader: AnyReader, robot: RobotConfig, src: str, progress: Progress | None) -> Recording:
    if reader.message_count == 0 and not reader.connections:
        raise BagError(f"{src}: the bag is empty (no topics, no messages)")
    chosen = _choose_topics(reader, robot, src)
    types = {c.topic: c.msgtype for c in reader.connections}
    wanted = [w for w in ([*chosen["wheels"].values()] if isinstance(chosen["wheels"], dict) else [chosen["wheels"]])]
    wanted += [chosen[r] for r in ("truth", "odometry") if chosen.get(r)]
    total = sum(ti.msgcount for t, ti in reader.topics.items() if t in wanted)
    count = _Counter(total, progress)
    w = chosen["wheels"]
    if isinstance(w, dict):
        wheels = _read_tick_pair(reader, w, count, src)
    elif types[w] == JOINT_STATE:
        wheels = _read_joint_states(reader, w, robot, src, count)
    else:
        wheels = _read_tick_array(reader, w, robot, count)
    if wheels.t_ns.size < 2:
        raise BagError(f"{src}: the wheel topic has {wheels.t_ns.size} message(s) (need at least 2)")
    truth = odom = None
    if chosen.get("truth"):
        if types[chosen["truth"]] == TF_MESSAGE:
            _check_tf_frames(reader, chosen["truth"], robot, src)
        truth = _read_poses(reader, chosen["truth"], robot, src, count)
    if chosen.get("odometry"):
        odom = _read_poses(reader, chosen["odometry"], robot, src, count)
    topics = {"wheels": str(w) if not isinstance(w, dict) else f"{w['left']} + {w['right']}"}
    topics.update({r: chosen[r] for r in ("truth", "odometry") if chosen.get(r)})
    return Recording(wheels=wheels, truth=truth, odometry=odom, topics=topics, source=src)


def read_bag(path: str | Path, robot: RobotConfig | None = None, progress: Progress | None = None) -> Recording:
    """Read the wheels, ground truth and robot odometry of a bag (module docstring).

    Parameters
    ----------
    path : a rosbag2 folder, ``.mcap``, ``.db3`` or ROS 1 ``.bag``
    robot : RobotConfig, optional — topic and joint names (default: found by type)
    progress : callable, optional — ``progress(done, total)`` messages read (about 10 calls)

    Returns
    -------
    Recording — raw streams in recorded order; :mod:`.align` cleans them

    Raises
    ------
    BagError — one line: missing, empty, truncated or damaged bag, wrong topic type, ...
    """
    src = str(path)
    cfg = robot if robot is not None else RobotConfig()
    paths = bag_paths(path)
    try:
        with AnyReader(paths) as reader:
            return _read_recording(reader, cfg, src, progress)
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags raises many kinds on a damaged file
        raise BagError(f"{src}: cannot read the bag, truncated or damaged ({first_line(exc)})") from None
