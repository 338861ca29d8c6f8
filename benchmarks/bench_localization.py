"""Speed of the localization filters against PythonRobotics-style Python loops, in the same run.

Run: ``.venv/bin/python -m benchmarks.bench_localization`` (or ``make bench``).
Writes ``benchmarks/results/localization.json``.

1. Particle filter (MCL): 10⁴ particles, 20 landmarks, 1000 steps (a 20 m × 20 m room,
   two laps of a 6 m square at 0.5 m/s, Δt = 0.1 s, range–bearing sensor every step with an
   8 m range and a full field of view: 13 landmarks seen per step on average), wheel-noise
   prediction, systematic resampling at ESS < n/2; float64 and float32 arithmetic, each on 1 and
   2 threads (the particles in two blocks, each with its own spawned generator: the same result
   on any number of threads), the fastest of ``REPEATS`` runs (the machine is shared: the load
   average is recorded). Particle-updates per second = particles × steps / Σ per-step
   kernel time (prediction + weighting + resampling; the measures computed for the logs are outside).
   ``goal_met``: the best configuration (at most the 2 cores) reaches 10⁷. A profile of one thread's
   step (ms per step in each part, the measures between the steps as in a run) says where the time goes.
   Baseline: the per-particle Python loop of PythonRobotics' ``particle_filter.py``
   (sample motion, weight by each observed landmark with ``math.exp``, low-variance
   resampling in a loop), timed on 100 particles × 100 steps and scaled.
2. Histogram filter: one step on 128 × 128 × 72 cells (12.8 m × 12.8 m at 0.1 m, 5°),
   velocity-model prediction (the multi-step map's FFT step) and the update with 8 landmark
   measurements: with the transition of a repeated control cached (its kernel and per-heading
   windows: the goal's step), and with a new control every step (kernel and windows built
   in the step, as with noisy odometry). Baseline: the per-cell Python loop of the update (range and
   bearing likelihood of every cell and heading), timed on 2000 cells and scaled; the
   prediction's per-cell loop (each cell pushed through a 3 × 3 × 3 kernel) likewise.
3. EKF: 1000 steps of EKF localization (Method A prediction, stacked landmark update), and
   100 seeded repetitions in one batched pass (:func:`run_ekf_batch`). Baseline:
   PythonRobotics' ``extended_kalman_filter.py`` style — per step, per landmark a
   sequential 2-D update with small numpy arrays in a Python loop.
"""

from __future__ import annotations

import math
import os
import time
from typing import Any

import numpy as np

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.grids import Grid
from pose_uncertainty.core.kinematics import wrap_angle
from pose_uncertainty.localization import ekf as E
from pose_uncertainty.localization import histogram as HF
from pose_uncertainty.localization import particle as PF
from pose_uncertainty.localization import sensors as S
from pose_uncertainty.localization import simulate as SIM
from pose_uncertainty.localization import world as W
from pose_uncertainty.localization.evaluation import weighted_mean_cov
from pose_uncertainty.localization.motion import Motion, sample_motion
from pose_uncertainty.localization.resampling import normalize_log_weights
from pose_uncertainty.methods import maps as M

from ._common import write_results

K = 1e-3  # wheel-noise constant [m]
REPEATS = 3  # runs of each particle-filter configuration (the fastest is reported)


def _room() -> tuple[W.World, S.RangeBearingSensor, SIM.SimulatedRun]:
    rng = np.random.default_rng(2026)
    lm = rng.uniform(1.0, 19.0, (20, 2))
    world = W.World(lm, np.arange(20), bounds=(0.0, 20.0, 0.0, 20.0))
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.03, max_range=8.0, period=0.1)
    side = [tr.Line(6.0), tr.Turn(math.pi / 2)] * 4
    traj = tr.from_segments(side * 2, speed=0.5, angular_speed=1.0, dt=0.1, start=(7.0, 7.0, 0.0))
    traj = tr.Trajectory(traj.ds_r[:1000], traj.ds_l[:1000], traj.dt, traj.track, traj.start)
    run = SIM.simulate(traj, world, rng, k_r=K, k_l=K, landmark_sensor=sen)
    return world, sen, run


