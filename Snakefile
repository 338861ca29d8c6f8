# pose-uncertainty: every experiment of the theses → run logs, figures, tables, the comparison report.
# Wiring only; the rules live in workflow/rules/, the numerics in src/pose_uncertainty/.
import gc
import os

from snakemake.utils import min_version

min_version("8.0")

# CPython's cyclic garbage collector walks every object it tracks at each full collection, and what
# this workflow builds (Snakemake's modules, the expanded sweeps, the rules) lives until the process
# ends: gc.freeze() moves the objects that exist into a generation the collector skips (reference
# counting still frees them). Called here, after the sweeps are expanded (workflow/rules/common.smk)
# and after the last rule: full collections took 1.6 of 9 CPU-s of a 10⁴-run sweep's DAG build.
gc.freeze()

# Snakemake's scheduling loop woke once a second per finished job: fixed by workflow/scheduler.py on the
# Snakemake it was verified on (POSE_UNCERTAINTY_SCHEDULER_PATCH=0 leaves Snakemake as it is).
import importlib.util as _importlib_util

_spec = _importlib_util.spec_from_file_location("pose_uncertainty_scheduler", os.path.join(workflow.basedir, "workflow", "scheduler.py"))
_scheduler = _importlib_util.module_from_spec(_spec)
_spec.loader.exec_module(_scheduler)
from snakemake.logging import logger as _logger

_logger.info(_scheduler.install()[1])


# The config: config/config.yaml, read by workflow/rules/common.smk (not by `configfile:`), unless a
# --configfile replaces it.


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/tables.smk"
include: "workflow/rules/studies.smk"
include: "workflow/rules/localization.smk"
include: "workflow/rules/robots.smk"
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
    summarize_sweep,
    collect_localization_metrics,
    collect_robots,
    collect_studies,
    evaluate_claims,
    summarize_pipeline,
    build_report,


rule all:
    input:
        all_outputs(),
    default_target: True


gc.freeze()  # the rules (see the top of this file)
