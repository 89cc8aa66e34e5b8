"""Vibration review (gyrodenoise.flightlog.vibration): the arithmetic exact on a SYNTHETIC
DataFlash log with known VIBE values and clip counts, the thresholds' table, and real
shared logs (a clipping ArduCopter telemetry log, a PX4 quad over its flight)."""
from __future__ import annotations

import functools
import json

import numpy as np
import pytest

from gyrodenoise.flightlog.segments import flight_segments
from gyrodenoise.flightlog.vibration import THRESHOLDS, vibration_review

from tests.flightlog.flight_logs import log_of_bytes, shared_flight_log
from tests.flightlog.synthetic_logs import DataFlashWriter


def _synthetic(with_imu=True):
    """SYNTHETIC DataFlash (ArduPilot 4.x layout): VIBE per IMU instance at 10 Hz from
    1 s to 20.9 s; armed at 3 s, in the air 5-15 s, disarmed at 18 s. IMU 0: VibeX 10 on
    the ground and 20 + k % 5 in the air, VibeZ 45 in the air (warn), Clip rising by 3
    in the air; IMU 1: VibeZ 70 in the air (fail). IMU AccX with a 40 Hz tone at 400 Hz."""
    w = DataFlashWriter()
    w.define("VIBE", "QBfffI", ["TimeUS", "IMU", "VibeX", "VibeY", "VibeZ", "Clip"])
    w.define("EV", "QB", ["TimeUS", "Id"])
    w.define("IMU", "QBfff", ["TimeUS", "I", "AccX", "AccY", "AccZ"])
    for ts, i in ((3.0, 10), (5.0, 28), (15.0, 18), (18.0, 11)):
        w.add("EV", int(ts * 1e6), i)
    clip = 0
    for k in range(200):
        us = 1_000_000 + 100_000 * k
        air = 5.0 <= us * 1e-6 <= 15.0
        if air and k % 30 == 0:
            clip += 1
        w.add("VIBE", us, 0, 20.0 + k % 5 if air else 10.0, 5.0, 45.0 if air else 1.0, clip)
        w.add("VIBE", us, 1, 1.0, 1.0, 70.0 if air else 1.0, 0)
    if with_imu:
        rng = np.random.default_rng(1)
        for j in range(int(20 * 400)):
            t = 1.0 + j / 400
            w.add("IMU", int(round(t * 1e6)), 0, 2.0 * np.sin(2 * np.pi * 40 * t) + rng.normal(0, 0.1),
                  rng.normal(0, 0.1), -9.8 + rng.normal(0, 0.1))
    data = w.bytes()
    return log_of_bytes(data, "dataflash")


@functools.lru_cache(maxsize=1)
def _synthetic_review():
    src = _synthetic()
    segs, _ = flight_segments(src)
    return segs, vibration_review(src, segs)


def test_synthetic_vibe_figures_exact_over_flying_time():
    segs, (res, note) = _synthetic_review()
    assert [s.kind for s in segs if s.kind != "hover"] == ["ground", "armed", "flying", "armed", "ground"]
    assert res["source"] == "VIBE" and res["over"] == "flying" and "95th percentile" in note
    (seg,) = res["segments"]
    assert (seg["start_s"], seg["end_s"]) == (5.0, 15.0)
    fig = seg["figures"]
    x = np.array([20.0 + k % 5 for k in range(40, 141)])          # samples 5.0 .. 15.0 s
    assert fig["imu0.VibeX"] == {"mean": float(f"{x.mean():.4g}"), "max": 24.0,
                                 "p95": float(f"{np.percentile(x, 95):.4g}"), "samples": 101, "verdict": "pass",
                                 "unit": "m/s/s", "threshold": {"warn": 30.0, "fail": 60.0}}
    assert fig["imu0.VibeZ"]["p95"] == 45.0 and fig["imu0.VibeZ"]["verdict"] == "warn"
    assert fig["imu1.VibeZ"]["max"] == 70.0 and fig["imu1.VibeZ"]["verdict"] == "fail"
    # clip counter: +1 at samples 60, 90, 120 (6, 9, 12 s) -> 3 in the air
    clip_th = {"warn": 1, "fail": 100}
    assert fig["imu0.Clip"] == {"increase": 3, "verdict": "warn", "unit": "count", "threshold": clip_th}
    assert fig["imu1.Clip"] == {"increase": 0, "verdict": "pass", "unit": "count", "threshold": clip_th}
    assert seg["verdict"] == "fail" and res["verdict"] == "fail"
    # the accelerometer spectrum finds the 40 Hz tone (rms 2/sqrt(2))
    top = seg["accel_peaks"][0]
    assert top["freq_hz"] == pytest.approx(40.0, abs=0.5)
    assert top["amplitude_rms_m_s2"] == pytest.approx(2 / np.sqrt(2), rel=0.1)
    json.dumps(res)                                                 # JSON-able as it is


