"""Claims and the report read the runs' logged parameters, never the labels or the workflow's copy of the config.

* a claim finds its runs by the ``param.*`` columns of its set's table: renaming every run
  label gives the same verdict, numbers and reason, and the figure it links to is the
  renamed run;
* a set that is there but lacks a parameter point a claim reads fails the claims job with
  one line naming the claim, the set and the parameters (not a silent "not measured");
* the report prints a run's parameters from its table row, whatever the manifest says.
"""

from __future__ import annotations

import math
import runpy
import types
from pathlib import Path

import pytest
import test_claims as tc

from pose_uncertainty.core.table_io import write_table
from pose_uncertainty.pipeline.claims import (
    PARAM_RTOL,
    ClaimDataError,
    evaluate_claim,
    evaluate_claims,
)

ROOT = Path(__file__).resolve().parents[1]

#: One fixture per claim that selects runs (the branch-test tables of tests/test_claims.py).
_FIXTURES = {
    2: lambda: tc._shape({"direct": 1.0, "s_curve": 2.0, "right_angles": 3.0},
                         {"direct": 1.0, "s_curve": 3.0, "right_angles": 2.0}),
    3: lambda: tc._profile(1.1),
    4: lambda: tc._parameters(0.1 / math.sqrt(10), 5.0, -5.0),
    5: lambda: tc._cloud(0.98, 0.39, 0.05, 0.3),
    6: lambda: tc._rotation(math.hypot(0.02, 0.01), math.atan2(0.01, 0.02), 0.0),
    8: lambda: tc._speed((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), (1.0, 2.0, 0.5)),
    9: lambda: tc._alpha((0.5, 1.0), (1.0, 0.5), (0.8, 1.0)),
    10: lambda: tc._b1({"straight": 1.5, "arc": 1.2, "rotation": 0.01}, 0.08),
    11: lambda: tc._speed((1.0, 1.0, 1.0), (1.0, 1.5, 1.0), None),
    12: lambda: tc._s001(-0.5, 1e-4, 0.2, 0.1),
}  # fmt: skip


def _renamed(rows: dict) -> tuple[dict, dict]:
    """The tables with every run label replaced (and the rows in reverse order); the old → new map."""
    names: dict[str, str] = {}
    out = {}
    for set_name, table in rows.items():
        new = []
        for i, r in enumerate(table):
            names[r["run"]] = f"renamed_{set_name}_{i}"
            new.append({**r, "run": names[r["run"]]})
        out[set_name] = new[::-1] if set_name != "B3_speed" else new  # claim 8 quotes the speeds in table order
    return out, names


@pytest.mark.parametrize("number", sorted(_FIXTURES))
def test_renaming_the_run_labels_keeps_the_verdict_and_numbers(number: int) -> None:
    rows = _FIXTURES[number]()
    before = evaluate_claim(rows, number)
    assert before.verdict != "not measured"
    renamed, names = _renamed(rows)
    after = evaluate_claim(renamed, number)
    assert (after.verdict, after.reason) == (before.verdict, before.reason)
    assert after.numbers == before.numbers  # the same runs: the same numbers, bit for bit
    if before.figure is not None and before.figure["run"] is not None:
        assert after.figure == {**before.figure, "run": names[before.figure["run"]]}


def test_a_float_parameter_matches_to_a_relative_tolerance() -> None:
    rows = tc._parameters(0.1 / math.sqrt(10), 5.0, -5.0)
    exact = evaluate_claim(rows, 4)
    for r in rows["A3_parameters"]:  # as a float written with other rounding would read back
        r["param.k_r"] *= 1 + PARAM_RTOL / 10
    assert evaluate_claim(rows, 4).numbers == exact.numbers
    rows["A3_parameters"][2]["param.k_r"] *= 1 + 1e-6  # another parameter point: not the run claim 4 reads
    with pytest.raises(ClaimDataError, match=r"k_r = 0\.0009, k_l = 0\.0001, trajectory\.track = 0\.2"):
        evaluate_claim(rows, 4)


def test_a_missing_parameter_point_fails_loudly_naming_it() -> None:
    rows = tc._parameters(0.1 / math.sqrt(10), 5.0, -5.0)
    rows["A3_parameters"] = [r for r in rows["A3_parameters"] if r["param.k_r"] != 9e-4]
    with pytest.raises(ClaimDataError) as err:
        evaluate_claims(rows)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg == ("claim 4 (robot_parameters): the set A3_parameters has no run with "
                   "k_r = 0.0009, k_l = 0.0001, trajectory.track = 0.2")  # fmt: skip
    # a set that is not in the config at all: "not measured", as before
    assert evaluate_claim({}, 4).verdict == "not measured"


def test_two_runs_at_one_parameter_point_are_an_error_too() -> None:
    rows = tc._cloud(0.98, 0.39, 0.05, 0.3)
    rows["A4_distribution"].append({**rows["A4_distribution"][0], "run": "again"})
    with pytest.raises(ClaimDataError, match=r"^claim 5 .*has 2 runs with monte_carlo.regime = 'per_step' "
                                             r"\(per_step, again\); the claim reads one$"):
        evaluate_claim(rows, 5)


