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

Only a regular file or a new path is ever replaced: :func:`check_destination` refuses a
directory, a FIFO, a socket or a device node at the destination (one line naming it), and a
symbolic link unless the caller chose to follow it (``follow_symlinks=True``; the command
line's ``--follow-symlink``), in which case its regular target is replaced and the link kept.
An :class:`OSError` of the write (a full disk, a read-only file system) names the destination,
never the hidden temporary file.

SIGTERM and SIGHUP (a ``timeout``, a cluster's time limit, a closed terminal), like SIGINT,
remove the temporary file of a write in progress: :func:`termination_as_exception` turns them
into :class:`Terminated`, which unwinds through :func:`atomic_write` like ``KeyboardInterrupt``;
the command line then exits with status 128 + the signal's number.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import signal
import socket
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

__all__ = [
    "PART_SUFFIX",
    "OutputError",
    "Terminated",
    "atomic_directory",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_text",
    "check_destination",
    "file_kind",
    "live_parts",
    "remove_stale_parts",
    "termination_as_exception",
]

#: suffix of the temporary file of a write in progress (or of a killed writer)
PART_SUFFIX = ".part"


class OutputError(OSError):
    """An output path that must not be replaced; ``str()`` is one line naming it."""

    def __init__(self, path: str | os.PathLike[str], problem: str, code: int = errno.EEXIST) -> None:
        super().__init__(code, problem, os.fspath(path))

    def __str__(self) -> str:
        return f"{self.filename}: {self.strerror}"


class Terminated(BaseException):
    """SIGTERM or SIGHUP arrived (see :func:`termination_as_exception`); ``signum`` is its number."""

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        super().__init__(f"terminated by {signal.Signals(self.signum).name}")


#: the temporary files of the writes in progress in this process
_LIVE: set[str] = set()


def live_parts() -> list[str]:
    """The temporary ``.part`` files of this process's writes in progress (absolute paths)."""
    return sorted(_LIVE)


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated(signum)


@contextlib.contextmanager
def termination_as_exception(signals: tuple[int, ...] = (signal.SIGTERM, signal.SIGHUP)) -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Terminated` (in the main thread).

    The exception unwinds through :func:`atomic_write` and :func:`atomic_directory`, which
    remove their temporary files, as SIGINT's ``KeyboardInterrupt`` does; the previous handlers
    are restored on exit. Outside the main thread (where handlers cannot be set) it does nothing.
    """
    try:
        previous = {s: signal.signal(s, _raise_terminated) for s in signals}
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
)


def file_kind(mode: int) -> str:
    """What a file that is not a regular one is, from its ``st_mode``, for a one-line error
    (``"a directory"``, ``"a FIFO (named pipe)"``, …; ``"not a regular file"`` otherwise)."""
    return next((what for test, what in _KINDS if test(mode)), "not a regular file")


def check_destination(path: str | os.PathLike[str], *, follow_symlinks: bool = False,
                      directory: bool = False) -> Path:  # fmt: skip
    """The file a write of ``path`` replaces, or :class:`OutputError` if it must not be replaced.

    Parameters
    ----------
    path : the destination as the user named it
    follow_symlinks : a symbolic link at ``path``: False (default) refuses it; True writes to its
        target, which must itself be a regular file (a folder with ``directory``) or a new path
    directory : the destination is a folder (:func:`atomic_directory`): a folder is replaced,
        a regular file is refused

    Returns
    -------
    Path — ``path``, or the target of the link when it is followed

    Raises
    ------
    OutputError — a directory (for a file), a FIFO, a socket, a device node, a refused link
    """
    dest = Path(path)
    try:
        st = os.lstat(dest)
    except FileNotFoundError:
        return dest
    except NotADirectoryError:
        raise OutputError(dest, "a parent of the path is not a directory", errno.ENOTDIR) from None
    if stat.S_ISLNK(st.st_mode):
        target = os.readlink(dest)
        if not follow_symlinks:
            raise OutputError(
                dest, f"is a symbolic link (to {target}); refusing to replace it "
                "(--follow-symlink writes to its target)",
            )  # fmt: skip
        real = Path(os.path.realpath(dest))
        checked = check_destination(real, directory=directory)
        return checked
    if directory and stat.S_ISDIR(st.st_mode):
        return dest
    if not directory and stat.S_ISREG(st.st_mode):
        return dest
    what = "a regular file" if directory else file_kind(st.st_mode)
    allowed = "a folder or a new path" if directory else "a regular file or a new path"
    code = errno.EISDIR if stat.S_ISDIR(st.st_mode) else errno.EEXIST
    raise OutputError(dest, f"is {what}; refusing to replace it (the output must be {allowed})", code)


def _naming(exc: OSError, dest: Path, tmp: str | None) -> OSError:
    """``exc`` naming ``dest`` where it named the temporary file (or nothing)."""
    if exc.filename not in (None, tmp, os.fspath(dest.parent)) or isinstance(exc, OutputError):
        return exc
    return OSError(exc.errno, exc.strerror or str(exc), os.fspath(dest))


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
    path: str | os.PathLike[str], mode: str = "wb", *, follow_symlinks: bool = False, **open_kw: Any
) -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on a clean exit it replaces ``path``.

    Parameters
    ----------
    path : destination (its parent folders are created); a regular file or a new path
        (:func:`check_destination`)
    mode : ``"wb"`` or ``"w"`` (text; ``open_kw`` such as ``encoding``, ``newline`` apply)
    follow_symlinks : write to the target of a symbolic link at ``path`` instead of refusing it

    Yields
    ------
    file object — write to it; do not close it

    Raises
    ------
    OutputError — ``path`` is a directory, a special file or a refused link (nothing written)
    OSError — of the write, naming ``path`` (not the temporary file)

    Examples
    --------
    >>> with atomic_write("out.csv", "w", encoding="utf-8", newline="") as fh:  # doctest: +SKIP
    ...     fh.write("a,b\\n")
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb' (allowed: 'w', 'wb'), got {mode!r}")
    named = Path(path)
    dest = check_destination(named, follow_symlinks=follow_symlinks)
    parent = dest.parent
    tmp: str | None = None
    try:
        parent.mkdir(parents=True, exist_ok=True)
        remove_stale_parts(dest)
        fd, tmp = tempfile.mkstemp(
            prefix=f".{dest.name}.{_host_tag()}-{os.getpid()}-", suffix=PART_SUFFIX, dir=parent
        )
    except OSError as exc:
        raise _naming(exc, named, tmp) from None
    _LIVE.add(tmp)
    try:
        with os.fdopen(fd, mode, **open_kw) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        check_destination(dest)  # a special file put there meanwhile is not replaced either
        os.replace(tmp, dest)
    except OSError as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise _naming(exc, named, tmp) from None
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    finally:
        _LIVE.discard(tmp)
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

    Raises
    ------
    OutputError — ``path`` is a regular file, a special file or a symbolic link
    """
    dest = check_destination(path, directory=True)
    part = dest.with_name(dest.name + PART_SUFFIX)
    check_destination(part, directory=True)
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
