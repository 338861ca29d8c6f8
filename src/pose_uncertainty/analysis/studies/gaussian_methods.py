"""Accuracy of the three Gaussian methods (Method A, the banana, Method C) against Monte Carlo.

:func:`accuracy_case` — coverage and distances on one path (the pipeline runs the
long paths); :func:`coverage_vs_distance` — coverage along a path;
:func:`expcoords_regions` — the data of the figure of clouds, ellipses and bananas.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...core import trajectories as tr
from ...core.stats import PR_3SIGMA
from ...localization.motion import velocity_alphas_for_wheels
from ...methods import covariance as cv
from ...methods import expcoords as ec
from ...methods import maps as mp_
from ...methods import sampling as sp
from ...methods import unscented as ut
from .. import accuracy as ac


def straight_path(length: float) -> dict[str, Any]:
    """The studies' default path as a trajectory configuration: straight, ``length`` [m], Δt 0.01 s, track 0.2 m."""
    return {"name": "straight", "length": length, "dt": 0.01, "track": 0.2}


def accuracy_case(
    trajectory: dict[str, Any] | None = None,
    k: float = 5e-4,
    n: int = 100_000,
    seed: int = 2026,
    n_bins: int = 60,
    n_threshold: int = 200_000,
    label: str = "",
) -> dict[str, Any]:
    """Coverage, Hellinger, KL, log-likelihood and NEES of the three Gaussian methods on one path.

    ``n`` per-step Monte Carlo runs (midpoint integration, ``k_r = k_l = k`` [m])
    of ``trajectory`` (a :func:`pose_uncertainty.core.trajectories.from_config`
    mapping; default straight 1 m, dt 0.01 s, b 0.2 m) against Method A, the
    exponential-coordinates Gaussian and Method C (the unscented transform)
    (:func:`pose_uncertainty.analysis.accuracy.compare_methods`).

    Returns
    -------
    dict: ``case`` (the label), ``k``, ``length`` [m] and the entries of ``compare_methods``.
    """
    t = tr.from_config(trajectory or straight_path(1.0))
    rng = np.random.default_rng(seed)
    cloud = sp.sample_end_poses(t, k, k, n, rng)
    A = cv.propagate(t, k, k)
    E = ec.propagate(t, k, k)
    C = ut.propagate(t, k, k)
    res = ac.compare_methods(
        cloud, (A.poses[-1], A.covs[-1]), (E.poses[-1], E.covs[-1]), rng, n_bins=n_bins,
        n_threshold=n_threshold, unscented=(C.poses[-1], C.covs[-1]),
    )  # fmt: skip
    return {"case": label, "k": k, "length": t.length, **res}


def coverage_vs_distance(
    trajectory: tr.Trajectory, k_r: float, k_l: float, n: int, seed: int, n_checkpoints: int = 5,
    n_threshold: int = 50_000,
) -> list[dict[str, Any]]:
    """Coverage of the Gaussian methods at checkpoints along a path (:func:`accuracy.accuracy_vs_distance`).

    Returns
    -------
    list of dict: ``distance`` [m], ``n``, ``coverage_se_98.89``, and per method
    (``cartesian``, ``expcoords``, ``unscented``) the (x, y) coverages at 50, 90, 98.89 % and
    the Hellinger distance, with the Monte Carlo ``hellinger_floor``.
    """
    rows = ac.accuracy_vs_distance(
        trajectory, k_r, k_l, n, np.random.default_rng(seed), n_checkpoints=n_checkpoints,
        n_threshold=n_threshold,
    )
    keep = ("coverage_xy_50", "coverage_xy_90", "coverage_xy_98.89", "hellinger")
    return [
        {"distance": r["distance"], "n": n,
         "coverage_se_98.89": r["monte_carlo"]["coverage_se_98.89"],
         "hellinger_floor": r["monte_carlo"]["hellinger_floor"],
         **{m: {key: r[m][key] for key in keep} for m in ("cartesian", "expcoords", "unscented")}}
        for r in rows
    ]


def accuracy_vs_distance_study(
    trajectory: dict[str, Any] = straight_path(20.0),  # noqa: B008
    k: float = 5e-4, n: int = 10_000, seed: int = 12, n_checkpoints: int = 5, n_threshold: int = 50_000,
) -> list[dict[str, Any]]:
    """:func:`coverage_vs_distance` along a configured trajectory (``n_threshold`` draws for the
    banana's density thresholds: probability error ``√(Pr(1−Pr)/n_threshold)``, 0.0005 at 98.89 %)."""
    return coverage_vs_distance(tr.from_config(trajectory), k, k, n, seed, n_checkpoints, n_threshold)


