"""The log formats the bridge reads and writes: which format a file is, its gyro
streams and facts, and the filtered copy.

Three formats, each with its own module: telemetry logs (:mod:`gyrodenoise.flightlog.tlog`),
ArduPilot DataFlash (:mod:`gyrodenoise.flightlog.dataflash`) and PX4 ULog
(:mod:`gyrodenoise.flightlog.ulog`). :func:`read_log` and :func:`write_filtered_log`
dispatch to them; what a reader returns beside the streams (the raw bytes, the
framing, the parsed ULog) travels as an opaque ``source`` dict from one to the other.
"""

from __future__ import annotations

from pathlib import Path

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog import dataflash, tlog, ulog

LOG_SUFFIXES = {".tlog": "tlog", ".mavlink": "tlog", ".bin": "dataflash", ".ulg": "ulog"}
GYRO_LOOKED_FOR = {
    "tlog": "RAW_IMU, SCALED_IMU, SCALED_IMU2, SCALED_IMU3, HIGHRES_IMU",
    "dataflash": "IMU, IMU2, IMU3 with GyrX/GyrY/GyrZ, ISBH/ISBD gyro bursts",
    "ulog": "sensor_combined.gyro_rad, sensor_gyro, sensor_gyro_fifo",
}


def log_kind(path):
    """'tlog', 'dataflash' or 'ulog' from the suffix, else from the first bytes."""
    p = Path(path)
    kind = LOG_SUFFIXES.get(p.suffix.lower())
    if kind:
        return kind
    try:
        with open(p, "rb") as fh:
            head = fh.read(600)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if head[:2] == b"\xa3\x95":
        return "dataflash"
    if head[:7] == b"ULog\x01\x12\x35":
        return "ulog"
    if tlog.looks_like_tlog(head):
        return "tlog"
    raise InputError(f"{path}: unknown file type (expected a MAVLink telemetry log .tlog, "
                     f"an ArduPilot DataFlash log .bin or a PX4 log .ulg)")


def read_log(path, kind, raw_imu_unit="auto", raw_imu_scale=None):
    """(gyro streams, source, facts) of the log at ``path`` of format ``kind``
    (:func:`log_kind`). ``source``: what :func:`write_filtered_log` needs to write
    the filtered copy; ``facts``: the report's fields on the file itself (messages,
    unreadable records and bytes, truncation). InputError when it has no gyro stream."""
    if kind == "dataflash":
        streams, source, facts = _read_dataflash(path)
    elif kind == "tlog":
        streams, source, facts = _read_tlog(path, raw_imu_unit, raw_imu_scale)
    else:
        streams, source, facts = _read_ulog(path)
    if not streams:
        raise InputError(f"{path}: no gyro stream (looked for {GYRO_LOOKED_FOR[kind]})")
    return streams, source, facts


def _read_dataflash(path):
    data, sc, streams = dataflash.read(path)
    facts = dict(messages=sc.n_messages, unreadable_records=len(sc.bad_regions),
                 unreadable_bytes=sc.bad_bytes, truncated=sc.truncated_bytes > 0,
                 truncated_bytes=sc.truncated_bytes,
                 truncation="message cut by the end of the file" if sc.truncated_bytes else None,
                 streams_skipped=sc.skipped)
    return streams, {"data": data, "sc": sc}, facts


def _read_tlog(path, raw_imu_unit, raw_imu_scale):
    data, fr, streams = tlog.read(path, raw_imu_unit, raw_imu_scale)
    facts = dict(messages=int(fr.ok.sum()), unreadable_records=fr.n_unreadable,
                 unreadable_bytes=int(fr.length[~fr.ok].sum()) + sum(e - s for s, e in fr.bad_regions),
                 truncated=fr.truncated_bytes > 0, truncated_bytes=fr.truncated_bytes,
                 truncation=("zero-filled tail" if fr.zero_tail else
                             "record cut by the end of the file" if fr.truncated_bytes else None))
    return streams, {"data": data, "fr": fr}, facts


def _read_ulog(path):
    u, streams, refs = ulog.read(path)
    cut = ulog.truncated_bytes(path)
    facts = dict(messages=sum(len(next(iter(d.data.values()), ())) for d in u.data_list),
                 streams_skipped=refs.skipped,
                 unreadable_records=None,
                 data_corruption=bool(getattr(u, "file_corruption", False)),
                 truncated=cut > 0, truncated_bytes=max(cut, 0),
                 truncation="message cut by the end of the file" if cut > 0 else None)
    return streams, {"u": u, "refs": refs}, facts


def write_filtered_log(kind, source, streams, path):
    """Write the filtered copy of a log to ``path``: the log of :func:`read_log`
    with the streams' ``filtered`` values in their gyro fields. Returns the
    report's fields on the writing (telemetry logs: ``signatures_dropped``, always 0 since a
    signed packet is never written unsigned: the pipeline writes signed links itself)."""
    if kind == "dataflash":
        Path(path).write_bytes(dataflash.patch(source["data"], source["sc"], streams))
        return {}
    if kind == "tlog":
        return {"signatures_dropped": tlog.write_filtered(source["data"], source["fr"], streams, path)}
    ulog.write_filtered(source["u"], streams, source["refs"], path)
    return {}
