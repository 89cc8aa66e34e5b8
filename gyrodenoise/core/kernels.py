"""Per-sample numerical kernels: online AR(n) identification and the KF / SHAKF.

The executable specification of the core
----------------------------------------
Every function here is plain scalar Python over two flat buffers of floats (``Buf``,
``MutBuf``):

* ``p`` -- the parameters (see :func:`make_params` and the ``P_*`` indices),
* ``s`` -- the whole filter state (see :func:`init_state` and the ``S_*`` indices).

Functions mutate ``s`` in place and return the scalar output, like
``scipy.signal.lfilter`` returning ``zf``: the caller owns the state and may
copy, save or restore it at any sample. ``gdcore.c`` (beside this file) is the
same functions in C99 over the same buffers, operation for operation; the
extension :mod:`gyrodenoise.core._gdcore` runs it for :mod:`gyrodenoise.core.batch`,
:class:`gyrodenoise.Denoiser` and the FMUs, and the tests hold it to this file
bit for bit. This file needs nothing but ``math`` and the method registry
(:mod:`gyrodenoise.core.methods`, standard library only): it is also the
fallback where the compiled core is not available (an FMU on a platform its
bundled binary does not fit), ~20-50 us a sample. Change the maths here first,
then mirror it in gdcore.c (the tests fail until both agree).

Equations cited are those of Sun et al. (2016), "FOG Random Drift Signal
Denoising Based on the Improved AR Model and Modified Sage-Husa Adaptive Kalman
Filter", Sensors 16(7):1073, doi:10.3390/s16071073.

Choices the paper leaves open (documented in docs/method/paper.md):

* RLS starts from theta = 0 and P = p0_rls * I (a large initial P); with
  forgetting factor ``lam`` this is exactly the ridge-regularised batch least
  squares solution (tested against it).
* Eq. (10) is implemented with the sign slip corrected: P = (I - K Z) P / lam.
* The process noise enters the first state only (B of Eq. 34), so the Q of the
  Sage-Husa estimator, Eq. (26), is estimated as q * e1 e1^T; its (0,0) element
  reduces to q + K0^2 (v^2 - S) and is clipped at ``r_floor`` (> 0), which
  keeps Q positive semi-definite and P positive definite (with q = 0 and phi = 0,
  e.g. an all-zero record, x0 would be exactly c and P singular).
* Warm-up: for ``warmup`` samples after each restart the AR model is still
  converging; the output is then the raw sample itself (no filtering, nothing
  invented) and the ``converged`` flag is 0. The filter runs internally all the
  while, so there is no start-up transient when the output switches over.
* The filter's c state is tied to the RLS estimate of c at every sample (see
  :func:`tie_c` for why: a free c state with no process noise locks onto a
  wrong mean while phi is still converging).
* Auto noise levels (``q0 = 0`` / ``r0 = 0``): the running variance s2 of the RLS
  one-step prediction error (Eq. 11's correction term) is split half to process
  noise, half to measurement noise: q = r = s2 / 2. The KF freezes these at the
  end of the warm-up; the SHAKF starts its estimators from them.
"""

from __future__ import annotations

import math
from collections.abc import MutableSequence, Sequence
from typing import Any, TypeAlias

from . import methods as _methods

#: the parameter buffer (read only) and the state buffer (written in place): lists of floats,
#: or the C core's float64 arrays
Buf: TypeAlias = Sequence[float]
MutBuf: TypeAlias = MutableSequence[float]

# ---------------------------------------------------------------- parameters
P_ORDER = 0      # AR order n (>= 1)
P_METHOD = 1     # METHOD_* below
P_LAM = 2        # RLS forgetting factor, 0 < lam <= 1
P_B = 3          # Sage-Husa forgetting factor b, 0 < b < 1
P_GAMMA = 4      # divergence criterion gamma >= 1, Eq. (32)
P_Q0 = 5         # process noise variance (deg/s)^2; 0 = auto
P_R0 = 6         # measurement noise variance (deg/s)^2; 0 = auto
P_P0_RLS = 7     # initial RLS covariance (diagonal)
P_P0_KF = 8      # initial filter covariance (diagonal), (deg/s)^2
P_WARMUP = 9     # warm-up length in samples after each restart
P_R_FLOOR = 10   # lower bound of R and of the auto noise levels, (deg/s)^2
P_OUTLIER_SIGMA = 11  # innovation gate k: |v| > k sqrt(S) rejects a sample; 0 = off
P_OUTLIER_RUN = 12    # consecutive rejections after which the filter re-opens (restart)
P_LP_NSEC = 13   # lowpass, and motion's rigid-body low-pass: number of second-order sections (0 = none)
P_LP_CUTOFF = 14  # lowpass, and motion's rigid-body low-pass: -3 dB cutoff, Hz
P_SOS = 15       # lowpass: MAX_SOS sections of (b0, b1, b2, a1, a2), a0 = 1
MAX_SOS = 4      # Butterworth orders 1..8
P_FS = P_SOS + 5 * MAX_SOS   # the sample rate, Hz (one_euro)
P_OE_MIN = P_FS + 1          # one_euro: cutoff at rest, Hz
P_OE_BETA = P_FS + 2         # one_euro: growth of the cutoff with |d rate / dt|, Hz per deg/s^2
P_OE_DCUT = P_FS + 3         # one_euro: cutoff of the low-pass on the rate's change, Hz
P_MO_NF = P_FS + 4               # motion: number of constant-velocity (CV) filters in the bank, lanes 0..NF-1;
                                 # P_MO_NCA constant-acceleration (CA) ones follow (NF + NCA <= MO_MAX_NF)
P_MO_FADE = P_MO_NF + 1          # motion: fading factor of the filters' log-likelihoods per sample
P_MO_BR = P_MO_NF + 2            # motion: forgetting factor of the noise-level estimate (Sage-Husa b)
P_MO_RESET = P_MO_NF + 3         # motion: log-likelihood gap below the best at which a filter is re-started from it
P_MO_NLAG = P_MO_NF + 4          # motion: lags 1..NLAG of the 4th-difference noise estimates
P_MO_HUBER = P_MO_NF + 5         # motion: Huber clip of |4th difference|, in units of its mean
P_MO_KAPPA = P_MO_NF + 6         # motion: gain of the angle feedback per sample (0 = off)
P_MO_CLIP2 = P_MO_NF + 7         # motion: Huber clip of the innovation in the state updates, (sigmas)^2
P_MO_VAR = P_MO_NF + 8           # motion: 1.0 = also keep the output variance M_PVAR (batch.run_offline), 0.0 = not
P_MO_G = P_MO_NF + 9             # motion: MO_MAX_NF steady-state gains on the rate, then MO_MAX_NF on the
                                 # slope, then MO_MAX_NF log S/R, then MO_MAX_NF gains on the slope's change
                                 # (gamma: 0 for a CV lane), then MO_MAX_NF tracking indices squared lam^2
                                 # (q = lam^2 R: S_Q); one run per quantity: the C core's lanes
MO_MAX_NF = 16
MO_MAX_NLAG = 8
P_MO_RFIX = P_MO_G + 5 * MO_MAX_NF   # motion: > 0 = the white-noise variance R to use, (deg/s)^2, instead of
                                     # the estimate (batch.run_offline with max_motion_hz only; 0 = estimate)
P_MO_SPEC = P_MO_RFIX + 1   # motion: spectral noise floor (:func:`spectral_floor`): 1 / (c sum w^2) over the
                            # MO_SPEC_NB bins (R's floor), 0 = off
P_MO_SBB = P_MO_RFIX + 2    # motion: its forgetting factor per block (P_MO_BR ^ MO_SPEC_N)
P_MO_SRATIO = P_MO_RFIX + 3  # motion: the spectral estimate rs replaces the lag one r where rs x this < r
P_MO_COS = P_MO_RFIX + 4    # motion: cos(2 pi m / MO_SPEC_N), m = 0..MO_SPEC_N-1 (window and DFT twiddles)
MO_SPEC_N = 128     # spectral floor: block length, samples (Hann-windowed DFT per block)
MO_SPEC_K0 = 8      # its first bin (MO_SPEC_N / 16: 0.0625 fs) ...
MO_SPEC_NB = 28     # ... and MO_SPEC_NB bins, every other one (nearly uncorrelated under the Hann window)
MO_SPEC_RANK = 4    # the periodogram's MO_SPEC_RANK-th smallest of those bins is read (a low quantile)
MO_HI_J0 = 12       # the line test's floor: the bins from MO_SPEC_K0 + 2 x 12 = 32 (0.25 fs) ...
MO_HI_NB = 16       # ... MO_HI_NB of them (to 62: 0.25-0.5 fs), their MO_SPEC_RANK-th smallest
MO_GUARD_FADE = 0.0625  # output guard: each sample's (z - y)^2 / R enters its mean with this weight (16 samples)
MO_GUARD_CAP = 1000.0   # ... clipped at this many R (one sample of a 32 sigma residual: raw at once; after a step the guard lets go within 30 samples)
MO_GUARD_LO = 2.5       # ... above this mean the output moves towards the raw sample,
MO_GUARD_HI = 5.0       # ... all the way at this one
MO_WU_N0 = 64        # warm-up output (:func:`warmup_output`): the mean of the samples so far from this many samples on,
MO_WU_NL = 3         # ... while the variance of the samples so far is within the white noise's spread of the noise level
                     # read from each of the 4th differences at lags 1..MO_WU_NL (each blind to other tones)
MO_WU_LO = 5.0       # ... all the way while that ratio is below 1 + MO_WU_LO / sqrt(m) at every lag (m: its differences),
MO_WU_HI = 10.0      # ... none from 1 + MO_WU_HI / sqrt(m) on (and never again until the bank starts),
MO_WU_LOW = 2.5      # ... nor at or below 1 - MO_WU_LOW / sqrt(m) (a lag's differences lifted more than the variance: colour)
MO_WU_SPIKE = 25.0   # ... nor from a sample beyond 5 sigma of the mean so far,
MO_WU_FADE = 0.125   # ... nor where the faded mean (this weight per sample) of the samples' (z - mean)^2 / R
MO_WU_GLIM = 4.0     # ... exceeds this
MO_SPEC_ZMAX = 1.0e150   # a block with a centred sample beyond this, deg/s (or not finite), is skipped (no overflow);
                         # so is a 4th difference beyond it in the lag noise estimates (M_MABS)
P_MO_PT = P_MO_COS + MO_SPEC_N   # motion: pass-through (:func:`motion_step`): smoothing of the best filter's
                                  # gain per sample (0 = off), the gain where the output starts moving to the raw
                                  # sample, and where it is the raw sample
P_MO_LINE = P_MO_PT + 3   # motion: spectral line test (:func:`spectral_floor`): a bin at or above
                          # MO_LINE_J0 whose |X|^2 x p[P_MO_SPEC] exceeds this x the floor, in two
                          # blocks in a row, puts the output on the raw sample (0 = off)
MO_LINE_J0 = 19           # the line test's first bin: MO_SPEC_K0 + 2 x 19 = 46 (0.36 fs)
P_MO_CUS = P_MO_PT + 4    # motion: summed-innovation test (:func:`motion_step`): fading of each filter's
                          # summed innovation per sample, and its weight in the log-likelihood (0 = off)
P_MO_NCA = P_MO_PT + 7   # motion: constant-acceleration filters in the bank, lanes P_MO_NF..P_MO_NF+NCA-1
P_MO_SPECH = P_MO_PT + 8  # motion: the line test's floor (:func:`spectral_floor`): 1 / (c sum w^2) over the
                          # MO_HI_NB bins from MO_HI_J0 (0 = off with P_MO_SPEC)
P_BIAS = P_MO_PT + 9       # motion: 1.0 = bias tracking (:func:`bias_update`), 0.0 = off
P_BIAS_LANE = P_BIAS + 1   # bias tracking: still where the most likely filter is at or below this lane
P_BIAS_NEED = P_BIAS + 2   # bias tracking: samples of a block (bias_still_s)
P_BIAS_CAP = P_BIAS + 3    # bias tracking: memory, blocks (bias_memory_s / bias_still_s)
P_BIAS_FLOOR = P_BIAS + 4  # bias tracking: deg/s of the estimate never removed (earth_rate_floor_deg_h)
P_BIAS_NAVR = P_BIAS + 5   # bias tracking: the floor applies where the bank's white-noise variance is below this
N_PARAMS = P_BIAS + 6

