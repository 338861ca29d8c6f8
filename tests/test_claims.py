"""Every verdict branch of every claim, on small synthetic tables (rows as the tables hold them).

Each case builds the few rows a claim reads, with numbers chosen so that one branch must be
taken, and checks the verdict (and, where a claim quotes it, the number it rests on). The
numbers of the real pipeline are pinned in tests/test_one_source.py (golden file).
"""

from __future__ import annotations

import json
import math

import pytest

from pose_uncertainty.core.stats import COVERAGE_LEVELS
from pose_uncertainty.pipeline.claims import (
    VERDICTS,
    ClaimDataError,
    evaluate_claim,
    evaluate_claims,
)
from pose_uncertainty.pipeline.method_guide import method_guide


def _verdict(rows: dict, number: int) -> str:
    claim = evaluate_claim(rows, number)
    assert claim.verdict in VERDICTS
    return claim.verdict


def _claim(rows: dict, number: int):
    return evaluate_claim(rows, number)


# --- 1: across grows faster than along -----------------------------------------------------


def _straight(p_along: float, p_across: float, c_across: float = 0.1, lengths=(1.0, 2.0, 4.0, 8.0)):
    return {"L_straight": [{"run": f"L{L:g}", "path_length": L, "A_sigma_along": 0.01 * L**p_along,
                            "A_sigma_across": c_across * L**p_across} for L in lengths]}


def test_claim1_branches():
    assert _verdict(_straight(0.5, 1.5), 1) == "confirmed"
    assert _claim(_straight(0.5, 1.5), 1).numbers["slope_across"] == pytest.approx(1.5)
    assert _verdict(_straight(0.5, 0.4, c_across=0.001), 1) == "refuted"
    assert _verdict(_straight(0.5, 1.5, lengths=(1.0, 2.0)), 1) == "not measured"


# --- 2: direct < s_curve < right_angles ----------------------------------------------------


def _shape(areas: dict, majors: dict):
    return {"A1_shape": [{"run": k, "param.trajectory.name": k, "A_ellipse_area": areas[k],
                          "A_ellipse_major": majors[k], "path_length": 1.0} for k in areas]}


def test_claim2_branches():
    ordered = {"direct": 1.0, "s_curve": 2.0, "right_angles": 3.0}
    reversed_ = {"direct": 3.0, "s_curve": 2.0, "right_angles": 1.0}
    assert _verdict(_shape(ordered, ordered), 2) == "confirmed"
    assert _verdict(_shape(ordered, reversed_), 2) == "qualified"
    assert _verdict(_shape(reversed_, reversed_), 2) == "refuted"
    assert _verdict({}, 2) == "not measured"
    # the set is there but a path is missing: the claims job fails, naming what it looked for
    with pytest.raises(ClaimDataError, match=r"^claim 2 .*A1_shape has no run with trajectory.name = 'right_angles'$"):
        evaluate_claims({"A1_shape": _shape(ordered, ordered)["A1_shape"][:2]})


# --- 3: the speed profile has no effect ----------------------------------------------------


def _profile(ramp_factor: float):
    rows = []
    for traj in ("straight", "circle", "rotation"):
        for prof, f in (("constant", 1.0), ("ramp", ramp_factor)):
            rows.append({"run": f"{traj}_{prof}", "param.trajectory.name": traj, "param.trajectory.profile": prof,
                         **{k: f * v for k, v in (
                ("A_sigma_along", 0.01), ("A_sigma_across", 0.02), ("A_sigma_theta", 0.1),
                ("A_ellipse_major", 0.05), ("A_ellipse_minor", 0.03))}})
    return {"A2_profile": rows}


def test_claim3_branches():
    assert _verdict(_profile(1.0 + 1e-4), 3) == "confirmed"
    assert _verdict(_profile(1.1), 3) == "refuted"
    assert _claim(_profile(1.1), 3).numbers["rel_diff_straight"] == pytest.approx(0.1)


# --- 4: k, unequal k, track ----------------------------------------------------------------


