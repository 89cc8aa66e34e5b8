"""The HTML reports in a real browser: Debian's Chromium driven by Playwright, offline.

Each page is loaded from a file with every other request refused (and none may be
made), and must draw every plot (plotly's ``.main-svg``, a screenshot of each plot
that is not blank), offer zoom and hover (plotly's modebar) and log no console error.
Skips with the reason where Chromium or Playwright is absent."""
import json
from pathlib import Path

import pytest

from tests.helpers import SHARED_LOGS
from tests.flightlog.html_browser import browser_missing, check_page, real_log_report, synthetic_report

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing()))]


def _assert_page_ok(res, n_plots_min):
    assert res["requests"] == [], f"the page asked the network for {res['requests'][:5]}"
    assert res["console_errors"] == [] and res["page_errors"] == [], (res["console_errors"], res["page_errors"])
    assert len(res["plots"]) >= n_plots_min, res["plots"]
    for p in res["plots"]:
        assert p["main_svg"], f"{p['id']}: plotly drew nothing"
        assert p["modebar"], f"{p['id']}: no zoom/hover toolbar"
        assert p["colours"] > 1, f"{p['id']}: the plot's region is blank"


def test_synthetic_log_report_draws_offline(tmp_path):
    from gyrodenoise.flightlog.html_report import write_log_report
    rep, series = synthetic_report(tmp_path)
    path = write_log_report(tmp_path / "synthetic.report.html", rep, series)
    text = path.read_text()
    assert "<script src" not in text and "<link" not in text and "@import" not in text
    assert text.count("Plotly.newPlot") >= 6
    # 2 time plots, spectrum, spectrogram, filter review, vibration
    _assert_page_ok(check_page(path), 6)


def test_real_log_report_draws_offline(tmp_path):
    from gyrodenoise.flightlog.html_report import write_log_report
    log = SHARED_LOGS / "log171.bin"
    if not log.exists():
        pytest.skip(f"third-party log not present: {log}")
    rep, series = real_log_report(log, tmp_path)
    path = write_log_report(tmp_path / "log171.report.html", rep, series)
    # 3 streams of 240 s at 50 Hz: their time series, spectra and one spectrogram
    assert path.stat().st_size < 8e6
    _assert_page_ok(check_page(path), 7)


def test_fleet_report_links_each_log_and_draws(tmp_path):
    from gyrodenoise.flightlog.html_report import write_fleet_report, write_log_report
    rep, series = synthetic_report(tmp_path)
    logs = []
    for name in ("a", "b"):
        r = dict(rep, file=str(tmp_path / f"{name}.bin"))
        r["report_html"] = str(write_log_report(tmp_path / "logs" / f"{name}.report.html", r, series))
        logs.append(r)
    rows = [{"log": f"{n}.bin", "file": str(tmp_path / f"{n}.bin"), "stream": "IMU[0]", "status": "ok",
             "compared_as": "IMU[0]", "rate_hz": 400.0, "noise_raw": 0.8, "noise_filtered": 0.2,
             "noise_density_deg_s_rthz": d, "flag": d > 0.1} for n, d in (("a", 0.05), ("b", 0.2))]
    rows.append({"log": "c.bin", "file": str(tmp_path / "c.bin"), "stream": "", "status": "failed",
                 "error": "c.bin: no gyro stream"})
    path = write_fleet_report(tmp_path / "fleet.html", {"rows": rows, "n_logs": 3, "n_ok": 2, "n_failed": 1},
                              logs)
    text = path.read_text()
    assert "href='logs/a.report.html'" in text and "href='logs/b.report.html'" in text
    res = check_page(path)
    _assert_page_ok(res, 1)
    json.dumps(res)                                       # plain data (a failing run prints it)
    assert Path(tmp_path / "logs" / "a.report.html").is_file()


def test_betaflight_overview_and_step_response_draw(tmp_path):
    """LOG00037 (Betaflight, 1 kHz setpoint and gyroADC): the overview opens the page and
    the step response plot is drawn with the others."""
    from gyrodenoise.flightlog.html_report import write_log_report
    log = SHARED_LOGS / "betaflight" / "LOG00037.BFL"
    if not log.exists():
        pytest.skip(f"third-party log not present: {log}")
    rep, series = real_log_report(log, tmp_path)
    path = write_log_report(tmp_path / "LOG00037.report.html", rep, series)
    text = path.read_text()
    assert text.index("<h2 id=overview>") < text.index("<h2 id=summary>") < text.index("<h2 id=step>")
    assert "HBRO KAKUTEF7" in text[:text.index("<h2 id=summary>")]
    assert text[text.index("<h2 id=step>"):text.index("<h2 id=vibration>")].count("Plotly.newPlot") == 1
    res = check_page(path)
    _assert_page_ok(res, text.count("Plotly.newPlot"))              # every plot drawn, the step response's too


def test_pages_sharing_one_plotlyjs_draw_offline(tmp_path):
    """--plotlyjs shared: a log's page in a sub-folder and the fleet page refer to one
    plotly.min.js by relative addresses; each loads it from its file (no other request),
    draws every plot and logs no error."""
    from gyrodenoise.flightlog.html_report import write_fleet_report, write_log_report, write_shared_plotlyjs
    rep, series = synthetic_report(tmp_path)
    js = write_shared_plotlyjs(tmp_path)
    log_page = write_log_report(tmp_path / "logs" / "a.report.html", dict(rep, file=str(tmp_path / "a.bin")),
                                series, plotlyjs=js)
    rows = [{"log": "a.bin", "file": str(tmp_path / "a.bin"), "stream": "IMU[0]", "status": "ok",
             "compared_as": "IMU[0]", "rate_hz": 400.0, "noise_raw": 0.8, "noise_filtered": 0.2,
             "noise_density_deg_s_rthz": 0.05, "flag": False}]
    fleet = write_fleet_report(tmp_path / "fleet.html", {"rows": rows, "n_logs": 1, "n_ok": 1, "n_failed": 0},
                               [dict(rep, file=str(tmp_path / "a.bin"), report_html=str(log_page))], plotlyjs=js)
    assert log_page.stat().st_size < 0.5 * js.stat().st_size
    text = log_page.read_text()
    _assert_page_ok(check_page(log_page), text.count("Plotly.newPlot"))
    _assert_page_ok(check_page(fleet), 1)
