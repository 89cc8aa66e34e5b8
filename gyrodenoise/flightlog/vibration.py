"""Vibration review of a log over its flight segments, against the thresholds the
autopilot communities publish (:data:`THRESHOLDS`, one table with the source of each).

Sources, the first the log has:

* ArduPilot DataFlash ``VIBE`` -- ``VibeX/Y/Z`` (m/s/s: the standard deviation of the
  accelerometer, high-passed) and the clip counters ``Clip0..2`` (or ``Clip`` per IMU
  in ArduPilot 4.x, which logs one VIBE per IMU instance, field ``IMU``); cumulative
  counts: a segment's figure is their increase over it.
* Telemetry log ``VIBRATION`` -- from ArduPilot ``vibration_x/y/z`` (the same m/s/s
  levels as VIBE), ``clipping_0..2`` (cumulative); from PX4 (its strategy's
  ``vibration_levels``) x is the delta-angle coning metric, y the gyro vibration metric
  and z the accelerometer vibration metric of ``vehicle_imu_status`` (PX4's
  MavlinkStreamVibration), named and judged as those.
* PX4 ULog ``vehicle_imu_status`` (every instance) -- ``accel_vibration_metric``
  (m/s/s), ``gyro_vibration_metric`` (rad/s), ``delta_angle_coning_metric`` (rad^2),
  ``accel_clipping[0..2]`` (cumulative).

Beside those, where the log has an accelerometer stream, its band rms per segment
(``accel_band_rms_x/y/z``, :func:`_accel_figures`: the rms over 1 s windows of the
accelerometer between 20 Hz -- half the Nyquist frequency for a stream slower than
48 Hz -- and the Nyquist frequency, mean/p95/max over the windows), with no verdict:
no community threshold exists for it (ArduPilot's VIBE thresholds apply to VIBE,
computed on board on the raw accelerometer at its full rate; the logged accelerometer
is low-passed and sampled at 25-250 Hz, so its band rms under-reads motor vibration),
and the accelerometer spectrum over each segment (DataFlash ``IMU``
AccX/Y/Z of the first IMU, ULog ``sensor_combined.accelerometer_m_s2[*]``): the
dominant peaks of the summed x+y+z Welch PSD
(:func:`gyrodenoise.analysis.spectrum.welch_psd`, :func:`~gyrodenoise.analysis.spectrum.find_peaks`),
for information: no community threshold exists for them, so they carry no verdict.

Figures are computed over the ``flying`` segments (:mod:`gyrodenoise.flightlog.segments`)
by default (``"over": "flying"``); ``over="whole"`` (or a log with no flying segment,
said in the note) takes the whole log as one segment (``"over": "whole log"``).
A level's verdict judges its 95th percentile (the ArduPilot wiki asks for levels
*mostly* below 30 m/s/s; brief peaks are normal); ``warn`` at or above the first
threshold, ``fail`` at or above the second.
"""

from __future__ import annotations

import re

import numpy as np

from gyrodenoise.analysis.spectrum import find_peaks, welch_psd
from gyrodenoise.flightlog.model import AFTER_IMPACT, Segment

ARDUPILOT_VIBE_URL = "https://ardupilot.org/copter/docs/common-measuring-vibration.html"
FLIGHT_REVIEW_URL = "https://github.com/PX4/flight_review/blob/main/app/plot_app/configured_plots.py"

