"""A published Allan-deviation curve as the measurement (``gyrodenoise gap --allan CURVE.csv``).

The curve (tau, ADEV and, optionally, the lower and upper bounds of its confidence
interval) replaces the record: the card's noise terms (Q, N, B, K and a dictionary
of Gauss-Markov processes, `spectral.fit_terms`) are fitted to the Allan
variance with weights from the bounds, written into the card, and the card is then
checked by simulation: the mean simulated Allan deviation of ``S`` records of the
published length and rate must lie inside the published bounds at every tau.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from gyrodenoise.errors import InputError
from gyrodenoise.modelgap.settings import CARD_FIELD, SIGMA_TO_CARD
from gyrodenoise.units import NOISE_SECTIONS, RATE_TO_DEG_S

# accepted column names (first match wins)
TAU_COLS = ("tau_s", "tau")
ADEV_COLS = ("allan_deviation", "adev")
LO_COLS = ("adev_lci", "adev_lo", "lower")
HI_COLS = ("adev_uci", "adev_hi", "upper")
Z95 = 1.959964
FIT_ROBUST = 10             # Huber re-weightings of the fit (spectral.fit_terms)
MAX_LINES = 2               # sinusoids the fit may add, only if they bring it inside the bounds at every tau


@dataclass
class AllanCurve:
    """A published curve in deg/s (bounds: NaN where absent or not positive)."""
    tau_s: np.ndarray
    adev_deg_s: np.ndarray
    lo_deg_s: np.ndarray
    hi_deg_s: np.ndarray
    sample_rate_hz: float
    n_samples: int
    label: str
    unit: str
    notes: list[str] = field(default_factory=list)


def _pick(header: list[str], names: Iterable[str]) -> int | None:
    return next((header.index(n) for n in names if n in header), None)


def read_allan_curve(path: str | os.PathLike[str], sensor: str | None = None, channel: str | None = None,
                     unit: str = "deg/s", sample_rate_hz: float | None = None,
                     n_samples: int | None = None) -> AllanCurve:
    """Read CURVE.csv (see the module docstring): one line, exit 2 on anything wrong.

    Columns: ``tau_s`` (or ``tau``), ``allan_deviation`` (or ``adev``); optional
    ``adev_lci``/``adev_uci`` (95 % bounds), ``sensor``, ``channel`` (then
    ``sensor``/``channel`` choose the rows; required when the file holds more
    than one curve), ``freq_hz`` and ``n_samples`` (else ``sample_rate_hz`` and
    ``n_samples`` must be given). ``unit`` is the unit of the ADEV columns.
    """
    src = str(path)
    if unit not in RATE_TO_DEG_S:
        raise InputError(f"--allan-unit {unit!r} is not one of {', '.join(RATE_TO_DEG_S)}", src)
    header, body = _read_rows(path, src)
    col = _columns(header)
    body = _select_curve(body, col, sensor, channel, src)
    tau, ad, lo, hi, notes = _curve_values(body, header, col, src)
    fs, n = _rate_and_length(body, col, sample_rate_hz, n_samples, src)
    if not fs > 0:
        raise InputError(f"the sample rate must be positive, got {fs:g}", src)
    if n < 2 * tau[-1] * fs:
        raise InputError(f"n_samples {n} is too short for tau {tau[-1]:g} s at {fs:g} Hz", src)
    k = RATE_TO_DEG_S[unit]
    label = " ".join(x for x in (sensor, channel) if x) or Path(src).name
    return AllanCurve(tau * 1.0, ad * k, lo * k, hi * k, fs, n, label, unit, notes)


def _read_rows(path: str | os.PathLike[str], src: str) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """(header, [(line number, fields)] of the non-blank rows, each as wide as the header)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the Allan curve: {getattr(exc, 'strerror', None) or exc.__class__.__name__}",
                         src) from None
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise InputError("empty Allan curve file", src)
    header = [h.strip() for h in rows[0]]
    if _pick(header, TAU_COLS) is None or _pick(header, ADEV_COLS) is None:
        raise InputError(f"line 1: need columns tau_s and allan_deviation (or tau, adev); got "
                         f"{', '.join(header) or 'nothing'}", src)
    body = [(k + 2, r) for k, r in enumerate(rows[1:]) if r and any(c.strip() for c in r)]
    for lineno, r in body:
        if len(r) != len(header):
            raise InputError(f"line {lineno}: {len(r)} fields, the header has {len(header)}", src)
    return header, body


def _columns(header: list[str]) -> dict[str, int | None]:
    """Index of each column the reader knows (None when absent)."""
    return {"tau": _pick(header, TAU_COLS), "adev": _pick(header, ADEV_COLS), "lo": _pick(header, LO_COLS),
            "hi": _pick(header, HI_COLS), "sensor": _pick(header, ("sensor",)),
            "channel": _pick(header, ("channel",)), "freq_hz": _pick(header, ("freq_hz",)),
            "n_samples": _pick(header, ("n_samples",))}


