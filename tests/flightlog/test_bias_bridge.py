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
