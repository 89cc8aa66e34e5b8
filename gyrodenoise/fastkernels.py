"""The batch loop of :func:`gyrodenoise.kernels.step` with the state held in locals.

:func:`gyrodenoise.batch.run` compiles the per-sample kernels of
:mod:`gyrodenoise.kernels` as they are: every call re-reads the parameters,
re-computes the buffer layout and loads/stores each state scalar through the
flat buffer ``s``. Over a whole record that bookkeeping costs several times
the arithmetic. :func:`run_local` is the same recursion written for a loop:
the parameters and the header scalars of the state (counters, R_hat, q_hat,
d_k's b^(k+1), ...) are local variables for the whole record, the vectors and
matrices live in small private arrays whose size is a compile-time constant
(numba specialises on the length of the ``shape`` tuple), and the state buffer
is unpacked once before and written back once after the loop.

Values that every sample overwrites before it reads them (the last
innovation, S, output and RLS error, the filter's c entry, the c row/column of
P, the scratch vector) are stored into ``s`` where they are final instead of
being carried from sample to sample, and the covariances are read as symmetric
(every state the kernels make is; :func:`gyrodenoise.batch.run` checks it with
:func:`symmetric_state` and otherwise uses the generic loop).

Every floating-point operation is the one :func:`gyrodenoise.kernels.step`
(and :func:`~gyrodenoise.kernels.gate`, ``rls_update``, ``kf_predict``,
``kf_update``, ``start_filter``, ``tie_c``, ``restart``) performs, in the same
order, with fastmath off (no reassociation, no FMA contraction), so the outputs
and the final state are bit-for-bit those of the generic path. The one product
left out, ``x * (1 / lam)`` when ``lam == 1``, is exact. tests/test_fastpath.py
checks every method, orders 1..6, steps, wild samples with the gate on and
off, re-opening, restarts, split runs. Any change of the maths in kernels.py
must be mirrored here; those tests fail otherwise.

Orders above :data:`MAX_ORDER` use the generic loop (compile time grows with
the unrolled size; measured 4-7 s per order up to 8, cached on disk).

Equations are those of Sun et al. (2016), cited as in :mod:`gyrodenoise.kernels`.
"""

from __future__ import annotations

import numpy as np

from . import kernels as K

try:
    import numba
except ImportError:  # pragma: no cover - batch.run then uses the generic path
    numba = None

#: Largest AR order with a specialised loop (higher orders use the generic loop).
MAX_ORDER = 8
#: Methods with a specialised loop (the others use the generic loop).
METHODS = (K.METHOD_NONE, K.METHOD_KF, K.METHOD_SHAKF, K.METHOD_SH_CLASSIC)


