"""Baselines tuned per run against the truth, as a drone or navigation engineer tunes them.

Each family is run over a grid of its parameters on one record and scored by
the RMSE against the reference over the evaluation window; the best point of
the grid is the tuned filter (an oracle: it saw the truth). Families:

causal
    ``butter1`` / ``butter2`` -- Butterworth order 1 / 2 over a cutoff grid
    (``scipy.signal.sosfilt``, started at the first sample's steady state);
    ``one_euro`` -- the 1-euro filter (Casiez, Roussel, Vogel, CHI 2012; the core's method
    ``one_euro``) over (min_cutoff, beta), derivative cutoff 1 Hz;
    ``cv_kf`` -- a constant-velocity Kalman filter, state [rate, rate
    derivative], white-noise-acceleration model, over its tracking index
    lambda = sigma_w T^2 / sigma_v (Kalata 1984);
    ``raw`` -- no filter (a user may choose none).
non-causal (offline references)
    ``savgol`` -- Savitzky-Golay, polynomial order 2 or 4, over window lengths;
    ``zp_butter`` -- zero-phase (forward-backward) Butterworth order 1-2 over the cutoffs;
    ``cv_rts`` -- the Rauch-Tung-Striebel smoother of the CV model over its tracking index;
    ``raw``.
"""

from __future__ import annotations

import math

import numpy as np

try:
    import numba
except ImportError:  # pragma: no cover
    numba = None


def _njit(fn):
    return numba.njit(cache=True, nogil=True)(fn) if numba is not None else fn


CAUSAL = ("raw", "butter1", "butter2", "one_euro", "cv_kf")
NONCAUSAL = ("raw", "savgol", "zp_butter", "cv_rts")   # the identity is zero-phase too
LOWPASS = ("butter1", "butter2")                        # "the best tuned low-pass" (rigid-body goal)


def cutoff_grid_hz(fs, quick):
    return np.geomspace(0.02, 0.45 * fs, 16 if quick else 36)


def tracking_grid(quick):
    return np.logspace(-12, 2, 15 if quick else 29)


def euro_grid(fs, quick):
    mins = np.geomspace(0.02, 0.45 * fs, 8 if quick else 14)
    betas = np.r_[0.0, np.logspace(-5, 0, 5 if quick else 11)]
    return [(m, b) for m in mins for b in betas]


