"""The output guard of ``motion`` (kernels.motion_step, MO_GUARD_*): where the faded mean square of
the bank's residual z - y, in units of R, says the model is wrong, the output moves to the raw
sample. Known truth: seeded sharp rate steps on a quiet gyro (a navigation FOG: the fastest filter
rang after each step and every slower one restarted from it, 8.6x raw's RMSE on such a record
before the guard), and white noise at rest, where the guard must stay off."""

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.core import batch
from gyrodenoise.core import kernels as K


def _steps(seed, fs=184.0, sigma=1.6e-4, seconds=30.0):
    rng = np.random.default_rng(seed)
    n = int(seconds * fs)
    truth = np.zeros(n)
    for k in range(int(3 * fs), n, int(4 * fs)):      # a jump of 20-150 deg/s every 4 s
        truth[k:] += rng.choice([-1.0, 1.0]) * rng.uniform(20.0, 150.0)
    return truth, truth + sigma * rng.standard_normal(n), fs


def _rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


@pytest.mark.parametrize("seed", range(4))
def test_sharp_steps_on_a_quiet_gyro_never_worse_than_raw(seed):
    truth, raw, fs = _steps(seed)
    out = gd.denoise(raw, fs)
    assert _rmse(out, truth) <= 1.005 * _rmse(raw, truth)


def test_the_guard_is_what_keeps_the_steps(monkeypatch):
    """The same record through the plain-Python kernels with the guard off (its threshold out of
    reach): the ringing comes back (a test of this test: it can fail)."""
    truth, raw, fs = _steps(0, seconds=12.0)
    p = K.make_params(method="motion", sample_rate_hz=fs)
    on, _ = batch.run(p, K.init_state(p), raw, compiled=False)
    monkeypatch.setattr(K, "MO_GUARD_LO", 1e300)
    off, _ = batch.run(p, K.init_state(p), raw, compiled=False)
    assert _rmse(on, truth) <= 1.005 * _rmse(raw, truth) < 2.0 * _rmse(raw, truth) < _rmse(off, truth)


def test_guard_stays_off_on_white_noise_at_rest():
    rng = np.random.default_rng(7)
    fs, sigma = 500.0, 0.05
    raw = sigma * rng.standard_normal(int(20 * fs))
    p = K.make_params(method="motion", sample_rate_hz=fs)
    o = K.ext_offset(p)
    _, _, g = batch.run(p, K.init_state(p), raw, trace_index=o + K.M_GRD)
    assert float(np.max(g)) < K.MO_GUARD_LO       # never once on in 10,000 samples of white noise
