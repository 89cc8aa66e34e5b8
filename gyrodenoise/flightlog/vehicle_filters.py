"""The vehicle's own gyro filters, from its logged parameters: which stages run,
their discrete-time responses, their phase lag, and whether a logged gyro stream
was taken before or after them.

Built from the autopilots' sources (read, not copied; the formulas are written
here from their descriptions):

* ArduPilot ``libraries/Filter/LowPassFilter2p.cpp`` (``DigitalBiquadFilter::
  compute_params``): a second-order Butterworth low-pass by the bilinear
  transform with the cutoff prewarped, ``ohm = tan(pi fc / fs)``. The gyro
  low-pass is ``INS_GYRO_FILTER`` (0: off); APM 2.x logs, which have none, set the
  MPU6000's own low-pass with ``INS_MPU6K_FILTER`` (Hz, 0 the default: 20 Hz), a
  lowpass stage modelled the same way (an approximation of the chip's filter). PX4
  ``src/lib/mathlib/math/filter/LowPassFilter2p.hpp`` is the same filter
  (``IMU_GYRO_CUTOFF``; ``IMU_DGYRO_CUTOFF`` filters the angular acceleration of
  the D term, not the rate: kept as a stage on that path, left out of the rate
  response).
* ArduPilot ``libraries/Filter/NotchFilter.cpp``: ``calculate_A_and_Q`` turns
  attenuation and bandwidth into ``A = 10**(-att/40)`` and, from the bandwidth in
  octaves ``oct = 2 log2(fc / (fc - bw/2))``, ``Q = sqrt(2**oct) / (2**oct - 1)``;
  ``init_with_A_and_Q`` makes the biquad ``alpha = sin(w0) / 2Q``,
  ``b = (1 + alpha A^2, -2 cos w0, 1 - alpha A^2)``, ``a = (1 + alpha, -2 cos w0,
  1 - alpha)``: the depth at the centre is ``A^2`` = the attenuation in dB.
* ArduPilot ``libraries/Filter/HarmonicNotchFilter.cpp``: ``INS_HNTCH_*`` (and a
  second set ``INS_HNTC2_*``): one such notch per harmonic in the ``HMNCS`` bitmask
  at n x the centre, all with the A and Q computed once from ``FREQ``, ``BW`` /
  (composite notches) and ``ATT`` (so the bandwidth scales with the harmonic); the
  double notch (``OPTS`` bit 0) puts two notches at centre x (1 -+ spread) and the
  triple notch (bit 4) those two plus the centre, spread = ``BW / (32 FREQ)``;
  notches at or above 0.48 x the sample rate are not run; the centre is kept within
  [0.52 BW, 0.48 fs]. The centre by ``MODE``: 0 fixed at ``FREQ``; 1 throttle,
  ``FREQ x max(FM_RAT, sqrt(throttle / REF))`` (``AP_Vehicle::update_throttle_notch``;
  older firmware: ``max(1, ...)``, i.e. ``FM_RAT`` 1; with the motors shut
  down it marks the notch inactive, which is not modelled); 2/5 RPM sensor, 3 ESC
  telemetry, 4 in-flight FFT: the centre comes from a measurement, modelled here
  only when the caller gives it (e.g. from the log's ``FTN`` message), else left
  out of the response with a note.
* PX4 ``src/lib/mathlib/math/filter/NotchFilter.hpp``: ``alpha = tan(pi bw / fs)``,
  ``beta = -cos(2 pi f0 / fs)``, ``b = (1, 2 beta, 1) / (1 + alpha)``, ``a = (1,
  2 beta / (1 + alpha), (1 - alpha) / (1 + alpha))``: a full-depth notch whose
  -3 dB band is ``bw`` wide. Static notches ``IMU_GYRO_NF0_FRQ/BW``,
  ``IMU_GYRO_NF1_FRQ/BW`` (older ``IMU_GYRO_NF_FREQ/BW``; 0 Hz: off); the dynamic
  notches ``IMU_GYRO_DNF_EN`` (bit 0 ESC RPM, bit 1 FFT), ``IMU_GYRO_DNF_HMC``
  harmonics, ``IMU_GYRO_DNF_BW``, ``IMU_GYRO_DNF_MIN`` follow measured frequencies
  and are not modelled (``src/modules/sensors/vehicle_angular_velocity``).

The rate the filters run at: ArduPilot runs them at the gyro backend rate (the
``INS_HNTCH_FREQ`` description: "typically 1 kHz"; ``INS_GYRO_RATE`` n gives
1 kHz x 2**n where fast sampling is on), which is also the batch sampler's
``smp_rate`` when it samples pre-filter without sensor-rate logging. PX4 filters
at the raw sensor rate ("commonly 8 kHz", ``IMU_GYRO_RATEMAX``'s description),
not logged unless ``sensor_gyro_fifo`` is. The coefficients here are float64; the
firmware's float32 moves a response by far less than the figures' rounding.
"""

