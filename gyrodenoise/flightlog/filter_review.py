"""A review of the vehicle's gyro filters from a pre-filter gyro spectrum, with
recommended settings -- what ArduPilot's web Filter Review and PX4 Flight Review
do with the batch sampler and the high-rate gyro FIFO.

:func:`filter_review` picks the pre-filter stream, takes its Welch PSD per axis
(:func:`gyrodenoise.analysis.spectrum.welch_psd`; over flying time when a mask is
given), predicts the post-filter PSD ``|H|^2 x PSD`` for the logged settings and
for the recommended ones (:func:`gyrodenoise.flightlog.vehicle_filters.chain_response`),
and gives for each:

* noise: the rms (deg/s) of the predicted post-filter gyro over the band from
  :data:`NOISE_BAND_LO_HZ` (30 Hz, above a multicopter's rate-control bandwidth:
  what the filters pass there is noise the rate controller feeds back and the D
  term amplifies) to the stream's Nyquist frequency (or the filter rate's, if
  lower), per axis and root-sum-square over the axes;
* phase lag in ms at 10, 20 and 30 Hz (:func:`vehicle_filters.phase_lag_ms`).

What it recommends, and why:

* a harmonic notch on the dominant vibration at or above :data:`PEAK_MIN_HZ`:
  the narrow peaks (:func:`gyrodenoise.analysis.spectrum.find_peaks`) and the broad
  humps (:func:`gyrodenoise.flightlog.spectra.find_humps`: a motor band, which the
  peak finder never marks) of the three axes, the one with the most power above its
  floor (:func:`_peaks`; one that is the n-th harmonic of a lower one moves the notch
  to that fundamental), with the bandwidth half its centre (widened to a hump's band,
  :func:`notch_bandwidth_hz`) and
  40 dB attenuation -- the ArduPilot wiki's guidance ("Managing Gyro Noise with
  the Static Notch and Dynamic Harmonic Notch Filters", and its "Throttle Based
  Dynamic Notch Setup": ``INS_HNTCH_FREQ`` the hover frequency, ``INS_HNTCH_BW``
  hover_freq / 2, ``INS_HNTCH_REF`` the hover thrust; ``INS_HNTCH_ATT`` 40 dB is
  the parameter's default in HarmonicNotchFilter.cpp), the harmonics
  (``HMNCS``) those found at 2x..5x the fundamental. Tracking: ESC telemetry
  (``MODE`` 3) where the log holds ESC RPM, an RPM sensor (2) where it holds RPM,
  else throttle (1) with ``REF`` the hover throttle (``MOT_THST_HOVER``, else the
  log's ``CTUN.ThH``) -- the wiki: "If you do not have ESC telemetry or an RPM
  sensor [...] then throttle-based [...] center frequency control is best". PX4: a static notch ``IMU_GYRO_NF0_FRQ``
  / ``_BW`` on the peak (the same half-centre bandwidth, within its 100 Hz
  maximum), or the ESC-RPM dynamic notch (``IMU_GYRO_DNF_EN`` 1) where ESC
  status is logged.
* the gyro low-pass cutoff: the highest (whole Hz, from :data:`CUTOFF_MIN_HZ`)
  whose predicted noise, with the recommended notch, is no more than the logged
  settings' -- no more noise than today, the least phase lag that allows.
  The order is the autopilots' documented one (the ArduPilot wiki: the harmonic
  notch on the motor peak, then ``INS_GYRO_FILTER`` raised; PX4's filter tuning
  guide likewise with ``IMU_GYRO_CUTOFF``): a prominent motor peak gets its notch,
  and ``notch_prediction`` puts our predicted figures beside it (the notch's
  attenuation at the peak, the mean lag at 10, 20 and 30 Hz with it and for the
  best chain without it).

Bins above half the rate the filters run at are left out of the predicted
spectra (the filtered gyro is resampled there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrodenoise.analysis import spectrum
from gyrodenoise.core.sessions import sessions
from gyrodenoise.flightlog import spectra
from gyrodenoise.flightlog import vehicle_filters as vf
from gyrodenoise.flightlog.model import fmt_value

#: the noise band starts here (Hz)
NOISE_BAND_LO_HZ = 30.0
#: vibration peaks below this are taken as motion, not noise to notch (Hz)
PEAK_MIN_HZ = 40.0
#: phase lag is given at these frequencies (Hz)
LAG_FREQS_HZ = (10.0, 20.0, 30.0)
#: the low-pass cutoff is searched from here (Hz)
CUTOFF_MIN_HZ = 15.0
#: a pre-filter stream slower than this cannot show motor noise (Hz)
MIN_REVIEW_RATE_HZ = 100.0
#: the notch attenuation recommended (dB; ArduPilot's INS_HNTCH_ATT default)
NOTCH_ATT_DB = 40.0
#: PX4's IMU_GYRO_NF0_BW maximum (Hz)
PX4_NOTCH_BW_MAX_HZ = 100.0
#: a notch is recommended only on a peak this far above the local spectral floor (dB)
NOTCH_MIN_PROMINENCE_DB = 10.0
#: above this share of the analysed stream's rate a peak may be folded (aliased), and no
#: low-pass cutoff is recommended above it: the spectrum says little there
FOLD_SHARE = 0.4
#: PX4 IMU_GYRO_DNF_EN bits (PX4 parameter reference: "0: ESC RPM, 1: Onboard FFT")
PX4_DNF_ESC_RPM, PX4_DNF_FFT = 1, 2
PX4_DNF_URL = "https://docs.px4.io/main/en/advanced_config/parameter_reference.html#IMU_GYRO_DNF_EN"
#: streams averaged before they are logged: their peaks may be folded, whatever their frequency
AVERAGED_MESSAGES = {"sensor_combined": "sensor_combined is the estimator's IMU, averaged over the "
                                        "integration interval: motor peaks above its Nyquist frequency fold "
                                        "into it"}
AP_HNTCH_REFRESH_NOTE = ("INS_HNTCH_ENABLE was 0: ArduPilot shows the other INS_HNTCH_* parameters only once it "
                         "is 1 -- set INS_HNTCH_ENABLE,1, reboot the autopilot (or refresh the parameter list), "
                         "then load the other lines")
AXES = ("x", "y", "z")
#: the autopilots' documented tuning order, quoted beside the recommendation
AP_PROCEDURE = ("the ArduPilot wiki's order: the harmonic notch on the motor peak first, then INS_GYRO_FILTER "
                "raised as far as the noise allows")
PX4_PROCEDURE = ("PX4's filter tuning guide: notch the motor peak (dynamic notch from ESC RPM or the onboard FFT, "
                 "else a static notch), then raise IMU_GYRO_CUTOFF as far as the noise allows")


# --------------------------------------------------------------------------- context from the log

def review_context(log, autopilot, params, filters, flying_mask_fn=None):
    """What :func:`filter_review` needs from the log beyond the gyro: a dict with
    ``notch_centre_hz`` ({stage params: Hz} of the harmonic notches where the log
    tells: throttle tracking from the median ``CTUN.ThO`` over flying time (whole
    log without a mask), measured tracking from ``FTN``), ``esc_telemetry`` and
    ``rpm_sensor`` (the log holds ESC RPM / RPM messages), ``hover_throttle``
    (``MOT_THST_HOVER`` or the median ``CTUN.ThH``), PX4's ``gyro_fft`` and ``notes``;
    what each autopilot reads: its strategy's ``review_context``."""
    ctx = {"notch_centre_hz": {}, "esc_telemetry": False, "rpm_sensor": False, "hover_throttle": None,
           "notes": [], "tracks_for": lambda stages: autopilot.notch_tracks(log, params, {"stages": stages})}
    return autopilot.review_context(log, params, filters, flying_mask_fn, ctx)


