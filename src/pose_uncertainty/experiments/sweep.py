"""Experiment sets: validate the pipeline config and expand each set into runs.

The pipeline config (``config/config.yaml``, validated against
``workflow/schemas/config.schema.yaml``, JSON Schema 2020-12) holds named
*experiment sets*. A set is a sweep: a ``base`` run configuration (the keys of
:class:`pose_uncertainty.experiments.run.RunConfig`) and a list of *axes*; each axis maps
dotted keys (``trajectory.speed``, ``k_r``, ``monte_carlo.method``, ``maps``)
to equal-length lists whose values are taken together (zipped); the runs of
the set are the product of its axes::

    A3_parameters:
      base: {trajectory: {name: straight, length: 1.0}}
      sweep:
        - k_r: [5.0e-4, 5.0e-5, 9.0e-4, 1.0e-4]
          k_l: [5.0e-4, 5.0e-5, 1.0e-4, 9.0e-4]
        - trajectory.track: [0.1, 0.2, 0.5]

expands into 4 × 3 = 12 runs. An axis may carry ``labels`` (one per value)
that replace the automatic label of its values in the run id.

Run ids are readable and stable: they are built from the swept values only
(``straight_L1_b0.2``), so an id changes exactly when a swept value changes,
and a change of a base value keeps the ids (Snakemake reruns the affected runs
because their parameters changed). Two different runs of one set that would
get the same id are an error; identical runs are merged.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ..core import trajectories
from ..core.schema import first_error
from ..core.table_io import plain_copy
from ..core.validation import parse_numbers
from .config import RUN_KEYS, RunConfig
from .config_keys import check_axis, check_partial

__all__ = [
    "ConfigError",
    "Run",
    "coerce_numbers",
    "expand_all",
    "expand_set",
    "label_value",
    "n_steps",
    "pipeline_structure",
    "run_label",
    "validate_config",
]

#: Short names of swept keys used in run ids (the key's last component otherwise).
ABBREVIATIONS: dict[str, str] = {
    "length": "L",
    "radius": "r",
    "angle": "a",
    "speed": "v",
    "angular_speed": "w",
    "dt": "dt",
    "track": "b",
    "laps": "laps",
    "dx": "dx",
    "dy": "dy",
    "k_r": "kr",
    "k_l": "kl",
    "n_particles": "n",
    "seed": "seed",
    "pr": "pr",
}

#: Keys whose value alone is readable (no ``key`` prefix in the id).
BARE_KEYS: frozenset[str] = frozenset({"name", "profile", "method", "regime", "model", "type"})

_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")


class ConfigError(ValueError):
    """A pipeline config that breaks the schema or the run rules; names key, value and what is allowed."""


@dataclass(frozen=True)
class Run:
    """One run of an experiment set.

    Attributes
    ----------
    set : str — experiment set name
    id : str — run id, unique within the set (letters, digits, ``_ . -``)
    config : dict — the full run configuration (``RunConfig.from_dict`` input, with ``name`` = id)
    swept : dict — the swept dotted keys and their values for this run
    """

    set: str
    id: str
    config: dict[str, Any]
    swept: dict[str, Any]

    @property
    def path(self) -> str:
        """Relative path of the run log, ``data/runs/<set>/<id>.mcap``."""
        return f"data/runs/{self.set}/{self.id}.mcap"


# --- schema validation ------------------------------------------------------------------


def _resolve(schema: Mapping[str, Any], root: Mapping[str, Any]) -> Mapping[str, Any]:
    ref = schema.get("$ref")
    if isinstance(ref, str) and ref.startswith("#/"):
        node: Any = root
        for part in ref[2:].split("/"):
            node = node[part]
        return node
    return schema


def _fill_defaults(schema: Mapping[str, Any], instance: Any, root: Mapping[str, Any] | None = None) -> None:
    """Insert schema ``default`` values for missing object keys, recursively (in place).

    Local ``$ref`` are followed; a schema with ``x-fill-defaults: false`` (the run
    configuration, whose defaults :class:`~pose_uncertainty.experiments.run.RunConfig` fills) is left alone.
    """
    root = schema if root is None else root
    schema = _resolve(schema, root)
    if not isinstance(instance, dict) or schema.get("x-fill-defaults") is False:
        return
    props = schema.get("properties", {})
    for key, sub in props.items():
        sub_r = _resolve(sub, root)
        if key not in instance and "default" in sub:
            instance[key] = copy.deepcopy(sub["default"])
        elif key not in instance and "default" in sub_r:
            instance[key] = copy.deepcopy(sub_r["default"])
        if key in instance:
            _fill_defaults(sub, instance[key], root)
    addl = schema.get("additionalProperties")
    if isinstance(addl, Mapping):
        for key, val in instance.items():
            if key not in props:
                _fill_defaults(addl, val, root)


def validate_config(config: Mapping[str, Any], schema: Mapping[str, Any]) -> dict[str, Any]:
    """Validate a pipeline config, fill defaults, expand the sets.

    The run keys (the shared ``defaults``, each set's ``base`` and sweep axes, and their
    localization counterparts) are validated by their key tables
    (:data:`~pose_uncertainty.experiments.config.RUN_KEYS`,
    :data:`~pose_uncertainty.experiments.localization_config.LOCALIZATION_KEYS`) — the one validator
    of a run key, which ``RunConfig.from_dict`` applies again to each complete run. The JSON
    Schema (generated from the same tables for editors and documentation) checks only the
    pipeline's own structure: the sets, studies, report.

    Parameters
    ----------
    config : mapping — the pipeline config as loaded from YAML
    schema : mapping — the JSON Schema (``workflow/schemas/config.schema.yaml``)

    Returns
    -------
    dict — the config with every default filled in

    Raises
    ------
    ConfigError
        On the first violation; the message names the key (dotted path), the value and what
        is allowed.
    """
    config = coerce_numbers(config)
    structure = _structure_of(schema)
    problem = first_error(structure, config)
    if problem is not None:
        raise ConfigError(problem)
    try:
        _check_run_keys(config)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    filled = copy.deepcopy(dict(config))
    _fill_defaults(structure, filled)
    expand_all(filled)  # raises ConfigError for bad runs
    return filled


#: The last schema validated against and its :func:`pipeline_structure`: the same structure object for
#: the same schema, so that its validator (checked against the meta-schema once) is reused.
_LAST_STRUCTURE: list[Any] = [None, None]


def _structure_of(schema: Mapping[str, Any]) -> dict[str, Any]:
    if _LAST_STRUCTURE[0] is not schema:
        _LAST_STRUCTURE[:] = [schema, pipeline_structure(schema)]
    return _LAST_STRUCTURE[1]  # type: ignore[no-any-return]


def pipeline_structure(schema: Mapping[str, Any]) -> dict[str, Any]:
    """The pipeline schema without its run keys: a run configuration is any mapping and a sweep
    axis any mapping of lists, since the key tables check them (:func:`validate_config`)."""
    out = copy.deepcopy(dict(schema))
    defs = out["$defs"]
    for name in ("run", "localization_run"):
        defs[name] = {"description": defs[name].get("description", ""), "type": "object", "x-fill-defaults": False}
    for name in ("set", "localization_set"):
        defs[name]["properties"]["sweep"]["items"] = {
            "type": "object", "minProperties": 1, "additionalProperties": {"type": "array", "minItems": 1},
        }  # fmt: skip
    return out


def _check_run_keys(config: Mapping[str, Any]) -> None:
    """The run keys of the pipeline config, by their key tables (ValueError naming the dotted key)."""
    from .localization_config import LOCALIZATION_KEYS

    for section, keys, sets in ((config, RUN_KEYS, "experiment_sets"),
                                (config.get("localization") or {}, LOCALIZATION_KEYS, "sets")):  # fmt: skip
        where = "" if sets == "experiment_sets" else "localization."
        if section.get("defaults") is not None:
            check_partial(f"{where}defaults", keys, section["defaults"])
        for name, spec in (section.get(sets) or {}).items():
            check_partial(f"{where}{sets}.{name}.base", keys, spec.get("base") or {})
            for ai, axis in enumerate(spec.get("sweep") or []):
                check_axis(f"{where}{sets}.{name}.sweep[{ai}]", keys, axis)


#: Keys whose values are text even when they look like numbers (``labels: ["1", "2"]``).
TEXT_KEYS: frozenset[str] = frozenset({"title", "description", "source", "labels", "name", "caption"})


def coerce_numbers(config: Mapping[str, Any]) -> dict[str, Any]:
    """A copy of a pipeline config with numbers written as text (``1e9``, ``5e-4``) parsed.

    YAML 1.1 — PyYAML, hence Snakemake — reads a float without a dot as a string. Every
    value, the run configurations and sweep axes included, goes through the one walker
    :func:`pose_uncertainty.core.validation.parse_numbers`; titles, labels and names
    (:data:`TEXT_KEYS`) stay text.
    """
    return dict(parse_numbers(config, text_keys=TEXT_KEYS))


def _relevance(error: Any) -> Any:
    from jsonschema.exceptions import relevance

    # prefer the deepest error, as best_match does
    return relevance(error)


# --- expansion ---------------------------------------------------------------------------


def _set_dotted(target: dict[str, Any], key: str, value: Any) -> None:
    parts = key.split(".")
    node = target
    for p in parts[:-1]:
        child = node.get(p)
        if not isinstance(child, dict):
            child = {}
            node[p] = child
        node = child
    last = parts[-1]
    if isinstance(value, Mapping) and isinstance(node.get(last), Mapping):
        node[last] = _deep_merge(node[last], value)
    else:
        node[last] = plain_copy(value)


def _deep_merge(a: Mapping[str, Any], b: Mapping[str, Any]) -> dict[str, Any]:
    out = plain_copy(dict(a))
    for k, v in b.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = _deep_merge(out[k], v)
        else:
            out[k] = plain_copy(v)
    return out


def label_value(value: Any) -> str:
    """Readable, file-name-safe label of one value (numbers as ``%g``)."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int | float):
        v = float(value)
        if v == int(v) and abs(v) < 1e6:
            return str(int(v))
        if math.isclose(v, round(v, 5), rel_tol=0, abs_tol=1e-12) and 1e-3 <= abs(v) < 1e6:
            text = f"{round(v, 5):g}"
        else:  # mantissa with at most 3 significant digits, two-digit exponent: 1e-04, 4.17e-04
            mant, _, exp = f"{v:.2e}".partition("e")
            text = mant.rstrip("0").rstrip(".") + "e" + exp
        return text.replace("+", "")
    if isinstance(value, str):
        return _SAFE.sub("-", value).strip("-") or "x"
    if isinstance(value, Mapping):
        parts = []
        if "name" in value:
            parts.append(label_value(value["name"]))
        if "model" in value:
            parts.append(label_value(value["model"]))
        if "type" in value:  # a drive section: its type first
            parts.append(label_value(value["type"]))
        for k in sorted(value):
            if k in ("name", "model", "type"):
                continue
            parts.append(run_label(k, value[k]))
        return "-".join(p for p in parts if p)
    if isinstance(value, list | tuple):
        return "-".join(label_value(v) for v in value) or "none"
    return _SAFE.sub("-", str(value))


