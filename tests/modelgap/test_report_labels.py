"""The gap report's step labels and the written card's closing comment say what each step
did (a label names the card of its step, not every term ever added; two steps with the same
card have different labels)."""

import numpy as np

import gyrodenoise as gd
from gyrodenoise.modelgap import format_report
from gyrodenoise.modelgap.report import describe_edits
from gyrodenoise.simulator import parse_card

STEPS = [{"name": "quantization", "params": {"Q": 1e-5}, "refit": False, "iteration": 0},
         {"name": "angle_random_walk", "params": {"N": 0.01}, "refit": False, "iteration": 0},
         {"name": "quantization", "params": None, "refit": True, "iteration": 1},
         {"name": "angle_random_walk", "params": {"N": 0.02}, "refit": True, "iteration": 1},
         {"name": "gauss_markov", "params": {"sigma": 1.0, "tau": 0.1}, "refit": False, "iteration": 1},
         {"name": "gauss_markov", "params": {"sigma": 2.0, "tau": 5.0}, "refit": False, "iteration": 1}]


def test_describe_edits_names_each_kind_once():
    assert describe_edits(STEPS[:2]) == "added quantization, angle_random_walk"
    assert describe_edits(STEPS[2:]) == "added gauss_markov; re-fitted angle_random_walk; removed quantization"
    assert describe_edits([]) == "nothing"


def test_report_labels_each_step_by_its_own_edits():
    rng = np.random.default_rng(5)
    res = gd.gap(0.01 * rng.standard_normal(4096), 100.0, parse_card(gd.simulator.load_card("paper_fog").text),
                 seeds=3, max_effects=1, quiet=True)
    its = res.iterations[:1] * 4        # four evaluations: input, after step 0, after step 1, same card again
    res.iterations, res.effects_added = its, STEPS
    lines = [ln for ln in format_report(res).splitlines() if ln[:3] in ("[0]", "[1]", "[2]", "[3]")]
    assert lines[0].startswith("[0] input card:")
    assert lines[1].startswith("[1] after added quantization, angle_random_walk:")
    assert lines[2].startswith("[2] after added gauss_markov; re-fitted angle_random_walk; removed quantization:")
    assert lines[3].startswith("[3] the same card compared again")
