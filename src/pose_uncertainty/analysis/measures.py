"""Every per-run measure the tables, claims, figures and report use, with its unit and definition.

A run computes these once, where it executes (:func:`pose_uncertainty.experiments.run.execute`),
and logs them; everything downstream reads them back. Names:

* run — ``path_length``, ``duration``, ``end_x``, ``end_y``, ``end_theta``;
* ``A_*`` — Method A's Gaussian at the end of the path (:func:`gaussian_measures`);
* ``MC_*`` — the Monte Carlo end-pose cloud against Method A (:func:`cloud_measures`);
* ``map_<name>_*`` — a probability map and its model's own sampler (:func:`map_measures`);
* ``accuracy_<method>_*`` — how far each Gaussian method is from the run's
  Monte Carlo (:func:`pose_uncertainty.analysis.accuracy.compare_methods`);
* ``C_*`` — Method C, the unscented transform, at the end of the path
  (:func:`unscented_measures`): as ``A_*``, plus its mean, its covariance and the mean's
  shift from the nominal end; ``MC_mean_shift_*``, ``MC_mean_offset_C`` — where the Monte
  Carlo mean lies (:func:`cloud_shift_measures`); ``accuracy_unscented_*`` — Method C against
  the Monte Carlo cloud. The UT on SE(2) (:func:`pose_uncertainty.methods.unscented.propagate_se2`)
  is not logged: its covariance is the exponential-coordinates Gaussian's (the banana's,
  ``accuracy_expcoords_*``) to a relative 4·10⁻¹¹ on a 64 m line and 1.6·10⁻⁹ on eight laps of
  the 1 m circle (k = 5·10⁻⁴ m, b = 0.2 m), at twice Method C's cost;
* runs with a ``drive`` section only (:mod:`pose_uncertainty.experiments.drive_run`):
  ``A_growth_*``, ``MC_growth_*`` — power-law exponents of the spreads against
  path length (:func:`pose_uncertainty.analysis.drive_growth.growth_measures`), and for a
  skid-steer drive ``drive_plain_odometry_*`` — the bias of plain differential
  odometry (:func:`pose_uncertainty.analysis.drive_growth.plain_odometry_measures`);
* ``loc_*`` — a localization run and its filters (registry and functions in
  :mod:`pose_uncertainty.analysis.localization`).

:func:`describe` gives the unit and definition of any of these names; a name it
does not know raises ``KeyError`` (a run cannot log an undefined number).

Conventions: distances in m, angles in rad, areas in m². "Along" and "across"
are the frame of the *nominal* end heading (:func:`pose_uncertainty.core.stats.along_across`).
The reference point of every distance on a map is the map's recorded centre, the
noiseless exact-arc end pose. Probability levels are those of
:mod:`pose_uncertainty.core.stats` (39.35 / 86.47 / 98.89 %).
"""

from __future__ import annotations

import functools
import math
import re

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.grids import Grid
from ..core.stats import (
    COVERAGE_LEVELS,
    along_across,
    fraction_inside_ellipse,
    hellinger,
    hellinger_noise_floor,
)
from ..core.validation import check_last_axis
from ..methods.covariance import ellipse
from ..methods.maps import ProbabilityMap
from .localization import DEFINITIONS as _LOCALIZATION_DEFINITIONS

__all__ = [
    "cloud_measures",
    "cloud_shift_measures",
    "describe",
    "gaussian_measures",
    "map_measures",
    "run_measures",
    "unscented_measures",
]

#: Kolmogorov distance at the 5 % level is about this over √n.
KS_CRIT_5PCT: float = 1.358

