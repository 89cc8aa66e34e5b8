/*
 * host.c -- a plain C FMI 2.0 co-simulation host for the project's FMUs (tests).
 *
 * Loads binaries/<platform>/<modelIdentifier>.<ext> of an unzipped FMU (dlopen on
 * linux64, aarch64-linux and the darwin ones, LoadLibrary on win64: the same file
 * cross-compiled for Windows runs under wine, for aarch64 Linux under qemu), reads the
 * GUID, model identifier and variables from its modelDescription.xml (a crude
 * attribute scan: enough for the FMUs we generate), and drives it through the
 * FMI 2.0 C API with the standard headers (fmpy's c-code directory).
 *
 *   host DIR run       [options] < samples   one line per sample: "z [restart]";
 *                                            prints the --out variables (%.17g)
 *   host DIR bench     [options]             --n synthetic samples, prints steps/s
 *   host DIR forbidden [options]             calls FMI 2.0 forbids; exit status =
 *                                            number of checks failed
 * options:
 *   --uri U            resource URI passed to fmi2Instantiate ("NULL" for NULL;
 *                      default file://DIR/resources)
 *   --set NAME=VALUE   a parameter, typed by the model description (repeatable);
 *                      forbidden: also set again after initialisation (must fail)
 *   --bad NAME=VALUE   forbidden: an invalid value, refused at fmi2ExitInitializationMode
 *   --in NAME          Real input fed from column 1      (default raw_rate)
 *   --restart NAME     Boolean input fed from column 2   (default restart; "" = none)
 *   --out NAME         Real output printed per sample (repeatable; default filtered_rate)
 *   --step H           communication step size (default 0.005)
 *   --init-sample      run/bench: the first sample's inputs are set in initialisation mode and
 *                      its outputs read after fmi2ExitInitializationMode (the sensor FMUs take
 *                      sample 0 there); each further sample is one step from its inputs
 *   --n N              samples of bench (default 1000000)
 *   --log              loggingOn = fmi2True
 *
 * Build: gcc -std=c99 -O2 -I<fmpy>/c-code host.c -o host -ldl
 *        x86_64-w64-mingw32-gcc -std=c99 -O2 -I<fmpy>/c-code host.c -o host.exe
 * The host itself needs no libm (so that it can check an FMU binary that must bring its own).
 */
#ifdef _WIN32
#define __USE_MINGW_ANSI_STDIO 1 /* C99 printf/scanf: %.17g round trips */
#include <windows.h>
#define PLATFORM_DIR "win64"
#define BINARY_EXT ".dll"
#else
#define _POSIX_C_SOURCE 200809L
#define _XOPEN_SOURCE 700      /* realpath */
#include <dlfcn.h>
#ifdef __APPLE__
#ifdef __aarch64__
#define PLATFORM_DIR "aarch64-darwin" /* FMI 2.0.4: the FMI 3.0 platform tuple for non-x86 */
#else
#define PLATFORM_DIR "darwin64"
#endif
#define BINARY_EXT ".dylib"
#else
#ifdef __aarch64__
#define PLATFORM_DIR "aarch64-linux" /* cross-built and run under qemu-aarch64: test_aarch64.py */
#else
#define PLATFORM_DIR "linux64"
#endif
#define BINARY_EXT ".so"
#endif
#endif
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"
#include "monotonic.h"

#define MAX_VARS 512
#define MAX_SET 64
#define MAX_OUT 32

typedef struct { char name[128]; unsigned vr; char type[16]; } var_t;

static var_t vars[MAX_VARS];
static int n_vars;
static char guid[128], model_id[128];
static int n_logged_errors; /* messages logged with status >= fmi2Error */
static int quiet_log;

