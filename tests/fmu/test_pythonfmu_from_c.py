"""The pythonfmu FMUs (FogDenoiser.fmu, SimulatedFog.fmu) from a plain C host.

tests/chost/host.c (dlopen + the FMI 2.0 C API) runs both FMUs with libpython
LD_PRELOADed (pythonfmu's binary does not link libpython): outputs equal to
gd.denoise / gd.simulate, the legal resource URI forms that pythonfmu's exporter
parses, clean process exits, and the calls FMI 2.0 forbids as far as pythonfmu
lets the slave answer them. Also SimulatedFog's refusal of forbidden writes
(fmpy, in process), as FogDenoiser does (tests/fmu/test_build_and_run.py).

What stays in pythonfmu 0.7.0's exporter (no way around it in the FMU):
``file:/path`` and ``file://localhost/path`` URIs, an empty URI (segfault) and a
NULL URI (std::terminate) in fmi2Instantiate: marked xfail below.
"""
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise import fmu as F
from gyrodenoise.fmu import native
from gyrodenoise.simulator import SimStream
from tests.helpers import CHOST

H = 0.005
FS = 1.0 / H
N_EXITS = 10          # clean exits per FMU (0 crashes in 50 runs of each after the workarounds)

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _libpython():
    libdir, name = sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("LDLIBRARY")
    if not libdir or not name or ".so" not in name:
        return None
    path = Path(libdir) / name
    return path if path.is_file() else None


LIBPYTHON = _libpython()
if shutil.which("gcc") is None:
    pytestmark = [pytestmark, pytest.mark.skip(reason="gcc not installed: the C host cannot be built")]
elif LIBPYTHON is None:
    pytestmark = [pytestmark, pytest.mark.skip(
        reason="no shared libpython (LDLIBRARY) for this Python: pythonfmu FMUs cannot run in a C host")]


# ----------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def fmus(builds_fmus, tmp_path_factory):
    out = tmp_path_factory.mktemp("pyfmus")
    dirs = {}
    for name in F.FMUS:
        fmu = F.build.build_fmu(name, out)
        d = out / name
        with zipfile.ZipFile(fmu) as z:
            z.extractall(d)
        dirs[name] = d
    dirs["_fmu"] = out
    return dirs


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    exe = tmp_path_factory.mktemp("chost_py") / "host"
    subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", f"-I{native.fmi_headers_dir()}",
                    str(CHOST / "host.c"), "-o", str(exe), "-ldl", "-lm"],
                   check=True, capture_output=True, text=True)
    return exe


def _env():
    env = dict(os.environ, LD_PRELOAD=str(LIBPYTHON))
    env.pop("PYTHONPATH", None)
    return env


def _run(host, d, mode, *args, stdin="", timeout=60):
    return subprocess.run([str(host), str(d), mode, *args], input=stdin, capture_output=True, text=True,
                          env=_env(), timeout=timeout)


SIM_ARGS = ("--in", "true_rate", "--out", "measured_rate", "--init-sample")


def _lines(z, rs):
    return "".join(f"{float(v)!r} {int(r)}\n" for v, r in zip(z, rs))


def _sim_input(n=1500):
    t = np.arange(n) / FS
    w = 2.0 * np.sin(2 * np.pi * 0.5 * t)
    rs = np.zeros(n, dtype=bool)
    rs[n // 2] = True
    return w, rs


# ------------------------------------------------------------ outputs
@pytest.mark.slow
def test_fogdenoiser_from_c_equals_denoise(fmus, host):
    z = gd.simulate("paper_fog", 1500, seed=4, true_rate_deg_s=1.0).rate_deg_s
    rs = np.zeros(len(z), dtype=bool)
    proc = _run(host, fmus["FogDenoiser"], "run", "--set", f"sample_period={H!r}", stdin=_lines(z, rs))
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = np.array([float(v) for v in proc.stdout.split()])
    np.testing.assert_allclose(out, gd.denoise(z, FS), rtol=0, atol=1e-9)


def test_simulatedfog_from_c_equals_simulate(fmus, host):
    w, rs = _sim_input()
    proc = _run(host, fmus["SimulatedFog"], "run", *SIM_ARGS, "--set", "seed=7", stdin=_lines(w, rs))
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = np.array([float(v) for v in proc.stdout.split()])
    ref = gd.simulate("paper_fog", len(w), seed=7, true_rate_deg_s=w, restarts=rs).rate_deg_s
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-9)


# ------------------------------------------------------------ resource URIs
def _uri_forms(d):
    r = d / "resources"
    return {
        "file:///path": f"file://{r}",
        "file:///path/": f"file://{r}/",
        "file:////path": f"file:///{r}",
        "plain path": str(r),
    }


