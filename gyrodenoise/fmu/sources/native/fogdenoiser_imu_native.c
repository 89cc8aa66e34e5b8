/*
 * fogdenoiser_imu_native.c -- FogDenoiserImuNative3: the gyrodenoise filter for a whole IMU
 * (three gyro axes) as a native FMI 3.0 co-simulation FMU, over the same C core and the same
 * FMI layer as FogDenoiserNative (gdfmi.h / gdfmi.c / gdfmi3.c).
 *
 * Array variables: raw_rate[3] (input) and filtered_rate[3] (output), Float64 with
 * <Dimension start="3"/>; one restart Boolean for the three axes; the parameters of the
 * scalar denoiser (fogdenoiser_params.c: the same checks, the same parameter buffer). Three
 * independent core filter states in the layer's state buffer s (axis j at j * L, L =
 * gd_layout_total(ar_order)): filtered_rate[j] equals gd.denoise of axis j's samples.
 *
 * Compile: see fogdenoiser_native.c (the unity file fogdenoiser_imu_native3_all.c).
 */
#include "gdfmi.h"
#include "gdcore.h"
#ifdef GD_IMU_AXIS_SCALARS /* FogDenoiserImuNative (fogdenoiser_imu_xyz_native.c): one scalar an axis */
#include "fogdenoiser_imu_xyz_native_vars.h"
#define START_raw_rate START_raw_rate_x
#define IMU_SERIAL_MAGIC "GDIMUXYZ"
#else
#include "fogdenoiser_imu_native_vars.h"
#define IMU_SERIAL_MAGIC "GDIMU3AX"
#endif

#define SERIAL_VERSION 5u   /* 2: the motion bank of 13 CV + 3 CA lanes (core parameters and state changed);
                               3: the line test's own spectral floor (P_MO_SPECH, M_SRH, M_SBKH); 4: the
                               parameters in the registry's order (gdmethods.h), the 1-euro filter's among
                               them, and the core's parameter buffer with P_FS and the 1-euro slots; 5: bias
                               tracking's parameters and state (gdbias.h), the output bias_hat */
#define N_AXES 3

#include "fogdenoiser_params.c"

typedef struct {
    int32_t restart;            /* input, all axes */
    user_t u;
    double raw_rate[N_AXES];      /* input */
    double filtered_rate[N_AXES]; /* output of the last step */
    double bias_hat[N_AXES];      /* output: the bias removed at the last step (gd_bias_hat) */
    double p[N_PARAMS];
} imu_t;

static const gdfmi_var_t vars[GD_N_VARS] = GD_VARIABLE_TABLE;

static void imu_defaults(void *mv) {
    imu_t *d = (imu_t *)mv;
    int j;
    user_defaults(&d->u);
    for (j = 0; j < N_AXES; j++) d->raw_rate[j] = START_raw_rate;
    d->restart = START_restart;
}

static long imu_build(gdfmi_inst_t *c, char *err, size_t nerr) {
    imu_t *d = (imu_t *)c->m;
    if (build_params(&d->u, d->p, err, nerr) != 0) return -1;
    return N_AXES * gd_layout_total(d->u.ar_order);
}

static void imu_start(gdfmi_inst_t *c) {
    imu_t *d = (imu_t *)c->m;
    long L = gd_layout_total(d->u.ar_order);
    int j;
    for (j = 0; j < N_AXES; j++) {
        gd_restart(d->p, c->s + j * L);
        d->filtered_rate[j] = 0.0;
        d->bias_hat[j] = 0.0;
    }
}

static double imu_period(const void *m) { return ((const imu_t *)m)->u.sample_period; }

static int imu_strict(const void *m) { return ((const imu_t *)m)->u.strict_step_size; }

static gd_status_t imu_step(gdfmi_inst_t *c, double t) {
    imu_t *d = (imu_t *)c->m;
    long L = gd_layout_total(d->u.ar_order);
    gd_status_t st = GD_OK;
    int j;
    for (j = 0; j < N_AXES; j++) {
        double z = d->raw_rate[j], *s = c->s + j * L;
        d->filtered_rate[j] = gd_step(d->p, s, z, d->restart ? 1 : 0);
        d->bias_hat[j] = gd_bias_hat(d->p, s);
        if (!isfinite(z)) { /* a dropout on this axis: as FogDenoiserNative (see fogdenoiser_native.c) */
            gdfmi_log(c, GD_WARNING, GD_FN("DoStep") ": raw_rate[%d] is %s at t=%.17g s: a dropout, processed "
                      "as gd.denoise processes it (a non-finite filter state restarts the filter, which passes "
                      "the raw samples through while it warms up again; %.17g such restart(s) so far on this "
                      "axis); filtered_rate[%d] = %.17g; the run goes on", j + 1,
                      isnan(z) ? "nan" : (z > 0 ? "inf" : "-inf"), t, s[S_NHEAL], j + 1, d->filtered_rate[j]);
            st = GD_WARNING;
        }
    }
    return st;
}

static double imu_get_real(const gdfmi_inst_t *c, gd_vr_t vr) {
    const imu_t *d = (const imu_t *)c->m;
#ifdef GD_IMU_AXIS_SCALARS
    if (vr >= VR_raw_rate_x && vr <= VR_raw_rate_z) return d->raw_rate[vr - VR_raw_rate_x];
    if (vr >= VR_filtered_rate_x && vr <= VR_filtered_rate_z) return d->filtered_rate[vr - VR_filtered_rate_x];
    if (vr >= VR_bias_hat_x && vr <= VR_bias_hat_z) return d->bias_hat[vr - VR_bias_hat_x];
#endif
    return param_real(&d->u, vr); /* the arrays are read through imu_real_ref */
}

