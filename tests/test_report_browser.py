"""The comparison report in headless Chromium: renders, no console error, no external request.

Chromium (Debian's ``chromium`` package, ``/usr/bin/chromium``) is driven over the
DevTools protocol with a small WebSocket client written on the standard library
(``tests/browser.py``): the test enables the Network, Runtime and Log domains, opens
``reports/comparison.html`` of the quick pipeline run from ``file://``, records
every request, console message, log entry and uncaught exception, and captures
a full-page screenshot (kept under the pytest tmp dir and copied to
``reports/screenshot.png`` of the repository).

Chromium missing is a FAILURE with instructions, not a skip: the report is a
deliverable and this is its only rendering check.
"""

from __future__ import annotations

import base64
import json
import shutil
from pathlib import Path

import pytest
from browser import open_chromium
from test_pipeline import REPO, quick_pipeline

#: Element ids of the studies sections that the quick report must contain.
STUDY_SECTION_IDS: list[str] = [
    "studies", "accuracy", "accuracy-distance", "expcoords", "fig-studies-expcoords", "growth-laws",
    "regimes", "polar-cartesian", "calibration",
]


@pytest.mark.slow
def test_report_renders_offline_without_console_errors(
    chromium: str, tmp_path: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    work = quick_pipeline(tmp_path_factory.getbasetemp())
    report = work / "reports/comparison.html"
    assert report.is_file()
    with open_chromium(chromium, tmp_path) as cdp:
        for domain in ("Page", "Network", "Runtime", "Log"):
            cdp.call(f"{domain}.enable")
        url = report.resolve().as_uri()
        cdp.call("Page.navigate", url=url)
        cdp.wait_event("Page.loadEventFired", timeout=60)
        # lazy images: scroll through the page so every image is decoded, then settle
        height = cdp.call("Runtime.evaluate", expression="document.body.scrollHeight", returnByValue=True)
        total = int(height["result"]["value"])
        for y in range(0, total, 2000):
            cdp.call("Runtime.evaluate", expression=f"window.scrollTo(0, {y})")
        cdp.call("Runtime.evaluate", expression="window.scrollTo(0, 0)")
        done = cdp.call(
            "Runtime.evaluate",
            expression=(
                # lazy images load when near the viewport: the instant scroll above does not wait for them
                "Promise.all([...document.images].map(i => (i.loading = 'eager', i))"
                ".map(i => i.decode().then(() => [i.alt, i.naturalWidth],"
                " () => [i.alt, -1])))"
            ),
            awaitPromise=True,
            returnByValue=True,
        )
        images = done["result"]["value"]
        metrics = cdp.call("Page.getLayoutMetrics")
        size = metrics.get("cssContentSize") or metrics["contentSize"]
        shot = cdp.call(
            "Page.captureScreenshot",
            format="png",
            captureBeyondViewport=True,
            clip={"x": 0, "y": 0, "width": size["width"], "height": min(size["height"], 12000), "scale": 1},
        )
        title = cdp.call("Runtime.evaluate", expression="document.title", returnByValue=True)["result"]["value"]
        n_claims = cdp.call(
            "Runtime.evaluate", expression="document.querySelectorAll('tr[id^=claim-]').length", returnByValue=True
        )["result"]["value"]
        study_ids = cdp.call(
            "Runtime.evaluate",
            expression="JSON.stringify(" + json.dumps(STUDY_SECTION_IDS) + ".filter(i => document.getElementById(i)))",
            returnByValue=True,
        )["result"]["value"]
        # drain what is left
        cdp.call("Runtime.evaluate", expression="1")

    png = base64.b64decode(shot["data"])
    out = tmp_path / "screenshot.png"
    out.write_bytes(png)
    assert png.startswith(b"\x89PNG\r\n\x1a\n")
    assert len(png) > 10_000
    (REPO / "reports").mkdir(exist_ok=True)
    shutil.copy2(out, REPO / "reports/screenshot.png")

    events = cdp.events
    requests = [e["params"]["request"]["url"] for e in events if e["method"] == "Network.requestWillBeSent"]
    external = [u for u in requests if not u.startswith(("file:", "data:", "about:"))]
    assert external == [], f"the report made network requests: {external}"
    assert url in requests  # the recorder saw the page itself
    console_errors = [
        e["params"] for e in events
        if (e["method"] == "Runtime.consoleAPICalled" and e["params"]["type"] in ("error", "assert", "warning"))
        or (e["method"] == "Log.entryAdded" and e["params"]["entry"]["level"] in ("error", "warning"))
        or e["method"] == "Runtime.exceptionThrown"
    ]
    assert console_errors == [], f"console errors: {console_errors}"
    failed = [e["params"] for e in events if e["method"] == "Network.loadingFailed"]
    assert failed == [], f"failed loads: {failed}"
    assert images
    assert all(w > 0 for _, w in images), f"images that did not decode: {[a for a, w in images if w <= 0]}"
    assert title.startswith("Pose uncertainty")
    assert n_claims == 12
    assert json.loads(study_ids) == STUDY_SECTION_IDS  # the studies sections are in the quick report


# --- the report as a reader sees it: first screen, no sideways scroll, runs open on demand ----------

#: Evaluated in the page: what a reader sees and can follow. Internal links resolve to an element, or to
#: one inside a run's <template> (the page's script opens that run when the link is followed).
_READ_JS = """(() => {
  const bottom = sel => { const e = document.querySelector(sel); return e ? e.getBoundingClientRect().bottom : 1e9; };
  const inTemplates = id => [...document.querySelectorAll('template')].some(t => t.content.getElementById(id));
  const links = [...document.querySelectorAll('a[href^="#"]')].map(a => decodeURIComponent(a.getAttribute('href').slice(1)));
  return {
    abstract: bottom('.abstract ol'), headline: bottom('#fig-studies-expcoords img'),
    body_scroll: document.documentElement.scrollWidth - document.documentElement.clientWidth,
    unresolved: [...new Set(links.filter(id => !document.getElementById(id) && !inTemplates(id)))],
    no_alt: [...document.images].filter(i => !i.alt).length,
    closed_runs: document.querySelectorAll('details.run').length,
    images_before: document.images.length,
  };
})()"""

#: Opens every run (as a reader's click does: the toggle event) and decodes every image then present.
_OPEN_RUNS_JS = """(async () => {
  document.querySelectorAll('details.run').forEach(d => { d.open = true; });
  await new Promise(r => setTimeout(r, 200));
  const imgs = [...document.images];
  imgs.forEach(i => { i.loading = 'eager'; });  // as if the reader scrolled to each one
  const res = await Promise.all(imgs.map(i => i.decode().then(() => i.naturalWidth, () => -1)));
  return { n: imgs.length, failed: imgs.filter((_, k) => res[k] <= 0).map(i => i.alt),
           templates_left: document.querySelectorAll('details.run > template').length };
})()"""


@pytest.mark.slow
def test_report_reads_first_screen_and_opens_runs(chromium: str, tmp_path: Path,
                                                   tmp_path_factory: pytest.TempPathFactory) -> None:
    work = quick_pipeline(tmp_path_factory.getbasetemp())
    url = (work / "reports/comparison.html").resolve().as_uri()
    with open_chromium(chromium, tmp_path, window="1400,900", timeout=120) as cdp:
        for domain in ("Page", "Runtime", "Log"):
            cdp.call(f"{domain}.enable")
        cdp.call("Page.navigate", url=url)
        cdp.wait_event("Page.loadEventFired", timeout=120)
        seen = cdp.call("Runtime.evaluate", expression=_READ_JS, returnByValue=True)["result"]["value"]
        first = cdp.call("Page.captureScreenshot", format="png", captureBeyondViewport=True,
                         clip={"x": 0, "y": 0, "width": 1400, "height": 900, "scale": 1})
        opened = cdp.call("Runtime.evaluate", expression=_OPEN_RUNS_JS, awaitPromise=True,
                          returnByValue=True)["result"]["value"]  # fmt: skip
        after = cdp.call("Runtime.evaluate", expression=_READ_JS, returnByValue=True)["result"]["value"]
        cdp.call("Runtime.evaluate", expression="1")
    (REPO / "reports").mkdir(exist_ok=True)
    (REPO / "reports/first-screen.png").write_bytes(base64.b64decode(first["data"]))
    assert seen["abstract"] <= 900, f"the findings end at {seen['abstract']} px, below the first screen"
    assert seen["headline"] <= 900, f"the headline figure ends at {seen['headline']} px, below the first screen"
    assert seen["body_scroll"] <= 0, f"the page scrolls sideways by {seen['body_scroll']} px"
    assert seen["unresolved"] == [], seen["unresolved"]
    assert seen["no_alt"] == 0
    assert seen["closed_runs"] > 0
    assert opened["templates_left"] == 0
    assert opened["n"] > seen["images_before"]  # the runs' figures came in when opened
    assert opened["failed"] == [], f"images that did not decode: {opened['failed']}"
    assert after["body_scroll"] <= 0, f"with the runs open the page scrolls sideways by {after['body_scroll']} px"
    errors = [e["params"] for e in cdp.events
              if (e["method"] == "Runtime.consoleAPICalled" and e["params"]["type"] in ("error", "assert", "warning"))
              or (e["method"] == "Log.entryAdded" and e["params"]["entry"]["level"] in ("error", "warning"))
              or e["method"] == "Runtime.exceptionThrown"]  # fmt: skip
    assert errors == [], f"console errors: {errors}"
