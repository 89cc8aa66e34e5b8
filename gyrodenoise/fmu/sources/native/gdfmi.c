/*
 * gdfmi.c -- the co-simulation layer shared by the native FMUs (see gdfmi.h), written once
 * for FMI 2.0 and FMI 3.0: the state machine, logging, get/set checks, FMU states. The
 * exported entry points are thin wrappers over these gdl_* functions: gdfmi2.c (fmi2*) and
 * gdfmi3.c (fmi3*). Included after the model file, which defines
 * `static const gdfmi_model_t gdfmi_model`.
 */
#include "gdfmi.h"

#define GDM (&gdfmi_model)

#define INSTANCE_MAGIC 0x46444e49u /* "FDNI" */
#define FMUSTATE_MAGIC 0x46444e53u /* "FDNS" */

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

static const char *const cat_names[N_CATS] = {
    "logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal", "logAll"};

/* an FMU state: linked into its instance's list, so that FreeInstance frees the
 * states the host did not free (FMI 2.0: fmi2FreeInstance frees all it allocated) */
struct gdfmi_state_s {
    uint32_t magic;
    uint64_t tag; /* the model's (model_tag): every native FMU shares this layer and its magic */
    gdfmi_core_t k;
    void *m;
    double *s;
    gdfmi_inst_t *owner; /* the instance that allocated it */
    gdfmi_state_t *prev, *next;
};

/* ------------------------------------------------------------------ memory */
static void *gdfmi_alloc(const gdfmi_inst_t *c, size_t n, size_t size) {
    if (n == 0) n = 1;
#if GD_FMI_VERSION == 2
    if (c && c->cb.allocateMemory) return c->cb.allocateMemory(n, size);
#else
    (void)c;
#endif
    return calloc(n, size);
}

static void gdfmi_free(const gdfmi_inst_t *c, void *ptr) {
    if (!ptr) return;
#if GD_FMI_VERSION == 2
    if (c && c->cb.freeMemory) c->cb.freeMemory(ptr);
    else free(ptr);
#else
    (void)c;
    free(ptr);
#endif
}

static char *str_dup(const gdfmi_inst_t *c, const char *src) {
    size_t n;
    char *dst;
    if (!src) return NULL;
    n = strlen(src) + 1;
    dst = (char *)gdfmi_alloc(c, n, 1);
    if (dst) memcpy(dst, src, n);
    return dst;
}

static void gdfmi_strip(const char *s, const char **begin, const char **end) {
    const char *a = s, *e;
#define PY_SPACE(ch) ((ch) == ' ' || ((ch) >= 0x09 && (ch) <= 0x0d) || ((ch) >= 0x1c && (ch) <= 0x1f))
    while (*a && PY_SPACE((unsigned char)*a)) a++;
    e = a + strlen(a);
    while (e > a && PY_SPACE((unsigned char)e[-1])) e--;
#undef PY_SPACE
    *begin = a;
    *end = e;
}

/* ----------------------------------------------------------------- logging */
static int cat_of(gd_status_t st) {
    switch (st) {
    case GD_WARNING: return CAT_WARNING;
    case GD_DISCARD: return CAT_DISCARD;
    case GD_ERROR: return CAT_ERROR;
    case GD_FATAL: return CAT_FATAL;
    default: return CAT_ALL;
    }
}

static void vlogmsg(const gdfmi_inst_t *c, gd_status_t st, const char *fmt, va_list ap) {
    char text[1024];
#if GD_FMI_VERSION == 2
    char escaped[2048];
    size_t i, j;
#endif
    int cat = cat_of(st);
    if (!c || !c->cb.logger) return;
    if (st == GD_OK) { /* information: only when logging is on and its category enabled */
        if (!c->logging_on || !(c->cat_on[cat] || c->cat_on[CAT_ALL])) return;
    } /* a message explaining a status other than OK (a warning or a refusal) always goes out */
    vsnprintf(text, sizeof text, fmt, ap);
#if GD_FMI_VERSION == 3
    c->cb.logger(c->cb.env, (fmi3Status)st, cat_names[cat], text); /* FMI 3.0: the message is plain text */
#else
    /* the logger treats the message as a printf format: escape '%' */
    for (i = 0, j = 0; text[i] && j + 2 < sizeof escaped; i++) {
        if (text[i] == '%') escaped[j++] = '%';
        escaped[j++] = text[i];
    }
    escaped[j] = '\0';
    c->cb.logger(c->cb.componentEnvironment, c->name ? c->name : "", (fmi2Status)st, cat_names[cat], escaped);
#endif
}

static void gdfmi_log(const gdfmi_inst_t *c, gd_status_t st, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlogmsg(c, st, fmt, ap);
    va_end(ap);
}

/* log the reason and enter the error state */
static gd_status_t gdfmi_fail(gdfmi_inst_t *c, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlogmsg(c, GD_ERROR, fmt, ap);
    va_end(ap);
    c->k.phase = ST_ERROR;
    return GD_ERROR;
}

static int gdfmi_fmt_err(char *err, size_t n, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, n, fmt, ap);
    va_end(ap);
    return -1;
}

