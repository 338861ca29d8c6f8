"""The comparison report in headless Chromium: renders, no console error, no external request.

Chromium (Debian's ``chromium`` package, ``/usr/bin/chromium``) is driven over the
DevTools protocol with a small WebSocket client written on the standard library
(``tests/browser.py``): the test enables the Network, Runtime and Log domains, opens
``reports/comparison.html`` of the quick pipeline run from ``file://``, then each of its
companion pages (``reports/runs/<set>.html``: a set's run figures), records every request,
console message, log entry and uncaught exception, and captures a full-page screenshot of
the report (kept under the pytest tmp dir and copied to ``reports/screenshot.png`` of the
repository).

Chromium missing is a FAILURE with instructions, not a skip: the report is a
deliverable and this is its only rendering check.
"""

from __future__ import annotations

import base64
import contextlib
import json
import math
import re
import shutil
import urllib.parse
from collections.abc import Iterator
from pathlib import Path

import pytest
from browser import CDP, open_chromium
from test_pipeline import REPO, quick_pipeline

#: Element ids of the studies sections that the quick report must contain.
STUDY_SECTION_IDS: list[str] = [
    "studies", "accuracy", "accuracy-distance", "expcoords", "fig-studies-expcoords", "growth-laws",
    "regimes", "polar-cartesian", "calibration",
]


#: Every image of the page decoded: ``[[alt, natural width (-1: it did not decode)], ...]``. Lazy images load
#: when near the viewport (an instant scroll does not wait for them): they are made eager first.
_DECODE_ALL_JS = """Promise.all([...document.images].map(i => (i.loading = 'eager', i))
  .map(i => i.decode().then(() => [i.alt, i.naturalWidth], () => [i.alt, -1])))"""


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
        done = cdp.call("Runtime.evaluate", expression=_DECODE_ALL_JS, awaitPromise=True, returnByValue=True)
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
        # the companion pages: every figure of every run decodes there
        companions = sorted((work / "reports/runs").glob("*.html"))
        for page in companions:
            cdp.navigate(page.resolve().as_uri(), timeout=60)
            images += cdp.call("Runtime.evaluate", expression=_DECODE_ALL_JS, awaitPromise=True,
                               returnByValue=True)["result"]["value"]  # fmt: skip
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
    assert companions, "no companion page of the runs' figures"
    for page in companions:
        assert page.resolve().as_uri() in requests, page
    assert title.startswith("Pose uncertainty")
    assert n_claims == len(json.loads((work / "reports/claims.json").read_text(encoding="utf-8"))["claims"])  # a row per claim
    assert json.loads(study_ids) == STUDY_SECTION_IDS  # the studies sections are in the quick report


# --- the report as a reader sees it: first screen, no sideways scroll, runs open on demand ----------

#: Evaluated in the page: what a reader sees and can follow. Internal links resolve to an element, or to
#: one inside a <template> (the page's script opens its details when the link is followed); the links to
#: other pages (a run's figures on its set's companion page, the report from there) are listed.
_READ_JS = """(() => {
  const bottom = sel => { const e = document.querySelector(sel); return e ? e.getBoundingClientRect().bottom : 1e9; };
  const inTemplates = id => [...document.querySelectorAll('template')].some(t => t.content.getElementById(id));
  const links = [...document.querySelectorAll('a[href^="#"]')].map(a => decodeURIComponent(a.getAttribute('href').slice(1)));
  return {
    abstract: bottom('.abstract ol'), headline: bottom('#fig-studies-expcoords img'),
    body_scroll: document.documentElement.scrollWidth - document.documentElement.clientWidth,
    unresolved: [...new Set(links.filter(id => !document.getElementById(id) && !inTemplates(id)))],
    other_pages: [...new Set([...document.querySelectorAll('a[href]')].map(a => a.href)
                              .filter(h => !h.startsWith(location.href.split('#')[0] + '#') && !h.startsWith('data:')))],
    no_alt: [...document.images].filter(i => !i.alt).length,
    closed_runs: document.querySelectorAll('details.run').length,
    ids: [...document.querySelectorAll('[id]')].map(e => e.id),
  };
})()"""

#: Opens every run's parameters (as a reader's click does: the toggle event).
_OPEN_RUNS_JS = """(async () => {
  document.querySelectorAll('details.run').forEach(d => { d.open = true; });
  await new Promise(r => setTimeout(r, 200));
  return { templates_left: document.querySelectorAll('details.run > template').length,
           tables: document.querySelectorAll('details.run > table.kv').length };
})()"""

