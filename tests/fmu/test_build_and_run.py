"""FMUs: build, check, run in fmpy and libcosim, state, reset, error paths.

The FMUs are built once per session into a temporary folder by the CLI in a
subprocess. References are independent of the FMUs: the core's batch paths
``gyrodenoise.simulate`` and ``gyrodenoise.denoise`` (the C core).
"""

import importlib.util
import json
import math
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise import fmu as F
from gyrodenoise.denoiser import Denoiser
from gyrodenoise.simulator import parse_card

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

FS = 200.0
H = 1.0 / FS
TOL = 1e-9


@pytest.fixture(scope="session")
def fmu_dir(fmu_build):
    out, proc = fmu_build           # conftest: `gyrodenoise fmu build --out DIR`, once per session
    assert proc.returncode == 0, proc.stderr
    for name in list(F.FMUS) + ["FogDenoiserNative", "SimulatedFogNative"]:
        assert (out / f"{name}.fmu").is_file()
    return out


def _inst(fmu_dir, name="FogDenoiser", instance="x"):
    return F.FmuInstance(fmu_dir / f"{name}.fmu", instance)


def _run_denoiser(inst, z, restarts=None, t0=0):
    step = F._stepper(inst, "raw_rate", "restart", "filtered_rate")
    rs = np.zeros(len(z), bool) if restarts is None else restarts
    return np.array([step(float(z[k]), bool(rs[k]), (t0 + k) * H, H) for k in range(len(z))])


def _raw(n, seed=3, rate=0.0, restarts=None):
    return gd.simulate("paper_fog", n, seed=seed, true_rate_deg_s=rate, restarts=restarts).rate_deg_s


# ------------------------------------------------------------------ checkers
@pytest.mark.parametrize("name", list(F.FMUS))
def test_fmpy_validate_finds_no_problem(fmu_dir, name):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(fmu_dir / f"{name}.fmu")) == []
    proc = subprocess.run([str(Path(sys.executable).with_name("fmpy")), "validate",
                           str(fmu_dir / f"{name}.fmu")], capture_output=True, text=True, timeout=120)
    assert "No problems found" in proc.stdout, proc.stdout + proc.stderr


