"""Overlapping Allan deviation and the five-term fit of Eq. (40).

Why not call allantools for the curve: it holds several record-sized arrays per
tau; here the sums read the cumulative sum in blocks of `BLOCK` samples (numpy
only), and `adev_of_chunks` takes a record of any length in chunks in bounded
memory (a benchmark of the repository measures both against pandas +
allantools). The tests check this module against allantools (1e-9) and against a
published ADIS16405 curve (1e-3), so allantools remains our reference
implementation.

Units: rates in deg/s in, tau in s; terms out in the spec's units
(N deg/sqrt(h), B deg/h, K deg/h^1.5, R deg/h^2, Q deg).

Which value to trust: the fit uses every point, and where the curve is not of Eq. (40)'s
shape (a sensor's internal filter bends it at short taus) it can miss its own points by 2x
and B with it. `AllanResult.agreement` holds, per term, the fit against the points where
that term dominates, against their 95 % band, and the IEEE 952 / MathWorks slope-point
read beside it (`SLOPE_READS`); `AllanResult.exported_terms` is what the exports write: the
fit where it agrees, the slope-point read where it misses.

References
----------
IEEE Std 952-1997, Annex C (Allan variance, error of the estimate).
Sun et al. (2016), Eq. (40).
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable, Collection, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from gyrodenoise.units import TERM_BY_SYMBOL, TERM_SYMBOLS

BI_FACTOR = 2.0 * math.log(2.0) / math.pi     # Eq. (40): sigma^2 = (2 ln2 / pi) B^2

#: samples of the phase read at a time by the Allan sums: what bounds their memory
#: (a few blocks of float64 whatever the record's length)
BLOCK = 1 << 18

#: reads the phase (cumulative sum x tau0) from index a to b (exclusive)
PhaseReader = Callable[[int, int], np.ndarray]


def _avar_sums(read: PhaseReader, n_phase: int, ms: np.ndarray) -> np.ndarray:
    """sum_k (x[k+2m] - 2 x[k+m] + x[k])^2 for each m of ``ms`` over the phase x of
    ``n_phase`` values, read `BLOCK` values of k at a time.

    The cluster sizes with 2m <= `BLOCK` are served by one read per block (the block
    and the 2m values after it); each larger m reads its two shifted slices. Memory:
    a few blocks, whatever ``n_phase``."""
    block = BLOCK
    out = np.zeros(ms.shape[0])
    with np.errstate(over="ignore", invalid="ignore"):     # an overflow gives inf: said by to_json
        _add_sums(read, n_phase, ms, block, out)
    return out


def _add_sums(read: PhaseReader, n_phase: int, ms: np.ndarray, block: int, out: np.ndarray) -> None:
    """The loop of `_avar_sums`, adding into ``out``."""
    if ms.size == 0:
        return
    small = 2 * ms <= block
    reach = int(2 * ms[small].max()) if small.any() else 0
    k_end = n_phase - 2 * int(ms.min())           # the most terms any m has
    for a in range(0, k_end, block):
        b = min(a + block, k_end)
        seg = read(a, min(b + reach, n_phase))
        for i, m in enumerate(ms):
            m = int(m)
            length = min(b, n_phase - 2 * m) - a
            if length <= 0:
                continue
            if small[i]:
                v = seg[2 * m:2 * m + length] - 2.0 * seg[m:m + length] + seg[:length]
            else:
                v = read(a + 2 * m, a + 2 * m + length) - 2.0 * read(a + m, a + m + length) + seg[:length]
            v *= v
            out[i] += float(v.sum())      # pairwise: within 1e-15 of an exact sum


def default_m(n_samples: int, per_decade: int = 10) -> np.ndarray:
    """Cluster sizes m, log-spaced ``per_decade`` per decade, 1 <= m <= (N-1)/2."""
    m_max = (n_samples - 1) // 2
    if m_max < 1:
        return np.array([], dtype=np.int64)
    n_pts = max(1, int(math.ceil(math.log10(m_max) * per_decade)) + 1)
    ms = np.unique(np.round(np.logspace(0, math.log10(m_max), n_pts)).astype(np.int64))
    return ms[(ms >= 1) & (ms <= m_max)]


def octave_m(n_samples: int) -> np.ndarray:
    """Cluster sizes 1, 2, 4, ... <= (N-1)/2: the octave-spaced taus of a long record."""
    m_max = (n_samples - 1) // 2
    if m_max < 1:
        return np.array([], dtype=np.int64)
    return 2 ** np.arange(int(math.log2(m_max)) + 1, dtype=np.int64)


def _cluster_sizes(n: int, tau0: float, m: npt.ArrayLike | None, tau_s: npt.ArrayLike | None,
                   default: Callable[[int], np.ndarray]) -> np.ndarray:
    """The cluster sizes asked for (``tau_s`` rounded to whole samples, else ``m``, else
    ``default(n)``), each once, within 1 <= m <= (n-1)/2."""
    if tau_s is not None:
        ms = np.round(np.asarray(tau_s, dtype=float) / tau0).astype(np.int64)
    elif m is not None:
        ms = np.asarray(m, dtype=np.int64)
    else:
        ms = default(n)
    return np.unique(ms[(ms >= 1) & (ms <= (n - 1) // 2)])


def _adev_of_sums(ms: np.ndarray, sums: np.ndarray, n: int,
                  tau0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """tau, adev, its 1-sigma error (IEEE 952 C.1) and the cluster count from the sums."""
    tau = ms * tau0
    n_terms = (n + 1 - 2 * ms).astype(float)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):   # inf / nan: said by to_json
        ad = np.sqrt(sums / (2.0 * tau * tau * n_terms))
    clusters = n / ms
    err = ad / np.sqrt(np.maximum(2.0 * (clusters - 1.0), 1.0))
    return tau, ad, err, clusters


def adev(rate_deg_s: npt.ArrayLike, sample_rate_hz: float, m: npt.ArrayLike | None = None,
         tau_s: npt.ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of a rate record.

    Parameters
    ----------
    rate_deg_s : array_like
    sample_rate_hz : float
    m : array_like of int, optional
        Cluster sizes; default `default_m`.
    tau_s : array_like, optional
        Averaging times instead of ``m`` (rounded to whole samples).

    Returns
    -------
    tau_s, adev_deg_s, adev_err_deg_s, n_clusters : ndarray
        ``adev_err_deg_s`` is the 1-sigma error of IEEE 952 C.1:
        adev / sqrt(2 (N/m - 1)).
    """
    y = np.asarray(rate_deg_s, dtype=np.float64)
    n = y.shape[0]
    tau0 = 1.0 / float(sample_rate_hz)
    ms = _cluster_sizes(n, tau0, m, tau_s, default_m)
    phase = np.concatenate(([0.0], np.cumsum(y))) * tau0
    sums = _avar_sums(lambda a, b: phase[a:b], phase.shape[0], ms)
    return _adev_of_sums(ms, sums, n, tau0)


