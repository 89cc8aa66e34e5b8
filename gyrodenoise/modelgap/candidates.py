"""Candidate effects from the spec's vocabulary, each fitted to the record."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
import numpy.typing as npt

from gyrodenoise.analysis.allan import AVAR_SHAPE
from gyrodenoise.modelgap.settings import CARD_FIELD, N_PARAMS, SIGMA_TO_CARD
from gyrodenoise.modelgap.spectral import AGM_TAU_MAX_S, angle_gm_avar
from gyrodenoise.units import NOISE_SECTIONS, TERM_BY_SECTION

if TYPE_CHECKING:
    from gyrodenoise.modelgap.metric import Layout, Reference, Signature
    from gyrodenoise.simulator import ModelCard

#: one edit of a card: (term, its parameters in card units or None to remove it, re-fit of a term in the card)
Change: TypeAlias = "tuple[str, dict[str, float] | None, bool]"


# ------------------------------------------------------------------ candidates
def gm_avar(tau: npt.ArrayLike, sigma: float, T: float) -> np.ndarray:
    """Allan variance of a first-order Gauss-Markov process (see module docstring)."""
    x = np.asarray(tau, dtype=float) / T
    small = x < 1e-3
    full = 2.0 * sigma ** 2 * T / np.maximum(tau, 1e-300) * (
        1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * np.maximum(x, 1e-300)))
    approx = 2.0 * sigma ** 2 * np.asarray(tau, dtype=float) / (3.0 * T) * (1.0 - 0.75 * x)
    return np.where(small, approx, full)


#: the Allan variance shape of each Allan-shaped noise term (card section), unit s-based coefficient
SHAPE = {nm: AVAR_SHAPE[TERM_BY_SECTION[nm].symbol] for nm in NOISE_SECTIONS}


def _deterministic_s(card: ModelCard, n: int, fs: float, restarts: npt.ArrayLike | None) -> np.ndarray:
    """The card's deterministic rate (deg/s): bias, ramp, transient, sinusoids (no noise)."""
    t = np.arange(n) / fs
    cb = card.terms.get("constant_bias", {})
    det = np.full(n, cb.get("value", 0.0) / 3600.0)
    rr = card.terms.get("rate_ramp")
    if rr:
        det += rr["R"] / 3600.0 ** 2 * t
    tt = card.terms.get("turn_on_transient")
    if tt:
        det += tt["amplitude"] / 3600.0 * np.exp(-_since_restart(n, fs, restarts) / tt["tau"])
    for s in card.term_list("sinusoid"):
        det += s["amplitude"] / 3600.0 * np.sin(2 * np.pi * s["frequency"] * t + math.radians(s.get("phase_deg", 0.0)))
    return det


def _since_restart(n: int, fs: float, restarts: npt.ArrayLike | None) -> np.ndarray:
    k = np.arange(n)
    if restarts is None or not np.any(restarts):
        return k / fs
    last = np.maximum.accumulate(np.where(np.asarray(restarts, bool) & (k > 0), k, 0))
    return (k - last) / fs


@dataclass
class Candidate:
    """An effect proposed for the card: a term with its parameters, why, and once simulated
    its gap, score and components."""
    name: str
    params: dict[str, float] | None     # card units; None: the term is removed
    refit: bool
    why: str
    text: str = ""
    gap: float = float("nan")
    score: float = float("nan")
    widen: float = float("nan")
    robust: float = float("nan")
    z: dict[str, np.ndarray] | None = None
    components: dict[str, float] | None = None
    extra: list[Change] = field(default_factory=list)   # (name, params, refit) changed along with this one
    fallback: bool = False    # a joint re-fit of every noise term, tried when no single effect will do

    @property
    def changes(self) -> list[Change]:
        """This candidate's change and those made along with it."""
        return [(self.name, self.params, self.refit)] + list(self.extra)

    @property
    def n_params(self) -> int:
        """Parameters written (a removal writes none)."""
        return sum(N_PARAMS[nm] for nm, pr, _ in self.changes if pr is not None)

    def to_json(self) -> dict[str, Any]:
        """Plain JSON."""
        return {"name": self.name, "params": _params_json(self.params),
                "refit": self.refit, "why": self.why,
                "with": [{"name": e[0], "params": _params_json(e[1]), "refit": e[2]} for e in self.extra], "gap": _f(self.gap), "robust_gap": _f(self.robust), "widen": _f(self.widen),
                "score": _f(self.score),
                "components": self.components}