def run_label(key: str, value: Any) -> str:
    """Label of one swept ``key = value`` in a run id: ``b0.2``, ``kr5e-04``, ``straight``."""
    last = key.split(".")[-1]
    text = label_value(value)
    if last in BARE_KEYS or isinstance(value, Mapping | list | tuple):
        return text
    return ABBREVIATIONS.get(last, _SAFE.sub("", last)) + text


def expand_set(
    name: str,
    spec: Mapping[str, Any],
    defaults: Mapping[str, Any] | None = None,
    *,
    normalize: Callable[[Mapping[str, Any]], dict[str, Any]] | None = None,
) -> list[Run]:
    """Expand one experiment set into its runs (product of axes, zipped within an axis).

    Parameters
    ----------
    name : str — set name
    spec : mapping with ``base`` (partial run config) and ``sweep`` (list of axes)
    defaults : mapping, optional — run-config defaults shared by every set
    normalize : callable, optional — validates a run configuration and returns every parameter
        (default: :class:`~pose_uncertainty.experiments.run.RunConfig`'s ``from_dict`` then ``to_dict``;
        the localization runs pass their own)

    Returns
    -------
    list of Run, in sweep order, duplicates merged

    Raises
    ------
    ConfigError naming ``experiment_sets.<name>...`` keys for unequal axis
    lengths, id clashes and invalid run configurations.
    """
    where = f"experiment_sets.{name}"
    base = _deep_merge(defaults or {}, spec.get("base", {}) or {})
    axes = [_axis_points(where, ai, axis) for ai, axis in enumerate(spec.get("sweep", []) or [])]
    runs: dict[str, Run] = {}
    for combo in itertools.product(*axes) if axes else [()]:
        run = _combine(name, where, base, combo, normalize)
        if run.id in runs:
            if runs[run.id].config != run.config:
                raise ConfigError(
                    f"config key '{where}.sweep' gives two different runs the id {run.id!r}; "
                    "allowed: distinct labels (add 'labels' to the axis)"
                )
            continue
        runs[run.id] = run
    return list(runs.values())


