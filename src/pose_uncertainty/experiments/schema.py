"""The run keys of ``workflow/schemas/config.schema.yaml``, generated from the key tables.

The key tables next to the config dataclasses (:data:`~pose_uncertainty.experiments.config.RUN_KEYS`
and its sections, :data:`~pose_uncertainty.experiments.drive_config.DRIVE_KEYS`) are the one
definition of every run key. :func:`run_schema` turns them into the JSON Schema of a run
configuration (``$defs.run``) and :func:`sweep_axis_schema` into that of a sweep axis;
:func:`config_schema` puts both into the pipeline schema, whose other parts (the experiment
sets, studies, localization) are kept as they are. Regenerate the checked-in file with::

    python -m pose_uncertainty.experiments.schema workflow/schemas/config.schema.yaml

(``make schema``); ``tests/test_config_schema.py`` fails while it differs.
"""

from __future__ import annotations

import copy
import dataclasses
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from ..core import trajectories
from ..methods.wheel_noise import WheelErrorSources
from .config import RUN_KEYS, _map_defaults
from .config_checks import builder_keywords
from .config_keys import Key, keys_schema
from .localization_config import LOCALIZATION_KEYS
from .localization_config import code_defaults as localization_code_defaults
from .pipeline_keys import PIPELINE_KEYS, REPORT_KEYS
from .robot_config import ROBOT_KEYS, ROBOTS_KEYS
from .robot_config import code_defaults as robot_code_defaults

__all__ = ["HEADER", "config_schema", "localization_run_schema", "render", "robots_schema", "run_schema",
           "sweep_axis_schema"]

HEADER = (
    "# GENERATED in part: $defs.run, $defs.localization_run, the sweep axes of $defs.set and\n"
    "# $defs.localization_set, properties.robots, runs_per_job and report.summary_above come from the\n"
    "# key tables of pose_uncertainty.experiments.config, .drive_config, .localization, .robot_config\n"
    "# and .pipeline_keys\n"
    "# (python -m pose_uncertainty.experiments.schema workflow/schemas/config.schema.yaml, or make schema).\n"
    "# Edit the key tables, not those parts.\n"
)


def _code_defaults() -> dict[str, Any]:
    """The defaults that the run keys take from the code they configure (builders, dataclasses)."""
    traj: dict[str, Any] = {}
    for name, fn in trajectories.BUILDERS.items():
        for k, v in builder_keywords("trajectory", fn, {"name": name})[0].items():
            traj.setdefault(k, list(v) if isinstance(v, tuple) else v)
    maps = {**_map_defaults("velocity", "multi"), **_map_defaults("velocity", "single"), "name": "velocity"}
    encoder = {f.name: f.default for f in dataclasses.fields(WheelErrorSources)}
    return {"trajectory": traj, "maps": maps, "drive": {"errors": {"encoder": encoder}}}


def _schema_of(keys: tuple[Key, ...], code: Mapping[str, Any], cls: str) -> dict[str, Any]:
    """The JSON Schema of a (partial) configuration of the key table ``keys`` (class ``cls``)."""
    properties = keys_schema(keys, code)
    # which trajectory keys apply depends on the builder: the config class names the builder's in its error
    del properties["trajectory"]["additionalProperties"]
    kind = "localization run" if "localization" in cls else "run"
    return {
        "description": f"A (partial) {kind} configuration, see pose_uncertainty.experiments.{cls}.",
        "x-fill-defaults": False,
        "type": "object",
        "additionalProperties": False,
        "properties": properties,
    }


def run_schema() -> dict[str, Any]:
    """The JSON Schema (2020-12) of a (partial) run configuration, from :data:`RUN_KEYS`."""
    return _schema_of(RUN_KEYS, _code_defaults(), "config.RunConfig")


def localization_run_schema() -> dict[str, Any]:
    """The JSON Schema of a (partial) localization run configuration, from :data:`LOCALIZATION_KEYS`."""
    return _schema_of(LOCALIZATION_KEYS, localization_code_defaults(), "localization.LocalizationConfig")


