"""Reference log bytes of runs without a ``drive`` section (the differential drive of k_r, k_l).

A run configuration without ``drive`` must log exactly what it logged before the
drives existed. :data:`CONFIGS` are small existing configurations (from
``config/quick.yaml`` and one with ``cov0``, checkpoints and the per-run regime);
``tests/data/default_runs/<name>.mcap`` holds each one's log (provenance replaced by a
fixed value, so that the git commit and the machine do not enter), written by the code
of commit ae20f79 (before the drives existed). The test compares the decoded records
within the reproducibility contract (:mod:`pose_uncertainty.records.reproducibility`), so
that it holds on any CPU: bit for bit on a CPU like the one that wrote them (AVX2, no
AVX-512), within tolerance on another. ``python tests/default_runs.py`` rewrites them;
do so only for a change that is *meant* to alter what a default run logs, and say so in
the commit.

The references are of run-log format version 2; version 3 (the differential drive computed
by the common drive stack, :data:`pose_uncertainty.records.run.FORMAT_VERSION`) logs the same
records, so they are kept — they pin the numbers of the code before the drives — and the
test writes the fresh log under the reference's version (:func:`reference_bytes`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import sys
from pathlib import Path
from typing import Any

from pose_uncertainty.experiments.run import RunConfig, execute
from pose_uncertainty.records.run import FORMAT_VERSION, log_bytes

REFERENCES = Path(__file__).with_name("data") / "default_runs"

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


def reference_bytes(config: dict[str, Any], format_version: str = FORMAT_VERSION) -> bytes:
    """The run's log bytes with the provenance fixed (no git commit, lock hash or host), stating ``format_version``."""
    result = execute(RunConfig.from_dict(config))
    fixed = dataclasses.replace(result, provenance={"package_version": "reference"})
    return log_bytes(fixed, format_version=format_version)


if __name__ == "__main__":
    REFERENCES.mkdir(parents=True, exist_ok=True)
    for name, cfg in CONFIGS.items():
        data = reference_bytes(cfg)
        (REFERENCES / f"{name}.mcap").write_bytes(data)
        sys.stdout.write(f"{name}: {len(data)} bytes, sha256 {hashlib.sha256(data).hexdigest()}\n")
