"""PX4 ULog (``.ulg``): gyro streams and a filtered copy patched in place.

Gyro topics: ``sensor_combined`` (``gyro_rad[0..2]``, rad/s) and ``sensor_gyro``
(``x``, ``y``, ``z``, rad/s; one stream per multi-instance), time ``timestamp``
(us since boot); and PX4's high-rate FIFO ``sensor_gyro_fifo``: each message holds
``samples`` (up to 32) readings per axis in int16 arrays ``x``, ``y``, ``z``,
rad/s = value * ``scale``, ``dt`` us apart; the last one at ``timestamp_sample``
(the FIFO's read time), so sample k of N is at ``timestamp_sample - (N-1-k) dt``.
``sensor_accel_fifo`` (the same layout, m/s^2) is read by :func:`accel_streams`. The gyro values are read from the file's data messages by
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

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrodenoise.errors import InputError

from gyrodenoise.flightlog import ulog_messages
from gyrodenoise.flightlog.streams import UNIT_TO_DEG_S, AccelStream, GyroStream, require_fit

TOPICS = {
    "sensor_combined": ("gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"),
    "sensor_gyro": ("x", "y", "z"),
    "sensor_gyro_fifo": ("x", "y", "z"),
}
#: body-rate topics that are not read as gyro streams, and why (said in the report's
#: ``streams_skipped``: a rate topic is never dropped without a word)
NOT_GYRO_STREAMS = {
    "vehicle_angular_velocity": "the controller's body rate, the gyro after PX4's own filters and "
                                "bias correction (its source, sensor_gyro, is read where logged); used "
                                "by the step response as the measured rate",
}
#: FIFO topics: int16 arrays of FIFO_LEN samples per axis
FIFO_TOPICS = ("sensor_gyro_fifo", "sensor_accel_fifo")
FIFO_LEN = 32
_FIFO_FIELDS = ("timestamp_sample", "dt", "scale", "samples")


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
        sc.dtype(topic)                  # e.g. two fields of one name
    except ValueError as exc:
        return str(exc)
    if topic in FIFO_TOPICS:
        need = [*_FIFO_FIELDS] + [f"{c}[{k}]" for c in cols for k in (0, FIFO_LEN - 1)]
        missing = [c for c in need if c not in lay]
        if missing:
            return f"no field {', '.join(missing)}"
        bad = [c for c in cols if lay[f"{c}[0]"][1] != np.dtype("<i2")
               or lay.get(f"{c}[{FIFO_LEN}]") is not None]
        if bad:
            return f"{', '.join(bad)} not int16[{FIFO_LEN}]"
        if lay["timestamp_sample"][1].kind not in "iu":
            return "timestamp_sample is not an integer"
        return None
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
        if topic in NOT_GYRO_STREAMS:
            refs.skipped.append(f"{topic}[{multi_id}]: {len(sc.data[(topic, multi_id)])} messages not read as "
                                f"gyro: {NOT_GYRO_STREAMS[topic]}")
            continue
        if cols is None:
            continue
        why = _topic_problem(sc, topic, cols)
        if why is not None:
            refs.skipped.append(f"{topic}[{multi_id}]: {len(sc.data[(topic, multi_id)])} messages not read "
                                f"as gyro: {why}")
            continue
        rec, offs = sc.decode(data, topic, multi_id)
        n_msgs = len(sc.data[(topic, multi_id)])
        if len(rec) < n_msgs:
            refs.skipped.append(f"{topic}[{multi_id}]: {n_msgs - len(rec)} of {n_msgs} messages not of the "
                                f"format's size ({sc.logged_size(topic)} bytes), left out")
        if not len(rec):
            continue
        n_inst = sum(1 for k in sc.data if k[0] == topic)
        name = topic + (f"[{multi_id}]" if n_inst > 1 or multi_id else "")
        lay, _ = sc.layout(topic)
        if topic in FIFO_TOPICS:
            fifo = _fifo_samples(rec, offs, cols)
            if fifo.dropped:
                refs.skipped.append(f"{name}: {fifo.dropped} messages with no valid dt/scale/samples left out")
            s = GyroStream(name=name, message=topic, unit="rad/s", to_deg_s=UNIT_TO_DEG_S["rad/s"],
                           time_s=fifo.time_s, raw=fifo.values, index=fifo.index,
                           note=f"ULog {topic}: int16 x/y/z[{FIFO_LEN}] * scale (rad/s), `samples` per "
                                f"message dt us apart, the last at timestamp_sample",
                           field_dtype="<i2", field_scale=1.0 / fifo.scale)
        else:
            s = GyroStream(name=name, message=topic, unit="rad/s", to_deg_s=UNIT_TO_DEG_S["rad/s"],
                           time_s=rec["timestamp"].astype(np.float64) * 1e-6,
                           raw=np.stack([rec[c].astype(np.float64) for c in cols], axis=1), index=offs,
                           note=f"ULog {topic}.{'/'.join(cols)} (rad/s), time timestamp",
                           field_dtype=lay[cols[0]][1].str)
        streams.append(s)
        d = next((e for e in u.data_list if e.name == topic and e.multi_id == multi_id), None)
        refs.append((d, cols))
    return u, streams, refs


@dataclass
class _Fifo:
    time_s: np.ndarray
    values: np.ndarray          # (n, 3), field value * scale
    index: np.ndarray           # D message offset * FIFO_LEN + position in its arrays
    scale: np.ndarray           # per sample
    dropped: int                # messages without a usable dt, scale or samples


def _fifo_samples(rec, offs, cols):
    """The samples of a FIFO topic's records, in file order."""
    n = rec["samples"].astype(np.int64)
    dt = rec["dt"].astype(np.float64)
    scale = rec["scale"].astype(np.float64)
    ok = (n > 0) & (n <= FIFO_LEN) & np.isfinite(dt) & (dt > 0) & np.isfinite(scale) & (scale > 0)
    k = np.arange(FIFO_LEN)
    mask = ok[:, None] & (k[None, :] < n[:, None])
    t = rec["timestamp_sample"].astype(np.float64)[:, None] - (n[:, None] - 1 - k[None, :]) * dt[:, None]
    vals = np.stack([np.stack([rec[f"{c}[{i}]"] for i in k], axis=1).astype(np.float64) for c in cols], axis=2)
    sc = np.broadcast_to(scale[:, None], mask.shape)
    return _Fifo(time_s=t[mask] * 1e-6, values=vals[mask] * sc[mask][:, None],
                 index=(offs[:, None] * FIFO_LEN + k[None, :])[mask], scale=sc[mask],
                 dropped=int((~ok & (n != 0)).sum()))


