"""MAVLink bridge on real logs: parsing against pymavlink, restarts, filtered logs
read back by pymavlink, unit handling, bad/truncated input, many logs.

References are independent of the bridge: pymavlink's own reading of the raw
fields, a whole-stream restart rule written here, and the core's batch
denoiser (``gyrodenoise.denoise``) on those samples.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.errors import InputError

from gyrodenoise.flightlog import dataflash, tlog
from gyrodenoise.flightlog.process import process_log, process_many
from gyrodenoise.flightlog.streams import RestartDetector, noise_per_axis, restart_flags
from tests.helpers import DATA, main_in_process, shared_log
from tests.flightlog.references import (by_name, df_reference, ref_filter, ref_restarts, run_cli,
                                       tlog_reference)

R2D = 180.0 / math.pi


# ------------------------------------------------------------ restart rule
def test_vectorised_restart_rule_equals_online_detector():
    rng = np.random.default_rng(1234)
    for _ in range(300):
        n = int(rng.integers(1, 400))
        dt = rng.choice([0.02, 0.021, 0.019, 0.0, -3.0, 0.5, 0.09], size=n,
                        p=[0.4, 0.3, 0.18, 0.04, 0.01, 0.04, 0.03])
        t = np.cumsum(dt)
        flags, reasons, repeated = restart_flags(t, 5.0)
        det = RestartDetector(5.0)
        online = [det.update(float(x)) for x in t]
        assert [r or "" for r in online] == list(reasons)
        assert flags.tolist() == [r is not None for r in online]
        assert repeated == det.repeated


def test_noise_figure_is_white_noise_sigma_and_ignores_restart_pairs():
    rng = np.random.default_rng(7)
    x = rng.normal(0, 0.3, size=(20000, 1)) + np.linspace(0, 5, 20000)[:, None]   # slow ramp
    assert noise_per_axis(x, None)[0] == pytest.approx(0.3, rel=0.03)
    y = x.copy()
    y[10000:] += 1000.0                       # a jump at a restart must not count
    r = np.zeros(20000, bool)
    r[10000] = True
    assert noise_per_axis(y, r)[0] == pytest.approx(noise_per_axis(x, r)[0], rel=1e-9)


# ------------------------------------------------------------ DataFlash
@pytest.mark.parametrize("name", ["ardusub_small.BIN", "plane_truncated_test.BIN"])
def test_dataflash_parser_matches_pymavlink(name):
    path = DATA / name
    data, sc, streams = dataflash.read(path)
    ref, msgs = df_reference(path)
    assert sc.n_messages == len(msgs)
    assert {s.name for s in streams} == set(ref)
    for s in streams:
        t, g = ref[s.name]
        np.testing.assert_array_equal(s.raw, g)
        np.testing.assert_allclose(s.time_s, t, rtol=0, atol=1e-9)


def _check_filtered_df(path, out_log, rep):
    """Every message of the filtered DataFlash log equals the original, except
    the IMU gyro fields, which equal the batch denoiser on pymavlink's samples."""
    ref, msgs = df_reference(path)
    ref_out, msgs_out = df_reference(out_log)
    assert len(msgs_out) == len(msgs)
    streams = by_name(rep)
    expected = {}
    for name, (t, g) in ref.items():
        s = streams[name]
        r = ref_restarts(t)
        assert s["restarts"] == int(r.sum())
        rate = 1.0 / np.median(np.diff(t)[np.diff(t) > 0])
        assert s["rate_hz"] == pytest.approx(rate, rel=1e-9)
        f = ref_filter(g * R2D, rate, r) / R2D
        expected[name] = f.astype(np.float32)
        np.testing.assert_array_equal(ref_out[name][1], expected[name].astype(np.float64))
        np.testing.assert_array_equal(ref_out[name][0], t)
    gyro = {"GyrX", "GyrY", "GyrZ"}
    for a, b in zip(msgs, msgs_out):
        assert a["mavpackettype"] == b["mavpackettype"]
        if a["mavpackettype"] in ("IMU", "IMU2", "IMU3"):
            a = {k: v for k, v in a.items() if k not in gyro}
            b = {k: v for k, v in b.items() if k not in gyro}
        assert repr(a) == repr(b)          # repr: NaN fields compare equal


def test_dataflash_filtered_log_read_back_by_pymavlink(tmp_path):
    path = DATA / "ardusub_small.BIN"
    rep = process_log(path, tmp_path, plots=False)
    out = Path(rep["output_log"])
    assert out.stat().st_size == path.stat().st_size
    _check_filtered_df(path, out, rep)
    # the filter did something on every axis (noise figure drops)
    for ax in by_name(rep)["IMU[0]"]["noise"].values():
        assert ax["filtered"] < ax["raw"]