# ----------------------------------------------------------------------------- PythonRobotics-style loops


def _pr_particle_filter(run: SIM.SimulatedRun, lm: np.ndarray, n: int, steps: int, rng: np.random.Generator) -> None:
    """PythonRobotics particle_filter.py: per particle, per landmark, in Python floats."""
    px = [[7.0, 7.0, 0.0] for _ in range(n)]
    pw = [1.0 / n] * n
    b, sr2, sb2 = run.track, 0.1**2, 0.03**2
    for k in range(steps):
        sr, sl = float(run.ds_r[k]), float(run.ds_l[k])
        seen = np.flatnonzero(run.landmark_valid[k + 1])
        zs = run.landmark_z[k + 1][seen].tolist()
        ms = lm[seen].tolist()
        for i in range(n):
            r = sr + math.sqrt(K * abs(sr)) * rng.standard_normal()
            l_ = sl + math.sqrt(K * abs(sl)) * rng.standard_normal()
            ds, dth = (r + l_) / 2, (r - l_) / b
            x, y, th = px[i]
            x += ds * math.cos(th + dth / 2)
            y += ds * math.sin(th + dth / 2)
            th += dth
            px[i] = [x, y, th]
            w = pw[i]
            for (zr, zb), (mx, my) in zip(zs, ms, strict=True):
                dr = math.hypot(mx - x, my - y) - zr
                db = (math.atan2(my - y, mx - x) - th - zb + math.pi) % (2 * math.pi) - math.pi
                w *= math.exp(-dr * dr / (2 * sr2)) * math.exp(-db * db / (2 * sb2))
            pw[i] = w
        tot = sum(pw) or 1.0
        pw = [w / tot for w in pw]
        if 1.0 / sum(w * w for w in pw) < n / 2:  # low-variance resampling
            cum, out, j = 0.0, [], 0
            c = [0.0] * n
            for i in range(n):
                cum += pw[i]
                c[i] = cum
            u0 = rng.random() / n
            for i in range(n):
                u = u0 + i / n
                while j < n - 1 and u > c[j]:
                    j += 1
                out.append(list(px[j]))
            px, pw = out, [1.0 / n] * n


def _pr_hf_update(grid: Grid, z: np.ndarray, lm: np.ndarray, cells: int) -> None:
    """Per-cell Python loop of the landmark update over ``cells`` (x, y) cells × all headings."""
    xs, ys, ts = grid.x.tolist(), grid.y.tolist(), grid.theta.tolist()
    done = 0
    for x in xs:
        for y in ys:
            for t in ts:
                p = 1.0
                for (zr, zb), (mx, my) in zip(z.tolist(), lm.tolist(), strict=True):
                    dr = math.hypot(mx - x, my - y) - zr
                    db = (math.atan2(my - y, mx - x) - t - zb + math.pi) % (2 * math.pi) - math.pi
                    p *= math.exp(-dr * dr / 0.02) * math.exp(-db * db / 0.0018)
            done += 1
            if done >= cells:
                return


def _pr_hf_predict(belief: np.ndarray, kernel: np.ndarray, cells: int) -> None:
    """Per-cell Python loop of the prediction: each source cell pushed through a 3×3×3 kernel."""
    nx, ny, nt = belief.shape
    out = np.zeros_like(belief)
    done = 0
    for i in range(1, nx - 1):
        for j in range(1, ny - 1):
            for t in range(nt):
                m = belief[i, j, t]
                for a in range(3):
                    for c in range(3):
                        for d in range(3):
                            out[i + a - 1, j + c - 1, (t + d - 1) % nt] += m * kernel[a, c, d]
            done += 1
            if done >= cells:
                return