#: One value of an axis: the swept dotted keys with their values, and its labels in the run id.
_AxisPoint = tuple[dict[str, Any], list[str]]


def _axis_points(where: str, ai: int, axis: Mapping[str, Any]) -> list[_AxisPoint]:
    """The values of one axis (its lists zipped), each with its run-id label(s).

    ConfigError naming ``<where>.sweep[ai]`` for lists of unequal length or a
    wrong number of ``labels``.
    """
    keys = [k for k in axis if k != "labels"]
    lengths = {k: len(axis[k]) for k in keys}
    if len(set(lengths.values())) > 1:
        raise ConfigError(
            f"config key '{where}.sweep[{ai}]' has lists of unequal length {lengths}; "
            "allowed: equal lengths (the values of one axis are taken together)"
        )
    n = next(iter(lengths.values()), 0)
    labels = axis.get("labels")
    if labels is not None and len(labels) != n:
        raise ConfigError(
            f"config key '{where}.sweep[{ai}].labels' has {len(labels)} labels for {n} values; "
            "allowed: one label per value"
        )
    if labels is None:  # a value given twice would silently give one run fewer
        rows = [[axis[k][i] for k in keys] for i in range(n)]
        for i, row in enumerate(rows):
            if row in rows[:i]:
                shown = repr(row[0]) if len(keys) == 1 else ", ".join(f"{k} = {v!r}" for k, v in zip(keys, row, strict=True))
                raise ConfigError(
                    f"config key '{where}.sweep[{ai}].{keys[0] if len(keys) == 1 else '{' + ', '.join(keys) + '}'}' "
                    f"repeats the value {shown} (at positions {rows.index(row)} and {i}); "
                    "allowed: distinct values, each giving one run (or 'labels' to tell repeats apart)"
                )
    points = []
    for i in range(n):
        values = {k: axis[k][i] for k in keys}
        lab = [label_value(labels[i])] if labels is not None else [run_label(k, v) for k, v in values.items()]
        points.append((values, lab))
    return points