@pytest.mark.slow
@pytest.mark.slow
def test_log171_three_imus_gap_restart_and_readback(tmp_path):
    path = shared_log("log171.bin")
    r = run_cli(path, "-o", tmp_path, "--json")
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)             # exactly one JSON object on stdout
    rep = summary["logs"][0]
    assert [s["name"] for s in rep["streams"]] == ["IMU", "IMU2", "IMU3"]
    for s in rep["streams"]:
        assert s["samples"] == 11916
        assert s["rate_hz"] == pytest.approx(50.0, rel=0.01)
        assert s["restarts"] == 1
        assert Path(s["csv"]).is_file() and Path(s["plot"]).stat().st_size > 10000
    # the 2.0 s gap is the restart, in all three streams
    assert {(e["reason"], round(e["time_s"] - e["previous_time_s"], 1)) for e in rep["restarts"]} == {("gap", 2.0)}
    assert rep["unreadable_records"] == 0 and rep["truncated"] is False
    _check_filtered_df(path, Path(rep["output_log"]), rep)
    # CSV: raw column is pymavlink's value in deg/s; filtered equals the reference
    ref, _ = df_reference(path)
    t, g = ref["IMU2"]
    csv = np.genfromtxt(Path(by_name(rep)["IMU2"]["csv"]), delimiter=",", names=True)
    np.testing.assert_allclose(csv["raw_y"], g[:, 1] * R2D, rtol=1e-8, atol=1e-12)
    f = ref_filter(g * R2D, by_name(rep)["IMU2"]["rate_hz"], ref_restarts(t))
    np.testing.assert_allclose(csv["filtered_z"], f[:, 2], rtol=1e-8, atol=1e-9)
    assert csv["restart"].sum() == 1


def test_truncated_dataflash_processed_up_to_the_cut(tmp_path):
    path = DATA / "plane_truncated_test.BIN"
    rep = process_log(path, tmp_path, plots=False)
    assert rep["truncated"] is True and rep["truncated_bytes"] == 24
    assert {s["name"]: s["samples"] for s in rep["streams"]} == {"IMU": 45, "IMU2": 45}
    _check_filtered_df(path, Path(rep["output_log"]), rep)
    # the cut bytes are kept as they were
    assert Path(rep["output_log"]).read_bytes()[-24:] == path.read_bytes()[-24:]


# ------------------------------------------------------------ tlog
@pytest.mark.parametrize("name,local", [("fs-batt.log.tlog", True)] + [
    pytest.param(name, False, marks=pytest.mark.slow)           # the shared logs: seconds each
    for name in ("ardusub_bad_data.tlog", "sitl_copter_reboot.tlog", "apm2_2013-10-13_18-31-24.tlog")])
def test_tlog_framer_matches_pymavlink(name, local):
    path = DATA / name if local else shared_log(name)
    data, fr, streams = tlog.read(path)
    ref, msgs, bad = tlog_reference(path)
    for s in streams:
        t, g = ref[s.message]
        np.testing.assert_array_equal(s.raw, g)
        np.testing.assert_allclose(s.time_s, t, rtol=0, atol=1e-9)
    assert {s.message for s in streams} == set(ref)
    if name == "ardusub_bad_data.tlog":
        # records with a bad CRC: the bridge counts exactly those pymavlink reports
        assert fr.n_unreadable == bad == 1967
        assert int(fr.ok.sum()) == len(msgs)
    elif name == "sitl_copter_reboot.tlog":
        # pymavlink reports its resync bytes in 140 pieces; the bridge counts 10 skipped
        # stretches, and recovers every message pymavlink reads
        assert bad == 140 and len(fr.bad_regions) == 10
        assert int(fr.ok.sum()) >= len(msgs)
    else:
        assert fr.n_unreadable == bad == 0
        assert int(fr.ok.sum()) == len(msgs)


def _check_filtered_tlog(path, out_log, rep, unit_mrad=True):
    ref, msgs, bad = tlog_reference(path)
    ref_out, msgs_out, bad_out = tlog_reference(out_log)
    assert bad_out == bad                       # unreadable bytes copied unchanged
    assert len(msgs_out) == len(msgs)
    streams = by_name(rep)
    expected = {}
    for name, (t, g) in ref.items():
        s = streams[name]
        r = ref_restarts(t)
        assert s["restarts"] == int(r.sum()), name
        rate = s["rate_hz"]
        assert rate == pytest.approx(1.0 / np.median(np.diff(t)[(np.diff(t) > 0) & ~r[1:]]), rel=1e-9)
        if rate < 20.0:
            # too slow to denoise: written raw, bit for bit, as the note says
            expected[name] = g
            np.testing.assert_array_equal(ref_out[name][1], g, err_msg=name)
            assert s["too_slow_to_denoise"] and "written raw" in s["slow_note"], name
            continue
        k = R2D / 1000.0 if unit_mrad or name != "RAW_IMU" else 1.0
        f = ref_filter(g * k, rate, r) / k
        expected[name] = np.clip(np.rint(f), -32768, 32767)
        got = ref_out[name][1]
        # int16 rounding of the same float: at most an exact .5 tie may differ
        assert np.abs(got - expected[name]).max() <= 1, name
        assert np.mean(got != expected[name]) < 1e-3, name
    gyro = set(tlog.GYRO_FIELDS)
    for a, b in zip(msgs, msgs_out):
        assert a["mavpackettype"] == b["mavpackettype"]
        # pymavlink's dialect is process-global (MAVLink 1 or 2 decoding, depending on
        # what it read before): MAVLink 2 extension fields may be present on one side
        # only, and then hold 0
        common = (set(a) & set(b)) - (gyro if a["mavpackettype"] in tlog.GYRO_MESSAGES else set())
        assert all(not a[k] for k in set(a) - set(b)) and all(not b[k] for k in set(b) - set(a))
        a = {k: a[k] for k in sorted(common)}
        b = {k: b[k] for k in sorted(common)}
        assert repr(a) == repr(b)          # repr: NaN fields compare equal
    return ref, expected


