"""Dropouts (non-finite gyro samples) in the bridge, file mode and live mode: fed to the
filter and healed as the library heals them, so every output sample is ``gd.denoise``'s on
the same samples (NaN payloads and infinities included), counted in ``dropouts_healed``.

The library's healing (gyrodenoise.core: ``step``): a non-finite sample leaves the filter
state non-finite, so the filter restarts at that sample (as if the gyro restarted there),
passes the sample through (the output there is the raw NaN/inf: a dropout stays a dropout in
the filtered log) and warms up again from the next sample. One exception, the library's too:
with the outlier gate of the AR methods (kf, shakf, ...; converged filter) a +-inf sample is
rejected as an outlier before it reaches the filter, and the output there is the held
prediction (a NaN passes the gate and is healed).

SYNTHETIC stream: a 100 Hz HIGHRES_IMU-like float stream in rad/s with NaN, +inf and -inf
samples, a run of NaN, and a NaN on a restart sample (a 1 s gap).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.flightlog.engines import NativeEngine
from gyrodenoise.flightlog.filtering import filter_streams
from gyrodenoise.flightlog.report import stream_report
from gyrodenoise.flightlog.streams import GyroStream

R2D = 180.0 / math.pi
FS = 100.0
N = 900
#: (sample, axis, value) of each dropout
DROPOUTS = [(250, 0, math.nan), (251, 0, math.nan), (252, 0, math.nan), (400, 1, math.inf),
            (500, 2, -math.inf), (600, 0, math.nan), (700, 1, math.nan)]


def record():
    """(time_s, raw rad/s (N, 3) float32 values) with the DROPOUTS; a 1 s gap (a restart)
    before sample 600, on which x drops out."""
    rng = np.random.default_rng(17)
    t = np.arange(N) / FS + 5.0
    t[600:] += 1.0
    g = 0.3 * np.sin(2 * np.pi * 0.4 * t)[:, None] + rng.normal(0.0, 0.01, (N, 3))
    for i, k, v in DROPOUTS:
        g[i, k] = v
    return t, g.astype(np.float32).astype(np.float64)


def stream():
    t, g = record()
    return GyroStream(name="HIGHRES_IMU", message="HIGHRES_IMU", unit="rad/s", to_deg_s=R2D, time_s=t,
                      raw=g, index=np.arange(N))


def expected_restarts():
    r = np.zeros(N, dtype=bool)
    r[600] = True
    return r


def bits(a):
    return np.asarray(a, dtype=np.float64).view(np.uint64)


ENGINES = [("motion", {}), ("shakf", {}), ("lowpass", {}), ("motion", {"offline": True}),
           ("lowpass", {"zero_phase": True})]


@pytest.mark.parametrize("method,form", ENGINES, ids=[f"{m}-{'-'.join(f) or 'causal'}" for m, f in ENGINES])
def test_file_mode_dropouts_equal_gd_denoise(method, form):
    s = stream()
    filter_streams([s], NativeEngine(method=method, **form), gap_factor=5.0)
    assert np.array_equal(s.restarts, expected_restarts())
    assert s.left_raw is None and s.not_filtered is None
    x, _, _, rate = s._work               # the rate the bridge measured (100 Hz to 2e-14)
    for k in range(3):
        ref = gd.denoise(x[:, k], rate, method=method, restarts=s.restarts, **form)
        assert np.array_equal(bits(s._work[1][:, k]), bits(ref)), (k, method, form)
    for i, k, v in DROPOUTS:
        if method == "shakf" and math.isinf(v):
            # the AR methods' outlier gate (converged filter) rejects +-inf before it reaches
            # the filter: the library's output there is the held prediction
            assert np.isfinite(s.filtered[i, k]), (i, k)
        else:                                    # healed: the dropout is passed through as it came
            assert bits(s.filtered[i, k]) == bits(s.raw[i, k]), (i, k)
    assert s.dropouts_healed == [4, 2, 1] and s.non_finite == [4, 2, 1]
    rep = stream_report(s)
    assert rep["dropouts_healed"] == len(DROPOUTS)
    assert rep["non_finite_samples"] == {"x": 4, "y": 2, "z": 1}


def test_file_mode_filter_restarts_at_a_dropout():
    """After a dropout the filter warms up again (1 s of raw output for motion), as the
    library does: the output is not the one of a filter that skipped the sample."""
    s = stream()
    filter_streams([s], NativeEngine(method="motion"), gap_factor=5.0)
    f, x = s._work[1][:, 1], s._work[0][:, 1]
    assert np.array_equal(f[401:401 + 99], x[401:401 + 99])            # warm-up after the inf at 400
    assert np.any(f[200:399] != x[200:399])                          # filtered before it


def test_live_mode_dropouts_equal_gd_denoise():
    """The live link's stream, sample by sample (Denoiser.step per axis): what it forwards
    is gd.denoise's output on the same samples and restarts, the dropouts forwarded as
    they came."""
    from gyrodenoise.flightlog.live import _LiveStream
    t, g = record()
    st = _LiveStream("HIGHRES_IMU@1.1", "HIGHRES_IMU", "rad/s", R2D, "", 5.0, "<f4")
    sent = np.array([st.step(ti, list(gi), FS, "motion", 3) for ti, gi in zip(t, g)])
    s = st.as_stream()
    assert np.array_equal(s.restarts, expected_restarts()) and s.left_raw is None
    for k in range(3):
        ref = gd.denoise(g[:, k] * R2D, FS, method="motion", restarts=s.restarts)
        want = np.where(bits(ref) == bits(g[:, k] * R2D), g[:, k], ref / R2D)   # passed through: raw
        assert np.array_equal(bits(sent[:, k]), bits(want)), k
    for i, k, v in DROPOUTS:
        assert bits(sent[i, k]) == bits(g[i, k])
    assert s.dropouts_healed == [4, 2, 1]
    assert stream_report(s)["dropouts_healed"] == len(DROPOUTS)