static const char *phase_name(int phase) {
    switch (phase) {
    case ST_INSTANTIATED: return "instantiated";
    case ST_INIT: return "initializationMode";
    case ST_STEP_COMPLETE: return GD_FMI_VERSION == 3 ? "stepMode" : "stepComplete";
    case ST_STEP_FAILED: return "stepFailed";
    case ST_TERMINATED: return "terminated";
    case ST_ERROR: return "error";
    case ST_FATAL: return "fatal";
    default: return "unknown";
    }
}

/* the instance behind c, or NULL (a NULL or foreign pointer cannot be logged to) */
static gdfmi_inst_t *inst_of(void *c) {
    gdfmi_inst_t *i = (gdfmi_inst_t *)c;
    if (!i || i->magic != INSTANCE_MAGIC) return NULL;
    return i;
}

/* 1 if a call of fn is allowed in the current state; else logs, enters the error state */
static int allowed(gdfmi_inst_t *c, int mask, const char *fn) {
    if (c->k.phase & mask) return 1;
    if (c->k.phase == ST_FATAL) {
        gdfmi_log(c, GD_ERROR, "%s: not allowed: the instance is in the fatal state", fn);
        return 0;
    }
    gdfmi_fail(c, "%s: not allowed in state %s (" GD_FMI_NAME " co-simulation state machine)", fn,
               phase_name(c->k.phase));
    return 0;
}

/* the first lines of an entry point: the instance behind `comp`, in a state that allows fn */
#define BEGIN(fn, mask)                        \
    gdfmi_inst_t *c = inst_of(comp);           \
    if (!c) return GD_API_ERROR;               \
    if (!allowed(c, (mask), fn)) return GD_API_ERROR

/* ------------------------------------------------------------- resources */
static int hexval(int ch) {
    if (ch >= '0' && ch <= '9') return ch - '0';
    if (ch >= 'a' && ch <= 'f') return ch - 'a' + 10;
    if (ch >= 'A' && ch <= 'F') return ch - 'A' + 10;
    return -1;
}

/* The fmuResourceLocation URI as a local path: file:///p, file:/p, file://localhost/p
 * (p percent-decoded; file:///C:/p is C:/p on Windows); also accepted: a drive letter
 * as authority (file://C:/p) and a plain path without a scheme. */
GDFMI_MAYBE_UNUSED static int gdfmi_resource_path(const gdfmi_inst_t *c, const char *relative, char *out, size_t n,
                               char *err, size_t nerr) {
    const char *u = c->resource_uri, *p;
    size_t j = 0, i, len;
    if (!u || !u[0])
        return gdfmi_fmt_err(err, nerr, "no resource location given to " GD_FN_INSTANTIATE " (needed for "
                             "resources/%s)", relative);
    if (strncmp(u, "file:", 5) == 0) {
        p = u + 5;
        if (strncmp(p, "//", 2) == 0) {
            p += 2;
            if (strncmp(p, "localhost/", 10) == 0) p += 9;
            else if (*p != '/' && !(((p[0] | 32) >= 'a' && (p[0] | 32) <= 'z') && p[1] == ':'))
                return gdfmi_fmt_err(err, nerr, "resource location %.200s: a file URI on another host "
                                     "is not a local path", u);
        }
#ifdef _WIN32
        if (p[0] == '/' && p[1] && p[2] == ':') p++; /* /C:/x -> C:/x */
#endif
    } else if (strstr(u, "://") != NULL) {
        return gdfmi_fmt_err(err, nerr, "resource location %.200s: only file: URIs are supported", u);
    } else {
        p = u; /* a plain path */
    }
    len = strlen(p);
    for (i = 0; i < len; i++) {
        int ch = (unsigned char)p[i];
        /* FMI 3.0's resourcePath is a plain path: percent-decoded only when given as a URI */
        if (ch == '%' && (GD_FMI_VERSION == 2 || p != u) && i + 2 < len + 0 && hexval(p[i + 1]) >= 0 && hexval(p[i + 2]) >= 0) {
            ch = hexval(p[i + 1]) * 16 + hexval(p[i + 2]);
            i += 2;
        }
        if (j + 1 >= n) break;
        out[j++] = (char)ch;
    }
    while (j > 0 && (out[j - 1] == '/' || out[j - 1] == '\\')) j--;
    if (j + 1 + strlen(relative) + 1 > n)
        return gdfmi_fmt_err(err, nerr, "resource location %.200s: path too long", u);
    out[j++] = '/';
    strcpy(out + j, relative);
    return 0;
}

/* ------------------------------------------------------------ general API */
/* the categories to enable: nCategories 0 = all; an unknown name is a warning */
static gd_status_t gdl_set_debug_logging(gdfmi_inst_t *c, const char *fn, int loggingOn, size_t nCategories,
                                         const char *const categories[]) {
    size_t i;
    int k, on[N_CATS] = {0}, unknown = 0;
    const char *first_unknown = NULL;
    if (nCategories > 0 && !categories)
        return gdfmi_fail(c, "%s: categories is NULL with nCategories = %lu", fn, (unsigned long)nCategories);
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        for (k = 0; k < N_CATS; k++)
            if (categories[i] && strcmp(categories[i], cat_names[k]) == 0) on[k] = found = 1;
        if (!found && !unknown++) first_unknown = categories[i] ? categories[i] : "(NULL)";
    }
    c->logging_on = loggingOn ? 1 : 0;
    for (k = 0; k < N_CATS; k++) c->cat_on[k] = nCategories == 0 ? 1 : on[k];
    if (unknown) {
        gdfmi_log(c, GD_WARNING, "%s: %d unknown log categor%s ignored, the first "
                  "'%.100s' (known: logStatusWarning, logStatusDiscard, logStatusError, logStatusFatal, "
                  "logAll)", fn, unknown, unknown == 1 ? "y" : "ies", first_unknown);
        return GD_WARNING;
    }
    return GD_OK;
}

