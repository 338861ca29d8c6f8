"""The report's section "Your robot": each robot's calibration outputs, read for the template.

The section (template ``templates/robots.html.j2``, included by ``comparison.html.j2``)
shows, for each robot of the config's ``robots`` section, what its calibration job logged in
``data/robots/<name>/`` (:mod:`pose_uncertainty.pipeline.robots`): the recovered against
the true parameters with their 95 % intervals (``recovery.json``; a recorded bag has no
truth), the held-out checks, nav2's coverage and UMBmark on the recorded squares
(``calibration.json``), the horizon (``horizon.json`` and its figure) and the three YAML
files to paste, verbatim. It reads and arranges; every number is a logged one.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = ["YAML_FILES", "robot_section"]

#: The parameter files shown verbatim, with what reads them.
YAML_FILES: tuple[tuple[str, str], ...] = (
    ("ros2_control.yaml", "ros2_control's diff_drive_controller"),
    ("nav2_amcl.yaml", "nav2's AMCL"),
    ("robot_localization.yaml", "robot_localization's EKF"),
)


def _json(path: str) -> Any:
    return json.loads(Path(path).read_text(encoding="utf-8"))


def robot_section(robots: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Each robot of the manifest with its outputs read: ``calibration``, ``recovery``, ``horizon`` (JSON as
    logged), ``yaml`` (``[(file, reader, text)]``) and ``figures`` (``{kind: path}`` of the PNGs that exist).

    Parameters
    ----------
    robots : sequence of ``{name, title, source, description, simulated, dir, files: {file name: path}}``
        (the workflow's manifest of the ``robots`` section)
    """
    out = []
    for r in robots:
        files = r["files"]
        out.append({
            **r,
            "calibration": _json(files["calibration.json"]),
            "recovery": _json(files["recovery.json"]),
            "horizon": _json(files["horizon.json"]),
            "yaml": [(f, reader, Path(files[f]).read_text(encoding="utf-8")) for f, reader in YAML_FILES],
            "figures": {k: files[f"{k}.png"] for k in ("horizon", "drive", "growth") if Path(files[f"{k}.png"]).is_file()},
        })  # fmt: skip
    return out
