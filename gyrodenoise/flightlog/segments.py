"""Flight segments of a log, from the log's own evidence: when the vehicle was on the
ground (disarmed), armed but not flying, flying, and hovering.

:func:`flight_segments` returns a list of :class:`~gyrodenoise.flightlog.model.Segment` (``kind``,
``start_s``, ``end_s``, ``session``; ``to_fields()`` the report's dict) in
the log's own time base (the gyro streams' ``time_s``; :mod:`gyrodenoise.flightlog.logdata`):

* ``ground`` -- not armed; ``armed`` -- armed, not in the air; ``flying`` -- in the air.
  These three partition the stretch of the log that holds evidence, in log order; a
  reboot (the boot time stepping back) ends every segment and starts a new one.
  A segment of no length (one sample) is left out.
* ``session`` -- the boot the segment lies in (0, 1, ...,
  :attr:`gyrodenoise.flightlog.model.FlightLog.boots`). A file can hold several boots
  (a reboot, a log downloaded whole, logs concatenated) whose boot times overlap: each
  boot's evidence is read on its own (its messages only) and its segments are on its
  own time axis; a time alone does not say which boot it is in, so a sample is in a
  segment when its boot and its time both are (:func:`segment_mask` with ``session``).
  Boots are numbered in file order by the records' place in the file (a telemetry
  record's frame index, a DataFlash message's byte offset: the same numbering for every
  message and gyro stream of the log).
* ``after impact`` -- the rest of a ``flying`` segment from a crash on
  (:mod:`gyrodenoise.flightlog.impact`): the flight ends at the impact (the first
  sample of the rate jump or the accelerometer spike); what follows is shown but kept out of the verdicts (the segment carries
  the :class:`~gyrodenoise.flightlog.impact.Impact`).
* ``hover`` -- EXTRA entries, not part of the partition: a stretch of a ``flying``
  segment where the throttle is steady -- the union of the 2 s windows
  (:data:`HOVER_WINDOW_S`, at least 3 throttle samples) whose throttle standard
  deviation is below 0.03 of full throttle (:data:`HOVER_STD`) and in which the body
  rate (the boot's first gyro, averaged per axis over :data:`HOVER_RATE_SMOOTH_S`) stays
  below :data:`HOVER_RATE_DPS` (steady throttle alone is not a hover: a motor failure
  swings the vehicle at a steady throttle) -- at least 3 s long
  (:data:`HOVER_MIN_S`). Each lies inside a ``flying`` segment.

Evidence, by format:

What each format reads is its adapter's ``flight_evidence`` (:mod:`gyrodenoise.flightlog.formats`):

* ArduPilot DataFlash (:func:`dataflash_evidence`): arming from ``ARM.ArmState`` and the ``EV`` events; in the air
  from the events ``NOT_LANDED`` (in the air) and ``LAND_COMPLETE`` (landed; arming
  and disarming also mean landed). Event ids from ArduPilot's ``LogEvent`` enum
  (libraries/AP_Logger/AP_Logger.h): 10 ARMED, 11 DISARMED, 15 AUTO_ARMED,
  17 LAND_COMPLETE_MAYBE (not used), 18 LAND_COMPLETE, 28 NOT_LANDED. A log whose
  first arming record is a disarm starts armed (logging began in flight or armed).
  Without land events the throttle decides (above :data:`FLYING_THROTTLE` of full
  throttle = in the air); without any arming record, the throttle alone decides
  between ``ground`` and ``flying`` (a log with no arming record and the throttle at
  zero is all ground). Without land events nor throttle, GPS and airspeed decide where
  logged (:func:`_df_motion`: a stretch above 5 m in which the ground speed or airspeed
  exceeds 3 m/s: an ArduPlane 3.1 log with no ARM/EV/CTUN). ArduSub and Rover never fly (armed at most). Throttle:
  ``CTUN.ThO`` (0..1), ``CTUN.ThrOut`` (0..1000, Copter 3.x), else the mean of
  ``RCOU`` C1..C4 (``Ch1..Ch4``) as (PWM - 1000 us) / 1000 us.
* Telemetry log (:func:`tlog_evidence`): the vehicle's ``HEARTBEAT`` (not a ground station's: autopilot 8 or
  type 6 are left out; the system id with most heartbeats, its component 1 if it
  sends any): armed = ``base_mode`` bit 128 (MAV_MODE_FLAG_SAFETY_ARMED); in the air:
  ``EXTENDED_SYS_STATE.landed_state`` 2-4 (in air, taking off, landing) where sent,
  else for an ArduPilot multicopter or helicopter ``system_status`` 4
  (MAV_STATE_ACTIVE: ArduCopter reports ACTIVE only while not landed); for other
  vehicles without EXTENDED_SYS_STATE (a plane) the height and speed rule of the
  DataFlash GPS evidence on ``GLOBAL_POSITION_INT.relative_alt`` and ``VFR_HUD``
  (:func:`_tlog_motion`), never for a rover, boat or submarine; else only ``ground``/``armed``. Throttle for hover:
  ``VFR_HUD.throttle`` (%), else ``SERVO_OUTPUT_RAW`` servo1..4.
* PX4 ULog (:func:`ulog_evidence`): armed = ``vehicle_status.arming_state`` 2 (ARMED) or ``actuator_armed.armed``;
  in the air = armed and ``vehicle_land_detected.landed`` 0; throttle for hover:
  ``vehicle_thrust_setpoint`` -xyz[2], else ``actuator_controls_0`` control[3].
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.flightlog.impact import boot_rate, find_impact
from gyrodenoise.flightlog.model import AFTER_IMPACT, FlightEvidence, Segment, Throttle

SEGMENT_KINDS = ("ground", "armed", "flying", AFTER_IMPACT, "hover")
GROUND, ARMED, FLYING = 0, 1, 2
_STATE_NAMES = ("ground", "armed", "flying")

HOVER_WINDOW_S = 2.0
HOVER_STD = 0.03
#: hover: the body rate, averaged over this (s) per axis, stays below ...
HOVER_RATE_SMOOTH_S = 0.25
#: ... this (deg/s) -- a motor failure with the throttle steady swings far beyond it
HOVER_RATE_DPS = 60.0
HOVER_MIN_S = 3.0
FLYING_THROTTLE = 0.2
REBOOT_STEP_S = 0.5

EV_ARMED, EV_DISARMED, EV_LAND_COMPLETE, EV_NOT_LANDED = 10, 11, 18, 28
MAV_STATE_ACTIVE = 4
MAV_SAFETY_ARMED = 128
COPTER_TYPES = {2, 3, 4, 13, 14, 15, 29}     # quad, coaxial, heli, hexa, octo, tri, dodeca
PX4_ARMING_STATE_ARMED = 2


def flight_segments(log, autopilot=None):
    """(segments, note) of a :class:`~gyrodenoise.flightlog.model.FlightLog`, boot by boot.

    ``segments``: list of :class:`~gyrodenoise.flightlog.model.Segment` (``kind``
    ``ground``/``armed``/``flying``/``hover``, ``start_s``, ``end_s``, ``session``: see the
    module doc; ``hover`` ones lie inside ``flying`` ones), each boot's on its own time axis; ``note``: which evidence gave them, or --
    with an empty list -- what was looked for when the log holds none. ``autopilot``
    (a strategy of :mod:`gyrodenoise.flightlog.autopilots`, or None) decides how a
    telemetry log's ``system_status`` is read."""
    out, notes, missing, hovers = [], [], [], False
    for boot in range(max(1, len(log.boots))):
        got = log.format.flight_evidence(log, boot, autopilot)
        if isinstance(got, str):
            missing.append(got)
            continue
        segs = _runs(got.time_s, got.state, np.full(len(got.time_s), boot))
        rate = boot_rate(log, boot)
        segs = _split_at_impacts(log, segs, rate)
        hov = _hover(segs, got.throttle, rate) if got.throttle is not None else []
        hovers |= bool(hov)
        if got.note not in notes:
            notes.append(got.note)
        for seg in segs:                 # log order; each hover entry after its flying segment
            out.append(seg)
            if seg.kind == "flying":
                out += [h for parent, h in hov if parent is seg]
    if not notes:
        return [], missing[0] if missing else "no flight evidence in the log"
    note = "; ".join(notes)
    if hovers:
        note += (f"; hover: throttle std over {HOVER_WINDOW_S:g} s below {HOVER_STD:g} of full "
                 f"throttle and the body rate (mean over {HOVER_RATE_SMOOTH_S:g} s) below "
                 f"{HOVER_RATE_DPS:g} deg/s for at least {HOVER_MIN_S:g} s")
    for seg in out:
        if seg.impact is not None:
            note += f"; boot {seg.session}: {seg.impact.reason}: the flight ends there (after impact)"
    if len(log.boots) > 1:
        note += f"; {len(log.boots)} boot sessions, each on its own boot time (numbered in file order)"
        if missing:
            note += f"; {len(missing)} without flight evidence"
    return out, note


