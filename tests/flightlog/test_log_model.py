"""The typed log model, the format registry and the autopilot strategies
(gyrodenoise.flightlog.model, .formats, .adapters, .autopilots): formats sniffed by
content, no format or autopilot switched on outside an adapter or a strategy, every
GyroStream attribute declared, boots as their own sessions (two DataFlash logs
concatenated), epoch time bases (PX4 SITL ULog, a telemetry log's HIGHRES_IMU)."""
from __future__ import annotations

import functools
import re
from pathlib import Path

import numpy as np
import pytest

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog import autopilots, formats
from gyrodenoise.flightlog.log_review import log_review
from gyrodenoise.flightlog.model import UNIX_EPOCH
from gyrodenoise.flightlog.streams import GyroStream

from tests.flightlog.flight_logs import log_of_bytes
from tests.flightlog.synthetic_logs import tlog_writer
from tests.helpers import shared_log

PACKAGE = Path(__file__).resolve().parents[2] / "gyrodenoise" / "flightlog"
#: where a format or an autopilot may be named in a comparison: its adapter, its strategy,
#: the registries, and the low-level readers (owned by their formats)
ALLOWED = {"formats.py", "autopilots.py", "dataflash.py", "tlog.py", "ulog.py", "blackbox.py", "rosbag.py",
           "betaflight_filters.py"}
NAMES = r"(tlog|dataflash|ulog|ardupilot|px4|betaflight|blackbox|rosbag)"
BRANCH = re.compile(rf"""(==|!=)\s*["']{NAMES}["']|["']{NAMES}["']\s*(==|!=)|\[kind\]|\.get\((kind|autopilot)\)""")


def test_no_format_or_autopilot_branch_outside_adapters_and_strategies():
    """A format or an autopilot compared by its name, or a table looked up by a format
    name, anywhere but in an adapter, a strategy or a registry: each is one more place a
    new format or autopilot would have to touch. (Segment and filter-stage kinds are
    not formats, and are not named here.)"""
    hits = []
    for p in sorted(PACKAGE.rglob("*.py")):
        if p.name in ALLOWED or "adapters" in p.parts:
            continue
        for i, line in enumerate(p.read_text().splitlines(), 1):
            code = line.split("#", 1)[0]
            if BRANCH.search(code):
                hits.append(f"{p.relative_to(PACKAGE)}:{i}: {line.strip()}")
    assert hits == []


def test_every_format_has_the_adapter_interface_and_sniffs_its_logs():
    needed = ("name", "suffixes", "gyro_looked_for", "flight_looked_for", "vibration_looked_for", "sniff", "read",
              "write_filtered", "signing", "keep_signed_raw", "messages", "message_names", "flight_evidence",
              "vibration_levels", "accelerometer", "parameters", "vehicle_rate")
    for f in formats.FORMATS:
        assert all(hasattr(f, k) for k in needed), f.name
    for name, fmt in (("log171.bin", "dataflash"), ("px4_sample.ulg", "ulog"), ("fs-batt.log.tlog", "tlog")):
        assert formats.log_format(shared_log(name)).name == fmt


def test_content_decides_not_the_suffix(tmp_path):
    """A DataFlash log named .ulg is read as DataFlash (the ULog reader never gets a file
    that is not a ULog); a file no format claims is refused in one line."""
    p = tmp_path / "renamed.ulg"
    p.write_bytes(shared_log("ardusub_small.BIN").read_bytes())
    log = formats.read_log(p)
    assert log.format.name == "dataflash" and log.gyro
    junk = tmp_path / "junk.dat"
    junk.write_bytes(b"\x00\x01garbage" * 50)
    with pytest.raises(InputError, match="unknown file type"):
        formats.read_log(junk)


def test_gyro_stream_declares_every_attribute():
    s = GyroStream(name="x", message="IMU", unit="rad/s", to_deg_s=1.0, time_s=np.zeros(1), raw=np.zeros((1, 3)),
                   index=np.zeros(1, np.int64))
    s.left_raw, s.warmup_samples, s._work, s.stage = "why", 3, (None, None, "deg/s", 1.0), "pre-filter"
    with pytest.raises(AttributeError):
        s.not_declared = 1


