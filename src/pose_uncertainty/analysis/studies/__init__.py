"""Šafránek 2022's studies and the growth laws, as functions returning tables (lists of dicts).

* :func:`integration_vs_step` — the three integration methods against step
  size: error of the end pose from the exact arc, and the fitted order;
  :func:`method_cloud_spread` — whether the cloud depends on the method
  (:mod:`.integration`, on the arc of :mod:`.arcs`).
* :func:`number_type_drift`, :func:`number_type_clouds` — integer
  millimetres, float32, float64 and long double: a sequential step loop in
  the given type (the one place a per-step loop is the point), its drift from
  the exact end pose and what it does to the cloud of end poses (:mod:`.number_types`).
* :func:`error_sources_vs_monte_carlo` — Šafránek 2022's error sources mapped to
  the equivalent ``k`` (:mod:`pose_uncertainty.methods.wheel_noise`) and checked
  against Monte Carlo; :func:`regime_growth` — systematic (per-run) against
  random (per-step) errors and their growth with distance (:mod:`.noise_models`).
* :func:`polar_vs_cartesian` — moments of the cloud in Cartesian ``(x, y)``
  and polar ``(r, φ)`` coordinates about the start; :func:`growth_laws` — how
  σ_along, σ_across, σ_θ and the credible-region area grow with distance: log-log
  power-law fits against exponential fits (:mod:`.growth`).
* :func:`map_vs_sampler` — single-step probability maps against their own sampler
  (:mod:`.probability_maps`).
* ``umbmark`` (:func:`pose_uncertainty.analysis.umbmark.umbmark_experiment`) — the
  UMBmark squares of a robot with known systematic errors, before and after the correction;
* Skalka 2011's localization techniques, measured: :func:`relative_sensing_study` (odometry, INS and
  gyro-aided odometry, :mod:`.relative_sensing`), :func:`absolute_sensing_study` (range, bearing, GNSS
  and compass in the three filters, :mod:`.absolute_sensing`), :func:`guaranteed_bounds_study` (interval
  boxes and zonotopes, :mod:`.guaranteed_bounds`), :func:`representations_study` (grid, graph of
  places, particles, Kalman filter and intervals on the same runs, :mod:`.representations`) and
  :func:`active_localization_study` (motions chosen by expected entropy, :mod:`.active_localization`) and
  :func:`dynamic_environment_study` (people not on the map, the beam model's components and the distance
  filter, :mod:`.dynamic_environment`); :func:`scan_matching_study` (scan-to-map matching in the EKF against
  the beam-model particle filter, in a room and an ambiguous corridor, :mod:`.scan_matching`);
* :func:`calibration_demo` — ``k`` fitted back from Monte Carlo end poses
  with both models (:mod:`.recalibration`).
* :func:`accuracy_case` — coverage and distances of the three Gaussian methods
  (A, the banana, C) on one path (the pipeline runs the long paths: straight 1, 5, 20 m; 1 and 3 laps
  of a circle; larger k); :func:`coverage_vs_distance` — coverage along a path;
  :func:`expcoords_regions` — the data of the figure of clouds, ellipses and bananas
  (:mod:`.gaussian_methods`).

The pipeline runs each study as a job of its own (config key ``studies``; kinds
in :data:`STUDIES`, executed and logged by :mod:`pose_uncertainty.experiments.study`);
:func:`summarize` (:mod:`.summary`) turns the logged results into what the report quotes.
The ``*_study`` functions are the studies as configured: keyword parameters with the
thesis's defaults, on a trajectory given as a config mapping.
"""

from __future__ import annotations

from typing import Any

from .. import umbmark as um
from .absolute_sensing import absolute_sensing_study
from .active_localization import active_localization_study
from .arcs import constant_speed_trajectory, exact_constant_arc
from .dynamic_environment import dynamic_environment_study
from .gaussian_methods import (
    accuracy_case,
    accuracy_vs_distance_study,
    coverage_vs_distance,
    expcoords_regions,
)
from .growth import growth_laws, growth_laws_study, polar_vs_cartesian, polar_vs_cartesian_study
from .guaranteed_bounds import guaranteed_bounds_study
from .integration import integration_vs_step, method_cloud_spread, method_cloud_spread_study
from .noise_models import (
    error_sources_study,
    error_sources_vs_monte_carlo,
    regime_growth,
    regime_growth_study,
)
from .number_types import (
    NUMBER_TYPES,
    integrate_in_type,
    number_type_clouds,
    number_type_clouds_study,
    number_type_drift,
)
from .probability_maps import map_vs_sampler
from .recalibration import calibration_demo
from .relative_sensing import relative_sensing_study
from .representations import representations_study
from .scan_matching import scan_matching_study
from .summary import summarize

__all__ = [
    "NUMBER_TYPES",
    "STUDIES",
    "absolute_sensing_study",
    "accuracy_case",
    "active_localization_study",
    "calibration_demo",
    "constant_speed_trajectory",
    "coverage_vs_distance",
    "dynamic_environment_study",
    "error_sources_vs_monte_carlo",
    "exact_constant_arc",
    "expcoords_regions",
    "growth_laws",
    "guaranteed_bounds_study",
    "integrate_in_type",
    "integration_vs_step",
    "map_vs_sampler",
    "method_cloud_spread",
    "number_type_clouds",
    "number_type_drift",
    "polar_vs_cartesian",
    "regime_growth",
    "relative_sensing_study",
    "representations_study",
    "scan_matching_study",
    "summarize",
]

#: Every study a config can run, by kind: a function of JSON-like keyword parameters (each with
#: its default, the thesis's setting) returning JSON-like results.
STUDIES: dict[str, Any] = {
    "integration_vs_step": integration_vs_step,
    "method_cloud_spread": method_cloud_spread_study,
    "number_type_drift": number_type_drift,
    "number_type_clouds": number_type_clouds_study,
    "error_sources": error_sources_study,
    "regime_growth": regime_growth_study,
    "polar_vs_cartesian": polar_vs_cartesian_study,
    "growth_laws": growth_laws_study,
    "map_vs_sampler": map_vs_sampler,
    "accuracy_case": accuracy_case,
    "calibration_demo": calibration_demo,
    "accuracy_vs_distance": accuracy_vs_distance_study,
    "expcoords_regions": expcoords_regions,
    "umbmark": um.umbmark_experiment,  # systematic errors: UMBmark before and after the correction
    # Skalka 2011's localization techniques, measured
    "relative_sensing": relative_sensing_study,
    "absolute_sensing": absolute_sensing_study,
    "guaranteed_bounds": guaranteed_bounds_study,
    "representations": representations_study,
    "active_localization": active_localization_study,
    "dynamic_environment": dynamic_environment_study,
    "scan_matching": scan_matching_study,
}
