"""Skalka 2011's comparison of the representations of the pose (§1.4, §2.7.3), measured on the same runs.

:func:`representations_study` simulates ``repeat`` runs of a robot touring a room (odometry with
wheel noise, a range–bearing landmark sensor; :func:`pose_uncertainty.localization.simulate.simulate`)
and localizes every run with five representations of the belief:

Tracking uses known correspondences; global localization and the kidnapped robot indistinguishable
landmarks (each filter's maximum-likelihood association), the particle filter then augmented MCL
for the kidnapping (it injects random particles when the measurements' likelihood drops). The intervals
always pair each measurement with its landmark.

* ``kalman`` — the EKF (:func:`~pose_uncertainty.localization.ekf.run_ekf`);
* ``grid`` — the histogram filter (:func:`~pose_uncertainty.localization.histogram.run_histogram`);
* ``particles`` — Monte Carlo localization (:func:`~pose_uncertainty.localization.particle.run_particle`);
* ``topological`` — the discrete Bayes filter over the room's graph of places
  (:mod:`pose_uncertainty.localization.topological`): the true path's nearest place at every step; when it
  changes, the move's compass direction is the action and the place's feature, drawn from the detector
  model, the observation;
* ``intervals`` — set-membership localization (:func:`~pose_uncertainty.localization.set_membership.sivia`)
  from the same range and bearing measurements, with the bounds ``bound_sigmas`` times the sensor's σ
  (a Gaussian error exceeds them now and then: the violated assumption), at ``n_sivia`` observation
  steps of each run.

Three scenarios on the same simulated runs: tracking (the start known), global localization (the start
unknown) and the kidnapped robot (carried away at ``kidnap_step``). Measures per representation:
position error (RMS over the tracking steps [m]), consistency (the share of tracking steps whose truth lies
in its 98.89 % region — the guaranteed set for the intervals — and the mean NEES where a covariance
exists), compute time per step [s] (wall clock, the one measure that is not reproducible bit for bit),
memory of the belief [bytes], the success rates of global localization and kidnapped-robot recovery
(errors at the last step within ``pos_tol`` and ``head_tol``; the topological filter: the most probable
place is the true one), the number of separate hypotheses the belief holds in global localization (the
largest number, over the steps, of connected groups of 1 m cells, each cell with at least 0.5 % and each
group with at least 5 % of the mass), and the share
of steps or measurements where the representation's assumption fails.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...core import trajectories as tr
from ...core.kinematics import wrap_angle
from ...core.stats import PR_3SIGMA, chi2_ppf
from ...localization import ekf, histogram, particle
from ...localization import set_membership as sm
from ...localization import topological as tp
from ...localization.evaluation import nees, pose_errors
from ...localization.motion import Motion
from ...localization.result import FilterResult, Start
from ...localization.sensors import RangeBearingSensor
from ...localization.simulate import SimulatedRun, simulate
from ...localization.world import World, load_world

__all__ = ["REPRESENTATIONS", "hypothesis_count", "representations_study"]

#: The representations of the comparison, in the order of Skalka 2011's table.
REPRESENTATIONS: tuple[str, ...] = ("grid", "topological", "particles", "kalman", "intervals")

_TOUR = [["line", 6.0], ["turn", 1.5707963267948966], ["line", 5.0], ["turn", 1.5707963267948966],
         ["line", 6.0], ["turn", 1.5707963267948966], ["line", 4.0]]  # fmt: skip
_CELL = 1.0  # [m] the cells the hypotheses are counted on
_MODE_MASS, _CELL_MASS = 0.05, 0.005


def hypothesis_count(mass: NDArray[np.float64]) -> int:
    """Hypotheses of a 2-D mass on cells: connected groups (4-neighbours) of the cells holding at least 0.5 %
    of the mass, counted when the group holds at least 5 % (a belief uniform over more than 200 cells holds none,
    over fewer one)."""
    # imported where used: it loads scipy.special (0.2 s), which the jobs do not import at start
    from scipy import ndimage

    m = np.asarray(mass, dtype=np.float64)
    total = m.sum()
    if total <= 0:
        return 0
    labels, n = ndimage.label(m / total >= _CELL_MASS)
    if n == 0:
        return 0
    group = ndimage.sum_labels(m / total, labels, index=np.arange(1, n + 1))
    return int(np.sum(group >= _MODE_MASS))


def _cells(world: World) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
    return np.arange(x0, x1 + _CELL, _CELL), np.arange(y0, y1 + _CELL, _CELL)


def _mass_of_points(world: World, xy: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
    ex, ey = _cells(world)
    return np.histogram2d(xy[:, 0], xy[:, 1], bins=(ex, ey), weights=w)[0]


def _gaussian_mass(world: World, mean: NDArray[np.float64], cov: NDArray[np.float64]) -> NDArray[np.float64]:
    """The mass of a Gaussian's (x, y) marginal on the 1 m cells (its density at 10 points a side of each)."""
    ex, ey = _cells(world)
    fx = np.linspace(ex[0], ex[-1], 10 * (ex.size - 1), endpoint=False) + _CELL / 20
    fy = np.linspace(ey[0], ey[-1], 10 * (ey.size - 1), endpoint=False) + _CELL / 20
    X, Y = np.meshgrid(fx, fy, indexing="ij")
    d = np.stack([X - mean[0], Y - mean[1]], axis=-1)
    S = cov[:2, :2] + 1e-12 * np.eye(2)
    q = np.einsum("...i,ij,...j->...", d, np.linalg.inv(S), d)
    dens = np.exp(-0.5 * q)
    return np.asarray(dens.reshape(ex.size - 1, 10, ey.size - 1, 10).sum(axis=(1, 3)))


