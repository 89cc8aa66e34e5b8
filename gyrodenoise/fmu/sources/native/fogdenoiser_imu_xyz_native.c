/*
 * fogdenoiser_imu_xyz_native.c -- FogDenoiserImuNative: FogDenoiserImuNative3 (fogdenoiser_imu_native.c)
 * as an FMI 2.0 co-simulation FMU with one scalar variable an axis (raw_rate_x, raw_rate_y,
 * raw_rate_z; filtered_rate_x, ...) instead of arrays, for hosts without FMI 3.0 arrays. The same
 * hooks, the same three filters; its variable header fogdenoiser_imu_xyz_native_vars.h and its
 * serialized states' magic ("GDIMUXYZ") are its own.
 */
#define GD_IMU_AXIS_SCALARS
#include "fogdenoiser_imu_native.c"
