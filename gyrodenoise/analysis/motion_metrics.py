"""What a filter did to the real motion, measured on (raw, filtered) record pairs.

The noise figure of a denoiser (std of first differences) rewards a flat line:
an output that lost every manoeuvre scores best. These metrics say how much of
the slow, real motion survived and how late it came out. Plain functions over
numpy arrays; the values are in the unit of the input (any unit, the same for
``raw`` and ``filtered``), times in seconds, rates in Hz.

* `lowband` -- the 0..``band_hz`` content of a record: zero-phase
  Butterworth low-pass (order 4, forwards and backwards), per segment, each
  segment's mean removed (a constant offset is not motion).
* `lowband_kept` -- correlation and amplitude ratio (std filtered / std
  raw) of the low-band content of the filtered and the raw record: identity
  keeps 1 and 1; a constant output keeps amplitude 0 (correlation undefined).
* `lag_s` -- the delay of the filtered low band behind the raw low band,
  at the peak of their cross-correlation (parabolic interpolation between
  samples), searched within ``max_lag_s``.
* `envelope_violation` -- the first sample where a filtered record is not
  finite or leaves the range of the raw samples seen since the last restart.
* `motion_above_noise` -- whether the raw low band holds motion at all
  (at rest it is noise, and "kept" figures measure noise removed).
* `motion_loss` -- the warning rule: most of the real motion removed.
* `white_noise_std` -- the record's white-noise level that motion does not
  lift: the core's own estimate (the motion filter's 4th differences at several
  lags, or its spectral noise floor where lower), the level the two functions above
  compare the low band with.

Segments: a record is cut at each restart (``restarts[i]`` True: sample i is the
first of a new session) and at every non-finite sample of either record; the
first ``skip_samples`` samples of each session (a filter's warm-up, when it
passes the raw samples through) and segments shorter than
`min_segment_samples` are left out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from gyrodenoise.core.sessions import sessions

#: default upper edge of the "real motion" band, Hz: vehicle manoeuvres (attitude
#: changes, turns) are below a few Hz; vibration and sensor noise are above
LOWBAND_HZ = 5.0
#: order of the Butterworth low-pass that isolates the band (applied forwards and
#: backwards: zero phase, squared magnitude)
LOWBAND_ORDER = 4
#: below this sample rate (Hz) a record is too slow to denoise: `too_slow_to_denoise`
MIN_DENOISE_RATE_HZ = 4.0 * LOWBAND_HZ
#: warning thresholds of `motion_loss`
KEPT_AMPLITUDE_MIN = 0.5
KEPT_CORR_MIN = 0.8
#: the raw low band "has motion" when its std is this many times the white noise's
#: share of the band (`lowband_noise_std`)
MOTION_TO_NOISE_MIN = 3.0
#: default largest lag searched by `lag_s`, s
MAX_LAG_S = 0.5


def too_slow_to_denoise(sample_rate_hz: float | None, band_hz: float = LOWBAND_HZ) -> bool:
    """True when samples come too slowly for denoising to keep the motion.

    The threshold is 4 x ``band_hz`` (20 Hz for the 5 Hz motion band): the
    Nyquist frequency is then twice the band, so the band can be isolated from
    the noise above it and a filter can average several samples per period of
    the fastest motion. Below it (telemetry RAW_IMU at 1-4 Hz: samples 0.25-1 s
    apart) consecutive samples are not repeated looks at the same rate: whatever
    a filter removes is motion as much as noise, and the first-difference noise
    figure is dominated by motion. ``None`` (rate unknown) counts as too slow."""
    return sample_rate_hz is None or not sample_rate_hz >= 4.0 * band_hz


def min_segment_samples(sample_rate_hz: float, band_hz: float = LOWBAND_HZ) -> int:
    """Shortest segment the low band is measured on: two periods of the band
    edge, and at least 3 x (2 x order + 1) + 1 samples (the forward-backward
    filter's padding)."""
    return max(int(math.ceil(2.0 * sample_rate_hz / band_hz)), 3 * (2 * LOWBAND_ORDER + 1) + 1)


def _zero_phase(x: npt.ArrayLike, sample_rate_hz: float, band_hz: float) -> np.ndarray:
    """Zero-phase (forward-backward) Butterworth low-pass of order
    LOWBAND_ORDER, by the core's ``lowpass`` method (no scipy.signal import,
    which costs ~1 s of a bridge run; the core's cascade equals
    ``scipy.signal.sosfilt(butter(...))``, tested)."""
    from gyrodenoise.denoiser import denoise
    if not (sample_rate_hz > 0 and 0 < band_hz < 0.5 * sample_rate_hz):
        raise ValueError(f"band_hz must be > 0 and below half the sample rate "
                         f"({0.5 * sample_rate_hz:g} Hz), got {band_hz!r}")
    return denoise(x, sample_rate_hz, method="lowpass", cutoff_hz=band_hz, order=LOWBAND_ORDER,
                   zero_phase=True)


def _lowband_pairs(raw: npt.ArrayLike, filtered: npt.ArrayLike, sample_rate_hz: float, band_hz: float, restarts: npt.ArrayLike | None,
                   skip_samples: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """[(raw low band, filtered low band)] per kept segment, means removed."""
    raw = np.asarray(raw, dtype=np.float64)
    filtered = np.asarray(filtered, dtype=np.float64)
    if raw.shape != filtered.shape or raw.ndim != 1:
        raise ValueError(f"raw and filtered must be 1-D of the same length, got {raw.shape} and "
                         f"{filtered.shape}")
    _zero_phase(np.zeros(1), sample_rate_hz, band_hz)      # checks the band
    finite = np.isfinite(raw) & np.isfinite(filtered)
    out = []
    for a, b in sessions(len(raw), restarts, skip_samples, finite, min_segment_samples(sample_rate_hz, band_hz)):
        lr = _zero_phase(raw[a:b] - raw[a:b].mean(), sample_rate_hz, band_hz)
        lf = _zero_phase(filtered[a:b] - filtered[a:b].mean(), sample_rate_hz, band_hz)
        out.append((lr - lr.mean(), lf - lf.mean()))
    return out


def lowband(x: npt.ArrayLike, sample_rate_hz: float, band_hz: float = LOWBAND_HZ,
            restarts: npt.ArrayLike | None = None) -> np.ndarray:
    """The 0..``band_hz`` content of ``x``, each segment's mean removed; NaN on
    samples outside the measured segments (see the module's docstring)."""
    x = np.asarray(x, dtype=np.float64)
    _zero_phase(np.zeros(1), sample_rate_hz, band_hz)      # checks the band
    out = np.full(len(x), np.nan)
    for a, b in sessions(len(x), restarts, 0, np.isfinite(x), min_segment_samples(sample_rate_hz, band_hz)):
        y = _zero_phase(x[a:b] - x[a:b].mean(), sample_rate_hz, band_hz)
        out[a:b] = y - y.mean()
    return out


def lowband_kept(raw: npt.ArrayLike, filtered: npt.ArrayLike, sample_rate_hz: float, band_hz: float = LOWBAND_HZ,
                 restarts: npt.ArrayLike | None = None, skip_samples: int = 0) -> dict[str, Any]:
    """How much of the raw record's 0..``band_hz`` motion the filtered record kept.

    Returns a dict:

    * ``corr``: Pearson correlation of the two low-band contents (None when
      either is constant);
    * ``amplitude_ratio``: std of the filtered low band / std of the raw low band
      (1 = all the motion's amplitude kept, 0 = a flat line; None without motion);
    * ``raw_lowband_std``, ``filtered_lowband_std``: those stds, input unit;
    * ``samples``: samples measured (0: no segment long enough; then all None).
    """
    pairs = _lowband_pairs(raw, filtered, sample_rate_hz, band_hz, restarts, skip_samples)
    res: dict[str, Any] = {"corr": None, "amplitude_ratio": None, "raw_lowband_std": None,
           "filtered_lowband_std": None, "samples": 0}
    if not pairs:
        return res
    lr = np.concatenate([p[0] for p in pairs])
    lf = np.concatenate([p[1] for p in pairs])
    sr = float(np.sqrt(np.mean(lr * lr)))
    sf = float(np.sqrt(np.mean(lf * lf)))
    res.update(raw_lowband_std=sr, filtered_lowband_std=sf, samples=int(len(lr)))
    if sr > 0:
        res["amplitude_ratio"] = sf / sr
    if sr > 0 and sf > 0:
        res["corr"] = float(np.clip(np.mean(lr * lf) / (sr * sf), -1.0, 1.0))
    return res


def lag_s(raw: npt.ArrayLike, filtered: npt.ArrayLike, sample_rate_hz: float, band_hz: float = LOWBAND_HZ,
          restarts: npt.ArrayLike | None = None, skip_samples: int = 0, max_lag_s: float = MAX_LAG_S) -> float | None:
    """Delay of the filtered record's low band behind the raw one's, s (positive:
    the filtered record comes later).

    The peak of the cross-correlation sum_i raw_low[i] filtered_low[i + k] over
    lags |k| <= ``max_lag_s`` (summed over the segments), refined by a parabola
    through the peak and its neighbours. Symmetric: identity gives 0 exactly. A
    pure delay of k samples gives k / ``sample_rate_hz`` to within 0.1 sample
    (the overlap shrinks with the lag: a small bias towards 0, 0.05 sample
    for a delay of 40 samples in 8000, tested); a filter of slowly varying group delay gives about its
    group delay in the band. None when the records have no low-band content, or
    when the peak is at the edge of the search (the lag is then at least
    ``max_lag_s``, or the filtered record is not a delayed copy of the raw one).
    """
    pairs = _lowband_pairs(raw, filtered, sample_rate_hz, band_hz, restarts, skip_samples)
    if not pairs:
        return None
    max_k = max(1, int(round(max_lag_s * sample_rate_hz)))
    max_k = min(max_k, max(len(p[0]) for p in pairs) // 2)
    if max_k < 1:
        return None
    cc = np.zeros(2 * max_k + 1)
    for lr, lf in pairs:
        n = len(lr)
        for j, k in enumerate(range(-max_k, max_k + 1)):
            if abs(k) < n:
                # np.sum, not np.dot: a threaded BLAS dot sums in an order that depends on the
                # number of threads, and the figure must not depend on what runs it
                cc[j] += float(np.sum(lr[:n - k] * lf[k:]) if k >= 0 else np.sum(lr[-k:] * lf[:n + k]))
    j = int(np.argmax(cc))
    if not cc[j] > 0 or j == 0 or j == len(cc) - 1:
        return None
    y0, y1, y2 = cc[j - 1], cc[j], cc[j + 1]
    den = y0 - 2.0 * y1 + y2
    frac = 0.5 * (y0 - y2) / den if den < 0 else 0.0
    return float((j - max_k + frac) / sample_rate_hz)


def white_noise_std(x: npt.ArrayLike, sample_rate_hz: float | None, restarts: npt.ArrayLike | None = None) -> float | None:
    """The white-noise standard deviation of a record (its unit), an estimate
    that slow motion does not lift, or None (no finite run longer than
    `noise_ready_samples`).

    It is the core's own estimate, not a second implementation: the record runs
    through ``method="motion"`` (`gyrodenoise.core.kernels.motion_step`),
    whose noise level R is the smallest over lags L = 1..6 of the running mean
    |4th difference| at lag L (Huber-clipped, 10 s memory) x sqrt(pi / 140), or
    the spectral noise floor (`gyrodenoise.core.kernels.spectral_floor`,
    a low quantile of the spectrum's upper quarter, which tones do not lift)
    where that is more than 1.5x lower.
    A 4th difference cancels any cubic over its 4 L samples, so motion below a
    few Hz adds (2 sin(pi f L / fs))^8 of its power: at 25 Hz, 1 Hz motion
    reaches it at 2e-5 of its power, where the first difference keeps 0.06.
    Returned: sqrt of the median of R over the samples where it has formed
    (each finite run of each session, after its first `noise_ready_samples`).
    On white noise it reads 2-6 % low (the smallest of six running means; 6 %
    at 25 Hz, 2 % at 250 Hz, tested); motion near the
    Nyquist frequency and vibration are not removed. 0.0 for a constant record."""
    from gyrodenoise.core import batch, kernels as K
    x = np.asarray(x, dtype=np.float64)
    fs = float(sample_rate_hz) if sample_rate_hz and sample_rate_hz > 0 else 1.0
    p = K.make_params(1, "motion", fs, warmup_s=0.0)
    p[K.P_MO_NF] = 1.0          # R comes before the bank and does not depend on it: one filter is enough
    at = K.ext_offset(p) + K.M_R
    ready = noise_ready_samples()
    s0 = K.init_state(p)                 # batch.run does not modify it: each run starts fresh
    vals = []
    for a, b in sessions(len(x), restarts, 0, np.isfinite(x), ready + 1):
        _, _, trace = batch.run(p, s0, x[a:b], None, trace_index=at)
        vals.append(trace[ready:])
    if not vals:
        return None
    r = float(np.median(np.concatenate(vals)))
    return 0.0 if r <= p[K.P_R_FLOOR] else math.sqrt(r)


def noise_ready_samples() -> int:
    """Samples of a run before `white_noise_std` reads the core's estimate:
    the 4th difference at the largest lag (4 x 6) and 32 samples of its mean."""
    from gyrodenoise.core import kernels as K
    return 4 * int(K.motion_params(1.0)[K.P_MO_NLAG - K.P_MO_NF]) + 32


def lowband_noise_std(white_noise_std: float, sample_rate_hz: float, band_hz: float = LOWBAND_HZ) -> float:
    """Std of white noise of std ``white_noise_std`` (sampled at ``sample_rate_hz``)
    after the 0..``band_hz`` low-pass: its power scales with the band's share of
    the Nyquist band, 2 band / fs (the order-4 Butterworth applied twice is close
    to a brick wall: noise bandwidth 1.006 x band)."""
    return float(white_noise_std) * math.sqrt(min(1.0, 2.0 * band_hz / sample_rate_hz))


def motion_above_noise(kept: Mapping[str, Any], white_noise_std: float | None, sample_rate_hz: float,
                       band_hz: float = LOWBAND_HZ) -> bool | None:
    """True when the raw low band of ``kept`` (a `lowband_kept` result) holds
    motion clearly above the noise: std at least `MOTION_TO_NOISE_MIN` x
    `lowband_noise_std` of the raw record's white-noise level
    ``white_noise_std``; False at rest (the low band is then noise, and what a
    filter removes from it is noise); None when it cannot be told."""
    sr = kept.get("raw_lowband_std")
    if not sr or white_noise_std is None or not math.isfinite(white_noise_std):
        return None
    return bool(sr >= MOTION_TO_NOISE_MIN * lowband_noise_std(white_noise_std, sample_rate_hz, band_hz))


def motion_loss(kept: Mapping[str, Any], white_noise_std: float | None, sample_rate_hz: float,
                band_hz: float = LOWBAND_HZ) -> str | None:
    """The warning rule: a short reason when the filter removed most of the real
    motion, else None.

    ``kept`` is a `lowband_kept` result, ``white_noise_std`` the raw
    record's white-noise level (e.g. std of first differences / sqrt 2). The
    raw low band must hold motion clearly above the noise (std at least
    `MOTION_TO_NOISE_MIN` x `lowband_noise_std`); then the filter
    is said to remove most of it when the amplitude kept is below
    `KEPT_AMPLITUDE_MIN` or the correlation below `KEPT_CORR_MIN`."""
    if not motion_above_noise(kept, white_noise_std, sample_rate_hz, band_hz):
        return None
    amp, corr = kept.get("amplitude_ratio"), kept.get("corr")
    why = []
    if amp is not None and amp < KEPT_AMPLITUDE_MIN:
        why.append(f"kept {100.0 * amp:.0f} % of the 0-{band_hz:g} Hz amplitude "
                   f"(< {100.0 * KEPT_AMPLITUDE_MIN:.0f} %)")
    if corr is None or corr < KEPT_CORR_MIN:
        why.append(f"0-{band_hz:g} Hz correlation {'undefined' if corr is None else f'{corr:.2f}'} "
                   f"(< {KEPT_CORR_MIN})")
    return "; ".join(why) or None


def envelope_violation(raw: npt.ArrayLike, filtered: npt.ArrayLike, restarts: npt.ArrayLike | None = None, rel_margin: float = 1e-9,
                       causal: bool = True) -> dict[str, Any] | None:
    """The first sample where ``filtered`` is not finite, or outside [lo - m, hi + m],
    lo/hi the least/greatest finite raw sample since the last restart (up to and
    including that sample; ``causal=False``: of the whole session, for a
    zero-phase filter, whose output depends on later samples too),
    m = ``rel_margin`` x (1 + max(|lo|, |hi|)).

    Samples whose raw value is not finite are not checked (a filter does not see
    them). Returns None, or a dict ``{"sample", "value", "low", "high", "reason"}``
    with reason ``"not finite"`` or ``"outside the raw range since the last restart"``.
    """
    raw = np.asarray(raw, dtype=np.float64)
    filtered = np.asarray(filtered, dtype=np.float64)
    n = len(raw)
    fin = np.isfinite(raw)
    lo = np.full(n, np.nan)
    hi = np.full(n, np.nan)
    starts = np.zeros(n, dtype=bool)
    if n:
        starts[0] = True
    if restarts is not None:
        starts |= np.asarray(restarts, dtype=bool)
    bounds = np.flatnonzero(starts).tolist() + [n]
    for a, b in zip(bounds[:-1], bounds[1:]):
        seg = raw[a:b]
        lo[a:b] = np.fmin.accumulate(np.where(fin[a:b], seg, np.inf))
        hi[a:b] = np.fmax.accumulate(np.where(fin[a:b], seg, -np.inf))
        if not causal and b > a:
            lo[a:b], hi[a:b] = lo[b - 1], hi[b - 1]
    with np.errstate(invalid="ignore", over="ignore"):
        m = rel_margin * (1.0 + np.maximum(np.abs(lo), np.abs(hi)))
        bad_nf = fin & ~np.isfinite(filtered)
        bad_out = fin & np.isfinite(filtered) & ((filtered < lo - m) | (filtered > hi + m))
    bad = np.flatnonzero(bad_nf | bad_out)
    if not len(bad):
        return None
    i = int(bad[0])
    return {"sample": i, "value": float(filtered[i]), "low": float(lo[i]), "high": float(hi[i]),
            "reason": "not finite" if bad_nf[i] else
            "outside the raw range since the last restart" if causal else "outside the raw range of its session"}