# (pattern, unit, definition); the first match wins. ``{1}``… are the pattern's groups.
_DEFINITIONS: tuple[tuple[str, str, str], ...] = (
    (r"path_length", "m", "length of the nominal path, Σ|Δs|"),
    (r"duration", "s", "duration of the run, N·Δt"),
    (r"end_(x|y)", "m", "nominal end {1} (Method A's mean, midpoint integration)"),
    (r"end_theta", "rad", "nominal end heading (Method A's mean, unwrapped)"),
    (r"A_sigma_(x|y)", "m", "Method A's standard deviation of {1} at the end"),
    (r"A_sigma_theta", "rad", "Method A's standard deviation of the heading at the end"),
    (r"A_sigma_(along|across)", "m",
     "Method A's standard deviation {1} the path (frame of the nominal end heading)"),
    (r"A_ellipse_(major|minor)", "m", "{1} semi-axis of Method A's Pr-ellipse at the run's Pr"),
    (r"A_ellipse_angle", "rad", "direction of the major axis of Method A's Pr-ellipse from the x axis"),
    (r"A_ellipse_area", "m^2", "area π·a·b of Method A's Pr-ellipse at the run's Pr"),
    (r"A_bend_ratio", "1",
     ("ρ = σ_θ·a/(2b): how far the heading error bends the cloud out of the ellipse, in short "
     "semi-axes (a, b the Pr-ellipse's semi-axes; the ellipse is trustworthy for ρ ≪ 1)")),
    (r"MC_n", "1", "number of Monte Carlo end poses"),
    (r"MC_sigma_(along|across)", "m",
     ("sample standard deviation of the Monte Carlo end positions {1} the path (frame of the "
     "nominal end heading)")),
    (r"MC_sigma_theta", "rad", "sample standard deviation of the Monte Carlo end headings"),
    (r"MC_ellipse_(major|minor)", "m",
     "{1} semi-axis of the Pr-ellipse of the Monte Carlo sample covariance"),
    (r"MC_ellipse_area", "m^2", "area of the Pr-ellipse of the Monte Carlo sample covariance"),
    (r"MC_coverage_(1s|2s|3s)", "1",
     ("fraction of Monte Carlo end positions inside Method A's ellipse of radius {1} "
     "(probability 39.35 / 86.47 / 98.89 % for 1s / 2s / 3s)")),
    (r"MC_coverage_pr", "1", "fraction of Monte Carlo end positions inside Method A's Pr-ellipse"),
    (r"MC_mean_offset", "m", "distance of the Monte Carlo mean position from the nominal end"),
    (r"MC_mean_(x|y)", "m", "sample mean of the Monte Carlo end {1}"),
    (r"MC_cov_(xx|xy|yy)", "m^2", "sample covariance ({1}) of the Monte Carlo end positions"),
    (r"MC_cov_rel_error", "1", "‖Σ_MC − Σ_A‖_F / ‖Σ_A‖_F of the (x, y) covariances"),
    (r"MC_ks_gauss", "1",
     ("Kolmogorov distance of the squared Mahalanobis radii (w.r.t. the sample's own mean and "
     "covariance) from χ²₂: 0 for a Gaussian cloud")),
    (r"MC_ks_crit", "1", "5 % critical value of MC_ks_gauss, 1.358/√n"),
    (r"MC_bend", "1",
     ("correlation of the along-track residual with the squared across-track residual: 0 for an "
     "ellipse, nonzero for a banana")),
    (r"MC_bend_crit", "1", "noise level of MC_bend, 2/√n"),
    (r"map_(.+)_peak_(x|y)", "m", "{2} of the most probable (x, y) cell of map {1}"),
    (r"map_(.+)_peak_offset", "m",
     ("distance of map {1}'s most probable (x, y) cell from the map's centre (the noiseless "
     "exact-arc end pose)")),
    (r"map_(.+)_peak_angle", "rad",
     "direction of map {1}'s most probable cell seen from the map's centre"),
    (r"map_(.+)_mean_offset", "m", "distance of map {1}'s mean position from the map's centre"),
    (r"map_(.+)_sigma_(along|across)", "m",
     "standard deviation of map {1}'s on-grid mass {2} the path (frame of the centre heading)"),
    (r"map_(.+)_region_area", "m^2",
     ("area of map {1}'s planar highest-density region holding the run's Pr of the whole "
     "distribution (nan when the grid holds less)")),
    (r"map_(.+)_lost_mass", "1", "probability mass of map {1} off its grid"),
    (r"map_(.+)_mass_on_grid", "1", "probability mass of map {1} on its grid"),
    (r"map_(.+)_sampler_n", "1", "number of draws of map {1}'s motion-model sampler"),
    (r"map_(.+)_sampler_inside", "1", "fraction of map {1}'s sampler draws on the map's grid"),
    (r"map_(.+)_hellinger_sampler", "1",
     ("Hellinger distance between map {1}'s (x, y) cell masses and the histogram of its own "
     "sampler's draws on the same cells")),
    (r"map_(.+)_hellinger_floor", "1",
     ("expected Hellinger distance of a histogram of as many exact draws from map {1}: the "
     "sampling floor of map_{1}_hellinger_sampler")),
    (r"accuracy_grid_(nx|ny)", "1", "cells per axis of the stated grid of the accuracy comparison"),
    (r"accuracy_grid_(dx|dy|x_min|x_max|y_min|y_max)", "m",
     "{1} of the stated grid of the accuracy comparison"),
    (r"accuracy_grid_n_samples", "1", "Monte Carlo end poses in the accuracy comparison"),
    (r"accuracy_monte_carlo_(hellinger|kl)_floor", "1",
     "{1} of Method A's Gaussian to a histogram of as many of its own draws: the sampling floor"),
    (r"accuracy_monte_carlo_coverage_se_(.+)", "1",
     "binomial standard error √(Pr(1−Pr)/n) of a coverage at Pr = {1} %"),
    (r"accuracy_(cartesian|expcoords)_coverage_xy_(.+)", "1",
     ("fraction of Monte Carlo end positions inside the {1} Gaussian's planar {2} % "
     "highest-density region")),
    (r"accuracy_(cartesian|expcoords)_coverage_pose_(.+)", "1",
     ("fraction of Monte Carlo end poses inside the {1} Gaussian's {2} % ellipsoid in its own "
     "coordinates")),
    (r"accuracy_(cartesian|expcoords)_hellinger", "1",
     ("Hellinger distance of the {1} Gaussian's cell probabilities from the Monte Carlo histogram "
     "on the stated grid")),
    (r"accuracy_(cartesian|expcoords)_kl", "nat",
     "KL(Monte Carlo ‖ {1} Gaussian) on the stated grid"),
    (r"accuracy_(cartesian|expcoords)_model_mass_on_grid", "1",
     "probability of the {1} Gaussian on the stated grid"),
    (r"accuracy_(cartesian|expcoords)_loglik_(pose|xy)", "nat",
     "mean log-likelihood of the Monte Carlo end {2}s under the {1} Gaussian"),
    (r"accuracy_(cartesian|expcoords)_nees_(pose|xy)", "1",
     "mean normalised estimation error squared of the {1} Gaussian ({2}; 3 or 2 if consistent)"),
    # --- runs with a drive section (pose_uncertainty.experiments.drive_run) -------------
    (r"A_growth_(sigma_along|sigma_across|sigma_theta)", "1",
     ("exponent p of the power law {1} ∝ s^p fitted (least squares, log-log) to Method A's {1} against "
     "the path length s at the growth points: the Monte Carlo checkpoints and the end, or without "
     "two checkpoints 20 poses evenly spaced from 5 % of the path to its end")),
    (r"MC_growth_(sigma_along|sigma_across|sigma_theta)", "1",
     ("exponent p of the power law {1} ∝ s^p fitted (least squares, log-log) to the Monte Carlo "
     "clouds' {1} (sample covariance, frame of the nominal heading) at the checkpoints and the end")),
    (r"(A|MC)_growth_(sigma_along|sigma_across|sigma_theta)_residual", "1",
     "rms residual of ln σ of the power law fitted in {1}_growth_{2}"),
    (r"drive_plain_odometry_position_error", "m",
     ("distance of the end position that plain differential odometry (χ = 1, x_ICR = 0) reports from "
     "the skid-steer drive's true (ICR-model) end position, on the nominal track travels")),
    (r"drive_plain_odometry_heading_error", "rad",
     "end heading reported by plain differential odometry minus the skid-steer drive's true end heading"),
    (r"drive_plain_odometry_max_heading_error", "rad",
     "largest |heading error| of plain differential odometry on a skid-steer drive along the path"),
    (r"drive_plain_odometry_mahalanobis", "1",
     ("Mahalanobis distance of plain odometry's end position from the true one under Method A's "
     "(x, y) covariance at the end: its bias in standard deviations of the uncertainty (3 at 98.89 %)")),
)

