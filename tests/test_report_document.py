"""The report as a reader's document, checked on a report built from one small run (fast).

* every work it names is cited by author and year and linked to a full entry under References;
  none of the development words (``issue``, ``SPEC``, a private document number) reaches its text;
* every internal link resolves (an id inside a ``<template>`` counts: the page's script opens its
  ``<details>`` when a link points into it), and so does every link between the report and its companion
  pages (``runs/<set>.html``: each set's run figures); each page's one inline script is allowed by its CSP hash;
* a set's summary table has at most 10 columns, and no table shows a column without a value;
* every image has alt text and a size; a run's figures are on its set's companion page, lazy;
* every number of the abstract equals the logged value it names (:func:`abstract_mismatches`,
  also run on the quick pipeline's report in tests/test_pipeline.py).
"""

from __future__ import annotations

import base64
import csv
import hashlib
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from pose_uncertainty.present import report as rp

#: Words of our own development that must not reach the report (beyond tests/test_words.py's FORBIDDEN).
REPORT_FORBIDDEN = {
    "the tracker": re.compile(r"\bissues?\b", re.IGNORECASE),
    "the internal specification": re.compile(r"\bSPEC\b"),
    "a source document by number": re.compile(r"\bseed[ _-]?0\d\d\b|seed0\d\d", re.IGNORECASE),
}


def report_words(html: str) -> list[str]:
    """Every forbidden word of the report's text (inlined image data is not text)."""
    text = re.sub(r"data:[^\"')\s]+", "data:", html)
    return [f"{kind}: {m.group(0)!r} in …{text[max(0, m.start() - 60):m.end() + 40]!r}…"
            for kind, pattern in REPORT_FORBIDDEN.items() for m in pattern.finditer(text)]  # fmt: skip


def _ids(html: str) -> set[str]:
    return set(re.findall(r'\bid="([^"]+)"', html))


def unresolved_links(html: str, here: Path | None = None) -> list[str]:
    """Links that lead nowhere: internal ones (``href="#id"``) with no element of that id (ids inside
    ``<template>`` count), and, with ``here`` (the folder of the page), links to a page beside it
    (``runs/<set>.html#id``, ``../comparison.html#id``) whose file is missing or has no such id.
    Without ``here`` a link to another page is unresolved."""
    ids = _ids(html)
    pages: dict[Path, set[str] | None] = {}
    bad = set()
    for href in re.findall(r'href="([^"]*)"', html):
        if href.startswith("data:"):
            continue
        page, _, anchor = href.partition("#")
        if not page:
            if anchor not in ids:
                bad.add(href)
            continue
        if here is None or re.match(r"[a-z]+:", page):
            bad.add(href)
            continue
        path = (here / page).resolve()
        if path not in pages:
            pages[path] = _ids(path.read_text(encoding="utf-8")) if path.is_file() else None
        if pages[path] is None or (anchor and anchor not in pages[path]):
            bad.add(href)
    return sorted(bad)


def report_pages(report: Path) -> dict[Path, str]:
    """The report and its companion pages (``runs/*.html`` beside it): path → text."""
    return {p: p.read_text(encoding="utf-8") for p in [report, *sorted((report.parent / "runs").glob("*.html"))]}


def _logged(path: str, files: dict[str, Any]) -> Any:
    """The value a ``data-src`` names: ``claims.<keys>``, ``studies.<keys>`` (``number=N`` picks the
    list item with that number, an integer the item at that index) or ``table.<table>.<run>.<measure>``."""
    if path.startswith("table."):
        table, run, measure = path[len("table."):].rsplit(".", 2)
        rows = {r["run"]: r for r in files["tables"][table]}
        return float(rows[run][measure])
    head, *keys = path.split(".")
    node = files[head]
    i = 0
    while i < len(keys):
        key = keys[i]
        # keys with a dot of their own (coverage_xy_98.89) are not used by the abstract
        if isinstance(node, list):
            if key.startswith("number="):
                node = next(x for x in node if x["number"] == int(key.split("=")[1]))
            else:
                node = node[int(key)]
        else:
            node = node[key]
        i += 1
    return node


