"""Betaflight / Cleanflight / INAV blackbox logs (``.bbl``, ``.bfl``, ``.txt``): decoder and CSV writer.

Written from the blackbox format's description (Betaflight's ``blackbox.c`` and
``blackbox_fielddefs.h``, the blackbox-log-viewer's parser): a file holds one or
more logs, each an ASCII header of ``H name:value`` lines and then binary frames,
each opened by a type byte: ``I`` (intra: absolute values), ``P`` (inter: values
predicted from the previous one or two main frames), ``S`` (slow: flight modes),
``G``/``H`` (GPS and its home), ``E`` (events). Each field has a predictor and an
encoding (variable-byte integers, zig-zag signed, and tagged groups of 3, 4 or 8
values packed in 2-32 bits).

No maintained, permissively licensed Python decoder was found (``orangebox`` is
GPL-3.0, and its 0.5.0 wheel does not install with a current pip), hence this one.

A damaged frame (its next byte is not a frame type, or its loop iteration or time
jumps) is dropped and counted, and decoding resumes at the next frame marker; P
frames after it are dropped until the next I frame, as the log viewer does.

A filtered copy of a blackbox log cannot be written by patching the gyro values
in place: P frames store each gyro value as a variable-length difference from the
one before, so a new value changes the frame's length and every later prediction.
:func:`write_filtered_csv` writes the filtered streams beside the log instead.
"""

from __future__ import annotations

import csv
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog.betaflight_filters import FilterSettings

LOG_START_MARKER = b"H Product:Blackbox flight data recorder by Nicholas Sherlock\n"
PATCHABLE = False
NOT_PATCHABLE_REASON = ("blackbox P frames store each gyro value as a variable-length difference from the "
                        "previous frames: a new value changes the frame's length and all later predictions, "
                        "so the filtered streams are written beside the log (CSV) instead")

MAX_FRAME_BYTES = 256
MAX_ITERATION_JUMP = 500 * 10
MAX_TIME_JUMP_US = 10 * 1000 * 1000

# encodings (FLIGHT_LOG_FIELD_ENCODING_*)
ENC_SIGNED_VB, ENC_UNSIGNED_VB, ENC_NEG_14BIT = 0, 1, 3
ENC_TAG8_8SVB, ENC_TAG2_3S32, ENC_TAG8_4S16, ENC_NULL, ENC_TAG2_3SVARIABLE = 6, 7, 8, 9, 10
KNOWN_ENCODINGS = {ENC_SIGNED_VB, ENC_UNSIGNED_VB, ENC_NEG_14BIT, ENC_TAG8_8SVB, ENC_TAG2_3S32,
                   ENC_TAG8_4S16, ENC_NULL}
# predictors (FLIGHT_LOG_FIELD_PREDICTOR_*)
PRED_ZERO, PRED_PREVIOUS, PRED_STRAIGHT_LINE, PRED_AVERAGE_2, PRED_MINTHROTTLE = 0, 1, 2, 3, 4
PRED_MOTOR_0, PRED_INC, PRED_HOME_COORD, PRED_1500, PRED_VBATREF = 5, 6, 7, 8, 9
PRED_LAST_MAIN_FRAME_TIME, PRED_MINMOTOR = 10, 11
KNOWN_PREDICTORS = set(range(12))
PREDICTOR_HEADER_VALUES = {PRED_MINTHROTTLE: "minthrottle", PRED_VBATREF: "vbatref", PRED_MINMOTOR: "motorOutput"}

# event types (FLIGHT_LOG_EVENT_*) with their payload readers, below
EVENT_NAMES = {0: "sync_beep", 13: "inflight_adjustment", 14: "logging_resume", 15: "disarm",
               30: "flight_mode", 255: "log_end"}

KNOWN_FIRMWARE = ("Betaflight", "INAV", "EmuFlight", "Rotorflight", "Butterflight", "Cleanflight", "Baseflight")

# Betaflight debug modes whose debug[0..2] hold the unfiltered gyro in deg/s (``DEBUG_GYRO_SCALED``).
PREFILTER_DEBUG_MODES = {6: "GYRO_SCALED"}


