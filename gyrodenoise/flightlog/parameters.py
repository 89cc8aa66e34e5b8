"""The autopilot that wrote a log and the parameters it logged.

:func:`log_parameters` reads them through the log's format adapter (its ``parameters``,
one of the readers below):

* DataFlash ``PARM`` (``Name``, ``Value``): each name's last value logged before
  the first arming (``EV`` id 10, ARMED, or ``ARM`` ``ArmState`` 1), else -- no
  arming in the log -- its first value (ArduPilot writes every parameter at the
  start of a log, and again when one changes).
* ULog: pyulog's ``initial_parameters`` plus its ``changed_parameters`` logged
  before the first arming (``vehicle_status.arming_state`` 2); without an arming,
  the initial ones.
* Telemetry log ``PARAM_VALUE`` (``param_id``, ``param_value``, ``param_type``) of
  the vehicle's system, each name's last value before the first armed ``HEARTBEAT``
  (``base_mode`` bit 7), else the first. PX4 sends integer parameters bytewise
  (the int32's bits in the float field, MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE):
  they are decoded so; ArduPilot casts them (C cast), kept as they are. A name the
  vehicle did not send is taken from the ``PARAM_VALUE`` records of any other source:
  Mission Planner writes the parameters it downloads by FTP as ``PARAM_VALUE`` under
  its own ids (system 255, component 190), and the vehicle then sends few or none
  itself; a note says so.

The autopilot (a strategy of :mod:`gyrodenoise.flightlog.autopilots`): ArduPilot for
DataFlash, PX4 for ULog; for a
telemetry log the ``HEARTBEAT.autopilot`` of the vehicle (3 ArduPilot, 12 PX4),
else from the parameter names (``INS_``/``ATC_`` ArduPilot, ``IMU_GYRO_``/``MC_``
PX4), else None.
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.flightlog.autopilots import (ARDUPILOT, AUTOPILOTS, PX4_AUTOPILOT, UNKNOWN, from_mav_autopilot,
                                               from_parameter_names)
from gyrodenoise.flightlog.model import LogParameters

MAV_TYPE_GCS = 6
MAV_MODE_FLAG_SAFETY_ARMED = 128
#: MAV_PARAM_TYPE values of integers (UINT8..INT64)
MAV_PARAM_INT_TYPES = {1, 2, 3, 4, 5, 6, 7, 8}
DF_EV_ARMED = 10


def log_parameters(log):
    """(autopilot, params) of a :class:`~gyrodenoise.flightlog.model.FlightLog`: the
    autopilot's strategy (:mod:`gyrodenoise.flightlog.autopilots`); params ``{NAME:
    value as logged}`` (floats; ints where the log types them so), empty when the log
    holds none (see the module doc for which value of a changed parameter is kept).
    The notes (where parameters came from another source than the vehicle):
    ``log.parameters().notes``."""
    got = log.parameters()
    return got.autopilot, got.values


def _first_time(times):
    times = np.asarray(times, dtype=np.float64)
    times = times[np.isfinite(times)]
    return float(times.min()) if len(times) else None


def _boot_first(log, name):
    """Message ``name`` of the log's first boot: parameters are those the vehicle flew
    with first (each boot logs its own; the first is the one every boot starts from)."""
    return log.boot_messages(name, 0)


def dataflash_parameters(log) -> LogParameters:
    """ArduPilot's parameters from a DataFlash log's ``PARM`` (its first boot)."""
    parm = _boot_first(log, "PARM")
    if parm is None or "Name" not in parm or "Value" not in parm:
        return LogParameters(ARDUPILOT, {})
    arm_times = []
    ev = _boot_first(log, "EV")
    if ev is not None and "Id" in ev:
        arm_times.append(ev["time_s"][np.asarray(ev["Id"]) == DF_EV_ARMED])
    arm = _boot_first(log, "ARM")
    if arm is not None and "ArmState" in arm:
        arm_times.append(arm["time_s"][np.asarray(arm["ArmState"]) == 1])
    t_arm = _first_time(np.concatenate(arm_times)) if arm_times else None
    if np.asarray(parm["Value"]).dtype.kind not in "iuf":
        return LogParameters(ARDUPILOT, {}, [f"PARM.Value is no number in this log's FMT "
                                             f"({np.asarray(parm['Value']).dtype}): parameters not read"])
    names, values, times = parm["Name"], np.asarray(parm["Value"], dtype=np.float64), parm["time_s"]
    out = {}
    for i in range(len(names)):
        n = str(names[i])
        if not n:
            continue
        before = t_arm is None or not np.isfinite(times[i]) or times[i] < t_arm
        if n not in out or (t_arm is not None and before):
            out[n] = _f32(values[i])
    return LogParameters(ARDUPILOT, out)


def ulog_parameters(log) -> LogParameters:
    """PX4's parameters from a ULog (pyulog's initial and changed parameters)."""
    u = log.payload.ulog
    out, bad = {}, []
    for k, v in (getattr(u, "initial_parameters", None) or {}).items():
        if _is_number(v):
            out[str(k)] = _plain(v)
        else:
            bad.append(str(k))
    vs = log.messages("vehicle_status")
    t_arm = None
    if vs is not None and "arming_state" in vs:
        t = vs["time_s"][np.asarray(vs["arming_state"]) == 2]
        t_arm = float(t[0]) if len(t) else None
    if t_arm is not None:
        offset = log.time_base.offset_s
        for ts, name, value in getattr(u, "changed_parameters", None) or []:
            if ts * 1e-6 - offset < t_arm and _is_number(value):
                out[str(name)] = _plain(value)
    notes = [f"{len(bad)} parameters with a value that is no number left out ({', '.join(bad[:5])})"] if bad else []
    return LogParameters(PX4_AUTOPILOT, out, notes)


def _is_number(v):
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _f32(v):
    """A float32 as logged, as the shortest decimal that reads back to it (0.32, not 0.3199999928)."""
    return float(str(np.float32(v)))


def _plain(v):
    if isinstance(v, (np.integer, int)) and not isinstance(v, bool):
        return int(v)
    return _f32(v) if isinstance(v, (np.float32, float)) else float(v)


def tlog_parameters(log) -> LogParameters:
    """The parameters of a telemetry log's ``PARAM_VALUE`` records (the module doc)."""
    notes = []
    hb = log.messages("HEARTBEAT")
    sysid, autopilot, t_arm = None, UNKNOWN, None
    if hb is not None and len(hb.get("time_s", [])):
        veh = np.asarray(hb["type"]) != MAV_TYPE_GCS
        ap = np.asarray(hb["autopilot"])
        known = veh & np.isin(ap, [a.mav_autopilot for a in AUTOPILOTS.values() if a.mav_autopilot is not None])
        if known.any():
            vals, counts = np.unique(ap[known], return_counts=True)
            autopilot = from_mav_autopilot(int(vals[np.argmax(counts)]))
            sys_known = np.asarray(hb["sysid"])[known & (ap == vals[np.argmax(counts)])]
            sv, sc = np.unique(sys_known, return_counts=True)
            sysid = int(sv[np.argmax(sc)])
            armed = known & (np.asarray(hb["sysid"]) == sysid) & (
                (np.asarray(hb["base_mode"]).astype(np.int64) & MAV_MODE_FLAG_SAFETY_ARMED) != 0)
            if armed.any():
                t_arm = int(np.flatnonzero(armed)[0])      # an index into HEARTBEAT: compare log times below
                t_arm = float(np.asarray(hb["log_time_s"])[t_arm])
    params = {}
    pv = log.messages("PARAM_VALUE")
    if pv is not None and len(pv.get("param_id", [])):
        own = np.ones(len(pv["param_id"]), dtype=bool)
        if sysid is not None:
            own &= np.asarray(pv["sysid"]) == sysid
        ids, vals = pv["param_id"], np.asarray(pv["param_value"], dtype=np.float32)
        types, log_t = np.asarray(pv["param_type"]), np.asarray(pv["log_time_s"])
        vehicle_names = {str(ids[i]) for i in np.flatnonzero(own)}
        other = np.flatnonzero(~own & ~np.isin(np.asarray(ids).astype(str), list(vehicle_names)))
        if len(other):
            pairs = sorted({(int(pv["sysid"][i]), int(pv["compid"][i])) for i in other})
            n_other = len({str(ids[i]) for i in other})
            notes.append(f"{n_other} parameters read from PARAM_VALUE records of "
                         f"{', '.join(f'system {a} component {b}' for a, b in pairs)} (not the vehicle's: a "
                         f"ground station's parameter download, e.g. Mission Planner's FTP), the vehicle "
                         f"itself sent {len(vehicle_names)}")
        for i in np.concatenate([np.flatnonzero(own), other]).astype(np.int64):
            n = str(ids[i])
            if not n:
                continue
            before = t_arm is None or log_t[i] < t_arm
            if n in params and not (t_arm is not None and before):
                continue
            v = vals[i]
            if autopilot.int_params_bytewise and int(types[i]) in MAV_PARAM_INT_TYPES:
                params[n] = int(np.asarray(v, dtype=np.float32).view(np.int32))
            else:
                params[n] = _f32(v)
    if autopilot is UNKNOWN and params:
        autopilot = from_parameter_names(params)
    return LogParameters(autopilot, params, notes)