static void set_defaults(gdfmi_inst_t *c) {
    memset(&c->k, 0, sizeof c->k);
    memset(c->m, 0, GDM->m_size);
    GDM->defaults(c->m);
    c->k.phase = ST_INSTANTIATED;
}

/* A new instance, or NULL with the reason logged through tmp (the host's callbacks in
 * tmp->cb, logging on). The version's entry point checked what only it has (fmuType). */
static gdfmi_inst_t *gdl_instantiate(gdfmi_inst_t *tmp, const char *instanceName, const char *token,
                                     const char *resource, int loggingOn) {
    gdfmi_inst_t *c;
    int k;
#ifdef GD_LIBM_MISSING /* a source build without -lm (see gdfmi_libm.h) */
    if (GD_LIBM_MISSING()) {
        gdfmi_log(tmp, GD_ERROR, GD_FN_INSTANTIATE ": %s: the math library is not loaded in this process "
                  "(%s() missing): this binary was built without -lm; rebuild it with -lm -DGD_LIBM_LINKED "
                  "(fmpy: build_platform_binary(..., cmake_options={'CMAKE_C_STANDARD_LIBRARIES:STRING': "
                  "'-lm', 'CMAKE_C_FLAGS:STRING': '-DGD_LIBM_LINKED'})) or use the binary shipped in the "
                  "FMU", GDM->identifier, GD_LIBM_MISSING());
        return NULL;
    }
#endif
    if (!instanceName || !instanceName[0]) {
        gdfmi_log(tmp, GD_ERROR, GD_FN_INSTANTIATE ": instanceName must be a non-empty string");
        return NULL;
    }
    if (!token || strcmp(token, GDM->guid) != 0) {
        gdfmi_log(tmp, GD_ERROR, GD_FN_INSTANTIATE ": " GD_TOKEN_NAME " %s does not match this binary's %s",
                  token ? token : "(NULL)", GDM->guid);
        return NULL;
    }
    c = (gdfmi_inst_t *)gdfmi_alloc(tmp, 1, sizeof *c);
    if (!c) {
        gdfmi_log(tmp, GD_ERROR, GD_FN_INSTANTIATE ": out of memory");
        return NULL;
    }
    memset(c, 0, sizeof *c);
    c->cb = tmp->cb;
    c->name = str_dup(c, instanceName);
    c->resource_uri = str_dup(c, resource);
    c->m = gdfmi_alloc(c, 1, GDM->m_size);
    if (!c->name || !c->m || (resource && !c->resource_uri)) {
        gdfmi_free(c, c->name);
        gdfmi_free(c, c->resource_uri);
        gdfmi_free(c, c->m);
        gdfmi_free(c, c);
        gdfmi_log(tmp, GD_ERROR, GD_FN_INSTANTIATE ": out of memory");
        return NULL;
    }
    c->magic = INSTANCE_MAGIC;
    c->logging_on = loggingOn ? 1 : 0;
    for (k = 0; k < N_CATS; k++) c->cat_on[k] = 1;
    set_defaults(c);
    c->s = NULL;
    gdfmi_log(c, GD_OK, GD_FN_INSTANTIATE ": %s instantiated (resources %s)", GDM->identifier,
              resource ? resource : "(NULL)");
    return c;
}

static void drop_model(gdfmi_inst_t *c) {
    gdfmi_free(c, c->s);
    c->s = NULL;
    c->k.have_model = 0;
    c->k.ns = 0;
}

static void free_state(gdfmi_state_t *f);

static void gdl_free_instance(void *comp) {
    gdfmi_inst_t *c = inst_of(comp);
    if (!c) return;
    drop_model(c);
    while (c->states) free_state(c->states); /* states the host did not free */
    c->magic = 0;
    gdfmi_free(c, c->name);
    gdfmi_free(c, c->resource_uri);
    gdfmi_free(c, c->m);
    gdfmi_free(c, c);
}

/* the experiment's start time (and stop time, if defined) */
static gd_status_t gdl_setup_experiment(gdfmi_inst_t *c, const char *fn, double startTime, int stopTimeDefined,
                                        double stopTime) {
    if (!isfinite(startTime))
        return gdfmi_fail(c, "%s: startTime %g is not finite", fn, startTime);
    if (stopTimeDefined && !(stopTime >= startTime))
        return gdfmi_fail(c, "%s: stopTime %.17g is before startTime %.17g", fn, stopTime, startTime);
    c->k.time = startTime;
    return GD_OK;
}

/* ---------------------------------------------- outputs before the first step */
/* The outputs for the parameters and inputs set so far, computed on a scratch copy of c (tmp:
 * its own m and s, no logger, no FMU states): the model built and started and, for a model whose
 * first sample a step takes (first_sample_at_start 0: the denoisers), one step at the start time.
 * So a master that propagates values in initialisation mode (OMSimulator) reads the sensor's
 * sample 0 and the denoiser's first output, not placeholders. 1 if tmp holds them (free it with
 * drop_scratch); 0 where the parameters cannot build the model (ExitInitializationMode will say
 * why) or memory is short: the outputs then read as before initialisation. */
