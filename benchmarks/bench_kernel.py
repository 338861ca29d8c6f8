"""Speed of the Monte Carlo kernel against a plain numpy loop over the steps, timed in the same run.

Run: ``.venv/bin/python -m benchmarks.bench_kernel`` (or ``make bench``).
Writes ``benchmarks/results/kernel.json``.

10⁶ particles × 100 steps of ``sampling.sample_end_poses`` (a 1 m straight, ``k = 5·10⁻⁴`` m,
midpoint steps, per-step noise), in particle-steps per second and as a ratio against the
plain numpy loop over the steps (one ``(2, n)`` draw, the midpoint step with numpy's
``cos``/``sin`` per step, on one thread), each the best of several repeats:

- a per-particle Python loop (a few hundred particles, scaled);
- the plain numpy loop;
- the numpy draws alone (the same ``standard_normal`` numbers, one thread): the floor of
  every kernel that draws them;
- the numpy kernel (``kernel="numpy"``, the reference) on 1 and 2 threads;
- the compiled kernel (``kernel="compiled"``, :mod:`pose_uncertainty.methods.mc_kernel`) on
  1 and 2 threads, and its ``trig="libm"`` variant on 1 thread;
- the first-call cost of the compiled kernel in a new process: numba's import and the load
  from its cache, and the compilation with an empty cache.

The machine may be shared: the load average (``os.getloadavg``) before and after is written
beside the rates, and each time is given as wall and CPU time (the CPU time of the calling
process, all its threads): on a loaded machine the wall times mix in the other processes,
the CPU times much less. ``ratio_ceiling_2_cores_numpy_draws``: the ratio against the numpy
loop of the draws alone on two cores, by CPU time, the most any kernel can reach while numpy
draws the normals.
"""

from __future__ import annotations

import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import mc_kernel
from pose_uncertainty.methods import sampling as sp
from pose_uncertainty.methods.particles import CHUNK_ELEMENTS

from ._common import write_results
from .bench_foundation import _loop_particle

N_PARTICLES = 1_000_000
K = 5e-4
REPEATS = 3

_FIRST_CALL = """
import time
t0 = time.perf_counter()
import numpy as np
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import sampling as sp
from pose_uncertainty.methods.particles import CHUNK_ELEMENTS
t1 = time.perf_counter()
sp.sample_end_poses(tr.straight(1.0, dt=0.01), 5e-4, 5e-4, 1000, np.random.default_rng(0), kernel="{kernel}")
print(time.perf_counter() - t1)
"""