MAX_MOTION_ORDER = 4      # motion's rigid-body low-pass (max_motion_hz): Butterworth of this order,
MAX_MOTION_CUTOFF = 2.0   # its -3 dB point at this many times max_motion_hz (gain 0.996 at max_motion_hz),
MAX_MOTION_FS_CAP = 0.45  # at most this fraction of the sample rate

# p[P_METHOD] of each method: the registry's ids (gyrodenoise.core.methods, gdmethods.h)
METHOD_NONE = _methods.BY_NAME["none"].id          # identification only, output = raw
METHOD_KF = _methods.BY_NAME["kf"].id              # conventional KF, fixed Q and R
METHOD_SHAKF = _methods.BY_NAME["shakf"].id        # modified Sage-Husa AKF (Section 3.2.3)
METHOD_SH_CLASSIC = _methods.BY_NAME["sh_classic"].id  # classic Sage-Husa, Eq. (22) and (26) unmodified
METHOD_MOTION = _methods.BY_NAME["motion"].id      # motion-aware: true rate + acceleration, adaptive (not in the paper)
METHOD_LOWPASS = _methods.BY_NAME["lowpass"].id    # causal Butterworth low-pass (not in the paper)
METHOD_ONE_EURO = _methods.BY_NAME["one_euro"].id  # the 1-euro filter, Casiez et al. 2012 (not in the paper)
#: method name -> p[P_METHOD]
METHODS = {m.name: m.id for m in _methods.METHODS}
#: the methods that identify the online AR(n) model (a constant c), and those of them that
#: filter with it (the outlier gate applies): gdmethods.h's GD_AR_MODEL / GD_AR_FILTER
AR_MODEL_IDS = frozenset(m.id for m in _methods.METHODS if m.ar_model)
AR_FILTER_IDS = frozenset(m.id for m in _methods.METHODS if m.ar_model and m.filters)
DEFAULT_METHOD = _methods.DEFAULT_METHOD   # of gd.denoise, the CLI, the bridge and the FMU

# --------------------------------------------------------------------- state
S_K = 0          # samples seen since the last restart
S_KD = 1         # Sage-Husa step counter k in d_k (reset by Eq. 32)
S_R = 2          # R_hat, (deg/s)^2 (motion: its white-noise estimate)
S_Q = 3          # q_hat, (deg/s)^2 (motion: the variance q of the rate increment per sample)
S_S2 = 4         # running variance of the RLS prediction error, (deg/s)^2
S_NS2 = 5        # samples in S_S2
S_CONV = 6       # 1.0 once the AR model has converged since the restart
S_INNOV = 7      # last innovation v_k, deg/s
S_SVAR = 8       # last innovation variance S_k = H P H' + R, (deg/s)^2
S_NRESET = 9     # number of times Eq. (32) restarted d_k
S_OUT = 10       # last output, deg/s
S_RLS_ERR = 11   # last RLS prediction error, deg/s
S_BK = 12        # b^(k+1) for d_k, kept by multiplication (no pow per sample)
S_NREJ = 13      # samples rejected by the outlier gate (since init_state; kept by restarts)
S_REJRUN = 14    # current run of consecutive rejections
S_NREOPEN = 15   # times a run of rejections re-opened the filter (kept by restarts)
S_ZREF = 16      # centring reference: the first raw sample since the restart, deg/s
S_LO = 17        # envelope: lowest centred input since the restart, deg/s
S_HI = 18        # envelope: highest centred input since the restart, deg/s
S_HOLD = 19      # 1.0 while a rejection run holds the output (AR model unstable)
S_NCLAMP = 20    # outputs clamped into the input envelope (kept by restarts)
S_NHEAL = 21     # restarts forced by a non-finite filter state (kept by restarts)
N_HEADER = 22


# method-specific state after the AR layout (lowpass delays, motion), N_EXT floats;
# motion's, at offset layout(n)[6] - N_EXT:
M_R = 0          # white-noise variance R of the sensor (the smallest lag estimate), (deg/s)^2
M_BK = 1         # b^(k+1) of d_k, Eq. (33)
M_HPOS = 2       # position of the newest sample in the ring M_HIST
M_ANG = 3        # angle feedback: integral of (input - output) since the restart, deg/s x samples
M_NW = 4         # samples filtered since the warm-up ended
M_BEST = 5       # index of the most likely filter at the last sample
M_PVAR = 6       # variance of the output (the weighted mixture of the filters), (deg/s)^2
M_MABS = 7       # MO_MAX_NLAG mean |4th difference| at lags 1..NLAG, deg/s
M_HIST = M_MABS + MO_MAX_NLAG              # ring of the last 4 NLAG + 1 centred samples
M_BANK = M_HIST + 4 * MO_MAX_NLAG + 1      # MO_MAX_NF rates, then MO_MAX_NF slopes per sample, log-likelihoods,
                                           # flags (1.0 if below the floor at the last sample), and the slopes'
                                           # change per sample (0.0 in a CV lane): one run per
                                           # quantity, the C core's lanes (MB_X + i, MB_A + i, ...)
MB_X = M_BANK                   # the bank's runs: rates,
MB_A = M_BANK + MO_MAX_NF       # slopes per sample,
MB_L = M_BANK + 2 * MO_MAX_NF   # log-likelihoods,
MB_H = M_BANK + 3 * MO_MAX_NF   # held flags,
MB_J = M_BANK + 4 * MO_MAX_NF   # changes of the slope per sample (CA lanes; 0.0 in the CV lanes)
M_LPD = M_BANK + 5 * MO_MAX_NF             # max_motion_hz: delays of the rigid-body low-pass, 2 per section
MO_WU_AT = M_LPD                   # warm-up output (:func:`warmup_output`, only without the rigid-body low-pass, whose
                               # delays these are): mean, sum of squares about it, the 4th differences' sums of squares
                               # at lags 1..MO_WU_NL, the faded residual, 1.0 once off
M_SPOS = M_LPD + 2 * MAX_SOS   # spectral floor: position of the next sample in the block
M_SR = M_SPOS + 1              # spectral floor: its smoothed white-noise variance, (deg/s)^2 (0 = no block yet)
M_SBK = M_SPOS + 2             # spectral floor: b^(blocks+1) of its d_k
M_SBAD = M_SPOS + 3            # spectral floor: 1.0 if the block holds a sample beyond MO_SPEC_ZMAX (it is skipped)
M_SFOLD = M_SPOS + 4           # spectral floor: the windowed block folded in two, x[n] + x[n + N/2] (N/2 floats)
M_GEFF = M_SFOLD + MO_SPEC_N // 2   # pass-through: the smoothed gain of the most likely filter
M_NWC = M_GEFF + 1                   # 1.0 once the growing-memory gains are below every filter's own (converged)
M_LRAT = M_NWC + 1    # line test: the last block's highest bin at or above MO_LINE_J0 / the floor (x p[P_MO_SPEC])
M_LON = M_NWC + 2     # line test: 1.0 while the last two blocks held a line (output = raw sample)
M_CUS = M_NWC + 3     # summed-innovation test: per filter, its faded sum of innovations, deg/s
M_SRH = M_CUS + MO_MAX_NF   # line test: its smoothed floor from the MO_HI_NB high bins, (deg/s)^2 (as M_SR)
M_SBKH = M_SRH + 1          # line test: b^(blocks+1) of that floor's d_k (as M_SBK)
M_GRD = M_SRH + 2           # output guard (:func:`motion_step`): faded (z - y)^2 / R of the bank's output
M_BIAS = M_SRH + 3          # bias tracking (:func:`bias_update`): its GB_N floats, the last of the state, kept by restarts
GB_CUR_SUM, GB_CUR_N, GB_NBLK, GB_PEND, GB_NB, GB_MEAN, GB_HAT = range(7)   # their order (gdbias.h's gd_bias_t)
GB_N = 7
N_EXT = M_BIAS + GB_N

# one_euro's state, the first floats of the method-specific block:
OE_X = 0         # the filtered (centred) rate, deg/s
OE_DX = 1        # the filtered rate of change, deg/s^2
OE_ZP = 2        # the last centred sample, deg/s


def layout(n: int) -> tuple[int, int, int, int, int, int, int]:
    """Offsets of (theta, P_rls, x, P, z_hist, w, total) for AR order ``n``."""
    m = n + 1
    o_theta = N_HEADER
    o_prls = o_theta + m
    o_x = o_prls + m * m
    o_p = o_x + m
    o_z = o_p + m * m
    o_w = o_z + n
    total = o_w + m + N_EXT
    return o_theta, o_prls, o_x, o_p, o_z, o_w, total



def ext_offset(p: Buf) -> int:
    """Offset in the state of the method-specific block (lowpass delays, motion's
    bank and noise estimates: the ``M_*`` offsets count from it), for params ``p``."""
    return layout(int(p[P_ORDER]))[6] - N_EXT

def fourth_difference(s, h0, pos, nh, lag, z):
    """z - 4 x[-lag] + 6 x[-2 lag] - 4 x[-3 lag] + x[-4 lag] of the history ring ``s[h0:h0 + nh]``
    whose newest sample before ``z`` is at ``pos - 1`` (x[-m] = s[h0 + (pos - m) mod nh]): the
    4th difference at lag ``lag``, blind to a constant, a ramp and curves up to cubics."""
    i1 = pos - lag
    if i1 < 0:
        i1 += nh
    i2 = pos - 2 * lag
    if i2 < 0:
        i2 += nh
    i3 = pos - 3 * lag
    if i3 < 0:
        i3 += nh
    i4 = pos - 4 * lag
    if i4 < 0:
        i4 += nh
    return z - 4.0 * s[h0 + i1] + 6.0 * s[h0 + i2] - 4.0 * s[h0 + i3] + s[h0 + i4]


def raw_warmup_samples(p) -> int:
    """Samples after a restart whose output is the raw sample whatever the record (the warm-up
    rule of :func:`step`): ``P_WARMUP``; for ``motion`` with the spectral floor on, until its
    first block is read (MO_SPEC_N samples; ``P_WARMUP`` + MO_SPEC_N at most where blocks are
    skipped) whatever ``warmup_s`` says, its output the mean of the samples so far from
    MO_WU_N0 samples on where they test as a constant plus white noise (:func:`warmup_output`)."""
    if int(p[P_METHOD]) == METHOD_MOTION and p[P_MO_SPEC] > 0.0:
        return MO_SPEC_N
    return int(p[P_WARMUP])


def make_params(ar_order: int = 3, method: str = DEFAULT_METHOD, sample_rate_hz: float = 200.0,
                **kw: float | int | None) -> list[float]:
    """Build and check the parameter buffer (a list of floats).

    The keywords, their defaults, ranges and units are the registry's
    (:data:`gyrodenoise.core.methods.PARAMS`); the main ones:

    Parameters
    ----------
    ar_order : int
        Order n of the improved AR(n) model, Eq. (4). n >= 1.
    method : str
        One of :data:`gyrodenoise.core.methods.METHODS`: "motion" (default) follows the
        true rate (:func:`motion_step`); "shakf", "kf", "sh_classic" filter on the AR
        state model (the paper); "lowpass" a Butterworth (``cutoff_hz``, ``order``);
        "one_euro" the 1-euro filter (``min_cutoff_hz``, ``beta``, ``d_cutoff_hz``,
        :func:`one_euro_step`); "none": output = input.
    sample_rate_hz : float
        Sample rate; turns ``warmup_s`` into samples, designs the low-passes.
    lam, b, gamma, q0, r0, p0_rls, p0_kf, warmup_s, r_floor : float
        The RLS forgetting factor (0, 1], the Sage-Husa forgetting factor (0, 1), the
        strictness of Eq. (32) (>= 1), the noise variances (0 = automatic: half the AR
        prediction-error variance each), the initial covariances, the warm-up after each
        restart (raw passed through; at least 10 (n+1) samples), the floor of R.
    outlier_sigma, outlier_run
        Innovation gate (not in the paper; docs/bench/outliers-soak.md, :func:`gate`): after
        the warm-up a sample with |v| > outlier_sigma sqrt(S) is rejected (kept out
        of the RLS, the filter and the R/Q estimators; the output is the filter's
        prediction); 0 = off (the paper's filter), otherwise >= 2. After ``outlier_run``
        consecutive rejections the filter re-opens at the next outlying sample.
    cutoff_hz, order
        ``method="lowpass"``: -3 dB cutoff (None: 20 Hz, ArduPilot's and PX4's usual
        gyro filter, at most a quarter of the sample rate) and Butterworth order 1..8.
    max_motion_hz : float
        ``method="motion"``, the rigid-body option: the band of interest,
        0 < max_motion_hz < sample_rate_hz / 2; content above it (a frame's
        vibration) counts as error and a Butterworth low-pass ahead of the bank
        removes it (:func:`rigid_cutoff_hz`: gain >= 0.996 up to max_motion_hz,
        0.062 at 4x). 0 (default) = off. Refused (> 0) with the other methods.

    Raises
    ------
    ValueError
        With a one-line reason naming the parameter.
    """
    unknown = sorted(set(kw) - set(_methods.BY_PARAM))
    if unknown:
        raise TypeError(f"make_params() got an unexpected keyword argument {unknown[0]!r}")
    _methods.method(method)
    values: dict[str, Any] = {**_methods.defaults(), **kw, "ar_order": ar_order, "sample_rate_hz": sample_rate_hz}
    fs = float(_checked(values, "sample_rate_hz", method))
    for par in _methods.PARAMS:
        if par.applies_to(method) or par.off:
            _checked(values, par.name, method, fs)
        if not par.applies_to(method) and par.off and values[par.name]:
            raise ValueError(f"{par.name} applies to method {par.methods[0]!r} only, got method {method!r}")
    n = int(values["ar_order"])
    cutoff_hz, sos = _lowpass_sections(method, fs, values["cutoff_hz"], values["order"],
                                       values["max_motion_hz"])
    p = [0.0] * N_PARAMS
    for par in _methods.PARAMS:
        if par.slot is not None and par.applies_to(method):
            p[globals()[par.slot]] = float(values[par.name])
    p[P_METHOD] = METHODS[method]
    p[P_WARMUP] = max(float(round(values["warmup_s"] * fs)), 10.0 * (n + 1))
    if method == "motion":
        for i, v in enumerate(motion_params(fs)):
            p[P_MO_NF + i] = v
    if method == "motion" and values["bias_tracking"]:     # off: p as without the option
        for i, v in enumerate(bias_params(fs, values["bias_still_s"], values["bias_memory_s"],
                                          values["earth_rate_floor_deg_h"])):
            p[P_BIAS_LANE + i] = v
    _write_sections(p, cutoff_hz, sos)
    return p


