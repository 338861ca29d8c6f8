"""The self-contained HTML comparison report: it formats what the pipeline logged, and computes nothing.

:func:`build_report` renders ``reports/comparison.html`` from the Jinja2 template
``templates/comparison.html.j2`` with

* the per-set tables (:mod:`pose_uncertainty.pipeline.tables`: every number a logged
  measure of a run, under its own name);
* ``reports/claims.json`` — the claims, the method guide and the Method C summary
  (:func:`pose_uncertainty.pipeline.claims.write_claims`);
* ``reports/studies.json`` — the studies' logged results and the numbers their text
  quotes (:func:`pose_uncertainty.experiments.study.collect_studies`; the report links the file, beside it);
* ``reports/pipeline.json`` — provenance read from every log, seeds and per-rule
  times (:func:`pose_uncertainty.pipeline.summary.summarize_pipeline`);
* the runs with a drive section, arranged by drive and path for the section "Beyond the
  differential drive" (their table rows as they are);
* every run's parameters as it logged them: the ``param.*`` columns and ``seed`` of its table
  row (:func:`logged_params`), never the workflow's copy of the config;
* the robots of the ``robots`` section (section "Your robot", :mod:`pose_uncertainty.present.robot_report`:
  their calibration outputs as the jobs logged them);
* the figures (inlined as ``data:`` URIs: no network request, works offline; each PNG
  re-encoded as lossless WebP, the same pixels in about 20 % fewer bytes) and the speed
  benchmarks' result files when ``make bench`` has written them.

The report holds the set, study, localization and robot figures; each run's own figures, and the set's
full table of every measure, are on its set's companion page, ``reports/runs/<set>.html`` (:func:`write_run_pages`: self-contained too,
one anchor per run, linked from the run's entry in the report and back). A browser reads a whole
HTML file before its first paint, so the report stays near 1 MB however many runs there are.

Every number in the HTML is one of those values, formatted (units converted for
display: m² → cm², fractions → %).
"""

from __future__ import annotations

import base64
import datetime as _dt
import hashlib
import html
import io
import json
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jinja2
from markupsafe import Markup
from PIL import Image

from ..core.atomic import atomic_directory, atomic_write_text
from ..core.drives import DRIVES
from ..core.provenance import MACHINE_KEYS
from ..core.stats import COVERAGE_LEVELS
from ..core.table_io import read_table
from .robot_report import robot_section

__all__ = ["REFERENCES", "RUNS_DIR", "RUN_COLUMNS", "SUMMARY_COLUMNS", "build_report", "cite", "logged_params",
           "read_speed_results", "write_run_pages"]


#: The works the report cites: ``(key, how the text names it, the full entry)``. Every name in
#: the report's prose that matches one becomes a link to its entry (:func:`cite`).
REFERENCES: tuple[tuple[str, tuple[str, ...], str], ...] = (
    ("nemec2012", ("Němec 2012",),
     ("Jakub Němec. <i>Analýza neurčitosti pozice kolového robota</i> (Analysis of robot position errors). Bachelor's "
     "thesis, Brno University of Technology, Faculty of Electrical Engineering and Communication, Department of Control "
     "and Instrumentation, 2012. Supervisor František Šolc. In Czech.")),
    ("safranek2022", ("Šafránek 2022",),
     ("Petr Šafránek. <i>Analýza kinematiky diferenciálního robotu</i> (A kinematic analysis of a skid-steer wheeled "
     "mobile robot). Bachelor's thesis, Brno University of Technology, Faculty of Electrical Engineering and "
     "Communication, Department of Control and Instrumentation, 2022. Supervisor František Burian. In Czech.")),
    ("skalka2011", ("Skalka 2011",),
     ("Marek Skalka. <i>Srovnání lokalizačních technik</i> (A comparison of localization techniques). Master's thesis, "
     "Charles University in Prague, Faculty of Mathematics and Physics, Department of Software Engineering, 2011. "
     "Supervisor David Obdržálek. In Czech.")),
    ("kulich2014", ("Kulich 2014",),
     ("Miroslav Kulich. <i>Pravděpodobnostní metody lokalizace v mobilní robotice</i> (Probabilistic localization "
     "methods in mobile robotics). Lecture slides, Intelligent and Mobile Robotics Group, Gerstner Laboratory, Czech "
     "Technical University in Prague, 27 February 2014. In Czech.")),
    ("motion-lecture", ("the Russian lecture deck on motion models", "Russian lecture deck on motion models"),
     ("<i>Мобильная робототехника: Вероятностные модели движения</i> (Mobile robotics: probabilistic motion models). "
     "Lecture slides of a mobile-robotics course, in Russian; the slides name no author, institution or year. They "
     "follow Thrun, Burgard &amp; Fox 2005, ch. 5 (odometry and velocity motion models).")),
    ("thrun2005", ("Thrun, Burgard & Fox 2005", "Thrun, Burgard & Fox"),
     ("Sebastian Thrun, Wolfram Burgard, Dieter Fox. <i>Probabilistic Robotics</i>. MIT Press, Cambridge, MA, 2005.")),
    ("siegwart2004", ("Siegwart & Nourbakhsh 2004", "Siegwart & Nourbakhsh"),
     ("Roland Siegwart, Illah R. Nourbakhsh. <i>Introduction to Autonomous Mobile Robots</i>. MIT Press, Cambridge, "
     "MA, 2004 (§5.2.4: odometric position error model).")),
    ("long2012", ("Long et al. RSS 2012", "Long et al., RSS 2012", "Long et al. 2012"),
     ("Andrew W. Long, Kevin C. Wolfe, Michael J. Mashner, Gregory S. Chirikjian. The banana distribution is Gaussian: "
     "a localization study with exponential coordinates. In <i>Robotics: Science and Systems VIII</i> (RSS), Sydney, 2012.")),
    ("borenstein1996", ("Borenstein & Feng 1996", "Borenstein & Feng"),
     ("Johann Borenstein, Liqiang Feng. Measurement and correction of systematic odometry errors in mobile robots. "
     "<i>IEEE Transactions on Robotics and Automation</i> 12(6), 869–880, 1996.")),
    ("julier2004", ("Julier & Uhlmann 2004", "Julier & Uhlmann"),
     ("Simon J. Julier, Jeffrey K. Uhlmann. Unscented filtering and nonlinear estimation. <i>Proceedings of the IEEE</i> "
     "92(3), 401–422, 2004.")),
    ("vandermerwe2004", ("van der Merwe 2004", "van der Merwe"),
     ("Rudolph van der Merwe. <i>Sigma-point Kalman filters for probabilistic inference in dynamic state-space "
     "models</i>. PhD thesis, OGI School of Science &amp; Engineering, Oregon Health &amp; Science University, 2004.")),
    ("wilson1927", ("Wilson 1927",),
     ("Edwin B. Wilson. Probable inference, the law of succession, and statistical inference. <i>Journal of the "
     "American Statistical Association</i> 22(158), 209–212, 1927.")),
)

