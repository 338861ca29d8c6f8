"""Shared machinery of the hostile-input trials (``tests/test_hostile_*.py``).

A trial runs the ``pose-uncertainty`` console entry point in a subprocess, in a scratch
folder, under an address-space limit (``resource.RLIMIT_AS``), so that a regression that
reads a huge input whole fails the test instead of taking the machine down. It returns
what a user sees: the exit code, standard output and standard error, and the scratch
folder's files before and after (name → (kind, size, sha256)), so a trial can assert that
nothing was left behind or replaced.
"""

from __future__ import annotations

import hashlib
import os
import resource
import stat
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

#: address-space limit of a trial's process: far above what a refused input needs (numpy,
#: scipy, matplotlib and mcap imported take ~1 GiB of address space), far below the machine's 24 GiB
MEMORY_LIMIT = 3 * 1024**3


def _limit(memory: int) -> None:  # pragma: no cover - runs in the child
    resource.setrlimit(resource.RLIMIT_AS, (memory, memory))


def snapshot(folder: Path) -> dict[str, tuple[str, int, str]]:
    """Every entry below ``folder`` (hidden ones included): relative path → (kind, size, sha256 of a
    regular file's bytes; '' otherwise). Links are not followed."""
    out: dict[str, tuple[str, int, str]] = {}
    for p in sorted(folder.rglob("*")):
        st = p.lstat()
        if stat.S_ISLNK(st.st_mode):
            out[str(p.relative_to(folder))] = ("link", 0, os.readlink(p))
        elif stat.S_ISREG(st.st_mode):
            out[str(p.relative_to(folder))] = ("file", st.st_size, hashlib.sha256(p.read_bytes()).hexdigest())
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


def run_cli(args: list[str], cwd: Path, *, memory: int = MEMORY_LIMIT, timeout: float = 120.0,
            env: dict[str, str] | None = None) -> Outcome:
    """Run ``python -m pose_uncertainty.cli ARGS`` in ``cwd`` under the memory limit."""
    before = snapshot(cwd)
    full_env = {**os.environ, **(env or {})}
    proc = subprocess.run(
        [sys.executable, "-m", "pose_uncertainty.cli", *args],
        cwd=cwd, capture_output=True, text=True, timeout=timeout, env=full_env,
        preexec_fn=lambda: _limit(memory), check=False,
    )
    return Outcome(proc.returncode, proc.stdout, proc.stderr, before, snapshot(cwd))
