"""Reference filters the benchmark compares the paper's SHAKF against.

Plain functions over arrays; where a filter has a state, it is passed in and
returned, like ``scipy.signal.lfilter``'s ``zi``/``zf``, so a stream may be
processed in chunks.

* :func:`lowpass1` -- first-order low-pass as ArduPilot's ``LowPassFilter``
  implements it: ``y += alpha (x - y)``, ``alpha = dt / (dt + RC)``,
  ``RC = 1 / (2 pi f_c)``. Its -3 dB point is near ``f_c`` only for
  ``f_c << f_s`` (see :func:`lowpass1_cutoff_3db_hz` for the exact one).
* :func:`butter2` -- second-order Butterworth as PX4's / ArduPilot's
  ``LowPassFilter2p`` designs it (bilinear transform with the cutoff
  pre-warped, so the -3 dB point is exactly ``f_c``); filtered with
  ``scipy.signal.lfilter`` from the coefficients computed here.
* :func:`record_ar_model` -- runs the project's own kernels (KF or SHAKF) and
  records, per sample, the model they used: phi_k and c_k of the improved
  AR(n) model (Eq. 4), q_k and r_k.
* :func:`ar_rts_smoother` -- an offline Rauch-Tung-Striebel smoother on the
  same AR state model (Eq. 34-35) driven by such a recorded model: forward KF
  storing predicted and filtered moments, then the RTS backward pass.
* :func:`vbakf` -- the variational-Bayes adaptive KF of Huang, Zhang, Wu and
  Chambers (2018), "A Novel Adaptive Kalman Filter With Inaccurate Process and
  Measurement Noise Covariance Matrices", IEEE TAC 63(2):594-601: inverse-
  Wishart priors on the predicted covariance P_{k|k-1} and on R (inverse-Gamma
  for the scalar measurement here), fixed-point iterations per sample.

State model shared by the last three (the kernels' Eq. 34 with c a known
input, as :func:`gyrodenoise.core.kernels.tie_c` makes it)::

    x_k = [z_k ... z_{k-n+1}],  x_k = A_k x_{k-1} + e1 (c_k + w_k),  w ~ N(0, q_k)
    z_k = x_k[0] + v_k,  v ~ N(0, r_k),  A_k = companion(phi_k).
"""

from __future__ import annotations

import math

import numpy as np

from benchmarks._jit import HAVE_NUMBA, njit
from gyrodenoise.core.sessions import sessions

from gyrodenoise.core import kernels as K





# ------------------------------------------------------------ low-pass filters
def lowpass1_alpha(sample_rate_hz, cutoff_hz):
    """ArduPilot's first-order smoothing factor alpha = dt / (dt + RC)."""
    if not (sample_rate_hz > 0 and cutoff_hz > 0):
        raise ValueError(f"sample_rate_hz and cutoff_hz must be > 0, got {sample_rate_hz!r}, {cutoff_hz!r}")
    dt = 1.0 / float(sample_rate_hz)
    rc = 1.0 / (2.0 * math.pi * float(cutoff_hz))
    return dt / (dt + rc)


def lowpass1_cutoff_3db_hz(sample_rate_hz, cutoff_hz):
    """Exact -3 dB frequency of :func:`lowpass1` (analytic, from |H(e^jw)|^2 = 1/2).

    H(z) = alpha / (1 - (1-alpha) z^-1), so |H|^2 = 1/2 where
    cos w = (1 + (1-alpha)^2 - 2 alpha^2) / (2 (1-alpha)). Returns nan if the
    gain never falls to -3 dB below Nyquist.
    """
    a = lowpass1_alpha(sample_rate_hz, cutoff_hz)
    b = 1.0 - a
    if b <= 0.0:
        return float("nan")
    cw = (1.0 + b * b - 2.0 * a * a) / (2.0 * b)
    if not -1.0 <= cw <= 1.0:
        return float("nan")
    return math.acos(cw) * sample_rate_hz / (2.0 * math.pi)


