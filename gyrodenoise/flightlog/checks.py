"""Checks on a stream before and after the filter: which samples are usable,
whether the filtered output may be written (the safety net), and whether the
gyro sat at its full scale.
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.analysis import motion_metrics as mm
from gyrodenoise.flightlog.streams import field_misfit, kept_restarts

#: |sample| beyond this in work units (deg/s, or raw counts when the unit is unknown)
#: is a corrupted record, not a reading (int16 counts stay below 32768)
ABSURD_WORK = 1.0e6


def usable_samples(x):
    """Bool mask of the samples of ``x`` (work units) that are readings: finite and
    within :data:`ABSURD_WORK` (DataFlash has no checksum, so a damaged record can
    decode to 1e23 rad/s)."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(x) & (np.abs(x) <= ABSURD_WORK)


def check_filtered(s, x, f, usable, causal=True, bias=None):
    """None, or one line saying why stream ``s`` must not be written filtered:
    an axis whose output (work units ``f``) is not finite or leaves the raw
    envelope of its session (:func:`gyrodenoise.analysis.motion_metrics.envelope_violation`,
    over the samples fed to the filter; the whole session's range for a zero-phase
    filter, ``causal=False``), or a value that does not fit the log's
    field type (:func:`gyrodenoise.flightlog.streams.field_misfit`).

    ``bias`` (work units, like ``f``; None: none): the bias that bias tracking removed after
    each sample (docs/method/bias.md). The check is then on what the filter clamps: causal,
    ``f + bias`` (the clamped value) inside the raw envelope; offline, ``f`` inside the envelope
    of ``x - bias`` (the samples the smoother ran on). The output is thus inside the raw
    envelope shifted by the estimated bias, nothing else."""
    problems = []
    for k, a in enumerate(s.axes):
        fin = usable[:, k]
        if not fin.any():
            continue
        raw, out = x[fin, k], f[fin, k]
        if bias is not None:
            raw, out = (raw, out + bias[fin, k]) if causal else (raw - bias[fin, k], out)
        v = mm.envelope_violation(raw, out, kept_restarts(s.restarts, fin), causal=causal)
        if v is not None:
            i = int(np.flatnonzero(fin)[v["sample"]])
            if bias is None:
                what = f"{f[i, k]:.6g} at sample {i} (t={s.time_s[i]:.3f} s)"
            elif causal:
                what = (f"{f[i, k]:.6g} at sample {i} (t={s.time_s[i]:.3f} s) plus the bias removed there "
                        f"{bias[i, k]:.6g}, {v['value']:.6g},")
            else:
                what = f"{f[i, k]:.6g} at sample {i} (t={s.time_s[i]:.3f} s), the samples less the bias removed,"
            problems.append(f"{a}: filtered value {what} {v['reason']} [{v['low']:.6g}, {v['high']:.6g}]")
    if not problems:
        bad = field_misfit(s, s.filtered) & usable
        for k, a in enumerate(s.axes):
            if bad[:, k].any():
                i = int(np.flatnonzero(bad[:, k])[0])
                problems.append(f"{a}: filtered value {s.filtered[i, k]:.6g} {s.unit} at sample {i} "
                                f"does not fit the field type {np.dtype(s.field_dtype).name}")
    return "; ".join(problems) or None


#: full scales (deg/s) of the gyros in autopilot logs: ArduPilot and PX4 set their IMUs
#: to +-2000 deg/s (a few newer ones to +-4000); a field in raw int16 counts ends at 32767
SATURATION_FULL_SCALES_DEG_S = (2000.0, 4000.0)
INT16_FULL_SCALE = 32767.0
#: a sample at or beyond this share of a full scale counts as at the full scale (a
#: calibrated reading sits a few % off the ADC's end: log171's IMU peaks at 2022.7)
SATURATION_FRACTION = 0.97
SATURATION_RULE = (f"|rate| >= {100 * SATURATION_FRACTION:g} % of a gyro full scale: "
                   f"{', '.join(f'{v:g}' for v in SATURATION_FULL_SCALES_DEG_S)} deg/s (the ranges "
                   f"ArduPilot and PX4 set), or {INT16_FULL_SCALE:g} in raw int16 counts when the unit "
                   f"is unknown; the largest full scale reached is named")


def saturation(s, x, unit):
    """None, or what says stream ``s`` (work values ``x``, (n, 3) in ``unit``) sits at
    a plausible full scale (:data:`SATURATION_RULE`): there the sensor clipped,
    the true rate may have been larger and no filter can restore it."""
    scales = SATURATION_FULL_SCALES_DEG_S if unit == "deg/s" else (
        (INT16_FULL_SCALE,) if np.dtype(s.field_dtype).kind in "iu" and s.to_deg_s is None else ())
    with np.errstate(invalid="ignore"):
        a = np.where(usable_samples(x), np.abs(x), 0.0)
    reached = [fs for fs in scales if a.max(initial=0.0) >= SATURATION_FRACTION * fs]
    if not reached:
        return None
    fs = reached[-1]
    hit = a >= SATURATION_FRACTION * fs
    i = int(np.flatnonzero(hit.any(axis=1))[0])
    k, j = np.unravel_index(int(np.argmax(a)), a.shape)[::-1]
    return {"full_scale": fs, "unit": unit, "threshold": SATURATION_FRACTION * fs,
            "samples": {ax: int(hit[:, m].sum()) for m, ax in enumerate(s.axes)},
            "first_time_s": float(s.time_s[i]), "peak": float(x[j, k]), "peak_axis": s.axes[k],
            "peak_time_s": float(s.time_s[j]), "rule": SATURATION_RULE}


def saturation_note(sat):
    """One line of the summary for a :func:`saturation` result."""
    n = ", ".join(f"{a} {v}" for a, v in sat["samples"].items() if v)
    return (f"at the gyro's full scale: {n} sample(s) at or beyond {SATURATION_FRACTION * 100:g} % of "
            f"+-{sat['full_scale']:g} {sat['unit']} (first at t={sat['first_time_s']:.2f} s; peak "
            f"{sat['peak']:.5g} on {sat['peak_axis']} at t={sat['peak_time_s']:.2f} s): likely saturated, the "
            f"true rate may have been larger there and no filter restores it")
