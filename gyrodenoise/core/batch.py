"""Batch loop over arrays: the compiled C core, or the plain-Python reference.

The fast path is ``gd_run`` of ``gdcore.c`` through the extension
:mod:`gyrodenoise.core._gdcore` (built by ``pip install``). ``compiled=False``
runs :func:`gyrodenoise.core.kernels.step` in plain Python over the same
buffers: the executable specification the C is tested against
(bit for bit). Diagnostics and theta histories need the
state after every sample, so they step sample by sample (C when available).
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np

from . import kernels as K

try:
    from . import _gdcore as C
except ImportError as _exc:  # a build without a C compiler (the extension is optional)
    C = None
    # one line, once per process (this module is imported once), when the batch paths
    # (gd.denoise, the CLI) first run. The cost, measured with run(..., compiled=True/False)
    # on 20000 samples at 200 Hz: C ~40 ns/sample, Python 7 us (motion) to 28 us (shakf)
    logging.getLogger("gyrodenoise").warning(
        "gyrodenoise: C core not built (%s): filtering runs on the plain-Python kernels, same "
        "numbers, ~170x (motion) to ~600x (shakf) slower per sample; reinstall with a C "
        "compiler for the fast path", _exc)


def compiled_core():
    """True if the C core is built and importable (else every path is plain Python)."""
    return C is not None


def run(p, s, z, restarts=None, *, diagnostics=False, record_theta=False, trace_index=None, compiled=True):
    """Filter an array of raw samples, continuing from state ``s``.

    Parameters
    ----------
    p : sequence of float
        Parameter buffer from :func:`gyrodenoise.core.kernels.make_params`.
    s : sequence of float
        State buffer (from :func:`gyrodenoise.core.kernels.init_state` or a
        previous call); it is *not* modified: the final state is returned.
    z : array_like
        Raw rate samples, deg/s.
    restarts : array_like of bool, optional
        True where the gyro restarted (that sample is the first of a run).
    diagnostics : bool
        Also return an (n, 4) array [innovation, R_hat, converged, rls_error].
    record_theta : bool
        Also return an (n, order+1) array of [phi_1..phi_n, c] after each
        sample (c in deg/s of the raw samples, :func:`~gyrodenoise.core.kernels.c_deg_s`).
    trace_index : int, optional
        Also return s[trace_index] after each sample (an (n,) array), e.g.
        the output variance of ``method="motion"`` for :func:`run_offline`.
    compiled : bool
        Use the C core (False: the plain-Python kernels, same numbers).

    Returns
    -------
    out : ndarray
        Filtered rate, deg/s.
    state : ndarray
        State after the last sample (pass it back in to continue).
    extra : ndarray, optional
        Diagnostics or theta history when asked for.
    """
    pa = np.ascontiguousarray(p, dtype=np.float64)
    sa = np.array(s, dtype=np.float64)
    za = np.ascontiguousarray(z, dtype=np.float64)
    if restarts is None:
        ra = np.zeros(za.shape[0], dtype=np.uint8)
    else:
        ra = np.ascontiguousarray(restarts, dtype=bool).view(np.uint8)
        if ra.shape != za.shape:
            raise ValueError("restarts must have the same length as the samples")
    out = np.empty_like(za)
    use_c = compiled and C is not None
    if use_c and trace_index is not None and not (diagnostics or record_theta):
        trace = np.empty_like(za)           # the C loop records it (gd_run_trace)
        C.run(pa, sa, za, ra, out, int(trace_index), trace)
        return out, sa, trace
    if not (diagnostics or record_theta or trace_index is not None):
        if use_c:
            C.run(pa, sa, za, ra, out)
            return out, sa
        sl = sa.tolist()
        pl = pa.tolist()
        for i, (v, r) in enumerate(zip(za.tolist(), ra.tolist())):
            out[i] = K.step(pl, sl, v, bool(r))
        return out, np.asarray(sl)
    # sample by sample, reading the state after each one
    st = sa if use_c else sa.tolist()
    pp = pa if use_c else pa.tolist()
    step = C.step if use_c else K.step
    n = int(pa[K.P_ORDER])
    extra = np.empty((za.shape[0], n + 1 if record_theta else 4) if trace_index is None else za.shape[0])
    for i, (v, r) in enumerate(zip(za.tolist(), ra.tolist())):
        out[i] = step(pp, st, v, bool(r))
        if trace_index is not None:
            extra[i] = st[trace_index]
        elif record_theta:
            for j in range(n):
                extra[i, j] = st[K.N_HEADER + j]
            extra[i, n] = K.c_deg_s(pp, st)
        else:
            extra[i] = (st[K.S_INNOV], st[K.S_R], st[K.S_CONV], st[K.S_RLS_ERR])
    return out, np.asarray(st, dtype=np.float64), extra


def _rigid_offline(p, seg, o_ext, compiled):
    """The offline form with ``max_motion_hz``, one run of samples: the
    blend of a forward and a backward pass each low-passed inside would keep the low-pass's
    phase (gain |H| cos(phase): 0.3 at max_motion_hz), so the rigid-body low-pass is run
    zero-phase first (the core's low-pass forwards, then backwards: |H|^2, 0.992 at
    max_motion_hz) and the bank blends on that, without a low-pass of its own and with the
    sensor's white-noise level read from the raw samples by the causal filter (the median
    of its estimate over the run: the low-passed samples no longer show it).
    Returns (low-passed samples, parameters of the bank)."""
    _, _, r_trace = run(p, K.init_state(p), seg, trace_index=o_ext + K.M_R, compiled=compiled)
    pos = r_trace[r_trace > 0.0]
    plp = list(p)
    plp[K.P_METHOD] = K.METHOD_LOWPASS
    fwd, _ = run(plp, K.init_state(plp), seg, compiled=compiled)
    y, _ = run(plp, K.init_state(plp), fwd[::-1].copy(), compiled=compiled)
    pb = list(p)
    pb[K.P_LP_NSEC] = 0.0
    pb[K.P_MO_RFIX] = float(np.median(pos)) if pos.size else 0.0
    return y[::-1].copy(), pb


SMOOTH_PASS = (0.6, 0.85)   # smooth_motion's pass-through: the smoothed variance (units of R) where the
                            # output starts moving to the raw sample, and where it is the raw sample
SMOOTH_BLOCK = 8192     # samples per block of the offline smoother (smooth_motion): its checkpoints' spacing


class TwoFilter(NamedTuple):
    """One constant-velocity model's two-filter smoothing at a sample (:func:`two_filter_rate`)."""

    rate: object      # the smoothed rate, deg/s
    loglik: object    # the log-likelihood of the two estimates' agreement
    chi2: object      # d^T (P_f + P_b)^-1 d / r, the agreement's chi-square (2 degrees of freedom)
    var: object       # the smoothed rate's variance, in units of r


