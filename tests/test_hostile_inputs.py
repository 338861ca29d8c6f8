"""Hostile input to the configuration layer: every trial is a clean one-line refusal, or its documented outcome.

Each trial writes its files into a scratch folder (beside an existing ``o.mcap`` that must survive),
runs ``pose-uncertainty ARGS`` (its ``main``, in this process) under an address-space limit
(:mod:`hostile`; a sample again in a new process, as a user types it), and checks what a user sees: exit code 2, one line on stderr naming the key
or the file (every needle), no traceback, and the folder exactly as before. The table holds the
inputs that were already refused well (bad types, unknown keys, ranges, malformed files) beside
those that were not: unbounded counts, map parameters that divided by zero, worlds that could
not work, repeated keys, unchecked booleans and choices, environment variables, and files that
are not regular or too large.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import yaml
from hostile import run_cli

from pose_uncertainty.core.input_files import MAX_CONFIG_BYTES
from pose_uncertainty.experiments import sweep
from pose_uncertainty.experiments.config import (
    MAP_KEYS,
    MONTE_CARLO_KEYS,
    RUN_KEYS,
    TRAJECTORY_KEYS,
)
from pose_uncertainty.experiments.config_keys import FROM_CODE, Key
from pose_uncertainty.experiments.drive_config import DRIVE_KEYS
from pose_uncertainty.experiments.localization import LOCALIZATION_KEYS

RUN = "trajectory: {name: straight, length: 1.0}\nmonte_carlo: {n_particles: 100}\n"
ONE_STEP = "trajectory: {name: straight, length: 0.01, dt: 0.02}\nmonte_carlo: {n_particles: 0}\n"
BOX = [[0.0, 0.0, 6.0, 0.0], [6.0, 0.0, 6.0, 5.0], [6.0, 5.0, 0.0, 5.0], [0.0, 5.0, 0.0, 0.0]]
LOCALIZATION: dict[str, Any] = {
    "kind": "localization", "name": "tiny", "seed": 3,
    "world": {"name": "box", "walls": {"segments": BOX, "resolution": 0.25},
              "landmarks": [{"id": 0, "x": 0.5, "y": 0.5}, {"id": 1, "x": 5.5, "y": 0.7}]},
    "trajectory": {"name": "tour", "segments": [["line", 1.0]], "speed": 0.5, "dt": 0.2, "start": [1.0, 1.0, 0.0]},
    "sensors": {"landmarks": {"range_std": 0.1, "bearing_std": 0.05, "max_range": 6.0, "period": 0.4}},
    "filters": {"ekf": {}},
}  # fmt: skip


def _loc(path: str, value: Any) -> str:
    """The localization config with the dotted ``path`` set to ``value``, as JSON text."""
    cfg = json.loads(json.dumps(LOCALIZATION))
    *head, last = path.split(".")
    node = cfg
    for k in head:
        node = node.setdefault(k, {})
    node[last] = value
    return json.dumps(cfg)


@dataclass
class Trial:
    """One hostile input: the files to write (name → text, bytes, or a callable making it), the CLI
    arguments, the environment, the expected exit code and the needles of the one line."""

    id: str
    files: dict[str, Any]
    needles: tuple[str, ...]
    args: tuple[str, ...] = ("run", "c.yaml", "-o", "o.mcap")
    env: dict[str, str] = field(default_factory=dict)


def _fifo(path: Path) -> None:
    os.mkfifo(path)


def _sparse(path: Path) -> None:
    with open(path, "wb") as fh:
        fh.truncate(3 * 1024**3)  # 3 GiB of holes: refused by its size, never read


def _directory(path: Path) -> None:
    path.mkdir()


TRIALS = [
    # --- what was refused well already ----------------------------------------------------------
    Trial("bad-type", {"c.yaml": RUN + "k_r: five\n"}, ("c.yaml", "'k_r'", "'five'")),
    Trial("bool-as-number", {"c.yaml": RUN + "k_r: true\n"}, ("'k_r'", "True")),
    Trial("unknown-key", {"c.yaml": RUN + "seeed: 3\n"}, ("'seeed'", "allowed")),
    Trial("out-of-range", {"c.yaml": RUN + "pr: 1.5\n"}, ("'pr'", "(0, 1)", "1.5")),
    Trial("negative", {"c.yaml": RUN + "k_l: -1.0e-4\n"}, ("'k_l'", ">= 0")),
    Trial("unknown-builder", {"c.yaml": "trajectory: {name: spiral}\n"}, ("'trajectory.name'", "'spiral'")),
    Trial("cov0-not-psd", {"c.yaml": RUN + "cov0: [[1, 0, 0], [0, -1, 0], [0, 0, 1]]\n"}, ("'cov0'",)),
    Trial("late-checkpoint", {"c.yaml": RUN.replace("100}", "10, checkpoints: [1000]}")},
          ("'monte_carlo.checkpoints'", "1..100")),
    Trial("malformed-yaml", {"c.yaml": "trajectory: [unclosed\n"}, ("c.yaml", "not valid YAML", "line")),
    Trial("malformed-json", {"c.json": '{"trajectory": '}, ("c.json", "not valid JSON"),
          ("run", "c.json", "-o", "o.mcap")),
    Trial("json-unknown-key", {"c.json": '{"trajectory": {"name": "straight"}, "kr": 1}'}, ("c.json", "'kr'"),
          ("run", "c.json", "-o", "o.mcap")),
    Trial("empty-file", {"c.yaml": ""}, ("c.yaml", "empty config file")),
    Trial("not-a-mapping", {"c.yaml": "- 1\n- 2\n"}, ("c.yaml", "must be a mapping", "list")),
    Trial("missing-file", {}, ("c.yaml", "no such file")),
    Trial("huge-particles", {"c.yaml": RUN.replace("100}", "1e12}")}, ("'monte_carlo.n_particles'", "1000000000000")),
    Trial("huge-steps", {"c.yaml": "trajectory: {name: straight, length: 1e9}\n"}, ("would need", "N = ")),
    Trial("huge-map", {"c.yaml": ONE_STEP + "maps: [{model: velocity, size: 100.0, resolution: 1e-4}]\n"},
          ("would need", "maps[0]")),
    # --- the defects of the hostile-input campaign ------------------------------------------------
    Trial("n-ellipses-1e9", {"c.yaml": RUN + "n_ellipses: 1e9\n"}, ("'n_ellipses'", "[1, 10000]", "1000000000")),
    Trial("map-resolution-0", {"c.yaml": RUN + "maps: [{model: velocity, resolution: 0}]\n"},
          ("'maps[0].resolution'", "> 0")),
    Trial("map-theta-resolution-0", {"c.yaml": ONE_STEP + "maps: [{model: velocity, theta_resolution: 0}]\n"},
          ("'maps[0].theta_resolution'", "(0, 6.28319]")),
    Trial("map-oversample-0", {"c.yaml": RUN + "maps: [{model: velocity, oversample: 0}]\n"},
          ("'maps[0].oversample'", "[1, 16]")),
    Trial("map-resolution-abc", {"c.yaml": RUN + "maps: [{model: velocity, resolution: abc}]\n"},
          ("'maps[0].resolution'", "'abc'")),
    Trial("map-resolution-nan", {"c.yaml": RUN + "maps: [{model: velocity, resolution: .nan}]\n"},
          ("'maps[0].resolution'", "nan")),
    Trial("map-corrected-3", {"c.yaml": ONE_STEP + "maps: [{model: velocity, corrected: 3}]\n"},
          ("'maps[0].corrected'", "true or false", "3")),
    Trial("map-cell-average-maybe", {"c.yaml": ONE_STEP + "maps: [{model: velocity, cell_average: maybe}]\n"},
          ("'maps[0].cell_average'", "'maybe'")),
    Trial("map-variance-from-bogus", {"c.yaml": ONE_STEP + "maps: [{model: odometry, variance_from: bogus}]\n"},
          ("'maps[0].variance_from'", "'hypothesis'", "'bogus'")),
    Trial("map-n-sampler-huge", {"c.yaml": RUN + "maps: [{model: velocity, n_sampler: 1e10}]\n"},
          ("'maps[0].n_sampler'",)),
    Trial("duplicate-key", {"c.yaml": RUN + "k_r: 1.0e-4\nk_r: 2.0e-4\n"}, ("c.yaml", "duplicate key 'k_r'",
                                                                          "lines 3 and 4")),
    Trial("duplicate-nested-key", {"c.yaml": "trajectory: {name: straight, length: 1.0, length: 2.0}\n"},
          ("c.yaml", "duplicate key 'length'")),
    Trial("json-duplicate-key", {"c.json": '{"trajectory": {"name": "straight"}, "seed": 1, "seed": 2}'},
          ("c.json", "duplicate key 'seed'"), ("run", "c.json", "-o", "o.mcap")),
    Trial("config-fifo", {"c.yaml": _fifo}, ("c.yaml", "FIFO", "regular file")),
    Trial("config-directory", {"c.yaml": _directory}, ("c.yaml", "directory", "regular file")),
    Trial("config-sparse-3gib", {"c.yaml": _sparse}, ("c.yaml", "too large", f"{MAX_CONFIG_BYTES:,}")),
    Trial("config-not-utf8", {"c.yaml": b"seed: \xff\xfe\n"}, ("c.yaml", "not UTF-8")),
    Trial("env-max-memory-1e400", {"c.yaml": RUN}, ("POSE_UNCERTAINTY_MAX_MEMORY", "'1e400'", "1 EiB"),
          env={"POSE_UNCERTAINTY_MAX_MEMORY": "1e400"}),
    Trial("env-max-memory-percent", {"c.yaml": RUN}, ("POSE_UNCERTAINTY_MAX_MEMORY", "'250%'", "(0, 100]"),
          env={"POSE_UNCERTAINTY_MAX_MEMORY": "250%"}),
    Trial("env-max-seconds-text", {"c.yaml": RUN}, ("POSE_UNCERTAINTY_MAX_SECONDS", "'soon'"),
          env={"POSE_UNCERTAINTY_MAX_SECONDS": "soon"}),
    Trial("env-max-seconds-1e400", {"c.yaml": RUN}, ("POSE_UNCERTAINTY_MAX_SECONDS", "'1e400'"),
          env={"POSE_UNCERTAINTY_MAX_SECONDS": "1e400"}),
    Trial("env-threads", {"c.yaml": RUN}, ("OMP_NUM_THREADS", "'many'"), env={"OMP_NUM_THREADS": "many"}),
    Trial("env-lock-directory", {"c.yaml": RUN}, ("POSE_UNCERTAINTY_ENVIRONMENT_LOCK", "regular file"),
          env={"POSE_UNCERTAINTY_ENVIRONMENT_LOCK": "."}),
    # --- localization worlds and filters ------------------------------------------------------------
    Trial("landmark-outside-room", {"c.yaml": _loc("world.landmarks", [*LOCALIZATION["world"]["landmarks"],
                                                                        {"id": 5, "x": 50, "y": 50}])},
          ("'world.landmarks[2]'", "bounds", "50")),
    Trial("start-outside-walls", {"c.yaml": _loc("trajectory.start", [-3.0, 1.0, 0.0])},
          ("'trajectory.start'", "bounds", "-3.0")),
    Trial("zero-landmarks", {"c.yaml": _loc("world.landmarks", [])}, ("'world.landmarks'", "sensors.landmarks")),
    Trial("particles-1e12", {"c.yaml": _loc("filters.particle", {"n_particles": 1e12})},
          ("'filters.particle.n_particles'", "1000000000000")),
    Trial("histogram-resolution-0", {"c.yaml": _loc("filters.histogram", {"resolution": 0})},
          ("'filters.histogram.resolution'", "> 0")),
    Trial("histogram-ntheta-huge", {"c.yaml": _loc("filters.histogram", {"ntheta": 1e9})},
          ("'filters.histogram.ntheta'",)),
    Trial("repeat-huge", {"c.yaml": _loc("repeat", 1e9)}, ("'repeat'",)),
    Trial("random-landmarks-huge", {"c.yaml": _loc("world.random_landmarks", {"count": 1e12})},
          ("'world.random_landmarks.count'",)),
    Trial("world-file-duplicate-key", {"c.yaml": _loc("world", {"file": "w.yaml"}),
                                       "w.yaml": "name: w\nname: v\nbounds: [0, 5, 0, 5]\n"},
          ("'world.file'", "w.yaml", "duplicate key 'name'")),
    Trial("world-file-fifo", {"c.yaml": _loc("world", {"file": "w.yaml"}), "w.yaml": _fifo},
          ("'world.file'", "w.yaml", "FIFO")),
]


def _write(folder: Path, files: dict[str, Any]) -> None:
    (folder / "o.mcap").write_bytes(b"an output that a refused run must leave alone\n")
    for name, content in files.items():
        p = folder / name
        if callable(content):
            content(p)
        elif isinstance(content, bytes):
            p.write_bytes(content)
        else:
            p.write_text(content, encoding="utf-8")


@pytest.mark.parametrize("trial", TRIALS, ids=[t.id for t in TRIALS])
def test_hostile_input_is_one_clean_line(trial: Trial, tmp_path: Path) -> None:
    _write(tmp_path, trial.files)
    out = run_cli(list(trial.args), tmp_path, env=trial.env)
    out.assert_clean_refusal(*trial.needles)


#: the trials run again in a new process, as a user types them: a variable that numpy's BLAS and OpenMP
#: read when the interpreter starts (and might complain of on stderr), a huge file under a whole
#: process's address-space limit
FRESH = ["env-threads", "config-sparse-3gib"]


@pytest.mark.parametrize("trial", [t for t in TRIALS if t.id in FRESH], ids=lambda t: t.id)
def test_hostile_input_is_one_clean_line_from_a_new_process(trial: Trial, tmp_path: Path) -> None:
    _write(tmp_path, trial.files)
    run_cli(list(trial.args), tmp_path, env=trial.env, process=True).assert_clean_refusal(*trial.needles)


def test_an_unusual_world_runs_with_a_one_line_warning_defining_its_measure(tmp_path: Path) -> None:
    """A path that leaves the room is unusual, not impossible: it runs, with one warning line."""
    (tmp_path / "c.yaml").write_text(_loc("trajectory.segments", [["line", 6.0]]), encoding="utf-8")
    out = run_cli(["run", "c.yaml", "-o", "o.mcap"], tmp_path)
    assert out.code == 0, out.stderr
    assert "Traceback" not in out.stderr
    lines = [ln for ln in out.stderr.splitlines() if ln.startswith("warning:")]
    assert len(lines) == 2, out.stderr  # the path leaves the bounds, and crosses the wall
    assert "leaves the world's bounds" in lines[0]
    assert "largest distance of a path pose outside" in lines[0]
    assert "% of the path's poses lie in occupied cells" in lines[1]
    assert set(out.after) - set(out.before) == {"o.mcap"}


# --- the pipeline's sweeps --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("axis", "needles"),
    [
        ({"trajectory.length": [1.0, 1.0, 16.0]}, ("sweep[0].trajectory.length'", "repeats the value 1.0")),
        ({"k_r": [1e-4, 2e-4], "k_l": [1e-4, 1e-4]}, ()),  # a zipped axis: its points differ
        ({"k_r": [1e-4, 1e-4], "k_l": [1e-4, 1e-4]}, ("sweep[0].{k_r, k_l}'", "k_r = 0.0001, k_l = 0.0001")),
    ],
)
def test_a_sweep_with_a_repeated_value_is_refused(axis: dict[str, Any], needles: tuple[str, ...]) -> None:
    spec = {"base": {"trajectory": {"name": "straight"}, "monte_carlo": {"n_particles": 0}}, "sweep": [axis]}
    if not needles:
        assert len(sweep.expand_set("S", spec)) == len(next(iter(axis.values())))
        return
    with pytest.raises(sweep.ConfigError) as err:
        sweep.expand_set("S", spec)
    assert "\n" not in str(err.value)
    for n in ("experiment_sets.S", *needles):
        assert n in str(err.value)


def test_labels_tell_repeated_values_apart() -> None:
    spec = {"base": {"trajectory": {"name": "straight"}, "monte_carlo": {"n_particles": 0}},
            "sweep": [{"seed": [1, 1], "labels": ["a", "b"]}]}  # fmt: skip
    assert [r.id for r in sweep.expand_set("S", spec)] == ["a", "b"]


# --- the key tables ------------------------------------------------------------------------------


def _walk(keys: tuple[Key, ...], where: str = "") -> list[tuple[str, Key]]:
    out: list[tuple[str, Key]] = []
    for k in keys:
        out.append((f"{where}{k.name}", k))
        out.extend(_walk(k.keys, f"{where}{k.name}."))
    return out


TABLES = [("run", RUN_KEYS), ("trajectory", TRAJECTORY_KEYS), ("monte_carlo", MONTE_CARLO_KEYS),
          ("maps", MAP_KEYS), ("drive", DRIVE_KEYS), ("localization", LOCALIZATION_KEYS)]  # fmt: skip


@pytest.mark.parametrize(("name", "table"), TABLES, ids=[n for n, _ in TABLES])
def test_every_key_has_a_doc_a_unit_a_default_and_a_range(name: str, table: tuple[Key, ...]) -> None:
    for dotted, k in _walk(table):
        assert k.doc.strip(), dotted
        assert k.unit not in (None, ""), dotted
        assert k.default is FROM_CODE or k.default is not None or k.nullable or k.kind in ("section", "choice") \
            or dotted.endswith("name") or dotted in ("run.drive",), (dotted, k.default)  # fmt: skip
        if k.kind == "integer":  # a count: bounded both ways, so no value can ask for unbounded memory
            assert k.lo is not None, dotted
            assert k.hi is not None, dotted
            assert math.isfinite(k.hi), dotted
        if k.kind == "choice":
            assert k.allowed, dotted


@pytest.mark.parametrize(("name", "table"), TABLES, ids=[n for n, _ in TABLES])
def test_every_integer_key_refuses_its_bounds_plus_one(name: str, table: tuple[Key, ...]) -> None:
    """Two routes to a key's range: the table's bounds and the check's refusal just beyond them."""
    for dotted, k in _walk(table):
        if k.kind != "integer":
            continue
        assert k.lo is not None
        assert k.hi is not None
        assert k.check(dotted, int(k.lo)) == int(k.lo)
        assert k.check(dotted, int(k.hi)) == int(k.hi)
        for bad in (int(k.lo) - 1, int(k.hi) + 1):
            with pytest.raises(ValueError, match=rf"config key '{dotted}' must be an integer in \[") as err:
                k.check(dotted, bad)
            assert str(bad) in str(err.value)


def test_the_schema_shows_the_same_bounds_as_the_tables() -> None:
    from pose_uncertainty.experiments.schema import run_schema

    props = run_schema()["properties"]
    for key in ("n_ellipses", "seed"):
        k = next(x for x in RUN_KEYS if x.name == key)
        assert (props[key]["minimum"], props[key]["maximum"]) == (k.lo, k.hi)
    maps = props["maps"]["items"]["properties"]
    for key in ("oversample", "n_sampler", "max_cells"):
        k = next(x for x in MAP_KEYS if x.name == key)
        assert (maps[key]["minimum"], maps[key]["maximum"]) == (k.lo, k.hi)


def test_the_shipped_configs_are_within_every_range() -> None:
    schema = yaml.safe_load((Path(__file__).resolve().parents[1] / "workflow/schemas/config.schema.yaml").read_text())
    for name in ("config.yaml", "quick.yaml"):
        cfg = yaml.safe_load((Path(__file__).resolve().parents[1] / "config" / name).read_text())
        assert sweep.validate_config(cfg, schema)