def _hypotheses_tracker(world: World, every: int) -> tuple[list[int], Callable[[int, dict[str, Any]], None]]:
    counts: list[int] = []

    def on_step(k: int, state: dict[str, Any]) -> None:
        if k % every:
            return
        if "particles" in state:
            m = _mass_of_points(world, state["particles"][:, :2], state["weights"])
        elif "belief" in state:
            g = state["grid"]
            xs, ys = g.x0 + g.dx * np.arange(g.nx), g.y0 + g.dy * np.arange(g.ny)
            X, Y = np.meshgrid(xs, ys, indexing="ij")
            m = _mass_of_points(world, np.stack([X.ravel(), Y.ravel()], -1), state["belief"].sum(axis=2).ravel())
        else:
            m = _gaussian_mass(world, state["mean"], state["cov"])
        counts.append(hypothesis_count(m))

    return counts, on_step


def _place_track(graph: tp.PlaceGraph, poses: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.int64], int]:
    """Nearest place of every true pose; the metric steps where it changes and the compass action of each change.

    Returns ``(nodes (K,), actions (K,) with −1 where the place does not change, number of changes that
    are not along an edge of the graph)``.
    """
    d = np.hypot(*(poses[:, None, :2] - graph.positions[None, :, :]).transpose(2, 0, 1))
    nodes = np.argmin(d, axis=1).astype(np.int64)
    actions = np.full(nodes.size, -1, dtype=np.int64)
    move = np.flatnonzero(nodes[1:] != nodes[:-1]) + 1
    delta = graph.positions[nodes[move]] - graph.positions[nodes[move - 1]]
    direction = np.where(np.abs(delta[:, 0]) >= np.abs(delta[:, 1]), np.where(delta[:, 0] > 0, 0, 2),
                         np.where(delta[:, 1] > 0, 1, 3))  # fmt: skip
    actions[move] = direction
    off_edge = int(np.sum(graph.neighbours[nodes[move - 1], direction] != nodes[move]))
    return nodes, actions, off_edge


