"""Šafránek 2022's error sources of a wheel-speed measurement, and their equivalent constant ``k``.

Each wheel's measured speed ``v`` is corrupted by three independent errors
(Šafránek 2022 §2.3):

* encoder quantisation — ``N`` pulses per revolution, wheel diameter ``D``,
  integration time ``T``: one pulse is ``q = πD/(N T)`` m/s and the error is
  uniform on ``[−q/2, q/2]``, variance ``q²/12``;
* wheel-surface irregularity — normal, standard deviation ``c·|v|``
  (``c = surface_rel_std``, e.g. 1 %), variance ``c² v²``;
* additive white noise — normal, standard deviation ``σ_a``, variance ``σ_a²``.

Total speed variance (independent errors' variances add)::

    σ_v²(v) = q²/12 + c² v² + σ_a²                                  [m²/s²]

Two regimes
-----------
``"per_step"`` (non-systematic, random walk): a fresh error ``e_i`` every step
of length ``dt``; the wheel's travel in that step is ``(v + e_i) dt``.
``"per_run"`` (systematic): one draw per run of each source — a constant
quantisation offset ``u``, a surface scale error ``ε`` (speed ``v(1+ε)``) and a
constant additive offset ``a`` — kept for every step of the run.

The equivalent constant ``k`` (derivation)
------------------------------------------
Method A models the travel of a wheel in a step as ``Δs' ~ N(Δs, k|Δs|)``:
``k`` is the variance of the wheel's travel *per metre travelled* [m²/m = m].
In the per-step regime the travel error of one step is ``e_i dt`` with
variance ``σ_v² dt²``, while the step covers ``|Δs| = |v| dt``. Matching
``k |v| dt = σ_v² dt²`` gives::

    k = σ_v²(v) · dt / |v|                                           [m]

and over a distance ``L = n|v|dt`` the total travel has variance
``n σ_v² dt² = k L``: linear in distance, as Method A assumes. Šafránek 2022's
empirical factor ``k = 0.01 σ_v²`` is this mapping for ``dt/|v| = 0.01 s²/m``
(10 ms steps at 1 m/s) and nothing else: the proper factor depends on the
step and on the speed. Two consequences of the derivation:

* ``k`` scales with ``dt``: independent errors on finer steps average out. A
  real encoder's quantisation errors are *not* independent — counts are
  cumulative, so the quantisation error of the total travel stays within one
  pulse however long the run — and the per-step regime overstates it;
* at a standstill the constant terms ``q²/12 + σ_a²`` still add travel
  variance while ``|Δs| = 0``, which ``k|Δs|`` cannot express; the mapping
  holds for a constant nonzero speed.

In the per-run regime the total travel error is ``(u + a) t + ε L`` with
``t = L/|v|``: its variance ``σ_v² L²/v²`` grows with the *square* of distance.
Matched at one distance ``L₀`` (the per-run ``k`` of
:mod:`pose_uncertainty.methods.sampling` is that matching), the two regimes differ
everywhere else.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.trajectories import Trajectory
from ..core.validation import (
    check_choice,
    check_finite,
    check_nonnegative,
    check_positive,
    check_positive_int,
)
from .particles import REGIMES, integrate_end

__all__ = [
    "SAFRANEK_2022_CHASSIS",
    "WheelErrorSources",
    "k_equivalent",
    "sample_end_poses",
    "sample_speed_errors",
    "sample_wheel_travels",
    "speed_variance",
    "travel_variance",
]


@dataclass(frozen=True)
class WheelErrorSources:
    """Error sources of one wheel's speed measurement (Šafránek 2022 §2.3).

    Attributes
    ----------
    pulses_per_rev : int — encoder resolution N [1/rev], ≥ 1
    wheel_diameter : float — D [m], > 0
    integration_time : float — T over which pulses are counted [s], > 0
    surface_rel_std : float — surface irregularity, std relative to the speed [1], ≥ 0
    additive_std : float — additive white noise std [m/s], ≥ 0
    quantisation : bool — include the encoder quantisation (default True)
    """

    pulses_per_rev: int = 400
    wheel_diameter: float = 0.065
    integration_time: float = 0.01
    surface_rel_std: float = 0.01
    additive_std: float = 0.01
    quantisation: bool = True

    def __post_init__(self) -> None:
        check_positive_int("pulses_per_rev", self.pulses_per_rev)
        check_positive("wheel_diameter", self.wheel_diameter)
        check_positive("integration_time", self.integration_time)
        check_nonnegative("surface_rel_std", self.surface_rel_std)
        check_nonnegative("additive_std", self.additive_std)

    @property
    def pulse_speed(self) -> float:
        """Speed of one pulse per integration time ``q = πD/(N T)`` [m/s]."""
        return math.pi * self.wheel_diameter / (self.pulses_per_rev * self.integration_time)

    @property
    def quantisation_var(self) -> float:
        """Variance of the uniform ±q/2 quantisation error, ``q²/12`` [m²/s²] (0 if disabled)."""
        return self.pulse_speed**2 / 12.0 if self.quantisation else 0.0


#: Šafránek 2022's chassis: 65 mm wheels, 400 pulses/rev, 10 ms, 1 % surface, 0.01 m/s noise.
SAFRANEK_2022_CHASSIS = WheelErrorSources()


def speed_variance(sources: WheelErrorSources, v: ArrayLike) -> NDArray[np.float64]:
    """Total speed-error variance ``σ_v² = q²/12 + c² v² + σ_a²`` [m²/s²] at speed ``v`` [m/s]."""
    vv = check_finite("v", v)
    return sources.quantisation_var + (sources.surface_rel_std * vv) ** 2 + sources.additive_std**2


def k_equivalent(sources: WheelErrorSources, v: ArrayLike, dt: float) -> NDArray[np.float64]:
    """Method A's constant equivalent to the per-step regime: ``k = σ_v²(v)·dt/|v|`` [m].

    Parameters
    ----------
    sources : WheelErrorSources
    v : array_like — wheel speed [m/s], nonzero
    dt : float — step [s], > 0

    See the module docstring for the derivation.
    """
    vv = check_finite("v", v)
    if np.any(vv == 0):
        raise ValueError(
            "v must be nonzero (allowed: any speed but 0 — at a standstill the travel variance "
            f"is not proportional to the travel), got {vv}"
        )
    step = float(check_positive("dt", dt))
    return speed_variance(sources, vv) * step / np.abs(vv)


def travel_variance(
    sources: WheelErrorSources, v: float, dt: float, n_steps: ArrayLike, regime: str = "per_step"
) -> NDArray[np.float64]:
    """Variance of a wheel's total travel after ``n_steps`` steps at constant speed ``v`` [m²].

    ``per_step``: ``n σ_v² dt²`` (= ``k L``); ``per_run``: ``(n dt)² σ_v²``.
    """
    check_choice("regime", regime, REGIMES)
    n = check_nonnegative("n_steps", n_steps)
    var = float(speed_variance(sources, v))
    step = float(check_positive("dt", dt))
    return n * var * step**2 if regime == "per_step" else (n * step) ** 2 * var


def sample_speed_errors(
    sources: WheelErrorSources,
    v: ArrayLike,
    n: int,
    rng: np.random.Generator,
    regime: str = "per_step",
) -> NDArray[np.float64]:
    """Draw speed errors ``e`` [m/s] of one wheel for ``n`` runs of a speed profile.

    Parameters
    ----------
    sources : WheelErrorSources
    v : array_like, shape (N,) — the wheel's true speed in each step [m/s]
    n : int — runs; rng : numpy.random.Generator
    regime : {"per_step", "per_run"} — fresh errors every step, or one draw of
        each source per run (constant offset ``u + a`` and scale error ``ε v``)

    Returns
    -------
    ndarray, shape (n, N) — measured speed minus true speed [m/s]
    """
    check_choice("regime", regime, REGIMES)
    n = check_positive_int("n", n)
    vv = check_finite("v", v)
    if vv.ndim != 1:
        raise ValueError(f"v must have shape (N,), got shape {vv.shape}")
    q = sources.pulse_speed if sources.quantisation else 0.0
    shape = (n, vv.size) if regime == "per_step" else (n, 1)
    u = rng.uniform(-q / 2.0, q / 2.0, size=shape)
    eps = sources.surface_rel_std * rng.standard_normal(shape)
    a = sources.additive_std * rng.standard_normal(shape)
    return u + eps * vv + a


def sample_wheel_travels(
    trajectory: Trajectory,
    sources: WheelErrorSources,
    n: int,
    rng: np.random.Generator,
    regime: str = "per_step",
    sources_left: WheelErrorSources | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Noisy per-step wheel travels ``(v + e) dt`` of ``n`` runs of a trajectory.

    Parameters
    ----------
    trajectory : Trajectory; sources : WheelErrorSources (right wheel, and left
    unless ``sources_left`` is given); n : int; rng : numpy.random.Generator
    regime : {"per_step", "per_run"}

    Returns
    -------
    ds_r, ds_l : ndarray, shape (n, N) [m]
    """
    left = sources if sources_left is None else sources_left
    dt = trajectory.dt
    e_r = sample_speed_errors(sources, trajectory.v_r, n, rng, regime)
    e_l = sample_speed_errors(left, trajectory.v_l, n, rng, regime)
    return trajectory.ds_r + e_r * dt, trajectory.ds_l + e_l * dt


def sample_end_poses(
    trajectory: Trajectory,
    sources: WheelErrorSources,
    n: int,
    rng: np.random.Generator,
    regime: str = "per_step",
    method: str = "midpoint",
    checkpoints: Sequence[int] | None = None,
    sources_left: WheelErrorSources | None = None,
) -> NDArray[np.float64]:
    """End poses of ``n`` runs with wheel-speed errors, integrated by :func:`.particles.integrate_end`.

    Returns
    -------
    ndarray, shape (n, 3) — or (n, C, 3) at the ``checkpoints`` step indices.
    """
    ds_r, ds_l = sample_wheel_travels(trajectory, sources, n, rng, regime, sources_left)
    out = integrate_end(ds_r, ds_l, trajectory.track, trajectory.start, method, checkpoints)
    return out[:, 0, :] if checkpoints is None else out
