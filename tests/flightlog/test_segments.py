"""Flight segments (gyrodenoise.flightlog.segments): exact on SYNTHETIC logs with known
arming, take-off and landing times (DataFlash, telemetry log), and the facts of the
real shared logs (which flew, for how long)."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from gyrodenoise.flightlog.model import Segment
from gyrodenoise.flightlog.segments import flight_segments, flying_time_s, segment_mask

from tests.flightlog.flight_logs import log_of_bytes, shared_flight_log
from tests.flightlog.synthetic_logs import DataFlashWriter, tlog_writer


def _kinds(segs):
    return [(s.kind, s.start_s, s.end_s) for s in segs]


def _synthetic_df(events, n=400, rate_hz=20.0, hover=None):
    """SYNTHETIC DataFlash: CTUN at ``rate_hz`` from t=1 s (ThO 0.1 on the ground, a
    0.2/0.8 alternating in the air, a steady 0.45 in the ``hover`` window), EV ``events``
    [(time_s, id)] and ARM records at the arming events."""
    w = DataFlashWriter()
    w.define("CTUN", "Qf", ["TimeUS", "ThO"])
    w.define("EV", "QB", ["TimeUS", "Id"])
    w.define("ARM", "QBIBB", ["TimeUS", "ArmState", "ArmChecks", "Forced", "Method"])
    t = 1.0 + np.arange(n) / rate_hz
    us = np.rint(t * 1e6).astype(np.int64)
    ev = sorted(events)
    air = np.zeros(n, bool)
    for ts, i in ev:
        air[t >= ts] = i == 28
    k = 0
    for j in range(n):
        while k < len(ev) and ev[k][0] * 1e6 <= us[j]:
            e_us = int(round(ev[k][0] * 1e6))
            w.add("EV", e_us, ev[k][1])
            if ev[k][1] in (10, 11):
                w.add("ARM", e_us, int(ev[k][1] == 10), 0, 0, 0)
            k += 1
        thr = 0.5 + 0.3 * (-1) ** j if air[j] else 0.1
        if hover and hover[0] <= t[j] <= hover[1]:
            thr = 0.45
        w.add("CTUN", int(us[j]), thr)
    return log_of_bytes(w.bytes(), "dataflash")


def test_synthetic_dataflash_arm_takeoff_land_disarm_exact():
    src = _synthetic_df([(3.0, 10), (5.0, 28), (12.0, 18), (14.0, 11)], hover=(7.0, 11.0))
    segs, note = flight_segments(src)
    main = [s for s in _kinds(segs) if s[0] != "hover"]
    assert main == [("ground", 1.0, 3.0), ("armed", 3.0, 5.0), ("flying", 5.0, 12.0),
                    ("armed", 12.0, 14.0), ("ground", 14.0, 20.95)]               # exact: event times
    (hov,) = [s for s in segs if s.kind == "hover"]
    assert segs.index(hov) == 3                                   # listed after its flying segment
    assert (hov.start_s, hov.end_s) == (7.0, 11.0)
    assert "EV NOT_LANDED/LAND_COMPLETE" in note and "hover" in note
    assert flying_time_s(segs) == 7.0
    t = np.array([2.9, 3.0, 5.0, 8.0, 12.0, 12.05, 20.0])
    assert segment_mask(t, segs, "flying").tolist() == [False, False, True, True, True, False, False]
    assert segment_mask(t, segs, "hover").tolist() == [False, False, False, True, False, False, False]


def test_synthetic_dataflash_log_starting_armed_and_throttle_fallback():
    # first arming record a disarm: armed from the start; no land events: the throttle decides
    src = _synthetic_df([(10.0, 11)])
    segs, note = flight_segments(src)
    assert _kinds(segs) == [("armed", 1.0, 10.0), ("ground", 10.0, 20.95)]
    assert "armed at the log's start" in note and "no land events" in note


def test_no_evidence_gives_empty_list_and_note():
    w = DataFlashWriter()
    w.define("BARO", "Qf", ["TimeUS", "Alt"])
    w.add("BARO", 1_000_000, 1.0)
    data = w.bytes()
    segs, note = flight_segments(log_of_bytes(data, "dataflash"))
    assert segs == [] and "ARM.ArmState" in note and "EV" in note
    mav, add, out = tlog_writer()
    add(mav.MAVLink_attitude_message(1000, 0, 0, 0, 0, 0, 0), 1_700_000_000_000_000)
    data = out()
    segs, note = flight_segments(log_of_bytes(data, "tlog"))
    assert segs == [] and "HEARTBEAT" in note


def test_synthetic_tlog_heartbeats_arming_and_active():
    """ArduCopter HEARTBEAT at 1 Hz (placed in boot time by ATTITUDE at 10 Hz), armed
    from 5 s, ACTIVE (in the air) 8-15 s, disarmed at 18 s; a ground station's heartbeat
    (autopilot 8) interleaved and ignored."""
    mav, add, out = tlog_writer()
    wall0 = 1_700_000_000_000_000
    for k in range(200):
        tb = 0.1 * k                                     # boot time, s
        add(mav.MAVLink_attitude_message(int(round(tb * 1000)), 0, 0, 0, 0, 0, 0), wall0 + k * 100_000)
        if k % 10 == 5:
            armed = 5.0 <= tb < 18.0
            active = 8.0 <= tb < 15.0
            add(mav.MAVLink_heartbeat_message(2, 3, 0x80 if armed else 0, 0, 4 if active else 3, 3),
                wall0 + k * 100_000 + 20_000)
            add(mav.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3), wall0 + k * 100_000 + 30_000)
    data = out()
    segs, note = flight_segments(log_of_bytes(data, "tlog"))
    got = [(k, round(a, 3), round(b, 3)) for k, a, b in _kinds(segs)]
    assert got == [("ground", 0.52, 5.52), ("armed", 5.52, 8.52), ("flying", 8.52, 15.52),
                   ("armed", 15.52, 18.52), ("ground", 18.52, 19.52)]
    assert "system_status is ACTIVE" in note


@functools.lru_cache(maxsize=None)
def _real(name):
    return flight_segments(shared_flight_log(name))


def _partition_ok(segs):
    """ground/armed/flying follow one another (within a boot session); hover inside flying."""
    main = [s for s in segs if s.kind != "hover"]
    for a, b in zip(main, main[1:]):
        assert b.start_s == a.end_s or b.start_s < a.end_s - 0.5      # or a reboot
    for h in (s for s in segs if s.kind == "hover"):
        assert any(f.kind == "flying" and f.start_s <= h.start_s and h.end_s <= f.end_s
                   for f in main)
        assert h.end_s - h.start_s >= 3.0


@pytest.mark.parametrize("name", ["copter_00061-2021-11-21_18-03-38.bin", "copter462_notch_fragment.bin",
                                  "copter_2021-12-08_15-42-00.bin", "px4_sample.ulg"])
def test_real_logs_that_never_flew(name):
    """copter_00061: never armed (motors at 1000 us, PreArm errors); the 4.6.2 fragment and
    the disarmed copter: no arming record, throttle 0; px4_sample.ulg: arming_state 0 and the
    motors at 900 us (disarmed) all along, z constant -- it did not fly, whatever its source says."""
    segs, note = _real(name)
    assert segs and {s.kind for s in segs} == {"ground"}, note
    assert flying_time_s(segs) == 0


@pytest.mark.parametrize("name, low_s, high_s", [
    ("log171.bin", 150, 160),                       # armed 72.6 s, NOT_LANDED 82.8 s, crashed at 239.1 s
    ("px4_quad_battery_brownout.ulg", 62, 76), ("px4_quad_ekf_failure.ulg", 70, 80),
    ("px4_quad_gps_interference.ulg", 50, 62), ("px4_vtol_small.ulg", 0.8, 2.0),
    ("copter_00000-2021-12-02_13-34-15.bin", 15, 25),
])
def test_real_logs_that_flew(name, low_s, high_s):
    segs, note = _real(name)
    _partition_ok(segs)
    assert low_s <= flying_time_s(segs) <= high_s, (flying_time_s(segs), note)
    kinds = [s.kind for s in segs if s.kind != "hover"]
    assert "flying" in kinds and kinds[-1] in ("ground", "flying", "after impact")


def test_real_telemetry_log_heartbeats():
    """Real ArduCopter 4.1 tlog (Mission Planner): armed about 3 s on the ground, flies
    about 7 min, disarms; the 44 min tlog on the ground is all ground."""
    segs, note = _real("copter_20211202-132614.tlog")
    _partition_ok(segs)
    assert [s.kind for s in segs if s.kind != "hover"] == ["ground", "armed", "flying", "armed", "ground"]
    assert "HEARTBEAT" in note and 400 < flying_time_s(segs) < 470
    segs, _ = _real("copter_20211123-010337.tlog")
    assert {s.kind for s in segs} == {"ground"}


def test_segment_mask_selects_by_session_and_time():
    """Two boot sessions whose boot times overlap: a sample at 50 s of session 1 is not in
    session 0's flying segment 40-60 s."""
    segs = [Segment("flying", 40.0, 60.0, 0), Segment("ground", 30.0, 90.0, 1)]
    t = np.array([50.0, 50.0, 70.0])
    sess = np.array([0, 1, 0])
    assert segment_mask(t, segs, "flying", sess).tolist() == [True, False, False]
    assert segment_mask(t, segs, "flying").tolist() == [True, True, False]      # time alone


