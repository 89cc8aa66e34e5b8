"""Scoring methods against the tuned baselines.

API (stable; the filter work calls it)::

    from benchmarks.motion_bench import bench
    rows = bench.evaluate({"mine": fn}, sensors=None, profiles=None, seeds=(0, 1, 2), quick=False)
    summary = bench.summarise(rows)            # geometric means per method and sensor
    gains = bench.gain_table({"mine": fn}, quick=True)
    lines = bench.goal_lines(rows, gains)      # [(method, goal, value, PASS/FAIL)]

``fn(rate_deg_s: ndarray, sample_rate_hz: float) -> ndarray`` (same length).

Per run (sensor x profile x seed) the tuned baselines of :mod:`benchmarks.motion_bench.baselines`
are tuned against the reference and every method is scored on the same
evaluation window (after ``SKIP_S``):

* ``rmse``: RMSE against the reference (true rate + slow sensor bias), deg/s;
* ``ratio_causal``: rmse / the best tuned causal filter's (raw included);
* ``ratio_noncausal``: rmse / the best tuned non-causal filter's;
* ``ratio_raw``: rmse / raw's;
* ``lag_ms``: delay of the output behind the reference (cross-correlation peak of
  both low-passed below 10 Hz, parabolic refinement), moving profiles only;
* ``angle_err_deg`` / ``angle_err_raw_deg``: |integral of (output - reference)|
  over the window after ``SKIP_S`` (60 s in the full run).

Ratios are geometric means over seeds; angle errors RMS over seeds; lag mean.

``rigid=True`` ("vibration counted as error"): the reference is
the true rate *without the frame vibration* plus the slow bias (a user who states
a band of interest counts the vibration as error), the baselines are tuned against
that, and every row also carries ``ratio_lowpass``: rmse / the best tuned
low-pass (Butterworth order 1 or 2 over the cutoff grid).
"""

from __future__ import annotations

import math
import time

import numpy as np

from benchmarks.motion_bench import baselines as B
from benchmarks.motion_bench import sim

SKIP_S = 2.0
ANGLE_WINDOW_S = 60.0
LAG_MAX_S = 0.5
LAG_BAND_HZ = 10.0


def durations(quick):
    """Record length (s): 2 s warm-up + 60 s scored (full), 2 + 10 s (quick)."""
    return SKIP_S + (10.0 if quick else ANGLE_WINDOW_S)


def package_methods(names=("motion", "shakf", "kf", "lowpass", "none")):
    """gd.denoise(rate, fs, method=name) for each name, as method functions."""
    import gyrodenoise as gd

    def make(name):
        def fn(rate_deg_s, sample_rate_hz):
            return gd.denoise(rate_deg_s, sample_rate_hz, method=name)
        fn.__name__ = name
        return fn
    return {n: make(n) for n in names}


def rigid_methods(max_motion_hz=(20.0,), offline=True):
    """``motion`` with the rigid-body option at each stated band, causal
    (``motion@<hz>``) and, with ``offline``, its offline form (``motion_offline@<hz>``)."""
    import gyrodenoise as gd

    def make(hz, off):
        def fn(rate_deg_s, sample_rate_hz):
            return gd.denoise(rate_deg_s, sample_rate_hz, max_motion_hz=hz, offline=off)
        fn.__name__ = f"motion{'_offline' if off else ''}@{hz:g}"
        return fn
    out = {}
    for hz in max_motion_hz:
        for off in ((False, True) if offline else (False,)):
            fn = make(float(hz), off)
            out[fn.__name__] = fn
    return out


