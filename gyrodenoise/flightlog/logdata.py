"""The per-format message decoders the format adapters use
(:mod:`gyrodenoise.flightlog.formats`): any message of a log as numpy columns,
in bulk (numpy, no loop over the messages), for the flight segments, the
vibration review and the parameters. Read them through
:meth:`gyrodenoise.flightlog.model.FlightLog.messages` (which caches them).

Names are spelled as the format spells them:

* DataFlash (:class:`DataFlashFile`, :func:`dataflash_messages`): the FMT name (``EV``, ``ARM``, ``MODE``,
  ``RCOU``, ``CTUN``, ``VIBE``, ``IMU``, ``PARM``, ``MSG``...). Values as pymavlink's
  ``DFReader`` gives them: format characters ``c``/``C``/``e``/``E`` scaled by 0.01 and
  ``L`` by 1e-7 (floats, divided by 100 and 1e7 as pymavlink does), ``n``/``N``/``Z`` strings (str, NULs stripped), ``a``
  (int16[32]) a 2-D column. ``NAME[i]`` selects instance ``i`` of a message with an
  instance column (``I``, ``IMU``, ``Instance``, ``C`` -- the first of those it has).
  ``time_s``: ``TimeUS`` * 1e-6 (or ``TimeMS`` * 1e-3); a message type with no time
  column takes the time of the last timed message before it in the file (before the
  first, and where the time steps back across it -- a new boot's first messages -- the
  next timed message's); so do old GPS messages, whose ``TimeMS`` is the GPS time of week (they
  do not count as timed messages either). ``record``: the message's byte offset (as a
  gyro stream's ``index``: :func:`dataflash_boot_starts` numbers boots by it).
* Telemetry log (:class:`TelemetryFile`, :func:`tlog_messages`): the message name of pymavlink's
  ``ardupilotmega`` dialect (``HEARTBEAT``, ``VIBRATION``, ``SERVO_OUTPUT_RAW``,
  ``RAW_IMU``, ``PARAM_VALUE``, ``STATUSTEXT``...), readable records only (good CRC,
  not rejected by a signature check). Values as pymavlink gives them; ``char[]``
  fields as str (NULs stripped), other arrays 2-D. Extra columns: ``sysid``,
  ``compid`` (of the packet header), ``log_time_s`` (the record's tlog timestamp,
  UNIX seconds), ``record`` (the record's frame index in the file, as a gyro
  stream's ``index``: :func:`tlog_boot_starts` numbers boot sessions by it). ``time_s`` (boot time, the gyro streams' time base): the message's
  own ``time_boot_ms`` * 1e-3, else its ``time_usec`` * 1e-6 where that is a boot time
  (below 1e12 us, about 11.6 days; larger values are UNIX times); else -- messages with
  no time of their own (HEARTBEAT, PARAM_VALUE, STATUSTEXT...) -- the boot time of the
  last earlier record of the same system that carries a ``time_boot_ms``, plus the
  tlog timestamps' difference between the two records (the first record carrying one
  anchors the records before it; NaN when the system sends none). A reboot
  (``time_boot_ms`` restarting) is followed, as the anchor is always the last one.
* ULog (:class:`ULogFile`, :func:`ulog_messages`): the topic name (``vehicle_status``,
  ``actuator_outputs``, ``sensor_accel``...), its first instance (lowest ``multi_id``);
  ``topic[1]`` the instance with ``multi_id`` 1. Field names as pyulog gives them
  (``accelerometer_m_s2[0]``...); ``char`` arrays joined into one str column.
  ``time_s``: ``timestamp`` * 1e-6 (a topic without ``timestamp``: None).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

import numpy as np

from gyrodenoise.flightlog import tlog

_INDEX_RE = re.compile(r"^(.+)\[(\d+)\]$")
DF_INSTANCE_COLUMNS = ("I", "IMU", "Instance", "C")

# DataFlash format character -> (numpy dtype, shape, divisor as pymavlink applies it)
_DF_CHARS = {
    "a": ("<i2", (32,), None), "b": ("i1", (), None), "B": ("u1", (), None), "g": ("<f2", (), None),
    "h": ("<i2", (), None), "H": ("<u2", (), None), "i": ("<i4", (), None), "I": ("<u4", (), None),
    "f": ("<f4", (), None), "d": ("<f8", (), None), "n": ("S4", (), None), "N": ("S16", (), None),
    "Z": ("S64", (), None), "c": ("<i2", (), 100.0), "C": ("<u2", (), 100.0), "e": ("<i4", (), 100.0),
    "E": ("<u4", (), 100.0), "L": ("<i4", (), 1e7), "M": ("u1", (), None), "q": ("<i8", (), None),
    "Q": ("<u8", (), None),
}
_BOOT_USEC_MAX = 1e12      # time_usec below this is a boot time, above a UNIX time
#: a log's boot time stepping back by more than this (s), in file order, starts a boot session
SESSION_STEP_BACK_S = 0.5


@dataclass
class DataFlashFile:
    """A DataFlash log as read: its bytes and :class:`~gyrodenoise.flightlog.dataflash.DFScan`."""
    data: bytes
    scan: object
    anchors: tuple | None = None


@dataclass
class TelemetryFile:
    """A telemetry log as read: its bytes and :class:`~gyrodenoise.flightlog.tlog.TlogFrames`."""
    data: bytes
    frames: object
    anchors: dict | None = None


@dataclass
class ULogFile:
    """A ULog as read: the ``pyulog.ULog`` and the gyro streams' (dataset, fields)."""
    ulog: object
    refs: list


