"""Every verdict branch of claims 13–29 (Skalka 2011's localization techniques), on small synthetic study logs.

Each case builds the logged results a claim reads (the documents of
:func:`pose_uncertainty.experiments.study.collect_studies`), with numbers chosen so that one branch must
be taken, and checks the verdict and the numbers it rests on. The claims find their studies by kind
(the ``skalka`` entry of the summary), never by name: renaming the studies changes nothing.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import pytest

from pose_uncertainty.analysis.studies import summarize
from pose_uncertainty.pipeline.claims import VERDICTS, evaluate_claim, evaluate_claims, write_claims


def _doc(**studies: tuple[str, dict]) -> dict:
    """A studies document from ``name=(kind, results)``, through the real summary."""
    return summarize({name: {"study": kind, "results": r} for name, (kind, r) in studies.items()})


def _verdict(doc: dict, number: int) -> str:
    c = evaluate_claim({}, number, doc)
    assert c.verdict in VERDICTS
    return c.verdict


# --- 13–15: relative sensing -------------------------------------------------------------


def _relative(ins: float, odo: float, gyr: float, p_ins: float = 2.0, p_odo: float = 1.5) -> dict:
    def scheme(final: float, p: float) -> dict:
        return {"final_a": final, "final_mc": final * 1.01, "mc_over_a": 1.01,
                "fits_a": {"time": {"power_exponent": p}, "distance": {"power_exponent": p}}}

    return {"path_length": 20.0, "duration": 40.0, "max_specific_force": 1e-3, "accel_bias_std": 0.01, "n": 100,
            "odometry": scheme(odo, p_odo), "ins": scheme(ins, p_ins), "gyro_odometry": scheme(gyr, 1.0)}  # fmt: skip


def test_claim13_ins_alone():
    assert _verdict(_doc(a=("relative_sensing", _relative(10.0, 8.0, 0.2))), 13) == "confirmed"
    assert _verdict(_doc(a=("relative_sensing", _relative(3.0, 8.0, 0.2))), 13) == "qualified"
    assert _verdict(_doc(a=("relative_sensing", _relative(0.1, 8.0, 0.2))), 13) == "refuted"
    c = evaluate_claim({}, 13, _doc(a=("relative_sensing", _relative(10.0, 8.0, 0.2))))
    assert c.numbers["a.ins_final"] == 10.0
    assert c.numbers["a.ins_over_distance"] == pytest.approx(0.5)


def test_claim14_combining():
    good, bad = _relative(10.0, 8.0, 0.2), _relative(10.0, 0.1, 0.2)
    assert _verdict(_doc(a=("relative_sensing", good), b=("relative_sensing", good)), 14) == "confirmed"
    assert _verdict(_doc(a=("relative_sensing", good), b=("relative_sensing", bad)), 14) == "qualified"
    assert _verdict(_doc(a=("relative_sensing", bad)), 14) == "refuted"


def test_claim15_ins_growth():
    assert _verdict(_doc(a=("relative_sensing", _relative(10, 8, 0.2, 2.0, 1.5))), 15) == "confirmed"
    assert _verdict(_doc(a=("relative_sensing", _relative(10, 8, 0.2, 1.4, 1.0))), 15) == "refuted"
    assert _verdict(_doc(a=("relative_sensing", _relative(10, 8, 0.2, 2.0, 1.5)),
                         b=("relative_sensing", _relative(10, 8, 0.2, 1.4, 1.0))), 15) == "qualified"


# --- 16–18: guaranteed bounds --------------------------------------------------------------


def _bounds(box: float, zon: float, sup: float, ell: float, contains: float = 1.0) -> dict:
    ratios = {"box_over_support": [box / sup], "zonotope_over_support": [zon / sup],
              "ellipse_over_support": [ell / sup], "box_over_zonotope": [box / zon]}
    final = {"distance": 10.0, "box_area": box, "zonotope_area": zon, "support_area": sup, "ellipse_area": ell,
             **{k: v[0] for k, v in ratios.items()}}
    return {"distance": [10.0], "box_area": [box], "zonotope_area": [zon], "support_area": [sup],
            "ellipse_area": [ell], **ratios, "box_contains": contains, "zonotope_contains": 1.0,
            "ellipse_contains": 0.99, "n": 1000, "pulse": 6e-4, "zonotope_tighter": [], "final": final}  # fmt: skip


def test_claim16_pessimism():
    assert _verdict(_doc(g=("guaranteed_bounds", _bounds(5.0, 4.0, 1.0, 0.1))), 16) == "confirmed"
    assert _verdict(_doc(g=("guaranteed_bounds", _bounds(2.0, 4.0, 1.0, 0.1))), 16) == "qualified"
    assert _verdict(_doc(g=("guaranteed_bounds", _bounds(2.0, 4.0, 1.0, 0.5))), 16) == "refuted"
    c = evaluate_claim({}, 16, _doc(g=("guaranteed_bounds", _bounds(2.0, 4.0, 1.0, 0.1))))
    assert c.numbers["g.box_over_ellipse"] == pytest.approx(20.0)


def test_claim17_zonotopes():
    assert _verdict(_doc(g=("guaranteed_bounds", _bounds(5.0, 4.0, 1.0, 0.1))), 17) == "confirmed"
    assert _verdict(_doc(g=("guaranteed_bounds", _bounds(2.0, 4.0, 1.0, 0.1))), 17) == "refuted"
    two = _doc(g=("guaranteed_bounds", _bounds(5.0, 4.0, 1.0, 0.1)), h=("guaranteed_bounds", _bounds(2.0, 4.0, 1.0, 0.1)))
    assert _verdict(two, 17) == "qualified"


def test_claim18_containment():
    assert _verdict(_doc(g=("guaranteed_bounds", _bounds(5.0, 4.0, 1.0, 0.1))), 18) == "confirmed"
    assert _verdict(_doc(g=("guaranteed_bounds", _bounds(5.0, 4.0, 1.0, 0.1, contains=0.999))), 18) == "refuted"


# --- 19–22: absolute sensing ---------------------------------------------------------------


def _absolute(fixes: dict[str, tuple[bool, bool, bool]], nees: float = 2.4) -> dict:
    def row(f: tuple[bool, bool, bool]) -> dict:
        sig = {k: (0.05 if ok else 1.0) for k, ok in zip(("x", "y", "theta"), f, strict=True)}
        return {"sigma": sig, "rms_error": sig, "fixes": dict(zip(("x", "y", "theta"), f, strict=True)),
                "nees_mean": nees, "nees_median": nees}

    return {"prior_std": {"x": 1.0, "y": 1.0, "theta": 0.5}, "nees_band": [1.25, 5.5],
            "sensors": {s: {flt: row(f) for flt in ("ekf", "histogram", "particle")} for s, f in fixes.items()}}


def test_claims19_to_22_absolute():
    truth = {"range": (True, True, False), "bearing": (True, True, True), "gnss": (True, True, False),
             "compass": (False, False, True)}  # fmt: skip
    inconsistent = _doc(a=("absolute_sensing", _absolute(truth, nees=50.0)))
    consistent = _doc(a=("absolute_sensing", _absolute(truth, nees=2.4)))
    assert [_verdict(inconsistent, n) for n in (19, 20, 21, 22)] == ["confirmed"] * 4
    assert [_verdict(consistent, n) for n in (21, 22)] == ["qualified"] * 2  # fixes right, consistent all the same
    wrong = {"range": (True, True, True), "bearing": (True, True, False), "gnss": (False, False, True),
             "compass": (True, True, True)}  # fmt: skip
    assert [_verdict(_doc(a=("absolute_sensing", _absolute(wrong, 2.4))), n) for n in (19, 20, 21, 22)] == ["refuted"] * 4


# --- 23–27, 29: the representations --------------------------------------------------------


def _rep(**over: dict) -> dict:
    base = {
        "grid": {"rms_position_error": 0.2, "seconds_per_step": 1e-2, "memory_bytes": 2e5, "global_success": 1.0,
                     "kidnapped_success": 0.0, "hypotheses": 3, "coverage_3s": 0.8, "assumption_violated": 0.1},
        "topological": {"rms_position_error": 0.7, "seconds_per_step": 1e-5, "memory_bytes": 500.0, "global_success": 0.0,
                            "kidnapped_success": 1.0, "hypotheses": 4, "coverage_3s": 1.0, "assumption_violated": 0.0},
        "particles": {"rms_position_error": 0.05, "seconds_per_step": 1e-3, "memory_bytes": 3e4, "global_success": 1.0,
                          "kidnapped_success": 1.0, "hypotheses": 2, "coverage_3s": 0.95, "assumption_violated": 0.04},
        "kalman": {"rms_position_error": 0.02, "seconds_per_step": 1e-4, "memory_bytes": 96.0, "global_success": 0.0,
                       "kidnapped_success": 0.0, "hypotheses": 1, "coverage_3s": 0.99, "assumption_violated": 0.05},
        "intervals": {"rms_position_error": 0.08, "seconds_per_step": 2e-2, "memory_bytes": 6e3, "global_success": 1.0,
                          "kidnapped_success": 1.0, "hypotheses": 1, "coverage_3s": 1.0, "assumption_violated": 0.0},
    }  # fmt: skip
    for rep, changes in over.items():
        base[rep] = {**base[rep], **changes}
    return _doc(r=("representations", {"table": base, "n_steps": 100, "repeat": 2, "n_places": 62,
                                       "grid_cells": 30000, "kidnap_step": 50, "pos_tol": 0.5, "head_tol": 0.25}))


def test_claim23_mcl_against_grid():
    assert _verdict(_rep(), 23) == "confirmed"
    assert _verdict(_rep(particles={"rms_position_error": 0.3}), 23) == "qualified"
    assert _verdict(_rep(particles={"rms_position_error": 0.3, "seconds_per_step": 0.1}), 23) == "refuted"


def test_claim24_topological():
    assert _verdict(_rep(), 24) == "confirmed"
    assert _verdict(_rep(topological={"rms_position_error": 0.01}), 24) == "qualified"
    assert _verdict(_rep(topological={"rms_position_error": 0.01, "memory_bytes": 1e6}), 24) == "refuted"


def test_claim25_kalman():
    assert _verdict(_rep(), 25) == "confirmed"
    assert _verdict(_rep(kalman={"global_success": 1.0}), 25) == "qualified"
    assert _verdict(_rep(kalman={"global_success": 1.0, "seconds_per_step": 1.0}), 25) == "refuted"


def test_claim26_hypotheses():
    assert _verdict(_rep(), 26) == "confirmed"
    assert _verdict(_rep(particles={"hypotheses": 1}), 26) == "qualified"
    assert _verdict(_rep(particles={"hypotheses": 1}, grid={"hypotheses": 1}, kalman={"hypotheses": 2}), 26) == "refuted"


def test_claim27_kidnapped():
    assert _verdict(_rep(), 27) == "confirmed"
    assert _verdict(_rep(kalman={"kidnapped_success": 1.0}), 27) == "qualified"
    assert _verdict(_rep(kalman={"kidnapped_success": 1.0}, particles={"kidnapped_success": 0.0}), 27) == "refuted"


def test_claim29_set_membership():
    assert _verdict(_rep(), 29) == "confirmed"
    assert _verdict(_rep(intervals={"global_success": 0.0}), 29) == "qualified"
    # the truth outside the set although no error exceeded its bound: the guarantee broken
    assert _verdict(_rep(intervals={"global_success": 0.0, "coverage_3s": 0.9}), 29) == "refuted"


# --- 28: active localization ---------------------------------------------------------------


def _active(e: tuple[float, float, float, float], r: tuple[float, float, float, float]) -> dict:
    def row(v: tuple[float, float, float, float]) -> dict:
        return {"success_rate": v[0], "success_low": v[1], "success_high": v[2], "median_steps": v[3],
                "mean_steps": v[3], "localized_by_step": [0.0, v[0]]}

    return _doc(a=("active_localization", {"n_places": 62, "n_runs": 200, "n_steps": 30, "entropy": row(e),
                                           "random": row(r), "fixed": row(r)}))  # fmt: skip


def test_claim28_active():
    assert _verdict(_active((0.9, 0.85, 0.94, 7), (0.2, 0.15, 0.26, 16)), 28) == "confirmed"
    assert _verdict(_active((0.9, 0.85, 0.94, 20), (0.2, 0.15, 0.26, 16)), 28) == "qualified"
    assert _verdict(_active((0.2, 0.15, 0.26, 20), (0.2, 0.15, 0.26, 16)), 28) == "refuted"


# --- reading ---------------------------------------------------------------------------------


def test_without_studies_the_claims_are_not_measured_naming_the_kind():
    claims = {c.number: c for c in evaluate_claims({})}
    for n in [*range(13, 30), *range(35, 39)]:
        assert claims[n].verdict == "not measured"
        assert "needs a study of kind" in claims[n].reason


def test_renaming_the_studies_keeps_every_verdict_and_number():
    doc = _rep()
    renamed = copy.deepcopy(doc)
    renamed["studies"] = {"other_name": renamed["studies"].pop("r")}
    renamed["summary"]["skalka"]["representations"] = ["other_name"]
    for n in (23, 24, 25, 26, 27, 29):
        a, b = evaluate_claim({}, n, doc), evaluate_claim({}, n, renamed)
        assert (a.verdict, a.numbers) == (b.verdict, b.numbers)


def test_write_claims_reads_the_studies_document(tmp_path: Path):
    p = tmp_path / "studies.json"
    p.write_text(json.dumps(_rep()), encoding="utf-8")
    doc = json.loads(write_claims({}, tmp_path / "claims.json", studies=p).read_text(encoding="utf-8"))
    verdicts = {c["number"]: c["verdict"] for c in doc["claims"]}
    assert verdicts[23] == "confirmed"
    assert verdicts[13] == "not measured"
    assert all(math.isfinite(v) for c in doc["claims"] if c["number"] == 23 for v in c["numbers"].values())


# --- 35–37: people not on the map (dynamic_environment) -----------------------------------


def _dyn_model(success: float, rms: float, lost: float = 0.0, used: float = 1.0) -> dict:
    return {"success_rate": success, "success_low": max(0.0, success - 0.2), "success_high": min(1.0, success + 0.2),
            "rms_position_error": rms, "median_final_error": rms, "lost_rate": lost, "beams_used": used}


def _dyn_row(n: int, hit: tuple, mix: tuple, filt: tuple) -> dict:
    f = {"hit_only": _dyn_model(*hit), "mixture": _dyn_model(*mix), "distance_filter": _dyn_model(*filt)}
    return {"n_obstacles": n, "blocked_share": 0.02 * n, "odometry_success": 0.0, "obstacle_area_share": 0.01 * n,
            "particle": copy.deepcopy(f), "histogram": copy.deepcopy(f)}


def _dyn(few: dict, many: dict) -> dict:
    # rows out of order: the claims sort them by the number of people
    return _doc(d=("dynamic_environment", {"densities": [0, 10], "rows": [many, few], "repeat": 5, "n_steps": 100,
                                          "n_beams": 12, "room_area": 80.0}))


def test_claim35_short_components():
    ok, bad = (1.0, 0.05), (0.0, math.nan, 1.0)
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, bad, ok, ok)), 35) == "confirmed"
    # the model without the components fails without people too: qualified
    assert _verdict(_dyn(_dyn_row(0, bad, ok, ok), _dyn_row(10, bad, ok, ok)), 35) == "qualified"
    one = _dyn_row(10, bad, ok, ok)
    one["histogram"]["mixture"] = _dyn_model(0.5, 0.3)
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), one), 35) == "qualified"
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, ok, ok, ok)), 35) == "refuted"  # both work
    c = evaluate_claim({}, 35, _dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, bad, ok, ok)))
    assert c.numbers["particle.mixture_success"] == 1.0
    assert c.numbers["histogram.hit_only_success"] == 0.0


def test_claim36_robustness_fails_in_crowds():
    ok = (1.0, 0.05)
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, ok, (0.5, 0.06), ok)), 36) == "confirmed"  # −50 points
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, ok, (1.0, 0.11), ok)), 36) == "confirmed"  # RMS ×2.2
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, ok, (0.9, 0.09), ok)), 36) == "refuted"
    mixed = _dyn_row(10, ok, ok, ok)
    mixed["particle"]["mixture"] = _dyn_model(0.2, 1.0)
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), mixed), 36) == "qualified"
    c = evaluate_claim({}, 36, _dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, ok, (0.5, 0.1), ok)))
    assert c.numbers["particle.success_drop"] == pytest.approx(0.5)
    assert c.numbers["histogram.rms_ratio"] == pytest.approx(2.0)


def test_claim37_distance_filter():
    ok = (1.0, 0.05)
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, ok, (0.6, 0.2), (0.9, 0.1, 0.0, 0.8))), 37) == "confirmed"
    # within 10 % of the mixture's RMS error counts as no worse; beyond it, worse
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, ok, (1.0, 0.1), (1.0, 0.109))), 37) == "confirmed"
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), _dyn_row(10, ok, (1.0, 0.1), (1.0, 0.111))), 37) == "refuted"
    mixed = _dyn_row(10, ok, (0.6, 0.2), (0.9, 0.1))
    mixed["histogram"]["distance_filter"] = _dyn_model(0.4, 0.3)
    assert _verdict(_dyn(_dyn_row(0, ok, ok, ok), mixed), 37) == "qualified"


def test_claims35_37_need_two_numbers_of_people():
    one = _doc(d=("dynamic_environment", {"densities": [5], "rows": [_dyn_row(5, (1, 0.1), (1, 0.1), (1, 0.1))]}))
    for n in (35, 36, 37):
        c = evaluate_claim({}, n, one)
        assert c.verdict == "not measured"
        assert "two numbers of people" in c.reason
        assert evaluate_claim({}, n, {}).verdict == "not measured"


# --- 38: scan matching (scan_matching) -----------------------------------------------------------


def _matching(ekf_rms: float, pf_rms: float, along: float, across: float, ekf_fail: float = 0.0) -> dict:
    def row(rms: float, fail: float) -> dict:
        return {"rms_position_error": rms, "rms_final_along": rms, "failure_rate": fail, "failure_low": 0.0,
                "failure_high": min(1.0, fail + 0.5)}

    ekf_room, ekf_cor = row(ekf_rms, ekf_fail), row(0.04, 0.0)
    ekf_room.update(match_sigma_x=0.03, match_sigma_y=0.03)
    ekf_cor.update(match_sigma_x=along, match_sigma_y=across)
    return _doc(m=("scan_matching", {"repeat": 3, "room": {"n_steps": 10, "ekf_matching": ekf_room,
                                                            "particle": row(pf_rms, 0.0)},
                                      "corridor": {"n_steps": 10, "ekf_matching": ekf_cor, "particle": row(0.05, 0.0)}}))


def test_claim38_scan_matching():
    assert _verdict(_matching(0.0185, 0.0179, 0.303, 0.028), 38) == "confirmed"
    # worse than the particle filter beyond the ratio, or failing more often: qualified
    assert _verdict(_matching(0.03, 0.0179, 0.303, 0.028), 38) == "qualified"
    assert _verdict(_matching(0.0185, 0.0179, 0.303, 0.028, ekf_fail=1 / 3), 38) == "qualified"
    # the corridor fixed along it as well as across: qualified; both parts fail: refuted
    assert _verdict(_matching(0.0185, 0.0179, 0.05, 0.028), 38) == "qualified"
    assert _verdict(_matching(0.03, 0.0179, 0.05, 0.028), 38) == "refuted"
