"""Another machine's transcendental functions, emulated on this one.

Two machines with the same ``environment.lock`` differ in the last bits of ``sin``, ``cos``,
``exp``, ``log``… (numpy's AVX-512 kernels against the C library's scalar ``libm``, each
within 1 ulp of the true value, so up to 2 ulp apart). :func:`install` replaces numpy's and
``math``'s transcendental functions by the same functions with their results moved by
``-ulps … +ulps`` ulp, the amount chosen from the result's own bits, so that the replacement
is a deterministic function, as a real ``libm`` is.

``python tests/other_libm.py ARGS…`` runs ``pose-uncertainty ARGS…`` with them installed.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

#: numpy's functions that go to a CPU-dependent kernel or libm (sqrt and + − × ÷ are
#: correctly rounded by IEEE-754 and equal everywhere)
NUMPY = ("sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "hypot", "exp", "expm1",
         "log", "log1p", "log2", "log10", "sinh", "cosh", "tanh")  # fmt: skip
MATH = ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "hypot", "exp", "expm1", "log",
        "log1p", "log2", "log10", "sinh", "cosh", "tanh")  # fmt: skip

_MIX = np.uint64(0x9E3779B97F4A7C15)


def nudge(values: Any, ulps: int) -> Any:
    """``values`` moved by a deterministic whole number of ulp in ``[-ulps, ulps]``."""
    a = np.asarray(values, dtype=np.float64)
    with np.errstate(over="ignore"):
        bits = a.view(np.uint64) * _MIX  # wraps: a hash of the value's bits
    k = (bits >> np.uint64(58)).astype(np.int64) % (2 * ulps + 1) - ulps
    out = a + k * np.spacing(np.abs(a))
    return np.where(np.isfinite(a), out, a)


def _wrap_ufunc(f: Any, ulps: int) -> Callable[..., Any]:
    def g(*args: Any, **kwargs: Any) -> Any:
        r = f(*args, **kwargs)
        if isinstance(r, np.ndarray) and r.dtype == np.float64:
            r[...] = nudge(r, ulps)
            return r
        if isinstance(r, float | np.floating):
            return type(r)(nudge(r, ulps))
        return r

    g.__name__ = f.__name__
    return g


def _wrap_math(f: Callable[..., float], ulps: int) -> Callable[..., float]:
    def g(*args: Any) -> float:
        return float(nudge(f(*args), ulps))

    g.__name__ = f.__name__
    return g


def install(ulps: int = 2) -> None:
    """Replace numpy's and ``math``'s transcendental functions, for this process."""
    for name in NUMPY:
        setattr(np, name, _wrap_ufunc(getattr(np, name), ulps))
    for name in MATH:
        setattr(math, name, _wrap_math(getattr(math, name), ulps))


if __name__ == "__main__":
    install()
    from pose_uncertainty.cli import main

    sys.exit(main(sys.argv[1:]))