/* FMI 2.0 functions */
static fmi2InstantiateTYPE *Instantiate;
static fmi2FreeInstanceTYPE *FreeInstance;
static fmi2SetupExperimentTYPE *SetupExperiment;
static fmi2EnterInitializationModeTYPE *EnterInit;
static fmi2ExitInitializationModeTYPE *ExitInit;
static fmi2TerminateTYPE *Terminate;
static fmi2ResetTYPE *Reset;
static fmi2GetRealTYPE *GetReal;
static fmi2SetRealTYPE *SetReal;
static fmi2SetIntegerTYPE *SetInteger;
static fmi2SetBooleanTYPE *SetBoolean;
static fmi2GetBooleanTYPE *GetBoolean;
static fmi2SetStringTYPE *SetString;
static fmi2DoStepTYPE *DoStep;
static fmi2GetFMUstateTYPE *GetFMUstate;
static fmi2SetFMUstateTYPE *SetFMUstate;
static fmi2FreeFMUstateTYPE *FreeFMUstate;
static fmi2SerializedFMUstateSizeTYPE *SerializedSize;
static fmi2SerializeFMUstateTYPE *Serialize;
static fmi2DeSerializeFMUstateTYPE *DeSerialize;

static void die(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fputs("host: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    exit(100);
}

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    va_list ap;
    (void)env;
    if (status >= fmi2Error) n_logged_errors++;
    if (quiet_log) return;
    fprintf(stderr, "[%d][%s] %s: ", (int)status, category ? category : "", name ? name : "");
    va_start(ap, message);
    vfprintf(stderr, message, ap);
    va_end(ap);
    fputc('\n', stderr);
}

static fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

/* ---------------------------------------------------- model description */
static int attr(const char *start, const char *end, const char *key, char *out, size_t n) {
    char pat[64];
    const char *p, *q;
    snprintf(pat, sizeof pat, " %s=\"", key);
    for (p = start; (p = strstr(p, pat)) != NULL && p < end; p++) {
        p += strlen(pat);
        q = strchr(p, '"');
        if (!q || (size_t)(q - p) >= n) return 0;
        memcpy(out, p, (size_t)(q - p));
        out[q - p] = '\0';
        return 1;
    }
    return 0;
}

static void read_model_description(const char *dir) {
    char path[4096], buf[32];
    FILE *f;
    long len;
    char *xml, *p;
    snprintf(path, sizeof path, "%s/modelDescription.xml", dir);
    f = fopen(path, "rb");
    if (!f) die("cannot open %s", path);
    fseek(f, 0, SEEK_END);
    len = ftell(f);
    fseek(f, 0, SEEK_SET);
    xml = malloc((size_t)len + 1);
    if (!xml || fread(xml, 1, (size_t)len, f) != (size_t)len) die("cannot read %s", path);
    xml[len] = '\0';
    fclose(f);
    p = strstr(xml, "<fmiModelDescription");
    if (!p || !attr(p, strchr(p, '>'), "guid", guid, sizeof guid)) die("no guid in %s", path);
    p = strstr(xml, "<CoSimulation");
    if (!p || !attr(p, strchr(p, '>'), "modelIdentifier", model_id, sizeof model_id))
        die("no CoSimulation modelIdentifier in %s", path);
    for (p = xml; (p = strstr(p, "<ScalarVariable")) != NULL; p++) {
        char *end = strstr(p, "</ScalarVariable>"), *tag = strchr(p, '>');
        var_t *v = &vars[n_vars];
        const char *types[] = {"Real", "Integer", "Boolean", "String", "Enumeration"};
        int k;
        if (!end || !tag || n_vars == MAX_VARS) break;
        if (!attr(p, tag, "name", v->name, sizeof v->name) || !attr(p, tag, "valueReference", buf, sizeof buf))
            continue;
        v->vr = (unsigned)strtoul(buf, NULL, 10);
        v->type[0] = '\0';
        for (k = 0; k < 5; k++) {
            char open[32];
            snprintf(open, sizeof open, "<%s", types[k]);
            if (strstr(tag, open) && strstr(tag, open) < end) strcpy(v->type, types[k]);
        }
        n_vars++;
    }
    free(xml);
}

static const var_t *var(const char *name) {
    int i;
    for (i = 0; i < n_vars; i++)
        if (strcmp(vars[i].name, name) == 0) return &vars[i];
    die("no variable %s in the model description", name);
    return NULL;
}