def test_autopilot_strategies_param_lines_and_registry():
    changes = {"IMU_GYRO_CUTOFF": 44.0, "GYRO_LPF1_STATIC_HZ": 150}
    assert autopilots.named("px4").param_lines(changes)[0] == "param set IMU_GYRO_CUTOFF 44"
    assert autopilots.named("ardupilot").param_lines({"INS_GYRO_FILTER": 37})[0] == "INS_GYRO_FILTER,37"
    assert autopilots.named("betaflight").param_lines({"GYRO_LPF1_STATIC_HZ": 150}) == [
        "set gyro_lpf1_static_hz = 150"]
    assert autopilots.named(None) is autopilots.UNKNOWN and autopilots.from_mav_autopilot(12).name == "px4"


# ------------------------------------------------------------ two boots in one file
@functools.lru_cache(maxsize=2)
def _reviews(tmp_root):
    single = shared_log("log171.bin")
    two = Path(tmp_root) / "two_boots.bin"
    two.write_bytes(single.read_bytes() * 2)
    return (log_review(formats.read_log(single)), formats.read_log(two), log_review(formats.read_log(two)))


@pytest.fixture(scope="module")
def reviews(tmp_path_factory):
    return _reviews(str(tmp_path_factory.mktemp("boots")))


def test_two_dataflash_logs_concatenated_are_two_boots(reviews):
    """log171.bin twice in one file: two boots, each with the segments, flying time and
    VIBE figures of the log alone, on its own time axis (before: one time axis, flying
    171.1 s instead of 342.3 s, boot 2's flight merged into boot 1's)."""
    one, log, two = reviews
    assert [b.index for b in log.boots] == [0, 1]
    assert log.boots[1].first_record == pytest.approx(shared_log("log171.bin").stat().st_size, abs=100)
    f1, f2 = one.fields, two.fields
    assert f2["flying_time_s"] == pytest.approx(2 * f1["flying_time_s"], abs=1e-6)
    assert [b["flying_time_s"] for b in f2["boots"]] == [f1["flying_time_s"]] * 2
    def own(seg):                  # a segment without its boot's number (its impact's too)
        out = {k: v for k, v in seg.items() if k != "session"}
        if "impact" in out:
            out["impact"] = {k: v for k, v in out["impact"].items() if k != "session"}
        return out
    strip = [own(s) for s in f1["segments"]]
    for k in (0, 1):
        got = [s for s in f2["segments"] if s["session"] == k]
        assert [own(s) for s in got] == strip
        assert f2["boots"][k]["segments"] == got
    from gyrodenoise.flightlog.log_review import review_text
    assert "2 boots, each on its own time (flying 156.3, 156.3 s)" in review_text(f2)[0]
    v1, v2 = f1["vibration"]["segments"], f2["vibration"]["segments"]
    assert [s["session"] for s in v2] == [0] * len(v1) + [1] * len(v1)
    for k in (0, 1):
        for a, b in zip(v1, v2[k * len(v1):(k + 1) * len(v1)]):
            assert a["figures"] == b["figures"]


def test_two_boots_flying_mask_selects_each_boots_own_samples(reviews):
    """A gyro sample is flying when its boot and its time are a flying segment's: the
    concatenated log's IMU flying samples are exactly twice the single log's."""
    one, log, two = reviews
    single = formats.read_log(shared_log("log171.bin"))
    s1 = next(s for s in single.gyro if s.name.startswith("IMU"))
    s2 = next(s for s in log.gyro if s.name == s1.name)
    n1 = int(one.flying_mask(s1.time_s, s1.index).sum())
    n2 = int(two.flying_mask(s2.time_s, s2.index).sum())
    assert n1 > 1000 and n2 == 2 * n1


