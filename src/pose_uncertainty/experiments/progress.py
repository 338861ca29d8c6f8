"""Progress of long loops on stderr: a bar on a terminal, a periodic line otherwise.

The kernels take an optional ``progress`` callback, ``progress(done, total)``,
called from the thread that called them after each unit of work (a chunk of
Monte Carlo particles, a step of a multi-step map, a step of the log); it is
None by default and costs nothing then. :class:`Progress` is the callback the
run uses: silent for the first ``delay`` seconds (short loops print nothing),
then, on a terminal, a bar redrawn at most every 0.2 s, and elsewhere — such as
Snakemake's rule logs, where stderr of a job goes — one line every ``interval``
seconds::

    progress: circle_a4: Monte Carlo 41 % (410,000/1,000,000), 12 s, about 17 s left
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["Progress"]


def _clock(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"


class Progress:
    """A ``progress(done, total)`` callback printing to ``stream`` (default stderr).

    Parameters
    ----------
    label : str — what is progressing (``"run A1: Monte Carlo"``)
    stream : text stream, optional — default ``sys.stderr`` at call time
    delay : float [s] — print nothing before this much time has passed
    interval : float [s] — between two lines when ``stream`` is not a terminal
    tty : bool, optional — force the terminal (bar) or the line mode
    """

    def __init__(
        self,
        label: str,
        stream: TextIO | None = None,
        *,
        delay: float = 2.0,
        interval: float = 10.0,
        tty: bool | None = None,
    ) -> None:
        self.label = label
        self.stream = stream
        self.delay = delay
        self.interval = interval
        self.tty = tty
        self.t0 = time.monotonic()
        self.last = -float("inf")
        self.shown = False

    def _out(self) -> TextIO:
        return self.stream if self.stream is not None else sys.stderr

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        elapsed = now - self.t0
        finished = done >= total
        if elapsed < self.delay and not (finished and self.shown):
            return
        out = self._out()
        tty = self.tty if self.tty is not None else bool(getattr(out, "isatty", lambda: False)())
        if not finished and now - self.last < (0.2 if tty else self.interval):
            return
        self.last = now
        frac = done / total if total > 0 else 1.0
        left = elapsed * (1.0 - frac) / frac if frac > 0 else float("nan")
        eta = f", about {_clock(left)} left" if 0 < frac < 1 else ""
        if tty:
            width = 30
            bar = "#" * int(frac * width) + "." * (width - int(frac * width))
            out.write(
                f"\r{self.label} [{bar}] {100 * frac:3.0f} % {_clock(elapsed)}{eta}\x1b[K"
                + ("\n" if finished else "")
            )
        else:
            out.write(
                f"progress: {self.label} {100 * frac:.0f} % ({done:,}/{total:,}), "
                f"{_clock(elapsed)}{eta}\n"
            )
        out.flush()
        self.shown = True