def _parameters(major_small: float, tilt_r: float, tilt_l: float, across=(0.3, 0.2, 0.1)):
    def row(run, major=0.1, angle=0.0, sa=0.2):
        k_r, k_l, b = {"k5e-4_b0.2": (5e-4, 5e-4, 0.2), "k5e-5_b0.2": (5e-5, 5e-5, 0.2), "kr9e-4_kl1e-4_b0.2": (9e-4, 1e-4, 0.2),
                       "kr1e-4_kl9e-4_b0.2": (1e-4, 9e-4, 0.2), "k5e-4_b0.1": (5e-4, 5e-4, 0.1),
                       "k5e-4_b0.5": (5e-4, 5e-4, 0.5)}[run]  # fmt: skip
        return {"run": run, "param.k_r": k_r, "param.k_l": k_l, "param.trajectory.track": b, "A_ellipse_major": major,
                "A_ellipse_angle": angle, "A_sigma_across": sa, "A_sigma_along": 0.01}
    return {"A3_parameters": [
        row("k5e-4_b0.2", sa=across[1]), row("k5e-5_b0.2", major=major_small),
        row("kr9e-4_kl1e-4_b0.2", angle=math.radians(tilt_r)), row("kr1e-4_kl9e-4_b0.2", angle=math.radians(tilt_l)),
        row("k5e-4_b0.1", sa=across[0]), row("k5e-4_b0.5", sa=across[2])]}


def test_claim4_branches():
    assert _verdict(_parameters(0.1 / math.sqrt(10), 5.0, -5.0), 4) == "confirmed"
    assert _verdict(_parameters(0.1 / math.sqrt(10), 0.0, 0.0), 4) == "qualified"  # no tilt
    assert _verdict(_parameters(0.2, 0.0, 0.0, across=(0.1, 0.2, 0.3)), 4) == "refuted"


# --- 5: the circle's cloud looks Gaussian --------------------------------------------------


def _cloud(cov3: float, cov1: float, ks: float, bend: float, n: int = 20000):
    return {"A4_distribution": [{"run": "per_step", "param.monte_carlo.regime": "per_step", "MC_n": n, "MC_coverage_3s": cov3, "MC_coverage_1s": cov1,
                                 "MC_ks_gauss": ks, "MC_ks_crit": 1.358 / math.sqrt(n), "MC_bend": bend,
                                 "MC_bend_crit": 2 / math.sqrt(n), "A_sigma_theta": 0.1}]}


def test_claim5_branches():
    lvl3, lvl1 = COVERAGE_LEVELS["3s"], COVERAGE_LEVELS["1s"]
    assert _verdict(_cloud(lvl3, lvl1, 0.001, 0.001), 5) == "confirmed"
    # coverage holds but the shape is bent beyond noise
    assert _verdict(_cloud(lvl3, lvl1, 0.05, 0.3), 5) == "qualified"
    assert _verdict(_cloud(0.90, 0.30, 0.05, 0.3), 5) == "refuted"
    # the coverage tolerance is 3 binomial standard errors: 3·√(p(1−p)/n) at n = 20000 is 0.0022 at 98.89 %
    se3 = 3 * math.sqrt(lvl3 * (1 - lvl3) / 20000)
    assert _verdict(_cloud(lvl3 - 0.9 * se3, lvl1, 0.001, 0.001), 5) == "confirmed"
    assert _verdict(_cloud(lvl3 - 1.1 * se3, lvl1, 0.001, 0.001), 5) == "qualified"


# --- 6: rotation in place peaks off the start ----------------------------------------------


def _rotation(offset: float, angle: float, corrected: float | None):
    row = {"run": "rotation", "param.trajectory.name": "rotation", "map_velocity_region_area": 1e-3, "map_velocity_peak_offset": offset,
           "map_velocity_peak_angle": angle}
    if corrected is not None:
        row["map_velocity_corrected_peak_offset"] = corrected
    return {"B1_trajectory": [row]}


def test_claim6_branches():
    thesis = (math.hypot(0.02, 0.01), math.atan2(0.01, 0.02))  # the thesis's point, 0.46 rad
    assert _verdict(_rotation(*thesis, 0.0), 6) == "refuted"  # reproduced, but the pose density peaks at the start
    assert _verdict(_rotation(*thesis, 0.02), 6) == "qualified"
    assert _verdict(_rotation(0.1, 1.5, 0.02), 6) == "refuted"
    assert _verdict(_rotation(*thesis, None), 6) == "qualified"
    assert _verdict(_rotation(0.1, 1.5, None), 6) == "refuted"


