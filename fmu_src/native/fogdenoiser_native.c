/*
 * fogdenoiser_native.c -- FogDenoiserNative: the gyrodenoise filter as a native
 * FMI 2.0 co-simulation slave (no Python, no libpython; C99 + libm).
 *
 * One communication step is one gyro sample: set raw_rate (and restart), call
 * fmi2DoStep, read filtered_rate and the AR model readouts. The numbers come
 * from the project's C core (gyrodenoise/core/gdcore.c, gd_step); this file is
 * the FMI layer only:
 *
 *   - the parameter buffer of gyrodenoise.core.kernels.make_params, built here
 *     from the FMU parameters with the same checks and the same floating-point
 *     operations (warm-up, motion constants, Butterworth sections), so the
 *     output equals gd.denoise (tests/test_fmu_native.py);
 *   - the FMI 2.0 co-simulation state machine: a call the standard does not
 *     allow in the current state returns fmi2Error with the reason logged, and
 *     puts the instance in the error state (from which fmi2SetFMUstate,
 *     fmi2Reset and fmi2FreeInstance recover, as the standard says);
 *   - FMU state get/set/free/serialize/deserialize (a versioned, checksummed
 *     byte image of the parameters and the filter's state buffer).
 *
 * Logging: a message that explains a return status other than fmi2OK
 * (fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal) is always passed to the
 * logger (it is not debug output; repeated step-size warnings are rate-limited);
 * information only when logging is on and its category ("logAll", or the
 * status categories "logStatusWarning", "logStatusDiscard", "logStatusError",
 * "logStatusFatal") is enabled (all of them when fmi2SetDebugLogging was given
 * no category).
 *
 * The value references, the GUID and the start values come from
 * fogdenoiser_native_vars.h, generated with modelDescription.xml from one table
 * (gyrodenoise/fmu/native.py), so the two cannot drift.
 *
 * Compile: gcc -O2 -ffp-contract=off -std=c99 -fPIC -shared -fvisibility=hidden
 *          -DGD_LIBM_LINKED fogdenoiser_native_all.c -lm   (no -ffast-math: see gdcore.h;
 *          fogdenoiser_native_all.c includes this file and gdcore.c)
 */
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "gdcore.h"
#include "fogdenoiser_native_vars.h"

/* ------------------------------------------------------------------ states */
enum {
    ST_INSTANTIATED = 1 << 0,
    ST_INIT = 1 << 1,
    ST_STEP_COMPLETE = 1 << 2,
    ST_STEP_FAILED = 1 << 3,
    ST_TERMINATED = 1 << 4,
    ST_ERROR = 1 << 5,
    ST_FATAL = 1 << 6
};
#define ST_ALL_BUT_FATAL (ST_INSTANTIATED | ST_INIT | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR)
#define MASK_SET_DEBUG_LOGGING ST_ALL_BUT_FATAL
#define MASK_SETUP_EXPERIMENT ST_INSTANTIATED
#define MASK_ENTER_INIT ST_INSTANTIATED
#define MASK_EXIT_INIT ST_INIT
#define MASK_TERMINATE (ST_STEP_COMPLETE | ST_STEP_FAILED)
#define MASK_RESET ST_ALL_BUT_FATAL
#define MASK_GET (ST_INIT | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR)
#define MASK_SET (ST_INSTANTIATED | ST_INIT | ST_STEP_COMPLETE)
#define MASK_FMU_STATE ST_ALL_BUT_FATAL
#define MASK_DO_STEP ST_STEP_COMPLETE
#define MASK_STATUS (ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED)

/* log categories (bits), in the order of <LogCategories> */
#define CAT_WARNING 0
#define CAT_DISCARD 1
#define CAT_ERROR 2
#define CAT_FATAL 3
#define CAT_ALL 4
#define N_CATS 5
static const char *const cat_names[N_CATS] = {
    "logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal", "logAll"};

#define INSTANCE_MAGIC 0x46444e49u /* "FDNI" */
#define FMUSTATE_MAGIC 0x46444e53u /* "FDNS" */
#define SERIAL_VERSION 2u   /* 2: max_motion_hz, the core state's rigid-body low-pass delays */
#define METHOD_LEN 64  /* method string buffer, terminating NUL included */
#define STEP_RTOL 1e-6 /* tolerated relative mismatch of step size and sample_period */

/* the fixed parameters, as set through the FMI */
typedef struct {
    int32_t ar_order, outlier_run, lowpass_order, strict_step_size;
    double sample_period, lam, b, gamma, q0, r0, p0_rls, p0_kf, warmup_s, r_floor,
        outlier_sigma, cutoff_hz, max_motion_hz;
    char method[METHOD_LEN];
} user_t;

/* everything an FMU state holds, except the filter's state buffer */
typedef struct {
    int32_t phase;
    int32_t restart;      /* input */
    int32_t have_filter;  /* p and s valid (after fmi2ExitInitializationMode) */
    int32_t pad_;
    user_t u;
    double raw_rate;      /* input */
    double time;          /* communication time reached */
    double filtered_rate; /* output of the last step */
    int64_t n_steps, n_bad_steps;
    int64_t ns;           /* doubles in s */
    double p[N_PARAMS];
} dyn_t;

typedef struct fmustate_s fmustate_t;

typedef struct {
    uint32_t magic;
    fmi2CallbackFunctions cb;
    char *name;
    char *resource_uri; /* copy, may be NULL; this FMU needs no resources */
    int logging_on;
    int cat_on[N_CATS];
    dyn_t d;
    double *s;
    fmustate_t *states; /* the FMU states this instance allocated and the host has not freed */
} inst_t;

