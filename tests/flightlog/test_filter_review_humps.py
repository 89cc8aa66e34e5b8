"""The filter review's notch on a broad motor hump (gyrodenoise.flightlog.filter_review):
SYNTHETIC batch-sampler gyro whose truth is known -- a 1/f floor, a band of noise
0.3 octave wide (white noise through a Butterworth band-pass) and/or a narrow line.
The hump, which the narrow-peak finder never marks, gets the harmonic notch: its
centre within 5 % of the band's true power centroid, its bandwidth covering the band,
and a predicted attenuation of the band's power of 10 dB or more; a narrow line keeps
its notch as before; a floor alone gets none."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import signal

from gyrodenoise.flightlog import filter_review as fr
from gyrodenoise.flightlog import vehicle_filters as vf
from gyrodenoise.flightlog.autopilots import named
from gyrodenoise.flightlog.streams import RAD_TO_DEG, GyroStream

FS = 2000.0
BURST = 1024
N_BURSTS = 32
BAND_HZ = (113.0, 147.0)
PARAMS = {"INS_GYRO_FILTER": 40.0, "INS_HNTCH_ENABLE": 0.0, "INS_LOG_BAT_MASK": 1.0, "INS_LOG_BAT_OPT": 0.0,
          "INS_GYR_ID": 1.0, "INS_GYR2_ID": 0.0, "INS_GYR3_ID": 0.0, "MOT_THST_HOVER": 0.3}
BP = signal.butter(4, BAND_HZ, btype="bandpass", fs=FS, output="sos")
#: the motor band's third harmonic: three times the band
BP3 = signal.butter(4, (3 * BAND_HZ[0], 3 * BAND_HZ[1]), btype="bandpass", fs=FS, output="sos")


def _true_centroid_hz():
    """The power centroid of the injected band: sum(f |H|^2) / sum(|H|^2) of the band-pass."""
    f = np.linspace(1.0, FS / 2, 20000)
    _, h = signal.sosfreqz(BP, worN=f, fs=FS)
    w = np.abs(h) ** 2
    return float(np.sum(f * w) / np.sum(w))


def _pink(rng, n):
    """1/f noise (power ~ 1/f) of unit variance: white noise shaped in the frequency domain."""
    spec = np.fft.rfft(rng.normal(size=n))
    f = np.fft.rfftfreq(n, 1.0 / FS)
    spec[1:] /= np.sqrt(f[1:] / f[1])
    spec[0] = 0.0
    x = np.fft.irfft(spec, n)
    return x / x.std()


def _band(rng, sos, rms):
    """``rms`` deg/s of white noise through ``sos``, the filter run in over 4 bursts' worth."""
    unit = np.sqrt(np.mean(signal.sosfilt(sos, rng.normal(size=20000))[2000:] ** 2))
    return rms * signal.sosfilt(sos, rng.normal(size=5 * BURST))[-BURST:] / unit


def _stream(seed=3, hump_deg_s=3.0, floor_deg_s=3.0, line_hz=None, line_deg_s=0.0, third_deg_s=0.0):
    """SYNTHETIC batch-sampler gyro (rad/s, as ISBD is read): bursts of BURST samples at FS,
    each axis a 1/f floor of ``floor_deg_s`` rms, plus on x and y the band-limited hump of
    ``hump_deg_s`` rms, its third harmonic (a band 3 x as wide at 3 x) of ``third_deg_s`` rms and a
    line of amplitude ``line_deg_s`` at ``line_hz``."""
    rng = np.random.default_rng(seed)
    t_parts, x_parts = [], []
    for k in range(N_BURSTS):
        t = 3.0 * k + np.arange(BURST) / FS
        x = np.stack([floor_deg_s * _pink(rng, BURST) for _ in range(3)], 1)
        for ax in (0, 1):
            x[:, ax] += _band(rng, BP, hump_deg_s)
            if third_deg_s:
                x[:, ax] += _band(rng, BP3, third_deg_s)
            if line_hz:
                x[:, ax] += line_deg_s * np.sin(2 * np.pi * line_hz * t + ax)
        t_parts.append(t)
        x_parts.append(x)
    t = np.concatenate(t_parts)
    x = np.concatenate(x_parts)
    return GyroStream(name="ISB.gyro[0]", message="ISBD", unit="rad/s", to_deg_s=RAD_TO_DEG, time_s=t,
                      raw=x / RAD_TO_DEG, index=np.arange(len(t)))