#: The headline figure's cases: the thesis's arc (V = 1 m/s, ω = 1 rad/s for 1 s: radius 1 m, 1 rad) and a long
#: path, each with the settings of its Method B map (:func:`_map_region`: cell side [m], heading cell [rad],
#: the map's own step [s]).
EXPCOORDS_CASES: tuple[dict[str, Any], ...] = (
    {"label": "arc r = 1 m, 1 rad", "trajectory": {"name": "arc", "radius": 1.0, "angle": 1.0},
     "map": {"resolution": 0.01, "theta_resolution": 0.035, "dt": 0.05}},
    {"label": "straight 5 m", "trajectory": {"name": "straight", "length": 5.0},
     "map": {"resolution": 0.04, "theta_resolution": 0.05, "dt": 0.1}},
)  # fmt: skip


def expcoords_regions(
    cases: Sequence[dict[str, Any]] = EXPCOORDS_CASES,
    k: float = 5e-4,
    track: float = 0.2,
    dt: float = 0.01,
    pr: float = PR_3SIGMA,
    n: int = 5000,
    seed: int = 6,
) -> dict[str, Any]:
    """Monte Carlo clouds of paths with every method's Pr region, for the report's headline figure.

    Per case: ``n`` per-step Monte Carlo end positions (midpoint integration,
    ``k_r = k_l = k`` [m], seeded ``[seed, case index]``), the nominal path,
    Method A's Pr-ellipse (polyline), the boundary polygons of the
    exponential-coordinates Gaussian's planar Pr highest-density region
    (:func:`pose_uncertainty.methods.expcoords.pr_region_xy`), Method C's
    Pr-ellipse about its own mean, and, for a case with a ``map`` entry, Method B's
    multi-step probability map of the same path and noise (:func:`_map_region`) with
    the boundary of its planar Pr highest-density region; and the share of the cloud
    inside each region.

    Returns
    -------
    dict: ``k``, ``track``, ``pr``, ``n`` and ``cases`` — list of {``label``,
    ``cloud_xy`` (n, 2), ``path_xy`` (N+1, 2), ``end`` (3,), ``ellipse_xy`` (401, 2),
    ``banana_xy`` (list of (m, 2)), ``c_mean`` (3,), ``c_ellipse_xy`` (401, 2),
    ``inside_ellipse``, ``inside_banana``, ``inside_c``, and with a map ``map`` (:func:`_map_region`)
    and ``inside_map``} (arrays as lists)
    """
    out: dict[str, Any] = {"k": k, "track": track, "pr": pr, "n": n, "cases": []}
    for j, case in enumerate(cases):
        t = tr.from_config({**dict(case["trajectory"]), "dt": dt, "track": track})
        rng = np.random.default_rng([seed, j])
        cloud = sp.sample_end_poses(t, k, k, n, rng)
        A, E, C = cv.propagate(t, k, k), ec.propagate(t, k, k), ut.propagate(t, k, k)
        end, cov = A.poses[-1], A.covs[-1]
        ellipse = cv.ellipse_polyline(cov[:2, :2], pr, end[:2], 400)
        c_mean, c_cov = C.poses[-1], C.covs[-1]
        banana = ec.pr_region_xy(E.poses[-1], E.covs[-1], pr, rng, n_grid=240, n=50_000)
        row = {
            "label": str(case.get("label", j)),
            "cloud_xy": cloud[:, :2].tolist(), "path_xy": t.poses[:, :2].tolist(), "end": end.tolist(),
            "ellipse_xy": ellipse.tolist(), "banana_xy": [b.tolist() for b in banana],
            "inside_ellipse": ac.coverage_ellipse(cloud[:, :2], end[:2], cov[:2, :2], (pr,))[ac.pr_label(pr)],
            "inside_banana": _inside_polygons(cloud[:, :2], banana),
            "c_mean": c_mean.tolist(),
            "c_ellipse_xy": cv.ellipse_polyline(c_cov[:2, :2], pr, c_mean[:2], 400).tolist(),
            "inside_c": ac.coverage_ellipse(cloud[:, :2], c_mean[:2], c_cov[:2, :2], (pr,))[ac.pr_label(pr)],
        }  # fmt: skip
        if case.get("map"):
            region, inside = _map_region(case["trajectory"], dict(case["map"]), k, track, pr, cloud[:, :2])
            row.update(map=region, inside_map=inside)
        out["cases"].append(row)
    return out


