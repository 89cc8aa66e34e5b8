"""One strategy per autopilot: what the flight review does differently for ArduPilot,
PX4 and Betaflight (and for a log whose autopilot is not known).

A strategy (:class:`Autopilot`) holds, for its autopilot:

* how it is recognised: ``name`` (the report's ``autopilot``), ``mav_autopilot`` (the
  ``HEARTBEAT.autopilot`` id), ``param_prefixes`` (names that only it uses), and
  ``int_params_bytewise`` (PX4 sends integer parameters as the int32's bits);
* its gyro filter chain (:meth:`filter_chain`: stages and the rate they run at, built by
  :mod:`gyrodenoise.flightlog.vehicle_filters`), the parameters that set it
  (``filter_param_prefixes``) and at which stage each gyro stream is logged
  (:meth:`stream_stage`);
* its flight rules (:meth:`air_from_system_status`: whether a telemetry log's
  ``system_status`` tells being in the air);
* the filter review's rules (:mod:`gyrodenoise.flightlog.filter_review`): what it reads
  from the log (:meth:`review_context`), the rate its filters run at
  (:meth:`review_filter_rate`), why no pre-filter stream (:meth:`no_stream_reason`),
  the notch it recommends (:meth:`recommend_notch`), its low-pass parameter
  (:meth:`lowpass_param`) and its parameter lines (:meth:`param_lines`: ArduPilot
  ``NAME,VALUE``, PX4 ``param set NAME VALUE``, Betaflight ``set name = value``).

:data:`AUTOPILOTS` is the registry; :func:`named` gives the strategy of a name
(``None``: :data:`UNKNOWN`). A new autopilot is one class here and one line in
:data:`AUTOPILOTS`.
"""

from __future__ import annotations

from gyrodenoise.flightlog.model import fmt_value

COPTER_TYPES = {2, 3, 4, 13, 14, 15, 29}     # MAV_TYPE quad, coaxial, heli, hexa, octo, tri, dodeca


class Autopilot:
    """A log whose autopilot is not known: no filter chain, no stage, no parameter lines."""
    name: str | None = None
    mav_autopilot: int | None = None
    param_prefixes: tuple = ()
    filter_param_prefixes: tuple = ()
    int_params_bytewise = False

    def __repr__(self):
        return f"<autopilot {self.name}>"

    def filter_chain(self, params):
        """(stages, filter rate Hz or None, where the rate comes from)."""
        return [], None, "unknown autopilot"

    def stream_stage(self, params, stream):
        return "unknown"

    def air_from_system_status(self, vehicle_type):
        return False

    def review_context(self, log, params, filters, flying_mask_fn, ctx):
        return ctx

    def review_filter_rate(self, stream, rate, params, ctx):
        """(rate Hz, source) the review's filters run at where the log tells better than
        :meth:`filter_chain` (None: it does not)."""
        return None

    def no_stream_reason(self, params, streams):
        return "; the autopilot is unknown, so no stream's stage can be told"

    def recommend_notch(self, params, fund, ctx, centre, bw):
        return {}, None, ["unknown autopilot: no notch parameters to recommend"]

    def recommend_without_notch(self, params, ctx):
        """({NAME: value}, reasons) recommended beside a review that sets no notch."""
        return {}, []

    def lowpass_param(self, params):
        return None

    def param_lines(self, changes):
        return [f"{k},{fmt_value(v)}" for k, v in changes.items()]

    def vibration_levels(self, levels):
        """The vibration levels of a log (:mod:`gyrodenoise.flightlog.vibration`) as this
        autopilot fills them: named and judged as what they are."""
        return levels


