"""Faults: a pipeline killed with SIGKILL anywhere recovers with a plain `make quick`.

* Every writer of a pipeline output is atomic (``pose_uncertainty.core.atomic``): a
  file is absent, its previous version or complete; a killed writer's ``.part`` file
  is removed by the next write of the same file or by ``workflow/run-locked.sh``.
* ``make quick`` / ``make report`` run snakemake under ``workflow/run-locked.sh``: a
  flock held for the whole run; with it, a Snakemake lock left by a killed run is
  stale and removed; a run really in progress makes a second one stop with one line.
* The slow test kills ``make quick`` (its whole process group, SIGKILL) during a
  simulation, during figure rendering and during the report build, reruns it each
  time, and checks that it completes, that every log passes ``replay --verify``, that
  Snakemake has nothing left to do and that no partial file is left in data/ or reports/.
  Its ``make quick`` runs the smallest pipeline with each of those jobs
  (``tests/data/killed_pipeline.yaml`` as the copy's ``config/quick.yaml``).
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from pose_uncertainty.cli import main
from pose_uncertainty.core.atomic import (
    atomic_directory,
    atomic_write,
    atomic_write_bytes,
    atomic_write_text,
)
from pose_uncertainty.experiments import sweep

REPO = Path(__file__).resolve().parents[1]
VENV = Path(sys.executable).parent.parent
LOCKED = REPO / "workflow/run-locked.sh"


def _dead_pid() -> int:
    """The pid of a process that has exited (and been reaped)."""
    proc = subprocess.Popen(["true"])
    proc.wait()
    return proc.pid


# --- atomic writes -------------------------------------------------------------------------------


def test_atomic_write_keeps_the_old_file_on_error_and_leaves_nothing(tmp_path: Path) -> None:
    dest = tmp_path / "table.csv"
    dest.write_text("old\n", encoding="utf-8")

    def interrupted_write() -> None:
        with atomic_write(dest, "w", encoding="utf-8") as fh:
            fh.write("new, half")
            raise RuntimeError("interrupted")

    with pytest.raises(RuntimeError, match="interrupted"):
        interrupted_write()
    assert dest.read_text(encoding="utf-8") == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]
    atomic_write_text(dest, "new\n")
    assert dest.read_text(encoding="utf-8") == "new\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]


def test_atomic_directory_replaces_the_folder_whole_or_keeps_the_old_one(tmp_path: Path) -> None:
    dest = tmp_path / "runs"
    (dest / "old").mkdir(parents=True)
    (tmp_path / "runs.part" / "left").mkdir(parents=True)  # a killed writer's folder
    seen: list[list[Path]] = []

    def fail() -> None:
        with atomic_directory(dest) as part:
            seen.append([part, *part.iterdir()])
            (part / "half.png").write_bytes(b"x")
            raise RuntimeError("drawing failed")

    with pytest.raises(RuntimeError):
        fail()
    assert seen == [[tmp_path / "runs.part"]]  # the stale folder was removed, the new one empty
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs"]
    assert [p.name for p in dest.iterdir()] == ["old"]  # the old folder untouched
    with atomic_directory(dest) as part:
        (part / "a").mkdir()
        (part / "a" / "f.png").write_bytes(b"png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs"]
    assert [p.name for p in dest.iterdir()] == ["a"]
    assert (dest / "a" / "f.png").read_bytes() == b"png"


def test_a_killed_writers_part_file_is_removed_by_the_next_write(tmp_path: Path) -> None:
    dest = tmp_path / "fig.png"
    host = re.sub(r"[^A-Za-z0-9-]+", "-", os.uname().nodename.split(".")[0])
    dead = tmp_path / f".fig.png.{host}-{_dead_pid()}-abc123.part"
    alive = tmp_path / f".fig.png.{host}-{os.getppid()}-def456.part"  # a live writer: kept
    other = tmp_path / f".other.png.{host}-{_dead_pid()}-ghi789.part"  # another file's: kept
    for p in (dead, alive, other):
        p.write_bytes(b"partial")
    atomic_write_bytes(dest, b"\x89PNG")
    assert dest.read_bytes() == b"\x89PNG"
    assert not dead.exists()
    assert alive.exists()
    assert other.exists()


KILLED_WRITER = """
import os, signal, sys
from pose_uncertainty.core.atomic import atomic_write
with atomic_write(sys.argv[1], "wb") as fh:
    fh.write(b"half a file")
    fh.flush()
    os.kill(os.getpid(), signal.SIGKILL)
