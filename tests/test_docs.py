"""The documentation site: it builds with warnings as errors, its examples run, its generated
reference is complete, its links resolve, and three pages render in a real browser.

One build (``sphinx-build -W --keep-going``, a few minutes: marked slow) serves every test that
reads the HTML. The examples are checked twice over: the Python ones are executed by the build
itself (MyST-NB pages and the exploration notebook; an exception fails the build), and the
tests below parse every ``pose-uncertainty`` command line of the docs with the real argument
parser and load every YAML example with the real configuration readers, without a build.
"""

from __future__ import annotations

import argparse
import html
import os
import re
import shlex
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
sys.path.insert(0, str(DOCS / "_ext"))

import pu_reference

#: The pages the browser opens: mathematics, a picture, an executed notebook with figures.
BROWSER_PAGES = ("theory/method-b.html", "explanation/design.html", "tutorials/explore_runs.html")


def _doc_sources() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts)


def _fenced(lang: str) -> list[tuple[Path, str]]:
    """Every fenced block of ``lang`` in the docs' Markdown pages and the README."""
    out = []
    for path in [*_doc_sources(), REPO / "README.md"]:
        text = path.read_text(encoding="utf-8")
        out += [(path, textwrap.dedent(m.group(2)))
                for m in re.finditer(rf"^( *)```{lang}\n(.*?)^\1```", text, re.MULTILINE | re.DOTALL)]
    return out


# --- without a build ----------------------------------------------------------------------------


def test_every_config_key_has_a_description() -> None:
    from pose_uncertainty.experiments.config import RUN_KEYS

    keys = pu_reference.walk_keys(pu_reference.config_schema())
    for name, sub in pu_reference.config_schema()["$defs"].items():
        keys += [(f"{name}:{p}", s) for p, s in pu_reference.walk_keys(sub)]
    assert len(keys) > 100
    missing = [path for path, sub in keys if not str(sub.get("description", "")).strip()]
    assert missing == [], f"configuration keys without a description: {missing}"

    def tables(ks: Any, prefix: str = "") -> list[str]:
        bad = []
        for k in ks:
            if not k.doc.strip():
                bad.append(prefix + k.name)
            bad += tables(k.keys, f"{prefix}{k.name}.")
        return bad

    assert tables(RUN_KEYS) == []


def test_command_examples_parse() -> None:
    """Every ``pose-uncertainty …`` line of the docs is accepted by the real parser."""
    from pose_uncertainty.cli import build_parser

    parser = build_parser()
    seen = 0
    for path, block in _fenced("sh"):
        for line in block.splitlines():
            line = line.split("  #")[0].strip()
            m = re.search(r"(?:\.venv/bin/)?pose-uncertainty (.*)$", line)
            if not m:
                continue
            argv = shlex.split(m.group(1).replace("<", "").replace(">", ""))
            try:
                parser.parse_args(argv)
            except SystemExit:
                pytest.fail(f"{path.relative_to(REPO)}: the parser rejects: {line}")
            seen += 1
    assert seen >= 8


def test_yaml_examples_are_accepted_by_the_config_readers() -> None:
    """Run, drive, localization, experiment-set, study and robot examples load as the code reads them."""
    import jsonschema

    from pose_uncertainty.experiments.localization import LocalizationConfig
    from pose_uncertainty.experiments.run import RunConfig

    schema = pu_reference.config_schema()
    kinds = []
    for path, block in _fenced("yaml"):
        data = yaml.safe_load(block)
        where = path.relative_to(REPO)
        if data.get("kind") == "localization":
            data["world"] = {"file": str(REPO / data["world"]["file"])}
            LocalizationConfig.from_dict(data)
            kinds.append("localization")
        elif "experiment_sets" in data:
            for name, entry in data["experiment_sets"].items():
                jsonschema.validate(entry, {"$defs": schema["$defs"], "$ref": "#/$defs/set"})
                kinds.append(f"set {name}")
        elif "studies" in data:
            jsonschema.validate(data["studies"], {"$defs": schema["$defs"], **schema["properties"]["studies"]})
            kinds.append("study")
        elif "robots" in data:
            from pose_uncertainty.experiments.robot_config import robots_config

            jsonschema.validate(data["robots"], schema["properties"]["robots"])
            kinds += [f"robot {name}" for name in robots_config(data)]
        elif set(data) <= {"runs_per_job", "report"}:  # the pipeline's own keys
            for key, value in data.items():
                jsonschema.validate(value, {"$defs": schema["$defs"], **schema["properties"][key]})
            kinds.append("pipeline")
        elif set(data) == {"drive"}:
            RunConfig.from_dict({"name": "doc", "trajectory": {"name": "arc", "radius": 1.0}, **data})
            kinds.append("drive")
        else:
            RunConfig.from_dict(data)
            kinds.append("run")
        assert kinds, where
    assert {"localization", "study", "drive", "run"} <= set(kinds)
    assert any(k.startswith("set") for k in kinds)
    assert any(k.startswith("robot") for k in kinds)


