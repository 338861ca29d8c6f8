"""Input checks shared by every public function.

Each check raises :class:`ValueError` with one message of the form
``"<name> must be <rule> (allowed: <range>), got <value>"`` so that a user sees
the parameter, the bad value and what is allowed.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "NUMBER_HINT",
    "as_float_array",
    "check_choice",
    "check_finite",
    "check_int",
    "check_last_axis",
    "check_nonnegative",
    "check_pose_cov",
    "check_positive",
    "check_positive_int",
    "check_probability",
    "first_line",
    "parse_number",
    "parse_numbers",
]

#: a decimal number written as text: ``1e9``, ``5e-4``, ``-2.5E+3``, ``.5``, ``7``
_NUMBER_TEXT = re.compile(r"^\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*$")
_INT_TEXT = re.compile(r"^\s*[-+]?\d+\s*$")

#: how to write a number, for messages refusing one
NUMBER_HINT = "written like 0.0005, 5.0e-4 or 5e-4"


def _show(value: Any) -> str:
    arr = np.asarray(value)
    if arr.size == 1:
        return repr(arr.ravel()[0].item())
    bad = arr.ravel()
    return f"values {bad[:4].tolist()}{' ...' if bad.size > 4 else ''}"


def as_float_array(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Convert ``value`` to a float64 array, raising ValueError naming ``name`` if impossible."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        hint = f" {NUMBER_HINT}" if isinstance(value, str) else ""
        raise ValueError(f"{name} must be numeric (allowed: real numbers{hint}), got {value!r}") from exc


def _all_finite(arr: NDArray[np.float64]) -> bool:
    """Whether every element is finite; a large array without an elementwise temporary.

    A finite sum proves every element finite (a NaN or an infinity makes any sum NaN
    or infinite); only a sum that overflows needs the elementwise test.
    """
    if arr.ndim == 0:  # a scalar (a configuration's numbers): no reduction
        return math.isfinite(float(arr))
    if arr.size >= _LARGE:
        with np.errstate(over="ignore", invalid="ignore"):
            if np.isfinite(arr.sum()):
                return True
    return bool(np.all(np.isfinite(arr)))


#: Elements from which :func:`_all_finite` and :func:`check_nonnegative` reduce instead of
#: testing elementwise (the belief of a histogram filter is checked at every step).
_LARGE = 1 << 12


def check_finite(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Return ``value`` as float64, rejecting NaN and ±inf."""
    arr = as_float_array(name, value)
    if not _all_finite(arr):
        bad = arr[~np.isfinite(arr)] if arr.ndim else arr
        raise ValueError(
            f"{name} must be finite (allowed: real numbers, no NaN or inf), got {_show(bad)}"
        )
    return arr


