"""workflow/scheduler.py: Snakemake's scheduling loop is woken once per timespan, not once per finished job."""

from __future__ import annotations

import importlib.util
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
    assert scheduler.install()
    assert JobScheduler._schedule_reevalutation is scheduler.one_reevaluation