#: figure -> warn and fail thresholds (at or above), unit, source and what it says
THRESHOLDS = {
    "vibe_m_s2": {
        "warn": 30.0, "fail": 60.0, "unit": "m/s/s", "source": ARDUPILOT_VIBE_URL,
        "says": "Vibration levels below 30m/s/s are normally acceptable. Levels above 30m/s/s may have "
                "problems and levels above 60m/s/s nearly always have problems with position or altitude hold.",
    },
    "clip_increase": {
        "warn": 1, "fail": 100, "unit": "count", "source": ARDUPILOT_VIBE_URL,
        "says": "Ideally these should be zero for the whole flight but low numbers (<100) are likely ok "
                "especially if they occur during hard landings.",
    },
    "accel_vibration_metric_m_s2": {
        "warn": 4.905, "fail": 9.81, "unit": "m/s/s", "source": FLIGHT_REVIEW_URL,
        "says": "PX4 Flight Review 'Vibration Metrics' plot: green below 4.905 m/s^2 (0.5 g), orange to "
                "9.81 m/s^2 (1 g), red above.",
    },
}
VERDICTS = ("pass", "warn", "fail")
MAX_PEAKS = 3
PEAK_MIN_FREQ_HZ = 5.0
#: the accelerometer's band rms runs from here to the stream's Nyquist frequency (Hz) ...
ACCEL_BAND_LO_HZ = 20.0
#: ... or, where the Nyquist frequency is below 1.2 x that (a 25 Hz stream), from this share of it
ACCEL_BAND_LO_NYQ_SHARE = 0.5
#: the accelerometer's band rms is taken over windows of this length (s)
ACCEL_WINDOW_S = 1.0
#: unit of each level column
LEVEL_UNITS = {"VibeX": "m/s/s", "VibeY": "m/s/s", "VibeZ": "m/s/s", "vibration_x": "m/s/s",
               "vibration_y": "m/s/s", "vibration_z": "m/s/s", "accel_vibration_metric": "m/s/s",
               "gyro_vibration_metric": "rad/s", "delta_angle_coning_metric": "rad^2"}


def vibration_review(log, segments, over="flying"):
    """(result, note) of the vibration figures of a log read by
    :func:`gyrodenoise.flightlog.formats.read_log`, over the ``flying`` segments of
    ``segments`` (:func:`gyrodenoise.flightlog.segments.flight_segments`) or, with
    ``over="whole"``, the whole log.

    ``result``: ``{"source", "over": "flying"|"whole log", "thresholds", "segments":
    [{"kind", "start_s", "end_s", "figures": {...}, "accel_peaks": [...],
    "verdict"}], "verdict"}`` (JSON-able; see the module doc), or None when the log has
    none of the sources, with a note naming what was looked for. In a log of several
    boots a sample is in a segment when its boot is the segment's ``session`` too."""
    if over not in ("flying", "whole"):
        raise ValueError(f"over must be 'flying' or 'whole', not {over!r}")
    levels = log.format.vibration_levels(log)
    if levels is not None:
        levels = log.parameters().autopilot.vibration_levels(levels)
    accel = log.format.accelerometer(log)
    for src in (levels, accel):
        if src is not None:
            src["session"] = (log.boot_of(src["record"]) if len(log.boots) > 1 and src.get("record") is not None
                              else None)
    if levels is None and accel is None:
        return None, f"no vibration data in the log (looked for {log.format.vibration_looked_for})"
    note = ""
    spans = [s for s in segments if s.kind == "flying"] if over == "flying" else []
    over_out = "flying"
    if over == "whole" or not spans:
        if over == "flying":
            note = "no flying segment in the log: figures over the whole log; "
        spans = _whole_boots(log, levels, accel)
        over_out = "whole log"
    else:                     # shown, labelled, outside the verdict: what a crash left in the log
        spans = sorted(spans + [s for s in segments if s.kind == AFTER_IMPACT],
                       key=lambda s: (s.session or 0, s.start_s))
    out_segs = []
    for seg in spans:
        entry = {"kind": seg.kind, "start_s": round(float(seg.start_s), 3),
                 "end_s": round(float(seg.end_s), 3), "session": int(seg.session or 0),
                 "figures": {}, "accel_peaks": None}
        if levels is not None:
            entry["figures"] = _segment_figures(levels, seg)
        if accel is not None:
            entry["accel_peaks"] = _segment_peaks(accel, seg)
            entry["figures"].update(_accel_figures(accel, seg))
        entry["verdict"] = _worst(f.get("verdict") for f in entry["figures"].values())
        if seg.kind == AFTER_IMPACT:
            entry["in_verdict"] = False
            entry["note"] = f"after impact ({seg.impact.reason}): shown, not judged"
        out_segs.append(entry)
    src_name = levels["source"] if levels is not None else "accelerometer"
    used = {levels["threshold"], "clip_increase"} if levels is not None else set()
    result = {
        "source": src_name,
        "accel_source": accel["source"] if accel is not None else None,
        "over": over_out,
        "thresholds": {k: dict(v) for k, v in THRESHOLDS.items() if k in used},
        "segments": out_segs,
        "verdict": _worst(s["verdict"] for s in out_segs if s.get("in_verdict", True)),
    }
    after = sum(not s.get("in_verdict", True) for s in out_segs)
    if after:
        note += (f"{after} segment(s) after an impact shown but kept out of the verdict (what the crash "
                 f"did to the sensors says nothing about the vehicle's vibration); ")
    note += (f"{src_name} over {len(out_segs) - after} {over_out} segment(s); "
             f"levels judged on their 95th percentile, clipping on its increase")
    if levels is None:
        note += ("; no vibration level in the log: the accelerometer's band rms and spectra only, no verdict "
                 "(no published threshold for them)")
    return result, note


