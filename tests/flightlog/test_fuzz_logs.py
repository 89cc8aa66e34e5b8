"""Mutated shared logs (seeded byte flips, truncations, duplicated or altered
format records): reading and writing the filtered copy never raises anything
but the one-line InputError, and the copy changes nothing but the gyro fields
(checked with pymavlink / pyulog on the mutant and its copy, and a bound on the
bytes changed). Small logs, a few mutants each: about 20 s in all."""
from __future__ import annotations

import numpy as np
import pytest

from gyrodenoise.errors import InputError
from tests.flightlog.test_byte_equality import ULOG_GYRO, check_dataflash, check_tlog, scaled
from tests.flightlog.test_format_fidelity import (assert_ulog_same_except, changed_positions, df_messages,
                                                  filter_copy)
from tests.helpers import shared_log

MUTANTS = 16
FMT_HEAD = b"\xa3\x95\x80"


def flips(data, rng):
    out = bytearray(data)
    k = int(rng.integers(1, 40))
    for at, v in zip(rng.integers(0, len(out), k).tolist(), rng.integers(0, 256, k).tolist()):
        out[at] = v
    return bytes(out), f"{k} bytes flipped"


def truncation(data, rng):
    cut = int(rng.integers(len(data) // 10, len(data)))
    return data[:cut], f"cut at {cut}"


def duplicated_fmt(data, rng):
    """A FMT record copied to a later message boundary (as a log restart leaves it),
    or copied with its type's name, format or length altered."""
    starts = [i for i in range(len(data)) if data.startswith(FMT_HEAD, i)][:400]
    if not starts:
        return flips(data, rng)
    a = int(rng.choice(starts))
    rec = bytearray(data[a:a + 89])
    what = "FMT copied"
    if rng.random() < 0.5:
        k = int(rng.integers(4, 89))
        rec[k] = int(rng.integers(256))
        what = f"FMT copied with byte {k} altered"
    heads = [i for i in range(a + 89, len(data) - 3) if data[i] == 0xA3 and data[i + 1] == 0x95][:5000]
    at = int(rng.choice(heads)) if heads else len(data)
    return data[:at] + bytes(rec) + data[at:], f"{what} from {a} to {at}"


def ulog_duplicated(data, rng):
    """A format ('F') or subscription ('A') message copied to a later message boundary."""
    pos, found, bounds = 16, [], []
    while pos + 3 <= len(data) and len(bounds) < 20000:
        size = data[pos] | (data[pos + 1] << 8)
        if data[pos + 2] in b"FA":
            found.append((pos, pos + 3 + size))
        bounds.append(pos)
        pos += 3 + size
    a, b = found[int(rng.integers(len(found)))]
    at = int(rng.choice([p for p in bounds if p > a] or [len(data)]))
    return data[:at] + data[a:b] + data[at:], f"message {a}:{b} copied to {at}"


def tlog_extreme_values(data, rng):
    """Gyro fields of a few RAW_IMU / SCALED_IMU2 packets set to the int16 ends (CRC
    recomputed, so that the packets stay readable), and a HIGHRES_IMU record with an
    infinity and a NaN among its gyro values inserted at a record boundary."""
    from pymavlink.dialects.v20 import ardupilotmega as mav
    from pymavlink.generator.mavcrc import x25crc
    out = bytearray(data)
    starts, pos = [], 0
    while pos + 9 <= len(out) and out[pos + 8] in (0xFE, 0xFD):
        v2 = out[pos + 8] == 0xFD
        n = (12 if v2 else 8) + out[pos + 9] + (13 if v2 and out[pos + 10] & 1 else 0)
        if pos + 8 + n > len(out):
            break
        starts.append((pos, v2))
        pos += 8 + n
    touched = 0
    for i in rng.permutation(len(starts)).tolist():
        a, v2 = starts[i]
        hl = 10 if v2 else 6
        msgid = (out[a + 15] | out[a + 16] << 8) if v2 else out[a + 13]
        if msgid not in (mav.MAVLINK_MSG_ID_RAW_IMU, mav.MAVLINK_MSG_ID_SCALED_IMU2) or (v2 and out[a + 10] & 1):
            continue
        c = mav.mavlink_map[msgid]
        off = 8 if msgid == mav.MAVLINK_MSG_ID_RAW_IMU else 4       # time, then xacc..zacc, then xgyro
        off += 6 + 2 * int(rng.integers(3))
        plen = out[a + 9]
        if off + 2 > plen:
            continue
        p0 = a + 8 + hl
        out[p0 + off:p0 + off + 2] = int(rng.choice([32767, -32768, -32767])).to_bytes(2, "little", signed=True)
        crc = x25crc(bytes(out[a + 9:p0 + plen]))
        crc.accumulate([c.crc_extra])
        out[p0 + plen:p0 + plen + 2] = crc.crc.to_bytes(2, "little")
        touched += 1
        if touched == 5:
            break
    m = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    g = [float("inf"), float("nan"), -1.0]
    pkt = mav.MAVLink_highres_imu_message(1000, 0, 0, 9.8, *g, 0, 0, 0, 1000, 0, 0, 20, 0).pack(m)
    at = starts[int(rng.integers(len(starts)))][0] if starts else 0
    rec = bytes(out[at:at + 8]) + pkt
    return bytes(out[:at]) + rec + bytes(out[at:]), f"{touched} gyro values at int16 ends, HIGHRES_IMU inf/nan at {at}"


def pymavlink_reads(path):
    try:
        df_messages(path)
    except Exception:  # noqa: BLE001 - pymavlink raises bare Exception on a bad FMT
        return False
    return True


def ulog_renamed_field(data, rng):
    """A field of a format ('F') message renamed (same length): half the time
    sensor_combined's timestamp, else a random field of a random format."""
    pos, fmts = 16, []
    while pos + 3 <= len(data):
        size = data[pos] | (data[pos + 1] << 8)
        if data[pos + 2] == ord("F"):
            fmts.append((pos + 3, pos + 3 + size))
        pos += 3 + size
    out = bytearray(data)
    comb = [f for f in fmts if data[f[0]:f[1]].startswith(b"sensor_combined:")]
    if comb and rng.random() < 0.5:
        a, b = comb[0]
        k = data.find(b" timestamp;", a, b)
        if k >= 0:
            out[k + 1] = ord("T")
            return bytes(out), "sensor_combined.timestamp renamed"
    a, b = fmts[int(rng.integers(len(fmts)))]
    spaces = [i for i in range(a, b) if data[i] == 0x20]
    k = int(rng.choice(spaces)) + 1
    out[k] = ord("Q")
    return bytes(out), f"a field renamed at {k}"


CASES = [
    ("plane_truncated_test.BIN", (flips, truncation, duplicated_fmt)),
    ("copter462_notch_fragment.bin", (flips, truncation, duplicated_fmt)),
    ("copter_20211202-133659.tlog", (flips, truncation, tlog_extreme_values)),
    ("fs-batt.log.tlog", (flips, truncation, tlog_extreme_values)),
    ("px4_vtol_small.ulg", (flips, truncation, ulog_duplicated, ulog_renamed_field)),
]


@pytest.mark.parametrize("name,mutations", CASES, ids=[c[0] for c in CASES])
def test_mutated_logs_no_traceback_nothing_else_changed(tmp_path, name, mutations):
    src = shared_log(name)
    data = src.read_bytes()
    rng = np.random.default_rng(sum(map(ord, name)))
    for i in range(MUTANTS):
        mutate = mutations[i % len(mutations)]
        mutant, what = mutate(data, rng)
        path = tmp_path / f"m{i}{src.suffix}"
        path.write_bytes(mutant)
        out = tmp_path / f"m{i}.filtered{src.suffix}"
        try:
            streams, _ = filter_copy(path, out, scaled)
        except InputError as exc:
            assert "\n" not in str(exc) and not out.exists(), what
            continue
        new = out.read_bytes()
        n = sum(s.n for s in streams)
        suffix = src.suffix.lower()
        if suffix == ".bin":
            assert len(new) == len(mutant), what
            if pymavlink_reads(path):        # else (a format character it rejects): the byte bound only
                check_dataflash(path, out, strict=False)
            assert len(changed_positions(mutant, new)) <= 12 * n, what
        elif suffix == ".tlog":
            check_tlog(path, out, strict=False)
        else:
            assert len(new) == len(mutant), what
            assert_ulog_same_except(path, out, ULOG_GYRO)
            assert len(changed_positions(mutant, new)) <= 12 * n, what