@dataclass(frozen=True)
class FieldDef:
    name: str
    signed: bool
    predictor: int
    encoding: int


@dataclass(frozen=True)
class BlackboxHeader:
    """The header of one log: every ``H`` line, and the fields the decoder and the review use."""

    lines: tuple[tuple[str, str], ...]
    firmware_type: str
    firmware_revision: str
    firmware_date: str
    board: str
    craft_name: str
    log_start: str
    data_version: int
    looptime_us: int | None             # None in logs that do not say (Cleanflight 2016)
    gyro_sync_denom: int
    pid_process_denom: int
    i_interval: int
    p_interval_num: int
    p_interval_denom: int
    debug_mode: int
    gyro_scale: float
    minthrottle: int
    vbatref: int
    motor_output: tuple[int, ...]
    defaults_used: tuple[str, ...]      # header values a predictor needs that the header lacks (0 used)
    filters: FilterSettings | None      # Betaflight's gyro filters; None for other firmware (not modelled)
    #                                     and without a looptime

    def get(self, name: str, default: str | None = None) -> str | None:
        for key, value in self.lines:
            if key == name:
                return value
        return default

    @property
    def firmware(self) -> str:
        """Betaflight, INAV, ...: the revision's first word where it names one (Betaflight 4 writes
        firmware type Cleanflight), else the firmware type."""
        first = (self.firmware_revision.split() or [""])[0]
        return first if first in KNOWN_FIRMWARE else self.firmware_type

    @property
    def log_rate_hz(self) -> float:
        """Nominal main frames per second: the PID rate divided by the P interval (NaN without a
        looptime). A loop that overruns logs slower: :attr:`BlackboxLog.sample_rate_hz` is measured."""
        if self.looptime_us is None:
            return float("nan")
        pid_rate = 1e6 / (self.looptime_us * self.pid_process_denom)
        return pid_rate * self.p_interval_num / self.p_interval_denom


@dataclass(frozen=True)
class BlackboxEvent:
    time_s: float | None    # the event's own time where it holds one, else the last main frame's
    kind: str
    values: tuple[int | float, ...]


@dataclass
class BlackboxLog:
    """One decoded log. Main-frame columns are ``main[:, fields.index(name)]``; ``time_s`` is the
    flight controller's boot time. Gyro values are deg/s."""

    path: str
    index: int                      # 1-based position of the log in its file
    header: BlackboxHeader
    fields: tuple[str, ...]
    main: np.ndarray                # (n, len(fields)) int64
    slow_fields: tuple[str, ...]
    slow: np.ndarray                # (m, len(slow_fields)) int64
    slow_main_index: np.ndarray     # index of the main frame each slow frame follows
    gps_fields: tuple[str, ...]
    gps: np.ndarray
    events: list[BlackboxEvent]
    frames_damaged: int = 0         # frames dropped as corrupt (and P frames dropped after them)
    bytes_skipped: int = 0
    ended_cleanly: bool = False     # an "End of log" event closed it

    def column(self, name: str) -> np.ndarray:
        try:
            return self.main[:, self.fields.index(name)]
        except ValueError:
            raise InputError(f"log {self.index} has no field {name!r}", self.path) from None

    def columns(self, prefix: str) -> np.ndarray | None:
        """The fields ``prefix[0]``, ``prefix[1]``, ... as an (n, k) array; None when absent."""
        idx = []
        while f"{prefix}[{len(idx)}]" in self.fields:
            idx.append(self.fields.index(f"{prefix}[{len(idx)}]"))
        return self.main[:, idx] if idx else None

    @property
    def time_s(self) -> np.ndarray:
        return self.column("time").astype(float) * 1e-6

    @property
    def gyro_dps(self) -> np.ndarray:
        """gyroADC: the filtered gyro the PID loop uses, deg/s, (n, 3)."""
        return self._scaled(self.columns("gyroADC"), "gyroADC")

    @property
    def gyro_prefilter_source(self) -> str | None:
        """Which debug mode holds the unfiltered gyro in debug[0..2]; None when this log has none."""
        debug = self.columns("debug")
        if self.header.firmware != "Betaflight" or debug is None or debug.shape[1] < 3:
            return None
        return PREFILTER_DEBUG_MODES.get(self.header.debug_mode)

    @property
    def gyro_prefilter_dps(self) -> np.ndarray | None:
        """The unfiltered gyro (deg/s, (n, 3)) where the debug mode logs it, else None.

        Betaflight sets it in the gyro loop and the blackbox keeps one sample in each P
        interval: it is decimated without an anti-alias filter (noise above half the
        log rate folds down), unlike gyroADC, which passed the lowpasses first."""
        if self.gyro_prefilter_source is None:
            return None
        return self.columns("debug")[:, :3].astype(float)

    @property
    def rc_command(self) -> np.ndarray | None:
        return self.columns("rcCommand")

    @property
    def setpoint(self) -> np.ndarray | None:
        return self.columns("setpoint")

    @property
    def motors(self) -> np.ndarray | None:
        return self.columns("motor")

    @property
    def throttle(self) -> np.ndarray | None:
        """Throttle in [0, 1]: Betaflight 4.x logs it as setpoint[3], 0-1000; None without it."""
        sp = self.setpoint
        if sp is None or sp.shape[1] < 4 or self.header.firmware != "Betaflight":
            return None
        return np.clip(sp[:, 3] / 1000.0, 0.0, 1.0)

    @property
    def sample_rate_hz(self) -> float:
        t = self.column("time")
        return 1e6 / float(np.median(np.diff(t))) if len(t) > 1 else float("nan")

    def _scaled(self, raw: np.ndarray | None, name: str) -> np.ndarray:
        if raw is None or raw.shape[1] != 3:
            found = 0 if raw is None else raw.shape[1]
            raise InputError(f"log {self.index} has {found} {name}[i] fields, 3 expected", self.path)
        return raw.astype(float) * self.header.gyro_scale


