"""Shared machinery of the hostile-input trials (``tests/test_hostile_*.py``).

A trial runs a command-line entry point (``pose-uncertainty``, or the pipeline's
``pose_uncertainty.cli.job``) in a scratch folder, under an address-space limit
(``resource.RLIMIT_AS``), so that a regression that reads a huge input whole fails the test
instead of taking the machine down. It returns what a user sees: the exit code, standard output
and standard error, and the scratch folder's files before and after (name → (kind, size,
digest)), so a trial can assert that nothing was left behind or replaced.

A trial runs in this process by default (:func:`run_cli`): the entry point's ``main`` is called
with the arguments, in the scratch folder, with the trial's environment, its two streams
captured, Python's default warning filters (those of a fresh interpreter), a timeout
(``SIGALRM``) and the address-space limit lowered to what the process holds plus the headroom a
fresh interpreter has under :data:`MEMORY_LIMIT`. What only a new process can show (the
interpreter's start-up reading the environment, the exit status the operating system reports,
the limit on a whole process) is tried with ``process=True``: ``python -m MODULE ARGS`` in a
subprocess, as a user types it.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import importlib
import io
import os
import resource
import signal
import stat
import subprocess
import sys
import traceback
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from unittest import mock

#: address-space limit of a trial's process: far above what a refused input needs (numpy,
#: scipy, matplotlib and mcap imported take ~1 GiB of address space), far below the machine's 24 GiB
MEMORY_LIMIT = 3 * 1024**3
#: what a trial run in this process may add to the address space it already holds: the limit of a
#: fresh process less the ~1 GiB its imports take (this process has them, or maps them in the trial)
IN_PROCESS_HEADROOM = MEMORY_LIMIT - 1024**3
#: the warning filters of a fresh interpreter (no -W option, no PYTHONWARNINGS, not in -X dev mode;
#: ``warnings.filters`` at start-up), so that a trial's warnings show as a user's shell shows them
#: and not as pytest's ``filterwarnings = error`` makes them
DEFAULT_WARNING_FILTERS: tuple[tuple[str, type[Warning], str], ...] = (
    ("default", DeprecationWarning, "__main__"),
    ("ignore", DeprecationWarning, ""),
    ("ignore", PendingDeprecationWarning, ""),
    ("ignore", ImportWarning, ""),
    ("ignore", ResourceWarning, ""),
)


def _limit(memory: int) -> None:  # pragma: no cover - runs in the child
    resource.setrlimit(resource.RLIMIT_AS, (memory, memory))


def _digest(path: Path) -> str:
    """sha256 of a regular file's content, read extent by extent: the offsets and bytes of its data,
    its holes (sparse zeros, ``SEEK_HOLE``) named by their offsets and never read, so that a 3 GiB
    sparse file is hashed at the cost of its few data blocks. Two files with the same extents and
    bytes have the same content; a file system without ``SEEK_DATA`` shows the whole file as data."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        fd = fh.fileno()
        size = os.fstat(fd).st_size
        pos = 0
        while pos < size:
            try:
                start = os.lseek(fd, pos, os.SEEK_DATA)
            except OSError as exc:  # only a hole from pos to the end
                if exc.errno != errno.ENXIO:
                    raise
                break
            end = os.lseek(fd, start, os.SEEK_HOLE)
            h.update(f"{start}:{end}\n".encode())
            for at in range(start, end, 1 << 20):
                h.update(os.pread(fd, min(1 << 20, end - at), at))
            pos = end
        h.update(f"size {size}\n".encode())
    return h.hexdigest()


def snapshot(folder: Path) -> dict[str, tuple[str, int, str]]:
    """Every entry below ``folder`` (hidden ones included): relative path → (kind, size, digest of a
    regular file's content (:func:`_digest`); '' otherwise). Links are not followed."""
    out: dict[str, tuple[str, int, str]] = {}
    for p in sorted(folder.rglob("*")):
        st = p.lstat()
        if stat.S_ISLNK(st.st_mode):
            out[str(p.relative_to(folder))] = ("link", 0, os.readlink(p))
        elif stat.S_ISREG(st.st_mode):
            out[str(p.relative_to(folder))] = ("file", st.st_size, _digest(p))
        elif stat.S_ISDIR(st.st_mode):
            out[str(p.relative_to(folder))] = ("dir", 0, "")
        else:
            out[str(p.relative_to(folder))] = ("special", 0, "")
    return out