class ArduPilot(Autopilot):
    name = "ardupilot"
    mav_autopilot = 3
    param_prefixes = ("INS_", "ATC_", "SCHED_")
    filter_param_prefixes = ("INS_GYRO_FILTER", "INS_MPU6K_FILTER", "INS_HNTCH_", "INS_HNTC2_", "INS_NOTCH_",
                             "INS_GYRO_RATE", "INS_FAST_SAMPLE", "INS_LOG_BAT_", "INS_GYR_ID", "INS_GYR2_ID",
                             "INS_GYR3_ID", "SCHED_LOOP_RATE")

    def filter_chain(self, params):
        from gyrodenoise.flightlog import vehicle_filters as vf
        return vf.ardupilot_chain(params)

    def stream_stage(self, params, stream):
        from gyrodenoise.flightlog import vehicle_filters as vf
        return vf.ardupilot_stream_stage(params, stream)

    def air_from_system_status(self, vehicle_type):
        return vehicle_type in COPTER_TYPES      # ArduCopter reports ACTIVE only while not landed

    def review_context(self, log, params, filters, flying_mask_fn, ctx):
        from gyrodenoise.flightlog import filter_review as fr
        return fr.ardupilot_context(log, params, filters, flying_mask_fn, ctx)

    def review_filter_rate(self, stream, rate, params, ctx):
        if stream.message == "ISBD" and not int(params.get("INS_LOG_BAT_OPT", 0)) & 1:
            return rate, "the batch sampler's rate (it samples at the rate the filters run at)"
        return None

    def no_stream_reason(self, params, streams):
        mask = params.get("INS_LOG_BAT_MASK")
        if mask is None:
            return ", and the batch sampler's INS_LOG_BAT_MASK is not logged"
        if not mask:
            return ", and the batch sampler is off (INS_LOG_BAT_MASK 0)"
        if not any(s.message == "ISBD" for s in streams):
            return f", and the log holds no batch-sampler data (INS_LOG_BAT_MASK {fmt_value(mask)})"
        return ""

    def recommend_notch(self, params, fund, ctx, centre, bw):
        from gyrodenoise.flightlog import filter_review as fr
        return fr.ardupilot_notch(params, fund, ctx, centre, bw)

    def lowpass_param(self, params):
        # an APM 2.x log whose only gyro low-pass is INS_MPU6K_FILTER (the sensor's own
        # filter, a few fixed values) gets none
        if params and "INS_GYRO_FILTER" not in params and "INS_MPU6K_FILTER" in params:
            return None
        return "INS_GYRO_FILTER"


class PX4(Autopilot):
    name = "px4"
    mav_autopilot = 12
    param_prefixes = ("IMU_GYRO_", "MC_", "SENS_")
    filter_param_prefixes = ("IMU_GYRO_CUTOFF", "IMU_GYRO_NF", "IMU_GYRO_DNF_", "IMU_GYRO_RATEMAX",
                             "IMU_DGYRO_CUTOFF", "IMU_GYRO_FFT_", "IMU_INTEG_RATE")
    int_params_bytewise = True

    def filter_chain(self, params):
        from gyrodenoise.flightlog import vehicle_filters as vf
        return vf.px4_chain(params)

    def stream_stage(self, params, stream):
        from gyrodenoise.flightlog import vehicle_filters as vf
        return vf.px4_stream_stage(params, stream)

    def review_context(self, log, params, filters, flying_mask_fn, ctx):
        from gyrodenoise.flightlog import filter_review as fr
        return fr.px4_context(log, params, filters, flying_mask_fn, ctx)

    def review_filter_rate(self, stream, rate, params, ctx):
        fft = ctx.get("gyro_fft")
        if fft is not None and fft.get("sample_rate_hz"):
            return fft["sample_rate_hz"], "sensor_gyro_fft.sensor_sample_rate_hz (the raw gyro rate)"
        return None

    def no_stream_reason(self, params, streams):
        return ", and the high-rate gyro FIFO (sensor_gyro_fifo) is not logged"

    def recommend_notch(self, params, fund, ctx, centre, bw):
        from gyrodenoise.flightlog import filter_review as fr
        return fr.px4_notch(params, fund, ctx, centre, bw)

    def recommend_without_notch(self, params, ctx):
        from gyrodenoise.flightlog import filter_review as fr
        return fr.px4_dynamic_notch(params, ctx)

    def lowpass_param(self, params):
        return "IMU_GYRO_CUTOFF"

    #: PX4's MAVLink VIBRATION fields: what of vehicle_imu_status each carries
    VIBRATION_FIELDS = {"vibration_x": "delta_angle_coning_metric", "vibration_y": "gyro_vibration_metric",
                        "vibration_z": "accel_vibration_metric"}

    def vibration_levels(self, levels):
        """PX4's telemetry VIBRATION carries vehicle_imu_status' metrics (x the delta-angle
        coning, y the gyro vibration, z the accelerometer vibration metric:
        MavlinkStreamVibration), not ArduPilot's m/s/s levels: renamed, and judged on the
        PX4 Flight Review thresholds (the accelerometer metric only)."""
        if levels.get("source") != "VIBRATION":
            return levels
        renamed = {self.VIBRATION_FIELDS.get(k, k): v for k, v in levels["levels"].items()}
        return dict(levels, source="VIBRATION (PX4: vehicle_imu_status metrics)",
                    threshold="accel_vibration_metric_m_s2", levels=renamed)

    def param_lines(self, changes):
        return [f"param set {k} {fmt_value(v)}" for k, v in changes.items()]


