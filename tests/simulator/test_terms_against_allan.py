"""The simulated gyro: each term alone against its analytic Allan curve (IEEE 952)."""
import math

import numpy as np
import pytest

import gyrodenoise as gd
from gyrodenoise.analysis import allan as A
from gyrodenoise.errors import InputError
from gyrodenoise.simulator import SimStream, parse_card

FS = 100.0


def card(terms, fs=FS):
    return parse_card(f"[sensor]\nsample_rate_hz = {fs}\n[terms]\n{terms}\n", "test")


def adev_of(terms, n, m, seed=1, fs=FS):
    rec = gd.simulate(card(terms, fs), n, seed=seed)
    return A.adev(rec.rate_deg_s, fs, m=m)


def test_quantization():
    Q = 2e-4     # deg
    tau, ad, err, _ = adev_of(f"quantization = {{ Q = {Q} }}", 200_000, [1, 4, 16, 64])
    np.testing.assert_allclose(ad, np.sqrt(3) * Q / tau, rtol=0.03)


def test_angle_random_walk():
    N = 0.5      # deg/sqrt(h)
    tau, ad, err, _ = adev_of(f"angle_random_walk = {{ N = {N} }}", 200_000, [1, 10, 100, 1000])
    np.testing.assert_allclose(ad, (N / 60.0) / np.sqrt(tau), rtol=0.05)


def test_bias_instability_plateau_is_0664_B():
    B = 10.0     # deg/h
    tau, ad, err, _ = adev_of(f"bias_instability = {{ B = {B} }}", 1_000_000, [100, 300, 1000, 3000, 10000],
                              seed=3)
    plateau = math.sqrt(2 * math.log(2) / math.pi) * B / 3600.0   # 0.664 B
    np.testing.assert_allclose(ad, plateau, rtol=0.12)


def test_rate_random_walk():
    K = 50.0     # deg/h^1.5
    tau, ad, err, _ = adev_of(f"rate_random_walk = {{ K = {K} }}", 400_000, [100, 1000, 10000], seed=4)
    np.testing.assert_allclose(ad, K / 3600 ** 1.5 * np.sqrt(tau / 3.0), rtol=0.2)


def test_rate_ramp_is_exact():
    R = 3600.0   # deg/h^2
    tau, ad, err, _ = adev_of(f"rate_ramp = {{ R = {R} }}", 10_000, [10, 100, 1000])
    np.testing.assert_allclose(ad, R / 3600 ** 2 * tau / np.sqrt(2.0), rtol=1e-6)


def test_gauss_markov_and_sinusoid():
    rec = gd.simulate(card("[[terms.gauss_markov]]\nsigma = 36.0\ntau = 0.5\n"), 400_000, seed=2)
    assert np.std(rec.rate_deg_s) == pytest.approx(0.01, rel=0.05)
    rec = gd.simulate(card("[[terms.sinusoid]]\namplitude = 3600.0\nfrequency = 2.0\n"), 1000)
    t = np.arange(1000) / FS
    np.testing.assert_allclose(rec.rate_deg_s, np.sin(2 * np.pi * 2.0 * t), atol=1e-12)


def test_angle_gauss_markov_reads_as_the_readme_says():
    """docs/method/model-cards.md: an angle Gauss-Markov term (sigma deg, tau s) is an angle error that
    stays within +-sigma (std sigma) instead of walking away; averaged over much less than tau it
    is white rate noise with N = sigma sqrt(2 / tau) (deg/sqrt(s)), over much more than tau it is
    white angle noise with Q = sigma; the rate's PSD rises like f^2 below 1 / (2 pi tau) and is
    flat above it, at 2 sigma^2 / tau. Checked on one seeded simulation against those limits (the
    exact curve, spectral.angle_gm_avar, is checked in tests/modelgap)."""
    from scipy.signal import welch
    sigma, tau_c, fs, n = 0.01, 1.0, 100.0, 400_000
    rec = gd.simulate(card(f"[[terms.angle_gauss_markov]]\nsigma = {sigma}\ntau = {tau_c}\n", fs), n, seed=3)
    angle = np.cumsum(rec.rate_deg_s) / fs
    assert np.std(angle) == pytest.approx(sigma, rel=0.05)
    tau, ad, err, _ = A.adev(rec.rate_deg_s, fs, m=[1, 2, 5, 10])             # 0.01-0.1 s << tau
    np.testing.assert_allclose(ad, sigma * math.sqrt(2.0 / tau_c) / np.sqrt(tau), rtol=0.02)
    tau, ad, err, _ = A.adev(rec.rate_deg_s, fs, m=[2000, 4000, 8000])       # 20-80 s >> tau
    np.testing.assert_allclose(ad, math.sqrt(3.0) * sigma / tau, rtol=0.15)
    f, p = welch(rec.rate_deg_s, fs=fs, nperseg=8192)                         # one-sided, (deg/s)^2/Hz
    flat = (f > 5.0) & (f < 20.0)       # >> 1 / (2 pi tau) = 0.16 Hz, well below Nyquist
    assert np.mean(p[flat]) / 2.0 == pytest.approx(2.0 * sigma ** 2 / tau_c, rel=0.1)
    f, p = welch(rec.rate_deg_s, fs=fs, nperseg=65536)
    low = (f > 0.01) & (f < 0.04)       # << 0.16 Hz: rises like f^2
    assert np.mean(p[low] / f[low] ** 2) / 2.0 == pytest.approx(2.0 * sigma ** 2 * tau_c * (2 * np.pi) ** 2, rel=0.3)