def test_a_step_back_of_one_message_type_is_no_boot():
    """SYNTHETIC: all VIBE records, then all IMU records (each type in time order, the
    file not): one boot, not two."""
    from tests.flightlog.synthetic_logs import DataFlashWriter
    w = DataFlashWriter()
    w.define("VIBE", "Qf", ["TimeUS", "VibeX"])
    w.define("IMU", "Qfff", ["TimeUS", "GyrX", "GyrY", "GyrZ"])
    for k in range(100):
        w.add("VIBE", 1_000_000 + 100_000 * k, 1.0)
    for k in range(400):
        w.add("IMU", 1_000_000 + 25_000 * k, 0.0, 0.0, 0.0)
    assert len(log_of_bytes(w.bytes(), "dataflash").boots) == 1


# --------------------------------------------------------------------- epoch time
def _epoch_ulog(tmp_path, offset_us=1_710_773_350_000_000):
    """px4_vtol_small.ulg with every timestamp moved onto a Unix epoch clock, as PX4
    SITL writes them."""
    import pyulog
    u = pyulog.ULog(str(shared_log("px4_vtol_small.ulg")))
    u._start_timestamp += offset_us
    for d in u.data_list:
        d.data["timestamp"] = d.data["timestamp"] + np.uint64(offset_us)
    u._changed_parameters = [(t + offset_us, n, v) for t, n, v in u.changed_parameters]
    for m in u.logged_messages:
        m.timestamp += offset_us
    p = tmp_path / "sitl_epoch.ulg"
    u.write_ulog(str(p))
    return p


def test_epoch_ulog_time_base_detected_and_segments_relative(tmp_path):
    """Before: axes 'boot time' to 1.71e9 s, segments at 1710773350 s. Now the log's time
    base says Unix epoch, times start at 0 at the log's start, and the segments are
    those of the same log on its boot clock."""
    ref = log_review(formats.read_log(shared_log("px4_vtol_small.ulg"))).fields
    log = formats.read_log(_epoch_ulog(tmp_path))
    rev = log_review(log).fields
    assert rev["time_base"]["kind"] == UNIX_EPOCH and "epoch" in rev["time_base"]["axis"]
    assert rev["time_base"]["offset_s"] > 1.7e9
    assert all(0 <= s.time_s.min() < 1e4 for s in log.gyro)
    assert rev["boots"][0]["wall_clock_offset_s"] == rev["time_base"]["offset_s"]
    shift = ref["boots"][0]["start_s"]
    assert rev["segments"] and len(rev["segments"]) == len(ref["segments"])
    for a, b in zip(rev["segments"], ref["segments"]):
        assert a["kind"] == b["kind"] and a["start_s"] == pytest.approx(b["start_s"] - shift, abs=1e-3)
    assert rev["flying_time_s"] == pytest.approx(ref["flying_time_s"], abs=1e-3)


def test_tlog_epoch_gyro_time_put_on_the_boot_time():
    """SYNTHETIC telemetry log: HIGHRES_IMU at 50 Hz whose time_usec is a Unix time,
    ATTITUDE at 10 Hz with time_boot_ms = 5 s + the same elapsed time. The gyro stream
    lands on the boot time (5 s + t, to the record stamps' jitter), with its own clock
    steps kept; before, its times were 1.7e9 s, beside every other message's boot time."""
    mav, add, out = tlog_writer()
    rng = np.random.default_rng(3)
    wall0, epoch0 = 1_700_000_000_000_000, 1_700_000_000_200_000
    for k in range(500):
        t = k / 50
        wall = wall0 + int(t * 1e6) + int(rng.integers(2000, 9000))       # the ground station's jitter
        add(mav.MAVLink_highres_imu_message(epoch0 + int(round(t * 1e6)), 0, 0, 0, 0.01, 0.02, 0.03,
                                            0, 0, 0, 0, 0, 0, 0, 0), wall)
        if k % 5 == 0:
            add(mav.MAVLink_attitude_message(int(round((5.0 + t) * 1000)), 0, 0, 0, 0, 0, 0), wall)
    log = log_of_bytes(out(), "tlog")
    (s,) = log.gyro
    assert log.time_base.kind != UNIX_EPOCH
    np.testing.assert_allclose(s.time_s, 5.0 + np.arange(500) / 50, atol=2e-3)
    np.testing.assert_allclose(np.diff(s.time_s), 0.02, atol=2e-6)         # the vehicle's clock, no jitter
    assert "Unix time" in s.note