def ardupilot_context(log, params, filters, flying_mask_fn, ctx):
    """:func:`review_context` of an ArduPilot log."""
    names = set(log.message_names() or [])
    ctx["esc_telemetry"] = "ESC" in names
    ctx["rpm_sensor"] = "RPM" in names
    ctun = log.messages("CTUN") if "CTUN" in names else None
    hover = params.get("MOT_THST_HOVER")
    if hover is None and ctun is not None and "ThH" in ctun and len(ctun["ThH"]):
        hover = float(np.nanmedian(ctun["ThH"]))
    ctx["hover_throttle"] = None if hover is None else float(hover)
    for st in filters.get("stages", []):
        if st["kind"] != "harmonic_notch":
            continue
        if st["tracking"] == "throttle" and ctun is not None and "ThO" in ctun:
            thr = _over_flying(ctun["time_s"], np.asarray(ctun["ThO"], dtype=np.float64), flying_mask_fn,
                               ctun.get("record"))
            if thr is not None:
                ctx["notch_centre_hz"][st["params"]] = vf.throttle_notch_centre_hz(st, thr)
                ctx["notes"].append(f"{st['params']}: throttle notch at the median throttle out "
                                    f"{thr:.3f} (CTUN.ThO): centre {ctx['notch_centre_hz'][st['params']]:.1f} Hz")
        elif st["tracking"] not in ("fixed", "throttle") and "FTN" in names:
            ftn = log.messages("FTN")
            col = next((c for c in ("NF1", "DnF1") if c in ftn), None)
            if col is not None:
                f = _over_flying(ftn["time_s"], np.asarray(ftn[col], dtype=np.float64), flying_mask_fn,
                                 ftn.get("record"))
                if f is not None and f > 0:
                    ctx["notch_centre_hz"][st["params"]] = f
                    ctx["notes"].append(f"{st['params']}: centre {f:.1f} Hz, the median FTN.{col}")
    return ctx


def px4_context(log, params, filters, flying_mask_fn, ctx):
    """:func:`review_context` of a PX4 log."""
    names = set(log.message_names() or [])
    esc = log.messages("esc_status") if "esc_status" in names else None
    ctx["esc_telemetry"] = esc is not None and any(
        np.nanmax(np.abs(np.asarray(v, dtype=np.float64)), initial=0.0) > 0
        for k, v in esc.items() if k.endswith("esc_rpm"))
    hte = log.messages("hover_thrust_estimate") if "hover_thrust_estimate" in names else None
    if hte is not None and "hover_thrust" in hte and len(hte["hover_thrust"]):
        ctx["hover_throttle"] = float(np.nanmedian(hte["hover_thrust"]))
    if "sensor_gyro_fft" in names:
        ctx["gyro_fft"] = px4_gyro_fft(log.messages("sensor_gyro_fft"), flying_mask_fn)
    return ctx


def px4_gyro_fft(m, flying_mask_fn=None):
    """What PX4's onboard gyro FFT (``sensor_gyro_fft``, computed on the raw gyro
    before any filter) found, over flying time where a mask is given: ``{"sample_rate_hz"``
    (median ``sensor_sample_rate_hz``: the raw gyro rate, the rate the filters run at),
    ``"peaks_hz"`` (the median, 10th and 90th percentile of the ``peak_frequencies_*``
    it reported, finite and positive), ``"n_peaks"``, ``"snr_median"``, ``"over"}``;
    None when it reported no peak."""
    if m is None or not len(m.get("time_s", [])):
        return None
    t = np.asarray(m["time_s"], dtype=np.float64)
    keep = np.ones(len(t), dtype=bool)
    over = "whole log"
    if flying_mask_fn is not None:
        fm = np.asarray(flying_mask_fn(t, None), dtype=bool)
        if fm.any():
            keep, over = fm, "flying"
    freq, snr = [], []
    for col in m:
        if col.startswith("peak_frequencies_"):
            f = np.asarray(m[col], dtype=np.float64)[keep]
            q = np.asarray(m.get(col.replace("peak_frequencies_", "peak_snr_"), np.full(len(t), np.nan)),
                           dtype=np.float64)[keep]
            ok = np.isfinite(f) & (f > 0)
            freq.append(f[ok])
            snr.append(q[ok])
    freq = np.concatenate(freq) if freq else np.zeros(0)
    snr = np.concatenate(snr) if snr else np.zeros(0)
    rate = np.asarray(m.get("sensor_sample_rate_hz", []), dtype=np.float64)
    rate = rate[np.isfinite(rate) & (rate > 0)]
    if not len(freq):
        return None
    p10, p50, p90 = np.percentile(freq, [10, 50, 90])
    return {"sample_rate_hz": round(float(np.median(rate)), 2) if len(rate) else None,
            "peaks_hz": {"median": round(float(p50), 1), "p10": round(float(p10), 1), "p90": round(float(p90), 1)},
            "n_peaks": int(len(freq)),
            "snr_median": round(float(np.nanmedian(snr)), 2) if np.isfinite(snr).any() else None,
            "over": over}


