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


# --------------------------------------------------------------------------- PX4: how the logged streams are made

PX4_RATE = 400.0
PX4_PARAMS = {"IMU_GYRO_CUTOFF": 40.0, "IMU_GYRO_NF0_FRQ": 0.0, "IMU_GYRO_DNF_EN": 0}


class _PX4Log(_Log):
    def parameters(self):
        return LogParameters(PX4_AUTOPILOT, self._p)


class _NoProduction(type(PX4_AUTOPILOT)):
    """PX4 with the streams' making left out: sensor_combined taken as the gyro the filters run on."""

    def pre_filter_production(self, log, params, filters, pre_stream):
        return None


@pytest.fixture(scope="module")
def px4_flight():
    """The gyro at 400 Hz (noise and tones at 45, 70 and 95 Hz); sensor_combined the mean of
    each pair (gyro_integral_dt 5 ms) at 200 Hz; vehicle_angular_velocity that gyro through
    scipy's 2nd-order Butterworth at 40 Hz designed at 400 Hz (PX4's LowPassFilter2p), logged
    with every third sample dropped, as PX4's logger does."""
    rng = np.random.default_rng(11)
    t = np.arange(int(12.0 * PX4_RATE)) / PX4_RATE
    g = rng.normal(0.0, 1.0, (len(t), 3))
    for f, amp in ((45.0, 6.0), (70.0, 8.0), (95.0, 10.0)):
        g += amp * np.sin(2 * np.pi * f * t + rng.uniform(0, 6))[:, None] * np.array([1.0, 0.8, 0.5])
    b, a = signal.butter(2, 40.0, fs=PX4_RATE)
    post = np.stack([signal.lfilter(b, a, g[:, k]) for k in range(3)], 1)
    keep = np.arange(len(t)) % 3 != 2
    sc = 0.5 * (g[0::2] + g[1::2])
    ts = t[1::2]
    msgs = {"sensor_combined": {"time_s": ts, "gyro_integral_dt": np.full(len(ts), 5000)},
            "vehicle_imu_status": {"time_s": np.array([0.0, 6.0]), "gyro_rate_hz": np.array([400, 400])},
            "vehicle_angular_velocity": {"time_s": t[keep], **{f"xyz[{k}]": np.radians(post[keep, k])
                                                               for k in range(3)}}}
    pre = GyroStream(name="sensor_combined", message="sensor_combined", unit="rad/s", to_deg_s=math.degrees(1.0),
                     time_s=ts, raw=np.radians(sc), index=np.arange(len(ts)))
    return _PX4Log([pre], msgs, PX4_PARAMS)


def _px4_replay(log, params, autopilot=PX4_AUTOPILOT):
    filters = vf.vehicle_filters(autopilot, params)
    return nr.replay_review(log, autopilot, params, filters, log.gyro[0])


def test_px4_replay_models_how_sensor_combined_and_the_logged_gyro_are_made(px4_flight):
    """The filter run at the gyro's rate, sensor_combined's pair mean undone, the replay read at
    the logged post-filter gyro's own (dropped-sample) times: within 1.5 dB, and far closer
    than the unfiltered gyro."""
    rep, _ = _px4_replay(px4_flight, PX4_PARAMS)
    assert rep["production"]["averaged"] == 2 and rep["filter_rate_hz"] == pytest.approx(400.0, rel=0.01)
    assert rep["agreement"]["db_rms"]["all"] < 1.5, rep["agreement"]
    assert rep["unfiltered_db_rms"] > 5.0
    assert not rep.get("worse_than_unfiltered")


def test_px4_replay_without_the_streams_making_is_clearly_worse(px4_flight):
    """sensor_combined taken as the filters' input (the filter designed at 200 Hz): > 4 dB off."""
    rep, _ = _px4_replay(px4_flight, PX4_PARAMS, _NoProduction())
    assert rep["production"] is None
    assert rep["agreement"]["db_rms"]["all"] > 4.0, rep["agreement"]


