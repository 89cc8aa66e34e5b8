"""Independent Allan terms for a static gyro record (the held-out check of records nobody developed on).

Reads the record with pandas (not with gyrodenoise), computes the overlapping Allan
deviation with allantools at octave-spaced taus, and reads the terms the way the
MathWorks / IEEE 952 slope-point recipe does:

* N: the -1/2 line through the curve point whose log-log slope is nearest -1/2,
  read at tau = 1 s;
* B: the minimum of the curve divided by sqrt(2 ln 2 / pi) = 0.664;
* K: the +1/2 line through the point whose slope is nearest +1/2, read at tau = 3 s
  (reported as None when no point has a slope above +0.25: not resolved).

Units: the rate is converted to deg/s with --scale first; N in deg/sqrt(h), B in deg/h,
K in deg/h^1.5, and the Kalibr densities (gyroscope_noise_density = N,
gyroscope_random_walk = K, both rad/s based). With --ours, the gyrodenoise JSON of the
same record is read and the ratios ours/independent printed per axis and term.

Example:
    python scripts/record_trial/check.py rec.csv --columns gx,gy,gz --sample-rate 100 \\
        --scale 1.3737e-4 --scale-to-deg 57.29578 --skiprows 4 --ours ours.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import allantools
import numpy as np
import pandas as pd

B_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.664


def slope_line_read(
    tau: np.ndarray, adev: np.ndarray, slope: float, at: float, min_slope: float | None = None
) -> float | None:
    """Read the line of the given log-log slope through the best-matching point at tau=at."""
    lt, la = np.log10(tau), np.log10(adev)
    d = np.diff(la) / np.diff(lt)
    i = int(np.argmin(np.abs(d - slope)))
    if min_slope is not None and d[i] < min_slope:
        return None
    b = la[i] - slope * lt[i]
    return float(10.0 ** (slope * math.log10(at) + b))


def terms(rate_deg_s: np.ndarray, fs: float) -> dict:
    n = rate_deg_s.size
    m = 2 ** np.arange(0, int(math.log2(n // 2)))  # octave taus, up to n/4
    taus, adev, _, _ = allantools.oadev(rate_deg_s, rate=fs, data_type="freq", taus=m / fs)
    n_ = slope_line_read(taus, adev, -0.5, 1.0)
    k_ = slope_line_read(taus, adev, 0.5, 3.0, min_slope=0.25)
    b_ = float(np.min(adev)) / B_FACTOR
    d2r = math.pi / 180.0
    return {
        "N_deg_sqrt_h": n_ * 60.0,
        "B_deg_h": b_ * 3600.0,
        "K_deg_h15": None if k_ is None else k_ * 3600.0 * 60.0,
        "tau_min_s": float(taus[int(np.argmin(adev))]),
        "kalibr_gyroscope_noise_density": n_ * d2r,
        "kalibr_gyroscope_random_walk": None if k_ is None else k_ * d2r,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("file")
    p.add_argument("--columns", required=True, help="gyro columns, comma-separated")
    p.add_argument("--sample-rate", type=float, help="Hz (else from --time-column)")
    p.add_argument("--time-column")
    p.add_argument("--time-scale", type=float, default=1.0, help="multiply the time column by this to get seconds")
    p.add_argument("--scale", type=float, default=1.0, help="multiply the column by this first (e.g. LSB -> rad/s)")
    p.add_argument(
        "--scale-to-deg", type=float, default=1.0, help="then multiply by this to reach deg/s (57.29578 from rad/s)"
    )
    p.add_argument("--skiprows", type=int, default=0)
    p.add_argument("--sep", default=",")
    p.add_argument("--ours", help="gyrodenoise allan --json output of the same record")
    a = p.parse_args(argv)

    df = pd.read_csv(a.file, skiprows=a.skiprows, sep=a.sep, engine="python" if len(a.sep) > 1 else "c")
    df.columns = [c.strip() for c in df.columns]
    if a.sample_rate:
        fs = a.sample_rate
    else:
        t = df[a.time_column].to_numpy(float) * a.time_scale
        fs = (t.size - 1) / (t[-1] - t[0])
    out = {"file": a.file, "sample_rate_hz": fs, "n_samples": int(len(df)), "axes": {}}
    for c in a.columns.split(","):
        x = df[c].to_numpy(float) * a.scale * a.scale_to_deg
        out["axes"][c] = terms(x[np.isfinite(x)], fs)
    if a.ours:
        ours = json.load(open(a.ours))
        out["ours_sample_rate_hz"] = ours.get("sample_rate_hz")
        for c, ind in out["axes"].items():
            ax = ours["axes"].get(c)
            if ax is None:
                continue
            ex = ax["exported_terms"]
            ind["ours_exported"] = {"N": ex.get("N"), "B": ex.get("B"), "K": ex.get("K")}
            ind["ours_fit"] = {k: ax["terms"].get(k) for k in ("N", "B", "K")}
            ind["ratio_ours_over_indep"] = {
                "N": ex["N"] / ind["N_deg_sqrt_h"],
                "B": ex["B"] / ind["B_deg_h"],
                "K": None if ind["K_deg_h15"] is None else ex["K"] / ind["K_deg_h15"],
            }
    json.dump(out, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
