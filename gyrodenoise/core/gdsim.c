/*
 * gdsim.c -- the simulated gyro of a model card (see gdsim.h for the model, the
 * generator and the buffers). gyrodenoise/core/simkernels.py is the same code in
 * plain Python, operation for operation (tested equal).
 *
 * Compile with -ffp-contract=off and without -ffast-math (as gdcore.c).
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "gdsim.h"

static const double PI = 3.141592653589793;  /* math.pi */

/* ---------------------------------------------------------------- generator */
static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static void load(const double *h, uint64_t w[4]) {
    int i;
    for (i = 0; i < 4; i++) w[i] = ((uint64_t)h[2 * i] << 32) | (uint64_t)h[2 * i + 1];
}

static void store(const uint64_t w[4], double *h) {
    int i;
    for (i = 0; i < 4; i++) {
        h[2 * i] = (double)(w[i] >> 32);
        h[2 * i + 1] = (double)(w[i] & 0xFFFFFFFFULL);
    }
}

/* xoshiro256** */
static uint64_t next_u64(uint64_t w[4]) {
    uint64_t result = rotl(w[1] * 5, 7) * 9, t = w[1] << 17;
    w[2] ^= w[0];
    w[3] ^= w[1];
    w[1] ^= w[2];
    w[0] ^= w[3];
    w[2] ^= t;
    w[3] = rotl(w[3], 45);
    return result;
}

/* uniform in [0, 1) from the top 53 bits */
static double uniform(uint64_t w[4]) { return (double)(next_u64(w) >> 11) * (1.0 / 9007199254740992.0); }

/* standard normal, Marsaglia's polar method */
static double normal(uint64_t w[4]) {
    double u, v, q;
    do {
        u = 2.0 * uniform(w) - 1.0;
        v = 2.0 * uniform(w) - 1.0;
        q = u * u + v * v;
    } while (q >= 1.0 || q == 0.0);
    return u * sqrt(-2.0 * log(q) / q);
}

/* generator `stream` (0: noise, 1: turn-on bias, 2: angle Gauss-Markov) of `seed`, into 8 halves */
static void seed_stream(double seed, int stream, double *h) {
    static const uint64_t key[3] = {0ULL, 0x5851F42D4C957F2DULL, 0xD1B54A32D192ED03ULL};
    uint64_t x = (uint64_t)seed ^ key[stream], w[4];
    int i;
    for (i = 0; i < 4; i++) w[i] = splitmix64(&x);
    store(w, h);
}

/* --------------------------------------------------------------- parameters */
static int n_flicker(const gd_card_t *c) {
    double n_dec;
    int n;
    if (!(c->B > 0)) return 0;
    n_dec = log10(0.5 * c->sample_rate_hz / GD_SIM_FLICKER_F_LO_HZ);
    n = (int)ceil(n_dec * GD_SIM_FLICKER_POLES_PER_DECADE);
    return n < 1 ? 1 : n;
}

void gd_sim_card_from_vector(const double *v, int n, gd_card_t *c)
{
    int i, M = GD_SIM_MAX_REPEAT;
    memset(c, 0, sizeof *c);
    c->sample_rate_hz = v[0];
    c->Q = v[1];
    c->N = v[2];
    c->B = v[3];
    c->K = v[4];
    c->R = v[5];
    c->bias = v[6];
    c->bias_rep = v[7];
    c->tr_amp = v[8];
    c->tr_tau = v[9];
    c->n_gm = (int)v[10];
    c->n_sin = (int)v[11];
    for (i = 0; i < M; i++) {
        c->gm_sigma[i] = v[12 + i];
        c->gm_tau[i] = v[12 + M + i];
        c->sin_amp[i] = v[12 + 2 * M + i];
        c->sin_f[i] = v[12 + 3 * M + i];
        c->sin_phase_deg[i] = v[12 + 4 * M + i];
    }
    if (n < GD_SIM_CARD_LEN)
        return;
    c->n_agm = (int)v[GD_SIM_CARD_LEN_V1];
    for (i = 0; i < M; i++) {
        c->agm_sigma[i] = v[GD_SIM_CARD_LEN_V1 + 1 + i];
        c->agm_tau[i] = v[GD_SIM_CARD_LEN_V1 + 1 + M + i];
    }
}

int gd_sim_n_bank(const gd_card_t *c) {
    int i, n = n_flicker(c);
    for (i = 0; i < c->n_gm; i++)
        if (c->gm_sigma[i] > 0) n++;
    if (c->K > 0) n++;
    return n;
}

