"""How long a full regeneration takes, and how large its outputs are (``make bench-regenerate``).

In a fresh clone of the current commit (in a temporary folder), with this checkout's
``.venv`` and package (so the time is "without the venv"; commit first: the package is
this working tree's), runs the pipeline from scratch, then again with nothing
changed, and measures:

* ``from_scratch_s`` — wall clock of ``snakemake --profile workflow/profiles/default``
  from an empty ``data/`` and ``reports/`` (cores: all);
* ``no_op_s`` — the second call, which must find nothing to do;
* ``cpu_s`` — user + system CPU seconds of the from-scratch call and every process it started
  (on 2 cores the wall clock cannot be below half of it; steadier than the wall clock on a shared machine);
* ``snakemake_process_cpu_s`` — the part of ``cpu_s`` that Snakemake's own process takes
  (scheduling, bookkeeping; read until it exits);
* ``jobs`` and ``job_s`` per rule: the sum of the jobs' wall clocks (Snakemake's ``benchmark:`` files);
* ``report_mb`` (``reports/comparison.html``), ``data_mb`` (``data/``) and the number of figures.

The measurements before the work on the regeneration time (commit 79ddfda, measured the same way in
the session that did it) are written beside them (``before``), so the report shows both.
Writes ``benchmarks/results/regenerate.json``.

Usage: ``python -m benchmarks.regenerate [--configfile config/quick.yaml] [--keep DIR]``
(``--keep``: clone into the new folder DIR and leave it, to read its report and claims).
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from ._common import write_results

REPO = Path(__file__).resolve().parents[1]

#: Commit 79ddfda, `make report` on a fresh clone, this 2-core machine (as first measured:
#: 8 min 35 s with the venv; measured again under the load of other work: 10 min 58 s).
BEFORE: dict[str, Any] = {
    "commit": "79ddfda",
    "from_scratch_s_with_venv": 515.0,
    "cpu_s": {"simulate_run": 303.0, "run_studies": 222.0, "render figures (about 250 jobs)": 390.0},
    "cpu_s_total": 942.0,
    "report_mb": 38.2,
    "data_mb": 801.0,
    "no_op_s": 3.6,
}


def _du_mb(path: Path) -> float:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) / 1e6 if path.exists() else 0.0


def _rule_times(bench: Path) -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    for f in bench.rglob("*.tsv"):
        rule = f.relative_to(bench).parts[0]
        lines = f.read_text(encoding="utf-8").splitlines()
        if len(lines) >= 2:
            s = float(lines[1].split("\t")[0])
            r = out.setdefault(rule, {"jobs": 0, "job_s": 0.0})
            r["jobs"] += 1
            r["job_s"] += s
    return {k: {"jobs": v["jobs"], "job_s": round(v["job_s"], 1)} for k, v in sorted(out.items(), key=lambda kv: -kv[1]["job_s"])}


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _snakemake(work: Path, extra: list[str]) -> tuple[float, float, float]:
    """(wall clock, CPU seconds of Snakemake and all its jobs, of the Snakemake process alone) of one call."""
    import psutil  # (a dependency of Snakemake)

    cpu0 = _children_cpu()
    cmd = [str(REPO / ".venv/bin/snakemake"), "--profile", "workflow/profiles/default", "--cores", "all", *extra]
    t0 = time.perf_counter()
    with tempfile.TemporaryFile("w+") as out:
        proc = subprocess.Popen(cmd, cwd=work, stdout=out, stderr=subprocess.STDOUT, text=True)
        own = 0.0
        while proc.poll() is None:  # the Snakemake process's own CPU time, read until it exits
            try:
                t = psutil.Process(proc.pid).cpu_times()
                own = t.user + t.system
            except psutil.Error:
                pass
            time.sleep(0.2)
        elapsed = time.perf_counter() - t0
        if proc.returncode != 0:
            out.seek(0)
            sys.stderr.write(out.read()[-6000:])
            raise SystemExit(f"snakemake failed in {work} (exit {proc.returncode})")
    return elapsed, _children_cpu() - cpu0, own


def measure(extra: list[str], keep: Path | None = None) -> dict[str, Any]:
    """Clone, regenerate from scratch, regenerate again; the numbers described in the module docstring."""
    if keep is not None:
        if keep.exists():
            raise SystemExit(f"--keep {keep}: the folder exists; give a new one")
        return _measure_in(keep, extra)
    with tempfile.TemporaryDirectory(prefix="regenerate-") as tmp:
        return _measure_in(Path(tmp) / "clone", extra)


def _measure_in(work: Path, extra: list[str]) -> dict[str, Any]:
    subprocess.run(["git", "clone", "--quiet", str(REPO), str(work)], check=True)
    scratch, cpu, own = _snakemake(work, extra)
    no_op, _, _ = _snakemake(work, extra)
    report = work / "reports/comparison.html"
    return {
        "from_scratch_s": round(scratch, 1),
        "cpu_s": round(cpu, 1),
        "snakemake_process_cpu_s": round(own, 1),
        "no_op_s": round(no_op, 2),
        "cores": os.cpu_count(),
        "load_average_1min_at_end": round(os.getloadavg()[0], 2),
        "report_mb": round(report.stat().st_size / 1e6, 2) if report.exists() else None,
        "data_mb": round(_du_mb(work / "data"), 1),
        "figures": sum(1 for _ in (work / "reports/figures").rglob("*.png")),
        "rules": _rule_times(work / "data/benchmarks"),
        "config": extra[-1] if extra else "config/config.yaml",
    }


def main(argv: list[str] | None = None) -> None:
    """Measure and write ``benchmarks/results/regenerate.json`` (see the module docstring)."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.regenerate", description=__doc__)
    parser.add_argument("--configfile", help="another config (default: config/config.yaml)")
    parser.add_argument("--keep", type=Path, help="clone into this new folder and keep it")
    args = parser.parse_args(argv)
    extra = ["--configfile", args.configfile] if args.configfile else []
    if shutil.which("git") is None:
        raise SystemExit("git is needed to clone the repository")
    after = measure(extra, args.keep)
    path = write_results("regenerate", {"before (79ddfda)": BEFORE, "after": after})
    print(f"wrote {path}: from scratch {after['from_scratch_s']} s, no-op {after['no_op_s']} s, "
          f"report {after['report_mb']} MB, data {after['data_mb']} MB")


if __name__ == "__main__":
    main()