def segment_mask(time_s, segments, kind, session=None):
    """Boolean array: True where ``time_s`` lies in a segment of ``kind`` (start and end
    included) -- and, given ``session`` (each sample's boot session, an int array like
    ``time_s``: :meth:`gyrodenoise.flightlog.model.FlightLog.boot_of`), in that segment's session. ``kind`` "flying"
    covers the hover stretches too (they lie inside)."""
    t = np.asarray(time_s, dtype=np.float64)
    mask = np.zeros(t.shape, dtype=bool)
    for s in segments:
        if s.kind == kind:
            mask |= s.contains(t, session)
    return mask


def flying_time_s(segments):
    """Seconds in the air: the summed length of the ``flying`` segments (float)."""
    return round(float(sum(s.duration_s for s in segments if s.kind == "flying")), 3)


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
            out.append(Segment(_STATE_NAMES[int(state[a])], round(float(t[a]), 6), round(float(end), 6),
                               int(sess[a])))
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


def _split_at_impacts(log, segs, rate):
    """``segs`` with each ``flying`` segment that holds an impact
    (:func:`gyrodenoise.flightlog.impact.find_impact`) cut there: ``flying`` up to the
    impact, ``after impact`` (the impact attached) from it to the segment's end."""
    out = []
    for s in segs:
        hit = find_impact(log, s, rate) if s.kind == "flying" and rate is not None else None
        if hit is None or not s.start_s < hit.time_s < s.end_s:
            out.append(s)
            continue
        t = round(float(hit.time_s), 6)
        out += [Segment("flying", s.start_s, t, s.session), Segment(AFTER_IMPACT, t, s.end_s, s.session, impact=hit)]
    return out


