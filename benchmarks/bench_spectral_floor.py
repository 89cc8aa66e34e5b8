"""What the spectral noise floor of ``method="motion"`` costs (issue 23):

    python benchmarks/bench_spectral_floor.py [--samples 400000] [--repeat 11]

The C batch core on the same seeded record with the floor on (the default)
and off (p[P_MO_SPEC] = 0: the 4th-difference estimate alone, the filter as it
was before), alternately in this one process; prints the fastest run of each
in ns/sample and their ratio (the machine is shared: the fastest run is the
least disturbed one).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gyrodenoise.core import batch, kernels as K


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=400_000)
    ap.add_argument("--repeat", type=int, default=11)
    a = ap.parse_args(argv)
    if a.samples < 1000 or a.repeat < 1:
        ap.error("--samples must be >= 1000 and --repeat >= 1")
    z = np.random.default_rng(0).standard_normal(a.samples) * 0.1
    on = K.make_params(3, "motion", 400.0)
    off = list(on)
    off[K.P_MO_SPEC] = 0.0
    best = {"off": float("inf"), "on": float("inf")}
    for _ in range(a.repeat):
        for name, p in (("off", off), ("on", on)):
            s = K.init_state(p)
            t0 = time.perf_counter()
            batch.run(p, s, z)
            best[name] = min(best[name], time.perf_counter() - t0)
    ns = {k: v * 1e9 / z.size for k, v in best.items()}
    print(f"motion, spectral floor off: {ns['off']:7.1f} ns/sample")
    print(f"motion, spectral floor on:  {ns['on']:7.1f} ns/sample = {ns['on'] / ns['off']:.3f}x off")


if __name__ == "__main__":
    main()
