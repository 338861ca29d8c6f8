"""The method guide: which method to use, with the numbers behind it, from the per-set tables.

:func:`method_guide` turns the tables that the claims read (:mod:`pose_uncertainty.pipeline.claims`)
into advice: covariance against Monte Carlo coverage, the bend of the cloud, exponential
coordinates, the control step, localization and Method C (the unscented transform, whose
per-run numbers :func:`unscented_summary` lists for the long-path sets).
"""


from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..core.stats import COVERAGE_LEVELS
from .evidence import Rows, coverage_tolerance, value_or_none

__all__ = ["LONG_SETS", "method_guide", "unscented_summary"]


def _logged(all_rows: Sequence[Mapping[str, Any]], *keys: str) -> list[Mapping[str, Any]]:
    """The rows that have every measure ``keys`` logged (none missing or NaN), in order."""
    return [r for r in all_rows if all(value_or_none(r, k) is not None for k in keys)]


def _guide_covariance(all_rows: Sequence[Mapping[str, Any]]) -> dict[str, Any] | None:
    """When Method A's ellipse holds: runs ordered by the bend ratio, the coverage rule of the claims."""
    level = COVERAGE_LEVELS["3s"]
    runs = [r for r in _logged(all_rows, "MC_coverage_3s", "A_bend_ratio") if r.get("param.monte_carlo.regime") == "per_step"]
    if not runs:
        return None
    runs.sort(key=lambda r: float(r["A_bend_ratio"]))
    short = [r for r in runs if r["MC_coverage_3s"] < level - coverage_tolerance(level, r["MC_n"])]
    worst = min(runs, key=lambda r: r["MC_coverage_3s"])
    numbers: dict[str, Any] = {
        "n_runs": len(runs), "median_coverage_3s": float(np.median([r["MC_coverage_3s"] for r in runs])),
        "worst_run": worst["run"], "worst_coverage_3s": worst["MC_coverage_3s"],
    }  # fmt: skip
    if short:
        first = short[0]
        numbers.update(first_short_run=first["run"], first_short_bend_ratio=first["A_bend_ratio"],
                       first_short_coverage_3s=first["MC_coverage_3s"],
                       n_hold_below=sum(r["A_bend_ratio"] < first["A_bend_ratio"] for r in runs))  # fmt: skip
        limit = (f"Ordered by the bend ratio ρ, all {numbers['n_hold_below']} runs with ρ < "
                 f"{first['A_bend_ratio']:.2g} held 98.89 % within 3 binomial standard errors; the first to fall "
                 f"short was {first['run']} ({100 * first['MC_coverage_3s']:.2f} %)")  # fmt: skip
    else:
        limit = "Every run held 98.89 % within 3 binomial standard errors"
    t_cov = [r["time_covariance"] for r in all_rows if value_or_none(r, "time_covariance") is not None]
    t_mc = [r["time_monte_carlo"] for r in all_rows if value_or_none(r, "time_monte_carlo") is not None]
    times = (f" Median compute time {float(np.median(t_cov)):.3g} s against {float(np.median(t_mc)):.3g} s for "
             "Monte Carlo." if t_cov and t_mc else "")  # fmt: skip
    return {
        "advice": "Method A (covariance propagation) for quick, repeated estimates while the cloud does not bend: "
                  "check ρ = σ_θ·a/(2b) from Method A's own output; trust the ellipse for ρ well below 1.",
        "evidence": f"Over {len(runs)} per-step runs the 98.89 % ellipse held a median "
                    f"{100 * numbers['median_coverage_3s']:.2f} % of the Monte Carlo particles. {limit}; the worst "
                    f"run, {worst['run']}, {100 * worst['MC_coverage_3s']:.2f} %.{times}",
        "numbers": numbers,
    }  # fmt: skip


def _largest(all_rows: Sequence[Mapping[str, Any]], key: str, *also: str) -> tuple[int, Mapping[str, Any]] | None:
    """Among the rows with ``key`` (and ``also``) logged: how many, and the one of largest ``|key|`` (None if none)."""
    rows = _logged(all_rows, key, *also)
    return (len(rows), max(rows, key=lambda r: abs(r[key]))) if rows else None