# --- Method C, the unscented transform: C_*, the mean shifts, accuracy_unscented_* --------------
_METHOD_C_DEFINITIONS: tuple[tuple[str, str, str], ...] = (
    (r"C_sigma_(x|y)", "m", "Method C's (the unscented transform's) standard deviation of {1} at the end"),
    (r"C_sigma_theta", "rad", "Method C's standard deviation of the heading at the end"),
    (r"C_sigma_(along|across)", "m",
     "Method C's standard deviation {1} the path (frame of the nominal end heading)"),
    (r"C_ellipse_(major|minor)", "m",
     "{1} semi-axis of Method C's Pr-ellipse at the run's Pr (centred on C's mean)"),
    (r"C_ellipse_angle", "rad", "direction of the major axis of Method C's Pr-ellipse from the x axis"),
    (r"C_ellipse_area", "m^2", "area π·a·b of Method C's Pr-ellipse at the run's Pr"),
    (r"C_bend_ratio", "1", "ρ = σ_θ·a/(2b) of Method C's Gaussian (as A_bend_ratio)"),
    (r"C_mean_(x|y)", "m", "{1} of Method C's mean end pose (the unscented transform's mean)"),
    (r"C_mean_theta", "rad", "Method C's mean end heading (circular mean, unwrapped)"),
    (r"C_cov_(xx|xy|yy)", "m^2", "Method C's covariance ({1}) of the end position"),
    (r"C_mean_offset", "m", "distance of Method C's mean position from the nominal end (Method A's mean)"),
    (r"C_mean_shift_(along|across)", "m",
     ("Method C's mean position minus the nominal end (Method A's mean), {1} the path (frame of "
      "the nominal end heading; across > 0 to the left)")),
    (r"MC_mean_shift_(along|across)", "m",
     ("the Monte Carlo mean position minus the nominal end (Method A's mean), {1} the path (frame "
      "of the nominal end heading; across > 0 to the left)")),
    (r"MC_mean_offset_C", "m", "distance of the Monte Carlo mean position from Method C's mean"),
    (r"accuracy_unscented_coverage_xy_(.+)", "1",
     "fraction of Monte Carlo end positions inside Method C's planar {1} % ellipse (about C's mean)"),
    (r"accuracy_unscented_coverage_pose_(.+)", "1",
     "fraction of Monte Carlo end poses inside Method C's {1} % ellipsoid in (x, y, θ)"),
    (r"accuracy_unscented_hellinger", "1",
     ("Hellinger distance of Method C's Gaussian's cell probabilities from the Monte Carlo histogram "
      "on the stated grid")),
    (r"accuracy_unscented_kl", "nat", "KL(Monte Carlo ‖ Method C's Gaussian) on the stated grid"),
    (r"accuracy_unscented_model_mass_on_grid", "1", "probability of Method C's Gaussian on the stated grid"),
    (r"accuracy_unscented_loglik_(pose|xy)", "nat",
     "mean log-likelihood of the Monte Carlo end {1}s under Method C's Gaussian"),
    (r"accuracy_unscented_nees_(pose|xy)", "1",
     "mean normalised estimation error squared of Method C's Gaussian ({1}; 3 or 2 if consistent)"),
)
# --- end Method C ---

