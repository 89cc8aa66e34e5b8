"""Bias tracking in the FMUs (motion's option bias_tracking, docs/method/bias.md): the four
parameters and the output bias_hat declared (units, bounds), appended after every existing
variable (existing value references unchanged), and the FMUs' bias_hat and filtered_rate equal
to the Python API's (Denoiser.step / Denoiser.bias_hat) on a still-then-moving record.

The FMUs are the session's build (tests/conftest.py: fmu_build, native_build). Tolerance: none.
The native FMUs compile the C core (gdcore.c, gdbias.c) with the flags of the Python
extension, and the pythonfmu FogDenoiser runs the same Denoiser over its bundled copy of the
core (the compiled C core where it loads, else the plain-Python kernels, equal to it bit for bit:
tests/core/test_bias.py): all are compared with ==."""
import zipfile

import numpy as np
import pytest

from gyrodenoise import Denoiser
from gyrodenoise.core import methods
from gyrodenoise.fmu import variables

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402
from fmpy.fmi3 import FMU3Slave  # noqa: E402

H = variables.DEFAULT_STEP_SIZE_S
FS = 1.0 / H
NEW_PARAMETERS = ("bias_tracking", "bias_still_s", "bias_memory_s", "earth_rate_floor_deg_h")
#: the parameters' units and bounds as the registry states them
UNITS = {"bias_tracking": None, "bias_still_s": "s", "bias_memory_s": "s", "earth_rate_floor_deg_h": "deg/h"}
#: the run: every bias-tracking parameter away from its default, so that each must reach the core
OPTION = {"bias_tracking": 1, "bias_still_s": 0.5, "bias_memory_s": 2.0, "earth_rate_floor_deg_h": 30.0}
SCALAR = ("FogDenoiser", "FogDenoiserNative", "FogDenoiserNative3")
IMU = ("FogDenoiserImuNative", "FogDenoiserImuNative3")
AXES = variables.IMU_AXIS_NAMES


@pytest.fixture(scope="module")
def fmus(fmu_build, native_build, tmp_path_factory):
    """{name: (unzipped folder, model description)} of the denoiser FMUs of the session's build."""
    folder, proc = fmu_build
    if proc.returncode != 0:
        pytest.skip(f"fmu build failed: {proc.stderr[-300:]}")
    dest = tmp_path_factory.mktemp("bias_fmus")
    out = {}
    for name in SCALAR + IMU:
        fmu = (folder if name == "FogDenoiser" else native_build[0]) / f"{name}.fmu"
        if not fmu.is_file():
            pytest.skip(f"{name}.fmu not built")
        with zipfile.ZipFile(fmu) as z:
            z.extractall(dest / name)
        out[name] = (dest / name, read_model_description(str(fmu)))
    return out


def record(axis=0, n=int(25 * FS)):
    """20 s still, then a 0.5 Hz manoeuvre; a bias of 72 (1 + axis) deg/h and 0.001 deg/s of white
    noise (an angle random walk of 0.004 deg/sqrt(h): navigation grade, so the Earth-rate floor
    applies and bias_hat is the bias less the floor)."""
    rng = np.random.default_rng(11 + axis)
    t = np.arange(n) / FS
    true = np.where(t >= 20.0, (20.0 + 5.0 * axis) * np.sin(2.0 * np.pi * 0.5 * (t - 20.0)), 0.0)
    return true + 0.02 * (1 + axis) + 0.001 * rng.standard_normal(n)


def python_api(z):
    """(filtered rate, bias_hat) after each sample: the Python API with the option on."""
    d = Denoiser(FS, **OPTION)
    out, hat = np.empty(len(z)), np.empty(len(z))
    for i, x in enumerate(z):
        out[i] = d.step(x)
        hat[i] = d.bias_hat
    return out, hat


class Run:
    """An FMU instance (FMI 2.0 or 3.0) in fmpy, initialised with ``params``; ``step(values)``
    sets the raw rate(s), takes one step and returns the reals read after it."""

    def __init__(self, unz, md, params):
        self.fmi3 = md.fmiVersion.startswith("3")
        self.v = {v.name: v for v in md.modelVariables}
        cls = FMU3Slave if self.fmi3 else FMU2Slave
        self.s = cls(guid=md.guid, unzipDirectory=str(unz), modelIdentifier=md.coSimulation.modelIdentifier,
                     instanceName="bias")
        self.s.instantiate()
        if not self.fmi3:
            self.s.setupExperiment(startTime=0.0)
        self.s.enterInitializationMode()
        for name, value in params.items():
            v = self.v[name]
            setter = {"Real": "setReal", "Float64": "setFloat64", "Integer": "setInteger", "Int32": "setInt32",
                      "String": "setString"}[v.type]
            getattr(self.s, setter)([v.valueReference], [value])
        self.s.exitInitializationMode()
        self.t = 0.0

    def set(self, names, values):
        refs = [self.v[n].valueReference for n in names]
        (self.s.setFloat64 if self.fmi3 else self.s.setReal)(refs, list(values))

    def get(self, names, n_values=None):
        refs = [self.v[n].valueReference for n in names]
        if self.fmi3:
            return self.s.getFloat64(refs, n_values or len(refs))
        return self.s.getReal(refs)

    def step(self):
        self.s.doStep(self.t, H)
        self.t += H

    def close(self):
        self.s.terminate()
        self.s.freeInstance()


