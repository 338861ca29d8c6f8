"""The simulated robot's parameters and its commanded drive (apart from the simulation: no bag library).

:class:`SimulatedRobot` holds the true and the nominal geometry, the wheel error constants
and the recording rates; :func:`calibration_drive` the commanded path. The simulation and
the bag it is written to are :mod:`.simulate`'s; the configuration's key table
(:mod:`pose_uncertainty.experiments.robot_config`) reads its defaults from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..core.trajectories import Arc, Line, Segment, Turn
from ..core.validation import check_nonnegative, check_positive, check_positive_int

__all__ = ["TRUTH_UNITS", "SimulatedRobot", "calibration_drive"]

#: The unit of each true quantity of :meth:`SimulatedRobot.truth` (the keys of ``calibration.json``).
TRUTH_UNITS: dict[str, str] = {
    "E_d": "1", "E_b": "1", "wheel_radius_left": "m", "wheel_radius_right": "m", "track": "m", "k_r": "m", "k_l": "m",
}  # fmt: skip


@dataclass(frozen=True)
class SimulatedRobot:
    """The true and nominal geometry, the error constants and the recording rates.

    Attributes
    ----------
    radius_left, radius_right, track : float [m] — the truth
    nominal_radius, nominal_track : float [m] — what the robot's odometry assumes
    k_r, k_l : float [m] — wheel-travel variance per metre travelled (Method A)
    truth_position_std [m], truth_heading_std [rad] — noise of each ground-truth sample
    wheel_rate, truth_rate : float [Hz]; truth_offset : float [s]
    ticks_per_revolution : int or None — None: JointState positions
    tick_offset : int — counter value at the start (near 2³¹ − 1 makes it wrap)
    speed [m/s], angular_speed [rad/s] — mean speeds of the path's segments
    """

    radius_left: float = 0.0502
    radius_right: float = 0.0498
    track: float = 0.306
    nominal_radius: float = 0.05
    nominal_track: float = 0.30
    k_r: float = 1.2e-4
    k_l: float = 0.8e-4
    truth_position_std: float = 5e-4
    truth_heading_std: float = 2e-3
    wheel_rate: float = 50.0
    truth_rate: float = 40.0
    truth_offset: float = 0.0037
    ticks_per_revolution: int | None = None
    tick_offset: int = 0
    speed: float = 0.5
    angular_speed: float = 1.0

    def __post_init__(self) -> None:
        for name in ("radius_left", "radius_right", "track", "nominal_radius", "nominal_track",
                     "wheel_rate", "truth_rate", "speed", "angular_speed"):  # fmt: skip
            check_positive(name, getattr(self, name))
        for name in ("k_r", "k_l", "truth_position_std", "truth_heading_std", "truth_offset"):
            check_nonnegative(name, getattr(self, name))
        if self.ticks_per_revolution is not None:
            check_positive_int("ticks_per_revolution", self.ticks_per_revolution)

    def truth(self) -> dict[str, dict[str, float | str]]:
        """The true values of the calibrated quantities, each ``{value, unit}`` (:data:`TRUTH_UNITS`).

        ``E_d = r_r / r_l`` and ``E_b = b / b_nominal`` (Borenstein & Feng 1996), relative to
        the geometry the robot's own odometry assumes, as the calibration reports them.
        """
        values = {
            "E_d": self.radius_right / self.radius_left, "E_b": self.track / self.nominal_track,
            "wheel_radius_left": self.radius_left, "wheel_radius_right": self.radius_right, "track": self.track,
            "k_r": self.k_r, "k_l": self.k_l,
        }  # fmt: skip
        return {k: {"value": float(v), "unit": TRUTH_UNITS[k]} for k, v in values.items()}


def calibration_drive(side: float = 2.0, laps: int = 3, arcs: int = 2) -> list[Segment]:
    """The commanded path: ``laps`` UMBmark squares cw, ``laps`` ccw, then ``arcs`` S-bends.

    Squares of ``side`` [m] turning in place by ∓π/2 at each corner (Borenstein & Feng
    1996); each S-bend is a quarter arc of radius 1 m left and one right.
    """
    L = float(check_positive("side", side))
    segs: list[Segment] = []
    for sign in (-1, 1):
        segs += [Line(L), Turn(sign * math.pi / 2)] * (4 * check_positive_int("laps", laps))
    for _ in range(int(arcs)):
        segs += [Arc(1.0, math.pi / 2), Arc(1.0, -math.pi / 2)]
    return segs