static int n_agm(const gd_card_t *c) {
    int i, n = 0;
    for (i = 0; i < c->n_agm; i++)
        if (c->agm_sigma[i] > 0) n++;
    return n;
}

int gd_sim_n_params(const gd_card_t *c) {
    return PS_BANK + 3 * gd_sim_n_bank(c) + 3 * c->n_sin + 1 + 3 * n_agm(c);
}

/* index in p of the angle Gauss-Markov count (its terms follow) */
static int agm_at(const double *p) { return PS_BANK + 3 * (int)p[PS_NBANK] + 3 * (int)p[PS_NSIN]; }

int gd_sim_n_state(const double *p) {
    int na = (int)p[agm_at(p)];
    return SS_X + (int)p[PS_NBANK] + (na > 0 ? 8 + na : 0);
}

/* simulator._bank and SimStream.__init__ of the Python model, in the same operations */
void gd_sim_params(const gd_card_t *c, double seed, double *p) {
    const double deg_h = 1.0 / 3600.0, deg_rth = 1.0 / 60.0, deg_h15 = 1.0 / pow(3600.0, 1.5),
                 deg_h2 = 1.0 / pow(3600.0, 2.0);
    double T = 1.0 / c->sample_rate_hz, *b = p + PS_BANK;
    int j, i, nb = 0, nf = n_flicker(c);
    uint64_t sd = (uint64_t)seed;
    if (nf > 0) { /* flicker: first-order Gauss-Markov poles, 3 per decade, Allan plateau 0.664 B */
        double B = c->B * deg_h, f_hi = 0.5 * c->sample_rate_hz;
        double delta = log(f_hi / GD_SIM_FLICKER_F_LO_HZ) / nf, var = B * B * delta / PI;
        for (j = 0; j < nf; j++) {
            double fj = GD_SIM_FLICKER_F_LO_HZ * exp((j + 0.5) * delta);
            double aj = exp(-2.0 * PI * fj * T);
            b[3 * nb] = aj;
            b[3 * nb + 1] = sqrt(var * (1.0 - aj * aj));
            b[3 * nb + 2] = sqrt(var);
            nb++;
        }
    }
    for (i = 0; i < c->n_gm; i++) {
        if (c->gm_sigma[i] > 0) {
            double aj = exp(-T / c->gm_tau[i]), s = c->gm_sigma[i] * deg_h;
            b[3 * nb] = aj;
            b[3 * nb + 1] = s * sqrt(1.0 - aj * aj);
            b[3 * nb + 2] = s;
            nb++;
        }
    }
    if (c->K > 0) { /* rate random walk: a = 1, starts at 0 */
        b[3 * nb] = 1.0;
        b[3 * nb + 1] = c->K * deg_h15 * sqrt(T);
        b[3 * nb + 2] = 0.0;
        nb++;
    }
    p[PS_T] = T;
    p[PS_NBANK] = (double)nb;
    p[PS_NSIN] = (double)c->n_sin;
    p[PS_Q] = c->Q;
    p[PS_ARW] = c->N * deg_rth / sqrt(T);
    p[PS_BIAS0] = c->bias * deg_h;
    p[PS_BIASREP] = c->bias_rep * deg_h;
    p[PS_TRAMP] = c->tr_amp * deg_h;
    p[PS_TRTAU] = c->tr_tau;
    p[PS_RAMP] = c->R * deg_h2;
    p[PS_SEED_HI] = (double)(sd >> 32);
    p[PS_SEED_LO] = (double)(sd & 0xFFFFFFFFULL);
    for (i = 0; i < c->n_sin; i++) {
        b[3 * nb + 3 * i] = c->sin_amp[i] * deg_h;
        b[3 * nb + 3 * i + 1] = c->sin_f[i];
        b[3 * nb + 3 * i + 2] = c->sin_phase_deg[i] * (PI / 180.0); /* math.radians */
    }
    b += 3 * nb + 3 * c->n_sin;
    b[0] = (double)n_agm(c);
    for (i = 0, j = 0; i < c->n_agm; i++) { /* angle Gauss-Markov: b = exp(-T / tau), angles in deg */
        if (c->agm_sigma[i] > 0) {
            double aj = exp(-T / c->agm_tau[i]), s = c->agm_sigma[i];
            b[1 + 3 * j] = aj;
            b[1 + 3 * j + 1] = s * sqrt(1.0 - aj * aj);
            b[1 + 3 * j + 2] = s;
            j++;
        }
    }
}