# ------------------------------------------------------------------ declarations
@pytest.mark.parametrize("name", SCALAR + IMU)
def test_declared_with_units_and_bounds_after_the_existing_variables(fmus, name):
    md = fmus[name][1]
    got = {v.name: v for v in md.modelVariables}
    spec = {**variables.MODELS, **variables.FMI3_MODELS}[name]
    for p in NEW_PARAMETERS:
        v, reg = got[p], methods.BY_FMU[p]
        lo, hi = reg.fmu_bounds()
        assert v.causality == "parameter" and v.unit == UNITS[p], (p, v.unit)
        assert (v.min is None if lo is None else float(v.min) == lo), (p, v.min, lo)
        assert (v.max is None if hi is None else float(v.max) == hi), (p, v.max, hi)
        assert float(v.start) == float(reg.fmu_default()), (p, v.start)
    hats = ["bias_hat"] if name in SCALAR or name.endswith("3") else [f"bias_hat_{a}" for a in AXES]
    for h in hats:
        assert got[h].causality == "output" and got[h].unit == "deg/s", h
    if name == "FogDenoiserImuNative3":
        assert got["bias_hat"].dimensions and int(got["bias_hat"].dimensions[0].start) == 3
    # appended: the new variables are the last ones (the FMI 3.0 independent variable time after
    # them), so every variable declared before them keeps its value reference
    names = [v.name for v in md.modelVariables if v.name != "time"]
    tail = NEW_PARAMETERS + tuple(hats)
    assert tuple(names[-len(tail):]) == tail, names[-len(tail):]
    assert [v.valueReference for v in md.modelVariables if v.name != "time"] == list(range(len(names)))
    assert len(spec) == len(names)


def test_earth_rate_floor_unit_is_deg_per_hour():
    """deg/h: rad/s x pi / 180 / 3600 in the FMUs' unit definitions."""
    unit = variables.UNITS["deg/h"]
    assert unit["rad"] == "1" and unit["s"] == "-1" and float(unit["factor"]) == np.pi / 180.0 / 3600.0


# ------------------------------------------------------------------ outputs
@pytest.mark.parametrize("name", SCALAR)
def test_scalar_fmu_bias_hat_and_output_equal_the_python_api(fmus, name):
    z = record()
    want_out, want_hat = python_api(z)
    # the record engages the option and shows the floor: 72 - 30 deg/h removed through the manoeuvre
    assert want_hat[0] == 0.0 and abs(want_hat[-1] * 3600.0 - 42.0) < 0.5, want_hat[-1] * 3600.0
    run = Run(*fmus[name], OPTION)
    out, hat = np.empty(len(z)), np.empty(len(z))
    for i, x in enumerate(z):
        run.set(["raw_rate"], [float(x)])
        run.step()
        out[i], hat[i] = run.get(["filtered_rate", "bias_hat"])
    run.close()
    np.testing.assert_array_equal(hat, want_hat)
    np.testing.assert_array_equal(out, want_out)


@pytest.mark.parametrize("name", IMU)
def test_imu_fmu_bias_hat_per_axis_equals_the_python_api(fmus, name):
    zs = np.column_stack([record(j) for j in range(3)])
    want = [python_api(zs[:, j]) for j in range(3)]
    assert all(abs(w[1][-1] * 3600.0 - (72.0 * (1 + j) - 30.0)) < 0.5 for j, w in enumerate(want))
    run = Run(*fmus[name], OPTION)
    arrays = name.endswith("3")
    out, hat = np.empty(zs.shape), np.empty(zs.shape)
    for i, row in enumerate(zs):
        if arrays:
            run.set(["raw_rate"], row)
            run.step()
            out[i] = run.get(["filtered_rate"], 3)
            hat[i] = run.get(["bias_hat"], 3)
        else:
            run.set([f"raw_rate_{a}" for a in AXES], row)
            run.step()
            out[i] = run.get([f"filtered_rate_{a}" for a in AXES])
            hat[i] = run.get([f"bias_hat_{a}" for a in AXES])
    run.close()
    for j in range(3):
        np.testing.assert_array_equal(hat[:, j], want[j][1])
        np.testing.assert_array_equal(out[:, j], want[j][0])
