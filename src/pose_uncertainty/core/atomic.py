"""Atomic file writes: a file is either absent, its previous version, or complete.

Every writer of a pipeline output (run logs, figures, tables, claims, studies,
the report) goes through :func:`atomic_write`: the bytes go to a hidden
temporary file beside the destination, ``.<name>.<pid>-<random>.part``, which is
flushed, fsynced and renamed over the destination (``os.replace``, atomic on
POSIX within one file system). An exception removes the temporary file; a
process killed with SIGKILL leaves it behind, and the next write of the same
destination removes the ``.part`` files of writers that are no longer alive on
this machine (:func:`remove_stale_parts`), as does ``workflow/run-locked.sh``
before a pipeline run.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import socket
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

__all__ = [
    "PART_SUFFIX",
    "atomic_directory",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_text",
    "remove_stale_parts",
]

#: suffix of the temporary file of a write in progress (or of a killed writer)
PART_SUFFIX = ".part"


def _host_tag() -> str:
    """A file-name-safe tag of this machine (pids are only meaningful on their host)."""
    return re.sub(r"[^A-Za-z0-9-]+", "-", socket.gethostname().split(".")[0]) or "host"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def remove_stale_parts(dest: str | os.PathLike[str]) -> list[Path]:
    """Remove the ``.part`` files of ``dest`` left by writers that died on this machine.

    Parameters
    ----------
    dest : path of the destination file

    Returns
    -------
    list of Path — the files removed
    """
    p = Path(dest)
    pattern = re.compile(
        rf"^\.{re.escape(p.name)}\.{re.escape(_host_tag())}-(\d+)-[^/]*{re.escape(PART_SUFFIX)}$"
    )
    removed = []
    try:
        siblings = list(p.parent.iterdir())
    except FileNotFoundError:
        return []
    for q in siblings:
        m = pattern.match(q.name)
        if m and int(m.group(1)) != os.getpid() and not _pid_alive(int(m.group(1))):
            with contextlib.suppress(FileNotFoundError):
                q.unlink()
                removed.append(q)
    return removed


def _fsync_dir(parent: Path) -> None:
    """Make a rename durable (best effort: some file systems refuse)."""
    try:
        fd = os.open(parent, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_write(
    path: str | os.PathLike[str], mode: str = "wb", **open_kw: Any
) -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on a clean exit it replaces ``path``.

    Parameters
    ----------
    path : destination (its parent folders are created)
    mode : ``"wb"`` or ``"w"`` (text; ``open_kw`` such as ``encoding``, ``newline`` apply)

    Yields
    ------
    file object — write to it; do not close it

    Examples
    --------
    >>> with atomic_write("out.csv", "w", encoding="utf-8", newline="") as fh:  # doctest: +SKIP
    ...     fh.write("a,b\\n")
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb' (allowed: 'w', 'wb'), got {mode!r}")
    dest = Path(path)
    parent = dest.parent
    parent.mkdir(parents=True, exist_ok=True)
    remove_stale_parts(dest)
    fd, tmp = tempfile.mkstemp(
        prefix=f".{dest.name}.{_host_tag()}-{os.getpid()}-", suffix=PART_SUFFIX, dir=parent
    )
    try:
        with os.fdopen(fd, mode, **open_kw) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, dest)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    _fsync_dir(parent)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; return ``Path(path)``."""
    with atomic_write(path, "wb") as fh:
        fh.write(data)
    return Path(path)


def atomic_write_text(path: str | os.PathLike[str], text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8 by default); return ``Path(path)``."""
    with atomic_write(path, "w", encoding=encoding) as fh:
        fh.write(text)
    return Path(path)


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Fill a folder beside ``path`` (``<name>.part``); on a clean exit it replaces ``path``.

    A ``.part`` folder left by an earlier, killed writer is removed first; an exception
    removes it. The swap is two renames apart (the old folder removed, the new one
    renamed), so a process killed between them leaves ``path`` absent, never partial.

    Yields
    ------
    Path — the folder to write into (created)
    """
    dest = Path(path)
    part = dest.with_name(dest.name + PART_SUFFIX)
    shutil.rmtree(part, ignore_errors=True)
    part.mkdir(parents=True)
    try:
        yield part
    except BaseException:
        shutil.rmtree(part, ignore_errors=True)
        raise
    shutil.rmtree(dest, ignore_errors=True)
    part.rename(dest)
    _fsync_dir(dest.parent)
