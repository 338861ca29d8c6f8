"""JSON Schema (2020-12) validation with one-line errors: the key, the bad value, what is allowed.

The one formatter of schema errors of the package, used for the pipeline config
(:mod:`pose_uncertainty.experiments.sweep`) and the world files
(:mod:`pose_uncertainty.localization.world`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

__all__ = ["first_error", "format_schema_error", "load_schema"]


def load_schema(path: str | Path) -> dict[str, Any]:
    """Load a JSON Schema written as YAML (or JSON).

    Read with libyaml's parser where PyYAML has it (the pipeline schema: 0.05 s instead of 0.5 s,
    at every start of the workflow); the values are those of the pure-Python safe loader.
    """
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    with open(path, encoding="utf-8") as fh:
        return yaml.load(fh, Loader=loader)


def _dotted(path: Sequence[Any], root: str) -> str:
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or root


_BOUNDS = (("minimum", ">="), ("exclusiveMinimum", ">"), ("maximum", "<="), ("exclusiveMaximum", "<"))


def _allowed(error: Any) -> str:
    """What the failing schema keyword allows, in words."""
    kw, val, sch = error.validator, error.validator_value, error.schema
    if kw == "enum":
        return "one of " + ", ".join(json.dumps(v) for v in val)
    if kw == "const":
        return json.dumps(val)
    if kw == "type":
        return f"type {val}"
    if kw in dict(_BOUNDS):
        return " and ".join(f"{sym} {sch[k]}" for k, sym in _BOUNDS if k in sch)
    if kw == "additionalProperties":
        props = sorted(sch.get("properties", {}))
        return "only the keys " + ", ".join(props) if props else "no further keys"
    if kw == "required":
        return "the keys " + ", ".join(val) + " are required"
    if kw == "pattern":
        return f"strings matching {val}"
    if kw == "propertyNames":
        return "key names as described in the schema"
    if kw in ("minItems", "maxItems", "minProperties", "maxProperties", "minLength"):
        return f"{kw} {val}"
    return f"{kw}: {json.dumps(val, default=str)}"


def format_schema_error(error: Any, what: str = "config") -> str:
    """One line naming the key, the bad value and what the schema allows.

    ``what`` names the document in the message: ``"config key 'a.b' has bad value ..."``.
    """
    path, value, root = list(error.absolute_path), error.instance, f"<{what}>"
    if error.validator == "additionalProperties" and isinstance(value, Mapping):
        known, patterns = set(error.schema.get("properties", {})), error.schema.get("patternProperties", {})
        extra = sorted(k for k in value if k not in known and not any(re.search(p, k) for p in patterns))
        key = _dotted([*path, extra[0]], root) if extra else _dotted(path, root)
        shown = json.dumps(value.get(extra[0]) if extra else value, default=str)
        return f"{what} key {key!r} is not allowed (value {shown}); allowed: {_allowed(error)}"
    if error.validator == "required":
        missing = [k for k in error.validator_value if isinstance(value, Mapping) and k not in value]
        key = _dotted([*path, missing[0]], root) if missing else _dotted(path, root)
        return f"{what} key {key!r} is missing; allowed: {_allowed(error)}"
    shown = json.dumps(value, default=str)
    if len(shown) > 120:
        shown = shown[:117] + "..."
    return f"{what} key {_dotted(path, root)!r} has bad value {shown}; allowed: {_allowed(error)}"


#: The validator of each schema checked so far, by ``id``, with the schema itself (kept alive, so
#: that its ``id`` is not reused): checking a schema against the meta-schema costs ~10 ms, and the
#: world schema validates every localization run of a sweep.
_VALIDATORS: dict[int, tuple[Mapping[str, Any], Any]] = {}


def _validator(schema: Mapping[str, Any]) -> Any:
    hit = _VALIDATORS.get(id(schema))
    if hit is None or hit[0] is not schema:
        # imported where used: jsonschema takes 60 ms to import, and a run job never validates
        from jsonschema import Draft202012Validator

        Draft202012Validator.check_schema(schema)
        hit = (schema, Draft202012Validator(schema))
        _VALIDATORS[id(schema)] = hit
    return hit[1]


def first_error(schema: Mapping[str, Any], instance: Any, what: str = "config") -> str | None:
    """The most specific violation of ``schema`` by ``instance`` as one line, or None if valid.

    ``schema`` is checked against its meta-schema the first time it is used (a schema is not
    changed after that: the validator is kept for the same object).
    """
    from jsonschema.exceptions import best_match, relevance

    err = best_match(_validator(schema).iter_errors(instance), key=relevance)
    return None if err is None else format_schema_error(err, what)