/* an FMU state: linked into its instance's list, so that fmi2FreeInstance frees the
 * states the host did not free (FMI 2.0: fmi2FreeInstance frees all it allocated) */
struct fmustate_s {
    uint32_t magic;
    dyn_t d;
    double *s;
    void *owner; /* the inst_t that allocated it */
    fmustate_t *prev, *next;
};

static void free_state(fmustate_t *f);

/* ------------------------------------------------------------------ memory */
static void *mem_alloc(const inst_t *c, size_t n, size_t size) {
    if (n == 0) n = 1;
    if (c && c->cb.allocateMemory) return c->cb.allocateMemory(n, size);
    return calloc(n, size);
}

static void mem_free(const inst_t *c, void *ptr) {
    if (!ptr) return;
    if (c && c->cb.freeMemory) c->cb.freeMemory(ptr);
    else free(ptr);
}

static char *str_dup(const inst_t *c, const char *src) {
    size_t n;
    char *dst;
    if (!src) return NULL;
    n = strlen(src) + 1;
    dst = (char *)mem_alloc(c, n, 1);
    if (dst) memcpy(dst, src, n);
    return dst;
}

/* ----------------------------------------------------------------- logging */
static int cat_of(fmi2Status st) {
    switch (st) {
    case fmi2Warning: return CAT_WARNING;
    case fmi2Discard: return CAT_DISCARD;
    case fmi2Error: return CAT_ERROR;
    case fmi2Fatal: return CAT_FATAL;
    default: return CAT_ALL;
    }
}

static void vlogmsg(const inst_t *c, fmi2Status st, const char *fmt, va_list ap) {
    char text[1024], escaped[2048];
    size_t i, j;
    int cat = cat_of(st);
    if (!c || !c->cb.logger) return;
    if (st == fmi2OK) { /* information: only when logging is on and its category enabled */
        if (!c->logging_on || !(c->cat_on[cat] || c->cat_on[CAT_ALL])) return;
    } /* a message explaining a status other than fmi2OK (a warning or a refusal) always goes out */
    vsnprintf(text, sizeof text, fmt, ap);
    /* the logger treats the message as a printf format: escape '%' */
    for (i = 0, j = 0; text[i] && j + 2 < sizeof escaped; i++) {
        if (text[i] == '%') escaped[j++] = '%';
        escaped[j++] = text[i];
    }
    escaped[j] = '\0';
    c->cb.logger(c->cb.componentEnvironment, c->name ? c->name : "", st, cat_names[cat], escaped);
}

static void logmsg(const inst_t *c, fmi2Status st, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlogmsg(c, st, fmt, ap);
    va_end(ap);
}

/* log the reason and enter the error state */
static fmi2Status fail(inst_t *c, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlogmsg(c, fmi2Error, fmt, ap);
    va_end(ap);
    c->d.phase = ST_ERROR;
    return fmi2Error;
}

static const char *phase_name(int phase) {
    switch (phase) {
    case ST_INSTANTIATED: return "instantiated";
    case ST_INIT: return "initializationMode";
    case ST_STEP_COMPLETE: return "stepComplete";
    case ST_STEP_FAILED: return "stepFailed";
    case ST_TERMINATED: return "terminated";
    case ST_ERROR: return "error";
    case ST_FATAL: return "fatal";
    default: return "unknown";
    }
}

/* the instance behind c, or NULL (a NULL or foreign pointer cannot be logged to) */
static inst_t *inst_of(fmi2Component c) {
    inst_t *i = (inst_t *)c;
    if (!i || i->magic != INSTANCE_MAGIC) return NULL;
    return i;
}

/* 1 if a call of fn is allowed in the current state; else logs, enters the error state */
static int allowed(inst_t *c, int mask, const char *fn) {
    if (c->d.phase & mask) return 1;
    if (c->d.phase == ST_FATAL) {
        logmsg(c, fmi2Error, "%s: not allowed: the instance is in the fatal state", fn);
        return 0;
    }
    fail(c, "%s: not allowed in state %s (FMI 2.0 co-simulation state machine)", fn,
         phase_name(c->d.phase));
    return 0;
}

#define BEGIN(fn, mask)                        \
    inst_t *c = inst_of(comp);                 \
    if (!c) return fmi2Error;                  \
    if (!allowed(c, (mask), fn)) return fmi2Error

/* ---------------------------------------------------------- the variables */
enum { T_REAL, T_INTEGER, T_BOOLEAN, T_STRING };
enum { K_INPUT, K_OUTPUT, K_PARAMETER };

static const struct {
    const char *name;
    int type, kind;
} vars[GD_N_VARS] = GD_VARIABLE_TABLE;

static void set_defaults(dyn_t *d) {
    user_t *u = &d->u;
    memset(d, 0, sizeof *d);
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
    d->phase = ST_INSTANTIATED;
}

/* ------------------------------------------- parameters: kernels.make_params */
/* Python's str.strip().lower() for ASCII */
static int py_space(int ch) { return ch == ' ' || (ch >= 0x09 && ch <= 0x0d) || (ch >= 0x1c && ch <= 0x1f); }

static double (*volatile libm_pow)(double, double) = pow; /* Python's float ** calls pow() */
/* cmath.exp calls sin() and cos(): called through pointers so that gcc does not fuse them into
 * the GNU sincos() (not in every libm; a weak reference in fogdenoiser_native_all.c) */
static double (*volatile libm_sin)(double) = sin;
static double (*volatile libm_cos)(double) = cos;

