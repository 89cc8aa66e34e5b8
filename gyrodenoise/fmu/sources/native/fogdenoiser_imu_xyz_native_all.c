/*
 * fogdenoiser_imu_xyz_native_all.c -- FogDenoiserImuNative (FMI 2.0) as one translation unit (see
 * gdfmi_libm.h): the core gdcore.c (gd_* hidden), the model hooks fogdenoiser_imu_xyz_native.c, the
 * shared FMI layer gdfmi.c (with gdfmi2.c: the fmi2* functions).
 */
#include "gdfmi_libm.h"

GDFMI_HIDE_BEGIN
#include "gdcore.c"
#include "gdbias.c"
GDFMI_HIDE_END

#include "fogdenoiser_imu_xyz_native.c"
#include "gdfmi.c"
