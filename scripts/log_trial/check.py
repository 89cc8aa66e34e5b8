"""Independent check of ``gyrodenoise mavlink`` on one autopilot log.

Reads the log with pymavlink (DataFlash .bin, telemetry .tlog) or pyulog (.ulg), never
with gyrodenoise, and prints one JSON object:

* ``log``: what the log itself shows: gyro streams (samples, median rate), boots (time
  restarts), time base (boot or Unix epoch), arming and in-air intervals where the log
  has that evidence, GPS ground speed and altitude;
* ``ours``: the same figures from our tool's JSON (``OUT/stdout.json``);
* ``copy``: the filtered copy against the input: same length, the bytes that differ
  (outside the gyro fields: must be 0), and a message-by-message comparison of every
  non-gyro field through pymavlink / pyulog.

Usage::

    python scripts/log_trial/check.py LOG OUT_DIR   # OUT_DIR: where -o wrote, with stdout.json
"""

from __future__ import annotations

import json
from collections import Counter
import struct
import sys
from pathlib import Path

import numpy as np

# gyro fields per message, as the formats name them (independent of gyrodenoise)
DF_GYRO = ("GyrX", "GyrY", "GyrZ")
TLOG_GYRO_MSGS = ("RAW_IMU", "SCALED_IMU", "SCALED_IMU2", "SCALED_IMU3", "HIGHRES_IMU")
TLOG_GYRO = ("xgyro", "ygyro", "zgyro")
ULOG_GYRO = {
    "sensor_combined": ("gyro_rad",),
    "sensor_gyro": ("x", "y", "z"),
    "vehicle_angular_velocity": ("xyz",),
    "sensor_gyro_fifo": ("x", "y", "z"),
}
# ArduPilot EV ids (AP_Logger LogEvent)
EV_ARMED, EV_DISARMED, EV_LAND_COMPLETE, EV_NOT_LANDED = 10, 11, 18, 28


def median_rate(t_s):
    t = np.asarray(t_s, float)
    if t.size < 3:
        return None
    d = np.diff(t)
    d = d[d > 0]
    return round(float(1.0 / np.median(d)), 3) if d.size else None


def intervals(t, state):
    """[start, end] runs where state is true (t sorted)."""
    out, start = [], None
    for ti, s in zip(t, state):
        if s and start is None:
            start = ti
        elif not s and start is not None:
            out.append([round(start, 3), round(ti, 3)])
            start = None
    if start is not None:
        out.append([round(start, 3), round(t[-1], 3)])
    return out


def total(iv):
    return round(sum(b - a for a, b in iv), 3)


def split_boots(t, jump_back_s=1.0):
    """indices where the time goes back by more than jump_back_s: a restart."""
    t = np.asarray(t, float)
    return [int(i) + 1 for i in np.nonzero(np.diff(t) < -jump_back_s)[0]]


# ------------------------------------------------------------------ DataFlash


def df_messages(path):
    """(name, start offset, length, DFFormat, DFMessage) for every message, by pymavlink."""
    from pymavlink import DFReader

    r = DFReader.DFReader_binary(str(path), zero_time_base=True)
    out = []
    while True:
        m = r.recv_msg()
        if m is None:
            break
        fmt = m.fmt
        end = r.offset
        out.append((m.get_type(), end - fmt.len, fmt.len, fmt, m))
    return out


def df_field_ranges(fmt, names):
    """byte ranges (relative to the message start) of the named columns."""
    ranges = []
    for name in names:
        if name not in fmt.colhash:
            continue
        from pymavlink.DFReader import FORMAT_TO_STRUCT

        i = fmt.colhash[name]
        chars = [FORMAT_TO_STRUCT[c][0] for c in fmt.msg_fmts]
        off = 3 + struct.calcsize("<" + "".join(chars[:i]))
        ranges.append((off, off + struct.calcsize("<" + chars[i])))
    return ranges


