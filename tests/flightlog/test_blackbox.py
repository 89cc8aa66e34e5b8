"""The blackbox decoder (gyrodenoise.flightlog.blackbox) on the shared Betaflight 4.2 log
LOG00037.BFL, against what can be known without it: the header read as plain text, the
loop iteration and time counters (any decoding slip breaks their steps at once), the
unfiltered gyro in the debug fields against the filtered gyroADC (two fields decoded
separately must agree below the filters' cutoffs), orangebox's decode where it is
installed; and damaged, truncated, concatenated and foreign files."""
from __future__ import annotations

import csv
import re

import numpy as np
import pytest
from scipy import signal

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog import betaflight_filters as bf
from gyrodenoise.flightlog import blackbox as bb

from tests.helpers import shared_log

NAME = "betaflight/LOG00037.BFL"


@pytest.fixture(scope="module")
def path():
    return shared_log(NAME)


@pytest.fixture(scope="module")
def log(path):
    logs = bb.read_blackbox(path)
    assert len(logs) == 1
    return logs[0]


def _plain_header(path):
    out = {}
    for line in path.read_bytes().split(b"\n"):
        m = re.match(rb"H ([^:]+):(.*)$", line)
        if m:
            out[m.group(1).decode()] = m.group(2).decode()
    return out


def test_header_fields_match_the_plain_text_header(path, log):
    text = _plain_header(path)
    h = log.header
    assert h.firmware_revision == text["Firmware revision"] == "Betaflight 4.2.0 (8f2d21460) STM32F745"
    assert h.firmware == "Betaflight"
    assert (h.board, h.craft_name) == (text["Board information"], text["Craft name"]) == ("HBRO KAKUTEF7", "AR8")
    assert h.looptime_us == int(text["looptime"]) == 125
    assert h.debug_mode == int(text["debug_mode"]) == 6
    assert h.gyro_scale == 1.0                      # 0x3f800000
    assert h.defaults_used == ()
    assert log.fields == tuple(text["Field I name"].split(","))
    f = h.filters
    assert f.gyro_rate_hz == 8000.0
    assert (f.lpf1_static_hz, f.lpf1_dyn_min_hz, f.lpf1_dyn_max_hz) == (200, 240, 600)
    assert (f.lpf2_static_hz, f.dyn_notch_min_hz, f.dyn_notch_max_hz, f.dyn_notch_q) == (300, 125, 350, 250)
    assert (f.rpm_harmonics, f.rpm_q, f.rpm_min_hz) == (3, 800, 100)


def test_counters_step_exactly_and_the_rate_is_1khz(log):
    it = log.column("loopIteration")
    t = log.column("time")
    assert len(it) == 16774 and log.frames_damaged == 0 and log.bytes_skipped == 0 and log.ended_cleanly
    # P interval 8 of the 8 kHz loop: every frame is 8 loop iterations after the one before
    assert np.all(np.diff(it) == 8)
    assert (it[-1] - it[0]) // 8 + 1 == len(it)
    assert np.all(it[np.arange(0, len(it), 32)] % log.header.i_interval == 0)    # I frames every 256 loops
    dt = np.diff(t)
    assert np.all(dt > 0) and np.median(dt) == 1000 and np.percentile(np.abs(dt - 1000), 99) < 150
    assert log.sample_rate_hz == log.header.log_rate_hz == 1000.0
    assert log.time_s[-1] - log.time_s[0] == pytest.approx(17.02, abs=0.01)
    assert [e.kind for e in log.events] == ["sync_beep", "disarm", "log_end"]


def test_prefilter_gyro_agrees_with_gyroadc_below_the_filters_and_is_noisier_above(log):
    assert log.gyro_prefilter_source == "GYRO_SCALED"
    g, u = log.gyro_dps, log.gyro_prefilter_dps
    assert g.shape == u.shape == (16774, 3)
    b, a = signal.butter(4, 20, fs=1000)
    for k in range(3):
        assert np.corrcoef(signal.filtfilt(b, a, g[:, k]), signal.filtfilt(b, a, u[:, k]))[0, 1] > 0.99
        f, pg = signal.welch(g[:, k], fs=1000, nperseg=1024)
        _, pu = signal.welch(u[:, k], fs=1000, nperseg=1024)
        hi = f > 200
        assert pu[hi].sum() > 10 * pg[hi].sum()
    assert np.abs(g).max() < 2000 and np.abs(g.mean(axis=0)).max() < 5
    m = log.motors
    assert m.shape == (16774, 4) and 0 < m.min() and m.max() <= 2047 and np.median(m) > log.header.motor_output[0]
    assert log.setpoint.shape == (16774, 4) and log.rc_command.shape == (16774, 4)


