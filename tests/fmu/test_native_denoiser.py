"""FogDenoiserNative.fmu: the native FMI 2.0 denoiser.

Built once per module with gcc (gyrodenoise.fmu.native.build_native_fmu), then
checked by fmpy validate, fmutool -check, fmpy's FMU2Slave and a plain C host
(tests/chost/host.c: dlopen + the FMI 2.0 headers): outputs equal to
gd.denoise, FMU state round trips, the calls FMI 2.0 forbids answered with
fmi2Error and a logged reason, legal resource URIs, clean exits.
"""
import ctypes
import math
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.core import kernels as K
from gyrodenoise.core.methods import BY_FMU
from gyrodenoise.errors import InputError
from gyrodenoise.fmu import native

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,  # noqa: E402
                       )

FS = 1.0 / 0.005        # the sample rate the FMU derives from sample_period
N = 2400
RESTART_AT = 1500

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")


from tests.fmu.fmi import (FMI_DISCARD, FMI_ERROR, FMI_WARNING, REBUILD_WITH_LIBM, Logger,  # noqa: E402
                           expect_error, exported_symbols, fmpy_rebuild, needed_libraries)
from tests.helpers import CHOST, REPO  # noqa: E402


# ----------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def built(native_build, tmp_path_factory):
    fmu = native_build[0] / "FogDenoiserNative.fmu"
    unz = tmp_path_factory.mktemp("native") / "unzipped"
    with zipfile.ZipFile(fmu) as z:
        z.extractall(unz)
    return fmu, unz


@pytest.fixture(scope="module")
def host(built, tmp_path_factory):
    exe = tmp_path_factory.mktemp("chost") / "host"
    # no -lm: the FMU binary must bring its own math library (it is NEEDED by the .so)
    subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", f"-I{native.fmi_headers_dir()}",
                    str(CHOST / "host.c"), "-o", str(exe), "-ldl"],
                   check=True, capture_output=True, text=True)
    return exe