from __future__ import annotations

import math

import numpy as np


#: ArduPilot's gyro backend rate when nothing in the log says otherwise
AP_DEFAULT_FILTER_RATE_HZ = 1000.0
#: PX4 filters at the raw sensor rate; "commonly 8 kHz" (IMU_GYRO_RATEMAX's description)
PX4_DEFAULT_FILTER_RATE_HZ = 8000.0
#: ArduPilot's harmonic notch: notches at or above this share of the sample rate are not run
AP_NOTCH_NYQUIST_SHARE = 0.48
#: ArduPilot's harmonic notch defaults (HarmonicNotchFilter.cpp var_info), for parameters not logged
AP_HNTCH_DEFAULTS = {"FREQ": 80.0, "BW": 40.0, "ATT": 40.0, "HMNCS": 3, "REF": 0.0, "MODE": 1,
                     "OPTS": 0, "FM_RAT": 1.0}
#: APM 2.x INS_MPU6K_FILTER 0 ("Default"): 20 Hz per the parameter's description
AP_MPU6K_DEFAULT_HZ = 20.0
#: ArduPilot's static notch defaults (NotchFilter.cpp var_info)
AP_NOTCH_DEFAULTS = {"FREQ": 80.0, "BW": 20.0, "ATT": 15.0}
AP_TRACKING = {0: "fixed", 1: "throttle", 2: "rpm", 3: "esc", 4: "fft", 5: "rpm2"}
#: INS_LOG_BAT_OPT bits (AP_InertialSensor BatchSampler: BATCH_OPT_*)
BAT_OPT_SENSOR_RATE, BAT_OPT_POST_FILTER, BAT_OPT_PRE_POST_FILTER = 1, 2, 4

def _num(params, name, default=None):
    v = params.get(name, default)
    try:
        return None if v is None else float(v)
    except (TypeError, ValueError):
        return default


def filter_parameters(autopilot, params):
    """The filter-relevant entries of ``params`` ({NAME: value}, names sorted) of
    ``autopilot`` (a strategy of :mod:`gyrodenoise.flightlog.autopilots`: `named` gives it from a name)."""
    prefixes = autopilot.filter_param_prefixes
    return {k: _jsonable(params[k]) for k in sorted(params) if k.startswith(prefixes)}


def _jsonable(v):
    """A parameter value as a plain int or float (numpy scalars converted)."""
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    return v


def vehicle_filters(autopilot, params):
    """The vehicle's gyro filter chain from its parameters: ``{"autopilot",
    "parameters": {the filter-relevant NAME: value}, "stages": [...],
    "filter_rate_hz", "filter_rate_source"}``. Each stage is a dict with ``kind``
    (``lowpass``, ``notch``, ``harmonic_notch``, ``dynamic_notch``), ``path``
    (``rate``: on the gyro rate the controllers use; ``d_term``: PX4's
    angular-acceleration filter), the parameter names it comes from and its
    settings. An unknown autopilot gives no stages. ``autopilot``: a strategy of
    :mod:`gyrodenoise.flightlog.autopilots` (`named` gives it from a name)."""
    params = params or {}
    ap = autopilot
    stages, rate, source = ap.filter_chain(params)
    return {"autopilot": ap.name, "parameters": filter_parameters(ap, params), "stages": stages,
            "filter_rate_hz": rate, "filter_rate_source": source}


def ardupilot_chain(params):
    """(stages, filter rate Hz, its source) of ArduPilot's gyro filters."""
    rate = _num(params, "INS_GYRO_RATE")
    if rate is not None and _num(params, "INS_FAST_SAMPLE", 0.0):
        return (_ardupilot_stages(params), 1000.0 * 2 ** int(rate),
                f"INS_GYRO_RATE {int(rate)} with fast sampling: 1 kHz x 2**{int(rate)}")
    return (_ardupilot_stages(params), AP_DEFAULT_FILTER_RATE_HZ,
            "assumed: ArduPilot's typical gyro backend rate (1 kHz)")


def px4_chain(params):
    """(stages, filter rate Hz, its source) of PX4's gyro filters."""
    return (_px4_stages(params), PX4_DEFAULT_FILTER_RATE_HZ,
            "assumed: PX4 filters at the raw sensor rate, commonly 8 kHz (not in the log unless "
            "sensor_gyro_fifo is)")