static int first_outputs(gdfmi_inst_t *c, gdfmi_inst_t *tmp) {
    char err[512];
    long total;
    *tmp = *c;
    tmp->cb.logger = NULL;
    tmp->states = NULL;
    tmp->s = NULL;
    tmp->m = gdfmi_alloc(c, 1, GDM->m_size);
    if (!tmp->m) return 0;
    memcpy(tmp->m, c->m, GDM->m_size);
    total = GDM->build(tmp, err, sizeof err);
    if (total > 0) tmp->s = (double *)gdfmi_alloc(c, (size_t)total, sizeof(double));
    if (!tmp->s) {
        gdfmi_free(c, tmp->m);
        return 0;
    }
    memset(tmp->s, 0, (size_t)total * sizeof(double));
    tmp->k.ns = total;
    tmp->k.have_model = 1;
    GDM->start(tmp);
    if (!GDM->first_sample_at_start) {
        gd_status_t st = GDM->step(tmp, tmp->k.time);
        if (st != GD_OK && st != GD_WARNING) {
            gdfmi_free(c, tmp->s);
            gdfmi_free(c, tmp->m);
            return 0;
        }
    }
    return 1;
}

static void drop_scratch(gdfmi_inst_t *tmp) {
    gdfmi_free(tmp, tmp->s);
    gdfmi_free(tmp, tmp->m);
}

static gd_status_t gdl_exit_initialization_mode(gdfmi_inst_t *c) {
    char err[1024], info[512];
    long total;
    err[0] = '\0';
    total = GDM->build(c, err, sizeof err);
    if (total <= 0) return gdfmi_fail(c, GD_FN("ExitInitializationMode") ": invalid parameter: %s", err);
    drop_model(c);
    c->s = (double *)gdfmi_alloc(c, (size_t)total, sizeof(double));
    if (!c->s) return gdfmi_fail(c, GD_FN("ExitInitializationMode") ": out of memory");
    memset(c->s, 0, (size_t)total * sizeof(double));
    c->k.ns = total;
    GDM->start(c);
    if (!GDM->first_sample_at_start) { /* until the first step, its outputs (a step changes only outputs in m) */
        gdfmi_inst_t tmp;
        if (first_outputs(c, &tmp)) {
            memcpy(c->m, tmp.m, GDM->m_size);
            drop_scratch(&tmp);
        }
    }
    c->k.have_model = 1;
    c->k.n_steps = c->k.n_bad_steps = 0;
    c->k.phase = ST_STEP_COMPLETE;
    if (c->logging_on) {
        GDM->describe(c, info, sizeof info);
        gdfmi_log(c, GD_OK, GD_FN("ExitInitializationMode") ": %s", info);
    }
    return GD_OK;
}

static gd_status_t gdl_terminate(gdfmi_inst_t *c) {
    if (c->k.n_bad_steps)
        gdfmi_log(c, GD_OK, GD_FN("Terminate") ": %lld step(s) had a size different from %s %.17g s "
                  "(%lld sample(s) taken)", (long long)c->k.n_bad_steps, GDM->period_name,
                  GDM->period(c->m), (long long)c->k.n_steps);
    if (c->n_slivers)
        gdfmi_log(c, GD_OK, GD_FN("Terminate") ": %lld step(s) shorter than %g of %s %.17g s took no "
                  "sample (a master's accumulated time)", (long long)c->n_slivers, SLIVER_RTOL,
                  GDM->period_name, GDM->period(c->m));
    c->k.phase = ST_TERMINATED;
    return GD_OK;
}

static gd_status_t gdl_reset(gdfmi_inst_t *c) {
    drop_model(c);
    set_defaults(c);
    c->n_slivers = 0;
    return GD_OK;
}

/* -------------------------------------------------------- getters/setters */
/* FMI 3.0: the independent variable "time" (Float64, read only), value reference = the number of
 * the model's variables (after them: theirs are the same in both versions) */
#if GD_FMI_VERSION == 3
#define IS_TIME(vr) ((vr) == GDM->n_vars)
#else
#define IS_TIME(vr) 0
#endif

/* every vr names a variable of the type, and their values number nValues (FMI 2.0: nvr) */
static int check_vrs(gdfmi_inst_t *c, const char *fn, const gd_vr_t vr[], size_t nvr, const void *value,
                     size_t nValues, int type) {
    static const char *const tnames[] = {GD_TYPE_NAME_REAL, GD_TYPE_NAME_INTEGER, "Boolean", "String"};
    size_t i, total = 0;
    if (nvr == 0) return 1;
    if (!vr || !value) {
        gdfmi_fail(c, "%s: NULL value-reference or value array with nvr = %lu", fn, (unsigned long)nvr);
        return 0;
    }
    for (i = 0; i < nvr; i++) {
        if (IS_TIME(vr[i]) && type == T_REAL) { /* FMI 3.0: the independent variable */
            total += 1;
            continue;
        }
        if (vr[i] >= GDM->n_vars) {
            gdfmi_fail(c, "%s: unknown value reference %u", fn, (unsigned)vr[i]);
            return 0;
        }
        if (GDM->vars[vr[i]].type != type) {
            gdfmi_fail(c, "%s: value reference %u (%s) is not a %s variable", fn, (unsigned)vr[i],
                       GDM->vars[vr[i]].name, tnames[type]);
            return 0;
        }
        total += GDM->vars[vr[i]].n;
    }
    if (total != nValues) {
        gdfmi_fail(c, "%s: nValues = %lu, the %lu variable(s) have %lu value(s)", fn, (unsigned long)nValues,
                   (unsigned long)nvr, (unsigned long)total);
        return 0;
    }
    return 1;
}

