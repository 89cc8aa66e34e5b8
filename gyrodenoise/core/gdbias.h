/*
 * gdbias.h -- bias tracking for open-loop attitude (motion's option bias_tracking):
 * the gyro's bias estimated while the motion bank says the gyro is still, carried
 * through motion and removed from the output. Mirrors kernels.bias_step (the plain-
 * Python specification): the same operations in the same order (bit for bit).
 * docs/method/bias.md gives the design, the Earth-rate floor and the measurements.
 */
#ifndef GDBIAS_H
#define GDBIAS_H

#ifdef __cplusplus
extern "C" {
#endif

/* the estimator's state: GB_N doubles at the end of the core's state (M_BIAS),
   kept by restarts (a gap does not change the sensor's bias) */
typedef struct {
    double cur_sum;   /* sum of the raw samples of the block being filled, deg/s */
    double cur_n;     /* its samples */
    double nblk;      /* blocks completed in the current still run */
    double pend;      /* mean of the run's last completed block (committed once another follows), deg/s */
    double nb;        /* blocks committed (at most the memory, p[P_BIAS_CAP]) */
    double mean;      /* the estimate: mean of the committed blocks, faded past the memory, deg/s */
    double hat;       /* the bias removed: mean less the Earth-rate floor (soft threshold), deg/s */
} gd_bias_t;
#define GB_N 7
#define GB_LANE 4               /* still: the bank's most likely filter in lanes 0..4 (tracking index <= 1e-6) */
#define GB_NAV_ARW_DEG_RTH 0.05 /* navigation grade (the Earth-rate floor applies) below this ARW, deg/sqrt(h) */

/* kernels.bias_params: p[P_BIAS_LANE ... P_BIAS_NAVR] from bias_still_s, bias_memory_s,
   earth_rate_floor_deg_h at sample rate fs */
void gd_bias_params(double *p, double fs, double still_s, double memory_s, double floor_deg_h);
/* kernels.bias_hat: the bias removed at the last sample, deg/s (0 when bias tracking is off) */
double gd_bias_hat(const double *p, const double *s);

/* load / save the struct from / into the GB_N doubles at b */
void gd_bias_load(const double *b, gd_bias_t *e);
void gd_bias_save(const gd_bias_t *e, double *b);
/* one raw sample z (deg/s); calm: the bank was still at this sample; r: the bank's white-noise
   variance, (deg/s)^2 (the record's grade). p: the core's parameters (P_BIAS_NEED, P_BIAS_CAP,
   P_BIAS_FLOOR, P_BIAS_NAVR). Returns the bias removed (e->hat). */
double gd_bias_update(const double *p, gd_bias_t *e, double z, int calm, double r);

#ifdef __cplusplus
}
#endif
#endif /* GDBIAS_H */