static int fmt_err(char *err, size_t n, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, n, fmt, ap);
    va_end(ap);
    return -1;
}

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
    const char *a = u->method, *e;
    size_t len, i;
    int n = u->ar_order, im = -1;
    double fs, warmup, wr, cutoff;
    struct { const char *name; double value; int ok; const char *rule; } checks[11];

    if (n < 1 || n > GD_MAX_AR_ORDER)
        return fmt_err(err, nerr, "ar_order must be in 1..%d (phi outputs declared), got %d",
                       GD_MAX_AR_ORDER, n);
    if (!(u->sample_period > 0 && isfinite(u->sample_period)))
        return fmt_err(err, nerr, "sample_period must be a finite number > 0 s, got %.17g",
                       u->sample_period);
    fs = 1.0 / u->sample_period;
    while (*a && py_space((unsigned char)*a)) a++;
    e = a + strlen(a);
    while (e > a && py_space((unsigned char)e[-1])) e--;
    len = (size_t)(e - a);
    for (i = 0; i < len && i + 1 < sizeof m; i++)
        m[i] = (a[i] >= 'A' && a[i] <= 'Z') ? (char)(a[i] - 'A' + 'a') : a[i];
    m[i] = '\0';
    for (i = 0; i < sizeof methods / sizeof methods[0]; i++)
        if (len < sizeof m && strcmp(m, methods[i].name) == 0) im = (int)i;
    if (im < 0)
        return fmt_err(err, nerr, "method must be one of ['kf', 'lowpass', 'motion', 'none', "
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
            return fmt_err(err, nerr, "%s out of range: %.17g (must be %s)", checks[i].name,
                           checks[i].value, checks[i].rule);
    if (u->outlier_run < 1)
        return fmt_err(err, nerr, "outlier_run must be an integer >= 1, got %d", (int)u->outlier_run);
    /* the lowpass parameters are checked against their declared bounds whatever the method
     * (a NaN, inf or negative cutoff_hz used to pass when the method was not lowpass) */
    if (!(u->cutoff_hz >= 0.0 && isfinite(u->cutoff_hz)))
        return fmt_err(err, nerr, "cutoff_hz out of range: %.17g (must be a finite number >= 0 Hz, "
                       "0 = default; checked whatever the method)", u->cutoff_hz);
    if (u->lowpass_order < 1 || u->lowpass_order > 2 * MAX_SOS)
        return fmt_err(err, nerr, "lowpass_order must be an integer 1..%d, got %d (checked whatever "
                       "the method)", 2 * MAX_SOS, (int)u->lowpass_order);
    /* the rigid-body option: 0 = off, else below the Nyquist frequency (checked whatever the
     * method; applied with motion only, as kernels.make_params) */
    if (!(u->max_motion_hz >= 0.0 && u->max_motion_hz < 0.5 * fs))
        return fmt_err(err, nerr, "max_motion_hz out of range: %.17g (must be 0 (off) or > 0 and below "
                       "half the sample rate, %g Hz; checked whatever the method)", u->max_motion_hz, 0.5 * fs);
    /* max(float(round(warmup_s * sample_rate_hz)), 10.0 * (n + 1)); round = half to even */
    wr = u->warmup_s * fs;
    if (!isfinite(wr))
        return fmt_err(err, nerr, "warmup_s out of range: %.17g s is too long at %.17g Hz",
                       u->warmup_s, fs);
    warmup = nearbyint(wr);
    if (10.0 * (double)(n + 1) > warmup) warmup = 10.0 * (double)(n + 1);

    memset(p, 0, N_PARAMS * sizeof *p);
    if (methods[im].value == METHOD_LOWPASS) {
        cutoff = u->cutoff_hz;
        if (cutoff == 0.0) cutoff = (0.25 * fs < 20.0) ? 0.25 * fs : 20.0; /* min(20.0, fs/4) */
        if (!(0.0 < cutoff && cutoff < 0.5 * fs))
            return fmt_err(err, nerr, "cutoff_hz out of range: %.17g (must be > 0 and below half "
                           "the sample rate, %g Hz)", cutoff, 0.5 * fs);
        if (u->lowpass_order < 1 || u->lowpass_order > 2 * MAX_SOS)
            return fmt_err(err, nerr, "order must be an integer 1..%d, got %d", 2 * MAX_SOS,
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

/* ------------------------------------------------------------ general API */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    size_t i;
    int k, on[N_CATS] = {0}, unknown = 0;
    const char *first_unknown = NULL;
    BEGIN("fmi2SetDebugLogging", MASK_SET_DEBUG_LOGGING);
    if (nCategories > 0 && !categories)
        return fail(c, "fmi2SetDebugLogging: categories is NULL with nCategories = %lu",
                    (unsigned long)nCategories);
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        for (k = 0; k < N_CATS; k++)
            if (categories[i] && strcmp(categories[i], cat_names[k]) == 0) on[k] = found = 1;
        if (!found && !unknown++) first_unknown = categories[i] ? categories[i] : "(NULL)";
    }
    c->logging_on = loggingOn ? 1 : 0;
    for (k = 0; k < N_CATS; k++) c->cat_on[k] = nCategories == 0 ? 1 : on[k];
    if (unknown) {
        logmsg(c, fmi2Warning, "fmi2SetDebugLogging: %d unknown log categor%s ignored, the first "
               "'%.100s' (known: logStatusWarning, logStatusDiscard, logStatusError, logStatusFatal, "
               "logAll)", unknown, unknown == 1 ? "y" : "ies", first_unknown);
        return fmi2Warning;
    }
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    inst_t tmp, *c;
    int k;
    (void)visible;
    memset(&tmp, 0, sizeof tmp);
    if (functions) tmp.cb = *functions;
    tmp.name = (char *)(instanceName ? instanceName : "");
    tmp.logging_on = 1;
    for (k = 0; k < N_CATS; k++) tmp.cat_on[k] = 1;
    if (!functions) return NULL; /* nowhere to report to */
    if ((functions->allocateMemory == NULL) != (functions->freeMemory == NULL)) {
        logmsg(&tmp, fmi2Error, "fmi2Instantiate: allocateMemory and freeMemory must both be given");
        return NULL;
    }
#ifdef GD_LIBM_MISSING /* a source build without -lm (see fogdenoiser_native_all.c) */
    if (GD_LIBM_MISSING()) {
        logmsg(&tmp, fmi2Error, "fmi2Instantiate: %s: the math library is not loaded in this process "
               "(%s() missing): this binary was built without -lm; rebuild it with -lm -DGD_LIBM_LINKED "
               "(fmpy: build_platform_binary(..., cmake_options={'CMAKE_C_STANDARD_LIBRARIES:STRING': "
               "'-lm', 'CMAKE_C_FLAGS:STRING': '-DGD_LIBM_LINKED'})) or use the binary shipped in the "
               "FMU", GD_MODEL_IDENTIFIER, GD_LIBM_MISSING());
        return NULL;
    }
#endif
    if (!instanceName || !instanceName[0]) {
        logmsg(&tmp, fmi2Error, "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        logmsg(&tmp, fmi2Error, "fmi2Instantiate: %s supports co-simulation only (fmuType %d)",
               GD_MODEL_IDENTIFIER, (int)fmuType);
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, GD_GUID) != 0) {
        logmsg(&tmp, fmi2Error, "fmi2Instantiate: GUID %s does not match this binary's %s",
               fmuGUID ? fmuGUID : "(NULL)", GD_GUID);
        return NULL;
    }
    c = (inst_t *)mem_alloc(&tmp, 1, sizeof *c);
    if (!c) {
        logmsg(&tmp, fmi2Error, "fmi2Instantiate: out of memory");
        return NULL;
    }
    memset(c, 0, sizeof *c);
    c->cb = tmp.cb;
    c->name = str_dup(c, instanceName);
    c->resource_uri = str_dup(c, fmuResourceLocation); /* not parsed: no resources needed */
    if (!c->name || (fmuResourceLocation && !c->resource_uri)) {
        mem_free(c, c->name);
        mem_free(c, c->resource_uri);
        mem_free(c, c);
        logmsg(&tmp, fmi2Error, "fmi2Instantiate: out of memory");
        return NULL;
    }
    c->magic = INSTANCE_MAGIC;
    c->logging_on = loggingOn ? 1 : 0;
    for (k = 0; k < N_CATS; k++) c->cat_on[k] = 1;
    set_defaults(&c->d);
    c->s = NULL;
    logmsg(c, fmi2OK, "fmi2Instantiate: %s instantiated (resources %s, not needed)",
           GD_MODEL_IDENTIFIER, fmuResourceLocation ? fmuResourceLocation : "(NULL)");
    return c;
}

