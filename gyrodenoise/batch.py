"""Batch loop over arrays: the kernels of :mod:`gyrodenoise.kernels`, compiled.

The loop below is written once; with numba installed it is compiled by
``numba.njit`` (the kernels it calls are ``register_jitable``), without numba
it runs as plain Python over the same functions. Both give the same numbers
(tested to 1e-12).

The common case (compiled, no diagnostics, no theta history) is dispatched to
:func:`gyrodenoise.fastkernels.run_local`, the same recursion with the state
held in locals for the whole record (several times faster; bit-identical
outputs and final state, tests/test_fastpath.py). ``fast=False`` forces the
generic compiled loop (used by the tests and benchmarks/bench_core.py).
"""

from __future__ import annotations

import numpy as np

from . import fastkernels as F
from . import kernels as K

try:
    import numba
except ImportError:  # pragma: no cover
    numba = None


def _run_py(p, s, z, restarts, out, diag):
    """Filter ``z`` into ``out``; ``diag`` (n_samples x 4 or 0 rows) receives
    [innovation, R_hat, converged, rls_error] per sample."""
    want_diag = len(diag) > 0
    for i in range(len(z)):
        out[i] = K.step(p, s, z[i], restarts[i])
        if want_diag:
            diag[i, 0] = s[K.S_INNOV]
            diag[i, 1] = s[K.S_R]
            diag[i, 2] = s[K.S_CONV]
            diag[i, 3] = s[K.S_RLS_ERR]


def _run_theta_py(p, s, z, restarts, out, theta):
    """As :func:`_run_py`, also recording [phi_1..phi_n, c] per sample."""
    n = int(p[K.P_ORDER])
    o = K.N_HEADER
    for i in range(len(z)):
        out[i] = K.step(p, s, z[i], restarts[i])
        for j in range(n):
            theta[i, j] = s[o + j]
        theta[i, n] = K.c_deg_s(p, s)


def invalidate_stale_cache(owner, patterns):
    """numba keys its on-disk cache on the file of the jitted function only,
    not on the kernels it inlines: drop the cache files matching ``patterns``
    (globs in this package's ``__pycache__``) when kernels.py changed since
    ``owner``'s stamp was written. Used here (batch, fastkernels) and by
    :mod:`gyrodenoise.reference_filters`."""
    import hashlib
    from pathlib import Path
    here = Path(__file__).resolve().parent
    digest = hashlib.sha256((here / "kernels.py").read_bytes()).hexdigest()
    cache = here / "__pycache__"
    stamp = cache / f"{owner}.kernels.sha256"
    try:
        if stamp.exists() and stamp.read_text() == digest:
            return
        for pattern in patterns:
            for f in cache.glob(pattern):
                f.unlink()
        cache.mkdir(exist_ok=True)
        stamp.write_text(digest)
    except OSError:  # read-only install: numba then does not cache either
        pass


if numba is not None:
    # (fastkernels.py reads only constants from kernels.py; its cache is checked too)
    invalidate_stale_cache("batch", ("batch.*.nb[ic]", "fastkernels.*.nb[ic]"))
    _run_fast = numba.njit(cache=True, nogil=True, error_model="numpy")(_run_py)
    _run_theta_fast = numba.njit(cache=True, nogil=True, error_model="numpy")(_run_theta_py)
else:  # pragma: no cover
    _run_fast = _run_py
    _run_theta_fast = _run_theta_py


def run(p, s, z, restarts=None, *, diagnostics=False, record_theta=False,
        compiled=True, fast=True):
    """Filter an array of raw samples, continuing from state ``s``.

    Parameters
    ----------
    p : sequence of float
        Parameter buffer from :func:`gyrodenoise.kernels.make_params`.
    s : sequence of float
        State buffer (from :func:`gyrodenoise.kernels.init_state` or a previous
        call); it is *not* modified: the final state is returned.
    z : array_like
        Raw rate samples, deg/s.
    restarts : array_like of bool, optional
        True where the gyro restarted (that sample is the first of a run).
    diagnostics : bool
        Also return an (n, 4) array [innovation, R_hat, converged, rls_error].
    record_theta : bool
        Also return an (n, order+1) array of [phi_1..phi_n, c] after each sample.
    compiled : bool
        Use the numba-compiled loop (False: the plain-Python loop, same code).
    fast : bool
        With ``compiled`` and neither ``diagnostics`` nor ``record_theta``
        (and AR order <= ``fastkernels.MAX_ORDER``, symmetric covariances in
        ``s`` as in every state the kernels make): use the specialised loop of
        :mod:`gyrodenoise.fastkernels` (same numbers, several times faster).
        False forces the generic compiled loop.

    Returns
    -------
    out : ndarray
        Filtered rate, deg/s.
    state : ndarray
        State after the last sample (pass it back in to continue).
    extra : ndarray, optional
        Diagnostics or theta history when asked for.
    """
    pa = np.asarray(p, dtype=np.float64)
    sa = np.array(s, dtype=np.float64)
    za = np.ascontiguousarray(z, dtype=np.float64)
    if restarts is None:
        ra = np.zeros(za.shape[0], dtype=np.bool_)
    else:
        ra = np.ascontiguousarray(restarts, dtype=np.bool_)
        if ra.shape != za.shape:
            raise ValueError("restarts must have the same length as the samples")
    out = np.empty_like(za)
    if record_theta:
        theta = np.empty((za.shape[0], int(pa[K.P_ORDER]) + 1))
        fn = _run_theta_fast if compiled else _run_theta_py
        if compiled:
            fn(pa, sa, za, ra, out, theta)
        else:
            sl = list(sa)
            fn(list(pa), sl, za, ra, out, theta)
            sa = np.asarray(sl)
        return out, sa, theta
    order = int(pa[K.P_ORDER])
    if (compiled and fast and not diagnostics and F.run_local_fast is not None
            and pa[K.P_METHOD] in F.METHODS
            and order <= F.MAX_ORDER and F.symmetric_state(sa, order)):
        F.run_local_fast(pa, sa, za, ra, out, (0.0,) * (order + 1))
        return out, sa
    diag = np.empty((za.shape[0] if diagnostics else 0, 4))
    if compiled:
        _run_fast(pa, sa, za, ra, out, diag)
    else:
        sl = list(sa)
        _run_py(list(pa), sl, za.tolist(), ra.tolist(), out, diag)
        sa = np.asarray(sl)
    if diagnostics:
        return out, sa, diag
    return out, sa
