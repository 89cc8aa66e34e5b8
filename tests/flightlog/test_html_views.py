"""The HTML report draws the flight views (gyrodenoise.flightlog.timeseries.flight_views):
the motors/throttle/vibration panels with the thresholds, the markers on every time axis
(the gyro's too) and the frequency-by-throttle map with its notch line; every trace a
few thousand points at most (the page stays small)."""
from __future__ import annotations

import json
import re

import numpy as np

from gyrodenoise.flightlog.html_report import ENVELOPE_BINS, write_log_report
from gyrodenoise.flightlog.timeseries import flight_views

from tests.flightlog.flight_logs import log_of_bytes
from tests.flightlog.test_timeseries import ardupilot_log


def _plots(html):
    """The plotly specs of a page (each ``Plotly.newPlot(id, data, layout, config)``)."""
    out = []
    for m in re.finditer(r'Plotly\.newPlot\(\s*"([^"]+)",\s*(\[.*?\]),\s*(\{.*?\}),\s*\{"displaylogo"', html, re.S):
        out.append((m.group(1), json.loads(m.group(2)), json.loads(m.group(3))))
    return out


def test_views_are_drawn_with_markers_thresholds_and_the_notch(tmp_path):
    log = log_of_bytes(ardupilot_log()[0], "dataflash")
    views = flight_views(log)
    s = log.gyro[0]
    raw = s.raw * s.to_deg_s
    series = {"streams": [{"name": s.name, "time_s": s.time_s, "raw": raw, "filtered": raw, "unit": "deg/s",
                           "axes": ("x", "y", "z"), "restarts": None}], "views": views}
    page = write_log_report(tmp_path / "r.html", {"file": "synthetic.bin"}, series).read_text()
    assert "Motors, throttle, RC, battery and vibration" in page and "Frequency by throttle" in page
    plots = _plots(page)
    names = [tr.get("name") for _, data, _ in plots for tr in data]
    for want in ("motor 1 (C2)", "throttle", "VibeZ[1]", "warn threshold", "fail threshold", "Clip[1]",
                 "events", "modes", "failsafes", "INS_HNTCH_* notch, harmonic 1 (throttle)"):
        assert want in names, want
    # the markers are on the gyro's axes too (its figure: 3 subplots, a trace per kind each)
    gyro = next(data for _, data, _ in plots if any(tr.get("name") == "raw" for tr in data))
    assert sum(tr.get("name") == "failsafes" for tr in gyro) == 3
    fs = next(tr for tr in gyro if tr.get("name") == "failsafes")
    assert "ERR FAILSAFE_BATT (6) ECode 1" in json.dumps(fs["text"])
    heat = [tr for _, data, _ in plots for tr in data if tr.get("type") == "heatmap"]
    assert heat, "no heatmap drawn"


def test_long_panels_are_decimated(tmp_path):
    """A 2-hour 50 Hz motor log: each trace at most 2 x ENVELOPE_BINS points (+ cuts)."""
    from gyrodenoise.flightlog.timeseries import Channels, FlightViews, Panel, TimeViews
    t = np.arange(360_000) / 50.0
    ch = Channels("RCOU", "PWM us", t, {f"motor {k}": 1500 + np.sin(t * k) for k in range(1, 5)})
    views = FlightViews(TimeViews([Panel("motors", "motors", ch)], [], {}), [], [])
    page = write_log_report(tmp_path / "r.html", {"file": "x.bin"}, {"views": views}).read_text()
    (_, data, _), = [p for p in _plots(page) if any(str(tr.get("name", "")).startswith("motor") for tr in p[1])]
    for tr in data:
        x = tr["x"]
        n = len(x) if isinstance(x, list) else int(np.frombuffer(__import__("base64").b64decode(x["bdata"]),
                                                                   dtype=x["dtype"]).size)
        assert n <= 2 * ENVELOPE_BINS + 10


def test_each_panel_lists_its_own_lines():
    """One legend per panel beside it (plotly's legend, legend2, ...), at its subplot's top;
    the markers and segments, which span every panel, in one more legend under the figure."""
    from gyrodenoise.flightlog.html_report import _panels_figure
    data, _, _ = ardupilot_log()
    views = flight_views(log_of_bytes(data, "dataflash"))
    segments = [{"kind": "flying", "start_s": 10.0, "end_s": 50.0}]
    fig = _panels_figure(views.time, segments, "time [s]")
    panels = views.time.panels
    common = f"legend{len(panels) + 1}"
    for r, p in enumerate(panels, 1):
        name = "legend" if r == 1 else f"legend{r}"
        mine = [d for d in fig.data if (d.legend or "legend") == name]
        assert {d.name for d in mine} >= set(p.channels.columns), (p.key, [d.name for d in mine])
        dom = fig.layout[f"yaxis{'' if r == 1 else r}"].domain
        assert fig.layout[name].y == dom[1]
    shared = {d.name for d in fig.data if d.legend == common and d.showlegend is not False}
    assert {"events", "modes", "failsafes", "segment: flying"} <= shared
