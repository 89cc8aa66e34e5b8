"""RLS identification of the improved AR(n) model against batch least squares."""
import numpy as np
import pytest

from gyrodenoise.core import kernels as K


def rls_theta(z, order, lam=1.0, p0=1e4):
    p = K.make_params(ar_order=order, method="none", lam=lam, p0_rls=p0)
    s = K.init_state(p)
    for v in z:
        K.step(p, s, float(v), False)
    return np.array(K.phi(p, s) + [K.rls_c(p, s)])


def batch_ridge(z, order, lam=1.0, p0=1e4):
    """Exact minimiser of sum lam^(N-k) e_k^2 + lam^N / p0 |theta|^2 (Eq. 5-7)
    for the samples centred on the first one (as the kernels do), with c turned
    back into deg/s of the raw samples: c = c_centred + (1 - sum phi) z_0."""
    z0 = z[0]
    th = _batch_ridge(np.asarray(z) - z0, order, lam, p0)
    th[order] += (1.0 - th[:order].sum()) * z0
    return th


def _batch_ridge(z, order, lam, p0):
    n = len(z)
    rows = np.array([[z[k - j] for j in range(1, order + 1)] + [1.0] for k in range(order, n)])
    y = np.asarray(z[order:])
    w = lam ** np.arange(len(y) - 1, -1, -1)
    A = rows.T @ (rows * w[:, None]) + lam ** len(y) / p0 * np.eye(order + 1)
    return np.linalg.solve(A, rows.T @ (w * y))


@pytest.mark.parametrize("order,lam", [(1, 1.0), (3, 1.0), (3, 0.995), (5, 0.999)])
def test_rls_equals_batch_least_squares(order, lam):
    rng = np.random.default_rng(order)
    z = 2.0 + np.cumsum(rng.standard_normal(400)) * 0.1 + rng.standard_normal(400)
    th = rls_theta(z, order, lam)
    ref = batch_ridge(z, order, lam)
    np.testing.assert_allclose(th, ref, rtol=1e-7, atol=1e-9)


def test_rls_recovers_ar3_parameters_with_constant():
    # z_k = 0.4885 z1 - 0.666 z2 - 0.1705 z3 + c  (the paper's Eq. 37), driven
    # by white a_k (std 1e-3); 5e4 samples
    phi = np.array([0.4885, -0.6660, -0.1705])
    c = 0.0048
    rng = np.random.default_rng(7)
    z = [0.01, 0.0, -0.01]
    for _ in range(50000):
        z.append(phi @ np.array(z[-1:-4:-1]) + c + 1e-3 * rng.standard_normal())
    th = rls_theta(np.array(z), 3, p0=1e8)
    np.testing.assert_allclose(th[:3], phi, atol=0.015)   # ~3 standard errors at N=5e4
    assert abs(th[3] - c) < 5e-4


def test_restart_reidentifies_from_scratch():
    rng = np.random.default_rng(1)
    a = rng.standard_normal(300) + 5.0
    b = rng.standard_normal(300) - 3.0
    p = K.make_params(ar_order=2, method="shakf")
    s = K.init_state(p)
    for v in a:
        K.step(p, s, float(v), False)
    outs = [K.step(p, s, float(v), i == 0) for i, v in enumerate(b)]
    s2 = K.init_state(p)
    ref = [K.step(p, s2, float(v), False) for v in b]
    assert outs == ref
    assert s == s2
