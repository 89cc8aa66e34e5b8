"""A card as a population (gyrodenoise.modelgap.population): a noise term's ``spread``
(drawn per simulated unit by the gap reference) and the card's own estimation error
(parametric bootstrap) in the held-out check. Known-truth simulations, seeded; the
numbers behind each tolerance are in the docstrings. The real ADIS16405 figures are
in docs/bench/gap.md (the gap_heldout study, docs/reports/studies.md)."""

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.errors import InputError
from gyrodenoise.modelgap import heldout_gap
from gyrodenoise.modelgap.metric import Layout, signature
from gyrodenoise.modelgap.population import (
    MagnitudeFit,
    draw_unit,
    estimate_spread,
    noise_terms,
    with_magnitudes,
)
from gyrodenoise.modelgap.simulation import Simulator
from gyrodenoise.simulator import parse_card

FS = 100.0
CARD = """[sensor]
name = "population test"
sample_rate_hz = 100.0

[terms]
angle_random_walk = { N = 0.1 }     # deg/sqrt(h)

[[terms.gauss_markov]]
sigma = 20.0
tau = 30.0
"""


def _spread_card(n_spread, gm_spread=None, gm_tau=30.0):
    text = CARD.replace("N = 0.1 }", f"N = 0.1, spread = {n_spread} }}").replace("tau = 30.0", f"tau = {gm_tau}")
    return text if gm_spread is None else text.replace(f"tau = {gm_tau}\n", f"tau = {gm_tau}\nspread = {gm_spread}\n")


def test_spread_is_a_checked_optional_field_of_the_noise_terms():
    card = parse_card(_spread_card(0.05, 0.2))
    assert card.terms["angle_random_walk"]["spread"] == 0.05
    assert card.term_list("gauss_markov")[0]["spread"] == 0.2
    with pytest.raises(InputError, match=r"terms.angle_random_walk.spread must be >= 0"):
        parse_card(_spread_card(-0.1))
    with pytest.raises(InputError, match=r"unknown field terms.constant_bias.spread"):
        parse_card(CARD + "\n[terms.constant_bias]\nvalue = 1.0\nspread = 0.1\n")


def test_a_card_without_spread_keeps_its_realisations_bit_for_bit():
    """The reference layer changes nothing for a card without ``spread`` (nor with
    spread 0): the simulations equal simulate(card, seed) exactly."""
    sim = Simulator(4096, FS, [1, 2, 3])
    direct = [gd.simulate(parse_card(CARD), 4096, seed=s).rate_deg_s for s in (1, 2, 3)]
    for text in (CARD, _spread_card(0.0)):
        assert draw_unit(text, 1) == text
        for a, b in zip(sim.run(text), direct):
            assert np.array_equal(a, b)


def test_spread_draws_one_unit_per_seed_with_the_stated_distribution():
    """spread 0.2 on N: ln(N_seed / N) over 400 seeds has mean 0 +- 0.03 (3 s.e.) and
    standard deviation 0.2 +- 0.021 (3 s.e. of a standard deviation from 400 draws);
    the GM term without spread keeps its sigma. Through the Simulator: the per-seed
    rms of a white-dominated card (4096 samples, own error ~1.1 %) scatters by
    0.2 +- 0.06 in log over 60 seeds, and seeds give the same draw every time."""
    text = _spread_card(0.2)
    ln = []
    for s in range(400):
        c = parse_card(draw_unit(text, s))
        ln.append(np.log(c.terms["angle_random_walk"]["N"] / 0.1))
        assert c.term_list("gauss_markov")[0]["sigma"] == 20.0
        assert "spread" not in c.terms["angle_random_walk"]
    assert abs(np.mean(ln)) < 0.03 and abs(np.std(ln, ddof=1) - 0.2) < 0.021, (np.mean(ln), np.std(ln))
    white = "[sensor]\nname = \"w\"\nsample_rate_hz = 100.0\n[terms]\nangle_random_walk = { N = 0.1, spread = 0.2 }\n"
    sim = Simulator(4096, FS, list(range(1, 61)))
    runs = sim.run(white)
    assert abs(np.std(np.log([np.std(r) for r in runs]), ddof=1) - 0.2) < 0.06
    assert np.array_equal(runs[5], sim.run(white)[5])


def test_spread_estimated_from_training_records_of_a_known_population():
    """16 units drawn from a population with N spread 0.1 and a Gauss-Markov term
    without spread (tau 3 s), 16384 samples each, the card without spread: the
    estimated N spread is 0.1 +- 0.04 (a standard deviation from 16 records is known to
    ~18 %: 2.2 s.e.), the GM's below 0.04 (its between-record scatter is its own
    estimation error, subtracted). Measured: 0.105 and 0."""
    truth = _spread_card(0.1, gm_tau=3.0)
    recs = [gd.simulate(parse_card(draw_unit(truth, 300 + k)), 16384, seed=300 + k).rate_deg_s for k in range(16)]
    spread, between, est, _ = estimate_spread(recs, FS, CARD.replace("tau = 30.0", "tau = 3.0"))
    assert abs(spread[0] - 0.1) < 0.04 and spread[1] < 0.04, (spread, between, est)
    assert between[1] > 0 and est[1] > 0