/* ------------------------------------------------------------- options */
static const char *opt_uri, *opt_in = "raw_rate", *opt_restart = "restart";
static const char *opt_set[MAX_SET], *opt_out[MAX_OUT], *opt_bad[MAX_SET];
static int n_set, n_out, n_bad, opt_log, opt_init_sample;
static double opt_step = 0.005;
static long opt_n = 1000000;
static char default_uri[4200];

/* default_uri = file://<absolute dir>/resources: a relative DIR ("SimulatedFogNative/", as the
 * README's example has it) would otherwise give "file://SimulatedFogNative//resources", a URI
 * whose host part is the folder's name, and the FMU could not find its resources */
static void set_default_uri(const char *dir) {
#ifdef _WIN32
    snprintf(default_uri, sizeof default_uri, "file://%s/resources", dir);   /* the tests pass Z:/... */
#else
    char *resolved = dir[0] == '/' ? NULL : realpath(dir, NULL);
    snprintf(default_uri, sizeof default_uri, "file://%s/resources", resolved ? resolved : dir);
    free(resolved);
#endif
}

#ifdef _WIN32
typedef HMODULE lib_t;
static void *sym(lib_t lib, const char *name) {
    void *f = (void *)GetProcAddress(lib, name);
    if (!f) die("%s not exported by the FMU binary", name);
    return f;
}
#else
typedef void *lib_t;
static void *sym(lib_t lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) die("%s not exported by the FMU binary", name);
    return f;
}
#endif

static void load(const char *dir) {
    char path[4400];
    lib_t lib;
    snprintf(path, sizeof path, "%s/binaries/" PLATFORM_DIR "/%s" BINARY_EXT, dir, model_id);
#ifdef _WIN32
    lib = LoadLibraryA(path);
    if (!lib) die("LoadLibrary %s: error %lu", path, (unsigned long)GetLastError());
#else
    lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) die("dlopen %s: %s", path, dlerror());
#endif
    Instantiate = (fmi2InstantiateTYPE *)sym(lib, "fmi2Instantiate");
    FreeInstance = (fmi2FreeInstanceTYPE *)sym(lib, "fmi2FreeInstance");
    SetupExperiment = (fmi2SetupExperimentTYPE *)sym(lib, "fmi2SetupExperiment");
    EnterInit = (fmi2EnterInitializationModeTYPE *)sym(lib, "fmi2EnterInitializationMode");
    ExitInit = (fmi2ExitInitializationModeTYPE *)sym(lib, "fmi2ExitInitializationMode");
    Terminate = (fmi2TerminateTYPE *)sym(lib, "fmi2Terminate");
    Reset = (fmi2ResetTYPE *)sym(lib, "fmi2Reset");
    GetReal = (fmi2GetRealTYPE *)sym(lib, "fmi2GetReal");
    SetReal = (fmi2SetRealTYPE *)sym(lib, "fmi2SetReal");
    SetInteger = (fmi2SetIntegerTYPE *)sym(lib, "fmi2SetInteger");
    SetBoolean = (fmi2SetBooleanTYPE *)sym(lib, "fmi2SetBoolean");
    GetBoolean = (fmi2GetBooleanTYPE *)sym(lib, "fmi2GetBoolean");
    SetString = (fmi2SetStringTYPE *)sym(lib, "fmi2SetString");
    DoStep = (fmi2DoStepTYPE *)sym(lib, "fmi2DoStep");
    GetFMUstate = (fmi2GetFMUstateTYPE *)sym(lib, "fmi2GetFMUstate");
    SetFMUstate = (fmi2SetFMUstateTYPE *)sym(lib, "fmi2SetFMUstate");
    FreeFMUstate = (fmi2FreeFMUstateTYPE *)sym(lib, "fmi2FreeFMUstate");
    SerializedSize = (fmi2SerializedFMUstateSizeTYPE *)sym(lib, "fmi2SerializedFMUstateSize");
    Serialize = (fmi2SerializeFMUstateTYPE *)sym(lib, "fmi2SerializeFMUstate");
    DeSerialize = (fmi2DeSerializeFMUstateTYPE *)sym(lib, "fmi2DeSerializeFMUstate");
    /* the library stays loaded until exit, as most hosts do */
}

