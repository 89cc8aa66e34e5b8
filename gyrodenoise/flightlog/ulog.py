"""PX4 ULog (``.ulg``): gyro streams and a filtered copy patched in place.

Gyro topics: ``sensor_combined`` (``gyro_rad[0..2]``, rad/s) and ``sensor_gyro``
(``x``, ``y``, ``z``, rad/s; one stream per multi-instance). Time: ``timestamp``
(us since boot). The gyro values are read from the file's data messages by
:mod:`gyrodenoise.flightlog.ulog_messages` (each sample knows the offset of its
message); pyulog parses the rest of the log (topics, parameters, messages) for
the review. The filtered copy is the file's bytes with the filtered values
written over the gyro fields of those messages: every other byte (sync,
subscription, parameter and logging messages, padding, a corrupt region, the
order of the messages) is as it was.

A gyro topic that cannot be read (no ``timestamp``, no gyro field, an integer gyro
field, a format that does not parse) is skipped, the reason in ``refs.skipped``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gyrodenoise.errors import InputError

from gyrodenoise.flightlog import ulog_messages
from gyrodenoise.flightlog.streams import UNIT_TO_DEG_S, GyroStream

TOPICS = {
    "sensor_combined": ("gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"),
    "sensor_gyro": ("x", "y", "z"),
}


class ULogRefs(list):
    """``refs[i]``: (pyulog dataset or None, field names) of ``streams[i]``; with the
    file's bytes (``data``), its message scan (``scan``) and the gyro topics
    skipped, each with the reason (``skipped``)."""

    def __init__(self, data, scan):
        super().__init__()
        self.data = data
        self.scan = scan
        self.skipped = []


def _topic_problem(sc, topic, cols):
    """Why ``topic`` cannot be read as a gyro stream (None: it can)."""
    try:
        lay, _ = sc.layout(topic)
    except ValueError as exc:
        return str(exc)
    missing = [c for c in ("timestamp", *cols) if c not in lay]
    if missing:
        return f"no field {', '.join(missing)}"
    if lay["timestamp"][1].kind not in "iu":
        return "timestamp is not an integer"
    bad = [c for c in cols if lay[c][1].kind != "f"]
    if bad:
        return f"{', '.join(bad)} not a float field"
    return None


def read(path):
    """(ULog object, streams, refs): refs is a :class:`ULogRefs` (``refs[i]`` is
    (dataset, field names) of ``streams[i]``). InputError if unreadable."""
    try:
        import pyulog
    except ImportError:  # pragma: no cover
        raise InputError(f"{path}: reading ULog needs pyulog (pip install pyulog)") from None
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    try:
        sc = ulog_messages.scan(data)
        u = pyulog.ULog(str(path))
    except Exception as exc:  # noqa: BLE001 - pyulog raises many kinds
        raise InputError(f"{path}: not a readable ULog ({type(exc).__name__}: {exc})") from None
    streams, refs = [], ULogRefs(data, sc)
    for topic, multi_id in sorted(sc.data):
        cols = TOPICS.get(topic)
        if cols is None:
            continue
        why = _topic_problem(sc, topic, cols)
        if why is not None:
            refs.skipped.append(f"{topic}[{multi_id}]: {len(sc.data[(topic, multi_id)])} messages not read "
                                f"as gyro: {why}")
            continue
        rec, offs = sc.decode(data, topic, multi_id)
        if not len(rec):
            continue
        n_inst = sum(1 for k in sc.data if k[0] == topic)
        lay, _ = sc.layout(topic)
        raw = np.stack([rec[c].astype(np.float64) for c in cols], axis=1)
        t = rec["timestamp"].astype(np.float64) * 1e-6
        streams.append(GyroStream(name=topic + (f"[{multi_id}]" if n_inst > 1 or multi_id else ""),
                                  message=topic, unit="rad/s", to_deg_s=UNIT_TO_DEG_S["rad/s"],
                                  time_s=t, raw=raw, index=offs,
                                  note=f"ULog {topic}.{'/'.join(cols)} (rad/s), time timestamp",
                                  field_dtype=lay[cols[0]][1].str))
        d = next((e for e in u.data_list if e.name == topic and e.multi_id == multi_id), None)
        refs.append((d, cols))
    return u, streams, refs


def truncated_bytes(path):
    """Bytes of a message cut by the end of the file (0: the file ends on a message
    boundary). Walks the message headers (uint16 size, uint8 type) after the
    16-byte file header, as pyulog does; pyulog itself stops silently at a cut
    message. -1 when the file is too short for a header."""
    with open(path, "rb") as fh:
        data = fh.read()
    n = len(data)
    if n < 16:
        return -1
    pos = 16
    while pos + 3 <= n:
        nxt = pos + 3 + (data[pos] | (data[pos + 1] << 8))
        if nxt > n:
            return n - pos
        pos = nxt
    return n - pos


def patched(streams, refs):
    """The file's bytes (bytearray) with each stream's filtered values written over
    its gyro fields (in the fields' own type); every other byte unchanged."""
    out = bytearray(refs.data)
    buf = np.frombuffer(out, dtype=np.uint8)
    for s, (_, cols) in zip(streams, refs):
        if s.filtered is None or s.n == 0:
            continue
        lay, _ = refs.scan.layout(s.message)
        for k, c in enumerate(cols):
            off, dt = lay[c]
            ulog_messages.write_fields(buf, s.index, off, s.filtered[:, k], dt)
    return out


def write_filtered(u, streams, refs, path):
    """Write the filtered copy of the log (:func:`patched`) to ``path``."""
    Path(path).write_bytes(patched(streams, refs))
