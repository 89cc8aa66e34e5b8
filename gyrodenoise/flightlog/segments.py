"""Flight segments of a log, from the log's own evidence: when the vehicle was on the
ground (disarmed), armed but not flying, flying, and hovering.

:func:`flight_segments` returns a list of ``{"kind", "start_s", "end_s", "session"}`` in
the log's own time base (the gyro streams' ``time_s``; :mod:`gyrodenoise.flightlog.logdata`):

* ``ground`` -- not armed; ``armed`` -- armed, not in the air; ``flying`` -- in the air.
  These three partition the stretch of the log that holds evidence, in log order; a
  reboot (the boot time stepping back) ends every segment and starts a new one.
  A segment of no length (one sample) is left out.
* ``session`` -- the boot session the segment lies in (0, 1, ...). A telemetry log can
  hold several boots (a reboot, or several logs written into one file) whose boot
  times overlap: a time alone does not say which boot it is in, so a sample is in a
  segment when its session and its time both are (:func:`segment_mask` with
  ``session``). Sessions are numbered in file order by the frame index of the
  records (:func:`gyrodenoise.flightlog.logdata.tlog_session_starts`, the same
  numbering for every message and gyro stream); a DataFlash or ULog log is one
  session (0).
* ``hover`` -- EXTRA entries, not part of the partition: a stretch of a ``flying``
  segment where the throttle is steady -- the union of the 2 s windows
  (:data:`HOVER_WINDOW_S`, at least 3 throttle samples) whose throttle standard
  deviation is below 0.03 of full throttle (:data:`HOVER_STD`) -- at least 3 s long
  (:data:`HOVER_MIN_S`). Each lies inside a ``flying`` segment.

Evidence, by format:

* ArduPilot DataFlash: arming from ``ARM.ArmState`` and the ``EV`` events; in the air
  from the events ``NOT_LANDED`` (in the air) and ``LAND_COMPLETE`` (landed; arming
  and disarming also mean landed). Event ids from ArduPilot's ``LogEvent`` enum
  (libraries/AP_Logger/AP_Logger.h): 10 ARMED, 11 DISARMED, 15 AUTO_ARMED,
  17 LAND_COMPLETE_MAYBE (not used), 18 LAND_COMPLETE, 28 NOT_LANDED. A log whose
  first arming record is a disarm starts armed (logging began in flight or armed).
  Without land events the throttle decides (above :data:`FLYING_THROTTLE` of full
  throttle = in the air); without any arming record, the throttle alone decides
  between ``ground`` and ``flying`` (a log with no arming record and the throttle at
  zero is all ground). ArduSub and Rover never fly (armed at most). Throttle:
  ``CTUN.ThO`` (0..1), ``CTUN.ThrOut`` (0..1000, Copter 3.x), else the mean of
  ``RCOU`` C1..C4 (``Ch1..Ch4``) as (PWM - 1000 us) / 1000 us.
* Telemetry log: the vehicle's ``HEARTBEAT`` (not a ground station's: autopilot 8 or
  type 6 are left out; the system id with most heartbeats, its component 1 if it
  sends any): armed = ``base_mode`` bit 128 (MAV_MODE_FLAG_SAFETY_ARMED); in the air:
  ``EXTENDED_SYS_STATE.landed_state`` 2-4 (in air, taking off, landing) where sent,
  else for an ArduPilot multicopter or helicopter ``system_status`` 4
  (MAV_STATE_ACTIVE: ArduCopter reports ACTIVE only while not landed); for other
  vehicles without EXTENDED_SYS_STATE only ``ground``/``armed``. Throttle for hover:
  ``VFR_HUD.throttle`` (%), else ``SERVO_OUTPUT_RAW`` servo1..4.
* PX4 ULog: armed = ``vehicle_status.arming_state`` 2 (ARMED) or ``actuator_armed.armed``;
  in the air = armed and ``vehicle_land_detected.landed`` 0; throttle for hover:
  ``vehicle_thrust_setpoint`` -xyz[2], else ``actuator_controls_0`` control[3].
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.flightlog.logdata import log_messages, tlog_session_starts

SEGMENT_KINDS = ("ground", "armed", "flying", "hover")
GROUND, ARMED, FLYING = 0, 1, 2
_STATE_NAMES = ("ground", "armed", "flying")

HOVER_WINDOW_S = 2.0
HOVER_STD = 0.03
HOVER_MIN_S = 3.0
FLYING_THROTTLE = 0.2
REBOOT_STEP_S = 0.5

EV_ARMED, EV_DISARMED, EV_LAND_COMPLETE, EV_NOT_LANDED = 10, 11, 18, 28
MAV_STATE_ACTIVE = 4
MAV_SAFETY_ARMED = 128
COPTER_TYPES = {2, 3, 4, 13, 14, 15, 29}     # quad, coaxial, heli, hexa, octo, tri, dodeca
PX4_ARMING_STATE_ARMED = 2

LOOKED_FOR = {
    "dataflash": "ARM.ArmState, EV (ARMED/DISARMED/NOT_LANDED/LAND_COMPLETE), CTUN.ThO/ThrOut, RCOU C1..C4",
    "tlog": "HEARTBEAT (base_mode armed bit, system_status) of the vehicle, EXTENDED_SYS_STATE.landed_state",
    "ulog": "vehicle_status.arming_state, actuator_armed.armed, vehicle_land_detected.landed",
}


def flight_segments(kind, source, autopilot=None):
    """(segments, note) of a log read by :func:`gyrodenoise.flightlog.formats.read_log`.

    ``segments``: list of ``{"kind": "ground"|"armed"|"flying"|"hover", "start_s",
    "end_s"}`` (see the module doc; ``hover`` entries lie inside ``flying`` ones);
    ``note``: which evidence gave them, or -- with an empty list -- what was looked for
    when the log holds none. ``autopilot`` ("ardupilot", "px4" or None: from the log)
    decides how a telemetry log's ``system_status`` is read."""
    if kind == "dataflash":
        got = _dataflash(source)
    elif kind == "tlog":
        got = _tlog(source, autopilot)
    elif kind == "ulog":
        got = _ulog(source)
    else:
        raise ValueError(f"unknown log kind {kind!r}")
    if isinstance(got, str):
        return [], got
    t, state, throttle, note = got[:4]
    segs = _runs(t, state, got[4] if len(got) > 4 else None)
    hov = _hover(segs, throttle) if throttle is not None else []
    if hov:
        note += (f"; hover: throttle std over {HOVER_WINDOW_S:g} s below {HOVER_STD:g} of full "
                 f"throttle for at least {HOVER_MIN_S:g} s")
    out = []
    for seg in segs:                 # log order; each hover entry after its flying segment
        out.append(seg)
        if seg["kind"] == "flying":
            out += [{k: v for k, v in h.items() if k != "_parent"} for h in hov if h["_parent"] is seg]
    return out, note


