/*
 * fogdenoiser_params.c -- the denoiser's fixed parameters (user_t), their start values and
 * their translation into the core's parameter buffer (build_params: kernels.make_params,
 * operation for operation), shared by the scalar denoiser (fogdenoiser_native.c) and the
 * 3-axis one (fogdenoiser_imu_native.c). Included by the model file after its generated
 * <model>_vars.h (the START_* values of the parameters, the same names in both).
 */
#define METHOD_LEN 64  /* method string buffer, terminating NUL included */

/* the fixed parameters, as set through the FMI */
typedef struct {
    int32_t ar_order, outlier_run, lowpass_order, strict_step_size;
    double sample_period, lam, b, gamma, q0, r0, p0_rls, p0_kf, warmup_s, r_floor,
        outlier_sigma, cutoff_hz, max_motion_hz;
    char method[METHOD_LEN];
} user_t;

/* where each parameter is stored, by value reference (the names of the including model's
   <model>_vars.h): its Real parameters, then its Integer ones; NULL for any other variable
   (the model's inputs, outputs and states are its own) */
static double *param_real_ref(user_t *u, gd_vr_t vr) {
    switch (vr) {
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

static int32_t *param_int_ref(user_t *u, gd_vr_t vr) {
    switch (vr) {
    case VR_ar_order: return &u->ar_order;
    case VR_outlier_run: return &u->outlier_run;
    case VR_lowpass_order: return &u->lowpass_order;
    case VR_strict_step_size: return &u->strict_step_size;
    default: return NULL;
    }
}

/* a Real parameter's value (0.0 for a variable that is not one) */
static double param_real(const user_t *u, gd_vr_t vr) {
    const double *r = param_real_ref((user_t *)u, vr);
    return r ? *r : 0.0;
}

/* the parameters' start values */
static void user_defaults(user_t *u) {
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

