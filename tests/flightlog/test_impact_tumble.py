"""A crash tumble is not a vibration peak: a SYNTHETIC 25 Hz ArduCopter DataFlash log (IMU
after the filters, as the 25 Hz IMU of real Copter 4.1 and ArduSub logs) whose vehicle,
after the impact, tumbles at 9 Hz -- inside the 25 Hz stream's band, above the vibration
review's 5 Hz peak floor. The flight ends at the impact (gyrodenoise.flightlog.impact), so
the flying segment lists no 9 Hz peak; the tumble is shown only in the segment after the
impact, out of the verdict. The same log with the impact cut removed lists it: the test
fails if the cut goes."""
from __future__ import annotations

import numpy as np
import pytest

from gyrodenoise.flightlog import segments as segments_module
from gyrodenoise.flightlog.log_review import log_review

from tests.flightlog.flight_logs import log_of_bytes
from tests.flightlog.synthetic_logs import DataFlashWriter

RATE = 25.0
CRASH_S, END_S, TUMBLE_HZ = 30.0, 50.0, 9.0


def _tumble_log():
    rng = np.random.default_rng(4)
    w = DataFlashWriter()
    w.define("IMU", "QBffffff", ["TimeUS", "I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("CTUN", "Qf", ["TimeUS", "ThO"])
    w.define("ATT", "Qff", ["TimeUS", "Roll", "Pitch"])
    w.define("EV", "QB", ["TimeUS", "Id"])
    w.define("MSG", "QZ", ["TimeUS", "Message"])
    for text in ("ArduCopter V4.1.0 (0123abcd)", "Frame: QUAD/X"):
        w.add("MSG", 900_000, text)
    t = 1.0 + np.arange(int((END_S - 1.0) * RATE)) / RATE
    gyr = rng.normal(0.0, 5.0, (len(t), 3))                                    # deg/s
    acc = rng.normal(0.0, 1.0, (len(t), 3)) + np.array([0.0, 0.0, -9.8])
    hit = (t >= CRASH_S) & (t < CRASH_S + 0.3)
    gyr[hit, 0] = 1500.0
    acc[(t >= CRASH_S) & (t < CRASH_S + 0.04), 2] = 12 * 9.8
    after = t >= CRASH_S + 0.3
    tone = np.sin(2 * np.pi * TUMBLE_HZ * t[after])[:, None]
    gyr[after] = 0.2 * gyr[after] + 400.0 * tone                               # the tumble
    acc[after] += 25.0 * tone * np.array([1.0, 0.8, 0.6])
    gyr = np.radians(gyr)
    events = [(2.0, 10), (4.0, 28)]
    for j, tj in enumerate(t):
        us = int(round(tj * 1e6))
        for te, eid in events:
            if abs(te - tj) < 0.5 / RATE:
                w.add("EV", int(te * 1e6), eid)
        w.add("IMU", us, 0, *gyr[j], *acc[j])
        if j % 5 == 0:
            w.add("CTUN", us, 0.45 if tj >= 4.0 else 0.1)
            w.add("ATT", us, 175.0 if tj >= CRASH_S + 0.3 else 0.0, 0.0)
    return log_of_bytes(w.bytes(), "dataflash")


def _peaks_hz(vib, kind):
    return [p["freq_hz"] for s in vib["segments"] if s["kind"] == kind for p in (s["accel_peaks"] or [])]


def _near(freqs, f0):
    return any(abs(f - f0) < 1.0 for f in freqs)


def test_a_9_hz_crash_tumble_is_not_a_vibration_peak_of_the_flight():
    rev = log_review(_tumble_log())
    assert [i["time_s"] for i in rev.fields["impacts"]] == [pytest.approx(CRASH_S, abs=0.05)]
    vib = rev.fields["vibration"]
    assert not _near(_peaks_hz(vib, "flying"), TUMBLE_HZ), vib["segments"]
    (after,) = [s for s in vib["segments"] if s["kind"] == "after impact"]
    assert after["in_verdict"] is False and _near(_peaks_hz(vib, "after impact"), TUMBLE_HZ)


def test_without_the_impact_cut_the_tumble_would_be_a_flight_peak(monkeypatch):
    """The counter-check: with the impact search removed the flight runs on through the tumble
    and its 9 Hz is listed among the flight's vibration peaks -- what the cut prevents."""
    monkeypatch.setattr(segments_module, "find_impact", lambda *a, **k: None)
    rev = log_review(_tumble_log())
    assert rev.fields["impacts"] == []
    assert _near(_peaks_hz(rev.fields["vibration"], "flying"), TUMBLE_HZ)
