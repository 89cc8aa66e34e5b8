"""The denoisers' invariant on every shared real log: for the default method and
the paper's filters, through the bridge's readers, the output of every stream
axis is finite and inside the raw range of each session (restart to restart).
Skips with a reason without ../shared/data (licences forbid copying the logs)."""

import numpy as np
import pytest

from gyrodenoise.core import kernels as K
from gyrodenoise.core.batch import run
from tests.helpers import SHARED_DATA

pytestmark = pytest.mark.slow          # every shared real log through the bridge's readers

LOGS = SHARED_DATA / "logs"
FILES = sorted(LOGS.glob("*")) if LOGS.is_dir() else []


def read_streams(path):
    from gyrodenoise.flightlog import dataflash, tlog, ulog
    from gyrodenoise.errors import InputError
    try:
        if path.suffix.lower() == ".bin":
            return dataflash.read(path)[2]
        if path.suffix == ".ulg":
            return ulog.read(path)[1]
        return tlog.read(path)[2]
    except InputError:
        return []               # e.g. plane_no_imu.bin: nothing to filter


def session_range(z, restarts):
    lo = np.empty_like(z)
    hi = np.empty_like(z)
    a = b = z[0]
    for i, v in enumerate(z.tolist()):
        if restarts[i] or i == 0:
            a = b = v
        a = v if v < a else a
        b = v if v > b else b
        lo[i], hi[i] = a, b
    return lo, hi


@pytest.mark.skipif(not FILES, reason="../shared/data/logs absent (third-party logs are not in the repository)")
@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_every_shared_log_stays_finite_and_inside_its_range(path):
    from gyrodenoise.flightlog.streams import detect_restarts
    for st in read_streams(path):
        detect_restarts(st)
        x, _, _ = st.work_units()
        fs = st.rate_hz or 1.0
        for k in range(x.shape[1]):
            usable = np.isfinite(x[:, k]) & (np.abs(x[:, k]) < 1e6)     # as the bridge feeds the filter
            z = np.ascontiguousarray(x[usable, k])
            rs = st.restarts[usable]
            if z.size == 0:
                continue
            lo, hi = session_range(z, rs)
            for method in ("motion", "kf", "shakf"):
                p = K.make_params(method=method, sample_rate_hz=fs)
                out, s = run(p, K.init_state(p), z, rs)
                assert np.all(np.isfinite(out)), (st.name, k, method)
                bad = np.flatnonzero((out < lo) | (out > hi))
                assert bad.size == 0, (st.name, k, method, bad[:3])
                assert s[K.S_NHEAL] == 0, (st.name, k, method)
