"""The native FMUs for every platform, cross-compiled on this machine.

`gyrodenoise fmu build` compiles the native FMU for linux64 (glibc 2.17 baseline),
win64 and darwin64 with zig (the ``ziglang`` PyPI package, a test extra) or
mingw-w64 (win64). Checked here:

- linux64: the highest GLIBC symbol version the binary needs is <= 2.17, it needs
  libc and libm only, exports the fmi2* functions only;
- win64: a PE32+ x86-64 DLL exporting the fmi2* functions only, importing system
  DLLs only; driven under wine by the C host cross-compiled for Windows
  (tests/chost/host.c), its output equals gd.denoise to 1e-12, the forbidden-call
  checks pass, and its steps/s is printed;
- darwin64: an x86-64 Mach-O dylib exporting the fmi2* functions only, linked to
  libSystem only, minimum macOS as declared. It cannot run here (no macOS, no
  Mach-O loader): these checks are on the file only.

`scripts/install_fmu_test_tools.sh` installs what these tests need (ziglang,
mingw-w64, wine); each test skips with the reason when its tool is absent.
"""
import os
import shutil
import subprocess
import sys
import zipfile

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.fmu import native

from tests.fmu import binfmt  # noqa: E402
from tests.helpers import CHOST, run_wine  # noqa: E402

FS = 200.0
FMI2_CS = {"fmi2Instantiate", "fmi2FreeInstance", "fmi2DoStep", "fmi2GetReal", "fmi2SetReal",
           "fmi2GetFMUstate", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate", "fmi2SetDebugLogging",
           "fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2CancelStep", "fmi2GetRealStatus"}
#: symbols the macOS linker defines in every dylib
MACHO_LINKER_SYMBOLS = {"_mh_dylib_header", "__dso_handle"}


@pytest.fixture(scope="module")
def unz(native_build, tmp_path_factory):
    d = tmp_path_factory.mktemp("platforms") / "FogDenoiserNative"
    with zipfile.ZipFile(native_build[0] / "FogDenoiserNative.fmu") as z:
        z.extractall(d)
    return d


def binary(unz, native_build, plat):
    what = native_build[1].get(plat, "not attempted")
    path = unz / "binaries" / plat / f"FogDenoiserNative{native.PLATFORMS[plat][0]}"
    if not path.is_file():
        pytest.skip(f"no {plat} binary built: {what} (scripts/install_fmu_test_tools.sh)")
    return path, what


def record(n=2400, seed=5):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    z = 1.0 + 2.0 * np.sin(2 * np.pi * 0.5 * t) * (t > 4.0) + 0.05 * rng.standard_normal(n)
    z[700] += 3.0
    rs = np.zeros(n, dtype=bool)
    rs[1600] = True
    return z, rs


# ------------------------------------------------------------------ linux64
def test_linux64_needs_glibc_2_17_at_most(unz, native_build):
    so, what = binary(unz, native_build, "linux64")
    if not what.startswith("zig"):
        pytest.skip(f"linux64 built with {what}: the glibc 2.17 baseline needs zig (pip install ziglang)")
    versions = binfmt.elf_glibc_versions(so)
    assert versions and max(versions) <= (2, 17), versions
    readelf = shutil.which("readelf")
    if readelf:
        dyn = subprocess.run([readelf, "-d", str(so)], capture_output=True, text=True, check=True).stdout
        needed = {ln.split("[")[1].split("]")[0] for ln in dyn.splitlines() if "(NEEDED)" in ln}
        assert needed == {"libc.so.6", "libm.so.6"}, needed
        syms = subprocess.run([readelf, "--dyn-syms", "-W", str(so)], capture_output=True, text=True,
                              check=True).stdout
        exported = {ln.split()[7].split("@")[0] for ln in syms.splitlines()
                    if len(ln.split()) >= 8 and ln.split()[4] == "GLOBAL" and ln.split()[6] != "UND"}
        assert exported and all(n.startswith("fmi2") for n in exported), sorted(exported)


# -------------------------------------------------------------------- win64
def test_win64_dll_exports_fmi2_only(unz, native_build):
    dll, _ = binary(unz, native_build, "win64")
    info = binfmt.pe_info(dll)
    assert info["machine"] == 0x8664 and info["is_dll"]
    assert FMI2_CS <= set(info["exports"]) and all(n.startswith("fmi2") for n in info["exports"]), info["exports"]
    system = {"kernel32.dll", "msvcrt.dll", "ucrtbase.dll"}
    assert all(d.lower() in system or d.lower().startswith("api-ms-win-crt-") for d in info["imports"]), info["imports"]


def _windows_cc():
    try:
        cc, _ = native.compiler_for("win64")
    except Exception as exc:
        pytest.skip(f"no Windows C compiler: {exc}")
    return cc