def _case(r: Mapping[str, Any]) -> str:
    """Where a guide's extreme case is: ``run <id>, σ_θ = <Method A's end σ_θ> rad``."""
    return f"run {r['run']}, σ_θ = {r.get('A_sigma_theta', math.nan):.3g} rad"


def _guide_bend(all_rows: Sequence[Mapping[str, Any]]) -> dict[str, Any] | None:
    found = _largest(all_rows, "MC_bend")
    if found is None:
        return None
    b = found[1]
    return {
        "advice": "Monte Carlo when the cloud bends (large heading uncertainty, systematic errors): a single "
                  "ellipse then misstates the shape.",
        "evidence": f"Largest bend statistic {b['MC_bend']:.3g} ({_case(b)}; 0 for an ellipse, noise level "
                    f"±{b.get('MC_bend_crit', math.nan):.2g}).",
        "numbers": {"run": b["run"], "bend": b["MC_bend"]},
    }  # fmt: skip


def _guide_expcoords(all_rows: Sequence[Mapping[str, Any]]) -> dict[str, Any] | None:
    found = _largest(all_rows, "accuracy_cartesian_hellinger", "accuracy_expcoords_hellinger")
    if found is None:
        return None
    n, bad = found
    better = sum(r["accuracy_expcoords_hellinger"] < r["accuracy_cartesian_hellinger"]
                 for r in _logged(all_rows, "accuracy_cartesian_hellinger", "accuracy_expcoords_hellinger"))  # fmt: skip
    return {
        "advice": "Method A in exponential coordinates (the banana-shaped Gaussian) instead of the Cartesian "
                  "ellipse when the heading uncertainty is large: same cost, closer to the truth.",
        "evidence": f"Hellinger distance to the Monte Carlo cloud lower in exponential coordinates in {better} of "
                    f"{n} runs; worst Cartesian case {bad['accuracy_cartesian_hellinger']:.3f} against "
                    f"{bad['accuracy_expcoords_hellinger']:.3f} ({_case(bad)}; the sampling floor there is "
                    f"{bad.get('accuracy_monte_carlo_hellinger_floor', math.nan):.2g}).",
        "numbers": {"n_better": better, "n_runs": n, "worst_run": bad["run"]},
    }  # fmt: skip


def _guide_control_step(rows: Rows) -> dict[str, Any] | None:
    ms = sorted((r for r in rows.get("M_multistep", []) if value_or_none(r, "map_velocity_region_area")),
                key=lambda r: r.get("n_steps") or 0)  # fmt: skip
    if len(ms) < 2:
        return None
    parts = ", ".join(f"{r['n_steps']} step{'s' if r['n_steps'] != 1 else ''}: "
                      f"{r['map_velocity_region_area'] * 1e4:.4g} cm²" for r in ms)  # fmt: skip
    hel = ", ".join(f"{r.get('map_velocity_hellinger_sampler', math.nan):.2g} (floor "
                    f"{r.get('map_velocity_hellinger_floor', math.nan):.2g})" for r in ms)  # fmt: skip
    return {
        "advice": "Probability maps and their motion models only for the control period they were tuned for: "
                  "their noise is per control step, so the same motion cut into more steps is predicted more "
                  "certain. Method A's k (per metre of wheel travel) has no such dependence.",
        "evidence": f"The arc V = 1 m/s, ω = 1 rad/s over 1 s, velocity model: 98.89 % region {parts}; Hellinger "
                    f"distance of each map to its model's sampler {hel}.",
        "numbers": {"region_area": {str(r["n_steps"]): r["map_velocity_region_area"] for r in ms}},
    }  # fmt: skip


