/*
 * simulatedfog_native.c -- SimulatedFogNative: the model-card gyro as a native FMI 2.0
 * co-simulation slave (no Python, no libpython; C99 + libm).
 *
 * One communication step is one sample. The sample at the start time is taken at
 * fmi2ExitInitializationMode from the inputs set before it (measured_rate and restarted
 * are initial="calculated": valid from then on, so a Jacobi master passes the sensor's
 * sample 0 to the next FMU at the first step, not a placeholder); each fmi2DoStep takes
 * the sample at the end of the step from the inputs set before it (FMI 2.0: inputs held
 * over the step, outputs valid at its end): set true_rate (and restart), call
 * fmi2DoStep, read measured_rate (= true_rate + the sensor errors of the card) and
 * restarted. Sample k (gyrodenoise.simulate's k-th) is the output at t = k h; the pythonfmu
 * SimulatedFog.fmu follows the same convention. The numbers come from the project's sensor model
 * (gyrodenoise/core/gdsim.c, gd_sim_step), the same C that gyrodenoise.simulate and
 * the pythonfmu SimulatedFog.fmu run: same card and seed, same numbers. This file is
 * the model's hooks for the shared FMI layer (gdfmi.h / gdfmi.c).
 *
 * The card. The parameter `card` is, as for SimulatedFog.fmu, the name of a card
 * bundled in the FMU (default paper_fog), a card file path, or the card's text; but
 * TOML is read by gyrodenoise in Python, so here a card is *compiled*: its card
 * vector (gyrodenoise.core.simkernels.card_vector, card units), one field a line,
 * each value as the 16 hex digits of its IEEE 754 bits (exact on every platform,
 * whatever the C library's strtod), then the decimal value as a comment:
 *
 *     gdcard 1 125
 *     sample_rate_hz 0x4069000000000000 200.0
 *     Q 0x3ee84107b8a9d2b8 1.1565e-05
 *     ...
 *
 * The same fields may be given on one line, separated by '|' (no comment lines):
 *
 *     gdcard 1 125 | sample_rate_hz 0x4069000000000000 200.0 | Q 0x3ee84107b8a9d2b8 1.1565e-05 | ...
 *
 * `gyrodenoise fmu build` compiles the bundled cards into resources/cards/NAME.gdcard;
 * `gyrodenoise fmu card CARD.toml [--one-line]` compiles any card (gyrodenoise.fmu.simnative.
 * compile_card); the SSP writer binds a bundled card's name, any other card on one line.
 * A TOML card given here is refused at fmi2ExitInitializationMode with the reason and the
 * command to use.
 *
 * The value references, the GUID, the start values and the card's field names come
 * from simulatedfog_native_vars.h, generated from one table (gyrodenoise/fmu/simnative.py).
 *
 * Compile: gcc -O2 -ffp-contract=off -std=c99 -fPIC -shared -fvisibility=hidden
 *          -DGD_LIBM_LINKED simulatedfog_native_all.c -lm
 */
#include "gdfmi.h"
#include "gdsim.h"
#include "simulatedfog_native_vars.h"

#define SERIAL_VERSION 1u
#define CARD_LEN 8192           /* the card parameter's buffer, terminating NUL included */
#define CARD_FILE_MAX 65536     /* a compiled card file larger than this is refused */

/* the model's fixed-size part (m); s holds the model's parameters p (np doubles) then its
 * state (gd_sim_n_state(p) doubles) */
typedef struct {
    int32_t restart, restarted, seed, strict_step_size; /* inputs, outputs, parameters */
    int32_t np, pad_;
    double true_rate, measured_rate;
    double v[GD_CARD_LEN]; /* the card in force (card vector), read at fmi2ExitInitializationMode */
    char card[CARD_LEN];
} sf_t;

static const gdfmi_var_t vars[GD_N_VARS] = GD_VARIABLE_TABLE;
static const char *const card_fields[GD_CARD_LEN] = GD_CARD_FIELDS;

