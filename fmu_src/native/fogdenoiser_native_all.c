/*
 * fogdenoiser_native_all.c -- FogDenoiserNative as one translation unit: the one
 * file <SourceFiles> of its modelDescription.xml lists, so that a generic source
 * build (fmpy's build_platform_binary, a tool's own cmake or make: no flags of
 * ours) still gives a binary that
 *   - exports the fmi2* functions only (the gd_* functions of the core are hidden
 *     here, whatever -fvisibility the build uses);
 *   - does the same arithmetic (no fused multiply-add: FP_CONTRACT off);
 *   - loads where the build did not link the math library (a build without -lm
 *     on Linux): the libm functions are weak references there, resolved from the
 *     process (most hosts have libm loaded), and fmi2Instantiate refuses with the
 *     reason logged when they are not (instead of a failed dlopen or a crash).
 * `gyrodenoise fmu build` compiles this file too, with -lm and -DGD_LIBM_LINKED.
 */
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#if defined(__ELF__) && !defined(GD_LIBM_LINKED)
#pragma weak exp
#pragma weak sqrt
#pragma weak sin
#pragma weak cos
#pragma weak tan
#pragma weak hypot
#pragma weak pow
#pragma weak nearbyint
#pragma weak log
/* the first libm function this process does not provide, or NULL */
static const char *gd_libm_missing(void) {
    const char *names[] = {"exp", "sqrt", "sin", "cos", "tan", "hypot", "pow", "nearbyint",
                           "log"};
    const void *addr[] = {(const void *)&exp, (const void *)&sqrt, (const void *)&sin,
                          (const void *)&cos, (const void *)&tan, (const void *)&hypot,
                          (const void *)&pow, (const void *)&nearbyint, (const void *)&log};
    size_t i;
    for (i = 0; i < sizeof names / sizeof names[0]; i++)
        if (!addr[i]) return names[i];
    return NULL;
}
#define GD_LIBM_MISSING gd_libm_missing
#endif

#if defined(__GNUC__) && !defined(_WIN32) && !defined(__CYGWIN__)
#pragma GCC visibility push(hidden)
#include "gdcore.c"
#pragma GCC visibility pop
#else
#include "gdcore.c"
#endif

#include "fogdenoiser_native.c"