def test_measured_filter_lag_lies_within_the_filter_model_bounds(log):
    """The lag of gyroADC behind the logged unfiltered gyro (phase slope, 5-60 Hz, where the
    two are coherent) against the chain modelled from the header: more than the lowpasses
    alone at full throttle, less than with every notch at its lowest centre (RPM notches
    at gyro_rpm_notch_min, the dynamic notch at dyn_notch_min_hz): the motor frequencies
    are not in this log, so the notches' places are bounded, not known."""
    s = log.header.filters
    f_band = np.arange(5.0, 61.0, 5.0)
    low = bf.chain_response(s, f_band, throttle=1.0).delay_ms.min()
    high = bf.chain_response(s, f_band, throttle=0.0, motor_hz=(s.rpm_min_hz / 3.0,) * 4,
                             dyn_notch_hz=(s.dyn_notch_min_hz,)).delay_ms.min()
    assert 0.7 < low < 1.0 and 4.0 < high < 4.5
    median_lowpass = bf.chain_response(s, [20.0], throttle=float(np.median(log.throttle))).delay_ms[0]
    for k in range(3):
        u, g = log.gyro_prefilter_dps[:, k], log.gyro_dps[:, k]
        f, pxy = signal.csd(u, g, fs=1000, nperseg=2048)
        _, pxx = signal.welch(u, fs=1000, nperseg=2048)
        _, coh = signal.coherence(u, g, fs=1000, nperseg=2048)
        sel = (f >= 5) & (f <= 60) & (coh > 0.9)
        assert sel.sum() > 20
        slope = np.polyfit(2 * np.pi * f[sel], np.unwrap(np.angle(pxy[sel] / pxx[sel])), 1)[0]
        lag_ms = -slope * 1e3
        assert median_lowpass + 0.5 < lag_ms < high, (k, lag_ms)     # measured 2.70, 2.95, 3.57 ms


def test_orangebox_decodes_the_same_values(path, log):
    orangebox = pytest.importorskip("orangebox", reason="orangebox (GPL-3.0, a second decoder) not installed")
    parser = orangebox.Parser.load(str(path))
    rows = np.array([fr.data[:len(log.fields)] for fr in parser.frames()], dtype=float)
    assert parser.field_names[:len(log.fields)] == list(log.fields)
    np.testing.assert_array_equal(rows, log.main)


