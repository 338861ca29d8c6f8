"""The summary views of a large set (more runs than report.summary_above), drawn from its table alone.

``config/sweep200.yaml`` (200 small runs, two chunk jobs) is run end to end; its set is shown by its
summary (axes, Sobol indices, partial dependence, response surfaces) instead of per-run figures,
and its table is a CSV file beside the report. The summary is checked by a second route: the
first-order index and the partial dependence recomputed from the CSV's rows with plain Python
grouping, and the total index of an axis no logged measure depends on (``n_ellipses`` only
changes the figures) is 0.
"""

from __future__ import annotations

import json
import shutil
from collections import defaultdict
from pathlib import Path

import pytest
from test_pipeline import SCHEMA, _config, _planned_jobs, copy_workflow, snakemake

from pose_uncertainty.core.table_io import read_table
from pose_uncertainty.experiments import sweep
from pose_uncertainty.pipeline.sweep_summary import sweep_summary

SET = "SWEEP_quick"


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    work = copy_workflow(tmp_path_factory.mktemp("sweep200"))
    proc = snakemake(work, "--configfile", "config/sweep200.yaml", timeout=1200)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return work


@pytest.mark.slow
def test_a_large_set_is_summarised_from_its_table_alone(built: Path) -> None:
    config = sweep.validate_config(_config("sweep200.yaml"), SCHEMA)
    n = len(sweep.expand_all(config)[SET])
    assert n == 200 > config["report"]["summary_above"]
    rows = read_table(built / f"reports/tables/{SET}.csv")
    summary = json.loads((built / f"reports/tables/{SET}.sweep.json").read_text(encoding="utf-8"))
    assert summary == json.loads(json.dumps(sweep_summary(rows, SET)))  # the CSV holds all it needs
    assert summary["n_runs"] == n
    assert summary["full_factorial"]
    # the axes in the table's column order, each with its levels
    axis = {a["name"]: i for i, a in enumerate(summary["axes"])}
    assert {a["name"]: len(a["levels"]) for a in summary["axes"]} == {"trajectory": 4, "k_r": 5, "k_l": 5, "n_ellipses": 2}
    assert summary["measures"], "no measure summarised"

    # second route: group the CSV's rows by each axis's columns in plain Python
    for m in summary["measures"]:
        y = [float(r[m["name"]]) for r in rows]
        mean = sum(y) / n
        var = sum((v - mean) ** 2 for v in y) / n
        for a, ax in enumerate(summary["axes"]):
            groups: dict[tuple, list[float]] = defaultdict(list)
            for r, v in zip(rows, y, strict=True):
                groups[tuple(json.dumps(r.get(c)) for c in ax["columns"])].append(v)
            means = [sum(g) / len(g) for g in groups.values()]
            first = sum(len(g) * (mu - mean) ** 2 for g, mu in zip(groups.values(), means, strict=True)) / n / var
            assert m["first"][a] == pytest.approx(first, abs=1e-9), (m["name"], ax["name"])
            assert sorted(m["dependence"][a]) == pytest.approx(sorted(means), rel=1e-12)
            assert m["first"][a] <= m["total"][a] + 1e-12
        # the figures' axis: no measure depends on it
        assert m["total"][axis["n_ellipses"]] == pytest.approx(0.0, abs=1e-12), m["name"]
    # k_r and k_l scale the wheels' variances: Method A's spread depends on them
    sigma = next(m for m in summary["measures"] if m["name"] == "A_sigma_across")
    assert sigma["total"][axis["k_r"]] > 0.01, sigma
    assert sigma["total"][axis["k_l"]] > 0.01, sigma

    # the logs are not read: without them the summary is made again, the same
    shutil.rmtree(built / "data/runs")
    proc = snakemake(built, "--configfile", "config/sweep200.yaml", "--forcerun", "summarize_sweep",
                     f"reports/tables/{SET}.sweep.json")  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    again = json.loads((built / f"reports/tables/{SET}.sweep.json").read_text(encoding="utf-8"))
    assert again == summary


@pytest.mark.slow
def test_the_report_shows_the_summary_and_links_the_table_instead_of_every_run(built: Path) -> None:
    html = (built / "reports/comparison.html").read_text(encoding="utf-8")
    rows = read_table(built / f"reports/tables/{SET}.csv")
    assert f'href="tables/{SET}.csv"' in html
    assert (built / f"reports/tables/{SET}.csv").is_file()
    assert f'id="fig-{SET}-sweep_heatmaps"' in html
    assert f'id="fig-{SET}-sweep_dependence"' in html
    assert not (built / f"reports/figures/{SET}/runs").exists()  # no per-run figures drawn
    # 20 of the 200 runs named (the preview), none with its own figure section
    named = [r["run"] for r in rows if f"<td>{r['run']}</td>" in html]
    assert len(named) == 20, len(named)
    assert f'id="run-{SET}-' not in html
    assert "Sobol indices" in html


@pytest.mark.slow  # a Snakemake dry run of the 200-run sweep
def test_the_summary_counts_the_chunk_jobs_and_the_summary_job(tmp_path: Path) -> None:
    work = copy_workflow(tmp_path / "w")
    jobs = _planned_jobs(snakemake(work, "--configfile", "config/sweep200.yaml", "--dry-run"))
    assert jobs.get("simulate_chunk_SWEEP_quick_0") == 1, jobs
    assert jobs.get("simulate_chunk_SWEEP_quick_1") == 1, jobs
    assert jobs.get("summarize_sweep") == 1, jobs
    assert "render_run_figures" not in jobs, jobs
