"""Seeded simulation of a localization run: the true path, the odometry and the measurements.

The robot is commanded along a nominal :class:`~pose_uncertainty.core.trajectories.Trajectory`.
Its encoders report the nominal wheel travels ``(Δs_r, Δs_l)`` — the odometry every
filter sees — while the wheels really travel ``Δs' ≠ Δs``, drawn by the existing noise
regimes of :func:`pose_uncertainty.methods.sampling.sample_end_poses` (one particle,
every pose kept, exact arcs):

* ``"per_step"`` — ``Δs' ~ N(Δs, k|Δs|)`` every step: the model Method A and the
  EKF assume (then the filters' model is right);
* ``"per_run"`` — one scale error per wheel for the whole run (systematic; the
  filters' model is then wrong in a realistic way).

So ``p(true travel | measured travel)`` is the wheel-noise model: the filters predict
from the measured travels and the truth drifts away from them.

``truth="commanded"`` turns this round (:data:`TRUTHS`): the robot follows the commanded
path exactly (as a robot steered along a route by an outer loop does) and its encoders
report noisy travels ``Δs' = Δs + N(0, k|Δs|)`` per step (``per_run``: ``Δs' = Δs(1 + ε)``,
``ε ~ N(0, k/L)``, as the sampler's regimes), so the odometry drifts and the truth does
not — a long path then stays inside its room. ``p(true | measured)`` is the same
wheel-noise model to first order (the variance is ``k|Δs|`` of the true rather than the
measured travel), so the filters' models are right in both.

Measurements are taken at the observation instants of each sensor: step ``k`` is an
observation step when ``k = 0`` or when ``t_k = k·Δt`` crosses a multiple of the
sensor's ``period``. Landmark measurements are drawn for every landmark at every step
(so the random stream does not depend on visibility) and masked; a beam scan is drawn
from the beam model at the true pose.

Kidnapping: from ``kidnap_step`` on, the true path is moved rigidly so that its pose at
that step becomes ``kidnap_pose`` (the robot is carried away between two steps and
then drives on with the same wheel travels); the odometry does not notice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import integrate
from ..core.trajectories import Trajectory
from ..core.validation import check_choice, check_finite, check_nonnegative
from ..methods.sampling import REGIMES, sample_end_poses
from .sensors import (
    BeamSensor,
    RangeBearingSensor,
    expected_ranges,
    sample_beam_measurements,
    sample_landmark_measurements,
)
from .world import World

__all__ = ["TRUTHS", "SimulatedRun", "measured_travels", "observation_steps", "relocate_path", "simulate"]

#: Where the wheel noise goes: the true path drifts from the commanded one ("drifts"), or the
#: robot follows the commanded path and the encoders' report drifts ("commanded").
TRUTHS: tuple[str, ...] = ("drifts", "commanded")

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class SimulatedRun:
    """One simulated run: plain arrays, index ``k = 0 … N`` over the poses.

    Attributes
    ----------
    times : ndarray, shape (N+1,) [s]
    dt : float [s]; track : float [m]
    true_poses : ndarray, shape (N+1, 3) [m, m, rad] — heading unwrapped
    ds_r, ds_l : ndarray, shape (N,) [m] — measured wheel travels of step k → k+1
    controls : ndarray, shape (N, 2) [m/s, rad/s] — measured ``(V, ω)`` (velocity model)
    odometry : ndarray, shape (N+1, 3) — dead-reckoned poses from the measured travels
        (exact arcs from the nominal start; the odometry model's ``u``)
    landmark_z : ndarray, shape (N+1, L, 2) — ``(r, φ)`` of landmark j in row j
    landmark_valid : ndarray of bool, shape (N+1, L) — observation step and landmark visible
    beam_z : ndarray, shape (N+1, B) [m], or None
    beam_valid : ndarray of bool, shape (N+1,) — observation steps of the beam sensor
    kidnap_step : int — −1 when the robot is not kidnapped
    regime : str
    """

    times: Array
    dt: float
    track: float
    true_poses: Array
    ds_r: Array
    ds_l: Array
    controls: Array
    odometry: Array
    landmark_z: Array
    landmark_valid: BoolArray
    beam_z: Array | None
    beam_valid: BoolArray
    kidnap_step: int
    regime: str

    @property
    def n_steps(self) -> int:
        """Number of motion steps ``N``."""
        return int(self.ds_r.size)


def observation_steps(n_steps: int, dt: float, period: float) -> BoolArray:
    """Which of the poses ``k = 0 … N`` are observation instants of a sensor, shape (N+1,).

    ``k = 0`` and every ``k`` whose time ``k·Δt`` reaches the next multiple of ``period``
    (10⁻⁹ relative slack against round-off); ``period ≤ Δt`` observes every step.
    """
    t = np.arange(n_steps + 1) * dt
    tick = np.floor(t / period + 1e-9)
    obs = np.ones(n_steps + 1, dtype=bool)
    obs[1:] = tick[1:] > tick[:-1]
    return obs


def relocate_path(poses: ArrayLike, new_start: ArrayLike) -> Array:
    """Move a path rigidly so that its first pose becomes ``new_start``, shape (M, 3)."""
    p = check_finite("poses", poses).reshape(-1, 3)
    q = check_finite("new_start", new_start)
    rot = q[2] - p[0, 2]
    c, s = np.cos(rot), np.sin(rot)
    d = p[:, :2] - p[0, :2]
    xy = q[:2] + np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], axis=-1)
    return np.concatenate([xy, (p[:, 2] + rot)[:, None]], axis=-1)


def _true_path(trajectory: Trajectory, k_r: float, k_l: float, regime: str, rng: np.random.Generator) -> Array:
    """One noisy execution of the trajectory, every pose kept: shape (N+1, 3) (exact arcs)."""
    N = trajectory.n_steps
    path = sample_end_poses(trajectory, k_r, k_l, 1, rng, regime=regime, method="exact",
                            checkpoints=range(N + 1), workers=1)  # fmt: skip
    return np.asarray(path[0])


def measured_travels(
    trajectory: Trajectory, k_r: float, k_l: float, regime: str, rng: np.random.Generator
) -> tuple[Array, Array]:
    """Noisy encoder readings of the commanded wheel travels, each shape (N,) [m].

    ``per_step``: ``Δs' = Δs + √(k|Δs|)·z`` per step and wheel; ``per_run``: ``Δs' = Δs(1 + ε)``
    with one ``ε ~ N(0, k/L)`` per wheel (``L = Σ|Δs|`` its total travel; ``ε = 0`` when ``L = 0``).
    """
    check_choice("regime", regime, REGIMES)
    out = []
    for ds, k in ((np.asarray(trajectory.ds_r), k_r), (np.asarray(trajectory.ds_l), k_l)):
        if regime == "per_step":
            out.append(ds + np.sqrt(k * np.abs(ds)) * rng.standard_normal(ds.shape))
        else:
            total = float(np.abs(ds).sum())
            eps = math.sqrt(k / total) * rng.standard_normal() if total > 0 else 0.0
            out.append(ds * (1.0 + eps))
    return out[0], out[1]


def simulate(
    trajectory: Trajectory,
    world: World,
    rng: np.random.Generator,
    *,
    k_r: float = 5e-4,
    k_l: float = 5e-4,
    regime: str = "per_step",
    landmark_sensor: RangeBearingSensor | None = None,
    beam_sensor: BeamSensor | None = None,
    kidnap_step: int = -1,
    kidnap_pose: ArrayLike | None = None,
    truth: str = "drifts",
) -> SimulatedRun:
    """Simulate a run along ``trajectory`` in ``world`` (see the module docs).

    Parameters
    ----------
    trajectory : Trajectory — nominal (commanded = measured) wheel travels and start pose
    world : World — landmarks (and a grid for the beam sensor)
    rng : numpy.random.Generator seeded from a SeedSequence (``default_rng(seed)``);
        three independent streams are spawned from it: path, landmarks, beams
    k_r, k_l : float [m] — wheel-noise constants (travel variance per metre), ≥ 0
    regime : {"per_step", "per_run"}
    landmark_sensor, beam_sensor : optional sensors (without one, its arrays are empty)
    kidnap_step : int — step at which the robot is carried to ``kidnap_pose`` (−1: never)
    kidnap_pose : array_like, shape (3,)
    truth : {"drifts", "commanded"} — which of the true path and the odometry carries the wheel noise

    Returns
    -------
    SimulatedRun
    """
    check_choice("regime", regime, REGIMES)
    kr, kl = float(check_nonnegative("k_r", k_r)), float(check_nonnegative("k_l", k_l))
    N = trajectory.n_steps
    seq = rng.bit_generator.seed_seq
    if not isinstance(seq, np.random.SeedSequence):
        raise TypeError("rng must be seeded from a SeedSequence (e.g. numpy.random.default_rng(seed))")
    g_path, g_lm, g_beam = (np.random.default_rng(s) for s in seq.spawn(3))
    measured = trajectory
    if check_choice("truth", truth, TRUTHS) == "drifts":
        true_poses = _true_path(trajectory, kr, kl, regime, g_path)
    else:
        true_poses = integrate(trajectory.ds, trajectory.dtheta, trajectory.start, method="exact")
        mr, ml = measured_travels(trajectory, kr, kl, regime, g_path)
        measured = Trajectory(mr, ml, trajectory.dt, trajectory.track, trajectory.start, trajectory.name)
    if kidnap_step >= 0:
        if not 0 < kidnap_step <= N or kidnap_pose is None:
            raise ValueError(f"kidnap_step must be in [1, {N}] with a kidnap_pose (allowed: 1..{N}), got {kidnap_step}")
        true_poses[kidnap_step:] = relocate_path(true_poses[kidnap_step:], kidnap_pose)
    L = world.n_landmarks
    lz, lvalid = np.zeros((N + 1, L, 2)), np.zeros((N + 1, L), dtype=bool)
    if landmark_sensor is not None and L:
        lz, vis = sample_landmark_measurements(true_poses, world.landmarks, landmark_sensor, g_lm)
        lvalid = vis & observation_steps(N, trajectory.dt, landmark_sensor.period)[:, None]
    bz, bvalid = None, np.zeros(N + 1, dtype=bool)
    if beam_sensor is not None:
        if world.grid is None:
            raise ValueError("beam_sensor needs a world with an occupancy grid (allowed: walls or image), got none")
        bvalid = observation_steps(N, trajectory.dt, beam_sensor.period)
        zs = expected_ranges(world.grid, true_poses, beam_sensor)
        bz = sample_beam_measurements(zs, beam_sensor, g_beam)
    odo = integrate(measured.ds, measured.dtheta, measured.start, method="exact")
    return SimulatedRun(
        times=trajectory.times, dt=trajectory.dt, track=trajectory.track, true_poses=true_poses,
        ds_r=np.array(measured.ds_r), ds_l=np.array(measured.ds_l), controls=measured.controls,
        odometry=odo, landmark_z=lz, landmark_valid=lvalid, beam_z=bz, beam_valid=bvalid,
        kidnap_step=int(kidnap_step), regime=regime,
    )  # fmt: skip