def run_local(p, s, z, restarts, out, shape):
    """Filter ``z`` into ``out``, continuing from and updating ``s`` in place.

    Parameters
    ----------
    p : ndarray of float64
        Parameter buffer (:func:`gyrodenoise.kernels.make_params`).
    s : ndarray of float64
        State buffer; overwritten with the state after the last sample.
    z : ndarray of float64
        Raw rate samples, deg/s.
    restarts : ndarray of bool
        True where the gyro restarted.
    out : ndarray of float64
        Receives the filtered rate, deg/s.
    shape : tuple of float
        ``(0.0,) * (order + 1)``: its length fixes the AR order at compile time.
    """
    m = len(shape)
    n = m - 1
    mm = m * m
    # -- parameters, once
    lam = p[K.P_LAM]
    b = p[K.P_B]
    g = p[K.P_GAMMA]
    q0 = p[K.P_Q0]
    r0 = p[K.P_R0]
    p0_rls = p[K.P_P0_RLS]
    p0_kf = p[K.P_P0_KF]
    warmup = p[K.P_WARMUP]
    floor = p[K.P_R_FLOOR]
    ksig = p[K.P_OUTLIER_SIGMA]
    orun = p[K.P_OUTLIER_RUN]
    method = p[K.P_METHOD]
    gate_on = ksig > 0.0 and method != K.METHOD_NONE
    adaptive = method == K.METHOD_SHAKF or method == K.METHOD_SH_CLASSIC
    shakf = method == K.METHOD_SHAKF
    filtering = method != K.METHOD_NONE
    ten_m = 10.0 * m
    kk2 = ksig * ksig
    g2 = g * g
    inv_lam = 1.0 / lam
    scale_rls = lam != 1.0      # x * (1/1) == x exactly: skip the product
    # -- state, unpacked once (offsets as kernels.layout). The covariances are
    # symmetric in every state the kernels produce (run() checks it): read the
    # upper triangle only, so that LLVM keeps one value per pair.
    o_theta = K.N_HEADER
    o_prls = o_theta + m
    o_x = o_prls + mm
    o_p = o_x + m
    o_z = o_p + mm
    o_w = o_z + n
    theta = _vector(shape)
    prls = _matrix(shape)
    x = _vector(shape)
    P = _matrix(shape)
    zh = _vector(shape)        # n used; the spare keeps one size for all vectors
    w = _vector(shape)
    for i in range(m):
        theta[i] = s[o_theta + i]
        x[i] = s[o_x + i]
        w[i] = 0.0
        for j in range(i, m):
            v = s[o_prls + i * m + j]
            prls[i * m + j] = v
            prls[j * m + i] = v
            v = s[o_p + i * m + j]
            P[i * m + j] = v
            P[j * m + i] = v
    for i in range(n):
        zh[i] = s[o_z + i]
    zh[n] = 0.0
    # Header scalars read by the recursion live in locals; those it only writes
    # (innovation, S, output, RLS error) and the rare counters go straight to s.
    # So do the values every sample overwrites before reading them (the filter's
    # c entry x[n], the c row/column of P, the scratch vector w): stored where
    # they are final, they are not carried from sample to sample in registers.
    k = s[K.S_K]
    kd = s[K.S_KD]
    R = s[K.S_R]
    Q = s[K.S_Q]
    s2 = s[K.S_S2]
    ns2 = s[K.S_NS2]
    conv = s[K.S_CONV]
    bk = s[K.S_BK]
    rejrun = s[K.S_REJRUN]

    zref = s[K.S_ZREF]
    lo = s[K.S_LO]
    hi = s[K.S_HI]
    hold = s[K.S_HOLD]
    m_p0 = m * p0_rls

    for t in range(z.shape[0]):
        zt = z[t]
        rs = restarts[t]
        while True:        # runs once; twice when the state must be healed
            code = 0
            xc = 0.0
            if not rs and gate_on and conv == 1.0:
                # ---- kernels.gate: tie_c, then the predicted innovation
                x[n] = theta[n]
                for i in range(n):
                    P[i * m + n] = 0.0
                    P[n * m + i] = 0.0
                P[n * m + n] = floor
                xp = x[n]
                for i in range(n):
                    xp += theta[i] * x[i]
                p00 = P[n * m + n]
                for i in range(n):
                    acc = 0.0
                    for j in range(n):
                        acc += theta[j] * P[i * m + j]
                    p00 += theta[i] * acc
                svg = p00 + Q + R
                vg = (zt - zref) - xp
                if not (vg * vg > kk2 * svg):
                    rejrun = 0.0
                elif rejrun >= orun:
                    rs = True          # a real change of rate: restart (below)
                    s[K.S_NREOPEN] += 1.0
                else:
                    if rejrun == 0.0:
                        hold = 0.0 if K.ar_stable(theta, 0, n, w, 0) else 1.0
                    if hold == 0.0:
                        x0 = _predict(theta, x, P, w, Q, n, m)
                    else:
                        x0 = x[0]
                    for j in range(n - 1, 0, -1):
                        zh[j] = zh[j - 1]
                    zh[0] = x0
                    s[K.S_NREJ] += 1.0
                    rejrun += 1.0
                    s[K.S_INNOV] = vg
                    s[K.S_SVAR] = svg
                    s[K.S_RLS_ERR] = 0.0
                    k += 1.0
                    code = 1
                    xc = x0
            if rs:
                # ---- kernels.restart (the cumulative counters are kept)
                for i in range(m):
                    theta[i] = 0.0
                    x[i] = 0.0
                    w[i] = 0.0
                    zh[i] = 0.0
                for i in range(mm):
                    prls[i] = 0.0
                    P[i] = 0.0
                for i in range(m):
                    prls[i * m + i] = p0_rls
                    P[i * m + i] = p0_kf
                k = 0.0
                kd = 0.0
                R = r0 if r0 > 0.0 else floor
                Q = q0
                s2 = 0.0
                ns2 = 0.0
                conv = 0.0
                s[K.S_INNOV] = 0.0
                s[K.S_SVAR] = 0.0
                s[K.S_NRESET] = 0.0
                s[K.S_OUT] = 0.0
                s[K.S_RLS_ERR] = 0.0
                bk = 0.0
                rejrun = 0.0
                hold = 0.0
            # ---- kernels.step: centring and envelope
            if k == 0.0:
                zref = zt
                lo = zt
                hi = zt
            if zt < lo:
                lo = zt
            if zt > hi:
                hi = zt
            if code == 0:
                zc = zt - zref
                # ---- kernels.filter_step. End of warm-up: noise levels and a
                # filter restarted from the model
                if conv == 0.0:
                    auto = 0.5 * s2
                    if auto < floor:
                        auto = floor
                    Q = q0 if q0 > 0.0 else auto
                    R = r0 if r0 > 0.0 else auto
                    if k >= warmup:
                        conv = 1.0
                        kd = 0.0
                        bk = b
                        # kernels.start_filter (its tie_c is repeated below, idempotent)
                        for i in range(mm):
                            P[i] = 0.0
                        for i in range(n):
                            x[i] = zh[i]
                            P[i * m + i] = R

                # ---- kernels.rls_update, Eq. (8)-(11)
                e = 0.0
                if k >= n:
                    den = _rls_gain(prls, zh, w, lam, n, m)
                    if not (den >= lam):
                        for i in range(mm):
                            prls[i] = 0.0
                        for i in range(m):
                            prls[i * m + i] = p0_rls
                        den = _rls_gain(prls, zh, w, lam, n, m)
                    pred = theta[n]
                    for j in range(n):
                        pred += zh[j] * theta[j]
                    e = zc - pred
                    inv_den = 1.0 / den
                    for i in range(m):
                        theta[i] += w[i] * inv_den * e                    # Eq. (11)
                    forget = scale_rls
                    if scale_rls:
                        tr = 0.0
                        for i in range(m):
                            tr += prls[i * m + i] - w[i] * inv_den * w[i]
                        if tr * inv_lam > m_p0:
                            forget = False                                # bounded
                    for i in range(m):
                        gi = w[i] * inv_den
                        for j in range(i, m):
                            v = prls[i * m + j] - gi * w[j]               # Eq. (10)
                            if forget:
                                v = v * inv_lam
                            prls[i * m + j] = v
                            prls[j * m + i] = v
                for j in range(n - 1, 0, -1):
                    zh[j] = zh[j - 1]
                zh[0] = zc
                s[K.S_RLS_ERR] = e
                if k >= ten_m:
                    ns2 += 1.0
                    s2 += (e * e - s2) / ns2

                if k == 0.0:
                    for i in range(n):
                        x[i] = zc
                    x[n] = 0.0
                    s[o_x + n] = 0.0
                    k = 1.0
                    s[K.S_INNOV] = 0.0
                    xc = zc
                else:
                    # ---- kernels.tie_c, kf_predict, Eq. (34)
                    x[n] = theta[n]
                    for i in range(n):
                        P[i * m + n] = 0.0
                        P[n * m + i] = 0.0
                    P[n * m + n] = floor
                    q = Q
                    xp = _predict(theta, x, P, w, q, n, m)
                    v = zc - xp                                # innovation, Eq. (16)
                    p00 = P[0]
                    r = R
                    if conv == 1.0 and adaptive:
                        if shakf and v * v > g2 * (p00 + r):
                            kd = 0.0                           # Eq. (32) violated
                            s[K.S_NRESET] += 1.0
                            bk = b
                        else:
                            kd += 1.0
                            bk *= b
                            if bk < 1e-290:
                                bk = 0.0
                        d = (1.0 - b) / (1.0 - bk)
                        if shakf:
                            r = (1.0 - d) * r + d * v * v               # Eq. (33)
                        else:
                            r = (1.0 - d) * r + d * (v * v - p00)       # Eq. (22)
                        if r < floor:
                            r = floor
                        R = r
                        svar = _update(x, P, w, v, r, m)
                        k0 = p00 / svar
                        q = q + d * k0 * k0 * (v * v - svar)            # Eq. (26), Q = q e1 e1'
                        if q < floor:
                            q = floor
                        Q = q
                    else:
                        svar = _update(x, P, w, v, r, m)
                    s[K.S_INNOV] = v
                    s[K.S_SVAR] = svar
                    k = k + 1.0
                    xc = zc
                    if conv == 1.0 and filtering:
                        xc = x[0]
            # ---- kernels._healthy: else restart and take zt as a first sample
            if (_finite(x[0]) and _finite(s[K.S_SVAR]) and _finite(R) and _finite(Q)
                    and _finite(s[K.S_RLS_ERR]) and _finite(s2)):
                break
            rs = True
            s[K.S_NHEAL] += 1.0
        if conv == 0.0 or not filtering:
            o = zt
        else:
            o = xc + zref
            if o < lo:
                o = lo
                s[K.S_NCLAMP] += 1.0
            elif o > hi:
                o = hi
                s[K.S_NCLAMP] += 1.0
        s[K.S_OUT] = o
        _store_tail(s, x, P, w, o_x, o_p, o_w, n, m)
        out[t] = o

    # -- the carried state, packed once
    for i in range(m):
        s[o_theta + i] = theta[i]
        for j in range(m):
            s[o_prls + i * m + j] = prls[i * m + j]
    for i in range(n):
        s[o_x + i] = x[i]
        s[o_z + i] = zh[i]
        for j in range(n):
            s[o_p + i * m + j] = P[i * m + j]
        s[o_p + n * m + i] = s[o_p + i * m + n]   # c row = c column (symmetric)
    s[K.S_K] = k
    s[K.S_KD] = kd
    s[K.S_R] = R
    s[K.S_Q] = Q
    s[K.S_S2] = s2
    s[K.S_NS2] = ns2
    s[K.S_CONV] = conv
    s[K.S_BK] = bk
    s[K.S_REJRUN] = rejrun
    s[K.S_ZREF] = zref
    s[K.S_LO] = lo
    s[K.S_HI] = hi
    s[K.S_HOLD] = hold