# --- the build ----------------------------------------------------------------------------------


@pytest.fixture(scope="session")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site built with warnings as errors into a temporary directory."""
    out = tmp_path_factory.mktemp("docs")
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    t0 = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-q",
         "-d", str(out / "doctrees"), str(DOCS), str(out / "html")],
        capture_output=True, text=True, env=env, cwd=REPO, timeout=1800, check=False,
    )  # fmt: skip
    warnings = [ln for ln in proc.stderr.splitlines() if "WARNING" in ln or "ERROR" in ln]
    warnings = [ln for ln in warnings if "[IPKernelApp]" not in ln]  # the kernel's own stderr
    assert warnings == []
    assert proc.returncode == 0, "\n".join(proc.stderr.splitlines()[-40:])
    print(f"docs built in {time.monotonic() - t0:.0f} s")
    return out / "html"


_ID = re.compile(r'\b(?:id|name)="([^"]+)"')
_LINK = re.compile(r'<(\w+)\b[^>]*?\b(href|src)="([^"]*)"')
_TAG = re.compile(r"<[^>]+>")


def _ids(path: Path) -> set[str]:
    return {html.unescape(m) for m in _ID.findall(path.read_text(encoding="utf-8"))}


def _links(path: Path) -> list[tuple[str, str]]:
    """``(tag.attribute, url)`` of every link and resource of a page."""
    return [(f"{t}.{a}", html.unescape(u)) for t, a, u in _LINK.findall(path.read_text(encoding="utf-8"))]


def _text(path: Path) -> str:
    """The page's text: tags removed, entities decoded, whitespace collapsed."""
    return " ".join(html.unescape(_TAG.sub(" ", path.read_text(encoding="utf-8"))).split())


@pytest.mark.slow
def test_site_has_every_section_and_the_executed_examples(site: Path) -> None:
    pages = sorted(site.rglob("*.html"))
    assert len(pages) > 150
    for section in ("tutorials", "howto", "theory", "explanation", "reference"):
        assert (site / section / "index.html").is_file()
    own = _text(site / "tutorials/own-run.html")
    m = re.search(r"Monte Carlo inside: ([0-9.]+)", own)
    assert m, "the executed tutorial shows no output"
    # the page shows the package's own number: the same seeded computation here gives it too
    import numpy as np

    from pose_uncertainty.core import stats, trajectories
    from pose_uncertainty.methods import covariance, sampling

    t = trajectories.straight(length=1.0, speed=1.0, dt=0.01, track=0.2)
    res = covariance.propagate(t, k_r=5e-4, k_l=5e-4)
    cloud = sampling.sample_end_poses(t, 5e-4, 5e-4, n=100_000, rng=np.random.default_rng(1), regime="per_step")
    inside = stats.fraction_inside_ellipse(cloud[:, :2], res.poses[-1, :2], res.covs[-1, :2, :2], covariance.PR_3SIGMA)
    assert m.group(1) == f"{inside:.4f}"
    notebook = _text(site / "tutorials/explore_runs.html")
    assert "Traceback" not in notebook
    assert "Traceback" not in own
    assert len(list((site / "_images").glob("*.png"))) >= 3  # the notebook's figures


@pytest.mark.slow
def test_generated_reference_lists_every_key_option_and_measure(site: Path) -> None:
    from pose_uncertainty.cli import build_parser

    config = _text(site / "reference/config.html")
    schema = pu_reference.config_schema()
    parts = [schema, *schema["$defs"].values()]
    paths = [p for part in parts for p, _ in pu_reference.walk_keys(part)]
    assert [p for p in paths if p not in config] == []

    measures = _text(site / "reference/measures.html")
    patterns = [pu_reference._readable(p) for p, _, _ in pu_reference.measure_registry()]
    assert [p for p in patterns if p not in measures] == []

    cli = _text(site / "reference/cli.html")

    def options(parser: Any) -> list[str]:
        out = []
        for a in parser._actions:
            if not isinstance(a, argparse._HelpAction):
                out += a.option_strings
            if isinstance(a, argparse._SubParsersAction):
                for sub in a.choices.values():
                    out += options(sub)
        return out

    assert [o for o in options(build_parser()) if o not in cli] == []