static double *imu_real_ref(void *m, gd_vr_t vr) {
    imu_t *d = (imu_t *)m;
    user_t *u = &d->u;
#ifdef GD_IMU_AXIS_SCALARS
    if (vr >= VR_raw_rate_x && vr <= VR_raw_rate_z) return d->raw_rate + (vr - VR_raw_rate_x);
    if (vr >= VR_filtered_rate_x && vr <= VR_filtered_rate_z) return d->filtered_rate + (vr - VR_filtered_rate_x);
    if (vr >= VR_bias_hat_x && vr <= VR_bias_hat_z) return d->bias_hat + (vr - VR_bias_hat_x);
    return param_real_ref(u, vr);
#else
    switch (vr) {
    case VR_raw_rate: return d->raw_rate;
    case VR_filtered_rate: return d->filtered_rate; /* read only: the layer never sets an output */
    case VR_bias_hat: return d->bias_hat;
    default: return param_real_ref(u, vr);
    }
#endif
}

static int32_t *imu_int_ref(void *m, gd_vr_t vr) {
    imu_t *d = (imu_t *)m;
    switch (vr) {
    case VR_restart: return &d->restart;
    default: return param_int_ref(&d->u, vr);
    }
}

static int32_t imu_get_integer(const gdfmi_inst_t *c, gd_vr_t vr) { return *imu_int_ref(c->m, vr); }

static int imu_get_boolean(const gdfmi_inst_t *c, gd_vr_t vr) { return *imu_int_ref(c->m, vr) ? 1 : 0; }

static const char *imu_get_string(const gdfmi_inst_t *c, gd_vr_t vr) {
    (void)vr;
    return ((const imu_t *)c->m)->u.method;
}

static char *imu_string_ref(void *m, gd_vr_t vr, size_t *capacity) {
    (void)vr;
    *capacity = METHOD_LEN;
    return ((imu_t *)m)->u.method;
}

/* serialized fields, format 5: the flags (8-byte integers), the parameters (user_xfer: the integer ones,
 * the method string, the real ones, in the registry's order), the inputs, time, the outputs (filtered_rate,
 * bias_hat), counters and the parameter buffer */
#define SER_DYN (8 * 4 + SER_USER + 8 * N_AXES + 8 + 8 * N_AXES + 8 * N_AXES + 8 * 3 + 8 * N_PARAMS)

static void imu_xfer(gdfmi_cursor_t *cu, gdfmi_core_t *k, void *m, gdfmi_io_t io) {
    imu_t *d = (imu_t *)m;
    int32_t pad = 0;
    int32_t *i32[] = {&k->phase, &d->restart, &k->have_model, &pad};
    size_t j;
    for (j = 0; j < 4; j++) { int64_t v = *i32[j]; io(cu, &v, 8); *i32[j] = (int32_t)v; }
    user_xfer(cu, &d->u, io);
    io(cu, d->raw_rate, 8 * N_AXES);
    io(cu, &k->time, 8);
    io(cu, d->filtered_rate, 8 * N_AXES);
    io(cu, d->bias_hat, 8 * N_AXES);
    io(cu, &k->n_steps, 8);
    io(cu, &k->n_bad_steps, 8);
    io(cu, &k->ns, 8);
    io(cu, d->p, 8 * N_PARAMS);
}

static int imu_check_state(const gdfmi_inst_t *c, const gdfmi_core_t *k, const void *m, const double *s,
                           char *err, size_t nerr) {
    const imu_t *d = (const imu_t *)m;
    double p[N_PARAMS];
    char why[512];
    (void)c;
    (void)s;
    if (memchr(d->u.method, 0, METHOD_LEN) == NULL || (d->restart != 0 && d->restart != 1))
        return gdfmi_fmt_err(err, nerr, "invalid state fields (corrupted state)");
    if (!k->have_model) return 0;
    if (build_params(&d->u, p, why, sizeof why) != 0)
        return gdfmi_fmt_err(err, nerr, "invalid parameter in the state: %s", why);
    if (memcmp(p, d->p, sizeof p) != 0 || k->ns != N_AXES * gd_layout_total(d->u.ar_order))
        return gdfmi_fmt_err(err, nerr, "filter buffers do not match the parameters (corrupted state)");
    return 0;
}

static void imu_describe(const gdfmi_inst_t *c, char *out, size_t n) {
    const imu_t *d = (const imu_t *)c->m;
    snprintf(out, n, "%d axes, method %s, AR order %d, %.17g Hz, warm-up %.0f samples", N_AXES, d->u.method,
             (int)d->u.ar_order, 1.0 / d->u.sample_period, d->p[P_WARMUP]);
}

static const gdfmi_model_t gdfmi_model = {
    GD_MODEL_IDENTIFIER, GD_GUID, vars, GD_N_VARS, sizeof(imu_t),
    IMU_SERIAL_MAGIC, SERIAL_VERSION, N_PARAMS, SER_DYN,
    "sample_period", "the filter's time base",
    imu_defaults, imu_build, imu_start, imu_period, imu_strict, imu_step,
    imu_get_real, imu_get_integer, imu_get_boolean, imu_get_string,
    imu_real_ref, imu_int_ref, imu_string_ref,
    imu_xfer, imu_check_state, imu_describe};
