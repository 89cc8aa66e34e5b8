"""The vehicle's own gyro filters (gyrodenoise.flightlog.vehicle_filters): the biquads
against scipy's freqz of coefficients computed independently from textbook formulas
(scipy's Butterworth and notch designs, the RBJ cookbook peaking filter), the
harmonic-notch and throttle-tracking rules, each stream's stage, and the stages read
from real logs' parameters."""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from scipy import signal

from gyrodenoise.flightlog.autopilots import UNKNOWN, named
from gyrodenoise.flightlog import formats, parameters
from gyrodenoise.flightlog import vehicle_filters as vf
from gyrodenoise.flightlog.streams import GyroStream

from tests.helpers import shared_log


def _db(h):
    return 20.0 * np.log10(np.abs(h))


def _freqz(sos, freq_hz, fs):
    b0, b1, b2, a1, a2 = sos
    return signal.freqz([b0, b1, b2], [1.0, a1, a2], worN=np.asarray(freq_hz, dtype=float), fs=fs)[1]


@pytest.mark.parametrize("fc, fs", [(30.0, 1000.0), (42.0, 2000.0), (40.0, 8000.0), (80.0, 400.0)])
def test_lowpass_is_scipy_butterworth_and_minus_3db_at_cutoff(fc, fs):
    sos = vf.lowpass2p_sos(fc, fs)
    b, a = signal.butter(2, fc, fs=fs)          # bilinear with prewarping: the same filter
    np.testing.assert_allclose(sos, [b[0], b[1], b[2], a[1], a[2]], rtol=1e-10, atol=1e-13)
    f = np.array([1.0, fc, 0.45 * fs])
    h = vf.sos_response([sos], f, fs)
    np.testing.assert_allclose(h, _freqz(sos, f, fs), rtol=1e-12)
    assert _db(h[1]) == pytest.approx(-10 * math.log10(2), abs=1e-9)
    assert abs(h[0]) == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("f0, bw, fs", [(100.0, 20.0, 8000.0), (75.0, 30.0, 1000.0), (150.0, 50.0, 2000.0)])
def test_px4_notch_is_scipy_iirnotch_full_depth_and_its_3db_band_is_bw(f0, bw, fs):
    sos = vf.px4_notch_sos(f0, bw, fs)
    b, a = signal.iirnotch(f0, f0 / bw, fs=fs)
    np.testing.assert_allclose(sos, [b[0], b[1], b[2], a[1], a[2]], rtol=1e-10, atol=1e-13)
    assert abs(vf.sos_response([sos], [f0], fs)[0]) < 1e-6
    # -3 dB edges (the digital band of tan(pi bw / fs)) are bw apart
    f = np.linspace(f0 - 2 * bw, f0 + 2 * bw, 40001)
    g = _db(vf.sos_response([sos], f, fs))
    below = f[g < -10 * math.log10(2)]
    assert below[-1] - below[0] == pytest.approx(bw, rel=2e-3)
    assert vf.px4_notch_sos(f0, bw, 2 * f0) is None       # at Nyquist: PX4 disables it


def _rbj_notch(f0, q, gain_db, fs):
    """The RBJ audio-EQ cookbook peaking filter (gain_db < 0: a notch of that depth)."""
    a_lin = 10 ** (gain_db / 40.0)
    w0 = 2 * math.pi * f0 / fs
    alpha = math.sin(w0) / (2 * q)
    b = [1 + alpha * a_lin, -2 * math.cos(w0), 1 - alpha * a_lin]
    a = [1 + alpha / a_lin, -2 * math.cos(w0), 1 - alpha / a_lin]
    return np.array(b) / a[0], np.array(a) / a[0]


@pytest.mark.parametrize("f0, bw, att, fs", [(97.0, 25.0, 6.0, 2000.0), (80.0, 40.0, 40.0, 1000.0),
                                              (200.0, 50.0, 15.0, 4000.0)])
def test_ardupilot_notch_depth_is_its_attenuation_and_edges_are_its_octaves(f0, bw, att, fs):
    a, q = vf.ardupilot_notch_a_q(f0, bw, att)
    sos = vf.ardupilot_notch_sos(f0, a, q, fs)
    # textbook: ArduPilot's biquad is the RBJ peaking filter of gain -att dB with Q_rbj = Q / A
    b_ref, a_ref = _rbj_notch(f0, q / a, -att, fs)
    np.testing.assert_allclose(sos, [*b_ref, a_ref[1], a_ref[2]], rtol=1e-10, atol=1e-13)
    f = np.linspace(f0 / 3, min(3 * f0, 0.49 * fs), 60001)
    g = _db(_freqz(sos, f, fs))
    np.testing.assert_allclose(g, _db(vf.sos_response([sos], f, fs)), atol=1e-9)
    assert _db(vf.sos_response([sos], [f0], fs)[0]) == pytest.approx(-att, abs=1e-6)
    # the bandwidth: Q from BW in octaves puts the edges at fc 2**(-+oct/2), oct = 2 log2(fc /
    # (fc - bw/2)), where the gain is sqrt((1 + A**4) / 2) (-3 dB for a deep notch) -- exactly in
    # the analogue prototype, here to within the bilinear transform's warping at these fc / fs
    edge_db = 10 * math.log10((1 + a ** 4) / 2)
    inside = f[g < edge_db]
    octaves = 2 * math.log2(f0 / (f0 - bw / 2))
    assert math.log2(inside[-1] / inside[0]) == pytest.approx(octaves, rel=0.05)    # 4.4 % at fc/fs 0.08