def _select_curve(body: list[tuple[int, list[str]]], col: dict[str, int | None], sensor: str | None, channel: str | None,
                  src: str) -> list[tuple[int, list[str]]]:
    """The rows of the chosen sensor and channel (required when the file holds several);
    at least 3."""
    for what, want in (("sensor", sensor), ("channel", channel)):
        i = col[what]
        if i is None:
            if want is not None:
                raise InputError(f"--{what} given but the file has no '{what}' column", src)
            continue
        found = sorted({r[i].strip() for _, r in body})
        if want is None and len(found) > 1:
            raise InputError(f"the file holds several curves: choose one with --{what} "
                             f"({', '.join(found)})", src)
        if want is not None and want not in found:
            raise InputError(f"no {what} {want!r} (the file has: {', '.join(found)})", src)
        body = [(ln, r) for ln, r in body if want is None or r[i].strip() == want]
    if len(body) < 3:
        raise InputError(f"only {len(body)} curve points; need at least 3", src)
    return body


def _number(lineno: int, r: list[str], i: int, name: str, src: str) -> float:
    """Field ``i`` of row ``r`` as a finite float, or InputError naming the line."""
    try:
        v = float(r[i])
    except ValueError:
        raise InputError(f"line {lineno}: {name} {r[i].strip()!r} is not a number", src) from None
    if not math.isfinite(v):
        raise InputError(f"line {lineno}: {name} is not finite", src)
    return v


