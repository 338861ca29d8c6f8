"""Latency of the interactive explorer: a control's change → the redrawn views.

Run: ``.venv/bin/python -m benchmarks.bench_explore`` (or ``make bench``).
Writes ``benchmarks/results/explore.json``.

The setting of the speed goal: Methods A and C, the banana and a 5,000-particle Monte Carlo on
a 500-step path (a 2.5 m straight at 0.5 m/s, dt = 0.01 s), on one core (the process — and the
explorer's server in the browser case — pinned to one CPU, the BLAS to one thread). Each
repetition changes k_r (so nothing is reused) and times

1. ``compute``: :func:`pose_uncertainty.present.explore.compute` — validation, the cost guard,
   the run's own execution without the accuracy comparison's density distances
   (``execute(config, distances=False)``) and the drawn regions — with its breakdown from the
   run's timings;
2. ``page_update_server_side``: the k_r field of a Bokeh document set to a new value, through
   the callback to every data source and table updated (synchronous, no WebSocket, no drawing);
3. ``browser_end_to_end``: in headless Chromium on the served page (``pose-uncertainty
   explore``), from setting the k_r field in the page to the next animation frame after the
   redrawn views arrived (the status line names the new k_r), measured in the page;

against the baseline ``full_run``: :func:`pose_uncertainty.experiments.run.execute` of the same
configuration with every measure, what ``pose-uncertainty run`` computes (timed in the same run).
``compute_parts_cpu`` splits ``compute`` by CPU time into the package's functions it calls (Method
C, the Monte Carlo as the explorer runs it, the banana's region levels from 50,000 draws, its
density at the cloud, its contour grid); ``option_compiled_monte_carlo_cpu`` is the Monte Carlo by
the compiled kernel with its normals kept (not what the explorer runs: its cloud equals the run's
within the reproducibility contract, not to the bit).
Wall-clock times depend on what else runs on the machine (its load average is recorded);
``compute_cpu`` and ``full_run_cpu`` are the process's CPU times (one thread computes), the work
itself on one core.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from pose_uncertainty.experiments.config import RunConfig
from pose_uncertainty.experiments.run import execute
from pose_uncertainty.present import explore

from ._common import write_results

SETTING = {"path": "straight", "size": "2.5", "speed": "0.5", "dt": "0.01", "n_particles": "5000"}
GOAL_P95_S = 0.150
TESTS = Path(__file__).resolve().parents[1] / "tests"


def _stats(times: list[float]) -> dict[str, float]:
    a = np.asarray(times)
    return {"n": float(a.size), "p50_s": float(np.percentile(a, 50)), "p95_s": float(np.percentile(a, 95)),
            "max_s": float(a.max())}  # fmt: skip


def _one_cpu() -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


def _parts_cpu(k_values: list[str]) -> dict[str, list[float]]:
    """CPU times [s] of the package's functions a move calls, each k_r of ``k_values``."""
    from pose_uncertainty.core import trajectories
    from pose_uncertainty.methods import expcoords, sampling, unscented
    from pose_uncertainty.methods.particles import DrawCache

    out: dict[str, list[float]] = {}
    kept = DrawCache()

    def timed(name: str, fn: Any, *args: Any, **kwargs: Any) -> Any:
        c0 = time.process_time()
        got = fn(*args, **kwargs)
        out.setdefault(name, []).append(time.process_time() - c0)
        return got

    for k in k_values:
        cfg = RunConfig.from_dict(explore.run_config({**SETTING, "k_r": k}))
        traj = trajectories.from_config(cfg.trajectory)
        mc = (traj, cfg.k_r, cfg.k_l, cfg.monte_carlo.n_particles)
        timed("method_c", unscented.propagate, traj, cfg.k_r, cfg.k_l)
        cloud = timed("monte_carlo", sampling.sample_end_poses, *mc, np.random.default_rng(cfg.seed),
                      cache=explore._DRAWS)  # fmt: skip
        sampling.sample_end_poses(*mc, np.random.default_rng(cfg.seed), kernel="compiled", draws="per-chunk", cache=kept)  # its normals
        timed("option_compiled_monte_carlo", sampling.sample_end_poses, *mc, np.random.default_rng(cfg.seed),
              kernel="compiled", draws="per-chunk", cache=kept)  # fmt: skip
        E = expcoords.propagate(traj, cfg.k_r, cfg.k_l)
        mu, cov = E.poses[-1], E.covs[-1]
        timed("banana_levels_50000_draws", expcoords.hdr_threshold, mu, cov, np.array([0.5, 0.9, 0.98889]),
              np.random.default_rng([cfg.seed, 1]), n=50_000)  # fmt: skip
        timed("banana_density_at_cloud", expcoords.pdf_xy, cloud[:, :2], mu, cov)
        lo, hi = cloud[:, :2].min(axis=0), cloud[:, :2].max(axis=0)
        grid = [np.linspace(lo[a], hi[a], explore._BANANA_GRID) for a in (0, 1)]
        timed("banana_contour_grid", expcoords.marginal_xy_grid, *grid, mu, cov)
    return out