def _pr_ekf(run: SIM.SimulatedRun, lm: np.ndarray, steps: int) -> None:
    """PythonRobotics-style EKF: per step and per landmark a sequential 2-D update (numpy 3×3)."""
    x, P = run.true_poses[0].copy(), np.diag([1e-4, 1e-4, 1e-4])
    Q = np.diag([0.1**2, 0.03**2])
    b = run.track
    for k in range(steps):
        sr, sl = float(run.ds_r[k]), float(run.ds_l[k])
        ds, dth = (sr + sl) / 2, (sr - sl) / b
        phi = x[2] + dth / 2
        Jp = np.array([[1, 0, -ds * math.sin(phi)], [0, 1, ds * math.cos(phi)], [0, 0, 1.0]])
        h = ds / (2 * b)
        Jd = np.array([[0.5 * math.cos(phi) - h * math.sin(phi), 0.5 * math.cos(phi) + h * math.sin(phi)],
                       [0.5 * math.sin(phi) + h * math.cos(phi), 0.5 * math.sin(phi) - h * math.cos(phi)],
                       [1 / b, -1 / b]])  # fmt: skip
        x = x + np.array([ds * math.cos(phi), ds * math.sin(phi), dth])
        P = Jp @ P @ Jp.T + Jd @ np.diag([K * abs(sr), K * abs(sl)]) @ Jd.T
        for j in np.flatnonzero(run.landmark_valid[k + 1]):
            dx, dy = lm[j, 0] - x[0], lm[j, 1] - x[1]
            q = dx * dx + dy * dy
            zhat = np.array([math.sqrt(q), math.atan2(dy, dx) - x[2]])
            H = np.array([[-dx / math.sqrt(q), -dy / math.sqrt(q), 0], [dy / q, -dx / q, -1.0]])
            S_ = H @ P @ H.T + Q
            Kg = P @ H.T @ np.linalg.inv(S_)
            nu = run.landmark_z[k + 1, j] - zhat
            nu[1] = (nu[1] + math.pi) % (2 * math.pi) - math.pi
            x = x + Kg @ nu
            P = (np.eye(3) - Kg @ H) @ P


# ----------------------------------------------------------------------------- benchmarks


def _particle_profile(world: W.World, sen: S.RangeBearingSensor, run: SIM.SimulatedRun, n: int,
                      dtype: str) -> dict[str, float]:  # fmt: skip
    """Where one thread's kernel time goes [ms per step]: run_particle's loop with a clock per part.

    The same calls as :func:`run_particle` (one thread, the blocks one after the other), the
    measures for the logs computed between the steps as there; the normal draws of the motion
    timed apart on a generator of their own (the same sizes).
    """
    cfg = PF.ParticleFilterConfig(n_particles=n, motion=Motion(k_r=K, k_l=K), dtype=dtype, workers=1)
    rng = np.random.default_rng(1)
    P = PF.initial_particles(PF.Start(pose=tuple(run.true_poses[0])), world, n, rng)
    w, lw = np.full(n, 1.0 / n), np.full(n, -math.log(n))
    blocks = S.chunks(n)
    gens, spare = rng.spawn(len(blocks)), np.random.default_rng(0)
    parts = dict.fromkeys(("measurement_preparation", "motion", "likelihood", "normalisation", "resampling",
                           "measures_outside_the_kernel"), 0.0)  # fmt: skip
    clock = time.perf_counter
    for k in range(run.n_steps + 1):
        t0 = clock()
        model = PF._measurement_model(run, world, sen, k, cfg)
        parts["measurement_preparation"] += clock() - t0
        moved, ll = (np.empty_like(P) if k else P), np.empty(n)
        for c, (a, b) in enumerate(blocks):
            t0 = clock()
            if k:
                sample_motion(P[a:b], cfg.motion, run, k - 1, gens[c], dtype, out=moved[a:b])
            t1 = clock()
            if model is not None:
                model[0](moved[a:b], ll[a:b])
            parts["motion"] += t1 - t0
            parts["likelihood"] += clock() - t1
        P = moved
        if model is not None:
            t0 = clock()
            lw += ll
            w, logev = normalize_log_weights(lw)
            lw -= logev
            t1 = clock()
            P, w, res = PF.pf_resample(P, w, rng, cfg.resampling, cfg.ess_threshold, 0, world, 1)
            if res:
                lw.fill(-math.log(n))
            parts["normalisation"] += t1 - t0
            parts["resampling"] += clock() - t1
        t0 = clock()
        weighted_mean_cov(P, w)
        PF._particle_region_flags(P, w, world, run.true_poses[k], cfg.hdr_resolution)
        P[:, 2] = wrap_angle(P[:, 2])
        parts["measures_outside_the_kernel"] += clock() - t0
    t0 = clock()
    for _ in range(run.n_steps):
        for a, b in blocks:
            spare.standard_normal((2, b - a))
    out = {key: round(1e3 * v / run.n_steps, 4) for key, v in parts.items()}
    out["motion_of_which_normal_draws"] = round(1e3 * (clock() - t0) / run.n_steps, 4)
    out["kernel_total"] = round(sum(v for key, v in out.items() if key in parts and key != "measures_outside_the_kernel"), 4)
    return out


