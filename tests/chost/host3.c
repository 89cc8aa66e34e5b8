/*
 * host3.c -- a plain C FMI 3.0 co-simulation host for the project's FMI 3.0 FMUs (tests):
 * dlopen + the standard FMI 3.0 headers (fmpy's c-code directory), no Python in the process.
 *
 *   host3 LIBRARY TOKEN RESOURCE_DIR [options] < samples
 *
 * Each stdin line is one sample: the --in values (a value reference's n values in a row),
 * then 0/1 for the --restart Boolean if given. Prints the --out values of each sample on one
 * line (%.17g, comma-separated). The caller reads value references from modelDescription.xml.
 * options:
 *   --in VR:N        a Float64 input of N values (repeatable, in the order of the columns)
 *   --restart VR     a Boolean input, the last column
 *   --out VR:N       a Float64 output of N values (repeatable)
 *   --step H         communication step size (default 0.005)
 *   --init-sample    the first sample's inputs are set in initialisation mode and its outputs
 *                    read after fmi3ExitInitializationMode (the sensor FMUs); each further
 *                    sample is one step from its inputs
 * Exit status 0, or 1 with the reason on stderr (a call that returned more than fmi3Warning).
 *
 * Build: gcc -std=c99 -O2 -I<fmpy>/c-code host3.c -o host3 -ldl
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define MAXV 16

static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    fprintf(stderr, "[%d %s] %s\n", (int)status, category ? category : "", message ? message : "");
}

static void *sym(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "host3: %s not exported\n", name);
        exit(1);
    }
    return f;
}

#define CHECK(call, what)                                                 \
    do {                                                                  \
        fmi3Status st_ = (call);                                          \
        if (st_ > fmi3Warning) {                                          \
            fprintf(stderr, "host3: %s returned %d\n", what, (int)st_);   \
            return 1;                                                     \
        }                                                                 \
    } while (0)

static int parse_vr(const char *s, fmi3ValueReference *vr, size_t *n) {
    unsigned a, b = 1;
    if (sscanf(s, "%u:%u", &a, &b) < 1 || b < 1 || b > MAXV) return -1;
    *vr = a;
    *n = b;
    return 0;
}

int main(int argc, char **argv) {
    fmi3ValueReference in_vr[MAXV], out_vr[MAXV], rs_vr = 0;
    size_t in_n[MAXV], out_n[MAXV], n_in = 0, n_out = 0, in_total = 0, out_total = 0, i, j;
    int has_restart = 0, init_sample = 0;
    double h = 0.005, t = 0.0, x[MAXV * MAXV], y[MAXV * MAXV];
    long k = 0;
    void *lib;
    fmi3Instance inst;
    char line[8192];
    fmi3InstantiateCoSimulationTYPE *instantiate;
    fmi3EnterInitializationModeTYPE *enter_init;
    fmi3ExitInitializationModeTYPE *exit_init;
    fmi3SetFloat64TYPE *set_f64;
    fmi3GetFloat64TYPE *get_f64;
    fmi3SetBooleanTYPE *set_bool;
    fmi3DoStepTYPE *do_step;
    fmi3TerminateTYPE *terminate;
    fmi3FreeInstanceTYPE *free_instance;

    if (argc < 4) {
        fprintf(stderr, "usage: host3 LIBRARY TOKEN RESOURCE_DIR [--in VR:N] [--restart VR] [--out VR:N] "
                        "[--step H] [--init-sample] < samples\n");
        return 2;
    }
    for (i = 4; i < (size_t)argc; i++) {
        if (!strcmp(argv[i], "--in") && i + 1 < (size_t)argc && n_in < MAXV) {
            if (parse_vr(argv[++i], &in_vr[n_in], &in_n[n_in]) != 0) return 2;
            in_total += in_n[n_in++];
        } else if (!strcmp(argv[i], "--out") && i + 1 < (size_t)argc && n_out < MAXV) {
            if (parse_vr(argv[++i], &out_vr[n_out], &out_n[n_out]) != 0) return 2;
            out_total += out_n[n_out++];
        } else if (!strcmp(argv[i], "--restart") && i + 1 < (size_t)argc) {
            rs_vr = (fmi3ValueReference)strtoul(argv[++i], NULL, 10);
            has_restart = 1;
        } else if (!strcmp(argv[i], "--step") && i + 1 < (size_t)argc) {
            h = strtod(argv[++i], NULL);
        } else if (!strcmp(argv[i], "--init-sample")) {
            init_sample = 1;
        } else {
            fprintf(stderr, "host3: unknown option %s\n", argv[i]);
            return 2;
        }
    }
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "host3: %s\n", dlerror());
        return 1;
    }
    instantiate = (fmi3InstantiateCoSimulationTYPE *)sym(lib, "fmi3InstantiateCoSimulation");
    enter_init = (fmi3EnterInitializationModeTYPE *)sym(lib, "fmi3EnterInitializationMode");
    exit_init = (fmi3ExitInitializationModeTYPE *)sym(lib, "fmi3ExitInitializationMode");
    set_f64 = (fmi3SetFloat64TYPE *)sym(lib, "fmi3SetFloat64");
    get_f64 = (fmi3GetFloat64TYPE *)sym(lib, "fmi3GetFloat64");
    set_bool = (fmi3SetBooleanTYPE *)sym(lib, "fmi3SetBoolean");
    do_step = (fmi3DoStepTYPE *)sym(lib, "fmi3DoStep");
    terminate = (fmi3TerminateTYPE *)sym(lib, "fmi3Terminate");
    free_instance = (fmi3FreeInstanceTYPE *)sym(lib, "fmi3FreeInstance");

    inst = instantiate("host3", argv[2], argv[3], fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0, NULL,
                       logger, NULL);
    if (!inst) {
        fprintf(stderr, "host3: fmi3InstantiateCoSimulation returned NULL\n");
        return 1;
    }
    CHECK(enter_init(inst, fmi3False, 0.0, 0.0, fmi3False, 0.0), "fmi3EnterInitializationMode");
    if (!init_sample) CHECK(exit_init(inst), "fmi3ExitInitializationMode");
    while (fgets(line, sizeof line, stdin)) {
        char *p = line, *e;
        fmi3Boolean rs = fmi3False;
        size_t at = 0;
        for (j = 0; j < in_total; j++) {
            x[j] = strtod(p, &e);
            if (e == p) break;
            p = e;
        }
        if (j < in_total) continue; /* a blank or short line */
        if (has_restart) rs = strtol(p, NULL, 10) != 0;
        for (j = 0; j < n_in; j++) {
            CHECK(set_f64(inst, &in_vr[j], 1, x + at, in_n[j]), "fmi3SetFloat64");
            at += in_n[j];
        }
        if (has_restart) CHECK(set_bool(inst, &rs_vr, 1, &rs, 1), "fmi3SetBoolean");
        if (init_sample && k == 0) {
            CHECK(exit_init(inst), "fmi3ExitInitializationMode");
        } else {
            fmi3Boolean ev, term, early;
            fmi3Float64 last;
            CHECK(do_step(inst, t, h, fmi3True, &ev, &term, &early, &last), "fmi3DoStep");
            if (ev || term || early || last != t + h) {
                fprintf(stderr, "host3: fmi3DoStep out-params %d %d %d %.17g at t=%.17g\n", ev, term, early,
                        last, t);
                return 1;
            }
            t = (double)(init_sample ? k : k + 1) * h;
        }
        at = 0;
        for (j = 0; j < n_out; j++) {
            CHECK(get_f64(inst, &out_vr[j], 1, y + at, out_n[j]), "fmi3GetFloat64");
            at += out_n[j];
        }
        for (j = 0; j < out_total; j++) printf(j ? ",%.17g" : "%.17g", y[j]);
        printf("\n");
        k++;
    }
    CHECK(terminate(inst), "fmi3Terminate");
    free_instance(inst);
    return 0;
}