def df_gyro_ranges(fmt, msg):
    if all(c in fmt.colhash for c in DF_GYRO):
        return df_field_ranges(fmt, DF_GYRO)
    if fmt.name == "ISBD":
        return df_field_ranges(fmt, ("x", "y", "z"))  # allowed: batch samples (gyro or accel)
    return []


def df_facts(path):
    msgs = df_messages(path)
    streams, t_all, ev, arm, gps, ctun_tho, isbh = {}, [], [], [], [], [], {}
    now = None  # boot time of the last timestamped record: untimed records (EV on Copter 3.1) get it
    untimed_ev = []  # EV before the first timestamp (Copter 3.1 logs from arming on: EV ARMED first)
    for name, _, _, fmt, m in msgs:
        t = getattr(m, "TimeUS", None)
        if t is None and name != "GPS":  # old GPS.TimeMS is GPS time of week, not boot time
            t = getattr(m, "TimeMS", None)
            t = None if t is None else t * 1000
        if t is not None:
            t_all.append(t / 1e6)
            now = t
        elif name == "EV" and now is not None:
            t = now
        elif name == "EV":
            untimed_ev.append(m.Id)
        if all(c in fmt.colhash for c in DF_GYRO) and t is not None:
            inst = getattr(m, "I", None)
            key = name if inst is None else f"{name}[{inst}]"
            streams.setdefault(key, []).append(t / 1e6)
        if name == "ISBH" and getattr(m, "type", None) == 1:
            isbh.setdefault(m.instance, 0)
            isbh[m.instance] += 1
        if name == "EV" and t is not None:
            ev.append((t / 1e6, m.Id))
        if name == "ARM" and t is not None:
            arm.append((t / 1e6, int(m.ArmState)))
        tg = getattr(m, "TimeUS", None) if name == "GPS" else None
        tg = tg / 1e6 if tg is not None else (getattr(m, "TimeMS", 0) / 1e3 if name == "GPS" else None)
        if name == "GPS" and getattr(m, "Status", 0) >= 3:
            gps.append((tg, float(getattr(m, "Spd", 0.0)), float(getattr(m, "Alt", 0.0))))
        if name == "CTUN" and t is not None and hasattr(m, "ThO"):
            ctun_tho.append((t / 1e6, float(m.ThO)))
    ev = [(t_all[0] if t_all else 0.0, i) for i in untimed_ev] + ev
    restarts = split_boots(t_all)
    boots = len(restarts) + 1
    armed_iv, air_iv = [], []
    a0 = l0 = None
    for t, i in sorted(ev) if boots == 1 else ev:
        if i in (EV_ARMED, 15):
            a0 = t if a0 is None else a0
        elif i == EV_DISARMED and a0 is not None:
            armed_iv.append([round(a0, 3), round(t, 3)])
            a0 = None
        elif i == EV_NOT_LANDED:
            l0 = t if l0 is None else l0
        elif i == EV_LAND_COMPLETE and l0 is not None:
            air_iv.append([round(l0, 3), round(t, 3)])
            l0 = None
    end = t_all[-1] if t_all else 0.0
    if a0 is not None:
        armed_iv.append([round(a0, 3), round(end, 3)])
    if l0 is not None:
        air_iv.append([round(l0, 3), round(end, 3)])
    facts = {
        "format": "dataflash",
        "messages": len(msgs),
        "boots": boots,
        "restart_times_s": [round(t_all[i], 3) for i in restarts],
        "time_span_s": [round(min(t_all), 3), round(max(t_all), 3)] if t_all else None,
        "streams": {k: {"samples": len(v), "rate_hz": median_rate(v)} for k, v in streams.items()},
        "batch_gyro_bursts": isbh,
        "events": sorted({i for _, i in ev}),
        "armed": armed_iv,
        "armed_s": total(armed_iv),
        "arm_msgs": len(arm),
        "in_air_from_ev": air_iv,
        "in_air_s": total(air_iv),
    }
    if gps:
        g = np.array(gps)
        moving = g[:, 1] > 3.0
        facts["gps"] = {
            "fixes": len(g),
            "max_speed_m_s": round(float(g[:, 1].max()), 2),
            "alt_range_m": round(float(g[:, 2].max() - g[:, 2].min()), 1),
            "moving_over_3m_s": intervals(list(g[:, 0]), list(moving))[:10],
            "moving_over_3m_s_total": total(intervals(list(g[:, 0]), list(moving))),
        }
    if ctun_tho:
        c = np.array(ctun_tho)
        facts["ctun_tho_max"] = round(float(c[:, 1].max()), 3)
    return facts