def abstract_mismatches(html: str, files: dict[str, Any]) -> list[str]:
    """Numbers of the abstract and of the headline figure's caption that do not equal the value they name.

    ``files``: ``{"claims": claims.json, "studies": studies.json, "tables": {name: rows}}``. Each number is a
    ``<span class="num" data-src=… data-value=…>``: its data-value must equal the logged value, and its text
    must be that value formatted (:func:`pose_uncertainty.present.report._cell_text`). Returns one line per mismatch;
    a report without any number in its abstract is a mismatch too.
    """
    spans = re.findall(r'<span class="num" data-src="([^"]+)" data-value="([^"]+)">([^<]*)</span>', html)
    if not spans:
        return ["no number in the abstract"]
    bad = []
    for src, value, shown in spans:
        logged = _logged(src, files)
        claimed = json.loads(value.replace("&#34;", '"'))
        if not math.isclose(float(claimed), float(logged), rel_tol=0, abs_tol=0):
            bad.append(f"{src}: shows {claimed}, logged {logged}")
        if shown not in {rp._cell_text(logged, k) for k in ("pct", "cm", "cm2", 2, 3, 4)}:
            bad.append(f"{src}: text {shown!r} is not the logged {logged} formatted")
    return bad


# --- small pieces --------------------------------------------------------------------------


def test_cite_links_every_work_to_its_entry_and_escapes_plain_text() -> None:
    out = str(rp.cite("Thrun, Burgard & Fox 2005 §8.3; Skalka 2011 ch. 2 <b>"))
    assert out == ('<a class="cite" href="#ref-thrun2005">Thrun, Burgard &amp; Fox 2005</a> §8.3; '
                   '<a class="cite" href="#ref-skalka2011">Skalka 2011</a> ch. 2 &lt;b&gt;')  # fmt: skip
    # the longest name wins: "Borenstein & Feng 1996" is one link, not "Borenstein & Feng" plus " 1996"
    assert str(rp.cite("Borenstein & Feng 1996")).count("<a ") == 1
    keys = [k for k, _, _ in rp.REFERENCES]
    assert len(keys) == len(set(keys))
    for name in ("Němec 2012", "Šafránek 2022", "Skalka 2011", "Kulich 2014", "the Russian lecture deck on motion models",
                 "Siegwart & Nourbakhsh", "Long et al. RSS 2012", "Borenstein & Feng 1996", "Julier & Uhlmann"):  # fmt: skip
        assert 'href="#ref-' in str(rp.cite(name)), name
    for key, _, entry in rp.REFERENCES:  # a full entry: a title in italics and a year
        assert "<i>" in entry, key
        assert re.search(r"\b(19|20)\d\d\b|no author, institution or year", entry), key


def test_columns_without_a_value_are_left_out_and_the_summary_is_short() -> None:
    runs = [{"m": {"path_length": 1.0, "A_sigma_along": 0.1, "MC_sigma_across": math.nan}, "maps": ["v"]},
            {"m": {"path_length": 2.0, "A_sigma_along": None, "map_v_region_area": 1e-4}, "maps": ["v"]}]
    cols = [c[0] for c in rp._columns_with_data(runs, rp.SUMMARY_COLUMNS)]
    assert cols == ["path_length", "A_sigma_along"]
    assert len(rp.SUMMARY_COLUMNS) + 1 <= 10  # with the run column
    assert all("[" in head or "Hellinger" in head for _, head, _ in rp.SUMMARY_COLUMNS)  # units, or unitless
    assert [c[1] for c in rp._map_columns(runs)] == ["map_v_region_area"]
    assert rp._cell_text(1e-4, "cm2") == "1"
    assert rp._cell_text(0.5, "pct") == "50.00 %"
    assert rp._cell_text(None, 3) == "–"


def test_the_run_config_is_a_two_column_table_not_a_json_wall() -> None:
    rows = rp._param_rows({"seed": 5, "trajectory": {"name": "arc", "track": 0.2}, "maps": [{"name": "v", "alphas": [1, 2]}]})
    assert rows == [("seed", "5"), ("trajectory.name", '"arc"'), ("trajectory.track", "0.2"),
                    ("maps[0].name", '"v"'), ("maps[0].alphas", "[1, 2]")]  # fmt: skip


def test_a_sets_shared_parameters_are_printed_once_and_each_runs_own_with_it() -> None:
    """The parameters every run of a set logged alike, and each run's others: together its whole configuration."""
    runs = [{"params": {"seed": 1, "k_r": 5e-4, "trajectory": {"name": "arc", "radius": 1.0}}},
            {"params": {"seed": 2, "k_r": 5e-4, "trajectory": {"name": "arc", "radius": 2.0}}}]  # fmt: skip
    shared = rp._shared_params(runs)
    assert shared == {("k_r", "0.0005"), ("trajectory.name", '"arc"')}
    for r in runs:
        own = [kv for kv in rp._param_rows(r["params"]) if kv not in shared]
        assert sorted(own + sorted(shared)) == sorted(rp._param_rows(r["params"]))
    assert [kv[0] for kv in rp._param_rows(runs[0]["params"]) if kv not in shared] == ["seed", "trajectory.radius"]
    assert rp._shared_params([]) == set()