def segment_mask(time_s, segments, kind, session=None):
    """Boolean array: True where ``time_s`` lies in a segment of ``kind`` (start and end
    included) -- and, given ``session`` (each sample's boot session, an int array like
    ``time_s``: :func:`sessions_of`), in that segment's session. ``kind`` "flying"
    covers the hover stretches too (they lie inside)."""
    t = np.asarray(time_s, dtype=np.float64)
    mask = np.zeros(t.shape, dtype=bool)
    sess = None if session is None else np.asarray(session)
    for s in segments:
        if s["kind"] == kind:
            m = (t >= s["start_s"]) & (t <= s["end_s"])
            if sess is not None:
                m &= sess == s.get("session", 0)
            mask |= m
    return mask


def session_starts(kind, source):
    """Frame indices at which the log's boot sessions 1, 2, ... begin (int array; empty
    for one session, and for DataFlash and ULog logs): see the module doc."""
    if kind == "tlog":
        return tlog_session_starts(source)
    return np.zeros(0, np.int64)


def sessions_of(records, starts):
    """The boot session (int array) of each of ``records`` (frame indices: a telemetry
    message's ``record`` column, a gyro stream's ``index``) given :func:`session_starts`."""
    return np.searchsorted(np.asarray(starts), np.asarray(records), side="right")


def flying_time_s(segments):
    """Seconds in the air: the summed length of the ``flying`` segments (float)."""
    return round(float(sum(s["end_s"] - s["start_s"] for s in segments if s["kind"] == "flying")), 3)


