"""Ground-truth benchmark on moving profiles (issue 12): who follows motion and who averages.

    python benchmarks/motion.py --out docs/motion [--quick] [--seed 1]

For the paper's FOG (models/paper_fog.toml, 200 Hz, manoeuvres of 5 deg/s RMS)
and an ICM-20602-like MEMS (models/icm20602.toml, 1 kHz, 20 deg/s RMS), every
profile of :mod:`benchmarks.profiles` is simulated with known truth and run
through every method. Printed and written to ``report.md``:

* RMSE against the true rate (after the first 2 s), and each method's ratio to
  the best *specialist* of that profile (raw, 1st-order LP 20 Hz, Butterworth
  30 Hz, kf, shakf: everything but ``motion``); the geometric mean of the
  ratios over all profiles;
* lag (cross-correlation peak between truth and output, ms) on the moving
  profiles, and the -3 dB bandwidth from sines of the manoeuvre RMS;
* on real flights (log171.bin, px4_sample.ulg, read by the bridge's readers),
  the 0-5 Hz correlation and amplitude kept against the raw rate, in the
  segments where the vehicle moves.

Nothing here is timed as a test; ratios are measured in this one run. The goal
of issue 12 is checked at the end (PASS/FAIL lines). Progress on stderr.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

import gyrodenoise as gd
from gyrodenoise.core import kernels as K
from benchmarks import reference_filters as RF
from benchmarks.profiles import PROFILES
from _data import SHARED_DATA

REPO = Path(__file__).resolve().parents[1]
SHARED_LOGS = SHARED_DATA / "logs"
SENSORS = {"FOG": ("paper_fog", 200.0, 5.0), "MEMS": ("icm20602", 1000.0, 20.0)}
LONG = ("at_rest", "constant")            # long enough for averaging to matter
SKIP_S = 2.0
SPECIALISTS = ["raw", "lp20", "bw30", "kf", "shakf"]
SUPERSEDED = ("> **Fixed specialists only (issue 23).** The ratios below are against *fixed* filters "
              "(a 20 Hz first-order low-pass, a 30 Hz Butterworth, kf, shakf), not against filters tuned per "
              "run: for that, see docs/tuned/report.md (`python benchmarks/tuned.py`) and, on real motion, "
              "docs/real_motion/report.md.")
LABEL = {"raw": "raw", "lp20": "1st-order LP 20 Hz", "bw30": "Butterworth-2 30 Hz",
         "kf": "kf (AR(3), gated)", "shakf": "shakf (paper + gate)", "motion": "motion"}


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def methods():
    return SPECIALISTS + (["motion"] if "motion" in K.METHODS else [])


def apply(method, z, fs):
    if method == "raw":
        return z.copy()
    if method == "lp20":
        return RF.lowpass1(z, fs, 20.0)[0]
    if method == "bw30":     # 30 Hz, or 0.4 fs on slow logs (log171.bin: 50 Hz -> 20 Hz)
        return gd.denoise(z, fs, method="lowpass", cutoff_hz=min(30.0, 0.4 * fs), order=2)
    return gd.denoise(z, fs, method=method)


def record(profile, sensor, seed, quick):
    card, fs, rms = SENSORS[sensor]
    dur = (120.0 if profile in LONG else 60.0) * (0.5 if quick else 1.0)
    n = int(dur * fs)
    kw = {} if profile in ("at_rest", "constant", "steps", "flight_like") else {"rms_deg_s": rms}
    if profile == "flight_like":
        kw["path"] = SHARED_LOGS / "px4_sample.ulg"
    truth = PROFILES[profile](n, fs, seed=seed, **kw)
    z = gd.simulate(card, n, seed=seed + 100, true_rate_deg_s=truth).rate_deg_s
    return np.asarray(z, dtype=float), truth, fs


def rmse(y, x, fs):
    i = int(SKIP_S * fs)
    return float(np.sqrt(np.mean((y[i:] - x[i:]) ** 2)))


def lag_ms(y, x, fs, max_ms=300.0):
    """Delay of ``y`` behind ``x`` at the cross-correlation peak, ms (0.1-sample
    resolution by parabolic interpolation)."""
    i = int(SKIP_S * fs)
    a = x[i:] - x[i:].mean()
    b = y[i:] - y[i:].mean()
    m = int(max_ms * fs / 1000.0)
    c = np.array([np.dot(a[:a.size - L], b[L:]) for L in range(m + 1)])
    k = int(np.argmax(c))
    frac = 0.0
    if 0 < k < m:
        den = c[k - 1] - 2 * c[k] + c[k + 1]
        frac = 0.5 * (c[k - 1] - c[k + 1]) / den if den != 0 else 0.0
    return 1000.0 * (k + frac) / fs


def bandwidth_hz(method, sensor, seed, quick):
    """-3 dB point from sines of the manoeuvre RMS: gain = fitted output
    amplitude / true amplitude at that frequency (the same noise in every run)."""
    card, fs, rms = SENSORS[sensor]
    freqs = np.geomspace(0.1, fs / 4, 9 if quick else 14)
    n = int((10.0 if quick else 20.0) * fs)
    gains = []
    for f in freqs:
        truth = _sine(n, fs, f, rms)
        z = gd.simulate(card, n, seed=seed + 200, true_rate_deg_s=truth).rate_deg_s
        y = apply(method, np.asarray(z, float), fs)
        i = int(SKIP_S * fs)
        t = np.arange(n)[i:] / fs
        e = np.exp(-2j * np.pi * f * t)
        gains.append(abs(np.sum(y[i:] * e)) / abs(np.sum(truth[i:] * e)))
    gains = np.array(gains)
    below = np.flatnonzero(gains < 10 ** (-3 / 20))
    if below.size == 0:
        return float(freqs[-1]), True          # above the last frequency tried
    j = below[0]
    if j == 0:
        return float(freqs[0]), False
    # log-linear interpolation of the crossing
    g0, g1 = 20 * np.log10(gains[j - 1]), 20 * np.log10(gains[j])
    f0, f1 = np.log(freqs[j - 1]), np.log(freqs[j])
    return float(np.exp(f0 + (-3 - g0) * (f1 - f0) / (g1 - g0))), False


def _sine(n, fs, f, rms):
    return rms * math.sqrt(2) * np.sin(2 * np.pi * f * np.arange(n) / fs + 0.3)


def flight_streams():
    """(log, stream, axis, raw deg/s, restarts, rate Hz) of the shared real
    flights' gyro streams at >= 20 Hz, read by the bridge's readers."""
    from gyrodenoise.mavlink import dataflash, ulog
    from gyrodenoise.mavlink.streams import detect_restarts
    for name, reader in (("log171.bin", lambda p: dataflash.read(p)[2]),
                         ("px4_sample.ulg", lambda p: ulog.read(p)[1])):
        path = SHARED_LOGS / name
        if not path.is_file():
            log(f"  {name}: absent (../shared/data), skipped")
            continue
        for st in reader(path):
            detect_restarts(st)
            if st.to_deg_s is None or not st.rate_hz or st.rate_hz < 20:
                continue
            x, _, _ = st.work_units()
            for k, ax in enumerate(st.axes):
                yield name, st.name, ax, x[:, k].copy(), st.restarts, st.rate_hz


def moving_windows(low_deg_s, fs, window_s=2.0, threshold_deg_s=2.0):
    """True in the ``window_s`` windows whose 0-5 Hz content has a std above
    ``threshold_deg_s`` (the vehicle moves)."""
    w = int(window_s * fs)
    moving = np.zeros(low_deg_s.size, bool)
    for i in range(0, low_deg_s.size - w + 1, w):
        moving[i:i + w] = np.std(low_deg_s[i:i + w]) > threshold_deg_s
    return moving


def real_flights(meths):
    """0-5 Hz correlation and amplitude kept (ratio of std's) on the shared real
    flights, per method, in the windows where the vehicle moves."""
    from gyrodenoise.analysis.motion_metrics import lowband
    rows = []
    for name, st, ax, z, restarts, fs in flight_streams():
        lz = np.nan_to_num(lowband(z, fs, restarts=restarts))
        mask = moving_windows(lz, fs)
        if mask.sum() < 2 * fs:
            continue
        for m in meths:
            if m == "raw":
                continue
            y = apply(m, z, fs) if m in ("lp20", "bw30") else gd.denoise(z, fs, method=m, restarts=restarts)
            ly = np.nan_to_num(lowband(y, fs, restarts=restarts))
            corr = float(np.corrcoef(lz[mask], ly[mask])[0, 1])
            amp = float(np.std(ly[mask]) / np.std(lz[mask]))
            high = float(np.std(y - ly) / np.std(z - lz))       # above 5 Hz, whole record
            rows.append((name, st, ax, m, corr, amp, high))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None, help="folder for report.md and the figures")
    ap.add_argument("--quick", action="store_true", help="half-length records, fewer sines")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-real", action="store_true", help="skip the real flights")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    meths = methods()
    profiles = list(PROFILES)
    if not (SHARED_LOGS / "px4_sample.ulg").is_file():
        profiles.remove("flight_like")
        log("flight_like skipped: ../shared/data/logs/px4_sample.ulg absent")
    R = {}
    series = {}
    for sensor in SENSORS:
        for prof in profiles:
            z, x, fs = record(prof, sensor, args.seed, args.quick)
            outs = {m: apply(m, z, fs) for m in meths}
            e = {m: rmse(y, x, fs) for m, y in outs.items()}
            best = min(e[m] for m in SPECIALISTS)
            moving = float(np.std(x)) > 0
            R[sensor, prof] = {m: {"rmse": e[m], "ratio": e[m] / best,
                                   "lag_ms": lag_ms(outs[m], x, fs) if moving else float("nan")}
                               for m in meths}
            R[sensor, prof]["_best"] = min(SPECIALISTS, key=lambda m: e[m])
            if prof in ("steps", "rest_manoeuvre_rest", "flight_like"):
                series[sensor, prof] = (z, x, fs, outs)
            log(f"{sensor:5s} {prof:20s} " + " ".join(f"{m}={e[m]:.3g}" for m in meths))
    bw = {}
    for sensor in SENSORS:
        for m in meths:
            bw[sensor, m] = bandwidth_hz(m, sensor, args.seed, args.quick)
    real = [] if args.no_real else real_flights(meths)
    text = report(R, bw, real, meths, profiles, args, time.perf_counter() - t0)
    print(text)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        figs = figures(out, R, series, meths, profiles)
        (out / "report.md").write_text(text + "\n" + "\n".join(f"![{f}]({f})" for f in figs) + "\n")
        log(f"wrote {out / 'report.md'}")
    return 0


def geomean(v):
    v = [x for x in v if x > 0 and math.isfinite(x)]
    return float(math.exp(sum(math.log(x) for x in v) / len(v))) if v else float("nan")


def report(R, bw, real, meths, profiles, args, elapsed):
    L = ["# Motion benchmark: RMSE against the true rate, ratio to the best specialist", "",
         SUPERSEDED, "",
         f"Command: `python benchmarks/motion.py{' --quick' if args.quick else ''} --seed {args.seed}`"
         f" ({elapsed:.0f} s). Specialists: {', '.join(SPECIALISTS)}; ratio 1.0 = the best of them.", ""]
    for sensor in SENSORS:
        card, fs, rms = SENSORS[sensor]
        L += [f"## {sensor} ({card}, {fs:g} Hz, manoeuvres {rms:g} deg/s RMS)", "",
              "| profile | best specialist | its RMSE deg/s | " + " | ".join(meths) + " |",
              "|---|---|---|" + "---|" * len(meths)]
        for prof in profiles:
            r = R[sensor, prof]
            b = r["_best"]
            L.append(f"| {prof} | {b} | {r[b]['rmse']:.3g} | "
                     + " | ".join(f"{r[m]['ratio']:.2f}" for m in meths) + " |")
        L.append("| geometric mean | | | " + " | ".join(
            f"{geomean([R[sensor, p][m]['ratio'] for p in profiles]):.2f}" for m in meths) + " |")
        L.append("| raw RMSE / method's, at rest | | | " + " | ".join(
            f"{R[sensor, 'at_rest']['raw']['rmse'] / R[sensor, 'at_rest'][m]['rmse']:.1f}" for m in meths) + " |")
        L += ["", "Lag (ms, cross-correlation with the truth) and -3 dB bandwidth:", "",
              "| | " + " | ".join(meths) + " |", "|---|" + "---|" * len(meths)]
        for prof in ("smooth", "rest_manoeuvre_rest", "flight_like", "sine_1hz"):
            if prof in profiles:
                L.append(f"| lag, {prof} | " + " | ".join(f"{R[sensor, prof][m]['lag_ms']:.1f}" for m in meths) + " |")
        L.append("| -3 dB bandwidth, Hz | " + " | ".join(
            (">" if bw[sensor, m][1] else "") + f"{bw[sensor, m][0]:.3g}" for m in meths) + " |")
        L.append("")
    if real:
        L += ["## Real flights: 0-5 Hz content kept (segments where the vehicle moves)", "",
              "corr and amplitude: the 0-5 Hz content of the output against the raw's, in the 2 s windows",
              "where it moves (0-5 Hz std > 2 deg/s); above 5 Hz: std of the output's content above 5 Hz",
              "over the raw's, whole record (vibration and noise removed: lower = more removed).", "",
              "| log | stream | axis | method | corr | amplitude kept | above 5 Hz kept |",
              "|---|---|---|---|---|---|---|"]
        for name, st, ax, m, corr, amp, high in real:
            L.append(f"| {name} | {st} | {ax} | {m} | {corr:.3f} | {100 * amp:.0f} % | {100 * high:.0f} % |")
        L.append("")
    L += goal_lines(R, real, profiles)
    return "\n".join(L)


def goal_lines(R, real, profiles):
    if "motion" not in K.METHODS:
        return ["(no `motion` method yet: goal not evaluated)"]
    L = ["## Goal of issue 12 (this run)", ""]
    ok_all = True
    for sensor in SENSORS:
        ratios = [R[sensor, p]["motion"]["ratio"] for p in profiles]
        below_raw = all(R[sensor, p]["motion"]["rmse"] < R[sensor, p]["raw"]["rmse"] for p in profiles)
        worst = max(zip(ratios, profiles))
        gm = geomean(ratios)
        rest = R[sensor, "at_rest"]["raw"]["rmse"] / R[sensor, "at_rest"]["motion"]["rmse"]
        for ok, what in ((below_raw, "RMSE below raw on every profile"),
                         (worst[0] <= 2.0, f"worst ratio {worst[0]:.2f} ({worst[1]}) <= 2"),
                         (gm <= 1.25, f"geometric-mean ratio {gm:.2f} <= 1.25"),
                         (rest >= 5.0, f"at rest {rest:.1f}x below raw (>= 5)")):
            L.append(f"- {sensor}: {'PASS' if ok else 'FAIL'}: {what}")
            ok_all &= ok
    for name, st, ax, m, corr, amp, _ in real:
        if m == "motion":
            ok = corr >= 0.95 and amp >= 0.85
            L.append(f"- {name} {st}.{ax}: {'PASS' if ok else 'FAIL'}: 0-5 Hz corr {corr:.3f} (>= 0.95), "
                     f"amplitude {100 * amp:.0f} % (>= 85 %)")
            ok_all &= ok
    L += ["", f"Overall: {'PASS' if ok_all else 'FAIL'}"]
    return L


def figures(out, R, series, meths, profiles):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    figs = []
    fig, axes = plt.subplots(1, len(SENSORS), figsize=(13, 4.5), sharey=True)
    for ax, sensor in zip(np.atleast_1d(axes), SENSORS):
        xs = np.arange(len(profiles))
        w = 0.8 / len(meths)
        for j, m in enumerate(meths):
            ax.bar(xs + (j - len(meths) / 2 + 0.5) * w, [R[sensor, p][m]["ratio"] for p in profiles], w,
                   label=LABEL.get(m, m))
        ax.set_yscale("log")
        ax.axhline(1, color="k", lw=0.8)
        ax.axhline(2, color="k", lw=0.8, ls="--")
        ax.set_xticks(xs, profiles, rotation=35, ha="right", fontsize=8)
        ax.set_title(f"{sensor}: RMSE / best specialist (lower is better; dashed = 2x)")
    np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "ratios.png", dpi=110)
    plt.close(fig)
    figs.append("ratios.png")
    for (sensor, prof), (z, x, fs, outs) in series.items():
        fig = plt.figure(figsize=(12, 6.5))
        top = fig.add_subplot(2, 1, 1)
        zooms = [fig.add_subplot(2, 2, 3), fig.add_subplot(2, 2, 4)]
        t = np.arange(z.size) / fs
        moving = np.flatnonzero(np.abs(np.diff(x)) > 0)
        mid = moving[moving.size // 2] if moving.size else z.size // 2
        windows = [(mid - int(0.25 * fs), mid + int(0.25 * fs), "in motion, 0.5 s"),
                   (z.size - int(1.5 * fs), z.size - int(0.5 * fs), "last second but one, 1 s")]
        for ax, (a, b, title) in zip([top] + zooms, [(0, z.size, f"{sensor}, {prof}")] + windows):
            a = max(a, 0)
            sl = slice(a, b)
            ax.plot(t[sl], z[sl], color="0.75", lw=0.5, label="raw")
            ax.plot(t[sl], x[sl], color="k", lw=1.2, label="truth")
            for m in ("shakf", "bw30", "motion"):
                if m in outs:
                    ax.plot(t[sl], outs[m][sl], lw=0.9, label=LABEL[m])
            ax.set_xlabel("s")
            ax.set_ylabel("deg/s")
            ax.set_title(title, fontsize=9)
        top.legend(fontsize=7, ncol=5)
        fig.tight_layout()
        name = f"{sensor.lower()}_{prof}.png"
        fig.savefig(out / name, dpi=90)
        plt.close(fig)
        figs.append(name)
    return figs


if __name__ == "__main__":
    sys.exit(main())
