"""The filter review (gyrodenoise.flightlog.filter_review): on a SYNTHETIC pre-filter
batch-sampler stream with a known tone in white noise and known parameters, the tone
is found within one PSD bin, the notch is recommended on it with half its centre as
bandwidth, and the predicted post-filter spectrum is the pre-filter one times the
computed |H|^2 of the recommended parameters; the note when there is no pre-filter
stream; real logs give a review (batch sampler, PX4 estimator IMU) or a clear note."""
from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest

from gyrodenoise.flightlog import filter_review as fr
from gyrodenoise.flightlog import formats, parameters
from gyrodenoise.flightlog import vehicle_filters as vf
from gyrodenoise.flightlog.autopilots import UNKNOWN, named
from gyrodenoise.flightlog.streams import RAD_TO_DEG, GyroStream

from tests.helpers import shared_log

FS = 2000.0
TONE_HZ = 123.4
PARAMS = {"INS_GYRO_FILTER": 40.0, "INS_HNTCH_ENABLE": 0.0, "INS_LOG_BAT_MASK": 1.0, "INS_LOG_BAT_OPT": 0.0,
          "INS_GYR_ID": 1.0, "INS_GYR2_ID": 0.0, "INS_GYR3_ID": 0.0, "MOT_THST_HOVER": 0.3}


def _batch_stream(seed=1, n_bursts=24, burst=1024, tone_deg_s=3.0, noise_deg_s=0.3, tone_hz=TONE_HZ):
    """SYNTHETIC batch-sampler gyro: bursts of ``burst`` samples at FS, 3 s apart, a tone
    at TONE_HZ on x and y plus white noise on all axes (rad/s, as ISBD is read)."""
    rng = np.random.default_rng(seed)
    t = np.concatenate([3.0 * k + np.arange(burst) / FS for k in range(n_bursts)])
    x = rng.normal(0.0, noise_deg_s, (len(t), 3))
    x[:, 0] += tone_deg_s * np.sin(2 * np.pi * tone_hz * t)
    x[:, 1] += 0.5 * tone_deg_s * np.sin(2 * np.pi * tone_hz * t + 1.0)
    return GyroStream(name="ISB.gyro[0]", message="ISBD", unit="rad/s", to_deg_s=RAD_TO_DEG, time_s=t,
                      raw=x / RAD_TO_DEG, index=np.arange(len(t)))


def _imu_stream():
    t = np.arange(500) / 25.0
    return GyroStream(name="IMU[0]", message="IMU", unit="rad/s", to_deg_s=RAD_TO_DEG, time_s=t,
                      raw=np.zeros((500, 3)), index=np.arange(500))


def _review_and_plot(streams, params=PARAMS, **kw):
    filters = vf.vehicle_filters(named("ardupilot"), params)
    return fr.filter_review(streams, named("ardupilot"), params, filters, **kw)


def _review(streams, params=PARAMS, **kw):
    return _review_and_plot(streams, params, **kw)[:2]


def test_synthetic_tone_found_notched_and_predicted():
    review, note, plot = _review_and_plot([_imu_stream(), _batch_stream()])
    assert note == "" and review["source"]["stream"] == "ISB.gyro[0]"
    df = review["source"]["resolution_hz"]
    assert review["filter_rate_hz"] == pytest.approx(FS)
    assert abs(review["peaks"][0]["freq_hz"] - TONE_HZ) <= df
    rec = review["recommended"]
    assert abs(rec["INS_HNTCH_FREQ"] - TONE_HZ) <= df
    assert rec["INS_HNTCH_BW"] == pytest.approx(rec["INS_HNTCH_FREQ"] / 2, abs=0.05)
    assert rec["INS_HNTCH_ENABLE"] == 1 and rec["INS_HNTCH_MODE"] == 1 and rec["INS_HNTCH_REF"] == 0.3
    assert rec["INS_HNTCH_HMNCS"] == 1 and rec["INS_HNTCH_ATT"] == 40.0
    assert f"INS_HNTCH_FREQ,{rec['INS_HNTCH_FREQ']:g}" in review["param_lines"]
    # the predicted spectrum is |H|^2 of the recommended parameters, as the vehicle would run them
    fs = review["filter_rate_hz"]
    h = vf.chain_response(vf.vehicle_filters(named("ardupilot"), {**PARAMS, **rec})["stages"], plot.freq_hz, fs)
    np.testing.assert_allclose(plot.psd_recommended, plot.psd_pre * np.abs(h) ** 2, rtol=1e-9)
    k = int(np.argmin(np.abs(plot.freq_hz - TONE_HZ)))
    assert plot.psd_recommended[0, k] / plot.psd_pre[0, k] == pytest.approx(abs(h[k]) ** 2, rel=1e-9)
    assert 10 * math.log10(abs(h[k]) ** 2) < -30        # the tone is notched
    # ... and the logged chain's the logged low-pass
    h_log = vf.chain_response(vf.vehicle_filters(named("ardupilot"), PARAMS)["stages"], plot.freq_hz, fs)
    np.testing.assert_allclose(plot.psd_logged, plot.psd_pre * np.abs(h_log) ** 2, rtol=1e-9)
    # figures: noise no worse than logged, and less lag (the reason the notch is there)
    figs = review["figures"]
    assert figs["recommended"]["noise_rms_deg_s"]["rss"] <= figs["logged"]["noise_rms_deg_s"]["rss"] * (1 + 1e-9)
    assert figs["recommended"]["phase_lag_ms"]["20"] < figs["logged"]["phase_lag_ms"]["20"]
    assert rec["INS_GYRO_FILTER"] > 40
    assert set(figs["logged"]["phase_lag_ms"]) == {"10", "20", "30"}
    json.dumps(review)                                                   # JSON-able, its plot apart


