"""Checks of run-configuration values: one-line errors naming the key, the value and what is allowed.

Shared by :mod:`pose_uncertainty.experiments.run` (the run configuration) and
:mod:`pose_uncertainty.experiments.drive_config` (its ``drive`` section). Every error has
the form ``"config key '<dotted.key>' must be <rule>, got <value>"`` or, for
unknown keys, ``"unknown config key(s) '<dotted.key>' (allowed: ...)"``.
"""

from __future__ import annotations

import functools
import inspect
import math
import re
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ..core import trajectories
from ..core.validation import NUMBER_HINT, check_int, parse_number

__all__ = ["ConfigWarning", "builder_keywords", "check_keys", "fail", "integer", "name", "real"]

_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")


class ConfigWarning(UserWarning):
    """A configuration that can run but is unusual (the message names the key and defines its measure)."""


def fail(key: str, rule: str, value: Any) -> ValueError:
    """The error for a bad value: ``config key '<key>' must be <rule>, got <value>``."""
    return ValueError(f"config key {key!r} must be {rule}, got {value!r}")


def check_keys(where: str, data: Mapping[str, Any], allowed: tuple[str, ...]) -> None:
    """Require a mapping whose keys are among ``allowed``; ``where`` is its dotted key ('' = the root)."""
    if not isinstance(data, Mapping):
        raise fail(where or "config", "a mapping", data)
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        prefix = f"{where}." if where else ""
        raise ValueError(
            f"unknown config key(s) {', '.join(repr(prefix + k) for k in unknown)} "
            f"(allowed: {', '.join(allowed)})"
        )


def real(key: str, value: Any, *, positive: bool = False, nonneg: bool = False) -> float:
    """A finite real number (not a bool), optionally > 0 or >= 0; ``"5e-4"`` written as text is read as a number."""
    value = parse_number(value)  # "5e-4": YAML 1.1 reads a float without a dot as text
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise fail(key, f"a real number {NUMBER_HINT}", value)
    v = float(value)
    if not math.isfinite(v):
        raise fail(key, "finite" + (" and > 0" if positive else " and >= 0" if nonneg else ""), value)
    if positive and not v > 0:
        raise fail(key, "> 0 (allowed: (0, inf))", value)
    if nonneg and not v >= 0:
        raise fail(key, ">= 0 (allowed: [0, inf))", value)
    return v


def integer(key: str, value: Any, *, minimum: int = 0, maximum: int | None = None) -> int:
    """An integer (not a bool) in ``[minimum, maximum]``; ``"1e5"`` or ``1e5`` (an integral float) read as 100000."""
    return check_int(f"config key {key!r}", parse_number(value, like=0), minimum, maximum)


def name(key: str, value: Any) -> str:
    """A name of letters, digits, ``_``, ``.``, ``-`` (not starting with ``.`` or ``-``)."""
    if not isinstance(value, str) or not _NAME_RE.match(value):
        raise fail(key, "a name of letters, digits, '_', '.', '-'", value)
    return value


@functools.cache
def _keyword_defaults(fn: Callable[..., Any]) -> tuple[tuple[str, Any], ...]:
    """The keyword defaults of ``fn`` and of ``from_segments`` (``fn``'s first), read once per builder."""
    defaults: dict[str, Any] = {}
    for f in (fn, trajectories.from_segments):
        for p in inspect.signature(f).parameters.values():
            if p.default is not inspect.Parameter.empty and p.name != "name":
                defaults.setdefault(p.name, p.default)
    return tuple(defaults.items())


def builder_keywords(
    where: str, fn: Callable[..., Any], data: Mapping[str, Any]
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The keyword defaults of a trajectory builder ``fn`` (and of ``from_segments``, which it
    forwards to) and the given parameters of ``data`` (all but ``name``), refusing unknown keys.

    Returns ``(defaults, params)``; raises ValueError naming the unknown ``<where>.<key>`` and
    the keys allowed for the builder ``data['name']``.
    """
    defaults = dict(_keyword_defaults(fn))
    params = {k: v for k, v in data.items() if k != "name"}
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ValueError(
            f"unknown config key(s) {', '.join(repr(f'{where}.{k}') for k in unknown)} "
            f"(allowed for {where} {data['name']!r}: {', '.join(sorted(defaults))})"
        )
    return defaults, params
