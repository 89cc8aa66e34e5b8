"""The per-sample kernels: both speeds agree, invariants hold, bad parameters refused."""
import math

import numpy as np
import pytest

from gyrodenoise import kernels as K
from gyrodenoise.batch import run
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


def test_warmup_passes_raw_through_and_flags_convergence():
    z = np.random.default_rng(2).standard_normal(1000)
    d = Denoiser(200.0, warmup_s=1.0)
    out = [d.step(v) for v in z[:200]]
    assert out == list(z[:200]) and not d.converged
    d.step(z[200])
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