_CITE_NAMES = sorted(((html.escape(name, quote=False), key) for key, names, _ in REFERENCES for name in names),
                     key=lambda nk: -len(nk[0]))  # fmt: skip
_CITE_RE = re.compile("|".join(re.escape(n) for n, _ in _CITE_NAMES))
_CITE_KEY = dict(_CITE_NAMES)


def cite(text: Any, page: str = "") -> Markup:
    """``text`` with every work of :data:`REFERENCES` it names linked to its entry (``#ref-<key>``).

    Plain text is escaped first; markup (a ``{% filter cite %}`` block of the template) is kept as it is,
    so only prose may pass through (a name inside an attribute would be linked too).

    Parameters
    ----------
    text : str or markup
    page : str — the page that holds the references, relative to the page the text is on ("" for the report
        itself; a companion page links to the report's entries, ``../comparison.html``)

    >>> str(cite("Němec 2012 §3.1"))
    '<a class="cite" href="#ref-nemec2012">Němec 2012</a> §3.1'
    """
    body = str(text) if hasattr(text, "__html__") else html.escape("" if text is None else str(text), quote=False)
    href = html.escape(page)
    return Markup(_CITE_RE.sub(lambda m: f'<a class="cite" href="{href}#ref-{_CITE_KEY[m.group(0)]}">{m.group(0)}</a>',
                               body))


#: The pages' only script: what a ``<details>`` holds in a ``<template>`` (inert: not parsed into the page,
#: not laid out — a set's full table, a run's parameters) is put into the page when the reader opens it, or
#: follows a link into it; before printing, the lazy figures are loaded.
LAZY_SCRIPT = """(function () {
  function fill(d) { var t = d.querySelector(':scope > template'); if (t) { d.appendChild(t.content.cloneNode(true)); t.remove(); } }
  document.addEventListener('toggle', function (e) { if (e.target.tagName === 'DETAILS' && e.target.open) fill(e.target); }, true);
  function reveal() {
    var id = decodeURIComponent(location.hash.slice(1));
    if (!id || document.getElementById(id)) return;
    var ts = document.querySelectorAll('details > template');
    for (var i = 0; i < ts.length; i++) {
      if (ts[i].content.getElementById(id)) {
        var d = ts[i].parentElement; fill(d); d.open = true;
        for (var p = d.parentElement; p; p = p.parentElement) { if (p.tagName === 'DETAILS') p.open = true; }
        document.getElementById(id).scrollIntoView(); return;
      }
    }
  }
  window.addEventListener('hashchange', reveal); reveal();
  // print: the figures below the screen are lazy; load them all before the page is laid out for paper
  window.addEventListener('beforeprint', function () {
    document.querySelectorAll('img[loading="lazy"]').forEach(function (i) { i.loading = 'eager'; });
  });
})();"""