@pytest.mark.parametrize("name", list(F.FMUS))
def test_fmutool_check_finds_no_problem(fmu_dir, name):
    exe = Path(sys.executable).with_name("fmutool")
    proc = subprocess.run([str(exe), "-input", str(fmu_dir / f"{name}.fmu"), "-check"],
                          capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    assert "No semantic error" in out and "compliant with FMI-2.0" in out, out
    assert "ERROR" not in out.upper().replace("NO SEMANTIC ERROR", ""), out


def test_model_description_interface(fmu_dir):
    from fmpy import read_model_description
    md = read_model_description(str(fmu_dir / "FogDenoiser.fmu"))
    v = {x.name: x for x in md.modelVariables}
    assert v["raw_rate"].causality == "input" and v["raw_rate"].type == "Real"
    assert v["restart"].causality == "input" and v["restart"].type == "Boolean"
    assert v["restart"].variability == "discrete"
    for name in ["filtered_rate", "c", "R_hat", "innovation", "converged"] + [f"phi_{i}" for i in (1, 2, 3)]:
        assert v[name].causality == "output", name
    for name in ["ar_order", "method", "lam", "b", "gamma", "q0", "r0", "p0_rls", "p0_kf", "sample_period"]:
        assert v[name].causality == "parameter", name
    assert "[deg/s]" in v["raw_rate"].description and "[(deg/s)^2]" in v["R_hat"].description
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    md2 = read_model_description(str(fmu_dir / "SimulatedFog.fmu"))
    v2 = {x.name: x for x in md2.modelVariables}
    assert {"true_rate", "restart", "measured_rate", "card", "seed"} <= set(v2)
    assert v2["seed"].causality == "parameter" and v2["card"].type == "String"


def test_bundled_core_is_the_per_sample_path_only(fmu_dir):
    """The FMU carries the plain-Python kernels, the method registry, the C core of this build
    and the variable declaration, nothing else."""
    with zipfile.ZipFile(fmu_dir / "FogDenoiser.fmu") as z:
        names = set(z.namelist())
    core = {n for n in names if n.startswith("resources/gdcore/") and n.endswith(".py")}
    assert core == {f"resources/gdcore/{m}" for m in ("__init__.py", "core/__init__.py", "core/kernels.py",
                                                      "core/methods.py", "denoiser.py", "errors.py",
                                                      "fmu/variables.py")}
    binaries = {n for n in names if n.startswith("resources/gdcore/core/_gdcore")}
    assert binaries == {f"resources/gdcore/core/{so.name}" for so in F.compiled_core_files()}
    assert F.stale_reason(fmu_dir / "FogDenoiser.fmu") is None


# ---------------------------------------------------- runs from anywhere
BLOCKED_HOST = textwrap.dedent("""
    import json, sys
    class Block:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in ("gyrodenoise", "numba", "scipy"):
                raise ImportError("blocked in this test: " + name)
    sys.meta_path.insert(0, Block())
    sys.path = [p for p in sys.path if "/work/main" not in p or "site-packages" in p]
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    out = {}
    for name, inp, outp, params in [("SimulatedFog", "true_rate", "measured_rate", {}),
                                    ("FogDenoiser", "raw_rate", "filtered_rate", {"sample_period": 0.005})]:
        path = sys.argv[1] + "/" + name + ".fmu"
        md = read_model_description(path)
        vr = {v.name: v.valueReference for v in md.modelVariables}
        s = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), modelIdentifier=name, instanceName=name)
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        for k, v in params.items():
            s.setReal([vr[k]], [v])
        xs = out.get("SimulatedFog", [0.0] * 600)
        s.enterInitializationMode()
        s.setReal([vr[inp]], [xs[0]])
        s.exitInitializationMode()
        # the sensor takes sample 0 at fmi2ExitInitializationMode, then a step per sample;
        # the denoiser steps on each sample
        first = name == "SimulatedFog"
        ys = [s.getReal([vr[outp]])[0]] if first else []
        for i in range(1 if first else 0, 600):
            s.setReal([vr[inp]], [xs[i]])
            s.doStep((i - 1 if first else i) * 0.005, 0.005)
            ys.append(s.getReal([vr[outp]])[0])
        s.terminate(); s.freeInstance()
        out[name] = ys
    out["modules"] = sorted(m for m in sys.modules if m.split(".")[0] in ("gyrodenoise", "numba", "scipy"))
    print(json.dumps(out))
""")


def test_fmus_run_from_any_directory_without_gyrodenoise_numba_scipy(fmu_dir, tmp_path):
    script = tmp_path / "host.py"
    script.write_text(BLOCKED_HOST)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([sys.executable, str(script), str(fmu_dir)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["modules"] == []
    ref_meas = gd.simulate("paper_fog", 600, seed=0).rate_deg_s     # scipy path here, numpy path there
    np.testing.assert_allclose(out["SimulatedFog"], ref_meas, rtol=0, atol=1e-12)
    ref = gd.denoise(np.array(out["SimulatedFog"]), FS)
    np.testing.assert_allclose(out["FogDenoiser"], ref, rtol=0, atol=TOL)


# ------------------------------------------------------ validation runs
@pytest.mark.parametrize("rate", [0.0, 10.0])
def test_fmpy_two_fmu_run_equals_core_batch(fmu_dir, rate):
    res = F.validation_run(fmu_dir, duration_s=40.0, rate_deg_s=rate, restart_at_s=20.0, seed=5,
                           keep_arrays=True)
    assert res["max_abs_diff_measured_vs_simulate_deg_s"] <= TOL
    assert res["max_abs_diff_filtered_vs_denoise_deg_s"] <= TOL
    assert res["allan_max_rel_diff"] <= 1e-6
    assert res["fmu_errors"] == [] and res["converged_at_end"] and res["ok"]
    for k, red in res["reduction_fmu"].items():
        assert red == pytest.approx(res["reduction_batch"][k], rel=1e-6), k
    # the restart in the middle was effective: without it the batch output differs
    a = res["arrays"]
    no_restart = gd.denoise(a["measured"], FS)
    assert np.max(np.abs(no_restart - a["filtered"])) > 1e-6
    # and the filter did its job on white noise (N reduced)
    assert res["reduction_fmu"]["N"] > 2.0


def test_cli_fmu_run_json(fmu_dir):
    proc = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "fmu", "run", "--fmu-dir", str(fmu_dir),
                           "--duration", "15", "--json"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert len(lines) == 1
    out = json.loads(lines[0])
    assert out["ok"] is True and set(out["cases"]) == {"static", "constant_rate"}
    assert out["cases"]["constant_rate"]["case"]["true_rate_deg_s"] == 10.0
    for case in out["cases"].values():
        assert case["max_abs_diff_filtered_vs_denoise_deg_s"] <= TOL
        assert case["case"]["restart_at_s"] == 7.5


def test_cli_fmu_run_missing_card_is_user_error(fmu_dir):
    proc = subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "fmu", "run", "--fmu-dir", str(fmu_dir),
                           "--duration", "1", "--card", "/nonexistent/card.toml"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.startswith("gyrodenoise: error:") and "Traceback" not in proc.stderr


@pytest.mark.parametrize("sensor,denoiser", [("SimulatedFogNative", "FogDenoiserNative"),
                                             ("SimulatedFog", "FogDenoiserNative"), ("SimulatedFog", "FogDenoiser")])
@pytest.mark.parametrize("ssp", [False, True])
def test_libcosim_two_fmu_system(fmu_dir, tmp_path, ssp, sensor, denoiser):
    """The first pair (the default) has no Python in the chain."""
    ssp_path = tmp_path / "chain.ssp" if ssp else None
    res = F.cosim_run(fmu_dir, duration_s=10.0, rate_deg_s=10.0, restart_at_s=5.0, seed=2, ssp=ssp_path,
                      keep_arrays=True, denoiser=denoiser, sensor=sensor)
    assert res["step_size_s"] == pytest.approx(H, rel=1e-9)
    # the sensor's sample 0 (taken at fmi2ExitInitializationMode) is the denoiser's first input
    assert res["first_received_is_a_sample"]
    assert res["first_received_deg_s"] == gd.simulate("paper_fog", 1, seed=2, true_rate_deg_s=10.0).rate_deg_s[0]
    assert res["max_abs_diff_received_vs_delayed_measured_deg_s"] == 0.0
    assert res["max_abs_diff_measured_vs_simulate_deg_s"] <= TOL
    assert res["max_abs_diff_filtered_vs_denoise_deg_s"] <= TOL
    assert res["converged_at_end"] and res["ok"]
    a = res["arrays"]
    # the injected restart reached the denoiser (one step late, through fog.restarted)
    rec_rs = np.concatenate(([False], a["restarts"][:-1]))
    with_rs = gd.denoise(a["received"], FS, restarts=rec_rs)
    without = gd.denoise(a["received"], FS)
    assert np.max(np.abs(with_rs - a["filtered"])) <= TOL
    assert np.max(np.abs(without - a["filtered"])) > 1e-6
    if ssp:
        with zipfile.ZipFile(ssp_path) as z:
            assert {"SystemStructure.ssd", f"resources/{denoiser}.fmu",
                    f"resources/{sensor}.fmu"} == set(z.namelist())


# --------------------------------------------------------------- state
def test_denoiser_state_roundtrip_and_serialize(fmu_dir):
    z = _raw(1200, seed=7, rate=2.0)
    a = _inst(fmu_dir, instance="a")
    b = _inst(fmu_dir, instance="b")
    try:
        a.initialize(sample_period=H, ar_order=4, method="shakf")
        b.initialize(sample_period=H)          # other order and method: the state carries the parameters
        first = _run_denoiser(a, z[:600])
        st = a.slave.getFMUstate()
        blob = a.slave.serializeFMUstate(st)
        cont = _run_denoiser(a, z[600:], t0=600)
        phi_a = [a.get(f"phi_{i}") for i in range(1, 5)]
        # back in time in the same instance
        a.slave.setFMUstate(st)
        again = _run_denoiser(a, z[600:], t0=600)
        a.slave.freeFMUstate(st)
        # into another instance through the serialized bytes
        st_b = b.slave.deSerializeFMUstate(blob)
        b.slave.setFMUstate(st_b)
        b.slave.freeFMUstate(st_b)
        other = _run_denoiser(b, z[600:], t0=600)
        phi_b = [b.get(f"phi_{i}") for i in range(1, 5)]
        assert b.get("ar_order") == 4
    finally:
        a.free()
        b.free()
    ref = gd.denoise(z, FS, ar_order=4, method="shakf")
    np.testing.assert_allclose(np.concatenate([first, cont]), ref, rtol=0, atol=TOL)
    np.testing.assert_array_equal(again, cont)
    np.testing.assert_array_equal(other, cont)
    assert phi_a == phi_b and phi_a[3] != 0.0


def test_simulator_state_roundtrip(fmu_dir):
    a = _inst(fmu_dir, "SimulatedFog", "fa")
    b = _inst(fmu_dir, "SimulatedFog", "fb")
    try:
        a.initialize(seed=11, true_rate=1.0)     # sample 0 at fmi2ExitInitializationMode
        b.initialize(seed=99)
        step_a = F._stepper(a, "true_rate", "restart", "measured_rate")
        step_b = F._stepper(b, "true_rate", "restart", "measured_rate")
        # the step from t_(k-1) produces sample k; 5000 samples cross a noise block
        first = [a.get("measured_rate")] + [step_a(1.0, False, k * H, H) for k in range(4999)]
        st = a.slave.getFMUstate()
        blob = a.slave.serializeFMUstate(st)
        a.slave.freeFMUstate(st)
        cont = [step_a(1.0, False, k * H, H) for k in range(4999, 5299)]
        st_b = b.slave.deSerializeFMUstate(blob)
        b.slave.setFMUstate(st_b)
        b.slave.freeFMUstate(st_b)
        other = [step_b(1.0, False, k * H, H) for k in range(4999, 5299)]
    finally:
        a.free()
        b.free()
    ref = gd.simulate("paper_fog", 5300, seed=11, true_rate_deg_s=1.0).rate_deg_s
    np.testing.assert_allclose(first + cont, ref, rtol=0, atol=TOL)
    assert other == cont


def test_reset_gives_fresh_filter(fmu_dir):
    z = _raw(800, seed=8)
    a = _inst(fmu_dir)
    try:
        a.initialize(sample_period=H)
        _run_denoiser(a, _raw(500, seed=9) + 0.3)
        a.slave.reset()
        assert a.get("converged") is False and a.get("phi_1") == 0.0
        a.initialize(sample_period=H)
        out = _run_denoiser(a, z)
    finally:
        a.free()
    np.testing.assert_allclose(out, gd.denoise(z, FS), rtol=0, atol=TOL)


def test_instances_are_independent(fmu_dir):
    z1, z2 = _raw(700, seed=1), _raw(700, seed=2, rate=-3.0)
    rs2 = np.zeros(700, bool)
    rs2[350] = True
    a, b = _inst(fmu_dir, instance="a"), _inst(fmu_dir, instance="b")
    try:
        a.initialize(sample_period=H, method="kf")
        b.initialize(sample_period=H, method="shakf", ar_order=2)
        sa = F._stepper(a, "raw_rate", "restart", "filtered_rate")
        sb = F._stepper(b, "raw_rate", "restart", "filtered_rate")
        o1, o2 = [], []
        for k in range(700):               # interleaved in one process
            o1.append(sa(z1[k], False, k * H, H))
            o2.append(sb(z2[k], bool(rs2[k]), k * H, H))
    finally:
        a.free()
        b.free()
    np.testing.assert_allclose(o1, gd.denoise(z1, FS, method="kf"), rtol=0, atol=TOL)
    np.testing.assert_allclose(o2, gd.denoise(z2, FS, method="shakf", ar_order=2, restarts=rs2), rtol=0, atol=TOL)


# ---------------------------------------------------------- error paths
@pytest.mark.parametrize("params, word", [
    ({"ar_order": 0}, "ar_order"),
    ({"ar_order": 7}, "ar_order"),
    ({"b": 1.0}, "b out of range"),
    ({"b": 0.0}, "b out of range"),
    ({"gamma": 0.5}, "gamma"),
    ({"p0_kf": -1.0}, "p0_kf"),
    ({"q0": -1e-6}, "q0"),
    ({"r0": -1.0}, "r0"),
    ({"method": "wiener"}, "method"),
    ({"method": ""}, "method"),
    ({"sample_period": 0.0}, "sample_period"),
    ({"sample_period": -0.005}, "sample_period"),
    ({"sample_period": float("nan")}, "sample_period"),
    ({"lam": 0.0}, "lam"),
    ({"lam": 1.5}, "lam"),
    ({"p0_rls": 0.0}, "p0_rls"),
    ({"warmup_s": -1.0}, "warmup_s"),
    ({"r_floor": 0.0}, "r_floor"),
    ({"gamma": float("inf")}, "gamma"),
    ({"outlier_sigma": 1.0}, "outlier_sigma"),
    ({"outlier_sigma": -5.0}, "outlier_sigma"),
    ({"outlier_run": 0}, "outlier_run"),
])
def test_invalid_parameters_refused_at_initialisation(fmu_dir, params, word):
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir)
    a.slave.setupExperiment(startTime=0.0)
    a.set(**params)
    a.slave.enterInitializationMode()
    with pytest.raises(FMICallException) as exc:
        a.slave.exitInitializationMode()
    assert exc.value.status >= 3
    errs = [m for m in a.errors() if "invalid parameter" in m[2]]
    assert errs and word in errs[0][2] and errs[0][0] == 3, a.messages
    a.free(terminate=False)


def test_invalid_card_refused(fmu_dir):
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir, "SimulatedFog")
    a.slave.setupExperiment(startTime=0.0)
    a.set(card="[sensor]\nsample_rate_hz = 200.0\n[terms]\nangle_random_walk = { N = -1.0 }\n")
    a.slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        a.slave.exitInitializationMode()
    assert any("angle_random_walk.N" in m[2] for m in a.errors()), a.messages
    a.free(terminate=False)


@pytest.mark.parametrize("card, word", [
    ("[sensor]\nsample_rate_hz = 200.0\n[terms]\nflux_capacitor = { N = 1.0 }\n", "unknown term"),
    ("[sensor]\nsample_rate_hz = 200.0\n[terms]\nbias_instability = { }\n", "missing the field B"),
    ("[sensor]\nsample_rate_hz = 200.0\n[terms]\nangle_random_walk = { N = 1e12 }\n", "not a usable number"),
    ("[sensor]\nsample_rate_hz = -5.0\n", "sample_rate_hz"),
    ("[terms]\nangle_random_walk = { N = 0.1 }\n", "missing [sensor]"),
    ("this is not toml = = \n", "not valid TOML"),
])
def test_bad_card_texts_refused_with_reason(fmu_dir, card, word):
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir, "SimulatedFog")
    a.slave.setupExperiment(startTime=0.0)
    a.set(card=card)
    a.slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        a.slave.exitInitializationMode()
    assert any(word in m[2] for m in a.errors()), a.messages
    a.free(terminate=False)


