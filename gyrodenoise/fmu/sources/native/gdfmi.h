/*
 * gdfmi.h -- the FMI 2.0 / FMI 3.0 co-simulation layer shared by the project's native FMUs
 * (FogDenoiserNative[3]: fogdenoiser_native.c, SimulatedFogNative[3]: simulatedfog_native.c,
 * FogDenoiserImuNative3: fogdenoiser_imu_native.c).
 *
 * One layer, two standards: GD_FMI_VERSION (2, the default, or 3) chooses the FMI headers
 * and the thin entry points compiled over it (gdfmi2.c: the fmi2* functions, gdfmi3.c: the
 * fmi3* functions). gdfmi.c holds everything they share, written once: the co-simulation
 * state machine (a
 * call the standard does not allow in the current state returns fmi2Error with the
 * reason logged and puts the instance in the error state, from which
 * fmi2SetFMUstate, fmi2Reset and fmi2FreeInstance recover), logging (a message
 * explaining a status other than fmi2OK always goes to the logger; information
 * only when logging is on and its category enabled), the resource URI, the
 * checks of get/set calls against the variable table (types, causality, fixed
 * parameters frozen after initialisation), the step-size rule (one communication
 * step = one sample), and FMU states (get/set/free, freed with the instance,
 * serialized as a versioned, checksummed byte image).
 *
 * A model is a set of hooks (gdfmi_model_t) over two buffers of its own: a
 * fixed-size part m (parameters, inputs, outputs: plain data, copied as bytes)
 * and a state buffer s of doubles (k.ns of them, allocated at
 * ExitInitializationMode). Each native FMU is one translation unit:
 *   the model file (includes this header, defines its hooks and
 *   `static const gdfmi_model_t gdfmi_model`), then gdfmi.c.
 * Everything here is static: only the fmi2* functions are exported.
 */
#ifndef GDFMI_H
#define GDFMI_H

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef GD_FMI_VERSION
#define GD_FMI_VERSION 2
#endif
#if GD_FMI_VERSION == 3
#include "fmi3Functions.h"
#define GD_FMI_NAME "FMI 3.0"
#define GD_FN(name) "fmi3" name /* a function's name in messages */
#define GD_FN_INSTANTIATE "fmi3InstantiateCoSimulation"
#define GD_FN_GET_STATE "fmi3GetFMUState"
#define GD_FN_SET_STATE "fmi3SetFMUState"
#define GD_FN_FREE_STATE "fmi3FreeFMUState"
#define GD_FN_STATE_SIZE "fmi3SerializedFMUStateSize"
#define GD_FN_SERIALIZE "fmi3SerializeFMUState"
#define GD_FN_DESERIALIZE "fmi3DeserializeFMUState"
#define GD_TOKEN_NAME "instantiationToken"
#define GD_API_ERROR fmi3Error /* what an entry point returns for an error */
#define GD_TYPE_NAME_REAL "Float64"
#define GD_TYPE_NAME_INTEGER "Int32"
#elif GD_FMI_VERSION == 2
#include "fmi2Functions.h"
#define GD_FMI_NAME "FMI 2.0"
#define GD_FN(name) "fmi2" name
#define GD_FN_INSTANTIATE "fmi2Instantiate"
#define GD_FN_GET_STATE "fmi2GetFMUstate"
#define GD_FN_SET_STATE "fmi2SetFMUstate"
#define GD_FN_FREE_STATE "fmi2FreeFMUstate"
#define GD_FN_STATE_SIZE "fmi2SerializedFMUstateSize"
#define GD_FN_SERIALIZE "fmi2SerializeFMUstate"
#define GD_FN_DESERIALIZE "fmi2DeSerializeFMUstate"
#define GD_TOKEN_NAME "GUID"
#define GD_API_ERROR fmi2Error /* what an entry point returns for an error */
#define GD_TYPE_NAME_REAL "Real"
#define GD_TYPE_NAME_INTEGER "Integer"
#else
#error "GD_FMI_VERSION must be 2 or 3"
#endif

/* the layer's status (the values of fmi2Status and fmi3Status) and value reference */
typedef int gd_status_t;
enum { GD_OK = 0, GD_WARNING = 1, GD_DISCARD = 2, GD_ERROR = 3, GD_FATAL = 4 };
typedef unsigned int gd_vr_t;

/* the host's callbacks */
#if GD_FMI_VERSION == 3
typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback logger;
} gdfmi_cb_t;
#else
typedef fmi2CallbackFunctions gdfmi_cb_t;
#endif

#if defined(__GNUC__)
#define GDFMI_MAYBE_UNUSED __attribute__((unused)) /* a helper not every model calls */
#else
#define GDFMI_MAYBE_UNUSED
#endif

/* states of the co-simulation state machine (bits) */
enum {
    ST_INSTANTIATED = 1 << 0,
    ST_INIT = 1 << 1,
    ST_STEP_COMPLETE = 1 << 2,
    ST_STEP_FAILED = 1 << 3,
    ST_TERMINATED = 1 << 4,
    ST_ERROR = 1 << 5,
    ST_FATAL = 1 << 6
};
#define ST_ALL_BUT_FATAL (ST_INSTANTIATED | ST_INIT | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR)

/* log categories (bits), in the order of <LogCategories> */
#define CAT_WARNING 0
#define CAT_DISCARD 1
#define CAT_ERROR 2
#define CAT_FATAL 3
#define CAT_ALL 4
#define N_CATS 5

#define STEP_RTOL 1e-6 /* tolerated relative mismatch of step size and the model's sample period */
/* a step shorter than this fraction of the sample period is no sample: the sliver a master that
 * accumulates its time (t += h) leaves before its stop time; answered OK, outputs unchanged */