static void drop_filter(inst_t *c) {
    mem_free(c, c->s);
    c->s = NULL;
    c->d.have_filter = 0;
    c->d.ns = 0;
}

void fmi2FreeInstance(fmi2Component comp) {
    inst_t *c = inst_of(comp);
    if (!c) return;
    drop_filter(c);
    while (c->states) free_state(c->states); /* states the host did not free */
    c->magic = 0;
    mem_free(c, c->name);
    mem_free(c, c->resource_uri);
    mem_free(c, c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN("fmi2SetupExperiment", MASK_SETUP_EXPERIMENT);
    (void)toleranceDefined;
    (void)tolerance;
    if (!isfinite(startTime))
        return fail(c, "fmi2SetupExperiment: startTime %g is not finite", startTime);
    if (stopTimeDefined && !(stopTime >= startTime))
        return fail(c, "fmi2SetupExperiment: stopTime %.17g is before startTime %.17g", stopTime,
                    startTime);
    c->d.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    BEGIN("fmi2EnterInitializationMode", MASK_ENTER_INIT);
    c->d.phase = ST_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    char err[512];
    long total;
    BEGIN("fmi2ExitInitializationMode", MASK_EXIT_INIT);
    if (build_params(&c->d.u, c->d.p, err, sizeof err) != 0)
        return fail(c, "fmi2ExitInitializationMode: invalid parameter: %s", err);
    total = gd_layout_total(c->d.u.ar_order);
    drop_filter(c);
    c->s = (double *)mem_alloc(c, (size_t)total, sizeof(double));
    if (!c->s) return fail(c, "fmi2ExitInitializationMode: out of memory");
    memset(c->s, 0, (size_t)total * sizeof(double));
    gd_restart(c->d.p, c->s); /* kernels.init_state */
    c->d.ns = total;
    c->d.have_filter = 1;
    c->d.filtered_rate = 0.0;
    c->d.n_steps = c->d.n_bad_steps = 0;
    c->d.phase = ST_STEP_COMPLETE;
    logmsg(c, fmi2OK, "fmi2ExitInitializationMode: method %s, AR order %d, %.17g Hz, warm-up %.0f samples",
           c->d.u.method, (int)c->d.u.ar_order, 1.0 / c->d.u.sample_period, c->d.p[P_WARMUP]);
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    BEGIN("fmi2Terminate", MASK_TERMINATE);
    if (c->d.n_bad_steps)
        logmsg(c, fmi2OK, "fmi2Terminate: %lld of %lld step(s) had a size different from "
               "sample_period %.17g s", (long long)c->d.n_bad_steps, (long long)c->d.n_steps,
               c->d.u.sample_period);
    c->d.phase = ST_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    BEGIN("fmi2Reset", MASK_RESET);
    drop_filter(c);
    set_defaults(&c->d);
    return fmi2OK;
}

/* -------------------------------------------------------- getters/setters */
static int check_vrs(inst_t *c, const char *fn, const fmi2ValueReference vr[], size_t nvr,
                     const void *value, int type) {
    static const char *const tnames[] = {"Real", "Integer", "Boolean", "String"};
    size_t i;
    if (nvr == 0) return 1;
    if (!vr || !value) {
        fail(c, "%s: NULL value-reference or value array with nvr = %lu", fn, (unsigned long)nvr);
        return 0;
    }
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= GD_N_VARS) {
            fail(c, "%s: unknown value reference %u", fn, (unsigned)vr[i]);
            return 0;
        }
        if (vars[vr[i]].type != type) {
            fail(c, "%s: value reference %u (%s) is not a %s variable", fn, (unsigned)vr[i],
                 vars[vr[i]].name, tnames[type]);
            return 0;
        }
    }
    return 1;
}