# --- header ----------------------------------------------------------------------------------------

def _int(lines: dict[str, str], name: str, default: int | None, source: str) -> int:
    text = lines.get(name)
    if text is None:
        if default is None:
            raise InputError(f"header has no {name} line", source)
        return default
    try:
        return int(text.split(",")[0].strip(), 0)
    except ValueError:
        raise InputError(f"header field {name} is {text!r}, not an integer", source) from None


def _ints(name: str, text: str, source: str) -> tuple[int, ...]:
    try:
        return tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise InputError(f"header field {name} is {text!r}, not integers", source) from None


def _table(rows: list[list[int]], width: int) -> np.ndarray:
    return np.array(rows, dtype=np.int64).reshape(len(rows), width)


def _field_defs(lines: dict[str, str], frame: str, source: str, inherit_from: str | None = None) -> list[FieldDef]:
    names_text = lines.get(f"Field {frame} name")
    if names_text is None:
        return []
    names = names_text.split(",")
    base = inherit_from or frame

    def numbers(key: str, from_frame: str) -> list[int]:
        text = lines.get(f"Field {from_frame} {key}")
        if text is None:
            if key == "signed":
                return [0] * len(names)
            raise InputError(f"header has no 'Field {from_frame} {key}' line", source)
        try:
            vals = [int(v) for v in text.split(",")]
        except ValueError:
            raise InputError(f"header field 'Field {from_frame} {key}' is not a list of integers", source) from None
        if len(vals) != len(names):
            raise InputError(f"header 'Field {from_frame} {key}' has {len(vals)} values for {len(names)} fields",
                             source)
        return vals

    signed = numbers("signed", base)
    predictor = numbers("predictor", frame)
    encoding = numbers("encoding", frame)
    for name, p, e in zip(names, predictor, encoding):
        if p not in KNOWN_PREDICTORS:
            raise InputError(f"field {name} of {frame} frames has predictor {p}, which this decoder does not know",
                             source)
        if e not in KNOWN_ENCODINGS:
            raise InputError(f"field {name} of {frame} frames has encoding {e}, which this decoder does not know",
                             source)
    return [FieldDef(n, bool(s), p, e) for n, s, p, e in zip(names, signed, predictor, encoding)]


