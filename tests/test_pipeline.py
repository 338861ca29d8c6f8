"""The Snakemake pipeline: config validation, sweep expansion, the quick config end to end.

The end-to-end tests run ``snakemake`` on a copy of the workflow (Snakefile,
workflow/, config/) in a temporary directory with ``config/quick.yaml``; the run
is shared by every test of the session through :func:`quick_pipeline` (the
browser test opens the same report).
"""

from __future__ import annotations

import base64
import copy
import io
import json
import math
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from pose_uncertainty.core.schema import load_schema
from pose_uncertainty.core.table_io import read_table
from pose_uncertainty.experiments import sweep
from pose_uncertainty.pipeline import jobs
from pose_uncertainty.pipeline.claims import VERDICTS

REPO = Path(__file__).resolve().parents[1]
SNAKEMAKE = Path(sys.executable).with_name("snakemake")
SCHEMA = load_schema(REPO / "workflow/schemas/config.schema.yaml")


def _config(name: str = "config.yaml") -> dict:
    return yaml.safe_load((REPO / "config" / name).read_text(encoding="utf-8"))


def copy_workflow(dest: Path) -> Path:
    """Copy what the pipeline needs (Snakefile, workflow/, config/, environment.lock) into ``dest``."""
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copy2(REPO / "Snakefile", dest / "Snakefile")
    shutil.copy2(REPO / "environment.lock", dest / "environment.lock")
    for d in ("workflow", "config"):
        shutil.copytree(REPO / d, dest / d, dirs_exist_ok=True)
    return dest


