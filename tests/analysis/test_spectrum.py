"""The spectrum view: gyrodenoise.analysis.spectrum against independent
references (scipy.signal, known injected tones, white noise), and the bridge's
spectrum outputs on a synthetic log with known tones and on real logs."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from gyrodenoise.analysis import spectrum as sp
from tests.helpers import shared_file

# the seeded record with known tones: (frequency Hz, amplitude deg/s), white noise 1 deg/s at 1 kHz
FS_HZ = 1000.0
TONES = [(37.0, 0.8), (83.3, 1.2), (166.6, 0.5), (249.9, 0.3)]


def tone_record(n=40000, seed=1, noise_deg_s=1.0, tones=TONES, fs=FS_HZ):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    x = rng.normal(0.0, noise_deg_s, n)
    for k, (f, a) in enumerate(tones):
        x += a * np.sin(2 * np.pi * f * t + k)
    return x


def test_welch_equals_scipy_and_keeps_the_variance():
    from scipy import signal
    x = tone_record()
    nper = sp.choose_nperseg([len(x)], FS_HZ)
    f, p, k = sp.welch_psd(x, FS_HZ, nper)
    f_ref, p_ref = signal.welch(x, FS_HZ, window="hann", nperseg=nper, noverlap=nper // 2,
                                detrend="constant", scaling="density")
    np.testing.assert_allclose(f, f_ref)
    np.testing.assert_allclose(p, p_ref, rtol=1e-10)
    assert k == (len(x) - nper) // (nper // 2) + 1
    # Parseval: the density integrates to the variance (within 1 %: Welch's segments)
    assert np.sum(p) * f[1] == pytest.approx(np.var(x), rel=0.01)


def test_welch_at_the_gap_segment_length_equals_scipy_to_1e12():
    """spectrum.welch_psd with the model-gap segment rule (nperseg_for_length: long
    segments, a record that is not a whole number of half segments) against
    scipy.signal.welch (Hann, half overlap, each segment's mean removed, density): the
    independent reference the gap signatures were first computed with."""
    from scipy import signal
    rng = np.random.default_rng(20)
    for n, fs in ((180_000, 100.0), (2 ** 17 + 333, 1000.0), (5000, 400.0)):
        x = 3.0 + rng.standard_normal(n) + 0.5 * np.sin(2 * np.pi * 12.3 * np.arange(n) / fs)
        nper = sp.nperseg_for_length(n)
        assert nper == 2 ** min(14, max(6, math.floor(math.log2(max(n / 32.0, 64)))))
        f, p, k = sp.welch_psd(x, fs, nper)
        f_ref, p_ref = signal.welch(x, fs, window="hann", nperseg=nper, noverlap=nper // 2,
                                    detrend="constant", scaling="density")
        np.testing.assert_allclose(f, f_ref, rtol=1e-15)
        np.testing.assert_allclose(p, p_ref, rtol=1e-12, atol=0)
        assert k == sp.segment_count([n], nper) == (n - nper) // (nper // 2) + 1


def test_running_median_is_scipys_median_filter():
    """The one running median of spectrum.py: with ends="nearest" it is exactly
    scipy.ndimage.median_filter(mode="nearest") (a median of an odd count is one of
    the values); with ends="reflect" and a width per bin it is the noise floor's."""
    from scipy.ndimage import median_filter
    rng = np.random.default_rng(4)
    p = rng.chisquare(4, 3000)
    for w in (5, 49, 331):
        np.testing.assert_array_equal(sp.running_median(p, w, ends="nearest"),
                                      median_filter(p, size=w, mode="nearest"))
    np.testing.assert_array_equal(sp.running_median(p, 7), median_filter(p, size=7, mode="mirror"))
    with pytest.raises(ValueError):
        sp.running_median(p, 4)


def test_segments_stay_within_sessions_and_skip_the_warmup():
    n, nper = 5000, 256
    restarts = np.zeros(n, bool)
    restarts[[1200, 3100]] = True
    finite = np.ones(n, bool)
    finite[2000] = False
    runs = sp.sessions(n, restarts, skip_samples=100, finite=finite)
    assert runs == [(100, 1200), (1300, 2000), (2001, 3100), (3200, 5000)]
    starts = sp.segments(runs, nper)
    for s0 in starts:
        assert any(a <= s0 and s0 + nper <= b for a, b in runs)
    # a jump between sessions does not reach the spectrum: each session alone is white
    rng = np.random.default_rng(3)
    x = rng.normal(size=n)
    x[1200:] += 500.0
    x[3100:] -= 900.0
    _, p, _ = sp.welch_psd(x, 100.0, nper, restarts)
    assert p[1:].max() < 10 * np.median(p)


def test_injected_tones_found_named_and_grouped():
    """Frequency within one bin, amplitude (rms) within 5 % of A / sqrt(2), the
    83.3 Hz line's harmonics grouped under it, and no other peak."""
    x = tone_record()
    nper = sp.choose_nperseg([len(x)], FS_HZ)
    f, p, k = sp.welch_psd(x, FS_HZ, nper)
    df = f[1] - f[0]
    peaks = sp.group_harmonics(sp.find_peaks(f, p, k, min_freq_hz=5.0), df)
    assert len(peaks) == len(TONES)
    for q, (f0, a0) in zip(peaks, TONES):
        assert abs(q["freq_hz"] - f0) <= df
        assert q["amplitude_rms"] == pytest.approx(a0 / math.sqrt(2), rel=0.05)
    by_f = {round(f0): q for q, (f0, _) in zip(peaks, TONES)}
    assert by_f[37]["harmonic_of_hz"] is None and by_f[83]["harmonic_of_hz"] is None
    assert by_f[167]["harmonic_of_hz"] == pytest.approx(by_f[83]["freq_hz"]) and by_f[167]["harmonic_n"] == 2
    assert by_f[250]["harmonic_of_hz"] == pytest.approx(by_f[83]["freq_hz"]) and by_f[250]["harmonic_n"] == 3
    assert by_f[83]["harmonics_hz"] == [by_f[167]["freq_hz"], by_f[250]["freq_hz"]]


def test_harmonic_needs_the_lower_ones():
    """A high multiple of a low peak with nothing between is not called its harmonic."""
    peaks = [{"freq_hz": 6.0, "amplitude_rms": 1.0}, {"freq_hz": 24.1, "amplitude_rms": 1.0}]
    out = sp.group_harmonics(peaks, 0.5)
    assert [q["harmonic_of_hz"] for q in out] == [None, None]
    out = sp.group_harmonics([{"freq_hz": 6.0}, {"freq_hz": 12.1}, {"freq_hz": 17.9}, {"freq_hz": 24.1}], 0.5)
    assert [q["harmonic_n"] for q in out] == [1, 2, 3, 4]


@pytest.mark.parametrize("n_samples", [8704, 40000])
def test_no_false_peak_on_white_noise_at_the_stated_level(n_samples):
    """White noise, 200 seeded records: the fraction with any peak stays near the
    stated false-alarm probability per spectrum (sp.FALSE_ALARM = 1 %; bound 3 %,
    the threshold alone: min_ratio=1). 8704 samples = 16 segments (the fewest the
    bridge uses), 40000 = 77."""
    n_rec, hits = 200, 0
    nper = sp.choose_nperseg([n_samples], FS_HZ)
    for i in range(n_rec):
        y = np.random.default_rng(1000 + i).normal(size=n_samples)
        f, p, k = sp.welch_psd(y, FS_HZ, nper)
        hits += bool(sp.find_peaks(f, p, k, min_ratio=1.0))
    assert hits / n_rec <= 0.03
    # a tone at the threshold's level is not missed either: 0.12 deg/s rms in 1 deg/s white noise
    x = tone_record(n=n_samples, tones=[(123.0, 0.12 * math.sqrt(2))], seed=7)
    f, p, k = sp.welch_psd(x, FS_HZ, nper)
    assert [round(q["freq_hz"]) for q in sp.find_peaks(f, p, k, min_ratio=1.0)] == [123]


def test_measured_response_of_the_core_lowpass_equals_the_computed_one():
    """White noise through the core's Butterworth low-pass: H1 from the
    cross-spectrum equals the sections' response (scipy.signal.sosfreqz as the
    independent reference) where the gain is above 0.05, and so does the lag."""
    from scipy import signal
    import gyrodenoise as gd
    from gyrodenoise.core import kernels as K
    fs, cutoff = 400.0, 40.0
    x = np.random.default_rng(11).normal(size=40000)
    y = np.asarray(gd.Denoiser(sample_rate_hz=fs, method="lowpass", cutoff_hz=cutoff, order=4,
                               warmup_s=0.0).process(x))
    p = K.make_params(method="lowpass", sample_rate_hz=fs, cutoff_hz=cutoff, order=4)
    sos = [tuple(p[K.P_SOS + 5 * i + j] for j in range(5)) for i in range(int(p[K.P_LP_NSEC]))]
    warm = int(p[K.P_WARMUP])
    nper = 512
    starts = sp.segments(sp.sessions(len(x), None, warm), nper)
    h, coh, delay = sp.cross_response(sp.segment_spectra(x, starts, nper), sp.segment_spectra(y, starts, nper))
    f = sp.freq_hz(nper, fs)
    sos_ref = np.array([[b0, b1, b2, 1.0, a1, a2] for b0, b1, b2, a1, a2 in sos])
    _, h_ref = signal.sosfreqz(sos_ref, worN=f, fs=fs)
    np.testing.assert_allclose(sp.sos_response(sos, f, fs), h_ref, rtol=1e-9, atol=1e-12)
    ok = np.abs(h_ref) > 0.05
    assert np.max(np.abs(np.abs(h[ok]) - np.abs(h_ref[ok]))) < 0.03
    gd_ref = -np.unwrap(np.angle(h_ref)) / (2 * np.pi * np.where(f > 0, f, 1))
    band = ok & (f >= 2 * f[1]) & (f < cutoff)          # bins 0, 1: emptied by the mean removal
    assert np.max(np.abs(delay[band] / fs - gd_ref[band])) < 0.5e-3          # 0.5 ms
    assert np.nanmin(coh[band]) > 0.95


# ------------------------------------------------------------------ the bridge
def _highres_tlog(path, fs=400.0, n=8000, seed=5):
    """SYNTHETIC PX4 tlog: HIGHRES_IMU at ``fs``; x holds an 83 Hz line (1.0 deg/s)
    and its 2nd harmonic (0.4 deg/s), y and z white noise only (0.1 deg/s);
    a reboot at sample n/2 (boot time back to 0.5 s)."""
    from pymavlink.dialects.v20 import ardupilotmega as mav
    m = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs + 10.0
    deg = rng.normal(0, 0.1, size=(n, 3))
    deg[:, 0] += 1.0 * np.sin(2 * np.pi * 83.0 * t) + 0.4 * np.sin(2 * np.pi * 166.0 * t + 0.3)
    t[n // 2:] = t[n // 2:] - t[n // 2] + 0.5
    g = np.radians(deg)
    out = bytearray()
    wall = 1_700_000_000_000_000
    for i, msg in enumerate([mav.MAVLink_heartbeat_message(2, 12, 0, 0, 0, 3)] +
                            [mav.MAVLink_highres_imu_message(int(round(t[i] * 1e6)), 0, 0, -9.8, *g[i],
                                                              0, 0, 0, 0, 0, 0, 20, 0x38, 0) for i in range(n)]):
        wall += 2500
        out.extend(struct.pack(">Q", wall) + msg.pack(m))
    path.write_bytes(bytes(out))


@pytest.mark.slow
def test_bridge_names_the_injected_line_and_the_lowpass_response(tmp_path):
    from gyrodenoise.flightlog.process import process_log
    path = tmp_path / "tones.tlog"
    _highres_tlog(path)
    rep = process_log(path, tmp_path / "out", method="lowpass", filter_kw={"cutoff_hz": 60.0}, csv=False)
    s = rep["streams"][0]
    spec = s["spectrum"]
    assert spec["available"] and spec["response"] == "computed and measured"
    df = spec["resolution_hz"]
    px = spec["peaks"]["x"]
    assert [round(q["freq_hz"] / df) for q in px] == [round(83 / df), round(166 / df)]
    assert abs(px[0]["freq_hz"] - 83.0) <= df and abs(px[1]["freq_hz"] - 166.0) <= df
    assert px[0]["amplitude_deg_s_rms"] == pytest.approx(1.0 / math.sqrt(2), rel=0.05)
    assert px[1]["amplitude_deg_s_rms"] == pytest.approx(0.4 / math.sqrt(2), rel=0.05)
    assert px[1]["harmonic_of_hz"] == pytest.approx(px[0]["freq_hz"]) and px[1]["harmonic_n"] == 2
    assert spec["peaks"]["y"] == [] and spec["peaks"]["z"] == []
    assert spec["dominant_peak"]["axis"] == "x" and spec["dominant_peak"]["freq_hz"] == px[0]["freq_hz"]
    # the filter's gain at the line: measured from the records = the Butterworth's |H| there
    from gyrodenoise.flightlog.spectra import _computed_sos
    sos = _computed_sos("lowpass", 400.0, {"cutoff_hz": 60.0})
    for q in px:
        h = abs(sp.sos_response(sos, [q["freq_hz"]], 400.0)[0])
        assert q["filter_gain"] == pytest.approx(h, abs=0.03)
    fx = spec["filter"]["x"]
    assert fx["measured"] and abs(fx["minus3db_hz"] - fx["computed_minus3db_hz"]) <= df
    assert abs(fx["computed_minus3db_hz"] - 60.0) <= df
    # the text summary names the line and its harmonic, and says when an axis has none
    from gyrodenoise.flightlog.spectra import summary_lines
    lines = summary_lines(spec)
    assert px[0]["present_in_segments"] == 1.0 and px[1]["present_in_segments"] == 1.0   # all along
    assert lines[0].startswith(f"x: vibration {px[0]['freq_hz']:.3g} Hz, 0.71 deg/s rms (in 100 % of "
                               f"segments), harmonics {px[1]['freq_hz']:.3g} Hz, filter gain ")
    assert lines[1:] == ["y, z: no vibration peak (none >= 5 Hz stands 6.02 dB above the noise floor)"]
    png = tmp_path / "out" / "tones.spectrum.png"
    assert s["spectrum_plot"] == str(png)
    _assert_png_drawn(png)


def _assert_png_drawn(path, min_height=300):
    import matplotlib.image as mpimg
    assert path.is_file() and path.stat().st_size > 20_000
    img = mpimg.imread(str(path))
    assert img.shape[0] > min_height and img.shape[1] > 500
    assert float(img[..., :3].std()) > 0.05             # not a blank canvas


PEAK_FIELDS = {"freq_hz", "amplitude_rms", "amplitude_deg_s_rms", "harmonic_of_hz", "harmonic_n", "present_in_segments",
               "harmonics_hz", "filter_gain", "phase_delay_s", "filtered_amplitude_rms"}


@pytest.mark.slow
def test_log171_spectrum_fields_in_the_json_and_png(tmp_path):
    """log171 (50 Hz): a spectrum, a spectrogram (4 min) and the filter's measured
    response per stream; its broadband vibration has no peak 6 dB above the floor,
    and each listed peak (if the method changes that) carries every field."""
    from gyrodenoise.flightlog.process import process_log
    log = shared_file("logs", "log171.bin")
    rep = process_log(log, tmp_path, csv=False)
    json.dumps(rep, allow_nan=False)
    for s in rep["streams"]:
        spec = s["spectrum"]
        assert spec["available"] and spec["rate_hz"] == pytest.approx(50.0)
        assert spec["resolution_hz"] == pytest.approx(50.0 / spec["nperseg"])
        assert spec["segments"] >= 16 and spec["spectrogram_columns"] > 0
        assert set(spec["peaks"]) == set(spec["filter"]) == {"x", "y", "z"}
        for a, peaks in spec["peaks"].items():
            for q in peaks:
                assert PEAK_FIELDS <= set(q) and 5.0 <= q["freq_hz"] <= 25.0
            f = spec["filter"][a]
            assert f["measured"] and f["segments"] >= 16 and 0 < f["mean_coherence"] <= 1
        assert s["spectrum_plot"] == str(tmp_path / "log171.spectrum.png")
    _assert_png_drawn(tmp_path / "log171.spectrum.png", min_height=900)     # 3 streams: one row each


def test_batch_sampler_bursts_spectrum_up_to_1khz(tmp_path):
    """copter_00061: the ISB bursts at ~2 kHz get a spectrum to ~1 kHz from
    segments inside the 1024-sample bursts; the 25 Hz IMU streams one to 12.5 Hz."""
    from gyrodenoise.flightlog.process import process_log
    log = shared_file("logs", "copter_00061-2021-11-21_18-03-38.bin")
    rep = process_log(log, tmp_path, csv=False, plots=False)
    s = {x["name"]: x["spectrum"] for x in rep["streams"]}
    isb = s["ISB.gyro[0]"]
    assert isb["available"] and isb["nperseg"] <= 1024
    assert isb["resolution_hz"] == pytest.approx(2001.6 / isb["nperseg"], rel=1e-3)
    peaks = isb["peaks"]["x"] + isb["peaks"]["y"] + isb["peaks"]["z"]
    assert peaks and all(PEAK_FIELDS <= set(q) and q["amplitude_deg_s_rms"] > 0 for q in peaks)
    assert max(q["freq_hz"] for q in peaks) < 1000.8 and isb["dominant_peak"]["freq_hz"] > 50
    # bursts passed through raw (shorter than the warm-up): no response claimed, a reason given
    for a, f in isb["filter"].items():
        assert f["measured"] or f["reason"]
        assert all((q["filter_gain"] is None) == (not f["measured"]) for q in isb["peaks"][a])
    assert s["IMU[0]"]["available"] and s["IMU[0]"]["resolution_hz"] < 1.0


def test_fleet_report_lists_each_logs_dominant_vibration_peak(tmp_path):
    """The fleet table has each stream's dominant peak, and fleet.md each log's:
    the strongest over the log's streams and axes of the summary's JSON."""
    from gyrodenoise.flightlog.fleet import write_fleet_report
    from gyrodenoise.flightlog.process import process_many
    logs = [shared_file("logs", "log171.bin"), shared_file("logs", "copter_00061-2021-11-21_18-03-38.bin")]
    summary = process_many([str(p) for p in logs], tmp_path / "out", plots=False, csv=False)
    md, js = write_fleet_report(summary, tmp_path / "out", html=False)[:2]
    text = md.read_text()
    assert "| dominant vibration peak |" in next(x for x in text.splitlines() if x.startswith("| log |"))
    section = text.split("## Dominant vibration peak per log")[1]
    rows = json.loads(js.read_text())["rows"]
    for rep in summary["logs"]:
        found = [(s["name"], s["spectrum"]["dominant_peak"]) for s in rep["streams"]
                 if s["spectrum"].get("dominant_peak")]
        line = next(x for x in section.splitlines() if x.startswith(f"- {Path(rep['file']).name}:"))
        if found:               # copter_00061: the ISB bursts' lines; log171: none (broadband)
            best = max(found, key=lambda t: t[1]["amplitude_rms"])
            assert f"{best[0]} {best[1]['axis']} {best[1]['freq_hz']:.3g} Hz" in line
        else:
            assert "no vibration peak" in line
        for s in rep["streams"]:
            row = next(r for r in rows if r["file"] == rep["file"] and r["stream"] == s["name"])
            dp = s["spectrum"].get("dominant_peak")
            assert (row["vibration_peak"] is None) == (dp is None)
            if dp:
                assert row["vibration_peak"]["freq_hz"] == dp["freq_hz"]
    assert sum("no vibration peak" not in x for x in section.splitlines() if x.startswith("- ")) >= 1


def test_presence_tells_a_line_all_along_from_one_loud_burst():
    """20 sessions of 1024 samples (a batch sampler's bursts) at 2 kHz: a 300 Hz
    line in every session, a 120 Hz one only in the last (20x louder, so that
    Welch's mean shows both as peaks): the line is present in >= 90 % of the
    segments, the burst in no more than its own share (3 segments of 57) + 1 %."""
    fs, n_burst, n_sess = 2000.0, 1024, 20
    rng = np.random.default_rng(21)
    t = np.arange(n_burst * n_sess) / fs
    x = rng.normal(0, 0.05, len(t)) + 0.05 * np.sin(2 * np.pi * 300.0 * t)
    last = slice((n_sess - 1) * n_burst, None)
    x[last] += 1.0 * np.sin(2 * np.pi * 120.0 * t[last])
    restarts = np.arange(len(t)) % n_burst == 0
    an = sp.analyse(x, x, fs, restarts, min_freq_hz=5.0, min_ratio=4.0)
    peaks = {round(q["freq_hz"] / 10) * 10: q for q in an["peaks"][0]}
    assert set(peaks) == {120, 300}
    n_seg = len(an["starts"])
    assert peaks[300]["present_in_segments"] >= 0.9
    assert peaks[120]["present_in_segments"] <= 3 / n_seg + 0.01
    # white noise alone: a bin group exceeds twice the floor in ~9.5 % of the segments (3 seeds: 9.3-9.5 %)
    y = rng.normal(size=(200 * 512))
    nper = 512
    starts = sp.segments([(0, len(y))], nper)
    seg = np.abs(sp.segment_spectra(y, starts, nper)) ** 2 * sp.density_scale(nper, fs)
    floor = sp.noise_floor(seg.mean(axis=0), len(starts))
    share = np.mean([sp.presence(seg, floor, k) for k in range(10, 250, 7)])
    assert 0.07 <= share <= 0.12