def symmetric_state(s, order):
    """True if both covariance matrices in state ``s`` are exactly symmetric
    (always so in states made by the kernels; :func:`run_local` relies on it)."""
    s = np.asarray(s)
    o_theta, o_prls, o_x, o_p, o_z, o_w, total = K.layout(int(order))
    m = int(order) + 1
    if s.shape != (total,):
        return False
    for o in (o_prls, o_p):
        a = s[o:o + m * m].reshape(m, m)
        if not np.array_equal(a, a.T):
            return False
    return True


def _store_tail(s, x, P, w, o_x, o_p, o_w, n, m):
    """Store the entries every sample overwrites before reading them: x[n],
    the c column of P (its row is mirrored after the loop) and w."""
    s[o_x + n] = x[n]
    for i in range(m):
        s[o_p + i * m + n] = P[i * m + n]
        s[o_w + i] = w[i]


def _finite(v):
    return v - v == 0.0


def _rls_gain(prls, zh, w, lam, n, m):
    """:func:`gyrodenoise.kernels._rls_gain` on the local arrays."""
    for i in range(m):
        acc = prls[i * m + n]
        for j in range(n):
            acc += prls[i * m + j] * zh[j]
        w[i] = acc
    den = lam + w[n]
    for j in range(n):
        den += zh[j] * w[j]
    return den


