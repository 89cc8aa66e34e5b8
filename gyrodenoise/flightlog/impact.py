"""A crash found in a flight's own evidence: where the flight ends, so that what the
vehicle recorded after hitting the ground stays out of the verdicts.

:func:`find_impact` looks, in one ``flying`` segment of one boot, for

1. **the rate jump** -- the body rate (the boot's first gyro stream with a known unit,
   |rate| over the three axes, deg/s) exceeding :data:`IMPACT_RATE_FACTOR` times the
   flight's own envelope (the 99th percentile of |rate| over the segment up to
   :data:`IMPACT_WINDOW_S` before the jump) and at least :data:`IMPACT_RATE_MIN_DPS`;
2. **the accelerometer spike** -- where the log has an accelerometer
   (:meth:`LogFormat.accelerometer`) or clip counters (:meth:`LogFormat.vibration_levels`:
   ``VIBE.Clip``, ``clipping_0..2``, ``accel_clipping``), |accel| of at least
   :data:`IMPACT_ACCEL_M_S2` (3 g) or a clip counter rising (the accelerometer hit its
   range: a low-passed 25 Hz log can under-read the spike itself) within
   :data:`IMPACT_WINDOW_S` of the rate jump; a log with neither is judged on 1 and 3 alone;
3. **what follows** -- within :data:`IMPACT_CONFIRM_S` the vehicle is no longer flying
   (disarmed or landed: the segment ends), or it tumbled: its tilt (from the attitude,
   :meth:`LogFormat.attitude`) stays above :data:`TUMBLE_TILT_DEG` over the
   :data:`TUMBLE_HOLD_S` after the first second.

The impact's time is the first sample of the rate jump or of the spike, whichever is
earlier. A flip in acro flight (a rate jump with no spike, the vehicle upright after)
and a motor failure that the vehicle rides out are no impact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: the rate jump: |rate| above this many times the flight's 99th percentile ...
IMPACT_RATE_FACTOR = 4.0
#: ... and above this (deg/s)
IMPACT_RATE_MIN_DPS = 400.0
#: the accelerometer spike (m/s/s): 3 g
IMPACT_ACCEL_M_S2 = 3 * 9.80665
#: the spike must lie this close (s) to the rate jump
IMPACT_WINDOW_S = 1.0
#: disarm/landing or the tumble must follow within this (s)
IMPACT_CONFIRM_S = 5.0
#: a tumble: the tilt (deg from level) stays above this ...
TUMBLE_TILT_DEG = 60.0
#: ... over this long (s), from 1 s after the jump
TUMBLE_HOLD_S = 2.0


@dataclass(frozen=True)
class Impact:
    """A crash: at ``time_s`` of boot ``session``; ``rate_peak_deg_s`` against the
    flight's ``rate_envelope_deg_s`` (99th percentile) from ``rate_source``;
    ``accel_peak_m_s2`` (None: no accelerometer); ``confirmed_by``: what followed."""
    time_s: float
    session: int
    rate_peak_deg_s: float
    rate_envelope_deg_s: float
    rate_source: str
    accel_peak_m_s2: float | None
    confirmed_by: str
    clipped: bool = False

    @property
    def reason(self):
        accel = ("" if self.accel_peak_m_s2 is None else
                 f", accelerometer peak {self.accel_peak_m_s2:.0f} m/s/s") + (
            ", the accelerometer clipping" if self.clipped else "")
        return (f"impact at {self.time_s:.2f} s: body rate {self.rate_peak_deg_s:.0f} deg/s against the "
                f"flight's 99th percentile before it {self.rate_envelope_deg_s:.0f} deg/s ({self.rate_source}){accel}; "
                f"then {self.confirmed_by}")

    def to_fields(self):
        return {"time_s": round(self.time_s, 3), "session": self.session,
                "rate_peak_deg_s": round(self.rate_peak_deg_s, 1),
                "rate_envelope_deg_s": round(self.rate_envelope_deg_s, 1), "rate_source": self.rate_source,
                "accel_peak_m_s2": None if self.accel_peak_m_s2 is None else round(self.accel_peak_m_s2, 2),
                "clipped": self.clipped, "confirmed_by": self.confirmed_by, "reason": self.reason}


def boot_rate(log, boot):
    """(time_s, rate (n, 3) deg/s, stream name) of boot ``boot``'s first gyro stream
    with a known unit, time-ordered; None without one."""
    for s in log.gyro:
        if s.to_deg_s is None or not len(s.time_s):
            continue
        sel = log.boot_of(s.index) == boot if len(log.boots) > 1 else np.ones(len(s.time_s), bool)
        t = np.asarray(s.time_s, np.float64)[sel]
        xyz = np.asarray(s.raw, np.float64)[sel] * s.to_deg_s
        ok = np.isfinite(t) & np.isfinite(xyz).all(axis=1)
        if ok.sum() < 3:
            continue
        order = np.argsort(t[ok], kind="stable")
        return t[ok][order], xyz[ok][order], s.name
    return None


def _boot_rows(log, src, boot):
    """(time_s, rows) of an accelerometer/attitude dict in boot ``boot``, time-ordered."""
    t = np.asarray(src["time_s"], np.float64)
    sel = np.isfinite(t)
    if len(log.boots) > 1 and src.get("record") is not None:
        sel &= log.boot_of(src["record"]) == boot
    order = np.argsort(t[sel], kind="stable")
    return t[sel][order], np.flatnonzero(sel)[order]


def find_impact(log, segment, rate=None) -> Impact | None:
    """The :class:`Impact` inside ``segment`` (a ``flying``
    :class:`~gyrodenoise.flightlog.model.Segment`) of ``log``, or None (the module doc).
    ``rate``: :func:`boot_rate` of the segment's boot (read when not given)."""
    boot = segment.session or 0
    rate = boot_rate(log, boot) if rate is None else rate
    if rate is None:
        return None
    t, xyz, name = rate
    mag = np.sqrt(np.sum(xyz * xyz, axis=1))
    inside = (t >= segment.start_s) & (t <= segment.end_s)
    if inside.sum() < 10:
        return None
    tf, mf = t[inside], mag[inside]
    accel = log.format.accelerometer(log)
    if accel is not None:
        ta, rows = _boot_rows(log, accel, boot)
        amag = np.sqrt(np.sum(np.asarray(accel["xyz"], np.float64)[rows] ** 2, axis=1))
    att = log.format.attitude(log)
    clips = _clip_times(log, boot)
    cand = np.flatnonzero(mf > IMPACT_RATE_MIN_DPS)
    if len(cand):                                  # the first sample of each burst above the floor
        cand = cand[np.concatenate([[True], np.diff(tf[cand]) > IMPACT_WINDOW_S])]
    for i in cand:
        t_jump = float(tf[i])
        before = mf[tf < t_jump - IMPACT_WINDOW_S]
        if len(before) < 10:
            continue
        envelope = float(np.percentile(before, 99))
        if mf[i] <= IMPACT_RATE_FACTOR * envelope:
            continue
        near = (tf >= t_jump - IMPACT_WINDOW_S) & (tf <= t_jump + IMPACT_WINDOW_S)
        peak = float(mf[near].max())
        t_imp, a_peak, clipped = t_jump, None, False
        if clips is not None:
            near_clip = clips[(clips >= t_jump - IMPACT_WINDOW_S) & (clips <= t_jump + IMPACT_WINDOW_S)]
            clipped = len(near_clip) > 0
        if accel is not None:
            w = (ta >= t_jump - IMPACT_WINDOW_S) & (ta <= t_jump + IMPACT_WINDOW_S)
            spike = w & (amag >= IMPACT_ACCEL_M_S2)
            a_peak = float(amag[w].max()) if w.any() else None
            if spike.any():
                t_imp = min(t_jump, float(ta[spike][0]))
            elif not clipped:
                continue
        elif clips is not None and not clipped:
            continue
        confirmed = _confirmed(log, att, boot, segment, t_imp)
        if confirmed:
            return Impact(t_imp, boot, peak, envelope, name, a_peak, confirmed, clipped)
    return None


