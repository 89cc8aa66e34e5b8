"""Betaflight / INAV blackbox logs (``.bbl``, ``.bfl``, ``.txt``): the adapter
(:mod:`gyrodenoise.flightlog.formats`), over the decoder :mod:`gyrodenoise.flightlog.blackbox`.

Boots: each log of the file (a flash dump holds one per arming) is a boot, on the flight
controller's own time; a stream's ``index`` numbers the main frames through the file.
Gyro streams: ``gyroADC`` (deg/s, after the gyro filters: post-filter) and, where the debug
mode logs it (``GYRO_SCALED``), ``debug[0..2]``, the gyro before the filters (pre-filter;
decimated to the log rate without an anti-alias filter). Parameters: the header's ``H``
lines (the first log's). Flight evidence: the log runs armed (Betaflight logs while armed)
until a ``disarm`` event; in the air where the mean motor output, over 0.25 s, is above
:data:`AIR_MOTOR_FRACTION` of its range (``motorOutput``); throttle ``setpoint[3]``.
Accelerometer: ``accSmooth`` / ``acc_1G`` in m/s^2.

A blackbox cannot be patched (:data:`gyrodenoise.flightlog.blackbox.NOT_PATCHABLE_REASON`):
the filtered copy is a CSV beside the log (``STEM.filtered.csv``:
:func:`gyrodenoise.flightlog.blackbox.write_filtered_csv`, the file's logs one after the
other), and the report says so.

This adapter took 157 lines (this module, docstring included) and one registry line in
``FORMATS``. Around it, once: the format interface gained ``filtered_name`` (a filtered copy
in another format) and a folder scan that knows a log by its content (``.txt``); the
Betaflight strategy (autopilots.py) its filter chain and recommendations, and
betaflight_filters its stages in the review's form (about 110 lines in all).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from gyrodenoise.flightlog import overview, step_response, blackbox
from gyrodenoise.flightlog.adapters import BaseFormat
from gyrodenoise.flightlog.autopilots import BETAFLIGHT, UNKNOWN
from gyrodenoise.flightlog.model import Boot, FlightEvidence, FlightLog, LogEvent, LogFacts, LogParameters, ModeChange, Throttle
from gyrodenoise.flightlog.streams import AccelStream, GyroStream

#: in the air where the mean motor output is above this share of its range (motorOutput)
AIR_MOTOR_FRACTION = 0.15
AIR_SMOOTH_S = 0.25
G = 9.80665


class BlackboxFormat(BaseFormat):
    name = "blackbox"
    description = "a Betaflight/INAV blackbox log"
    suffixes = (".bbl", ".bfl")     # a ".txt" one (Betaflight's SD card names) is known by its content
    setpoint_looked_for = "setpoint[0..2], gyroADC[0..2]"
    gyro_looked_for = "gyroADC[0..2], debug[0..2] in debug mode GYRO_SCALED"
    flight_looked_for = "disarm events, motor[0..3] against motorOutput, setpoint[3]"
    vibration_looked_for = "accSmooth[0..2] (acc_1G)"

    def sniff(self, head):
        return blackbox.sniff(head)

    def filtered_name(self, path, stem):
        return f"{stem}.filtered.csv"

    def read(self, path, options):
        logs = blackbox.read_blackbox(path)
        starts = np.cumsum([0] + [len(b.main) for b in logs])
        skipped, parts = [], {"gyroADC": [], "debug": []}
        for b, first in zip(logs, starts):
            if not len(b.main):
                continue
            idx = first + np.arange(len(b.main))
            try:
                parts["gyroADC"].append((b.time_s, b.gyro_dps, idx))
            except Exception as exc:  # noqa: BLE001 - the decoder's InputError: one log without gyroADC
                skipped.append(f"log {b.index}: {exc}")
            if b.gyro_prefilter_dps is not None:
                parts["debug"].append((b.time_s, b.gyro_prefilter_dps, idx))
        streams = [_stream(name, got) for name, got in parts.items() if got]
        facts = LogFacts(messages=int(starts[-1]), unreadable_records=sum(b.frames_damaged for b in logs),
                         unreadable_bytes=sum(b.bytes_skipped for b in logs), truncated_bytes=0,
                         truncation=None if all(b.ended_cleanly for b in logs) else "a log without its end-of-log event",
                         streams_skipped=skipped)
        boots = [Boot(index=k, first_record=int(first), start_s=float(b.time_s[0]) if len(b.main) else np.nan,
                      end_s=float(b.time_s[-1]) if len(b.main) else np.nan)
                 for k, (b, first) in enumerate(zip(logs, starts))]
        log = FlightLog(format=self, path=Path(path), gyro=streams, facts=facts, payload=logs, boots=boots,
                        options=options)
        acc = self.accelerometer(log)
        log.accel = [] if acc is None else [AccelStream("accSmooth", "accSmooth", acc["time_s"], acc["xyz"],
                                                        rate_hz=logs[0].sample_rate_hz, note=acc["source"])]
        return log

    def write_filtered(self, log, path, link=None):
        post = next((s for s in log.gyro if s.message == "gyroADC"), None)
        filtered = None if post is None else np.full((post.n, 3), np.nan) if post.filtered is None else post.filtered
        with open(path, "w") as out, tempfile.TemporaryDirectory(prefix="gyrodenoise-bbl-") as tmp:
            header = None
            for k, b in enumerate(log.payload):
                if not len(b.main) or post is None:
                    continue
                rows = log.boot_of(post.index) == k
                one = blackbox.write_filtered_csv(b, filtered[rows], Path(tmp) / f"{k}.csv",
                                                  label="gyroADC_filtered").read_text().splitlines(keepends=True)
                out.writelines(one if one[0] != header else one[1:])
                header = one[0]
        return {"patched": False, "filtered_copy": "CSV of gyroADC and its filtered values beside the log",
                "not_patched_reason": blackbox.NOT_PATCHABLE_REASON}

    def flight_evidence(self, log, boot, autopilot):
        b = log.payload[boot]
        motors = b.motors
        if not len(b.main) or motors is None:
            return f"no flight evidence in log {b.index} (looked for {self.flight_looked_for})"
        t = b.time_s
        lo, hi = (b.header.motor_output + (0, 0))[:2]
        frac = (motors.mean(axis=1) - lo) / max(hi - lo, 1)
        width = max(1, int(round(AIR_SMOOTH_S * b.sample_rate_hz)))
        frac = np.convolve(frac, np.ones(width) / width, mode="same")
        disarm = [e.time_s for e in b.events if e.kind == "disarm" and e.time_s is not None]
        armed = t < (disarm[0] if disarm else np.inf)
        state = np.where(armed, np.where(frac > AIR_MOTOR_FRACTION, 2, 1), 0)
        thr = b.throttle
        return FlightEvidence(t, state, Throttle(t, thr, "setpoint[3]") if thr is not None else None,
                              f"armed while logging until a disarm event; in the air where the mean of motor[i], "
                              f"over {AIR_SMOOTH_S:g} s, is above {AIR_MOTOR_FRACTION:g} of motorOutput {lo}..{hi}")

    def messages(self, log, name):
        """The main frames' fields ``name[0]``, ``name[1]``... (``motor``, ``setpoint``,
        ``debug``) or the field ``name`` itself, as columns of every log of the file, with
        ``time_s`` and ``record`` (the frame's number through the file); None when absent."""
        cols, times, records, first = {}, [], [], 0
        for b in log.payload:
            n = len(b.main)
            got = b.columns(name)
            if n and got is None and name in b.fields:
                got = b.column(name)[:, None]
            if n and got is not None:
                keys = [f"{name}[{k}]" for k in range(got.shape[1])] if b.columns(name) is not None else [name]
                for k, key in enumerate(keys):
                    cols.setdefault(key, []).append(got[:, k])
                times.append(b.time_s)
                records.append(first + np.arange(n))
            first += n
        if not times:
            return None
        out = {k: np.concatenate(v) for k, v in cols.items() if len(v) == len(times)}
        out.update(time_s=np.concatenate(times), record=np.concatenate(records))
        return out

    def message_names(self, log):
        return sorted({f.split("[")[0] for b in log.payload for f in b.fields})

    def rate_setpoint(self, log):
        return step_response.blackbox_rate_setpoint(log)

    def identity(self, log):
        return overview.blackbox_identity(log)

    def accelerometer(self, log):
        rows = [(b.time_s, b.columns("accSmooth"), float(b.header.get("acc_1G") or "nan")) for b in log.payload
                if len(b.main) and b.columns("accSmooth") is not None]
        if not rows or not all(np.isfinite(g) and g > 0 for *_, g in rows):
            return None
        return {"source": "accSmooth / acc_1G", "time_s": np.concatenate([t for t, _, _ in rows]), "record": None,
                "xyz": np.concatenate([a.astype(np.float64) / g * G for _, a, g in rows])}

    def events(self, log):
        return [LogEvent(e.time_s, k, " ".join([e.kind, *map(str, e.values)]))
                for k, b in enumerate(log.payload) for e in b.events if e.time_s is not None]

    def modes(self, log):
        return [ModeChange(e.time_s, k, f"flightModeFlags {e.values[0]}") for k, b in enumerate(log.payload)
                for e in b.events if e.kind == "flight_mode" and e.time_s is not None]

    def parameters(self, log):
        header = log.payload[0].header
        if header.firmware != "Betaflight" or header.filters is None:
            return LogParameters(UNKNOWN, dict(header.lines), [f"{header.firmware_revision or header.firmware}: "
                                                               "only Betaflight's filter chain is modelled"])
        return LogParameters(BETAFLIGHT, dict(header.lines))


def _stream(name, got):
    pre = name == "debug"
    return GyroStream(name="gyro pre-filter (debug GYRO_SCALED)" if pre else "gyroADC", message=name,
                      unit="deg/s", to_deg_s=1.0, time_s=np.concatenate([t for t, _, _ in got]),
                      raw=np.concatenate([v for _, v, _ in got]).astype(np.float64),
                      index=np.concatenate([i for _, _, i in got]), field_dtype="<f8",
                      stage="pre-filter" if pre else "post-filter", instance=0,
                      note=("debug[0..2] of debug mode GYRO_SCALED: the gyro before the filters, one sample per "
                            "logged frame (no anti-alias filter)") if pre else "gyroADC: the filtered gyro")


FORMAT = BlackboxFormat()