def lowpass1(rate_deg_s, sample_rate_hz, cutoff_hz, y_prev=None):
    """First-order low-pass, ArduPilot style.

    Parameters
    ----------
    rate_deg_s : array_like
    sample_rate_hz, cutoff_hz : float
    y_prev : float, optional
        Output before the first sample (the filter state). Default: the first
        sample, as ArduPilot initialises on its first ``apply``.

    Returns
    -------
    y : ndarray
        Filtered rate, deg/s.
    y_last : float
        State to pass as ``y_prev`` for the next chunk.
    """
    from scipy.signal import lfilter
    x = np.asarray(rate_deg_s, dtype=float)
    if x.size == 0:
        return x.copy(), y_prev
    a = lowpass1_alpha(sample_rate_hz, cutoff_hz)
    y0 = float(x[0]) if y_prev is None else float(y_prev)
    # y_k = (1 - a) y_{k-1} + a x_k  -> b = [a], a = [1, -(1 - a)], zi = (1 - a) y_{-1}
    y, _ = lfilter([a], [1.0, -(1.0 - a)], x, zi=[(1.0 - a) * y0])
    return y, float(y[-1])


def butter2_coefficients(sample_rate_hz, cutoff_hz):
    """(b, a) of the 2nd-order Butterworth low-pass, as PX4's LowPassFilter2p.

    Bilinear transform with pre-warping: ohm = tan(pi f_c / f_s),
    c = 1 + 2 cos(pi/4) ohm + ohm^2, b = [ohm^2, 2 ohm^2, ohm^2] / c,
    a = [1, 2 (ohm^2 - 1) / c, (1 - 2 cos(pi/4) ohm + ohm^2) / c].
    Requires 0 < f_c < f_s / 2.
    """
    fs, fc = float(sample_rate_hz), float(cutoff_hz)
    if not (fs > 0 and 0 < fc < fs / 2):
        raise ValueError(f"cutoff_hz must be in (0, sample_rate_hz/2), got {fc!r} at {fs!r} Hz")
    ohm = math.tan(math.pi * fc / fs)
    k = 2.0 * math.cos(math.pi / 4.0) * ohm
    c = 1.0 + k + ohm * ohm
    b0 = ohm * ohm / c
    b = np.array([b0, 2.0 * b0, b0])
    a = np.array([1.0, 2.0 * (ohm * ohm - 1.0) / c, (1.0 - k + ohm * ohm) / c])
    return b, a


def butter2(rate_deg_s, sample_rate_hz, cutoff_hz, zi=None):
    """Second-order Butterworth low-pass (PX4 / ArduPilot ``LowPassFilter2p``).

    Parameters
    ----------
    rate_deg_s : array_like
    sample_rate_hz, cutoff_hz : float
        Needs ``cutoff_hz < sample_rate_hz / 2``.
    zi : array_like of 2 floats, optional
        Filter state (transposed direct form II, as ``scipy.signal.lfilter``).
        Default: the steady state for the first sample (the filter "reset to
        the first sample", as PX4 does).

    Returns
    -------
    y : ndarray
    zf : ndarray
        State for the next chunk.
    """
    from scipy.signal import lfilter, lfilter_zi
    x = np.asarray(rate_deg_s, dtype=float)
    b, a = butter2_coefficients(sample_rate_hz, cutoff_hz)
    if zi is None:
        zi = lfilter_zi(b, a) * (x[0] if x.size else 0.0)
    y, zf = lfilter(b, a, x, zi=np.asarray(zi, dtype=float))
    return y, zf


# ------------------------------------------------ the AR model a run used
def _record(p, s, z, restarts, out, theta, q_used, r_used, conv):
    """Run the core sample by sample; record per sample [phi, c], the q of the
    time update, the r of the measurement update, and the converged flag."""
    from gyrodenoise.core.batch import C
    step = C.step if C is not None else K.step
    if C is None:
        p, s = list(p), list(s)
    n = int(p[K.P_ORDER])
    o = K.N_HEADER
    for i in range(z.shape[0]):
        if restarts[i] or s[K.S_CONV] == 0.0:
            # q of this step's time update is set inside step() from the
            # warm-up noise level (see kernels.step): read it back afterwards
            pre_q = -1.0
        else:
            pre_q = s[K.S_Q]
        out[i] = step(p, s, float(z[i]), bool(restarts[i]))
        for j in range(n):
            theta[i, j] = s[o + j]
        theta[i, n] = K.c_deg_s(p, s)
        conv[i] = s[K.S_CONV]
        r_used[i] = s[K.S_R]
        if pre_q < 0.0:
            # first converged step (or still warming up): the time update used
            # the level set at the start of the step; for KF/SHAKF that is the
            # q the step starts from, unchanged by the KF, adapted by SHAKF
            pre_q = s[K.S_Q] if p[K.P_METHOD] == K.METHOD_KF else -1.0
        q_used[i] = pre_q


