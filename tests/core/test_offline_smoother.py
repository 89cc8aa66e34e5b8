"""The offline form of ``method="motion"`` (batch.smooth_motion, batch.run_offline): the
two-filter smoother of one constant-velocity model against the batch least-squares solution
(linear-Gaussian, no bank), the plain-Python path against the compiled one, sessions, and the
invariants (finite output for finite input, inside the input's envelope) on seeded
hypothesis records."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import gyrodenoise as gd
from gyrodenoise.core import batch
from gyrodenoise.core import kernels as K
from gyrodenoise.io.recording import ABSURD_RATE_DEG_S

F = np.array([[1.0, 1.0], [0.0, 1.0]])
GQ = np.array([[0.25, 0.5], [0.5, 1.0]])        # white-noise acceleration, per lam^2 R


def _kf(z, lam2, m0, p0):
    """Exact Kalman filter of the CV model (R = 1): filtered means and covariances."""
    x, p = np.array(m0, float), np.array(p0, float)
    xs, ps = [], []
    for k, zk in enumerate(z):
        if k:
            x, p = F @ x, F @ p @ F.T + lam2 * GQ
        s = p[0, 0] + 1.0
        g = p[:, 0] / s
        x, p = x + g * (zk - x[0]), p - np.outer(g, p[0])
        xs.append(x)
        ps.append(p)
    return np.array(xs), np.array(ps)


def _batch_ls(z, lam2, m0, p0, m1, p1):
    """The batch least-squares (information-form) solution of the same problem, in the
    unknowns theta = (x_0, w_0 .. w_{n-2}) (x_{k+1} = F x_k + (1/2, 1) w_k, w_k of variance
    lam2): the measurements, the process noise, and a prior on the first and on the last
    state, all in one normal equation. Returns the smoothed rates."""
    n = z.size
    g = np.array([0.5, 1.0])
    t = np.zeros((n, 2, n + 1))               # x_k = t[k] @ theta
    t[0, :, :2] = np.eye(2)
    for k in range(1, n):
        t[k] = F @ t[k - 1]
        t[k, :, 2 + k - 1] += g
    a = np.zeros((n + 1, n + 1))
    b = np.zeros(n + 1)
    h = t[:, 0, :]                            # the rates
    a += h.T @ h
    b += h.T @ z
    a[2:, 2:] += np.eye(n - 1) / lam2
    for i, m, p in ((0, m0, p0), (n - 1, m1, p1)):
        w = np.linalg.inv(p)
        a += t[i].T @ w @ t[i]
        b += t[i].T @ w @ np.asarray(m, float)
    return h @ np.linalg.solve(a, b)


@pytest.mark.parametrize("lam", [1e-3, 0.05, 1.0])
def test_two_filter_rate_equals_the_batch_least_squares_solution(lam):
    """A single constant-velocity model (no bank), R = 1: the forward Kalman filter from a
    prior on the first state, the same filter on the reversed samples from a prior on the
    last one, combined per sample by batch.two_filter_rate (Eq. S1), equal the batch
    least-squares solution of all samples and both priors to 1e-9."""
    rng = np.random.default_rng(3)
    n, lam2 = 120, lam * lam
    x = np.zeros((n, 2))
    x[0] = (1.0, 0.1)
    for k in range(1, n):
        x[k] = F @ x[k - 1] + lam * np.array([0.5, 1.0]) * rng.standard_normal()
    z = x[:, 0] + rng.standard_normal(n)
    m0, p0 = (0.5, 0.0), np.diag([4.0, 0.5])
    m1, p1 = (z[-1], 0.0), np.diag([3.0, 0.3])
    xf, pf = _kf(z, lam2, m0, p0)
    j = np.diag([1.0, -1.0])                 # reversed time: slope sign
    xb, pb = _kf(z[::-1], lam2, j @ m1, j @ p1 @ j)
    xb, pb = xb[::-1], pb[::-1]
    ref = _batch_ls(z, lam2, m0, p0, m1, p1)
    k = np.arange(n - 1)
    rate, ll, chi2, var = batch.two_filter_rate((xf[k, 0], xf[k, 1]), (pf[k, 0, 0], pf[k, 0, 1], pf[k, 1, 1]),
                                     (xb[k + 1, 0], xb[k + 1, 1]),
                                     (pb[k + 1, 0, 0], pb[k + 1, 0, 1], pb[k + 1, 1, 1]), lam2, 1.0)
    np.testing.assert_allclose(rate, ref[:-1], rtol=0, atol=1e-9 * max(1.0, np.abs(ref).max()))
    assert np.all(np.isfinite(ll)) and np.all(chi2 >= 0.0)
    assert np.all((var > 0.0) & (var < pf[k, 0, 0]))     # both halves: below the forward variance
    assert np.abs(xf[:-1, 0] - ref[:-1]).max() > 1e-3     # the forward filter alone is not it


def _session(n, fs, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    truth = 5.0 * np.sin(2.0 * np.pi * 0.4 * t) + np.where(t > n / fs / 2, 3.0, 0.0)
    return truth + 0.3 * rng.standard_normal(n), truth


def test_offline_smoother_python_equals_compiled_and_each_session_is_on_its_own():
    """batch.run_offline compiled and plain Python give the same bits (the bank is stepped by
    the C core or the Python kernels, equal bit for bit, and the combination is the same
    numpy); with restarts, each session equals the smoother of that session alone."""
    fs = 100.0
    z, _ = _session(900, fs, 1)
    rs = np.zeros(z.size, dtype=bool)
    rs[500] = True
    p = K.make_params(3, "motion", sample_rate_hz=fs, warmup_s=1.0)
    a = batch.run_offline(p, z, rs)
    b = batch.run_offline(p, z, rs, compiled=False)
    assert a.tolist() == b.tolist()
    for lo, hi in ((0, 500), (500, 900)):
        assert a[lo:hi].tolist() == batch.smooth_motion(p, z[lo:hi]).tolist()
    assert a.tolist() == gd.denoise(z, fs, restarts=rs, offline=True).tolist()


def test_offline_smoother_beats_the_causal_blend_it_replaced():
    """On a seeded record (sine + step, 20 s at 100 Hz) the smoother's RMSE is below that of
    the forward/backward causal blend it replaced (batch._blend) and of raw."""
    fs = 100.0
    z, truth = _session(2000, fs, 2)
    p = K.make_params(3, "motion", sample_rate_hz=fs)
    y = batch.smooth_motion(p, z)
    pv = list(p)
    pv[K.P_MO_VAR] = 1.0
    old = batch._blend(pv, z, True)
    i = slice(200, -200)

    def err(v):
        return float(np.sqrt(np.mean((v[i] - truth[i]) ** 2)))
    assert err(y) < err(old) < err(z)


def test_non_finite_samples_pass_through_and_the_rest_stays_finite():
    """A NaN and an inf inside a session: the output there is the sample (as the causal form
    gives), finite everywhere else, inside the envelope of the finite samples."""
    fs = 100.0
    z, _ = _session(600, fs, 4)
    z[250] = np.nan
    z[400] = np.inf
    y = gd.denoise(z, fs, offline=True)
    fin = np.isfinite(z)
    assert np.isnan(y[250]) and y[400] == np.inf
    assert np.all(np.isfinite(y[fin]))
    assert y[fin].min() >= z[fin].min() and y[fin].max() <= z[fin].max()


SETTINGS = dict(derandomize=True, deadline=None, database=None, max_examples=40,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
FINITE = st.floats(-ABSURD_RATE_DEG_S, ABSURD_RATE_DEG_S, allow_nan=False, allow_infinity=False)


@st.composite
def records(draw):
    n = draw(st.integers(20, 300))
    if draw(st.booleans()):
        z = np.array(draw(st.lists(FINITE, min_size=n, max_size=n)), dtype=float)
    else:
        rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
        z = draw(st.floats(-1e3, 1e3)) + 10.0 ** draw(st.integers(-9, 3)) * rng.standard_normal(n)
        for _ in range(draw(st.integers(0, 3))):
            z[draw(st.integers(0, n - 1))] = draw(FINITE)
    rs = np.zeros(n, dtype=bool)
    for i in draw(st.lists(st.integers(0, n - 1), max_size=2)):
        rs[i] = True
    return z, rs


@settings(**SETTINGS)
@given(rec=records())
def test_offline_output_is_finite_and_inside_each_sessions_envelope(rec):
    """Finite input: finite output, never outside [min, max] of its session's samples."""
    z, rs = rec
    p = K.make_params(3, "motion", sample_rate_hz=100.0, warmup_s=0.1)
    y = batch.run_offline(p, z, rs)
    assert np.all(np.isfinite(y))
    bounds = [0] + [int(i) for i in np.flatnonzero(rs) if i > 0] + [z.size]
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        assert y[lo:hi].min() >= z[lo:hi].min() and y[lo:hi].max() <= z[lo:hi].max()


def test_blocks_of_the_combination_do_not_change_a_bit(monkeypatch):
    """batch.SMOOTH_BLOCK only bounds the temporaries: blocks of 97 samples give the same bits."""
    fs = 100.0
    z, _ = _session(700, fs, 5)
    p = K.make_params(3, "motion", sample_rate_hz=fs, warmup_s=1.0)
    ref = batch.smooth_motion(p, z)
    monkeypatch.setattr(batch, "SMOOTH_BLOCK", 97)
    assert batch.smooth_motion(p, z).tolist() == ref.tolist()