def test_harmonic_notch_biquads_harmonics_double_and_nyquist():
    st = {"kind": "harmonic_notch", "path": "rate", "params": "INS_HNTCH_*", "centre_hz": 100.0,
          "bandwidth_hz": 50.0, "attenuation_db": 30.0, "harmonics": [1, 2, 3], "tracking": "fixed",
          "composite": 1, "reference": 0.0, "min_ratio": 1.0}
    fs = 1000.0
    sos = vf.harmonic_notch_sos(st, fs)
    assert len(sos) == 3
    g = _db(vf.sos_response(sos, [100.0, 200.0, 300.0], fs))
    assert np.all(g < -29.0)
    # Q fixed across harmonics: the 2nd harmonic's notch is twice as wide
    a, q = vf.ardupilot_notch_a_q(100.0, 50.0, 30.0)
    assert sos[1] == pytest.approx(vf.ardupilot_notch_sos(200.0, a, q, fs))
    # fundamental 200 Hz: the 3rd harmonic (600 Hz) is above 0.48 fs and not run
    assert len(vf.harmonic_notch_sos(st, fs, centre_hz=200.0)) == 2
    double = dict(st, composite=2, harmonics=[1])
    d = vf.harmonic_notch_sos(double, fs)
    spread = 50.0 / (32 * 100.0)
    assert len(d) == 2
    assert d[0] == pytest.approx(vf.ardupilot_notch_sos(100.0 * (1 - spread), *vf.ardupilot_notch_a_q(100.0, 25.0, 30.0), fs))


def test_throttle_tracking_centre():
    st = {"centre_hz": 97.0, "reference": 0.32, "min_ratio": 0.75}
    assert vf.throttle_notch_centre_hz(st, 0.32) == pytest.approx(97.0)
    assert vf.throttle_notch_centre_hz(st, 0.5) == pytest.approx(97.0 * math.sqrt(0.5 / 0.32))
    assert vf.throttle_notch_centre_hz(st, 0.0) == pytest.approx(97.0 * 0.75)      # the FM_RAT floor
    assert vf.throttle_notch_centre_hz(dict(st, reference=0.0), 0.9) == 97.0         # REF 0: fixed


def test_chain_response_and_phase_lag():
    stages = vf.vehicle_filters(named("ardupilot"), {"INS_GYRO_FILTER": 30.0, "INS_HNTCH_ENABLE": 1,
                                              "INS_HNTCH_FREQ": 80.0, "INS_HNTCH_BW": 40.0,
                                              "INS_HNTCH_ATT": 40.0, "INS_HNTCH_HMNCS": 1,
                                              "INS_HNTCH_MODE": 1, "INS_HNTCH_REF": 0.3})["stages"]
    fs = 1000.0
    f = np.array([30.0, 80.0, 120.0])
    h = vf.chain_response(stages, f, fs)
    lp = vf.lowpass2p_sos(30.0, fs)
    a, q = vf.ardupilot_notch_a_q(80.0, 40.0, 40.0)
    np.testing.assert_allclose(h, vf.sos_response([lp, vf.ardupilot_notch_sos(80.0, a, q, fs)], f, fs), rtol=1e-12)
    # a given centre moves the notch
    h2 = vf.chain_response(stages, [100.0], fs, notch_centre_hz={"INS_HNTCH_*": 100.0})
    assert _db(h2[0]) < -40.0
    # lag of the low-pass alone: -phase / (2 pi f) of the same response
    lags = vf.phase_lag_ms([stages[-1]], [10.0, 20.0, 30.0], fs)
    ph = np.angle(vf.sos_response([lp], [10.0, 20.0, 30.0], fs))
    np.testing.assert_allclose(lags, -ph / (2 * np.pi * np.array([10.0, 20.0, 30.0])) * 1000, rtol=1e-9)
    assert 7.0 < lags[1] < 9.0
    # measured-tracking notch with no centre: left out, and said so
    rpm = [dict(stages[0], tracking="esc")]
    sos, notes = vf.chain_sections(rpm, fs)
    assert sos == [] and "not modelled" in notes[0]


