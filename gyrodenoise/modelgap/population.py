"""A card as a population: the spread of its noise terms between units or runs, and the
error of a card estimated from one finite record (for the held-out check, `heldout_gap`).

Two things make a held-out record differ from a card fitted on another record beyond the
simulations' own scatter:

* the units (or runs) differ: a term's ``spread`` (relative 1-sigma of its magnitude;
  `SPREAD_FIELDS`) is drawn per simulated record, ``magnitude * exp(spread * z)``,
  ``z ~ N(0, 1)`` from a generator seeded by ``(SPREAD_STREAM, seed)``, in the layer that
  builds the reference (`simulation.Simulator`); the simulator itself (C core,
  FMUs) simulates the card's values. A card without ``spread`` keeps its realisations bit
  for bit (its text is simulated unchanged).
* the card was itself estimated from one record: `bootstrap_cards` re-estimates the
  card's term magnitudes on simulated training records of the card (a parametric bootstrap),
  so the held-out reference is a prediction interval, not a confidence interval.

The magnitudes are re-fitted by weighted non-negative least squares of the Allan variance
(octave taus) and the Welch-band PSD on the card's OWN terms (their correlation times held),
on the exact columns of `spectral`, with the analytic 1-sigma of one record as the
weights (`MagnitudeFit`). A term's spread is estimated where it (or its
``spread_group``) makes most of the card's signature (`estimate_spread`), from
training records that never include the record to be checked.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from gyrodenoise.modelgap.cards import card_at_rate, edit_card
from gyrodenoise.units import NOISE_SECTIONS, TERM_BY_SECTION

if TYPE_CHECKING:
    from gyrodenoise.modelgap.metric import Layout, Signature
    from gyrodenoise.simulator import ModelCard

SPREAD_STREAM = 952          # first word of the spread draws' seed (IEEE Std 952): numpy default_rng([952, seed])
DOMINANT_SHARE = 0.8         # a term's spread is estimated where it makes more than 80 % of the card's signature
TRAIN_SEED_OFFSET = 2 ** 40  # the bootstrap's simulated training records: seeds 2^40 + seed
# term -> the field that carries its magnitude (what ``spread`` scales)
SPREAD_FIELDS = {**{nm: TERM_BY_SECTION[nm].symbol for nm in NOISE_SECTIONS},
                 "gauss_markov": "sigma", "angle_gauss_markov": "sigma"}


def noise_terms(card: ModelCard) -> list[tuple[str, int | None, dict[str, float]]]:
    """The card's noise terms with a magnitude, in the order of `spectral.stochastic_specs`:
    list of ``(name, index, params)`` (``index`` within a repeatable term, else None)."""
    out: list[tuple[str, int | None, dict[str, float]]] = []
    for nm in NOISE_SECTIONS:
        if card.terms.get(nm):
            out.append((nm, None, card.terms[nm]))
    for nm in ("gauss_markov", "angle_gauss_markov"):
        out += [(nm, i, p) for i, p in enumerate(card.term_list(nm))]
    return out


def with_magnitudes(text: str, card: ModelCard, factors: Sequence[float] | np.ndarray, spreads: Iterable[float | None] | None = None,
                    note: str = "drawn unit", groups: Mapping[int, int] | None = None) -> str:
    """The card text with each noise term's magnitude multiplied by ``factors[i]`` (order of
    `noise_terms`) and its ``spread`` set to ``spreads[i]`` (None: the field dropped,
    a value <= 0 too) and, given ``groups`` ({index: group id}), its ``spread_group``.
    Every other term and field is kept."""
    terms = noise_terms(card)
    spreads = [None] * len(terms) if spreads is None else list(spreads)
    rep: dict[str, list[dict[str, float]]] = {}
    for i, ((nm, idx, p), f, s) in enumerate(zip(terms, factors, spreads)):
        fld = SPREAD_FIELDS[nm]
        new = {k: v for k, v in p.items() if k != "spread"}
        new[fld] = p[fld] * float(f)
        if s is not None and s > 0:
            new["spread"] = float(s)
        if groups and i in groups:
            new["spread_group"] = float(groups[i])
        if idx is None:
            text = edit_card(text, nm, new, True, note)
        else:
            rep.setdefault(nm, []).append(new)
    for nm, items in rep.items():
        text = edit_card(text, nm, None, True, note)
        for new in items:
            text = edit_card(text, nm, new, False, note)
    return text


def draw_unit(text: str, seed: int, source: str = "<card>") -> str:
    """The card text of one simulated unit: each noise term's magnitude times
    ``exp(spread * z)``, ``z ~ N(0, 1)`` drawn in the order of `noise_terms` (one draw
    per term, spread or not) from ``numpy.random.default_rng([SPREAD_STREAM, seed])``; terms
    with the same ``spread_group`` (> 0) all take the draw of the first of them (their
    magnitudes move together: a group of terms that only together make a part of the signature).
    A card with no ``spread`` field is returned unchanged (its realisations stay bit for bit)."""
    if "spread" not in text:
        return text
    from gyrodenoise.simulator import parse_card
    card = parse_card(text, source)
    terms = noise_terms(card)
    sp = np.array([p.get("spread", 0.0) for _, _, p in terms])
    if not np.any(sp > 0):
        return text
    z = np.random.default_rng([SPREAD_STREAM, int(seed)]).standard_normal(len(terms))
    first: dict[float, int] = {}
    for i, (_, _, p) in enumerate(terms):     # a spread_group shares the draw of its first term
        g = p.get("spread_group", 0.0)
        if g > 0:
            z[i] = z[first.setdefault(g, i)]
    return with_magnitudes(text, card, np.exp(sp * z), None, f"unit drawn for seed {int(seed)}")


class MagnitudeFit:
    """Weighted NNLS of a record's Allan variance and Welch bands on a card's own noise terms
    (correlation times held): `coefficients` of a record, in the s-based squared units of
    `spectral.stochastic_specs`. The columns are computed once per card and layout."""

    def __init__(self, card: ModelCard, layout: Layout, bands: Sequence[tuple[float, float]] = ()) -> None:
        from gyrodenoise.modelgap.spectral import allan_columns, band_columns, stochastic_specs
        self.layout, self.bands = layout, list(bands)
        self.specs, self.coef = stochastic_specs(card)
        self.A_a = allan_columns(self.specs, layout.m, layout.fs, self.bands)
        self.A_p, self.clear = band_columns(self.specs, layout, self.bands)

    def _weighted(self, sig: Signature) -> tuple[np.ndarray, np.ndarray]:
        """(A, b): the columns and the record's Allan variance and clear Welch bands, each row
        divided by the analytic 1-sigma of one record."""
        from gyrodenoise.modelgap.metric import _floors
        fl = _floors(sig, self.layout)
        e = self.layout.band_edges
        psd = np.array([sig["psd_bins"][e[i]:e[i + 1]].mean() for i in range(len(e) - 1)])
        sd_a, sd_p = 2.0 * sig["avar"] * fl["allan"], psd * fl["psd"]
        A = np.vstack([self.A_a / sd_a[:, None], (self.A_p / sd_p[:, None])[self.clear]])
        b = np.concatenate([sig["avar"] / sd_a, (psd / sd_p)[self.clear]])
        return A, b

    def coefficients(self, sig: Signature) -> np.ndarray:
        """Squared magnitudes fitted jointly to one record's signature (``metric.signature``)."""
        from gyrodenoise.modelgap.spectral import _nnls_huber
        return _nnls_huber(*self._weighted(sig), 0)[0]

    def group_factors(self, sig: Signature, groups: Iterable[list[int]]) -> np.ndarray:
        """Each GROUP of terms (lists of term indices, `noise_terms` order) re-fitted alone
        to one record by one common factor on its squared magnitudes, on the points where the
        group makes more than DOMINANT_SHARE of the card's own Allan variance or band PSD, every
        other term held at the card's value (weighted least squares of one number, >= 0).
        Well conditioned where the joint fit is not (a dictionary card's terms trade off
        against each other). A group that dominates nowhere keeps factor 1 (its spread cannot
        be told from the data). Returns the squared-magnitude factor of each group."""
        A, b = self._weighted(sig)
        r = b - A @ self.coef
        cols = np.vstack([self.A_a, self.A_p[self.clear]])
        tot = cols @ self.coef
        out: list[float] = []
        for g in groups:
            d = A[:, g] @ self.coef[g]
            part = cols[:, g] @ self.coef[g]
            dm = np.where(part > DOMINANT_SHARE * np.maximum(tot, 1e-300), d, 0.0)
            den = float(dm @ dm)
            out.append(max(1.0 + float(dm @ r) / den, 0.0) if den > 0 else 1.0)
        return np.array(out)