def record(n=N, seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    z = 2.0 + 3.0 * np.sin(2 * np.pi * 0.7 * t) * (t > 3.0) + 0.05 * rng.standard_normal(n)
    z[min(900, n // 3)] += 4.0          # an outlier
    rs = np.zeros(n, dtype=bool)
    rs[min(RESTART_AT, 2 * n // 3)] = True
    return z, rs


def slave(built, md, logger=None, logging_on=False, **params):
    """An instance of the native FMU in initialisation mode with ``params`` set."""
    fmu, unz = built
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(unz), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="native")
    s.instantiate(callbacks=logger.callbacks if logger else None, loggingOn=logging_on)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    set_params(s, md, params)
    return s


def set_params(s, md, params):
    types = {v.name: (v.type, v.valueReference) for v in md.modelVariables}
    for name, value in params.items():
        t, ref = types[name]
        {"Real": s.setReal, "Integer": s.setInteger, "Boolean": s.setBoolean,
         "String": s.setString}[t]([ref], [value])


def run(s, vr, z, rs, t0=0.0, h=0.005):
    out = np.empty(len(z))
    for i in range(len(z)):
        s.setReal([vr["raw_rate"]], [float(z[i])])
        s.setBoolean([vr["restart"]], [bool(rs[i])])
        s.doStep(t0 + i * h, h)
        out[i] = s.getReal([vr["filtered_rate"]])[0]
    return out


# -------------------------------------------------------- the built FMU
def test_fmpy_validate_clean(built):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(built[0])) == []


def test_fmutool_check_clean(built):
    exe = shutil.which("fmutool") or str(Path(sys.executable).parent / "fmutool")
    if not Path(exe).exists():
        pytest.skip("fmutool not installed")
    proc = subprocess.run([exe, "-input", str(built[0]), "-check"], capture_output=True, text=True,
                          timeout=60)
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, text
    assert "compliant with FMI-2.0" in text and "No semantic error" in text, text
    assert "ERROR" not in text, text


def test_binary_needs_no_python(built):
    so = built[1] / "binaries" / "linux64" / "FogDenoiserNative.so"
    readelf = shutil.which("readelf")
    if readelf is None:
        pytest.skip("readelf not installed")
    dyn = subprocess.run([readelf, "-d", str(so)], capture_output=True, text=True, check=True).stdout
    needed = {line.split("[")[1].split("]")[0] for line in dyn.splitlines() if "(NEEDED)" in line}
    assert needed <= {"libm.so.6", "libc.so.6"}, needed
    assert "python" not in so.read_bytes().decode("latin-1").lower().replace("pythonfmu", "")
    syms = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True, text=True).stdout
    exported = {line.split()[-1] for line in syms.splitlines() if line.strip()}
    assert exported and all(name.startswith("fmi2") for name in exported), exported


def test_fmu_contents_and_model_description(built, md):
    fmu, unz = built
    names = set(zipfile.ZipFile(fmu).namelist())
    assert {"modelDescription.xml", "binaries/linux64/FogDenoiserNative.so",
            "sources/fogdenoiser_native.c", "sources/gdcore.c", "sources/gdcore.h", "sources/gdbias.c",
            "sources/fogdenoiser_native_vars.h"} <= names
    cs = md.coSimulation
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate and not cs.needsExecutionTool
    assert md.defaultExperiment.stepSize == "0.005" or float(md.defaultExperiment.stepSize) == 0.005
    units = {u.name for u in md.unitDefinitions}
    assert {"deg/s", "deg2/s2", "s", "Hz"} <= units
    by = {v.name: v for v in md.modelVariables}
    for name in ("raw_rate", "filtered_rate", "c", "innovation"):
        assert by[name].unit == "deg/s"
    for name in ("R_hat", "Q_hat", "q0", "r0", "p0_kf", "r_floor"):
        assert by[name].unit == "deg2/s2"
    assert by["sample_period"].unit == "s" and by["cutoff_hz"].unit == "Hz"
    assert (by["ar_order"].min, by["ar_order"].max) == ("1", "6")
    assert (by["lowpass_order"].min, by["lowpass_order"].max) == ("1", "8")
    assert by["method"].type == "String"
    for m in K.METHODS:
        assert f"'{m}'" in by["method"].description
    # the C header was generated from the same table as the XML
    header = (unz / "sources" / "fogdenoiser_native_vars.h").read_text()
    assert f'#define GD_GUID "{md.guid}"' in header
    for v in md.modelVariables:
        assert f"#define VR_{v.name} {v.valueReference}u" in header


def test_same_variables_as_pythonfmu_fogdenoiser(md, tmp_path):
    from gyrodenoise.fmu.build import build_fmu
    try:
        py_fmu = build_fmu("FogDenoiser", out_dir=tmp_path)
    except Exception as exc:  # pragma: no cover - pythonfmu missing
        pytest.skip(f"pythonfmu FogDenoiser not buildable here: {exc}")
    ref = read_model_description(str(py_fmu))

    def sig(m):
        return {v.name: (v.type, v.causality, v.variability) for v in m.modelVariables}
    assert sig(md) == sig(ref)


def test_build_without_gcc_is_one_line_input_error(monkeypatch, tmp_path):
    monkeypatch.setenv("GYRODENOISE_CC", "no-such-compiler-xyz")
    with pytest.raises(InputError) as exc:
        native.build_native_fmu(tmp_path)
    assert "\n" not in str(exc.value) and "no-such-compiler-xyz" in str(exc.value)


# ------------------------------------------------------ outputs via fmpy
CASES = [("motion", {}), ("shakf", {}), ("kf", {}),
         ("lowpass", {"cutoff_hz": 10.0, "lowpass_order": 3}),
         ("motion", {"max_motion_hz": 20.0}),      # the rigid-body option
         ("one_euro", {"min_cutoff_hz": 2.0, "beta": 0.02, "d_cutoff_hz": 3.0})]


def _core_kw(extra):
    """gd.denoise's arguments for the FMU parameters ``extra`` (the registry's names)."""
    return {BY_FMU[k].name if k in BY_FMU else k: v for k, v in extra.items()}


@pytest.mark.parametrize("method,extra", CASES, ids=[c[0] + "".join("-" + k for k in c[1]) for c in CASES])
def test_outputs_equal_gd_denoise(built, md, vr, method, extra):
    z, rs = record()
    if "max_motion_hz" in extra:        # a 60 Hz 'frame vibration' for the option to remove
        z = z + 2.0 * np.sin(2 * np.pi * 60.0 * np.arange(z.size) / FS)
    s = slave(built, md, method=method, **extra)
    s.exitInitializationMode()
    out = run(s, vr, z, rs)
    kw = _core_kw(extra)
    ref = gd.denoise(z, FS, method=method, restarts=rs, **kw)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)
    # the readouts equal the Python Denoiser's after the same samples
    den = gd.Denoiser(sample_rate_hz=FS, method=method, **kw)
    for i in range(N):
        den.step(z[i], rs[i])
    phis = s.getReal([vr[f"phi_{k}"] for k in range(1, 7)])
    np.testing.assert_allclose(phis[:3], den.phi, rtol=0, atol=1e-12)
    assert phis[3:] == [0.0, 0.0, 0.0]
    c, r_hat, q_hat, innov = s.getReal([vr["c"], vr["R_hat"], vr["Q_hat"], vr["innovation"]])
    assert abs(c - den.c) <= 1e-12 * max(1.0, abs(den.c))
    assert (r_hat, q_hat, innov) == pytest.approx((den.R_hat, den.q_hat, den.innovation), abs=1e-12)
    assert s.getBoolean([vr["converged"]])[0] == den.converged
    assert s.getInteger([vr["n_rejected"]])[0] == den.n_rejected
    s.terminate()
    s.freeInstance()


def test_lowpass_every_order_and_default_cutoff(built, md, vr):
    z, rs = record(n=300)
    for order in range(1, 9):
        for cutoff in (0.0, 3.3, 49.9):
            s = slave(built, md, method="lowpass", cutoff_hz=cutoff, lowpass_order=order)
            s.exitInitializationMode()
            out = run(s, vr, z, rs)
            ref = gd.denoise(z, FS, method="lowpass", restarts=rs, order=order,
                             cutoff_hz=None if cutoff == 0.0 else cutoff)
            assert np.max(np.abs(out - ref)) <= 1e-12, (order, cutoff)
            s.terminate()
            s.freeInstance()


def test_other_parameters_and_sample_period(built, md, vr):
    z, rs = record(n=1200)
    params = dict(ar_order=2, sample_period=0.01, lam=0.999, b=0.98, gamma=2.0, q0=1e-4, r0=2e-3,
                  p0_rls=100.0, p0_kf=2.0, warmup_s=0.7, r_floor=1e-12, outlier_sigma=4.0,
                  outlier_run=5)
    for method in ("sh_classic", "none", "motion"):
        s = slave(built, md, method=f"  {method.upper()} ", **params)
        s.exitInitializationMode()
        out = run(s, vr, z, rs, h=0.01)
        kw = {k: v for k, v in params.items() if k != "sample_period"}
        ref = gd.denoise(z, 1.0 / 0.01, method=method, restarts=rs, **kw)
        np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)
        s.terminate()
        s.freeInstance()