def _params_json(params: Mapping[str, float] | None) -> dict[str, float] | None:
    """Plain floats, or None for a term removed from the card."""
    return None if params is None else {k: float(v) for k, v in params.items()}


def _f(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def propose(y: npt.ArrayLike, layout: Layout, ref: Reference, z: Mapping[str, np.ndarray], card: ModelCard,
            restarts: npt.ArrayLike | None = None, limit: float = 3.0) -> list[Candidate]:
    """Candidate effects with parameters fitted to the record ``y`` (deg/s).

    Allan-shaped terms (Q, N, B, K) and gauss_markov are fitted to the Allan
    variance excess (measured minus mean simulated); rate_ramp,
    constant_bias, turn_on_transient and sinusoid by least squares on the
    record minus the card's deterministic part. A term already in the card is
    re-fitted (its new value replaces the old one) rather than added twice.
    When that joint fit changes the card's own terms, the same term is
    also proposed fitted alone to the excess over the whole current card (its
    terms held, Allan points where the record is below the card left out),
    and re-simulation chooses between the two.
    """
    fs, n = layout.fs, layout.n
    cands: list[Candidate] = []
    allan_flag = np.any(np.abs(z["allan"]) > limit)
    if allan_flag:
        ax = _AllanExcess.of(layout, ref, z, card, limit)
        cands += _allan_shape_candidates(ax)
        # --- Gauss-Markov bump (T >= 3 samples)
        cands += _correlated_candidates(ax, "gauss_markov", lambda T: gm_avar(ax.tau, 1.0, T), math.log(3.0 / fs),
                                        math.log(ax.tau[-1]), 3600.0, "Allan bump")
        # --- angle Gauss-Markov: white angle noise with a correlation time (an Allan slope
        # between -1/2 (white rate, tau >> T) and -1 (white angle)); exact for the sampled term
        cands += _correlated_candidates(ax, "angle_gauss_markov", lambda T: angle_gm_avar(layout.m, fs, T),
                                        math.log(0.3 / fs), math.log(min(AGM_TAU_MAX_S, ax.tau[-1])), 1.0,
                                        "Allan slope between white rate and white angle noise",
                                        rivals=(SHAPE["angle_random_walk"](ax.tau), SHAPE["quantization"](ax.tau)))
    r = np.asarray(y, float) - _deterministic_s(card, n, fs, restarts)
    t = np.arange(n) / fs
    if abs(z["mean"][0]) > limit:
        cands.append(_bias_candidate(card, r, z))
    if np.any(np.abs(z["trend"]) > limit) or (allan_flag and z["allan"][-1] > limit):
        cands.append(_ramp_candidate(card, r, t))
        cands += _transient_candidates(card, r, fs, restarts)
    zl = z["line"]
    k = int(np.argmax(zl))
    if zl[k] > limit and zl[k] ** 2 > 2.0 * math.log(len(zl)):
        cands.append(_sinusoid_candidate(r, t, layout, k, zl[k]))
    return cands


@dataclass
class _AllanExcess:
    """The Allan variance the record has beyond the card, and the weighted fits on it.

    ``avar_m``: the measured Allan variance, ``avar_s``: the simulations' mean, weights
    ``sw`` = 1 / (1-sigma of the larger), ``existing``: the card's Allan-shaped terms
    (s-based squared coefficients), ``target``: the measured variance minus what the
    rest of the card contributes (what the card's Allan-shaped terms and a new term
    share), ``keep``: the points not below the card by more than ``limit`` sigmas."""
    tau: np.ndarray
    avar_m: np.ndarray
    avar_s: np.ndarray
    sw: np.ndarray
    target: np.ndarray
    existing: dict[str, float]
    keep: np.ndarray
    limit: float

    @classmethod
    def of(cls, layout: Layout, ref: Reference, z: Mapping[str, np.ndarray], card: ModelCard,
           limit: float) -> _AllanExcess:
        tau = layout.tau_s
        avar_m = np.exp(2 * (ref.mean["allan"] + z["allan"] * ref.sigma["allan"]))   # measured
        avar_s = np.exp(2 * ref.mean["allan"])
        sig_avar = 2.0 * np.maximum(avar_m, avar_s) * ref.sigma["allan"]
        w = 1.0 / sig_avar ** 2
        existing = {nm: (card.terms[nm][CARD_FIELD[nm][0]] / CARD_FIELD[nm][1]) ** 2
                    for nm in NOISE_SECTIONS if nm in card.terms}
        rest = np.maximum(avar_s - sum(v * SHAPE[nm](tau) for nm, v in existing.items()), 0.0)
        return cls(tau, avar_m, avar_s, np.sqrt(w), avar_m - rest, existing, z["allan"] >= -limit, limit)

    @property
    def ex_names(self) -> list[str]:
        return list(self.existing)

    @property
    def ex_cols(self) -> list[np.ndarray]:
        return [SHAPE[nm](self.tau) for nm in self.existing]

    def joint(self, cols: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, float]:
        """Weighted NNLS of the target on ``cols`` (the card's Allan-shaped terms re-fitted
        with the others): (coefficients, z of each (unconstrained covariance at the
        solution), chi^2)."""
        from scipy.optimize import nnls
        A = np.column_stack(cols) * self.sw[:, None]
        scale = np.max(np.abs(A), axis=0)
        scale[scale == 0] = 1.0
        coef, rn = nnls(A / scale, self.target * self.sw)
        coef = coef / scale
        try:
            cov = np.linalg.inv(A.T @ A)
            zc = coef / np.sqrt(np.maximum(np.diag(cov), 1e-300))
        except np.linalg.LinAlgError:
            zc = np.zeros_like(coef)
        return coef, zc, rn * rn

    def refits(self, coef: np.ndarray) -> list[Change]:
        """Changes [(name, params or None, True)] of the card's Allan-shaped terms whose
        re-fitted coefficient moves by more than 2 % (a term re-fitted to zero is removed)."""
        out = []
        for nm, c in zip(self.ex_names, coef):
            old = self.existing[nm]
            if abs(math.sqrt(c) - math.sqrt(old)) > 0.02 * math.sqrt(old):
                fld, to_card = CARD_FIELD[nm]
                out.append((nm, {fld: math.sqrt(c) * to_card} if c > 0 else None, True))
        return out

    def held(self, col: np.ndarray) -> tuple[float, float]:
        """Fit one term to the excess over the WHOLE current card, its terms held:
        (coefficient, its z).

        The joint re-fit lets every Allan point pull on the card's terms, so
        points that no term can explain (a sensor's internal low-pass filter
        at short tau, with 0.1 % errors in a long record) drag a correct
        white-noise line away; re-simulation then decides between the two
        variants. Points where the record is BELOW the card (z < -limit)
        are left out: adding a term only adds Allan variance, so no added
        term can explain them."""
        a = (col * self.sw)[self.keep]
        if not np.any(a > 0):
            return 0.0, 0.0
        c = float(np.dot(a, ((self.avar_m - self.avar_s) * self.sw)[self.keep]) / np.dot(a, a))
        return c, c * math.sqrt(float(np.dot(a, a)))

    def held_chi2(self, col: np.ndarray) -> float:
        """chi^2 of `held` (the points it uses)."""
        hc, _ = self.held(col)
        res = ((self.avar_m - self.avar_s - max(hc, 0.0) * col) * self.sw)[self.keep]
        return float(np.dot(res, res))


def _allan_shape_candidates(ax: _AllanExcess) -> list[Candidate]:
    """Each Allan-shaped term the card lacks, fitted jointly with the card's own (and, when
    that changes them, with them held), and a re-fit of the card's own alone."""
    out: list[Candidate] = []
    ex_names, ex_cols = ax.ex_names, ax.ex_cols
    for name in NOISE_SECTIONS:
        fld, to_card = CARD_FIELD[name]
        if name in ax.existing:
            continue
        coef, zc, _ = ax.joint(ex_cols + [SHAPE[name](ax.tau)])
        if coef[-1] <= 0 or zc[-1] < ax.limit:
            continue
        ch = ax.refits(coef[:-1])
        out.append(Candidate(name, {fld: math.sqrt(coef[-1]) * to_card}, False,
                             f"Allan excess ~ {name} shape (z={zc[-1]:.1f})", extra=ch))
        if ch:      # the same term with the card's own terms held (see _AllanExcess.held)
            hc, hz = ax.held(SHAPE[name](ax.tau))
            if hc > 0 and hz >= ax.limit:
                out.append(Candidate(name, {fld: math.sqrt(hc) * to_card}, False,
                                     f"Allan excess ~ {name} shape, card's terms held (z={hz:.1f})"))
    if ex_names:    # re-fit the existing Allan-shaped terms only
        coef, zc, _ = ax.joint(ex_cols)
        ch = ax.refits(coef)
        if ch:
            out.append(Candidate(ch[0][0], ch[0][1], True, "re-fit of the Allan-shaped terms", extra=ch[1:]))
    return out


def _best_log_tau(chi2: Callable[[float], float], lo_T: float, hi_T: float) -> float:
    """The log correlation time minimising ``chi2(log T)``: a 41-point grid over
    ``lo_T .. hi_T``, then a bounded refinement within +-0.25 of the grid's best."""
    from scipy.optimize import minimize_scalar
    grid = np.linspace(lo_T, hi_T, 41)
    g0 = grid[int(np.argmin([chi2(g) for g in grid]))]
    opt = minimize_scalar(chi2, bounds=(max(g0 - 0.25, lo_T), g0 + 0.25), method="bounded")
    return float(opt.x)


def _correlated_candidates(ax: _AllanExcess, kind: str, col_of: Callable[[float], np.ndarray], lo_T: float, hi_T: float,
                           to_card: float, what: str, rivals: Sequence[np.ndarray] = ()) -> list[Candidate]:
    """A term with a correlation time (sigma, tau): tau by `_best_log_tau`, jointly
    with the card's Allan-shaped terms, and (when the card has some) with them held. With
    ``rivals`` (Allan shapes of the same number of parameters that the term tends to at its
    limits), it is proposed only when it fits the Allan variance better than they do by
    ``limit^2`` in chi^2 (its correlation time is resolved)."""
    out: list[Candidate] = []
    ex_names, ex_cols, limit = ax.ex_names, ax.ex_cols, ax.limit
    rival = ax.joint(ex_cols + list(rivals))[2] if rivals else math.inf
    rival_held = min((ax.held_chi2(c) for c in rivals), default=math.inf)
    T = math.exp(_best_log_tau(lambda logT: ax.joint(ex_cols + [col_of(math.exp(logT))])[2], lo_T, hi_T))
    coef, zc, c2 = ax.joint(ex_cols + [col_of(T)])
    if rivals and not c2 < rival - limit ** 2:
        zc = np.zeros_like(zc)      # not resolved: no better than its limits
    if coef[-1] > 0 and zc[-1] > limit:
        out.append(Candidate(kind, {"sigma": math.sqrt(coef[-1]) * to_card, "tau": T}, False,
                             f"{what}, best correlation time {T:.3g} s (z={zc[-1]:.1f})",
                             extra=ax.refits(coef[:-1])))
    if ex_names:    # the term on top of the card's terms held, its own correlation time
        def held_chi2(logT: float) -> float:
            return ax.held_chi2(col_of(math.exp(logT)))
        Th = math.exp(_best_log_tau(held_chi2, lo_T, hi_T))
        hc, hz = ax.held(col_of(Th))
        same = (coef[-1] > 0 and zc[-1] > limit and not ax.refits(coef[:-1])
                and abs(math.log(Th / T)) < 0.05)
        resolved = not rivals or held_chi2(math.log(Th)) < rival_held - limit ** 2
        if hc > 0 and hz >= limit and not same and resolved:
            out.append(Candidate(kind, {"sigma": math.sqrt(hc) * to_card, "tau": Th}, False,
                                 f"{what} at {Th:.3g} s, card's terms held (z={hz:.1f})"))
    return out


def _bias_candidate(card: ModelCard, r: np.ndarray, z: Mapping[str, np.ndarray]) -> Candidate:
    """The constant bias that takes the mean of ``r`` (record minus the card's deterministic part)."""
    old = card.terms.get("constant_bias")
    params = dict(old) if old else {}
    params["value"] = (old["value"] if old else 0.0) + float(r.mean()) * 3600.0
    return Candidate("constant_bias", params, old is not None, f"record mean off by z={z['mean'][0]:.1f}")


def _ramp_candidate(card: ModelCard, r: np.ndarray, t: np.ndarray) -> Candidate:
    """The rate ramp fitted to ``r`` through the origin (the card's ramp is R t)."""
    old = card.terms.get("rate_ramp")
    slope = float(np.dot(r, t) / np.dot(t, t))
    return Candidate("rate_ramp", {"R": (old["R"] if old else 0.0) + slope * 3600.0 ** 2},
                     old is not None, "trend over the record (linear)")


def _transient_candidates(card: ModelCard, r: np.ndarray, fs: float, restarts: npt.ArrayLike | None) -> list[Candidate]:
    """The turn-on transient (amplitude, tau) fitted to block means of ``r`` (about 2000
    samples each) after start and restarts: least squares of a constant and the decay
    for each tau of a 40-point log grid, then a bounded refinement; none when the best
    tau is the grid's longest."""
    from scipy.optimize import minimize_scalar
    n = len(r)
    nb = max(1, n // 2000)
    m = n // nb
    tb = _since_restart(n, fs, restarts)[:m * nb].reshape(m, nb)
    rb = r[:m * nb].reshape(m, nb).mean(axis=1)

    def sse(logtau: float, ret: bool = False) -> Any:
        e = np.exp(-tb / math.exp(logtau)).mean(axis=1)
        A = np.column_stack([np.ones(m), e])
        coef, *_ = np.linalg.lstsq(A, rb, rcond=None)
        res = float(np.sum((rb - A @ coef) ** 2))
        return (res, coef) if ret else res
    grid = np.linspace(math.log(max(2.0 / fs, 0.5)), math.log(n / fs), 40)
    vals = [sse(g) for g in grid]
    g0 = int(np.argmin(vals))
    lo, hi = grid[max(g0 - 1, 0)], grid[min(g0 + 1, len(grid) - 1)]
    opt = minimize_scalar(sse, bounds=(lo, hi), method="bounded") if hi > lo else None
    lt = float(opt.x) if opt is not None else grid[g0]
    _, coef = sse(lt, ret=True)
    old = card.terms.get("turn_on_transient")
    if abs(coef[1]) > 0 and lt < grid[-1] - 1e-6:
        return [Candidate("turn_on_transient", {"amplitude": float(coef[1]) * 3600.0, "tau": math.exp(lt)},
                          old is not None, "decaying trend after start/restarts")]
    return []


def _sinusoid_candidate(r: np.ndarray, t: np.ndarray, layout: Layout, k: int, z_line: float) -> Candidate:
    """The sinusoid at the Welch bin ``k`` where the record's PSD stands out of the
    simulations' (z ``z_line``): the frequency of the peak of the record's own periodogram
    (zero-padded 4x) within +-1.5 Welch bins, refined by maximising the power of ``r`` at
    it; amplitude and phase by least squares."""
    from scipy.optimize import minimize_scalar
    fs, n = layout.fs, len(r)
    f = layout.freq_hz
    df = f[1] - f[0]
    nfft = 4 * (1 << int(math.ceil(math.log2(n))))
    spec = np.abs(np.fft.rfft(r - r.mean(), nfft)) ** 2
    ff = np.fft.rfftfreq(nfft, 1.0 / fs)
    sel = np.flatnonzero((ff >= f[k] - 1.5 * df) & (ff <= f[k] + 1.5 * df))
    j = int(sel[np.argmax(spec[sel])])
    dff = ff[1] - ff[0]

    def neg_power(fr: float) -> float:
        ph = 2 * np.pi * fr * t
        return -(np.dot(r, np.cos(ph)) ** 2 + np.dot(r, np.sin(ph)) ** 2)
    opt = minimize_scalar(neg_power, bounds=(max(ff[j] - dff, 1e-9), min(ff[j] + dff, fs / 2)),
                          method="bounded", options={"xatol": 1e-3 * dff})
    fr = float(opt.x)
    A = np.column_stack([np.sin(2 * np.pi * fr * t), np.cos(2 * np.pi * fr * t), np.ones(n)])
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    amp = math.hypot(coef[0], coef[1])
    phase = math.degrees(math.atan2(coef[1], coef[0]))
    return Candidate("sinusoid", {"amplitude": amp * 3600.0, "frequency": fr, "phase_deg": phase},
                     False, f"spectral line at {fr:.4g} Hz (z={z_line:.1f})")


def spectral_refit(sig_m: Signature, layout: Layout, ref: Reference, card: ModelCard,
                   bands: Sequence[tuple[float, float]] = (), why: str = "",
                   angle_gm: bool = False) -> Candidate | None:
    """One candidate that re-fits ALL the card's noise terms at once (up, down or to
    zero = removed): Q, N, B, K and the Gauss-Markov terms (with ``angle_gm``, also
    a dictionary of angle Gauss-Markov terms), by
    `spectral.fit_terms` on the measured Allan variance and Welch-band PSD
    minus what the card's other terms (sinusoids, ramp, transient, bias) add in
    the simulations. None when nothing would change."""
    from gyrodenoise.modelgap.spectral import allan_columns, band_columns, fit_terms, stochastic_specs
    specs, coef = stochastic_specs(card)
    e = layout.band_edges
    band_mean = lambda p: np.array([p[e[i]:e[i + 1]].mean() for i in range(len(e) - 1)])  # noqa: E731
    psd_m = band_mean(sig_m["psd_bins"])
    psd_s = band_mean(ref.mean["psd_bins"])
    if specs:
        own_a = allan_columns(specs, layout.m, layout.fs, bands) @ coef
        own_p = band_columns(specs, layout, bands)[0] @ coef
    else:
        own_a, own_p = 0.0, 0.0
    rest_a = np.maximum(ref.mean["avar"] - own_a, 0.0)
    rest_p = np.maximum(psd_s - own_p, 0.0)
    terms, _, _ = fit_terms(layout, bands, sig_m["avar"] - rest_a, 2.0 * sig_m["avar"] * ref.sigma["allan"],
                            psd_m - rest_p, psd_m * ref.sigma["psd"], angle_gm=angle_gm)
    if angle_gm and not terms.get("angle_gauss_markov"):
        return None         # the same as the plain re-fit
    changes: list[Change] = []
    for nm in NOISE_SECTIONS:
        fld, to_card = CARD_FIELD[nm]
        new = math.sqrt(terms[nm]) * to_card
        old = card.terms.get(nm, {}).get(fld)
        if old is None and new > 0:
            changes.append((nm, {fld: new}, False))
        elif old is not None and new == 0:
            changes.append((nm, None, True))
        elif old is not None and abs(new - old) > 0.02 * old:
            changes.append((nm, {fld: new}, True))
    for kind, to_card in SIGMA_TO_CARD.items():
        old_gm = sorted((g["sigma"], g["tau"]) for g in card.term_list(kind))
        new_gm = sorted((s * to_card, t) for s, t in terms.get(kind, ()))
        if len(old_gm) != len(new_gm) or any(abs(a[0] - b[0]) > 0.02 * a[0] or abs(a[1] - b[1]) > 0.02 * a[1]
                                             for a, b in zip(old_gm, new_gm)):
            if old_gm:
                changes.append((kind, None, True))
            changes += [(kind, {"sigma": s, "tau": t}, False) for s, t in new_gm]
    if not changes:
        return None
    (nm, pr, rf), rest = changes[0], changes[1:]
    return Candidate(nm, pr, rf, why or "joint re-fit of every noise term (Q, N, B, K, Gauss-Markov"
                     + (", angle Gauss-Markov" if angle_gm else "") + ") to the "
                     "Allan variance and the PSD; terms may go up, down or to zero (removed)", extra=rest)
