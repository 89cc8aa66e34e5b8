"""The flight review's time series (gyrodenoise.flightlog.timeseries) from SYNTHETIC logs
written byte by byte: motors read back equal to what was written (ArduPilot's
SERVOn_FUNCTION mapping applied), events, modes and failsafes at their known times and
named, vibration levels per IMU with the cited thresholds, the clip counters, and the
frequency-by-throttle map of a throttle-tracked tone through the log with the notch of
the log's own parameters on it; PX4's actuator_motors and failsafe flags likewise."""
from __future__ import annotations

import numpy as np
import pytest

from gyrodenoise.flightlog.timeseries import EVENT, FAILSAFE, MODE, flight_views

from tests.flightlog.flight_logs import log_of_bytes
from tests.flightlog.synthetic_logs import DataFlashWriter, ULogWriter

FS = 1000.0
F_HZ, REF = 90.0, 0.4
SECONDS = 60.0
#: outputs 1..4 drive motors 2, 1, 4, 3
SERVO_FUNCTIONS = {1: 34, 2: 33, 3: 36, 4: 35}
EVENTS = [(5.0, 10), (30.0, 28), (55.0, 11)]            # ARMED, NOT_LANDED, DISARMED
ERRS = [(40.0, 6, 1), (41.0, 6, 0)]                      # FAILSAFE_BATT raised, cleared
MODES = [(2.0, 0), (20.0, 5)]                            # STABILIZE, LOITER


def _throttle(t):
    return 0.2 + 0.5 * (0.5 - 0.5 * np.cos(2 * np.pi * t / SECONDS))


