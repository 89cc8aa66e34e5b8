/*
 * gdcore.c -- the per-sample filter kernels, translated from
 * gyrodenoise/core/kernels.py (the executable specification; read the docstrings
 * there for the equations and the reasons). Every function keeps the Python's
 * operations and their order: a + b * c stays (a + (b * c)), d * v * v stays
 * ((d * v) * v). Build with -O2 -ffp-contract=off, never -ffast-math.
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "gdcore.h"

#define ORDER(p) ((int)(p)[P_ORDER])

/* The kernels are inlined into the batch loop, specialised there for the
 * common AR orders (constant loop bounds); the arithmetic is unchanged. */
#if defined(__GNUC__)
#define KERNEL static inline __attribute__((always_inline))
#if !defined(__clang__) && defined(__x86_64__) && defined(__linux__) && defined(__GLIBC__) && __GNUC__ >= 8 \
    && !defined(GD_NO_TARGET_CLONES)
/* gd_run's motion loop and gd_step compiled twice, for AVX2 machines (chosen at load
   time, glibc's ifunc) and for the rest: the bank's loops four lanes at a time. The
   same IEEE operations (no fused multiply-add: -ffp-contract=off, and AVX2 alone does
   not enable FMA), so the same bits (tests/core/test_c_core_equals_python.py runs
   whichever this machine picks). -DGD_NO_TARGET_CLONES builds the one copy. */
#define GD_CLONES __attribute__((noinline, target_clones("avx2", "default")))
#endif
#define RARE static __attribute__((noinline, cold))   /* kept out of the hot loop */
#else
#define KERNEL static inline
#define RARE static
#endif

#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 8
#define UNROLL _Pragma("GCC unroll 16")
#elif defined(__clang__)
#define UNROLL _Pragma("clang loop unroll(full)")
#else
#define UNROLL
#endif

KERNEL void tie_c_(const double *p, double *s);

KERNEL gd_layout_t layout_(int n)
{
    gd_layout_t L;
    long m = (long)n + 1;
    L.theta = N_HEADER;
    L.prls = L.theta + m;
    L.x = L.prls + m * m;
    L.p = L.x + m;
    L.z = L.p + m * m;
    L.w = L.z + n;
    L.total = L.w + m + N_EXT;
    return L;
}

KERNEL long layout_total_(int n)
{
    return layout_(n).total;
}

const char *gd_check(const double *p, long n_p, long n_s)
{
    double order, nsec;
    if (n_p < N_PARAMS)
        return "p is too short: fewer than N_PARAMS floats";
    order = p[P_ORDER];
    if (!(order >= 1.0 && order <= (double)GD_MAX_ORDER))
        return "p[P_ORDER] must be >= 1 and <= 100000";
    nsec = p[P_LP_NSEC];
    if (!(nsec >= 0.0 && nsec < (double)(MAX_SOS + 1)))
        return "p[P_LP_NSEC] must be in 0..MAX_SOS";
    if (n_s != layout_total_(ORDER(p)))
        return "s has the wrong length for the AR order p[P_ORDER]";
    if (p[P_METHOD] == METHOD_MOTION) {   /* the bank's and the history's sizes in s and in mo_bank_t */
        double nf = p[P_MO_NF], nlag = p[P_MO_NLAG];
        if (!(nf >= 1.0 && nf <= (double)MO_MAX_NF && nf == (double)(int)nf))
            return "p[P_MO_NF] must be a whole number in 1..MO_MAX_NF";
        if (!(p[P_MO_NCA] >= 0.0 && p[P_MO_NCA] <= (double)MO_MAX_NF - nf
              && p[P_MO_NCA] == (double)(int)p[P_MO_NCA]))
            return "p[P_MO_NCA] must be a whole number in 0..MO_MAX_NF - p[P_MO_NF]";
        if (!(nlag >= 1.0 && nlag <= (double)MO_MAX_NLAG && nlag == (double)(int)nlag))
            return "p[P_MO_NLAG] must be a whole number in 1..MO_MAX_NLAG";
    }
    return NULL;
}

KERNEL void restart_(const double *p, double *s)
{
    int n = ORDER(p);
    long m = (long)n + 1;
    gd_layout_t L = layout_(n);
    double nrej = s[S_NREJ], nreopen = s[S_NREOPEN], nclamp = s[S_NCLAMP], nheal = s[S_NHEAL];
    long i;
    for (i = 0; i < L.total - GB_N; i++)   /* the bias tracking's block (M_BIAS, last) is kept */
        s[i] = 0.0;
    s[S_NREJ] = nrej;
    s[S_NREOPEN] = nreopen;
    s[S_NCLAMP] = nclamp;
    s[S_NHEAL] = nheal;
    for (i = 0; i < m; i++) {
        s[L.prls + i * m + i] = p[P_P0_RLS];
        s[L.p + i * m + i] = p[P_P0_KF];
    }
    s[S_R] = p[P_R0] > 0.0 ? p[P_R0] : p[P_R_FLOOR];
    s[S_Q] = p[P_Q0];
}

/* g = P h into w (h = regressor, h[n] = 1); returns lam + h' P h */
KERNEL double rls_gain(const double *p, double *s, long o_prls, long o_z, long o_w, int n, long m)
{
    long i, j;
    double acc, den;
    for (i = 0; i < m; i++) {
        acc = s[o_prls + i * m + n];
        for (j = 0; j < n; j++)
            acc += s[o_prls + i * m + j] * s[o_z + j];
        s[o_w + i] = acc;
    }
    den = p[P_LAM] + s[o_w + n];
    for (j = 0; j < n; j++)
        den += s[o_z + j] * s[o_w + j];
    return den;
}

KERNEL double rls_update_(const double *p, double *s, double z)
{
    int n = ORDER(p);
    long m = (long)n + 1;
    double lam = p[P_LAM];
    gd_layout_t L = layout_(n);
    double e = 0.0;
    long i, j;
    if (s[S_K] >= (double)n) {
        double den = rls_gain(p, s, L.prls, L.z, L.w, n, m);
        double pred, inv_den, scale;
        if (!(den >= lam)) {
            for (i = 0; i < m * m; i++)
                s[L.prls + i] = 0.0;
            for (i = 0; i < m; i++)
                s[L.prls + i * m + i] = p[P_P0_RLS];
            den = rls_gain(p, s, L.prls, L.z, L.w, n, m);
        }
        pred = s[L.theta + n];
        for (j = 0; j < n; j++)
            pred += s[L.z + j] * s[L.theta + j];
        e = z - pred;
        inv_den = 1.0 / den;
        for (i = 0; i < m; i++)
            s[L.theta + i] += s[L.w + i] * inv_den * e;
        scale = 1.0 / lam;
        if (lam != 1.0) {
            double tr = 0.0;
            for (i = 0; i < m; i++)
                tr += s[L.prls + i * m + i] - s[L.w + i] * inv_den * s[L.w + i];
            if (tr * scale > (double)m * p[P_P0_RLS])
                scale = 1.0;
        }
        for (i = 0; i < m; i++) {
            double gi = s[L.w + i] * inv_den;
            for (j = i; j < m; j++) {
                double v = (s[L.prls + i * m + j] - gi * s[L.w + j]) * scale;
                s[L.prls + i * m + j] = v;
                s[L.prls + j * m + i] = v;
            }
        }
    }
    for (j = n - 1; j > 0; j--)
        s[L.z + j] = s[L.z + j - 1];
    s[L.z] = z;
    return e;
}

KERNEL double kf_predict_(const double *p, double *s, double q)
{
    int n = ORDER(p);
    long m = (long)n + 1;
    gd_layout_t L = layout_(n);
    long i, j;
    double x0, acc, p00, v;
    x0 = s[L.x + n];
    for (i = 0; i < n; i++)
        x0 += s[L.theta + i] * s[L.x + i];
    for (i = n - 1; i > 0; i--)
        s[L.x + i] = s[L.x + i - 1];
    s[L.x] = x0;
    for (j = 0; j < m; j++) {
        acc = s[L.p + n * m + j];
        for (i = 0; i < n; i++)
            acc += s[L.theta + i] * s[L.p + i * m + j];
        s[L.w + j] = acc;
    }
    for (i = n - 1; i > 0; i--) {
        for (j = n - 1; j > 0; j--)
            s[L.p + i * m + j] = s[L.p + (i - 1) * m + (j - 1)];
        v = s[L.p + (i - 1) * m + n];
        s[L.p + i * m + n] = v;
        s[L.p + n * m + i] = v;
    }
    p00 = s[L.w + n] + q;
    for (i = 0; i < n; i++)
        p00 += s[L.theta + i] * s[L.w + i];
    s[L.p] = p00;
    for (j = 1; j < n; j++) {
        s[L.p + j] = s[L.w + j - 1];
        s[L.p + j * m] = s[L.w + j - 1];
    }
    s[L.p + n] = s[L.w + n];
    s[L.p + n * m] = s[L.w + n];
    return x0;
}

KERNEL double kf_update_(const double *p, double *s, double v, double r)
{
    int n = ORDER(p);
    long m = (long)n + 1;
    gd_layout_t L = layout_(n);
    long i, j;
    double svar = s[L.p] + r;
    double inv_s = 1.0 / svar;
    for (i = 0; i < m; i++)
        s[L.w + i] = s[L.p + i * m];
    for (i = 0; i < m; i++)
        s[L.x + i] += s[L.w + i] * inv_s * v;
    for (i = 0; i < m; i++) {
        double ki = s[L.w + i] * inv_s;
        for (j = i; j < m; j++) {
            double val = s[L.p + i * m + j] - ki * s[L.w + j];
            s[L.p + i * m + j] = val;
            s[L.p + j * m + i] = val;
        }
    }
    for (i = 0; i < m; i++)
        if (s[L.p + i * m + i] < 1e-300)
            s[L.p + i * m + i] = 1e-300;
    return svar;
}

KERNEL void start_filter_(const double *p, double *s)
{
    int n = ORDER(p);
    long m = (long)n + 1;
    gd_layout_t L = layout_(n);
    long i;
    for (i = 0; i < m * m; i++)
        s[L.p + i] = 0.0;
    for (i = 0; i < n; i++) {
        s[L.x + i] = s[L.z + i];
        s[L.p + i * m + i] = s[S_R];
    }
    tie_c_(p, s);
}

KERNEL void tie_c_(const double *p, double *s)
{
    int n = ORDER(p);
    long m = (long)n + 1;
    gd_layout_t L = layout_(n);
    long i;
    s[L.x + n] = s[L.theta + n];
    for (i = 0; i < n; i++) {
        s[L.p + i * m + n] = 0.0;
        s[L.p + n * m + i] = 0.0;
    }
    s[L.p + n * m + n] = p[P_R_FLOOR];
}

/* a and w may be the same buffer (step passes s twice) */
KERNEL int ar_stable_(const double *a, long o_a, int n, double *w, long o_w)
{
    int i, order, lo, hi;
    double kr, den, al, ah;
    for (i = 0; i < n; i++)
        w[o_w + i] = -a[o_a + i];
    for (order = n; order > 0; order--) {
        kr = w[o_w + order - 1];
        if (!(kr * kr < 1.0))
            return 0;
        den = 1.0 - kr * kr;
        lo = 1;
        hi = order - 1;
        while (lo < hi) {
            al = w[o_w + lo - 1];
            ah = w[o_w + hi - 1];
            w[o_w + lo - 1] = (al - kr * ah) / den;
            w[o_w + hi - 1] = (ah - kr * al) / den;
            lo += 1;
            hi -= 1;
        }
        if (lo == hi) {
            al = w[o_w + lo - 1];
            w[o_w + lo - 1] = (al - kr * al) / den;
        }
    }
    return 1;
}

