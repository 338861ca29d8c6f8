"""The report in a browser, measured: Lighthouse on ``reports/comparison.html`` (``make bench-report``).

Serves the report's folder from 127.0.0.1 with Python's ``http.server`` (on a free port, in a
thread), runs Lighthouse (npm ``lighthouse``, exactly the version pinned in
``benchmarks/lighthouse/package.json`` and its lock file) with Debian's Chromium
(``CHROME_PATH``, default ``/usr/bin/chromium``; flags ``--headless --no-sandbox --disable-gpu``)
once with the desktop preset and once with the default mobile one, and writes the category
scores, the paint timings and the page's weight to ``benchmarks/results/report.json`` (which the
report's "Speed benchmarks" section shows on its next build).

Usage: ``python -m benchmarks.report_lighthouse [REPORT.html] [--name report] [--runs 3] [--gzip]``. Timings
depend on the machine and on what else runs on it: the machine is recorded with them, and with each
preset the load average over the last minute before each run (``load_average_1min``, their mean) and
every run's performance score; the other numbers are those of the run of median performance.

What sets the timings: Lighthouse simulates a throttled network (desktop ~10 Mbit/s, mobile
~1.6 Mbit/s) and counts the whole HTML document before the first paint, however early in it the
first screen is: a document of N MB costs about 0.8·N s on the desktop preset and 5·N s on the
mobile one (a 3 MB page holding one heading and a <template> of 3 MB measured 2.6 s on the desktop).
Hence the report holds no run's figures: they are on its companion pages (``runs/<set>.html``).

``--gzip`` serves the HTML pages gzip-compressed (``Content-Encoding: gzip``, as any static web host
does) to a client that accepts it; Lighthouse then counts the compressed bytes. The results record
how the page was served (``content_encoding``) and the bytes sent (``transfer_MB``).
"""

from __future__ import annotations

import argparse
import functools
import gzip
import http.server
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any, ClassVar

from benchmarks._common import write_results

HERE = Path(__file__).resolve().parent / "lighthouse"
LIGHTHOUSE = HERE / "node_modules" / ".bin" / "lighthouse"
CHROME_FLAGS = "--headless --no-sandbox --disable-gpu"

#: audit id -> (result key, factor): timings in s (Lighthouse gives ms), weights in MB
AUDITS = {
    "first-contentful-paint": ("first_contentful_paint_s", 1e-3),
    "largest-contentful-paint": ("largest_contentful_paint_s", 1e-3),
    "speed-index": ("speed_index_s", 1e-3),
    "interactive": ("time_to_interactive_s", 1e-3),
    "total-blocking-time": ("total_blocking_time_s", 1e-3),
    "cumulative-layout-shift": ("cumulative_layout_shift", 1.0),
    "total-byte-weight": ("page_weight_MB", 1e-6),  # bytes sent: compressed when served with --gzip
    "dom-size": ("dom_elements", 1.0),
}


class _Quiet(http.server.SimpleHTTPRequestHandler):
    """The static file server, without a log line per request."""

    def log_message(self, format: str, *args: Any) -> None:
        pass


class _Gzip(_Quiet):
    """The static file server sending an HTML page gzip-compressed (level 6, as web servers default to) to a
    client that accepts it; anything else as it is. The compressed pages are made once per path."""

    cache: ClassVar[dict[str, bytes]] = {}

    def do_GET(self) -> None:
        path = self.translate_path(self.path)
        accepts = "gzip" in self.headers.get("Accept-Encoding", "")
        if not (accepts and path.endswith(".html") and os.path.isfile(path)):
            super().do_GET()
            return
        if path not in self.cache:
            with open(path, "rb") as f:
                self.cache[path] = gzip.compress(f.read(), compresslevel=6, mtime=0)
        body = self.cache[path]
        self.send_response(200)
        self.send_header("Content-Type", "text/html; charset=utf-8")
        self.send_header("Content-Encoding", "gzip")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)


def _version() -> str:
    lock = json.loads((HERE / "package-lock.json").read_text(encoding="utf-8"))
    return str(lock["packages"]["node_modules/lighthouse"]["version"])


def summarize(lhr: dict[str, Any]) -> dict[str, Any]:
    """The scores (0–1) of the four categories, the timings [s], the weight [MB] and the DOM size of one run,
    with the audits that failed (score < 0.9) by id."""
    out: dict[str, Any] = {f"score_{k.replace('-', '_')}": v.get("score") for k, v in lhr["categories"].items()}
    for audit, (key, factor) in AUDITS.items():
        value = lhr["audits"].get(audit, {}).get("numericValue")
        out[key] = None if value is None else value * factor
    failed = sorted(k for k, a in lhr["audits"].items()
                    if a.get("score") is not None and a.get("scoreDisplayMode") in ("binary", "numeric") and a["score"] < 0.9)  # fmt: skip
    out["failed_audits"] = ", ".join(failed)
    return out