# the localization runs' measures (loc_*) live in their own registry, consulted here too
_COMPILED = tuple(
    (re.compile(p + r"\Z"), u, d)
    for p, u, d in (*_DEFINITIONS, *_METHOD_C_DEFINITIONS, *_LOCALIZATION_DEFINITIONS)
)


@functools.lru_cache(maxsize=4096)
def describe(name: str) -> tuple[str, str]:
    """``(unit, definition)`` of a logged measure; ``KeyError`` for an unknown name (remembered
    per name: a run describes each of its ~100 measures, and the next run the same ones)."""
    for pattern, unit, definition in _COMPILED:
        m = pattern.match(name)
        if m:
            return unit, definition.format(None, *m.groups())
    raise KeyError(f"no definition for the measure {name!r}")


def _put(out: dict[str, float], **values: float) -> None:
    out.update({k: float(v) for k, v in values.items()})


def gaussian_measures(pose: ArrayLike, cov: ArrayLike, pr: float) -> dict[str, float]:
    """Method A's measures at one pose: σ's, σ along/across, Pr-ellipse and bend ratio (``A_*``)."""
    p = check_last_axis("pose", pose, 3)
    C = np.asarray(cov, dtype=np.float64)
    out: dict[str, float] = {}
    sd = np.sqrt(np.maximum(np.diag(C), 0.0))
    al, ac = along_across(C[:2, :2], p[2])
    alpha, a, b = (float(v) for v in ellipse(C[:2, :2], pr))
    _put(out, A_sigma_x=sd[0], A_sigma_y=sd[1], A_sigma_theta=sd[2], A_sigma_along=al,
         A_sigma_across=ac, A_ellipse_major=a, A_ellipse_minor=b, A_ellipse_angle=alpha,
         A_ellipse_area=math.pi * a * b,
         A_bend_ratio=sd[2] * a / (2.0 * b) if b > 0 else math.inf)  # fmt: skip
    return out