def test_outlier_gate_in_the_fmu_equals_core_and_counts(fmu_dir):
    z = _raw(3000, seed=6, rate=1.0)
    z[1500] += 20.0                       # one wild sample after the warm-up
    z[2200] -= 15.0
    a = _inst(fmu_dir)
    try:
        a.initialize(sample_period=H, method="shakf", outlier_sigma=5.0, outlier_run=20)
        got = _run_denoiser(a, z)
        n_rej = a.get("n_rejected")
        assert not a.errors()
    finally:
        a.free()
    d = Denoiser(FS, method="shakf", outlier_sigma=5.0, outlier_run=20)
    ref = d.process(z)
    np.testing.assert_allclose(got, ref, rtol=0, atol=TOL)
    assert n_rej == d.n_rejected == 2
    assert abs(got[1500] - 1.0) < 0.05 and abs(got[2200] - 1.0) < 0.05   # output = prediction


def test_card_text_parameter(fmu_dir):
    card = "[sensor]\nsample_rate_hz = 100.0\n[terms]\nangle_random_walk = { N = 0.01 }\n"
    a = _inst(fmu_dir, "SimulatedFog")
    try:
        a.initialize(card=card, seed=4, true_rate=0.5)     # sample 0 at fmi2ExitInitializationMode
        step = F._stepper(a, "true_rate", "restart", "measured_rate")
        out = [a.get("measured_rate")] + [step(0.5, False, k * 0.01, 0.01) for k in range(299)]
        # information only: the sensor model in use (the extension this FMU bundles loads here)
        assert [m[0] for m in a.messages] == [0], a.messages
        assert "runs on the bundled C core (gdsim.c)" in a.messages[0][2]
    finally:
        a.free()
    ref = gd.simulate(parse_card(card), 300, seed=4, true_rate_deg_s=0.5).rate_deg_s
    np.testing.assert_allclose(out, ref, rtol=0, atol=TOL)


