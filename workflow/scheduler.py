"""A fix to Snakemake's scheduling loop, installed by the Snakefile (:func:`install`).

Snakemake 9's job-rate limiter (``--max-jobs-per-timespan``, default ``100/1s``) starts a
new one-second ``threading.Timer`` at every pass of its scheduling loop
(``JobScheduler._schedule_reevalutation``), and every timer's release starts another pass,
which starts another timer. So after ``n`` jobs have finished while others wait, ``n`` chains
of timers each re-run the scheduler every second: a regeneration of this pipeline (261 jobs, 255 s) spent
51 CPU seconds in Snakemake's own process, against 6 s for the 100 jobs of the quick one.

:func:`one_reevaluation` keeps at most one timer pending (a daemon: it never delays the
exit). The loop is still re-evaluated within the timespan, and a finished job still wakes
it at once (its callback releases the same semaphore).

:func:`install` replaces the method only on the Snakemake versions it was verified on
(:data:`VERIFIED`, the major.minor of ``environment.lock``'s) and unless the environment sets
``POSE_UNCERTAINTY_SCHEDULER_PATCH=0``; it returns the one line the Snakefile logs, saying
which. The report for Snakemake itself is workflow/UPSTREAM.md.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Mapping
from typing import Any

__all__ = ["ENV", "VERIFIED", "install", "one_reevaluation"]

#: Snakemake major.minor whose ``JobScheduler._schedule_reevalutation`` the fix was verified against
#: (the version of environment.lock; tests/test_scheduler.py checks both against each other)
VERIFIED: tuple[int, int] = (9, 27)

#: The environment variable that turns the fix off (``0``, ``no``, ``false`` or ``off``)
ENV = "POSE_UNCERTAINTY_SCHEDULER_PATCH"


def one_reevaluation(scheduler: Any, delay: float) -> None:
    """Release ``scheduler._open_jobs`` once after ``delay`` seconds, unless a release is already pending."""
    pending = getattr(scheduler, "_one_reevaluation", None)
    if pending is not None and pending.is_alive():
        return
    timer = threading.Timer(delay, scheduler._open_jobs.release)
    timer.daemon = True
    timer.start()
    scheduler._one_reevaluation = timer


def install(version: str | None = None, environ: Mapping[str, str] | None = None) -> tuple[bool, str]:
    """Replace ``JobScheduler._schedule_reevalutation`` by :func:`one_reevaluation` where it is safe.

    Parameters
    ----------
    version : str, optional — the Snakemake version (default: the installed one's)
    environ : mapping, optional — the environment (default: ``os.environ``)

    Returns
    -------
    (installed, line) — whether the method was replaced and one line saying so or why not:
    turned off by :data:`ENV`, a Snakemake other than :data:`VERIFIED`, or no such method.
    """
    environ = os.environ if environ is None else environ
    if environ.get(ENV, "").strip().lower() in ("0", "no", "false", "off"):
        return False, f"Snakemake's scheduler left as it is: {ENV}={environ[ENV]}"
    if version is None:
        from snakemake import __version__ as version
    try:
        major_minor = tuple(int(p) for p in version.split(".")[:2])
    except ValueError:
        major_minor = ()
    verified = ".".join(map(str, VERIFIED))
    if major_minor != VERIFIED:
        return False, (f"Snakemake's scheduler left as it is: the fix of workflow/scheduler.py was verified on "
                       f"Snakemake {verified}.x, this is {version}")
    from snakemake.scheduling import job_scheduler

    cls = job_scheduler.JobScheduler
    if not callable(getattr(cls, "_schedule_reevalutation", None)):
        return False, f"Snakemake's scheduler left as it is: Snakemake {version} has no _schedule_reevalutation"
    cls._schedule_reevalutation = one_reevaluation
    return True, (f"Snakemake {version}'s scheduler: at most one pending re-evaluation (workflow/scheduler.py; "
                  f"{ENV}=0 turns it off)")