static void sf_defaults(void *mv) {
    sf_t *d = (sf_t *)mv;
    d->true_rate = START_true_rate;
    d->restart = START_restart;
    d->measured_rate = 0.0; /* initial="calculated": the first sample, at fmi2ExitInitializationMode */
    d->restarted = 0;
    d->seed = START_seed;
    d->strict_step_size = START_strict_step_size;
    strcpy(d->card, START_card);
}

/* ------------------------------------------------------------------ the card */
/* the checks of simulator.parse_card that the numbers themselves carry */
static int check_vector(const double *v, char *err, size_t nerr) {
    const double absurd = 1.0e9;
    int i, R = GD_SIM_MAX_REPEAT, n_gm, n_sin, n_agm;
    const double *agm = v + 12 + 5 * R; /* n_agm, agm_sigma x R (deg), agm_tau x R (s) */
    for (i = 0; i < GD_CARD_LEN; i++)
        if (!isfinite(v[i]) || fabs(v[i]) > absurd)
            return gdfmi_fmt_err(err, nerr, "card field %s is not a usable number: %.17g", card_fields[i], v[i]);
    if (!(v[0] > 0))
        return gdfmi_fmt_err(err, nerr, "card field sample_rate_hz must be > 0 Hz, got %.17g", v[0]);
    for (i = 1; i <= 4; i++) /* Q, N, B, K */
        if (v[i] < 0)
            return gdfmi_fmt_err(err, nerr, "card field %s must be >= 0, got %.17g", card_fields[i], v[i]);
    if (v[7] < 0)
        return gdfmi_fmt_err(err, nerr, "card field bias_rep must be >= 0, got %.17g", v[7]);
    if (!(v[9] > 0))
        return gdfmi_fmt_err(err, nerr, "card field tr_tau must be > 0 s, got %.17g", v[9]);
    if (!(v[10] >= 0 && v[10] <= R && v[10] == floor(v[10])) || !(v[11] >= 0 && v[11] <= R && v[11] == floor(v[11])))
        return gdfmi_fmt_err(err, nerr, "card fields n_gm and n_sin must be whole numbers 0..%d, got %g and %g",
                             R, v[10], v[11]);
    if (!(agm[0] >= 0 && agm[0] <= R && agm[0] == floor(agm[0])))
        return gdfmi_fmt_err(err, nerr, "card field n_agm must be a whole number 0..%d, got %g", R, agm[0]);
    n_gm = (int)v[10];
    n_sin = (int)v[11];
    n_agm = (int)agm[0];
    for (i = 0; i < n_agm; i++)
        if (agm[1 + i] < 0 || !(agm[1 + R + i] > 0))
            return gdfmi_fmt_err(err, nerr, "card angle_gauss_markov %d: sigma must be >= 0 deg and tau > 0 s, "
                                 "got %g, %g", i + 1, agm[1 + i], agm[1 + R + i]);
    for (i = 0; i < n_gm; i++)
        if (v[12 + i] < 0 || !(v[12 + R + i] > 0))
            return gdfmi_fmt_err(err, nerr, "card gauss_markov %d: sigma must be >= 0 and tau > 0 s, got %g, %g",
                                 i + 1, v[12 + i], v[12 + R + i]);
    for (i = 0; i < n_sin; i++)
        if (v[12 + 3 * R + i] < 0 || v[12 + 3 * R + i] > 0.5 * v[0])
            return gdfmi_fmt_err(err, nerr, "card sinusoid %d: frequency %g Hz must be in 0..Nyquist (%g Hz)",
                                 i + 1, v[12 + 3 * R + i], 0.5 * v[0]);
    return 0;
}

static int hex_digit(int ch) {
    if (ch >= '0' && ch <= '9') return ch - '0';
    if (ch >= 'a' && ch <= 'f') return ch - 'a' + 10;
    if (ch >= 'A' && ch <= 'F') return ch - 'A' + 10;
    return -1;
}

