"""Mode changes named per ArduPilot vehicle on SYNTHETIC logs: Plane, Rover and Sub number
their modes differently from Copter (the MAVLink ardupilotmega dialect's PLANE_MODE,
ROVER_MODE, SUB_MODE enums); the vehicle is the one the boot message names, else the
vehicle's HEARTBEAT type in a telemetry log; a vehicle no one names keeps the numbers."""
from __future__ import annotations

import pytest

from gyrodenoise.flightlog import autopilots
from gyrodenoise.flightlog.timeseries import MODE, markers

from tests.flightlog.flight_logs import log_of_bytes
from tests.flightlog.synthetic_logs import DataFlashWriter, tlog_writer


def _dataflash(boot_message, modes):
    w = DataFlashWriter()
    w.define("MSG", "QZ", ["TimeUS", "Message"])
    w.define("IMU", "Qffffff", ["TimeUS", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("MODE", "QMBB", ["TimeUS", "Mode", "ModeNum", "Rsn"])
    if boot_message:
        w.add("MSG", 100_000, boot_message)
    for i in range(100):
        us = 200_000 + 20_000 * i
        for t, m in modes:
            if us - 20_000 < t * 1e6 <= us:
                w.add("MODE", int(t * 1e6), m, m, 1)
        w.add("IMU", us, 0.0, 0.0, 0.0, 0.0, 0.0, -9.8)
    return log_of_bytes(w.bytes(), "dataflash")


def _mode_texts(log):
    return [(round(m.time_s, 3), m.text) for m in markers(log, autopilots.ARDUPILOT) if m.kind == MODE]


@pytest.mark.parametrize("boot, modes, named", [
    ("ArduPlane V4.5.0 (0123abcd)", [(0.5, 5), (1.0, 10), (1.5, 17)], ["FBWA", "AUTO", "QSTABILIZE"]),
    ("APM:Plane V3.1.0", [(0.5, 11), (1.0, 25)], ["RTL", "LOITER_ALT_QLAND"]),
    ("ArduRover V4.2.0", [(0.5, 4), (1.0, 10), (1.5, 12)], ["HOLD", "AUTO", "SMART_RTL"]),
    ("ArduSub V4.1.0", [(0.5, 19), (1.0, 2), (1.5, 21)], ["MANUAL", "ALT_HOLD", "SURFTRAK"]),
    ("ArduCopter V4.5.7", [(0.5, 5), (1.0, 28)], ["LOITER", "TURTLE"]),
])
def test_modes_named_for_the_vehicle_the_boot_message_names(boot, modes, named):
    got = _mode_texts(_dataflash(boot, modes))
    assert got == [(t, f"mode {m} {n}") for (t, m), n in zip(modes, named)]


def test_a_vehicle_no_one_names_keeps_the_numbers():
    assert _mode_texts(_dataflash(None, [(0.5, 5), (1.0, 10)])) == [(0.5, "mode 5"), (1.0, "mode 10")]


@pytest.mark.parametrize("mav_type, named", [(12, ["MANUAL", "SURFACE"]), (10, ["STEERING", "SMART_RTL"]),
                                             (1, ["TRAINING", "RTL"]), (2, ["ALT_HOLD", "BRAKE"])])
def test_telemetry_modes_named_by_the_heartbeat_type(mav_type, named):
    """A telemetry log with no boot message: the autopilot's HEARTBEAT type says the vehicle
    (a ground station's heartbeats, type 6, autopilot 8, outnumbering it, are not the vehicle's)."""
    mav, add, data = tlog_writer()
    first, then = {12: (19, 9), 10: (3, 12), 1: (3, 11), 2: (2, 17)}[mav_type]
    gcs, add_gcs, gcs_data = tlog_writer(sysid=255)
    for i in range(40):
        wall = 1_000_000 + 250_000 * i
        add(mav.MAVLink_heartbeat_message(mav_type, 3, 81, first if i < 20 else then, 4, 3), wall)
        add(mav.MAVLink_attitude_message(250 * i, 0, 0, 0, 0, 0, 0), wall + 1)
        for k in range(2):
            add_gcs(gcs.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3), wall + 2 + k)
    log = log_of_bytes(data() + gcs_data(), "tlog")
    assert _mode_texts(log) == [(0.0, f"mode {first} {named[0]}"), (5.0, f"mode {then} {named[1]}")]
