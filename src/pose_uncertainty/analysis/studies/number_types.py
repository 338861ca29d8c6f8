"""Number types: the step loop in integer millimetres, float32, float64 and long double.

Šafránek 2022 ran the simulator in several C++ number types. :func:`integrate_in_type`
repeats that sequential step loop in a given type (the one place a per-step loop is
the point); :func:`number_type_drift` measures its drift from the exact end pose and
:func:`number_type_clouds` what the type does to the cloud of end poses.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...core import trajectories as tr
from ...core.kinematics import METHODS
from ...core.validation import check_choice, check_positive, check_positive_int
from ...methods import wheel_noise as wn
from .arcs import constant_speed_trajectory, exact_constant_arc

NUMBER_TYPES: tuple[str, ...] = ("int_mm", "float32", "float64", "longdouble")


def integrate_in_type(
    ds_r: ArrayLike,
    ds_l: ArrayLike,
    track: float,
    dt: float,
    number_type: str,
    *,
    method: str = "exact",
    scheme: str = "full",
) -> NDArray[np.float64]:
    """Integrate wheel travels with a sequential step loop in one number type.

    As in Šafránek 2022, lengths are millimetres inside the loop and the wheel
    *speeds* [mm/s] are stored in the type (for integers: truncated toward
    zero, C's conversion); each step's travel is speed × step. The result is
    returned in metres as float64.

    Parameters
    ----------
    ds_r, ds_l : array_like, shape (n, N) — per-run, per-step wheel travels [m]
    track : float [m]; dt : float — step [s]
    number_type : {"int_mm", "float32", "float64", "longdouble"}
    method : {"exact", "midpoint", "euler", "euler_end"}
    scheme : {"full", "thesis"}
        ``full`` — every quantity (speeds, step, heading, trigonometry,
        positions) in the type (floats only); ``thesis`` — as Šafránek 2022's C++:
        positions and speeds in the type, heading and the increments in double,
        each increment added to the stored position and converted back to the
        type (for integers with truncation toward zero). ``int_mm`` always
        uses ``thesis``.

    Returns
    -------
    ndarray, shape (n, 3) — end poses [m, m, rad]
    """
    check_choice("number_type", number_type, NUMBER_TYPES)
    check_choice("method", method, METHODS)
    check_choice("scheme", scheme, ("full", "thesis"))
    step = float(check_positive("dt", dt))
    r_m = np.atleast_2d(np.asarray(ds_r, dtype=np.float64))
    l_m = np.atleast_2d(np.asarray(ds_l, dtype=np.float64))
    is_int = number_type == "int_mm"
    T: Any = _NUMPY_TYPES[number_type]
    # wheel speeds [mm/s] stored in the type (Šafránek 2022 keeps them in TYPENAME)
    vr_t = _store(r_m / step * 1000.0, T)
    vl_t = _store(l_m / step * 1000.0, T)
    if scheme == "full" and not is_int:
        x, y, th64 = _integrate_all_in_type(vr_t, vl_t, track, step, method, T)
    else:
        x, y, th64 = _integrate_as_thesis(vr_t, vl_t, track, step, method, T)
    return np.stack([x.astype(np.float64) / 1000.0, y.astype(np.float64) / 1000.0, th64], -1)


_NUMPY_TYPES: dict[str, Any] = {
    "int_mm": np.int64, "float32": np.float32, "float64": np.float64, "longdouble": np.longdouble,
}  # fmt: skip


def _store(v: NDArray, T: Any) -> NDArray:
    """``v`` converted to the number type ``T`` (integers: truncated toward zero, as C converts)."""
    return np.trunc(v).astype(np.int64) if T is np.int64 else v.astype(T)


def _integrate_all_in_type(
    vr_t: NDArray, vl_t: NDArray, track: float, step: float, method: str, T: Any
) -> tuple[NDArray, NDArray, NDArray[np.float64]]:
    """Scheme ``full``: speeds, step, heading, trigonometry and positions all in the float type ``T``.

    ``vr_t, vl_t`` (n, N) wheel speeds [mm/s] in ``T``; returns x, y [mm] in ``T``
    and the heading [rad] as float64, each shape (n,).
    """
    n_runs, n_steps = vr_t.shape
    x = np.zeros(n_runs, dtype=T)
    y = np.zeros(n_runs, dtype=T)
    b = T(track * 1000.0)
    h = T(step)
    half = T(0.5)
    th = np.zeros(n_runs, dtype=T)
    for i in range(n_steps):  # the sequential loop in the type is the experiment
        r, l = vr_t[:, i] * h, vl_t[:, i] * h
        ds = (r + l) * half
        dth = (r - l) / b
        phi, scale = _phi_scale(th, ds, dth, method, half, T)
        x = x + scale * np.cos(phi)
        y = y + scale * np.sin(phi)
        th = th + dth
    return x, y, th.astype(np.float64)


def _integrate_as_thesis(
    vr_t: NDArray, vl_t: NDArray, track: float, step: float, method: str, T: Any
) -> tuple[NDArray, NDArray, NDArray[np.float64]]:
    """Scheme ``thesis``, as Šafránek 2022's C++: positions and speeds in ``T``, the rest in double.

    Each increment is computed in double, added to the stored position and
    converted back to ``T`` (integers: truncated toward zero). Arguments and
    result as :func:`_integrate_all_in_type`.
    """
    n_runs, n_steps = vr_t.shape
    is_int = T is np.int64
    x = np.zeros(n_runs, dtype=T)
    y = np.zeros(n_runs, dtype=T)
    bd = track * 1000.0
    th64 = np.zeros(n_runs)
    for i in range(n_steps):
        r = vr_t[:, i].astype(np.float64) * step
        l = vl_t[:, i].astype(np.float64) * step
        ds = (r + l) * 0.5
        dth = (r - l) / bd
        phi, scale = _phi_scale(th64, ds, dth, method, 0.5, np.float64)
        # iX += increment: computed in double, converted back to the stored type
        x = _store(x.astype(np.float64) + scale * np.cos(phi), T) if is_int else (
            x + scale * np.cos(phi)).astype(T)
        y = _store(y.astype(np.float64) + scale * np.sin(phi), T) if is_int else (
            y + scale * np.sin(phi)).astype(T)
        th64 = th64 + dth
    return x, y, th64


def _phi_scale(
    th: NDArray, ds: NDArray, dth: NDArray, method: str, half: Any, T: Any
) -> tuple[NDArray, NDArray]:
    """Heading of the chord and its length for one step, in the arrays' type."""
    if method == "euler":
        return th, ds
    if method == "euler_end":
        return th + dth, ds
    phi = th + dth * half
    if method == "midpoint":
        return phi, ds
    h = dth * half
    safe = np.where(h == 0, T(1), h)
    sinc = np.where(h == 0, T(1), np.sin(safe) / safe)
    return phi, ds * sinc


def number_type_drift(
    n_steps: Sequence[int] = (100, 1000, 10_000),
    *,
    v_r: float = 1.0,
    v_l: float = 0.95,
    dt: float = 0.01,
    track: float = 0.1,
    scheme: str = "full",
    number_types: Sequence[str] = NUMBER_TYPES,
) -> list[dict[str, Any]]:
    """Drift of the noiseless end pose computed in each number type from the exact result.

    Constant wheel speeds (Šafránek 2022's arc), exact-arc steps, so the only error
    is arithmetic; the reference is the closed form in long double.

    Returns
    -------
    list of dict: ``number_type``, ``scheme``, ``n_steps``, ``distance`` [m],
    ``position_error`` [m], ``heading_error`` [rad].
    """
    rows = []
    for N in n_steps:
        N = check_positive_int("n_steps", N)
        truth = exact_constant_arc(v_r, v_l, N * dt, track).astype(np.float64)
        r = np.full((1, N), v_r * dt)
        l = np.full((1, N), v_l * dt)
        for nt in number_types:
            end = integrate_in_type(r, l, track, dt, nt, scheme=scheme)[0]
            rows.append(
                {
                    "number_type": nt,
                    "scheme": "thesis" if nt == "int_mm" else scheme,
                    "n_steps": N,
                    "distance": N * dt * (v_r + v_l) / 2,
                    "position_error": float(math.hypot(end[0] - truth[0], end[1] - truth[1])),
                    "heading_error": float(abs(end[2] - truth[2])),
                }
            )
    return rows


def number_type_clouds(
    trajectory: tr.Trajectory,
    sources: wn.WheelErrorSources,
    n: int,
    seed: int,
    *,
    regime: str = "per_step",
    scheme: str = "thesis",
    number_types: Sequence[str] = NUMBER_TYPES,
) -> dict[str, dict[str, Any]]:
    """What each number type does to the cloud: same wheel-speed draws, four arithmetics.

    Returns
    -------
    dict per number type: ``mean`` (3,), ``std`` (3,), ``distinct_y`` (number
    of distinct y values: integer millimetres collapse the across-track
    spread onto a few values), and ``max_abs_difference_m`` — the largest
    position difference of a run from its long-double result.
    """
    ds_r, ds_l = wn.sample_wheel_travels(trajectory, sources, n, np.random.default_rng(seed), regime)
    ends = {
        nt: integrate_in_type(ds_r, ds_l, trajectory.track, trajectory.dt, nt, scheme=scheme)
        for nt in number_types
    }
    ref = ends.get("longdouble")
    out = {}
    for nt, e in ends.items():
        row = {
            "mean": e.mean(0).tolist(),
            "std": e.std(0, ddof=1).tolist(),
            "distinct_y": int(np.unique(e[:, 1]).size),
        }
        if ref is not None:
            row["max_abs_difference_m"] = float(np.max(np.hypot(*(e[:, :2] - ref[:, :2]).T)))
        out[nt] = row
    return out


def number_type_clouds_study(
    v_r: float = 1.0, v_l: float = 1.0, duration: float = 1.0, dt: float = 0.01, track: float = 0.1,
    n: int = 1000, seed: int = 3, regime: str = "per_step", scheme: str = "thesis",
) -> dict[str, Any]:
    """:func:`number_type_clouds` with Šafránek 2022's error sources."""
    t = constant_speed_trajectory(v_r, v_l, duration, dt, track)
    return number_type_clouds(t, wn.SAFRANEK_2022_CHASSIS, n, seed, regime=regime, scheme=scheme)
