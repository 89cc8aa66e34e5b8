/* Motion-cost driver: reads a case file written by motion_cost.py
 * (n_p, n_s, n doubles as int64; p, s, z doubles; restarts bytes), runs
 * gd_run over it and writes the output and the final state (doubles).
 * Used for callgrind's instruction counts and the aarch64 (qemu) bit check. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include "gdcore.h"   /* -I the core folder */

int main(int argc, char **argv)
{
    int64_t hdr[3];
    FILE *f;
    double *p, *s, *z, *out;
    unsigned char *rs;
    if (argc != 3) {
        fprintf(stderr, "usage: driver CASE.bin OUT.bin\n");
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
    gd_run(p, s, z, rs, out, (long)hdr[2]);
    f = fopen(argv[2], "wb");
    if (!f)
        return 1;
    fwrite(out, 8, hdr[2], f);
    fwrite(s, 8, hdr[1], f);
    fclose(f);
    return 0;
}