def test_the_csp_hash_is_the_scripts() -> None:
    digest = base64.b64encode(hashlib.sha256(rp.LAZY_SCRIPT.encode()).digest()).decode()
    assert rp._csp_hash(rp.LAZY_SCRIPT) == f"'sha256-{digest}'"


def test_abstract_check_catches_a_wrong_number() -> None:
    files = {"claims": {"claims": [{"number": 1, "numbers": {"slope": 1.5}}]}, "studies": {}, "tables": {}}
    good = '<span class="num" data-src="claims.claims.number=1.numbers.slope" data-value="1.5">1.5</span>'
    assert abstract_mismatches(good, files) == []
    assert abstract_mismatches(good.replace('"1.5"', '"1.6"'), files)
    assert abstract_mismatches(good.replace(">1.5<", ">1.6<"), files)
    assert abstract_mismatches("<p>no numbers</p>", files)


# --- a report built from one small run -----------------------------------------------------


#: A results file of ``make bench-report`` (two presets, the median of three runs each).
LIGHTHOUSE_RESULTS = {
    "benchmark": "report", "machine": {"cores": 2},
    "results": {preset: {"score_performance": perf, "score_accessibility": 0.97, "score_best_practices": 1.0,
                         "first_contentful_paint_s": fcp, "largest_contentful_paint_s": fcp + 0.1,
                         "time_to_interactive_s": fcp + 0.5, "page_weight_MB": 1.234, "dom_elements": 4321,
                         "lighthouse": "12.2.3", "runs": 3, "load_average_1min": 6.5,
                         "score_performance_runs": f"{perf}, 0.5, 0.61"}
                for preset, perf, fcp in (("desktop", 0.58, 3.25), ("mobile", 0.31, 19.5))},
}  # fmt: skip


def small_report_inputs(tmp: Path) -> tuple[dict[str, Any], dict[str, Path], Path, Path]:
    """The inputs of a report of one small run: manifest, tables, claims.json and pipeline.json, written in ``tmp``."""
    from pose_uncertainty.experiments.run import RunConfig, execute
    from pose_uncertainty.pipeline.claims import write_claims
    from pose_uncertainty.pipeline.summary import summarize_pipeline
    from pose_uncertainty.pipeline.tables import collect_table
    from pose_uncertainty.records.run import write_run

    cfg = {"name": "r1", "seed": 5, "k_r": 5e-4, "k_l": 5e-4, "n_ellipses": 2, "monte_carlo": {"n_particles": 200},
           "trajectory": {"name": "straight", "length": 1.0, "dt": 0.1, "speed": 0.5, "track": 0.2}}
    log = write_run(tmp / "r1.mcap", execute(RunConfig.from_dict(cfg)))
    table = collect_table("S_small", [log], None, tmp / "S_small.csv")
    png = tmp / "trajectory.png"
    Image.fromarray(np.full((60, 80, 3), 200, np.uint8)).save(png)
    run = {"id": "r1", "log": str(log), "swept": {"k_r": 0}, "figures": {"trajectory": str(png)}}
    manifest = {"sets": [{"name": "S_small", "title": "Chassis", "source": "Šafránek 2022 §4.2", "description": "",
                          "table": str(table), "figures": {}, "runs": [run]}], "config": {}}  # fmt: skip
    return (manifest, {"S_small": table}, write_claims({"S_small": table}, tmp / "claims.json"),
            summarize_pipeline({"S_small": table}, [], [], tmp / "pipeline.json"))


@pytest.fixture(scope="module")
def small_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Path]:
    tmp = tmp_path_factory.mktemp("small_report")
    (tmp / "results").mkdir()  # a Lighthouse results file as benchmarks/report_lighthouse.py writes it
    (tmp / "results/report.json").write_text(json.dumps(LIGHTHOUSE_RESULTS), encoding="utf-8")
    out = rp.build_report(*small_report_inputs(tmp), tmp / "r.html", speed_dir=tmp / "results")
    return out.read_text(encoding="utf-8"), tmp


def _companion(tmp: Path) -> str:
    return (tmp / "runs/S_small.html").read_text(encoding="utf-8")


def test_the_small_report_has_no_development_words_and_cites_its_sources(small_report: tuple[str, Path]) -> None:
    html, tmp = small_report
    assert report_words(html) == []
    assert report_words(_companion(tmp)) == []
    assert '<li id="ref-safranek2022">' in html
    assert '<li id="ref-nemec2012">' in html
    assert 'Source: <a class="cite" href="#ref-safranek2022">Šafránek 2022</a> §4.2' in html
    # the companion page cites the report's entries
    assert 'Source: <a class="cite" href="../r.html#ref-safranek2022">Šafránek 2022</a> §4.2' in _companion(tmp)


