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
 *     filter's state buffer, format 6: the parameters of the method registry, gdmethods.h).
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

#define SERIAL_VERSION 6u   /* 2: max_motion_hz, the core state's rigid-body low-pass delays; 3: the motion
                                bank of 13 CV + 3 CA lanes (MO_MAX_NF 16, the lanes' j, gamma, lam^2); 4: the
                                line test's own spectral floor (P_MO_SPECH, M_SRH, M_SBKH); 5: the parameters
                                in the registry's order (gdmethods.h), the 1-euro filter's among them, and the
                                core's parameter buffer with P_FS and the 1-euro slots; 6: bias tracking's
                                parameters and state (gdbias.h) */
#include "fogdenoiser_params.c"

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
    user_defaults(&d->u);
    d->raw_rate = START_raw_rate;
    d->restart = START_restart;
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
    case VR_bias_hat: return s ? gd_bias_hat(d->p, s) : 0.0;
    default: return param_real(u, vr);
    }
}

static double *dn_real_ref(void *m, gd_vr_t vr) {
    dn_t *d = (dn_t *)m;
    user_t *u = &d->u;
    switch (vr) {
    case VR_raw_rate: return &d->raw_rate;
    default: return param_real_ref(u, vr);
    }
}

static int32_t *dn_int_ref(void *m, gd_vr_t vr) {
    dn_t *d = (dn_t *)m;
    switch (vr) {
    case VR_restart: return &d->restart;
    default: return param_int_ref(&d->u, vr);
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

/* serialized fields, format 6: the flags (8-byte integers), the parameters (user_xfer: the integer ones,
 * the method string, the real ones, in the registry's order), then the run's values and the core's state,
 * in the order of dn_xfer */
#define SER_DYN (8 * 4 + SER_USER + 8 * 3 + 8 * 3 + 8 * N_PARAMS)

static void dn_xfer(gdfmi_cursor_t *cu, gdfmi_core_t *k, void *m, gdfmi_io_t io) {
    dn_t *d = (dn_t *)m;
    int32_t pad = 0;
    int32_t *i32[] = {&k->phase, &d->restart, &k->have_model, &pad};
    size_t j;
    for (j = 0; j < 4; j++) { int64_t v = *i32[j]; io(cu, &v, 8); *i32[j] = (int32_t)v; }
    user_xfer(cu, &d->u, io);
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