def _rate_unsteady(rate):
    """(time_s, bool per sample): the body rate, averaged per axis over
    :data:`HOVER_RATE_SMOOTH_S` (motor noise out), above :data:`HOVER_RATE_DPS`."""
    t, xyz, _ = rate
    c = np.vstack([np.zeros((1, 3)), np.cumsum(xyz, axis=0)])
    lo = np.searchsorted(t, t - HOVER_RATE_SMOOTH_S / 2, side="left")
    hi = np.searchsorted(t, t + HOVER_RATE_SMOOTH_S / 2, side="right")
    mean = (c[hi] - c[lo]) / (hi - lo)[:, None]
    return t, np.sqrt(np.sum(mean * mean, axis=1)) > HOVER_RATE_DPS


def _hover(segs, throttle, rate=None):
    """[(its flying segment, hover segment)] inside the flying ones (of one boot) from
    ``throttle`` (:class:`Throttle`) and, where the boot has a gyro, the body ``rate``
    (:func:`gyrodenoise.flightlog.impact.boot_rate`): a window is steady when both are."""
    tt, thr = throttle.time_s, throttle.value
    ok = np.isfinite(tt) & np.isfinite(thr)
    tt, thr = np.asarray(tt, np.float64)[ok], np.asarray(thr, np.float64)[ok]
    if rate is not None:
        rt, bad = _rate_unsteady(rate)
        n_bad = np.concatenate([[0], np.cumsum(bad)])
    out = []
    for s in segs:
        if s.kind != "flying":
            continue
        sel = s.contains(tt)
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
        if rate is not None:                                     # no unsteady rate sample in the window
            a = np.searchsorted(rt, t, side="left")
            b = np.searchsorted(rt, t + HOVER_WINDOW_S, side="right")
            ok &= n_bad[b] == n_bad[a]
        cover = np.zeros(len(t) + 1, np.int64)                   # samples inside a steady window
        np.add.at(cover, lo[ok], 1)
        np.add.at(cover, hi[ok], -1)
        steady = np.cumsum(cover[:-1]) > 0
        edges = np.diff(np.concatenate([[0], steady.astype(np.int8), [0]]))
        for i, j in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1):
            if t[j] - t[i] >= HOVER_MIN_S:       # from the first to the last steady sample
                out.append((s, Segment("hover", round(float(t[i]), 6), round(float(t[j]), 6), s.session)))
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
def _df_throttle(log, boot):
    """(time_s, throttle 0..1, where from) or None."""
    ctun = log.boot_messages("CTUN", boot)
    if ctun is not None and "ThO" in ctun:
        return ctun["time_s"], ctun["ThO"].astype(np.float64), "CTUN.ThO"
    if ctun is not None and "ThrOut" in ctun:
        return ctun["time_s"], ctun["ThrOut"].astype(np.float64) / 1000.0, "CTUN.ThrOut/1000"
    rcou = log.boot_messages("RCOU", boot)
    if rcou is not None:
        cols = [c for c in ("C1", "C2", "C3", "C4") if c in rcou] or \
               [c for c in ("Ch1", "Ch2", "Ch3", "Ch4") if c in rcou]
        if cols:
            pwm = np.mean([rcou[c].astype(np.float64) for c in cols], axis=0)
            return rcou["time_s"], np.clip((pwm - 1000.0) / 1000.0, 0, 1), f"RCOU {'/'.join(cols)}"
    return None


