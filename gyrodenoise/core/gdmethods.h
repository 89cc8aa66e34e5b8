/* gdmethods.h -- generated from gyrodenoise/core/methods.py (python -m gyrodenoise.core.methods):
 * do not edit; tests/core/test_methods.py holds this file to the registry.
 *
 * METHOD_<NAME>: p[P_METHOD] of each method (doubles, compared with ==);
 * GD_METHODS(X): X(name, id) per method, the default first;
 * GD_AR_MODEL(m): method m identifies the online AR(n) model; GD_AR_FILTER(m): and filters with it
 *   (the outlier gate applies);
 * GD_REAL_PARAMS(X) / GD_INT_PARAMS(X): the FMU parameters, X(name, start, slot, lo, hi, flags, rule,
 *   methods) with slot the p[] index it is written to (-1: computed), lo / hi its range (-HUGE_VAL /
 *   HUGE_VAL: none), flags GD_LO_OPEN | GD_HI_OPEN | GD_OFF | GD_NYQUIST | GD_COMPUTED, rule the
 *   range as the message says it (%g: half the sample rate), method the METHOD_* it applies to
 *   (-1.0: all). An FMU checks every parameter against its range whatever the method. */
#ifndef GDMETHODS_H
#define GDMETHODS_H

#define METHOD_MOTION 4.0
#define METHOD_SHAKF 2.0
#define METHOD_KF 1.0
#define METHOD_SH_CLASSIC 3.0
#define METHOD_LOWPASS 5.0
#define METHOD_ONE_EURO 6.0
#define METHOD_NONE 0.0
#define GD_N_METHODS 7
#define GD_METHOD_NAMES "['kf', 'lowpass', 'motion', 'none', 'one_euro', 'sh_classic', 'shakf']"
#define GD_METHODS(X) \
    X("motion", METHOD_MOTION) \
    X("shakf", METHOD_SHAKF) \
    X("kf", METHOD_KF) \
    X("sh_classic", METHOD_SH_CLASSIC) \
    X("lowpass", METHOD_LOWPASS) \
    X("one_euro", METHOD_ONE_EURO) \
    X("none", METHOD_NONE) \

#define GD_AR_MODEL(m) ((m) == METHOD_SHAKF || (m) == METHOD_KF || (m) == METHOD_SH_CLASSIC || (m) == METHOD_NONE)
#define GD_AR_FILTER(m) ((m) == METHOD_SHAKF || (m) == METHOD_KF || (m) == METHOD_SH_CLASSIC)

#define GD_LO_OPEN 1
#define GD_HI_OPEN 2
#define GD_OFF 4
#define GD_NYQUIST 8
#define GD_COMPUTED 16   /* 0 stands for the default computed from the sample rate */
#define GD_N_REAL_PARAMS 18
#define GD_REAL_PARAMS(X) \
    X(cutoff_hz, 0.0, -1, 0.0, HUGE_VAL, GD_LO_OPEN | GD_NYQUIST | GD_COMPUTED, "> 0 Hz and below half the sample rate, %g Hz; 0 = the default", METHOD_LOWPASS) \
    X(max_motion_hz, 0.0, -1, 0.0, HUGE_VAL, GD_LO_OPEN | GD_OFF | GD_NYQUIST, "0 (off) or > 0 Hz and below half the sample rate, %g Hz", METHOD_MOTION) \
    X(min_cutoff_hz, 1.0, P_OE_MIN, 0.0, HUGE_VAL, GD_LO_OPEN, "> 0 Hz", METHOD_ONE_EURO) \
    X(beta, 0.001, P_OE_BETA, 0.0, HUGE_VAL, 0, ">= 0", METHOD_ONE_EURO) \
    X(d_cutoff_hz, 1.0, P_OE_DCUT, 0.0, HUGE_VAL, GD_LO_OPEN, "> 0 Hz", METHOD_ONE_EURO) \
    X(warmup_s, 1.0, -1, 0.0, HUGE_VAL, 0, ">= 0 s", -1.0) \
    X(b, 0.99, P_B, 0.0, 1.0, GD_LO_OPEN | GD_HI_OPEN, "0 < b < 1", -1.0) \
    X(gamma, 3.0, P_GAMMA, 1.0, HUGE_VAL, 0, ">= 1", -1.0) \
    X(lam, 1.0, P_LAM, 0.0, 1.0, GD_LO_OPEN, "0 < lam <= 1", -1.0) \
    X(q0, 0.0, P_Q0, 0.0, HUGE_VAL, GD_OFF, ">= 0 (deg/s)^2, 0 = automatic", -1.0) \
    X(r0, 0.0, P_R0, 0.0, HUGE_VAL, GD_OFF, ">= 0 (deg/s)^2, 0 = automatic", -1.0) \
    X(p0_rls, 10000.0, P_P0_RLS, 0.0, HUGE_VAL, GD_LO_OPEN, "> 0", -1.0) \
    X(p0_kf, 1.0, P_P0_KF, 0.0, HUGE_VAL, GD_LO_OPEN, "> 0 (deg/s)^2", -1.0) \
    X(r_floor, 1e-18, P_R_FLOOR, 0.0, HUGE_VAL, GD_LO_OPEN, "> 0 (deg/s)^2", -1.0) \
    X(outlier_sigma, 5.0, P_OUTLIER_SIGMA, 2.0, HUGE_VAL, GD_OFF, "0 (off) or >= 2", -1.0) \
    X(bias_still_s, 1.0, -1, 0.0, HUGE_VAL, GD_LO_OPEN, "> 0 s", METHOD_MOTION) \
    X(bias_memory_s, 60.0, -1, 0.0, HUGE_VAL, GD_LO_OPEN, "> 0 s", METHOD_MOTION) \
    X(earth_rate_floor_deg_h, 15.0, -1, 0.0, HUGE_VAL, 0, ">= 0 deg/h", METHOD_MOTION) \

#define GD_N_INT_PARAMS 4
#define GD_INT_PARAMS(X) \
    X(ar_order, 3, P_ORDER, 1.0, 6.0, 0, "1..6", -1.0) \
    X(lowpass_order, 2, -1, 1.0, 8.0, 0, "1..8", METHOD_LOWPASS) \
    X(outlier_run, 20, P_OUTLIER_RUN, 1.0, HUGE_VAL, 0, ">= 1", -1.0) \
    X(bias_tracking, 0, P_BIAS, 0.0, 1.0, GD_OFF, "0..1", METHOD_MOTION) \

#endif