def _run_places(graph: tp.PlaceGraph, model: tp.PlaceModel, nodes: NDArray[np.int64], actions: NDArray[np.int64],
                prior: NDArray[np.float64], rng: np.random.Generator) -> tuple[NDArray[np.float64], float]:  # fmt: skip
    """The topological belief at every metric step (updated when the place changes) and the seconds it took."""
    T, L = model.transitions(graph), model.likelihood(graph)
    K = nodes.size
    z = tp.sample_features(L, nodes, rng)
    t0 = time.perf_counter()
    out = np.empty((K, graph.n_nodes))
    b, _ = tp.topological_correct(prior, L[z[0]])
    out[0] = b
    for k in range(1, K):  # over time: a matrix-vector product where the place changes
        if actions[k] >= 0:
            b, _ = tp.topological_correct(tp.topological_predict(b, T[actions[k]]), L[z[k]])
        out[k] = b
    return out, time.perf_counter() - t0


def _sivia_steps(run: SimulatedRun, world: World, sensor: RangeBearingSensor, n_sivia: int, bound_sigmas: float,
                 eps: float) -> dict[str, Any]:  # fmt: skip
    """SIVIA at ``n_sivia`` observation steps with at least three landmarks seen (every 3rd such step from the end)."""
    obs = np.flatnonzero(run.landmark_valid.sum(axis=1) >= 3)
    steps = obs[::-1][: 3 * n_sivia : 3][::-1]
    x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
    d_r, d_phi = bound_sigmas * sensor.range_std, bound_sigmas * sensor.bearing_std
    errors, inside, seconds, boxes, exceed, n_meas, masses = [], [], 0.0, [], 0, 0, []
    for k in steps:  # a few observation steps; each SIVIA is vectorised over boxes and landmarks
        v = run.landmark_valid[k]
        z, lm = run.landmark_z[k, v], world.landmarks[v]
        truth = run.true_poses[k]
        true_z = np.stack([np.hypot(*(lm - truth[:2]).T),
                           wrap_angle(np.arctan2(lm[:, 1] - truth[1], lm[:, 0] - truth[0]) - truth[2])], -1)  # fmt: skip
        e = np.abs(z - true_z)
        e[:, 1] = np.abs(wrap_angle(e[:, 1]))
        exceed += int(np.sum(e[:, 0] > d_r) + np.sum(e[:, 1] > d_phi))
        n_meas += 2 * z.shape[0]
        t0 = time.perf_counter()
        s = sm.sivia(z, lm, (x0, x1, y0, y1), range_bound=d_r, bearing_bound=d_phi, eps=(eps, 0.1))
        seconds += time.perf_counter() - t0
        vol = np.prod(s.hi - s.lo, axis=1)
        if vol.sum() > 0:
            centre = ((s.lo[:, :2] + s.hi[:, :2]) / 2 * vol[:, None]).sum(axis=0) / vol.sum()
            errors.append(float(np.hypot(*(centre - truth[:2]))))
        else:  # no pose is consistent with the measurements: an error beyond its bound emptied the set
            errors.append(math.inf)
        inside.append(bool(s.contains(np.array([truth[0], truth[1], wrap_angle(truth[2])])[None])[0]))
        boxes.append(s.lo.shape[0])
        masses.append(_mass_of_points(world, (s.lo[:, :2] + s.hi[:, :2]) / 2, vol))
    return {"errors": errors, "inside": inside, "seconds": seconds, "n": len(steps), "boxes": boxes,
            "exceed": exceed, "n_measurements": n_meas, "hypotheses": [hypothesis_count(m) for m in masses]}  # fmt: skip


def _summary(errors: list[float], cover: list[float], nees_values: list[float], seconds: float, n_steps: int,
             memory: float) -> dict[str, float]:  # fmt: skip
    e = np.asarray(errors, dtype=float)
    nv = np.asarray(nees_values, dtype=float)
    nv = nv[np.isfinite(nv)]
    return {"rms_position_error": float(np.sqrt(np.mean(e**2))) if e.size else math.nan,
            "coverage_3s": float(np.mean(cover)) if len(cover) else math.nan,
            "nees_mean": float(np.mean(nv)) if nv.size else math.nan,
            "seconds_per_step": seconds / max(n_steps, 1), "memory_bytes": float(memory)}  # fmt: skip