def test_synthetic_tlog_two_boot_sessions_kept_apart():
    """SYNTHETIC telemetry log of two boots written one after the other (boot time 0-20 s,
    then 0-20 s again): the first flies 8-15 s, the second stays on the ground. Each
    segment carries its session; none has zero length."""
    mav, add, out = tlog_writer()
    wall0 = 1_700_000_000_000_000
    for boot in (0, 1):
        for k in range(200):
            tb = 0.1 * k
            wall = wall0 + (boot * 200 + k) * 100_000
            add(mav.MAVLink_attitude_message(int(round(tb * 1000)), 0, 0, 0, 0, 0, 0), wall)
            if k % 10 == 5:
                armed = boot == 0 and 5.0 <= tb < 18.0
                active = boot == 0 and 8.0 <= tb < 15.0
                add(mav.MAVLink_heartbeat_message(2, 3, 0x80 if armed else 0, 0, 4 if active else 3, 3),
                    wall + 20_000)
    data = out()
    segs, note = flight_segments(log_of_bytes(data, "tlog"))
    got = [(s.kind, round(s.start_s, 2), round(s.end_s, 2), s.session) for s in segs]
    assert got == [("ground", 0.52, 5.52, 0), ("armed", 5.52, 8.52, 0), ("flying", 8.52, 15.52, 0),
                   ("armed", 15.52, 18.52, 0), ("ground", 18.52, 19.52, 0), ("ground", 0.52, 19.52, 1)]
    assert "2 boot sessions" in note
    assert all(s.end_s > s.start_s for s in segs)


def test_real_multi_boot_tlog_flying_mask_by_session():
    """copter_20211202-132613.tlog holds 3 boots whose boot times overlap; it flies in
    the first only (77-559 s). Its flying VIBRATION samples are that boot's 482, not
    the 1020 the times alone select; the segment (561.4, 561.4) of no length is gone."""
    from gyrodenoise.flightlog.vibration import vibration_review
    src = shared_flight_log("copter_20211202-132613.tlog")
    segs, _ = flight_segments(src)
    assert all(s.end_s > s.start_s for s in segs)
    assert {s.session for s in segs if s.kind == "flying"} == {0}
    assert {s.session for s in segs} == {0, 1, 2}
    res, _ = vibration_review(src, segs)
    (seg,) = res["segments"]
    vz = seg["figures"]["vibration_z"]
    assert seg["session"] == 0 and vz["samples"] == 482
    assert vz["mean"] == pytest.approx(22.55, abs=0.01) and vz["verdict"] == "warn"
