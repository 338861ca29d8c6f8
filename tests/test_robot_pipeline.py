"""The pipeline's robots section: its keys, its two jobs and the report's section "Your robot".

* the section's keys are checked by their key table (one-line errors naming the dotted key);
* the simulation job logs the true values with units, the calibration job writes every output,
  and its recovered-against-true check equals a second route from the two logs alone;
* the report's section formats those logs: every value it shows is a logged one, the YAML files
  verbatim, no development words, every internal link resolving;
* on the quick pipeline the section is in reports/comparison.html and the robots' table holds
  every robot of the config.
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import pytest
from markupsafe import escape

from pose_uncertainty.experiments.robot_config import robots_config
from pose_uncertainty.robot.fit import CALIBRATION_KEYS
from pose_uncertainty.robot.simulated import SimulatedRobot

OUTPUTS = ("calibration.json", "ros2_control.yaml", "nav2_amcl.yaml", "robot_localization.yaml", "horizon.json",
           "report.html", "recovery.json", "drive.png", "growth.png", "horizon.png")  # fmt: skip


def test_the_robots_keys_are_checked_by_their_table() -> None:
    full = robots_config({"seed": 11, "robots": {"runs": {"r": {"drive": {"laps": 2}}}}})
    assert full["r"]["seed"] == 11  # null: the config's seed
    assert full["r"]["simulate"] == {k: getattr(SimulatedRobot(), k) for k in full["r"]["simulate"]}
    assert full["r"]["drive"] == {"side": 2.0, "laps": 2, "arcs": 2}
    assert full["r"]["title"] == "r"
    assert robots_config({"robots": {"enabled": False, "runs": {"r": {}}}}) == {}
    for bad, match in (
        ({"r": {"simulate": {"track": 0}}}, r"'robots\.runs\.r\.simulate\.track' must be > 0"),
        ({"r": {"drive": {"laps": 0}}}, r"'robots\.runs\.r\.drive\.laps'"),
        ({"r": {"bagg": "x"}}, r"unknown config key\(s\) 'robots\.runs\.r\.bagg' \(allowed: title, "),
        ({"r": {"bag": 3}}, r"'robots\.runs\.r\.bag' must be a path"),
        ({"r": {"seed": -1}}, r"robots\.runs\.r\.seed"),
    ):
        with pytest.raises(ValueError, match=match):
            robots_config({"robots": {"runs": bad}})


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    from pose_uncertainty.pipeline.robots import calibrate_robot, simulate_robot

    d = tmp_path_factory.mktemp("robot_job")
    spec = robots_config({"seed": 5, "robots": {"runs": {"sim": {"drive": {"laps": 2, "arcs": 1},
                                                                  "title": "Simulated", "source": "Borenstein & Feng 1996"}}}})["sim"]  # fmt: skip
    simulate_robot(spec, d / "bag.mcap", d / "truth.json")
    calibrate_robot(spec, d / "bag.mcap", d / "out", d / "truth.json")
    return d, spec


@pytest.mark.slow
def test_the_jobs_log_the_truth_and_check_it_a_second_way(calibrated: tuple[Path, dict]) -> None:
    d, spec = calibrated
    assert sorted(p.name for p in (d / "out").iterdir()) == sorted(OUTPUTS)
    truth = json.loads((d / "truth.json").read_text())
    robot = SimulatedRobot(**spec["simulate"])
    assert truth["truth"]["E_d"] == {"value": robot.radius_right / robot.radius_left, "unit": "1"}
    assert truth["truth"]["k_l"] == {"value": robot.k_l, "unit": "m"}
    assert truth["units"]["simulate"]["truth_heading_std"] == "rad"
    assert truth["simulate"] == spec["simulate"]
    assert {k: getattr(robot, k) for k in truth["simulate"]} == {k: v for k, v in dataclasses.asdict(robot).items() if k in truth["simulate"]}
    cal = json.loads((d / "out/calibration.json").read_text())
    rec = json.loads((d / "out/recovery.json").read_text())
    # second route: the interval check from the two logs alone
    for q in CALIBRATION_KEYS:
        t = truth["truth"][q]["value"]
        lo, hi = cal[q]["ci95"]
        assert rec["quantities"][q] == {"true": t, "value": cal[q]["value"], "ci95": [lo, hi], "unit": cal[q]["unit"],
                                        "covers": lo <= t <= hi}  # fmt: skip
    assert rec["n_covered"] == sum(rec["quantities"][q]["covers"] for q in CALIBRATION_KEYS)
    hz = json.loads((d / "out/horizon.json").read_text())
    assert hz["units"]["distance"] == "m"
    assert hz["n_mc"] > 0
    assert cal["provenance"]["package_version"]
    # UMBmark on the recorded squares uses every lap driven
    assert cal["umbmark"]["laps"] == {"cw": 2, "ccw": 2}


@pytest.mark.slow
def test_the_report_section_formats_the_logs(calibrated: tuple[Path, dict]) -> None:
    from test_report_document import report_words, small_report_inputs, unresolved_links

    from pose_uncertainty.present import report as rp

    d, spec = calibrated
    files = {f: str(d / "out" / f) for f in OUTPUTS}
    robots = [{"name": "sim", "title": spec["title"], "source": spec["source"], "description": "", "simulated": True,
               "dir": str(d / "out"), "files": files}]  # fmt: skip
    out = rp.build_report(*small_report_inputs(d), d / "r.html", robots=robots)
    page = out.read_text(encoding="utf-8")
    assert report_words(page) == []
    assert unresolved_links(page, out.parent) == []
    section = page[page.index('<h2 id="your-robot">'):page.index('<h2 id="references">')]
    cal = json.loads((d / "out/calibration.json").read_text())
    rec = json.loads((d / "out/recovery.json").read_text())
    table = section[section.index('id="robot-sim-parameters"'):section.index("</table>")]
    rows = re.findall(r"<tr><td>.*?</tr>", table, re.DOTALL)
    assert len(rows) == len(CALIBRATION_KEYS)
    for q, row in zip(CALIBRATION_KEYS, rows, strict=True):
        cells = re.findall(r'<td class="n">([^<]*)</td>', row)
        assert cells[0] == rp._fmt(rec["quantities"][q]["true"], 6)
        assert cells[1] == rp._fmt(cal[q]["value"], 6)
        assert cells[3] == f"{rp._fmt(cal[q]['ci95'][0], 6)} – {rp._fmt(cal[q]['ci95'][1], 6)}"
        assert row.rstrip().endswith(f"<td>{'yes' if rec['quantities'][q]['covers'] else 'no'}</td></tr>")
    for name in ("ros2_control.yaml", "nav2_amcl.yaml", "robot_localization.yaml"):
        assert str(escape((d / "out" / name).read_text())) in section  # verbatim (escaped as the page escapes), to paste
    assert re.search(r'id="fig-robot-sim-horizon"[^>]*><img src="data:image/webp;base64,', section)
    assert f"{rec['n_covered']} of 7 95 % intervals hold" in section
    assert '<a href="#your-robot">' in page  # in the contents


@pytest.mark.slow  # reads the quick pipeline's build
def test_the_quick_report_has_the_robot_section(tmp_path_factory: pytest.TempPathFactory) -> None:
    from test_pipeline import _config, quick_pipeline

    from pose_uncertainty.core.table_io import read_table

    quick = quick_pipeline(tmp_path_factory.getbasetemp())
    names = list(_config("quick.yaml")["robots"]["runs"])
    rows = read_table(quick / "reports/tables/robots/robots.csv")
    assert [r["robot"] for r in rows] == names
    for name in names:
        assert all((quick / f"data/robots/{name}/{f}").is_file() for f in OUTPUTS)
        cal = json.loads((quick / f"data/robots/{name}/calibration.json").read_text())
        row = next(r for r in rows if r["robot"] == name)
        assert all(row[q] == cal[q]["value"] for q in CALIBRATION_KEYS)  # the table holds the logged values
    page = (quick / "reports/comparison.html").read_text(encoding="utf-8")
    assert '<h2 id="your-robot">' in page
    assert all(f'id="robot-{name}-parameters"' in page for name in names)
    claims = {c["number"]: c for c in json.loads((quick / "reports/claims.json").read_text())["claims"]}
    assert all(claims[n]["verdict"] != "not measured" for n in range(30, 35)), claims
