"""Speed of the exponential-coordinates propagation, the accuracy measures and calibration.

Run: ``.venv/bin/python -m benchmarks.bench_accuracy`` (or ``make bench``).
Writes ``benchmarks/results/accuracy.json``.

1. Exp-coords propagation along a 2000-step path: closed form (prefix sums) against
   the step recursion.
2. The banana's planar density at 10⁵ points (Gauss–Hermite over the heading,
   64 nodes) — the kernel of the coverage and likelihood measures.
3. ``accuracy.compare_methods`` on a cloud of 10⁵ particles (both Gaussian
   methods, 60 × 60 grid, 2·10⁵ draws for the banana's thresholds).
4. ``calibration.fit_k`` with profile-likelihood intervals on 10⁴ end poses.
"""

from __future__ import annotations

import numpy as np

from pose_uncertainty.analysis import accuracy as ac
from pose_uncertainty.analysis import calibration as cb
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import covariance as cv
from pose_uncertainty.methods import expcoords as ec
from pose_uncertainty.methods import sampling as sp

from ._common import best_of, write_results


def main() -> None:
    """Run the benchmarks and write the results file."""
    results: dict[str, dict[str, float]] = {}

    t = tr.straight(20.0, dt=0.01, track=0.2)  # 2000 steps
    closed = best_of(lambda: ec.propagate(t, 5e-4, 5e-4))
    recursive = best_of(lambda: ec.propagate_recursive(t, 5e-4, 5e-4), repeat=1)
    results["expcoords_propagate_2000_steps"] = {
        "closed_form_s": closed,
        "recursive_s": recursive,
        "speedup": recursive / closed,
    }
    print(f"exp-coords propagation, 2000 steps: closed {closed:.4f} s, recursive {recursive:.3f} s")

    t1 = tr.straight(1.0, dt=0.01, track=0.2)
    E = ec.propagate(t1, 5e-4, 5e-4)
    A = cv.propagate(t1, 5e-4, 5e-4)
    cloud = sp.sample_end_poses(t1, 5e-4, 5e-4, 100_000, np.random.default_rng(1))
    pts = cloud[:, :2].copy()
    dens = best_of(lambda: ec.pdf_xy(pts, E.poses[-1], E.covs[-1]))
    results["banana_pdf_xy_1e5_points"] = {"seconds": dens, "points_per_s": 1e5 / dens}
    print(f"banana planar density at 1e5 points: {dens:.3f} s")

    cmp_s = best_of(
        lambda: ac.compare_methods(
            cloud,
            (A.poses[-1], A.covs[-1]),
            (E.poses[-1], E.covs[-1]),
            np.random.default_rng(2),
        ),
        repeat=2,
    )
    results["compare_methods_1e5_particles"] = {"seconds": cmp_s}
    print(f"compare_methods, 1e5 particles: {cmp_s:.3f} s")

    ends = cloud[:10_000]
    fit_s = best_of(lambda: cb.fit_k(ends, t1), repeat=2)
    results["fit_k_profile_1e4_poses"] = {"seconds": fit_s}
    print(f"fit_k (k_r, k_l, profile intervals), 1e4 poses: {fit_s:.3f} s")

    path = write_results("accuracy", results)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
