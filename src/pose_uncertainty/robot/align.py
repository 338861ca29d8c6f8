"""Cleaning a recording and aligning it in time.

Each stream is put in stamp order and counted:

* ``out_of_order`` — messages whose stamp is earlier than the one before (as recorded);
  they are sorted into place (a stable sort);
* ``duplicates`` — messages with the stamp of an earlier one; the first is kept;
* ``gaps`` / ``dropped`` — intervals longer than 1.5 × the median interval, and the
  messages missing from them (``round(Δt / median) − 1`` each). Joint positions and
  ticks are cumulative, so a gap loses nothing but the time resolution; velocities
  are integrated across it (trapezoid), which a segment then must not span;
* ``wraps`` — counter wrap-arounds: ticks jump by about ``2**bits`` (the increments
  are taken modulo ``2**bits`` into ``[−2**(bits−1), 2**(bits−1))``); joint positions
  jump by more than π between two samples (a wheel does not turn half a revolution in
  one sample): they are unwrapped.

Wheel readings become cumulative wheel angles ``φ_l, φ_r`` [rad]: positions as they are,
ticks ``2π·count / ticks_per_revolution``, velocities integrated. Headings of poses
are unwrapped.

SE(2) interpolation
-------------------
Ground truth is needed at wheel stamps. Between two truth samples ``T_i`` and ``T_{i+1}``
the robot is taken to move with a constant twist: ``T(t) = T_i · exp(u · log(T_i⁻¹ T_{i+1}))``
with ``u = (t − t_i)/(t_{i+1} − t_i)`` (``log``/``exp`` of :mod:`..methods.expcoords`, the
heading difference wrapped), which follows an arc instead of cutting its chord and
interpolates the heading the short way round. A stamp outside the truth's time span, or
in a truth gap longer than ``max_gap`` × the median interval, has no truth.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..core import se2
from ..core.kinematics import wrap_angle
from .bag import BagError, PoseStream, Recording, WheelStream
from .config import RobotConfig

__all__ = ["AlignedRecording", "StreamCounts", "align", "interpolate_poses", "order_stamps"]


@dataclass(frozen=True)
class StreamCounts:
    """What cleaning found in one stream (module docstring)."""

    messages: int = 0
    out_of_order: int = 0
    duplicates: int = 0
    gaps: int = 0
    dropped: int = 0
    wraps: int = 0

    def problems(self) -> dict[str, int]:
        """The non-zero counts of problems."""
        keys = ("out_of_order", "duplicates", "gaps", "dropped", "wraps")
        return {k: getattr(self, k) for k in keys if getattr(self, k)}


@dataclass(frozen=True, eq=False)
class AlignedRecording:
    """A recording cleaned and on one clock.

    Attributes
    ----------
    t : ndarray, shape (n,) — wheel stamps [s] since ``t0_ns``
    phi_l, phi_r : ndarray, shape (n,) — cumulative wheel angles [rad]
    wheel_gap : ndarray of bool, shape (n − 1,) — interval i → i+1 is a wheel gap
    truth_t, truth_poses : (m,), (m, 3) or None — ground truth, heading unwrapped
    odom_t, odom_poses : (q,), (q, 3) or None — the robot's own odometry
    counts : dict stream → StreamCounts
    kind : how the wheels were recorded ("position", "velocity", "ticks")
    t0_ns : int — the clock's origin [ns]
    """

    t: NDArray[np.float64]
    phi_l: NDArray[np.float64]
    phi_r: NDArray[np.float64]
    wheel_gap: NDArray[np.bool_]
    truth_t: NDArray[np.float64] | None
    truth_poses: NDArray[np.float64] | None
    odom_t: NDArray[np.float64] | None
    odom_poses: NDArray[np.float64] | None
    counts: dict[str, StreamCounts] = field(default_factory=dict)
    kind: str = "position"
    t0_ns: int = 0


def order_stamps(t_ns: NDArray[np.int64]) -> tuple[NDArray[np.intp], int, int]:
    """Indices putting stamps in order without duplicates, and the counts (out of order, duplicates)."""
    t = np.asarray(t_ns, dtype=np.int64)
    out_of_order = int(np.count_nonzero(np.diff(t) < 0))
    order = np.argsort(t, kind="stable")
    keep = np.ones(order.size, dtype=bool)
    keep[1:] = np.diff(t[order]) != 0
    return order[keep], out_of_order, int(np.count_nonzero(~keep))


def _gaps(t: NDArray) -> tuple[NDArray[np.bool_], int, int]:
    """Gap flags per interval, the number of gaps and of messages missing from them."""
    if t.size < 3:
        return np.zeros(max(t.size - 1, 0), dtype=bool), 0, 0
    dt = np.diff(t)
    med = float(np.median(dt))
    gap = dt > 1.5 * med
    dropped = int(np.sum(np.round(dt[gap] / med) - 1)) if med > 0 else 0
    return gap, int(np.count_nonzero(gap)), dropped


def _unwrap_counter(c: NDArray, bits: int) -> tuple[NDArray, int]:
    """Cumulative counts from a counter of ``bits`` bits (increments modulo 2**bits), and the wraps."""
    if bits >= 64:
        return c - c[0], 0
    m = float(2**bits)
    raw = np.diff(c)
    inc = np.mod(raw + m / 2, m) - m / 2
    wraps = int(np.count_nonzero(np.abs(raw - inc) > m / 4))
    return np.concatenate([[0.0], np.cumsum(inc)]), wraps


def _wheel_angles(w: WheelStream, t: NDArray, robot: RobotConfig, src: str) -> tuple[NDArray, NDArray, int]:
    """Cumulative angles (left, right) [rad] from sorted readings, and the wraps undone."""
    left, right = w.left, w.right
    if w.kind == "ticks":
        if robot.ticks_per_revolution is None:
            raise BagError(f"{src}: the wheels are encoder ticks; give ticks_per_revolution in the robot file")
        bits = w.bits or 64
        cl, wl = _unwrap_counter(left, bits)
        cr, wr = _unwrap_counter(right, bits)
        scale = 2 * np.pi / robot.ticks_per_revolution
        return cl * scale, cr * scale, wl + wr
    if w.kind == "velocity":
        dt = np.diff(t)
        integ = [np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)]) for v in (left, right)]
        return integ[0], integ[1], 0
    wraps = int(np.count_nonzero(np.abs(np.diff(left)) > np.pi) + np.count_nonzero(np.abs(np.diff(right)) > np.pi))
    return np.unwrap(left), np.unwrap(right), wraps


def _clean_poses(s: PoseStream | None, t0_ns: int) -> tuple[NDArray | None, NDArray | None, StreamCounts]:
    if s is None or s.t_ns.size == 0:
        return None, None, StreamCounts()
    idx, ooo, dup = order_stamps(s.t_ns)
    t = (s.t_ns[idx] - t0_ns) * 1e-9
    p = s.poses[idx].copy()
    p[:, 2] = np.unwrap(p[:, 2])
    _, n_gaps, dropped = _gaps(t)
    return t, p, StreamCounts(int(s.t_ns.size), ooo, dup, n_gaps, dropped, 0)


def align(rec: Recording, robot: RobotConfig | None = None) -> AlignedRecording:
    """Clean every stream of ``rec`` and put them on the wheel clock (module docstring)."""
    cfg = robot if robot is not None else RobotConfig()
    w = rec.wheels
    if not np.all(np.isfinite(w.left)) or not np.all(np.isfinite(w.right)):
        raise BagError(f"{rec.source}: the wheel readings contain NaN or infinite values")
    idx, ooo, dup = order_stamps(w.t_ns)
    if idx.size < 2:
        raise BagError(f"{rec.source}: fewer than 2 wheel readings with distinct stamps")
    t0 = int(w.t_ns[idx[0]])
    t = ((w.t_ns[idx] - t0) * 1e-9).astype(np.float64)
    sorted_w = WheelStream(w.t_ns[idx], w.left[idx], w.right[idx], w.kind, w.bits, w.names)
    phi_l, phi_r, wraps = _wheel_angles(sorted_w, t, cfg, rec.source)
    gap, n_gaps, dropped = _gaps(t)
    counts = {"wheels": StreamCounts(int(w.t_ns.size), ooo, dup, n_gaps, dropped, wraps)}
    truth_t, truth_p, counts["truth"] = _clean_poses(rec.truth, t0)
    odom_t, odom_p, counts["odometry"] = _clean_poses(rec.odometry, t0)
    return AlignedRecording(
        t=t, phi_l=phi_l, phi_r=phi_r, wheel_gap=gap, truth_t=truth_t, truth_poses=truth_p,
        odom_t=odom_t, odom_poses=odom_p, counts=counts, kind=w.kind, t0_ns=t0,
    )  # fmt: skip


def interpolate_poses(
    t_src: NDArray[np.float64],
    poses: NDArray[np.float64],
    t_query: NDArray[np.float64],
    max_gap: float = 3.0,
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.intp], NDArray[np.float64]]:
    """Poses at ``t_query`` by SE(2) interpolation (module docstring).

    Parameters
    ----------
    t_src : (m,) increasing [s]; poses : (m, 3); t_query : (q,) [s]
    max_gap : float — longest bracket, in median intervals of ``t_src``, to interpolate across

    Returns
    -------
    poses : (q, 3) — NaN where there is no truth; valid : (q,) bool;
    i : (q,) — index of the bracket's first sample; u : (q,) — the fraction within it
    """
    if t_src.size < 2:
        q = t_query.size
        return np.full((q, 3), np.nan), np.zeros(q, bool), np.zeros(q, np.intp), np.zeros(q)
    i = np.clip(np.searchsorted(t_src, t_query, side="right") - 1, 0, t_src.size - 2)
    span = t_src[i + 1] - t_src[i]
    u = (t_query - t_src[i]) / span
    med = float(np.median(np.diff(t_src)))
    valid = (t_query >= t_src[0]) & (t_query <= t_src[-1]) & (span <= max_gap * med)
    a, b = poses[i], poses[i + 1]
    rel = se2.compose(se2.inverse(a), b)
    rel[:, 2] = wrap_angle(rel[:, 2])
    out = se2.compose(a, se2.exp(u[:, None] * se2.log(rel)))
    out[~valid] = np.nan
    return out, valid, i, np.where(valid, u, 0.0)