def test_flying_mask_and_its_fallback():
    s = _batch_stream()
    review, _ = _review([s], flying_mask_fn=lambda t, records=None: t >= 30.0)
    assert review["source"]["over"] == "flying"
    review, _ = _review([s], flying_mask_fn=lambda t, records=None: np.zeros(len(t), dtype=bool))
    assert review["source"]["over"] == "whole log"


def test_no_peak_no_notch():
    review, _ = _review([_batch_stream(tone_deg_s=0.0)])
    assert not any(k.startswith("INS_HNTCH") for k in review["recommended"])
    assert review["why"][0].startswith("no vibration peak")


def test_no_pre_filter_stream_note():
    review, note = _review([_imu_stream()], params={**PARAMS, "INS_LOG_BAT_MASK": 0.0})
    assert review is None
    assert note == ("no pre-filter gyro stream: IMU[0] is logged after the vehicle's filters at 25 Hz, "
                    "and the batch sampler is off (INS_LOG_BAT_MASK 0)")
    review, note, _ = fr.filter_review([_imu_stream()], UNKNOWN, {}, vf.vehicle_filters(UNKNOWN, {}))
    assert review is None and "autopilot is unknown" in note


def test_param_lines():
    assert fr.param_lines(named("ardupilot"), {"INS_GYRO_FILTER": 37, "INS_HNTCH_BW": 37.6}) == \
        ["INS_GYRO_FILTER,37", "INS_HNTCH_BW,37.6"]
    assert fr.param_lines(named("px4"), {"IMU_GYRO_CUTOFF": 44.0}) == ["param set IMU_GYRO_CUTOFF 44"]


@functools.lru_cache(maxsize=8)
def _real(name):
    log = formats.read_log(shared_log(name))
    ap, params = parameters.log_parameters(log)
    filters = vf.vehicle_filters(ap, params)
    ctx = fr.review_context(log, ap, params, filters)
    return fr.filter_review(log.gyro, ap, params, filters, context=ctx)[:2], filters


def test_copter_00061_review_from_its_batch_sampler():
    (review, note), _ = _real("copter_00061-2021-11-21_18-03-38.bin")
    assert note == "" and review["source"]["stream"] == "ISB.gyro[0]"
    assert review["source"]["sample_rate_hz"] == pytest.approx(2000, rel=0.01)
    assert review["logged"]["INS_GYRO_FILTER"] == 30.0
    assert "INS_GYRO_FILTER" in review["recommended"]
    json.dumps(review)


def test_copter462_review_sees_the_logged_throttle_notch():
    """The logged harmonic notch (INS_HNTCH_ENABLE 1) shows in ``logged`` and the logged
    chain, is kept in the recommended chain and said so; no line for an unchanged value
    (INS_GYRO_FILTER 42 logged). (The bridge gives this fragment no review: never armed.)"""
    (review, note), filters = _real("copter462_notch_fragment.bin")
    assert note == "" and review["source"]["stage"] == "pre-filter"
    # not flying, throttle out 0: the throttle notch sits at FREQ x FM_RAT
    assert any("centre 72.8 Hz" in n for n in review["notes"])
    assert review["logged"]["INS_HNTCH_ENABLE"] == 1.0 and review["logged"]["INS_HNTCH_FREQ"] == 97.0
    assert any(s["kind"] == "harmonic_notch" for s in review["logged_stages"])
    assert any(s["kind"] == "harmonic_notch" for s in review["recommended_stages"])
    assert any(w.startswith("INS_HNTCH_* (harmonic_notch 97 Hz") and "kept as logged" in w for w in review["why"])
    assert "INS_GYRO_FILTER,42" not in review["param_lines"]
    assert all(not fr._same(review["logged"].get(k), v) for k, v in review["changes"].items())


