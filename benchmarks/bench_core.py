"""Core speed benchmark (issue 2): prints ratios measured in this one process.

    python benchmarks/bench_core.py

1. per-sample cost of the batch SHAKF (numba) vs filterpy's KalmanFilter on the
   same 4-state AR(3) model: the specialised loop batch.run dispatches to
   (gyrodenoise.fastkernels, state in locals), the generic compiled loop of the
   kernels (run(..., fast=False)) and the plain-Python per-sample path;
2. Allan deviation + five-term fit of 1e6 samples at >= 100 taus, vs allantools.oadev.
"""
import time

import numpy as np


def best_of(fn, repeat=3):
    t = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        t.append(time.perf_counter() - t0)
    return min(t)


def main():
    import gyrodenoise as gd
    from gyrodenoise import allanvar
    from gyrodenoise.core import kernels as K
    from gyrodenoise.core.batch import run
    rng = np.random.default_rng(0)
    n = 1_440_000                                     # 2 h at 200 Hz
    z = gd.simulate("paper_fog", n, seed=0).rate_deg_s
    p = K.make_params(method="shakf")
    run(p, K.init_state(p), z[:1000])                 # compile (not timed)
    run(p, K.init_state(p), z[:1000], fast=False)
    t_fast = best_of(lambda: run(p, K.init_state(p), z), 5) / n
    t_generic = best_of(lambda: run(p, K.init_state(p), z, fast=False)) / n
    # the paper's SHAKF exactly (no outlier gate: filterpy's KF has none either)
    p_paper = K.make_params(method="shakf", outlier_sigma=0.0)
    run(p_paper, K.init_state(p_paper), z[:1000])
    t_paper = best_of(lambda: run(p_paper, K.init_state(p_paper), z), 5) / n
    m = 20_000
    t_plain = best_of(lambda: run(p, K.init_state(p), z[:m], compiled=False), 1) / m

    from filterpy.kalman import KalmanFilter
    st = run(p, K.init_state(p), z[:20000])[1]
    kf = KalmanFilter(dim_x=4, dim_z=1)
    phi = K.phi(p, list(st))
    kf.F = np.array([[phi[0], phi[1], phi[2], 1.0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1.0]])
    kf.H = np.array([[1.0, 0, 0, 0]])
    kf.Q = np.diag([st[K.S_Q], 0, 0, 0]) + 1e-18
    kf.R = np.array([[st[K.S_R]]])
    mf = 10_000

    def filterpy_loop():
        for v in z[:mf]:
            kf.predict()
            kf.update(v)
    t_fp = best_of(filterpy_loop) / mf
    print(f"SHAKF batch (default: 5-sigma outlier gate on), AR(3):")
    print(f"SHAKF batch, fast loop (numba):    {t_fast * 1e9:7.1f} ns/sample  ({n} samples = 2 h "
          f"at 200 Hz in {t_fast * n:.3f} s)")
    print(f"SHAKF batch, generic loop (numba): {t_generic * 1e9:7.1f} ns/sample  "
          f"(fast loop {t_generic / t_fast:.1f}x faster)")
    print(f"SHAKF per-sample (plain Python):   {t_plain * 1e6:7.2f} us/sample")
    print(f"filterpy KalmanFilter:             {t_fp * 1e6:7.2f} us/sample (same 4-state model, "
          f"fixed Q/R)")
    print(f"ratio filterpy / SHAKF fast loop:    {t_fp / t_fast:6.0f}x   (target >= 1000x)")
    print(f"ratio filterpy / SHAKF generic loop: {t_fp / t_generic:6.0f}x")
    print(f"SHAKF without the outlier gate (the paper's filter), fast loop: {t_paper * 1e9:.1f} "
          f"ns/sample, ratio filterpy / it {t_fp / t_paper:.0f}x")

    x = rng.standard_normal(1_000_000)
    allanvar.allan(x[:2000], 100.0)                   # compile
    ms = allanvar.default_m(x.size, per_decade=20)
    t_ours = best_of(lambda: allanvar.allan(x, 100.0, m=ms))
    import allantools
    t_at = best_of(lambda: allantools.oadev(x, rate=100.0, data_type="freq", taus=ms / 100.0), 1)
    print(f"Allan deviation + 5-term fit, 1e6 samples, {ms.size} taus: {t_ours:.3f} s (target <= 0.5 s)")
    print(f"allantools.oadev alone, same taus:                  {t_at:.3f} s  (ratio {t_at / t_ours:.1f}x)")


if __name__ == "__main__":
    main()