def _ardupilot_stages(p):
    stages = []
    for prefix in ("INS_HNTCH_", "INS_HNTC2_"):
        if _num(p, prefix + "ENABLE", 0.0):
            stages.append(_ap_harmonic_notch(p, prefix))
    if _num(p, "INS_NOTCH_ENABLE", 0.0):
        g = {k: _num(p, "INS_NOTCH_" + k, d) for k, d in AP_NOTCH_DEFAULTS.items()}
        stages.append({"kind": "notch", "path": "rate", "form": "ardupilot", "params": "INS_NOTCH_*",
                       "centre_hz": g["FREQ"], "bandwidth_hz": g["BW"], "attenuation_db": g["ATT"]})
    fc = _num(p, "INS_GYRO_FILTER")
    if fc is not None and fc > 0:
        stages.append({"kind": "lowpass", "path": "rate", "params": "INS_GYRO_FILTER", "cutoff_hz": fc,
                       "order": 2, "design": "Butterworth, bilinear with prewarping (LowPassFilter2p)"})
    mpu = _num(p, "INS_MPU6K_FILTER")
    if fc is None and mpu is not None:
        stages.append(_mpu6k_stage(mpu))
    return stages


def _mpu6k_stage(value_hz):
    """The low-pass stage of APM 2.x's ``INS_MPU6K_FILTER`` (AP_InertialSensor: "Filter
    frequency to ask the MPU6000 to apply to samples"; values 0 default, 5, 10, 20, 42,
    98 Hz): the MPU6000's own digital low-pass (its DLPF_CFG setting), before the
    samples reach the autopilot -- not a software biquad; modelled as a 2nd-order
    Butterworth at that cutoff, an approximation. 0 is the firmware's default: 20 Hz
    in the parameter's description for ArduPlane, APMrover2 and ArduCopter (some
    ArduCopter releases of the time say 42 Hz)."""
    default = value_hz <= 0
    return {"kind": "lowpass", "path": "rate", "params": "INS_MPU6K_FILTER",
            "cutoff_hz": AP_MPU6K_DEFAULT_HZ if default else float(value_hz), "order": 2,
            "design": "MPU6000 on-chip digital low-pass (DLPF_CFG), modelled as a 2nd-order Butterworth",
            **({"note": f"INS_MPU6K_FILTER 0: the firmware default, {AP_MPU6K_DEFAULT_HZ:g} Hz per the parameter's "
                        "description (42 Hz on some ArduCopter releases)"} if default else {})}


def _ap_harmonic_notch(p, prefix):
    g = {k: _num(p, prefix + k, d) for k, d in AP_HNTCH_DEFAULTS.items()}
    hm = int(g["HMNCS"])
    opts = int(g["OPTS"])
    mode = int(g["MODE"])
    composite = 2 if opts & 1 else 3 if opts & 16 else 1
    tracking = AP_TRACKING.get(mode, f"mode {mode}")
    if g["REF"] == 0 and mode != 0:
        tracking_note = "REF 0: dynamic updates off, the notch stays at FREQ"
        tracking = "fixed"
    elif tracking in ("fixed", "throttle"):
        tracking_note = ("centre FREQ" if tracking == "fixed" else
                         "centre FREQ x max(FM_RAT, sqrt(throttle / REF)) (AP_Vehicle::update_throttle_notch)")
    else:
        tracking_note = (f"centre from a measurement ({tracking}): modelled only where the log gives it "
                         f"(FTN), else at FREQ, the lowest it goes")
    return {"kind": "harmonic_notch", "path": "rate", "params": prefix + "*", "centre_hz": g["FREQ"],
            "bandwidth_hz": g["BW"], "attenuation_db": g["ATT"],
            "harmonics": [i + 1 for i in range(16) if hm >> i & 1], "tracking": tracking, "mode": mode,
            "reference": g["REF"], "min_ratio": g["FM_RAT"], "composite": composite,
            "multi_source": bool(opts & 2), "options": opts, "tracking_note": tracking_note}


def _px4_stages(p):
    stages = []
    nf = [("IMU_GYRO_NF0_FRQ", "IMU_GYRO_NF0_BW"), ("IMU_GYRO_NF1_FRQ", "IMU_GYRO_NF1_BW"),
          ("IMU_GYRO_NF_FREQ", "IMU_GYRO_NF_BW")]
    for f_name, bw_name in nf:
        f0, bw = _num(p, f_name, 0.0), _num(p, bw_name, 20.0)
        if f0 and f0 > 0 and bw and bw > 0:
            stages.append({"kind": "notch", "path": "rate", "form": "px4", "params": f"{f_name}, {bw_name}",
                           "centre_hz": f0, "bandwidth_hz": bw, "attenuation_db": None})
    dnf = int(_num(p, "IMU_GYRO_DNF_EN", 0.0) or 0)
    if dnf:
        stages.append({"kind": "dynamic_notch", "path": "rate", "params": "IMU_GYRO_DNF_*",
                       "sources": [s for b, s in ((1, "esc_rpm"), (2, "fft")) if dnf & b],
                       "harmonics": int(_num(p, "IMU_GYRO_DNF_HMC", 3.0)),
                       "bandwidth_hz": _num(p, "IMU_GYRO_DNF_BW", 15.0),
                       "min_hz": _num(p, "IMU_GYRO_DNF_MIN", 25.0),
                       "tracking_note": "follows measured frequencies (ESC RPM / onboard FFT): not modelled"})
    fc = _num(p, "IMU_GYRO_CUTOFF")
    if fc is not None and fc > 0:
        stages.append({"kind": "lowpass", "path": "rate", "params": "IMU_GYRO_CUTOFF", "cutoff_hz": fc,
                       "order": 2, "design": "Butterworth, bilinear with prewarping (LowPassFilter2p)"})
    fd = _num(p, "IMU_DGYRO_CUTOFF")
    if fd is not None and fd > 0:
        stages.append({"kind": "lowpass", "path": "d_term", "params": "IMU_DGYRO_CUTOFF", "cutoff_hz": fd,
                       "order": 2, "design": "Butterworth on the angular acceleration (D term)"})
    return stages


