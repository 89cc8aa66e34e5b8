"""The flight review's time series beside the gyro: motor outputs, throttle, vibration
levels and clipping, and the events, mode changes and failsafes to mark on every time
axis (:func:`time_views`).

What a tuner opens first in PX4 Flight Review, ArduPilot's UAV Log Viewer or
PIDtoolbox, read from a :class:`gyrodenoise.flightlog.model.FlightLog`:

* motors -- the outputs driving the motors as the autopilot logs them (ArduPilot
  ``RCOU`` C1..Cn of the ``SERVOn_FUNCTION`` motors, PX4 ``actuator_motors`` /
  ``actuator_outputs``, Betaflight ``motor[0..3]``): the strategy's
  :meth:`~gyrodenoise.flightlog.autopilots.Autopilot.motor_channels`;
* throttle -- the throttle the flight segments use (the format's flight evidence:
  ``CTUN.ThO``, ``vehicle_thrust_setpoint``, ``setpoint[3]``), 0..1;
* RC input and battery -- the pilot's sticks (ArduPilot ``RCIN``, ``RC_CHANNELS``; PX4
  ``input_rc``; Betaflight ``rcCommand``) and the battery's voltage and current (``BAT``,
  ``CURR``, ``SYS_STATUS``; ``battery_status``; ``vbatLatest``, ``amperageLatest``):
  the strategy's ``rc_input`` and ``battery_channels``;
* vibration and clipping -- the levels of the vibration review
  (:mod:`gyrodenoise.flightlog.vibration`: ``VIBE``, ``VIBRATION``,
  ``vehicle_imu_status``) with its cited warn/fail thresholds drawn, and the clip
  counters as they run;
* markers -- the log's events and messages, its mode changes (named by the strategy's
  :meth:`~gyrodenoise.flightlog.autopilots.Autopilot.mode_names`) and its failsafes and
  errors (:meth:`~gyrodenoise.flightlog.autopilots.Autopilot.failsafe_events`).

Everything is plain arrays on each boot's own time axis (``boot`` per sample); the
HTML report (:mod:`gyrodenoise.flightlog.html_report`) draws them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: the kinds of a marker, in drawing order
EVENT, MODE, FAILSAFE = "event", "mode", "failsafe"


@dataclass
class Channels:
    """Columns logged together: ``columns`` ``{label: (n,) values}`` at ``time_s`` (boot
    ``boot`` per row), their ``unit`` and ``source`` (the message and fields)."""
    source: str
    unit: str
    time_s: np.ndarray
    columns: dict
    boot: np.ndarray | None = None
    note: str = ""

    def boots(self):
        return np.zeros(len(self.time_s), np.int64) if self.boot is None else np.asarray(self.boot)


@dataclass(frozen=True)
class Threshold:
    """A horizontal line: ``value`` in the panel's unit, ``level`` (warn/fail), where it comes from."""
    value: float
    level: str
    label: str


@dataclass
class Panel:
    """One time plot: ``channels`` and the ``thresholds`` drawn over them."""
    key: str
    title: str
    channels: Channels
    thresholds: list = field(default_factory=list)


@dataclass(frozen=True)
class Marker:
    """A vertical line on every time axis: ``kind`` (:data:`EVENT`, :data:`MODE`,
    :data:`FAILSAFE`) at ``time_s`` of boot ``boot``."""
    time_s: float
    boot: int
    kind: str
    text: str


@dataclass
class TimeViews:
    """The time panels of a log, the markers and, per missing panel, why it is missing."""
    panels: list
    markers: list
    missing: dict = field(default_factory=dict)

    def panel(self, key):
        return next((p for p in self.panels if p.key == key), None)


@dataclass
class FlightViews:
    """What the HTML report draws beside the gyro: the time panels and markers, the
    frequency maps (:mod:`gyrodenoise.flightlog.heatmap`) and why a map is missing."""
    time: TimeViews
    maps: list
    map_notes: list
    #: the dynamic notch's centres as logged (the strategy's ``notch_centre_track``), or None
    notch_track: Channels | None = None


