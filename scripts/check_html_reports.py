"""Run the bridge on a folder of logs and check every HTML page it writes in headless Chromium.

Usage (from the repository root)::

    PYTHONPATH=. python scripts/check_html_reports.py ../shared/data/logs --out /tmp/pages --jobs 2
    PYTHONPATH=. python scripts/check_html_reports.py --pages-only /tmp/pages   # pages already written
    PYTHONPATH=. python scripts/check_html_reports.py ../shared/data/logs --plotlyjs shared  # one plotly.min.js

The bridge (``gyrodenoise mavlink LOGS --out OUT --json``, the real CLI) writes one
``NAME.report.html`` per log and ``fleet.html`` for several; each page is opened from its
file in Debian's Chromium (Playwright, nothing downloaded) with every non-file request
refused and counted. One line per page: plots drawn / plots on the page, console and page
errors, refused requests, size, load time (navigation until every plot has drawn). A plot
counts as drawn when plotly rendered its SVG and at least one of its traces holds a point.

Exit status: 0 when every page passed; 1 when a page failed (a request, a console or page
error, a plot not drawn or empty, no page for a log the bridge processed, or a page that
did not finish drawing); 2 on bad usage. A log the bridge refuses (e.g. no gyro stream) has
no page: its line says REFUSED with the bridge's reason and does not fail the run unless
``--strict``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:          # run as a file: the tests' helpers live in the repository
    sys.path.insert(0, str(REPO))

from tests.flightlog.html_browser import CHROMIUM, CHROMIUM_ARGS, browser_missing  # noqa: E402

#: JavaScript: per plotly div its id, whether plotly drew it (and its zoom/hover toolbar), its trace
#: count and the points of its
#: visible traces (plotly's own ``_fullData``: the page's arrays are base64 typed-array specs)
PLOTS_JS = """() => Array.from(document.querySelectorAll('div.plotly-graph-div')).map(gd => {
  let points = 0;
  for (const tr of (gd._fullData || [])) {
    if (tr.visible === false) continue;
    if (typeof tr._length === 'number') points += tr._length;
    else if (tr.z && typeof tr.z.length === 'number') points += tr.z.length;
  }
  const t = gd.layout && gd.layout.title;
  return {id: gd.id, drawn: gd.querySelector('.main-svg') !== null, modebar: gd.querySelector('.modebar') !== null,
          traces: (gd._fullData || []).length, points: points,
          title: t ? (typeof t === 'string' ? t : (t.text || '')) : ''};
})"""

#: JavaScript: true once every plotly div on the page has its SVG
ALL_DRAWN_JS = ("() => { const d = document.querySelectorAll('div.plotly-graph-div'); "
                "return Array.from(d).every(g => g.querySelector('.main-svg') !== null); }")


def run_bridge(logs, out_dir, jobs=2, extra=()):
    """Run ``gyrodenoise mavlink LOGS --out OUT --json --jobs N``; returns (exit status, the
    JSON summary as a dict, or None where stdout held none, stderr's text)."""
    exe = Path(sys.executable).with_name("gyrodenoise")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "gyrodenoise.cli"]
    cmd += ["mavlink", *map(str, logs), "--out", str(out_dir), "--json", "--jobs", str(jobs),
            "--no-progress", *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    try:
        summary = json.loads(proc.stdout)
    except json.JSONDecodeError:
        summary = None
    return proc.returncode, summary, proc.stderr


def _refuser(refused):
    """A Playwright route handler: file, data and blob URLs go through, any other request
    is aborted and its URL appended to ``refused``; returns the handler."""
    def route(r):
        if r.request.url.startswith(("file:", "data:", "blob:")):
            r.continue_()
        else:
            refused.append(r.request.url)
            r.abort()
    return route


def check_pages(pages, timeout_s=60.0, screenshot_dir=None):
    """Open each HTML page in one headless Chromium; returns one dict per page: ``page``,
    ``size_mb``, ``load_s`` (navigation until every plot drew; None if it never did),
    ``requests`` (URLs refused), ``console_errors``, ``page_errors``, ``plots`` (per plot
    div: ``id``, ``drawn``, ``modebar``, ``traces``, ``points``, ``title``), ``error`` (why the check
    stopped, or None). With ``screenshot_dir`` a full-page PNG of each is saved there."""
    from playwright.sync_api import Error as PlaywrightError
    from playwright.sync_api import sync_playwright
    results = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            for html in pages:
                html = Path(html)
                res = {"page": str(html), "size_mb": html.stat().st_size / 1e6, "load_s": None, "requests": [],
                       "console_errors": [], "page_errors": [], "plots": [], "error": None}
                ctx = browser.new_context(viewport={"width": 1300, "height": 900})
                page = ctx.new_page()

                page.route("**/*", _refuser(res["requests"]))
                page.on("console", lambda m, res=res: res["console_errors"].append(m.text)
                        if m.type == "error" else None)
                page.on("pageerror", lambda e, res=res: res["page_errors"].append(str(e)))
                try:
                    t0 = time.perf_counter()
                    page.goto(html.resolve().as_uri(), wait_until="load", timeout=timeout_s * 1000)
                    page.wait_for_function(ALL_DRAWN_JS, timeout=timeout_s * 1000)
                    res["load_s"] = time.perf_counter() - t0
                    res["plots"] = page.evaluate(PLOTS_JS)
                    if screenshot_dir:
                        Path(screenshot_dir).mkdir(parents=True, exist_ok=True)
                        page.screenshot(path=str(Path(screenshot_dir) / (html.stem + ".png")), full_page=True)
                except PlaywrightError as exc:
                    res["error"] = str(exc).splitlines()[0]
                finally:
                    ctx.close()
                results.append(res)
        finally:
            browser.close()
    return results


def page_failures(res):
    """What is wrong with one checked page (``check_pages``'s dict): a list of short
    phrases, empty when the page passed."""
    bad = []
    if res["error"]:
        bad.append(f"check stopped: {res['error']}")
    if res["requests"]:
        bad.append(f"{len(res['requests'])} network request(s), first {res['requests'][0]}")
    if res["console_errors"]:
        bad.append(f"console error: {res['console_errors'][0][:120]}")
    if res["page_errors"]:
        bad.append(f"page error: {res['page_errors'][0][:120]}")
    if not res["error"] and not res["plots"]:
        bad.append("no plot on the page")
    for pl in res["plots"]:
        if not pl["drawn"]:
            bad.append(f"plot {pl['title'] or pl['id']!r} not drawn")
        elif not pl["modebar"]:
            bad.append(f"plot {pl['title'] or pl['id']!r} has no zoom/hover toolbar")
        elif pl["points"] == 0:
            bad.append(f"plot {pl['title'] or pl['id']!r} drawn empty")
    return bad


def page_line(name, res):
    """One line of the run's output for a checked page: verdict, name, plots, errors,
    requests, size and load time."""
    bad = page_failures(res)
    drawn = sum(1 for pl in res["plots"] if pl["drawn"] and pl["points"] > 0)
    load = f"{res['load_s']:.2f} s" if res["load_s"] is not None else "-"
    line = (f"{'FAIL' if bad else 'ok  '} {name:40s} plots {drawn:2d}/{len(res['plots']):<2d} "
            f"console {len(res['console_errors']) + len(res['page_errors'])}  requests {len(res['requests'])}  "
            f"{res['size_mb']:5.2f} MB  load {load}")
    return line + (f"  <- {'; '.join(bad)}" if bad else "")


def main(argv=None):
    """Run the bridge on the logs, check every page in Chromium, print one line per log;
    returns the exit status (0 all pages passed, 1 a failure, 2 bad usage)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("logs", nargs="+", help="log files or folders (as the bridge takes them); with "
                    "--pages-only, folders of pages already written")
    ap.add_argument("--out", help="output folder of the bridge (default: a temporary folder, removed)")
    ap.add_argument("--jobs", type=int, default=2, help="logs processed in parallel by the bridge (default 2)")
    ap.add_argument("--pages-only", action="store_true", help="do not run the bridge: check every *.html "
                    "in the folders given")
    ap.add_argument("--screenshots", metavar="DIR", help="save a full-page PNG of each page in DIR")
    ap.add_argument("--strict", action="store_true", help="a log the bridge refuses fails the run too")
    ap.add_argument("--timeout-s", type=float, default=60.0, help="per page, to load and draw (default 60)")
    ap.add_argument("--json", metavar="FILE", help="write every page's full check result to FILE")
    ap.add_argument("--plotlyjs", choices=["inline", "shared"], default="inline",
                    help="the bridge's --plotlyjs: each page holds plotly.js (inline, default) or they share "
                         "one plotly.min.js in the output folder (shared)")
    a = ap.parse_args(argv)
    why = browser_missing()
    if why:
        print(f"check_html_reports: {why}", file=sys.stderr)
        return 2
    for p in a.logs:
        if not Path(p).exists():
            print(f"check_html_reports: {p}: no such file or folder", file=sys.stderr)
            return 2
    tmp = None
    failed = False
    named = []              # (name, page path or None, reason when no page)
    if a.pages_only:
        for p in a.logs:
            p = Path(p)
            named += [(h.name, h, None) for h in (sorted(p.glob("*.html")) if p.is_dir() else [p])]
    else:
        if a.out:
            out = Path(a.out)
        else:
            tmp = tempfile.TemporaryDirectory(prefix="check_html_reports-")
            out = Path(tmp.name)
        t0 = time.perf_counter()
        rc, summary, err = run_bridge(a.logs, out, a.jobs, extra=("--plotlyjs", a.plotlyjs))
        print(f"bridge: exit {rc} in {time.perf_counter() - t0:.1f} s, output {out}")
        if summary is None or "logs" not in summary:
            print(f"FAIL the bridge wrote no JSON summary: {(err.strip().splitlines() or ['?'])[-1]}")
            return 1
        for rep in summary["logs"]:
            page = rep.get("report_html")
            named.append((Path(rep["file"]).name, Path(page) if page else None,
                          None if page else "the bridge processed it but wrote no report_html"))
        for f in summary.get("failed", []):
            named.append((Path(f["file"]).name, None, "REFUSED " + f["error"].split(": ", 1)[-1]))
        fleet = [p for p in summary.get("fleet_report") or [] if str(p).endswith(".html")]
        named += [("(fleet) " + Path(p).name, Path(p), None) for p in fleet]
    try:
        pages = [p for _, p, _ in named if p is not None and p.exists()]
        results = {r["page"]: r for r in check_pages(pages, a.timeout_s, a.screenshots)}
        n_ok = n_pages = 0
        for name, page, reason in sorted(named, key=lambda x: (x[0].startswith("(fleet)"), x[0])):
            if page is None or not page.exists():
                reason = reason or f"page {page} missing"
                refused = reason.startswith("REFUSED")
                failed |= (not refused) or a.strict
                print(f"{'FAIL' if (not refused) or a.strict else '--  '} {name:40s} no page: {reason}")
                continue
            res = results[str(page)]
            n_pages += 1
            n_ok += not page_failures(res)
            failed |= bool(page_failures(res))
            print(page_line(name, res))
        print(f"{n_ok} of {n_pages} page(s) passed")
        if a.json:
            Path(a.json).write_text(json.dumps(list(results.values()), indent=1))
    finally:
        if tmp is not None:
            tmp.cleanup()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
