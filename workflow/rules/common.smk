# Config validation (JSON Schema 2020-12, before any rule reads the config) and input functions.
import functools as _functools
import json as _json
import shlex as _shlex
import sys as _sys
from pathlib import Path

from pose_uncertainty.experiments import sweep as _sweep
from pose_uncertainty.pipeline import chunks as _chunks
from pose_uncertainty.core.provenance import closure_sha256, imports_of
from pose_uncertainty.core.schema import load_schema
from pose_uncertainty.present.study_figures import STUDY_FIGURE_KEYS as _STUDY_FIGURE_KEYS

# The config files are read with the package's reader, which refuses a repeated key (naming both
# lines; Snakemake's YAML loader takes the last of two equal keys), a file that is not a regular one
# and one over its size limit.
from pose_uncertainty.core.input_files import InputFileError as _InputFileError
from pose_uncertainty.core.input_files import read_mapping_file as _read_mapping_file

DEFAULT_CONFIG = "config/config.yaml"

if workflow.overwrite_configfiles:
    # A config file given on the command line (--configfile config/quick.yaml) REPLACES
    # config/config.yaml instead of deep-merging into it (whose sets would otherwise leak in);
    # --config key=value overrides still apply on top. Snakemake has read it: read it once more.
    import copy as _copy

    config.clear()
    config.update(_copy.deepcopy(workflow.config_settings.overwrite_config))
    for _configfile in workflow.configfiles:
        try:
            _read_mapping_file(_configfile, "config")
        except _InputFileError as _exc:
            raise WorkflowError(f"invalid config: {_exc}") from None
else:
    # config/config.yaml, read here rather than by Snakemake's `configfile:` (a pure-Python YAML reader:
    # 0.2 s of every start, where libyaml takes 0.03 s), and merged as `configfile:` merges it: recorded
    # among the workflow's config files, the --config key=value overrides on top (or alone, with
    # --replace-workflow-config).
    from snakemake.utils import update_config as _update_config

    try:
        _default_config = _read_mapping_file(DEFAULT_CONFIG, "config")
    except _InputFileError as _exc:
        raise WorkflowError(f"invalid config: {_exc}") from None
    workflow.configfiles.append(DEFAULT_CONFIG)
    if not workflow.config_settings.replace_workflow_config:
        _update_config(config, _default_config)
    _update_config(config, workflow.config_settings.overwrite_config)

_SCHEMA = load_schema(workflow.source_path("../schemas/config.schema.yaml"))
try:
    _validated = _sweep.validate_config(config, _SCHEMA)
except _sweep.ConfigError as _exc:
    raise WorkflowError(f"invalid config: {_exc}") from None
config.clear()
config.update(_validated)  # in place: every default filled in

RUNS = _sweep.expand_all(config)  # {set: [Run, ...]}

# the studies: name -> (kind, every parameter), validated like the runs (their modules imported only
# when studies are enabled: a sweep's config turns them off, and its DAG build does not pay for them)
STUDIES = {}
if config["studies"]["enabled"]:
    from pose_uncertainty.experiments import study as _study

    try:
        STUDIES = {name: _study.study_params(name, spec) for name, spec in config["studies"]["runs"].items()}
    except ValueError as _exc:
        raise WorkflowError(f"invalid config: {_exc}") from None

# The source each rule runs (its param `source`): the hash of the import closure of the package modules
# it executes (pose_uncertainty.core.provenance.closure_sha256). Snakemake reruns a rule when that code
# changes, and only then: no log, table or figure is older than the code that makes it, and rewording a
# claim reruns the claims and the report, not the runs. The workflow scripts themselves are tracked by
# Snakemake (rerun trigger `code`: a script newer than its rule's outputs reruns the rule).
SOURCE_JOB = closure_sha256("pose_uncertainty.cli.job")  # the JOB commands: runs, localization runs, studies

