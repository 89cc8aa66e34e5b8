/*
 * chain.c -- the simulated gyro -> denoiser chain from plain C: two native FMUs, no
 * Python anywhere (tests/fmu/test_c_chain.py).
 *
 *   chain FOG_DIR DEN_DIR [options] < inputs   one line per sample: "true_rate [restart]";
 *                                              writes CSV on stdout:
 *                                              t_s,true_rate,restart,measured_rate,filtered_rate
 *   chain FOG_DIR DEN_DIR --bench N [options]  N steps at a zero true rate; prints
 *                                              two_fmu_steps_per_s
 * options:
 *   --fog NAME=VALUE   a parameter of the sensor FMU (repeatable), e.g. card=imar_fog, seed=3
 *   --den NAME=VALUE   a parameter of the denoiser FMU (repeatable), e.g. method=shakf
 *   --step H           communication step size, s (default 0.005)
 *
 * Master: the sensor takes sample 0 at fmi2ExitInitializationMode (the first line's
 * true_rate and restart set before it) and each further sample k in its step from
 * t_(k-1) (the inputs of line k set before it); the denoiser receives sample k and its
 * restarted in its step from t_k. So the denoiser's output is the library's gd.denoise
 * of gd.simulate's samples, with no placeholder and no delay (a Jacobi master, as
 * libcosim's, gives the same: the sensor's output at t_k is sample k).
 *
 * FOG_DIR and DEN_DIR are unzipped FMUs; this file reuses host.c's model-description
 * reader, loader and parameter setter (one FMU at a time is "current" there).
 *
 * Build: gcc -std=c99 -O2 -I<fmpy>/c-code chain.c -o chain -ldl
 *        x86_64-w64-mingw32-gcc -std=c99 -O2 -I<fmpy>/c-code chain.c -o chain.exe
 */
#define GD_HOST_NO_MAIN
#include "host.c"

/* one loaded, initialised FMU instance of the chain */
typedef struct {
    fmi2Component c;
    fmi2SetRealTYPE *set_real;
    fmi2SetBooleanTYPE *set_boolean;
    fmi2GetRealTYPE *get_real;
    fmi2GetBooleanTYPE *get_boolean;
    fmi2DoStepTYPE *do_step;
    fmi2TerminateTYPE *terminate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2ValueReference in, restart_in, out, restart_out;
} link_t;

/* load the FMU unzipped in dir, initialise it with the parameters sets[0..n) */
static link_t open_link(const char *dir, const char **sets, int n, const char *in, const char *restart_in,
                        const char *out, const char *restart_out) {
    link_t l;
    int i;
    n_vars = 0;
    set_default_uri(dir);
    read_model_description(dir);
    load(dir);
    n_set = 0;
    for (i = 0; i < n && i < MAX_SET; i++) opt_set[n_set++] = sets[i];
    l.c = start();
    l.set_real = SetReal;
    l.set_boolean = SetBoolean;
    l.get_real = GetReal;
    l.get_boolean = GetBoolean;
    l.do_step = DoStep;
    l.terminate = Terminate;
    l.free_instance = FreeInstance;
    l.in = var(in)->vr;
    l.restart_in = var(restart_in)->vr;
    l.out = var(out)->vr;
    l.restart_out = restart_out ? var(restart_out)->vr : 0;
    return l;
}

static void close_link(link_t *l) {
    if (l->terminate(l->c) != fmi2OK) die("fmi2Terminate failed");
    l->free_instance(l->c);
}

/* the inputs of sample k: a line of stdin, or (bench) a zero rate for k < n_bench; 0 at the end */
static int next_input(long n_bench, long k, char *line, size_t n, fmi2Real *w, fmi2Boolean *r) {
    *w = 0.0;
    *r = fmi2False;
    if (n_bench >= 0) return k < n_bench;
    for (;;) {
        int rs = 0;
        if (!fgets(line, (int)n, stdin)) return 0;
        if (sscanf(line, "%lf %d", w, &rs) < 1) continue;
        *r = rs ? fmi2True : fmi2False;
        return 1;
    }
}