def _stream(name, message):
    return GyroStream(name=name, message=message, unit="rad/s", to_deg_s=1.0,
                      time_s=np.zeros(1), raw=np.zeros((1, 3)), index=np.zeros(1, dtype=int))


@pytest.mark.parametrize("opt, inst, expect", [
    (0, 0, "pre-filter"), (2, 0, "post-filter"), (4, 0, "pre-filter"), (4, 2, "post-filter"),
    (3, 1, "pre-filter"), (3, 2, "post-filter"), (1, 0, "pre-filter")])
def test_batch_sampler_stage_by_ins_log_bat_opt(opt, inst, expect):
    p = {"INS_LOG_BAT_OPT": opt, "INS_GYR_ID": 1234, "INS_GYR2_ID": 5678, "INS_GYR3_ID": 0}
    assert vf.stream_stage(named("ardupilot"), p, _stream(f"ISB.gyro[{inst}]", "ISBD")) == expect
    assert vf.stream_stage(named("ardupilot"), {}, _stream("ISB.gyro[0]", "ISBD")) == "unknown"


def test_stream_stages():
    ap, px4 = named("ardupilot"), named("px4")
    assert vf.stream_stage(ap, {}, _stream("IMU[0]", "IMU")) == "post-filter"
    assert vf.stream_stage(ap, {}, _stream("RAW_IMU", "RAW_IMU")) == "post-filter"
    assert vf.stream_stage(px4, {}, _stream("vehicle_angular_velocity", "vehicle_angular_velocity")) == "post-filter"
    assert vf.stream_stage(px4, {}, _stream("sensor_gyro_fifo", "sensor_gyro_fifo")) == "pre-filter"
    assert vf.stream_stage(px4, {"IMU_INTEG_RATE": 200}, _stream("sensor_combined", "sensor_combined")) == "pre-filter"
    assert vf.stream_stage(px4, {}, _stream("sensor_combined", "sensor_combined")) == "unknown"
    assert vf.stream_stage(UNKNOWN, {}, _stream("RAW_IMU", "RAW_IMU")) == "unknown"


@functools.lru_cache(maxsize=8)
def _log(name):
    log = formats.read_log(shared_log(name))
    ap, params = parameters.log_parameters(log)
    return log.gyro, ap, params, vf.vehicle_filters(ap, params)


def test_copter_00061_lowpass_30_no_notch_batch_pre_filter():
    streams, ap, params, f = _log("copter_00061-2021-11-21_18-03-38.bin")
    assert ap.name == "ardupilot"
    assert [s["kind"] for s in f["stages"]] == ["lowpass"]
    assert f["stages"][0]["cutoff_hz"] == 30.0
    assert f["parameters"]["INS_GYRO_FILTER"] == 30.0 and f["parameters"]["INS_HNTCH_ENABLE"] == 0
    assert f["filter_rate_hz"] == 2000.0           # INS_GYRO_RATE 1 with fast sampling
    stage = {s.name: vf.stream_stage(ap, params, s) for s in streams}
    assert stage == {"IMU[0]": "post-filter", "IMU[1]": "post-filter", "ISB.gyro[0]": "pre-filter"}


def test_copter462_throttle_harmonic_notch_and_pre_filter_batch():
    streams, ap, params, f = _log("copter462_notch_fragment.bin")
    hn = [s for s in f["stages"] if s["kind"] == "harmonic_notch"]
    assert len(hn) == 1
    hn = hn[0]
    assert (hn["centre_hz"], hn["bandwidth_hz"], hn["tracking"], hn["reference"]) == (97.0, 25.0, "throttle", 0.32)
    assert hn["harmonics"] == [1] and hn["attenuation_db"] == 6.0 and hn["min_ratio"] == 0.75
    assert [s["cutoff_hz"] for s in f["stages"] if s["kind"] == "lowpass"] == [42.0]
    isb = next(s for s in streams if s.message == "ISBD")
    assert vf.stream_stage(ap, params, isb) == "pre-filter"      # INS_LOG_BAT_OPT 4, instance 0 < 2 gyros


@pytest.mark.parametrize("name", ["px4_quad_battery_brownout.ulg", "px4_quad_ekf_failure.ulg",
                                  "px4_quad_gps_interference.ulg", "px4_vtol_small.ulg"])
def test_px4_gyro_cutoff_40(name):
    _, ap, params, f = _log(name)
    assert ap.name == "px4"
    rate = [s for s in f["stages"] if s["kind"] == "lowpass" and s["path"] == "rate"]
    assert [s["cutoff_hz"] for s in rate] == [40.0]
    assert not [s for s in f["stages"] if "notch" in s["kind"]]        # NF0 0 Hz, DNF off
