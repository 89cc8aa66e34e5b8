"""Helpers of the FMI 3.0 FMU tests: the unzipped FMI 3.0 FMUs of the session's build, an
fmpy FMU3Slave that keeps its log and the plain C host tests/chost/host3.c."""
import io
import shutil
import subprocess
import zipfile

import numpy as np
import pytest

from gyrodenoise.fmu import native

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi3 import FMU3Slave, fmi3LogMessageCallback  # noqa: E402

from tests.helpers import CHOST  # noqa: E402

FMI3_FMUS = ("FogDenoiserNative3", "SimulatedFogNative3", "FogDenoiserImuNative3")


def unzip_all(folder, names, dest):
    """{name: (fmu path, unzipped folder, model description)} of the FMUs ``names`` in ``folder``
    (skips when one is missing)."""
    out = {}
    for name in names:
        fmu = folder / f"{name}.fmu"
        if not fmu.is_file():
            pytest.skip(f"{name}.fmu not built")
        with zipfile.ZipFile(fmu) as z:
            z.extractall(dest / name)
        out[name] = (fmu, dest / name, read_model_description(str(fmu)))
    return out


class Slave3:
    """An FMU3Slave instance with its log [(status, category, message)] kept."""

    def __init__(self, unz, md, instance="fmi3"):
        self.md = md
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.log = []
        self.s = FMU3Slave(guid=md.guid, unzipDirectory=str(unz), modelIdentifier=md.coSimulation.modelIdentifier,
                           instanceName=instance)
        self.s.instantiate(logMessage=fmi3LogMessageCallback(self._log))

    def _log(self, env, status, category, message):
        self.log.append((status, (category or b"").decode(), (message or b"").decode()))

    def set(self, **params):
        for name, value in params.items():
            v = next(x for x in self.md.modelVariables if x.name == name)
            {"Float64": self.s.setFloat64, "Int32": self.s.setInt32, "Boolean": self.s.setBoolean,
             "String": self.s.setString}[v.type]([v.valueReference], [value])


def build_host3(dest):
    """The FMI 3.0 C host (tests/chost/host3.c) compiled with gcc into ``dest``; skips without gcc."""
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed")
    exe = dest / "host3"
    proc = subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", "-Werror", f"-I{native.fmi_headers_dir()}",
                           str(CHOST / "host3.c"), "-o", str(exe), "-ldl"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return exe


def host3_run(exe, unz, md, ins, restart, outs, rows, init_sample=False):
    """Run the C host over an unzipped FMI 3.0 FMU: ``ins``/``outs`` [(name, n values)], ``rows``
    the stdin lines; returns the printed outputs (one row a sample) and the stderr."""
    vr = {v.name: v.valueReference for v in md.modelVariables}
    lib = unz / "binaries" / "x86_64-linux" / f"{md.coSimulation.modelIdentifier}.so"
    cmd = [str(exe), str(lib), md.guid, str(unz / "resources") + "/"]
    for name, n in ins:
        cmd += ["--in", f"{vr[name]}:{n}"]
    if restart:
        cmd += ["--restart", str(vr[restart])]
    for name, n in outs:
        cmd += ["--out", f"{vr[name]}:{n}"]
    if init_sample:
        cmd.append("--init-sample")
    proc = subprocess.run(cmd, input="".join(r + "\n" for r in rows), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return np.loadtxt(io.StringIO(proc.stdout), delimiter=",", ndmin=2), proc.stderr