def _parse_header(text: bytes, source: str) -> tuple[BlackboxHeader, dict[str, list[FieldDef]]]:
    pairs: list[tuple[str, str]] = []
    for raw in text.split(b"\n"):
        if not raw.startswith(b"H "):
            continue
        line = raw[2:].decode("latin-1")
        name, sep, value = line.partition(":")
        if sep:
            pairs.append((name, value))
    lines = dict(pairs)
    frames = {"I": _field_defs(lines, "I", source)}
    if not frames["I"]:
        raise InputError("header has no 'Field I name' line: not a blackbox log", source)
    p_pred, p_enc = lines.get("Field P predictor"), lines.get("Field P encoding")
    if p_pred is None or p_enc is None:
        raise InputError("header has no 'Field P predictor/encoding' lines", source)
    i_names = lines["Field I name"]
    lines_p = dict(lines, **{"Field P name": i_names})
    frames["P"] = _field_defs(lines_p, "P", source, inherit_from="I")
    for frame in ("S", "G", "H"):
        frames[frame] = _field_defs(lines, frame, source)

    p_text = lines.get("P interval", "1")
    p_parts = _ints("P interval", p_text.replace("/", ","), source)
    p_num, p_den = (1, p_parts[0]) if len(p_parts) == 1 else p_parts[:2]
    if p_num <= 0 or p_den <= 0:
        raise InputError(f"header field P interval is {p_text!r}", source)
    motor_output = _ints("motorOutput", lines.get("motorOutput", "0"), source)
    scale_text = lines.get("gyro_scale", lines.get("gyro.scale", "0x3f800000"))
    try:
        gyro_scale = struct.unpack("<f", struct.pack("<I", int(scale_text, 16)))[0]
    except (ValueError, struct.error):
        raise InputError(f"header field gyro_scale is {scale_text!r}, not a hexadecimal float", source) from None
    revision = lines.get("Firmware revision", "")
    looptime = _int(lines, "looptime", -1, source) if "looptime" in lines else None
    if looptime is not None and looptime <= 0:
        raise InputError(f"header field looptime is {lines['looptime']!r}, not a positive time", source)
    betaflight = (revision.split() or [""])[0] == "Betaflight"
    if lines.get("Firmware type", "").lower() == "baseflight":
        gyro_scale = gyro_scale * 1e6 * 180.0 / np.pi      # Baseflight's scale gives rad/us
    data_version = _int(lines, "Data version", 2, source)
    if data_version != 2 and any(f.encoding == ENC_TAG8_4S16 for f in frames["P"]):
        raise InputError(f"data version {data_version}: only version 2 of the TAG8_4S16 encoding is decoded", source)
    header = BlackboxHeader(
        lines=tuple(pairs),
        firmware_type=lines.get("Firmware type", ""),
        firmware_revision=revision,
        firmware_date=lines.get("Firmware date", ""),
        board=lines.get("Board information", ""),
        craft_name=lines.get("Craft name", ""),
        log_start=lines.get("Log start datetime", ""),
        data_version=data_version,
        looptime_us=looptime,
        gyro_sync_denom=_int(lines, "gyro_sync_denom", 1, source),
        pid_process_denom=_int(lines, "pid_process_denom", 1, source),
        i_interval=max(_int(lines, "I interval", 32, source), 1),
        p_interval_num=p_num,
        p_interval_denom=p_den,
        debug_mode=_int(lines, "debug_mode", 0, source),
        gyro_scale=float(gyro_scale),
        minthrottle=_int(lines, "minthrottle", 0, source),
        vbatref=_int(lines, "vbatref", 0, source),
        motor_output=motor_output or (0,),
        defaults_used=tuple(name for pred, name in PREDICTOR_HEADER_VALUES.items()
                            if name not in lines and any(d.predictor == pred for d in frames["I"] + frames["P"])),
        filters=FilterSettings.from_header(lines, source) if betaflight and looptime else None,
    )
    return header, frames


# --- value decoding --------------------------------------------------------------------------------

class _Truncated(Exception):
    """The data ended inside a frame."""