/* a set of vr is allowed in the current state: inputs in instantiated, initialization
 * mode and stepComplete; fixed parameters before fmi2ExitInitializationMode; outputs never */
static int check_settable(inst_t *c, const char *fn, const fmi2ValueReference vr[], size_t nvr) {
    size_t i;
    for (i = 0; i < nvr; i++) {
        int kind = vars[vr[i]].kind;
        if (kind == K_OUTPUT) {
            fail(c, "%s: %s is an output and cannot be set", fn, vars[vr[i]].name);
            return 0;
        }
        if (kind == K_PARAMETER && !(c->d.phase & (ST_INSTANTIATED | ST_INIT))) {
            fail(c, "%s: %s is a fixed parameter: it can only be set before "
                 "fmi2ExitInitializationMode (state is %s)", fn, vars[vr[i]].name,
                 phase_name(c->d.phase));
            return 0;
        }
    }
    return 1;
}

static double get_real(const inst_t *c, fmi2ValueReference vr) {
    const user_t *u = &c->d.u;
    const double *s = c->d.have_filter ? c->s : NULL;
    if (vr >= VR_phi_1 && vr < VR_phi_1 + GD_MAX_AR_ORDER) {
        int k = (int)(vr - VR_phi_1); /* phi_(k+1) */
        if (!s || k >= u->ar_order) return 0.0;
        return s[gd_layout(u->ar_order).theta + k];
    }
    switch (vr) {
    case VR_raw_rate: return c->d.raw_rate;
    case VR_filtered_rate: return c->d.filtered_rate;
    case VR_c: return s ? gd_c_deg_s(c->d.p, s) : 0.0;
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

static double *real_param(inst_t *c, fmi2ValueReference vr) {
    user_t *u = &c->d.u;
    switch (vr) {
    case VR_raw_rate: return &c->d.raw_rate;
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

static int32_t *int_var(inst_t *c, fmi2ValueReference vr) {
    switch (vr) {
    case VR_ar_order: return &c->d.u.ar_order;
    case VR_outlier_run: return &c->d.u.outlier_run;
    case VR_lowpass_order: return &c->d.u.lowpass_order;
    case VR_restart: return &c->d.restart;
    case VR_strict_step_size: return &c->d.u.strict_step_size;
    default: return NULL;
    }
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    size_t i;
    BEGIN("fmi2GetReal", MASK_GET);
    if (!check_vrs(c, "fmi2GetReal", vr, nvr, value, T_REAL)) return fmi2Error;
    for (i = 0; i < nvr; i++) value[i] = get_real(c, vr[i]);
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    size_t i;
    BEGIN("fmi2GetInteger", MASK_GET);
    if (!check_vrs(c, "fmi2GetInteger", vr, nvr, value, T_INTEGER)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] == VR_n_rejected) {
            double v = c->d.have_filter ? c->s[S_NREJ] : 0.0;
            value[i] = v >= (double)INT_MAX ? INT_MAX : (fmi2Integer)v;
        } else {
            value[i] = *int_var(c, vr[i]);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    size_t i;
    BEGIN("fmi2GetBoolean", MASK_GET);
    if (!check_vrs(c, "fmi2GetBoolean", vr, nvr, value, T_BOOLEAN)) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (vr[i] == VR_converged)
            value[i] = (c->d.have_filter && c->s[S_CONV] == 1.0) ? fmi2True : fmi2False;
        else
            value[i] = *int_var(c, vr[i]) ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    size_t i;
    BEGIN("fmi2GetString", MASK_GET);
    if (!check_vrs(c, "fmi2GetString", vr, nvr, value, T_STRING)) return fmi2Error;
    for (i = 0; i < nvr; i++) value[i] = c->d.u.method; /* valid until the next call */
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    size_t i;
    BEGIN("fmi2SetReal", MASK_SET);
    if (!check_vrs(c, "fmi2SetReal", vr, nvr, value, T_REAL) || !check_settable(c, "fmi2SetReal", vr, nvr))
        return fmi2Error;
    for (i = 0; i < nvr; i++) *real_param(c, vr[i]) = value[i];
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    size_t i;
    BEGIN("fmi2SetInteger", MASK_SET);
    if (!check_vrs(c, "fmi2SetInteger", vr, nvr, value, T_INTEGER) ||
        !check_settable(c, "fmi2SetInteger", vr, nvr))
        return fmi2Error;
    for (i = 0; i < nvr; i++) *int_var(c, vr[i]) = value[i];
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    size_t i;
    BEGIN("fmi2SetBoolean", MASK_SET);
    if (!check_vrs(c, "fmi2SetBoolean", vr, nvr, value, T_BOOLEAN) ||
        !check_settable(c, "fmi2SetBoolean", vr, nvr))
        return fmi2Error;
    for (i = 0; i < nvr; i++) *int_var(c, vr[i]) = value[i] ? 1 : 0;
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    size_t i;
    BEGIN("fmi2SetString", MASK_SET);
    if (!check_vrs(c, "fmi2SetString", vr, nvr, value, T_STRING) ||
        !check_settable(c, "fmi2SetString", vr, nvr))
        return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (!value[i]) return fail(c, "fmi2SetString: NULL string for %s", vars[vr[i]].name);
        if (strlen(value[i]) >= METHOD_LEN)
            return fail(c, "fmi2SetString: %s is %lu characters long, at most %d allowed",
                        vars[vr[i]].name, (unsigned long)strlen(value[i]), METHOD_LEN - 1);
    }
    for (i = 0; i < nvr; i++) strcpy(c->d.u.method, value[i]);
    return fmi2OK;
}

/* --------------------------------------------------------------- FMU state */
static fmustate_t *state_of(fmi2FMUstate st) {
    fmustate_t *f = (fmustate_t *)st;
    return (f && f->magic == FMUSTATE_MAGIC) ? f : NULL;
}

/* unlink f from the list of the instance that allocated it, free it with that
 * instance's memory callbacks */
static void free_state(fmustate_t *f) {
    inst_t *c;
    if (!f) return;
    c = (inst_t *)f->owner;
    if (f->prev) f->prev->next = f->next;
    else if (c->states == f) c->states = f->next;
    if (f->next) f->next->prev = f->prev;
    f->magic = 0;
    mem_free(c, f->s);
    mem_free(c, f);
}

/* a new FMU state holding d and s (ns doubles) */
static fmustate_t *new_state(inst_t *c, const dyn_t *d, const double *s) {
    fmustate_t *f = (fmustate_t *)mem_alloc(c, 1, sizeof *f);
    if (!f) return NULL;
    memset(f, 0, sizeof *f);
    f->d = *d;
    f->s = NULL;
    if (d->ns > 0) {
        f->s = (double *)mem_alloc(c, (size_t)d->ns, sizeof(double));
        if (!f->s) {
            mem_free(c, f);
            return NULL;
        }
        memcpy(f->s, s, (size_t)d->ns * sizeof(double));
    }
    f->magic = FMUSTATE_MAGIC;
    f->owner = c;
    f->prev = NULL;
    f->next = c->states;
    if (c->states) c->states->prev = f;
    c->states = f;
    return f;
}

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    fmustate_t *f, *old;
    BEGIN("fmi2GetFMUstate", MASK_FMU_STATE);
    if (!FMUstate) return fail(c, "fmi2GetFMUstate: FMUstate is NULL");
    old = *FMUstate ? state_of(*FMUstate) : NULL;
    if (*FMUstate && !old)
        return fail(c, "fmi2GetFMUstate: *FMUstate is neither NULL nor a state of this FMU");
    if (old && old->d.ns == c->d.ns) { /* overwrite in place */
        old->d = c->d;
        if (c->d.ns > 0) memcpy(old->s, c->s, (size_t)c->d.ns * sizeof(double));
        return fmi2OK;
    }
    f = new_state(c, &c->d, c->s);
    if (!f) return fail(c, "fmi2GetFMUstate: out of memory");
    free_state(old);
    *FMUstate = f;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate) {
    fmustate_t *f;
    double *s = NULL;
    BEGIN("fmi2SetFMUstate", MASK_FMU_STATE);
    f = state_of(FMUstate);
    if (!f) return fail(c, "fmi2SetFMUstate: not a state of this FMU (NULL, freed or foreign)");
    if (f->d.ns > 0) {
        s = (double *)mem_alloc(c, (size_t)f->d.ns, sizeof(double));
        if (!s) return fail(c, "fmi2SetFMUstate: out of memory");
        memcpy(s, f->s, (size_t)f->d.ns * sizeof(double));
    }
    mem_free(c, c->s);
    c->s = s;
    c->d = f->d;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    fmustate_t *f;
    BEGIN("fmi2FreeFMUstate", MASK_FMU_STATE);
    if (!FMUstate || !*FMUstate) return fmi2OK; /* nothing to free */
    f = state_of(*FMUstate);
    if (!f) return fail(c, "fmi2FreeFMUstate: not a state of this FMU");
    free_state(f);
    *FMUstate = NULL;
    return fmi2OK;
}

/* Serialized form (native byte order; checked on deserialization):
 *   "GDNATIVE" | u32 version | u32 byte-order mark 0x01020304 | u64 total size |
 *   u64 N_PARAMS | dyn_t fields one by one | s[ns] | u64 FNV-1a of all bytes before */
#define SER_HEADER (8 + 4 + 4 + 8 + 8)
#define SER_DYN (8 * 4 + 4 * 4 + METHOD_LEN + 8 * 13 + 8 * 3 + 8 * 3 + 8 * N_PARAMS)

static size_t serial_size(int64_t ns) { return SER_HEADER + SER_DYN + 8 * (size_t)ns + 8; }

static uint64_t fnv1a(const unsigned char *b, size_t n) {
    uint64_t h = 1469598103934665603ULL;
    size_t i;
    for (i = 0; i < n; i++) {
        h ^= b[i];
        h *= 1099511628211ULL;
    }
    return h;
}

typedef struct { unsigned char *b; size_t at, n; int ok; } cursor_t;

static void put(cursor_t *w, const void *src, size_t n) {
    if (w->at + n > w->n) { w->ok = 0; return; }
    memcpy(w->b + w->at, src, n);
    w->at += n;
}

static void get(cursor_t *r, void *dst, size_t n) {
    if (r->at + n > r->n) { r->ok = 0; memset(dst, 0, n); return; }
    memcpy(dst, r->b + r->at, n);
    r->at += n;
}

/* the fields of d in a fixed order, in either direction */
static void xfer_dyn(cursor_t *cu, dyn_t *d, void (*io)(cursor_t *, void *, size_t)) {
    int32_t *i32[] = {&d->phase, &d->restart, &d->have_filter, &d->pad_};
    int32_t *u32[] = {&d->u.ar_order, &d->u.outlier_run, &d->u.lowpass_order, &d->u.strict_step_size};
    double *f64[] = {&d->u.sample_period, &d->u.lam, &d->u.b, &d->u.gamma, &d->u.q0, &d->u.r0,
                     &d->u.p0_rls, &d->u.p0_kf, &d->u.warmup_s, &d->u.r_floor, &d->u.outlier_sigma,
                     &d->u.cutoff_hz, &d->u.max_motion_hz};
    size_t k;
    for (k = 0; k < 4; k++) { int64_t v = *i32[k]; io(cu, &v, 8); *i32[k] = (int32_t)v; }
    for (k = 0; k < 4; k++) io(cu, u32[k], 4);
    io(cu, d->u.method, METHOD_LEN);
    for (k = 0; k < 13; k++) io(cu, f64[k], 8);
    io(cu, &d->raw_rate, 8);
    io(cu, &d->time, 8);
    io(cu, &d->filtered_rate, 8);
    io(cu, &d->n_steps, 8);
    io(cu, &d->n_bad_steps, 8);
    io(cu, &d->ns, 8);
    io(cu, d->p, 8 * N_PARAMS);
}

static void io_put(cursor_t *c, void *p, size_t n) { put(c, p, n); }
static void io_get(cursor_t *c, void *p, size_t n) { get(c, p, n); }

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate, size_t *size) {
    fmustate_t *f;
    BEGIN("fmi2SerializedFMUstateSize", MASK_FMU_STATE);
    f = state_of(FMUstate);
    if (!f) return fail(c, "fmi2SerializedFMUstateSize: not a state of this FMU");
    if (!size) return fail(c, "fmi2SerializedFMUstateSize: size is NULL");
    *size = serial_size(f->d.ns);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    fmustate_t *f;
    cursor_t w;
    dyn_t d;
    uint32_t version = SERIAL_VERSION, bom = 0x01020304u;
    uint64_t total, npar = N_PARAMS, h;
    BEGIN("fmi2SerializeFMUstate", MASK_FMU_STATE);
    f = state_of(FMUstate);
    if (!f) return fail(c, "fmi2SerializeFMUstate: not a state of this FMU");
    total = serial_size(f->d.ns);
    if (!serializedState || size < total)
        return fail(c, "fmi2SerializeFMUstate: buffer of %lu bytes, %lu needed (fmi2SerializedFMUstateSize)",
                    (unsigned long)size, (unsigned long)total);
    w.b = (unsigned char *)serializedState;
    w.at = 0;
    w.n = (size_t)total;
    w.ok = 1;
    put(&w, "GDNATIVE", 8);
    put(&w, &version, 4);
    put(&w, &bom, 4);
    put(&w, &total, 8);
    put(&w, &npar, 8);
    d = f->d;
    xfer_dyn(&w, &d, io_put);
    if (f->d.ns > 0) put(&w, f->s, 8 * (size_t)f->d.ns);
    h = fnv1a(w.b, w.at);
    put(&w, &h, 8);
    if (!w.ok || w.at != total) return fail(c, "fmi2SerializeFMUstate: internal size mismatch");
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    cursor_t r;
    char magic[8], err[512];
    uint32_t version, bom;
    uint64_t total, npar, h, h_read;
    dyn_t d;
    double p[N_PARAMS];
    double *s = NULL;
    fmustate_t *f;
    int phases = ST_ALL_BUT_FATAL;
    BEGIN("fmi2DeSerializeFMUstate", MASK_FMU_STATE);
    if (!FMUstate) return fail(c, "fmi2DeSerializeFMUstate: FMUstate is NULL");
    if (!serializedState || size < SER_HEADER + 8)
        return fail(c, "fmi2DeSerializeFMUstate: %lu bytes is too short for a serialized state",
                    (unsigned long)size);
    r.b = (unsigned char *)serializedState;
    r.at = 0;
    r.n = size;
    r.ok = 1;
    get(&r, magic, 8);
    get(&r, &version, 4);
    get(&r, &bom, 4);
    get(&r, &total, 8);
    get(&r, &npar, 8);
    if (memcmp(magic, "GDNATIVE", 8) != 0)
        return fail(c, "fmi2DeSerializeFMUstate: not a serialized %s state", GD_MODEL_IDENTIFIER);
    if (bom != 0x01020304u)
        return fail(c, "fmi2DeSerializeFMUstate: serialized on a platform of another byte order");
    if (version != SERIAL_VERSION || npar != N_PARAMS)
        return fail(c, "fmi2DeSerializeFMUstate: serialized state version %u (%lu parameters), this "
                    "binary reads version %u (%d parameters)", (unsigned)version, (unsigned long)npar,
                    SERIAL_VERSION, N_PARAMS);
    if (total != size)
        return fail(c, "fmi2DeSerializeFMUstate: %lu bytes given, the state says %lu (truncated?)",
                    (unsigned long)size, (unsigned long)total);
    memcpy(&h_read, r.b + size - 8, 8);
    h = fnv1a(r.b, size - 8);
    if (h != h_read) return fail(c, "fmi2DeSerializeFMUstate: checksum mismatch (corrupted state)");
    memset(&d, 0, sizeof d);
    xfer_dyn(&r, &d, io_get);
    if (!r.ok || d.ns < 0 || serial_size(d.ns) != size)
        return fail(c, "fmi2DeSerializeFMUstate: inconsistent sizes (corrupted state)");
    if (!(d.phase & phases) || (d.phase & (d.phase - 1)) || memchr(d.u.method, 0, METHOD_LEN) == NULL
        || (d.have_filter != 0 && d.have_filter != 1) || (d.restart != 0 && d.restart != 1)
        || ((d.phase & (ST_INSTANTIATED | ST_INIT)) && d.have_filter)
        || ((d.phase & (ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED)) && !d.have_filter))
        return fail(c, "fmi2DeSerializeFMUstate: invalid state fields (corrupted state)");
    if (d.have_filter) {
        if (build_params(&d.u, p, err, sizeof err) != 0)
            return fail(c, "fmi2DeSerializeFMUstate: invalid parameter in the state: %s", err);
        if (memcmp(p, d.p, sizeof p) != 0 || d.ns != gd_layout_total(d.u.ar_order))
            return fail(c, "fmi2DeSerializeFMUstate: filter buffers do not match the parameters "
                        "(corrupted state)");
    } else if (d.ns != 0) {
        return fail(c, "fmi2DeSerializeFMUstate: filter buffer without a filter (corrupted state)");
    }
    if (d.ns > 0) {
        s = (double *)mem_alloc(c, (size_t)d.ns, sizeof(double));
        if (!s) return fail(c, "fmi2DeSerializeFMUstate: out of memory");
        get(&r, s, 8 * (size_t)d.ns);
    }
    f = new_state(c, &d, s);
    mem_free(c, s);
    if (!f) return fail(c, "fmi2DeSerializeFMUstate: out of memory");
    *FMUstate = f;
    return fmi2OK;
}

/* ------------------------------------------------- not provided by this FMU */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    inst_t *c = inst_of(comp);
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    if (!c) return fmi2Error;
    return fail(c, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=false)");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    inst_t *c = inst_of(comp);
    (void)vr; (void)nvr; (void)order; (void)value;
    if (!c) return fmi2Error;
    return fail(c, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    inst_t *c = inst_of(comp);
    (void)vr; (void)nvr; (void)order; (void)value;
    if (!c) return fmi2Error;
    return fail(c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder=0)");
}

/* --------------------------------------------------------------- stepping */
fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    fmi2Status status = fmi2OK;
    double h = communicationStepSize, t = currentCommunicationPoint, T, z;
    BEGIN("fmi2DoStep", MASK_DO_STEP);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!c->d.have_filter || !c->s) return fail(c, "fmi2DoStep: no filter (internal error)");
    T = c->d.u.sample_period;
    z = c->d.raw_rate;
    if (!isfinite(t))
        return fail(c, "fmi2DoStep: currentCommunicationPoint %g is not finite", t);
    if (!(h > 0.0) || !isfinite(h))
        return fail(c, "fmi2DoStep: communication step size %.17g at t=%.17g s is not a finite "
                    "number > 0", h, t);
    if (fabs(h - T) > STEP_RTOL * T) {
        c->d.n_bad_steps++;
        if (c->d.u.strict_step_size) {
            logmsg(c, fmi2Discard, "fmi2DoStep: step size %.17g s at t=%.17g s differs from "
                   "sample_period %.17g s; step refused (strict_step_size)", h, t, T);
            c->d.phase = ST_STEP_FAILED;
            return fmi2Discard;
        }
        if (c->d.n_bad_steps == 1 || c->d.n_bad_steps % 100000 == 0)
            logmsg(c, fmi2Warning, "fmi2DoStep: step size %.17g s at t=%.17g s differs from "
                   "sample_period %.17g s; one step = one sample, so the filter's time base is "
                   "wrong (%lld such step(s) so far)", h, t, T, (long long)c->d.n_bad_steps);
        status = fmi2Warning;
    }
    if (!isfinite(z))
        return fail(c, "fmi2DoStep: raw_rate is %g at t=%.17g s; sample refused, filter state "
                    "unchanged", z, t);
    c->d.filtered_rate = gd_step(c->d.p, c->s, z, c->d.restart ? 1 : 0);
    c->d.n_steps++;
    c->d.time = t + h;
    return status;
}