class Betaflight(Autopilot):
    """Betaflight: its gyro filter chain from the blackbox header (low-passes, static and
    dynamic notches, RPM filter: :mod:`gyrodenoise.flightlog.betaflight_filters`), its
    streams' stages (``gyroADC`` after the filters, debug ``GYRO_SCALED`` before), and its
    recommendations (``betaflight_filters.recommend``) as ``set name = value`` lines."""
    name = "betaflight"
    filter_param_prefixes = ("gyro_", "dyn_notch_", "dyn_lpf_", "rpm_filter_", "looptime", "dshot_bidir")
    STAGES = {"gyroADC": "post-filter", "debug": "pre-filter"}

    @staticmethod
    def settings(params):
        from gyrodenoise.flightlog.betaflight_filters import FilterSettings
        return FilterSettings.from_header(params)

    def filter_chain(self, params):
        from gyrodenoise.flightlog.betaflight_filters import review_stages
        s = self.settings(params)
        return review_stages(s), s.gyro_rate_hz, f"looptime {params.get('looptime')} us (the gyro loop)"

    def stream_stage(self, params, stream):
        return self.STAGES.get(stream.message, "unknown")

    def review_context(self, log, params, filters, flying_mask_fn, ctx):
        return dict(ctx, rpm_available=str(params.get("dshot_bidir", "0")).strip() == "1")

    def no_stream_reason(self, params, streams):
        return (f", and the debug mode ({params.get('debug_mode', 'not logged')}) is not GYRO_SCALED (6): the "
                "blackbox holds no gyro from before the filters")

    def _recommend(self, params, **evidence):
        from gyrodenoise.flightlog.betaflight_filters import changed_settings, recommend
        s = self.settings(params)
        rec = recommend(s, **evidence)
        return changed_settings(s, rec), list(rec.reasons)

    def recommend_notch(self, params, fund, ctx, centre, bw):
        s = self.settings(params)
        changes, why = self._recommend(params, noise_peak_hz=fund["freq_hz"])
        if not changes:
            why = [f"dominant vibration at {centre:g} Hz ({fund['axis']} axis): inside the dynamic notch range "
                   f"{s.dyn_notch_min_hz}-{s.dyn_notch_max_hz} Hz, which follows it" if s.dyn_notch_max_hz else
                   f"dominant vibration at {centre:g} Hz: the dynamic notch is off, no range to widen"]
        return changes, None, why

    def recommend_without_notch(self, params, ctx):
        return self._recommend(params, rpm_available=bool(ctx.get("rpm_available")))

    def lowpass_param(self, params):
        return None

    def param_lines(self, changes):
        return [f"set {k.lower()} = {fmt_value(v)}" for k, v in changes.items()]


UNKNOWN = Autopilot()
ARDUPILOT, PX4_AUTOPILOT, BETAFLIGHT = ArduPilot(), PX4(), Betaflight()
#: every autopilot strategy, by the report's name
AUTOPILOTS = {a.name: a for a in (ARDUPILOT, PX4_AUTOPILOT, BETAFLIGHT)}


def named(autopilot) -> Autopilot:
    """The strategy of ``autopilot``: a strategy is returned as it is, a name looked up
    in :data:`AUTOPILOTS`, None (or an unknown name) is :data:`UNKNOWN`."""
    if isinstance(autopilot, Autopilot):
        return autopilot
    return AUTOPILOTS.get(autopilot, UNKNOWN)


def from_mav_autopilot(mav_id) -> Autopilot:
    """The strategy of a ``HEARTBEAT.autopilot`` id (:data:`UNKNOWN` when none matches)."""
    return next((a for a in AUTOPILOTS.values() if a.mav_autopilot == mav_id), UNKNOWN)


def from_parameter_names(names) -> Autopilot:
    """The strategy whose ``param_prefixes`` the first of ``names`` matches, in registry order."""
    names = list(names)
    for a in AUTOPILOTS.values():
        if a.param_prefixes and any(n.startswith(a.param_prefixes) for n in names):
            return a
    return UNKNOWN