# --- 7: "exponential" growth ---------------------------------------------------------------


def test_claim7_branches():
    L = (1.0, 2.0, 4.0, 8.0, 16.0)
    power = {"L_straight": [{"run": f"L{x:g}", "path_length": x, "A_sigma_across": x**1.5, "A_sigma_along": x**0.5}
                            for x in L]}
    expo = {"L_straight": [{"run": f"L{x:g}", "path_length": x, "A_sigma_across": math.exp(0.5 * x),
                            "A_sigma_along": math.exp(0.2 * x)} for x in L]}
    assert _verdict(power, 7) == "refuted"
    assert _verdict(expo, 7) == "confirmed"
    circle = {"L_circle": [{"run": f"c{x:g}", "path_length": x, "A_ellipse_major": math.exp(0.3 * x)} for x in L]}
    assert _verdict({**power, **circle}, 7) == "qualified"
    assert _verdict({}, 7) == "not measured"


# --- 8 and 11: speed -----------------------------------------------------------------------


def _speed(vel: tuple, odo: tuple, vel_abs: tuple | None):
    rows = []
    for i, (v, o) in enumerate(zip(vel, odo, strict=True)):
        r = {"run": f"straight_v{i}", "param.trajectory.name": "straight", "map_velocity_region_area": v,
             "map_odometry_region_area": o}
        if vel_abs is not None:
            r["map_velocity_abs_region_area"] = vel_abs[i]
        rows.append(r)
    return {"B3_speed": rows}


def test_claim8_branches():
    same = (1.0, 1.0, 1.0)
    assert _verdict(_speed(same, same, None), 8) == "confirmed"
    assert _verdict(_speed(same, same, (1.0, 2.0, 0.5)), 8) == "qualified"
    assert _verdict(_speed((1.0, 1.2, 1.0), same, None), 8) == "refuted"
    assert _verdict({"B3_speed": []}, 8) == "not measured"


def test_claim11_branches():
    same = (1.0, 1.0, 1.0)
    assert _verdict(_speed(same, same, None), 11) == "refuted"
    assert _verdict(_speed(same, (1.0, 1.5, 1.0), None), 11) == "confirmed"
    assert _claim(_speed(same, (1.0, 1.5, 1.0), None), 11).numbers["rel_spread"] == pytest.approx(0.5)


# --- 9: which α sets which size ------------------------------------------------------------


def _alpha(a12: tuple, a34: tuple, a56: tuple):
    def row(run, al, ac):
        reduced = {"base": (), "a12": (0, 1), "a34": (2, 3), "a56": (4, 5)}[run]
        alphas = [0.005 if i in reduced else 0.05 for i in range(6)]
        return {"run": run, "param.maps": json.dumps([{"name": "velocity", "model": "velocity", "alphas": alphas}]),
                "map_velocity_region_area": 1.0, "map_velocity_sigma_along": al, "map_velocity_sigma_across": ac}
    return {"B4_alpha": [row("base", 1.0, 1.0), row("a12", *a12), row("a34", *a34), row("a56", *a56)]}


def test_claim9_branches():
    assert _verdict(_alpha((0.5, 1.0), (1.0, 0.5), (1.0, 1.0)), 9) == "confirmed"
    assert _verdict(_alpha((0.5, 1.0), (1.0, 0.5), (0.8, 1.0)), 9) == "qualified"
    assert _verdict(_alpha((1.0, 0.5), (0.5, 1.0), (0.8, 0.8)), 9) == "refuted"


# --- 10: odometry against velocity maps ----------------------------------------------------


def _b1(ratios: dict, peak_offset: float):
    rows = []
    for run, ratio in ratios.items():
        rows.append({"run": run, "param.trajectory.name": run, "map_velocity_region_area": 1.0,
                     "map_odometry_region_area": ratio,
                     "map_odometry_peak_offset": peak_offset})
    return {"B1_trajectory": rows}