/* a set of vr is allowed in the current state: inputs in instantiated, initialization
 * mode and step mode; fixed parameters before ExitInitializationMode; outputs never */
static int check_settable(gdfmi_inst_t *c, const char *fn, const gd_vr_t vr[], size_t nvr) {
    size_t i;
    for (i = 0; i < nvr; i++) {
        int kind;
        if (IS_TIME(vr[i])) {
            gdfmi_fail(c, "%s: time is the independent variable and cannot be set", fn);
            return 0;
        }
        kind = GDM->vars[vr[i]].kind;
        if (kind == K_OUTPUT) {
            gdfmi_fail(c, "%s: %s is an output and cannot be set", fn, GDM->vars[vr[i]].name);
            return 0;
        }
        if (kind == K_PARAMETER && !(c->k.phase & (ST_INSTANTIATED | ST_INIT))) {
            gdfmi_fail(c, "%s: %s is a fixed parameter: it can only be set before "
                       GD_FN("ExitInitializationMode") " (state is %s)", fn, GDM->vars[vr[i]].name,
                       phase_name(c->k.phase));
            return 0;
        }
    }
    return 1;
}

/* Get<Real>: the values of vr (an array variable's n values in a row) */
/* the instance the values of vr are read from: c, or in initialisation mode, when vr names an
 * output, the scratch copy tmp holding the first sample's outputs (drop_scratch it when != c) */
static gdfmi_inst_t *read_source(gdfmi_inst_t *c, const gd_vr_t vr[], size_t nvr, gdfmi_inst_t *tmp) {
    size_t i;
    if (c->k.phase != ST_INIT) return c;
    for (i = 0; i < nvr; i++)
        if (!IS_TIME(vr[i]) && GDM->vars[vr[i]].kind == K_OUTPUT) return first_outputs(c, tmp) ? tmp : c;
    return c;
}

static gd_status_t gdl_get_real(gdfmi_inst_t *c, const char *fn, const gd_vr_t vr[], size_t nvr, double value[],
                                size_t nValues) {
    size_t i, at = 0;
    gdfmi_inst_t tmp, *src;
    if (!check_vrs(c, fn, vr, nvr, value, nValues, T_REAL)) return GD_ERROR;
    src = read_source(c, vr, nvr, &tmp);
    for (i = 0; i < nvr; i++) {
        unsigned n = IS_TIME(vr[i]) ? 1 : GDM->vars[vr[i]].n;
        if (IS_TIME(vr[i])) value[at++] = c->k.time;
        else if (n == 1) value[at++] = GDM->get_real(src, vr[i]);
        else {
            memcpy(value + at, GDM->real_ref(src->m, vr[i]), n * sizeof(double));
            at += n;
        }
    }
    if (src != c) drop_scratch(&tmp);
    return GD_OK;
}

static gd_status_t gdl_set_real(gdfmi_inst_t *c, const char *fn, const gd_vr_t vr[], size_t nvr,
                                const double value[], size_t nValues) {
    size_t i, at = 0;
    if (!check_vrs(c, fn, vr, nvr, value, nValues, T_REAL) || !check_settable(c, fn, vr, nvr)) return GD_ERROR;
    for (i = 0; i < nvr; i++) {
        unsigned n = GDM->vars[vr[i]].n;
        memcpy(GDM->real_ref(c->m, vr[i]), value + at, n * sizeof(double));
        at += n;
    }
    return GD_OK;
}

/* Integer (FMI 3.0: Int32) and Boolean: scalars; the version's entry point converts */
static gd_status_t gdl_check_get(gdfmi_inst_t *c, const char *fn, const gd_vr_t vr[], size_t nvr,
                                 const void *value, size_t nValues, int type) {
    return check_vrs(c, fn, vr, nvr, value, nValues, type) ? GD_OK : GD_ERROR;
}

static gd_status_t gdl_check_set(gdfmi_inst_t *c, const char *fn, const gd_vr_t vr[], size_t nvr,
                                 const void *value, size_t nValues, int type) {
    return check_vrs(c, fn, vr, nvr, value, nValues, type) && check_settable(c, fn, vr, nvr) ? GD_OK : GD_ERROR;
}

static gd_status_t gdl_set_string(gdfmi_inst_t *c, const char *fn, const gd_vr_t vr[], size_t nvr,
                                  const char *const value[], size_t nValues) {
    size_t i, cap;
    if (gdl_check_set(c, fn, vr, nvr, value, nValues, T_STRING) != GD_OK) return GD_ERROR;
    for (i = 0; i < nvr; i++) {
        if (!value[i]) return gdfmi_fail(c, "%s: NULL string for %s", fn, GDM->vars[vr[i]].name);
        GDM->string_ref(c->m, vr[i], &cap);
        if (strlen(value[i]) >= cap)
            return gdfmi_fail(c, "%s: %s is %lu characters long, at most %lu allowed", fn,
                              GDM->vars[vr[i]].name, (unsigned long)strlen(value[i]), (unsigned long)(cap - 1));
    }
    for (i = 0; i < nvr; i++) strcpy(GDM->string_ref(c->m, vr[i], &cap), value[i]);
    return GD_OK;
}