def test_the_small_report_links_resolve_and_its_script_is_allowed(small_report: tuple[str, Path]) -> None:
    html, tmp = small_report
    assert unresolved_links(html) == ["S_small.csv", "runs/S_small.html", "runs/S_small.html#params-S_small",
                                      "runs/S_small.html#run-S_small-r1",
                                      "runs/S_small.html#table-S_small"]  # not without a folder
    for page, text in report_pages(tmp / "r.html").items():
        assert unresolved_links(text, page.parent) == [], page
        script = re.search(r"<script>(.*?)</script>", text, re.DOTALL)
        assert script is not None
        assert script.group(1) == rp.LAZY_SCRIPT
        csp = re.search(r'http-equiv="Content-Security-Policy" content="([^"]+)"', text)
        assert csp is not None
        assert rp._csp_hash(rp.LAZY_SCRIPT) in csp.group(1).replace("&#39;", "'")
        assert "https:" not in text
        assert "http:" not in text
    assert sorted(p.name for p in report_pages(tmp / "r.html")) == ["S_small.html", "r.html"]


def test_each_section_below_the_first_screen_is_laid_out_when_reached(small_report: tuple[str, Path]) -> None:
    """Every section after the findings and the contents is a ``section.part`` of its own (one heading each, the
    tags balanced), which the stylesheet lets Chromium skip until it is scrolled to, and lays out for print."""
    html, _ = small_report
    body = html[html.index("<main"):html.index("</main>")]
    heads = re.findall(r'(<section class="part">\n)?<h2 id="([^"]+)"', body)
    assert [h for s, h in heads if not s] == ["findings", "contents"]
    assert len(heads) >= 8  # guide, claims, a set, references, reproducibility, ... (the small report)
    assert body.count("<section") == body.count("</section>")
    css = html[html.index("<style>"):html.index("</style>")]
    assert re.search(r"section\.part \{ content-visibility: auto;", css)
    # a skipped section's contents, measured while it stands at its placeholder size, do not spill over the next's
    assert re.search(r"section\.part \{ content-visibility: auto; contain-intrinsic-size: auto \d+px; overflow: hidden; \}", css)
    assert re.search(r"@media print \{\n  section\.part \{ content-visibility: visible; overflow: visible; \}", css)


def test_a_runs_entry_links_its_figures_and_the_page_links_back(small_report: tuple[str, Path]) -> None:
    """The run's entry in the report (its id, what its set sweeps, its parameters) links to its anchor on
    the set's companion page; that anchor holds its figures and links back to the entry."""
    html, tmp = small_report
    entry = html[html.index('<li id="run-S_small-r1">'):]
    entry = entry[:entry.index("</li>")]
    assert '<a href="runs/S_small.html#run-S_small-r1"><b>r1</b>: 1 figure</a>' in entry
    assert "k_r = " in entry
    # one run: every parameter it logged is the set's, in a table on the set's page, which the report links
    assert '<p class="small shared" id="params-S_small"><a href="runs/S_small.html#params-S_small">' in html
    assert '<details class="shared"' not in html
    assert '<details class="run"' not in html
    page = _companion(tmp)
    params = page[page.index('<section id="params-S_small"'):]
    params = params[:params.index("</section>")]
    assert '<table class="kv">' in params
    assert "<tr><th>seed</th><td>5</td></tr>" in params
    run = page[page.index('id="run-S_small-r1"'):]
    run = run[:run.index("</section>")]
    assert '<a href="../r.html#run-S_small-r1">' in run
    assert 'id="fig-S_small-r1-trajectory"' in run
    assert re.search(r'<h1>Chassis: each run.s figures</h1>', page)
    assert "<style>" in page
    assert page[page.index("<style>"):page.index("</style>")] == html[html.index("<style>"):html.index("</style>")]