def test_a_replay_worse_than_the_unfiltered_gyro_is_flagged(px4_flight):
    """A cutoff far too low: the replay further from the logged gyro than the unfiltered one --
    flagged, with a note, never published as an agreement without a word."""
    rep, _ = _px4_replay(px4_flight, {**PX4_PARAMS, "IMU_GYRO_CUTOFF": 8.0})
    assert rep["agreement"]["db_rms"]["all"] >= rep["unfiltered_db_rms"]
    assert rep["worse_than_unfiltered"] is True and "not an agreement" in rep["agreement_note"]
    assert "Not an agreement" in nr.replay_section_html({"notch_replay": rep})


def test_on_lattice_fills_dropped_samples_and_keeps_the_rate():
    """A 400 Hz tone series with every third sample dropped: back on its 400 Hz lattice, the
    filled samples within 5 % of the tone (a 10 Hz tone: linear interpolation error ~ (pi f / fs)**2 / 2)."""
    t = np.arange(4000) / 400.0
    x = np.sin(2 * np.pi * 10.0 * t)[:, None] * np.ones(3)
    keep = np.arange(4000) % 3 != 2
    s = nr.GyroSeries("s", t[keep], x[keep], nr.series_rate(t[keep]))
    xyz, rate, filled = nr.on_lattice(s)
    assert filled and rate == pytest.approx(400.0) and len(xyz) == 4000 - (4000 % 3 == 0)
    assert np.max(np.abs(xyz - x[:len(xyz)])) < 0.05


def test_lattice_found_when_most_steps_skip_samples():
    """250 Hz times with most steps 8 or 12 ms (one or two samples dropped) and 2 % at 4 ms (a
    held-out PX4 log's vehicle_angular_velocity): the lattice is 4 ms, not the commonest step."""
    rng = np.random.default_rng(3)
    skip = rng.choice([2, 3, 1], size=1000, p=[0.49, 0.49, 0.02])
    k = np.r_[0, np.cumsum(skip)]
    t = 5.0 + k * 0.004 + rng.normal(0.0, 1e-5, len(k))          # timestamp jitter 10 us
    lat = nr.lattice(t)
    assert lat is not None
    step, idx = lat
    assert step == pytest.approx(0.004, rel=1e-4)
    assert np.array_equal(idx, k)


def test_a_pre_filter_gyro_with_dropped_samples_is_replayed_on_its_lattice():
    """The filters' input logged at their rate (400 Hz) with every fourth sample dropped, the
    logged output with every third: the pre-filter gyro put back on its lattice before the chain
    runs -- within 1.5 dB; the chain run over the logged samples as if consecutive is not."""
    rng = np.random.default_rng(5)
    t = np.arange(int(12.0 * PX4_RATE)) / PX4_RATE
    g = rng.normal(0.0, 1.0, (len(t), 3))
    for f, amp in ((45.0, 6.0), (70.0, 8.0)):
        g += amp * np.sin(2 * np.pi * f * t)[:, None] * np.array([1.0, 0.8, 0.5])
    b, a = signal.butter(2, 40.0, fs=PX4_RATE)
    post = np.stack([signal.lfilter(b, a, g[:, k]) for k in range(3)], 1)
    keep_pre = np.arange(len(t)) % 4 != 3
    keep_post = np.arange(len(t)) % 3 != 2
    msgs = {"vehicle_angular_velocity": {"time_s": t[keep_post], **{f"xyz[{k}]": np.radians(post[keep_post, k])
                                                                     for k in range(3)}}}
    pre = GyroStream(name="sensor_combined", message="sensor_combined", unit="rad/s", to_deg_s=math.degrees(1.0),
                     time_s=t[keep_pre], raw=np.radians(g[keep_pre]), index=np.arange(int(keep_pre.sum())))
    rep, _ = _px4_replay(_PX4Log([pre], msgs, PX4_PARAMS), PX4_PARAMS, _NoProduction())
    assert rep["filter_rate_hz"] == pytest.approx(400.0, rel=0.01)
    assert any("dropped" in n for n in rep["notes"])
    assert rep["agreement"]["db_rms"]["all"] < 1.5, rep["agreement"]
