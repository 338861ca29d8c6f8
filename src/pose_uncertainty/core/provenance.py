"""Where a result comes from: package version, source hash, environment.lock, git commit, machine.

Every run and study log records :func:`provenance` (with :func:`source_sha256`, the hash of
the whole package). The pipeline passes :func:`closure_sha256` of the modules a rule runs as
a rule parameter: the hash of their import closure (:func:`import_closure`), so Snakemake
reruns the rule when code it can execute changes, and only then (rewording a claim reruns
the claims and the report, not the runs).
"""

from __future__ import annotations

import ast
import ctypes
import functools
import glob
import hashlib
import os
import platform
import re
import subprocess
from pathlib import Path

import numpy as np
import scipy

from .. import __version__

__all__ = [
    "LAYERS",
    "MACHINE_KEYS",
    "PROVENANCE_KEYS",
    "closure_sha256",
    "environment_lock_sha256",
    "git_commit",
    "import_closure",
    "imports_of",
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


def _python_files(root: Path, package: str) -> dict[str, Path]:
    """Every module of ``package`` under ``root`` by dotted name (a package by its own name).

    Cached on the folders' modification times (a file added, removed or renamed changes its
    folder's): the workflow asks for it once per rule while it parses, a walk of ~250 files each.
    """
    stamp = []
    for folder, dirs, _ in os.walk(os.path.join(root, package)):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        stamp.append((folder, os.stat(folder).st_mtime_ns))
    return dict(_python_files_at(str(root), package, tuple(stamp)))


@functools.lru_cache(maxsize=8)
def _python_files_at(root: str, package: str, stamp: tuple[tuple[str, int], ...]) -> tuple[tuple[str, Path], ...]:
    del stamp  # the cache key only
    out: dict[str, Path] = {}
    for folder, dirs, files in os.walk(os.path.join(root, package)):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        prefix = tuple(os.path.relpath(folder, root).split(os.sep))
        for f in files:
            if f.endswith(".py"):
                stem = f[:-3]
                name = ".".join(prefix if stem == "__init__" else (*prefix, stem))
                out[name] = Path(folder, f)
    return tuple(out.items())


_FROM_HEAD = re.compile(r"from[ \t]+[\w.]+[ \t]+")


def _import_statements(source: str) -> list[str]:
    """The text of every statement of ``source`` that begins a line with ``import`` or ``from M import``.

    A statement runs to its line's end, through a parenthesised name list and backslash
    continuations. Found from the word ``import`` (a literal search: the whole package in
    ms, where :func:`ast.parse` of every file takes over a second).
    """
    out: list[str] = []
    seen: set[int] = set()
    for match in re.finditer(r"import\b", source):
        start = source.rfind("\n", 0, match.start()) + 1
        if start in seen:
            continue
        seen.add(start)
        head = source[start:match.start()].lstrip(" \t")
        if head and not _FROM_HEAD.fullmatch(head):
            continue
        end = source.find("\n", match.end())
        end = len(source) if end < 0 else end
        if "(" in source[match.end():end]:
            close = source.find(")", match.end())
            end = source.find("\n", close) if close >= 0 else len(source)
            end = len(source) if end < 0 else end
        while source[start:end].endswith("\\"):
            nxt = source.find("\n", end + 1)
            end = len(source) if nxt < 0 else nxt
        out.append(source[start:end].strip())
    return out


def _import_names(source: str, own_package: list[str], package: str) -> list[str]:
    """Dotted names of ``package`` that the Python ``source`` may import (see :func:`_names_in`)."""
    names: list[str] = []
    for statement in _import_statements(source):
        try:
            tree = ast.parse(statement)
        except SyntaxError:  # prose in a docstring ("from the logs import ...")
            continue
        for node in tree.body:
            if isinstance(node, ast.Import):
                names.extend(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    up = len(own_package) - (node.level - 1)
                    if up <= 0:
                        continue  # beyond the top package: not ours
                    base = ".".join(own_package[:up] + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                names.append(base)
                names.extend(f"{base}.{alias.name}" for alias in node.names if alias.name != "*")
    for m in re.finditer(rf"{re.escape(package)}(?:\.\w+)+", source):  # a module name as a string
        quote = source[m.start() - 1:m.start()]
        if quote in ("'", '"') and source[m.end():m.end() + 1] == quote:
            names.append(m.group())
    return [n for n in names if n == package or n.startswith(package + ".")]


@functools.lru_cache(maxsize=4096)
def _names_in(path: Path, root: Path, package: str, mtime_ns: int, size: int) -> tuple[str, ...]:
    """Dotted names of ``package`` that the module file ``path`` (under ``root``) may import.

    Every ``import`` and ``from ... import`` statement anywhere in the file (module level,
    functions, classes, conditionals), relative ones resolved against the file's own package;
    for ``from M import x`` both ``M`` and ``M.x`` (the closure keeps ``M.x`` when it is a
    module). A string constant that is a dotted name inside ``package`` counts as well (what
    ``importlib.import_module`` is given). A statement is found where it begins a line; one
    after ``;`` or a colon on its line (``if x: import y``) is not; an import statement written
    in a docstring is taken (more is hashed, never less). Cached on the file's mtime and size.
    """
    del mtime_ns, size  # the cache key only
    own_package = list(path.relative_to(root).parts[:-1])  # of a/b/c.py and of a/b/__init__.py: a.b
    return tuple(_import_names(path.read_text(encoding="utf-8"), own_package, package))


def imports_of(path: str | os.PathLike[str], package: str = "pose_uncertainty") -> tuple[str, ...]:
    """The modules of ``package`` that a script outside it imports (e.g. a workflow script).

    Parameters
    ----------
    path : path — a Python source file
    package : str — the top-level package whose modules are kept

    Returns
    -------
    tuple of dotted module names, sorted, as :func:`import_closure` takes them (absolute
    imports only: a script is not part of a package). Names that are attributes rather than
    modules (``from pose_uncertainty.x import f``) are kept; the closure resolves them.
    """
    tree = ast.parse(Path(path).read_bytes(), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names if alias.name != "*")
    return tuple(sorted(n for n in names if n == package or n.startswith(package + ".")))


def import_closure(*modules: str, root: str | os.PathLike[str] | None = None) -> tuple[str, ...]:
    """The package modules that importing ``modules`` can execute: their static import closure.

    Starting from ``modules`` (dotted names of one top-level package), the import statements
    of every file are parsed (nothing is imported) and each ``import`` / ``from ... import`` is
    followed, wherever it stands (module level or inside a function: a lazy import runs when
    the function does),
    relative imports resolved; a dotted string constant naming a module of the package is
    followed too (``importlib.import_module``). Importing ``a.b.c`` runs ``a/__init__.py`` and
    ``a/b/__init__.py`` first, so every module brings its parent packages. Modules outside
    the package (numpy, the standard library) are not followed: their versions are recorded
    by :func:`provenance` and pinned by ``environment.lock``.

    Parameters
    ----------
    *modules : str — dotted module names, e.g. ``pose_uncertainty.pipeline.claims``; a name
        that is no module (``pose_uncertainty.x.function``) stands for its module
    root : path, optional — the directory holding the package folder; default: that of this
        installed package

    Returns
    -------
    tuple of dotted module names, sorted (packages by their name, not ``__init__``)

    Raises
    ------
    ValueError if a name resolves to no module file under ``root``.
    """
    root_dir = Path(root) if root is not None else _PACKAGE.parent
    if not modules:
        raise ValueError("import_closure needs at least one module name, got none")
    package = modules[0].split(".")[0]
    files = _python_files(root_dir, package)
    found: set[str] = set()
    todo = list(modules)
    while todo:
        name = todo.pop()
        if name in found:
            continue
        path = files.get(name)
        if path is None:
            parent = name.rpartition(".")[0]
            if name in modules and parent not in files:
                raise ValueError(f"module {name!r}: no {name.replace('.', '/')}.py or __init__.py under {root_dir}")
            if parent:
                todo.append(parent)  # an attribute of a module: the module itself
            continue
        found.add(name)
        parts = name.split(".")
        todo.extend(".".join(parts[:i]) for i in range(1, len(parts)))  # the parent packages
        stat = path.stat()
        todo.extend(_names_in(path, root_dir, package, stat.st_mtime_ns, stat.st_size))
    return tuple(sorted(found))


def closure_sha256(*modules: str, data: tuple[str, ...] = (), root: str | os.PathLike[str] | None = None) -> str:
    """sha256 (hex) of the source that importing ``modules`` can execute (:func:`import_closure`).

    The files of the closure, and the package data files ``data``, are hashed in sorted order
    of their path relative to ``root`` (``pose_uncertainty/pipeline/claims.py``) with their
    bytes, so the hash changes exactly when one of those files does, and does not depend on
    where the package lies (a copy of the tree hashes the same).

    Parameters
    ----------
    *modules : str — dotted module names (see :func:`import_closure`)
    data : tuple of str — further files, relative to ``root`` (e.g. a template the code reads)
    root : path, optional — the directory holding the package folder; default: this package's

    Returns
    -------
    str — 64 hex digits
    """
    root_dir = Path(root) if root is not None else _PACKAGE.parent
    modules_ = import_closure(*modules, root=root_dir)
    files = _python_files(root_dir, modules_[0].split(".")[0])
    paths = {files[name] for name in modules_} | {root_dir / d for d in data}
    h = hashlib.sha256()
    for f in sorted(paths, key=lambda p: p.relative_to(root_dir).as_posix()):
        h.update(f.relative_to(root_dir).as_posix().encode() + b"\0")
        h.update(f.read_bytes() + b"\0")
    return h.hexdigest()
