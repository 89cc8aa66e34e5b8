"""ROS 1 bags, ROS 2 bags (a folder with its ``metadata.yaml``, or a bare ``.db3``) and MCAP
files with ``sensor_msgs/Imu``: the adapter (:mod:`gyrodenoise.flightlog.formats`), over
:mod:`gyrodenoise.flightlog.rosbag`.

Gyro streams: one per Imu topic (named by its topic), ``angular_velocity`` in rad/s
(REP 103), timed by the messages' header stamps (the rate is measured from them); a topic
whose stamps are all zero (a driver that leaves them unset) is timed by the bag's receive
times instead, and its note says so. Stamps above 1e9 s are Unix time: the times then start
at 0 at the bag's first Imu stamp and the time base says so (a simulation or boot clock is
kept as it is). One boot per bag.

Accelerometer: ``linear_acceleration`` (m/s^2) of each Imu topic that does not declare it
absent. The filtered copy: a bag of the same kind with the same connections and messages in
the same order, in each filtered topic's messages only ``angular_velocity`` patched
(:func:`gyrodenoise.flightlog.rosbag.write_filtered`). A bag holds no arming, throttle,
landed state or autopilot parameters: the review says so.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from gyrodenoise.flightlog import rosbag
from gyrodenoise.flightlog.adapters import BaseFormat
from gyrodenoise.flightlog.autopilots import UNKNOWN
from gyrodenoise.flightlog.model import UNIX_EPOCH, Boot, FlightLog, LogFacts, LogParameters, TimeBase
from gyrodenoise.flightlog.stopping import completed_path
from gyrodenoise.flightlog.streams import AccelStream, GyroStream
from gyrodenoise.units import RAD_TO_DEG

NO_FLIGHT = ("a ROS bag's sensor_msgs/Imu holds no arming, throttle, land-detector or GPS state "
             "(only Imu topics are read)")


class RosBagFormat(BaseFormat):
    name = "rosbag"
    description = "a ROS 1/ROS 2 bag or MCAP file"
    suffixes = (".bag", ".mcap", ".db3")
    gyro_looked_for = "sensor_msgs/Imu topics (angular_velocity)"
    flight_looked_for = "nothing: " + NO_FLIGHT
    vibration_looked_for = "sensor_msgs/Imu linear_acceleration"

    def sniff(self, head):
        return head.startswith((rosbag.ROS1_MAGIC, rosbag.MCAP_MAGIC, rosbag.SQLITE_MAGIC))

    def sniff_folder(self, path):
        return rosbag.sniff_ros2_dir(Path(path))

    def read(self, path, options):
        bag = rosbag.read_imu(path)
        firsts = [int(_times_ns(t)[0].min()) for t in bag.imu if len(t)]
        epoch = bool(firsts) and min(firsts) > rosbag.EPOCH_AFTER_S * 1e9
        offset_ns = min(firsts) if epoch else 0        # subtracted in ns: float seconds of 1.7e9 lose 0.2 us
        base = TimeBase(UNIX_EPOCH, offset_ns * 1e-9) if epoch else TimeBase()
        streams = [_stream(t, offset_ns) for t in bag.imu]
        ends = [(float(s.time_s.min()), float(s.time_s.max())) for s in streams if s.n]
        boot = Boot(index=0, first_record=0, start_s=min(e[0] for e in ends) if ends else np.nan,
                    end_s=max(e[1] for e in ends) if ends else np.nan, time_base=base,
                    wall_clock_offset_s=base.offset_s if epoch else None)
        facts = LogFacts(messages=bag.message_count, unreadable_records=None, truncated_bytes=0, truncation=None,
                         streams_skipped=[f"{t.topic}: every message declares angular_velocity absent "
                                          f"(covariance[0] = -1)" for t in bag.imu
                                          if len(t) and t.angular_velocity_absent == len(t)])
        streams = [s for s, t in zip(streams, bag.imu) if not (len(t) and t.angular_velocity_absent == len(t))]
        log = FlightLog(format=self, path=Path(path), gyro=streams, facts=facts, payload=bag, boots=[boot],
                        options=options)
        log.accel = self.accelerometer(log, all_topics=True) or []
        return log

    def write_filtered(self, log, path, link=None):
        filtered = {}
        for s in log.gyro:
            if s.filtered is None or s.n == 0:
                continue
            f = np.asarray(s.filtered, dtype=np.float64)
            filtered[s.message] = np.where(np.isfinite(f), f, s.raw)   # a value not filtered keeps its raw one
        path = Path(path)
        if not log.path.is_dir():
            rosbag.write_filtered(log.path, path, filtered)
        else:       # a ROS 2 bag folder names its storage file after itself: written under its final name
            with tempfile.TemporaryDirectory(prefix=".gyrodenoise-bag-", dir=path.parent) as tmp:
                done = rosbag.write_filtered(log.path, Path(tmp) / completed_path(path).name, filtered)
                os.replace(done, path)
        return {"filtered_topics": sorted(filtered)}

    def messages(self, log, name):
        t = next((t for t in log.payload.imu if t.topic == name), None)
        if t is None:
            return None
        out = {"time_s": _times_ns(t)[0] * 1e-9, "record": np.arange(len(t))}
        for k, ax in enumerate("xyz"):
            out[f"angular_velocity.{ax}"] = t.angular_velocity[:, k]
            out[f"linear_acceleration.{ax}"] = t.linear_acceleration[:, k]
        return out

    def message_names(self, log):
        return sorted(t.topic for t in log.payload.imu)

    def flight_evidence(self, log, boot, autopilot):
        return f"no flight evidence: {NO_FLIGHT}"

    def accelerometer(self, log, all_topics=False):
        """The vibration review's accelerometer (the first Imu topic with one), or with
        ``all_topics`` one :class:`~gyrodenoise.flightlog.streams.AccelStream` per topic."""
        got = []
        for t in sorted(log.payload.imu, key=lambda t: -len(t)):     # the most messages first
            if not len(t) or t.linear_acceleration_absent == len(t):
                continue
            time_s = (_times_ns(t)[0] - round(log.time_base.offset_s * 1e9)) * 1e-9
            if not all_topics:
                return {"source": f"{t.topic}.linear_acceleration", "time_s": time_s, "record": None,
                        "xyz": np.asarray(t.linear_acceleration, dtype=np.float64)}
            got.append(AccelStream(name=t.topic, message=t.topic, time_s=time_s, values=t.linear_acceleration,
                                   rate_hz=t.rate_hz, note=f"{t.msgtype}.linear_acceleration (m/s^2)"))
        return got or None

    def parameters(self, log):
        return LogParameters(UNKNOWN, {}, ["a ROS bag holds no autopilot parameters: the vehicle's filters "
                                           "are not known and no parameter change is recommended"])


def _times_ns(t):
    """(time of each message in ns, note): the header stamps, or the receive times where every
    stamp is zero."""
    if len(t) and not t.stamp_ns.any():
        return t.receive_ns, "header stamps all zero: timed by the bag's receive times"
    return t.stamp_ns, ""


def _stream(t, offset_ns):
    time_ns, note = _times_ns(t)
    return GyroStream(name=t.topic, message=t.topic, unit="rad/s", to_deg_s=RAD_TO_DEG,
                      time_s=(time_ns - offset_ns) * 1e-9,
                      raw=np.asarray(t.angular_velocity, dtype=np.float64).reshape(-1, 3),
                      index=np.arange(len(t), dtype=np.int64), note=note, field_dtype="<f8", instance=0)


FORMAT = RosBagFormat()
