"""The workflow: score candidates, choose, edit the card, repeat (`gap`)."""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from gyrodenoise.console import log
from gyrodenoise.errors import InputError
from gyrodenoise.modelgap.candidates import Candidate, Change, _f, propose, spectral_refit
from gyrodenoise.modelgap.cards import card_at_rate, check_editable, edit_card
from gyrodenoise.modelgap.metric import (
    Layout,
    Reference,
    Signature,
    gap_components,
    gap_value,
    loo_gaps,
    signature,
    where_disagree,
    zscores,
)
from gyrodenoise.modelgap.report import _short
from gyrodenoise.modelgap.settings import (
    CARD_FIELD,
    COMPONENT_FLOOR,
    COMPONENTS,
    GAP_METRIC,
    MIN_IMPROVEMENT,
    MIN_SAMPLES,
    OFFSET_RATIO,
    PENALTY_PER_PARAM,
    SIGMA_TO_CARD,
    WIDEN_COMPONENTS,
    Z2_CAP,
)
from gyrodenoise.modelgap.simulation import Simulator
from gyrodenoise.modelgap.spectral import band_stop, find_bumps
from gyrodenoise.simulator import CardLike, ModelCard


# ------------------------------------------------------------------ the workflow
@dataclass
class GapResult:
    """Outcome of `gap`: the card reached (``card_text``), the effects added, the gap
    before and after with its threshold, and each iteration's candidates and scores."""
    effects_added: list[dict[str, Any]]
    gap_before: float
    gap_after: float
    card_text: str
    iterations: list[dict[str, Any]]
    threshold: float
    engine: str
    component_threshold: dict[str, float]
    seeds: list[int]
    limitations: list[str] = field(default_factory=list)
    layout: Layout | None = None
    measured: Signature | None = None
    stop_bands: list[tuple[float, float, float]] = field(default_factory=list)  # [(lo_hz, hi_hz, peak ratio or nan)]
    named: list[str] = field(default_factory=list)     # physical effects named from the evidence
    white_factor: float | None = None     # heldout_gap(refit_white=True): the white-noise level's factor
    card_error: list[float] | None = None  # heldout_gap(card_error=True): bootstrap relative 1-sigma per noise term

    @property
    def within_scatter(self) -> bool:
        """The final card is within the simulations' scatter (the stop test of the loop)."""
        return bool(self.iterations[-1].get("within_scatter", False))

    def to_json(self) -> Any:
        """Plain JSON (every float finite or null, see `_finite`)."""
        return _finite({"effects_added": [{"name": e["name"], "params": e["params"], "refit": e["refit"],
                                           "iteration": e["iteration"]}
                                          for e in self.effects_added],
                        "gap_before": self.gap_before, "gap_after": self.gap_after,
                        "gap_metric": GAP_METRIC,
                        "threshold": self.threshold, "component_threshold": self.component_threshold,
                        "engine": self.engine, "seeds": list(self.seeds),
                        "within_scatter": self.within_scatter,
                        "stop": self.iterations[-1].get("stop"),
                        "limitations": list(self.limitations),
                        "stop_bands_hz": [[lo, hi] for lo, hi, _ in self.stop_bands],
                        "named_effects": list(self.named),
                        "iterations": [{k: v for k, v in it.items() if not k.startswith("_")}
                                       for it in self.iterations]})


def _finite(obj: Any) -> Any:
    """A copy of a JSON-able structure with every float through `_f` (NaN/inf -> None)."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (bool, str)) or obj is None:
        return obj
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _f(float(obj))
    if isinstance(obj, np.ndarray):
        return _finite(obj.tolist())
    return obj


def _zeroed(changes: Iterable[Change]) -> list[str]:
    """Fields that a set of changes would write as 0 (a noise term fitted to nothing)."""
    out = []
    for nm, pr, _ in changes:
        if pr is None:          # a removal: the term goes, nothing is written as 0
            continue
        fld = CARD_FIELD.get(nm, (None,))[0]
        for k in ([fld] if fld else []) + (["sigma"] if nm in ("gauss_markov", "angle_gauss_markov") else []) + \
                (["amplitude"] if nm == "sinusoid" else []):
            if k in pr and not float(pr[k]) > 0:
                out.append(f"{nm}.{k}")
    return out


def _points(z: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per-point contributions to the five gap components (component units)."""
    nl = len(z["line"])
    return {"allan": z["allan"] ** 2, "psd": z["psd"] ** 2,
            "line": np.array([np.max(z["line"] ** 2) / (2.0 * math.log(max(nl, 3)))]),
           "mean": z["mean"] ** 2, "trend": z["trend"] ** 2}


