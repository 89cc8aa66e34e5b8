"""Every shared flight log, in every format: the filtered copy changes the gyro
fields and nothing else. Checked with independent readers (pymavlink for
DataFlash and telemetry logs, pyulog for ULog) on the original and the copy, and
with a byte diff: every message decodes the same except the gyro fields, which
hold the filtered values (here: the raw values times FACTOR), and the changed
bytes lie in the gyro fields (and, for MAVLink, the packets' CRC)."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from gyrodenoise.errors import InputError
from tests.flightlog.test_format_fidelity import (ULOG_GYRO, assert_ulog_same_except, changed_positions,
                                                  df_messages, filter_copy, ulog_gyro_positions)
from tests.helpers import SHARED_LOGS

FACTOR = 0.5
LOG_SUFFIXES = (".bin", ".tlog", ".ulg")
BIG = 1_000_000          # bytes: logs above this are marked slow


def scaled(s):
    """The 'filtered' values written: raw * FACTOR; a non-finite raw sample as it is."""
    return np.where(np.isfinite(s.raw), s.raw * FACTOR, s.raw)


def shared_logs():
    if not SHARED_LOGS.is_dir():
        return [pytest.param(None, marks=pytest.mark.skip(reason=f"no shared logs at {SHARED_LOGS}"))]
    out = []
    for p in sorted(SHARED_LOGS.iterdir()):
        if p.is_file() and p.suffix.lower() in LOG_SUFFIXES:
            marks = [pytest.mark.slow] if p.stat().st_size > BIG else []
            out.append(pytest.param(p, id=p.name, marks=marks))
    return out


def same(a, b):
    """Equal values, NaN equal to NaN (field values of pymavlink messages)."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


def scaled_ok(orig, got, is_float, strict):
    """``got`` is ``orig`` times FACTOR as the field stores it (float32 exactly; an
    integer to the nearest, a tie either way); or, unless ``strict``, ``orig`` (a
    stream left raw)."""
    if not strict and same(orig, got):
        return True
    if is_float:
        if not math.isfinite(orig):
            return same(orig, got)
        return got == float(np.float32(orig * FACTOR))
    return abs(got - orig * FACTOR) <= 0.5 + 1e-6


# -------------------------------------------------------------------- DataFlash
IMU_NAME = re.compile(r"^IMU\d?$")
DF_GYRO = ("GyrX", "GyrY", "GyrZ")


def check_dataflash(src, out, strict=True):
    before, after = df_messages(src), df_messages(out)
    assert [m[0] for m in before] == [m[0] for m in after]
    gyro_n = {}                    # ISBH N of gyro bursts
    changed = 0
    for (name, fa), (_, fb) in zip(before, after):
        assert list(fa) == list(fb), name
        if name == "ISBH":
            gyro_n[fa["N"]] = fa["type"] == 1
        if IMU_NAME.match(name) and all(g in fa for g in DF_GYRO):
            gyro = DF_GYRO
        elif name == "ISBD" and gyro_n.get(fa.get("N")):
            gyro = ("x", "y", "z")
        else:
            gyro = ()
        for k in fa:
            va, vb = fa[k], fb[k]
            if hasattr(va, "tolist"):                   # ISBD's int16 arrays
                va, vb = va.tolist(), vb.tolist()
            if k not in gyro:
                assert same(va, vb), (name, k, va, vb)
            elif isinstance(va, list):                  # the unused tail of a burst kept
                assert all(scaled_ok(x, y, False, False) for x, y in zip(va, vb)), (name, k)
                changed += sum(x != y for x, y in zip(va, vb))
            else:
                assert scaled_ok(va, vb, True, strict), (name, k, va, vb)
                changed += va != vb
    return changed


# ------------------------------------------------------------ telemetry logs
TLOG_GYRO = {"RAW_IMU", "SCALED_IMU", "SCALED_IMU2", "SCALED_IMU3", "HIGHRES_IMU"}
MAV_GYRO = ("xgyro", "ygyro", "zgyro")


def tlog_messages(path):
    """[(type, {field: value} or raw bytes for BAD_DATA, tlog timestamp)] as pymavlink reads them."""
    from pymavlink import mavutil
    m = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    out = []
    while (msg := m.recv_msg()) is not None:
        t = msg.get_type()
        if t == "BAD_DATA":
            out.append((t, bytes(msg.data), None))
        else:
            out.append((t, msg.to_dict(), getattr(msg, "_timestamp", None)))
    return out


def check_tlog(src, out, strict=True):
    before, after = tlog_messages(src), tlog_messages(out)
    assert [m[0] for m in before] == [m[0] for m in after]
    changed = 0
    for (t, fa, ta), (_, fb, tb) in zip(before, after):
        assert ta == tb
        if t == "BAD_DATA" or t not in TLOG_GYRO:
            assert same(fa, fb) if t == "BAD_DATA" else all(same(fa[k], fb[k]) for k in fa), (t, fa, fb)
            continue
        for k in fa:
            if k in MAV_GYRO:
                assert scaled_ok(fa[k], fb[k], t == "HIGHRES_IMU", strict), (t, k, fa[k], fb[k])
                changed += fa[k] != fb[k]
            else:
                assert same(fa[k], fb[k]), (t, k)
    return changed


# ------------------------------------------------------------------- ULog
def check_ulog(src, out, streams):
    expected = {}
    for s in streams:
        _, _, inst = s.name.partition("[")
        expected[(s.message, int(inst.rstrip("]")) if inst else 0)] = s.filtered
    assert_ulog_same_except(src, out, ULOG_GYRO, expected)
    import pyulog
    orig = pyulog.ULog(str(src))
    for d in orig.data_list:                   # the expected values from pyulog's raw ones
        if d.name in ULOG_GYRO:
            raw = np.stack([d.data[c] for c in ULOG_GYRO[d.name]], axis=1).astype(np.float64)
            np.testing.assert_array_equal(expected[(d.name, d.multi_id)].astype(np.float32),
                                          np.where(np.isfinite(raw), raw * FACTOR, raw).astype(np.float32))
    allowed = ulog_gyro_positions(src, ULOG_GYRO)
    assert changed_positions(src.read_bytes(), out.read_bytes()) - allowed == set()


# -------------------------------------------------------------------- the test
@pytest.mark.parametrize("src", shared_logs())
def test_filtered_copy_changes_only_the_gyro_fields(tmp_path, src):
    out = tmp_path / ("filtered" + src.suffix)
    try:
        streams, facts = filter_copy(src, out, scaled)
    except InputError as exc:                   # a log without a gyro stream: one line, no copy
        assert "no gyro stream" in str(exc) and not out.exists()
        return
    orig, new = src.read_bytes(), out.read_bytes()
    suffix = src.suffix.lower()
    if suffix == ".ulg":
        check_ulog(src, out, streams)
        return
    n_samples = sum(s.n for s in streams)
    if suffix == ".bin":
        assert len(orig) == len(new)
        assert check_dataflash(src, out) > 0
        assert len(changed_positions(orig, new)) <= 12 * n_samples
    else:
        changed = check_tlog(src, out)
        assert changed > 0
        if len(orig) == len(new):             # gyro fields, CRC and length byte of the gyro packets
            assert len(changed_positions(orig, new)) <= 15 * n_samples
