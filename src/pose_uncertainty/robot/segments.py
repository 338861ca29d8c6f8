"""The recorded path cut into independent segments, with their odometry and ground truth.

A segment runs from wheel stamp ``a`` to wheel stamp ``c``. Its lengths, in wheel
travel ``τ = Σ (|Δs_r| + |Δs_l|)/2`` (so that a turn in place counts too), cycle
through :data:`LENGTHS`: short and long segments together tell the noise that grows
with the distance (the wheels') from the noise that does not (the ground truth's).
Two segments never share a ground-truth sample (the next one starts after the truth
bracket of the last one's end), so their residuals are independent under the model,
and a segment of integrated velocities never spans a wheel gap.

For each segment:

* the wheel angle increments ``Δφ_l, Δφ_r`` (padded with zeros to a common length: a
  step without travel moves nothing and adds no noise);
* the ground-truth relative pose ``z = T_a⁻¹ T_c`` (x, y in the frame of the start
  pose, θ the heading change);
* the interpolation weights ``w = (1 − u)² + u²`` of its two ends: the variance factor
  of a truth pose interpolated between two samples with independent noise.

The odometry prediction for radii ``r_l, r_r`` and track ``b`` is the exact-arc
integration of ``Δs = r Δφ`` from the identity, and the residual is
``z − g`` with the heading difference wrapped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core import se2
from ..core.kinematics import integrate, wrap_angle
from .align import AlignedRecording, interpolate_poses

__all__ = ["LENGTHS", "Segments", "cut_segments", "predict", "residuals"]

#: Segment lengths in wheel travel [m], cycled.
LENGTHS: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0)


@dataclass(frozen=True, eq=False)
class Segments:
    """Independent segments of a recording (module docstring).

    Attributes
    ----------
    start, end : (J,) — wheel indices a, c
    dphi_l, dphi_r : (J, K) — per-step wheel angle increments [rad], zero-padded
    z : (J, 3) — ground-truth relative poses [m, m, rad]
    w_start, w_end : (J,) — interpolation variance factors of the two truth ends
    travel : (J,) — nominal wheel travel τ of each segment [m]
    """

    start: NDArray[np.intp]
    end: NDArray[np.intp]
    dphi_l: NDArray[np.float64]
    dphi_r: NDArray[np.float64]
    z: NDArray[np.float64]
    w_start: NDArray[np.float64]
    w_end: NDArray[np.float64]
    travel: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.start.size)

    def take(self, mask: ArrayLike) -> Segments:
        """The segments where ``mask`` is true (or at the given indices)."""
        m = np.asarray(mask)
        return Segments(*(getattr(self, f)[m] for f in (
            "start", "end", "dphi_l", "dphi_r", "z", "w_start", "w_end", "travel")))  # fmt: skip


def _travel(rec: AlignedRecording, radius: float) -> NDArray:
    """Cumulative nominal wheel travel τ at each wheel stamp [m]."""
    step = 0.5 * radius * (np.abs(np.diff(rec.phi_l)) + np.abs(np.diff(rec.phi_r)))
    return np.concatenate([[0.0], np.cumsum(step)])


def _boundaries(
    rec: AlignedRecording, tau: NDArray, ok: NDArray, bracket: NDArray, lengths: tuple[float, ...]
) -> list[tuple[int, int]]:
    """Greedy (a, c) pairs: length cycled, no shared truth sample, no velocity gap inside."""
    gap_before = np.concatenate([[0], np.cumsum(rec.wheel_gap)])  # gaps in [0, i)
    check_gaps = rec.kind == "velocity"
    pairs: list[tuple[int, int]] = []
    n = tau.size
    a = int(np.argmax(ok)) if ok.any() else n
    j = 0
    while a < n:
        target = tau[a] + lengths[j % len(lengths)]
        c = int(np.searchsorted(tau, target, side="left"))
        if c >= n:
            break
        if ok[c] and not (check_gaps and gap_before[c] - gap_before[a] > 0):
            pairs.append((a, c))
            j += 1
            # the next start: after the truth bracket (i, i+1) of c
            nxt = np.flatnonzero(ok[c + 1 :] & (bracket[c + 1 :] > bracket[c] + 1))
            a = c + 1 + int(nxt[0]) if nxt.size else n
        else:
            nxt = np.flatnonzero(ok[c + 1 :])
            a = c + 1 + int(nxt[0]) if nxt.size else n
    return pairs


def cut_segments(
    rec: AlignedRecording, radius: float, lengths: tuple[float, ...] = LENGTHS
) -> Segments:
    """Cut the recording into independent segments (module docstring).

    Parameters
    ----------
    rec : AlignedRecording with ground truth
    radius : float [m] — nominal wheel radius (only to measure travel)
    lengths : segment lengths in wheel travel [m], cycled
    """
    assert rec.truth_t is not None
    assert rec.truth_poses is not None
    truth, ok, bracket, u = interpolate_poses(rec.truth_t, rec.truth_poses, rec.t)
    tau = _travel(rec, radius)
    pairs = _boundaries(rec, tau, ok, bracket, lengths)
    if not pairs:
        return Segments(*(np.zeros((0, *s)) for s in ((), (), (0,), (0,), (3,), (), (), ())))  # type: ignore[arg-type]
    a = np.array([p[0] for p in pairs], dtype=np.intp)
    c = np.array([p[1] for p in pairs], dtype=np.intp)
    K = int((c - a).max())
    steps = a[:, None] + np.arange(K)[None, :]
    inside = steps < c[:, None]
    steps = np.minimum(steps, rec.t.size - 2)
    dl = np.where(inside, np.diff(rec.phi_l)[steps], 0.0)
    dr = np.where(inside, np.diff(rec.phi_r)[steps], 0.0)
    z = se2.compose(se2.inverse(truth[a]), truth[c])
    z[:, 2] = truth[c, 2] - truth[a, 2]
    w = (1.0 - u) ** 2 + u**2
    return Segments(a, c, dl, dr, z, w[a], w[c], tau[c] - tau[a])


def predict(seg: Segments, radius_l: ArrayLike, radius_r: ArrayLike, track: ArrayLike) -> NDArray[np.float64]:
    """Odometry relative poses ``g`` of the segments for geometries (batch shape B...).

    Parameters
    ----------
    radius_l, radius_r, track : array_like, shape (B...) [m]

    Returns
    -------
    ndarray, shape (B..., J, 3)
    """
    rl, rr, b = (np.asarray(v, dtype=np.float64)[..., None, None] for v in (radius_l, radius_r, track))
    ds_l, ds_r = rl * seg.dphi_l, rr * seg.dphi_r
    poses = integrate((ds_r + ds_l) / 2.0, (ds_r - ds_l) / b, method="exact")
    return poses[..., -1, :]


def residuals(seg: Segments, g: NDArray[np.float64]) -> NDArray[np.float64]:
    """``z − g`` with the heading difference wrapped, shape (..., J, 3)."""
    r = seg.z - g
    r[..., 2] = wrap_angle(r[..., 2])
    return r
