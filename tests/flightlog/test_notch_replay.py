"""The notch replayed sample by sample against the logged post-filter gyro: SYNTHETIC
truth. A pre-filter gyro holding a throttle-tracked motor tone, its post-filter twin
made by the true chain (an independent per-sample loop over the scalar biquads of
vehicle_filters and scipy's Butterworth), read through the ArduPilot strategy as a
batch sampler with pre- and post-filter data (INS_LOG_BAT_OPT 4)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from gyrodenoise.flightlog import notch_replay as nr
from gyrodenoise.flightlog import vehicle_filters as vf
from gyrodenoise.flightlog.autopilots import ARDUPILOT, PX4_AUTOPILOT
from gyrodenoise.flightlog.model import LogParameters
from gyrodenoise.flightlog.streams import GyroStream

FS = 2000.0
PARAMS = {"INS_HNTCH_ENABLE": 1, "INS_HNTCH_MODE": 1, "INS_HNTCH_FREQ": 97.0, "INS_HNTCH_BW": 25.0,
          "INS_HNTCH_ATT": 40.0, "INS_HNTCH_HMNCS": 1, "INS_HNTCH_REF": 0.32, "INS_HNTCH_FM_RAT": 0.75,
          "INS_GYRO_FILTER": 60.0, "INS_GYR_ID": 1, "INS_GYR2_ID": 2, "INS_LOG_BAT_OPT": 4, "INS_LOG_BAT_MASK": 1,
          "SCHED_LOOP_RATE": 400}


def _throttle(t):
    return 0.2 + 0.3 * np.clip((t - 1.0) / 8.0, 0.0, 1.0)          # 0.2 -> 0.5 over 8 s


def _true_post(pre, t, thr_t, thr, params):
    """The true chain, written apart from the module: per loop (5 samples at 2 kHz / 400 Hz)
    the centre FREQ x max(FM_RAT, sqrt(thr / REF)) slewed 5 %, the notch from the scalar
    ardupilot_notch_sos, Direct Form I; then scipy's 2nd-order Butterworth."""
    st = vf._ap_harmonic_notch(params, "INS_HNTCH_")
    a, q = vf.ardupilot_notch_a_q(st["centre_hz"], st["bandwidth_hz"], st["attenuation_db"])
    out = np.empty_like(pre)
    every = int(FS / params["SCHED_LOOP_RATE"])
    for ax in range(3):
        x1 = x2 = y1 = y2 = float(pre[0, ax])
        c = None
        for i in range(len(t)):
            if i % every == 0:
                want = vf.throttle_notch_centre_hz(st, float(np.interp(t[i], thr_t, thr)))
                c = want if c is None else min(max(want, c * 0.95), c / 0.95)
                b0, b1, b2, a1, a2 = vf.ardupilot_notch_sos(c, a, q, FS)
            x = float(pre[i, ax])
            y = b0 * x + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2
            x2, x1, y2, y1 = x1, x, y1, y
            out[i, ax] = y
    b, aa = signal.butter(2, params["INS_GYRO_FILTER"], fs=FS)
    zi = signal.lfilter_zi(b, aa)
    return np.stack([signal.lfilter(b, aa, out[:, k], zi=zi * out[0, k])[0] for k in range(3)], 1)


class _Log:
    """The little of a FlightLog the ArduPilot strategy reads for the replay."""

    def __init__(self, gyro, messages, params):
        self.gyro, self._m, self._p = gyro, messages, params

    def message_names(self):
        return sorted(self._m)

    def messages(self, name):
        return self._m.get(name)

    def parameters(self):
        return LogParameters(ARDUPILOT, self._p)


def _stream(name, t, xyz_deg_s):
    return GyroStream(name=name, message="ISBD", unit="rad/s", to_deg_s=math.degrees(1.0), time_s=t,
                      raw=np.radians(xyz_deg_s), index=np.arange(len(t)))


@pytest.fixture(scope="module")
def flight():
    rng = np.random.default_rng(7)
    t = np.arange(int(10.0 * FS)) / FS
    thr_t = np.arange(0.0, 10.0, 0.1)                                   # CTUN at 10 Hz
    thr = _throttle(thr_t)
    st = vf._ap_harmonic_notch(PARAMS, "INS_HNTCH_")
    f = np.array([vf.throttle_notch_centre_hz(st, x) for x in np.interp(t, thr_t, thr)])
    phase = 2 * np.pi * np.cumsum(f) / FS
    pre = rng.normal(0.0, 0.5, (len(t), 3)) + 20.0 * np.sin(phase)[:, None] * np.array([1.0, 0.7, 0.4])
    post = _true_post(pre, t, thr_t, thr, PARAMS)
    log = _Log([_stream("ISB.gyro[0]", t, pre), _stream("ISB.gyro[2]", t, post)],
               {"CTUN": {"time_s": thr_t, "ThO": thr}}, PARAMS)
    return log


