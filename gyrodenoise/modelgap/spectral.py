"""Exact spectra of the card's stochastic terms as simulated, their Allan variances, the
bands taken out of the comparison (`find_bumps`: broad bumps and lines wandering in
frequency) with the band-stop shared by the record and its simulations, and the joint
spectral fit.

Three questions about spectral lines are answered here and in
`gyrodenoise.analysis.spectrum`, each with its own statistic:

* is there a narrow line at f above the local floor? --
  `gyrodenoise.analysis.spectrum.find_peaks` (a local maximum whose ratio to the
  bias-corrected running median passes an F-test at a false-alarm rate per spectrum);
* is there a line too wide for one sinusoid, and over which bins? -- `wandering_lines`
  (runs of at least `MIN_LINE_BINS` bins standing `LINE_RATIO` x above the
  plain running median of the same `gyrodenoise.analysis.spectrum.running_median`,
  widened over their skirt): a sinusoid, which the card's ``sinusoid`` term gives, must NOT
  be reported, and a wandering line must be reported with its extent, which a per-bin test
  does not give;
* how far does a broad excess extend? -- `find_bumps` (band means against the lowest
  band on both sides, then `bump_tail_end`).

A narrow line the card lacks is found by comparison with the card's simulations instead
(the ``line`` signature's z, `gyrodenoise.modelgap.candidates.propose`), and the
lines of a published Allan curve, which has no spectrum, by the Allan chi^2
(`_pick_allan_lines`). The F-test of ``find_peaks`` is not used for wandering lines:
its threshold at the gap's segment count (about 1.6 x the floor for the ring-laser gyro record
psins_lasergyro.imu: 89 segments, a Bonferroni bound over 2048 bins) accepts runs that
the fixed 3 x rejects: on that record's x and y axes it adds two and three stop bands
(0.02-0.66, 1.5-2.3, 26.8-27.0, 39.1-39.4 Hz) and would move the results the tests pin.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from gyrodenoise.analysis.spectrum import nperseg_for_length, running_median, segment_count, welch_psd
from gyrodenoise.units import NOISE_SECTIONS

if TYPE_CHECKING:
    from gyrodenoise.modelgap.metric import Layout
    from gyrodenoise.simulator import ModelCard

N_LIN = 4000          # integration points below 40 / (m T) (50 per oscillation of sin^4)
N_TAIL = 1500         # log-spaced points above, where sin^4 averages to 3/8
MIN_BUMP_BINS = 16    # a bump spans at least this many Welch bins (narrower: a spectral line)
WIDEN = 2.0           # a bump is widened while its PSD stays above WIDEN x its far-side floor
MIN_LINE_BINS = 6     # a line wandering in frequency spans at least this many Welch bins
LINE_RATIO = 3.0      # ... standing LINE_RATIO x above the PSD's running median
LINE_BRIDGE_BINS = 8  # ... its runs joined across gaps of up to this many bins
LINE_WINDOW_HZ = 2.0  # ... taken over this many Hz
SKIRT_RATIO = 1.5     # ... and widened over its skirt: bins above SKIRT_RATIO x the running median,
                      # within LINE_BRIDGE_BINS of the band (~4 standard errors of a Welch bin over
                      # ~80 segments: a noise bin is there about once in 1e5)
TAIL_BINS = 16        # a bump's upper tail is tested in chunks of this many Welch bins ...
TAIL_SE = 3.0         # ... taken out while a chunk stands more than TAIL_SE standard errors above
TAIL_FIT = (1.5, 2.5)  # ... the sensor's level fitted over TAIL_FIT x the bump's upper edge


def psd_two_sided(name: str, f: np.ndarray, fs: float, tau_s: float | None = None) -> np.ndarray:
    """Two-sided PSD of one term with unit s-based coefficient (see module docstring)."""
    T = 1.0 / fs
    s2 = np.maximum(np.sin(np.pi * f * T) ** 2, 1e-300)
    if name == "angle_random_walk":
        return np.ones_like(f)
    if name == "quantization":
        return 4.0 * s2 / T
    if name == "rate_random_walk":
        return T * T / (4.0 * s2)
    if name in ("gauss_markov", "angle_gauss_markov"):
        if tau_s is None:
            raise ValueError(f"psd_two_sided: {name} needs its correlation time tau_s")
        a = math.exp(-T / tau_s)
        gm = (1.0 - a * a) * T / (1.0 - 2.0 * a * np.cos(2.0 * np.pi * f * T) + a * a)
        # angle_gauss_markov: a first-order GM ANGLE (std 1, tau_s), differenced / T
        return gm if name == "gauss_markov" else gm * 4.0 * s2 / (T * T)
    if name == "bias_instability":
        from gyrodenoise.simulator import _bank, parse_card
        card = parse_card(f"[sensor]\nname='unit'\nsample_rate_hz={fs!r}\n[terms]\n"
                          f"bias_instability = {{ B = 3600.0 }}\n")
        a_, _, sd = _bank(card)
        out = np.zeros_like(f)
        c = np.cos(2.0 * np.pi * f * T)
        for aj, sj in zip(a_, sd):
            out += sj * sj * (1.0 - aj * aj) * T / (1.0 - 2.0 * aj * c + aj * aj)
        return out
    raise ValueError(name)


def angle_gm_avar(m: npt.ArrayLike, fs: float, tau_s: float, sigma: float = 1.0) -> np.ndarray:
    """Closed-form overlapping Allan variance at cluster sizes ``m`` of the simulator's
    angle Gauss-Markov term (angle std ``sigma``, correlation time ``tau_s``, rate =
    angle differenced / T): the m-sample mean rate is ``(th_(k+m) - th_k) / (m T)``, the
    angle's autocovariance ``sigma^2 a^|j|`` with ``a = exp(-T / tau_s)``, so
    ``avar(m) = sigma^2 (3 - 4 a^m + a^(2m)) / (m T)^2``; ``3 sigma^2 / tau^2`` (quantization
    with Q = sigma) once ``m T >> tau_s``. An independent check of
    ``allan_columns([("angle_gauss_markov", tau_s)])``."""
    T = 1.0 / fs
    m = np.asarray(m, float)
    am = np.exp(-m * T / tau_s)
    return sigma * sigma * (3.0 - 4.0 * am + am * am) / (m * T) ** 2


EDGE_REL = 1e-9     # a frequency within this relative distance of a stop band's edge is on it


def stop_mask(f: np.ndarray, bands: Sequence[tuple[float, float]] | None) -> np.ndarray:
    """1 outside, 0 inside the stop bands [(lo, hi), ...] (Hz), edges included.

    An edge that is a bin's frequency (the top band ``0.3 fs .. fs / 2`` ends on the
    Nyquist bin; a found band starts on a Welch bin) is matched within `EDGE_REL`:
    compared exactly, rounding put that bin in or out as the rate moved by 2e-11 (the
    Nyquist bin kept at one rate and zeroed at the next)."""
    m = np.ones_like(f)
    af = np.abs(f)
    for lo, hi in bands or ():
        m[(af >= lo * (1.0 - EDGE_REL)) & (af <= hi * (1.0 + EDGE_REL))] = 0.0
    return m


def band_stop(y: npt.ArrayLike, fs: float, bands: Sequence[tuple[float, float]] | None) -> np.ndarray:
    """The record with the stop bands removed (FFT bins zeroed, the mean removed
    first and kept; zero-padded to a fast FFT length).

    Applied alike to the measured record and to every simulation of the card,
    so the comparison stays like for like (the signatures of both are taken
    through the same linear filter)."""
    if not bands:
        return np.asarray(y, float)
    from scipy import fft as sfft
    y = np.asarray(y, float)
    n = y.shape[0]
    nfft = sfft.next_fast_len(n, real=True)     # 184,718 = 2 x 92,359 (a prime): 100x slower unpadded
    mu = float(y.mean())
    X = sfft.rfft(y - mu, nfft)
    X *= stop_mask(sfft.rfftfreq(nfft, 1.0 / fs), bands)
    return sfft.irfft(X, nfft)[:n] + mu


def lowpass_gain(f: np.ndarray, fs: float, cutoff_hz: float | None = None) -> np.ndarray | float:
    """Power gain ``|H|^2`` of a first-order discrete low-pass on the sensor's output,
    ``y_k = a y_(k-1) + (1 - a) x_k`` with ``a = exp(-2 pi cutoff_hz / fs)``:
    ``(1 - a)^2 / (1 - 2 a cos(2 pi f / fs) + a^2)`` (1 at f = 0); 1 when ``cutoff_hz`` is None."""
    if cutoff_hz is None:
        return np.ones_like(f)
    a = math.exp(-2.0 * math.pi * cutoff_hz / fs)
    return (1.0 - a) ** 2 / (1.0 - 2.0 * a * np.cos(2.0 * np.pi * f / fs) + a * a)


def allan_columns(specs: Sequence[tuple[str, float | None]], m: Sequence[float] | np.ndarray, fs: float, bands: Sequence[tuple[float, float]] | None = (),
                  lowpass_hz: float | None = None) -> np.ndarray:
    """Allan variance at cluster sizes ``m`` of each term in ``specs`` (list of
    (name, tau_s or None)) with unit coefficient, through the stop mask (and the
    output low-pass `lowpass_gain` when ``lowpass_hz`` is given)."""
    T = 1.0 / fs
    out = np.zeros((len(m), len(specs)))
    for i, mi in enumerate(np.asarray(m, float)):
        f_lin_hi = min(fs / 2.0, 40.0 / (mi * T))
        f1 = np.linspace(0.0, f_lin_hi, N_LIN + 1)[1:]
        f1 = np.concatenate([np.logspace(math.log10(f1[0]) - 6, math.log10(f1[0]), 200, endpoint=False), f1])
        h1 = 4.0 * np.sin(np.pi * f1 * mi * T) ** 4 / (mi * mi * np.maximum(np.sin(np.pi * f1 * T) ** 2, 1e-300))
        parts = [(f1, h1)]
        if f_lin_hi < fs / 2.0:
            f2 = np.logspace(math.log10(f_lin_hi), math.log10(fs / 2.0), N_TAIL)
            h2 = 1.5 / (mi * mi * np.sin(np.pi * f2 * T) ** 2)
            parts.append((f2, h2))
        for j, (name, tc) in enumerate(specs):
            acc = 0.0
            for ff, hh in parts:
                acc += np.trapezoid(psd_two_sided(name, ff, fs, tc) * stop_mask(ff, bands) * hh
                                    * lowpass_gain(ff, fs, lowpass_hz), ff)
            out[i, j] = acc
    return out


def band_columns(specs: Sequence[tuple[str, float | None]], layout: Layout, bands: Sequence[tuple[float, float]] | None = (),
                 lowpass_hz: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Welch-band PSD (mean over each band's bins) of each term with unit
    coefficient, through the stop mask; and a mask of the bands clear of the stop
    bands (two Welch bins of margin for the Hann window's leakage)."""
    f = layout.freq_hz
    e = layout.band_edges
    df = layout.fs / layout.nperseg
    keep_bin = stop_mask(f, [(lo - 2 * df, hi + 2 * df) for lo, hi in bands or ()]) > 0
    cols = np.zeros((len(e) - 1, len(specs)))
    for j, (name, tc) in enumerate(specs):
        p = 2.0 * psd_two_sided(name, f, layout.fs, tc) * lowpass_gain(f, layout.fs, lowpass_hz)
        cols[:, j] = [p[e[i]:e[i + 1]].mean() for i in range(len(e) - 1)]
    clear = np.array([bool(np.all(keep_bin[e[i]:e[i + 1]])) for i in range(len(e) - 1)])
    return cols, clear