def test_step_size_mismatch_is_reported(fmu_dir):
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir)
    try:
        a.initialize(sample_period=H)
        a.set(raw_rate=0.1)
        a.slave.doStep(0.0, 2 * H)
        warn = [m for m in a.messages if m[0] == 1 and "step size" in m[2]]
        assert warn and "0.01" in warn[0][2] and "0.005" in warn[0][2]
    finally:
        a.free()
    b = _inst(fmu_dir)
    try:
        b.initialize(sample_period=H, strict_step_size=True)
        b.slave.doStep(0.0, H)
        with pytest.raises(FMICallException) as exc:
            b.slave.doStep(H, 0.5 * H)
        assert exc.value.status == 2      # fmi2Discard: pythonfmu's only non-fatal refusal
        assert any("step refused" in m[2] for m in b.errors())
    finally:
        b.free()


def test_nonfinite_input_is_a_dropout_processed_as_the_library_does(fmu_dir):
    """A NaN raw_rate is a dropout (spec, FMUs): the step goes on, the reason is logged as a
    warning, and the outputs, before, at and after it, are gd.denoise's on the same record."""
    z = _raw(400, seed=12)
    z[200] = math.nan
    a = _inst(fmu_dir)
    try:
        a.initialize(sample_period=H)
        out = _run_denoiser(a, z)
        warned = [m for m in a.messages if "raw_rate is nan" in m[2]]
        assert warned and all(m[0] == 1 for m in warned), a.messages     # fmi2Warning
    finally:
        a.free()
    np.testing.assert_allclose(out, gd.denoise(z, FS), rtol=0, atol=TOL, equal_nan=True)