def _bench_particle(world: W.World, sen: S.RangeBearingSensor, run: SIM.SimulatedRun) -> dict[str, Any]:
    n, steps = 10_000, run.n_steps
    out: dict[str, Any] = {"particles": n, "steps": steps, "landmarks": world.n_landmarks,
                           "mean_measurements_per_step": round(float(run.landmark_valid[1:].sum(axis=1).mean()), 2),
                           "repeats": REPEATS}  # fmt: skip
    means = {}
    for dtype, workers in (("float64", 2), ("float64", 1), ("float32", 1), ("float32", 2)):
        cfg = PF.ParticleFilterConfig(n_particles=n, motion=Motion(k_r=K, k_l=K), dtype=dtype, workers=workers)
        runs = []
        for _ in range(REPEATS):  # the machine is shared: the fastest of a few runs
            t0 = time.perf_counter()
            res = PF.run_particle(run, world, sen, np.random.default_rng(1), cfg)
            runs.append((float(res.step_seconds.sum()), time.perf_counter() - t0, res))
        kernel, wall, res = min(runs, key=lambda r: r[0])
        err = np.hypot(*(res.mean[:, :2] - run.true_poses[:, :2]).T)
        means[(dtype, workers)] = res.mean
        key = dtype if workers == 2 else f"{dtype}_1_thread"
        out[key] = {
            "threads": workers,
            "kernel_seconds": round(kernel, 3),
            "kernel_seconds_of_each_repeat": [round(r[0], 3) for r in runs],
            "wall_seconds_with_measures": round(wall, 3),
            "particle_updates_per_second": float(f"{n * steps / kernel:.3g}"),
            "resampling_steps": int(res.diagnostics["resampled"].sum()),
            "rms_position_error_m": round(float(np.sqrt(np.mean(err**2))), 4),
        }
        print(f"PF {key}: {kernel:.2f} s kernels ({wall:.2f} s wall) → {n * steps / kernel:.3g} particle-updates/s")
    for dtype in ("float64", "float32"):
        out[f"{dtype}_same_result_on_1_and_2_threads"] = bool(np.array_equal(means[(dtype, 1)], means[(dtype, 2)]))
    out["float32_1_thread_profile_ms_per_step"] = _particle_profile(world, sen, run, n, "float32")
    out["float64_1_thread_profile_ms_per_step"] = _particle_profile(world, sen, run, n, "float64")
    sub_n, sub_steps = 100, 100
    t0 = time.perf_counter()
    _pr_particle_filter(run, world.landmarks, sub_n, sub_steps, np.random.default_rng(0))
    t_sub = time.perf_counter() - t0
    t_loop = t_sub * (n / sub_n) * (steps / sub_steps)
    out["python_loop_seconds_scaled"] = round(t_loop, 1)
    out["python_loop_measured_on"] = f"{sub_n} particles x {sub_steps} steps: {t_sub:.2f} s, scaled linearly"
    out["speedup_vs_loop_float64"] = round(t_loop / out["float64"]["kernel_seconds"], 1)
    out["speedup_vs_loop_float32"] = round(t_loop / out["float32"]["kernel_seconds"], 1)
    out["goal_particle_updates_per_second"] = 1e7
    best = max(("float32", "float32_1_thread", "float64", "float64_1_thread"),
               key=lambda key: out[key]["particle_updates_per_second"])  # fmt: skip
    out["best"] = {"config": best, "particle_updates_per_second": out[best]["particle_updates_per_second"]}
    out["note"] = ("2 threads: float64 splits the particles' blocks over the threads and draws the next step's "
                   "wheel normals during the correction; float32 keeps the blocks on one thread (its short numpy "
                   "calls would hand the GIL back and forth) and the other draws the next step's normals. The "
                   "cores are shared with other jobs (load_average_1_min): the 2-thread numbers suffer most.")  # fmt: skip
    out["goal_met"] = bool(out[best]["particle_updates_per_second"] >= 1e7)  # on at most the 2 cores
    print(f"PF python loop ≈ {t_loop:.0f} s → ×{out['speedup_vs_loop_float64']}")
    return out


