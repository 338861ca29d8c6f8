"""Figures the pipeline draws beyond a single run's (those are in :mod:`pose_uncertainty.present.figures`).

* :func:`render_run_figure` — one figure of one run log, by kind (``trajectory``,
  ``cloud``, ``map_<name>``), drawn by the same functions ``replay --figures`` uses;
* :func:`growth_figure` — how each uncertainty measure grows with distance (log-log),
  over the runs of a set;
* :func:`cloud_polar_figure` — seed 001's Cartesian and polar views of the end-pose clouds;
* :func:`expcoords_figure` — long-path Monte Carlo clouds with Method A's ellipse and the
  exponential-coordinates Gaussian's region (the banana) drawn over them.

Every figure is saved by :func:`pose_uncertainty.present.figures.save_figure` (deterministic bytes).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ..logs.runlog import open_run
from . import figures

__all__ = [
    "MAP_SAMPLES",
    "cloud_polar_figure",
    "expcoords_figure",
    "growth_figure",
    "map_cloud_figure",
    "map_sampler_cloud",
    "render_expcoords_figure",
    "render_run_figure",
    "render_run_figures",
    "render_set_figure",
]

#: Number of motion-model samples drawn to check a single-step map (Monte Carlo truth of Method B).
MAP_SAMPLES: int = 20000


def render_run_figure(log: str | os.PathLike[str], kind: str, out: str | os.PathLike[str]) -> Path:
    """Draw one figure of a run log and save it.

    Parameters
    ----------
    log : path — run log (``*.mcap``)
    kind : {"trajectory", "cloud", "map_<name>", "mapcloud_<name>"}
    out : path — ``*.png`` / ``*.svg`` / ``*.pdf``

    Raises
    ------
    ValueError if the kind is unknown or the run lacks what the figure draws.
    """
    return render_run_figures(log, [kind], [out])[0]


def render_run_figures(
    log: str | os.PathLike[str], kinds: Sequence[str], outs: Sequence[str | os.PathLike[str]]
) -> list[Path]:
    """Draw several figures of one run log (read once); see :func:`render_run_figure` for the kinds."""
    if len(kinds) != len(outs):
        raise ValueError(f"kinds and outs must have equal length, got {len(kinds)} and {len(outs)}")
    run = open_run(log)
    return [_render(run, log, kind, out) for kind, out in zip(kinds, outs, strict=True)]


def _render(run: Any, log: str | os.PathLike[str], kind: str, out: str | os.PathLike[str]) -> Path:
    fig: Figure | None
    if kind == "trajectory":
        fig = figures.trajectory_figure(run)
    elif kind == "cloud":
        fig = figures.cloud_figure(run)
        if fig is None:
            raise ValueError(f"{log}: kind 'cloud' needs Monte Carlo end poses (monte_carlo.n_particles > 0)")
    elif kind.startswith("mapcloud_"):
        name = kind[len("mapcloud_"):]
        maps = {m.name: m for m in run.maps}
        if name not in maps:
            raise ValueError(f"{log}: map {name!r} not in the run (allowed: {', '.join(maps) or 'none'})")
        fig = map_cloud_figure(run, maps[name])
    elif kind.startswith("map_"):
        name = kind[4:]
        maps = {m.name: m for m in run.maps}
        if name not in maps:
            raise ValueError(f"{log}: map {name!r} not in the run (allowed: {', '.join(maps) or 'none'})")
        fig = figures.map_figure(run, maps[name])
    else:
        raise ValueError(
            f"figure kind must be 'trajectory', 'cloud', 'map_<name>' or 'mapcloud_<name>', got {kind!r}"
        )
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    return figures.save_figure(fig, out)


def map_sampler_cloud(run: Any, mp: Any, n: int = MAP_SAMPLES) -> np.ndarray:
    """End poses drawn from the motion model's own sampler along the run's controls (Method B's Monte Carlo).

    One step: ``sample_velocity`` / ``sample_odometry``; several steps: the model's
    sampler applied step after step (``sample_velocity_path`` / ``sample_odometry_path``),
    which is what a multi-step map predicts. The odometry ``u`` is the noiseless
    velocity motion, as in seed 000. The generator is seeded from the run's seed
    (``default_rng([seed, 1])``), so the cloud is the same every time.

    Parameters
    ----------
    run : RunResult
    mp : MapRecord — one of ``run.maps``
    n : int — number of samples

    Returns
    -------
    ndarray, shape (n, 3)
    """
    from ..core import trajectories
    from ..methods import motion_models as mm

    p = mp.params
    traj = run.config.trajectory
    tr = trajectories.build(traj["name"], **{k: v for k, v in traj.items() if k != "name"})
    start, controls, dt = tr.start, tr.controls, tr.dt
    rng = np.random.default_rng([run.config.seed, 1])
    noise = p.get("noise", "normal")
    scaling = p.get("scaling", "squared")
    if mp.model == "velocity":
        if tr.n_steps == 1:
            return mm.sample_velocity(start, controls[0], dt, p["alphas"], n, rng, noise=noise, scaling=scaling)
        return mm.sample_velocity_path(start, controls, dt, p["alphas"], n, rng, noise=noise, scaling=scaling)
    od = mm.noiseless_velocity_poses(start, controls, dt)
    if tr.n_steps == 1:
        return mm.sample_odometry(start, od[0], od[1], p["alphas"], n, rng, noise=noise, scaling=scaling)
    return mm.sample_odometry_path(start, od, p["alphas"], n, rng, noise=noise, scaling=scaling)


def _hdr_levels(mass: np.ndarray, prs: Sequence[float]) -> list[float]:
    """Cell-mass thresholds of the highest-density regions holding each ``pr`` of ``mass``."""
    order = np.sort(mass.ravel())[::-1]
    cum = np.cumsum(order) / max(order.sum(), 1e-300)
    return [float(order[min(int(np.searchsorted(cum, pr)), order.size - 1)]) for pr in prs]


def map_cloud_figure(run: Any, mp: Any, n: int = MAP_SAMPLES) -> Figure:
    """The motion model's sampled end poses over the map's 39 / 86 / 98.89 % contours.

    Parameters
    ----------
    run : RunResult
    mp : MapRecord
    n : int — number of samples drawn by :func:`map_sampler_cloud`
    """
    marg = mp.marginal_xy()
    end = run.poses[-1]
    fig = figures.new_figure((6.0, 6.0))
    ax = fig.add_subplot()
    cloud = map_sampler_cloud(run, mp, n)
    if cloud.shape[0]:
        ax.scatter(cloud[:, 0], cloud[:, 1], s=1.0, color="0.35", alpha=0.3, linewidths=0, rasterized=True,
                   label=f"sampler end poses (n = {cloud.shape[0]})")
    prs = (1.0 - math.exp(-0.5), 1.0 - math.exp(-2.0), 1.0 - math.exp(-4.5))
    levels = _hdr_levels(marg, prs)
    colors = ("tab:blue", "tab:purple", "red")
    for lvl, pr, col in sorted(zip(levels, prs, colors, strict=True)):
        if marg.max() > lvl > 0:
            ax.contour(mp.x, mp.y, marg.T, levels=[lvl], colors=[col], linewidths=1.0)
            ax.plot([], [], color=col, lw=1.0, label=f"map region {100 * pr:.2f} %")
    ax.plot(*end[:2], marker="+", color="red", ms=10, ls="none", label="noiseless end point")
    ax.plot(*run.poses[0, :2], marker="o", color="k", ms=3, ls="none", label="start")
    ax.set_xlim(float(mp.x[0]), float(mp.x[-1]))
    ax.set_ylim(float(mp.y[0]), float(mp.y[-1]))
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{run.config.name}: {mp.model} model, map contours vs its sampler", fontsize="medium")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(loc="upper right", fontsize="x-small")
    return fig


def _frame(theta: float) -> np.ndarray:
    """Rows: unit vectors along and across a heading ``theta`` [rad]."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, s], [-s, c]])


def growth_figure(logs: Sequence[str | os.PathLike[str]], title: str = "") -> Figure:
    """Uncertainty measures against path length, log-log, with reference slopes.

    Draws, for every run of the set (sorted by path length): Method A's standard
    deviations along and across the end heading and of θ, the semi-axes of the
    Pr-ellipse, and the Monte Carlo sample's along/across standard deviations.

    Parameters
    ----------
    logs : sequence of paths to run logs
    title : str
    """
    rows = []
    for p in logs:
        run = open_run(p)
        end = run.poses[-1]
        R = _frame(float(end[2]))
        cov = R @ run.covs[-1][:2, :2] @ R.T
        row = {
            "L": run.metrics.get("path_length", float("nan")),
            "A: σ along": math.sqrt(max(cov[0, 0], 0.0)),
            "A: σ across": math.sqrt(max(cov[1, 1], 0.0)),
            "A: σ_θ [rad]": math.sqrt(max(run.covs[-1][2, 2], 0.0)),
            "A: ellipse major": run.metrics.get("ellipse_major", float("nan")),
            "A: ellipse minor": run.metrics.get("ellipse_minor", float("nan")),
        }
        if run.end_poses is not None and run.end_poses.shape[0] > 2:
            d = (run.end_poses[:, :2] - run.end_poses[:, :2].mean(axis=0)) @ R.T
            row["MC: σ along"] = float(d[:, 0].std(ddof=1))
            row["MC: σ across"] = float(d[:, 1].std(ddof=1))
        rows.append(row)
    rows.sort(key=lambda r: r["L"])
    L = np.array([r["L"] for r in rows])
    fig = figures.new_figure((6.4, 5.2))
    ax = fig.add_subplot()
    styles = {
        "A: σ along": ("tab:blue", "-", "o"),
        "A: σ across": ("tab:red", "-", "o"),
        "A: σ_θ [rad]": ("tab:green", "-", "s"),
        "A: ellipse major": ("0.3", ":", "^"),
        "A: ellipse minor": ("0.6", ":", "v"),
        "MC: σ along": ("tab:blue", "none", "x"),
        "MC: σ across": ("tab:red", "none", "x"),
    }
    for key, (color, ls, marker) in styles.items():
        vals = np.array([r.get(key, np.nan) for r in rows])
        ok = np.isfinite(vals) & (vals > 0)
        if ok.sum() == 0:
            continue
        ax.loglog(L[ok], vals[ok], color=color, ls=ls, marker=marker, ms=4, lw=1.0, label=key)
    if L.size >= 2:
        # reference slopes through the first point of the curve they describe, offset below it
        ref = np.array([L.min(), L.max()])
        for slope, key, dash in ((0.5, "A: σ along", (0, (2, 2))), (1.5, "A: σ across", (0, (6, 2)))):
            y0 = 0.5 * float(rows[0][key])
            ax.loglog(ref, y0 * (ref / ref[0]) ** slope, color="k", lw=0.6, ls=dash,
                      label=f"slope {slope:g} (∝ L^{slope:g})")
    ax.set_xlabel("path length L [m]")
    ax.set_ylabel("uncertainty [m] (σ_θ in rad)")
    ax.set_title(title or "growth of the uncertainty with distance")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize="x-small", loc="upper left")
    return fig