static fmi2Component instantiate(void) {
    const char *uri = opt_uri ? (strcmp(opt_uri, "NULL") == 0 ? NULL : opt_uri) : default_uri;
    fmi2Component c = Instantiate("host", fmi2CoSimulation, guid, uri, &callbacks, fmi2False,
                                  opt_log ? fmi2True : fmi2False);
    if (!c) die("fmi2Instantiate returned NULL (uri %s)", uri ? uri : "NULL");
    return c;
}

static fmi2Status set_param(fmi2Component c, const char *assignment) {
    char name[128];
    const char *eq = strchr(assignment, '=');
    const var_t *v;
    if (!eq || (size_t)(eq - assignment) >= sizeof name) die("--set expects NAME=VALUE: %s", assignment);
    memcpy(name, assignment, (size_t)(eq - assignment));
    name[eq - assignment] = '\0';
    v = var(name);
    if (strcmp(v->type, "Real") == 0) {
        fmi2Real x = strtod(eq + 1, NULL);
        return SetReal(c, &v->vr, 1, &x);
    }
    if (strcmp(v->type, "Integer") == 0 || strcmp(v->type, "Enumeration") == 0) {
        fmi2Integer x = (fmi2Integer)strtol(eq + 1, NULL, 10);
        return SetInteger(c, &v->vr, 1, &x);
    }
    if (strcmp(v->type, "Boolean") == 0) {
        fmi2Boolean x = (strcmp(eq + 1, "true") == 0 || strcmp(eq + 1, "1") == 0) ? fmi2True : fmi2False;
        return SetBoolean(c, &v->vr, 1, &x);
    }
    {
        fmi2String x = eq + 1;
        return SetString(c, &v->vr, 1, &x);
    }
}

/* instantiate, set the parameters: an instance in initialisation mode */
static fmi2Component start_init(void) {
    int i;
    fmi2Component c = instantiate();
    if (SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) > fmi2Warning) die("fmi2SetupExperiment failed");
    if (EnterInit(c) > fmi2Warning) die("fmi2EnterInitializationMode failed");
    for (i = 0; i < n_set; i++)
        if (set_param(c, opt_set[i]) > fmi2Warning) die("setting %s failed", opt_set[i]);
    return c;
}

static void exit_init(fmi2Component c) {
    if (ExitInit(c) > fmi2Warning) die("fmi2ExitInitializationMode failed");
}

/* instantiate, set the parameters, initialise */
static fmi2Component start(void) {
    fmi2Component c = start_init();
    exit_init(c);
    return c;
}


/* ------------------------------------------------------------------ run */
static int run(int bench) {
    fmi2Component c = start_init();
    int in_init = opt_init_sample; /* the first sample is taken at fmi2ExitInitializationMode */
    fmi2ValueReference vin = var(opt_in)->vr, vr_restart = 0, vout[MAX_OUT];
    fmi2Real out[MAX_OUT];
    int has_restart = opt_restart[0] != '\0', i;
    long k = 0;
    double t = 0.0, t0, elapsed;
    unsigned long long rng = 88172645463325252ULL;
    char line[256];
    if (has_restart) vr_restart = var(opt_restart)->vr;
    if (n_out == 0) opt_out[n_out++] = "filtered_rate";
    for (i = 0; i < n_out; i++) vout[i] = var(opt_out[i])->vr;
    if (!in_init) exit_init(c);
    t0 = now();
    for (;;) {
        fmi2Real z;
        fmi2Boolean r = fmi2False;
        if (bench) {
            if (k >= opt_n) break;
            rng ^= rng << 13; rng ^= rng >> 7; rng ^= rng << 17; /* xorshift64 */
            /* a slow triangle (period 4000 samples, +-0.5) plus uniform noise: no libm needed */
            z = 0.5 * (fabs((double)(k % 4000) - 2000.0) / 1000.0 - 1.0)
                + 1e-2 * ((double)(rng >> 11) / 9007199254740992.0 - 0.5);
        } else {
            int rs = 0;
            if (!fgets(line, sizeof line, stdin)) break;
            if (sscanf(line, "%lf %d", &z, &rs) < 1) continue;
            r = rs ? fmi2True : fmi2False;
        }
        if (SetReal(c, &vin, 1, &z) != fmi2OK) die("fmi2SetReal(%s) failed at sample %ld", opt_in, k);
        if (has_restart && SetBoolean(c, &vr_restart, 1, &r) != fmi2OK) die("fmi2SetBoolean failed");
        if (in_init) {
            exit_init(c);
            in_init = 0;
        } else {
            if (DoStep(c, t, opt_step, fmi2True) > fmi2Warning) die("fmi2DoStep failed at sample %ld", k);
            t += opt_step;
        }
        if (GetReal(c, vout, (size_t)n_out, out) != fmi2OK) die("fmi2GetReal failed at sample %ld", k);
        if (!bench) {
            for (i = 0; i < n_out; i++) printf(i ? " %.17g" : "%.17g", out[i]);
            putchar('\n');
        }
        k++;
    }
    elapsed = now() - t0;
    if (in_init) exit_init(c); /* no sample at all */
    if (Terminate(c) != fmi2OK) die("fmi2Terminate failed");
    FreeInstance(c);
    if (bench) printf("steps_per_s %.0f\n", (double)k / elapsed);
    else fprintf(stderr, "host: %ld steps, %.0f steps/s\n", k, elapsed > 0 ? (double)k / elapsed : 0.0);
    return 0;
}

