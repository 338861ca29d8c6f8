"""The quick pipeline on a real single-node SLURM cluster, through snakemake-executor-plugin-slurm.

The cluster is Debian's slurmctld + slurmd + munge started by ``.ci/slurm-up.sh`` (``.ci/run``
starts it in CI; ``make slurm-up`` as root on a developer's machine). The test runs
``config/quick.yaml`` with ``workflow/profiles/slurm-test`` in a copy of the workflow, cancels
one running simulation with ``scancel`` on the way, and checks that

* the runs are submitted in chunks (config key ``runs_per_job``): one cluster job per chunk, of
  dead-reckoning and of localization runs alike;
* the cancelled chunk job is retried (the profile's ``retries``) and the pipeline completes;
* that job asked the scheduler for what its runs' cost estimates say
  (``pose_uncertainty.experiments.cost.chunk_resources``: ``--mem`` and ``--time``);
* every run log (dead reckoning and localization) made through SLURM is byte-identical to the same
  run made locally (the quick pipeline of tests/test_pipeline.py, shared by the session);
* the report builds from them.

Without root or without the SLURM binaries the test is skipped with the reason; with
``POSE_UNCERTAINTY_REQUIRE_SLURM=1`` (set by ``.ci/run``) it fails instead.
"""

from __future__ import annotations

import ast
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml
from test_pipeline import REPO, copy_workflow, quick_pipeline

from pose_uncertainty.core.schema import load_schema
from pose_uncertainty.experiments import cost, localization, sweep
from pose_uncertainty.pipeline import chunks

VENV_BIN = Path(sys.executable).parent
BINARIES = ("sinfo", "squeue", "sbatch", "scancel", "srun")


def _plugin_settings() -> set[str]:
    """Fields of the installed plugin's ExecutorSettings, read from its source (importing it
    runs sacct/scontrol to choose a default)."""
    spec = importlib.util.find_spec("snakemake_executor_plugin_slurm")
    assert spec is not None, "snakemake-executor-plugin-slurm missing"
    assert spec.origin is not None
    tree = ast.parse(Path(spec.origin).read_text(encoding="utf-8"))
    (cls,) = [n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "ExecutorSettings"]
    return {n.target.id for n in cls.body if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)}