def cloud_polar_figure(logs: Sequence[str | os.PathLike[str]], title: str = "") -> Figure:
    """Seed 001's two views of the end-pose clouds: Cartesian (x, y) and polar (bearing, range).

    One column per run (at most 8 runs: the caller selects them); top row the
    cloud in the plane with Method A's Pr-ellipse, bottom row the same cloud as
    bearing ``atan2(y, x)`` [deg] against range ``√(x²+y²)`` [m] from the start.

    Parameters
    ----------
    logs : sequence of paths to run logs (the first 8 are drawn)
    title : str
    """
    runs = [open_run(p) for p in list(logs)[:8]]
    n = max(len(runs), 1)
    fig = figures.new_figure((3.0 * n, 6.0))
    for j, run in enumerate(runs):
        ax = fig.add_subplot(2, n, j + 1)
        axp = fig.add_subplot(2, n, n + j + 1)
        end, cov = run.poses[-1], run.covs[-1]
        cloud = run.end_poses if run.end_poses is not None else np.zeros((0, 3))
        ax.scatter(cloud[:, 0], cloud[:, 1], s=1.0, color="0.3", alpha=0.4, linewidths=0, rasterized=True)
        from ..methods.covariance import ellipse_polyline

        pts = ellipse_polyline(cov[:2, :2], run.config.pr, end[:2], 200)
        ax.plot(pts[:, 0], pts[:, 1], color="red", lw=1.0)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(run.config.name, fontsize="small")
        start = run.poses[0]
        rel = cloud[:, :2] - start[:2]
        bearing = np.degrees(np.arctan2(rel[:, 1], rel[:, 0]))
        rng = np.hypot(rel[:, 0], rel[:, 1])
        axp.scatter(bearing, rng, s=1.0, color="0.3", alpha=0.4, linewidths=0, rasterized=True)
        erel = pts - start[:2]
        axp.plot(np.degrees(np.arctan2(erel[:, 1], erel[:, 0])), np.hypot(erel[:, 0], erel[:, 1]), color="red", lw=1.0)
        axp.set_xlabel("bearing from start [deg]")
        axp.set_ylabel("range from start [m]")
        axp.grid(True, lw=0.3, alpha=0.5)
        ax.grid(True, lw=0.3, alpha=0.5)
    if title:
        fig.suptitle(title)
    return fig


