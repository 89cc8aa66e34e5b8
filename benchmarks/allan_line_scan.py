"""How well does ONE spectral line explain a published Allan curve, by frequency?

For a curve of ``../shared/data/allan_reference/avar_precomputed_curves.csv`` (default
the KVH 1750 gyro x, ADEV in deg/s): chi^2 of the joint fit (Q, N, B, K, Gauss-Markov
dictionary; weights from the 95 % bounds, no Huber) without a line, and with one line at
each frequency of ``modelgap.spectral.line_grid``; printed: the best frequencies, the chi^2
and the number of taus whose exact model is inside the bounds. Quoted in docs/GAP.md and in
the header of models/kvh1750.toml (the frequency is not unique).

With a third argument ``agm`` the dictionary holds the angle Gauss-Markov terms too
(``spectral.agm_grid``, as ``gap --allan`` uses when the fit without them is outside).

Run: .venv/bin/python benchmarks/allan_line_scan.py ["KVH 1750 IMU" deg/s [agm]]
     .venv/bin/python benchmarks/allan_line_scan.py LN200 rad/s agm
"""

from __future__ import annotations

import sys

import numpy as np
from _data import SHARED_DATA

CURVES = SHARED_DATA / "allan_reference" / "avar_precomputed_curves.csv"


def main(sensor="KVH 1750 IMU", unit="deg/s", dictionary=""):
    from gyrodenoise.modelgap import spectral as sp
    from gyrodenoise.modelgap.curve import Z95, _CurveLayout, inside, read_allan_curve
    c = read_allan_curve(CURVES, sensor=sensor, channel="Gyro. X", unit=unit)
    m = np.maximum(np.round(c.tau_s * c.sample_rate_hz), 1)
    lay = _CurveLayout(m, c.sample_rate_hz, c.n_samples)
    half = np.where(np.isfinite(c.lo_deg_s), (c.hi_deg_s - c.lo_deg_s) / 2.0, c.hi_deg_s - c.adev_deg_s)
    sd = 2.0 * c.adev_deg_s * half / Z95        # as curve.fit_curve (the upper bound alone where no lower)
    b = c.adev_deg_s ** 2 / sd
    specs = [(nm, None) for nm in sp.ALLAN_TERMS] + [("gauss_markov", t) for t in sp.gm_grid(lay)]
    if dictionary == "agm":
        specs += [("angle_gauss_markov", t) for t in sp.agm_grid(lay)]
    A = sp.allan_columns(specs, lay.m, lay.fs) / sd[:, None]
    x, chi0 = sp._nnls_huber(A, b, 0)
    print(f"{sensor}: {len(b)} taus; no line: chi2 {chi0:.1f}, inside at {int(inside(c, np.sqrt(A @ x * sd)).sum())}")
    grid = sp.line_grid(lay.fs, lay.m)
    L = sp.line_allan_columns(grid, lay.m, lay.fs) / sd[:, None]
    rows = []
    for j, f in enumerate(grid):
        A1 = np.hstack([A, L[:, [j]]])
        x1, chi = sp._nnls_huber(A1, b, 0)
        rows.append((chi, f, int(inside(c, np.sqrt(A1 @ x1 * sd)).sum()), np.sqrt(x1[-1]) * 3600))
    rows.sort()
    for chi, f, k, a in rows[:10]:
        print(f"  line at {f:8.2f} Hz, {a:.3g} deg/h: chi2 {chi:.1f}, inside at {k}")
    good = sorted(f for chi, f, k, a in rows if k == len(b))
    print(f"  one line puts the exact model inside at every tau for {len(good)} of {len(grid)} frequencies"
          + (f", {min(good):.1f}-{max(good):.1f} Hz" if good else ""))
    if good:        # the runs of adjacent grid frequencies that do
        idx = np.searchsorted(grid, good)
        runs = np.split(np.asarray(good), np.flatnonzero(np.diff(idx) > 1) + 1)
        print("  in " + ", ".join(f"{r[0]:.1f}-{r[-1]:.1f} Hz" for r in runs))


if __name__ == "__main__":
    main(*sys.argv[1:])