def ardupilot_log(seed=2):
    """(bytes, written RCOU (t, (n, 4) PWM), VIBE rows) of a SYNTHETIC ArduCopter log:
    IMU at 1 kHz with a 4 deg/s tone at F sqrt(ThO / REF) on every axis, CTUN.ThO and
    RCOU at 10 Hz, VIBE for two IMUs, EV/ERR/MODE at known times, PARM with a throttle
    harmonic notch at F, REF (FM_RAT 0.5) and the SERVOn_FUNCTIONs."""
    rng = np.random.default_rng(seed)
    w = DataFlashWriter()
    w.define("PARM", "QNf", ["TimeUS", "Name", "Value"])
    w.define("MSG", "QZ", ["TimeUS", "Message"])
    w.define("IMU", "QBffffff", ["TimeUS", "I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("CTUN", "Qf", ["TimeUS", "ThO"])
    w.define("RCOU", "QHHHH", ["TimeUS", "C1", "C2", "C3", "C4"])
    w.define("VIBE", "QBfffI", ["TimeUS", "IMU", "VibeX", "VibeY", "VibeZ", "Clip"])
    w.define("EV", "QB", ["TimeUS", "Id"])
    w.define("ERR", "QBB", ["TimeUS", "Subsys", "ECode"])
    w.define("MODE", "QMBB", ["TimeUS", "Mode", "ModeNum", "Rsn"])
    params = {"INS_HNTCH_ENABLE": 1, "INS_HNTCH_MODE": 1, "INS_HNTCH_FREQ": F_HZ, "INS_HNTCH_REF": REF,
              "INS_HNTCH_FM_RAT": 0.5, "INS_HNTCH_HMNCS": 1, "INS_HNTCH_BW": 20, "INS_HNTCH_ATT": 40,
              "INS_GYRO_FILTER": 120, "FRAME_CLASS": 1,
              **{f"SERVO{n}_FUNCTION": f for n, f in SERVO_FUNCTIONS.items()}}
    for name, v in params.items():
        w.add("PARM", 100_000, name, v)
    w.add("MSG", 100_000, "ArduCopter V4.5.7 (0123abcd)")
    t = np.arange(int(SECONDS * FS)) / FS + 1.0
    thr = _throttle(t - 1.0)
    phase = 2 * np.pi * np.cumsum(F_HZ * np.sqrt(thr / REF)) / FS
    gyr = np.radians(4.0 * np.sin(phase)[:, None] + rng.normal(0, 0.5, (len(t), 3)))
    timed = [(s, "EV", (i,)) for s, i in EVENTS] + [(s, "ERR", (a, c)) for s, a, c in ERRS] + \
        [(s, "MODE", (m, m, 1)) for s, m in MODES]
    timed.sort()
    rcou, vibe, k = [], [], 0
    for j in range(len(t)):
        us = int(round(t[j] * 1e6))
        while k < len(timed) and timed[k][0] * 1e6 <= us:
            w.add(timed[k][1], int(round(timed[k][0] * 1e6)), *timed[k][2])
            k += 1
        w.add("IMU", us, 0, *gyr[j], 0.0, 0.0, -9.8)
        if j % 100 == 0:
            w.add("CTUN", us, float(thr[j]))
            pwm = (1100 + 800 * thr[j] + np.array([0, 10, 20, 30]) + rng.integers(0, 5, 4)).astype(int)
            w.add("RCOU", us, *pwm)
            rcou.append((t[j], pwm))
            for imu in (0, 1):
                row = (imu, 5.0 + imu, 6.0, 20.0 + 10 * imu, j // 100 * imu)
                w.add("VIBE", us, *row)
                vibe.append((t[j], row))
    return w.bytes(), rcou, vibe


@pytest.fixture(scope="module")
def ap_views():
    data, rcou, vibe = ardupilot_log()
    return flight_views(log_of_bytes(data, "dataflash")), rcou, vibe


def test_motors_read_back_equal_to_written_in_servo_function_order(ap_views):
    views, rcou, _ = ap_views
    m = views.time.panel("motors").channels
    written = np.array([p for _, p in rcou], dtype=float)
    assert m.unit == "PWM us" and np.allclose(m.time_s, [t for t, _ in rcou], atol=1e-6)
    # SERVO1 is motor 2, SERVO2 motor 1, SERVO3 motor 4, SERVO4 motor 3
    assert list(m.columns) == ["motor 1 (C2)", "motor 2 (C1)", "motor 3 (C4)", "motor 4 (C3)"]
    for (name, col), c in zip(m.columns.items(), (1, 0, 3, 2)):
        assert np.array_equal(col, written[:, c]), name


def test_events_modes_and_failsafes_at_their_times_and_named(ap_views):
    views, _, _ = ap_views
    mk = views.time.markers
    got = {(m.kind, round(m.time_s, 6), m.text) for m in mk}
    assert {(EVENT, 5.0, "EV 10 ARMED"), (EVENT, 30.0, "EV 28 NOT_LANDED"), (EVENT, 55.0, "EV 11 DISARMED"),
            (MODE, 2.0, "mode 0 STABILIZE"), (MODE, 20.0, "mode 5 LOITER"),
            (FAILSAFE, 40.0, "ERR FAILSAFE_BATT (6) ECode 1"),
            (FAILSAFE, 41.0, "ERR FAILSAFE_BATT (6) ECode 0 (cleared)")} <= got
    assert [m.time_s for m in mk] == sorted(m.time_s for m in mk)


def test_vibration_per_imu_with_ardupilots_thresholds_and_clip_counters(ap_views):
    views, _, vibe = ap_views
    v = views.time.panel("vibration")
    assert [(th.level, th.value) for th in v.thresholds] == [("warn", 30.0), ("fail", 60.0)]
    cols = v.channels.columns
    assert sorted(cols) == ["VibeX[0]", "VibeX[1]", "VibeY[0]", "VibeY[1]", "VibeZ[0]", "VibeZ[1]"]
    z1 = cols["VibeZ[1]"]
    assert np.allclose(z1[np.isfinite(z1)], 30.0) and np.allclose(cols["VibeZ[0]"][np.isfinite(cols["VibeZ[0]"])], 20.0)
    clip = views.time.panel("clipping").channels.columns["Clip[1]"]
    assert np.array_equal(clip[np.isfinite(clip)], [row[4] for _, row in vibe if row[0] == 1])


def test_throttle_map_through_the_log_follows_the_tone_and_its_notch(ap_views):
    views, _, _ = ap_views
    (hm,) = [m for m in views.maps if m.x_label.startswith("throttle")]
    df = hm.freq_hz[1] - hm.freq_hz[0]
    ok = hm.windows > 0
    assert ok.sum() >= 20 and hm.x_source == "CTUN.ThO"
    assert np.max(np.abs(hm.ridge_hz()[ok] - F_HZ * np.sqrt(hm.centres[ok] / REF))) <= df
    (line,) = hm.lines
    on_bins = np.interp(hm.centres[ok], line.x, line.freq_hz)
    assert np.max(np.abs(on_bins - hm.ridge_hz()[ok])) <= df
    assert any("RPM" in n for n in views.map_notes)           # no ESC RPM logged: said so


def test_px4_motors_and_failsafe_flags():
    u = ULogWriter()
    u.define("sensor_combined", [("uint64_t", "timestamp"), ("float[3]", "gyro_rad")])
    u.define("actuator_motors", [("uint64_t", "timestamp"), ("float[4]", "control")])
    u.define("vehicle_status", [("uint64_t", "timestamp"), ("uint8_t", "arming_state"), ("uint8_t", "nav_state"),
                                ("bool", "failsafe")])
    u.define("failsafe_flags", [("uint64_t", "timestamp"), ("bool", "battery_warning"),
                                ("bool", "mode_req_attitude")])
    sc, am, vs, ff = (u.subscribe(n) for n in ("sensor_combined", "actuator_motors", "vehicle_status",
                                                "failsafe_flags"))
    written = []
    for j in range(200):
        us = 1000 + j * 50_000
        u.add(sc, us, [0.0, 0.0, 0.0])
        c = [0.1 * (j % 7), 0.2, 0.3, float("nan")]
        u.add(am, us, c)
        written.append(c)
        if j % 20 == 0:
            u.add(vs, us, 2, 2 if j < 100 else 5, int(100 <= j < 140))
            u.add(ff, us, int(j >= 60), 1)
    views = flight_views(log_of_bytes(u.bytes(), "ulog"))
    m = views.time.panel("motors").channels
    assert list(m.columns) == ["motor 1", "motor 2", "motor 3"]      # motor 4 NaN throughout: not a motor
    assert np.allclose(m.columns["motor 1"], np.float32([c[0] for c in written]))
    texts = {(round(k.time_s, 3), k.text) for k in views.time.markers if k.kind != EVENT}
    assert {(3.001, "failsafe_flags.battery_warning raised"), (5.001, "failsafe on"), (7.001, "failsafe off"),
            (0.001, "mode 2 POSCTL"), (5.001, "mode 5 AUTO_RTL")} <= texts
    assert not any("mode_req" in t for _, t in texts)