KERNEL int gate_(const double *p, double *s, double z)
{
    int n = ORDER(p);
    long m = (long)n + 1;
    gd_layout_t L = layout_(n);
    long i, j;
    double xp, p00, acc, svar, v, k, x0;
    tie_c_(p, s);
    xp = s[L.x + n];
    for (i = 0; i < n; i++)
        xp += s[L.theta + i] * s[L.x + i];
    p00 = s[L.p + n * m + n];
    for (i = 0; i < n; i++) {
        long row = L.p + i * m;
        acc = 0.0;
        for (j = 0; j < n; j++)
            acc += s[L.theta + j] * s[row + j];
        p00 += s[L.theta + i] * acc;
    }
    svar = p00 + s[S_Q] + s[S_R];
    v = z - xp;
    k = p[P_OUTLIER_SIGMA];
    if (!(v * v > k * k * svar)) {
        s[S_REJRUN] = 0.0;
        return 0;
    }
    if (s[S_REJRUN] >= p[P_OUTLIER_RUN]) {
        restart_(p, s);
        s[S_NREOPEN] += 1.0;
        return 2;
    }
    if (s[S_REJRUN] == 0.0)
        s[S_HOLD] = ar_stable_(s, L.theta, n, s, L.w) ? 0.0 : 1.0;
    if (s[S_HOLD] == 0.0)
        x0 = kf_predict_(p, s, s[S_Q]);
    else
        x0 = s[L.x];
    for (j = n - 1; j > 0; j--)
        s[L.z + j] = s[L.z + j - 1];
    s[L.z] = x0;
    s[S_NREJ] += 1.0;
    s[S_REJRUN] += 1.0;
    s[S_INNOV] = v;
    s[S_SVAR] = svar;
    s[S_RLS_ERR] = 0.0;
    s[S_K] += 1.0;
    s[S_OUT] = x0;
    return 1;
}

KERNEL double filter_step_(const double *p, double *s, double z)
{
    int n = ORDER(p);
    double method = p[P_METHOD];
    double floor_ = p[P_R_FLOOR];
    gd_layout_t L = layout_(n);
    double k = s[S_K];
    long m = (long)n + 1;
    long i;
    int converged;
    double e, q, xp, v, p00, r, svar, out;

    converged = k >= p[P_WARMUP];
    if (s[S_CONV] == 0.0) {
        double autolevel = 0.5 * s[S_S2];
        if (autolevel < floor_)
            autolevel = floor_;
        s[S_Q] = p[P_Q0] > 0.0 ? p[P_Q0] : autolevel;
        s[S_R] = p[P_R0] > 0.0 ? p[P_R0] : autolevel;
        if (converged) {
            s[S_CONV] = 1.0;
            s[S_KD] = 0.0;
            s[S_BK] = p[P_B];
            start_filter_(p, s);
        }
    }

    e = rls_update_(p, s, z);
    s[S_RLS_ERR] = e;
    if (k >= 10.0 * (double)m) {
        s[S_NS2] += 1.0;
        s[S_S2] += (e * e - s[S_S2]) / s[S_NS2];
    }

    if (k == 0.0) {
        for (i = 0; i < n; i++)
            s[L.x + i] = z;
        s[L.x + n] = 0.0;
        s[S_K] = 1.0;
        s[S_OUT] = z;
        s[S_INNOV] = 0.0;
        return z;
    }

    tie_c_(p, s);
    q = s[S_Q];
    xp = kf_predict_(p, s, q);
    v = z - xp;
    p00 = s[L.p];
    r = s[S_R];
    if (s[S_CONV] == 1.0 && (method == METHOD_SHAKF || method == METHOD_SH_CLASSIC)) {
        double b = p[P_B];
        double g = p[P_GAMMA];
        double d, k0;
        if (method == METHOD_SHAKF && v * v > g * g * (p00 + r)) {
            s[S_KD] = 0.0;
            s[S_NRESET] += 1.0;
            s[S_BK] = b;
        } else {
            s[S_KD] += 1.0;
            s[S_BK] *= b;
            if (s[S_BK] < 1e-290)
                s[S_BK] = 0.0;
        }
        d = (1.0 - b) / (1.0 - s[S_BK]);
        if (method == METHOD_SHAKF)
            r = (1.0 - d) * r + d * v * v;
        else
            r = (1.0 - d) * r + d * (v * v - p00);
        if (r < floor_)
            r = floor_;
        s[S_R] = r;
        svar = kf_update_(p, s, v, r);
        k0 = p00 / svar;
        q = q + d * k0 * k0 * (v * v - svar);
        if (q < floor_)
            q = floor_;
        s[S_Q] = q;
    } else {
        svar = kf_update_(p, s, v, r);
    }

    s[S_INNOV] = v;
    s[S_SVAR] = svar;
    s[S_K] = k + 1.0;
    out = z;
    if (s[S_CONV] == 1.0 && method != METHOD_NONE)
        out = s[L.x];
    s[S_OUT] = out;
    return out;
}

/* kernels.sos_cascade: the Butterworth cascade of p[P_SOS ...], delays at s[o ...] */
KERNEL double sos_cascade_(const double *p, double *s, long o, double z)
{
    double y = z, x;
    int i, nsec = (int)p[P_LP_NSEC];
    for (i = 0; i < nsec; i++) {
        int c = P_SOS + 5 * i;
        x = y;
        y = p[c] * x + s[o + 2 * i];
        s[o + 2 * i] = p[c + 1] * x - p[c + 3] * y + s[o + 2 * i + 1];
        s[o + 2 * i + 1] = p[c + 2] * x - p[c + 4] * y;
    }
    return y;
}

KERNEL double lowpass_step_(const double *p, double *s, double z)
{
    double y = sos_cascade_(p, s, layout_total_(ORDER(p)) - N_EXT, z);
    s[S_K] += 1.0;
    s[S_CONV] = 1.0;
    return y;
}

/* kernels.one_euro_step: the 1-euro filter (Casiez et al. 2012) on the centred sample */
KERNEL double one_euro_step_(const double *p, double *s, double z)
{
    long o = layout_total_(ORDER(p)) - N_EXT;
    double x;
    if (s[S_K] == 0.0) {
        x = z;
        s[o + OE_DX] = 0.0;
    } else {
        double fs = p[P_FS];
        double ad = 1.0 / (1.0 + fs / (6.283185307179586 * p[P_OE_DCUT]));
        double dx = s[o + OE_DX], a;
        dx = dx + ad * ((z - s[o + OE_ZP]) * fs - dx);
        s[o + OE_DX] = dx;
        a = 1.0 / (1.0 + fs / (6.283185307179586 * (p[P_OE_MIN] + p[P_OE_BETA] * fabs(dx))));
        x = s[o + OE_X];
        x = x + a * (z - x);
    }
    s[o + OE_X] = x;
    s[o + OE_ZP] = z;
    s[S_K] += 1.0;
    s[S_CONV] = 1.0;
    return x;
}

/* ---- kernels.butter_sos, operation for operation (complex arithmetic as CPython's): the
 * native FMU designs its low-passes here, the extension exposes it for the tests */
static double (*volatile libm_pow)(double, double) = pow; /* Python's float ** calls pow() */
/* cmath.exp calls sin() and cos(): called through pointers so that gcc does not fuse them into
 * the GNU sincos() (not in every libm; a weak reference in gdfmi_libm.h) */
static double (*volatile libm_sin)(double) = sin;
static double (*volatile libm_cos)(double) = cos;

/* _Py_c_quot: complex division as CPython does it */
static void py_c_quot(double ar, double ai, double br, double bi, double *rr, double *ri)
{
    double abs_br = br < 0 ? -br : br, abs_bi = bi < 0 ? -bi : bi;
    if (abs_br >= abs_bi) {
        if (abs_br == 0.0) {
            *rr = *ri = 0.0;
        } else {
            double ratio = bi / br, denom = br + bi * ratio;
            *rr = (ar + ai * ratio) / denom;
            *ri = (ai - ar * ratio) / denom;
        }
    } else if (abs_bi >= abs_br) {
        double ratio = br / bi, denom = br * ratio + bi;
        *rr = (ar * ratio + ai) / denom;
        *ri = (ai * ratio - ar) / denom;
    } else {
        *rr = *ri = NAN;
    }
}

int gd_butter_sos(int order, double cutoff_hz, double fs, double *p)
{
    const double pi = 3.141592653589793; /* math.pi */
    double fs2 = 2.0 * fs;
    double wc = fs2 * tan(pi * cutoff_hz / fs);
    int k, nsec = 0;
    for (k = 0; k < order / 2; k++) {
        /* 1j * math.pi * (2k + order + 1) / (2 order): (0, pi m) / (2N, 0) */
        double ang_r, ang_i, cr, ci, sr, si, zr, zi, a1, a2, g;
        py_c_quot(0.0 * (double)(2 * k + order + 1) - pi * 0.0, pi * (double)(2 * k + order + 1),
                  (double)(2 * order), 0.0, &ang_r, &ang_i);
        /* cmath.exp */
        cr = exp(ang_r) * libm_cos(ang_i);
        ci = exp(ang_r) * libm_sin(ang_i);
        /* wc * (cr, ci) */
        sr = wc * cr - 0.0 * ci;
        si = wc * ci + 0.0 * cr;
        /* (fs2 + sp) / (fs2 - sp) */
        py_c_quot(fs2 + sr, 0.0 + si, fs2 - sr, 0.0 - si, &zr, &zi);
        a1 = -2.0 * zr;
        a2 = libm_pow(hypot(zr, zi), 2.0);
        g = (1.0 + a1 + a2) / 4.0;
        p[P_SOS + 5 * nsec + 0] = g;
        p[P_SOS + 5 * nsec + 1] = 2.0 * g;
        p[P_SOS + 5 * nsec + 2] = g;
        p[P_SOS + 5 * nsec + 3] = a1;
        p[P_SOS + 5 * nsec + 4] = a2;
        nsec++;
    }
    if (order % 2) {
        double zp = (fs2 - wc) / (fs2 + wc);
        double g = (1.0 - zp) / 2.0;
        p[P_SOS + 5 * nsec + 0] = g;
        p[P_SOS + 5 * nsec + 1] = g;
        p[P_SOS + 5 * nsec + 2] = 0.0;
        p[P_SOS + 5 * nsec + 3] = -zp;
        p[P_SOS + 5 * nsec + 4] = 0.0;
        nsec++;
    }
    return nsec;
}


/* kernels.rank_mean: the mean of the MO_SPEC_RANK-th smallest of n_bins exponential
 * variables of mean 1 (the spectral floors' order-statistic bias) */
static double rank_mean_(int n_bins)
{
    double c = 0.0;
    int i;
    for (i = 0; i < MO_SPEC_RANK; i++)
        c += 1.0 / (double)(n_bins - i);
    return c;
}

/* kernels.motion_params(fs) with its defaults, written into p[P_MO_NF ...]
 * (the native FMU builds its parameters here; the tests hold it to the
 * Python bit for bit). */