def record_psd(y: Sequence[float] | np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray, int]:
    """The record's one-sided Welch PSD above DC, with the segments of the gap
    signatures (`gyrodenoise.analysis.spectrum.nperseg_for_length`): (freq_hz,
    psd, nperseg)."""
    nper = nperseg_for_length(len(y))
    f, p, _ = welch_psd(y, fs, nper)
    if p is None:
        raise ValueError(f"a record of {len(y)} samples holds no Welch segment of {nper}")
    return f[1:], p[1:], nper


def find_bumps(y: npt.ArrayLike, fs: float, ratio: float = 3.0, span: float = 5.0,
               per_decade: int = 20) -> list[tuple[float, float, float]]:
    """The bands to take out of the comparison: broad spectral bumps and lines
    wandering in frequency (`wandering_lines`), [(lo_hz, hi_hz, peak_ratio)].

    A bump is a band whose PSD, averaged in log-spaced bands (``per_decade``),
    stands more than ``ratio`` times above the lowest band PSD on BOTH sides within
    a factor ``span`` in frequency (a monotone spectrum - white, 1/f, f^2 - never
    does; `_bump_flags`) and spans at least `MIN_BUMP_BINS` Welch bins
    (a narrower one is a line, for a sinusoid). Each is widened over its flanks
    (`_widen_run`), reaches down to DC when nothing below it is the sensor's,
    and up over its tail (`bump_tail_end`). A wandering line inside a bump
    is not listed again.

    This answers "how far does a broad excess extend?", not "is there a line at
    f?": its test is a ratio of band means to the band floor on both sides, not a
    per-bin test against a local floor (`gyrodenoise.analysis.spectrum.find_peaks`,
    which would report a bump as a row of peaks and not give its extent)."""
    y = np.asarray(y, float)
    f, p, nper = record_psd(y, fs)
    lines, p = wandering_lines(f, p)
    edges, fc, pv = _log_bands(f, p, per_decade)
    flag, side = _bump_flags(fc, pv, ratio, span)
    out = []
    i = 0
    while i < len(fc):
        if not flag[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(fc) and flag[j + 1]:
            j += 1
        i, j = _widen_run(i, j, fc, pv, span)
        bump = _bump_of_run(y, fs, f, p, nper, edges, fc, pv, side, i, j, span)
        if bump is not None:
            out.append(bump)
        i = j + 1
    return out + [ln for ln in lines if not any(a <= ln[0] and ln[1] <= b for a, b, _ in out)]


def _log_bands(f: np.ndarray, p: np.ndarray, per_decade: int) -> tuple[list[tuple[float, float]], np.ndarray, np.ndarray]:
    """Log-spaced bands (``per_decade``) over the Welch bins ``f``: (edges of the bands
    holding at least one bin [(lo_hz, hi_hz)], their centres (geometric), their mean PSD)."""
    # edges in Welch bin numbers (``f`` is bins 1, 2, ... of one spacing), then in Hz: which bin
    # falls in which band does not move with the rate
    nb = len(f)
    k = np.arange(1, nb + 1)
    edges_k = np.logspace(0.0, math.log10(nb) + 1e-9, int(math.ceil(math.log10(nb) * per_decade)) + 1)
    idx = np.searchsorted(k, edges_k)
    edges = edges_k * float(f[0])
    bands = [(edges[i], edges[i + 1], p[idx[i]:idx[i + 1]].mean()) for i in range(len(edges) - 1)
             if idx[i + 1] > idx[i]]
    fc = np.array([math.sqrt(a * b) for a, b, _ in bands])
    pv = np.array([v for _, _, v in bands])
    return [(a, b) for a, b, _ in bands], fc, pv


def _bump_flags(fc: np.ndarray, pv: np.ndarray, ratio: float, span: float) -> tuple[np.ndarray, np.ndarray]:
    """Per band: does it stand more than ``ratio`` above the lowest band on both sides
    within a factor ``span``; and that side floor (the larger of the two minima)."""
    flag = np.zeros(len(fc), bool)
    side = np.zeros(len(fc))
    for i in range(len(fc)):
        left = pv[(fc >= fc[i] / span) & (fc < fc[i])]
        right = pv[(fc > fc[i]) & (fc <= fc[i] * span)]
        if len(left) and len(right):
            side[i] = max(left.min(), right.min())
            flag[i] = pv[i] > ratio * side[i]
    return flag, side


def _widen_run(i: int, j: int, fc: np.ndarray, pv: np.ndarray, span: float) -> tuple[int, int]:
    """Bands ``i..j`` of a bump widened while the PSD stays above `WIDEN` x the
    lowest band on the far side (within ``span``)."""
    while i > 0:
        left = pv[(fc >= fc[i - 1] / span) & (fc < fc[i - 1])]
        if not len(left) or pv[i - 1] <= WIDEN * left.min():
            break
        i -= 1
    while j + 1 < len(fc):
        right = pv[(fc > fc[j + 1]) & (fc <= fc[j + 1] * span)]
        if not len(right) or pv[j + 1] <= WIDEN * right.min():
            break
        j += 1
    return i, j


def _bump_of_run(y: np.ndarray, fs: float, f: np.ndarray, p: np.ndarray, nper: int, edges: list[tuple[float, float]], fc: np.ndarray,
                 pv: np.ndarray, side: np.ndarray, i: int, j: int, span: float) -> tuple[float, float, float] | None:
    """The bump (lo_hz, hi_hz, peak_ratio) of the bands ``i..j`` (flagged, then widened),
    or None when it spans fewer than `MIN_BUMP_BINS` Welch bins (a narrow line: a
    sinusoid's business, not a band to take out)."""
    lo = edges[max(i - 1, 0)][0]
    hi = min(edges[min(j + 1, len(edges) - 1)][1], fs / 2.0)
    if np.count_nonzero((f >= lo) & (f <= hi)) < MIN_BUMP_BINS:
        return None
    peak = float(np.max(pv[i:j + 1] / np.maximum(side[i:j + 1], 1e-300)))
    # base motion down to DC: when every band below the bump stays above
    # WIDEN x the floor on the bump's upper side (the sensor's own level),
    # nothing below the bump is the sensor's (its terms give a PSD that is
    # flat, falling, or rising like f^2 from far below that floor)
    up = pv[(fc > hi) & (fc <= hi * span)]
    below = pv[fc < lo]
    if len(up) and len(below) and below.min() > WIDEN * up.min():
        lo = float(f[0])
    hi = bump_tail_end(f, p, hi, fs, y.shape[0], nper)
    return float(lo), float(hi), peak


def bump_tail_end(f: np.ndarray, p: np.ndarray, hi_hz: float, fs: float, n: int, nperseg: int) -> float:
    """Upper edge (Hz) of a bump with its tail: the base motion falls steeply above the
    band that `find_bumps` widened (2x its far-side floor), but a tail of 10-50 %
    over the sensor's level is left, and the comparison resolves the PSD to ~1 %
    (the RLG's y axis: 1.2-3x from 10 to 15 Hz). The sensor's level is fitted over
    `TAIL_FIT` x ``hi_hz`` by non-negative least squares (relative weights) on the
    shapes the sensor's terms take above a few Hz - white rate ``1``, white angle
    ``sin^2(pi f T)`` - and extrapolated down (a third shape falling like ``1 / sin^2(pi f
    T)`` is not separable from these over the span and extrapolated the noise of the fit:
    on seeded records it stops the edge with half the tail left). The edge moves up over
    each chunk of `TAIL_BINS` Welch bins whose mean stands more than
    `TAIL_SE` standard errors of a chunk (``1 / sqrt(1.8 K TAIL_BINS)``, ``K``
    Welch segments) above it, and stops at the first two chunks in a row that do not
    (or at the fitted span). Unchanged when the fitted span
    does not fit below the top Welch bin. ``p``: the PSD with the wandering lines
    replaced by their running median."""
    from scipy.optimize import nnls
    k0, k_fit0, k_fit1 = np.searchsorted(f, [hi_hz, TAIL_FIT[0] * hi_hz, TAIL_FIT[1] * hi_hz])
    if k_fit1 - k_fit0 < 2 * TAIL_BINS or TAIL_FIT[1] * hi_hz > f[-1]:
        return float(hi_hz)
    sn = np.sin(np.pi * f / fs) ** 2
    shapes = np.column_stack([np.ones_like(f), sn])
    fit = slice(k_fit0, k_fit1)
    c, _ = nnls(shapes[fit] / p[fit, None], np.ones(k_fit1 - k_fit0))
    level = shapes @ c
    n_seg = max(segment_count([n], nperseg), 1)
    limit = 1.0 + TAIL_SE / math.sqrt(1.8 * n_seg * TAIL_BINS)
    def above(k_: int) -> bool:
        return k_ + TAIL_BINS <= k_fit0 and p[k_:k_ + TAIL_BINS].mean() > limit * level[k_:k_ + TAIL_BINS].mean()
    k = k0
    while True:
        if above(k):
            k += TAIL_BINS
        elif above(k + TAIL_BINS):      # one chunk below the limit by chance is bridged
            k += 2 * TAIL_BINS
        else:
            break
    return float(f[k - 1]) if k > k0 else float(hi_hz)


def wandering_lines(f: np.ndarray, p: np.ndarray, ratio: float = LINE_RATIO,
                    window_hz: float = LINE_WINDOW_HZ) -> tuple[list[tuple[float, float, float]], np.ndarray]:
    """Lines too wide for one sinusoid: runs spanning at least `MIN_LINE_BINS`
    Welch bins (gaps of up to LINE_BRIDGE_BINS bins bridged) that stand more than ``ratio`` times
    above the running median of the PSD over ``window_hz``. A sinusoid stays within
    the Hann main lobe (4 bins; about 3 above 3x for a line 15x its floor); a line
    whose frequency wanders (a ring-laser gyro's dither, aliased; a motor whose
    speed drifts) spreads wider and no term of the card gives it. With ~80 Welch
    segments a noise bin 3x above the median is ~13 standard deviations off (a fixed
    ratio to the plain running median, not the F-test of
    `gyrodenoise.analysis.spectrum.find_peaks`: see the module docstring).
    Each run is then widened over its skirt: while a bin within LINE_BRIDGE_BINS of
    its edge stands above SKIRT_RATIO x the median (a line wandering over a band
    leaves weaker lobes beside its strongest run: the RLG y axis at 10.0-11.0 Hz).
    Returns ([(lo_hz, hi_hz, peak_ratio)] widened by 2 bins on either side, the
    PSD with those bins replaced by the running median)."""
    df = float(f[1] - f[0])
    w = max(int(round(window_hz / df)) | 1, 8 * MIN_LINE_BINS + 1)
    floor = running_median(p, w, ends="nearest")
    idx = np.flatnonzero(p > ratio * floor)
    out: list[tuple[float, float, float]] = []
    clean = p.copy()
    if not len(idx):
        return out, clean
    skirt = p > SKIRT_RATIO * floor
    for r in np.split(idx, np.flatnonzero(np.diff(idx) > LINE_BRIDGE_BINS + 1) + 1):
        if r[-1] - r[0] + 1 < MIN_LINE_BINS:
            continue
        lo, hi = int(r[0]), int(r[-1])
        while True:     # the skirt
            near = np.flatnonzero(skirt[max(lo - LINE_BRIDGE_BINS - 1, 0):lo])
            if not len(near):
                break
            lo = max(lo - LINE_BRIDGE_BINS - 1, 0) + int(near[0])
        while True:
            near = np.flatnonzero(skirt[hi + 1:hi + LINE_BRIDGE_BINS + 2])
            if not len(near):
                break
            hi = hi + 1 + int(near[-1])
        a, b = max(lo - 2, 0), min(hi + 2, len(f) - 1)
        out.append((float(f[a]), float(f[b]), float(np.max(p[r] / floor[r]))))
        clean[a:b + 1] = floor[a:b + 1]
    return out, clean


# ------------------------------------------------------------------ the joint fit
GM_PER_DECADE = 6
HUBER_C = 1.5
LINE_GRID_POINTS = 400     # line frequencies tried in an Allan-curve fit (log-spaced, line_grid)


AGM_TAU_MAX_S = 10.0       # the angle Gauss-Markov dictionary's longest correlation time


def gm_grid(layout: Any) -> list[float]:
    """Correlation times of the Gauss-Markov dictionary: 3 per decade, 2 samples .. record / 3."""
    lo, hi = math.log10(0.5 / layout.fs), math.log10(layout.n / layout.fs / 3.0)
    return list(10.0 ** np.arange(lo, hi + 1e-9, 1.0 / GM_PER_DECADE))


def agm_grid(layout: Any) -> list[float]:
    """Correlation times of the angle Gauss-Markov dictionary: GM_PER_DECADE per decade from
    half a sample to AGM_TAU_MAX_S (at most a tenth of the record). Shorter than half a
    sample the term is white angle noise (quantization); much longer, it is white rate noise
    (N^2 = 2 sigma^2 / tau) below tau: both already in the dictionary."""
    lo = math.log10(0.5 / layout.fs)
    hi = math.log10(max(min(AGM_TAU_MAX_S, layout.n / layout.fs / 10.0), 1.0 / layout.fs))
    return list(10.0 ** np.arange(lo, hi + 1e-9, 1.0 / GM_PER_DECADE))


def stochastic_specs(card: ModelCard) -> tuple[list[tuple[str, float | None]], np.ndarray]:
    """(specs, s-based squared coefficients) of a card's stochastic terms (dictionary form)."""
    from gyrodenoise.modelgap.settings import CARD_FIELD, SIGMA_TO_CARD
    specs: list[tuple[str, float | None]] = []
    coef: list[float] = []
    for nm in NOISE_SECTIONS:
        t = card.terms.get(nm)
        if t:
            fld, to_card = CARD_FIELD[nm]
            specs.append((nm, None))
            coef.append((t[fld] / to_card) ** 2)
    for kind, to_card in SIGMA_TO_CARD.items():
        for g in card.term_list(kind):
            specs.append((kind, g["tau"]))
            coef.append((g["sigma"] / to_card) ** 2)
    return specs, np.array(coef)


def card_allan_variance(card: ModelCard, m: Sequence[float] | np.ndarray, fs: float) -> np.ndarray:
    """Exact Allan variance (deg/s)^2 at cluster sizes ``m`` of a card's stochastic terms
    and sinusoids as the simulator draws them at ``fs`` (deterministic ramp, bias and
    transient left out: the published curves are of records without them)."""
    specs, coef = stochastic_specs(card)
    av = allan_columns(specs, m, fs) @ coef if specs else np.zeros(len(m))
    for s in card.term_list("sinusoid"):
        av = av + (s["amplitude"] / 3600.0) ** 2 * line_allan_columns([s["frequency"]], m, fs)[:, 0]
    return av


def line_allan_columns(freq_hz: npt.ArrayLike, m: npt.ArrayLike, fs: float) -> np.ndarray:
    """Allan variance at cluster sizes ``m`` of a sampled sinusoid of unit amplitude at
    each of ``freq_hz``: ``(1/4) * 4 sin^4(pi f m T) / (m^2 sin^2(pi f T))`` (the Allan
    filter at the line; its variance 1/2 split over +-f)."""
    T = 1.0 / fs
    m = np.asarray(m, float)[:, None]
    f = np.asarray(freq_hz, float)[None, :]
    return np.sin(np.pi * f * m * T) ** 4 / (m * m * np.sin(np.pi * f * T) ** 2)


def line_grid(fs: float, m: npt.ArrayLike) -> np.ndarray:
    """Candidate line frequencies for an Allan-curve fit: LINE_GRID_POINTS log-spaced
    from a tenth of the inverse of the longest cluster to 0.45 fs."""
    return np.geomspace(0.1 * fs / float(np.max(m)), 0.45 * fs, LINE_GRID_POINTS)


def _nnls_huber(A: np.ndarray, b: np.ndarray, robust: int) -> tuple[np.ndarray, float]:
    """Non-negative least squares of ``A x = b`` (columns scaled), ``robust`` Huber
    re-weightings: a point that no combination of the columns reaches (a sensor's
    internal filter at the shortest taus) is down-weighted instead of pulling every
    term off the others. Returns (x, chi2 of the last, unweighted residual)."""
    from scipy.optimize import nnls
    scale = np.max(np.abs(A), axis=0)
    scale[scale == 0] = 1.0
    w = np.ones(len(b))
    for _ in range(1 + int(robust)):
        c, _ = nnls(A / scale * w[:, None], b * w, maxiter=50 * A.shape[1])
        r = np.abs(A / scale @ c - b)
        w = np.where(r > HUBER_C, np.sqrt(HUBER_C / np.maximum(r, 1e-300)), 1.0)
    return c / scale, float(r @ r)


def _drop_unneeded(A: np.ndarray, b: np.ndarray, c: np.ndarray, chi2: float, min_dchi2: float, n_params: np.ndarray) -> np.ndarray:
    """Backward elimination: while some column with a non-zero coefficient raises the
    chi^2 by less than ``min_dchi2`` when it is left out (the others re-fitted), one of
    those is left out: the one with the most parameters (``n_params`` per column: a
    Gauss-Markov term's correlation time is one more; a Gauss-Markov much shorter than a
    sample is white noise, and it goes before the angle random walk it mimics), and
    among those the one that raises the chi^2 least. Only the terms of the full fit take
    part, and a term once at zero stays out (none enters in another's place). A term enters a fit only when the
    data ask for it: the NNLS optimum of a rich dictionary otherwise keeps small terms
    that follow one record's scatter (a white-noise record fitted with a short
    Gauss-Markov or a small quantization beside its white rate noise). Plain (not
    robust) chi^2: the rows' weights must be the data's true 1-sigma. Returns the
    coefficients."""
    off = c <= 0        # a term out of the fit stays out: the fit only shrinks
    while True:
        best = None
        for j in np.flatnonzero(~off):
            keep = ~off
            keep[j] = False
            cj = np.zeros_like(c)
            if np.any(keep):
                cj[keep], chi2_j = _nnls_huber(A[:, keep], b, 0)
            else:       # no term left: the residual is the data
                chi2_j = float(b @ b)
            key = (-n_params[j], chi2_j)
            if chi2_j - chi2 < min_dchi2 and (best is None or key < best[0]):
                best = (key, j, chi2_j, cj)
        if best is None:
            return c
        c, chi2 = best[3], best[2]
        off |= c <= 0


def _pick_allan_lines(A: np.ndarray, b: np.ndarray, sd: np.ndarray, m: np.ndarray, fs: float, max_lines: int,
                      inside_fn: Callable[[np.ndarray], bool]) -> list[float]:
    """Greedy choice of up to ``max_lines`` sinusoids (frequencies of `line_grid`)
    for an Allan-curve fit: each step adds the line that lowers the plain chi^2 most.
    The lines are kept only when, with them, the model is inside the published bounds
    at every tau (``inside_fn(model_avar)``) and it is not without them: a line is not spent
    on a curve it does not then explain. A published Allan curve has no spectrum, so
    this is a model choice on the Allan variance, not a spectral line detector."""
    grid = line_grid(fs, m)
    L = line_allan_columns(grid, m, fs) / sd[:, None]      # weighted like A (rows / 1-sigma)
    x0, _ = _nnls_huber(A, b, 0)
    if inside_fn(A @ x0):
        return []
    chosen: list[int] = []
    for _ in range(max_lines):
        best = min(((_nnls_huber(np.hstack([A, L[:, chosen + [j]]]), b, 0)[1], j) for j in range(len(grid))
                    if j not in chosen), default=None)
        if best is None:
            break
        chosen.append(best[1])
        A1 = np.hstack([A, L[:, chosen]])
        if inside_fn(A1 @ _nnls_huber(A1, b, 0)[0]):
            return [float(grid[j]) for j in chosen]
    return []


def fit_terms(layout: Any, bands: Sequence[tuple[float, float]] | None, avar_target: np.ndarray, avar_sd: np.ndarray,
              psd_target: np.ndarray | None, psd_sd: np.ndarray | None, rel_floor: float = 0.0, robust: int = 0,
              lowpass_hz: float | None = None, max_lines: int = 0,
              inside_fn: Callable[[np.ndarray], bool] | None = None, angle_gm: bool = False,
              min_dchi2: float = 0.0) -> tuple[dict[str, Any], np.ndarray, np.ndarray | None]:
    """Weighted non-negative least squares of the Allan variance (at ``layout.m``) and
    the Welch-band PSD (clear bands only) on Q, N, B, K and a dictionary of
    Gauss-Markov processes (`gm_grid`), each through the stop mask; with
    ``angle_gm`` also a dictionary of angle Gauss-Markov terms (`agm_grid`).

    ``robust``: that many Huber re-weightings (`_nnls_huber`).
    ``max_lines`` (Allan curve only, ``psd_target`` None): up to that many sinusoids
    (`_pick_allan_lines`), kept only when they bring the model inside the bounds
    (``inside_fn(model_avar) -> bool``) at every point.
    ``min_dchi2`` > 0: a term stays only when leaving it out (the others re-fitted)
    raises the plain chi^2 by at least that much (`_drop_unneeded`).
    Returns ``(terms, model_avar, model_psd)``: ``terms`` maps each of Q, N, B, K
    to its s-based coefficient (0 = not needed), ``"gauss_markov"`` to a list
    of ``(sigma_deg_s, tau_s)``, ``"angle_gauss_markov"`` to a list of ``(sigma_deg, tau_s)``
    and ``"sinusoid"`` to ``(amplitude_deg_s, frequency_hz)``."""
    specs = [(nm, None) for nm in NOISE_SECTIONS] + [("gauss_markov", t) for t in gm_grid(layout)]
    if angle_gm:
        specs += [("angle_gauss_markov", t) for t in agm_grid(layout)]
    A_a = allan_columns(specs, layout.m, layout.fs, bands, lowpass_hz)
    sd_a = np.maximum(avar_sd, rel_floor * np.abs(avar_target))
    A, b = A_a / sd_a[:, None], avar_target / sd_a
    A_p = None
    f_lines = []
    if psd_target is not None:      # no PSD for a published Allan curve
        if max_lines:
            raise ValueError("fit_terms: max_lines is for an Allan curve (psd_target None)")
        A_p, clear = band_columns(specs, layout, bands, lowpass_hz)
        if psd_sd is None:
            raise ValueError("fit_terms: psd_target needs psd_sd")
        sd_p = np.maximum(psd_sd, rel_floor * np.abs(psd_target))
        A = np.vstack([A, (A_p / sd_p[:, None])[clear]])
        b = np.concatenate([b, (psd_target / sd_p)[clear]])
    elif max_lines:
        if inside_fn is None:
            raise ValueError("fit_terms: max_lines needs inside_fn")
        inside = inside_fn
        f_lines = _pick_allan_lines(A, b, sd_a, layout.m, layout.fs, max_lines, lambda av: inside(av * sd_a))
        if f_lines:
            A_l = line_allan_columns(f_lines, layout.m, layout.fs)
            A_a, A = np.hstack([A_a, A_l]), np.hstack([A, A_l / sd_a[:, None]])
    c, chi2 = _nnls_huber(A, b, robust)
    if min_dchi2 > 0:
        if robust:
            raise ValueError("fit_terms: min_dchi2 compares plain chi^2 (robust=0)")
        n_par = np.array([1 if tc is None else 2 for _, tc in specs] + [2] * (A.shape[1] - len(specs)))
        c = _drop_unneeded(A, b, c, chi2, min_dchi2, n_par)
    terms: dict[str, Any] = {nm: float(c[i]) for i, nm in enumerate(NOISE_SECTIONS)}
    for kind in ("gauss_markov", "angle_gauss_markov"):
        terms[kind] = [(math.sqrt(c[i]), specs[i][1]) for i in range(len(NOISE_SECTIONS), len(specs))
                       if c[i] > 0 and specs[i][0] == kind]
    terms["sinusoid"] = [(math.sqrt(c[len(specs) + k]), f) for k, f in enumerate(f_lines) if c[len(specs) + k] > 0]
    return terms, A_a @ c, None if A_p is None else A_p @ c