def test_bad_state_is_refused_and_the_instance_kept(fmu_dir):
    """A state of another version is refused at fmi2SetFMUstate (pythonfmu answers a raising
    slave with fmi2Fatal) with the reason logged; the instance keeps its state and steps on."""
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir)
    try:
        a.initialize(sample_period=H)
        st = a.slave.deSerializeFMUstate(json.dumps({"version": 99}).encode())
        with pytest.raises(FMICallException):
            a.slave.setFMUstate(st)
        a.slave.freeFMUstate(st)
        assert any("fmi2SetFMUstate" in m[2] and "unchanged" in m[2] for m in a.messages), a.messages
        out = _run_denoiser(a, _raw(50, seed=2))
    finally:
        a.free()
    np.testing.assert_allclose(out, gd.denoise(_raw(50, seed=2), FS), rtol=0, atol=TOL)


def _slave_class(fmu_dir, tmp_path):
    """The FogDenoiser slave class from the built FMU's resources, in this process."""
    from fmpy import extract
    d = Path(extract(str(fmu_dir / "FogDenoiser.fmu"), unzipdir=str(tmp_path / "fd")))
    sys.path.insert(0, str(d / "resources"))
    try:
        spec = importlib.util.spec_from_file_location("_test_fogdenoiser_slave",
                                                      d / "resources" / "fogdenoiser_fmu.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(d / "resources"))
    return mod.FogDenoiser, str(d / "resources")


def test_exception_in_step_is_logged_and_returned(fmu_dir, tmp_path):
    cls, resources = _slave_class(fmu_dir, tmp_path)
    s = cls(instance_name="t", resources=resources)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    s.raw_rate = 0.01
    assert s.do_step(0.0, H) is True
    before = s._den.get_state()

    def boom(z, restart):
        s._den.state[5] = 123.0      # partly mutated, then fails
        raise ZeroDivisionError("float division by zero")
    s._den.step = boom
    assert s.do_step(H, H) is False
    msgs = [(m.status, m.msg) for m in s.log_queue]
    assert any(st == 3 and "ZeroDivisionError: float division by zero" in msg for st, msg in msgs), msgs
    assert s._den.get_state() == before          # state restored
    # the core was loaded from an FMU's copy (named by its contents), not from the installed package
    assert s._D.__name__.startswith("_gdcore_")
    assert s._D.__file__.endswith("/resources/gdcore/denoiser.py")
    assert not Path(s._D.__file__).is_relative_to(Path(gd.__file__).parent)


@pytest.mark.parametrize("params,kw", [({"method": "lowpass", "cutoff_hz": 10.0, "lowpass_order": 3},
                                        {"method": "lowpass", "cutoff_hz": 10.0, "order": 3}),
                                       ({}, {"method": "motion"}),
                                       ({"max_motion_hz": 20.0}, {"method": "motion", "max_motion_hz": 20.0}),
                                       ({"method": "one_euro", "min_cutoff_hz": 2.0, "beta": 0.02},
                                        {"method": "one_euro", "min_cutoff_hz": 2.0, "beta": 0.02})])
def test_lowpass_and_motion_in_the_fmu_equal_the_core(fmu_dir, params, kw):
    """The FMU's default method is motion; lowpass takes cutoff_hz and lowpass_order;
    motion takes max_motion_hz (a 60 Hz tone, 'vibration', rides on the record)."""
    z = _raw(1500, seed=9, rate=3.0)
    z[700:] += 5.0                        # a step
    z += 2.0 * np.sin(2 * np.pi * 60.0 * np.arange(z.size) / FS)
    a = _inst(fmu_dir)
    try:
        a.initialize(sample_period=H, **params)
        got = _run_denoiser(a, z)
        assert not a.errors()
    finally:
        a.free()
    np.testing.assert_allclose(got, gd.denoise(z, FS, **kw), rtol=0, atol=TOL)


def test_fmu_runs_the_c_core_and_falls_back_with_a_message(fmu_dir, tmp_path):
    """FogDenoiser runs the bundled C core (logged); the same FMU without a
    binary that fits (here: removed, as on another platform) runs the
    plain-Python kernels, says so in a warning, and gives the same numbers."""
    z = _raw(800, seed=4, rate=2.0)
    z[400:] += 3.0
    ref = gd.denoise(z, FS)
    stripped = tmp_path / "FogDenoiser.fmu"
    with zipfile.ZipFile(fmu_dir / "FogDenoiser.fmu") as src, zipfile.ZipFile(stripped, "w") as dst:
        for item in src.infolist():
            if "/_gdcore" not in item.filename:
                dst.writestr(item, src.read(item))
    for path, core in ((fmu_dir / "FogDenoiser.fmu", "C"), (stripped, "Python")):
        a = F.FmuInstance(path, "c")
        try:
            a.initialize(sample_period=H)
            got = _run_denoiser(a, z)
            text = " ".join(m[2] for m in a.messages)
        finally:
            a.free()
        if core == "C":
            assert "bundled C core" in text and "falling back" not in text
        else:
            assert "falling back to the plain-Python kernels" in text
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


def test_model_description_declares_units_default_experiment_and_bounds(fmu_dir):
    """Spec section 5: every physical Real carries a unit declared in
    UnitDefinitions, a DefaultExperiment gives the step size, bounded
    parameters carry min/max (pythonfmu cannot: added after its build)."""
    from fmpy import read_model_description
    for name in F.FMUS:
        md = read_model_description(str(fmu_dir / f"{name}.fmu"))
        assert md.defaultExperiment is not None and float(md.defaultExperiment.stepSize) == pytest.approx(H)
        units = {u.name: u for u in md.unitDefinitions}
        assert "deg/s" in units
        assert float(units["deg/s"].baseUnit.factor) == pytest.approx(np.pi / 180)
        v = {x.name: x for x in md.modelVariables}
        rates = ("raw_rate", "filtered_rate") if name == "FogDenoiser" else ("true_rate", "measured_rate")
        for r in rates:
            assert v[r].unit == "deg/s", (name, r)
    md = read_model_description(str(fmu_dir / "FogDenoiser.fmu"))
    v = {x.name: x for x in md.modelVariables}
    assert v["R_hat"].unit == "deg2/s2" and v["sample_period"].unit == "s" and v["cutoff_hz"].unit == "Hz"
    assert float(v["lam"].max) == 1.0 and float(v["gamma"].min) == 1.0
    # FMI min is inclusive: parameters that must be > 0 declare a positive min, not min="0.0"
    for p in ("sample_period", "lam", "b", "p0_rls", "p0_kf", "r_floor"):
        assert 0.0 < float(v[p].min) <= sys.float_info.min, (p, v[p].min)
    assert float(v["b"].max) < 1.0 and float(v["q0"].min) == 0.0 and float(v["cutoff_hz"].min) == 0.0
    assert int(v["ar_order"].min) == 1 and int(v["ar_order"].max) == 6
    assert int(v["lowpass_order"].max) == 8


@pytest.mark.parametrize("name", list(F.FMUS))
@pytest.mark.parametrize("bad_step", [0.0, -H, float("nan"), float("inf")])
def test_non_positive_or_nan_step_size_is_refused(fmu_dir, name, bad_step):
    """FMI 2.0 requires communicationStepSize > 0: refused with a logged reason
    (fmi2Discard, pythonfmu's only non-fatal refusal), the state unchanged (a
    NaN step is not processed as a sample)."""
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir, name)
    inp, out = ("raw_rate", "filtered_rate") if name == "FogDenoiser" else ("true_rate", "measured_rate")
    try:
        a.initialize(**({"sample_period": H} if name == "FogDenoiser" else {}))
        a.set(**{inp: 1.0})
        a.slave.doStep(0.0, H)
        before = a.get(out)
        with pytest.raises(FMICallException) as exc:
            a.slave.doStep(H, bad_step)
        assert exc.value.status == 2
        assert any("not a positive finite number" in m[2] for m in a.errors())
        assert a.get(out) == before
    finally:
        a.free()


