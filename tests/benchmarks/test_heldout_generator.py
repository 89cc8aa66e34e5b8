"""The held-out benchmark's generator and baselines (benchmarks/heldout): seeded, in its stated
ranges, its noise at the drawn Allan level, its causal baselines causal."""

import dataclasses

import allantools
import numpy as np
import pytest

from benchmarks.heldout import baselines
from benchmarks.heldout.cases import DURATION_S, MAX_SAMPLES, SEED_SETS, make_case
from benchmarks.heldout.metrics import angle_error_rms, rmse
from benchmarks.heldout.motions import EARTH_RATE_DPS, PROFILE_BY_NAME
from benchmarks.heldout.sensors import (
    GM_FACTOR, GRADE_BY_NAME, GRADES, WARMUP_TAU_S, analytic_avar, draw_sensor, stochastic_error, white_noise)

SOME_SEEDS = list(SEED_SETS["dev"])[:15] + list(SEED_SETS["heldout"])[:15]


def test_the_split_is_fixed_and_disjoint():
    assert SEED_SETS["dev"] == range(0, 100)
    assert SEED_SETS["heldout"] == range(1000, 1100)


@pytest.mark.parametrize("seed", [3, 1007])
def test_a_seed_gives_the_same_run(seed):
    a, b = make_case(seed), make_case(seed)
    assert a.sensor == b.sensor and a.profile == b.profile and a.earth_rate_dps == b.earth_rate_dps
    np.testing.assert_array_equal(a.truth, b.truth)
    np.testing.assert_array_equal(a.raw, b.raw)
    c = make_case(seed + 1)
    assert c.sensor != a.sensor


@pytest.mark.parametrize("seed", SOME_SEEDS)
def test_drawn_parameters_lie_in_the_stated_ranges(seed):
    case = make_case(seed)
    s, grade, profile = case.sensor, GRADE_BY_NAME[case.sensor.grade], case.profile
    assert PROFILE_BY_NAME[profile.name] is profile
    for field in ("arw_deg_rt_h", "bi_deg_h", "rrw_deg_h_rt_h", "lsb_dps", "full_scale_dps"):
        assert getattr(grade, field).contains(getattr(s, field)), field
    for field in ("turn_on_bias_dps", "warmup_dps"):  # magnitudes, either sign
        assert getattr(grade, field).contains(abs(getattr(s, field))), field
    assert WARMUP_TAU_S.contains(s.warmup_tau_s)
    for sigma in s.gm_sigma_dps:
        assert GM_FACTOR.contains(sigma / (s.bi_deg_h / 3600.0) * (1 + 1e-12))
    assert grade.sample_rate_hz.lo - 0.5 <= s.sample_rate_hz <= grade.sample_rate_hz.hi + 0.5
    assert s.sample_rate_hz >= profile.min_rate_hz - 0.5
    n = len(case.raw)
    assert n == len(case.truth)
    assert n == MAX_SAMPLES or DURATION_S.lo - 1 / s.sample_rate_hz <= n / s.sample_rate_hz <= DURATION_S.hi + 1e-9
    assert abs(case.earth_rate_dps) <= EARTH_RATE_DPS
    # what the gyro outputs: on its LSB grid, within its full scale; the truth within 0.8 of it
    codes = case.raw / s.lsb_dps
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-6)
    assert np.max(np.abs(case.raw)) <= s.full_scale_dps * (1 + 1e-12)
    assert np.max(np.abs(case.truth)) <= 0.8 * s.full_scale_dps + EARTH_RATE_DPS + 1e-9
    if profile.at_rest:
        np.testing.assert_allclose(case.truth, case.earth_rate_dps)


def test_every_grade_and_profile_is_drawn():
    cases = [make_case(seed) for seed in list(SEED_SETS["dev"])[:60]]
    assert {c.sensor.grade for c in cases} == set(GRADE_BY_NAME)
    assert {c.profile.name for c in cases} == set(PROFILE_BY_NAME)


def _oadev_1s(x, fs):
    taus, adev, _, _ = allantools.oadev(x, rate=fs, data_type="freq", taus=[1.0])
    assert taus[0] == pytest.approx(1.0)
    return adev[0]


@pytest.mark.parametrize("grade", GRADES, ids=lambda g: g.name)
@pytest.mark.parametrize("seed", [0, 1])
def test_allan_deviation_at_1s_matches_the_drawn_noise(grade, seed):
    """600 s at 200 Hz: the overlapping Allan deviation at tau = 1 s has a relative standard error
    of about 3 %; a band of 12 % is 4 of those, and a unit slip (deg/h vs deg/s, /60) is far out."""
    rng = np.random.default_rng(seed)
    sensor = dataclasses.replace(draw_sensor(rng, grade), sample_rate_hz=200.0)
    n = 600 * 200
    # the angle random walk alone: sigma_A(1 s) = N (deg/s/sqrt(Hz)) = ARW / 60
    white = _oadev_1s(white_noise(sensor, n, np.random.default_rng(seed + 10)), 200.0)
    assert white == pytest.approx(sensor.arw_deg_rt_h / 60.0, rel=0.12)
    # all the stochastic terms against the analytic sum (white + Gauss-Markov + rate random walk)
    total = _oadev_1s(stochastic_error(sensor, n, np.random.default_rng(seed + 20)), 200.0)
    assert total == pytest.approx(np.sqrt(analytic_avar(sensor, 1.0)), rel=0.12)


