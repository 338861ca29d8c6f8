"""YAML files ready to paste into a ROS 2 navigation setup, from a calibration.

Twist covariance of wheel odometry at a nominal speed ``v`` and update rate ``f``
---------------------------------------------------------------------------------
Over one update period ``T = 1/f`` at speed ``v`` each wheel travels ``vT`` with variance
``k vT`` (Method A), so its speed has variance ``k v / T``. With
``V = (v_r + v_l)/2`` and ``ω = (v_r − v_l)/b``::

    var(V) = (k_r + k_l) v f / 4,        var(ω) = (k_r + k_l) v f / b²

The lateral speed of a differential drive is zero by construction: a small variance
(10⁻⁹) keeps a filter fusing it well conditioned; z, roll and pitch are not measured (10⁶).

Pose covariance
---------------
diff_drive_controller publishes one constant ``pose_covariance_diagonal``; the true one
grows with the distance driven. The exported diagonal is Method A's after driving
``covariance_distance`` straight with the calibrated constants.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..methods import covariance as cv
from .nav2 import DIFFERENTIAL_MODEL, OMNI_MODEL

__all__ = ["nav2_amcl_yaml", "pose_covariance_at", "robot_localization_yaml", "ros2_control_yaml", "twist_variances"]

_UNMEASURED = 1e6
_LATERAL = 1e-9


def twist_variances(k_r: float, k_l: float, track: float, speed: float, rate: float) -> tuple[float, float]:
    """``(var(V) [m²/s²], var(ω) [rad²/s²])`` at ``speed`` [m/s] and ``rate`` [Hz] (module docstring)."""
    ks = k_r + k_l
    return ks * speed * rate / 4.0, ks * speed * rate / track**2


def pose_covariance_at(k_r: float, k_l: float, track: float, distance: float) -> np.ndarray:
    """Method A's (x, y, θ) covariance after ``distance`` [m] straight from a known pose."""
    n = 200
    ds = np.full(n, distance / n)
    _, covs = cv.propagate_travels(ds, ds, track, k_r, k_l)
    return covs[-1]


def _list(values: list[float]) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in values) + "]"


def _twist_diag(q: dict[str, Any], speed: float, rate: float) -> list[float]:
    vv, vw = twist_variances(q["k_r"]["value"], q["k_l"]["value"], q["track"]["value"], speed, rate)
    return [vv, _LATERAL, _UNMEASURED, _UNMEASURED, _UNMEASURED, vw]


def ros2_control_yaml(q: dict[str, Any], nominal: tuple[float, float, float], speed: float, rate: float,
                      distance: float) -> str:  # fmt: skip
    """``ros2_control.yaml`` for diff_drive_controller (calibration quantities ``q``)."""
    rl_n, rr_n, b_n = nominal
    cov = pose_covariance_at(q["k_r"]["value"], q["k_l"]["value"], q["track"]["value"], distance)
    pose = [cov[0, 0], cov[1, 1], _UNMEASURED, _UNMEASURED, _UNMEASURED, cov[2, 2]]
    radius = 0.5 * (rl_n + rr_n)
    return "\n".join([
        "# diff_drive_controller parameters from pose-uncertainty's robot calibration.",
        "# The multipliers scale the nominal geometry below to the calibrated one",
        f"# (E_d = D_R/D_L = {q['E_d']['value']:.6g}, E_b = b/b_nominal = {q['E_b']['value']:.6g};",
        "# Borenstein & Feng 1996).",
        "diff_drive_controller:",
        "  ros__parameters:",
        f"    wheel_separation: {b_n:.6g}  # m, nominal",
        f"    wheel_radius: {radius:.6g}  # m, nominal",
        f"    wheel_separation_multiplier: {q['track']['value'] / b_n:.6g}",
        f"    left_wheel_radius_multiplier: {q['wheel_radius_left']['value'] / radius:.6g}",
        f"    right_wheel_radius_multiplier: {q['wheel_radius_right']['value'] / radius:.6g}",
        f"    # twist covariance at a nominal speed of {speed:g} m/s and an update rate of {rate:g} Hz",
        "    # (the controller publishes it unchanged at any speed; the wheel noise grows with speed)",
        f"    twist_covariance_diagonal: {_list(_twist_diag(q, speed, rate))}",
        "    # pose covariance: CONSTANT in the controller, while the true covariance grows with the",
        f"    # distance driven; this is Method A's after {distance:g} m straight from a known pose",
        f"    pose_covariance_diagonal: {_list(pose)}",
        "",
    ])  # fmt: skip


