"""The model-gap workflow: what is a model card missing to behave like a real gyro?

Modules, by concern: `metric` (signatures, z-scores, the gap),
`cards` (card text: re-parse, edit), `simulation` (the card S
times, FMU or native), `candidates` (effects fitted to the record),
`workflow` (choose, edit, repeat: `gap`), `report` (text and
plot), `settings` (constants).

Given a measured rate record and a model card, the workflow

1. simulates the card ``S`` times (seeds 1..S) at the record's sample rate and
   length, through ``SimulatedFog.fmu`` (engine ``"fmu"``) or the core simulator
   (engine ``"native"``; the two are bit-identical, see ``tests/fmu/test_build_and_run.py``);
2. compares five noise *signatures* of the record with the simulations
   (`signature`, `zscores`, `GAP_METRIC`);
3. proposes candidate effects from the vocabulary of the spec, fits each
   candidate's parameters to the record (`propose`), screens each by
   re-simulation and keeps the one that shrinks the gap most for its number of
   parameters;
4. adds it to the card text (`edit_card`) and repeats until the gap is
   within the simulations' own scatter (leave-one-out threshold) or nothing
   improves it.

Signatures and the gap metric
-----------------------------
For one record ``y`` (deg/s):

* ``allan``: log overlapping Allan deviation at octave cluster sizes
  ``m = 1, 2, 4, ...`` with at least 16 clusters;
* ``psd``: log Welch PSD (Hann, 50 % overlap) averaged in log-spaced bands,
  10 per decade;
* ``line``: the Welch PSD bin by bin (for spectral lines);
* ``mean``: the record mean;
* ``trend``: the means of 16 equal blocks minus the record mean.

Each measured quantity gets a score ``z = (measured - mean of the S
simulations) / (sigma sqrt(1 + 1/S))``, with ``sigma`` the scatter of one
simulated record: the larger of the seeds' standard deviation and an analytic
floor (Allan: IEEE 952 C.1 error; PSD: chi-square of the Welch average; means:
white-noise standard error). The gap is the average of five components, each
about 1 when the card explains the record: mean z^2 over Allan taus, mean z^2
over PSD bands, max z^2 over PSD bins divided by 2 ln(number of bins), z^2 of
the mean, mean z^2 over the block means.

Choosing a candidate
--------------------
The gap measures how far the record is from a card; choosing WHICH effect to
add uses a different number, the candidate's *score*: the gap with every
point's ``z^2`` capped at 25 (`robust_gap`; points that neither the card
nor any candidate brings within ``|z| <= 5`` count 0), plus the Gaussian
log-likelihood price of a wider simulated scatter that the record does not ask
for (`widening`: per point ``ln(sigma_new^2 / sigma_old^2) - ln(max(z^2,
1))`` when positive), times ``1 + 0.05``
per parameter. A candidate is accepted when its score is below 0.8 times the
current card's capped gap. Before any stochastic candidate, a record mean far
off the card's (``|z| > 3`` and more than 5 times the rms wander of the block
means, `deterministic_offset`) is explained by a constant bias. Why: on a
long real record (an ADIS16405, docs/bench/gap.md) the plain gap rewards a large rate
random walk, whose wider scatter shrinks the z of a deterministic mean offset,
and is dominated by short-tau points (a sensor's internal low-pass filter)
that no term can fix.

Analytic Allan variances used to fit candidates (avar adds for independent
terms): Eq. (40) of the paper for Q, N, B, K, R, and for a first-order
Gauss-Markov process of stationary std ``sigma`` and correlation time ``T``
(IEEE Std 952-1997, Annex C; El-Sheimy et al. 2008)::

    avar(tau) = 2 sigma^2 T / tau * (1 - T / (2 tau) * (3 - 4 exp(-tau/T) + exp(-2 tau/T)))

which tends to ``2 sigma^2 tau / (3 T)`` for ``tau << T`` and to ``2 sigma^2 T / tau``
for ``tau >> T`` and peaks near ``tau = 1.89 T``.
"""

from gyrodenoise.modelgap.candidates import SHAPE, Candidate, gm_avar, propose
from gyrodenoise.modelgap.cards import card_at_rate, check_editable, edit_card, text_at_rate
from gyrodenoise.modelgap.metric import Layout, Reference, gap_components, gap_value, signature, zscores
from gyrodenoise.modelgap.report import format_report, plot_gap
from gyrodenoise.modelgap.settings import COMPONENTS, GAP_METRIC
from gyrodenoise.modelgap.simulation import Simulator, fmu_path_for
from gyrodenoise.modelgap.workflow import GapResult, check_record, gap, heldout_gap, robust_gap, widening

__all__ = ["SHAPE", "Candidate", "gm_avar", "propose", "card_at_rate", "check_editable", "edit_card",
           "text_at_rate", "Layout", "Reference", "gap_components", "gap_value", "signature", "zscores",
           "format_report", "plot_gap", "COMPONENTS", "GAP_METRIC", "Simulator", "fmu_path_for", "GapResult",
           "check_record", "gap", "heldout_gap", "robust_gap", "widening"]
