"""Sphinx directives that generate the reference pages from the code, so they cannot drift.

* ``pu-cli`` — every command and option of ``pose-uncertainty`` (and of the pipeline's
  ``python -m pose_uncertainty.cli.job``), from the argument parsers themselves;
* ``pu-config-keys`` — every configuration key with its type, unit, default, what is
  allowed and its description, from the pipeline schema whose run keys are regenerated
  from the key tables (:func:`pose_uncertainty.experiments.schema.config_schema`);
  a key without a description is a build error;
* ``pu-measures`` — every logged measure (name pattern, unit, definition) from the
  registry of :mod:`pose_uncertainty.analysis.measures`;
* ``pu-log-schemas`` — the fields of the package's own protobuf messages and the fixed
  topics of a run log, from :mod:`pose_uncertainty.records`.

Each directive renders reStructuredText and parses it in place; use them in ``.rst`` pages.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path
from typing import Any

from docutils import nodes
from sphinx.application import Sphinx
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective
from sphinx.util.parsing import nested_parse_to_nodes

LOG = logging.getLogger(__name__)
REPO = Path(__file__).resolve().parents[2]
SCHEMA_FILE = REPO / "workflow" / "schemas" / "config.schema.yaml"


def _cell(text: Any) -> str:
    """One line of a list-table cell (no line breaks; literal where it is code)."""
    return " ".join(str(text).split())


def _lit(text: Any) -> str:
    s = _cell(text).replace("``", "` `")
    return f"``{s}``" if s else ""


def _plain(text: Any) -> str:
    """Free text as RST text: `code` spans as literals, the rest escaped where reST would read markup."""
    parts = re.split(r"(`[^`]+`)", _cell(text))
    # "\\ " (an escaped space, which reST drops) lets a literal touch the text around it
    return "".join(f"\\ {_lit(p[1:-1])}\\ " if p.startswith("`") and p.endswith("`") and len(p) > 1 else _escape(p)
                   for p in parts)  # fmt: skip


def _escape(s: str) -> str:
    """Escape what reST would read as markup in plain text."""
    s = s.replace("\\", "\\\\").replace("*", "\\*").replace("`", "\\`").replace("|", "\\|")
    s = re.sub(r"(?<![\w\\])_", r"\\_", s)
    s = re.sub(r"_(?!\w)", r"\\_", s)
    return s


def _table(header: list[str], rows: list[list[str]], widths: str = "auto") -> list[str]:
    out = [".. list-table::", "   :header-rows: 1", f"   :widths: {widths}", ""]
    for row in [header, *rows]:
        out.append(f"   * - {row[0] or ' '}")
        out.extend(f"     - {c or ' '}" for c in row[1:])
    out.append("")
    return out


class _Generated(SphinxDirective):
    has_content = False

    def lines(self) -> list[str]:  # pragma: no cover - overridden
        raise NotImplementedError

    def run(self) -> list[nodes.Node]:
        text = "\n".join(self.lines())
        return nested_parse_to_nodes(self.state, text, source=f"<{self.name}>", allow_section_headings=True)


# --- the command line ---------------------------------------------------------------------------


def _option_rows(parser: argparse.ArgumentParser) -> list[list[str]]:
    rows = []
    for a in parser._actions:
        if isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        if a.option_strings:
            metavar = a.metavar or (a.dest.upper() if a.nargs != 0 else "")
            if isinstance(metavar, tuple):
                metavar = " ".join(metavar)
            name = ", ".join(a.option_strings) + (f" {metavar}" if metavar and a.nargs != 0 else "")
        else:
            name = a.metavar if isinstance(a.metavar, str) else a.dest
        help_text = (a.help or "") % {"default": a.default, "prog": parser.prog} if a.help else ""
        if a.help is None or a.help == argparse.SUPPRESS:
            if a.help == argparse.SUPPRESS:
                continue
            LOG.warning("pu-cli: the option %s of %r has no help text", name, parser.prog)
        extra = []
        if a.choices and not isinstance(a, argparse._SubParsersAction):
            extra.append("one of " + ", ".join(_lit(c) for c in a.choices))
        if a.option_strings and a.nargs != 0 and a.default not in (None, argparse.SUPPRESS) and "default" not in help_text:
            extra.append(f"default {_lit(a.default)}")
        text = _plain(help_text) + ("" if not extra else (" (" + "; ".join(extra) + ")"))
        rows.append([_lit(name), text])
    return rows


def _cli_lines(parser: argparse.ArgumentParser, level: int, chars: str = "=-~^") -> list[str]:
    title = parser.prog
    out = [title, chars[level] * max(len(title), 3), ""]
    if parser.description:
        out += [_plain(parser.description), ""]
    usage = parser.format_usage().strip().removeprefix("usage: ")
    out += ["::", "", "   " + " ".join(usage.split()), ""]
    rows = _option_rows(parser)
    if rows:
        out += _table(["argument", "meaning"], rows, "30 70")
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for sub in a.choices.values():
                out += _cli_lines(sub, level + 1, chars)
    return out


class CliDirective(_Generated):
    """The command line reference, generated from the argument parsers."""

    def lines(self) -> list[str]:
        import os

        from pose_uncertainty.cli import build_parser
        from pose_uncertainty.cli.job import _parser as job_parser
        from pose_uncertainty.cli.robot_job import parser as robot_job_parser

        os.environ["COLUMNS"] = "200"
        return [*_cli_lines(build_parser(), 1), *_cli_lines(job_parser(), 1), *_cli_lines(robot_job_parser(), 1)]


# --- the configuration keys ---------------------------------------------------------------------


def config_schema() -> dict[str, Any]:
    """The pipeline schema with its run keys regenerated from the key tables (not the file's copy)."""
    import yaml

    from pose_uncertainty.experiments.schema import config_schema as regenerate

    return regenerate(yaml.safe_load(SCHEMA_FILE.read_text(encoding="utf-8")))


def _type_of(s: dict[str, Any]) -> str:
    if "$ref" in s:
        return "see " + s["$ref"].rsplit("/", 1)[-1]
    if "enum" in s:
        return "one of " + ", ".join(_lit(v) for v in s["enum"])
    if "const" in s:
        return "exactly " + _lit(s["const"])
    for alt in ("oneOf", "anyOf"):
        if alt in s:
            return " or ".join(_type_of(x) for x in s[alt])
    t = s.get("type", "any")
    t = " or ".join(t) if isinstance(t, list) else t
    bounds = []
    for k, sym in (("minimum", "≥"), ("exclusiveMinimum", ">"), ("maximum", "≤"), ("exclusiveMaximum", "<")):
        if k in s:
            bounds.append(f"{sym} {s[k]}")
    if bounds:
        t += " (" + ", ".join(bounds) + ")"
    if t == "array" and isinstance(s.get("items"), dict):
        t += " of " + _type_of(s["items"])
    return t


def walk_keys(schema: dict[str, Any], prefix: str = "") -> list[tuple[str, dict[str, Any]]]:
    """Every key of ``schema`` (object properties, recursively): ``(dotted.path, its schema)``."""
    out = []
    for name, sub in (schema.get("properties") or {}).items():
        path = f"{prefix}{name}"
        out.append((path, sub))
        out.extend(walk_keys(sub, path + "."))
        extra = sub.get("additionalProperties")
        if isinstance(extra, dict) and (extra.get("properties") or {}):
            out.extend(walk_keys(extra, path + ".<name>."))
        items = sub.get("items")
        if isinstance(items, dict) and items.get("properties"):
            out.extend(walk_keys(items, path + "[]."))
    return out


def _default(s: dict[str, Any]) -> str:
    if "default" not in s:
        return ""
    d = s["default"]
    if isinstance(d, (dict, list)) and len(json.dumps(d)) > 60:
        return "(see the keys below)" if isinstance(d, dict) else _lit(json.dumps(d)[:57] + "…")
    return _lit(json.dumps(d, ensure_ascii=False))


class ConfigKeysDirective(_Generated):
    """Every configuration key: the top level and each ``$defs`` entry, one table each."""

    def lines(self) -> list[str]:
        schema = config_schema()
        parts: list[tuple[str, str, dict[str, Any]]] = [("The pipeline configuration (top level)", "top", schema)]
        parts += [(f"{name}", name, sub) for name, sub in schema.get("$defs", {}).items()]
        out: list[str] = []
        for title, anchor, part in parts:
            out += [f".. _config-{anchor}:", "", title, "-" * len(title), ""]
            if part.get("description"):
                out += [_plain(part["description"]), ""]
            for path, sub in walk_keys(part):
                doc = sub.get("description")
                if not doc:
                    LOG.warning("pu-config-keys: the key %s of %s has no description", path, title)
                    doc = ""
                unit = sub.get("x-unit", "")
                facts = [_type_of(sub)]
                if isinstance(unit, str) and unit:
                    facts.append(f"unit {_lit(unit)}")
                if _default(sub):
                    facts.append(f"default {_default(sub)}")
                # a definition list: the key, then what it takes, then what it means
                out += [_lit(path), "   " + " · ".join(facts), "", "   " + (_plain(doc) or "—"), ""]
        return out


# --- the measures -------------------------------------------------------------------------------


def measure_registry() -> list[tuple[str, str, str]]:
    """``(name pattern, unit, definition)`` of every logged measure, in the registry's order."""
    from pose_uncertainty.analysis import measures

    return [(p.pattern.removesuffix(r"\Z"), u, d) for p, u, d in measures._COMPILED]


def _readable(pattern: str) -> str:
    """``A_sigma_(x|y)`` → ``A_sigma_{x|y}``; ``(.+)`` → ``<…>``."""
    s = re.sub(r"\(\.\+\)|\(\.\*\)|\(\[\^_\]\+\)", "<…>", pattern)
    s = re.sub(r"\(([^()]*)\)", r"{\1}", s)
    return s.replace("\\", "")


class MeasuresDirective(_Generated):
    """Every measure a run logs, from :mod:`pose_uncertainty.analysis.measures`."""

    def lines(self) -> list[str]:
        rows = []
        for pattern, unit, definition in measure_registry():
            text = re.sub(r"\{(\d)\}", lambda m: "{" + "⟨" + m.group(1) + "⟩" + "}", definition)
            text = text.replace("{⟨", "⟨").replace("⟩}", "⟩")
            rows.append([_lit(_readable(pattern)), _lit(unit), _plain(text)])
        head = [("A name in braces ``{a|b}`` stands for each alternative, ``<…>`` for a label; "
                 "⟨1⟩ in a definition is the first alternative chosen."), ""]  # fmt: skip
        return head + _table(["measure", "unit", "definition"], rows, "30 8 62")


# --- the log format -----------------------------------------------------------------------------


class LogSchemasDirective(_Generated):
    """The package's protobuf messages (fields, types) and the fixed topics of a run log."""

    def lines(self) -> list[str]:
        from pose_uncertainty.records import foxglove, run

        out = ["Fixed topics of a run log", "-------------------------", ""]
        rows = [[_lit(t), _lit(s)] for t, s in run.TOPICS.items()]
        out += _table(["topic", "schema"], rows, "40 60")
        for title, spec in (("pose_uncertainty/runlog.proto", foxglove.RUNLOG_MESSAGES),
                            ("pose_uncertainty/localization.proto", foxglove.LOCALIZATION_MESSAGES)):  # fmt: skip
            out += [f"Messages of ``{title}``", "-" * (len(title) + 16), ""]
            for msg, fields in spec.items():
                out += [f"``pose_uncertainty.{msg}``", "", *_table(
                    ["field", "type", "repeated"],
                    [[_lit(n), _lit(t), "yes" if rep else "no"] for n, t, rep in fields], "30 40 30"), ""]
        return out


# --- short cross-references in docstrings ---------------------------------------------------------


def resolve_short_reference(app: Sphinx, env: Any, node: Any, contnode: nodes.Node) -> nodes.Node | None:
    """Resolve a Python reference that a docstring writes short (``multi_step_map``,
    ``.analysis.umbmark``, ``Grid.centered``) to the one documented object whose full name ends
    with it; an ambiguous or unknown one is left to Sphinx (a broken reference is a build error).
    """
    if node.get("refdomain") != "py":
        return None
    target = str(node.get("reftarget", "")).lstrip(".~")
    if not target:
        return None
    from sphinx.util.nodes import make_refnode

    domain = env.get_domain("py")
    hits = [(name, obj) for name, obj in domain.objects.items()
            if (name == target or name.endswith("." + target)) and not obj.aliased]  # fmt: skip
    if len(hits) > 1:  # a re-exported object: prefer the referring module's package, then the shortest path
        here = str(node.get("py:module") or "")
        while here and len(hits) > 1:
            near = [h for h in hits if h[0].startswith(here + ".")]
            hits = near or hits
            here = here.rpartition(".")[0]
        hits = sorted(hits, key=lambda h: (h[0].count("."), h[0]))[:1]
    if not hits:
        hits = _by_import(domain, target, str(node.get("py:module") or ""))
    if not hits:
        return None
    name, obj = hits[0]
    return make_refnode(app.builder, node["refdoc"], obj.docname, obj.node_id, contnode, name)


def _by_import(domain: Any, target: str, here: str) -> list[tuple[str, Any]]:
    """The documented home of ``target`` found by importing it: a re-exported function's own
    entry (``maps.multi_step_map`` → ``maps.multi_step.multi_step_map``), or, for a module
    constant without a doc comment (which autodoc does not list), its module's page."""
    import importlib

    prefixes = [here.rsplit(".", i)[0] for i in range(here.count(".") + 1)] if here else []
    for full in [target, *(f"{p}.{target}" for p in prefixes)]:
        parts = full.split(".")
        for i in range(len(parts) - 1, 0, -1):
            try:
                obj: Any = importlib.import_module(".".join(parts[:i]))
            except ImportError:
                continue
            module = ".".join(parts[:i])
            try:
                for attr in parts[i:]:
                    obj = getattr(obj, attr)
            except AttributeError:
                break
            real = f"{getattr(obj, '__module__', '')}.{getattr(obj, '__qualname__', '')}"
            if real in domain.objects:
                return [(real, domain.objects[real])]
            if len(parts) - i == 1 and module in domain.objects:
                return [(module, domain.objects[module])]
            break
    return []


def setup(app: Sphinx) -> dict[str, Any]:
    app.connect("missing-reference", resolve_short_reference)
    app.add_directive("pu-cli", CliDirective)
    app.add_directive("pu-config-keys", ConfigKeysDirective)
    app.add_directive("pu-measures", MeasuresDirective)
    app.add_directive("pu-log-schemas", LogSchemasDirective)
    return {"parallel_read_safe": True, "parallel_write_safe": True, "version": "1"}