@pytest.mark.slow
def test_internal_links_resolve_and_nothing_is_fetched(site: Path) -> None:
    files = {str(p) for p in site.rglob("*") if p.is_file()}
    broken, external = [], []
    ids: dict[str, set[str]] = {}
    for page in sorted(p for p in site.rglob("*.html") if p.relative_to(site).parts[0] != "_static"):
        for attr, url in set(_links(page)):
            parts = urlsplit(url)
            if parts.scheme in ("http", "https"):
                if attr != "a.href":  # a script, style sheet, font or image from the web
                    external.append(f"{page.relative_to(site)}: {url}")
                continue
            if parts.scheme in ("mailto", "data", "javascript") or (not parts.path and not parts.fragment):
                continue
            target = os.path.normpath(os.path.join(page.parent, unquote(parts.path))) if parts.path else str(page)
            if target not in files and os.path.join(target, "index.html") in files:
                target = os.path.join(target, "index.html")
            if target not in files:
                broken.append(f"{page.relative_to(site)}: {url}")
            elif parts.fragment and target.endswith(".html"):
                if target not in ids:
                    ids[target] = _ids(Path(target))
                if unquote(parts.fragment) not in ids[target]:
                    broken.append(f"{page.relative_to(site)}: {url} (no such anchor)")
    assert external == [], external[:20]
    assert broken == [], broken[:20]


@pytest.mark.slow
def test_three_pages_render_in_chromium(site: Path, chromium: str, tmp_path: Path) -> None:
    from browser import open_chromium

    results: dict[str, dict[str, Any]] = {}
    with open_chromium(chromium, tmp_path) as cdp:
        for domain in ("Page", "Network", "Runtime", "Log"):
            cdp.call(f"{domain}.enable")
        for name in BROWSER_PAGES:
            cdp.events.clear()
            url = (site / name).as_uri()
            cdp.call("Page.navigate", url=url)
            cdp.wait_event("Page.loadEventFired", timeout=60)
            state = cdp.call(
                "Runtime.evaluate",
                expression=(
                    "(async () => {"
                    " if (window.MathJax && MathJax.startup) { await MathJax.startup.promise; }"
                    " const imgs = await Promise.all([...document.images].map("
                    "   i => i.decode().then(() => [i.src, i.naturalWidth], () => [i.src, -1])));"
                    " return {math: document.querySelectorAll('mjx-container').length,"
                    "         mathErrors: document.querySelectorAll('mjx-merror').length,"
                    "         rawTex: document.querySelectorAll('.math:not(:has(mjx-container))').length,"
                    "         images: imgs, title: document.title}; })()"
                ),
                awaitPromise=True, returnByValue=True,
            )["result"]["value"]  # fmt: skip
            cdp.call("Runtime.evaluate", expression="1")  # drain the events of the page
            events = list(cdp.events)
            state["requests"] = [e["params"]["request"]["url"] for e in events
                                 if e["method"] == "Network.requestWillBeSent"]  # fmt: skip
            state["console"] = [
                e["params"] for e in events
                if (e["method"] == "Runtime.consoleAPICalled" and e["params"]["type"] in ("error", "assert", "warning"))
                or (e["method"] == "Log.entryAdded" and e["params"]["entry"]["level"] in ("error", "warning"))
                or e["method"] == "Runtime.exceptionThrown"
            ]  # fmt: skip
            state["failed"] = [e["params"] for e in events if e["method"] == "Network.loadingFailed"]
            results[name] = state

    for name, s in results.items():
        external = [u for u in s["requests"] if not u.startswith(("file:", "data:", "about:", "blob:"))]
        assert external == [], f"{name} fetched from the network: {external}"
        assert s["console"] == [], f"{name}: console errors {s['console']}"
        assert s["failed"] == [], f"{name}: failed loads {s['failed']}"
        assert all(w > 0 for _, w in s["images"]), f"{name}: images that did not load {s['images']}"
        assert s["mathErrors"] == 0, f"{name}: MathJax errors ({s})"
        assert s["rawTex"] == 0, f"{name}: math left as TeX ({s})"
    assert results["theory/method-b.html"]["math"] > 20  # MathJax typeset the page's formulas
    assert len(results["explanation/design.html"]["images"]) >= 1
    assert len([w for _, w in results["tutorials/explore_runs.html"]["images"] if w > 0]) >= 3