# the report's template ships with the package (present/templates); the report rule hashes it with its code
REPORT_TEMPLATE = "pose_uncertainty/present/templates/comparison.html.j2"
SWEEP_TEMPLATE = "pose_uncertainty/present/templates/sweep_summary.html.j2"  # included by it
SKALKA_TEMPLATE = "pose_uncertainty/present/templates/skalka.html.j2"  # included by it
RUNS_TEMPLATE = "pose_uncertainty/present/templates/runs.html.j2"  # the companion pages of the runs' figures
FULL_TABLE_TEMPLATE = "pose_uncertainty/present/templates/full_table.html.j2"  # included by both: a set's full table
STYLE_SHEET = "pose_uncertainty/present/templates/report.css"  # included by the report and its companion pages


@_functools.cache
def script_source(script, data=()):
    """The `source` param of a script rule: the closure hash of what workflow/scripts/<script>.py imports
    from the package, with the package ``data`` files (paths relative to the package's parent)."""
    return closure_sha256(*imports_of(Path(workflow.basedir, "workflow", "scripts", f"{script}.py")), data=data)

RUN_BY_ID = {(s, r.id): r for s, runs in RUNS.items() for r in runs}
SETS = list(RUNS)

# Config key `runs_per_job` (pose_uncertainty.experiments.pipeline_keys): 1 runs each run as a job of its own
# (rules simulate_run, simulate_localization); above 1 each set's runs are cut, in order, into chunks of at
# most that many, one job (and one SLURM job) each: the rules simulate_chunk_<set>_<i> and
# simulate_localization_chunk_<set>_<i> of workflow/rules/simulate.smk.
RUNS_PER_JOB = config["runs_per_job"]
CHUNKS = {s: _chunks.chunk_runs(RUNS[s], RUNS_PER_JOB) for s in SETS} if RUNS_PER_JOB > 1 else {}


def chunk_timings(set_name, i, localization=False):
    """The timings file of chunk ``i`` of a set (of localization runs with ``localization``): every run's
    timings, written by its job after its last log (pose_uncertainty.pipeline.chunks.read_timings reads a run's)."""
    return f"data/{'localization' if localization else 'runs'}/{set_name}/chunks/{i}.timings.json"


# each chunked run's chunk
RUN_CHUNK = {(s, r.id): i for s, parts in CHUNKS.items() for i, part in enumerate(parts) for r in part}
gc.freeze()  # the expanded sweeps live to the end: out of the cyclic collector's walks (see the Snakefile)


def runs_made(set_name, timings=False, localization=False):
    """What a job that reads every log of a set (and with ``timings`` every run's timings) waits for; with
    ``localization``, of a localization set.

    One job per run: those files. In chunks: each chunk's timings file (:func:`chunk_timings`), the
    first output of its rule, so that Snakemake resolves a set of 10⁴ runs by 100 files, not by 2·10⁴
    of them matched against the chunks' explicit outputs one by one; a rerun chunk rewrites its
    timings file, which reruns its readers. Snakemake reruns a job for a missing output only when a
    reader asks for that output, so the log of a finished chunk (its timings file there) that is
    missing since is asked for too (:func:`_missing_logs`): its chunk runs again. The jobs read the
    files themselves from their params (``logs``, ``timings``).
    """
    if RUNS_PER_JOB > 1:
        parts = (LOC_CHUNKS if localization else CHUNKS)[set_name]
        out = [chunk_timings(set_name, i, localization) for i in range(len(parts))]
        return out + _missing_logs(set_name, localization)
    logs, tims = (localization_logs, localization_timings) if localization else (run_logs, run_timings)
    return [*logs(set_name), *(tims(set_name) if timings else [])]


@_functools.cache
def _missing_logs(set_name, localization):
    """The logs of a set's finished chunks (their timings files exist) that do not exist: one listing of
    the set's folder when its workflow is read (none for a chunk not yet made, as in a first build)."""
    parts = (LOC_CHUNKS if localization else CHUNKS)[set_name]
    done = [i for i in range(len(parts)) if os.path.exists(chunk_timings(set_name, i, localization))]
    if not done:
        return []
    folder = f"data/{'localization' if localization else 'runs'}/{set_name}"
    present = {e.name for e in os.scandir(folder)} if os.path.isdir(folder) else set()
    return [f"{folder}/{r.id}.mcap" for i in done for r in parts[i] if f"{r.id}.mcap" not in present]