/* --------------------------------------------------------------- FMU state */
/* the tag of this model's FMU states: FNV-1a of its GUID (instantiation token), so that an FMU
 * refuses the in-memory state of another of the project's FMUs (same layer, same magic, other
 * buffers) instead of reading past that model's buffers */
static uint64_t model_tag(void) {
    const unsigned char *p = (const unsigned char *)GDM->guid;
    uint64_t h = 1469598103934665603ULL;
    while (*p) {
        h ^= *p++;
        h *= 1099511628211ULL;
    }
    return h;
}

static gdfmi_state_t *state_of(void *st) {
    gdfmi_state_t *f = (gdfmi_state_t *)st;
    return (f && f->magic == FMUSTATE_MAGIC && f->tag == model_tag()) ? f : NULL;
}
/* unlink f from the list of the instance that allocated it, free it with that
 * instance's memory callbacks */
static void free_state(gdfmi_state_t *f) {
    gdfmi_inst_t *c;
    if (!f) return;
    c = f->owner;
    if (f->prev) f->prev->next = f->next;
    else if (c->states == f) c->states = f->next;
    if (f->next) f->next->prev = f->prev;
    f->magic = 0;
    gdfmi_free(c, f->s);
    gdfmi_free(c, f->m);
    gdfmi_free(c, f);
}

/* a new FMU state holding (k, m, s) */
static gdfmi_state_t *new_state(gdfmi_inst_t *c, const gdfmi_core_t *k, const void *m, const double *s) {
    gdfmi_state_t *f = (gdfmi_state_t *)gdfmi_alloc(c, 1, sizeof *f);
    if (!f) return NULL;
    memset(f, 0, sizeof *f);
    f->k = *k;
    f->m = gdfmi_alloc(c, 1, GDM->m_size);
    if (!f->m) {
        gdfmi_free(c, f);
        return NULL;
    }
    memcpy(f->m, m, GDM->m_size);
    f->s = NULL;
    if (k->ns > 0) {
        f->s = (double *)gdfmi_alloc(c, (size_t)k->ns, sizeof(double));
        if (!f->s) {
            gdfmi_free(c, f->m);
            gdfmi_free(c, f);
            return NULL;
        }
        memcpy(f->s, s, (size_t)k->ns * sizeof(double));
    }
    f->magic = FMUSTATE_MAGIC;
    f->tag = model_tag();
    f->owner = c;
    f->prev = NULL;
    f->next = c->states;
    if (c->states) c->states->prev = f;
    c->states = f;
    return f;
}

static gd_status_t gdl_get_fmu_state(void *comp, void **FMUstate) {
    gdfmi_state_t *f, *old;
    BEGIN(GD_FN_GET_STATE, MASK_FMU_STATE);
    if (!FMUstate) return gdfmi_fail(c, GD_FN_GET_STATE ": FMUstate is NULL");
    old = *FMUstate ? state_of(*FMUstate) : NULL;
    if (*FMUstate && !old)
        return gdfmi_fail(c, GD_FN_GET_STATE ": *FMUstate is neither NULL nor a state of this FMU");
    if (old && old->k.ns == c->k.ns) { /* overwrite in place */
        old->k = c->k;
        memcpy(old->m, c->m, GDM->m_size);
        if (c->k.ns > 0) memcpy(old->s, c->s, (size_t)c->k.ns * sizeof(double));
        return GD_OK;
    }
    f = new_state(c, &c->k, c->m, c->s);
    if (!f) return gdfmi_fail(c, GD_FN_GET_STATE ": out of memory");
    free_state(old);
    *FMUstate = f;
    return GD_OK;
}

static gd_status_t gdl_set_fmu_state(void *comp, void *FMUstate) {
    gdfmi_state_t *f;
    double *s = NULL;
    BEGIN(GD_FN_SET_STATE, MASK_FMU_STATE);
    f = state_of(FMUstate);
    if (!f) return gdfmi_fail(c, GD_FN_SET_STATE ": not a state of this FMU (NULL, freed or foreign)");
    if (f->k.ns > 0) {
        s = (double *)gdfmi_alloc(c, (size_t)f->k.ns, sizeof(double));
        if (!s) return gdfmi_fail(c, GD_FN_SET_STATE ": out of memory");
        memcpy(s, f->s, (size_t)f->k.ns * sizeof(double));
    }
    gdfmi_free(c, c->s);
    c->s = s;
    c->k = f->k;
    memcpy(c->m, f->m, GDM->m_size);
    return GD_OK;
}

static gd_status_t gdl_free_fmu_state(void *comp, void **FMUstate) {
    gdfmi_state_t *f;
    BEGIN(GD_FN_FREE_STATE, MASK_FMU_STATE);
    if (!FMUstate || !*FMUstate) return GD_OK; /* nothing to free */
    f = state_of(*FMUstate);
    if (!f) return gdfmi_fail(c, GD_FN_FREE_STATE ": not a state of this FMU");
    free_state(f);
    *FMUstate = NULL;
    return GD_OK;
}

