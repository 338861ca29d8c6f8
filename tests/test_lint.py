"""House style is enforced, not hoped for: ruff (NPY, B, PT, RUF, I) and mypy on the package."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _run(*cmd: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)


def test_ruff_clean():
    res = _run(str(BIN / "ruff"), "check", "src", "tests", "benchmarks", "workflow/scripts")
    assert res.returncode == 0, res.stdout + res.stderr


@pytest.mark.slow
def test_mypy_clean():
    res = _run(str(BIN / "mypy"))
    assert res.returncode == 0, res.stdout + res.stderr