# --------------------------------------------------------------------------- biquads

def lowpass2p_sos(cutoff_hz, sample_rate_hz):
    """(b0, b1, b2, a1, a2) of the 2nd-order Butterworth low-pass of LowPassFilter2p
    (a0 = 1), or None when the cutoff is not within (0, fs/2)."""
    if not 0 < cutoff_hz < 0.5 * sample_rate_hz:
        return None
    ohm = math.tan(math.pi * cutoff_hz / sample_rate_hz)
    c = 1.0 + 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm
    b0 = ohm * ohm / c
    return (b0, 2.0 * b0, b0, 2.0 * (ohm * ohm - 1.0) / c, (1.0 - 2.0 * math.cos(math.pi / 4.0) * ohm + ohm * ohm) / c)


def ardupilot_notch_a_q(centre_hz, bandwidth_hz, attenuation_db):
    """(A, Q) of ArduPilot's NotchFilter::calculate_A_and_Q; Q is 0 (no notch) when
    the centre is not above half the bandwidth."""
    a = 10.0 ** (-attenuation_db / 40.0)
    if centre_hz <= 0.5 * bandwidth_hz:
        return a, 0.0
    octaves = 2.0 * math.log2(centre_hz / (centre_hz - bandwidth_hz / 2.0))
    return a, math.sqrt(2.0 ** octaves) / (2.0 ** octaves - 1.0)


def ardupilot_notch_sos(centre_hz, a, q, sample_rate_hz):
    """(b0, b1, b2, a1, a2) of ArduPilot's NotchFilter::init_with_A_and_Q (normalised
    by a0), or None when it would not be initialised (centre outside (0, fs/2), Q <= 0)."""
    if not (0 < centre_hz < 0.5 * sample_rate_hz and q > 0):
        return None
    w0 = 2.0 * math.pi * centre_hz / sample_rate_hz
    alpha = math.sin(w0) / (2.0 * q)
    a0 = 1.0 + alpha
    return ((1.0 + alpha * a * a) / a0, -2.0 * math.cos(w0) / a0, (1.0 - alpha * a * a) / a0,
            -2.0 * math.cos(w0) / a0, (1.0 - alpha) / a0)


def px4_notch_sos(centre_hz, bandwidth_hz, sample_rate_hz):
    """(b0, b1, b2, a1, a2) of PX4's NotchFilter::setParameters, or None when PX4
    disables it (centre or bandwidth not positive, centre at or above fs/2)."""
    if centre_hz <= 0 or bandwidth_hz <= 0 or centre_hz >= 0.5 * sample_rate_hz:
        return None
    alpha = math.tan(math.pi * bandwidth_hz / sample_rate_hz)
    beta = -math.cos(2.0 * math.pi * centre_hz / sample_rate_hz)
    a0_inv = 1.0 / (1.0 + alpha)
    return (a0_inv, 2.0 * beta * a0_inv, a0_inv, 2.0 * beta * a0_inv, (1.0 - alpha) * a0_inv)


def throttle_notch_centre_hz(stage, throttle):
    """The centre of a throttle-tracking harmonic notch at ``throttle`` (0..1, the
    motors' throttle out): ``FREQ x max(FM_RAT, sqrt(throttle / REF))``; FREQ when
    REF is 0."""
    ref = stage.get("reference") or 0.0
    if ref <= 0:
        return float(stage["centre_hz"])
    return float(stage["centre_hz"]) * max(float(stage.get("min_ratio", 1.0)), math.sqrt(max(0.0, throttle) / ref))


def harmonic_notch_sos(stage, sample_rate_hz, centre_hz=None):
    """The biquads of an ArduPilot harmonic notch stage with its fundamental at
    ``centre_hz`` (default: the stage's ``centre_hz``): a list of (b0, b1, b2, a1, a2)."""
    fs = float(sample_rate_hz)
    base = float(stage["centre_hz"])
    bw = float(stage["bandwidth_hz"])
    composite = int(stage.get("composite", 1))
    nyq = AP_NOTCH_NYQUIST_SHARE * fs
    base_c = min(max(base, 0.52 * bw), nyq)
    spread = bw / (32.0 * base_c)
    a, q = ardupilot_notch_a_q(base_c, bw / composite, float(stage["attenuation_db"]))
    fc = base_c if centre_hz is None else min(max(float(centre_hz), 0.0), nyq)
    out = []
    for n in stage.get("harmonics", [1]):
        c = fc * n
        centres = []
        if composite != 2:
            centres.append(c)
        if composite > 1:
            centres += [c * (1.0 - spread), c * (1.0 + spread)]
        for cc in centres:
            if cc < nyq:
                s = ardupilot_notch_sos(cc, a, q, fs)
                if s is not None:
                    out.append(s)
    return out