def _bench_histogram() -> dict[str, Any]:
    rng = np.random.default_rng(3)
    lm = rng.uniform(0.5, 12.3, (8, 2))
    world = W.World(lm, np.arange(8), bounds=(0.0, 12.8, 0.0, 12.8))
    grid = HF.pose_grid_for(world, 0.1, 72)
    assert grid.shape == (128, 128, 72)
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.03)
    truth = np.array([6.0, 5.0, 0.3])
    z = S.landmark_h(truth, lm)
    X, Y = np.meshgrid(grid.x, grid.y, indexing="ij")
    belief = np.exp(-((X - 6) ** 2 + (Y - 5) ** 2) / (2 * 0.5**2))[:, :, None] * np.ones(72)
    belief /= belief.sum()
    motion_args = ("velocity", grid, (0.5, 0.1), 0.1, (0.01, 0.0, 0.05, 0.0, 0.0, 0.0))
    t0 = time.perf_counter()
    trans = M.grid_transition(*motion_args)
    t_kernel = time.perf_counter() - t0

    def step() -> np.ndarray:
        b, _ = M.predict_on_grid(belief, trans)
        ll = HF.landmark_log_likelihood_grid(grid, z, lm, sen)
        post, _ = HF.hf_correct(b, ll)
        return post

    times = []
    for _ in range(4):
        t0 = time.perf_counter()
        step()
        times.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    M.predict_on_grid(belief, trans)
    t_pred = time.perf_counter() - t0
    t0 = time.perf_counter()
    HF.landmark_log_likelihood_grid(grid, z, lm, sen)
    t_upd = time.perf_counter() - t0
    t_step = min(times[1:])
    new_control = []
    for i in range(3):  # a new control every step (noisy odometry): kernel and windows built in the step
        t0 = time.perf_counter()
        tr_i = M.grid_transition("velocity", grid, (0.5 + 0.01 * i, 0.1), 0.1, (0.01, 0.0, 0.05, 0.0, 0.0, 0.0))
        b, _ = M.predict_on_grid(belief, tr_i)
        HF.hf_correct(b, HF.landmark_log_likelihood_grid(grid, z, lm, sen))
        new_control.append(time.perf_counter() - t0)
    cells_xy = 128 * 128
    sub = 20
    t0 = time.perf_counter()
    _pr_hf_update(grid, z, lm, sub)
    t_loop_upd = (time.perf_counter() - t0) * cells_xy / sub
    sub_p = 200
    t0 = time.perf_counter()
    _pr_hf_predict(belief, np.full((3, 3, 3), 1 / 27), sub_p)
    t_prd = (time.perf_counter() - t0) * cells_xy / sub_p
    out = {
        "cells": 128 * 128 * 72, "landmark_measurements": 8,
        "seconds_per_step": round(t_step, 4), "seconds_prediction": round(t_pred, 4),
        "seconds_update_likelihood": round(t_upd, 4),
        "seconds_kernel_build_once_per_control": round(t_kernel, 4), "goal_seconds": 0.2,
        "goal_met": bool(t_step <= 0.2),
        "seconds_per_step_new_control_every_step": round(min(new_control), 4),
        "python_loop_update_seconds_scaled": round(t_loop_upd, 1),
        "python_loop_prediction_3x3x3_seconds_scaled": round(t_prd, 1),
        "python_loop_measured_on": f"update {sub} (x, y) cells x 72 headings; prediction {sub_p} x 72 cells; scaled",
        "speedup_vs_loop": round((t_loop_upd + t_prd) / t_step, 1),
    }  # fmt: skip
    print(f"HF step 128x128x72: {t_step:.3f} s (prediction {t_pred:.3f} s, update {t_upd:.3f} s, kernel build "
          f"{t_kernel:.3f} s; new control every step {min(new_control):.3f} s); python loops ≈ "
          f"{t_loop_upd + t_prd:.0f} s → ×{out['speedup_vs_loop']}")  # fmt: skip
    return out


