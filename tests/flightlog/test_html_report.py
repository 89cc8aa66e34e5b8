"""The HTML report without a browser: any subset of the report's keys renders, notes
stand in for missing sections, long series are reduced, the page holds no external
resource (the browser test, test_html_report_browser.py, checks that it draws)."""
import numpy as np

from gyrodenoise.flightlog.autopilots import named
from gyrodenoise.flightlog import html_report as hr


def test_a_report_with_only_its_file_renders_with_its_notes(tmp_path):
    rep = {"file": "x.bin", "segments": [], "segments_note": "no arming record",
           "vehicle_filters": None, "vehicle_filters_note": "no parameters in the log",
           "filter_review": None, "filter_review_note": "no pre-filter stream", "vibration": None,
           "vibration_note": "no VIBE messages"}
    text = hr.write_log_report(tmp_path / "r.html", rep).read_text()
    for note in ("no arming record", "no parameters in the log", "no pre-filter stream", "no VIBE messages"):
        assert note in text
    assert "<script src" not in text and "<link" not in text and "cdn." not in text.lower().split("</head>")[1]
    hr.write_log_report(tmp_path / "bare.html", {"file": "y.bin"})


def test_envelope_keeps_the_extremes_in_time_order():
    t = np.arange(240_000) / 400.0
    y = np.sin(t)
    y[12345] = 50.0
    tt, yy = hr.envelope(t, y, nbins=1500)
    assert len(tt) <= 3000 and yy.max() == 50.0 and np.all(np.diff(tt) >= 0)
    r = np.zeros(len(t), dtype=bool)
    r[100_000] = True
    tt, yy = hr.session_envelope(t, y, r)
    assert np.isnan(yy).sum() == 1 and len(tt) <= 3002


def test_vehicle_response_is_the_vehicles_own_chain():
    """The page's gain of the vehicle's filters is the filter review's model (the
    autopilot's biquads, vehicle_filters.chain_response), notches included: before, a
    second model (scipy) read ``center_hz``, which no stage has, and drew every notch
    as all-pass."""
    from gyrodenoise.flightlog import vehicle_filters as vf
    stages = vf.vehicle_filters(named("ardupilot"), {"INS_GYRO_FILTER": 100.0, "INS_HNTCH_ENABLE": 1,
                                              "INS_HNTCH_FREQ": 80.0, "INS_HNTCH_BW": 20.0,
                                              "INS_HNTCH_ATT": 40.0, "INS_HNTCH_HMNCS": 1,
                                              "INS_HNTCH_MODE": 0})["stages"]
    f = np.array([1.0, 80.0, 150.0])
    g, skipped = hr.vehicle_response(stages + [{"kind": "mystery", "params": "X"}], f, 1000.0)
    np.testing.assert_allclose(g, np.abs(vf.chain_response(stages, f, 1000.0)), rtol=1e-12)
    assert g[0] > 0.99 and g[1] < 0.05 and skipped == ["mystery"]


def _vibration(tmp_path):
    from tests.flightlog.html_browser import _vibe_segment
    return {"source": "VIBE", "verdict": "warn", "over": "flying",
            "segments": [_vibe_segment("flying", 22.0, 62.0, (12.0, 35.0, 20.0), 3),
                         _vibe_segment("hover", 30.0, 45.0, (10.0, 28.0, 18.0), 0)]}