def _bank_record(p, seg, compiled, state=None):
    """The causal ``motion`` filter stepped over ``seg`` from ``state`` (default a fresh
    one; a checkpoint of :func:`_checkpoints`), recording its bank after every sample. Returns (out, bank, nw, r, active, line, zref): the causal output (n,);
    per constant-velocity filter (the bank's first P_MO_NF lanes; the P_MO_NCA
    constant-acceleration lanes after them are not recorded) its rate (centred), slope per sample and
    faded log-likelihood, (ncv, 3, n);
    the growing-memory sample count M_NW; the white-noise variance M_R; 1.0 where the bank
    filtered that sample (past its warm-up, S_CONV); 1.0 where the line test held the
    output on the raw sample (M_LON); the centring reference S_ZREF (deg/s) of each sample."""
    o = K.ext_offset(p)
    nf = int(p[K.P_MO_NF])       # the constant-velocity lanes (the CA ones follow them)
    idx = [o + lane + i for i in range(nf) for lane in (K.MB_X, K.MB_A, K.MB_L)]   # the bank's lanes
    idx += [o + K.M_NW, o + K.M_R, K.S_CONV, o + K.M_LON, K.S_ZREF]
    n = seg.shape[0]
    out = np.empty(n)
    rec = np.empty((len(idx), n))            # one row per recorded value
    use_c = compiled and C is not None
    start = K.init_state(p) if state is None else state
    if use_c:                                # the C loop records them (gd_run_record)
        C.record(np.ascontiguousarray(p, dtype=np.float64), np.array(start, dtype=np.float64),
                 np.ascontiguousarray(seg, dtype=np.float64), out, np.asarray(idx, dtype=np.float64), rec)
    else:
        pp, st = list(p), [float(v) for v in start]
        for i, v in enumerate(seg.tolist()):
            out[i] = K.step(pp, st, v, False)
            rec[:, i] = [st[j] for j in idx]
    m = 3 * nf
    return out, rec[:m].reshape(nf, 3, n), rec[m], rec[m + 1], rec[m + 2], rec[m + 3], rec[m + 4]


