"""The report of a filtered stream (counts, noise, motion kept, saturation) and
the stderr lines and summary entries drawn from it.
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.analysis import motion_metrics as mm
from gyrodenoise.flightlog.checks import ABSURD_WORK, saturation
from gyrodenoise.flightlog.output import joined_time
from gyrodenoise.flightlog.streams import noise_per_axis

MOTION_METRIC = ("per axis, over each session after the filter's warm-up: the 0-5 Hz content of "
                 "raw and filtered (zero-phase Butterworth order 4, session mean removed); corr = "
                 "their correlation, amplitude_ratio = std filtered / std raw, lag_s = delay of "
                 "the filtered one at the peak of their cross-correlation (within 0.5 s); "
                 "gyrodenoise.analysis.motion_metrics")


def stream_report(s, csv_path=None, png_path=None, band_hz=None, keep=None):
    """The report of one stream: counts, noise figures and, beside them, how much
    of the low-band motion the filter kept and the lag it added
    (:mod:`gyrodenoise.analysis.motion_metrics`); a stream sampled too slowly to denoise
    gets a note instead of an improvement figure. ``keep`` (bool per sample, e.g.
    the flying samples): the noise figures are over those samples only (the others
    as gaps); the motion figures, which need whole sessions, over all."""
    band_hz = mm.LOWBAND_HZ if band_hz is None else band_hz
    x, f, unit, rate = _figure_values(s)
    slow = mm.too_slow_to_denoise(s.rate_hz, band_hz)
    unfiltered = getattr(s, "not_filtered", None)
    written_raw = slow or unfiltered or getattr(s, "left_raw", None)
    noise = None
    noise_over_note = None
    if keep is not None and not np.all(keep):
        gap = ~np.asarray(keep, dtype=bool)[:, None]
        noise, _ = _noise_figures(s, np.where(gap, np.nan, x), np.where(gap, np.nan, f), rate, slow,
                                  unfiltered, written_raw)
        if any(noise[a]["raw"] is None for a in s.axes) and np.count_nonzero(keep) < len(keep):
            # the kept (flying) stretches are too short for the estimate to form: whole log, said so
            noise = None
            noise_over_note = (f"the noise estimate does not form over the {int(np.count_nonzero(keep))} kept "
                               f"samples (it needs a finite run of {mm.noise_ready_samples()}): over the whole log")
        else:
            # the motion figures' noise level: the same sensor noise, over the kept samples where it formed
            noise_raw = [noise[a]["raw"] if noise[a]["raw"] is not None
                         else mm.white_noise_std(x[:, k], rate, s.restarts) for k, a in enumerate(s.axes)]
    if noise is None:
        noise, noise_raw = _noise_figures(s, x, f, rate, slow, unfiltered, written_raw)
    skip = int(getattr(s, "warmup_samples", 0) or 0)
    motion, warnings = _motion_figures(s, x, f, noise_raw, band_hz, skip, written_raw)
    dur = float(np.sum(np.diff(joined_time(s.time_s, s.restarts)))) if s.n > 1 else 0.0
    rep = {
        "name": s.name, "message": s.message, "field_unit": s.unit,
        "to_deg_s": s.to_deg_s, "unit_known": s.to_deg_s is not None,
        "samples": int(s.n), "rate_hz": s.rate_hz, "filter_rate_hz": rate,
        "duration_s": dur, "restarts": len(s.restart_events),
        "repeated_timestamps": int(s.repeated_timestamps),
        "non_finite_samples": dict(zip(s.axes, s.non_finite or [0] * len(s.axes))),
        "dropouts_healed": 0 if written_raw else int(sum(getattr(s, "dropouts_healed", ()))),
        "all_zero": bool(s.n and not np.any(s.raw)),
        "noise_unit": unit, "noise": noise,
        "motion_band_hz": band_hz, "warmup_samples": skip, "motion": motion,
        "too_slow_to_denoise": bool(slow),
        "left_raw": getattr(s, "left_raw", None),
        "not_filtered": unfiltered,
        "cutoff_hz": getattr(s, "cutoff_hz", None),
        "warnings": warnings,
        "saturation": saturation(s, x, unit),
    }
    if slow:
        rep["slow_note"] = (f"sampled at {_hz(s.rate_hz)} Hz, below {mm.MIN_DENOISE_RATE_HZ:g} Hz: too "
                            f"slowly to denoise (what a filter removes is motion as much as noise): "
                            f"written raw (unfiltered), no improvement figure")
    if noise_over_note:
        rep["noise_over_note"] = noise_over_note
    if s.note:
        rep["note"] = s.note
    if csv_path:
        rep["csv"] = str(csv_path)
    if png_path:
        rep["plot"] = str(png_path)
    return rep


def _figure_values(s):
    """(raw, filtered, unit, filter rate) of a filtered stream in work units, the
    corrupted samples (beyond :data:`gyrodenoise.flightlog.checks.ABSURD_WORK`) as NaN:
    they stay out of the figures."""
    x, f, unit, rate = s._work
    if np.any(np.abs(x) > ABSURD_WORK):
        bad = np.abs(x) > ABSURD_WORK
        x, f = np.where(bad, np.nan, x), np.where(bad, np.nan, f)
    return x, f, unit, rate


def _noise_figures(s, x, f, rate, slow, unfiltered, written_raw):
    """({axis: noise figures}, raw white-noise std per axis) of :data:`gyrodenoise.flightlog.streams.NOISE_METRIC`."""
    dr = noise_per_axis(x, s.restarts)       # first differences: noise + motion + vibration
    df = noise_per_axis(f, s.restarts)
    nr = [mm.white_noise_std(x[:, k], rate, s.restarts) for k in range(x.shape[1])]
    # an output written raw has the raw figures (no second run of the estimator)
    nf = nr if written_raw else [mm.white_noise_std(f[:, k], rate, s.restarts) for k in range(x.shape[1])]
    noise = {}
    for k, a in enumerate(s.axes):
        ratio = (nf[k] / nr[k]) if (nr[k] and nf[k] is not None and not slow and not unfiltered) else None
        noise[a] = {"raw": nr[k], "filtered": nf[k], "ratio": ratio,
                    "first_diff_raw": dr[k], "first_diff_filtered": df[k]}
    return noise, nr


def _motion_figures(s, x, f, noise_raw, band_hz, skip, written_raw):
    """({axis: low-band motion kept and lag, or None for a stream written raw},
    warnings where the filter removed most of the real motion)."""
    motion, warnings = {}, []
    for k, a in enumerate(s.axes):
        if written_raw:
            motion[a] = None
            continue
        kept = mm.lowband_kept(x[:, k], f[:, k], s.rate_hz, band_hz, s.restarts, skip)
        kept["lag_s"] = mm.lag_s(x[:, k], f[:, k], s.rate_hz, band_hz, s.restarts, skip)
        kept["motion_above_noise"] = mm.motion_above_noise(kept, noise_raw[k], s.rate_hz, band_hz)
        motion[a] = kept
        why = mm.motion_loss(kept, noise_raw[k], s.rate_hz, band_hz)
        if why:
            warnings.append(f"{s.name}.{a}: the filter removed most of the real motion: {why}")
    return motion, warnings


def _hz(v):
    return "unknown" if v is None else f"{v:.3g}"


def log_problems(rep, log):
    """One stderr line per stream left raw, and per motion-loss warning."""
    for s in rep["streams"]:
        if s.get("left_raw"):
            log(f"{rep['file']}: {s['name']}: NOT FILTERED: {s['left_raw']}; the stream's samples "
                f"are written RAW (unfiltered) into {rep.get('output_log')}")
        for w in s.get("warnings", []):
            log(f"{rep['file']}: warning: {w}")


def signing_problems(rep, log):
    """One stderr line on a log's / link's signed packets left raw for want of a key,
    and one on the packets that failed the signature check (from which sources)."""
    if rep.get("signed_left_raw"):
        log(f"{rep['file']}: {rep['signing_note']}")
    if rep.get("rejected_signatures"):
        log(f"{rep['file']}: {rejected_text(rep)}")


def rejected_text(rep):
    """'12 packets failed the signature check and were dropped (from 1.1: 10 unsigned, 2 bad_signature)'."""
    parts = []
    for r in rep.get("rejected_by_source", []):
        why = ", ".join(f"{r[k]} {k}" for k in ("unsigned", "mavlink1", "bad_signature", "replayed_timestamp")
                        if r.get(k))
        parts.append(f"from {r['system']}.{r['component']}: {why}")
    n = rep["rejected_signatures"]
    return (f"{n} packet{'' if n == 1 else 's'} failed the signature check and {'was' if n == 1 else 'were'} "
            f"dropped (not filtered, not written or forwarded; {'; '.join(parts)})")


def streams_left_raw(logs):
    """[{"file", "stream", "reason"}] of the streams written raw by the safety net."""
    return [{"file": r["file"], "stream": s["name"], "reason": s["left_raw"]}
            for r in logs for s in r["streams"] if s.get("left_raw")]