def _curve_values(body: list[tuple[int, list[str]]], header: list[str], col: dict[str, int | None],
                  src: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """(tau, adev, lower, upper, notes) in the file's unit, checked: tau positive and
    increasing, adev positive, the bounds enclosing it (NaN where a bound is absent or
    not positive, with a note)."""
    def column(key: str) -> np.ndarray:
        i = col[key]
        assert i is not None        # the caller checks that the column is there
        return np.array([_number(ln, r, i, header[i], src) for ln, r in body])
    tau, ad = column("tau"), column("adev")
    for (ln, _), t_, a_ in zip(body, tau, ad):
        if not t_ > 0:
            raise InputError(f"line {ln}: tau must be positive, got {t_:g}", src)
        if not a_ > 0:
            raise InputError(f"line {ln}: the Allan deviation must be positive, got {a_:g}", src)
    if np.any(np.diff(tau) <= 0):
        k = int(np.flatnonzero(np.diff(tau) <= 0)[0]) + 1
        raise InputError(f"line {body[k][0]}: tau must increase from row to row", src)
    nan = np.full(len(tau), np.nan)
    lo = column("lo") if col["lo"] is not None else nan
    hi = column("hi") if col["hi"] is not None else nan
    bad = np.flatnonzero((hi < ad) | (lo > ad))
    if len(bad):
        raise InputError(f"line {body[bad[0]][0]}: the bounds do not enclose the Allan deviation", src)
    notes: list[str] = []
    if np.any(lo <= 0):
        notes.append(f"{int(np.sum(lo <= 0))} lower bound(s) <= 0 (long tau): no lower bound there")
    return tau, ad, np.where(lo > 0, lo, np.nan), hi, notes


def _rate_and_length(body: list[tuple[int, list[str]]], col: dict[str, int | None], sample_rate_hz: float | None, n_samples: int | None,
                     src: str) -> tuple[float, int]:
    """(sample rate, record length) from the file's first row, else from the arguments."""
    ln, r = body[0]
    if col["freq_hz"] is not None:
        fs = _number(ln, r, col["freq_hz"], "freq_hz", src)
    elif sample_rate_hz is not None:
        fs = float(sample_rate_hz)
    else:
        raise InputError("no freq_hz column: give --sample-rate", src)
    if col["n_samples"] is not None:
        n = int(_number(ln, r, col["n_samples"], "n_samples", src))
    elif n_samples is not None:
        n = int(n_samples)
    else:
        raise InputError("no n_samples column: give --n-samples (the length of the published record)", src)
    return fs, n


class _CurveLayout:
    """What `spectral.fit_terms` needs of a layout when there is no PSD."""
    def __init__(self, m: npt.ArrayLike, fs: float, n: int) -> None:
        self.m, self.fs, self.n = np.asarray(m, np.int64), float(fs), int(n)


def fit_curve(curve: AllanCurve) -> tuple[dict[str, Any], np.ndarray]:
    """Fit Q, N, B, K and Gauss-Markov terms to the curve's Allan variance.

    Weights: the 1-sigma of the Allan variance from the bounds (half the
    95 % interval / 1.96; the upper bound alone where the lower is absent),
    else 5 % of the ADEV; Huber re-weighted (FIT_ROBUST passes), so that the
    shortest taus of a long record (bounds of +-0.1 %, shaped by the sensor's
    internal filter, which no term represents) do not pull every term off the rest
    of the curve. When the fit is not inside the bounds at every tau, up to
    MAX_LINES sinusoids are tried (`spectral.fit_terms`, ``max_lines``) and kept
    only if they bring it inside everywhere (the KVH 1750 curve: one line). When it is
    still outside somewhere, the fit is made again with a dictionary of angle
    Gauss-Markov terms added (white angle noise with a correlation time,
    `spectral.agm_grid`) and kept when it is inside at more taus (the LN-200
    curve, whose ADEV falls slightly faster than white noise from 0.16 to 2.6 s).
    Returns (terms, model ADEV at the curve's tau in deg/s)."""
    from gyrodenoise.modelgap.spectral import fit_terms
    m = np.maximum(np.round(curve.tau_s * curve.sample_rate_hz), 1)
    half = np.where(np.isfinite(curve.lo_deg_s), (curve.hi_deg_s - curve.lo_deg_s) / 2.0,
                    curve.hi_deg_s - curve.adev_deg_s)
    sd_ad = np.where(np.isfinite(half) & (half > 0), half / Z95, 0.05 * curve.adev_deg_s)
    avar = curve.adev_deg_s ** 2

    def fit(angle_gm: bool) -> tuple[dict[str, Any], np.ndarray, int]:
        t, mav, _ = fit_terms(_CurveLayout(m, curve.sample_rate_hz, curve.n_samples), (), avar,
                              2.0 * curve.adev_deg_s * sd_ad, None, None, robust=FIT_ROBUST, max_lines=MAX_LINES,
                              inside_fn=lambda av: bool(np.all(inside(curve, np.sqrt(np.maximum(av, 0.0))))),
                              angle_gm=angle_gm)
        ad = np.sqrt(np.maximum(mav, 0.0))
        return t, ad, int(np.sum(~inside(curve, ad)))
    terms, model, n_out = fit(False)
    if n_out:
        terms_a, model_a, n_out_a = fit(True)
        if n_out_a < n_out:
            terms, model = terms_a, model_a
    return terms, model


def card_from_terms(text: str, terms: Mapping[str, Any], note: str, source: str = "<card>") -> str:
    """The card text with its noise terms replaced by ``terms`` (from `fit_curve`)."""
    from gyrodenoise.simulator import parse_card
    from gyrodenoise.modelgap.cards import edit_card
    card = parse_card(text, source)
    for nm in NOISE_SECTIONS:
        fld, to_card = CARD_FIELD[nm]
        if terms[nm] > 0:
            text = edit_card(text, nm, {fld: math.sqrt(terms[nm]) * to_card}, nm in card.terms, note, source)
        elif nm in card.terms:
            text = edit_card(text, nm, None, True, note, source)
    for kind, to_card in SIGMA_TO_CARD.items():
        if card.term_list(kind):
            text = edit_card(text, kind, None, True, note, source)
        for s, t in terms.get(kind, ()):
            text = edit_card(text, kind, {"sigma": s * to_card, "tau": float(t)}, False, note, source)
    for a, f in terms.get("sinusoid", ()):
        text = edit_card(text, "sinusoid", {"amplitude": a * 3600.0, "frequency": float(f)}, False, note, source)
    return text


def simulated_curve(text: str, curve: AllanCurve, seeds: Iterable[int],
                    source: str = "<card>") -> tuple[np.ndarray, np.ndarray]:
    """Mean (over ``seeds``) and each seed's ADEV (deg/s) at the curve's tau of the
    card simulated at the curve's rate and length."""
    from gyrodenoise.analysis.allan import adev
    from gyrodenoise.simulator import simulate
    from gyrodenoise.modelgap.cards import card_at_rate
    card = card_at_rate(text, curve.sample_rate_hz, source)
    m = np.maximum(np.round(curve.tau_s * curve.sample_rate_hz), 1).astype(np.int64)
    each = np.array([adev(simulate(card, curve.n_samples, seed=int(s)).rate_deg_s, curve.sample_rate_hz, m=m)[1]
                     for s in seeds])
    return each.mean(axis=0), each


def inside(curve: AllanCurve, ad: np.ndarray) -> np.ndarray:
    """Per tau: is ``ad`` inside the published bounds (an absent bound does not bind)?"""
    lo_ok = ~np.isfinite(curve.lo_deg_s) | (ad >= curve.lo_deg_s)
    hi_ok = ~np.isfinite(curve.hi_deg_s) | (ad <= curve.hi_deg_s)
    return lo_ok & hi_ok
