"""How many threads a computation uses when it is not told: the one default of the package.

``OMP_NUM_THREADS`` when it holds a positive integer (Snakemake sets it to each job's
``threads``, 1 unless a rule asks for more, so that two jobs on two cores do not run four
threads), else the machine's cores, at most 8. The results never depend on it: the
computations that take a thread count split their work into blocks that are the same for
any count.
"""

from __future__ import annotations

import os

__all__ = ["MAX_DEFAULT_WORKERS", "default_workers"]

#: More threads than this are used only when asked for.
MAX_DEFAULT_WORKERS = 8


def default_workers() -> int:
    """The default thread count: ``OMP_NUM_THREADS`` if it is a positive integer, else ``min(cores, 8)``.

    A value of ``OMP_NUM_THREADS`` that is not a positive integer (OpenMP also allows lists
    such as ``"4,2"``) is read up to its first comma; anything else is ignored.
    """
    text = os.environ.get("OMP_NUM_THREADS", "").split(",")[0].strip()
    if text.isdigit() and int(text) > 0:
        return min(int(text), MAX_DEFAULT_WORKERS)
    return max(1, min(MAX_DEFAULT_WORKERS, os.cpu_count() or 1))