def _over_flying(time_s, values, flying_mask_fn, records=None):
    """The median of ``values`` over the flying samples (all without a mask); ``records``:
    the samples' records, which tell their boot in a log of several."""
    v = np.asarray(values, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    if flying_mask_fn is not None:
        m = np.asarray(flying_mask_fn(t, records), dtype=bool)
        if m.any():
            v = v[m]
    v = v[np.isfinite(v)]
    return float(np.median(v)) if len(v) else None


# --------------------------------------------------------------------------- stream choice

def stream_rate_hz(stream):
    """Sample rate (Hz) of a stream: its ``rate_hz``, else 1 / the median positive time step."""
    if getattr(stream, "rate_hz", None):
        return float(stream.rate_hz)
    dt = np.diff(np.asarray(stream.time_s, dtype=np.float64))
    dt = dt[dt > 0]
    return float(1.0 / np.median(dt)) if len(dt) else None


def pick_pre_filter_stream(streams, autopilot, params):
    """(stream, rate_hz, stages {name: stage}) of the pre-filter stream to review:
    the batch sampler logged before the filters, then PX4's high-rate gyro FIFO,
    else the highest-rate pre-filter stream; (None, None, stages) when there is none."""
    stages = {s.name: vf.stream_stage(autopilot, params, s) for s in streams}
    pre = [s for s in streams if stages[s.name] == "pre-filter" and s.n > 1]

    def rank(s):
        first = s.message == "ISBD" or s.message == "sensor_gyro_fifo"
        return (first, stream_rate_hz(s) or 0.0, s.n)
    if not pre:
        return None, None, stages
    best = max(pre, key=rank)
    return best, stream_rate_hz(best), stages


def _no_stream_note(streams, autopilot, params, stages):
    """Why no stream is fit for the review, in one line."""
    parts = []
    for s in streams:
        r = stream_rate_hz(s)
        rate = f" at {r:.0f} Hz" if r else ""
        where = {"post-filter": "after the vehicle's filters", "pre-filter": "before the vehicle's filters",
                 "unknown": "at an unknown stage"}[stages[s.name]]
        parts.append(f"{s.name} is logged {where}{rate}")
    why = "; ".join(parts) if parts else "no gyro stream"
    why += autopilot.no_stream_reason(params, streams)
    return f"no pre-filter gyro stream: {why}"


# --------------------------------------------------------------------------- the review

def _psd(stream, rate_hz, flying_mask_fn):
    """(freq_hz, psd (3, n_bins) in (deg/s)^2/Hz, n_segments, nperseg, over) or None."""
    t = np.asarray(stream.time_s, dtype=np.float64)
    x = np.asarray(stream.raw, dtype=np.float64) * (stream.to_deg_s or 1.0)
    dt = np.diff(t)
    restarts = np.r_[False, (dt <= 0) | (dt > 5.0 / rate_hz)]
    over = "whole log"
    if flying_mask_fn is not None:
        m = np.asarray(flying_mask_fn(t, stream.sample_records), dtype=bool)
        if m.any():
            x = np.where(m[:, None], x, np.nan)
            over = "flying"
    runs = [int(np.isfinite(x[a:b, 0]).sum()) for a, b in sessions(len(t), restarts)]
    longest = max(runs) if runs else 0
    if longest < 64:
        return None
    cap = 2 ** int(math.floor(math.log2(longest)))
    nperseg = max(spectrum.nperseg_for_length(int(np.isfinite(x[:, 0]).sum()), min_segments=8,
                                              min_nperseg=64, max_nperseg=min(cap, 4096)), min(128, cap))
    out, n_seg, f = [], 0, None
    for k in range(3):
        f, p, n_seg = spectrum.welch_psd(x[:, k], rate_hz, nperseg, restarts=restarts)
        if p is None:
            return None
        out.append(p)
    return f, np.array(out), n_seg, nperseg, over


def _band_rms(freq_hz, psd, lo_hz, hi_hz):
    sel = (freq_hz >= lo_hz) & (freq_hz <= hi_hz)
    df = freq_hz[1] - freq_hz[0]
    per = [float(math.sqrt(max(0.0, float(np.sum(p[sel]) * df)))) for p in psd]
    return {**{a: round(v, 5) for a, v in zip(AXES, per)}, "rss": round(math.sqrt(sum(v * v for v in per)), 5)}


@dataclass(frozen=True)
class AlongFlight:
    """The pre-filter gyro for a tracking notch modelled along the flight: ``time_s``,
    ``xyz`` (n, 3) deg/s (NaN outside the samples the review is over) at ``rate_hz``,
    the review's ``nperseg``, and ``tracks_for(stages) -> {stage params: Track}``: what
    moves each stage (the autopilot strategy's ``notch_tracks``)."""
    time_s: np.ndarray
    xyz: np.ndarray
    rate_hz: float
    nperseg: int
    tracks_for: object


def _along_flight(stream, rate_hz, flying_mask_fn, nperseg, tracks_for):
    t = np.asarray(stream.time_s, dtype=np.float64)
    x = np.asarray(stream.raw, dtype=np.float64) * (stream.to_deg_s or 1.0)
    if flying_mask_fn is not None:
        m = np.asarray(flying_mask_fn(t, stream.sample_records), dtype=bool)
        if m.any():
            x = np.where(m[:, None], x, np.nan)
    return AlongFlight(t, x, float(rate_hz), int(nperseg), tracks_for)


def chain_power(stages, f, fs_filter, centre, along=None):
    """|H(f)|**2 of the chain, (bins,) or per axis (3, bins). With ``along`` (an
    :class:`AlongFlight` at the rate the filters run at) and a tracking stage whose
    track the log holds: the tracking stages replayed sample by sample along the flight
    (:func:`~gyrodenoise.flightlog.vehicle_filters.replay_sections`,
    :func:`~gyrodenoise.flightlog.notch_replay.run_biquads`: the centre moved with the
    throttle / RPM / FFT as the autopilot moves it), their power response the Welch
    spectrum of that replay over the pre-filter one, times the fixed stages' |H|**2;
    else at ``centre`` (one centre per log)."""
    from gyrodenoise.flightlog import notch_replay as nr

    tracked = [st for st in stages if st["kind"] == "harmonic_notch" and st.get("tracking") not in (None, "fixed")]
    tracks = along.tracks_for(tracked) if along is not None and tracked else {}
    tracked = [st for st in tracked if st["params"] in tracks]
    if not tracked or abs(along.rate_hz - fs_filter) > 0.02 * fs_filter:
        return np.abs(vf.chain_response(stages, f, fs_filter, centre)) ** 2
    coefs, _ = vf.replay_sections(tracked, tracks, along.time_s, fs_filter, None, slew=False)
    y = nr.run_biquads(along.xyz, coefs)
    ratio = []
    for k in range(3):
        _, p_in, _ = spectrum.welch_psd(along.xyz[:, k], along.rate_hz, along.nperseg)
        _, p_out, _ = spectrum.welch_psd(y[:, k], along.rate_hz, along.nperseg)
        if p_in is None or p_out is None:
            return np.abs(vf.chain_response(stages, f, fs_filter, centre)) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio.append(np.where(p_in > 0, p_out / p_in, 1.0)[:len(f)])
    fixed = [st for st in stages if st not in tracked]
    return np.array(ratio) * (np.abs(vf.chain_response(fixed, f, fs_filter, centre)) ** 2)[None, :]


def _figures(stages, f, psd, fs_filter, band, centre, along=None):
    post = psd * chain_power(stages, f, fs_filter, centre, along)
    lags = vf.phase_lag_ms(stages, LAG_FREQS_HZ, fs_filter, centre)
    return post, {"noise_rms_deg_s": _band_rms(f, post, *band),
                  "phase_lag_ms": {f"{q:g}": round(v, 3) for q, v in zip(LAG_FREQS_HZ, lags)}}


def _peaks(f, psd, n_seg, fs, eligible=None):
    """(peaks, humps, fundamental or None): the strongest narrow peaks and broad humps
    (each with ``notch_ok`` and, where not, ``why_not``) and the fundamental a notch would
    sit on, from the candidates ``eligible(candidate) -> "" | reason`` lets through.

    Two finders, because a motor band and a line are different things: the narrow-peak
    finder (:func:`gyrodenoise.analysis.spectrum.find_peaks`) sees a line standing above
    a floor some tens of bins wide, and never a band 0.3 octave wide, which *is* that
    floor; the hump finder (:func:`gyrodenoise.flightlog.spectra.find_humps`) sees the
    band -- the motor noise wandering with the throttle that a tuner puts the notch on.
    The dominant candidate is the one with the most power above its floor
    (``amplitude_rms``: over a line's 7 bins, over a hump's band); a harmonic moves the
    notch to its fundamental (a hump's from the humps of its axis, a line's from the
    lines')."""
    found, humps = [], []
    for k, a in enumerate(AXES):
        for q in spectrum.find_peaks(f, psd[k], n_seg, min_freq_hz=PEAK_MIN_HZ):
            q = dict(q)
            q["axis"] = a
            q["why_not"] = eligible(q) if eligible is not None else ""
            found.append(q)
        for h in spectra.find_humps(f, psd[k], min_freq_hz=PEAK_MIN_HZ):
            h = dict(h, axis=a, ratio_db=h["above_floor_db"], kind="hump")
            h["why_not"] = eligible(h) if eligible is not None else ""
            humps.append(h)
    peaks = [{"freq_hz": round(float(q["freq_hz"]), 2), "axis": q["axis"],
              "amplitude_rms_deg_s": round(float(q["amplitude_rms"]), 5), "ratio_db": round(float(q["ratio_db"]), 2),
              "notch_ok": not q["why_not"], **({"why_not": q["why_not"]} if q["why_not"] else {})}
             for q in sorted(found, key=lambda q: -q["amplitude_rms"])[:8]]
    hump_list = [{"freq_hz": round(float(h["freq_hz"]), 2), "lo_hz": round(float(h["lo_hz"]), 2),
                  "hi_hz": round(float(h["hi_hz"]), 2), "axis": h["axis"],
                  "amplitude_rms_deg_s": round(float(h["amplitude_rms"]), 5), "ratio_db": round(float(h["ratio_db"]), 2),
                  "harmonic_of_hz": None if h["harmonic_of_hz"] is None else round(float(h["harmonic_of_hz"]), 2),
                  "harmonic_n": int(h["harmonic_n"]),
                  "notch_ok": not h["why_not"], **({"why_not": h["why_not"]} if h["why_not"] else {})}
                 for h in sorted(humps, key=lambda q: -q["amplitude_rms"])[:8]]
    lines = [q for q in found if not q["why_not"]]
    bands = [h for h in humps if not h["why_not"]]
    if not lines and not bands:
        return peaks, hump_list, None
    dom = max(lines + bands, key=lambda q: q["amplitude_rms"])
    if dom.get("kind") == "hump":
        return peaks, hump_list, _hump_fundamental(dom, [h for h in humps if h["axis"] == dom["axis"]])
    same_axis = [q for q in lines if q["axis"] == dom["axis"]]
    df = f[1] - f[0]
    grouped = spectrum.group_harmonics(same_axis, df)
    fund = dom
    if dom.get("harmonic_of_hz"):
        fund = next(q for q in grouped if q["freq_hz"] == dom["harmonic_of_hz"])
    harmonics = sorted({1} | {q["harmonic_n"] for q in grouped if q.get("harmonic_of_hz") == fund["freq_hz"]})
    half = spectrum.PEAK_HALF_WIDTH_BINS * df
    return peaks, hump_list, {"freq_hz": float(fund["freq_hz"]), "axis": fund["axis"], "harmonics": harmonics,
                              "kind": "line", "band_hz": [float(fund["freq_hz"]) - half, float(fund["freq_hz"]) + half]}


def _hump_fundamental(dom, axis_humps):
    """The fundamental of the dominant hump ``dom``: the hump of its axis it is a harmonic
    of (found 6 dB or more over the floor, ``find_humps``; the fundamental need not be the
    strongest), else itself; its harmonics those of the axis' humps that are n x it."""
    fund = dom
    if dom.get("harmonic_of_hz"):
        fund = next((h for h in axis_humps if h["freq_hz"] == dom["harmonic_of_hz"]), dom)
    harmonics = sorted({1} | {int(h["harmonic_n"]) for h in axis_humps if h.get("harmonic_of_hz") == fund["freq_hz"]})
    return {"freq_hz": float(fund["freq_hz"]), "axis": fund["axis"], "harmonics": harmonics, "kind": "hump",
            "band_hz": [float(fund["lo_hz"]), float(fund["hi_hz"])]}


def _fund_text(fund):
    """What the notch sits on, in words: 'the broad hump 113-147 Hz (centre 128 Hz)' or
    'the vibration peak at 123.4 Hz'."""
    if fund.get("kind") == "hump":
        lo, hi = fund["band_hz"]
        return f"the broad hump {lo:.0f}-{hi:.0f} Hz (centre {fund['freq_hz']:.1f} Hz)"
    return f"the vibration peak at {fund['freq_hz']:.1f} Hz"


def _bw_text(fund):
    return ("half the centre, widened to the hump's band where that is wider" if fund.get("kind") == "hump"
            else "half the centre, the ArduPilot wiki's rule")


def notch_bandwidth_hz(fund):
    """The notch's bandwidth (Hz) on ``fund``: half its centre -- the ArduPilot wiki's
    ``INS_HNTCH_BW`` = hover_freq / 2 ("Throttle Based Dynamic Notch Setup",
    https://ardupilot.org/copter/docs/common-throttle-based-notch.html; "half of
    INS_HNTCH_FREQ" in its RPM-sensor setup) -- widened to the hump's band
    (``hi - lo``, where it stays above half its height) when the band is wider: a
    notch narrower than the motor band leaves its shoulders."""
    bw = fund["freq_hz"] / 2.0
    if fund.get("kind") == "hump":
        lo, hi = fund["band_hz"]
        bw = max(bw, hi - lo)
    return round(bw, 1)


def px4_dynamic_notch(params, ctx):
    """({NAME: value}, reasons) of PX4's dynamic notch where the log shows what drives it:
    the onboard FFT's peaks (``sensor_gyro_fft``, computed on the raw gyro) or ESC RPM
    (``esc_status``); ({}, []) where it shows neither."""
    fft = ctx.get("gyro_fft")
    dnf = int(float(params.get("IMU_GYRO_DNF_EN", 0) or 0))
    rec, why = {}, []
    if fft is not None:
        pk = fft["peaks_hz"]
        if dnf & PX4_DNF_FFT:
            why.append(f"the onboard FFT (sensor_gyro_fft) puts the motor peaks at {pk['p10']:g}-{pk['p90']:g} Hz "
                       f"(median {pk['median']:g}) and its dynamic notch is on (IMU_GYRO_DNF_EN bit 1): no change")
        else:
            rec["IMU_GYRO_DNF_EN"] = dnf | PX4_DNF_FFT
            if int(float(params.get("IMU_GYRO_FFT_EN", 0) or 0)) != 1:
                rec["IMU_GYRO_FFT_EN"] = 1
            why.append(f"the onboard FFT (sensor_gyro_fft, on the raw gyro at {fft['sample_rate_hz']} Hz) puts the "
                       f"motor peaks at {pk['p10']:g}-{pk['p90']:g} Hz (median {pk['median']:g}, {fft['n_peaks']} "
                       f"peaks over {fft['over']}) but IMU_GYRO_DNF_EN {dnf} does not use it: enable the FFT-driven "
                       f"dynamic notch, IMU_GYRO_DNF_EN bit 1 (value {dnf | PX4_DNF_FFT}; {PX4_DNF_URL})")
    if ctx.get("esc_telemetry") and not dnf & PX4_DNF_ESC_RPM:
        rec["IMU_GYRO_DNF_EN"] = rec.get("IMU_GYRO_DNF_EN", dnf) | PX4_DNF_ESC_RPM
        why.append("ESC status (esc_status) is logged: the ESC-RPM dynamic notch, IMU_GYRO_DNF_EN bit 0 "
                   f"({PX4_DNF_URL})")
    return rec, why


def _recommend_notch(autopilot, params, filters, fund, ctx, fs_filter):
    """({NAME: value}, stage or None, reasons) of the recommended notch."""
    if fund is None:
        return {}, None, [f"no vibration peak or broad hump at or above {PEAK_MIN_HZ:g} Hz fit for a notch (the "
                          "rules: at least "
                          f"{NOTCH_MIN_PROMINENCE_DB:g} dB above the local floor, at most {FOLD_SHARE:g} x the "
                          "stream's rate, from a stream that is not averaged): no static notch recommended"]
    centre = round(fund["freq_hz"], 1)
    return autopilot.recommend_notch(params, fund, ctx, centre, notch_bandwidth_hz(fund))


#: what moves ArduPilot's harmonic notch in each INS_HNTCH_MODE this review recommends
AP_MODE_TRACKING = {1: "throttle", 2: "rpm", 3: "esc"}


def ardupilot_notch(params, fund, ctx, centre, bw):
    """({NAME: value}, stage, reasons) of ArduPilot's recommended harmonic notch."""
    why = []
    hm = sum(1 << (n - 1) for n in fund["harmonics"])
    if ctx.get("esc_telemetry"):
        mode, ref, how = 3, 1.0, "ESC telemetry is logged: the notch follows the motors' RPM"
    elif ctx.get("rpm_sensor"):
        mode, ref, how = 2, 1.0, "an RPM sensor is logged: the notch follows it"
    else:
        hover = ctx.get("hover_throttle") or params.get("MOT_THST_HOVER")
        logged_ref = params.get("INS_HNTCH_REF")
        ref = round(float(hover), 3) if hover else (float(logged_ref) if logged_ref else 0.35)
        mode = 1
        how = ("no RPM or ESC telemetry in the log: throttle tracking, REF the hover throttle "
               f"({'MOT_THST_HOVER/CTUN.ThH' if hover else 'assumed'} {ref})")
    rec = {"INS_HNTCH_ENABLE": 1, "INS_HNTCH_MODE": mode, "INS_HNTCH_FREQ": centre, "INS_HNTCH_BW": bw,
           "INS_HNTCH_ATT": NOTCH_ATT_DB, "INS_HNTCH_HMNCS": hm, "INS_HNTCH_REF": ref}
    stage = {"kind": "harmonic_notch", "path": "rate", "params": "INS_HNTCH_*", "centre_hz": centre,
             "bandwidth_hz": bw, "attenuation_db": NOTCH_ATT_DB, "harmonics": fund["harmonics"],
             "tracking": AP_MODE_TRACKING[mode], "composite": 1, "reference": ref, "min_ratio": 1.0}
    why.append(f"dominant vibration: {_fund_text(fund)} ({fund['axis']} axis), harmonics {fund['harmonics']}: "
               f"harmonic notch at {centre:g} Hz, BW {bw:g} Hz ({_bw_text(fund)}), ATT {NOTCH_ATT_DB:g} dB; {how}; "
               f"{AP_PROCEDURE}")
    return rec, stage, why


def px4_notch(params, fund, ctx, centre, bw):
    """({NAME: value}, stage, reasons) of PX4's recommended notch."""
    why = []
    bw = min(bw, PX4_NOTCH_BW_MAX_HZ)
    if ctx.get("esc_telemetry"):
        rec = {"IMU_GYRO_DNF_EN": int(float(params.get("IMU_GYRO_DNF_EN", 0) or 0)) | PX4_DNF_ESC_RPM,
               "IMU_GYRO_DNF_HMC": max(fund["harmonics"]), "IMU_GYRO_DNF_MIN": round(0.5 * centre, 1)}
        why.append(f"dominant vibration: {_fund_text(fund)}: ESC status is logged, ESC-RPM dynamic notch; "
                   f"{PX4_PROCEDURE}")
        stage = {"kind": "notch", "path": "rate", "form": "px4", "params": "IMU_GYRO_DNF_*",
                 "centre_hz": centre, "bandwidth_hz": float(params.get("IMU_GYRO_DNF_BW", 15.0)),
                 "attenuation_db": None}
        return rec, stage, why
    rec = {"IMU_GYRO_NF0_FRQ": centre, "IMU_GYRO_NF0_BW": bw}
    why.append(f"dominant vibration: {_fund_text(fund)} ({fund['axis']} axis): static notch IMU_GYRO_NF0 at "
               f"{centre:g} Hz, BW {bw:g} Hz ({_bw_text(fund)}, at most {PX4_NOTCH_BW_MAX_HZ:g} Hz); no ESC telemetry "
               f"in the log for the dynamic notch; {PX4_PROCEDURE}")
    stage = {"kind": "notch", "path": "rate", "form": "px4", "params": "IMU_GYRO_NF0_FRQ, IMU_GYRO_NF0_BW",
             "centre_hz": centre, "bandwidth_hz": bw, "attenuation_db": None}
    return rec, stage, why


def _best_chain(logged_stages, notch_stage, f, psd, fs_filter, band, centre, target, lp_name, cap_hz=None,
                along=None):
    """(stages, cutoff_hz or None, notch centres) of the recommended chain: ``notch_stage``
    (if any) in place of the logged stage it sets, the other logged notches as they
    are, and the highest whole-Hz low-pass cutoff whose predicted noise is no more
    than ``target`` (None when none is)."""
    replaced = notch_stage["params"] if notch_stage else None
    base = ([notch_stage] if notch_stage else []) + [
        s for s in logged_stages
        if s.get("path", "rate") == "rate" and s["kind"] != "lowpass" and s["params"] != replaced]
    rec_centre = ({k: v for k, v in centre.items() if k != replaced} or None) if isinstance(centre, dict) else None
    p_base = psd * chain_power(base, f, fs_filter, rec_centre, along)
    best = None
    top = min(0.45 * fs_filter, band[1], cap_hz if cap_hz else np.inf)
    for fc in range(int(CUTOFF_MIN_HZ), int(top) + 1):
        lp = vf.lowpass2p_sos(float(fc), fs_filter)
        if _band_rms(f, p_base * np.abs(vf.sos_response([lp], f, fs_filter)) ** 2, *band)["rss"] <= target * (1 + 1e-9):
            best = fc
    stages = base + ([{"kind": "lowpass", "path": "rate", "params": lp_name or "lowpass", "cutoff_hz": float(best)}]
                     if best else [])
    return stages, best, rec_centre


def _notch_prediction(notch_stage, fund, f, psd, fs_filter, with_notch, without, logged_lp):
    """What the recommended notch is predicted to do: its attenuation (dB) at the peak, the
    rss noise over the band's axis of the peak before and after the whole recommended chain,
    and the mean lag with it and for the best chain without it."""
    sos, _ = vf.chain_sections([notch_stage], fs_filter)
    g = abs(complex(vf.sos_response(sos, [fund["freq_hz"]], fs_filter)[0]))
    # the band's power through the notch alone: sum(|H|^2 PSD) / sum(PSD) over the hump's
    # lo..hi (a line: its 7 bins), on the axis it was found on
    lo, hi = fund["band_hz"]
    sel = (f >= lo) & (f <= hi)
    p_axis = psd[AXES.index(fund["axis"])][sel]
    h2 = np.abs(vf.sos_response(sos, f[sel], fs_filter)) ** 2
    through = float(np.sum(h2 * p_axis)) / max(float(np.sum(p_axis)), 1e-300)
    return {"peak_hz": round(float(fund["freq_hz"]), 2), "kind": fund.get("kind", "line"),
            "band_hz": [round(float(lo), 2), round(float(hi), 2)],
            "attenuation_at_peak_db": round(-20.0 * math.log10(max(g, 1e-12)), 1),
            "attenuation_of_band_db": round(-10.0 * math.log10(max(through, 1e-12)), 1),
            "mean_lag_ms_with_notch": round(_mean_lag(with_notch, logged_lp, fs_filter), 3),
            "mean_lag_ms_without": round(_mean_lag(without, logged_lp, fs_filter), 3)}


def _mean_lag(chain, logged_lp, fs_filter):
    stages, best, centre = chain
    if best is None:
        stages = stages + logged_lp
    return float(np.mean(vf.phase_lag_ms(stages, LAG_FREQS_HZ, fs_filter, centre)))


@dataclass(frozen=True)
class ReviewPlot:
    """The filter review's spectra for the plots: the pre-filter PSD and the predicted
    post-filter PSDs of the logged and the recommended settings, ((deg/s)^2/Hz, one row
    per axis of :data:`AXES`) at ``freq_hz``."""
    freq_hz: np.ndarray
    psd_pre: np.ndarray
    psd_logged: np.ndarray
    psd_recommended: np.ndarray
    axes: tuple = AXES


def filter_review(streams, autopilot, params, filters, flying_mask_fn=None, context=None):
    """(review or None, note, plot or None) of the vehicle's gyro filters from a pre-filter
    gyro stream.

    ``streams``: the log's gyro streams (:func:`gyrodenoise.flightlog.formats.read_log`);
    ``params``/``filters``: :func:`gyrodenoise.flightlog.parameters.log_parameters` and
    :func:`gyrodenoise.flightlog.vehicle_filters.vehicle_filters`;
    ``flying_mask_fn(time_s, records) -> bool array``: the flying samples (``records``: the
    samples' records, which tell their boot, or None) (whole log when
    None or when no pre-filter sample is flying); ``context``: :func:`review_context`.

    The review (JSON-able; its spectra for the plots apart, a :class:`ReviewPlot`): ``source`` (stream, rate, what the PSD is over),
    ``filter_rate_hz``, ``noise_band_hz``, ``peaks``, ``figures`` {``pre_filter``,
    ``logged``, ``recommended``: ``noise_rms_deg_s`` per axis and ``rss``, and
    (the last two) ``phase_lag_ms`` at 10/20/30 Hz}, ``logged`` {NAME: value},
    ``recommended`` {NAME: value}, ``param_lines``, ``why``, ``notes``. None and a
    one-line note naming why when there is no usable pre-filter stream."""
    params = params or {}
    ctx = context or {}
    ap = autopilot
    stream, rate, stages = pick_pre_filter_stream(streams, ap, params)
    if stream is None:
        return None, _no_stream_note(streams, autopilot, params, stages), None
    if rate is None or rate < MIN_REVIEW_RATE_HZ:
        return None, (f"no pre-filter gyro stream fast enough: {stream.name} is pre-filter but at "
                      f"{rate or 0:.0f} Hz (below {MIN_REVIEW_RATE_HZ:g} Hz it cannot show motor noise)"), None
    spec = _psd(stream, rate, flying_mask_fn)
    if spec is None:
        return None, f"{stream.name}: too few contiguous samples for a spectrum (64 needed)", None
    f, psd, n_seg, nperseg, over = spec
    notes = list(ctx.get("notes", []))
    fs_filter, fs_src = filters.get("filter_rate_hz"), filters.get("filter_rate_source")
    own_rate = ap.review_filter_rate(stream, rate, params, ctx)
    if own_rate is not None:
        fs_filter, fs_src = own_rate
    fft = ctx.get("gyro_fft")
    if not fs_filter:
        fs_filter, fs_src = rate, "assumed: the pre-filter stream's rate"
    keep = f < 0.5 * fs_filter
    f, psd = f[keep], psd[:, keep]
    band = (NOISE_BAND_LO_HZ, float(f[-1]))
    centre = ctx.get("notch_centre_hz") or None
    logged_stages = [st for st in filters.get("stages", []) if st.get("path", "rate") == "rate"]
    _, logged_notes = vf.chain_sections(logged_stages, fs_filter, centre)
    notes += logged_notes
    averaged = AVERAGED_MESSAGES.get(stream.message)
    fold_hz = FOLD_SHARE * rate
    if averaged:
        notes.append(f"{averaged} (IMU_INTEG_RATE {fmt_value(params.get('IMU_INTEG_RATE'))} Hz; attenuated near its "
                     "Nyquist frequency): no static notch is recommended from its peaks")

    def eligible(q):
        if averaged:
            return f"{stream.message} is averaged: the peak may be folded"
        top = q.get("hi_hz", q["freq_hz"])            # a hump: its whole band
        if top > fold_hz:
            return f"above {FOLD_SHARE:g} x the stream's rate ({fold_hz:.0f} Hz): may be folded"
        if q["ratio_db"] < NOTCH_MIN_PROMINENCE_DB:
            return f"{q['ratio_db']:.1f} dB above the floor, below the {NOTCH_MIN_PROMINENCE_DB:g} dB a notch needs"
        return ""

    along = None if ctx.get("tracks_for") is None else _along_flight(stream, rate, flying_mask_fn, nperseg,
                                                                       ctx["tracks_for"])
    post_logged, fig_logged = _figures(logged_stages, f, psd, fs_filter, band, centre, along)
    peaks, humps, fund = _peaks(f, psd, n_seg, rate, eligible)
    rec, notch_stage, why = _recommend_notch(autopilot, params, filters, fund, ctx, fs_filter)
    if notch_stage is None:
        dyn_rec, dyn_why = ap.recommend_without_notch(params, ctx)
        rec.update(dyn_rec)
        why += dyn_why

    lp_name = ap.lowpass_param(params)
    target = fig_logged["noise_rms_deg_s"]["rss"]
    logged_lp = [s for s in logged_stages if s["kind"] == "lowpass"]
    with_notch = _best_chain(logged_stages, notch_stage, f, psd, fs_filter, band, centre, target, lp_name, fold_hz,
                             along)
    without = _best_chain(logged_stages, None, f, psd, fs_filter, band, centre, target, lp_name, fold_hz, along)
    predicted = None
    if notch_stage is not None:
        # the autopilots' documented procedure: the notch on the motor peak first, then the
        # low-pass raised as far as the noise allows; the prediction stands beside it
        predicted = _notch_prediction(notch_stage, fund, f, psd, fs_filter, with_notch, without, logged_lp)
        why.append(f"predicted: the notch takes {predicted['attenuation_at_peak_db']:g} dB off the peak at "
                   f"{notch_stage['centre_hz']:g} Hz and {predicted['attenuation_of_band_db']:g} dB off the power of "
                   f"{predicted['band_hz'][0]:.0f}-{predicted['band_hz'][1]:.0f} Hz; mean lag at {', '.join(f'{q:g}' for q in LAG_FREQS_HZ)} Hz "
                   f"{predicted['mean_lag_ms_with_notch']:g} ms with it, {predicted['mean_lag_ms_without']:g} ms "
                   "for the best chain without it")
    rec_stages, best, rec_centre = with_notch if notch_stage is not None else without
    if not lp_name:
        rec_stages = [st for st in rec_stages if st["kind"] != "lowpass"] + logged_lp
        why.append(f"low-pass cutoffs left as logged: no low-pass parameter is recommended for {ap.name}")
    elif best is None:
        why.append(f"no cutoff from {CUTOFF_MIN_HZ:g} Hz keeps the noise at the logged settings' "
                   f"{target:.3g} deg/s: low-pass cutoff left as logged")
        rec_stages = rec_stages + logged_lp
    elif lp_name:
        rec[lp_name] = best
        capped = " (searched up to %.0f Hz, %g x the stream's rate: the spectrum says little above)" % (
            fold_hz, FOLD_SHARE) if best >= int(fold_hz) else ""
        why.append(f"{lp_name} {best}: the highest cutoff whose predicted noise ({NOISE_BAND_LO_HZ:g} Hz.."
                   f"{band[1]:.0f} Hz) is no more than the logged settings' ({target:.3g} deg/s rss){capped}")
    post_rec, fig_rec = _figures(rec_stages, f, psd, fs_filter, band, rec_centre, along)
    fig_pre = {"noise_rms_deg_s": _band_rms(f, psd, *band)}
    logged_params = filters.get("parameters", {})
    rec = {k: vf._jsonable(v) for k, v in rec.items()}
    changes = {k: v for k, v in rec.items() if not _same(logged_params.get(k), v)}
    for st in logged_stages:                # the logged notches the recommendation keeps
        if st["kind"] != "lowpass" and (notch_stage is None or st["params"] != notch_stage["params"]):
            why.append(f"{st['params']} ({_stage_text(st)}): logged on, kept as logged")
    if changes.get("INS_HNTCH_ENABLE") == 1:
        notes.append(AP_HNTCH_REFRESH_NOTE)
        changes = {"INS_HNTCH_ENABLE": 1, **{k: v for k, v in changes.items() if k != "INS_HNTCH_ENABLE"}}
    review = {
        "source": {"stream": stream.name, "message": stream.message, "stage": "pre-filter",
                   "sample_rate_hz": round(rate, 3), "n_samples": int(stream.n), "over": over,
                   "nperseg": int(nperseg), "resolution_hz": round(float(f[1] - f[0]), 4),
                   "n_segments": int(n_seg), "averaged": bool(averaged), "fold_hz": round(fold_hz, 1)},
        "filter_rate_hz": float(fs_filter), "filter_rate_source": fs_src,
        "noise_band_hz": [band[0], round(band[1], 3)],
        "noise_metric": (f"rms of the predicted post-filter gyro (deg/s) over {band[0]:g}..{band[1]:.0f} Hz: "
                         "sqrt(sum(|H|^2 PSD) df) per axis, rss over the axes"),
        "notch_rule": (f"a static or harmonic notch only on a peak or a broad hump at or above {PEAK_MIN_HZ:g} Hz, "
                       f"at least {NOTCH_MIN_PROMINENCE_DB:g} dB above the local floor, at most {FOLD_SHARE:g} x the "
                       "analysed stream's rate (a hump: its whole band), from a stream that is not averaged; the "
                       "strongest (power above its floor) sets the notch, a harmonic moves it to its fundamental; "
                       "bandwidth half the centre, widened to a hump's band; no low-pass cutoff above "
                       f"{FOLD_SHARE:g} x that rate"),
        "peaks": peaks,
        "humps": humps,
        "onboard_fft": fft,
        "figures": {"pre_filter": fig_pre, "logged": fig_logged, "recommended": fig_rec},
        "logged": {k: v for k, v in logged_params.items() if k in rec or _in_stages(k, logged_stages)},
        "logged_stages": logged_stages,
        "recommended": rec,
        "recommended_stages": rec_stages,
        "changes": changes,
        "verdict": "change" if changes else "no change",
        "param_lines": param_lines(autopilot, changes),
        "notch_prediction": predicted,
        "why": why,
        "notes": notes,
    }
    plot = ReviewPlot(freq_hz=f, psd_pre=psd, psd_logged=post_logged, psd_recommended=post_rec)
    if not changes:
        review["why"].append("no change: every recommended value is the logged one")
    return review, "", plot


def _same(logged, value):
    """Whether a logged parameter value and a recommended one are the same setting."""
    try:
        return logged is not None and math.isclose(float(logged), float(value), rel_tol=1e-6, abs_tol=1e-6)
    except (TypeError, ValueError):
        return False


def _in_stages(name, stages):
    """Whether parameter ``name`` sets one of ``stages`` (their ``params``: a name, a
    ``PREFIX_*`` or a comma-separated list)."""
    for st in stages:
        for p in str(st.get("params", "")).split(","):
            p = p.strip()
            if name == p or (p.endswith("*") and name.startswith(p[:-1])):
                return True
    return False


def _stage_text(st):
    """A stage's settings in a few words, e.g. 'harmonic_notch 97 Hz, BW 25 Hz, 6 dB, throttle'."""
    parts = [st["kind"]]
    if st.get("centre_hz") is not None:
        parts.append(f"{fmt_value(float(st['centre_hz']))} Hz")
    if st.get("bandwidth_hz") is not None:
        parts.append(f"BW {fmt_value(float(st['bandwidth_hz']))} Hz")
    if st.get("attenuation_db") is not None:
        parts.append(f"{fmt_value(float(st['attenuation_db']))} dB")
    if st.get("tracking"):
        parts.append(str(st["tracking"]))
    if st.get("sources"):
        parts.append("/".join(st["sources"]))
    return ", ".join(parts[:1]) + (" " + ", ".join(parts[1:]) if len(parts) > 1 else "")


def param_lines(autopilot, rec):
    """Lines to paste: ArduPilot parameter-file ``NAME,VALUE``; PX4 console ``param set NAME VALUE``
    (the strategy's ``param_lines``)."""
    return autopilot.param_lines(rec)