# ------------------------------------------------------------------ helpers
def _sessions(t):
    """Session number of each sample: +1 wherever the time steps back by more than
    :data:`REBOOT_STEP_S` (a reboot; smaller steps back are the jitter of a telemetry
    log's anchored times)."""
    return np.concatenate([[0], np.cumsum(np.diff(t) < -REBOOT_STEP_S)]) if len(t) else np.zeros(0, np.int64)


def _runs(t, state, sess=None):
    """Segments of constant ``state`` along the timeline ``t`` (log order), each with
    its ``session``: a run ends where the next run starts, or at its last sample
    before a reboot. ``sess``: each sample's boot session (the samples are then
    ordered by session, then time); without it a step back in ``t`` of more than
    :data:`REBOOT_STEP_S` starts a new one. Runs of no length are left out."""
    t = np.asarray(t, dtype=np.float64)
    state = np.asarray(state)
    ok = np.isfinite(t)
    t, state = t[ok], state[ok]
    if sess is not None:
        sess = np.asarray(sess)[ok]
        order = np.lexsort((t, sess))
        t, state, sess = t[order], state[order], sess[order]
    if not len(t):
        return []
    if sess is None:
        sess = _sessions(t)
    brk = np.flatnonzero((np.diff(state) != 0) | (np.diff(sess) != 0)) + 1
    starts = np.concatenate([[0], brk])
    ends = np.concatenate([brk, [len(t)]])
    out = []
    for a, b in zip(starts.tolist(), ends.tolist()):
        end = t[b] if b < len(t) and sess[b] == sess[a] else t[b - 1]
        if end > t[a]:
            out.append({"kind": _STATE_NAMES[int(state[a])], "start_s": round(float(t[a]), 6),
                        "end_s": round(float(end), 6), "session": int(sess[a])})
    return out


def _step(t_query, t_change, values, initial):
    """Value of a step function (``values`` from times ``t_change``, in log order) at
    ``t_query``; ``initial`` before the first change."""
    out = np.full(len(t_query), initial, dtype=np.int64)
    if not len(t_change):
        return out
    order = np.argsort(t_change, kind="stable")
    tc, vc = np.asarray(t_change)[order], np.asarray(values)[order]
    k = np.searchsorted(tc, t_query, side="right") - 1
    out[k >= 0] = vc[k[k >= 0]]
    return out


def _hover(segs, throttle):
    """Hover segments inside the flying ones from ``throttle`` = (time_s, 0..1[, session])."""
    tt, thr = throttle[0], throttle[1]
    ok = np.isfinite(tt) & np.isfinite(thr)
    tt, thr = np.asarray(tt, np.float64)[ok], np.asarray(thr, np.float64)[ok]
    tsess = np.asarray(throttle[2])[ok] if len(throttle) > 2 else None
    out = []
    for s in segs:
        if s["kind"] != "flying":
            continue
        sel = (tt >= s["start_s"]) & (tt <= s["end_s"])
        if tsess is not None:
            sel &= tsess == s["session"]
        t, x = tt[sel], thr[sel]
        order = np.argsort(t, kind="stable")
        t, x = t[order], x[order]
        if len(t) < 3 or t[-1] - t[0] < HOVER_MIN_S:
            continue
        c1 = np.concatenate([[0.0], np.cumsum(x)])
        c2 = np.concatenate([[0.0], np.cumsum(x * x)])
        lo = np.arange(len(t))                                   # windows [t_i, t_i + 2 s]
        hi = np.searchsorted(t, t + HOVER_WINDOW_S, side="right")
        n = hi - lo
        mean = (c1[hi] - c1[lo]) / n
        var = np.maximum((c2[hi] - c2[lo]) / n - mean * mean, 0.0)
        ok = (np.sqrt(var) < HOVER_STD) & (n >= 3) & (t + HOVER_WINDOW_S <= t[-1])
        cover = np.zeros(len(t) + 1, np.int64)                   # samples inside a steady window
        np.add.at(cover, lo[ok], 1)
        np.add.at(cover, hi[ok], -1)
        steady = np.cumsum(cover[:-1]) > 0
        edges = np.diff(np.concatenate([[0], steady.astype(np.int8), [0]]))
        for i, j in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1):
            if t[j] - t[i] >= HOVER_MIN_S:       # from the first to the last steady sample
                out.append({"kind": "hover", "start_s": round(float(t[i]), 6),
                            "end_s": round(float(t[j]), 6), "session": s["session"], "_parent": s})
    return out