def test_forbidden_writes_and_step_after_terminate_are_refused_with_a_reason(fmu_dir):
    """FMI 2.0 forbids setting an output, a fixed parameter after initialisation,
    and fmi2DoStep after fmi2Terminate. pythonfmu cannot return fmi2Error from a
    setter: the write is refused (value unchanged) with a logged error, and the
    next step is refused (fmi2Discard) with the reason."""
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir)
    try:
        a.initialize(sample_period=H, method="shakf")
        a.set(raw_rate=1.0)
        a.slave.doStep(0.0, H)
        out = a.get("filtered_rate")
        a.set(filtered_rate=123.0)                       # an output
        assert a.get("filtered_rate") == out
        with pytest.raises(FMICallException) as exc:
            a.slave.doStep(H, H)
        assert exc.value.status == 2
        assert any("'filtered_rate' refused (it is an output)" in m[2] for m in a.errors())
        a.slave.doStep(H, H)                             # the refusal is reported once, then it steps
        a.set(lam=0.5)                                   # a fixed parameter after initialisation
        assert a.get("lam") == 1.0
        with pytest.raises(FMICallException):
            a.slave.doStep(2 * H, H)
        assert any("fixed parameter 'lam' after initialisation refused" in m[2] for m in a.errors())
        a.slave.terminate()
        with pytest.raises(FMICallException):
            a.slave.doStep(3 * H, H)
        assert any("fmi2DoStep after fmi2Terminate refused" in m[2] for m in a.errors())
    finally:
        a.free()