def _ks_gauss(xy: NDArray[np.float64], mean: NDArray, cov: NDArray) -> float:
    """Kolmogorov distance of squared Mahalanobis radii from χ²₂ (CDF 1 − e^{−d²/2})."""
    d = xy - mean
    d2 = np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov), d)
    u = np.sort(-np.expm1(-d2 / 2.0))
    n = u.size
    grid = np.arange(1, n + 1) / n
    return float(max(np.max(grid - u), np.max(u - (grid - 1.0 / n))))


def cloud_measures(
    cloud: ArrayLike, pose: ArrayLike, cov: ArrayLike, pr: float
) -> dict[str, float]:
    """The Monte Carlo cloud's measures against Method A's Gaussian ``(pose, cov)`` (``MC_*``).

    Parameters
    ----------
    cloud : array_like, shape (n, 3), n ≥ 3 — end poses (unwrapped headings)
    pose : array_like, shape (3,) — nominal end pose; cov : array_like, shape (3, 3) — Method A's Σ
    pr : float — the run's probability level
    """
    s = check_last_axis("cloud", cloud, 3)
    if s.ndim != 2 or s.shape[0] < 3:
        raise ValueError(f"cloud must have shape (n, 3) with n >= 3, got shape {s.shape}")
    p, C = check_last_axis("pose", pose, 3), np.asarray(cov, dtype=np.float64)
    n = s.shape[0]
    mean = s.mean(axis=0)
    c, sn = math.cos(p[2]), math.sin(p[2])
    d = (s[:, :2] - mean[:2]) @ np.array([[c, -sn], [sn, c]])  # columns: along, across
    dth = np.angle(np.exp(1j * (s[:, 2] - p[2])))
    cmc = np.cov(s[:, :2].T)
    _, ma, mb = (float(v) for v in ellipse(cmc, pr))
    out: dict[str, float] = {}
    _put(out, MC_n=n, MC_sigma_along=d[:, 0].std(ddof=1), MC_sigma_across=d[:, 1].std(ddof=1),
         MC_sigma_theta=dth.std(ddof=1), MC_ellipse_major=ma, MC_ellipse_minor=mb,
         MC_ellipse_area=math.pi * ma * mb,
         MC_mean_offset=math.hypot(mean[0] - p[0], mean[1] - p[1]), MC_mean_x=mean[0], MC_mean_y=mean[1],
         MC_cov_xx=cmc[0, 0], MC_cov_xy=cmc[0, 1], MC_cov_yy=cmc[1, 1])  # fmt: skip
    for key, level in COVERAGE_LEVELS.items():
        out[f"MC_coverage_{key}"] = fraction_inside_ellipse(s[:, :2], p[:2], C[:2, :2], level)
    out["MC_coverage_pr"] = fraction_inside_ellipse(s[:, :2], p[:2], C[:2, :2], pr)
    norm = float(np.linalg.norm(C[:2, :2]))
    out["MC_cov_rel_error"] = float(np.linalg.norm(cmc - C[:2, :2]) / norm) if norm > 0 else math.nan
    if np.linalg.det(cmc) > 0:
        _put(out, MC_ks_gauss=_ks_gauss(s[:, :2], mean[:2], cmc), MC_ks_crit=KS_CRIT_5PCT / math.sqrt(n))
    a2 = d[:, 1] ** 2
    if d[:, 0].std() > 0 and a2.std() > 0:
        _put(out, MC_bend=np.corrcoef(d[:, 0], a2)[0, 1], MC_bend_crit=2.0 / math.sqrt(n))
    return out


