"""The FMI 3.0 native FMUs (FogDenoiserNative3, SimulatedFogNative3, FogDenoiserImuNative3),
from the session's `fmu build` (tests/conftest.py: native_build): fmpy validate clean, the
model description in FMI 3.0 form from the same declarations as the FMI 2.0 FMUs, fmpy's
FMU3Slave equal to gd.denoise / gd.simulate bit for bit (the 3-axis FMU: each axis), a NaN
input answered with fmi3Warning and the healed output, a bad parameter refused with the
reason, FMU states round trips, fmi3DoStep's out-parameters."""
import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.fmu import native
from gyrodenoise.fmu.native3 import FMI3_PLATFORM_FOLDERS, fmi3_platform_folder
from tests.conftest import FMI3_TEST_PLATFORM
from gyrodenoise.fmu.variables import FOG_DENOISER, FOG_DENOISER_IMU, SIMULATED_FOG_NATIVE

from tests.fmu.fmi import FMI_ERROR, FMI_WARNING  # noqa: E402
from tests.fmu.fmi3 import FMI3_FMUS, Slave3, unzip_all  # noqa: E402

from fmpy.fmi1 import FMICallException  # noqa: E402

FS = 200.0
H = 1.0 / FS


@pytest.fixture(scope="module")
def fmus(native_build, tmp_path_factory):
    return unzip_all(native_build[0], FMI3_FMUS, tmp_path_factory.mktemp("fmi3"))


def slave(fmus, name, **params):
    """A Slave3 of ``name`` in initialisation mode with ``params`` set."""
    s = Slave3(fmus[name][1], fmus[name][2])
    s.s.enterInitializationMode(startTime=0.0)
    s.set(**params)
    return s