# ------------------------------------------------- flight evidence without arming records
def _plane31(fly=(20.0, 80.0), speed_cm_s=1000, rel_alt_cm=8600):
    """SYNTHETIC ArduPlane 3.1 layout: IMU (TimeMS) at 10 Hz for 100 s, GPS at 5 Hz whose
    TimeMS is the GPS time of week (with Week), 3-D fix; ground speed ``speed_cm_s`` at
    ``rel_alt_cm`` between ``fly``, 0 at 0 m elsewhere; no ARM, EV, CTUN nor RCOU."""
    from tests.flightlog.synthetic_logs import DataFlashWriter
    w = DataFlashWriter()
    w.define("IMU", "Iffffff", ["TimeMS", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("GPS", "BIHBcLLeeEefI", ["Status", "TimeMS", "Week", "NSats", "HDop", "Lat", "Lng", "RelAlt", "Alt",
                                     "Spd", "GCrs", "VZ", "T"])
    for k in range(1000):
        t = k / 10
        w.add("IMU", k * 100, 0.0, 0.0, 0.0, 0.0, 0.0, -9.8)
        if k % 2 == 0:
            air = fly[0] <= t < fly[1]
            w.add("GPS", 3, 300_000_000 + k * 100, 1800, 10, 100, 0, 0, rel_alt_cm if air else 0,
                  1000 + (rel_alt_cm if air else 0), speed_cm_s if air else 0, 0, 0.0, k * 100)
    return log_of_bytes(w.bytes(), "dataflash")


def test_plane_without_arming_records_flies_on_gps_evidence():
    """GPS 10 m/s at 86 m with no ARM/EV/CTUN: flying 20-80 s, the evidence named
    (before: 'no flight evidence'; the GPS time of week was taken for a boot time)."""
    from gyrodenoise.flightlog.segments import flight_segments, flying_time_s
    segs, note = flight_segments(_plane31())
    assert [(s.kind, s.start_s, s.end_s) for s in segs] == [
        ("ground", 0.0, 20.0), ("flying", 20.0, 80.0), ("ground", 80.0, 99.9)]
    assert flying_time_s(segs) == 60.0
    assert "GPS.Spd" in note and "GPS.RelAlt" in note and "no ARM/EV arming record" in note


def test_gps_speed_on_the_ground_is_not_flying():
    """10 m/s at 0 m (a car, a taxi run): ground throughout."""
    from gyrodenoise.flightlog.segments import flight_segments
    segs, _ = flight_segments(_plane31(rel_alt_cm=0))
    assert {s.kind for s in segs} == {"ground"}


def test_html_report_shows_the_boots_and_their_summed_flying_time(reviews, tmp_path):
    """The page's flying time is the report's (summed over the boots: 312.6 s, each boot
    flying until its crash at 239.1 s), not the flying spans merged on one time axis
    (156.3 s, the two boots' spans overlapping),
    and a table lists the boots."""
    from gyrodenoise.flightlog.html_report import write_log_report
    _, log, two = reviews
    page = tmp_path / "two.report.html"
    fields = {k: v for k, v in two.fields.items() if k != "stream_stages"}
    write_log_report(page, {"file": str(log.path), "format": "dataflash", "streams": [], **fields})
    html = page.read_text()
    assert "flying time</td><td>312.6 s" in html
    assert "<h3>Boots</h3>" in html and "the file holds 2 boots" in html


def test_quadplane_tlog_flies_on_height_and_speed():
    """sitl_vtol.tlog (SITL ArduPlane QuadPlane, no EXTENDED_SYS_STATE): in the air from
    its height and speed, take-off after arming to the 'Land complete' message, a
    pymavlink read giving both times (before: never flying, 'not split into flying')."""
    from pymavlink import mavutil
    from gyrodenoise.flightlog.segments import flight_segments
    c = mavutil.mavlink_connection(str(shared_log("sitl_vtol.tlog")))
    t_boot, armed_at, landed_at = None, None, None
    while True:
        m = c.recv_match(type=["GLOBAL_POSITION_INT", "HEARTBEAT", "STATUSTEXT"])
        if m is None:
            break
        if m.get_type() == "GLOBAL_POSITION_INT" and m.get_srcSystem() == 1:
            t_boot = m.time_boot_ms / 1000
        elif m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 1 and m.base_mode & 128 and armed_at is None:
            armed_at = t_boot
        elif m.get_type() == "STATUSTEXT" and "Land complete" in m.text:
            landed_at = t_boot
    segs, note = flight_segments(formats.read_log(shared_log("sitl_vtol.tlog")))
    (fly,) = [s for s in segs if s.kind == "flying"]
    assert armed_at < fly.start_s < armed_at + 5.0
    assert abs(fly.end_s - landed_at) < 2.0
    assert "GLOBAL_POSITION_INT.relative_alt" in note and "VFR_HUD" in note


def test_events_and_modes_equal_pymavlink_and_pyulog(reviews):
    """The model's events and mode changes: DataFlash EV/MSG/MODE as pymavlink reads them
    (each boot of the concatenated log tagged), ULog logged messages as pyulog gives them."""
    from pymavlink import mavutil
    c = mavutil.mavlink_connection(str(shared_log("log171.bin")))
    ev, msg, modes = [], [], []
    while True:
        m = c.recv_match(type=["EV", "MSG", "MODE"])
        if m is None:
            break
        {"EV": ev, "MSG": msg, "MODE": modes}[m.get_type()].append(m)
    log = formats.read_log(shared_log("log171.bin"))
    texts = [e.text for e in log.events()]
    assert sorted(texts) == sorted([f"EV {m.Id}" for m in ev] + [m.Message for m in msg])
    assert [m.mode for m in log.modes()] == [str(m.Mode) for m in modes]
    two = reviews[1]
    assert [e.boot for e in two.events()] == [0] * len(texts) + [1] * len(texts)
    assert [(m.boot, m.mode) for m in two.modes()] == [(b, str(m.Mode)) for b in (0, 1) for m in modes]
    import pyulog
    u = pyulog.ULog(str(shared_log("px4_vtol_small.ulg")))
    ulog = formats.read_log(shared_log("px4_vtol_small.ulg"))
    assert [e.text for e in ulog.events()] == [m.message for m in u.logged_messages]
    np.testing.assert_allclose([e.time_s for e in ulog.events()], [m.timestamp * 1e-6 for m in u.logged_messages])


def test_streams_carry_their_instance():
    got = {n: [(s.name, s.instance) for s in formats.read_log(shared_log(n)).gyro]
           for n in ("log171.bin", "px4_vtol_small.ulg")}
    assert got["log171.bin"] == [("IMU", 0), ("IMU2", 1), ("IMU3", 2)]
    assert got["px4_vtol_small.ulg"][1:] == [("sensor_gyro[0]", 0), ("sensor_gyro[1]", 1), ("sensor_gyro[2]", 2)]


def test_epoch_time_base_on_the_axes_and_in_the_report(tmp_path):
    """The report of a PX4 SITL-like log says its clock (time_base) and its HTML page's
    time axes are labelled with it, not 'boot time' (before: 'boot time [s]' running to
    1.71e9)."""
    from gyrodenoise.flightlog.pipeline import process_log
    rep = process_log(_epoch_ulog(tmp_path), tmp_path / "out", csv=False)
    assert rep["time_base"]["kind"] == UNIX_EPOCH
    html = Path(rep["report_html"]).read_text()
    assert "time since the log's start [s] (Unix epoch clock)" in html
    assert all(s["start_s"] < 1e4 for s in rep["segments"])


def test_damaged_timestamps_and_log_stamps_are_no_boots():
    """ardusub_bad_data.tlog (1967 unreadable records) is one boot, not 906: a boot time
    that steps back for a record or a few is damage; sitl_vtol.tlog's boot time stepping
    back 1.5 s at 612 s is its stamps (README), not a reboot; the three boots of
    copter_20211202-132613.tlog and sitl_copter_reboot.tlog's reboot stay."""
    n = {name: len(formats.read_log(shared_log(name)).boots)
         for name in ("ardusub_bad_data.tlog", "sitl_vtol.tlog", "copter_20211202-132613.tlog",
                      "sitl_copter_reboot.tlog")}
    assert n == {"ardusub_bad_data.tlog": 1, "sitl_vtol.tlog": 1, "copter_20211202-132613.tlog": 3,
                 "sitl_copter_reboot.tlog": 2}


def test_land_events_without_arming_records():
    """SYNTHETIC DataFlash: EV NOT_LANDED at 5 s and LAND_COMPLETE at 12 s, a throttle, no
    ARM and no arming event: flying 5-12 s from the land events (before: 'flight segments
    failed: UnboundLocalError', found by mutating shared logs)."""
    from tests.flightlog.synthetic_logs import DataFlashWriter
    from gyrodenoise.flightlog.segments import flight_segments
    w = DataFlashWriter()
    w.define("EV", "QB", ["TimeUS", "Id"])
    w.define("CTUN", "Qf", ["TimeUS", "ThO"])
    for k in range(200):
        w.add("CTUN", 1_000_000 + 100_000 * k, 0.1)
        if k in (40, 110):
            w.add("EV", 1_000_000 + 100_000 * k, 28 if k == 40 else 18)
    segs, note = flight_segments(log_of_bytes(w.bytes(), "dataflash"))
    assert [(s.kind, s.start_s, s.end_s) for s in segs if s.kind != "hover"] == [
        ("ground", 1.0, 5.0), ("flying", 5.0, 12.0), ("ground", 12.0, 20.9)]
    assert "from the land events alone" in note


def test_parameters_with_a_text_value_column_are_left_out_with_a_note():
    from tests.flightlog.synthetic_logs import DataFlashWriter
    w = DataFlashWriter()
    w.define("PARM", "QNN", ["TimeUS", "Name", "Value"])
    w.add("PARM", 1_000_000, "INS_GYRO_FILTER", "20")
    got = log_of_bytes(w.bytes(), "dataflash").parameters()
    assert got.values == {} and "PARM.Value is no number" in got.notes[0]


def test_ulog_parameter_that_is_no_number_is_left_out_with_a_note():
    """A ULog parameter whose value pyulog hands back as bytes (a damaged type): the others
    are read and a note names it (before: 'reading the parameters failed: ValueError',
    found by mutating shared logs)."""
    from types import SimpleNamespace
    from gyrodenoise.flightlog.logdata import ULogFile
    from gyrodenoise.flightlog.model import FlightLog, LogFacts
    u = SimpleNamespace(initial_parameters={"IMU_GYRO_CUTOFF": 40.0, "BROKEN": b"\x00\x80\xbbD"},
                        changed_parameters=[], data_list=[])
    log = FlightLog(format=formats.format_named("ulog"), path=Path("x.ulg"), gyro=[],
                    facts=LogFacts(0, None, 0, None), payload=ULogFile(u, []))
    got = log.parameters()
    assert got.values == {"IMU_GYRO_CUTOFF": 40.0} and "BROKEN" in got.notes[0]


def test_px4_telemetry_vibration_judged_as_px4_metrics():
    """SYNTHETIC PX4 telemetry log (HEARTBEAT autopilot 12): its VIBRATION carries
    vehicle_imu_status' metrics (x coning, y gyro, z accelerometer: PX4's
    MavlinkStreamVibration). z 12 m/s/s fails PX4 Flight Review's 9.81; x 40 (rad^2) has
    no threshold (before: read as ArduPilot's m/s/s levels, x 'warn' at 40, z 'pass')."""
    from gyrodenoise.flightlog.vibration import vibration_review
    mav, add, out = tlog_writer()
    wall = 1_700_000_000_000_000
    for k in range(100):
        add(mav.MAVLink_heartbeat_message(2, 12, 0, 0, 3, 3), wall + k * 100_000)
        add(mav.MAVLink_vibration_message(k * 100_000, 40.0, 0.1, 12.0, 0, 0, 0), wall + k * 100_000 + 10)
    log = log_of_bytes(out(), "tlog")
    assert log.parameters().autopilot.name == "px4"
    res, _ = vibration_review(log, [], over="whole")
    figs = res["segments"][0]["figures"]
    assert figs["accel_vibration_metric"]["verdict"] == "fail"
    assert figs["delta_angle_coning_metric"]["verdict"] is None and "vibration_x" not in figs
    assert "PX4" in res["source"] and set(res["thresholds"]) == {"accel_vibration_metric_m_s2", "clip_increase"}


def test_flight_log_accel_holds_the_px4_accelerometer_fifo(tmp_path):
    """FlightLog.accel: the ULog adapter reads sensor_accel_fifo (m/s^2, at its 2 kHz, on the
    log's time axis, the tone on z where the generator put it). Failed before: accel empty."""
    from tests.flightlog.test_format_fidelity import fifo_log
    data, _, _, _ = fifo_log(tone_hz=173.0)
    path = tmp_path / "fifo.ulg"
    path.write_bytes(data)
    log = formats.read_log(path)
    assert [(a.name, a.unit) for a in log.accel] == [("sensor_accel_fifo", "m/s^2")]
    a = log.accel[0]
    assert a.rate_hz == pytest.approx(2000.0) and a.values.shape == (len(a.time_s), 3)
    assert a.time_s[0] == pytest.approx(1.0, abs=1e-3) and np.all(np.diff(a.time_s) > 0)
    assert np.mean(a.values[:, 2]) == pytest.approx(-9.81, abs=0.05)
    spec = np.abs(np.fft.rfft(a.values[:, 2] - a.values[:, 2].mean()))
    assert np.fft.rfftfreq(len(a.time_s), 1 / 2000.0)[np.argmax(spec)] == pytest.approx(173.0, abs=0.5)


# ------------------------------------------------------------ boots of logs joined (unseen logs)
def _dataflash_boot(t0_s, n, filler_types=0):
    """One synthetic boot: ``filler_types`` dummy formats first (so IMU gets another
    type id), an untimed EV 10 (armed, as Copter 3.1 logs it: no time column) before
    the first timed message, then IMU at 50 Hz from ``t0_s``."""
    from tests.flightlog.synthetic_logs import DataFlashWriter
    w = DataFlashWriter()
    for k in range(filler_types):
        w.define(f"XX{k}", "Qf", ["TimeUS", "V"])
    w.define("EV", "B", ["Id"])
    w.define("IMU", "Qffffff", ["TimeUS", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.add("EV", 10)
    for i in range(n):
        w.add("IMU", int((t0_s + i / 50.0) * 1e6), 0.01, 0.02, 0.03, 0.0, 0.0, -9.81)
    return w.bytes()


def test_logs_joined_whose_imu_type_ids_differ_are_two_boots(tmp_path):
    """Two logs of different firmware joined: IMU is type 0x82 in the first, 0x81 in the
    second (an unseen pair of Copter 3.6.4 / 3.4.4 logs was read as one boot, its second
    flight lost: boots were found in one type id). Each untimed message at a boot's start
    takes that boot's time (Copter 3.1's EV armed took the previous boot's last time)."""
    p = tmp_path / "joined.bin"
    first, second = _dataflash_boot(200.0, 500, filler_types=1), _dataflash_boot(30.0, 400)
    p.write_bytes(first + second)
    log = formats.read_log(p)
    assert [b.index for b in log.boots] == [0, 1]
    assert log.boots[1].first_record == pytest.approx(len(first), abs=200)
    ev = log.messages("EV")
    np.testing.assert_allclose(ev["time_s"], [200.0, 30.0])


def test_a_px4_body_rate_topic_not_read_is_said():
    """PX4's vehicle_angular_velocity (the gyro after PX4's filters) is not a gyro stream
    here; it was left out without a word (held-out trial: px4_events, roboto_fmuv5): now
    the report's streams_skipped names it and why."""
    log = formats.read_log(shared_log("px4_vtol_small.ulg"))
    skipped = log.facts.to_fields()["streams_skipped"]
    assert any(r.startswith("vehicle_angular_velocity[0]: ") and "not read as gyro" in r for r in skipped)
    assert "vehicle_angular_velocity" not in {s.message for s in log.gyro}
