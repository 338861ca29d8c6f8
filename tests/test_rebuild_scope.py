"""What an edit of the package reruns: exactly the rules whose code it touches, and what reads their outputs.

Each rule's ``source`` param is the hash of the import closure of what it runs
(:func:`pose_uncertainty.core.provenance.closure_sha256`). On the built quick pipeline, a copy of
the package with one file edited is put first on ``PYTHONPATH`` and Snakemake is asked, with the
profile's rerun triggers, what it would run (``--dry-run``). And parsing the workflow (every
``snakemake`` call, every SLURM job) imports no matplotlib.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from test_pipeline import SCHEMA, SNAKEMAKE, _config, _planned_jobs, copy_workflow, quick_pipeline

from pose_uncertainty.core import provenance
from pose_uncertainty.experiments import localization, sweep

PACKAGE = Path(provenance.__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return quick_pipeline(tmp_path_factory.getbasetemp())


def _package_copy(dest: Path, edit: str | None) -> Path:
    """A copy of the package under ``dest/src`` with a comment appended to the file ``edit``; returns ``dest/src``."""
    src = dest / "src"
    shutil.copytree(PACKAGE, src / PACKAGE.name, ignore=shutil.ignore_patterns("__pycache__"))
    if edit is not None:
        with (src / PACKAGE.name / edit).open("a", encoding="utf-8") as f:
            f.write("\n# an edit that changes no behaviour, but the source\n")
    return src


def _would_run(quick: Path, src: Path) -> dict[str, int]:
    """The jobs a dry run of the quick config plans, by rule, with ``src`` first on PYTHONPATH."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(src), *filter(None, [os.environ.get("PYTHONPATH")])])}
    cmd = [str(SNAKEMAKE), "--profile", "workflow/profiles/default", "--cores", "2",
           "--configfile", "config/quick.yaml", "--dry-run"]  # fmt: skip
    proc = subprocess.run(cmd, cwd=quick, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    jobs = _planned_jobs(proc)
    assert jobs.pop("total", 0) == sum(jobs.values()), jobs
    return jobs


def test_a_copy_of_the_package_elsewhere_reruns_nothing(quick: Path, tmp_path: Path) -> None:
    """The control: the hashes do not depend on where the package lies."""
    assert _would_run(quick, _package_copy(tmp_path, None)) == {}


def test_rewording_a_claim_reruns_the_claims_and_the_report_only(quick: Path, tmp_path: Path) -> None:
    jobs = _would_run(quick, _package_copy(tmp_path, "pipeline/claims.py"))
    # claims.json is read by the report; the summary reads the claims job's benchmark (its time)
    assert jobs == {"evaluate_claims": 1, "summarize_pipeline": 1, "build_report": 1, "all": 1}


def test_editing_the_report_template_reruns_the_report_only(quick: Path, tmp_path: Path) -> None:
    jobs = _would_run(quick, _package_copy(tmp_path, "present/templates/comparison.html.j2"))
    assert jobs == {"build_report": 1, "all": 1}


def test_editing_a_core_module_reruns_every_run(quick: Path, tmp_path: Path) -> None:
    config = sweep.validate_config(_config("quick.yaml"), SCHEMA)
    n_runs = sum(len(runs) for runs in sweep.expand_all(config).values())
    n_loc = sum(len(runs) for runs in localization.expand_localization(config).values())
    n_studies = len(config["studies"]["runs"]) if config["studies"]["enabled"] else 0
    jobs = _would_run(quick, _package_copy(tmp_path, "core/se2.py"))
    assert jobs["simulate_run"] == n_runs, jobs
    assert jobs["simulate_localization"] == n_loc, jobs
    assert jobs.get("run_study", 0) == n_studies, jobs
    assert jobs["evaluate_claims"] == 1, jobs  # its tables are remade
    assert jobs["build_report"] == 1, jobs


_HARNESS = """
import atexit, sys
atexit.register(lambda: print("matplotlib loaded:", "matplotlib" in sys.modules))
{pre}
from snakemake.cli import main
sys.argv = ["snakemake", *sys.argv[1:]]
sys.exit(main())
"""


def _matplotlib_after(workdir: Path, pre: str, *args: str) -> tuple[bool, str]:
    """Whether matplotlib was imported when ``snakemake ARGS`` (after ``pre``) exited; and its output."""
    proc = subprocess.run([sys.executable, "-c", _HARNESS.format(pre=pre), *args], cwd=workdir,
                          capture_output=True, text=True, timeout=600, check=False)  # fmt: skip
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("matplotlib loaded:")]
    assert lines, proc.stdout[-2000:] + proc.stderr[-2000:]
    return lines[-1].endswith("True"), proc.stdout + proc.stderr


@pytest.mark.slow  # two Snakemake processes, one parsing the workflow and building its DAG
def test_parsing_and_dry_running_the_workflow_imports_no_matplotlib(tmp_path: Path) -> None:
    work = copy_workflow(tmp_path / "work")
    assert _matplotlib_after(work, "import pose_uncertainty.present.pipeline_figures", "--version")[0]  # sees it
    loaded, out = _matplotlib_after(work, "", "--profile", "workflow/profiles/default", "--cores", "1",
                                    "--configfile", "config/quick.yaml", "--dry-run")  # fmt: skip
    assert "Job stats:" in out  # the workflow was parsed and its DAG built
    assert "build_report" in out
    assert not loaded