def _axis_keys() -> list[tuple[str, Key]]:
    """The scalar run keys a sweep axis may set: the top-level ones and those of the sections."""
    out: list[tuple[str, Key]] = []
    for key in RUN_KEYS:
        if key.kind == "section" and key.name in ("trajectory", "monte_carlo"):
            out.extend((f"{key.name}.{k.name}", k) for k in key.keys if k.kind in ("number", "integer", "choice"))
        elif key.kind in ("number", "integer", "choice"):
            out.append((key.name, key))
    return out


def sweep_axis_schema() -> dict[str, Any]:
    """The JSON Schema of one sweep axis: dotted run keys to equal-length lists of their values."""
    names = "|".join(["labels", *(k.name for k in RUN_KEYS)])
    properties: dict[str, Any] = {
        "labels": {"description": "One readable run-id label per value of the axis.", "type": "array",
                   "items": {"type": "string", "pattern": "^[A-Za-z0-9_.-]+$"}},
    }  # fmt: skip
    for dotted, key in _axis_keys():
        item = {k: v for k, v in key.schema().items() if k not in ("description", "default", "x-unit")}
        properties[dotted] = {"description": key.doc, "type": "array", "items": item}
    return {
        "type": "object",
        "minProperties": 1,
        "propertyNames": {"pattern": f"^({names})(\\.[A-Za-z_0-9]+)*$"},
        "additionalProperties": {"type": "array", "minItems": 1},
        "properties": properties,
    }


def robots_schema() -> dict[str, Any]:
    """The JSON Schema of the ``robots`` section, from :data:`~.robot_config.ROBOTS_KEYS` and :data:`~.robot_config.ROBOT_KEYS`."""
    entry = {"type": "object", "additionalProperties": False, "properties": keys_schema(ROBOT_KEYS, robot_code_defaults())}
    return {
        "description": ("Your robot (pose_uncertainty.experiments.robot_config): each entry a bag calibrated by a "
                        "pipeline job as `pose-uncertainty robot calibrate` does (calibration.json, the ros2_control, "
                        "nav2 AMCL and robot_localization YAML files, horizon.json in data/robots/<name>/), a "
                        "simulated robot's bag written by the pipeline itself when `bag` is null; the report's "
                        "section \"Your robot\".\n"),
        "type": "object",
        "additionalProperties": False,
        "default": {"enabled": True, "runs": {}},
        "properties": {
            **keys_schema(ROBOTS_KEYS),
            "runs": {"description": "Named robots; the name is a directory name under data/robots/.",
                     "type": "object", "default": {}, "propertyNames": {"pattern": "^[A-Za-z0-9_-]+$"},
                     "additionalProperties": entry},
        },
    }  # fmt: skip


def config_schema(current: Mapping[str, Any]) -> dict[str, Any]:
    """The pipeline schema ``current`` with its run keys regenerated from the key tables."""
    out = copy.deepcopy(dict(current))
    for key in PIPELINE_KEYS:
        out["properties"][key.name] = key.schema()
    report = out["properties"]["report"]
    for key in REPORT_KEYS:
        report["properties"][key.name] = key.schema()
        report["default"][key.name] = key.default
    out["$defs"]["run"] = run_schema()
    out["$defs"]["set"]["properties"]["sweep"]["items"] = sweep_axis_schema()
    out["$defs"]["localization_run"] = localization_run_schema()
    out["properties"]["robots"] = robots_schema()
    out["$defs"].pop("localization_motion", None)  # now inline, from the key table
    names = "|".join(["labels", *(k.name for k in LOCALIZATION_KEYS)])
    loc_axis = out["$defs"]["localization_set"]["properties"]["sweep"]["items"]
    loc_axis["propertyNames"] = {"pattern": f"^({names})(\\.[A-Za-z_0-9]+)*$"}
    return out


def render(current: Mapping[str, Any]) -> str:
    """The text of the checked-in schema file: :data:`HEADER` and :func:`config_schema` as YAML."""
    return HEADER + yaml.safe_dump(config_schema(current), sort_keys=False, allow_unicode=True, width=110)


def main(argv: list[str] | None = None) -> int:
    """Regenerate the schema file given as the one argument, in place."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m pose_uncertainty.experiments.schema workflow/schemas/config.schema.yaml",
              file=sys.stderr)  # fmt: skip
        return 2
    path = Path(args[0])
    text = render(yaml.safe_load(path.read_text(encoding="utf-8")))
    path.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