def _review(stream, params=PARAMS, autopilot="ardupilot"):
    ap = named(autopilot)
    review, note, plot = fr.filter_review([stream], ap, params, vf.vehicle_filters(ap, params))
    assert note == ""
    return review, plot


@pytest.fixture(scope="module")
def hump_review():
    return _review(_stream())


def test_the_narrow_peak_finder_alone_misses_the_hump(hump_review):
    """The premise: no narrow peak at the band is fit for a notch; the hump is listed."""
    review, _ = hump_review
    assert not any(BAND_HZ[0] <= p["freq_hz"] <= BAND_HZ[1] and p["notch_ok"] for p in review["peaks"])
    found = [h for h in review["humps"] if h["axis"] in ("x", "y") and h["notch_ok"]]
    assert found, review["humps"]


def test_a_broad_hump_gets_the_harmonic_notch_on_its_centre(hump_review):
    review, _ = hump_review
    truth = _true_centroid_hz()
    rec = review["recommended"]
    assert rec["INS_HNTCH_ENABLE"] == 1 and rec["INS_HNTCH_MODE"] == 1
    assert rec["INS_HNTCH_FREQ"] == pytest.approx(truth, rel=0.05), (rec["INS_HNTCH_FREQ"], truth)
    # bandwidth: at least half the centre (the wiki's rule) and at least the hump's band
    hump = review["notch_prediction"]
    lo, hi = hump["band_hz"]
    assert hump["kind"] == "hump"
    assert rec["INS_HNTCH_BW"] >= rec["INS_HNTCH_FREQ"] / 2 - 0.05
    assert rec["INS_HNTCH_BW"] >= (hi - lo) - 0.05
    # the band found is the injected one, within the smoothing grid's 1/24 octave and a bit
    assert lo == pytest.approx(BAND_HZ[0], rel=0.08) and hi == pytest.approx(BAND_HZ[1], rel=0.08)
    # the predicted attenuation of the hump's power by the notch alone
    assert hump["attenuation_of_band_db"] >= 10.0, hump
    assert hump["attenuation_at_peak_db"] >= 30.0, hump
    # ... computed independently from the recommended parameters as the vehicle runs them
    _, plot = hump_review
    stages = vf.vehicle_filters(named("ardupilot"), {**PARAMS, **rec})["stages"]
    notch = [s for s in stages if s["kind"] == "harmonic_notch"]
    f = plot.freq_hz
    sel = (f >= lo) & (f <= hi)
    h2 = np.abs(vf.chain_response(notch, f[sel], review["filter_rate_hz"])) ** 2
    p = plot.psd_pre[fr.AXES.index(review["humps"][0]["axis"])][sel]
    att = -10 * np.log10(np.sum(h2 * p) / np.sum(p))
    assert att == pytest.approx(hump["attenuation_of_band_db"], abs=0.15)
    # sane: above 20 Hz, below Nyquist; the low-pass raised, never beyond the fold cap
    assert 20.0 < rec["INS_HNTCH_FREQ"] < review["filter_rate_hz"] / 2
    assert PARAMS["INS_GYRO_FILTER"] <= rec["INS_GYRO_FILTER"] <= review["source"]["fold_hz"]
    assert any("broad hump" in w for w in review["why"])


def test_a_floor_alone_gets_no_notch():
    review, _ = _review(_stream(hump_deg_s=0.0))
    assert not any(k.startswith("INS_HNTCH") for k in review["recommended"])
    assert review["notch_prediction"] is None
    assert not any(h["notch_ok"] for h in review["humps"])
    assert review["why"][0].startswith("no vibration peak")


def test_a_narrow_line_still_gets_its_notch_as_before():
    """A 20 dB line at 210 Hz on the 1/f floor, no hump: the notch on the line (within one
    bin), bandwidth half its centre, and the line is what the prediction is about."""
    review, _ = _review(_stream(hump_deg_s=0.0, line_hz=210.0, line_deg_s=3.0))
    rec = review["recommended"]
    df = review["source"]["resolution_hz"]
    assert abs(rec["INS_HNTCH_FREQ"] - 210.0) <= df
    assert rec["INS_HNTCH_BW"] == pytest.approx(rec["INS_HNTCH_FREQ"] / 2, abs=0.05)
    assert review["notch_prediction"]["kind"] == "line"
    assert review["notch_prediction"]["attenuation_at_peak_db"] > 30.0


