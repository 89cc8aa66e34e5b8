/*
 * gdfmi_libm.h -- included first by each native FMU's single translation unit
 * (fogdenoiser_native_all.c, simulatedfog_native_all.c): the one file <SourceFiles>
 * of its modelDescription.xml lists, so that a generic source build (fmpy's
 * build_platform_binary, a tool's own cmake or make: no flags of ours) still gives
 * a binary that
 *   - does the same arithmetic (no fused multiply-add: FP_CONTRACT off);
 *   - loads where the build did not link the math library (a build without -lm
 *     on Linux): the libm functions are weak references there, resolved from the
 *     process (most hosts have libm loaded), and fmi2Instantiate refuses with the
 *     reason logged when they are not (instead of a failed dlopen or a crash).
 * The unity files hide the cores' gd_* functions (only fmi2* exported, whatever
 * -fvisibility the build uses). `gyrodenoise fmu build` compiles them with -lm and
 * -DGD_LIBM_LINKED.
 */
#ifndef GDFMI_LIBM_H
#define GDFMI_LIBM_H

/* every standard header the cores use, included before their functions are hidden */
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
#pragma weak log10
#pragma weak ceil
/* the first libm function this process does not provide, or NULL */
static const char *gd_libm_missing(void) {
    const char *names[] = {"exp", "sqrt", "sin", "cos", "tan", "hypot", "pow", "nearbyint",
                           "log", "log10", "ceil"};
    const void *addr[] = {(const void *)&exp, (const void *)&sqrt, (const void *)&sin,
                          (const void *)&cos, (const void *)&tan, (const void *)&hypot,
                          (const void *)&pow, (const void *)&nearbyint, (const void *)&log,
                          (const void *)&log10, (const void *)&ceil};
    size_t i;
    for (i = 0; i < sizeof names / sizeof names[0]; i++)
        if (!addr[i]) return names[i];
    return NULL;
}
#define GD_LIBM_MISSING gd_libm_missing
#endif

#if defined(__GNUC__) && !defined(_WIN32) && !defined(__CYGWIN__)
#define GDFMI_HIDE_BEGIN _Pragma("GCC visibility push(hidden)")
#define GDFMI_HIDE_END _Pragma("GCC visibility pop")
#else
#define GDFMI_HIDE_BEGIN
#define GDFMI_HIDE_END
#endif

#endif