# -------------------------------------------------------------- FMU state
def test_state_get_set_and_serialize_round_trip(built, md, vr):
    z, rs = record()
    s = slave(built, md, method="shakf")
    s.exitInitializationMode()
    run(s, vr, z[:1000], rs[:1000])
    state = s.getFMUstate()
    blob = s.serializeFMUstate(state)
    tail_a = run(s, vr, z[1000:1600], rs[1000:1600], t0=5.0)
    s.setFMUstate(state)
    tail_b = run(s, vr, z[1000:1600], rs[1000:1600], t0=5.0)
    assert np.array_equal(tail_a, tail_b)
    # a serialized state restores in another instance
    s2 = slave(built, md)
    s2.exitInitializationMode()
    state2 = s2.deSerializeFMUstate(blob)
    s2.setFMUstate(state2)
    assert s2.getString([vr["method"]])[0] == b"shakf" or s2.getString([vr["method"]])[0] == "shakf"
    tail_c = run(s2, vr, z[1000:1600], rs[1000:1600], t0=5.0)
    assert np.array_equal(tail_a, tail_c)
    assert s2.serializeFMUstate(state2) == blob
    s.freeFMUstate(state)
    s2.freeFMUstate(state2)
    for inst in (s, s2):
        inst.terminate()
        inst.freeInstance()