void gd_motion_params(double *p, double fs)
{
    const int nf = 13, nca = 3;
    const double lmin = -10.0, lmax = 2.0, amin = -2.0, amax = 0.0;
    int i;
    p[P_MO_NF] = (double)nf;
    p[P_MO_FADE] = exp(-1.0 / (3.0 * fs));
    p[P_MO_BR] = 1.0 - 1.0 / (10.0 * fs);
    p[P_MO_RESET] = 20.0;
    p[P_MO_NLAG] = 6.0;
    p[P_MO_HUBER] = 4.0;
    p[P_MO_KAPPA] = 1.0 / (30.0 * fs);
    p[P_MO_CLIP2] = 4.0 * 4.0;
    p[P_MO_VAR] = 0.0;
    for (i = 0; i < 5 * MO_MAX_NF; i++)
        p[P_MO_G + i] = 0.0;
    for (i = 0; i < nf; i++) {
        double e = lmin + (lmax - lmin) * i / (double)(nf - 1);
        double lam = pow(10.0, e);
        double r = sqrt(lam * lam + 8.0 * lam);
        double alpha = -(lam * lam + 8.0 * lam - (lam + 4.0) * r) / 8.0;
        double beta = (lam * lam + 4.0 * lam - lam * r) / 4.0;
        p[P_MO_G + i] = alpha;
        p[P_MO_G + MO_MAX_NF + i] = beta;
        p[P_MO_G + 2 * MO_MAX_NF + i] = -log(1.0 - alpha);
        p[P_MO_G + 4 * MO_MAX_NF + i] = beta * beta / (1.0 - alpha);
    }
    for (i = 0; i < nca; i++) {     /* kernels.ca_gains: Newton on the cubic, a fixed count */
        double e = amin + (amax - amin) * i / (double)(nca - 1);
        double lam = pow(10.0, e), u = 1.0, alpha;
        int it;
        for (it = 0; it < CA_NEWTON_STEPS; it++) {
            double g = ((2.0 * u - lam) * u + 3.0 * lam) * u - 2.0 * lam;
            double dg = (6.0 * u - 2.0 * lam) * u + 3.0 * lam;
            u = u - g / dg;
        }
        alpha = u * (2.0 - u);
        p[P_MO_G + nf + i] = alpha;
        p[P_MO_G + MO_MAX_NF + nf + i] = 2.0 * u * u;
        p[P_MO_G + 2 * MO_MAX_NF + nf + i] = -log(1.0 - alpha);
        p[P_MO_G + 3 * MO_MAX_NF + nf + i] = 2.0 * u * u * u / (2.0 - u);
        p[P_MO_G + 4 * MO_MAX_NF + nf + i] = lam * lam;
    }
    p[P_MO_RFIX] = 0.0;
    gd_spectral_params(p, p[P_MO_BR], 1.5);
    {
        double t = 0.02 * fs;
        p[P_MO_PT] = 1.0 / (t >= 1.0 ? t : 1.0);
        p[P_MO_PT + 1] = 0.7;
        p[P_MO_PT + 2] = 0.95;
    }
    {
        double c = rank_mean_(MO_HI_NB);
        p[P_MO_LINE] = p[P_MO_SPEC] > 0.0 ? 10.0 / c : 0.0;
        p[P_MO_SPECH] = p[P_MO_SPEC] > 0.0 ? 1.0 / (c * (0.375 * MO_SPEC_N)) : 0.0;
    }
    {
        double t = 0.1 * fs, fc = exp(-1.0 / (t >= 1.0 ? t : 1.0));
        p[P_MO_CUS] = fc;
        p[P_MO_CUS + 1] = 1.0;
        p[P_MO_CUS + 2] = 3.75 * 3.75 / (1.0 - fc * fc);
    }
    p[P_MO_NCA] = (double)nca;
}

/* kernels.spectral_params(b, ratio) into p[P_MO_SPEC ...] */
void gd_spectral_params(double *p, double b, double ratio)
{
    double c = rank_mean_(MO_SPEC_NB), bb = 1.0;
    int i;
    for (i = 0; i < MO_SPEC_N; i++)
        bb *= b;
    for (i = 0; i < MO_SPEC_N; i++)
        p[P_MO_COS + i] = cos(2.0 * 3.141592653589793 * (double)i / (double)MO_SPEC_N);
    p[P_MO_SBB] = bb;
    if (ratio < 0.0) {
        p[P_MO_SPEC] = 0.0;
        p[P_MO_SRATIO] = 0.0;
    } else {
        p[P_MO_SPEC] = 1.0 / (c * (0.375 * MO_SPEC_N));
        p[P_MO_SRATIO] = ratio;
    }
}

/* kernels._forget_weight: d_k = (1 - b) / (1 - bk), without the division once
 * 1 - bk rounds to 1 */
KERNEL double forget_weight_(double b, double bk)
{
    double den = 1.0 - bk;
    if (den == 1.0)
        return 1.0 - b;
    return (1.0 - b) / den;
}

/* kernels._insert_low: offer pw to the MO_SPEC_RANK smallest (ascending, nl
 * filled); returns the new count */
KERNEL int insert_low_(double *low, int nl, double pw)
{
    int i;
    if (nl < MO_SPEC_RANK) {
        i = nl;
        nl++;
    } else if (pw < low[MO_SPEC_RANK - 1]) {
        i = MO_SPEC_RANK - 1;
    } else {
        return nl;
    }
    while (i > 0 && low[i - 1] > pw) {
        low[i] = low[i - 1];
        i--;
    }
    low[i] = pw;
    return nl;
}

/* kernels._floor_update: one block's estimate xb into the smoothed floor s[im]
 * (Sage-Husa weight from s[ibk], Huber clip); returns the new floor */
KERNEL double floor_update_(const double *restrict p, double *restrict s, long im, long ibk, double xb)
{
    double bb = p[P_MO_SBB], d, m;
    s[ibk] *= bb;
    d = forget_weight_(bb, s[ibk]);
    m = s[im];
    if (d < 0.25 && xb > p[P_MO_HUBER] * m)
        xb = p[P_MO_HUBER] * m;
    m += d * (xb - m);
    if (m == 0.0)
        s[ibk] = 1.0;
    s[im] = m;
    return m;
}

/* kernels.spectral_floor: the white-noise variance from a low quantile of the
 * Hann-windowed spectrum's bins 0.0625-0.48 fs, blocks of MO_SPEC_N samples,
 * accumulated sample by sample; 0.0 before the first block; the line test's
 * own floor from the MO_HI_NB bins from MO_HI_J0 (see kernels.py) */
KERNEL double spectral_floor_(const double *restrict p, double *restrict s, long o, double z, double k)
{
    const double *cs = p + P_MO_COS;
    double x, low[MO_SPEC_RANK], lowh[MO_SPEC_RANK], w1[MO_SPEC_NB], w2[MO_SPEC_NB], cf[MO_SPEC_NB], m, top;
    int n, j, nl, nh;
    if (k == 0.0) {
        s[o + M_SPOS] = 0.0;
        s[o + M_SR] = 0.0;
        s[o + M_SBK] = 1.0;
        s[o + M_SBAD] = 0.0;
        s[o + M_LRAT] = 0.0;
        s[o + M_LON] = 0.0;
        s[o + M_SRH] = 0.0;
        s[o + M_SBKH] = 1.0;
    }
    if (!(fabs(z) < MO_SPEC_ZMAX)) {
        z = 0.0;
        s[o + M_SBAD] = 1.0;
    }
    n = (int)s[o + M_SPOS];
    x = (0.5 - 0.5 * cs[n]) * z;
    if (n < MO_SPEC_N / 2)
        s[o + M_SFOLD + n] = x;
    else
        s[o + M_SFOLD + n - MO_SPEC_N / 2] += x;
    n += 1;
    if (n < MO_SPEC_N) {
        s[o + M_SPOS] = (double)n;
        return s[o + M_SR];
    }
    s[o + M_SPOS] = 0.0;
    /* Goertzel per bin, the bins side by side (data-parallel: the compiler runs
       them two at a time), as kernels.spectral_floor */
    for (j = 0; j < MO_SPEC_NB; j++) {
        w1[j] = 0.0;
        w2[j] = 0.0;
        cf[j] = 2.0 * cs[MO_SPEC_K0 + 2 * j];
    }
    for (n = 0; n < MO_SPEC_N / 2; n++) {
        double y = s[o + M_SFOLD + n];
        for (j = 0; j < MO_SPEC_NB; j++) {
            double w0 = y + cf[j] * w1[j] - w2[j];
            w2[j] = w1[j];
            w1[j] = w0;
        }
    }
    nl = 0;
    nh = 0;
    top = 0.0;
    for (j = 0; j < MO_SPEC_NB; j++) {
        double pw = w1[j] * w1[j] + w2[j] * w2[j] - cf[j] * w1[j] * w2[j];
        if (j >= MO_LINE_J0 && pw > top)
            top = pw;
        if (j >= MO_HI_J0)
            nh = insert_low_(lowh, nh, pw);
        nl = insert_low_(low, nl, pw);
    }
    if (s[o + M_SBAD] != 0.0) {
        s[o + M_SBAD] = 0.0;
        return s[o + M_SR];
    }
    m = floor_update_(p, s, o + M_SR, o + M_SBK, low[MO_SPEC_RANK - 1] * p[P_MO_SPEC]);
    if (p[P_MO_LINE] > 0.0) {    /* line test (kernels.spectral_floor), against the high bins' floor */
        double mh = floor_update_(p, s, o + M_SRH, o + M_SBKH, lowh[MO_SPEC_RANK - 1] * p[P_MO_SPECH]);
        double lr = top * p[P_MO_SPECH], th = p[P_MO_LINE] * mh;
        s[o + M_LON] = (lr > th && s[o + M_LRAT] > th) ? 1.0 : 0.0;
        s[o + M_LRAT] = lr;
    }
    return m;
}

/* kernels.exp_neg: exp(x) for -30 <= x <= 0 (0 below), same operations: 8
 * squarings. Split in two: exp_neg_sq_ (whatever x; no branch, so the bank
 * runs it on two filters at a time) and the choice of 0 below -30 by its
 * caller. */
KERNEL double exp_neg_sq_(double x)
{
    double u, e;
    u = x * 0.00390625;
    e = 1.0 + u * (1.0 + u * 0.5);
    e = e * e;
    e = e * e;
    e = e * e;
    e = e * e;
    e = e * e;
    e = e * e;
    e = e * e;
    e = e * e;
    return e;
}

/* kernels.log1m_small: -log(1 - g), series to g^8 for g <= 0.125 */
KERNEL double log1m_small_(double g)
{
    if (g > 0.125)
        return -log(1.0 - g);
    return g * (1.0 + g * (0.5 + g * (0.3333333333333333 + g * (0.25 + g * (0.2 + g * (0.16666666666666666
        + g * (0.14285714285714285 + g * 0.125)))))));
}

/* The motion bank held outside the state by gd_run's batch loop (the
 * per-sample paths keep it in s, in the same structure-of-arrays layout: one
 * run of MO_MAX_NF values per quantity): x = rate, a = change per sample,
 * l = log-likelihood, held = 1 if held at the floor, c = summed innovation; the
 * per-filter parameters likewise, and the sample history twice over
 * (hist[j] == hist[j + nh]) so that no index wraps. s keeps the history ring
 * (written every sample too) and the scalars; mo_load_ / mo_save_ move the bank
 * between s and here (nothing the loop keeps can alias out[] or z[]). Same
 * operations in the same order as on s, so the same bits. */
