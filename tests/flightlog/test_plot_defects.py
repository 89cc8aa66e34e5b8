"""The PNG plots of the bridge (gyrodenoise.flightlog.plotting, .spectra), read back as
matplotlib figures: raw drawn above the filtered line and both labelled, a stream
written raw never called "filtered", the PSD's legend clear of the low-frequency
corner, the spectrogram's colour bar with its unit, the batch sampler's response
measured when it was filtered, and the flight segments shaded."""
import numpy as np
import pytest

from gyrodenoise.flightlog import plotting, spectra
from gyrodenoise.flightlog.streams import GyroStream


@pytest.fixture
def captured(monkeypatch):
    """The figures the plots would save (the saved file is not written)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.figure
    figs = []
    from pathlib import Path

    def savefig(self, fname, *a, **k):
        figs.append(self)
        Path(fname).write_bytes(b"")

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    import matplotlib.pyplot as plt
    monkeypatch.setattr(plt, "close", lambda *a, **k: None)
    return figs


def _stream(n=4000, rate=400.0, bursts=None, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    restarts = np.zeros(n, dtype=bool)
    if bursts:                                   # the batch sampler: bursts with gaps between
        t = t + np.repeat(np.arange(n // bursts) * 10.0, bursts)
        restarts[::bursts] = True
        restarts[0] = False
    x = np.column_stack([np.sin(2 * np.pi * 1.0 * t), np.cos(2 * np.pi * 0.5 * t), 0 * t]) * 10
    x = x + np.sin(2 * np.pi * 80.0 * t)[:, None] + rng.normal(0, 0.5, (n, 3))
    s = GyroStream(name="ISB.gyro[0]" if bursts else "IMU", message="ISBD" if bursts else "IMU", unit="deg/s",
                   to_deg_s=1.0, time_s=t, raw=x, index=np.arange(n), rate_hz=rate, restarts=restarts)
    return s, x


def _lowpass(x, rate, restarts, cutoff_hz=30.0):
    from scipy.signal import butter, sosfilt
    sos = butter(2, cutoff_hz, fs=rate, output="sos")
    out = np.empty_like(x)
    cuts = [0] + list(np.flatnonzero(restarts)) + [len(x)]
    for a, b in zip(cuts[:-1], cuts[1:]):
        out[a:b] = sosfilt(sos, x[a:b], axis=0)
    return out


def test_raw_is_drawn_above_the_filtered_line_and_both_are_labelled(captured, tmp_path):
    s, x = _stream()
    f = _lowpass(x, 400.0, s.restarts)
    plotting.plot_stream(tmp_path / "a.png", "t", s.time_s, x, f, s.restarts, "deg/s")
    ax = captured[-1].axes[0]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    assert {"raw", "filtered"} <= set(lines)
    assert lines["raw"].get_zorder() > lines["filtered"].get_zorder()       # raw on top ...
    assert lines["raw"].get_alpha() < 1.0                                   # ... and see-through
    assert lines["raw"].get_color() != lines["filtered"].get_color()


def test_a_stream_written_raw_is_not_labelled_filtered(captured, tmp_path):
    s, x = _stream()
    plotting.plot_stream(tmp_path / "a.png", "t", s.time_s, x, x.copy(), s.restarts, "deg/s")
    labels = [ln.get_label() for ax in captured[-1].axes for ln in ax.get_lines()]
    assert not any("filtered" == lb or lb.startswith("filtered") for lb in labels), labels
    assert any("written raw" in lb for lb in labels)
    assert plotting.written_raw(x, None) and not plotting.written_raw(x, x + 1)


def test_segments_are_shaded_on_the_time_plot_and_none_by_default(captured, tmp_path):
    s, x = _stream()
    f = _lowpass(x, 400.0, s.restarts)
    segs = [{"kind": "armed", "start_s": 1.0, "end_s": 2.0}, {"kind": "flying", "start_s": 2.0, "end_s": 8.0}]
    plotting.plot_stream(tmp_path / "a.png", "t", s.time_s, x, f, s.restarts, "deg/s", segments=segs)
    ax = captured[-1].axes[0]
    assert {p.get_label() for p in ax.patches} >= {"armed", "flying"}
    plotting.plot_stream(tmp_path / "b.png", "t", s.time_s, x, f, s.restarts, "deg/s")
    assert not captured[-1].axes[0].patches


def _spectrum_figure(captured, tmp_path, n=16000):
    s, x = _stream(n=n)
    f = _lowpass(x, 400.0, s.restarts)
    s.time_s = s.time_s * 3.0                 # spans 120 s: a spectrogram
    rep, pd = spectra.stream_spectrum(s, x, f, "deg/s", 400.0, "lowpass", {"cutoff_hz": 30.0}, 40)
    spectra.draw_log_spectrum(tmp_path / "s.png", "t", [("IMU", pd)])
    return captured[-1]


def test_psd_legend_leaves_the_low_frequency_corner_clear(captured, tmp_path):
    fig = _spectrum_figure(captured, tmp_path)
    fig.canvas.draw()
    ax = fig.axes[0]
    box = ax.bbox
    (text,) = [t for t in ax.texts if "peaks" in t.get_text()]
    tb = text.get_window_extent(renderer=fig.canvas.get_renderer())
    # the lower-left quarter of the axes (low frequencies, the motion and a filter's knee)
    corner_x1, corner_y1 = box.x0 + 0.25 * box.width, box.y0 + 0.5 * box.height
    assert tb.x0 > corner_x1 or tb.y0 > corner_y1, (tb, box)


def test_the_spectrogram_has_a_colour_bar_with_its_unit(captured, tmp_path):
    fig = _spectrum_figure(captured, tmp_path)
    images = [ax for ax in fig.axes if ax.images]
    assert images, "no spectrogram drawn"
    cbars = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert len(cbars) == 1
    assert "dB" in cbars[0].get_ylabel() and "deg/s" in cbars[0].get_ylabel()


def test_batch_sampler_response_is_measured_when_it_was_filtered(captured, tmp_path):
    # bursts of 1024 samples at 2 kHz, a warm-up of 200 samples: no 1024-sample
    # segment is left after it, yet the stream was filtered
    s, x = _stream(n=1024 * 24, rate=2000.0, bursts=1024)
    f = _lowpass(x, 2000.0, s.restarts, cutoff_hz=100.0)
    rep, pd = spectra.stream_spectrum(s, x, f, "deg/s", 2000.0, "motion", None, 200)
    assert rep["response_segments"] > 0
    assert rep["filter"]["x"]["measured"], rep["filter"]["x"]
    assert 60.0 < rep["filter"]["x"]["minus3db_hz"] < 160.0
    assert "warm-up" in rep["response_note"]
    spectra.draw_log_spectrum(tmp_path / "s.png", "t", [("ISB.gyro[0]", pd)])
    texts = " ".join(t.get_text() for ax in captured[-1].axes for t in ax.texts)
    assert "not measured" not in texts


def test_a_stream_written_raw_says_why_its_response_is_not_measured(captured, tmp_path):
    s, x = _stream()
    rep, pd = spectra.stream_spectrum(s, x, x.copy(), "deg/s", 400.0, "motion", None, 40)
    assert not rep["filter"]["x"]["measured"]
    spectra.draw_log_spectrum(tmp_path / "s.png", "t", [("IMU", pd)])
    texts = " ".join(t.get_text() for ax in captured[-1].axes for t in ax.texts)
    assert "not measured (written raw" in texts


def test_a_crash_spike_does_not_set_the_png_y_range(captured, tmp_path):
    s, x = _stream()
    x[-10:] = 2000.0
    f = _lowpass(x, 400.0, s.restarts)
    segs = [{"kind": "flying", "start_s": 1.0, "end_s": 9.0}]
    plotting.plot_stream(tmp_path / "a.png", "t", s.time_s, x, f, s.restarts, "deg/s", segments=segs)
    ax = captured[-1].axes[0]
    assert ax.get_ylim()[1] < 100 and "y clipped to 1-99 % of the samples" in ax.get_title()