"""


def test_sigkill_mid_write_leaves_no_file_at_the_destination(tmp_path: Path) -> None:
    dest = tmp_path / "claims.json"
    proc = subprocess.run([sys.executable, "-c", KILLED_WRITER, str(dest)], check=False, timeout=60)
    assert proc.returncode == -signal.SIGKILL
    assert not dest.exists()
    (part,) = tmp_path.glob(".claims.json.*.part")
    atomic_write_text(dest, "[]\n")  # the rerun of the job
    assert not part.exists()
    assert dest.read_text(encoding="utf-8") == "[]\n"


# --- the locked wrapper (fast: a shell command stands in for snakemake) ---------------------


def _locked(work: Path, *cmd: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(LOCKED), *cmd], cwd=work, capture_output=True, text=True, timeout=60, check=False
    )


def test_stale_snakemake_lock_and_part_files_are_cleared(tmp_path: Path) -> None:
    locks = tmp_path / ".snakemake/locks"
    locks.mkdir(parents=True)
    (locks / "0.input.lock").write_text("data/runs/A/x.mcap\n", encoding="utf-8")
    part = tmp_path / "data/runs/A/.x.mcap.vm-123-abc.part"
    part.parent.mkdir(parents=True)
    part.write_bytes(b"partial")
    kept = tmp_path / "data/runs/A/x.mcap"
    kept.write_bytes(b"complete")
    res = _locked(tmp_path, "sh", "-c", "ls .snakemake/locks | wc -l; echo ran")
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["0", "ran"]
    assert "removing the Snakemake lock left by an interrupted run" in res.stderr
    assert not part.exists()
    assert kept.exists()


def test_a_run_holding_the_lock_stops_a_second_one_in_one_line(tmp_path: Path) -> None:
    (tmp_path / ".snakemake").mkdir()
    holder = subprocess.Popen(
        ["flock", str(tmp_path / ".snakemake/run.flock"), "sleep", "60"], cwd=tmp_path
    )
    try:
        for _ in range(100):  # until flock has taken the lock
            probe = subprocess.run(
                ["flock", "-n", str(tmp_path / ".snakemake/run.flock"), "true"], check=False
            )
            if probe.returncode != 0:
                break
            time.sleep(0.05)
        res = _locked(tmp_path, "sh", "-c", "echo ran")
    finally:
        holder.kill()
        holder.wait()
    assert res.returncode == 75
    assert res.stdout == ""
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith(f"run-locked: another pipeline run is active in {tmp_path};")


@pytest.mark.parametrize("job", ["script", "command"])
def test_a_job_that_outlived_its_snakemake_stops_the_rerun(tmp_path: Path, job: str) -> None:
    """kill -9 of snakemake alone leaves its jobs running: wait for them, do not rerun.

    A job is a script job (``python .snakemake/scripts/tmp….py``) or a job command
    (``python -m pose_uncertainty.cli.job …``: here a stand-in with that argument that sleeps).
    """
    scripts = tmp_path / ".snakemake/scripts"
    scripts.mkdir(parents=True)
    (scripts / "tmpabc.simulate_run.py").write_text("import time\ntime.sleep(60)\n", encoding="utf-8")
    (tmp_path / ".snakemake/locks").mkdir()
    (tmp_path / ".snakemake/locks/0.output.lock").write_text("x\n", encoding="utf-8")
    argv = (
        [sys.executable, ".snakemake/scripts/tmpabc.simulate_run.py"]
        if job == "script"
        else [sys.executable, "-c", "import time; time.sleep(60)", "pose_uncertainty.cli.job"]
    )
    orphan = subprocess.Popen(argv, cwd=tmp_path)
    try:
        res = _locked(tmp_path, "sh", "-c", "echo ran")
    finally:
        orphan.kill()
        orphan.wait()
    assert res.returncode == 75
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith(f"run-locked: another snakemake run or its jobs are still working in {tmp_path} (pid")
    assert str(orphan.pid) in line
    assert (tmp_path / ".snakemake/locks/0.output.lock").exists()  # not removed under a live job


# --- the quick pipeline, killed three times ------------------------------------------------------


#: the pipeline `make quick` runs in the copies of the project: two runs, their figures, table, claims and report
KILLED_PIPELINE = Path(__file__).with_name("data") / "killed_pipeline.yaml"


def copy_project(dest: Path) -> Path:
    """What `make quick` needs, modification times kept (so make does not rebuild the venv), with
    :data:`KILLED_PIPELINE` as its quick config."""
    dest.mkdir(parents=True, exist_ok=True)
    for f in ("Makefile", "Snakefile", "environment.lock", "pyproject.toml"):
        shutil.copy2(REPO / f, dest / f)
    for d in ("workflow", "config"):
        shutil.copytree(REPO / d, dest / d, dirs_exist_ok=True)
    shutil.copy2(KILLED_PIPELINE, dest / "config/quick.yaml")
    return dest


def _make_quick(work: Path) -> subprocess.Popen[str]:
    stamp = VENV / ".installed"
    return subprocess.Popen(
        ["make", "--no-print-directory", "-o", str(stamp), "quick", f"VENV={VENV}", "CORES=2"],
        cwd=work, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,  # its own process group: killpg reaches snakemake and its jobs
    )  # fmt: skip


class Watch(threading.Thread):
    """Collect a process's output; set ``hit`` when a line matches ``pattern``."""

    def __init__(self, proc: subprocess.Popen[str], pattern: str | None) -> None:
        super().__init__(daemon=True)
        self.proc, self.pattern = proc, re.compile(pattern) if pattern else None
        self.lines: list[str] = []
        self.hit = threading.Event()

    def run(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line)
            if self.pattern is not None and self.pattern.search(line):
                self.hit.set()