def explainable(zs: Iterable[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Mask of the points that at least one of the z sets (the current card and
    its candidates) brings within the cap ``|z| <= 5``."""
    pts = [_points(z) for z in zs]
    return {c: np.any([p[c] < Z2_CAP for p in pts], axis=0) for c in COMPONENTS}


def robust_gap(z: Mapping[str, np.ndarray], mask: Mapping[str, np.ndarray] | None = None) -> float:
    """The gap used to CHOOSE candidates: every point's ``z^2`` capped at
    `Z2_CAP` (``|z| = 5``), and, given ``mask`` (`explainable`), the
    points that no candidate brings within the cap left out (they count 0).

    A candidate is then judged by how many points it brings into agreement,
    not by how it shifts a disagreement that no term of the vocabulary
    removes (e.g. a sensor's internal low-pass filter at short tau, where a
    1e6-sample record has Allan errors of 0.1 % and z of -100). The divisor
    of each component stays its number of points, so the value stays
    comparable between candidates of one iteration. When every disagreement
    is explainable (the simulated hidden-effect cases) this is the gap with
    a cap.
    """
    pts = _points(z)
    comp = {}
    for c in COMPONENTS:
        v = np.minimum(pts[c], Z2_CAP)
        if mask is not None:
            v = np.where(mask[c], v, 0.0)
        comp[c] = float(np.mean(v))
    return gap_value(comp)


def widening(ref_new: Reference, ref_old: Reference, z_old: Mapping[str, np.ndarray]) -> float:
    """Log-likelihood price of a wider simulated scatter that the record does not ask for.

    ``-2 ln L`` of the measured signatures under a card is ``sum z^2 + sum
    ln(2 pi sigma^2)``: the gap holds the ``z^2`` part only, so a candidate
    that merely widens the simulations' scatter (e.g. a large random walk
    whose wander covers a mean offset) lowers every ``z`` and looks better
    than it is. Per point, the widening ``ln(sigma_new^2 / sigma_old^2)`` is
    charged beyond what the record itself asks for, ``ln(max(z_old^2, 1))``
    (a point off by 4 sigma justifies a scatter up to 4x wider; a point that
    already agrees justifies none). Averaged like the gap: over the points of
    each of ``allan``, ``psd``, ``mean`` and ``trend``, then over the five
    components (``line``, a maximum, counts 0).
    """
    tot = 0.0
    for c in WIDEN_COMPONENTS:
        w = np.log(ref_new.sigma[c] ** 2 / ref_old.sigma[c] ** 2) - np.log(np.maximum(z_old[c] ** 2, 1.0))
        tot += float(np.mean(np.maximum(w, 0.0)))
    return tot / len(COMPONENTS)


def deterministic_offset(sig_m: Signature, ref: Reference, z: Mapping[str, np.ndarray],
                         limit: float = 3.0) -> tuple[bool, float, float]:
    """Is the record mean's disagreement a deterministic offset rather than a wander?

    A slow random process (bias instability, random walk, Gauss-Markov) that
    moves the record mean by ``d`` also moves the block means about one
    another by a similar amount; a constant bias moves the mean and leaves the
    block means alone. True when ``|z_mean| > limit`` and the offset of the
    record mean from the simulations' mean is more than ``OFFSET_RATIO`` times
    the rms of the measured block means about the record mean. Returns
    ``(flag, offset_deg_s, wander_rms_deg_s)``.
    """
    off = float(sig_m["mean"][0] - ref.mean["mean"][0])
    wander = float(np.sqrt(np.mean(sig_m["trend"] ** 2)))
    flag = abs(z["mean"][0]) > limit and abs(off) > OFFSET_RATIO * wander
    return bool(flag), off, wander


def _evaluate(sims: Iterable[np.ndarray], sig_m: Signature, layout: Layout, bands: Sequence[tuple[float, float]] = ()) -> tuple[Reference, dict[str, np.ndarray], dict[str, float], float]:
    ref = Reference(layout, [signature(band_stop(s, layout.fs, bands), layout) for s in sims])
    z = zscores(sig_m, ref)
    comp = gap_components(z)
    return ref, z, comp, gap_value(comp)


# The price a term of the initial fit pays to stay when initial_terms is given it (_initial_fit,
# which the workflow uses, does not ask for it): leaving the term out must cost more than 3^2 in
# chi^2 (the angle Gauss-Markov candidate's rule against its simpler rivals), counted twice: the
# fit's rows are two views of the same record (its Allan variance and its PSD: a high-frequency
# excess shows in the shortest taus and the top bands alike). On 40 seeded white records, 3^2
# alone keeps another term on 2, 2 x 3^2 on none.
INITIAL_DCHI2 = 2 * 3.0 ** 2


def welch_band_rel_sd(layout: Layout) -> np.ndarray:
    """Relative 1-sigma of the mean of each Welch band's bins for a smooth spectrum
    (Hann window, 50 % overlap, ``K`` segments): one bin ``sqrt(1.056 / K)`` (adjacent
    segments' periodograms correlated 0.028, counted twice), and the bins of a band
    correlated 0.444 with their neighbours and 0.028 with the next ones (``|W(k)|^2 /
    |W(0)|^2`` of the squared Hann window). ``metric._floors``' ``1 / sqrt(1.8 K nbins)``
    is 1.4x (one bin) to 1.9x (wide bands) below this and below the scatter of seeded
    white records."""
    nb = np.diff(layout.band_edges).astype(float)
    corr = 1.0 + (2.0 * 0.444 * np.maximum(nb - 1.0, 0.0) + 2.0 * 0.028 * np.maximum(nb - 2.0, 0.0)) / nb
    return np.sqrt(1.056 * corr / (layout.n_segments * nb))


def initial_terms(sig_m: Signature, layout: Layout, bands: Sequence[tuple[float, float]], min_dchi2: float = 0.0,
                  psd_rel_sd: np.ndarray | None = None) -> dict[str, Any]:
    """The noise terms fitted to the record's signatures alone (`spectral.fit_terms`;
    weights: the analytic 1-sigma of one record's Allan variance and, unless
    ``psd_rel_sd`` is given, ``metric._floors``' for its Welch bands). With ``min_dchi2``
    > 0 a term is kept only when leaving it out (the others re-fitted) raises the fit's
    chi^2 by more than that: with ``INITIAL_DCHI2`` and ``welch_band_rel_sd(layout)`` a
    white-noise record comes out as angle random walk alone (the workflow's
    `_initial_fit` does not apply this rule: docs/bench/gap.md, "Initial fit")."""
    from gyrodenoise.modelgap.metric import _floors
    from gyrodenoise.modelgap.spectral import fit_terms
    fl = _floors(sig_m, layout)
    e = layout.band_edges
    psd_m = np.array([sig_m["psd_bins"][e[i]:e[i + 1]].mean() for i in range(len(e) - 1)])
    rel = fl["psd"] if psd_rel_sd is None else psd_rel_sd
    return fit_terms(layout, bands, sig_m["avar"], 2.0 * sig_m["avar"] * fl["allan"], psd_m,
                     psd_m * rel, min_dchi2=min_dchi2)[0]


def _initial_fit(text: str, sig_m: Signature, layout: Layout, bands: Sequence[tuple[float, float]], card: ModelCard, csrc: str,
                 source: str, effects: list[dict[str, Any]]) -> str:
    """Write the noise terms fitted to the record alone (`initial_terms`) into a
    card that has none; appends to ``effects``."""
    terms = initial_terms(sig_m, layout, bands)
    note = f"initial fit to {Path(str(source)).name}"
    changes = [(nm, {CARD_FIELD[nm][0]: float(np.sqrt(v)) * CARD_FIELD[nm][1]}) for nm, v in terms.items()
               if nm in CARD_FIELD and v > 0]
    changes += [("gauss_markov", {"sigma": s_ * SIGMA_TO_CARD["gauss_markov"], "tau": t_})
                for s_, t_ in terms["gauss_markov"]]
    if not changes:
        raise InputError("the card has no noise term and none could be fitted to the record", csrc)
    for nm, pr in changes:
        text = edit_card(text, nm, pr, nm in card.terms, note, csrc)
        effects.append({"name": nm, "params": pr, "refit": nm in card.terms,
                        "why": "initial fit (the card had no noise term)", "iteration": 0})
    return text


def check_record(rate_deg_s: npt.ArrayLike, source: str = "MEASURED") -> np.ndarray:
    """The measured record as a float array, or InputError (one line) when the
    workflow cannot use it: not 1-D finite, too short, or constant."""
    y = np.asarray(rate_deg_s, dtype=float)
    if y.ndim != 1 or not np.all(np.isfinite(y)):
        raise InputError("the record must be a 1-D array of finite rates", source)
    if y.shape[0] < MIN_SAMPLES:
        raise InputError(f"only {y.shape[0]} samples; the gap workflow needs at least {MIN_SAMPLES} "
                         f"(Allan deviation over octaves and a Welch PSD)", source)
    if not np.ptp(y) > 0:
        raise InputError("the record is constant (zero variance): nothing to compare", source)
    return y


FALLBACK_GAIN = 0.5  # the joint re-fit is accepted when it at least halves the plain gap
TOP_FROM = 0.3      # the band given to an internal low-pass filter: 0.3 fs to Nyquist


def _top_disagreement(res: GapResult) -> float | None:
    """Lower edge (Hz) of the band given to the sensor's internal low-pass filter,
    TOP_FROM * fs, when what still disagrees sits at the top of the band: a run of
    Welch bands ending at Nyquist with |z| > 3, or the one-sample Allan point; else
    None. (A fixed edge: where the run starts moves with the seeds' scatter.)"""
    if res.layout is None or not _top_disagrees(res.iterations[-1]["_z"]):
        return None
    return float(TOP_FROM * res.layout.fs)


def _top_disagrees(z: Mapping[str, np.ndarray]) -> bool:
    """A run of Welch bands ending at Nyquist with |z| > 3, or the one-sample Allan point."""
    return abs(z["psd"][-1]) > 3.0 or abs(z["allan"][0]) > 3.0


def gap(rate_deg_s: npt.ArrayLike, sample_rate_hz: float, card: CardLike, seeds: int | Sequence[int] = 6,
        engine: str = "native", restarts: npt.ArrayLike | None = None, max_effects: int = 6,
        fmu_dir: str | os.PathLike[str] | None = None, workers: int | None = None, source: str = "MEASURED",
        quiet: bool = True, stop_bands: str | Sequence[tuple[float, float]] | None = "auto", latitude_deg: float | None = None,
        outliers: bool = False) -> GapResult:
    """Find what a model card misses to behave like a measured record.

    With ``stop_bands="auto"``, when the card cannot be brought within the scatter
    and what still disagrees sits at the top of the band (the sensor's internal
    low-pass filter, which no term of the vocabulary represents), the workflow goes
    on from the card reached, with that top band taken out of the comparison as well
    (named in ``named``); ``gap_before`` stays the first pass's and the iterations
    of both passes are kept.

    Parameters
    ----------
    rate_deg_s : array_like
        Measured rate (deg/s), fixed sample rate.
    sample_rate_hz : float
    card : ModelCard, path or card name
    seeds : int or list of int
        Simulated records per evaluation (int S: seeds 1..S).
    engine : {"native", "fmu"}
        Simulator for the reported gaps; candidates are screened with the
        native engine (bit-identical to the FMU).
    restarts : array_like of bool, optional
    max_effects : int
        Most effects added (a joint re-fit of the noise terms counts as one).
    fmu_dir : path, optional
        Folder of SimulatedFog.fmu (engine "fmu"; default build/, built when missing).
    workers : int, optional
        Processes for the FMU engine (default: one per seed, up to the cores).
    source : str
        The record's name in messages.
    quiet : bool
        No progress lines on stderr.
    stop_bands : "auto", list of (lo_hz, hi_hz) or None
        Spectral bumps (base vibration, dither) taken out of the comparison by
        one band-stop applied alike to the record and to every simulation;
        "auto": `spectral.find_bumps`; None or []: none.
    latitude_deg : float, optional
        Where the record was taken: a fitted constant bias is compared with the
        Earth's rotation there (`effects.name_effects`).
    outliers : bool
        Replace isolated outliers by the running median before the comparison.

    Returns
    -------
    GapResult
    """
    n_out = 0
    if outliers:
        from gyrodenoise.modelgap.effects import screen_outliers
        rate_deg_s, idx = screen_outliers(check_record(rate_deg_s, source))
        n_out = len(idx)
        log(f"gyrodenoise: {n_out} outlier(s) replaced by the running median before the comparison", quiet=quiet)
    kw: dict[str, Any] = dict(seeds=seeds, engine=engine, restarts=restarts, max_effects=max_effects, fmu_dir=fmu_dir,
                              workers=workers, source=source, quiet=quiet, latitude_deg=latitude_deg)
    res = _gap_once(rate_deg_s, sample_rate_hz, card, stop_bands=stop_bands, **kw)
    lo = None if res.within_scatter or stop_bands != "auto" else _top_disagreement(res)
    if lo is None:
        return _with_outliers(res, n_out, len(np.asarray(rate_deg_s)))
    from gyrodenoise.simulator import parse_card
    log(f"gyrodenoise: what disagrees sits at the top of the band: the sensor's internal low-pass filter; "
        f"going on with {lo:.3g}-{float(sample_rate_hz) / 2:.3g} Hz taken out as well", quiet=quiet)
    card1 = parse_card(res.card_text, getattr(card, "source", "<card>"))
    bands = [(a, b) for a, b, _ in res.stop_bands] + [(lo, float(sample_rate_hz) / 2.0)]
    kw["max_effects"] = max(max_effects - len({e["iteration"] for e in res.effects_added}), 1)
    res2 = _gap_once(rate_deg_s, sample_rate_hz, card1, stop_bands=bands, **kw)
    n0 = len(res.iterations)
    for e in res2.effects_added:
        e["iteration"] += n0
    res2.effects_added = res.effects_added + res2.effects_added
    res2.iterations = res.iterations + res2.iterations
    res2.gap_before = res.gap_before
    res2.stop_bands = list(res.stop_bands) + [(lo, float(sample_rate_hz) / 2.0, -1.0)]
    from gyrodenoise.modelgap.effects import name_effects
    res2.named = name_effects(check_record(rate_deg_s, source), float(sample_rate_hz),
                              parse_card(res2.card_text), res2.stop_bands, latitude_deg)
    return _with_outliers(res2, n_out, len(np.asarray(rate_deg_s)))


def _with_outliers(res: GapResult, n_out: int, n: int) -> GapResult:
    if n_out:
        res.named.insert(0, f"outliers: {n_out} isolated wild samples ({100.0 * n_out / n:.2g} % of the record, "
                            f"> 10 robust sigmas off the running median) replaced before the comparison; no term "
                            f"of the card makes them")
    return res


@dataclass
class _Pass:
    """What one pass of the workflow (`_gap_once`) holds fixed: the record and
    its signatures, the simulator, the stop bands, and where the card came from."""
    y: np.ndarray
    fs: float
    layout: Layout
    sim: Simulator
    sig_m: Signature
    bands: list[tuple[float, float]]
    restarts: npt.ArrayLike | None
    source: str
    csrc: str
    stop_bands: str | Sequence[tuple[float, float]] | None      # as given: "auto" or a list
    quiet: bool

    def evaluate(self, text: str, engine: str | None = None) -> tuple[Reference, dict[str, np.ndarray], dict[str, float], float]:
        """(reference, z, components, gap) of the card ``text`` simulated (``engine``: the
        simulator's own unless given)."""
        sims = self.sim.run(text) if engine is None else self.sim.run(text, engine=engine)
        return _evaluate(sims, self.sig_m, self.layout, self.bands)

    def edited(self, text: str, changes: Iterable[Change]) -> str:
        """``text`` with ``changes`` [(name, params, refit)] written in, each with its note."""
        for nm, pr, rf in changes:
            text = edit_card(text, nm, pr, rf, f"fitted to {Path(str(self.source)).name}", self.csrc)
        return text


def _seed_list(seeds: int | Sequence[int]) -> list[int]:
    """Seeds 1..S for an int S, else the given seeds; InputError below 3."""
    seed_list = (list(range(1, int(cast(int, seeds)) + 1)) if np.isscalar(seeds)
                 else [int(s) for s in cast(Sequence[int], seeds)])
    if len(seed_list) < 3:
        raise InputError(f"need at least 3 seeds to know the simulation's scatter, got {len(seed_list)}")
    return seed_list


def _resolve_stop_bands(y: np.ndarray, fs: float,
                        stop_bands: str | Sequence[tuple[float, float]] | None) -> list[tuple[float, float, float]]:
    """The bands taken out of the comparison, [(lo_hz, hi_hz, peak ratio or NaN when
    given)]: `spectral.find_bumps` for ``"auto"``; InputError for a bad band."""
    if isinstance(stop_bands, str):
        if stop_bands != "auto":
            raise InputError(f"stop_bands must be 'auto', None or a list of (lo_hz, hi_hz), got {stop_bands!r}")
        bumps = find_bumps(y, fs)
    else:
        bumps = [(float(lo), float(hi), float("nan")) for lo, hi in (stop_bands or ())]
    for lo, hi, _ in bumps:
        if not 0 <= lo < hi:
            raise InputError(f"stop band {lo:g}-{hi:g} Hz: need 0 <= low < high")
    return bumps


def _thresholds(ref: Reference) -> tuple[float, dict[str, float]]:
    """(gap threshold, per-component thresholds) from the simulations' leave-one-out gaps:
    1.5 x their largest, at least 1.5 for the gap and COMPONENT_FLOOR for a component."""
    loo = loo_gaps(ref)
    threshold = max(1.5, 1.5 * max(g_ for g_, _ in loo)) if loo else 2.0
    comp_threshold = {c: max(COMPONENT_FLOOR, 1.5 * max(cc[c] for _, cc in loo)) if loo else COMPONENT_FLOOR
                      for c in COMPONENTS}
    return threshold, comp_threshold


def _start_pass(rate_deg_s: npt.ArrayLike, sample_rate_hz: float, card: CardLike, seeds: int | Sequence[int],
                engine: str, restarts: npt.ArrayLike | None, fmu_dir: str | os.PathLike[str] | None,
                workers: int | None, source: str, quiet: bool, stop_bands: str | Sequence[tuple[float, float]] | None
                ) -> tuple[_Pass, str, list[tuple[float, float, float]], list[int]]:
    """Check the inputs and set up one pass: (`_Pass`, card text, stop bands, seeds)."""
    from gyrodenoise.simulator import load_card
    y = check_record(rate_deg_s, source)
    fs = float(sample_rate_hz)
    card0 = load_card(card)
    card_at_rate(card0.text, fs, card0.source)      # the card as simulated at the record's rate (Nyquist)
    check_editable(card0)               # every term of the vocabulary can be written into this card
    seed_list = _seed_list(seeds)
    layout = Layout.for_record(y.shape[0], fs)
    sim = Simulator(y.shape[0], fs, seed_list, engine, restarts, fmu_dir, workers, quiet, source=card0.source)
    bumps = _resolve_stop_bands(y, fs, stop_bands)
    bands = [(lo, hi) for lo, hi, _ in bumps]
    if bands:
        log("gyrodenoise: spectral bump(s) taken out of the comparison (band-stop on the record and on "
            "every simulation alike): " + ", ".join(f"{lo:.3g}-{hi:.3g} Hz" for lo, hi in bands), quiet=quiet)
    sig_m = signature(band_stop(y, fs, bands), layout)
    ctx = _Pass(y, fs, layout, sim, sig_m, bands, restarts, source, card0.source, stop_bands, quiet)
    return ctx, card0.text, bumps, seed_list


def _first_card(ctx: _Pass, text: str, effects: list[dict[str, Any]]) -> tuple[str, list[np.ndarray]]:
    """The card the loop starts from and its simulations: an empty (or deterministic-only)
    card starts from the noise terms fitted to the record alone, with the analytic scatter
    of one record as the weights (`_initial_fit`; appends to ``effects``)."""
    sims = ctx.sim.run(text)
    if not np.any([np.std(s_) > 0 for s_ in sims]):
        text = _initial_fit(text, ctx.sig_m, ctx.layout, ctx.bands, card_at_rate(text, ctx.fs, ctx.csrc), ctx.csrc,
                            ctx.source, effects)
        log("gyrodenoise: the card has no noise term: started from " + ", ".join(
            f"{e['name']} {_short(e['params'])}" for e in effects), quiet=ctx.quiet)
        sims = ctx.sim.run(text)
    return text, sims


def _gap_once(rate_deg_s: npt.ArrayLike, sample_rate_hz: float, card: CardLike, seeds: int | Sequence[int] = 6,
              engine: str = "native", restarts: npt.ArrayLike | None = None, max_effects: int = 6,
              fmu_dir: str | os.PathLike[str] | None = None, workers: int | None = None, source: str = "MEASURED",
              quiet: bool = True, stop_bands: str | Sequence[tuple[float, float]] | None = "auto",
              latitude_deg: float | None = None) -> GapResult:
    """One pass of `gap` (its parameters), with the stop bands as given."""
    ctx, text, bumps, seed_list = _start_pass(rate_deg_s, sample_rate_hz, card, seeds, engine, restarts, fmu_dir,
                                              workers, source, quiet, stop_bands)
    effects: list[dict[str, Any]] = []
    iterations: list[dict[str, Any]] = []
    limitations: list[str] = []
    text, sims = _first_card(ctx, text, effects)
    ref, z, comp, g = _evaluate(sims, ctx.sig_m, ctx.layout, ctx.bands)
    threshold, comp_threshold = _thresholds(ref)
    log(f"gyrodenoise: gap of the input card {g:.3g} (threshold {threshold:.3g})", quiet=quiet)
    if not math.isfinite(g):
        raise InputError(f"the gap of the input card is not finite ({g}): the record's signatures "
                         f"cannot be compared with the card's", source)
    gap_before = g
    while True:
        it = {"card_gap": g, "components": comp, "where": where_disagree(z, ctx.layout),
              "_ref": ref, "_z": z, "candidates": []}
        iterations.append(it)
        within = g <= threshold and all(comp[c] <= comp_threshold[c] for c in COMPONENTS)
        it["within_scatter"] = bool(within)
        steps = {e["iteration"] for e in effects if e["iteration"] > 0 or not e["why"].startswith("initial")}
        if within or len(steps) >= max_effects:
            it["stop"] = "within the simulations' scatter" if within else "max_effects reached"
            break
        best = _choose(ctx, text, ref, z, g, it, limitations, threshold, comp_threshold)
        if best is None:
            it["stop"] = "no candidate shrinks the gap significantly"
            break
        text = _take(best, g, it, len(iterations) - 1, effects, quiet)
        ref, z, comp, g = ctx.evaluate(text)
    _note_card_noisier(iterations[-1], limitations)
    from gyrodenoise.modelgap.effects import name_effects
    named = name_effects(ctx.y, ctx.fs, card_at_rate(text, ctx.fs, ctx.csrc), bumps, latitude_deg)
    return GapResult(named=named, limitations=limitations, effects_added=effects, gap_before=gap_before, gap_after=g,
                     card_text=text, iterations=iterations, threshold=threshold, engine=engine, seeds=seed_list,
                     component_threshold=comp_threshold, layout=ctx.layout, measured=ctx.sig_m, stop_bands=bumps)


def _take(best: Candidate, g: float, it: dict[str, Any], iteration: int, effects: list[dict[str, Any]], quiet: bool) -> str:
    """Accept candidate ``best`` in iteration ``it`` (number ``iteration``): log it, list
    its changes in ``effects`` and ``it["chosen"]``; returns the card text with it."""
    log("gyrodenoise: " + "; ".join(f"{'re-fit' if rf else 'add'} {nm} {_short(pr)}"
                                     for nm, pr, rf in best.changes)
        + f": gap {g:.3g} -> {best.gap:.3g}", quiet=quiet)
    for nm, pr, rf in best.changes:
        effects.append({"name": nm, "params": None if pr is None else {k: float(v) for k, v in pr.items()},
                        "refit": rf, "why": best.why, "iteration": iteration})
    it["chosen"] = [nm for nm, _, _ in best.changes]
    return best.text


def _note_card_noisier(last: dict[str, Any], limitations: list[str]) -> None:
    """Add the limitation "the card is noisier than the record" when the last iteration
    is not within the scatter and every Allan disagreement is the record below the card."""
    if not last["within_scatter"] and any(s_ < 0 for s_ in last["where"]["allan_sign"]) \
            and not any(s_ > 0 for s_ in last["where"]["allan_sign"]):
        msg = ("the record's Allan deviation is below the card's wherever they disagree: the card is "
               "noisier than the record there; no re-fit of its terms (down, or to nothing: the "
               "'(removed)' candidates) shrank the gap enough to be accepted")
        if not any("noisier" in m_ for m_ in limitations):
            limitations.append(msg)


# ------------------------------------------------------------------ one iteration: choose a candidate
def _score(c: Candidate) -> float:
    """A candidate's score: capped gap plus the widening, times 1 + PENALTY_PER_PARAM per parameter."""
    return (c.robust + c.widen) * (1.0 + PENALTY_PER_PARAM * c.n_params)


def _candidates(ctx: _Pass, card: ModelCard, ref: Reference, z: Mapping[str, np.ndarray], it: dict[str, Any]) -> list[Candidate]:
    """The candidates of one iteration: `candidates.propose`, the joint re-fits
    (`candidates.spectral_refit`, plain and with angle Gauss-Markov terms: the
    fallback, marked ``fallback``) when the Allan or PSD signatures disagree, and only
    the constant bias when the record mean is off deterministically
    (`deterministic_offset`)."""
    cands = propose(ctx.y, ctx.layout, ref, z, card, ctx.restarts)
    if np.any(np.abs(z["allan"]) > 3.0) or np.any(np.abs(z["psd"]) > 3.0):
        for agm in (False, True):   # the fallback: tried when no single effect (or pair) will do
            sr = spectral_refit(ctx.sig_m, ctx.layout, ref, card, ctx.bands, angle_gm=agm)
            if sr is not None:
                sr.fallback = True
                cands.append(sr)
    det, off, wander = deterministic_offset(ctx.sig_m, ref, z)
    if det and any(c.name == "constant_bias" for c in cands):
        # deterministic signatures first: a mean offset far beyond the block-mean
        # wander is a constant bias, not the wander of a slow random process
        cands = [c for c in cands if c.name == "constant_bias"]
        cands[0].why += (f"; offset {off * 3600:.4g} deg/h = {abs(off) / max(wander, 1e-300):.3g} x the "
                         f"block-mean wander ({wander * 3600:.3g} deg/h rms): deterministic, explained first")
        it["deterministic_first"] = True
    return cands


def _simulate_candidate(ctx: _Pass, c: Candidate, text: str, ref: Reference, z: Mapping[str, np.ndarray],
                        limitations: list[str]) -> None:
    """Write candidate ``c`` into the card ``text`` and evaluate it by re-simulation (native
    engine): sets ``c.text``, ``c.z``, ``c.components``, ``c.gap``, ``c.widen``; a candidate
    that would write a term as 0, that the card cannot hold at the record's rate or whose gap
    is not finite is rejected (``c.z`` None, the reason in ``c.why``)."""
    zeroed = _zeroed(c.changes)
    if zeroed:
        msg = (f"the card is noisier than the record ({', '.join(zeroed)} would be set to 0); "
               f"gap writes no term fitted to 0 (removing a term is a candidate of its own, "
               f"listed as '(removed)')")
        c.why += f" (rejected: {msg})"
        if msg not in limitations:
            limitations.append(msg)
        return
    c.text = ctx.edited(text, c.changes)
    try:
        card_at_rate(c.text, ctx.fs, ctx.csrc)
    except InputError as exc:
        c.why += f" (rejected: {exc})"
        return
    cref, c.z, c.components, c.gap = ctx.evaluate(c.text, engine="native")
    c.widen = widening(cref, ref, z)
    if not math.isfinite(c.gap):
        c.why += " (rejected: non-finite gap)"
        c.z = None


def _choose(ctx: _Pass, text: str, ref: Reference, z: Mapping[str, np.ndarray], g: float, it: dict[str, Any], limitations: list[str],
            threshold: float, comp_threshold: Mapping[str, float]) -> Candidate | None:
    """The candidate accepted in this iteration, or None: every candidate simulated and
    scored (`robust_gap` over the points some candidate explains, plus
    `widening`, penalised per parameter), then the acceptance rules in turn:
    a score below MIN_IMPROVEMENT x the card's, a pair of candidates
    (`_best_pair`), the joint re-fit (`_with_fallback`), a 4x smaller plain
    gap (`_on_plain_gap`), and the card brought within the scatter
    (`_within_scatter`). Records the candidates in ``it``."""
    cands = _candidates(ctx, card_at_rate(text, ctx.fs, ctx.csrc), ref, z, it)
    for c in cands:
        _simulate_candidate(ctx, c, text, ref, z, limitations)
    ok = [c for c in cands if c.z is not None]
    zs = [c.z for c in ok if c.z is not None]
    mask = explainable([z, *zs])
    for c, cz in zip(ok, zs):
        c.robust = robust_gap(cz, mask)
        c.score = _score(c)
    ok = [c for c in ok if math.isfinite(c.score)]      # never accept a non-finite score
    it["candidates"] = [c.to_json() for c in cands]
    fallback = [c for c in ok if c.fallback]
    ok = [c for c in ok if not c.fallback]
    best = min(ok, key=lambda c: c.score) if ok else None
    rg = robust_gap(z, mask)
    it["unexplained_points"] = {c_: int(np.sum(~mask[c_])) for c_ in COMPONENTS}
    it["robust_gap"] = rg
    if best is not None and best.score > MIN_IMPROVEMENT * rg and len(ok) >= 2:
        best = _best_pair(ctx, ok, best, ref, z, mask, it)
    best, ok = _with_fallback(fallback, best, ok, g, rg)
    best = _on_plain_gap(ok, best, g, rg)
    accepted = best is not None and math.isfinite(rg) and (best.score <= MIN_IMPROVEMENT * rg
                                                            or best.gap <= 0.25 * g)
    if not accepted and (ctx.stop_bands != "auto" or not _top_disagrees(z)):
        best, accepted = _within_scatter(ok + fallback, best, g, rg, threshold, comp_threshold)
    return best if accepted else None


def _best_pair(ctx: _Pass, ok: list[Candidate], best: Candidate, ref: Reference, z: Mapping[str, np.ndarray], mask: Mapping[str, np.ndarray],
               it: dict[str, Any]) -> Candidate:
    """No single effect shrinks the gap significantly: look one step ahead, pairs of the
    three best-scoring candidates (two effects that only together explain a signature,
    e.g. a bias and a ramp that offset each other's mean). The best pair replaces
    ``best`` when its score is below MIN_IMPROVEMENT x ``best``'s; recorded in ``it``."""
    top = sorted(ok, key=lambda c: c.score)[:3]
    pairs = []
    for i, a in enumerate(top):
        for b in top[i + 1:]:
            if a.name == b.name or _zeroed(b.changes):
                continue
            pc = Candidate(a.name, a.params, a.refit, f"{a.why}; together with {b.name}",
                           extra=a.extra + b.changes)
            pc.text = ctx.edited(a.text, b.changes)
            try:
                card_at_rate(pc.text, ctx.fs, ctx.csrc)
            except InputError:
                continue
            pref, pz, pc.components, pc.gap = ctx.evaluate(pc.text, engine="native")
            pc.robust = robust_gap(pz, mask)
            pc.widen = widening(pref, ref, z)
            pc.score = _score(pc)
            if math.isfinite(pc.score) and math.isfinite(pc.gap):
                pairs.append(pc)
    it["pairs"] = [c.to_json() for c in pairs]
    bp = min(pairs, key=lambda c: c.score) if pairs else None
    return bp if bp is not None and bp.score < MIN_IMPROVEMENT * best.score else best


def _with_fallback(fallback: list[Candidate], best: Candidate | None, ok: list[Candidate], g: float,
                   rg: float) -> tuple[Candidate | None, list[Candidate]]:
    """The joint re-fit (with or without angle Gauss-Markov terms) when no candidate is
    accepted on its score: it replaces ``best`` when it scores better or brings the
    plain gap to a quarter, and it is accepted when it halves the plain gap
    (FALLBACK_GAIN) and is no worse capped, although its many parameters cost it the
    penalised score. Returns (best, ok with the fallback candidates when considered)."""
    if fallback and (best is None or not (math.isfinite(rg) and best.score <= MIN_IMPROVEMENT * rg)):
        fb = min(fallback, key=lambda c: c.score)
        if best is None or fb.score < best.score or fb.gap <= 0.25 * min(g, best.gap):
            best = fb
        ok = ok + fallback
        if fb.gap <= FALLBACK_GAIN * g and fb.robust + fb.widen <= rg and best is fb:
            fb.why += f" (accepted: plain gap {g:.3g} -> {fb.gap:.3g}, capped no worse)"
            fb.score = min(fb.score, MIN_IMPROVEMENT * rg)
    return best, ok


def _on_plain_gap(ok: list[Candidate], best: Candidate | None, g: float, rg: float) -> Candidate | None:
    """Every capped point stays capped (|z| > 5 everywhere, e.g. a card far from a long
    real record): the capped score cannot see progress; the candidate that shrinks the
    plain gap most, by at least 4x, is taken when it is no worse capped."""
    if best is None or not (math.isfinite(rg) and best.score <= MIN_IMPROVEMENT * rg):
        big = [c for c in ok if math.isfinite(c.gap) and c.gap <= 0.25 * g
               and c.robust + c.widen <= rg]
        if big:
            best = min(big, key=lambda c: c.gap)
            best.why += f" (accepted on the plain gap: {g:.3g} -> {best.gap:.3g}; the capped score saturates)"
    return best


def _within_scatter(cands: list[Candidate], best: Candidate | None, g: float, rg: float, threshold: float,
                    comp_threshold: Mapping[str, float]) -> tuple[Candidate | None, bool]:
    """The loop's own stop test: a candidate that brings the card within the scatter (its
    gap and every component below their thresholds), no worse capped with the widening
    charged, is accepted although its score gains less than the rule asks. Not applied
    while the top of the band still disagrees in the first pass (`_choose`): that
    band is taken out next (`gap`), and the card is judged without it. Returns
    (best, accepted)."""
    inside = [c for c in {id(c): c for c in cands}.values()
              if c.gap <= threshold and c.components is not None
              and all(c.components[k] <= comp_threshold[k] for k in COMPONENTS)
              and c.robust + c.widen <= rg]
    if not inside:
        return best, False
    best = min(inside, key=lambda c: c.score)
    best.why += f" (accepted: within the scatter, gap {g:.3g} -> {best.gap:.3g}, capped no worse)"
    return best, True


def white_level_factor(y: np.ndarray, fs: float, card: ModelCard, bands: Sequence[tuple[float, float]] = ()) -> float:
    """The factor ``s`` by which the card's white noise (N and the Gauss-Markov terms
    with tau < 2 samples, which act as white noise) would be scaled to fit record ``y``,
    every other term held: weighted least squares (``s^2 >= 0``) of the record's Allan
    variance at the octave taus, through the stop bands, on the exact columns of
    `spectral`, with the analytic 1-sigma of one record as the weights."""
    from gyrodenoise.modelgap.metric import _floors
    from gyrodenoise.modelgap.spectral import allan_columns, stochastic_specs
    layout = Layout.for_record(len(y), fs)
    sig = signature(band_stop(y, fs, bands), layout)
    specs, coef = stochastic_specs(card)
    if not specs:
        return 1.0
    cols = allan_columns(specs, layout.m, fs, bands)
    white = np.array([_acts_as_white(nm, tc, fs) for nm, tc in specs])
    a_w, a_rest = cols[:, white] @ coef[white], cols[:, ~white] @ coef[~white]
    w = 1.0 / (2.0 * sig["avar"] * _floors(sig, layout)["allan"]) ** 2
    if not np.any(a_w > 0):
        return 1.0
    s2 = float(np.sum(w * a_w * (sig["avar"] - a_rest)) / np.sum(w * a_w * a_w))
    return math.sqrt(max(s2, 0.0))


def _acts_as_white(name: str, tau_s: float | None, fs: float) -> bool:
    """N, and a Gauss-Markov term shorter than 2 samples: the terms that act as white noise."""
    return name == "angle_random_walk" or (name == "gauss_markov" and tau_s is not None and tau_s < 2.0 / fs)


def _scale_white(text: str, card: ModelCard, s: float, fs: float, note: str) -> str:
    """The card text with its white noise (see `white_level_factor`) scaled by ``s``."""
    from gyrodenoise.modelgap.population import noise_terms, with_magnitudes
    terms = noise_terms(card)
    factors = [s if _acts_as_white(nm, p.get("tau", 0.0), fs) else 1.0 for nm, _, p in terms]
    return with_magnitudes(text, card, factors, [p.get("spread") for _, _, p in terms], note)


def _heldout_population(y: np.ndarray, fs: float, text: str, bands: Sequence[tuple[float, float]], seed_list: list[int], n_train: int,
                        source: str) -> GapResult:
    """One evaluation of record ``y`` (no fitting) against a reference whose simulation ``j``
    is card ``j`` of `population.bootstrap_cards` (the card re-estimated on a simulated
    training record of ``n_train`` samples) simulated with seed ``j``: a prediction interval."""
    from gyrodenoise.modelgap.effects import name_effects
    from gyrodenoise.modelgap.population import bootstrap_cards, relative_error
    layout = Layout.for_record(y.shape[0], fs)
    texts, factors = bootstrap_cards(text, fs, n_train, seed_list, bands, "<fitted card>")
    sims = [Simulator(y.shape[0], fs, [s_], source="<fitted card>").run(t_)[0] for t_, s_ in zip(texts, seed_list)]
    sig_m = signature(band_stop(y, fs, bands), layout)
    ref, z, comp, g = _evaluate(sims, sig_m, layout, bands)
    threshold, comp_threshold = _thresholds(ref)
    within = g <= threshold and all(comp[c] <= comp_threshold[c] for c in COMPONENTS)
    it = {"card_gap": g, "components": comp, "where": where_disagree(z, layout), "_ref": ref, "_z": z,
          "candidates": [], "within_scatter": bool(within),
          "stop": "within the simulations' scatter" if within else "max_effects reached"}
    bumps = [(lo, hi, float("nan")) for lo, hi in bands]
    res = GapResult(effects_added=[], gap_before=g, gap_after=g, card_text=text, iterations=[it],
                    threshold=threshold, engine="native", component_threshold=comp_threshold, seeds=seed_list,
                    layout=layout, measured=sig_m, stop_bands=bumps,
                    named=name_effects(y, fs, card_at_rate(text, fs, "<fitted card>"), bumps, None))
    res.card_error = [float(v) for v in relative_error(factors)]
    res.named.insert(0, f"held out against the card's prediction interval: each of the {len(seed_list)} "
                        f"simulations from the card re-estimated on a simulated training record of {int(n_train)} "
                        f"samples (parametric bootstrap of the card's own estimation error)")
    return res


def heldout_gap(rate_deg_s: npt.ArrayLike, sample_rate_hz: float, card_text: str,
                stop_bands: Sequence[Sequence[float]] | None = (),
                seeds: int | Sequence[int] = 4, refit_bias: bool = True, source: str = "HELD-OUT",
                outliers: bool = False, refit_white: bool = False, card_error: bool = False,
                n_train: int | None = None) -> GapResult:
    """The gap of an already fitted card on ANOTHER record of the same sensor (nothing added).

    With ``refit_bias`` the card's constant bias is first set to this record's mean:
    a turn-on bias differs from run to run (its spread is the term's
    ``repeatability``), the card's noise is what is checked. The same stop bands
    as in the fit. Returns the `GapResult` of that single evaluation
    (``within_scatter``, ``gap_after``, ``threshold``).

    ``refit_white`` (an option, NOT the default held-out check): the card's white-noise
    level is also re-fitted to this record, every other term held
    (`white_level_factor`; N and the Gauss-Markov terms shorter than 2 samples
    scaled by one factor, reported in ``named``). This checks the card's SHAPE - its
    correlated terms, filter, bands - on a run whose white-noise level differs (a
    sensor's ARW varies from run to run and unit to unit, like its turn-on bias); it
    is a weaker check than the plain held-out gap, with one more parameter fitted to
    the held-out record.

    ``card_error`` (an option, NOT the default): the reference is a prediction interval
    that includes the card's own estimation error (`_heldout_population`): simulation
    ``j`` comes from the card re-estimated on a simulated training record of ``n_train``
    samples (default: as long as this record; give the length of the record the card was
    fitted on). Nothing is fitted to the held-out record (but its bias, as above).

    The card's ``spread`` fields (relative 1-sigma of a term's magnitude between units,
    `population`), when it has them, are drawn per simulation in every case: the
    reference is then the population of units, not one unit. The default held-out check
    (no option) is the plain one: the card as written, S seeded simulations."""
    from gyrodenoise.simulator import parse_card
    y = check_record(rate_deg_s, source)
    if outliers:
        from gyrodenoise.modelgap.effects import screen_outliers
        y = screen_outliers(y)[0]
    text = card_text
    if refit_bias:
        card = parse_card(text, "<fitted card>")
        params = dict(card.terms.get("constant_bias", {}))
        params["value"] = float(np.mean(y)) * 3600.0
        text = edit_card(text, "constant_bias", params, "constant_bias" in card.terms,
                         f"this record's mean ({Path(str(source)).name})")
    bands = [(lo, hi) for lo, hi, *_ in stop_bands or ()]
    factor = None
    if refit_white:
        card = parse_card(text, "<fitted card>")
        factor = white_level_factor(y, float(sample_rate_hz), card, bands)
        text = _scale_white(text, card, factor, float(sample_rate_hz),
                            f"white-noise level re-fitted to {Path(str(source)).name} (x{factor:.4g})")
    if card_error:
        res = _heldout_population(y, float(sample_rate_hz), text, bands, _seed_list(seeds),
                                  len(y) if n_train is None else int(n_train), source)
    else:
        res = _gap_once(y, sample_rate_hz, parse_card(text, "<fitted card>"), seeds=seeds, max_effects=0,
                        source=source, stop_bands=bands)
    if factor is not None:
        res.named.insert(0, f"held out with the white-noise level re-fitted (an option, one parameter fitted to "
                            f"this record): the card's white noise x {factor:.4g}")
    res.white_factor = factor
    return res
