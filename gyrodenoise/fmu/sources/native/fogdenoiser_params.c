/*
 * fogdenoiser_params.c -- the denoiser's fixed parameters (user_t), their start values and
 * their translation into the core's parameter buffer (build_params: kernels.make_params,
 * operation for operation; the checks and the slots from the registry's gdmethods.h), shared by the scalar denoiser (fogdenoiser_native.c) and the
 * 3-axis one (fogdenoiser_imu_native.c). Included by the model file after its generated
 * <model>_vars.h (the START_* values of the parameters, the same names in both).
 */
#define METHOD_LEN 64  /* method string buffer, terminating NUL included */

/* the fixed parameters, as set through the FMI: those of the method registry (gdmethods.h,
 * generated from gyrodenoise/core/methods.py), the sample period, strict_step_size, the method */
#define REAL_FIELD(name, start, slot, lo, hi, flags, rule, method) double name;
#define INT_FIELD(name, start, slot, lo, hi, flags, rule, method) int32_t name;
typedef struct {
    GD_INT_PARAMS(INT_FIELD)
    int32_t strict_step_size;
    double sample_period;
    GD_REAL_PARAMS(REAL_FIELD)
    char method[METHOD_LEN];
} user_t;
#undef REAL_FIELD
#undef INT_FIELD

/* where each parameter is stored, by value reference (the names of the including model's
   <model>_vars.h): its Real parameters, then its Integer ones; NULL for any other variable
   (the model's inputs, outputs and states are its own) */
#define REAL_CASE(name, start, slot, lo, hi, flags, rule, method) case VR_##name: return &u->name;
#define INT_CASE(name, start, slot, lo, hi, flags, rule, method) case VR_##name: return &u->name;
static double *param_real_ref(user_t *u, gd_vr_t vr) {
    switch (vr) {
    case VR_sample_period: return &u->sample_period;
    GD_REAL_PARAMS(REAL_CASE)
    default: return NULL;
    }
}

static int32_t *param_int_ref(user_t *u, gd_vr_t vr) {
    switch (vr) {
    GD_INT_PARAMS(INT_CASE)
    case VR_strict_step_size: return &u->strict_step_size;
    default: return NULL;
    }
}
#undef REAL_CASE
#undef INT_CASE

/* a Real parameter's value (0.0 for a variable that is not one) */
static double param_real(const user_t *u, gd_vr_t vr) {
    const double *r = param_real_ref((user_t *)u, vr);
    return r ? *r : 0.0;
}

/* the parameters' start values (the registry's defaults; the <model>_vars.h START_* of the same
   variables are generated from the same table) */
#define SET_START(name, start, slot, lo, hi, flags, rule, method) u->name = start;
static void user_defaults(user_t *u) {
    GD_INT_PARAMS(SET_START)
    GD_REAL_PARAMS(SET_START)
    u->strict_step_size = START_strict_step_size;
    u->sample_period = START_sample_period;
    strcpy(u->method, START_method);
}
#undef SET_START

/* the serialized parameters: the integers (4 bytes each), then the reals (8 bytes each) */
#define N_USER_INTS (GD_N_INT_PARAMS + 1)
#define N_USER_REALS (GD_N_REAL_PARAMS + 1)
#define INT_PTR(name, start, slot, lo, hi, flags, rule, method) &u->name,
#define REAL_PTR(name, start, slot, lo, hi, flags, rule, method) &u->name,
static void user_xfer(gdfmi_cursor_t *cu, user_t *u, gdfmi_io_t io) {
    int32_t *i32[N_USER_INTS] = {GD_INT_PARAMS(INT_PTR) &u->strict_step_size};
    double *f64[N_USER_REALS] = {&u->sample_period, GD_REAL_PARAMS(REAL_PTR)};
    size_t j;
    for (j = 0; j < N_USER_INTS; j++) io(cu, i32[j], 4);
    io(cu, u->method, METHOD_LEN);
    for (j = 0; j < N_USER_REALS; j++) io(cu, f64[j], 8);
}
#undef INT_PTR
#undef REAL_PTR
#define SER_USER (4 * N_USER_INTS + METHOD_LEN + 8 * N_USER_REALS)

/* the registry's range check of one parameter (gyrodenoise.core.methods.Param.fmu_error), whatever
 * the method: 0 if in range, else -1 and the one-line reason in err */
static int check_param(const char *name, double v, double lo, double hi, int flags, const char *rule,
                       int is_int, double fs, char *err, size_t nerr) {
    char r[160];
    int ok;
    if (is_int) {
        if (v >= lo && v <= hi) return 0;
        return gdfmi_fmt_err(err, nerr, "%s must be an integer %s, got %d", name, rule, (int)v);
    }
    if ((flags & GD_COMPUTED) && v == 0.0) return 0;
    ok = isfinite(v) && ((flags & GD_LO_OPEN) ? v > lo : v >= lo) && ((flags & GD_HI_OPEN) ? v < hi : v <= hi)
         && (!(flags & GD_NYQUIST) || v < 0.5 * fs);
    if (ok || ((flags & GD_OFF) && v == 0.0)) return 0;
    snprintf(r, sizeof r, rule, 0.5 * fs);
    return gdfmi_fmt_err(err, nerr, "%s out of range: %.17g (must be %s)", name, v, r);
}

