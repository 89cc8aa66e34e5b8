"""The reference results every FMU carries (gyrodenoise.fmu.reference: documentation/<Model>_in.csv
and <Model>_ref.csv, as the Modelica Reference-FMUs ship <Model>_in.csv / <Model>_ref.csv),
produced by the library, replayed as fmusim replays them (tests/fmu/hosts.py: fmusim's stepping
and input application emulated over fmpy's FMU2Slave / FMU3Slave), through fmpy's simulate_fmu
with the same files, and through the plain C hosts (tests/chost/host.c: FMI 2.0,
tests/chost/host3.c: FMI 3.0). Tolerance: none: the CSV numbers are Python reprs (they read back
to the same doubles), the outputs are compared with ==."""
import subprocess
import zipfile

import numpy as np
import pytest

from gyrodenoise.fmu import native
from gyrodenoise.fmu.reference import (KINDS, N_SAMPLES, RESTART_AT, reference_documents, reference_tables,
                                       sensor_sample_rows)

from tests.fmu.fmi3 import FMI3_FMUS, Slave3, build_host3, host3_run, unzip_all  # noqa: E402
from tests.fmu.hosts import fmusim_run, read_table  # noqa: E402
from tests.helpers import CHOST  # noqa: E402

from fmpy import simulate_fmu  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402
from fmpy.util import read_csv as fmpy_read_csv  # noqa: E402

FMI2_NATIVE = ("FogDenoiserNative", "SimulatedFogNative", "FogDenoiserImuNative")
C_HOST2 = ("FogDenoiserNative", "SimulatedFogNative")     # one scalar input, one output: tests/chost/host.c
PYTHONFMU = ("FogDenoiser", "SimulatedFog")
ALL = PYTHONFMU + FMI2_NATIVE + FMI3_FMUS
H = 0.005
STOP = (N_SAMPLES - 1) * H      # the last row's time: fmusim --stop-time 3.995


@pytest.fixture(scope="module")
def fmus(fmu_build, native_build, tmp_path_factory):
    folder, proc = fmu_build
    if proc.returncode != 0:
        pytest.skip(f"fmu build failed: {proc.stderr[-300:]}")
    dest = tmp_path_factory.mktemp("reference")
    out = unzip_all(folder, PYTHONFMU, dest)
    out.update(unzip_all(native_build[0], FMI2_NATIVE + FMI3_FMUS, dest))
    return out


def documents(fmu, name):
    """(inputs, reference outputs) read from the FMU's documentation/ folder, fmusim's format."""
    with zipfile.ZipFile(fmu) as z:
        return (read_table(z.read(f"documentation/{name}_in.csv").decode()),
                read_table(z.read(f"documentation/{name}_ref.csv").decode()))


def test_reference_run_has_a_restart_and_filtered_samples():
    inputs, outputs = reference_tables("denoiser")
    assert len(inputs["time"]) == N_SAMPLES and np.flatnonzero(inputs["restart"]).tolist() == [RESTART_AT]
    y = outputs["filtered_rate"]
    filtered = y[1:] != inputs["raw_rate"][:-1]     # output row k + 1 filters input row k
    # warm-up after the start and after the restart: raw passed through for its first MO_WU_N0 - 1
    # samples at least (then the mean of the samples so far where they test as a constant, else raw)
    # until motion has read its noise level (MO_SPEC_N - 1 samples: the spectral floor's first block);
    # filtered (mostly: the motion filter may pass a manoeuvre sample through) in between and after
    from gyrodenoise.core.kernels import MO_SPEC_N, MO_WU_N0
    raw, w = MO_WU_N0 - 1, MO_SPEC_N - 1
    assert not filtered[:raw].any() and not filtered[RESTART_AT:RESTART_AT + raw].any()
    assert filtered[w:RESTART_AT].mean() > 0.5 and filtered[RESTART_AT + w:].mean() > 0.5


def test_sensor_reference_takes_row_k_in_the_step_from_t_k():
    """fmusim sets input row k before the step [t_k, t_(k+1)]: the sensor's sample k + 1 is taken
    from row k (sample 0 from row 0 at initialisation), so the restart of input row 500 shows in
    output row 501."""
    inputs, outputs = reference_tables("sensor")
    assert sensor_sample_rows(4).tolist() == [0, 0, 1, 2]
    assert np.flatnonzero(outputs["restarted"]).tolist() == [RESTART_AT + 1]


@pytest.mark.parametrize("kind", ["imu"])
def test_array_columns_are_fmusims_format(kind):
    """An array variable is one column named after it, its values space-separated (fmusim: 'Variable
    raw_rate[1] not found' for the columns raw_rate[1]..[3])."""
    docs = reference_documents("FogDenoiserImuNative3")
    header_in = docs["FogDenoiserImuNative3_in.csv"].decode().splitlines()[0]
    header_ref = docs["FogDenoiserImuNative3_ref.csv"].decode().splitlines()[0]
    assert header_in == "time,raw_rate,restart" and header_ref == "time,filtered_rate"
    inputs, _ = reference_tables(kind)
    assert read_table(docs["FogDenoiserImuNative3_in.csv"].decode())["raw_rate"].shape == inputs["raw_rate"].shape