def bootstrap_cards(text: str, fs: float, n_train: int, seeds: Iterable[int], bands: Sequence[tuple[float, float]] = (),
                    source: str = "<card>") -> tuple[list[str], np.ndarray]:
    """One card per seed, re-estimated from a simulated training record of ``n_train`` samples
    (a parametric bootstrap of the card's estimation error): the card's noise-term magnitudes
    re-fitted (`MagnitudeFit`) to the simulation of the card (one drawn unit,
    `draw_unit`) with seed ``TRAIN_SEED_OFFSET + seed`` (streams the held-out reference
    does not use). Each bootstrap card is the card as it would have come out of that training
    record: its expected signatures are the card's plus the fit's error (several terms of a
    dictionary card trade off against each other, so the single magnitudes swing much more
    than the signatures they add up to). Returns ``(texts, factors)``: the per-seed card texts
    (the card's ``spread`` kept) and the amplitude factors ``sqrt(c_j / c)`` (rows: seeds;
    columns: `noise_terms`; a term the card has at 0 stays 0)."""
    from gyrodenoise.simulator import simulate
    from gyrodenoise.modelgap.metric import Layout, signature
    from gyrodenoise.modelgap.spectral import band_stop
    card = card_at_rate(text, fs, source)
    layout = Layout.for_record(int(n_train), fs)
    fit = MagnitudeFit(card, layout, bands)
    c0 = fit.coef
    sp = [p.get("spread") for _, _, p in noise_terms(card)]
    texts: list[str] = []
    factors: list[np.ndarray] = []
    for s in seeds:
        ts = TRAIN_SEED_OFFSET + int(s)
        y = simulate(card_at_rate(draw_unit(text, ts, source), fs, source), int(n_train), seed=ts).rate_deg_s
        cj = fit.coefficients(signature(band_stop(y, fs, bands), layout))
        f = np.sqrt(np.where(c0 > 0, cj, 0.0) / np.where(c0 > 0, c0, 1.0))
        factors.append(f)
        texts.append(with_magnitudes(text, card, f, sp, f"re-estimated on a simulated training record "
                                                        f"(bootstrap seed {int(s)})"))
    return texts, np.array(factors)


