"""A non-finite raw_rate (a sensor dropout) in both denoiser FMUs: the sample is healed the
way the library heals it, the step answers with a warning and the reason logged, and the
run goes on.

The reference is the library itself on the same input sequence (NaN, +inf, -inf and a run of
NaN in a seeded record, a restart among them): ``gd.denoise`` (the batch path) and
``Denoiser.step`` (the per-sample path), compared bit for bit (NaN payloads included) with
what FogDenoiserNative.fmu and FogDenoiser.fmu (pythonfmu) return through fmpy's FMU2Slave.

FogDenoiserNative answers such a step with fmi2Warning. pythonfmu 0.7.0's fmi2DoStep can
only return fmi2OK, fmi2Discard or fmi2Fatal (``do_step`` returns a bool): FogDenoiser
answers fmi2OK and logs the reason with status fmi2Warning.
"""
import math
import re
import zipfile

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.denoiser import Denoiser

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402

from tests.fmu.fmi import FMI_WARNING, Logger  # noqa: E402

FS = 200.0
H = 1.0 / FS
N = 1400
FMI_OK = 0

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def dropout_record(seed=29):
    """A seeded gyro record (a manoeuvre, white noise) with dropouts of every kind."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) / FS
    z = 0.4 + 2.0 * np.sin(2 * np.pi * 0.5 * t) * (t > 2.0) + 0.03 * rng.standard_normal(N)
    z[300] = math.nan              # after the warm-up: the filter has converged
    z[520] = math.inf
    z[700] = -math.inf
    z[900:906] = math.nan          # a run of dropouts
    z[1100] = math.nan             # a dropout on the restart sample
    rs = np.zeros(N, dtype=bool)
    rs[1100] = True
    return z, rs


DROPOUTS = (300, 520, 700, 900, 901, 902, 903, 904, 905, 1100)


def bits(a):
    return np.asarray(a, dtype=np.float64).view(np.uint64)


def library(z, rs, method):
    """gd.denoise and Denoiser.step on the same sequence, which must agree bit for bit."""
    batch = gd.denoise(z, FS, method=method, restarts=rs)
    d = Denoiser(sample_rate_hz=FS, method=method)
    per_sample = np.array([d.step(v, restart=bool(r)) for v, r in zip(z, rs)])
    assert np.array_equal(bits(batch), bits(per_sample))
    return batch


# ----------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def native_fmu(native_build, tmp_path_factory):
    fmu = native_build[0] / "FogDenoiserNative.fmu"
    unz = tmp_path_factory.mktemp("dropouts_native") / "unzipped"
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(unz)
    return fmu, unz


@pytest.fixture(scope="module")
def python_fmu(fmu_build, tmp_path_factory):
    out, proc = fmu_build
    if proc.returncode != 0:
        pytest.skip(f"gyrodenoise fmu build failed: {proc.stderr[-500:]}")
    fmu = out / "FogDenoiser.fmu"
    unz = tmp_path_factory.mktemp("dropouts_python") / "unzipped"
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(unz)
    return fmu, unz


def start(built, logger, method):
    fmu, unz = built
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(unz), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="dropouts")
    s.instantiate(callbacks=logger.callbacks, loggingOn=True)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setReal([vr["sample_period"]], [H])
    s.setString([vr["method"]], [method])
    s.exitInitializationMode()
    return s, vr


def run(s, vr, z, rs):
    """The FMU over the record; (outputs, the status of each fmi2DoStep)."""
    out, status = np.empty(len(z)), np.empty(len(z), dtype=int)
    for i in range(len(z)):
        s.setReal([vr["raw_rate"]], [float(z[i])])
        s.setBoolean([vr["restart"]], [bool(rs[i])])
        status[i] = s.fmi2DoStep(s.component, i * H, H, 1)
        out[i] = s.getReal([vr["filtered_rate"]])[0]
    return out, status


def check(built, method, step_status_at_dropout):
    z, rs = dropout_record()
    ref = library(z, rs, method)
    log = Logger()
    s, vr = start(built, log, method)
    try:
        out, status = run(s, vr, z, rs)
    finally:
        s.freeInstance()
    drop = np.zeros(N, dtype=bool)
    drop[list(DROPOUTS)] = True
    assert set(np.flatnonzero(~np.isfinite(z))) == set(DROPOUTS)
    # the run goes on: every step answered, dropouts with the warning status
    assert list(np.flatnonzero(status != FMI_OK)) == (list(DROPOUTS) if step_status_at_dropout else [])
    assert np.all(status[drop] == (FMI_WARNING if step_status_at_dropout else FMI_OK))
    # each dropout's reason logged with status fmi2Warning, naming the value and the time
    warnings = [m for st, _, m in log.messages if st == FMI_WARNING and "raw_rate" in m]
    assert len(warnings) == len(DROPOUTS), warnings
    for k, msg in zip(DROPOUTS, warnings):
        assert f"raw_rate is {float(z[k])!r} at t=" in msg and "dropout" in msg, msg
        assert float(re.search(r" at t=(\S+) s", msg).group(1)) == k * H, msg
    assert not [m for st, _, m in log.messages if st > FMI_WARNING]
    # the outputs are the library's, bit for bit; the finite samples after each dropout are filtered
    assert np.array_equal(bits(out), bits(ref))
    assert np.all(np.isfinite(out[~drop]))
    return z, out


@pytest.mark.parametrize("method", ["motion", "shakf", "lowpass"])
def test_native_fmu_heals_dropouts_as_the_library(native_fmu, method):
    z, out = check(native_fmu, method, step_status_at_dropout=True)
    # filtered again once the restarted filter has warmed up (1 s, 200 samples, for motion and
    # the AR methods; 1 sample for lowpass): the output is no longer the raw sample
    assert np.any(out[505:519] != z[505:519])


@pytest.mark.slow
@pytest.mark.parametrize("method", ["motion", "shakf"])
def test_python_fmu_heals_dropouts_as_the_library(python_fmu, method):
    z, out = check(python_fmu, method, step_status_at_dropout=False)
    assert np.any(out[505:519] != z[505:519])


def test_native_fmu_state_saved_at_a_dropout_replays_it(native_fmu):
    """A state saved just before a dropout replays the same healed outputs (nothing of the
    dropout is kept outside the state)."""
    z, rs = dropout_record()
    ref = library(z, rs, "motion")
    log = Logger()
    s, vr = start(native_fmu, log, "motion")
    try:
        run(s, vr, z[:300], rs[:300])
        st = s.getFMUstate()
        first = np.array([_step(s, vr, z[k], rs[k], k) for k in range(300, 320)])
        s.setFMUstate(st)
        again = np.array([_step(s, vr, z[k], rs[k], k) for k in range(300, 320)])
        s.freeFMUstate(st)
    finally:
        s.terminate()
        s.freeInstance()
    assert np.array_equal(bits(first), bits(ref[300:320]))
    assert np.array_equal(bits(again), bits(first))


def _step(s, vr, z, r, k):
    s.setReal([vr["raw_rate"]], [float(z)])
    s.setBoolean([vr["restart"]], [bool(r)])
    s.fmi2DoStep(s.component, k * H, H, 1)
    return s.getReal([vr["filtered_rate"]])[0]