def numpy_loop(t: tr.Trajectory, k: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """The plain numpy loop over the steps: every particle at once, one step at a time (midpoint)."""
    x, y, th = np.zeros(n), np.zeros(n), np.zeros(n)
    b = t.track
    for sr, sl in zip(t.ds_r.tolist(), t.ds_l.tolist(), strict=True):
        z = rng.standard_normal((2, n))
        r = sr + math.sqrt(k * abs(sr)) * z[0]
        l = sl + math.sqrt(k * abs(sl)) * z[1]
        ds, dth = (r + l) / 2, (r - l) / b
        phi = th + dth / 2
        x += ds * np.cos(phi)
        y += ds * np.sin(phi)
        th += dth
    return np.stack([x, y, th], axis=-1)


def python_loop(t: tr.Trajectory, k: float, n: int, rng: np.random.Generator) -> None:
    """``n`` particles, each one step at a time in plain Python floats (bench_foundation's loop)."""
    for _ in range(n):
        _loop_particle(t, k, rng)


def _best(fn: Callable[[], Any], repeat: int = REPEATS) -> tuple[float, float]:
    """Best wall time and the CPU time of that call [s], after one warm-up call."""
    fn()
    best = (math.inf, math.inf)
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        w, c = time.perf_counter() - w0, time.process_time() - c0
        if w < best[0]:
            best = (w, c)
    return best


def _first_call(kernel: str, cache_dir: str | None) -> dict[str, float]:
    """The first ``sample_end_poses`` call of a new process (numba's import included): its wall
    time [s], and the CPU time of the whole process (interpreter and imports included) [s]."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    code = _FIRST_CALL.format(kernel=kernel)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"first_call_wall_s": float(out.stdout.strip().splitlines()[-1]), "process_cpu_s": cpu}


def main() -> None:
    """Time every variant and write the results file."""
    load_before = os.getloadavg()
    t = tr.straight(1.0, dt=0.01)  # 100 steps
    steps = t.n_steps
    work = N_PARTICLES * steps
    rows: dict[str, dict[str, float]] = {}

    def record(name: str, wall: float, cpu: float, particle_steps: int = work) -> None:
        rows[name] = {"wall_s": wall, "cpu_s": cpu, "particle_steps_per_s": particle_steps / wall,
                      "particle_steps_per_cpu_s": particle_steps / cpu}  # fmt: skip
        print(f"{name:28s} {particle_steps / wall:10.3g} particle-steps/s  (wall {wall:.3f} s, CPU {cpu:.3f} s)")

    n_py = 200
    w0, c0 = time.perf_counter(), time.process_time()
    python_loop(t, K, n_py, np.random.default_rng(1))
    record("python_loop", time.perf_counter() - w0, time.process_time() - c0, n_py * steps)

    def sfc64() -> np.random.Generator:
        return np.random.Generator(np.random.SFC64(1))

    record("numpy_loop", *_best(lambda: numpy_loop(t, K, N_PARTICLES, sfc64())))
    chunk = CHUNK_ELEMENTS // steps
    buf = np.empty((2, chunk, steps))

    def draws() -> None:  # the kernels' draws: one block of a chunk's particles at a time
        g = sfc64()
        for _ in range(N_PARTICLES // chunk):
            g.standard_normal(out=buf)

    record("draws_only_1_thread", *_best(draws), chunk * (N_PARTICLES // chunk) * steps)
    for kernel in ("numpy", "compiled"):
        for workers in (1, 2):
            def run(kernel: str = kernel, workers: int = workers) -> None:
                sp.sample_end_poses(t, K, K, N_PARTICLES, np.random.default_rng(2), kernel=kernel, workers=workers)

            record(f"{kernel}_kernel_{workers}_threads", *_best(run))
    same = np.abs(
        sp.sample_end_poses(t, K, K, 100_000, np.random.default_rng(3), kernel="numpy")
        - sp.sample_end_poses(t, K, K, 100_000, np.random.default_rng(3), kernel="compiled")
    ).max()
    base = rows["numpy_loop"]["particle_steps_per_s"]
    base_cpu = rows["numpy_loop"]["particle_steps_per_cpu_s"]
    for row in rows.values():
        row["ratio_vs_numpy_loop"] = row["particle_steps_per_s"] / base
        row["cpu_ratio_vs_numpy_loop"] = row["particle_steps_per_cpu_s"] / base_cpu
    # what no kernel that draws numpy's normals can beat on 2 cores: the draws alone, split in two
    ceiling = 2 * rows["draws_only_1_thread"]["particle_steps_per_cpu_s"] / base_cpu
    print(f"ratio ceiling of any kernel drawing numpy's normals, 2 cores, by CPU time: x{ceiling:.2f}")
    first = {
        "numpy_kernel_s": _first_call("numpy", None),
        "compiled_kernel_cached_s": _first_call("compiled", None),
    }
    with tempfile.TemporaryDirectory() as empty:
        first["compiled_kernel_empty_cache_s"] = _first_call("compiled", empty)
    print(f"first call in a new process: {first}")
    print(f"largest |compiled - numpy| over 10^5 end poses: {same:.3g}")
    write_results("kernel", {
        "monte_carlo_1e6_particles_100_steps": rows,
        "first_call": first,
        "max_abs_difference_compiled_vs_numpy": float(same),
        "ratio_ceiling_2_cores_numpy_draws": ceiling,
        "min_particle_steps_for_auto": mc_kernel.MIN_PARTICLE_STEPS,
        "goal": {"particle_steps_per_s_2_threads": 1e8, "ratio_vs_numpy_loop": 7.0},
        "load_average_before": list(load_before),
        "load_average_after": list(os.getloadavg()),
    })  # fmt: skip


if __name__ == "__main__":
    main()
