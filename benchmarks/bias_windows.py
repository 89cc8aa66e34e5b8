"""The gyro bias that open-loop attitude integrates, on real data without the oracle de-biasing
RMS rotation error over 10 s and 60 s windows of

* raw: the gyro as logged, its bias in;
* start-up calibration: minus the mean of the first ``--cal-s`` seconds (what users do by hand;
  every BROAD trial starts at rest);
* bank stillness: minus a bias estimated while the ``motion`` bank says the gyro is still (a
  prototype of item 3, in numpy on the causal filter's state: still where, on every axis, the
  most likely filter of the bank tracks at most ``--still-lane``'s index (lane 4: 1e-6, an
  average over minutes) for ``--still-s`` seconds in a row; the estimate is the mean of the raw
  samples of every still stretch so far, causal);
* oracle: minus the mean of the trial's first rest segment from its ``movement`` flags (what
  ``real_motion.py`` removes before any filter; not available to a user in general).

    python benchmarks/bias_windows.py                 # every BROAD trial found (about 20 s)
    python benchmarks/bias_windows.py --per-axis      # stillness decided per axis (a one-axis core)

Data: ``../shared/data/motion/broad`` (README there). Windows and the reference rotation are
:mod:`benchmarks.motion_bench.realmotion`'s (the time offset estimated on the oracle-de-biased
rate, as there). BROAD's gyro is a MEMS: Earth's rotation (<= 15 deg/h) is far below its bias;
a navigation-grade record is not judged here. Printed: per trial and window, each method's RMS
angle error (deg) and its ratio to raw's and to the start-up calibration's.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first

from benchmarks.motion_bench import realmotion as R  # noqa: E402
from gyrodenoise.core import batch  # noqa: E402
from gyrodenoise.core import kernels as K  # noqa: E402

WINDOWS_S = (10.0, 60.0)


def _raw_gyro(path):
    import h5py
    with h5py.File(path, "r") as f:
        return np.degrees(f["imu_gyr"][()]), f["movement"][()].astype(bool)


def best_lane(rate_deg_s, fs):
    """The bank's most likely filter after each sample (M_BEST; -1 during the warm-up), causal."""
    p = K.make_params(method="motion", sample_rate_hz=fs)
    _, _, best = batch.run(p, K.init_state(p), rate_deg_s, trace_index=K.ext_offset(p) + K.M_BEST)
    _, _, conv = batch.run(p, K.init_state(p), rate_deg_s, trace_index=K.S_CONV)
    return np.where(conv == 1.0, best, -1.0)


def _still(calm, need):
    run = np.zeros(calm.size, dtype=int)
    c = 0
    for i, v in enumerate(calm):
        c = c + 1 if v else 0
        run[i] = c
    return run >= need


def stillness_bias(raw, fs, still_lane, still_s, per_axis=False):
    """Causal bias estimate (N x 3): the mean of the raw samples of the still stretches so far
    (still: every axis's most likely filter at or below ``still_lane`` for ``still_s`` s; with
    ``per_axis``, each axis on its own, as a one-axis filter core would decide)."""
    lanes = np.column_stack([best_lane(raw[:, k], fs) for k in range(raw.shape[1])])
    calm = (lanes >= 0) & (lanes <= still_lane)
    need = max(1, int(round(still_s * fs)))
    if per_axis:
        still = np.column_stack([_still(calm[:, k], need) for k in range(raw.shape[1])])
    else:
        still = np.repeat(_still(np.all(calm, axis=1), need)[:, None], raw.shape[1], axis=1)
    n = np.cumsum(still, axis=0)
    s = np.cumsum(np.where(still, raw, 0.0), axis=0)
    bias = np.where(n > 0, s / np.maximum(n, 1), 0.0)
    return bias, float(still.mean())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cal-s", type=float, default=2.0, help="start-up calibration: seconds averaged")
    ap.add_argument("--still-lane", type=int, default=4, help="bank stillness: slowest lanes counted as still")
    ap.add_argument("--still-s", type=float, default=1.0, help="bank stillness: seconds still in a row")
    ap.add_argument("--per-axis", action="store_true", help="bank stillness decided per axis (not all three)")
    args = ap.parse_args(argv)
    paths = sorted((R.MOTION_DIR / "broad").glob("*.hdf5"))
    if not paths:
        print(f"no BROAD trials under {R.MOTION_DIR / 'broad'}", file=sys.stderr)
        return 2
    names = ("raw", "startup_cal", "bank_still", "oracle")
    print(f"RMS rotation error over windows (deg); ratio to raw / to the start-up calibration "
          f"({args.cal_s:g} s); bank stillness: lanes <= {args.still_lane}, {args.still_s:g} s"
          f"{', per axis' if args.per_axis else ', all axes'}")
    print(f"{'trial':44s} {'win':>4s} " + " ".join(f"{n:>12s}" for n in names) + "  still%")
    for path in paths:
        trial = R.load_broad(path)
        R.calibrate(trial)                               # the time offset, on the oracle-de-biased rate
        raw, movement = _raw_gyro(path)
        fs = trial.sample_rate_hz
        k = int(round(args.cal_s * fs))
        if movement[:k].any():
            print(f"{path.stem}: moves within the first {args.cal_s:g} s: skipped", file=sys.stderr)
            continue
        oracle = raw - trial.rate_deg_s                  # the first rest segment's mean, per axis
        bias, frac = stillness_bias(raw, fs, args.still_lane, args.still_s, args.per_axis)
        rates = {"raw": raw, "startup_cal": raw - raw[:k].mean(axis=0), "bank_still": raw - bias,
                 "oracle": raw - oracle}
        for w in WINDOWS_S:
            e = {n: R.rms(R.window_errors_deg(trial, r, w)) for n, r in rates.items()}
            cells = " ".join(f"{e[n]:6.3f} {e[n] / e['raw']:5.2f}" for n in names)
            print(f"{path.stem:44s} {w:4g} {cells}  {100 * frac:5.1f}"
                  f"   bank/cal {e['bank_still'] / e['startup_cal']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