def test_heldout_against_a_card_with_spread_accepts_another_unit_of_the_population():
    """The fitted card N = 0.1; a held-out unit with N 8 % higher (1e5 samples: its white
    level known to ~0.3 %): the card as one unit is far outside; the same card with
    spread 0.1 on N (the unit is 0.8 sigma of the population off) is within; a unit
    with N 40 % higher (3.4 sigma) is not."""
    y = gd.simulate(parse_card(CARD.replace("N = 0.1 ", "N = 0.108 ")), 100000, seed=1001).rate_deg_s
    plain = heldout_gap(y, FS, CARD, seeds=8, refit_bias=False)
    wide = heldout_gap(y, FS, _spread_card(0.1), seeds=8, refit_bias=False)
    assert not plain.within_scatter and plain.gap_after > plain.threshold
    assert wide.within_scatter, (wide.gap_after, wide.threshold, wide.iterations[-1]["components"])
    y_far = gd.simulate(parse_card(CARD.replace("N = 0.1 ", "N = 0.14 ")), 100000, seed=1002).rate_deg_s
    assert not heldout_gap(y_far, FS, _spread_card(0.1), seeds=8, refit_bias=False).within_scatter


@pytest.mark.slow
def test_heldout_prediction_interval_includes_the_cards_estimation_error():
    """Known truth (N = 0.1, GM 20 deg/h, 30 s). Ten times: the card fitted on a short
    training record (16384 samples: the GM magnitude comes out 0.76-1.16 of the truth),
    checked on a held-out record of 131072 samples from the SAME truth, 12 seeds.
    Measured: within 9/10 with ``card_error=True`` (n_train 16384), 6/10 without (the
    card's error is not in the reference); asserted >= 8 and at least 2 more than
    without. A held-out record from a DIFFERENT card (N 5 % higher) is within 0/5 times
    (asserted <= 1). (Over 30 seeded runs: 27/30 against 16/30; 0/30 for N x 1.05.)"""
    truth = parse_card(CARD)
    lay = Layout.for_record(16384, FS)
    fit = MagnitudeFit(truth, lay)
    other = parse_card(CARD.replace("N = 0.1 ", "N = 0.105 "))
    won, plain, wrong = 0, 0, 0
    for k in range(10):
        c = fit.coefficients(signature(gd.simulate(truth, 16384, seed=5000 + k).rate_deg_s, lay))
        hat = with_magnitudes(CARD, truth, np.sqrt(c / fit.coef), None, "fitted")
        y = gd.simulate(truth, 131072, seed=7000 + k).rate_deg_s
        won += heldout_gap(y, FS, hat, seeds=12, card_error=True, n_train=16384, refit_bias=False).within_scatter
        plain += heldout_gap(y, FS, hat, seeds=12, refit_bias=False).within_scatter
        if k < 5:
            y2 = gd.simulate(other, 131072, seed=7000 + k).rate_deg_s
            h = heldout_gap(y2, FS, hat, seeds=12, card_error=True, n_train=16384, refit_bias=False)
            wrong += h.within_scatter
            assert h.card_error is not None and len(h.card_error) == len(noise_terms(truth))
    assert won >= 8 and won >= plain + 2 and wrong <= 1, (won, plain, wrong)


def test_a_spread_group_moves_its_terms_together_and_is_estimated_where_no_term_alone_dominates():
    """Two Gauss-Markov terms at 1 and 2 s (20 deg/h each; neither makes 80 % of the
    signature anywhere, together they do at 1-10 s) scaled TOGETHER between units (spread
    0.1, one ``spread_group``), white noise without spread; 16 units of 16384 samples.
    Draws: the two terms' log factors are equal for every seed. Estimate: term by term
    nothing can be told (spread 0: neither dominates); as a group the spread is 0.1 +-
    0.04 (a standard deviation from 16 records, ~18 %; measured 0.080). groups_by_tau puts
    the two in one group and N alone."""
    from gyrodenoise.modelgap.population import groups_by_tau, spread_text
    gm = "\n[[terms.gauss_markov]]\nsigma = 20.0\ntau = {}\nspread = 0.1\nspread_group = 1\n"
    truth = CARD.split("[[terms.gauss_markov]]")[0] + gm.format(1.0) + gm.format(2.0)
    for s in range(20):
        g = parse_card(draw_unit(truth, s)).term_list("gauss_markov")
        assert g[0]["sigma"] == pytest.approx(g[1]["sigma"], rel=1e-5) and g[0]["sigma"] != 20.0
    card = truth.replace("spread = 0.1\nspread_group = 1\n", "")
    recs = [gd.simulate(parse_card(draw_unit(truth, 400 + k)), 16384, seed=400 + k).rate_deg_s for k in range(16)]
    alone, *_ = estimate_spread(recs, FS, card)
    groups = groups_by_tau(parse_card(card), FS)
    assert groups == [[0], [1, 2]]
    together, *_ = estimate_spread(recs, FS, card, groups=groups)
    assert np.all(alone[1:] == 0) and abs(together[1] - 0.1) < 0.04 and together[1] == together[2], (alone, together)
    back = parse_card(spread_text(card, together, groups=groups)).term_list("gauss_markov")
    assert back[0]["spread_group"] == back[1]["spread_group"] == 2.0 and back[0]["spread"] == pytest.approx(together[1], rel=1e-5)