def test_serialized_state_size_is_the_one_the_readme_states(built, md, vr):
    """docs/cosim/native.md, "FMU state": "(N bytes at order 3)" is what fmi2SerializeFMUstate
    gives at order 3."""
    import re
    text = (REPO / "docs" / "cosim" / "native.md").read_text(encoding="utf-8")
    found = re.search(r"FogDenoiserNative \((\d+) bytes at order 3", text)
    assert found, "docs/cosim/native.md no longer states the state size at order 3"
    s = slave(built, md, ar_order=3)
    s.exitInitializationMode()
    state = s.getFMUstate()
    assert len(s.serializeFMUstate(state)) == int(found.group(1))
    s.freeFMUstate(state)
    s.terminate()
    s.freeInstance()


def test_corrupted_serialized_state_is_an_error(built, md, vr):
    log = Logger()
    s = slave(built, md, logger=log)
    s.exitInitializationMode()
    run(s, vr, *record(n=50))
    st = s.getFMUstate()
    blob = bytearray(s.serializeFMUstate(st))
    s.freeFMUstate(st)
    for bad in (blob[:-9], blob[:10], bytes(blob[:40]) + b"\xff" + bytes(blob[41:]),
                b"GDNATIVE" + bytes(blob[8:100]) + bytes(len(blob) - 100)):
        r = expect_error(log, s.deSerializeFMUstate, bytes(bad))
        assert "fmi2DeSerializeFMUstate" in r
        s.reset()               # the error state is left by fmi2Reset
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
    s.terminate()
    s.freeInstance()


def test_set_fmu_state_recovers_from_error(built, md, vr):
    log = Logger()
    s = slave(built, md, logger=log)
    s.exitInitializationMode()
    z, rs = record(n=400)
    run(s, vr, z[:200], rs[:200])
    st = s.getFMUstate()
    expect_error(log, s.doStep, 1.0, -0.005)           # -> error state
    expect_error(log, s.doStep, 1.0, 0.005)            # refused there
    s.setFMUstate(st)                                  # back to stepComplete
    out = run(s, vr, z[200:], rs[200:], t0=1.0)
    assert np.array_equal(out, gd.denoise(z, FS, restarts=rs)[200:])
    s.freeFMUstate(st)
    s.terminate()
    s.freeInstance()


def test_reset_restores_instantiated_defaults(built, md, vr):
    s = slave(built, md, method="kf", lam=0.9, ar_order=2)
    s.exitInitializationMode()
    run(s, vr, *record(n=300))
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    assert s.getString([vr["method"]])[0] in (b"motion", "motion")
    assert s.getReal([vr["lam"]]) == [1.0]
    assert s.getInteger([vr["ar_order"]]) == [3]
    s.exitInitializationMode()
    z, rs = record()
    assert np.array_equal(run(s, vr, z, rs), gd.denoise(z, FS, restarts=rs))
    s.terminate()
    s.freeInstance()


# ----------------------------------------------------------- forbidden calls
def test_forbidden_calls_are_fmi2error_with_a_reason(built, md, vr):
    log = Logger()

    def fresh(init=True):
        s = slave(built, md, logger=log)
        if init:
            s.exitInitializationMode()
        return s

    s = fresh()
    s.setReal([vr["raw_rate"]], [1.0])
    s.doStep(0.0, 0.005)
    s.terminate()
    assert "terminated" in expect_error(log, s.doStep, 0.005, 0.005)
    s.freeInstance()

    s = fresh()
    assert "output" in expect_error(log, s.setReal, [vr["filtered_rate"]], [1.0])
    s.freeInstance()
    s = fresh(init=False)
    expect_error(log, s.setBoolean, [vr["converged"]], [True])
    s.freeInstance()

    for h in (-0.005, 0.0, math.nan, math.inf):
        s = fresh()
        assert "step size" in expect_error(log, s.doStep, 0.0, h)
        s.freeInstance()

    s = fresh()
    assert "unknown value reference" in expect_error(log, s.getReal, [9999])
    s.freeInstance()
    s = fresh(init=False)
    assert "unknown value reference" in expect_error(log, s.setReal, [9999], [1.0])
    s.freeInstance()
    s = fresh()
    assert "not a Real" in expect_error(log, s.getReal, [vr["ar_order"]])
    s.freeInstance()

    s = fresh(init=False)
    assert "not allowed" in expect_error(log, s.enterInitializationMode)
    s.freeInstance()

    for name, value in (("lam", 0.5), ("ar_order", 2), ("method", "kf"), ("strict_step_size", True)):
        s = fresh()
        with pytest.raises(FMICallException) as exc:
            set_params(s, md, {name: value})
        assert exc.value.status == FMI_ERROR
        assert "fixed parameter" in log.errors()[-1] and name in log.errors()[-1]
        s.freeInstance()

    s = fresh()
    assert "not allowed" in expect_error(log, s.exitInitializationMode)
    s.freeInstance()