def browser_times(k_values: list[str], chromium: str = "/usr/bin/chromium") -> list[float]:
    """End-to-end times [s] of k_r moves in headless Chromium on the served explorer (pinned to one CPU).

    Uses the browser test's page fixture and its in-page timer (``tests/test_explore_browser.py``).
    """
    sys.path.insert(0, str(TESTS))
    from test_explore_browser import _wait_status, explorer_page, redraw_ms, set_field

    cpu = min(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    times = []
    with tempfile.TemporaryDirectory() as tmp, explorer_page(chromium, Path(tmp), server_cpu=cpu) as (cdp, _url):
        _wait_status(cdp, "steps", timeout=300)  # the page has drawn its first setting
        for k, v in SETTING.items():
            set_field(cdp, f"field-{k}", v)
        redraw_ms(cdp, "4.9e-4")  # warm-up: the setting drawn once
        for k in k_values:
            times.append(redraw_ms(cdp, k) / 1000.0)
    return times


def main(repeat: int = 12, browser: bool = True) -> dict[str, Any]:
    """Run the benchmark and write the results file."""
    load_before = os.getloadavg()[0]  # others' work on this machine slows every time below alike
    all_cpus = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    _one_cpu()
    k_values = [f"{k:.4g}" for k in np.geomspace(1e-4, 4e-3, repeat + 1)]
    explore.compute(explore.run_config({**SETTING, "k_r": "5e-4"}))  # warm-up (imports, caches)
    full, full_cpu = [], []
    for k in k_values[:3]:
        cfg = RunConfig.from_dict(explore.run_config({**SETTING, "k_r": k}))
        t0, c0 = time.perf_counter(), time.process_time()
        execute(cfg)
        full.append(time.perf_counter() - t0)
        full_cpu.append(time.process_time() - c0)
    compute_times: list[float] = []
    compute_cpu: list[float] = []
    parts: dict[str, list[float]] = {}
    for k in k_values[:repeat]:
        t0, c0 = time.perf_counter(), time.process_time()
        view = explore.compute(explore.run_config({**SETTING, "k_r": k}))
        compute_times.append(time.perf_counter() - t0)
        compute_cpu.append(time.process_time() - c0)
        for key, val in view.result.timings.items():
            parts.setdefault(key, []).append(val)
        parts.setdefault("regions_and_views_s", []).append(compute_times[-1] - view.result.timings["total_s"])
    parts_cpu = _parts_cpu(k_values[:repeat])
    assert view.result.n_steps == 500
    assert view.result.end_poses is not None
    assert len(view.result.end_poses) == 5000
    assert {"a", "c", "e"} <= set(view.coverage)
    from bokeh.document import Document

    doc = Document()
    explore.make_document(doc, {**SETTING, "k_r": "5e-4"}, background=False)
    field = doc.select_one({"name": "field-k_r"})
    page_times = []
    for k in k_values[1:]:
        t0 = time.perf_counter()
        field.value = k
        page_times.append(time.perf_counter() - t0)
    compute = _stats(compute_times)
    results: dict[str, Any] = {
        "setting": {**SETTING, "n_steps": 500, "methods": "A, C, banana, Monte Carlo", "cores": 1,
                    "change": "k_r, geometric steps 1e-4 … 4e-3 m"},
        "goal": {"p95_s": GOAL_P95_S},
        "machine_load": {"loadavg_1min_before": load_before, "cpus": float(os.cpu_count() or 0)},
        "full_run": {**_stats(full), "what": "execute(config): every measure, as pose-uncertainty run"},
        "compute": {**compute, "speedup_p50_vs_full_run": float(np.median(full)) / compute["p50_s"]},
        # CPU time of the process (one thread computes): the work itself, whatever else runs on the machine
        "full_run_cpu": _stats(full_cpu),
        "compute_cpu": {**_stats(compute_cpu),
                        "speedup_p50_vs_full_run": float(np.median(full_cpu)) / float(np.median(compute_cpu))},
        "compute_parts_median": {k: float(np.median(v)) for k, v in parts.items()},
        "compute_parts_cpu": {k: _stats(v) for k, v in parts_cpu.items() if not k.startswith("option")},
        "option_compiled_monte_carlo_cpu": _stats(parts_cpu["option_compiled_monte_carlo"]),
        "page_update_server_side": _stats(page_times),
    }
    if browser and Path("/usr/bin/chromium").exists():
        if all_cpus is not None:  # the server alone is pinned (to the same CPU); Chromium is not
            os.sched_setaffinity(0, all_cpus)
        try:
            results["browser_end_to_end"] = _stats(browser_times(k_values[1:]))
        except (OSError, AssertionError, TimeoutError, ConnectionError) as exc:
            results["browser_end_to_end"] = {"not_measured": f"{type(exc).__name__}: {exc}"}
    else:
        results["browser_end_to_end"] = {"not_measured": "no Chromium at /usr/bin/chromium (or --no-browser)"}
    results["machine_load"]["loadavg_1min_after"] = os.getloadavg()[0]
    path = write_results("explore", results)
    b = results["browser_end_to_end"]
    print(f"CPU: full run p50 {results['full_run_cpu']['p50_s']:.3f} s, compute p50 "
          f"{results['compute_cpu']['p50_s']:.3f} s, p95 {results['compute_cpu']['p95_s']:.3f} s ("
          + ", ".join(f"{k} {v['p50_s']:.3f}" for k, v in results["compute_parts_cpu"].items())
          + f"; option compiled Monte Carlo {results['option_compiled_monte_carlo_cpu']['p50_s']:.3f}); wall: "
          f"full run p50 {results['full_run']['p50_s']:.3f} s; compute p50 {compute['p50_s']:.3f} s, "
          f"p95 {compute['p95_s']:.3f} s; page update p95 {results['page_update_server_side']['p95_s']:.3f} s; "
          f"browser p50 {b.get('p50_s', float('nan')):.3f} s, p95 {b.get('p95_s', float('nan')):.3f} s "
          f"(goal p95 {GOAL_P95_S} s) → {path}")  # fmt: skip
    return results


if __name__ == "__main__":
    main(browser="--no-browser" not in sys.argv)
