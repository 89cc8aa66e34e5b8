"""Steps per second of the native FMUs by FMI version and host, next to the library.

    python benchmarks/bench_fmi3.py --fmu-dir build       # FMUs from `gyrodenoise fmu build`

Runs the reference input (gyrodenoise.fmu.reference, N samples repeated) through:
fmpy (FMU2Slave for FMI 2.0, FMU3Slave for FMI 3.0: one set/step/get per sample) and the plain
C hosts (tests/chost/host.c for FMI 2.0, tests/chost/host3.c for FMI 3.0: one line of stdin
per sample, parsing and printing included), and prints each with its ratio to the library
(``gyrodenoise.denoise`` of the same samples, batch; ``Denoiser.step`` one sample a call).
The 3-axis FMU does three filters per step. Best of 3; the machine's load matters.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

import gyrodenoise as gd
from gyrodenoise.fmu import native
from gyrodenoise.fmu.reference import reference_tables

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from benchmarks._timing import best_of  # noqa: E402
from tests.fmu.fmi3 import Slave3, build_host3  # noqa: E402


def fmpy_steps_per_s(unz, md, z, rs, n_axes):
    from fmpy.fmi2 import FMU2Slave
    if md.fmiVersion == "3.0":
        s = Slave3(unz, md).s
        s.enterInitializationMode(startTime=0.0)
        set_r, get_r = s.setFloat64, s.getFloat64
    else:
        s = FMU2Slave(guid=md.guid, unzipDirectory=str(unz), modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="bench")
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        set_r, get_r = s.setReal, s.getReal
    s.exitInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    t0 = [0.0]

    def loop():
        k0 = int(round(t0[0] / 0.005))
        for k in range(len(z)):
            set_r([vr["raw_rate"]], [float(x) for x in np.atleast_1d(z[k])])
            s.setBoolean([vr["restart"]], [bool(rs[k])])
            s.doStep((k0 + k) * 0.005, 0.005)
            get_r([vr["filtered_rate"]], n_axes) if n_axes > 1 else get_r([vr["filtered_rate"]])
        t0[0] = (k0 + len(z)) * 0.005
    rate = len(z) / best_of(loop)
    s.terminate()
    s.freeInstance()
    return rate


def c_host_steps_per_s(host2, host3, unz, md, z, rs, n_axes):
    rows = "".join(" ".join(repr(float(x)) for x in np.atleast_1d(z[k])) + f" {int(rs[k])}\n"
                   for k in range(len(z)))
    if md.fmiVersion == "3.0":
        vr = {v.name: v.valueReference for v in md.modelVariables}
        lib = unz / "binaries" / "x86_64-linux" / f"{md.coSimulation.modelIdentifier}.so"
        cmd = [str(host3), str(lib), md.guid, str(unz / "resources") + "/", "--in", f"{vr['raw_rate']}:{n_axes}",
               "--restart", str(vr["restart"]), "--out", f"{vr['filtered_rate']}:{n_axes}"]
    else:
        cmd = [str(host2), str(unz), "run"]
    return len(z) / best_of(lambda: subprocess.run(cmd, input=rows, capture_output=True, text=True, check=True))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fmu-dir", default="build", help="folder of the built FMUs (default: build/)")
    ap.add_argument("--repeat", type=int, default=25, help="times the 800-sample reference input is repeated")
    args = ap.parse_args(argv)
    folder = Path(args.fmu_dir)
    ins, _ = reference_tables("denoiser")
    z = np.tile(ins["raw_rate"], args.repeat)
    rs = np.tile(ins["restart"], args.repeat)
    n = len(z)
    lib_batch = n / best_of(lambda: gd.denoise(z, 200.0, restarts=rs))
    d = gd.Denoiser(200.0)

    def per_sample():
        for k in range(n):
            d.step(float(z[k]), restart=bool(rs[k]))
    lib_step = n / best_of(per_sample, 1)
    print(f"{n} samples of the reference input (load avg {open('/proc/loadavg').read().split()[0]})")
    print(f"  library gd.denoise (batch)            {lib_batch:12.0f} samples/s")
    print(f"  library Denoiser.step (one a call)    {lib_step:12.0f} samples/s")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        host2 = tmp / "host"
        subprocess.run(["gcc", "-std=c99", "-O2", f"-I{native.fmi_headers_dir()}", str(REPO / "tests/chost/host.c"),
                        "-o", str(host2), "-ldl"], check=True)
        host3 = build_host3(tmp)
        from fmpy import read_model_description
        print(f"  {'FMU':24s} {'FMI':4s} {'host':5s} {'steps/s':>12s}  {'x batch':>8s} {'x step':>8s}")
        for name, n_axes in (("FogDenoiserNative", 1), ("FogDenoiserNative3", 1), ("FogDenoiserImuNative3", 3)):
            fmu = folder / f"{name}.fmu"
            if not fmu.is_file():
                print(f"  {name}: not built in {folder}")
                continue
            unz = tmp / name
            with zipfile.ZipFile(fmu) as zf:
                zf.extractall(unz)
            md = read_model_description(str(fmu))
            zz = np.column_stack([z] * n_axes) if n_axes > 1 else z
            for host, rate in (("fmpy", fmpy_steps_per_s(unz, md, zz, rs, n_axes)),
                               ("C", c_host_steps_per_s(host2, host3, unz, md, zz, rs, n_axes))):
                print(f"  {name:24s} {md.fmiVersion:4s} {host:5s} {rate:12.0f}  {rate / lib_batch:8.3f} "
                      f"{rate / lib_step:8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
