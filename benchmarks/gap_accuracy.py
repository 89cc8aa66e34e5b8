"""Per-effect accuracy of the gap workflow (docs/bench/gap.md table).

For each effect of the vocabulary, simulate RECORDS "measured" records (30 min at
100 Hz, seeds 2001..) from the white-noise base card plus the hidden effect, run
``gyrodenoise.gap`` from the base card (native engine, 5 seeds), and print how
often the right effect is named alone, the median and worst relative error of
each fitted parameter, and the median gap before/after.

Run: python benchmarks/gap_accuracy.py [RECORDS]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first

import gyrodenoise as gd
from gyrodenoise.modelgap import edit_card
from gyrodenoise.simulator import parse_card

FS = 100.0
N = int(30 * 60 * FS)
BASE = """[sensor]
name = "base"
sample_rate_hz = 100.0

[terms]
angle_random_walk = { N = 0.1 }
"""
BASE_Q = BASE.replace("angle_random_walk = { N = 0.1 }", "quantization = { Q = 3.0e-4 }")
CASES = [
    ("quantization", BASE, {"Q": 3.0e-4}),
    ("angle_random_walk", BASE_Q, {"N": 0.1}),
    ("bias_instability", BASE, {"B": 3.0}),
    ("rate_random_walk", BASE, {"K": 20.0}),
    ("rate_ramp", BASE, {"R": 20.0}),
    ("constant_bias", BASE, {"value": 2.0}),
    ("turn_on_transient", BASE, {"amplitude": 10.0, "tau": 120.0}),
    ("gauss_markov", BASE, {"sigma": 6.0, "tau": 2.0}),
    ("sinusoid", BASE, {"amplitude": 3.0, "frequency": 1.3}),
]


def main(records=5):
    print(f"{records} records of 30 min at 100 Hz per effect, base card ARW N = 0.1 deg/sqrt(h) "
          f"(Q = 3e-4 deg for the ARW case), 5 simulated seeds")
    print("| effect | truth | named alone | median / worst error | gap before -> after (median) | s/run |")
    print("|---|---|---|---|---|---|")
    for name, base, truth in CASES:
        ok, errs, gb, ga, dt, other = 0, {k: [] for k in truth}, [], [], [], []
        for r in range(records):
            y = gd.simulate(parse_card(edit_card(base, name, truth)), N, seed=2001 + r).rate_deg_s
            t0 = time.perf_counter()
            res = gd.gap(y, FS, parse_card(base), seeds=5, engine="native")
            dt.append(time.perf_counter() - t0)
            names = [e["name"] for e in res.effects_added]
            gb.append(res.gap_before)
            ga.append(res.gap_after)
            if names == [name]:
                ok += 1
                for k in truth:   # frequency: absolute error in mHz, the others relative in %
                    got = res.effects_added[0]["params"][k]
                    errs[k].append(abs(got - truth[k]) * 1e3 if k == "frequency" else abs(got / truth[k] - 1.0) * 100)
            else:
                other.append("+".join(names) or "nothing")
        e = "; ".join(f"{k} {np.median(v):.2g} / {np.max(v):.2g} {'mHz' if k == 'frequency' else '%'}"
                      for k, v in errs.items() if v)
        tr = ", ".join(f"{k}={v:g}" for k, v in truth.items())
        miss = f" (else: {', '.join(other)})" if other else ""
        print(f"| {name} | {tr} | {ok}/{records}{miss} | {e} | {np.median(gb):.3g} -> {np.median(ga):.3g} "
              f"| {np.mean(dt):.1f} |", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