def _guide_localization(all_rows: Sequence[Mapping[str, Any]]) -> dict[str, Any] | None:
    """Which Bayes filter to localize with: tracking accuracy and cost, consistency, global localization."""
    track = [r for r in all_rows if r.get("param.scenario.kind") == "tracking"
             and value_or_none(r, "loc_ekf_rms_position_error") is not None and value_or_none(r, "loc_particle_rms_position_error") is not None]
    glob = [r for r in all_rows if r.get("param.scenario.kind") == "global" and value_or_none(r, "loc_particle_success_rate") is not None]
    if not track and not glob:
        return None
    parts: list[str] = []
    numbers: dict[str, Any] = {}
    if track:
        med = {f: float(np.median([r[f"loc_{f}_rms_position_error"] for r in track])) for f in ("ekf", "particle")}
        dr = float(np.median([r["loc_dead_reckoning_rms_position_error"] for r in track
                              if value_or_none(r, "loc_dead_reckoning_rms_position_error") is not None]))  # fmt: skip
        band = {f: float(np.median([r[f"loc_{f}_nees_in_band"] for r in track if value_or_none(r, f"loc_{f}_nees_in_band") is not None]))
                for f in ("ekf", "particle")}  # fmt: skip
        times = {f: [r[f"time_{f}_step"] for r in track if value_or_none(r, f"time_{f}_step") is not None] for f in ("ekf", "particle")}
        t = {f: float(np.median(v)) * 1e3 if v else math.nan for f, v in times.items()}
        numbers.update(n_tracking=len(track), median_rms_ekf=med["ekf"], median_rms_particle=med["particle"],
                       median_rms_dead_reckoning=dr, median_ms_ekf=t["ekf"], median_ms_particle=t["particle"])  # fmt: skip
        parts.append(f"Over {len(track)} tracking runs with landmarks the median RMS position error is {med['ekf']:.3g} m "
                     f"for the EKF and {med['particle']:.3g} m for the particle filter (dead reckoning {dr:.3g} m), at "
                     f"{t['ekf']:.3g} against {t['particle']:.3g} ms per step; their NEES averaged over the runs lies "
                     f"in its 95 % band at a median {100 * band['ekf']:.1f} % and {100 * band['particle']:.1f} % of the steps.")
    if glob:
        best = max(glob, key=lambda r: (r["loc_particle_success_rate"], -(r.get("param.filters.particle.n_particles") or 0)))
        worst = min(glob, key=lambda r: r.get("param.filters.particle.n_particles") or 0)
        ekf = [r["loc_ekf_success_rate"] for r in glob if value_or_none(r, "loc_ekf_success_rate") is not None]
        numbers.update(n_global=len(glob), best_success=best["loc_particle_success_rate"],
                       best_particles=best.get("param.filters.particle.n_particles"))  # fmt: skip
        parts.append(f"In global localization the particle filter succeeded in {100 * best['loc_particle_success_rate']:.0f} % "
                     f"of the runs with {best.get('param.filters.particle.n_particles')} particles "
                     f"({100 * worst['loc_particle_success_rate']:.0f} % with {worst.get('param.filters.particle.n_particles')})"
                     + (f"; the EKF, whose single Gaussian cannot hold the hypotheses, in {100 * max(ekf):.0f} % at most."
                        if ekf else "."))  # fmt: skip
    return {
        "advice": "Localize with the EKF (Method A's prediction) when the start is known and the landmarks can be told "
                  "apart; with the particle filter (Monte Carlo's prediction), with enough particles, when the start is "
                  "unknown, the landmarks look alike or the robot may be kidnapped. The histogram filter (Method B's) "
                  "handles those too on small worlds, at a cost that grows with its cells.",
        "evidence": " ".join(parts),
        "numbers": numbers,
    }  # fmt: skip


def method_guide(rows: Rows) -> list[dict[str, Any]]:
    """When to use which method, with the numbers behind each piece of advice.

    Parameters
    ----------
    rows : mapping of set name to its rows (:func:`pose_uncertainty.core.table_io.read_table`)

    Returns
    -------
    list of ``{"advice", "evidence", "numbers"}`` — only the advice the tables hold evidence for.
    """
    all_rows = [r for rs in rows.values() for r in rs]
    items = [_guide_covariance(all_rows), _guide_bend(all_rows), _guide_expcoords(all_rows),
             _guide_unscented(rows), _guide_control_step(rows), _guide_localization(all_rows)]  # fmt: skip
    n_maps = sum(1 for r in all_rows for k in r if k.startswith("map_") and k.endswith("_region_area"))
    if n_maps:
        items.append({
            "advice": "Probability maps (Method B) for single steps with large or non-Gaussian noise, where the "
                      "full density (several peaks, off-centre peak) matters; their cost grows with the grid.",
            "evidence": f"{n_maps} maps computed; see the claims 6, 9 and 10 for their shapes.",
            "numbers": {"n_maps": n_maps},
        })  # fmt: skip
    return [g for g in items if g is not None]


_PR_KEY = "coverage_xy_98_89"