def test_stream_equals_batch_with_true_rate_and_restarts():
    c = gd.load_card("paper_fog")
    c = parse_card(c.text + "turn_on_transient = { amplitude = 1.0, tau = 3.0 }\n", "t")
    c.terms["constant_bias"]["repeatability"] = 0.5
    n = 9000
    rs = np.zeros(n, dtype=bool)
    rs[[0, 3000, 8500]] = True
    truth = np.linspace(-5, 5, n)
    rec = gd.simulate(c, n, seed=9, true_rate_deg_s=truth, restarts=rs)
    s = SimStream(c, seed=9)
    y = np.array([s.step(t, r) for t, r in zip(truth, rs)])
    np.testing.assert_allclose(y, rec.rate_deg_s, rtol=0, atol=1e-12)


def test_restart_draws_a_fresh_turn_on_bias():
    c = parse_card("[sensor]\nsample_rate_hz = 10.0\n[terms]\nconstant_bias = { value = 0.0, repeatability = 36.0 }\n")
    rs = np.zeros(300, dtype=bool)
    rs[100] = rs[200] = True
    y = gd.simulate(c, 300, seed=1, restarts=rs).rate_deg_s
    levels = [y[0], y[100], y[200]]
    assert np.all(y[:100] == levels[0]) and np.all(y[100:200] == levels[1])
    assert len(set(levels)) == 3


def test_seeded_and_reproducible():
    a = gd.simulate("paper_fog", 5000, seed=1).rate_deg_s
    b = gd.simulate("paper_fog", 5000, seed=1).rate_deg_s
    c = gd.simulate("paper_fog", 5000, seed=2).rate_deg_s
    assert np.array_equal(a, b) and not np.array_equal(a, c)


@pytest.mark.parametrize("text,needle", [
    ("[sensor]\nsample_rate_hz = 100\n[terms]\nwobble = { x = 1 }\n", "unknown term terms.wobble"),
    ("[sensor]\nsample_rate_hz = 100\n[terms]\nangle_random_walk = { }\n", "missing the field N"),
    ("[sensor]\nsample_rate_hz = 100\n[terms]\nangle_random_walk = { N = -1 }\n", "must be >= 0"),
    ("[sensor]\nsample_rate_hz = 100\n[terms]\nangle_random_walk = { N = 1e30 }\n", "not a usable number"),
    ("[sensor]\nsample_rate_hz = -5\n", "sample_rate_hz"),
    ("[terms]\n", "missing [sensor]"),
    ("[sensor]\nsample_rate_hz = 100\n[terms]\nangle_random_walk = { N = 'a' }\n", "must be a number"),
    ("[sensor\n", "not valid TOML"),
    ("[sensor]\nsample_rate_hz = 100\n[terms]\n[[terms.sinusoid]]\namplitude = 1\nfrequency = 80\n", "Nyquist"),
])
def test_bad_cards_get_one_line(text, needle):
    with pytest.raises(InputError) as exc:
        parse_card(text, "card.toml")
    msg = str(exc.value)
    assert needle in msg and msg.startswith("card.toml: ") and "\n" not in msg


def test_restarts_must_be_one_bool_per_sample():
    """restarts given as indices ([3, 7]) are refused, not read as booleans for the first samples."""
    import gyrodenoise as gd
    from gyrodenoise.errors import InputError
    with pytest.raises(InputError, match="one bool per sample"):
        gd.simulate("paper_fog", 10, restarts=[3, 7])