#: On a companion page opened at a run's anchor: where that run's section is, and every image decoded.
_LANDED_JS = """(async () => {
  const target = document.getElementById(decodeURIComponent(location.hash.slice(1)));
  const top = target ? target.getBoundingClientRect().top : null;
  const imgs = [...document.images];
  imgs.forEach(i => { i.loading = 'eager'; });  // as if the reader scrolled to each one
  const res = await Promise.all(imgs.map(i => i.decode().then(() => i.naturalWidth, () => -1)));
  return { top: top, n: imgs.length, failed: imgs.filter((_, k) => res[k] <= 0).map(i => i.alt),
           in_run: target ? target.querySelectorAll('img').length : 0,
           // the runs' parameters: the set's shared ones, each run's own (a set of one run has only the former)
           params: document.querySelectorAll('table.kv').length };
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
        # follow the links into the companion pages: each opens at its run, whose figures decode there
        report_ids = set(seen["ids"])
        runs = [h for h in seen["other_pages"] if "/reports/runs/" in h and "#" in h]
        landed, pages = [], {}
        for page in sorted({h.split("#")[0] for h in runs}):
            # the page's first run (or figure), as a reader follows it; not the set's full table or parameters
            link = next(h for h in runs if h.startswith(page + "#") and not re.search(r"#(table|params)-", h))
            cdp.navigate(link, timeout=120)
            landed.append((link, cdp.call("Runtime.evaluate", expression=_LANDED_JS, awaitPromise=True,
                                          returnByValue=True)["result"]["value"]))  # fmt: skip
            pages[page] = cdp.call("Runtime.evaluate", expression=_READ_JS, returnByValue=True)["result"]["value"]
        cdp.call("Runtime.evaluate", expression="1")
    (REPO / "reports").mkdir(exist_ok=True)
    (REPO / "reports/first-screen.png").write_bytes(base64.b64decode(first["data"]))
    assert seen["abstract"] <= 900, f"the findings end at {seen['abstract']} px, below the first screen"
    assert seen["headline"] <= 900, f"the headline figure ends at {seen['headline']} px, below the first screen"
    assert seen["body_scroll"] <= 0, f"the page scrolls sideways by {seen['body_scroll']} px"
    assert seen["unresolved"] == [], seen["unresolved"]
    assert seen["no_alt"] == 0
    # a run without figures keeps its parameters in the report, in a <details> filled when opened; the others
    # are on their set's page (below)
    assert opened["templates_left"] == 0
    assert opened["tables"] == seen["closed_runs"]  # each run's parameters came in when opened
    assert after["body_scroll"] <= 0, f"with the runs open the page scrolls sideways by {after['body_scroll']} px"
    # every link to another file (a companion page, the studies' results beside the report) leads to a file
    files = {h.split("#")[0] for h in seen["other_pages"] if h.startswith("file:")}
    assert any(f.endswith("/studies.json") for f in files), "the report does not link the studies' results"
    assert [f for f in files if not Path(urllib.parse.unquote(urllib.parse.urlparse(f).path)).is_file()] == []
    # every run's figures are linked, every link leads to a page and an anchor that are there
    assert runs, "no run links to its figures"
    assert {p.resolve().as_uri() for p in (work / "reports/runs").glob("*.html")} == set(pages)
    for page, read in pages.items():
        ids = set(read["ids"])
        missing = [h for h in runs if h.startswith(page + "#") and h.split("#", 1)[1] not in ids]
        assert missing == [], missing
        assert read["unresolved"] == [], (page, read["unresolved"])
        assert read["no_alt"] == 0, page
        assert read["body_scroll"] <= 0, f"{page} scrolls sideways by {read['body_scroll']} px"
        back = [h for h in read["other_pages"] if h.split("#")[0] == url]
        assert back, f"{page} does not link back to the report"
        assert all(h.split("#", 1)[1] in report_ids for h in back if "#" in h), (page, back)
    for link, at in landed:
        assert at["top"] is not None, f"{link}: no such anchor"
        # the run (or the figure a claim links to) at the top of the window: its top within a pixel of it
        assert -1 <= at["top"] < 900, f"{link}: its target starts at {at['top']} px, not at the top of the window"
        assert at["in_run"] > 0, f"{link}: no figure at the run or figure followed"
        assert at["failed"] == [], f"{link}: images that did not decode: {at['failed']}"
        if "#run-" in link:  # an experiment set's page (a localization set's runs log no parameter table)
            assert at["params"] > 0, f"{link}: no table of the runs' parameters on the page"
    errors = [e["params"] for e in cdp.events
              if (e["method"] == "Runtime.consoleAPICalled" and e["params"]["type"] in ("error", "assert", "warning"))
              or (e["method"] == "Log.entryAdded" and e["params"]["entry"]["level"] in ("error", "warning"))
              or e["method"] == "Runtime.exceptionThrown"]  # fmt: skip
    assert errors == [], f"console errors: {errors}"


# --- print to PDF: the page count a bound predicts, no figure split across pages -------------------

#: A4 with Chromium's default margins (0.4 in): the printable box in CSS px (96 per inch).
PAPER_IN, MARGIN_IN = (8.27, 11.69), 0.4
PRINT_W, PRINT_H = round((PAPER_IN[0] - 2 * MARGIN_IN) * 96), round((PAPER_IN[1] - 2 * MARGIN_IN) * 96)

#: Evaluated in the page laid out for print (print media, the printable width): the content's height,
#: the blocks that must not be split (``break-inside: avoid``) and what print shows of the details.
_PRINT_LAYOUT_JS = """(() => {
  const shown = e => e.getClientRects().length > 0;
  const figs = [...document.querySelectorAll('figure')].filter(shown);
  const atoms = [...document.querySelectorAll('figure, tr, .abstract li')].filter(shown);
  const heads = [...document.querySelectorAll('h2, h3')].filter(shown);
  return {
    height: document.documentElement.scrollHeight,
    body_scroll: document.documentElement.scrollWidth - document.documentElement.clientWidth,
    figures: figs.map(f => ({id: f.id, h: f.getBoundingClientRect().height,
                             avoid: getComputedStyle(f).breakInside, imgs: f.querySelectorAll('img').length})),
    atoms_h: atoms.reduce((s, e) => s + e.getBoundingClientRect().height, 0),
    heads_h: heads.reduce((s, e) => s + e.getBoundingClientRect().height, 0),
    max_atom: Math.max(0, ...atoms.map(e => e.getBoundingClientRect().height)),
    images: [...document.images].filter(shown).length,
    // how many shown images carry each picture (a figure may be shown twice: the PDF keeps one image of it)
    pictures: Object.values([...document.images].filter(shown).reduce((n, i) => (n[i.src] = (n[i.src] || 0) + 1, n), {})),
    run_details_shown: [...document.querySelectorAll('details.run, details.full, p.full, details.shared, p.shared, ul.runs')].filter(shown).length,
    open_details: [...document.querySelectorAll('details[open]')].filter(shown).length,
  };
})()"""


def pdf_pages(pdf: bytes) -> list[set[int]]:
    """The pages of a PDF written by Chromium (Skia: plain objects, no object streams), in no particular
    order, each as the set of image objects its resources name (a figure split over two pages draws its
    image on both: the same object from two pages)."""

    objs = {int(n): body for n, body in re.findall(rb"(\d+) 0 obj\s*(.*?)\s*endobj", pdf, re.DOTALL)}
    assert not any(b"/Type /ObjStm" in b for b in objs.values()), "object streams: this reader cannot follow them"

    def deref(body: bytes, key: bytes) -> bytes:
        m = re.search(key + rb"\s*(\d+) 0 R", body)
        if m:
            return objs[int(m.group(1))]
        m = re.search(key + rb"\s*<<", body)
        if not m:
            return b""
        depth, i = 1, m.end()
        while depth:  # the inline dictionary up to its matching >>
            if body.startswith(b"<<", i):
                depth, i = depth + 1, i + 2
            elif body.startswith(b">>", i):
                depth, i = depth - 1, i + 2
            else:
                i += 1
        return body[m.end():i - 2]

    pages = []
    for body in objs.values():
        if re.match(rb"<<\s*/Type /Page\b(?!s)", body) or re.search(rb"/Type /Page\b(?!s)", body.split(b"stream")[0]):
            xobjects = deref(deref(body, rb"/Resources"), rb"/XObject")
            refs = {int(n) for n in re.findall(rb"(\d+) 0 R", xobjects)}
            pages.append({r for r in refs if b"/Subtype /Image" in objs.get(r, b"").split(b"stream")[0]})
    return pages


@contextlib.contextmanager
def _page(chromium: str, tmp_path: Path, width: int, height: int) -> Iterator[CDP]:
    """A headless Chromium of that window size, its first page over the DevTools protocol (Page, Runtime
    and Log enabled); closed and the browser ended on exit."""
    with open_chromium(chromium, tmp_path, window=f"{width},{height}", timeout=120) as cdp:
        for domain in ("Page", "Runtime", "Log"):
            cdp.call(f"{domain}.enable")
        yield cdp


@pytest.mark.slow
def test_report_prints_to_pdf_with_the_pages_a_bound_predicts(chromium: str, tmp_path: Path,
                                                               tmp_path_factory: pytest.TempPathFactory) -> None:
    """``Page.printToPDF`` (A4, default margins): the page count lies between two bounds measured on the
    print layout, every figure fits on a page and asks not to be split, and no image is drawn on two pages.

    The bounds, with ``H`` the content's height laid out for print at the printable width and ``P`` the
    printable height: a page holds at most ``P`` of content, so ``pages ≥ ⌈H/P⌉``; a page ends early only
    to keep an unsplittable block (a figure, a table row, a finding, or a heading kept with what follows)
    whole, and each such block is pushed at most once, so the space lost is at most the sum of their
    heights ``S`` and ``pages ≤ ⌈(H + S)/P⌉``; and no page loses more than the tallest block ``M``, so
    also ``pages ≤ ⌈H/(P − M)⌉``.
    """
    work = quick_pipeline(tmp_path_factory.getbasetemp())
    url = (work / "reports/comparison.html").resolve().as_uri()
    with _page(chromium, tmp_path, PRINT_W, PRINT_H) as cdp:
        cdp.call("Page.navigate", url=url)
        cdp.wait_event("Page.loadEventFired", timeout=120)
        cdp.call("Emulation.setEmulatedMedia", media="print")
        cdp.call("Emulation.setDeviceMetricsOverride", width=PRINT_W, height=PRINT_H, deviceScaleFactor=1, mobile=False)
        lay = cdp.call("Runtime.evaluate", expression=_PRINT_LAYOUT_JS, returnByValue=True)["result"]["value"]
        cdp.call("Emulation.clearDeviceMetricsOverride")
        pdf = base64.b64decode(cdp.call("Page.printToPDF", paperWidth=PAPER_IN[0], paperHeight=PAPER_IN[1],
                                        marginTop=MARGIN_IN, marginBottom=MARGIN_IN, marginLeft=MARGIN_IN,
                                        marginRight=MARGIN_IN, printBackground=False)["data"])  # fmt: skip
    (tmp_path / "report.pdf").write_bytes(pdf)
    pages = pdf_pages(pdf)
    n = len(pages)
    low = math.ceil(lay["height"] / PRINT_H)
    high = min(math.ceil((lay["height"] + lay["atoms_h"] + lay["heads_h"]) / PRINT_H),
               math.ceil(lay["height"] / max(1.0, PRINT_H - lay["max_atom"])))  # fmt: skip
    assert low <= n <= high, f"{n} pages, expected {low}–{high} (print layout {lay['height']} px on pages of {PRINT_H} px)"
    assert lay["body_scroll"] <= 0, f"in print the page is {lay['body_scroll']} px too wide"
    assert lay["figures"], "no figure in print"
    for f in lay["figures"]:
        assert f["avoid"] == "avoid", f"figure {f['id']} may be split (break-inside: {f['avoid']})"
        assert f["h"] <= PRINT_H, f"figure {f['id']} is taller ({f['h']} px) than a page ({PRINT_H} px)"
    assert lay["run_details_shown"] == 0  # the runs' list (links to their figures) and full tables are left to the screen
    # every image print shows is in the PDF (the lazy ones too: the page loads them before it prints),
    # each on one page only: no figure was split
    drawn = [i for p in pages for i in p]
    assert lay["images"] == sum(lay["pictures"])
    # a picture shown k times is on k pages (k figures, each whole on its page); a split figure adds a page
    assert sorted(drawn.count(i) for i in set(drawn)) == sorted(lay["pictures"]), (
        f"images on pages {sorted(drawn.count(i) for i in set(drawn))}, shown {sorted(lay['pictures'])}: a figure split over pages")