BAD_PARAMS = [
    ({"lam": 1.5}, "lam out of range"), ({"b": 1.0}, "b out of range"),
    ({"gamma": math.nan}, "gamma out of range"), ({"method": "wiener"}, "method must be one of"),
    ({"ar_order": 7}, "ar_order must be an integer 1..6"), ({"ar_order": 0}, "ar_order"),
    ({"sample_period": 0.0}, "sample_period"), ({"sample_period": -1.0}, "sample_period"),
    ({"r_floor": 0.0}, "r_floor"), ({"outlier_sigma": 1.0}, "outlier_sigma"),
    ({"outlier_run": 0}, "outlier_run"), ({"q0": -1.0}, "q0"), ({"warmup_s": math.inf}, "warmup_s"),
    ({"method": "lowpass", "cutoff_hz": 100.0}, "cutoff_hz"),
    ({"method": "lowpass", "lowpass_order": 9}, "order must be an integer 1..8"),
    ({"max_motion_hz": math.nan}, "max_motion_hz out of range"),
    ({"max_motion_hz": math.inf}, "max_motion_hz out of range"),
    ({"max_motion_hz": -1.0}, "max_motion_hz out of range"),
    ({"max_motion_hz": 100.0}, "max_motion_hz out of range"),      # = half the sample rate
    ({"method": "shakf", "max_motion_hz": -1.0}, "max_motion_hz out of range"),   # whatever the method
    ({"method": "one_euro", "min_cutoff_hz": 0.0}, "min_cutoff_hz out of range: 0 (must be > 0 Hz)"),
    ({"method": "one_euro", "beta": -1.0}, "beta out of range"),
    ({"method": "one_euro", "d_cutoff_hz": math.inf}, "d_cutoff_hz out of range"),
]


@pytest.mark.parametrize("params,reason", BAD_PARAMS, ids=[r for _, r in BAD_PARAMS])
def test_invalid_parameter_refused_at_exit_initialization(built, md, params, reason):
    log = Logger()
    s = slave(built, md, logger=log, **params)
    msg = expect_error(log, s.exitInitializationMode)
    assert "invalid parameter" in msg and reason in msg
    # the same parameters are refused by the Python core too
    if not any(k in params for k in ("ar_order", "sample_period")):
        kw = _core_kw(params)
        with pytest.raises(ValueError):
            K.make_params(sample_rate_hz=FS, **kw)
    s.freeInstance()


@pytest.mark.parametrize("method", ["motion", "shakf", "none"])
@pytest.mark.parametrize("cutoff", [math.nan, math.inf, -1.0])
def test_bad_cutoff_refused_whatever_the_method(built, md, method, cutoff):
    """cutoff_hz NaN, inf or -1 (declared min 0) is refused whatever the method, lowpass or not."""
    log = Logger()
    s = slave(built, md, logger=log, method=method, cutoff_hz=cutoff)
    msg = expect_error(log, s.exitInitializationMode)
    assert "invalid parameter" in msg and "cutoff_hz out of range" in msg
    s.freeInstance()
    s = slave(built, md, logger=log, method=method, lowpass_order=9)
    assert "lowpass_order must be an integer 1..8" in expect_error(log, s.exitInitializationMode)
    s.freeInstance()


def test_strictly_positive_parameters_declare_a_positive_min(md):
    """Parameters that must be > 0 declare a positive min, not min="0.0" (FMI min is inclusive)."""
    by = {v.name: v for v in md.modelVariables}
    for name in ("sample_period", "lam", "b", "p0_rls", "p0_kf", "r_floor"):
        lo = float(by[name].min)
        assert 0.0 < lo <= sys.float_info.min, (name, by[name].min)
    assert float(by["b"].max) < 1.0 and float(by["lam"].max) == 1.0
    for name in ("q0", "r0", "warmup_s", "cutoff_hz", "outlier_sigma"):   # these may be 0
        assert float(by[name].min) == 0.0, name