def load_method(spec):
    """{name: fn} for a gd.denoise method name or ``FILE.py:FUNCTION``; ValueError
    (one line naming the option) when neither."""
    import importlib.util
    from pathlib import Path

    from gyrodenoise.core import kernels as K
    if ":" in spec and spec.split(":", 1)[0].endswith(".py"):
        path, func = spec.split(":", 1)
        if not Path(path).is_file():
            raise ValueError(f"--method {spec}: no file {path}")
        mod_spec = importlib.util.spec_from_file_location(Path(path).stem, path)
        mod = importlib.util.module_from_spec(mod_spec)
        mod_spec.loader.exec_module(mod)
        if not callable(getattr(mod, func, None)):
            raise ValueError(f"--method {spec}: {path} has no function {func}")
        return {f"{Path(path).stem}:{func}": getattr(mod, func)}
    if spec not in K.METHODS:
        raise ValueError(f"--method {spec}: not a gd.denoise method ({', '.join(K.METHODS)}) nor FILE.py:FUNCTION")
    return package_methods((spec,))


def _as_methods(method_fn):
    if callable(method_fn):
        return {getattr(method_fn, "__name__", "method"): method_fn}
    return dict(method_fn)


# ------------------------------------------------------------------ metrics
def rmse(y, ref, lo, hi):
    d = np.asarray(y[lo:hi], dtype=float) - ref[lo:hi]
    return math.sqrt(float(np.mean(d * d)))


