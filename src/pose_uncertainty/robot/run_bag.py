"""A run of this project exported as a ROS 2 bag (rosbag2 folder, MCAP storage).

Topics:

* ``/odometry`` — ``nav_msgs/msg/Odometry`` per step: the nominal pose and Method A's
  propagated covariance (planar block at rows/columns x, y, yaw, :mod:`.messages`), frame
  ``odom``, the twist (V, ω) of the step ending there;
* ``/monte_carlo/particles`` — ``geometry_msgs/msg/PoseArray`` per Monte Carlo checkpoint
  (the end cloud at the last step);
* ``/maps/<name>`` — ``nav_msgs/msg/OccupancyGrid`` per probability map at the end: the
  θ-marginal, each cell ``round(100 · mass / peak)`` (0–100, the shape of the map, not
  its exact masses), row-major from cell (x₀, y₀), the cell size the map's.

Stamps are the run's simulated times from 0. The run is read through its attributes
(``times``, ``poses``, ``covs``, ``checkpoints``, ``end_poses``, ``maps``), so any run
result can be exported.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from .bag_write import open_bag
from .messages import OCCUPANCY_GRID, ODOMETRY, POSE_ARRAY

__all__ = ["write_run_bag"]


def _stamp_ns_of(t: float) -> int:
    return round(float(t) * 1e9)


def _grid_cells(marg: np.ndarray) -> np.ndarray:
    """(nx, ny) masses → (ny, nx) int8 cells 0–100 (module docstring)."""
    peak = float(marg.max()) if marg.size and marg.max() > 0 else 1.0
    return np.round(100.0 * np.clip(marg / peak, 0.0, 1.0)).astype(np.int8).T


def write_run_bag(run: Any, dest: str | Path) -> Path:
    """Write ``run`` (a run log or result) as a ROS 2 bag at ``dest`` (module docstring)."""
    missing = [a for a in ("times", "poses", "covs") if not hasattr(run, a)]
    if missing:
        raise ValueError(f"only runs with poses and covariances can be exported as a bag (missing: {missing})")
    times, poses, covs = np.asarray(run.times), np.asarray(run.poses), np.asarray(run.covs)
    n = times.size
    clouds = dict(getattr(run, "checkpoints", {}) or {})
    end = getattr(run, "end_poses", None)
    if end is not None and (n - 1) not in clouds:
        clouds[n - 1] = end
    maps = tuple(getattr(run, "maps", ()) or ())
    dt = np.diff(times)
    with open_bag(dest, "mcap") as sink:
        kit = sink.kit
        sink.add("/odometry", ODOMETRY)
        if clouds:
            sink.add("/monte_carlo/particles", POSE_ARRAY)
        names = []
        for i, mp in enumerate(maps):
            name = "/maps/" + (re.sub(r"[^A-Za-z0-9_]", "_", mp.name or "") or f"map{i}")
            names.append(name)
            sink.add(name, OCCUPANCY_GRID)
        for i in range(n):
            if i == 0:
                twist = (0.0, 0.0)
            else:
                d = poses[i] - poses[i - 1]
                twist = (float(np.hypot(d[0], d[1]) / dt[i - 1]), float(d[2] / dt[i - 1]))
            sink.write("/odometry", _stamp_ns_of(times[i]), kit.odometry(_stamp_ns_of(times[i]), poses[i], covs[i], twist))
        for i in sorted(clouds):
            sink.write("/monte_carlo/particles", _stamp_ns_of(times[i]), kit.pose_array(_stamp_ns_of(times[i]), clouds[i]))
        for name, mp in zip(names, maps, strict=True):
            marg = mp.marginal_xy()
            dx = float(mp.x[1] - mp.x[0]) if len(mp.x) > 1 else 0.01
            cells = _grid_cells(marg)
            origin = (float(mp.x[0]) - dx / 2.0, float(mp.y[0]) - dx / 2.0)
            sink.write(name, _stamp_ns_of(times[-1]), kit.occupancy_grid(_stamp_ns_of(times[-1]), cells, origin, dx))
    return Path(dest)
