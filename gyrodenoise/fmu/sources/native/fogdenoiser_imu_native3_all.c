/*
 * fogdenoiser_imu_native3_all.c -- FogDenoiserImuNative3 as one translation unit (see
 * gdfmi_libm.h): the core gdcore.c (gd_* hidden), the model hooks
 * fogdenoiser_imu_native.c, the shared FMI layer gdfmi.c (with gdfmi3.c: the fmi3* functions).
 */
#define GD_FMI_VERSION 3 /* FMI 3.0 only */
#include "gdfmi_libm.h"

GDFMI_HIDE_BEGIN
#include "gdcore.c"
#include "gdbias.c"
GDFMI_HIDE_END

#include "fogdenoiser_imu_native.c"
#include "gdfmi.c"