/* Serialized form (native byte order; checked on deserialization):
 *   magic (8 bytes) | u32 version | u32 byte-order mark 0x01020304 | u64 total size |
 *   u64 layout count | the model's fields (xfer) | s[ns] | u64 FNV-1a of all bytes before */
#define SER_HEADER (8 + 4 + 4 + 8 + 8)

static size_t serial_size(int64_t ns) { return SER_HEADER + GDM->serial_m_bytes + 8 * (size_t)ns + 8; }

static uint64_t fnv1a(const unsigned char *b, size_t n) {
    uint64_t h = 1469598103934665603ULL;
    size_t i;
    for (i = 0; i < n; i++) {
        h ^= b[i];
        h *= 1099511628211ULL;
    }
    return h;
}

static void put(gdfmi_cursor_t *w, const void *src, size_t n) {
    if (w->at + n > w->n) { w->ok = 0; return; }
    memcpy(w->b + w->at, src, n);
    w->at += n;
}

static void get(gdfmi_cursor_t *r, void *dst, size_t n) {
    if (r->at + n > r->n) { r->ok = 0; memset(dst, 0, n); return; }
    memcpy(dst, r->b + r->at, n);
    r->at += n;
}

static void io_put(gdfmi_cursor_t *c, void *p, size_t n) { put(c, p, n); }
static void io_get(gdfmi_cursor_t *c, void *p, size_t n) { get(c, p, n); }

static gd_status_t gdl_serialized_size(void *comp, void *FMUstate, size_t *size) {
    gdfmi_state_t *f;
    BEGIN(GD_FN_STATE_SIZE, MASK_FMU_STATE);
    f = state_of(FMUstate);
    if (!f) return gdfmi_fail(c, GD_FN_STATE_SIZE ": not a state of this FMU");
    if (!size) return gdfmi_fail(c, GD_FN_STATE_SIZE ": size is NULL");
    *size = serial_size(f->k.ns);
    return GD_OK;
}

static gd_status_t gdl_serialize(void *comp, void *FMUstate, unsigned char serializedState[], size_t size) {
    gdfmi_state_t *f;
    gdfmi_cursor_t w;
    gdfmi_core_t k;
    void *m;
    uint32_t version = GDM->serial_version, bom = 0x01020304u;
    uint64_t total, layout = GDM->serial_layout, h;
    BEGIN(GD_FN_SERIALIZE, MASK_FMU_STATE);
    f = state_of(FMUstate);
    if (!f) return gdfmi_fail(c, GD_FN_SERIALIZE ": not a state of this FMU");
    total = serial_size(f->k.ns);
    if (!serializedState || size < total)
        return gdfmi_fail(c, GD_FN_SERIALIZE ": buffer of %lu bytes, %lu needed "
                          "(" GD_FN_STATE_SIZE ")", (unsigned long)size, (unsigned long)total);
    m = gdfmi_alloc(c, 1, GDM->m_size);
    if (!m) return gdfmi_fail(c, GD_FN_SERIALIZE ": out of memory");
    memcpy(m, f->m, GDM->m_size);
    k = f->k;
    w.b = (unsigned char *)serializedState;
    w.at = 0;
    w.n = (size_t)total;
    w.ok = 1;
    put(&w, GDM->serial_magic, 8);
    put(&w, &version, 4);
    put(&w, &bom, 4);
    put(&w, &total, 8);
    put(&w, &layout, 8);
    GDM->xfer(&w, &k, m, io_put);
    gdfmi_free(c, m);
    if (f->k.ns > 0) put(&w, f->s, 8 * (size_t)f->k.ns);
    h = fnv1a(w.b, w.at);
    put(&w, &h, 8);
    if (!w.ok || w.at != total) return gdfmi_fail(c, GD_FN_SERIALIZE ": internal size mismatch");
    return GD_OK;
}

/* the layer's own consistency rules of a deserialized state; 0 if consistent */
static int core_consistent(const gdfmi_core_t *k) {
    int phase = k->phase;
    if (!(phase & ST_ALL_BUT_FATAL) || (phase & (phase - 1))) return 0;
    if (k->have_model != 0 && k->have_model != 1) return 0;
    if ((phase & (ST_INSTANTIATED | ST_INIT)) && k->have_model) return 0;
    if ((phase & (ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED)) && !k->have_model) return 0;
    if (k->ns < 0 || (!k->have_model && k->ns != 0) || (k->have_model && k->ns == 0)) return 0;
    return 1;
}