typedef struct {
    double x[MO_MAX_NF], a[MO_MAX_NF], l[MO_MAX_NF], held[MO_MAX_NF], c[MO_MAX_NF], j[MO_MAX_NF];
    double g0[MO_MAX_NF], g1[MO_MAX_NF], ls[MO_MAX_NF], g2[MO_MAX_NF];
    double ct[MO_MAX_NF];   /* the Huber clip's threshold per lane: p[P_MO_CLIP2], +inf for the fastest CV one */
    double hist[2 * (4 * MO_MAX_NLAG + 1)];
} mo_bank_t;

KERNEL void mo_load_(const double *p, const double *s, mo_bank_t *b)
{
    long o = layout_total_(ORDER(p)) - N_EXT, q = o + M_BANK;
    int i, nh = 4 * (int)p[P_MO_NLAG] + 1, ncv = (int)p[P_MO_NF];
    for (i = 0; i < MO_MAX_NF; i++) {
        b->x[i] = s[q + i];
        b->a[i] = s[q + MO_MAX_NF + i];
        b->l[i] = s[q + 2 * MO_MAX_NF + i];
        b->held[i] = s[q + 3 * MO_MAX_NF + i];
        b->j[i] = s[q + 4 * MO_MAX_NF + i];
        b->c[i] = s[o + M_CUS + i];
        b->g0[i] = p[P_MO_G + i];
        b->g1[i] = p[P_MO_G + MO_MAX_NF + i];
        b->ls[i] = p[P_MO_G + 2 * MO_MAX_NF + i];
        b->g2[i] = p[P_MO_G + 3 * MO_MAX_NF + i];
        b->ct[i] = i != ncv - 1 ? p[P_MO_CLIP2] : HUGE_VAL;
    }
    for (i = 0; i < nh; i++) {
        b->hist[i] = s[o + M_HIST + i];
        b->hist[i + nh] = s[o + M_HIST + i];
    }
}

KERNEL void mo_save_(const double *p, double *s, const mo_bank_t *b)
{
    long o = layout_total_(ORDER(p)) - N_EXT, q = o + M_BANK;
    int i, nf = (int)p[P_MO_NF] + (int)p[P_MO_NCA];
    for (i = 0; i < nf; i++) {      /* the lanes from nf on: computed, never read, not saved */
        s[q + i] = b->x[i];
        s[q + MO_MAX_NF + i] = b->a[i];
        s[q + 2 * MO_MAX_NF + i] = b->l[i];
        s[q + 3 * MO_MAX_NF + i] = b->held[i];
        s[q + 4 * MO_MAX_NF + i] = b->j[i];
        s[o + M_CUS + i] = b->c[i];
    }
}

/* The bank's state update, all lanes side by side (motion_step_): the summed
 * innovation's penalty on the log-likelihood (kernels.motion_step) and the rate,
 * slope and slope change (0.0 in a CV lane, whose gamma is 0.0) updated with the
 * gains g0, g1, g2 (the filters' own, or the growing-memory ones) from the
 * predictions W, AP; a function of its own so that each caller's gains are known
 * apart from the bank (restrict), which the vectoriser needs. */
KERNEL void mo_update_(const double *restrict p, double inv_r, const double *restrict V,
                       const double *restrict W, const double *restrict AP, const double *restrict OM,
                       const double *restrict LK, const double *restrict g0, const double *restrict g1,
                       const double *restrict g2, double *restrict bx,
                       double *restrict ba, double *restrict bl, double *restrict bc, double *restrict bj)
{
    int i;
    if (p[P_MO_CUS + 1] > 0.0) {     /* summed innovation (kernels.motion_step) */
        double cf = p[P_MO_CUS], cw = 0.5 * p[P_MO_CUS + 1], cth = p[P_MO_CUS + 2], cf2 = 1.0 - cf * cf;
        for (i = 0; i < MO_MAX_NF; i++) {
            double v = V[i], cs = cf * bc[i] + v, x2 = cs * cs * OM[i] * inv_r - cth, lk = LK[i];
            double xp = x2 > 0.0 ? x2 : 0.0;     /* lk - 0.0 == lk: the same as no penalty */
            double jn = bj[i] + g2[i] * v;
            bc[i] = cs;
            bx[i] = W[i] + g0[i] * v;
            ba[i] = AP[i] + g1[i] * v;
            bl[i] = lk - cw * xp * cf2;
            bj[i] = jn;     /* a CV lane's j stays 0.0: gamma is 0.0 there */
        }
    } else {
        for (i = 0; i < MO_MAX_NF; i++) {
            double v = V[i], jn = bj[i] + g2[i] * v;
            bx[i] = W[i] + g0[i] * v;
            ba[i] = AP[i] + g1[i] * v;
            bl[i] = LK[i];
            bj[i] = jn;
        }
    }
}

/* the 4th difference at lag `lag` of the history ring ending with z (kernels.fourth_difference):
 * z - 4 x[-lag] + 6 x[-2 lag] - 4 x[-3 lag] + x[-4 lag], x[-m] = hist[at - m], wrapped by `wrap`
 * samples where that index is below 0 (0: a doubled ring, never wrapped) */
KERNEL double fourth_diff_(const double *hist, int at, int wrap, int lag, double z)
{
    int i1 = at - lag, i2 = at - 2 * lag, i3 = at - 3 * lag, i4 = at - 4 * lag;
    if (i1 < 0)
        i1 += wrap;
    if (i2 < 0)
        i2 += wrap;
    if (i3 < 0)
        i3 += wrap;
    if (i4 < 0)
        i4 += wrap;
    return z - 4.0 * hist[i1] + 6.0 * hist[i2] - 4.0 * hist[i3] + hist[i4];
}

/* motion's output during its warm-up (kernels.warmup_output): the mean of the
 * samples so far where their variance about it stays within white noise's spread
 * of the noise level of the 4th differences at every lag 1..MO_WU_NL, else z */
KERNEL double warmup_output_(double *restrict s, long o, double z, double k, int pos, int nh)
{
    double *w0 = s + o + MO_WU_AT, *hist = s + o + M_HIST;
    double n = k + 1.0, mean, e, var, r1 = 0.0, u, g, w = 1.0, t;
    int lag, i, nl = 4 * MO_WU_NL < nh ? MO_WU_NL : (nh - 1) / 4;
    if (k == 0.0)
        for (i = 0; i < 4 + MO_WU_NL; i++)
            w0[i] = 0.0;
    mean = w0[0];
    e = z - mean;
    mean += e / n;
    w0[0] = mean;
    w0[1] += e * (z - mean);
    for (lag = 1; lag <= nl; lag++)
        if (k >= 4.0 * lag) {
            double d4 = fourth_diff_(hist, pos, nh, lag, z);
            w0[1 + lag] += d4 * d4;
        }
    t = 0.0;
    for (i = 0; i < 2 + MO_WU_NL; i++)
        t += w0[i];
    if (!(t - t == 0.0)) {          /* a sum overflowed (a huge sample): stop, the state finite */
        for (i = 0; i < 3 + MO_WU_NL; i++)
            w0[i] = 0.0;
        w0[3 + MO_WU_NL] = 1.0;
        return z;
    }
    if (w0[3 + MO_WU_NL] != 0.0 || n < MO_WU_N0 || !(n > 4.0 * nl))
        return z;
    var = w0[1] / (n - 1.0);
    for (lag = 1; lag <= nl; lag++) {
        double rl = w0[1 + lag] / (70.0 * (n - 4.0 * lag));
        if (lag == 1 || rl < r1)
            r1 = rl;
    }
    if (!(r1 > 0.0) || !(var - var == 0.0))
        return z;
    u = e * e / r1;
    g = w0[2 + MO_WU_NL];
    g += MO_WU_FADE * (u - g);
    w0[2 + MO_WU_NL] = g;
    if (u > MO_WU_SPIKE || g > MO_WU_GLIM) {
        w0[3 + MO_WU_NL] = 1.0;
        return z;
    }
    for (lag = 1; lag <= nl; lag++) {
        double m = n - 4.0 * lag, q = var * 70.0 * m / w0[1 + lag], sm = sqrt(m);
        double hi = 1.0 + MO_WU_HI / sm, lo = 1.0 + MO_WU_LO / sm;
        if (!(q < hi) || q <= 1.0 - MO_WU_LOW / sm) {
            w0[3 + MO_WU_NL] = 1.0;
            return z;
        }
        if (q > lo) {
            double wl = (hi - q) / (hi - lo);
            if (wl < w)
                w = wl;
        }
    }
    return z + w * (mean - z);
}

/* method="motion": the bank of constant-velocity Kalman filters weighted by
 * their faded likelihoods, the noise level from 4th differences at several
 * lags, restarts from the best filter, angle feedback; with max_motion_hz
 * (p[P_LP_NSEC] > 0) the bank works on the low-passed sample, the noise level
 * on the raw one (see kernels.py). The bank in s (bk == NULL) or in *bk
 * (gd_run's batch loop, see mo_bank_t). */
