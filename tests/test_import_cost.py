"""What a pipeline job imports: every job is a fresh interpreter, so its imports are paid ~260 times.

The modules a job script imports at its top must not pull in the heavy libraries that only some
code paths need (scipy.special and scipy.fft through scipy's array-API layer cost 0.15–0.2 s,
scipy.optimize 0.3 s, jsonschema 60 ms, matplotlib 0.4 s); those are imported in the functions
that use them. Checked in a fresh interpreter, by the modules present after the import.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from default_runs import CONFIGS

#: job script → (its top-level import, modules it must not load)
_RUN_HEAVY = ["scipy.special", "scipy.fft", "scipy.optimize", "jsonschema", "matplotlib", "PIL", "contourpy"]
_JOB = "from pose_uncertainty.cli.job import main; "  # the runs' and studies' job command
JOBS = {
    "simulate_run": (_JOB + "from pose_uncertainty.pipeline.jobs import simulate_run", _RUN_HEAVY),
    "simulate_localization": (_JOB + "from pose_uncertainty.pipeline.jobs import simulate_localization",
                              _RUN_HEAVY),
    "run_study": (_JOB + "from pose_uncertainty.pipeline.jobs import run_study", _RUN_HEAVY),
    "render_run_figures": ("from pose_uncertainty.present.pipeline_figures import render_run_figures",
                           ["scipy.optimize", "scipy.special", "jsonschema"]),
}  # fmt: skip


def _loaded_after(statement: str) -> set[str]:
    code = f"import sys, json; {statement}; print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    return set(json.loads(out))


@pytest.mark.slow
@pytest.mark.parametrize("job", sorted(JOBS))
def test_a_job_imports_no_heavy_library_at_start(job):
    statement, heavy = JOBS[job]
    loaded = _loaded_after(statement)
    assert "pose_uncertainty" in loaded  # the statement did run
    assert not [m for m in heavy if m in loaded], f"{job}: imports {[m for m in heavy if m in loaded]} at start"


def test_the_check_sees_a_heavy_import():
    assert "scipy.special" in _loaded_after("import pose_uncertainty, scipy.special")


@pytest.mark.slow
def test_a_localization_log_kind_is_found_without_importing_its_module_first():
    code = (
        "import sys; from pose_uncertainty.records import formats, run as runlog; before = sorted(formats.FORMATS); "
        "loaded = 'pose_uncertainty.records.localization' in sys.modules; "
        "kind = formats.log_format('pose-uncertainty-localization'); "
        "print(before == [runlog.FORMAT], loaded, kind is formats.FORMATS['pose-uncertainty-localization'], "
        "formats.log_format(runlog.FORMAT) is runlog.RUN_LOG)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", "False", "True", "True"]


@pytest.mark.slow
def test_a_monte_carlo_run_without_maps_runs_without_scipy_special(tmp_path):
    """Its χ² levels come from core.stats' table of scipy's values (most runs of the default config)."""
    code = (
        "import json, sys; from pose_uncertainty.cli.job import main; "
        f"main(['simulate-run', json.dumps({CONFIGS['straight']!r}), {str(tmp_path / 'a.mcap')!r}, "
        f"{str(tmp_path / 'a.json')!r}]); print('scipy.special' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False"]
    assert (tmp_path / "a.mcap").stat().st_size > 0