@pytest.mark.parametrize("name", ["FogDenoiser", "SimulatedFog"])
def test_out_of_sequence_calls_and_writes_after_terminate_are_refused(fmu_dir, name):
    """FMI 2.0 allows fmi2SetupExperiment only before initialisation,
    fmi2EnterInitializationMode once, fmi2ExitInitializationMode only in
    initialisation mode, fmi2Terminate once, no fmi2Set after it, and a finite
    communication point. pythonfmu
    answers fmi2OK to any call that does not raise: the call does nothing, an error
    is logged, and the next step is refused (fmi2Discard) with the reason."""
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir, name)
    try:
        s = a.slave
        s.setupExperiment(startTime=0.0)
        s.exitInitializationMode()                        # before entering it
        assert any("fmi2ExitInitializationMode refused: not in initialisation mode" in m[2]
                   for m in a.errors())
        s.enterInitializationMode()
        s.enterInitializationMode()                       # twice
        assert any("fmi2EnterInitializationMode refused: already in initialisation mode" in m[2]
                   for m in a.errors())
        s.exitInitializationMode()
        with pytest.raises(FMICallException) as exc:      # the first refusal is reported at the step
            s.doStep(0.0, H)
        assert exc.value.status == 2
        s.doStep(0.0, H)                                  # then it steps
        s.enterInitializationMode()                       # after initialisation
        with pytest.raises(FMICallException):
            s.doStep(H, H)
        assert any("already initialised" in m[2] for m in a.errors())
        s.setupExperiment(startTime=0.0)                  # only before initialisation
        with pytest.raises(FMICallException):
            s.doStep(H, H)
        assert any("fmi2SetupExperiment refused" in m[2] for m in a.errors())
        with pytest.raises(FMICallException):             # a time that is not finite
            s.doStep(float("nan"), H)
        assert any("currentCommunicationPoint nan s is not finite" in m[2] for m in a.errors())
        s.doStep(H, H)
        s.terminate()
        s.terminate()                                     # twice
        assert any("fmi2Terminate refused: already terminated" in m[2] for m in a.errors())
        var = "raw_rate" if name == "FogDenoiser" else "true_rate"
        before = a.get(var)
        a.set(**{var: 42.0})
        assert a.get(var) == before
        assert any(f"fmi2Set of '{var}' after fmi2Terminate refused" in m[2] for m in a.errors())
        s.enterInitializationMode()
        assert any("fmi2EnterInitializationMode refused: after fmi2Terminate" in m[2] for m in a.errors())
    finally:
        a.free()


@pytest.mark.parametrize("sensor", ["SimulatedFogNative", "SimulatedFog"])
def test_the_ssp_runs_in_fmpy_simulate_ssp(fmu_dir, tmp_path, sensor):
    """The same .ssp that libcosim runs (test above) loads and runs in fmpy's
    simulate_ssp: the chain's free inputs are not listed as connectors (fmpy
    needs every listed input connected). fmpy ignores ParameterBindings, so this
    SSP is written with the FMUs' defaults (card paper_fog, seed 0, rate 0):
    the denoiser's output equals gd.denoise of what the fog FMU produced."""
    from fmpy.ssp.simulation import simulate_ssp
    ssp = F.write_ssp(tmp_path / "chain.ssp", fmu_dir=fmu_dir, sensor=sensor)
    r = simulate_ssp(str(ssp), stop_time=1.0, step_size=H)
    measured = np.asarray(r["fog.measured_rate"], dtype=float)
    filtered = np.asarray(r["denoiser.filtered_rate"], dtype=float)
    assert len(measured) > 150 and np.std(measured) > 0
    samples = gd.simulate("paper_fog", len(measured) + 1, seed=0).rate_deg_s
    # the fog's own output (fmpy records it after each step: samples 1.., sample 0 was taken at
    # fmi2ExitInitializationMode) is the library's, bit for bit
    assert np.array_equal(measured, samples[1:])
    # Jacobi master: the denoiser's input in step k is the fog's output at the end of step k-1,
    # sample k; in step 0 fmpy's own placeholder: simulate_ssp starts every connector at 0.0 and
    # reads outputs only after a step, not after initialisation (libcosim and Ecos pass sample 0)
    received = np.concatenate(([0.0], samples[1:-1]))
    np.testing.assert_allclose(filtered, gd.denoise(received, FS), rtol=0, atol=1e-9)