def savgol_grid(fs, n, quick):
    hi = max(7, min(n // 4, int(20 * fs)))
    w = np.unique((np.geomspace(5, hi, 12 if quick else 26).astype(int) // 2) * 2 + 1)
    return [(int(x), p) for p in (2, 4) for x in w if x > p + 1]


def _score(y, ref, lo, hi):
    d = y[lo:hi] - ref[lo:hi]
    return math.sqrt(float(np.mean(d * d)))


# ------------------------------------------------------------------ Butterworth
def butter(z, fs, order, cutoff_hz, zero_phase=False):
    from scipy.signal import butter as _design, sosfilt, sosfilt_zi, sosfiltfilt
    sos = _design(order, cutoff_hz, fs=fs, output="sos")
    if zero_phase:
        return sosfiltfilt(sos, z, padtype="odd", padlen=min(z.size - 1, int(3 * fs / cutoff_hz)))
    y, _ = sosfilt(sos, z, zi=sosfilt_zi(sos) * z[0])
    return y


# ------------------------------------------------------------------ 1-euro
def one_euro(z: np.ndarray, fs: float, min_cutoff_hz: float, beta: float, d_cutoff_hz: float = 1.0) -> np.ndarray:
    """The 1-euro filter: the core's method ``one_euro`` (gd.denoise), the filter a user runs."""
    import gyrodenoise as gd
    return gd.denoise(np.asarray(z, dtype=float), float(fs), method="one_euro", min_cutoff_hz=float(min_cutoff_hz),
                      beta=float(beta), d_cutoff_hz=float(d_cutoff_hz))


@_njit
def _rmse(y, ref, lo, hi):
    acc = 0.0
    for k in range(lo, hi):
        e = y[k] - ref[k]
        acc += e * e
    return math.sqrt(acc / (hi - lo))


# ------------------------------------------------------------------ constant-velocity KF and its smoother
@_njit
def _cv_forward(z, fs, lam, xf, pf, xp, pp):
    """CV Kalman filter, R = 1 (only the ratio q/R matters), q = lam^2 / T^4 (Kalata's
    tracking index lam = sigma_w T^2 / sigma_v), discrete white-noise acceleration:
    Q = q [[T^4/4, T^3/2], [T^3/2, T^2]]. Stores the filtered (xf, pf) and predicted
    (xp, pp) moments; covariances as (p11, p12, p22)."""
    T = 1.0 / fs
    q = lam * lam / (T ** 4)
    q11 = q * T ** 4 / 4.0
    q12 = q * T ** 3 / 2.0
    q22 = q * T * T
    x0 = z[0]
    x1 = 0.0
    p11 = 1.0
    p12 = 0.0
    p22 = 1.0 / (T * T)
    for k in range(z.size):
        if k > 0:
            # predict
            x0 = x0 + T * x1
            n11 = p11 + 2.0 * T * p12 + T * T * p22 + q11
            n12 = p12 + T * p22 + q12
            n22 = p22 + q22
            p11, p12, p22 = n11, n12, n22
        xp[k, 0] = x0
        xp[k, 1] = x1
        pp[k, 0] = p11
        pp[k, 1] = p12
        pp[k, 2] = p22
        if k > 0:
            # update, R = 1
            s = p11 + 1.0
            k0 = p11 / s
            k1 = p12 / s
            v = z[k] - x0
            x0 += k0 * v
            x1 += k1 * v
            p22 = p22 - k1 * p12
            p12 = (1.0 - k0) * p12
            p11 = (1.0 - k0) * p11
        xf[k, 0] = x0
        xf[k, 1] = x1
        pf[k, 0] = p11
        pf[k, 1] = p12
        pf[k, 2] = p22


@_njit
def _cv_run(z, fs, lam, smooth, y, xf, pf, xp, pp):
    """Filtered (smooth False) or Rauch-Tung-Striebel smoothed rate into y: the
    forward pass, then backwards x_s[k] = x_f[k] + C (x_s[k+1] - x_p[k+1]),
    C = P_f[k] F' P_p[k+1]^-1."""
    _cv_forward(z, fs, lam, xf, pf, xp, pp)
    n = z.size
    if not smooth:
        for k in range(n):
            y[k] = xf[k, 0]
        return
    T = 1.0 / fs
    s0 = xf[n - 1, 0]
    s1 = xf[n - 1, 1]
    y[n - 1] = s0
    for k in range(n - 2, -1, -1):
        # P_f F' with F' = [[1, 0], [T, 1]]
        a11 = pf[k, 0] + T * pf[k, 1]
        a12 = pf[k, 1]
        a21 = pf[k, 1] + T * pf[k, 2]
        a22 = pf[k, 2]
        det = pp[k + 1, 0] * pp[k + 1, 2] - pp[k + 1, 1] * pp[k + 1, 1]
        i11 = pp[k + 1, 2] / det
        i12 = -pp[k + 1, 1] / det
        i22 = pp[k + 1, 0] / det
        d0 = s0 - xp[k + 1, 0]
        d1 = s1 - xp[k + 1, 1]
        s0 = xf[k, 0] + (a11 * i11 + a12 * i12) * d0 + (a11 * i12 + a12 * i22) * d1
        s1 = xf[k, 1] + (a21 * i11 + a22 * i12) * d0 + (a21 * i12 + a22 * i22) * d1
        y[k] = s0


@_njit
def _cv_grid(z, fs, lams, smooth, ref, lo, hi, out):
    n = z.size
    y = np.empty(n)
    xf, xp = np.empty((n, 2)), np.empty((n, 2))
    pf, pp = np.empty((n, 3)), np.empty((n, 3))
    for g in range(lams.size):
        _cv_run(z, fs, lams[g], smooth, y, xf, pf, xp, pp)
        out[g] = _rmse(y, ref, lo, hi)


def _cv(z, fs, tracking_index, smooth):
    z = np.ascontiguousarray(z, dtype=float)
    n = z.size
    y = np.empty(n)
    _cv_run(z, float(fs), float(tracking_index), smooth, y, np.empty((n, 2)), np.empty((n, 3)),
            np.empty((n, 2)), np.empty((n, 3)))
    return y


def cv_kf(z, fs, tracking_index):
    """Constant-velocity Kalman filter (causal)."""
    return _cv(z, fs, tracking_index, False)


def cv_rts(z, fs, tracking_index):
    """Rauch-Tung-Striebel smoother of the same model (offline)."""
    return _cv(z, fs, tracking_index, True)


# ------------------------------------------------------------------ Savitzky-Golay
def savgol(z, window, polyorder):
    """Centred Savitzky-Golay smoothing by FFT convolution, ends padded by odd reflection."""
    from scipy.signal import oaconvolve, savgol_coeffs
    h = savgol_coeffs(window, polyorder)
    half = window // 2
    m = min(half, z.size - 1)
    pad = np.r_[2 * z[0] - z[m:0:-1], z, 2 * z[-1] - z[-2:-m - 2:-1]]
    if m < half:
        pad = np.r_[np.full(half - m, pad[0]), pad, np.full(half - m, pad[-1])]
    return oaconvolve(pad, h[::-1], mode="valid")


# ------------------------------------------------------------------ tuning
def tune(family, z, ref, fs, lo, hi, quick=False):
    """Best parameters of ``family`` on this record: returns (params, rmse, output)."""
    z = np.ascontiguousarray(z, dtype=float)
    ref = np.ascontiguousarray(ref, dtype=float)
    if family == "raw":
        return {}, _score(z, ref, lo, hi), z.copy()
    if family in ("butter1", "butter2", "zp_butter"):
        orders = (int(family[-1]),) if family != "zp_butter" else (1, 2)
        best = (math.inf, None, None)
        for order in orders:
            for fc in cutoff_grid_hz(fs, quick):
                y = butter(z, fs, order, fc, zero_phase=family == "zp_butter")
                s = _score(y, ref, lo, hi)
                if s < best[0]:
                    best = (s, {"order": order, "cutoff_hz": float(fc)}, y)
        return best[1], best[0], best[2]
    if family == "one_euro":
        grid = euro_grid(fs, quick)
        mins = np.array([g[0] for g in grid])
        betas = np.array([g[1] for g in grid])
        runs = [one_euro(z, fs, m, b) for m, b in zip(mins, betas)]
        out = np.array([_rmse(y, ref, lo, hi) for y in runs])
        g = int(np.argmin(out))
        return {"min_cutoff_hz": float(mins[g]), "beta": float(betas[g])}, float(out[g]), runs[g]
    if family in ("cv_kf", "cv_rts"):
        lams = tracking_grid(quick)
        out = np.empty(lams.size)
        _cv_grid(z, float(fs), lams, family == "cv_rts", ref, lo, hi, out)
        g = int(np.argmin(out))
        return {"tracking_index": float(lams[g])}, float(out[g]), _cv(z, fs, lams[g], family == "cv_rts")
    if family == "savgol":
        best = (math.inf, None, None)
        for w, p in savgol_grid(fs, z.size, quick):
            y = savgol(z, w, p)
            s = _score(y, ref, lo, hi)
            if s < best[0]:
                best = (s, {"window": w, "polyorder": p}, y)
        return best[1], best[0], best[2]
    raise ValueError(f"unknown baseline family {family!r}")
