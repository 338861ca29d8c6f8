"""The studies of Šafránek 2022 and the growth laws, as functions returning tables (lists of dicts).

* :func:`integration_vs_step` — the three integration methods against step
  size: error of the end pose from the exact arc, and the fitted order;
  :func:`method_cloud_spread` — whether the cloud depends on the method.
* :func:`number_type_drift`, :func:`number_type_clouds` — integer
  millimetres, float32, float64 and long double: a sequential step loop in
  the given type (the one place a per-step loop is the point), its drift from
  the exact end pose and what it does to the cloud of end poses.
* :func:`error_sources_vs_monte_carlo` — Šafránek 2022's error sources mapped to
  the equivalent ``k`` (:mod:`pose_uncertainty.methods.wheel_noise`) and checked
  against Monte Carlo; :func:`regime_growth` — systematic (per-run) against
  random (per-step) errors and their growth with distance.
* :func:`polar_vs_cartesian` — moments of the cloud in Cartesian ``(x, y)``
  and polar ``(r, φ)`` coordinates about the start.
* :func:`growth_laws` — how σ_along, σ_across, σ_θ and the credible-region
  area grow with distance: log-log power-law fits against exponential fits.
* ``umbmark`` (:func:`pose_uncertainty.analysis.umbmark.umbmark_experiment`) — the
  UMBmark squares of a robot with known systematic errors, before and after the correction;
* :func:`calibration_demo` — ``k`` fitted back from Monte Carlo end poses
  with both models; :func:`coverage_vs_distance` — coverage along a path.
* :func:`accuracy_case` — coverage and distances of the three Gaussian methods
  (A, the banana, C) on one path (the pipeline runs the long paths: straight 1, 5, 20 m; 1 and 3 laps
  of a circle; larger k); :func:`expcoords_regions` — the data of the figure of
  clouds, ellipses and bananas.

The pipeline runs each study as a job of its own (config key ``studies``; kinds
in :data:`STUDIES`, executed and logged by :mod:`pose_uncertainty.experiments.study`);
:func:`summarize` turns the logged results into what the report quotes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core import trajectories as tr
from ..core.grids import Grid
from ..core.kinematics import METHODS
from ..core.stats import PR_3SIGMA, fit_growth, path_spreads
from ..core.validation import check_choice, check_positive, check_positive_int
from ..methods import covariance as cv
from ..methods import expcoords as ec
from ..methods import maps
from ..methods import motion_models as mm
from ..methods import sampling as sp
from ..methods import unscented as ut
from ..methods import wheel_noise as wn
from . import accuracy as ac
from . import calibration as cb
from . import umbmark as um

__all__ = [
    "NUMBER_TYPES",
    "accuracy_case",
    "calibration_demo",
    "constant_speed_trajectory",
    "coverage_vs_distance",
    "error_sources_vs_monte_carlo",
    "exact_constant_arc",
    "growth_laws",
    "integrate_in_type",
    "integration_vs_step",
    "map_vs_sampler",
    "method_cloud_spread",
    "number_type_clouds",
    "number_type_drift",
    "polar_vs_cartesian",
    "regime_growth",
]

NUMBER_TYPES: tuple[str, ...] = ("int_mm", "float32", "float64", "longdouble")


# --- trajectories of Šafránek 2022 --------------------------------------------------------------


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


# --- 1. integration methods against step size -----------------------------------------------------


def integration_vs_step(
    dts: Sequence[float] = (0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001),
    *,
    v_r: float = 1.0,
    v_l: float = 0.95,
    duration: float = 1.0,
    track: float = 0.1,
    methods: Sequence[str] = ("euler", "euler_end", "midpoint", "exact"),
) -> dict[str, Any]:
    """End-pose error of each integration method against the exact arc, for several steps.

    Wheel speeds are constant (Šafránek 2022's arc: 1 and 0.95 m/s, b = 0.1 m,
    1 s), so the exact arc is the truth for every step size.

    Returns
    -------
    dict: ``rows`` — one per (dt, method): ``dt`` [s], ``method``,
    ``position_error`` [m], ``heading_error`` [rad]; ``order`` — per method the
    log-log slope of the position error against dt (1 for Euler, 2 for the
    midpoint rule; the exact arc is at rounding level).
    """
    truth = exact_constant_arc(v_r, v_l, duration, track, np.float64)
    rows = []
    for dt in dts:
        t = constant_speed_trajectory(v_r, v_l, duration, dt, track)
        for m in methods:
            check_choice("method", m, METHODS)
            end = t.poses_by(m)[-1]
            rows.append(
                {
                    "dt": float(dt),
                    "method": m,
                    "position_error": float(math.hypot(end[0] - truth[0], end[1] - truth[1])),
                    "heading_error": float(abs(end[2] - truth[2])),
                }
            )
    order = {}
    for m in methods:
        e = np.array([r["position_error"] for r in rows if r["method"] == m])
        d = np.array([r["dt"] for r in rows if r["method"] == m])
        ok = e > 1e-13
        order[m] = float(np.polyfit(np.log(d[ok]), np.log(e[ok]), 1)[0]) if ok.sum() >= 2 else 0.0
    return {"rows": rows, "order": order}


def method_cloud_spread(
    trajectory: tr.Trajectory,
    k_r: float,
    k_l: float,
    n: int,
    seed: int,
    methods: Sequence[str] = ("euler", "euler_end", "midpoint", "exact"),
) -> dict[str, Any]:
    """Does the cloud depend on the integration method? Same noise, four methods.

    The same wheel-travel draws (same seed) are integrated by each method.

    Returns
    -------
    dict: per method ``mean`` (3,) and ``cov`` (3, 3) of the cloud, and
    ``max_rel_cov_difference`` — the largest relative difference of a
    covariance entry (x, y, θ diagonal) from the exact-arc cloud.
    """
    out: dict[str, Any] = {}
    clouds = {
        m: sp.sample_end_poses(trajectory, k_r, k_l, n, np.random.default_rng(seed), method=m)
        for m in methods
    }
    ref = np.cov(clouds["exact"].T) if "exact" in clouds else None
    for m, c in clouds.items():
        C = np.cov(c.T)
        row = {"mean": c.mean(0).tolist(), "cov": C.tolist()}
        if ref is not None:
            row["max_rel_cov_difference"] = float(np.max(np.abs(np.diag(C) / np.diag(ref) - 1)))
        out[m] = row
    return out


# --- 2. number types ----------------------------------------------------------------------------


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
    scheme : {"full", "seed001"}
        ``full`` — every quantity (speeds, step, heading, trigonometry,
        positions) in the type (floats only); ``seed001`` — as Šafránek 2022's C++:
        positions and speeds in the type, heading and the increments in double,
        each increment added to the stored position and converted back to the
        type (for integers with truncation toward zero). ``int_mm`` always
        uses ``seed001``.

    Returns
    -------
    ndarray, shape (n, 3) — end poses [m, m, rad]
    """
    check_choice("number_type", number_type, NUMBER_TYPES)
    check_choice("method", method, METHODS)
    check_choice("scheme", scheme, ("full", "seed001"))
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
        x, y, th64 = _integrate_as_seed001(vr_t, vl_t, track, step, method, T)
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