/* the compiled card's text into v: 0, or -1 with the reason */
static int parse_compiled(const char *text, const char *what, double *v, char *err, size_t nerr) {
    const char *p = text;
    int line = 0, field = -1; /* -1: header expected */
    /* the one-line form (a '|' on the header's line): its fields separated by '|' */
    const char *nl = strchr(text, '\n'), *bar = strchr(text, '|');
    const char sep = bar != NULL && (nl == NULL || bar < nl) ? '|' : '\n';
    while (*p) {
        const char *eol = p, *q, *name;
        size_t nlen;
        line++;
        while (*eol && *eol != '\n' && *eol != sep) eol++;
        q = p;
        while (q < eol && (*q == ' ' || *q == '\t' || *q == '\r')) q++;
        if (q == eol || *q == '#') { /* blank or comment */
            p = *eol ? eol + 1 : eol;
            continue;
        }
        if (field < 0) {
            char head[64];
            int version = 0, n = 0;
            size_t len = (size_t)(eol - q) < sizeof head - 1 ? (size_t)(eol - q) : sizeof head - 1;
            memcpy(head, q, len);
            head[len] = '\0';
            if (sscanf(head, "gdcard %d %d", &version, &n) != 2)
                return gdfmi_fmt_err(err, nerr, "%s: not a compiled card (first line must be 'gdcard 1 %d'); "
                                     "a TOML card is compiled by gyrodenoise: gyrodenoise fmu card CARD.toml",
                                     what, GD_CARD_LEN);
            if (version != 1 || n != GD_CARD_LEN)
                return gdfmi_fmt_err(err, nerr, "%s: compiled card format %d with %d fields, this FMU reads "
                                     "format 1 with %d: compile the card again with this gyrodenoise "
                                     "(gyrodenoise fmu card)", what, version, n, GD_CARD_LEN);
            field = 0;
        } else {
            uint64_t bits = 0;
            int k;
            if (field >= GD_CARD_LEN)
                return gdfmi_fmt_err(err, nerr, "%s line %d: more than the %d fields of a card", what, line,
                                     GD_CARD_LEN);
            name = q;
            while (q < eol && *q != ' ' && *q != '\t') q++;
            nlen = (size_t)(q - name);
            if (nlen != strlen(card_fields[field]) || strncmp(name, card_fields[field], nlen) != 0)
                return gdfmi_fmt_err(err, nerr, "%s line %d: field %s expected, got '%.*s'", what, line,
                                     card_fields[field], (int)(nlen < 40 ? nlen : 40), name);
            while (q < eol && (*q == ' ' || *q == '\t')) q++;
            if (eol - q < 18 || q[0] != '0' || (q[1] | 32) != 'x')
                return gdfmi_fmt_err(err, nerr, "%s line %d: %s: expected 0x and the 16 hex digits of the "
                                     "value's IEEE 754 bits", what, line, card_fields[field]);
            for (k = 2; k < 18; k++) {
                int h = hex_digit((unsigned char)q[k]);
                if (h < 0)
                    return gdfmi_fmt_err(err, nerr, "%s line %d: %s: '%c' is not a hex digit", what, line,
                                         card_fields[field], q[k]);
                bits = (bits << 4) | (uint64_t)h;
            }
            if (q + 18 < eol && q[18] != ' ' && q[18] != '\t' && q[18] != '\r')
                return gdfmi_fmt_err(err, nerr, "%s line %d: %s: more than 16 hex digits", what, line,
                                     card_fields[field]);
            memcpy(&v[field], &bits, 8);
            field++;
        }
        p = *eol ? eol + 1 : eol;
    }
    if (field < 0) return gdfmi_fmt_err(err, nerr, "%s: empty card", what);
    if (field != GD_CARD_LEN)
        return gdfmi_fmt_err(err, nerr, "%s: %d of the %d card fields (the first missing: %s)", what, field,
                             GD_CARD_LEN, card_fields[field]);
    return check_vector(v, err, nerr);
}