KERNEL double motion_step_(const double *restrict p, double *restrict s, double z, mo_bank_t *restrict bk)
{
    long o = layout_total_(ORDER(p)) - N_EXT;
    double zr = z, k, r, rs, wu, nw, gm0, gm1, lgm, fade, inv_r, clip2, lmax, num, den, y, thr, out, bg = 0.0;
    int nlag = (int)p[P_MO_NLAG], nh = 4 * nlag + 1, ncv = (int)p[P_MO_NF], nf = ncv + (int)p[P_MO_NCA];
    int pos, i, j, best, c, hb;
    double wts[MO_MAX_NF], ee[MO_MAX_NF], G0[MO_MAX_NF], G1[MO_MAX_NF], G2[MO_MAX_NF], W[MO_MAX_NF],
        AP[MO_MAX_NF], V[MO_MAX_NF], U[MO_MAX_NF], LK[MO_MAX_NF], OM[MO_MAX_NF], CL[MO_MAX_NF];
    double *bx, *ba, *bl, *bh, *bc, *bj;
    const double *pg0, *pg1, *pls, *pg2, *pct, *hist;
    double ctl[MO_MAX_NF];
    if (bk) {          /* the batch loop's bank (mo_bank_t) */
        bx = bk->x;
        ba = bk->a;
        bl = bk->l;
        bh = bk->held;
        bc = bk->c;
        bj = bk->j;
        pg0 = bk->g0;
        pg1 = bk->g1;
        pls = bk->ls;
        pg2 = bk->g2;
        pct = bk->ct;
    } else {           /* the state's bank, the same layout: MO_MAX_NF lanes per value */
        bx = s + o + M_BANK;
        ba = bx + MO_MAX_NF;
        bl = bx + 2 * MO_MAX_NF;
        bh = bx + 3 * MO_MAX_NF;
        bj = bx + 4 * MO_MAX_NF;
        bc = s + o + M_CUS;
        pg0 = p + P_MO_G;
        pg1 = pg0 + MO_MAX_NF;
        pls = pg0 + 2 * MO_MAX_NF;
        pg2 = pg0 + 3 * MO_MAX_NF;
        for (i = 0; i < MO_MAX_NF; i++)
            ctl[i] = i != ncv - 1 ? p[P_MO_CLIP2] : HUGE_VAL;
        pct = ctl;
    }
    if (p[P_LP_NSEC] > 0.0) {
        z = sos_cascade_(p, s, o + M_LPD, z);
        s[S_CONV] = 1.0;
    }
    k = s[S_K];
    if (k == 0.0) {
        s[o + M_BK] = 1.0;
        pos = 0;
    } else {
        pos = (int)s[o + M_HPOS] + 1;
        if (pos >= nh)
            pos = 0;
    }
    s[o + M_HPOS] = (double)pos;
    s[o + M_HIST + pos] = zr;
    rs = 0.0;
    if (p[P_MO_SPEC] > 0.0)
        rs = spectral_floor_(p, s, o, zr, k);
    if (bk) {
        bk->hist[pos] = zr;
        bk->hist[pos + nh] = zr;
        hist = bk->hist;
        hb = pos + nh;     /* hist[hb - m] is the sample m back, m <= nh - 1 */
    } else {
        hist = s + o + M_HIST;
        hb = pos;          /* hist[hb - m], wrapped into 0..nh-1 */
    }
    if (k >= 4.0 * nlag) {
        double b = p[P_MO_BR], d, hub = p[P_MO_HUBER], least = 0.0, sig;
        int clip;
        s[o + M_BK] *= b;
        d = forget_weight_(b, s[o + M_BK]);
        clip = d < 0.03125;
        UNROLL     /* every lag a constant: the history's indices are too */
        for (j = 1; j <= MO_MAX_NLAG; j++) {
            double d4, x, m;
            if (j > nlag)
                break;
            d4 = fourth_diff_(hist, hb, bk ? 0 : nh, j, zr);
            x = fabs(d4);
            m = s[o + M_MABS + j - 1];
            /* a difference beyond MO_SPEC_ZMAX (or not finite: a lone huge sample)
               is left out, so the mean stays below it and sig * sig below cannot
               overflow into an infinite R */
            if (x < MO_SPEC_ZMAX) {
                if (clip && x > hub * m)
                    x = hub * m;
                m += d * (x - m);
                s[o + M_MABS + j - 1] = m;
            }
            if (j == 1 || m < least)
                least = m;
        }
        if (least == 0.0)
            s[o + M_BK] = 1.0;
        sig = least * 0.14980634836659743;
        r = sig * sig;
        if (rs > 0.0 && rs * p[P_MO_SRATIO] < r)
            r = rs;
        if (r < p[P_R_FLOOR])
            r = p[P_R_FLOOR];
        if (p[P_MO_RFIX] > 0.0)
            r = p[P_MO_RFIX];
        s[o + M_R] = r;
    }
    s[S_K] = k + 1.0;
    r = s[o + M_R];
    wu = p[P_WARMUP];      /* with the spectral floor on, its first block ends the warm-up (kernels.py) */
    if (p[P_MO_SPEC] > 0.0)
        wu += MO_SPEC_N;
    if ((k < wu && !(p[P_MO_SPEC] > 0.0 && s[o + M_SR] > 0.0)) || r == 0.0) {
        for (i = 0; i < nf; i++) {
            bx[i] = z;
            ba[i] = 0.0;
            bl[i] = 0.0;
            bh[i] = 0.0;
            bj[i] = 0.0;
            bc[i] = 0.0;
        }
        s[o + M_GRD] = 0.0;
        if (p[P_LP_NSEC] == 0.0 && s[o + M_NW] == 0.0)
            return warmup_output_(s, o, z, k, pos, nh);
        return z;
    }
    s[S_CONV] = 1.0;
    gm0 = 0.0;
    gm1 = 0.0;
    lgm = 0.0;
    if (s[o + M_NWC] == 0.0) {   /* the growing-memory gains, until below every filter's own */
        int grows = 0;
        nw = s[o + M_NW] + 1.0;
        s[o + M_NW] = nw;
        gm0 = 2.0 * (2.0 * nw - 1.0) / (nw * (nw + 1.0));
        gm1 = 6.0 / (nw * (nw + 1.0));
        if (gm0 < 1.0)
            lgm = log1m_small_(gm0);
        for (i = 0; i < nf && !grows; i++)   /* the slowest filter first: one test, as a rule */
            grows = gm0 > pg0[i];
        s[o + M_NWC] = grows ? 0.0 : 1.0;
    }
    fade = p[P_MO_FADE];
    inv_r = 1.0 / r;
    clip2 = p[P_MO_CLIP2];
    /* The bank, the filters side by side: every loop over all MO_MAX_NF lanes without
       a branch (the compiler runs them two or more lanes at a time; the lanes from nf
       on are computed and never read), each lane the same operations as
       kernels.motion_step.
       Both sides of a choice are computed, then one is picked: with the default
       -ftrapping-math the compiler does not itself hoist floating-point operations
       out of a condition, so a conditional one keeps the loop scalar. */
    if (gm0 == 0.0) {      /* the growing-memory gains are off: every filter at its own */
        for (i = 0; i < MO_MAX_NF; i++) {
            /* omega + a + j / 2, a + j: a CV lane's j is 0.0 (gamma 0.0), so it predicts
               omega + a, a (kernels.motion_step) */
            double om = 1.0 - pg0[i], w = bx[i] + ba[i] + 0.5 * bj[i], v = z - w, u = v * v * om * inv_r;
            OM[i] = om;
            W[i] = w;
            AP[i] = ba[i] + bj[i];
            V[i] = v;
            U[i] = u;
            CL[i] = u > pct[i] ? 1.0 : 0.0;
            LK[i] = fade * bl[i] - 0.5 * (u + pls[i]);
        }
    } else {
        for (i = 0; i < MO_MAX_NF; i++) {
            double g0 = pg0[i], g1 = pg1[i], ls = pls[i], g2 = pg2[i], w, v, u, om;
            int grow = gm0 > g0;
            g1 = (grow & (gm1 > g1)) ? gm1 : g1;
            g0 = grow ? gm0 : g0;
            ls = grow ? lgm : ls;
            g2 = grow ? 0.0 : g2;      /* the line's start-up: gamma 0 */
            om = 1.0 - g0;
            w = bx[i] + ba[i] + 0.5 * bj[i];
            v = z - w;
            u = v * v * om * inv_r;
            G0[i] = g0;
            G1[i] = g1;
            G2[i] = g2;
            OM[i] = om;
            W[i] = w;
            AP[i] = ba[i] + bj[i];
            V[i] = v;
            U[i] = u;
            CL[i] = u > pct[i] ? 1.0 : 0.0;
            LK[i] = fade * bl[i] - 0.5 * (u + ls);
        }
    }
#if MO_MAX_NF != 16
#error "the sum of CL below is written out for MO_MAX_NF == 16"
#endif
    for (i = 0; i < MO_MAX_NF / 2; i++)   /* how many filters clip: 0.0 or 1.0 per lane, summed */
        CL[i] += CL[i + MO_MAX_NF / 2];
    if (CL[0] + CL[1] + CL[2] + CL[3] + CL[4] + CL[5] + CL[6] + CL[7] > 0.0) {
        for (i = 0; i < nf; i++)     /* Huber: the update sees at most clip sigma (not the fastest CV lane) */
            if (i != ncv - 1 && U[i] > clip2)
                V[i] = V[i] * sqrt(clip2 / U[i]);
    }
    if (gm0 == 0.0)      /* the filters' own gains, read where they are */
        mo_update_(p, inv_r, V, W, AP, OM, LK, pg0, pg1, pg2, bx, ba, bl, bc, bj);
    else
        mo_update_(p, inv_r, V, W, AP, OM, LK, G0, G1, G2, bx, ba, bl, bc, bj);
    /* the first most likely: lmax = the largest (left to right, each bl[i] > lmax
       taken: maxsd), best = the first lane equal to it (none where bl[0] is NaN: 0),
       as the scan that keeps the first strictly larger */
    lmax = bl[0];
    if (nf == MO_MAX_NF) {
        UNROLL
        for (i = 1; i < MO_MAX_NF; i++)
            lmax = bl[i] > lmax ? bl[i] : lmax;
    } else {
        for (i = 1; i < nf; i++)
            lmax = bl[i] > lmax ? bl[i] : lmax;
    }
    best = 0;
    for (i = 0; i < nf; i++)
        if (bl[i] == lmax) {
            best = i;
            break;
        }
    for (i = 0; i < MO_MAX_NF; i++)
        ee[i] = exp_neg_sq_(bl[i] - lmax);
    if (!bk) {     /* the state's lanes from nf on stay 0.0, as in kernels.py (mo_save_ leaves them) */
        for (i = nf; i < MO_MAX_NF; i++) {
            bx[i] = 0.0;
            ba[i] = 0.0;
            bl[i] = 0.0;
            bc[i] = 0.0;
            bj[i] = 0.0;
        }
    }
    num = 0.0;
    den = 0.0;
    thr = p[P_MO_RESET];
    {   /* the best filter's values, which no lane below changes (x = 0.0 there) */
        double xb = bx[best], ab = ba[best], cb = bc[best], jb = bj[best], lo = lmax - thr;
#define MO_WEIGH_LANE(i)                                                                    \
        do {                                                                                \
            double x = bl[i] - lmax;                                                        \
            if (x < -thr) {                                                                 \
                if (bh[i] == 1.0) {                                                         \
                    bx[i] = xb;                                                             \
                    ba[i] = ab;                                                             \
                    bc[i] = cb;                                                             \
                    if ((i) >= ncv)                                                         \
                        bj[i] = jb;     /* 0.0 from a CV filter */                          \
                }                                                                           \
                bl[i] = lo;                                                                 \
                bh[i] = 1.0;                                                                \
            } else {                                                                        \
                double e = x < -30.0 ? 0.0 : ee[i];     /* kernels.exp_neg(x) */            \
                num += e * bx[i];                                                           \
                den += e;                                                                   \
                bh[i] = 0.0;                                                                \
                wts[i] = e;                                                                 \
            }                                                                               \
        } while (0)
        if (nf == MO_MAX_NF) {     /* the whole bank (the default): the loop unrolled */
            UNROLL
            for (i = 0; i < MO_MAX_NF; i++)
                MO_WEIGH_LANE(i);
        } else {
            for (i = 0; i < nf; i++)
                MO_WEIGH_LANE(i);
        }
#undef MO_WEIGH_LANE
    }
    y = num / den;
    if (p[P_MO_VAR] != 0.0) {
        double var = 0.0;
        for (i = 0; i < nf; i++) {
            if (bh[i] == 0.0) {
                double g0 = pg0[i], dw;
                if (gm0 > g0)
                    g0 = gm0;
                dw = bx[i] - y;
                var += wts[i] * (g0 * r + dw * dw);
            }
        }
        var = var / den;
        if (!(var - var == 0.0))
            var = 1.7976931348623157e308;
        s[o + M_PVAR] = var;
    }
    {   /* output guard (kernels.motion_step): the faded (z - y)^2 / R of the bank's output */
        double d = z - y, u = d * d * inv_r, gm = s[o + M_GRD];
        if (!(u < MO_GUARD_CAP))
            u = MO_GUARD_CAP;
        gm += MO_GUARD_FADE * (u - gm);
        s[o + M_GRD] = gm;
        if (gm > MO_GUARD_LO) {
            bg = (gm - MO_GUARD_LO) / (MO_GUARD_HI - MO_GUARD_LO);
            if (bg > 1.0)
                bg = 1.0;
        }
    }
    c = P_MO_G + best;     /* alpha of the most likely filter; its lam^2 at c + 4 MO_MAX_NF */
    if (p[P_MO_PT] > 0.0) {      /* pass-through (kernels.motion_step) */
        double g = s[o + M_GEFF], lo = p[P_MO_PT + 1];
        g += p[P_MO_PT] * (p[c] - g);
        s[o + M_GEFF] = g;
        if (g > lo) {
            double bt = (g - lo) / (p[P_MO_PT + 2] - lo);
            if (bt > 1.0)
                bt = 1.0;
            y = y + bt * (z - y);
        }
    }
    if (bg > 0.0)
        y = y + bg * (z - y);
    if (s[o + M_LON] != 0.0)
        y = z;                   /* a line near the Nyquist frequency: the raw sample */
    out = y + p[P_MO_KAPPA] * s[o + M_ANG];
    s[o + M_ANG] += z - out;
    s[o + M_BEST] = (double)best;
    s[S_INNOV] = z - out;
    s[S_SVAR] = r / (1.0 - p[c]);
    s[S_R] = r;
    s[S_Q] = p[c + 4 * MO_MAX_NF] * r;
    return out;
}

