"""Absolute sensing (Skalka 2011 §4.1, §4.3) in the three filters: what each sensor fixes, and how consistently.

:func:`absolute_sensing_study` puts a robot at a known true pose with a broad Gaussian prior (its mean
drawn from the prior itself, so that a consistent filter's NEES averages 3) and corrects it with
``n_measurements`` measurements of one absolute sensor
(:mod:`pose_uncertainty.localization.absolute_sensors`), in each filter:

* ``ekf`` — :func:`~pose_uncertainty.localization.absolute_sensors.ekf_update_absolute`, one measurement
  after the other (the GNSS with a χ² gate at 99 %, which rejects outliers);
* ``histogram`` — the prior's density on a pose grid about the prior's mean (±4σ), times every measurement's
  likelihood (:func:`~pose_uncertainty.localization.absolute_sensors.grid_log_likelihood`,
  :func:`~pose_uncertainty.localization.histogram.hf_correct`);
* ``particle`` — particles drawn from the prior, weighted by every measurement's likelihood.

The sensors: ranges to three beacons (trilateration), bearings to the same beacons (triangulation), a
GNSS-like position with a systematic offset and 5 % outliers, and a compass with a heading bias and a
local magnetic disturbance at the robot. The measurements come from the true model; the filters use it
without the offset, the bias and the disturbance (a user who does not know them), which is what their NEES
then shows. Measures per sensor and filter: the posterior σ of x, y and θ (RMS over the trials) against
the prior's, which components the sensor fixes (posterior σ below half the prior's), the RMS errors and
the mean NEES.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...core.grids import Grid
from ...core.kinematics import wrap_angle
from ...localization import absolute_sensors as ab
from ...localization.evaluation import nees, nees_band, weighted_mean_cov
from ...localization.histogram import hf_correct, hf_estimate

__all__ = ["ABSOLUTE_FILTERS", "ABSOLUTE_SENSORS", "absolute_sensing_study"]

#: The sensors and the filters of the study, in the order the report shows them.
ABSOLUTE_SENSORS: tuple[str, ...] = ("range", "bearing", "gnss", "compass")
ABSOLUTE_FILTERS: tuple[str, ...] = ("ekf", "histogram", "particle")

_COMPONENTS = ("x", "y", "theta")


def _sensor_pairs(beacons: np.ndarray, pose: np.ndarray, gnss_bias: list[float], compass_bias: float,
             disturbance: float) -> dict[str, tuple[Any, Any]]:  # fmt: skip
    """(true model, the filters' model) of every sensor."""
    dist = np.array([[pose[0] + 0.5, pose[1], disturbance, 1.0]])
    return {
        "range": (ab.RangeBeacons(beacons, 0.1),) * 2,
        "bearing": (ab.BearingBeacons(beacons, 0.02),) * 2,
        "gnss": (ab.Gnss(1.0, np.asarray(gnss_bias), 0.05, 20.0), ab.Gnss(1.0, np.zeros(2), 0.05, 20.0)),
        "compass": (ab.Compass(0.05, compass_bias, dist), ab.Compass(0.05)),
    }


def absolute_sensing_study(
    pose: list[float] = [4.0, 3.0, 0.3],  # noqa: B006
    beacons: list[list[float]] = [[0.0, 0.0], [10.0, 0.0], [5.0, 8.0]],  # noqa: B006
    prior_std: list[float] = [1.0, 1.0, 0.5],  # noqa: B006
    gnss_bias: list[float] = [1.0, 0.5],  # noqa: B006
    compass_bias: float = 0.05,
    disturbance: float = 0.2,
    n_measurements: int = 5,
    n_trials: int = 10,
    n_particles: int = 20_000,
    grid_resolution: float = 0.2,
    grid_ntheta: int = 36,
    seed: int = 19,
) -> dict[str, Any]:
    """Every absolute sensor in every filter from a broad prior (module docs).

    Parameters
    ----------
    pose : list of 3 floats — the true pose [m, m, rad]
    beacons : list of [x, y] — the beacons of the range and bearing sensors [m]
    prior_std : list of 3 floats — σ of the prior in x, y, θ [m, m, rad]
    gnss_bias : list of 2 floats — the satellite fix's offset [m]
    compass_bias : float — the compass's bias [rad]
    disturbance : float — the magnetic deviation at the robot [rad]
    n_measurements : int — measurements per trial
    n_trials : int — trials (prior means) per sensor
    n_particles : int — particles of the particle filter
    grid_resolution : float — cell side of the histogram filter [m]
    grid_ntheta : int — heading cells of the histogram filter
    seed : int — the random seed

    Returns
    -------
    dict
        ``sensors`` — per sensor and filter: ``sigma`` {x, y, theta} (RMS posterior σ [m, m, rad]),
        ``rms_error`` {x, y, theta}, ``fixes`` {x, y, theta} (bool: σ below half the prior's),
        ``nees_mean`` and ``nees_median`` [1] (the median is robust to the rare trial whose particles
        collapse onto a few); ``prior_std``; ``nees_band`` — the 95 % band of the NEES averaged over
        the trials
    """
    p = np.asarray(pose, dtype=float)
    s0 = np.asarray(prior_std, dtype=float)
    S0 = np.diag(s0**2)
    sensors = _sensor_pairs(np.asarray(beacons, dtype=float), p, gnss_bias, compass_bias, disturbance)
    rng = np.random.default_rng(seed)
    half = 4.0 * s0[:2]
    nx, ny = (np.ceil(2 * half / grid_resolution).astype(int) + 1).tolist()
    out: dict[str, Any] = {"prior_std": dict(zip(_COMPONENTS, s0.tolist(), strict=True)), "sensors": {}}
    for name in ABSOLUTE_SENSORS:
        true_model, model = sensors[name]
        g_sense, g_prior, g_pf = rng.spawn(3)
        rows: dict[str, dict[str, list[Any]]] = {f: {"sig": [], "err": [], "nees": []} for f in ABSOLUTE_FILTERS}
        for _ in range(int(n_trials)):  # a few trials; every filter's update is vectorised over its state
            z = true_model.sample(np.broadcast_to(p, (int(n_measurements), 3)), g_sense)
            m0 = p + s0 * g_prior.standard_normal(3)
            m0[2] = wrap_angle(m0[2])
            # EKF
            mean, cov = m0.copy(), S0.copy()
            for zi in z:  # one measurement after the other
                mean, cov, _, _ = ab.ekf_update_absolute(mean, cov, zi, model, gate=0.99 if name == "gnss" else None)
            est = {"ekf": (mean, cov)}
            # histogram: the prior's density on a grid about the prior's mean (as a filter that does not know the truth)
            grid = Grid(m0[0] - half[0], m0[1] - half[1], nx, ny, grid_resolution, grid_resolution, grid_ntheta)
            X, Y, TH = np.meshgrid(grid.x, grid.y, grid.theta, indexing="ij")
            d = np.stack([X - m0[0], Y - m0[1], wrap_angle(TH - m0[2])], axis=-1)
            belief = np.exp(-0.5 * np.sum((d / s0) ** 2, axis=-1))
            belief /= belief.sum()
            for zi in z:
                belief, _ = hf_correct(belief, ab.grid_log_likelihood(model, grid, zi))
            est["histogram"] = hf_estimate(belief, grid)
            # particles drawn from the prior
            P = m0 + s0 * g_pf.standard_normal((int(n_particles), 3))
            lw = sum(model.log_likelihood(P, zi) for zi in z)
            w = np.exp(lw - lw.max())
            est["particle"] = weighted_mean_cov(P, w / w.sum())
            for f, (mu, C) in est.items():
                e = mu - p
                e[2] = wrap_angle(e[2])
                rows[f]["sig"].append(np.sqrt(np.maximum(np.diag(C), 0.0)))
                rows[f]["err"].append(e)
                rows[f]["nees"].append(float(nees(mu, C, p)))
        out["sensors"][name] = {}
        for f, r in rows.items():
            sig = np.sqrt(np.mean(np.square(r["sig"]), axis=0))
            err = np.sqrt(np.mean(np.square(r["err"]), axis=0))
            nv = np.asarray(r["nees"])
            out["sensors"][name][f] = {
                "sigma": dict(zip(_COMPONENTS, sig.tolist(), strict=True)),
                "rms_error": dict(zip(_COMPONENTS, err.tolist(), strict=True)),
                "fixes": dict(zip(_COMPONENTS, (sig < 0.5 * s0).tolist(), strict=True)),
                "nees_mean": float(np.mean(nv[np.isfinite(nv)])) if np.isfinite(nv).any() else math.nan,
                "nees_median": float(np.median(nv[np.isfinite(nv)])) if np.isfinite(nv).any() else math.nan,
            }  # fmt: skip

    out["nees_band"] = list(nees_band(3, int(n_trials)))
    return out
