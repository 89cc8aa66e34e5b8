"""Betaflight's gyro filter chain (gyrodenoise.flightlog.betaflight_filters): each section
against scipy (freqz of the same difference equation, scipy's Butterworth, the bilinear
transform of the analogue notch), the PTn cutoff corrections against their -3 dB
definition, the dynamic lowpass and RPM rules, settings read from both header
generations, and the ``set`` lines."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog import betaflight_filters as bf

FS = 8000.0

HEADER_42 = {   # LOG00037.BFL (Betaflight 4.2.0), the lines that matter
    "looptime": "125", "gyro_lowpass_type": "0", "gyro_lowpass_hz": "200", "gyro_lowpass_dyn_hz": "240,600",
    "gyro_lowpass2_type": "0", "gyro_lowpass2_hz": "300", "gyro_notch_hz": "0,0", "gyro_notch_cutoff": "0,0",
    "dyn_notch_max_hz": "350", "dyn_notch_width_percent": "0", "dyn_notch_q": "250", "dyn_notch_min_hz": "125",
    "gyro_rpm_notch_harmonics": "3", "gyro_rpm_notch_q": "800", "gyro_rpm_notch_min": "100"}

HEADER_44 = {   # a 4.4-style header (names from 4.3 on)
    "looptime": "125", "gyro_lpf1_type": "0", "gyro_lpf1_static_hz": "250", "gyro_lpf1_dyn_hz": "250,500",
    "gyro_lpf1_dyn_expo": "5", "gyro_lpf2_type": "3", "gyro_lpf2_static_hz": "500",
    "gyro_notch_hz": "0,0", "gyro_notch_cutoff": "0,0", "dyn_notch_count": "3", "dyn_notch_q": "300",
    "dyn_notch_min_hz": "100", "dyn_notch_max_hz": "600", "rpm_filter_harmonics": "3", "rpm_filter_q": "500",
    "rpm_filter_min_hz": "100", "rpm_filter_fade_range_hz": "50"}


def _freqz(b, a, f, fs=FS):
    return signal.freqz(b, a, worN=np.asarray(f, dtype=float), fs=fs)[1]


@pytest.mark.parametrize("fc", [30.0, 200.0, 600.0])
def test_pt1_is_its_difference_equation_and_near_minus_3db_at_cutoff(fc):
    k = bf.pt1_gain(fc, 1 / FS)
    assert k == pytest.approx((1 / FS) / (1 / (2 * math.pi * fc) + 1 / FS))
    f = np.array([1.0, fc, 0.4 * FS])
    stage = bf.Stage("pt1", (bf.pt1_section(k),))
    # y[n] - (1-k) y[n-1] = k x[n]
    np.testing.assert_allclose(stage.response(f, FS), _freqz([k], [1, -(1 - k)], f), rtol=1e-12)
    # a discretised RC: -3 dB at the cutoff, less exactly as the cutoff nears the sample rate
    # (-3.06 dB at 30 Hz, -3.88 dB at 600 Hz when run at 8 kHz)
    assert 20 * np.log10(abs(stage.response([fc], FS)[0])) == pytest.approx(-3.01, abs=0.05 + 12 * fc / FS)


@pytest.mark.parametrize("order", [2, 3])
@pytest.mark.parametrize("fc", [100.0, 300.0])
def test_ptn_cutoff_correction_puts_minus_3db_at_cutoff(order, fc):
    st = bf._lowpass_stage("x", bf.LOWPASS_TYPES.index(f"PT{order}"), fc, FS)
    assert len(st.sections) == order
    k = bf.ptn_gain(order, fc, 1 / FS)
    b, a = [k], [1, -(1 - k)]
    for _ in range(order - 1):
        b, a = np.convolve(b, [k]), np.convolve(a, [1, -(1 - k)])
    np.testing.assert_allclose(st.response([fc, 2 * fc], FS), _freqz(b, a, [fc, 2 * fc]), rtol=1e-12)
    # (a discrete PTn sits a little below: -3.42 dB for a PT3 at 100 Hz run at 8 kHz)
    assert -3.01 - 0.05 - 40 * fc / FS < 20 * np.log10(abs(st.response([fc], FS)[0])) < -2.96
    # without the correction it would sit well below -3 dB
    k_raw = bf.pt1_gain(fc, 1 / FS)
    raw = abs(_freqz([k_raw], [1, -(1 - k_raw)], [fc])[0]) ** order
    assert 20 * np.log10(raw) < -5.5


@pytest.mark.parametrize("fc", [100.0, 500.0, 2000.0])
def test_biquad_lowpass_is_scipy_butterworth(fc):
    b, a = signal.butter(2, fc, fs=FS)
    np.testing.assert_allclose(bf.biquad_lowpass(fc, FS), [b[0], b[1], b[2], a[1], a[2]], rtol=1e-10, atol=1e-13)


@pytest.mark.parametrize("centre, q", [(150.0, 2.5), (300.0, 8.0), (1000.0, 5.0)])
def test_biquad_notch_is_the_bilinear_analogue_notch(centre, q):
    # RBJ's notch: the analogue (s^2 + w^2) / (s^2 + s w / Q + w^2), bilinear, prewarped at the centre
    w = 2 * FS * math.tan(math.pi * centre / FS)
    bz, az = signal.bilinear([1, 0, w * w], [1, w / q, w * w], fs=FS)
    bz, az = bz / az[0], az / az[0]
    np.testing.assert_allclose(bf.biquad_notch(centre, q, FS), [*bz, *az[1:]], rtol=1e-9, atol=1e-12)
    st = bf.Stage("n", (bf.biquad_notch(centre, q, FS),))
    assert abs(st.response([centre], FS)[0]) < 1e-9


def test_static_notch_q_from_centre_and_cutoff():
    # Betaflight's Q = fc * fco / (fc^2 - fco^2): the -3 dB points of the analogue notch at fco and fc^2/fco
    fc, fco = 200.0, 150.0
    q = bf.notch_q(fc, fco)
    assert q == pytest.approx(fc * fco / (fc ** 2 - fco ** 2))
    s = 1j * fco
    h = (s * s + fc * fc) / (s * s + s * fc / q + fc * fc)
    assert abs(h) == pytest.approx(1 / math.sqrt(2), rel=1e-12)


def test_dynamic_lowpass_rules():
    s42 = bf.FilterSettings.from_header(HEADER_42)
    assert s42.lpf1_dynamic
    assert s42.lpf1_cutoff_hz(0.0) == 240                       # the minimum
    assert s42.lpf1_cutoff_hz(1.0) == pytest.approx(600.0)      # 1 * (1 - 1/3) * 1.5 = 1: the maximum
    t = 0.5
    assert s42.lpf1_cutoff_hz(t) == pytest.approx(max(t * (1 - t * t / 3) * 1.5 * 600, 240))
    s44 = bf.FilterSettings.from_header(HEADER_44)
    assert s44.lpf1_cutoff_hz(0.5) == pytest.approx((500 - 250) * (0.5 * 0.5 * 0.5 + 0.5) + 250)
    static = bf.FilterSettings.from_header({**HEADER_42, "gyro_lowpass_dyn_hz": "0,0"})
    assert not static.lpf1_dynamic and static.lpf1_cutoff_hz(0.9) == 200


def test_settings_from_both_header_generations():
    s = bf.FilterSettings.from_header(HEADER_42)
    assert (s.gyro_rate_hz, s.new_names, s.lpf2_static_hz) == (8000.0, False, 300)
    assert (s.dyn_notch_count, s.dyn_notch_q, s.dyn_notch_min_hz, s.dyn_notch_max_hz) == (1, 250, 125, 350)
    assert (s.rpm_harmonics, s.rpm_q, s.rpm_min_hz) == (3, 800, 100)
    assert bf.FilterSettings.from_header({**HEADER_42, "dyn_notch_width_percent": "8"}).dyn_notch_count == 2
    n = bf.FilterSettings.from_header(HEADER_44)
    assert n.new_names and (n.lpf2_type, n.dyn_notch_count, n.rpm_fade_range_hz) == (3, 3, 50)
    with pytest.raises(InputError, match="gyro_lowpass2_type"):
        bf.FilterSettings.from_header({**HEADER_42, "gyro_lowpass2_type": "2"})     # PT2 only from 4.3
    with pytest.raises(InputError, match="looptime"):
        bf.FilterSettings.from_header({k: v for k, v in HEADER_42.items() if k != "looptime"})
    with pytest.raises(InputError, match="gyro_rpm_notch_q"):
        bf.FilterSettings.from_header({**HEADER_42, "gyro_rpm_notch_q": "high"})


def test_rpm_notch_centres_clamp_and_fade():
    s = bf.FilterSettings.from_header(HEADER_42)
    assert s.rpm_centres_hz(80.0) == [(100.0, 1.0), (160.0, 1.0), (240.0, 1.0)]
    assert s.rpm_centres_hz(2000.0)[2] == (0.48 * 8000, 1.0)
    n = bf.FilterSettings.from_header(HEADER_44)
    assert n.rpm_centres_hz(125.0)[0] == (125.0, pytest.approx(0.5))


def test_chain_response_is_the_product_of_its_stages_and_notches_where_told():
    s = bf.FilterSettings.from_header(HEADER_42)
    f = np.array([10.0, 80.0, 150.0, 240.0, 300.0, 1000.0])
    ch = bf.chain_response(s, f, throttle=0.3, motor_hz=(150.0, 150.0, 150.0, 150.0), dyn_notch_hz=(240.0,))
    names = [st.name for st in ch.stages]
    assert sum("RPM" in n for n in names) == 12 and sum("dynamic notch" in n for n in names) == 1
    np.testing.assert_allclose(ch.response, np.prod(np.array(ch.stage_responses), axis=0), rtol=1e-12)
    assert ch.magnitude_db[2] < -60 and ch.magnitude_db[3] < -60       # RPM notch at 150 Hz, dyn notch at 240
    assert ch.magnitude_db[0] == pytest.approx(0.0, abs=0.1)
    assert 1.0 < ch.delay_ms[0] < 3.0       # the notches add lag below their centres
    # the lowpass part alone against scipy: the two PT1s in series
    lp = bf.chain_response(s, f, throttle=0.3)
    k1, k2 = bf.pt1_gain(s.lpf1_cutoff_hz(0.3), 1 / FS), bf.pt1_gain(300, 1 / FS)
    ref = _freqz([k1], [1, -(1 - k1)], f) * _freqz([k2], [1, -(1 - k2)], f)
    np.testing.assert_allclose(lp.response, ref, rtol=1e-12)
    # low-frequency lag of two PT1s: about RC = 1/(2 pi fc) each
    expected_ms = 1e3 * sum(1 / (2 * math.pi * fc) for fc in (s.lpf1_cutoff_hz(0.3), 300.0))
    assert lp.delay_ms[0] == pytest.approx(expected_ms, rel=0.03)
    with pytest.raises(InputError, match="Nyquist"):
        bf.chain_response(s, [5000.0])


def test_set_lines_use_the_firmware_names_and_recommend_gives_reasons():
    s42 = bf.FilterSettings.from_header(HEADER_42)
    assert s42.set_lines(lpf2_static_hz=250, rpm_min_hz=80) == ["set gyro_lowpass2_hz = 250",
                                                                   "set gyro_rpm_notch_min = 80"]
    s44 = bf.FilterSettings.from_header(HEADER_44)
    assert s44.set_lines(lpf1_dyn_min_hz=200) == ["set gyro_lpf1_dyn_min_hz = 200"]
    with pytest.raises(InputError, match="not a Betaflight gyro filter setting"):
        s42.set_lines(gyro_lowpass_hz=100)
    rec = bf.recommend(s42, noise_peak_hz=420.0, motor_hz_range=(70.0, 250.0))
    assert rec.lines == ("set dyn_notch_max_hz = 463", "set gyro_rpm_notch_min = 70")
    assert rec.settings.dyn_notch_max_hz == 463 and len(rec.reasons) == 2
    assert bf.recommend(s42, noise_peak_hz=200.0).lines == ()
    off = bf.FilterSettings.from_header({**HEADER_42, "gyro_rpm_notch_harmonics": "0"})
    assert bf.recommend(off, rpm_available=True).lines == ("set gyro_rpm_notch_harmonics = 3",)
