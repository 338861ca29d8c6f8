# pose-uncertainty: every experiment of the theses → run logs, figures, tables, the comparison report.
# Wiring only; the rules live in workflow/rules/, the numerics in src/pose_uncertainty/.
import os

from snakemake.utils import min_version

min_version("8.0")

# Every job inherits this: the runs allocate and free numpy temporaries of a few MB at each step,
# which glibc by default hands back to the system (mmap/munmap, heap trimming) and then faults in
# again; measured 10–30 % of a dead-reckoning run's time. With these thresholds they stay in the
# heap. The numbers do not change (log bytes compared with and without; replay --verify in the tests).
os.environ.setdefault(
    "GLIBC_TUNABLES",
    "glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=268435456:glibc.malloc.top_pad=67108864",
)

# Every job is a new interpreter that imports the package: compile its bytecode once here, so
# that no job compiles ~20 000 lines again (0.15 s a job when PYTHONDONTWRITEBYTECODE is set,
# as in many containers; the files are up to date after the first run and this takes ms).
import compileall as _compileall
import pose_uncertainty as _package

_compileall.compile_dir(os.path.dirname(_package.__file__), quiet=1)

# Snakemake's scheduling loop woke once a second per finished job (workflow/scheduler.py): fixed.
import importlib.util as _importlib_util

_spec = _importlib_util.spec_from_file_location("pose_uncertainty_scheduler", os.path.join(workflow.basedir, "workflow", "scheduler.py"))
_scheduler = _importlib_util.module_from_spec(_spec)
_spec.loader.exec_module(_scheduler)
_scheduler.install()


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/tables.smk"
include: "workflow/rules/studies.smk"
include: "workflow/rules/localization.smk"
include: "workflow/rules/report.smk"


# On a cluster (workflow/profiles/slurm) only the computations are submitted: runs, studies and
# localization runs. The rules below read logs and draw, tabulate or format them in a second or
# two, less than a scheduler's round trip, so they run where Snakemake runs.
localrules:
    all,
    render_run_figures,
    render_growth_figure,
    render_cloud_polar_figure,
    render_drives_figure,
    render_localization_figures,
    render_localization_set_figure,
    render_study_figure,
    collect_metrics,
    collect_localization_metrics,
    collect_studies,
    evaluate_claims,
    summarize_pipeline,
    build_report,


rule all:
    input:
        all_outputs(),
    default_target: True
