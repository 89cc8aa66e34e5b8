"""The Python-free chain: SimulatedFogNative -> FogDenoiserNative driven
by a plain C program (tests/chost/chain.c: dlopen / LoadLibrary + the FMI 2.0 C API; no
Python in the process), on linux64 and on win64 under wine. Its CSV output is checked
against the library: measured_rate equal to gyrodenoise.simulate bit for bit, and
filtered_rate equal to gyrodenoise.denoise of that record (Gauss-Seidel master: the denoiser
gets the sample of the same step) to 1e-12. (The chain in fmpy's simulate_ssp and in
libcosim: test_build_and_run.py.)
"""
import io
import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.fmu import native
from gyrodenoise.simulator import load_card

from tests.fmu.fmi import needed_libraries, windows_program  # noqa: E402
from tests.helpers import CHOST, run_wine  # noqa: E402

pytest.importorskip("fmpy")     # the FMI 2.0 C headers

CASES = [("paper_fog", 4, "motion"), ("imar_fog", 21, "shakf"), ("kvh1750", 5, "kf")]


@pytest.fixture(scope="module")
def unz(native_build, tmp_path_factory):
    d = tmp_path_factory.mktemp("chain")
    out = {}
    for name in ("SimulatedFogNative", "FogDenoiserNative"):
        fmu = native_build[0] / f"{name}.fmu"
        if not fmu.is_file():
            pytest.skip(f"{name}.fmu not built")
        with zipfile.ZipFile(fmu) as z:
            z.extractall(d / name)
        out[name] = d / name
    return out, native_build[1]


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed")
    exe = tmp_path_factory.mktemp("chainhost") / "chain"
    proc = subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", "-Werror", f"-I{native.fmi_headers_dir()}",
                           str(CHOST / "chain.c"), "-o", str(exe), "-ldl"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return [str(exe)]


