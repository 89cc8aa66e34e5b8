/*
 * simulatedfog_native_all.c -- SimulatedFogNative as one translation unit (see
 * gdfmi_libm.h): the sensor model gdsim.c (gd_* hidden), the model hooks
 * simulatedfog_native.c, the shared FMI layer gdfmi.c (the fmi2* functions).
 */
#include "gdfmi_libm.h"

GDFMI_HIDE_BEGIN
#include "gdsim.c"
GDFMI_HIDE_END

#include "simulatedfog_native.c"
#include "gdfmi.c"
