"""VIBE computed from an accelerometer (gyrodenoise.flightlog.vibration.vibe_levels,
computed_vibe) for logs without VIBE: ArduPilot's definition (the square root of the 2 Hz
first-order low-pass of (accel - its 5 Hz first-order low-pass)^2) against a per-sample
reference loop and analytic truth (a tone's rms), and the time panel a log without VIBE
gets: labelled as computed, ArduPilot's thresholds drawn only from an accelerometer at
VIBE's own rate (1 kHz and up)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from gyrodenoise.flightlog import vibration as vb
from gyrodenoise.flightlog.timeseries import time_views

from tests.flightlog.flight_logs import log_of_bytes
from tests.flightlog.synthetic_logs import DataFlashWriter


def _reference(t, a):
    """VIBE by its definition, one sample at a time (ArduPilot's LowPassFilter form)."""
    dt0 = float(np.median(np.diff(t)))
    head = a[:max(1, int(round(0.1 / dt0)))]
    floor, vibe = head.mean(axis=0), ((head - head.mean(axis=0)) ** 2).mean(axis=0)
    out = np.empty_like(a)
    prev = t[0] - dt0
    for i in range(len(t)):
        dt = t[i] - prev if t[i] > prev else dt0
        prev = t[i]
        a5 = dt / (dt + 1.0 / (2 * math.pi * 5.0))
        a2 = dt / (dt + 1.0 / (2 * math.pi * 2.0))
        floor = floor + a5 * (a[i] - floor)
        vibe = vibe + a2 * ((a[i] - floor) ** 2 - vibe)
        out[i] = np.sqrt(vibe)
    return out


def test_equal_to_the_definition_sample_by_sample_even_and_jittered():
    rng = np.random.default_rng(4)
    for jitter in (0.0, 0.2):
        t = np.cumsum(np.full(3000, 1e-3) * (1 + jitter * rng.uniform(-1, 1, 3000)))
        a = rng.normal(0, 2.0, (3000, 3)) + [0.0, 0.0, -9.8]
        np.testing.assert_allclose(vb.vibe_levels(t, a), _reference(t, a), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("freq_hz, amp", [(150.0, 3.0), (60.0, 10.0)])
def test_a_tone_reads_its_rms(freq_hz, amp):
    """A tone far above the 5 Hz floor: VIBE -> A/sqrt(2) (within 3 %, the 5 Hz filter's
    leak and the 2 Hz filter's ripple), on every axis it is on; the gravity axis' offset
    taken out by the floor."""
    fs = 2000.0
    t = np.arange(int(10 * fs)) / fs
    a = np.zeros((len(t), 3))
    a[:, 0] = amp * np.sin(2 * np.pi * freq_hz * t)
    a[:, 2] = -9.8 + amp * np.sin(2 * np.pi * freq_hz * t + 1.0)
    lv = vb.vibe_levels(t, a)[t > 2.0]
    for k in (0, 2):
        assert np.median(lv[:, k]) == pytest.approx(amp / math.sqrt(2), rel=0.03)
    assert np.max(lv[:, 1]) == 0.0


def _log_without_vibe(rate_hz, seconds=20.0, amp=40.0):
    """A SYNTHETIC DataFlash log (no VIBE) with IMU gyro and accelerometer at ``rate_hz``,
    the accelerometer x holding a tone of amplitude ``amp`` m/s/s at 0.4 x the rate."""
    w = DataFlashWriter()
    w.define("IMU", "QBffffff", ["TimeUS", "I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    t = np.arange(int(seconds * rate_hz)) / rate_hz + 1.0
    ax = amp * np.sin(2 * np.pi * 0.4 * rate_hz * t)
    for j in range(len(t)):
        w.add("IMU", int(round(t[j] * 1e6)), 0, 0.0, 0.0, 0.0, float(ax[j]), 0.0, -9.8)
    return w.bytes()


@pytest.mark.parametrize("rate_hz", [50.0, 1000.0])
def test_a_log_without_vibe_gets_the_computed_levels(rate_hz):
    log = log_of_bytes(_log_without_vibe(rate_hz), "dataflash")
    assert log.format.vibration_levels(log) is None
    views = time_views(log)
    panel = views.panel("vibration")
    assert panel is not None and "vibration" not in views.missing
    assert "computed" in panel.channels.source and "by gyrodenoise" in panel.title
    assert "computed by gyrodenoise" in panel.channels.note
    lv = panel.channels.columns
    late = panel.channels.time_s > 5.0
    # the tone's rms times |1 - H5| at its frequency (H5: the 5 Hz first-order low-pass as
    # run at the log's rate, a / (1 - (1 - a) z^-1): at 50 Hz it passes a third of 20 Hz)
    dt = 1.0 / rate_hz
    a5 = dt / (dt + 1.0 / (2 * math.pi * 5.0))
    z = np.exp(-2j * math.pi * 0.4)
    keep = abs(1.0 - a5 / (1.0 - (1.0 - a5) * z))
    assert np.median(lv["VibeX"][late]) == pytest.approx(40.0 / math.sqrt(2) * keep, rel=0.05)
    assert np.nanmax(lv["VibeY"]) == 0.0
    # the logged IMU accelerometer is low-passed (INS_ACCEL_FILTER): never VIBE's input,
    # whatever its rate: no ArduPilot thresholds, and the note says why
    assert panel.thresholds == []
    assert "low-passed or averaged before it was logged" in panel.channels.note
    assert ("sampled below 1000 Hz" in panel.channels.note) is (rate_hz < 1000.0)


@pytest.mark.parametrize("rate_hz, raw, judged", [(2000.0, True, True), (500.0, True, False),
                                                   (2000.0, False, False)])
def test_judged_only_on_a_raw_accelerometer_at_vibes_rate(rate_hz, raw, judged):
    t = np.arange(int(3 * rate_hz)) / rate_hz
    acc = np.zeros((len(t), 3))
    cv = vb.computed_vibe({"source": "test", "time_s": t, "xyz": acc, "raw": raw})
    assert cv["judged"] is judged
    assert ("thresholds are not drawn" in cv["note"]) is not judged


def test_equal_to_the_logged_vibe_on_the_batch_samplers_raw_accelerometer():
    """copter_00061 (ArduCopter 4.1, ../shared/data) logs VIBE and the batch sampler's raw
    accelerometer (ISBH type 0, 2 kHz bursts of 1024 samples): VIBE computed over each
    burst, its last 0.1 s against the logged VIBE of that IMU there, agrees to 1-2 % in the
    median (measured 1.01, 1.02, 1.02 on x, y, z) and within 12 % on every burst."""
    from tests.flightlog.flight_logs import shared_flight_log
    log = shared_flight_log("copter_00061-2021-11-21_18-03-38.bin")
    h, d, v = log.messages("ISBH"), log.messages("ISBD"), log.messages("VIBE")
    vt, vi = np.asarray(v["time_s"]), np.asarray(v["IMU"])
    ratios = []
    for hi in np.flatnonzero(np.asarray(h["type"]) == 0):
        sel = np.flatnonzero(d["N"] == h["N"][hi])
        sel = sel[np.argsort(d["seqno"][sel])]
        n = min(32 * len(sel), int(h["smp_cnt"][hi]))
        acc = np.stack([np.asarray(d[c])[sel].reshape(-1)[:n] for c in "xyz"], 1) / float(h["mul"][hi])
        t = h["SampleUS"][hi] * 1e-6 + np.arange(n) / float(h["smp_rate"][hi])
        near = (vi == h["instance"][hi]) & (vt >= t[-1] - 0.15) & (vt <= t[-1] + 0.05)
        if not near.any():
            continue
        ours = vb.vibe_levels(t, acc)[t >= t[-1] - 0.1].mean(axis=0)
        ratios.append(ours / np.array([np.mean(v[c][near]) for c in ("VibeX", "VibeY", "VibeZ")]))
    ratios = np.array(ratios)
    assert len(ratios) >= 20
    np.testing.assert_allclose(np.median(ratios, axis=0), 1.0, atol=0.04)
    assert np.all(np.abs(ratios - 1.0) < 0.12), ratios
