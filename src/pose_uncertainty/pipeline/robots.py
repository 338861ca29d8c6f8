"""The jobs of the ``robots`` section and the robots' table (:mod:`pose_uncertainty.experiments.robot_config`).

Jobs (run as ``python -m pose_uncertainty.cli.robot_job``): :func:`simulate_robot` writes a
simulated robot's bag and its true values; :func:`calibrate_robot` calibrates a bag as
``pose-uncertainty robot calibrate`` does and checks the recovered values against the
truth (:func:`recovery`). The table: one row per robot, from its calibration job's outputs.

:func:`robot_row` flattens what the job logged (``calibration.json``, ``recovery.json``,
``horizon.json`` in ``data/robots/<name>/``) into the columns the claims read; nothing is
computed here, every cell is a logged value (a boolean as 1 or 0):

* ``<q>``, ``<q>.ci_lo``, ``<q>.ci_hi``, ``<q>.true``, ``<q>.covers`` for each calibrated
  quantity ``q`` (:data:`pose_uncertainty.robot.fit.CALIBRATION_KEYS`; the truth only for a
  simulated robot), ``n_covered``, ``n_quantities``;
* ``held_out.*`` — the held-out segments' NEES and 95 % ellipse coverage with their bands;
* ``nav2.*`` — the fitted AMCL alphas and their coverage of the wheel model's cloud, overall
  and per motion class, with the number of draws;
* ``horizon.<path>.<radius>.*`` — distance, time and Monte Carlo ratio of each threshold;
* ``umbmark.*`` — UMBmark on the squares found in the recording, where there are enough.
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.atomic import atomic_write_text
from ..core.provenance import provenance
from ..core.table_io import write_table
from ..experiments.config_keys import units
from ..experiments.robot_config import DRIVE_KEYS, SIMULATED_ROBOT_KEYS
from ..robot.calibrate import calibrate_bag
from ..robot.config import RobotConfig, read_robot_file
from ..robot.fit import CALIBRATION_KEYS
from ..robot.simulate import SimulatedRobot, calibration_drive, write_simulated_bag

__all__ = ["ROBOT_TRUTH_FORMAT", "calibrate_robot", "collect_robot_table", "recovery", "robot_row", "simulate_robot"]


def _load(path: Path) -> Any:
    return json.loads(path.read_text(encoding="utf-8"))


def _flag(value: Any) -> int | None:
    return None if value is None else int(bool(value))


def robot_row(name: str, calibration: Mapping[str, Any], recovery: Mapping[str, Any],
              horizon: Mapping[str, Any]) -> dict[str, Any]:  # fmt: skip
    """One robot's table row (module docstring) from the contents of its three JSON outputs."""
    row: dict[str, Any] = {"robot": name, "seed": calibration["seed"], "bag": calibration["bag"],
                           "n_segments": calibration["n_segments"]}  # fmt: skip
    rec = recovery.get("quantities", {})
    for q in CALIBRATION_KEYS:
        v = calibration[q]
        row.update({q: v["value"], f"{q}.ci_lo": v["ci95"][0], f"{q}.ci_hi": v["ci95"][1], f"{q}.std_error": v["std_error"]})
        if q in rec:
            row.update({f"{q}.true": rec[q]["true"], f"{q}.covers": _flag(rec[q]["covers"])})
    row.update(n_covered=recovery.get("n_covered"), n_quantities=recovery.get("n_quantities"))
    ho = calibration["held_out"]
    row.update({
        "held_out.n_segments": ho["n_segments"], "held_out.nees_mean": ho["nees_mean"],
        "held_out.nees_band_lo": ho["nees_band95"][0], "held_out.nees_band_hi": ho["nees_band95"][1],
        "held_out.nees_ok": _flag(ho["nees_ok"]), "held_out.ellipse_level": ho["ellipse_level"],
        "held_out.ellipse_coverage": ho["ellipse_coverage"], "held_out.coverage_lo": ho["ellipse_coverage_ci95"][0],
        "held_out.coverage_hi": ho["ellipse_coverage_ci95"][1], "held_out.ellipse_ok": _flag(ho["ellipse_ok"]),
    })  # fmt: skip
    nav = calibration["nav2_amcl"]
    row.update({f"nav2.alpha{i}": nav[f"alpha{i}"] for i in range(1, 5)})
    cov = nav["coverage"]
    row.update({"nav2.level": cov["level"], "nav2.coverage": cov["overall"], "nav2.n_draws": cov["n_draws"],
                "nav2.n_samples": nav["n_samples"], "nav2.n_increments": nav["n_increments"]})  # fmt: skip
    for cls, c in cov.items():
        if isinstance(c, Mapping):
            row.update({f"nav2.{cls}.coverage": c["coverage"], f"nav2.{cls}.increments": c["increments"]})
    row["horizon.n_mc"] = horizon.get("n_mc")
    for path in ("straight", "turning"):
        for t in horizon[path]["thresholds"]:
            base = f"horizon.{path}.{t['radius']:g}"
            row.update({f"{base}.distance": t["distance"], f"{base}.time": t["time"], f"{base}.mc_ratio": t["mc_ratio"]})
    um = calibration.get("umbmark") or {}
    row.update({"umbmark.laps_cw": um.get("laps", {}).get("cw"), "umbmark.laps_ccw": um.get("laps", {}).get("ccw")})
    for q in ("E_d", "E_b"):
        if um.get(q):
            row.update({f"umbmark.{q}": um[q]["value"], f"umbmark.{q}.ci_lo": um[q]["ci95"][0],
                        f"umbmark.{q}.ci_hi": um[q]["ci95"][1]})  # fmt: skip
    return row


