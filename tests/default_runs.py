"""Reference log bytes of runs without a ``drive`` section (the differential drive of k_r, k_l).

A run configuration without ``drive`` must log exactly what it logged before the
drives existed. :data:`CONFIGS` are small existing configurations (from
``config/quick.yaml`` and one with ``cov0``, checkpoints and the per-run regime);
``tests/data/default_run_logs.json`` holds the sha256 of each one's log bytes
(provenance replaced by a fixed value, so that the git commit does not enter),
written by ``python tests/default_runs.py`` at the commit it records. Regenerate it
only for a change that is *meant* to alter what a default run logs, and say so in
the commit.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

from pose_uncertainty.logs.run import RunConfig, execute
from pose_uncertainty.logs.runlog import log_bytes

REFERENCE = Path(__file__).with_name("data") / "default_run_logs.json"

_TRAJ = {"dt": 0.05, "track": 0.2, "speed": 0.5, "angular_speed": 1.0}

CONFIGS: dict[str, dict[str, Any]] = {
    "straight": {"name": "straight", "seed": 7, "n_ellipses": 5, "trajectory": {"name": "straight", "length": 1.0, **_TRAJ},
                 "monte_carlo": {"n_particles": 300}},
    "right_angles": {"name": "right_angles", "seed": 7, "n_ellipses": 5,
                     "trajectory": {"name": "right_angles", "dx": 2.0, "dy": 2.0, **_TRAJ},
                     "monte_carlo": {"n_particles": 300}},
    "per_run_exact": {"name": "b0.2_exact", "seed": 7, "k_r": 4.17e-4, "k_l": 4.17e-4, "pr": 0.99,
                      "trajectory": {"name": "straight", "length": 1.0, "speed": 1.0, "dt": 0.01, "track": 0.2},
                      "monte_carlo": {"n_particles": 300, "regime": "per_run", "method": "exact"}},
    "circle_cov0_checkpoints": {"name": "circle", "seed": 3, "k_r": 9e-4, "k_l": 1e-4,
                                "cov0": [[1e-4, 0.0, 0.0], [0.0, 2e-4, 1e-5], [0.0, 1e-5, 1e-3]],
                                "trajectory": {"name": "circle", "radius": 0.5, "laps": 0.5, "dt": 0.05, "track": 0.2},
                                "monte_carlo": {"n_particles": 400, "regime": "per_step", "checkpoints": [5, 20]}},
    "map_arc": {"name": "arc", "seed": 7, "n_ellipses": 5,
                "trajectory": {"name": "arc", "radius": 1.0, "angle": 1.0, "dt": 1.0, "speed": 1.0,
                               "angular_speed": 1.0, "track": 0.2},
                "monte_carlo": {"n_particles": 0},
                "maps": [{"name": "velocity", "model": "velocity", "alphas": [0.05] * 6, "resolution": 0.02},
                         {"name": "odometry", "model": "odometry", "alphas": [0.05] * 4, "resolution": 0.02}]},
}  # fmt: skip


def reference_bytes(config: dict[str, Any]) -> bytes:
    """The run's log bytes with the provenance fixed (no git commit, lock hash or host)."""
    result = execute(RunConfig.from_dict(config))
    return log_bytes(dataclasses.replace(result, provenance={"package_version": "reference"}))


def sha256(config: dict[str, Any]) -> str:
    return hashlib.sha256(reference_bytes(config)).hexdigest()


if __name__ == "__main__":
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=False).stdout.strip()
    doc = {"commit": commit, "sha256": {name: sha256(cfg) for name, cfg in CONFIGS.items()}}
    REFERENCE.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    sys.stdout.write(json.dumps(doc, indent=1) + "\n")