def _csp_hash(script: str) -> str:
    """The Content-Security-Policy source of an inline script: ``'sha256-…'`` of its UTF-8 bytes."""
    return "'sha256-" + base64.b64encode(hashlib.sha256(script.encode("utf-8")).digest()).decode("ascii") + "'"


#: The key columns of a set's summary table: ``(measure, header with unit, format)``; format "pct" is a
#: share shown in %, "cm2"/"cm" a value in m² / m shown in cm² / cm, a number the significant digits.
SUMMARY_COLUMNS: tuple[tuple[str, str, Any], ...] = (
    ("path_length", "L [m]", 3),
    ("A_sigma_along", "A: σ along [m]", 3),
    ("A_sigma_across", "A: σ across [m]", 3),
    ("MC_sigma_across", "Monte Carlo: σ across [m]", 3),
    ("MC_coverage_3s", "Monte Carlo in A's 98.89 % ellipse [%]", "pct"),
    ("accuracy_unscented_coverage_xy_98_89", "Monte Carlo in C's 98.89 % ellipse [%]", "pct"),
    ("accuracy_cartesian_hellinger", "Hellinger A to Monte Carlo", 3),
    ("accuracy_expcoords_hellinger", "Hellinger exp. coords to Monte Carlo", 3),
)

#: Every per-run column of a set's full table: ``(group, measure, header, format)`` (as :data:`SUMMARY_COLUMNS`).
RUN_COLUMNS: tuple[tuple[str, str, str, Any], ...] = (
    ("", "path_length", "L [m]", 4),
    ("Method A (covariance)", "A_sigma_along", "σ along [m]", 4),
    ("Method A (covariance)", "A_sigma_across", "σ across [m]", 4),
    ("Method A (covariance)", "A_sigma_theta", "σ<sub>θ</sub> [rad]", 4),
    ("Method A (covariance)", "A_ellipse_major", "ellipse a [m]", 4),
    ("Method A (covariance)", "A_ellipse_minor", "ellipse b [m]", 4),
    ("Method A (covariance)", "A_bend_ratio", "bend ratio ρ", 2),
    ("Method C (sigma points)", "C_sigma_along", "σ along [m]", 4),
    ("Method C (sigma points)", "C_sigma_across", "σ across [m]", 4),
    ("Method C (sigma points)", "C_mean_shift_along", "mean shift along [m]", 3),
    ("Method C (sigma points)", "C_mean_shift_across", "mean shift across [m]", 3),
    ("Method C (sigma points)", "accuracy_unscented_coverage_xy_98_89", "MC in its 98.89 % ellipse", "pct"),
    ("Monte Carlo", "MC_sigma_along", "σ along [m]", 4),
    ("Monte Carlo", "MC_sigma_across", "σ across [m]", 4),
    ("Monte Carlo", "MC_coverage_3s", "in A's 98.89 % ellipse", "pct"),
    ("Monte Carlo", "MC_cov_rel_error", "Σ rel. error", 3),
    ("Monte Carlo", "MC_ks_gauss", "KS to χ²₂", 3),
    ("Monte Carlo", "MC_ks_crit", "KS crit.", 2),
    ("Monte Carlo", "MC_bend", "bend", 3),
    ("Monte Carlo", "MC_bend_crit", "bend noise", 2),
    ("Monte Carlo", "MC_mean_shift_along", "mean shift along [m]", 3),
    ("Monte Carlo", "MC_mean_shift_across", "mean shift across [m]", 3),
    ("Hellinger to Monte Carlo", "accuracy_cartesian_hellinger", "A, Cartesian", 3),
    ("Hellinger to Monte Carlo", "accuracy_expcoords_hellinger", "A, exp. coords", 3),
    ("Hellinger to Monte Carlo", "accuracy_unscented_hellinger", "C", 3),
    ("Hellinger to Monte Carlo", "accuracy_monte_carlo_hellinger_floor", "floor", 2),
    ("compute time [s]", "time_covariance", "A", 2),
    ("compute time [s]", "time_unscented", "C", 2),
    ("compute time [s]", "time_monte_carlo", "MC", 2),
)


def _has(value: Any) -> bool:
    return value is not None and not (isinstance(value, float) and math.isnan(value)) and value != ""


def _columns_with_data(runs: list[dict[str, Any]], spec: tuple[tuple[Any, ...], ...]) -> list[tuple[Any, ...]]:
    """The columns of ``spec`` (measure second-to-last-but-one: ``spec[i][-3]``) that hold a value in some run."""
    return [c for c in spec if any(_has(r["m"].get(c[-3])) for r in runs)]


