"""Where a result comes from: package version, source hash, environment.lock, git commit, machine.

Every run and study log records :func:`provenance`; the pipeline passes
:func:`source_sha256` of the layers a rule runs as a rule parameter, so that
Snakemake reruns the rule when that code changes and no log can be left stale.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import hashlib
import os
import platform
import subprocess
from pathlib import Path

import numpy as np
import scipy

from .. import __version__

__all__ = [
    "LAYERS",
    "MACHINE_KEYS",
    "PROVENANCE_KEYS",
    "environment_lock_sha256",
    "git_commit",
    "machine",
    "provenance",
    "source_sha256",
]

#: The package's layer folders, lowest first (tests/test_layers.py checks that none imports a higher one).
LAYERS: tuple[str, ...] = ("core", "methods", "localization", "analysis", "robot", "experiments", "records", "pipeline", "present", "cli")

_PACKAGE = Path(__file__).resolve().parents[1]
_REPO_ROOT = _PACKAGE.parents[1]


@functools.lru_cache(maxsize=1)
def environment_lock_sha256() -> str | None:
    """sha256 (hex) of the ``environment.lock`` the package was built from, or None.

    Looked up, in order: ``$POSE_UNCERTAINTY_ENVIRONMENT_LOCK`` (a path); an
    ``environment.lock`` shipped inside the package; the repository root of a
    source checkout or editable install (``src/pose_uncertainty/../../``); the
    current directory and its parents.
    """
    candidates: list[Path] = []
    env = os.environ.get("POSE_UNCERTAINTY_ENVIRONMENT_LOCK")
    if env:
        candidates.append(Path(env))
    candidates.append(_PACKAGE / "environment.lock")
    candidates.append(_REPO_ROOT / "environment.lock")
    cwd = Path.cwd()
    candidates.extend(d / "environment.lock" for d in (cwd, *cwd.parents))
    for path in candidates:
        if path.is_file():
            return hashlib.sha256(path.read_bytes()).hexdigest()
    return None


@functools.lru_cache(maxsize=1)
def git_commit() -> tuple[str, bool] | None:
    """``(commit, dirty)`` of the git work tree holding this package, or None.

    Runs ``git rev-parse HEAD`` (and ``git status --porcelain --untracked-files=no``)
    in the package's own directory, so the commit is that of the code, not of the
    caller's current directory; None when git or the repository is unavailable.
    """
    here = _PACKAGE
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
        if head.returncode != 0:
            return None
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip(), bool(status.stdout.strip())


#: The keys of :func:`provenance`, in the order logs and reports show them.
PROVENANCE_KEYS: tuple[str, ...] = (
    "package_version",
    "source_sha256",
    "environment_lock_sha256",
    "git_commit",
    "git_dirty",
    "python_version",
    "numpy_version",
    "scipy_version",
    "machine",
    "numpy_cpu_baseline",
    "numpy_cpu_dispatch",
    "libc",
    "blas",
)

#: The keys of :func:`machine`: what decides the last bits of the arithmetic.
MACHINE_KEYS: tuple[str, ...] = PROVENANCE_KEYS[-5:]


@functools.cache
def _blas() -> str:
    """OpenBLAS of numpy's wheel: version, build and the kernel core it chose for this CPU."""
    libs = os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs")
    for path in sorted(glob.glob(os.path.join(libs, "libscipy_openblas*.so*"))):
        try:
            lib = ctypes.CDLL(path)
            parts = []
            for fn in ("scipy_openblas_get_config64_", "scipy_openblas_get_corename64_"):
                f = getattr(lib, fn)
                f.restype = ctypes.c_char_p
                parts.append(f().decode().strip())
        except (OSError, AttributeError):
            continue
        config, core = parts
        version = " ".join(config.split()[:2])
        return f"{version} ({core} kernels)"
    return "unknown"


@functools.cache
def machine() -> dict[str, str]:
    """What decides the last bits of this machine's arithmetic (logged in every provenance).

    Returns
    -------
    dict with :data:`MACHINE_KEYS`:
        ``machine`` (e.g. ``x86_64``); ``numpy_cpu_baseline``, the SIMD extensions numpy was
        built for; ``numpy_cpu_dispatch``, those of numpy's dispatch targets this CPU has and
        that are not disabled (``NPY_DISABLE_CPU_FEATURES``), or ``none``; ``libc`` (``glibc
        2.36``); ``blas`` (OpenBLAS version and the kernels it chose).
    """
    from numpy._core._multiarray_umath import (  # the dispatch numpy reports (np.show_runtime)
        __cpu_baseline__,
        __cpu_dispatch__,
        __cpu_features__,
    )

    found = [t for t in __cpu_dispatch__ if __cpu_features__.get(t)]
    libc, libc_version = platform.libc_ver()
    return {
        "machine": platform.machine() or "unknown",
        "numpy_cpu_baseline": " ".join(__cpu_baseline__) or "none",
        "numpy_cpu_dispatch": " ".join(found) or "none",
        "libc": f"{libc} {libc_version}".strip() or "unknown",
        "blas": _blas(),
    }


def provenance() -> dict[str, str]:
    """What produced a result: package version, source hash, environment.lock, git, versions, machine.

    Keys :data:`PROVENANCE_KEYS`; values are strings, an unknown value is ``"unknown"``.
    """
    git = git_commit()
    return {
        "package_version": __version__,
        "source_sha256": source_sha256(),
        "environment_lock_sha256": environment_lock_sha256() or "unknown",
        "git_commit": git[0] if git else "unknown",
        "git_dirty": ("true" if git[1] else "false") if git else "unknown",
        "python_version": platform.python_version(),
        "numpy_version": np.__version__,
        "scipy_version": scipy.__version__,
        **machine(),
    }


@functools.cache
def source_sha256(*layers: str) -> str:
    """sha256 (hex) of the installed package's source: every file of the given layer folders.

    With no layer, the whole package. Files are hashed in sorted order by their
    path relative to the package and their bytes (``*.py``, templates and other
    package data; caches excluded), so the hash changes exactly when the code does.
    """
    unknown = sorted(set(layers) - set(LAYERS))
    if unknown:
        raise ValueError(f"layers must be among {LAYERS}, got {unknown}")
    roots = [_PACKAGE / layer for layer in layers] if layers else [_PACKAGE]
    h = hashlib.sha256()
    for root in roots:
        if not root.exists():
            continue
        for f in sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
            h.update(str(f.relative_to(_PACKAGE)).encode() + b"\0")
            h.update(f.read_bytes() + b"\0")
    return h.hexdigest()