#: GPS/airspeed evidence: in the air above this speed (m/s) ...
FLYING_SPEED_M_S = 3.0
#: ... and this height (m) above the first 3-D fix (or GPS RelAlt)
FLYING_HEIGHT_M = 5.0
GPS_3D_FIX = 3


def _df_motion(log, boot):
    """(time_s, in the air 0/1, the evidence named) from GPS ground speed and height
    (``GPS.Spd``; ``GPS.RelAlt`` where logged, else ``GPS.Alt`` above the median of the
    first 10 samples with a 3-D fix) and airspeed (``ARSP.Airspeed``, where faster):
    in the air over each stretch above :data:`FLYING_HEIGHT_M` in which the speed
    exceeds :data:`FLYING_SPEED_M_S` (:func:`_height_runs_moving`); None without a GPS
    height and speed."""
    gps = log.boot_messages("GPS", boot)
    if gps is None or "Spd" not in gps or not ({"RelAlt", "Alt"} & gps.keys()):
        return None
    t = np.asarray(gps["time_s"], dtype=np.float64)
    fix = np.asarray(gps["Status"]) >= GPS_3D_FIX if "Status" in gps else np.ones(len(t), bool)
    fix &= np.isfinite(t)
    if fix.sum() < 2:
        return None
    t = t[fix]
    speed = np.asarray(gps["Spd"], dtype=np.float64)[fix]
    if "RelAlt" in gps:
        height, hname = np.asarray(gps["RelAlt"], dtype=np.float64)[fix], "GPS.RelAlt"
    else:
        alt = np.asarray(gps["Alt"], dtype=np.float64)[fix]
        height, hname = alt - np.median(alt[:10]), "GPS.Alt above the first fix"
    what = f"{hname} > {FLYING_HEIGHT_M:g} m in a stretch whose GPS.Spd exceeds {FLYING_SPEED_M_S:g} m/s"
    arsp = log.boot_messages("ARSP", boot)
    if arsp is not None and "Airspeed" in arsp and len(arsp["time_s"]) > 1:
        ta, va = _sorted(np.asarray(arsp["time_s"], np.float64), np.asarray(arsp["Airspeed"], np.float64))
        if len(ta) > 1:
            speed = np.maximum(speed, np.interp(t, ta, va, left=0.0, right=0.0))
            what = (f"{hname} > {FLYING_HEIGHT_M:g} m in a stretch whose GPS.Spd or ARSP.Airspeed exceeds "
                    f"{FLYING_SPEED_M_S:g} m/s")
    return t, _height_runs_moving(height, speed), what


