"""Issue 20: how often the initial fit (an EMPTY card) names a term the record does not have,
and how often it still names one it does, for the chi^2 price a term must pay to stay.

    .venv/bin/python benchmarks/gap_white.py [--records 40]
    .venv/bin/python benchmarks/gap_white.py --scatter [--records 60]

Records: white rate noise (N = 0.5 deg/sqrt(h), numpy generator seeds 101..), and the same
with a quantization the record does have (the core simulator, Q such that its PSD at Nyquist,
4 Q^2 / T, is 0.3 N^2), 20,000 samples at 100 Hz and 1 kHz. For each price (0: the plain
NNLS optimum with metric._floors' PSD weights, what the workflow's initial fit does now; 9 and
INITIAL_DCHI2 with the Welch-band weights of welch_band_rel_sd) the share of records with a term other than
angle_random_walk (white), or with quantization named (white + Q), and the worst |N / N_true - 1|.
--scatter: the scatter of the Welch-band PSD and of the Allan variance over the white records,
against the analytic 1-sigma the fit's weights use (metric._floors, workflow.welch_band_rel_sd).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import gyrodenoise as gd
from gyrodenoise.modelgap.metric import Layout, _floors, signature
from gyrodenoise.modelgap.workflow import INITIAL_DCHI2, initial_terms, welch_band_rel_sd
from gyrodenoise.simulator import parse_card

N_TRUE = 0.5        # deg/sqrt(h)
N_SAMPLES = 20000


def named(terms):
    out = {nm for nm in ("quantization", "angle_random_walk", "bias_instability", "rate_random_walk")
           if terms[nm] > 0}
    return out | ({"gauss_markov"} if terms["gauss_markov"] else set())


def scatter(n_records):
    """Empirical relative scatter / analytic 1-sigma, per Welch band and Allan point."""
    fs = 100.0
    layout = Layout.for_record(N_SAMPLES, fs)
    e = layout.band_edges
    psd, avar, fl_psd, fl_allan = [], [], [], []
    for seed in range(101, 101 + n_records):
        sig = signature(np.random.default_rng(seed).standard_normal(N_SAMPLES), layout)
        fl = _floors(sig, layout)
        psd.append([sig["psd_bins"][e[i]:e[i + 1]].mean() for i in range(len(e) - 1)])
        avar.append(sig["avar"])
        fl_psd.append(fl["psd"])
        fl_allan.append(fl["allan"])
    psd, avar = np.array(psd), np.array(avar)
    rel_psd = psd.std(axis=0, ddof=1) / psd.mean(axis=0)
    print("bins per Welch band      ", np.diff(e).tolist())
    print("PSD scatter / _floors    ", np.round(rel_psd / np.mean(fl_psd, axis=0), 2).tolist())
    print("PSD scatter / welch_band_rel_sd", np.round(rel_psd / welch_band_rel_sd(layout), 2).tolist())
    print("Allan var. scatter / (2 _floors)", np.round(avar.std(axis=0, ddof=1) / avar.mean(axis=0)
                                                      / (2.0 * np.mean(fl_allan, axis=0)), 2).tolist())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--scatter", action="store_true")
    a = ap.parse_args()
    if a.scatter:
        scatter(a.records)
        return
    prices = (0.0, 9.0, INITIAL_DCHI2)
    for fs in (100.0, 1000.0):
        layout = Layout.for_record(N_SAMPLES, fs)
        rel = [None, welch_band_rel_sd(layout), welch_band_rel_sd(layout)]
        q_deg = math.sqrt(0.3 * (N_TRUE / 60.0) ** 2 / fs / 4.0)
        card_q = parse_card(f"[sensor]\nsample_rate_hz = {fs}\n[terms]\nangle_random_walk = {{ N = {N_TRUE} }}\n"
                            f"quantization = {{ Q = {q_deg} }}\n")
        spurious, found, n_err = np.zeros(len(prices)), np.zeros(len(prices)), np.zeros(len(prices))
        for seed in range(101, 101 + a.records):
            y = np.random.default_rng(seed).standard_normal(N_SAMPLES) * N_TRUE / 60.0 * math.sqrt(fs)
            yq = gd.simulate(card_q, N_SAMPLES, seed=seed).rate_deg_s
            sw, sq = signature(y, layout), signature(yq, layout)
            for i, p in enumerate(prices):
                tw = initial_terms(sw, layout, (), min_dchi2=p, psd_rel_sd=rel[i])
                spurious[i] += named(tw) != {"angle_random_walk"}
                n_err[i] = max(n_err[i], abs(math.sqrt(tw["angle_random_walk"]) * 60.0 / N_TRUE - 1.0))
                found[i] += "quantization" in named(initial_terms(sq, layout, (), min_dchi2=p, psd_rel_sd=rel[i]))
        for i, p in enumerate(prices):
            print(f"{fs:g} Hz, {N_SAMPLES} samples, price {p:g}: white records with another term "
                  f"{spurious[i]:.0f}/{a.records}, worst |N/N_true - 1| {n_err[i]:.4f}; "
                  f"white + Q (Q = {q_deg * 3600:.3g} arcsec) with Q named {found[i]:.0f}/{a.records}", flush=True)


if __name__ == "__main__":
    main()