@pytest.mark.slow
@pytest.mark.slow
def test_copter_tlog_three_boot_sessions(tmp_path):
    path = shared_log("copter_20211202-132613.tlog")
    rep = process_log(path, tmp_path, plots=False)
    streams = by_name(rep)
    assert set(streams) == {"RAW_IMU", "SCALED_IMU2"}
    for name in streams:
        back = [e for e in rep["restarts"] if e["stream"] == name and e["reason"] == "boot_time_backwards"]
        assert len(back) == 2                  # three boot sessions
        assert streams[name]["field_unit"] == "mrad/s" and streams[name]["unit_known"]
    assert rep["unreadable_records"] == 2
    _check_filtered_tlog(path, Path(rep["output_log"]), rep)


@pytest.mark.slow
def test_fs_batt_tlog_end_to_end_via_cli(tmp_path):
    path = DATA / "fs-batt.log.tlog"
    r = run_cli(path, "-o", tmp_path, "--json")
    assert r.returncode == 0, r.stderr
    rep = json.loads(r.stdout)["logs"][0]
    s = by_name(rep)
    assert s["RAW_IMU"]["samples"] == 27 and s["SCALED_IMU2"]["samples"] == 27
    assert s["RAW_IMU"]["note"].startswith("RAW_IMU from ArduPilot")     # APM:Copter V3.4 string
    # the 9.6 s gap restarts both streams
    assert [round(e["time_s"] - e["previous_time_s"]) for e in rep["restarts"]] == [10, 10]
    _check_filtered_tlog(path, Path(rep["output_log"]), rep)


@pytest.mark.slow
def test_sitl_reboot_and_bad_records(tmp_path):
    path = shared_log("sitl_copter_reboot.tlog")
    rep = process_log(path, tmp_path, plots=False, csv=False)
    assert rep["unreadable_records"] == 10
    ev = [e for e in rep["restarts"] if e["stream"] == "RAW_IMU"]
    assert [e["reason"] for e in ev] == ["boot_time_backwards"]
    assert ev[0]["previous_time_s"] > ev[0]["time_s"]
    z = by_name(rep)["SCALED_IMU3"]
    assert z["all_zero"] is True                     # SITL's third IMU is all zeros
    _check_filtered_tlog(path, Path(rep["output_log"]), rep)


@pytest.mark.slow
def test_ardusub_bad_records_counted_and_kept(tmp_path):
    path = shared_log("ardusub_bad_data.tlog")
    rep = process_log(path, tmp_path, plots=False, csv=False)
    assert rep["unreadable_records"] == 1967
    assert by_name(rep)["RAW_IMU"]["samples"] == 627
    _check_filtered_tlog(path, Path(rep["output_log"]), rep)


@pytest.mark.parametrize("name", ["copter_20211202-133659.tlog", "copter_20211208-151424.tlog"])
def test_truncated_tlogs_processed(tmp_path, name):
    path = shared_log(name)
    rep = process_log(path, tmp_path, plots=False, csv=False)
    ref, msgs, bad = tlog_reference(path)
    # these logs were cut at a 32/64 kB block and zero-filled: truncated, not unreadable
    assert rep["truncated"] is True and rep["truncation"] == "zero-filled tail"
    assert rep["unreadable_records"] == 0 and bad == 1       # pymavlink: one BAD_DATA for the zeros
    assert path.read_bytes()[-rep["truncated_bytes"]:] == bytes(rep["truncated_bytes"])
    assert rep["messages"] == len(msgs)
    assert by_name(rep)["RAW_IMU"]["samples"] == len(ref["RAW_IMU"][0])
    _check_filtered_tlog(path, Path(rep["output_log"]), rep)


@pytest.mark.slow
def test_apm2_raw_counts_are_not_guessed(tmp_path):
    path = shared_log("apm2_2013-10-13_18-31-24.tlog")
    rep = process_log(path, tmp_path, plots=False)
    s = by_name(rep)["RAW_IMU"]
    assert s["field_unit"] == "counts" and s["unit_known"] is False and s["to_deg_s"] is None
    assert "--raw-imu-scale" in s["note"] and s["noise_unit"] == "counts"
    header = Path(s["csv"]).read_text().splitlines()[0]
    assert "raw_x_counts" in header
    _check_filtered_tlog(path, Path(rep["output_log"]), rep, unit_mrad=False)
    rep2 = process_log(path, tmp_path / "scaled", plots=False, csv=False, raw_imu_scale=0.0610)
    s2 = by_name(rep2)["RAW_IMU"]
    assert s2["unit_known"] and s2["to_deg_s"] == 0.0610 and s2["noise_unit"] == "deg/s"


def test_repack_round_trip_through_pymavlink():
    """A re-packed MAVLink 1 and 2 packet decodes (CRC checked) to the new values."""
    from pymavlink.dialects.v20 import ardupilotmega as mav2
    from pymavlink.dialects.v10 import ardupilotmega as mav1
    for dialect, force1 in ((mav2, False), (mav1, True)):
        m = dialect.MAVLink(None, srcSystem=7, srcComponent=3)
        m.seq = 42
        pkt = dialect.MAVLink_raw_imu_message(123456, 1, 2, 3, 0, 0, 0, 0, 0, 0).pack(m, force_mavlink1=force1) \
            if dialect is mav1 else dialect.MAVLink_raw_imu_message(123456, 1, 2, 3, 0, 0, 0, 0, 0, 0, 0, 0).pack(m)
        new, dropped = tlog.repack(pkt, "RAW_IMU", [-5.4, 7.5, 32767.4])
        assert not dropped
        dec = mav2.MAVLink(None)
        msg = dec.parse_char(new)
        assert msg is not None and msg.get_type() == "RAW_IMU"
        assert (msg.xgyro, msg.ygyro, msg.zgyro) == (-5, 8, 32767)
        for bad in (32767.9, -32768.6, float("nan"), float("inf"), 1e300):   # never clipped silently
            with pytest.raises(ValueError, match="does not fit int16"):
                tlog.repack(pkt, "RAW_IMU", [0.0, 0.0, bad])
        assert (msg.xacc, msg.yacc, msg.zacc, msg.time_usec) == (1, 2, 3, 123456)
        assert (msg.get_srcSystem(), msg.get_srcComponent(), msg.get_seq()) == (7, 3, 42)


