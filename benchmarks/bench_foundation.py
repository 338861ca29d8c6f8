"""Speed of the foundation kernels against naive Python loops measured in the same run.

Run: ``.venv/bin/python -m benchmarks.bench_foundation`` (or ``make bench``).
Writes ``benchmarks/results/foundation.json``.

1. Covariance propagation of a 1000-step trajectory for 1000 parameter sets
   (k_r, k_l and track all different) in one call, against the per-step,
   per-set recursion in a Python loop (measured on a subset of sets, scaled).
2. Monte Carlo: 10⁶ particles × 100 steps, against a per-particle Python loop
   (measured on a subset of particles, scaled).
"""

from __future__ import annotations

import math
import time

import numpy as np

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import covariance as cv
from pose_uncertainty.methods import sampling as sp

from ._common import best_of, write_results


def _loop_covariance(t: tr.Trajectory, k_r: float, k_l: float, b: float) -> np.ndarray:
    """The thesis way: one 3×3 update per step, in Python, for one parameter set."""
    p = np.zeros(3)
    S = np.zeros((3, 3))
    for sr, sl in zip(t.ds_r.tolist(), t.ds_l.tolist(), strict=True):
        p, S = cv.step(p, S, sr, sl, k_r, k_l, b)
    return S


def _loop_particle(t: tr.Trajectory, k: float, rng: np.random.Generator) -> tuple[float, float, float]:
    """One particle, one step at a time, in plain Python floats."""
    x = y = th = 0.0
    b = t.track
    for sr, sl in zip(t.ds_r.tolist(), t.ds_l.tolist(), strict=True):
        r = sr + math.sqrt(k * abs(sr)) * rng.standard_normal()
        l = sl + math.sqrt(k * abs(sl)) * rng.standard_normal()
        ds, dth = (r + l) / 2, (r - l) / b
        x += ds * math.cos(th + dth / 2)
        y += ds * math.sin(th + dth / 2)
        th += dth
    return x, y, th


def main() -> None:
    """Run both benchmarks and write the results file."""
    results: dict[str, dict[str, float]] = {}

    # --- covariance --------------------------------------------------------------------
    t = tr.straight(10.0, dt=0.01)  # 1000 steps
    assert t.n_steps == 1000
    n_sets = 1000
    k_r = np.linspace(1e-5, 1e-3, n_sets)
    k_l = k_r[::-1].copy()
    track = np.linspace(0.1, 0.5, n_sets)
    vec = best_of(lambda: cv.propagate(t, k_r, k_l, track=track))
    shared = best_of(lambda: cv.propagate(t, k_r, k_l))
    subset = 5
    t0 = time.perf_counter()
    for i in range(subset):
        _loop_covariance(t, k_r[i], k_l[i], track[i])
    loop = (time.perf_counter() - t0) / subset * n_sets
    results["covariance_1000_steps_1000_sets"] = {
        "vectorised_s": vec,
        "vectorised_shared_geometry_s": shared,
        "python_loop_s_scaled": loop,
        "python_loop_sets_measured": subset,
        "speedup": loop / vec,
        "target_s": 1.0,
    }
    print(f"covariance 1000x1000: {vec:.3f} s (shared track {shared:.3f} s); "
          f"loop {loop:.1f} s (scaled from {subset} sets) -> x{loop / vec:.0f}")

    # --- Monte Carlo -------------------------------------------------------------------
    t = tr.straight(1.0, dt=0.01)  # 100 steps
    n = 1_000_000
    mc = best_of(lambda: sp.sample_end_poses(t, 5e-4, 5e-4, n, np.random.default_rng(0)), repeat=2)
    rate = n * t.n_steps / mc
    subset = 2000
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    for _ in range(subset):
        _loop_particle(t, 5e-4, rng)
    loop = (time.perf_counter() - t0) / subset * n
    results["monte_carlo_1e6_particles_100_steps"] = {
        "vectorised_s": mc,
        "particle_steps_per_s": rate,
        "python_loop_s_scaled": loop,
        "python_loop_particles_measured": subset,
        "speedup": loop / mc,
        "target_s": 2.0,
    }
    print(f"monte carlo 1e6x100: {mc:.2f} s = {rate:.3g} particle-steps/s; "
          f"loop {loop:.0f} s (scaled from {subset}) -> x{loop / mc:.0f}")
    print(f"wrote {write_results('foundation', results)}")


if __name__ == "__main__":
    main()
