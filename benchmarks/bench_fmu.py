"""Speed of the FMUs (a benchmark, not a test).

Prints, in one run:
  * steps/s of FogDenoiser.fmu in an fmpy ``FMU2Slave`` loop (set raw_rate and
    restart, doStep, get the outputs), once through fmpy's wrappers and once with
    the FMI functions called directly (what ``gyrodenoise fmu run`` does);
  * the same loop on an empty pythonfmu FMU with the same interface (one Real and
    one Boolean in, the same outputs, do_step does nothing): the floor of
    pythonfmu + ctypes on this machine;
  * the per-sample core alone (Denoiser.step, the C core), no FMI;
  * from a plain C host (tests/chost/host.c): the empty FMU, FogDenoiser.fmu,
    FogDenoiserNative.fmu, SimulatedFog.fmu and SimulatedFogNative.fmu (paper_fog);
  * the 10-minute 200 Hz two-FMU validation run (SimulatedFog -> FogDenoiser).

Targets: FogDenoiser >= 0.7x the steps/s of the empty FMU in the same run,
>= 50 000 steps/s; 10-min validation run <= 10 s; each native FMU >= 10x the steps/s of the
empty pythonfmu FMU from the C host.

    python benchmarks/bench_fmu.py [--steps N] [--fmu-dir DIR] [--skip-long] [--wine]
    python benchmarks/bench_fmu.py --native-only [--wine]   # the native FMUs by platform
"""

import argparse
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first

from benchmarks._data import REPO
from gyrodenoise import fmu as F

EMPTY_SLAVE = textwrap.dedent('''
    from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real

    class EmptyFmu(Fmi2Slave):
        """Same interface as FogDenoiser's inputs and main outputs; does nothing."""

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.raw_rate = 0.0
            self.restart = False
            self.filtered_rate = 0.0
            self.converged = False
            P, C, I = Fmi2Causality, Fmi2Variability, Fmi2Initial
            self.register_variable(Real("raw_rate", causality=P.input))
            self.register_variable(Boolean("restart", causality=P.input, variability=C.discrete))
            self.register_variable(Real("filtered_rate", causality=P.output, initial=I.exact))
            for name in ("phi_1", "phi_2", "phi_3", "c", "R_hat", "innovation"):
                setattr(self, name, 0.0)
                self.register_variable(Real(name, causality=P.output, initial=I.exact))
            self.register_variable(Boolean("converged", causality=P.output, initial=I.exact,
                                           variability=C.discrete))

        def do_step(self, current_time, step_size):
            return True
''')

OUTPUTS = ["filtered_rate", "phi_1", "phi_2", "phi_3", "c", "R_hat", "innovation"]


def build_empty(out_dir):
    src = Path(out_dir) / "emptyfmu_bench.py"
    src.write_text(EMPTY_SLAVE)
    subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(src), "-d", str(out_dir)],
                   check=True, capture_output=True, cwd=out_dir)
    return Path(out_dir) / "EmptyFmu.fmu"


def c_host_steps_per_s(fmu, tmp, n, params=(), signals=("raw_rate", "restart", "filtered_rate"), step=0.005):
    """Steps/s of ``fmu`` driven by the project's plain C host (tests/chost/host.c:
    dlopen + the FMI 2.0 C API), libpython preloaded for pythonfmu FMUs; ``signals``:
    the Real input, the Boolean input and the Real output of each step."""
    import sysconfig
    import zipfile

    from gyrodenoise.fmu import native
    tmp = Path(tmp)
    host = tmp / "chost"
    if not host.exists():
        subprocess.run(["gcc", "-std=c99", "-O2", f"-I{native.fmi_headers_dir()}", "-o", str(host),
                        str(REPO / "tests" / "chost" / "host.c"), "-ldl", "-lm"], check=True)
    unz = tmp / ("unz_" + Path(fmu).stem)
    with zipfile.ZipFile(fmu) as z:
        z.extractall(unz)
    env = dict(__import__("os").environ)
    libpy = Path(sysconfig.get_config_var("LIBDIR")) / sysconfig.get_config_var("LDLIBRARY")
    env["LD_PRELOAD"] = str(libpy)
    cmd = [str(host), str(unz), "bench", "--in", signals[0], "--restart", signals[1], "--out", signals[2],
           "--n", str(n), "--step", repr(step)]
    for kv in params:
        cmd += ["--set", kv]
    best = 0.0
    for _ in range(3):
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300).stdout
        best = max(best, float(out.split("steps_per_s")[-1].split()[0]))
    return best


