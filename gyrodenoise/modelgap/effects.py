"""Naming physical effects from the evidence of a record and its fitted card."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from gyrodenoise.simulator import ModelCard

EARTH_RATE_DEG_H = 15.041067       # sidereal rotation of the Earth (deg/h)


def record_quantum(y: npt.ArrayLike) -> float | None:
    """The record's quantum (deg/s per sample) when every sample is a whole multiple
    of one step (a pulse or LSB output), else None."""
    y = np.asarray(y, float)
    u = np.unique(y)
    if len(u) < 3 or len(u) > max(len(y) // 10, 3):
        return None
    q = float(np.min(np.diff(u)))
    k = y / q
    if q > 0 and np.max(np.abs(k - np.round(k))) < 1e-6:
        return q
    return None


def name_effects(y: np.ndarray, fs: float, card: ModelCard, bumps: Sequence[Sequence[float]] = (),
                 latitude_deg: float | None = None) -> list[str]:
    """Plain sentences naming what the evidence says (see docs/bench/gap.md)."""
    out = []
    n = len(y)
    b = card.terms.get("constant_bias", {}).get("value")
    if b is not None and abs(b) > 0.05 * EARTH_RATE_DEG_H:
        if latitude_deg is not None:
            v = EARTH_RATE_DEG_H * math.sin(math.radians(latitude_deg))
            h = EARTH_RATE_DEG_H * math.cos(math.radians(latitude_deg))
            out.append(f"constant bias {b:.4g} deg/h: the Earth's rotation at latitude {latitude_deg:.4g} deg is "
                       f"{v:.4g} deg/h on a vertical axis (the bias minus it: {b - math.copysign(v, b):.3g} deg/h) "
                       f"and up to {h:.4g} deg/h on a horizontal one")
        elif abs(b) <= 1.02 * EARTH_RATE_DEG_H:
            lat = math.degrees(math.asin(min(abs(b) / EARTH_RATE_DEG_H, 1.0)))
            out.append(f"constant bias {b:.4g} deg/h is within the Earth's rotation ({EARTH_RATE_DEG_H:.4g} deg/h): "
                       f"consistent with it projected on the axis (a vertical axis at latitude {lat:.3g} deg); "
                       f"give --latitude to check")
    q = record_quantum(y)
    if q is not None:
        s_deg = q / fs
        line = (f"quantum: every sample is a whole multiple of {q:.4g} deg/s = {s_deg:.4g} deg "
                f"({s_deg * 3600:.3g} arcsec) per sample; as angle quantization Q = step/sqrt(12) = "
                f"{s_deg / math.sqrt(12):.3g} deg")
        qc = card.terms.get("quantization", {}).get("Q")
        if qc:
            line += f" (the fitted Q is {qc:.3g} deg: {qc / (s_deg / math.sqrt(12)):.3g} x that)"
        out.append(line)
    alike = "taken out of the comparison by one band-stop on record and simulations alike"
    for lo, hi, peak in bumps:
        if peak < 0:
            out.append(f"the record's PSD rolls off above {lo:.3g} Hz, below what any noise term gives: the "
                       f"sensor's internal low-pass filter; {lo:.3g}-{hi:.3g} Hz {alike}")
        elif not peak > 0:
            out.append(f"stop band {lo:.3g}-{hi:.3g} Hz (given): {alike}")
        elif hi < 1.15 * lo:     # (a wandering line with its skirt: RLG y 9.91-11.1 Hz)
            out.append(f"line wandering in frequency {lo:.4g}-{hi:.4g} Hz ({peak:.3g} x the PSD's running median; "
                       f"too wide for one sinusoid): a dither / aliased line or a machine whose speed drifts, "
                       f"not the sensor's noise; {alike}")
        elif lo <= fs / 64.0:
            out.append(f"base motion {lo:.3g}-{hi:.3g} Hz ({peak:.3g} x the PSD on both sides of its peak, and "
                       f"everything below it more than 2 x the sensor's level above it): the angular motion of "
                       f"the base, not the sensor's noise; {alike}. The sensor's slow terms (bias instability, "
                       f"rate random walk) are hidden under it: the card's long-tau terms are not measured here")
        else:
            what = "dither / aliased line" if lo > 0.4 * fs else "base vibration (a random narrow-band motion)"
            out.append(f"spectral bump {lo:.3g}-{hi:.3g} Hz ({peak:.3g} x the PSD on both sides): {what}, not "
                       f"the sensor's noise; {alike}")
    dur = n / fs
    slow = [g["tau"] for g in card.term_list("gauss_markov") if g["tau"] > dur / 10.0]
    if card.terms.get("rate_ramp") or card.terms.get("turn_on_transient") or slow:
        out.append("slow drift (" + ", ".join(
            [x for x in ("rate_ramp" if card.terms.get("rate_ramp") else "",
                         "turn_on_transient" if card.terms.get("turn_on_transient") else "",
                         f"Gauss-Markov tau {max(slow):.3g} s > record/10" if slow else "") if x])
                   + "): temperature-like; a record with temperature would tell")
    return out


OUTLIER_K = 10.0            # robust sigmas off the running median
OUTLIER_WINDOW = 31         # samples of the running median
OUTLIER_MAX_FRACTION = 0.01


def screen_outliers(y: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Isolated wild samples: more than OUTLIER_K robust sigmas (1.4826 x the median
    absolute deviation of the record about its running median of OUTLIER_WINDOW
    samples) off that running median. Returns (cleaned copy, indices): each outlier
    replaced by the running median there. None of the card's terms makes such
    samples, and a handful of them dominate the Allan deviation at short tau and
    the PSD at every frequency; more than OUTLIER_MAX_FRACTION of the record is not
    'isolated' and nothing is replaced.

    Opt-in (``gap(outliers=True)``, ``--outliers``): by amplitude alone the
    injected outliers of the XSens record (median 10.9 robust sigmas) cannot be
    told from the heavy tail of a vibrating base (the RLG's x and y axes: median
    12.8-13.3 robust sigmas, 0.4-0.6 % of the samples)."""
    from scipy.ndimage import median_filter
    y = np.asarray(y, float)
    med = median_filter(y, size=OUTLIER_WINDOW, mode="nearest")
    r = y - med
    sig = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    if not sig > 0:
        return y, np.array([], dtype=np.int64)
    idx = np.flatnonzero(np.abs(r) > OUTLIER_K * sig)
    if len(idx) == 0 or len(idx) > OUTLIER_MAX_FRACTION * len(y):
        return y, np.array([], dtype=np.int64)
    out = y.copy()
    out[idx] = med[idx]
    return out, idx
