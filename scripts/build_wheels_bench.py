"""Builds of the C core side by side: Denoiser.step (benchmarks/bench_core.py's per-sample loop)
and the batch run (ns/sample), in one process, CPU time (time.process_time: steadier than the wall
clock on a shared machine), rounds rotated so that no build always runs first; the best of each,
and whether the outputs are identical.

    python scripts/build_wheels_bench.py LABEL=PATH/_gdcore.abi3.so LABEL=PATH/_gdcore...so ...

e.g. the in-place build (setup.py, gcc) against a wheel's (scripts/build_wheels.py, zig): unzip the
wheel and name its gyrodenoise/core/_gdcore.abi3.so. Run from the repository root.
"""
import importlib.machinery
import importlib.util
import sys
import time

import numpy as np

sys.path.insert(0, ".")
import gyrodenoise as gd  # noqa: E402
from gyrodenoise.core import kernels as K  # noqa: E402


def load(path):
    loader = importlib.machinery.ExtensionFileLoader("gyrodenoise.core._gdcore", path)
    spec = importlib.util.spec_from_file_location("gyrodenoise.core._gdcore", path, loader=loader)
    m = importlib.util.module_from_spec(spec)
    loader.exec_module(m)
    return m


mods = {}
for arg in sys.argv[1:]:
    label, path = arg.split("=", 1)
    mods[label] = load(path)
zarr = np.ascontiguousarray(gd.simulate("paper_fog", 200_000, seed=0).rate_deg_s)
z = zarr.tolist()


class Trivial:
    def step(self, rate_deg_s, restart=False):
        return rate_deg_s


def best(fn, k, n):
    ts = []
    for _ in range(k):
        t0 = time.process_time()
        fn()
        ts.append(time.process_time() - t0)
    return min(ts) / n


tr = Trivial()
print(f"trivial Python method call: {best(lambda: [tr.step(v, False) for v in z], 5, len(z)) * 1e9:6.1f} ns/call")
for method in ("shakf", "kf", "motion", "lowpass"):
    step, batch, outs = {}, {}, {}
    order = list(mods.items())
    for rnd in range(6):
        for name, m in order[rnd % len(order):] + order[:rnd % len(order)]:   # rotated: no seat favoured
            d = gd.Denoiser(200.0, method=method)
            d._step = m.step
            outs[name] = [d.step(v, False) for v in z[:20000]]
            step[name] = min(step.get(name, 1e9), best(lambda: [d.step(v, False) for v in z], 2, len(z)))
            p = np.asarray(K.make_params(method=method, sample_rate_hz=200.0), dtype=float)

            def batch_run():
                s = np.asarray(K.init_state(p), dtype=float)
                out = np.empty_like(zarr)
                m.run(p, s, zarr, None, out)
            batch[name] = min(batch.get(name, 1e9), best(batch_run, 2, len(z)))
    ref = next(iter(outs.values()))
    same = all(o == ref for o in outs.values())
    print(f"{method:<8} Denoiser.step " + "  ".join(f"{k}: {v * 1e9:5.1f}" for k, v in step.items())
          + " ns/call | batch " + "  ".join(f"{k}: {v * 1e9:5.1f}" for k, v in batch.items())
          + f" ns/sample | outputs identical: {same}")