#define SLIVER_RTOL 1e-6

/* variable types and kinds of the variable table */
enum { T_REAL, T_INTEGER, T_BOOLEAN, T_STRING };
enum { K_INPUT, K_OUTPUT, K_PARAMETER };

typedef struct {
    const char *name;
    int type, kind;
    unsigned n; /* values: 1 for a scalar, the length of an array variable (FMI 3.0, Real only) */
} gdfmi_var_t;

/* the part of an instance's state the layer owns (copied into FMU states) */
typedef struct {
    int32_t phase;
    int32_t have_model; /* s valid (after ExitInitializationMode) */
    double time;        /* communication time reached */
    int64_t n_steps, n_bad_steps;
    int64_t ns;         /* doubles in s */
} gdfmi_core_t;

typedef struct gdfmi_state_s gdfmi_state_t;

typedef struct {
    uint32_t magic;
    gdfmi_cb_t cb;
    char *name;
    char *resource_uri; /* copy, may be NULL */
    int logging_on;
    int cat_on[N_CATS];
    gdfmi_core_t k;
    void *m;   /* the model's fixed-size part (gdfmi_model.m_size bytes) */
    double *s; /* the model's state buffer, k.ns doubles (NULL before initialisation) */
    gdfmi_state_t *states; /* the FMU states this instance allocated and the host has not freed */
    int64_t n_slivers;     /* steps shorter than SLIVER_RTOL of the period (no sample), for the log */
} gdfmi_inst_t;

/* a serialization cursor; io is put (write) or get (read) */
typedef struct { unsigned char *b; size_t at, n; int ok; } gdfmi_cursor_t;
typedef void (*gdfmi_io_t)(gdfmi_cursor_t *, void *, size_t);

typedef struct {
    const char *identifier, *guid;
    const gdfmi_var_t *vars;
    unsigned n_vars;
    size_t m_size;
    /* serialized form: magic (8 characters), format version, a layout count (checked
     * on reading: another count is another layout) and the bytes xfer moves */
    const char *serial_magic;
    uint32_t serial_version;
    uint64_t serial_layout;
    size_t serial_m_bytes;
    /* the step-size rule: "sample_period" / "the card's sample period", and whose time
     * base a wrong size breaks ("the filter's time base", "the simulated time base") */
    const char *period_name, *time_base;

    void (*defaults)(void *m); /* instantiated state: start values */
    /* at ExitInitializationMode: check the parameters and build the model; returns
     * the doubles of s needed (> 0), or -1 with a one-line reason in err */
    long (*build)(gdfmi_inst_t *c, char *err, size_t nerr);
    /* fill s (ns doubles, zeroed) for the built model */
    void (*start)(gdfmi_inst_t *c);
    double (*period)(const void *m);
    int (*strict_step_size)(const void *m);
    /* one sample at time t (the layer checked the state, t and the step size); returns
     * GD_OK, GD_WARNING (the sample processed, the reason logged by the model: the step
     * completes) or gdfmi_fail(...) */
    gd_status_t (*step)(gdfmi_inst_t *c, double t);
    /* getters (any variable of the type), setters (references to settable variables) */
    double (*get_real)(const gdfmi_inst_t *c, gd_vr_t vr);
    int32_t (*get_integer)(const gdfmi_inst_t *c, gd_vr_t vr);
    int (*get_boolean)(const gdfmi_inst_t *c, gd_vr_t vr);
    const char *(*get_string)(const gdfmi_inst_t *c, gd_vr_t vr);
    double *(*real_ref)(void *m, gd_vr_t vr); /* an array variable: its first value, inputs and outputs */
    int32_t *(*int_ref)(void *m, gd_vr_t vr); /* Integer and Boolean */
    char *(*string_ref)(void *m, gd_vr_t vr, size_t *capacity);
    /* the serialized fields of (k, m), in a fixed order, in either direction */
    void (*xfer)(gdfmi_cursor_t *cu, gdfmi_core_t *k, void *m, gdfmi_io_t io);
    /* a deserialized (k, m, s) the layer found consistent: 0, or -1 with the reason */
    int (*check_state)(const gdfmi_inst_t *c, const gdfmi_core_t *k, const void *m, const double *s,
                       char *err, size_t nerr);
    /* information logged at ExitInitializationMode */
    void (*describe)(const gdfmi_inst_t *c, char *out, size_t n);
    /* 1: start takes the first sample (a sensor's sample 0, from the inputs set in initialisation
     * mode); 0: the first step does (a denoiser). Either way the outputs read in initialisation
     * mode are the first sample's, computed on a scratch copy (gdfmi.c: first_outputs) */
    int first_sample_at_start;
} gdfmi_model_t;

/* helpers for the model (defined in gdfmi.c) */
static void *gdfmi_alloc(const gdfmi_inst_t *c, size_t n, size_t size);
static void gdfmi_free(const gdfmi_inst_t *c, void *ptr);
static void gdfmi_log(const gdfmi_inst_t *c, gd_status_t st, const char *fmt, ...);
static gd_status_t gdfmi_fail(gdfmi_inst_t *c, const char *fmt, ...);
static int gdfmi_fmt_err(char *err, size_t n, const char *fmt, ...);
/* the local path of `relative` in the instance's resources folder: 0, or -1 with the reason */
GDFMI_MAYBE_UNUSED static int gdfmi_resource_path(const gdfmi_inst_t *c, const char *relative, char *out, size_t n,
                               char *err, size_t nerr);
/* Python's str.strip() for ASCII: [*begin, *end) of s */
static void gdfmi_strip(const char *s, const char **begin, const char **end);

#endif