@pytest.mark.parametrize("name", ALL)
def test_every_fmu_carries_the_library_reference_results(fmus, name):
    with zipfile.ZipFile(fmus[name][0]) as z:
        docs = {n[len("documentation/"):]: z.read(n) for n in z.namelist() if n.startswith("documentation/")
                and n.endswith(".csv")}
    assert docs == reference_documents(name)
    inputs, outputs = reference_tables(KINDS[name])
    ref = read_table(docs[f"{name}_ref.csv"].decode())
    assert list(ref) == list(outputs)
    for col, values in outputs.items():      # the CSV reads back to the library's doubles, bit for bit
        assert np.array_equal(ref[col], np.asarray(values, dtype=float)), col
    assert list(read_table(docs[f"{name}_in.csv"].decode())) == list(inputs)


def _slave(unz, md, name="ref"):
    """An fmpy slave of the FMU in initialisation mode (start time 0), and what keeps its callbacks."""
    if md.fmiVersion == "3.0":
        keep = Slave3(unz, md)
        keep.s.enterInitializationMode(startTime=0.0)
        return keep.s, keep
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(unz), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName=name)
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    return s, None


@pytest.mark.parametrize("name", ALL)
def test_replay_as_fmusim_equals_the_reference_row_for_row(fmus, name):
    """fmusim --interface-type cs --output-interval 0.005 --stop-time 3.995 --input-file <Model>_in.csv,
    emulated: every recorded row equals _ref.csv's."""
    fmu, unz, md = fmus[name]
    inputs, ref = documents(fmu, name)
    slave, _keep = _slave(unz, md)
    out = fmusim_run(slave, md, inputs, [c for c in ref if c != "time"], STOP, H)
    slave.terminate()
    slave.freeInstance()
    assert len(out["time"]) == N_SAMPLES
    for col in ref:
        assert np.array_equal(out[col], ref[col]), col


@pytest.mark.parametrize("name", ALL)
def test_fmpy_simulate_fmu_with_the_same_files_equals_the_reference(fmus, name, tmp_path):
    fmu, unz, md = fmus[name]
    with zipfile.ZipFile(fmu) as z:
        for kind in ("in", "ref"):
            (tmp_path / f"{kind}.csv").write_bytes(z.read(f"documentation/{name}_{kind}.csv"))
    ref = fmpy_read_csv(tmp_path / "ref.csv")
    res = simulate_fmu(str(fmu), input=fmpy_read_csv(tmp_path / "in.csv"), stop_time=STOP, output_interval=H,
                       output=[c for c in ref.dtype.names if c != "time"], fmi_type="CoSimulation")
    assert len(res) == N_SAMPLES
    for col in ref.dtype.names:
        assert np.array_equal(np.asarray(res[col], dtype=float), np.asarray(ref[col], dtype=float)), col


@pytest.fixture(scope="module")
def host2(tmp_path_factory):
    exe = tmp_path_factory.mktemp("refhost") / "host"
    proc = subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", f"-I{native.fmi_headers_dir()}",
                           str(CHOST / "host.c"), "-o", str(exe), "-ldl"], capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"the FMI 2.0 C host does not build here: {proc.stderr[-200:]}")
    return exe


def _host_rows(kind, n):
    """The input rows a C host is fed (one a sample) and the reference rows its outputs are: a sensor
    takes sample 0 at initialisation (--init-sample) from row 0, sample j from row j - 1; a
    denoiser filters rows 0..n-2 in the steps whose ends are the reference rows 1..n-1."""
    if kind == "sensor":
        return sensor_sample_rows(n), np.arange(n)
    return np.arange(n - 1), np.arange(1, n)


@pytest.mark.parametrize("name", C_HOST2)
def test_replay_through_the_fmi2_c_host_equals_the_reference(fmus, host2, name):
    fmu, unz, md = fmus[name]
    inputs, ref = documents(fmu, name)
    sensor = KINDS[name] == "sensor"
    col_in, col_out = ("true_rate", "measured_rate") if sensor else ("raw_rate", "filtered_rate")
    rows, refrows = _host_rows(KINDS[name], len(inputs["time"]))
    data = "".join(f"{float(inputs[col_in][k])!r} {int(inputs['restart'][k])}\n" for k in rows)
    args = ["--in", col_in, "--out", col_out] + (["--init-sample"] if sensor else [])
    proc = subprocess.run([str(host2), str(unz), "run", *args], input=data, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = np.array([float(x) for x in proc.stdout.split()])
    assert np.array_equal(out, ref[col_out][refrows])


@pytest.mark.parametrize("name", FMI3_FMUS)
def test_replay_through_the_fmi3_c_host_equals_the_reference(fmus, tmp_path_factory, name):
    exe = build_host3(tmp_path_factory.mktemp("host3"))
    fmu, unz, md = fmus[name]
    inputs, ref = documents(fmu, name)
    kind = KINDS[name]
    col_in, col_out = {"imu": ("raw_rate", "filtered_rate"), "sensor": ("true_rate", "measured_rate"),
                       "denoiser": ("raw_rate", "filtered_rate")}[kind]
    n = 3 if kind == "imu" else 1
    x = inputs[col_in].reshape(len(inputs["time"]), n)
    rows, refrows = _host_rows(kind, len(inputs["time"]))
    lines = [" ".join(repr(float(v)) for v in x[k]) + f" {int(inputs['restart'][k])}" for k in rows]
    out, _ = host3_run(exe, unz, md, [(col_in, n)], "restart", [(col_out, n)], lines,
                       init_sample=kind == "sensor")
    assert np.array_equal(out, ref[col_out].reshape(len(inputs["time"]), n)[refrows])