def df_copy(src, dst):
    a, b = Path(src).read_bytes(), Path(dst).read_bytes()
    res = {"same_length": len(a) == len(b), "len_in": len(a), "len_out": len(b)}
    ma, mb = df_messages(src), df_messages(dst)
    res["messages_in"], res["messages_out"] = len(ma), len(mb)
    allowed = np.zeros(len(a), bool)
    type_mismatch = field_diff = gyro_changed = 0
    first = []
    for (na, oa, la, fa, xa), (nb, ob, lb, fb, xb) in zip(ma, mb):
        if na != nb or oa != ob or la != lb:
            type_mismatch += 1
            if len(first) < 5:
                first.append(f"message at {oa}: {na} vs {nb} at {ob}")
            continue
        gr = df_gyro_ranges(fa, xa)
        for s, e in gr:
            allowed[oa + s : oa + e] = True
        gyro_cols = set(DF_GYRO) | ({"x", "y", "z"} if na == "ISBD" else set())
        for col in fa.columns:
            if col in gyro_cols:
                continue
            va, vb = getattr(xa, col, None), getattr(xb, col, None)
            same = va == vb or (isinstance(va, float) and isinstance(vb, float) and np.isnan(va) and np.isnan(vb))
            if not same:
                field_diff += 1
                if len(first) < 5:
                    first.append(f"{na}.{col} at {oa}: {va!r} -> {vb!r}")
        if gr and a[oa : oa + la] != b[ob : ob + lb]:
            gyro_changed += 1
    res["message_sequence_mismatches"] = type_mismatch + abs(len(ma) - len(mb))
    res["non_gyro_field_differences"] = field_diff
    res["gyro_messages_changed"] = gyro_changed
    n = min(len(a), len(b))
    diff = np.frombuffer(a[:n], np.uint8) != np.frombuffer(b[:n], np.uint8)
    res["bytes_differing"] = int(diff.sum()) + abs(len(a) - len(b))
    res["bytes_differing_outside_gyro_fields"] = int((diff & ~allowed[:n]).sum()) + abs(len(a) - len(b))
    res["examples"] = first
    return res


# ------------------------------------------------------------------ telemetry log


def tlog_messages(path):
    from pymavlink import mavutil

    c = mavutil.mavlink_connection(str(path), dialect="ardupilotmega", robust_parsing=True)
    out = []
    while True:
        m = c.recv_msg()
        if m is None:
            break
        if m.get_type() == "BAD_DATA":
            out.append(("BAD_DATA", None, m))
            continue
        out.append((m.get_type(), m._timestamp, m))
    return out


