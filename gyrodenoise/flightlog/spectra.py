"""The spectrum view of a gyro stream: what goes into the report and the PNG.

The maths is :mod:`gyrodenoise.analysis.spectrum`; this module picks its settings for a
stream, names what it found (peaks, harmonics, the filter's response) in the
report, and draws ``NAME.spectrum.png``, one figure per log (in the plot helper
process).
"""

from __future__ import annotations

import itertools

import numpy as np

from gyrodenoise.analysis import spectrum as sp

from gyrodenoise.flightlog.stopping import atomic_path

#: below this frequency the content is the vehicle's motion (the bridge's motion
#: band, :data:`gyrodenoise.analysis.motion_metrics.LOWBAND_HZ`), not vibration
MIN_PEAK_FREQ_HZ = 5.0
#: a peak must also stand this far above the floor (power ratio; 4 = 6 dB): with
#: hundreds of segments the statistical threshold alone tends to 1 (1.3 = 1.1 dB at
#: 184 segments), and a flight's spectrum is not stationary noise: its 3-5 dB
#: ripples (log171, px4_sample) are not what an engineer calls a vibration peak
MIN_PEAK_RATIO = 4.0
#: peaks listed per axis (the strongest)
MAX_PEAKS = 6
#: peaks named on the plot per axis (the strongest; the others are marked only)
LABELLED_PEAKS = 3
#: a stream spanning at least this many seconds gets a spectrogram
SPECTROGRAM_MIN_SPAN_S = 30.0

SPECTRUM_METRIC = (
    "per stream and axis: Welch PSD (Hann, half-overlapping segments within sessions, segment mean "
    "removed, one-sided, unit**2/Hz); peaks = local maxima >= {f:g} Hz above a running-median "
    "noise floor by max(6 dB, the chi-square threshold for a {fa:g} false-alarm probability per "
    "spectrum); amplitude_rms = sqrt of the excess power over the floor within 3 bins (a tone of "
    "amplitude A gives A/sqrt(2)); harmonic_of_hz: the lower peak it is n x (n = 2..5, within "
    "max((n+1)/4 bins, 1 %)); present_in_segments: share of the segments whose power there is 2x the "
    "floor's (noise alone ~10 %); filter_gain / phase_delay_s: the filter's response measured from the "
    "raw->filtered cross-spectrum (H1 = S_xf/S_xx, after each session's warm-up); "
    "gyrodenoise.analysis.spectrum").format(f=MIN_PEAK_FREQ_HZ, fa=sp.FALSE_ALARM)


#: broad humps (:func:`find_humps`): the log-frequency grid [points per octave], the
#: smoothing of the PSD before it (a mean of power over this many octaves), the floor's
#: running median [octaves] and the top of a hump over it [dB]
HUMP_GRID_PER_OCTAVE = 24
HUMP_SMOOTH_OCTAVES = 1.0 / 12.0
HUMP_FLOOR_OCTAVES = 3.0
HUMP_MIN_DB = 6.0
#: a hump's width at half its height over the floor (in dB), in octaves: narrower is a
#: line (:func:`gyrodenoise.analysis.spectrum.find_peaks` sees it), wider the floor's shape
HUMP_MIN_OCTAVES = 1.0 / 8.0
HUMP_MAX_OCTAVES = 1.0
#: a hump whose excess power over the floor lies this much in one line's bins
#: (the peak finder's window, 2 x 3 + 1 bins) is that line, not a hump
HUMP_LINE_SHARE = 0.8
#: humps listed per axis (the strongest)
MAX_HUMPS = 3

HUMP_METRIC = (
    "per stream and axis, the broad humps of the raw PSD (what a notch with a bandwidth sits on: a motor "
    "band wandering with the throttle): the PSD averaged over {s:.3g} octave, on a log-frequency grid "
    "({g} points per octave) from {f:g} Hz to Nyquist; its floor the running median of log PSD over "
    "{w:g} octaves (ends reflected about the end value: a power law is followed exactly); a hump is a "
    "maximum >= {d:g} dB over that floor, its band (lo_hz..hi_hz) where it stays above half its height "
    "in dB, {mn:.3g} to {mx:g} octave wide and >= {lw} bins; one whose excess power lies >= {ls:.0%} in "
    "one line's {lb} bins is that line (a peak). freq_hz: the centroid of the excess power over the "
    "band; amplitude_rms: sqrt of that excess power").format(
        s=HUMP_SMOOTH_OCTAVES, g=HUMP_GRID_PER_OCTAVE, f=MIN_PEAK_FREQ_HZ, w=HUMP_FLOOR_OCTAVES, d=HUMP_MIN_DB,
        mn=HUMP_MIN_OCTAVES, mx=HUMP_MAX_OCTAVES, lw=4 * sp.PEAK_HALF_WIDTH_BINS,
        ls=HUMP_LINE_SHARE, lb=2 * sp.PEAK_HALF_WIDTH_BINS + 1)