def _others_in(work: Path) -> list[int]:
    """Processes still working in ``work`` (their cwd), e.g. jobs that survived a kill."""
    out = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            try:
                if Path(os.readlink(proc / "cwd")).is_relative_to(work):
                    out.append(int(proc.name))
            except OSError:
                continue
    return out


def _kill_when(work: Path, pattern: str, started: str | None, delay: float) -> str:
    """Start `make quick`; when it has printed ``pattern`` (a job of that rule was started) and,
    if given, a file matching the glob ``started`` exists (the job's script is running),
    wait ``delay`` s and SIGKILL its process group. Returns what it printed."""
    proc = _make_quick(work)
    watch = Watch(proc, pattern)
    watch.start()
    try:
        if not watch.hit.wait(timeout=900):
            proc.wait()
            pytest.fail(f"{pattern!r} never printed:\n{''.join(watch.lines)[-4000:]}")
        for _ in range(6000):
            if started is None or any(work.glob(started)) or proc.poll() is not None:
                break
            time.sleep(0.01)
        time.sleep(delay)
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    finally:
        watch.join(timeout=10)
        assert proc.stdout is not None
        proc.stdout.close()
    for _ in range(100):  # the kernel reaps the group's members asynchronously
        if not _others_in(work):
            break
        time.sleep(0.05)
    assert _others_in(work) == [], "processes survived the kill of the process group"
    return "".join(watch.lines)