def chunk_job_spec(runs, logs, timings, kind="run"):
    """The JSON argument of the job that executes ``runs``, a chunk of ``kind`` (run or localization) with
    their ``logs`` and the chunk's ``timings`` file (pose_uncertainty.pipeline.chunks.chunk_spec)."""
    return _json.dumps(_chunks.chunk_spec([r.config for r in runs], logs, None, kind=kind, chunk_timings=timings),
                       allow_nan=False)


def chunk_resources(runs, kind="run"):
    """A chunk's cluster resources: the largest memory and the summed time of its runs' estimates."""
    from pose_uncertainty.experiments import cost as _cost

    return _cost.chunk_resources([r.config for r in runs], kind)


@_functools.cache
def _run_resources(set_name, run_id):
    from pose_uncertainty.experiments import cost as _cost

    return _cost.job_resources(RUN_BY_ID[(set_name, run_id)].config)


def run_resources(wildcards):
    """The cluster resources (mem_mb, runtime) of one run, from its cost estimate (computed once per run)."""
    return _run_resources(wildcards.set, wildcards.run)


def run_timing(run):
    """The file that holds a run's timings: its own (one job per run) or its chunk's (:func:`chunk_timings`)."""
    if RUNS_PER_JOB > 1:
        return chunk_timings(run.set, RUN_CHUNK[(run.set, run.id)])
    return f"data/runs/{run.set}/{run.id}.timings.json"


def run_benchmarks(set_name):
    """The benchmark files of the jobs that compute a set's runs (one per run or one per chunk)."""
    if RUNS_PER_JOB > 1:
        return [f"data/benchmarks/simulate_chunk/{set_name}/{i}.tsv" for i in range(len(CHUNKS[set_name]))]
    return [f"data/benchmarks/simulate_run/{set_name}/{r.id}.tsv" for r in RUNS[set_name]]


def run_benchmarks_made(set_name):
    """What a job that reads :func:`run_benchmarks` waits for: the files, or in chunks the chunks' timings files
    (a benchmark file comes after a chunk's every output in Snakemake's search for its producer; the job
    has written it when Snakemake sees the chunk's outputs)."""
    return runs_made(set_name) if RUNS_PER_JOB > 1 else run_benchmarks(set_name)


wildcard_constraints:
    set="[A-Za-z0-9_]+",
    run="[A-Za-z0-9_.-]+",
    study="[A-Za-z0-9_.-]+",
    map="[A-Za-z0-9_.-]+",


# The computing jobs (runs, localization runs, studies) are shell commands of this module, which
# imports only what the job needs (a script: job imports Snakemake first, 0.1 s each).
# GLIBC_TUNABLES: the runs allocate and free numpy temporaries of a few MB at each step, which glibc
# by default hands back to the system (mmap/munmap, heap trimming) and then faults in again; measured
# 10–30 % of a dead-reckoning run's time. With these thresholds they stay in the heap. The numbers do
# not change (log bytes compared with and without; replay --verify in the tests). glibc reads it when
# the interpreter starts, so it is part of the command: every computing job gets it, local or on
# SLURM; a GLIBC_TUNABLES already in the environment is kept.
GLIBC_TUNABLES = "glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=268435456:glibc.malloc.top_pad=67108864"
JOB = f'GLIBC_TUNABLES="${{GLIBC_TUNABLES:-{GLIBC_TUNABLES}}}" {_shlex.quote(_sys.executable)} -m pose_uncertainty.cli.job'


def as_json(param):
    """A rule param: the value of ``param(wildcards)`` as one JSON argument of a :data:`JOB` command."""
    return lambda wildcards: _json.dumps(param(wildcards), allow_nan=False)


def run_config(wildcards):
    """The full run configuration of data/runs/<set>/<run>.mcap (a rule param)."""
    return RUN_BY_ID[(wildcards.set, wildcards.run)].config


