"""One definition per configuration key: type, unit, default, what is allowed, description.

Each config dataclass (:class:`~pose_uncertainty.experiments.config.RunConfig` and its
sections, :class:`~pose_uncertainty.experiments.drive_config.DriveConfig`) keeps a table of
:class:`Key` next to it. From that table alone come

* the value check with its one-line error (:meth:`Key.check`, the form of
  :mod:`pose_uncertainty.experiments.config_checks`),
* the default a missing key takes (:meth:`Key.get`),
* the unit logged with the configuration (:func:`units`),
* the JSON Schema of the key (:meth:`Key.schema`), from which
  :mod:`pose_uncertainty.experiments.schema` generates the run keys of
  ``workflow/schemas/config.schema.yaml``.

A default that belongs to a lower layer (a trajectory builder's keyword, a drive class's
field) is not copied: the key's ``default`` is :data:`FROM_CODE` and the schema generator
reads it from that code.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..core.validation import check_choice
from .config_checks import check_keys, fail, integer, name, real

__all__ = ["FROM_CODE", "Key", "check_axis", "check_partial", "key_of", "keys_schema", "section_values", "units", "vector"]


class _FromCode:
    """The default of a key read from the code it configures (a builder's keyword default)."""

    def __repr__(self) -> str:
        return "FROM_CODE"


#: The default of this key is its code's (a builder keyword, a dataclass field).
FROM_CODE: Any = _FromCode()

_TYPES = ("number", "integer", "string", "name", "boolean", "choice", "array", "section", "sections")


@dataclass(frozen=True)
class Key:
    """One configuration key.

    Attributes
    ----------
    name : str — the key (one component of the dotted path)
    kind : str — ``number``, ``integer``, ``string``, ``name`` (letters, digits, ``_ . -``),
        ``boolean``, ``choice`` (one of ``allowed``), ``array``, ``section`` (a mapping of
        ``keys``) or ``sections`` (a list of such mappings)
    unit : str or dict — ``"1"`` dimensionless, ``"-"`` not a number; a section's units when
        they are not its keys' (a nested mapping)
    doc : str — the description (required: the schema and the docs show it)
    default : any — the value of a missing key (:data:`FROM_CODE`: the code's own)
    allowed : tuple — the choices of a ``choice`` key
    lo, hi : float or None — bounds of a number (``lo``, ``hi``: the minimum and maximum of an
        integer; every count has both, so that no value can ask for unbounded memory or time)
    lo_open, hi_open : bool — whether a bound is excluded
    nullable : bool — null is allowed (and means what ``doc`` says)
    rule : str — the wording of the range in an error, where the plain interval reads badly
    extra : dict — further JSON Schema keywords (``items``, ``minItems``) of an array
    keys : tuple of Key — the keys of a section
    """

    name: str
    kind: str
    unit: Any
    doc: str
    default: Any = None
    allowed: tuple[Any, ...] = ()
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    nullable: bool = False
    rule: str = ""
    extra: Mapping[str, Any] = field(default_factory=dict)
    keys: tuple[Key, ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in _TYPES:
            raise ValueError(f"key {self.name!r}: kind must be one of {_TYPES}, got {self.kind!r}")
        if not self.doc.strip():
            raise ValueError(f"key {self.name!r} has no description (every configuration key has one)")
        if self.kind == "choice" and not self.allowed:
            raise ValueError(f"key {self.name!r}: a choice needs its allowed values")

    # --- checks -------------------------------------------------------------------------------

    def check(self, where: str, value: Any) -> Any:
        """``value`` checked (numbers written as text read as numbers); ValueError naming ``where``.

        Arrays and sections are returned unchanged: their owner checks their items.
        """
        if value is None and self.nullable:
            return None
        if self.kind == "choice":
            return check_choice(f"config key {where!r}", value, self.allowed)
        if self.kind == "boolean":
            if not isinstance(value, bool):
                raise fail(where, "true or false", value)
            return value
        if self.kind == "name":
            return name(where, value)
        if self.kind == "integer":
            return integer(where, value, minimum=0 if self.lo is None else int(self.lo),
                           maximum=None if self.hi is None else int(self.hi))
        if self.kind == "number":
            return self._number(where, value)
        return value

    def _number(self, where: str, value: Any) -> float:
        lo, hi = self.lo, self.hi
        if hi is None and lo == 0.0:  # the two common ranges keep their short wording
            return real(where, value, positive=self.lo_open, nonneg=not self.lo_open)
        v = real(where, value)
        below = lo is not None and (v <= lo if self.lo_open else v < lo)
        above = hi is not None and (v >= hi if self.hi_open else v > hi)
        if below or above:
            raise fail(where, self.rule or f"in {self.interval()}", value)
        return v

    def interval(self) -> str:
        """The allowed range of a number, ``(0, 3.14159]``."""
        left, right = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
        lo = "-inf" if self.lo is None else f"{self.lo:g}"
        hi = "inf" if self.hi is None else f"{self.hi:g}"
        return f"{left}{lo}, {hi}{right}"

    def get(self, where: str, data: Mapping[str, Any]) -> Any:
        """The checked value of this key in ``data`` (its default when missing); ``where`` is the section."""
        key = f"{where}.{self.name}" if where else self.name
        return self.check(key, data.get(self.name, self.default))

    # --- schema -------------------------------------------------------------------------------

    def schema(self, code: Any = None) -> dict[str, Any]:
        """The JSON Schema (2020-12) of this key.

        ``code`` gives the :data:`FROM_CODE` defaults: the value for a key, a mapping of its
        keys' values (nested alike) for a section.
        """
        out: dict[str, Any] = {"description": self.doc}
        if isinstance(self.unit, str):
            out["x-unit"] = self.unit
        json_type = {"number": "number", "integer": "integer", "string": "string", "name": "string",
                     "boolean": "boolean", "array": "array", "section": "object", "sections": "array"}  # fmt: skip
        if self.kind == "choice":
            out["enum"] = [*self.allowed, *([None] if self.nullable else [])]
        else:
            t = json_type[self.kind]
            out["type"] = [t, "null"] if self.nullable else t
        if self.kind == "name":
            out["pattern"] = "^[A-Za-z0-9_][A-Za-z0-9_.-]*$"
        if self.kind in ("number", "integer"):
            if self.lo is not None:  # an integral bound as an int: the error reads "> 0", not "> 0.0"
                out["exclusiveMinimum" if self.lo_open else "minimum"] = _bound(self.lo)
            if self.hi is not None and math.isfinite(self.hi):
                out["exclusiveMaximum" if self.hi_open else "maximum"] = _bound(self.hi)
        out.update(dict(self.extra))
        if self.kind == "section":
            out["additionalProperties"] = False
            out["properties"] = keys_schema(self.keys, code if isinstance(code, Mapping) else None)
        if self.kind == "sections":
            out["items"] = {"type": "object", **dict(self.extra.get("items", {})),
                            "properties": keys_schema(self.keys, code if isinstance(code, Mapping) else None)}  # fmt: skip
        if self.kind == "section":
            out["default"] = None if self.nullable else {}
        else:
            d = code if self.default is FROM_CODE else self.default
            out["default"] = list(d) if isinstance(d, tuple) else d
        return out


def _bound(bound: float) -> float | int:
    return int(bound) if float(bound).is_integer() else bound


def keys_schema(keys: tuple[Key, ...], code: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The ``properties`` of a section's JSON Schema; ``code`` gives the :data:`FROM_CODE` defaults."""
    return {k.name: k.schema((code or {}).get(k.name)) for k in keys}


def units(keys: tuple[Key, ...]) -> dict[str, Any]:
    """The unit of every key of a table, a section's as a nested mapping (in table order)."""
    out: dict[str, Any] = {}
    for k in keys:
        if k.kind in ("section", "sections") and k.keys and isinstance(k.unit, str):
            out[k.name] = units(k.keys)
        else:
            out[k.name] = dict(k.unit) if isinstance(k.unit, Mapping) else k.unit
    return out


def section_values(where: str, keys: tuple[Key, ...], data: Any,
                   code: Mapping[str, Any] | None = None) -> dict[str, Any]:  # fmt: skip
    """Every key of a section checked by its table, defaults filled in; ``where`` is its dotted key.

    Unknown keys are refused (naming them and the allowed ones); a :data:`FROM_CODE` default is
    taken from ``code``. Arrays and sections are returned as given (or their default): their
    owner checks them. ``None`` as ``data`` is the empty section.
    """
    data = {} if data is None else data
    check_keys(where, data, tuple(k.name for k in keys))
    out: dict[str, Any] = {}
    for k in keys:
        value = data.get(k.name, k.default)
        if value is FROM_CODE:
            value = (code or {})[k.name]
        out[k.name] = k.check(f"{where}.{k.name}" if where else k.name, value)
    return out


def vector(key: str, value: Any, n: int, *, nonneg: bool = False) -> list[float]:
    """A list of ``n`` finite numbers (each >= 0 when ``nonneg``); ValueError naming ``key[i]``."""
    if not isinstance(value, list | tuple) or len(value) != n:
        raise fail(key, f"a list of {n} numbers", value)
    return [real(f"{key}[{i}]", v, nonneg=nonneg) for i, v in enumerate(value)]


def key_of(table: tuple[Key, ...], name: str) -> Key:
    """The key ``name`` of a table."""
    return next(k for k in table if k.name == name)


def check_partial(where: str, keys: tuple[Key, ...], data: Any) -> None:
    """Check every key present in a partial configuration (a set's ``base``, the shared
    ``defaults``) by its table: unknown keys, types, ranges and choices, each error naming the
    full dotted key. Arrays are left to the configuration class, which checks them in context
    (and the whole run once it is complete)."""
    check_keys(where, data, tuple(k.name for k in keys))
    for k in keys:
        if k.name in data:
            _check_value(f"{where}.{k.name}" if where else k.name, k, data[k.name])


def _check_value(path: str, k: Key, value: Any) -> None:
    if value is None and k.nullable:
        return
    if k.kind == "section":
        check_partial(path, k.keys, {} if value is None else value)
    elif k.kind == "sections":
        if not isinstance(value, list | tuple):
            raise fail(path, "a list of mappings", value)
        for i, item in enumerate(value):
            check_partial(f"{path}[{i}]", k.keys, item)
    elif k.kind != "array":
        k.check(path, value)


def check_axis(where: str, keys: tuple[Key, ...], axis: Mapping[str, Any]) -> None:
    """Check the values of one sweep axis (dotted keys to lists of values) by the key tables."""
    for dotted, values in axis.items():
        if dotted == "labels":
            continue
        table, key = keys, None
        for part in dotted.split("."):
            key = next((k for k in table if k.name == part), None)
            if key is None:
                raise ValueError(f"unknown config key(s) '{where}.{dotted}' "
                                 f"(allowed: {', '.join(k.name for k in table)})")  # fmt: skip
            table = key.keys
        if not isinstance(values, list | tuple):
            raise fail(f"{where}.{dotted}", "a list of values (one per run)", values)
        for i, v in enumerate(values):
            if key is not None:
                _check_value(f"{where}.{dotted}[{i}]", key, v)
