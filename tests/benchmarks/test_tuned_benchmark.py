"""The motion benchmark (benchmarks/motion_bench): its simulator against
analytic expectations, its tuned baselines against independent references, its
metrics against known answers. Seeded; tolerances stated per test."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from benchmarks.motion_bench import baselines as B
from benchmarks.motion_bench import bench, sim
import gyrodenoise as gd

from gyrodenoise.analysis.allan import adev

pytestmark = pytest.mark.slow          # the benchmark's simulator, baselines and metrics


def _only(sensor_key, **kw):
    """The sensor with every error term zero but those given."""
    zero = dict(arw_deg_rt_h=0.0, bias_inst_deg_h=0.0, rrw_deg_h_rt_h=0.0, turn_on_deg_s=0.0,
                temp_slope_deg_s_per_s=0.0, quant_rate_deg_s=0.0, quant_angle_deg=0.0)
    zero.update(kw)
    return dataclasses.replace(sim.SENSORS[sensor_key], **zero)


def test_arw_allan_deviation_is_n_over_sqrt_tau():
    # ARW N: Allan deviation N / sqrt(tau) (N in deg/s/sqrt(Hz) = N_deg_rt_h / 60); within 10 %
    s = _only("tactical", arw_deg_rt_h=0.66)
    fs = s.sample_rate_hz
    z = sim.measure(s, np.zeros(int(300 * fs)), np.random.default_rng(1))
    taus = np.array([0.01, 0.1, 1.0])
    res = adev(z, fs, tau_s=taus)
    got = res[1]
    want = 0.66 / 60.0 / np.sqrt(taus)
    assert np.all(np.abs(got / want - 1.0) < 0.10), (got, want)


def test_rate_random_walk_allan_deviation_is_k_sqrt_tau_over_3():
    # RRW K: Allan deviation K sqrt(tau / 3), K in deg/s/sqrt(s) = K_deg_h_rt_h / 3600 / 60; within 15 %
    s = dataclasses.replace(_only("drone", rrw_deg_h_rt_h=10.0), sample_rate_hz=20.0)
    b = sim.bias_terms(s, int(20000 * 20), np.random.default_rng(2))
    taus = np.array([10.0, 30.0, 100.0])
    res = adev(b, 20.0, tau_s=taus)
    got = res[1]
    want = 10.0 / 3600.0 / 60.0 * np.sqrt(taus / 3.0)
    assert np.all(np.abs(got / want - 1.0) < 0.15), (got, want)


def test_gauss_markov_std_and_correlation_time():
    rng = np.random.default_rng(3)
    x = sim.gauss_markov(400000, 10.0, 2.0, 5.0, rng)     # 40000 s, tau_c = 5 s = 50 samples
    assert abs(x.std() / 2.0 - 1.0) < 0.05
    r = np.corrcoef(x[:-50], x[50:])[0, 1]
    assert abs(r - math.exp(-1.0)) < 0.03


def test_fog_angle_quantisation_keeps_the_integral():
    # the FOG counts angle increments: its integrated output never leaves the true angle by a quantum
    s = _only("fog", quant_angle_deg=1.1e-4)
    fs = s.sample_rate_hz
    ref = 3.0 * np.sin(np.arange(20000) / fs)
    z = sim.measure(s, ref, np.random.default_rng(4))
    err = np.cumsum(z - ref) / fs
    assert np.max(np.abs(err)) <= 1.1e-4 * (1 + 1e-9)
    assert np.max(np.abs(z - ref)) > 0.01          # and it is quantised (rate steps of q fs = 0.022)


def test_mems_rate_quantisation_and_total_noise_std():
    s = sim.SENSORS["drone"]
    z = sim.measure(s, np.zeros(200000), np.random.default_rng(5))
    k = z / s.quant_rate_deg_s
    assert np.allclose(k, np.round(k), atol=1e-9)
    assert abs(z.std() / s.noise_std_deg_s - 1.0) < 0.02


def test_static_drone_has_no_vibration_and_moving_has_it():
    rest = sim.record("drone", "static_ramp", 0, 4.0)
    assert np.all(rest.truth == 0.0)
    fly = sim.record("drone", "trapezoid", 0, 4.0)
    power = np.abs(np.fft.rfft(fly.truth)) ** 2
    f = np.fft.rfftfreq(fly.truth.size, 1 / 400.0)
    vib = power[(f > 75) & (f < 85)].sum()
    assert vib > 100 * power[(f > 30) & (f < 60)].sum()
    # 3 deg/s amplitude (+-30 % slow AM): mean power 4.5 (deg/s)^2 by Parseval, within 40 %
    assert 0.6 < 2 * vib / fly.truth.size ** 2 / 4.5 < 1.4


def test_records_are_seeded():
    a = sim.record("tactical", "car", 7, 3.0)
    b = sim.record("tactical", "car", 7, 3.0)
    c = sim.record("tactical", "car", 8, 3.0)
    assert np.array_equal(a.z, b.z) and not np.array_equal(a.z, c.z)


# ------------------------------------------------------------------ baselines
def test_one_euro_is_the_core_s_and_grid_scores():
    """The baseline runs the core's method one_euro (tests/core/test_one_euro.py holds that to the
    paper); the tuned point's output and score are those of the core at the chosen parameters."""
    rec = sim.record("drone", "car", 0, 3.0)
    assert np.array_equal(B.one_euro(rec.z, 400.0, 2.0, 0.01),
                          gd.denoise(rec.z, 400.0, method="one_euro", min_cutoff_hz=2.0, beta=0.01))
    params, score, out = B.tune("one_euro", rec.z, rec.ref, 400.0, 100, rec.z.size, quick=True)
    assert np.array_equal(out, gd.denoise(rec.z, 400.0, method="one_euro", **params))
    assert score == pytest.approx(bench.rmse(out, rec.ref, 100, rec.z.size), rel=1e-9)
    grid = B.euro_grid(400.0, True)
    assert (params["min_cutoff_hz"], params["beta"]) in [(float(m), float(b)) for m, b in grid]
    assert all(bench.rmse(B.one_euro(rec.z, 400.0, m, b), rec.ref, 100, rec.z.size) >= score * (1 - 1e-12)
               for m, b in grid[::7])