def _timeline(*times):
    """Sorted union of time columns (finite values), without the times a damaged record
    gives: those further outside the span of the middle 80 % than twice that span (plus
    60 s) -- a bit flip in a timestamp must not stretch a segment to 10^12 s."""
    parts = [np.asarray(t, np.float64) for t in times if t is not None and len(t)]
    if not parts:
        return np.zeros(0)
    t = np.concatenate(parts)
    t = t[np.isfinite(t)]
    if len(t):
        lo, hi = np.quantile(t, [0.1, 0.9])
        margin = 2.0 * (hi - lo) + 60.0
        t = t[(t >= lo - margin) & (t <= hi + margin)]
    return np.unique(t)


def _forward_fill(v):
    """``v`` with each -1 replaced by the last value before it that is not -1 (0 at the start)."""
    v = np.asarray(v, np.int64)
    idx = np.where(v >= 0, np.arange(len(v)), -1)
    idx = np.maximum.accumulate(idx) if len(v) else idx
    return np.where(idx >= 0, v[np.maximum(idx, 0)], 0)


# ---------------------------------------------------------------- DataFlash
def _df_throttle(source):
    """(time_s, throttle 0..1, where from) or None."""
    ctun = log_messages("dataflash", source, "CTUN")
    if ctun is not None and "ThO" in ctun:
        return ctun["time_s"], ctun["ThO"].astype(np.float64), "CTUN.ThO"
    if ctun is not None and "ThrOut" in ctun:
        return ctun["time_s"], ctun["ThrOut"].astype(np.float64) / 1000.0, "CTUN.ThrOut/1000"
    rcou = log_messages("dataflash", source, "RCOU")
    if rcou is not None:
        cols = [c for c in ("C1", "C2", "C3", "C4") if c in rcou] or \
               [c for c in ("Ch1", "Ch2", "Ch3", "Ch4") if c in rcou]
        if cols:
            pwm = np.mean([rcou[c].astype(np.float64) for c in cols], axis=0)
            return rcou["time_s"], np.clip((pwm - 1000.0) / 1000.0, 0, 1), f"RCOU {'/'.join(cols)}"
    return None


def _df_vehicle(source):
    msg = log_messages("dataflash", source, "MSG")
    if msg is None:
        return None
    for text in msg["Message"].tolist():
        for name in ("ArduSub", "ArduRover", "Rover", "ArduPlane", "ArduCopter", "APM:Copter", "APM:Plane"):
            if text.startswith(name):
                return name
    return None


