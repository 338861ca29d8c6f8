"""The studies section of the report: the logged results by name and the numbers the text quotes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

#: The study kinds of Skalka 2011's localization techniques (their report sections and claims find them by kind).
SKALKA_KINDS: tuple[str, ...] = (
    "relative_sensing", "absolute_sensing", "guaranteed_bounds", "representations", "active_localization",
    "dynamic_environment", "scan_matching",
)


def summarize(results: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """The studies section's data: every study's results by name and the numbers the text quotes.

    Parameters
    ----------
    results : mapping name → ``{"study": kind, "results": ...}`` — the logged studies, in
        config order

    Returns
    -------
    dict: ``studies`` — results by name, plus ``accuracy_table`` (the ``accuracy_case``
    studies' results in order); ``summary`` — (each only when its study is present):
    ``accuracy`` — Method A's worst 98.89 % coverage and its case, the banana's range, the
    rows by case; ``distance`` — first and last rows of the coverage along a path;
    ``growth`` — in how many fits the power law has the smaller rms log residual, and the
    median residuals; ``calibration`` — the equal-k row of each model; ``umbmark`` — the
    first UMBmark study's name, E_max before and after the correction, their ratio and
    which delta intervals hold the true values; ``skalka`` — the names of the studies of each kind of
    :data:`SKALKA_KINDS` (Skalka 2011's localization techniques), in config order.
    """
    studies: dict[str, Any] = {name: r["results"] for name, r in results.items()}
    table = [r["results"] for r in results.values() if r["study"] == "accuracy_case"]
    if table:
        studies["accuracy_table"] = table
    out: dict[str, Any] = {}
    if table:
        out["accuracy"] = _accuracy_summary(table)
    dist = next((r["results"] for r in results.values() if r["study"] == "accuracy_vs_distance"), None)
    if dist:
        out["distance"] = {"first": dist[0], "last": dist[-1]}
    fits = [f for r in results.values() if r["study"] == "growth_laws"
            for method in r["results"].values() for f in method.values()]  # fmt: skip
    if fits:
        power = [f["power_rms_log_residual"] for f in fits]
        expo = [f["exp_rms_log_residual"] for f in fits]
        out["growth"] = {
            "n_power_better": int(sum(a < b for a, b in zip(power, expo, strict=True))),
            "median_power_residual": float(np.median(power)),
            "median_exp_residual": float(np.median(expo)),
            "n_fits": len(fits),
        }
    cal = next((r["results"] for r in results.values() if r["study"] == "calibration_demo"), None)
    if cal:
        out["calibration"] = {r["coords"]: r for r in cal["rows"] if r["equal"]}
    techniques = {kind: [name for name, r in results.items() if r["study"] == kind] for kind in SKALKA_KINDS}
    if any(techniques.values()):
        out["skalka"] = {kind: names for kind, names in techniques.items() if names}
    umb = next((name for name, r in results.items() if r["study"] == "umbmark"), None)
    if umb:
        out["umbmark"] = _umbmark_summary(umb, results[umb]["results"])
    return {"studies": studies, "summary": out}


def _umbmark_summary(name: str, res: Mapping[str, Any]) -> dict[str, Any]:
    """The UMBmark study's headline numbers: E_max before/after and how many intervals hold the truth."""
    est = res["umbmark"]["estimates"]
    before, after = est["E_max_before"]["value"], res["umbmark"]["E_max_after_measured"]["value"]
    rows = {r["quantity"]: r for r in res["recovered"]}
    return {
        "study": name, "E_max_before": before, "E_max_after": after, "improvement": before / after,
        "n_covered": sum(r["delta_covers"] for r in res["recovered"]), "n_quantities": len(rows),
        "umbmark_covers": {q: rows[q]["delta_covers"] for q in ("E_d", "E_b") if q in rows},
        "fit_covers": {q: rows[q]["delta_covers"] for q in ("E_d_fit", "E_b_fit") if q in rows},
    }  # fmt: skip


def _accuracy_summary(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    key = "coverage_xy_98.89"
    worst = min(rows, key=lambda r: r["cartesian"][key])
    ban = [r["expcoords"][key] for r in rows if "expcoords" in r]
    c_rows = [r for r in rows if "unscented" in r]  # Method C
    worst_c = min(c_rows, key=lambda r: r["unscented"][key]) if c_rows else None
    return {
        "worst_a": worst["cartesian"][key], "worst_case": worst["case"],
        "best_a": max(r["cartesian"][key] for r in rows),
        "banana_min": min(ban) if ban else None, "banana_max": max(ban) if ban else None,
        "worst_c": worst_c["unscented"][key] if worst_c else None,
        "worst_c_case": worst_c["case"] if worst_c else None,
        "best_c": max(r["unscented"][key] for r in c_rows) if c_rows else None,
        "n_cases": len(rows), "by_case": {r["case"]: r for r in rows},
    }  # fmt: skip