/* a whole file into a buffer (allocated with the instance's callbacks), or NULL */
static char *read_file(const gdfmi_inst_t *c, const char *path) {
    FILE *f = fopen(path, "rb");
    char *buf;
    size_t n;
    if (!f) return NULL;
    buf = (char *)gdfmi_alloc(c, CARD_FILE_MAX + 1, 1);
    if (buf) {
        n = fread(buf, 1, CARD_FILE_MAX + 1, f);
        if (n > CARD_FILE_MAX) {
            gdfmi_free(c, buf);
            buf = NULL;
        } else {
            buf[n] = '\0';
        }
    }
    fclose(f);
    return buf;
}

static int looks_like_toml(const char *a, const char *e) {
    for (; a < e; a++)
        if (*a == '[' || *a == '=') return 1;
    return 0;
}

static int toml_refused(char *err, size_t nerr) {
    return gdfmi_fmt_err(err, nerr, "card: TOML text cannot be read by %s (no Python at run time): compile it "
                         "with 'gyrodenoise fmu card CARD.toml' and give the compiled text or file, or a bundled "
                         "card name (%s)", GD_MODEL_IDENTIFIER, GD_BUNDLED_CARDS);
}

/* The card parameter into v, as SimulatedFog.fmu reads it: text (several lines), a file
 * path, or the name of a bundled card (resources/cards/NAME.gdcard); several lines or a line
 * that is not a file and looks like TOML ('[' or '='): TOML, refused. 0, or -1 + reason. */
static int resolve_card(const gdfmi_inst_t *c, const char *card, double *v, char *err, size_t nerr) {
    const char *a, *e;
    char name[512], rel[600], path[4600], why[600];
    char *text;
    size_t len;
    int rc;
    FILE *probe;
    gdfmi_strip(card, &a, &e);
    len = (size_t)(e - a);
    if (len >= 6 && strncmp(a, "gdcard", 6) == 0) return parse_compiled(a, "card text", v, err, nerr);
    if (len == 0) return gdfmi_fmt_err(err, nerr, "card is empty (bundled cards: %s)", GD_BUNDLED_CARDS);
    if (memchr(a, '\n', len) != NULL) return toml_refused(err, nerr);
    if (len >= sizeof name) return gdfmi_fmt_err(err, nerr, "card: a name or path of %lu characters is too "
                                                 "long", (unsigned long)len);
    memcpy(name, a, len);
    name[len] = '\0';
    probe = fopen(name, "rb");
    if (probe) { /* a file path */
        fclose(probe);
        text = read_file(c, name);
        if (!text) return gdfmi_fmt_err(err, nerr, "card %s: cannot read it (or larger than %d bytes)", name,
                                        CARD_FILE_MAX);
        rc = parse_compiled(text, name, v, err, nerr);
        gdfmi_free(c, text);
        return rc;
    }
    if (looks_like_toml(a, e)) return toml_refused(err, nerr); /* one line of TOML, not a file */
    { /* a bundled card: its name, or a file name whose stem is one */
        const char *base = name, *s;
        size_t blen;
        for (s = name; *s; s++)
            if (*s == '/' || *s == '\\') base = s + 1;
        blen = strlen(base);
        if (blen > 5 && strcmp(base + blen - 5, ".toml") == 0) blen -= 5;
        else if (blen > 7 && strcmp(base + blen - 7, ".gdcard") == 0) blen -= 7;
        snprintf(rel, sizeof rel, "cards/%.*s.gdcard", (int)blen, base);
    }
    if (gdfmi_resource_path(c, rel, path, sizeof path, why, sizeof why) != 0)
        return gdfmi_fmt_err(err, nerr, "card '%s': no such file, and no bundled card: %s", name, why);
    text = read_file(c, path);
    if (!text)
        return gdfmi_fmt_err(err, nerr, "card '%s': no such file and no such bundled card (%s; bundled: %s)",
                             name, path, GD_BUNDLED_CARDS);
    rc = parse_compiled(text, path, v, err, nerr);
    gdfmi_free(c, text);
    return rc;
}