def _integrate_as_seed001(
    vr_t: NDArray, vl_t: NDArray, track: float, step: float, method: str, T: Any
) -> tuple[NDArray, NDArray, NDArray[np.float64]]:
    """Scheme ``seed001``, as Šafránek 2022's C++: positions and speeds in ``T``, the rest in double.

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
                    "scheme": "seed001" if nt == "int_mm" else scheme,
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
    scheme: str = "seed001",
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


# --- 3. error sources → k, and the two regimes ---------------------------------------------------


def error_sources_vs_monte_carlo(
    sources: wn.WheelErrorSources = wn.SEED001,
    *,
    speed: float = 1.0,
    duration: float = 1.0,
    dt: float = 0.01,
    track: float = 0.1,
    n: int = 100_000,
    seed: int = 1,
) -> dict[str, float]:
    """Šafránek 2022's error sources → equivalent ``k`` → Method A, against Monte Carlo of the sources.

    Straight run at ``speed``; per-step regime.

    Returns
    -------
    dict: ``k_equivalent`` [m], ``k_seed001_factor`` (Šafránek 2022's
    ``0.01·σ_v²``), the Monte Carlo total-travel variance per metre of the
    right wheel ``k_mc_travel`` [m], and Method A's against the Monte Carlo
    end-pose variances ``var_<x|y|theta>_method_a`` / ``_mc``.
    """
    t = constant_speed_trajectory(speed, speed, duration, dt, track)
    rng = np.random.default_rng(seed)
    k = float(wn.k_equivalent(sources, speed, dt))
    ds_r, ds_l = wn.sample_wheel_travels(t, sources, n, rng, "per_step")
    L = t.wheel_travel[0]
    ends = sp.integrate_end(ds_r, ds_l, track)[:, 0, :]
    A = cv.propagate(t, k, k).covs[-1]
    C = np.cov(ends.T)
    out = {
        "speed_variance": float(wn.speed_variance(sources, speed)),
        "k_equivalent": k,
        "k_seed001_factor": 0.01 * float(wn.speed_variance(sources, speed)),
        "k_mc_travel": float(ds_r.sum(axis=1).var(ddof=1) / L),
        "n_samples": float(n),
    }
    for i, name in enumerate(("x", "y", "theta")):
        out[f"var_{name}_method_a"] = float(A[i, i])
        out[f"var_{name}_mc"] = float(C[i, i])
    return out


def regime_growth(
    trajectory: tr.Trajectory,
    k_r: float,
    k_l: float,
    n: int,
    seed: int,
    n_checkpoints: int = 10,
) -> dict[str, Any]:
    """Per-step (random) against per-run (systematic) errors: spreads against distance.

    Both regimes have the same total-travel variance at the end of the path
    (:mod:`pose_uncertainty.methods.sampling`); along the way the per-run spread grows
    faster. Spreads are Monte Carlo standard deviations along/across the
    nominal heading.

    Returns
    -------
    dict: ``distance`` (C,), per regime ``sigma_along``, ``sigma_across``,
    ``sigma_theta`` lists and ``fits`` (:func:`fit_growth` of each).
    """
    N = trajectory.n_steps
    steps = sorted({max(1, round(N * (i + 1) / n_checkpoints)) for i in range(n_checkpoints)})
    dist = np.concatenate([[0.0], np.cumsum(np.abs(trajectory.ds))])[steps]
    nominal = trajectory.poses[steps]
    out: dict[str, Any] = {"distance": dist.tolist()}
    for regime in ("per_step", "per_run"):
        clouds = sp.sample_end_poses(
            trajectory, k_r, k_l, n, np.random.default_rng(seed), regime=regime, checkpoints=steps
        )
        covs = np.stack([np.cov(clouds[:, i, :].T) for i in range(len(steps))])
        aa = path_spreads(nominal, covs)
        row: dict[str, Any] = {k: v.tolist() for k, v in aa.items() if k != "area"}
        row["fits"] = {k: fit_growth(dist, aa[k]) for k in ("sigma_along", "sigma_across", "sigma_theta")}
        out[regime] = row
    return out


# --- 4. polar against Cartesian -------------------------------------------------------------------


def _moments(v: NDArray) -> dict[str, float]:
    """Mean, sample std, and the moment estimates of skewness ``m3/m2^1.5`` and excess kurtosis
    ``m4/m2² − 3`` (``scipy.stats.skew``/``kurtosis`` with their default ``bias=True``)."""
    d = v - v.mean()
    m2, m3, m4 = (float(np.mean(d**k)) for k in (2, 3, 4))
    return {
        "mean": float(v.mean()),
        "std": float(v.std(ddof=1)),
        "skewness": m3 / m2**1.5,
        "excess_kurtosis": m4 / m2**2 - 3.0,
    }


def polar_vs_cartesian(samples: ArrayLike, origin: ArrayLike = (0.0, 0.0)) -> dict[str, Any]:
    """Moments of a cloud of end positions in Cartesian and in polar coordinates about ``origin``.

    Gaussianity of each view: ``coverage_98.89`` is the fraction of points
    inside the 98.89 % ellipse of the view's own mean and covariance (98.89 %
    for a Gaussian cloud); ``|skewness|`` and ``|excess kurtosis|`` near 0.

    Returns
    -------
    dict: ``cartesian`` {``x``, ``y``, ``coverage_98.89``}, ``polar`` {``r``, ``phi``, ``coverage_98.89``}
    """
    s = np.asarray(samples, dtype=float)
    o = np.asarray(origin, dtype=float)
    d = s[:, :2] - o
    r = np.hypot(d[:, 0], d[:, 1])
    phi = np.unwrap(np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(d[:, 1].mean(), d[:, 0].mean()))
    phi = (phi + np.pi) % (2 * np.pi) - np.pi + np.arctan2(d[:, 1].mean(), d[:, 0].mean())

    def cover(a: NDArray, b: NDArray) -> float:
        X = np.stack([a, b], -1)
        return ac.coverage_ellipse(X, X.mean(0), np.cov(X.T), (PR_3SIGMA,))["98.89"]

    return {
        "cartesian": {"x": _moments(s[:, 0]), "y": _moments(s[:, 1]),
                      "coverage_98.89": cover(s[:, 0], s[:, 1])},
        "polar": {"r": _moments(r), "phi": _moments(phi), "coverage_98.89": cover(r, phi)},
    }


# --- 5. growth laws -------------------------------------------------------------------------------


def growth_laws(
    trajectory: tr.Trajectory,
    k_r: float,
    k_l: float,
    n_points: int = 50,
    skip: float = 0.05,
    *,
    n_particles: int = 0,
    seed: int = 0,
    regime: str = "per_step",
) -> dict[str, Any]:
    """Fitted growth of the spreads with distance: Method A and (optionally) Monte Carlo.

    ``n_points`` poses evenly spaced in path length from ``skip`` of the path to
    its end; for each measure — σ_along, σ_across (in the frame of the nominal
    heading), σ_θ, and the area of the 98.89 % ellipse ``π k √det Σ_xy`` — a
    power law and an exponential are fitted (:func:`fit_growth`). With
    ``n_particles > 0`` the same measures of the Monte Carlo cloud (its sample
    covariance) are fitted too, and always those of Method C (the unscented
    transform, :func:`pose_uncertainty.methods.unscented.propagate`; along and
    across the nominal heading, as A's). (The exponential-coordinates Gaussian has
    the same second moments as Method A to first order, so it is not repeated.)

    Returns
    -------
    dict: ``distance`` list; ``method_a``, ``method_c`` and possibly ``monte_carlo``:
    {measure: values list, ``fits``: {measure: fit}}
    """
    A = cv.propagate(trajectory, k_r, k_l)
    C = ut.propagate(trajectory, k_r, k_l)
    dist = np.concatenate([[0.0], np.cumsum(np.abs(trajectory.ds))])
    targets = np.linspace(skip * dist[-1], dist[-1], check_positive_int("n_points", n_points))
    idx = np.unique(np.clip(np.searchsorted(dist, targets), 1, trajectory.n_steps))
    s = dist[idx]
    out: dict[str, Any] = {"distance": s.tolist()}
    measures = {"method_a": path_spreads(A.poses[idx], A.covs[idx]),
                "method_c": path_spreads(A.poses[idx], C.covs[idx])}  # frame of the nominal heading
    if n_particles > 0:
        clouds = sp.sample_end_poses(
            trajectory, k_r, k_l, n_particles, np.random.default_rng(seed), regime=regime,
            checkpoints=idx.tolist(),
        )
        covs = np.stack([np.cov(clouds[:, i, :].T) for i in range(idx.size)])
        measures["monte_carlo"] = path_spreads(trajectory.poses[idx], covs)
    for name, d in measures.items():
        out[name] = {k: v.tolist() for k, v in d.items()}
        out[name]["fits"] = {k: fit_growth(s, v) for k, v in d.items()}
    return out


# --- 6. probability maps against their own sampler ------------------------------------------------


def map_vs_sampler(
    model: str = "velocity",
    control: Sequence[float] = (1.0, 1.0),
    alphas: Sequence[float] | None = None,
    n: int = 100_000,
    seed: int = 0,
    size: float = 3.0,
    resolution: float = 0.02,
) -> dict[str, dict[str, float]]:
    """Single-step probability maps (thesis's and corrected) against the model's own sampler.

    The Monte Carlo truth is ``motion_models.sample_velocity`` (or
    ``sample_odometry``, with the odometry ``u`` the noiseless velocity motion)
    from (0, 0, 0) for ``Δt = 1``; the maps are
    ``maps.single_step_map(corrected=False)`` (Thrun's density, as the thesis)
    and ``corrected=True`` (the sampler's pose-space density), on a square
    grid of side ``size`` [m] centred on the noiseless end pose. Measures as
    :func:`pose_uncertainty.analysis.accuracy.evaluate_gridded`.

    Returns
    -------
    dict: ``thesis_map``, ``corrected_map`` → measures (plus ``lost_mass``)
    """
    check_choice("model", model, ("velocity", "odometry"))
    al = np.full(6 if model == "velocity" else 4, 0.05) if alphas is None else np.asarray(alphas)
    u = np.asarray(control, dtype=float)
    start = np.zeros(3)
    end = mm.noiseless_velocity_poses(start, u[None, :], 1.0)[-1]
    grid = Grid.centered(end, size=size, resolution=resolution)
    rng = np.random.default_rng(seed)
    if model == "velocity":
        samples = mm.sample_velocity(start, u, 1.0, al, n, rng)
    else:
        samples = mm.sample_odometry(start, start, end, al, n, rng)
    out = {}
    for name, corrected in (("thesis_map", False), ("corrected_map", True)):
        pm = maps.single_step_map(model, start, u, 1.0, al, grid=grid, corrected=corrected)
        res = ac.evaluate_gridded(pm, samples)
        res["lost_mass"] = float(pm.lost_mass)
        out[name] = res
    return out


# --- 7. accuracy on long paths --------------------------------------------------------------------


def accuracy_case(
    trajectory: dict[str, Any] | None = None,
    k: float = 5e-4,
    n: int = 100_000,
    seed: int = 2026,
    n_bins: int = 60,
    n_threshold: int = 200_000,
    label: str = "",
) -> dict[str, Any]:
    """Coverage, Hellinger, KL, log-likelihood and NEES of the three Gaussian methods on one path.

    ``n`` per-step Monte Carlo runs (midpoint integration, ``k_r = k_l = k`` [m])
    of ``trajectory`` (a :func:`pose_uncertainty.core.trajectories.from_config`
    mapping; default straight 1 m, dt 0.01 s, b 0.2 m) against Method A, the
    exponential-coordinates Gaussian and Method C (the unscented transform)
    (:func:`pose_uncertainty.analysis.accuracy.compare_methods`).

    Returns
    -------
    dict: ``case`` (the label), ``k``, ``length`` [m] and the entries of ``compare_methods``.
    """
    t = tr.from_config(trajectory or {"name": "straight", "length": 1.0, "dt": 0.01, "track": 0.2})
    rng = np.random.default_rng(seed)
    cloud = sp.sample_end_poses(t, k, k, n, rng)
    A = cv.propagate(t, k, k)
    E = ec.propagate(t, k, k)
    C = ut.propagate(t, k, k)
    res = ac.compare_methods(
        cloud, (A.poses[-1], A.covs[-1]), (E.poses[-1], E.covs[-1]), rng, n_bins=n_bins,
        n_threshold=n_threshold, unscented=(C.poses[-1], C.covs[-1]),
    )  # fmt: skip
    return {"case": label, "k": k, "length": t.length, **res}


# --- 8. calibration and coverage along a path -----------------------------------------------------


def calibration_demo(
    n: int = 20_000, seed: int = 11, k: float = 5e-4, track: float = 0.2, dt: float = 0.02,
    length: float = 1.0,
) -> dict[str, Any]:
    """Fit ``k`` back from Monte Carlo end poses of a straight line, with both models.

    ``n`` per-step Monte Carlo runs of a straight line of ``length`` [m] with
    true ``k_r = k_l = k`` [m]; :func:`pose_uncertainty.analysis.calibration.fit_k` with
    ``coords`` "expcoords" and "cartesian", each with one constant (``equal``)
    and with separate ``k_r, k_l``; 95 % profile-likelihood intervals.

    Returns
    -------
    dict: ``true_k``, ``n``, ``trajectory`` (its parameters) and ``rows`` — list
    of {``coords``, ``equal``, ``parameter``, ``estimate``, ``ci_low``,
    ``ci_high``, ``contains_true``, ``relative_bias``}
    """
    t = tr.straight(length, dt=dt, track=track)
    cloud = sp.sample_end_poses(t, k, k, n, np.random.default_rng(seed))
    rows = []
    for coords in ("expcoords", "cartesian"):
        for equal in (True, False):
            r = cb.fit_k(cloud, t, coords=coords, equal=equal)
            for name, est, lo, hi in zip(r.names, r.estimate, r.ci_low, r.ci_high, strict=True):
                rows.append({
                    "coords": coords, "equal": equal, "parameter": name, "estimate": est,
                    "ci_low": lo, "ci_high": hi, "level": r.level,
                    "contains_true": bool(lo <= k <= hi), "relative_bias": est / k - 1.0,
                })
    return {"true_k": k, "n": n, "seed": seed,
            "trajectory": {"name": "straight", "length": length, "dt": dt, "track": track},
            "rows": rows}


def coverage_vs_distance(
    trajectory: tr.Trajectory, k_r: float, k_l: float, n: int, seed: int, n_checkpoints: int = 5,
    n_threshold: int = 50_000,
) -> list[dict[str, Any]]:
    """Coverage of the Gaussian methods at checkpoints along a path (:func:`accuracy.accuracy_vs_distance`).

    Returns
    -------
    list of dict: ``distance`` [m], ``n``, ``coverage_se_98.89``, and per method
    (``cartesian``, ``expcoords``, ``unscented``) the (x, y) coverages at 50, 90, 98.89 % and
    the Hellinger distance, with the Monte Carlo ``hellinger_floor``.
    """
    rows = ac.accuracy_vs_distance(
        trajectory, k_r, k_l, n, np.random.default_rng(seed), n_checkpoints=n_checkpoints,
        n_threshold=n_threshold,
    )
    keep = ("coverage_xy_50", "coverage_xy_90", "coverage_xy_98.89", "hellinger")
    return [
        {"distance": r["distance"], "n": n,
         "coverage_se_98.89": r["monte_carlo"]["coverage_se_98.89"],
         "hellinger_floor": r["monte_carlo"]["hellinger_floor"],
         **{m: {key: r[m][key] for key in keep} for m in ("cartesian", "expcoords", "unscented")}}
        for r in rows
    ]


# --- 9. the figure of the exponential coordinates --------------------------------------------------


def expcoords_regions(
    cases: Sequence[dict[str, Any]] = (
        {"label": "straight 5 m", "trajectory": {"name": "straight", "length": 5.0}},
        {"label": "circle r = 1 m, 1 lap", "trajectory": {"name": "circle", "radius": 1.0, "laps": 1}},
    ),
    k: float = 5e-4,
    track: float = 0.2,
    dt: float = 0.01,
    pr: float = PR_3SIGMA,
    n: int = 5000,
    seed: int = 6,
) -> dict[str, Any]:
    """Monte Carlo clouds of long paths with the Gaussian methods' Pr regions, for the figure.

    Per case: ``n`` per-step Monte Carlo end positions (midpoint integration,
    ``k_r = k_l = k`` [m], seeded ``[seed, case index]``), the nominal path,
    Method A's Pr-ellipse (polyline), the boundary polygons of the
    exponential-coordinates Gaussian's planar Pr highest-density region
    (:func:`pose_uncertainty.methods.expcoords.pr_region_xy`), Method C's
    Pr-ellipse about its own mean, and the share of the cloud inside each region.

    Returns
    -------
    dict: ``k``, ``track``, ``pr``, ``n`` and ``cases`` — list of {``label``,
    ``cloud_xy`` (n, 2), ``path_xy`` (N+1, 2), ``end`` (3,), ``ellipse_xy`` (401, 2),
    ``banana_xy`` (list of (m, 2)), ``c_mean`` (3,), ``c_ellipse_xy`` (401, 2),
    ``inside_ellipse``, ``inside_banana``, ``inside_c``} (arrays as lists)
    """
    out: dict[str, Any] = {"k": k, "track": track, "pr": pr, "n": n, "cases": []}
    for j, case in enumerate(cases):
        t = tr.from_config({**dict(case["trajectory"]), "dt": dt, "track": track})
        rng = np.random.default_rng([seed, j])
        cloud = sp.sample_end_poses(t, k, k, n, rng)
        A, E, C = cv.propagate(t, k, k), ec.propagate(t, k, k), ut.propagate(t, k, k)
        end, cov = A.poses[-1], A.covs[-1]
        ellipse = cv.ellipse_polyline(cov[:2, :2], pr, end[:2], 400)
        c_mean, c_cov = C.poses[-1], C.covs[-1]
        banana = ec.pr_region_xy(E.poses[-1], E.covs[-1], pr, rng, n_grid=240, n=50_000)
        out["cases"].append({
            "label": str(case.get("label", j)),
            "cloud_xy": cloud[:, :2].tolist(), "path_xy": t.poses[:, :2].tolist(), "end": end.tolist(),
            "ellipse_xy": ellipse.tolist(), "banana_xy": [b.tolist() for b in banana],
            "inside_ellipse": ac.coverage_ellipse(cloud[:, :2], end[:2], cov[:2, :2], (pr,))[ac.pr_label(pr)],
            "inside_banana": _inside_polygons(cloud[:, :2], banana),
            "c_mean": c_mean.tolist(),
            "c_ellipse_xy": cv.ellipse_polyline(c_cov[:2, :2], pr, c_mean[:2], 400).tolist(),
            "inside_c": ac.coverage_ellipse(cloud[:, :2], c_mean[:2], c_cov[:2, :2], (pr,))[ac.pr_label(pr)],
        })  # fmt: skip
    return out


def _inside_polygons(xy: NDArray[np.float64], polygons: Sequence[NDArray[np.float64]]) -> float:
    """Share of points inside the union of closed polygons (even–odd rule: holes subtract)."""
    inside = np.zeros(xy.shape[0], dtype=bool)
    for poly in polygons:
        x0, y0 = poly[:, 0], poly[:, 1]
        x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
        px, py = xy[:, 0:1], xy[:, 1:2]
        crosses = (y0 > py) != (y1 > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
        inside ^= (np.count_nonzero(crosses & (px < x_at), axis=1) % 2) == 1
    return float(inside.mean())


# --- the studies as configured, logged jobs ------------------------------------------------------


def _method_cloud_spread(
    v_r: float = 1.0, v_l: float = 0.95, duration: float = 1.0, dt: float = 0.01, track: float = 0.1,
    k: float = 4.17e-6, n: int = 100_000, seed: int = 7,
) -> dict[str, Any]:
    """:func:`method_cloud_spread` on Šafránek 2022's constant-speed arc."""
    return method_cloud_spread(constant_speed_trajectory(v_r, v_l, duration, dt, track), k, k, n, seed)


def _number_type_clouds(
    v_r: float = 1.0, v_l: float = 1.0, duration: float = 1.0, dt: float = 0.01, track: float = 0.1,
    n: int = 1000, seed: int = 3, regime: str = "per_step", scheme: str = "seed001",
) -> dict[str, Any]:
    """:func:`number_type_clouds` with Šafránek 2022's error sources."""
    t = constant_speed_trajectory(v_r, v_l, duration, dt, track)
    return number_type_clouds(t, wn.SEED001, n, seed, regime=regime, scheme=scheme)


def _error_sources(
    speed: float = 1.0, duration: float = 1.0, dt: float = 0.01, track: float = 0.1,
    n: int = 100_000, seed: int = 1,
) -> dict[str, float]:
    """:func:`error_sources_vs_monte_carlo` with Šafránek 2022's error sources."""
    return error_sources_vs_monte_carlo(wn.SEED001, speed=speed, duration=duration, dt=dt, track=track,
                                        n=n, seed=seed)  # fmt: skip


_STRAIGHT_5M = {"name": "straight", "length": 5.0, "dt": 0.01, "track": 0.2}


def _regime_growth(
    trajectory: dict[str, Any] = _STRAIGHT_5M, k: float = 5e-4, n: int = 20_000, seed: int = 4,
    n_checkpoints: int = 10,
) -> dict[str, Any]:
    """:func:`regime_growth` along a configured trajectory."""
    return regime_growth(tr.from_config(trajectory), k, k, n, seed, n_checkpoints)


def _polar_vs_cartesian(
    trajectory: dict[str, Any] = {"name": "straight", "length": 1.0, "dt": 0.01, "track": 0.2},  # noqa: B006
    k: float = 5e-4, n: int = 100_000, seed: int = 5,
) -> dict[str, Any]:
    """:func:`polar_vs_cartesian` of a per-step Monte Carlo cloud of a configured trajectory."""
    t = tr.from_config(trajectory)
    return polar_vs_cartesian(sp.sample_end_poses(t, k, k, n, np.random.default_rng(seed)), t.start[:2])


def _growth_laws(
    trajectory: dict[str, Any] = {"name": "straight", "length": 20.0, "dt": 0.01, "track": 0.2},  # noqa: B006
    k: float = 5e-4, n_points: int = 20, n_particles: int = 20_000, seed: int = 0,
    regime: str = "per_step",
) -> dict[str, Any]:
    """The fits of :func:`growth_laws` along a configured trajectory."""
    g = growth_laws(tr.from_config(trajectory), k, k, n_points, n_particles=n_particles, seed=seed,
                    regime=regime)  # fmt: skip
    return {m: g[m]["fits"] for m in ("method_a", "method_c", "monte_carlo") if m in g}


def _accuracy_vs_distance(
    trajectory: dict[str, Any] = {"name": "straight", "length": 20.0, "dt": 0.01, "track": 0.2},  # noqa: B006
    k: float = 5e-4, n: int = 10_000, seed: int = 12, n_checkpoints: int = 5, n_threshold: int = 50_000,
) -> list[dict[str, Any]]:
    """:func:`coverage_vs_distance` along a configured trajectory (``n_threshold`` draws for the
    banana's density thresholds: probability error ``√(Pr(1−Pr)/n_threshold)``, 0.0005 at 98.89 %)."""
    return coverage_vs_distance(tr.from_config(trajectory), k, k, n, seed, n_checkpoints, n_threshold)


#: Every study a config can run, by kind: a function of JSON-like keyword parameters (each with
#: its default, the thesis's setting) returning JSON-like results.
STUDIES: dict[str, Any] = {
    "integration_vs_step": integration_vs_step,
    "method_cloud_spread": _method_cloud_spread,
    "number_type_drift": number_type_drift,
    "number_type_clouds": _number_type_clouds,
    "error_sources": _error_sources,
    "regime_growth": _regime_growth,
    "polar_vs_cartesian": _polar_vs_cartesian,
    "growth_laws": _growth_laws,
    "map_vs_sampler": map_vs_sampler,
    "accuracy_case": accuracy_case,
    "calibration_demo": calibration_demo,
    "accuracy_vs_distance": _accuracy_vs_distance,
    "expcoords_regions": expcoords_regions,
    "umbmark": um.umbmark_experiment,  # systematic errors, UMBmark before/after correction
}


def summarize(results: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """The studies section's data: every study's results by name and the numbers the text quotes.

    Parameters
    ----------
    results : mapping name → ``{"study": kind, "results": ...}`` — the logged studies, in
        config order

    Returns
    -------
    dict: ``studies`` — results by name, plus ``accuracy_table`` (the ``accuracy_case``
    studies' results in order); ``summary`` — (each only when its study is present):
    ``accuracy`` — Method A's worst 98.89 % coverage and its case, the banana's range, the
    rows by case; ``distance`` — first and last rows of the coverage along a path;
    ``growth`` — in how many fits the power law has the smaller rms log residual, and the
    median residuals; ``calibration`` — the equal-k row of each model; ``umbmark`` — the
    first UMBmark study's name, E_max before and after the correction, their ratio and
    which delta intervals hold the true values.
    """
    studies: dict[str, Any] = {name: r["results"] for name, r in results.items()}
    table = [r["results"] for r in results.values() if r["study"] == "accuracy_case"]
    if table:
        studies["accuracy_table"] = table
    out: dict[str, Any] = {}
    if table:
        out["accuracy"] = _accuracy_summary(table)
    dist = next((r["results"] for r in results.values() if r["study"] == "accuracy_vs_distance"), None)
    if dist:
        out["distance"] = {"first": dist[0], "last": dist[-1]}
    fits = [f for r in results.values() if r["study"] == "growth_laws"
            for method in r["results"].values() for f in method.values()]  # fmt: skip
    if fits:
        power = [f["power_rms_log_residual"] for f in fits]
        expo = [f["exp_rms_log_residual"] for f in fits]
        out["growth"] = {
            "n_power_better": int(sum(a < b for a, b in zip(power, expo, strict=True))),
            "median_power_residual": float(np.median(power)),
            "median_exp_residual": float(np.median(expo)),
            "n_fits": len(fits),
        }
    cal = next((r["results"] for r in results.values() if r["study"] == "calibration_demo"), None)
    if cal:
        out["calibration"] = {r["coords"]: r for r in cal["rows"] if r["equal"]}
    umb = next((name for name, r in results.items() if r["study"] == "umbmark"), None)
    if umb:
        out["umbmark"] = _umbmark_summary(umb, results[umb]["results"])
    return {"studies": studies, "summary": out}


def _umbmark_summary(name: str, res: Mapping[str, Any]) -> dict[str, Any]:
    """The UMBmark study's headline numbers: E_max before/after and how many intervals hold the truth."""
    est = res["umbmark"]["estimates"]
    before, after = est["E_max_before"]["value"], res["umbmark"]["E_max_after_measured"]["value"]
    rows = {r["quantity"]: r for r in res["recovered"]}
    return {
        "study": name, "E_max_before": before, "E_max_after": after, "improvement": before / after,
        "n_covered": sum(r["delta_covers"] for r in res["recovered"]), "n_quantities": len(rows),
        "umbmark_covers": {q: rows[q]["delta_covers"] for q in ("E_d", "E_b") if q in rows},
        "fit_covers": {q: rows[q]["delta_covers"] for q in ("E_d_fit", "E_b_fit") if q in rows},
    }  # fmt: skip


def _accuracy_summary(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    key = "coverage_xy_98.89"
    worst = min(rows, key=lambda r: r["cartesian"][key])
    ban = [r["expcoords"][key] for r in rows if "expcoords" in r]
    c_rows = [r for r in rows if "unscented" in r]  # Method C
    worst_c = min(c_rows, key=lambda r: r["unscented"][key]) if c_rows else None
    return {
        "worst_a": worst["cartesian"][key], "worst_case": worst["case"],
        "best_a": max(r["cartesian"][key] for r in rows),
        "banana_min": min(ban) if ban else None, "banana_max": max(ban) if ban else None,
        "worst_c": worst_c["unscented"][key] if worst_c else None,
        "worst_c_case": worst_c["case"] if worst_c else None,
        "best_c": max(r["unscented"][key] for r in c_rows) if c_rows else None,
        "n_cases": len(rows), "by_case": {r["case"]: r for r in rows},
    }  # fmt: skip
