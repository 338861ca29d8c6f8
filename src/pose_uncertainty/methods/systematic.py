"""Systematic odometry errors: wheels and track that differ from what the odometry assumes.

Skalka 2011 §3.2.1: unequal wheel diameters and a wrong track dominate the
odometry error indoors, and grow steadily with distance. UMBmark (Borenstein &
Feng 1996) measures them by driving a square; this module simulates that.

Model
-----
Encoder readings are expressed in *nominal metres*: the travel a wheel of the
nominal diameter would make for the counted rotation. A :class:`WheelGeometry`
``(track, scale_r, scale_l)`` says that for a reading ``r`` a wheel really
travels ``scale · r`` (``scale = D / D_nominal``) and that the wheels are
``track`` apart. Two geometries describe a robot:

* ``odometry`` — what the robot's odometry assumes (nominal: scales 1, the
  nominal track; after a calibration, the corrected values);
* ``true`` — how the robot really moves.

The robot drives closed-loop on its odometry, as in UMBmark: its controller
makes the *odometry* trace the commanded path exactly, so the readings of a
step with commanded (odometry) travels ``Δs`` are ``r = Δs / scale_odo``, and the
wheels really travel ``scale_true · r`` on the true track. On top of that the
existing random error (:mod:`pose_uncertainty.methods.sampling`, per-step
``N(0, k|Δs|)`` of each wheel's true travel: slip) applies; the physical motion
is integrated by exact arcs. The odometry's belief is the commanded path.

Borenstein & Feng's parameters: ``E_d = D_R / D_L`` (true diameters) and
``E_b = b_actual / b_nominal``, with the mean diameter right:
``scale_r = 2E_d/(E_d+1)``, ``scale_l = 2/(E_d+1)`` (:meth:`WheelGeometry.from_ratios`).
A common scale error of both wheels is not part of UMBmark (it is calibrated on a
straight run); on the square it would look like a track error.

Return-position error (sign convention)
---------------------------------------
UMBmark's ``ε = (x_abs − x_calc, y_abs − y_calc)``: the *true* end position minus
the *odometry's* end position, in the frame of the start pose (x along the
robot's initial heading, which is the first leg of the square, y to its left)
[m]. The square starts at the start pose and turns left (``"ccw"``) or right
(``"cw"``) at each corner (:func:`pose_uncertainty.core.trajectories.square`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import integrate
from ..core.trajectories import Trajectory, square
from ..core.validation import check_choice, check_nonnegative, check_positive, check_positive_int
from .sampling import REGIMES, sample_end_poses

__all__ = [
    "DIRECTIONS",
    "WheelGeometry",
    "executed",
    "return_errors",
    "return_errors_noiseless",
    "umbmark_runs",
]

#: Directions of the UMBmark square: clockwise (right turns), counter-clockwise (left turns).
DIRECTIONS: tuple[str, ...] = ("cw", "ccw")
_SIGN = {"cw": -1, "ccw": 1}


@dataclass(frozen=True)
class WheelGeometry:
    """Wheel scales and track of a differential-drive robot (module docstring).

    Attributes
    ----------
    track : float — wheel separation b [m], > 0
    scale_r, scale_l : float — wheel travel per nominal metre read by the encoder,
        ``D / D_nominal`` [1], > 0
    """

    track: float
    scale_r: float = 1.0
    scale_l: float = 1.0

    def __post_init__(self) -> None:
        for name in ("track", "scale_r", "scale_l"):
            object.__setattr__(self, name, float(check_positive(name, getattr(self, name))))

    @classmethod
    def from_ratios(cls, track_nominal: float, E_d: float = 1.0, E_b: float = 1.0) -> WheelGeometry:
        """Geometry with diameter ratio ``E_d = D_R/D_L`` (mean diameter nominal) and track ``E_b·b``.

        Also Borenstein's corrected geometry: ``c_R = 2/(1/E_d + 1)``, ``c_L = 2/(E_d + 1)``,
        ``b = E_b b_nominal``.
        """
        e_d = float(check_positive("E_d", E_d))
        e_b = float(check_positive("E_b", E_b))
        b = float(check_positive("track_nominal", track_nominal))
        return cls(track=e_b * b, scale_r=2.0 * e_d / (e_d + 1.0), scale_l=2.0 / (e_d + 1.0))

    @property
    def E_d(self) -> float:
        """Diameter ratio ``D_R / D_L`` [1]."""
        return self.scale_r / self.scale_l


def executed(commanded: Trajectory, odometry: WheelGeometry, true: WheelGeometry) -> Trajectory:
    """The true wheel travels when the odometry traces ``commanded`` exactly.

    Readings ``r = Δs_cmd / scale_odo``; true travels ``scale_true · r`` on the true track.

    Parameters
    ----------
    commanded : Trajectory — the path as the odometry sees it; its track must be the odometry's
    odometry, true : WheelGeometry

    Returns
    -------
    Trajectory — same steps, true travels [m], true track, same start
    """
    if not math.isclose(commanded.track, odometry.track, rel_tol=1e-12):
        raise ValueError(
            f"commanded.track must be the odometry's track {odometry.track!r} (the odometry plans "
            f"its turns with it), got {commanded.track!r}"
        )
    return Trajectory(
        ds_r=commanded.ds_r * (true.scale_r / odometry.scale_r),
        ds_l=commanded.ds_l * (true.scale_l / odometry.scale_l),
        dt=commanded.dt,
        track=true.track,
        start=np.array(commanded.start),
        name=f"{commanded.name} (executed)",
    )


def return_errors(
    side: float,
    direction: str,
    true: WheelGeometry,
    odometry: WheelGeometry,
    n: int,
    rng: np.random.Generator,
    *,
    k_r: float = 0.0,
    k_l: float = 0.0,
    regime: str = "per_step",
    **square_kw: Any,
) -> NDArray[np.float64]:
    """Return-position errors of ``n`` runs of the UMBmark square (module docstring).

    Parameters
    ----------
    side : float [m], > 0 — side L of the square
    direction : {"cw", "ccw"}
    true, odometry : WheelGeometry
    n : int ≥ 1 — runs; rng : numpy.random.Generator
    k_r, k_l : float [m], ≥ 0 — random error constants (wheel-travel variance per metre)
    regime : {"per_step", "per_run"} — random-error regime of :func:`sample_end_poses`
    **square_kw : speed, angular_speed, dt, profile of the square (trajectories.from_segments)

    Returns
    -------
    ndarray, shape (n, 2) — ε = (x_abs − x_calc, y_abs − y_calc) in the start frame [m]
    """
    check_choice("direction", direction, DIRECTIONS)
    check_choice("regime", regime, REGIMES)
    n = check_positive_int("n", n)
    commanded = square(side, _SIGN[direction], track=odometry.track, **square_kw)
    moved = executed(commanded, odometry, true)
    ends = sample_end_poses(
        moved, float(check_nonnegative("k_r", k_r)), float(check_nonnegative("k_l", k_l)),
        n, rng, regime=regime, method="exact",
    )
    return ends[:, :2] - commanded.poses[-1, :2]


def umbmark_runs(
    side: float,
    true: WheelGeometry,
    odometry: WheelGeometry,
    n: int,
    rng: np.random.Generator,
    **kw: Any,
) -> dict[str, NDArray[np.float64]]:
    """``n`` clockwise and ``n`` counter-clockwise squares: ``{"cw": (n, 2), "ccw": (n, 2)}`` [m].

    Keywords as :func:`return_errors`; the two directions draw from the one generator in
    the order cw, ccw.
    """
    return {d: return_errors(side, d, true, odometry, n, rng, **kw) for d in DIRECTIONS}


def _square_segments(side: NDArray, sign: int, track: NDArray) -> tuple[NDArray, NDArray]:
    """Commanded wheel travels of one lap, one step per segment: shapes (..., 8) [m].

    Legs ``(L, L)``, corners ``(±(π/2)(b/2), ∓(π/2)(b/2))`` — the square of
    :func:`trajectories.square`, whose exact-arc steps compose to these segments.
    """
    leg = np.broadcast_to(side[..., None], (*np.broadcast_shapes(side.shape, track.shape), 1))
    turn = sign * (math.pi / 2) * track[..., None] / 2.0 + 0.0 * leg
    ds_r = np.concatenate([leg, turn] * 4, axis=-1)
    ds_l = np.concatenate([leg, -turn] * 4, axis=-1)
    return ds_r, ds_l


def return_errors_noiseless(
    side: ArrayLike,
    direction: str,
    true_scale_r: ArrayLike,
    true_scale_l: ArrayLike,
    true_track: ArrayLike,
    odometry_scale_r: ArrayLike = 1.0,
    odometry_scale_l: ArrayLike = 1.0,
    odometry_track: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Return-position error of one noiseless square, vectorised over geometries.

    The same model as :func:`return_errors` with ``k = 0``, computed per segment
    (each leg and corner is one exact arc), for arrays of geometries.

    Parameters
    ----------
    side : array_like [m], > 0
    direction : {"cw", "ccw"}
    true_scale_r, true_scale_l, true_track : array_like, shape (B...) — true geometry [1, 1, m]
    odometry_scale_r, odometry_scale_l, odometry_track : array_like, shape (B...) — the
        odometry's geometry (default: scales 1, track = ``true_track``)

    Returns
    -------
    ndarray, shape (B..., 2) — ε [m]
    """
    check_choice("direction", direction, DIRECTIONS)
    L = check_positive("side", side)
    sr, sl = check_positive("true_scale_r", true_scale_r), check_positive("true_scale_l", true_scale_l)
    b = check_positive("true_track", true_track)
    osr = check_positive("odometry_scale_r", odometry_scale_r)
    osl = check_positive("odometry_scale_l", odometry_scale_l)
    ob = b if odometry_track is None else check_positive("odometry_track", odometry_track)
    cmd_r, cmd_l = _square_segments(L, _SIGN[direction], ob)
    true_r = cmd_r * (sr / osr)[..., None]
    true_l = cmd_l * (sl / osl)[..., None]
    moved = integrate((true_r + true_l) / 2.0, (true_r - true_l) / b[..., None], method="exact")
    belief = integrate((cmd_r + cmd_l) / 2.0, (cmd_r - cmd_l) / ob[..., None], method="exact")
    return moved[..., -1, :2] - belief[..., -1, :2]