def record_ar_model(rate_deg_s, sample_rate_hz, method="kf", ar_order=3, restarts=None, **kw):
    """Run the project's KF/SHAKF and record the model it used at every sample.

    Parameters
    ----------
    rate_deg_s : array_like
    sample_rate_hz : float
    method : {"kf", "shakf", "sh_classic"}
    ar_order : int
    restarts : array_like of bool, optional
    **kw
        Further :func:`gyrodenoise.core.kernels.make_params` parameters.

    Returns
    -------
    dict
        ``out`` (the filter's output), ``phi`` (N x n), ``c`` (N), ``q`` (N; the
        q of each step's time update, nan where it is not recorded: warm-up,
        and the first converged SHAKF step), ``r`` (N, the measurement-update
        r), ``converged`` (N bool), ``params``.
    """
    p = np.asarray(K.make_params(ar_order=ar_order, method=method,
                                 sample_rate_hz=sample_rate_hz, **kw), dtype=float)
    s = np.asarray(K.init_state(list(p)), dtype=float)
    z = np.ascontiguousarray(rate_deg_s, dtype=float)
    ra = np.zeros(z.shape[0], dtype=np.bool_) if restarts is None else np.ascontiguousarray(restarts, dtype=np.bool_)
    n = int(ar_order)
    out = np.empty_like(z)
    theta = np.empty((z.shape[0], n + 1))
    q = np.empty_like(z)
    r = np.empty_like(z)
    conv = np.empty_like(z)
    _record(p, s, z, ra, out, theta, q, r, conv)
    q[q < 0.0] = np.nan
    return {"out": out, "phi": theta[:, :n], "c": theta[:, n], "q": q, "r": r,
            "converged": conv == 1.0, "params": p}


# ------------------------------------------------------ RTS on the AR model
def _rts_py(z, phi, c, q, r, x0, p0, xs, want_filtered, xf_out):
    """Forward KF + RTS pass over one segment; xs[k] <- smoothed state."""
    nn = z.shape[0]
    n = phi.shape[1]
    xp = np.empty((nn, n))
    pp = np.empty((nn, n, n))
    xf = np.empty((nn, n))
    pf = np.empty((nn, n, n))
    a = np.zeros((n, n))
    for i in range(1, n):
        a[i, i - 1] = 1.0
    x = x0.copy()
    P = p0.copy()
    for k in range(nn):
        for j in range(n):
            a[0, j] = phi[k, j]
        # time update, Eq. (34): x = A x + e1 c, P = A P A' + q e1 e1'
        xpk = a @ x
        xpk[0] += c[k]
        ppk = a @ P @ a.T
        ppk[0, 0] += q[k]
        # measurement update, Eq. (35), H = e1
        sv = ppk[0, 0] + r[k]
        g = ppk[:, 0] / sv
        x = xpk + g * (z[k] - xpk[0])
        P = ppk - np.outer(g, ppk[0, :])
        P = 0.5 * (P + P.T)
        xp[k] = xpk
        pp[k] = ppk
        xf[k] = x
        pf[k] = P
    if want_filtered:
        for k in range(nn):
            xf_out[k] = xf[k, 0]
    # RTS backward pass: G_k = P_k A_{k+1}' P_{k+1|k}^-1
    xs[nn - 1] = xf[nn - 1, 0]
    xsk = xf[nn - 1].copy()
    for k in range(nn - 2, -1, -1):
        for j in range(n):
            a[0, j] = phi[k + 1, j]
        # G' = solve(P_{k+1|k}, A P_k)  (P_{k+1|k} symmetric)
        gt = np.linalg.solve(pp[k + 1], a @ pf[k])
        xsk = xf[k] + gt.T @ (xsk - xp[k + 1])
        xs[k] = xsk[0]


_rts_fast = njit(_rts_py) if HAVE_NUMBA else None


