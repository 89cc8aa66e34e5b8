/*
 * simdriver.c -- runs the simulated gyro of gyrodenoise/core/gdsim.c from plain C
 * (tests/simulator/test_c_simulator_equals_python.py: the same numbers on linux64 and on win64 under wine as the
 * plain-Python specification; the steps/s of the model).
 *
 *   simdriver SEED N [bench] < card_vector     card vector: the 125 numbers of
 *                                              simkernels.card_vector, whitespace-separated
 * prints N samples (%.17g, true rate 0, a restart at sample N/2), or with "bench"
 * the samples per second of N steps.
 *
 * Build: gcc -std=c99 -O2 -ffp-contract=off -I gyrodenoise/core simdriver.c gdsim.c -lm
 */
#ifdef _WIN32
#define __USE_MINGW_ANSI_STDIO 1
#include <windows.h>
#else
#define _POSIX_C_SOURCE 200809L
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gdsim.h"
#include "monotonic.h"


int main(int argc, char **argv) {
    enum { LEN = GD_SIM_CARD_LEN };
    double v[LEN], *p, *s, seed, t0, y = 0.0;
    gd_card_t c;
    long n, i;
    int k, bench;
    if (argc < 3) {
        fprintf(stderr, "usage: simdriver SEED N [bench] < card_vector\n");
        return 2;
    }
    seed = strtod(argv[1], NULL);
    n = strtol(argv[2], NULL, 10);
    bench = argc > 3 && strcmp(argv[3], "bench") == 0;
    for (k = 0; k < LEN; k++)
        if (scanf("%lf", &v[k]) != 1) {
            fprintf(stderr, "simdriver: card vector item %d missing\n", k);
            return 2;
        }
    gd_sim_card_from_vector(v, LEN, &c);
    p = calloc((size_t)gd_sim_n_params(&c), sizeof *p);
    gd_sim_params(&c, seed, p);
    s = calloc((size_t)gd_sim_n_state(p), sizeof *s);
    gd_sim_reset(p, s);
    t0 = now();
    for (i = 0; i < n; i++) {
        y = gd_sim_step(p, s, 0.0, i == n / 2);
        if (!bench) printf("%.17g\n", y);
    }
    if (bench) printf("steps_per_s %.0f (last %g)\n", (double)n / (now() - t0), y);
    free(s);
    free(p);
    return 0;
}