def chain_sections(stages, sample_rate_hz, notch_centre_hz=None):
    """(biquads [(b0, b1, b2, a1, a2)], notes) of the stages on the gyro rate path at
    ``sample_rate_hz``. ``notch_centre_hz``: the harmonic notches' fundamental, one
    number for all or {params prefix, e.g. "INS_HNTCH_*": Hz}; without it a fixed
    or throttle notch sits at its FREQ (throttle: the centre at the reference
    throttle, the hover), and a notch that follows a measurement (RPM, ESC, FFT) or
    PX4's dynamic notches are left out, with a note."""
    fs = float(sample_rate_hz)
    sos, notes = [], []
    for st in stages:
        if st.get("path", "rate") != "rate":
            continue
        kind = st["kind"]
        if "sections" in st:                # the autopilot's own biquads (Betaflight), designed at rate_hz
            if not math.isclose(float(st["rate_hz"]), fs):
                notes.append(f"{st['params']}: designed for {st['rate_hz']:g} Hz, not run at fs {fs:g} Hz")
            else:
                sos += [tuple(x) for x in st["sections"]]
        elif kind == "lowpass":
            s = lowpass2p_sos(float(st["cutoff_hz"]), fs)
            if s is None:
                notes.append(f"{st['params']}: cutoff {st['cutoff_hz']} Hz not below fs/2 = {fs / 2:g} Hz: not applied")
            else:
                sos.append(s)
        elif kind == "notch":
            s = NOTCH_FORMS[st.get("form", "ardupilot")](st, fs)
            if s is None:
                notes.append(f"{st['params']}: notch at {st['centre_hz']} Hz not run at fs {fs:g} Hz")
            else:
                sos.append(s)
        elif kind == "harmonic_notch":
            centre = notch_centre_hz.get(st["params"]) if isinstance(notch_centre_hz, dict) else notch_centre_hz
            if centre is None and st.get("tracking") not in ("fixed", "throttle"):
                notes.append(f"{st['params']}: tracks {st['tracking']}, no centre given: not modelled")
                continue
            sos += harmonic_notch_sos(st, fs, centre)
        elif kind == "dynamic_notch":
            notes.append(f"{st['params']}: dynamic notch ({', '.join(st.get('sources', []))}): not modelled")
    return sos, notes


def _ardupilot_notch(st, fs):
    a, q = ardupilot_notch_a_q(float(st["centre_hz"]), float(st["bandwidth_hz"]), float(st["attenuation_db"]))
    return ardupilot_notch_sos(float(st["centre_hz"]), a, q, fs)


def _px4_notch(st, fs):
    return px4_notch_sos(float(st["centre_hz"]), float(st["bandwidth_hz"]), fs)


#: a notch stage's ``form`` (whose biquad design it runs) -> its biquad at fs
NOTCH_FORMS = {"ardupilot": _ardupilot_notch, "px4": _px4_notch}


def sos_response(sos, freq_hz, sample_rate_hz):
    """Complex response of biquads [(b0, b1, b2, a1, a2)] at ``freq_hz`` run at
    ``sample_rate_hz`` (1 for an empty list)."""
    z1 = np.exp(-2j * np.pi * np.asarray(freq_hz, dtype=np.float64) / float(sample_rate_hz))
    h = np.ones_like(z1)
    for b0, b1, b2, a1, a2 in sos:
        h = h * (b0 + b1 * z1 + b2 * z1 * z1) / (1.0 + a1 * z1 + a2 * z1 * z1)
    return h


def chain_response(stages, freq_hz, sample_rate_hz, notch_centre_hz=None):
    """Complex frequency response (array like ``freq_hz``) of the vehicle's gyro
    filter stages on the rate path, as the discrete-time biquads run at
    ``sample_rate_hz`` (see :func:`chain_sections` for ``notch_centre_hz`` and what is
    left out)."""
    sos, _ = chain_sections(stages, sample_rate_hz, notch_centre_hz)
    return sos_response(sos, freq_hz, sample_rate_hz)


