"""The per-sample kernels: both speeds agree, invariants hold, bad parameters refused."""
import math

import numpy as np
import pytest

from gyrodenoise.core import kernels as K
from gyrodenoise.core.batch import run
from gyrodenoise.denoiser import Denoiser


def signal(n=6000, seed=0):
    rng = np.random.default_rng(seed)
    z = 0.5 + 0.01 * rng.standard_normal(n)
    z[n // 3:] += 2.0                       # a rate step
    z[n // 2] += 5.0                        # a wild sample
    restarts = np.zeros(n, dtype=bool)
    restarts[2 * n // 3] = True
    return z, restarts


@pytest.mark.parametrize("method", ["shakf", "kf", "none", "sh_classic"])
@pytest.mark.parametrize("order", [1, 3, 6])
def test_compiled_and_plain_paths_agree(method, order):
    z, rs = signal()
    p = K.make_params(ar_order=order, method=method, warmup_s=0.5)
    fast, sf = run(p, K.init_state(p), z, rs, compiled=True)
    plain, sp = run(p, K.init_state(p), z, rs, compiled=False)
    np.testing.assert_allclose(fast, plain, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sf, sp, rtol=1e-12, atol=1e-15)
    # and the Denoiser's per-sample step (plain Python lists) gives the same
    d = Denoiser(200.0, method=method, ar_order=order, warmup_s=0.5)
    steps = np.array([d.step(v, r) for v, r in zip(z[:1500], rs[:1500])])
    np.testing.assert_allclose(steps, fast[:1500], rtol=0, atol=1e-12)


def test_split_run_equals_one_run():
    z, rs = signal(seed=3)
    p = K.make_params(method="shakf")
    whole, s_whole = run(p, K.init_state(p), z, rs)
    a, s_mid = run(p, K.init_state(p), z[:2500], rs[:2500])
    b, s_end = run(p, s_mid, z[2500:], rs[2500:])
    np.testing.assert_array_equal(np.concatenate([a, b]), whole)
    np.testing.assert_array_equal(s_end, s_whole)


def test_restarting_twice_equals_restarting_once():
    z, _ = signal(seed=4)
    p = K.make_params(method="shakf")
    once = [0] * len(z)
    s = K.init_state(p)
    for i, v in enumerate(z):
        once[i] = K.step(p, s, float(v), i == 1000)
    s2 = K.init_state(p)
    twice = [0] * len(z)
    for i, v in enumerate(z):
        if i == 1000:
            K.restart(p, s2)
        twice[i] = K.step(p, s2, float(v), i == 1000)
    assert once == twice


@pytest.mark.parametrize("method", ["shakf", "kf", "sh_classic"])
def test_covariance_stays_spd_and_r_positive(method):
    rng = np.random.default_rng(11)
    z = np.concatenate([rng.standard_normal(2000) * 1e-3, rng.standard_normal(2000) * 10 + 50,
                        np.full(500, 3.0), rng.standard_normal(1000) * 1e3])
    z[3000] = 1e6
    p = K.make_params(method=method, ar_order=3)
    s = K.init_state(p)
    for i, v in enumerate(z):
        y = K.step(p, s, float(v), False)
        assert math.isfinite(y)
        if i % 97 == 0 or i == 3000:
            P = np.array(K.filter_cov(p, s))
            assert np.allclose(P, P.T, rtol=0, atol=0)
            assert np.all(np.linalg.eigvalsh(P) > 0), (i, np.linalg.eigvalsh(P))
            assert s[K.S_R] > 0 and s[K.S_Q] >= 0


@pytest.mark.parametrize("method, warm, raw", [("shakf", 200, 200), ("motion", K.MO_SPEC_N - 1, int(K.MO_WU_N0) - 1)])
def test_warmup_passes_raw_through_and_flags_convergence(method, warm, raw):
    """The AR methods pass warmup_s (1 s: 200 samples at 200 Hz) through raw; motion ends its
    warm-up earlier, once its noise floor has read its first block (at its last sample), and
    passes raw samples only until its warm-up output's test has MO_WU_N0 samples."""
    z = np.random.default_rng(2).standard_normal(1000)
    d = Denoiser(200.0, method=method, warmup_s=1.0)
    out = [d.step(v) for v in z[:warm]]
    assert out[:raw] == list(z[:raw]) and not d.converged
    d.step(z[warm])
    assert d.converged


@pytest.mark.parametrize("kw", [{"ar_order": 0}, {"b": 1.0}, {"b": 0.0}, {"gamma": 0.5},
                                {"q0": -1.0}, {"r0": -1e-3}, {"p0_kf": 0.0}, {"lam": 1.5},
                                {"method": "ukf"}, {"ar_order": 2.5}, {"sample_rate_hz": float("nan")}])
def test_bad_parameters_are_refused_with_a_reason(kw):
    with pytest.raises(ValueError) as exc:
        K.make_params(**kw)
    assert "\n" not in str(exc.value)
    assert list(kw)[0] in str(exc.value)


def test_sage_husa_weight_follows_the_closed_form():
    """d_k kept by multiplication equals (1-b)/(1-b^(k+1)), resets included."""
    z = 0.01 * np.random.default_rng(8).standard_normal(3000)
    z[2000] = 50.0                             # violates Eq. (32): d restarts from k = 0
    p = K.make_params(method="shakf", b=0.97)
    s = K.init_state(p)
    for v in z:
        K.step(p, s, float(v), False)
        if s[K.S_CONV] == 1.0:
            assert s[K.S_BK] == pytest.approx(0.97 ** (s[K.S_KD] + 1), rel=1e-9, abs=1e-300)
    assert s[K.S_NRESET] >= 1


# ---------------------------------------------------------------- outlier gate
def _spiky(seed=3, n=40_000, n_spikes=20):
    """Known truth: paper_fog at a constant 2 deg/s, 200 Hz, with injected spikes."""
    import gyrodenoise as gd
    rec = gd.simulate("paper_fog", n, seed=seed, true_rate_deg_s=2.0)
    rng = np.random.default_rng(seed)
    z = rec.rate_deg_s.copy()
    where = np.sort(rng.choice(np.arange(1000, n - 1000, 50), n_spikes, replace=False))
    z[where] += rng.choice([-1.0, 1.0], n_spikes) * rng.uniform(5.0, 20.0, n_spikes)
    return z, rec.rate_deg_s, where


def test_gate_rejects_injected_spikes_and_matches_the_clean_run():
    """Each spike (5..20 deg/s on 0.0036 deg/s noise) is rejected and the output
    there is the prediction. Against the same filter on the clean record: max
    difference < 1e-3 deg/s (at a spike sample: prediction vs update; measured
    6e-4), RMS difference < 1e-5 deg/s (measured 4.3e-6), and the RMSE against the
    truth within 1 % of the clean run's. Without the gate the spikes make the RMSE
    more than 10x worse (measured 3.1e-3 vs 1.4e-4 deg/s)."""
    z, clean, where = _spiky()
    p = K.make_params(method="shakf", outlier_sigma=5.0)
    out, s = run(p, K.init_state(p), z)
    ref, _ = run(p, K.init_state(p), clean)
    assert s[K.S_NREOPEN] == 0
    assert len(where) <= s[K.S_NREJ] <= len(where) + 3      # + rare 5-sigma noise samples
    assert np.max(np.abs(out - ref)) < 1e-3
    assert np.sqrt(np.mean((out - ref) ** 2)) < 1e-5
    assert np.max(np.abs(out[where] - 2.0)) < 2e-3            # prediction, not the spike
    rmse = lambda y: np.sqrt(np.mean((y[1000:] - 2.0) ** 2))  # noqa: E731
    assert rmse(out) < 1.01 * rmse(ref)
    p_off = K.make_params(method="shakf", outlier_sigma=0.0)
    off, _ = run(p_off, K.init_state(p_off), z)
    assert rmse(off) > 10 * rmse(ref)


def test_gate_reopens_on_a_real_step_and_shortens_the_lag():
    """A 10 deg/s step is not an outlier: after outlier_run rejections the filter
    restarts there, so the output reaches 90 % within outlier_run samples + 1 (the
    warm-up then passes the raw sample), where the ungated SHAKF needs > 100 s."""
    import gyrodenoise as gd
    from gyrodenoise.analysis.experiments import rise_time
    fs, n = 200.0, 120_000
    truth = np.zeros(n)
    truth[n // 2:] = 10.0
    z = gd.simulate("paper_fog", n, seed=1, true_rate_deg_s=truth).rate_deg_s
    t = np.arange(n) / fs
    p = K.make_params(method="shakf", outlier_sigma=5.0, outlier_run=20)
    on, s = run(p, K.init_state(p), z)
    assert s[K.S_NREOPEN] == 1 and s[K.S_NREJ] == 20
    assert rise_time(on, t, t[n // 2], 10.0) <= 21 / fs
    p_off = K.make_params(method="shakf", outlier_sigma=0.0)
    off, _ = run(p_off, K.init_state(p_off), z)
    assert rise_time(off, t, t[n // 2], 10.0) is None or rise_time(off, t, t[n // 2], 10.0) > 100.0
    # after the re-identification the output is filtered again (std well below raw)
    tail = slice(n // 2 + 4000, n)
    assert np.std(on[tail]) < 0.2 * np.std(z[tail])


@pytest.mark.parametrize("method", ["shakf", "kf", "sh_classic"])
def test_gate_paths_agree_and_counters_survive_restarts(method):
    z, _, where = _spiky(seed=5, n=8000, n_spikes=6)
    z[5000:5100] += 8.0                                    # a short real step: re-opens
    rs = np.zeros(z.size, bool)
    rs[6000] = True
    p = K.make_params(method=method, outlier_sigma=4.0, outlier_run=10)
    fast, sf = run(p, K.init_state(p), z, rs)
    plain, sp = run(p, K.init_state(p), z, rs, compiled=False)
    np.testing.assert_allclose(fast, plain, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sf, sp, rtol=1e-12, atol=1e-15)
    assert sf[K.S_NREJ] >= 6 and sf[K.S_NREOPEN] >= 1
    d = Denoiser(200.0, method=method, outlier_sigma=4.0, outlier_run=10)
    d.process(z[:6000], rs[:6000])
    before = d.n_rejected
    d.step(z[6000], restart=True)
    assert d.n_rejected == before                           # kept by a restart


def test_gate_off_is_the_papers_filter():
    """outlier_sigma = 0: no sample is ever rejected, whatever the input."""
    z, _, _ = _spiky(seed=7, n=6000)
    p = K.make_params(method="shakf", outlier_sigma=0.0)
    _, s = run(p, K.init_state(p), z)
    assert s[K.S_NREJ] == 0 and s[K.S_NREOPEN] == 0


@pytest.mark.slow
def test_gate_on_real_imu4_outliers():
    """The real ADIS16405 imu4 record (100 Hz) around its outliers: with the gate
    the output within 5 s after each outlier stays within 0.01 deg/s of the
    output on the record with the outliers replaced by the median of their
    neighbours (measured 0.0034 deg/s; ungated 0.0091 deg/s, docs/bench/outliers-soak.md)."""
    from tests.helpers import shared_file
    from gyrodenoise.io.recording import read_recording
    rec = read_recording(shared_file("static", "adis16405_imu4.csv.gz"), rate_column="gyro_x")
    z = rec.rate_deg_s[:20_000]                       # the first three outliers
    med = np.median(z)
    mad = 1.4826 * np.median(np.abs(z - med))
    idx = np.flatnonzero(np.abs(z - med) > 8 * mad)
    assert idx.size == 3
    clean = z.copy()
    clean[idx] = med
    p = K.make_params(method="shakf", sample_rate_hz=100.0, outlier_sigma=5.0)
    out, s = run(p, K.init_state(p), z)
    p_off = K.make_params(method="shakf", sample_rate_hz=100.0, outlier_sigma=0.0)
    ref, _ = run(p_off, K.init_state(p_off), clean)
    assert s[K.S_NREJ] >= 1 and s[K.S_NREOPEN] == 0
    assert np.all(np.isfinite(out))
    for i in idx:
        assert np.max(np.abs(out[i:i + 500] - ref[i:i + 500])) < 0.01


# ---------------------------------------------- records built to break a denoiser
@pytest.mark.parametrize("method", ["shakf", "kf", "sh_classic"])
@pytest.mark.parametrize("offset", [1e6, 1e7, -1e7])
def test_large_offsets_are_harmless(method, offset):
    """The regression is centred (z - z_ref): 1e6/1e7 + noise filtered as well as
    the same noise alone (was NaN: sh_classic from 1e6, every method from 1e7)."""
    rng = np.random.default_rng(3)
    noise = 0.01 * rng.standard_normal(6000)
    y0 = gd_denoise(noise, method)
    y1 = gd_denoise(offset + noise, method)
    assert np.all(np.isfinite(y1))
    # same filter up to the rounding of the offset (ulp(1e7) = 2e-9)
    np.testing.assert_allclose(y1 - offset, y0, rtol=0, atol=1e-6)


def gd_denoise(z, method, **kw):
    from gyrodenoise import denoise
    return denoise(z, 200.0, method=method, **kw)


@pytest.mark.parametrize("lam,gate", [(0.99, 0.0), (0.99, 5.0), (0.999, 5.0)])
def test_forgetting_on_constant_and_quantised_records_stays_bounded(lam, gate):
    """lam < 1 wound the RLS covariance up in directions a constant record never
    excites (P ~ lam^-k: NaN from sample ~21000 at lam = 0.99). The forgetting
    is bounded by the prior's trace now."""
    rng = np.random.default_rng(5)
    for z in (np.full(30000, 0.01), np.round((0.2 + 0.01 * rng.standard_normal(30000)) / 0.01) * 0.01):
        p = K.make_params(method="shakf", sample_rate_hz=200.0, lam=lam, outlier_sigma=gate)
        out, s = run(p, K.init_state(p), z)
        assert np.all(np.isfinite(out)) and np.all(np.isfinite(s))
        assert np.all((out >= z.min()) & (out <= z.max()))
        tr = np.trace(np.array(K.rls_cov(p, s)))
        assert tr <= 4 * 1e4 * (1 + 1e-12)


def test_lone_huge_sample_with_gate_off_heals():
    """A single 1e155 sample with the gate off squared to inf and left the output
    NaN for good; now the filter restarts at that sample (counted) and is back
    to filtering after a warm-up."""
    rng = np.random.default_rng(2)
    z = 0.01 * rng.standard_normal(4000)
    z[2000] = 1e155
    p = K.make_params(method="shakf", sample_rate_hz=200.0, outlier_sigma=0.0)
    out, s = run(p, K.init_state(p), z)
    assert np.all(np.isfinite(out))
    assert s[K.S_NHEAL] >= 1
    assert s[K.S_CONV] == 1.0
    assert np.std(out[-500:]) < 0.5 * np.std(z[-500:])      # filtering again


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8])
def test_ar_stability_test_matches_the_roots(n):
    """ar_stable (Schur-Cohn step-down) against numpy's roots of z^n - phi_1 z^(n-1) - ... ."""
    rng = np.random.default_rng(n)
    w = [0.0] * n
    for _ in range(400):
        phi = rng.uniform(-2.0, 2.0, n) / np.arange(1, n + 1) ** rng.uniform(0, 1.5)
        roots = np.roots(np.r_[1.0, -phi])
        rmax = np.max(np.abs(roots))
        if abs(rmax - 1.0) < 1e-9:
            continue
        assert K.ar_stable(list(phi), 0, n, w, 0) == (rmax < 1.0), (phi, rmax)


def test_gate_holds_instead_of_extrapolating_an_unstable_model():
    """The 1e15 deg/s blow-ups: rejected samples were replaced by the AR
    prediction, which grows exponentially for an identified model with a root
    outside the unit circle. With an unstable model the rejected run now holds
    the last filtered value."""
    rng = np.random.default_rng(0)
    p = K.make_params(ar_order=2, method="shakf", sample_rate_hz=200.0, outlier_run=20)
    s = K.init_state(p)
    for v in 0.01 * rng.standard_normal(1000):
        K.step(p, s, float(v), False)
    o = K.layout(2)[0]
    s[o], s[o + 1] = 2.2, -1.0                  # roots 1.63 and 0.61: explosive
    last = s[K.S_OUT]
    outs = [K.step(p, s, 50.0 + float(v), False) for v in 0.01 * rng.standard_normal(19)]
    assert s[K.S_NREJ] == 19 and s[K.S_HOLD] == 1.0
    np.testing.assert_allclose(outs, last, rtol=0, atol=1e-12)
    # a stable model is still extrapolated (the paper-like prediction)
    s2 = K.init_state(p)
    for v in 0.01 * rng.standard_normal(1000):
        K.step(p, s2, float(v), False)
    for v in 50.0 + 0.01 * rng.standard_normal(5):
        K.step(p, s2, float(v), False)
    assert s2[K.S_HOLD] == 0.0 and s2[K.S_NREJ] == 5