def _map_shape(mp: ProbabilityMap, mass: NDArray[np.float64]) -> dict[str, float]:
    """Peak, mean and spread of a map's planar mass, from its recorded centre."""
    center = mp.center
    i, j = np.unravel_index(int(np.argmax(mass)), mass.shape)
    px, py = float(mp.x[i]), float(mp.y[j])
    out = {"peak_x": px, "peak_y": py,
           "peak_offset": math.hypot(px - center[0], py - center[1]),
           "peak_angle": math.atan2(py - center[1], px - center[0])}  # fmt: skip
    total = float(mass.sum())
    if total > 0:
        w = mass / total
        wx, wy = w.sum(axis=1), w.sum(axis=0)
        mx, my = float(wx @ mp.x), float(wy @ mp.y)
        X, Y = mp.x[:, None] - mx, mp.y[None, :] - my
        cxx, cyy, cxy = float((w * X * X).sum()), float((w * Y * Y).sum()), float((w * X * Y).sum())
        al, ac = along_across(np.array([[cxx, cxy], [cxy, cyy]]), center[2])
        out.update(sigma_along=float(al), sigma_across=float(ac),
                   mean_offset=math.hypot(mx - center[0], my - center[1]))  # fmt: skip
    return out


def map_measures(
    mp: ProbabilityMap, pr: float, sampler: ArrayLike | None = None
) -> dict[str, float]:
    """A map's measures (``map_<name>_*``): shape about its centre, Pr-region, and its sampler.

    Parameters
    ----------
    mp : ProbabilityMap — with ``name`` and ``center`` (the noiseless end pose)
    pr : float — the run's probability level
    sampler : array_like, shape (n, 3), optional — draws of the map's motion model along the
        same controls (the map's Monte Carlo truth); gives the Hellinger distance to the map
        and its sampling floor
    """
    mass = mp.marginal_xy()
    out = _map_shape(mp, mass)
    out.update(lost_mass=mp.lost_mass, mass_on_grid=float(mass.sum()),
               region_area=mp.region_xy(pr)[1])  # fmt: skip
    s = None if sampler is None else check_last_axis("sampler", sampler, 3).reshape(-1, 3)
    if s is not None and s.shape[0] > 0 and mp.x.size > 1 and mp.y.size > 1:
        hist = _grid_of(mp).histogram_xy(s)
        out.update(sampler_n=float(s.shape[0]), sampler_inside=float(hist.sum()))
        if hist.sum() > 0:
            out.update(hellinger_sampler=hellinger(mass, hist),
                       hellinger_floor=hellinger_noise_floor(mass, s.shape[0]))  # fmt: skip
    return {f"map_{mp.name}_{k}": float(v) for k, v in out.items()}


