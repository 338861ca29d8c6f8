"""Latency of the interactive explorer: a control's change → the redrawn views, server side.

Run: ``.venv/bin/python -m benchmarks.bench_explore`` (or ``make bench``).
Writes ``benchmarks/results/explore.json``.

The setting of the speed goal: Methods A and C, the banana and a 5,000-particle Monte Carlo on
a 500-step path (a 2.5 m straight at 0.5 m/s, dt = 0.01 s), on one core (the process is pinned
to one CPU and the BLAS to one thread). Each repetition changes k_r (so nothing is reused) and
times (1) :func:`pose_uncertainty.present.explore.compute` — validation, the cost guard, the
run's own execution and the drawn regions — with its breakdown from the run's timings, and
(2) the whole server-side page update: the k_r field of a Bokeh document set to a new value,
through the callback to every data source and table updated (not the WebSocket transfer nor
the browser's drawing).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time

import numpy as np

from pose_uncertainty.present import explore

from ._common import write_results

SETTING = {"path": "straight", "size": "2.5", "speed": "0.5", "dt": "0.01", "n_particles": "5000"}
GOAL_P95_S = 0.150


def _stats(times: list[float]) -> dict[str, float]:
    a = np.asarray(times)
    return {"n": float(a.size), "p50_s": float(np.percentile(a, 50)), "p95_s": float(np.percentile(a, 95)),
            "max_s": float(a.max())}  # fmt: skip


def main(repeat: int = 12) -> None:
    """Run the benchmark and write the results file."""
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    k_values = np.geomspace(1e-4, 4e-3, repeat + 1)
    explore.compute(explore.run_config({**SETTING, "k_r": "5e-4"}))  # warm-up
    compute_times, parts = [], {}
    for k in k_values[:repeat]:
        t0 = time.perf_counter()
        view = explore.compute(explore.run_config({**SETTING, "k_r": repr(float(k))}))
        compute_times.append(time.perf_counter() - t0)
        for key, val in view.result.timings.items():
            parts.setdefault(key, []).append(val)
    assert view.result.n_steps == 500
    assert view.result.end_poses is not None
    from bokeh.document import Document

    doc = Document()
    explore.make_document(doc, {**SETTING, "k_r": "5e-4"})
    field = doc.select_one({"name": "field-k_r"})
    page_times = []
    for k in k_values[1:]:
        t0 = time.perf_counter()
        field.value = repr(float(k))
        page_times.append(time.perf_counter() - t0)
    results = {
        "setting": {**SETTING, "n_steps": 500, "methods": "A, C, banana, Monte Carlo", "cores": 1},
        "goal_p95_s": GOAL_P95_S,
        "compute": _stats(compute_times),
        "compute_breakdown_median_s": {k: float(np.median(v)) for k, v in parts.items()},
        "page_update_server_side": _stats(page_times),
        "browser_end_to_end": "not measured",
    }
    path = write_results("explore", results)
    print(f"compute p50 {results['compute']['p50_s']:.3f} s, p95 {results['compute']['p95_s']:.3f} s; "
          f"page update p95 {results['page_update_server_side']['p95_s']:.3f} s (goal {GOAL_P95_S} s) → {path}")  # fmt: skip


if __name__ == "__main__":
    main()