/* Python's v - v == 0.0: false for inf and nan. volatile-free: without
 * -ffast-math the compiler may not fold v - v to 0. */
KERNEL int finite_(double v)
{
    return v - v == 0.0;
}

KERNEL int healthy(const double *p, const double *s)
{
    long o_x = layout_(ORDER(p)).x;
    return finite_(s[o_x]) && finite_(s[S_SVAR]) && finite_(s[S_R])
        && finite_(s[S_Q]) && finite_(s[S_RLS_ERR]) && finite_(s[S_S2]);
}


KERNEL double c_deg_s_(const double *p, const double *s)
{
    int n = ORDER(p);
    long o = layout_(n).theta;
    double one_minus = 1.0;
    int i;
    if (!GD_AR_MODEL(p[P_METHOD]))
        return 0.0;                       /* no AR model identified */
    for (i = 0; i < n; i++)
        one_minus -= s[o + i];
    return s[o + n] + one_minus * s[S_ZREF];
}

/* bias tracking (kernels.bias_step): still where the bank has converged and its most
 * likely filter is one of the slowest (at or below lane p[P_BIAS_LANE]) */
RARE double bias_step_(const double *p, double *s, double z)
{
    double *b = s + layout_total_(ORDER(p)) - N_EXT + M_BIAS;
    gd_bias_t e;
    double hat;
    gd_bias_load(b, &e);
    hat = gd_bias_update(p, &e, z, s[S_CONV] == 1.0 && b[M_BEST - M_BIAS] <= p[P_BIAS_LANE], s[S_R]);
    gd_bias_save(&e, b);
    return hat;
}

/* one sample of any method; bk: the motion bank outside s (run_motion_, only
 * for method motion) or NULL (the bank in s). With bk the method is motion, so
 * the copies inlined into run_motion_'s loops hold motion's code only: the
 * other methods' kernels, never run there, were a third of the compile time. */
KERNEL double step_(const double *p, double *s, double z, int is_restart, mo_bank_t *bk)
{
    int code = 0;
    int lowpass = !bk && p[P_METHOD] == METHOD_LOWPASS;
    int motion = bk || p[P_METHOD] == METHOD_MOTION;
    int one_euro = !bk && p[P_METHOD] == METHOD_ONE_EURO;
    double xc, out, zc;
    if (is_restart) {
        restart_(p, s);
        if (bk)
            mo_load_(p, s, bk);
    } else if (!bk && GD_AR_FILTER(p[P_METHOD]) && p[P_OUTLIER_SIGMA] > 0.0 && s[S_CONV] == 1.0)
        code = gate_(p, s, z - s[S_ZREF]);
    if (s[S_K] == 0.0) {
        s[S_ZREF] = z;
        s[S_LO] = z;
        s[S_HI] = z;
    }
    if (z < s[S_LO])
        s[S_LO] = z;
    if (z > s[S_HI])
        s[S_HI] = z;
    zc = z - s[S_ZREF];
    if (code == 1)
        xc = s[S_OUT];
    else if (lowpass)
        xc = lowpass_step_(p, s, z - s[S_ZREF]);
    else if (motion)
        xc = motion_step_(p, s, zc, bk);
    else if (one_euro)
        xc = one_euro_step_(p, s, z - s[S_ZREF]);
    else
        xc = filter_step_(p, s, z - s[S_ZREF]);
    if (!(healthy(p, s) && finite_(xc))) {
        restart_(p, s);
        if (bk)
            mo_load_(p, s, bk);
        s[S_NHEAL] += 1.0;
        s[S_ZREF] = z;
        s[S_LO] = z;
        s[S_HI] = z;
        zc = 0.0;
        if (lowpass)
            xc = lowpass_step_(p, s, 0.0);
        else if (motion)
            xc = motion_step_(p, s, 0.0, bk);
        else if (one_euro)
            xc = one_euro_step_(p, s, 0.0);
        else
            xc = filter_step_(p, s, 0.0);
    }
    /* warm-up / identification only: raw (motion's warm-up output where it moved the sample) */
    if ((s[S_CONV] == 0.0 && !(motion && xc != zc)) || (!motion && p[P_METHOD] == METHOD_NONE)) {
        out = z;
    } else {
        out = xc + s[S_ZREF];
        if (out < s[S_LO]) {
            out = s[S_LO];
            s[S_NCLAMP] += 1.0;
        } else if (out > s[S_HI]) {
            out = s[S_HI];
            s[S_NCLAMP] += 1.0;
        }
    }
    s[S_OUT] = out;
    if (motion && p[P_BIAS] > 0.0)       /* bias tracking: the bias removed (gdbias.c) */
        out -= bias_step_(p, s, z);
    return out;
}

/* ------------------------------------------------------------------------
 * The batch loop of the AR methods (none, kf, shakf, sh_classic) for orders
 * 1..LOC_MAX_ORDER with the state in locals: the same recursion as step_
 * (restart_, gate_, filter_step_, rls_update_, kf_predict_, kf_update_,
 * start_filter_, tie_c_, healthy), operation for operation and in the same
 * order, on the header scalars held in local variables and the vectors and
 * covariances in fixed-size local arrays, unpacked from s once before the loop
 * and packed back once after it. The order is a compile-time constant in
 * each instance (loops fully unrolled, constant indices, so the compiler
 * keeps the arrays in registers and stack slots), and nothing the loop keeps
 * can alias out[] or z[].
 *
 * Work left out, none of it visible in any output or in the final state:
 *   - the lower triangles of the covariances (see SY),
 *   - the RLS covariance's v * 1.0 when it is not forgotten (exact),
 *   - kf_update_'s c entries except on the last sample (see loc_update).
 * Change the maths in kernels.py and step_ above, then here: the tests
 * compare this loop bit for bit with kernels.py.
 */
#define LOC_MAX_ORDER 8


/* The (i, j) entry of a local covariance. Both are symmetric bit for bit in
 * every state the kernels make and every kernel keeps them so (gd_run checks
 * it before it uses this loop): only the upper triangle is kept up to date and
 * read here, and the lower one is mirrored when the state is packed. */
#define SY(A, i, j) (A)[(i) > (j) ? (j) * m + (i) : (i) * m + (j)]

/* rls_gain on the local arrays: g = P h into w; returns lam + h' P h */
KERNEL double loc_rls_gain(const double *prls, const double *zh, double *w, double lam,
                           const int n, const int m)
{
    int i, j;
    double acc, den;
    UNROLL
    for (i = 0; i < m; i++) {
        acc = prls[i * m + n];
        UNROLL
        for (j = 0; j < n; j++)
            acc += SY(prls, i, j) * zh[j];
        w[i] = acc;
    }
    den = lam + w[n];
    UNROLL
    for (j = 0; j < n; j++)
        den += zh[j] * w[j];
    return den;
}

/* tie_c_ on the local arrays */
KERNEL void loc_tie_c(const double *th, double *x, double *P, double floor_, const int n,
                      const int m)
{
    int i;
    x[n] = th[n];
    UNROLL
    for (i = 0; i < n; i++)
        P[i * m + n] = 0.0;
    P[n * m + n] = floor_;
}

/* kf_predict_ on the local arrays */
KERNEL double loc_predict(const double *th, double *x, double *P, double *w, double q,
                          const int n, const int m)
{
    int i, j;
    double x0, acc, p00, v;
    x0 = x[n];
    UNROLL
    for (i = 0; i < n; i++)
        x0 += th[i] * x[i];
    UNROLL
    for (i = n - 1; i > 0; i--)
        x[i] = x[i - 1];
    x[0] = x0;
    UNROLL
    for (j = 0; j < m; j++) {
        acc = SY(P, n, j);
        UNROLL
        for (i = 0; i < n; i++)
            acc += th[i] * SY(P, i, j);
        w[j] = acc;
    }
    UNROLL
    for (i = n - 1; i > 0; i--) {
        UNROLL
        for (j = n - 1; j > 0; j--)
            if (i <= j)
                P[i * m + j] = SY(P, i - 1, j - 1);
        v = P[(i - 1) * m + n];
        P[i * m + n] = v;
    }
    p00 = w[n] + q;
    UNROLL
    for (i = 0; i < n; i++)
        p00 += th[i] * w[i];
    P[0] = p00;
    UNROLL
    for (j = 1; j < n; j++)
        P[j] = w[j - 1];
    P[n] = w[n];
    return x0;
}

/* kf_update_ on the local arrays. The c entries it updates (x[n], the c
 * column of P and its clamp) are dead within a record: every next sample
 * overwrites them (tie_c_ in gate_ and filter_step_, start_filter_, restart_)
 * before anything reads them. They are computed, with the same operations,
 * only when `full` (the last sample of the call: they are then the state left
 * in s). Every other entry is computed independently of them, as in kf_update_. */
KERNEL double loc_update(double *x, double *P, double *w, double v, double r, const int n,
                         const int m, const int full)
{
    int i, j;
    double svar = P[0] + r;
    double inv_s = 1.0 / svar;
    UNROLL
    for (i = 0; i < m; i++)
        w[i] = SY(P, i, 0);
    UNROLL
    for (i = 0; i < n; i++)
        x[i] += w[i] * inv_s * v;
    UNROLL
    for (i = 0; i < n; i++) {
        double ki = w[i] * inv_s;
        UNROLL
        for (j = i; j < n; j++)
            P[i * m + j] = P[i * m + j] - ki * w[j];
    }
    UNROLL
    for (i = 0; i < n; i++)
        if (P[i * m + i] < 1e-300)
            P[i * m + i] = 1e-300;
    if (full) {
        x[n] += w[n] * inv_s * v;
        UNROLL
        for (i = 0; i < m; i++) {
            double ki = w[i] * inv_s;
            P[i * m + n] = P[i * m + n] - ki * w[n];
        }
        if (P[n * m + n] < 1e-300)
            P[n * m + n] = 1e-300;
    }
    return svar;
}