# ------------------------------------------------------------------- sources
# The sources, one reader per format (the format adapters' ``vibration_levels`` and
# ``accelerometer``): levels {"source", "threshold", "time_s", "record" (or None),
# "instance", "levels": {name: column}, "clips": {name: cumulative column}};
# accelerometer {"source", "time_s", "record", "xyz": (n, 3)}; or None.
def dataflash_levels(log):
    m = log.messages("VIBE")
    if m is None:
        return None
    inst = m["IMU"].astype(np.int64) if "IMU" in m else np.zeros(len(m["time_s"]), np.int64)
    return {"source": "VIBE", "threshold": "vibe_m_s2", "time_s": m["time_s"], "record": m["record"],
            "instance": inst, "levels": {c: m[c] for c in ("VibeX", "VibeY", "VibeZ") if c in m},
            "clips": {c: m[c] for c in m if re.fullmatch(r"Clip\d?", c)}}


def tlog_levels(log):
    m = log.messages("VIBRATION")
    if m is None:
        return None
    return {"source": "VIBRATION", "threshold": "vibe_m_s2", "time_s": m["time_s"], "record": m["record"],
            "instance": np.zeros(len(m["time_s"]), np.int64),
            "levels": {c: m[c] for c in ("vibration_x", "vibration_y", "vibration_z")},
            "clips": {c: m[c] for c in ("clipping_0", "clipping_1", "clipping_2")}}


def ulog_levels(log):
    parts = []
    k = 0
    while True:
        m = log.messages("vehicle_imu_status" + (f"[{k}]" if k else ""))
        if m is None or "accel_vibration_metric" not in m:
            break
        parts.append(m)
        k += 1
    if not parts:
        return None
    cat = {c: np.concatenate([p[c] for p in parts]) for c in parts[0] if all(c in p for p in parts)}
    inst = np.concatenate([np.full(len(p["time_s"]), i) for i, p in enumerate(parts)])
    lv = {c: cat[c] for c in ("accel_vibration_metric", "gyro_vibration_metric", "delta_angle_coning_metric")
          if c in cat}
    return {"source": "vehicle_imu_status", "threshold": "accel_vibration_metric_m_s2", "time_s": cat["time_s"],
            "instance": inst, "levels": lv,
            "clips": {c: cat[c] for c in cat if c.startswith("accel_clipping[")}}


def dataflash_accel(log):
    m = log.messages("IMU")
    if m is None or not all(c in m for c in ("AccX", "AccY", "AccZ")):
        return None
    sel = m["I"] == 0 if "I" in m else np.ones(len(m["time_s"]), bool)
    return {"source": "IMU.AccX/AccY/AccZ", "time_s": m["time_s"][sel], "record": m["record"][sel],
            "xyz": np.stack([m[c][sel] for c in ("AccX", "AccY", "AccZ")], 1).astype(np.float64)}


def ulog_accel(log):
    m = log.messages("sensor_combined")
    cols = [f"accelerometer_m_s2[{i}]" for i in range(3)]
    if m is None or not all(c in m for c in cols):
        return None
    return {"source": "sensor_combined.accelerometer_m_s2", "time_s": m["time_s"], "record": None,
            "xyz": np.stack([m[c] for c in cols], 1).astype(np.float64)}


# -------------------------------------------------- VIBE computed from the accelerometer
#: ArduPilot's vibration level (AP_InertialSensor, described in its header): the
#: accelerometer's "floor" is its first-order low-pass at 5 Hz; the level is the square
#: root of the first-order low-pass at 2 Hz of the squared difference, per axis, on every
#: raw sample at the sensor's rate
VIBE_FLOOR_HZ = 5.0
VIBE_FILTER_HZ = 2.0