def phase_lag_ms(stages, freq_hz, sample_rate_hz, notch_centre_hz=None):
    """Phase lag in ms of the filter chain at each of ``freq_hz``: -unwrapped
    phase / (2 pi f), the phase unwrapped along a fine grid from 0 Hz (so a lag of
    more than half a cycle is right). A list of floats (NaN at 0 Hz)."""
    sos, _ = chain_sections(stages, sample_rate_hz, notch_centre_hz)
    out = []
    for f in np.atleast_1d(np.asarray(freq_hz, dtype=np.float64)):
        if f <= 0:
            out.append(float("nan"))
            continue
        grid = np.linspace(0.0, f, max(64, int(math.ceil(f / 0.25)) + 1))
        ph = np.unwrap(np.angle(sos_response(sos, grid, sample_rate_hz)))
        out.append(float(-ph[-1] / (2.0 * math.pi * f) * 1000.0))
    return out


# --------------------------------------------------------------------------- streams

def _gyro_count(params):
    ids = [_num(params, n) for n in ("INS_GYR_ID", "INS_GYR2_ID", "INS_GYR3_ID")]
    known = [i for i in ids if i is not None]
    return sum(1 for i in known if i != 0) if known else None


def batch_stage(params, instance):
    """("pre-filter" | "post-filter" | "unknown", the IMU it samples or None, why) of
    ArduPilot batch-sampler instance ``instance`` (ISBH ``instance``), from
    ``INS_LOG_BAT_OPT``: bit 0 sensor-rate logging, bit 1 post-filter, bit 2 pre- and
    post-filter. With bit 2, or bits 0 and 1 together, the post-filter batches are
    written as instance + the number of gyros (``Write_ISBH`` in
    AP_InertialSensor_Logging.cpp; the WebTools FilterReview reads them the same
    way); otherwise all batches are post-filter when bit 1 is set, pre-filter when
    not. The number of gyros is counted from ``INS_GYRn_ID`` != 0."""
    opt = _num(params, "INS_LOG_BAT_OPT")
    if opt is None:
        return "unknown", None, "INS_LOG_BAT_OPT not logged"
    opt = int(opt)
    sensor_rate, post, prepost = bool(opt & 1), bool(opt & 2), bool(opt & 4)
    if prepost or (post and sensor_rate):
        n = _gyro_count(params)
        if n is None or n == 0:
            return "unknown", None, (f"INS_LOG_BAT_OPT {opt}: post-filter batches are instance + the gyro "
                                     f"count, and INS_GYRn_ID are not logged")
        if instance >= n:
            return "post-filter", instance - n, f"INS_LOG_BAT_OPT {opt}: instance {instance} >= {n} gyros"
        return "pre-filter", instance, f"INS_LOG_BAT_OPT {opt}: instance {instance} < {n} gyros"
    if post:
        return "post-filter", instance, f"INS_LOG_BAT_OPT {opt}: bit 1 (post-filter)"
    return "pre-filter", instance, f"INS_LOG_BAT_OPT {opt}: bit 1 and 2 clear (pre-filter)"


def stream_stage(autopilot, params, stream):
    """"pre-filter", "post-filter" or "unknown": whether a gyro stream was logged
    before or after the vehicle's own gyro filters.

    The rule and its sources:

    * ArduPilot DataFlash ``IMU``/``IMU2``/``IMU3`` GyrX..: post-filter (the logged
      gyro is ``AP_InertialSensor::get_gyro``, the filtered value).
    * ArduPilot batch sampler ``ISBD`` (stream ``ISB.gyro[i]``): by
      ``INS_LOG_BAT_OPT`` (:func:`batch_stage`); unknown when it is not logged.
    * ArduPilot telemetry ``RAW_IMU``/``SCALED_IMU2``/``SCALED_IMU3``: post-filter
      (``GCS_MAVLINK::send_raw_imu`` sends ``ins.get_gyro(0)``, the filtered gyro, in
      mrad/s; ``send_scaled_imu`` likewise for the others).
    * PX4 ``vehicle_angular_velocity``: post-filter (VehicleAngularVelocity
      publishes the notched and low-passed rate). ``sensor_gyro_fifo``: pre-filter
      (the driver's raw FIFO samples).
    * PX4 ``sensor_gyro`` and ``sensor_combined``: before the ``IMU_GYRO_*`` filters
      since PX4 1.11, where those filters moved into vehicle_angular_velocity and
      sensor_combined became the estimator's integrated IMU (``vehicle_imu``
      delta angle / dt: averaged over the integration interval, which the filters
      never touch: "This only affects the angular velocity sent to the
      controllers, not the estimators"). Those versions log ``IMU_INTEG_RATE``;
      without it (older PX4, whose drivers low-passed sensor_gyro) unknown.
    * anything else, or an unknown autopilot: unknown.

    ``autopilot``: a strategy of :mod:`gyrodenoise.flightlog.autopilots` (`named` gives it from a name).
    """
    return autopilot.stream_stage(params or {}, stream)