def _checked(values, name, method, fs=None):
    """``values[name]``, ValueError with the registry's reason if it is out of range."""
    v = values[name]
    if v is None and _methods.BY_PARAM[name].default is None:
        return v
    _methods.check(name, v, fs)
    return v


def _write_sections(p, cutoff_hz, sos):
    """Put the low-pass's second-order sections ``sos`` (none: nothing) into ``p``."""
    if not sos:
        return
    p[P_LP_NSEC] = float(len(sos))
    p[P_LP_CUTOFF] = float(cutoff_hz)
    for i, sec in enumerate(sos):
        for j in range(5):
            p[P_SOS + 5 * i + j] = sec[j]


def _lowpass_sections(method, sample_rate_hz, cutoff_hz, order, max_motion_hz):
    """(cutoff_hz, second-order sections) of the Butterworth low-pass the method runs:
    the rigid-body low-pass of ``motion`` with ``max_motion_hz`` > 0, the ``lowpass``
    method's filter, or (cutoff_hz, []) for none. ValueError for a default cutoff out of
    range (a sample rate below 0 Hz cannot take)."""
    if max_motion_hz > 0:
        cutoff_hz = rigid_cutoff_hz(float(max_motion_hz), float(sample_rate_hz))
        return cutoff_hz, butter_sos(MAX_MOTION_ORDER, cutoff_hz, float(sample_rate_hz))
    if method != "lowpass":
        return cutoff_hz, []
    if cutoff_hz is None:
        cutoff_hz = min(20.0, 0.25 * sample_rate_hz)
    return cutoff_hz, butter_sos(int(order), float(cutoff_hz), float(sample_rate_hz))


def rigid_cutoff_hz(max_motion_hz: float, sample_rate_hz: float) -> float:
    """-3 dB point of the rigid-body low-pass for a stated band ``max_motion_hz``:
    MAX_MOTION_CUTOFF x max_motion_hz, at most MAX_MOTION_FS_CAP x the sample rate
    (the native FMU repeats these operations). With the Butterworth of order
    MAX_MOTION_ORDER the gain is >= 0.996 up to max_motion_hz, 0.71 at 2x, 0.062
    (-24 dB) at 4x, 0.004 at 8x."""
    fc = MAX_MOTION_CUTOFF * max_motion_hz
    cap = MAX_MOTION_FS_CAP * sample_rate_hz
    return cap if fc > cap else fc


def cv_gains(tracking_index: float) -> tuple[float, float, float]:
    """Steady-state gains (alpha on the rate, beta on its change per sample) of
    the constant-velocity Kalman filter with white-noise acceleration of
    tracking index lam = sigma_w T^2 / sigma_v (Kalata 1984, "The tracking
    index", closed form), and log(S / R) = -log(1 - alpha), S its innovation
    variance. lam^2 = beta^2 / (1 - alpha)."""
    lam = float(tracking_index)
    r = math.sqrt(lam * lam + 8.0 * lam)
    alpha = -(lam * lam + 8.0 * lam - (lam + 4.0) * r) / 8.0
    beta = (lam * lam + 4.0 * lam - lam * r) / 4.0
    return alpha, beta, -math.log(1.0 - alpha)


CA_NEWTON_STEPS = 60   # ca_gains: Newton steps on its cubic from u = 1 (a fixed count: the same bits in C)


def ca_gains(tracking_index: float) -> tuple[float, float, float, float, float]:
    """Steady-state gains of the constant-acceleration Kalman filter: state
    [omega, a, j] (rate, its change per sample, the change of a per sample),
    omega += a + j / 2, a += j, j += white noise w, G = [1/2, 1, 1]^T, process
    noise q = lam^2 R (the discrete Wiener-process acceleration model, in units
    of the white-noise variance R of z = omega + noise).

    The discrete algebraic Riccati equation's steady state satisfies (Kalata;
    Gray and Murray 1993) beta = 2(2 - alpha) - 4 sqrt(1 - alpha), gamma =
    beta^2 / (2 alpha), lam^2 = gamma^2 / (1 - alpha); with s = sqrt(1 - alpha),
    u = 1 - s: lam = 2 u^3 / (s (1 + s)), i.e. the cubic 2u^3 - lam u^2 + 3 lam u
    - 2 lam = 0, increasing in u (lam < 18) with its one root in (0, 1), solved
    here by CA_NEWTON_STEPS Newton steps from u = 1 (convex there: monotone).
    Then alpha = u (2 - u), beta = 2 u^2, gamma = 2 u^3 / (2 - u).
    Returns (alpha, beta, gamma, log(S / R) = -log(1 - alpha), lam^2)."""
    lam = float(tracking_index)
    u = 1.0
    for _ in range(CA_NEWTON_STEPS):
        g = ((2.0 * u - lam) * u + 3.0 * lam) * u - 2.0 * lam
        dg = (6.0 * u - 2.0 * lam) * u + 3.0 * lam
        u = u - g / dg
    alpha = u * (2.0 - u)
    beta = 2.0 * u * u
    gamma = 2.0 * u * u * u / (2.0 - u)
    return alpha, beta, gamma, -math.log(1.0 - alpha), lam * lam


def motion_params(sample_rate_hz: float, n_filters: int = 13, log10_lambda_min: float = -10.0,
                  log10_lambda_max: float = 2.0, n_accel: int = 3, log10_accel_min: float = -2.0,
                  log10_accel_max: float = 0.0, tau_l_s: float = 3.0, r_tau_s: float = 10.0, reset: float = 20.0,
                  n_lag: int = 6, huber: float = 4.0, tau_angle_s: float = 30.0, clip_sigma: float = 4.0,
                  spectral: float = 1.5, pass_tau_s: float = 0.02, pass_gain: tuple[float, float] = (0.7, 0.95),
                  line: float = 10.0, cusum_tau_s: float = 0.1, cusum_weight: float = 1.0,
                  cusum_sigma: float = 3.75) -> list[float]:
    """The constants of ``method="motion"`` (:func:`motion_step`), one default
    for every sensor (they are relative to the noise level the filter reads
    from the data; times are turned into samples here). Measured against
    filters tuned per record on the truth (docs/reports/tuned/report.md); not
    meant to be tuned by a user.

    n_filters constant-velocity Kalman filters, tracking indices log-spaced
    from 10^log10_lambda_min (averages a whole record) to 10^log10_lambda_max
    (follows every sample), then n_accel constant-acceleration ones
    (:func:`ca_gains`), tracking indices log-spaced from 10^log10_accel_min to
    10^log10_accel_max (a CV filter lags a smoothly accelerating motion; a CA
    one follows it with a third-order error); tau_l_s: memory of their log-likelihoods; r_tau_s:
    memory of the noise-level estimate; reset: log-likelihood gap below the
    best at which a filter restarts from the best (as an IMM mixes); n_lag:
    lags of the 4th-difference noise estimates; huber: their clip; tau_angle_s:
    time constant of the angle feedback (0 = off); clip_sigma: each filter
    but the fastest updates its state with its innovation clipped at this many sigma (a lone
    spike moves the filters that did not follow it by a negligible amount);
    spectral: the ratio of the spectral noise floor (:func:`spectral_params`; negative = off);
    pass_tau_s, pass_gain: the pass-through (smoothing of the most likely filter's gain, and the
    gains (lo, hi) between which the output moves from the bank's mean to the raw sample;
    pass_tau_s = 0: off); line: the spectral line test's threshold in units of the white-noise
    level of one bin (:func:`spectral_floor`; 0 = off)."""
    fs = float(sample_rate_hz)
    if (not 1 <= n_filters or not 0 <= n_accel or not n_filters + n_accel <= MO_MAX_NF
            or not 1 <= n_lag <= MO_MAX_NLAG):
        raise ValueError("motion: n_filters >= 1 and n_accel >= 0 must sum to at most %d, and n_lag be 1..%d"
                         % (MO_MAX_NF, MO_MAX_NLAG))
    p = [float(n_filters), math.exp(-1.0 / (tau_l_s * fs)), 1.0 - 1.0 / (r_tau_s * fs), float(reset),
         float(n_lag), float(huber), 1.0 / (tau_angle_s * fs) if tau_angle_s > 0 else 0.0,
         float(clip_sigma) * float(clip_sigma), 0.0]
    gains = [0.0] * (5 * MO_MAX_NF)      # runs: alpha, beta, log S/R, gamma, lam^2
    for i in range(n_filters):
        e = log10_lambda_min + (log10_lambda_max - log10_lambda_min) * i / max(n_filters - 1, 1)
        a, b, ls = cv_gains(10.0 ** e)
        gains[i], gains[MO_MAX_NF + i], gains[2 * MO_MAX_NF + i] = a, b, ls
        gains[4 * MO_MAX_NF + i] = b * b / (1.0 - a)      # lam^2 (S_Q), as the bank computed it before
    for c in range(n_accel):
        i = n_filters + c
        e = log10_accel_min + (log10_accel_max - log10_accel_min) * c / max(n_accel - 1, 1)
        a, b, g, ls, lam2 = ca_gains(10.0 ** e)
        gains[i], gains[MO_MAX_NF + i], gains[2 * MO_MAX_NF + i] = a, b, ls
        gains[3 * MO_MAX_NF + i], gains[4 * MO_MAX_NF + i] = g, lam2
    pt = [1.0 / max(pass_tau_s * fs, 1.0) if pass_tau_s > 0 else 0.0, float(pass_gain[0]), float(pass_gain[1])]
    sp = spectral_params(p[2], spectral)
    ch = rank_mean(MO_HI_NB)
    ln = [float(line) / ch if line > 0 and sp[0] > 0 else 0.0]
    cu = [0.0, 0.0, 0.0]
    if cusum_tau_s > 0 and cusum_weight > 0:
        fc = math.exp(-1.0 / max(cusum_tau_s * fs, 1.0))
        cu = [fc, float(cusum_weight), float(cusum_sigma) ** 2 / (1.0 - fc * fc)]
    sph = [1.0 / (ch * (0.375 * MO_SPEC_N)) if sp[0] > 0 else 0.0]   # as P_MO_SPEC, for MO_HI_NB bins
    return p + gains + [0.0] + sp + pt + ln + cu + [float(n_accel)] + sph