def _combine(
    name: str,
    where: str,
    base: dict[str, Any],
    combo: Sequence[_AxisPoint],
    normalize: Callable[[Mapping[str, Any]], dict[str, Any]] | None = None,
) -> Run:
    """The run of one combination of axis values: ``base`` with them set, its id from their labels.

    ConfigError naming the set and the run id when the result is not a valid run configuration.
    """
    cfg = plain_copy(base)
    swept: dict[str, Any] = {}
    parts: list[str] = []
    for values, lab in combo:
        for k, v in values.items():
            _set_dotted(cfg, k, v)
            swept[k] = plain_copy(v)
        parts.extend(lab)
    run_id = "_".join(x for x in parts if x) or "run"
    run_id = _SAFE.sub("-", run_id)
    cfg["name"] = run_id
    try:
        full = RunConfig.from_dict(cfg).to_dict() if normalize is None else normalize(cfg)
    except ValueError as exc:
        raise ConfigError(f"{where}, run {run_id!r}: {exc}") from None
    return Run(set=name, id=run_id, config=full, swept=swept)


def expand_all(config: Mapping[str, Any]) -> dict[str, list[Run]]:
    """Expand every experiment set of a (validated, defaults-filled) pipeline config.

    Returns
    -------
    dict of set name to list of Run, in config order
    """
    key = json.dumps([config.get("defaults"), config.get("seed"), config.get("experiment_sets")],
                     sort_keys=True, default=repr)  # fmt: skip
    hit = _EXPANDED.get(key)
    if hit is None:
        defaults = dict(config.get("defaults", {}) or {})
        if "seed" in config and "seed" not in defaults:
            defaults["seed"] = config["seed"]
        hit = {name: expand_set(name, spec, defaults) for name, spec in (config.get("experiment_sets", {}) or {}).items()}
        _EXPANDED.clear()  # the last config only: the workflow validates it, then expands it
        _EXPANDED[key] = hit
    return {name: list(runs) for name, runs in hit.items()}


#: The runs of the last config expanded (:func:`expand_all`), by its JSON text.
_EXPANDED: dict[str, dict[str, list[Run]]] = {}


def n_steps(config: Mapping[str, Any]) -> int:
    """Number of steps of a run configuration's trajectory (counted, not built)."""
    tp = {k: v for k, v in config["trajectory"].items() if k != "name"}
    return trajectories.n_steps(config["trajectory"]["name"], **tp)
