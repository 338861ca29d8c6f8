"""The ROS message types this package reads and writes, built and taken apart with rosbags.

Planar poses ``(x, y, θ)`` map to ``geometry_msgs/msg/Pose`` with ``z = 0`` and the
quaternion of a rotation by θ about z; reading one back takes the yaw
``atan2(2(wz + xy), 1 − 2(y² + z²))``. A planar covariance (3, 3) over ``(x, y, θ)``
maps to the 6 × 6 row-major covariance of ``PoseWithCovariance`` over
``(x, y, z, roll, pitch, yaw)`` at rows and columns 0, 1, 5; the other entries are 0
(the motion is planar: those axes are known exactly).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from rosbags.typesys import Stores, get_typestore

__all__ = [
    "INT_ARRAY_BITS",
    "INT_SCALAR_BITS",
    "JOINT_STATE",
    "OCCUPANCY_GRID",
    "ODOMETRY",
    "PLANAR_INDEX",
    "POSE_ARRAY",
    "POSE_STAMPED",
    "TF_MESSAGE",
    "MessageKit",
    "cov3_from_6",
    "cov6_from_3",
    "stamp_ns",
    "yaw_of",
]

JOINT_STATE = "sensor_msgs/msg/JointState"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
POSE_ARRAY = "geometry_msgs/msg/PoseArray"
OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
#: Integer array types of encoder ticks → the counter's width in bits (its wrap-around).
INT_ARRAY_BITS: dict[str, int] = {
    "std_msgs/msg/Int16MultiArray": 16, "std_msgs/msg/UInt16MultiArray": 16,
    "std_msgs/msg/Int32MultiArray": 32, "std_msgs/msg/UInt32MultiArray": 32,
    "std_msgs/msg/Int64MultiArray": 64, "std_msgs/msg/UInt64MultiArray": 64,
}  # fmt: skip
#: Scalar integer types of one wheel's ticks → the counter's width in bits.
INT_SCALAR_BITS: dict[str, int] = {
    "std_msgs/msg/Int16": 16, "std_msgs/msg/UInt16": 16, "std_msgs/msg/Int32": 32,
    "std_msgs/msg/UInt32": 32, "std_msgs/msg/Int64": 64, "std_msgs/msg/UInt64": 64,
}  # fmt: skip
#: Rows/columns of (x, y, yaw) in a 6 × 6 ROS pose or twist covariance.
PLANAR_INDEX: tuple[int, int, int] = (0, 1, 5)


def stamp_ns(stamp: Any) -> int:
    """Nanoseconds of a ``builtin_interfaces/msg/Time``."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def yaw_of(q: Any) -> float:
    """Yaw [rad] of a quaternion message (rotation about z; roll and pitch ignored)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def cov6_from_3(cov: ArrayLike) -> NDArray[np.float64]:
    """Row-major 36-vector of the 6 × 6 covariance holding a planar (3, 3) one (module docstring)."""
    c = np.asarray(cov, dtype=np.float64)
    if c.shape != (3, 3):
        raise ValueError(f"cov must have shape (3, 3), got shape {c.shape}")
    out = np.zeros((6, 6))
    out[np.ix_(PLANAR_INDEX, PLANAR_INDEX)] = c
    return out.ravel()


def cov3_from_6(cov36: ArrayLike) -> NDArray[np.float64]:
    """The planar (3, 3) block of a row-major 36-vector covariance."""
    c = np.asarray(cov36, dtype=np.float64)
    if c.size != 36:
        raise ValueError(f"a ROS covariance has 36 entries, got {c.size}")
    return c.reshape(6, 6)[np.ix_(PLANAR_INDEX, PLANAR_INDEX)]


class MessageKit:
    """Builds messages of one ROS distribution's type store and serialises them.

    Parameters
    ----------
    ros : {"ros2", "ros1"} — ROS 2 (Humble types, CDR) or ROS 1 (Noetic types)
    """

    def __init__(self, ros: str = "ros2") -> None:
        if ros not in ("ros2", "ros1"):
            raise ValueError(f"ros must be 'ros2' or 'ros1', got {ros!r}")
        self.ros = ros
        self.typestore = get_typestore(Stores.ROS2_HUMBLE if ros == "ros2" else Stores.ROS1_NOETIC)
        self._t = self.typestore.types
        header_type: Any = self._t["std_msgs/msg/Header"]
        self._header_has_seq = "seq" in {f.name for f in dataclasses.fields(header_type)}

    def serialize(self, msg: Any, msgtype: str) -> bytes:
        """The message's bytes: CDR (ROS 2) or ROS 1 serialisation."""
        if self.ros == "ros2":
            return bytes(self.typestore.serialize_cdr(msg, msgtype))
        return bytes(self.typestore.serialize_ros1(msg, msgtype))

    def header(self, t_ns: int, frame_id: str) -> Any:
        time = self._t["builtin_interfaces/msg/Time"](sec=int(t_ns // 1_000_000_000), nanosec=int(t_ns % 1_000_000_000))
        if self._header_has_seq:
            return self._t["std_msgs/msg/Header"](seq=0, stamp=time, frame_id=frame_id)
        return self._t["std_msgs/msg/Header"](stamp=time, frame_id=frame_id)

    def pose(self, x: float, y: float, theta: float) -> Any:
        T = self._t
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
            orientation=self.quaternion(theta),
        )

    def quaternion(self, theta: float) -> Any:
        h = 0.5 * float(theta)
        return self._t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(h), w=math.cos(h))

    def _vector3(self, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
        return self._t["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def odometry(
        self,
        t_ns: int,
        pose: ArrayLike,
        cov: ArrayLike,
        twist: tuple[float, float] = (0.0, 0.0),
        twist_cov: ArrayLike | None = None,
        frame_id: str = "odom",
        child_frame_id: str = "base_link",
    ) -> Any:
        """``nav_msgs/msg/Odometry``: planar pose (3,), its covariance (3, 3), twist (V, ω)."""
        T = self._t
        p = np.asarray(pose, dtype=np.float64)
        tc = np.zeros(36) if twist_cov is None else cov6_from_3(twist_cov)
        return T[ODOMETRY](
            header=self.header(t_ns, frame_id),
            child_frame_id=child_frame_id,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=self.pose(p[0], p[1], p[2]), covariance=cov6_from_3(cov)
            ),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](
                    linear=self._vector3(twist[0]), angular=self._vector3(z=twist[1])
                ),
                covariance=tc,
            ),
        )

    def pose_stamped(self, t_ns: int, pose: ArrayLike, frame_id: str = "map") -> Any:
        p = np.asarray(pose, dtype=np.float64)
        return self._t[POSE_STAMPED](header=self.header(t_ns, frame_id), pose=self.pose(p[0], p[1], p[2]))

    def tf_message(self, t_ns: int, pose: ArrayLike, frame_id: str, child_frame_id: str) -> Any:
        T = self._t
        p = np.asarray(pose, dtype=np.float64)
        tf = T["geometry_msgs/msg/TransformStamped"](
            header=self.header(t_ns, frame_id),
            child_frame_id=child_frame_id,
            transform=T["geometry_msgs/msg/Transform"](
                translation=self._vector3(p[0], p[1]), rotation=self.quaternion(p[2])
            ),
        )
        return T[TF_MESSAGE](transforms=[tf])

    def joint_state(
        self,
        t_ns: int,
        names: list[str],
        position: ArrayLike | None = None,
        velocity: ArrayLike | None = None,
    ) -> Any:
        """``sensor_msgs/msg/JointState`` with positions [rad] and/or velocities [rad/s]."""
        empty = np.zeros(0, dtype=np.float64)
        pos = empty if position is None else np.asarray(position, dtype=np.float64)
        vel = empty if velocity is None else np.asarray(velocity, dtype=np.float64)
        return self._t[JOINT_STATE](
            header=self.header(t_ns, ""), name=list(names), position=pos, velocity=vel, effort=empty
        )

    def int_array(self, msgtype: str, values: ArrayLike) -> Any:
        """An integer ``std_msgs/msg/*MultiArray`` holding ``values`` (no layout)."""
        T = self._t
        dtype = {16: np.int16, 32: np.int32, 64: np.int64}[INT_ARRAY_BITS[msgtype]]
        if msgtype.split("/")[-1].startswith("U"):
            dtype = {np.int16: np.uint16, np.int32: np.uint32, np.int64: np.uint64}[dtype]
        layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
        return T[msgtype](layout=layout, data=np.asarray(values).astype(dtype))

    def int_scalar(self, msgtype: str, value: int) -> Any:
        return self._t[msgtype](data=int(value))

    def pose_array(self, t_ns: int, poses: ArrayLike, frame_id: str = "odom") -> Any:
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        return self._t[POSE_ARRAY](
            header=self.header(t_ns, frame_id), poses=[self.pose(*row) for row in p]
        )

    def occupancy_grid(
        self,
        t_ns: int,
        cells: NDArray[np.int8],
        origin_xy: tuple[float, float],
        resolution: float,
        frame_id: str = "odom",
    ) -> Any:
        """``nav_msgs/msg/OccupancyGrid``: ``cells`` (height, width) row-major, cell [0, 0] at origin."""
        T = self._t
        h, w = cells.shape
        stamp = self.header(t_ns, frame_id)
        info = T["nav_msgs/msg/MapMetaData"](
            map_load_time=stamp.stamp, resolution=float(resolution), width=int(w), height=int(h),
            origin=self.pose(origin_xy[0], origin_xy[1], 0.0),
        )  # fmt: skip
        return T[OCCUPANCY_GRID](header=stamp, info=info, data=cells.astype(np.int8).ravel())