def dataflash_message_names(f: DataFlashFile):
    sc = f.scan
    return sorted({sc.formats[t].name for t in sc.offsets if t in sc.formats})


def tlog_message_names(f: TelemetryFile):
    fr = f.frames
    mav = tlog._dialect()
    ids = np.unique(fr.msgid[fr.usable])
    return sorted(mav.mavlink_map[int(i)].msgname for i in ids if int(i) in mav.mavlink_map)


def ulog_message_names(f: ULogFile):
    return sorted({d.name if d.multi_id == 0 else f"{d.name}[{d.multi_id}]" for d in f.ulog.data_list})


def _split_index(name):
    m = _INDEX_RE.match(name)
    return (m.group(1), int(m.group(2))) if m else (name, None)


def _strings(col):
    """bytes column -> str column (NULs stripped, undecodable bytes replaced)."""
    flat = np.asarray(col).reshape(-1)
    if not len(flat):
        return np.zeros(0, dtype=str)
    return np.array([b.split(b"\0", 1)[0].decode("utf-8", "replace") for b in flat.tolist()])


# ----------------------------------------------------------------- DataFlash
def _df_dtype(f):
    """(numpy dtype of the message, {column: divisor}) of DataFlash format ``f``."""
    names, formats, offsets, scales = [], [], [], {}
    off = 3
    for ch, col in zip(f.format, f.columns):
        if ch not in _DF_CHARS:
            raise ValueError(f"unknown DataFlash format character {ch!r} in {f.name}")
        base, shape, scale = _DF_CHARS[ch]
        dt = np.dtype((base, shape)) if shape else np.dtype(base)
        names.append(col)
        formats.append(dt)
        offsets.append(off)
        if scale is not None:
            scales[col] = scale
        off += dt.itemsize
    if off > f.length:
        raise ValueError(f"{f.name}: format {f.format!r} gives {off} bytes, FMT says {f.length}")
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": f.length}), scales


def _df_records(data, sc, tid):
    f = sc.formats[tid]
    dt, scales = _df_dtype(f)
    offs = np.asarray(sc.offsets[tid], dtype=np.int64)
    buf = np.frombuffer(data, dtype=np.uint8)
    rows = buf[offs[:, None] + np.arange(f.length)]
    return rows.view(dt).reshape(-1), scales, offs