def collect_robot_table(names: Sequence[str], outdirs: Sequence[str | os.PathLike[str]],
                        out: str | os.PathLike[str]) -> Path:  # fmt: skip
    """Read each robot's outputs (``outdirs``, in ``names`` order) and write the robots' table (CSV)."""
    rows = []
    for name, d in zip(names, outdirs, strict=True):
        p = Path(d)
        rows.append(robot_row(name, _load(p / "calibration.json"), _load(p / "recovery.json"), _load(p / "horizon.json")))
    return write_table(rows, out, first=("robot", "seed", "bag"))


# --- the jobs ----------------------------------------------------------------------------------------------

#: The format name of a simulated robot's truth file (``data/robots/<name>/truth.json``).
ROBOT_TRUTH_FORMAT = "pose-uncertainty-robot-truth"


def simulate_robot(spec: Mapping[str, Any], bag_out: str | os.PathLike[str], truth_out: str | os.PathLike[str]) -> Path:
    """Write the bag of a simulated robot with known parameters, and its true values beside it.

    Parameters
    ----------
    spec : mapping — one entry of the config's ``robots.runs``, checked
        (:func:`pose_uncertainty.experiments.robot_config.robots_config`): its ``simulate``
        (:class:`~pose_uncertainty.robot.simulate.SimulatedRobot`), ``drive``
        (:func:`~pose_uncertainty.robot.simulate.calibration_drive`) and ``seed``
    bag_out : path — the bag, one ``.mcap`` file (ROS 2, written with rosbags)
    truth_out : path — JSON: the simulated robot's parameters and the true value of each
        calibrated quantity, with units, and the provenance

    Returns
    -------
    Path — ``bag_out``
    """
    robot = SimulatedRobot(**spec["simulate"])
    segments = calibration_drive(**spec["drive"])
    path = write_simulated_bag(Path(bag_out), robot, np.random.default_rng(int(spec["seed"])), segments, storage="mcap-file")
    doc = {
        "format": ROBOT_TRUTH_FORMAT, "format_version": "1", "seed": int(spec["seed"]),
        "simulate": dict(spec["simulate"]), "drive": dict(spec["drive"]),
        "units": {"simulate": units(SIMULATED_ROBOT_KEYS), "drive": units(DRIVE_KEYS)},
        "truth": robot.truth(), "provenance": provenance(),
    }  # fmt: skip
    atomic_write_text(truth_out, json.dumps(doc, indent=1, sort_keys=True) + "\n")
    return path


def recovery(calibration: Mapping[str, Any], truth: Mapping[str, Any] | None) -> dict[str, Any]:
    """The recovered against the true value of each calibrated quantity: ``{quantity: {true, value, ci95,
    unit, covers}}`` (``covers``: the 95 % interval holds the true value), with their count; empty without truth."""
    if truth is None:
        return {"quantities": {}, "n_covered": None, "n_quantities": 0}
    rows = {}
    for key, t in truth["truth"].items():
        q = calibration[key]
        if q["unit"] != t["unit"]:
            raise ValueError(f"{key}: the calibration's unit {q['unit']!r} is not the truth's {t['unit']!r}")
        lo, hi = q["ci95"]
        rows[key] = {"true": t["value"], "value": q["value"], "ci95": [lo, hi], "unit": q["unit"],
                     "covers": bool(lo <= t["value"] <= hi)}  # fmt: skip
    return {"quantities": rows, "n_covered": sum(r["covers"] for r in rows.values()), "n_quantities": len(rows)}


def calibrate_robot(
    spec: Mapping[str, Any],
    bag: str | os.PathLike[str],
    outdir: str | os.PathLike[str],
    truth: str | os.PathLike[str] | None = None,
) -> Path:
    """Calibrate one robot of the ``robots`` section: what ``pose-uncertainty robot calibrate`` writes, and more.

    Writes into ``outdir`` the files of :data:`pose_uncertainty.robot.calibrate.OUTPUT_FILES`, the figures
    (:data:`~pose_uncertainty.robot.calibrate.FIGURE_FILES`) and ``recovery.json`` (:func:`recovery`:
    the recovered against the true values, when ``truth`` — a simulated robot's truth file — is given).

    Parameters
    ----------
    spec : mapping — one checked entry of ``robots.runs`` (its ``robot_file`` and ``seed``)
    bag : path — the bag; outdir : path — the folder of the outputs (created)
    truth : path, optional — :func:`simulate_robot`'s truth file

    Returns
    -------
    Path — ``outdir``
    """
    robot = read_robot_file(spec["robot_file"]) if spec.get("robot_file") else RobotConfig()
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    cal = calibrate_bag(Path(bag), robot, out, seed=int(spec["seed"]), figure_files=True,
                        progress=lambda text: print(text, file=sys.stderr, flush=True))  # fmt: skip
    doc = json.loads(Path(truth).read_text(encoding="utf-8")) if truth is not None else None
    if doc is not None and doc.get("format") != ROBOT_TRUTH_FORMAT:
        raise ValueError(f"{truth}: not a simulated robot's truth file")
    atomic_write_text(out / "recovery.json", json.dumps(recovery(cal, doc), indent=1, sort_keys=True) + "\n")
    return out