/* The gate's rejection on the local arrays (rare: out of the hot loop, which
 * then holds more of its state in registers): on the first sample of a
 * rejection run, test the identified model (ar_stable_, *hold = 1 when it is
 * unstable); then the prediction, or the last filtered value when holding,
 * replaces the sample in the regression history. Returns that value. */
RARE double loc_reject(const double *th, double *x, double *P, double *w, double *zh, double q,
                       const int n, const int first, double *hold)
{
    const int m = n + 1;
    double x0;
    int j;
    if (first)
        *hold = ar_stable_(th, 0, n, w, 0) ? 0.0 : 1.0;
    if (*hold == 0.0)
        x0 = loc_predict(th, x, P, w, q, n, m);
    else
        x0 = x[0];
    for (j = n - 1; j > 0; j--)
        zh[j] = zh[j - 1];
    zh[0] = x0;
    return x0;
}

/* restart_ on the locals (the cumulative counters nrej, nreopen, nclamp and
 * nheal are kept; the method block of s is zeroed when the state is packed) */
#define LOC_RESTART()                                          \
    do {                                                       \
        UNROLL                                                 \
        for (i = 0; i < m; i++) {                              \
            th[i] = 0.0;                                       \
            x[i] = 0.0;                                        \
            w[i] = 0.0;                                        \
        }                                                      \
        UNROLL                                                 \
        for (i = 0; i < n; i++)                                \
            zh[i] = 0.0;                                       \
        UNROLL                                                 \
        for (i = 0; i < m * m; i++) {                          \
            prls[i] = 0.0;                                     \
            P[i] = 0.0;                                        \
        }                                                      \
        UNROLL                                                 \
        for (i = 0; i < m; i++) {                              \
            prls[i * m + i] = p0_rls;                          \
            P[i * m + i] = p0_kf;                              \
        }                                                      \
        k = kd = s2 = ns2 = conv = innov = svar_s = nreset = 0.0; \
        out_s = rls_err = bk = rejrun = zref = lo = hi = hold = 0.0; \
        R = r0 > 0.0 ? r0 : floor_;                            \
        Q = q0;                                                \
        restarted = 1;                                         \
    } while (0)

/* filter_step_ on the locals: zc centred sample, result into xc */
#define LOC_FILTER_STEP(zc_expr)                                                  \
    do {                                                                          \
        double zc = (zc_expr);                                                    \
        double kk = k;                                                            \
        double e = 0.0;                                                           \
        if (conv == 0.0) {                                                        \
            double autolevel = 0.5 * s2;                                          \
            if (autolevel < floor_)                                               \
                autolevel = floor_;                                               \
            Q = q0 > 0.0 ? q0 : autolevel;                                        \
            R = r0 > 0.0 ? r0 : autolevel;                                        \
            if (kk >= warmup) {                                                   \
                conv = 1.0;                                                       \
                kd = 0.0;                                                         \
                bk = b;                                                           \
                UNROLL                                                            \
                for (i = 0; i < m * m; i++)                                       \
                    P[i] = 0.0;                                                   \
                UNROLL                                                            \
                for (i = 0; i < n; i++) {                                         \
                    x[i] = zh[i];                                                 \
                    P[i * m + i] = R;                                             \
                }                                                                 \
                loc_tie_c(th, x, P, floor_, n, m);                                \
            }                                                                     \
        }                                                                         \
        /* rls_update_ */                                                         \
        if (kk >= (double)n) {                                                    \
            double den = loc_rls_gain(prls, zh, w, lam, n, m);                    \
            double pred, inv_den;                                                 \
            int forget;                                                           \
            if (!(den >= lam)) {                                                  \
                UNROLL                                                            \
                for (i = 0; i < m * m; i++)                                       \
                    prls[i] = 0.0;                                                \
                UNROLL                                                            \
                for (i = 0; i < m; i++)                                           \
                    prls[i * m + i] = p0_rls;                                     \
                den = loc_rls_gain(prls, zh, w, lam, n, m);                       \
            }                                                                     \
            pred = th[n];                                                         \
            UNROLL                                                                \
            for (j = 0; j < n; j++)                                               \
                pred += zh[j] * th[j];                                            \
            e = zc - pred;                                                        \
            inv_den = 1.0 / den;                                                  \
            UNROLL                                                                \
            for (i = 0; i < m; i++)                                               \
                th[i] += w[i] * inv_den * e;                                      \
            forget = lam != 1.0;                                                  \
            if (forget) {                                                         \
                double tr = 0.0;                                                  \
                UNROLL                                                            \
                for (i = 0; i < m; i++)                                           \
                    tr += prls[i * m + i] - w[i] * inv_den * w[i];                \
                if (tr * inv_lam > m_p0)                                          \
                    forget = 0;                                                   \
            }                                                                     \
            UNROLL                                                                \
            for (i = 0; i < m; i++) {                                             \
                double gi = w[i] * inv_den;                                       \
                UNROLL                                                            \
                for (j = i; j < m; j++) {                                         \
                    double v_ = prls[i * m + j] - gi * w[j];                      \
                    if (forget)                                                   \
                        v_ = v_ * inv_lam;                                        \
                    prls[i * m + j] = v_;                                         \
                }                                                                 \
            }                                                                     \
        }                                                                         \
        UNROLL                                                                    \
        for (j = n - 1; j > 0; j--)                                               \
            zh[j] = zh[j - 1];                                                    \
        zh[0] = zc;                                                               \
        rls_err = e;                                                              \
        if (kk >= ten_m) {                                                        \
            ns2 += 1.0;                                                           \
            s2 += (e * e - s2) / ns2;                                             \
        }                                                                         \
        if (kk == 0.0) {                                                          \
            UNROLL                                                                \
            for (i = 0; i < n; i++)                                               \
                x[i] = zc;                                                        \
            x[n] = 0.0;                                                           \
            k = 1.0;                                                              \
            out_s = zc;                                                           \
            innov = 0.0;                                                          \
            xc = zc;                                                              \
        } else {                                                                  \
            double q, xp, v, p00, r, svar;                                        \
            loc_tie_c(th, x, P, floor_, n, m);                                    \
            q = Q;                                                                \
            xp = loc_predict(th, x, P, w, q, n, m);                               \
            v = zc - xp;                                                          \
            p00 = P[0];                                                           \
            r = R;                                                                \
            if (conv == 1.0 && adaptive) {                                        \
                double d, k0;                                                     \
                if (shakf && v * v > g2 * (p00 + r)) {                            \
                    kd = 0.0;                                                     \
                    nreset += 1.0;                                                \
                    bk = b;                                                       \
                } else {                                                          \
                    kd += 1.0;                                                    \
                    bk *= b;                                                      \
                    if (bk < 1e-290)                                              \
                        bk = 0.0;                                                 \
                }                                                                 \
                d = (1.0 - b) / (1.0 - bk);                                       \
                if (shakf)                                                        \
                    r = (1.0 - d) * r + d * v * v;                                \
                else                                                              \
                    r = (1.0 - d) * r + d * (v * v - p00);                        \
                if (r < floor_)                                                   \
                    r = floor_;                                                   \
                R = r;                                                            \
                svar = loc_update(x, P, w, v, r, n, m, t == N - 1);               \
                k0 = p00 / svar;                                                  \
                q = q + d * k0 * k0 * (v * v - svar);                             \
                if (q < floor_)                                                   \
                    q = floor_;                                                   \
                Q = q;                                                            \
            } else {                                                              \
                svar = loc_update(x, P, w, v, r, n, m, t == N - 1);               \
            }                                                                     \
            innov = v;                                                            \
            svar_s = svar;                                                        \
            k = kk + 1.0;                                                         \
            xc = zc;                                                              \
            if (conv == 1.0 && filtering)                                         \
                xc = x[0];                                                        \
            out_s = xc;                                                           \
        }                                                                         \
    } while (0)

KERNEL void run_ar_(const double *p, double *s, const double *z,
                    const unsigned char *restarts, double *out, long N, const int n,
                    double *th, double *prls, double *x, double *P, double *zh, double *w)
{
    const int m = n + 1;
    const gd_layout_t L = layout_(n);
    /* parameters */
    const double method = p[P_METHOD];
    const double lam = p[P_LAM], b = p[P_B], g = p[P_GAMMA];
    const double q0 = p[P_Q0], r0 = p[P_R0], p0_rls = p[P_P0_RLS], p0_kf = p[P_P0_KF];
    const double warmup = p[P_WARMUP], floor_ = p[P_R_FLOOR];
    const double ksig = p[P_OUTLIER_SIGMA], orun = p[P_OUTLIER_RUN];
    const int gate_on = ksig > 0.0 && method != METHOD_NONE;
    const int adaptive = method == METHOD_SHAKF || method == METHOD_SH_CLASSIC;
    const int shakf = method == METHOD_SHAKF;
    const int filtering = method != METHOD_NONE;
    const double kk2 = ksig * ksig, g2 = g * g, inv_lam = 1.0 / lam;
    const double ten_m = 10.0 * (double)m, m_p0 = (double)m * p0_rls;
    /* header */
    double k = s[S_K], kd = s[S_KD], R = s[S_R], Q = s[S_Q], s2 = s[S_S2], ns2 = s[S_NS2];
    double conv = s[S_CONV], innov = s[S_INNOV], svar_s = s[S_SVAR], nreset = s[S_NRESET];
    double out_s = s[S_OUT], rls_err = s[S_RLS_ERR], bk = s[S_BK], nrej = s[S_NREJ];
    double rejrun = s[S_REJRUN], nreopen = s[S_NREOPEN], zref = s[S_ZREF], lo = s[S_LO];
    double hi = s[S_HI], hold = s[S_HOLD], nclamp = s[S_NCLAMP], nheal = s[S_NHEAL];
    int restarted = 0;
    long t;
    int i, j;

    UNROLL
    for (i = 0; i < m; i++) {
        th[i] = s[L.theta + i];
        x[i] = s[L.x + i];
        w[i] = s[L.w + i];
    }
    UNROLL
    for (i = 0; i < m * m; i++) {
        prls[i] = s[L.prls + i];
        P[i] = s[L.p + i];
    }
    UNROLL
    for (i = 0; i < n; i++)
        zh[i] = s[L.z + i];

    for (t = 0; t < N; t++) {
        const double zt = z[t];
        int rs = restarts != NULL && restarts[t];
        int heal = 0;
        double xc, o;
        /* one pass; a second one (heal) when the state has left the finite
         * numbers: restart and filter 0.0 as the first sample (step_) */
        for (;;) {
            int code = 0;
            double zin;
            if (!rs && !heal && gate_on && conv == 1.0) {
                /* gate_ */
                double zg = zt - zref;
                double xp, p00, acc, svg, vg;
                loc_tie_c(th, x, P, floor_, n, m);
                xp = x[n];
                UNROLL
                for (i = 0; i < n; i++)
                    xp += th[i] * x[i];
                p00 = P[n * m + n];
                UNROLL
                for (i = 0; i < n; i++) {
                    acc = 0.0;
                    UNROLL
                    for (j = 0; j < n; j++)
                        acc += th[j] * SY(P, i, j);
                    p00 += th[i] * acc;
                }
                svg = p00 + Q + R;
                vg = zg - xp;
                if (!(vg * vg > kk2 * svg)) {
                    rejrun = 0.0;
                } else if (rejrun >= orun) {
                    rs = 1;         /* restarted below, then filtered (code 2) */
                    nreopen += 1.0;
                } else {
                    double x0 = loc_reject(th, x, P, w, zh, Q, n, rejrun == 0.0, &hold);
                    nrej += 1.0;
                    rejrun += 1.0;
                    innov = vg;
                    svar_s = svg;
                    rls_err = 0.0;
                    k += 1.0;
                    out_s = x0;
                    code = 1;
                }
            }
            if (rs || heal)
                LOC_RESTART();
            if (heal) {
                nheal += 1.0;
                zref = zt;
                lo = zt;
                hi = zt;
                zin = 0.0;
            } else {
                if (k == 0.0) {
                    zref = zt;
                    lo = zt;
                    hi = zt;
                }
                if (zt < lo)
                    lo = zt;
                if (zt > hi)
                    hi = zt;
                zin = zt - zref;
            }
            if (code == 1)
                xc = out_s;
            else
                LOC_FILTER_STEP(zin);
            if (heal || (finite_(x[0]) && finite_(svar_s) && finite_(R) && finite_(Q)
                         && finite_(rls_err) && finite_(s2) && finite_(xc)))
                break;
            heal = 1;
        }
        if (conv == 0.0 || !filtering) {
            o = zt;
        } else {
            o = xc + zref;
            if (o < lo) {
                o = lo;
                nclamp += 1.0;
            } else if (o > hi) {
                o = hi;
                nclamp += 1.0;
            }
        }
        out_s = o;
        out[t] = o;
    }

    UNROLL
    for (i = 0; i < m; i++) {
        s[L.theta + i] = th[i];
        s[L.x + i] = x[i];
        s[L.w + i] = w[i];
    }
    UNROLL
    for (i = 0; i < m; i++) {
        UNROLL
        for (j = 0; j < m; j++) {
            s[L.prls + i * m + j] = SY(prls, i, j);
            s[L.p + i * m + j] = SY(P, i, j);
        }
    }
    UNROLL
    for (i = 0; i < n; i++)
        s[L.z + i] = zh[i];
    if (restarted)
        for (i = 0; i < N_EXT; i++)
            s[L.total - N_EXT + i] = 0.0;
    s[S_K] = k;
    s[S_KD] = kd;
    s[S_R] = R;
    s[S_Q] = Q;
    s[S_S2] = s2;
    s[S_NS2] = ns2;
    s[S_CONV] = conv;
    s[S_INNOV] = innov;
    s[S_SVAR] = svar_s;
    s[S_NRESET] = nreset;
    s[S_OUT] = out_s;
    s[S_RLS_ERR] = rls_err;
    s[S_BK] = bk;
    s[S_NREJ] = nrej;
    s[S_REJRUN] = rejrun;
    s[S_NREOPEN] = nreopen;
    s[S_ZREF] = zref;
    s[S_LO] = lo;
    s[S_HI] = hi;
    s[S_HOLD] = hold;
    s[S_NCLAMP] = nclamp;
    s[S_NHEAL] = nheal;
}

