"""The dynamic notch's logged centre (the strategy's ``notch_centre_track``: ArduPilot
``FTN``, PX4 ``sensor_gyro_fft``) drawn on the frequency-by-throttle map and the
spectrogram. A SYNTHETIC ArduCopter log: a gyro tone at F sqrt(thr / REF) and FTN.NF1
logging that frequency (as a tracking notch would), FTN.NF2 unused (0): the map's logged
centre line lies on the ridge within one frequency bin, and the spectrogram carries it."""
from __future__ import annotations

import numpy as np

from gyrodenoise.flightlog.heatmap import track_centre_hz
from gyrodenoise.flightlog.timeseries import flight_views

from tests.flightlog.flight_logs import log_of_bytes
from tests.flightlog.synthetic_logs import DataFlashWriter

FS, F_HZ, REF, SECONDS = 1000.0, 90.0, 0.4, 40.0


def _log(seed=3):
    rng = np.random.default_rng(seed)
    w = DataFlashWriter()
    w.define("PARM", "QNf", ["TimeUS", "Name", "Value"])
    w.define("MSG", "QZ", ["TimeUS", "Message"])
    w.define("IMU", "QBffffff", ["TimeUS", "I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("CTUN", "Qf", ["TimeUS", "ThO"])
    w.define("FTN", "QBff", ["TimeUS", "NDn", "NF1", "NF2"])
    for name, v in {"INS_HNTCH_ENABLE": 1, "INS_HNTCH_MODE": 4, "INS_HNTCH_FREQ": 60.0, "INS_HNTCH_REF": 1.0,
                    "INS_HNTCH_HMNCS": 1, "INS_HNTCH_BW": 20, "INS_HNTCH_ATT": 40, "FRAME_CLASS": 1}.items():
        w.add("PARM", 100_000, name, v)
    w.add("MSG", 100_000, "ArduCopter V4.5.7 (0123abcd)")
    t = np.arange(int(SECONDS * FS)) / FS + 1.0
    thr = 0.2 + 0.5 * (0.5 - 0.5 * np.cos(2 * np.pi * (t - 1.0) / SECONDS))
    f = F_HZ * np.sqrt(thr / REF)
    gyr = np.radians(4.0 * np.sin(2 * np.pi * np.cumsum(f) / FS)[:, None] + rng.normal(0, 0.5, (len(t), 3)))
    for j in range(len(t)):
        us = int(round(t[j] * 1e6))
        w.add("IMU", us, 0, *gyr[j], 0.0, 0.0, -9.8)
        if j % 100 == 0:
            w.add("CTUN", us, float(thr[j]))
            w.add("FTN", us, 1, float(f[j]), 0.0)
    return log_of_bytes(w.bytes(), "dataflash")


def test_the_logged_centre_lies_on_the_ridge_of_the_throttle_map():
    views = flight_views(_log())
    tr = views.notch_track
    assert tr is not None and list(tr.columns) == ["NF1"] and tr.unit == "Hz"      # NF2 all 0: left out
    hm = next(m for m in views.maps if m.x_label.startswith("throttle"))
    line = next(ln for ln in hm.lines if ln.label.startswith("logged dynamic notch centre (FTN NF1"))
    ridge = hm.ridge_hz()
    ok = (hm.windows > 0) & np.isfinite(line.freq_hz)
    assert ok.sum() >= 10
    bin_hz = hm.freq_hz[1] - hm.freq_hz[0]
    assert np.max(np.abs(line.freq_hz[ok] - ridge[ok])) <= bin_hz
    # the truth: F sqrt(thr / REF) at the bin centres, within half a throttle bin's change
    truth = F_HZ * np.sqrt(line.x[ok] / REF)
    half_bin = F_HZ * (np.sqrt(hm.edges[1:] / REF) - np.sqrt(hm.edges[:-1] / REF))[ok]
    assert np.all(np.abs(line.freq_hz[ok] - truth) <= half_bin)


def test_the_spectrogram_carries_the_logged_centre():
    from gyrodenoise.flightlog.html_report import _spectrogram_figure
    views = flight_views(_log())
    tr = views.notch_track
    t = np.linspace(1.0, SECONDS + 1.0, 50)
    pd = {"spectrogram": (t, np.ones((50, 129))), "freq_hz": np.linspace(0, 500, 129), "unit": "deg/s"}
    fig = _spectrogram_figure("IMU[0]", pd, tr)
    line = [d for d in fig.data if d.type == "scatter"]
    assert len(line) == 1 and "FTN NF1" in line[0].name
    y = np.asarray(line[0].y, np.float64)
    lo, hi = np.nanmin(track_centre_hz(tr)), np.nanmax(track_centre_hz(tr))
    assert np.nanmin(y) >= lo - 1e-3 and np.nanmax(y) <= hi + 1e-3
    assert len(_spectrogram_figure("IMU[0]", pd).data) == 1          # no track: the heatmap alone
    # a spectrogram ending under the notch (a 25 Hz stream): no track, the axis kept to its span
    slow = dict(pd, freq_hz=np.linspace(0, 12.5, 129))
    fig = _spectrogram_figure("IMU[0]", slow, tr)
    assert len(fig.data) == 1 and list(fig.layout.yaxis.range) == [0.0, 12.5]