def ar_rts_smoother(z, phi, c, q, r, x0, p0, return_filtered=False):
    """Rauch-Tung-Striebel smoother on the improved-AR(n) state model.

    Parameters
    ----------
    z : array_like, shape (N,)
        Measurements z_1..z_N, deg/s.
    phi : array_like, shape (N, n)
        AR coefficients used at each step (Eq. 4); row k builds A_k.
    c, q, r : array_like, shape (N,) (or scalars)
        Constant term (deg/s), process and measurement noise variances
        ((deg/s)^2) of each step.
    x0 : array_like, shape (n,)
        Filtered state before z_1 (e.g. [z_0, z_{-1}, ...]).
    p0 : array_like, shape (n, n)
        Its covariance.
    return_filtered : bool
        Also return the forward (causal) KF estimate of z_k.

    Returns
    -------
    smoothed : ndarray, shape (N,)
        E[z_k true | z_1..z_N], the first state component.
    filtered : ndarray, optional
    """
    za = np.ascontiguousarray(z, dtype=float)
    nn = za.shape[0]
    ph = np.ascontiguousarray(np.broadcast_to(np.asarray(phi, dtype=float).reshape(-1, np.shape(x0)[0]),
                                              (nn, np.shape(x0)[0])))
    cc = np.ascontiguousarray(np.broadcast_to(np.asarray(c, dtype=float), (nn,)))
    qq = np.ascontiguousarray(np.broadcast_to(np.asarray(q, dtype=float), (nn,)))
    rr = np.ascontiguousarray(np.broadcast_to(np.asarray(r, dtype=float), (nn,)))
    if not (np.all(np.isfinite(qq)) and np.all(qq >= 0) and np.all(rr > 0)):
        raise ValueError("q must be finite and >= 0, r finite and > 0")
    xs = np.empty(nn)
    xf = np.empty(nn if return_filtered else 0)
    if nn:
        (_rts_fast or _rts_py)(za, ph, cc, qq, rr, np.asarray(x0, dtype=float).copy(),
                               np.asarray(p0, dtype=float).copy(), xs, return_filtered, xf)
    return (xs, xf) if return_filtered else xs


def smooth_record(rate_deg_s, sample_rate_hz, ar_order=3, restarts=None, model=None, **kw):
    """Offline RTS smoothing of a gyro record on the KF's identified AR model.

    The model (phi_k, c_k, q, r) is the one the project's conventional KF
    used in a causal run over the same record (:func:`record_ar_model`, method
    "kf", with the kernels' outlier gate off unless ``outlier_sigma`` is given:
    a gated sample changes the run in ways this state model does not
    describe); during each warm-up the raw sample is passed through, as the
    KF does.

    Returns
    -------
    ndarray
        Smoothed rate, deg/s.
    """
    z, m, out = _kf_model(rate_deg_s, sample_rate_hz, ar_order, restarts, model, kw)
    for w, b, x0, p0 in _filtered_runs(z, m, ar_order, restarts):
        out[w:b] = ar_rts_smoother(z[w:b], m["phi"][w:b], m["c"][w:b], m["q"][w:b], m["r"][w:b], x0, p0)
    return out


def _kf_model(rate_deg_s, sample_rate_hz, ar_order, restarts, model, kw):
    """(z, the KF run's recorded AR model, a copy of z for the output)."""
    z = np.asarray(rate_deg_s, dtype=float)
    m = model if model is not None else record_ar_model(z, sample_rate_hz, "kf", ar_order, restarts,
                                                        **{"outlier_sigma": 0.0, **kw})
    return z, m, z.copy()


def _filtered_runs(z, m, ar_order, restarts):
    """Per run between restarts: (w, b, x0, p0) with w the first sample the KF
    filtered (after its warm-up), b the end of the run, x0 = [z_{w-1} ... z_{w-n}]
    (as kernels.start_filter) and p0 = r_w I."""
    n = int(ar_order)
    for a, b in sessions(z.shape[0], restarts):
        conv = np.flatnonzero(m["converged"][a:b])
        if conv.size == 0:
            continue
        w = a + int(conv[0])
        if w - n < a:
            continue
        yield w, b, z[w - n:w][::-1].copy(), np.eye(n) * m["r"][w]


