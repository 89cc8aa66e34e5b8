"""The co-simulation's parameters and its check against the core, without building an FMU:
gyrodenoise.fmu.cosim.system_parameters (what an SSP or a libcosim run sets) and
gyrodenoise.fmu.validation.compare_with_core (an FMU run against gd.simulate / gd.denoise)."""
import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.fmu.cosim import system_parameters
from gyrodenoise.fmu.simnative import compile_card
from gyrodenoise.fmu.validation import compare_with_core
from gyrodenoise.simulator import load_card


def test_the_fog_gets_its_card_as_each_sensor_takes_it():
    card = load_card("imar_fog")
    card_obj, native = system_parameters("imar_fog", seed=7, rate_deg_s=2.5)
    assert card_obj.sample_rate_hz == card.sample_rate_hz
    # a bundled card is bound by its name (one line: a host's result CSV keeps one row a step)
    assert native["fog"] == {"card": "imar_fog", "seed": 7, "true_rate": 2.5}
    _, python = system_parameters("imar_fog", seed=7, sensor="SimulatedFog")
    assert python["fog"]["card"] == "imar_fog"
    assert "\n" not in compile_card(card, one_line=True)      # the form for any other card
    assert python["denoiser"] == native["denoiser"]


def test_the_cores_own_outputs_compare_equal_and_a_changed_sample_does_not():
    card = load_card("paper_fog")
    n, seed, true_rate = 20_000, 4, 3.0
    restarts = np.zeros(n, dtype=bool)
    restarts[12_000] = True
    measured = gd.simulate(card, n, seed=seed, true_rate_deg_s=true_rate, restarts=restarts).rate_deg_s
    filtered = gd.denoise(measured, card.sample_rate_hz, method="motion", ar_order=3, restarts=restarts)
    same = compare_with_core(measured, filtered, true_rate, restarts, card, seed, "motion", 3)
    assert same["max_abs_diff_measured_vs_simulate_deg_s"] == 0.0
    assert same["max_abs_diff_filtered_vs_denoise_deg_s"] == 0.0
    assert same["allan_max_rel_diff"] == 0.0
    changed = filtered.copy()
    changed[5000] += 0.25
    assert compare_with_core(measured, changed, true_rate, restarts, card, seed, "motion", 3)[
        "max_abs_diff_filtered_vs_denoise_deg_s"] == pytest.approx(0.25)