SPECTRUM_METRIC += "; humps: " + HUMP_METRIC


def _smoothed_on_grid(f, p, grid):
    """The mean of ``p`` over the bins within ``HUMP_SMOOTH_OCTAVES`` around each grid
    frequency (at least the nearest bin): power averaged before its log is taken."""
    half = 2.0 ** (HUMP_SMOOTH_OCTAVES / 2.0)
    csum = np.r_[0.0, np.cumsum(p)]
    lo = np.searchsorted(f, grid / half, side="left")
    hi = np.searchsorted(f, grid * half, side="right")
    near = np.clip(np.rint((grid - f[0]) / (f[1] - f[0])).astype(np.int64), 0, len(f) - 1)
    empty = hi <= lo
    lo = np.where(empty, near, lo)
    hi = np.where(empty, near + 1, hi)
    return (csum[hi] - csum[lo]) / (hi - lo)


def hump_floor(log_psd, width_points):
    """Running median of a log PSD on a log-frequency grid over ``width_points``
    (odd), the ends reflected about the end values (``y[-k] = 2 y[0] - y[k]``): on a
    log-log axis a power law is a straight line, which this reflection continues, and
    the median of a straight line's symmetric window is its centre value: the floor of
    a 1/f**a spectrum is that spectrum, whatever a, up to the ends."""
    from numpy.lib.stride_tricks import sliding_window_view
    y = np.asarray(log_psd, dtype=np.float64)
    h = min(int(width_points) // 2, len(y) - 1)
    if h < 1:
        return y.copy()
    pad = np.pad(y, h, mode="reflect", reflect_type="odd")
    return np.median(sliding_window_view(pad, 2 * h + 1), axis=1)


def find_humps(freq_hz, psd, min_freq_hz=MIN_PEAK_FREQ_HZ, max_humps=MAX_HUMPS):
    """Broad humps of a PSD (a motor band, tens of Hz wide), strongest first: a list of
    dicts ``freq_hz`` (centroid of the excess power), ``lo_hz``/``hi_hz`` (the band at
    half the hump's height over the floor, in dB), ``width_octaves``, ``above_floor_db``
    (the smoothed PSD's top over the floor), ``amplitude_rms`` (sqrt of the excess power
    over the band; unit of the PSD's square root). See :data:`HUMP_METRIC`.

    :func:`gyrodenoise.analysis.spectrum.find_peaks` asks whether a narrow line stands
    above a floor some tens of bins wide; a band 0.3 octave wide at 130 Hz is that
    floor there, so it is never a peak. Here the floor is 3 octaves wide and the
    spectrum is smoothed first, so the band stands out and a line does not (its power
    sits in a few bins: :data:`HUMP_LINE_SHARE`)."""
    f = np.asarray(freq_hz, dtype=np.float64)
    p = np.asarray(psd, dtype=np.float64)
    if len(f) < 16 or not np.all(np.isfinite(p)) or f[1] <= f[0]:
        return []
    df = f[1] - f[0]
    f_lo = max(float(min_freq_hz), float(f[sp.MIN_PEAK_BIN]))
    f_hi = float(f[-1])
    if f_hi <= 2.0 * f_lo:                          # less than an octave: no floor to stand above
        return []
    n_grid = int(np.floor(np.log2(f_hi / f_lo) * HUMP_GRID_PER_OCTAVE)) + 1
    grid = f_lo * 2.0 ** (np.arange(n_grid) / HUMP_GRID_PER_OCTAVE)
    smooth = _smoothed_on_grid(f, p, grid)
    if not np.all(smooth > 0):
        return []
    y = 10.0 * np.log10(smooth)
    width = 2 * int(round(HUMP_FLOOR_OCTAVES * HUMP_GRID_PER_OCTAVE / 2)) + 1
    # the running median of the spectrum less its overall slope (Theil-Sen: the median of
    # the pairwise slopes): on a falling floor a hump's points would sort among those of
    # lower frequencies and lift the median by half the hump's points x the slope per
    # point (3 dB for a 0.3 octave hump on 1/f**2); on the level residual they do not
    idx = np.arange(n_grid, dtype=np.float64)
    i, j = np.triu_indices(n_grid, 1)
    slope = float(np.median((y[j] - y[i]) / (j - i)))
    floor_db = hump_floor(y - slope * idx, width) + slope * idx
    e = y - floor_db
    floor_lin = np.interp(np.log(np.maximum(f, f_lo)), np.log(grid), 10.0 ** (floor_db / 10.0))
    found, taken = [], np.zeros(n_grid, dtype=bool)
    for i in np.argsort(-e):
        if e[i] < HUMP_MIN_DB:
            break
        if taken[i] or (i > 0 and e[i - 1] > e[i]) or (i < n_grid - 1 and e[i + 1] > e[i]):
            continue
        half = e[i] / 2.0
        a = i
        while a > 0 and e[a - 1] >= half:
            a -= 1
        b = i
        while b < n_grid - 1 and e[b + 1] >= half:
            b += 1
        if taken[a:b + 1].any():                    # a shoulder of a stronger hump
            taken[a:b + 1] = True
            continue
        taken[a:b + 1] = True
        lo_hz, hi_hz = float(grid[a]), float(grid[b])
        width = float(np.log2(hi_hz / lo_hz))
        if not (HUMP_MIN_OCTAVES <= width <= HUMP_MAX_OCTAVES) or hi_hz - lo_hz < 4 * sp.PEAK_HALF_WIDTH_BINS * df:
            continue
        band = (f >= lo_hz) & (f <= hi_hz)
        excess = np.maximum(p - floor_lin, 0.0) * band
        total = float(excess.sum())
        if total <= 0:
            continue
        line = float(np.max(np.convolve(excess, np.ones(2 * sp.PEAK_HALF_WIDTH_BINS + 1), mode="same")))
        if line >= HUMP_LINE_SHARE * total:
            continue
        found.append({"freq_hz": float(np.sum(f * excess) / total), "lo_hz": lo_hz, "hi_hz": hi_hz,
                      "width_octaves": width, "above_floor_db": float(e[i]),
                      "amplitude_rms": float(np.sqrt(total * df))})
    found.sort(key=lambda q: -q["amplitude_rms"])
    return _hump_harmonics(found[:max_humps])


#: a hump is n x a lower one when its centre is within this share of n x that centre
HUMP_HARMONIC_TOL = 0.05


def _hump_harmonics(humps):
    """Set ``harmonic_of_hz``/``harmonic_n`` on each hump (strongest first, as given):
    n x (n = 2..5) the centre of a lower hump that is not itself a harmonic, within
    :data:`HUMP_HARMONIC_TOL` (a motor band's centroid moves with its shape; 5 % of a
    3 x 128 Hz band is 19 Hz, under the band's own width)."""
    for q in humps:
        q["harmonic_of_hz"], q["harmonic_n"] = None, 1
    for q in sorted(humps, key=lambda q: q["freq_hz"]):
        for base in sorted(humps, key=lambda q: q["freq_hz"]):
            if base is q or base["freq_hz"] >= q["freq_hz"] or base["harmonic_of_hz"] is not None:
                continue
            n = int(round(q["freq_hz"] / base["freq_hz"]))
            if 2 <= n <= 5 and abs(q["freq_hz"] - n * base["freq_hz"]) <= HUMP_HARMONIC_TOL * n * base["freq_hz"]:
                q["harmonic_of_hz"], q["harmonic_n"] = base["freq_hz"], n
                break
    return humps


def describe_hump(q, unit="deg/s"):
    """'broad 110-145 Hz (centre 128 Hz), 2.1 deg/s rms, 18 dB over the floor' (one hump)."""
    text = (f"broad {q['lo_hz']:.3g}-{q['hi_hz']:.3g} Hz (centre {q['freq_hz']:.3g} Hz), "
            f"{q['amplitude_rms']:.2g} {unit} rms, {q['above_floor_db']:.0f} dB over the floor")
    if q.get("harmonic_of_hz"):
        text += f" ({q['harmonic_n']} x {q['harmonic_of_hz']:.3g} Hz)"
    return text


#: a lag this small [ms] is numerical noise of the measurement: printed as 0
LAG_ZERO_MS = 0.01


def lag_text(lag_ms):
    """A lag [ms] as text: "0" where ``|lag| <`` :data:`LAG_ZERO_MS` (numerical noise,
    not "-3.1e-05"), else two significant digits ('.2g')."""
    if not np.isfinite(lag_ms):
        return "-"
    return "0" if abs(lag_ms) < LAG_ZERO_MS else f"{lag_ms:.2g}"


def _computed_sos(method, rate_hz, filter_kw):
    """The low-pass's sections when the method is the core's Butterworth, else None."""
    if method != "lowpass":
        return None
    from gyrodenoise.core import kernels as K
    p = K.make_params(method=method, sample_rate_hz=rate_hz, **dict(filter_kw or {}))
    nsec = int(p[K.P_LP_NSEC])
    return [tuple(p[K.P_SOS + 5 * i + j] for j in range(5)) for i in range(nsec)]


def stream_spectrum(s, x, f, unit, filter_rate_hz, method="motion", filter_kw=None, skip_samples=0,
                    time_axis_s=None, usable=None):
    """(report dict, plot data or None) of the spectrum of one stream
    (:func:`gyrodenoise.analysis.spectrum.analyse`).

    ``x``/``f``: raw/filtered (n, 3) in ``unit``; ``s``: the GyroStream
    (restarts, rate_hz, time_s, left_raw); ``skip_samples``: the filter's
    warm-up after each restart, left out of the measured response;
    ``time_axis_s``: the plot's time of each sample (spectrogram columns) when
    the log's time does not run forwards; ``usable``: samples to use (bool)."""
    rate = s.rate_hz
    if rate is None or s.n < 64:
        return {"available": False, "reason": "too few samples for a spectrum"}, None
    from gyrodenoise.analysis.motion_metrics import too_slow_to_denoise
    if too_slow_to_denoise(rate):
        return {"available": False, "reason": f"sampled at {rate:.3g} Hz: no vibration band "
                                               f"above the {MIN_PEAK_FREQ_HZ:g} Hz motion band"}, None
    # a stream the filter never ran on (written raw, with its reason) has no computed response
    sos = None if getattr(s, "not_filtered", None) else _computed_sos(method, filter_rate_hz, filter_kw)
    an = sp.analyse(x, f, rate, s.restarts, skip_samples, usable, min_freq_hz=MIN_PEAK_FREQ_HZ,
                    min_ratio=MIN_PEAK_RATIO, max_peaks=MAX_PEAKS, sos=sos)
    if an is None:
        return {"available": False, "reason": "no session long enough for a spectrum (32 samples)"}, None
    # the response is measured after each session's warm-up; where what is left of
    # the sessions cannot hold one segment of the PSD's length (the batch sampler's
    # bursts of 1024 samples after a 0.1 s warm-up), it is measured with shorter ones
    resp = an
    if an["response_segments"] == 0 and not an["filtered_is_raw"] and skip_samples:
        resp = _response_after_warmup(x, f, rate, s.restarts, skip_samples, usable, sos) or an
    freq = an["freq_hz"]
    rep = {"available": True, "rate_hz": rate, "nperseg": int(an["nperseg"]), "resolution_hz": float(freq[1]),
           "segments": int(len(an["starts"])), "response_segments": int(resp["response_segments"]),
           "unit": unit, "min_peak_freq_hz": MIN_PEAK_FREQ_HZ,
           "min_peak_db": round(10 * np.log10(MIN_PEAK_RATIO), 2), "false_alarm": sp.FALSE_ALARM,
           "response": "computed and measured" if sos is not None else "measured", "peaks": {}, "humps": {}, "filter": {}}
    if resp is not an:
        rep["response_nperseg"] = int(resp["nperseg"])
        rep["response_note"] = (f"measured over the {resp['response_over']}, with segments of {resp['nperseg']} "
                                f"samples: the sessions after the filter's warm-up ({skip_samples} samples) hold "
                                f"no segment of the spectrum's {an['nperseg']}")
        _peak_response(an, resp)
    for k, a in enumerate(s.axes):
        rep["peaks"][a] = [{
            "freq_hz": q["freq_hz"], "amplitude_rms": q["amplitude_rms"],
            "amplitude_deg_s_rms": q["amplitude_rms"] if unit == "deg/s" else None,
            "above_floor_db": q["ratio_db"], "present_in_segments": q["present_in_segments"],
            "harmonic_of_hz": q["harmonic_of_hz"],
            "harmonic_n": q["harmonic_n"], "harmonics_hz": q["harmonics_hz"],
            "filtered_amplitude_rms": q["filtered_amplitude_rms"],
            "filter_gain": q["filter_gain"], "phase_delay_s": q["phase_delay_s"],
        } for q in an["peaks"][k]]
        rep["filter"][a] = _response_summary(resp, k)
        rep["humps"][a] = [{key: (round(v, 3) if isinstance(v, float) else v) for key, v in q.items()}
                           for q in find_humps(freq, an["psd_raw"][k])]
    rep["dominant_peak"] = dominant_peak(rep["peaks"])
    pd = {"freq_hz": freq, "unit": unit, "axes": s.axes, "raw": an["psd_raw"], "filtered": an["psd_filtered"],
          "floor": an["floor_raw"], "gain": resp["gain"], "coherence": resp["coherence"],
          "delay_s": resp["delay_s"], "response_freq_hz": resp["freq_hz"],
          "peaks": [rep["peaks"][a] for a in s.axes], "humps": [rep["humps"][a] for a in s.axes],
          "computed_gain": resp["computed_gain"],
          "computed_delay_s": resp["computed_delay_s"], "spectrogram": None,
          "filtered_is_raw": an["filtered_is_raw"]}
    span = float(s.time_s[-1] - s.time_s[0]) if s.n > 1 else 0.0
    if span >= SPECTROGRAM_MIN_SPAN_S and len(an["starts"]) >= 20:
        centre, dens = sp.spectrogram(an["power_raw_sum"], an["starts"], an["nperseg"])
        # the log's time when it runs forwards (a batch sampler's bursts spread over the
        # flight), else the plot's sessions laid end to end
        t = s.time_s if time_axis_s is None or np.all(np.diff(s.time_s) >= 0) else time_axis_s
        cidx = np.clip(np.rint(centre).astype(np.int64), 0, s.n - 1)
        pd["spectrogram"] = (np.asarray(t, dtype=np.float64)[cidx], dens)
        rep["spectrogram_columns"] = int(len(centre))
    return rep, pd


def _response_after_warmup(x, f, rate, restarts, skip_samples, usable, sos):
    """The filter's response (:func:`gyrodenoise.analysis.spectrum.analyse`) over the
    samples after each session's warm-up only, its segment length chosen from what is
    left of the sessions; None when even that holds no segment."""
    from gyrodenoise.core.sessions import sessions
    n = len(x)
    ok = (np.isfinite(x).all(axis=1) & np.isfinite(f).all(axis=1)) if usable is None else np.asarray(usable, bool)
    after = np.zeros(n, dtype=bool)
    for a, b in sessions(n, restarts, skip_samples):
        after[a:b] = True
    resp = sp.analyse(x, f, rate, restarts, 0, ok & after, min_freq_hz=MIN_PEAK_FREQ_HZ,
                      min_ratio=MIN_PEAK_RATIO, max_peaks=1, sos=sos)
    if resp is not None and resp["response_segments"]:
        resp["response_over"] = "after the warm-up"
        return resp
    # nothing left after the warm-up (a 1 s warm-up, 0.5 s bursts): where the filter
    # did act within its warm-up (a low-pass does; the motion filter passes raw samples
    # through), the response is measured over the whole sessions, and says so
    warm = ok & ~after
    if warm.any() and not np.array_equal(x[warm], f[warm], equal_nan=True):
        resp = sp.analyse(x, f, rate, restarts, 0, ok, min_freq_hz=MIN_PEAK_FREQ_HZ,
                          min_ratio=MIN_PEAK_RATIO, max_peaks=1, sos=sos)
        if resp is not None and resp["response_segments"]:
            resp["response_over"] = "whole sessions, the filter's warm-up included"
            return resp
    return None


def _peak_response(an, resp):
    """The filter's gain and lag at each peak of ``an`` from the response ``resp``
    measured on another frequency grid (the nearest bin)."""
    for k, peaks in enumerate(an["peaks"]):
        if resp["gain"][k] is None:
            continue
        for q in peaks:
            b = int(np.argmin(np.abs(resp["freq_hz"] - q["freq_hz"])))
            q["filter_gain"] = float(resp["gain"][k][b])
            q["phase_delay_s"] = float(resp["delay_s"][k][b])


def _response_summary(an, k):
    """Per axis: where the measured gain first falls below -3 dB, and the lag there."""
    if an["filtered_is_raw"]:
        return {"measured": False, "reason": "the output is the raw record (filter not applied)"}
    gain = an["gain"][k]
    if gain is None:
        return {"measured": False, "reason": "no segment after the filter's warm-up"}
    freq, coh = an["freq_hz"], an["coherence"][k]
    b = sp.minus3db_bin(freq, gain)
    ok = (freq > 0) & np.isfinite(coh)
    out = {"measured": True, "segments": int(an["response_segments"]),
           "minus3db_hz": None if b is None else float(freq[b]),
           "phase_delay_s_at_minus3db": None if b is None else float(an["delay_s"][k][b]),
           "mean_coherence": float(np.mean(coh[ok])) if ok.any() else None}
    if an["computed_gain"] is not None:
        bc = sp.minus3db_bin(freq, an["computed_gain"])
        out["computed_minus3db_hz"] = None if bc is None else float(freq[bc])
    return out


def dominant_peak(peaks_by_axis):
    """The strongest peak over the axes: dict with ``axis`` added, or None."""
    best = None
    for a, peaks in peaks_by_axis.items():
        for q in peaks:
            if best is None or q["amplitude_rms"] > best["amplitude_rms"]:
                best = dict(q, axis=a)
    return best


def describe_peak(q, unit="deg/s"):
    """'83 Hz, 0.9 deg/s rms (in 95 % of segments), harmonics 166, 249 Hz' (one peak of the report)."""
    text = f"{q['freq_hz']:.3g} Hz, {q['amplitude_rms']:.2g} {unit} rms"
    if q.get("present_in_segments") is not None:
        text += f" (in {100 * q['present_in_segments']:.0f} % of segments)"
    if q.get("harmonics_hz"):
        text += ", harmonics " + ", ".join(f"{h:.3g}" for h in q["harmonics_hz"]) + " Hz"
    if q.get("harmonic_of_hz"):
        text += f" ({q['harmonic_n']} x {q['harmonic_of_hz']:.3g} Hz)"
    return text


def summary_lines(spec):
    """Text lines of the spectrum of one stream's report (for the text summary)."""
    if not spec:
        return []
    if not spec.get("available"):
        return [f"spectrum: none ({spec.get('reason')})"]
    unit = spec.get("unit", "deg/s")
    lines, quiet = [], []
    for a, humps in (spec.get("humps") or {}).items():
        if humps:
            lines.append(f"{a}: " + "; ".join(describe_hump(q, unit) for q in sorted(humps, key=lambda q: q["freq_hz"])))
    for a, peaks in spec["peaks"].items():
        main = sorted([q for q in peaks if q.get("harmonic_of_hz") is None],
                      key=lambda q: -q["amplitude_rms"])[:3]          # the 3 strongest, by frequency
        if not main:
            quiet.append(a)
            continue
        parts = []
        for q in sorted(main, key=lambda q: q["freq_hz"]):
            g = q.get("filter_gain")
            parts.append(describe_peak(q, unit) + ("" if g is None else f", filter gain {g:.2f}"))
        lines.append(f"{a}: vibration " + "; ".join(parts))
    if quiet:
        lines.append(f"{', '.join(quiet)}: no vibration peak (none >= {spec['min_peak_freq_hz']:g} Hz "
                     f"stands {spec['min_peak_db']:g} dB above the noise floor)")
    return lines


# ------------------------------------------------------------------ drawing
#: colours of the axes x, y, z (matplotlib's first three)
AXIS_COLOURS = ("blue", "orange", "green")


def draw_log_spectrum(path, title, items):
    """The spectrum PNG of one log: per stream (``items``: [(name, plot data of
    :func:`stream_spectrum`)]) its raw (solid) and filtered (dashed) PSD per axis
    with the noise floor and the peaks named; then the filter's response: gain
    |H| per stream (measured, the median over the axes; dashed: computed for the
    low-pass) with its lag; then the spectrogram of the raw record of the
    fastest stream spanning 30 s or more. One figure per log, not per stream: a
    matplotlib axes costs the plot helper ~0.03 s of CPU wherever it is, and the
    helper is the bridge's critical path (docs/logs/mavlink.md, Speed)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sg_item = max((it for it in items if it[1]["spectrogram"] is not None),
                  key=lambda it: it[1]["freq_hz"][-1], default=None)
    ratios = [2.6] * len(items) + [1.7] + ([2.0] if sg_item else [])
    fig, axs = plt.subplots(len(ratios), 1, figsize=(9, 1.95 * len(ratios) + 0.9),
                            gridspec_kw={"height_ratios": ratios})
    fig.subplots_adjust(left=0.09, right=0.92 if sg_item else 0.97,   # 0.92: room for the colour bar's label
                        top=1.0 - 0.45 / fig.get_figheight(), bottom=0.06, hspace=0.45)
    for ax, (name, pd) in zip(axs, items):
        _draw_psd(ax, name, pd)
    axs[0].set_title(title, fontsize=9)
    _draw_response(axs[len(items)], items)
    if sg_item:
        _draw_spectrogram(axs[-1], *sg_item)
    with atomic_path(path) as tmp:                # an interrupt leaves no half-written PNG
        fig.savefig(tmp, format="png", dpi=90, pil_kwargs={"compress_level": 1})
    plt.close(fig)


def _draw_psd(ax, name, pd):
    from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator
    fr = pd["freq_hz"]
    sel = fr > 0
    unit = pd["unit"]
    listing = []
    for k, a in enumerate(pd["axes"]):
        ax.plot(fr[sel], pd["raw"][k][sel], lw=0.8, color=f"C{k}")
        if not pd["filtered_is_raw"]:
            ax.plot(fr[sel], pd["filtered"][k][sel], lw=0.8, ls="--", color=f"C{k}", alpha=0.7)
        ax.plot(fr[sel], pd["floor"][k][sel], lw=0.5, ls=":", color=f"C{k}")
        # one line of markers per run of peaks of one size (the same pixels as one a peak, in
        # the same order; a matplotlib line costs its marker's set-up each)
        for ms, run in itertools.groupby(pd["peaks"][k], key=lambda q: 4 if q["harmonic_of_hz"] else 6):
            run = list(run)
            b = [int(np.argmin(np.abs(fr - q["freq_hz"]))) for q in run]
            ax.plot([q["freq_hz"] for q in run], np.asarray(pd["raw"][k])[b], "v", ls="none", color=f"C{k}",
                    ms=ms, mec="k", mew=0.5)
        for q in (pd.get("humps") or [[]] * (k + 1))[k]:      # a bar over each broad hump's band
            band = (fr >= q["lo_hz"]) & (fr <= q["hi_hz"])
            if band.any():
                ax.hlines(1.6 * float(np.max(np.asarray(pd["raw"][k])[band])), q["lo_hz"], q["hi_hz"],
                          color=f"C{k}", lw=3, alpha=0.6)
        named = sorted(pd["peaks"][k], key=lambda q: -q["amplitude_rms"])[:LABELLED_PEAKS]
        listing.append(f"{a}: " + ("; ".join(
            f"{q['freq_hz']:.4g} Hz {q['amplitude_rms']:.2g} ({100 * q['present_in_segments']:.0f} %)" +
            (f" {q['harmonic_n']}x" if q["harmonic_of_hz"] else "")
            for q in sorted(named, key=lambda q: q["freq_hz"])) or "no peak"))
    colours = ", ".join(f"{a} {c}" for a, c in zip(pd["axes"], AXIS_COLOURS))
    lines = "raw (filtered = raw)" if pd["filtered_is_raw"] else "solid raw, dashed filtered"
    # one text box instead of legends: fewer artists, a cheaper figure
    # upper right (room made above the curves): the low-frequency corner, where the
    # motion's power and a low-pass's knee are, stays clear
    ax.text(0.99, 0.97, f"{name}: {colours}; {lines}, dotted noise floor, bars: broad humps\n"
            f"peaks (strongest {LABELLED_PEAKS} per axis; rms {unit}; in % of the segments; "
            f">= {MIN_PEAK_FREQ_HZ:g} Hz, >= {10 * np.log10(MIN_PEAK_RATIO):.0f} dB above the floor)\n" + "\n".join(listing),
            transform=ax.transAxes, fontsize=7, va="top", ha="right",
            bbox={"boxstyle": "round", "fc": "white", "ec": "0.7", "alpha": 0.85})
    ax.set_yscale("log")
    shown = np.concatenate([v[sel] for v in pd["raw"] + pd["filtered"]])
    shown = shown[np.isfinite(shown) & (shown > 0)]
    if len(shown):                        # room at the top for the list of peaks
        lo, hi = float(shown.min()), float(shown.max())
        ax.set_ylim(lo / 2.0, hi * (hi / lo) ** 0.9)
    ax.yaxis.set_major_locator(LogLocator(numticks=5))
    ax.yaxis.set_minor_locator(NullLocator())
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))   # no mathtext: cheaper
    ax.set_ylabel(f"{name}\nPSD [({unit})²/Hz]", fontsize=8)
    ax.grid(True, lw=0.3)
    ax.set_xlim(0, fr[-1])
    ax.tick_params(labelsize=7)


def _draw_response(ax, items):
    """Per stream the filter's measured gain |H| (median over the axes; dashed:
    computed), and its lag (phase delay, median over the axes) at a few
    frequencies as text: a second y axis for a lag curve would cost the plot
    helper a fifth of a figure's time."""
    from matplotlib.ticker import FuncFormatter
    drawn, rows, f_max, f_min = False, [], 0.0, np.inf
    for j, (name, pd) in enumerate(items):
        fr = pd.get("response_freq_hz", pd["freq_hz"])
        sel = fr > 0
        f_max = max(f_max, fr[-1])
        f_min = min(f_min, fr[1])
        gains = [g for g in pd["gain"] if g is not None]
        colour = f"C{3 + j % 7}"
        if gains:
            g = np.median(np.vstack(gains), axis=0)
            ax.plot(fr[sel], g[sel], lw=1.0, color=colour)
            drawn = True
        if pd["computed_gain"] is not None:
            ax.plot(fr[sel], pd["computed_gain"][sel], lw=1.2, ls="--", color="k")
        if not gains:
            rows.append(f"{name}: not measured (" + ("written raw: the filter was not applied" if pd["filtered_is_raw"]
                                                   else "no segment after the filter's warm-up") + ")")
            continue
        marks = [f for f in (1.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0) if f < 0.8 * fr[-1]][-3:]
        vals = []
        for f in marks:
            b = int(np.argmin(np.abs(fr - f)))
            ok = [1000.0 * d[b] for d, gk, c in zip(pd["delay_s"], pd["gain"], pd["coherence"])
                  if d is not None and np.isfinite(d[b]) and gk[b] > 0.1 and c[b] > 0.5]
            calc = "" if pd["computed_delay_s"] is None else f" ({lag_text(1000.0 * pd['computed_delay_s'][b])})"
            vals.append(f"{lag_text(float(np.median(ok)))}{calc}" if ok else "-")
        rows.append(f"{name} ({colour_name(j)}): lag at " + " / ".join(f"{f:g}" for f in marks) +
                    " Hz: " + " / ".join(vals) + " ms")
    ax.set_ylim(0, 1.3)
    ax.set_xscale("log")                  # streams of 25 Hz and 2 kHz on one axis
    ax.set_xlim(f_min if np.isfinite(f_min) else 0.1, f_max or 1.0)
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))   # no mathtext: cheaper
    ax.set_ylabel("filter gain |H|", fontsize=8)
    ax.set_xlabel("frequency [Hz] (log)", fontsize=8)
    ax.grid(True, lw=0.3)
    ax.tick_params(labelsize=7)
    note = "measured, median over the axes" + ("; dashed: computed, lag computed in ()" if any(
        pd["computed_gain"] is not None for _, pd in items) else "")
    # low-passing filters: on a log frequency axis the bottom left is where no gain curve goes
    ax.text(0.01, 0.04, f"filter response ({note})\n" + "\n".join(rows),
            transform=ax.transAxes, ha="left", va="bottom", fontsize=7,
            bbox={"boxstyle": "round", "fc": "white", "ec": "0.7", "alpha": 0.85})
    return drawn