def _map_columns(runs: list[dict[str, Any]]) -> list[tuple[str, str, str, Any]]:
    """The Method B columns of a set's full table: per map name, its logged region, peak offset, Hellinger, time."""
    names: list[str] = []
    for r in runs:
        names += [n for n in r["maps"] if n not in names]
    cols = []
    for n in names:
        g = f"Method B map {n}"
        cols += [(g, f"map_{n}_region_area", "98.89 % region [cm²]", "cm2"), (g, f"map_{n}_peak_offset", "peak offset [cm]", "cm"),
                 (g, f"map_{n}_hellinger_sampler", "Hellinger to its sampler", 3),
                 (g, f"map_{n}_hellinger_floor", "floor", 2), (g, f"time_map_{n}", "time [s]", 2)]  # fmt: skip
    return _columns_with_data(runs, tuple(cols))


def _cell_text(value: Any, kind: Any) -> str:
    """A table cell's text: the value formatted by ``kind`` (see :data:`SUMMARY_COLUMNS`), "–" for none."""
    if not _has(value):
        return "–"
    if kind == "pct":
        return f"{100.0 * float(value):.2f} %"
    if kind == "cm2":
        return _fmt(float(value) * 1e4, 4)
    if kind == "cm":
        return _fmt(float(value) * 100.0, 3)
    return _fmt(value, int(kind))


def _param_rows(params: Mapping[str, Any], prefix: str = "") -> list[tuple[str, str]]:
    """A run's logged parameters as ``(dotted key, value as JSON)`` rows, for a two-column table."""
    rows: list[tuple[str, str]] = []
    for k, v in params.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping) and v:
            rows += _param_rows(v, key + ".")
        elif isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v):
            for i, x in enumerate(v):
                rows += _param_rows(x, f"{key}[{i}].")
        else:
            rows.append((key, json.dumps(v, ensure_ascii=False)))
    return rows


def _data_uri(path: str | os.PathLike[str], encoded: Mapping[str, bytes] | None = None) -> str:
    """The file as a ``data:`` URI; a PNG becomes a lossless WebP (identical pixels, fewer bytes).

    ``encoded``: WebP bytes already made for some PNGs, by path (:func:`_encode_all`).
    """
    p = Path(path)
    suffix = p.suffix.lstrip(".").lower()
    mime = {"png": "image/webp", "svg": "image/svg+xml", "jpg": "image/jpeg"}.get(suffix)
    if mime is None:
        raise ValueError(f"cannot inline {p} (allowed: .png, .svg, .jpg)")
    if suffix == "png":
        data = encoded[str(path)] if encoded is not None and str(path) in encoded else _webp(p)
    else:
        data = p.read_bytes()
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


def _pngs(*trees: Any) -> list[str]:
    """Every string ending in ``.png`` in nested mappings and lists (the figures a report inlines)."""
    out: list[str] = []
    stack = list(trees)
    while stack:
        node = stack.pop()
        if isinstance(node, Mapping):
            stack.extend(node.values())
        elif isinstance(node, (list, tuple)):
            stack.extend(node)
        elif isinstance(node, (str, os.PathLike)) and str(node).lower().endswith(".png"):
            out.append(str(node))
    return sorted(set(out))


def _encode_all(paths: list[str]) -> dict[str, bytes]:
    """The WebP of each existing PNG, encoded on the job's threads (Pillow encodes without the GIL):
    the report's last and only job otherwise leaves a core idle for the 500 figures' ~5 s."""
    from concurrent.futures import ThreadPoolExecutor

    from ..core.threads import default_workers

    files = [p for p in paths if Path(p).is_file()]
    with ThreadPoolExecutor(max_workers=default_workers()) as pool:
        return dict(zip(files, pool.map(lambda f: _webp(Path(f)), files), strict=True))


def _webp(png: Path) -> bytes:
    """A PNG re-encoded as lossless WebP (libwebp method 2: deterministic, ~10 ms for a figure).

    Every modern browser shows WebP; the pixels are the PNG's exactly.
    """
    with Image.open(png) as image:
        out = io.BytesIO()
        image.save(out, format="WEBP", lossless=True, method=2, exact=True)
    return out.getvalue()


def _img(path: str | os.PathLike[str], alt: str, uri: Any, *, eager: bool = False) -> Markup:
    """An ``<img>`` of the inlined figure with its alt text and its size in CSS pixels (the PNG's at
    :data:`pose_uncertainty.present.figures.HIDPI`-times density), so the page does not shift as it loads."""
    from .figures import HIDPI

    with Image.open(path) as image:
        w, h = image.size
    lazy = "" if eager else ' loading="lazy"'
    return Markup(f'<img src="{uri(path)}" alt="{html.escape(alt)}" width="{round(w / HIDPI)}" '
                  f'height="{round(h / HIDPI)}" decoding="async"{lazy}>')  # fmt: skip


