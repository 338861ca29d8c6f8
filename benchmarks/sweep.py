"""A large sweep, batched against one run per job (``make bench-sweep``).

The sweep of ``config/sweep10k.yaml`` (10⁴ small runs over k_r, k_l, the track, the speed and
twenty paths), cut down to ``--runs`` runs (its longest axes shortened first) unless ``--full``,
is built from scratch in a temporary copy of the workflow twice, timed in the same benchmark run:

* ``batched`` — ``runs_per_job`` of the config (100): one job per chunk of runs;
* ``one_run_per_job`` — ``runs_per_job: 1`` on the first ``--baseline-runs`` runs of the same
  sweep (fewer: each of its jobs pays an interpreter start-up, which is what is measured).

Per layout:

* ``dag_build_s``, ``dag_build_cpu_s`` — wall clock and CPU time of ``snakemake --dry-run`` (parse the
  workflow, expand the sweep, build the graph of jobs), before anything exists;
* ``wall_s``, ``cpu_s`` — the build from scratch (``--cores``, default 2): wall clock, and user +
  system CPU of Snakemake and every process it started;
* ``peak_rss_mb`` — the largest resident set of any one of those processes;
* ``no_op_s``, ``no_op_cpu_s`` — the same command again, with nothing to do (``no_op_load_1min``: the
  load average before it);
* ``jobs`` — the simulation jobs (what a cluster would be sent);
* ``per_run_overhead_ms`` — the simulation jobs' summed CPU time (Snakemake's ``benchmark:``
  files) minus the runs' own computing time (each run's ``total_s`` in its timings file), per run:
  what a run costs beyond its own work (interpreter, imports, log writing); ``per_run_overhead_wall_ms``
  the same from the jobs' wall clocks (which a loaded machine inflates);
* ``report_mb`` — ``reports/comparison.html``;
* ``wall_s_per_run``, ``cpu_s_per_run`` — the two layouts ran different numbers of runs, so they
  are compared per run.

``ratio_to_one_run_per_job`` gives batched ÷ one-run-per-job for each per-run figure (below 1: the
batched layout is better). ``load_1min`` records the machine's load average before each build (the
machine may be shared: its timings are then upper bounds). Writes ``benchmarks/results/sweep.json``.

Usage: ``python -m benchmarks.sweep [--runs 500] [--baseline-runs 100] [--cores 2] [--full] [--dag-only]``
(``--dag-only``: only the dry runs, e.g. of the full 10⁴-run sweep).
"""

from __future__ import annotations

import argparse
import copy
import csv
import json
import math
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

from ._common import write_results

REPO = Path(__file__).resolve().parents[1]
SNAKEMAKE = Path(sys.executable).with_name("snakemake")
SET = "SWEEP_10k"


def cut_sweep(config: dict[str, Any], runs: int) -> dict[str, Any]:
    """``config`` with its set's axes shortened (the longest first, from its end) to at most ``runs`` runs."""
    out = copy.deepcopy(config)
    axes = out["experiment_sets"][SET]["sweep"]
    lengths = [len(next(iter(a.values()))) for a in axes]
    while math.prod(lengths) > runs and max(lengths) > 1:
        i = lengths.index(max(lengths))
        lengths[i] -= 1
    for axis, n in zip(axes, lengths, strict=True):
        for key in axis:
            axis[key] = axis[key][:n]
    return out


def _workflow(base: Path, name: str, config: dict[str, Any]) -> Path:
    work = base / name
    work.mkdir(parents=True)
    shutil.copy2(REPO / "Snakefile", work / "Snakefile")
    shutil.copy2(REPO / "environment.lock", work / "environment.lock")
    for d in ("workflow", "config"):
        shutil.copytree(REPO / d, work / d)
    (work / "config/bench.yaml").write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    return work