# ------------------------------------------------------------ ULog
@pytest.mark.slow
def test_px4_ulog_dropouts_and_filtered_copy(tmp_path):
    path = shared_log("px4_sample.ulg")
    import pyulog
    rep = process_log(path, tmp_path, plots=False)
    s = by_name(rep)["sensor_combined"]
    u = pyulog.ULog(str(path), ["sensor_combined"])
    d = u.data_list[0].data
    t = d["timestamp"] * 1e-6
    g = np.stack([d[f"gyro_rad[{k}]"] for k in range(3)], axis=1).astype(float)
    r = ref_restarts(t)
    assert s["samples"] == len(t) and s["rate_hz"] == pytest.approx(250.0, rel=0.02)
    assert s["restarts"] == int(r.sum()) >= 4
    f = ref_filter(g * R2D, s["rate_hz"], r) / R2D
    u2 = pyulog.ULog(rep["output_log"], ["sensor_combined"])
    d2 = u2.data_list[0].data
    got = np.stack([d2[f"gyro_rad[{k}]"] for k in range(3)], axis=1)
    np.testing.assert_array_equal(got, f.astype(np.float32))
    np.testing.assert_array_equal(d2["accelerometer_m_s2[2]"], d["accelerometer_m_s2[2]"])


# ------------------------------------------------------------ bad input
def test_no_gyro_stream_exits_2_with_one_line(tmp_path):
    path = shared_log("plane_no_imu.bin")
    r = run_cli(path, "-o", tmp_path)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert lines[0].startswith("gyrodenoise: error: ") and "plane_no_imu.bin" in lines[0]
    assert "no gyro stream" in lines[0]
    assert r.stdout == ""


def test_unknown_file_type_exits_2(tmp_path):
    junk = tmp_path / "notes.dat"
    junk.write_bytes(b"hello, this is not a flight log\n" * 40)
    r = run_cli(junk, "-o", tmp_path / "o", "--json")
    msg = (f"{junk}: unknown file type (expected an ArduPilot DataFlash log .bin, a PX4 log .ulg, "
           f"a MAVLink telemetry log .tlog/.mavlink, a ROS 1/ROS 2 bag or MCAP file .bag/.mcap/.db3, "
           f"a Betaflight/INAV blackbox log .bbl/.bfl)")
    assert r.returncode == 2
    assert json.loads(r.stdout) == {"error": msg, "exit_status": 2}     # --json: one object, the error
    assert r.stdout.count("\n") == 1
    assert r.stderr.strip().splitlines() == [f"gyrodenoise: error: {msg}"]
    with pytest.raises(InputError, match="not a DataFlash binary log"):
        process_log(shutil.copy(junk, tmp_path / "fake.bin"), tmp_path / "o")


@pytest.mark.slow
def test_many_logs_in_parallel_one_summary(tmp_path):
    folder = tmp_path / "logs"
    folder.mkdir()
    shutil.copy(DATA / "fs-batt.log.tlog", folder)
    shutil.copy(DATA / "plane_truncated_test.BIN", folder)
    shutil.copy(DATA / "ardusub_small.BIN", folder)
    (folder / "broken.bin").write_bytes(b"\x00" * 1000)           # fails
    (folder / "notes.txt").write_text("ignored")
    out = tmp_path / "out"
    r = run_cli(folder, "-o", out, "--jobs", "2", "--json", "--no-plots")
    assert r.returncode == 2                                    # one log failed
    summary = json.loads(r.stdout)
    assert summary["n_logs"] == 4 and summary["n_ok"] == 3 and summary["n_failed"] == 1
    assert summary["failed"][0]["file"].endswith("broken.bin")
    assert "broken.bin: not a DataFlash binary log" in summary["failed"][0]["error"]
    assert summary["ignored_files"][0]["file"].endswith("notes.txt")
    assert "broken.bin" in r.stderr and "Traceback" not in r.stderr
    # each processed log equals a single-log run of the same file
    for rep in summary["logs"]:
        single = process_log(rep["file"], tmp_path / "single", plots=False)
        assert Path(rep["output_log"]).read_bytes() == Path(single["output_log"]).read_bytes()
        assert rep["streams"][0]["noise"] == single["streams"][0]["noise"]
    assert json.loads((out / "summary.json").read_text())["n_ok"] == 3