#: The long-path sets whose runs the Method C section lists.
LONG_SETS: tuple[str, ...] = ("L_straight", "L_circle")


def _c_run(set_name: str, r: Mapping[str, Any]) -> dict[str, Any] | None:
    """One per-step run's numbers on Method C against A, the banana and Monte Carlo (None if not logged)."""
    keys = ("path_length", "A_sigma_theta", "MC_n", "MC_sigma_along", "MC_sigma_across", "MC_mean_offset",
            "MC_mean_offset_C", "MC_mean_shift_along", "MC_mean_shift_across", "C_mean_shift_along",
            "C_mean_shift_across", f"accuracy_cartesian_{_PR_KEY}", f"accuracy_unscented_{_PR_KEY}",
            "accuracy_cartesian_hellinger", "accuracy_unscented_hellinger")  # fmt: skip
    if r.get("param.monte_carlo.regime") != "per_step" or any(value_or_none(r, k) is None for k in keys):
        return None
    n = float(r["MC_n"])
    return {
        "set": set_name, "run": r["run"], "path_length": r["path_length"], "sigma_theta": r["A_sigma_theta"],
        "n": n,
        "coverage": {"a": r[f"accuracy_cartesian_{_PR_KEY}"], "c": r[f"accuracy_unscented_{_PR_KEY}"],
                     "banana": value_or_none(r, f"accuracy_expcoords_{_PR_KEY}")},
        "coverage_se": math.sqrt(COVERAGE_LEVELS["3s"] * (1.0 - COVERAGE_LEVELS["3s"]) / n),
        "hellinger": {"a": r["accuracy_cartesian_hellinger"], "c": r["accuracy_unscented_hellinger"],
                      "banana": value_or_none(r, "accuracy_expcoords_hellinger"),
                      "floor": value_or_none(r, "accuracy_monte_carlo_hellinger_floor")},
        # the Monte Carlo mean's standard error along and across (its error as an estimate of the truth)
        "mean_se": {"along": r["MC_sigma_along"] / math.sqrt(n), "across": r["MC_sigma_across"] / math.sqrt(n)},
        "mean_error": {"a": r["MC_mean_offset"], "c": r["MC_mean_offset_C"],
                       "se": math.hypot(r["MC_sigma_along"], r["MC_sigma_across"]) / math.sqrt(n)},
        "shift": {"mc_along": r["MC_mean_shift_along"], "mc_across": r["MC_mean_shift_across"],
                  "c_along": r["C_mean_shift_along"], "c_across": r["C_mean_shift_across"]},
        "time": {"a": value_or_none(r, "time_covariance"), "c": value_or_none(r, "time_unscented")},
    }  # fmt: skip


def unscented_summary(rows: Rows) -> dict[str, Any] | None:
    """Where Method C beats Method A and where it still fails, from the per-run tables.

    Over the per-step runs with Monte Carlo (those have every logged number used here):

    * ``mean`` — in how many runs C's mean end position is closer to the Monte Carlo mean
      than A's (the nominal end), how many of those A misses by more than 3 standard errors
      of the Monte Carlo mean, and the run with the largest inward (across-track) shift of
      the Monte Carlo mean: ``shift_run`` (C's shift beside Monte Carlo's; A's is 0);
    * ``coverage`` — in how many runs the 98.89 % ellipse of C holds a share closer to
      98.89 % than A's, and the run where C's holds least (``worst``, with A's and the
      banana's there);
    * ``hellinger`` — in how many runs C's Hellinger distance to Monte Carlo is below A's
      and below the banana's;
    * ``long_runs`` — every such run of the long-path sets (:data:`LONG_SETS`), by set and length;
    * ``median_time`` — median compute time of A and C [s].

    Returns None when no run has logged Method C beside Monte Carlo.
    """
    runs = [c for name, t in rows.items() for r in t if (c := _c_run(name, r)) is not None]
    if not runs:
        return None
    level = COVERAGE_LEVELS["3s"]
    closer = [r for r in runs if r["mean_error"]["c"] < r["mean_error"]["a"]]
    significant = [r for r in runs if r["mean_error"]["a"] > 3.0 * r["mean_error"]["se"]]
    shift_run = max(runs, key=lambda r: abs(r["shift"]["mc_across"]) / r["mean_se"]["across"])
    worst = min(runs, key=lambda r: r["coverage"]["c"])
    best_gain = max(runs, key=lambda r: abs(r["coverage"]["a"] - level) - abs(r["coverage"]["c"] - level))
    banana = [r for r in runs if r["hellinger"]["banana"] is not None]
    t_a = [r["time"]["a"] for r in runs if r["time"]["a"] is not None]
    t_c = [r["time"]["c"] for r in runs if r["time"]["c"] is not None]
    long_runs = sorted((r for r in runs if r["set"] in LONG_SETS),
                       key=lambda r: (LONG_SETS.index(r["set"]), r["path_length"]))  # fmt: skip
    return {
        "n_runs": len(runs),
        "mean": {"n_closer": len(closer), "n_a_off": len(significant),
                 "n_closer_where_a_off": sum(r["mean_error"]["c"] < r["mean_error"]["a"] for r in significant),
                 "shift_run": shift_run},
        "coverage": {
            "n_closer": sum(abs(r["coverage"]["c"] - level) < abs(r["coverage"]["a"] - level) for r in runs),
            "worst": worst, "best_gain": best_gain,
        },
        "hellinger": {"n_below_a": sum(r["hellinger"]["c"] < r["hellinger"]["a"] for r in runs),
                      "n_below_banana": sum(r["hellinger"]["c"] < r["hellinger"]["banana"] for r in banana),
                      "n_with_banana": len(banana)},
        "long_runs": long_runs,
        "median_time": {"a": float(np.median(t_a)) if t_a else None, "c": float(np.median(t_c)) if t_c else None},
    }  # fmt: skip