def inputs(n, fs):
    t = np.arange(n) / fs
    truth = 3.0 * np.sin(2 * np.pi * 0.5 * t) * (t > 2.0) + 0.5
    rs = np.zeros(n, dtype=bool)
    rs[n // 2] = True
    return truth, rs


def run_chain(cmd, fog, den, card, seed, method, truth, rs, fs, env=None, timeout=120):
    data = "".join(f"{float(w)!r} {int(r)}\n" for w, r in zip(truth, rs))
    proc = run_wine([*cmd, str(fog), str(den), "--fog", f"card={card}", "--fog", f"seed={seed}",
                     "--den", f"method={method}", "--den", f"sample_period={1.0 / fs!r}",
                     "--step", repr(1.0 / fs)],
                    input=data, env=env, timeout=timeout)      # files, not pipes (linux64 too)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.startswith("t_s,true_rate,restart,measured_rate,filtered_rate\n")
    return np.loadtxt(io.StringIO(proc.stdout), delimiter=",", skiprows=1)


def check(table, card, seed, method, truth, rs, fs, measured_atol=0.0):
    assert table.shape == (len(truth), 5)
    assert np.array_equal(table[:, 1], truth) and np.array_equal(table[:, 2].astype(bool), rs)
    sim = gd.simulate(card, len(truth), seed=seed, true_rate_deg_s=truth, restarts=rs).rate_deg_s
    if measured_atol == 0.0:
        assert np.array_equal(table[:, 3], sim), np.max(np.abs(table[:, 3] - sim))
    else:
        np.testing.assert_allclose(table[:, 3], sim, rtol=0, atol=measured_atol)
    ref = gd.denoise(table[:, 3], fs, method=method, restarts=rs)
    np.testing.assert_allclose(table[:, 4], ref, rtol=0, atol=1e-12)
    assert np.max(np.abs(table[:, 4] - table[:, 3])) > 0.0    # the denoiser did act on it


@pytest.mark.parametrize("card,seed,method", CASES, ids=[c[0] for c in CASES])
def test_c_chain_equals_simulate_then_denoise(unz, chain, card, seed, method):
    dirs, _ = unz
    fs = load_card(card).sample_rate_hz
    truth, rs = inputs(3000, fs)
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    table = run_chain(chain, dirs["SimulatedFogNative"], dirs["FogDenoiserNative"], card, seed, method,
                      truth, rs, fs, env=env)
    check(table, card, seed, method, truth, rs, fs)


def test_c_chain_runs_the_readme_command_with_relative_folders(unz, chain):
    """The docs' command (docs/cosim/non-python.md), `./chain SimulatedFogNative/ FogDenoiserNative/ --fog card=imar_fog ...`,
    run from the folder that holds the unzipped FMUs: relative folders and a bundled card. (The
    resource URI was built as file://SimulatedFogNative//resources, whose host part is the folder's
    name: the sensor refused the bundled card, exit status 100.)"""
    dirs, _ = unz
    card, seed, method = "imar_fog", 21, "shakf"
    fs = load_card(card).sample_rate_hz
    truth, rs = inputs(2000, fs)
    data = "".join(f"{float(w)!r} {int(r)}\n" for w, r in zip(truth, rs))
    proc = subprocess.run([*chain, "SimulatedFogNative/", "FogDenoiserNative/", "--fog", f"card={card}",
                           "--fog", f"seed={seed}", "--den", f"method={method}",
                           "--den", f"sample_period={1.0 / fs!r}", "--step", repr(1.0 / fs)],
                          input=data, capture_output=True, text=True, timeout=120,
                          cwd=dirs["SimulatedFogNative"].parent)
    assert proc.returncode == 0, proc.stderr[-2000:]
    table = np.loadtxt(io.StringIO(proc.stdout), delimiter=",", skiprows=1)
    check(table, card, seed, method, truth, rs, fs)


def test_c_chain_process_has_no_python(unz, chain):
    """The chain program and both FMU binaries link libc / libm / libdl only."""
    dirs, _ = unz
    files = [Path(chain[0])] + [dirs[n] / "binaries" / "linux64" / f"{n}.so"
                                 for n in ("SimulatedFogNative", "FogDenoiserNative")]
    for f in files:
        assert needed_libraries(f) <= {"libc.so.6", "libm.so.6", "libdl.so.2"}, f.name


def test_c_chain_steps_per_second(unz, chain):
    """Throughput of the two-FMU chain from C, printed (not asserted: benchmarks/bench_fmu.py)."""
    dirs, _ = unz
    proc = subprocess.run([*chain, str(dirs["SimulatedFogNative"]), str(dirs["FogDenoiserNative"]),
                           "--bench", "300000"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    rate = float(proc.stdout.split()[-1])
    print(f"\nSimulatedFogNative -> FogDenoiserNative from C: {rate:,.0f} two-FMU steps/s")
    assert rate > 0


@pytest.fixture(scope="module")
def wine_chain(unz, tmp_path_factory):
    dirs, report = unz
    for name in ("SimulatedFogNative", "FogDenoiserNative"):
        if not (dirs[name] / "binaries" / "win64" / f"{name}.dll").is_file():
            pytest.skip(f"no win64 binary of {name}: {report.get('win64', 'not attempted')}")
    return windows_program(CHOST / "chain.c", tmp_path_factory.mktemp("winchain"))


def test_win64_chain_under_wine_equals_simulate_then_denoise(unz, wine_chain):
    dirs, _ = unz
    cmd, env = wine_chain
    card, seed, method = CASES[1]
    fs = load_card(card).sample_rate_hz
    truth, rs = inputs(2000, fs)
    table = run_chain(cmd, "Z:" + str(dirs["SimulatedFogNative"]), "Z:" + str(dirs["FogDenoiserNative"]),
                      card, seed, method, truth, rs, fs, env=env, timeout=300)
    # msvcrt's libm may round log/exp/sin differently from glibc's in the last bit
    check(table, card, seed, method, truth, rs, fs, measured_atol=1e-12)
