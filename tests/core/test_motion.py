"""method="motion" on seeded ground-truth profiles: the goal's
properties, not timing. References: the true rate of the simulation and the
specialists (raw, 1st-order LP 20 Hz, Butterworth-2 30 Hz, kf, shakf) run on
the same record."""

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.core import batch
from gyrodenoise.core import kernels as K
from benchmarks import reference_filters as RF
from benchmarks.profiles import PROFILES
from tests.helpers import SHARED_DATA

SENSORS = {"fog": ("paper_fog", 200.0, 5.0), "mems": ("icm20602", 1000.0, 20.0)}
SKIP_S = 2.0
LOGS = SHARED_DATA / "logs"


def record(profile, sensor, seconds, seed=1):
    card, fs, rms = SENSORS[sensor]
    n = int(seconds * fs)
    kw = {"rms_deg_s": rms} if profile in ("smooth", "sine_0p2hz", "sine_1hz", "sine_5hz",
                                           "rest_manoeuvre_rest") else {}
    truth = PROFILES[profile](n, fs, seed=seed, **kw)
    z = gd.simulate(card, n, seed=seed + 100, true_rate_deg_s=truth).rate_deg_s
    return np.asarray(z, float), truth, fs


def rmse(y, x, fs):
    i = int(SKIP_S * fs)
    return float(np.sqrt(np.mean((y[i:] - x[i:]) ** 2)))


def specialists(z, fs):
    return {"raw": z, "lp20": RF.lowpass1(z, fs, 20.0)[0],
            "bw30": gd.denoise(z, fs, method="lowpass", cutoff_hz=30.0, order=2),
            "kf": gd.denoise(z, fs, method="kf"), "shakf": gd.denoise(z, fs, method="shakf")}


def test_motion_is_the_default():
    assert K.DEFAULT_METHOD == "motion"
    z, _, fs = record("smooth", "mems", 5.0)
    np.testing.assert_array_equal(gd.denoise(z, fs), gd.denoise(z, fs, method="motion"))


@pytest.mark.parametrize("sensor", ["fog", "mems"])
def test_at_rest_it_averages_at_least_5x_below_raw(sensor):
    z, x, fs = record("at_rest", sensor, 60.0)
    y = gd.denoise(z, fs, method="motion")
    assert rmse(y, x, fs) * 5.0 <= rmse(z, x, fs)
    # and within 2x of the paper's SHAKF, the specialist at rest
    assert rmse(y, x, fs) <= 2.0 * rmse(gd.denoise(z, fs, method="shakf"), x, fs)


@pytest.mark.parametrize("sensor", ["fog", "mems"])
@pytest.mark.parametrize("profile", ["steps", "smooth", "sine_1hz", "sine_5hz", "rest_manoeuvre_rest"])
def test_moving_profiles_below_raw_and_within_2x_of_the_best(sensor, profile):
    z, x, fs = record(profile, sensor, 20.0)
    y = gd.denoise(z, fs, method="motion")
    e = rmse(y, x, fs)
    spec = {m: rmse(v, x, fs) for m, v in specialists(z, fs).items()}
    # not above raw's beyond rounding: where the most likely filter follows every sample (the
    # FOG's 5 Hz sine, 0.025 fs) the pass-through puts the output on the raw sample (1.0000x)
    assert e <= spec["raw"] * (1.0 + 1e-6), (e, spec)
    assert e <= 2.0 * min(spec.values()), (e, spec)


