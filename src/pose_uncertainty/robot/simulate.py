"""A simulated robot with known wheel radii, track and wheel error constants, recorded as a bag.

The robot drives closed-loop on its own (nominal) odometry, as in UMBmark (Borenstein &
Feng 1996): the commanded path — UMBmark squares clockwise and counter-clockwise, then
arcs both ways — is traced exactly by the *odometry*, so the encoders turn by
``Δφ = Δs_cmd / r_nominal`` per wheel sample. The wheels really travel
``Δs = r_true Δφ + ε`` with ``ε ~ N(0, k |r_true Δφ|)`` independently per sample and
wheel (Method A's random-walk error with constants ``k_r, k_l``; Thrun, Burgard & Fox 2005
call this slip), on the true track; the true motion is integrated by exact arcs. Each
segment of the path ramps its speed up and down (no jumps of the speeds).

Recorded streams
----------------
* wheels at ``wheel_rate``: joint positions [rad] (``ticks_per_revolution`` None) or
  encoder ticks ``floor(φ N / 2π)`` wrapped to a signed 32-bit counter starting at
  ``tick_offset`` (so that a long drive wraps around);
* ground truth at ``truth_rate``, its stamps offset by ``truth_offset`` from the wheels':
  the true pose at that instant (the exact arc of the current wheel sample, part way)
  plus ``N(0, σ_p²)`` on x and y and ``N(0, σ_θ²)`` on θ;
* the robot's own odometry at the wheel stamps: the nominal geometry applied to the
  encoder readings (exact arcs).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..core.kinematics import integrate, step
from ..core.trajectories import Segment, from_segments
from .bag import PoseStream, Recording, WheelStream
from .bag_write import write_recording
from .simulated import TRUTH_UNITS, SimulatedRobot, calibration_drive

__all__ = ["EPOCH_NS", "TRUTH_UNITS", "SimulatedRobot", "calibration_drive", "simulate_recording", "write_simulated_bag"]


#: Stamp of the first wheel sample [ns] (a plausible wall-clock time, 2023-11-14).
EPOCH_NS: int = 1_700_000_000 * 1_000_000_000


def _encoder_angles(robot: SimulatedRobot, segments: list[Segment]) -> tuple[NDArray, NDArray]:
    """Per-sample encoder angle increments (left, right) [rad] of the commanded path."""
    traj = from_segments(
        segments, speed=robot.speed, angular_speed=robot.angular_speed, dt=1.0 / robot.wheel_rate,
        track=robot.nominal_track, profile="ramp",
    )  # fmt: skip
    return traj.ds_l / robot.nominal_radius, traj.ds_r / robot.nominal_radius


def _truth_at(
    t: NDArray, t_wheel: NDArray, poses: NDArray, ds: NDArray, dth: NDArray
) -> NDArray:
    """True poses at times ``t`` [s]: the exact arc of the wheel sample containing each, part way."""
    i = np.clip(np.searchsorted(t_wheel, t, side="right") - 1, 0, ds.size - 1)
    u = (t - t_wheel[i]) / (t_wheel[i + 1] - t_wheel[i])
    return step(poses[i], u * ds[i], u * dth[i], method="exact")


def simulate_recording(
    robot: SimulatedRobot,
    rng: np.random.Generator,
    segments: list[Segment] | None = None,
    *,
    truth: bool = True,
) -> Recording:
    """Simulate the robot driving ``segments`` (default :func:`calibration_drive`) (module docstring).

    Draws, from ``rng`` in this order: the wheel errors (2, n), the truth noise (3, m).
    """
    segs = calibration_drive() if segments is None else segments
    dphi_l, dphi_r = _encoder_angles(robot, segs)
    n = dphi_l.size
    true_l, true_r = robot.radius_left * dphi_l, robot.radius_right * dphi_r
    eps = rng.standard_normal((2, n)) * np.sqrt(
        np.stack([robot.k_l * np.abs(true_l), robot.k_r * np.abs(true_r)])
    )
    true_l, true_r = true_l + eps[0], true_r + eps[1]
    ds, dth = (true_r + true_l) / 2.0, (true_r - true_l) / robot.track
    poses = integrate(ds, dth, method="exact")
    t_wheel = np.arange(n + 1) / robot.wheel_rate
    phi_l = np.concatenate([[0.0], np.cumsum(dphi_l)])
    phi_r = np.concatenate([[0.0], np.cumsum(dphi_r)])
    wheel_ns = EPOCH_NS + np.round(t_wheel * 1e9).astype(np.int64)
    if robot.ticks_per_revolution is None:
        wheels = WheelStream(wheel_ns, phi_l, phi_r, "position")
    else:
        N = robot.ticks_per_revolution

        def counter(phi: NDArray) -> NDArray:
            raw = np.floor(phi * N / (2 * math.pi)).astype(np.int64) + robot.tick_offset
            return ((raw + 2**31) % 2**32 - 2**31).astype(np.float64)  # a signed 32-bit counter

        wheels = WheelStream(wheel_ns, counter(phi_l), counter(phi_r), "ticks", 32, ("0", "1"))
    nominal = integrate(
        robot.nominal_radius * (np.diff(phi_r) + np.diff(phi_l)) / 2.0,
        robot.nominal_radius * (np.diff(phi_r) - np.diff(phi_l)) / robot.nominal_track,
        method="exact",
    )
    odometry = PoseStream(wheel_ns.copy(), nominal)
    truth_stream = None
    if truth:
        t_truth = np.arange(robot.truth_offset, t_wheel[-1], 1.0 / robot.truth_rate)
        p = _truth_at(t_truth, t_wheel, poses, ds, dth)
        noise = rng.standard_normal((3, t_truth.size))
        p[:, 0] += robot.truth_position_std * noise[0]
        p[:, 1] += robot.truth_position_std * noise[1]
        p[:, 2] = np.mod(p[:, 2] + robot.truth_heading_std * noise[2] + np.pi, 2 * np.pi) - np.pi
        truth_stream = PoseStream(EPOCH_NS + np.round(t_truth * 1e9).astype(np.int64), p)
    return Recording(wheels=wheels, truth=truth_stream, odometry=odometry, source="simulated robot")


def write_simulated_bag(
    dest: str | Path,
    robot: SimulatedRobot,
    rng: np.random.Generator,
    segments: list[Segment] | None = None,
    *,
    storage: str = "mcap",
    truth: bool = True,
) -> Path:
    """Simulate (:func:`simulate_recording`) and write the recording as a bag (rosbags writer).

    The wheel topic is ``/joint_states`` (JointState) or, with ticks, ``/wheel_ticks``
    (Int32MultiArray); ground truth ``/ground_truth`` (PoseStamped), robot odometry ``/odom``.
    """
    rec = simulate_recording(robot, rng, segments, truth=truth)
    fmt = "joint_state" if rec.wheels.kind == "position" else "ticks"
    return write_recording(rec, dest, storage=storage, wheel_format=fmt)