def _height_runs_moving(height, speed):
    """In the air (0/1 per sample): each run of samples above :data:`FLYING_HEIGHT_M`
    in which the speed exceeds :data:`FLYING_SPEED_M_S` at least once (a hover or a
    slow descent inside a flight stays in the air; a GPS height offset on the ground,
    never moving, does not fly; a taxi at 0 m does not either)."""
    up = np.asarray(height, dtype=np.float64) > FLYING_HEIGHT_M
    fast = np.asarray(speed, dtype=np.float64) > FLYING_SPEED_M_S
    air = np.zeros(len(up), np.int64)
    edges = np.diff(np.concatenate([[0], up.astype(np.int8), [0]]))
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
        if fast[a:b].any():
            air[a:b] = 1
    return air


def _df_vehicle(log, boot):
    msg = log.boot_messages("MSG", boot)
    if msg is None:
        return None
    for text in msg["Message"].tolist():
        for name in ("ArduSub", "ArduRover", "Rover", "ArduPlane", "ArduCopter", "APM:Copter", "APM:Plane"):
            if text.startswith(name):
                return name
    return None


def dataflash_evidence(log, boot, looked_for) -> FlightEvidence | str:
    """The flight evidence of boot ``boot`` of a DataFlash log (the module doc)."""
    ev = log.boot_messages("EV", boot)
    arm = log.boot_messages("ARM", boot)
    thr = _df_throttle(log, boot)
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
    motion = _df_motion(log, boot)
    if not len(at) and thr is None and motion is None:
        return f"no flight evidence in the log (looked for {looked_for})"
    clock = None
    for name in ("CTUN", "RCOU", "ATT", "IMU", "BARO"):
        m = log.boot_messages(name, boot)
        if m is not None:
            clock = m["time_s"]
            break
    n_land = int(np.isin(lv, (0, 1)).sum()) if len(lv) else 0
    has_land_events = ev is not None and np.isin(ev["Id"], (EV_LAND_COMPLETE, EV_NOT_LANDED)).any()
    if (has_land_events and n_land) or thr is not None:
        motion = None                  # GPS/airspeed only where neither land events nor throttle tell
    t = _timeline(clock, at, lt, thr[0] if thr is not None else None,
                  motion[0] if motion is not None else None)
    vehicle = _df_vehicle(log, boot)
    never_flies = vehicle in ("ArduSub", "ArduRover", "Rover")
    notes = []
    if len(at):
        order = np.argsort(at, kind="stable")
        armed = _step(t, at, av, initial=1 - int(av[order][0]))
        notes.append("armed from ARM/EV" + (" (armed at the log's start: its first record is a disarm)"
                                            if av[order][0] == 0 else ""))
    else:
        armed = None
    if never_flies:
        air = np.zeros(len(t), np.int64)
        notes.append(f"{vehicle}: never flying")
        alone = "the vehicle type"
    elif has_land_events and n_land:
        order = np.argsort(lt, kind="stable")
        first_land = lv[order][0]
        first_id = ev["Id"][np.isin(ev["Id"], (EV_ARMED, EV_DISARMED, EV_LAND_COMPLETE, EV_NOT_LANDED))]
        init = 1 if (first_land == 0 and int(first_id[0]) == EV_LAND_COMPLETE) else 0
        air = _step(t, lt, lv, initial=init)
        notes.append("in the air from EV NOT_LANDED/LAND_COMPLETE")
        alone = "the land events"
    elif thr is not None:
        tv = np.interp(t, *_sorted(thr[0], thr[1]))
        air = (tv > FLYING_THROTTLE).astype(np.int64)
        notes.append(f"in the air where {thr[2]} > {FLYING_THROTTLE:g} (no land events)")
        alone = "the throttle"
    elif motion is not None:
        air = _step(t, motion[0], motion[1], initial=0)
        notes.append(f"in the air from {motion[2]} (no land events nor throttle)")
        alone = "GPS/airspeed"
    else:
        air = np.zeros(len(t), np.int64)
        notes.append("no land events nor throttle: armed stretches not split into flying")
        alone = "nothing"
    if armed is None:
        state = np.where(air == 1, FLYING, GROUND)
        notes.insert(0, f"no ARM/EV arming record: ground/flying from {alone} alone")
    else:
        state = np.where(armed == 1, np.where(air == 1, FLYING, ARMED), GROUND)
    throttle = Throttle(thr[0], thr[1], thr[2]) if thr is not None else None
    return FlightEvidence(t, state, throttle, "DataFlash: " + "; ".join(notes))


