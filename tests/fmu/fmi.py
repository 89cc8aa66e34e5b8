"""Helpers of the FMU tests: fmpy callbacks that keep the log, an FMI call expected to fail
with a reason, a shared object's exports and needed libraries, a source rebuild by fmpy
(cmake), a C program cross-compiled for win64 and run under wine."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from gyrodenoise.errors import InputError
from gyrodenoise.fmu import native

fmpy = pytest.importorskip("fmpy")
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,  # noqa: E402
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

FMI_WARNING, FMI_DISCARD, FMI_ERROR = 1, 2, 3


class Logger:
    """fmpy callbacks that keep the log messages (status, category, text)."""

    def __init__(self):
        self.messages = []
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)

    def _log(self, env, name, status, category, message):
        self.messages.append((status, (category or b"").decode(), (message or b"").decode()))

    def errors(self):
        return [m for s, c, m in self.messages if s >= FMI_ERROR]


def expect_error(logger, call, *args):
    """``call(*args)`` fails with fmi2Error and logs a reason."""
    before = len(logger.errors())
    with pytest.raises(FMICallException) as exc:
        call(*args)
    assert exc.value.status == FMI_ERROR
    assert len(logger.errors()) > before, "no reason logged"
    return logger.errors()[-1]


def exported_symbols(so):
    """The names a shared object exports (nm -D --defined-only); skips without binutils."""
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm (binutils) not installed")
    out = subprocess.run([nm, "-D", "--defined-only", str(so)], capture_output=True, text=True,
                         check=True).stdout
    return {line.split()[-1] for line in out.splitlines() if line.strip()}


def needed_libraries(so):
    """The libraries a shared object needs (its NEEDED entries, readelf -d); skips without binutils."""
    readelf = shutil.which("readelf")
    if readelf is None:
        pytest.skip("readelf (binutils) not installed")
    dyn = subprocess.run([readelf, "-d", str(so)], capture_output=True, text=True, check=True).stdout
    return {line.split("[")[1].split("]")[0] for line in dyn.splitlines() if "(NEEDED)" in line}


#: the cmake options the docs and the fmi2Instantiate message give for a rebuild with libm
REBUILD_WITH_LIBM = {"CMAKE_C_STANDARD_LIBRARIES:STRING": "-lm", "CMAKE_C_FLAGS:STRING": "-DGD_LIBM_LINKED"}


def fmpy_rebuild(built, tmp_path, monkeypatch, cmake_options=None):
    """The FMU's sources rebuilt by fmpy's build_platform_binary (its own CMakeLists: no flags,
    no libraries of ours); returns the unzipped folder with the new binaries/linux64."""
    from fmpy.build import build_platform_binary
    cmake = shutil.which("cmake") or str(Path(sys.executable).parent / "cmake")
    if not Path(cmake).exists():
        pytest.skip("cmake not installed (pip install cmake)")
    monkeypatch.setenv("PATH", str(Path(cmake).parent) + os.pathsep + os.environ.get("PATH", ""))
    unz = tmp_path / "unzipped"
    shutil.copytree(built[1], unz)
    shutil.rmtree(unz / "binaries")
    (tmp_path / "cmake_build").mkdir()
    build_platform_binary(unz, tmp_path / "cmake_build", cmake_options=cmake_options)
    assert len(list((unz / "binaries" / "linux64").glob("*.so"))) == 1   # (also used for SimulatedFogNative)
    return unz


def windows_program(source, out_dir):
    """(wine command, environment) of the C program ``source`` (tests/chost) cross-compiled
    for win64; skips with the reason when wine or a Windows C compiler is absent."""
    wine = shutil.which("wine") or shutil.which("wine64")
    if wine is None:
        pytest.skip("wine not installed (scripts/install_fmu_test_tools.sh)")
    try:
        cc, _ = native.compiler_for("win64")
    except InputError as exc:
        pytest.skip(f"no Windows C compiler: {exc}")
    exe = Path(out_dir) / (Path(source).stem + ".exe")
    proc = subprocess.run([*cc, "-std=c99", "-O2", f"-I{native.fmi_headers_dir()}", str(source), "-o", str(exe)],
                          capture_output=True, text=True, timeout=300, cwd=exe.parent)
    assert proc.returncode == 0, proc.stderr
    return [wine, str(exe)], dict(os.environ, WINEDEBUG="-all")