class _Reader:
    __slots__ = ("data", "pos", "end")

    def __init__(self, data: bytes, pos: int, end: int):
        self.data, self.pos, self.end = data, pos, end

    def byte(self) -> int:
        if self.pos >= self.end:
            raise _Truncated
        b = self.data[self.pos]
        self.pos += 1
        return b

    def uvb(self) -> int:
        result, shift = 0, 0
        for _ in range(5):
            b = self.byte()
            result |= (b & 0x7F) << shift
            if b < 0x80:
                return result
            shift += 7
        return 0        # over-long: the viewer gives 0 and the frame check catches it

    def svb(self) -> int:
        u = self.uvb()
        return (u >> 1) ^ -(u & 1)


def _sx(value: int, bits: int) -> int:
    sign = 1 << (bits - 1)
    return (value & (sign - 1)) - (value & sign)


def _tag2_3s32(r: _Reader) -> list[int]:
    lead = r.byte()
    sel = lead >> 6
    if sel == 0:
        return [_sx((lead >> 4) & 3, 2), _sx((lead >> 2) & 3, 2), _sx(lead & 3, 2)]
    if sel == 1:
        b = r.byte()
        return [_sx(lead & 0x0F, 4), _sx(b >> 4, 4), _sx(b & 0x0F, 4)]
    if sel == 2:
        b1, b2 = r.byte(), r.byte()
        return [_sx(lead & 0x3F, 6), _sx(b1 & 0x3F, 6), _sx(b2 & 0x3F, 6)]
    out = []
    for _ in range(3):
        size = lead & 3
        if size == 0:
            out.append(_sx(r.byte(), 8))
        elif size == 1:
            b1, b2 = r.byte(), r.byte()
            out.append(_sx(b1 | (b2 << 8), 16))
        elif size == 2:
            b1, b2, b3 = r.byte(), r.byte(), r.byte()
            out.append(_sx(b1 | (b2 << 8) | (b3 << 16), 24))
        else:
            b1, b2, b3, b4 = r.byte(), r.byte(), r.byte(), r.byte()
            out.append(_sx(b1 | (b2 << 8) | (b3 << 16) | (b4 << 24), 32))
        lead >>= 2
    return out


def _tag8_4s16(r: _Reader) -> list[int]:
    selector = r.byte()
    out = []
    nibble_pending, buffer = False, 0
    for _ in range(4):
        width = selector & 3
        if width == 0:
            out.append(0)
        elif width == 1:
            if not nibble_pending:
                buffer = r.byte()
                out.append(_sx(buffer >> 4, 4))
                nibble_pending = True
            else:
                out.append(_sx(buffer & 0x0F, 4))
                nibble_pending = False
        elif width == 2:
            if not nibble_pending:
                out.append(_sx(r.byte(), 8))
            else:
                high = (buffer & 0x0F) << 4
                buffer = r.byte()
                out.append(_sx(high | (buffer >> 4), 8))
        else:
            if not nibble_pending:
                b1, b2 = r.byte(), r.byte()
                out.append(_sx((b1 << 8) | b2, 16))
            else:
                b1, b2 = r.byte(), r.byte()
                out.append(_sx(((buffer & 0x0F) << 12) | (b1 << 4) | (b2 >> 4), 16))
                buffer = b2
        selector >>= 2
    return out


def _tag8_8svb(r: _Reader, count: int) -> list[int]:
    if count == 1:
        return [r.svb()]
    header = r.byte()
    out = []
    for _ in range(count):
        out.append(r.svb() if header & 1 else 0)
        header >>= 1
    return out


def _read_raw(r: _Reader, defs: list[FieldDef]) -> list[int]:
    """The encoded values of one frame, before prediction."""
    out: list[int] = []
    n = len(defs)
    i = 0
    while i < n:
        enc = defs[i].encoding
        if enc == ENC_SIGNED_VB:
            out.append(r.svb())
            i += 1
        elif enc == ENC_UNSIGNED_VB:
            out.append(r.uvb())
            i += 1
        elif enc == ENC_NEG_14BIT:
            out.append(-_sx(r.uvb(), 14))
            i += 1
        elif enc == ENC_NULL:
            out.append(0)
            i += 1
        elif enc == ENC_TAG8_4S16:
            out.extend(_tag8_4s16(r))
            i += 4
        elif enc == ENC_TAG2_3S32:
            out.extend(_tag2_3s32(r))
            i += 3
        else:   # ENC_TAG8_8SVB: up to 8 consecutive fields with this encoding
            count = 1
            while count < 8 and i + count < n and defs[i + count].encoding == ENC_TAG8_8SVB:
                count += 1
            out.extend(_tag8_8svb(r, count))
            i += count
    return out[:n]


