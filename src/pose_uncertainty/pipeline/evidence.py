"""How the claims and the method guide read the per-set tables: one rule for each reading.

The rows type of the per-set tables, a logged value or None (a missing or NaN cell), and the
one verdict rule for a coverage (within a few binomial standard errors of its level).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["COVERAGE_TOLERANCE_SE", "Rows", "coverage_tolerance", "value_or_none"]

#: The per-set tables: set name → rows (one mapping of logged measures per run).
Rows = Mapping[str, Sequence[Mapping[str, Any]]]

#: Tolerance of a coverage test, in binomial standard errors √(Pr(1−Pr)/n).
COVERAGE_TOLERANCE_SE: float = 3.0


def coverage_tolerance(level: float, n: float) -> float:
    """The one verdict rule for a coverage: it holds within 3 binomial standard errors of its level."""
    return COVERAGE_TOLERANCE_SE * math.sqrt(level * (1.0 - level) / n)


def value_or_none(r: Mapping[str, Any], key: str) -> float | None:
    """The logged value ``r[key]`` as a float, None where it is missing or NaN."""
    v = r.get(key)
    return None if v is None or (isinstance(v, float) and math.isnan(v)) else float(v)