def _sorted(t, v):
    ok = np.isfinite(t) & np.isfinite(v)
    order = np.argsort(t[ok], kind="stable")
    return t[ok][order], v[ok][order]


# --------------------------------------------------------------------- tlog
def tlog_evidence(log, boot, autopilot, looked_for) -> FlightEvidence | str:
    """The flight evidence of boot ``boot`` of a telemetry log (the module doc)."""
    from gyrodenoise.flightlog.autopilots import from_mav_autopilot
    hb = log.boot_messages("HEARTBEAT", boot)
    if hb is None or not len(hb["time_s"]):
        return f"no flight evidence in the log (looked for {looked_for})"
    veh = (hb["autopilot"] != 8) & (hb["type"] != 6) & np.isfinite(hb["time_s"])
    if not veh.any():
        return (f"no vehicle HEARTBEAT with a boot time (only ground stations', or no message "
                f"with time_boot_ms to place them; looked for {looked_for})")
    ids, counts = np.unique(hb["sysid"][veh], return_counts=True)
    sysid = int(ids[np.argmax(counts)])
    veh &= hb["sysid"] == sysid
    if (veh & (hb["compid"] == 1)).any():
        veh &= hb["compid"] == 1
    t = hb["time_s"][veh]
    armed = (hb["base_mode"][veh] & MAV_SAFETY_ARMED) != 0
    ap = autopilot or from_mav_autopilot(int(np.bincount(hb["autopilot"][veh]).argmax()))
    vtype = int(np.bincount(hb["type"][veh]).argmax())
    ess = log.boot_messages("EXTENDED_SYS_STATE", boot)
    if ess is not None:
        ess_sel = (ess["sysid"] == sysid) & np.isfinite(ess["time_s"])
        ess = None if not ess_sel.any() else (ess["record"][ess_sel], ess["landed_state"][ess_sel])
    if ess is not None:         # in file order: boot times of several sessions overlap
        air = _step(hb["record"][veh], ess[0], np.isin(ess[1], (2, 3, 4)).astype(np.int64), initial=0) == 1
        how = "in the air from EXTENDED_SYS_STATE.landed_state"
    elif ap.air_from_system_status(vtype):
        ss = hb["system_status"][veh]
        air = _forward_fill(np.where(ss == MAV_STATE_ACTIVE, 1, np.where(np.isin(ss, (5, 6)), -1, 0))) == 1
        how = ("in the air where system_status is ACTIVE (ArduPilot multicopter; CRITICAL/EMERGENCY "
               "keep the state before)")
    elif vtype not in NEVER_FLYING_TYPES and (motion := _tlog_motion(log, boot, sysid)) is not None:
        air = _step(t, motion[0], motion[1], initial=0) == 1
        how = (f"in the air from {motion[2]} (no EXTENDED_SYS_STATE, and the vehicle (autopilot {ap.name}, "
               f"type {vtype}) does not report landing in system_status)")
    else:
        air = np.zeros(len(t), bool)
        how = (f"not split into flying: no EXTENDED_SYS_STATE and the vehicle (autopilot {ap.name}, "
               f"type {vtype}) does not report landing in system_status"
               + ("" if vtype in NEVER_FLYING_TYPES else ", nor GPS height and speed"))
    state = np.where(armed, np.where(air, FLYING, ARMED), GROUND)
    throttle = None
    vfr = log.boot_messages("VFR_HUD", boot)
    if vfr is not None and (vfr["sysid"] == sysid).any():
        s = vfr["sysid"] == sysid
        throttle = Throttle(vfr["time_s"][s], vfr["throttle"][s].astype(np.float64) / 100.0, "VFR_HUD.throttle")
    else:
        so = log.boot_messages("SERVO_OUTPUT_RAW", boot)
        if so is not None and (so["sysid"] == sysid).any():
            s = so["sysid"] == sysid
            pwm = np.mean([so[f"servo{i}_raw"][s].astype(np.float64) for i in range(1, 5)], axis=0)
            throttle = Throttle(so["time_s"][s], np.clip((pwm - 1000.0) / 1000.0, 0, 1), "SERVO_OUTPUT_RAW")
    return FlightEvidence(t, state, throttle,
                          f"telemetry log: HEARTBEAT of system {sysid} (armed bit of base_mode); {how}")