def _flat(d: dict, prefix: str = "") -> dict[str, object]:
    out: dict[str, object] = {}
    for k, v in d.items():
        out.update(_flat(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
    return out


def test_test_profile_differs_from_the_site_profile_only_where_the_cluster_must() -> None:
    site = _flat(yaml.safe_load((REPO / "workflow/profiles/slurm/config.yaml").read_text()))
    test = _flat(yaml.safe_load((REPO / "workflow/profiles/slurm-test/config.yaml").read_text()))
    changed = {k for k in site.keys() | test.keys() if site.get(k) != test.get(k)}
    assert changed == {
        "latency-wait",  # one machine
        "default-resources.slurm_account",  # no accounts without a database ...
        "slurm-no-account",  # ... so none is sent
        "default-resources.slurm_partition",  # the partition of .ci/slurm-up.sh
        "slurm-status-command",  # squeue: no accounting database for sacct
        "slurm-init-seconds-before-status-checks",  # short jobs
    }
    # the plugin's own option names (profile key slurm-<name> ↔ ExecutorSettings.<name>)
    plugin_keys = [k for k in test if k.startswith("slurm-")]
    settings = _plugin_settings()
    assert {"status_command", "no_account", "init_seconds_before_status_checks"} <= settings
    assert plugin_keys
    for key in plugin_keys:
        assert key.removeprefix("slurm-").replace("-", "_") in settings, key


def _cluster_state() -> str | None:
    """The node state sinfo reports (idle, mixed, ...), or None when nothing answers."""
    try:
        out = subprocess.run(
            ["sinfo", "-h", "-o", "%T"], capture_output=True, text=True, timeout=20, check=False
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return out.stdout.split()[0] if out.returncode == 0 and out.stdout.split() else None


def _unavailable(reason: str) -> None:
    if os.environ.get("POSE_UNCERTAINTY_REQUIRE_SLURM") == "1":
        pytest.fail(f"SLURM is required here (POSE_UNCERTAINTY_REQUIRE_SLURM=1) but {reason}")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def slurm_cluster() -> object:
    """A running single-node cluster: the one already up, or one started (and stopped) here."""
    missing = [b for b in BINARIES if shutil.which(b) is None]
    if missing:
        _unavailable(
            f"SLURM binaries missing ({', '.join(missing)}): apt-get install --no-install-recommends "
            "slurmctld slurmd slurm-client munge, then `make slurm-up` as root"
        )
    if _cluster_state() in ("idle", "mixed", "allocated"):
        yield None
        return
    if os.geteuid() != 0:
        _unavailable("no SLURM cluster answers and starting one needs root (`make slurm-up` as root)")
    up = subprocess.run(
        [str(REPO / ".ci/slurm-up.sh")], capture_output=True, text=True, timeout=180, check=False
    )
    assert up.returncode == 0, f".ci/slurm-up.sh failed:\n{up.stderr[-3000:]}"
    yield None
    subprocess.run([str(REPO / ".ci/slurm-down.sh")], capture_output=True, timeout=120, check=False)


#: The quick config through SLURM runs in chunks (config key runs_per_job): each chunk is one cluster job.
RUNS_PER_JOB = 3


class Canceller(threading.Thread):
    """Watch squeue; scancel the first simulate_chunk job seen RUNNING (until one ends CANCELLED)."""

    def __init__(self, stop: threading.Event) -> None:
        super().__init__(daemon=True)
        self.stop = stop
        self.cancelled: dict[str, str] | None = None
        self.tried: list[str] = []

    def _squeue(self, *args: str) -> list[list[str]]:
        out = subprocess.run(
            ["squeue", "-h", "-o", "%i|%T|%k|%m|%l", *args],
            capture_output=True, text=True, timeout=20, check=False,
        )  # fmt: skip
        return [ln.split("|") for ln in out.stdout.splitlines() if ln.count("|") == 4]

    def run(self) -> None:
        while not self.stop.is_set() and self.cancelled is None:
            for jid, state, comment, mem, limit in self._squeue():
                if state != "RUNNING" or not comment.startswith("rule_simulate_chunk_") or jid in self.tried:
                    continue
                self.tried.append(jid)
                subprocess.run(["scancel", jid], capture_output=True, timeout=20, check=False)
                for _ in range(50):  # the state settles within a few seconds
                    rows = self._squeue("-t", "all", "-j", jid)
                    if rows and rows[0][1] not in ("RUNNING", "COMPLETING"):
                        break
                    time.sleep(0.1)
                if rows and rows[0][1] == "CANCELLED":
                    self.cancelled = {"id": jid, "comment": comment, "mem": mem, "limit": limit}
                break
            time.sleep(0.2)


def _megabytes(text: str) -> int:
    """squeue's %m: ``603M``, ``2G``."""
    m = re.fullmatch(r"(\d+)([KMGT]?)", text.strip())
    assert m, text
    return int(m.group(1)) * {"K": 1 / 1024, "M": 1, "G": 1024, "T": 1024**2, "": 1}[m.group(2)]


def _minutes(text: str) -> float:
    """squeue's %l: ``10:00`` (min:s), ``1:00:00`` (h:min:s), ``1-00:00:00``."""
    days, _, rest = text.rpartition("-")
    parts = [int(p) for p in rest.split(":")]
    while len(parts) < 3:
        parts.insert(0, 0)
    h, mi, s = parts
    return (int(days or 0) * 24 + h) * 60 + mi + s / 60


#: what the cluster computes again of the local build: the dead-reckoning and localization runs (their
#: logs, their timings, their benchmark records); the tables, figures and report are made again from them
RERUN_ON_THE_CLUSTER = ("data/runs", "data/localization", "data/benchmarks/simulate_run",
                        "data/benchmarks/simulate_localization")  # fmt: skip


def _with_the_local_build_but_its_runs(local: Path, work: Path) -> Path:
    """``work`` given the local build's data and Snakemake's records of them (``.snakemake/metadata``:
    the code, parameters and inputs each was made from), less :data:`RERUN_ON_THE_CLUSTER`.

    The studies and the robot's jobs are then up to date and not submitted: they go through the same
    executor as the runs, which is what this test is about, and would double its time. (The benchmark
    folders of chunk rules are named after the rule, ``simulate_chunk_<set>_<i>``.)"""
    for d in ("data", ".snakemake/metadata"):  # not reports/: Snakemake makes no missing input a present output does not ask for
        shutil.copytree(local / d, work / d, symlinks=True)
    for d in (work / "data/benchmarks").iterdir():
        if d.name.startswith(("simulate_chunk", "simulate_localization_chunk")):
            shutil.rmtree(d)
    for d in RERUN_ON_THE_CLUSTER:
        shutil.rmtree(work / d, ignore_errors=True)
    return work


@pytest.mark.slow
def test_quick_pipeline_through_slurm(slurm_cluster: object, tmp_path_factory: pytest.TempPathFactory) -> None:
    local = quick_pipeline(tmp_path_factory.getbasetemp())
    work = _with_the_local_build_but_its_runs(local, copy_workflow(tmp_path_factory.mktemp("slurm")))
    env = dict(os.environ, PATH=f"{VENV_BIN}{os.pathsep}{os.environ.get('PATH', '')}")
    stop = threading.Event()
    canceller = Canceller(stop)
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [str(VENV_BIN / "snakemake"), "--profile", "workflow/profiles/slurm-test",
         "--configfile", "config/quick.yaml", "--config", f"runs_per_job={RUNS_PER_JOB}"],
        cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip
    canceller.start()
    try:
        out, _ = proc.communicate(timeout=1500)
    finally:
        stop.set()
        if proc.poll() is None:  # timed out: stop snakemake and the jobs it submitted
            os.killpg(proc.pid, 9)
            ids = [p.stem for p in (work / ".snakemake/slurm_logs").rglob("*.log")]
            subprocess.run(["scancel", *ids], capture_output=True, timeout=60, check=False)
    elapsed = time.perf_counter() - t0
    (work / "snakemake.out").write_text(out, encoding="utf-8")
    print(f"quick pipeline through SLURM: {elapsed:.0f} s")
    assert proc.returncode == 0, f"SLURM pipeline failed after {elapsed:.0f} s:\n{out[-6000:]}"

    # a running simulation was cancelled, reported failed, retried, and the pipeline completed
    cancelled = canceller.cancelled
    assert cancelled is not None, f"no simulate_chunk job could be cancelled while running (tried {canceller.tried})"
    assert f"SLURM-job '{cancelled['id']}' failed, SLURM status is: 'CANCELLED'" in out, out[-6000:]
    job = re.search(rf"jobid: (\d+)\n(?:.*\n){{0,6}}?\s*external_jobid: {cancelled['id']}\n", out)
    assert job, out[-6000:]
    jid = job.group(1)
    after = out[job.end():]
    assert f"Trying to restart job {jid}." in after  # the profile's retries
    resubmitted = re.search(rf"Job {jid} has been submitted with SLURM jobid (\d+)", after)
    assert resubmitted, after[-6000:]
    assert resubmitted.group(1) != cancelled["id"]
    rule = cancelled["comment"].removeprefix("rule_")  # a chunk's rule has no wildcards
    assert f"Finished jobid: {jid} (Rule: {rule})" in after

    # a chunk job per RUNS_PER_JOB runs of a set, not a job per run
    config = sweep.validate_config(yaml.safe_load((work / "config/quick.yaml").read_text()), load_schema(
        work / "workflow/schemas/config.schema.yaml"))  # fmt: skip
    sets = sweep.expand_all(config)
    runs = [r for rs in sets.values() for r in rs]
    submitted = set(re.findall(r"\(Rule: (simulate_(?:run|chunk_\w+))\)", out))  # dead reckoning (the robot is not chunked)
    assert submitted == {f"simulate_chunk_{s}_{i}" for s, rs in sets.items() for i in range(-(-len(rs) // RUNS_PER_JOB))}
    loc_sets = localization.expand_localization(config)  # the localization runs, by the same key
    submitted = set(re.findall(r"\(Rule: (simulate_localization\w*)\)", out))
    assert submitted == {f"simulate_localization_chunk_{s}_{i}" for s, rs in loc_sets.items()
                         for i in range(-(-len(rs) // RUNS_PER_JOB))}  # fmt: skip
    # it asked for what its runs' cost estimates say (the largest memory, the summed time)
    chunk_of = {f"simulate_chunk_{s}_{i}": part for s, rs in sets.items()
                for i, part in enumerate(chunks.chunk_runs(rs, RUNS_PER_JOB))}  # fmt: skip
    want = cost.chunk_resources([r.config for r in chunk_of[rule]])
    assert _megabytes(cancelled["mem"]) == want["mem_mb"]
    assert _minutes(cancelled["limit"]) == want["runtime"]

    # every run log identical to the local run's, and the report built from them
    logs_local = sorted(p.relative_to(local) for p in (local / "data/runs").rglob("*.mcap"))
    logs_slurm = sorted(p.relative_to(work) for p in (work / "data/runs").rglob("*.mcap"))
    assert logs_slurm == logs_local
    assert len(logs_local) == len(runs)
    differ = [str(p) for p in logs_local if (local / p).read_bytes() != (work / p).read_bytes()]
    assert differ == [], f"run logs made through SLURM differ from the local ones: {differ}"
    loc_local = sorted(p.relative_to(local) for p in (local / "data/localization").rglob("*.mcap"))
    assert sorted(p.relative_to(work) for p in (work / "data/localization").rglob("*.mcap")) == loc_local
    assert len(loc_local) == sum(len(rs) for rs in loc_sets.values())
    differ = [str(p) for p in loc_local if (local / p).read_bytes() != (work / p).read_bytes()]
    assert differ == [], f"localization logs made through SLURM differ from the local ones: {differ}"
    html = (work / "reports/comparison.html").read_text(encoding="utf-8")
    assert all(r.id in html for r in runs)