def expcoords_figure(
    cases: Sequence[tuple[str, dict[str, Any]]] = (
        ("straight 5 m", {"name": "straight", "length": 5.0}),
        ("circle r = 1 m, 1 lap", {"name": "circle", "radius": 1.0, "laps": 1}),
    ),
    k: float = 5e-4,
    track: float = 0.2,
    dt: float = 0.01,
    pr: float = 1.0 - math.exp(-4.5),
    n: int = 5000,
    seed: int = 6,
) -> Figure:
    """Monte Carlo end poses of long paths with both Gaussian methods' Pr regions drawn over them.

    One panel per case: ``n`` per-step Monte Carlo end positions (midpoint
    integration, ``k_r = k_l = k`` [m]), Method A's Pr-ellipse (red) and the
    boundary of the exponential-coordinates Gaussian's planar Pr highest-density
    region (blue, :func:`pose_uncertainty.methods.expcoords.pr_region_xy`); equal aspect,
    metres. The legend gives the share of the cloud inside each region.

    Parameters
    ----------
    cases : sequence of (label, trajectory parameters for :func:`trajectories.build`)
    k : float — wheel-noise constant [m]; track : float [m]; dt : float [s]
    pr : float in (0, 1) — region probability (default 98.89 %, radius 3)
    n : int — Monte Carlo runs per case; seed : int
    """
    from matplotlib.path import Path as MplPath

    from ..core import trajectories as tr
    from ..methods import covariance as cv
    from ..methods import expcoords as ec
    from ..methods.sampling import sample_end_poses

    fig = figures.new_figure((5.2 * len(cases), 5.0))
    for j, (label, params) in enumerate(cases):
        p = dict(params)
        t = tr.build(p.pop("name"), dt=dt, track=track, **p)
        rng = np.random.default_rng([seed, j])
        cloud = sample_end_poses(t, k, k, n, rng)
        A = cv.propagate(t, k, k)
        E = ec.propagate(t, k, k)
        end, cov = A.poses[-1], A.covs[-1]
        ell = cv.ellipse_polyline(cov[:2, :2], pr, end[:2], 400)
        banana = ec.pr_region_xy(E.poses[-1], E.covs[-1], pr, rng, n_grid=240, n=50_000)
        d = cloud[:, :2] - end[:2]
        m2 = np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov[:2, :2]), d)
        in_ell = float(np.mean(m2 <= cv.pr_to_k(pr)))
        in_ban = np.zeros(n, dtype=bool)
        for poly in banana:
            in_ban ^= MplPath(poly).contains_points(cloud[:, :2])
        ax = fig.add_subplot(1, len(cases), j + 1)
        ax.scatter(cloud[:, 0], cloud[:, 1], s=1.0, color="0.3", alpha=0.35, linewidths=0,
                   rasterized=True, label=f"Monte Carlo, {n} runs")
        ax.plot(ell[:, 0], ell[:, 1], color="tab:red", lw=1.2,
                label=f"Method A ellipse {100 * pr:.2f} % (holds {100 * in_ell:.1f} %)")
        for i, poly in enumerate(banana):
            ax.plot(poly[:, 0], poly[:, 1], color="tab:blue", lw=1.2,
                    label=f"exp. coords {100 * pr:.2f} % (holds {100 * float(in_ban.mean()):.1f} %)"
                    if i == 0 else None)
        ax.plot(t.poses[:, 0], t.poses[:, 1], color="k", lw=0.6, ls="--", label="noiseless path")
        ax.plot([end[0]], [end[1]], marker="+", color="k", ms=8)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"{label}, k = {k:g} m, b = {track:g} m", fontsize="small")
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize="x-small", loc="lower left")
    return fig


def render_expcoords_figure(out: str | os.PathLike[str], **kwargs: Any) -> Path:
    """Draw :func:`expcoords_figure` (keyword arguments passed on) and save it (deterministic bytes)."""
    fig = expcoords_figure(**kwargs)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    return figures.save_figure(fig, out)


def render_set_figure(
    kind: str, logs: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str], title: str = ""
) -> Path:
    """Draw a set-level figure (``growth`` or ``cloud_polar``) and save it."""
    if kind == "growth":
        fig = growth_figure(logs, title)
    elif kind == "cloud_polar":
        fig = cloud_polar_figure(logs, title)
    else:
        raise ValueError(f"set figure kind must be 'growth' or 'cloud_polar', got {kind!r}")
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    return figures.save_figure(fig, out)
