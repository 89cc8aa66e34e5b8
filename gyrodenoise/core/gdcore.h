/*
 * gdcore.h -- the per-sample filter kernels of gyrodenoise in portable C99.
 *
 * A line-by-line translation of gyrodenoise/core/kernels.py (the plain-Python
 * executable specification): the same functions with a gd_ prefix, the same
 * two flat buffers of doubles and the same floating-point operations in the
 * same order, so that results agree with the Python to rounding (tested to
 * 1e-12; in practice bit for bit).
 *
 *   p  parameters, at least GD_N_PARAMS doubles (built by kernels.make_params)
 *   s  state, gd_layout_total(n) doubles (built by kernels.init_state)
 *
 * Compile with -ffp-contract=off and without -ffast-math: no fused
 * multiply-add, no reassociation (the finiteness test v - v == 0.0 must stay).
 * Depends on libm only (fabs, exp, sqrt, log, cos; tan, hypot, pow, sin for gd_butter_sos).
 *
 * The buffers are not checked here: the caller guarantees p has GD_N_PARAMS
 * doubles, s has gd_layout_total((int)p[P_ORDER]) doubles, and
 * 0 <= p[P_LP_NSEC] <= GD_MAX_SOS (see gd_check, used by the Python binding).
 */
#ifndef GDCORE_H
#define GDCORE_H

