"""Constants of the model-gap workflow (metric, scoring, card fields)."""

from __future__ import annotations

from gyrodenoise.units import ALLAN_TERMS

GAP_METRIC = ("gap = average of 5 components, each ~1 when the card explains the record: "
              "mean z^2 over octave-spaced Allan deviations (log), mean z^2 over log-spaced Welch PSD "
              "bands (log), max z^2 over PSD bins / 2 ln(n_bins), z^2 of the record mean, mean z^2 over "
              "16 block means minus the record mean; z = (measured - mean of S simulations of the card) "
              "/ (scatter of one simulation * sqrt(1 + 1/S))")

COMPONENTS = ("allan", "psd", "line", "mean", "trend")
N_BLOCKS = 16
MIN_CLUSTERS = 16
BANDS_PER_DECADE = 10
MIN_SAMPLES = 4096
COMPONENT_FLOOR = 3.0         # a component above max(3, 1.5 x its leave-one-out max) is a disagreement
# parameters per candidate (for the penalty)
N_PARAMS = {"quantization": 1, "angle_random_walk": 1, "bias_instability": 1, "rate_random_walk": 1,
            "rate_ramp": 1, "constant_bias": 1, "turn_on_transient": 2, "gauss_markov": 2,
            "sinusoid": 3, "angle_gauss_markov": 2}
PENALTY_PER_PARAM = 0.05      # score = gap * (1 + PENALTY_PER_PARAM * n_params)
MIN_IMPROVEMENT = 0.8         # accept a candidate only when it brings the gap below 0.8x
Z2_CAP = 25.0                 # selection: each point's z^2 counts at most 25 (|z| = 5)
OFFSET_RATIO = 5.0            # mean offset > 5x the block-mean wander (and |z| > 3): a deterministic bias
WIDEN_COMPONENTS = ("allan", "psd", "mean", "trend")   # scatter-widening penalty (log-likelihood term)
# Allan term's card section -> (its card field, s-based value -> card units)
CARD_FIELD = {t.section: (t.symbol, t.to_spec) for t in ALLAN_TERMS}
# correlated term -> its sigma's s-based value -> card units (gauss_markov in deg/h, angle_gauss_markov in deg)
SIGMA_TO_CARD = {"gauss_markov": 3600.0, "angle_gauss_markov": 1.0}