/* ------------------------------------------- parameters: kernels.make_params */

/* the Butterworth sections: gd_butter_sos of the core (kernels.butter_sos bit for bit) */
#define butter_sos gd_butter_sos

/* Build p (N_PARAMS doubles) from the FMU parameters, with the checks of the
 * pythonfmu FogDenoiser and kernels.make_params; -1 and a one-line reason in err. */
static int build_params(const user_t *u, double *p, char *err, size_t nerr) {
#define METHOD_ROW(name, id) {name, id},
    static const struct { const char *name; double value; } methods[] = {GD_METHODS(METHOD_ROW)};
#undef METHOD_ROW
    char m[METHOD_LEN];
    const char *a, *e;
    size_t len, i;
    int n = u->ar_order, im = -1;
    double fs, warmup, wr, cutoff, method;

    if (!(u->sample_period > 0 && isfinite(u->sample_period)))
        return gdfmi_fmt_err(err, nerr, "sample_period must be a finite number > 0 s, got %.17g",
                       u->sample_period);
    fs = 1.0 / u->sample_period;
#define CHECK_REAL(name, start, slot, lo, hi, flags, rule, method_) \
    if (check_param(#name, u->name, lo, hi, flags, rule, 0, fs, err, nerr) != 0) return -1;
#define CHECK_INT(name, start, slot, lo, hi, flags, rule, method_) \
    if (check_param(#name, (double)u->name, lo, hi, flags, rule, 1, fs, err, nerr) != 0) return -1;
    GD_INT_PARAMS(CHECK_INT)
    GD_REAL_PARAMS(CHECK_REAL)
#undef CHECK_REAL
#undef CHECK_INT
    gdfmi_strip(u->method, &a, &e);
    len = (size_t)(e - a);
    for (i = 0; i < len && i + 1 < sizeof m; i++)
        m[i] = (a[i] >= 'A' && a[i] <= 'Z') ? (char)(a[i] - 'A' + 'a') : a[i];
    m[i] = '\0';
    for (i = 0; i < sizeof methods / sizeof methods[0]; i++)
        if (len < sizeof m && strcmp(m, methods[i].name) == 0) im = (int)i;
    if (im < 0)
        return gdfmi_fmt_err(err, nerr, "method must be one of %s, got '%s'", GD_METHOD_NAMES, u->method);
    method = methods[im].value;
    /* max(float(round(warmup_s * sample_rate_hz)), 10.0 * (n + 1)); round = half to even */
    wr = u->warmup_s * fs;
    if (!isfinite(wr))
        return gdfmi_fmt_err(err, nerr, "warmup_s out of range: %.17g s is too long at %.17g Hz",
                       u->warmup_s, fs);
    warmup = nearbyint(wr);
    if (10.0 * (double)(n + 1) > warmup) warmup = 10.0 * (double)(n + 1);

    memset(p, 0, N_PARAMS * sizeof *p);
    /* the parameters the registry writes into a slot of p, where they apply to the method */
#define WRITE_SLOT(name, start, slot, lo, hi, flags, rule, method_) \
    if ((slot) >= 0 && ((method_) < 0.0 || (method_) == method)) p[(slot) >= 0 ? (slot) : 0] = (double)u->name;
    GD_INT_PARAMS(WRITE_SLOT)
    GD_REAL_PARAMS(WRITE_SLOT)
#undef WRITE_SLOT
    p[P_FS] = fs;
    p[P_METHOD] = method;
    p[P_WARMUP] = warmup;
    if (method == METHOD_LOWPASS) {
        cutoff = u->cutoff_hz;
        if (cutoff == 0.0) cutoff = (0.25 * fs < 20.0) ? 0.25 * fs : 20.0; /* min(20.0, fs/4) */
        p[P_LP_NSEC] = (double)butter_sos(u->lowpass_order, cutoff, fs, p);
        p[P_LP_CUTOFF] = cutoff;
    }
    if (method == METHOD_MOTION) {
        gd_motion_params(p, fs);     /* kernels.motion_params(fs) with its defaults */
        if (u->bias_tracking)        /* off: p as without the option (kernels.make_params) */
            gd_bias_params(p, fs, u->bias_still_s, u->bias_memory_s, u->earth_rate_floor_deg_h);
        if (u->max_motion_hz > 0.0) {  /* the rigid-body low-pass ahead of the bank */
            double fc = MAX_MOTION_CUTOFF * u->max_motion_hz, cap = MAX_MOTION_FS_CAP * fs;
            if (fc > cap) fc = cap;    /* kernels.rigid_cutoff_hz */
            p[P_LP_NSEC] = (double)butter_sos(MAX_MOTION_ORDER, fc, fs, p);
            p[P_LP_CUTOFF] = fc;
        }
    }
    return 0;
}