def _line_cov(nw):
    """Covariance of the least-squares line through ``nw`` samples (an array) at its last
    sample, rate and slope per sample, in units of R: the bank's filters while they run at
    the growing-memory gains (:func:`~gyrodenoise.core.kernels.motion_step`). Returns
    (c00, c01, c11) = (2(2nw-1)/(nw(nw+1)), 6/(nw(nw+1)), 12/(nw(nw^2-1)))."""
    w = np.maximum(nw, 2.0)
    w1 = w * (w + 1.0)
    return 2.0 * (2.0 * w - 1.0) / w1, 6.0 / w1, 12.0 / (w1 * (w - 1.0))


def _filtered_cov(p, i, line):
    """Filtered covariance of bank filter ``i`` (its rate and slope, in units of R): the
    least-squares line's (``line`` = :func:`_line_cov`) where its rate gain is larger than
    the filter's own (its start-up), else the steady state of the alpha-beta filter
    (alpha, beta from :func:`~gyrodenoise.core.kernels.cv_gains`):
    [[alpha, beta], [beta, beta(2 alpha - beta) / (2(1 - alpha))]]. Returns (c00, c01, c11)."""
    a, b = p[K.P_MO_G + i], p[K.P_MO_G + K.MO_MAX_NF + i]          # the gains' lanes: alpha, beta
    on = line[0] > a
    return (np.where(on, line[0], a), np.where(on, line[1], b),
            np.where(on, line[2], b * (2.0 * a - b) / (2.0 * (1.0 - a))))


def two_filter_rate(xf, pf, xb, pb, lam2, r):
    """One constant-velocity model's smoothed rate at sample k from its forward filtered
    estimate at k and its backward (time-reversed) filtered estimate at k + 1.

    ``xf`` = (rate, slope per sample) after z_k, ``pf`` = its covariance (c00, c01, c11) in
    units of the white-noise variance ``r``; ``xb``, ``pb`` the same of the filter run on the
    reversed samples after z_{k+1} (its slope per reversed sample); ``lam2`` the tracking
    index squared (process noise lam2 r [[1/4, 1/2], [1/2, 1]] per sample). Scalars or
    arrays. Returns a :class:`TwoFilter`: the smoothed rate, the log-likelihood of the two
    estimates' agreement, its chi-square and the smoothed rate's variance in units of ``r``.

    * backward prediction to k (the reversed model is the same white-noise acceleration
      model): x_b = F x_b(k+1), P_b = F P_b(k+1) F^T + Q, then the slope back to forward
      time (sign);
    * Eq. S1, the two-filter smoother (Fraser and Potter 1969; the same fixed point as the
      RTS smoother x_s(k) = x_f(k) + C_k (x_s(k+1) - x_p(k+1)), C_k = P_f F^T P_p(k+1)^-1):
      x_s = x_f + P_f (P_f + P_b)^-1 (x_b - x_f);
    * the agreement: -(d^T (P_f + P_b)^-1 d / r + log det(P_f + P_b)) / 2, d = x_b - x_f;
    * the smoothed covariance P_f - P_f (P_f + P_b)^-1 P_f, its rate's entry."""
    f00, f01, f11 = pf
    c00, c01, c11 = pb
    b00 = c00 + 2.0 * c01 + c11 + 0.25 * lam2          # F P F^T + Q, reversed time ...
    b01 = -(c01 + c11 + 0.5 * lam2)                    # ... and the slope's sign turned back
    b11 = c11 + lam2
    xb0, xb1 = xb[0] + xb[1], -xb[1]
    m00, m01, m11 = f00 + b00, f01 + b01, f11 + b11    # P_f + P_b
    det = m00 * m11 - m01 * m01
    d0, d1 = xb0 - xf[0], xb1 - xf[1]
    u0 = (m11 * d0 - m01 * d1) / det                   # (P_f + P_b)^-1 d
    u1 = (m00 * d1 - m01 * d0) / det
    rate = xf[0] + f00 * u0 + f01 * u1                 # Eq. S1, its rate
    chi2 = (d0 * u0 + d1 * u1) / r
    var = f00 - (f00 * (m11 * f00 - m01 * f01) + f01 * (m00 * f01 - m01 * f00)) / det
    return TwoFilter(rate, -0.5 * (chi2 + np.log(det)), chi2, var)