def test_method_description_names_every_method_and_no_fixed_cutoff(fmu_dir):
    """FogDenoiser's ``method`` description names every method (sh_classic included) and no
    fixed cutoff (the cutoff is a parameter), as the native one does."""
    from fmpy import read_model_description
    from gyrodenoise.core.kernels import METHODS
    for name in ("FogDenoiser", "FogDenoiserNative"):
        md = read_model_description(str(fmu_dir / f"{name}.fmu"))
        desc = {v.name: v.description for v in md.modelVariables}["method"]
        assert "20 Hz" not in desc and "cutoff_hz" in desc and "refused" in desc, (name, desc)
        for m in METHODS:
            assert f"'{m}'" in desc, (name, m)


@pytest.mark.parametrize("cutoff", [float("nan"), float("inf"), -1.0])
def test_bad_cutoff_refused_whatever_the_method(fmu_dir, cutoff):
    """cutoff_hz NaN/inf/-1 (declared min 0) is refused whatever the method, lowpass or not."""
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir)
    a.slave.setupExperiment(startTime=0.0)
    a.set(method="shakf", cutoff_hz=cutoff)
    a.slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        a.slave.exitInitializationMode()
    assert any("cutoff_hz out of range" in m[2] for m in a.errors()), a.messages
    a.free(terminate=False)


@pytest.mark.parametrize("method", ["motion", "shakf"])
@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -1.0, 100.0, 250.0])
def test_bad_max_motion_hz_refused_whatever_the_method(fmu_dir, method, bad):
    """max_motion_hz (declared min 0) NaN, inf, negative or not below half
    the sample rate (100 Hz here) is refused at initialisation with the reason logged."""
    from fmpy.fmi1 import FMICallException
    a = _inst(fmu_dir)
    a.slave.setupExperiment(startTime=0.0)
    a.set(method=method, max_motion_hz=bad, sample_period=H)
    a.slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        a.slave.exitInitializationMode()
    assert any("max_motion_hz out of range" in m[2] for m in a.errors()), a.messages
    a.free(terminate=False)


SECOND_USE = """
import shutil, sys, tempfile
from pathlib import Path
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.ssp.simulation import simulate_ssp
fmu, ssp = sys.argv[1], sys.argv[2]
md = read_model_description(fmu)
vr = {v.name: v.valueReference for v in md.modelVariables}
outs = []
for k in range(2):          # unzip, run, free, delete the folder; again in the same process
    d = extract(fmu, tempfile.mkdtemp())
    s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier="SimulatedFog", instanceName=f"f{k}")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    out = []
    for i in range(50):
        s.setReal([vr["true_rate"]], [1.0])
        s.doStep(i * 0.005, 0.005)
        out.append(s.getReal([vr["measured_rate"]])[0])
    s.terminate()
    s.freeInstance()
    shutil.rmtree(d)
    outs.append(out)
assert outs[0] == outs[1], "second use differs"
runs = [simulate_ssp(ssp, stop_time=0.2, step_size=0.005) for _ in range(2)]
assert list(runs[0]["fog.measured_rate"]) == list(runs[1]["fog.measured_rate"]), "second SSP run differs"
print("ok", outs[1][:2])
"""


def test_simulatedfog_second_use_in_a_process(fmu_dir, tmp_path):
    """A second SimulatedFog instance in a process, after the first unzip folder was deleted,
    passes fmi2ExitInitializationMode (finds its model card), and so does a second fmpy
    simulate_ssp. Run in a fresh process (the first use must be in it)."""
    ssp = F.write_ssp(tmp_path / "chain.ssp", fmu_dir=fmu_dir, sensor="SimulatedFog")
    proc = subprocess.run([sys.executable, "-c", SECOND_USE, str(fmu_dir / "SimulatedFog.fmu"), str(ssp)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.startswith("ok"), proc.stdout + proc.stderr[-2000:]


def test_ssp_writer_targets_the_native_fmus_by_default(fmu_dir, tmp_path):
    """The SSP writer's default chain is SimulatedFogNative -> FogDenoiserNative (no Python), a
    bundled card bound by its name."""
    ssp = F.write_ssp(tmp_path / "chain.ssp", fmu_dir=fmu_dir, card="imar_fog")
    with zipfile.ZipFile(ssp) as z:
        ssd = z.read("SystemStructure.ssd").decode()
        assert {"resources/FogDenoiserNative.fmu", "resources/SimulatedFogNative.fmu"} <= set(z.namelist())
    assert 'source="resources/FogDenoiserNative.fmu"' in ssd and "FogDenoiser.fmu" not in ssd
    assert 'source="resources/SimulatedFogNative.fmu"' in ssd and "SimulatedFog.fmu" not in ssd
    import xml.etree.ElementTree as ET
    values = {p.get("name"): p[0].get("value") for p in ET.fromstring(ssd).iter(
        "{http://ssp-standard.org/SSP1/SystemStructureParameterValues}Parameter")}
    assert values["card"] == "imar_fog"
    from gyrodenoise.errors import InputError
    with pytest.raises(InputError, match="denoiser must be one of"):
        F.write_ssp(tmp_path / "x.ssp", fmu_dir=fmu_dir, denoiser="Wiener")
    with pytest.raises(InputError, match="sensor must be one of"):
        F.write_ssp(tmp_path / "x.ssp", fmu_dir=fmu_dir, sensor="Gyro")
