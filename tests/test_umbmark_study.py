"""The pipeline's UMBmark study: its log, its recovered-vs-true table, its figure drawn from the log alone."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.analysis import studies as st
from pose_uncertainty.analysis import umbmark as um
from pose_uncertainty.experiments.study import read_study, run_study, study_params
from pose_uncertainty.methods import systematic as sy
from pose_uncertainty.present.pipeline_figures import (
    STUDY_FIGURES,
    render_study_figure,
    umbmark_figure,
)

STUDY = {"study": "umbmark", "n": 4, "n_boot": 100, "dt": 0.05, "seed": 9}


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return run_study("umbmark", STUDY, tmp_path_factory.mktemp("umb") / "umbmark.json")


def test_umbmark_is_a_configurable_study() -> None:
    kind, params = study_params("u", STUDY)
    assert kind == "umbmark"
    assert st.STUDIES["umbmark"] is um.umbmark_experiment
    assert params["side"] == 4.0
    assert params["n"] == 4
    with pytest.raises(ValueError, match=r"studies\.u\.wobble"):
        study_params("u", {**STUDY, "wobble": 1})


def test_logged_estimates_equal_umbmark_on_the_logged_returns(log: Path) -> None:
    """Second route: analysis.umbmark.umbmark on the return errors read back from the log."""
    doc = read_study(log)
    res, p = doc["results"], doc["params"]
    before = {d: np.asarray(v) for d, v in res["before"].items()}
    after = {d: np.asarray(v) for d, v in res["after"].items()}
    again = um.umbmark(before, p["side"], p["track"], np.random.default_rng([p["seed"], 1]), level=p["level"],
                       n_boot=p["n_boot"], after=after)  # fmt: skip
    assert json.loads(json.dumps(again.as_dict())) == res["umbmark"]
    for row in res["recovered"]:
        e = again.estimates[row["quantity"]]
        assert row["estimate"] == e.value
        assert row["delta_ci"] == list(e.delta)
        assert row["delta_covers"] == (e.delta[0] <= row["true"] <= e.delta[1])
    for d in sy.DIRECTIONS:
        assert res["centres_before"][d] == before[d].mean(axis=0).tolist()
        assert res["centres_after"][d] == after[d].mean(axis=0).tolist()


def test_logged_runs_are_the_simulator_with_the_logged_geometries(log: Path) -> None:
    """The before runs: the nominal odometry; the after runs: the corrected geometry the log records."""
    doc = read_study(log)
    res, p = doc["results"], doc["params"]
    true = sy.WheelGeometry.from_ratios(p["track"], p["E_d"], p["E_b"])
    drive = {"k_r": p["k"], "k_l": p["k"], "speed": p["speed"], "angular_speed": p["angular_speed"], "dt": p["dt"]}
    before = sy.umbmark_runs(p["side"], true, sy.WheelGeometry(p["track"]), p["n"],
                             np.random.default_rng(p["seed"]), **drive)  # fmt: skip
    corrected = sy.WheelGeometry(**res["corrected"])
    after = sy.umbmark_runs(p["side"], true, corrected, p["n"], np.random.default_rng([p["seed"], 2]), **drive)
    for d in sy.DIRECTIONS:
        assert res["before"][d] == before[d].tolist()
        assert res["after"][d] == after[d].tolist()
    # the corrected geometry is UMBmark's c_R, c_L and E_b·b
    est = res["umbmark"]["estimates"]
    assert_allclose([corrected.scale_r, corrected.scale_l, corrected.track],
                    [est["c_R"]["value"], est["c_L"]["value"], est["track_corrected"]["value"]], rtol=1e-12)


def test_true_quantities_are_what_a_noiseless_square_gives_the_direct_fit() -> None:
    """Second route to the truth: the direct fit on noiseless centres recovers E_d, E_b; α, β from the geometry."""
    side, track, E_d, E_b = 4.0, 0.3, 1.002, 1.01
    t = um.true_quantities(side, track, E_d, E_b)
    g = sy.WheelGeometry.from_ratios(track, E_d, E_b)
    c = {d: sy.return_errors_noiseless(side, d, g.scale_r, g.scale_l, g.track, odometry_track=track)
         for d in sy.DIRECTIONS}  # fmt: skip
    fit = um.direct_fit(c["cw"], c["ccw"], side, track)
    assert_allclose([float(fit[0]), float(fit[1])], [t["E_d_fit"], t["E_b_fit"]], rtol=1e-9)
    # a commanded π/2 turn in place turns (π/2)(c_R + c_L)/2 / E_b = (π/2)/E_b; a leg curves by L(c_R − c_L)/b_true
    assert t["alpha"] == pytest.approx(math.pi / 2 - (math.pi / 2) / E_b, rel=1e-12)
    assert t["beta"] == pytest.approx(side * (g.scale_r - g.scale_l) / (E_b * track), rel=1e-12)
    assert t["E_max_before"] == pytest.approx(max(math.hypot(*c["cw"]), math.hypot(*c["ccw"])), rel=1e-12)


def test_the_correction_shrinks_the_return_errors(log: Path) -> None:
    res = read_study(log)["results"]
    before = res["umbmark"]["estimates"]["E_max_before"]["value"]
    after = res["umbmark"]["E_max_after_measured"]["value"]
    # E_max ≈ 0.48 m of systematic error against a random scatter of a few cm at k = 1e-7 m
    assert after < 0.25 * before
    summary = st.summarize({"umbmark": {"study": "umbmark", "results": res}})["summary"]["umbmark"]
    assert summary["E_max_before"] == before
    assert summary["improvement"] == before / after
    assert summary["n_covered"] == sum(r["delta_covers"] for r in res["recovered"])


def test_umbmark_figure_from_the_log_is_deterministic(log: Path, tmp_path: Path) -> None:
    a = render_study_figure(log, tmp_path / "a.png")
    b = render_study_figure(log, tmp_path / "b.png")
    assert a.read_bytes() == b.read_bytes()
    res = read_study(log)["results"]
    fig = umbmark_figure(res)
    points = [c.get_offsets() for c in fig.axes[0].collections]  # before cw, after cw, before ccw, after ccw
    assert_allclose(points[0], res["before"]["cw"], rtol=0, atol=0)
    assert_allclose(points[3], res["after"]["ccw"], rtol=0, atol=0)
    assert fig.axes[0].get_aspect() == 1.0


def test_a_study_without_a_figure_is_rejected(tmp_path: Path) -> None:
    assert set(STUDY_FIGURES) == {"expcoords_regions", "umbmark"}
    p = run_study("drift", {"study": "number_type_drift", "n_steps": [10]}, tmp_path / "drift.json")
    with pytest.raises(ValueError, match=r"'number_type_drift' study has no figure \(allowed: expcoords_regions, umbmark\)"):
        render_study_figure(p, tmp_path / "x.png")
