/*
 * simdriver.c -- runs the simulated gyro of gyrodenoise/core/gdsim.c from plain C
 * (tests/test_gdsim.py: the same numbers on linux64 and on win64 under wine as the
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
    enum { M = GD_SIM_MAX_REPEAT, LEN = 12 + 5 * GD_SIM_MAX_REPEAT + 1 + 2 * GD_SIM_MAX_REPEAT };
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
    memset(&c, 0, sizeof c);
    c.sample_rate_hz = v[0]; c.Q = v[1]; c.N = v[2]; c.B = v[3]; c.K = v[4]; c.R = v[5];
    c.bias = v[6]; c.bias_rep = v[7]; c.tr_amp = v[8]; c.tr_tau = v[9];
    c.n_gm = (int)v[10]; c.n_sin = (int)v[11];
    for (k = 0; k < M; k++) {
        c.gm_sigma[k] = v[12 + k]; c.gm_tau[k] = v[12 + M + k]; c.sin_amp[k] = v[12 + 2 * M + k];
        c.sin_f[k] = v[12 + 3 * M + k]; c.sin_phase_deg[k] = v[12 + 4 * M + k];
    }
    c.n_agm = (int)v[12 + 5 * M];
    for (k = 0; k < M; k++) {
        c.agm_sigma[k] = v[13 + 5 * M + k]; c.agm_tau[k] = v[13 + 6 * M + k];
    }
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
