"""Reading configuration files safely: kind and size checked first, duplicate keys refused.

Every configuration the package reads from a file — a run or localization configuration,
a world file, a robot file — goes through :func:`read_mapping_file`, which

* refuses anything but a regular file (a FIFO, ``/dev/zero``, a directory) before opening
  it for reading, so that a device cannot be read without end;
* refuses a file larger than :data:`MAX_CONFIG_BYTES` before reading it, and never reads
  more than that many bytes (a file that grows while it is read is refused too);
* parses YAML with :class:`UniqueKeyLoader` (PyYAML's safe loader that refuses a mapping
  holding a key twice, naming the key and both lines) and JSON with a hook that does the same;
* raises :class:`InputFileError`, a ValueError whose message is one line naming the file,
  the problem and what is allowed.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

import yaml

from .atomic import file_kind

__all__ = ["MAX_CONFIG_BYTES", "InputFileError", "UniqueKeyLoader", "parse_mapping", "read_mapping_file",
           "read_text_file"]  # fmt: skip

#: Largest configuration file read [bytes]: the shipped pipeline config is ~20 kB, a world file
#: with a thousand landmarks ~50 kB; 4 MiB leaves a wide margin and bounds what parsing costs.
MAX_CONFIG_BYTES = 4 * 1024 * 1024


class InputFileError(ValueError):
    """A configuration file that cannot be used: one line naming the file and what is allowed."""


def read_text_file(path: str | Path, what: str = "config", limit: int = MAX_CONFIG_BYTES) -> str:
    """The text (UTF-8) of a regular file of at most ``limit`` bytes.

    The kind and size are checked on the path (``stat``, following a symlink) before the file
    is opened, and again on the open descriptor; at most ``limit + 1`` bytes are read.

    Raises
    ------
    InputFileError
        One line: ``<path>: no such file``, ``<path>: not a <what> file (a FIFO); allowed: a
        regular file``, ``<path>: <what> file of N bytes is too large (allowed: at most 4 MiB)``,
        ``<path>: cannot read (...)``, ``<path>: not UTF-8 text (...)``.
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise InputFileError(f"{p}: no such file") from None
    except OSError as exc:
        raise InputFileError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputFileError(f"{p}: not a {what} file ({file_kind(st.st_mode)}); allowed: a regular file")
    _check_size(p, what, st.st_size, limit)
    try:
        # O_NONBLOCK: a path swapped for a FIFO between stat and open cannot block the open
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as fh:
            st = os.fstat(fh.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise InputFileError(f"{p}: not a {what} file ({file_kind(st.st_mode)}); allowed: a regular file")
            data = fh.read(limit + 1)
    except OSError as exc:
        raise InputFileError(f"{p}: cannot read ({exc.strerror or exc})") from None
    _check_size(p, what, len(data), limit)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"{p}: not UTF-8 text ({exc.reason} at byte {exc.start}); allowed: a UTF-8 {what} "
                             "file") from None  # fmt: skip


def _check_size(p: Path, what: str, size: int, limit: int) -> None:
    if size > limit:
        raise InputFileError(f"{p}: {what} file of {size:,} bytes is too large "
                             f"(allowed: at most {limit:,} bytes)")  # fmt: skip


class _UniqueKeys(yaml.constructor.SafeConstructor):
    """Refuse a mapping that holds a key twice (mixed into a safe loader, before its parser)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        """The mapping of ``node``; :class:`DuplicateKeyError` on a repeated key."""
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # '<<' merges are not keys
                continue
            key = self.construct_object(key_node, deep=True)
            line = key_node.start_mark.line + 1
            try:
                first = seen.get(key)
            except TypeError:  # an unhashable key: the base class refuses it
                continue
            seen[key] = line
            if first is not None:
                raise DuplicateKeyError(f"duplicate key {key!r} on lines {first} and {line} (allowed: each key once)")
        return super().construct_mapping(node, deep=deep)


class DuplicateKeyError(yaml.YAMLError):
    """A YAML mapping holding one key twice (the message names the key and both lines)."""


class UniqueKeyLoader(_UniqueKeys, yaml.SafeLoader):
    """PyYAML's safe loader, refusing a mapping that holds a key twice (YAML forbids it; PyYAML
    would keep the last value). The error names the key and the lines of both."""


class _FastUniqueKeyLoader(_UniqueKeys, getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """:class:`UniqueKeyLoader` on libyaml's parser (ten times faster; the same values). A file it
    refuses is read again by :class:`UniqueKeyLoader`, whose error the user sees."""


for _loader in (UniqueKeyLoader, _FastUniqueKeyLoader):
    _loader.add_constructor("tag:yaml.org,2002:map", _loader.construct_yaml_map)  # type: ignore[attr-defined]


def _json_pairs(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"duplicate key {k!r} (allowed: each key once)")
        out[k] = v
    return out


def _load_yaml(text: str) -> Any:
    """``text`` read by the fast loader; on any error, by the pure-Python one (whose error is raised)."""
    try:
        return yaml.load(text, Loader=_FastUniqueKeyLoader)
    except Exception:  # noqa: BLE001 - the error the user sees is the reference loader's
        return yaml.load(text, Loader=UniqueKeyLoader)


def parse_mapping(text: str, name: str, json_syntax: bool = False, what: str = "config",
                  empty_ok: bool = False) -> dict[str, Any]:
    """Parse ``text`` (YAML, or JSON when ``json_syntax``) into a mapping; ``name`` names it in errors
    (an empty text is ``{}`` when ``empty_ok``).

    Raises
    ------
    InputFileError
        ``<name>: not valid YAML (<the parser's first line>)`` (a repeated key among them),
        ``<name>: empty <what> file; allowed: a mapping of keys``, ``<name>: the <what> must be a
        mapping, got list``.
    """
    try:
        if json_syntax:
            data = json.loads(text, object_pairs_hook=_json_pairs)
        else:
            data = _load_yaml(text)
    except DuplicateKeyError as exc:
        raise InputFileError(f"{name}: {exc}") from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise InputFileError(f"{name}: not valid YAML ({exc.problem or exc.context}{where})") from None
    except Exception as exc:  # noqa: BLE001 - any parser error is a bad file
        first = " ".join(str(exc).split()) or type(exc).__name__
        raise InputFileError(f"{name}: not valid {'JSON' if json_syntax else 'YAML'} ({first[:300]})") from None
    if data is None and empty_ok:
        return {}
    if data is None:
        raise InputFileError(f"{name}: empty {what} file; allowed: a mapping of keys")
    if not isinstance(data, dict):
        raise InputFileError(f"{name}: the {what} must be a mapping, got {type(data).__name__}")
    return data


def read_mapping_file(path: str | Path, what: str = "config", empty_ok: bool = False) -> dict[str, Any]:
    """A mapping read from a YAML or JSON file (JSON by the suffix ``.json``), checked first.

    See :func:`read_text_file` and :func:`parse_mapping` for the checks and their errors.
    """
    p = Path(path)
    return parse_mapping(read_text_file(p, what), str(p), p.suffix.lower() == ".json", what, empty_ok)