def test_whole_log_and_thresholds_table():
    src = _synthetic(with_imu=False)
    segs, _ = flight_segments(src)
    res, _ = vibration_review(src, segs, over="whole")
    (seg,) = res["segments"]
    assert res["over"] == "whole log" and seg["kind"] == "whole log"
    assert seg["figures"]["imu0.VibeX"]["samples"] == 200 and seg["figures"]["imu0.VibeX"]["max"] == 24.0
    assert seg["accel_peaks"] is None
    assert set(res["thresholds"]) == {"vibe_m_s2", "clip_increase"}
    assert THRESHOLDS["vibe_m_s2"]["warn"] == 30 and THRESHOLDS["vibe_m_s2"]["fail"] == 60
    assert all(v["source"].startswith("https://") and v["says"] for v in THRESHOLDS.values())
    # no flying segment: the whole log, said in the note
    res, note = vibration_review(src, [])
    assert res["over"] == "whole log" and "no flying segment" in note
    with pytest.raises(ValueError):
        vibration_review(src, segs, over="hover")


def test_nothing_to_review_gives_none_and_note():
    w = DataFlashWriter()
    w.define("BARO", "Qf", ["TimeUS", "Alt"])
    w.add("BARO", 1_000_000, 1.0)
    data = w.bytes()
    res, note = vibration_review(log_of_bytes(data, "dataflash"), [])
    assert res is None and "VIBE" in note and "IMU" in note


@functools.lru_cache(maxsize=None)
def _real(name, over="flying"):
    src = shared_flight_log(name)
    segs, _ = flight_segments(src)
    return vibration_review(src, segs, over=over)


def test_real_copter_tlog_clips_in_flight():
    """Real ArduCopter 4.1 telemetry log: VIBRATION over its 7 min flight; accelerometer 0
    clipped thousands of times in the air (fail), VibeZ p95 above 30 m/s/s (warn)."""
    res, _ = _real("copter_20211202-132614.tlog")
    (seg,) = res["segments"]
    assert res["source"] == "VIBRATION" and res["over"] == "flying"
    assert seg["figures"]["clipping_0"]["increase"] > 1000 and seg["figures"]["clipping_0"]["verdict"] == "fail"
    assert seg["figures"]["vibration_z"]["verdict"] == "warn" and res["verdict"] == "fail"


def test_real_px4_quad_metrics_and_spectrum():
    res, _ = _real("px4_quad_battery_brownout.ulg")
    (seg,) = res["segments"]
    assert res["source"] == "vehicle_imu_status" and res["thresholds"].keys() == {
        "accel_vibration_metric_m_s2", "clip_increase"}
    assert seg["figures"]["imu0.accel_vibration_metric"]["verdict"] in ("warn", "fail")
    assert seg["figures"]["imu0.gyro_vibration_metric"]["verdict"] is None     # no published threshold
    assert seg["accel_peaks"] and 5 <= seg["accel_peaks"][0]["freq_hz"] <= 110


def test_real_log_without_levels_spectra_only():
    res, note = _real("log171.bin")               # Copter 3.3: no VIBE message
    assert res["source"] == "accelerometer" and res["verdict"] is None and "no verdict" in note
    seg, after = res["segments"]             # it crashed at 239.14 s: the rest shown, not judged
    assert after["kind"] == "after impact" and after["in_verdict"] is False and after["start_s"] == 239.14
    assert seg["figures"]["accel_band_rms_x"]["max"] < after["figures"]["accel_band_rms_x"]["max"]
    fz = seg["figures"]["accel_band_rms_z"]
    assert fz["band_hz"][0] == 20.0 and fz["band_hz"][1] == pytest.approx(25.0, abs=0.2) and fz["verdict"] is None and fz["threshold"] is None


FIGURE_KEYS = {"mean", "p95", "max", "unit", "threshold", "verdict"}


def _check_shape(figures):
    """Every figure has the documented shape: levels {mean, p95, max, unit, threshold,
    verdict}, clip counters {increase, unit, threshold, verdict}; threshold None or
    {warn, fail}."""
    for name, f in figures.items():
        keys = {"increase", "unit", "threshold", "verdict"} if "increase" in f else FIGURE_KEYS
        assert keys <= set(f), (name, f)
        assert f["threshold"] is None or set(f["threshold"]) == {"warn", "fail"}
        assert f["verdict"] in (None, "pass", "warn", "fail")


def test_figures_shape_documented():
    _, (res, _) = _synthetic_review()
    for seg in res["segments"]:
        _check_shape(seg["figures"])
    assert res["segments"][0]["figures"]["imu0.VibeZ"]["threshold"] == {"warn": 30.0, "fail": 60.0}
    assert res["segments"][0]["figures"]["imu0.VibeZ"]["unit"] == "m/s/s"


@pytest.mark.parametrize("name", ["copter_00000-2021-12-02_13-34-15.bin", "px4_sample.ulg", "log171.bin"])
def test_real_accelerometer_only_logs_get_figures(name):
    """No vibration level logged: the accelerometer's band rms per segment, no verdict
    (copter_00000: IMU at 25 Hz, so the band is 6.25-12.5 Hz)."""
    res, _ = _real(name)
    for seg in res["segments"]:
        assert {"accel_band_rms_x", "accel_band_rms_y", "accel_band_rms_z"} <= set(seg["figures"])
        _check_shape(seg["figures"])
        assert all(f["verdict"] is None for f in seg["figures"].values())