def tlog_facts(path):
    msgs = tlog_messages(path)
    streams, tb, hb, vfr, landed = {}, [], [], [], []
    for name, ts, m in msgs:
        if name in TLOG_GYRO_MSGS:
            t = m.time_usec / 1e6 if hasattr(m, "time_usec") else m.time_boot_ms / 1e3
            streams.setdefault(name, []).append(t)
        if hasattr(m, "time_boot_ms") and m.get_srcComponent() == 1:
            tb.append(m.time_boot_ms / 1e3)
        # on the boot clock (the autopilot's time_boot_ms): SITL runs faster than the wall clock
        if name == "HEARTBEAT" and m.type not in (6, 27) and m.autopilot != 8 and tb:
            hb.append((tb[-1], bool(m.base_mode & 128)))
        if name == "VFR_HUD":
            vfr.append((ts, m.groundspeed, m.alt))
        if name == "EXTENDED_SYS_STATE":
            landed.append((ts, m.landed_state))
    facts = {
        "format": "tlog",
        "messages": len(msgs),
        "bad_data": sum(1 for n, _, _ in msgs if n == "BAD_DATA"),
        "boots": len(split_boots(tb)) + 1 if tb else None,
        "streams": {k: {"samples": len(v), "rate_hz": median_rate(v)} for k, v in streams.items()},
    }
    if hb:
        t = [x[0] for x in hb]
        iv = intervals(t, [x[1] for x in hb])
        facts["armed_boot_time"] = iv[:10]
        facts["armed_s"] = total(iv)
    if vfr:
        v = np.array(vfr)
        facts["vfr_max_groundspeed"] = round(float(v[:, 1].max()), 2)
        facts["vfr_alt_range"] = round(float(v[:, 2].max() - v[:, 2].min()), 1)
    if landed:
        t = [x[0] for x in landed]
        facts["in_air_s"] = total(intervals(t, [x[1] in (2, 3, 4) for x in landed]))
    return facts


def tlog_copy(src, dst):
    a, b = Path(src).read_bytes(), Path(dst).read_bytes()
    ma, mb = tlog_messages(src), tlog_messages(dst)
    res = {"len_in": len(a), "len_out": len(b), "messages_in": len(ma), "messages_out": len(mb)}
    seq = field_diff = 0
    first = []
    for (na, ta, xa), (nb, tb, xb) in zip(ma, mb):
        if na != nb or ta != tb:
            seq += 1
            if len(first) < 5:
                first.append(f"{na}@{ta} vs {nb}@{tb}")
            continue
        if na == "BAD_DATA":
            if xa.data != xb.data:
                field_diff += 1
            continue
        skip = TLOG_GYRO if na in TLOG_GYRO_MSGS else ()
        for f in xa.get_fieldnames():
            if f in skip:
                continue
            va, vb = getattr(xa, f), getattr(xb, f)
            if va != vb and repr(va) != repr(vb):  # repr: NaN (and lists of NaN) equal to itself
                field_diff += 1
                if len(first) < 5:
                    first.append(f"{na}.{f}@{ta}: {va!r} -> {vb!r}")
        if not skip and xa.get_msgbuf() != xb.get_msgbuf():
            field_diff += 1
            if len(first) < 5:
                first.append(f"{na}@{ta}: packet bytes differ")
    res["message_sequence_mismatches"] = seq + abs(len(ma) - len(mb))
    res["non_gyro_field_differences"] = field_diff
    res["examples"] = first
    return res


# ------------------------------------------------------------------ ULog

_ULOG_SIZES = {
    "int8_t": 1,
    "uint8_t": 1,
    "int16_t": 2,
    "uint16_t": 2,
    "int32_t": 4,
    "uint32_t": 4,
    "int64_t": 8,
    "uint64_t": 8,
    "float": 4,
    "double": 8,
    "bool": 1,
    "char": 1,
}


def _ulog_flat(formats, name, prefix=""):
    """[(flat field name, offset, size)] of a format, nested types flattened."""
    out, off = [], 0
    for typ, n, fname in formats[name].fields:
        reps = range(n) if n > 0 else [None]
        for i in reps:
            fn = prefix + fname + ("" if i is None else f"[{i}]")
            if typ in _ULOG_SIZES:
                out.append((fn, off, _ULOG_SIZES[typ]))
                off += _ULOG_SIZES[typ]
            else:
                sub = _ulog_flat(formats, typ, fn + ".")
                size = sum(s for _, _, s in sub)
                out.extend((f, off + o, s) for f, o, s in sub)
                off += size
    return out


def ulog_walk(data):
    """[(type char, offset of the message, size incl. header, payload)] of a ULog file."""
    out, off = [], 16
    while off + 3 <= len(data):
        size, typ = struct.unpack_from("<HB", data, off)
        if off + 3 + size > len(data):
            out.append(("TRUNC", off, len(data) - off, b""))
            break
        out.append((chr(typ), off, 3 + size, data[off + 3 : off + 3 + size]))
        off += 3 + size
    return out