/* ------------------------------------------------------------------ hooks */
static long sf_build(gdfmi_inst_t *c, char *err, size_t nerr) {
    sf_t *d = (sf_t *)c->m;
    gd_card_t card;
    double *p;
    long n_state;
    if (d->seed < 0) return gdfmi_fmt_err(err, nerr, "seed must be an integer >= 0, got %d", (int)d->seed);
    if (!isfinite(d->true_rate)) /* the first sample is taken at fmi2ExitInitializationMode */
        return gdfmi_fmt_err(err, nerr, "true_rate is %g: the first sample (taken at "
                             GD_FN("ExitInitializationMode") ") needs a finite true rate", d->true_rate);
    if (resolve_card(c, d->card, d->v, err, nerr) != 0) return -1;
    gd_sim_card_from_vector(d->v, GD_CARD_LEN, &card);
    d->np = gd_sim_n_params(&card);
    p = (double *)gdfmi_alloc(c, (size_t)d->np, sizeof(double));
    if (!p) return gdfmi_fmt_err(err, nerr, "out of memory");
    gd_sim_params(&card, (double)d->seed, p);
    n_state = gd_sim_n_state(p);
    gdfmi_free(c, p);
    return (long)d->np + n_state;
}

static void sf_start(gdfmi_inst_t *c) {
    sf_t *d = (sf_t *)c->m;
    gd_card_t card;
    gd_sim_card_from_vector(d->v, GD_CARD_LEN, &card);
    gd_sim_params(&card, (double)d->seed, c->s);
    gd_sim_reset(c->s, c->s + d->np);
    /* the sample at the start time, from the inputs set during initialisation: measured_rate
     * is valid from fmi2ExitInitializationMode on (a Jacobi master passes it on before the
     * first step), and each step produces the sample at its end */
    d->measured_rate = gd_sim_step(c->s, c->s + d->np, d->true_rate, d->restart ? 1 : 0);
    d->restarted = d->restart ? 1 : 0;
}

static double sf_period(const void *m) { return 1.0 / ((const sf_t *)m)->v[0]; }

static int sf_strict(const void *m) { return ((const sf_t *)m)->strict_step_size; }

static gd_status_t sf_step(gdfmi_inst_t *c, double t) {
    sf_t *d = (sf_t *)c->m;
    double w = d->true_rate;
    if (!isfinite(w))
        return gdfmi_fail(c, GD_FN("DoStep") ": true_rate is %g at t=%.17g s; sample refused, sensor state "
                          "unchanged", w, t);
    d->measured_rate = gd_sim_step(c->s, c->s + d->np, w, d->restart ? 1 : 0);
    d->restarted = d->restart ? 1 : 0;
    return GD_OK;
}

static double sf_get_real(const gdfmi_inst_t *c, gd_vr_t vr) {
    const sf_t *d = (const sf_t *)c->m;
    return vr == VR_true_rate ? d->true_rate : d->measured_rate;
}

static double *sf_real_ref(void *m, gd_vr_t vr) {
    (void)vr; /* the only settable Real: true_rate */
    return &((sf_t *)m)->true_rate;
}

static int32_t *sf_int_ref(void *m, gd_vr_t vr) {
    sf_t *d = (sf_t *)m;
    switch (vr) {
    case VR_restart: return &d->restart;
    case VR_restarted: return &d->restarted;
    case VR_seed: return &d->seed;
    case VR_strict_step_size: return &d->strict_step_size;
    default: return NULL;
    }
}

static int32_t sf_get_integer(const gdfmi_inst_t *c, gd_vr_t vr) {
    return *sf_int_ref(c->m, vr);
}

static int sf_get_boolean(const gdfmi_inst_t *c, gd_vr_t vr) {
    return *sf_int_ref(c->m, vr) ? 1 : 0;
}

static const char *sf_get_string(const gdfmi_inst_t *c, gd_vr_t vr) {
    (void)vr;
    return ((const sf_t *)c->m)->card;
}