def _bench_ekf(world: W.World, sen: S.RangeBearingSensor, run: SIM.SimulatedRun) -> dict[str, Any]:
    cfg = E.EKFConfig(motion=Motion(k_r=K, k_l=K))
    times, kernels = [], []
    for _ in range(3):
        t0 = time.perf_counter()
        res = E.run_ekf(run, world, sen, cfg)
        times.append(time.perf_counter() - t0)
        kernels.append(float(res.step_seconds.sum()))
    t0 = time.perf_counter()
    _pr_ekf(run, world.landmarks, run.n_steps)
    t_loop = time.perf_counter() - t0
    # 100 seeded repetitions (the NEES study) in one batched pass
    traj = tr.Trajectory(run.ds_r, run.ds_l, run.dt, run.track, run.true_poses[0])
    runs = [SIM.simulate(traj, world, np.random.default_rng(s), k_r=K, k_l=K, landmark_sensor=sen)
            for s in range(100)]  # fmt: skip
    t0 = time.perf_counter()
    E.run_ekf_batch(runs, world, sen, cfg)
    t_batch = time.perf_counter() - t0
    wall, kern = min(times), min(kernels)
    out = {
        "steps": run.n_steps, "wall_seconds": round(wall, 3), "kernel_seconds": round(kern, 3),
        "python_loop_seconds": round(t_loop, 3),
        "speedup_vs_loop_kernel_time": round(t_loop / kern, 2),
        "batched_100_runs_seconds": round(t_batch, 3),
        "python_loop_100_runs_seconds_scaled": round(100 * t_loop, 1),
        "speedup_batched_vs_loop": round(100 * t_loop / t_batch, 1),
        "note": "one run: both loop over time steps (Python overhead per step dominates, the baseline "
                "updates landmark by landmark); the kernels batch over runs",
    }  # fmt: skip
    print(f"EKF 1000 steps: {wall:.3f} s wall, {kern:.3f} s kernels; loop {t_loop:.3f} s; "
          f"100 runs batched {t_batch:.2f} s vs loop ≈ {100 * t_loop:.0f} s")
    return out


def main() -> None:
    """Run the localization benchmarks and write ``benchmarks/results/localization.json``."""
    world, sen, run = _room()
    load = os.getloadavg()[0]  # other jobs on the machine slow every number down
    results: dict[str, Any] = {
        "particle_filter_1e4_particles_20_landmarks_1000_steps": _bench_particle(world, sen, run),
        "histogram_filter_step_128x128x72_landmarks": _bench_histogram(),
        "ekf_1000_steps": _bench_ekf(world, sen, run),
    }
    results["load_average_1_min"] = {"start": round(load, 2), "end": round(os.getloadavg()[0], 2)}
    path = write_results("localization", results)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