def flight_views(log, stages=None) -> FlightViews:
    """The :class:`FlightViews` of ``log``; ``stages``: the vehicle's filter chain
    (default: from the log's parameters) whose notches the maps draw."""
    from gyrodenoise.flightlog.heatmap import log_heatmaps
    views = time_views(log)
    thr = views.panel("throttle")
    maps, notes = log_heatmaps(log, thr.channels if thr is not None else None, stages)
    return FlightViews(views, maps, notes, log.parameters().autopilot.notch_centre_track(log))


def time_views(log, autopilot=None) -> TimeViews:
    """The :class:`TimeViews` of ``log`` (``autopilot``: its strategy, default the log's)."""
    ap = autopilot or log.parameters().autopilot
    panels, missing = [], {}
    motors = ap.motor_channels(log)
    if motors is not None and motors.columns:
        panels.append(Panel("motors", f"motor outputs [{motors.unit}] ({motors.source})", motors))
    else:
        missing["motors"] = f"no motor outputs in the log (looked for {ap.motors_looked_for})"
    thr = throttle_channels(log, ap)
    if thr is not None:
        panels.append(Panel("throttle", f"throttle [0..1] ({thr.source})", thr))
    else:
        missing["throttle"] = f"no throttle in the log (looked for {log.format.flight_looked_for})"
    rc = ap.rc_input(log)
    if rc is not None:
        panels.append(Panel("rc", f"RC input [{rc.unit}] ({rc.source})", rc))
    else:
        missing["rc"] = f"no RC input in the log (looked for {ap.rc_looked_for})"
    volts, amps = ap.battery_channels(log)
    for key, ch in (("battery voltage", volts), ("battery current", amps)):
        if ch is not None:
            panels.append(Panel(key, f"{key} [{ch.unit}] ({ch.source})", ch))
    if volts is None and amps is None:
        missing["battery"] = f"no battery voltage or current in the log (looked for {ap.battery_looked_for})"
    pid = ap.pid_terms(log)
    for axis, ch in pid:
        panels.append(Panel("pid", f"rate PID terms, {axis} [{ch.unit}] ({ch.source})", ch))
    if not pid:
        missing["pid"] = f"no rate controller terms in the log (looked for {ap.pid_looked_for})"
    vib, clip, why = vibration_channels(log, ap)
    panels += vib + ([clip] if clip is not None else [])
    if not vib and clip is None:
        missing["vibration"] = why
    return TimeViews(panels, markers(log, ap), missing)


def throttle_channels(log, autopilot):
    """The throttle (0..1) of every boot as the flight segments read it (the format's
    flight evidence), or None."""
    ts, vs, bs, source = [], [], [], None
    for b in range(max(1, len(log.boots))):
        ev = log.format.flight_evidence(log, b, autopilot)
        thr = getattr(ev, "throttle", None)
        if thr is None or not len(thr.time_s):
            continue
        ts.append(np.asarray(thr.time_s, np.float64))
        vs.append(np.asarray(thr.value, np.float64))
        bs.append(np.full(len(thr.time_s), b))
        source = source or thr.source
    if not ts:
        return None
    return Channels(source, "0..1", np.concatenate(ts), {"throttle": np.concatenate(vs)}, np.concatenate(bs))


