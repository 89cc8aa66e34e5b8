/* Motion-cost driver: reads a case file written by motion_cost.py
 * (n_p, n_s, n doubles as int64; p, s, z doubles; restarts bytes), runs
 * gd_run over it and writes the output and the final state (doubles).
 * Used for callgrind's instruction counts and the aarch64 (qemu) bit check.
 * With a third argument R: also runs the record R more times from the same
 * initial state and prints the fastest run's ns/sample (wall clock); with
 * "step" instead: the per-sample path, gd_step for every sample. */
#define _POSIX_C_SOURCE 199309L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "gdcore.h"   /* -I the core folder */

int main(int argc, char **argv)
{
    int64_t hdr[3];
    FILE *f;
    double *p, *s, *z, *out;
    unsigned char *rs;
    if (argc != 3 && argc != 4) {
        fprintf(stderr, "usage: driver CASE.bin OUT.bin [REPEAT | step]\n");
        return 2;
    }
    f = fopen(argv[1], "rb");
    if (!f || fread(hdr, 8, 3, f) != 3)
        return 1;
    p = malloc(8 * hdr[0]);
    s = malloc(8 * hdr[1]);
    z = malloc(8 * hdr[2]);
    out = malloc(8 * hdr[2]);
    rs = malloc(hdr[2]);
    if (fread(p, 8, hdr[0], f) != (size_t)hdr[0] || fread(s, 8, hdr[1], f) != (size_t)hdr[1]
        || fread(z, 8, hdr[2], f) != (size_t)hdr[2] || fread(rs, 1, hdr[2], f) != (size_t)hdr[2])
        return 1;
    fclose(f);
    if (argc == 4 && strcmp(argv[3], "step") == 0) {
        long k;
        for (k = 0; k < (long)hdr[2]; k++)
            out[k] = gd_step(p, s, z[k], rs[k]);
    } else if (argc == 4) {
        double *s0 = malloc(8 * hdr[1]), best = 1e300;
        int r, nr = atoi(argv[3]);
        memcpy(s0, s, 8 * hdr[1]);
        for (r = 0; r < nr; r++) {
            struct timespec t0, t1;
            double ns;
            memcpy(s, s0, 8 * hdr[1]);
            clock_gettime(CLOCK_MONOTONIC, &t0);
            gd_run(p, s, z, rs, out, (long)hdr[2]);
            clock_gettime(CLOCK_MONOTONIC, &t1);
            ns = ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / (double)hdr[2];
            if (ns < best)
                best = ns;
        }
        printf("%.1f ns/sample (best of %d)\n", best, nr);
        memcpy(s, s0, 8 * hdr[1]);
        free(s0);
    }
    if (argc != 4 || strcmp(argv[3], "step") != 0)
        gd_run(p, s, z, rs, out, (long)hdr[2]);
    f = fopen(argv[2], "wb");
    if (!f)
        return 1;
    fwrite(out, 8, hdr[2], f);
    fwrite(s, 8, hdr[1], f);
    fclose(f);
    return 0;
}