/* ------------------------------------------------------------ forbidden */
static int n_fail;

/* the call returned fmi2Error and logged why */
static void expect_error(const char *what, fmi2Status st, int logged_before) {
    int logged = n_logged_errors > logged_before;
    if (st == fmi2Error && logged) {
        printf("PASS %s\n", what);
    } else {
        printf("FAIL %s: status %d, reason logged: %s\n", what, (int)st, logged ? "yes" : "no");
        n_fail++;
    }
}

static void expect_ok(const char *what, fmi2Status st) {
    if (st == fmi2OK) printf("PASS %s\n", what);
    else { printf("FAIL %s: status %d\n", what, (int)st); n_fail++; }
}

#define CHECK_ERR(what, call) do { int nb_ = n_logged_errors; expect_error(what, (call), nb_); } while (0)

static int forbidden(void) {
    fmi2Component c;
    fmi2ValueReference vin = var(opt_in)->vr, vout = var(n_out ? opt_out[0] : "filtered_rate")->vr;
    fmi2ValueReference bad = 0x7fffff00u;
    fmi2Real x = 1.0, nan = NAN;
    double steps[3] = {-0.005, 0.0, 0.0};
    int i;
    steps[2] = nan;

    c = instantiate();
    CHECK_ERR("fmi2DoStep before initialisation", DoStep(c, 0.0, opt_step, fmi2True));
    FreeInstance(c);

    c = start();
    CHECK_ERR("fmi2SetReal on an output", SetReal(c, &vout, 1, &x));
    FreeInstance(c);

    c = instantiate();
    CHECK_ERR("fmi2SetReal on an output before initialisation", SetReal(c, &vout, 1, &x));
    FreeInstance(c);

    for (i = 0; i < 3; i++) {
        char what[64];
        snprintf(what, sizeof what, "fmi2DoStep with step size %g", steps[i]);
        c = start();
        SetReal(c, &vin, 1, &x);
        CHECK_ERR(what, DoStep(c, 0.0, steps[i], fmi2True));
        FreeInstance(c);
    }

    c = start();
    CHECK_ERR("fmi2GetReal of an unknown value reference", GetReal(c, &bad, 1, &x));
    FreeInstance(c);
    c = instantiate();
    CHECK_ERR("fmi2SetReal of an unknown value reference", SetReal(c, &bad, 1, &x));
    FreeInstance(c);

    c = instantiate();
    expect_ok("fmi2EnterInitializationMode", EnterInit(c));
    CHECK_ERR("second fmi2EnterInitializationMode", EnterInit(c));
    FreeInstance(c);

    c = start();
    SetReal(c, &vin, 1, &x);
    expect_ok("fmi2DoStep", DoStep(c, 0.0, opt_step, fmi2True));
    expect_ok("fmi2Terminate", Terminate(c));
    CHECK_ERR("fmi2DoStep after fmi2Terminate", DoStep(c, opt_step, opt_step, fmi2True));
    CHECK_ERR("fmi2SetReal on an input after fmi2Terminate", SetReal(c, &vin, 1, &x));
    /* the instance is in the error state now: only reset / free / get / state calls */
    CHECK_ERR("fmi2DoStep in the error state", DoStep(c, opt_step, opt_step, fmi2True));
    expect_ok("fmi2Reset from the error state", Reset(c));
    FreeInstance(c);

    for (i = 0; i < n_set; i++) { /* a fixed parameter after initialisation */
        c = start();
        {
            char what[200];
            snprintf(what, sizeof what, "setting fixed parameter %.100s after initialisation", opt_set[i]);
            CHECK_ERR(what, set_param(c, opt_set[i]));
        }
        FreeInstance(c);
    }

    for (i = 0; i < n_bad; i++) { /* an invalid parameter value */
        char what[200];
        c = instantiate();
        SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
        EnterInit(c);
        if (set_param(c, opt_bad[i]) != fmi2OK) {
            printf("FAIL setting %.100s in initialisation mode was refused\n", opt_bad[i]);
            n_fail++;
        } else {
            snprintf(what, sizeof what, "fmi2ExitInitializationMode with %.100s", opt_bad[i]);
            CHECK_ERR(what, ExitInit(c));
        }
        FreeInstance(c);
    }

    c = start();
    {
        fmi2FMUstate st = NULL;
        size_t n = 0;
        fmi2Byte *buf;
        expect_ok("fmi2GetFMUstate", GetFMUstate(c, &st));
        expect_ok("fmi2SerializedFMUstateSize", SerializedSize(c, st, &n));
        buf = calloc(n ? n : 1, 1);
        expect_ok("fmi2SerializeFMUstate", Serialize(c, st, buf, n));
        expect_ok("fmi2FreeFMUstate", FreeFMUstate(c, &st));
        if (n > 40) buf[n / 2] ^= 0x5a;
        CHECK_ERR("fmi2DeSerializeFMUstate of a corrupted state", DeSerialize(c, buf, n, &st));
        free(buf);
    }
    FreeInstance(c);

    printf("%d failed\n", n_fail);
    return n_fail;
}

