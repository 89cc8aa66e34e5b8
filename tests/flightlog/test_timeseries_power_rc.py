"""The battery (voltage, current) and RC input panels from SYNTHETIC logs written byte by
byte: values read back equal to what was written, in volts, amperes and PWM us (each
format's scale undone: ArduPilot CURR in cV/cA, MAVLink SYS_STATUS in mV/cA), the
'not measured' values (-1, UINT16_MAX, a channel at 0) left out; Betaflight's 0.01 V
scale checked against the log's own reference voltage (vbatref). An old ArduCopter log's
motors counted from the frame its boot message names."""
from __future__ import annotations

import numpy as np
import pytest

from gyrodenoise.flightlog.timeseries import time_views

from tests.flightlog.flight_logs import log_of_bytes, shared_flight_log
from tests.flightlog.synthetic_logs import DataFlashWriter, ULogWriter, tlog_writer

N = 50


def _finite(v):
    return v[np.isfinite(v)]


def test_ardupilot_bat_two_batteries_and_rcin():
    w = DataFlashWriter()
    w.define("IMU", "Qffffff", ["TimeUS", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("BAT", "QBff", ["TimeUS", "Instance", "Volt", "Curr"])
    w.define("RCIN", "QHHHH", ["TimeUS", "C1", "C2", "C3", "C4"])
    bat, rc = [], []
    for j in range(N):
        us = 100_000 + 20_000 * j
        w.add("IMU", us, 0.0, 0.0, 0.0, 0.0, 0.0, -9.8)
        for i in (0, 1):
            row = (i, 16.8 - 0.01 * j - i, 10.0 + j * 0.5 + i)
            w.add("BAT", us + 1 + i, *row)
            bat.append(row)
        pwm = (1000 + j, 1500, 1500 - j, 1900)
        w.add("RCIN", us + 3, *pwm)
        rc.append(pwm)
    tv = time_views(log_of_bytes(w.bytes(), "dataflash"))
    v, a = tv.panel("battery voltage").channels, tv.panel("battery current").channels
    assert v.unit == "V" and a.unit == "A" and sorted(v.columns) == ["Volt[0]", "Volt[1]"]
    for i in (0, 1):
        assert np.allclose(_finite(v.columns[f"Volt[{i}]"]), np.float32([r[1] for r in bat if r[0] == i]))
        assert np.allclose(_finite(a.columns[f"Curr[{i}]"]), np.float32([r[2] for r in bat if r[0] == i]))
    r = tv.panel("rc").channels
    assert r.unit == "PWM us" and list(r.columns) == ["C1", "C2", "C3", "C4"]
    assert np.array_equal(np.column_stack(list(r.columns.values())), np.array(rc, float))


def test_ardupilot_old_curr_in_centivolts_and_centiamps():
    w = DataFlashWriter()
    w.define("IMU", "Qffffff", ["TimeUS", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("CURR", "QhhI", ["TimeUS", "Volt", "Curr", "CurrTot"])
    for j in range(N):
        w.add("IMU", 100_000 + 20_000 * j, 0.0, 0.0, 0.0, 0.0, 0.0, -9.8)
        w.add("CURR", 100_001 + 20_000 * j, 1549 - j, 1407 + j, j)
    tv = time_views(log_of_bytes(w.bytes(), "dataflash"))
    assert np.allclose(tv.panel("battery voltage").channels.columns["Volt"], (1549 - np.arange(N)) / 100.0)
    assert np.allclose(tv.panel("battery current").channels.columns["Curr"], (1407 + np.arange(N)) / 100.0)
    assert "rc" in tv.missing and "RCIN" in tv.missing["rc"]


def test_telemetry_sys_status_and_rc_channels_unset_values_left_out():
    mav, add, data = tlog_writer()
    for j in range(N):
        wall = 1_000_000 + 100_000 * j
        add(mav.MAVLink_heartbeat_message(2, 3, 81, 0, 4, 3), wall)        # ArduPilot (autopilot 3), a quad
        add(mav.MAVLink_attitude_message(100 * j, 0, 0, 0, 0, 0, 0), wall)
        # current -1: not measured (the first half)
        add(mav.MAVLink_sys_status_message(0, 0, 0, 500, 15287 - j, -1 if j < N // 2 else 200 + j, 80,
                                           0, 0, 0, 0, 0, 0), wall + 1)
        add(mav.MAVLink_rc_channels_message(100 * j, 4, 1000 + j, 1500, 1500, 1500, *([65535] * 14), 255), wall + 2)
    tv = time_views(log_of_bytes(data(), "tlog"))
    v = tv.panel("battery voltage").channels.columns["voltage_battery"]
    a = tv.panel("battery current").channels.columns["current_battery"]
    assert np.allclose(v, (15287 - np.arange(N)) / 1000.0)
    assert np.isnan(a[:N // 2]).all() and np.allclose(a[N // 2:], (200 + np.arange(N // 2, N)) / 100.0)
    r = tv.panel("rc").channels
    assert list(r.columns) == ["chan1_raw", "chan2_raw", "chan3_raw", "chan4_raw"]     # 5..8 unset: left out
    assert np.array_equal(r.columns["chan1_raw"], 1000.0 + np.arange(N))


def test_px4_battery_status_and_input_rc():
    u = ULogWriter()
    u.define("battery_status", [("uint64_t", "timestamp"), ("float", "voltage_v"), ("float", "current_a")])
    u.define("input_rc", [("uint64_t", "timestamp"), ("uint8_t", "channel_count"), ("uint16_t[18]", "values")])
    bs, rc = u.subscribe("battery_status"), u.subscribe("input_rc")
    for j in range(N):
        us = 1000 + 100_000 * j
        u.add(bs, us, 12.6 - 0.01 * j, -1.0 if j == 0 else 5.0 + j)
        u.add(rc, us + 1, 6, [1000 + j, 1500, 1100, 1500, 1000, 2000] + [0] * 12)
    tv = time_views(log_of_bytes(u.bytes(), "ulog"))
    assert np.allclose(tv.panel("battery voltage").channels.columns["voltage_v"], np.float32(12.6 - 0.01 * np.arange(N)))
    a = tv.panel("battery current").channels.columns["current_a"]
    assert np.isnan(a[0]) and np.allclose(a[1:], 5.0 + np.arange(1, N))
    r = tv.panel("rc").channels
    assert list(r.columns) == [f"ch {i}" for i in range(1, 7)]          # channel_count 6 of 18
    assert np.array_equal(r.columns["ch 1"], 1000.0 + np.arange(N))


def test_betaflight_vbat_in_volts_matches_its_reference_voltage():
    """LOG00037 (Betaflight 4.2): vbatLatest in 0.01 V; the header's vbatref (the battery's
    voltage at boot, same unit) within 0.5 V of the first samples; rcCommand's throttle
    in 1000..2000 (give or take a count)."""
    log = shared_flight_log("betaflight/LOG00037.BFL")              # skips where the shared data is absent
    tv = time_views(log)
    v = tv.panel("battery voltage").channels.columns["vbatLatest"]
    ref = float(log.parameters().values["vbatref"]) * 0.01
    assert abs(np.median(v[:100]) - ref) < 0.5, (np.median(v[:100]), ref)
    thr = tv.panel("rc").channels.columns["throttle (rcCommand[3])"]
    assert 990 <= thr.min() and thr.max() <= 2010 and np.ptp(thr) > 200
    assert tv.panel("battery current").channels.unit == "A"


@pytest.mark.parametrize("boot, motors, why", [("Frame: HEXA/X", 6, "frame HEXA/X in the boot messages"),
                                              (None, 4, "a quad assumed")])
def test_motors_of_an_old_log_from_its_frame_message(boot, motors, why):
    """No SERVOn_FUNCTION nor FRAME_CLASS (ArduCopter 3.3): the frame the boot message names
    says how many outputs are motors."""
    w = DataFlashWriter()
    w.define("MSG", "QZ", ["TimeUS", "Message"])
    w.define("IMU", "Qffffff", ["TimeUS", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("RCOU", "QHHHHHHHH", ["TimeUS", *(f"C{n}" for n in range(1, 9))])
    if boot:
        w.add("MSG", 50_000, boot)
    for j in range(N):
        w.add("IMU", 100_000 + 20_000 * j, 0.0, 0.0, 0.0, 0.0, 0.0, -9.8)
        w.add("RCOU", 100_001 + 20_000 * j, *(1100 + 10 * n + j for n in range(8)))
    m = time_views(log_of_bytes(w.bytes(), "dataflash")).panel("motors").channels
    assert list(m.columns) == [f"motor {n} (C{n})" for n in range(1, motors + 1)]
    assert m.note.endswith(f"({why})") or why in m.note