@pytest.mark.slow
def test_sigkill_during_simulation_rendering_and_report_then_make_quick_recovers(
    tmp_path: Path,
) -> None:
    work = copy_project(tmp_path / "project")
    t0 = time.perf_counter()
    # 1. during a simulation: its job has started
    _kill_when(work, r"rule simulate_run:", "logs/simulate_run/*/*.log", 0.5)
    assert any((work / "logs/simulate_run").rglob("*.log"))
    assert any((work / ".snakemake/locks").iterdir()), "the kill should leave Snakemake's lock"
    # 2. during figure rendering (the rerun resumes: Snakemake's lock is stale and removed)
    out = _kill_when(work, r"rule render_\w+:", "logs/render_*/**/*.log", 0.5)
    assert "removing the Snakemake lock left by an interrupted run" in out
    # 3. during the report build: killed before it could write the report
    out = _kill_when(work, r"rule build_report:", None, 0.2)
    assert not (work / "reports/comparison.html").exists(), "the report was built before the kill"
    # 4. make quick again: it completes
    final = _make_quick(work)
    watch = Watch(final, None)
    watch.start()
    final.wait(timeout=1200)
    watch.join(timeout=10)
    assert final.stdout is not None
    final.stdout.close()
    out = "".join(watch.lines)
    print(f"killed three times and recovered in {time.perf_counter() - t0:.0f} s")
    assert final.returncode == 0, out[-6000:]
    assert "removing the Snakemake lock left by an interrupted run" in out
    assert (work / "reports/comparison.html").is_file()

    # Snakemake has nothing left to do (no incomplete output)
    dry = subprocess.run(
        [str(VENV / "bin/snakemake"), "--profile", "workflow/profiles/default", "--cores", "1",
         "--configfile", "config/quick.yaml", "-n"],
        cwd=work, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert dry.returncode == 0, dry.stderr[-3000:]
    assert "Nothing to be done" in dry.stdout + dry.stderr, (dry.stdout + dry.stderr)[-3000:]

    # no partial or temporary file anywhere in data/ and reports/ (Snakemake marks a finished
    # directory output with its own .snakemake_timestamp)
    leftovers = [
        str(p.relative_to(work))
        for d in ("data", "reports")
        for p in (work / d).rglob("*")
        if (p.name.startswith(".") and p.name != ".snakemake_timestamp") or p.suffix in (".part", ".tmp")
    ]
    assert leftovers == []

    # every log passes replay --verify, one log for each run of the config
    logs = sorted((work / "data/runs").rglob("*.mcap"))
    config = yaml.safe_load(KILLED_PIPELINE.read_text(encoding="utf-8"))
    assert len(logs) == sum(len(runs) for runs in sweep.expand_all(config).values()) == 2
    failed = [str(p) for p in logs if main(["replay", str(p), "--verify"]) != 0]
    assert failed == []


@pytest.mark.slow
def test_a_second_make_quick_says_one_run_is_already_active(tmp_path: Path) -> None:
    work = copy_project(tmp_path / "project")
    first = _make_quick(work)
    watch = Watch(first, r"rule \w+:")
    watch.start()
    try:
        assert watch.hit.wait(timeout=300), "".join(watch.lines)[-3000:]
        second = subprocess.run(
            ["make", "--no-print-directory", "-o", str(VENV / ".installed"), "quick", f"VENV={VENV}"],
            cwd=work, capture_output=True, text=True, timeout=120, check=False,
        )  # fmt: skip
    finally:
        os.killpg(first.pid, signal.SIGKILL)
        first.wait()
        watch.join(timeout=10)
        assert first.stdout is not None
        first.stdout.close()
    assert second.returncode != 0
    ours = [ln for ln in (second.stdout + second.stderr).splitlines() if ln.startswith("run-locked:")]
    assert len(ours) == 1, second.stdout + second.stderr
    assert re.fullmatch(
        rf"run-locked: another pipeline run \(pid \d+\) is active in {re.escape(str(work))}; "
        r"wait for it to finish or stop it, then rerun",
        ours[0],
    ), ours[0]
    assert "LockException" not in second.stderr
    assert "Traceback" not in second.stderr
