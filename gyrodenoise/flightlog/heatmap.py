"""Frequency-by-throttle and frequency-by-RPM heatmaps of the gyro, with the notch
centres the vehicle's filters would use drawn on them (:func:`log_heatmaps`).

As ArduPilot's Filter Review and PIDtoolbox show it: the gyro record is cut into short
Hann windows (:func:`window_psd`); each window's PSD (summed over the axes) goes into
the bin of the throttle (or the mean motor RPM) at its centre, and each bin's PSDs are
averaged (:func:`binned_psd`). A motor's vibration is a ridge that climbs with throttle
(f ~ sqrt(thrust) ~ sqrt(throttle)) or lies on f = n x RPM / 60.

The notch lines (:func:`notch_lines`), per stage of the vehicle's chain
(:mod:`gyrodenoise.flightlog.vehicle_filters`), at every harmonic it notches:

* a throttle-tracking ArduPilot harmonic notch: ``FREQ x max(FM_RAT, sqrt(thr / REF))``
  (:func:`gyrodenoise.flightlog.vehicle_filters.throttle_notch_centre_hz`);
* an RPM or ESC-tracking one, on the RPM map: ``max(FREQ x FM_RAT, REF x rpm / 60)``
  (AP_Vehicle::update_dynamic_notch: the measured frequency scaled by REF, floored);
* a fixed notch: its centre, a horizontal line; PX4's static notches likewise.

A notch that follows a measurement on the throttle map (ESC, RPM, FFT) has no line
there: the map says so.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

#: throttle / RPM bins of a map
BINS = 24
#: the window's length: about this many seconds, a power of two of samples in
#: [MIN_NPERSEG, MAX_NPERSEG] (1 kHz: 256 samples, 3.9 Hz bins)
WINDOW_S = 0.25
MIN_NPERSEG, MAX_NPERSEG = 32, 512
#: a gap longer than this many sample intervals ends a run (no window spans it)
GAP_FACTOR = 1.5
#: the default x range leaves out windows whose x is under this share of the highest (ground idle)
IDLE_SHARE = 0.1
#: a map needs windows in at least this many bins: fewer is one column (a throttle that
#: hardly varied, a vehicle that never flew), which a spectrum shows better
MIN_BINS = 3
#: the RPM map's lines: these motor-rotation harmonics where no notch stage tracks RPM
ROTATION_HARMONICS = (1, 2, 3)


@dataclass
class NotchLine:
    """A curve to draw on a map: ``freq_hz`` at each ``x`` (throttle or RPM)."""
    label: str
    x: np.ndarray
    freq_hz: np.ndarray


@dataclass
class Heatmap:
    """``psd[i, j]``: the mean PSD ((deg/s)^2/Hz, axes summed) of the windows whose
    ``x`` falls in bin i (``edges[i]..edges[i+1]``), at ``freq_hz[j]``; NaN for an
    empty bin; ``windows[i]`` of them. ``x_label``/``x_source`` name the x quantity."""
    stream: str
    x_label: str
    x_source: str
    edges: np.ndarray
    freq_hz: np.ndarray
    psd: np.ndarray
    windows: np.ndarray
    lines: list = field(default_factory=list)
    notes: list = field(default_factory=list)

    @property
    def centres(self):
        return 0.5 * (self.edges[1:] + self.edges[:-1])

    def ridge_hz(self):
        """The frequency of each bin's highest PSD (NaN for an empty bin)."""
        out = np.full(len(self.windows), np.nan)
        ok = self.windows > 0
        out[ok] = self.freq_hz[np.nanargmax(self.psd[ok], axis=1)]
        return out


def nperseg_for(rate_hz):
    """The window length (samples) at ``rate_hz``: :data:`WINDOW_S` as a power of two."""
    n = 2 ** int(round(math.log2(max(rate_hz * WINDOW_S, 1.0))))
    return int(min(max(n, MIN_NPERSEG), MAX_NPERSEG))


def _runs(time_s, boots, rate_hz):
    """(start, end) of the stretches without a gap, a time step back or a boot change."""
    dt = np.diff(time_s)
    cut = (dt <= 0) | (dt > GAP_FACTOR / rate_hz) | (np.diff(boots) != 0) | ~np.isfinite(dt)
    edges = np.concatenate([[0], np.flatnonzero(cut) + 1, [len(time_s)]])
    return list(zip(edges[:-1], edges[1:]))


