"""The fleet trend pages in a real browser: Debian's Chromium driven by Playwright, offline.

A synthetic fleet (a steady airframe, one whose vibration and line grow, and a folder
mixing two aircraft) is written as trend pages with plotly.js shared beside them; the
index and each airframe page are loaded from files with every other request refused
(none may be made) and must log no console or page error; each plot must be drawn by
plotly with the traces its trend has (the series with one point per log, the
history's band, the flagged logs, the CUSUM; the series alone where not trended).
Skips with the reason where Chromium or Playwright is absent."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.flightlog.html_browser import CHROMIUM, CHROMIUM_ARGS, browser_missing

pytest.importorskip("pyarrow")
pytest.importorskip("duckdb")
pytest.importorskip("plotly")

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing()))]

#: per plot: its id, the traces plotly holds, the traces it drew, the first trace's points drawn
_PLOTS_JS = """() => Array.from(document.querySelectorAll('.js-plotly-plot')).map(gd => ({
    id: gd.id, traces: gd.data.length, drawn: gd.querySelectorAll('.scatterlayer .trace').length,
    points: gd.querySelectorAll('.scatterlayer .trace')[0].querySelectorAll('.point').length,
    svg: gd.querySelector('.main-svg') !== null}))"""


def open_pages(paths, screenshot=None):
    """Load each page in headless Chromium (file: only). Returns {page name: {"requests",
    "errors" (console and page errors), "plots" (:data:`_PLOTS_JS`), "rows" (the first
    table's rows as text)}}; ``screenshot``: (page name, PNG path) of one page's first screen."""
    from playwright.sync_api import sync_playwright
    out = {}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            for path in paths:
                page = browser.new_page(viewport={"width": 1300, "height": 900})
                got = {"requests": [], "errors": []}

                def route(r, got=got):
                    if r.request.url.startswith("file:"):
                        r.continue_()
                    else:
                        got["requests"].append(r.request.url)
                        r.abort()

                page.route("**/*", route)
                page.on("console", lambda m, got=got: got["errors"].append(m.text) if m.type == "error" else None)
                page.on("pageerror", lambda e, got=got: got["errors"].append(str(e)))
                page.goto(Path(path).resolve().as_uri(), wait_until="load")
                page.wait_for_function("() => Array.from(document.querySelectorAll('.plotly-graph-div'))"
                                       ".every(d => d.querySelector('.main-svg'))", timeout=30000)
                got["plots"] = page.evaluate(_PLOTS_JS)
                got["rows"] = page.evaluate("() => Array.from(document.querySelectorAll('table tr'))"
                                            ".map(r => r.innerText)")
                if screenshot and screenshot[0] == Path(path).name:
                    page.screenshot(path=str(screenshot[1]))
                out[Path(path).name] = got
                page.close()
        finally:
            browser.close()
    return out


def trend_pages(tmp_path):
    """(trends, page paths) of the synthetic fleet of the module's docstring."""
    from gyrodenoise.flightlog import trends as tr
    from tests.flightlog.test_trends import _fleet, _folder_fleet
    store = _fleet(tmp_path, n_logs=10, onset=5)
    _folder_fleet(tmp_path, "shared-logs", [("ardupilot", "ArduCopter", "CUAVv5", "QUAD/X"),
                                            ("px4", "PX4 quadrotor", "PX4_FMU_V6C", None)], n_logs=6)
    found = tr.trends(store)
    return found, tr.write_pages(found, tmp_path / "pages", plotlyjs="shared")


def test_trend_pages_draw_offline(tmp_path):
    found, paths = trend_pages(tmp_path)
    res = open_pages(paths)
    assert set(res) == {"index.html", "airframe-AF-drift.html", "airframe-AF-steady.html",
                        "airframe-shared-logs.html"}
    for name, got in res.items():
        assert got["requests"] == [], (name, got["requests"][:5])
        assert got["errors"] == [], (name, got["errors"])
    index = res["index.html"]
    assert index["plots"] == []
    rows = {r.split("\t")[0]: r for r in index["rows"][1:]}
    assert rows["AF-drift"].split("\t")[2].startswith("GROWTH: vibration from AF-drift-")
    assert rows["AF-steady"].split("\t")[2] == "steady"
    assert rows["shared-logs"].split("\t")[2] == "not trended" and "of different aircraft" in rows["shared-logs"]
    for airframe in ("AF-drift", "AF-steady", "shared-logs"):
        ts = [t for t in found if t.airframe == airframe]
        plots = res[f"airframe-{airframe}.html"]["plots"]
        assert len(plots) == len(ts) > 0
        for t, plot in zip(ts, plots):
            # the series, then (trended) the band's two edges, the flagged logs where any, the CUSUM
            want = 1 if not t.trended else 4 + any(t.detection.flagged)
            assert plot["svg"] and plot["traces"] == plot["drawn"] == want, (airframe, t.metric, plot)
            assert plot["points"] == len(t.points), (airframe, t.metric, plot)
    assert any(t.status == "growth" for t in found if t.airframe == "AF-drift")