def accel_streams(refs):
    """The accelerometer FIFO streams (``sensor_accel_fifo``) of a log read by
    :func:`read` (its ``refs``)."""
    sc, data = refs.scan, refs.data
    out = []
    keys = sorted(k for k in sc.data if k[0] == "sensor_accel_fifo")
    for topic, multi_id in keys:
        if _topic_problem(sc, topic, ("x", "y", "z")) is not None:
            continue
        rec, offs = sc.decode(data, topic, multi_id)
        fifo = _fifo_samples(rec, offs, ("x", "y", "z"))
        if not len(fifo.time_s):
            continue
        dt = rec["dt"].astype(np.float64)
        dt = dt[np.isfinite(dt) & (dt > 0)]
        out.append(AccelStream(name=topic + (f"[{multi_id}]" if len(keys) > 1 or multi_id else ""),
                               message=topic, time_s=fifo.time_s, values=fifo.values,
                               rate_hz=float(1e6 / np.median(dt)) if len(dt) else None,
                               note=f"ULog {topic}: int16 x/y/z[{FIFO_LEN}] * scale (m/s^2)"))
    return out


def truncated_bytes(path):
    """Bytes of a message cut by the end of the file (0: the file ends on a message
    boundary; pyulog itself stops silently at a cut message), from the walk of
    :func:`gyrodenoise.flightlog.ulog_messages.scan`. -1 when the file has no
    ULog header."""
    with open(path, "rb") as fh:
        data = fh.read()
    try:
        return ulog_messages.scan(data).truncated_bytes
    except ValueError:
        return -1


def patched(streams, refs):
    """The file's bytes (bytearray) with each stream's filtered values written over
    its gyro fields (in the fields' own type); every other byte unchanged."""
    out = bytearray(refs.data)
    buf = np.frombuffer(out, dtype=np.uint8)
    for s, (_, cols) in zip(streams, refs):
        if s.filtered is None or s.n == 0:
            continue
        lay, _ = refs.scan.layout(s.message)
        if s.message in FIFO_TOPICS:
            require_fit(s.name, s.filtered, "<i2", np.asarray(s.field_scale))
            counts = np.rint(s.filtered * np.asarray(s.field_scale)[:, None])
            msg, pos = s.index // FIFO_LEN, s.index % FIFO_LEN
            for k, c in enumerate(cols):
                off, dt = lay[f"{c}[0]"]
                ulog_messages.write_fields(buf, msg, off + dt.itemsize * pos, counts[:, k], dt)
            continue
        for k, c in enumerate(cols):
            off, dt = lay[c]
            require_fit(s.name, s.filtered[:, k], dt)
            ulog_messages.write_fields(buf, s.index, off, s.filtered[:, k], dt)
    return out


def write_filtered(u, streams, refs, path):
    """Write the filtered copy of the log (:func:`patched`) to ``path``."""
    Path(path).write_bytes(patched(streams, refs))