static char *sf_string_ref(void *m, gd_vr_t vr, size_t *capacity) {
    (void)vr;
    *capacity = CARD_LEN;
    return ((sf_t *)m)->card;
}

#define SER_M (8 * 6 + 4 * 6 + 8 * 2 + 8 * GD_CARD_LEN + CARD_LEN)

static void sf_xfer(gdfmi_cursor_t *cu, gdfmi_core_t *k, void *m, gdfmi_io_t io) {
    sf_t *d = (sf_t *)m;
    int32_t *i32[] = {&d->restart, &d->restarted, &d->seed, &d->strict_step_size, &d->np, &d->pad_};
    size_t j;
    int64_t phase = k->phase, have = k->have_model;
    io(cu, &phase, 8);
    io(cu, &have, 8);
    k->phase = (int32_t)phase;
    k->have_model = (int32_t)have;
    io(cu, &k->time, 8);
    io(cu, &k->n_steps, 8);
    io(cu, &k->n_bad_steps, 8);
    io(cu, &k->ns, 8);
    for (j = 0; j < 6; j++) io(cu, i32[j], 4);
    io(cu, &d->true_rate, 8);
    io(cu, &d->measured_rate, 8);
    io(cu, d->v, 8 * GD_CARD_LEN);
    io(cu, d->card, CARD_LEN);
}

static int sf_check_state(const gdfmi_inst_t *c, const gdfmi_core_t *k, const void *m, const double *s,
                          char *err, size_t nerr) {
    const sf_t *d = (const sf_t *)m;
    gd_card_t card;
    double *p;
    char why[512];
    int same;
    if (memchr(d->card, 0, CARD_LEN) == NULL || (d->restart != 0 && d->restart != 1)
        || (d->restarted != 0 && d->restarted != 1) || (d->strict_step_size != 0 && d->strict_step_size != 1)
        || d->seed < 0)
        return gdfmi_fmt_err(err, nerr, "invalid state fields (corrupted state)");
    if (!k->have_model) return 0;
    if (check_vector(d->v, why, sizeof why) != 0)
        return gdfmi_fmt_err(err, nerr, "invalid card in the state: %s", why);
    gd_sim_card_from_vector(d->v, GD_CARD_LEN, &card);
    if (d->np != gd_sim_n_params(&card))
        return gdfmi_fmt_err(err, nerr, "sensor buffers do not match the card (corrupted state)");
    p = (double *)gdfmi_alloc(c, (size_t)d->np, sizeof(double));
    if (!p) return gdfmi_fmt_err(err, nerr, "out of memory");
    gd_sim_params(&card, (double)d->seed, p);
    same = memcmp(p, s, (size_t)d->np * sizeof(double)) == 0 && k->ns == d->np + gd_sim_n_state(p);
    gdfmi_free(c, p);
    if (!same) return gdfmi_fmt_err(err, nerr, "sensor buffers do not match the card (corrupted state)");
    return 0;
}

static void sf_describe(const gdfmi_inst_t *c, char *out, size_t n) {
    const sf_t *d = (const sf_t *)c->m;
    snprintf(out, n, "card %.60s%s, %.17g Hz, seed %d, %d model parameters", d->card,
             strlen(d->card) > 60 ? "..." : "", d->v[0], (int)d->seed, (int)d->np);
}

static const gdfmi_model_t gdfmi_model = {
    GD_MODEL_IDENTIFIER, GD_GUID, vars, GD_N_VARS, sizeof(sf_t),
    "GDSIMFOG", SERIAL_VERSION, GD_CARD_LEN, SER_M,
    "the card's sample period", "the simulated time base",
    sf_defaults, sf_build, sf_start, sf_period, sf_strict, sf_step,
    sf_get_real, sf_get_integer, sf_get_boolean, sf_get_string,
    sf_real_ref, sf_int_ref, sf_string_ref,
    sf_xfer, sf_check_state, sf_describe, 1};