# --- frames ----------------------------------------------------------------------------------------

FRAME_TYPES = b"IPSGHE"


@dataclass
class _State:
    header: BlackboxHeader
    defs: dict[str, list[FieldDef]]
    prev: list[int] | None = None
    prev2: list[int] | None = None
    last_iteration: int = -1
    last_time: int = 0
    gps_home: list[int] = field(default_factory=lambda: [0, 0])
    gps_prev: list[int] | None = None
    slow_prev: list[int] | None = None


def _should_have_frame(header: BlackboxHeader, index: int) -> bool:
    return (index % header.i_interval + header.p_interval_num - 1) % header.p_interval_denom < header.p_interval_num


def _skipped(header: BlackboxHeader, last_iteration: int) -> int:
    count, idx = 0, last_iteration + 1
    while not _should_have_frame(header, idx) and count < MAX_ITERATION_JUMP:
        count += 1
        idx += 1
    return count


def _predict_inter(st: _State, defs: list[FieldDef], raw: list[int]) -> list[int]:
    h = st.header
    values = [0] * len(defs)
    prev, prev2 = st.prev, st.prev2
    for i, (d, v) in enumerate(zip(defs, raw)):
        p = d.predictor
        if p == PRED_ZERO:
            pass
        elif p == PRED_PREVIOUS:
            v += prev[i]
        elif p == PRED_STRAIGHT_LINE:
            v += 2 * prev[i] - prev2[i]
        elif p == PRED_AVERAGE_2:
            s = prev[i] + prev2[i]
            v += s // 2 if s >= 0 else -((-s) // 2)
        elif p == PRED_MINTHROTTLE:
            v += h.minthrottle
        elif p == PRED_INC:
            v += prev[i] + _skipped(h, st.last_iteration) + 1
        elif p == PRED_1500:
            v += 1500
        elif p == PRED_VBATREF:
            v += h.vbatref
        elif p == PRED_MINMOTOR:
            v += h.motor_output[0]
        else:
            raise ValueError(f"predictor {p} in a P frame")
        values[i] = v
    return values


def _read_event(r: _Reader) -> tuple[str, tuple]:
    kind = r.byte()
    if kind == 0:
        return "sync_beep", (r.uvb(),)
    if kind == 13:
        func = r.byte()
        if func & 128:
            b = bytes(r.byte() for _ in range(4))
            return "inflight_adjustment", (func & 127, struct.unpack("<f", b)[0])
        return "inflight_adjustment", (func, r.svb())
    if kind == 14:
        return "logging_resume", (r.uvb(), r.uvb())
    if kind == 15:
        return "disarm", (r.uvb(),)
    if kind == 30:
        return "flight_mode", (r.uvb(), r.uvb())
    if kind == 255:
        text = bytes(r.byte() for _ in range(11))
        if text != b"End of log\x00":
            raise ValueError("bad end-of-log event")
        return "log_end", ()
    raise ValueError(f"unknown event type {kind}")