def test_a_step_is_followed_in_the_same_sample():
    card, fs, _ = SENSORS["fog"]
    n = int(20 * fs)
    truth = np.zeros(n)
    truth[n // 2:] = 10.0
    z = gd.simulate(card, n, seed=5, true_rate_deg_s=truth).rate_deg_s
    y = gd.denoise(z, fs, method="motion")
    assert abs(y[n // 2] - 10.0) < 0.05          # noise 0.0036 deg/s: the step itself, not a lag
    assert np.max(np.abs(y[n // 2 + 1:] - 10.0)) < 0.05


def test_per_sample_path_equals_batch_and_restarts_reidentify():
    z, _, fs = record("rest_manoeuvre_rest", "mems", 6.0)
    rs = np.zeros(z.size, dtype=bool)
    rs[3000] = True
    batch = gd.denoise(z, fs, method="motion", restarts=rs)
    d = gd.Denoiser(fs, method="motion")
    plain = np.array([d.step(v, bool(r)) for v, r in zip(z, rs)])
    np.testing.assert_allclose(plain, batch, rtol=0, atol=1e-12)
    # after the restart: the same as a fresh filter on the rest of the record
    np.testing.assert_allclose(batch[3000:], gd.denoise(z[3000:], fs, method="motion"), rtol=0, atol=1e-12)


def _lowband(x, fs, band_hz=5.0):
    from scipy.signal import butter, sosfiltfilt
    return sosfiltfilt(butter(4, band_hz, fs=fs, output="sos"), x)


def _streams(name):
    from gyrodenoise.flightlog import dataflash, ulog
    return dataflash.read(LOGS / name)[2] if name.endswith(".bin") else ulog.read(LOGS / name)[1]


@pytest.mark.parametrize("name", ["log171.bin", "px4_sample.ulg"])
def test_real_flight_keeps_the_low_band_motion(name):
    """Real flights (log171.bin: Pixhawk, 50 Hz; px4_sample.ulg: PX4, 250 Hz):
    in the 2 s windows where the vehicle moves (0-5 Hz content above 2 deg/s
    std), the 0-5 Hz content of the output correlates >= 0.95 with the raw's
    and keeps >= 85 % of its amplitude (the goal set for motion on real flights)."""
    if not (LOGS / name).is_file():
        pytest.skip(f"../shared/data/logs/{name} absent")
    from gyrodenoise.flightlog.streams import detect_restarts
    checked = 0
    for st in _streams(name):
        detect_restarts(st)
        x, _, _ = st.work_units()
        fs = st.rate_hz
        for k in range(3):
            z = x[:, k]
            y = gd.denoise(z, fs, method="motion", restarts=st.restarts)
            lz, ly = _lowband(z, fs), _lowband(y, fs)
            w = int(2 * fs)
            moving = np.zeros(z.size, bool)
            for i in range(0, z.size - w, w):
                moving[i:i + w] = np.std(lz[i:i + w]) > 2.0
            if moving.sum() < 2 * w:
                continue
            corr = np.corrcoef(lz[moving], ly[moving])[0, 1]
            amp = np.std(ly[moving]) / np.std(lz[moving])
            assert corr >= 0.95 and amp >= 0.85, (st.name, k, corr, amp)
            checked += 1
    assert checked >= 3


def test_motion_reports_its_noise_estimates_and_no_ar_model():
    """R_hat/q_hat (and the FMUs' R_hat/Q_hat outputs) are motion's own estimates:
    R the white-noise variance of the sensor (known here: sigma 0.05 deg/s), q > 0;
    c and phi are 0 for the methods that identify no AR model (were z_ref and 0)."""
    rng = np.random.default_rng(7)
    sigma = 0.05
    z = 3.0 + sigma * rng.standard_normal(40_000)          # 200 s at 200 Hz, offset 3 deg/s
    for method in ("motion", "lowpass"):
        den = gd.Denoiser(sample_rate_hz=200.0, method=method)
        for v in z:
            den.step(float(v))
        assert den.c == 0.0 and list(den.phi) == [0.0] * len(den.phi)
        if method == "motion":
            assert den.R_hat == pytest.approx(sigma ** 2, rel=0.10)
            assert 0.0 < den.q_hat < den.R_hat and np.isfinite(den.q_hat)
    den = gd.Denoiser(sample_rate_hz=200.0, method="shakf")    # the AR methods: unchanged meaning
    for v in z[:5000]:
        den.step(float(v))
    assert den.c == pytest.approx(3.0 * (1.0 - sum(den.phi)), abs=0.05)


def _sine_gain(y, f_hz, fs, lo):
    t = np.arange(y.size) / fs
    X = np.column_stack([np.sin(2 * np.pi * f_hz * t), np.cos(2 * np.pi * f_hz * t), np.ones_like(t)])[lo:]
    c = np.linalg.lstsq(X, y[lo:], rcond=None)[0]
    return float(np.hypot(c[0], c[1]))


@pytest.mark.parametrize("snr, tols", [(10.0, {0.01: 0.05, 0.05: 0.05, 0.15: 0.05, 0.25: 0.05, 0.35: 0.05,
                                                0.45: 0.05}),
                                        (3.0, {0.01: 0.10, 0.05: 0.10, 0.15: 0.10})])
def test_gain_of_a_sinusoid_is_kept(snr, tols):
    """A sinusoid standing snr sigma above white noise (1 kHz, sigma 0.35 deg/s, seeded)
    keeps its amplitude within 5 %, up to 0.45 fs at 10 sigma (the old 4th-difference noise
    level erased everything above fs/4); at 3 sigma within 10 % up to 0.25 fs (the next
    test). Measured on seeds 11-13 (this test: seed 11) with the default bank (13 CV lanes,
    tracking indices 10x apart, + 3 CA lanes, 1e-2..1): 10 sigma 1.012-1.014 at 0.01 fs (13 CV
    lanes alone 1.031-1.033), 1.033-1.038 at 0.05 fs, 0.997-1.001 from 0.15 fs up; 3 sigma
    1.033-1.039 at 0.01 fs, 1.028-1.047 at 0.05 fs, 0.998-1.008 at 0.15 fs (as the CV lanes
    alone). Not tested, same seeds: 0.02 fs at 3 sigma 1.103-1.114. A bank of 8 CV lanes
    (52x apart) + 4 CA lanes (1e-4..1), tried: 1.076-1.087 at 0.01 fs, 3 sigma."""
    fs, sig, n = 1000.0, 0.35, 8000
    rng = np.random.default_rng(11)
    t = np.arange(n) / fs
    for frac, tol in tols.items():
        x = snr * sig * np.sin(2 * np.pi * frac * fs * t + 0.3)
        y = gd.denoise(x + sig * rng.standard_normal(n), fs)
        g = _sine_gain(y, frac * fs, fs, 2000) / (snr * sig)
        assert abs(g - 1.0) <= tol, (frac, g)


def test_gain_of_a_3_sigma_sinusoid_at_a_quarter_of_the_rate():
    """The 3-sigma sinusoid of the test above at 0.25 fs (the same seeded noise stream: the
    draws for 0.01, 0.05 and 0.15 fs first) keeps its amplitude within 2 %. Measured on seeds
    11-13 (this test: seed 11): 0.990-1.002 with the default bank (13 CV lanes, 10x apart, + 3
    CA lanes); a bank of 8 CV lanes (52x apart) + 4 CA lanes, tried, averaged it down to
    0.49-0.55 of its amplitude (the CA lanes did not change that)."""
    fs, sig, n = 1000.0, 0.35, 8000
    rng = np.random.default_rng(11)
    t = np.arange(n) / fs
    for frac in (0.01, 0.05, 0.15, 0.25):
        x = 3.0 * sig * np.sin(2 * np.pi * frac * fs * t + 0.3)
        z = x + sig * rng.standard_normal(n)
    g = _sine_gain(gd.denoise(z, fs), frac * fs, fs, 2000) / (3.0 * sig)
    assert abs(g - 1.0) <= 0.02, g


def test_a_lone_spike_is_not_held():
    """Hand-made record: 1 deg/s at rest (sigma 0.05, 200 Hz, seeded), one
    sample +25 deg/s. The output at the spike moves at most to it, the next
    samples are back at the rate (within 5 sigma) -- nothing held -- and the
    averaging goes on (the 5 s after it: RMSE still 10x below raw)."""
    rng = np.random.default_rng(3)
    fs, n, sig, i = 200.0, 4000, 0.05, 3000
    z = 1.0 + sig * rng.standard_normal(n)
    z[i] += 25.0
    y = gd.denoise(z, fs)
    assert abs(y[i] - y[i - 1]) <= abs(z[i] - y[i - 1]) + 1e-9
    assert np.max(np.abs(y[i + 1:i + 6] - 1.0)) < 5.0 * sig, y[i - 1:i + 6]
    assert np.sqrt(np.mean((y[i + 10:i + 1000] - 1.0) ** 2)) * 10.0 < sig
    # and the output stays inside the input's envelope
    assert y.max() <= z.max() and y.min() >= z.min()


def _log171_spikes():
    """(stream, axis, z, y, i, height) for every lone spike of log171.bin: a sample
    > 10 deg/s off the mean of its neighbours, which agree, after 5 calm
    samples (within 30 % of the height of the last one; a spike, not a swing
    of the 50 Hz-aliased vibration)."""
    from tests.helpers import shared_file
    path = shared_file("logs", "log171.bin")
    from gyrodenoise.flightlog import dataflash
    from gyrodenoise.flightlog.streams import detect_restarts
    for st in dataflash.read(path)[2]:
        detect_restarts(st)
        x, _, _ = st.work_units()
        for k in range(3):
            z = x[:, k]
            y = gd.denoise(z, st.rate_hz, restarts=st.restarts)
            dev = np.abs(z[1:-1] - 0.5 * (z[:-2] + z[2:]))
            idx = np.where((dev > 10.0) & (np.abs(z[:-2] - z[2:]) < 0.3 * dev))[0] + 1
            for i in idx[(idx + 4 < z.size) & (idx > 6)]:
                if np.max(np.abs(z[i - 6:i - 1] - z[i - 1])) < 0.3 * dev[i - 1]:
                    yield st, k, z, y, int(i), float(dev[i - 1])


def test_log171_a_spike_moves_the_output_at_most_by_itself():
    """log171.bin (50 Hz, real flight; the issue: raw -3.3, output 11.1 after a
    25.8 deg/s spike): at every lone spike the output moves at most to the
    spike (+15 % of its height: the slope of the most likely filter may carry
    it beyond; measured: none beyond, over the 8 spikes)."""
    n = 0
    for st, k, z, y, i, h in _log171_spikes():
        assert abs(y[i] - y[i - 1]) <= abs(z[i] - y[i - 1]) + 0.15 * h, (st.name, k, i)
        n += 1
    assert n >= 5


def test_log171_a_spike_is_not_held():
    """Against the same record with the spike replaced by the mean of its
    neighbours (the counterfactual): 3 samples on, the output is pulled
    towards the spike by at most 20 % of its height (measured: at most 15 %,
    in a noisy stretch; the issue's case, before: 43 % -- raw 0.07, output
    11.1 after 25.8 deg/s)."""
    n = 0
    for st, k, z, y, i, h in _log171_spikes():
        zc = z.copy()
        zc[i] = 0.5 * (z[i - 1] + z[i + 1])
        yc = gd.denoise(zc, st.rate_hz, restarts=st.restarts)
        towards = (y[i + 3] - yc[i + 3]) * np.sign(z[i] - zc[i])
        assert towards <= 0.2 * h, (st.name, k, i, y[i:i + 4], yc[i:i + 4])
        n += 1
    assert n >= 5


def test_log171_a_lone_spike_is_not_held():
    """A lone spike of a real flight: log171.bin, IMU axis 0, sample 4366 (25.8 deg/s
    between 15.5 and -3.3 deg/s). The first form of motion followed it and held it
    (11.1 deg/s at the next sample, 11.0 where raw is 0.07). Now, against the
    same record with the spike replaced by the mean of its neighbours, the
    output is pulled towards it by at most 30 % of its height at the next
    sample and 10 % four samples on (measured: 22 %, 16 %, 11 %, 7 %; in this
    stretch the rate swings by 15 deg/s a sample, so the spike is no outlier
    to the noise level read there and is partly averaged in)."""
    from tests.helpers import shared_file
    path = shared_file("logs", "log171.bin")
    from gyrodenoise.flightlog import dataflash
    from gyrodenoise.flightlog.streams import detect_restarts
    st = dataflash.read(path)[2][0]
    detect_restarts(st)
    z = st.work_units()[0][:, 0]
    i = 4366
    assert z[i] == pytest.approx(25.78, abs=0.01) and z[i + 1] == pytest.approx(-3.26, abs=0.01)
    zc = z.copy()
    zc[i] = 0.5 * (z[i - 1] + z[i + 1])
    h = z[i] - zc[i]
    y = gd.denoise(z, st.rate_hz, restarts=st.restarts)
    yc = gd.denoise(zc, st.rate_hz, restarts=st.restarts)
    assert y[i] - y[i - 1] <= z[i] - y[i - 1]
    assert y[i + 1] - yc[i + 1] <= 0.3 * h, (y[i:i + 6], yc[i:i + 6])
    assert np.max(y[i + 4:i + 20] - yc[i + 4:i + 20]) <= 0.1 * h, (y[i:i + 6], yc[i:i + 6])


def test_causal_blend_is_the_blend_of_the_forward_and_backward_runs():
    """batch._blend (the offline form before the smoother, kept by the rigid-body option
    max_motion_hz): per run between restarts, the forward and backward runs of the
    causal filter weighted by the inverse of their output variances (M_PVAR),
    each alone where the other warms up; rebuilt here sample by sample with
    the plain-Python kernels (the specification)."""
    z, _, fs = record("rest_manoeuvre_rest", "mems", 6.0)
    p = K.make_params(3, "motion", sample_rate_hz=fs)
    p[K.P_MO_VAR] = 1.0            # the causal filter keeps its output variance only when asked
    off = np.concatenate([batch._blend(p, z[:3500], True), batch._blend(p, z[3500:], True)])
    warm = int(p[K.P_WARMUP])
    assert warm == 1000            # so both runs (3500, 2500 samples) have a blended middle
    o = K.layout(3)[6] - K.N_EXT + K.M_PVAR

    def one_way(x):
        s = K.init_state(p)
        y, v = [], []
        for zi in x:
            y.append(K.step(p, s, float(zi), False))
            v.append(s[o])
        return np.array(y), np.array(v)
    for a, b in ((0, 3500), (3500, z.size)):
        seg = z[a:b]
        fwd, vf = one_way(seg)
        bwd, vb = one_way(seg[::-1])
        bwd, vb = bwd[::-1], vb[::-1]
        with np.errstate(invalid="ignore", divide="ignore"):    # 0/0 in the warm-ups, replaced below
            ref = (vb * fwd + vf * bwd) / (vf + vb)
        ref[:warm] = bwd[:warm]
        ref[-warm:] = fwd[-warm:]
        assert np.all(vf[warm:] > 0) and np.all(vb[:-warm] > 0)
        np.testing.assert_allclose(off[a:b], ref, rtol=0, atol=1e-12)
        assert np.max(np.abs(off[a + warm:b - warm] - 0.5 * (fwd + bwd)[warm:-warm])) > 0   # not a plain mean
    with pytest.raises(ValueError, match="offline"):
        gd.denoise(z, fs, method="kf", offline=True)


@pytest.mark.parametrize("sensor", ["fog", "mems"])
def test_offline_has_no_lag_and_beats_the_causal_filter(sensor):
    """On a smooth manoeuvre (seeded, known truth) the offline output lags the
    truth by less than one sample (cross-correlation peak) and its RMSE is
    below the causal filter's."""
    z, x, fs = record("smooth", sensor, 20.0)
    off = gd.denoise(z, fs, offline=True)
    cau = gd.denoise(z, fs)
    assert rmse(off, x, fs) < rmse(cau, x, fs)
    i = int(SKIP_S * fs)
    e, t = off[i:-i] - off[i:-i].mean(), x[i:-i] - x[i:-i].mean()
    lags = range(-5, 6)
    c = [np.dot(np.roll(e, -k), t) for k in lags]
    assert list(lags)[int(np.argmax(c))] == 0


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_summed_innovations_cut_the_angle_error_on_a_chirp(seed):
    """A chirp (0.2-3.2 Hz, 20 sigma, 20 s at 200 Hz): the summed-innovation test of the bank
    (p[P_MO_CUS]) drops a filter that lags, so the integrated angle error over 0.1 s windows is
    lower than with it off, for at most 3 % more RMSE. Measured with the 13-filter CV bank:
    11-15 % lower on seeds 0-5, RMSE -1 to +2 %; with the default bank (13 CV + 3 CA lanes):
    2.1-8.2 % lower, RMSE -0.9 to +0.9 %, the angle error itself 0.00149-0.00163 deg (the CA
    lanes follow the chirp: less left for the test to drop); 8 CV + 4 CA lanes, tried: 5-12 %."""
    fs, n, sig, lo = 200.0, 4000, 0.05, 400
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    truth = 20.0 * sig * np.sin(2.0 * np.pi * np.cumsum(0.2 + 0.15 * t) / fs)
    z = truth + sig * rng.standard_normal(n)
    p = K.make_params(method="motion", sample_rate_hz=fs)
    assert p[K.P_MO_CUS + 1] > 0.0
    p_off = list(p)
    p_off[K.P_MO_CUS + 1] = 0.0
    on = batch.run(p, K.init_state(p), z)[0]
    off = batch.run(p_off, K.init_state(p_off), z)[0]

    def angle(y):
        a = (y[lo:] - truth[lo:]).reshape(-1, 20).sum(axis=1) / fs
        return float(np.sqrt(np.mean(a * a)))

    def err(y):
        return float(np.sqrt(np.mean((y[lo:] - truth[lo:]) ** 2)))

    assert angle(on) < 0.98 * angle(off)
    assert err(on) <= 1.03 * err(off)


def test_the_line_test_stays_off_on_white_noise_and_on_a_tone_below_it():
    """The spectral line test (a bin at or above 0.36 fs 10x over the floor in two blocks in a
    row) never trips on 5 minutes of white noise at 200 Hz (about 1e-7 per block pair), nor on
    a strong tone at 0.2 fs (below its bins: the bank follows it); it trips on a 3-sigma tone at
    0.45 fs from its second block on."""
    fs, n = 200.0, 60000
    rng = np.random.default_rng(5)
    p = K.make_params(method="motion", sample_rate_hz=fs)
    o = K.ext_offset(p) + K.M_LON
    t = np.arange(n) / fs
    white = rng.standard_normal(n)
    for z in (white, white + 20.0 * np.sin(2.0 * np.pi * 0.2 * fs * t)):
        assert not batch.run(p, K.init_state(p), z, trace_index=o)[2].any()
    tone = white[:2000] + 3.0 * np.sin(2.0 * np.pi * 0.45 * fs * t[:2000])
    on = batch.run(p, K.init_state(p), tone, trace_index=o)[2]
    assert not on[:2 * K.MO_SPEC_N - 1].any() and on[2 * K.MO_SPEC_N:].all()


def test_ca_gains_equal_the_riccati_solution():
    """kernels.ca_gains (Newton on the steady state's cubic, a fixed count) equals the
    constant-acceleration filter's gains from scipy's discrete algebraic Riccati solver
    within 1e-12 relative over the default lanes' tracking indices (1e-4..1), and
    log(S / R) = -log(1 - alpha)."""
    linalg = pytest.importorskip("scipy.linalg")
    f3 = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
    g3 = np.array([[0.5], [1.0], [1.0]])
    h = np.array([[1.0, 0.0, 0.0]])
    for e in np.linspace(-4.0, 0.0, 7):
        lam = 10.0 ** e
        pp = linalg.solve_discrete_are(f3.T, h.T, lam * lam * (g3 @ g3.T), np.array([[1.0]]))
        ref = (pp @ h.T / (pp[0, 0] + 1.0))[:, 0]
        alpha, beta, gamma, ls, lam2 = K.ca_gains(lam)
        assert np.allclose([alpha, beta, gamma], ref, rtol=1e-12, atol=0.0), e
        assert abs(ls - np.log(pp[0, 0] + 1.0)) <= 1e-12 * abs(ls)
        assert lam2 == lam * lam


def test_default_bank_is_13_cv_and_3_ca_lanes():
    """The default bank: 13 constant-velocity lanes (tracking indices 1e-10..1e2) then 3
    constant-acceleration ones (1e-2..1); a CV lane's gamma is 0 and its lam^2 the value
    S_Q used before (beta^2 / (1 - alpha)); the fastest CV lane is the last CV one."""
    p = K.make_params(method="motion", sample_rate_hz=200.0)
    ncv, nca = int(p[K.P_MO_NF]), int(p[K.P_MO_NCA])
    nf = ncv + nca
    assert (ncv, nca) == (13, 3) and nf == K.MO_MAX_NF == 16
    g = K.P_MO_G
    m = K.MO_MAX_NF
    for i in range(13):
        a, b, ls = K.cv_gains(10.0 ** (-10.0 + 12.0 * i / 12))
        assert (p[g + i], p[g + m + i], p[g + 2 * m + i], p[g + 3 * m + i]) == (a, b, ls, 0.0)
        assert p[g + 4 * m + i] == b * b / (1.0 - a)
    for c in range(3):
        a, b, gm, ls, lam2 = K.ca_gains(10.0 ** (-2.0 + 2.0 * c / 2))
        assert [p[g + j * m + 13 + c] for j in range(5)] == [a, b, ls, gm, lam2]
    assert all(v == 0.0 for j in range(5) for v in p[g + j * m + nf:g + (j + 1) * m])


def test_cv_lanes_keep_j_zero_and_ca_lanes_track_a_parabola():
    """On a quadratic rate (constant rate acceleration, 30 deg/s^3, 200 Hz, sigma 0.05) the
    CV lanes' j stays exactly 0.0, the most likely lane at the end is a CA lane and its j
    reads the acceleration's change per sample (0.00135 against 0.0015); the output's error is
    within 1 % of the 13 CV lanes' alone (RMSE after 2 s 0.0399 against 0.0397 deg/s: a CV
    lane's lag on a parabola is a constant the bank's slow lanes absorb). With 3 deg/s^3 the
    most likely lane is a CV one and the RMSE equal to the CV lanes' alone."""
    fs = 200.0
    n = 4000
    t = np.arange(n) / fs
    truth = 30.0 * t * t
    z = truth + 0.05 * np.random.default_rng(5).standard_normal(n)
    p = K.make_params(method="motion", sample_rate_hz=fs)
    y, s = batch.run(p, K.init_state(p), z)
    o = K.ext_offset(p)
    ncv = int(p[K.P_MO_NF])
    assert all(s[o + K.MB_J + i] == 0.0 for i in range(ncv))
    best = int(s[o + K.M_BEST])
    assert best >= ncv
    assert abs(s[o + K.MB_J + best] - 60.0 / fs ** 2) < 0.3 * 60.0 / fs ** 2     # 2 x 30 deg/s^3 / fs^2
    cv = K.make_params(method="motion", sample_rate_hz=fs)
    for i, v in enumerate(K.motion_params(fs, n_accel=0)):   # the default's CV lanes alone
        cv[K.P_MO_NF + i] = v
    ycv, _ = batch.run(cv, K.init_state(cv), z)
    assert rmse(y, truth, fs) < 1.01 * rmse(ycv, truth, fs)