def _predict(theta, x, P, w, q, n, m):
    """:func:`gyrodenoise.kernels.kf_predict` on the local arrays, Eq. (34)."""
    x0 = x[n]
    for i in range(n):
        x0 += theta[i] * x[i]
    for i in range(n - 1, 0, -1):
        x[i] = x[i - 1]
    x[0] = x0
    for j in range(m):
        acc = P[n * m + j]
        for i in range(n):
            acc += theta[i] * P[i * m + j]
        w[j] = acc
    for i in range(n - 1, 0, -1):
        for j in range(n - 1, 0, -1):
            P[i * m + j] = P[(i - 1) * m + (j - 1)]
        v = P[(i - 1) * m + n]
        P[i * m + n] = v
        P[n * m + i] = v
    p00 = w[n] + q
    for i in range(n):
        p00 += theta[i] * w[i]
    P[0] = p00
    for j in range(1, n):
        P[j] = w[j - 1]
        P[j * m] = w[j - 1]
    P[n] = w[n]
    P[n * m] = w[n]
    return x0


def _update(x, P, w, v, r, m):
    """:func:`gyrodenoise.kernels.kf_update` on the local arrays, Eq. (35)."""
    svar = P[0] + r
    inv_s = 1.0 / svar
    for i in range(m):
        w[i] = P[i * m]
    for i in range(m):
        x[i] += w[i] * inv_s * v
    for i in range(m):
        ki = w[i] * inv_s
        for j in range(i, m):
            val = P[i * m + j] - ki * w[j]
            P[i * m + j] = val
            P[j * m + i] = val
    for i in range(m):
        if P[i * m + i] < 1e-300:
            P[i * m + i] = 1e-300
    return svar