def smooth_motion(p, seg, *, compiled=True, out=None):
    """Fixed-interval smoother of the ``motion`` bank over one run of samples (no restart
    inside): the two-filter smoother of every constant-velocity model of the bank, blended
    by the models' probabilities given the whole run. The bank runs here with its
    constant-velocity lanes only (the first P_MO_NF, whose covariances have the closed forms
    below; P_MO_NCA is set to 0): with the causal bank's constant-acceleration lanes in its
    runs (restarts from them, the causal output where one direction warms up) but not in the
    combination, the smoother's angle over 0.1 s / 1 s windows went from 1.009 / 1.028 to
    1.079 / 1.126 x raw's (FOG pendulum; docs/method/motion.md).

    The bank runs forwards and, from a fresh state, backwards in time (the causal filter on
    the reversed samples); per model i and sample k:

    * forward filtered estimate x_f = [rate, slope] after z_k, covariance P_f R
      (:func:`_filtered_cov`);
    * backward estimate after z_{k+1} (time reversed), predicted to k: x_b = F x_b(k+1),
      P_b = F P(k+1) F^T + Q, Q = lam^2 [[1/4, 1/2], [1/2, 1]] (the white-noise acceleration
      model the bank's gains come from), the slope's sign turned back to forward time. It
      holds every sample after k, the forward one every sample up to k: independent;
    * Eq. S1 (the two-filter smoother, Fraser and Potter 1969, the RTS smoother's fixed
      point): x_s = x_f + P_f (P_f + P_b)^-1 (x_b - x_f);
    * Eq. S2 (the model's log-probability given the whole run): the forward and backward
      faded log-likelihoods of the bank plus that of the two estimates' agreement,
      -(d^T (P_f + P_b)^-1 d / R + log det(P_f + P_b)) / 2, d = x_b - x_f;
    * the output is the mean of the x_s rates weighted by exp(S2 - max S2);
    * the pass-through: where the weighted mean of the models' smoothed variances (units of
      R, :class:`TwoFilter`) is above SMOOTH_PASS[0] the smoother removes little noise and its
      model may not follow the motion (real vibration above the noise): the output moves
      linearly to the raw sample, all the way at SMOOTH_PASS[1];
    * the break test: where every model's agreement chi-square exceeds twice the bank's
      restart gap (P_MO_RESET log-likelihood units), no model sees the samples up to k and
      those after it as one motion (a step: the fastest filter rings after it and the slower
      ones restart from it), and the output is the raw sample.

    Where only one direction filters (the other's warm-up: the first and last ``P_WARMUP``
    samples) its causal output is used; where either direction's spectral line test holds
    its output on the raw sample, the raw sample. The output stays inside [min, max] of the
    finite samples of ``seg``; where it would not be finite (an input near the largest
    float), the causal blend of :func:`run_offline` is used there.

    Memory is bounded whatever the length: the two banks' records are made one block of
    SMOOTH_BLOCK samples at a time, each direction restarted from its state saved at the
    block's edge (:func:`_checkpoints`, one state buffer a block) instead of recorded over
    the whole run (88 values, 704 bytes, a sample); the state is the filter's whole state,
    so a block's records are those of the one pass over the run, bit for bit. ``seg`` may be
    anything that slices into arrays (a record spilled to disk); ``out`` (optional) receives
    the output. Returns the smoothed rate (deg/s), an ndarray like ``seg`` (``out`` when
    given)."""
    p = list(p)
    p[K.P_MO_NCA] = 0.0                          # the CV lanes only (above)
    n, block = len(seg), int(SMOOTH_BLOCK)
    y = np.empty(n) if out is None else out
    starts = list(range(0, n, block))
    # block [a, b) needs the forward records at a..b-1 (state before a) and the backward ones
    # at a..c-1, c = min(b + 1, n) (the backward bank's state after samples n-1 down to c)
    ends = [min(a + block + 1, n) for a in starts]
    fwd = _checkpoints(p, lambda lo, hi: seg[lo:hi], starts, compiled)
    bwd = _checkpoints(p, lambda lo, hi: seg[n - hi:n - lo][::-1], [n - c for c in reversed(ends)], compiled)[::-1]
    finite = _finite_range(seg, block)
    bad = []
    for a, c, sf, sb in zip(starts, ends, fwd, bwd):
        b = min(a + block, n)
        z = np.ascontiguousarray(seg[a:c], dtype=np.float64)
        yb, nonfinite = _smooth_block(p, z, b - a, sf, sb, finite, compiled)
        bad.extend((nonfinite + a).tolist())
        y[a:b] = yb
    if bad:
        idx = np.asarray(bad)
        y[idx] = _blend(p, np.ascontiguousarray(seg[0:n], dtype=np.float64), compiled)[idx]
    return y