def test_the_full_table_is_on_the_sets_page_one_link_away(small_report: tuple[str, Path]) -> None:
    """A set with a companion page: the report links its full table there (every byte of the report is loaded
    before its first paint), and the page holds it: every measure of the set, a row per run linking its section."""
    html, tmp = small_report
    from pose_uncertainty.core.table_io import read_table

    rows = [{"m": r} for r in read_table(tmp / "S_small.csv")]
    n_columns = len(rp._columns_with_data(rows, rp.RUN_COLUMNS))  # the run's measures with a value (no maps)
    assert n_columns > 10
    assert '<details class="full">' not in html
    link = re.search(r'<p class="full small"><a href="([^"#]+)#([^"]+)">Full table: all (\d+) measures of the 1 runs</a>', html)
    assert link, "no link to the set's full table"
    assert (link.group(1), link.group(2), int(link.group(3))) == ("runs/S_small.html", "table-S_small", n_columns)
    page = _companion(tmp)
    table = page[page.index('<section id="table-S_small"'):]
    table = table[:table.index("</section>")]
    assert len(re.findall(r"<th>", table.split("</thead>")[0])) == n_columns  # the second header row: a measure each
    assert '<td><a href="#run-S_small-r1">r1</a></td>' in table
    assert 'id="run-S_small-r1"' in page


def test_the_small_reports_tables_and_images(small_report: tuple[str, Path]) -> None:
    html, tmp = small_report
    summary = html[html.index("<h3>Comparison per run</h3>"):html.index('class="full')]
    heads = re.findall(r"<th>", summary.split("</thead>")[0])
    assert 2 <= len(heads) <= 10
    assert '<table class="nums">' in summary  # every cell but the run's a number, right-aligned
    body = summary.split("</thead>")[1]
    cells = re.findall(r'<td>([^<]*)</td>', body)
    assert cells
    assert "–" not in cells
    assert "<img " not in html  # the run's figure is on its set's companion page, not in the report
    imgs = re.findall(r"<img [^>]*>", _companion(tmp))
    assert len(imgs) == 1
    for i in imgs:
        assert re.search(r'alt="[^"]{8,}"', i), i
        assert 'width="' in i, i
        assert 'height="' in i, i
        assert 'loading="lazy"' in i, i
    assert 'width="40" height="30"' in imgs[0]  # an 80 × 60 PNG is shown at half its pixels (2×)


def test_the_quick_tables_match_the_abstract_format(small_report: tuple[str, Path]) -> None:
    """The abstract reader of the quick report reads this table format (``run`` column, measures as numbers)."""
    _, tmp = small_report
    with open(tmp / "S_small.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert rows[0]["run"] == "r1"
    assert float(rows[0]["path_length"]) == pytest.approx(1.0)


def test_log_axes_show_every_point_with_room() -> None:
    """The accuracy-against-time figure's limits hold every finite point (the histogram filter's far to
    the right included), checked against the points' own extent."""
    from pose_uncertainty.present import figures
    from pose_uncertainty.present.localization import _fit_log_limits

    fig = figures.new_figure((4.0, 3.0))
    ax = fig.add_subplot()
    pts = [(0.05, 0.03), (0.2, 0.02), (40.0, 0.5), (float("nan"), 1.0), (0.0, 2.0)]
    for x, y in pts:
        ax.plot([x], [y], ls="none", marker="o")
    ax.set_xscale("log")
    ax.set_yscale("log")
    _fit_log_limits(ax)
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    for x, y in pts[:3]:
        assert x0 < x < x1
        assert y0 < y < y1
    assert x1 >= 40.0 * 1.6  # room on the right for the run's label
    assert y1 < 2.0  # the points it cannot draw on log axes do not stretch them


def test_the_small_report_shows_the_lighthouse_results(small_report: tuple[str, Path]) -> None:
    """``benchmarks/results/report.json`` (``make bench-report``) is shown: every preset with its scores,
    paint times, weight, the runs' scores and the load they ran under."""
    html, _ = small_report
    section = html[html.index('<h3 id="speed-report">'):]
    section = section[:section.index("</table>")]
    assert "Lighthouse 12.2.3" in section
    assert "served from 127.0.0.1\nas it is, uncompressed" in section  # no content_encoding: the file as it is
    for preset, r in LIGHTHOUSE_RESULTS["results"].items():
        row = re.search(rf"<tr><td>{preset}</td>(.*?)</tr>", section, re.DOTALL)
        assert row is not None, preset
        cells = re.findall(r'<td class="n">([^<]*)</td>', row.group(1))
        assert cells == [rp._fmt(r["score_performance"], 2), rp._fmt(r["score_accessibility"], 2),
                         rp._fmt(r["score_best_practices"], 2), rp._fmt(r["first_contentful_paint_s"], 2),
                         rp._fmt(r["largest_contentful_paint_s"], 2), rp._fmt(r["time_to_interactive_s"], 2),
                         rp._fmt(r["page_weight_MB"], 3), rp._fmt(r["dom_elements"], 5), r["score_performance_runs"],
                         rp._fmt(r["load_average_1min"], 2)]  # fmt: skip
