"""How hosts we do not run here step our FMUs, emulated over fmpy's low-level API
(tests/fmu/hosts.py): a master that propagates values in initialisation mode (OMSimulator), a
master that accumulates its time (OMSimulator, the FMU Compliance Checker). Neither host is
installed here: these are emulations of their documented and observed behaviour."""
import zipfile

import numpy as np
import pytest

import gyrodenoise as gd
from tests.fmu.fmi import Logger  # noqa: E402
from tests.fmu.fmi3 import Slave3, unzip_all  # noqa: E402
from tests.fmu.hosts import Driver, accumulated_run, row_at  # noqa: E402

from fmpy.fmi2 import FMU2Slave  # noqa: E402

#: (sensor, denoiser) pairs of one FMU kind
CHAINS = {"native FMI 2.0": ("SimulatedFogNative", "FogDenoiserNative"),
          "native FMI 3.0": ("SimulatedFogNative3", "FogDenoiserNative3"),
          "pythonfmu": ("SimulatedFog", "FogDenoiser")}
H = 0.005


@pytest.fixture(scope="module")
def fmus(fmu_build, native_build, tmp_path_factory):
    folder, proc = fmu_build
    if proc.returncode != 0:
        pytest.skip(f"fmu build failed: {proc.stderr[-300:]}")
    dest = tmp_path_factory.mktemp("hosts")
    out = unzip_all(folder, ("SimulatedFog", "FogDenoiser"), dest)
    out.update(unzip_all(native_build[0], ("SimulatedFogNative", "FogDenoiserNative", "SimulatedFogNative3",
                                           "FogDenoiserNative3", "FogDenoiserImuNative3", "FogDenoiserImuNative"),
                         dest))
    return out