def ardupilot_stream_stage(params, stream):
    """:func:`stream_stage` of an ArduPilot log."""
    msg = getattr(stream, "message", "") or ""
    name = getattr(stream, "name", "") or ""
    if msg == "ISBD" or name.startswith("ISB."):
        inst = _instance(name)
        return batch_stage(params, inst if inst is not None else 0)[0]
    if msg in ("IMU", "IMU2", "IMU3", "RAW_IMU", "SCALED_IMU", "SCALED_IMU2", "SCALED_IMU3"):
        return "post-filter"
    return "unknown"


def px4_stream_stage(params, stream):
    """:func:`stream_stage` of a PX4 log."""
    msg = getattr(stream, "message", "") or ""
    if msg == "vehicle_angular_velocity":
        return "post-filter"
    if msg == "sensor_gyro_fifo":
        return "pre-filter"
    if msg in ("sensor_gyro", "sensor_combined"):
        return "pre-filter" if "IMU_INTEG_RATE" in params else "unknown"
    return "unknown"


def _instance(name):
    if "[" in name and name.endswith("]"):
        try:
            return int(name[name.rindex("[") + 1:-1])
        except ValueError:
            return None
    return None


# --------------------------------------------------------------------------- replay along the flight

#: ArduPilot's NotchFilter slew limit per centre update (NOTCH_MAX_SLEW)
AP_NOTCH_MAX_SLEW = 0.05


def constant_sections(sos, n):
    """(n, k, 5) of fixed biquads ``sos`` [(b0, b1, b2, a1, a2)]."""
    if not sos:
        return np.zeros((n, 0, 5))
    return np.broadcast_to(np.asarray(sos, dtype=np.float64)[None, :, :], (n, len(sos), 5))


def slewed_centres(desired_hz, update_every, max_slew=AP_NOTCH_MAX_SLEW):
    """ArduPilot's notch centre per sample: the ``desired_hz`` (n,) or (n, k) taken once
    every ``update_every`` samples, each update kept within [previous x (1 - slew),
    previous / (1 - slew)] (NotchFilter::init_with_A_and_Q), held in between."""
    d = np.asarray(desired_hz, dtype=np.float64)
    out = np.empty_like(d)
    lo, hi = 1.0 - max_slew, 1.0 / (1.0 - max_slew)
    prev = d[0].copy() if d.ndim > 1 else float(d[0])
    step = max(1, int(update_every))
    for a in range(0, len(d), step):
        want = d[a]
        prev = np.clip(want, prev * lo, prev * hi) if np.all(np.isfinite(prev)) and np.all(prev > 0) else want
        out[a:a + step] = prev
    return out


def ardupilot_notch_sections(centre_hz, a, q, sample_rate_hz):
    """:func:`ardupilot_notch_sos` at each of ``centre_hz`` (n,): (n, 5), a pass-through
    (1, 0, 0, 0, 0) where the notch would not run (centre outside (0, 0.48 fs) or Q <= 0)."""
    c = np.asarray(centre_hz, dtype=np.float64)
    fs = float(sample_rate_hz)
    ok = np.isfinite(c) & (c > 0) & (c < AP_NOTCH_NYQUIST_SHARE * fs) & (q > 0)
    w0 = 2.0 * np.pi * np.where(ok, c, 1.0) / fs
    alpha = np.sin(w0) / (2.0 * q) if q > 0 else np.zeros_like(w0)
    a0 = 1.0 + alpha
    out = np.stack([(1.0 + alpha * a * a) / a0, -2.0 * np.cos(w0) / a0, (1.0 - alpha * a * a) / a0,
                    -2.0 * np.cos(w0) / a0, (1.0 - alpha) / a0], axis=-1)
    out[~ok] = (1.0, 0.0, 0.0, 0.0, 0.0)
    return out


def px4_notch_sections(centre_hz, bandwidth_hz, sample_rate_hz, min_hz=0.0):
    """:func:`px4_notch_sos` at each of ``centre_hz`` (n,): (n, 5), a pass-through where PX4
    runs none (centre not above ``min_hz``, at or above fs/2)."""
    c = np.asarray(centre_hz, dtype=np.float64)
    fs = float(sample_rate_hz)
    ok = np.isfinite(c) & (c > max(min_hz, 0.0)) & (c < 0.5 * fs) & (bandwidth_hz > 0)
    alpha = math.tan(math.pi * bandwidth_hz / fs)
    beta = -np.cos(2.0 * np.pi * np.where(ok, c, 1.0) / fs)
    inv = 1.0 / (1.0 + alpha)
    ones = np.full_like(beta, inv)
    out = np.stack([ones, 2.0 * beta * inv, ones, 2.0 * beta * inv, np.full_like(beta, (1.0 - alpha) * inv)], -1)
    out[~ok] = (1.0, 0.0, 0.0, 0.0, 0.0)
    return out


