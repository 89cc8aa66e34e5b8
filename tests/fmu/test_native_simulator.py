"""SimulatedFogNative.fmu: the sensor model gdsim.c as a native FMI 2.0 FMU.

Built once per session with the other native FMU (conftest ``native_build``: linux64, and
win64 / darwin64 where a cross compiler is found). Checked against independent
references: ``gyrodenoise.simulate`` (numpy over the compiled core, itself tested equal to
the plain-Python specification simkernels.py), bit for bit, for every card term, through
fmpy's FMU2Slave, a plain C host (tests/chost/host.c) and, for win64, the same host
cross-compiled and run under wine; the variables against the pythonfmu SimulatedFog.fmu;
fmpy validate; the binaries' imports and exports; the calls FMI 2.0 forbids (refused with
fmi2Error and a logged reason, by the FMI layer it shares with FogDenoiserNative).
"""
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.fmu import native, simnative
from gyrodenoise.core import simkernels as SK
from gyrodenoise.simulator import load_card, parse_card

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE  # noqa: E402

from tests.fmu import binfmt  # noqa: E402
from tests.fmu.fmi import (FMI_DISCARD, FMI_WARNING, REBUILD_WITH_LIBM, Logger, expect_error, exported_symbols, fmpy_rebuild,  # noqa: E402
                           needed_libraries, windows_program)
from tests.helpers import CHOST, DATA, REPO, run_wine  # noqa: E402

@pytest.fixture(scope="module")
def built(native_build, tmp_path_factory):
    fmu = native_build[0] / "SimulatedFogNative.fmu"
    if not fmu.is_file():
        pytest.skip("SimulatedFogNative.fmu not built")
    unz = tmp_path_factory.mktemp("simnative") / "unzipped"
    with zipfile.ZipFile(fmu) as z:
        z.extractall(unz)
    return fmu, unz, native_build[1]


@pytest.fixture(scope="module")
def every_term_card(tmp_path_factory):
    """(ModelCard, path of its TOML, compiled text) of the card with every term (tests/data)
    plus two angle Gauss-Markov terms (one with sigma 0: not drawn)."""
    path = tmp_path_factory.mktemp("cards") / "every_term_agm.toml"
    path.write_text((DATA / "every_term.toml").read_text()
                    + "[[terms.angle_gauss_markov]]\nsigma = 5.0e-5\ntau = 0.3\n"
                    + "[[terms.angle_gauss_markov]]\nsigma = 0.0\ntau = 1.0\n")
    return load_card(path), path, simnative.compile_card(path)


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed")
    exe = tmp_path_factory.mktemp("chost") / "host"
    subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", f"-I{native.fmi_headers_dir()}",
                    str(CHOST / "host.c"), "-o", str(exe), "-ldl"],
                   check=True, capture_output=True, text=True)
    return exe


class CountingLogger(Logger):
    """A Logger whose memory callbacks keep the blocks alive: {pointer: bytes}."""

    def __init__(self):
        super().__init__()
        self.live = {}
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(self._calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(self._free)

    def _calloc(self, n, size):
        ptr = fmpy.calloc(n, size)
        self.live[ptr] = n * size
        return ptr

    def _free(self, ptr):
        self.live.pop(ptr, None)
        fmpy.free(ptr)


def slave(built, md, logger=None, unz=None, **params):
    """An instance in initialisation mode with ``params`` set."""
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(unz or built[1]),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="simnative")
    s.instantiate(callbacks=logger.callbacks if logger else None, loggingOn=False)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    types = {v.name: (v.type, v.valueReference) for v in md.modelVariables}
    for name, value in params.items():
        t, ref = types[name]
        {"Real": s.setReal, "Integer": s.setInteger, "Boolean": s.setBoolean,
         "String": s.setString}[t]([ref], [value])
    return s