def adev_of_chunks(chunks: Iterable[npt.ArrayLike], sample_rate_hz: float, m: npt.ArrayLike | None = None,
                   tau_s: npt.ArrayLike | None = None, spill_dir: str | None = None,
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`adev` of a record given in chunks (any length), in memory bounded by the chunk
    size and `BLOCK`, whatever the length.

    The running cumulative sum (the phase) is carried from chunk to chunk (the same
    sequential sums as ``np.cumsum`` over the whole record, bit for bit) and written to
    an anonymous temporary file (8 bytes a sample, in ``spill_dir``, default the
    system's), which the sums then read in blocks: the overlapping estimator at
    cluster size m needs the phase 2m samples back, which no bounded memory can hold
    for m up to half the record. Default taus: octave-spaced (`octave_m`).

    Raises
    ------
    ValueError
        A chunk that is not 1-D or holds NaN or inf (the sample index said).
    """
    tau0 = 1.0 / float(sample_rate_hz)
    ms, sums, n = _sums_of_chunks(chunks, tau0, m, tau_s, spill_dir)
    return _adev_of_sums(ms, sums, n, tau0)


def _sums_of_chunks(chunks: Iterable[npt.ArrayLike], tau0: float, m: npt.ArrayLike | None,
                    tau_s: npt.ArrayLike | None, spill_dir: str | None) -> tuple[np.ndarray, np.ndarray, int]:
    """The cluster sizes, their Allan sums and the sample count of a chunked record
    (`adev_of_chunks`)."""
    with tempfile.TemporaryFile(dir=spill_dir) as f:
        carry, n = 0.0, 0
        np.zeros(1).tofile(f)
        for chunk in chunks:
            y = np.asarray(chunk, dtype=np.float64)
            if y.ndim != 1:
                raise ValueError(f"a chunk of shape {y.shape}: need 1-D chunks")
            bad = np.flatnonzero(~np.isfinite(y))
            if bad.size:
                raise ValueError(f"the record holds NaN or inf (sample {n + int(bad[0])})")
            if y.size:
                s = np.cumsum(np.concatenate(([carry], y)))
                (s[1:] * tau0).tofile(f)
                carry, n = float(s[-1]), n + y.shape[0]
        f.flush()
        ms = _cluster_sizes(n, tau0, m, tau_s, octave_m)

        def read(a: int, b: int) -> np.ndarray:
            f.seek(8 * a)
            return np.fromfile(f, dtype=np.float64, count=b - a)

        return ms, _avar_sums(read, n + 1, ms), n


#: each term's Allan variance at averaging times t (s) for a unit s-based coefficient, Eq. (40):
#: sigma^2 = R^2 t^2/2 + K^2 t/3 + (2ln2/pi) B^2 + N^2/t + 3Q^2/t^2
AVAR_SHAPE: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "R": lambda t: t * t / 2.0, "K": lambda t: t / 3.0, "B": lambda t: np.full_like(t, BI_FACTOR),
    "N": lambda t: 1.0 / t, "Q": lambda t: 3.0 / (t * t)}
_ORDER = ("R", "K", "B", "N", "Q")   # column order of basis()


def basis(tau_s: npt.ArrayLike) -> np.ndarray:
    """Design matrix of Eq. (40) in the coefficients [R^2, K^2, B^2, N^2, Q^2]
    (s-based units): the columns of `AVAR_SHAPE`."""
    t = np.asarray(tau_s, dtype=float)
    return np.column_stack([AVAR_SHAPE[k](t) for k in _ORDER])
DCHI2_RESOLVED = 25.0
IRLS_ITERATIONS = 5


def fit_terms(tau_s: npt.ArrayLike, adev_deg_s: npt.ArrayLike,
              adev_err_deg_s: npt.ArrayLike) -> tuple[dict[str, float], dict[str, str], dict[str, float]]:
    """Weighted non-negative least-squares fit of Eq. (40) to an Allan curve.

    Each point's residual in Allan *variance* is weighted by the inverse of its
    1-sigma error, 2 x (relative adev error, from the cluster count) x the
    *fitted* variance: iteratively reweighted from the measured variance, so
    that a point which happens to come out low cannot claim a large weight. A term is "fit" when removing
    it from the fit raises chi^2 by more than ``DCHI2_RESOLVED``; otherwise
    the record cannot resolve it and its value is an upper bound: the largest
    coefficient whose contribution stays below the measured variance plus
    2 sigma at every tau.

    Returns
    -------
    terms_s : dict
        Term -> value in s-based units (N deg/sqrt(s), B deg/s, K deg/s^1.5,
        R deg/s^2, Q deg).
    kinds : dict
        Term -> "fit" or "upper_bound".
    fitted_s : dict
        The model refitted with the resolved terms only (0 for the others):
        what `model_adev` should draw.
    """
    t = np.asarray(tau_s, dtype=float)
    a = np.asarray(adev_deg_s, dtype=float)
    e = np.asarray(adev_err_deg_s, dtype=float)
    ok = np.isfinite(a) & (a > 0) & np.isfinite(e)
    t, a, e = t[ok], a[ok], e[ok]
    if t.size == 0:
        return ({k: 0.0 for k in TERM_SYMBOLS}, {k: "upper_bound" for k in TERM_SYMBOLS},
                {k: 0.0 for k in TERM_SYMBOLS})
    avar = a * a
    rel = e / a                                # relative 1-sigma of adev (cluster count only)
    A = basis(t)
    sig = _irls_sigma(A, avar, rel)
    fit = _WeightedFit(A, avar, sig)
    resolved = _resolved_columns(fit)
    terms: dict[str, float] = {}
    kinds: dict[str, str] = {}
    for j, name in enumerate(_ORDER):
        if j in resolved:
            terms[name] = math.sqrt(fit.coef[j])
            kinds[name] = "fit"
        else:
            bound = np.min((avar + 2.0 * sig) / A[:, j])
            terms[name] = math.sqrt(bound)
            kinds[name] = "upper_bound"
    return terms, kinds, _refit_resolved(fit, kinds)


class _WeightedFit:
    """Non-negative least squares of ``avar`` on the columns of ``A`` with 1-sigma
    errors ``sig``: the weighted system (``Aw``, ``yw``), its column scaling (for
    conditioning), the coefficients and chi^2."""

    def __init__(self, A: np.ndarray, avar: np.ndarray, sig: np.ndarray) -> None:
        from scipy.optimize import nnls
        self.Aw = A / sig[:, None]
        self.yw = avar / sig
        self.scale = np.max(np.abs(self.Aw), axis=0)
        coef, rnorm = nnls(self.Aw / self.scale, self.yw)
        self.coef = coef / self.scale
        self.chi2 = rnorm * rnorm

    def coef_of(self, cols: list[int]) -> tuple[np.ndarray, float]:
        """Coefficients of the fit on the columns ``cols`` only, and its chi^2."""
        from scipy.optimize import nnls
        c, rn = nnls(self.Aw[:, cols] / self.scale[cols], self.yw)
        return c / self.scale[cols], rn * rn

    def chi2_without(self, drop: Collection[int]) -> float:
        """chi^2 of the fit with the columns ``drop`` left out."""
        keep = [i for i in range(self.Aw.shape[1]) if i not in drop]
        return self.coef_of(keep)[1]


def _irls_sigma(A: np.ndarray, avar: np.ndarray, rel: np.ndarray) -> np.ndarray:
    """1-sigma of each Allan variance point, 2 x ``rel`` x the variance, for the fit.

    Weighting by the *measured* variance (2 a^2 rel) lets a point that happens to
    come out low (last taus, few clusters) take a huge weight and drag the fit; so
    iterate with the variance of the fitted model (iteratively reweighted least
    squares), from the measured start, at most IRLS_ITERATIONS times."""
    sig = np.maximum(2.0 * avar * rel, 1e-300)
    for _ in range(IRLS_ITERATIONS):
        coef = _WeightedFit(A, avar, sig).coef
        model = A @ coef
        sig_next = np.maximum(2.0 * np.maximum(model, 1e-300) * rel, 1e-300)
        if np.allclose(sig_next, sig, rtol=1e-6, atol=0.0):
            break
        sig = sig_next
    return sig


def _resolved_columns(fit: _WeightedFit) -> set[int]:
    """Columns of the basis the record resolves: those whose removal raises chi^2 by
    more than DCHI2_RESOLVED (neighbouring taus are correlated, hence the generous
    threshold). Terms that can stand in for each other (K and R, N and Q) may each
    look dispensable while the pair is not: the stronger one of such a group is kept."""
    n_cols = fit.Aw.shape[1]
    gain = {j: (fit.chi2_without({j}) - fit.chi2 if fit.coef[j] > 0 else 0.0) for j in range(n_cols)}
    resolved = {j for j in gain if gain[j] > DCHI2_RESOLVED}
    while True:
        rest = {j for j in gain if fit.coef[j] > 0 and j not in resolved}
        if not rest or fit.chi2_without(rest) - fit.chi2 <= DCHI2_RESOLVED:
            break
        resolved.add(max(rest, key=lambda j: gain[j]))
    return resolved


def _refit_resolved(fit: _WeightedFit, kinds: Mapping[str, str]) -> dict[str, float]:
    """The model curve: the terms refitted with the resolved ones only (0 for the others)."""
    cols = [j for j, name in enumerate(_ORDER) if kinds[name] == "fit"]
    fitted = {name: 0.0 for name in _ORDER}
    if cols:
        coef, _ = fit.coef_of(cols)
        for j, cj in zip(cols, coef):
            fitted[_ORDER[j]] = math.sqrt(cj)
    return fitted


def model_adev(tau_s: npt.ArrayLike, terms_s: Mapping[str, float]) -> np.ndarray:
    """Allan deviation (deg/s) of Eq. (40) for terms in s-based units."""
    c = np.array([terms_s[k] ** 2 for k in _ORDER])
    return np.sqrt(basis(tau_s) @ c)


#: a point of the curve is read (the fit's agreement, the slope-point reads) when its
#: 1-sigma error is under this fraction of the Allan deviation: the last taus of any
#: record scatter by tens of per cent
WELL_MEASURED = 0.1
#: the confidence band of a point: +-Z_95 x its 1-sigma error (IEEE 952 C.1), about 95 %
Z_95 = 1.96
#: a slope-point read is taken only where the curve's local log-log slope is within this of
#: the term's slope; further off, the curve has no stretch of that slope to read
SLOPE_TOLERANCE = 0.2


@dataclass(frozen=True)
class SlopeRead:
    """The IEEE 952 / MathWorks slope-point read of one term from the measured curve: the
    line of the term's log-log ``slope`` through the point whose local slope is nearest
    it (for the flat term, the curve's minimum), read at ``tau_read_s``, divided by
    ``divisor``."""
    symbol: str
    slope: float
    tau_read_s: float
    divisor: float
    recipe: str      #: how it is read, in words

    def read(self, tau: np.ndarray, adev: np.ndarray) -> tuple[float, float, float] | None:
        """(value in s-based units, tau of the point read, the curve's local slope there),
        or None when fewer than 3 points or no stretch within `SLOPE_TOLERANCE` of the slope."""
        if tau.size < 3:
            return None
        lt, la = np.log10(tau), np.log10(adev)
        local = np.gradient(la, lt)
        i = int(np.argmin(adev)) if self.slope == 0.0 else int(np.argmin(np.abs(local - self.slope)))
        if abs(local[i] - self.slope) > SLOPE_TOLERANCE:
            return None
        level = la[i] + self.slope * (math.log10(self.tau_read_s) - lt[i])
        return 10.0 ** level / self.divisor, float(tau[i]), float(local[i])


#: the three terms the IEEE 952 / MathWorks recipe reads off the curve by their slopes
SLOPE_READS: dict[str, SlopeRead] = {r.symbol: r for r in (
    SlopeRead("N", -0.5, 1.0, 1.0, "the -1/2 line read at tau = 1 s"),
    SlopeRead("B", 0.0, 1.0, math.sqrt(BI_FACTOR), "the curve's minimum / 0.664"),
    SlopeRead("K", 0.5, 3.0, 1.0, "the +1/2 line read at tau = 3 s"))}


@dataclass(frozen=True)
class TermAgreement:
    """How the Eq. (40) fit of one term agrees with the measured points where that term
    dominates the fit, and which value the exports use.

    ``fit_over_measured`` and ``band`` are at ``tau_s``, the worst point of the term's
    stretch; ``band`` is the point's relative 95 % half-width. ``slope_point`` is the
    slope-point read (spec unit; None where the recipe has none or the curve no stretch
    of that slope); ``exported`` is "fit" or "slope_point", ``why`` says why in words."""
    symbol: str
    tau_s: float | None
    fit_over_measured: float | None
    band: float | None
    misses: bool
    slope_point: float | None
    slope_point_tau_s: float | None
    exported: str
    why: str

    def to_json(self) -> dict[str, Any]:
        return {"tau_s": self.tau_s, "fit_over_measured": self.fit_over_measured, "band_95": self.band,
                "misses": self.misses, "slope_point": self.slope_point,
                "slope_point_tau_s": self.slope_point_tau_s, "exported": self.exported, "why": self.why}


def term_agreement(tau: np.ndarray, adev: np.ndarray, err: np.ndarray, fitted_s: Mapping[str, float],
                   bounds: Mapping[str, str]) -> dict[str, TermAgreement]:
    """Each term's `TermAgreement` on a measured curve (s-based units in, spec units out)."""
    ok = (adev > 0) & (err < WELL_MEASURED * adev)
    t, a, e = tau[ok], adev[ok], err[ok]
    parts = basis(t) * np.array([fitted_s[k] ** 2 for k in _ORDER])    # each term's share of the model
    model = np.sqrt(parts.sum(axis=1)) if t.size else np.zeros(0)
    lead = np.argmax(parts, axis=1) if t.size else np.zeros(0, dtype=int)
    out = {}
    for j, sym in enumerate(_ORDER):
        to_spec = TERM_BY_SYMBOL[sym].to_spec
        recipe = SLOPE_READS.get(sym)
        read = recipe.read(t, a) if recipe else None
        slope_value = float(read[0] * to_spec) if read else None
        slope_tau = read[1] if read else None
        where = (lead == j) & (parts[:, j] > 0) if t.size else np.zeros(0, dtype=bool)
        if bounds[sym] != "fit" or not where.any():
            why = ("not resolved by the record: the fit's upper bound is exported" if bounds[sym] != "fit"
                   else "dominates the fit at no well-measured tau: the fit is exported")
            out[sym] = TermAgreement(sym, None, None, None, False, slope_value, slope_tau, "fit", why)
            continue
        ratio = model[where] / a[where]
        band = Z_95 * e[where] / a[where]
        i = int(np.argmax(np.abs(np.log(ratio)) - np.log1p(band)))     # the worst against its band
        misses = bool(abs(ratio[i] - 1.0) > band[i])
        at = f"fit/measured {ratio[i]:.3g} at tau {t[where][i]:.3g} s, 95 % band +-{100 * band[i]:.2g} %"
        if not misses:
            exported, why = "fit", f"the fit agrees with its points where {sym} dominates ({at})"
        elif slope_value is None or recipe is None:
            exported = "fit"
            why = (f"the fit misses its points where {sym} dominates ({at}); "
                   + ("the recipe reads no slope point for it" if recipe is None else
                      f"the curve has no stretch of slope {recipe.slope:+g} to read it from")
                   + ": the fit is exported")
        else:
            exported = "slope_point"
            why = (f"the fit misses its points where {sym} dominates ({at}): the slope-point read "
                   f"({recipe.recipe}, as IEEE 952 and the MathWorks example) is exported")
        out[sym] = TermAgreement(sym, float(t[where][i]), float(ratio[i]), float(band[i]), misses,
                                 slope_value, slope_tau, exported, why)
    return {k: out[k] for k in TERM_SYMBOLS}


@dataclass
class AllanResult:
    """Allan deviation of a record and its five-term fit (spec section 3).

    Attributes
    ----------
    tau_s, adev_deg_s, adev_err_deg_s : ndarray
        Averaging times (s), the overlapping Allan deviation (deg/s) and its 1-sigma error.
    terms : dict
        Symbol (N, B, K, R, Q) -> value in the spec's unit (``gyrodenoise.units.ALLAN_TERMS``).
    terms_s : dict
        The same in s-based units (deg/s, s).
    bounds : dict
        Symbol -> "fit", or "upper_bound" where the record cannot resolve the term.
    fitted_s : dict
        The model refitted with the resolved terms only (0 for the others): what
        `model_adev` draws.
    agreement : dict
        Symbol -> `TermAgreement`: the fit against its own points where the term
        dominates, the slope-point read beside it, and which of the two is exported.
    exported_terms, exported_bounds : dict
        What the exports (Kalibr, MATLAB) write: the fit, or the slope-point read where
        the fit misses its points (``exported_bounds`` then says "slope_point").
    """
    tau_s: np.ndarray
    adev_deg_s: np.ndarray
    adev_err_deg_s: np.ndarray
    terms_s: dict[str, float]      #: symbol -> value in s-based units (deg/s, s)
    bounds: dict[str, str]         #: symbol -> "fit" or "upper_bound"
    fitted_s: dict[str, float]     #: the model refitted with the resolved terms only
    sample_rate_hz: float
    n_samples: int
    terms: dict[str, float] = field(init=False)   #: symbol -> value in the spec's unit
    agreement: dict[str, TermAgreement] = field(init=False)

    def __post_init__(self) -> None:
        self.terms = {k: self.terms_s[k] * TERM_BY_SYMBOL[k].to_spec for k in TERM_SYMBOLS}
        self.agreement = term_agreement(self.tau_s, self.adev_deg_s, self.adev_err_deg_s, self.fitted_s,
                                        self.bounds)

    @property
    def exported_terms(self) -> dict[str, float]:
        """Symbol -> the value the exports write (spec unit): the fit, or the slope-point read."""
        return {k: (a.slope_point if a.exported == "slope_point" and a.slope_point is not None
                    else self.terms[k]) for k, a in self.agreement.items()}

    @property
    def exported_bounds(self) -> dict[str, str]:
        """Symbol -> "fit", "upper_bound" or "slope_point": what `exported_terms` holds."""
        return {k: ("slope_point" if a.exported == "slope_point" else self.bounds[k])
                for k, a in self.agreement.items()}

    @property
    def adev_deg_h(self) -> np.ndarray:
        """The Allan deviation in deg/h."""
        return self.adev_deg_s * 3600.0

    @property
    def adev_err_deg_h(self) -> np.ndarray:
        """Its 1-sigma error in deg/h."""
        return self.adev_err_deg_s * 3600.0

    def model_adev_deg_h(self, tau_s: npt.ArrayLike | None = None) -> np.ndarray:
        """The fitted model's Allan deviation (deg/h) at ``tau_s`` (default: the measured taus)."""
        t = self.tau_s if tau_s is None else np.asarray(tau_s, dtype=float)
        return model_adev(t, self.fitted_s) * 3600.0

    def fit_misfit(self) -> float | None:
        """Largest factor between the Eq. (40) fit and the measured Allan deviation
        over the well-measured taus (1.0 = the fit passes through every point). A filter's output
        is not a sum of Eq. (40) noises: a large factor says its terms are a fit to a
        curve of another shape, not the properties of a sensor."""
        adev = self.adev_deg_s
        model = model_adev(self.tau_s, self.fitted_s)
        # only the taus the record measures well (1-sigma error under 10 %): the last
        # few taus of any record scatter by tens of per cent
        ok = (adev > 0) & (model > 0) & (self.adev_err_deg_s < WELL_MEASURED * adev)
        if not ok.any():
            return None
        return float(np.exp(np.max(np.abs(np.log(model[ok] / adev[ok])))))

    def to_json(self) -> dict[str, Any]:
        """Plain JSON: the terms with their units and bounds, each term's agreement and what
        the exports use, the curve in deg/h. Strict JSON: a value that is not a finite
        number is null, and ``nulls`` says which and why."""
        d = {"terms": {k: float(self.terms[k]) for k in TERM_SYMBOLS},
             "units": {k: TERM_BY_SYMBOL[k].unit for k in TERM_SYMBOLS},
             "bounds": dict(self.bounds),
             "fit_agreement": {k: a.to_json() for k, a in self.agreement.items()},
             "exported_terms": {k: float(v) for k, v in self.exported_terms.items()},
             "exported_bounds": self.exported_bounds,
             "tau_s": [float(v) for v in self.tau_s],
             "adev_deg_h": [float(v) for v in self.adev_deg_h],
             "adev_err_deg_h": [float(v) for v in self.adev_err_deg_h],
             "sample_rate_hz": float(self.sample_rate_hz),
             "n_samples": int(self.n_samples)}
        nulls: dict[str, str] = {}
        d = _finite_or_null(d, "", nulls)
        d["nulls"] = nulls
        return d


def _finite_or_null(v: Any, path: str, nulls: dict[str, str]) -> Any:
    """``v`` with every float that is not finite replaced by None, its path and value noted
    in ``nulls`` (strict JSON has no Infinity or NaN)."""
    if isinstance(v, dict):
        return {k: _finite_or_null(x, f"{path}.{k}" if path else str(k), nulls) for k, x in v.items()}
    if isinstance(v, list):
        return [_finite_or_null(x, f"{path}[{i}]", nulls) for i, x in enumerate(v)]
    if isinstance(v, float) and not math.isfinite(v):
        nulls[path] = (f"computed as {v!r}, not a finite number (float64 overflow or 0/0: a sample rate "
                       f"or values far outside a gyro's)")
        return None
    return v


def allan(rate_deg_s: npt.ArrayLike, sample_rate_hz: float, m: npt.ArrayLike | None = None,
          tau_s: npt.ArrayLike | None = None, per_decade: int = 10) -> AllanResult:
    """Allan deviation (overlapping) and five-term fit of a rate record.

    Parameters
    ----------
    rate_deg_s : array_like
        Rate, deg/s.
    sample_rate_hz : float
    m, tau_s : array_like, optional
        Cluster sizes or averaging times; default ``per_decade`` log-spaced
        points per decade up to half the record.

    Returns
    -------
    AllanResult
        ``.terms`` in the spec's units, ``.bounds`` says "fit" or
        "upper_bound" per term.
    """
    y = np.asarray(rate_deg_s, dtype=np.float64)
    if y.ndim != 1 or y.shape[0] < 5:
        raise ValueError(f"need a 1-D record of at least 5 samples, got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError("the record holds NaN or inf")
    if m is None and tau_s is None:
        m = default_m(y.shape[0], per_decade)
    tau, ad, err, _ = adev(y, sample_rate_hz, m=m, tau_s=tau_s)
    return allan_of_curve(tau, ad, err, sample_rate_hz, y.shape[0])


def allan_of_record(rate: npt.ArrayLike, sample_rate_hz: float, source: str | None = None) -> AllanResult:
    """`allan` of a record read from a file, a refusal as one line (InputError naming
    ``source``): fewer than 5 samples, or no tau with a finite Allan deviation."""
    from gyrodenoise.errors import InputError
    y = np.asarray(rate, dtype=np.float64)
    if len(y) < 5:
        raise InputError(f"only {len(y)} samples; the Allan deviation needs at least 5", source)
    res = allan(y, sample_rate_hz)
    if not np.isfinite(res.adev_deg_s).any():
        raise InputError(f"the Allan deviation is not a finite number at any tau at {sample_rate_hz:g} Hz: "
                         f"the sample rate or the rates are beyond what float64 holds", source)
    return res


def allan_of_chunks(chunks: Iterable[npt.ArrayLike], sample_rate_hz: float, m: npt.ArrayLike | None = None,
                    tau_s: npt.ArrayLike | None = None, spill_dir: str | None = None) -> AllanResult:
    """`allan` of a record given in chunks, in bounded memory (`adev_of_chunks`; default
    taus octave-spaced)."""
    tau0 = 1.0 / float(sample_rate_hz)
    ms, sums, n = _sums_of_chunks(chunks, tau0, m, tau_s, spill_dir)
    if n < 5:
        raise ValueError(f"need a record of at least 5 samples, got {n}")
    tau, ad, err, _ = _adev_of_sums(ms, sums, n, tau0)
    return allan_of_curve(tau, ad, err, sample_rate_hz, n)


def allan_of_curve(tau_s: np.ndarray, adev_deg_s: np.ndarray, adev_err_deg_s: np.ndarray,
                   sample_rate_hz: float, n_samples: int) -> AllanResult:
    """The five-term fit of a measured Allan curve (tau s, adev deg/s and its 1-sigma error)."""
    terms_s, kinds, fitted_s = fit_terms(tau_s, adev_deg_s, adev_err_deg_s)
    return AllanResult(tau_s=tau_s, adev_deg_s=adev_deg_s, adev_err_deg_s=adev_err_deg_s, terms_s=terms_s,
                       bounds=kinds, fitted_s=fitted_s, sample_rate_hz=float(sample_rate_hz),
                       n_samples=int(n_samples))