def rank_mean(n_bins: int) -> float:
    """Mean of the MO_SPEC_RANK-th smallest of ``n_bins`` independent exponential
    variables of mean 1 (Renyi): sum over i < MO_SPEC_RANK of 1 / (n_bins - i); the
    spectral floors' order-statistic bias (:func:`spectral_params`)."""
    c = 0.0
    for i in range(MO_SPEC_RANK):
        c += 1.0 / (n_bins - i)
    return c


def spectral_params(b: float, ratio: float = 1.0) -> list[float]:
    """Parameters of :func:`spectral_floor` (p[P_MO_SPEC ...]) for the per-sample
    forgetting factor ``b`` of the noise level; the spectral estimate replaces
    the lag estimate where it is below it by more than ``ratio`` (1.0: R is the
    smaller of the two; 0.0: the spectral one alone; negative: off).

    Scale: for white noise of variance R each bin's |X|^2 is R sum(w^2) times an
    exponential variable of mean 1 (chi-square, 2 degrees of freedom), and the
    j-th smallest of M independent ones has the mean sum_{i<j} 1 / (M - i)
    (Renyi); sum(w^2) = 3 N / 8 for the periodic Hann window. Returns
    p[P_MO_SPEC:P_MO_PT]; the line test's own scale (MO_HI_NB bins,
    p[P_MO_SPECH]) is set by :func:`motion_params`."""
    c = rank_mean(MO_SPEC_NB)
    bb = 1.0
    for _ in range(MO_SPEC_N):
        bb *= b
    cos_tab = [math.cos(2.0 * math.pi * m / MO_SPEC_N) for m in range(MO_SPEC_N)]
    if ratio < 0.0:
        return [0.0, bb, 0.0] + cos_tab
    return [1.0 / (c * (0.375 * MO_SPEC_N)), bb, float(ratio)] + cos_tab