def _dataflash(source):
    ev = log_messages("dataflash", source, "EV")
    arm = log_messages("dataflash", source, "ARM")
    thr = _df_throttle(source)
    # arming changes: (time, 0/1) from ARM.ArmState and EV 10/11
    at, av = [], []
    if arm is not None and "ArmState" in arm:
        at.append(arm["time_s"])
        av.append((arm["ArmState"] != 0).astype(np.int64))
    lt, lv = [], []                  # land changes: 1 = in the air, 0 = landed
    if ev is not None:
        ids = ev["Id"].astype(np.int64)
        sel = np.isin(ids, (EV_ARMED, EV_DISARMED))
        at.append(ev["time_s"][sel])
        av.append((ids[sel] == EV_ARMED).astype(np.int64))
        sel = np.isin(ids, (EV_ARMED, EV_DISARMED, EV_LAND_COMPLETE, EV_NOT_LANDED))
        lt.append(ev["time_s"][sel])
        lv.append((ids[sel] == EV_NOT_LANDED).astype(np.int64))
    at = np.concatenate(at) if at else np.zeros(0)
    av = np.concatenate(av) if av else np.zeros(0, np.int64)
    ok = np.isfinite(at)
    at, av = at[ok], av[ok]
    lt = np.concatenate(lt) if lt else np.zeros(0)
    lv = np.concatenate(lv) if lv else np.zeros(0, np.int64)
    ok = np.isfinite(lt)
    lt, lv = lt[ok], lv[ok]
    if not len(at) and thr is None:
        return f"no flight evidence in the log (looked for {LOOKED_FOR['dataflash']})"
    clock = None
    for name in ("CTUN", "RCOU", "ATT", "IMU", "BARO"):
        m = log_messages("dataflash", source, name)
        if m is not None:
            clock = m["time_s"]
            break
    t = _timeline(clock, at, lt, thr[0] if thr is not None else None)
    vehicle = _df_vehicle(source)
    never_flies = vehicle in ("ArduSub", "ArduRover", "Rover")
    notes = []
    if len(at):
        order = np.argsort(at, kind="stable")
        armed = _step(t, at, av, initial=1 - int(av[order][0]))
        notes.append("armed from ARM/EV" + (" (armed at the log's start: its first record is a disarm)"
                                            if av[order][0] == 0 else ""))
    else:
        armed = None
    n_land = int(np.isin(lv, (0, 1)).sum()) if len(lv) else 0
    has_land_events = ev is not None and np.isin(ev["Id"], (EV_LAND_COMPLETE, EV_NOT_LANDED)).any()
    if never_flies:
        air = np.zeros(len(t), np.int64)
        notes.append(f"{vehicle}: never flying")
    elif has_land_events and n_land:
        order = np.argsort(lt, kind="stable")
        first_land = lv[order][0]
        first_id = ev["Id"][np.isin(ev["Id"], (EV_ARMED, EV_DISARMED, EV_LAND_COMPLETE, EV_NOT_LANDED))]
        init = 1 if (first_land == 0 and int(first_id[0]) == EV_LAND_COMPLETE) else 0
        air = _step(t, lt, lv, initial=init)
        notes.append("in the air from EV NOT_LANDED/LAND_COMPLETE")
    elif thr is not None:
        tv = np.interp(t, *_sorted(thr[0], thr[1]))
        air = (tv > FLYING_THROTTLE).astype(np.int64)
        notes.append(f"in the air where {thr[2]} > {FLYING_THROTTLE:g} (no land events)")
    else:
        air = np.zeros(len(t), np.int64)
        notes.append("no land events nor throttle: armed stretches not split into flying")
    if armed is None:
        state = np.where(air == 1, FLYING, GROUND)
        notes.insert(0, "no ARM/EV arming record: ground/flying from the throttle alone")
    else:
        state = np.where(armed == 1, np.where(air == 1, FLYING, ARMED), GROUND)
    throttle = (thr[0], thr[1]) if thr is not None else None
    return t, state, throttle, "DataFlash: " + "; ".join(notes)


def _sorted(t, v):
    ok = np.isfinite(t) & np.isfinite(v)
    order = np.argsort(t[ok], kind="stable")
    return t[ok][order], v[ok][order]