def test_the_analytic_allan_variance_has_the_textbook_limits():
    sensor = dataclasses.replace(draw_sensor(np.random.default_rng(0), GRADES[0]),
                                 arw_deg_rt_h=0.0, rrw_deg_h_rt_h=0.0, gm_sigma_dps=(0.0, 0.0, 1.0))
    # a Gauss-Markov of correlation time T: 2 sigma^2 tau / (3 T) for tau << T, 2 sigma^2 T / tau for tau >> T
    assert analytic_avar(sensor, 0.01) == pytest.approx(2 * 0.01 / 300, rel=1e-3)
    assert analytic_avar(sensor, 1e5) == pytest.approx(2 * 100 / 1e5, rel=1e-2)


def _impulse_pair(n=4000, k=2500, seed=0):
    x = np.cumsum(np.random.default_rng(seed).normal(size=n)) * 0.01 + np.random.default_rng(seed + 1).normal(size=n)
    y = x.copy()
    y[k] += 50.0
    return x, y, k


@pytest.mark.parametrize("family", baselines.CAUSAL_FAMILIES, ids=lambda f: f.name)
def test_the_causal_baselines_are_causal(family):
    x, y, k = _impulse_pair()
    fs = 1000.0
    grid = family.grid(fs)
    for params in grid[:: max(1, len(grid) // 7)] + grid[-1:]:
        a, b = family.apply(x, fs, **params), family.apply(y, fs, **params)
        np.testing.assert_array_equal(a[:k], b[:k], err_msg=f"{family.name} {params}")
        assert not np.array_equal(a[k:], b[k:]), f"{family.name} {params}: the impulse is not seen at all"


def test_the_zero_phase_baseline_is_not_causal():
    """The control of the test above: it catches a filter that looks ahead."""
    x, y, k = _impulse_pair()
    a = baselines.butterworth_zero_phase(x, 1000.0, 2, 20.0)
    b = baselines.butterworth_zero_phase(y, 1000.0, 2, 20.0)
    assert not np.array_equal(a[:k], b[:k])


def test_tuning_picks_the_grid_minimum_and_is_never_worse_than_raw():
    case = make_case(2)
    best = baselines.best_tuned(baselines.CAUSAL_FAMILIES, case.raw, case.truth, case.fs)
    assert best.score <= rmse(case.raw, case.truth)
    assert best.score == pytest.approx(rmse(best.estimate, case.truth))
    for params in baselines.butterworth_grid(case.fs)[::5]:
        assert best.score <= rmse(baselines.butterworth_causal(case.raw, case.fs, **params), case.truth)
    # one pass, several scores: each the minimum of its own
    by_rmse, by_angle = baselines.best_tuned_each(
        baselines.CAUSAL_FAMILIES, case.raw, case.fs,
        [lambda e: rmse(e, case.truth), lambda e: angle_error_rms(e, case.truth, case.fs, 1.0)])
    assert by_rmse.score == best.score
    assert by_angle.score <= angle_error_rms(best.estimate, case.truth, case.fs, 1.0)
    assert by_angle.score <= angle_error_rms(case.raw, case.truth, case.fs, 1.0)


def test_the_angle_error_of_a_constant_rate_error():
    """A rate error of 0.5 deg/s held over a 0.1 s window is 0.05 deg, in every window."""
    truth = np.zeros(1000)
    assert angle_error_rms(truth + 0.5, truth, 200.0, 0.1) == pytest.approx(0.05)


def test_the_constant_velocity_kalman_matches_filterpy():
    """An independent reference: filterpy's KalmanFilter with the same model, the same start."""
    kalman = pytest.importorskip("filterpy.kalman")
    fs, q_over_r = 200.0, 50.0
    dt = 1 / fs
    z = np.cumsum(np.random.default_rng(3).normal(size=600)) * 0.05 + np.random.default_rng(4).normal(size=600)
    kf = kalman.KalmanFilter(dim_x=2, dim_z=1)
    kf.F = np.array([[1.0, dt], [0.0, 1.0]])
    kf.H = np.array([[1.0, 0.0]])
    kf.R = np.array([[1.0]])
    kf.Q = q_over_r * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
    kf.x = np.array([[z[0]], [0.0]])
    kf.P = np.diag([1.0, 1e12])
    expected = [z[0]]
    for zk in z[1:]:
        kf.predict()
        kf.update(zk)
        expected.append(kf.x[0, 0])
    np.testing.assert_allclose(baselines.cv_kalman(z, fs, q_over_r), expected, rtol=1e-9, atol=1e-9)
