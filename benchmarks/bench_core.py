"""Core speed benchmark: prints ratios measured in this one process.

    python benchmarks/bench_core.py

1. Batch: ns/sample of the C core (``gyrodenoise.core.batch.run``) per method,
   against a bare scalar 3-state KF loop in C (compiled here with the same
   flags, the arithmetic floor of a Kalman filter of that size) and against
   filterpy's KalmanFilter on the same 4-state AR(3) model;
2. per sample: ``Denoiser.step`` against a trivial Python method call with the
   same signature, and the plain-Python kernels (the executable specification);
3. Allan deviation + five-term fit of 1e6 samples at >= 100 taus, vs allantools.oadev.

Targets: batch <= 3.5x the bare KF loop (motion: <= 4x); Denoiser.step <= 10x a trivial
method call; Allan deviation + fit of 1e6 samples <= 0.5 s. The ratio to filterpy is printed
without a target: it moves with filterpy's own speed more than with ours.
"""
import ctypes
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first
from benchmarks._timing import best_of  # noqa: E402

BARE_KF_C = r"""
/* A bare scalar 3-state KF (random walk rate, AR(1) error, bias), fixed Q and R:
   the floor a per-sample Kalman filter of this size costs. */
void bare_kf(const double *z, double *out, long n) {
    double x0 = 0, x1 = 0, x2 = 0;
    double P[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const double a = 0.5, q0 = 1e-6, q1 = 1e-5, r = 1e-5;
    for (long k = 0; k < n; k++) {
        /* predict: x0 <- x0, x1 <- a x1, x2 <- x2 */
        x1 *= a;
        P[0][1] *= a; P[1][0] = P[0][1];
        P[1][1] *= a * a; P[1][2] *= a; P[2][1] = P[1][2];
        P[0][0] += q0; P[1][1] += q1;
        /* update with H = [1 1 1] */
        double h0 = P[0][0] + P[0][1] + P[0][2];
        double h1 = P[1][0] + P[1][1] + P[1][2];
        double h2 = P[2][0] + P[2][1] + P[2][2];
        double s = h0 + h1 + h2 + r, inv = 1.0 / s;
        double v = z[k] - (x0 + x1 + x2);
        double k0 = h0 * inv, k1 = h1 * inv, k2 = h2 * inv;
        x0 += k0 * v; x1 += k1 * v; x2 += k2 * v;
        double hh[3] = {h0, h1, h2}, kk[3] = {k0, k1, k2};
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                P[i][j] -= kk[i] * hh[j];
        out[k] = x0;
    }
}
"""


def bare_kf_loop():
    """Compile the bare KF with the C core's flags; return a callable(z) -> out."""
    d = Path(tempfile.mkdtemp(prefix="bare_kf_"))
    (d / "bare.c").write_text(BARE_KF_C)
    subprocess.run(["gcc", "-O2", "-fschedule-insns", "-fsched-pressure", "-ffp-contract=off", "-std=c99", "-shared", "-fPIC", "-o",
                    str(d / "bare.so"), str(d / "bare.c")], check=True)
    lib = ctypes.CDLL(str(d / "bare.so"))
    dp = ctypes.POINTER(ctypes.c_double)

    def run(z):
        out = np.empty_like(z)
        lib.bare_kf(z.ctypes.data_as(dp), out.ctypes.data_as(dp), ctypes.c_long(z.size))
        return out
    return run


class Trivial:
    """A Python method with Denoiser.step's signature that does nothing."""

    def step(self, rate_deg_s, restart=False):
        return rate_deg_s


def main():
    import gyrodenoise as gd
    from gyrodenoise.analysis import allan
    from gyrodenoise.core import kernels as K
    from gyrodenoise.core.batch import compiled_core, run
    if not compiled_core():
        raise SystemExit("the C core is not built (pip install -e . builds it)")
    n = 1_440_000                                     # 2 h at 200 Hz
    z = np.ascontiguousarray(gd.simulate("paper_fog", n, seed=0).rate_deg_s)
    bare = bare_kf_loop()
    bare(z[:1000])
    t_bare = best_of(lambda: bare(z), 5) / n
    print(f"bare scalar 3-state KF loop (C, -O2):       {t_bare * 1e9:6.1f} ns/sample")
    t_method = {}
    for method, kw in (("shakf", {}), ("shakf", {"outlier_sigma": 0.0}), ("kf", {}), ("motion", {}),
                       ("lowpass", {})):
        p = K.make_params(method=method, sample_rate_hz=200.0, **kw)
        t = best_of(lambda: run(p, K.init_state(p), z), 5) / n
        label = method + (" (paper, no gate)" if kw else "")
        t_method[label] = t
        target = "<= 4x" if method == "motion" else "<= 3.5x"
        print(f"C core batch, {label:<28} {t * 1e9:6.1f} ns/sample = {t / t_bare:4.2f}x the bare KF "
              f"(target {target})")

    from filterpy.kalman import KalmanFilter
    p = K.make_params(method="shakf")
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
    print(f"filterpy KalmanFilter (same 4-state model):  {t_fp * 1e6:6.2f} us/sample; "
          f"ratio to the C SHAKF {t_fp / t_method['shakf']:.0f}x")

    # per sample
    m = 200_000
    zs = z[:m].tolist()
    triv = Trivial()
    t_triv = best_of(lambda: [triv.step(v, False) for v in zs], 5) / m
    print(f"trivial Python method call:                 {t_triv * 1e9:6.1f} ns/call")
    for method in ("shakf", "kf", "motion", "lowpass"):
        d = gd.Denoiser(200.0, method=method)
        for v in zs[:1000]:
            d.step(v, False)
        t_step = best_of(lambda: [d.step(v, False) for v in zs], 5) / m
        print(f"Denoiser.step, {method:<8} (C core):          {t_step * 1e9:6.1f} ns/call = "
              f"{t_step / t_triv:4.1f}x the trivial call (target <= 10x)")
    p = K.make_params(method="shakf")
    mp = 20_000
    t_plain = best_of(lambda: run(p, K.init_state(p), z[:mp], compiled=False), 1) / mp
    print(f"plain-Python kernels (the specification):    {t_plain * 1e6:6.2f} us/sample "
          f"({t_plain / t_method['shakf']:.0f}x the C core)")

    rng = np.random.default_rng(0)
    x = rng.standard_normal(1_000_000)
    allan.allan(x[:2000], 100.0)                      # compile
    ms = allan.default_m(x.size, per_decade=20)
    t_ours = best_of(lambda: allan.allan(x, 100.0, m=ms))
    import allantools
    t_at = best_of(lambda: allantools.oadev(x, rate=100.0, data_type="freq", taus=ms / 100.0), 1)
    print(f"Allan deviation + 5-term fit, 1e6 samples, {ms.size} taus: {t_ours:.3f} s (target <= 0.5 s)")
    print(f"allantools.oadev alone, same taus:                  {t_at:.3f} s  (ratio {t_at / t_ours:.1f}x)")


if __name__ == "__main__":
    main()
