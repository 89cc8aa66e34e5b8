"""Helpers of the HTML report's browser test: a synthetic log's report and series, a real
log's through the bridge's steps, and a check of a report page in headless Chromium
(Playwright, Debian's /usr/bin/chromium, nothing downloaded, every network request
refused and counted).

The docs' screenshot comes from here (docs/logs/report.md)::

    PYTHONPATH=. python -m tests.flightlog.html_browser ../shared/data/logs/log171.bin \\
        --out /tmp/report171 --screenshot docs/img/html_report_log171.png
"""

from __future__ import annotations

import argparse
import os
import shutil
from pathlib import Path

import numpy as np

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


def browser_missing():
    """Why the browser test cannot run here (a sentence), or None."""
    if not (os.path.exists(CHROMIUM) or shutil.which("chromium")):
        return f"Chromium not installed ({CHROMIUM}; apt-get install chromium)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright Python package is not installed (pip install playwright)"
    return None


def synthetic_report(out_dir, seconds=60.0, rate_hz=400.0, seed=3):
    """(report, series) of a synthetic log: one stream at ``rate_hz`` (slow motion, white
    noise, an 80 Hz vibration with its harmonic, one restart), a second written raw, a
    vehicle rate, segments, vehicle filters, a filter review and vibration levels: every
    section of the page has something to draw."""
    from gyrodenoise.flightlog.spectra import stream_spectrum
    from gyrodenoise.flightlog.streams import GyroStream
    from gyrodenoise.flightlog.html_report import stream_series
    from gyrodenoise.flightlog.vehicle_filters import vehicle_filters
    from gyrodenoise.flightlog.autopilots import named
    rng = np.random.default_rng(seed)
    n = int(seconds * rate_hz)
    t = 10.0 + np.arange(n) / rate_hz
    motion = 20.0 * np.sin(2 * np.pi * 0.3 * t)[:, None] * np.array([1.0, 0.6, 0.2])
    vib = 1.5 * np.sin(2 * np.pi * 80.0 * t)[:, None] + 0.5 * np.sin(2 * np.pi * 160.0 * t)[:, None]
    raw = motion + vib + rng.normal(0, 0.8, (n, 3))
    from scipy.signal import butter, sosfiltfilt
    filt = sosfiltfilt(butter(4, 30.0, fs=rate_hz, output="sos"), raw, axis=0)
    restarts = np.zeros(n, dtype=bool)
    restarts[n // 2] = True
    s = GyroStream(name="IMU[0]", message="IMU", unit="rad/s", to_deg_s=57.29577951308232, time_s=t,
                   raw=raw / 57.29577951308232, index=np.arange(n), rate_hz=rate_hz, restarts=restarts)
    s.filtered = filt / 57.29577951308232
    s._work = (raw, filt, "deg/s", rate_hz)
    s.warmup_samples = 40
    spec, pd = stream_spectrum(s, raw, filt, "deg/s", rate_hz, "lowpass", {"cutoff_hz": 30.0}, 40)
    slow_t = 10.0 + np.arange(int(seconds * 4)) / 4.0
    slow = GyroStream(name="RAW_IMU", message="RAW_IMU", unit="mrad/s", to_deg_s=0.0572957795,
                      time_s=slow_t, raw=rng.normal(0, 10, (len(slow_t), 3)), index=np.arange(len(slow_t)),
                      rate_hz=4.0, restarts=np.zeros(len(slow_t), dtype=bool))
    slow._work = (slow.raw * slow.to_deg_s, slow.raw * slow.to_deg_s, "deg/s", 4.0)
    segments = [{"kind": "ground", "start_s": 10.0, "end_s": 18.0},
                {"kind": "armed", "start_s": 18.0, "end_s": 22.0},
                {"kind": "flying", "start_s": 22.0, "end_s": 62.0},
                {"kind": "hover", "start_s": 30.0, "end_s": 45.0},
                {"kind": "ground", "start_s": 62.0, "end_s": 10.0 + seconds}]
    report = {
        "file": str(Path(out_dir) / "synthetic.bin"), "format": "dataflash", "engine": "native",
        "method": "lowpass", "form": "offline", "form_note": "synthetic", "seconds": 0.1,
        "streams": [{"name": "IMU[0]", "rate_hz": rate_hz, "samples": n, "restarts": 1, "noise_unit": "deg/s",
                     "noise": {a: {"raw": 0.8, "filtered": 0.2, "ratio": 0.25} for a in "xyz"},
                     "spectrum": spec, "stage": "pre-filter", "warnings": []},
                    {"name": "RAW_IMU", "rate_hz": 4.0, "samples": len(slow_t), "restarts": 0,
                     "noise_unit": "deg/s", "too_slow_to_denoise": True,
                     "spectrum": {"available": False, "reason": "sampled at 4 Hz"},
                     "slow_note": "sampled at 4 Hz: written raw"}],
        "restarts": [{"stream": "IMU[0]", "kind": "gap"}],
        "segments": segments,
        "vehicle_filters": {"autopilot": "ardupilot", "parameters": {"INS_GYRO_FILTER": 20, "INS_HNTCH_ENABLE": 1,
                                                                     "INS_HNTCH_FREQ": 80, "INS_HNTCH_BW": 20},
                            "stages": vehicle_filters(named("ardupilot"), {
                                "INS_GYRO_FILTER": 20.0, "INS_HNTCH_ENABLE": 1, "INS_HNTCH_FREQ": 80.0,
                                "INS_HNTCH_BW": 20.0, "INS_HNTCH_ATT": 40.0, "INS_HNTCH_HMNCS": 3,
                                "INS_HNTCH_MODE": 0})["stages"]},
        "filter_review": {
            "source": {"stream": "IMU[0]", "stage": "pre-filter", "sample_rate_hz": rate_hz, "over": "flying"},
            "noise_band_hz": [30.0, 160.0],
            "notch_rule": "a static or harmonic notch only on a peak at or above 40 Hz, at least 10 dB above the "
                          "local floor, at most 0.4 x the analysed stream's rate",
            "peaks": [{"freq_hz": 80.0, "axis": "x", "amplitude_rms_deg_s": 1.06, "ratio_db": 25.0,
                       "notch_ok": True, "why_not": None},
                      {"freq_hz": 160.0, "axis": "x", "amplitude_rms_deg_s": 0.35, "ratio_db": 12.0,
                       "notch_ok": False, "why_not": "above 0.4 x the stream's rate"}],
            "figures": {"pre_filter": {"noise_rms_deg_s": {"x": 1.2, "y": 1.2, "z": 1.2, "rss": 2.08}},
                        "logged": {"noise_rms_deg_s": {"x": 0.3, "y": 0.3, "z": 0.3, "rss": 0.52},
                                   "phase_lag_ms": {"10": 9.0, "20": 9.5, "30": 10.1}},
                        "recommended": {"noise_rms_deg_s": {"x": 0.2, "y": 0.2, "z": 0.2, "rss": 0.35},
                                        "phase_lag_ms": {"10": 6.0, "20": 6.2, "30": 6.5}}},
            "logged": {"INS_GYRO_FILTER": 20, "INS_HNTCH_FREQ": 80},
            "logged_stages": [{"kind": "lowpass", "params": "INS_GYRO_FILTER", "cutoff_hz": 20.0}],
            "recommended_stages": [{"kind": "lowpass", "params": "INS_GYRO_FILTER", "cutoff_hz": 40.0}],
            "recommended": {"INS_GYRO_FILTER": 40, "INS_HNTCH_FREQ": 80},
            "changes": {"INS_GYRO_FILTER": 40}, "verdict": "change",
            "param_lines": ["INS_GYRO_FILTER,40"],
            "why": ["INS_GYRO_FILTER 40: the highest cutoff whose predicted noise is no more than the logged "
                    "settings'"]},
        "vibration": {"source": "VIBE", "verdict": "warn", "over": "flying",
                      "thresholds": {"vibe_level_m_s2": {"warn": 30.0, "fail": 60.0, "unit": "m/s/s"},
                                     "clip_increase": {"warn": 1, "fail": 100, "unit": "count"}},
                      "segments": [_vibe_segment("flying", 22.0, 62.0, (12.0, 35.0, 20.0), 3),
                                   _vibe_segment("hover", 30.0, 45.0, (10.0, 28.0, 18.0), 0)]},
    }
    fr = pd["freq_hz"]
    from gyrodenoise.flightlog.html_report import vehicle_response
    resp_logged, _ = vehicle_response(report["vehicle_filters"]["stages"], fr, rate_hz)
    resp_rec, _ = vehicle_response([{"kind": "lowpass", "path": "rate", "params": "INS_GYRO_FILTER", "cutoff_hz": 40.0},
                                    {"kind": "notch", "path": "rate", "form": "px4", "params": "IMU_GYRO_NF0_FRQ",
                                     "centre_hz": 80.0, "bandwidth_hz": 20.0, "attenuation_db": None}],
                                   fr, rate_hz)
    pre = np.mean(pd["raw"], axis=0)
    series = {"streams": [stream_series(s, "filtered (lowpass 30 Hz, offline)"), stream_series(slow)],
              "vehicle_rate": [{"name": "RATE", "time_s": t[::8], "rate": motion[::8], "unit": "deg/s"}],
              "spectra": {"IMU[0]": pd},
              "filter_review": {"freq_hz": fr, "unit": "deg/s", "psd_pre": pre,
                                "psd_post_logged": pre * resp_logged ** 2, "psd_post_recommended": pre * resp_rec ** 2,
                                "response_logged": resp_logged, "response_recommended": resp_rec}}
    return report, series


def _vibe_segment(kind, start_s, end_s, p95, clips):
    """A segment of ``report["vibration"]`` in the review's shape (docs/logs/vibration.md):
    VibeX/Y/Z levels with ArduPilot's thresholds, a clip counter, and a gyro metric with
    no published threshold."""
    def verdict(v):
        return "fail" if v >= 60.0 else "warn" if v >= 30.0 else "pass"
    figures = {f"Vibe{a}": {"mean": 0.7 * v, "p95": v, "max": 1.3 * v, "unit": "m/s/s",
                            "threshold": {"warn": 30.0, "fail": 60.0}, "verdict": verdict(v), "samples": 400}
               for a, v in zip("XYZ", p95)}
    figures["Clip0"] = {"increase": clips, "unit": "count", "threshold": {"warn": 1, "fail": 100},
                        "verdict": "warn" if clips else "pass"}
    figures["gyro_vibration_metric"] = {"mean": 0.4, "p95": 0.5, "max": 0.6, "unit": "rad/s", "threshold": None,
                                        "verdict": None, "samples": 400}
    worst = max((f["verdict"] for f in figures.values() if f["verdict"]), key=("pass", "warn", "fail").index)
    return {"kind": kind, "start_s": start_s, "end_s": end_s, "session": 0, "figures": figures,
            "accel_peaks": [{"freq_hz": 80.0, "amplitude_rms_m_s2": 0.6, "ratio_db": 14.0}], "verdict": worst}


def real_log_report(log_path, out_dir):
    """(report, series) of a real log: the bridge's report (:func:`process_log`, no
    PNG, no CSV) and its streams read and filtered again by the same steps (the
    pipeline does not hand its streams out yet)."""
    from gyrodenoise.core.kernels import DEFAULT_METHOD
    from gyrodenoise.flightlog.engines import make_engine
    from gyrodenoise.flightlog.filtering import filter_streams
    from gyrodenoise.flightlog.formats import read_log
    from gyrodenoise.flightlog.html_report import series_of_streams
    from gyrodenoise.flightlog.output import joined_time
    from gyrodenoise.flightlog.pipeline import process_log
    from gyrodenoise.flightlog.spectra import stream_spectrum
    from gyrodenoise.flightlog.checks import usable_samples
    rep = process_log(log_path, out_dir, plots=False, csv=False)
    streams = read_log(Path(log_path)).gyro
    eng = make_engine("native", DEFAULT_METHOD, offline=True)
    try:
        filter_streams(streams, eng, 5.0)
    finally:
        eng.close()
    spectra = {}
    for s in streams:
        x, f, unit, rate = s._work
        usable = (usable_samples(x) & np.isfinite(f)).all(axis=1)
        _, pd = stream_spectrum(s, x, f, unit, rate, DEFAULT_METHOD, None, getattr(s, "warmup_samples", 0),
                                joined_time(s.time_s, s.restarts), usable)
        if pd is not None:
            spectra[s.name] = pd
    return rep, series_of_streams(streams, f"filtered ({DEFAULT_METHOD}, {rep.get('form')})", spectra)


def check_page(html_path, screenshot=None, plot_shots=True):
    """Open ``html_path`` in headless Chromium with every non-file request refused.
    Returns a dict: ``requests`` (URLs refused), ``console_errors``, ``page_errors``,
    ``plots`` (per plot div: ``main_svg`` (plotly drew it), ``modebar`` (zoom/hover
    tools), ``colours`` (distinct colours in a screenshot of its region)); with
    ``screenshot`` the page's first screen is saved there as PNG."""
    from playwright.sync_api import sync_playwright
    from PIL import Image
    import io
    blocked, console, page_errors, plots = [], [], [], []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1300, "height": 900})

            def route(r):
                if r.request.url.startswith("file:"):
                    r.continue_()
                else:
                    blocked.append(r.request.url)
                    r.abort()

            page.route("**/*", route)
            page.on("console", lambda m: console.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: page_errors.append(str(e)))
            page.goto(Path(html_path).resolve().as_uri(), wait_until="load")
            page.wait_for_function("() => document.querySelectorAll('div.plot .js-plotly-plot .main-svg').length > 0 && document.querySelectorAll('div.plot .js-plotly-plot').length === "
                                   "document.querySelectorAll('div.plot div.plotly-graph-div').length", timeout=30000)
            for div in page.query_selector_all("div.plot div.plotly-graph-div"):
                info = {"id": div.get_attribute("id"), "main_svg": div.query_selector(".main-svg") is not None,
                        "modebar": div.query_selector(".modebar") is not None}
                if plot_shots:
                    div.scroll_into_view_if_needed()
                    img = Image.open(io.BytesIO(div.screenshot())).convert("RGB")
                    info["colours"] = len(img.getcolors(maxcolors=1 << 20) or [])
                plots.append(info)
            if screenshot:
                page.evaluate("window.scrollTo(0, 0)")
                Path(screenshot).parent.mkdir(parents=True, exist_ok=True)
                page.evaluate("() => { const h = document.getElementById('streams'); "
                              "if (h) h.scrollIntoView({block: 'start'}); }")
                page.screenshot(path=str(screenshot))
        finally:
            browser.close()
    return {"requests": blocked, "console_errors": console, "page_errors": page_errors, "plots": plots}


def main(argv=None):
    """Write a log's HTML report and, optionally, a screenshot of it (the docs' figure)."""
    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("log", help="a log file, or 'synthetic'")
    ap.add_argument("--out", required=True, help="output folder")
    ap.add_argument("--screenshot", help="PNG of the page's first plot")
    a = ap.parse_args(argv)
    from gyrodenoise.flightlog.html_report import write_log_report
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.log == "synthetic":
        rep, series = synthetic_report(out)
        name = "synthetic"
    else:
        rep, series = real_log_report(a.log, out)
        name = Path(a.log).stem
    html_path = write_log_report(out / f"{name}.report.html", rep, series)
    print(f"{html_path}: {html_path.stat().st_size / 1e6:.2f} MB")
    if a.screenshot:
        res = check_page(html_path, a.screenshot, plot_shots=False)
        print(f"{a.screenshot}: {len(res['plots'])} plots, {len(res['requests'])} requests refused, "
              f"{len(res['console_errors'])} console errors")


if __name__ == "__main__":
    main()