#ifndef GD_HOST_NO_MAIN /* chain.c includes this file for its FMU loading and helpers */
int main(int argc, char **argv) {
    const char *dir, *mode;
    int i;
    if (argc < 3) {
        fprintf(stderr, "usage: host FMU_DIR run|bench|forbidden [options]\n");
        return 2;
    }
    dir = argv[1];
    mode = argv[2];
    for (i = 3; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "--log") == 0) { opt_log = 1; continue; }
        if (strcmp(a, "--init-sample") == 0) { opt_init_sample = 1; continue; }
        if (!v) die("%s needs a value", a);
        if (strcmp(a, "--uri") == 0) opt_uri = v;
        else if (strcmp(a, "--set") == 0 && n_set < MAX_SET) opt_set[n_set++] = v;
        else if (strcmp(a, "--bad") == 0 && n_bad < MAX_SET) opt_bad[n_bad++] = v;
        else if (strcmp(a, "--in") == 0) opt_in = v;
        else if (strcmp(a, "--restart") == 0) opt_restart = v;
        else if (strcmp(a, "--out") == 0 && n_out < MAX_OUT) opt_out[n_out++] = v;
        else if (strcmp(a, "--step") == 0) opt_step = strtod(v, NULL);
        else if (strcmp(a, "--n") == 0) opt_n = strtol(v, NULL, 10);
        else die("unknown option %s", a);
        i++;
    }
    set_default_uri(dir);
    read_model_description(dir);
    load(dir);
    if (strcmp(mode, "run") == 0) return run(0);
    if (strcmp(mode, "bench") == 0) { quiet_log = 1; return run(1); }
    if (strcmp(mode, "forbidden") == 0) return forbidden();
    die("unknown mode %s", mode);
    return 2;
}
#endif