def ulog_gyro_byte_mask(data, formats):
    allowed = np.zeros(len(data), bool)
    subs, changed_topics = {}, {}
    for typ, off, size, payload in ulog_walk(data):
        if typ == "A":
            msg_id = struct.unpack_from("<H", payload, 1)[0]
            subs[msg_id] = payload[3:].decode("utf-8", "replace")
        elif typ == "D":
            msg_id = struct.unpack_from("<H", payload, 0)[0]
            name = subs.get(msg_id)
            if name in ULOG_GYRO and name in formats:
                for fn, o, s in _ulog_flat(formats, name):
                    if fn.split("[")[0] in ULOG_GYRO[name]:
                        allowed[off + 5 + o : off + 5 + o + s] = True
    return allowed, subs, changed_topics


def ulog_facts(path):
    from pyulog import ULog

    u = ULog(str(path))
    streams, t0 = {}, u.start_timestamp
    for d in u.data_list:
        if d.name in ULOG_GYRO:
            t = d.data["timestamp"] / 1e6
            key = d.name if d.multi_id == 0 else f"{d.name}[{d.multi_id}]"
            info = {"samples": int(t.size), "rate_hz": median_rate(t)}
            if d.name == "sensor_gyro_fifo" and "dt" in d.data:
                n = d.data.get("samples")
                info["fifo_rate_hz"] = round(float(1e6 / np.median(d.data["dt"])), 1)
                info["fifo_samples"] = int(np.sum(n)) if n is not None else None
            streams[key] = info
    facts = {
        "format": "ulog",
        "file_corrupt": bool(u.file_corruption),
        "start_timestamp_s": round(t0 / 1e6, 3),
        "epoch_time_base": t0 > 1e15,  # > ~31 years of boot time: Unix epoch
        "last_timestamp_s": round(u.last_timestamp / 1e6, 3),
        "appended_offsets": [int(x) for x in u._appended_offsets if x],
        "dropouts": len(u.dropouts),
        "topics": len({d.name for d in u.data_list}),
        "streams": streams,
    }
    for d in u.data_list:
        t = list(d.data["timestamp"] / 1e6)
        if d.name == "vehicle_status" and d.multi_id == 0:
            iv = intervals(t, list(d.data["arming_state"] == 2))
            facts["armed"], facts["armed_s"] = iv, total(iv)
        if d.name == "vehicle_land_detected" and d.multi_id == 0:
            iv = intervals(t, list(d.data["landed"] == 0))
            facts["in_air"], facts["in_air_s"] = iv, total(iv)
        if d.name == "vehicle_gps_position" and d.multi_id == 0 and "vel_m_s" in d.data:
            facts["gps_max_speed_m_s"] = round(float(np.max(d.data["vel_m_s"])), 2)
    return facts