/* both covariances of s symmetric bit for bit (run_ar_ relies on it; a state
 * that is not, never made by the kernels, takes the generic loop) */
static int symmetric_(const double *s, int n)
{
    gd_layout_t L = layout_(n);
    long m = (long)n + 1, i, j;
    for (i = 0; i < m; i++)
        for (j = i + 1; j < m; j++)
            if (memcmp(&s[L.prls + i * m + j], &s[L.prls + j * m + i], sizeof(double)) != 0
                || memcmp(&s[L.p + i * m + j], &s[L.p + j * m + i], sizeof(double)) != 0)
                return 0;
    return 1;
}

/* one instance per order: the local arrays have their exact sizes */
#define DEFINE_RUN_AR(N_)                                                              \
    static void run_ar_##N_(const double *p, double *s, const double *z,              \
                            const unsigned char *r, double *o, long n)                \
    {                                                                                  \
        double th[N_ + 1], prls[(N_ + 1) * (N_ + 1)], x[N_ + 1];                       \
        double P[(N_ + 1) * (N_ + 1)], zh[N_], w[N_ + 1];                              \
        run_ar_(p, s, z, r, o, n, N_, th, prls, x, P, zh, w);                          \
    }
DEFINE_RUN_AR(1)
DEFINE_RUN_AR(2)
DEFINE_RUN_AR(3)
DEFINE_RUN_AR(4)
DEFINE_RUN_AR(5)
DEFINE_RUN_AR(6)
DEFINE_RUN_AR(7)
DEFINE_RUN_AR(8)

typedef void (*run_fn)(const double *, double *, const double *, const unsigned char *,
                       double *, long);
static const run_fn run_ar_table[LOC_MAX_ORDER + 1] = {
    NULL, run_ar_1, run_ar_2, run_ar_3, run_ar_4, run_ar_5, run_ar_6, run_ar_7, run_ar_8,
};

/* step_ from the first sample to the last, restarted where restarts[i] (or
 * never: NULL); trace (or NULL) gets s[trace_index] after each sample; bk: as
 * step_. Inlined into run_steps_ and run_motion_ only. */
KERNEL void steps_(const double *p, double *s, const double *z, const unsigned char *restarts,
                   double *out, long n, long trace_index, double *trace, mo_bank_t *bk)
{
    long i;
    if (restarts == NULL && trace == NULL)      /* gd_run's common case, its own loop */
        for (i = 0; i < n; i++)
            out[i] = step_(p, s, z[i], 0, bk);
    else
        for (i = 0; i < n; i++) {
            out[i] = step_(p, s, z[i], restarts != NULL && restarts[i] != 0, bk);
            if (trace)
                trace[i] = s[trace_index];
        }
}

/* The two batch loops below are called once per run and not inlined: step_ is
 * compiled into their loops only, not again into each of gd_run's and
 * gd_run_trace's (inlined there, every method's kernels would be compiled
 * once per copy: ~2/3 of this file's compile time). */

/* gd_run's and gd_run_trace's loop for the methods and states without a loop of
 * their own (lowpass, AR orders above LOC_MAX_ORDER): the bank in s */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
static void run_steps_(const double *p, double *s, const double *z, const unsigned char *restarts,
                       double *out, long n, long trace_index, double *trace)
{
    steps_(p, s, z, restarts, out, n, trace_index, trace, NULL);
}

/* the motion loop of gd_run and gd_run_trace: the bank outside s (mo_bank_t)
 * from the first sample to the last; s[trace_index] must not be in the bank */
#ifdef GD_CLONES
GD_CLONES
#elif defined(__GNUC__)
__attribute__((noinline))
#endif
static void run_motion_(const double *p, double *s, const double *z, const unsigned char *restarts,
                        double *out, long n, long trace_index, double *trace)
{
    mo_bank_t bk;
    mo_load_(p, s, &bk);
    steps_(p, s, z, restarts, out, n, trace_index, trace, &bk);
    mo_save_(p, s, &bk);
}

void gd_run(const double *p, double *s, const double *z, const unsigned char *restarts,
            double *out, long n)
{
    double order = p[P_ORDER], method = p[P_METHOD];
    if ((method == METHOD_NONE || method == METHOD_KF || method == METHOD_SHAKF
         || method == METHOD_SH_CLASSIC)
        && order >= 1.0 && order <= (double)LOC_MAX_ORDER && order == (double)(int)order
        && symmetric_(s, (int)order)) {
        run_ar_table[(int)order](p, s, z, restarts, out, n);
        return;
    }
    if (method == METHOD_MOTION) {
        run_motion_(p, s, z, restarts, out, n, 0, NULL);
        return;
    }
    run_steps_(p, s, z, restarts, out, n, 0, NULL);
}

/* gd_run that also records s[trace_index] after each sample into trace[i]
 * (e.g. the output variance of the motion bank for the offline form,
 * batch.run_offline); the same step_ as gd_run's loops (for motion with the
 * bank outside s, unless the traced value is one of the bank's). */
void gd_run_trace(const double *p, double *s, const double *z, const unsigned char *restarts,
                  double *out, long n, long trace_index, double *trace)
{
    long bank = layout_total_(ORDER(p)) - N_EXT + M_BANK;
    long cus = bank - M_BANK + M_CUS;
    if (p[P_METHOD] == METHOD_MOTION && (trace_index < bank || trace_index >= bank + 5 * MO_MAX_NF)
        && (trace_index < cus || trace_index >= cus + MO_MAX_NF)) {
        run_motion_(p, s, z, restarts, out, n, trace_index, trace);
        return;
    }
    run_steps_(p, s, z, restarts, out, n, trace_index, trace);
}

/* gd_run with no restarts that also records s[idx[j]] after each sample i into
 * rec[j * n + i] (the offline smoother's forward and backward runs of the motion
 * bank, batch.smooth_motion: the bank in s, as gd_step keeps it) */
void gd_run_record(const double *p, double *s, const double *z, double *out, long n,
                   const long *idx, long m, double *rec)
{
    long i, j;
    for (i = 0; i < n; i++) {
        out[i] = step_(p, s, z[i], 0, NULL);
        for (j = 0; j < m; j++)
            rec[j * n + i] = s[idx[j]];
    }
}

/* ------------------------------------------------------------------------
 * The public names. The kernels above are static so that the compiler may
 * inline them into step_ and gd_run (exported functions in a -fPIC shared
 * object may be interposed, which forbids inlining them).
 */
gd_layout_t gd_layout(int n) { return layout_(n); }
long gd_layout_total(int n) { return layout_total_(n); }
void gd_restart(const double *p, double *s) { restart_(p, s); }
double gd_rls_update(const double *p, double *s, double z) { return rls_update_(p, s, z); }
double gd_kf_predict(const double *p, double *s, double q) { return kf_predict_(p, s, q); }
double gd_kf_update(const double *p, double *s, double v, double r) { return kf_update_(p, s, v, r); }
void gd_start_filter(const double *p, double *s) { start_filter_(p, s); }
void gd_tie_c(const double *p, double *s) { tie_c_(p, s); }
int gd_ar_stable(const double *a, long o_a, int n, double *w, long o_w)
{
    return ar_stable_(a, o_a, n, w, o_w);
}
int gd_gate(const double *p, double *s, double z) { return gate_(p, s, z); }
double gd_filter_step(const double *p, double *s, double z) { return filter_step_(p, s, z); }
double gd_lowpass_step(const double *p, double *s, double z) { return lowpass_step_(p, s, z); }
double gd_motion_step(const double *p, double *s, double z) { return motion_step_(p, s, z, NULL); }
double gd_one_euro_step(const double *p, double *s, double z) { return one_euro_step_(p, s, z); }
double gd_c_deg_s(const double *p, const double *s) { return c_deg_s_(p, s); }
#ifdef GD_CLONES
/* gd_step's two copies (AVX2, baseline) in a static function: an exported function
   with target_clones would export its resolver and clones too (the FMUs export fmi2*
   only) */
GD_CLONES static double step_cloned_(const double *p, double *s, double z, int is_restart)
{
    return step_(p, s, z, is_restart, NULL);
}
double gd_step(const double *p, double *s, double z, int is_restart) { return step_cloned_(p, s, z, is_restart); }
#else
double gd_step(const double *p, double *s, double z, int is_restart) { return step_(p, s, z, is_restart, NULL); }
#endif
