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

import numpy as np

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

    # --- time series (motors, vibration, failsafes) ---
    motors_looked_for = "nothing: the autopilot is unknown"
    rpm_looked_for = "nothing: the autopilot is unknown"

    def motor_channels(self, log):
        """The motor outputs (:class:`gyrodenoise.flightlog.timeseries.Channels`), or None."""
        return None

    def motor_rpm(self, log):
        """The motors' RPM, a column per motor (NaN where another motor's row), or None."""
        return None

    def event_label(self, text):
        """An event's text as the report shows it (an id named)."""
        return text

    def mode_names(self, log):
        """``{logged mode: its name}`` of this autopilot's flight modes (empty: shown as logged)."""
        return {}

    def failsafe_events(self, log):
        """The failsafes and errors the log records (``LogEvent``), beyond its events."""
        return []

    battery_looked_for = "nothing: the autopilot is unknown"
    rc_looked_for = "nothing: the autopilot is unknown"

    def battery_channels(self, log):
        """The battery's voltage [V] and current [A] (:class:`~gyrodenoise.flightlog.timeseries.Channels`,
        a column per battery), each None where not logged."""
        return None, None

    def rc_input(self, log):
        """The pilot's RC input (:class:`~gyrodenoise.flightlog.timeseries.Channels`), or None."""
        return None

    notch_track_looked_for = "nothing: the autopilot is unknown"

    def notch_centre_track(self, log):
        """The dynamic notch's centre frequencies over time as the vehicle logged them [Hz]
        (:class:`~gyrodenoise.flightlog.timeseries.Channels`, 0 and unset left out), or None."""
        return None

    pid_looked_for = "nothing: the autopilot is unknown"

    def pid_terms(self, log):
        """The rate controller's terms per axis: ``[(axis, Channels)]`` (P, I, D, FF as
        logged, in the controller's output unit), empty where not logged."""
        return []

    # --- motor speed (ESC RPM) ---
    # what moves the filters along the flight and the logged post-filter gyro, for the
    # replay (gyrodenoise.flightlog.notch_replay)

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

    def accel_filtering(self, params):
        """(stage, the accelerometer low-pass's parameter or None) of the logged accelerometers."""
        return "unknown", None

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

    # --- time series (motors, vibration, failsafes) ---
    motors_looked_for = "RCOU C1..Cn / Ch1..Chn, SERVO_OUTPUT_RAW (the SERVOn_FUNCTION motors)"
    rpm_looked_for = "ESC (RPM per Instance)"
    #: the outputs each SERVOn_FUNCTION names (ArduPilot SRV_Channel: 33..40 Motor1..8, 82..85 Motor9..12)
    MOTOR_FUNCTIONS = {**{33 + k: k + 1 for k in range(8)}, **{82 + k: k + 9 for k in range(4)}}
    #: motors per FRAME_CLASS (1 quad, 2 hexa, 3 octa, 4 octaquad, 5 Y6, 7 tri)
    FRAME_MOTORS = {1: 4, 2: 6, 3: 8, 4: 8, 5: 6, 7: 3}
    #: LogEvent ids (AP_Logger LogEvent) the markers name
    EVENTS = {10: "ARMED", 11: "DISARMED", 15: "AUTO_ARMED", 17: "LAND_COMPLETE_MAYBE", 18: "LAND_COMPLETE",
              19: "LOST_GPS", 21: "FLIP_START", 22: "FLIP_END", 25: "SET_HOME", 28: "NOT_LANDED"}
    #: ERR subsystems (AP_Logger LogErrorSubsystem)
    ERR_SUBSYSTEMS = {1: "MAIN", 2: "RADIO", 3: "COMPASS", 4: "OPTFLOW", 5: "FAILSAFE_RADIO", 6: "FAILSAFE_BATT",
                      7: "FAILSAFE_GPS", 8: "FAILSAFE_GCS", 9: "FAILSAFE_FENCE", 10: "FLIGHT_MODE", 11: "GPS",
                      12: "CRASH_CHECK", 13: "FLIP", 14: "AUTOTUNE", 15: "PARACHUTES", 16: "EKFCHECK",
                      17: "FAILSAFE_EKFINAV", 18: "BARO", 19: "CPU", 20: "FAILSAFE_ADSB", 21: "TERRAIN",
                      22: "NAVIGATION", 23: "FAILSAFE_TERRAIN", 24: "EKF_PRIMARY", 25: "THRUST_LOSS_CHECK",
                      26: "FAILSAFE_SENSORS", 27: "FAILSAFE_LEAK", 28: "PILOT_INPUT", 29: "FAILSAFE_VIBE"}
    #: each vehicle's flight mode numbers, as ``MODE.Mode`` and ``HEARTBEAT.custom_mode`` carry them: the
    #: MAVLink ardupilotmega dialect's COPTER_MODE, PLANE_MODE, ROVER_MODE and SUB_MODE enums (the
    #: vehicles' FLTMODE1 / MODE1 parameter values, https://ardupilot.org/dev/docs/mavlink-get-set-flightmode.html)
    COPTER_MODES = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 5: "LOITER", 6: "RTL",
                    7: "CIRCLE", 9: "LAND", 11: "DRIFT", 13: "SPORT", 14: "FLIP", 15: "AUTOTUNE", 16: "POSHOLD",
                    17: "BRAKE", 18: "THROW", 19: "AVOID_ADSB", 20: "GUIDED_NOGPS", 21: "SMART_RTL",
                    22: "FLOWHOLD", 23: "FOLLOW", 24: "ZIGZAG", 25: "SYSTEMID", 26: "AUTOROTATE", 27: "AUTO_RTL",
                    28: "TURTLE"}
    PLANE_MODES = {0: "MANUAL", 1: "CIRCLE", 2: "STABILIZE", 3: "TRAINING", 4: "ACRO", 5: "FBWA", 6: "FBWB",
                   7: "CRUISE", 8: "AUTOTUNE", 10: "AUTO", 11: "RTL", 12: "LOITER", 13: "TAKEOFF", 14: "AVOID_ADSB",
                   15: "GUIDED", 16: "INITIALISING", 17: "QSTABILIZE", 18: "QHOVER", 19: "QLOITER", 20: "QLAND",
                   21: "QRTL", 22: "QAUTOTUNE", 23: "QACRO", 24: "THERMAL", 25: "LOITER_ALT_QLAND"}
    ROVER_MODES = {0: "MANUAL", 1: "ACRO", 3: "STEERING", 4: "HOLD", 5: "LOITER", 6: "FOLLOW", 7: "SIMPLE",
                   8: "DOCK", 9: "CIRCLE", 10: "AUTO", 11: "RTL", 12: "SMART_RTL", 15: "GUIDED", 16: "INITIALISING"}
    SUB_MODES = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 7: "CIRCLE", 9: "SURFACE",
                 16: "POSHOLD", 19: "MANUAL", 20: "MOTOR_DETECT", 21: "SURFTRAK"}
    #: the vehicle the boot message names (its firmware's name ends so) -> its modes
    VEHICLE_MODES = (("Copter", COPTER_MODES), ("Plane", PLANE_MODES), ("Rover", ROVER_MODES), ("Sub", SUB_MODES))
    #: where no boot message names it: the vehicle's HEARTBEAT.type (MAV_TYPE) -> its modes (fixed wing and
    #: the VTOL types run Plane; multirotors and helicopters Copter; rovers and boats Rover; submarines Sub)
    MAV_TYPE_MODES = {1: PLANE_MODES, **dict.fromkeys((2, 3, 4, 13, 14, 15, 29), COPTER_MODES),
                      **dict.fromkeys((19, 20, 21, 22, 23, 24, 25), PLANE_MODES),
                      **dict.fromkeys((10, 11), ROVER_MODES), 12: SUB_MODES}

    def motor_channels(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        params = log.parameters().values
        motors = {}
        for n in range(1, 33):
            f = params.get(f"SERVO{n}_FUNCTION")
            if f is not None and int(f) in self.MOTOR_FUNCTIONS:
                motors[n] = self.MOTOR_FUNCTIONS[int(f)]
        for name, col in (("RCOU", "C{}"), ("RCOU", "Ch{}"), ("SERVO_OUTPUT_RAW", "servo{}_raw")):
            m = log.messages(name)
            if m is None or col.format(1) not in m:
                continue
            note = ""
            if not motors:
                count, why = self._motor_count(log, params)
                motors = {n: n for n in range(1, count + 1)}
                note = f"SERVOn_FUNCTION not logged: outputs 1..{count} taken as the motors ({why})"
            cols = {f"motor {k} ({col.format(n)})": m[col.format(n)].astype(float)
                    for n, k in sorted(motors.items(), key=lambda nk: nk[1]) if col.format(n) in m}
            return Channels(f"{name} {col.format('n')}", "PWM us", m["time_s"], cols, log.rows_boot(m), note)
        return None

    #: the motors of the frame the boot message names (``Frame: QUAD/X``), before FRAME_CLASS existed
    FRAME_WORD_MOTORS = (("OCTA", 8), ("HEXA", 6), ("Y6", 6), ("QUAD", 4), ("TRI", 3))

    def _motor_count(self, log, params):
        """(motors, from what) of the frame: FRAME_CLASS, else the boot message's frame, else 4."""
        if params.get("FRAME_CLASS") is not None:
            return self.FRAME_MOTORS.get(int(params["FRAME_CLASS"]), 4), f"FRAME_CLASS {fmt_value(params['FRAME_CLASS'])}"
        frame = str(log.format.identity(log).get("frame") or "")
        count = next((n for word, n in self.FRAME_WORD_MOTORS if word in frame.upper()), None)
        if count is not None:
            return count, f"frame {frame} in the boot messages"
        return 4, "neither FRAME_CLASS nor the frame logged: a quad assumed"

    def motor_rpm(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("ESC")
        if m is None or "RPM" not in m:
            return None
        inst = m["Instance"].astype(int) if "Instance" in m else np.zeros(len(m["time_s"]), int)
        rpm = m["RPM"].astype(float)
        cols = {f"ESC {i}": np.where(inst == i, rpm, np.nan) for i in np.unique(inst)}
        return Channels("ESC.RPM", "rpm", m["time_s"], cols, log.rows_boot(m))

    def event_label(self, text):
        head, _, num = text.partition(" ")
        if head == "EV" and num.isdigit() and int(num) in self.EVENTS:
            return f"{text} {self.EVENTS[int(num)]}"
        return text

    def mode_names(self, log):
        """The modes of the vehicle the boot messages name (ArduCopter, APM:Plane, Rover, ArduSub),
        else of the vehicle's HEARTBEAT type (a telemetry log without them); {} when neither says."""
        vehicle = str(log.format.identity(log).get("vehicle") or "")
        modes = next((m for word, m in self.VEHICLE_MODES if word in vehicle), None)
        if modes is None:
            modes = self.MAV_TYPE_MODES.get(self._heartbeat_type(log), {})
        return {str(k): v for k, v in modes.items()}

    @staticmethod
    def _heartbeat_type(log):
        """The MAV_TYPE most HEARTBEATs of an autopilot carry (not a ground station's: type 6,
        autopilot 8), or None."""
        hb = log.messages("HEARTBEAT")
        if hb is None or "type" not in hb:
            return None
        veh = (hb["type"] != 6) & (hb["autopilot"] != 8) if "autopilot" in hb else hb["type"] != 6
        if not veh.any():
            return None
        types, counts = np.unique(hb["type"][veh].astype(int), return_counts=True)
        return int(types[np.argmax(counts)])

    def failsafe_events(self, log):
        from gyrodenoise.flightlog.model import LogEvent
        m = log.messages("ERR")
        if m is None or "Subsys" not in m:
            return []
        return [LogEvent(float(t), int(b), f"ERR {self.ERR_SUBSYSTEMS.get(int(s), 'subsystem')} ({int(s)}) "
                                           f"ECode {int(c)}" + (" (cleared)" if int(c) == 0 else ""))
                for t, b, s, c in zip(m["time_s"], log.rows_boot(m), m["Subsys"], m["ECode"])]

    battery_looked_for = "BAT (Volt, Curr per Instance), CURR (cV, cA), SYS_STATUS (mV, cA)"
    rc_looked_for = "RCIN C1..C8, RC_CHANNELS / RC_CHANNELS_RAW chan1_raw..chan8_raw"
    #: (message, voltage field, current field, to volts, to amperes, the value meaning "not measured")
    BATTERY_FIELDS = (("BAT", "Volt", "Curr", 1.0, 1.0, None), ("CURR", "Volt", "Curr", 0.01, 0.01, None),
                      ("SYS_STATUS", "voltage_battery", "current_battery", 0.001, 0.01, (65535, -1)))

    def battery_channels(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        for name, vf, cf, v_scale, c_scale, unset in self.BATTERY_FIELDS:
            m = log.messages(name)
            if m is None or vf not in m:
                continue
            inst = m["Instance"].astype(int) if "Instance" in m else np.zeros(len(m["time_s"]), int)
            several = len(np.unique(inst)) > 1
            out = []
            for field, scale, unit, not_set in ((vf, v_scale, "V", unset and unset[0]),
                                                (cf, c_scale, "A", unset and unset[1])):
                v = m[field].astype(float) if field in m else np.full(len(inst), np.nan)
                v = np.where(v == not_set, np.nan, v * scale) if not_set is not None else v * scale
                cols = {(f"{field}[{i}]" if several else field): np.where(inst == i, v, np.nan) for i in np.unique(inst)}
                out.append(Channels(f"{name}.{field}", unit, m["time_s"], cols, log.rows_boot(m))
                           if np.isfinite(v).any() else None)
            return tuple(out)
        return None, None

    def rc_input(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        for name, col in (("RCIN", "C{}"), ("RC_CHANNELS", "chan{}_raw"), ("RC_CHANNELS_RAW", "chan{}_raw")):
            m = log.messages(name)
            if m is None or col.format(1) not in m:
                continue
            # 0 and 65535: a channel not received (MAVLink's UINT16_MAX, or never set)
            cols = {col.format(n): np.where(np.isin(v := m[col.format(n)].astype(float), (0, 65535)), np.nan, v)
                    for n in range(1, 9) if col.format(n) in m}
            cols = {k: v for k, v in cols.items() if np.isfinite(v).any()}
            if cols:
                return Channels(f"{name} {col.format('n')}", "PWM us", m["time_s"], cols, log.rows_boot(m))
        return None

    notch_track_looked_for = "FTN NF1.. / DnF1.. (the harmonic notch's centres as tracked)"

    def notch_centre_track(self, log):
        # FTN: the harmonic notch's dynamic centre per source (motor, or FFT peak), as
        # updated by the vehicle (NF1..NF12 in 4.2+, DnF1..DnF4 before); 0: unused
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("FTN")
        if m is None:
            return None
        cols = {}
        for c in [c for c in m if any(c.startswith(p) and c[len(p):].isdigit() for p in ("NF", "DnF"))]:
            v = np.asarray(m[c], np.float64)
            v = np.where(np.isfinite(v) & (v > 0), v, np.nan)
            if np.isfinite(v).any():
                cols[c] = v
        if not cols:
            return None
        inst = np.asarray(m["I"]) if "I" in m else None
        if inst is not None and len(np.unique(inst)) > 1:      # one notch set per instance: its own columns
            cols = {f"{c}[{i}]": np.where(inst == i, v, np.nan) for c, v in cols.items() for i in np.unique(inst)}
        return Channels("FTN " + ", ".join(cols), "Hz", m["time_s"], cols, log.rows_boot(m))

    pid_looked_for = "PIDR, PIDP, PIDY (P, I, D, FF)"

    def pid_terms(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        out = []
        for name, axis in (("PIDR", "roll"), ("PIDP", "pitch"), ("PIDY", "yaw")):
            m = log.messages(name)
            if m is None:
                continue
            cols = {c: np.asarray(m[c], np.float64) for c in ("P", "I", "D", "FF") if c in m}
            if cols:
                out.append((axis, Channels(f"{name} {', '.join(cols)}", "controller output", m["time_s"], cols,
                                           log.rows_boot(m))))
        return out

    # --- motor speed (ESC RPM) ---

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
                tr = nr.track_of(self.motor_rpm(log))
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

    def accel_filtering(self, params):
        # IMU.AccX.. and RAW_IMU's accel are AP_InertialSensor::get_accel, after INS_ACCEL_FILTER
        return "post-filter", "INS_ACCEL_FILTER"

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

    def notch_tracks(self, log, params, filters):
        st = next((s for s in filters.get("stages", []) if s["kind"] == "dynamic_notch"
                   and "esc_rpm" in s.get("sources", [])), None)
        from gyrodenoise.flightlog import notch_replay as nr
        tr = nr.track_of(self.motor_rpm(log)) if st is not None else None
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

    def accel_filtering(self, params):
        # sensor_combined's accelerometer: vehicle_imu's integrated delta velocity, before the
        # IMU_ACCEL_CUTOFF filter (which feeds vehicle_acceleration) since PX4 1.11 (IMU_INTEG_RATE)
        return ("pre-filter" if "IMU_INTEG_RATE" in params else "unknown"), None

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

    # --- time series (motors, vibration, failsafes) ---
    motors_looked_for = "actuator_motors.control[i], actuator_outputs.output[i]"
    rpm_looked_for = "esc_status esc[i].esc_rpm"
    #: vehicle_status.nav_state (PX4 vehicle_status.msg NAVIGATION_STATE_*)
    NAV_STATES = {0: "MANUAL", 1: "ALTCTL", 2: "POSCTL", 3: "AUTO_MISSION", 4: "AUTO_LOITER", 5: "AUTO_RTL",
                  10: "ACRO", 12: "DESCEND", 13: "TERMINATION", 14: "OFFBOARD", 15: "STAB", 17: "AUTO_TAKEOFF",
                  18: "AUTO_LAND", 19: "AUTO_FOLLOW_TARGET", 20: "AUTO_PRECLAND", 21: "ORBIT",
                  22: "AUTO_VTOL_TAKEOFF"}
    #: at most this many outputs of actuator_outputs are shown (which drive motors is not logged there)
    MAX_OUTPUTS = 8

    def motor_channels(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("actuator_motors")
        if m is not None:
            cols = {f"motor {i + 1}": m[c].astype(float) for i in range(16) if (c := f"control[{i}]") in m
                    and np.isfinite(m[c].astype(float)).any()}
            if cols:
                return Channels("actuator_motors.control", "0..1", m["time_s"], cols)
        m = log.messages("actuator_outputs")
        if m is None:
            return None
        n = int(np.nanmax(m["noutputs"])) if "noutputs" in m and len(m["noutputs"]) else self.MAX_OUTPUTS
        cols = {f"output {i + 1}": m[c].astype(float) for i in range(min(n, self.MAX_OUTPUTS))
                if (c := f"output[{i}]") in m and np.ptp(m[c]) > 0}
        return Channels("actuator_outputs.output", "PWM us / raw", m["time_s"], cols,
                        note="actuator_outputs: the log does not say which outputs drive motors; those "
                             "that vary are shown") if cols else None

    def motor_rpm(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("esc_status")
        if m is None:
            return None
        cols = {f"ESC {i}": m[c].astype(float) for i in range(8) if (c := f"esc[{i}].esc_rpm") in m
                and np.nanmax(np.abs(m[c])) > 0}
        return Channels("esc_status.esc[i].esc_rpm", "rpm", m["time_s"], cols) if cols else None

    def mode_names(self, log):
        return {str(k): v for k, v in self.NAV_STATES.items()}

    def failsafe_events(self, log):
        """``vehicle_status.failsafe`` where it changes, and each ``failsafe_flags`` flag
        (not the ``mode_req_*`` masks) where it is raised or cleared."""
        from gyrodenoise.flightlog.model import LogEvent
        out = []
        vs = log.messages("vehicle_status")
        if vs is not None and "failsafe" in vs:
            out += _edges(vs["time_s"], vs["failsafe"], "failsafe on", "failsafe off")
        ff = log.messages("failsafe_flags")
        for k in (ff or {}):
            if k not in ("timestamp", "time_s", "record") and not k.startswith("mode_req_"):
                out += _edges(ff["time_s"], ff[k], f"failsafe_flags.{k} raised", f"failsafe_flags.{k} cleared")
        return [LogEvent(t, 0, text) for t, text in out]

    battery_looked_for = "battery_status voltage_v, current_a"
    rc_looked_for = "input_rc values[0..7]"

    def battery_channels(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("battery_status")
        if m is None:
            return None, None
        out = []
        for field, unit in (("voltage_v", "V"), ("current_a", "A")):
            v = m[field].astype(float) if field in m else None
            if v is not None:
                v = np.where(v < 0, np.nan, v)               # -1: not measured
            out.append(Channels(f"battery_status.{field}", unit, m["time_s"], {field: v})
                       if v is not None and np.isfinite(v).any() else None)
        return tuple(out)

    def rc_input(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("input_rc")
        if m is None:
            return None
        n = int(np.nanmax(m["channel_count"])) if "channel_count" in m and len(m["channel_count"]) else 8
        cols = {f"ch {i + 1}": m[c].astype(float) for i in range(min(n, 8)) if (c := f"values[{i}]") in m}
        return Channels("input_rc.values", "PWM us", m["time_s"], cols) if cols else None

    notch_track_looked_for = "sensor_gyro_fft peak_frequencies_x/y/z (the onboard FFT's peaks)"

    def notch_centre_track(self, log):
        # the onboard FFT's strongest peak per axis: where the FFT-driven dynamic notch
        # (IMU_GYRO_DNF_EN) puts its centres; 0 / NaN: no peak
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("sensor_gyro_fft")
        if m is None:
            return None
        cols = {}
        for a in "xyz":
            c = f"peak_frequencies_{a}[0]"
            if c in m:
                v = np.asarray(m[c], np.float64)
                v = np.where(np.isfinite(v) & (v > 0), v, np.nan)
                if np.isfinite(v).any():
                    cols[f"FFT peak {a}"] = v
        return Channels("sensor_gyro_fft.peak_frequencies_*[0]", "Hz", m["time_s"], cols) if cols else None

    pid_looked_for = "rate_ctrl_status (the rate integrators only: PX4 logs no P/D terms)"

    def pid_terms(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("rate_ctrl_status")
        if m is None:
            return []
        cols = {f"I {a}": np.asarray(m[f"{a}speed_integ"], np.float64) for a in ("roll", "pitch", "yaw")
                if f"{a}speed_integ" in m}
        return [("roll, pitch, yaw", Channels("rate_ctrl_status.*speed_integ", "integrator", m["time_s"], cols))] \
            if cols else []


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
        changes, why = self._recommend(params, noise_peak_hz=fund["freq_hz"],
                                       rpm_available=bool(ctx.get("rpm_available")),
                                       noise_band_hz=fund["band_hz"] if fund.get("kind") == "hump" else None)
        if not changes and not why:
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

    # --- time series (motors, vibration, failsafes) ---
    motors_looked_for = "motor[0..3] (main frames)"
    rpm_looked_for = "eRPM[i] (logged with bidirectional DShot, Betaflight 4.3 on)"

    def motor_channels(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("motor")
        if m is None:
            return None
        cols = {f"motor {i + 1}": m[c].astype(float) for i in range(8) if (c := f"motor[{i}]") in m}
        rng = log.parameters().values.get("motorOutput", "")
        return Channels("motor[i]", f"motor output ({rng})" if rng else "motor output", m["time_s"], cols,
                        log.rows_boot(m))

    battery_looked_for = "vbatLatest, amperageLatest (0.01 V, 0.01 A)"
    rc_looked_for = "rcCommand[0..3]"

    def battery_channels(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        out = []
        for field, unit in (("vbatLatest", "V"), ("amperageLatest", "A")):
            m = log.messages(field)
            out.append(None if m is None or field not in m else
                       Channels(field, unit, m["time_s"], {field: m[field].astype(float) * 0.01}, log.rows_boot(m)))
        return tuple(out)

    def rc_input(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        m = log.messages("rcCommand")
        if m is None:
            return None
        cols = {f"{a} (rcCommand[{i}])": m[f"rcCommand[{i}]"].astype(float)
                for i, a in enumerate(("roll", "pitch", "yaw", "throttle")) if f"rcCommand[{i}]" in m}
        return Channels("rcCommand[i]", "roll/pitch/yaw -500..500, throttle 1000..2000", m["time_s"], cols,
                        log.rows_boot(m)) if cols else None

    pid_looked_for = "axisP, axisI, axisD, axisF"

    def pid_terms(self, log):
        from gyrodenoise.flightlog.timeseries import Channels
        terms = {t: log.messages(f"axis{t}") for t in ("P", "I", "D", "F")}
        out = []
        for i, axis in enumerate(("roll", "pitch", "yaw")):
            cols, t, boot = {}, None, None
            for term, m in terms.items():
                if m is not None and f"axis{term}[{i}]" in m:
                    cols["FF" if term == "F" else term] = np.asarray(m[f"axis{term}[{i}]"], np.float64)
                    t, boot = m["time_s"], log.rows_boot(m)
            if cols and all(len(v) == len(t) for v in cols.values()):
                out.append((axis, Channels(f"axisP/I/D/F[{i}]", "PID sum units", t, cols, boot)))
        return out


    # --- motor speed (ESC RPM) ---

    def motor_rpm(self, log):
        """Motor rev/min from the blackbox's ``eRPM[i]`` (eRPM / 100 in the log; rev/min =
        eRPM x 100 / (motor_poles / 2)); None without them (Betaflight 4.2 logs none)."""
        from gyrodenoise.flightlog.timeseries import Channels
        rows = [(b.time_s, b.columns("eRPM")) for b in log.payload if len(b.main) and b.columns("eRPM") is not None]
        if not rows:
            return None
        poles = float(log.parameters().values.get("motor_poles", 14) or 14)
        rpm = np.concatenate([v for _, v in rows]).astype(np.float64) * 100.0 / (poles / 2.0)
        rpm = rpm.reshape(len(rpm), -1)
        return Channels("eRPM[i]", "rpm", np.concatenate([t for t, _ in rows]),
                        {f"motor {i}": rpm[:, i] for i in range(rpm.shape[1])})

    def notch_tracks(self, log, params, filters):
        import numpy as np
        from gyrodenoise.flightlog import notch_replay as nr
        out = {}
        rows = [(b.time_s, b.throttle) for b in log.payload if len(b.main) and b.throttle is not None]
        if rows:
            out["throttle"] = nr.Track(np.concatenate([t for t, _ in rows]), np.concatenate([v for _, v in rows]),
                                       "setpoint[3] / 1000 (throttle)")
        rpm = nr.track_of(self.motor_rpm(log))
        if rpm is not None:
            out["motor_hz"] = nr.Track(rpm.time_s, rpm.value / 60.0, f"{rpm.source} (rev/s)")
        return out

    def logged_post_filter(self, log, pre_stream):
        from gyrodenoise.flightlog import notch_replay as nr
        return nr.GyroSeries.of_stream(next((s for s in log.gyro if s.message == "gyroADC"), None))

    def replay_sections(self, params, filters, tracks, time_s, rate_hz):
        from gyrodenoise.flightlog.betaflight_filters import replay_sections
        return replay_sections(self.settings(params), tracks, time_s, rate_hz)


def _edges(time_s, values, on, off):
    """[(time, text)] where ``values`` turns true (``on``) or false (``off``), the first row
    counted only when true."""
    v = np.asarray(values).astype(bool)
    if not len(v):
        return []
    prev = np.concatenate([[False], v[:-1]])
    return [(float(time_s[i]), on if v[i] else off) for i in np.flatnonzero(v != prev)]

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