def test_free_instance_frees_the_states_the_host_did_not_free(built, md, vr):
    """fmi2FreeInstance frees the FMU states the host had not freed (FMI 2.0: it frees
    everything the instance allocated). Counted through the host's memory callbacks."""
    live = {}

    def alloc(n, size):
        ptr = fmpy.calloc(n, size)
        live[ptr] = n * size
        return ptr

    def free(ptr):
        live.pop(ptr, None)
        fmpy.free(ptr)

    log = Logger()
    log.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(alloc)
    log.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    s = slave(built, md, logger=log, method="shakf")
    s.exitInitializationMode()
    run(s, vr, *record(n=100))
    kept = [s.getFMUstate(), s.getFMUstate()]
    blob = s.serializeFMUstate(kept[0])
    kept.append(s.deSerializeFMUstate(blob))
    s.freeFMUstate(kept[1])
    assert live, "the instance allocated nothing through the callbacks"
    s.terminate()
    s.freeInstance()
    assert live == {}, f"{len(live)} blocks ({sum(live.values())} bytes) not freed by fmi2FreeInstance"


def test_step_size_mismatch_warns_or_discards(built, md, vr):
    log = Logger()
    s = slave(built, md, logger=log, logging_on=True)
    s.exitInitializationMode()
    s.setReal([vr["raw_rate"]], [1.0])
    assert s.fmi2DoStep(s.component, 0.0, 0.01, 1) == FMI_WARNING
    assert any(st == FMI_WARNING and "differs from sample_period" in m for st, _, m in log.messages)
    s.freeInstance()
    log = Logger()
    s = slave(built, md, logger=log, strict_step_size=True)          # logging off: still explained
    s.exitInitializationMode()
    with pytest.raises(FMICallException) as exc:
        s.doStep(0.0, 0.01)
    assert exc.value.status == FMI_DISCARD
    assert any(st == FMI_DISCARD and "step refused (strict_step_size)" in m for st, _, m in log.messages)
    s.terminate()               # allowed from stepFailed
    s.freeInstance()


def test_logging_honours_logging_on_and_categories(built, md, vr):
    log = Logger()
    s = slave(built, md, logger=log, logging_on=False)
    s.exitInitializationMode()                              # information: not logged (logging off)
    assert log.messages == []
    # a warning status is explained even with logging off
    assert s.fmi2DoStep(s.component, 0.0, 0.01, 1) == FMI_WARNING
    assert [(st, c) for st, c, _ in log.messages] == [(FMI_WARNING, "logStatusWarning")]
    assert "differs from sample_period" in log.messages[-1][2]
    expect_error(log, s.setReal, [vr["c"]], [0.0])          # an error is always explained
    assert [c for _, c, _ in log.messages] == ["logStatusWarning", "logStatusError"]
    s.freeInstance()
    log = Logger()
    s = slave(built, md, logger=log, logging_on=False)
    s.setDebugLogging(True, ["logStatusWarning"])
    s.exitInitializationMode()                              # information (logAll): not logged
    assert s.fmi2DoStep(s.component, 0.0, 0.01, 1) == FMI_WARNING
    assert [c for _, c, _ in log.messages] == ["logStatusWarning"]
    s.setDebugLogging(True, [])                             # no category: all of them
    s.terminate()
    assert log.messages[-1][1] == "logAll" and "step(s) had a size" in log.messages[-1][2]
    s.freeInstance()


def test_unknown_log_category_is_a_warning_with_its_reason(built, md):
    """fmi2SetDebugLogging with an unknown category returns fmi2Warning and logs the reason,
    even with logging off."""
    log = Logger()
    s = slave(built, md, logger=log, logging_on=False)
    for logging_on in (0, 1):
        cats = (ctypes.c_char_p * 2)(b"logStatusWarning", b"noSuchCategory")
        assert s.fmi2SetDebugLogging(s.component, logging_on, 2, cats) == FMI_WARNING
        status, cat, msg = log.messages[-1]
        assert (status, cat) == (FMI_WARNING, "logStatusWarning")
        assert "unknown log category" in msg and "'noSuchCategory'" in msg
    assert len(log.messages) == 2
    s.freeInstance()