def _grid_of(mp: ProbabilityMap) -> Grid:
    """The planar grid of a map's cell centres (the same for a computed and a logged map)."""
    return Grid(float(mp.x[0]), float(mp.y[0]), mp.x.size, mp.y.size,
                float(mp.x[1] - mp.x[0]), float(mp.y[1] - mp.y[0]))  # fmt: skip


def run_measures(path_length: float, duration: float, end: ArrayLike) -> dict[str, float]:
    """The run's own numbers: ``path_length`` [m], ``duration`` [s], nominal end pose."""
    e = check_last_axis("end", end, 3)
    out: dict[str, float] = {}
    _put(out, path_length=path_length, duration=duration, end_x=e[0], end_y=e[1], end_theta=e[2])
    return out


# --- Method C, the unscented transform ---------------------------------------------------------


def _shift(point: NDArray[np.float64], nominal: NDArray[np.float64]) -> tuple[float, float]:
    """``point − nominal`` (planar) along and across the nominal heading ``nominal[2]`` [m]."""
    dx, dy = float(point[0] - nominal[0]), float(point[1] - nominal[1])
    c, s = math.cos(nominal[2]), math.sin(nominal[2])
    return c * dx + s * dy, -s * dx + c * dy


def unscented_measures(mean: ArrayLike, cov: ArrayLike, nominal: ArrayLike, pr: float) -> dict[str, float]:
    """Method C's measures at the end (``C_*``): those of :func:`gaussian_measures`, its mean and its shift.

    Method C's mean is not the nominal pose: heading noise pulls it back along a
    line and inwards on an arc. Its σ along/across use the frame of the nominal end
    heading, as Method A's and the Monte Carlo's.

    Parameters
    ----------
    mean : array_like, shape (3,) — C's mean end pose [m, m, rad]
    cov : array_like, shape (3, 3) — C's covariance
    nominal : array_like, shape (3,) — the nominal end pose (Method A's mean)
    pr : float — the run's probability level
    """
    m = check_last_axis("mean", mean, 3)
    n = check_last_axis("nominal", nominal, 3)
    C = np.asarray(cov, dtype=np.float64)
    out = {"C" + k[1:]: v for k, v in gaussian_measures((m[0], m[1], n[2]), C, pr).items()}
    along, across = _shift(m, n)
    _put(out, C_mean_x=m[0], C_mean_y=m[1], C_mean_theta=m[2], C_cov_xx=C[0, 0], C_cov_xy=C[0, 1],
         C_cov_yy=C[1, 1], C_mean_offset=math.hypot(along, across), C_mean_shift_along=along,
         C_mean_shift_across=across)  # fmt: skip
    return out


def cloud_shift_measures(
    cloud: ArrayLike, nominal: ArrayLike, c_mean: ArrayLike | None = None
) -> dict[str, float]:
    """Where the Monte Carlo mean lies: its shift along/across from the nominal end, its distance from C's mean.

    Parameters
    ----------
    cloud : array_like, shape (n, 3), n ≥ 1 — end poses
    nominal : array_like, shape (3,) — the nominal end pose
    c_mean : array_like, shape (3,), optional — Method C's mean (``MC_mean_offset_C`` only with it)
    """
    s = check_last_axis("cloud", cloud, 3).reshape(-1, 3)
    if s.shape[0] < 1:
        raise ValueError(f"cloud must hold at least one pose, got shape {s.shape}")
    n = check_last_axis("nominal", nominal, 3)
    mean = s.mean(axis=0)
    along, across = _shift(mean, n)
    out: dict[str, float] = {}
    _put(out, MC_mean_shift_along=along, MC_mean_shift_across=across)
    if c_mean is not None:
        c = check_last_axis("c_mean", c_mean, 3)
        out["MC_mean_offset_C"] = math.hypot(mean[0] - c[0], mean[1] - c[1])
    return out


# --- end Method C ---
