"""The explorer in headless Chromium: it loads with no console error and a k_r change redraws.

The server is started as the command (``pose-uncertainty explore``, loopback, a free port);
Chromium is driven over the DevTools protocol (``tests/browser.py``).
Every request the page makes must go to 127.0.0.1. The numbers read from the page's DOM (inside
Bokeh's shadow roots) must equal :func:`pose_uncertainty.present.explore.compute` of the same
settings, before and after k_r is changed in the page.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from browser import CDP, open_chromium

from pose_uncertainty.present import explore

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


@pytest.mark.slow
def test_explorer_in_chromium(chromium: str, tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    server = subprocess.Popen(
        [sys.executable, "-m", "pose_uncertainty.cli", "explore"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env,
    )  # fmt: skip
    try:
        line = server.stdout.readline() if server.stdout else ""
        m = re.search(r"(http://127\.0\.0\.1:\d+/)", line)
        assert m, line
        url = m.group(1)
        with open_chromium(chromium, tmp_path, timeout=120) as cdp:
            for domain in ("Page", "Network", "Runtime", "Log"):
                cdp.call(f"{domain}.enable")
            cdp.call("Page.navigate", url=url)
            cdp.wait_event("Page.loadEventFired", timeout=60)
            first = _wait_text(cdp, "coverage-a", None, timeout=120)
            want = explore.compute(explore.run_config(explore.DEFAULTS))
            assert first == _shown(want, "a")
            assert _text(cdp, "coverage-c") == _shown(want, "c")
            assert _text(cdp, "coverage-e") == _shown(want, "e")
            # move k_r in the page (the widget's model, as the slider's edit would)
            cdp.call(
                "Runtime.evaluate",
                expression="Bokeh.documents[0].get_model_by_name('field-k_r').value = '3e-3'",
            )
            second = _wait_text(cdp, "coverage-a", first, timeout=120)
            moved = explore.compute(explore.run_config({**explore.DEFAULTS, "k_r": "3e-3"}))
            assert second == _shown(moved, "a")
            assert _text(cdp, "coverage-c") == _shown(moved, "c")
            shot = cdp.call("Page.captureScreenshot", format="png")
            cdp.call("Runtime.evaluate", expression="1")  # drain
    finally:
        server.send_signal(signal.SIGINT)
        try:
            server.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.communicate()
    assert shot["data"]
    events = cdp.events
    errors = [e for e in events if e["method"] == "Runtime.exceptionThrown"]
    errors += [
        e
        for e in events
        if e["method"] == "Runtime.consoleAPICalled" and e["params"]["type"] == "error"
    ]
    errors += [
        e
        for e in events
        if e["method"] == "Log.entryAdded" and e["params"]["entry"]["level"] == "error"
    ]
    assert errors == []
    requests = [
        e["params"]["request"]["url"] for e in events if e["method"] == "Network.requestWillBeSent"
    ]
    assert requests
    local = (url, url.replace("http", "ws"), "data:", "blob:")
    assert [u for u in requests if not u.startswith(local)] == []
