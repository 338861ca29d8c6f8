"""Speed of Method C (the unscented transform) over many parameter sets in one call.

Run: ``.venv/bin/python -m benchmarks.bench_unscented`` (or ``make bench``).
Writes ``benchmarks/results/unscented.json``.

A 1000-step trajectory for 1000 parameter sets (k_r, k_l and track all different)
in one call of :func:`~pose_uncertainty.methods.unscented.propagate` (Cartesian)
and :func:`~pose_uncertainty.methods.unscented.propagate_se2`, against the same
function called once per set in a Python loop (measured on a subset of sets,
scaled), and against Method A's closed form on the same sets for scale.
"""

from __future__ import annotations

import time

import numpy as np

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import covariance as cv
from pose_uncertainty.methods import unscented as ut

from ._common import best_of, write_results


def main() -> None:
    """Run the benchmarks and write the results file."""
    results: dict[str, dict[str, float]] = {}
    t = tr.straight(10.0, dt=0.01)  # 1000 steps
    assert t.n_steps == 1000
    n_sets = 1000
    k_r = np.linspace(1e-5, 1e-3, n_sets)
    k_l = k_r[::-1].copy()
    track = np.linspace(0.1, 0.5, n_sets)
    method_a = best_of(lambda: cv.propagate(t, k_r, k_l, track=track))
    for name, fn in (("cartesian", ut.propagate), ("se2", ut.propagate_se2)):
        vec = best_of(lambda fn=fn: fn(t, k_r, k_l, track=track), repeat=2)
        subset = 5
        t0 = time.perf_counter()
        for i in range(subset):
            fn(t, k_r[i], k_l[i], track=track[i])
        loop = (time.perf_counter() - t0) / subset * n_sets
        results[f"unscented_{name}_1000_steps_1000_sets"] = {
            "vectorised_s": vec,
            "python_loop_s_scaled": loop,
            "python_loop_sets_measured": subset,
            "speedup": loop / vec,
            "method_a_closed_form_s": method_a,
        }
        print(
            f"unscented ({name}) 1000x1000: {vec:.2f} s; per-set loop {loop:.0f} s "
            f"(scaled from {subset} sets) -> x{loop / vec:.0f}; Method A {method_a:.3f} s"
        )
    print(f"wrote {write_results('unscented', results)}")


if __name__ == "__main__":
    main()
