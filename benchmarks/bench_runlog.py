"""Run-log speed: write and summarise a run of 1000 steps, 10⁵ end particles and 3 maps.

Targets: write ≤ 2 s, summary ≤ 1 s. The run is computed with the real
trajectory, covariance and Monte Carlo code; the three maps are synthetic
101 × 101 × 180 (x, y, θ) float64 arrays, the size of the default map grid
(1 m × 1 m at 1 cm, 2° headings; 14.7 MB each), since multi-step maps along
1000 steps take far longer to compute than to log. Timed: ``write_run`` (best
of 3), ``open_run`` + ``format_summary`` in process (best of 3), and
``pose-uncertainty replay RUN.mcap`` end to end in a fresh interpreter.

    .venv/bin/python -m benchmarks.bench_runlog     → benchmarks/results/runlog.json
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks._common import best_of, write_results
from pose_uncertainty.experiments.run import MapRecord, RunConfig, RunResult, execute
from pose_uncertainty.records.run import format_summary, open_run, write_run

CONFIG = {
    "name": "bench_runlog",
    "seed": 1,
    # circle of radius 1 m at 0.2π m/s with dt = 0.01 s: 1000 steps
    "trajectory": {"name": "circle", "radius": 1.0, "speed": 0.2 * math.pi, "dt": 0.01},
    "monte_carlo": {"n_particles": 100_000},
}
N_MAPS, NX, NY, NTH = 3, 101, 101, 180  # the default map grid: 1 m × 1 m at 1 cm, 2° headings


def _maps(result: RunResult) -> tuple[MapRecord, ...]:
    rng = np.random.default_rng(0)
    end = result.poses[-1]
    x = end[0] + np.linspace(-0.5, 0.5, NX)
    y = end[1] + np.linspace(-0.5, 0.5, NY)
    th = np.linspace(-math.pi, math.pi, NTH, endpoint=False)
    X, Y, T = np.meshgrid(x - end[0], y - end[1], th, indexing="ij")
    out = []
    for i in range(N_MAPS):
        values = np.exp(-(X**2 + Y**2) / (0.01 * (i + 1)) - T**2) * (1 + 1e-3 * rng.random(X.shape))
        out.append(MapRecord(f"map{i}", "velocity", x, y, th, values, 1e-4, {"synthetic": True}))
    return tuple(out)


def main() -> None:
    """Measure and write ``benchmarks/results/runlog.json``."""
    t0 = time.perf_counter()
    result = execute(RunConfig.from_dict(CONFIG))
    t_execute = time.perf_counter() - t0
    result = dataclasses.replace(result, maps=_maps(result))
    assert result.n_steps == 1000
    assert result.end_poses.shape == (100_000, 3)

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.mcap"
        t_write = best_of(lambda: write_run(path, result), repeat=3)
        size = path.stat().st_size
        t_summary = best_of(lambda: format_summary(open_run(path)), repeat=3)
        # end to end, as a user runs it: a fresh interpreter, imports included
        walls = []
        for _ in range(3):
            t0 = time.perf_counter()
            subprocess.run(
                [sys.executable, "-m", "pose_uncertainty.cli", "replay", str(path)],
                check=True,
                capture_output=True,
            )
            walls.append(time.perf_counter() - t0)
    results = {
        "steps": result.n_steps,
        "end_particles": int(result.end_poses.shape[0]),
        "maps": f"{N_MAPS} x ({NX}, {NY}, {NTH}) float64",
        "execute_s": round(t_execute, 4),
        "write_s": round(t_write, 4),
        "write_target_s": 2.0,
        "summary_in_process_s": round(t_summary, 4),
        "summary_cli_wall_s": round(min(walls), 4),
        "summary_target_s": 1.0,
        "file_bytes": size,
        "file_MB": round(size / 1e6, 2),
    }
    out = write_results("runlog", results)
    for key, value in results.items():
        print(f"{key:>24}: {value}")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