def test_the_claims_job_exits_with_one_line(tmp_path: Path) -> None:
    """workflow/scripts/evaluate_claims.py, run as Snakemake runs it: exit 1, one line, no claims.json."""
    rows = tc._speed((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), None)["B3_speed"]
    table = write_table([{**r, "param.trajectory.name": "rotation"} for r in rows], tmp_path / "B3_speed.csv")
    out, log = tmp_path / "claims.json", tmp_path / "claims.log"
    sm = types.SimpleNamespace(
        input=types.SimpleNamespace(tables=[str(table)], loc_tables=[], robot_tables=[]), output=[str(out)], log=[str(log)],
        params=types.SimpleNamespace(sets=["B3_speed"], loc_sets=[], robot_sets=[]))  # fmt: skip
    with pytest.raises(SystemExit) as err:
        runpy.run_path(str(ROOT / "workflow/scripts/evaluate_claims.py"), init_globals={"snakemake": sm})
    line = "evaluate_claims: claim 8 (velocity_speed_no_effect): the set B3_speed has no run with trajectory.name = 'straight'"
    assert err.value.code == line
    assert log.read_text(encoding="utf-8") == line + "\n"
    assert not out.exists()


# --- the report ----------------------------------------------------------------------------


def test_logged_params_nest_the_param_columns() -> None:
    from pose_uncertainty.present.report import logged_params

    row = {"run": "x", "seed": 3, "param.k_r": 5e-4, "param.trajectory.name": "arc", "param.trajectory.track": 0.2,
           "param.maps": '[{"name": "velocity", "alphas": [0.05, 0.05]}]', "param.drive.type": None, "A_sigma_along": 1.0}
    assert logged_params(row) == {"seed": 3, "k_r": 5e-4, "trajectory": {"name": "arc", "track": 0.2},
                                  "maps": [{"name": "velocity", "alphas": [0.05, 0.05]}]}  # fmt: skip


def test_the_report_prints_the_logged_parameters_not_the_manifests(tmp_path: Path) -> None:
    from pose_uncertainty.experiments.run import RunConfig, execute
    from pose_uncertainty.pipeline.claims import write_claims
    from pose_uncertainty.pipeline.summary import summarize_pipeline
    from pose_uncertainty.pipeline.tables import collect_table
    from pose_uncertainty.present.report import build_report
    from pose_uncertainty.records.run import write_run

    cfg = {"name": "b0.2", "seed": 5, "k_r": 9e-4, "k_l": 1e-4, "n_ellipses": 2, "monte_carlo": {"n_particles": 0},
           "trajectory": {"name": "straight", "length": 0.5, "dt": 0.1, "speed": 0.5, "track": 0.2}}
    log = write_run(tmp_path / "b0.2.mcap", execute(RunConfig.from_dict(cfg)))
    table = collect_table("S", [log], None, tmp_path / "S.csv")
    # the manifest names the swept keys; its values (and any config it might carry) are not what the run logged
    run = {"id": "b0.2", "log": str(log), "swept": {"trajectory": {"track": 0.5}, "k_r": 0.0123}, "figures": {}}
    manifest = {"sets": [{"name": "S", "title": "S", "source": "", "description": "", "table": str(table),
                          "figures": {}, "runs": [run]}], "config": {}}  # fmt: skip
    html = build_report(manifest, {"S": table}, write_claims({"S": table}, tmp_path / "claims.json"),
                        summarize_pipeline({"S": table}, [], [], tmp_path / "pipeline.json"),
                        tmp_path / "r.html").read_text(encoding="utf-8")  # fmt: skip
    # the set's section: its parameters (one run: every parameter is the set's) and the run's entry
    details = html[html.index('<details class="shared" id="params-S">'):]
    details = details[:details.index("</ul>")]
    assert 'trajectory = {"track": 0.2}; k_r = 0.0009' in details  # the swept keys, with the logged values
    assert "<tr><th>k_r</th><td>0.0009</td></tr>" in details
    assert "<tr><th>k_l</th><td>0.0001</td></tr>" in details
    assert "<tr><th>trajectory.track</th><td>0.2</td></tr>" in details
    assert '"track": 0.5' not in details
    assert ">0.5<" not in details.split("trajectory.track")[1][:30]
    assert "0.0123" not in details
    assert "<tr><th>seed</th><td>5</td></tr>" in details


def test_a_swept_list_of_maps_is_shown_with_its_swept_keys_and_logged_values() -> None:
    from pose_uncertainty.present.report import _with_row

    row = {"run": "a12", "seed": 7, "param.maps": '[{"name": "velocity", "alphas": [0.005, 0.05], "size": 2.0}]'}
    run = {"id": "a12", "swept": {"maps": [{"name": "velocity", "alphas": [0.5, 0.5]}]}}
    assert _with_row(run, row)["swept"] == {"maps": [{"name": "velocity", "alphas": [0.005, 0.05]}]}