def _decode_log(data: bytes, start: int, end: int, index: int, path: str) -> BlackboxLog:
    # the header is the run of lines starting "H "
    pos = start
    while pos < end and data.startswith(b"H ", pos):
        nl = data.find(b"\n", pos, end)
        if nl < 0:
            break
        pos = nl + 1
    header, defs = _parse_header(data[start:pos], f"{path} (log {index})")
    i_defs, p_defs = defs["I"], defs["P"]
    names = tuple(d.name for d in i_defs)
    if "time" not in names or "loopIteration" not in names:
        raise InputError(f"log {index}: I frames have no loopIteration/time fields", path)
    it_idx, time_idx = names.index("loopIteration"), names.index("time")
    motor0 = names.index("motor[0]") if "motor[0]" in names else None
    st = _State(header, defs)
    main_rows: list[list[int]] = []
    slow_rows: list[list[int]] = []
    slow_at: list[int] = []
    gps_rows: list[list[int]] = []
    events: list[BlackboxEvent] = []
    damaged = skipped_bytes = 0
    ended = False
    r = _Reader(data, pos, end)
    while r.pos < end:
        frame_start = r.pos
        ftype = data[frame_start]
        if ftype not in FRAME_TYPES:
            # not a frame marker: skip to the next one
            r.pos += 1
            skipped_bytes += 1
            continue
        r.pos += 1
        kind = chr(ftype)
        try:
            if kind == "E":
                name, values = _read_event(r)
                ok = _frame_end_ok(data, r.pos, end)
                if ok:
                    time_s = values[1] * 1e-6 if name == "logging_resume" else st.last_time * 1e-6
                    events.append(BlackboxEvent(time_s, name, tuple(values)))
                    if name == "logging_resume":
                        st.last_iteration, st.last_time = values[0], values[1]
                        st.prev = st.prev2 = None
                    if name == "log_end":
                        ended = True
                        break
            elif kind in "IP":
                fdefs = i_defs if kind == "I" else p_defs
                raw = _read_raw(r, fdefs)
                ok = _frame_end_ok(data, r.pos, end) and r.pos - frame_start <= MAX_FRAME_BYTES
                if kind == "P" and st.prev is None:
                    ok = False      # no valid I frame to predict from: dropped until the next one
                if ok and kind == "I":
                    values = _predict_intra(st, fdefs, raw, motor0)
                    if st.last_iteration >= 0 and st.prev is not None and not (
                            st.last_iteration <= values[it_idx] < st.last_iteration + MAX_ITERATION_JUMP
                            and st.last_time <= values[time_idx] < st.last_time + MAX_TIME_JUMP_US):
                        ok = False
                elif ok:
                    values = _predict_inter(st, fdefs, raw)
                if ok:
                    st.prev2 = st.prev if kind == "P" else values
                    st.prev = values
                    st.last_iteration, st.last_time = values[it_idx], values[time_idx]
                    main_rows.append(values)
                else:
                    st.prev = st.prev2 = None
            elif kind == "S":
                raw = _read_raw(r, defs["S"])
                ok = _frame_end_ok(data, r.pos, end)
                if ok:
                    slow_rows.append(raw)
                    slow_at.append(len(main_rows) - 1)
            elif kind == "H":
                raw = _read_raw(r, defs["H"])
                ok = _frame_end_ok(data, r.pos, end)
                if ok:
                    st.gps_home = (raw + [0, 0])[:2]
            else:   # G
                raw = _read_raw(r, defs["G"])
                ok = _frame_end_ok(data, r.pos, end)
                if ok:
                    gps_rows.append(_predict_gps(st, defs["G"], raw))
        except (_Truncated, ValueError, IndexError):
            ok = False
        if not ok:
            damaged += 1
            if kind in "IP":
                st.prev = st.prev2 = None
            r.pos = frame_start + 1
    main = _wrap(_table(main_rows, len(names)), i_defs)
    slow_names = tuple(d.name for d in defs["S"])
    gps_names = tuple(d.name for d in defs["G"])
    return BlackboxLog(
        path=path, index=index, header=header, fields=names, main=main,
        slow_fields=slow_names, slow=_table(slow_rows, len(slow_names)),
        slow_main_index=np.array(slow_at, dtype=np.int64),
        gps_fields=gps_names, gps=_table(gps_rows, len(gps_names)),
        events=events, frames_damaged=damaged, bytes_skipped=skipped_bytes, ended_cleanly=ended)


