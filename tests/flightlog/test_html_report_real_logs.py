"""Real logs' HTML reports through the real pipeline, in a real browser.

One DataFlash log, one ULog and one telemetry log from ../shared/data go through
:func:`gyrodenoise.flightlog.pipeline.process_log` (the bridge's own step, PNG plots and
the HTML report on, no CSV); the three pages it writes (``report_html``) are opened in one
Debian Chromium offline by scripts/check_html_reports.py's ``check_pages`` (every
non-file request refused; one browser for the three pages: a launch and plotly's parse
cost 4-6 s a page here, tests/flightlog/html_browser.py's ``check_page`` launches one per
page) and must make no request, log no console or page error, and draw every plot with
plotly's toolbar and at least one point. Skips with the reason where Chromium,
Playwright or the shared logs are absent."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from tests.helpers import REPO, SHARED_LOGS
from tests.flightlog.html_browser import browser_missing

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing()))]

#: (log, what it is, the fewest plots its page draws): the time plot of each stream, then
#: spectra / spectrogram / filter review where the log has a fast stream
LOGS = [
    ("copter_00000-2021-12-02_13-34-15.bin", "DataFlash, ArduCopter 4.1, IMU at 25 Hz, flies 19 s", 3),
    ("px4_vtol_small.ulg", "ULog, PX4 VTOL, sensor_combined at 205 Hz, a filter review", 4),
    ("fs-batt.log.tlog", "telemetry log, Copter 3.4, RAW_IMU at 2.4 Hz", 1),
]


def _checker():
    """scripts/check_html_reports.py as a module (scripts/ is not a package)."""
    spec = importlib.util.spec_from_file_location("check_html_reports", REPO / "scripts" / "check_html_reports.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def pages(tmp_path_factory):
    """{log name: (its report, its page's check result or None)}; each log processed once
    and the pages checked in one browser."""
    from gyrodenoise.flightlog.pipeline import process_log
    out = tmp_path_factory.mktemp("real_pages")
    reports = {name: process_log(SHARED_LOGS / name, out, plots=True, csv=False)
               for name, _, _ in LOGS if (SHARED_LOGS / name).exists()}
    chk = _checker()
    results = {r["page"]: r for r in chk.check_pages([r["report_html"] for r in reports.values()
                                                      if r.get("report_html")])}
    return {name: (rep, results.get(str(rep.get("report_html"))), chk) for name, rep in reports.items()}


@pytest.mark.parametrize("name,what,n_plots_min", LOGS, ids=[n for n, _, _ in LOGS])
def test_real_log_page_draws_offline(pages, name, what, n_plots_min):
    if name not in pages:
        pytest.skip(f"third-party log not present: {SHARED_LOGS / name} (licence forbids copying it "
                    f"into the repo)")
    rep, res, chk = pages[name]
    assert rep.get("report_html"), f"{name} ({what}): process_log wrote no HTML report"
    page = Path(rep["report_html"])
    assert page.is_file() and page.name == Path(name).stem + ".report.html", page
    assert chk.page_failures(res) == [], chk.page_line(name, res)
    assert res["requests"] == [] and res["console_errors"] == [] and res["page_errors"] == [], res
    assert len(res["plots"]) >= n_plots_min, (name, [p["title"] for p in res["plots"]])
    assert all(p["drawn"] and p["modebar"] and p["points"] > 0 for p in res["plots"]), res["plots"]
    text = page.read_text()
    assert "<script src" not in text and "<link" not in text, f"{name}: the page loads something from outside"
    for key in ("segments", "vehicle_filters", "filter_review", "vibration"):
        assert key in rep, f"{name}: the report lacks {key!r} (spec section 8)"
