"""Scan-to-map matching in the EKF against the beam-model particle filter (Skalka 2011 §4.2.2), measured.

:func:`scan_matching_study` simulates ``repeat`` runs in two places — the room's tour, and a straight drive
along a long corridor whose ends are out of the laser's range (every scan there looks alike along it) — and
localizes each run (the start known) two ways on the same scans:

* ``ekf_matching`` — the EKF's Method A prediction from the odometry, corrected at every scan by the
  correlative match of the scan against the map about the EKF's mean
  (:func:`pose_uncertainty.localization.scan_matching.correlative_match`: the candidates' weighted mean and
  covariance as a pose measurement, :func:`~pose_uncertainty.localization.scan_matching.ekf_update_pose`);
* ``particle`` — the particle filter with the beam model (:func:`pose_uncertainty.localization.particle.run_particle`).

The robot follows its commanded path (the encoders' report drifts). A run fails when its last estimate is
farther than ``pos_tol`` or ``head_tol`` from the truth. Measures per place and method: the RMS position error
over the steps [m], the RMS error along x (the corridor's axis) at the end [m], the failure rate (95 % Wilson
interval); for the matching, the mean σ of the matches along x and y [m] (wide along an ambiguous corridor).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core import trajectories as tr
from ...core.kinematics import wrap_angle
from ...core.stats import wilson_interval
from ...localization import particle
from ...localization import scan_matching as sm
from ...localization.ekf import ekf_predict_wheels
from ...localization.evaluation import pose_errors
from ...localization.motion import Motion
from ...localization.result import Start
from ...localization.sensors import BeamSensor
from ...localization.simulate import SimulatedRun, simulate
from ...localization.world import World, load_world, world_from_dict

__all__ = ["MATCHING_METHODS", "MATCHING_PLACES", "scan_matching_study"]

#: The places and the methods of the study, in the order the report shows them.
MATCHING_PLACES: tuple[str, ...] = ("room", "corridor")
MATCHING_METHODS: tuple[str, ...] = ("ekf_matching", "particle")

_TOUR = [["line", 6.0], ["turn", 1.5707963267948966], ["line", 5.0], ["turn", 1.5707963267948966],
         ["line", 6.0], ["turn", 1.5707963267948966], ["line", 4.0]]  # fmt: skip


def _ekf_matching(run: SimulatedRun, world: World, laser: BeamSensor, k: float, field: np.ndarray,
                  window: tuple[float, float], step: tuple[float, float]) -> tuple[np.ndarray, list[np.ndarray]]:  # fmt: skip
    """The EKF's means (K, 3) with a scan match at every scan, and the matches' σ (x, y)."""
    assert run.beam_z is not None
    assert world.grid is not None
    mean, cov = run.true_poses[0].copy(), np.diag([0.02**2, 0.02**2, 0.01**2])
    means, sig = np.empty((run.n_steps + 1, 3)), []
    for i in range(run.n_steps + 1):  # over time
        if i > 0:
            mean, cov = ekf_predict_wheels(mean, cov, run.ds_r[i - 1], run.ds_l[i - 1], k, k, run.track)
        if run.beam_valid[i]:
            m = sm.correlative_match(field, world.grid, run.beam_z[i], laser, mean, window, step)
            mean, cov = sm.ekf_update_pose(mean, cov, m.mean, m.cov)
            sig.append(np.sqrt(np.diag(m.cov)[:2]))
        means[i] = [mean[0], mean[1], wrap_angle(mean[2])]
    return means, sig


def scan_matching_study(
    world: str = "config/worlds/room.yaml",
    tour: list[list[Any]] = _TOUR,
    start: list[float] = [2.0, 1.0, 0.0],  # noqa: B006
    corridor: list[float] = [30.0, 2.0],  # noqa: B006
    corridor_drive: float = 10.0,
    speed: float = 0.5,
    dt: float = 0.2,
    k: float = 5e-4,
    n_beams: int = 24,
    max_range: float = 5.0,
    sigma_hit: float = 0.05,
    period: float = 0.4,
    field_sigma: float = 0.1,
    window: list[float] = [0.5, 0.2],  # noqa: B006
    step: list[float] = [0.05, 0.01],  # noqa: B006
    repeat: int = 5,
    n_particles: int = 500,
    pos_tol: float = 0.5,
    head_tol: float = 0.25,
    seed: int = 31,
) -> dict[str, Any]:
    """Scan matching in the EKF against the beam-model particle filter, in the room and a corridor (module docs).

    Parameters
    ----------
    world : the room's world file; tour, start : its path; corridor : [length, width] [m] of the corridor,
    driven along its axis for ``corridor_drive`` [m] from a quarter of its length; speed [m/s], dt [s], k [m] —
    the wheel noise; n_beams, max_range [m], sigma_hit [m], period [s] — the laser; field_sigma [m] — the
    likelihood field's σ; window [m, rad], step [m, rad] — the matcher's search; repeat — runs per place;
    n_particles; pos_tol [m], head_tol [rad] — success; seed — the random seed

    Returns
    -------
    dict: per place of :data:`MATCHING_PLACES`, per method of :data:`MATCHING_METHODS`: ``rms_position_error``
    [m], ``rms_final_along`` [m] (the last step's error along x), ``failure_rate``, ``failure_low``,
    ``failure_high`` [1]; ``ekf_matching`` also ``match_sigma_x``, ``match_sigma_y`` [m] (mean σ of the
    matches); per place ``n_steps``; ``repeat``
    """
    laser = BeamSensor(n_beams=n_beams, max_range=max_range, sigma_hit=sigma_hit, period=period)
    length, width = (float(v) for v in corridor)
    places = {
        "room": (load_world(world), tr.tour(tour, start=tuple(start), speed=speed, dt=dt, track=0.2)),
        "corridor": (world_from_dict({"name": "corridor", "walls": {"resolution": 0.1, "segments": [
            [0.0, 0.0, length, 0.0], [length, 0.0, length, width], [length, width, 0.0, width],
            [0.0, width, 0.0, 0.0]]}}),
            tr.tour([["line", corridor_drive]], start=(length / 4, width / 2, 0.0), speed=speed, dt=dt, track=0.2)),
    }  # fmt: skip
    pf_cfg = particle.ParticleFilterConfig(n_particles=n_particles, motion=Motion(k_r=k, k_l=k))
    out: dict[str, Any] = {"repeat": int(repeat)}
    for p_idx, place in enumerate(MATCHING_PLACES):
        w, traj = places[place]
        assert w.grid is not None
        field = sm.likelihood_field(w.grid, field_sigma)
        acc: dict[str, dict[str, list[Any]]] = {m: {"err": [], "along": [], "ok": [], "sig": []} for m in MATCHING_METHODS}
        for rep in np.random.SeedSequence([seed, p_idx]).spawn(int(repeat)):
            g_sim, g_pf = (np.random.default_rng(s) for s in rep.spawn(2))
            run = simulate(traj, w, g_sim, k_r=k, k_l=k, beam_sensor=laser, truth="commanded")
            means, sig = _ekf_matching(run, w, laser, k, field, (window[0], window[1]), (step[0], step[1]))
            res = particle.run_particle(run, w, laser, g_pf, pf_cfg, Start(pose=tuple(run.true_poses[0])))  # type: ignore[arg-type]
            for m, est in (("ekf_matching", means), ("particle", res.mean)):
                pe, he = pose_errors(est, run.true_poses)
                acc[m]["err"].extend(pe.tolist())
                acc[m]["along"].append(float(est[-1, 0] - run.true_poses[-1, 0]))
                acc[m]["ok"].append(bool(pe[-1] <= pos_tol and he[-1] <= head_tol))
            acc["ekf_matching"]["sig"].extend(sig)
        out[place] = {"n_steps": traj.n_steps + 1}
        for m in MATCHING_METHODS:
            a = acc[m]
            fails = int(len(a["ok"]) - sum(a["ok"]))
            lo, hi = wilson_interval(fails, len(a["ok"]))
            row = {"rms_position_error": float(np.sqrt(np.mean(np.square(a["err"])))),
                   "rms_final_along": float(np.sqrt(np.mean(np.square(a["along"])))),
                   "failure_rate": fails / len(a["ok"]), "failure_low": lo, "failure_high": hi}  # fmt: skip
            if a["sig"]:
                s = np.asarray(a["sig"])
                row.update(match_sigma_x=float(s[:, 0].mean()), match_sigma_y=float(s[:, 1].mean()))
            out[place][m] = row
    return out
