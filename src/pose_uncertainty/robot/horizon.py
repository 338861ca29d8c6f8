"""The uncertainty horizon: how far and how long until the 95 % position error reaches a radius.

Method A (:func:`..methods.covariance.propagate_travels`) with the calibrated constants,
driving straight, or turning on a circle of radius ``turn_radius``, at the nominal
speed. The 95 % position error radius ``r95`` is the radius of the circle about the
odometry's position holding 95 % of the (x, y) Gaussian: with eigenvalues ``λ₁, λ₂``
of its covariance::

    P(|e| ≤ r) = (1/2π) ∫₀^{2π} (1 − exp(−r² a(φ)/2)) / (a(φ) √(λ₁λ₂)) dφ,
    a(φ) = cos²φ/λ₁ + sin²φ/λ₂

(polar coordinates; a periodic integrand, so the rectangle rule on 256 points is
exact to rounding), solved for ``P = 0.95`` by bisection. ``r95`` grows
monotonically with distance; the crossing distance of each threshold is interpolated
on a grid of 2000 steps (r95 at every fifth) up to a distance found by doubling (at most ``max_distance``).

Monte Carlo check: at each crossing, ``n_mc`` runs of the wheel model
(:func:`..methods.sampling.sample_end_poses`, midpoint steps as Method A) give the
empirical 95th percentile of the distance to the noiseless end position; its ratio to
the threshold is 1 for a right Gaussian.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.trajectories import Trajectory
from ..methods import covariance as cv
from ..methods.sampling import sample_end_poses

__all__ = ["PATHS", "UNITS", "horizon", "radius95"]

#: The unit of each quantity of the horizon (:func:`horizon`'s keys; a threshold's and a curve's by their names).
UNITS: dict[str, str] = {
    "speed": "m/s", "turn_radius": "m", "level": "1", "k_r": "m", "k_l": "m", "track": "m", "n_mc": "1",
    "radius": "m", "distance": "m", "time": "s", "mc_r95": "m", "mc_ratio": "1", "r95": "m",
}  # fmt: skip

PATHS: tuple[str, ...] = ("straight", "turning")
_N_GRID = 2000
_GRID = np.arange(0, _N_GRID + 1, 5)  # the steps at which r95 is evaluated
_PHI = np.linspace(0.0, 2.0 * math.pi, 256, endpoint=False)


def radius95(cov_xy: NDArray[np.float64], level: float = 0.95) -> NDArray[np.float64]:
    """Radius holding ``level`` of centred (x, y) Gaussians (module docstring); cov (..., 2, 2) → (...)."""
    lam = np.maximum(np.linalg.eigvalsh(cov_xy), 1e-150)  # (..., 2)
    l1, l2 = lam[..., 0, None], lam[..., 1, None]
    a = np.cos(_PHI) ** 2 / l1 + np.sin(_PHI) ** 2 / l2  # (..., 256)
    norm = 1.0 / np.sqrt(l1 * l2)

    def prob(r: NDArray) -> NDArray:
        return np.mean((1.0 - np.exp(-(r[..., None] ** 2) * a / 2.0)) / a, axis=-1) * norm[..., 0]

    lo = np.zeros(lam.shape[:-1])
    hi = 3.0 * np.sqrt(lam[..., 1])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        below = prob(mid) < level
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _path(kind: str, distance: float, track: float, turn_radius: float, speed: float, n: int = _N_GRID) -> Trajectory:
    ds = np.full(n, distance / n)
    dth = np.zeros(n) if kind == "straight" else ds / turn_radius
    # wheel travels of the axle-centre motion: Δs ± (b/2)Δθ
    return Trajectory(ds_r=ds + 0.5 * track * dth, ds_l=ds - 0.5 * track * dth,
                      dt=distance / n / speed, track=track, name=kind)  # fmt: skip


def _r95_along(traj: Trajectory, k_r: float, k_l: float) -> NDArray:
    _, covs = cv.propagate_travels(traj.ds_r, traj.ds_l, traj.track, k_r, k_l)
    return radius95(covs[_GRID, :2, :2])


def horizon(
    k_r: float,
    k_l: float,
    track: float,
    speed: float,
    thresholds: tuple[float, ...] = (0.05, 0.10, 0.50),
    turn_radius: float = 1.0,
    rng: np.random.Generator | None = None,
    n_mc: int = 1000,
    max_distance: float = 1e5,
) -> dict[str, Any]:
    """Distance [m] and time [s] until ``r95`` reaches each threshold, straight and turning.

    Returns ``{path: {"thresholds": [{"radius", "distance", "time", "mc_r95", "mc_ratio"}],
    "curve": {"distance": [...], "r95": [...]}}}`` with the inputs, ``n_mc`` (0 without the
    check) and the ``units`` of every quantity (:data:`UNITS`); a threshold not reached within
    ``max_distance`` has distance and time None. ``rng`` None skips the Monte Carlo check.
    """
    out: dict[str, Any] = {"speed": speed, "turn_radius": turn_radius, "level": 0.95, "k_r": k_r, "k_l": k_l, "track": track,
                           "n_mc": n_mc if rng is not None else 0, "units": dict(UNITS)}
    top = max(thresholds)
    for kind in PATHS:
        D = 1.0
        while True:
            traj = _path(kind, D, track, turn_radius, speed)
            r95 = _r95_along(traj, k_r, k_l)
            if r95[-1] >= top or D >= max_distance:
                break
            D = min(D * 4.0, max_distance)
        dist = D * _GRID / _N_GRID
        rows = []
        for thr in thresholds:
            if r95[-1] < thr:
                rows.append({"radius": thr, "distance": None, "time": None, "mc_r95": None, "mc_ratio": None})
                continue
            d = float(np.interp(thr, r95, dist))
            row: dict[str, Any] = {"radius": thr, "distance": d, "time": d / speed, "mc_r95": None, "mc_ratio": None}
            if rng is not None and d > 0:
                t = _path(kind, d, track, turn_radius, speed, 400)
                ends = sample_end_poses(t, k_r, k_l, n_mc, rng, method="midpoint", workers=1)
                err = np.hypot(*(ends[:, :2] - t.poses_by("midpoint")[-1, :2]).T)
                row["mc_r95"] = float(np.quantile(err, 0.95))
                row["mc_ratio"] = row["mc_r95"] / thr
            rows.append(row)
        keep = slice(None, None, 2)
        out[kind] = {"thresholds": rows, "curve": {"distance": dist[keep].tolist(), "r95": r95[keep].tolist()}}
    return out
