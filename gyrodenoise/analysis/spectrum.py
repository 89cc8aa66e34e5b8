"""Spectra of gyro records: Welch PSD, spectrogram, a filter's measured response,
vibration peaks against a robust noise floor, and their harmonics.

Plain functions over numpy arrays (numpy only: no scipy import). Values are in
the unit of the input (deg/s in the bridge), densities in unit**2/Hz, times in
s, frequencies in Hz.

* `segments` -- where the Welch segments go: within sessions (a record
  is cut at each restart and at every non-finite sample), after each session's
  first ``skip_samples`` (a filter's warm-up), half-overlapping.
* `choose_nperseg` (a target resolution, the bridge's views) and
  `nperseg_for_length` (a number of segments, the model-gap signatures) --
  two rules for the segment length; `segment_count` -- how many segments fit.
* `segment_spectra` / `welch_psd` -- one-sided density, Hann
  window, each segment's mean removed: ``sum(psd) * df`` is the variance
  (Parseval); equal to ``scipy.signal.welch(window="hann", noverlap=nperseg // 2,
  detrend="constant")`` to rounding (tests/analysis/test_spectrum.py). The mean over the
  segments is Welch's estimate; the segments themselves, in time order, are the
  spectrogram (`spectrogram`).
* `cross_response` -- the filter's response measured from the raw and
  filtered records (H1 = S_xf / S_xx, coherence, phase delay); it is the best
  linear description of an adaptive filter, the exact one of a linear filter.
* `sos_response` -- the computed response of second-order sections
  (the core's Butterworth low-pass).
* `analyse` -- all of it for a raw/filtered record pair, per axis.
* `running_median` -- the local level of a spectrum (exact, a width per
  bin or one for all, ends reflected or repeated).
* `noise_floor` -- running median of the PSD over a width proportional
  to the frequency (5..31 bins), corrected for the bias of the median of a
  chi-square variable: robust to the peaks themselves, following a steep slope.
* `find_peaks` -- local maxima above the floor by a threshold set for a
  chosen false-alarm probability per spectrum (`peak_threshold`: a Welch
  bin over its median floor treated as F-distributed), and at least
  ``min_ratio``; amplitude = rms of the excess over the floor across the
  window's main lobe.
* `presence` -- in what share of the segments a peak is there: a line
  all along, or one loud burst that dominates Welch's mean.
* `group_harmonics` -- a peak within tolerance of n x a lower peak
  (n = 2..``max_harmonic``) is that peak's harmonic.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from statistics import NormalDist
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from gyrodenoise.core.sessions import sessions

#: correlation of Hann windows overlapping by half (Harris 1978, table 1):
#: the Welch estimate's equivalent degrees of freedom use it
HANN_OVERLAP_CORR = 0.167
#: bins either side of a peak over which its power is summed (the Hann main
#: lobe is 2 bins either side; one more takes a tone between two bins)
PEAK_HALF_WIDTH_BINS = 3
#: lowest bin that can hold a peak: bins 0..3 are shaped by each segment's mean
#: removal (a notch at DC, two bins wide with the Hann window) and the floor's
#: 5-bin minimum window, which makes the steep low end of a spectrum look like a peak
MIN_PEAK_BIN = 4
#: a segment "holds" a peak when its power there is this many times the floor's (`presence`)
PRESENCE_RATIO = 2.0
#: default false-alarm probability of `find_peaks`, per spectrum
FALSE_ALARM = 0.01
#: bins of the running median of `noise_floor` (at most), and its width
#: either side relative to the bin index (`floor_window_bins`)
FLOOR_WINDOW_BINS = 31
FLOOR_REL_WIDTH = 0.5
#: variance inflation of a median of neighbouring Hann-window bins (their powers
#: correlate: 1 + 2 x 0.25**2 = 1.125 from the nearest neighbours' amplitude
#: coherence 0.5, rounded up to 1.2 for the others): an approximation; the
#: false-alarm rate it gives is measured in tests/analysis/test_spectrum.py
HANN_BIN_CORR_FACTOR = 1.2


def hann(n: int) -> np.ndarray:
    """Periodic Hann window of ``n`` samples (the spectral-analysis form)."""
    return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)


def choose_nperseg(session_lengths: Iterable[int], sample_rate_hz: float, resolution_hz: float = 0.5,
                   min_segments: int = 16, min_nperseg: int = 32, max_nperseg: int = 1024) -> int | None:
    """Segment length: the power of two nearest ``sample_rate_hz / resolution_hz``
    (within ``min_nperseg .. max_nperseg``), halved until the sessions give at
    least ``min_segments`` half-overlapping segments; None when even
    ``min_nperseg`` gives none."""
    lengths = [int(n) for n in session_lengths]
    target = max(min_nperseg, min(max_nperseg, sample_rate_hz / resolution_hz))
    n = 2 ** int(round(math.log2(target)))
    n = max(min_nperseg, min(max_nperseg, n))
    while n > min_nperseg and _count(lengths, n) < min_segments:
        n //= 2
    return n if _count(lengths, n) else None


def _count(lengths: list[int], n: int) -> int:
    step = n // 2
    return sum((m - n) // step + 1 for m in lengths if m >= n)


def segment_count(session_lengths: Iterable[int], nperseg: int) -> int:
    """Number of half-overlapping segments of ``nperseg`` samples that sessions of
    ``session_lengths`` samples hold (a session shorter than a segment holds none)."""
    return _count([int(n) for n in session_lengths], int(nperseg))


def nperseg_for_length(n_samples: int, min_segments: int = 32, min_nperseg: int = 64,
                       max_nperseg: int = 16384) -> int:
    """Segment length for one session of ``n_samples``: the largest power of two
    that gives at least ``min_segments`` segments without overlap
    (``n_samples / min_segments``), within ``min_nperseg .. max_nperseg`` (powers
    of two). Half-overlapping, that is about twice ``min_segments`` segments: the
    resolution of a long record is traded for a Welch estimate whose bins scatter
    by about 1/sqrt(1.8 x 2 x ``min_segments``) (the model-gap signatures)."""
    lo, hi = int(math.log2(min_nperseg)), int(math.log2(max_nperseg))
    return int(2 ** min(hi, max(lo, math.floor(math.log2(max(n_samples / float(min_segments), min_nperseg))))))


def segments(runs: Iterable[tuple[int, int]], nperseg: int) -> np.ndarray:
    """Start indices of the half-overlapping segments of length ``nperseg`` in ``runs``."""
    step = nperseg // 2
    out = [np.arange(a, b - nperseg + 1, step) for a, b in runs if b - a >= nperseg]
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def segment_spectra(x: npt.ArrayLike, starts: npt.ArrayLike, nperseg: int) -> np.ndarray:
    """Hann-windowed FFT of each segment (mean removed): complex (n_segments, nperseg // 2 + 1)."""
    x = np.asarray(x, dtype=np.float64)
    idx = np.asarray(starts, dtype=np.int64)[:, None] + np.arange(nperseg)
    seg = x[idx]
    seg = seg - seg.mean(axis=1, keepdims=True)
    return np.fft.rfft(seg * hann(nperseg), axis=1)


def density_scale(nperseg: int, sample_rate_hz: float) -> np.ndarray:
    """Per-bin factors turning |FFT|**2 of Hann segments into a one-sided density
    (unit**2/Hz): 2 / (fs * sum(w**2)), not doubled at 0 and at Nyquist."""
    w = hann(nperseg)
    sc = np.full(nperseg // 2 + 1, 2.0 / (sample_rate_hz * float(np.sum(w * w))))
    sc[0] *= 0.5
    if nperseg % 2 == 0:
        sc[-1] *= 0.5
    return sc


def freq_hz(nperseg: int, sample_rate_hz: float) -> np.ndarray:
    """The frequencies (Hz) of the bins of an rfft of ``nperseg`` samples."""
    return np.fft.rfftfreq(nperseg, 1.0 / sample_rate_hz)


def welch_psd(x: npt.ArrayLike, sample_rate_hz: float, nperseg: int, restarts: npt.ArrayLike | None = None,
              skip_samples: int = 0) -> tuple[np.ndarray, np.ndarray | None, int]:
    """(freq_hz, psd in unit**2/Hz, number of segments) of one record; psd is None
    when no segment fits. Segments stay within sessions (see `sessions`)."""
    x = np.asarray(x, dtype=np.float64)
    starts = segments(sessions(len(x), restarts, skip_samples, np.isfinite(x)), nperseg)
    f = freq_hz(nperseg, sample_rate_hz)
    if not len(starts):
        return f, None, 0
    X = segment_spectra(x, starts, nperseg)
    return f, np.mean(np.abs(X) ** 2, axis=0) * density_scale(nperseg, sample_rate_hz), len(starts)


def spectrogram(power: np.ndarray, starts: np.ndarray, nperseg: int,
                max_columns: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Time-frequency density from per-segment densities ``power`` (n_seg, n_bins):
    averaged in groups of consecutive segments to at most ``max_columns``
    columns. Returns (centre sample of each column, density (n_cols, n_bins))."""
    n = len(starts)
    if n == 0:
        return np.zeros(0), np.zeros((0, power.shape[1]))
    k = max(1, math.ceil(n / max_columns))
    groups = np.arange(n) // k
    cols = groups[-1] + 1
    dens = np.zeros((cols, power.shape[1]))
    np.add.at(dens, groups, power)
    counts = np.bincount(groups).astype(np.float64)
    centre = np.bincount(groups, weights=np.asarray(starts, dtype=np.float64) + nperseg / 2.0) / counts
    return centre, dens / counts[:, None]


def cross_response(X: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measured response of the filter raw -> filtered from their segment spectra
    ``X``, ``F`` (same segments): H1 = S_xf / S_xx (complex, per bin),
    coherence |S_xf|**2 / (S_xx S_ff) and the phase delay -unwrap(arg H) / (2 pi f)
    in samples (multiply by the sample period for seconds; NaN in bins 0 and 1,
    which each segment's mean removal empties)."""
    sxx = np.mean(np.abs(X) ** 2, axis=0)
    sff = np.mean(np.abs(F) ** 2, axis=0)
    sxf = np.mean(np.conj(X) * F, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(sxx > 0, sxf / sxx, np.nan)
        coh = np.where((sxx > 0) & (sff > 0), np.abs(sxf) ** 2 / (sxx * sff), np.nan)
    delay = phase_delay_samples(h)
    delay[:2] = np.nan
    return h, coh, delay


def phase_delay_samples(h: npt.ArrayLike) -> np.ndarray:
    """-unwrap(arg H) / omega of a response ``h`` on the bins of an rfft
    (omega = pi k / (n_bins - 1) rad/sample), in samples; NaN at DC."""
    h = np.asarray(h)
    omega = np.pi * np.arange(len(h)) / max(1, len(h) - 1)
    phase = np.unwrap(np.nan_to_num(np.angle(h)))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(omega > 0, -phase / np.where(omega > 0, omega, 1.0), np.nan)


def sos_response(sos: Iterable[Sequence[float]], freq_hz: npt.ArrayLike, sample_rate_hz: float) -> np.ndarray:
    """Complex response of second-order sections [(b0, b1, b2, a1, a2)] (a0 = 1)
    at ``freq_hz``: the product of (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)."""
    z1 = np.exp(-2j * np.pi * np.asarray(freq_hz, dtype=np.float64) / sample_rate_hz)
    h = np.ones_like(z1)
    for b0, b1, b2, a1, a2 in sos:
        h *= (b0 + b1 * z1 + b2 * z1 * z1) / (1.0 + a1 * z1 + a2 * z1 * z1)
    return h


def welch_dof(n_segments: float) -> float:
    """Equivalent degrees of freedom of a Welch estimate from ``n_segments``
    half-overlapping Hann segments (Welch 1967: 2K over the correlation of
    neighbours)."""
    k = float(n_segments)
    if k <= 1:
        return 2.0
    return 2.0 * k / (1.0 + 2.0 * (1.0 - 1.0 / k) * HANN_OVERLAP_CORR ** 2)


def chi2_quantile_per_dof(p: float, dof: float) -> float:
    """Quantile ``p`` of chi2(dof) / dof (Wilson-Hilferty: good to a few % for dof >= 10)."""
    z = NormalDist().inv_cdf(p)
    a = 2.0 / (9.0 * dof)
    return max(0.0, 1.0 - a + z * math.sqrt(a)) ** 3


def floor_window_bins(n_bins: int, window_bins: int = FLOOR_WINDOW_BINS,
                      rel_width: float = FLOOR_REL_WIDTH) -> np.ndarray:
    """Odd running-median width per bin: ``rel_width`` x the bin index either side
    (constant relative bandwidth, so that the floor follows the steep low end of a
    spectrum), at least 5 bins, at most ``window_bins``."""
    k = np.arange(n_bins)
    w = 2 * np.rint(rel_width * k).astype(np.int64) + 1
    return np.clip(w, 5, max(5, int(window_bins) | 1))


def running_median(psd: npt.ArrayLike, width_bins: npt.ArrayLike, ends: str = "reflect") -> np.ndarray:
    """Running median of ``psd`` over an odd number of bins centred on each bin:
    ``width_bins`` a scalar, or one width per bin. Beyond the ends the PSD is
    reflected about its first and last bins (``ends="reflect"``) or its end values
    repeated (``ends="nearest"``, as ``scipy.ndimage.median_filter(mode="nearest")``).
    The median of an odd number of values is one of them: the result is exact.

    The local level of a spectrum that a line or a bump stands above: robust to the
    line itself as long as it covers less than half the window."""
    psd = np.asarray(psd, dtype=np.float64)
    n = len(psd)
    widths = np.broadcast_to(np.asarray(width_bins, dtype=np.int64), (n,))
    if np.any(widths % 2 == 0):
        raise ValueError("running_median: the widths must be odd")
    h_max = int(widths.max()) // 2
    modes: dict[str, Literal["reflect", "edge"]] = {"reflect": "reflect", "nearest": "edge"}
    pad = np.pad(psd, h_max, mode=modes[ends])
    from numpy.lib.stride_tricks import sliding_window_view
    med = np.empty(n)
    for w in np.unique(widths):
        h = int(w) // 2
        ks = np.flatnonzero(widths == w)
        win = sliding_window_view(pad[h_max - h:len(pad) - (h_max - h)], int(w))
        med[ks] = np.median(win[ks], axis=1)
    return med


def noise_floor(psd: npt.ArrayLike, n_segments: float, window_bins: int = FLOOR_WINDOW_BINS) -> np.ndarray:
    """Robust floor of a Welch PSD: a running median (`running_median`, widths
    of `floor_window_bins`, ends reflected), divided by the median of
    chi2(dof)/dof so that it estimates the mean density where there is no peak."""
    psd = np.asarray(psd, dtype=np.float64)
    n = len(psd)
    if n < 7:
        return psd.copy()
    med = running_median(psd, floor_window_bins(n, min(window_bins, 2 * (n // 2) - 1)))
    return med / chi2_quantile_per_dof(0.5, welch_dof(n_segments))


def f_quantile(p: float, dof1: float, dof2: float) -> float:
    """Quantile ``p`` of the F(dof1, dof2) distribution (Paulson's approximation:
    Wilson-Hilferty applied to both chi-square variables)."""
    z = NormalDist().inv_cdf(p)
    a, b = 1.0 - 2.0 / (9.0 * dof2), 1.0 - 2.0 / (9.0 * dof1)
    c, d = 2.0 / (9.0 * dof2), 2.0 / (9.0 * dof1)
    qa, qb, qc = a * a - z * z * c, -2.0 * a * b, b * b - z * z * d
    if qa <= 0:
        return math.inf
    u = (-qb + math.sqrt(max(0.0, qb * qb - 4.0 * qa * qc))) / (2.0 * qa)   # u = F**(1/3)
    return u ** 3


def peak_threshold(n_bins: int, n_segments: float, false_alarm: float = FALSE_ALARM,
                   window_bins: npt.ArrayLike = FLOOR_WINDOW_BINS) -> float | np.ndarray:
    """PSD / floor above which a bin is a peak: the (1 - false_alarm / n_bins)
    quantile (a Bonferroni bound over the bins) of the ratio of a Welch bin,
    chi2(dof)/dof, to the floor, itself an estimate: the median of
    ``window_bins`` such bins (a scalar, or one per bin), which varies like a
    chi2 of pi/2 fewer degrees of freedom than their sum, fewer again for the
    correlation of neighbouring Hann bins (`HANN_BIN_CORR_FACTOR`). White
    noise then gives a false peak in a spectrum with probability about
    ``false_alarm`` (measured in tests/analysis/test_spectrum.py)."""
    dof = welch_dof(n_segments)
    p = 1.0 - false_alarm / max(1, n_bins)
    w = np.atleast_1d(np.asarray(window_bins, dtype=np.float64))
    cache = {v: f_quantile(p, dof, dof * v * 2.0 / math.pi / HANN_BIN_CORR_FACTOR) for v in np.unique(w)}
    out = np.array([cache[v] for v in w])
    return float(out[0]) if np.ndim(window_bins) == 0 else out


def find_peaks(freq_hz: npt.ArrayLike, psd: npt.ArrayLike, n_segments: float, floor: npt.ArrayLike | None = None,
               min_freq_hz: float = 0.0, false_alarm: float = FALSE_ALARM, min_ratio: float = 2.0,
               max_peaks: int = 8, half_width_bins: int = PEAK_HALF_WIDTH_BINS) -> list[dict[str, Any]]:
    """Vibration peaks of a Welch PSD, strongest first (at most ``max_peaks``).

    A peak is a local maximum at or above ``min_freq_hz`` (and bin
    `MIN_PEAK_BIN`)
    whose PSD is above the floor (`noise_floor` unless given) by the
    larger of `peak_threshold` and ``min_ratio``; of two within
    ``half_width_bins`` the higher is kept. Each is a dict: ``freq_hz`` (log-
    parabolic interpolation over 3 bins), ``bin``, ``amplitude_rms`` (square
    root of the excess power over the floor within ``half_width_bins``: the rms
    of a tone, sqrt(2) below its amplitude), ``ratio_db`` (peak over floor).

    The statistic: the ratio of a Welch bin to the floor, F-distributed for noise
    alone, against its (1 - false_alarm / n_bins) quantile. It answers "is there a
    narrow line at f above the local floor?"; a line wandering wider than the
    window's main lobe and its extent, or a broad bump's extent, are other questions
    (`gyrodenoise.modelgap.spectral`)."""
    f = np.asarray(freq_hz, dtype=np.float64)
    p = np.asarray(psd, dtype=np.float64)
    nb = len(p)
    if nb < 5 or not np.all(np.isfinite(p)):
        return []
    floor = noise_floor(p, n_segments) if floor is None else np.asarray(floor, dtype=np.float64)
    df = f[1] - f[0]
    cand_bins = np.flatnonzero(f >= min_freq_hz)
    cand_bins = cand_bins[(cand_bins >= MIN_PEAK_BIN) & (cand_bins <= nb - 1)]
    thr = np.maximum(peak_threshold(len(cand_bins), n_segments, false_alarm, floor_window_bins(nb)),
                     float(min_ratio))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(floor > 0, p / floor, 0.0)
    left = np.r_[-np.inf, p[:-1]]
    right = np.r_[p[1:], -np.inf]
    is_max = (p > left) & (p >= right) & (ratio > thr)
    ks = [int(k) for k in cand_bins if is_max[k]]
    ks.sort(key=lambda k: -p[k])
    kept: list[int] = []
    for k in ks:
        if all(abs(k - j) > half_width_bins for j in kept):
            kept.append(k)
    peaks = []
    for k in kept[:max_peaks]:
        excess = excess_power(p, floor, k, df, half_width_bins)
        fk = f[k]
        if 0 < k < nb - 1 and p[k - 1] > 0 and p[k + 1] > 0:
            a, b, c = np.log(p[k - 1]), np.log(p[k]), np.log(p[k + 1])
            den = a - 2.0 * b + c
            if den < 0:
                fk = f[k] + 0.5 * (a - c) / den * df
        peaks.append({"freq_hz": float(fk), "bin": k, "amplitude_rms": math.sqrt(excess),
                      "ratio_db": float(10.0 * math.log10(ratio[k]))})
    return peaks


def excess_power(psd: npt.ArrayLike, floor: npt.ArrayLike, k: int, resolution_hz: float,
                 half_width_bins: int = PEAK_HALF_WIDTH_BINS) -> float:
    """Power (unit**2) of ``psd`` above ``floor`` within ``half_width_bins`` of bin ``k``:
    the square of a peak's rms amplitude."""
    p, fl = np.asarray(psd), np.asarray(floor)
    lo, hi = max(0, k - half_width_bins), min(len(p), k + half_width_bins + 1)
    return float(np.sum(np.maximum(p[lo:hi] - fl[lo:hi], 0.0)) * resolution_hz)


def presence(segment_psd: np.ndarray, floor: np.ndarray, k: int, ratio: float = PRESENCE_RATIO) -> float:
    """Fraction of the segments (rows of ``segment_psd``, one density per
    segment) whose power in bins k-1..k+1 exceeds ``ratio`` x the floor's there:
    near 1 for a line present all along, near 1/N for one burst of N segments.
    Noise alone: the sum of 3 bins of a Hann periodogram exceeds twice its mean
    in ~9.5 % of the segments (measured, tests/analysis/test_spectrum.py; 6.2 % if the
    3 bins were independent, chi-square with 6 degrees of freedom: the Hann
    window correlates neighbouring bins)."""
    lo, hi = max(0, k - 1), min(segment_psd.shape[1], k + 2)
    power = np.sum(segment_psd[:, lo:hi], axis=1)
    return float(np.mean(power > ratio * float(np.sum(floor[lo:hi]))))


def analyse(raw: npt.ArrayLike, filtered: npt.ArrayLike, sample_rate_hz: float, restarts: npt.ArrayLike | None = None,
            skip_samples: int = 0, usable: npt.ArrayLike | None = None, min_freq_hz: float = 0.0, min_ratio: float = 2.0,
            max_peaks: int = 8, false_alarm: float = FALSE_ALARM,
            sos: Iterable[Sequence[float]] | None = None) -> dict[str, Any] | None:
    """The spectrum view of a raw/filtered record pair (``(n, m)`` arrays, one
    column per axis), or None when no session holds a segment.

    Welch segments (`choose_nperseg`) over the usable samples (``usable``:
    bool per sample, default all finite) within sessions; the filter's response
    over those after each session's first ``skip_samples``. Returns a dict:
    ``nperseg``, ``freq_hz``, ``starts`` (segment starts), ``response_segments``,
    ``psd_raw``/``psd_filtered``/``floor_raw``/``floor_filtered`` (lists per
    column), ``power_raw_sum`` (per-segment density summed over the columns: the
    spectrogram's input), ``gain``/``coherence``/``delay_s`` (lists per column;
    None when no segment follows the warm-up or the output equals the input),
    ``peaks`` (per column, `find_peaks` then `group_harmonics`, each
    with ``present_in_segments`` (`presence`), ``filtered_amplitude_rms`` at
    the same bins, ``filter_gain`` and ``phase_delay_s`` there), ``filtered_is_raw``, and with ``sos`` (second-order
    sections of a linear filter) ``computed_gain`` and ``computed_delay_s``."""
    x = np.asarray(raw, dtype=np.float64)
    y = np.asarray(filtered, dtype=np.float64)
    if x.ndim == 1:
        x, y = x[:, None], y[:, None]
    n = len(x)
    usable = (np.isfinite(x).all(axis=1) & np.isfinite(y).all(axis=1)) if usable is None else np.asarray(usable)
    runs = sessions(n, restarts, 0, usable)
    nper = choose_nperseg([b - a for a, b in runs], sample_rate_hz)
    if nper is None:
        return None
    starts = segments(runs, nper)
    starts_h = segments(sessions(n, restarts, skip_samples, usable), nper)
    freq = freq_hz(nper, sample_rate_hz)
    df = float(freq[1])
    scale = density_scale(nper, sample_rate_hz)
    same = bool(np.array_equal(x[usable], y[usable]))
    out: dict[str, Any] = {"nperseg": nper, "freq_hz": freq, "starts": starts, "response_segments": len(starts_h),
                           "filtered_is_raw": same, "computed_gain": None, "computed_delay_s": None}
    for key in ("psd_raw", "psd_filtered", "floor_raw", "floor_filtered", "gain", "coherence",
                "delay_s", "peaks"):
        out[key] = []
    if sos is not None:
        h_calc = sos_response(sos, freq, sample_rate_hz)
        out["computed_gain"] = np.abs(h_calc)
        out["computed_delay_s"] = phase_delay_samples(h_calc) / sample_rate_hz
    power_sum = 0.0
    for k in range(x.shape[1]):
        X = segment_spectra(x[:, k], starts, nper)
        pxx = np.abs(X) ** 2 * scale
        psd_x = pxx.mean(axis=0)
        psd_y = (np.abs(segment_spectra(y[:, k], starts, nper)) ** 2 * scale).mean(axis=0)
        floor_x, floor_y = noise_floor(psd_x, len(starts)), noise_floor(psd_y, len(starts))
        power_sum = power_sum + pxx
        gain = coh = delay_s = None
        if len(starts_h) and not same:
            Xh = X if np.array_equal(starts_h, starts) else segment_spectra(x[:, k], starts_h, nper)
            h, coh, delay = cross_response(Xh, segment_spectra(y[:, k], starts_h, nper))
            gain, delay_s = np.abs(h), delay / sample_rate_hz
        peaks = group_harmonics(find_peaks(freq, psd_x, len(starts), floor=floor_x, min_freq_hz=min_freq_hz,
                                           false_alarm=false_alarm, min_ratio=min_ratio,
                                           max_peaks=max_peaks), df)
        for q in peaks:
            b = q["bin"]
            q["present_in_segments"] = presence(pxx, floor_x, b)
            q["filtered_amplitude_rms"] = math.sqrt(excess_power(psd_y, floor_y, b, df))
            q["filter_gain"] = None if gain is None else float(gain[b])
            q["phase_delay_s"] = None if delay_s is None else float(delay_s[b])
        for key, val in (("psd_raw", psd_x), ("psd_filtered", psd_y), ("floor_raw", floor_x),
                         ("floor_filtered", floor_y), ("gain", gain), ("coherence", coh),
                         ("delay_s", delay_s), ("peaks", peaks)):
            out[key].append(val)
    out["power_raw_sum"] = power_sum
    return out


def minus3db_bin(freq_hz: npt.ArrayLike, gain: npt.ArrayLike) -> int | None:
    """The first bin (above 0 Hz) where ``gain`` is below 1/sqrt(2), or None."""
    f = np.asarray(freq_hz)
    g = np.asarray(gain, dtype=np.float64)
    below = np.flatnonzero((f > 0) & np.isfinite(g) & (g < 1.0 / math.sqrt(2.0)))
    return int(below[0]) if len(below) else None


def group_harmonics(peaks: Iterable[dict[str, Any]], resolution_hz: float, max_harmonic: int = 5,
                    rel_tol: float = 0.01) -> list[dict[str, Any]]:
    """Set ``harmonic_of_hz`` and ``harmonic_n`` on each peak (in place; returns
    the peaks sorted by frequency): a peak within tolerance of n x a lower peak
    that is not itself a harmonic (n = 2..``max_harmonic``) is that peak's n-th
    harmonic, provided its harmonics 2..n-1 were found too (a chance match of
    a high multiple of a low peak is likely, a chain of them is not); the
    others get None and 1, and ``harmonics_hz`` lists what was grouped under
    them. Tolerance: max((n + 1) / 4 x ``resolution_hz``,
    ``rel_tol`` x the frequency): a quarter bin of error on each peak's
    frequency, the fundamental's multiplied by n."""
    out = sorted(peaks, key=lambda q: q["freq_hz"])
    for q in out:
        q["harmonic_of_hz"], q["harmonic_n"], q["harmonics_hz"] = None, 1, []
    found: dict[int, set[int]] = {}         # id of a fundamental -> harmonic numbers found
    for i, q in enumerate(out):
        for base in out[:i]:
            if base["harmonic_of_hz"] is not None or base["freq_hz"] <= 0:
                continue
            n = int(round(q["freq_hz"] / base["freq_hz"]))
            tol = max(0.25 * (n + 1) * resolution_hz, rel_tol * q["freq_hz"])
            chain = all(m in found.get(id(base), ()) for m in range(2, n))
            if 2 <= n <= max_harmonic and chain and abs(q["freq_hz"] - n * base["freq_hz"]) <= tol:
                q["harmonic_of_hz"], q["harmonic_n"] = base["freq_hz"], n
                found.setdefault(id(base), set()).add(n)
                base["harmonics_hz"].append(q["freq_hz"])
                break
    return out