def estimate_spread(records: Sequence[np.ndarray], fs: float, text: str, bands: Sequence[tuple[float, float]] = (),
                    seeds: Iterable[int] = range(1, 17), source: str = "<card>",
                    groups: Sequence[list[int]] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Relative 1-sigma spread of each noise term's magnitude between ``records`` (training
    records: never the record to be checked), net of the estimator's own error.

    Each term's amplitude ``a = sqrt(c)`` is re-fitted on each record alone, where it
    dominates the card, the other terms held (`MagnitudeFit.group_factors`; with
    ``groups``, lists of term indices, one common factor per group, the group's spread
    given to each of its terms: write them with one ``spread_group``), over the records'
    common length ``n``;
    ``between = std(a / a_card, ddof=1)``. The same estimator on simulations of the card
    itself (``seeds``, length ``n``) gives its own error ``est``; the spread is
    ``sqrt(max(between^2 - est^2, 0))`` (method of moments: what the records differ by
    beyond what one record's estimate scatters). Returns ``(spread, between, est, factors)``
    (factors: ``a / a_card``, rows records, columns `noise_terms`; terms in no group
    get 0 and factor 1)."""
    from gyrodenoise.simulator import simulate
    from gyrodenoise.modelgap.metric import Layout, signature
    from gyrodenoise.modelgap.spectral import band_stop
    if len(records) < 2:
        raise ValueError("estimate_spread needs at least two training records")
    card = card_at_rate(text, fs, source)
    n = min(len(r) for r in records)
    layout = Layout.for_record(n, fs)
    fit = MagnitudeFit(card, layout, bands)
    groups = [[i] for i in range(len(fit.coef))] if groups is None else [list(g) for g in groups]
    member = np.zeros((len(groups), len(fit.coef)))
    for k, g in enumerate(groups):
        member[k, g] = 1.0

    def factors(ys: Iterable[np.ndarray]) -> np.ndarray:
        return np.array([np.sqrt(fit.group_factors(signature(band_stop(np.asarray(y[:n], float), fs, bands),
                                                             layout), groups)) @ member
                         + (1.0 - member.sum(axis=0)) for y in ys])
    f_rec = factors(records)
    f_sim = factors(simulate(card, n, seed=TRAIN_SEED_OFFSET + int(s)).rate_deg_s for s in seeds)
    between, est = f_rec.std(axis=0, ddof=1), f_sim.std(axis=0, ddof=1)
    return np.sqrt(np.maximum(between ** 2 - est ** 2, 0.0)), between, est, f_rec


def spread_text(text: str, spread: Sequence[float] | np.ndarray, source: str = "<card>",
                note: str = "spread between the training records",
                groups: Iterable[list[int]] | None = None) -> str:
    """The card text with each noise term's ``spread`` set (order of `noise_terms`) and,
    for each of ``groups`` with more than one term, ``spread_group = k`` (k = 1, 2, ...)."""
    from gyrodenoise.simulator import parse_card
    card = parse_card(text, source)
    gid: dict[int, int] = {}
    for k, g in enumerate(groups or ()):
        if len(g) > 1:
            gid.update({i: k + 1 for i in g})
    return with_magnitudes(text, card, np.ones(len(spread)), [float(s) for s in spread], note, gid)


def groups_by_tau(card: ModelCard, fs: float, edges_s: Sequence[float] = (10.0,)) -> list[list[int]]:
    """Groups of the card's noise terms (lists of indices, `noise_terms` order) for
    `estimate_spread`: the terms that act as white noise (Gauss-Markov tau < 2 samples),
    N, Q, B and K each alone; the other Gauss-Markov and angle Gauss-Markov terms by their
    correlation time, split at ``edges_s``."""
    groups: dict[tuple[str, int], list[int]] = {}
    for i, (nm, _, p) in enumerate(noise_terms(card)):
        if "tau" not in p or (nm == "gauss_markov" and p["tau"] < 2.0 / fs):
            groups[("alone", i)] = [i]
        else:
            groups.setdefault(("tau", int(np.searchsorted(np.asarray(edges_s, float), p["tau"]))), []).append(i)
    return list(groups.values())


def relative_error(factors: npt.ArrayLike) -> np.ndarray:
    """Relative 1-sigma of each magnitude over bootstrap factors (rows seeds)."""
    f = np.asarray(factors, float)
    return f.std(axis=0, ddof=1) if f.shape[0] > 1 else np.zeros(f.shape[1])