def _map_region(
    trajectory: dict[str, Any], spec: dict[str, Any], k: float, track: float, pr: float, cloud_xy: NDArray[np.float64]
) -> tuple[dict[str, Any], float]:
    """Method B on the case's path: the velocity model's multi-step map with the wheel noise's variances.

    The map (:func:`pose_uncertainty.methods.maps.multi_step_map`, ``scaling="abs"``) runs along the
    same path with its own step ``spec["dt"]`` [s] on cells of ``spec["resolution"]`` [m] and
    ``spec["theta_resolution"]`` [rad]; its constants are those whose per-step variances of travel
    and turn equal the wheel model's (:func:`pose_uncertainty.localization.motion.velocity_alphas_for_wheels`:
    it drops the travel–turn correlation of a turn). Its planar Pr region is every cell whose θ-marginal
    mass reaches the level of :meth:`~pose_uncertainty.methods.maps.ProbabilityMap.region_xy`.

    Returns
    -------
    map : dict — ``model``, ``alphas``, ``dt`` [s], ``resolution`` [m], ``theta_resolution`` [rad],
        ``n_steps``, ``lost_mass``, ``area`` [m²] of the region, ``boundary_xy`` (closed polylines
        [m] round the region's cells, contoured at the level on the cell centres)
    inside : float — the share of ``cloud_xy`` in a cell of the region (a point off the grid is outside)
    """
    step = float(spec["dt"])
    t = tr.from_config({**trajectory, "dt": step, "track": track})
    alphas = velocity_alphas_for_wheels(k, k, track, step)
    pm = mp_.multi_step_map("velocity", t.controls, t.dt, alphas=alphas, start=t.start, scaling="abs",
                            resolution=float(spec["resolution"]), theta_resolution=float(spec["theta_resolution"]))  # fmt: skip
    level, area = pm.region_xy(pr)
    region = {"model": "velocity", "alphas": list(alphas), "dt": step, "resolution": float(pm.x[1] - pm.x[0]),
              "theta_resolution": float(spec["theta_resolution"]), "n_steps": int(t.n_steps),
              "lost_mass": float(pm.lost_mass), "area": float(area),
              "boundary_xy": [line.tolist() for line in _region_boundary(pm, level)]}  # fmt: skip
    return region, float(_in_region(pm, level, cloud_xy).mean())


def _in_region(pm: mp_.ProbabilityMap, level: float, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Whether each point lies in a cell of the map's planar region (θ-marginal mass ≥ ``level``); off the grid: no."""
    mass = pm.marginal_xy()
    h = float(pm.x[1] - pm.x[0])
    ix = np.rint((xy[:, 0] - pm.x[0]) / h).astype(np.intp)
    iy = np.rint((xy[:, 1] - pm.y[0]) / h).astype(np.intp)
    on = (ix >= 0) & (ix < pm.x.size) & (iy >= 0) & (iy < pm.y.size)
    inside = np.zeros(xy.shape[0], dtype=bool)
    inside[on] = mass[ix[on], iy[on]] >= level
    return inside


def _region_boundary(pm: mp_.ProbabilityMap, level: float) -> list[NDArray[np.float64]]:
    """Closed polylines [m] round the cells of the map's planar region: the θ-marginal contoured at ``level``
    on the cell centres, framed by a ring of empty cells so that every contour closes."""
    import contourpy  # imported where used: only this boundary needs it

    h = float(pm.x[1] - pm.x[0])
    xs = np.concatenate(([pm.x[0] - h], pm.x, [pm.x[-1] + h]))
    ys = np.concatenate(([pm.y[0] - h], pm.y, [pm.y[-1] + h]))
    lines = contourpy.contour_generator(xs, ys, np.pad(pm.marginal_xy(), 1).T).lines(level)
    return [np.asarray(line) for line in lines]


def _inside_polygons(xy: NDArray[np.float64], polygons: Sequence[NDArray[np.float64]]) -> float:
    """Share of points inside the union of closed polygons (even–odd rule: holes subtract)."""
    inside = np.zeros(xy.shape[0], dtype=bool)
    for poly in polygons:
        x0, y0 = poly[:, 0], poly[:, 1]
        x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
        px, py = xy[:, 0:1], xy[:, 1:2]
        crosses = (y0 > py) != (y1 > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
        inside ^= (np.count_nonzero(crosses & (px < x_at), axis=1) % 2) == 1
    return float(inside.mean())