def run_logs(set_name):
    return [f"data/runs/{set_name}/{r.id}.mcap" for r in RUNS[set_name]]


def run_timings(set_name):
    """Each run's timings file (:func:`run_timing`), in the set's order."""
    return [run_timing(r) for r in RUNS[set_name]]


# Config key report.summary_above: a set of more runs shows summary views from its table (rule
# summarize_sweep: reports/tables/<set>.sweep.json and two figures) instead of per-run figures.
SUMMARY_ABOVE = config["report"]["summary_above"]


def summarized(set_name):
    """Whether a set is shown by its summary views (more runs than report.summary_above)."""
    return len(RUNS[set_name]) > SUMMARY_ABOVE


def sweep_outputs(set_name):
    """The summary of a summarised set and its figures, by kind."""
    return {"summary": f"reports/tables/{set_name}.sweep.json",
            "sweep_heatmaps": f"reports/figures/{set_name}/sweep_heatmaps.png",
            "sweep_dependence": f"reports/figures/{set_name}/sweep_dependence.png"}


def sweep_summaries(wildcards=None):
    return [sweep_outputs(s)["summary"] for s in SETS if summarized(s)]


def run_figures(set_name, run):
    """Per-run figures of one run, by kind."""
    base = f"reports/figures/{set_name}/runs/{run.id}"
    figs = {"trajectory": f"{base}/trajectory.png"}
    if run.config["monte_carlo"]["n_particles"] > 0:
        figs["cloud"] = f"{base}/cloud.png"
    for m in run.config["maps"]:
        figs[f"map_{m['name']}"] = f"{base}/map_{m['name']}.png"
        # the map's contours with its model's own sampler (step by step) over them
        figs[f"mapcloud_{m['name']}"] = f"{base}/mapcloud_{m['name']}.png"
    return figs


def set_figures(set_name):
    """Set-level figures (config key experiment_sets.<set>.plots)."""
    return {p: f"reports/figures/{set_name}/{p}.png" for p in config["experiment_sets"][set_name]["plots"]}


def figures_of_set(wildcards_or_name):
    """The figure outputs of a set: its set-level figures and the folder of its runs' figures
    (render_run_figures: reports/figures/<set>/runs/<run>/<kind>.png)."""
    name = getattr(wildcards_or_name, "set", wildcards_or_name)
    if summarized(name):
        return [*set_figures(name).values(), *list(sweep_outputs(name).values())[1:]]
    return [*set_figures(name).values(), f"reports/figures/{name}/runs"]


def all_figures(wildcards=None):
    return [f for s in SETS for f in figures_of_set(s)]


def all_tables(wildcards=None):
    return [f"reports/tables/{s}.csv" for s in SETS]


def study_logs(wildcards=None):
    """The study logs, in config order (data/studies/<name>.json)."""
    return [f"data/studies/{name}.json" for name in STUDIES]


def study_config(wildcards):
    """The configuration ``{"study": kind, **every parameter}`` of one study (a rule param)."""
    kind, params = STUDIES[wildcards.study]
    return {"study": kind, **params}


def study_kind(wildcards):
    """The kind of one study (a rule param: the figure it gets)."""
    return STUDIES[wildcards.study][0]


def studies_figures(wildcards=None):
    """Figures of the studies sections, by report key: the first study of each kind with a figure
    (pose_uncertainty.present.study_figures.STUDY_FIGURE_KEYS: the exp.-coordinates figure, UMBmark's)."""
    out = {}
    for name, (kind, _) in STUDIES.items():
        if kind in _STUDY_FIGURE_KEYS:
            out.setdefault(_STUDY_FIGURE_KEYS[kind], f"reports/figures/studies/{name}.png")
    return out


def studies_json(wildcards=None):
    """reports/studies.json when any study is configured, else nothing."""
    return ["reports/studies.json"] if STUDIES else []