def lag_s(y, ref, fs, lo, hi, max_s=LAG_MAX_S, band_hz=LAG_BAND_HZ):
    """Delay of y behind ref (s): the shift k (|k| <= max_s) maximising the
    normalised correlation of ref[lo+m : hi-m] with y shifted by k (full overlap
    at every k), both low-passed (zero phase, same filter) below ``band_hz``: the
    lag on manoeuvres, not the ambiguous phase of a vibration tone. Parabolic
    refinement around the peak. NaN when the correlation has no peak inside the
    range (the edges within 1 % of the maximum)."""
    from scipy.signal import butter, correlate, sosfiltfilt
    sos = butter(4, min(band_hz, 0.4 * fs), fs=fs, output="sos")
    a = sosfiltfilt(sos, np.asarray(ref[lo:hi], dtype=float))
    b = sosfiltfilt(sos, np.asarray(y[lo:hi], dtype=float))
    n = a.size
    m = max(1, min(int(max_s * fs), (n - 3) // 4))
    ac = a[m:n - m] - a[m:n - m].mean()
    c = correlate(b, ac, mode="valid", method="fft")            # c[j]: shift k = j - m
    csum = np.r_[0.0, np.cumsum(b)]
    c2sum = np.r_[0.0, np.cumsum(b * b)]
    L = ac.size
    mean_b = (csum[L:] - csum[:-L]) / L
    var_b = np.maximum((c2sum[L:] - c2sum[:-L]) / L - mean_b ** 2, 1e-300)
    ncc = c / np.sqrt(var_b)                                    # the mean of b drops out (ac has none)
    j = int(np.argmax(ncc))
    if ncc[j] <= 0 or (ncc[j] - max(ncc[0], ncc[-1])) < 0.01 * ncc[j]:
        return math.nan      # no peak within +-max_s (a record too short for its slow motion)
    frac = 0.0
    if 0 < j < ncc.size - 1:
        den = ncc[j - 1] - 2 * ncc[j] + ncc[j + 1]
        frac = 0.5 * (ncc[j - 1] - ncc[j + 1]) / den if den < 0 else 0.0
    return (j - m + frac) / fs


def angle_error_deg(y, ref, fs, lo, hi):
    return abs(float(np.sum(np.asarray(y[lo:hi], dtype=float) - ref[lo:hi]))) / fs


ANGLE_WINDOWS_S = (0.1, 1.0)
NOT_WORSE_MARGIN = 0.005       # "never worse than raw": ratio to raw <= 1 + this (noise)


def window_angle_error_deg(y, ref, fs, lo, hi, window_s):
    """RMS over the non-overlapping windows of ``window_s`` in [lo, hi) of the integrated
    angle error |sum over the window of (output - reference)| / fs, deg."""
    w = max(1, int(round(window_s * fs)))
    d = np.asarray(y[lo:hi], dtype=float) - ref[lo:hi]
    nw = d.size // w
    if nw == 0:
        return math.nan
    a = d[:nw * w].reshape(nw, w).sum(axis=1) / fs
    return math.sqrt(float(np.mean(a * a)))


def _geomean(x):
    x = np.asarray([v for v in x if np.isfinite(v) and v > 0], dtype=float)
    return float(np.exp(np.mean(np.log(x)))) if x.size else math.nan


# ------------------------------------------------------------------ one run
def reference(rec, rigid=False):
    """What a filter should output: rec.ref, or with ``rigid`` rec.ref minus the frame vibration."""
    return rec.ref - rec.vibration if rigid else rec.ref


def run_one(rec, methods, quick=False, rigid=False):
    """Score ``methods`` and the tuned baselines on one record: {name: metrics}."""
    fs = rec.sample_rate_hz
    lo, hi = int(SKIP_S * fs), rec.z.size
    ref = reference(rec, rigid)
    outputs, params = {}, {}
    for fam in dict.fromkeys(B.CAUSAL + B.NONCAUSAL):
        params[fam], _, outputs[fam] = B.tune(fam, rec.z, ref, fs, lo, hi, quick)
    for name, fn in methods.items():
        y = np.asarray(fn(rec.z.copy(), fs), dtype=float)
        if y.shape != rec.z.shape:
            raise ValueError(f"method {name!r} returned shape {y.shape}, expected {rec.z.shape}")
        outputs[name] = y
    scores = {k: rmse(y, ref, lo, hi) for k, y in outputs.items()}
    best_c = min(scores[f] for f in B.CAUSAL)
    best_nc = min(scores[f] for f in B.NONCAUSAL)
    best_lp = min(scores[f] for f in B.LOWPASS)
    moving = rec.profile in sim.MOVING
    angle_raw = angle_error_deg(rec.z, ref, fs, lo, hi)
    win_raw = {w: window_angle_error_deg(rec.z, ref, fs, lo, hi, w) for w in ANGLE_WINDOWS_S}
    out = {}
    for k, y in outputs.items():
        out[k] = {"rmse": scores[k], "ratio_causal": scores[k] / best_c,
                  "ratio_noncausal": scores[k] / best_nc, "ratio_raw": scores[k] / scores["raw"],
                  "ratio_lowpass": scores[k] / best_lp, "ratio_zp_lowpass": scores[k] / scores["zp_butter"],
                  "lag_ms": 1e3 * lag_s(y, ref, fs, lo, hi) if moving else math.nan,
                  "angle_err_deg": angle_error_deg(y, ref, fs, lo, hi),
                  "angle_err_raw_deg": angle_raw, "params": params.get(k, {})}
        for w in ANGLE_WINDOWS_S:
            out[k][f"angle_ratio_{w:g}s"] = window_angle_error_deg(y, ref, fs, lo, hi, w) / win_raw[w]
    out["best_causal"] = {"rmse": best_c, "ratio_causal": 1.0, "ratio_noncausal": best_c / best_nc,
                          "ratio_raw": best_c / scores["raw"], "ratio_lowpass": best_c / best_lp,
                          "ratio_zp_lowpass": best_c / scores["zp_butter"], "lag_ms": math.nan, "angle_err_deg": math.nan, "angle_err_raw_deg": angle_raw,
                          "params": {}}
    for w in ANGLE_WINDOWS_S:
        out["best_causal"][f"angle_ratio_{w:g}s"] = math.nan
    return out


def evaluate(method_fn, sensors=None, profiles=None, seeds=(0, 1, 2), quick=False,
             duration_s=None, progress=None, rigid=False):
    """Rows (dicts) per sensor x profile x method: the metrics of the module doc,
    aggregated over ``seeds``. ``method_fn``: a callable or {name: callable};
    ``rigid``: vibration counted as error (module doc)."""
    methods = _as_methods(method_fn)
    sensors = list(sensors or sim.SENSORS)
    profiles = list(profiles or sim.PROFILES)
    dur = duration_s or durations(quick)
    rows = []
    for s in sensors:
        for p in profiles:
            t0 = time.perf_counter()
            runs = [run_one(sim.record(s, p, seed, dur), methods, quick, rigid) for seed in seeds]
            for name in runs[0]:
                r = [run[name] for run in runs]
                rows.append({
                    "sensor": s, "profile": p, "method": name, "n_seeds": len(r),
                    "rmse": float(np.sqrt(np.mean([x["rmse"] ** 2 for x in r]))),
                    "ratio_causal": _geomean([x["ratio_causal"] for x in r]),
                    "ratio_noncausal": _geomean([x["ratio_noncausal"] for x in r]),
                    "ratio_raw": _geomean([x["ratio_raw"] for x in r]),
                    "ratio_lowpass": _geomean([x["ratio_lowpass"] for x in r]),
                    "ratio_zp_lowpass": _geomean([x["ratio_zp_lowpass"] for x in r]),
                    "lag_ms": float(np.nanmean([x["lag_ms"] for x in r])) if any(
                        np.isfinite(x["lag_ms"]) for x in r) else math.nan,
                    "angle_err_deg": float(np.sqrt(np.mean([x["angle_err_deg"] ** 2 for x in r]))),
                    "angle_err_raw_deg": float(np.sqrt(np.mean([x["angle_err_raw_deg"] ** 2 for x in r]))),
                    "params": [x["params"] for x in r]})
                for w in ANGLE_WINDOWS_S:      # RMS over seeds of the per-seed ratios
                    key = f"angle_ratio_{w:g}s"
                    rows[-1][key] = float(np.sqrt(np.mean([x[key] ** 2 for x in r])))
            if progress:
                progress(f"{s:9s} {p:12s} {len(seeds)} seed(s) {time.perf_counter() - t0:5.1f} s")
    return rows


def summarise(rows):
    """{method: {"overall": gm, "worst": (ratio, sensor, profile), sensor: gm, ...}}
    of ratio_causal (and "<sensor>_noncausal" of ratio_noncausal)."""
    out = {}
    for m in dict.fromkeys(r["method"] for r in rows):
        mr = [r for r in rows if r["method"] == m]
        d = {"overall": _geomean([r["ratio_causal"] for r in mr]),
             "overall_noncausal": _geomean([r["ratio_noncausal"] for r in mr])}
        w = max(mr, key=lambda r: r["ratio_causal"])
        d["worst"] = (w["ratio_causal"], w["sensor"], w["profile"])
        for s in dict.fromkeys(r["sensor"] for r in mr):
            sr = [r for r in mr if r["sensor"] == s]
            d[s] = _geomean([r["ratio_causal"] for r in sr])
            d[s + "_noncausal"] = _geomean([r["ratio_noncausal"] for r in sr])
        out[m] = d
    return out


# ------------------------------------------------------------------ gain vs frequency
GAIN_FRACS = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45)
GAIN_LOW_HZ = (0.1, 1.0)
GAIN_SNR = (3.0, 30.0)


def sine_gain(y, f_hz, fs, lo, hi, amp):
    """Amplitude of y at f_hz (least squares with a constant and a slope) / amp."""
    t = np.arange(lo, hi) / fs
    X = np.column_stack([np.sin(2 * np.pi * f_hz * t), np.cos(2 * np.pi * f_hz * t),
                         np.ones_like(t), t - t.mean()])
    c, *_ = np.linalg.lstsq(X, np.asarray(y[lo:hi], dtype=float), rcond=None)
    return math.hypot(c[0], c[1]) / amp


def gain_table(method_fn, sensors=None, quick=False, snrs=GAIN_SNR, seed=0, progress=None,
               baselines=("best_causal",)):
    """Rows {sensor, f_hz, f_frac, snr, amp, method, gain}: a pure sinusoid of
    amplitude snr x the sensor's noise std (plus every sensor error) through each
    method; the tuned baselines (tuned on that record) as ``best_causal``. The
    gain is fitted on output - the simulated slow bias (a drifting bias is not
    the sine's amplitude), over at least 5 periods."""
    methods = _as_methods(method_fn)
    rows = []
    dur = 8.0 if quick else 20.0
    for s in (sensors or sim.SENSORS):
        sensor = sim.SENSORS[s]
        fs = sensor.sample_rate_hz
        lo = int(SKIP_S * fs)
        freqs = [f for f in GAIN_LOW_HZ] + [r * fs for r in GAIN_FRACS]
        for snr in snrs:
            amp = snr * sensor.noise_std_deg_s
            for i, f in enumerate(freqs):
                n = int(max(dur, SKIP_S + 5.0 / f) * fs)    # at least 5 periods scored
                t = np.arange(n) / fs
                truth = amp * np.sin(2 * np.pi * f * t + 0.3)
                rec = sim.record(s, f"sine{i}", seed, n / fs, truth=truth)
                bias = rec.ref - rec.truth     # the slow sensor errors are not the sine's
                outs = {k: fn(rec.z.copy(), fs) for k, fn in methods.items()}
                outs["raw"] = rec.z
                if "best_causal" in baselines:
                    best = min((B.tune(fam, rec.z, rec.ref, fs, lo, n, True) for fam in B.CAUSAL),
                               key=lambda x: x[1])
                    outs["best_causal"] = best[2]
                for k, y in outs.items():
                    rows.append({"sensor": s, "f_hz": f, "f_frac": f / fs, "snr": snr, "amp": amp,
                                 "method": k, "gain": sine_gain(y - bias, f, fs, lo, n, amp)})
            if progress:
                progress(f"gain {s:9s} snr {snr:g}")
    return rows


# ------------------------------------------------------------------ goal: vibration counted as error
RIGID_GOAL = 1.25


def rigid_goal_lines(rows, methods):
    """[(method, goal text, measured, 'PASS'|'FAIL')]: vibration counted as error:
    geometric mean over the rows (sensor x profile) of rmse / the best tuned low-pass (causal
    Butterworth 1-2; for an offline method, whose name says so, the tuned zero-phase one)."""
    out = []
    for m in methods:
        mr = [r for r in rows if r["method"] == m]
        if not mr:
            continue
        key, bar = (("ratio_zp_lowpass", "tuned zero-phase low-pass") if "offline" in m
                    else ("ratio_lowpass", "tuned causal low-pass"))
        gm = _geomean([r[key] for r in mr])
        w = max(mr, key=lambda r: r[key])
        out.append((m, f"vibration counted as error: geometric mean <= {RIGID_GOAL:.2f}x the best {bar}",
                    f"{gm:.3f}x (worst {w[key]:.2f}x, {w['sensor']} {w['profile']})",
                    "PASS" if gm <= RIGID_GOAL else "FAIL"))
    return out


# ------------------------------------------------------------------ goals against the tuned baselines
GOAL_GEOMEAN = 1.00    # causal: geometric mean over the table / the best tuned causal filter
GOAL_WORST = 1.5       # causal: worst profile / the best tuned causal filter
GOAL_OFFLINE = 1.15    # offline form: geometric mean / the best tuned non-causal filter
GOAL_REST = 2.0        # at rest (long record): RMSE / the best tuned causal filter


def rest_lines(method_fn, sensors=None, duration_s=120.0, seed=0, quick=False):
    """[(method, goal text, measured, 'PASS'|'FAIL')] at rest: each sensor ``duration_s`` at rest
    (true rate 0, the ordinary slow bias), RMSE after SKIP_S / the best tuned causal filter's on
    that record (worst over the sensors), and rows {sensor, method, ratio} behind it."""
    methods = _as_methods(method_fn)
    ratios = {m: [] for m in methods}
    for s in (sensors or sim.SENSORS):
        rec = sim.record(s, "rest", seed, duration_s, truth=np.zeros(int(round(duration_s * sim.SENSORS[s].sample_rate_hz))))
        fs = rec.sample_rate_hz
        lo, hi = int(SKIP_S * fs), rec.z.size
        best = min(B.tune(fam, rec.z, rec.ref, fs, lo, hi, quick)[1] for fam in B.CAUSAL)
        for m, fn in methods.items():
            ratios[m].append((rmse(np.asarray(fn(rec.z.copy(), fs), dtype=float), rec.ref, lo, hi) / best, s))
    out = []
    for m, r in ratios.items():
        w = max(r)
        out.append((m, f"at rest ({duration_s:g} s) <= {GOAL_REST:.1f}x the best tuned causal filter",
                    f"worst {w[0]:.2f}x ({w[1]}); " + ", ".join(f"{s} {v:.2f}x" for v, s in r),
                    "PASS" if w[0] <= GOAL_REST else "FAIL"))
    return out


def goal_lines(rows, gains, methods=None):
    """[(method, goal text, measured, 'PASS'|'FAIL')] for the measurable goals against the tuned baselines."""
    methods = methods or [m for m in dict.fromkeys(r["method"] for r in rows)
                          if m not in B.CAUSAL + B.NONCAUSAL + ("best_causal",)]
    summ = summarise(rows)
    out = []
    for m in methods:
        mr = [r for r in rows if r["method"] == m]
        if not mr:
            continue
        if "offline" in m:
            gm = summ[m]["overall_noncausal"]
            out.append((m, f"offline: geometric mean <= {GOAL_OFFLINE:.2f}x best tuned non-causal",
                        f"{gm:.3f}x", gm <= GOAL_OFFLINE))
        else:
            gm = summ[m]["overall"]
            out.append((m, f"geometric mean <= {GOAL_GEOMEAN:.2f}x best tuned causal", f"{gm:.3f}x",
                        gm <= GOAL_GEOMEAN))
            w = summ[m]["worst"]
            out.append((m, f"no profile worse than {GOAL_WORST:.1f}x best tuned causal",
                        f"worst {w[0]:.2f}x ({w[1]} {w[2]})", w[0] <= GOAL_WORST))
        lim = 1.0 + NOT_WORSE_MARGIN
        for key, what in [("ratio_raw", "RMSE")] + [(f"angle_ratio_{w:g}s", f"angle over {w:g} s windows")
                                                    for w in ANGLE_WINDOWS_S]:
            vals = [r for r in mr if np.isfinite(r.get(key, math.nan))]
            if not vals:
                continue
            wr = max(vals, key=lambda r: r[key])
            out.append((m, f"never worse than raw: {what} / raw's <= {lim:.3f} on every profile",
                        f"worst {wr[key]:.3f} ({wr['sensor']} {wr['profile']})", wr[key] <= lim))
        mg = [g for g in gains if g["method"] == m and g["snr"] >= 3.0]
        if mg:
            wg = max(mg, key=lambda g: abs(g["gain"] - 1.0))
            out.append((m, "gain within 5 % of 1, DC-0.45 fs, sinusoids >= 3 sigma",
                        f"worst {wg['gain']:.3f} ({wg['sensor']}, {wg['f_hz']:.3g} Hz = {wg['f_frac']:.3f} fs, "
                        f"{wg['snr']:g} sigma)", abs(wg["gain"] - 1.0) <= 0.05))
        ar = [r["angle_err_deg"] / r["angle_err_raw_deg"] for r in mr if r["angle_err_raw_deg"] > 0]
        wa = max(mr, key=lambda r: r["angle_err_deg"] / max(r["angle_err_raw_deg"], 1e-300))
        out.append((m, "integrated angle error no worse than raw's (ratio <= 1.05, RMS over seeds)",
                    f"worst {max(ar):.2f}x ({wa['sensor']} {wa['profile']})", max(ar) <= 1.05))
        rest = [r for r in mr if r["profile"] == "static_ramp"]
        if rest:
            wr = min(rest, key=lambda r: 1.0 / r["ratio_raw"])
            out.append((m, "at rest (static with bias ramp) >= 5x below raw",
                        f"worst {1.0 / wr['ratio_raw']:.1f}x ({wr['sensor']})", 1.0 / wr["ratio_raw"] >= 5.0))
    return [(m, g, v, "PASS" if ok else "FAIL") for m, g, v, ok in out]
