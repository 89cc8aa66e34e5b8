"""In-flight noise for the estimator, against SYNTHETIC truth: white gyro and
accelerometer noise of known densities in flight and at rest (with the vehicle's slow
motion on top in flight) recovered within stated tolerances; the EKF parameters in the
autopilot's names, units and documented ranges; the Kalibr imu.yaml."""
from __future__ import annotations

import math

import numpy as np
import pytest

from gyrodenoise.flightlog import inflight_noise as inf
from gyrodenoise.flightlog.autopilots import ARDUPILOT, BETAFLIGHT, PX4_AUTOPILOT
from gyrodenoise.flightlog.model import Segment
from gyrodenoise.flightlog.streams import AccelStream, GyroStream

FS = 400.0
GYRO_REST, GYRO_FLY = 0.001, 0.005           # rad/s/sqrt(Hz)
ACC_REST, ACC_FLY = 0.003, 0.03             # m/s/s/sqrt(Hz)
SEGMENTS = [Segment("ground", 0.0, 90.0), Segment("armed", 90.0, 95.0), Segment("flying", 95.0, 155.0)]


class _Log:
    def __init__(self, gyro, accel):
        self.gyro, self.accel, self.boots = gyro, accel, []


def _white(rng, density, n):
    return rng.normal(0.0, density * math.sqrt(FS), (n, 3))      # sigma = N sqrt(fs)


@pytest.fixture(scope="module")
def log():
    rng = np.random.default_rng(3)
    t = np.arange(int(160 * FS)) / FS
    fly = t >= 95.0
    g = np.where(fly[:, None], _white(rng, GYRO_FLY, len(t)), _white(rng, GYRO_REST, len(t)))
    g[fly, 0] += 0.8 * np.sin(2 * np.pi * 0.7 * t[fly])              # slow manoeuvres: rad/s, below 5 Hz
    a = np.where(fly[:, None], _white(rng, ACC_FLY, len(t)), _white(rng, ACC_REST, len(t)))
    a[:, 2] -= 9.81
    s = GyroStream(name="IMU", message="IMU", unit="rad/s", to_deg_s=math.degrees(1.0), time_s=t,
                   raw=g, index=np.arange(len(t)), stage="pre-filter")
    return _Log([s], [AccelStream("accel", "accel", t, a)])


def test_known_densities_recovered_flying_and_at_rest(log):
    rep, note = inf.inflight_noise(log, SEGMENTS, PX4_AUTOPILOT, {})
    assert note == ""
    g, a = rep["gyro"][0], rep["accel"][0]
    # Welch over 60-90 s, ~100 bins: a 5 % tolerance is many standard errors (about 0.5 %)
    assert g["flying"]["mean"] == pytest.approx(GYRO_FLY, rel=0.05)
    assert g["rest"]["mean"] == pytest.approx(GYRO_REST, rel=0.05)
    assert a["flying"]["mean"] == pytest.approx(ACC_FLY, rel=0.05)
    assert a["rest"]["mean"] == pytest.approx(ACC_REST, rel=0.05)
    assert g["ratio"] == pytest.approx(GYRO_FLY / GYRO_REST, rel=0.08)
    assert a["ratio"] == pytest.approx(ACC_FLY / ACC_REST, rel=0.08)


def test_bias_walk_of_white_noise_is_its_bound_at_a_tenth_of_the_rest(log):
    """White noise of density N gives sigma(tau) = N / sqrt(tau); the walk read there is
    N sqrt(3) / tau (tau = 9 s of the 90 s rest)."""
    rep, _ = inf.inflight_noise(log, SEGMENTS, PX4_AUTOPILOT, {})
    w = rep["gyro"][0]["bias_walk_rest"]
    assert w["tau_s"] == pytest.approx(9.0, rel=0.01)
    assert w["mean"] == pytest.approx(GYRO_REST * math.sqrt(3.0) / 9.0, rel=0.35)


@pytest.mark.parametrize("ap,gname,aname,dt", [(ARDUPILOT, "EK3_GYRO_P_NSE", "EK3_ACC_P_NSE", 0.012),
                                               (PX4_AUTOPILOT, "EKF2_GYR_NOISE", "EKF2_ACC_NOISE", 0.010)])
def test_ekf_parameters_in_the_autopilots_names_and_units(log, ap, gname, aname, dt):
    rep, _ = inf.inflight_noise(log, SEGMENTS, ap, {gname: 0.015})
    ekf = rep["ekf_parameters"]
    assert set(ekf) == {gname, aname}
    g = ekf[gname]
    assert g["unit"] == "rad/s" and g["range"] == [0.0001, 0.1] and g["logged"] == 0.015
    assert g["value"] == pytest.approx(rep["gyro"][0]["flying"]["mean"] / math.sqrt(dt), rel=1e-3)
    assert ekf[aname]["unit"] == "m/s/s"
    assert ekf[aname]["value"] == pytest.approx(ACC_FLY / math.sqrt(dt), rel=0.06)


def test_ekf_value_kept_in_the_documented_range():
    got = ARDUPILOT.ekf_noise_params(1.0, 1e-6, {})
    assert got["EK3_GYRO_P_NSE"]["value"] == 0.1 and got["EK3_GYRO_P_NSE"]["clamped"]
    assert got["EK3_ACC_P_NSE"]["value"] == 0.01 and got["EK3_ACC_P_NSE"]["clamped"]
    assert BETAFLIGHT.ekf_noise_params(0.01, 0.1, {}) == {}


def test_kalibr_yaml_for_flight(log):
    rep, _ = inf.inflight_noise(log, SEGMENTS, PX4_AUTOPILOT, {})
    text = inf.kalibr_yaml(rep["kalibr_flight"])
    vals = dict(line.split(": ", 1) for line in text.splitlines() if not line.startswith("#"))
    assert float(vals["gyroscope_noise_density"]) == pytest.approx(GYRO_FLY, rel=0.05)
    assert float(vals["accelerometer_noise_density"]) == pytest.approx(ACC_FLY, rel=0.05)
    assert float(vals["update_rate"]) == pytest.approx(FS)
    assert vals["rostopic"] == "/imu0"


def test_no_flying_segment_no_figures(log):
    rep, note = inf.inflight_noise(log, SEGMENTS[:1], PX4_AUTOPILOT, {})
    assert rep is None and "no flying segment" in note