fmi2Status fmi2CancelStep(fmi2Component comp) {
    inst_t *c = inst_of(comp);
    if (!c) return fmi2Error;
    return fail(c, "fmi2CancelStep: no asynchronous step to cancel (fmi2DoStep never returns fmi2Pending)");
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value) {
    BEGIN("fmi2GetStatus", MASK_STATUS);
    (void)value;
    logmsg(c, fmi2Discard, "fmi2GetStatus: status kind %d not available (no asynchronous steps)", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    BEGIN("fmi2GetRealStatus", MASK_STATUS);
    if (s == fmi2LastSuccessfulTime && value) {
        *value = c->d.time;
        return fmi2OK;
    }
    logmsg(c, fmi2Discard, "fmi2GetRealStatus: status kind %d not available", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value) {
    BEGIN("fmi2GetIntegerStatus", MASK_STATUS);
    (void)value;
    logmsg(c, fmi2Discard, "fmi2GetIntegerStatus: status kind %d not available", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value) {
    BEGIN("fmi2GetBooleanStatus", MASK_STATUS);
    if (s == fmi2Terminated && value) {
        *value = fmi2False; /* the slave never asks to end the simulation */
        return fmi2OK;
    }
    logmsg(c, fmi2Discard, "fmi2GetBooleanStatus: status kind %d not available", (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value) {
    BEGIN("fmi2GetStringStatus", MASK_STATUS);
    (void)value;
    logmsg(c, fmi2Discard, "fmi2GetStringStatus: status kind %d not available", (int)s);
    return fmi2Discard;
}