def harmonic_notch_centre(stage, value):
    """The fundamental (Hz) an ArduPilot harmonic notch ``stage`` wants for driving
    ``value`` (an array): by its tracking, throttle ``FREQ x max(FM_RAT, sqrt(value /
    REF))`` (AP_Vehicle::update_throttle_notch); ESC / RPM (``value`` rev/min)
    ``max(FREQ x FM_RAT, REF x value / 60)``; FFT (``value`` Hz) ``max(FREQ x FM_RAT,
    value)``; fixed: FREQ."""
    freq = float(stage["centre_hz"])
    ref = float(stage.get("reference") or 0.0)
    lo = freq * float(stage.get("min_ratio", 1.0))
    v = np.asarray(value, dtype=np.float64)
    tracking = stage.get("tracking")
    if tracking == "throttle" and ref > 0:
        return freq * np.maximum(float(stage.get("min_ratio", 1.0)), np.sqrt(np.maximum(v, 0.0) / ref))
    if tracking in ("esc", "rpm", "rpm2"):
        return np.maximum(lo, (ref if ref > 0 else 1.0) * v / 60.0)
    if tracking == "fft":
        return np.maximum(lo, v)
    return np.full(v.shape, freq)


def replay_sections(stages, tracks, time_s, sample_rate_hz, loop_rate_hz, slew=True):
    """((n, k, 5) biquads per sample, notes) of ArduPilot's or PX4's gyro chain
    ``stages`` along the flight at ``time_s``, designed at ``sample_rate_hz``.

    ``tracks``: {stage ``params``: :class:`~gyrodenoise.flightlog.notch_replay.Track`} of
    what moves each tracking stage (throttle 0..1, motor rev/min as (m, motors), FFT
    Hz). ArduPilot's harmonic notch takes its centre from :func:`harmonic_notch_centre`,
    updated once per ``loop_rate_hz`` and slewed by at most 5 % an update (``slew``);
    its A and Q are those of FREQ and BW (computed once, so the bandwidth scales with
    the centre); with ``multi_source`` and several motors, a notch set per motor, else
    one at the motors' mean. PX4's dynamic notch: one notch per ESC and harmonic at
    ``h x rpm / 60``, none below ``min_hz``. A tracking stage without its track stays
    at FREQ (fixed and throttle) or is left out, with a note."""
    t = np.asarray(time_s, dtype=np.float64)
    n, fs = len(t), float(sample_rate_hz)
    parts, notes = [], []
    every = max(1, int(round(fs / float(loop_rate_hz)))) if loop_rate_hz else 1
    for st in stages:
        if st.get("path", "rate") != "rate":
            continue
        tr = tracks.get(st["params"])
        if st["kind"] == "harmonic_notch" and (tr is not None or st.get("tracking") in ("fixed", "throttle")):
            if tr is None:
                notes.append(f"{st['params']}: tracks {st['tracking']}, no track in the log: held at FREQ "
                             f"{st['centre_hz']:g} Hz")
                want = np.full((n, 1), float(st["centre_hz"]))
            else:
                v = tr.at(t)
                v = v if v.ndim == 2 else v[:, None]
                if not st.get("multi_source") and v.shape[1] > 1:
                    v = np.nanmean(v, axis=1, keepdims=True)
                want = harmonic_notch_centre(st, v)
            bw = float(st["bandwidth_hz"])
            want = np.clip(want, 0.52 * bw, AP_NOTCH_NYQUIST_SHARE * fs)
            centre = slewed_centres(want, every) if slew else want
            composite = int(st.get("composite", 1))
            base_c = min(max(float(st["centre_hz"]), 0.52 * bw), AP_NOTCH_NYQUIST_SHARE * fs)
            spread = bw / (32.0 * base_c)
            a, q = ardupilot_notch_a_q(base_c, bw / composite, float(st["attenuation_db"]))
            mults = ([1.0] if composite != 2 else []) + ([1.0 - spread, 1.0 + spread] if composite > 1 else [])
            for h in st.get("harmonics", [1]):
                for m in mults:
                    for j in range(centre.shape[1]):
                        parts.append(ardupilot_notch_sections(centre[:, j] * h * m, a, q, fs)[:, None, :])
        elif st["kind"] == "dynamic_notch" and tr is not None and "esc_rpm" in st.get("sources", []):
            v = tr.at(t)
            v = v if v.ndim == 2 else v[:, None]
            for h in range(1, int(st.get("harmonics", 1)) + 1):
                for j in range(v.shape[1]):
                    parts.append(px4_notch_sections(h * v[:, j] / 60.0, float(st["bandwidth_hz"]), fs,
                                                    float(st.get("min_hz") or 0.0))[:, None, :])
            if "fft" in st.get("sources", []):
                notes.append(f"{st['params']}: the FFT-driven notches (per axis, their peaks not logged) are left out")
        else:
            sos, why = chain_sections([st], fs)
            notes += why
            if sos:
                parts.append(np.array(constant_sections(sos, n)))
    if not parts:
        return np.zeros((n, 0, 5)), notes
    return np.concatenate(parts, axis=1), notes