def all_benchmarks(wildcards=None, made=False):
    """Benchmark files of every job the summary depends on (per-rule times in the report); with ``made``
    what the summary waits for (:func:`run_benchmarks_made`: the chunks' timings files for theirs)."""
    out = []
    for s in SETS:
        out.extend(run_benchmarks_made(s) if made else run_benchmarks(s))
        for kind in set_figures(s):
            out.append(f"data/benchmarks/render_{kind}_figure/{s}.tsv")
        out.append(f"data/benchmarks/{'summarize_sweep' if summarized(s) else 'render_run_figures'}/{s}.tsv")
        out.append(f"data/benchmarks/collect_metrics/{s}.tsv")
    out.append("data/benchmarks/evaluate_claims/all.tsv")
    out.extend(f"data/benchmarks/run_study/{name}.tsv" for name in STUDIES)
    out.extend(f"data/benchmarks/render_study_figure/{Path(f).stem}.tsv" for f in studies_figures().values())
    out.extend(localization_benchmarks(made))
    out.extend(robot_benchmarks())  # workflow/rules/robots.smk
    return out


def report_manifest():
    """Everything the report builder needs to know about the sets, runs and figures (a rule param)."""
    sets = []
    for s in SETS:
        spec = config["experiment_sets"][s]
        # a summarised set: its summary and figures, the number of its runs, and no run listed
        # (its table, a CSV beside the report, has them all)
        big = summarized(s)
        sets.append(
            {
                "name": s,
                "title": spec["title"] or s,
                "source": spec["source"],
                "description": spec["description"],
                "table": f"reports/tables/{s}.csv",
                "figures": set_figures(s),
                "n_runs": len(RUNS[s]),
                **({"sweep": sweep_outputs(s)} if big else {}),
                "runs": [] if big else [
                    {
                        "id": r.id,
                        "log": r.path,
                        "swept": r.swept,  # which keys the set sweeps (the report prints their logged values)
                        "figures": run_figures(s, r),
                    }
                    for r in RUNS[s]
                ],
            }
        )
    return {"sets": sets, "config": config, "localization": localization_manifest()}


def all_outputs():
    return ["reports/comparison.html", "reports/runs", *all_tables(), *all_figures(), *studies_figures().values(),
            *localization_tables(), *localization_figures(), *robot_tables()]


def polar_logs(wildcards):
    """Runs drawn in Šafránek 2022's Cartesian/polar view: the midpoint-sampler runs (at most 8)."""
    runs = [r for r in RUNS[wildcards.set] if r.config["monte_carlo"]["method"] == "midpoint"]
    return [r.path for r in (runs or RUNS[wildcards.set])[:8]]


# --- localization (pose_uncertainty.experiments.localization): its sets, runs, outputs --------------------
# Config key `localization.sets`: sweeps over localization run configurations, expanded like the
# experiment sets; logs in data/localization/<set>/<run>.mcap, rules in workflow/rules/localization.smk.
LOC_RUNS = {}  # {set: [Run, ...]}; the localization modules imported only when it is enabled
if config["localization"]["enabled"]:
    from pose_uncertainty.experiments import localization as _loc

    try:
        LOC_RUNS = _loc.expand_localization(config)
    except _sweep.ConfigError as _exc:
        raise WorkflowError(f"invalid config: {_exc}") from None
LOC_BY_ID = {(s, r.id): r for s, runs in LOC_RUNS.items() for r in runs}
LOC_SETS = list(LOC_RUNS)
# chunks of localization runs (config key runs_per_job, as the dead-reckoning runs), and each run's chunk
LOC_CHUNKS = {s: _chunks.chunk_runs(LOC_RUNS[s], RUNS_PER_JOB) for s in LOC_SETS} if RUNS_PER_JOB > 1 else {}
LOC_RUN_CHUNK = {(s, r.id): i for s, parts in LOC_CHUNKS.items() for i, part in enumerate(parts) for r in part}
LOC_RUN_FIGURES = ("paths", "errors", "nees")


def localization_config(wildcards):
    """The full configuration of data/localization/<set>/<run>.mcap (a rule param)."""
    return LOC_BY_ID[(wildcards.set, wildcards.run)].config