def test_the_stronger_of_a_hump_and_a_weak_line_sets_the_notch():
    """A hump (3 deg/s rms) and a weak line at 300 Hz (0.5 deg/s amplitude, above its floor
    but carrying a fraction of the hump's power): the notch goes on the hump."""
    review, _ = _review(_stream(line_hz=300.0, line_deg_s=0.5))
    assert review["recommended"]["INS_HNTCH_FREQ"] == pytest.approx(_true_centroid_hz(), rel=0.05)


def test_a_stronger_third_harmonic_hump_puts_the_notch_on_the_fundamental():
    """The motor band and its third harmonic, the harmonic carrying more power: the notch on
    the fundamental (ArduPilot's harmonic notch: INS_HNTCH_FREQ the fundamental, the
    harmonics in INS_HNTCH_HMNCS, bit n-1 for harmonic n), HMNCS 1 + 4."""
    review, _ = _review(_stream(hump_deg_s=3.0, third_deg_s=5.0))
    rec = review["recommended"]
    assert rec["INS_HNTCH_FREQ"] == pytest.approx(_true_centroid_hz(), rel=0.05), review["humps"]
    assert rec["INS_HNTCH_HMNCS"] == 1 + 4, review["humps"]


def _diff(before, rec):
    """The settings a recommendation changes, by field."""
    return {k: v for k, v in vars(rec.settings).items() if getattr(before, k) != v}


def test_betaflight_rules_for_a_motor_band():
    """Betaflight: the RPM filter follows a motor band above its minimum (no change); a band
    reaching below the minimum lowers it; without the RPM filter the dynamic notch range
    widens to hold the band."""
    from gyrodenoise.flightlog import betaflight_filters as bf

    base = bf.FilterSettings(gyro_rate_hz=8000.0, dyn_notch_count=1, dyn_notch_q=250, dyn_notch_min_hz=125,
                             dyn_notch_max_hz=350, rpm_harmonics=3, rpm_q=800, rpm_min_hz=100)
    rec = bf.recommend(base, noise_peak_hz=128.0, noise_band_hz=(113.0, 147.0))
    assert rec.lines == () and any("RPM filter" in r for r in rec.reasons)
    rec = bf.recommend(base, noise_peak_hz=95.0, noise_band_hz=(82.0, 110.0))
    assert _diff(base, rec) == {"rpm_min_hz": 82}
    no_rpm = dataclasses.replace(base, rpm_harmonics=0)
    rec = bf.recommend(no_rpm, noise_peak_hz=128.0, noise_band_hz=(113.0, 147.0))
    assert _diff(no_rpm, rec) == {"dyn_notch_min_hz": 101}
    rec = bf.recommend(no_rpm, noise_peak_hz=340.0, noise_band_hz=(300.0, 380.0))
    assert _diff(no_rpm, rec) == {"dyn_notch_max_hz": 418}
    # a line (no band): the rule as before
    assert _diff(no_rpm, bf.recommend(no_rpm, noise_peak_hz=47.0)) == {"dyn_notch_min_hz": 42}


def test_log00037_the_motor_band_is_the_dominant_candidate():
    """The shared Betaflight LOG00037.BFL (debug GYRO_SCALED, 1 kHz, RPM filter on from
    100 Hz): the motor band (110-147 Hz, 16-21 dB over the floor) is what the review weighs,
    not the 0.24 deg/s line at 47 Hz that set dyn_notch_min_hz 42 before; nothing absurd
    is recommended (no notch range below 20 Hz, none above Nyquist)."""
    from gyrodenoise.flightlog import formats, parameters

    from tests.helpers import shared_log

    log = formats.read_log(shared_log("betaflight/LOG00037.BFL"))
    ap, params = parameters.log_parameters(log)
    filters = vf.vehicle_filters(ap, params)
    review, note, _ = fr.filter_review(log.gyro, ap, params, filters,
                                       context=fr.review_context(log, ap, params, filters))
    assert note == ""
    ok = [h for h in review["humps"] if h["notch_ok"]]
    assert {h["axis"] for h in ok} == {"x", "y", "z"}
    assert all(100.0 < h["lo_hz"] < h["freq_hz"] < h["hi_hz"] < 150.0 for h in ok), ok
    line = max(review["peaks"], key=lambda p: p["amplitude_rms_deg_s"])
    assert max(h["amplitude_rms_deg_s"] for h in ok) > 4 * line["amplitude_rms_deg_s"]
    assert "dyn_notch_min_hz" not in review["changes"]
    nyquist = review["source"]["sample_rate_hz"] / 2
    assert all(20.0 <= float(v) <= nyquist for k, v in review["changes"].items() if k.endswith("_hz"))