def signal(n, seed=3, restart_at=None):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    z = 1.0 + 2.0 * np.sin(2 * np.pi * 0.6 * t) * (t > 1.0) + 0.05 * rng.standard_normal(n)
    rs = np.zeros(n, dtype=bool)
    rs[restart_at if restart_at is not None else 2 * n // 3] = True
    return z, rs


def denoise_run(s, z, rs, n_axes=1):
    vr = s.vr
    out = np.empty((len(z), n_axes))
    for k in range(len(z)):
        s.s.setFloat64([vr["raw_rate"]], list(np.atleast_1d(z[k]).astype(float)))
        s.s.setBoolean([vr["restart"]], [bool(rs[k])])
        ev, term, early, last = s.s.doStep(k * H, H)
        assert (ev, term, early) == (False, False, False) and last == (k * H) + H
        out[k] = s.s.getFloat64([vr["filtered_rate"]], n_axes)
    return out[:, 0] if n_axes == 1 else out


def test_fmpy_validate_clean(fmus):
    from fmpy.validation import validate_fmu
    for name in FMI3_FMUS:
        assert validate_fmu(str(fmus[name][0])) == [], name


def test_model_descriptions_fmi3_form_same_variables_as_fmi2(fmus):
    for name, decl in (("FogDenoiserNative3", FOG_DENOISER), ("SimulatedFogNative3", SIMULATED_FOG_NATIVE),
                       ("FogDenoiserImuNative3", FOG_DENOISER_IMU)):
        md = fmus[name][2]
        assert md.fmiVersion == "3.0" and md.guid.startswith("{")
        cs = md.coSimulation
        assert cs.modelIdentifier == name and cs.canHandleVariableCommunicationStepSize is False
        assert float(cs.fixedInternalStepSize) == 0.005 and md.defaultExperiment.stepSize == "0.005"
        declared = [(v.name, v.causality, v.unit) for v in decl]
        got = [(v.name, v.causality, v.declaredType.unit if v.declaredType else v.unit)
               for v in md.modelVariables if v.causality != "independent"]
        assert got == declared, name
        assert [v.valueReference for v in md.modelVariables] == list(range(len(decl) + 1))
        time = md.modelVariables[-1]
        assert (time.name, time.causality, time.type) == ("time", "independent", "Float64")
        assert [u.variable.name for u in md.outputs] == [v.name for v in decl if v.causality == "output"]
    imu = {v.name: v for v in fmus["FogDenoiserImuNative3"][2].modelVariables}
    for name in ("raw_rate", "filtered_rate"):
        assert imu[name].type == "Float64" and [int(d.start) for d in imu[name].dimensions] == [3]
    assert imu["restart"].type == "Boolean" and not imu["restart"].dimensions
    types = {v.name: v.type for v in fmus["FogDenoiserNative3"][2].modelVariables}
    assert (types["raw_rate"], types["ar_order"], types["converged"], types["method"]) == \
        ("Float64", "Int32", "Boolean", "String")


def test_binaries_in_fmi3_platform_folders(fmus, native_build):
    # the session builds the FMI 3.0 FMUs for one platform (tests/conftest.py: FMI3_TEST_PLATFORM)
    built = {plat for plat, what in native_build[1].items() if not what.startswith("skipped")}
    assert FMI3_TEST_PLATFORM in built
    for name in FMI3_FMUS:
        folders = {p.name for p in (fmus[name][1] / "binaries").iterdir()}
        assert folders == {FMI3_PLATFORM_FOLDERS[FMI3_TEST_PLATFORM]}, name
    assert [fmi3_platform_folder(p) for p in ("linux64", "win64", "darwin64")] == \
        ["x86_64-linux", "x86_64-windows", "x86_64-darwin"]
    assert fmi3_platform_folder("aarch64-darwin") == "aarch64-darwin"


@pytest.mark.parametrize("method", ["motion", "shakf"])
def test_denoiser_equals_gd_denoise_bit_for_bit(fmus, method):
    z, rs = signal(700)
    s = slave(fmus, "FogDenoiserNative3", method=method, warmup_s=0.25)
    s.s.exitInitializationMode()
    y = denoise_run(s, z, rs)
    ref = gd.denoise(z, FS, method=method, restarts=rs, warmup_s=0.25)
    assert np.array_equal(y, ref)
    s.s.terminate()
    s.s.freeInstance()


def test_imu_each_axis_equals_gd_denoise_bit_for_bit(fmus):
    zs = np.column_stack([signal(600, seed=j)[0] * (j + 1) for j in range(3)])
    rs = signal(600)[1]
    s = slave(fmus, "FogDenoiserImuNative3", warmup_s=0.25)
    s.s.exitInitializationMode()
    y = denoise_run(s, zs, rs, n_axes=3)
    for j in range(3):
        assert np.array_equal(y[:, j], gd.denoise(zs[:, j], FS, restarts=rs, warmup_s=0.25)), j
    s.s.freeInstance()


def test_sensor_equals_gd_simulate_bit_for_bit(fmus):
    n = 500
    truth, rs = signal(n)
    s = slave(fmus, "SimulatedFogNative3", seed=4)
    out = np.empty(n)
    for k in range(n):
        s.s.setFloat64([s.vr["true_rate"]], [float(truth[k])])
        s.s.setBoolean([s.vr["restart"]], [bool(rs[k])])
        if k == 0:
            s.s.exitInitializationMode()
        else:
            s.s.doStep((k - 1) * H, H)
        out[k] = s.s.getFloat64([s.vr["measured_rate"]])[0]
    ref = gd.simulate("paper_fog", n, seed=4, true_rate_deg_s=truth, restarts=rs).rate_deg_s
    assert np.array_equal(out, ref)


@pytest.mark.parametrize("name", ["FogDenoiserNative3", "FogDenoiserImuNative3"])
def test_nan_input_is_a_warning_and_healed_as_gd_denoise(fmus, name):
    n_axes = 3 if name.startswith("FogDenoiserImu") else 1
    z, rs = signal(400)
    z[150] = np.nan
    zz = np.column_stack([z] * n_axes) if n_axes > 1 else z
    s = slave(fmus, name, warmup_s=0.25)
    s.s.exitInitializationMode()
    y = denoise_run(s, zz, rs, n_axes)
    warnings = [m for st, c, m in s.log if st == FMI_WARNING]
    assert len(warnings) == n_axes and "raw_rate" in warnings[0] and "is nan at t=0.75" in warnings[0]
    assert all(c == "logStatusWarning" for st, c, m in s.log if st == FMI_WARNING)
    ref = gd.denoise(z, FS, restarts=rs, warmup_s=0.25)
    for j in range(n_axes):     # the dropout sample passes through as NaN, as in gd.denoise
        assert np.array_equal(y if n_axes == 1 else y[:, j], ref, equal_nan=True)
    assert np.isnan(ref[150]) and np.all(np.isfinite(np.delete(ref, 150)))


@pytest.mark.parametrize("name,params,reason", [
    ("FogDenoiserNative3", {"lam": 1.5}, "lam out of range"),
    ("FogDenoiserImuNative3", {"method": "kalman"}, "method must be one of"),
    ("SimulatedFogNative3", {"card": "no_such_card"}, "card"),
])
def test_bad_parameter_refused_with_the_reason(fmus, name, params, reason):
    s = slave(fmus, name, **params)
    with pytest.raises(FMICallException):
        s.s.exitInitializationMode()
    errors = [m for st, c, m in s.log if st >= FMI_ERROR]
    assert errors and errors[-1].startswith("fmi3ExitInitializationMode: invalid parameter") and reason in errors[-1]


def test_fixed_parameter_after_initialisation_and_forbidden_calls_refused(fmus):
    s = slave(fmus, "FogDenoiserNative3")
    s.s.exitInitializationMode()
    with pytest.raises(FMICallException):
        s.s.setFloat64([s.vr["lam"]], [0.9])
    assert "lam is a fixed parameter" in s.log[-1][2] and "fmi3ExitInitializationMode" in s.log[-1][2]
    s.s.reset()     # the error state is left by fmi3Reset
    s.s.enterInitializationMode(startTime=0.0)
    s.s.exitInitializationMode()
    with pytest.raises(FMICallException):
        s.s.enterEventMode()
    assert "hasEventMode" in s.log[-1][2]


def test_time_is_the_independent_variable(fmus):
    s = slave(fmus, "FogDenoiserNative3")
    s.s.exitInitializationMode()
    t_vr = len(FOG_DENOISER)
    for k in range(3):
        s.s.doStep(k * H, H)
    assert s.s.getFloat64([t_vr]) == [3 * H]


@pytest.mark.parametrize("name", ["FogDenoiserNative3", "FogDenoiserImuNative3"])
def test_fmu_state_round_trip_and_serialized(fmus, name):
    n_axes = 3 if name.startswith("FogDenoiserImu") else 1
    z, rs = signal(500)
    zz = np.column_stack([z * (j + 1) for j in range(n_axes)])
    s = slave(fmus, name, warmup_s=0.25)
    s.s.exitInitializationMode()
    first = [_step_at(s, k, zz[k], rs[k], n_axes) for k in range(250)]
    state = s.s.getFMUState()
    blob = s.s.serializeFMUState(state)
    rest = [_step_at(s, k, zz[k], rs[k], n_axes) for k in range(250, 500)]
    s.s.setFMUState(state)
    assert np.array_equal([_step_at(s, k, zz[k], rs[k], n_axes) for k in range(250, 500)], rest)
    other = slave(fmus, name, warmup_s=0.25)
    other.s.exitInitializationMode()
    restored = other.s.deserializeFMUState(blob)
    other.s.setFMUState(restored)
    assert np.array_equal([_step_at(other, k, zz[k], rs[k], n_axes) for k in range(250, 500)], rest)
    full = np.array(first + rest).reshape(500, n_axes)
    for j in range(n_axes):
        assert np.array_equal(full[:, j], gd.denoise(zz[:, j], FS, restarts=rs, warmup_s=0.25)), j
    s.s.freeFMUState(state)
    other.s.freeFMUState(restored)


def _step_at(s, k, z, r, n_axes):
    s.s.setFloat64([s.vr["raw_rate"]], list(np.atleast_1d(z).astype(float)))
    s.s.setBoolean([s.vr["restart"]], [bool(r)])
    s.s.doStep(k * H, H)
    y = s.s.getFloat64([s.vr["filtered_rate"]], n_axes)
    return y[0] if n_axes == 1 else y


def test_exports_only_fmi3_functions(fmus):
    from tests.fmu.fmi import exported_symbols
    so = fmus["FogDenoiserNative3"][1] / "binaries" / "x86_64-linux" / "FogDenoiserNative3.so"
    syms = exported_symbols(so)
    assert syms and all(x.startswith("fmi3") for x in syms), sorted(syms)
    assert {"fmi3InstantiateCoSimulation", "fmi3DoStep", "fmi3GetFloat64", "fmi3SerializeFMUState"} <= syms
    assert native.host_platform() is None or (fmus["FogDenoiserNative3"][1] / "binaries" / "x86_64-linux").is_dir()