@pytest.fixture(scope="module")
def wine_host(unz, native_build, tmp_path_factory):
    binary(unz, native_build, "win64")
    wine = shutil.which("wine") or shutil.which("wine64")
    if wine is None:
        pytest.skip("wine not installed (scripts/install_fmu_test_tools.sh: apt-get install wine)")
    exe = tmp_path_factory.mktemp("winhost") / "host.exe"
    proc = subprocess.run([*_windows_cc(), "-std=c99", "-O2", f"-I{native.fmi_headers_dir()}",
                           str(CHOST / "host.c"), "-o", str(exe)],
                          capture_output=True, text=True, timeout=300, cwd=exe.parent)
    assert proc.returncode == 0, proc.stderr
    env = dict(os.environ, WINEDEBUG="-all")
    return [wine, str(exe)], env


def wine_run(wine_host, unz, *args, data=None, timeout=180):
    cmd, env = wine_host
    return run_wine([*cmd, "Z:" + str(unz), *args], input=data, env=env, timeout=timeout)


CASES = [("motion", {}), ("shakf", {}), ("kf", {}), ("lowpass", {"cutoff_hz": 7.5, "lowpass_order": 5})]


def test_win64_under_wine_equals_gd_denoise(wine_host, unz):
    z, rs = record()
    data = "".join(f"{float(v)!r} {int(r)}\n" for v, r in zip(z, rs))
    for method, extra in CASES:
        args = ["run", "--set", f"method={method}"] + [a for k, v in extra.items() for a in ("--set", f"{k}={v!r}")]
        proc = wine_run(wine_host, unz, *args, data=data)
        assert proc.returncode == 0, (method, proc.stderr[-2000:])
        out = np.array([float(x) for x in proc.stdout.split()])
        kw = {"cutoff_hz": extra["cutoff_hz"], "order": extra["lowpass_order"]} if extra else {}
        ref = gd.denoise(z, FS, method=method, restarts=rs, **kw)
        assert len(out) == len(ref)
        np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12, err_msg=method)


def test_win64_under_wine_forbidden_calls_and_steps_per_second(wine_host, unz):
    proc = wine_run(wine_host, unz, "forbidden", "--set", "lam=0.5", "--bad", "method=wiener",
                    "--bad", "cutoff_hz=-1")
    assert proc.returncode == 0 and "0 failed" in proc.stdout, proc.stdout + proc.stderr[-1000:]
    proc = wine_run(wine_host, unz, "bench", "--n", "2000000")
    assert proc.returncode == 0, proc.stderr
    rate = float(proc.stdout.split()[-1])
    print(f"\nFogDenoiserNative win64 under wine: {rate:,.0f} steps/s (C host, motion)")
    assert rate > 0


# ----------------------------------------------------------------- darwin64
def test_darwin64_dylib_inspected(unz, native_build):
    """darwin64 cannot run here (no macOS): the file is checked, not executed."""
    dylib, _ = binary(unz, native_build, "darwin64")
    info = binfmt.macho_info(dylib)
    assert info["cputype"] == binfmt.CPU_TYPE_X86_64 and info["filetype"] == binfmt.MH_DYLIB
    exports = set(info["exports"]) - MACHO_LINKER_SYMBOLS
    assert FMI2_CS <= exports and all(n.startswith("fmi2") for n in exports), sorted(exports)
    assert info["dylibs"] == ["/usr/lib/libSystem.B.dylib"], info["dylibs"]
    want = tuple(int(x) for x in native.DARWIN_MIN.split("."))
    assert info["min_macos"] == want, info["min_macos"]


def test_every_platform_in_the_model_description_sources(unz, native_build):
    """One source file listed, every built platform's binary in the FMU, and the reason
    for a platform skipped."""
    names = {p.relative_to(unz).as_posix() for p in unz.rglob("*") if p.is_file()}
    for plat, what in native_build[1].items():
        path = f"binaries/{plat}/FogDenoiserNative{native.PLATFORMS[plat][0]}"
        assert (path in names) != what.startswith("skipped"), (plat, what)
    xml = (unz / "modelDescription.xml").read_text()
    assert '<File name="fogdenoiser_native_all.c"/>' in xml and xml.count("<File ") == 1


def test_cli_unknown_platform_is_one_line_exit_2(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "fmu", "build", "--out", str(out),
                           "--platforms", "linux64,win32"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "--platforms" in proc.stderr and "win32" in proc.stderr
    assert "Traceback" not in proc.stderr and not out.exists()


def test_missing_cross_compiler_is_named(monkeypatch, tmp_path):
    """A platform asked for without its compiler: one line naming the platform and the fix."""
    monkeypatch.setattr(native, "zig_command", lambda: None)
    monkeypatch.setattr(native.shutil, "which", lambda name: None)
    with pytest.raises(native.InputError) as exc:
        native.build_native_fmu(tmp_path, platforms=["darwin64"])
    assert "darwin64" in str(exc.value) and "ziglang" in str(exc.value) and "\n" not in str(exc.value)
    assert not (tmp_path / "FogDenoiserNative.fmu").exists()
