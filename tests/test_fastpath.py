"""The specialised batch loop (gyrodenoise.fastkernels) against the generic one.

batch.run dispatches the common case (compiled, no diagnostics, no theta
history) to fastkernels.run_local. It must give the outputs AND the final
state of the generic compiled loop of kernels.step (``fast=False``) and of the
plain-Python per-sample path, to 1e-12 relative (it performs the same
floating-point operations in the same order, so in practice they are equal
bit for bit), whatever happens in the record: steps, wild samples with the
outlier gate on and off, runs of rejections that re-open the filter, restarts
(also inside the warm-up and back to back), and records split anywhere with
the state carried over.
"""
import numpy as np
import pytest

from gyrodenoise import kernels as K
from gyrodenoise.batch import run
from gyrodenoise.denoiser import Denoiser

RTOL = 1e-12
METHODS = ["shakf", "kf", "sh_classic", "none"]


def eventful(seed=0):
    """Noise on a mean, a rate step, wild samples, a short real step, restarts."""
    n = 5000
    rng = np.random.default_rng(seed)
    z = 0.5 + 0.01 * rng.standard_normal(n)
    z[n // 3:] += 2.0                                  # a rate step
    for i in (700, 1100, 1900, 2300, 3200, 3700, 4200, 4600):     # wild samples
        z[i] += rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 50.0)
    z[3 * n // 5:3 * n // 5 + 60] += 5.0               # a short real step (gate re-opens)
    rs = np.zeros(n, dtype=bool)
    rs[0] = True
    rs[n // 2] = True                                  # a restart
    rs[n // 2 + 40] = True                             # another inside the warm-up
    rs[n // 2 + 41] = True                             # and back to back
    return z, rs


def same(a, b):
    np.testing.assert_allclose(a, b, rtol=RTOL, atol=0)


@pytest.mark.parametrize("gate", [0.0, 4.0])
@pytest.mark.parametrize("order", [1, 3, 6])
@pytest.mark.parametrize("method", METHODS)
def test_fast_equals_generic_and_plain(method, order, gate):
    z, rs = eventful(seed=order)
    p = K.make_params(ar_order=order, method=method, warmup_s=0.4, outlier_sigma=gate,
                      outlier_run=15)
    fast, sf = run(p, K.init_state(p), z, rs)
    gen, sg = run(p, K.init_state(p), z, rs, fast=False)
    same(fast, gen)
    same(sf, sg)
    plain, sp = run(p, K.init_state(p), z[:2500], rs[:2500], compiled=False)
    f2, sf2 = run(p, K.init_state(p), z[:2500], rs[:2500])
    same(f2, plain)
    same(sf2, sp)
    if gate > 0.0 and method != "none":
        # the record exercised what it is meant to
        assert sf[K.S_NREJ] >= 3 and sf[K.S_NREOPEN] >= 1, (sf[K.S_NREJ], sf[K.S_NREOPEN])
    if method == "shakf" and gate == 0.0:
        assert sf[K.S_NRESET] >= 1                     # Eq. (32) restarts of d_k happened


@pytest.mark.parametrize("method", METHODS)
def test_split_runs_carry_the_state(method):
    """Cut inside the warm-up, exactly at its end, inside a run of rejections,
    at a restart, one sample before the end; the pieces equal the generic whole."""
    z, rs = eventful(seed=11)
    p = K.make_params(ar_order=3, method=method, warmup_s=0.4, outlier_sigma=4.0,
                      outlier_run=15)
    whole, s_whole = run(p, K.init_state(p), z, rs, fast=False)
    warm = int(p[K.P_WARMUP])
    cuts = sorted({0, 1, 7, warm - 1, warm, warm + 1, 3 * z.size // 5 + 5, z.size // 2,
                   z.size // 2 + 41, z.size - 1, z.size})
    s = K.init_state(p)
    pieces = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        y, s = run(p, s, z[a:b], rs[a:b])
        pieces.append(y)
    same(np.concatenate(pieces), whole)
    same(s, s_whole)


def test_fast_path_continues_a_per_sample_state():
    """A Denoiser stepped sample by sample (list state), then batch-processed."""
    z, rs = eventful(seed=5)
    d = Denoiser(200.0, method="shakf", ar_order=3, warmup_s=0.4, outlier_sigma=4.0)
    head = [d.step(v, r) for v, r in zip(z[:700], rs[:700])]
    tail = d.process(z[700:], rs[700:])
    p = d.params
    ref, s_ref = run(p, K.init_state(p), z, rs, fast=False)
    same(np.concatenate([head, tail]), ref)
    same(np.asarray(d.state), s_ref)


@pytest.mark.parametrize("seed", range(6))
def test_random_parameters_and_records(seed):
    """Random orders, methods, parameters and heavy-tailed records with random restarts."""
    rng = np.random.default_rng(100 + seed)
    order = int(rng.integers(1, 7))
    method = METHODS[seed % 4]
    p = K.make_params(ar_order=order, method=method, sample_rate_hz=float(rng.uniform(50, 400)),
                      lam=float(rng.choice([1.0, 0.999, 0.99])), b=float(rng.uniform(0.9, 0.999)),
                      gamma=float(rng.uniform(1.0, 5.0)),
                      q0=float(rng.choice([0.0, 1e-6])), r0=float(rng.choice([0.0, 1e-4])),
                      warmup_s=float(rng.uniform(0.0, 1.0)),
                      outlier_sigma=float(rng.choice([0.0, 2.0, 5.0])),
                      outlier_run=int(rng.integers(1, 30)))
    n = 4000
    z = np.cumsum(1e-3 * rng.standard_normal(n)) + rng.standard_t(2, n) * 0.05
    z[rng.integers(0, n, 10)] *= 100.0
    rs = rng.random(n) < 2e-3
    fast, sf = run(p, K.init_state(p), z, rs)
    gen, sg = run(p, K.init_state(p), z, rs, fast=False)
    same(fast, gen)
    same(sf, sg)


def test_degenerate_records():
    """Empty input returns the state unchanged; constant and zero records agree."""
    p = K.make_params(method="shakf")
    s0 = np.asarray(K.init_state(p))
    y, s = run(p, s0, np.empty(0))
    assert y.shape == (0,)
    np.testing.assert_array_equal(s, s0)
    for z in (np.zeros(1500), np.full(1500, 3.0)):
        fast, sf = run(p, K.init_state(p), z)
        gen, sg = run(p, K.init_state(p), z, fast=False)
        same(fast, gen)
        same(sf, sg)


def test_diagnostics_and_theta_still_use_the_generic_loop():
    """The options the fast loop does not record give the same outputs as it."""
    z, rs = eventful(seed=2)
    p = K.make_params(method="shakf", warmup_s=0.4, outlier_sigma=4.0)
    fast, sf = run(p, K.init_state(p), z, rs)
    d_out, d_s, diag = run(p, K.init_state(p), z, rs, diagnostics=True)
    t_out, t_s, theta = run(p, K.init_state(p), z, rs, record_theta=True)
    for y, st in ((d_out, d_s), (t_out, t_s)):
        same(y, fast)
        same(st, sf)
    assert diag.shape == (z.size, 4) and theta.shape == (z.size, 4)
    same(theta[-1], np.asarray(K.phi(p, sf) + [K.rls_c(p, sf)]))   # c in deg/s (uncentred)


def test_asymmetric_state_falls_back_to_the_generic_loop():
    """The fast loop reads the upper triangles of the covariances (every state
    the kernels make is symmetric); a state that is not goes the generic way."""
    from gyrodenoise import fastkernels as F
    z, rs = eventful(seed=9)
    p = K.make_params(method="shakf", warmup_s=0.4)
    _, s = run(p, K.init_state(p), z[:1000])
    assert F.symmetric_state(s, 3)
    o_p = K.layout(3)[3]
    s[o_p + 1] *= 1.0 + 1e-9                          # P[0][1] != P[1][0]
    assert not F.symmetric_state(s, 3)
    fast, sf = run(p, s, z[1000:], rs[1000:])
    gen, sg = run(p, s, z[1000:], rs[1000:], fast=False)
    same(fast, gen)
    same(sf, sg)


def test_dispatch_goes_to_the_fast_loop_only_where_it_applies(monkeypatch):
    """batch.run calls the fast loop for the common case, and not for orders
    above MAX_ORDER, diagnostics, theta history, fast=False or compiled=False."""
    from gyrodenoise import fastkernels as F
    calls = []
    real = F.run_local_fast

    def spy(*args):
        calls.append(len(args[-1]) - 1)
        return real(*args)
    monkeypatch.setattr(F, "run_local_fast", spy)
    z, rs = eventful(seed=4)
    z, rs = z[:1500], rs[:1500]
    p = K.make_params(ar_order=3, method="shakf", warmup_s=0.4)
    run(p, K.init_state(p), z, rs)
    assert calls == [3]
    run(p, K.init_state(p), z, rs, diagnostics=True)
    run(p, K.init_state(p), z, rs, record_theta=True)
    run(p, K.init_state(p), z, rs, fast=False)
    run(p, K.init_state(p), z[:50], rs[:50], compiled=False)
    assert calls == [3]
    big = K.make_params(ar_order=F.MAX_ORDER + 1, method="shakf", warmup_s=0.4)
    y, _ = run(big, K.init_state(big), z, rs)
    assert calls == [3] and np.all(np.isfinite(y))
