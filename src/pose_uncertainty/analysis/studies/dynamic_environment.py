"""Localization among people and boxes that are not on the map (Skalka 2011 §5.1), measured.

:func:`dynamic_environment_study` simulates ``repeat`` runs of a robot touring a room with a laser range
finder while ``n`` unmapped discs (people seen from above, of radius ``obstacle_radius``) walk through the
room at ``obstacle_speed`` in straight lines, bouncing off the room's outer walls, for every ``n`` of
``densities``. A person within ``clearance`` of the robot steps aside (is left out of that scan). Each scan
is the map's ranges cut short by the people (:func:`pose_uncertainty.localization.dynamic.occluded_ranges`)
plus the laser's own noise (a hit with ``sigma_hit``, a few max-range and random readings; no short
component: the people are the short readings).

The robot follows the commanded tour (it stays in the room) and its encoders' report drifts
(:func:`pose_uncertainty.localization.simulate.simulate` with ``truth="commanded"``). Every run is tracked (the start known) by the particle filter and the histogram filter, each with three
measurement models (:data:`BEAM_MODELS`, on the same runs and scans):

* ``hit_only`` — the beam model without the short-reading and random components (hit and max only);
* ``mixture`` — the full mixture, with the short-reading and random components (Skalka 2011 §5.1.1:
  relying on the robustness of probabilistic localization);
* ``distance_filter`` — the mixture and the distance filter (Skalka 2011 §5.1.2), which leaves out the
  beams whose probability of being a short reading under the predicted belief reaches ``threshold``
  (0.5 by default: with the mixture's random component a reading metres short of the map is a short reading
  with a probability of only ~0.8, so Fox et al.'s 0.99 would leave out nothing).

A run succeeds when its last estimate is within ``pos_tol`` and ``head_tol`` of the truth; a filter that
finds no pose explaining a scan (zero likelihood everywhere) has lost the robot and fails. Measures per
density, filter and model: the success rate (95 % Wilson interval), the RMS position error over the steps of
the runs that finished [m], the median final position error [m], the share of runs lost, and the share of
beams used; per density the share of the scans' beams the people block, and dead reckoning's success rate
(the odometry alone, for reference).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...core import trajectories as tr
from ...core.stats import wilson_interval
from ...localization import histogram, particle
from ...localization.dynamic import occluded_ranges
from ...localization.evaluation import pose_errors
from ...localization.motion import Motion
from ...localization.result import FilterResult, Start
from ...localization.sensors import BeamSensor, expected_ranges, sample_beam_measurements
from ...localization.simulate import SimulatedRun, simulate
from ...localization.world import World, load_world

__all__ = ["BEAM_MODELS", "DYNAMIC_FILTERS", "dynamic_environment_study", "walking_discs"]

#: The measurement models and the filters of the study, in the order the report shows them.
BEAM_MODELS: tuple[str, ...] = ("hit_only", "mixture", "distance_filter")
DYNAMIC_FILTERS: tuple[str, ...] = ("particle", "histogram")

_TOUR = [["line", 6.0], ["turn", 1.5707963267948966], ["line", 5.0], ["turn", 1.5707963267948966],
         ["line", 6.0], ["turn", 1.5707963267948966], ["line", 4.0]]  # fmt: skip


def walking_discs(world: World, n: int, radius: float, speed: float, times: NDArray[np.float64],
                  rng: np.random.Generator) -> NDArray[np.float64]:  # fmt: skip
    """Discs walking in straight lines at ``speed`` and bouncing off the world's bounds, shape (K, n, 3).

    Each disc starts at a uniform place inside the bounds (``radius`` from them) with a uniform direction; its
    centre at time ``t`` is ``p₀ + v t`` folded back into the interval ``[lo, hi]`` of each axis (a mirror at
    each bound: ``lo + L − |((x − lo) mod 2L) − L|``, ``L = hi − lo``).
    """
    x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
    lo = np.array([x0 + radius, y0 + radius])
    hi = np.array([x1 - radius, y1 - radius])
    p0 = lo + (hi - lo) * rng.random((int(n), 2))
    a = rng.uniform(-math.pi, math.pi, int(n))
    v = speed * np.stack([np.cos(a), np.sin(a)], axis=-1)
    span = hi - lo
    u = np.mod(p0 + v * np.asarray(times)[:, None, None] - lo, 2 * span)  # (K, n, 2)
    xy = lo + span - np.abs(u - span)
    return np.concatenate([xy, np.full((*xy.shape[:-1], 1), float(radius))], axis=-1)


def _scans(run: SimulatedRun, world: World, laser: BeamSensor, discs: NDArray[np.float64], clearance: float,
           rng: np.random.Generator) -> tuple[NDArray[np.float64], float]:  # fmt: skip
    """The run's scans with the people in the room, and the share of the scanned beams they block."""
    assert world.grid is not None
    poses = run.true_poses
    z_map = expected_ranges(world.grid, poses, laser)
    z_true = z_map.copy()
    near = np.hypot(*(discs[..., :2] - poses[:, None, :2]).transpose(2, 0, 1)) < discs[..., 2] + clearance
    for k in np.flatnonzero(run.beam_valid):  # over time: the people move between the scans
        z_true[k] = occluded_ranges(z_map[k], poses[k], laser, discs[k][~near[k]])
    blocked = float(np.mean((z_true < z_map - 1e-9)[run.beam_valid]))
    return sample_beam_measurements(z_true, laser, rng), blocked