class Instance:
    """An fmpy slave of an unzipped FMU (FMI 2.0 or 3.0) with a Driver, its log kept."""

    def __init__(self, entry, name):
        fmu, unz, md = entry
        self.md = md
        self.log = []
        if md.fmiVersion == "3.0":
            self._keep = Slave3(unz, md, instance=name)
            self.s = self._keep.s
            self.log = self._keep.log
        else:
            self._keep = Logger()
            self.log = self._keep.messages
            self.s = FMU2Slave(guid=md.guid, unzipDirectory=str(unz),
                               modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
            self.s.instantiate(callbacks=self._keep.callbacks, loggingOn=True)
        self.d = Driver(self.s, md)

    def enter(self):
        if self.md.fmiVersion == "3.0":
            self.s.enterInitializationMode(startTime=0.0)
        else:
            self.s.setupExperiment(startTime=0.0)
            self.s.enterInitializationMode()

    def close(self):
        self.s.terminate()
        self.s.freeInstance()


def _truth(n):
    t = np.arange(n) * H
    truth = 0.5 + 3.0 * np.sin(2 * np.pi * 0.5 * t) * (t > 1.0)
    rs = np.zeros(n, dtype=bool)
    rs[300] = True
    return truth, rs


@pytest.mark.parametrize("chain", list(CHAINS))
def test_a_master_that_propagates_in_initialisation_gets_the_chain_from_sample_0(fmus, chain):
    """OMSimulator's order: in initialisation mode the sensor's outputs are read and set on the
    denoiser; then each step: every FMU steps, then the outputs are passed on. The sensor's
    sample 0 must be there in initialisation mode (it read 0.0 before: 0.49 deg/s off end to end
    at sample 0), and the denoiser's output from then on is gd.denoise(gd.simulate(...)) from
    sample 0."""
    sensor_name, denoiser_name = CHAINS[chain]
    n = 600
    truth, rs = _truth(n + 1)
    sensor, den = Instance(fmus[sensor_name], "sensor"), Instance(fmus[denoiser_name], "denoiser")
    sensor.enter()
    den.enter()
    sensor.d.set("true_rate", truth[0])
    sensor.d.set("restart", rs[0])
    s0, r0 = sensor.d.get("measured_rate"), sensor.d.get("restarted")
    den.d.set("raw_rate", s0)
    den.d.set("restart", r0)
    y_init = den.d.get("filtered_rate")
    sensor.s.exitInitializationMode()
    den.s.exitInitializationMode()
    assert sensor.d.get("measured_rate") == s0          # the sample taken at initialisation, unchanged
    assert den.d.get("filtered_rate") == y_init         # the first output, until the first step
    ys, ss = [], [s0]
    for k in range(n):
        sensor.d.set("true_rate", truth[k + 1])        # sample k + 1 from the step [t_k, t_k+1]
        sensor.d.set("restart", rs[k + 1])
        sensor.s.doStep(k * H, H)
        den.s.doStep(k * H, H)
        ys.append(den.d.get("filtered_rate"))
        ss.append(sensor.d.get("measured_rate"))
        den.d.set("raw_rate", ss[-1])                   # propagation after the step
        den.d.set("restart", sensor.d.get("restarted"))
    sensor.close()
    den.close()
    rec = gd.simulate("paper_fog", n + 1, seed=0, true_rate_deg_s=truth, restarts=rs)
    assert s0 == rec.rate_deg_s[0]
    assert np.array_equal(ss, rec.rate_deg_s)
    want = gd.denoise(rec.rate_deg_s[:n], 1 / H, restarts=rs[:n])
    assert y_init == want[0]
    assert np.array_equal(ys, want)


@pytest.mark.parametrize("name", ["FogDenoiserNative", "FogDenoiserNative3", "FogDenoiser",
                                  "FogDenoiserImuNative3"])
def test_the_denoisers_first_output_in_initialisation_follows_its_inputs_without_filtering(fmus, name):
    """Reading the output in initialisation mode filters nothing: the first step still filters the
    input set before it as sample 0."""
    inst = Instance(fmus[name], "d")
    inst.enter()
    imu = name.endswith("ImuNative3")
    z = (np.array([1.0, 2.0, 3.0]) if imu else 1.0)
    inst.d.set("raw_rate", z)
    first = inst.d.get("filtered_rate")
    inst.d.set("raw_rate", 2 * z)
    second = inst.d.get("filtered_rate")
    inst.s.exitInitializationMode()
    inst.d.set("raw_rate", 3 * z)
    inst.s.doStep(0.0, H)
    after = inst.d.get("filtered_rate")
    inst.close()
    one = lambda x: gd.denoise(np.array([x]), 1 / H)[0]  # noqa: E731
    np.testing.assert_array_equal(first, np.vectorize(one)(z))
    np.testing.assert_array_equal(second, np.vectorize(one)(2 * z))
    np.testing.assert_array_equal(after, np.vectorize(one)(3 * z))


@pytest.mark.parametrize("name,stop", [("FogDenoiserNative", 600.0), ("FogDenoiserNative3", 600.0),
                                       ("SimulatedFogNative", 600.0), ("SimulatedFogNative3", 4.0),
                                       ("FogDenoiser", 4.0), ("SimulatedFog", 4.0)])
def test_a_run_with_accumulated_time_ends_without_a_warning(fmus, name, stop):
    """t += 0.005 up to 600 s (or 4 s) ends with a step of 4.7e-10 s (6.3e-14 s): below 1e-6 of the
    sample period, no sample: answered OK without a warning, the outputs unchanged (OMSimulator
    treats a warning as an error: the run failed at its last step)."""
    inst = Instance(fmus[name], "acc")
    inst.enter()
    sensor = "Simulated" in name
    out = "measured_rate" if sensor else "filtered_rate"
    inst.s.exitInitializationMode()
    last = []
    sizes = accumulated_run(inst.s, inst.md, lambda t: {("true_rate" if sensor else "raw_rate"): 1.0 + np.sin(t)},
                            stop, H, on_step=lambda t, size: last.append(inst.d.get(out)) if size < H / 2 else None)
    assert 0 < sizes[-1] < 1e-6 * H and all(s == H for s in sizes[:-1])
    assert len(sizes) == round(stop / H) + 1
    assert [m for m in inst.log if m[0] >= 1] == []          # no warning, no error
    before = inst.d.get(out)
    inst.close()
    assert last == [before]


def test_the_reference_replays_under_accumulated_time(fmus):
    """A master that accumulates its time and reads its inputs at the row its time belongs to
    within 1e-6 of the period: the reference of FogDenoiserNative replays row for row, the
    restart on its sample, the last step a sliver."""
    from gyrodenoise.fmu.reference import N_SAMPLES
    from tests.fmu.hosts import read_table
    fmu, unz, md = fmus["FogDenoiserNative"]
    with zipfile.ZipFile(fmu) as z:
        inputs = read_table(z.read("documentation/FogDenoiserNative_in.csv").decode())
        ref = read_table(z.read("documentation/FogDenoiserNative_ref.csv").decode())
    inst = Instance(fmus["FogDenoiserNative"], "acc")
    inst.enter()
    inst.d.set("raw_rate", inputs["raw_rate"][0])
    inst.s.exitInitializationMode()
    rows = lambda t: row_at(inputs["time"], t, 1e-6 * H)  # noqa: E731
    out = [inst.d.get("filtered_rate")]
    accumulated_run(inst.s, md, lambda t: {"raw_rate": inputs["raw_rate"][rows(t)],
                                           "restart": inputs["restart"][rows(t)]},
                    (N_SAMPLES - 1) * H, H, on_step=lambda t, size: out.append(inst.d.get("filtered_rate")))
    assert [m for m in inst.log if m[0] >= 1] == []
    inst.close()
    assert np.array_equal(out[:N_SAMPLES], ref["filtered_rate"])


def test_the_3_axis_denoiser_without_arrays(fmus):
    """FogDenoiserImuNative: FMI 2.0, one scalar variable an axis (OMSimulator reads one value of an FMI
    3.0 array, FMI 2.0 hosts have none), the outputs of FogDenoiserImuNative3 axis by axis."""
    import gyrodenoise.fmu.variables as V
    md = fmus["FogDenoiserImuNative"][2]
    assert md.fmiVersion == "2.0"
    names = [v.name for v in md.modelVariables]
    assert names[:7] == ["raw_rate_x", "raw_rate_y", "raw_rate_z", "restart", "filtered_rate_x",
                         "filtered_rate_y", "filtered_rate_z"]
    assert names == [v.name for v in V.FOG_DENOISER_IMU_XYZ]
    xyz, arr = Instance(fmus["FogDenoiserImuNative"], "xyz"), Instance(fmus["FogDenoiserImuNative3"], "arr")
    rng = np.random.default_rng(3)
    z = 1.0 + 0.05 * rng.standard_normal((400, 3)) + np.array([0.0, 1.0, 2.0])
    for inst in (xyz, arr):
        inst.enter()
        inst.d.set("restart", False)
    for a, col in zip("xyz", z[0]):
        xyz.d.set(f"raw_rate_{a}", col)
    arr.d.set("raw_rate", z[0])
    xyz.s.exitInitializationMode()
    arr.s.exitInitializationMode()
    ys = []
    for k in range(len(z)):
        for a, col in zip("xyz", z[k]):
            xyz.d.set(f"raw_rate_{a}", col)
        arr.d.set("raw_rate", z[k])
        xyz.d.set("restart", k == 250)
        arr.d.set("restart", k == 250)
        xyz.s.doStep(k * H, H)
        arr.s.doStep(k * H, H)
        y = [xyz.d.get(f"filtered_rate_{a}") for a in "xyz"]
        assert np.array_equal(y, arr.d.get("filtered_rate"))
        ys.append(y)
    xyz.close()
    arr.close()
    rs = np.arange(len(z)) == 250
    for j in range(3):
        assert np.array_equal(np.array(ys)[:, j], gd.denoise(z[:, j], 1 / H, restarts=rs))