def snakemake(workdir: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    """Run the venv's snakemake in ``workdir`` with the default profile and 2 cores."""
    cmd = [str(SNAKEMAKE), "--profile", "workflow/profiles/default", "--cores", "2", *args]
    return subprocess.run(cmd, cwd=workdir, capture_output=True, text=True, timeout=timeout, check=False)


def quick_pipeline(base: Path) -> Path:
    """The quick config run end to end once per session in ``base/quick``; returns the work dir.

    Writes ``base/quick/run.json`` with the wall-clock time of the first run.
    """
    work = base / "quick"
    stamp = work / "run.json"
    if stamp.is_file():
        return work
    copy_workflow(work)
    t0 = time.perf_counter()
    proc = snakemake(work, "--configfile", "config/quick.yaml")
    elapsed = time.perf_counter() - t0
    assert proc.returncode == 0, f"quick pipeline failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}"
    stamp.write_text(json.dumps({"seconds": elapsed}), encoding="utf-8")
    return work


@pytest.fixture(scope="session")
def quick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return quick_pipeline(tmp_path_factory.getbasetemp())


# --- config validation and sweep expansion (fast) ------------------------------------------


@pytest.mark.parametrize("name", ["config.yaml", "quick.yaml"])
def test_shipped_configs_validate(name: str) -> None:
    full = sweep.validate_config(_config(name), SCHEMA)
    sets = sweep.expand_all(full)
    assert sets, "no experiment sets"
    for set_name, runs in sets.items():
        ids = [r.id for r in runs]
        assert len(ids) == len(set(ids)), f"{set_name}: duplicate run ids"
        for r in runs:
            assert re.fullmatch(r"[A-Za-z0-9_.-]+", r.id), r.id
            assert r.config["name"] == r.id


def test_default_config_holds_every_experiment_of_the_theses() -> None:
    sets = sweep.expand_all(sweep.validate_config(_config(), SCHEMA))
    expected = {
        "A1_shape": 6, "A2_profile": 6, "A3_parameters": 12, "A4_distribution": 2,
        "B1_trajectory": 3, "B2_distance": 6, "B3_speed": 6, "B4_alpha": 10, "S_chassis": 32,
    }
    for name, n in expected.items():
        assert len(sets[name]) == n, name
    assert {"L_straight", "L_circle"} <= set(sets)


def _keys_without(schema: dict) -> list[str]:
    """Config keys (schema properties) lacking a description or a default.

    The keys of a sweep axis are exempt from ``default``: an axis lists the values a
    key takes; a key that is not swept keeps the value of ``base``.
    """
    bad: list[str] = []

    def walk(node: dict, path: str, axis: bool) -> None:
        for key, sub in node.get("properties", {}).items():
            here = f"{path}.{key}" if path else key
            target = sub
            if "$ref" in sub:
                target = SCHEMA["$defs"][sub["$ref"].rsplit("/", 1)[-1]]
            if "description" not in sub and "description" not in target:
                bad.append(here)
            if not axis and "default" not in sub:
                bad.append(here)
            if "$ref" not in sub:
                walk(sub, here, axis)
                if isinstance(sub.get("items"), dict):
                    walk(sub["items"], here + "[]", axis or key == "sweep")

    walk(schema, "", False)
    for name, node in schema["$defs"].items():
        walk(node, f"$defs.{name}", False)
    return bad


def test_every_schema_key_has_description_and_default() -> None:
    assert _keys_without(SCHEMA) == []


def test_sweep_product_of_axes_zip_within() -> None:
    spec = {
        "base": {"trajectory": {"name": "straight", "length": 1.0}},
        "sweep": [
            {"k_r": [1e-4, 2e-4], "k_l": [3e-4, 4e-4]},
            {"trajectory.track": [0.1, 0.2, 0.5]},
        ],
    }
    runs = sweep.expand_set("S", spec)
    assert len(runs) == 2 * 3
    pairs = {(r.config["k_r"], r.config["k_l"], r.config["trajectory"]["track"]) for r in runs}
    assert pairs == {(a, b, t) for a, b in ((1e-4, 3e-4), (2e-4, 4e-4)) for t in (0.1, 0.2, 0.5)}
    assert [r.id for r in runs][:3] == ["kr1e-04_kl3e-04_b0.1", "kr1e-04_kl3e-04_b0.2", "kr1e-04_kl3e-04_b0.5"]
    # the base keys not swept are kept, the builder's defaults are filled in
    assert all(r.config["trajectory"]["length"] == 1.0 for r in runs)
    assert all("dt" in r.config["trajectory"] for r in runs)


def test_run_ids_are_stable_and_depend_only_on_swept_values() -> None:
    spec = {"base": {"trajectory": {"name": "straight"}}, "sweep": [{"trajectory.length": [1.0, 2.5]}]}
    a = [r.id for r in sweep.expand_set("S", spec)]
    spec2 = copy.deepcopy(spec)
    spec2["base"]["k_r"] = 9e-4  # a base change keeps the ids (Snakemake reruns on the params)
    b = [r.id for r in sweep.expand_set("S", spec2)]
    assert a == b == ["L1", "L2.5"]
    assert sweep.expand_set("S", spec)[0].config != sweep.expand_set("S", spec2)[0].config


def test_sweep_merges_identical_runs_and_rejects_id_clashes() -> None:
    spec = {"base": {"trajectory": {"name": "straight"}},
            "sweep": [{"labels": ["a", "a"], "k_r": [1e-4, 1e-4]}]}
    assert len(sweep.expand_set("S", spec)) == 1
    spec["sweep"][0]["k_r"] = [1e-4, 2e-4]
    with pytest.raises(sweep.ConfigError, match=r"experiment_sets\.S\.sweep.*two different runs the id 'a'"):
        sweep.expand_set("S", spec)


def test_unequal_axis_lengths_are_rejected() -> None:
    spec = {"base": {"trajectory": {"name": "straight"}}, "sweep": [{"k_r": [1e-4, 2e-4], "k_l": [1e-4]}]}
    with pytest.raises(sweep.ConfigError, match=r"experiment_sets\.S\.sweep\[0\].*unequal length"):
        sweep.expand_set("S", spec)


@pytest.mark.parametrize(
    ("mutate", "pattern"),
    [
        (lambda c: c["experiment_sets"]["A1_shape"]["base"]["trajectory"].update(profile="wobbly"),
         r"'experiment_sets\.A1_shape\.base\.trajectory\.profile' must be one of 'constant', 'ramp', got 'wobbly'"),
        (lambda c: c.update(seeed=3), r"config key 'seeed' is not allowed.*allowed: only the keys"),
        (lambda c: c["defaults"].update(k_r=-1.0), r"'defaults\.k_r' must be >= 0 \(allowed: \[0, inf\)\), got -1\.0"),
        (lambda c: c["experiment_sets"]["L_straight"]["sweep"][0].update({"trajectory.length": "far"}),
         r"experiment_sets\.L_straight\.sweep\[0\]\.trajectory\.length.*\"far\".*allowed: type array"),
        (lambda c: c["experiment_sets"]["A1_shape"]["base"].update(monte_carlo={"regime": "sometimes"}),
         r"'experiment_sets\.A1_shape\.base\.monte_carlo\.regime' must be one of 'per_step', 'per_run', got 'sometimes'"),
    ],
)
def test_bad_config_names_key_value_and_allowed(mutate, pattern: str) -> None:
    cfg = _config("quick.yaml")
    mutate(cfg)
    with pytest.raises(sweep.ConfigError, match=pattern):
        sweep.validate_config(cfg, SCHEMA)


def test_run_level_errors_name_the_set_and_run() -> None:
    cfg = _config("quick.yaml")
    cfg["experiment_sets"]["A1_shape"]["base"]["trajectory"]["radius"] = 0.3  # a key of arcs, not of a line
    with pytest.raises(sweep.ConfigError, match=r"experiment_sets\.A1_shape, run 'straight'.*'trajectory\.radius'"):
        sweep.validate_config(cfg, SCHEMA)


# --- the pipeline end to end (quick config) -------------------------------------------------


@pytest.mark.slow
def test_bad_config_fails_before_any_rule_runs(tmp_path: Path) -> None:
    work = copy_workflow(tmp_path / "bad")
    cfg = yaml.safe_load((work / "config/quick.yaml").read_text(encoding="utf-8"))
    cfg["experiment_sets"]["A1_shape"]["base"]["trajectory"]["profile"] = "wobbly"
    (work / "config/bad.yaml").write_text(yaml.safe_dump(cfg), encoding="utf-8")
    proc = snakemake(work, "--configfile", "config/bad.yaml", timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "experiment_sets.A1_shape.base.trajectory.profile" in out
    assert "'wobbly'" in out
    assert "'constant', 'ramp'" in out
    assert not (work / "data").exists(), "a rule ran although the config is invalid"


@pytest.mark.slow
def test_a_repeated_key_in_the_config_file_fails_before_any_rule_runs(tmp_path: Path) -> None:
    # Snakemake's own YAML loader would take the second value silently
    work = copy_workflow(tmp_path / "dup")
    text = (work / "config/quick.yaml").read_text(encoding="utf-8")
    (work / "config/dup.yaml").write_text(text + "\nreport:\n  title: again\n", encoding="utf-8")
    proc = snakemake(work, "--configfile", "config/dup.yaml", "-n", timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "dup.yaml" in out
    assert "'report'" in out
    assert not (work / "data").exists()


@pytest.mark.slow
def test_the_default_config_file_is_read_by_the_package_with_config_overrides_on_top(tmp_path: Path) -> None:
    # config/config.yaml is read by the workflow (not by Snakemake's `configfile:`): --config applies on
    # top of it, and a repeated key is refused as in a --configfile
    work = copy_workflow(tmp_path / "default")
    text = (work / "config/quick.yaml").read_text(encoding="utf-8")
    (work / "config/config.yaml").write_text(text, encoding="utf-8")
    proc = snakemake(work, "-n", "--config", "runs_per_job=3", timeout=180)
    assert proc.returncode == 0, proc.stderr[-3000:]
    jobs = _planned_jobs(proc)
    assert "simulate_run" not in jobs, jobs
    assert any(name.startswith("simulate_chunk_") for name in jobs), jobs
    (work / "config/config.yaml").write_text(text + "\nreport:\n  title: again\n", encoding="utf-8")
    proc = snakemake(work, "-n", timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "config.yaml" in out
    assert "'report'" in out


def test_quick_pipeline_end_to_end(quick: Path) -> None:
    from pose_uncertainty.present import figures
    from pose_uncertainty.records.run import open_run

    cfg = sweep.validate_config(_config("quick.yaml"), SCHEMA)
    sets = sweep.expand_all(cfg)
    html = (quick / "reports/comparison.html").read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>")
    # each set's run figures on a companion page of its own beside the report (reports/runs/<set>.html)
    pages = {p.stem: p.read_text(encoding="utf-8") for p in (quick / "reports/runs").glob("*.html")}
    for name, runs in sets.items():
        rows = read_table(quick / f"reports/tables/{name}.csv")
        assert [r["run"] for r in rows] == [r.id for r in runs]
        assert pages[name].startswith("<!DOCTYPE html>")
        for run in runs:
            log = open_run(quick / run.path)
            assert log.config.to_dict() == run.config  # the logged config is the swept one
            assert (quick / f"reports/figures/{name}/runs/{run.id}/trajectory.png").is_file()
            assert f'id="run-{name}-{run.id}"' in html  # its entry in the report
            assert f'href="runs/{name}.html#run-{name}-{run.id}"' in html  # links its figures
            assert f'id="run-{name}-{run.id}"' in pages[name]
            assert f'id="fig-{name}-{run.id}-trajectory"' in pages[name]
            assert f'id="fig-{name}-{run.id}-trajectory"' not in html
    # a pipeline figure has the bytes the replay functions give from the log alone
    run = sets["A1_shape"][0]
    fig = figures.trajectory_figure(open_run(quick / run.path))
    again = quick / "replayed.png"
    figures.save_figure(fig, again)
    assert again.read_bytes() == (quick / f"reports/figures/A1_shape/runs/{run.id}/trajectory.png").read_bytes()
    claims = json.loads((quick / "reports/claims.json").read_text(encoding="utf-8"))["claims"]
    assert [c["number"] for c in claims][:12] == list(range(1, 13))
    assert sorted(c["number"] for c in claims) == list(range(1, 39))
    # Skalka 2011's techniques: measured from the quick config's studies (branches: tests/test_skalka_claims.py)
    skalka = {c["number"]: c for c in claims if 13 <= c["number"] <= 29 or 35 <= c["number"] <= 38}
    assert sorted(skalka) == [*range(13, 30), *range(35, 39)]
    assert all(c["verdict"] != "not measured" for c in skalka.values()), skalka
    assert all(c["verdict"] in VERDICTS for c in claims)
    measured = {c["number"] for c in claims if c["verdict"] != "not measured"}
    assert {1, 2, 3, 6, 7, 10, 12, 30, 31, 32, 33, 34} <= measured, claims
    for c in claims:
        if c["figure"]:
            f = c["figure"]
            fid = f'fig-{f["set"]}-{f["run"] or "set"}-{f["kind"]}'
            if f["run"]:  # a run's figure: on its set's companion page, linked from the claim
                assert f'id="{fid}"' in pages[f["set"]], c
                assert f'href="runs/{f["set"]}.html#{fid}"' in html, c
            else:
                assert f'id="{fid}"' in html, c
    # no network: no http(s) resource references, every image inlined, in the report and its companion pages
    for text in (html, *pages.values()):
        assert not re.search(r'(src|href)="(https?:)?//', text)
        sources = re.findall(r'<img src="([^"]{0,23})', text)
        assert sources
        assert all(s.startswith("data:image/webp;base64,") for s in sources)
    # the inlined WebP has the pixels of the pipeline's PNG exactly (lossless re-encoding)
    fid = f'id="fig-A1_shape-{run.id}-trajectory"><img src="data:image/webp;base64,'
    page = pages["A1_shape"]
    start = page.index(fid) + len(fid)
    webp = base64.b64decode(page[start : page.index('"', start)])
    with Image.open(io.BytesIO(webp)) as inlined, Image.open(
        quick / f"reports/figures/A1_shape/runs/{run.id}/trajectory.png"
    ) as png:
        assert inlined.format == "WEBP"
        assert np.array_equal(np.asarray(inlined.convert("RGB")), np.asarray(png.convert("RGB")))


def test_report_cites_only_what_a_reader_can_look_up(quick: Path) -> None:
    """The generated report has none of the words tests/test_words.py keeps out of the product."""
    from test_report_document import report_pages, report_words
    from test_words import FORBIDDEN

    pages = report_pages(quick / "reports/comparison.html")  # the report and its companion pages
    assert len(pages) > 1
    for path, html in pages.items():
        text = re.sub(r"data:[^\"')\s]+", "data:", html)  # inlined images are not words
        hits = [f"{path.name}:{n}: {kind}: {m.group(0)!r} in {line.strip()[:160]}"
                for n, line in enumerate(text.splitlines(), 1)
                for kind, pattern in FORBIDDEN.items() for m in pattern.finditer(line)]
        assert not hits, "\n".join(hits)
        # and none of our development words (issue, SPEC, seed001 as a document), in the pages' text
        assert report_words(html) == [], path


def test_the_quick_reports_abstract_links_and_references(quick: Path) -> None:
    """Every number of the abstract is the logged value it names; every internal link resolves; the
    sources are cited with full entries."""
    from test_report_document import abstract_mismatches, unresolved_links

    from pose_uncertainty.core.table_io import read_table

    html = (quick / "reports/comparison.html").read_text(encoding="utf-8")
    tables = {f"localization/{p.stem}": read_table(p) for p in (quick / "reports/tables/localization").glob("*.csv")}
    files = {"claims": json.loads((quick / "reports/claims.json").read_text(encoding="utf-8")),
             "studies": json.loads((quick / "reports/studies.json").read_text(encoding="utf-8")), "tables": tables}
    abstract = html[html.index('<section class="abstract"'):html.index("</figcaption></figure>")]
    assert abstract.count('class="num"') >= 8  # 4–6 findings, most with two numbers, and the headline figure's
    assert abstract_mismatches(abstract, files) == []
    # every link resolves: within the report, into its companion pages and back (reports/runs/<set>.html)
    from test_report_document import report_pages

    for path, text in report_pages(quick / "reports/comparison.html").items():
        assert unresolved_links(text, path.parent) == [], path
    for key in ("nemec2012", "safranek2022", "skalka2011", "kulich2014", "motion-lecture", "thrun2005", "long2012"):
        assert f'<li id="ref-{key}">' in html, key
        assert f'href="#ref-{key}"' in html, key


def test_report_has_the_studies_sections(quick: Path) -> None:
    from pose_uncertainty.present.pipeline_figures import render_study_figure

    html = (quick / "reports/comparison.html").read_text(encoding="utf-8")
    for sid in ("studies", "accuracy", "accuracy-distance", "expcoords", "fig-studies-expcoords",
                "growth-laws", "regimes", "polar-cartesian", "calibration"):
        assert f'id="{sid}"' in html, sid
    studies = json.loads((quick / "reports/studies.json").read_text(encoding="utf-8"))["studies"]
    for key in ("accuracy_table", "calibration_demo", "accuracy_vs_distance_straight_20m"):
        assert studies[key], key
    # the figure is drawn from the study's log alone: the same bytes when drawn again from it
    again = quick / "expcoords_again.png"
    render_study_figure(quick / "data/studies/expcoords_regions.json", again)
    assert again.read_bytes() == (quick / "reports/figures/studies/expcoords_regions.png").read_bytes()
    assert "pose-uncertainty calibrate runs.csv" in html


def test_report_has_method_c_and_umbmark(quick: Path) -> None:
    """Method C in the per-run tables (= the logs), its section, and the UMBmark section with its figure."""
    from pose_uncertainty.present.pipeline_figures import render_study_figure
    from pose_uncertainty.records.run import open_run

    html = (quick / "reports/comparison.html").read_text(encoding="utf-8")
    for sid in ("method-c", "umbmark", "fig-studies-umbmark"):
        assert f'id="{sid}"' in html, sid
    # its group in the full tables (on the sets' pages, reports/runs/<set>.html)
    full = "".join(p.read_text(encoding="utf-8") for p in (quick / "reports/runs").glob("*.html"))
    assert re.search(r'<th colspan="\d">Method C \(sigma points\)</th>', full)
    run = sweep.expand_all(sweep.validate_config(_config("quick.yaml"), SCHEMA))["L_straight"][-1]
    row = next(r for r in read_table(quick / "reports/tables/L_straight.csv") if r["run"] == run.id)
    metrics = open_run(quick / run.path).metrics
    for key in ("C_sigma_along", "C_mean_shift_along", "MC_mean_shift_along", "accuracy_unscented_coverage_xy_98_89"):
        assert row[key] == metrics[key], key
    claims = json.loads((quick / "reports/claims.json").read_text(encoding="utf-8"))
    assert claims["unscented"]["n_runs"] > 0
    assert any(g["advice"].startswith("Method C") for g in claims["guide"])
    summary = json.loads((quick / "reports/studies.json").read_text(encoding="utf-8"))["summary"]
    assert summary["umbmark"]["E_max_after"] < summary["umbmark"]["E_max_before"]
    again = quick / "umbmark_again.png"
    render_study_figure(quick / "data/studies/umbmark.json", again)
    assert again.read_bytes() == (quick / "reports/figures/studies/umbmark.png").read_bytes()


def test_no_change_rerun_does_nothing(quick: Path) -> None:
    before = {p: p.stat().st_mtime_ns for p in (quick / "reports").rglob("*") if p.is_file()}
    before |= {p: p.stat().st_mtime_ns for p in (quick / "data/runs").rglob("*") if p.is_file()}
    t0 = time.perf_counter()
    proc = snakemake(quick, "--configfile", "config/quick.yaml", timeout=120)
    elapsed = time.perf_counter() - t0
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Nothing to be done" in proc.stdout + proc.stderr
    after = {p: p.stat().st_mtime_ns for p in before}
    assert after == before
    (quick / "rerun.json").write_text(json.dumps({"seconds": elapsed}), encoding="utf-8")


def _planned_jobs(proc: subprocess.CompletedProcess[str]) -> dict[str, int]:
    text = proc.stdout + proc.stderr
    stats = text[text.index("Job stats:"):] if "Job stats:" in text else ""
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+)\s+(\d+)$", stats, re.MULTILINE)}


def test_changing_one_parameter_reruns_only_what_it_affects(quick: Path) -> None:
    cfg = yaml.safe_load((quick / "config/quick.yaml").read_text(encoding="utf-8"))
    cfg["experiment_sets"]["L_straight"]["base"]["k_r"] = 4.0e-4  # one set, one parameter
    (quick / "config/changed.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False), encoding="utf-8")
    proc = snakemake(quick, "--configfile", "config/changed.yaml", "--dry-run", timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    jobs = _planned_jobs(proc)
    n = len(cfg["experiment_sets"]["L_straight"]["sweep"][0]["trajectory.length"])
    assert jobs.get("simulate_run") == n, jobs
    assert jobs.get("render_run_figures") == 1, jobs  # the set's figures, drawn by one job
    assert jobs.get("collect_metrics") == 1, jobs
    assert jobs.get("render_growth_figure") == 1, jobs
    assert "render_cloud_polar_figure" not in jobs, jobs


def test_pipeline_logs_are_byte_reproducible(quick: Path, tmp_path: Path) -> None:
    run = sweep.expand_all(sweep.validate_config(_config("quick.yaml"), SCHEMA))["A1_shape"][1]
    again = tmp_path / "again.mcap"
    jobs.simulate_run(run.config, again)
    assert again.read_bytes() == (quick / run.path).read_bytes()


def test_report_shows_per_rule_times_and_reproducibility(quick: Path) -> None:
    html = (quick / "reports/comparison.html").read_text(encoding="utf-8")
    for rule in ("simulate_run", "render_run_figures", "collect_metrics", "evaluate_claims"):
        assert f"<td>{rule}</td>" in html
    # provenance is read from the logs: the lock hash the runs recorded, none flagged as different
    import hashlib

    lock = hashlib.sha256((REPO / "environment.lock").read_bytes()).hexdigest()
    pipeline = json.loads((quick / "reports/pipeline.json").read_text(encoding="utf-8"))
    assert pipeline["provenance"]["environment_lock_sha256"] == {"value": lock, "counts": {lock: pipeline["n_logs"]},
                                                                   "differs": []}
    assert "<th>environment_lock_sha256</th>" in html
    assert lock in html
    assert "log(s) differ" not in html
    # each run's replay command in its section of its set's page, which the report's reproducibility section names
    assert "pose-uncertainty replay data/runs/A1_shape/" in (quick / "reports/runs/A1_shape.html").read_text(encoding="utf-8")
    assert '<a href="tables/A1_shape.csv">A1_shape</a>' in html  # the table with each run's seed


def test_snakemake_report_archive(quick: Path) -> None:
    proc = snakemake(quick, "--configfile", "config/quick.yaml", "--report", "reports/provenance.zip", timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    import zipfile

    with zipfile.ZipFile(quick / "reports/provenance.zip") as z:
        names = z.namelist()
    assert any(n.endswith("trajectory.png") for n in names)


def test_table_measures_match_the_straight_line_closed_form(quick: Path) -> None:
    """Two routes to σ_along, σ_θ on a straight line: the collected table vs the closed form.

    Straight line of length L, equal k, track b: each wheel's travel variance is k L, so
    σ_along² = Var((s_r+s_l)/2) = k L / 2 and σ_θ² = Var((s_r−s_l)/b) = 2 k L / b². Across:
    with N midpoint steps of Δs = L/N the heading error δθ_j of step j moves the end by
    Δs (N − j + ½), so σ_across² = (2 k Δs³ / b²) Σ_{m=0}^{N−1} (m + ½)² = 2 k L³/(3 b²) (1 − 1/(4N²)).
    """
    cfg = sweep.validate_config(_config("quick.yaml"), SCHEMA)
    runs = {r.id: r for r in sweep.expand_all(cfg)["L_straight"]}
    rows = read_table(quick / "reports/tables/L_straight.csv")
    assert rows
    for row in rows:
        c = runs[row["run"]].config
        k, b, L = c["k_r"], c["trajectory"]["track"], c["trajectory"]["length"]
        n = sweep.n_steps(c)
        assert row["A_sigma_along"] == pytest.approx(math.sqrt(k * L / 2), rel=1e-9)
        assert row["A_sigma_theta"] == pytest.approx(math.sqrt(2 * k * L) / b, rel=1e-9)
        across = 2 * k * L**3 / (3 * b**2) * (1 - 1 / (4 * n**2))
        assert row["A_sigma_across"] == pytest.approx(math.sqrt(across), rel=1e-9)


def test_speed_results_are_read_for_the_report(tmp_path: Path) -> None:
    from pose_uncertainty.present.report import read_speed_results

    assert read_speed_results(tmp_path / "missing") == []
    (tmp_path / "a.json").write_text(
        json.dumps({"benchmark": "foundation", "machine": {"cores": 2},
                    "results": {"mc": {"vectorised_s": 2.3, "speedup": 49.0}, "x": 1.5}}),
        encoding="utf-8",
    )
    (tmp_path / "b.json").write_text("{not json", encoding="utf-8")
    res = read_speed_results(tmp_path)
    assert [r["benchmark"] for r in res] == ["foundation", "b"]
    assert res[0]["results"] == {"mc": {"vectorised_s": 2.3, "speedup": 49.0}, "x": {"value": 1.5}}
    assert "error" in res[1]


def test_report_has_the_drives_section(quick: Path) -> None:
    """"Beyond the differential drive" formats the D_drives table: its numbers, from the logged measures."""
    from pose_uncertainty.present.report import _fmt

    html = (quick / "reports/comparison.html").read_text(encoding="utf-8")
    section = html[html.index('<h2 id="drives">'):html.index('<h2 id="reproducibility">')]
    rows = {r["run"]: r for r in read_table(quick / "reports/tables/D_drives.csv")}
    for run in ("differential_straight", "tricycle_straight", "synchro_straight"):
        r = rows[run]
        assert f'<a href="#run-D_drives-{run}">' in section
        for key in ("A_sigma_across", "MC_sigma_across", "A_growth_sigma_across", "MC_growth_sigma_along"):
            assert _fmt(r[key], 3) in section, (run, key)
    arc = rows["skid_steer_arc"]
    assert arc["drive_plain_odometry_mahalanobis"] > 3  # the turn bias is outside the 98.89 % ellipse
    assert f"{_fmt(arc['drive_plain_odometry_mahalanobis'], 3)} standard deviations" in section
    assert 'id="fig-D_drives-set-drives"' in html


def test_localization_figures_one_job_per_set(quick: Path) -> None:
    """Every localization run's figures are drawn (one job per set) into runs/<run>/ and shown on the set's
    companion page of the report (linked from the run's entry), with the bytes the replay functions give from
    the run's log alone."""
    from pose_uncertainty.experiments import localization as loc
    from pose_uncertainty.present.localization import RUN_FIGURES, render_localization_run_figures

    html = (quick / "reports/comparison.html").read_text(encoding="utf-8")
    sets = loc.expand_localization(sweep.validate_config(_config("quick.yaml"), SCHEMA))
    assert sets
    for name, runs in sets.items():
        folder = quick / f"reports/figures/localization/{name}/runs"
        page = (quick / f"reports/runs/localization-{name}.html").read_text(encoding="utf-8")  # its companion page
        assert sorted(p.name for p in folder.iterdir() if p.is_dir()) == sorted(r.id for r in runs)
        assert not (folder.parent / "runs.part").exists()
        for r in runs:
            for kind in RUN_FIGURES:
                assert (folder / r.id / f"{kind}.png").is_file(), (name, r.id, kind)
                assert f'id="fig-localization-{name}-{r.id}-{kind}"' in page, (name, r.id, kind)
            assert f'href="runs/localization-{name}.html#loc-run-{name}-{r.id}"' in html, (name, r.id)
    bench = sorted(p.name for p in (quick / "data/benchmarks/render_localization_figures").iterdir())
    assert bench == sorted(f"{name}.tsv" for name in sets)  # one job per set
    name, runs = next(iter(sets.items()))
    again = render_localization_run_figures(
        quick / f"data/localization/{name}/{runs[0].id}.mcap", list(RUN_FIGURES),
        [quick / f"replayed_{kind}.png" for kind in RUN_FIGURES],
    )  # fmt: skip
    for kind, path in zip(RUN_FIGURES, again, strict=True):
        assert path.read_bytes() == (quick / f"reports/figures/localization/{name}/runs/{runs[0].id}/{kind}.png").read_bytes()
