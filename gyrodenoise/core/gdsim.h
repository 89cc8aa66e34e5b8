/*
 * gdsim.h -- the simulated gyro of a model card, in portable C99 (libm only).
 *
 * The one implementation of the sensor model: gyrodenoise.simulate (through the
 * extension gyrodenoise.core._gdcore), the pythonfmu SimulatedFog.fmu (the same
 * extension, bundled) and SimulatedFogNative.fmu (compiled in) all call it.
 * gyrodenoise/core/simkernels.py is the same functions in plain Python (the
 * executable specification and the fallback without a compiler; tested equal).
 *
 * Conventions of gyrodenoise/simulator.py (IEEE Std 952-1997, Annex C), per sample
 * k with T = 1 / sample_rate_hz, t = k T, t_r = T (samples since the last restart):
 *   y_k = true_k + noise_k + det_k
 *   noise_k = N_arw w1 + (Q w0_k - Q w0_{k-1}) / T + sum_j x_j,k + sum_i (th_i,k - th_i,k-1) / T
 *   x_j,k = a_j x_j,k-1 + g_j w_(2+j)      (flicker bank, Gauss-Markov, rate random walk)
 *   th_i,k = b_i th_i,k-1 + sigma_i sqrt(1 - b_i^2) v_i,k, b_i = exp(-T / tau_i)
 *                                          (angle Gauss-Markov: a correlated ANGLE noise, differenced)
 *   det_k = bias + R t + A exp(-t_r / tau) + sum_i amp_i sin(2 pi f_i t + phase_i)
 * with w ~ N(0, 1) drawn in this order each sample from one generator, the
 * turn-on bias repeatability drawn from a second one (at the start and at each
 * restart), and the angle Gauss-Markov normals v from a third (so a card
 * without that term draws exactly the numbers it drew before the term existed,
 * and adding the term leaves the other terms' realisations unchanged).
 *
 * Generator: xoshiro256** (Blackman and Vigna 2018), seeded by splitmix64 from
 * (seed, stream); normal deviates by Marsaglia's polar method (one per pair of
 * uniforms, the second discarded), uniforms from the top 53 bits. Integer
 * arithmetic only, except log and sqrt in the polar method: the same numbers on
 * every platform (to the last bit where libm's log is correctly rounded).
 *
 * Buffers, as in gdcore.h: p (parameters, gd_sim_n_params doubles) from
 * gd_sim_params, s (state, gd_sim_n_state doubles). Each 64-bit generator word
 * is kept as two doubles holding 32 bits each (exact), so the state is a plain
 * float64 array (serializable as text, portable).
 */
#ifndef GDSIM_H
#define GDSIM_H

#ifdef __cplusplus
extern "C" {
#endif

#define GD_SIM_MAX_REPEAT 16 /* gauss_markov and sinusoid terms, each */

/* a model card's numbers, in the card's units (spec section 4); absent term = 0 */
typedef struct {
    double sample_rate_hz;
    double Q;                        /* quantization, deg */
    double N;                        /* angle random walk, deg/sqrt(h) */
    double B;                        /* bias instability, deg/h */
    double K;                        /* rate random walk, deg/h^1.5 */
    double R;                        /* rate ramp, deg/h^2 */
    double bias, bias_rep;           /* constant bias and its repeatability, deg/h */
    double tr_amp, tr_tau;           /* turn-on transient, deg/h and s (tau 1 when absent) */
    int n_gm;
    double gm_sigma[GD_SIM_MAX_REPEAT], gm_tau[GD_SIM_MAX_REPEAT];          /* deg/h, s */
    int n_sin;
    double sin_amp[GD_SIM_MAX_REPEAT], sin_f[GD_SIM_MAX_REPEAT], sin_phase_deg[GD_SIM_MAX_REPEAT];
    int n_agm;                       /* angle Gauss-Markov terms (added last: a zeroed struct has none) */
    double agm_sigma[GD_SIM_MAX_REPEAT], agm_tau[GD_SIM_MAX_REPEAT];        /* deg, s */
} gd_card_t;

/* parameters p[] */
#define PS_T 0           /* sample period, s */
#define PS_NBANK 1       /* AR(1) channels in the bank */
#define PS_NSIN 2
#define PS_Q 3           /* deg */
#define PS_ARW 4         /* white rate noise std per sample, deg/s */
#define PS_BIAS0 5       /* deg/s */
#define PS_BIASREP 6     /* deg/s */
#define PS_TRAMP 7       /* deg/s */
#define PS_TRTAU 8       /* s */
#define PS_RAMP 9        /* deg/s^2 */
#define PS_SEED_HI 10    /* seed, two 32-bit halves */
#define PS_SEED_LO 11
#define PS_BANK 12       /* n_bank x (a, g, stationary std), then n_sin x (amp deg/s, f Hz, phase rad),
                            then n_agm, then n_agm x (b, sigma sqrt(1 - b^2), sigma) in deg */

/* state s[] */
#define SS_RNG 0         /* noise generator: 4 words x 2 halves */
#define SS_RNG_RESTART 8 /* turn-on bias generator */
#define SS_WPREV 16      /* last quantization angle, deg */
#define SS_K 17          /* samples since the start */
#define SS_KR 18         /* samples since the last restart */
#define SS_BIAS 19       /* bias in force, deg/s */
#define SS_X 20          /* bank states, deg/s; then, only when n_agm > 0, the angle Gauss-Markov
                            generator (8 halves) and the n_agm angles, deg */

/* the flicker bank: poles from 1e-5 Hz to Nyquist, 3 per decade */
#define GD_SIM_FLICKER_F_LO_HZ 1.0e-5
#define GD_SIM_FLICKER_POLES_PER_DECADE 3

/* the card vector (simkernels.card_vector): GD_SIM_CARD_LEN doubles, or GD_SIM_CARD_LEN_V1
 * (written before the angle Gauss-Markov term: no such term) */
#define GD_SIM_CARD_LEN_V1 (12 + 5 * GD_SIM_MAX_REPEAT)
#define GD_SIM_CARD_LEN (GD_SIM_CARD_LEN_V1 + 1 + 2 * GD_SIM_MAX_REPEAT)
/* v (n doubles, n = GD_SIM_CARD_LEN or GD_SIM_CARD_LEN_V1) into *card; the counts are cast,
 * not checked: the caller validates the vector first */
void gd_sim_card_from_vector(const double *v, int n, gd_card_t *card);

int gd_sim_n_bank(const gd_card_t *card);
int gd_sim_n_params(const gd_card_t *card);
int gd_sim_n_state(const double *p);
/* fill p (gd_sim_n_params(card) doubles) from the card and the seed (< 2^53) */
void gd_sim_params(const gd_card_t *card, double seed, double *p);
/* the state at the start (seeded generators, stationary bank, first bias draw) */
void gd_sim_reset(const double *p, double *s);
/* one measured sample, deg/s */
double gd_sim_step(const double *p, double *s, double true_rate_deg_s, int restart);
/* n samples: out[i] = gd_sim_step(p, s, truth ? truth[i] : 0, restarts ? restarts[i] : 0) */
void gd_sim_run(const double *p, double *s, long n, const double *truth, const unsigned char *restarts,
                double *out);

#ifdef __cplusplus
}
#endif
#endif