def _filterpy_cv(z, fs, lam):
    """The CV model run by filterpy (independent reference): the filter and its moments."""
    filterpy = pytest.importorskip("filterpy.kalman")
    T = 1 / fs
    kf = filterpy.KalmanFilter(dim_x=2, dim_z=1)
    kf.x = np.array([z[0], 0.0])
    kf.F = np.array([[1, T], [0, 1]])
    kf.H = np.array([[1.0, 0.0]])
    kf.R = np.array([[1.0]])
    kf.Q = lam ** 2 / T ** 4 * np.array([[T ** 4 / 4, T ** 3 / 2], [T ** 3 / 2, T ** 2]])
    kf.P = np.diag([1.0, 1.0 / T ** 2])
    xs, ps = [kf.x.copy()], [kf.P.copy()]
    for zk in z[1:]:
        kf.predict()
        kf.update(zk)
        xs.append(kf.x.copy())
        ps.append(kf.P.copy())
    return kf, np.array(xs), np.array(ps)


def test_cv_kalman_matches_filterpy():
    rec = sim.record("drone", "pendulum", 0, 1.0)
    _, xs, _ = _filterpy_cv(rec.z, 400.0, 1e-3)
    assert np.allclose(B.cv_kf(rec.z, 400.0, 1e-3), xs[:, 0], rtol=0, atol=1e-9)


def test_cv_rts_smoother_matches_filterpy():
    rec = sim.record("fog", "pendulum", 0, 1.0)
    kf, xs, ps = _filterpy_cv(rec.z, 200.0, 1e-4)
    sm, _, _, _ = kf.rts_smoother(xs, ps)
    assert np.allclose(B.cv_rts(rec.z, 200.0, 1e-4), sm[:, 0], rtol=0, atol=1e-9)


