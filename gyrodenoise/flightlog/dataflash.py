"""ArduPilot DataFlash binary logs (``.bin``): scan, decode the IMU gyro fields, patch.

A DataFlash log is a sequence of messages ``A3 95 <type> <payload>``; the
length and layout of each type come from FMT messages (type 128) in the log
itself. :func:`scan` walks the file once (as pymavlink's ``DFReader_binary``
does: bytes that do not start a known message are skipped and counted, a
message cut by the end of the file ends the walk) and keeps the offsets of
every message per type. The IMU messages are then decoded in bulk with numpy,
and :func:`patch` writes the filtered gyro values into a copy of the file at
the same offsets: every other byte of the file is unchanged.

Gyro streams: ``IMU``, ``IMU2``, ``IMU3`` (older logs, one type per IMU) and
``IMU`` with an instance field ``I`` (ArduPilot 4.x: one stream per instance).
Fields ``GyrX``, ``GyrY``, ``GyrZ`` are rad/s (float). Time: ``TimeUS`` (us) or
``TimeMS`` (ms) since boot.

Batch-sampler bursts: an ``ISBH`` header (``type`` 1 = gyro, ``instance``,
``mul``, ``smp_cnt``, ``SampleUS`` of the first sample, ``smp_rate``) followed
by ``ISBD`` messages with the same ``N`` (``seqno`` 0, 1, ...), each holding 32
samples per axis in int16 arrays ``x``, ``y``, ``z``; rad/s = value / mul. One
stream ``ISB.gyro[instance]`` per instance; sample k of a burst is at
``SampleUS + k / smp_rate``. A burst whose ISBD messages are incomplete is
used as far as it goes (the samples it has).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from gyrodenoise.errors import InputError

from gyrodenoise.flightlog.streams import UNIT_TO_DEG_S, GyroStream, require_fit

HEAD1, HEAD2, FMT_TYPE, FMT_LEN = 0xA3, 0x95, 0x80, 89

# DataFlash format characters -> numpy dtype (little endian)
_DF_TYPES = {
    "a": ("<i2", (32,)), "b": ("i1", ()), "B": ("u1", ()), "h": ("<i2", ()), "H": ("<u2", ()),
    "i": ("<i4", ()), "I": ("<u4", ()), "f": ("<f4", ()), "d": ("<f8", ()), "n": ("S4", ()),
    "N": ("S16", ()), "Z": ("S64", ()), "c": ("<i2", ()), "C": ("<u2", ()), "e": ("<i4", ()),
    "E": ("<u4", ()), "L": ("<i4", ()), "M": ("u1", ()), "q": ("<i8", ()), "Q": ("<u8", ()),
}

GYRO_FIELDS = ("GyrX", "GyrY", "GyrZ")
IMU_TYPE_RE = re.compile(r"^IMU\d?$")


@dataclass
class DFFormat:
    type: int
    length: int
    name: str
    format: str
    columns: list

    def dtype(self):
        """numpy structured dtype of the whole message, header included."""
        names, formats, offsets = [], [], []
        off = 3
        for ch, col in zip(self.format, self.columns):
            if ch not in _DF_TYPES:
                raise ValueError(f"unknown DataFlash format character {ch!r} in {self.name}")
            base, shape = _DF_TYPES[ch]
            dt = np.dtype((base, shape)) if shape else np.dtype(base)
            names.append(col)
            formats.append(dt)
            offsets.append(off)
            off += dt.itemsize
        if off != self.length:
            raise ValueError(f"{self.name}: format {self.format!r} gives {off} bytes, FMT says {self.length}")
        return np.dtype({"names": names, "formats": formats, "offsets": offsets,
                         "itemsize": self.length})


@dataclass
class DFScan:
    """Where the messages of a DataFlash log are. ``formats`` and ``offsets`` are
    keyed by a *format key*: the type id for the first definition of a type, and
    ``type id + 256 * k`` for its k-th redefinition with another name or layout (a
    FMT message re-declaring a type id mid-log holds from that point on, as
    pymavlink's sequential reader does); ``formats[key].type`` is the type id."""
    path: str
    size: int
    formats: dict                          # format key -> DFFormat
    offsets: dict                          # format key -> list of offsets
    n_messages: int = 0
    bad_regions: list = field(default_factory=list)   # (start, end) of skipped bytes
    truncated_bytes: int = 0               # bytes of a message cut by the end of the file
    redefinitions: int = 0                 # FMT messages that changed a type's name or layout
    skipped: list = field(default_factory=list)       # why a would-be gyro format was not read

    @property
    def bad_bytes(self):
        return sum(e - s for s, e in self.bad_regions)

    def keys_named(self, name):
        """Format keys (with messages) of the formats named ``name``, in order of definition."""
        return [k for k, f in self.formats.items() if f.name == name and k in self.offsets]


def _parse_fmt(data, pos):
    t = data[pos + 3]
    ln = data[pos + 4]
    name = bytes(data[pos + 5:pos + 9]).split(b"\0", 1)[0].decode("ascii", "replace")
    fmt = bytes(data[pos + 9:pos + 25]).split(b"\0", 1)[0].decode("ascii", "replace")
    cols = bytes(data[pos + 25:pos + 89]).split(b"\0", 1)[0].decode("ascii", "replace")
    return DFFormat(t, ln, name, fmt, cols.split(",") if cols else [])


def _same_layout(a: DFFormat, b: DFFormat):
    return (a.length, a.name, a.format, a.columns) == (b.length, b.name, b.format, b.columns)


def scan(data, path="<bytes>"):
    """Walk a DataFlash log held in ``data`` (bytes); return a :class:`DFScan`."""
    n = len(data)
    lens = {FMT_TYPE: FMT_LEN}
    formats = {FMT_TYPE: DFFormat(FMT_TYPE, FMT_LEN, "FMT", "BBnNZ",
                                  ["Type", "Length", "Name", "Format", "Columns"])}
    current = {FMT_TYPE: FMT_TYPE}         # type id -> format key now in force
    generation = {}                        # type id -> redefinitions so far
    offsets = {}
    bad = []
    pos = 0
    count = 0
    truncated = 0
    redefinitions = 0
    bad_start = None
    find = data.find
    while pos + 3 <= n:
        if data[pos] == HEAD1 and data[pos + 1] == HEAD2:
            t = data[pos + 2]
            ln = lens.get(t)
            if ln is not None:
                end = pos + ln
                if end > n:
                    truncated = n - pos
                    break
                if bad_start is not None:
                    bad.append((bad_start, pos))
                    bad_start = None
                if t == FMT_TYPE:
                    f = _parse_fmt(data, pos)
                    if f.length >= 3 and f.type != FMT_TYPE:
                        key = current.get(f.type)
                        if key is None:
                            key = f.type
                        elif not _same_layout(formats[key], f):
                            generation[f.type] = generation.get(f.type, 0) + 1
                            key = f.type + 256 * generation[f.type]
                            redefinitions += 1
                        current[f.type] = key
                        lens[f.type] = f.length
                        formats[key] = f
                key = current[t]
                lst = offsets.get(key)
                if lst is None:
                    lst = offsets[key] = []
                lst.append(pos)
                count += 1
                pos = end
                continue
        # not the start of a known message: skip to the next header candidate
        if bad_start is None:
            bad_start = pos
        nxt = find(b"\xa3\x95", pos + 1)
        pos = n if nxt < 0 else nxt
    else:
        if pos < n and bad_start is None:   # 1-2 stray bytes at the very end
            truncated = n - pos
    if bad_start is not None:
        bad.append((bad_start, min(pos, n)))
    return DFScan(path, n, formats, offsets, count, bad, truncated, redefinitions)


def decode(data, sc: DFScan, type_id):
    """All messages of ``type_id`` as a numpy structured array (header included)."""
    f = sc.formats[type_id]
    offs = np.asarray(sc.offsets.get(type_id, []), dtype=np.int64)
    buf = np.frombuffer(data, dtype=np.uint8)
    rows = buf[offs[:, None] + np.arange(f.length)]
    return rows.view(f.dtype()).reshape(-1)


def _gyro_format_problem(f: DFFormat):
    """Why format ``f`` (named like an IMU) cannot be read as a gyro stream, or None."""
    missing = [g for g in GYRO_FIELDS if g not in f.columns]
    if missing:
        return f"no {'/'.join(missing)} field"
    if not ("TimeUS" in f.columns or "TimeMS" in f.columns):
        return "no TimeUS/TimeMS field"
    try:
        f.dtype()
    except ValueError as exc:
        return str(exc)
    chars = dict(zip(f.columns, f.format))
    bad = [g for g in GYRO_FIELDS if chars.get(g) != "f"]
    if bad:
        return f"{'/'.join(bad)} not float ('f') in format {f.format!r}"
    return None


def gyro_streams(data, sc: DFScan):
    """The gyro streams of a scanned log, in file order of first appearance. A
    type redefined mid-log is read with the layout in force at each message; the
    messages of one name (and instance) form one stream whatever their format key.
    A format named like an IMU that cannot be read is skipped, the reason in
    ``sc.skipped``."""
    pieces = {}                            # stream name -> [(offsets, time, raw, format name, time column)]
    for key in sorted(sc.offsets, key=lambda k: sc.offsets[k][0]):
        f = sc.formats.get(key)
        if f is None or not IMU_TYPE_RE.match(f.name):
            continue
        why = _gyro_format_problem(f)
        if why is not None:
            sc.skipped.append(f"{f.name} (type {f.type}): {len(sc.offsets[key])} messages not read "
                              f"as gyro: {why}")
            continue
        tcol, tscale = ("TimeUS", 1e-6) if "TimeUS" in f.columns else ("TimeMS", 1e-3)
        rec = decode(data, sc, key)
        offs = np.asarray(sc.offsets[key], dtype=np.int64)
        raw = np.stack([rec[g].astype(np.float64) for g in GYRO_FIELDS], axis=1)
        tt = rec[tcol].astype(np.float64) * tscale
        if "I" in f.columns:
            inst = rec["I"].astype(np.int64)
            groups = [(f"{f.name}[{i}]", inst == i) for i in np.unique(inst)]
        else:
            groups = [(f.name, np.ones(len(rec), dtype=bool))]
        for name, sel in groups:
            pieces.setdefault(name, []).append((offs[sel], tt[sel], raw[sel], f.name, tcol))
    streams = []
    for name, parts in sorted(pieces.items(), key=lambda kv: min(p[0][0] for p in kv[1])):
        offs = np.concatenate([p[0] for p in parts])
        order = np.argsort(offs, kind="stable")
        tcols = sorted({p[4] for p in parts})
        streams.append(GyroStream(
            name=name, message=parts[0][3], unit="rad/s", to_deg_s=UNIT_TO_DEG_S["rad/s"],
            time_s=np.concatenate([p[1] for p in parts])[order],
            raw=np.concatenate([p[2] for p in parts])[order], index=offs[order],
            note=f"DataFlash {parts[0][3]}.GyrX/GyrY/GyrZ (float, rad/s), time {'/'.join(tcols)}"
                 + (f"; {len(parts)} layouts (FMT redefined mid-log)" if len(parts) > 1 else "")))
    streams += batch_sampler_streams(data, sc)
    return streams


def _type_id(sc, name):
    for t, f in sc.formats.items():
        if f.name == name and t in sc.offsets:
            return t
    return None


def batch_sampler_streams(data, sc: DFScan):
    """Gyro streams of the batch sampler (ISBH/ISBD), one per IMU instance."""
    th, td = _type_id(sc, "ISBH"), _type_id(sc, "ISBD")
    if th is None or td is None:
        return []
    fh, fd = sc.formats[th], sc.formats[td]
    need_h = {"N", "type", "instance", "mul", "SampleUS", "smp_rate"}
    need_d = {"N", "seqno", "x", "y", "z"}
    if not need_h <= set(fh.columns) or not need_d <= set(fd.columns):
        return []
    chars = dict(zip(fd.columns, fd.format))
    why = None
    try:
        fh.dtype(), fd.dtype()
    except ValueError as exc:
        why = str(exc)
    if why is None and any(chars.get(a) != "a" for a in ("x", "y", "z")):
        why = f"x/y/z not int16[32] ('a') in format {fd.format!r}"
    if why is not None:
        sc.skipped.append(f"ISBH/ISBD: batch sampler not read as gyro: {why}")
        return []
    h = decode(data, sc, th)
    d = decode(data, sc, td)
    d_offs = np.asarray(sc.offsets[td], dtype=np.int64)
    per_inst = {}
    for hi in np.nonzero(h["type"] == 1)[0]:
        hdr = h[hi]
        sel = np.nonzero(d["N"] == hdr["N"])[0]
        if not len(sel) or hdr["mul"] == 0 or not hdr["smp_rate"] > 0:
            continue
        sel = sel[np.argsort(d["seqno"][sel], kind="stable")]
        n = 32 * len(sel)
        cnt = int(hdr["smp_cnt"]) if "smp_cnt" in fh.columns else n
        n = min(n, cnt)
        vals = np.stack([d[a][sel].reshape(-1)[:n] for a in ("x", "y", "z")], axis=1).astype(np.float64)
        k = np.arange(n)
        t = hdr["SampleUS"] * 1e-6 + k / float(hdr["smp_rate"])
        # sample index -> (ISBD message offset) * 32 + position in its arrays
        idx = d_offs[sel][k // 32] * 32 + (k % 32)
        mul = np.full(n, float(hdr["mul"]))
        per_inst.setdefault(int(hdr["instance"]), []).append((t, vals / mul[:, None], idx, mul))
    out = []
    for inst, bursts in sorted(per_inst.items()):
        t = np.concatenate([b[0] for b in bursts])
        raw = np.concatenate([b[1] for b in bursts])
        idx = np.concatenate([b[2] for b in bursts])
        mul = np.concatenate([b[3] for b in bursts])
        s = GyroStream(name=f"ISB.gyro[{inst}]", message="ISBD", unit="rad/s",
                       to_deg_s=UNIT_TO_DEG_S["rad/s"], time_s=t, raw=raw, index=idx,
                       note=f"DataFlash batch sampler ISBH/ISBD, gyro instance {inst}: "
                            f"{len(bursts)} bursts, int16 / mul = rad/s, time SampleUS + k/smp_rate")
        s.field_dtype, s.field_scale = "<i2", mul
        out.append(s)
    return out


def _gyro_positions(sc: DFScan, s):
    """Per sample of stream ``s`` (message offsets ``s.index``): the byte offsets
    of its GyrX/GyrY/GyrZ, (n, 3), from the layout each message was written with."""
    at = np.full((s.n, 3), -1, dtype=np.int64)
    for key, f in sc.formats.items():
        if f.name != s.message or key not in sc.offsets or _gyro_format_problem(f) is not None:
            continue
        sel = np.isin(s.index, np.asarray(sc.offsets[key], dtype=np.int64))
        dt = f.dtype()
        at[sel] = s.index[sel, None] + np.array([dt.fields[g][1] for g in GYRO_FIELDS])
    if (at < 0).any():
        raise ValueError(f"{s.name}: {int((at[:, 0] < 0).sum())} samples not at a {s.message} message")
    return at


def patch(data, sc: DFScan, streams):
    """A copy of ``data`` (bytearray) with each stream's filtered values (field
    unit, float32) written over its gyro fields."""
    out = bytearray(data)
    buf = np.frombuffer(out, dtype=np.uint8)
    for s in streams:
        if s.filtered is None or s.n == 0:
            continue
        if s.message == "ISBD":
            dt = next(f for f in sc.formats.values() if f.name == "ISBD").dtype()
            off = s.index // 32
            pos = s.index % 32
            require_fit(s.name, s.filtered, "<i2", s.field_scale)
            counts = np.rint(s.filtered * s.field_scale[:, None]).astype("<i2")
            for k, a in enumerate(("x", "y", "z")):
                at = off + dt.fields[a][1] + 2 * pos
                buf[at[:, None] + np.arange(2)] = counts[:, k].copy().view(np.uint8).reshape(-1, 2)
            continue
        at = _gyro_positions(sc, s)
        require_fit(s.name, s.filtered, "<f4")
        vals = np.ascontiguousarray(s.filtered, dtype="<f4")      # (n, 3)
        for k in range(3):
            b = vals[:, k].copy().view(np.uint8).reshape(-1, 4)
            buf[at[:, k][:, None] + np.arange(4)] = b
    return out


def read(path):
    """Read a DataFlash file: (bytes, DFScan, streams). InputError if unreadable."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if len(data) < 3 or data[0] != HEAD1 or data[1] != HEAD2:
        raise InputError(f"{path}: not a DataFlash binary log (does not start with A3 95)")
    sc = scan(data, str(path))
    try:
        streams = gyro_streams(data, sc)
    except ValueError as exc:
        raise InputError(f"{path}: bad FMT message: {exc}") from None
    return data, sc, streams
