"""An FMU state belongs to the model that made it: a native FMU refuses another model's in-memory
state with fmi2Error / fmi3Error and the reason (all our native FMUs share one FMI layer, so
before they took each other's states as theirs: a heap over-read of the other model's buffers
under valgrind)."""
import pytest

from tests.fmu.fmi import FMI_ERROR, Logger  # noqa: E402
from tests.fmu.fmi3 import Slave3, unzip_all  # noqa: E402

from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402

PAIRS = [("FogDenoiserNative", "SimulatedFogNative"), ("SimulatedFogNative", "FogDenoiserNative"),
         ("FogDenoiserNative3", "SimulatedFogNative3"), ("FogDenoiserImuNative3", "FogDenoiserNative3"),
         ("FogDenoiserNative3", "FogDenoiserImuNative3")]


@pytest.fixture(scope="module")
def fmus(native_build, tmp_path_factory):
    dest = tmp_path_factory.mktemp("tags")
    return unzip_all(native_build[0], ("FogDenoiserNative", "SimulatedFogNative", "FogDenoiserNative3",
                                       "SimulatedFogNative3", "FogDenoiserImuNative3"), dest)


def _initialised(entry, name):
    """(slave, log messages, what keeps the callbacks) of an FMU past ExitInitializationMode."""
    fmu, unz, md = entry
    if md.fmiVersion == "3.0":
        keep = Slave3(unz, md, instance=name)
        keep.s.enterInitializationMode(startTime=0.0)
        keep.s.exitInitializationMode()
        return keep.s, keep.log, keep
    keep = Logger()
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(unz), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName=name)
    s.instantiate(callbacks=keep.callbacks)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    return s, keep.messages, keep


@pytest.mark.parametrize("owner,other", PAIRS)
def test_a_state_of_another_model_is_refused(fmus, owner, other):
    a, _, keep_a = _initialised(fmus[owner], "owner")
    b, log_b, keep_b = _initialised(fmus[other], "other")
    state, own = a.getFMUState(), b.getFMUState()
    with pytest.raises(FMICallException) as exc:
        b.setFMUState(state)
    assert exc.value.status == FMI_ERROR
    assert "not a state of this FMU" in log_b[-1][2]
    b.setFMUState(own)                                  # its own state, saved before, brings it back
    b.doStep(0.0, 0.005)
    a.freeFMUState(state)
    b.freeFMUState(own)
    for s in (a, b):
        s.freeInstance()