def _predict_intra(st: _State, defs: list[FieldDef], raw: list[int], motor0: int | None) -> list[int]:
    h = st.header
    values = list(raw)
    for i, d in enumerate(defs):
        p = d.predictor
        if p == PRED_MINTHROTTLE:
            values[i] += h.minthrottle
        elif p == PRED_1500:
            values[i] += 1500
        elif p == PRED_VBATREF:
            values[i] += h.vbatref
        elif p == PRED_MINMOTOR:
            values[i] += h.motor_output[0]
        elif p == PRED_MOTOR_0:
            if motor0 is None or motor0 >= i:
                raise ValueError("MOTOR_0 predictor without an earlier motor[0]")
            values[i] += values[motor0]
        elif p != PRED_ZERO:
            raise ValueError(f"predictor {p} in an I frame")
    return values


def _predict_gps(st: _State, defs: list[FieldDef], raw: list[int]) -> list[int]:
    values = list(raw)
    coord = 0
    for i, d in enumerate(defs):
        if d.predictor == PRED_HOME_COORD:
            values[i] += st.gps_home[coord % 2]
            coord += 1
        elif d.predictor == PRED_LAST_MAIN_FRAME_TIME:
            values[i] += st.last_time
        elif d.predictor == PRED_PREVIOUS and st.gps_prev is not None:
            values[i] += st.gps_prev[i]
    st.gps_prev = values
    return values


def _frame_end_ok(data: bytes, pos: int, end: int) -> bool:
    """A frame is accepted only if the next byte opens a frame (or the log ends), as the viewer checks."""
    return pos >= end or data[pos] in FRAME_TYPES or data.startswith(b"H ", pos)


def _wrap(main: np.ndarray, defs: list[FieldDef]) -> np.ndarray:
    """Values as the firmware's 32-bit fields hold them (signed or unsigned)."""
    for j, d in enumerate(defs):
        col = main[:, j] & 0xFFFFFFFF
        main[:, j] = np.where(d.signed & (col >= 2 ** 31), col - 2 ** 32, col)
    return main


# --- files -----------------------------------------------------------------------------------------

def sniff(head: bytes) -> bool:
    """True when the bytes (a file's first kilobytes) hold a blackbox log's first header line;
    a dump from flash may have bytes before it."""
    return b"H Product:Blackbox flight data recorder" in head


def read_blackbox(path: str | os.PathLike) -> list[BlackboxLog]:
    """Every log in a blackbox file, in order; a log with no main frame is kept (empty arrays)."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", str(p)) from None
    starts = []
    at = data.find(LOG_START_MARKER)
    while at >= 0:
        starts.append(at)
        at = data.find(LOG_START_MARKER, at + 1)
    if not starts:
        raise InputError("no blackbox log in this file (no 'H Product:Blackbox flight data recorder' line)",
                         str(p))
    bounds = list(zip(starts, starts[1:] + [len(data)]))
    return [_decode_log(data, s, e, i + 1, str(p)) for i, (s, e) in enumerate(bounds)]


def write_filtered_csv(log: BlackboxLog, filtered_dps: np.ndarray, out_path: str | os.PathLike,
                       label: str = "filtered") -> Path:
    """The log's time, gyroADC and (where logged) pre-filter gyro, and the filtered gyro, as one CSV.

    Columns: ``time_s, gyroADC_x..z`` (deg/s), ``gyro_prefilter_x..z`` when the debug
    mode holds it, ``{label}_x..z`` (deg/s). ``filtered_dps`` must have one row per
    main frame.
    """
    filtered = np.asarray(filtered_dps, dtype=float)
    n = len(log.main)
    if filtered.shape != (n, 3):
        raise InputError(f"filtered gyro has shape {filtered.shape}, the log has {n} frames x 3 axes", log.path)
    cols = [("time_s", log.time_s), *((f"gyroADC_{a}", log.gyro_dps[:, k]) for k, a in enumerate("xyz"))]
    pre = log.gyro_prefilter_dps
    if pre is not None:
        cols += [(f"gyro_prefilter_{a}", pre[:, k]) for k, a in enumerate("xyz")]
    cols += [(f"{label}_{a}", filtered[:, k]) for k, a in enumerate("xyz")]
    out = Path(out_path)
    with out.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([c for c, _ in cols])
        for row in zip(*(v for _, v in cols)):
            w.writerow([f"{x:.9g}" for x in row])
    return out