def test_vibration_figures_are_plotted_per_metric_against_their_thresholds(tmp_path):
    vib = _vibration(tmp_path)
    rows = hr.vibration_levels(vib)
    assert [len(f) for _, f in rows] == [5, 5]
    assert not any("session" in f for _, f in rows)
    plots = hr._vibration_plots(rows)
    levels, gyro, clips = plots                        # m/s/s, rad/s, count
    bars = [t for t in levels.data if t.type == "bar"]
    assert len(bars) == 2 and list(bars[0].y) == [12.0, 35.0, 20.0]
    assert list(bars[0].marker.color) == [hr.VERDICT_COLOURS[v] for v in ("pass", "warn", "pass")]
    assert {s.y0 for s in levels.layout.shapes} == {30.0, 60.0}
    assert any(t.name == "flying 22-62 s: max" and np.allclose(t.y, [15.6, 45.5, 26.0]) for t in levels.data)
    assert "no published threshold" in gyro.data[0].x[0] and not gyro.layout.shapes
    assert [t for t in clips.data if t.type == "bar"][0].y == (3,)
    text = hr.write_log_report(tmp_path / "v.html", {"file": "v.bin", "vibration": vib}).read_text()
    assert "VibeY" in text and "no published threshold" in text and '"session"' not in text


def test_the_filter_review_is_a_readable_table_not_a_cut_json(tmp_path):
    from tests.flightlog.html_browser import synthetic_report
    rep, _ = synthetic_report(tmp_path, seconds=4.0)
    rev = rep["filter_review"]
    rev["notes"] = ["x" * 400]                         # a long text stays whole
    text = hr.write_log_report(tmp_path / "f.html", rep).read_text()
    body = text.split("</head>")[1]
    assert "..." not in body and "x" * 400 in body
    assert "lag at 20 Hz [ms]" in body and "noise rss [deg/s]" in body and "9.5" in body
    assert "<pre class=paste>INS_GYRO_FILTER,40</pre>" in body
    assert "above 0.4 x the stream&#x27;s rate" in body and "notch rule:" in body
    assert "verdict: <span class=\"warn\">change</span>" in body
    rev.update(changes={}, verdict="no change", param_lines=[])
    assert "the logged settings are kept" in hr.write_log_report(tmp_path / "g.html", rep).read_text()


def _spiky_stream(n=8000, rate_hz=400.0):
    rng = np.random.default_rng(2)
    t = np.arange(n) / rate_hz
    raw = rng.normal(0, 5.0, (n, 3))
    raw[-20:] = 2000.0                                 # the crash, after the flight
    return {"name": "IMU", "time_s": t, "raw": raw, "filtered": raw * 0.5, "unit": "deg/s",
            "axes": ("x", "y", "z"), "restarts": None}


def test_a_crash_spike_does_not_set_the_initial_y_range():
    st = _spiky_stream()
    segs = [{"kind": "flying", "start_s": 2.0, "end_s": 18.0}]
    fig, _ = hr._time_figure(st, [], segs, "IMU")
    lo, hi = fig.layout.yaxis.range
    assert -40 < lo < -10 and 10 < hi < 40
    assert "y clipped to 1-99 % of the samples" in fig.layout.title.text
    st["raw"][15 * 400:15 * 400 + 60] = -1500.0        # a crash inside the flight: 0.75 % of its samples
    fig, _ = hr._time_figure(st, [], segs, "IMU")
    assert -40 < fig.layout.yaxis.range[0] < -10
    st = _spiky_stream()
    st["raw"] = st["raw"][:-20]
    st["filtered"], st["time_s"] = st["raw"] * 0.5, st["time_s"][:-20]
    fig, _ = hr._time_figure(st, [], None, "IMU")      # no spike: plotly's own range
    assert fig.layout.yaxis.range is None and "clipped" not in fig.layout.title.text


def test_wide_tables_scroll_in_their_own_box_and_legend_names_stay_short():
    assert hr._table([["a" * 300]]).startswith('<div class="tbl"><table')
    assert "div.tbl{max-width:100%;overflow-x:auto}" in hr.CSS
    st = _spiky_stream()
    st["filtered"], st["raw_reason"] = None, "too slow to denoise: written raw because of a very long reason"
    fig, _ = hr._time_figure(st, [], None, "IMU")
    names = {t.name for t in fig.data if t.showlegend is not False}
    assert max(len(n) for n in names) <= 30, names
    assert any("very long reason" in t.hovertemplate for t in fig.data)