def check_positive(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Return ``value`` as float64, requiring every element finite and > 0."""
    arr = check_finite(name, value)
    if not (float(arr) > 0 if arr.ndim == 0 else np.all(arr > 0)):
        raise ValueError(f"{name} must be > 0 (allowed: (0, inf)), got {_show(arr[arr <= 0])}")
    return arr


def check_nonnegative(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Return ``value`` as float64, requiring every element finite and >= 0."""
    arr = check_finite(name, value)
    if not (arr.min() >= 0 if arr.size >= _LARGE else np.all(arr >= 0)):
        raise ValueError(f"{name} must be >= 0 (allowed: [0, inf)), got {_show(arr[arr < 0])}")
    return arr


def check_probability(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Return ``value`` as float64, requiring every element in the open interval (0, 1)."""
    arr = check_finite(name, value)
    if not np.all((arr > 0) & (arr < 1)):
        bad = arr[~((arr > 0) & (arr < 1))]
        raise ValueError(
            f"{name} must be a probability strictly between 0 and 1 (allowed: (0, 1)), "
            f"got {_show(bad)}"
        )
    return arr


def check_int(name: str, value: Any, minimum: int = 1, maximum: int | None = None) -> int:
    """Return ``value`` as an int, requiring an integer (not a bool) in ``[minimum, maximum]``.

    ``maximum`` None: no upper bound. The error reads ``"<name> must be an integer >= 1, got 0"``
    or ``"<name> must be an integer in [1, 1000000], got 2000000"``.
    """
    if (isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum
            or (maximum is not None and value > maximum)):  # fmt: skip
        rule = f"an integer >= {minimum}" if maximum is None else f"an integer in [{minimum}, {maximum}]"
        raise ValueError(f"{name} must be {rule}, got {value!r}")
    return int(value)


def check_positive_int(name: str, value: Any) -> int:
    """Return ``value`` as an int, requiring an integer >= 1."""
    return check_int(name, value)


def check_choice(name: str, value: Any, allowed: tuple[Any, ...]) -> Any:
    """Return ``value`` if it is one of ``allowed``, else raise ValueError listing them."""
    # True == 1: a boolean is the choice true or false only, never 1 or 0
    ok = any(value == a and isinstance(value, bool) == isinstance(a, bool) for a in allowed)
    if not ok:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, allowed))}, got {value!r}")
    return value


def check_last_axis(name: str, value: ArrayLike, n: int) -> NDArray[np.float64]:
    """Return ``value`` as float64, requiring its last axis to have length ``n``."""
    arr = as_float_array(name, value)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}), got shape {arr.shape}")
    return arr


def check_pose_cov(name: str, value: ArrayLike | None) -> NDArray[np.float64]:
    """A pose covariance, shape (..., 3, 3) over (x [m], y [m], θ [rad]): symmetric, PSD.

    ``None`` is the zero covariance (a known pose). Raises ValueError naming
    ``name``, the problem and what is allowed.
    """
    if value is None:
        return np.zeros((3, 3))
    S = check_finite(name, value)
    if S.shape[-2:] != (3, 3):
        raise ValueError(f"{name} must have shape (..., 3, 3), got shape {S.shape}")
    if not np.allclose(S, np.swapaxes(S, -1, -2)):
        raise ValueError(f"{name} must be symmetric (allowed: symmetric positive semi-definite 3x3)")
    eig = np.linalg.eigvalsh(S)
    if np.any(eig < -1e-12 * max(1.0, float(np.abs(S).max()))):
        raise ValueError(
            f"{name} must be positive semi-definite (allowed: symmetric, eigenvalues >= 0), "
            f"got eigenvalues {eig.tolist()}"
        )
    return S


def parse_number(value: Any, like: Any = None) -> Any:
    """A number written as text → the number; anything else unchanged.

    YAML 1.1 (PyYAML, hence Snakemake and our config files) reads ``1e9`` and ``5e-4``
    — a float without a dot — as the *strings* ``"1e9"`` and ``"5e-4"``. Config
    readers pass every value that should be a number through this function:
    ``"7"`` → 7, ``"1e9"`` → 1e9; a float equal to an integer becomes an int when
    ``like`` (the key's default) is an int (``"2e7"`` → 20000000). Strings that are
    not decimal numbers (``"abc"``, ``"inf"``) are returned unchanged, to be refused
    by the caller's check.
    """
    if isinstance(value, str):
        if _INT_TEXT.match(value):
            value = int(value)
        elif _NUMBER_TEXT.match(value):
            value = float(value)
    if (
        isinstance(like, int)
        and not isinstance(like, bool)
        and isinstance(value, float)
        and value.is_integer()
    ):
        return int(value)
    return value


def parse_numbers(value: Any, like: Any = None, *, text_keys: frozenset[str] = frozenset()) -> Any:
    """:func:`parse_number` through mappings and lists: the one walker of numbers written as text.

    Returns a copy of ``value`` (mappings as dicts, tuples as lists) with every number written
    as text parsed. ``like`` is a template of the same shape (a key's default): an item of a
    list is typed by ``like[0]``, a value of a mapping by ``like[key]``, so an integral float
    whose default is an int becomes an int. The values of the keys in ``text_keys`` (titles,
    labels, names) stay as written.
    """
    if isinstance(value, Mapping):
        sub = like if isinstance(like, Mapping) else {}
        return {
            k: v if k in text_keys else parse_numbers(v, sub.get(k), text_keys=text_keys)
            for k, v in value.items()
        }
    if isinstance(value, list | tuple):
        item = like[0] if isinstance(like, list | tuple) and like else None
        return [parse_numbers(v, item, text_keys=text_keys) for v in value]
    return parse_number(value, like)


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type's name when it has none), for a one-line error."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