def test_damage_is_counted_and_the_rest_decoded(path, log, tmp_path):
    data = bytearray(path.read_bytes())
    body = data.index(b"\nI", 0) + 1
    rng = np.random.default_rng(37)
    spots = sorted(rng.integers(body + 20000, len(data) - 20000, size=5))
    for s in spots:
        data[s:s + 3] = b"\xff\x00\x7f"
    bad = tmp_path / "damaged.bfl"
    bad.write_bytes(bytes(data))
    got = bb.read_blackbox(bad)[0]
    assert got.frames_damaged > 0
    assert 0.9 * len(log.main) < len(got.main) < len(log.main)
    # every frame kept is a frame of the clean decode (matched on loop iteration)
    clean = {int(r[0]): r for r in log.main}
    kept = np.array([clean[int(r[0])] for r in got.main if int(r[0]) in clean])
    assert len(kept) > 0.97 * len(got.main)
    same = np.all(kept == np.array([r for r in got.main if int(r[0]) in clean]), axis=1)
    assert same.mean() > 0.97
    cut = tmp_path / "cut.bfl"
    cut.write_bytes(path.read_bytes()[: len(data) // 2])
    half = bb.read_blackbox(cut)[0]
    assert not half.ended_cleanly and 0.4 * len(log.main) < len(half.main) < 0.6 * len(log.main)
    np.testing.assert_array_equal(half.main, log.main[: len(half.main)])


def test_two_logs_in_one_file(path, log, tmp_path):
    two = tmp_path / "two.bbl"
    two.write_bytes(path.read_bytes() * 2)
    logs = bb.read_blackbox(two)
    assert [lg.index for lg in logs] == [1, 2]
    for lg in logs:
        np.testing.assert_array_equal(lg.main, log.main)


def test_foreign_and_broken_files_give_one_line(tmp_path, path):
    junk = tmp_path / "x.bbl"
    junk.write_bytes(b"\x00" * 100)
    with pytest.raises(InputError, match="no blackbox log") as e:
        bb.read_blackbox(junk)
    assert "\n" not in str(e.value)
    with pytest.raises(InputError, match="cannot read"):
        bb.read_blackbox(tmp_path / "missing.bbl")
    text = path.read_bytes()
    broken = tmp_path / "enc.bbl"
    broken.write_bytes(text.replace(b"H Field P encoding:9,", b"H Field P encoding:42,", 1))
    with pytest.raises(InputError, match="encoding 42"):
        bb.read_blackbox(broken)
    novbat = tmp_path / "novbat.bfl"
    novbat.write_bytes(text.replace(b"H vbatref:2277\n", b"", 1))
    assert bb.read_blackbox(novbat)[0].header.defaults_used == ("vbatref",)      # vbatLatest's I predictor
    inav = tmp_path / "inav.txt"
    inav.write_bytes(text.replace(b"Firmware revision:Betaflight 4.2.0", b"Firmware revision:INAV 6.1.0", 1))
    other = bb.read_blackbox(inav)[0]
    assert other.header.firmware == "INAV" and other.header.filters is None       # Betaflight's chain not assumed
    assert other.gyro_prefilter_dps is None and other.throttle is None          # debug modes are Betaflight's
    assert other.gyro_dps.shape == (16774, 3)
    assert bb.sniff(text[:64]) and bb.sniff(b"\xff" * 10 + text[:64]) and not bb.sniff(b"\x89HDF")


def test_filtered_streams_are_written_beside_as_csv(log, tmp_path):
    assert not bb.PATCHABLE and "variable-length" in bb.NOT_PATCHABLE_REASON
    filt = log.gyro_prefilter_dps * 0.5
    out = bb.write_filtered_csv(log, filt, tmp_path / "f.csv")
    with out.open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time_s", "gyroADC_x", "gyroADC_y", "gyroADC_z", "gyro_prefilter_x", "gyro_prefilter_y",
                       "gyro_prefilter_z", "filtered_x", "filtered_y", "filtered_z"]
    assert len(rows) == len(log.main) + 1
    arr = np.array(rows[1:], dtype=float)
    np.testing.assert_allclose(arr[:, 0], log.time_s, atol=1e-9)
    np.testing.assert_allclose(arr[:, 7:], filt, atol=1e-6)
    with pytest.raises(InputError, match="shape"):
        bb.write_filtered_csv(log, filt[:10], tmp_path / "g.csv")


def test_mutated_logs_decode_or_give_one_line(path, tmp_path):
    """A seeded fuzz over the first 40 kB of the log: header bytes changed, body bytes changed,
    truncations, chunks cut out or inserted. Each file decodes (damage counted) or gives one
    InputError line; nothing else is raised."""
    data = path.read_bytes()[:40000]
    body = data.index(b"\nI") + 1
    rng = np.random.default_rng(2037)
    target = tmp_path / "m.bfl"
    outcomes = {"decoded": 0, "refused": 0}
    for trial in range(120):
        b = bytearray(data)
        mode = trial % 4
        if mode == 0:
            for _ in range(rng.integers(1, 4)):
                b[rng.integers(0, body)] = rng.integers(32, 127)
        elif mode == 1:
            for _ in range(rng.integers(1, 20)):
                b[rng.integers(body, len(b))] = rng.integers(0, 256)
        elif mode == 2:
            b = b[: rng.integers(0, len(b))]
        else:
            i = int(rng.integers(0, len(b)))
            b = b[:i] + rng.integers(0, 256, int(rng.integers(0, 50))).astype(np.uint8).tobytes() + \
                b[i + int(rng.integers(1, 200)):]
        target.write_bytes(bytes(b))
        try:
            for lg in bb.read_blackbox(target):
                assert lg.main.shape[1] == len(lg.fields)
                if all(f"gyroADC[{k}]" in lg.fields for k in range(3)):
                    assert lg.gyro_dps.shape == (len(lg.main), 3)
            outcomes["decoded"] += 1
        except InputError as e:
            assert "\n" not in str(e)
            outcomes["refused"] += 1
    assert outcomes["decoded"] > 60 and outcomes["refused"] > 5


def test_header_without_looptime_and_with_old_gyro_scale_name(path, log, tmp_path):
    """Cleanflight's 2016 logs have no looptime line and name the scale gyro.scale (counts to deg/s)."""
    text = path.read_bytes()
    old = text.replace(b"H looptime:125\n", b"", 1).replace(b"H gyro_scale:0x3f800000", b"H gyro.scale:0x3d79c190", 1)
    p = tmp_path / "old.TXT"
    p.write_bytes(old)
    got = bb.read_blackbox(p)[0]
    assert got.header.looptime_us is None and np.isnan(got.header.log_rate_hz) and got.header.filters is None
    assert got.sample_rate_hz == 1000.0
    np.testing.assert_allclose(got.gyro_dps, log.main[:, [log.fields.index(f"gyroADC[{k}]") for k in range(3)]]
                               * np.float32(0.0609756112), rtol=1e-7)