def _lowpass1(x, dt, cutoff_hz, start):
    """First-order low-pass y += alpha (x - y), alpha = dt / (dt + 1 / (2 pi fc)) (the
    form of ArduPilot's LowPassFilter) per column of ``x`` (n, m), from state ``start``;
    ``dt`` per sample."""
    rc = 1.0 / (2.0 * np.pi * cutoff_hz)
    alpha = np.asarray(dt / (dt + rc), np.float64)
    from scipy.signal import lfilter
    y = np.empty_like(x)
    if np.ptp(alpha) < 1e-12 * max(1.0, float(alpha.max())):      # even steps: one IIR
        a = float(alpha[0])
        zi = (1.0 - a) * np.asarray(start, np.float64)
        for k in range(x.shape[1]):
            y[:, k] = lfilter([a], [1.0, -(1.0 - a)], x[:, k], zi=[zi[k]])[0]
        return y
    state = np.asarray(start, np.float64).copy()
    for i in range(len(x)):
        state += alpha[i] * (x[i] - state)
        y[i] = state
    return y


def vibe_levels(time_s, accel_m_s2):
    """ArduPilot's VIBE levels (m/s/s, per axis) computed from an accelerometer record
    (n, 3) at ``time_s``: ``sqrt(LP2(a - LP5(a)) ** 2)`` (:data:`VIBE_FLOOR_HZ`,
    :data:`VIBE_FILTER_HZ`), the filters started at the first samples' mean and
    mean square (no warm-up from zero). Equal to the logged VIBE only where the record
    is the raw accelerometer at its sensor rate: a logged, low-passed, slower
    accelerometer holds less of the vibration (see :func:`computed_vibe`)."""
    t = np.asarray(time_s, np.float64)
    a = np.asarray(accel_m_s2, np.float64)
    if len(t) < 2:
        return np.full_like(a, np.nan)
    dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
    dt = np.where(dt > 0, dt, np.median(np.diff(t)))
    head = a[:max(1, min(len(a), int(round(0.1 / float(np.median(dt))))))]
    floor = _lowpass1(a, dt, VIBE_FLOOR_HZ, head.mean(axis=0))
    sq = (a - floor) ** 2
    return np.sqrt(_lowpass1(sq, dt, VIBE_FILTER_HZ, ((head - head.mean(axis=0)) ** 2).mean(axis=0)))


#: a computed VIBE is judged against ArduPilot's thresholds only from an accelerometer at
#: least this fast (Hz): the sensor rate VIBE is computed at on board (1 kHz and up); a
#: logged IMU at 25-400 Hz after INS_ACCEL_FILTER under-reads it
VIBE_JUDGED_MIN_RATE_HZ = 1000.0


def computed_vibe(accel, rate_hz=None):
    """``{"time_s", "levels" {VibeX, VibeY, VibeZ}, "source", "judged", "note"}`` of
    :func:`vibe_levels` over an accelerometer source (``accelerometer(log)``'s dict), its
    gaps (over 5 median steps) restarting the filters, or None. ``judged``: whether the
    source is VIBE's own input -- the raw accelerometer (the source's ``"raw"``: true; the
    logged IMU/``sensor_combined``/``accSmooth`` streams are low-passed or averaged, so
    not) at :data:`VIBE_JUDGED_MIN_RATE_HZ` or more -- so that VIBE's thresholds apply."""
    if accel is None or len(accel["time_s"]) < 20:
        return None
    t = np.asarray(accel["time_s"], np.float64)
    a = np.asarray(accel["xyz"], np.float64)
    ok = np.isfinite(t) & np.isfinite(a).all(axis=1)
    t, a = t[ok], a[ok]
    if len(t) < 20:
        return None
    step = float(np.median(np.diff(t)))
    rate = rate_hz or (1.0 / step if step > 0 else None)
    if not rate:
        return None
    cuts = np.r_[0, np.flatnonzero(np.diff(t) > 5 * step) + 1, len(t)]
    out = np.full_like(a, np.nan)
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        if hi - lo >= 2:
            out[lo:hi] = vibe_levels(t[lo:hi], a[lo:hi])
    raw = bool(accel.get("raw", False))
    judged = raw and rate >= VIBE_JUDGED_MIN_RATE_HZ
    note = (f"computed by gyrodenoise from {accel['source']} at {rate:.4g} Hz with VIBE's definition "
            f"(sqrt of the {VIBE_FILTER_HZ:g} Hz low-pass of (accel - its {VIBE_FLOOR_HZ:g} Hz low-pass)^2)")
    if not judged:
        why = [w for w, bad in (("low-passed or averaged before it was logged", not raw),
                                (f"sampled below {VIBE_JUDGED_MIN_RATE_HZ:g} Hz", rate < VIBE_JUDGED_MIN_RATE_HZ)) if bad]
        note += (f"; not the VIBE the vehicle would log: this accelerometer is {' and '.join(why)}, so it "
                 f"under-reads the vibration VIBE sees on the raw samples: ArduPilot's thresholds are not drawn")
    return {"time_s": t, "levels": {f"Vibe{c}": out[:, k] for k, c in enumerate("XYZ")},
            "source": f"{accel['source']} (VIBE computed)", "judged": judged, "note": note}


