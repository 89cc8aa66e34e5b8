"""A log's events and flight modes (:meth:`gyrodenoise.flightlog.model.FlightLog.events`
and ``modes``), one reader per format (the format adapters' ``events`` and ``modes``):

* DataFlash: ``EV`` (``EV <Id>``, ArduPilot's LogEvent ids) and ``MSG`` texts; ``MODE``
  rows (``Mode``, a name or a number as logged).
* Telemetry log: ``STATUSTEXT`` texts; the vehicle's ``HEARTBEAT.custom_mode`` where it
  changes (the autopilot's own numbering).
* ULog: the logged messages (pyulog ``logged_messages``); ``vehicle_status.nav_state``
  where it changes (PX4's numbering).
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.flightlog.model import LogEvent, ModeChange

MAV_AUTOPILOT_INVALID, MAV_TYPE_GCS = 8, 6


def _events(log, m, texts):
    boots = log.rows_boot(m)
    return [LogEvent(float(t), int(b), str(x)) for t, b, x in zip(m["time_s"], boots, texts)]


def _changes(log, m, values, names=None):
    """ModeChange at each row of ``m`` whose value differs from the row before (per boot)."""
    boots = log.rows_boot(m)
    v = np.asarray(values)
    keep = np.ones(len(v), bool)
    keep[1:] = (v[1:] != v[:-1]) | (boots[1:] != boots[:-1])
    return [ModeChange(float(m["time_s"][i]), int(boots[i]), str(names[i] if names is not None else v[i]))
            for i in np.flatnonzero(keep)]


def dataflash_events(log):
    out = []
    ev = log.messages("EV")
    if ev is not None and "Id" in ev:
        out += _events(log, ev, [f"EV {int(i)}" for i in ev["Id"]])
    msg = log.messages("MSG")
    if msg is not None and "Message" in msg:
        out += _events(log, msg, msg["Message"])
    return sorted(out, key=lambda e: (e.boot, e.time_s))


def dataflash_modes(log):
    m = log.messages("MODE")
    if m is None or "Mode" not in m:
        return []
    boots = log.rows_boot(m)
    return [ModeChange(float(t), int(b), str(x)) for t, b, x in zip(m["time_s"], boots, m["Mode"])]


def tlog_events(log):
    st = log.messages("STATUSTEXT")
    return [] if st is None else _events(log, st, st["text"])


def tlog_modes(log):
    hb = log.messages("HEARTBEAT")
    if hb is None:
        return []
    veh = (hb["autopilot"] != MAV_AUTOPILOT_INVALID) & (hb["type"] != MAV_TYPE_GCS)
    if not veh.any():
        return []
    ids, counts = np.unique(hb["sysid"][veh], return_counts=True)
    veh &= hb["sysid"] == ids[np.argmax(counts)]
    sel = {k: (v[veh] if isinstance(v, np.ndarray) and len(v) == len(veh) else v) for k, v in hb.items()}
    return _changes(log, sel, sel["custom_mode"])


def ulog_events(log):
    offset = log.time_base.offset_s
    return [LogEvent(m.timestamp * 1e-6 - offset, 0, str(m.message))
            for m in getattr(log.payload.ulog, "logged_messages", None) or []]


def ulog_modes(log):
    vs = log.messages("vehicle_status")
    if vs is None or "nav_state" not in vs:
        return []
    return _changes(log, vs, vs["nav_state"])
