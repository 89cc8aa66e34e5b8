/*
 * simulatedfog_native3_all.c -- the FMI 3.0 build of simulatedfog_native_all.c: the same translation unit
 * (core, model hooks, shared FMI layer) with the fmi3* entry points (gdfmi3.c).
 */
#define GD_FMI_VERSION 3
#include "simulatedfog_native_all.c"