def window_psd(time_s, values, rate_hz, boots=None, nperseg=None):
    """(window centre times, their boots, freq_hz, PSD per window (m, nfreq)) of
    ``values`` (n,) or (n, k), the axes' one-sided PSDs summed: each window of
    ``nperseg`` samples (half overlapping, inside one run) less its mean, Hann-weighted,
    ``2 |X|^2 / (fs sum w^2)`` (the DC and Nyquist bins not doubled)."""
    t = np.asarray(time_s, np.float64)
    x = np.asarray(values, np.float64)
    x = x[:, None] if x.ndim == 1 else x
    b = np.zeros(len(t), np.int64) if boots is None else np.asarray(boots)
    n = nperseg or nperseg_for(rate_hz)
    w = np.hanning(n + 1)[:-1]                    # periodic Hann
    scale = 1.0 / (rate_hz * np.sum(w ** 2))
    freq = np.fft.rfftfreq(n, 1.0 / rate_hz)
    starts = [s for a, e in _runs(t, b, rate_hz) for s in range(a, e - n + 1, n // 2)]
    if not starts:
        return np.zeros(0), np.zeros(0, np.int64), freq, np.zeros((0, len(freq)))
    idx = np.asarray(starts)[:, None] + np.arange(n)
    seg = x[idx]                                   # (m, n, k)
    finite = np.isfinite(seg).all(axis=(1, 2))
    seg, idx = seg[finite], idx[finite]
    seg = seg - seg.mean(axis=1, keepdims=True)
    spec = np.abs(np.fft.rfft(seg * w[None, :, None], axis=1)) ** 2 * scale
    spec[:, 1:-1 if n % 2 == 0 else None] *= 2.0
    centre = idx[:, n // 2]
    return t[centre], b[centre], freq, spec.sum(axis=2)


def binned_psd(x, psd, edges):
    """(mean PSD per bin (nbins, nfreq), NaN where empty; windows per bin) of the windows
    whose ``x`` lies in ``edges[i]..edges[i+1]`` (the last edge included)."""
    x = np.asarray(x, np.float64)
    nb = len(edges) - 1
    k = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, nb - 1)
    ok = np.isfinite(x) & (x >= edges[0]) & (x <= edges[-1])
    counts = np.bincount(k[ok], minlength=nb)
    out = np.full((nb, psd.shape[1]), np.nan)
    for i in np.flatnonzero(counts):
        out[i] = psd[ok & (k == i)].mean(axis=0)
    return out, counts


def value_at(channels, time_s, boots):
    """The mean over ``channels``' columns, each interpolated on its own finite rows of
    the same boot, at ``time_s`` (NaN outside a column's span)."""
    out = np.zeros(len(time_s))
    have = np.zeros(len(time_s))
    cb = channels.boots()
    ct = np.asarray(channels.time_s, np.float64)
    for v in channels.columns.values():
        v = np.asarray(v, np.float64)
        for b in np.unique(boots):
            rows = (cb == b) & np.isfinite(v) & np.isfinite(ct)
            at = boots == b
            if rows.sum() < 2 or not at.any():
                continue
            order = np.argsort(ct[rows], kind="stable")
            tt, vv = ct[rows][order], v[rows][order]
            got = np.interp(time_s[at], tt, vv, left=np.nan, right=np.nan)
            fin = np.isfinite(got)
            sel = np.flatnonzero(at)[fin]
            out[sel] += got[fin]
            have[sel] += 1
    with np.errstate(invalid="ignore"):
        return np.where(have > 0, out / np.maximum(have, 1), np.nan)


def heatmap(stream_name, time_s, values, rate_hz, x_channels, x_label, boots=None, bins=BINS, x_range=None):
    """The :class:`Heatmap` of a gyro record against ``x_channels`` (throttle or RPM
    :class:`gyrodenoise.flightlog.timeseries.Channels`), ``bins`` equal bins over
    ``x_range`` (default: the 1st..99th percentile of the windows' x above
    :data:`IDLE_SHARE` of the highest); None when no window lands in a bin."""
    tc, bc, freq, psd = window_psd(time_s, values, rate_hz, boots)
    xv = value_at(x_channels, tc, bc)
    fin = np.isfinite(xv)
    if not fin.any():
        return None
    if x_range is None:
        # the range of the windows with the motors turning: ground idle (throttle or RPM
        # under IDLE_SHARE of the highest) would take most of the map's width
        turning = fin & (xv > IDLE_SHARE * np.nanmax(xv[fin]))
        x_range = np.percentile(xv[turning if turning.any() else fin], [1, 99])
    lo, hi = x_range
    if not hi > lo:
        lo, hi = lo - 0.5 * abs(lo or 1.0) * 0.1, hi + 0.5 * abs(hi or 1.0) * 0.1
    edges = np.linspace(lo, hi, bins + 1)
    mean, counts = binned_psd(xv, psd, edges)
    if not counts.sum():
        return None
    return Heatmap(stream_name, x_label, x_channels.source, edges, freq, mean, counts)


def too_narrow(hm, what):
    """Why map ``hm`` is not worth drawing (its windows in fewer than :data:`MIN_BINS` bins of
    ``what``), or None."""
    filled = int((hm.windows > 0).sum())
    if filled >= MIN_BINS:
        return None
    return (f"no frequency-by-{what} map: its {int(hm.windows.sum())} gyro windows fall in {filled} of the "
            f"{len(hm.windows)} {what} bins ({what} {hm.edges[0]:.3g}..{hm.edges[-1]:.3g}: it hardly varied); "
            f"a map needs {MIN_BINS} (the spectra show the gyro's noise)")


def throttle_notch_hz(stage, throttle):
    """The fundamental of notch ``stage`` at each ``throttle`` on the throttle map, or None
    where it follows a measurement (no line)."""
    from gyrodenoise.flightlog.vehicle_filters import throttle_notch_centre_hz
    tracking = stage.get("tracking", "fixed")
    if tracking not in ("fixed", "throttle"):
        return None
    return np.array([throttle_notch_centre_hz(stage, float(x)) for x in throttle])


def rpm_notch_hz(stage, rpm):
    """The fundamental of notch ``stage`` at each mean motor ``rpm`` on the RPM map:
    ``max(FREQ x FM_RAT, REF x rpm / 60)`` for RPM/ESC tracking, FREQ for a fixed one;
    None for throttle or FFT tracking (another measurement)."""
    tracking = stage.get("tracking", "fixed")
    if tracking == "fixed":
        return np.full(len(rpm), float(stage["centre_hz"]))
    if tracking not in ("rpm", "esc", "rpm2"):
        return None
    floor = float(stage["centre_hz"]) * float(stage.get("min_ratio", 1.0))
    return np.maximum(floor, float(stage.get("reference") or 1.0) * np.asarray(rpm, np.float64) / 60.0)


def notch_lines(stages, x, centre_fn, nyquist_hz):
    """[:class:`NotchLine`] of each notch stage's harmonics at ``x`` (``centre_fn(stage, x)``
    gives the fundamental or None), under ``nyquist_hz``; and notes on the stages without one."""
    lines, notes = [], []
    for st in stages or []:
        if st.get("kind") not in ("notch", "harmonic_notch") or st.get("path", "rate") != "rate":
            continue
        f0 = centre_fn(st, x)
        if f0 is None:
            notes.append(f"{st.get('params')}: follows {st.get('tracking')}, not this map's x: no line")
            continue
        for h in st.get("harmonics", [1]):
            f = f0 * h
            if np.nanmin(f) < nyquist_hz:
                lines.append(NotchLine(f"{st.get('params')} notch, harmonic {h} ({st.get('tracking', 'fixed')})",
                                       np.asarray(x, np.float64), np.where(f < nyquist_hz, f, np.nan)))
    return lines, notes


def track_centre_hz(track):
    """The logged dynamic notch centre per row of ``track`` (the strategy's
    ``notch_centre_track``): the median over its columns (motors, FFT peaks) [Hz]."""
    cols = [np.asarray(v, np.float64) for v in track.columns.values()]
    with warnings.catch_warnings():                  # a row of NaNs only: NaN, said once
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(np.vstack(cols), axis=0)


def track_line(track, x_channels, edges):
    """A :class:`NotchLine` of the logged dynamic notch centre (:func:`track_centre_hz`)
    on a map: at each row of ``track`` the map's x (throttle or RPM, interpolated), the
    median centre per bin of ``edges``; None where no row lands in a bin."""
    f = track_centre_hz(track)
    x = value_at(x_channels, np.asarray(track.time_s, np.float64), track.boots())
    ok = np.isfinite(f) & np.isfinite(x) & (x >= edges[0]) & (x <= edges[-1])
    if not ok.any():
        return None
    nb = len(edges) - 1
    k = np.clip(np.searchsorted(edges, x[ok], side="right") - 1, 0, nb - 1)
    centres = 0.5 * (edges[1:] + edges[:-1])
    med = np.array([np.median(f[ok][k == i]) if (k == i).any() else np.nan for i in range(nb)])
    return NotchLine(f"logged dynamic notch centre ({track.source}; median per bin)", centres, med)


def stream_rate_hz(stream):
    """A stream's rate: its ``rate_hz`` once filtered, else from its median sample interval."""
    if stream.rate_hz:
        return float(stream.rate_hz)
    dt = np.diff(np.asarray(stream.time_s, np.float64))
    dt = dt[np.isfinite(dt) & (dt > 0)]
    return float(1.0 / np.median(dt)) if len(dt) else 0.0


def review_stream(log, autopilot, params):
    """(the stream the maps use, its stage, its rate): the fastest pre-filter gyro, else
    the fastest stream (its stage named on the map); Nones without a stream."""
    staged = [(s, autopilot.stream_stage(params, s), stream_rate_hz(s)) for s in log.gyro]
    staged = [x for x in staged if x[2] > 0]
    if not staged:
        return None, None, None
    pre = [x for x in staged if x[1] == "pre-filter"]
    return max(pre or staged, key=lambda x: x[2])


def log_heatmaps(log, throttle, stages=None, autopilot=None):
    """([:class:`Heatmap`] by throttle and, where the log holds motor RPM, by RPM, with
    the notch lines of ``stages`` (the vehicle's chain; default from the log's
    parameters)), notes on what is missing. ``throttle``: the throttle
    :class:`~gyrodenoise.flightlog.timeseries.Channels` (None: the log has none)."""
    ap = autopilot or log.parameters().autopilot
    params = log.parameters().values
    if stages is None:
        stages = ap.filter_chain(params)[0]
    stream, stage, rate = review_stream(log, ap, params)
    if stream is None:
        return [], ["no gyro stream with a rate"]
    values = stream.raw * (stream.to_deg_s or 1.0)
    unit = "deg/s" if stream.to_deg_s else stream.unit
    boots = log.boot_of(stream.index) if len(log.boots) > 1 else None
    maps, notes = [], []
    where = f"{stream.name} ({stage} gyro, {rate:.4g} Hz, {unit})"
    thr = throttle

    def one_map(by, name, what, x_label, looked_for):
        """The map against ``by`` (throttle or RPM Channels), or None with a note why not."""
        if by is None:
            notes.append(f"no frequency-by-{name} map: no {what} in the log (looked for {looked_for})")
            return None
        hm = heatmap(where, stream.time_s, values, rate, by, x_label, boots)
        why = (f"no frequency-by-{name} map: no gyro window ({nperseg_for(rate)} samples without a gap) lies in "
               f"the {name}'s time span") if hm is None else too_narrow(hm, name)
        if why:
            notes.append(why)
            return None
        return hm

    hm = one_map(thr, "throttle", "throttle", "throttle [0..1]", log.format.flight_looked_for)
    if hm is not None:
        x = np.linspace(hm.edges[0], hm.edges[-1], 64)
        hm.lines, hm.notes = notch_lines(stages, x, throttle_notch_hz, rate / 2.0)
        maps.append(hm)
    track = ap.notch_centre_track(log)
    if track is not None:
        for hm in maps:
            ln = track_line(track, thr, hm.edges)
            if ln is not None:
                hm.lines.append(ln)
    rpm = ap.motor_rpm(log)
    hm = one_map(rpm, "RPM", "motor RPM", "mean motor RPM [rev/min]", ap.rpm_looked_for)
    if hm is not None:
        x = np.linspace(hm.edges[0], hm.edges[-1], 64)
        lines, hm.notes = notch_lines(stages, x, rpm_notch_hz, rate / 2.0)
        lines += [NotchLine(f"motor rotation x{h} (rpm/60 x {h})", x, h * x / 60.0) for h in ROTATION_HARMONICS
                  if np.nanmin(h * x / 60.0) < rate / 2.0]
        ln = track_line(track, rpm, hm.edges) if track is not None else None
        hm.lines = lines + ([ln] if ln is not None else [])
        maps.append(hm)
    return maps, notes