def _df_time_column(f):
    if "TimeUS" in f.columns:
        return "TimeUS", 1e-6
    if "TimeMS" in f.columns:
        return "TimeMS", 1e-3
    return None, None


def dataflash_messages(f: DataFlashFile, name):
    """Message ``name`` of a DataFlash log (see the module doc); None when absent. A format
    redefined in the log (its FMT again, another layout) gives the rows of every definition,
    in file order; a column that only some definitions have is NaN (empty text) in the others."""
    base, inst = _split_index(name)
    parts = [p for p in (_df_key_messages(f, key, inst) for key in f.scan.keys_named(base)) if p is not None]
    if len(parts) < 2:
        return parts[0] if parts else None
    cols = list(dict.fromkeys(c for p in parts for c in p))
    out = {}
    for c in cols:
        kinds = [p[c] for p in parts if c in p]
        text = any(v.dtype.kind in "OU" for v in kinds)
        out[c] = np.concatenate([p[c] if c in p else np.full(len(p["record"]), "" if text else np.nan,
                                                              dtype=object if text else np.float64)
                                 for p in parts])
    order = np.argsort(out["record"], kind="stable")
    return {c: v[order] for c, v in out.items()}


def _df_key_messages(f: DataFlashFile, tid, inst):
    """The messages of one format key ``tid`` (of instance ``inst`` where not None), or None."""
    data, sc = f.data, f.scan
    fmt = sc.formats[tid]
    rec, scales, offs = _df_records(data, sc, tid)
    if inst is not None:
        icol = next((c for c in DF_INSTANCE_COLUMNS if c in fmt.columns), None)
        if icol is None:
            return None
        keep = rec[icol].astype(np.int64) == inst
        if not keep.any():
            return None
        rec, offs = rec[keep], offs[keep]
    out = {}
    for col in fmt.columns:
        v = rec[col]
        if v.dtype.kind == "S":
            out[col] = _strings(v)
        elif col in scales:
            out[col] = v.astype(np.float64) / scales[col]
        else:
            out[col] = np.array(v)
    tcol, tscale = _df_time_column(fmt)
    if tcol is not None and not _gps_time_of_week(fmt, tcol):
        out["time_s"] = rec[tcol].astype(np.float64) * tscale
    else:
        out["time_s"] = _df_anchor_time(f, offs)
    out["record"] = offs.astype(np.int64)
    return out


def _gps_time_of_week(fmt, tcol):
    """True for old GPS messages, whose ``TimeMS`` is the GPS time of week, not a boot time."""
    return tcol == "TimeMS" and "Week" in fmt.columns


def _df_anchor_time(file: DataFlashFile, offs):
    """Time of the last timed message before each offset; the next one's before the first
    timed message and where the time steps back across the offset (a new boot)."""
    anchors = file.anchors
    if anchors is None:
        data, sc = file.data, file.scan
        at, tt = [], []
        for tid, lst in sc.offsets.items():
            f = sc.formats.get(tid)
            if f is None or not lst:
                continue
            tcol, tscale = _df_time_column(f)
            if tcol is None or _gps_time_of_week(f, tcol):
                continue            # old GPS messages: TimeMS is the GPS time of week
            try:
                rec, _, o = _df_records(data, sc, tid)
            except ValueError:
                continue
            at.append(o)
            tt.append(rec[tcol].astype(np.float64) * tscale)
        if at:
            a, t = np.concatenate(at), np.concatenate(tt)
            order = np.argsort(a, kind="stable")
            anchors = (a[order], t[order])
        else:
            anchors = (np.zeros(0, np.int64), np.zeros(0))
        file.anchors = anchors
    a, t = anchors
    out = np.full(len(offs), np.nan)
    if not len(a):
        return out
    k = np.searchsorted(a, offs) - 1
    # before the first timed message, or where the time steps back across the message
    # (a new boot: logs joined, a reboot), the next timed message's time: an untimed
    # message at a boot's start (Copter 3.1's EV) belongs to that boot, not the one before
    nxt = np.minimum(k + 1, len(a) - 1)
    prev = t[np.maximum(k, 0)]
    use_next = (k < 0) | ((k + 1 < len(a)) & (t[nxt] < prev - SESSION_STEP_BACK_S))
    out[:] = np.where(use_next, t[nxt], prev)
    return out