def butter_sos(order: int, cutoff_hz: float, sample_rate_hz: float) -> list[tuple[float, float, float, float, float]]:
    """Digital Butterworth low-pass as second-order sections [(b0, b1, b2, a1, a2)].

    The analog prototype's poles exp(i pi (2k + N + 1) / (2N)), scaled to the
    pre-warped cutoff 2 fs tan(pi fc / fs), mapped by the bilinear transform;
    zeros at z = -1; each section has unit gain at DC. Same response as
    ``scipy.signal.butter(order, cutoff_hz, fs=sample_rate_hz, output="sos")``
    (tested), with no scipy needed (the FMU runs this).
    """
    import cmath
    import math
    fs2 = 2.0 * sample_rate_hz
    wc = fs2 * math.tan(math.pi * cutoff_hz / sample_rate_hz)
    sos = []
    for k in range(order // 2):
        sp = wc * cmath.exp(1j * math.pi * (2 * k + order + 1) / (2 * order))
        zp = (fs2 + sp) / (fs2 - sp)
        a1 = -2.0 * zp.real
        a2 = abs(zp) ** 2
        g = (1.0 + a1 + a2) / 4.0
        sos.append((g, 2.0 * g, g, a1, a2))
    if order % 2:
        zp = (fs2 - wc) / (fs2 + wc)
        g = (1.0 - zp) / 2.0
        sos.append((g, g, 0.0, -zp, 0.0))
    return sos


def init_state(p: Buf) -> list[float]:
    """A fresh state buffer (list of floats) for parameters ``p``."""
    n = int(p[P_ORDER])
    s = [0.0] * layout(n)[6]
    restart(p, s)
    return s


def restart(p: Buf, s: MutBuf) -> None:
    """Re-initialise identification and filter (a gyro restart), in place.

    The cumulative counters S_NREJ, S_NREOPEN, S_NCLAMP and S_NHEAL are kept.
    """
    n = int(p[P_ORDER])
    m = n + 1
    o_theta, o_prls, o_x, o_p, o_z, o_w, total = layout(n)
    nrej = s[S_NREJ]
    nreopen = s[S_NREOPEN]
    nclamp = s[S_NCLAMP]
    nheal = s[S_NHEAL]
    for i in range(total - GB_N):    # the bias tracking's block (M_BIAS, the last) is kept
        s[i] = 0.0
    s[S_NREJ] = nrej
    s[S_NREOPEN] = nreopen
    s[S_NCLAMP] = nclamp
    s[S_NHEAL] = nheal
    for i in range(m):
        s[o_prls + i * m + i] = p[P_P0_RLS]
        s[o_p + i * m + i] = p[P_P0_KF]
    s[S_R] = p[P_R0] if p[P_R0] > 0.0 else p[P_R_FLOOR]
    s[S_Q] = p[P_Q0]


def _rls_gain(p, s, o_prls, o_z, o_w, n, m):
    """g = P h into the scratch vector w (h = regressor, h[n] = 1); returns
    the denominator lam + h' P h of Eq. (9)-(11)."""
    for i in range(m):
        acc = s[o_prls + i * m + n]
        for j in range(n):
            acc += s[o_prls + i * m + j] * s[o_z + j]
        s[o_w + i] = acc
    den = p[P_LAM] + s[o_w + n]
    for j in range(n):
        den += s[o_z + j] * s[o_w + j]
    return den


def rls_update(p: Buf, s: MutBuf, z: float) -> float:
    """One RLS step of the improved AR(n) model, Eq. (8)-(11); returns e.

    Regressor Z_(h+1) = [z_{k-1} ... z_{k-n} 1] (Eq. 8); the past samples are
    kept in the state. Does nothing (returns 0) until n past samples exist.
    """
    n = int(p[P_ORDER])
    m = n + 1
    lam = p[P_LAM]
    o_theta, o_prls, o_x, o_p, o_z, o_w, total = layout(n)
    e = 0.0
    if s[S_K] >= n:
        den = _rls_gain(p, s, o_prls, o_z, o_w, n, m)
        if not (den >= lam):
            # h' P h < 0: rounding has cost P its positive definiteness along
            # the regressor (a huge sample after a constant stretch): restart
            # the covariance from its prior, keep the estimate, recompute
            for i in range(m * m):
                s[o_prls + i] = 0.0
            for i in range(m):
                s[o_prls + i * m + i] = p[P_P0_RLS]
            den = _rls_gain(p, s, o_prls, o_z, o_w, n, m)
        pred = s[o_theta + n]
        for j in range(n):
            pred += s[o_z + j] * s[o_theta + j]
        e = z - pred
        inv_den = 1.0 / den
        # Eq. (11): theta += K e, K = P h / (lam + h' P h)
        for i in range(m):
            s[o_theta + i] += s[o_w + i] * inv_den * e
        # Eq. (10), sign corrected: P = (P - g g' / den) / lam, kept symmetric.
        # Bounded forgetting: the division by lam inflates every direction,
        # also those the regressors never excite (a constant or quantised
        # record), where P would grow as lam^-k into overflow. It is skipped
        # when it would lift the trace of P above its prior's, (n+1) p0_rls.
        # With lam = 1 nothing changes (the paper's RLS).
        scale = 1.0 / lam
        if lam != 1.0:
            tr = 0.0
            for i in range(m):
                tr += s[o_prls + i * m + i] - s[o_w + i] * inv_den * s[o_w + i]
            if tr * scale > m * p[P_P0_RLS]:
                scale = 1.0
        for i in range(m):
            gi = s[o_w + i] * inv_den
            for j in range(i, m):
                v = (s[o_prls + i * m + j] - gi * s[o_w + j]) * scale
                s[o_prls + i * m + j] = v
                s[o_prls + j * m + i] = v
    # shift the regressor history: z_hist[0] = z_k
    for j in range(n - 1, 0, -1):
        s[o_z + j] = s[o_z + j - 1]
    s[o_z] = z
    return e


def kf_predict(p: Buf, s: MutBuf, q: float) -> float:
    """Time update on the AR state model, Eq. (34); returns the prediction of z.

    X = [z_k ... z_{k-n+1}, c], A = [[phi_1..phi_n, 1], [I 0 0], [0 .. 0 1]].
    P_pred = A P A' + q e1 e1'. Done in O(m^2) using the companion structure.
    """
    n = int(p[P_ORDER])
    m = n + 1
    o_theta, o_prls, o_x, o_p, o_z, o_w, total = layout(n)
    # state: x0 <- sum phi_i x_{i-1} + c ; shift
    x0 = s[o_x + n]
    for i in range(n):
        x0 += s[o_theta + i] * s[o_x + i]
    for i in range(n - 1, 0, -1):
        s[o_x + i] = s[o_x + i - 1]
    s[o_x] = x0
    # w = first row of A P
    for j in range(m):
        acc = s[o_p + n * m + j]
        for i in range(n):
            acc += s[o_theta + i] * s[o_p + i * m + j]
        s[o_w + j] = acc
    # shift the (n-1)x(n-1) block and the c column down the diagonal
    for i in range(n - 1, 0, -1):
        for j in range(n - 1, 0, -1):
            s[o_p + i * m + j] = s[o_p + (i - 1) * m + (j - 1)]
        v = s[o_p + (i - 1) * m + n]
        s[o_p + i * m + n] = v
        s[o_p + n * m + i] = v
    # first row / column: (A P A')[0, j] = w . A[j, :]
    p00 = s[o_w + n] + q
    for i in range(n):
        p00 += s[o_theta + i] * s[o_w + i]
    s[o_p] = p00
    for j in range(1, n):
        s[o_p + j] = s[o_w + j - 1]
        s[o_p + j * m] = s[o_w + j - 1]
    s[o_p + n] = s[o_w + n]
    s[o_p + n * m] = s[o_w + n]
    return x0


def kf_update(p: Buf, s: MutBuf, v: float, r: float) -> float:
    """Measurement update with H = [1 0 ... 0], Eq. (35); returns S = HPH' + r.

    K = P H' / S, x += K v, P = P - P H' H P / S (equal to the Joseph form for
    this optimal gain; PD because S > P00 when r > 0).
    """
    n = int(p[P_ORDER])
    m = n + 1
    o_theta, o_prls, o_x, o_p, o_z, o_w, total = layout(n)
    svar = s[o_p] + r
    inv_s = 1.0 / svar
    for i in range(m):
        s[o_w + i] = s[o_p + i * m]          # u = P H'
    for i in range(m):
        s[o_x + i] += s[o_w + i] * inv_s * v
    for i in range(m):
        ki = s[o_w + i] * inv_s
        for j in range(i, m):
            val = s[o_p + i * m + j] - ki * s[o_w + j]
            s[o_p + i * m + j] = val
            s[o_p + j * m + i] = val
    # keep the diagonal strictly positive (c becomes exactly known only at k=inf)
    for i in range(m):
        if s[o_p + i * m + i] < 1e-300:
            s[o_p + i * m + i] = 1e-300
    return svar


def start_filter(p: Buf, s: MutBuf) -> None:
    """(Re)start the filter from the identified model at the end of warm-up.

    X = [z_{k-1} ... z_{k-n}, c_rls] (the last n raw samples and the RLS
    constant); P = diag(R, ..., R, r_floor) (see :func:`tie_c`).
    """
    n = int(p[P_ORDER])
    m = n + 1
    o_theta, o_prls, o_x, o_p, o_z, o_w, total = layout(n)
    for i in range(m * m):
        s[o_p + i] = 0.0
    for i in range(n):
        s[o_x + i] = s[o_z + i]
        s[o_p + i * m + i] = s[S_R]
    tie_c(p, s)


def tie_c(p: Buf, s: MutBuf) -> None:
    """Set the filter's c state to the RLS estimate of c (Eq. 4).

    The RLS identifies phi and c jointly; least squares with an intercept keeps
    the model's mean c / (1 - sum phi) at the data mean even while phi and c
    are still converging (they are nearly collinear when the mean is large).
    Were c a free filter state with no process noise (A of Eq. 34 read
    literally), its variance would collapse within seconds while phi still
    moves, and the filter would lock onto a wrong mean (measured: at a
    constant 5 deg/s the SHAKF settled at 0.77 deg/s). So c is a known input
    of the state model: x_c = c_rls, with zero cross-covariance and a
    negligible variance (r_floor) that keeps P positive definite.
    """
    n = int(p[P_ORDER])
    m = n + 1
    o_theta, o_prls, o_x, o_p, o_z, o_w, total = layout(n)
    s[o_x + n] = s[o_theta + n]
    for i in range(n):
        s[o_p + i * m + n] = 0.0
        s[o_p + n * m + i] = 0.0
    s[o_p + n * m + n] = p[P_R_FLOOR]


def ar_stable(a: Buf, o_a: int, n: int, w: MutBuf, o_w: int) -> bool:
    """True if the AR(n) model with phi_i = a[o_a + i - 1] is stable.

    Tests the polynomial 1 - phi_1 q^-1 - ... - phi_n q^-n (Eq. 4) with the
    Schur-Cohn step-down recursion: stable (every root strictly inside the unit
    circle) iff every reflection coefficient has |k| < 1. ``w[o_w:o_w + n]`` is
    scratch. O(n^2); used once per run of rejected samples.
    """
    for i in range(n):
        w[o_w + i] = -a[o_a + i]          # a_i of 1 + a_1 q^-1 + ... + a_n q^-n
    for order in range(n, 0, -1):
        kr = w[o_w + order - 1]
        if not (kr * kr < 1.0):
            return False
        den = 1.0 - kr * kr
        lo = 1
        hi = order - 1
        while lo < hi:                    # a_i <- (a_i - k a_{order-i}) / (1 - k^2)
            al = w[o_w + lo - 1]
            ah = w[o_w + hi - 1]
            w[o_w + lo - 1] = (al - kr * ah) / den
            w[o_w + hi - 1] = (ah - kr * al) / den
            lo += 1
            hi -= 1
        if lo == hi:
            al = w[o_w + lo - 1]
            w[o_w + lo - 1] = (al - kr * al) / den
    return True


def gate(p: Buf, s: MutBuf, z: float) -> int:
    """Innovation gate against single wild samples (not in the paper).

    ``z`` is the centred sample (see :func:`step`). Predicts the innovation
    v = z - H X_pred and its variance S = H P_pred H' + R with the model as it
    stands (before the RLS sees z). If v^2 <= k^2 S (k = outlier_sigma) the
    sample is accepted: returns 0.

    Otherwise it is rejected (returns 1): the filter only makes its time update
    (Eq. 34), the output is the prediction (left in ``s[S_OUT]``, centred), the
    RLS regressor history receives the prediction instead of z, and neither the
    RLS nor the R/Q estimators (Eq. 33, 26) see the sample. The prediction runs
    the identified AR model forward, which is only safe for a stable model: at
    the first rejection of a run the model is tested (:func:`ar_stable`) and,
    if it is unstable, the run holds the last filtered value instead of
    extrapolating (an unstable AR(n) grows exponentially: 1e15 deg/s within
    20 samples on real logs).

    After ``outlier_run`` consecutive rejections the next outlying sample is
    taken as a real rate change: the filter restarts at that sample (as for a
    gyro restart) and 2 is returned so that :func:`step` processes it.
    """
    n = int(p[P_ORDER])
    m = n + 1
    o_theta, o_prls, o_x, o_p, o_z, o_w, total = layout(n)
    tie_c(p, s)        # idempotent: step() ties c again after the RLS update
    # prediction with the same operations as kf_predict
    xp = s[o_x + n]
    for i in range(n):
        xp += s[o_theta + i] * s[o_x + i]
    # (A P A')_00 + q with a = [phi_1..phi_n, 1]; after tie_c the c row and
    # column of P are zero but for P[n][n]
    p00 = s[o_p + n * m + n]
    for i in range(n):
        row = o_p + i * m
        acc = 0.0
        for j in range(n):
            acc += s[o_theta + j] * s[row + j]
        p00 += s[o_theta + i] * acc
    svar = p00 + s[S_Q] + s[S_R]
    v = z - xp
    k = p[P_OUTLIER_SIGMA]
    if not (v * v > k * k * svar):
        s[S_REJRUN] = 0.0
        return 0
    if s[S_REJRUN] >= p[P_OUTLIER_RUN]:
        # a run of outlying samples: a real change of rate, not a wild sample
        restart(p, s)
        s[S_NREOPEN] += 1.0
        return 2
    if s[S_REJRUN] == 0.0:
        s[S_HOLD] = 0.0 if ar_stable(s, o_theta, n, s, o_w) else 1.0
    if s[S_HOLD] == 0.0:
        x0 = kf_predict(p, s, s[S_Q])
    else:
        x0 = s[o_x]       # unstable model: hold, do not propagate the state
    for j in range(n - 1, 0, -1):
        s[o_z + j] = s[o_z + j - 1]
    s[o_z] = x0
    s[S_NREJ] += 1.0
    s[S_REJRUN] += 1.0
    s[S_INNOV] = v
    s[S_SVAR] = svar
    s[S_RLS_ERR] = 0.0
    s[S_K] += 1.0
    s[S_OUT] = x0
    return 1


def filter_step(p: Buf, s: MutBuf, z: float) -> float:
    """Identification and filter for one accepted, centred sample ``z``;
    returns the centred filter estimate (or ``z`` itself while warming up).
    Called by :func:`step`, which owns restarts, the gate and the envelope."""
    n = int(p[P_ORDER])
    method = p[P_METHOD]
    floor = p[P_R_FLOOR]
    o_theta, o_prls, o_x, o_p, o_z, o_w, total = layout(n)
    k = s[S_K]
    m = n + 1

    # -- end of warm-up: noise levels and a filter restarted from the model
    converged = k >= p[P_WARMUP]
    if s[S_CONV] == 0.0:
        auto = 0.5 * s[S_S2]
        if auto < floor:
            auto = floor
        # warm-up: noise levels follow the AR prediction error (auto) or p
        s[S_Q] = p[P_Q0] if p[P_Q0] > 0.0 else auto
        s[S_R] = p[P_R0] if p[P_R0] > 0.0 else auto
        if converged:
            s[S_CONV] = 1.0
            s[S_KD] = 0.0
            s[S_BK] = p[P_B]
            start_filter(p, s)

    # -- online identification of the improved AR(n) model, Eq. (4), (8)-(11)
    e = rls_update(p, s, z)
    s[S_RLS_ERR] = e
    if k >= 10.0 * m:  # skip RLS start-up errors in the noise level
        s[S_NS2] += 1.0
        s[S_S2] += (e * e - s[S_S2]) / s[S_NS2]

    if k == 0.0:
        # first sample after a restart: state = [z ... z, 0], nothing to filter
        for i in range(n):
            s[o_x + i] = z
        s[o_x + n] = 0.0
        s[S_K] = 1.0
        s[S_OUT] = z
        s[S_INNOV] = 0.0
        return z

    tie_c(p, s)
    q = s[S_Q]
    xp = kf_predict(p, s, q)
    v = z - xp                        # innovation, Eq. (16) with r = 0
    p00 = s[o_p]
    r = s[S_R]
    if s[S_CONV] == 1.0 and (method == METHOD_SHAKF or method == METHOD_SH_CLASSIC):
        b = p[P_B]
        g = p[P_GAMMA]
        if method == METHOD_SHAKF and v * v > g * g * (p00 + r):
            # Eq. (32) violated: v'v > gamma^2 tr E[v v'], with E[v v'] =
            # H P H' + R_{k-1} (Eq. 31): restart d_k from k = 0 (d_0 = 1)
            s[S_KD] = 0.0
            s[S_NRESET] += 1.0
            s[S_BK] = b
        else:
            s[S_KD] += 1.0
            s[S_BK] *= b
            if s[S_BK] < 1e-290:    # b^(k+1) has vanished: avoid denormals
                s[S_BK] = 0.0
        d = (1.0 - b) / (1.0 - s[S_BK])    # d_k = (1-b)/(1-b^(k+1))
        if method == METHOD_SHAKF:
            r = (1.0 - d) * r + d * v * v               # Eq. (33)
        else:
            r = (1.0 - d) * r + d * (v * v - p00)       # Eq. (22)
        if r < floor:
            r = floor
        s[S_R] = r
        svar = kf_update(p, s, v, r)
        k0 = p00 / svar
        # Eq. (26) restricted to Q = q e1 e1' (B of Eq. 34): q + K0^2 (v^2 - S)
        q = q + d * k0 * k0 * (v * v - svar)
        if q < floor:      # > 0: x0 never becomes exactly c + phi.x (P stays PD)
            q = floor
        s[S_Q] = q
    else:
        svar = kf_update(p, s, v, r)

    s[S_INNOV] = v
    s[S_SVAR] = svar
    s[S_K] = k + 1.0
    out = z
    if s[S_CONV] == 1.0 and method != METHOD_NONE:
        out = s[o_x]
    s[S_OUT] = out
    return out


def sos_cascade(p: Buf, s: MutBuf, o: int, z: float) -> float:
    """One sample ``z`` through the Butterworth cascade of p[P_SOS ...]
    (transposed direct form II, as ``scipy.signal.sosfilt``), its delays at
    s[o], s[o + 1] (first section), ...; returns the output."""
    y = z
    for i in range(int(p[P_LP_NSEC])):
        c = P_SOS + 5 * i
        x = y
        y = p[c] * x + s[o + 2 * i]
        s[o + 2 * i] = p[c + 1] * x - p[c + 3] * y + s[o + 2 * i + 1]
        s[o + 2 * i + 1] = p[c + 2] * x - p[c + 4] * y
    return y


def lowpass_step(p: Buf, s: MutBuf, z: float) -> float:
    """One sample of the Butterworth cascade (:func:`sos_cascade`) on the
    centred sample ``z``; the delays start at 0, which is the steady state for
    the first sample (centred to 0)."""
    y = sos_cascade(p, s, ext_offset(p), z)
    s[S_K] += 1.0
    s[S_CONV] = 1.0
    return y


def one_euro_step(p: Buf, s: MutBuf, z: float) -> float:
    """One centred sample ``z`` through the 1-euro filter (Casiez, Roussel, Vogel,
    CHI 2012): a first-order low-pass whose cutoff is p[P_OE_MIN] + p[P_OE_BETA] x
    |dz/dt|, dz/dt the rate's change per second through a first-order low-pass of
    cutoff p[P_OE_DCUT]; each low-pass's weight is alpha = 1 / (1 + fs / (2 pi fc)).
    The first sample since the restart is passed through (the filter starts on it)."""
    o = ext_offset(p)
    if s[S_K] == 0.0:
        x = z
        s[o + OE_DX] = 0.0
    else:
        fs = p[P_FS]
        ad = 1.0 / (1.0 + fs / (6.283185307179586 * p[P_OE_DCUT]))
        dx = s[o + OE_DX]
        dx = dx + ad * ((z - s[o + OE_ZP]) * fs - dx)
        s[o + OE_DX] = dx
        a = 1.0 / (1.0 + fs / (6.283185307179586 * (p[P_OE_MIN] + p[P_OE_BETA] * abs(dx))))
        x = s[o + OE_X]
        x = x + a * (z - x)
    s[o + OE_X] = x
    s[o + OE_ZP] = z
    s[S_K] += 1.0
    s[S_CONV] = 1.0
    return x


def exp_neg(x: float) -> float:
    """exp(x) for -30 <= x <= 0 (0.0 below): the Taylor polynomial of degree 2
    at x / 256, squared 8 times; relative error < 3e-6 for x >= -1, < 2 % at
    -20 (weights below 2e-9 there). The weights of the motion bank need no
    more, and gdcore.c repeats these operations, so C and Python agree bit
    for bit without depending on libm's exp (and it is several times cheaper)."""
    if x < -30.0:
        return 0.0
    u = x * 0.00390625
    e = 1.0 + u * (1.0 + u * 0.5)
    for _ in range(8):
        e = e * e
    return e


def log1m_small(g: float) -> float:
    """-log(1 - g) for 0 <= g <= 0.125 by its series to g^8 (error < 1e-9
    relative), with math.log above: the log-likelihood penalty of the
    growing-memory gain, one per sample (gdcore.c repeats these operations)."""
    if g > 0.125:
        return -math.log(1.0 - g)
    return g * (1.0 + g * (0.5 + g * (0.3333333333333333 + g * (0.25 + g * (0.2 + g * (0.16666666666666666
        + g * (0.14285714285714285 + g * 0.125)))))))


def _forget_weight(b, bk):
    """The Sage-Husa weight d_k = (1 - b) / (1 - b^(k+1)) for ``bk`` = b^(k+1); (1 - b) itself, with
    no division, once 1 - bk rounds to 1 (the same number: x / 1.0 == x)."""
    den = 1.0 - bk
    if den == 1.0:
        return 1.0 - b
    return (1.0 - b) / den


def spectral_floor(p: Buf, s: MutBuf, o: int, z: float, k: float) -> float:
    """The sensor's white-noise variance R read from the spectrum:
    a floor that vibration tones do not lift. Returns the current estimate,
    (deg/s)^2, 0.0 before the first block. ``o``: offset of motion's state,
    ``z``: the raw centred sample, ``k``: samples since the restart.

    Every MO_SPEC_N samples: the Hann-windowed DFT of the block at the
    MO_SPEC_NB bins MO_SPEC_K0, MO_SPEC_K0 + 2, ... (0.0625-0.48 fs: above
    the motion of every profile, and wide enough that a vibration lifting
    the whole upper half of the band, as on a quadrotor at 120 Hz, leaves
    bins below it; every other bin: the Hann window correlates
    neighbours); all those bins are even, so the windowed block is folded in
    two as it comes (x[n] + x[n + N/2]) and the DFT runs over N/2 samples at
    the block's end (MO_SPEC_NB x N/2 multiply-adds per block: O(1) per
    sample amortised); the MO_SPEC_RANK-th smallest |X|^2 of them times p[P_MO_SPEC]
    (:func:`spectral_params`: chi-square order-statistic bias and the window's
    sum of squares) is the block's estimate: a few tones occupy a few bins and
    cannot move a low quantile. The blocks are averaged with the Sage-Husa
    weight d_k of Eq. (33) (forgetting p[P_MO_SBB] per block), each clipped at
    p[P_MO_HUBER] x the mean once 4 blocks are in; a block holding a sample
    beyond MO_SPEC_ZMAX (or not finite) is left out (no overflow in the state).

    The line test (p[P_MO_LINE] > 0) keeps its own floor, from the same
    pass: the MO_SPEC_RANK-th smallest of the MO_HI_NB bins from MO_HI_J0
    (0.25-0.5 fs) times p[P_MO_SPECH], smoothed as above in M_SRH (M_SBKH):
    a noise rising towards the Nyquist frequency (a FOG's angle
    quantisation) lifts those bins and their floor alike, so it does not
    read as a line against the lower R."""
    n_blk = MO_SPEC_N
    half = n_blk // 2
    if k == 0.0:
        s[o + M_SPOS] = 0.0
        s[o + M_SR] = 0.0
        s[o + M_SBK] = 1.0
        s[o + M_SBAD] = 0.0
        s[o + M_LRAT] = 0.0
        s[o + M_LON] = 0.0
        s[o + M_SRH] = 0.0
        s[o + M_SBKH] = 1.0
    if not abs(z) < MO_SPEC_ZMAX:
        z = 0.0
        s[o + M_SBAD] = 1.0
    n = int(s[o + M_SPOS])
    c = P_MO_COS
    x = (0.5 - 0.5 * p[c + n]) * z
    if n < half:
        s[o + M_SFOLD + n] = x
    else:
        s[o + M_SFOLD + n - half] += x      # even bins: x[n] and x[n + N/2] share every twiddle
    n += 1
    if n < n_blk:
        s[o + M_SPOS] = float(n)
        return s[o + M_SR]
    s[o + M_SPOS] = 0.0
    # |X|^2 of the folded block (N/2 samples) at its bins K0/2 + j, j = 0..NB-1 (the 128-point
    # DFT's K0 + 2 j): Goertzel's recursion per bin, w = y + 2 cos(t) w1 - w2, all bins side by side
    # (a loop over the bins inside the loop over the samples: data-parallel, no table look-up)
    w1 = [0.0] * MO_SPEC_NB
    w2 = [0.0] * MO_SPEC_NB
    cf = [2.0 * p[c + MO_SPEC_K0 + 2 * j] for j in range(MO_SPEC_NB)]
    for n in range(half):
        y = s[o + M_SFOLD + n]
        for j in range(MO_SPEC_NB):
            w0 = y + cf[j] * w1[j] - w2[j]
            w2[j] = w1[j]
            w1[j] = w0
    # the MO_SPEC_RANK smallest |X|^2 of all the bins and of the MO_HI_NB from MO_HI_J0, ascending
    # (insertion), and the highest from MO_LINE_J0 on
    low = [0.0] * MO_SPEC_RANK
    lowh = [0.0] * MO_SPEC_RANK
    nl = 0
    nh = 0
    top = 0.0
    for j in range(MO_SPEC_NB):
        pw = w1[j] * w1[j] + w2[j] * w2[j] - cf[j] * w1[j] * w2[j]
        if j >= MO_LINE_J0 and pw > top:
            top = pw
        if j >= MO_HI_J0:
            nh = _insert_low(lowh, nh, pw)
        nl = _insert_low(low, nl, pw)
    if s[o + M_SBAD] != 0.0:
        s[o + M_SBAD] = 0.0
        return s[o + M_SR]
    m = _floor_update(p, s, o + M_SR, o + M_SBK, low[MO_SPEC_RANK - 1] * p[P_MO_SPEC])
    if p[P_MO_LINE] > 0.0:
        # line test: a bin near the Nyquist frequency far above the high bins' floor, in this block
        # and the last (a tone, not the edge of a lone step): the bank would average it away
        mh = _floor_update(p, s, o + M_SRH, o + M_SBKH, lowh[MO_SPEC_RANK - 1] * p[P_MO_SPECH])
        lr = top * p[P_MO_SPECH]
        th = p[P_MO_LINE] * mh
        s[o + M_LON] = 1.0 if lr > th and s[o + M_LRAT] > th else 0.0
        s[o + M_LRAT] = lr
    return m


def _insert_low(low, nl, pw):
    """Keep in ``low`` (ascending, ``nl`` filled) the MO_SPEC_RANK smallest values seen,
    with ``pw`` offered (insertion). Returns the new count of filled entries."""
    if nl < MO_SPEC_RANK:
        i = nl
        nl += 1
    elif pw < low[MO_SPEC_RANK - 1]:
        i = MO_SPEC_RANK - 1
    else:
        return nl
    while i > 0 and low[i - 1] > pw:
        low[i] = low[i - 1]
        i -= 1
    low[i] = pw
    return nl


def _floor_update(p, s, i_m, i_bk, xb):
    """One block's estimate ``xb`` into the smoothed floor s[i_m] (:func:`spectral_floor`):
    Sage-Husa weight from s[i_bk] (forgetting p[P_MO_SBB] per block), clipped at
    p[P_MO_HUBER] x the mean once d < 1/4. Returns the new floor, (deg/s)^2."""
    bb = p[P_MO_SBB]
    s[i_bk] *= bb
    d = _forget_weight(bb, s[i_bk])
    m = s[i_m]
    if d < 0.25 and xb > p[P_MO_HUBER] * m:
        xb = p[P_MO_HUBER] * m
    m += d * (xb - m)
    if m == 0.0:
        s[i_bk] = 1.0     # a constant input so far: the mean starts with the first change
    s[i_m] = m
    return m


def motion_step(p: Buf, s: MutBuf, z: float) -> float:
    """``method="motion"``: one centred sample ``z`` through a bank of
    constant-velocity Kalman filters weighted by their likelihoods (not in the
    paper).

    Model of the p[P_MO_NF] constant-velocity (CV) filters: state [omega, a], the
    true rate and its change per sample; omega += a, a += white noise (white-noise
    acceleration), z = omega + white noise of variance R. They differ only in their
    tracking index lam (q = lam^2 R): from one that averages the whole record to one
    that follows every sample. The p[P_MO_NCA] constant-acceleration (CA) filters
    after them (lanes P_MO_NF..) add j, the change of a per sample: omega += a + j/2,
    a += j, j += white noise (:func:`ca_gains`; gamma updates j); a CV filter lags
    a smoothly accelerating motion, a CA one follows it. Per sample, all O(1):

    * R, the sensor's white-noise level: the mean |4th difference| of the
      samples at lags 1..NLAG (70 R for white noise: E|d4| = sqrt(70 R 2/pi)),
      each Huber-clipped at ``huber`` x its mean and averaged with the
      Sage-Husa weight d_k = (1-b)/(1-b^(k+1)) of Eq. (22)/(33); R is the
      smallest of them. Motion only adds to a 4th difference, and a lag-L
      difference is blind to the frequencies m fs / L, so the smallest reads
      the noise under slow manoeuvres and under a vibration tone that the
      lag-1 difference takes for noise (and would erase everything above
      fs/4 with it). Where the spectral floor is on (p[P_MO_SPEC] > 0,
      :func:`spectral_floor`), the spectral estimate replaces it where it is
      below it by more than p[P_MO_SRATIO] (1: R is the smaller of the two): several tones lift every lag's estimate
      (the drone multirotor: 35-80x), not a low quantile of the spectrum.
    * Each filter runs at its steady-state gains (:func:`cv_gains`), or at the
      gains of the least-squares line through all the samples since the
      warm-up when these are larger (its start-up: a growing memory, so the
      slowest filters average from the first sample instead of waiting for
      their Riccati equation).
    * Log-likelihood of each filter, faded: L = f L - (v^2 / S + log S/R) / 2,
      S = R / (1 - g0). The state update uses the innovation clipped at
      ``clip`` sigma (Huber), except in the fastest filter: a filter does not
      chase a jump, it loses likelihood and is restarted from the one that
      followed it (below). The output is the likelihood-weighted mean of the
      rates (weights exp(L - L_max), by :func:`exp_neg`).
    * A filter whose L falls ``reset`` below the best is held there (L
      floored), and if it was already there at the last sample it restarts
      from the best filter's state (the mixing of an IMM): after a manoeuvre
      the slow filters resume averaging where the motion ended, not where
      they lagged. Waiting one sample keeps a lone spike from being copied
      into every filter: the filters that ignored it win again at the next
      sample.
    * Angle feedback: the output is corrected by kappa times the integral of
      (input - output), so over a record the output integrates to the same
      angle as the input (a lagging filter otherwise loses lag x rate change).

    While warming up the filters sit on z and the output is raw (as for the other
    methods): ``P_WARMUP`` samples (``warmup_s``) or, with the spectral floor on,
    until the end of its first block (MO_SPEC_N samples: the noise level is read
    from the lag estimates and that block), whichever comes first; and until the
    noise level is read. The warm-up was ``warmup_s`` alone (1 s at every rate): on
    a 20 s record at rest at 1 kHz, 1000 raw samples dominated the RMSE; the lag
    estimates alone (ending at 10 (n+1) samples) read vibration far above the noise as
    noise and smoothed it away (17x raw's RMSE in the first second of a FOG car record).

    Rigid-body option (``max_motion_hz``, p[P_LP_NSEC] > 0):
    the stated band of interest. The sample first passes a Butterworth
    low-pass flat to max_motion_hz (order 4, -3 dB at twice it:
    :func:`rigid_cutoff_hz`, :func:`sos_cascade`, delays at M_LPD), and the
    bank, its warm-up output and the angle feedback work on that; the noise
    level R is still read from the raw samples (the sensor's own white noise:
    the bank then takes the vibration the low-pass lets through as motion
    where it stands above that noise). The output is the low-passed sample
    from the first sample on (the low-pass needs no warm-up). Off (0 sections):
    no operation changes.
    """
    o = ext_offset(p)
    zr = z                     # raw (centred) sample: the noise level is read from it
    if p[P_LP_NSEC] > 0.0:
        z = sos_cascade(p, s, o + M_LPD, z)
        s[S_CONV] = 1.0
    k = s[S_K]
    nlag = int(p[P_MO_NLAG])
    nh = 4 * nlag + 1
    if k == 0.0:
        s[o + M_BK] = 1.0
        pos = 0
    else:
        pos = int(s[o + M_HPOS]) + 1
        if pos >= nh:
            pos = 0
    s[o + M_HPOS] = float(pos)
    s[o + M_HIST + pos] = zr
    rs = 0.0
    if p[P_MO_SPEC] > 0.0:
        rs = spectral_floor(p, s, o, zr, k)
    if k >= 4.0 * nlag:
        b = p[P_MO_BR]
        s[o + M_BK] *= b
        d = _forget_weight(b, s[o + M_BK])          # d_k, as in Eq. (33)
        hub = p[P_MO_HUBER]
        clip = d < 0.03125                           # no clip while the mean forms (32 samples)
        least = 0.0
        for j in range(1, nlag + 1):
            d4 = fourth_difference(s, o + M_HIST, pos, nh, j, zr)
            x = abs(d4)
            m = s[o + M_MABS + j - 1]
            # a difference beyond MO_SPEC_ZMAX (or not finite: a lone huge sample)
            # is left out, so the mean stays below it and sig * sig below cannot
            # overflow into an infinite R
            if x < MO_SPEC_ZMAX:
                if clip and x > hub * m:
                    x = hub * m
                m += d * (x - m)
                s[o + M_MABS + j - 1] = m
            if j == 1 or m < least:
                least = m
        if least == 0.0:
            s[o + M_BK] = 1.0      # a constant input so far: the means start with the first change
        sig = least * 0.14980634836659743            # E|N(0, 70 R)| = sqrt(70 R 2/pi)
        r = sig * sig
        if rs > 0.0 and rs * p[P_MO_SRATIO] < r:
            r = rs                 # the spectral floor: vibration tones do not lift it
        if r < p[P_R_FLOOR]:
            r = p[P_R_FLOOR]
        if p[P_MO_RFIX] > 0.0:
            r = p[P_MO_RFIX]       # read from the raw record beforehand (batch.run_offline, max_motion_hz)
        s[o + M_R] = r
    s[S_K] = k + 1.0
    r = s[o + M_R]
    ncv = int(p[P_MO_NF])
    nf = ncv + int(p[P_MO_NCA])      # lanes 0..ncv-1 constant velocity, ncv..nf-1 constant acceleration
    # with the spectral floor on, the warm-up waits for its first block even where warmup_s
    # ends earlier (below 128 Hz): the lag estimates alone read broad vibration as noise (20 s at
    # 100 Hz, vibration over 10-40 % of the Nyquist band 1000x the noise: 75x raw's RMSE, all of it
    # in the second after warmup_s); MO_SPEC_N samples more at most (where its blocks are skipped)
    wu = p[P_WARMUP]
    if p[P_MO_SPEC] > 0.0:
        wu += MO_SPEC_N
    if (k < wu and not (p[P_MO_SPEC] > 0.0 and s[o + M_SR] > 0.0)) or r == 0.0:
        for i in range(nf):
            s[o + MB_X + i] = z
            s[o + MB_A + i] = 0.0
            s[o + MB_L + i] = 0.0
            s[o + MB_H + i] = 0.0
            s[o + MB_J + i] = 0.0
            s[o + M_CUS + i] = 0.0
        s[o + M_GRD] = 0.0
        if p[P_LP_NSEC] == 0.0 and s[o + M_NW] == 0.0:
            return warmup_output(p, s, o, z, k, pos, nh)
        return z
    s[S_CONV] = 1.0
    gm0 = 0.0
    gm1 = 0.0
    lgm = 0.0
    if s[o + M_NWC] == 0.0:
        nw = s[o + M_NW] + 1.0
        s[o + M_NW] = nw
        # gains of the least-squares line through the nw samples so far
        gm0 = 2.0 * (2.0 * nw - 1.0) / (nw * (nw + 1.0))
        gm1 = 6.0 / (nw * (nw + 1.0))
        if gm0 < 1.0:
            lgm = log1m_small(gm0)
        # gm0 falls with nw: once it is at or below every filter's steady-state gain it
        # never wins again (nor gm1, used only with it): 0 from the next sample on
        conv = 1.0
        for i in range(nf):
            if gm0 > p[P_MO_G + i]:
                conv = 0.0
        s[o + M_NWC] = conv
    fade = p[P_MO_FADE]
    inv_r = 1.0 / r
    clip2 = p[P_MO_CLIP2]
    # the filters one after another here; gdcore.c runs them side by side, in several
    # passes over the filters, each filter's operations the same and in the same order.
    # Every lane predicts omega + a + j / 2, a + j and updates j with gamma; a CV lane's gamma
    # is 0.0, so its j stays 0.0 and it is the CV filter it was (up to the sign of an exactly
    # zero sum: x + a + 0.0 is +0.0 where x + a is -0.0; no select, so gdcore.c vectorises).
    # While the least-squares line's gain gm0 is above a lane's alpha, the lane (CV or CA)
    # runs at the line's gains and gamma 0 (the same as a CA filter from a diffuse prior)
    for i in range(nf):
        g0 = p[P_MO_G + i]
        g1 = p[P_MO_G + MO_MAX_NF + i]
        ls = p[P_MO_G + 2 * MO_MAX_NF + i]
        g2 = p[P_MO_G + 3 * MO_MAX_NF + i]
        if gm0 > g0:
            g0 = gm0
            ls = lgm
            g2 = 0.0
            if gm1 > g1:
                g1 = gm1
        wp = s[o + MB_X + i] + s[o + MB_A + i] + 0.5 * s[o + MB_J + i]
        ap = s[o + MB_A + i] + s[o + MB_J + i]
        v = z - wp
        u2 = v * v * (1.0 - g0) * inv_r                 # v^2 / S
        lk = fade * s[o + MB_L + i] - 0.5 * (u2 + ls)
        if u2 > clip2 and i != ncv - 1:     # every lane but the fastest CV filter
            v = v * math.sqrt(clip2 / u2)                # Huber: the update sees at most clip sigma
        if p[P_MO_CUS + 1] > 0.0:
            # summed innovation: a filter that lags on accelerating motion leaves innovations
            # of one sign, small each; their faded sum (of the clipped innovations: a lone
            # spike does not count), over its variance under the filter's own model
            # (chi-square, 1 degree), counts against its likelihood beyond its threshold
            cs = p[P_MO_CUS] * s[o + M_CUS + i] + v
            s[o + M_CUS + i] = cs
            x2 = cs * cs * (1.0 - g0) * inv_r - p[P_MO_CUS + 2]
            if x2 > 0.0:
                lk -= 0.5 * p[P_MO_CUS + 1] * x2 * (1.0 - p[P_MO_CUS] * p[P_MO_CUS])
        s[o + MB_X + i] = wp + g0 * v
        s[o + MB_A + i] = ap + g1 * v
        s[o + MB_L + i] = lk
        s[o + MB_J + i] = s[o + MB_J + i] + g2 * v      # 0.0 + 0.0 * v in a CV lane
    lmax = s[o + MB_L]
    best = 0
    for i in range(1, nf):
        if s[o + MB_L + i] > lmax:
            lmax = s[o + MB_L + i]
            best = i
    num = 0.0
    den = 0.0
    wts = [0.0] * nf
    thr = p[P_MO_RESET]
    for i in range(nf):
        x = s[o + MB_L + i] - lmax
        if x < -thr:
            # weight below exp(-thr): left out of the mean; held at the floor,
            # restarted from the best at the second sample there
            if s[o + MB_H + i] == 1.0:
                s[o + MB_X + i] = s[o + MB_X + best]
                s[o + MB_A + i] = s[o + MB_A + best]
                s[o + M_CUS + i] = s[o + M_CUS + best]
                if i >= ncv:
                    s[o + MB_J + i] = s[o + MB_J + best]     # 0.0 from a CV filter
            s[o + MB_L + i] = lmax - thr
            s[o + MB_H + i] = 1.0
        else:
            e = exp_neg(x)
            num += e * s[o + MB_X + i]
            den += e
            s[o + MB_H + i] = 0.0
            wts[i] = e
    y = num / den
    # variance of the mixture: sum of w (g0 R + (rate - y)^2) / sum of w, the
    # posterior variance of a Kalman filter's rate being g0 R
    if p[P_MO_VAR] != 0.0:
        var = 0.0
        for i in range(nf):
            if s[o + MB_H + i] == 0.0:
                g0 = p[P_MO_G + i]
                if gm0 > g0:
                    g0 = gm0
                dw = s[o + MB_X + i] - y
                var += wts[i] * (g0 * r + dw * dw)
        var = var / den
        if not var - var == 0.0:
            var = 1.7976931348623157e308     # overflowed (an input near the largest float): the largest
        s[o + M_PVAR] = var
    # output guard: under the bank's model the output's residual z - y has a variance of at most R
    # ((1 - g0) R for a filter of gain g0), so its faded mean square in units of R stays near 1 or
    # below; where it stands above MO_GUARD_LO the model is wrong there (a step the fastest filter
    # rings after, vibration taken for noise, a lag on a manoeuvre) and the output's error is already
    # larger than the raw sample's (mean square about (m - 1) R): the output (after the pass-through) moves to
    # the raw sample, all the way at MO_GUARD_HI
    d = z - y
    u = d * d * inv_r
    if not u < MO_GUARD_CAP:
        u = MO_GUARD_CAP       # one sample counts at most MO_GUARD_CAP (not finite: as much)
    gm = s[o + M_GRD]
    gm += MO_GUARD_FADE * (u - gm)
    s[o + M_GRD] = gm
    bg = 0.0
    if gm > MO_GUARD_LO:
        bg = (gm - MO_GUARD_LO) / (MO_GUARD_HI - MO_GUARD_LO)
        if bg > 1.0:
            bg = 1.0
    c = P_MO_G + best      # alpha of the most likely filter; its lam^2 at c + 4 MO_MAX_NF
    if p[P_MO_PT] > 0.0:
        # pass-through: where the most likely filter follows nearly every sample (its gain,
        # smoothed, above p[P_MO_PT + 1]) the bank removes little noise and cannot tell a tone
        # near the Nyquist frequency from noise (its prediction of it is poor): the output moves
        # to the raw sample, all the way at p[P_MO_PT + 2] (never worse than raw there)
        g = s[o + M_GEFF]
        g += p[P_MO_PT] * (p[c] - g)
        s[o + M_GEFF] = g
        lo = p[P_MO_PT + 1]
        if g > lo:
            bt = (g - lo) / (p[P_MO_PT + 2] - lo)
            if bt > 1.0:
                bt = 1.0
            y = y + bt * (z - y)
    if bg > 0.0:
        y = y + bg * (z - y)
    if s[o + M_LON] != 0.0:
        y = z              # a line near the Nyquist frequency (spectral_floor): the raw sample
    out = y + p[P_MO_KAPPA] * s[o + M_ANG]
    s[o + M_ANG] += z - out
    s[o + M_BEST] = float(best)
    s[S_INNOV] = z - out
    s[S_SVAR] = r / (1.0 - p[c])
    s[S_R] = r      # reported as the other methods report theirs (R_hat, Q_hat of the FMUs)
    s[S_Q] = p[c + 4 * MO_MAX_NF] * r     # q = lam^2 R of the most likely filter
    return out


def warmup_output(p: Buf, s: MutBuf, o: int, z: float, k: float, pos: int, nh: int) -> float:
    """motion's output during its warm-up (before the bank's first sample; without the rigid-body
    low-pass): the mean of the samples so far where they look like a constant and white noise, else
    the raw sample ``z`` (centred; ``k`` samples before it since the restart, ``pos``: its place in the
    ring M_HIST of ``nh``). The noise level is not read yet; a constant is tested instead: the samples'
    variance about their mean against the noise level from the 4th differences at each lag L = 1..MO_WU_NL
    (mean square / 70, m = k + 1 - 4 L of them). White noise gives a ratio near 1 at every lag (its spread
    about 2.3 / sqrt(m)); motion or vibration adds to the variance more than to the differences of at
    least one lag (a lag-L difference is blind to m fs / L: a tone that lifts one lag's estimate leaves
    another's), so the ratio rises there. The output is z + w (mean - z), w = 1 while every ratio is
    below 1 + MO_WU_LO / sqrt(m), falling linearly to 0 at 1 + MO_WU_HI / sqrt(m), where it stops for the
    rest of the warm-up (and at 1 - MO_WU_LOW / sqrt(m): a lag's differences lifted more than the variance); as it does at a sample beyond MO_WU_SPIKE (in units of the smallest lag
    estimate) from the mean so far, or where the faded mean of those units exceeds MO_WU_GLIM. At rest the
    warm-up's raw samples were most of the error of a 20 s record (the bank reads the noise level from
    its first block of MO_SPEC_N samples); vibration read as noise would be averaged away, so the test
    asks every lag, and stops for good."""
    w0 = o + MO_WU_AT
    if k == 0.0:
        for i in range(4 + MO_WU_NL):
            s[w0 + i] = 0.0
    n = k + 1.0
    mean = s[w0]
    e = z - mean
    mean += e / n
    s[w0] = mean
    s[w0 + 1] += e * (z - mean)                  # Welford: sum of squares about the mean
    nl = MO_WU_NL if 4 * MO_WU_NL < nh else (nh - 1) // 4
    for lag in range(1, nl + 1):
        if k >= 4.0 * lag:
            d4 = fourth_difference(s, o + M_HIST, pos, nh, lag, z)
            s[w0 + 1 + lag] += d4 * d4
    t = 0.0
    for i in range(2 + MO_WU_NL):
        t += s[w0 + i]
    if not t - t == 0.0:                         # a sum overflowed (a huge sample): stop, the state finite
        for i in range(3 + MO_WU_NL):
            s[w0 + i] = 0.0
        s[w0 + 3 + MO_WU_NL] = 1.0
        return z
    if s[w0 + 3 + MO_WU_NL] != 0.0 or n < MO_WU_N0 or not n > 4.0 * nl:
        return z
    var = s[w0 + 1] / (n - 1.0)
    r1 = 0.0
    for lag in range(1, nl + 1):
        rl = s[w0 + 1 + lag] / (70.0 * (n - 4.0 * lag))
        if lag == 1 or rl < r1:
            r1 = rl
    if not r1 > 0.0 or not var - var == 0.0:
        return z
    u = e * e / r1
    g = s[w0 + 2 + MO_WU_NL]
    g += MO_WU_FADE * (u - g)
    s[w0 + 2 + MO_WU_NL] = g
    if u > MO_WU_SPIKE or g > MO_WU_GLIM:
        s[w0 + 3 + MO_WU_NL] = 1.0
        return z
    w = 1.0
    for lag in range(1, nl + 1):
        m = n - 4.0 * lag
        q = var * 70.0 * m / s[w0 + 1 + lag]
        sm = math.sqrt(m)
        hi = 1.0 + MO_WU_HI / sm
        if not q < hi or q <= 1.0 - MO_WU_LOW / sm:
            s[w0 + 3 + MO_WU_NL] = 1.0
            return z
        lo = 1.0 + MO_WU_LO / sm
        if q > lo:
            wl = (hi - q) / (hi - lo)
            if wl < w:
                w = wl
    return z + w * (mean - z)


def _method_step(p, s, zc):
    """One centred sample through the method's own filter (see :func:`step`)."""
    if p[P_METHOD] == METHOD_LOWPASS:
        return lowpass_step(p, s, zc)
    if p[P_METHOD] == METHOD_MOTION:
        return motion_step(p, s, zc)
    if p[P_METHOD] == METHOD_ONE_EURO:
        return one_euro_step(p, s, zc)
    return filter_step(p, s, zc)


def _finite(v):
    return v - v == 0.0


def _healthy(p, s):
    """False if the filter state has left the finite numbers (an input so
    large that its square overflows, with the gate off)."""
    o_x = layout(int(p[P_ORDER]))[2]
    return (_finite(s[o_x]) and _finite(s[S_SVAR]) and _finite(s[S_R])
            and _finite(s[S_Q]) and _finite(s[S_RLS_ERR]) and _finite(s[S_S2]))


def step(p: Buf, s: MutBuf, z: float, is_restart: bool) -> float:
    """Process one raw sample ``z`` (deg/s); returns the output (deg/s).

    ``is_restart`` true re-initialises everything first (the gyro restarted and
    ``z`` is its first sample).

    Around the paper's filter (:func:`filter_step`) this keeps three
    guarantees, for every method and parameter set:

    * Centring: the RLS and the filter see z - z_ref, z_ref the first sample
      since the restart, so a large offset (1e7 deg/s) costs no precision in
      the regressors (Eq. 8) or the covariances. The model is the same (the
      constant c of Eq. 4 absorbs the offset; :func:`rls_c` reads it back in
      deg/s).
    * Finite: if the filter state stops being finite (a lone 1e155 sample with
      the gate off squares to inf), the filter restarts at that sample
      (counted in S_NHEAL) and passes the raw sample through while it warms up.
    * Envelope: the output never leaves [min, max] of the raw samples seen
      since the restart (counted in S_NCLAMP when the filter had to be held
      back: a denoiser does not invent motion).
    """
    code = 0
    if is_restart:
        restart(p, s)
    elif p[P_OUTLIER_SIGMA] > 0.0 and s[S_CONV] == 1.0 and p[P_METHOD] in AR_FILTER_IDS:
        code = gate(p, s, z - s[S_ZREF])
    if s[S_K] == 0.0:
        s[S_ZREF] = z
        s[S_LO] = z
        s[S_HI] = z
    if z < s[S_LO]:
        s[S_LO] = z
    if z > s[S_HI]:
        s[S_HI] = z
    zc = z - s[S_ZREF]
    if code == 1:
        xc = s[S_OUT]
    else:
        xc = _method_step(p, s, zc)
    if not (_healthy(p, s) and _finite(xc)):
        restart(p, s)
        s[S_NHEAL] += 1.0
        s[S_ZREF] = z
        s[S_LO] = z
        s[S_HI] = z
        zc = 0.0
        xc = _method_step(p, s, zc)
    # warm-up / identification only: raw (motion's warm-up output, where it moved the sample, is
    # its mean so far: :func:`warmup_output`)
    if (s[S_CONV] == 0.0 and not (p[P_METHOD] == METHOD_MOTION and xc != zc)) or p[P_METHOD] == METHOD_NONE:
        out = z
    else:
        out = xc + s[S_ZREF]
        if out < s[S_LO]:
            out = s[S_LO]
            s[S_NCLAMP] += 1.0
        elif out > s[S_HI]:
            out = s[S_HI]
            s[S_NCLAMP] += 1.0
    s[S_OUT] = out
    if p[P_BIAS] > 0.0 and p[P_METHOD] == METHOD_MOTION:   # bias tracking: the bias removed
        out -= bias_step(p, s, z)
    return out


GB_NAV_ARW_DEG_RTH = 0.05   # bias tracking: a record is navigation grade (the Earth-rate floor applies) below this ARW, deg/sqrt(h)
GB_LANE = 4   # bias tracking: the slowest lanes (0..4: tracking index <= 1e-6, an average over minutes) are "still"


def bias_params(sample_rate_hz: float, still_s: float, memory_s: float, floor_deg_h: float) -> list[float]:
    """p[P_BIAS_LANE ... P_BIAS_NAVR] (gdbias.c's gd_bias_params): the still lanes, the block
    (samples), the memory (blocks), the Earth-rate floor (deg/s), the white-noise variance below
    which a record is navigation grade ((deg/s)^2: ARW^2 = R / fs)."""
    need = max(1.0, float(round(still_s * sample_rate_hz)))
    a = GB_NAV_ARW_DEG_RTH / 60.0
    return [float(GB_LANE), need, max(1.0, float(round(memory_s * sample_rate_hz / need))), floor_deg_h / 3600.0,
            a * a * sample_rate_hz]


def bias_step(p: Buf, s: MutBuf, z: float) -> float:
    """Bias tracking, one raw sample ``z``: still where the bank has converged and its
    most likely filter is one of the slowest (at or below lane p[P_BIAS_LANE]); returns the
    bias removed (:func:`bias_update`)."""
    o = ext_offset(p) + M_BIAS
    calm = s[S_CONV] == 1.0 and s[o + M_BEST - M_BIAS] <= p[P_BIAS_LANE]
    return bias_update(p, s, o, z, calm, s[S_R])


def bias_update(p: Buf, s: MutBuf, o: int, z: float, calm: bool, r: float) -> float:
    """The bias estimator (gdbias.c), on its GB_N floats at ``s[o:]``; returns the bias removed.

    Blocks of p[P_BIAS_NEED] still samples: a block's mean is committed only when it is
    neither the first block of its still run (the bank calls the gyro still a little after
    the motion stopped) nor the last (it calls it moving a little after the motion
    started): a completed block waits as pending until the next one completes, and a
    sample that is not still drops the block being filled and the pending one. Then

        nb <- min(nb + 1, cap);  mean <- mean + (pend - mean) / nb             (B1)

    the mean of the committed blocks, then an exponential memory of ``cap`` blocks
    (bias_memory_s) that follows a slow drift. Before the first commit the estimate is
    the mean of the current run's completed blocks (B0: a start-up calibration from the
    first still block on), replaced at the first commit. What is removed,

        hat = mean - floor if mean > floor, mean + floor if mean < -floor, else 0   (B2)

    floor = earth_rate_floor_deg_h on a navigation-grade record (the bank's white-noise
    variance ``r`` below p[P_BIAS_NAVR], an angle random walk below :data:`GB_NAV_ARW_DEG_RTH`):
    never the first ``floor`` of its bias, where a still sensor's Earth rate (<= 15 deg/h on
    any axis) hides; 0 on a noisier (MEMS) record, whose whole estimate is removed, Earth's
    rate with it: attitude relative to the Earth (docs/method/bias.md).
    """
    if not calm or not _finite(z):      # moving (or a non-finite sample): the run ends
        s[o + GB_CUR_SUM] = 0.0
        s[o + GB_CUR_N] = 0.0
        s[o + GB_NBLK] = 0.0
        return s[o + GB_HAT]
    s[o + GB_CUR_SUM] += z
    s[o + GB_CUR_N] += 1.0
    if s[o + GB_CUR_N] < p[P_BIAS_NEED]:
        return s[o + GB_HAT]
    bm = s[o + GB_CUR_SUM] / s[o + GB_CUR_N]
    s[o + GB_NBLK] += 1.0
    if s[o + GB_NBLK] >= 3.0:           # the pending block: neither the run's first nor its last
        nb = s[o + GB_NB] + 1.0 if s[o + GB_NB] + 1.0 < p[P_BIAS_CAP] else p[P_BIAS_CAP]
        s[o + GB_NB] = nb
        s[o + GB_MEAN] = s[o + GB_MEAN] + (s[o + GB_PEND] - s[o + GB_MEAN]) / nb      # (B1)
    elif s[o + GB_NB] == 0.0:           # nothing committed yet: the run's blocks so far (B0)
        s[o + GB_MEAN] = s[o + GB_MEAN] + (bm - s[o + GB_MEAN]) / s[o + GB_NBLK]
    if s[o + GB_NBLK] >= 3.0 or s[o + GB_NB] == 0.0:
        mean = s[o + GB_MEAN]
        fl = p[P_BIAS_FLOOR] if r < p[P_BIAS_NAVR] else 0.0
        if mean > fl:                                                        # (B2)
            s[o + GB_HAT] = mean - fl
        elif mean < -fl:
            s[o + GB_HAT] = mean + fl
        else:
            s[o + GB_HAT] = 0.0
    s[o + GB_PEND] = bm
    s[o + GB_CUR_SUM] = 0.0
    s[o + GB_CUR_N] = 0.0
    return s[o + GB_HAT]


def bias_index(p: Buf) -> int:
    """Where in the state bias tracking keeps the bias it removes (``bias_hat``)."""
    return ext_offset(p) + M_BIAS + GB_HAT


def bias_hat(p: Buf, s: Buf) -> float:
    """The bias removed by bias tracking at the last sample, deg/s (0.0 when it is off)."""
    return float(s[bias_index(p)]) if p[P_BIAS] > 0.0 else 0.0


# ------------------------------------------------------------------ readouts
def phi(p: Buf, s: MutBuf) -> list[float]:
    """Current AR parameters [phi_1 ... phi_n] (list)."""
    n = int(p[P_ORDER])
    o = layout(n)[0]
    return [float(s[o + i]) for i in range(n)]


def c_deg_s(p: Buf, s: MutBuf) -> float:
    """Constant term c of the improved AR model, Eq. (4), deg/s, for the raw
    (uncentred) samples: the state holds c for z - z_ref (see :func:`step`),
    and z = sum phi_i z_{k-i} + c holds with c = c_ref + (1 - sum phi) z_ref.
    0.0 for the methods that identify no AR model (motion, lowpass, one_euro)."""
    if p[P_METHOD] not in AR_MODEL_IDS:
        return 0.0
    n = int(p[P_ORDER])
    o = layout(n)[0]
    one_minus = 1.0
    for i in range(n):
        one_minus -= s[o + i]
    return s[o + n] + one_minus * s[S_ZREF]


def rls_c(p: Buf, s: MutBuf) -> float:
    """Current constant term c of the improved AR model, Eq. (4), deg/s."""
    return float(c_deg_s(p, s))


def filter_state(p: Buf, s: MutBuf) -> list[float]:
    """Filter state estimate [z_k ... z_{k-n+1}, c] (list), deg/s."""
    n = int(p[P_ORDER])
    o = layout(n)[2]
    return ([float(s[o + i] + s[S_ZREF]) for i in range(n)]
            + [float(s[o + n] + (1.0 - sum(phi(p, s))) * s[S_ZREF])])


def filter_cov(p: Buf, s: MutBuf) -> list[list[float]]:
    """Filter covariance P as a list of rows."""
    n = int(p[P_ORDER])
    m = n + 1
    o = layout(n)[3]
    return [[float(s[o + i * m + j]) for j in range(m)] for i in range(m)]


def rls_cov(p: Buf, s: MutBuf) -> list[list[float]]:
    """RLS covariance as a list of rows."""
    n = int(p[P_ORDER])
    m = n + 1
    o = layout(n)[1]
    return [[float(s[o + i * m + j]) for j in range(m)] for i in range(m)]
