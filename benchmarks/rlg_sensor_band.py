"""Does the ring-laser gyro's own band (above the base motion) need an output low-pass?

For each axis of ``../shared/data/static/psins_lasergyro.imu``: the Welch PSD (4096
points, the comparison's length) at 9-49.5 Hz with the wandering lines (23, 48, 35.8,
10.7 Hz) left out, fitted by non-negative least squares in relative terms with
(a) white angle noise + white rate (Q, N: the card's terms, exact discrete PSDs of
``modelgap.spectral``), (b) the same through a first-order low-pass, its cut-off
searched on a grid of 60 points from 5 to 200 Hz, and (c) a Gauss-Markov ANGLE
(``angle_gauss_markov``: white angle noise with a correlation time, on the same grid as
1 / (2 pi cut-off)) + white rate. Printed: the relative rms residual of
each (the Welch scatter of ~90 half-overlapping segments is ~0.11-0.13) and Q, N.
Quoted in docs/GAP.md ("What still does not hold").

Run: .venv/bin/python benchmarks/rlg_sensor_band.py
"""

from __future__ import annotations


import numpy as np
from _data import SHARED_DATA

DATA = SHARED_DATA / "static" / "psins_lasergyro.imu"
LINES_HZ = ((22.8, 23.3), (47.8, 48.4), (35.5, 36.1), (10.4, 11.0))


def fit(f, p, fs, cutoff_hz):
    from scipy.optimize import nnls

    from gyrodenoise.modelgap.spectral import psd_two_sided
    h = 1.0 if cutoff_hz is None else 1.0 / (1.0 + (f / cutoff_hz) ** 2)
    cols = np.column_stack([2.0 * psd_two_sided("quantization", f, fs) * h,
                            2.0 * psd_two_sided("angle_random_walk", f, fs) * h]) / p[:, None]
    c, _ = nnls(cols, np.ones_like(f))
    return float(np.sqrt(np.mean((cols @ c - 1.0) ** 2))), c


def fit_agm(f, p, fs, tau_s):
    from scipy.optimize import nnls

    from gyrodenoise.modelgap.spectral import psd_two_sided
    cols = np.column_stack([2.0 * psd_two_sided("angle_gauss_markov", f, fs, tau_s),
                            2.0 * psd_two_sided("angle_random_walk", f, fs)]) / p[:, None]
    c, _ = nnls(cols, np.ones_like(f))
    return float(np.sqrt(np.mean((cols @ c - 1.0) ** 2))), c


def main():
    from scipy.signal import welch

    from gyrodenoise.io.psins import read_psins
    log = read_psins(DATA)
    fs = log.sample_rate_hz
    for name in ("gyro_x", "gyro_y", "gyro_z"):
        f, p = welch(log.axis(name), fs=fs, nperseg=4096, noverlap=2048)
        keep = (f > 9.0) & (f < 49.5)
        for lo, hi in LINES_HZ:
            keep &= ~((f > lo) & (f < hi))
        f, p = f[keep], p[keep]
        rms0, c0 = fit(f, p, fs, None)
        best = min((fit(f, p, fs, fc) + (fc,) for fc in np.geomspace(5.0, 200.0, 60)), key=lambda r: r[0])
        agm = min((fit_agm(f, p, fs, 1.0 / (2.0 * np.pi * fc)) + (fc,) for fc in np.geomspace(5.0, 200.0, 60)),
                  key=lambda r: r[0])
        print(f"{name}: angle Gauss-Markov (tau = 1 / (2 pi {agm[2]:.1f} Hz)) + N: rms {agm[0]:.3f}")
        print(f"{name}: Q + N: rms {rms0:.3f} (Q {np.sqrt(c0[0]):.3g} deg, N {np.sqrt(c0[1]) * 60:.3g} deg/sqrt(h)); "
              f"through a 1st-order low-pass at {best[2]:.1f} Hz: rms {best[0]:.3f} "
              f"(Q {np.sqrt(best[1][0]):.3g}, N {np.sqrt(best[1][1]) * 60:.3g})")


if __name__ == "__main__":
    main()
