/*
 * fogdenoiser_native.c -- FogDenoiserNative: the gyrodenoise filter as a native
 * FMI 2.0 co-simulation slave (no Python, no libpython; C99 + libm).
 *
 * One communication step is one gyro sample: set raw_rate (and restart), call
 * fmi2DoStep, read filtered_rate and the AR model readouts. The numbers come
 * from the project's C core (gyrodenoise/core/gdcore.c, gd_step); this file is
 * the model's hooks for the shared FMI layer (gdfmi.h / gdfmi.c: state machine,
 * logging, get/set checks, FMU states):
 *
 *   - the parameter buffer of gyrodenoise.core.kernels.make_params, built here
 *     from the FMU parameters with the same checks and the same floating-point
 *     operations (warm-up, motion constants, Butterworth sections), so the
 *     output equals gd.denoise (tests/fmu/test_native_denoiser.py);
 *   - the variables (get/set), one step, and the fields of the serialized FMU
 *     state (a versioned, checksummed byte image of the parameters and the
 *     filter's state buffer, format 2: unchanged by the split into layer + hooks).
 *
 * The value references, the GUID and the start values come from
 * fogdenoiser_native_vars.h, generated with modelDescription.xml from one table
 * (gyrodenoise/fmu/native.py), so the two cannot drift.
 *
 * Compile: gcc -O2 -ffp-contract=off -std=c99 -fPIC -shared -fvisibility=hidden
 *          -DGD_LIBM_LINKED fogdenoiser_native_all.c -lm   (no -ffast-math: see gdcore.h;
 *          fogdenoiser_native_all.c includes gdcore.c, this file and gdfmi.c)
 */
#include "gdfmi.h"
#include "gdcore.h"
#include "fogdenoiser_native_vars.h"

#define SERIAL_VERSION 2u   /* 2: max_motion_hz, the core state's rigid-body low-pass delays */
#define METHOD_LEN 64  /* method string buffer, terminating NUL included */

/* the fixed parameters, as set through the FMI */
typedef struct {
    int32_t ar_order, outlier_run, lowpass_order, strict_step_size;
    double sample_period, lam, b, gamma, q0, r0, p0_rls, p0_kf, warmup_s, r_floor,
        outlier_sigma, cutoff_hz, max_motion_hz;
    char method[METHOD_LEN];
} user_t;

/* the model's fixed-size part (m): parameters, inputs, outputs, the core's parameter
 * buffer; the filter's state buffer is the layer's s */
typedef struct {
    int32_t restart;      /* input */
    user_t u;
    double raw_rate;      /* input */
    double filtered_rate; /* output of the last step */
    double p[N_PARAMS];
} dn_t;

static const gdfmi_var_t vars[GD_N_VARS] = GD_VARIABLE_TABLE;

static void dn_defaults(void *mv) {
    dn_t *d = (dn_t *)mv;
    user_t *u = &d->u;
    u->ar_order = START_ar_order;
    u->outlier_run = START_outlier_run;
    u->lowpass_order = START_lowpass_order;
    u->strict_step_size = START_strict_step_size;
    u->sample_period = START_sample_period;
    u->lam = START_lam;
    u->b = START_b;
    u->gamma = START_gamma;
    u->q0 = START_q0;
    u->r0 = START_r0;
    u->p0_rls = START_p0_rls;
    u->p0_kf = START_p0_kf;
    u->warmup_s = START_warmup_s;
    u->r_floor = START_r_floor;
    u->outlier_sigma = START_outlier_sigma;
    u->cutoff_hz = START_cutoff_hz;
    u->max_motion_hz = START_max_motion_hz;
    strcpy(u->method, START_method);
    d->raw_rate = START_raw_rate;
    d->restart = START_restart;
}

/* ------------------------------------------- parameters: kernels.make_params */

static double (*volatile libm_pow)(double, double) = pow; /* Python's float ** calls pow() */
/* cmath.exp calls sin() and cos(): called through pointers so that gcc does not fuse them into
 * the GNU sincos() (not in every libm; a weak reference in gdfmi_libm.h) */
static double (*volatile libm_sin)(double) = sin;
static double (*volatile libm_cos)(double) = cos;