@pytest.mark.parametrize("name", ["px4_quad_battery_brownout.ulg", "px4_quad_ekf_failure.ulg",
                                  "px4_quad_gps_interference.ulg"])
def test_px4_quads_no_static_notch_from_the_averaged_stream(name):
    """sensor_combined is averaged (aliased): no static notch from its peaks whatever
    their prominence (battery_brownout: 19 dB at 50.6 Hz), no low-pass cutoff above
    0.4 x its rate, no line for an unchanged value."""
    (review, note), filters = _real(name)
    assert filters["parameters"]["IMU_GYRO_CUTOFF"] == 40.0
    assert review["source"]["stream"] == "sensor_combined" and review["source"]["averaged"]
    assert any("sensor_combined is the estimator's IMU" in n for n in review["notes"])
    assert not any(k.startswith("IMU_GYRO_NF") for k in review["recommended"])
    assert all(not p["notch_ok"] for p in review["peaks"])
    assert review["recommended"]["IMU_GYRO_CUTOFF"] <= 0.4 * review["source"]["sample_rate_hz"]
    assert "param set IMU_GYRO_CUTOFF 40" not in review["param_lines"]


def test_px4_battery_brownout_onboard_fft_enables_the_dynamic_notch():
    """sensor_gyro_fft (on the 1995 Hz raw gyro) puts the motor peaks at 113-136 Hz,
    IMU_GYRO_FFT_EN 1 and IMU_GYRO_DNF_EN 0: the advice is IMU_GYRO_DNF_EN bit 1 (2);
    the filter rate is the FFT's sensor_sample_rate_hz, not an assumed 8 kHz."""
    (review, _), _ = _real("px4_quad_battery_brownout.ulg")
    assert review["filter_rate_hz"] == pytest.approx(1995, abs=2)
    assert "sensor_gyro_fft" in review["filter_rate_source"]
    assert 113 <= review["onboard_fft"]["peaks_hz"]["median"] <= 136
    assert review["changes"] == {"IMU_GYRO_DNF_EN": 2}
    assert review["param_lines"] == ["param set IMU_GYRO_DNF_EN 2"]


def test_notch_rules_fold_and_prominence():
    """SYNTHETIC batch sampler at 2 kHz: a tone above 0.4 x the rate (850 Hz) may be
    folded, and a tone 2-3 dB above the floor is too weak: neither gets a notch."""
    high, _ = _review([_batch_stream(tone_hz=850.0)])
    assert "INS_HNTCH_FREQ" not in high["recommended"]
    assert any("may be folded" in p.get("why_not", "") for p in high["peaks"])
    weak, _ = _review([_batch_stream(tone_deg_s=0.05)])
    assert "INS_HNTCH_FREQ" not in weak["recommended"]
    assert all(p["ratio_db"] < fr.NOTCH_MIN_PROMINENCE_DB for p in weak["peaks"] if not p["notch_ok"])


def test_hntch_enable_goes_first_with_the_refresh_note():
    review, _ = _review([_batch_stream()])
    assert review["param_lines"][0] == "INS_HNTCH_ENABLE,1"
    assert fr.AP_HNTCH_REFRESH_NOTE in review["notes"]


def test_tlog_note():
    (review, note), _ = _real("copter_20211125-124019.tlog")
    assert review is None and note.startswith("no pre-filter gyro stream: RAW_IMU is logged after the vehicle's filters")


def test_a_prominent_motor_line_gets_its_notch_then_the_low_pass_raised():
    """The autopilots' documented order: a 22 dB motor line over a 3 deg/s noise floor gets
    the harmonic notch (never declined for its own lag), then INS_GYRO_FILTER is raised;
    the predicted attenuation at the peak stands beside it."""
    review, note = _review([_imu_stream(), _batch_stream(noise_deg_s=3.0, tone_deg_s=3.0)])
    assert note == ""
    top = max(review["peaks"], key=lambda q: q["amplitude_rms_deg_s"])
    assert top["notch_ok"] and top["ratio_db"] > 20.0
    rec = review["recommended"]
    assert rec["INS_HNTCH_ENABLE"] == 1 and abs(rec["INS_HNTCH_FREQ"] - TONE_HZ) < 2 * review["source"]["resolution_hz"]
    assert rec["INS_GYRO_FILTER"] > PARAMS["INS_GYRO_FILTER"]          # raised once the peak is notched
    pred = review["notch_prediction"]
    assert pred["attenuation_at_peak_db"] > 20.0
    assert any("the harmonic notch on the motor peak first, then INS_GYRO_FILTER" in w for w in review["why"])