@pytest.mark.slow
@pytest.mark.parametrize("form", ["file:///path", "file:///path/", "file:////path", "plain path"])
@pytest.mark.parametrize("name", list(F.FMUS))
def test_resource_uri_forms_that_work(fmus, host, name, form):
    d = fmus[name]
    args = SIM_ARGS if name == "SimulatedFog" else ()
    proc = _run(host, d, "run", "--uri", _uri_forms(d)[form], *args, stdin="0.5 0\n0.25 0\n")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert len(proc.stdout.split()) == 2


def test_percent_encoded_space_in_the_uri(fmus, host, tmp_path):
    d = tmp_path / "dir with space" / "SimulatedFog"
    shutil.copytree(fmus["SimulatedFog"], d)
    uri = "file://" + str(d / "resources").replace(" ", "%20")
    proc = _run(host, d, "run", "--uri", uri, *SIM_ARGS, stdin="0.5 0\n")
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.xfail(strict=False, reason=(
    "pythonfmu 0.7.0 exporter (src/pythonfmu/fmi2.cpp fmi2Instantiate): the URI is only "
    "stripped of a literal 'file://' (and %20 decoded), so file:/p, file://localhost/p and '' "
    "give a path where PySlaveInstance's constructor cannot read slavemodule.txt; findClass "
    "returns nullptr with no Python error set, handle_py_exception does not throw, and "
    "initialize() calls PyObject_Call(nullptr): segfault. NULL: std::string(nullptr) outside the "
    "try: std::terminate. Nothing in the FMU runs before; hosts: pass file:///absolute/path"))
@pytest.mark.parametrize("form", ["file:/path", "file://localhost/path", "empty", "NULL"])
def test_resource_uri_forms_pythonfmu_crashes_on(fmus, host, form):
    r = fmus["SimulatedFog"] / "resources"
    uri = {"file:/path": f"file:{r}", "file://localhost/path": f"file://localhost{r}",
           "empty": "", "NULL": "NULL"}[form]
    proc = _run(host, fmus["SimulatedFog"], "run", "--uri", uri, *SIM_ARGS, stdin="0.5 0\n")
    assert proc.returncode in (0, 100), f"host killed by signal {-proc.returncode}"


# ------------------------------------------------------------ clean exits
@pytest.mark.slow
@pytest.mark.parametrize("name", list(F.FMUS))
def test_clean_exits(fmus, host, name):
    """SimulatedFog crashed at exit in 1 of 5 to 13 of 13 runs (pythonfmu's static
    shared_ptr released again by its library destructor; scipy's _uarray in
    Py_FinalizeEx; the module dict's borrowed reference released at every
    instantiation): worked around in gyrodenoise/fmu/sources/simulatedfog_fmu.py."""
    args = SIM_ARGS if name == "SimulatedFog" else ()
    stdin = "".join(f"{0.01 * k!r} 0\n" for k in range(300))
    codes = [_run(host, fmus[name], "run", *args, stdin=stdin).returncode for _ in range(N_EXITS)]
    assert codes == [0] * N_EXITS


# ------------------------------------------------------------ forbidden calls from C
def test_simulatedfog_forbidden_calls_from_c(fmus, host):
    """What pythonfmu lets the slave answer: a refused step is fmi2Discard (not
    fmi2Error), a refused write is logged and refuses the next step, unknown value
    references are fmi2Fatal with the reason logged; and nothing crashes (the
    instance stays usable after such an fmi2Fatal, the process exits cleanly)."""
    proc = _run(host, fmus["SimulatedFog"], "forbidden", *SIM_ARGS, "--set", "seed=3", "--log")
    assert 0 <= proc.returncode < 100, f"host crashed ({proc.returncode}): {proc.stderr[-2000:]}"
    res = {line.split(":")[0][5:]: line for line in proc.stdout.splitlines() if line.startswith(("PASS", "FAIL"))}
    for what in ("fmi2DoStep before initialisation", "fmi2DoStep with step size -0.005",
                 "fmi2DoStep with step size 0", "fmi2DoStep with step size nan",
                 "fmi2DoStep after fmi2Terminate"):
        assert "status 2, reason logged: yes" in res[what], res[what]
    for what in ("fmi2GetReal of an unknown value reference", "fmi2SetReal of an unknown value reference"):
        assert "status 4, reason logged: yes" in res[what], res[what]
    err = proc.stderr
    assert "'measured_rate' refused (it is an output)" in err
    assert "fixed parameter 'seed' after initialisation refused" in err
    assert "fmi2DoStep after fmi2Terminate refused" in err
    assert "unknown value reference(s) [2147483392]" in err
    assert res["fmi2Reset from the error state"].startswith("PASS")


# ------------------------------------------------------------ SimulatedFog in process (fmpy)
def _inst(fmus):
    return F.FmuInstance(fmus["_fmu"] / "SimulatedFog.fmu", "sf")


