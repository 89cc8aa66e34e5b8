"""End-to-end speed of ``gyrodenoise gap`` on the real ring-laser gyro (issue 20 target: < 20 s).

What is timed: reading ``../shared/data/static/psins_lasergyro.imu`` (184,718 samples at
100 Hz) and the whole workflow on its z axis from an empty card, native engine, 6 seeds
(what ``gyrodenoise gap psins_lasergyro.imu --rate-column gyro_z --model empty.toml
--engine native`` does, minus the figure). Printed: wall and CPU seconds of the run, and
the same as a ratio to one card evaluation (6 seeds simulated + their signatures), the
baseline run in the same process, so that a loaded machine shows as such.

Run: .venv/bin/python benchmarks/gap_rlg.py [AXIS]
"""

from __future__ import annotations

import sys
import time
from _data import SHARED_DATA

TARGET_S = 20.0
DATA = SHARED_DATA / "static" / "psins_lasergyro.imu"
EMPTY = "[sensor]\nname = \"empty\"\nsample_rate_hz = 100.0\n"


def main(axis="gyro_z"):
    if not DATA.exists():
        print(f"skipped: {DATA} not present")
        return 0
    from gyrodenoise.modelgap import gap
    from gyrodenoise.modelgap.metric import Layout, Reference, signature
    from gyrodenoise.modelgap.simulation import Simulator
    from gyrodenoise.io.psins import read_psins
    from gyrodenoise.simulator import parse_card
    w0, c0 = time.perf_counter(), time.process_time()
    log = read_psins(DATA)
    y = log.axis(axis)
    res = gap(y, log.sample_rate_hz, parse_card(EMPTY), seeds=6, engine="native", latitude_deg=log.latitude_deg)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    # baseline: one evaluation of the final card (6 seeds simulated, signatures)
    lay = Layout.for_record(len(y), log.sample_rate_hz)
    w1, c1 = time.perf_counter(), time.process_time()
    sims = Simulator(len(y), log.sample_rate_hz, range(1, 7)).run(res.card_text)
    Reference(lay, [signature(s, lay) for s in sims])
    bw, bc = time.perf_counter() - w1, time.process_time() - c1
    print(f"RLG {axis}: {len(y)} samples; gap {res.gap_before:.3g} -> {res.gap_after:.3g} "
          f"(threshold {res.threshold:.3g}); {len(res.iterations)} evaluations of the card, "
          f"{sum(len(it['candidates']) for it in res.iterations)} candidates")
    print(f"end to end: wall {wall:.2f} s, CPU {cpu:.2f} s (target: wall < {TARGET_S:g} s: "
          f"{'met' if wall < TARGET_S else 'NOT met'})")
    print(f"baseline, one card evaluation: wall {bw:.2f} s, CPU {bc:.2f} s; run / baseline: "
          f"wall {wall / bw:.1f}x, CPU {cpu / bc:.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
