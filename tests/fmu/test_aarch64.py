"""The aarch64 binaries of the native FMUs: aarch64-linux executed under qemu, aarch64-darwin
inspected.

FMI 2.0 names x86 platforms only; FMI 2.0.4 (section 2.3) says any other platform uses the
FMI 3.0 platform tuple, so the binaries go to ``binaries/aarch64-linux`` and
``binaries/aarch64-darwin`` (:data:`gyrodenoise.fmu.native.PLATFORMS`).

- aarch64-linux: an AArch64 ELF needing GLIBC 2.17 at most, libc and libm only. The plain C
  hosts (tests/chost/host.c and chain.c) are cross-built with ``zig cc -target
  aarch64-linux-gnu.2.17`` and run with ``qemu-aarch64 -L /usr/aarch64-linux-gnu`` (user-mode
  emulation: the Debian packages qemu-user and libc6-arm64-cross). Their outputs equal
  gd.denoise and gd.simulate bit for bit, except the lowpass method (to 1e-13: the Butterworth
  design calls hypot(), and glibc's aarch64 hypot is 1 ULP off the x86_64 one for one of the
  poles; a libm difference, not an FMU one). All targets compile with -ffp-contract=off:
  without it clang contracts a*b+c into fma on aarch64 and the outputs differ from x86_64.
- aarch64-darwin: an arm64 Mach-O dylib exporting the fmi2* functions only, linked to
  libSystem only, minimum macOS 11.0. Not executed (no macOS here).

Each test skips with the reason where zig, qemu-aarch64 or the aarch64 C library is absent.
"""
import io
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.fmu import native
from gyrodenoise.simulator import load_card

from tests.fmu import binfmt  # noqa: E402
from tests.fmu.test_c_chain import inputs  # noqa: E402
from tests.fmu.test_platforms import CASES, FMI2_CS, FS, MACHO_LINKER_SYMBOLS, record  # noqa: E402
from tests.helpers import CHOST  # noqa: E402

pytest.importorskip("fmpy")     # the FMI 2.0 C headers

AARCH64_SYSROOT = Path("/usr/aarch64-linux-gnu")
CHAIN_CASES = [("paper_fog", 4, "motion"), ("imar_fog", 21, "shakf"), ("kvh1750", 5, "kf")]
#: lowpass: glibc's hypot differs by 1 ULP between aarch64 and x86_64 for one Butterworth pole
LOWPASS_ATOL = 1e-13
NAMES = ("FogDenoiserNative", "SimulatedFogNative")


@pytest.fixture(scope="module")
def unz(native_build, tmp_path_factory):
    """{model name: unzipped folder} of both native FMUs, with their report."""
    d = tmp_path_factory.mktemp("aarch64")
    out = {}
    for name in NAMES:
        with zipfile.ZipFile(native_build[0] / f"{name}.fmu") as z:
            z.extractall(d / name)
        out[name] = d / name
    return out, native_build[1]


def binary(unz, plat, name="FogDenoiserNative"):
    dirs, report = unz
    path = dirs[name] / "binaries" / plat / f"{name}{native.PLATFORMS[plat][0]}"
    if not path.is_file():
        pytest.skip(f"no {plat} binary of {name}: {report.get(plat, 'not attempted')} (pip install ziglang)")
    return path


def _zig_cc(target, source, exe):
    zig = native.zig_command()
    if zig is None:
        pytest.skip("zig not installed (pip install ziglang): the C hosts are cross-built with it")
    proc = subprocess.run([*zig, "cc", "-target", target, "-std=c99", "-O2", "-ffp-contract=off",
                           f"-I{native.fmi_headers_dir()}", str(source), "-o", str(exe), "-ldl"],
                          capture_output=True, text=True, timeout=300, cwd=exe.parent)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return exe


@pytest.fixture(scope="module")
def qemu(unz, tmp_path_factory):
    """{"host", "chain"}: the C hosts built for aarch64 Linux, as qemu-aarch64 command lines."""
    for name in NAMES:
        binary(unz, "aarch64-linux", name)
    exe = shutil.which("qemu-aarch64")
    if exe is None:
        pytest.skip("qemu-aarch64 not installed (apt-get install qemu-user)")
    if not (AARCH64_SYSROOT / "lib" / "ld-linux-aarch64.so.1").is_file():
        pytest.skip(f"no aarch64 C library in {AARCH64_SYSROOT} (apt-get install libc6-arm64-cross)")
    d = tmp_path_factory.mktemp("a64hosts")
    return {name: [exe, "-L", str(AARCH64_SYSROOT),
                   str(_zig_cc("aarch64-linux-gnu.2.17", CHOST / f"{name}.c", d / name))]
            for name in ("host", "chain")}


