"""PX4 ULog (``.ulg``) through pyulog: gyro streams and a filtered copy.

Gyro topics: ``sensor_combined`` (``gyro_rad[0..2]``, rad/s) and
``sensor_gyro`` (``x``, ``y``, ``z``, rad/s; one stream per multi-instance).
Time: ``timestamp`` (us since boot). The filtered copy is written by pyulog's
``write_ulog`` with the gyro columns replaced (float32).
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.errors import InputError

from gyrodenoise.flightlog.streams import UNIT_TO_DEG_S, GyroStream

TOPICS = {
    "sensor_combined": ("gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"),
    "sensor_gyro": ("x", "y", "z"),
}


def read(path):
    """(ULog object, streams, refs); refs[i] is (dataset, field names) of streams[i]."""
    try:
        import pyulog
    except ImportError:  # pragma: no cover
        raise InputError(f"{path}: reading ULog needs pyulog (pip install pyulog)") from None
    try:
        u = pyulog.ULog(str(path))
    except Exception as exc:  # noqa: BLE001 - pyulog raises many kinds
        raise InputError(f"{path}: not a readable ULog ({type(exc).__name__}: {exc})") from None
    streams, refs = [], []
    for d in u.data_list:
        cols = TOPICS.get(d.name)
        if cols is None or not all(c in d.data for c in cols) or "timestamp" not in d.data:
            continue
        n_inst = sum(1 for e in u.data_list if e.name == d.name)
        name = d.name + (f"[{d.multi_id}]" if n_inst > 1 or d.multi_id else "")
        raw = np.stack([np.asarray(d.data[c], dtype=np.float64) for c in cols], axis=1)
        t = np.asarray(d.data["timestamp"], dtype=np.float64) * 1e-6
        streams.append(GyroStream(name=name, message=d.name, unit="rad/s",
                                  to_deg_s=UNIT_TO_DEG_S["rad/s"], time_s=t, raw=raw,
                                  index=np.arange(len(t)),
                                  note=f"ULog {d.name}.{'/'.join(cols)} (rad/s), time timestamp",
                                  field_dtype=np.asarray(d.data[cols[0]]).dtype.str))
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


def write_filtered(u, streams, refs, path):
    for s, (d, cols) in zip(streams, refs):
        if s.filtered is None:
            continue
        for k, c in enumerate(cols):
            d.data[c] = s.filtered[:, k].astype(d.data[c].dtype)
    u.write_ulog(str(path))