def test_claim10_branches():
    assert _verdict(_b1({"straight": 1.5, "arc": 1.2, "rotation": 0.01}, 0.08), 10) == "confirmed"
    assert _verdict(_b1({"straight": 1.5, "arc": 1.2, "rotation": 0.01}, 0.0), 10) == "qualified"
    assert _verdict(_b1({"straight": 0.5, "arc": 0.5, "rotation": 2.0}, 0.0), 10) == "refuted"
    # the claim quotes the logged peak offset of each run (its reference: the map's centre)
    c = _claim(_b1({"straight": 1.5, "arc": 1.2, "rotation": 0.01}, 0.099), 10)
    assert c.numbers["odometry_peak_offset_arc"] == 0.099
    assert "9.90 cm" in c.measured
    assert "from the map's centre, the noiseless exact-arc end pose" in c.measured


# --- 12: Šafránek 2022's bent cloud, FK method, track --------------------------------------


def _s001(bend: float, fk_rel: float, major_b01: float, major_b02: float, n: int = 1000):
    rows = []
    for track, major in ((0.1, major_b01), (0.2, major_b02)):
        for method, scale in (("exact", 1.0), ("midpoint", 1.0 + fk_rel)):
            rows.append({"run": f"b{track}_{method}", "param.monte_carlo.regime": "per_run",
                         "param.monte_carlo.method": method, "param.trajectory.name": "straight",
                         "param.trajectory.track": track, "MC_ellipse_major": major * scale, "MC_n": n,
                         "MC_bend": bend, "MC_bend_crit": 2 / math.sqrt(n)})
    return {"S_chassis": rows}


def test_claim12_branches():
    assert _verdict(_s001(-0.5, 1e-4, 0.2, 0.1), 12) == "confirmed"
    assert _verdict(_s001(0.0, 1e-4, 0.2, 0.1), 12) == "qualified"
    assert _verdict(_s001(0.0, 0.5, 0.1, 0.2), 12) == "refuted"
    # the FK tolerance is the relative standard error of a sample standard deviation, 1/√(2(n−1))
    se = 1 / math.sqrt(2 * 999)
    assert _claim(_s001(-0.5, 0.9 * se, 0.2, 0.1), 12).verdict == "confirmed"
    assert _claim(_s001(-0.5, 1.1 * se, 0.2, 0.1), 12).verdict == "qualified"


def test_every_claim_is_not_measured_without_its_sets():
    claims = evaluate_claims({})
    numbers = [c.number for c in claims]
    assert numbers[:12] == list(range(1, 13))
    # Skalka 2011's techniques (tests/test_skalka_claims.py) and your robot's (tests/test_claims_robot.py)
    assert sorted(numbers) == list(range(1, 39))  # 35–38: Skalka 2011 §5.1, §4.2.2
    assert {c.verdict for c in claims} == {"not measured"}
    assert all("needs" in c.reason for c in claims)


# --- the method guide ----------------------------------------------------------------------


def test_guide_orders_runs_by_bend_ratio_with_the_claims_coverage_rule():
    n, lvl = 2000, COVERAGE_LEVELS["3s"]
    tol = 3 * math.sqrt(lvl * (1 - lvl) / n)
    rows = {"S": [
        {"run": "a", "param.monte_carlo.regime": "per_step", "MC_coverage_3s": lvl, "A_bend_ratio": 0.1, "MC_n": n},
        {"run": "b", "param.monte_carlo.regime": "per_step", "MC_coverage_3s": lvl - 0.5 * tol, "A_bend_ratio": 0.3,
         "MC_n": n},
        {"run": "c", "param.monte_carlo.regime": "per_step", "MC_coverage_3s": lvl - 2 * tol, "A_bend_ratio": 0.5,
         "MC_n": n},
        {"run": "d", "param.monte_carlo.regime": "per_run", "MC_coverage_3s": 0.5, "A_bend_ratio": 0.01, "MC_n": n},
    ]}
    g = method_guide(rows)[0]
    assert g["numbers"]["first_short_run"] == "c"  # b is within 3 standard errors, the per-run d is not counted
    assert g["numbers"]["n_hold_below"] == 2
    assert g["numbers"]["worst_run"] == "c"
    assert g["numbers"]["median_coverage_3s"] == pytest.approx(lvl - 0.5 * tol)
