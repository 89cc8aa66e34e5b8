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


def run_offline(p, z, restarts=None, *, compiled=True):
    """Whole-record (non-causal) filtering with ``method="motion"``: no lag.

    Each run of samples between restarts is filtered forwards and, from a
    fresh state, backwards in time (the same causal core on the reversed
    samples); the output is the mean of the two, which cancels the lag of
    each (a forward filter lags, the backward one leads by as much), weighted
    by the inverse of their variances (the filter's own, ``M_PVAR``: the
    two-filter smoother's combination). Where one of the two is still in its
    warm-up (the raw sample, the first ``P_WARMUP`` samples of its
    direction) the other is used alone. Measured against filters tuned on the
    truth in docs/reports/tuned/report.md. The output stays inside [min, max]
    of the raw samples of its run.

    Returns the filtered rate (deg/s), an ndarray like ``z``.
    """
    if p[K.P_METHOD] != K.METHOD_MOTION:
        raise ValueError("offline filtering is defined for method='motion' only")
    za = np.ascontiguousarray(z, dtype=np.float64)
    n = za.shape[0]
    starts = [0]
    if restarts is not None:
        ra = np.asarray(restarts, dtype=bool)
        if ra.shape != za.shape:
            raise ValueError("restarts must have the same length as the samples")
        starts += [int(i) for i in np.flatnonzero(ra) if i > 0]
    bounds = starts + [n]
    out = np.empty_like(za)
    p = list(p)
    p[K.P_MO_VAR] = 1.0          # keep the output variance (not computed by the causal filter)
    warm = int(p[K.P_WARMUP])
    rigid = p[K.P_LP_NSEC] > 0.0
    o_ext = K.ext_offset(p)
    for a, b in zip(bounds[:-1], bounds[1:]):
        seg = za[a:b]
        pb = p
        if rigid:
            seg, pb = _rigid_offline(p, seg, o_ext, compiled)
        o = o_ext + K.M_PVAR
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
        out[a:b] = y
    return out