/* -------------------------------------------------------------------- model */
static double draw_bias(const double *p, double *s) {
    uint64_t w[4];
    double v;
    if (p[PS_BIASREP] == 0.0) return p[PS_BIAS0];
    load(s + SS_RNG_RESTART, w);
    v = p[PS_BIAS0] + p[PS_BIASREP] * normal(w);
    store(w, s + SS_RNG_RESTART);
    return v;
}

void gd_sim_reset(const double *p, double *s) {
    double seed = p[PS_SEED_HI] * 4294967296.0 + p[PS_SEED_LO];
    int j, nb = (int)p[PS_NBANK];
    uint64_t w[4];
    seed_stream(seed, 0, s + SS_RNG);
    seed_stream(seed, 1, s + SS_RNG_RESTART);
    load(s + SS_RNG, w);
    for (j = 0; j < nb; j++) s[SS_X + j] = p[PS_BANK + 3 * j + 2] * normal(w); /* stationary start */
    s[SS_WPREV] = p[PS_Q] * normal(w);
    store(w, s + SS_RNG);
    s[SS_K] = 0.0;
    s[SS_KR] = 0.0;
    s[SS_BIAS] = draw_bias(p, s);
    {   /* angle Gauss-Markov: its own generator, stationary start */
        const double *ag = p + agm_at(p);
        int na = (int)ag[0];
        double *sa = s + SS_X + nb;
        if (na > 0) {
            seed_stream(seed, 2, sa);
            load(sa, w);
            for (j = 0; j < na; j++) sa[8 + j] = ag[1 + 3 * j + 2] * normal(w);
            store(w, sa);
        }
    }
}

double gd_sim_step(const double *p, double *s, double true_rate_deg_s, int restart) {
    const double T = p[PS_T], *bank = p + PS_BANK;
    int j, nb = (int)p[PS_NBANK], ns = (int)p[PS_NSIN];
    double w0, w1, noise, t, tr, det;
    uint64_t w[4];
    if (restart && s[SS_K] > 0) {
        s[SS_KR] = 0.0;
        s[SS_BIAS] = draw_bias(p, s);
    }
    load(s + SS_RNG, w);
    w0 = normal(w);
    w1 = normal(w);
    noise = p[PS_ARW] * w1;
    if (p[PS_Q] > 0) {
        double ang = p[PS_Q] * w0;
        noise = noise + (ang - s[SS_WPREV]) / T;
        s[SS_WPREV] = ang;
    }
    if (nb > 0) {
        double sum = 0.0;
        for (j = 0; j < nb; j++) {
            s[SS_X + j] = bank[3 * j] * s[SS_X + j] + bank[3 * j + 1] * normal(w);
            sum = sum + s[SS_X + j];
        }
        noise = noise + sum;
    }
    store(w, s + SS_RNG);
    {   /* angle Gauss-Markov, differenced / T */
        const double *ag = bank + 3 * nb + 3 * ns;
        int na = (int)ag[0];
        double *sa = s + SS_X + nb;
        if (na > 0) {
            double sum = 0.0;
            load(sa, w);
            for (j = 0; j < na; j++) {
                double th = ag[1 + 3 * j] * sa[8 + j] + ag[1 + 3 * j + 1] * normal(w);
                sum = sum + (th - sa[8 + j]) / T;
                sa[8 + j] = th;
            }
            store(w, sa);
            noise = noise + sum;
        }
    }
    t = s[SS_K] * T;
    tr = s[SS_KR] * T;
    det = s[SS_BIAS] + p[PS_RAMP] * t;
    if (p[PS_TRAMP] != 0.0) det = det + p[PS_TRAMP] * exp(-tr / p[PS_TRTAU]);
    for (j = 0; j < ns; j++) {
        const double *sn = bank + 3 * nb + 3 * j;
        det = det + sn[0] * sin(2.0 * PI * sn[1] * t + sn[2]);
    }
    s[SS_K] = s[SS_K] + 1.0;
    s[SS_KR] = s[SS_KR] + 1.0;
    return true_rate_deg_s + noise + det;
}

void gd_sim_run(const double *p, double *s, long n, const double *truth, const unsigned char *restarts,
                double *out) {
    long i;
    for (i = 0; i < n; i++)
        out[i] = gd_sim_step(p, s, truth ? truth[i] : 0.0, restarts ? restarts[i] != 0 : 0);
}