def run(cmd, *args, data=None, timeout=300):
    proc = subprocess.run([*cmd, *args], input=data, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


# ------------------------------------------------------------ aarch64-linux
def test_aarch64_linux_elf_needs_glibc_2_17_at_most(unz):
    for name in NAMES:
        so = binary(unz, "aarch64-linux", name)
        assert binfmt.elf_machine(so) == binfmt.EM_AARCH64
        versions = binfmt.elf_glibc_versions(so)
        assert versions and max(versions) <= (2, 17), versions
        readelf = shutil.which("readelf")
        if readelf:
            dyn = subprocess.run([readelf, "-d", str(so)], capture_output=True, text=True, check=True).stdout
            needed = {ln.split("[")[1].split("]")[0] for ln in dyn.splitlines() if "(NEEDED)" in ln}
            assert needed == {"libc.so.6", "libm.so.6"}, needed


def test_aarch64_linux_under_qemu_equals_gd_denoise(qemu, unz):
    """FogDenoiserNative (aarch64) driven by the aarch64 C host under qemu: every method's
    output is gd.denoise's, bit for bit (lowpass: to LOWPASS_ATOL, a libm hypot difference)."""
    dirs, _ = unz
    z, rs = record()
    data = "".join(f"{float(v)!r} {int(r)}\n" for v, r in zip(z, rs))
    for method, extra in CASES:
        args = ["run", "--set", f"method={method}"] + [a for k, v in extra.items() for a in ("--set", f"{k}={v!r}")]
        out = np.array([float(x) for x in run(qemu["host"], str(dirs["FogDenoiserNative"]), *args, data=data).split()])
        kw = {"cutoff_hz": extra["cutoff_hz"], "order": extra["lowpass_order"]} if extra else {}
        ref = gd.denoise(z, FS, method=method, restarts=rs, **kw)
        assert len(out) == len(ref)
        if method == "lowpass":
            np.testing.assert_allclose(out, ref, rtol=0, atol=LOWPASS_ATOL, err_msg=method)
        else:
            assert np.array_equal(out, ref), (method, np.max(np.abs(out - ref)))


@pytest.mark.parametrize("card,seed,method", CHAIN_CASES, ids=[c[0] for c in CHAIN_CASES])
def test_aarch64_linux_chain_under_qemu_equals_simulate_then_denoise(qemu, unz, card, seed, method):
    """SimulatedFogNative -> FogDenoiserNative, both aarch64, from the aarch64 chain program:
    measured_rate is gd.simulate's and filtered_rate gd.denoise's, bit for bit."""
    dirs, _ = unz
    fs = load_card(card).sample_rate_hz
    truth, rs = inputs(3000, fs)
    data = "".join(f"{float(w)!r} {int(r)}\n" for w, r in zip(truth, rs))
    out = run(qemu["chain"], str(dirs["SimulatedFogNative"]), str(dirs["FogDenoiserNative"]),
              "--fog", f"card={card}", "--fog", f"seed={seed}", "--den", f"method={method}",
              "--den", f"sample_period={1.0 / fs!r}", "--step", repr(1.0 / fs), data=data)
    table = np.loadtxt(io.StringIO(out), delimiter=",", skiprows=1)
    assert table.shape == (len(truth), 5)
    sim = gd.simulate(card, len(truth), seed=seed, true_rate_deg_s=truth, restarts=rs).rate_deg_s
    assert np.array_equal(table[:, 3], sim), np.max(np.abs(table[:, 3] - sim))
    ref = gd.denoise(table[:, 3], fs, method=method, restarts=rs)
    assert np.array_equal(table[:, 4], ref), np.max(np.abs(table[:, 4] - ref))


def test_aarch64_linux_forbidden_calls_under_qemu(qemu, unz):
    dirs, _ = unz
    out = run(qemu["host"], str(dirs["FogDenoiserNative"]), "forbidden", "--set", "lam=0.5",
              "--bad", "method=wiener", "--bad", "cutoff_hz=-1")
    assert "0 failed" in out, out


def test_aarch64_linux_steps_per_second_under_qemu_and_x86_64_native(qemu, unz, tmp_path):
    """steps/s of FogDenoiserNative (motion) from the C host: aarch64 under qemu (emulation, so
    far slower than real aarch64 hardware) and x86_64 natively, printed (not asserted)."""
    dirs, _ = unz
    rate_a64 = float(run(qemu["host"], str(dirs["FogDenoiserNative"]), "bench", "--n", "200000").split()[-1])
    host_x64 = _zig_cc("x86_64-linux-gnu.2.17", CHOST / "host.c", tmp_path / "host")
    rate_x64 = float(run([str(host_x64)], str(dirs["FogDenoiserNative"]), "bench", "--n", "2000000").split()[-1])
    print(f"\nFogDenoiserNative steps/s (C host, motion): aarch64 under qemu-aarch64 (emulated) "
          f"{rate_a64:,.0f}, x86_64 native {rate_x64:,.0f}")
    assert rate_a64 > 0 and rate_x64 > 0


# ----------------------------------------------------------- aarch64-darwin
def test_aarch64_darwin_dylib_inspected(unz):
    """aarch64-darwin cannot run here (no macOS): the file is checked, not executed."""
    for name in NAMES:
        info = binfmt.macho_info(binary(unz, "aarch64-darwin", name))
        assert info["cputype"] == binfmt.CPU_TYPE_ARM64 and info["filetype"] == binfmt.MH_DYLIB
        exports = set(info["exports"]) - MACHO_LINKER_SYMBOLS
        assert FMI2_CS <= exports and all(n.startswith("fmi2") for n in exports), sorted(exports)
        assert info["dylibs"] == ["/usr/lib/libSystem.B.dylib"], info["dylibs"]
        assert info["min_macos"] == tuple(int(x) for x in native.DARWIN_AARCH64_MIN.split(".")), info["min_macos"]


def test_platform_folders_are_fmi_names():
    """FMI 2.0's own names for x86_64, FMI 3.0 platform tuples (as FMI 2.0.4 asks) for aarch64."""
    assert set(native.PLATFORMS) == {"linux64", "win64", "darwin64", "aarch64-linux", "aarch64-darwin"}
    assert set(native.PLATFORM_FLAGS) == set(native.PLATFORMS)
    assert "-ffp-contract=off" in native.COMMON_FLAGS