def _success(res: FilterResult, run: SimulatedRun, pos_tol: float, head_tol: float) -> bool:
    p, h = pose_errors(res.mean[-1], run.true_poses[-1])
    return bool(p <= pos_tol and h <= head_tol)


def representations_study(
    world: str = "config/worlds/room.yaml",
    tour: list[list[Any]] = _TOUR,
    start: list[float] = [2.0, 1.0, 0.0],  # noqa: B006
    speed: float = 0.5,
    dt: float = 0.2,
    k: float = 5e-4,
    range_std: float = 0.1,
    bearing_std: float = 0.05,
    max_range: float = 5.0,
    fov: float = 3.141592653589793,
    period: float = 0.4,
    repeat: int = 2,
    n_particles: int = 1000,
    grid_resolution: float = 0.25,
    grid_ntheta: int = 24,
    place_spacing: float = 1.0,
    p_move: float = 0.9,
    p_correct: float = 0.9,
    n_sivia: int = 4,
    bound_sigmas: float = 3.0,
    sivia_eps: float = 0.1,
    kidnap_fraction: float = 0.5,
    kidnap_pose: list[float] = [8.0, 6.0, 3.141592653589793],  # noqa: B006
    pos_tol: float = 0.5,
    head_tol: float = 0.25,
    seed: int = 17,
) -> dict[str, Any]:
    """The five representations of the pose on the same simulated runs (module docs).

    Parameters
    ----------
    world : path of the world file; tour : segments of :func:`pose_uncertainty.core.trajectories.tour`;
    start : [x, y, θ]; speed [m/s], dt [s]; k [m] — wheel noise of the truth and of the filters;
    range_std [m], bearing_std [rad], max_range [m], period [s] — the landmark sensor;
    repeat — runs; n_particles; grid_resolution [m], grid_ntheta — the histogram filter;
    place_spacing [m], p_move, p_correct — the topological filter; n_sivia, bound_sigmas, sivia_eps [m] —
    the intervals; kidnap_fraction — share of the run before the kidnapping; kidnap_pose;
    pos_tol [m], head_tol [rad] — success; seed

    Returns
    -------
    dict: ``table`` — per representation (:data:`REPRESENTATIONS`): ``rms_position_error`` [m],
    ``coverage_3s`` [1], ``nees_mean`` [1] (NaN without a covariance), ``seconds_per_step`` [s],
    ``memory_bytes`` [B], ``global_success`` [1], ``kidnapped_success`` [1], ``hypotheses`` [1] (most
    separate hypotheses held in global localization), ``several_hypotheses`` (bool),
    ``assumption`` (str), ``assumption_violated`` [1] (share of steps or measurements);
    ``n_steps``, ``repeat``, ``n_places``, ``grid_cells``
    """
    w = load_world(world)
    traj = tr.tour(tour, start=tuple(start), speed=speed, dt=dt, track=0.2)
    sensor = RangeBearingSensor(range_std=range_std, bearing_std=bearing_std, max_range=max_range, fov=fov,
                                period=period)  # fmt: skip
    graph = tp.place_graph(w, place_spacing)
    places = tp.PlaceModel(p_move, p_correct)
    motion = Motion(k_r=k, k_l=k)
    # tracking with known correspondences; global and kidnapped with indistinguishable landmarks
    # (maximum-likelihood association), MCL augmented (random particles injected) for the kidnapping
    cfg: dict[str, dict[str, Any]] = {}
    for assoc in ("known", "ml"):
        cfg[assoc] = {
            "kalman": ekf.EKFConfig(motion, assoc),
            "grid": histogram.HistogramFilterConfig(motion=Motion(model="velocity"), resolution=grid_resolution,
                                                    ntheta=grid_ntheta, association=assoc, workers=1),
            "particles": particle.ParticleFilterConfig(n_particles=n_particles, motion=motion, association=assoc),
        }  # fmt: skip
    cfg["kidnapped"] = dict(cfg["ml"], particles=particle.ParticleFilterConfig(
        n_particles=n_particles, motion=motion, association="ml", injection="augmented", alpha_slow=0.05,
        alpha_fast=0.5))  # fmt: skip
    K = traj.n_steps + 1
    kidnap = max(1, round(kidnap_fraction * traj.n_steps))
    names = ("kalman", "grid", "particles")
    acc: dict[str, dict[str, list[Any]]] = {r: {"err": [], "cover": [], "nees": [], "glob": [], "kid": [], "hyp": [],
                                                "viol": []} for r in REPRESENTATIONS}  # fmt: skip
    secs = dict.fromkeys(REPRESENTATIONS, 0.0)
    steps = dict.fromkeys(REPRESENTATIONS, 0)
    boxes: list[int] = []
    off_edge = moves = exceed = n_meas = 0
    cells = 0
    ss = np.random.SeedSequence(seed)
    nees_hi = float(chi2_ppf(0.95, 3.0))
    for _ in range(int(repeat)):
        g_sim, g_kid, g_pf, g_pfg, g_pfk, g_places = (np.random.default_rng(s) for s in ss.spawn(6))
        run = simulate(traj, w, g_sim, k_r=k, k_l=k, landmark_sensor=sensor)
        krun = simulate(traj, w, g_kid, k_r=k, k_l=k, landmark_sensor=sensor, kidnap_step=kidnap,
                        kidnap_pose=kidnap_pose)  # fmt: skip
        known = Start(pose=tuple(run.true_poses[0]))  # type: ignore[arg-type]
        unknown = Start(scenario="global")
        runners: dict[str, Callable[..., FilterResult]] = {
            "kalman": lambda rn, st, c, g, cb: ekf.run_ekf(rn, w, sensor, c, st, on_step=cb),
            "grid": lambda rn, st, c, g, cb: histogram.run_histogram(rn, w, sensor, c, st, on_step=cb),
            "particles": lambda rn, st, c, g, cb: particle.run_particle(rn, w, sensor, g, c, st, on_step=cb),
        }
        for name in names:
            res = runners[name](run, known, cfg["known"][name], g_pf, None)
            p, _ = pose_errors(res.mean, run.true_poses)
            acc[name]["err"].extend(p.tolist())
            acc[name]["cover"].extend(res.in_region[:, 2].tolist())
            nv = nees(res.mean, res.cov, run.true_poses)
            acc[name]["nees"].extend(nv.tolist())
            secs[name] += float(res.step_seconds.sum())
            steps[name] += K
            counts, cb = _hypotheses_tracker(w, 1)
            gres = runners[name](run, unknown, cfg["ml"][name], g_pfg, cb)
            acc[name]["glob"].append(_success(gres, run, pos_tol, head_tol))
            acc[name]["hyp"].append(max(counts) if counts else 0)
            kres = runners[name](krun, known, cfg["kidnapped"][name], g_pfk, None)
            acc[name]["kid"].append(_success(kres, krun, pos_tol, head_tol))
            if name == "particles":
                ess = res.diagnostics.get("ess", np.full(K, float(n_particles)))
                acc[name]["viol"].extend((ess < 0.1 * n_particles).tolist())
            else:
                acc[name]["viol"].extend((nv > nees_hi).tolist())
            if name == "grid":
                g = histogram.pose_grid_for(w, grid_resolution, grid_ntheta)
                cells = g.nx * g.ny * g.ntheta
        # topological: the same true paths
        nodes, actions, off = _place_track(graph, run.true_poses)
        off_edge, moves = off_edge + off, moves + int(np.sum(actions >= 0))
        uniform = np.full(graph.n_nodes, 1.0 / graph.n_nodes)
        at_start = np.zeros(graph.n_nodes)
        at_start[nodes[0]] = 1.0
        g_t1, g_t2, g_t3 = g_places.spawn(3)
        bel, sec = _run_places(graph, places, nodes, actions, 0.98 * at_start + 0.02 * uniform, g_t1)
        best = np.argmax(bel, axis=1)
        acc["topological"]["err"].extend(np.hypot(*(graph.positions[best] - run.true_poses[:, :2]).T).tolist())
        order = np.argsort(-bel, axis=1)
        cum = np.take_along_axis(bel, order, axis=1).cumsum(axis=1)
        rank = np.argmax(order == nodes[:, None], axis=1)
        acc["topological"]["cover"].extend((np.concatenate([np.zeros((K, 1)), cum[:, :-1]], axis=1)
                                            [np.arange(K), rank] < PR_3SIGMA).tolist())  # fmt: skip
        secs["topological"] += sec
        steps["topological"] += K
        gbel, _ = _run_places(graph, places, nodes, actions, uniform, g_t2)
        acc["topological"]["glob"].append(bool(np.argmax(gbel[-1]) == nodes[-1]))
        acc["topological"]["hyp"].append(max(hypothesis_count(_mass_of_points(w, graph.positions, b))
                                             for b in gbel))  # fmt: skip
        knodes, kactions, _ = _place_track(graph, krun.true_poses)
        kstart = np.zeros(graph.n_nodes)
        kstart[knodes[0]] = 1.0
        kbel, _ = _run_places(graph, places, knodes, kactions, 0.98 * kstart + 0.02 * uniform, g_t3)
        acc["topological"]["kid"].append(bool(np.argmax(kbel[-1]) == knodes[-1]))
        # intervals: set-membership at a few observation steps of the same runs
        iv = _sivia_steps(run, w, sensor, n_sivia, bound_sigmas, sivia_eps)
        acc["intervals"]["err"].extend(iv["errors"])
        acc["intervals"]["cover"].extend(iv["inside"])
        secs["intervals"] += iv["seconds"]
        steps["intervals"] += iv["n"]
        boxes.extend(iv["boxes"])
        exceed, n_meas = exceed + iv["exceed"], n_meas + iv["n_measurements"]
        acc["intervals"]["hyp"].append(max(iv["hypotheses"]) if iv["hypotheses"] else 0)
        kiv = _sivia_steps(krun, w, sensor, 1, bound_sigmas, sivia_eps)  # memoryless: the last step after the kidnapping
        acc["intervals"]["kid"].append(bool(kiv["inside"] and kiv["inside"][-1] and kiv["errors"][-1] <= pos_tol))
        acc["intervals"]["glob"].append(bool(iv["inside"] and iv["inside"][-1] and iv["errors"][-1] <= pos_tol))
    memory = {"kalman": 12 * 8, "grid": cells * 8, "particles": n_particles * 4 * 8,
              "topological": graph.n_nodes * 8, "intervals": float(np.mean(boxes)) * 7 * 8 if boxes else math.nan}
    assumptions = {
        "kalman": ("a Gaussian belief, linearisable models: share of tracking steps with NEES above χ²₃(95 %)", None),
        "grid": ("the belief is constant within a cell: share of tracking steps with NEES above χ²₃(95 %)", None),
        "particles": ("enough particles: share of tracking steps with an effective sample size below 10 %", None),
        "topological": ("the robot moves along the graph's edges: share of place changes off an edge",
                        off_edge / moves if moves else math.nan),
        "intervals": (("bounded errors (and known correspondences): share of range and bearing errors beyond "
                       "their bounds"), exceed / n_meas if n_meas else math.nan),
    }  # fmt: skip
    table: dict[str, dict[str, Any]] = {}
    for rep in REPRESENTATIONS:
        a = acc[rep]
        row: dict[str, Any] = _summary(a["err"], a["cover"], a["nees"], secs[rep], steps[rep], memory[rep])
        text, viol = assumptions[rep]
        row.update(global_success=float(np.mean(a["glob"])), kidnapped_success=float(np.mean(a["kid"])),
                   hypotheses=int(max(a["hyp"])) if a["hyp"] else 0, assumption=text,
                   assumption_violated=float(np.mean(a["viol"])) if viol is None else float(viol))  # fmt: skip
        row["several_hypotheses"] = row["hypotheses"] >= 2
        table[rep] = row
    return {"table": table, "n_steps": K, "repeat": int(repeat), "n_places": graph.n_nodes, "grid_cells": cells,
            "kidnap_step": kidnap, "pos_tol": pos_tol, "head_tol": head_tol}  # fmt: skip