def _snakemake(work: Path, cores: int, *args: str) -> tuple[float, float, float]:
    """Run snakemake in ``work``: (wall [s], CPU of it and its children [s], peak RSS of one process [MB])."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO / "src"), os.environ.get("PYTHONPATH")]))}
    cmd = [str(SNAKEMAKE), "--profile", "workflow/profiles/default", "--cores", str(cores),
           "--configfile", "config/bench.yaml", *args]  # fmt: skip
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"snakemake {' '.join(args)} failed in {work}:\n{proc.stderr[-3000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, after.ru_maxrss / 1024  # ru_maxrss in KiB on Linux


def _job_times(work: Path) -> tuple[int, float, float]:
    """The simulation jobs, the sum of their wall clocks and of their CPU times [s] (Snakemake's benchmark files)."""
    files = [*(work / "data/benchmarks").glob("simulate_chunk/*/*.tsv"), *(work / "data/benchmarks").glob("simulate_run/*/*.tsv")]
    wall = cpu = 0.0
    for f in files:
        with f.open(encoding="utf-8") as fh:
            for row in csv.DictReader(fh, delimiter="\t"):
                wall += float(row["s"])
                cpu += float(row.get("cpu_time") or "nan")
    return len(files), wall, cpu


def _runs_total_s(work: Path) -> tuple[int, float]:
    """The runs and their summed computing time [s]: each run's timings file, or its chunk's (every run's
    timings under ``runs``; ``pose_uncertainty.pipeline.chunks.read_timings``)."""
    runs = []
    for t in (work / "data/runs").rglob("*.timings.json"):
        data = json.loads(t.read_text(encoding="utf-8"))
        runs.extend(data["runs"].values() if isinstance(data.get("runs"), dict) else [data])
    return len(runs), sum(float(r["total_s"]) for r in runs)


def measure(work: Path, cores: int, dag_only: bool = False) -> dict[str, Any]:
    """Time one layout in ``work`` (see the module docstring)."""
    out: dict[str, Any] = {"load_1min": os.getloadavg()[0]}
    out["dag_build_s"], out["dag_build_cpu_s"], _ = _snakemake(work, cores, "--dry-run", "--quiet", "rules")
    if dag_only:
        return out
    out["wall_s"], out["cpu_s"], out["peak_rss_mb"] = _snakemake(work, cores)
    out["no_op_load_1min"] = os.getloadavg()[0]
    out["no_op_s"], out["no_op_cpu_s"], _ = _snakemake(work, cores)
    jobs, job_s, job_cpu_s = _job_times(work)
    n, runs_s = _runs_total_s(work)
    out.update(runs=n, jobs=jobs, per_run_overhead_ms=1e3 * (job_cpu_s - runs_s) / n,
               per_run_overhead_wall_ms=1e3 * (job_s - runs_s) / n,
               report_mb=(work / "reports/comparison.html").stat().st_size / 1e6,
               wall_s_per_run=out["wall_s"] / n, cpu_s_per_run=out["cpu_s"] / n)  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    """Build the sweep both ways, print and write the measurements."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=500, help="runs of the batched sweep (default 500)")
    ap.add_argument("--baseline-runs", type=int, default=100, help="runs of the one-run-per-job sweep (default 100)")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--full", action="store_true", help="the whole 10⁴-run sweep (batched)")
    ap.add_argument("--dag-only", action="store_true", help="only the dry runs (DAG build)")
    ap.add_argument("--keep", default=None, help="build under this folder (default: the system's temporary folder)")
    args = ap.parse_args(argv)
    config = yaml.safe_load((REPO / "config/sweep10k.yaml").read_text(encoding="utf-8"))
    n_full = math.prod(len(next(iter(a.values()))) for a in config["experiment_sets"][SET]["sweep"])
    batched = config if args.full else cut_sweep(config, args.runs)
    single = {**cut_sweep(config, min(args.baseline_runs, args.runs if not args.full else n_full)), "runs_per_job": 1}
    results: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="bench-sweep-", dir=args.keep) as tmp:
        for name, cfg in (("one_run_per_job", single), ("batched", batched)):
            print(f"{name}: building in {tmp}/{name} ...", flush=True)
            results[name] = measure(_workflow(Path(tmp), name, cfg), args.cores, args.dag_only)
            results[name]["runs_per_job"] = cfg["runs_per_job"]
            print(json.dumps(results[name], indent=1), flush=True)
    if not args.dag_only:
        b, s = results["batched"], results["one_run_per_job"]
        results["ratio_to_one_run_per_job"] = {k: b[k] / s[k] for k in
                                               ("wall_s_per_run", "cpu_s_per_run", "per_run_overhead_ms", "no_op_s",
                                                "dag_build_s", "dag_build_cpu_s", "peak_rss_mb") if s.get(k)}  # fmt: skip
    results["goals"] = {"dag_build_s": 10.0, "sweep_10k_wall_s": 600.0, "per_run_overhead_ms": 20.0, "report_mb": 10.0}
    path = write_results("sweep", results)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
