"""Bias tracking (motion's option bias_tracking, docs/method/bias.md): known-truth synthetic
records, the Earth-rate floor, C == Python bit for bit, and off = unchanged."""

import math
from pathlib import Path

import numpy as np
import pytest

from gyrodenoise import Denoiser, denoise
from gyrodenoise.core import batch
from gyrodenoise.core import kernels as K

FS = 200.0
HAT = None


def _record(seed, bias, noise, walk=0.0, still_s=20.0, move_s=10.0, tail_s=20.0):
    """Still, a manoeuvre (a 0.5 Hz sine of 30 deg/s), still again; the gyro's bias a random walk
    of ``walk`` deg/s per sqrt(s) from ``bias``. Returns (measured, true rate, true bias)."""
    rng = np.random.default_rng(seed)
    n = int((still_s + move_s + tail_s) * FS)
    t = np.arange(n) / FS
    moving = (t >= still_s) & (t < still_s + move_s)
    true = np.where(moving, 30.0 * np.sin(2.0 * np.pi * 0.5 * (t - still_s)), 0.0)
    b = bias + np.cumsum(rng.standard_normal(n)) * walk / math.sqrt(FS)
    return true + b + noise * rng.standard_normal(n), true, b


def _hat_trace(p, z):
    _, _, hat = batch.run(p, K.init_state(p), z, trace_index=K.ext_offset(p) + K.M_BIAS + K.GB_HAT)
    return hat


def test_bias_hat_converges_on_a_mems_record_and_is_carried_through_motion():
    """A MEMS-like gyro (0.05 deg/s white noise: ARW 0.21 deg/sqrt(h), above the navigation-grade
    limit, so no floor) with a 0.5 deg/s bias and a slow random walk: bias_hat within 0.01 deg/s
    (about 3 block-mean standard deviations over the few blocks the bank calls still) of the true
    bias at the end of the first still part, unchanged through the manoeuvre, and the integrated
    angle error over the record below a tenth of raw's."""
    z, true, b = _record(1, 0.5, 0.05, walk=1e-4)
    p = K.make_params(method="motion", sample_rate_hz=FS, bias_tracking=1)
    hat = _hat_trace(p, z)
    k0, k1 = int(19.9 * FS), int(30.0 * FS)
    assert abs(hat[k0] - b[k0]) < 0.01
    assert np.all(hat[k0:k1] == hat[k0])               # not updated while moving
    assert abs(hat[-1] - b[-1]) < 0.01
    out, _ = batch.run(p, K.init_state(p), z)
    ang = abs(np.sum(out - true)) / FS
    raw = abs(np.sum(z - true)) / FS
    assert ang < 0.1 * raw, (ang, raw)


def test_off_changes_nothing():
    """bias_tracking=0 (default): the parameters and the outputs bit for bit those without it."""
    z, _, _ = _record(2, 0.3, 0.05, still_s=5.0, move_s=3.0, tail_s=2.0)
    p0 = K.make_params(method="motion", sample_rate_hz=FS)
    p1 = K.make_params(method="motion", sample_rate_hz=FS, bias_tracking=0, earth_rate_floor_deg_h=3.0)
    assert p0 == p1
    assert K.bias_hat(p0, K.init_state(p0)) == 0.0
    with pytest.raises(ValueError, match="bias_tracking applies to method 'motion' only"):
        K.make_params(method="kf", bias_tracking=1)


def test_earth_rate_below_the_floor_is_kept_on_a_navigation_grade_record():
    """A FOG-grade still record (white noise 0.002 deg/s at 200 Hz: ARW 0.0085 deg/sqrt(h), below
    the 0.05 limit) measuring Earth's rate on this axis, 10 deg/h, and a 0.02 deg/s (72 deg/h)
    bias: with the 15 deg/h floor nothing below it is removed (a bias of 10 deg/h: hat 0; of
    82 deg/h: hat 82 - 15 = 67 deg/h, within 1 deg/h); with the floor at 0 the whole estimate."""
    earth = 10.0 / 3600.0
    for bias, want in ((0.0, 0.0), (0.02, (0.02 + earth) - 15.0 / 3600.0)):
        z, _, _ = _record(3, bias + earth, 0.002, still_s=60.0, move_s=0.0, tail_s=0.0)
        p = K.make_params(method="motion", sample_rate_hz=FS, bias_tracking=1)
        hat = _hat_trace(p, z)[-1]
        assert abs(hat - want) * 3600.0 < 1.0, (bias, hat * 3600.0)
        if bias == 0.0:
            assert hat == 0.0
    p = K.make_params(method="motion", sample_rate_hz=FS, bias_tracking=1, earth_rate_floor_deg_h=0.0)
    z, _, _ = _record(3, earth, 0.002, still_s=60.0, move_s=0.0, tail_s=0.0)
    assert abs(_hat_trace(p, z)[-1] - earth) * 3600.0 < 1.0


