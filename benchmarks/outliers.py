"""What a user gets from the SHAKF on records with wild samples.

    python benchmarks/outliers.py [--quick]

For each record (the real ADIS16405 imu4 x/y, the contaminated XSens MTi-G and
a simulated paper_fog record with injected spikes) the SHAKF runs with the
outlier gate off (the paper's filter, only the Eq. (32) gamma test) and on
(``outlier_sigma`` = 4, 5, 6). Outliers are the samples more than 8 robust
standard deviations (1.4826 MAD) from the median; the "clean" record replaces
each by the median of its 11 neighbours. Reported per setting:

* rejected / re-opened: the gate's counters;
* excess: the output on the contaminated record minus the output of the
  ungated SHAKF on the clean record (what the outliers cost), max |.| within
  5 s after an outlier (outliers in the first 2 s, the warm-up, where the raw
  sample is passed through, are left out) and RMS after 2 s, deg/s;
* Allan terms N (deg/sqrt h) and B (deg/h) of the output after warm-up;
* for the simulated record, RMSE against the known truth;
* the 90 % rise time of a 10 deg/s step (paper_fog, 200 Hz), the price paid.

Numbers are measured here, in this process; docs/bench/outliers-soak.md quotes them.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first

import gyrodenoise as gd
from benchmarks._data import SHARED_DATA
from gyrodenoise.analysis.allan import allan
from gyrodenoise.analysis.experiments import rise_time
from gyrodenoise.core import kernels as K
from gyrodenoise.core.batch import run

DATA = SHARED_DATA / "static"
SIGMAS = (0.0, 4.0, 5.0, 6.0)


def outliers_and_clean(z, thresh=8.0):
    med = np.median(z)
    mad = 1.4826 * np.median(np.abs(z - med))
    idx = np.flatnonzero(np.abs(z - med) > thresh * mad)
    clean = z.copy()
    for i in idx:
        lo, hi = max(0, i - 5), min(z.size, i + 6)
        nb = np.delete(z[lo:hi], np.flatnonzero(np.isin(np.arange(lo, hi), idx)))
        clean[i] = np.median(nb) if nb.size else med
    return idx, clean


def shakf(z, fs, sigma):
    p = K.make_params(method="shakf", sample_rate_hz=fs, outlier_sigma=sigma)
    out, st = run(p, K.init_state(p), z)
    return out, st


def report(name, z, fs, truth=None, allan_terms=True):
    idx, clean = outliers_and_clean(z)
    ref, _ = shakf(clean, fs, 0.0)
    w = int(5 * fs)
    skip = int(2 * fs)
    print(f"\n== {name}: {z.size} samples at {fs:g} Hz, {idx.size} outliers (>8 MAD), "
          f"range {z.min():.3g}..{z.max():.3g} deg/s")
    head = f"{'setting':<14}{'rejected':>9}{'reopened':>9}{'max excess':>12}{'rms excess':>12}"
    if allan_terms:
        head += f"{'N deg/rt h':>12}{'B deg/h':>10}"
    if truth is not None:
        head += f"{'RMSE vs truth':>15}"
    print(head)
    rows = [("raw", z, None)] + [(f"shakf k={s:g}" if s else "shakf (off)",) + shakf(z, fs, s)
                                  for s in SIGMAS]
    for label, y, st in rows:
        exc = y - ref
        near = max((np.max(np.abs(exc[i:i + w])) for i in idx if i >= skip), default=0.0)
        line = f"{label:<14}"
        line += (f"{int(st[K.S_NREJ]):>9}{int(st[K.S_NREOPEN]):>9}" if st is not None
                 else f"{'':>9}{'':>9}")
        line += f"{near:12.4g}{np.sqrt(np.mean(exc[skip:] ** 2)):12.4g}"
        if allan_terms:
            t = allan(y[skip:], fs).terms
            line += f"{t['N']:12.4g}{t['B']:10.4g}"
        if truth is not None:
            line += f"{np.sqrt(np.mean((y[skip:] - truth[skip:]) ** 2)):15.4g}"
        print(line)


def step_lag(fs=200.0, duration_s=600.0, step=10.0, seed=0):
    card = gd.load_card("paper_fog")
    n = int(duration_s * fs)
    truth = np.zeros(n)
    truth[n // 2:] = step
    rec = gd.simulate(card, n, seed=seed, true_rate_deg_s=truth)
    t = np.arange(n) / fs
    print(f"\n== price paid: {step:g} deg/s step at t={t[n // 2]:g} s (paper_fog, {fs:g} Hz, seed {seed})")
    print(f"{'setting':<14}{'90% rise s':>12}{'rejected':>9}{'reopened':>9}{'RMSE after step':>16}")
    for s in SIGMAS:
        y, st = shakf(rec.rate_deg_s, fs, s)
        rt = rise_time(y, t, t[n // 2], step)
        rms = np.sqrt(np.mean((y[n // 2:] - truth[n // 2:]) ** 2))
        label = f"shakf k={s:g}" if s else "shakf (off)"
        rts = f"{rt:.3g}" if rt is not None else "never"
        print(f"{label:<14}{rts:>12}{int(st[K.S_NREJ]):>9}{int(st[K.S_NREOPEN]):>9}{rms:16.4g}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="first 200k samples of each real record")
    args = ap.parse_args(argv)
    n = 200_000 if args.quick else None
    from gyrodenoise.io.recording import read_recording
    for fname, col, unit in [("adis16405_imu4.csv.gz", "gyro_x", "deg/s"),
                             ("adis16405_imu4.csv.gz", "gyro_y", "deg/s"),
                             ("xsens_mtig_contaminated.csv.gz", "gyro_x", "rad/s")]:
        path = DATA / fname
        if not path.exists():
            print(f"\n(skipped {fname}: not found at {path})")
            continue
        rec = read_recording(path, rate_column=col, rate_unit=unit)
        report(f"{fname} {col} ({unit})", rec.rate_deg_s[:n], rec.sample_rate_hz)
    # known truth: 1 h of paper_fog at 200 Hz, constant 2 deg/s, 50 spikes of +-(5..20) deg/s
    fs = 200.0
    rec = gd.simulate("paper_fog", int(3600 * fs) if not args.quick else 200_000, seed=3,
                      true_rate_deg_s=2.0)
    rng = np.random.default_rng(3)
    z = rec.rate_deg_s.copy()
    where = rng.choice(np.arange(1000, z.size), 50, replace=False)
    z[where] += rng.choice([-1, 1], 50) * rng.uniform(5, 20, 50)
    report("paper_fog 2 deg/s + 50 spikes", z, fs, truth=rec.true_rate_deg_s)
    step_lag()
    return 0


if __name__ == "__main__":
    sys.exit(main())