/* _Py_c_quot: complex division as CPython does it */
static void py_c_quot(double ar, double ai, double br, double bi, double *rr, double *ri) {
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

/* kernels.butter_sos, operation for operation (complex arithmetic as CPython's);
 * writes the sections into p[P_SOS..], returns their number */
static int butter_sos(int order, double cutoff_hz, double fs, double *p) {
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

/* Build p (N_PARAMS doubles) from the FMU parameters, with the checks of the
 * pythonfmu FogDenoiser and kernels.make_params; -1 and a one-line reason in err. */
static int build_params(const user_t *u, double *p, char *err, size_t nerr) {
    static const struct { const char *name; double value; } methods[] = {
        {"motion", METHOD_MOTION}, {"shakf", METHOD_SHAKF}, {"kf", METHOD_KF},
        {"sh_classic", METHOD_SH_CLASSIC}, {"lowpass", METHOD_LOWPASS}, {"none", METHOD_NONE}};
    char m[METHOD_LEN];
    const char *a, *e;
    size_t len, i;
    int n = u->ar_order, im = -1;
    double fs, warmup, wr, cutoff;
    struct { const char *name; double value; int ok; const char *rule; } checks[11];

    if (n < 1 || n > GD_MAX_AR_ORDER)
        return gdfmi_fmt_err(err, nerr, "ar_order must be in 1..%d (phi outputs declared), got %d",
                       GD_MAX_AR_ORDER, n);
    if (!(u->sample_period > 0 && isfinite(u->sample_period)))
        return gdfmi_fmt_err(err, nerr, "sample_period must be a finite number > 0 s, got %.17g",
                       u->sample_period);
    fs = 1.0 / u->sample_period;
    gdfmi_strip(u->method, &a, &e);
    len = (size_t)(e - a);
    for (i = 0; i < len && i + 1 < sizeof m; i++)
        m[i] = (a[i] >= 'A' && a[i] <= 'Z') ? (char)(a[i] - 'A' + 'a') : a[i];
    m[i] = '\0';
    for (i = 0; i < sizeof methods / sizeof methods[0]; i++)
        if (len < sizeof m && strcmp(m, methods[i].name) == 0) im = (int)i;
    if (im < 0)
        return gdfmi_fmt_err(err, nerr, "method must be one of ['kf', 'lowpass', 'motion', 'none', "
                       "'sh_classic', 'shakf'], got '%s'", u->method);

#define CHECK(k, nm, v, cond, r) checks[k].name = nm, checks[k].value = v, checks[k].ok = (cond), checks[k].rule = r
    CHECK(0, "sample_rate_hz", fs, fs > 0, "> 0 Hz");
    CHECK(1, "lam", u->lam, 0 < u->lam && u->lam <= 1, "0 < lam <= 1");
    CHECK(2, "b", u->b, 0 < u->b && u->b < 1, "0 < b < 1");
    CHECK(3, "gamma", u->gamma, u->gamma >= 1, ">= 1");
    CHECK(4, "q0", u->q0, u->q0 >= 0, ">= 0 (deg/s)^2, 0 = automatic");
    CHECK(5, "r0", u->r0, u->r0 >= 0, ">= 0 (deg/s)^2, 0 = automatic");
    CHECK(6, "p0_rls", u->p0_rls, u->p0_rls > 0, "> 0");
    CHECK(7, "p0_kf", u->p0_kf, u->p0_kf > 0, "> 0 (deg/s)^2");
    CHECK(8, "warmup_s", u->warmup_s, u->warmup_s >= 0, ">= 0 s");
    CHECK(9, "r_floor", u->r_floor, u->r_floor > 0, "> 0 (deg/s)^2");
    CHECK(10, "outlier_sigma", u->outlier_sigma, u->outlier_sigma == 0 || u->outlier_sigma >= 2,
          "0 (off) or >= 2");
#undef CHECK
    for (i = 0; i < 11; i++)
        if (!(checks[i].ok && isfinite(checks[i].value)))
            return gdfmi_fmt_err(err, nerr, "%s out of range: %.17g (must be %s)", checks[i].name,
                           checks[i].value, checks[i].rule);
    if (u->outlier_run < 1)
        return gdfmi_fmt_err(err, nerr, "outlier_run must be an integer >= 1, got %d", (int)u->outlier_run);
    /* the lowpass parameters are checked against their declared bounds whatever the method
     * (a NaN, inf or negative cutoff_hz is refused even when the method is not lowpass) */
    if (!(u->cutoff_hz >= 0.0 && isfinite(u->cutoff_hz)))
        return gdfmi_fmt_err(err, nerr, "cutoff_hz out of range: %.17g (must be a finite number >= 0 Hz, "
                       "0 = default; checked whatever the method)", u->cutoff_hz);
    if (u->lowpass_order < 1 || u->lowpass_order > 2 * MAX_SOS)
        return gdfmi_fmt_err(err, nerr, "lowpass_order must be an integer 1..%d, got %d (checked whatever "
                       "the method)", 2 * MAX_SOS, (int)u->lowpass_order);
    /* the rigid-body option: 0 = off, else below the Nyquist frequency (checked whatever the
     * method; applied with motion only, as kernels.make_params) */
    if (!(u->max_motion_hz >= 0.0 && u->max_motion_hz < 0.5 * fs))
        return gdfmi_fmt_err(err, nerr, "max_motion_hz out of range: %.17g (must be 0 (off) or > 0 and below "
                       "half the sample rate, %g Hz; checked whatever the method)", u->max_motion_hz, 0.5 * fs);
    /* max(float(round(warmup_s * sample_rate_hz)), 10.0 * (n + 1)); round = half to even */
    wr = u->warmup_s * fs;
    if (!isfinite(wr))
        return gdfmi_fmt_err(err, nerr, "warmup_s out of range: %.17g s is too long at %.17g Hz",
                       u->warmup_s, fs);
    warmup = nearbyint(wr);
    if (10.0 * (double)(n + 1) > warmup) warmup = 10.0 * (double)(n + 1);

    memset(p, 0, N_PARAMS * sizeof *p);
    if (methods[im].value == METHOD_LOWPASS) {
        cutoff = u->cutoff_hz;
        if (cutoff == 0.0) cutoff = (0.25 * fs < 20.0) ? 0.25 * fs : 20.0; /* min(20.0, fs/4) */
        if (!(0.0 < cutoff && cutoff < 0.5 * fs))
            return gdfmi_fmt_err(err, nerr, "cutoff_hz out of range: %.17g (must be > 0 and below half "
                           "the sample rate, %g Hz)", cutoff, 0.5 * fs);
        if (u->lowpass_order < 1 || u->lowpass_order > 2 * MAX_SOS)
            return gdfmi_fmt_err(err, nerr, "order must be an integer 1..%d, got %d", 2 * MAX_SOS,
                           (int)u->lowpass_order);
        p[P_LP_NSEC] = (double)butter_sos(u->lowpass_order, cutoff, fs, p);
        p[P_LP_CUTOFF] = cutoff;
    }
    p[P_ORDER] = (double)n;
    p[P_METHOD] = methods[im].value;
    p[P_LAM] = u->lam;
    p[P_B] = u->b;
    p[P_GAMMA] = u->gamma;
    p[P_Q0] = u->q0;
    p[P_R0] = u->r0;
    p[P_P0_RLS] = u->p0_rls;
    p[P_P0_KF] = u->p0_kf;
    p[P_WARMUP] = warmup;
    p[P_R_FLOOR] = u->r_floor;
    p[P_OUTLIER_SIGMA] = u->outlier_sigma;
    p[P_OUTLIER_RUN] = (double)u->outlier_run;
    if (methods[im].value == METHOD_MOTION) {
        gd_motion_params(p, fs);     /* kernels.motion_params(fs) with its defaults */
        if (u->max_motion_hz > 0.0) {  /* the rigid-body low-pass ahead of the bank */
            double fc = MAX_MOTION_CUTOFF * u->max_motion_hz, cap = MAX_MOTION_FS_CAP * fs;
            if (fc > cap) fc = cap;    /* kernels.rigid_cutoff_hz */
            p[P_LP_NSEC] = (double)butter_sos(MAX_MOTION_ORDER, fc, fs, p);
            p[P_LP_CUTOFF] = fc;
        }
    }
    return 0;
}

/* ------------------------------------------------------------------ hooks */
static long dn_build(gdfmi_inst_t *c, char *err, size_t nerr) {
    dn_t *d = (dn_t *)c->m;
    if (build_params(&d->u, d->p, err, nerr) != 0) return -1;
    return gd_layout_total(d->u.ar_order);
}

static void dn_start(gdfmi_inst_t *c) {
    dn_t *d = (dn_t *)c->m;
    gd_restart(d->p, c->s); /* kernels.init_state */
    d->filtered_rate = 0.0;
}

static double dn_period(const void *m) { return ((const dn_t *)m)->u.sample_period; }

static int dn_strict(const void *m) { return ((const dn_t *)m)->u.strict_step_size; }

static gd_status_t dn_step(gdfmi_inst_t *c, double t) {
    dn_t *d = (dn_t *)c->m;
    double z = d->raw_rate;
    d->filtered_rate = gd_step(d->p, c->s, z, d->restart ? 1 : 0);
    if (!isfinite(z)) {
        /* a dropout: processed as gd.denoise and Denoiser.step process it (the core heals a
         * non-finite state by restarting the filter, counted in S_NHEAL, and passes the raw
         * sample through while it warms up again); the run goes on, with a warning */
        gdfmi_log(c, GD_WARNING, GD_FN("DoStep") ": raw_rate is %s at t=%.17g s: a dropout, processed as "
                  "gd.denoise processes it (a non-finite filter state restarts the filter, which passes "
                  "the raw samples through while it warms up again; %.17g such restart(s) so far); "
                  "filtered_rate = %.17g; the run goes on", isnan(z) ? "nan" : (z > 0 ? "inf" : "-inf"),
                  t, c->s[S_NHEAL], d->filtered_rate);
        return GD_WARNING;
    }
    return GD_OK;
}

static double dn_get_real(const gdfmi_inst_t *c, gd_vr_t vr) {
    const dn_t *d = (const dn_t *)c->m;
    const user_t *u = &d->u;
    const double *s = c->k.have_model ? c->s : NULL;
    if (vr >= VR_phi_1 && vr < VR_phi_1 + GD_MAX_AR_ORDER) {
        int k = (int)(vr - VR_phi_1); /* phi_(k+1) */
        if (!s || k >= u->ar_order) return 0.0;
        return s[gd_layout(u->ar_order).theta + k];
    }
    switch (vr) {
    case VR_raw_rate: return d->raw_rate;
    case VR_filtered_rate: return d->filtered_rate;
    case VR_c: return s ? gd_c_deg_s(d->p, s) : 0.0;
    case VR_R_hat: return s ? s[S_R] : 0.0;
    case VR_Q_hat: return s ? s[S_Q] : 0.0;
    case VR_innovation: return s ? s[S_INNOV] : 0.0;
    case VR_sample_period: return u->sample_period;
    case VR_lam: return u->lam;
    case VR_b: return u->b;
    case VR_gamma: return u->gamma;
    case VR_q0: return u->q0;
    case VR_r0: return u->r0;
    case VR_p0_rls: return u->p0_rls;
    case VR_p0_kf: return u->p0_kf;
    case VR_warmup_s: return u->warmup_s;
    case VR_r_floor: return u->r_floor;
    case VR_outlier_sigma: return u->outlier_sigma;
    case VR_cutoff_hz: return u->cutoff_hz;
    case VR_max_motion_hz: return u->max_motion_hz;
    default: return 0.0;
    }
}

static double *dn_real_ref(void *m, gd_vr_t vr) {
    dn_t *d = (dn_t *)m;
    user_t *u = &d->u;
    switch (vr) {
    case VR_raw_rate: return &d->raw_rate;
    case VR_sample_period: return &u->sample_period;
    case VR_lam: return &u->lam;
    case VR_b: return &u->b;
    case VR_gamma: return &u->gamma;
    case VR_q0: return &u->q0;
    case VR_r0: return &u->r0;
    case VR_p0_rls: return &u->p0_rls;
    case VR_p0_kf: return &u->p0_kf;
    case VR_warmup_s: return &u->warmup_s;
    case VR_r_floor: return &u->r_floor;
    case VR_outlier_sigma: return &u->outlier_sigma;
    case VR_cutoff_hz: return &u->cutoff_hz;
    case VR_max_motion_hz: return &u->max_motion_hz;
    default: return NULL;
    }
}

static int32_t *dn_int_ref(void *m, gd_vr_t vr) {
    dn_t *d = (dn_t *)m;
    switch (vr) {
    case VR_ar_order: return &d->u.ar_order;
    case VR_outlier_run: return &d->u.outlier_run;
    case VR_lowpass_order: return &d->u.lowpass_order;
    case VR_restart: return &d->restart;
    case VR_strict_step_size: return &d->u.strict_step_size;
    default: return NULL;
    }
}

static int32_t dn_get_integer(const gdfmi_inst_t *c, gd_vr_t vr) {
    if (vr == VR_n_rejected) {
        double v = c->k.have_model ? c->s[S_NREJ] : 0.0;
        return v >= (double)INT_MAX ? INT_MAX : (int32_t)v;
    }
    return *dn_int_ref(c->m, vr);
}

static int dn_get_boolean(const gdfmi_inst_t *c, gd_vr_t vr) {
    if (vr == VR_converged) return (c->k.have_model && c->s[S_CONV] == 1.0) ? 1 : 0;
    return *dn_int_ref(c->m, vr) ? 1 : 0;
}

static const char *dn_get_string(const gdfmi_inst_t *c, gd_vr_t vr) {
    (void)vr;
    return ((const dn_t *)c->m)->u.method;
}

static char *dn_string_ref(void *m, gd_vr_t vr, size_t *capacity) {
    (void)vr;
    *capacity = METHOD_LEN;
    return ((dn_t *)m)->u.method;
}

/* serialized fields, format 2: the flags (8-byte integers), the integer parameters, the method
 * string, the real parameters, then the run's values and the core's state, in the order of dn_xfer */
#define SER_DYN (8 * 4 + 4 * 4 + METHOD_LEN + 8 * 13 + 8 * 3 + 8 * 3 + 8 * N_PARAMS)

static void dn_xfer(gdfmi_cursor_t *cu, gdfmi_core_t *k, void *m, gdfmi_io_t io) {
    dn_t *d = (dn_t *)m;
    int32_t pad = 0;
    int32_t *i32[] = {&k->phase, &d->restart, &k->have_model, &pad};
    int32_t *u32[] = {&d->u.ar_order, &d->u.outlier_run, &d->u.lowpass_order, &d->u.strict_step_size};
    double *f64[] = {&d->u.sample_period, &d->u.lam, &d->u.b, &d->u.gamma, &d->u.q0, &d->u.r0,
                     &d->u.p0_rls, &d->u.p0_kf, &d->u.warmup_s, &d->u.r_floor, &d->u.outlier_sigma,
                     &d->u.cutoff_hz, &d->u.max_motion_hz};
    size_t j;
    for (j = 0; j < 4; j++) { int64_t v = *i32[j]; io(cu, &v, 8); *i32[j] = (int32_t)v; }
    for (j = 0; j < 4; j++) io(cu, u32[j], 4);
    io(cu, d->u.method, METHOD_LEN);
    for (j = 0; j < 13; j++) io(cu, f64[j], 8);
    io(cu, &d->raw_rate, 8);
    io(cu, &k->time, 8);
    io(cu, &d->filtered_rate, 8);
    io(cu, &k->n_steps, 8);
    io(cu, &k->n_bad_steps, 8);
    io(cu, &k->ns, 8);
    io(cu, d->p, 8 * N_PARAMS);
}

static int dn_check_state(const gdfmi_inst_t *c, const gdfmi_core_t *k, const void *m, const double *s,
                          char *err, size_t nerr) {
    const dn_t *d = (const dn_t *)m;
    double p[N_PARAMS];
    char why[512];
    (void)c;
    (void)s;
    if (memchr(d->u.method, 0, METHOD_LEN) == NULL || (d->restart != 0 && d->restart != 1))
        return gdfmi_fmt_err(err, nerr, "invalid state fields (corrupted state)");
    if (!k->have_model) return 0;
    if (build_params(&d->u, p, why, sizeof why) != 0)
        return gdfmi_fmt_err(err, nerr, "invalid parameter in the state: %s", why);
    if (memcmp(p, d->p, sizeof p) != 0 || k->ns != gd_layout_total(d->u.ar_order))
        return gdfmi_fmt_err(err, nerr, "filter buffers do not match the parameters (corrupted state)");
    return 0;
}

static void dn_describe(const gdfmi_inst_t *c, char *out, size_t n) {
    const dn_t *d = (const dn_t *)c->m;
    snprintf(out, n, "method %s, AR order %d, %.17g Hz, warm-up %.0f samples", d->u.method,
             (int)d->u.ar_order, 1.0 / d->u.sample_period, d->p[P_WARMUP]);
}

static const gdfmi_model_t gdfmi_model = {
    GD_MODEL_IDENTIFIER, GD_GUID, vars, GD_N_VARS, sizeof(dn_t),
    "GDNATIVE", SERIAL_VERSION, N_PARAMS, SER_DYN,
    "sample_period", "the filter's time base",
    dn_defaults, dn_build, dn_start, dn_period, dn_strict, dn_step,
    dn_get_real, dn_get_integer, dn_get_boolean, dn_get_string,
    dn_real_ref, dn_int_ref, dn_string_ref,
    dn_xfer, dn_check_state, dn_describe};