def _checkpoints(p, piece, positions, compiled):
    """The causal bank's whole state before each of ``positions`` (ascending sample counts)
    of one pass from a fresh state over the samples ``piece(lo, hi)`` gives (lo..hi-1 of the
    pass, in the order it steps them). Returns a list of state buffers."""
    s, pos, saved = np.array(K.init_state(p), dtype=np.float64), 0, []
    for at in positions:
        if at > pos:
            _, s = run(p, s, piece(pos, at), compiled=compiled)
            pos = at
        saved.append(s.copy())
    return saved


def _finite_range(seg, block):
    """(min, max) of the finite samples of ``seg`` read a block at a time, None when none is."""
    lo, hi = np.inf, -np.inf
    for a in range(0, len(seg), block):
        z = np.asarray(seg[a:a + block], dtype=np.float64)
        z = z[np.isfinite(z)]
        if z.size:
            lo, hi = min(lo, float(z.min())), max(hi, float(z.max()))
    return (lo, hi) if lo <= hi else None


def _smooth_block(p, z, m, sf, sb, finite, compiled):
    """:func:`smooth_motion` on its samples a..a+m-1: ``z`` holds them and, unless the run ends
    there, sample a+m (the backward bank's estimate after it enters the combination at a+m-1);
    ``sf`` the forward bank's state before a, ``sb`` the backward one's after a+len(z)-1;
    ``finite`` the run's (min, max) of finite samples. Returns (the output of the m samples,
    the indices, within the block, where it is not finite and the causal blend stands in)."""
    nf = int(p[K.P_MO_NF])                       # the CV models
    fo, bf, nwf, rf, af, lf, zf = _bank_record(p, z[:m], compiled, sf)
    bo, bb, nwb, rb, ab, lb, zb = _bank_record(p, z[::-1].copy(), compiled, sb)
    bo, bb, nwb, rb, ab, lb, zb = bo[::-1], bb[:, :, ::-1], nwb[::-1], rb[::-1], ab[::-1], lb[::-1], zb[::-1]
    seg = z[:m]
    y = np.where(af == 1.0, fo, bo[:m])      # one direction alone where the other warms up
    gate = 2.0 * p[K.P_MO_RESET]               # the break test's chi-square (below)
    lo, hi = SMOOTH_PASS
    # every sample k with the forward bank at k and the backward one at k + 1 (the last sample
    # of the run has none; the samples where one direction warms up are computed and left out:
    # they may divide by zero, hence the errstate)
    kn = len(z) - 1
    if kn > 0:
        k, j = slice(0, kn), slice(1, kn + 1)
        both = (af[k] == 1.0) & (ab[j] == 1.0)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            lnf, lnb = _line_cov(nwf[k]), _line_cov(nwb[j])
            r = 0.5 * (rf[k] + rb[j])
            r = np.where(r > 0.0, r, 1.0)
            xs = np.empty((nf, kn))
            ll, c2, vs = np.empty_like(xs), np.empty_like(xs), np.empty_like(xs)
            for i in range(nf):
                lam2 = p[K.P_MO_G + 4 * K.MO_MAX_NF + i]     # lam^2 = beta^2 / (1 - alpha)
                xs[i], ll[i], c2[i], vs[i] = two_filter_rate(
                    (bf[i, 0, k] + zf[k], bf[i, 1, k]), _filtered_cov(p, i, lnf),
                    (bb[i, 0, j] + zb[j], bb[i, 1, j]), _filtered_cov(p, i, lnb), lam2, r)
                ll[i] += bf[i, 2, k] + bb[i, 2, j]                  # Eq. S2: the faded log-likelihoods
            w = np.exp(ll - ll.max(axis=0))
            sw = np.sum(w, axis=0)
            ys = np.sum(w * xs, axis=0) / sw
            if p[K.P_MO_PT] > 0.0:                                  # the pass-through
                u = np.clip((np.sum(w * vs, axis=0) / sw - lo) / (hi - lo), 0.0, 1.0)
                ys += u * (seg[k] - ys)
            ys = np.where(c2.min(axis=0) <= gate, ys, seg[k])      # the break test
        y[k][both] = ys[both]
    on = (lf == 1.0) | (lb[:m] == 1.0)
    y[on] = seg[on]                          # the line test: the raw sample
    fin = np.isfinite(seg)
    if finite is not None:
        y = np.clip(y, *finite)
    bad = np.flatnonzero(fin & ~np.isfinite(y))
    y[~fin] = seg[~fin]
    return y, bad