def vibration_channels(log, autopilot):
    """([a levels panel per unit], clipping panel or None, why none) from the vibration
    review's source, named and judged as the autopilot fills it; the cited warn/fail
    thresholds (:data:`gyrodenoise.flightlog.vibration.THRESHOLDS`) drawn on the panel of
    the metrics they judge (ArduPilot's on VibeX/Y/Z, PX4 Flight Review's on the
    accelerometer metric only)."""
    from gyrodenoise.flightlog import vibration as vb
    levels = log.format.vibration_levels(log)
    if levels is None:
        why = f"no vibration levels in the log (looked for {log.format.vibration_looked_for})"
        panel = computed_vibration_panel(log)
        return ([panel] if panel is not None else []), None, why
    levels = autopilot.vibration_levels(levels)
    t = np.asarray(levels["time_s"], np.float64)
    boot = log.boot_of(levels["record"]) if levels.get("record") is not None and len(log.boots) > 1 else None
    inst = np.asarray(levels.get("instance", np.zeros(len(t), np.int64)))
    several = len(np.unique(inst)) > 1

    def split(cols):
        """One column per metric and instance (``VibeZ[1]``: the second IMU), NaN on other rows."""
        out = {}
        for name, v in cols.items():
            v = np.asarray(v, np.float64)
            for i in np.unique(inst):
                out[f"{name}[{i}]" if several else name] = np.where(inst == i, v, np.nan)
        return out
    th = vb.THRESHOLDS.get(levels.get("threshold") or "")
    judged = {k for k in levels.get("levels") or {} if vb.LEVEL_UNITS.get(k) == (th or {}).get("unit")}
    if th and levels.get("threshold") != "vibe_m_s2":          # one metric judged, not every m/s/s column
        judged = {k for k in judged if levels["threshold"].startswith(k)}
    panels = []
    by_unit = {}
    for k, v in (levels.get("levels") or {}).items():
        by_unit.setdefault(vb.LEVEL_UNITS.get(k, ""), {})[k] = v
    for unit, cols in by_unit.items():
        lines = [Threshold(th[k], k, f"{k} {th[k]:g} {th['unit']} on {', '.join(sorted(judged & set(cols)))} "
                                     f"({th['source']})") for k in ("warn", "fail")] \
            if th and judged & set(cols) else []
        panels.append(Panel("vibration", f"vibration levels [{unit or 'no unit'}] ({levels['source']}: "
                                         f"{', '.join(cols)})", Channels(levels["source"], unit, t, split(cols), boot),
                            lines))
    clip = None
    cl = split(levels.get("clips") or {})
    if cl:
        limit = vb.THRESHOLDS["clip_increase"]
        clip = Panel("clipping", f"accelerometer clipping, cumulative count ({levels['source']}); ArduPilot's "
                                 f"limit is per flight: low numbers (<{limit['fail']:g}) likely ok",
                     Channels(levels["source"], "count", t, cl, boot))
    return panels, clip, ""


def computed_vibration_panel(log):
    """A log without vibration levels: VIBE's levels computed from its accelerometer
    (:func:`gyrodenoise.flightlog.vibration.computed_vibe`), labelled as computed, with
    ArduPilot's thresholds only where the accelerometer is as fast as VIBE's input; or None."""
    from gyrodenoise.flightlog import vibration as vb
    accel = log.format.accelerometer(log)
    cv = vb.computed_vibe(accel)
    if cv is None:
        return None
    rec = accel.get("record")
    boot = None
    if rec is not None and len(log.boots) > 1:
        t_all = np.asarray(accel["time_s"], np.float64)
        keep = np.isin(t_all, cv["time_s"])
        boot = log.boot_of(np.asarray(rec)[keep])[:len(cv["time_s"])]
    th = vb.THRESHOLDS["vibe_m_s2"]
    lines = [Threshold(th[k], k, f"{k} {th[k]:g} {th['unit']} ({th['source']})") for k in ("warn", "fail")] \
        if cv["judged"] else []
    return Panel("vibration", f"vibration levels [m/s/s] ({cv['source']}, by gyrodenoise"
                              f"{'' if cv['judged'] else '; under-reads VIBE: no thresholds'})",
                 Channels(cv["source"], "m/s/s", cv["time_s"], cv["levels"], boot, cv["note"]), lines)


def markers(log, autopilot) -> list[Marker]:
    """Every event (named by the strategy's ``event_label``), mode change (``mode_names``)
    and failsafe or error (``failsafe_events``) of the log, in time order per boot."""
    out = [Marker(e.time_s, e.boot, EVENT, autopilot.event_label(e.text)) for e in log.events()]
    modes = log.modes()
    names = autopilot.mode_names(log) if modes else {}
    out += [Marker(m.time_s, m.boot, MODE, f"mode {m.mode}" + (f" {names[m.mode]}" if m.mode in names else ""))
            for m in modes]
    out += [Marker(e.time_s, e.boot, FAILSAFE, e.text) for e in autopilot.failsafe_events(log)]
    return sorted((m for m in out if np.isfinite(m.time_s)), key=lambda m: (m.boot, m.time_s))
