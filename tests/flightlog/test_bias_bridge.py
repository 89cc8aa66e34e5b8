"""Bias tracking through the bridge (docs/method/bias.md): ``gyrodenoise mavlink LOG --method motion
--bias-tracking 1`` hands the option to the denoiser (the filtered CSV is the Python API's with it
on, and the still gyro's bias is gone from it), the JSON says it was on, and without it the
report's filter_options are what they were before the option existed ({}). The live bridge builds
its Denoisers from the same options (gyrodenoise/flightlog/live.py)."""
from __future__ import annotations

import json

import numpy as np

from gyrodenoise import denoise
from gyrodenoise.core import kernels as K
from gyrodenoise.flightlog.live import _LiveStream
from tests.flightlog.synthetic_logs import DataFlashWriter
from tests.helpers import run_main

RATE_HZ = 200.0
BIAS_DEG_S = (0.1, -0.08, 0.06)


def _still_then_moving_log(path):
    """A SYNTHETIC ArduPilot DataFlash log: IMU gyro (rad/s) at 200 Hz, 30 s still with a bias
    of BIAS_DEG_S and 0.3 deg/s of white noise (a MEMS gyro: the bias within the
    noise's spread, so the output, bias removed, stays inside the raw envelope the bridge checks), then 10 s of a 0.5 Hz roll manoeuvre."""
    rng = np.random.default_rng(5)
    t = 1.0 + np.arange(int(40 * RATE_HZ)) / RATE_HZ
    gyr = np.array(BIAS_DEG_S) + 0.3 * rng.standard_normal((len(t), 3))
    moving = t >= 31.0
    gyr[moving, 0] += 40.0 * np.sin(2 * np.pi * 0.5 * (t[moving] - 31.0))
    w = DataFlashWriter()
    w.define("IMU", "QBffffff", ["TimeUS", "I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("MSG", "QZ", ["TimeUS", "Message"])
    w.add("MSG", 900_000, "ArduCopter V4.5.7 (0123abcd)")
    for tj, g in zip(t, np.radians(gyr)):
        w.add("IMU", int(round(tj * 1e6)), 0, *g, 0.0, 0.0, -9.8)
    path.write_bytes(w.bytes())
    return path


def _run(log, out, *extra):
    status, stdout, stderr = run_main("mavlink", log, "-o", out, "--method", "motion", "--no-plots", "--json", *extra)
    assert status == 0, stderr
    rep = json.loads(stdout)["logs"][0]
    return rep, np.genfromtxt(rep["streams"][0]["csv"], delimiter=",", names=True)


def test_mavlink_bias_tracking_reaches_the_denoiser_and_the_json(tmp_path):
    log = _still_then_moving_log(tmp_path / "still.BIN")
    rep, a = _run(log, tmp_path / "on", "--bias-tracking", "1")
    assert rep["filter_options"] == {"bias_tracking": 1, "bias_still_s": 1.0, "bias_memory_s": 60.0,
                                     "earth_rate_floor_deg_h": 15.0}
    off, b = _run(log, tmp_path / "off")
    assert off["filter_options"] == {}
    assert rep["form"] == "offline"
    fs = rep["streams"][0]["filter_rate_hz"]
    late = slice(int(25 * fs), int(30 * fs))           # still, long after tracking engaged
    for j, ax in enumerate("xyz"):
        # the CSV (9 significant digits) is the Python API's output with the option on (the
        # bridge's default form for a file: offline, the causal run's bias_hat taken off first)
        want = np.asarray(denoise(a[f"raw_{ax}"], fs, method="motion", bias_tracking=1, offline=True))
        assert np.allclose(a[f"filtered_{ax}"], want, rtol=1e-8, atol=1e-8), ax
        # the still gyro's bias is gone with the option (within 0.02 deg/s), kept without it
        assert abs(np.mean(a[f"filtered_{ax}"][late])) < 0.02, ax
        assert abs(np.mean(b[f"filtered_{ax}"][late]) - BIAS_DEG_S[j]) < 0.02, ax
    assert not rep["streams"][0]["not_filtered"]


def test_live_stream_builds_its_denoisers_with_the_option():
    """The live bridge: the filter options reach each axis's Denoiser (bias tracking on in its
    parameters) and its output is that Denoiser's, bias removed, while it stays in the raw range."""
    st = _LiveStream("IMU", "IMU", "deg/s", 1.0, "", 5.0, "<f8")
    rng = np.random.default_rng(2)
    for i in range(3):
        st.step(i / RATE_HZ, [0.5, 0.0, 0.0] + 0.05 * rng.standard_normal(3), RATE_HZ, "motion", 3,
                filter_kw={"bias_tracking": 1, "earth_rate_floor_deg_h": 0.0})
    assert [d.params[K.P_BIAS] for d in st.den] == [1.0, 1.0, 1.0]
    assert st.den[0].params[K.P_BIAS_FLOOR] == 0.0


def _quiet_biased_log(path, bias=0.5, noise=0.05):
    """A SYNTHETIC DataFlash log: a quiet gyro (``noise`` deg/s) with a large bias (``bias`` deg/s
    on every axis), 30 s still then 10 s of a 0.5 Hz roll manoeuvre on x. With the bias removed
    the still output sits near 0, below the raw samples' envelope (bias - ~4 noise at least)."""
    rng = np.random.default_rng(11)
    t = 1.0 + np.arange(int(40 * RATE_HZ)) / RATE_HZ
    gyr = bias + noise * rng.standard_normal((len(t), 3))
    moving = t >= 31.0
    gyr[moving, 0] += 40.0 * np.sin(2 * np.pi * 0.5 * (t[moving] - 31.0))
    w = DataFlashWriter()
    w.define("IMU", "QBffffff", ["TimeUS", "I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    w.define("MSG", "QZ", ["TimeUS", "Message"])
    w.add("MSG", 900_000, "ArduCopter V4.5.7 (0123abcd)")
    for tj, g in zip(t, np.radians(gyr)):
        w.add("IMU", int(round(tj * 1e6)), 0, *g, 0.0, 0.0, -9.8)
    path.write_bytes(w.bytes())
    return path


def test_a_bias_larger_than_the_noise_is_filtered_not_left_raw(tmp_path):
    """0.5 deg/s of bias in 0.05 deg/s of noise: the output (bias removed, near 0 while still)
    leaves the raw envelope by up to |bias_hat|, which is what bias tracking is for. The range
    check applies to what the filter clamps (the output plus the bias removed after each sample;
    offline, the output against the envelope of the samples less that bias), so the stream is
    written filtered, in both forms, and equals the Python API's output."""
    log = _quiet_biased_log(tmp_path / "quiet.BIN")
    for form, extra, offline in (("offline", (), True), ("causal", ("--causal",), False)):
        rep, a = _run(log, tmp_path / form, "--bias-tracking", "1", "--earth-rate-floor-deg-h", "0", *extra)
        st = rep["streams"][0]
        assert rep["form"] == form
        assert not st["left_raw"], st["left_raw"]
        fs = st["filter_rate_hz"]
        late = slice(int(25 * fs), int(30 * fs))
        for ax in "xyz":
            want = np.asarray(denoise(a[f"raw_{ax}"], fs, method="motion", bias_tracking=1,
                                      earth_rate_floor_deg_h=0.0, offline=offline))
            # the CSV's 9 significant digits, the filter run on them: within 1e-6 deg/s
            assert np.allclose(a[f"filtered_{ax}"], want, rtol=1e-7, atol=1e-6), (form, ax)
            assert abs(np.mean(a[f"filtered_{ax}"][late])) < 0.02, (form, ax)
            # below every raw sample of the still part: outside the raw envelope, by design
            assert np.max(a[f"filtered_{ax}"][late]) < np.min(a[f"raw_{ax}"][:late.stop]) - 0.2, (form, ax)


def test_the_range_check_still_refuses_what_the_shift_does_not_explain():
    """The invariant kept: the output must be inside the raw envelope shifted by the bias removed,
    nothing else. An output off by more than that is refused (file check and live check)."""
    from gyrodenoise.flightlog.checks import check_filtered
    from gyrodenoise.flightlog.streams import GyroStream
    n = 400
    rng = np.random.default_rng(3)
    x = 0.5 + 0.05 * rng.standard_normal((n, 3))
    s = GyroStream(name="IMU", message="IMU", unit="deg/s", to_deg_s=1.0, time_s=np.arange(n) / RATE_HZ,
                   raw=x.copy(), index=np.arange(n), note="", field_dtype="<f8")
    s.restarts = np.zeros(n, dtype=bool)
    s.filtered = x.copy()
    usable = np.ones_like(x, dtype=bool)
    bias = np.full((n, 3), 0.5)
    f = x - bias                                   # clamped value (here the raw sample) less the bias
    assert check_filtered(s, x, f, usable, causal=True, bias=bias) is None
    assert check_filtered(s, x, f, usable, causal=False, bias=bias) is None
    assert check_filtered(s, x, f, usable, causal=True) is not None      # no bias given: refused
    g = f.copy()
    g[200, 1] -= 0.6                               # beyond the shifted envelope
    for causal in (True, False):
        why = check_filtered(s, x, g, usable, causal=causal, bias=bias)
        assert why is not None and why.startswith("y: filtered value") and "sample 200" in why, why


def test_live_stream_checks_the_output_plus_the_bias_removed():
    """Live: the same quiet gyro with a large bias, sample by sample: the stream is never forwarded
    raw, and the forwarded output is the Denoiser's (bias removed) on every sample."""
    from gyrodenoise.denoiser import Denoiser
    st = _LiveStream("IMU", "IMU", "deg/s", 1.0, "", 5.0, "<f8")
    rng = np.random.default_rng(4)
    n = int(30 * RATE_HZ)
    z = 0.5 + 0.05 * rng.standard_normal((n, 3))
    kw = {"bias_tracking": 1, "earth_rate_floor_deg_h": 0.0}
    out = np.array([st.step(i / RATE_HZ, z[i], RATE_HZ, "motion", 3, filter_kw=kw) for i in range(n)])
    assert st.left_raw is None, st.left_raw
    ref = Denoiser(sample_rate_hz=RATE_HZ, method="motion", **kw)
    want = np.array([ref.step(v) for v in z[:, 0]])
    assert np.array_equal(out[:, 0], want)
    assert abs(np.mean(out[-int(2 * RATE_HZ):, 0])) < 0.02
    assert abs(st.den[0].bias_hat - 0.5) < 0.01


def test_fmu_engine_returns_the_bias_it_removed(fmu_build, tmp_path):
    """``--engine fmu``: the FMU's output bias_hat read after each step, equal to the native
    engine's, and the quiet gyro with a large bias is written filtered (the same check)."""
    import pytest

    from gyrodenoise.flightlog.engines import FmuEngine, NativeEngine
    out, r = fmu_build
    fmu = out / "FogDenoiser.fmu"
    if r.returncode != 0 or not fmu.is_file():
        pytest.skip("FogDenoiser.fmu cannot be built here")
    kw = {"bias_tracking": 1, "earth_rate_floor_deg_h": 0.0}
    rng = np.random.default_rng(6)
    x = 0.5 + 0.05 * rng.standard_normal(int(20 * RATE_HZ))
    eng = FmuEngine(method="motion", fmu_path=fmu, filter_kw=kw)
    try:
        got, gb = eng.filter_with_bias(x, None, RATE_HZ)
    finally:
        eng.close()
    want, wb = NativeEngine(method="motion", filter_kw=kw).filter_with_bias(x, None, RATE_HZ)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(gb, wb, rtol=1e-9, atol=1e-12)
    assert abs(wb[-1] - 0.5) < 0.01
    log = _quiet_biased_log(tmp_path / "quiet.BIN")
    rep, _ = _run(log, tmp_path / "fmu", "--bias-tracking", "1", "--earth-rate-floor-deg-h", "0",
                  "--engine", "fmu", "--fmu", str(fmu))
    assert rep["form"] == "causal" and not rep["streams"][0]["left_raw"]