@_functools.cache
def _localization_resources(set_name, run_id):
    from pose_uncertainty.experiments import cost as _cost

    config = _loc.LocalizationConfig.from_dict(LOC_BY_ID[(set_name, run_id)].config)
    return _cost.resources_of(_cost.estimate_localization(config))


def localization_resources(wildcards):
    """The cluster resources (mem_mb, runtime) of one localization run, from its cost estimate."""
    return _localization_resources(wildcards.set, wildcards.run)


def study_resources(wildcards):
    """The cluster resources (mem_mb, runtime) of one study, from its cost bound."""
    from pose_uncertainty.experiments import cost as _cost

    kind, params = STUDIES[wildcards.study]
    return _cost.resources_of(_cost.estimate_study(wildcards.study, kind, params))


def localization_log(set_name, run_id):
    return f"data/localization/{set_name}/{run_id}.mcap"


def localization_logs(set_name):
    return [localization_log(set_name, r.id) for r in LOC_RUNS[set_name]]


def localization_timing(set_name, run_id):
    """The file that holds a localization run's timings: its own (one job per run) or its chunk's."""
    if RUNS_PER_JOB > 1:
        return chunk_timings(set_name, LOC_RUN_CHUNK[(set_name, run_id)], localization=True)
    return f"data/localization/{set_name}/{run_id}.timings.json"


def localization_timings(set_name):
    """Each localization run's timings file (:func:`localization_timing`), in the set's order."""
    return [localization_timing(set_name, r.id) for r in LOC_RUNS[set_name]]


def localization_run_figures(set_name, run_id):
    """Figures of one localization run, by kind (render_localization_figures draws a set's runs into
    reports/figures/localization/<set>/runs/<run>/<kind>.png)."""
    return {k: f"reports/figures/localization/{set_name}/runs/{run_id}/{k}.png" for k in LOC_RUN_FIGURES}


def localization_set_figures(set_name):
    plots = config["localization"]["sets"][set_name]["plots"]
    return {p: f"reports/figures/localization/{set_name}/{p}.png" for p in plots}


def localization_figures(wildcards=None):
    out = []
    for s in LOC_SETS:
        out.extend(localization_set_figures(s).values())
        out.append(f"reports/figures/localization/{s}/runs")
    return out


def localization_tables(wildcards=None):
    return [f"reports/tables/localization/{s}.csv" for s in LOC_SETS]


def localization_table_names():
    """The claims', summary's and report's name of each localization table (apart from the experiment sets)."""
    return [f"localization/{s}" for s in LOC_SETS]


def localization_benchmarks(made=False):
    """Benchmark files of the localization jobs; with ``made`` what the summary waits for (all_benchmarks)."""
    out = []
    for s in LOC_SETS:
        if made and RUNS_PER_JOB > 1:  # the chunks' timings files (see run_benchmarks_made)
            out.extend(runs_made(s, localization=True))
        elif RUNS_PER_JOB > 1:
            out.extend(f"data/benchmarks/simulate_localization_chunk/{s}/{i}.tsv" for i in range(len(LOC_CHUNKS[s])))
        else:
            out.extend(f"data/benchmarks/simulate_localization/{s}/{r.id}.tsv" for r in LOC_RUNS[s])
        out.append(f"data/benchmarks/render_localization_figures/{s}.tsv")
        out.extend(f"data/benchmarks/render_localization_set_figure/{s}/{p}.tsv" for p in localization_set_figures(s))
        out.append(f"data/benchmarks/collect_localization_metrics/{s}.tsv")
    return out


def localization_manifest():
    """The localization sets, runs and figures the report shows (a rule param)."""
    sets = []
    for s in LOC_SETS:
        spec = config["localization"]["sets"][s]
        sets.append(
            {
                "name": s,
                "title": spec["title"] or s,
                "source": spec["source"],
                "description": spec["description"],
                "table": f"reports/tables/localization/{s}.csv",
                "figures": localization_set_figures(s),
                "runs": [
                    {"id": r.id, "log": localization_log(s, r.id), "swept": r.swept,
                     "figures": localization_run_figures(s, r.id)}
                    for r in LOC_RUNS[s]
                ],
            }
        )
    return {"sets": sets}