# ------------------------------------------------------------------- figures
def _verdict(value, key):
    th = THRESHOLDS[key]
    if value is None or not np.isfinite(value):
        return None
    return "fail" if value >= th["fail"] else "warn" if value >= th["warn"] else "pass"


def _threshold(key):
    """{"warn", "fail"} of a THRESHOLDS entry, or None (no published threshold)."""
    return None if key is None else {"warn": THRESHOLDS[key]["warn"], "fail": THRESHOLDS[key]["fail"]}


def _worst(verdicts):
    vs = [v for v in verdicts if v is not None]
    return max(vs, key=VERDICTS.index) if vs else None


def _whole_boots(log, levels, accel):
    """One ``whole log`` segment per boot over the samples of the sources (a log of one
    boot: one over all of them, of no boot in particular)."""
    srcs = [x for x in (levels, accel) if x is not None]
    t = np.concatenate([np.asarray(x["time_s"], np.float64) for x in srcs])
    several = len(log.boots) > 1 and all(x.get("session") is not None for x in srcs)
    if not several:
        t = t[np.isfinite(t)]
        return [Segment("whole log", float(t.min()), float(t.max()), None)]
    sess = np.concatenate([np.asarray(x["session"]) for x in srcs])
    out = []
    for k in np.unique(sess).tolist():
        tk = t[(sess == k) & np.isfinite(t)]
        if len(tk):
            out.append(Segment("whole log", float(tk.min()), float(tk.max()), int(k)))
    return out


def _segment_figures(lv, seg):
    """Per level column and instance (``imuN.`` before the name where the log has
    several): mean/max/p95 and verdict; per clip column: its increase and verdict."""
    t = lv["time_s"]
    out = {}
    for inst in np.unique(lv["instance"]).tolist():
        isel = lv["instance"] == inst
        sel = isel & seg.contains(t, lv.get("session"))
        prefix = f"imu{inst}." if len(np.unique(lv["instance"])) > 1 else ""
        for name, col in lv["levels"].items():
            x = np.asarray(col, np.float64)[sel]
            x = x[np.isfinite(x)]
            if not len(x):
                continue
            key = ("vibe_m_s2" if name in ("VibeX", "VibeY", "VibeZ", "vibration_x", "vibration_y", "vibration_z")
                   else "accel_vibration_metric_m_s2" if name == "accel_vibration_metric" else None)
            fig = {"mean": _r(np.mean(x)), "p95": _r(np.percentile(x, 95)), "max": _r(np.max(x)),
                   "unit": LEVEL_UNITS.get(name), "threshold": _threshold(key),
                   "verdict": _verdict(_r(np.percentile(x, 95)), key) if key else None,   # None: no threshold
                   "samples": int(len(x))}
            out[prefix + name] = fig
        for name, col in lv["clips"].items():
            c = np.asarray(col, np.float64)
            idx = np.flatnonzero(sel)
            if not len(idx):
                continue
            before = isel & (t < seg.start_s)
            if lv.get("session") is not None and seg.session is not None:
                before &= lv["session"] == seg.session
            before = np.flatnonzero(before)
            base = c[before[-1]] if len(before) else c[idx[0]]
            inc = float(np.max(c[idx]) - base)
            inc = max(inc, 0.0)
            out[prefix + name] = {"increase": int(inc), "unit": "count", "threshold": _threshold("clip_increase"),
                                  "verdict": _verdict(inc, "clip_increase")}
    return out