static gd_status_t gdl_deserialize(void *comp, const unsigned char serializedState[], size_t size,
                                   void **FMUstate) {
    gdfmi_cursor_t r;
    char magic[8], err[512];
    uint32_t version, bom;
    uint64_t total, layout, h, h_read;
    gdfmi_core_t k;
    void *m;
    double *s = NULL;
    gdfmi_state_t *f;
    gd_status_t st = GD_OK;
    BEGIN(GD_FN_DESERIALIZE, MASK_FMU_STATE);
    if (!FMUstate) return gdfmi_fail(c, GD_FN_DESERIALIZE ": FMUstate is NULL");
    if (!serializedState || size < SER_HEADER + 8)
        return gdfmi_fail(c, GD_FN_DESERIALIZE ": %lu bytes is too short for a serialized state",
                          (unsigned long)size);
    r.b = (unsigned char *)serializedState;
    r.at = 0;
    r.n = size;
    r.ok = 1;
    get(&r, magic, 8);
    get(&r, &version, 4);
    get(&r, &bom, 4);
    get(&r, &total, 8);
    get(&r, &layout, 8);
    if (memcmp(magic, GDM->serial_magic, 8) != 0)
        return gdfmi_fail(c, GD_FN_DESERIALIZE ": not a serialized %s state", GDM->identifier);
    if (bom != 0x01020304u)
        return gdfmi_fail(c, GD_FN_DESERIALIZE ": serialized on a platform of another byte order");
    if (version != GDM->serial_version || layout != GDM->serial_layout)
        return gdfmi_fail(c, GD_FN_DESERIALIZE ": serialized state version %u (%lu parameters), this "
                          "binary reads version %u (%lu parameters)", (unsigned)version,
                          (unsigned long)layout, (unsigned)GDM->serial_version,
                          (unsigned long)GDM->serial_layout);
    if (total != size)
        return gdfmi_fail(c, GD_FN_DESERIALIZE ": %lu bytes given, the state says %lu (truncated?)",
                          (unsigned long)size, (unsigned long)total);
    memcpy(&h_read, r.b + size - 8, 8);
    h = fnv1a(r.b, size - 8);
    if (h != h_read) return gdfmi_fail(c, GD_FN_DESERIALIZE ": checksum mismatch (corrupted state)");
    m = gdfmi_alloc(c, 1, GDM->m_size);
    if (!m) return gdfmi_fail(c, GD_FN_DESERIALIZE ": out of memory");
    memset(m, 0, GDM->m_size);
    memset(&k, 0, sizeof k);
    GDM->xfer(&r, &k, m, io_get);
    if (!r.ok || k.ns < 0 || serial_size(k.ns) != size) {
        st = gdfmi_fail(c, GD_FN_DESERIALIZE ": inconsistent sizes (corrupted state)");
    } else if (!core_consistent(&k)) {
        st = gdfmi_fail(c, GD_FN_DESERIALIZE ": invalid state fields (corrupted state)");
    } else {
        if (k.ns > 0) {
            s = (double *)gdfmi_alloc(c, (size_t)k.ns, sizeof(double));
            if (!s) st = gdfmi_fail(c, GD_FN_DESERIALIZE ": out of memory");
            else get(&r, s, 8 * (size_t)k.ns);
        }
        if (st == GD_OK && GDM->check_state(c, &k, m, s, err, sizeof err) != 0)
            st = gdfmi_fail(c, GD_FN_DESERIALIZE ": %s", err);
    }
    if (st == GD_OK) {
        f = new_state(c, &k, m, s);
        if (!f) st = gdfmi_fail(c, GD_FN_DESERIALIZE ": out of memory");
        else *FMUstate = f;
    }
    gdfmi_free(c, s);
    gdfmi_free(c, m);
    return st;
}

/* --------------------------------------------------------------- stepping */
/* one communication step [t, t + h]: one sample (the state allowed DoStep) */
static gd_status_t gdl_do_step(gdfmi_inst_t *c, double t, double h) {
    gd_status_t status = GD_OK, st;
    double T;
    if (!c->k.have_model || !c->s) return gdfmi_fail(c, GD_FN("DoStep") ": no model (internal error)");
    T = GDM->period(c->m);
    if (!isfinite(t))
        return gdfmi_fail(c, GD_FN("DoStep") ": currentCommunicationPoint %g is not finite", t);
    if (!(h > 0.0) || !isfinite(h))
        return gdfmi_fail(c, GD_FN("DoStep") ": communication step size %.17g at t=%.17g s is not a finite "
                          "number > 0", h, t);
    if (h < SLIVER_RTOL * T) { /* no sample: the outputs stay those at t */
        c->n_slivers++;
        gdfmi_log(c, GD_OK, GD_FN("DoStep") ": step size %.17g s at t=%.17g s is below %g of %s %.17g s: "
                  "no sample (a master's accumulated time), outputs unchanged", h, t, SLIVER_RTOL,
                  GDM->period_name, T);
        c->k.time = t + h;
        return GD_OK;
    }
    if (fabs(h - T) > STEP_RTOL * T) {
        c->k.n_bad_steps++;
        if (GDM->strict_step_size(c->m)) {
            gdfmi_log(c, GD_DISCARD, GD_FN("DoStep") ": step size %.17g s at t=%.17g s differs from "
                      "%s %.17g s; step refused (strict_step_size)", h, t, GDM->period_name, T);
            c->k.phase = ST_STEP_FAILED;
            return GD_DISCARD;
        }
        if (c->k.n_bad_steps == 1 || c->k.n_bad_steps % 100000 == 0)
            gdfmi_log(c, GD_WARNING, GD_FN("DoStep") ": step size %.17g s at t=%.17g s differs from "
                      "%s %.17g s; one step = one sample, so %s is "
                      "wrong (%lld such step(s) so far)", h, t, GDM->period_name, T, GDM->time_base,
                      (long long)c->k.n_bad_steps);
        status = GD_WARNING;
    }
    st = GDM->step(c, t);
    if (st != GD_OK && st != GD_WARNING) return st;
    c->k.n_steps++;
    c->k.time = t + h;
    return st == GD_WARNING ? GD_WARNING : status;
}


/* the exported entry points of the standard compiled */
#if GD_FMI_VERSION == 3
#include "gdfmi3.c"
#else
#include "gdfmi2.c"
#endif

#undef GDM