# ------------------------------------------------------------------ C host
def host_run(host, unz, z, rs, *args, uri=None):
    data = "".join(f"{float(v)!r} {int(r)}\n" for v, r in zip(z, rs))
    cmd = [str(host), str(unz), "run", *args]
    if uri is not None:
        cmd += ["--uri", uri]
    proc = subprocess.run(cmd, input=data, capture_output=True, text=True, timeout=60)
    return proc


@pytest.mark.parametrize("method,extra", CASES[:2] + CASES[3:], ids=["motion", "shakf", "lowpass", "motion-rigid",
                                                                     "one_euro"])
def test_c_host_equals_gd_denoise(built, host, method, extra):
    z, rs = record()
    args = ["--set", f"method={method}"] + [a for k, v in extra.items() for a in ("--set", f"{k}={v!r}")]
    proc = host_run(host, built[1], z, rs, *args)
    assert proc.returncode == 0, proc.stderr
    out = np.array([float(x) for x in proc.stdout.split()])
    kw = _core_kw(extra)
    np.testing.assert_allclose(out, gd.denoise(z, FS, method=method, restarts=rs, **kw), rtol=0, atol=1e-12)


def test_c_host_uri_forms_and_20_clean_exits(built, host):
    unz = built[1].resolve()
    z, rs = record(n=400)
    ref = gd.denoise(z, FS, restarts=rs)
    uris = ["NULL", f"file:{unz}/resources", f"file://{unz}/resources",
            f"file://localhost{unz}/resources", f"file:///{str(unz).lstrip('/')}/resources/", ""]
    for k in range(20):
        proc = host_run(host, built[1], z, rs, uri=uris[k % len(uris)])
        assert proc.returncode == 0, (uris[k % len(uris)], proc.returncode, proc.stderr[-500:])
        out = np.array([float(x) for x in proc.stdout.split()])
        assert np.array_equal(out, ref)