def inputs(n, fs, seed=11):
    """A true rate (steps, a sine, noise-free) and two restarts."""
    t = np.arange(n) / fs
    truth = 5.0 * np.sin(2 * np.pi * 0.3 * t) + 2.0 * (t > 1.0)
    rs = np.zeros(n, dtype=bool)
    rs[[n // 3, 2 * n // 3]] = True
    return truth, rs


def run(s, vr, truth, rs, fs, t0=0.0, init=True):
    """The sensor's samples for ``truth`` and ``rs`` (and its restarted outputs).

    ``init=True``: ``s`` is in initialisation mode; sample 0 is taken at
    fmi2ExitInitializationMode from truth[0], rs[0] set before it, then the step from
    t0 + (i-1)/fs produces sample i (the inputs set before it). ``init=False``: ``s`` is
    initialised at time t0; the step from t0 + i/fs produces sample i."""
    out, restarted = np.empty(len(truth)), np.empty(len(truth), dtype=bool)
    for i in range(len(truth)):
        s.setReal([vr["true_rate"]], [float(truth[i])])
        s.setBoolean([vr["restart"]], [bool(rs[i])])
        if init and i == 0:
            s.exitInitializationMode()
        else:
            s.doStep(t0 + (i - 1 if init else i) / fs, 1.0 / fs)
        out[i] = s.getReal([vr["measured_rate"]])[0]
        restarted[i] = s.getBoolean([vr["restarted"]])[0]
    return out, restarted


# ------------------------------------------------------------- the FMU file
def test_fmpy_validate_clean(built):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(built[0])) == []


def test_fmutool_check_clean(built):
    """FMU Manipulation Toolbox's conformity and semantic checks."""
    exe = Path(sys.executable).parent / "fmutool"
    if not exe.exists():
        pytest.skip("fmutool not installed")
    out = subprocess.run([str(exe), "-input", str(built[0]), "-check"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "ERROR" not in out.stdout + out.stderr, out.stdout + out.stderr
    assert "compliant with FMI-2.0" in out.stdout + out.stderr and "No semantic error" in out.stdout + out.stderr


def test_same_variables_as_pythonfmu_simulatedfog(md, tmp_path):
    """Names, types, causality, variability, initial, units and start values of SimulatedFog.fmu."""
    from gyrodenoise.fmu.build import build_fmu
    ref = read_model_description(str(build_fmu("SimulatedFog", tmp_path)))

    def sig(m):
        return {v.name: (v.type, v.causality, v.variability, v.initial, v.unit,
                         None if v.start is None else str(v.start).lower().replace("0.0", "0"))
                for v in m.modelVariables}
    assert sig(md) == sig(ref)
    assert float(md.defaultExperiment.stepSize) == float(ref.defaultExperiment.stepSize)


def test_contents_bundled_cards_and_no_python(built, md):
    fmu, unz, _ = built
    names = set(zipfile.ZipFile(fmu).namelist())
    assert {"binaries/linux64/SimulatedFogNative.so", "sources/simulatedfog_native_all.c", "sources/gdsim.c",
            "sources/gdfmi.c", "sources/simulatedfog_native_vars.h"} <= names
    for name in simnative.bundled_cards():
        assert f"resources/cards/{name}.gdcard" in names
        assert zipfile.ZipFile(fmu).read(f"resources/cards/{name}.gdcard").decode() == \
            simnative.compile_card(name)
    cs = md.coSimulation
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate and not cs.needsExecutionTool
    so = unz / "binaries" / "linux64" / "SimulatedFogNative.so"
    assert b"libpython" not in so.read_bytes().lower() and b"Py_Initialize" not in so.read_bytes()
    header = (unz / "sources" / "simulatedfog_native_vars.h").read_text()
    assert f'#define GD_GUID "{md.guid}"' in header
    assert f"#define GD_CARD_LEN {len(simnative.CARD_FIELDS)}" in header


def test_a_stale_native_fmu_is_detected(built, tmp_path):
    """gyrodenoise fmu run rebuilds the native FMUs of its libcosim/SSP chain when their
    sources or bundled cards differ from the tree."""
    assert native.native_stale_reason(built[0], simnative.SIMULATED_FOG_NATIVE) is None
    old = tmp_path / "old.fmu"
    with zipfile.ZipFile(built[0]) as src, zipfile.ZipFile(old, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            dst.writestr(item, data + b"/* older */\n" if item.filename == "sources/gdsim.c" else data)
    assert "sources/gdsim.c" in native.native_stale_reason(old, simnative.SIMULATED_FOG_NATIVE)
    assert native.native_stale_reason(tmp_path / "none.fmu", simnative.SIMULATED_FOG_NATIVE) == "missing"


def test_compiled_card_is_the_card_vector_bit_for_bit(every_term_card):
    """The compiled text holds each card-vector value exactly (IEEE 754 bits) and its decimal."""
    card, _, text = every_term_card
    lines = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    assert lines[0] == f"gdcard 1 {SK.CARD_LEN}"
    v = SK.card_vector(card)
    for (name, bits, dec), x, want in zip((ln.split() for ln in lines[1:]), v, simnative.CARD_FIELDS):
        assert name == want
        assert np.float64(x).view(np.uint64) == int(bits, 16) and float(dec) == x
    assert len(lines) == 1 + len(v)


def test_a_card_with_a_long_name_compiles_to_a_text_the_fmu_takes(built, md, vr, every_term_card, tmp_path):
    """A card named with 5000 characters compiled to 9384 characters: the FMU refused it
    ("card is 9384 characters long, at most 8191 allowed") and `fmu run --master ssp` aborted
    inside libcosim. The name in the comment is now shortened; the FMU takes the text and gives
    gd.simulate's numbers."""
    import re
    c_src = (REPO / "gyrodenoise" / "fmu" / "sources" / "native" / "simulatedfog_native.c").read_text()
    text_max = int(re.search(r"#define CARD_LEN (\d+)", c_src).group(1)) - 1    # the terminating NUL
    _, path, _ = every_term_card
    long_path = tmp_path / "long_name.toml"
    assert "\nname =" not in path.read_text()
    long_path.write_text(path.read_text().replace("[sensor]\n", "[sensor]\nname = \"" + "x" * 5000 + "\"\n", 1))
    assert len(load_card(long_path).name) == 5000
    text = simnative.compile_card(long_path)
    assert len(text) <= text_max and getattr(simnative, "CARD_TEXT_MAX", text_max) == text_max
    fs = load_card(long_path).sample_rate_hz
    truth, rs = inputs(500, fs)
    s = slave(built, md, card=text, seed=3)
    out, _ = run(s, vr, truth, rs, fs)
    s.terminate()
    s.freeInstance()
    ref = gd.simulate(long_path, len(truth), seed=3, true_rate_deg_s=truth, restarts=rs).rate_deg_s
    assert np.array_equal(out, ref)


# ------------------------------------------------------------- the numbers
@pytest.mark.parametrize("card_name,seed", [("paper_fog", 0), ("imar_fog", 7), ("kvh1750", 123456789)])
def test_bundled_cards_equal_gd_simulate_bit_for_bit(built, md, vr, card_name, seed):
    fs = load_card(card_name).sample_rate_hz
    truth, rs = inputs(2000, fs)
    s = slave(built, md, card=card_name, seed=seed)
    out, restarted = run(s, vr, truth, rs, fs)
    s.terminate()
    s.freeInstance()
    ref = gd.simulate(card_name, len(truth), seed=seed, true_rate_deg_s=truth, restarts=rs).rate_deg_s
    assert np.array_equal(out, ref), np.max(np.abs(out - ref))
    assert np.array_equal(restarted, rs)


def test_every_card_term_equals_gd_simulate_bit_for_bit(built, md, vr, every_term_card, tmp_path):
    """The compiled text as the card parameter, and a compiled card file's path (the card of
    tests/data/every_term.toml: every term, one Gauss-Markov term with sigma 0)."""
    card, _, text = every_term_card
    fs = card.sample_rate_hz
    truth, rs = inputs(3000, fs)
    ref = gd.simulate(card, len(truth), seed=42, true_rate_deg_s=truth, restarts=rs).rate_deg_s
    compiled = tmp_path / "run=3 [x]" / "every term.gdcard"     # '=' and '[' in a path: still a path
    compiled.parent.mkdir()
    compiled.write_text(text)
    for given in (text, str(compiled)):
        s = slave(built, md, card=given, seed=42)
        out, _ = run(s, vr, truth, rs, fs)
        s.terminate()
        s.freeInstance()
        assert np.array_equal(out, ref), np.max(np.abs(out - ref))


def test_state_round_trip_and_serialized_into_another_instance(built, md, vr, every_term_card):
    card, _, text = every_term_card
    fs = card.sample_rate_hz
    truth, rs = inputs(600, fs)
    ref = gd.simulate(card, 600, seed=5, true_rate_deg_s=truth, restarts=rs).rate_deg_s
    s = slave(built, md, card=text, seed=5)
    head, _ = run(s, vr, truth[:300], rs[:300], fs)
    st = s.getFMUstate()
    blob = s.serializeFMUstate(st)
    tail_a, _ = run(s, vr, truth[300:], rs[300:], fs, t0=299 / fs, init=False)
    s.setFMUstate(st)
    tail_b, _ = run(s, vr, truth[300:], rs[300:], fs, t0=299 / fs, init=False)
    other = slave(built, md)                     # another instance, default card: the state carries the card
    other.exitInitializationMode()
    other.setFMUstate(other.deSerializeFMUstate(blob))
    tail_c, _ = run(other, vr, truth[300:], rs[300:], fs, t0=299 / fs, init=False)
    assert np.array_equal(np.concatenate([head, tail_a]), ref)
    assert np.array_equal(tail_a, tail_b) and np.array_equal(tail_a, tail_c)
    s.freeFMUstate(st)
    for inst in (s, other):
        inst.terminate()
        inst.freeInstance()


def test_corrupted_or_foreign_serialized_state_is_an_error(built, md, vr, native_build):
    log = Logger()
    s = slave(built, md, logger=log)
    run(s, vr, *inputs(20, 200.0), 200.0)
    st = s.getFMUstate()
    blob = bytearray(s.serializeFMUstate(st))
    s.freeFMUstate(st)
    flipped = bytes(blob[:60]) + bytes([blob[60] ^ 0x5A]) + bytes(blob[61:])
    for bad, why in ((blob[:-9], "truncated"), (flipped, "checksum"),
                     (b"GDNATIVE" + bytes(blob[8:]), "not a serialized SimulatedFogNative state")):
        r = expect_error(log, s.deSerializeFMUstate, bytes(bad))
        assert "fmi2DeSerializeFMUstate" in r and why in r, r
        s.reset()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
    s.terminate()
    s.freeInstance()


def _fnv1a(data):
    h = 1469598103934665603
    for b in data:
        h = ((h ^ b) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return h


def test_consistent_checksum_but_inconsistent_state_is_refused(built, md, vr):
    """A block whose checksum is right but whose seed no longer matches its generator
    parameters (an edited or mis-built state) is refused by the model's own check."""
    import struct
    log = Logger()
    s = slave(built, md, logger=log, seed=8)
    s.exitInitializationMode()
    st = s.getFMUstate()
    blob = bytearray(s.serializeFMUstate(st))
    s.freeFMUstate(st)
    at = 32 + 6 * 8 + 2 * 4          # header, core fields, restart, restarted: then the seed (int32)
    assert struct.unpack_from("<i", blob, at)[0] == 8
    struct.pack_into("<i", blob, at, 9)
    struct.pack_into("<Q", blob, len(blob) - 8, _fnv1a(bytes(blob[:-8])))
    assert "sensor buffers do not match the card" in expect_error(log, s.deSerializeFMUstate, bytes(blob))
    s.freeInstance()


# ----------------------------------------------------------- the card rules
@pytest.mark.parametrize("card,reason", [
    ("no_such_card", "no such bundled card"),
    ("[sensor]\nsample_rate_hz = 200.0\n", "TOML text cannot be read"),
    ("gdcard 1 3\nsample_rate_hz 0x4069000000000000\n", "compile the card again"),
    (f"gdcard 1 {SK.CARD_LEN}\nsample_rate_hz 0x40690000000000zz\n", "is not a hex digit"),
    (f"gdcard 1 {SK.CARD_LEN}\nQ 0x4069000000000000\n", "field sample_rate_hz expected"),
    ("gdcard 1 92\nsample_rate_hz 0x4069000000000000\n", "compile the card again"),   # before angle GM
])
def test_bad_card_refused_at_exit_initialization_with_the_reason(built, md, card, reason):
    log = Logger()
    s = slave(built, md, logger=log, card=card)
    assert reason in expect_error(log, s.exitInitializationMode)
    s.freeInstance()


def test_unusable_card_values_and_seed_refused(built, md, every_term_card):
    _, _, text = every_term_card
    fs_bits = f"0x{int(np.float64(100.0).view(np.uint64)):016x}"
    zero_fs = text.replace(f"sample_rate_hz {fs_bits}", "sample_rate_hz 0x0000000000000000")
    assert zero_fs != text
    nan_q = text.replace("\nQ 0x", "\nQ 0x7ff8000000000000 was 0x")
    for card, seed, reason in ((zero_fs, 0, "sample_rate_hz must be > 0"),
                               (nan_q, 0, "Q is not a usable number"),
                               ("paper_fog", -1, "seed must be an integer >= 0")):
        log = Logger()
        s = slave(built, md, logger=log, card=card, seed=seed)
        assert reason in expect_error(log, s.exitInitializationMode)
        s.freeInstance()


def test_second_use_in_a_process_after_the_first_unzip_folder_is_gone(built, md, vr, tmp_path):
    """A second instance in a process, after the first one's unzip folder is gone: each instance reads
    the bundled card from its own resources."""
    ref = gd.simulate("paper_fog", 200, seed=3).rate_deg_s
    for k in range(2):
        unz = tmp_path / f"copy{k}"
        shutil.copytree(built[1], unz)
        s = slave(built, md, unz=unz, seed=3)
        out, _ = run(s, vr, np.zeros(200), np.zeros(200, dtype=bool), 200.0)
        s.terminate()
        s.freeInstance()
        shutil.rmtree(unz)
        assert np.array_equal(out, ref)


def test_step_size_rules_and_nan_input(built, md, vr):
    log = Logger()
    s = slave(built, md, logger=log)
    s.exitInitializationMode()
    assert s.fmi2DoStep(s.component, 0.0, 0.01, 1) == FMI_WARNING
    assert any(st == FMI_WARNING and "differs from the card's sample period" in m for st, _, m in log.messages)
    s.setReal([vr["true_rate"]], [float("nan")])
    assert "true_rate is nan" in expect_error(log, s.doStep, 0.01, 0.005)
    s.freeInstance()
    log = Logger()
    s = slave(built, md, logger=log, strict_step_size=True)
    s.exitInitializationMode()
    with pytest.raises(FMICallException) as exc:
        s.doStep(0.0, 0.01)
    assert exc.value.status == FMI_DISCARD
    assert any(st == FMI_DISCARD and "step refused (strict_step_size)" in m for st, _, m in log.messages)
    s.terminate()
    s.freeInstance()


def test_free_instance_frees_everything_it_allocated(built, md, vr):
    log = CountingLogger()
    s = slave(built, md, logger=log, card="imar_fog")
    run(s, vr, *inputs(50, 400.0), 400.0)
    kept = [s.getFMUstate(), s.getFMUstate()]
    kept.append(s.deSerializeFMUstate(s.serializeFMUstate(kept[0])))
    assert log.live
    s.terminate()
    s.freeInstance()
    assert log.live == {}, f"{len(log.live)} blocks not freed by fmi2FreeInstance"


# ------------------------------------------------------------------ C host
def host_cmd(host, unz, mode, *args):
    return [*host, str(unz), mode, "--in", "true_rate", "--restart", "restart", "--out", "measured_rate", "--init-sample",
            *args]


def host_data(truth, rs):
    return "".join(f"{float(v)!r} {int(r)}\n" for v, r in zip(truth, rs))


def test_c_host_equals_gd_simulate(built, host, every_term_card):
    card, _, text = every_term_card
    truth, rs = inputs(2500, card.sample_rate_hz)
    for given, seed, c in ((text, 9, card), ("paper_fog", 2, "paper_fog")):
        fs = load_card(c).sample_rate_hz
        proc = subprocess.run(host_cmd([str(host)], built[1], "run", "--set", f"card={given}",
                                       "--set", f"seed={seed}", "--step", repr(1.0 / fs)),
                              input=host_data(truth, rs), capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, proc.stderr[-2000:]
        out = np.array([float(x) for x in proc.stdout.split()])
        ref = gd.simulate(c, len(truth), seed=seed, true_rate_deg_s=truth, restarts=rs).rate_deg_s
        assert np.array_equal(out, ref), np.max(np.abs(out - ref))


@pytest.mark.parametrize("with_libm", [True, False], ids=["with libm", "without libm"])
def test_fmpy_source_rebuild(built, host, tmp_path, monkeypatch, with_libm):
    """The one listed source file, rebuilt by fmpy's build_platform_binary (no flags of ours):
    fmi2* exports only; with libm linked (the docs' option) it equals gd.simulate from a
    host without libm; without, that host gets fmi2Instantiate's refusal with the reason."""
    unz = fmpy_rebuild(built, tmp_path, monkeypatch, REBUILD_WITH_LIBM if with_libm else None)
    so = unz / "binaries" / "linux64" / "SimulatedFogNative.so"
    assert all(n.startswith("fmi2") for n in exported_symbols(so))
    assert ("libm.so.6" in needed_libraries(so)) == with_libm
    truth, rs = inputs(1000, 100.0)
    proc = subprocess.run(host_cmd([str(host)], unz, "run", "--set", "card=paper_fog", "--set", "seed=6"),
                          input=host_data(truth, rs), capture_output=True, text=True, timeout=60)
    if with_libm:
        assert proc.returncode == 0, proc.stderr[-2000:]
        out = np.array([float(x) for x in proc.stdout.split()])
        assert np.array_equal(out, gd.simulate("paper_fog", 1000, seed=6, true_rate_deg_s=truth,
                                               restarts=rs).rate_deg_s)
    else:
        assert proc.returncode != 0 and "built without -lm" in proc.stderr, proc.stderr[-2000:]


FORBIDDEN_ARGS = ["--set", "seed=4", "--set", "card=imar_fog", "--set", "strict_step_size=true",
                  "--bad", "card=no_such_card", "--bad", "seed=-3", "--bad", "card=[sensor]",
                  "--step", "0.0025"]


def test_c_host_forbidden_calls(built, host):
    proc = subprocess.run(host_cmd([str(host)], built[1], "forbidden", *FORBIDDEN_ARGS),
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "FAIL" not in proc.stdout and "0 failed" in proc.stdout
    assert proc.stdout.count("PASS setting fixed parameter") == 3
    assert proc.stdout.count("PASS fmi2ExitInitializationMode with") == 3


# ------------------------------------------------------------- platforms
def binary(built, plat):
    path = built[1] / "binaries" / plat / f"SimulatedFogNative{native.PLATFORMS[plat][0]}"
    if not path.is_file():
        pytest.skip(f"no {plat} binary built: {built[2].get(plat, 'not attempted')} "
                    "(scripts/install_fmu_test_tools.sh)")
    return path


def test_linux64_glibc_2_17_libc_libm_only_fmi2_exports(built):
    so = binary(built, "linux64")
    if not built[2].get("linux64", "").startswith("zig"):
        pytest.skip(f"linux64 built with {built[2].get('linux64')}: the glibc 2.17 baseline needs zig")
    versions = binfmt.elf_glibc_versions(so)
    assert versions and max(versions) <= (2, 17), versions
    assert needed_libraries(so) == {"libc.so.6", "libm.so.6"}
    exported = exported_symbols(so)
    assert exported and all(n.startswith("fmi2") for n in exported), sorted(exported)


def test_win64_dll_and_darwin64_dylib_exports(built):
    dll = binary(built, "win64")
    info = binfmt.pe_info(dll)
    assert info["machine"] == 0x8664 and info["is_dll"]
    assert "fmi2DoStep" in info["exports"] and all(n.startswith("fmi2") for n in info["exports"])
    system = {"kernel32.dll", "msvcrt.dll", "ucrtbase.dll"}
    assert all(d.lower() in system or d.lower().startswith("api-ms-win-crt-") for d in info["imports"])
    dylib = binary(built, "darwin64")
    mach = binfmt.macho_info(dylib)     # darwin64 cannot run here (no macOS): the file is checked
    assert mach["cputype"] == binfmt.CPU_TYPE_X86_64 and mach["filetype"] == binfmt.MH_DYLIB
    exports = set(mach["exports"]) - {"_mh_dylib_header", "__dso_handle"}
    assert "fmi2DoStep" in exports and all(n.startswith("fmi2") for n in exports), sorted(exports)
    assert mach["dylibs"] == ["/usr/lib/libSystem.B.dylib"], mach["dylibs"]


@pytest.fixture(scope="module")
def wine_host(built, tmp_path_factory):
    binary(built, "win64")
    return windows_program(CHOST / "host.c", tmp_path_factory.mktemp("winhost"))


def test_win64_under_wine_equals_gd_simulate(built, wine_host, every_term_card):
    cmd, env = wine_host
    card, _, text = every_term_card
    truth, rs = inputs(1500, card.sample_rate_hz)
    unz = "Z:" + str(built[1])
    for given, seed, c in ((text, 9, card), ("kvh1750", 77, "kvh1750")):
        fs = load_card(c).sample_rate_hz
        proc = run_wine(host_cmd(cmd, unz, "run", "--set", f"card={given}", "--set", f"seed={seed}",
                                 "--step", repr(1.0 / fs)),
                        input=host_data(truth, rs), env=env, timeout=180)
        assert proc.returncode == 0, proc.stderr[-2000:]
        out = np.array([float(x) for x in proc.stdout.split()])
        ref = gd.simulate(c, len(truth), seed=seed, true_rate_deg_s=truth, restarts=rs).rate_deg_s
        # libm's log/sin/exp differ between glibc and msvcrt in the last bit at most
        np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)
    proc = run_wine(host_cmd(cmd, unz, "forbidden", *FORBIDDEN_ARGS), env=env, timeout=180)
    assert proc.returncode == 0 and "0 failed" in proc.stdout, proc.stdout + proc.stderr


# ------------------------------------------------------------------- CLI
def test_cli_card_compiles_and_refuses_a_bad_card(tmp_path, every_term_card):
    from gyrodenoise.cli import main
    _, path, text = every_term_card
    out = tmp_path / "c.gdcard"
    assert main(["fmu", "card", str(path), "--out", str(out)]) == 0
    assert out.read_text() == text
    bad = tmp_path / "bad.toml"
    bad.write_text("[sensor]\nsample_rate_hz = -1\n")
    out2 = tmp_path / "bad.gdcard"
    assert main(["fmu", "card", str(bad), "--out", str(out2)]) == 2
    assert not out2.exists()
    with pytest.raises(Exception):
        parse_card(bad.read_text())
