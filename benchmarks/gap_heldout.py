"""Fit a card on ADIS16405 imu1, then check it on the five other records (docs/GAP.md, held-out table).

The card is fitted from an empty card on imu1 (``gyrodenoise.gap``, native engine, 4 seeds,
``--outliers``); on each of imu2..imu6 the fitted card is evaluated once, nothing added, its
constant bias set to that record's mean (:func:`gyrodenoise.modelgap.heldout_gap`), with the
stop bands of the fit. Printed: gap, scatter threshold, within_scatter and the components,
and the record's Allan deviation at tau 0.01, 1 and 100 s divided by imu1's (with the
estimate's own 1-sigma relative error: how far the noise LEVEL differs between runs).

With ``--refit-white`` each record is also checked with the card's white-noise level
re-fitted to it, every other term held (``heldout_gap(refit_white=True)``: an option, one
parameter fitted to the held-out record; the factor is printed).

With ``--population`` the card is checked as a population (:mod:`gyrodenoise.modelgap.population`,
8 seeds): the spread of its noise terms is estimated on the TRAINING records imu1..imu3
(``estimate_spread``, printed) and written into the card; imu4..imu6 (held out, never used for
the spread) are checked (a) with the card's estimation error only (``card_error=True``,
n_train = imu1's length), (b) with the spread only, (c) with both. With ``--loo`` each of
imu2..imu6 is checked (both ingredients) against the spread estimated on the other five records.
``--first-seed=K``, ``--pop-seeds=S``: the population checks use seeds K..K+S-1 (default 1, 8).
``--groups``: the spread estimated per group of terms (``groups_by_tau``: the white-noise terms
alone, the other Gauss-Markov terms split at tau 10 s), each group drawn as one (``spread_group``).

Run: .venv/bin/python benchmarks/gap_heldout.py [N_SAMPLES] [AXIS] [--refit-white] [--population] [--loo]
[--first-seed=K] [--pop-seeds=S] [--groups]
(default 1000000 gyro_x; about 1 minute on an idle 2-core box, about 1 more with --population)
"""

from __future__ import annotations

import sys
import time
from _data import SHARED_DATA

STATIC = SHARED_DATA / "static"
EMPTY = "[sensor]\nname = \"empty\"\nsample_rate_hz = 100.0\n"


def main(*argv):
    white, popu, loo = "--refit-white" in argv, "--population" in argv, "--loo" in argv
    grouped = "--groups" in argv
    opt = {k: int(a.split("=", 1)[1]) for a in argv for k in ("--first-seed", "--pop-seeds") if a.startswith(k + "=")}
    argv = [a for a in argv if not a.startswith("--")]
    n, axis = int(argv[0]) if argv else 1000000, argv[1] if len(argv) > 1 else "gyro_x"
    if not (STATIC / "adis16405_imu1.csv.gz").exists():
        print(f"skipped: {STATIC} not present")
        return 0
    import gyrodenoise as gd
    from gyrodenoise.modelgap import heldout_gap
    from gyrodenoise.io.recording import read_recording
    from gyrodenoise.simulator import parse_card

    def rec(i):
        return read_recording(STATIC / f"adis16405_imu{i}.csv.gz", rate_column=axis).rate_deg_s[:n]
    t = time.perf_counter()
    res = gd.gap(rec(1), 100.0, parse_card(EMPTY), seeds=4, outliers=True)
    print(f"fit on imu1: gap {res.gap_before:.4g} -> {res.gap_after:.4g}, threshold {res.threshold:.3g}, "
          f"within {res.within_scatter}, stop bands {[(round(a, 3), round(b, 3)) for a, b, _ in res.stop_bands]}"
          f" ({time.perf_counter() - t:.1f} s)")
    import numpy as np

    from gyrodenoise.analysis.allan import adev
    m_lvl = np.array([1, 100, 10000])        # tau 0.01, 1, 100 s

    def level(y):
        _, ad, err, _ = adev(y, 100.0, m=m_lvl)
        return ad, err / ad
    ad1, _ = level(rec(1))
    for i in range(2, 7):
        t = time.perf_counter()
        y = rec(i)
        h = heldout_gap(y, 100.0, res.card_text, res.stop_bands, seeds=4, outliers=True, source=f"imu{i}")
        comp = {k: round(v, 2) for k, v in h.iterations[-1]["components"].items()}
        ad, rel = level(y)
        lv = ", ".join(f"{r:.4f} +- {e:.4f}" for r, e in zip(ad / ad1, rel))
        print(f"imu{i}: gap {h.gap_after:.4g}, threshold {h.threshold:.3g}, within {h.within_scatter}, {comp} "
              f"({time.perf_counter() - t:.1f} s); ADEV / imu1's at tau 0.01, 1, 100 s: {lv}", flush=True)
        if white:
            h = heldout_gap(y, 100.0, res.card_text, res.stop_bands, seeds=4, outliers=True, source=f"imu{i}",
                            refit_white=True)
            comp = {k: round(v, 2) for k, v in h.iterations[-1]["components"].items()}
            print(f"      white-noise level re-fitted (x{h.white_factor:.4f}): gap {h.gap_after:.4g}, threshold "
                  f"{h.threshold:.3g}, within {h.within_scatter}, {comp}", flush=True)
    if popu or loo:
        population(res, rec, n, popu, loo, opt.get("--first-seed", 1), opt.get("--pop-seeds", 8), grouped)
    return 0