def _replay(log, params):
    filters = vf.vehicle_filters(ARDUPILOT, params)
    return nr.replay_review(log, ARDUPILOT, params, filters, log.gyro[0])


def test_replay_of_a_throttle_tracked_tone_agrees_within_1_db(flight):
    rep, note = _replay(flight, PARAMS)
    assert note == ""
    assert rep["post"]["stream"] == "ISB.gyro[2]"                 # the post-filter batch of the same IMU
    assert rep["tracks"] == {"INS_HNTCH_*": "CTUN.ThO (throttle out)"}
    ag = rep["agreement"]
    assert ag["band_hz"][0] == 30.0 and ag["band_hz"][1] > 900
    assert ag["db_rms"]["all"] < 1.0, ag


@pytest.mark.parametrize("wrong", [{"INS_HNTCH_REF": 0.2}, {"INS_HNTCH_MODE": 0}, {"INS_GYRO_FILTER": 40.0}])
def test_a_wrong_parameter_agrees_clearly_worse(flight, wrong):
    rep, _ = _replay(flight, {**PARAMS, **wrong})
    assert rep["agreement"]["db_rms"]["all"] > 3.0, (wrong, rep["agreement"])


def test_a_notch_held_at_one_centre_misses_the_tracked_tone(flight):
    """One centre per log (the hover throttle's) is what the replay replaces: it agrees worse."""
    filters = vf.vehicle_filters(ARDUPILOT, PARAMS)
    pre = nr.GyroSeries.of_stream(flight.gyro[0])
    fixed = vf.replay_sections(filters["stages"], {}, pre.time_s, FS, 400.0)[0]
    one = nr.GyroSeries("one centre", pre.time_s, nr.run_biquads(pre.xyz, fixed), FS)
    ag, _ = nr.agreement(one, nr.GyroSeries.of_stream(flight.gyro[1]))
    assert ag["db_rms"]["all"] > 3.0


def test_run_biquads_with_fixed_coefficients_is_scipys_filter():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(3000, 3)) + 5.0
    sos = [vf.lowpass2p_sos(80.0, 1000.0), vf.ardupilot_notch_sos(120.0, 0.1, 2.0, 1000.0)]
    y = nr.run_biquads(x, vf.constant_sections(sos, len(x)))
    ref = np.asarray(sos)
    scipy_sos = np.c_[ref[:, :3], np.ones(len(ref)), ref[:, 3:]]
    zi = signal.sosfilt_zi(scipy_sos)
    want = np.stack([signal.sosfilt(scipy_sos, x[:, k], zi=zi * x[0, k])[0] for k in range(3)], 1)
    np.testing.assert_allclose(y, want, rtol=0, atol=1e-9)


def test_slewed_centre_moves_at_most_5_percent_an_update():
    c = vf.slewed_centres(np.r_[np.full(10, 100.0), np.full(200, 200.0)], 5)
    steps = c[5::5] / c[:-5:5]
    assert np.all(steps <= 1 / 0.95 + 1e-12) and c[-1] == 200.0 and c[14] == pytest.approx(100 / 0.95)


def test_no_figure_when_the_slower_stream_stops_below_30_hz():
    t = np.arange(2000) / 50.0
    a = nr.GyroSeries("a", t, np.random.default_rng(0).normal(size=(2000, 3)), 50.0)
    ag, why = nr.agreement(a, a)
    assert ag is None and "below the 30 Hz" in why


def test_px4_dynamic_notch_follows_each_esc():
    """PX4 IMU_GYRO_DNF_EN bit 0: a notch per ESC and harmonic at h x rpm / 60."""
    params = {"IMU_GYRO_DNF_EN": 1, "IMU_GYRO_DNF_HMC": 2, "IMU_GYRO_DNF_BW": 15.0, "IMU_GYRO_DNF_MIN": 25.0}
    filters = vf.vehicle_filters(PX4_AUTOPILOT, params)
    t = np.arange(100) / 1000.0
    track = nr.Track(np.array([0.0, 1.0]), np.array([[6000.0, 7200.0], [6000.0, 7200.0]]), "esc")
    coefs, notes = vf.replay_sections(filters["stages"], {"IMU_GYRO_DNF_*": track}, t, 1000.0, None, slew=False)
    assert coefs.shape == (100, 4, 5)
    for centre in (100.0, 120.0, 200.0, 240.0):                   # harmonic 1 (ESC 1, 2), harmonic 2
        want = vf.px4_notch_sos(centre, 15.0, 1000.0)
        assert any(np.allclose(c, want) for c in coefs[0]), centre