def test_tuned_baselines_beat_fixed_ones():
    # seeded: a tactical MEMS on a car; the tuned Butterworth-2 and CV-KF are at
    # least as good as fixed choices a user might copy (30 Hz, 20 Hz first order)
    rec = sim.record("tactical", "car", 0, 8.0)
    fs, lo, hi = 1000.0, 2000, rec.z.size
    fixed30 = bench.rmse(B.butter(rec.z, fs, 2, 30.0), rec.ref, lo, hi)
    fixed20 = bench.rmse(B.butter(rec.z, fs, 1, 20.0), rec.ref, lo, hi)
    for fam in ("butter2", "cv_kf", "one_euro"):
        _, s, _ = B.tune(fam, rec.z, rec.ref, fs, lo, hi, quick=True)
        assert s <= min(fixed30, fixed20), fam
    # the car's motion is slow: tuning finds far more than a fixed 30 Hz filter
    _, s, _ = B.tune("butter2", rec.z, rec.ref, fs, lo, hi, quick=False)
    assert s < 0.8 * fixed30


def test_savgol_is_exact_on_a_quadratic_and_matches_scipy_inside():
    from scipy.signal import savgol_filter
    t = np.linspace(0, 1, 500)
    x = 3 * t * t - t + 0.5
    assert np.allclose(B.savgol(x, 51, 2)[25:-25], x[25:-25], atol=1e-9)
    rng = np.random.default_rng(0)
    z = rng.standard_normal(2000)
    a = B.savgol(z, 41, 4)
    b = savgol_filter(z, 41, 4, mode="interp")
    assert np.allclose(a[40:-40], b[40:-40], atol=1e-9)


# ------------------------------------------------------------------ metrics
def test_lag_finds_a_known_delay():
    rec = sim.record("tactical", "multirotor", 0, 6.0)
    fs = 1000.0
    y = np.r_[np.full(7, rec.ref[0]), rec.ref[:-7]]
    assert bench.lag_s(y, rec.ref, fs, 2000, rec.z.size) * fs == pytest.approx(7.0, abs=0.3)
    assert abs(bench.lag_s(rec.ref, rec.ref, fs, 2000, rec.z.size)) * fs < 0.05


def test_sine_gain_of_a_scaled_sine():
    fs = 200.0
    t = np.arange(4000) / fs
    y = 0.8 * np.sin(2 * np.pi * 3.0 * t + 1.0) + 5.0 + 0.1 * t
    assert bench.sine_gain(y, 3.0, fs, 400, 4000, 1.0) == pytest.approx(0.8, rel=1e-9)


def test_evaluate_api_and_goal_lines():
    rows = bench.evaluate({"ident": lambda z, fs: z.copy()}, sensors=["fog"],
                          profiles=["static_ramp", "car"], seeds=(0,), quick=True)
    by = {(r["profile"], r["method"]): r for r in rows}
    # the identity is raw: ratio to raw 1, angle error raw's
    assert by[("car", "ident")]["ratio_raw"] == pytest.approx(1.0)
    assert by[("car", "ident")]["angle_err_deg"] == pytest.approx(by[("car", "raw")]["angle_err_deg"])
    # the best causal filter is never worse than any causal family, at rest far better than raw
    for p in ("static_ramp", "car"):
        assert all(by[(p, "best_causal")]["rmse"] <= by[(p, f)]["rmse"] * (1 + 1e-12) for f in B.CAUSAL)
    assert by[("static_ramp", "raw")]["ratio_causal"] > 5
    lines = bench.goal_lines(rows, [], ["ident"])
    got = {g: ok for _, g, _, ok in lines}
    assert got["never worse than raw: RMSE / raw's <= 1.005 on every profile"] == "PASS"
    assert got["at rest (static with bias ramp) >= 5x below raw"] == "FAIL"


# ------------------------------------------------------------------ real motion (item 5)
from benchmarks.motion_bench import realmotion as RM  # noqa: E402

from tests.helpers import shared_file  # noqa: E402