def _line(tag, h):
    comp = {k: round(v, 2) for k, v in h.iterations[-1]["components"].items()}
    return f"{tag}: gap {h.gap_after:.4g}, threshold {h.threshold:.3g}, within {h.within_scatter}, {comp}"


def population(res, rec, n, popu, loo, first_seed=1, n_seeds=8, grouped=False):
    """The held-out check with the card's estimation error and the spread of its terms
    (seeds first_seed .. first_seed + n_seeds - 1)."""
    seeds = list(range(first_seed, first_seed + n_seeds))

    from gyrodenoise.modelgap import heldout_gap
    from gyrodenoise.modelgap.effects import screen_outliers
    from gyrodenoise.modelgap.population import estimate_spread, groups_by_tau, noise_terms, spread_text
    from gyrodenoise.simulator import parse_card
    bands = [(lo, hi) for lo, hi, _ in res.stop_bands]
    ys = {i: rec(i) for i in range(1, 7)}
    clean = {i: screen_outliers(y)[0] for i, y in ys.items()}
    groups = groups_by_tau(parse_card(res.card_text), 100.0) if grouped else None
    if grouped:
        print(f"spread groups (noise_terms indices; tau split at 10 s): {groups}")
    names = [f"{nm}{'' if i is None else f'[{i}]'}" + (f"(tau {p['tau']:.3g} s)" if "tau" in p else "")
             for nm, i, p in noise_terms(parse_card(res.card_text))]

    def check(i, text, tag, **kw):
        t = time.perf_counter()
        h = heldout_gap(ys[i], 100.0, text, res.stop_bands, seeds=seeds, outliers=True, source=f"imu{i}", **kw)
        print(_line(f"imu{i} {tag} (seeds {seeds[0]}..{seeds[-1]})", h) + f" ({time.perf_counter() - t:.1f} s)",
              flush=True)
        return h
    if popu:
        t = time.perf_counter()
        spread, between, est, _ = estimate_spread([clean[i] for i in (1, 2, 3)], 100.0, res.card_text, bands,
                                                  groups=groups)
        print(f"spread from the training records imu1..imu3 ({time.perf_counter() - t:.1f} s): " + ", ".join(
            f"{nm} {s_:.4g} (between {b:.4g}, own error {e:.4g})" for nm, s_, b, e in zip(names, spread, between, est)
            if b > 0))
        wide = spread_text(res.card_text, spread, groups=groups)
        for i in (4, 5, 6):
            h = check(i, res.card_text, "card error only", card_error=True, n_train=n)
            if i == 4:
                print("      bootstrap relative error of each magnitude: " + ", ".join(
                    f"{nm} {e:.3g}" for nm, e in zip(names, h.card_error)))
            check(i, wide, "spread only")
            check(i, wide, "spread + card error", card_error=True, n_train=n)
    if loo:
        for i in range(2, 7):
            others = [clean[j] for j in range(1, 7) if j != i]
            spread, *_ = estimate_spread(others, 100.0, res.card_text, bands, groups=groups)
            sp = ", ".join(f"{nm} {s_:.3g}" for nm, s_ in zip(names, spread) if s_ > 0) or "none"
            check(i, spread_text(res.card_text, spread, groups=groups), f"leave-one-out spread [{sp}] + card error",
                  card_error=True, n_train=n)
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