# --------------------------------------------------------------------- tlog
def _tlog(source, autopilot):
    hb = log_messages("tlog", source, "HEARTBEAT")
    if hb is None:
        return f"no flight evidence in the log (looked for {LOOKED_FOR['tlog']})"
    veh = (hb["autopilot"] != 8) & (hb["type"] != 6) & np.isfinite(hb["time_s"])
    if not veh.any():
        return (f"no vehicle HEARTBEAT with a boot time (only ground stations', or no message "
                f"with time_boot_ms to place them; looked for {LOOKED_FOR['tlog']})")
    ids, counts = np.unique(hb["sysid"][veh], return_counts=True)
    sysid = int(ids[np.argmax(counts)])
    veh &= hb["sysid"] == sysid
    if (veh & (hb["compid"] == 1)).any():
        veh &= hb["compid"] == 1
    t = hb["time_s"][veh]
    starts = tlog_session_starts(source)
    hb_sess = sessions_of(hb["record"][veh], starts)
    armed = (hb["base_mode"][veh] & MAV_SAFETY_ARMED) != 0
    ap = autopilot or ("ardupilot" if int(np.bincount(hb["autopilot"][veh]).argmax()) == 3 else
                       "px4" if int(np.bincount(hb["autopilot"][veh]).argmax()) == 12 else None)
    vtype = int(np.bincount(hb["type"][veh]).argmax())
    ess = log_messages("tlog", source, "EXTENDED_SYS_STATE")
    if ess is not None:
        ess_sel = (ess["sysid"] == sysid) & np.isfinite(ess["time_s"])
        ess = None if not ess_sel.any() else (ess["record"][ess_sel], ess["landed_state"][ess_sel])
    if ess is not None:         # in file order: boot times of several sessions overlap
        air = _step(hb["record"][veh], ess[0], np.isin(ess[1], (2, 3, 4)).astype(np.int64), initial=0) == 1
        how = "in the air from EXTENDED_SYS_STATE.landed_state"
    elif ap == "ardupilot" and vtype in COPTER_TYPES:
        ss = hb["system_status"][veh]
        air = _forward_fill(np.where(ss == MAV_STATE_ACTIVE, 1, np.where(np.isin(ss, (5, 6)), -1, 0))) == 1
        how = ("in the air where system_status is ACTIVE (ArduPilot multicopter; CRITICAL/EMERGENCY "
               "keep the state before)")
    else:
        air = np.zeros(len(t), bool)
        how = (f"not split into flying: no EXTENDED_SYS_STATE and the vehicle (autopilot {ap}, "
               f"type {vtype}) does not report landing in system_status")
    state = np.where(armed, np.where(air, FLYING, ARMED), GROUND)
    throttle = None
    vfr = log_messages("tlog", source, "VFR_HUD")
    if vfr is not None and (vfr["sysid"] == sysid).any():
        s = vfr["sysid"] == sysid
        throttle = (vfr["time_s"][s], vfr["throttle"][s].astype(np.float64) / 100.0,
                    sessions_of(vfr["record"][s], starts))
    else:
        so = log_messages("tlog", source, "SERVO_OUTPUT_RAW")
        if so is not None and (so["sysid"] == sysid).any():
            s = so["sysid"] == sysid
            pwm = np.mean([so[f"servo{i}_raw"][s].astype(np.float64) for i in range(1, 5)], axis=0)
            throttle = (so["time_s"][s], np.clip((pwm - 1000.0) / 1000.0, 0, 1), sessions_of(so["record"][s], starts))
    how += f"; {len(starts) + 1} boot sessions (numbered in file order)" if len(starts) else ""
    return (t, state, throttle,
            f"telemetry log: HEARTBEAT of system {sysid} (armed bit of base_mode); {how}", hb_sess)


# --------------------------------------------------------------------- ULog
def _ulog(source):
    vs = log_messages("ulog", source, "vehicle_status")
    aa = log_messages("ulog", source, "actuator_armed")
    ld = log_messages("ulog", source, "vehicle_land_detected")
    if vs is None and aa is None:
        return f"no flight evidence in the log (looked for {LOOKED_FOR['ulog']})"
    ends = [m["time_s"][-1] for m in (vs, aa, ld) if m is not None and len(m["time_s"])]
    for name in ("sensor_combined", "vehicle_angular_velocity"):
        m = log_messages("ulog", source, name)
        if m is not None and len(m["time_s"]):
            ends.append(m["time_s"][-1])
    span = [source["u"].start_timestamp * 1e-6, max(ends)]
    if vs is not None and "arming_state" in vs:
        at, av, how = vs["time_s"], (vs["arming_state"] == PX4_ARMING_STATE_ARMED).astype(np.int64), \
            "vehicle_status.arming_state"
    elif aa is not None:
        at, av, how = aa["time_s"], (aa["armed"] != 0).astype(np.int64), "actuator_armed.armed"
    else:
        return f"no flight evidence in the log (looked for {LOOKED_FOR['ulog']})"
    t = _timeline(span, at, ld["time_s"] if ld is not None else None)
    t = t[(t >= span[0]) & (t <= span[1])]
    armed = _step(t, at, av, initial=int(av[0]))
    if ld is not None and "landed" in ld:
        air = _step(t, ld["time_s"], (ld["landed"] == 0).astype(np.int64), initial=0)
        how += "; in the air from vehicle_land_detected.landed"
    else:
        air = np.zeros(len(t), np.int64)
        how += "; no vehicle_land_detected: armed stretches not split into flying"
    state = np.where(armed == 1, np.where(air == 1, FLYING, ARMED), GROUND)
    throttle = None
    ts = log_messages("ulog", source, "vehicle_thrust_setpoint")
    if ts is not None and "xyz[2]" in ts:
        throttle = (ts["time_s"], -ts["xyz[2]"].astype(np.float64))
    else:
        ac = log_messages("ulog", source, "actuator_controls_0")
        if ac is not None and "control[3]" in ac:
            throttle = (ac["time_s"], ac["control[3]"].astype(np.float64))
    return t, state, throttle, "ULog: armed from " + how