def _vector(shape):
    """Scratch vector of len(shape) floats (plain-Python fallback)."""
    return np.empty(len(shape))


def _matrix(shape):
    """Scratch len(shape)^2 flat matrix (plain-Python fallback)."""
    return np.empty(len(shape) ** 2)


if numba is not None:
    import llvmlite.ir as _ir
    from numba.core import cgutils as _cgutils
    from numba.core import types as _types
    from numba.extending import intrinsic as _intrinsic

    def _stack_buffer(square):
        """Intrinsic: pointer to a fixed-size float64 array on the stack.

        With the size a compile-time constant and every index a constant once
        the loops over range(m) are unrolled, LLVM keeps the elements in
        registers (SROA): the state is not re-read from memory every sample.
        The arrays never leave :func:`run_local` (helpers are inlined).
        """
        @_intrinsic
        def alloca(typingctx, shape):
            size = len(shape) ** 2 if square else len(shape)

            def codegen(context, builder, sig, args):
                fty = context.get_value_type(_types.float64)
                ptr = _cgutils.alloca_once(builder, _ir.ArrayType(fty, size))
                return builder.bitcast(ptr, fty.as_pointer())
            return _types.CPointer(_types.float64)(shape), codegen
        return alloca

    _alloca_vector = _stack_buffer(False)
    _alloca_matrix = _stack_buffer(True)

    @numba.njit(inline="always")
    def _vector(shape):  # noqa: F811 - compiled replacement
        return numba.carray(_alloca_vector(shape), (len(shape),))

    @numba.njit(inline="always")
    def _matrix(shape):  # noqa: F811 - compiled replacement
        return numba.carray(_alloca_matrix(shape), (len(shape) ** 2,))

    _inline = numba.njit(inline="always", error_model="numpy", boundscheck=False)
    _predict = _inline(_predict)
    _update = _inline(_update)
    _store_tail = _inline(_store_tail)
    _finite = _inline(_finite)
    _rls_gain = _inline(_rls_gain)
    run_local_fast = numba.njit(cache=True, nogil=True, error_model="numpy",
                                boundscheck=False)(run_local)
else:  # pragma: no cover
    run_local_fast = None
