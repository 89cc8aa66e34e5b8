"""Real motion: each method's output integrated into orientation and compared with a
motion reference over 0.1 s and 1 s windows.

    python benchmarks/real_motion.py --out docs/reports/real_motion   # all trials found (about a minute)
    python benchmarks/real_motion.py --method my.py:fn             # add a method: fn(rate_deg_s, fs) -> ndarray

Data: ``../shared/data/motion`` (BROAD, PSINS car, quadrotor; README there);
method and calibration: :mod:`benchmarks.motion_bench.realmotion`. Every method runs
per axis on the same (bias-removed where known) input; the time offset and mounting are
estimated on raw and shared. Printed: each method's RMS rotation error / raw's per trial
and window, and the goal line (within 0.5 % of raw on every trial and window). With
``--out`` writes report.md (stamped with the commit and the command), results.json and a
plot. Nothing here is timed; progress on stderr.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first

from benchmarks.motion_bench import bench
from benchmarks.motion_bench import realmotion as R
from benchmarks.provenance import stamp

LABEL = {"shakf_paper": "shakf, paper (outlier_sigma=0)", "shakf": "shakf (+ outlier gate)",
         "lowpass": "lowpass (package default 20 Hz)", "butter_tuned": "Butterworth, tuned per trial (oracle)"}


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def default_methods():
    import gyrodenoise as gd
    m = bench.package_methods(("motion", "shakf", "kf", "lowpass"))

    def shakf_paper(rate_deg_s, sample_rate_hz):
        return gd.denoise(rate_deg_s, sample_rate_hz, method="shakf", outlier_sigma=0)
    m["shakf_paper"] = shakf_paper
    return m


def run(trials, methods, progress=None):
    """Rows {trial, dataset, window_s, method, err_deg, ratio_raw, n_windows} + calibration notes."""
    rows, notes = [], {}
    for name, loader in trials:
        t0 = time.perf_counter()
        tr = R.calibrate(loader())
        fs = tr.sample_rate_hz
        notes[name] = tr.notes + [f"time offset {tr.offset + tr.frac:+.2f} samples ({1e3 * (tr.offset + tr.frac) / fs:+.1f} ms)"] + (
            [] if tr.mounting_known else [f"mounting rotation {R.qangle_deg(tr.mounting):.2f} deg (estimated)"])
        outs = {"raw": tr.rate_deg_s}
        for k, fn in methods.items():
            outs[k] = R.apply_per_axis(fn, tr.rate_deg_s, fs)
        for w in R.WINDOWS_S:
            prm, outs_w = R.tuned_butter(tr, w)
            raw_err = R.rms(R.window_errors_deg(tr, tr.rate_deg_s, w))
            n_win = len(R.windows(tr, w)[0])
            for k, y in list(outs.items()) + [("butter_tuned", outs_w)]:
                e = R.rms(R.window_errors_deg(tr, y, w))
                rows.append({"trial": name, "dataset": tr.dataset, "window_s": w, "method": k, "err_deg": e,
                             "ratio_raw": e / raw_err, "n_windows": n_win,
                             "params": prm if k == "butter_tuned" else {}})
        if progress:
            progress(f"{name:48s} {time.perf_counter() - t0:5.1f} s")
    return rows, notes


def write_report(out, rows, notes, methods, elapsed_s, argv=None, default="motion"):
    trials = list(dict.fromkeys(r["trial"] for r in rows))
    cols = ["raw"] + list(methods) + ["butter_tuned"]
    idx = {(r["trial"], r["window_s"], r["method"]): r for r in rows}
    L = ["# Real motion: rotation error over 0.1 s and 1 s windows, every method against raw", "",
         stamp(argv), "",
         f"Run time {elapsed_s:.0f} s. Method: `benchmarks/motion_bench/realmotion.py` (module doc). "
         "Each method's output (per axis, on the same input) is "
         "integrated into a body-frame rotation over non-overlapping windows and compared with the reference's "
         "rotation over the same window; the figure is the RMS of the error angle, and below, its ratio to raw's "
         "(< 1: closer to the reference than the raw gyro). `butter_tuned` is a causal Butterworth (order 1-2, "
         "cutoff grid 0.5 Hz-0.45 fs) tuned per trial and window against the reference (an oracle).",
         "", "The references are not perfect: BROAD's optical orientation is noisy per sample (0.1 s windows carry "
         "its noise), the quadrotor's autopilot attitude is 10 Hz and 0.1 deg-quantised (its 0.1 s figures are mostly "
         "reference error, so ratios near 1 there say little), the PSINS INS attitude is 10 Hz.", ""]
    for w in R.WINDOWS_S:
        L += [f"## {w:g} s windows: RMS error of raw (deg) and each method's ratio to raw", "",
              "| trial | windows | raw, deg | " + " | ".join(LABEL.get(c, c) for c in cols[1:]) + " |",
              "|---|---|---|" + "---|" * (len(cols) - 1)]
        for t in trials:
            raw = idx[(t, w, "raw")]
            vals = []
            for c in cols[1:]:
                r = idx.get((t, w, c))
                v = f"{r['ratio_raw']:.3f}" if r else "-"
                if c == "butter_tuned" and r:
                    v += f" ({r['params']['order']}, {r['params']['cutoff_hz']:.3g} Hz)"
                vals.append(v)
            L.append(f"| {t} | {raw['n_windows']} | {raw['err_deg']:.4f} | " + " | ".join(vals) + " |")
        L.append("")
    L += ["## Summary: ratio to raw over all trials", "", "| method | window | geometric mean | worst (trial) |",
          "|---|---|---|---|"]
    for c in cols[1:]:
        for w in R.WINDOWS_S:
            sel = [r for r in rows if r["method"] == c and r["window_s"] == w]
            gm = float(np.exp(np.mean(np.log([r["ratio_raw"] for r in sel]))))
            wr = max(sel, key=lambda r: r["ratio_raw"])
            L.append(f"| {LABEL.get(c, c)} | {w:g} s | {gm:.3f} | {wr['ratio_raw']:.3f} ({wr['trial']}) |")
    L += ["", "## Goal: no worse than raw", ""]
    L += [f"* {line}" for line in goal_lines(rows, methods, default)]
    L += ["", "![ratio to raw per trial](ratios.png)", ""]
    L += ["", "## Calibration (estimated on raw, shared by every method)", ""]
    L += [f"* {t}: " + "; ".join(notes[t]) for t in trials]
    (out / "report.md").write_text("\n".join(L) + "\n")


def plot(out, rows, methods):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    trials = list(dict.fromkeys(r["trial"] for r in rows))
    cols = list(methods) + ["butter_tuned"]
    idx = {(r["trial"], r["window_s"], r["method"]): r["ratio_raw"] for r in rows}
    fig, axes = plt.subplots(len(R.WINDOWS_S), 1, figsize=(12, 3.6 * len(R.WINDOWS_S)), sharex=True, squeeze=False)
    w = 0.8 / len(cols)
    for ax, win in zip(axes[:, 0], R.WINDOWS_S):
        for j, c in enumerate(cols):
            ax.bar(np.arange(len(trials)) + j * w, [idx.get((t, win, c), np.nan) for t in trials], w,
                   label=LABEL.get(c, c))
        ax.set_yscale("log")
        ax.axhline(1.0, color="k", lw=0.8)
        ax.axhline(1.02, color="g", lw=0.8, ls="--")
        ax.set_ylabel(f"RMS error / raw's, {win:g} s")
    axes[-1, 0].set_xticks(np.arange(len(trials)) + 0.4, trials, rotation=40, ha="right", fontsize=7)
    axes[0, 0].legend(fontsize=7, ncol=3)
    fig.tight_layout()
    fig.savefig(out / "ratios.png", dpi=90)
    plt.close(fig)


def goal_lines(rows, methods, default="motion"):
    out = []
    for m in methods:
        sel = [r for r in rows if r["method"] == m]
        if not sel:
            continue
        wr = max(sel, key=lambda r: r["ratio_raw"])
        ok = wr["ratio_raw"] <= 1.005
        tag = " (the default)" if m == default else ""
        out.append(f"{'PASS' if ok else 'FAIL'}  {m}{tag}: no worse than raw by more than 0.5 % on every trial and "
                   f"window: worst {wr['ratio_raw']:.3f} ({wr['trial']}, {wr['window_s']:g} s)")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path)
    ap.add_argument("--data", type=Path, default=R.MOTION_DIR, help="the motion folder (default %(default)s)")
    ap.add_argument("--method", action="append", default=[], help="extra method: NAME or FILE.py:FUNCTION")
    ap.add_argument("--only", default="", help="comma-separated substrings of trial names to keep")
    a = ap.parse_args(argv)
    methods = default_methods()
    try:
        for spec in a.method:
            methods.update(bench.load_method(spec))
    except ValueError as exc:
        print(f"real_motion.py: {exc}", file=sys.stderr)
        return 2
    trials = R.available_trials(a.data)
    if a.only:
        keys = a.only.split(",")
        trials = [t for t in trials if any(k in t[0] for k in keys)]
    if not trials:
        print(f"real_motion.py: --data {a.data}: no trial found (BROAD *.hdf5, psins_car, quadrotor_4imu)",
              file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    rows, notes = run(trials, methods, progress=log)
    elapsed = time.perf_counter() - t0
    cols = ["raw"] + list(methods) + ["butter_tuned"]
    for w in R.WINDOWS_S:
        print(f"\n{w:g} s windows: RMS rotation error of raw (deg), each method / raw")
        print(f"{'trial':44s} {'raw':>8s} " + " ".join(f"{c[:12]:>12s}" for c in cols[1:]))
        for t in dict.fromkeys(r["trial"] for r in rows):
            d = {r["method"]: r for r in rows if r["trial"] == t and r["window_s"] == w}
            print(f"{t:44s} {d['raw']['err_deg']:8.4f} " + " ".join(f"{d[c]['ratio_raw']:12.3f}" for c in cols[1:]))
    print()
    for line in goal_lines(rows, methods):
        print(line)
    if a.out:
        a.out.mkdir(parents=True, exist_ok=True)
        write_report(a.out, rows, notes, methods, elapsed, argv)
        plot(a.out, rows, methods)
        (a.out / "results.json").write_text(json.dumps({"rows": rows, "notes": notes}, indent=1, default=float))
        print(f"wrote {a.out / 'report.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