#: nav2's source file of each motion model the export writes, by ``robot_model_type``.
_NAV2_SOURCES = {
    DIFFERENTIAL_MODEL: "differential_motion_model.cpp",
    OMNI_MODEL: "omni_motion_model.cpp",
}


def nav2_amcl_yaml(nav2: dict[str, Any]) -> str:
    """``nav2_amcl.yaml``: a fitted motion model's alphas and the thresholds they hold for.

    Parameters
    ----------
    nav2 : dict — :meth:`.nav2.Nav2Fit.as_dict`: ``robot_model_type``
        ``"nav2_amcl::DifferentialMotionModel"`` with ``alpha1``…``alpha4``
        (:func:`.nav2.fit_nav2_alphas`) or ``"nav2_amcl::OmniMotionModel"`` with
        ``alpha1``…``alpha5`` (:func:`.nav2_omni.fit_nav2_omni_alphas`)
    """
    cov, model = nav2["coverage"], nav2["robot_model_type"]
    if model not in _NAV2_SOURCES:
        raise ValueError(f"robot_model_type must be one of {sorted(_NAV2_SOURCES)}, got {model!r}")
    n_alphas = 5 if model == OMNI_MODEL else 4
    fitted_to, made_by = (("calibrated wheel model", "robot calibration") if model == DIFFERENTIAL_MODEL
                          else ("drive's wheel-noise model", "robot.nav2_omni"))  # fmt: skip
    return "\n".join([
        f"# nav2 AMCL motion model fitted by maximum likelihood to the {fitted_to}",
        f"# (pose-uncertainty {made_by}; nav2_amcl {_NAV2_SOURCES[model]}'s sampler).",
        f"# Holds for: {nav2['holds_for']}.",
        (f"# Coverage of the wheel model's Monte Carlo draws by the fitted model's 95 % region: "
        f"{cov['overall']:.3f} overall ({nav2['n_increments']} increments x {nav2['n_samples']} draws)."),
        "amcl:",
        "  ros__parameters:",
        f'    robot_model_type: "{model}"',
        *(f"    alpha{i}: {nav2[f'alpha{i}']:.6g}" for i in range(1, n_alphas + 1)),
        f"    update_min_d: {nav2['update_min_d']:g}  # m, the alphas hold for this",
        f"    update_min_a: {nav2['update_min_a']:g}  # rad, the alphas hold for this",
        "",
    ])  # fmt: skip


def robot_localization_yaml(q: dict[str, Any], speed: float, rate: float, odom_topic: str = "/odom") -> str:
    """``robot_localization.yaml``: fuse the odometry's twist; its covariance as the message must carry it."""
    diag = _twist_diag(q, speed, rate)
    return "\n".join([
        "# robot_localization EKF fusing the wheel odometry's twist (pose-uncertainty robot calibration).",
        "# robot_localization takes each input's covariance from its messages: the odometry must carry",
        f"# the twist covariance below, for a nominal speed of {speed:g} m/s and an update rate of {rate:g} Hz",
        "# (ros2_control.yaml's twist_covariance_diagonal sets it in diff_drive_controller).",
        f"# odom0 twist covariance diagonal (vx, vy, vz, vroll, vpitch, vyaw): {_list(diag)}",
        "ekf_filter_node:",
        "  ros__parameters:",
        f"    frequency: {rate:g}",
        "    two_d_mode: true",
        f"    odom0: {odom_topic}",
        "    # fuse vx, vy (zero for a differential drive) and vyaw",
        "    odom0_config: [false, false, false, false, false, false,",
        "                   true, true, false, false, false, true,",
        "                   false, false, false]",
        "    odom0_differential: false",
        "",
    ])  # fmt: skip