def test_window_integration_against_scipy_rotations():
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(6)
    fs = 100.0
    rate = rng.normal(0, 200.0, (300, 3))             # deg/s, large: the composition order matters
    q = RM.integrate_windows(rate, fs, np.array([0, 50]), np.array([300, 120]))
    for i, (a, b) in enumerate(((0, 300), (50, 120))):
        r = Rotation.identity()
        for w in rate[a:b]:
            r = r * Rotation.from_rotvec(np.radians(w) / fs)     # body frame: right-multiply
        xyzw = r.as_quat()
        ref = np.r_[xyzw[3], xyzw[:3]]
        assert RM.qangle_deg(RM.qmul(RM.qconj(q[i]), ref)) < 1e-9
    # a constant rate about one axis: angle = rate x time
    one = RM.integrate_windows(np.tile([0.0, 0.0, 30.0], (100, 1)), fs, [0], [100])
    assert RM.qangle_deg(one)[0] == pytest.approx(30.0, rel=1e-12)


def test_slerp_against_scipy():
    from scipy.spatial.transform import Rotation, Slerp
    rots = Rotation.from_rotvec([[0.1, 0.2, -0.3], [0.5, -0.4, 0.9]])
    s = Slerp([0.0, 1.0], rots)(0.3).as_quat()
    a, b = (np.r_[x[3], x[:3]] for x in rots.as_quat())
    got = RM.qslerp(a[None], b[None], np.array([0.3]))[0]
    assert RM.qangle_deg(RM.qmul(RM.qconj(got), np.r_[s[3], s[:3]])) < 1e-9


def _broad(name="02_undisturbed_slow_rotation_B"):
    pytest.importorskip("h5py")
    return RM.load_broad(shared_file("motion", "broad", f"{name}.hdf5"))


def test_broad_raw_error_small_and_delayed_copy_caught():
    tr = RM.calibrate(_broad())
    # the data README: gyro 1 sample behind the differentiated reference; we find 2.35 samples (8 ms)
    assert tr.offset in (1, 2, 3) and abs(tr.frac) <= 0.5
    raw = tr.rate_deg_s
    e01 = RM.rms(RM.window_errors_deg(tr, raw, 0.1))
    e1 = RM.rms(RM.window_errors_deg(tr, raw, 1.0))
    assert e01 < 0.25 and e1 < 0.45           # measured 0.194 and 0.348 deg
    # a copy delayed by 3 samples (10.5 ms) is 3x worse over both windows (measured 3.2x, 3.8x)
    late = np.vstack([np.repeat(raw[:1], 3, 0), raw[:-3]])
    assert RM.rms(RM.window_errors_deg(tr, late, 0.1)) > 2.5 * e01
    assert RM.rms(RM.window_errors_deg(tr, late, 1.0)) > 2.5 * e1
    # and calibrating on the delayed copy finds the 3 extra samples
    tr2 = _broad()
    tr2.rate_deg_s = late
    RM.calibrate(tr2)
    assert tr2.offset + tr2.frac == pytest.approx(tr.offset + tr.frac + 3, abs=0.06)


def test_psins_mounting_estimate_matches_the_mat_file():
    import scipy.io as sio
    shared_file("motion", "psins_car", "transfer_align_mems_imu_100Hz.csv")
    tr = RM.calibrate(RM.load_psins_car(shared_file("motion", "psins_car")))
    mu0 = sio.loadmat(shared_file("motion", "psins_car", "transfer_align_fog_mems.mat"))["mu0"].ravel()
    # the estimated mounting angle against the .mat's misalignment (0.31 deg): within 0.05 deg
    assert RM.qangle_deg(tr.mounting) == pytest.approx(np.degrees(np.linalg.norm(mu0)), abs=0.05)
    assert abs(tr.offset) <= 5
    assert RM.rms(RM.window_errors_deg(tr, tr.rate_deg_s, 1.0)) < 0.03      # measured 0.012 deg


def test_quadrotor_offset_in_the_documented_range():
    tr = RM.calibrate(RM.load_quadrotor(shared_file("motion", "quadrotor_4imu", "path_4"), 1))
    lag_s = (tr.offset + tr.frac) / tr.sample_rate_hz
    assert 0.04 <= lag_s <= 0.45            # README: 0.06-0.42 s; measured 0.063 s