def _guide_unscented(rows: Rows) -> dict[str, Any] | None:
    """Method C: where its mean beats Method A's, and where its ellipse still misses the banana's tails."""
    s = unscented_summary(rows)
    if s is None:
        return None
    m, cov = s["mean"], s["coverage"]
    sr, w = m["shift_run"], cov["worst"]
    ban = w["coverage"]["banana"]
    ban_txt = f", the banana's {100 * ban:.2f} %" if ban is not None else ""
    t = s["median_time"]
    cost = (f" Median compute time {t['c']:.3g} s against {t['a']:.3g} s for Method A."
            if t["a"] is not None and t["c"] is not None else "")  # fmt: skip
    return {
        "advice": "Method C (the unscented transform, sigma points) instead of Method A when the heading "
                  "uncertainty has grown: it puts the mean where the robot is on average — inwards on long arcs "
                  "and circles, back along a straight line — which A's nominal pose misses. It is still one "
                  "ellipse: once the cloud bends into a banana (σ_θ of tenths of a radian and more, long straight "
                  "lines) its ellipse misses the tails; use the exponential-coordinates Gaussian or Monte Carlo there.",
        "evidence": f"Over {s['n_runs']} per-step runs C's mean was closer to the Monte Carlo mean than A's in "
                    f"{m['n_closer']} ({m['n_closer_where_a_off']} of the {m['n_a_off']} runs where A's is off by "
                    f"more than 3 standard errors). On {sr['run']} ({sr['set']}, L = {sr['path_length']:.3g} m) the "
                    f"Monte Carlo mean lies {100 * sr['shift']['mc_across']:.3g} cm across the path from the nominal "
                    f"end (positive: to the left; standard error {100 * sr['mean_se']['across']:.2g} cm); C puts its mean at "
                    f"{100 * sr['shift']['c_across']:.3g} cm, A at 0. C's 98.89 % ellipse held a share closer to "
                    f"98.89 % than A's in {cov['n_closer']} of {s['n_runs']} runs; where it held least, "
                    f"{w['run']} ({w['set']}, σ_θ = {w['sigma_theta']:.3g} rad), it held "
                    f"{100 * w['coverage']['c']:.2f} % against A's {100 * w['coverage']['a']:.2f} %{ban_txt}.{cost}",
        "numbers": {"n_runs": s["n_runs"], "n_mean_closer": m["n_closer"], "n_a_off": m["n_a_off"],
                    "n_mean_closer_where_a_off": m["n_closer_where_a_off"], "shift_run": sr["run"],
                    "n_coverage_closer": cov["n_closer"], "worst_run": w["run"],
                    "worst_coverage_c": w["coverage"]["c"]},
    }  # fmt: skip