def _clip_times(log, boot):
    """The times (sorted) at which any of boot ``boot``'s accelerometer clip counters
    rose; None when the log has no clip counter."""
    lv = log.format.vibration_levels(log)
    if lv is None or not lv.get("clips"):
        return None
    t = np.asarray(lv["time_s"], np.float64)
    sel = np.isfinite(t)
    if len(log.boots) > 1 and lv.get("record") is not None:
        sel &= log.boot_of(lv["record"]) == boot
    inst = np.asarray(lv.get("instance", np.zeros(len(t), np.int64)))
    rises = []
    for col in lv["clips"].values():
        c = np.asarray(col, np.float64)
        for k in np.unique(inst[sel]):                   # a counter per IMU instance
            m = sel & (inst == k)
            order = np.argsort(t[m], kind="stable")
            tk, ck = t[m][order], c[m][order]
            rises.append(tk[1:][np.diff(ck) > 0])
    return np.sort(np.concatenate(rises)) if rises else np.zeros(0)


def _confirmed(log, att, boot, segment, t_imp):
    """What follows an impact at ``t_imp`` (a line), or "" (nothing: no impact)."""
    if segment.end_s - t_imp <= IMPACT_CONFIRM_S:
        return f"no longer flying {segment.end_s - t_imp:.1f} s later (disarmed or landed)"
    if att is None:
        return ""
    ta, rows = _boot_rows(log, att, boot)
    r = np.radians(np.asarray(att["roll_deg"], np.float64)[rows])
    p = np.radians(np.asarray(att["pitch_deg"], np.float64)[rows])
    tilt = np.degrees(np.arccos(np.clip(np.cos(r) * np.cos(p), -1.0, 1.0)))
    hold = (ta >= t_imp + 1.0) & (ta <= t_imp + 1.0 + TUMBLE_HOLD_S)
    if hold.sum() >= 2 and tilt[hold].min() > TUMBLE_TILT_DEG:
        return (f"a tumble: tilt above {TUMBLE_TILT_DEG:g} deg ({att['source']}) from "
                f"{t_imp + 1.0:.1f} to {t_imp + 1.0 + TUMBLE_HOLD_S:.1f} s")
    return ""


# ----------------------------------------------------------- attitude, per format
def dataflash_attitude(log):
    """Roll and pitch (deg) of DataFlash ``ATT``; None without it."""
    m = log.messages("ATT")
    if m is None or "Roll" not in m or "Pitch" not in m:
        return None
    return {"source": "ATT.Roll/Pitch", "time_s": m["time_s"], "record": m.get("record"),
            "roll_deg": m["Roll"].astype(np.float64), "pitch_deg": m["Pitch"].astype(np.float64)}


def ulog_attitude(log):
    """Roll and pitch (deg) from PX4 ``vehicle_attitude.q`` (w, x, y, z); None without it."""
    m = log.messages("vehicle_attitude")
    cols = [f"q[{i}]" for i in range(4)]
    if m is None or not all(c in m for c in cols):
        return None
    w, x, y, z = (m[c].astype(np.float64) for c in cols)
    roll = np.degrees(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)))
    pitch = np.degrees(np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0)))
    return {"source": "vehicle_attitude.q", "time_s": m["time_s"], "record": None,
            "roll_deg": roll, "pitch_deg": pitch}