def _steps_per_s(cmd, env=None, repeats=3):
    """Best steps/s printed (last number) by a C host command over ``repeats`` runs."""
    best = 0.0
    for _ in range(repeats):
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
        if proc.returncode != 0:
            raise RuntimeError(f"{cmd[0]} failed: {proc.stderr[-500:]}")
        best = max(best, float(proc.stdout.split()[-1]))
    return best


def native_platforms(nats, tmp, n, wine=False):
    """Steps/s of the native FMUs from the C hosts (tests/chost/host.c, chain.c): linux64, and
    with ``wine`` the win64 binaries driven by the same hosts cross-compiled for Windows,
    alternately in the same run (darwin64 cannot run here)."""
    import os
    import shutil
    import zipfile

    from gyrodenoise.fmu import native
    tmp = Path(tmp)
    unz = {}
    for name, fmu in nats.items():
        unz[name] = tmp / ("plat_" + name)
        with zipfile.ZipFile(fmu) as z:
            z.extractall(unz[name])
    hdr = f"-I{native.fmi_headers_dir()}"
    platforms = {"linux64": ([], None, lambda d: str(d))}
    for prog in ("host", "chain"):
        subprocess.run(["gcc", "-std=c99", "-O2", hdr, "-o", str(tmp / prog), str(REPO / "tests" / "chost" / f"{prog}.c"),
                        "-ldl"], check=True)
    if wine:
        exe = shutil.which("wine") or shutil.which("wine64")
        cc, _ = native.compiler_for("win64")
        for prog in ("host", "chain"):
            subprocess.run([*cc, "-std=c99", "-O2", hdr, "-o", str(tmp / f"{prog}.exe"),
                            str(REPO / "tests" / "chost" / f"{prog}.c")], check=True, cwd=tmp)
        platforms["win64 (wine)"] = ([exe], dict(os.environ, WINEDEBUG="-all"), lambda d: "Z:" + str(d))
    rows = {}
    for _ in range(2):          # alternate the platforms: the machine's load drifts
        for plat, (pre, env, path) in platforms.items():
            ext = ".exe" if pre else ""
            host, chain = pre + [str(tmp / f"host{ext}")], pre + [str(tmp / f"chain{ext}")]
            fd, sf = path(unz["FogDenoiserNative"]), path(unz["SimulatedFogNative"])
            runs = {"FogDenoiserNative": host + [fd, "bench", "--n", str(100 * n)],
                    "SimulatedFogNative (paper_fog)": host + [sf, "bench", "--in", "true_rate", "--out",
                                                              "measured_rate", "--n", str(20 * n)],
                    "chain SimulatedFogNative -> FogDenoiserNative": chain + [sf, fd, "--bench", str(20 * n)]}
            for what, cmd in runs.items():
                rate = _steps_per_s(cmd, env, repeats=2)
                rows[(what, plat)] = max(rows.get((what, plat), 0.0), rate)
    print(f"native FMUs from the C hosts, by platform (load avg {open('/proc/loadavg').read().split()[0]}):")
    for what in dict.fromkeys(w for w, _ in rows):
        cells = "  ".join(f"{plat} {rows[(what, plat)]:11.0f}" for plat in platforms)
        print(f"  {what:46s} {cells}  steps/s")