int main(int argc, char **argv) {
    const char *fog_sets[MAX_SET], *den_sets[MAX_SET];
    int n_fog = 0, n_den = 0, i;
    long n_bench = -1, k = 0;
    double h = 0.005, t = 0.0, t0, elapsed;
    link_t fog, den;
    char line[256], w_set[64], r_set[16];
    fmi2Real w = 0.0;
    fmi2Boolean r = fmi2False;
    int have;
    (void)run;       /* host.c's own modes, not used here */
    (void)forbidden;
    if (argc < 3) {
        fprintf(stderr, "usage: chain FOG_DIR DEN_DIR [--fog N=V] [--den N=V] [--step H] [--bench N] < inputs\n");
        return 2;
    }
    for (i = 3; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!v) die("%s needs a value", a);
        if (strcmp(a, "--fog") == 0 && n_fog < MAX_SET) fog_sets[n_fog++] = v;
        else if (strcmp(a, "--den") == 0 && n_den < MAX_SET) den_sets[n_den++] = v;
        else if (strcmp(a, "--step") == 0) h = strtod(v, NULL);
        else if (strcmp(a, "--bench") == 0) n_bench = strtol(v, NULL, 10);
        else die("unknown option %s", a);
        i++;
    }
    quiet_log = n_bench >= 0;
    have = next_input(n_bench, k, line, sizeof line, &w, &r);
    /* sample 0 is taken at the sensor's fmi2ExitInitializationMode: its inputs go in as
     * initial values (set in initialisation mode, with the parameters) */
    snprintf(w_set, sizeof w_set, "true_rate=%.17g", have ? w : 0.0);
    snprintf(r_set, sizeof r_set, "restart=%d", have ? (int)r : 0);
    if (n_fog + 2 > MAX_SET) die("too many --fog options");
    fog_sets[n_fog++] = w_set;
    fog_sets[n_fog++] = r_set;
    fog = open_link(argv[1], fog_sets, n_fog, "true_rate", "restart", "measured_rate", "restarted");
    den = open_link(argv[2], den_sets, n_den, "raw_rate", "restart", "filtered_rate", NULL);
    if (n_bench < 0) printf("t_s,true_rate,restart,measured_rate,filtered_rate\n");
    t0 = now();
    while (have) {
        fmi2Real y, f;
        fmi2Boolean rr;
        if (k > 0 /* sample k: the sensor's step from t_(k-1), the inputs of sample k set before it */
            && (fog.set_real(fog.c, &fog.in, 1, &w) != fmi2OK
                || fog.set_boolean(fog.c, &fog.restart_in, 1, &r) != fmi2OK
                || fog.do_step(fog.c, t - h, h, fmi2True) != fmi2OK))
            die("sensor FMU failed at sample %ld", k);
        if (fog.get_real(fog.c, &fog.out, 1, &y) != fmi2OK || fog.get_boolean(fog.c, &fog.restart_out, 1, &rr) != fmi2OK)
            die("sensor FMU failed at sample %ld", k);
        if (den.set_real(den.c, &den.in, 1, &y) != fmi2OK || den.set_boolean(den.c, &den.restart_in, 1, &rr) != fmi2OK
            || den.do_step(den.c, t, h, fmi2True) != fmi2OK || den.get_real(den.c, &den.out, 1, &f) != fmi2OK)
            die("denoiser FMU failed at sample %ld", k);
        if (n_bench < 0) printf("%.17g,%.17g,%d,%.17g,%.17g\n", t, w, (int)r, y, f);
        t += h;
        k++;
        have = next_input(n_bench, k, line, sizeof line, &w, &r);
    }
    elapsed = now() - t0;
    close_link(&fog);
    close_link(&den);
    if (n_bench >= 0) printf("two_fmu_steps_per_s %.0f\n", (double)k / elapsed);
    return 0;
}