#: MAV_TYPE of vehicles that never fly: ground rover, surface boat, submarine
NEVER_FLYING_TYPES = {10, 11, 12}


def _tlog_motion(log, boot, sysid):
    """(time_s, in the air 0/1, the evidence named) of a telemetry log's system ``sysid``
    from its height (``GLOBAL_POSITION_INT.relative_alt``) and speed (``VFR_HUD``
    groundspeed or airspeed, the faster): the rule of :func:`_df_motion`; None without both."""
    gp = log.boot_messages("GLOBAL_POSITION_INT", boot)
    vfr = log.boot_messages("VFR_HUD", boot)
    if gp is None or vfr is None:
        return None
    g, v = gp["sysid"] == sysid, vfr["sysid"] == sysid
    if g.sum() < 2 or v.sum() < 2:
        return None
    t = np.asarray(gp["time_s"], dtype=np.float64)[g]
    height = np.asarray(gp["relative_alt"], dtype=np.float64)[g] / 1000.0
    tv = np.asarray(vfr["time_s"], dtype=np.float64)[v]
    speed = np.maximum(np.asarray(vfr["groundspeed"], dtype=np.float64)[v],
                       np.asarray(vfr["airspeed"], dtype=np.float64)[v])
    ts, vs = _sorted(tv, speed)
    ok = np.isfinite(t)
    if len(ts) < 2 or ok.sum() < 2:
        return None
    t, height = t[ok], height[ok]
    return t, _height_runs_moving(height, np.interp(t, ts, vs)), (
        f"GLOBAL_POSITION_INT.relative_alt > {FLYING_HEIGHT_M:g} m in a stretch whose VFR_HUD "
        f"groundspeed/airspeed exceeds {FLYING_SPEED_M_S:g} m/s")


# --------------------------------------------------------------------- ULog
def ulog_evidence(log, looked_for) -> FlightEvidence | str:
    """The flight evidence of a ULog (one boot; the module doc)."""
    vs = log.messages("vehicle_status")
    aa = log.messages("actuator_armed")
    ld = log.messages("vehicle_land_detected")
    if vs is None and aa is None:
        return f"no flight evidence in the log (looked for {looked_for})"
    ends = [m["time_s"][-1] for m in (vs, aa, ld) if m is not None and len(m["time_s"])]
    for name in ("sensor_combined", "vehicle_angular_velocity"):
        m = log.messages(name)
        if m is not None and len(m["time_s"]):
            ends.append(m["time_s"][-1])
    span = [log.boots[0].start_s, max(ends)]
    if vs is not None and "arming_state" in vs:
        at, av, how = vs["time_s"], (vs["arming_state"] == PX4_ARMING_STATE_ARMED).astype(np.int64), \
            "vehicle_status.arming_state"
    elif aa is not None:
        at, av, how = aa["time_s"], (aa["armed"] != 0).astype(np.int64), "actuator_armed.armed"
    else:
        return f"no flight evidence in the log (looked for {looked_for})"
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
    ts = log.messages("vehicle_thrust_setpoint")
    if ts is not None and "xyz[2]" in ts:
        throttle = Throttle(ts["time_s"], -ts["xyz[2]"].astype(np.float64), "vehicle_thrust_setpoint.xyz[2]")
    else:
        ac = log.messages("actuator_controls_0")
        if ac is not None and "control[3]" in ac:
            throttle = Throttle(ac["time_s"], ac["control[3]"].astype(np.float64), "actuator_controls_0.control[3]")
    return FlightEvidence(t, state, throttle, "ULog: armed from " + how)