def _accel_figures(acc, seg):
    """``accel_band_rms_x/y/z``: the rms (m/s/s) of the accelerometer in the band from
    :data:`ACCEL_BAND_LO_HZ` (from half the Nyquist frequency where that is below 24 Hz) to the
    stream's Nyquist frequency, per window of :data:`ACCEL_WINDOW_S` inside the segment
    (mean removed per window; Parseval over the window's FFT bins in the band), as
    mean/p95/max over the windows; no threshold, no verdict. {} when the segment holds
    no whole window."""
    t = acc["time_s"]
    sel = np.flatnonzero(seg.contains(t, acc.get("session")) & np.isfinite(t))
    if len(sel) < 8:
        return {}
    ts = t[sel]
    dt = np.diff(ts)
    pos = dt[dt > 0]
    if not len(pos):
        return {}
    rate_hz = 1.0 / float(np.median(pos))
    nyq = 0.5 * rate_hz
    lo = ACCEL_BAND_LO_HZ if nyq >= 1.2 * ACCEL_BAND_LO_HZ else ACCEL_BAND_LO_NYQ_SHARE * nyq
    w = max(8, int(round(ACCEL_WINDOW_S * rate_hz)))
    brk = np.r_[0, np.flatnonzero((np.diff(sel) != 1) | (dt > 2.5 / rate_hz) | (dt <= 0)) + 1, len(sel)]
    freq = np.fft.rfftfreq(w, 1.0 / rate_hz)
    band = freq >= lo
    out = {}
    for k, axis in enumerate("xyz"):
        vals = []
        for a, b in zip(brk[:-1], brk[1:]):
            for c in range(a, b - w + 1, w):
                x = acc["xyz"][sel[c:c + w], k]
                if not np.all(np.isfinite(x)):
                    continue
                spec = np.abs(np.fft.rfft(x - x.mean())) ** 2
                wt = np.where((freq > 0) & (freq < nyq - 1e-9), 2.0, 1.0)      # one-sided bins
                vals.append(float(np.sqrt(np.sum(spec[band] * wt[band])) / w))
        if vals:
            v = np.asarray(vals)
            out[f"accel_band_rms_{axis}"] = {
                "mean": _r(v.mean()), "p95": _r(np.percentile(v, 95)), "max": _r(v.max()), "unit": "m/s/s",
                "threshold": None, "verdict": None, "samples": int(len(v) * w), "windows": int(len(v)),
                "band_hz": [_r(lo), _r(nyq)], "source": acc["source"]}
    return out


def _segment_peaks(acc, seg):
    """Dominant peaks of the summed x+y+z accelerometer PSD over the segment
    (strongest first), or [] when the segment is too short for a spectrum."""
    t = acc["time_s"]
    sel = np.flatnonzero(seg.contains(t, acc.get("session")) & np.isfinite(t))
    if len(sel) < 64:
        return []
    ts = t[sel]
    dt = np.diff(ts)
    rate_hz = 1.0 / float(np.median(dt))
    restarts = np.zeros(len(sel), bool)
    restarts[1:] = (np.diff(sel) != 1) | (dt > 2.5 / rate_hz) | (dt <= 0)
    nperseg = int(min(256, 2 ** int(np.floor(np.log2(max(len(sel) // 4, 16))))))
    total, n_seg, f = None, 0, None
    for k in range(3):
        x = acc["xyz"][sel, k]
        x = x - np.nanmean(x)
        f, p, n = welch_psd(x, rate_hz, nperseg, restarts=restarts)
        if p is None:
            return []
        total = p if total is None else total + p
        n_seg = n
    peaks = find_peaks(f, total, n_seg, min_freq_hz=PEAK_MIN_FREQ_HZ, max_peaks=MAX_PEAKS)
    return [{"freq_hz": _r(p["freq_hz"]), "amplitude_rms_m_s2": _r(p["amplitude_rms"]),
             "ratio_db": _r(p["ratio_db"])} for p in peaks]


def _r(v, digits=4):
    """float rounded to ``digits`` significant figures (JSON-able)."""
    v = float(v)
    if v == 0 or not np.isfinite(v):
        return v
    return float(f"{v:.{digits}g}")