#: timed messages either side of a step back that must confirm it (a new boot)
BOOT_CONFIRM = 20
#: a new boot's time steps back by more than this share of the time before the step too
#: (a telemetry log's boot time stepping back 1.5 s at 612 s is its stamps, not a reboot)
BOOT_STEP_SHARE = 0.1


def boot_steps(t):
    """Indices ``i`` where a boot begins in the boot times ``t`` (in file order): ``t``
    steps back by more than :data:`SESSION_STEP_BACK_S` and :data:`BOOT_STEP_SHARE` of
    ``t[i - 1]``, and stays back: the median of the next :data:`BOOT_CONFIRM` times is
    below ``t[i - 1]`` and the median of the ones before above ``t[i]`` by as much (one
    damaged timestamp, or a run of them, is no boot)."""
    t = np.asarray(t, dtype=np.float64)
    out = []
    for i in (np.flatnonzero(np.diff(t) < -SESSION_STEP_BACK_S) + 1).tolist():
        step = max(SESSION_STEP_BACK_S, BOOT_STEP_SHARE * abs(t[i - 1]))
        if t[i - 1] - t[i] <= step:
            continue
        if np.median(t[i:i + BOOT_CONFIRM]) < t[i - 1] - step and \
                np.median(t[max(0, i - BOOT_CONFIRM):i]) > t[i] + step:
            out.append(i)
    return np.asarray(out, dtype=np.int64)


def dataflash_boot_starts(f: DataFlashFile):
    """Byte offsets (sorted int64 array) at which a DataFlash log's boots 1, 2, ... begin,
    empty for a log of one boot: where the boot time of the timed message type the log
    holds most of steps back, in file order, and stays back (:func:`boot_steps`). A boot
    begins just after the last timed message (of any type) before the first one whose
    time stepped back, so that its own FMT and PARM messages are in it."""
    _df_anchor_time(f, np.zeros(0, np.int64))
    a, t = f.anchors
    sc = f.scan
    # the message name (not the type id: two logs joined may give one name two ids, and
    # a redefined FMT gives it another key) with the most timed messages, all its keys
    counts = {}
    for key, offs in sc.offsets.items():
        fmt = sc.formats.get(key)
        if fmt is not None and _df_time_column(fmt)[0] is not None \
                and not _gps_time_of_week(fmt, _df_time_column(fmt)[0]):
            counts[fmt.name] = counts.get(fmt.name, 0) + len(offs)
    if not counts or max(counts.values()) < 2:
        return np.zeros(0, np.int64)
    best = max(counts, key=counts.get)
    parts_t, parts_o = [], []
    for key in sc.keys_named(best):
        fmt = sc.formats[key]
        tcol, tscale = _df_time_column(fmt)
        if tcol is None or _gps_time_of_week(fmt, tcol):
            continue
        try:
            rec, _, offs = _df_records(f.data, sc, key)
        except ValueError:
            continue
        parts_t.append(rec[tcol].astype(np.float64) * tscale)
        parts_o.append(np.asarray(offs, dtype=np.int64))
    if not parts_o:
        return np.zeros(0, np.int64)
    offs = np.concatenate(parts_o)
    order = np.argsort(offs, kind="stable")
    offs, tt = offs[order], np.concatenate(parts_t)[order]
    out = []
    for i in boot_steps(tt).tolist():
        lo, hi = np.searchsorted(a, offs[i - 1]), np.searchsorted(a, offs[i])
        back = np.flatnonzero(t[lo:hi + 1] < tt[i - 1] - SESSION_STEP_BACK_S)
        j = lo + int(back[0]) if len(back) else hi
        out.append(int(a[j - 1]) + 1)
    return np.asarray(out, dtype=np.int64)