def test_a_throttle_tracked_notch_is_predicted_along_the_flight_not_at_one_centre():
    """SYNTHETIC: a motor tone that follows the throttle (80 -> 160 Hz) under a logged MODE 1
    notch that follows it too. The predicted post-filter noise of the logged settings, the
    notch moved along the flight, is within 25 % of the truth (the same gyro replayed sample
    by sample through the chain); the notch held at the median centre predicts more than
    twice the truth (the tone, away from that centre most of the flight, passes)."""
    from scipy import signal

    from gyrodenoise.flightlog import notch_replay as nr

    params = {**PARAMS, "INS_HNTCH_ENABLE": 1, "INS_HNTCH_MODE": 1, "INS_HNTCH_FREQ": 80.0, "INS_HNTCH_BW": 40.0,
              "INS_HNTCH_ATT": 40.0, "INS_HNTCH_REF": 0.25, "INS_HNTCH_FM_RAT": 1.0, "INS_HNTCH_HMNCS": 1,
              "INS_GYRO_FILTER": 200.0}
    rng = np.random.default_rng(5)
    t = np.arange(int(12.0 * FS)) / FS
    thr_t = np.arange(0.0, 12.1, 0.1)
    thr = 0.25 + 0.75 * np.clip(thr_t / 12.0, 0.0, 1.0)                     # 80 -> 160 Hz
    track = nr.Track(thr_t, thr, "CTUN.ThO")
    centre = 80.0 * np.sqrt(np.interp(t, thr_t, thr) / 0.25)
    x = rng.normal(0.0, 0.3, (len(t), 3)) + 10.0 * np.sin(2 * np.pi * np.cumsum(centre) / FS)[:, None]
    stream = GyroStream(name="ISB.gyro[0]", message="ISBD", unit="rad/s", to_deg_s=RAD_TO_DEG, time_s=t,
                        raw=x / RAD_TO_DEG, index=np.arange(len(t)))
    filters = vf.vehicle_filters(named("ardupilot"), params)
    stage = next(s for s in filters["stages"] if s["kind"] == "harmonic_notch")
    median_centre = {"INS_HNTCH_*": float(vf.throttle_notch_centre_hz(stage, float(np.median(thr))))}

    def tracks_for(stages):
        return {s["params"]: track for s in stages if s.get("tracking") == "throttle"}

    along, _, _ = fr.filter_review([stream], named("ardupilot"), params, filters,
                                   context={"notch_centre_hz": median_centre, "tracks_for": tracks_for})
    one, _, _ = fr.filter_review([stream], named("ardupilot"), params, filters,
                                 context={"notch_centre_hz": median_centre})
    # the truth, apart from the module's replay: per sample the scalar notch at the tone's
    # centre (Direct Form I), then scipy's Butterworth at INS_GYRO_FILTER
    a_, q_ = vf.ardupilot_notch_a_q(80.0, 40.0, 40.0)
    post = np.empty_like(x)
    for ax in range(3):
        x1 = x2 = y1 = y2 = 0.0
        for i in range(len(t)):
            b0, b1, b2, a1, a2 = vf.ardupilot_notch_sos(float(centre[i]), a_, q_, FS)
            y = b0 * x[i, ax] + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2
            x2, x1, y2, y1 = x1, x[i, ax], y1, y
            post[i, ax] = y
    b, a = signal.butter(2, 200.0, fs=FS)
    post = np.stack([signal.lfilter(b, a, post[:, k]) for k in range(3)], 1)
    band = along["noise_band_hz"]
    f, p = np.array([0.0]), []
    for k in range(3):
        f, pk, _ = fr.spectrum.welch_psd(post[:, k], FS, along["source"]["nperseg"])
        p.append(pk)
    truth = fr._band_rms(f, np.array(p), band[0], band[1])["rss"]
    got_along = along["figures"]["logged"]["noise_rms_deg_s"]["rss"]
    got_one = one["figures"]["logged"]["noise_rms_deg_s"]["rss"]
    assert got_along == pytest.approx(truth, rel=0.25), (got_along, truth, got_one)
    assert got_one > 2.0 * truth, (got_one, truth)