def loop_wrapped(inst, z, rs):
    """fmpy's FMU2Slave methods, as a user would write it."""
    s = inst.slave
    vr_in, vr_rs = [inst.vr["raw_rate"]], [inst.vr["restart"]]
    vr_out, vr_conv = [inst.vr[n] for n in OUTPUTS], [inst.vr["converged"]]
    t0 = time.perf_counter()
    for k in range(len(z)):
        s.setReal(vr_in, [z[k]])
        s.setBoolean(vr_rs, [rs[k]])
        s.doStep(k * 0.005, 0.005)
        s.getReal(vr_out)
        s.getBoolean(vr_conv)
    return len(z) / (time.perf_counter() - t0)


def loop_direct(inst, z, rs):
    """The FMI functions called directly with preallocated ctypes buffers."""
    from fmpy.fmi2 import fmi2Boolean, fmi2Real, fmi2ValueReference
    s = inst.slave
    c = s.component
    f = s._functions
    set_real, set_bool, do_step = f["fmi2SetReal"], f["fmi2SetBoolean"], f["fmi2DoStep"]
    get_real, get_bool = f["fmi2GetReal"], f["fmi2GetBoolean"]
    vr_in = (fmi2ValueReference * 1)(inst.vr["raw_rate"])
    vr_rs = (fmi2ValueReference * 1)(inst.vr["restart"])
    vr_out = (fmi2ValueReference * len(OUTPUTS))(*[inst.vr[n] for n in OUTPUTS])
    vr_conv = (fmi2ValueReference * 1)(inst.vr["converged"])
    x, flag = (fmi2Real * 1)(), (fmi2Boolean * 1)()
    y, conv = (fmi2Real * len(OUTPUTS))(), (fmi2Boolean * 1)()
    nout = len(OUTPUTS)
    t0 = time.perf_counter()
    for k in range(len(z)):
        x[0] = z[k]
        flag[0] = rs[k]
        if (set_real(c, vr_in, 1, x) | set_bool(c, vr_rs, 1, flag) | do_step(c, k * 0.005, 0.005, 1)
                | get_real(c, vr_out, nout, y) | get_bool(c, vr_conv, 1, conv)) > 1:
            raise RuntimeError(inst.messages)
    return len(z) / (time.perf_counter() - t0)


