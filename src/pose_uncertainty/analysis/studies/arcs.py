"""The constant-speed arc of Šafránek 2022's studies: the trajectory and its closed-form end pose.

Constant wheel speeds drive an exact circular arc, so the closed form
(:func:`exact_constant_arc`, in long double by default) is the truth that the
integration-method and number-type studies measure against.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...core import trajectories as tr
from ...core.validation import check_positive, check_positive_int


def constant_speed_trajectory(
    v_r: float = 1.0, v_l: float = 0.95, duration: float = 1.0, dt: float = 0.01, track: float = 0.1
) -> tr.Trajectory:
    """Šafránek 2022's run: constant wheel speeds [m/s] for ``duration`` [s] in steps of ``dt`` [s]."""
    n = check_positive_int("n_steps", max(1, round(float(check_positive("duration", duration)) / dt)))
    return tr.Trajectory(
        ds_r=np.full(n, v_r * dt), ds_l=np.full(n, v_l * dt), dt=dt, track=track,
        name=f"constant wheels {v_r:g}/{v_l:g} m/s, {n} steps of {dt:g} s",
    )


def exact_constant_arc(
    v_r: float, v_l: float, t: ArrayLike, track: float, dtype: Any = np.longdouble
) -> NDArray:
    """Closed-form pose after driving constant wheel speeds for time ``t`` from (0, 0, 0).

    ``x = V t sinc(ωt/2) cos(ωt/2)``, ``y = V t sinc(ωt/2) sin(ωt/2)``,
    ``θ = ωt``, evaluated in ``dtype`` (long double by default: the reference
    of the number-type study). Returns shape (..., 3).
    """
    T = np.dtype(dtype).type
    tt = np.asarray(t, dtype=dtype)
    V = (T(v_r) + T(v_l)) / T(2)
    w = (T(v_r) - T(v_l)) / T(track)
    th = w * tt
    half = th / T(2)
    with np.errstate(invalid="ignore", divide="ignore"):
        sinc = np.where(half == 0, T(1), np.sin(half) / np.where(half == 0, T(1), half))
    chord = V * tt * sinc
    return np.stack([chord * np.cos(half), chord * np.sin(half), th], axis=-1)
