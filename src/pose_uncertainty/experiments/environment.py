"""The environment variables the package reads, each checked before a command does any work.

======================================  =========================================================
variable                                allowed
======================================  =========================================================
``POSE_UNCERTAINTY_MAX_MEMORY``         a size from 1 B to 1 EiB (``64G``, ``500M``), a percentage
                                        in (0, 100] of the available memory (``80%``), or ``none``
                                        (:mod:`pose_uncertainty.experiments.cost`)
``POSE_UNCERTAINTY_MAX_SECONDS``        a duration in (0, 1e9] s (``600``, ``90m``, ``6h``) or ``none``
``POSE_UNCERTAINTY_ENVIRONMENT_LOCK``   the path of a regular file (the ``environment.lock`` whose
                                        sha256 the logs carry, :mod:`pose_uncertainty.core.provenance`)
``OMP_NUM_THREADS``                     a positive integer, or OpenMP's comma-separated list of them
                                        (:mod:`pose_uncertainty.core.threads` reads the first)
======================================  =========================================================

An unset or empty variable takes its default. :func:`check_environment` raises ValueError
with one line naming the variable, its value and what is allowed.
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Mapping

from . import cost

__all__ = ["ENV_ENVIRONMENT_LOCK", "ENV_OMP_THREADS", "check_environment"]

ENV_ENVIRONMENT_LOCK = "POSE_UNCERTAINTY_ENVIRONMENT_LOCK"
ENV_OMP_THREADS = "OMP_NUM_THREADS"
_THREADS = re.compile(r"^\s*[1-9]\d{0,5}\s*(,\s*[1-9]\d{0,5}\s*)*$")


def check_environment(env: Mapping[str, str] | None = None) -> None:
    """Check every environment variable the package reads (see the module docstring).

    Raises
    ------
    ValueError
        ``"<VARIABLE> must be <rule> (allowed: ...), got '<value>'"``.
    """
    env = os.environ if env is None else env
    cost.limits(env)  # the two limits of the cost guard
    lock = env.get(ENV_ENVIRONMENT_LOCK, "")
    if lock:
        try:
            ok = stat.S_ISREG(os.stat(lock).st_mode)
        except (OSError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"{ENV_ENVIRONMENT_LOCK} must be the path of a regular file (allowed: an "
                             f"environment.lock), got {lock!r}")  # fmt: skip
    threads = env.get(ENV_OMP_THREADS, "")
    if threads.strip() and not _THREADS.match(threads):
        raise ValueError(f"{ENV_OMP_THREADS} must be a positive integer (allowed: 1 to 999999, or a "
                         f"comma-separated list of them), got {threads!r}")  # fmt: skip