def _outcome(res: FilterResult | None, run: SimulatedRun, pos_tol: float, head_tol: float) -> dict[str, Any]:
    if res is None:  # lost: no pose explained a scan
        return {"ok": False, "lost": True, "final": math.nan, "errors": [], "used": []}
    p, h = pose_errors(res.mean, run.true_poses)
    m = res.diagnostics["n_measurements"][run.beam_valid]
    return {"ok": bool(p[-1] <= pos_tol and h[-1] <= head_tol), "lost": False, "final": float(p[-1]),
            "errors": p.tolist(), "used": m.tolist()}  # fmt: skip


def dynamic_environment_study(
    world: str = "config/worlds/room.yaml",
    tour: list[list[Any]] = _TOUR,
    start: list[float] = [2.0, 1.0, 0.0],  # noqa: B006
    speed: float = 0.5,
    dt: float = 0.2,
    k: float = 5e-4,
    densities: list[int] = [0, 2, 5, 10],  # noqa: B006
    obstacle_radius: float = 0.25,
    obstacle_speed: float = 0.5,
    clearance: float = 0.3,
    n_beams: int = 24,
    max_range: float = 8.0,
    sigma_hit: float = 0.05,
    period: float = 0.4,
    laser_max: float = 0.02,
    laser_rand: float = 0.0,
    threshold: float = 0.5,
    repeat: int = 5,
    n_particles: int = 1000,
    grid_resolution: float = 0.5,
    grid_ntheta: int = 24,
    pos_tol: float = 0.5,
    head_tol: float = 0.25,
    seed: int = 29,
) -> dict[str, Any]:
    """Success rate and error of the particle and histogram filters among unmapped people (module docs).

    Parameters
    ----------
    world : path of the world file; tour : segments of :func:`pose_uncertainty.core.trajectories.tour`;
    start : [x, y, θ]; speed [m/s], dt [s]; k [m] — wheel noise of the truth and of the filters;
    densities — numbers of people in the room; obstacle_radius [m], obstacle_speed [m/s], clearance [m];
    n_beams, max_range [m], sigma_hit [m], period [s] — the laser; laser_max, laser_rand — its share of
    max-range and random readings; threshold — the distance filter's; repeat — runs per density;
    n_particles; grid_resolution [m], grid_ntheta — the histogram filter; pos_tol [m], head_tol [rad] —
    success; seed — the random seed

    Returns
    -------
    dict: ``densities``; ``rows`` — per density (in order): ``n_obstacles``, ``blocked_share`` [1] (beams the
    people block), ``odometry_success`` [1], and per filter of :data:`DYNAMIC_FILTERS` and model of
    :data:`BEAM_MODELS`: ``success_rate``, ``success_low``, ``success_high`` [1] (95 % Wilson interval),
    ``rms_position_error`` [m] (NaN when every run was lost), ``median_final_error`` [m], ``lost_rate`` [1],
    ``beams_used`` [1] (share of the scans' beams in the corrections); ``repeat``, ``n_steps``, ``n_beams``,
    ``obstacle_area_share`` per density (the people's area over the room's) and ``room_area`` [m²]
    """
    w = load_world(world)
    traj = tr.tour(tour, start=tuple(start), speed=speed, dt=dt, track=0.2)
    laser = BeamSensor(n_beams=n_beams, max_range=max_range, sigma_hit=sigma_hit, period=period,
                       z_hit=1.0 - laser_max - laser_rand, z_short=0.0, z_max=laser_max, z_rand=laser_rand)  # fmt: skip
    mixture = replace(laser, z_hit=0.8, z_short=0.1, z_max=0.05, z_rand=0.05)
    hit_only = replace(laser, z_hit=1.0 - laser_max, z_rand=0.0)
    models = {"hit_only": (hit_only, None), "mixture": (mixture, None), "distance_filter": (mixture, threshold)}
    motion = Motion(k_r=k, k_l=k)
    pf_cfg = particle.ParticleFilterConfig(n_particles=n_particles, motion=motion)
    hf_cfg = histogram.HistogramFilterConfig(motion=Motion(model="velocity"), resolution=grid_resolution,
                                             ntheta=grid_ntheta, workers=1)  # fmt: skip
    x0, x1, y0, y1 = w.bounds  # type: ignore[misc]
    rows: list[dict[str, Any]] = []
    for d_idx, n in enumerate(densities):
        acc: dict[tuple[str, str], list[dict[str, Any]]] = {(f, m): [] for f in DYNAMIC_FILTERS for m in BEAM_MODELS}
        blocked, odo_ok = [], []
        for rep_seq in np.random.SeedSequence([seed, d_idx]).spawn(int(repeat)):
            g_sim, g_people, g_scan, g_pf = (np.random.default_rng(s) for s in rep_seq.spawn(4))
            run = simulate(traj, w, g_sim, k_r=k, k_l=k, beam_sensor=laser, truth="commanded")
            discs = walking_discs(w, int(n), obstacle_radius, obstacle_speed, run.times, g_people)
            z, share = _scans(run, w, laser, discs, clearance, g_scan)
            run = replace(run, beam_z=z)
            blocked.append(share)
            po, ho = pose_errors(run.odometry[-1], run.true_poses[-1])
            odo_ok.append(bool(po <= pos_tol and ho <= head_tol))
            known = Start(pose=tuple(run.true_poses[0]))  # type: ignore[arg-type]
            pf_seed = int(g_pf.integers(2**63))  # one stream for every model: paired runs
            for m, (sensor, thr) in models.items():
                for f in DYNAMIC_FILTERS:
                    try:
                        res: FilterResult | None = (
                            particle.run_particle(run, w, sensor, np.random.default_rng(pf_seed), pf_cfg, known,
                                                  distance_threshold=thr)
                            if f == "particle" else
                            histogram.run_histogram(run, w, sensor, hf_cfg, known, distance_threshold=thr))  # fmt: skip
                    except ValueError:  # every pose has zero likelihood: the filter lost the robot
                        res = None
                    acc[(f, m)].append(_outcome(res, run, pos_tol, head_tol))
        row: dict[str, Any] = {"n_obstacles": int(n), "blocked_share": float(np.mean(blocked)),
                               "odometry_success": float(np.mean(odo_ok)),
                               "obstacle_area_share": float(n * math.pi * obstacle_radius**2 / ((x1 - x0) * (y1 - y0)))}
        for f in DYNAMIC_FILTERS:
            row[f] = {}
            for m in BEAM_MODELS:
                runs = acc[(f, m)]
                ok = sum(r["ok"] for r in runs)
                lo, hi = wilson_interval(ok, len(runs))
                err = np.concatenate([np.asarray(r["errors"], dtype=float) for r in runs])
                used = np.concatenate([np.asarray(r["used"], dtype=float) for r in runs])
                finals = np.array([r["final"] for r in runs if not r["lost"]])
                row[f][m] = {
                    "success_rate": ok / len(runs), "success_low": lo, "success_high": hi,
                    "rms_position_error": float(np.sqrt(np.mean(err**2))) if err.size else math.nan,
                    "median_final_error": float(np.median(finals)) if finals.size else math.nan,
                    "lost_rate": float(np.mean([r["lost"] for r in runs])),
                    "beams_used": float(np.mean(used) / n_beams) if used.size else math.nan,
                }  # fmt: skip
        rows.append(row)
    return {"densities": [int(n) for n in densities], "rows": rows, "repeat": int(repeat),
            "n_steps": traj.n_steps + 1, "n_beams": int(n_beams), "room_area": float((x1 - x0) * (y1 - y0))}  # fmt: skip