def test_c_host_forbidden_calls(built, host):
    proc = subprocess.run([str(host), str(built[1]), "forbidden", "--set", "lam=0.5", "--set", "method=kf",
                           "--bad", "lam=2", "--bad", "method=wiener", "--bad", "ar_order=0"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "FAIL" not in proc.stdout and "0 failed" in proc.stdout
    assert proc.stdout.count("PASS fmi2ExitInitializationMode with") == 3


def test_steps_per_second(built, md, vr, host):
    """Throughput, printed (not asserted): the C host, and fmpy's FMU2Slave."""
    proc = subprocess.run([str(host), str(built[1]), "bench", "--n", "2000000"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    c_rate = float(proc.stdout.split()[-1])
    s = slave(built, md)
    s.exitInitializationMode()
    z, rs = record(n=5000)
    t0 = time.perf_counter()
    run(s, vr, z, rs)
    py_rate = len(z) / (time.perf_counter() - t0)
    s.terminate()
    s.freeInstance()
    print(f"\nFogDenoiserNative: C host {c_rate:,.0f} steps/s (set raw_rate + fmi2DoStep + get "
          f"filtered_rate); fmpy FMU2Slave {py_rate:,.0f} steps/s (setReal, setBoolean, doStep, getReal)")
    assert c_rate > 0 and py_rate > 0


def test_instantiate_refuses_wrong_guid_and_model_exchange(built, md):
    so = built[1] / "binaries" / "linux64" / "FogDenoiserNative.so"
    lib = ctypes.CDLL(str(so))
    lib.fmi2Instantiate.restype = ctypes.c_void_p
    log = Logger()
    for kind, guid in ((1, b"{wrong}"), (0, md.guid.encode()), (1, None)):
        assert lib.fmi2Instantiate(b"x", kind, guid, None, ctypes.byref(log.callbacks), 0, 0) is None
    assert len(log.errors()) == 3
    # calls with a NULL instance do not crash
    lib.fmi2DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
    assert lib.fmi2DoStep(None, 0.0, 0.005, 1) == FMI_ERROR
    lib.fmi2FreeInstance(None)


# ------------------------------------------- a source rebuild by fmpy (cmake)
def test_fmpy_source_rebuild_exports_fmi2_only_and_explains_a_missing_libm(built, host, tmp_path,
                                                                            monkeypatch):
    """A rebuild with fmpy's build_platform_binary exports the fmi2* functions only (no
    internal gd_* symbol) and, not linked with libm, still loads in a host without libm (no
    undefined pow). The one listed source file hides the core; libm calls are weak there, so the binary loads and
    fmi2Instantiate refuses with the reason where the process has no libm."""
    unz = fmpy_rebuild(built, tmp_path, monkeypatch)
    so = unz / "binaries" / "linux64" / "FogDenoiserNative.so"
    exported = exported_symbols(so)
    assert exported and all(n.startswith("fmi2") for n in exported), sorted(exported)
    assert "libm.so.6" not in needed_libraries(so)
    z, rs = record(n=200)
    proc = host_run(host, unz, z, rs)             # the host has no libm either
    assert proc.returncode != 0
    assert "built without -lm" in proc.stderr and "fmi2Instantiate" in proc.stderr, proc.stderr
    # where the process has libm (Python, most tools), the same binary works
    lib = ctypes.CDLL(str(so))
    lib.fmi2Instantiate.restype = ctypes.c_void_p
    md = read_model_description(str(unz))
    log = Logger()
    comp = lib.fmi2Instantiate(b"x", 1, md.guid.encode(), None, ctypes.byref(log.callbacks), 0, 0)
    assert comp and not log.errors()
    lib.fmi2FreeInstance.argtypes = [ctypes.c_void_p]
    lib.fmi2FreeInstance(comp)


def test_fmpy_source_rebuild_with_libm_equals_gd_denoise(built, host, tmp_path, monkeypatch):
    """The rebuild with the one option the docs give (link libm) runs in a host with no
    libm of its own and equals gd.denoise."""
    unz = fmpy_rebuild(built, tmp_path, monkeypatch, REBUILD_WITH_LIBM)
    so = unz / "binaries" / "linux64" / "FogDenoiserNative.so"
    assert "libm.so.6" in needed_libraries(so)
    assert all(n.startswith("fmi2") for n in exported_symbols(so))
    z, rs = record()
    for method in ("motion", "lowpass"):
        proc = host_run(host, unz, z, rs, "--set", f"method={method}")
        assert proc.returncode == 0, proc.stderr
        out = np.array([float(x) for x in proc.stdout.split()])
        np.testing.assert_allclose(out, gd.denoise(z, FS, method=method, restarts=rs), rtol=0, atol=1e-12)


def test_readme_vendor_table_maps_every_parameter_to_gd_denoise(md):
    """The FMU <-> gd.denoise table of docs/cosim/native.md names every parameter and input,
    and the argument names it gives are accepted by gd.denoise."""
    import re
    text = (REPO / "docs" / "cosim" / "native.md").read_text()
    section = text.split("## Parameters and `gd.denoise`", 1)[1].split("\n\n", 3)[2]
    rows = [ln for ln in section.splitlines() if ln.startswith("| `")]
    fmu_names = {n for ln in rows for n in re.findall(r"`([a-z_0-9]+)`", ln.split("|")[1])}
    want = {v.name for v in md.modelVariables if v.causality in ("parameter", "input")}
    assert want <= fmu_names, want - fmu_names
    z, _ = record(n=50)
    args = {}
    for ln in rows:
        fmu_col, py_col = ln.split("|")[1], ln.split("|")[2]
        if "the same names" in py_col:
            args.update({n: None for n in re.findall(r"`([a-z_0-9]+)`", fmu_col)})
        elif py_col.strip().startswith("`") and "[k]" not in py_col:
            args[re.findall(r"`([a-z_0-9]+)", py_col)[0]] = None
    assert {"sample_rate_hz", "method", "ar_order", "cutoff_hz", "order", "lam", "outlier_run"} <= set(args)
    by = {v.name: v for v in md.modelVariables}
    kw = {k: (float if by[k].type == "Real" else int)(by[k].start) for k in args
          if k in by and by[k].type in ("Real", "Integer")}
    kw.update(method="lowpass", order=2, cutoff_hz=None)
    gd.denoise(z, FS, **kw)          # every argument name the table gives is gd.denoise's