@dataclass
class Outcome:
    """What a trial gave: exit code, the two streams, the folder before and after."""

    code: int
    stdout: str
    stderr: str
    before: dict[str, tuple[str, int, str]]
    after: dict[str, tuple[str, int, str]]

    def assert_clean_refusal(self, *needles: str) -> None:
        """Exit code 2, one line on standard error holding every needle, no traceback, and the
        folder exactly as it was (nothing left, nothing replaced)."""
        lines = [ln for ln in self.stderr.splitlines() if ln.strip()]
        assert self.code == 2, (self.code, self.stderr[-2000:])
        assert "Traceback" not in self.stderr, self.stderr[-2000:]
        assert len(lines) == 1, self.stderr
        for n in needles:
            assert n in lines[0], (n, lines[0])
        assert self.after == self.before, sorted(set(self.after.items()) ^ set(self.before.items()))


class TrialTimeout(BaseException):
    """A trial run in this process outlived its timeout (raised by ``SIGALRM``; a ``BaseException``
    so that the command's own error handler does not turn it into an exit status)."""


def _address_space() -> int:
    """The address space this process holds now, bytes (``VmSize``)."""
    for line in Path("/proc/self/status").read_text(encoding="ascii").splitlines():
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize in /proc/self/status")


@contextlib.contextmanager
def _limits(headroom: int, timeout: float) -> Iterator[None]:
    """Within the block: the address space limited to what the process holds plus ``headroom``
    (the soft limit: raised back on exit) and ``SIGALRM`` after ``timeout`` s raising
    :class:`TrialTimeout`."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = _address_space() + headroom
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)

    def expire(signum: int, frame: Any) -> None:
        raise TrialTimeout(f"the trial took more than {timeout} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, timeout)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _call_main(module: str, args: list[str]) -> int:
    """``MODULE.main(args)`` as ``python -m MODULE`` ends: its status; ``SystemExit`` (argparse's usage
    errors) as the interpreter reports it; an escaped exception as a traceback and status 1."""
    try:
        return int(importlib.import_module(module).main(args))
    except SystemExit as exc:
        if exc.code is None or isinstance(exc.code, int):
            return exc.code or 0
        print(exc.code, file=sys.stderr)
        return 1
    except Exception:  # noqa: BLE001 - what the interpreter does with an uncaught exception
        traceback.print_exc(file=sys.stderr)
        return 1


def run_cli(args: list[str], cwd: Path, *, module: str = "pose_uncertainty.cli", process: bool = False,
            memory: int = MEMORY_LIMIT, timeout: float = 120.0, env: dict[str, str] | None = None) -> Outcome:
    """Run the entry point ``module`` (``pose-uncertainty`` by default) with ARGS in ``cwd`` under the
    memory limit: in this process, or with ``process=True`` as ``python -m MODULE ARGS`` in a new one."""
    before = snapshot(cwd)
    if process:
        proc = subprocess.run(
            [sys.executable, "-m", module, *args],
            cwd=cwd, capture_output=True, text=True, timeout=timeout, env={**os.environ, **(env or {})},
            preexec_fn=lambda: _limit(memory), check=False,
        )  # fmt: skip
        return Outcome(proc.returncode, proc.stdout, proc.stderr, before, snapshot(cwd))
    out, err = io.StringIO(), io.StringIO()
    with contextlib.ExitStack() as stack:
        stack.enter_context(mock.patch.dict(os.environ, env or {}))
        stack.enter_context(contextlib.chdir(cwd))
        stack.enter_context(warnings.catch_warnings())
        warnings.resetwarnings()
        for action, category, where in DEFAULT_WARNING_FILTERS:
            warnings.filterwarnings(action, category=category, module=where, append=True)
        stack.enter_context(contextlib.redirect_stdout(out))
        stack.enter_context(contextlib.redirect_stderr(err))
        stack.enter_context(_limits(memory - (MEMORY_LIMIT - IN_PROCESS_HEADROOM), timeout))
        code = _call_main(module, args)
    return Outcome(code, out.getvalue(), err.getvalue(), before, snapshot(cwd))


#: A Python that restores SIGINT's default disposition, then ``exec``s the rest of its arguments.
_DEFAULT_SIGINT = "import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); os.execv(sys.argv[1], sys.argv[1:])"


def interruptible(argv: list[str]) -> list[str]:
    """``argv`` as a command that the test interrupts with SIGINT as Ctrl-C at a terminal does.

    A command started in the background by a non-interactive shell (``make test &``, a CI runner)
    inherits SIGINT *ignored*, and Python then installs no ``KeyboardInterrupt`` handler: the
    child would sleep through the test's SIGINT. A small wrapper restores the default disposition
    and ``exec``s the command, whose interpreter then installs its handler, as in a terminal (no
    ``preexec_fn``, which is unsafe in a threaded test process).
    """
    return [sys.executable, "-c", _DEFAULT_SIGINT, *argv]


def interrupt(proc: subprocess.Popen) -> None:
    """Stop a child started with :func:`interruptible` as Ctrl-C does (SIGINT), killing it if it has
    not exited 20 s later; its output is read to the end either way."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
