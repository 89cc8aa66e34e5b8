"""Instruction count of the default ``motion`` filter per sample (callgrind), and the
aarch64 build's output checked bit for bit against x86_64's (under qemu: emulation,
no timing).

    python benchmarks/motion_cost/motion_cost.py            # callgrind Ir / sample, AVX2 vs SSE2 copy,
                                                            # and the bare KF loop of bench_core.py (the ratio)
    python benchmarks/motion_cost/motion_cost.py --aarch64  # also zig cc + qemu-aarch64

A small C driver (driver.c) runs gd_run over case files written here: the core
benchmark's record (paper_fog, 200 Hz) for the count, and for the bit check also a
record with steps, spikes, a tone near the Nyquist frequency and restarts, the output
variance kept, and the rigid-body option. Needs gcc and valgrind; --aarch64 needs
the ziglang package and qemu-aarch64 with /usr/aarch64-linux-gnu.
"""
import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
CORE = ROOT / "gyrodenoise" / "core"
FLAGS = ["-O2", "-fschedule-insns", "-fsched-pressure", "-ffp-contract=off", "-std=c99"]


def write_case(path, p, z, restarts):
    """Write one case file; returns its path."""
    import gyrodenoise.core.kernels as K
    p = np.asarray(p, dtype=np.float64)
    s = np.asarray(K.init_state(list(p)), dtype=np.float64)
    z = np.ascontiguousarray(z, dtype=np.float64)
    with open(path, "wb") as f:
        np.array([p.size, s.size, z.size], dtype=np.int64).tofile(f)
        p.tofile(f)
        s.tofile(f)
        z.tofile(f)
        np.asarray(restarts, dtype=np.uint8).tofile(f)
    return path