def test_mems_record_gets_its_whole_bias_removed():
    """The floor is for navigation-grade records only: a MEMS-like record's 0.01 deg/s (36 deg/h)
    bias is removed whole (within 0.005 deg/s), not less 15 deg/h."""
    z, _, _ = _record(4, 0.01, 0.05, still_s=60.0, move_s=0.0, tail_s=0.0)
    p = K.make_params(method="motion", sample_rate_hz=FS, bias_tracking=1)
    assert abs(_hat_trace(p, z)[-1] - 0.01) < 0.005


@pytest.mark.parametrize("floor", [15.0, 0.0])
def test_c_equals_python_bit_for_bit_with_bias_tracking(floor):
    """The C core (batch and per-sample) and the plain-Python kernels: outputs and states equal
    bit for bit, with restarts (the estimate is kept by them) and a non-finite sample."""
    z, _, _ = _record(5, 0.4, 0.05, still_s=6.0, move_s=2.0, tail_s=4.0)
    z[700] = math.nan
    rs = np.zeros(z.size, dtype=bool)
    rs[1500] = True
    p = K.make_params(method="motion", sample_rate_hz=FS, bias_tracking=1, bias_still_s=0.5,
                      earth_rate_floor_deg_h=floor)
    s = K.init_state(p)
    ref = [K.step(p, s, float(v), bool(r)) for v, r in zip(z, rs)]
    out, st = batch.run(p, K.init_state(p), z, rs)
    np.testing.assert_array_equal(out, np.array(ref))
    np.testing.assert_array_equal(st, np.array(s))
    assert K.bias_hat(p, s) != 0.0
    d = Denoiser(sample_rate_hz=FS, bias_tracking=1, bias_still_s=0.5, earth_rate_floor_deg_h=floor)
    one = [d.step(v, r) for v, r in zip(z, rs)]
    np.testing.assert_array_equal(np.array(one), np.array(ref))
    assert d.bias_hat == K.bias_hat(p, s)


def test_offline_removes_the_causal_bias():
    """gd.denoise(offline=True, bias_tracking=1): the smoother on the samples less the causal
    run's bias; the integrated angle error over the still tail within 0.2 deg of 0."""
    z, true, _ = _record(6, 0.5, 0.05, still_s=10.0, move_s=5.0, tail_s=10.0)
    y = denoise(z, FS, offline=True, bias_tracking=1)
    k = int(15.5 * FS)
    assert abs(np.sum(y[k:] - true[k:]) / FS) < 0.2


PSINS = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "static" / "psins_lasergyro.imu"


@pytest.mark.skipif(not PSINS.is_file(), reason="real data absent: ../shared/data/static/psins_lasergyro.imu")
def test_real_navigation_grade_record_keeps_earth_rate():
    """PSINS's ring-laser gyro, quasi-static near 34.2 deg N (its mean |rate| is Earth's 15 deg/h):
    the first 5 minutes of each axis; bias tracking never removes the first 15 deg/h of what it
    estimates (|hat| <= max(0, |mean| - 15 deg/h) + 1 deg/h)."""
    rows = []
    with open(PSINS) as fh:
        for line in fh:
            if line.startswith("%") or not line.strip():
                continue
            rows.append(line.split())
    fs = 1000.0 / float(rows[1][4])
    data = np.array([[float(x) for x in r] for r in rows[3:3 + int(300 * fs)]])
    rate = data[:, :3] * (0.1 / 3600.0) * fs            # pulses of 0.1 arcsec per sample -> deg/s
    p = K.make_params(method="motion", sample_rate_hz=fs, bias_tracking=1)
    for k in range(3):
        zk = np.ascontiguousarray(rate[:, k])
        hat = _hat_trace(p, zk)[-1] * 3600.0
        mean = abs(zk.mean()) * 3600.0
        assert abs(hat) <= max(0.0, mean - 15.0) + 1.0, (k, hat, mean)
