"""What keeping the integrated angle costs a causal filter: the RMSE frontier under the angle goal.

    python benchmarks/angle_frontier.py            # 3 seeds, 62 s records (as benchmarks/tuned.py)
    python benchmarks/angle_frontier.py --quick    # 1 seed, 12 s records

For every sensor x moving profile of the motion benchmark (benchmarks/motion_bench/sim.py) it runs
three linear causal families over a fine grid of their one parameter -- Butterworth order 2 (cutoff),
the steady-state constant-velocity Kalman filter and the steady-state constant-acceleration Kalman
filter (tracking index; gains from scipy.linalg.solve_discrete_are) -- and prints, per profile:

* ``best``: the lowest RMSE of any grid point over the best tuned causal filter's
  (benchmarks/motion_bench/baselines.py, tuned on the truth for RMSE), with that point's angle ratios;
* ``kept``: the lowest RMSE among the grid points whose integrated angle error over 0.1 s and
  1 s windows is at most raw's x 1.005 (the goal line of benchmarks/tuned.py), as the same ratio.

``kept`` / ``best`` is what the angle goal costs a linear causal filter on that record: where
``kept`` is above 1.5x (the benchmark's worst-profile line), no filter of these families meets
the angle goal and the RMSE goal together there.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from scipy.linalg import solve_discrete_are
from scipy.signal import lfilter, lfilter_zi, ss2tf

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.motion_bench import baselines as B  # noqa: E402
from benchmarks.motion_bench import bench, sim  # noqa: E402
from benchmarks.provenance import stamp  # noqa: E402

MARGIN = bench.NOT_WORSE_MARGIN


def kf_tf(order, tracking_index):
    """(b, a) of the steady-state Kalman filter of a polynomial rate model (order 1: constant
    velocity, 2: constant acceleration; white noise on the highest state, per sample, variance
    tracking_index^2 R), from the measured rate to its filtered estimate."""
    n = order + 1
    f = np.eye(n)
    for i in range(n):
        for j in range(i + 1, n):
            f[i, j] = 1.0 / math.factorial(j - i)
    g = np.array([[1.0 / math.factorial(n - 1 - i)] for i in range(n)])
    h = np.zeros((1, n))
    h[0, 0] = 1.0
    p = solve_discrete_are(f.T, h.T, tracking_index ** 2 * (g @ g.T), np.array([[1.0]]))
    k = p @ h.T / (p[0, 0] + 1.0)
    a_cl = (np.eye(n) - k @ h) @ f            # x+ = a_cl x+ + k z
    b, a = ss2tf(a_cl, k, h @ a_cl, h @ k)
    return np.atleast_1d(b.ravel()), np.atleast_1d(a.ravel())


def run_tf(b, a, z):
    return lfilter(b, a, z, zi=lfilter_zi(b, a) * z[0])[0]


def grid_outputs(z, fs):
    """(family, parameter, output) over each family's grid."""
    for fc in np.geomspace(0.01, 0.45 * fs, 60):
        yield "butter2", float(fc), B.butter(z, fs, 2, fc)
    for order, fam in ((1, "cv_kf"), (2, "ca_kf")):
        for e in np.arange(-9.0, 2.01, 0.25):
            try:
                b, a = kf_tf(order, 10.0 ** e)
            except (np.linalg.LinAlgError, ValueError):
                continue
            yield fam, float(10.0 ** e), run_tf(b, a, z)


def profile_row(sensor, profile, seeds, duration_s):
    best_tuned, best, kept = [], [], []
    for seed in seeds:
        rec = sim.record(sensor, profile, seed, duration_s)
        fs, z, ref = rec.sample_rate_hz, rec.z, rec.ref
        lo, hi = int(bench.SKIP_S * fs), z.size
        tuned = min(B.tune(f, z, ref, fs, lo, hi)[1] for f in B.CAUSAL)
        raw_w = [bench.window_angle_error_deg(z, ref, fs, lo, hi, w) for w in bench.ANGLE_WINDOWS_S]
        b_pt, k_pt = None, None
        for fam, par, y in grid_outputs(z, fs):
            e = bench.rmse(y, ref, lo, hi)
            ang = [bench.window_angle_error_deg(y, ref, fs, lo, hi, w) / r for w, r in zip(bench.ANGLE_WINDOWS_S, raw_w)]
            if b_pt is None or e < b_pt[0]:
                b_pt = (e, fam, par, ang)
            if max(ang) <= 1.0 + MARGIN and (k_pt is None or e < k_pt[0]):
                k_pt = (e, fam, par, ang)
        k_pt = k_pt or (bench.rmse(z, ref, lo, hi), "raw", 0.0, [1.0, 1.0])
        best_tuned.append(tuned)
        best.append(b_pt)
        kept.append(k_pt)
    g = lambda xs: float(np.exp(np.mean(np.log(xs))))  # noqa: E731
    return {"sensor": sensor, "profile": profile,
            "best": g([b[0] / t for b, t in zip(best, best_tuned)]), "best_fam": best[0][1],
            "best_angle": [max(b[3][i] for b in best) for i in range(2)],
            "kept": g([k[0] / t for k, t in zip(kept, best_tuned)]), "kept_fam": kept[0][1],
            "kept_angle": [max(k[3][i] for k in kept) for i in range(2)]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="1 seed, 12 s records")
    ap.add_argument("--sensors", default=",".join(sim.SENSORS))
    a = ap.parse_args(argv)
    seeds = (0,) if a.quick else (0, 1, 2)
    dur = bench.durations(a.quick)
    print(stamp())
    print(f"RMSE over the best tuned causal filter; {len(seeds)} seed(s), {dur:g} s records; "
          f"angle ratios = worst over seeds, 0.1 s / 1 s windows")
    print(f"{'sensor':9s} {'profile':11s} {'best of the grid':>34s}   {'best with angle <= raw x 1.005':>34s}")
    worst = 0.0
    for s in a.sensors.split(","):
        for p in sim.MOVING:
            r = profile_row(s, p, seeds, dur)
            worst = max(worst, r["kept"])
            print(f"{s:9s} {p:11s} {r['best']:6.2f}x {r['best_fam']:8s} ({r['best_angle'][0]:5.2f}/{r['best_angle'][1]:5.2f})"
                  f"   {r['kept']:6.2f}x {r['kept_fam']:8s} ({r['kept_angle'][0]:5.3f}/{r['kept_angle'][1]:5.3f})",
                  flush=True)
    print(f"worst profile with the angle kept: {worst:.2f}x the best tuned causal filter")
    return 0


if __name__ == "__main__":
    sys.exit(main())
