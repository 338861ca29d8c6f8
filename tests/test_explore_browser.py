"""The explorer in headless Chromium: it loads with no console error and a k_r change redraws.

The server is started as the command (``pose-uncertainty explore``, loopback, a free port);
Chromium is driven over the DevTools protocol with the client of the report's browser test.
Every request the page makes must go to 127.0.0.1. The numbers read from the page's DOM (inside
Bokeh's shadow roots) must equal :func:`pose_uncertainty.present.explore.compute` of the same
settings, before and after k_r is changed in the page.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from browser import CDP, open_chromium
from hostile import interrupt, interruptible

from pose_uncertainty.cli import main
from pose_uncertainty.present import explore
from pose_uncertainty.records.formats import open_run

SRC = Path(__file__).resolve().parents[1] / "src"

#: Finds an element by CSS selector through every open shadow root (Bokeh renders into them).
DEEP = (
    "function deep(root, sel) { const r = root.querySelector(sel); if (r) return r;"
    " for (const el of root.querySelectorAll('*')) { if (el.shadowRoot) { const s = deep(el.shadowRoot, sel);"
    " if (s) return s; } } return null; }"
)


def _text(cdp: CDP, element_id: str) -> str | None:
    expr = f"(() => {{ {DEEP}; const e = deep(document, '#{element_id}'); return e ? e.textContent : null; }})()"
    return cdp.call("Runtime.evaluate", expression=expr, returnByValue=True)["result"].get("value")


def _wait_text(cdp: CDP, element_id: str, differs_from: str | None, timeout: float) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        t = _text(cdp, element_id)
        if t is not None and t != differs_from:
            return t
        time.sleep(0.25)
    raise TimeoutError(f"#{element_id} did not change from {differs_from!r} within {timeout} s")


def _shown(view: explore.View, key: str) -> str:
    return f"{100 * view.coverage[key]['fraction']:.2f}"


@contextlib.contextmanager
def explorer_page(
    browser: str, tmp_path: Path, server_cpu: int | None = None
) -> Iterator[tuple[CDP, str]]:
    """The explorer started as the command and opened in headless Chromium: ``(cdp, url)``.

    ``server_cpu`` pins the server process to that CPU (the benchmark's one core).
    The DevTools domains Page, Network, Runtime and Log are enabled before the page loads, so
    that ``cdp.events`` holds every request, console message and exception.
    """
    env = {**os.environ, "PYTHONPATH": f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    server = subprocess.Popen(
        interruptible([sys.executable, "-m", "pose_uncertainty.cli", "explore"]),
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env,
    )  # fmt: skip
    if server_cpu is not None:
        os.sched_setaffinity(server.pid, {server_cpu})
    try:
        line = server.stdout.readline() if server.stdout else ""
        m = re.search(r"(http://127\.0\.0\.1:\d+/)", line)
        assert m, line
        url = m.group(1)
        with open_chromium(browser, tmp_path, timeout=120) as cdp:
            for domain in ("Page", "Network", "Runtime", "Log"):
                cdp.call(f"{domain}.enable")
            cdp.call("Page.navigate", url=url)
            cdp.wait_event("Page.loadEventFired", timeout=60)
            yield cdp, url
    finally:
        interrupt(server)


def _evaluate(cdp: CDP, expression: str) -> Any:
    """The value of a JavaScript expression in the page."""
    out = cdp.call("Runtime.evaluate", expression=expression, returnByValue=True)
    assert "exceptionDetails" not in out, out
    return out["result"].get("value")


#: JavaScript: click the page's "Save as run config" button (found through the shadow roots).
CLICK_SAVE = (
    "(() => { const all = []; const walk = (root) => { for (const el of root.querySelectorAll('*')) {"
    " if (el.tagName === 'BUTTON' && el.textContent.trim() === 'Save as run config') all.push(el);"
    " if (el.shadowRoot) walk(el.shadowRoot); } }; walk(document); all.forEach(b => b.click());"
    " return all.length; })()"
)


def set_field(cdp: CDP, name: str, value: str | float, prop: str = "value") -> None:
    """Set a control's value in the page (the widget's model, as a user's edit does)."""
    cdp.call("Runtime.evaluate",
             expression=f"Bokeh.documents[0].get_model_by_name({json.dumps(name)}).{prop} = {json.dumps(value)}")  # fmt: skip


def release_slider(cdp: CDP, name: str, value: float) -> None:
    """Move a slider and let go: its value, then its ``value_throttled`` (what the release sets)."""
    set_field(cdp, name, value)
    set_field(cdp, name, value, "value_throttled")


#: JavaScript: set field-k_r to a value and resolve with the milliseconds until the status line
#: names that value (the same server message updates the sources, the tables and the status).
REDRAW_MS = (
    "(async (value) => { const t0 = performance.now();"
    " Bokeh.documents[0].get_model_by_name('field-k_r').value = value;"
    " const doc = Bokeh.documents[0]; const st = doc.get_model_by_name('status');"
    " while (performance.now() - t0 < 120000) {"
    "   await new Promise(r => setTimeout(r, 1));"
    "   if (st.text.includes('k_r ' + value + ',') && !st.text.includes('computing')) {"
    "     await new Promise(r => requestAnimationFrame(() => r()));"
    "     return performance.now() - t0; } }"
    " return -1; })"
)


def redraw_ms(cdp: CDP, value: str) -> float:
    """Milliseconds from setting k_r in the page to the redrawn views (:data:`REDRAW_MS`)."""
    out = cdp.call("Runtime.evaluate", expression=f"{REDRAW_MS}({json.dumps(value)})", awaitPromise=True,
                   returnByValue=True)  # fmt: skip
    if "exceptionDetails" in out or not isinstance(out["result"].get("value"), int | float):
        raise AssertionError(f"the in-page timer failed: {out}")
    return float(out["result"]["value"])


def _wait_status(cdp: CDP, *words: str, timeout: float = 120) -> str:
    """The status line once it holds every word (the page has drawn that setting)."""
    deadline = time.monotonic() + timeout
    text = ""
    while time.monotonic() < deadline:
        out = cdp.call("Runtime.evaluate", returnByValue=True,
                       expression="Bokeh.documents[0].get_model_by_name('status').text")  # fmt: skip
        text = str(out["result"].get("value"))
        if all(w in text for w in words) and "computing" not in text:
            return text
        time.sleep(0.25)
    raise TimeoutError(f"the status line did not show {words} within {timeout} s: {text!r}")


def _console_errors(events: list[dict[str, Any]]) -> list[dict[str, Any]]:
    errors = [e for e in events if e["method"] == "Runtime.exceptionThrown"]
    errors += [e for e in events
               if e["method"] == "Runtime.consoleAPICalled" and e["params"]["type"] == "error"]  # fmt: skip
    errors += [e for e in events if e["method"] == "Log.entryAdded" and e["params"]["entry"]["level"] == "error"]
    return errors


@pytest.mark.slow
def test_explorer_in_chromium(chromium: str, tmp_path: Path) -> None:
    with explorer_page(chromium, tmp_path) as (cdp, url):
        first = _wait_text(cdp, "coverage-a", None, timeout=120)
        want = explore.compute(explore.run_config(explore.DEFAULTS))
        assert first == _shown(want, "a")
        assert _text(cdp, "coverage-c") == _shown(want, "c")
        assert _text(cdp, "coverage-e") == _shown(want, "e")
        # move k_r in the page (the widget's model, as the slider's edit would)
        set_field(cdp, "field-k_r", "3e-3")
        second = _wait_text(cdp, "coverage-a", first, timeout=120)
        moved = explore.compute(explore.run_config({**explore.DEFAULTS, "k_r": "3e-3"}))
        assert second == _shown(moved, "a")
        assert _text(cdp, "coverage-c") == _shown(moved, "c")
        # the drawn ellipse is the library's for the new setting
        xs = _evaluate(cdp, "Array.from(Bokeh.documents[0].get_model_by_name('source-a').data.xs[0])")
        np.testing.assert_allclose(xs, moved.regions["a"][0][:, 0], rtol=1e-12, atol=1e-15)
        # the slider (log10 k_r) writes the field, and the page redraws
        release_slider(cdp, "slider-k_r", -2.5)
        _wait_status(cdp, "k_r 0.00316,")
        slid = explore.compute(explore.run_config({**explore.DEFAULTS, "k_r": "0.00316"}))
        assert _text(cdp, "coverage-a") == _shown(slid, "a")
        # a bad value: its one-line error in the page, the last good picture kept
        set_field(cdp, "field-k_l", "-1")
        deadline = time.monotonic() + 120
        while "k_l" not in str(_evaluate(cdp, "Bokeh.documents[0].get_model_by_name('error').text")):
            assert time.monotonic() < deadline, "no error shown for k_l = -1"
            time.sleep(0.25)
        shown_error = str(_evaluate(cdp, "Bokeh.documents[0].get_model_by_name('error').text"))
        assert "-1" in shown_error
        assert "\n" not in shown_error
        assert _text(cdp, "coverage-a") == _shown(slid, "a")
        set_field(cdp, "field-k_l", explore.DEFAULTS["k_l"])
        _wait_text(cdp, "coverage-a", None, timeout=120)
        # "Save as run config" from the page: the run of that file logs the numbers the page shows
        saved = tmp_path / "explored.yaml"
        set_field(cdp, "save-path", str(saved))
        assert _evaluate(cdp, CLICK_SAVE) == 1
        _wait_status(cdp, "wrote")
        assert main(["run", str(saved), "-o", str(tmp_path / "explored.mcap")]) == 0
        logged = open_run(tmp_path / "explored.mcap").metrics
        for key, name in (("a", "cartesian"), ("c", "unscented"), ("e", "expcoords")):
            assert _text(cdp, f"coverage-{key}") == f"{100 * logged[f'accuracy_{name}_coverage_xy_98_89']:.2f}"
        shot = cdp.call("Page.captureScreenshot", format="png")
        cdp.call("Runtime.evaluate", expression="1")  # drain
    assert shot["data"]
    assert _console_errors(cdp.events) == []
    requests = [
        e["params"]["request"]["url"] for e in cdp.events if e["method"] == "Network.requestWillBeSent"
    ]
    assert requests
    local = (url, url.replace("http", "ws"), "data:", "blob:")
    assert [u for u in requests if not u.startswith(local)] == []


#: A setting whose velocity-model map takes seconds (100 steps on 2 cm cells) and whose moves are quick.
MAP_SETTING = {"path": "straight", "size": "1.0", "dt": "0.02", "n_particles": "1000",
               "map": "velocity", "map_resolution": "0.02"}  # fmt: skip


@pytest.mark.slow
def test_map_is_computed_in_the_background_while_the_controls_stay_live(
    chromium: str, tmp_path: Path
) -> None:
    with explorer_page(chromium, tmp_path) as (cdp, _url):
        _wait_text(cdp, "coverage-a", None, timeout=120)
        for k in ("path", "size", "dt", "n_particles", "map_resolution"):
            set_field(cdp, f"field-{k}", MAP_SETTING[k])
        _wait_status(cdp, "100 steps", "1000 particles")
        start = _text(cdp, "coverage-a")
        set_field(cdp, "field-map", "velocity")
        progress = _wait_text(cdp, "map-progress", None, timeout=60)
        assert progress.startswith("map:")
        # while the map computes, a move of k_r is redrawn: the map is not in the way
        ms = redraw_ms(cdp, "2e-3")
        assert ms > 0
        assert _text(cdp, "map-done") is None, "the map finished before the move: make it slower"
        assert _text(cdp, "coverage-a") != start
        # the map arrives, its region drawn in the overlay, its coverage the library's
        _wait_text(cdp, "map-done", None, timeout=300)
        n_lines = cdp.call("Runtime.evaluate", returnByValue=True,
                           expression="Bokeh.documents[0].get_model_by_name('source-map').data.xs.length")  # fmt: skip
        assert n_lines["result"]["value"] >= 1
        view = explore.compute(explore.run_config({**explore.DEFAULTS, **MAP_SETTING, "k_r": "0.002"}))
        assert _text(cdp, "coverage-map") == _shown(view, "map")
    assert _console_errors(cdp.events) == []


#: A quick setting for the new controls' browser test (100 steps, 1000 particles).
QUICK = {"size": "1.0", "dt": "0.02", "n_particles": "1000"}


@pytest.mark.slow
def test_segments_profile_and_error_sources_in_chromium(chromium: str, tmp_path: Path) -> None:
    """The path as a list of segments, the speed profile and the wheel-noise model's error sources,
    typed into the page: the page's numbers are the library's; a bad segment list shows its one-line
    error and keeps the last good picture; the saved config runs unchanged and logs the same numbers."""
    with explorer_page(chromium, tmp_path) as (cdp, _url):
        _wait_text(cdp, "coverage-a", None, timeout=120)
        for k, v in QUICK.items():
            set_field(cdp, f"field-{k}", v)
        _wait_status(cdp, "100 steps", "1000 particles")
        segments = "[[line, 0.5], [turn, 1.5708], [arc, 0.4, 1.0]]"
        set_field(cdp, "field-segments", segments)
        set_field(cdp, "field-profile", "ramp")
        before = _text(cdp, "coverage-a")
        set_field(cdp, "field-path", "tour")
        tour = {**explore.DEFAULTS, **QUICK, "path": "tour", "segments": segments, "profile": "ramp"}
        want = explore.compute(explore.run_config(tour))
        _wait_status(cdp, f"{want.result.n_steps} steps")
        for key in ("a", "c", "e"):
            assert _text(cdp, f"coverage-{key}") == _shown(want, key), key
        assert _text(cdp, "coverage-a") != before
        xs = _evaluate(cdp, "Array.from(Bokeh.documents[0].get_model_by_name('source-a').data.xs[0])")
        np.testing.assert_allclose(xs, want.regions["a"][0][:, 0], rtol=1e-12, atol=1e-15)
        # a bad segment list: its one-line error, the last good picture kept
        set_field(cdp, "field-segments", "[[line, 0.5], [jump, 1.0]]")
        deadline = time.monotonic() + 120
        while "segments[1]" not in str(_evaluate(cdp, "Bokeh.documents[0].get_model_by_name('error').text")):
            assert time.monotonic() < deadline, "no error shown for a bad segment"
            time.sleep(0.25)
        assert "\n" not in str(_evaluate(cdp, "Bokeh.documents[0].get_model_by_name('error').text"))
        assert _text(cdp, "coverage-a") == _shown(want, "a")
        xs_kept = _evaluate(cdp, "Array.from(Bokeh.documents[0].get_model_by_name('source-a').data.xs[0])")
        assert xs_kept == xs
        set_field(cdp, "field-segments", segments)
        _wait_status(cdp, f"{want.result.n_steps} steps")
        # the wheel-noise model's error sources in place of k_r, k_l
        sources = "pulses_per_rev: 100, surface_rel_std: 0.03"
        set_field(cdp, "field-error_sources", sources)
        moved = explore.compute(explore.run_config({**tour, "error_sources": sources}))
        _wait_text(cdp, "coverage-a", _shown(want, "a"), timeout=120)
        assert _text(cdp, "coverage-a") == _shown(moved, "a")
        assert _text(cdp, "coverage-e") == _shown(moved, "e")
        # saved and run unchanged: the log holds the numbers the page shows
        saved = tmp_path / "explored.yaml"
        set_field(cdp, "save-path", str(saved))
        assert _evaluate(cdp, CLICK_SAVE) == 1
        _wait_status(cdp, "wrote")
        assert main(["run", str(saved), "-o", str(tmp_path / "explored.mcap")]) == 0
        log = open_run(tmp_path / "explored.mcap")
        assert log.config.trajectory["segments"] == [["line", 0.5], ["turn", 1.5708], ["arc", 0.4, 1.0]]
        assert log.config.trajectory["profile"] == "ramp"
        assert log.config.drive is not None
        assert log.config.drive.errors.encoder["pulses_per_rev"] == 100
        for key, name in (("a", "cartesian"), ("e", "expcoords")):
            assert _text(cdp, f"coverage-{key}") == f"{100 * log.metrics[f'accuracy_{name}_coverage_xy_98_89']:.2f}"
    assert _console_errors(cdp.events) == []