def best_of(fn, repeats=3):
    return max(fn() for _ in range(repeats))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--fmu-dir", default=None, help="use FMUs built there (default: build afresh)")
    ap.add_argument("--skip-long", action="store_true", help="skip the 10-minute validation run")
    ap.add_argument("--native-only", action="store_true",
                    help="only the native FMUs from the C hosts, by platform")
    ap.add_argument("--wine", action="store_true",
                    help="also the win64 binaries under wine (needs wine and a Windows C compiler)")
    args = ap.parse_args(argv)
    import gyrodenoise as gd

    if args.native_only:
        from gyrodenoise.fmu.native import build_native_fmus
        with tempfile.TemporaryDirectory() as tmp:
            native_platforms(build_native_fmus(tmp), tmp, args.steps, wine=args.wine)
        return

    with tempfile.TemporaryDirectory() as tmp:
        fmu_dir = Path(args.fmu_dir) if args.fmu_dir else Path(tmp) / "fmus"
        if not args.fmu_dir:
            F.build_all(fmu_dir)
        empty = build_empty(tmp)
        n = args.steps
        z = gd.simulate("paper_fog", n, seed=0).rate_deg_s.tolist()
        rs = [0] * n

        print(f"FMU step loop, {n} steps, best of 3 (machine load matters: "
              f"{open('/proc/loadavg').read().split()[0]} load avg)")
        rows = []
        for label, path, params in [("empty pythonfmu FMU (floor)", empty, {}),
                                    ("FogDenoiser.fmu", fmu_dir / "FogDenoiser.fmu", {"sample_period": 0.005})]:
            for mode, fn in (("fmpy wrappers", loop_wrapped), ("direct FMI calls", loop_direct)):
                inst = F.FmuInstance(path, "bench")
                inst.initialize(**params)
                rate = best_of(lambda: fn(inst, z, rs))
                inst.free()
                rows.append((label, mode, rate))
                print(f"  {label:28s} {mode:17s} {rate:10.0f} steps/s  {1e6 / rate:7.1f} us/step")
        d = gd.Denoiser(200.0)
        t0 = time.perf_counter()
        for k in range(n):
            d.step(z[k], False)
        core = n / (time.perf_counter() - t0)
        print(f"  {'core Denoiser.step (no FMI)':28s} {gd.denoiser.core_name() + ' core':17s} {core:10.0f} steps/s  "
              f"{1e6 / core:7.1f} us/step")
        table = dict(((r[0], r[1]), r[2]) for r in rows)
        fd = table[("FogDenoiser.fmu", "direct FMI calls")]
        for mode in ("fmpy wrappers", "direct FMI calls"):
            ratio = table[("FogDenoiser.fmu", mode)] / table[("empty pythonfmu FMU (floor)", mode)]
            print(f"FogDenoiser / empty FMU, {mode}: {ratio:.2f}x (target >= 0.7x): "
                  f"{'met' if ratio >= 0.7 else 'NOT met'}")
        print(f"target >= 50000 FogDenoiser steps/s: {'met' if fd >= 50000 else 'NOT met'} ({fd:.0f})")
        from gyrodenoise.fmu.native import build_native_fmus
        nats = build_native_fmus(tmp)
        nat = nats["FogDenoiserNative"]
        sensor = ("true_rate", "restart", "measured_rate")
        c_empty = c_host_steps_per_s(empty, tmp, n)
        c_fd = c_host_steps_per_s(fmu_dir / "FogDenoiser.fmu", tmp, n, ["sample_period=0.005"])
        c_nat = c_host_steps_per_s(nat, tmp, 20 * n)
        c_sf = c_host_steps_per_s(fmu_dir / "SimulatedFog.fmu", tmp, n, signals=sensor)
        c_sfn = c_host_steps_per_s(nats["SimulatedFogNative"], tmp, 20 * n, signals=sensor)
        print("plain C host (tests/chost/host.c; libpython preloaded for pythonfmu):")
        print(f"  empty pythonfmu FMU (floor)  {c_empty:10.0f} steps/s")
        print(f"  FogDenoiser.fmu              {c_fd:10.0f} steps/s = {c_fd / c_empty:.2f}x the empty FMU "
              f"(target >= 0.7x): {'met' if c_fd / c_empty >= 0.7 else 'NOT met'}")
        print(f"  FogDenoiserNative.fmu        {c_nat:10.0f} steps/s = {c_nat / c_empty:.0f}x the empty pythonfmu "
              f"FMU (target >= 10x): {'met' if c_nat / c_empty >= 10 else 'NOT met'}")
        print(f"  SimulatedFog.fmu (paper_fog) {c_sf:10.0f} steps/s = {c_sf / c_empty:.2f}x the empty FMU")
        print(f"  SimulatedFogNative.fmu       {c_sfn:10.0f} steps/s = {c_sfn / c_empty:.0f}x the empty pythonfmu "
              f"FMU (target >= 10x): {'met' if c_sfn / c_empty >= 10 else 'NOT met'} (paper_fog; "
              f"{c_sfn / c_sf:.0f}x SimulatedFog.fmu)")
        native_platforms(nats, tmp, n, wine=args.wine)

        if not args.skip_long:
            res = F.validation_run(fmu_dir, duration_s=600.0, rate_deg_s=10.0, restart_at_s=300.0)
            print(f"10-min 200 Hz two-FMU validation run (fmpy, {res['case']['n_samples']} samples): "
                  f"{res['elapsed_s']:.2f} s stepping, {res['two_fmu_steps_per_s']:.0f} two-FMU steps/s; "
                  f"target <= 10 s: {'met' if res['elapsed_s'] <= 10 else 'NOT met'}; "
                  f"max |FMU - core| = {res['max_abs_diff_filtered_vs_denoise_deg_s']:.3g} deg/s")


if __name__ == "__main__":
    main()