def _blend(p, seg, compiled, pb=None):
    """The forward and backward causal runs of one run of samples blended by their output
    variances (the offline form before :func:`smooth_motion`; the rigid-body option keeps
    it). Returns the blended rate (deg/s)."""
    pb = p if pb is None else pb
    warm = int(p[K.P_WARMUP])
    o = K.ext_offset(p) + K.M_PVAR
    fwd, _, vf = run(pb, K.init_state(pb), seg, trace_index=o, compiled=compiled)
    bwd, _, vb = run(pb, K.init_state(pb), seg[::-1].copy(), trace_index=o, compiled=compiled)
    bwd, vb = bwd[::-1], vb[::-1]
    den = vf + vb
    ok = den > 0.0
    y = 0.5 * (fwd + bwd)
    y[ok] = (vb[ok] * fwd[ok] + vf[ok] * bwd[ok]) / den[ok]
    m = min(warm, seg.shape[0])
    y[:m] = bwd[:m]                       # the forward pass is warming up there
    y[seg.shape[0] - m:] = fwd[seg.shape[0] - m:]   # and the backward one here
    return y


def run_offline(p, z, restarts=None, *, compiled=True, out=None):
    """Whole-record (non-causal) filtering with ``method="motion"``: no lag.

    Each run of samples between restarts is smoothed on its own by
    :func:`smooth_motion` (the two-filter smoother of every model of the bank,
    blended by the models' probabilities given the whole run). With the
    rigid-body option (``max_motion_hz``) the run is low-passed zero-phase
    first (:func:`_rigid_offline`) and the forward and backward runs of the
    causal filter are blended by the inverse of their output variances
    (:func:`_blend`). Measured against filters tuned on the truth in
    docs/method/motion.md. The output stays inside [min, max] of the raw
    samples of its run.

    ``z`` may also be a record spilled to disk: an object with ``len()``, slices read as
    arrays and ``window(a, b)`` (its samples a..b-1 as such an object), e.g.
    :class:`gyrodenoise.io.chunked.SpoolSlice`; ``out`` (given then) the same, written by
    slice assignment: the smoother then holds a block of samples at a time (the rigid-body
    option reads each run whole).

    Returns the filtered rate (deg/s), an ndarray like ``z`` (``out`` when given).
    """
    if p[K.P_METHOD] != K.METHOD_MOTION:
        raise ValueError("offline filtering is defined for method='motion' only")
    spilled = hasattr(z, "window")
    za = z if spilled else np.ascontiguousarray(z, dtype=np.float64)
    n = len(za)
    starts = [0]
    if restarts is not None:
        ra = np.asarray(restarts, dtype=bool)
        if ra.shape != (n,):
            raise ValueError("restarts must have the same length as the samples")
        starts += [int(i) for i in np.flatnonzero(ra) if i > 0]
    bounds = starts + [n]
    if out is None:
        out = np.empty(n)
    p = list(p)
    p[K.P_MO_VAR] = 1.0          # keep the output variance (not computed by the causal filter)
    rigid = p[K.P_LP_NSEC] > 0.0
    o_ext = K.ext_offset(p)
    for a, b in zip(bounds[:-1], bounds[1:]):
        seg = za.window(a, b) if spilled else za[a:b]
        part = out.window(a, b) if hasattr(out, "window") else out[a:b]
        if rigid:
            seg, pb = _rigid_offline(p, np.ascontiguousarray(seg[0:b - a], dtype=np.float64), o_ext, compiled)
            part[0:b - a] = _blend(p, seg, compiled, pb)
        else:
            smooth_motion(p, seg, compiled=compiled, out=part)
    return out