def test_simulatedfog_forbidden_writes_and_step_after_terminate(fmus):
    from fmpy.fmi1 import FMICallException
    a = _inst(fmus)
    try:
        a.initialize(seed=5)
        a.set(true_rate=1.0)
        a.slave.doStep(0.0, H)
        out = a.get("measured_rate")
        a.set(measured_rate=123.0)                       # an output
        assert a.get("measured_rate") == out
        with pytest.raises(FMICallException) as exc:
            a.slave.doStep(H, H)
        assert exc.value.status == 2
        assert any("'measured_rate' refused (it is an output)" in m[2] for m in a.errors())
        a.slave.doStep(H, H)                             # reported once, then it steps
        a.set(restarted=True)                            # the other output
        assert a.get("restarted") is False
        with pytest.raises(FMICallException):
            a.slave.doStep(2 * H, H)
        a.set(seed=9)                                    # a fixed parameter after initialisation
        assert a.get("seed") == 5
        with pytest.raises(FMICallException):
            a.slave.doStep(2 * H, H)
        assert any("fixed parameter 'seed' after initialisation refused" in m[2] for m in a.errors())
        a.set(card="icm20602")
        assert a.get("card") == "paper_fog"
        with pytest.raises(FMICallException):
            a.slave.doStep(2 * H, H)
        a.slave.doStep(2 * H, H)
        a.slave.terminate()
        with pytest.raises(FMICallException) as exc:
            a.slave.doStep(3 * H, H)
        assert exc.value.status == 2
        assert any("fmi2DoStep after fmi2Terminate refused" in m[2] for m in a.errors())
    finally:
        a.free()


def test_simulatedfog_parameters_settable_before_initialisation_and_after_reset(fmus):
    a = _inst(fmus)
    try:
        # sample 0 at fmi2ExitInitializationMode (true_rate set before it), then a step per sample
        a.initialize(seed=11, strict_step_size=True, true_rate=1.0)
        step = F._stepper(a, "true_rate", "restart", "measured_rate")
        first = [a.get("measured_rate")] + [step(1.0, False, k * H, H) for k in range(49)]
        a.slave.reset()
        a.initialize(seed=11, strict_step_size=True, true_rate=1.0)
        again = [a.get("measured_rate")] + [step(1.0, False, k * H, H) for k in range(49)]
    finally:
        a.free()
    assert first == again
    ref = gd.simulate("paper_fog", 50, seed=11, true_rate_deg_s=1.0).rate_deg_s
    np.testing.assert_allclose(first, ref, rtol=0, atol=1e-9)


def test_simulatedfog_corrupted_state_is_refused_and_the_instance_kept(fmus):
    """A corrupted state is refused at fmi2SetFMUstate (pythonfmu answers a raising slave with
    fmi2Fatal), the reason logged; the instance keeps its state and steps on."""
    from fmpy.fmi1 import FMICallException
    a = _inst(fmus)
    try:
        a.initialize()
        st = a.slave.deSerializeFMUstate(b"{not json")
        with pytest.raises(FMICallException):
            a.slave.setFMUstate(st)
        a.slave.freeFMUstate(st)
        assert any("state" in m[2] for m in a.errors()), a.messages
        a.slave.doStep(0.0, H)
    finally:
        a.free()


_AFTER_FATAL = r"""
import sys
from gyrodenoise import fmu as F
from fmpy.fmi1 import FMICallException
a = F.FmuInstance(sys.argv[1], "x")
inp, out = sys.argv[2], sys.argv[3]
a.initialize()
for _ in range(4):
    try:
        a.slave.getReal([99999])
    except FMICallException as exc:
        assert exc.status == 4
a.set(**{inp: 1.0})
a.slave.doStep(0.0, 0.005)
print(a.get(out))
a.free()
print("ok")
"""


@pytest.mark.slow
@pytest.mark.parametrize("name,inp,out", [("SimulatedFog", "true_rate", "measured_rate"),
                                          ("FogDenoiser", "raw_rate", "filtered_rate")])
def test_usable_after_repeated_fatal(fmus, name, inp, out):
    """pythonfmu releases the instance's objects at every fmi2Fatal (and again in
    fmi2FreeInstance): the slaves keep them alive (gyrodenoise/fmu/sources/gyrodenoise_pythonfmu_rules.py),
    so later calls and the process exit do not crash."""
    proc = subprocess.run([sys.executable, "-c", _AFTER_FATAL, str(fmus["_fmu"] / f"{name}.fmu"), inp, out],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split()[-1] == "ok"


def test_state_json_roundtrip_unchanged(fmus):
    a = _inst(fmus)
    try:
        a.initialize(seed=2)
        st = a.slave.getFMUstate()
        blob = a.slave.serializeFMUstate(st)
        a.slave.freeFMUstate(st)
    finally:
        a.free()
    d = json.loads(bytes(blob))
    # version 2: the simulator's state is gdsim.c's state buffer (version 1 held numpy's generators)
    assert d["version"] == 2
    ref = SimStream("paper_fog", seed=2)
    ref.step(0.0, False)        # as initialised: sample 0 taken at fmi2ExitInitializationMode, no step yet
    assert d["sim"] == ref.get_state()
