"""The run keys of the pipeline schema are generated from the key tables, and every key is described."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from pose_uncertainty.experiments import schema
from pose_uncertainty.experiments.config import RUN_KEYS, RunConfig
from pose_uncertainty.experiments.config_keys import Key

SCHEMA_FILE = Path(__file__).resolve().parents[1] / "workflow/schemas/config.schema.yaml"


def test_the_generated_schema_equals_the_checked_in_one() -> None:
    text = SCHEMA_FILE.read_text(encoding="utf-8")
    assert schema.render(yaml.safe_load(text)) == text, "run `make schema` and commit the result"


def _properties(node: dict, where: str = ""):
    for name, sub in (node.get("properties") or {}).items():
        yield f"{where}{name}", sub
        yield from _properties(sub, f"{where}{name}.")
        if isinstance(sub.get("items"), dict):
            yield from _properties(sub["items"], f"{where}{name}[].")


def test_every_run_key_has_a_description_and_a_default() -> None:
    run = schema.run_schema()
    keys = list(_properties(run))
    assert len(keys) > 50
    for name, sub in keys:
        assert sub.get("description", "").strip(), name
        assert "default" in sub, name


def test_a_key_without_a_description_is_refused() -> None:
    with pytest.raises(ValueError, match="'k_x' has no description"):
        Key("k_x", "number", "m", "  ", 1.0)


def test_the_schema_defaults_are_the_code_defaults() -> None:
    props = schema.run_schema()["properties"]
    full = RunConfig.from_dict({"trajectory": {"name": "straight"}}).to_dict()
    for key in RUN_KEYS:
        if key.kind not in ("section", "sections"):
            assert props[key.name]["default"] == full[key.name], key.name
    mc = props["monte_carlo"]["properties"]
    assert {k: v["default"] for k, v in mc.items()} == full["monte_carlo"]
    traj = props["trajectory"]["properties"]
    assert all(traj[k]["default"] == v for k, v in full["trajectory"].items() if k != "name")