# --------------------------------------------------------------------- tlog
_STRUCT_TO_NP = {"Q": "<u8", "q": "<i8", "I": "<u4", "i": "<i4", "H": "<u2", "h": "<i2",
                 "B": "u1", "b": "i1", "f": "<f4", "d": "<f8", "c": "S1", "?": "u1"}


def _tlog_fields(c):
    """{field: (offset, dtype, is_string)} of pymavlink message class ``c`` (wire order)."""
    tokens = re.findall(r"(\d*)([a-zA-Z?])", c.unpacker.format.lstrip("<"))
    out = {}
    off = 0
    for name, (cnt, ch) in zip(c.ordered_fieldnames, tokens):
        k = int(cnt) if cnt else 1
        if ch in "sc":
            out[name] = (off, np.dtype(f"S{k}"), True)
        else:
            dt = np.dtype(_STRUCT_TO_NP[ch])
            out[name] = (off, dt if k == 1 else np.dtype((dt, (k,))), False)
        off += struct.calcsize("<" + cnt + ch)
    return out, off


def tlog_messages(f: TelemetryFile, name):
    """Message ``name`` of a telemetry log (see the module doc); None when absent."""
    data, fr = f.data, f.frames
    mav = tlog._dialect()
    mid = getattr(mav, "MAVLINK_MSG_ID_" + name, None)
    if mid is None or mid not in mav.mavlink_map:
        return None
    c = mav.mavlink_map[mid]
    buf = np.frombuffer(data, dtype=np.uint8)
    sel = np.nonzero(fr.usable & (fr.msgid == mid))[0]
    if not len(sel):
        return None
    fields, size = _tlog_fields(c)
    pay = tlog._payloads(buf, fr, sel, size)
    out = {}
    for fname in c.fieldnames:
        off, dt, is_str = fields[fname]
        v = np.ascontiguousarray(pay[:, off:off + dt.itemsize]).view(dt.base).reshape((len(sel),) + dt.shape)
        out[fname] = _strings(v) if is_str else np.array(v)
    v2 = fr.v2[sel]
    start = fr.start[sel]
    sysid = np.where(v2, buf[start + 13], buf[start + 11]).astype(np.int64)
    out["sysid"] = sysid
    out["compid"] = np.where(v2, buf[start + 14], buf[start + 12]).astype(np.int64)
    wall_us = _tlog_stamps_us(buf, start)
    out["log_time_s"] = wall_us * 1e-6
    out["record"] = sel.astype(np.int64)
    own = None
    if "time_boot_ms" in fields:
        own = out["time_boot_ms"].astype(np.float64) * 1e-3
    elif "time_usec" in fields and not fields["time_usec"][1].shape:
        t = out["time_usec"].astype(np.float64)
        if len(t) and np.all(t < _BOOT_USEC_MAX):
            own = t * 1e-6
    out["time_s"] = own if own is not None else _tlog_anchor_time(f, sel, sysid, wall_us)
    return out


def _tlog_stamps_us(buf, start):
    """The records' tlog timestamps (big-endian uint64, us) as int64."""
    b = buf[start[:, None] + np.arange(8)]
    return np.ascontiguousarray(b).view(">u8").reshape(-1).astype(np.int64)


