"""Which term would a card need for the published curves it does not fit? (evidence for a
simulator change; nothing here is written into a card).

For each gyro x curve of ``../shared/data/allan_reference/avar_precomputed_curves.csv``
(KVH 1750 in deg/s, LN200 and IMAR in rad/s): the joint fit of the card's terms (Q, N, B,
K, Gauss-Markov dictionary; weights from the 95 % bounds, Huber as in ``gap --allan``) on
the EXACT Allan columns of ``modelgap.spectral``, and the same fit
(a) through a first-order output low-pass (``lowpass_gain``), cut-off on a 16-point grid
    from 0.02 to 0.45 fs, best kept;
(b) with a dictionary of angle Gauss-Markov terms added (``angle_gauss_markov``: a GM
    ANGLE, differenced: white angle noise with a correlation time; 40 correlation times
    from half a sample to 10 s).
Printed: the taus whose exact model is outside the published bounds.

Run: .venv/bin/python benchmarks/allan_proposed_terms.py
"""

from __future__ import annotations


import numpy as np
from _data import SHARED_DATA

CURVES = SHARED_DATA / "allan_reference" / "avar_precomputed_curves.csv"


def main():
    from gyrodenoise.modelgap import spectral as sp
    from gyrodenoise.modelgap.curve import FIT_ROBUST, Z95, _CurveLayout, inside, read_allan_curve
    for sensor, unit in (("KVH 1750 IMU", "deg/s"), ("LN200", "rad/s"), ("IMAR", "rad/s")):
        c = read_allan_curve(CURVES, sensor=sensor, channel="Gyro. X", unit=unit)
        m = np.maximum(np.round(c.tau_s * c.sample_rate_hz), 1)
        lay = _CurveLayout(m, c.sample_rate_hz, c.n_samples)
        half = np.where(np.isfinite(c.lo_deg_s), (c.hi_deg_s - c.lo_deg_s) / 2.0, c.hi_deg_s - c.adev_deg_s)
        sd = 2.0 * c.adev_deg_s * np.where(np.isfinite(half) & (half > 0), half / Z95, 0.05 * c.adev_deg_s)
        b = c.adev_deg_s ** 2 / sd
        specs = [(nm, None) for nm in sp.ALLAN_TERMS] + [("gauss_markov", t) for t in sp.gm_grid(lay)]

        def out(A):
            x, chi = sp._nnls_huber(A, b, FIT_ROBUST)
            ok = inside(c, np.sqrt(np.maximum(A @ x * sd, 0.0)))
            return [float(t) for t in c.tau_s[~ok]]

        A0 = sp.allan_columns(specs, lay.m, lay.fs) / sd[:, None]
        print(f"{sensor} ({len(b)} taus): card terms: outside at {out(A0)}")
        best = None
        for fc in c.sample_rate_hz * np.geomspace(0.02, 0.45, 16):
            o = out(sp.allan_columns(specs, lay.m, lay.fs, (), fc) / sd[:, None])
            if best is None or len(o) < len(best[1]):
                best = (fc, o)
        print(f"  through a first-order output low-pass (best cut-off {best[0]:.1f} Hz): outside at {best[1]}")
        ag = [("angle_gauss_markov", t) for t in np.geomspace(0.5 / lay.fs, 10.0, 40)]
        AG = sp.allan_columns(ag, lay.m, lay.fs) / sd[:, None]
        print(f"  with angle Gauss-Markov terms: outside at {out(np.hstack([A0, AG]))}")


if __name__ == "__main__":
    main()
