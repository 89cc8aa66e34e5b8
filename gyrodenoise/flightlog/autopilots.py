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

    # --- motor speed (ESC RPM) ---
    # what moves the filters along the flight and the logged post-filter gyro, for the
    # replay (gyrodenoise.flightlog.notch_replay)

    def motor_speed(self, log):
        """The motors' speed (a :class:`~gyrodenoise.flightlog.notch_replay.Track`, rev/min
        per motor as (m, motors)) where the log holds ESC telemetry, else None."""
        return None

    def notch_tracks(self, log, params, filters):
        """{stage ``params``: Track} of what moves each tracking stage along the flight."""
        return {}

    def logged_post_filter(self, log, pre_stream):
        """The logged post-filter gyro (:class:`~gyrodenoise.flightlog.notch_replay.GyroSeries`)
        of the IMU of ``pre_stream``, or None."""
        return None

    def pre_filter_production(self, log, params, filters, pre_stream):
        """How the logged pre-filter stream was made from the gyro the filters run on (a
        :class:`~gyrodenoise.flightlog.notch_replay.Production`), or None: taken at the
        filters' rate, as it is."""
        return None

    def replay_sections(self, params, filters, tracks, time_s, rate_hz):
        """((n, k, 5) biquads per sample, notes) of the vehicle's chain along the flight."""
        import numpy as np
        return np.zeros((len(time_s), 0, 5)), ["unknown autopilot: no filter chain to replay"]

    # --- estimator noise (EKF parameters) ---

    #: {"gyro"|"accel": (parameter name, unit, (lo, hi) documented range, default)}; the
    #: EKF's prediction step (s): the parameter is the 1-sigma noise of one step's rate
    EKF_NOISE_PARAMS: dict = {}
    EKF_DT_S: float | None = None
    EKF_NOISE_SOURCE = ""

    def ekf_noise_params(self, gyro_density, accel_density, params):
        """{name: {"value", "unit", "range", "logged", "from", "clamped"}} of the EKF noise
        parameters for white noise of ``gyro_density`` (rad/s/sqrt(Hz)) and
        ``accel_density`` (m/s/s/sqrt(Hz)) (either None: left out): the density over
        sqrt(the EKF step) -- a delta angle over dt has variance density**2 dt, the
        EKF's (dt sigma)**2 -- kept within the parameter's documented range. Empty for
        an autopilot without an EKF."""
        out = {}
        for kind, density in (("gyro", gyro_density), ("accel", accel_density)):
            if kind not in self.EKF_NOISE_PARAMS or density is None or not self.EKF_DT_S:
                continue
            name, unit, (lo, hi), default = self.EKF_NOISE_PARAMS[kind]
            raw = float(density) / self.EKF_DT_S ** 0.5
            val = min(max(raw, lo), hi)
            out[name] = {"value": round(val, 5), "unit": unit, "range": [lo, hi], "default": default,
                         "logged": params.get(name), "clamped": val != raw,
                         "from": f"{density:.4g} {unit}/sqrt(Hz) / sqrt({self.EKF_DT_S:g} s, the EKF step)"}
        return out

    def accel_series(self, log):
        """[(name, time_s, (n, 3) m/s/s)] of the log's accelerometers."""
        return [(a.name, a.time_s, a.values) for a in getattr(log, "accel", []) or []]


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

    # --- motor speed (ESC RPM) ---

    def motor_speed(self, log):
        from gyrodenoise.flightlog import notch_replay as nr
        return nr.instance_track(log.messages("ESC") if "ESC" in set(log.message_names() or []) else None,
                                 "Instance", "RPM", "ESC.RPM (rev/min)")

    def notch_tracks(self, log, params, filters):
        from gyrodenoise.flightlog import notch_replay as nr
        names = set(log.message_names() or [])
        out = {}
        for st in filters.get("stages", []):
            if st["kind"] != "harmonic_notch":
                continue
            tr = None
            if st["tracking"] == "throttle" and "CTUN" in names:
                tr = nr.column_track(log.messages("CTUN"), "ThO", "CTUN.ThO (throttle out)")
            elif st["tracking"] == "esc":
                tr = self.motor_speed(log)
            elif st["tracking"] == "fft" and "FTN" in names:
                m = log.messages("FTN")
                col = next((c for c in ("NF1", "DnF1") if c in m), None)
                tr = nr.column_track(m, col, f"FTN.{col} (Hz)") if col else None
            if tr is not None:
                out[st["params"]] = tr
        return out

    def logged_post_filter(self, log, pre_stream):
        from gyrodenoise.flightlog import notch_replay as nr
        from gyrodenoise.flightlog import vehicle_filters as vf
        params = log.parameters().values
        imu = pre_stream.instance or 0
        if pre_stream.message == "ISBD":
            imu = vf.batch_stage(params, vf._instance(pre_stream.name) or 0)[1] or 0
        cands = []
        for s in log.gyro:
            if s is pre_stream or vf.stream_stage(self, params, s) != "post-filter":
                continue
            own = vf.batch_stage(params, vf._instance(s.name) or 0)[1] if s.message == "ISBD" else s.instance
            if (own or 0) == imu:
                cands.append(s)
        best = max(cands, key=lambda s: (nr.series_rate(s.time_s), s.n), default=None)
        return nr.GyroSeries.of_stream(best)

    def replay_sections(self, params, filters, tracks, time_s, rate_hz):
        from gyrodenoise.flightlog import vehicle_filters as vf
        loop = float(params.get("SCHED_LOOP_RATE") or 400.0)
        return vf.replay_sections(filters.get("stages", []), tracks, time_s, rate_hz, loop)

    # --- estimator noise (EKF parameters) ---

    #: AP_NavEKF3 parameter table: EK3_GYRO_P_NSE "Rate gyro noise (rad/s)" 0.0001-0.1,
    #: default 0.015; EK3_ACC_P_NSE "Accelerometer noise (m/s^2)" 0.01-1.0, default 0.35
    EKF_NOISE_PARAMS = {"gyro": ("EK3_GYRO_P_NSE", "rad/s", (0.0001, 0.1), 0.015),
                        "accel": ("EK3_ACC_P_NSE", "m/s/s", (0.01, 1.0), 0.35)}
    #: EKF3's prediction step: EKF_TARGET_DT 0.012 s (AP_NavEKF3_core.h)
    EKF_DT_S = 0.012

    def accel_series(self, log):
        import numpy as np
        if getattr(log, "accel", None):          # the adapter read them
            return super().accel_series(log)
        out = []
        for name in ("IMU", "IMU2", "IMU3"):
            m = log.messages(name) if name in set(log.message_names() or []) else None
            if m is None or not all(c in m for c in ("AccX", "AccY", "AccZ")):
                continue
            inst = np.asarray(m.get("I", np.zeros(len(m["time_s"]))))
            for i in np.unique(inst):
                k = inst == i
                out.append((f"{name}[{int(i)}]" if name == "IMU" and len(np.unique(inst)) > 1 else name,
                            np.asarray(m["time_s"])[k],
                            np.stack([np.asarray(m[c], dtype=np.float64)[k] for c in ("AccX", "AccY", "AccZ")], 1)))
        return out


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

    # --- motor speed (ESC RPM) ---

    def motor_speed(self, log):
        from gyrodenoise.flightlog import notch_replay as nr
        m = log.messages("esc_status") if "esc_status" in set(log.message_names() or []) else None
        return nr.columns_track(m, "esc_rpm", "esc_status.esc[i].esc_rpm (rev/min)")

    def notch_tracks(self, log, params, filters):
        st = next((s for s in filters.get("stages", []) if s["kind"] == "dynamic_notch"
                   and "esc_rpm" in s.get("sources", [])), None)
        tr = self.motor_speed(log) if st is not None else None
        return {st["params"]: tr} if tr is not None else {}

    def logged_post_filter(self, log, pre_stream):
        import numpy as np
        from gyrodenoise.flightlog import notch_replay as nr
        m = log.messages("vehicle_angular_velocity") if "vehicle_angular_velocity" in set(
            log.message_names() or []) else None
        if m is None or not all(f"xyz[{k}]" in m for k in range(3)) or len(m["time_s"]) < 2:
            return None
        t = np.asarray(m["time_s"], dtype=np.float64)
        xyz = np.degrees(np.stack([np.asarray(m[f"xyz[{k}]"], dtype=np.float64) for k in range(3)], 1))
        return nr.GyroSeries("vehicle_angular_velocity", t, xyz, nr.series_rate(t))

    def pre_filter_production(self, log, params, filters, pre_stream):
        """``sensor_combined.gyro_rad`` is ``vehicle_imu``'s integrated delta angle over
        ``gyro_integral_dt`` divided by that interval (VehicleIMU, Integrator: the mean of
        the gyro samples integrated), and the ``IMU_GYRO_*`` filters run in
        VehicleAngularVelocity on each gyro sample at the gyro's rate, which
        ``vehicle_imu_status.gyro_rate_hz`` logs (the FIFO rate where the filters take
        the FIFO; ``sensor_gyro_fft.sensor_sample_rate_hz`` where that is logged)."""
        import numpy as np
        from gyrodenoise.flightlog import notch_replay as nr
        if pre_stream is None or pre_stream.message != "sensor_combined":
            return None
        names = set(log.message_names() or [])
        rate, src = None, ""
        if "vehicle_imu_status" in names:
            m = log.messages("vehicle_imu_status")
            if "gyro_rate_hz" in m and len(m["time_s"]):
                v = np.asarray(m["gyro_rate_hz"], dtype=np.float64)
                if "gyro_device_id" in m and "sensor_selection" in names:
                    sel = log.messages("sensor_selection").get("gyro_device_id")
                    if sel is not None and len(sel):
                        mine = np.asarray(m["gyro_device_id"]) == np.asarray(sel)[-1]
                        v = v[mine] if mine.any() else v
                v = v[v > 0]
                if len(v):
                    rate, src = float(np.median(v)), "vehicle_imu_status.gyro_rate_hz"
        if rate is None and filters.get("filter_rate_source", "").startswith("sensor_gyro_fft"):
            rate, src = float(filters["filter_rate_hz"]), filters["filter_rate_source"]
        if rate is None:
            return None
        m = log.messages("sensor_combined")
        n = 1
        if "gyro_integral_dt" in m and len(m["gyro_integral_dt"]):
            dt = float(np.median(np.asarray(m["gyro_integral_dt"], dtype=np.float64)))
            dt = dt * 1e-6 if dt > 1.0 else dt          # us in 1.x logs (a float s in the oldest)
            n = max(1, int(round(dt * rate)))
            src += f"; sensor_combined.gyro_integral_dt {dt * 1e6:.0f} us = {n} samples"
        return nr.Production(rate, n, src)

    def replay_sections(self, params, filters, tracks, time_s, rate_hz):
        from gyrodenoise.flightlog import vehicle_filters as vf
        coefs, notes = vf.replay_sections(filters.get("stages", []), tracks, time_s, rate_hz, None, slew=False)
        fs = filters.get("filter_rate_hz")
        if fs and abs(float(fs) - rate_hz) > 0.02 * rate_hz and not filters.get("filter_rate_source", "").startswith(
                "assumed"):
            notes = [f"designed at the logged rate {rate_hz:.0f} Hz; PX4 runs its filters at the raw gyro rate "
                     f"({float(fs):g} Hz, {filters.get('filter_rate_source')})"] + notes
        return coefs, notes

    # --- estimator noise (EKF parameters) ---

    #: PX4 parameter reference: EKF2_GYR_NOISE "Rate gyro noise for covariance prediction"
    #: rad/s 0.0001-0.1, default 0.015; EKF2_ACC_NOISE m/s^2 0.01-1.0, default 0.35
    EKF_NOISE_PARAMS = {"gyro": ("EKF2_GYR_NOISE", "rad/s", (0.0001, 0.1), 0.015),
                        "accel": ("EKF2_ACC_NOISE", "m/s/s", (0.01, 1.0), 0.35)}
    #: EKF2's prediction step: 10 ms (FILTER_UPDATE_PERIOD_MS)
    EKF_DT_S = 0.010

    def accel_series(self, log):
        import numpy as np
        if getattr(log, "accel", None):          # the adapter read them
            return super().accel_series(log)
        m = log.messages("sensor_combined") if "sensor_combined" in set(log.message_names() or []) else None
        cols = [f"accelerometer_m_s2[{k}]" for k in range(3)]
        if m is None or not all(c in m for c in cols):
            return []
        return [("sensor_combined", np.asarray(m["time_s"], dtype=np.float64),
                 np.stack([np.asarray(m[c], dtype=np.float64) for c in cols], 1))]

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

    # --- motor speed (ESC RPM) ---

    def motor_speed(self, log):
        """Motor rev/min from the blackbox's ``eRPM[i]`` (eRPM / 100 in the log; rev/min =
        eRPM x 100 / (motor_poles / 2)); None without them (Betaflight 4.2 logs none)."""
        import numpy as np
        from gyrodenoise.flightlog import notch_replay as nr
        rows = [(b.time_s, b.columns("eRPM")) for b in log.payload if len(b.main) and b.columns("eRPM") is not None]
        if not rows:
            return None
        poles = float(log.parameters().values.get("motor_poles", 14) or 14)
        rpm = np.concatenate([v for _, v in rows]).astype(np.float64) * 100.0 / (poles / 2.0)
        return nr.Track(np.concatenate([t for t, _ in rows]), rpm, "eRPM[i] (rev/min)")

    def notch_tracks(self, log, params, filters):
        import numpy as np
        from gyrodenoise.flightlog import notch_replay as nr
        out = {}
        rows = [(b.time_s, b.throttle) for b in log.payload if len(b.main) and b.throttle is not None]
        if rows:
            out["throttle"] = nr.Track(np.concatenate([t for t, _ in rows]), np.concatenate([v for _, v in rows]),
                                       "setpoint[3] / 1000 (throttle)")
        rpm = self.motor_speed(log)
        if rpm is not None:
            out["motor_hz"] = nr.Track(rpm.time_s, rpm.value / 60.0, rpm.source.replace("rev/min", "rev/s"))
        return out

    def logged_post_filter(self, log, pre_stream):
        from gyrodenoise.flightlog import notch_replay as nr
        return nr.GyroSeries.of_stream(next((s for s in log.gyro if s.message == "gyroADC"), None))

    def replay_sections(self, params, filters, tracks, time_s, rate_hz):
        from gyrodenoise.flightlog.betaflight_filters import replay_sections
        return replay_sections(self.settings(params), tracks, time_s, rate_hz)


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
