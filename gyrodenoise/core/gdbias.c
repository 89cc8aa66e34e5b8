/*
 * gdbias.c -- bias tracking for open-loop attitude, translated from
 * kernels.bias_update (read its docstring for the reasons). Build as gdcore.c:
 * -ffp-contract=off, never -ffast-math.
 *
 * Blocks of p[P_BIAS_NEED] still samples (bias_still_s): a block's mean is
 * committed only when it is neither the first block of its still run (the bank
 * decides "still" a little after the motion stopped) nor the last (the bank
 * decides "moving" a little after the motion started): a completed block waits
 * as "pending" until the next one completes, and a sample that is not still
 * drops the block being filled and the pending one. The estimate:
 *     nb <- min(nb + 1, cap);   mean <- mean + (pend - mean) / nb        (B1)
 * the mean of the committed blocks, then an exponential memory of cap blocks
 * (bias_memory_s) that follows a slow drift. Before the first commit (B0) the
 * estimate is the mean of the current run's completed blocks (a start-up
 * calibration from the first still second on), replaced at the first commit.
 * What is removed (B2):
 *     hat = mean - floor if mean > floor, mean + floor if mean < -floor, else 0
 * floor = earth_rate_floor_deg_h on a navigation-grade record (the bank's white-noise
 * variance r below p[P_BIAS_NAVR]: an angle random walk below GB_NAV_ARW_DEG_RTH):
 * never the first floor deg/s of its bias (a still sensor measures Earth's rotation,
 * <= 15 deg/h on any axis); 0 on a noisier (MEMS) record, whose whole estimate is
 * removed, Earth's rate with it (attitude relative to the Earth).
 */
#include "gdbias.h"
#include "gdcore.h"

#include <math.h>

void gd_bias_params(double *p, double fs, double still_s, double memory_s, double floor_deg_h)
{
    double need = nearbyint(still_s * fs), cap, a = GB_NAV_ARW_DEG_RTH / 60.0;   /* round half to even */
    if (need < 1.0)
        need = 1.0;
    cap = nearbyint(memory_s * fs / need);
    p[P_BIAS_LANE] = (double)GB_LANE;
    p[P_BIAS_NEED] = need;
    p[P_BIAS_CAP] = cap < 1.0 ? 1.0 : cap;
    p[P_BIAS_FLOOR] = floor_deg_h / 3600.0;
    p[P_BIAS_NAVR] = a * a * fs;      /* ARW^2 = R / fs, deg^2/s */
}

double gd_bias_hat(const double *p, const double *s)
{
    return p[P_BIAS] > 0.0 ? s[gd_layout_total((int)p[P_ORDER]) - N_EXT + M_BIAS + 6] : 0.0;
}

void gd_bias_load(const double *b, gd_bias_t *e)
{
    e->cur_sum = b[0];
    e->cur_n = b[1];
    e->nblk = b[2];
    e->pend = b[3];
    e->nb = b[4];
    e->mean = b[5];
    e->hat = b[6];
}

void gd_bias_save(const gd_bias_t *e, double *b)
{
    b[0] = e->cur_sum;
    b[1] = e->cur_n;
    b[2] = e->nblk;
    b[3] = e->pend;
    b[4] = e->nb;
    b[5] = e->mean;
    b[6] = e->hat;
}

double gd_bias_update(const double *p, gd_bias_t *e, double z, int calm, double r)
{
    double floor_ = r < p[P_BIAS_NAVR] ? p[P_BIAS_FLOOR] : 0.0, bm;
    if (!calm || !(z - z == 0.0)) {     /* moving (or a non-finite sample): the run ends */
        e->cur_sum = 0.0;
        e->cur_n = 0.0;
        e->nblk = 0.0;
        return e->hat;
    }
    e->cur_sum += z;
    e->cur_n += 1.0;
    if (e->cur_n < p[P_BIAS_NEED])
        return e->hat;
    bm = e->cur_sum / e->cur_n;
    e->nblk += 1.0;
    if (e->nblk >= 3.0) {               /* the pending block: neither the run's first nor its last */
        e->nb = e->nb + 1.0 < p[P_BIAS_CAP] ? e->nb + 1.0 : p[P_BIAS_CAP];
        e->mean = e->mean + (e->pend - e->mean) / e->nb;            /* (B1) */
    } else if (e->nb == 0.0)            /* nothing committed yet: the run's blocks so far (B0) */
        e->mean = e->mean + (bm - e->mean) / e->nblk;
    if (e->nblk >= 3.0 || e->nb == 0.0) {
        if (e->mean > floor_)                                         /* (B2) */
            e->hat = e->mean - floor_;
        else if (e->mean < -floor_)
            e->hat = e->mean + floor_;
        else
            e->hat = 0.0;
    }
    e->pend = bm;
    e->cur_sum = 0.0;
    e->cur_n = 0.0;
    return e->hat;
}