def colour_name(j):
    """Name of matplotlib's colour C(3 + j) (the streams' lines of the response panel)."""
    return ("red", "purple", "brown", "pink", "grey", "olive", "cyan")[j % 7]


def _draw_spectrogram(ax, name, pd):
    t, dens = pd["spectrogram"]
    fr = pd["freq_hz"]
    with np.errstate(divide="ignore"):
        db = 10.0 * np.log10(np.where(dens > 0, dens, np.nan))
    lo, hi = np.nanpercentile(db, [5, 99.5]) if np.isfinite(db).any() else (0, 1)
    im = ax.imshow(db.T, origin="lower", aspect="auto", cmap="viridis", vmin=lo, vmax=hi,
                   extent=(t[0], t[-1] if t[-1] > t[0] else t[0] + 1, 0, fr[-1]), interpolation="nearest")
    cb = ax.figure.colorbar(im, ax=ax, pad=0.01, fraction=0.025)
    cb.set_label(f"PSD [dB ({pd['unit']})²/Hz]", fontsize=7)
    cb.ax.tick_params(labelsize=7)
    ax.set_ylabel(f"{name}\nfrequency [Hz]", fontsize=8)
    ax.set_xlabel(f"time [s]; spectrogram of {name} raw, axes summed", fontsize=8)
    ax.tick_params(labelsize=7)
