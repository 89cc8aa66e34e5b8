"""The message stream of a PX4 ULog file, byte by byte: where each data message
of each topic lies, and the byte layout of its fields.

A ULog file is a 16-byte header (``ULog`` magic, version, start time) followed by
messages ``<uint16 size><uint8 type><payload of size bytes>``. Formats (``F``:
``name:type field;type field;...``, fields possibly arrays ``float[3]`` or other
formats) define the layouts; subscriptions (``A``: multi id, uint16 msg id, topic
name) bind a msg id to a topic; data messages (``D``: uint16 msg id, then the
topic's fields packed, padding fields included) carry the samples. :func:`scan`
walks the messages once and keeps the offset of every data message per (topic,
multi id); a message of an unknown type is a corruption: the walk resumes after
the next sync sequence (as pyulog does) and the skipped bytes are counted. The
filtered copy of a log changes the gyro fields of the data messages in place
(:func:`decode`/:func:`write_fields`), every other byte as it was.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

HEADER_MAGIC = b"ULog\x01\x12\x35"
HEADER_LEN = 16
SYNC_BYTES = b"\x2F\x73\x13\x20\x25\x0C\xBB\x12"
MAX_MESSAGE = 0xFFFF            # bytes of a message's payload at most (uint16 size)
#: message types the walk knows (others are a corruption)
KNOWN_TYPES = frozenset(b"FDIMPQARLCSOB")

BASE_TYPES = {
    "int8_t": "i1", "uint8_t": "u1", "int16_t": "<i2", "uint16_t": "<u2", "int32_t": "<i4",
    "uint32_t": "<u4", "int64_t": "<i8", "uint64_t": "<u8", "float": "<f4", "double": "<f8",
    "bool": "u1", "char": "S1",
}


@dataclass
class ULogFormat:
    name: str
    fields: list                     # (type name, array length or None, field name)


@dataclass
class ULogScan:
    """The messages of a ULog file (offsets are of the message header)."""
    size: int
    formats: dict                    # format name -> ULogFormat
    data: dict                       # (topic, multi id) -> list of D message offsets
    n_messages: int = 0
    bad_regions: list = field(default_factory=list)     # (start, end) of skipped bytes
    truncated_bytes: int = 0         # bytes of a message cut by the end of the file
    _layouts: dict = field(default_factory=dict)

    @property
    def bad_bytes(self):
        return sum(e - s for s, e in self.bad_regions)

    def layout(self, name):
        """{flat field name: (offset in the topic's payload, numpy dtype)} and the
        payload size of format ``name``; flat names as pyulog's (``gyro_rad[0]``,
        ``x[31]``, ``nested.field``). ValueError for an unknown type or a cycle."""
        if name not in self._layouts:
            out = {}
            size = self._flatten(name, "", 0, out, ())
            self._layouts[name] = (out, size)
        return self._layouts[name]

    def _flatten(self, name, prefix, base, out, seen):
        if name in seen or len(seen) > 16:
            raise ValueError(f"format {name!r} nests itself")
        fmt = self.formats.get(name)
        if fmt is None:
            raise ValueError(f"no format {name!r}")
        off = base
        for tname, alen, fname in fmt.fields:
            count = alen or 1
            for i in range(count):
                label = prefix + (f"{fname}[{i}]" if alen else fname)
                if tname in BASE_TYPES:
                    dt = np.dtype(BASE_TYPES[tname])
                    if label in out:
                        raise ValueError(f"format {name!r} has two fields named {label!r}")
                    if not fname.startswith("_padding"):
                        out[label] = (off, dt)
                    off += dt.itemsize
                else:
                    off = self._flatten(tname, label + ".", off, out, seen + (name,))
                if off - base > MAX_MESSAGE:
                    raise ValueError(f"format {name!r} is longer than a message can be")
        return off

    def dtype(self, name):
        """numpy structured dtype of the payload of topic format ``name`` (after the msg id)."""
        lay, size = self.layout(name)
        names = list(lay)
        return np.dtype({"names": names, "formats": [lay[k][1] for k in names],
                         "offsets": [lay[k][0] for k in names], "itemsize": self.logged_size(name)})

    def logged_size(self, name):
        """Bytes of a data message's fields for format ``name``: up to the end of its
        last field that is not padding (a logger leaves trailing padding out)."""
        lay, _ = self.layout(name)
        return max((off + dt.itemsize for off, dt in lay.values()), default=0)

    def decode(self, data, topic, multi_id=0):
        """(records as a structured array, D message offsets) of a topic instance;
        a message whose size is not the topic's :meth:`logged_size` is left out
        (pyulog skips it too, as corrupt)."""
        offs = np.asarray(self.data.get((topic, multi_id), []), dtype=np.int64)
        dt = self.dtype(topic)
        buf = np.frombuffer(data, dtype=np.uint8)
        if len(offs):
            sizes = buf[offs].astype(np.int64) | (buf[offs + 1].astype(np.int64) << 8)
            offs = offs[sizes - 2 == self.logged_size(topic)]
        rows = buf[(offs + 5)[:, None] + np.arange(dt.itemsize)] if len(offs) else np.zeros((0, dt.itemsize), np.uint8)
        return np.ascontiguousarray(rows).view(dt).reshape(-1), offs


def _parse_format(payload):
    text = payload.split(b"\0", 1)[0].decode("ascii", "replace")
    name, _, body = text.partition(":")
    fields = []
    for part in body.split(";"):
        part = part.strip()
        if not part:
            continue
        tname, _, fname = part.partition(" ")
        alen = None
        if tname.endswith("]") and "[" in tname:
            tname, _, n = tname[:-1].partition("[")
            alen = int(n) if n.isdigit() else None
            if alen is None or not 0 < alen <= MAX_MESSAGE:
                raise ValueError(f"bad array length in {part!r}")
        fields.append((tname, alen, fname))
    return ULogFormat(name, fields)


def scan(data):
    """Walk the messages of a ULog file held in ``data``; a :class:`ULogScan`
    (ValueError when the header is not a ULog header)."""
    n = len(data)
    if n < HEADER_LEN or data[:7] != HEADER_MAGIC:
        raise ValueError("not a ULog file (no ULog header)")
    formats, subs, where = {}, {}, {}
    bad = []
    pos, count, truncated = HEADER_LEN, 0, 0
    while pos + 3 <= n:
        size = data[pos] | (data[pos + 1] << 8)
        mtype = data[pos + 2]
        end = pos + 3 + size
        if mtype not in KNOWN_TYPES:
            nxt = data.find(SYNC_BYTES, pos + 1)
            resume = n if nxt < 0 else nxt + len(SYNC_BYTES)
            bad.append((pos, resume))
            pos = resume
            continue
        if end > n:
            truncated = n - pos
            break
        payload = data[pos + 3:end]
        if mtype == 0x46:                                   # F
            try:
                f = _parse_format(bytes(payload))
                formats[f.name] = f
            except ValueError:
                pass
        elif mtype == 0x41 and size >= 3:                   # A
            multi_id = payload[0]
            msg_id = payload[1] | (payload[2] << 8)
            topic = bytes(payload[3:]).split(b"\0", 1)[0].decode("ascii", "replace")
            subs[msg_id] = (topic, multi_id)
        elif mtype == 0x44 and size >= 2:                   # D
            key = subs.get(payload[0] | (payload[1] << 8))
            if key is not None:
                lst = where.get(key)
                if lst is None:
                    lst = where[key] = []
                lst.append(pos)
        count += 1
        pos = end
    if 0 < n - pos < 3:
        truncated = n - pos
    return ULogScan(n, formats, where, count, bad, truncated)


def write_fields(buf, offs, field_offset, values, dtype):
    """Write ``values`` (one per D message at ``offs``) as ``dtype`` at
    ``field_offset`` (one for all, or one per value) of each message's payload into
    ``buf`` (a writable uint8 array)."""
    dt = np.dtype(dtype)
    b = np.ascontiguousarray(np.asarray(values).astype(dt)).view(np.uint8).reshape(-1, dt.itemsize)
    buf[(np.asarray(offs, dtype=np.int64) + 5 + field_offset)[:, None] + np.arange(dt.itemsize)] = b