def cases(d, n_count):
    """The case files: {name: path}; 'bench' first (the one counted)."""
    import gyrodenoise as gd
    import gyrodenoise.core.kernels as K
    z = gd.simulate("paper_fog", n_count, seed=0).rate_deg_s
    out = {"bench": write_case(d / "bench.bin", K.make_params(method="motion", sample_rate_hz=200.0),
                               z, np.zeros(z.size, bool))}
    rng = np.random.default_rng(1)
    n = 40_000
    t = np.arange(n) / 400.0
    h = (np.cumsum(np.where(rng.random(n) < 0.002, rng.normal(0, 50, n), 0.0))
         + 20 * np.sin(2 * np.pi * 0.7 * t) + rng.normal(0, 0.3, n))
    h[n // 2:] += 0.9 * np.sin(2 * np.pi * 0.41 * 400.0 * t[n // 2:])
    h[rng.integers(0, n, 20)] += rng.normal(0, 1e3, 20)
    rs = np.zeros(n, bool)
    rs[[7_000, 7_003, 25_000]] = True
    out["hostile"] = write_case(d / "hostile.bin", K.make_params(method="motion", sample_rate_hz=400.0), h, rs)
    pv = K.make_params(method="motion", sample_rate_hz=400.0)
    pv[K.P_MO_VAR] = 1.0
    out["variance"] = write_case(d / "variance.bin", pv, h, rs)
    out["rigid"] = write_case(d / "rigid.bin", K.make_params(method="motion", sample_rate_hz=400.0,
                                                             max_motion_hz=20.0), h, rs)
    return out


BARE_MAIN_C = r"""
#include <stdlib.h>
void bare_kf(const double *z, double *out, long n);
int main(int argc, char **argv)
{
    long n = atol(argv[1]), k;
    double *z = malloc(n * sizeof *z), *out = malloc(n * sizeof *out), acc = 0.0;
    for (k = 0; k < n; k++)
        z[k] = (double)(k % 97) * 1e-3;
    bare_kf(z, out, n);
    for (k = 0; k < n; k++)
        acc += out[k];
    return acc == 12345.0;
}
"""


def bare_kf_count(d, n):
    """callgrind's instructions per sample of bench_core.py's bare 3-state KF loop (the cost goal's
    unit), compiled with the core's flags; its count does not depend on the data."""
    from benchmarks.bench_core import BARE_KF_C
    (d / "bare.c").write_text(BARE_KF_C + BARE_MAIN_C)
    exe = d / "bare"
    subprocess.run(["gcc"] + FLAGS + ["-o", str(exe), str(d / "bare.c")], check=True)
    cg = d / "cg_bare.out"
    subprocess.run(["valgrind", "--tool=callgrind", "--toggle-collect=bare_kf*", f"--callgrind-out-file={cg}",
                    str(exe), str(n)], check=True, capture_output=True)
    return _total(cg) / n


def _total(cg):
    rep = subprocess.run(["callgrind_annotate", str(cg)], check=True, capture_output=True, text=True).stdout
    return next(int(ln.split()[0].replace(",", "")) for ln in rep.splitlines() if "PROGRAM TOTALS" in ln)


def build(d, cc, name, flags=FLAGS, core=CORE):
    """Compile the driver with the core in folder ``core``; returns the executable's path."""
    exe = d / name
    subprocess.run(cc + flags + ["-I", str(core), "-o", str(exe), str(Path(__file__).with_name("driver.c")),
                                 str(core / "gdcore.c")]
                   + [str(f) for f in (core / "gdbias.c",) if f.exists()] + ["-lm"], check=True)
    return exe


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1_440_000, help="samples of the counted record (bench_core's)")
    ap.add_argument("--core", type=Path, default=CORE,
                    help="folder of the gdcore.c / gdcore.h to count; the case files come from this "
                         "checkout's kernels.py, so its parameter and state layout must match (to count "
                         "an older commit, copy this folder into a `git archive` of it and run it there)")
    ap.add_argument("--aarch64", action="store_true", help="also the aarch64 bit check (qemu)")
    a = ap.parse_args()
    d = Path(tempfile.mkdtemp(prefix="motion_cost_"))
    cs = cases(d, a.n)
    x86 = build(d, ["gcc"], "drv_x86", core=a.core)
    sse2 = build(d, ["gcc"], "drv_sse2", FLAGS + ["-DGD_NO_TARGET_CLONES"], core=a.core)
    bare = bare_kf_count(d, a.n)
    print(f"bare 3-state KF loop of bench_core.py (gcc, the core's flags): {bare:.1f} instructions/sample "
          "(callgrind)", flush=True)
    for label, exe in (("as built (the AVX2 copy where the CPU has it)", x86),
                       ("-DGD_NO_TARGET_CLONES (x86-64 baseline, SSE2)", sse2)):
        for fn, extra in (("gd_run", []), ("gd_step", ["step"])):   # batch, per sample
            cg = d / "cg.out"
            subprocess.run(["valgrind", "--tool=callgrind", f"--toggle-collect={fn}*",
                            f"--callgrind-out-file={cg}", str(exe), str(cs["bench"]), str(d / "o.bin")] + extra,
                           check=True, capture_output=True)
            ir = _total(cg)
            print(f"motion, {fn}, paper_fog 200 Hz, {a.n} samples, {label}: "
                  f"{ir / a.n:.1f} instructions/sample (callgrind) = {ir / a.n / bare:.2f}x the bare KF loop",
                  flush=True)
    for name, case in cs.items():
        subprocess.run([str(x86), str(case), str(d / f"{name}.x86")], check=True)
        subprocess.run([str(sse2), str(case), str(d / f"{name}.sse2")], check=True)
        same = (d / f"{name}.x86").read_bytes() == (d / f"{name}.sse2").read_bytes()
        print(f"x86_64 as built vs -DGD_NO_TARGET_CLONES, case {name}: output and final state "
              f"{'identical bit for bit' if same else 'DIFFER'}")
    if not a.aarch64:
        return
    zig = [sys.executable, "-m", "ziglang", "cc", "-target", "aarch64-linux-gnu"]
    arm = build(d, zig, "drv_arm", ["-O2", "-ffp-contract=off", "-std=c99", "-w"])   # clang: no -fsched-*
    for name, case in cs.items():
        subprocess.run(["qemu-aarch64", "-L", "/usr/aarch64-linux-gnu", str(arm), str(case),
                        str(d / f"{name}.arm")], check=True)
        same = (d / f"{name}.x86").read_bytes() == (d / f"{name}.arm").read_bytes()
        print(f"aarch64 (zig cc, qemu) vs x86_64, case {name}: output and final state "
              f"{'identical bit for bit' if same else 'DIFFER'}")


if __name__ == "__main__":
    main()