def test_a_filter_that_changed_nothing_says_so(tmp_path):
    s = {"name": "sensor_combined", "rate_hz": 220.0, "noise_unit": "deg/s", "note": "ULog sensor_combined",
         "noise": {a: {"raw": 0.5, "filtered": 0.5, "ratio": 1.0} for a in "xyz"}}
    assert hr.passed_through(s).startswith(hr.PASSED_THROUGH_NOTE)
    assert not hr.passed_through({**s, "noise": {"x": {"ratio": 0.6}}})
    text = hr.write_log_report(tmp_path / "p.html", {"file": "p.ulg", "streams": [s]}).read_text()
    assert "kept as motion: the filter passed the signal through" in text


def test_lags_that_are_numerical_noise_print_as_zero():
    from gyrodenoise.flightlog.spectra import lag_text
    assert lag_text(-3.1e-05) == "0" and lag_text(0.004) == "0" and lag_text(2.345) == "2.3"


def test_the_fleet_table_gives_each_noise_figure_its_unit(tmp_path):
    rows = [{"log": "a", "file": "a.bin", "stream": "IMU", "status": "ok", "rate_hz": 400.0, "noise_raw": 0.8,
             "noise_filtered": 0.2, "noise_unit": "deg/s"},
            {"log": "b", "file": "b.tlog", "stream": "RAW_IMU", "status": "ok", "rate_hz": 10.0, "noise_raw": 12.0,
             "noise_filtered": 12.0, "noise_unit": None}]
    text = hr.write_fleet_report(tmp_path / "fleet.html", {"rows": rows, "n_logs": 2}).read_text()
    assert "0.8</span> deg/s" in text and "12</span> raw counts (unit unknown)" in text


def test_the_desired_rate_is_drawn_only_while_armed():
    st = _spiky_stream()
    t = st["time_s"]
    vr = [{"name": "RATE desired (RDes, PDes, YDes)", "time_s": t[::4], "rate": np.ones((len(t[::4]), 3)),
           "unit": "deg/s"}]
    segs = [{"kind": "ground", "start_s": 0.0, "end_s": 5.0}, {"kind": "armed", "start_s": 5.0, "end_s": 10.0}]
    fig, _ = hr._time_figure(st, vr, segs, "IMU")
    (tr,) = [d for d in fig.data if d.name and d.name.startswith("vehicle rate") and d.showlegend]
    y, x = np.asarray(tr.y, dtype=float), np.asarray(tr.x, dtype=float)
    assert "while armed" in tr.name and np.isnan(y[x < 4.9]).all() and np.isfinite(y[(x > 5.1) & (x < 9.9)]).all()


def test_spectra_switch_between_linear_and_log_frequency_batch_sampler_log_first():
    f = np.linspace(0, 1000, 513)
    pd = {"freq_hz": f, "raw": [np.ones_like(f)] * 3, "filtered": [np.ones_like(f) * 0.5] * 3, "unit": "deg/s"}
    fig = hr._spectrum_figure("ISB.gyro[0]", pd, [], "t")
    assert fig.layout.xaxis.type == "log"
    assert {b.args[0]["xaxis.type"] for b in fig.layout.updatemenus[0].buttons} == {"log", "linear"}
    assert hr._spectrum_figure("IMU", pd, [], "t").layout.xaxis.type == "linear"


def test_slow_streams_written_raw_share_one_plot(tmp_path):
    t = np.arange(60.0)
    slow = [{"name": f"sensor_gyro[{i}]", "time_s": t, "raw": np.zeros((60, 3)), "filtered": None, "unit": "deg/s",
             "axes": ("x", "y", "z"), "raw_reason": "too slow to denoise: written raw"} for i in range(2)]
    with hr._Figures() as figs:
        html_text = hr._streams_section({"streams": []}, {"streams": slow}, figs)
    assert figs.n == 1 and "Slow streams, written raw" in html_text
    fig = hr._slow_figure(slow)
    assert {d.name for d in fig.data} == {"sensor_gyro[0]", "sensor_gyro[1]"} and len(fig.data) == 6