def _fmt(value: Any, digits: int = 4) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        if math.isnan(value):
            return "–"
        if value == 0:
            return "0"
        if 1e-3 <= abs(value) < 1e4:
            return f"{value:.{digits}g}"
        return f"{value:.{digits - 1}e}"
    return html.escape(str(value))


def read_speed_results(directory: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The speed benchmarks' result files (``benchmarks/results/*.json``, written by ``make bench``).

    Returns one entry per file: ``{"benchmark", "machine", "file", "results":
    {case: {measure: value}}}``, sorted by name; an unreadable file becomes an
    entry with an ``"error"``. A missing directory gives an empty list.
    """
    d = Path(directory)
    out: list[dict[str, Any]] = []
    for f in sorted(d.glob("*.json")) if d.is_dir() else []:
        try:
            data = json.loads(f.read_text(encoding="utf-8"))
            out.append(
                {
                    "benchmark": str(data.get("benchmark", f.stem)),
                    "machine": data.get("machine", {}),
                    "file": str(f),
                    "results": {
                        str(case): (vals if isinstance(vals, Mapping) else {"value": vals})
                        for case, vals in dict(data.get("results", {})).items()
                    },
                }
            )
        except (OSError, ValueError, TypeError, AttributeError) as exc:
            out.append({"benchmark": f.stem, "file": str(f), "error": str(exc), "results": {}})
    return out


def _read_json(path: str | os.PathLike[str] | None) -> Any:
    if path is None or not Path(path).is_file():
        return None
    return json.loads(Path(path).read_text(encoding="utf-8"))


def _environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("pose_uncertainty.present", "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["fmt"] = _fmt
    env.filters["datauri"] = _data_uri
    env.filters["pct"] = lambda v: "–" if v is None else f"{100.0 * float(v):.2f} %"
    env.filters["cite"] = cite
    env.filters["cell"] = lambda v, kind: _cell_text(v, kind)
    env.filters["flat"] = _param_rows
    return env


def logged_params(row: Mapping[str, Any]) -> dict[str, Any]:
    """A run's logged configuration, nested, from its table row (the ``param.*`` columns and ``seed``).

    ``param.trajectory.track`` becomes ``{"trajectory": {"track": ...}}``; a list (logged as
    JSON in its cell, e.g. ``param.maps``) is decoded; an empty cell (a key this run does not
    have) is left out.

    Parameters
    ----------
    row : mapping — one row of a per-set table (:func:`pose_uncertainty.pipeline.tables.run_row`)

    Returns
    -------
    dict — the parameters as the run logged them
    """
    out: dict[str, Any] = {} if row.get("seed") is None else {"seed": row["seed"]}
    for column, value in row.items():
        if not column.startswith("param.") or value is None:
            continue
        *parents, leaf = column[len("param."):].split(".")
        node = out
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = json.loads(value) if isinstance(value, str) and value.startswith("[") else value
    return out


def _at(params: Mapping[str, Any], dotted: str) -> Any:
    """The logged value of the dotted key (None if the run did not log it)."""
    node: Any = params
    for part in dotted.split("."):
        node = node.get(part) if isinstance(node, Mapping) else None
    return node


def _shaped(shape: Any, value: Any) -> Any:
    """``value`` cut to the keys of ``shape`` where both are mappings (a swept sub-mapping), element by element
    where both are lists of one length (a swept list of maps), else ``value`` itself."""
    if isinstance(shape, Mapping) and isinstance(value, Mapping):
        return {k: _shaped(v, value.get(k)) for k, v in shape.items()}
    if isinstance(shape, list | tuple) and isinstance(value, list) and len(shape) == len(value):
        return [_shaped(a, b) for a, b in zip(shape, value, strict=True)]
    return value


def _with_row(run: Mapping[str, Any], row: Mapping[str, Any]) -> dict[str, Any]:
    """A manifest run with its table row (``m``), its logged parameters (``params``) and the logged values of
    the keys its set sweeps (``swept``: the manifest names the keys; every value printed is the log's)."""
    params = logged_params(row)
    swept = {k: _shaped(v, _at(params, k)) for k, v in dict(run.get("swept", {})).items()}
    return {**run, "m": row, "params": params, "swept": swept}


def _sets(manifest: Mapping[str, Any], tables: Mapping[str, str | os.PathLike[str]]) -> list[dict[str, Any]]:
    """The manifest's sets with each run's table row attached (:func:`_with_row`) and its map names."""
    sets = []
    for s in manifest["sets"]:
        rows = {r["run"]: r for r in read_table(tables[s["name"]])} if s["name"] in tables else {}
        runs = [{**_with_row(r, rows.get(r["id"], {})), "maps": [k[4:] for k in r["figures"] if k.startswith("map_")]}
                for r in s["runs"]]  # fmt: skip
        shared = _shared_params(runs)
        for r in runs:
            r["own_params"] = [kv for kv in _param_rows(r["params"]) if kv not in shared]
        sets.append({**s, "runs": runs, "summary_columns": _columns_with_data(runs, SUMMARY_COLUMNS),
                     "columns": _columns_with_data(runs, RUN_COLUMNS) + _map_columns(runs),
                     "shared_params": [kv for kv in _param_rows(runs[0]["params"]) if kv in shared] if runs else []})
    return sets


def _shared_params(runs: list[dict[str, Any]]) -> set[tuple[str, str]]:
    """The logged parameters (``(dotted key, value)`` rows, :func:`_param_rows`) every run of a set has alike:
    the report prints them once for the set, and for each run the rest (selection only; the values are the logs')."""
    rows = [set(_param_rows(r["params"])) for r in runs]
    return set.intersection(*rows) if rows else set()


def _drive_runs(sets: list[dict[str, Any]]) -> dict[str, Any]:
    """The runs with a drive section, arranged for "Beyond the differential drive" (selection only).

    Returns ``{"drives": [type, ...] (in DRIVES order), "paths": [trajectory name, ...] (first
    appearance), "by": {type: {path: run}}, "sets": [set name, ...], "figures": {set: path}}``;
    a run is ``{"set", "id", "path", "drive" (its logged section), "m" (its table row)}``. The first run of a
    (drive, path) pair wins.
    """
    by: dict[str, dict[str, dict[str, Any]]] = {}
    paths: list[str] = []
    names: list[str] = []
    figs: dict[str, str] = {}
    for s in sets:
        for r in s["runs"]:
            drive = r["params"].get("drive")
            if not drive:
                continue
            path = r["params"]["trajectory"]["name"]
            paths += [] if path in paths else [path]
            names += [] if s["name"] in names else [s["name"]]
            run = {"set": s["name"], "id": r["id"], "path": path, "drive": drive, "m": r["m"]}
            by.setdefault(drive["type"], {}).setdefault(path, run)
            if "drives" in s["figures"]:
                figs[s["name"]] = s["figures"]["drives"]
    return {"drives": [d for d in DRIVES if d in by], "paths": paths, "by": by, "sets": names, "figures": figs}


def _localization(
    manifest: Mapping[str, Any] | None, tables: Mapping[str, str | os.PathLike[str]]
) -> dict[str, Any] | None:
    """The localization sets with each run's table row (``m``) and the lead run (first run of the first set)."""
    if not manifest or not manifest.get("sets"):
        return None
    sets = []
    for s in manifest["sets"]:
        path = tables.get(f"localization/{s['name']}", tables.get(s["name"]))
        rows = {r["run"]: r for r in read_table(path)} if path is not None else {}
        sets.append({**s, "runs": [_with_row(r, rows.get(r["id"], {})) for r in s["runs"]]})
    lead = sets[0]["runs"][0] if sets[0]["runs"] else None
    return {"sets": sets, "lead": lead}


# --- Skalka 2011's localization techniques: the sections' data, selected from the studies' logs --------


def skalka_sections(studies: Mapping[str, Any] | None) -> dict[str, list[dict[str, Any]]]:
    """The logged studies of Skalka 2011's techniques by section, for the report's sections on them.

    Parameters
    ----------
    studies : mapping or None — the studies document (:func:`pose_uncertainty.experiments.study.collect_studies`)

    Returns
    -------
    dict — kind (``relative_sensing``, ``absolute_sensing``, ``guaranteed_bounds``, ``representations``,
    ``active_localization``) → ``[{"name", "r"}, ...]``, the studies of that kind in config order with their
    logged results (nothing is computed: the sections format these numbers); empty without such studies
    """
    if not studies or not studies.get("studies"):
        return {}
    kinds = (studies.get("summary") or {}).get("skalka") or {}
    return {kind: [{"name": n, "r": studies["studies"][n]} for n in names] for kind, names in kinds.items()}
# --- large sweeps: their summary views instead of per-run figures (pipeline.sweep_summary) -----------

#: The rows of a summarised set's table the report prints (the whole table is the CSV beside the report).
SWEEP_PREVIEW_ROWS = 20


def sweep_views(sets: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The sets with each summarised set's summary attached (formatting only: every number is the summary's).

    A manifest set with a ``sweep`` entry (``{"summary": JSON path, "sweep_heatmaps": PNG,
    "sweep_dependence": PNG}``, :func:`pose_uncertainty.pipeline.sweep_summary.summarize_sweep`) gets
    ``sweep_summary`` (the JSON document), ``sweep_index_rows`` (one row per measure: its name, unit and
    per axis the first-order and total index), ``csv`` (the table's path relative to the report,
    ``tables/<set>.csv``) and ``preview`` (the first :data:`SWEEP_PREVIEW_ROWS` rows of its table).
    """
    out = []
    for s in sets:
        sweep = s.get("sweep")
        if not sweep:
            out.append(s)
            continue
        summary = _read_json(sweep["summary"])
        rows = [{"name": m["name"], "unit": m["unit"],
                 "indices": list(zip(m["first"], m["total"], strict=True))} for m in summary["measures"]]  # fmt: skip
        preview = read_table(s["table"])[:SWEEP_PREVIEW_ROWS] if Path(s["table"]).is_file() else []
        table = Path(s["table"])
        csv = "/".join(table.parts[1:]) if table.parts and table.parts[0] == "reports" else str(table)
        shown = [{"id": r.get("run"), "m": r} for r in preview]
        out.append({**s, "sweep_summary": summary, "sweep_index_rows": rows, "csv": csv, "preview": shown,
                    "summary_columns": _columns_with_data(shown, SUMMARY_COLUMNS)})  # fmt: skip
    return out


#: The folder beside the report that holds its companion pages: ``<set>.html`` per experiment set and
#: ``localization-<set>.html`` per localization set (set names have no hyphen: the two never collide).
RUNS_DIR = "runs"


def _relative(target: Path, start: Path) -> str:
    """``target`` as a link from a page in the folder ``start`` (forward slashes, as a URL)."""
    return Path(os.path.relpath(target.resolve(), start.resolve())).as_posix()


def write_run_pages(
    env: jinja2.Environment,
    sets: list[dict[str, Any]],
    localization_sets: list[dict[str, Any]],
    report: Path,
    folder: str | os.PathLike[str],
    *,
    title: str,
) -> dict[str, dict[str, Any]]:
    """Write the companion pages of the runs' figures into ``folder`` (replaced as a whole, atomically).

    One self-contained page (images inlined, the report's stylesheet, no network) per set whose runs have
    figures: ``<set>.html`` for an experiment set, ``localization-<set>.html`` for a localization set, with
    an experiment set's full table (``table-<set>``, template ``full_table.html.j2``: the report links it) and
    one anchor per run (``run-<set>-<run>``, ``loc-run-<set>-<run>``: the ids of the runs' entries in the
    report, which link to them) and links back to the report.

    Parameters
    ----------
    env : the report's Jinja2 environment (its ``img`` filter inlines the figures)
    sets : the experiment sets as the report has them (:func:`_sets`, :func:`sweep_views`)
    localization_sets : the localization sets (:func:`_localization`)
    report : path of the report the pages link back to
    folder : path of the pages' folder
    title : the report's title

    Returns
    -------
    dict — ``set name`` (``localization/<set>`` for a localization set) → ``{"href": the page relative to the
    report, "folder", "n_figures", "megabytes": its size}``, for the sets that have a page
    """
    folder = Path(folder)
    template = env.get_template("runs.html.j2")
    pages: dict[str, dict[str, Any]] = {}
    with atomic_directory(folder) as part:
        for s, localized in [*((s, False) for s in sets), *((s, True) for s in localization_sets)]:
            runs = [r for r in s["runs"] if r.get("figures")]
            if not runs:
                continue
            name = f"localization-{s['name']}.html" if localized else f"{s['name']}.html"
            back = f"localization-{s['name']}" if localized else f"set-{s['name']}"
            text = template.render(
                title=title, s=s, localization=localized, prefix="loc-run" if localized else "run", back=back,
                report=_relative(report, folder), lazy_script=LAZY_SCRIPT, script_hash=_csp_hash(LAZY_SCRIPT),
            )  # fmt: skip
            atomic_write_text(part / name, text)
            pages[f"localization/{s['name']}" if localized else s["name"]] = {
                "href": f"{_relative(folder, report.parent)}/{name}",
                "folder": _relative(folder, report.parent) + "/",
                "n_figures": sum(len(r["figures"]) for r in runs),
                "megabytes": len(text.encode("utf-8")) / 1e6,
            }
    return pages


def build_report(
    manifest: Mapping[str, Any],
    tables: Mapping[str, str | os.PathLike[str]],
    claims_path: str | os.PathLike[str],
    pipeline_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    title: str = "Pose uncertainty: three methods compared",
    config_text: str = "",
    studies_path: str | os.PathLike[str] | None = None,
    studies_figures: Mapping[str, str | os.PathLike[str]] | None = None,
    speed_dir: str | os.PathLike[str] | None = None,
    localization: Mapping[str, Any] | None = None,
    localization_tables: Mapping[str, str | os.PathLike[str]] | None = None,
    robots: list[Mapping[str, Any]] | None = None,
    runs_out: str | os.PathLike[str] | None = None,
) -> Path:
    """Render ``reports/comparison.html`` and its companion pages of the runs' figures (``reports/runs/``).

    The report holds every number, table, set and study figure; each run's figures are on the companion
    page of its set (:func:`write_run_pages`), which the run's entry in the report links to.

    Parameters
    ----------
    manifest : mapping — ``{"sets": [{name, title, source, description, figures, runs: [{id,
        log, swept, figures}]}], "config": {...}}`` (built by the workflow; ``swept`` names the keys a
        run's set sweeps — every parameter value the report prints is read from the run's table row,
        :func:`logged_params`; ``config`` is the pipeline config shown verbatim)
    tables : mapping of set name to its CSV (:func:`pose_uncertainty.pipeline.tables.collect_table`)
    claims_path : path — ``{"claims", "guide"}`` JSON (:func:`pose_uncertainty.pipeline.claims.write_claims`)
    pipeline_path : path — provenance, seeds and rule times (:func:`pose_uncertainty.pipeline.summary.summarize_pipeline`)
    out : path — the HTML file (self-contained: images inlined, no external resources)
    title : str
    config_text : str — the validated config as YAML (shown verbatim)
    studies_path : path, optional — :func:`pose_uncertainty.experiments.study.collect_studies` output
    studies_figures : mapping, optional — figures of the studies sections by kind; missing files are skipped
    speed_dir : path, optional — folder of the speed benchmarks' results (:func:`read_speed_results`)
    localization : mapping, optional — ``{"sets": [{name, title, source, description, table, figures,
        runs: [{id, log, swept, figures}]}]}``: the localization sets (section "From dead reckoning to
        localization"; its lead run is the first run of the first set)
    localization_tables : mapping, optional — ``localization/<set>`` (or ``<set>``) to its CSV
    robots : list, optional — the robots of the section "Your robot" with their output files
        (:func:`pose_uncertainty.present.robot_report.robot_section`)
    runs_out : path, optional — the folder of the companion pages, one per set with run figures (default
        :data:`RUNS_DIR` beside ``out``; replaced as a whole, :func:`write_run_pages`)

    Returns
    -------
    Path — ``out``
    """
    claims = _read_json(claims_path)
    pipeline = _read_json(pipeline_path)
    studies = _read_json(studies_path) or {"studies": None, "summary": {}}
    prov = pipeline["provenance"]
    sets = sweep_views(_sets(manifest, tables))
    loc = _localization(localization, localization_tables or {})
    env = _environment()
    encoded = _encode_all(_pngs(manifest, localization or {}, dict(studies_figures or {}), robots or []))
    env.filters["datauri"] = lambda path: _data_uri(path, encoded)
    env.filters["img"] = lambda path, alt, eager=False: _img(path, alt, env.filters["datauri"], eager=eager)
    p = Path(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    for s in [*sets, *(loc or {}).get("sets", [])]:  # each set's table (its runs' seeds), linked from the report
        s["table_href"] = _relative(Path(s["table"]), p.parent)
    # the companion pages first: the report never links to a page that is not there
    pages = write_run_pages(env, sets, (loc or {}).get("sets", []), p, p.parent / RUNS_DIR if runs_out is None else runs_out,
                            title=title)  # fmt: skip
    text = env.get_template("comparison.html.j2").render(
        title=title,
        sets=sets,
        drives=_drive_runs(sets),
        claims=claims["claims"],
        guide=claims["guide"],
        unscented=claims.get("unscented"),  # Method C: pipeline.method_guide.unscented_summary
        provenance=prov,
        machine_keys=MACHINE_KEYS,
        package=prov.get("package_version", {}).get("value", "unknown"),
        git_commit=prov.get("git_commit", {}).get("value", "unknown"),
        bench=pipeline["rule_times"]["rules"],
        bench_total=pipeline["rule_times"]["total_s"],
        n_logs=pipeline["n_logs"],
        speed=read_speed_results(speed_dir) if speed_dir is not None else [],
        config_text=config_text,
        generated=_dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        levels=COVERAGE_LEVELS,
        studies=studies["studies"],
        summary=studies["summary"],
        studies_figures={k: str(v) for k, v in (studies_figures or {}).items() if Path(v).is_file()},
        # the studies' whole results: the file beside the report, linked (every byte of the report is loaded
        # before its first paint; the results as JSON were a tenth of it)
        studies_href=_relative(Path(studies_path), p.parent) if studies_path is not None and Path(studies_path).is_file()
        else "",
        localization=loc,
        pages=pages,  # the companion pages of the runs' figures (write_run_pages)
        skalka=skalka_sections(studies),  # Skalka 2011's techniques (template skalka.html.j2)
        robots=robot_section(robots or []),  # the section "Your robot" (templates/robots.html.j2)
        references=[{"key": k, "entry": Markup(e)} for k, _, e in REFERENCES],
        lazy_script=LAZY_SCRIPT,
        script_hash=_csp_hash(LAZY_SCRIPT),
    )
    atomic_write_text(p, text)
    return p