def _tlog_anchors(f: TelemetryFile):
    """Per system id: (frame indices, boot time s, tlog time us) of every record that
    carries a ``time_boot_ms``, in file order."""
    if f.anchors is not None:
        return f.anchors
    data, fr = f.data, f.frames
    mav = tlog._dialect()
    buf = np.frombuffer(data, dtype=np.uint8)
    idx, boot = [], []
    for mid in np.unique(fr.msgid[fr.usable]).tolist():
        c = mav.mavlink_map.get(mid)
        if c is None or "time_boot_ms" not in c.fieldnames:
            continue
        fields, size = _tlog_fields(c)
        sel = np.nonzero(fr.usable & (fr.msgid == mid))[0]
        off, dt, _ = fields["time_boot_ms"]
        pay = tlog._payloads(buf, fr, sel, off + dt.itemsize)
        idx.append(sel)
        boot.append(np.ascontiguousarray(pay[:, off:off + dt.itemsize]).view(dt).reshape(-1) * 1e-3)
    anchors = {}
    if idx:
        i = np.concatenate(idx)
        b = np.concatenate(boot).astype(np.float64)
        order = np.argsort(i, kind="stable")
        i, b = i[order], b[order]
        start = fr.start[i]
        s = np.where(fr.v2[i], buf[start + 13], buf[start + 11]).astype(np.int64)
        w = _tlog_stamps_us(buf, start)
        for sid in np.unique(s).tolist():
            k = s == sid
            anchors[sid] = (i[k], b[k], w[k])
    f.anchors = anchors
    return anchors




def tlog_boot_starts(f: TelemetryFile):
    """Frame indices (sorted int64 array) at which a telemetry log's boot sessions 1, 2, ...
    begin, empty for a log of one boot: where the ``time_boot_ms`` of the system that
    sends most of them steps back, in file order, and stays back (:func:`boot_steps`: a
    reboot, or logs of several boots written into one file). The session of a record with frame index ``i`` is
    ``searchsorted(starts, i, side="right")``: the same numbering for every message
    and gyro stream of the log, whatever their own clocks do."""
    anchors = _tlog_anchors(f)
    if not anchors:
        return np.zeros(0, np.int64)
    sid = max(anchors, key=lambda k: len(anchors[k][0]))
    idx, boot, _ = anchors[sid]
    return np.asarray(idx[boot_steps(boot)], dtype=np.int64)


def _tlog_anchor_time(f, sel, sysid, wall_us):
    anchors = _tlog_anchors(f)
    out = np.full(len(sel), np.nan)
    for sid in np.unique(sysid).tolist():
        got = anchors.get(sid)
        if got is None:
            continue
        ai, ab, aw = got
        k = sysid == sid
        j = np.clip(np.searchsorted(ai, sel[k], side="right") - 1, 0, len(ai) - 1)
        out[k] = ab[j] + (wall_us[k] - aw[j]) * 1e-6
    return out


# --------------------------------------------------------------------- ULog
def ulog_messages(f: ULogFile, name):
    """Topic ``name`` of a ULog (see the module doc); None when absent."""
    u = f.ulog
    base, inst = _split_index(name)
    ds = [d for d in u.data_list if d.name == base]
    if not ds:
        return None
    if inst is None:
        d = min(ds, key=lambda e: e.multi_id)
    else:
        d = next((e for e in ds if e.multi_id == inst), None)
        if d is None:
            return None
    chars = {}
    for f in d.field_data:
        if f.type_str.startswith("char"):
            m = _INDEX_RE.match(f.field_name)
            if m:
                chars.setdefault(m.group(1), []).append((int(m.group(2)), f.field_name))
    out = {}
    done = set()
    for key, val in d.data.items():
        m = _INDEX_RE.match(key)
        if m and m.group(1) in chars:
            base_name = m.group(1)
            if base_name not in done:
                cols = [d.data[k] for _, k in sorted(chars[base_name])]
                mat = np.stack([np.asarray(c).astype(np.uint8) for c in cols], axis=1)
                out[base_name] = _strings(np.ascontiguousarray(mat).view(f"S{mat.shape[1]}"))
                done.add(base_name)
            continue
        out[key] = np.asarray(val)
    if "timestamp" not in d.data:
        return None
    out["time_s"] = np.asarray(d.data["timestamp"], dtype=np.float64) * 1e-6
    return out
