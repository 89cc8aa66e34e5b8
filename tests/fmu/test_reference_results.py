"""The reference results every FMU carries (gyrodenoise.fmu.reference: documentation/<Model>_in.csv
and <Model>_ref.csv, as the Modelica Reference-FMUs ship <Model>_in.csv / <Model>_ref.csv),
produced by the library, replayed through fmpy (FMI 2.0: FMU2Slave, FMI 3.0: FMU3Slave) and
through the plain C hosts (tests/chost/host.c: FMI 2.0, tests/chost/host3.c: FMI 3.0). Tolerance:
none: the CSV numbers are Python reprs (they read back to the same doubles), the outputs are
compared with ==."""
import io
import subprocess
import zipfile

import numpy as np
import pytest

from gyrodenoise.fmu import native
from gyrodenoise.fmu.reference import KINDS, N_SAMPLES, RESTART_AT, reference_documents, reference_tables

from tests.fmu.fmi3 import FMI3_FMUS, Slave3, build_host3, host3_run, run_reference, unzip_all  # noqa: E402
from tests.helpers import CHOST  # noqa: E402

from fmpy.fmi2 import FMU2Slave  # noqa: E402

FMI2_NATIVE = ("FogDenoiserNative", "SimulatedFogNative")
PYTHONFMU = ("FogDenoiser", "SimulatedFog")
ALL = PYTHONFMU + FMI2_NATIVE + FMI3_FMUS


@pytest.fixture(scope="module")
def fmus(fmu_build, native_build, tmp_path_factory):
    folder, proc = fmu_build
    if proc.returncode != 0:
        pytest.skip(f"fmu build failed: {proc.stderr[-300:]}")
    dest = tmp_path_factory.mktemp("reference")
    out = unzip_all(folder, PYTHONFMU, dest)
    out.update(unzip_all(native_build[0], FMI2_NATIVE + FMI3_FMUS, dest))
    return out


def read_csv(data):
    """{column: array} of a reference CSV (bytes)."""
    text = data.decode()
    names = text.splitlines()[0].split(",")
    values = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1, ndmin=2)
    return {n: values[:, i] for i, n in enumerate(names)}


def test_reference_run_has_a_restart_and_filtered_samples():
    inputs, outputs = reference_tables("denoiser")
    assert len(inputs["time"]) == N_SAMPLES and np.flatnonzero(inputs["restart"]).tolist() == [RESTART_AT]
    filtered = outputs["filtered_rate"] != inputs["raw_rate"]
    # warm-up (raw passed through) 0..200 and 500..700; filtered (mostly: the motion filter may pass a
    # manoeuvre sample through) in between and after
    assert not filtered[:200].any() and not filtered[RESTART_AT:RESTART_AT + 200].any()
    assert filtered[200:RESTART_AT].mean() > 0.5 and filtered[RESTART_AT + 200:].mean() > 0.5


@pytest.mark.parametrize("name", ALL)
def test_every_fmu_carries_the_library_reference_results(fmus, name):
    with zipfile.ZipFile(fmus[name][0]) as z:
        docs = {n[len("documentation/"):]: z.read(n) for n in z.namelist() if n.startswith("documentation/")
                and n.endswith(".csv")}
    assert docs == reference_documents(name)
    inputs, outputs = reference_tables(KINDS[name])
    ref = read_csv(docs[f"{name}_ref.csv"])
    assert list(ref) == list(outputs)
    for col, values in outputs.items():      # the CSV reads back to the library's doubles, bit for bit
        assert np.array_equal(ref[col], np.asarray(values, dtype=float)), col
    assert list(read_csv(docs[f"{name}_in.csv"])) == list(inputs)


@pytest.mark.parametrize("name", ALL)
def test_replay_through_fmpy_equals_the_reference(fmus, name):
    fmu, unz, md = fmus[name]
    with zipfile.ZipFile(fmu) as z:
        inputs = read_csv(z.read(f"documentation/{name}_in.csv"))
        ref = read_csv(z.read(f"documentation/{name}_ref.csv"))
    inputs["restart"] = inputs["restart"].astype(bool)
    if md.fmiVersion == "3.0":
        s = Slave3(unz, md)
        slave, vr = s.s, s.vr
        slave.enterInitializationMode(startTime=0.0)
    else:
        slave = FMU2Slave(guid=md.guid, unzipDirectory=str(unz), modelIdentifier=md.coSimulation.modelIdentifier,
                          instanceName="ref")
        vr = {v.name: v.valueReference for v in md.modelVariables}
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
    out = run_reference(slave, vr, KINDS[name], inputs)
    slave.terminate()
    slave.freeInstance()
    for col, values in out.items():
        assert np.array_equal(values.astype(float), ref[col]), col


@pytest.fixture(scope="module")
def host2(tmp_path_factory):
    exe = tmp_path_factory.mktemp("refhost") / "host"
    proc = subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", f"-I{native.fmi_headers_dir()}",
                           str(CHOST / "host.c"), "-o", str(exe), "-ldl"], capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"the FMI 2.0 C host does not build here: {proc.stderr[-200:]}")
    return exe


@pytest.mark.parametrize("name", FMI2_NATIVE)
def test_replay_through_the_fmi2_c_host_equals_the_reference(fmus, host2, name):
    fmu, unz, md = fmus[name]
    inputs, ref = (read_csv(zipfile.ZipFile(fmu).read(f"documentation/{name}_{k}.csv")) for k in ("in", "ref"))
    sensor = KINDS[name] == "sensor"
    col_in, col_out = ("true_rate", "measured_rate") if sensor else ("raw_rate", "filtered_rate")
    data = "".join(f"{float(v)!r} {int(r)}\n" for v, r in zip(inputs[col_in], inputs["restart"]))
    args = ["--in", col_in, "--out", col_out] + (["--init-sample"] if sensor else [])
    proc = subprocess.run([str(host2), str(unz), "run", *args], input=data, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = np.array([float(x) for x in proc.stdout.split()])
    assert np.array_equal(out, ref[col_out])


@pytest.mark.parametrize("name", FMI3_FMUS)
def test_replay_through_the_fmi3_c_host_equals_the_reference(fmus, tmp_path_factory, name):
    exe = build_host3(tmp_path_factory.mktemp("host3"))
    fmu, unz, md = fmus[name]
    inputs, ref = (read_csv(zipfile.ZipFile(fmu).read(f"documentation/{name}_{k}.csv")) for k in ("in", "ref"))
    kind = KINDS[name]
    if kind == "imu":
        ins, outs = [("raw_rate", 3)], [("filtered_rate", 3)]
        cols_in, cols_out = [f"raw_rate[{j}]" for j in (1, 2, 3)], [f"filtered_rate[{j}]" for j in (1, 2, 3)]
    elif kind == "sensor":
        ins, outs, cols_in, cols_out = [("true_rate", 1)], [("measured_rate", 1)], ["true_rate"], ["measured_rate"]
    else:
        ins, outs, cols_in, cols_out = [("raw_rate", 1)], [("filtered_rate", 1)], ["raw_rate"], ["filtered_rate"]
    rows = [" ".join(repr(float(inputs[c][k])) for c in cols_in) + f" {int(inputs['restart'][k])}"
            for k in range(len(inputs["time"]))]
    out, _ = host3_run(exe, unz, md, ins, "restart", outs, rows, init_sample=kind == "sensor")
    for j, col in enumerate(cols_out):
        assert np.array_equal(out[:, j], ref[col]), col