# -------------------------------------------------------------- VB-AKF
def _vbakf_py(z, phi, c, q_nom, r0, x0, p0, tau, rho, n_iter, out, r_hat):
    nn = z.shape[0]
    n = x0.shape[0]
    a = np.zeros((n, n))
    for i in range(1, n):
        a[i, i - 1] = 1.0
    x = x0.copy()
    P = p0.copy()
    # inverse-Gamma (1-D inverse-Wishart, m = 1) on R: dof u, scale U
    u = 1.0 + 1.0 + tau
    U = (u - 2.0) * r0
    for k in range(nn):
        for j in range(n):
            a[0, j] = phi[k, j]
        xp = a @ x
        xp[0] += c[k]
        pt = a @ P @ a.T
        pt[0, 0] += q_nom[k]
        # priors: P_{k|k-1} ~ IW(t, T), t = n + tau + 1, T = tau * P~
        t_post = n + tau + 1.0 + 1.0
        T_pri = tau * pt
        u = rho * (u - 2.0) + 2.0          # u_{k|k-1} = rho (u - m - 1) + m + 1
        U = rho * U
        u_post = u + 1.0
        xi = xp.copy()
        Pi = pt.copy()
        Ui = U
        for it in range(n_iter):
            d = xi - xp
            T = T_pri + Pi + np.outer(d, d)
            e = z[k] - xi[0]
            Ui = U + e * e + Pi[0, 0]
            # E[P^-1]^-1 = T / (t - n - 1), E[R^-1]^-1 = U / (u - 2)
            pk = T / (t_post - n - 1.0)
            rk = Ui / (u_post - 2.0)
            sv = pk[0, 0] + rk
            g = pk[:, 0] / sv
            xi = xp + g * (z[k] - xp[0])
            Pi = pk - np.outer(g, pk[0, :])
            Pi = 0.5 * (Pi + Pi.T)
        # posterior of R: the last iteration's (Huang et al., Algorithm 1)
        U = Ui
        u = u_post
        x = xi
        P = Pi
        out[k] = x[0]
        r_hat[k] = U / (u - 2.0)


_vbakf_fast = njit(_vbakf_py) if HAVE_NUMBA else None


def vbakf(z, phi, c, q_nom, r0, x0, p0, tau=3.0, rho=1.0 - math.exp(-4.0), n_iter=10):
    """Variational-Bayes adaptive KF (Huang et al. 2018) on the AR state model.

    Parameters
    ----------
    z : array_like, shape (N,)
    phi : array_like, shape (N, n)
    c, q_nom : array_like, shape (N,) or scalars
        Constant term and the nominal (possibly wrong) process noise variance.
    r0 : float
        Nominal measurement noise variance, the prior mean of R.
    x0, p0 : array_like
        Initial state and covariance.
    tau : float
        Tuning parameter of the inverse-Wishart prior on P_{k|k-1}
        (t = n + tau + 1, T = tau P~); the paper uses tau = 3.
    rho : float
        Forgetting factor of the R prior, 0 < rho <= 1 (paper: 1 - exp(-4)).
    n_iter : int
        Fixed-point iterations per sample (paper: N = 10).

    Returns
    -------
    out : ndarray
        Filtered z_k.
    r_hat : ndarray
        Posterior mean estimate of R after each sample, (deg/s)^2.
    """
    za = np.ascontiguousarray(z, dtype=float)
    nn = za.shape[0]
    n = int(np.shape(x0)[0])
    ph = np.ascontiguousarray(np.broadcast_to(np.asarray(phi, dtype=float).reshape(-1, n), (nn, n)))
    cc = np.ascontiguousarray(np.broadcast_to(np.asarray(c, dtype=float), (nn,)))
    qq = np.ascontiguousarray(np.broadcast_to(np.asarray(q_nom, dtype=float), (nn,)))
    if not (tau > 0 and 0 < rho <= 1 and n_iter >= 1 and r0 > 0):
        raise ValueError("need tau > 0, 0 < rho <= 1, n_iter >= 1, r0 > 0")
    out = np.empty(nn)
    rh = np.empty(nn)
    (_vbakf_fast or _vbakf_py)(za, ph, cc, qq, float(r0), np.asarray(x0, dtype=float).copy(),
                               np.asarray(p0, dtype=float).copy(), float(tau), float(rho),
                               int(n_iter), out, rh)
    return out, rh


def vbakf_record(rate_deg_s, sample_rate_hz, ar_order=3, restarts=None, model=None, **kw):
    """VB-AKF over a gyro record, on the KF's identified AR model (phi_k, c_k)
    with the KF's q and r as the nominal values (outlier gate off, as in
    :func:`smooth_record`); raw pass-through in warm-up."""
    z, m, out = _kf_model(rate_deg_s, sample_rate_hz, ar_order, restarts, model, kw)
    for w, b, x0, p0 in _filtered_runs(z, m, ar_order, restarts):
        out[w:b] = vbakf(z[w:b], m["phi"][w:b], m["c"][w:b], m["q"][w:b], m["r"][w], x0, p0)[0]
    return out