def ulog_copy(src, dst):
    from pyulog import ULog

    a, b = Path(src).read_bytes(), Path(dst).read_bytes()
    ua, ub = ULog(str(src)), ULog(str(dst))
    res = {"same_length": len(a) == len(b), "len_in": len(a), "len_out": len(b)}
    wa, wb = ulog_walk(a), ulog_walk(b)
    res["message_kinds_in"] = dict(sorted(Counter(x[0] for x in wa).items()))
    res["message_kinds_out"] = dict(sorted(Counter(x[0] for x in wb).items()))
    res["message_sequence_mismatches"] = sum(
        1 for x, y in zip(wa, wb) if (x[0], x[1], x[2]) != (y[0], y[1], y[2])
    ) + abs(len(wa) - len(wb))
    allowed, _, _ = ulog_gyro_byte_mask(a, ua.message_formats)
    n = min(len(a), len(b))
    diff = np.frombuffer(a[:n], np.uint8) != np.frombuffer(b[:n], np.uint8)
    res["bytes_differing"] = int(diff.sum()) + abs(len(a) - len(b))
    res["bytes_differing_outside_gyro_fields"] = int((diff & ~allowed[:n]).sum()) + abs(len(a) - len(b))
    # pyulog, field by field
    db = {(d.name, d.multi_id): d for d in ub.data_list}
    field_diff, first, changed_gyro = 0, [], {}
    for d in ua.data_list:
        e = db.get((d.name, d.multi_id))
        if e is None:
            field_diff += 1
            first.append(f"{d.name}[{d.multi_id}] missing in copy")
            continue
        gyro = ULOG_GYRO.get(d.name, ())
        for f, va in d.data.items():
            vb = e.data.get(f)
            if f.split("[")[0] in gyro:
                if vb is not None and not np.array_equal(va, vb, equal_nan=True):
                    changed_gyro.setdefault(f"{d.name}[{d.multi_id}]", []).append(f)
                continue
            if (
                vb is None
                or va.shape != vb.shape
                or not np.array_equal(np.ascontiguousarray(va).view(np.uint8), np.ascontiguousarray(vb).view(np.uint8))
            ):
                field_diff += 1
                if len(first) < 5:
                    first.append(f"{d.name}[{d.multi_id}].{f} differs")
    res["non_gyro_field_differences"] = field_diff
    res["gyro_fields_changed"] = changed_gyro
    res["params_equal"] = (
        ua.initial_parameters == ub.initial_parameters and ua.changed_parameters == ub.changed_parameters
    )
    res["logged_messages_equal"] = [(m.timestamp, m.message) for m in ua.logged_messages] == [
        (m.timestamp, m.message) for m in ub.logged_messages
    ]
    res["info_equal"] = ua.msg_info_dict == ub.msg_info_dict
    res["examples"] = first
    return res


# ------------------------------------------------------------------ ours


def ours(out_dir):
    p = Path(out_dir) / "stdout.json"
    if not p.exists():
        return None
    d = json.loads(p.read_text() or "null")
    if not d or "logs" not in d or not d["logs"]:
        return d
    L = d["logs"][0]
    return {
        "exit_status": d.get("exit_status"),
        "format": L.get("format"),
        "boots": len(L.get("boots") or []),
        "time_base": L.get("time_base"),
        "restarts": len(L.get("restarts") or []),
        "flying_time_s": L.get("flying_time_s"),
        "per_boot_flying_s": [b.get("flying_time_s") for b in L.get("boots") or []],
        "segments": [(s["kind"], s["start_s"], s["end_s"], s.get("session")) for s in L.get("segments") or []][:20],
        "over": L.get("over"),
        "streams": {
            s["name"]: {
                "samples": s.get("samples"),
                "rate_hz": s.get("rate_hz"),
                "restarts": s.get("restarts"),
                "left_raw": s.get("left_raw"),
                "too_slow": s.get("too_slow_to_denoise"),
                "not_filtered": s.get("not_filtered"),
            }
            for s in L.get("streams") or []
        },
        "streams_skipped": L.get("streams_skipped"),
        "output_log": L.get("output_log"),
        "filter_review_note": L.get("filter_review_note"),
        "vibration_verdict": (L.get("vibration") or {}).get("verdict"),
        "unreadable_records": L.get("unreadable_records"),
        "truncated": L.get("truncated"),
    }


FORMATS = {".bin": (df_facts, df_copy), ".tlog": (tlog_facts, tlog_copy), ".ulg": (ulog_facts, ulog_copy)}


def main(argv):
    log, out_dir = Path(argv[1]), Path(argv[2])
    facts_fn, copy_fn = FORMATS[log.suffix.lower()]
    res = {"file": str(log), "log": facts_fn(log), "ours": ours(out_dir)}
    o = res["ours"] or {}
    out_log = o.get("output_log") if isinstance(o, dict) else None
    if out_log and Path(out_log).exists():
        res["copy"] = copy_fn(log, out_log)
    print(json.dumps(res, indent=1, default=str))


if __name__ == "__main__":
    main(sys.argv)
