"""The autopilot and the parameters of a log (gyrodenoise.flightlog.parameters): the
value before the first arming on SYNTHETIC DataFlash and telemetry logs, PX4's
bytewise integers in PARAM_VALUE, and real logs' filter parameters."""
from __future__ import annotations

import functools
import struct

import pytest

from gyrodenoise.flightlog.autopilots import named
from gyrodenoise.flightlog import parameters

from tests.flightlog.flight_logs import log_of_bytes, shared_flight_log
from tests.flightlog.synthetic_logs import DataFlashWriter, tlog_writer


def test_dataflash_value_before_first_arming():
    w = DataFlashWriter()
    w.define("PARM", "QNf", ["TimeUS", "Name", "Value"])
    w.define("EV", "QB", ["TimeUS", "Id"])
    w.add("PARM", 1_000_000, "INS_GYRO_FILTER", 20.0)
    w.add("PARM", 1_000_100, "INS_HNTCH_REF", 0.32)
    w.add("PARM", 2_000_000, "INS_GYRO_FILTER", 30.0)       # changed on the ground
    w.add("EV", 3_000_000, 10)                               # armed
    w.add("PARM", 4_000_000, "INS_GYRO_FILTER", 60.0)       # changed in flight: not the setting flown
    w.add("PARM", 4_000_100, "ATC_RAT_RLL_P", 0.1)          # first logged after arming: kept
    data = w.bytes()
    ap, p = parameters.log_parameters(log_of_bytes(data, "dataflash"))
    assert ap.name == "ardupilot"
    assert p == {"INS_GYRO_FILTER": 30.0, "INS_HNTCH_REF": 0.32, "ATC_RAT_RLL_P": 0.1}


def test_dataflash_without_arming_keeps_the_first():
    w = DataFlashWriter()
    w.define("PARM", "QNf", ["TimeUS", "Name", "Value"])
    w.add("PARM", 1_000_000, "INS_GYRO_FILTER", 20.0)
    w.add("PARM", 2_000_000, "INS_GYRO_FILTER", 30.0)
    data = w.bytes()
    assert parameters.log_parameters(log_of_bytes(data, "dataflash"))[1] == \
        {"INS_GYRO_FILTER": 20.0}


def _tlog(autopilot, params, armed_at=None):
    mav, add, out = tlog_writer()
    wall = 1_700_000_000_000_000
    add(mav.MAVLink_attitude_message(1000, 0, 0, 0, 0, 0, 0), wall)
    add(mav.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3), wall + 1000)    # a GCS: ignored
    add(mav.MAVLink_heartbeat_message(2, autopilot, 0, 0, 3, 3), wall + 2000)
    for k, (name, value, ptype) in enumerate(params):
        add(mav.MAVLink_param_value_message(name.encode(), value, ptype, len(params), k), wall + 10_000 * (k + 1))
        if armed_at == k:
            add(mav.MAVLink_heartbeat_message(2, autopilot, 0x80, 0, 4, 3), wall + 10_000 * (k + 1) + 5000)
    data = out()
    ap, params = parameters.log_parameters(log_of_bytes(data, "tlog"))
    return ap.name, params


def test_tlog_px4_bytewise_integers_and_autopilot():
    as_float = struct.unpack("<f", struct.pack("<i", 800))[0]     # PX4 sends the int's bits
    ap, p = _tlog(12, [("IMU_GYRO_CUTOFF", 40.0, 9), ("IMU_GYRO_RATEMAX", as_float, 6)])
    assert ap == "px4"
    assert p == {"IMU_GYRO_CUTOFF": 40.0, "IMU_GYRO_RATEMAX": 800}


def test_tlog_ardupilot_value_before_arming():
    ap, p = _tlog(3, [("INS_GYRO_FILTER", 20.0, 9), ("INS_GYRO_FILTER", 30.0, 9), ("INS_GYRO_FILTER", 50.0, 9)],
                  armed_at=1)
    assert ap == "ardupilot" and p == {"INS_GYRO_FILTER": 30.0}


@functools.lru_cache(maxsize=8)
def _log(name):
    ap, params = parameters.log_parameters(shared_flight_log(name))
    return ap.name, params


@pytest.mark.parametrize("name, autopilot, expect", [
    ("copter_00061-2021-11-21_18-03-38.bin", "ardupilot", {"INS_GYRO_FILTER": 30.0, "INS_HNTCH_ENABLE": 0.0,
                                                            "INS_LOG_BAT_MASK": 1.0}),
    ("copter462_notch_fragment.bin", "ardupilot", {"INS_HNTCH_ENABLE": 1.0, "INS_HNTCH_MODE": 1.0,
                                                    "INS_HNTCH_FREQ": 97.0, "INS_HNTCH_BW": 25.0,
                                                    "INS_HNTCH_REF": 0.32, "INS_GYRO_FILTER": 42.0,
                                                    "INS_LOG_BAT_OPT": 4.0}),
    ("px4_quad_battery_brownout.ulg", "px4", {"IMU_GYRO_CUTOFF": 40.0, "IMU_GYRO_FFT_EN": 1,
                                              "IMU_GYRO_DNF_EN": 0, "IMU_GYRO_NF0_FRQ": 0.0,
                                              "IMU_GYRO_RATEMAX": 800}),
    ("px4_vtol_small.ulg", "px4", {"IMU_GYRO_CUTOFF": 40.0}),
])
def test_real_logs(name, autopilot, expect):
    ap, p = _log(name)
    assert ap == autopilot
    assert {k: p[k] for k in expect} == expect


def test_real_tlog_autopilot_from_heartbeat():
    ap, p = _log("sitl_copter_reboot.tlog")
    assert ap == "ardupilot" and p["INS_GYR3_ID"] == 0.0


def test_real_tlog_parameters_from_the_ground_stations_download():
    """copter_2021-12-08-14-59-44.tlog: Mission Planner wrote the FTP parameter download
    as PARAM_VALUE under its own ids (system 255, component 190); the vehicle sent one
    name. Those ~980 parameters are read, and a note says where they came from."""
    got = shared_flight_log("copter_2021-12-08-14-59-44.tlog").parameters()
    ap, params, notes = got.autopilot, got.values, got.notes
    assert ap.name == "ardupilot" and len(params) > 900
    assert params["INS_GYRO_FILTER"] == 20.0 and params["INS_HNTCH_ENABLE"] == 0.0
    assert notes and "system 255 component 190" in notes[0]


def test_apm2_mpu6k_filter_is_the_gyro_lowpass():
    """APM 2.x: INS_MPU6K_FILTER (the MPU6000's own low-pass, Hz; 0 the default 20 Hz)."""
    from gyrodenoise.flightlog.vehicle_filters import vehicle_filters
    (st,) = vehicle_filters(named("ardupilot"), {"INS_MPU6K_FILTER": 42.0})["stages"]
    assert st["kind"] == "lowpass" and st["params"] == "INS_MPU6K_FILTER" and st["cutoff_hz"] == 42.0
    (st,) = vehicle_filters(named("ardupilot"), {"INS_MPU6K_FILTER": 0.0})["stages"]
    assert st["cutoff_hz"] == 20.0 and "default" in st["note"]
    ap, params = parameters.log_parameters(shared_flight_log("apm2_2013-10-13_16-58-51.tlog"))
    assert vehicle_filters(ap, params)["parameters"] == {"INS_MPU6K_FILTER": 0.0}
