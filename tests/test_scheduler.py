"""workflow/scheduler.py: Snakemake's scheduling loop is woken once per timespan, not once per finished job."""

from __future__ import annotations

import importlib.util
import re
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

_PATH = Path(__file__).resolve().parents[1] / "workflow" / "scheduler.py"
_spec = importlib.util.spec_from_file_location("pose_uncertainty_scheduler", _PATH)
scheduler = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(scheduler)


def _releases(sem: threading.Semaphore) -> int:
    n = 0
    while sem.acquire(blocking=False):
        n += 1
    return n


def test_many_requests_while_one_is_pending_release_once():
    s = SimpleNamespace(_open_jobs=threading.Semaphore(0))
    for _ in range(10):  # ten passes of the loop within the timespan
        scheduler.one_reevaluation(s, 0.05)
    assert s._one_reevaluation.daemon  # never delays the exit
    time.sleep(0.3)
    assert _releases(s._open_jobs) == 1
    scheduler.one_reevaluation(s, 0.05)  # after it fired, a new request is served again
    time.sleep(0.3)
    assert _releases(s._open_jobs) == 1


def test_snakemakes_own_method_releases_once_per_request():
    """What the fix replaces: each pass starts its own timer (so the passes multiply)."""
    from snakemake.scheduling.job_scheduler import JobScheduler

    s = SimpleNamespace(_open_jobs=threading.Semaphore(0))
    for _ in range(10):
        JobScheduler._schedule_reevalutation(s, 0.05)
    time.sleep(0.3)
    assert _releases(s._open_jobs) == 10


def test_install_replaces_the_method(monkeypatch: pytest.MonkeyPatch):
    from snakemake.scheduling.job_scheduler import JobScheduler

    monkeypatch.setattr(JobScheduler, "_schedule_reevalutation", JobScheduler._schedule_reevalutation)
    installed, line = scheduler.install(environ={})
    assert installed, line
    assert JobScheduler._schedule_reevalutation is scheduler.one_reevaluation
    assert "\n" not in line  # one line
    assert scheduler.ENV in line  # saying how to turn it off


def test_verified_on_the_locked_snakemake():
    """The version the fix was checked against is that of environment.lock (and the one installed)."""
    import snakemake

    lock = (Path(__file__).resolve().parents[1] / "environment.lock").read_text(encoding="utf-8")
    locked = re.search(r"^snakemake==(\d+)\.(\d+)\.", lock, re.MULTILINE)
    assert locked, "snakemake is not in environment.lock"
    assert scheduler.VERIFIED == (int(locked[1]), int(locked[2]))
    assert tuple(int(p) for p in snakemake.__version__.split(".")[:2]) == scheduler.VERIFIED


@pytest.mark.parametrize("version", ["9.28.0", "10.27.1", "9.26.3", "not-a-version"])
def test_another_snakemake_is_left_alone(monkeypatch: pytest.MonkeyPatch, version: str):
    from snakemake.scheduling.job_scheduler import JobScheduler

    original = JobScheduler._schedule_reevalutation
    monkeypatch.setattr(JobScheduler, "_schedule_reevalutation", original)
    installed, line = scheduler.install(version, environ={})
    assert not installed
    assert JobScheduler._schedule_reevalutation is original
    assert version in line
    assert "verified on Snakemake 9.27.x" in line
    v = ".".join(map(str, scheduler.VERIFIED))
    assert scheduler.install(f"{v}.99", environ={})[0]  # any patch release of the verified one
    assert JobScheduler._schedule_reevalutation is scheduler.one_reevaluation


@pytest.mark.parametrize("value", ["0", "no", "False", " off "])
def test_the_environment_turns_it_off(monkeypatch: pytest.MonkeyPatch, value: str):
    from snakemake.scheduling.job_scheduler import JobScheduler

    original = JobScheduler._schedule_reevalutation
    monkeypatch.setattr(JobScheduler, "_schedule_reevalutation", original)
    monkeypatch.setenv(scheduler.ENV, value)
    installed, line = scheduler.install()
    assert not installed
    assert JobScheduler._schedule_reevalutation is original
    assert f"{scheduler.ENV}={value}" in line
    monkeypatch.setenv(scheduler.ENV, "1")
    assert scheduler.install()[0]