#ifdef __cplusplus
extern "C" {
#endif

/* ---- everything below mirrors gyrodenoise/core/kernels.py: keep them equal ---- */

/* parameters p[] */
#define P_ORDER 0           /* AR order n (>= 1) */
#define P_METHOD 1          /* METHOD_* */
#define P_LAM 2             /* RLS forgetting factor */
#define P_B 3               /* Sage-Husa forgetting factor b */
#define P_GAMMA 4           /* divergence criterion, Eq. (32) */
#define P_Q0 5              /* process noise variance; 0 = auto */
#define P_R0 6              /* measurement noise variance; 0 = auto */
#define P_P0_RLS 7          /* initial RLS covariance (diagonal) */
#define P_P0_KF 8           /* initial filter covariance (diagonal) */
#define P_WARMUP 9          /* warm-up length in samples */
#define P_R_FLOOR 10        /* lower bound of R and the auto noise levels */
#define P_OUTLIER_SIGMA 11  /* innovation gate k; 0 = off */
#define P_OUTLIER_RUN 12    /* rejections after which the filter re-opens */
#define P_LP_NSEC 13        /* lowpass, motion's rigid-body low-pass: second-order sections */
#define P_LP_CUTOFF 14      /* lowpass, motion's rigid-body low-pass: -3 dB cutoff, Hz */
#define P_SOS 15            /* lowpass: MAX_SOS x (b0, b1, b2, a1, a2) */
#define MAX_SOS 4
#define MAX_MOTION_ORDER 4  /* motion's rigid-body low-pass (max_motion_hz): Butterworth order, */
#define MAX_MOTION_CUTOFF 2.0  /* -3 dB at this many times max_motion_hz, */
#define MAX_MOTION_FS_CAP 0.45 /* at most this fraction of the sample rate (kernels.rigid_cutoff_hz) */
#define P_FS (P_SOS + 5 * MAX_SOS)  /* the sample rate, Hz (one_euro) */
#define P_OE_MIN (P_FS + 1)         /* one_euro: cutoff at rest, Hz */
#define P_OE_BETA (P_FS + 2)        /* one_euro: growth of the cutoff with |d rate / dt| */
#define P_OE_DCUT (P_FS + 3)        /* one_euro: cutoff of the low-pass on the rate's change, Hz */
#define P_MO_NF (P_FS + 4)              /* motion: constant-velocity filters, lanes 0..NF-1 */
#define P_MO_FADE (P_MO_NF + 1)         /* motion: fading of the log-likelihoods */
#define P_MO_BR (P_MO_NF + 2)           /* motion: forgetting of the noise level */
#define P_MO_RESET (P_MO_NF + 3)        /* motion: restart gap of the log-likelihood */
#define P_MO_NLAG (P_MO_NF + 4)         /* motion: lags of the 4th differences */
#define P_MO_HUBER (P_MO_NF + 5)        /* motion: clip of |4th difference| */
#define P_MO_KAPPA (P_MO_NF + 6)        /* motion: angle feedback gain */
#define P_MO_CLIP2 (P_MO_NF + 7)        /* motion: Huber clip of the innovation, sigma^2 */
#define P_MO_VAR (P_MO_NF + 8)         /* motion: 1 = keep the output variance M_PVAR */
#define P_MO_G (P_MO_NF + 9)            /* motion: MO_MAX_NF alphas, then the betas, the log S/R, the gammas
                                           (0 in a CV lane), the lam^2 (S_Q) */
#define MO_MAX_NF 16
#define MO_MAX_NLAG 8
#define CA_NEWTON_STEPS 60 /* motion: Newton steps of the CA lanes' steady-state gains (kernels.ca_gains) */
#define P_MO_RFIX (P_MO_G + 5 * MO_MAX_NF) /* motion: > 0 = R to use instead of the estimate */
#define P_MO_SPEC (P_MO_RFIX + 1)  /* motion: spectral noise floor scale 1 / (c sum w^2), 0 = off */
#define P_MO_SBB (P_MO_RFIX + 2)   /* motion: its forgetting per block */
#define P_MO_SRATIO (P_MO_RFIX + 3) /* motion: the spectral estimate rs replaces the lag one r where rs x this < r */
#define P_MO_COS (P_MO_RFIX + 4)   /* motion: cos(2 pi m / MO_SPEC_N), m = 0..MO_SPEC_N-1 */
#define MO_SPEC_N 128              /* spectral floor: block length */
#define MO_SPEC_K0 8               /* its first bin (0.0625 fs) */
#define MO_SPEC_NB 28              /* its bins, every other one (to 62: 0.48 fs) */
#define MO_SPEC_RANK 4             /* the rank of |X|^2 read */
#define MO_HI_J0 12                /* the line test's floor: the bins from MO_SPEC_K0 + 2 x 12 = 32 (0.25 fs) */
#define MO_HI_NB 16                /* ... MO_HI_NB of them */
#define MO_SPEC_ZMAX 1.0e150       /* a block with a centred sample beyond this (or not finite) is skipped;
                                     so is a 4th difference beyond it in the lag noise estimates (M_MABS) */
#define MO_WU_N0 64.0              /* warm-up output (kernels.warmup_output): from this many samples on, */
#define MO_WU_NL 3                 /* ... the noise level of the 4th differences at lags 1..MO_WU_NL, */
#define MO_WU_LO 5.0               /* ... the mean all the way below 1 + MO_WU_LO / sqrt(m), */
#define MO_WU_HI 10.0              /* ... none (and off) from 1 + MO_WU_HI / sqrt(m), */
#define MO_WU_LOW 2.5              /* ... and at or below 1 - MO_WU_LOW / sqrt(m), */
#define MO_WU_SPIKE 25.0           /* ... off at a sample this many times the noise level from the mean, */
#define MO_WU_FADE 0.125           /* ... or where the faded mean (this weight) of those units */
#define MO_WU_GLIM 4.0             /* ... exceeds this */
#define MO_GUARD_FADE 0.0625       /* output guard (kernels.motion_step): weight of a sample's (z - y)^2 / R */
#define MO_GUARD_CAP 1000.0        /* ... clipped at this many R */
#define MO_GUARD_LO 2.5            /* ... the output moves towards the raw sample above this mean, */
#define MO_GUARD_HI 5.0            /* ... all the way at this one */
#define P_MO_PT (P_MO_COS + MO_SPEC_N) /* motion: pass-through: gain smoothing per sample (0 = off), gains lo, hi */
#define P_MO_LINE (P_MO_PT + 3) /* motion: spectral line test threshold x the floor (0 = off) */
#define MO_LINE_J0 19              /* the line test's first bin (MO_SPEC_K0 + 2 x 19 = 46: 0.36 fs) */
#define P_MO_CUS (P_MO_PT + 4) /* motion: summed innovation: fading, weight, threshold (0 weight = off) */
#define P_MO_NCA (P_MO_PT + 7) /* motion: constant-acceleration filters, lanes NF..NF+NCA-1 */
#define P_MO_SPECH (P_MO_PT + 8) /* motion: the line test's floor scale 1 / (c sum w^2) over MO_HI_NB bins */
#define P_BIAS (P_MO_PT + 9)     /* motion: 1 = bias tracking (gdbias.c), 0 = off */
#define P_BIAS_LANE (P_BIAS + 1) /* bias tracking: still where the most likely filter is at or below this lane */
#define P_BIAS_NEED (P_BIAS + 2) /* bias tracking: samples of a block (bias_still_s) */
#define P_BIAS_CAP (P_BIAS + 3)  /* bias tracking: memory, blocks (bias_memory_s / bias_still_s) */
#define P_BIAS_FLOOR (P_BIAS + 4) /* bias tracking: deg/s of the estimate never removed (Earth's rate) */
#define P_BIAS_NAVR (P_BIAS + 5)  /* bias tracking: the floor applies where the white-noise variance is below this */
#define N_PARAMS (P_BIAS + 6)

/* p[P_METHOD] values (doubles, compared with ==): METHOD_* of the registry
   (gyrodenoise/core/methods.py), generated into gdmethods.h */
#include "gdmethods.h"
#include "gdbias.h"

/* state header s[] */
#define S_K 0
#define S_KD 1
#define S_R 2
#define S_Q 3
#define S_S2 4
#define S_NS2 5
#define S_CONV 6
#define S_INNOV 7
#define S_SVAR 8
#define S_NRESET 9
#define S_OUT 10
#define S_RLS_ERR 11
#define S_BK 12
#define S_NREJ 13
#define S_REJRUN 14
#define S_NREOPEN 15
#define S_ZREF 16
#define S_LO 17
#define S_HI 18
#define S_HOLD 19
#define S_NCLAMP 20
#define S_NHEAL 21
#define N_HEADER 22

/* method-specific block (lowpass delays, motion) at gd_layout_total(n) - N_EXT */
#define M_R 0
#define M_BK 1
#define M_HPOS 2
#define M_ANG 3
#define M_NW 4
#define M_BEST 5
#define M_PVAR 6
#define M_MABS 7
#define M_HIST (M_MABS + MO_MAX_NLAG)
#define M_BANK (M_HIST + 4 * MO_MAX_NLAG + 1) /* MO_MAX_NF rates, then the slopes, log-likelihoods, held flags,
                                                 the slopes' changes (j: 0 in a CV lane) */
#define M_LPD (M_BANK + 5 * MO_MAX_NF)  /* max_motion_hz: delays of the rigid-body low-pass */
#define MO_WU_AT M_LPD                   /* warm-up output's statistics (kernels.warmup_output; without the low-pass only) */
#define M_SPOS (M_LPD + 2 * MAX_SOS) /* spectral floor: position in the block */
#define M_SR (M_SPOS + 1)            /* spectral floor: smoothed R (0 = no block yet) */
#define M_SBK (M_SPOS + 2)           /* spectral floor: b^(blocks+1) */
#define M_SBAD (M_SPOS + 3)          /* spectral floor: 1 if the block holds a sample beyond MO_SPEC_ZMAX */
#define M_SFOLD (M_SPOS + 4)         /* spectral floor: the windowed block folded in two (N/2) */
#define M_GEFF (M_SFOLD + MO_SPEC_N / 2) /* pass-through: smoothed gain of the most likely filter */
#define M_NWC (M_GEFF + 1)           /* 1 once the growing-memory gains are below every filter's */
#define M_LRAT (M_NWC + 1)           /* line test: the last block's highest top bin x p[P_MO_SPEC] */
#define M_LON (M_NWC + 2)            /* line test: 1 while the last two blocks held a line (raw output) */
#define M_CUS (M_NWC + 3)            /* summed innovation per filter (MO_MAX_NF) */
#define M_SRH (M_CUS + MO_MAX_NF)    /* line test: its smoothed floor from the MO_HI_NB high bins (as M_SR) */
#define M_SBKH (M_SRH + 1)           /* line test: b^(blocks+1) of that floor (as M_SBK) */
#define M_GRD (M_SRH + 2)            /* output guard: faded (z - y)^2 / R of the bank's output */
#define M_BIAS (M_SRH + 3)           /* bias tracking: its GB_N doubles (gd_bias_t), the last of the state, kept by restarts */
#define N_EXT (M_BIAS + GB_N)
/* one_euro's state, the first floats of the method-specific block */
#define OE_X 0
#define OE_DX 1
#define OE_ZP 2

/* ---------------------------------------------------------------- layout */
typedef struct {
    long theta, prls, x, p, z, w, total;
} gd_layout_t;

/* offsets of (theta, P_rls, x, P, z_hist, w, total) for AR order n */
gd_layout_t gd_layout(int n);
long gd_layout_total(int n);

/* 0 if p (n_p doubles) and s (n_s doubles) fit together, else a static
 * one-line reason (the order must be an integer >= 1 and <= GD_MAX_ORDER). */
#define GD_MAX_ORDER 100000
const char *gd_check(const double *p, long n_p, long n_s);

/* --------------------------------------------------------------- kernels */
void gd_restart(const double *p, double *s);
double gd_rls_update(const double *p, double *s, double z);
double gd_kf_predict(const double *p, double *s, double q);
double gd_kf_update(const double *p, double *s, double v, double r);
void gd_start_filter(const double *p, double *s);
void gd_tie_c(const double *p, double *s);
int gd_ar_stable(const double *a, long o_a, int n, double *w, long o_w);
int gd_gate(const double *p, double *s, double z);
double gd_filter_step(const double *p, double *s, double z);
double gd_lowpass_step(const double *p, double *s, double z);
double gd_motion_step(const double *p, double *s, double z);
double gd_one_euro_step(const double *p, double *s, double z);
/* kernels.motion_params(fs) with its defaults into p[P_MO_NF ...] (the native FMU) */
void gd_motion_params(double *p, double fs);
/* kernels.butter_sos(order, cutoff_hz, fs) into p[P_SOS ...]; returns the number of sections */
int gd_butter_sos(int order, double cutoff_hz, double fs, double *p);
/* kernels.spectral_params(b, ratio) into p[P_MO_SPEC ...] (ratio < 0: off) */
void gd_spectral_params(double *p, double b, double ratio);
double gd_c_deg_s(const double *p, const double *s);
double gd_step(const double *p, double *s, double z, int is_restart);

/* the batch loop: out[i] = gd_step(p, s, z[i], restarts[i]) (restarts may be NULL) */
void gd_run(const double *p, double *s, const double *z, const unsigned char *restarts,
            double *out, long n);
/* gd_run, also trace[i] = s[trace_index] after sample i (0 <= trace_index < state length) */
void gd_run_trace(const double *p, double *s, const double *z, const unsigned char *restarts,
                  double *out, long n, long trace_index, double *trace);
/* the step loop with no restarts, also rec[j * n + i] = s[idx[j]] after sample i
 * (0 <= idx[j] < state length; the state values the offline smoother reads,
 * batch.smooth_motion) */
void gd_run_record(const double *p, double *s, const double *z, double *out, long n,
                   const long *idx, long m, double *rec);

#ifdef __cplusplus
}
#endif
#endif /* GDCORE_H */
