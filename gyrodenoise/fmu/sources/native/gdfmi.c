/*
 * gdfmi.c -- the FMI 2.0 co-simulation layer shared by the native FMUs (see gdfmi.h).
 * Included after the model file, which defines `static const gdfmi_model_t gdfmi_model`.
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

/* an FMU state: linked into its instance's list, so that fmi2FreeInstance frees the
 * states the host did not free (FMI 2.0: fmi2FreeInstance frees all it allocated) */
struct gdfmi_state_s {
    uint32_t magic;
    gdfmi_core_t k;
    void *m;
    double *s;
    gdfmi_inst_t *owner; /* the instance that allocated it */
    gdfmi_state_t *prev, *next;
};

/* ------------------------------------------------------------------ memory */
static void *gdfmi_alloc(const gdfmi_inst_t *c, size_t n, size_t size) {
    if (n == 0) n = 1;
    if (c && c->cb.allocateMemory) return c->cb.allocateMemory(n, size);
    return calloc(n, size);
}

static void gdfmi_free(const gdfmi_inst_t *c, void *ptr) {
    if (!ptr) return;
    if (c && c->cb.freeMemory) c->cb.freeMemory(ptr);
    else free(ptr);
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
static int cat_of(fmi2Status st) {
    switch (st) {
    case fmi2Warning: return CAT_WARNING;
    case fmi2Discard: return CAT_DISCARD;
    case fmi2Error: return CAT_ERROR;
    case fmi2Fatal: return CAT_FATAL;
    default: return CAT_ALL;
    }
}

static void vlogmsg(const gdfmi_inst_t *c, fmi2Status st, const char *fmt, va_list ap) {
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

static void gdfmi_log(const gdfmi_inst_t *c, fmi2Status st, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlogmsg(c, st, fmt, ap);
    va_end(ap);
}

/* log the reason and enter the error state */
static fmi2Status gdfmi_fail(gdfmi_inst_t *c, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlogmsg(c, fmi2Error, fmt, ap);
    va_end(ap);
    c->k.phase = ST_ERROR;
    return fmi2Error;
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
    case ST_STEP_COMPLETE: return "stepComplete";
    case ST_STEP_FAILED: return "stepFailed";
    case ST_TERMINATED: return "terminated";
    case ST_ERROR: return "error";
    case ST_FATAL: return "fatal";
    default: return "unknown";
    }
}

/* the instance behind c, or NULL (a NULL or foreign pointer cannot be logged to) */
static gdfmi_inst_t *inst_of(fmi2Component c) {
    gdfmi_inst_t *i = (gdfmi_inst_t *)c;
    if (!i || i->magic != INSTANCE_MAGIC) return NULL;
    return i;
}

/* 1 if a call of fn is allowed in the current state; else logs, enters the error state */
static int allowed(gdfmi_inst_t *c, int mask, const char *fn) {
    if (c->k.phase & mask) return 1;
    if (c->k.phase == ST_FATAL) {
        gdfmi_log(c, fmi2Error, "%s: not allowed: the instance is in the fatal state", fn);
        return 0;
    }
    gdfmi_fail(c, "%s: not allowed in state %s (FMI 2.0 co-simulation state machine)", fn,
               phase_name(c->k.phase));
    return 0;
}

#define BEGIN(fn, mask)                        \
    gdfmi_inst_t *c = inst_of(comp);           \
    if (!c) return fmi2Error;                  \
    if (!allowed(c, (mask), fn)) return fmi2Error

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
        return gdfmi_fmt_err(err, nerr, "no resource location given to fmi2Instantiate (needed for "
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
        if (ch == '%' && i + 2 < len + 0 && hexval(p[i + 1]) >= 0 && hexval(p[i + 2]) >= 0) {
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
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    size_t i;
    int k, on[N_CATS] = {0}, unknown = 0;
    const char *first_unknown = NULL;
    BEGIN("fmi2SetDebugLogging", MASK_SET_DEBUG_LOGGING);
    if (nCategories > 0 && !categories)
        return gdfmi_fail(c, "fmi2SetDebugLogging: categories is NULL with nCategories = %lu",
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
        gdfmi_log(c, fmi2Warning, "fmi2SetDebugLogging: %d unknown log categor%s ignored, the first "
                  "'%.100s' (known: logStatusWarning, logStatusDiscard, logStatusError, logStatusFatal, "
                  "logAll)", unknown, unknown == 1 ? "y" : "ies", first_unknown);
        return fmi2Warning;
    }
    return fmi2OK;
}

static void set_defaults(gdfmi_inst_t *c) {
    memset(&c->k, 0, sizeof c->k);
    memset(c->m, 0, GDM->m_size);
    GDM->defaults(c->m);
    c->k.phase = ST_INSTANTIATED;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    gdfmi_inst_t tmp, *c;
    int k;
    (void)visible;
    memset(&tmp, 0, sizeof tmp);
    if (functions) tmp.cb = *functions;
    tmp.name = (char *)(instanceName ? instanceName : "");
    tmp.logging_on = 1;
    for (k = 0; k < N_CATS; k++) tmp.cat_on[k] = 1;
    if (!functions) return NULL; /* nowhere to report to */
    if ((functions->allocateMemory == NULL) != (functions->freeMemory == NULL)) {
        gdfmi_log(&tmp, fmi2Error, "fmi2Instantiate: allocateMemory and freeMemory must both be given");
        return NULL;
    }
#ifdef GD_LIBM_MISSING /* a source build without -lm (see gdfmi_libm.h) */
    if (GD_LIBM_MISSING()) {
        gdfmi_log(&tmp, fmi2Error, "fmi2Instantiate: %s: the math library is not loaded in this process "
                  "(%s() missing): this binary was built without -lm; rebuild it with -lm -DGD_LIBM_LINKED "
                  "(fmpy: build_platform_binary(..., cmake_options={'CMAKE_C_STANDARD_LIBRARIES:STRING': "
                  "'-lm', 'CMAKE_C_FLAGS:STRING': '-DGD_LIBM_LINKED'})) or use the binary shipped in the "
                  "FMU", GDM->identifier, GD_LIBM_MISSING());
        return NULL;
    }
#endif
    if (!instanceName || !instanceName[0]) {
        gdfmi_log(&tmp, fmi2Error, "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        gdfmi_log(&tmp, fmi2Error, "fmi2Instantiate: %s supports co-simulation only (fmuType %d)",
                  GDM->identifier, (int)fmuType);
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, GDM->guid) != 0) {
        gdfmi_log(&tmp, fmi2Error, "fmi2Instantiate: GUID %s does not match this binary's %s",
                  fmuGUID ? fmuGUID : "(NULL)", GDM->guid);
        return NULL;
    }
    c = (gdfmi_inst_t *)gdfmi_alloc(&tmp, 1, sizeof *c);
    if (!c) {
        gdfmi_log(&tmp, fmi2Error, "fmi2Instantiate: out of memory");
        return NULL;
    }
    memset(c, 0, sizeof *c);
    c->cb = tmp.cb;
    c->name = str_dup(c, instanceName);
    c->resource_uri = str_dup(c, fmuResourceLocation);
    c->m = gdfmi_alloc(c, 1, GDM->m_size);
    if (!c->name || !c->m || (fmuResourceLocation && !c->resource_uri)) {
        gdfmi_free(c, c->name);
        gdfmi_free(c, c->resource_uri);
        gdfmi_free(c, c->m);
        gdfmi_free(c, c);
        gdfmi_log(&tmp, fmi2Error, "fmi2Instantiate: out of memory");
        return NULL;
    }
    c->magic = INSTANCE_MAGIC;
    c->logging_on = loggingOn ? 1 : 0;
    for (k = 0; k < N_CATS; k++) c->cat_on[k] = 1;
    set_defaults(c);
    c->s = NULL;
    gdfmi_log(c, fmi2OK, "fmi2Instantiate: %s instantiated (resources %s)", GDM->identifier,
              fmuResourceLocation ? fmuResourceLocation : "(NULL)");
    return c;
}

static void drop_model(gdfmi_inst_t *c) {
    gdfmi_free(c, c->s);
    c->s = NULL;
    c->k.have_model = 0;
    c->k.ns = 0;
}

static void free_state(gdfmi_state_t *f);

void fmi2FreeInstance(fmi2Component comp) {
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

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN("fmi2SetupExperiment", MASK_SETUP_EXPERIMENT);
    (void)toleranceDefined;
    (void)tolerance;
    if (!isfinite(startTime))
        return gdfmi_fail(c, "fmi2SetupExperiment: startTime %g is not finite", startTime);
    if (stopTimeDefined && !(stopTime >= startTime))
        return gdfmi_fail(c, "fmi2SetupExperiment: stopTime %.17g is before startTime %.17g", stopTime,
                          startTime);
    c->k.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    BEGIN("fmi2EnterInitializationMode", MASK_ENTER_INIT);
    c->k.phase = ST_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    char err[1024], info[512];
    long total;
    BEGIN("fmi2ExitInitializationMode", MASK_EXIT_INIT);
    err[0] = '\0';
    total = GDM->build(c, err, sizeof err);
    if (total <= 0) return gdfmi_fail(c, "fmi2ExitInitializationMode: invalid parameter: %s", err);
    drop_model(c);
    c->s = (double *)gdfmi_alloc(c, (size_t)total, sizeof(double));
    if (!c->s) return gdfmi_fail(c, "fmi2ExitInitializationMode: out of memory");
    memset(c->s, 0, (size_t)total * sizeof(double));
    c->k.ns = total;
    GDM->start(c);
    c->k.have_model = 1;
    c->k.n_steps = c->k.n_bad_steps = 0;
    c->k.phase = ST_STEP_COMPLETE;
    if (c->logging_on) {
        GDM->describe(c, info, sizeof info);
        gdfmi_log(c, fmi2OK, "fmi2ExitInitializationMode: %s", info);
    }
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    BEGIN("fmi2Terminate", MASK_TERMINATE);
    if (c->k.n_bad_steps)
        gdfmi_log(c, fmi2OK, "fmi2Terminate: %lld of %lld step(s) had a size different from "
                  "%s %.17g s", (long long)c->k.n_bad_steps, (long long)c->k.n_steps, GDM->period_name,
                  GDM->period(c->m));
    c->k.phase = ST_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    BEGIN("fmi2Reset", MASK_RESET);
    drop_model(c);
    set_defaults(c);
    return fmi2OK;
}

/* -------------------------------------------------------- getters/setters */
static int check_vrs(gdfmi_inst_t *c, const char *fn, const fmi2ValueReference vr[], size_t nvr,
                     const void *value, int type) {
    static const char *const tnames[] = {"Real", "Integer", "Boolean", "String"};
    size_t i;
    if (nvr == 0) return 1;
    if (!vr || !value) {
        gdfmi_fail(c, "%s: NULL value-reference or value array with nvr = %lu", fn, (unsigned long)nvr);
        return 0;
    }
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= GDM->n_vars) {
            gdfmi_fail(c, "%s: unknown value reference %u", fn, (unsigned)vr[i]);
            return 0;
        }
        if (GDM->vars[vr[i]].type != type) {
            gdfmi_fail(c, "%s: value reference %u (%s) is not a %s variable", fn, (unsigned)vr[i],
                       GDM->vars[vr[i]].name, tnames[type]);
            return 0;
        }
    }
    return 1;
}