#: The categories measured; ``--performance-only`` keeps the first (the others read the page's whole
#: body over DevTools, which times out on a large page on a loaded machine).
CATEGORIES = ("performance", "accessibility", "best-practices", "seo")


def run(report: Path, preset: str, port: int, chrome: str, categories: tuple[str, ...] = CATEGORIES) -> dict[str, Any]:
    """One Lighthouse run (``preset``: "desktop" or "mobile") on the served report; its summary."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "lhr.json"
        cmd = [str(LIGHTHOUSE), f"http://127.0.0.1:{port}/{report.name}", "--output=json", f"--output-path={out}",
               f"--chrome-flags={CHROME_FLAGS}", "--quiet", f"--only-categories={','.join(categories)}",
               "--max-wait-for-load=120000"]  # fmt: skip
        if preset == "desktop":
            cmd.append("--preset=desktop")
        proc = subprocess.run(cmd, env={**os.environ, "CHROME_PATH": chrome}, capture_output=True, text=True,
                              check=False, timeout=900)  # fmt: skip
        if proc.returncode != 0 or not out.is_file():
            raise SystemExit(f"lighthouse failed ({preset}, exit {proc.returncode}): {proc.stderr.strip()[-400:]}")
        return summarize(json.loads(out.read_text(encoding="utf-8")))


def _median_of(report: Path, preset: str, port: int, chrome: str, n: int,
               categories: tuple[str, ...] = CATEGORIES) -> dict[str, Any]:  # fmt: skip
    """``n`` runs of one preset: the run of median performance, with every run's score and the mean load."""
    runs, loads = [], []
    failures = 0
    while len(runs) < n:
        loads.append(os.getloadavg()[0])
        try:
            runs.append(run(report, preset, port, chrome, categories))
        except SystemExit as exc:  # a DevTools timeout under load: try again, at most n times in all
            failures += 1
            print(f"{preset}: {exc}; {'giving up' if failures >= n else 'again'}", file=sys.stderr)
            if failures >= n:
                raise
            loads.pop()
    ranked = sorted(runs, key=lambda r: r.get("score_performance") or 0.0)
    return {**ranked[(n - 1) // 2], "runs": n, "load_average_1min": sum(loads) / n,
            "score_performance_runs": ", ".join(f"{r.get('score_performance')}" for r in runs)}  # fmt: skip


def main(argv: list[str] | None = None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report", nargs="?", default="reports/comparison.html")
    ap.add_argument("--name", default="report", help="results file benchmarks/results/<name>.json")
    ap.add_argument("--performance-only", action="store_true",
                    help="measure the performance category only (the others time out on a large page under load)")
    ap.add_argument("--runs", type=int, default=3, help="Lighthouse runs per preset (the median is kept; default 3)")
    ap.add_argument("--gzip", action="store_true",
                    help="serve the HTML gzip-compressed (Content-Encoding: gzip), as a static web host does")
    args = ap.parse_args(argv)
    if args.runs < 1:
        raise SystemExit(f"--runs must be at least 1, got {args.runs}")
    report = Path(args.report).resolve()
    chrome = os.environ.get("CHROME_PATH", "/usr/bin/chromium")
    if not report.is_file():
        raise SystemExit(f"no report at {report}: build it first (make report)")
    if not LIGHTHOUSE.is_file():
        raise SystemExit(f"lighthouse is not installed in {HERE}: run `npm ci --prefix {HERE}` (make bench-report does)")
    if not shutil.which(chrome):
        raise SystemExit(f"no Chromium at {chrome}: apt-get install -y chromium, or set CHROME_PATH")
    handler = _Gzip if args.gzip else _Quiet
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(handler, directory=str(report.parent)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        port = server.server_address[1]
        categories = CATEGORIES[:1] if args.performance_only else CATEGORIES
        results = {preset: _median_of(report, preset, port, chrome, args.runs, categories)
                   for preset in ("desktop", "mobile")}  # fmt: skip
    finally:
        server.shutdown()
    data = report.read_bytes()
    for preset, r in results.items():
        r["report_MB"] = len(data) / 1e6
        r["content_encoding"] = "gzip" if args.gzip else "identity"
        r["transfer_MB"] = len(gzip.compress(data, compresslevel=6, mtime=0) if args.gzip else data) / 1e6
        r["lighthouse"] = _version()
        print(preset, json.dumps(r, indent=1), file=sys.stderr)
    return write_results(args.name, results)


if __name__ == "__main__":
    print(main())