def test_each_axis_and_stream_has_its_own_denoiser(tmp_path):
    """Filtering a stream alone or beside others gives the same values."""
    data, sc, streams = dataflash.read(DATA / "plane_truncated_test.BIN")
    rep = process_many([DATA / "plane_truncated_test.BIN"], tmp_path, plots=False, csv=False)
    ref, _ = df_reference(DATA / "plane_truncated_test.BIN")
    out, _ = df_reference(rep["logs"][0]["output_log"])
    t, g = ref["IMU2"]
    alone = np.stack([gd.denoise(g[:, k] * R2D, 1 / np.median(np.diff(t)), restarts=ref_restarts(t),
                                 offline=True) for k in range(3)], axis=1)
    np.testing.assert_array_equal(out["IMU2"][1], (alone / R2D).astype(np.float32))


# ------------------------------------------------------------ message types absent from the real logs
def _synthetic_tlog(path, autopilot, n=900, seed=5, nan_at=()):
    """SYNTHETIC tlog (no real log has these): HIGHRES_IMU (rad/s), SCALED_IMU (mrad/s)
    and RAW_IMU at 100 Hz, a reboot at sample 300 (boot time back to 0.5 s), a 1 s gap at 600."""
    import struct
    from pymavlink.dialects.v20 import ardupilotmega as mav
    m = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    rng = np.random.default_rng(seed)
    true = 0.2 * np.sin(np.arange(n) / 50.0)                     # rad/s
    g = true[:, None] + rng.normal(0, 0.01, size=(n, 3))
    t = np.arange(n) * 0.01 + 10.0
    t[300:] = t[300:] - t[300] + 0.5                              # reboot
    t[600:] += 1.0                                                # gap
    for i, k in nan_at:
        g[i, k] = np.nan
    out = bytearray()
    wall = 1_700_000_000_000_000

    def rec(msg):
        nonlocal wall
        wall += 3000
        out.extend(struct.pack(">Q", wall) + msg.pack(m))
    rec(mav.MAVLink_heartbeat_message(2, autopilot, 0, 0, 0, 3))
    for i in range(n):
        us = int(round(t[i] * 1e6))
        rec(mav.MAVLink_highres_imu_message(us, 0, 0, -9.8, *g[i], 0, 0, 0, 0, 0, 0, 20, 0x38, 0))
        mr = np.rint(np.nan_to_num(g[i]) * 1000).astype(int)
        rec(mav.MAVLink_scaled_imu_message(us // 1000, 0, 0, -1000, *mr, 0, 0, 0, 0))
        rec(mav.MAVLink_raw_imu_message(us, 0, 0, 0, *mr, 0, 0, 0, 0, 0))
    path.write_bytes(bytes(out))
    return t, g


def test_highres_and_scaled_imu_units_and_restarts_synthetic(tmp_path):
    path = tmp_path / "synthetic_px4.tlog"
    t, g = _synthetic_tlog(path, autopilot=12)                    # PX4
    rep = process_log(path, tmp_path / "out", plots=False)
    s = by_name(rep)
    assert s["HIGHRES_IMU"]["field_unit"] == "rad/s" and s["HIGHRES_IMU"]["to_deg_s"] == pytest.approx(R2D)
    assert s["SCALED_IMU"]["field_unit"] == "mrad/s"
    assert s["RAW_IMU"]["field_unit"] == "counts" and not s["RAW_IMU"]["unit_known"]   # not ArduPilot
    for name in ("HIGHRES_IMU", "SCALED_IMU", "RAW_IMU"):
        ev = [(e["sample"], e["reason"]) for e in rep["restarts"] if e["stream"] == name]
        assert ev == [(300, "boot_time_backwards"), (600, "gap")]
        assert s[name]["rate_hz"] == pytest.approx(100.0, rel=1e-6)
    ref, _, _ = tlog_reference(path)
    out, _, _ = tlog_reference(Path(rep["output_log"]))
    r = np.zeros(len(t), bool)
    r[[300, 600]] = True
    f = ref_filter(ref["HIGHRES_IMU"][1] * R2D, 100.0, r) / R2D
    np.testing.assert_array_equal(out["HIGHRES_IMU"][1], f.astype(np.float32).astype(float))
    fs = ref_filter(ref["SCALED_IMU"][1] * R2D / 1000, 100.0, r) / (R2D / 1000)
    assert np.abs(out["SCALED_IMU"][1] - np.rint(fs)).max() <= 1
    # the reported noise figures are those of the reference arrays
    from gyrodenoise.flightlog.streams import noise_per_axis as npa
    from gyrodenoise.analysis.motion_metrics import white_noise_std as wns
    ny = s["HIGHRES_IMU"]["noise"]["y"]
    assert ny["first_diff_filtered"] == pytest.approx(npa(f * R2D, r)[1], rel=1e-6)
    assert ny["first_diff_raw"] == pytest.approx(npa(ref["HIGHRES_IMU"][1] * R2D, r)[1], rel=1e-9)
    assert ny["filtered"] == pytest.approx(wns(f[:, 1] * R2D, s["HIGHRES_IMU"]["filter_rate_hz"], r), rel=1e-6)
    assert ny["raw"] == pytest.approx(wns(ref["HIGHRES_IMU"][1][:, 1] * R2D, s["HIGHRES_IMU"]["filter_rate_hz"], r), rel=1e-9)
    # the same log from ArduPilot: RAW_IMU is mrad/s (MAVLink 2 + autopilot 3)
    _synthetic_tlog(path, autopilot=3)
    rep3 = process_log(path, tmp_path / "out3", plots=False, csv=False)
    assert by_name(rep3)["RAW_IMU"]["field_unit"] == "mrad/s"


@pytest.mark.slow
def test_batch_sampler_bursts_parsed_filtered_and_written_back(tmp_path):
    """ISBH/ISBD gyro bursts (1024 samples at ~2 kHz) of a real ArduCopter 4.1 log,
    assembled independently here from pymavlink's messages."""
    path = shared_log("copter_00061-2021-11-21_18-03-38.bin")
    from pymavlink import DFReader

    def bursts(p):
        r = DFReader.DFReader_binary(str(p))
        hdr, dat = {}, {}
        while True:
            m = r.recv_match(type=["ISBH", "ISBD"])
            if m is None:
                break
            if m.get_type() == "ISBH":
                hdr[m.N] = m
            else:
                dat.setdefault(m.N, []).append(m)
        out = []
        for n, h in sorted(hdr.items(), key=lambda kv: kv[1].SampleUS):
            if h.type != 1 or n not in dat:
                continue
            ds = sorted(dat[n], key=lambda m: m.seqno)
            v = np.array([[c for m in ds for c in getattr(m, a)] for a in "xyz"], dtype=float).T
            t = h.SampleUS * 1e-6 + np.arange(len(v)) / h.smp_rate
            out.append((t, v, h.mul))
        return out

    ref = bursts(path)
    assert len(ref) == 23 and all(len(b[1]) == 1024 for b in ref)
    rep = process_log(path, tmp_path, plots=False, csv=False, warmup_s=0.1)
    s = by_name(rep)["ISB.gyro[0]"]
    assert s["samples"] == 23 * 1024 and s["rate_hz"] == pytest.approx(2000, rel=0.01)
    assert s["restarts"] == 22                                   # every burst after the first
    got = bursts(rep["output_log"])
    rate = s["rate_hz"]
    for (t, v, mul), (t2, v2, mul2) in zip(ref, got):
        assert mul2 == mul
        np.testing.assert_array_equal(t2, t)
        f = np.stack([gd.denoise(v[:, k] / mul * R2D, rate, restarts=None, warmup_s=0.1, offline=True)
                      for k in range(3)], axis=1) / R2D
        expected = np.clip(np.rint(f * mul), -32768, 32767)
        assert np.abs(v2 - expected).max() <= 1 and np.mean(v2 != expected) < 1e-3
    # the filter did run (the default motion bank follows these 2 kHz bursts closely and passes
    # most samples through: 0.3 % of the integer samples change, 2.2 % before the pass-through;
    # the paper's SHAKF changes > 20 %)
    assert np.mean(np.concatenate([b[1] for b in got]) != np.concatenate([b[1] for b in ref])) > 0.001


def test_non_finite_samples_are_dropouts_healed_as_gd_denoise_heals_them(tmp_path):
    """SYNTHETIC HIGHRES_IMU with NaN gyro values (one on x at 450, one on y at the
    restart sample 600): dropouts, fed to the filter with the other samples, which heals
    them as gd.denoise does (the filter restarts there): the filtered log is gd.denoise of
    the whole axis, NaN kept at the dropouts; counted in non_finite_samples and
    dropouts_healed."""
    path = tmp_path / "nan.tlog"
    t, g = _synthetic_tlog(path, autopilot=12, nan_at=[(450, 0), (600, 1)])
    r = run_cli(path, "-o", tmp_path / "out", "--json", "--no-plots")
    assert r.returncode == 0, r.stderr
    rep = json.loads(r.stdout)["logs"][0]
    s = by_name(rep)["HIGHRES_IMU"]
    assert s["non_finite_samples"] == {"x": 1, "y": 1, "z": 0} and s["dropouts_healed"] == 2
    assert all(v["raw"] is not None and np.isfinite(v["raw"]) for v in s["noise"].values())
    out, _, _ = tlog_reference(Path(rep["output_log"]))
    raw = tlog_reference(path)[0]["HIGHRES_IMU"][1]               # float32 values as logged
    got = out["HIGHRES_IMU"][1]
    assert np.isnan(got[450, 0]) and np.isnan(got[600, 1]) and np.isfinite(got).sum() == got.size - 2
    r_all = np.zeros(len(t), bool)
    r_all[[300, 600]] = True
    for k in range(3):
        ref = gd.denoise(raw[:, k] * R2D, 100.0, restarts=r_all, offline=True) / R2D
        np.testing.assert_array_equal(got[:, k], ref.astype(np.float32).astype(float))


# ------------------------------------------------------------ failing loudly
def test_garbage_filter_output_leaves_that_stream_raw_exit_1(tmp_path, monkeypatch):
    """The safety net: a filter that returns garbage for one stream (IMU2 of the
    ArduPlane log) gets that stream written RAW, bit for bit, with one stderr line
    naming log, stream and axis; the other stream is filtered; exit status 1."""
    from gyrodenoise.flightlog import engines
    path = DATA / "plane_truncated_test.BIN"
    real = engines.NativeEngine.filter
    calls = {"n": 0}

    def garbage_for_imu2(self, x, restarts, rate_hz):
        calls["n"] += 1
        out = real(self, x, restarts, rate_hz)
        if 4 <= calls["n"] <= 6:             # the 3 axes of the 2nd stream (IMU2)
            out = out.copy()
            out[-1] = 1.9e12 if calls["n"] == 5 else np.nan
        return out

    monkeypatch.setattr(engines.NativeEngine, "filter", garbage_for_imu2)
    from gyrodenoise.cli import main
    import contextlib
    import io
    so, se = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(so), contextlib.redirect_stderr(se):
        status = main(["mavlink", str(path), "-o", str(tmp_path), "--json", "--no-plots", "--method", "shakf",
                       "--warmup-s", "0.1"])     # 45 samples: motion's warm-up (128) would pass them raw
    assert status == 1
    summary = json.loads(so.getvalue())
    assert summary["exit_status"] == 1
    assert [(e["stream"], e["file"]) for e in summary["streams_left_raw"]] == [("IMU2", str(path))]
    s = by_name(summary["logs"][0])
    assert s["IMU"]["left_raw"] is None
    why = s["IMU2"]["left_raw"]
    assert why.startswith("x: filtered value nan") and "y: filtered value 1.9e+12" in why and "outside" in why
    lines = [ln for ln in se.getvalue().splitlines() if "NOT FILTERED" in ln]
    assert len(lines) == 1 and str(path) in lines[0] and "IMU2" in lines[0] and "RAW" in lines[0]
    ref, _ = df_reference(path)
    out, _ = df_reference(Path(summary["logs"][0]["output_log"]))
    np.testing.assert_array_equal(out["IMU2"][1], ref["IMU2"][1])          # raw, bit for bit
    assert not np.array_equal(out["IMU"][1], ref["IMU"][1])                 # the other one filtered
    assert np.isfinite(out["IMU"][1]).all()
    # the text summary says it too
    so = io.StringIO()
    calls["n"] = 0
    with contextlib.redirect_stdout(so), contextlib.redirect_stderr(io.StringIO()):
        assert main(["mavlink", str(path), "-o", str(tmp_path / "t"), "--no-plots", "--warmup-s", "0.1"]) == 1
    assert "NOT FILTERED, written raw" in so.getvalue() and "1 stream(s) left raw (exit status 1)" in so.getvalue()


def test_filtered_value_that_does_not_fit_int16_is_never_clipped(tmp_path, monkeypatch):
    """A filtered RAW_IMU value beyond int16 (sitl_vtol.tlog z was clipped at 32767)
    leaves the stream raw and is reported -- checked on its own here: the envelope
    check (which would catch it first) is switched off."""
    from gyrodenoise.flightlog import engines
    from gyrodenoise.analysis import motion_metrics
    path = DATA / "fs-batt.log.tlog"
    real = engines.NativeEngine.filter

    def z_beyond_int16(self, x, restarts, rate_hz):
        out = real(self, x, restarts, rate_hz).copy()
        out[-1] = 40.0 * R2D                              # 40000 mrad/s
        return out

    monkeypatch.setattr(engines.NativeEngine, "filter", z_beyond_int16)
    monkeypatch.setattr(motion_metrics, "envelope_violation", lambda *a, **k: None)
    # the 2.4 Hz streams are too slow to denoise and go out raw unfiltered: filter them here
    monkeypatch.setattr(motion_metrics, "too_slow_to_denoise", lambda *a, **k: False)
    rep = process_log(path, tmp_path, plots=False, csv=False)
    for name in ("RAW_IMU", "SCALED_IMU2"):
        assert "does not fit the field type int16" in by_name(rep)[name]["left_raw"]
    out, _, _ = tlog_reference(Path(rep["output_log"]))
    ref, _, _ = tlog_reference(path)
    np.testing.assert_array_equal(out["RAW_IMU"][1], ref["RAW_IMU"][1])


@pytest.mark.slow
def test_every_user_error_is_one_line_exit_2_and_one_json_object(tmp_path, capfd):
    """Paths and option values; each gives one line naming the
    option or path on stderr, exit 2, no traceback; with --json one object.
    The 66 runs go through gyrodenoise.cli in this process (main_in_process); three
    kinds (a path, an option value, an argparse error) also as the installed command in a
    process of its own (run_cli: the console entry, interpreter start and exit)."""
    log = DATA / "ardusub_small.BIN"
    afile = tmp_path / "afile"
    afile.write_text("x")
    cases = [
        (["-o", afile], "-o "), (["-o", "/proc/nope"], "-o /proc/nope"),
        (["--warmup-s", "inf"], "--warmup-s"), (["--warmup-s", "1e308"], "--warmup-s"),
        (["--warmup-s", "nan"], "--warmup-s"), (["--warmup-s", "-1"], "--warmup-s"),
        (["--jobs", "0"], "--jobs"), (["--jobs", "abc"], "--jobs"),
        (["--gap-factor", "inf"], "--gap-factor"), (["--gap-factor", "nan"], "--gap-factor"),
        (["--sample-rate", "inf"], "--sample-rate"), (["--sample-rate", "-5"], "--sample-rate"),
        (["--sample-rate", "1e308", "--warmup-s", "1e6"], "--sample-rate"),
        # a rate no gyro has (nothing would be filtered); live-only options with a file;
        # low-pass options
        (["--sample-rate", "1e12"], "--sample-rate"), (["--count", "5"], "--count"),
        (["--duration", "3"], "--duration"), (["--forward", "udpout:127.0.0.1:14551"], "--forward"),
        (["--cutoff-hz", "10"], "--cutoff-hz"), (["--method", "lowpass", "--cutoff-hz", "-1"], "--cutoff-hz"),
        (["--method", "lowpass", "--order", "9"], "--order"), (["--zero-phase"], "--zero-phase"),
        (["--method", "lowpass", "--zero-phase", "--engine", "fmu"], "--zero-phase"),
        (["--outlier-sigma", "nan"], "--outlier-sigma"), (["--outlier-sigma", "1"], "outlier_sigma"),
        (["--outlier-run", "0"], "--outlier-run"), (["--ar-order", "0"], "--ar-order"),
        (["--ar-order", "1000000"], "--ar-order"), (["--raw-imu-scale", "inf"], "--raw-imu-scale"),
        (["--duration", "inf"], "--duration"), (["--count", "0"], "--count"),
        (["--method", "magic"], "--method"), (["--no-such-option"], "--no-such-option"),
    ]
    in_a_process = {0, 4, len(cases) - 1}       # -o a file, --warmup-s nan, an unknown option
    for i, (extra, named) in enumerate(cases):
        for js in ([], ["--json"]):
            args = ([log, "-o", tmp_path / "o"] if extra[0] != "-o" else [log]) + [*extra, *js, "--no-plots",
                                                                                   "--no-csv"]
            runs = [main_in_process(capfd, "mavlink", *args)]
            if i in in_a_process:
                r = run_cli(*args)
                runs.append((r.returncode, r.stdout, r.stderr))
            for status, stdout, stderr in runs:
                what = f"{extra} {js}: {stderr!r}"
                assert status == 2, what
                assert "Traceback" not in stderr, what
                lines = stderr.strip().splitlines()
                assert len(lines) == 1 and lines[0].startswith("gyrodenoise: error: ") and named in lines[0], what
                if js:
                    assert stdout.count("\n") == 1, what
                    obj = json.loads(stdout)
                    assert obj["exit_status"] == 2 and named in obj["error"], what
                else:
                    assert stdout == "", what
    # a failing single log with --json: one object with the error in it
    r = run_cli(DATA / "plane_no_imu.bin" if (DATA / "plane_no_imu.bin").exists()
                else shared_log("plane_no_imu.bin"), "-o", tmp_path / "o", "--json")
    assert r.returncode == 2 and "no gyro stream" in json.loads(r.stdout)["error"]


@pytest.mark.slow
def test_truncated_ulog_is_reported(tmp_path):
    """A .ulg cut in the middle of a message is reported as truncated (pyulog stops
    there silently); the whole file is not."""
    from gyrodenoise.flightlog import ulog
    src = shared_log("px4_sample.ulg")
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(src.read_bytes()[:2_000_000])
    assert ulog.truncated_bytes(src) == 0
    rep = process_log(cut, tmp_path / "o", plots=False, csv=False)
    assert rep["truncated"] is True and rep["truncated_bytes"] == ulog.truncated_bytes(cut) > 0
    assert rep["truncation"] == "message cut by the end of the file"
    r = run_cli(cut, "-o", tmp_path / "o2", "--no-plots", "--no-csv")
    assert r.returncode == 0 and f"truncated ({rep['truncated_bytes']} bytes cut)" in r.stdout


def test_summary_motion_kept_lag_and_slow_note(tmp_path):
    """The summary's motion figures are gyrodenoise.analysis.motion_metrics over the CSV's raw and
    filtered columns; a 2.4 Hz stream gets a note instead of an improvement figure; the
    paper's filter on a real flight is warned about (it flattens the manoeuvres)."""
    from gyrodenoise.analysis import motion_metrics as mm
    rep = process_log(DATA / "ardusub_small.BIN", tmp_path, plots=False)
    s = rep["streams"][0]
    a = np.genfromtxt(s["csv"], delimiter=",", names=True)
    r = a["restart"].astype(bool)
    for ax in "xyz":
        m = s["motion"][ax]
        k = mm.lowband_kept(a[f"raw_{ax}"], a[f"filtered_{ax}"], s["rate_hz"], 5.0, r, s["warmup_samples"])
        assert m["corr"] == pytest.approx(k["corr"], abs=1e-6)
        assert m["amplitude_ratio"] == pytest.approx(k["amplitude_ratio"], abs=1e-6)
        assert m["lag_s"] == pytest.approx(mm.lag_s(a[f"raw_{ax}"], a[f"filtered_{ax}"], s["rate_hz"], 5.0, r,
                                                    s["warmup_samples"]), abs=1e-6)
    slow = process_log(DATA / "fs-batt.log.tlog", tmp_path, plots=False, csv=False)
    for st in slow["streams"]:
        assert st["too_slow_to_denoise"] and "too slowly to denoise" in st["slow_note"]
        assert all(v["ratio"] is None for v in st["noise"].values())
        assert all(v is None for v in st["motion"].values())
    r = run_cli(DATA / "fs-batt.log.tlog", "-o", tmp_path / "t", "--no-plots", "--no-csv")
    assert "no improvement figure" in r.stdout and "(x" not in r.stdout


@pytest.mark.slow
def test_paper_filter_on_a_real_flight_is_warned(tmp_path):
    path = shared_log("log171.bin")
    r = run_cli(path, "-o", tmp_path, "--method", "shakf", "--no-plots", "--no-csv", "--json")
    assert r.returncode == 0
    rep = json.loads(r.stdout)["logs"][0]
    imu = by_name(rep)["IMU"]
    assert imu["motion"]["x"]["amplitude_ratio"] < 0.5 and imu["warnings"]
    assert "removed most of the real motion" in r.stderr
    r = run_cli(path, "-o", tmp_path, "--no-plots", "--no-csv", "--json")        # the default method
    rep = json.loads(r.stdout)["logs"][0]
    for s in rep["streams"]:
        for m in s["motion"].values():
            assert m["corr"] > 0.9 and m["amplitude_ratio"] > 0.8