/* a set of vr is allowed in the current state: inputs in instantiated, initialization
 * mode and stepComplete; fixed parameters before fmi2ExitInitializationMode; outputs never */
static int check_settable(gdfmi_inst_t *c, const char *fn, const fmi2ValueReference vr[], size_t nvr) {
    size_t i;
    for (i = 0; i < nvr; i++) {
        int kind = GDM->vars[vr[i]].kind;
        if (kind == K_OUTPUT) {
            gdfmi_fail(c, "%s: %s is an output and cannot be set", fn, GDM->vars[vr[i]].name);
            return 0;
        }
        if (kind == K_PARAMETER && !(c->k.phase & (ST_INSTANTIATED | ST_INIT))) {
            gdfmi_fail(c, "%s: %s is a fixed parameter: it can only be set before "
                       "fmi2ExitInitializationMode (state is %s)", fn, GDM->vars[vr[i]].name,
                       phase_name(c->k.phase));
            return 0;
        }
    }
    return 1;
}

/* fmi2Get<Type>: the state allows it, every vr names a variable of the type, then the
 * model's getter for each (a String stays valid until the next call) */
#define GDFMI_GETTER(fn, ctype, type, hook)                                                      \
    fmi2Status fn(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, ctype value[]) { \
        size_t i;                                                                                \
        BEGIN(#fn, MASK_GET);                                                                    \
        if (!check_vrs(c, #fn, vr, nvr, value, type)) return fmi2Error;                          \
        for (i = 0; i < nvr; i++) value[i] = GDM->hook(c, vr[i]);                                \
        return fmi2OK;                                                                           \
    }
GDFMI_GETTER(fmi2GetReal, fmi2Real, T_REAL, get_real)
GDFMI_GETTER(fmi2GetInteger, fmi2Integer, T_INTEGER, get_integer)
GDFMI_GETTER(fmi2GetBoolean, fmi2Boolean, T_BOOLEAN, get_boolean)
GDFMI_GETTER(fmi2GetString, fmi2String, T_STRING, get_string)
#undef GDFMI_GETTER

/* fmi2Set<Type> of Real, Integer, Boolean: the state allows it, every vr names a settable
 * variable of the type (inputs; fixed parameters before initialisation ends), then `store` */
#define GDFMI_SETTER(fn, ctype, type, store)                                                           \
    fmi2Status fn(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const ctype value[]) { \
        size_t i;                                                                                      \
        BEGIN(#fn, MASK_SET);                                                                          \
        if (!check_vrs(c, #fn, vr, nvr, value, type) || !check_settable(c, #fn, vr, nvr))             \
            return fmi2Error;                                                                          \
        for (i = 0; i < nvr; i++) store;                                                               \
        return fmi2OK;                                                                                 \
    }
GDFMI_SETTER(fmi2SetReal, fmi2Real, T_REAL, *GDM->real_ref(c->m, vr[i]) = value[i])
GDFMI_SETTER(fmi2SetInteger, fmi2Integer, T_INTEGER, *GDM->int_ref(c->m, vr[i]) = value[i])
GDFMI_SETTER(fmi2SetBoolean, fmi2Boolean, T_BOOLEAN, *GDM->int_ref(c->m, vr[i]) = value[i] ? 1 : 0)
#undef GDFMI_SETTER

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    size_t i, cap;
    BEGIN("fmi2SetString", MASK_SET);
    if (!check_vrs(c, "fmi2SetString", vr, nvr, value, T_STRING) ||
        !check_settable(c, "fmi2SetString", vr, nvr))
        return fmi2Error;
    for (i = 0; i < nvr; i++) {
        if (!value[i]) return gdfmi_fail(c, "fmi2SetString: NULL string for %s", GDM->vars[vr[i]].name);
        GDM->string_ref(c->m, vr[i], &cap);
        if (strlen(value[i]) >= cap)
            return gdfmi_fail(c, "fmi2SetString: %s is %lu characters long, at most %lu allowed",
                              GDM->vars[vr[i]].name, (unsigned long)strlen(value[i]), (unsigned long)(cap - 1));
    }
    for (i = 0; i < nvr; i++) strcpy(GDM->string_ref(c->m, vr[i], &cap), value[i]);
    return fmi2OK;
}

/* --------------------------------------------------------------- FMU state */
static gdfmi_state_t *state_of(fmi2FMUstate st) {
    gdfmi_state_t *f = (gdfmi_state_t *)st;
    return (f && f->magic == FMUSTATE_MAGIC) ? f : NULL;
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
    f->owner = c;
    f->prev = NULL;
    f->next = c->states;
    if (c->states) c->states->prev = f;
    c->states = f;
    return f;
}

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    gdfmi_state_t *f, *old;
    BEGIN("fmi2GetFMUstate", MASK_FMU_STATE);
    if (!FMUstate) return gdfmi_fail(c, "fmi2GetFMUstate: FMUstate is NULL");
    old = *FMUstate ? state_of(*FMUstate) : NULL;
    if (*FMUstate && !old)
        return gdfmi_fail(c, "fmi2GetFMUstate: *FMUstate is neither NULL nor a state of this FMU");
    if (old && old->k.ns == c->k.ns) { /* overwrite in place */
        old->k = c->k;
        memcpy(old->m, c->m, GDM->m_size);
        if (c->k.ns > 0) memcpy(old->s, c->s, (size_t)c->k.ns * sizeof(double));
        return fmi2OK;
    }
    f = new_state(c, &c->k, c->m, c->s);
    if (!f) return gdfmi_fail(c, "fmi2GetFMUstate: out of memory");
    free_state(old);
    *FMUstate = f;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate) {
    gdfmi_state_t *f;
    double *s = NULL;
    BEGIN("fmi2SetFMUstate", MASK_FMU_STATE);
    f = state_of(FMUstate);
    if (!f) return gdfmi_fail(c, "fmi2SetFMUstate: not a state of this FMU (NULL, freed or foreign)");
    if (f->k.ns > 0) {
        s = (double *)gdfmi_alloc(c, (size_t)f->k.ns, sizeof(double));
        if (!s) return gdfmi_fail(c, "fmi2SetFMUstate: out of memory");
        memcpy(s, f->s, (size_t)f->k.ns * sizeof(double));
    }
    gdfmi_free(c, c->s);
    c->s = s;
    c->k = f->k;
    memcpy(c->m, f->m, GDM->m_size);
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    gdfmi_state_t *f;
    BEGIN("fmi2FreeFMUstate", MASK_FMU_STATE);
    if (!FMUstate || !*FMUstate) return fmi2OK; /* nothing to free */
    f = state_of(*FMUstate);
    if (!f) return gdfmi_fail(c, "fmi2FreeFMUstate: not a state of this FMU");
    free_state(f);
    *FMUstate = NULL;
    return fmi2OK;
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

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate, size_t *size) {
    gdfmi_state_t *f;
    BEGIN("fmi2SerializedFMUstateSize", MASK_FMU_STATE);
    f = state_of(FMUstate);
    if (!f) return gdfmi_fail(c, "fmi2SerializedFMUstateSize: not a state of this FMU");
    if (!size) return gdfmi_fail(c, "fmi2SerializedFMUstateSize: size is NULL");
    *size = serial_size(f->k.ns);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    gdfmi_state_t *f;
    gdfmi_cursor_t w;
    gdfmi_core_t k;
    void *m;
    uint32_t version = GDM->serial_version, bom = 0x01020304u;
    uint64_t total, layout = GDM->serial_layout, h;
    BEGIN("fmi2SerializeFMUstate", MASK_FMU_STATE);
    f = state_of(FMUstate);
    if (!f) return gdfmi_fail(c, "fmi2SerializeFMUstate: not a state of this FMU");
    total = serial_size(f->k.ns);
    if (!serializedState || size < total)
        return gdfmi_fail(c, "fmi2SerializeFMUstate: buffer of %lu bytes, %lu needed "
                          "(fmi2SerializedFMUstateSize)", (unsigned long)size, (unsigned long)total);
    m = gdfmi_alloc(c, 1, GDM->m_size);
    if (!m) return gdfmi_fail(c, "fmi2SerializeFMUstate: out of memory");
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
    if (!w.ok || w.at != total) return gdfmi_fail(c, "fmi2SerializeFMUstate: internal size mismatch");
    return fmi2OK;
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

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    gdfmi_cursor_t r;
    char magic[8], err[512];
    uint32_t version, bom;
    uint64_t total, layout, h, h_read;
    gdfmi_core_t k;
    void *m;
    double *s = NULL;
    gdfmi_state_t *f;
    fmi2Status st = fmi2OK;
    BEGIN("fmi2DeSerializeFMUstate", MASK_FMU_STATE);
    if (!FMUstate) return gdfmi_fail(c, "fmi2DeSerializeFMUstate: FMUstate is NULL");
    if (!serializedState || size < SER_HEADER + 8)
        return gdfmi_fail(c, "fmi2DeSerializeFMUstate: %lu bytes is too short for a serialized state",
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
        return gdfmi_fail(c, "fmi2DeSerializeFMUstate: not a serialized %s state", GDM->identifier);
    if (bom != 0x01020304u)
        return gdfmi_fail(c, "fmi2DeSerializeFMUstate: serialized on a platform of another byte order");
    if (version != GDM->serial_version || layout != GDM->serial_layout)
        return gdfmi_fail(c, "fmi2DeSerializeFMUstate: serialized state version %u (%lu parameters), this "
                          "binary reads version %u (%lu parameters)", (unsigned)version,
                          (unsigned long)layout, (unsigned)GDM->serial_version,
                          (unsigned long)GDM->serial_layout);
    if (total != size)
        return gdfmi_fail(c, "fmi2DeSerializeFMUstate: %lu bytes given, the state says %lu (truncated?)",
                          (unsigned long)size, (unsigned long)total);
    memcpy(&h_read, r.b + size - 8, 8);
    h = fnv1a(r.b, size - 8);
    if (h != h_read) return gdfmi_fail(c, "fmi2DeSerializeFMUstate: checksum mismatch (corrupted state)");
    m = gdfmi_alloc(c, 1, GDM->m_size);
    if (!m) return gdfmi_fail(c, "fmi2DeSerializeFMUstate: out of memory");
    memset(m, 0, GDM->m_size);
    memset(&k, 0, sizeof k);
    GDM->xfer(&r, &k, m, io_get);
    if (!r.ok || k.ns < 0 || serial_size(k.ns) != size) {
        st = gdfmi_fail(c, "fmi2DeSerializeFMUstate: inconsistent sizes (corrupted state)");
    } else if (!core_consistent(&k)) {
        st = gdfmi_fail(c, "fmi2DeSerializeFMUstate: invalid state fields (corrupted state)");
    } else {
        if (k.ns > 0) {
            s = (double *)gdfmi_alloc(c, (size_t)k.ns, sizeof(double));
            if (!s) st = gdfmi_fail(c, "fmi2DeSerializeFMUstate: out of memory");
            else get(&r, s, 8 * (size_t)k.ns);
        }
        if (st == fmi2OK && GDM->check_state(c, &k, m, s, err, sizeof err) != 0)
            st = gdfmi_fail(c, "fmi2DeSerializeFMUstate: %s", err);
    }
    if (st == fmi2OK) {
        f = new_state(c, &k, m, s);
        if (!f) st = gdfmi_fail(c, "fmi2DeSerializeFMUstate: out of memory");
        else *FMUstate = f;
    }
    gdfmi_free(c, s);
    gdfmi_free(c, m);
    return st;
}

/* ------------------------------------------------- not provided by these FMUs */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    gdfmi_inst_t *c = inst_of(comp);
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    if (!c) return fmi2Error;
    return gdfmi_fail(c, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=false)");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    gdfmi_inst_t *c = inst_of(comp);
    (void)vr; (void)nvr; (void)order; (void)value;
    if (!c) return fmi2Error;
    return gdfmi_fail(c, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    gdfmi_inst_t *c = inst_of(comp);
    (void)vr; (void)nvr; (void)order; (void)value;
    if (!c) return fmi2Error;
    return gdfmi_fail(c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder=0)");
}

/* --------------------------------------------------------------- stepping */
fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    fmi2Status status = fmi2OK, st;
    double h = communicationStepSize, t = currentCommunicationPoint, T;
    BEGIN("fmi2DoStep", MASK_DO_STEP);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!c->k.have_model || !c->s) return gdfmi_fail(c, "fmi2DoStep: no model (internal error)");
    T = GDM->period(c->m);
    if (!isfinite(t))
        return gdfmi_fail(c, "fmi2DoStep: currentCommunicationPoint %g is not finite", t);
    if (!(h > 0.0) || !isfinite(h))
        return gdfmi_fail(c, "fmi2DoStep: communication step size %.17g at t=%.17g s is not a finite "
                          "number > 0", h, t);
    if (fabs(h - T) > STEP_RTOL * T) {
        c->k.n_bad_steps++;
        if (GDM->strict_step_size(c->m)) {
            gdfmi_log(c, fmi2Discard, "fmi2DoStep: step size %.17g s at t=%.17g s differs from "
                      "%s %.17g s; step refused (strict_step_size)", h, t, GDM->period_name, T);
            c->k.phase = ST_STEP_FAILED;
            return fmi2Discard;
        }
        if (c->k.n_bad_steps == 1 || c->k.n_bad_steps % 100000 == 0)
            gdfmi_log(c, fmi2Warning, "fmi2DoStep: step size %.17g s at t=%.17g s differs from "
                      "%s %.17g s; one step = one sample, so %s is "
                      "wrong (%lld such step(s) so far)", h, t, GDM->period_name, T, GDM->time_base,
                      (long long)c->k.n_bad_steps);
        status = fmi2Warning;
    }
    st = GDM->step(c, t);
    if (st != fmi2OK && st != fmi2Warning) return st;
    c->k.n_steps++;
    c->k.time = t + h;
    return st == fmi2Warning ? fmi2Warning : status;
}

fmi2Status fmi2CancelStep(fmi2Component comp) {
    gdfmi_inst_t *c = inst_of(comp);
    if (!c) return fmi2Error;
    return gdfmi_fail(c, "fmi2CancelStep: no asynchronous step to cancel (fmi2DoStep never returns fmi2Pending)");
}

/* a status kind this FMU does not provide: fmi2Discard, the reason logged */
static fmi2Status no_status(const gdfmi_inst_t *c, const char *fn, int kind, const char *why) {
    gdfmi_log(c, fmi2Discard, "%s: status kind %d not available%s", fn, kind, why);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value) {
    BEGIN("fmi2GetStatus", MASK_STATUS);
    (void)value;
    return no_status(c, "fmi2GetStatus", (int)s, " (no asynchronous steps)");
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    BEGIN("fmi2GetRealStatus", MASK_STATUS);
    if (s != fmi2LastSuccessfulTime || !value) return no_status(c, "fmi2GetRealStatus", (int)s, "");
    *value = c->k.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value) {
    BEGIN("fmi2GetIntegerStatus", MASK_STATUS);
    (void)value;
    return no_status(c, "fmi2GetIntegerStatus", (int)s, "");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value) {
    BEGIN("fmi2GetBooleanStatus", MASK_STATUS);
    if (s != fmi2Terminated || !value) return no_status(c, "fmi2GetBooleanStatus", (int)s, "");
    *value = fmi2False; /* the slave never asks to end the simulation */
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value) {
    BEGIN("fmi2GetStringStatus", MASK_STATUS);
    (void)value;
    return no_status(c, "fmi2GetStringStatus", (int)s, "");
}

#undef GDM
