"""Betaflight's gyro filter chain, from a blackbox header: settings, frequency responses, ``set`` lines.

The chain, in the order Betaflight applies it to each gyro axis (``sensors/gyro.c``
``gyroFilter``): RPM notches (per motor, per harmonic), gyro lowpass 1 (static, or
dynamic: its cutoff follows the throttle), gyro lowpass 2, the two static notches,
the dynamic notches (their centres follow the FFT peak). The filters run at the
gyro loop rate, ``1e6 / looptime`` Hz.

Filter definitions (read from Betaflight's ``common/filter.c``; written here from
their equations):

* PT1: ``y += k (x - y)``, ``k = dT / (RC + dT)``, ``RC = 1 / (2 pi f_cut)``.
* PT2 / PT3: two / three PT1 stages in series with the same ``k``, computed for
  ``f_cut * c`` where ``c = 1 / sqrt(2**(1/n) - 1)`` (n = 2, 3) puts the cascade's
  -3 dB point at ``f_cut``.
* Biquad lowpass and notch: the RBJ cookbook sections, ``omega = 2 pi f dT``,
  ``alpha = sin(omega) / (2 Q)``; lowpass Q = 1/sqrt(2) (the bilinear Butterworth);
  a static notch's Q from its centre and cutoff, ``Q = fc fco / (fc**2 - fco**2)``.
  Both are the sections :mod:`gyrodenoise.flightlog.vehicle_filters` already computes
  for ArduPilot (its ``LowPassFilter2p``, its notch at full depth), reused here.
* Dynamic lowpass cutoff at throttle ``t`` in [0, 1]: with ``expo = 0``
  ``max(t (1 - t**2 / 3) 1.5 max_hz, min_hz)``; with ``expo > 0``
  ``(max - min) (t (1 - t) expo / 10 + t) + min``.
* RPM notch centre: ``clamp(h f_motor, min_hz, 0.48 fs)`` for harmonic ``h``; from
  4.3 on its weight fades from 0 at ``min_hz`` to 1 at ``min_hz + fade_range_hz``.

Header names and CLI names changed in Betaflight 4.3 (``gyro_lowpass_hz`` became
``gyro_lpf1_static_hz``, ``gyro_rpm_notch_*`` became ``rpm_filter_*``): both
generations are read, and ``set`` lines use the names of the firmware that wrote
the header. The module knows nothing of the log format: it takes the header as a
mapping of name to text.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog.vehicle_filters import ardupilot_notch_sections, ardupilot_notch_sos, lowpass2p_sos, sos_response

# Betaflight's lowpass types (``lowpassFilterType_e``): the header's *_type numbers.
LOWPASS_TYPES = ("PT1", "BIQUAD", "PT2", "PT3")
PT_ORDER = {"PT1": 1, "PT2": 2, "PT3": 3}     # PTn: n PT1 stages in series
BIQUAD_Q = 1.0 / math.sqrt(2.0)
RPM_MAX_FRACTION_OF_RATE = 0.48     # Betaflight clamps RPM notch centres below 0.48 fs


@dataclass(frozen=True)
class Setting:
    """One filter setting: its field here, its header names and CLI names (before 4.3, from 4.3)."""

    field: str
    header_old: str
    header_new: str
    cli_old: str
    cli_new: str
    index: int | None = None    # for headers that pack two numbers ("240,600")


# One row per setting: the single place where header and CLI names are known.
SETTINGS = (
    Setting("lpf1_type", "gyro_lowpass_type", "gyro_lpf1_type", "gyro_lowpass_type", "gyro_lpf1_type"),
    Setting("lpf1_static_hz", "gyro_lowpass_hz", "gyro_lpf1_static_hz", "gyro_lowpass_hz", "gyro_lpf1_static_hz"),
    Setting("lpf1_dyn_min_hz", "gyro_lowpass_dyn_hz", "gyro_lpf1_dyn_hz",
            "dyn_lpf_gyro_min_hz", "gyro_lpf1_dyn_min_hz", 0),
    Setting("lpf1_dyn_max_hz", "gyro_lowpass_dyn_hz", "gyro_lpf1_dyn_hz",
            "dyn_lpf_gyro_max_hz", "gyro_lpf1_dyn_max_hz", 1),
    Setting("lpf1_dyn_expo", "dyn_lpf_curve_expo", "gyro_lpf1_dyn_expo", "dyn_lpf_curve_expo", "gyro_lpf1_dyn_expo"),
    Setting("lpf2_type", "gyro_lowpass2_type", "gyro_lpf2_type", "gyro_lowpass2_type", "gyro_lpf2_type"),
    Setting("lpf2_static_hz", "gyro_lowpass2_hz", "gyro_lpf2_static_hz", "gyro_lowpass2_hz", "gyro_lpf2_static_hz"),
    Setting("notch1_hz", "gyro_notch_hz", "gyro_notch_hz", "gyro_notch1_hz", "gyro_notch1_hz", 0),
    Setting("notch2_hz", "gyro_notch_hz", "gyro_notch_hz", "gyro_notch2_hz", "gyro_notch2_hz", 1),
    Setting("notch1_cutoff_hz", "gyro_notch_cutoff", "gyro_notch_cutoff", "gyro_notch1_cutoff", "gyro_notch1_cutoff", 0),
    Setting("notch2_cutoff_hz", "gyro_notch_cutoff", "gyro_notch_cutoff", "gyro_notch2_cutoff", "gyro_notch2_cutoff", 1),
    Setting("dyn_notch_count", "dyn_notch_count", "dyn_notch_count", "dyn_notch_count", "dyn_notch_count"),
    Setting("dyn_notch_width_percent", "dyn_notch_width_percent", "dyn_notch_width_percent",
            "dyn_notch_width_percent", "dyn_notch_width_percent"),
    Setting("dyn_notch_q", "dyn_notch_q", "dyn_notch_q", "dyn_notch_q", "dyn_notch_q"),
    Setting("dyn_notch_min_hz", "dyn_notch_min_hz", "dyn_notch_min_hz", "dyn_notch_min_hz", "dyn_notch_min_hz"),
    Setting("dyn_notch_max_hz", "dyn_notch_max_hz", "dyn_notch_max_hz", "dyn_notch_max_hz", "dyn_notch_max_hz"),
    Setting("rpm_harmonics", "gyro_rpm_notch_harmonics", "rpm_filter_harmonics",
            "gyro_rpm_notch_harmonics", "rpm_filter_harmonics"),
    Setting("rpm_q", "gyro_rpm_notch_q", "rpm_filter_q", "gyro_rpm_notch_q", "rpm_filter_q"),
    Setting("rpm_min_hz", "gyro_rpm_notch_min", "rpm_filter_min_hz", "gyro_rpm_notch_min", "rpm_filter_min_hz"),
    Setting("rpm_fade_range_hz", "rpm_filter_fade_range_hz", "rpm_filter_fade_range_hz",
            "rpm_filter_fade_range_hz", "rpm_filter_fade_range_hz"),
)
SETTING_BY_FIELD = {s.field: s for s in SETTINGS}


@dataclass(frozen=True)
class FilterSettings:
    """Betaflight's gyro filter settings, in Betaflight's own units (Hz; Q x 100 as the CLI has it).

    A field is 0 where the filter is off or the header does not hold it (as in the
    CLI, 0 disables). ``new_names`` is True for Betaflight 4.3 and later headers.
    """

    gyro_rate_hz: float
    new_names: bool = False
    lpf1_type: int = 0
    lpf1_static_hz: int = 0
    lpf1_dyn_min_hz: int = 0
    lpf1_dyn_max_hz: int = 0
    lpf1_dyn_expo: int = 0
    lpf2_type: int = 0
    lpf2_static_hz: int = 0
    notch1_hz: int = 0
    notch2_hz: int = 0
    notch1_cutoff_hz: int = 0
    notch2_cutoff_hz: int = 0
    dyn_notch_count: int = 0
    dyn_notch_width_percent: int = 0
    dyn_notch_q: int = 0
    dyn_notch_min_hz: int = 0
    dyn_notch_max_hz: int = 0
    rpm_harmonics: int = 0
    rpm_q: int = 0
    rpm_min_hz: int = 0
    rpm_fade_range_hz: int = 0

    @classmethod
    def from_header(cls, header: Mapping[str, str], source: str = "blackbox header") -> "FilterSettings":
        """The settings from a blackbox header (name -> text, as in ``H name:value``)."""
        looptime = header.get("looptime")
        try:
            looptime_us = float(looptime)
        except (TypeError, ValueError):
            raise InputError(f"header field looptime is {looptime!r}, not a loop time in microseconds",
                             source) from None
        if not looptime_us > 0:
            raise InputError(f"header field looptime is {looptime!r}, not a positive time", source)
        new_names = "gyro_lpf1_static_hz" in header or "rpm_filter_harmonics" in header
        values: dict[str, int] = {}
        for setting in SETTINGS:
            name = setting.header_new if new_names else setting.header_old
            if name not in header:
                continue
            parts = [p.strip() for p in header[name].split(",")]
            index = setting.index or 0
            if index >= len(parts):
                raise InputError(f"header field {name} is {header[name]!r}: expected two numbers", source)
            text = parts[index]
            try:
                values[setting.field] = int(text)
            except ValueError:
                raise InputError(f"header field {name} is {header[name]!r}, not an integer", source) from None
        if "dyn_notch_count" not in values and values.get("dyn_notch_max_hz", 0) > 0:
            # before 4.3: one notch per axis, two when dyn_notch_width_percent > 0
            values["dyn_notch_count"] = 2 if values.get("dyn_notch_width_percent", 0) > 0 else 1
        # PT2 and PT3 came with 4.3's names; before, 0 and 1 (PT1, biquad) only, and 2 was a FIR in 3.x
        known = len(LOWPASS_TYPES) if new_names else 2
        for field in ("lpf1_type", "lpf2_type"):
            if not 0 <= values.get(field, 0) < known:
                setting = SETTING_BY_FIELD[field]
                raise InputError(f"header field {setting.header_new if new_names else setting.header_old} is "
                                 f"{values[field]}: lowpass types {', '.join(LOWPASS_TYPES[:known])} "
                                 f"(0-{known - 1}) are modelled for this firmware", source)
        return cls(gyro_rate_hz=1e6 / looptime_us, new_names=new_names, **values)

    @property
    def lpf1_dynamic(self) -> bool:
        return self.lpf1_dyn_min_hz > 0

    def lpf1_cutoff_hz(self, throttle: float) -> float:
        """Lowpass 1's cutoff at a throttle in [0, 1] (the static cutoff when it is not dynamic)."""
        if not self.lpf1_dynamic:
            return float(self.lpf1_static_hz)
        t = min(max(float(throttle), 0.0), 1.0)
        lo, hi = self.lpf1_dyn_min_hz, self.lpf1_dyn_max_hz
        if self.lpf1_dyn_expo > 0:
            return (hi - lo) * (t * (1 - t) * self.lpf1_dyn_expo / 10.0 + t) + lo
        return max(t * (1 - t * t / 3.0) * 1.5 * hi, lo)

    def rpm_centres_hz(self, motor_hz: float) -> list[tuple[float, float]]:
        """(centre Hz, weight) of each RPM notch for one motor turning at ``motor_hz`` revolutions/s."""
        top = RPM_MAX_FRACTION_OF_RATE * self.gyro_rate_hz
        out = []
        for harmonic in range(1, self.rpm_harmonics + 1):
            f = harmonic * float(motor_hz)
            centre = min(max(f, float(self.rpm_min_hz)), top)
            weight = 1.0
            if self.rpm_fade_range_hz > 0:
                weight = min(max((f - self.rpm_min_hz) / self.rpm_fade_range_hz, 0.0), 1.0)
            out.append((centre, weight))
        return out

    def set_lines(self, **changes: int) -> list[str]:
        """``set NAME = VALUE`` lines for the settings in ``changes`` (fields of this class), in this
        firmware's CLI names; unknown fields are an :class:`InputError`."""
        lines = []
        for field, value in changes.items():
            setting = SETTING_BY_FIELD.get(field)
            if setting is None:
                raise InputError(f"{field!r} is not a Betaflight gyro filter setting "
                                 f"(one of {', '.join(SETTING_BY_FIELD)})")
            lines.append(f"set {setting.cli_new if self.new_names else setting.cli_old} = {int(value)}")
        return lines


# --- single sections -------------------------------------------------------------------------------

def pt1_gain(cutoff_hz: float, dt: float) -> float:
    """Betaflight's PT1 gain ``k`` for a cutoff and a sample period."""
    rc = 1.0 / (2.0 * math.pi * cutoff_hz)
    return dt / (rc + dt)


def ptn_gain(order: int, cutoff_hz: float, dt: float) -> float:
    """The per-stage gain of Betaflight's PT2 / PT3 (order stages of the same PT1), -3 dB at the cutoff."""
    correction = 1.0 / math.sqrt(2.0 ** (1.0 / order) - 1.0) if order > 1 else 1.0
    return pt1_gain(cutoff_hz * correction, dt)


def pt1_section(k: float) -> tuple[float, float, float, float, float]:
    """One PT1 stage ``y[n] = y[n-1] + k (x[n] - y[n-1])`` as a biquad (b0, b1, b2, a1, a2)."""
    return (k, 0.0, 0.0, -(1.0 - k), 0.0)


def biquad_lowpass(cutoff_hz: float, fs: float) -> tuple[float, ...]:
    """Betaflight's biquad lowpass (RBJ, Q = 1/sqrt(2)): the bilinear Butterworth of
    :func:`vehicle_filters.lowpass2p_sos`, the same filter."""
    sos = lowpass2p_sos(cutoff_hz, fs)
    if sos is None:
        raise InputError(f"biquad lowpass cutoff {cutoff_hz:g} Hz is not below the Nyquist {fs / 2:g} Hz")
    return sos


def biquad_notch(centre_hz: float, q: float, fs: float) -> tuple[float, ...]:
    """Betaflight's biquad notch (RBJ, full depth): ArduPilot's notch form with A = 0."""
    sos = ardupilot_notch_sos(centre_hz, 0.0, q, fs)
    if sos is None:
        raise InputError(f"notch at {centre_hz:g} Hz (Q {q:g}) cannot run at {fs:g} Hz")
    return sos


def notch_q(centre_hz: float, cutoff_hz: float) -> float:
    """Betaflight's notch Q from a centre and a lower cutoff frequency."""
    return centre_hz * cutoff_hz / (centre_hz * centre_hz - cutoff_hz * cutoff_hz)


# --- the chain -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Stage:
    """One filter of the chain: its name, its sections (b, a), and a weight (1: fully applied)."""

    name: str
    sections: tuple[tuple[float, ...], ...]     # (b0, b1, b2, a1, a2) each
    weight: float = 1.0

    def response(self, freqs_hz: np.ndarray, fs: float) -> np.ndarray:
        return self.weight * sos_response(self.sections, freqs_hz, fs) + (1.0 - self.weight)


@dataclass(frozen=True)
class ChainResponse:
    """The response of the gyro filter chain at given frequencies (one operating point)."""

    freqs_hz: np.ndarray
    stages: tuple[Stage, ...]
    stage_responses: tuple[np.ndarray, ...]
    response: np.ndarray

    @property
    def magnitude_db(self) -> np.ndarray:
        return 20.0 * np.log10(np.maximum(np.abs(self.response), 1e-300))

    @property
    def phase_deg(self) -> np.ndarray:
        return np.degrees(np.angle(self.response))

    @property
    def delay_ms(self) -> np.ndarray:
        """Phase delay (lag) in ms: ``-unwrapped phase / (2 pi f)``; NaN at 0 Hz."""
        phase = np.unwrap(np.angle(self.response))
        f = np.asarray(self.freqs_hz, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(f > 0, -phase / (2 * np.pi * f) * 1e3, np.nan)


def _lowpass_stage(name: str, kind: int, cutoff_hz: float, fs: float) -> Stage:
    label = LOWPASS_TYPES[kind]
    if label == "BIQUAD":
        return Stage(f"{name} BIQUAD {cutoff_hz:g} Hz", (biquad_lowpass(cutoff_hz, fs),))
    order = PT_ORDER[label]
    return Stage(f"{name} {label} {cutoff_hz:g} Hz", (pt1_section(ptn_gain(order, cutoff_hz, 1.0 / fs)),) * order)


def chain_stages(settings: FilterSettings, throttle: float = 0.5, motor_hz: tuple[float, ...] = (),
                 dyn_notch_hz: tuple[float, ...] = ()) -> tuple[Stage, ...]:
    """The filters of the chain at one operating point.

    ``throttle`` in [0, 1] places the dynamic lowpass; ``motor_hz`` (one value per
    motor, revolutions per second) the RPM notches; ``dyn_notch_hz`` the dynamic
    notches' centres (Betaflight moves them to the spectrum's peaks; each is clamped
    into [dyn_notch_min_hz, dyn_notch_max_hz]; at most ``dyn_notch_count`` of them).
    """
    fs = settings.gyro_rate_hz
    stages: list[Stage] = []
    if settings.rpm_harmonics > 0 and settings.rpm_q > 0:
        for m, f_motor in enumerate(motor_hz):
            for h, (centre, weight) in enumerate(settings.rpm_centres_hz(f_motor), start=1):
                sec = biquad_notch(centre, settings.rpm_q / 100.0, fs)
                stages.append(Stage(f"RPM motor {m + 1} harmonic {h} {centre:.1f} Hz", (sec,), weight))
    cutoff1 = settings.lpf1_cutoff_hz(throttle)
    if cutoff1 > 0:
        stages.append(_lowpass_stage("gyro lowpass 1" + (" (dynamic)" if settings.lpf1_dynamic else ""),
                                     settings.lpf1_type, cutoff1, fs))
    if settings.lpf2_static_hz > 0:
        stages.append(_lowpass_stage("gyro lowpass 2", settings.lpf2_type, settings.lpf2_static_hz, fs))
    for label, centre, cutoff in (("notch 1", settings.notch1_hz, settings.notch1_cutoff_hz),
                                  ("notch 2", settings.notch2_hz, settings.notch2_cutoff_hz)):
        if centre > 0 and 0 < cutoff < centre:
            stages.append(Stage(f"static {label} {centre} Hz",
                                (biquad_notch(centre, notch_q(centre, cutoff), fs),)))
    if settings.dyn_notch_count > 0 and settings.dyn_notch_q > 0 and settings.dyn_notch_max_hz > 0:
        for i, centre in enumerate(dyn_notch_hz[:settings.dyn_notch_count]):
            c = min(max(float(centre), settings.dyn_notch_min_hz), settings.dyn_notch_max_hz)
            stages.append(Stage(f"dynamic notch {i + 1} {c:.1f} Hz",
                                (biquad_notch(c, settings.dyn_notch_q / 100.0, fs),)))
    return tuple(stages)


def chain_response(settings: FilterSettings, freqs_hz, throttle: float = 0.5, motor_hz: tuple[float, ...] = (),
                   dyn_notch_hz: tuple[float, ...] = ()) -> ChainResponse:
    """Magnitude and phase of the whole chain (see :func:`chain_stages` for the operating point)."""
    freqs = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    if np.any(freqs < 0) or np.any(freqs > settings.gyro_rate_hz / 2):
        raise InputError(f"frequencies must lie in [0, {settings.gyro_rate_hz / 2:g}] Hz (the gyro Nyquist)")
    stages = chain_stages(settings, throttle, motor_hz, dyn_notch_hz)
    responses = tuple(st.response(freqs, settings.gyro_rate_hz) for st in stages)
    total = np.ones(len(freqs), dtype=complex)
    for r in responses:
        total = total * r
    return ChainResponse(freqs, stages, responses, total)


# --- recommendations -------------------------------------------------------------------------------

@dataclass(frozen=True)
class Recommendation:
    """Changed settings, why, and the ``set`` lines that apply them."""

    settings: FilterSettings
    reasons: tuple[str, ...]
    lines: tuple[str, ...]


def recommend(settings: FilterSettings, noise_peak_hz: float | None = None,
              motor_hz_range: tuple[float, float] | None = None, rpm_available: bool = False,
              noise_band_hz: tuple[float, float] | None = None) -> Recommendation:
    """Setting changes from measured evidence, each with its reason.

    Rules: a dominant pre-filter noise peak outside the dynamic notch range widens
    the range to hold it (with a 10 % margin); a dominant broad band (``noise_band_hz``,
    lo..hi: the motor noise) is the RPM filter's where it is on -- Betaflight's own
    RPM-filter setups say "motor noise will already be eliminated by the rpm filter"
    and point the dynamic notch at "narrow frame resonances"
    (https://github.com/betaflight/bidircfg, each target's ``.cf``; the 4.3 tuning notes,
    https://betaflight.com/docs/wiki/tuning/4-3-tuning-notes, recommend RPM filtering):
    no change while the band lies above the RPM notch minimum, else the minimum lowered
    to the band's bottom; with the RPM filter off the dynamic notch range widens to hold
    the whole band (10 % margin); an RPM filter that is off while bidirectional DShot is
    on (``rpm_available``) is turned on with 3 harmonics; an RPM minimum above the
    lowest motor frequency seen is lowered to it. No evidence, no change.
    """
    changes: dict[str, int] = {}
    reasons: list[str] = []
    if noise_band_hz is not None:
        _band_rule(settings, noise_band_hz, changes, reasons)
    elif noise_peak_hz is not None and settings.dyn_notch_max_hz > 0:
        if noise_peak_hz > settings.dyn_notch_max_hz:
            changes["dyn_notch_max_hz"] = int(math.ceil(noise_peak_hz * 1.1))
            reasons.append(f"noise peak {noise_peak_hz:.0f} Hz above dyn_notch_max_hz {settings.dyn_notch_max_hz}")
        elif noise_peak_hz < settings.dyn_notch_min_hz:
            changes["dyn_notch_min_hz"] = max(int(math.floor(noise_peak_hz * 0.9)), 1)
            reasons.append(f"noise peak {noise_peak_hz:.0f} Hz below dyn_notch_min_hz {settings.dyn_notch_min_hz}")
    if rpm_available and settings.rpm_harmonics == 0:
        changes["rpm_harmonics"] = 3
        reasons.append("bidirectional DShot is on but the RPM filter is off")
    if motor_hz_range is not None and settings.rpm_harmonics > 0 and settings.rpm_min_hz > motor_hz_range[0] > 0:
        changes["rpm_min_hz"] = int(math.floor(motor_hz_range[0]))
        reasons.append(f"motors turn at {motor_hz_range[0]:.0f} Hz, below the RPM notch minimum {settings.rpm_min_hz}")
    return Recommendation(dataclasses.replace(settings, **changes), tuple(reasons),
                          tuple(settings.set_lines(**changes)))


def _band_rule(settings: FilterSettings, band_hz: tuple[float, float], changes: dict, reasons: list) -> None:
    """:func:`recommend`'s rule for a broad noise band (the motor band) ``band_hz`` (lo, hi)."""
    lo, hi = float(band_hz[0]), float(band_hz[1])
    if settings.rpm_harmonics > 0:
        if lo >= settings.rpm_min_hz:
            reasons.append(f"noise band {lo:.0f}-{hi:.0f} Hz: the RPM filter ({settings.rpm_harmonics} harmonics, "
                           f"from {settings.rpm_min_hz} Hz) follows the motors there")
        else:
            changes["rpm_min_hz"] = max(int(math.floor(lo)), 1)
            reasons.append(f"noise band {lo:.0f}-{hi:.0f} Hz reaches below the RPM notch minimum "
                           f"{settings.rpm_min_hz}")
        return
    if settings.dyn_notch_max_hz <= 0:
        return
    if hi > settings.dyn_notch_max_hz:
        changes["dyn_notch_max_hz"] = int(math.ceil(round(hi * 1.1, 6)))   # 380 x 1.1 is 418.00000000000006
        reasons.append(f"noise band {lo:.0f}-{hi:.0f} Hz reaches above dyn_notch_max_hz {settings.dyn_notch_max_hz}")
    if lo < settings.dyn_notch_min_hz:
        changes["dyn_notch_min_hz"] = max(int(math.floor(lo * 0.9)), 1)
        reasons.append(f"noise band {lo:.0f}-{hi:.0f} Hz reaches below dyn_notch_min_hz {settings.dyn_notch_min_hz}")


# --- the flight review's stages --------------------------------------------------------------------

#: the chain's stage names (:func:`chain_stages`) -> (the review's kind, the settings that set it)
REVIEW_STAGES = (("gyro lowpass 1 (dynamic)", "lowpass", ("lpf1_dyn_min_hz", "lpf1_dyn_max_hz")),
                 ("gyro lowpass 1", "lowpass", ("lpf1_static_hz",)), ("gyro lowpass 2", "lowpass", ("lpf2_static_hz",)),
                 ("static notch 1", "notch", ("notch1_hz", "notch1_cutoff_hz")),
                 ("static notch 2", "notch", ("notch2_hz", "notch2_cutoff_hz")))


def cli_name(settings: FilterSettings, field: str) -> str:
    """The CLI name of setting ``field`` in the firmware that wrote ``settings``."""
    s = SETTING_BY_FIELD[field]
    return s.cli_new if settings.new_names else s.cli_old


def review_stages(settings: FilterSettings, throttle: float = 0.5) -> list[dict]:
    """The chain as the flight review's stages (:mod:`gyrodenoise.flightlog.vehicle_filters`):
    the low-passes (the dynamic one at ``throttle``) and static notches with their biquads
    (``sections``, run at ``rate_hz``); the RPM filter and the dynamic notches, whose centres
    follow the motors and the gyro spectrum, as ``dynamic_notch`` stages (not modelled)."""
    out = []
    for st in chain_stages(settings, throttle):
        name, kind, fields = next(r for r in REVIEW_STAGES if st.name.startswith(r[0]))
        out.append({"kind": kind, "path": "rate", "params": ", ".join(cli_name(settings, f) for f in fields),
                    "name": st.name, "sections": [list(x) for x in st.sections], "rate_hz": settings.gyro_rate_hz})
        if kind == "lowpass":
            lpf1 = name.startswith("gyro lowpass 1")
            out[-1]["cutoff_hz"] = round(settings.lpf1_cutoff_hz(throttle) if lpf1 else float(settings.lpf2_static_hz), 3)
        if name.endswith("(dynamic)"):
            out[-1]["note"] = f"dynamic: its cutoff follows the throttle, here at throttle {throttle:g}"
    if settings.rpm_harmonics > 0:
        out.append({"kind": "dynamic_notch", "path": "rate", "params": cli_name(settings, "rpm_harmonics"),
                    "sources": ["motor RPM"], "harmonics": settings.rpm_harmonics})
    if settings.dyn_notch_count > 0 and settings.dyn_notch_max_hz > 0:
        out.append({"kind": "dynamic_notch", "path": "rate", "params": "dyn_notch_*", "sources": ["gyro FFT"],
                    "range_hz": [settings.dyn_notch_min_hz, settings.dyn_notch_max_hz]})
    return out


def changed_settings(before: FilterSettings, rec: Recommendation) -> dict[str, int]:
    """{CLI name: value} of the settings ``rec`` changes (the names its ``set`` lines use)."""
    return {cli_name(before, f): getattr(rec.settings, f) for f in SETTING_BY_FIELD
            if getattr(rec.settings, f) != getattr(before, f)}


# --- replay along the flight -----------------------------------------------------------------------

def _lowpass_sections(kind: int, cutoff_hz: np.ndarray, fs: float) -> np.ndarray:
    """(n, order, 5) of a Betaflight low-pass of type ``kind`` at a cutoff per sample."""
    c = np.clip(np.asarray(cutoff_hz, dtype=float), 1e-3, 0.499 * fs)
    label = LOWPASS_TYPES[kind]
    if label == "BIQUAD":                      # lowpass2p_sos, one row per sample
        ohm = np.tan(np.pi * c / fs)
        d = 1.0 + math.sqrt(2.0) * ohm + ohm * ohm
        b0 = ohm * ohm / d
        return np.stack([b0, 2 * b0, b0, 2 * (ohm * ohm - 1) / d, (1 - math.sqrt(2.0) * ohm + ohm * ohm) / d], -1)[:, None]
    order = PT_ORDER[label]
    corr = 1.0 / math.sqrt(2.0 ** (1.0 / order) - 1.0) if order > 1 else 1.0
    dt = 1.0 / fs
    k = dt / (1.0 / (2.0 * np.pi * c * corr) + dt)
    z = np.zeros_like(k)
    one = np.stack([k, z, z, -(1.0 - k), z], -1)[:, None]
    return np.repeat(one, order, axis=1)


def replay_sections(settings: FilterSettings, tracks: Mapping, time_s, fs: float):
    """((n, k, 5) biquads per sample, notes) of Betaflight's gyro chain along the flight,
    designed at ``fs`` (the replayed stream's rate; the firmware runs it at the gyro rate).
    ``tracks``: ``"throttle"`` (0..1) moves the dynamic low-pass 1, ``"motor_hz"`` (rev/s
    per motor) the RPM notches; without them the low-pass sits at throttle 0.5 and the RPM
    notches are left out, with a note. The dynamic notches follow Betaflight's own FFT,
    which the log does not hold: left out, with a note."""
    t = np.asarray(time_s, dtype=float)
    n = len(t)
    parts, notes = [], []
    if not math.isclose(fs, settings.gyro_rate_hz, rel_tol=0.02):
        notes.append(f"designed at the logged rate {fs:g} Hz; Betaflight runs the chain at the gyro rate "
                     f"{settings.gyro_rate_hz:g} Hz")
        if fs < 0.5 * settings.gyro_rate_hz:
            notes.append(f"both gyros are logged every {settings.gyro_rate_hz / fs:.0f}th loop, point samples: "
                         f"what lies above {fs / 2:g} Hz (motor noise) folds into the logged pre-filter gyro, "
                         "where the vehicle's filters had taken it out of the post-filter one before logging; "
                         "the replay cannot take out what is folded: its excess over the logged gyro bounds "
                         "the agreement")
        top = max(settings.lpf1_dyn_max_hz if settings.lpf1_dynamic else settings.lpf1_static_hz,
                  settings.lpf2_static_hz)
        if top >= 0.5 * fs:
            notes.append(f"low-pass cutoffs up to {top} Hz lie above the logged Nyquist frequency ({fs / 2:g} Hz): "
                         f"held at {0.499 * fs:.1f} Hz in the replay")
    if settings.rpm_harmonics > 0 and settings.rpm_q > 0:
        tr = tracks.get("motor_hz")
        if tr is None:
            notes.append("RPM filter: the log holds no motor eRPM: left out")
        else:
            v = tr.at(t)
            v = v if v.ndim == 2 else v[:, None]
            top = RPM_MAX_FRACTION_OF_RATE * fs
            for h in range(1, settings.rpm_harmonics + 1):
                for j in range(v.shape[1]):
                    c = np.clip(h * v[:, j], float(settings.rpm_min_hz), top)
                    parts.append(ardupilot_notch_sections(c, 0.0, settings.rpm_q / 100.0, fs)[:, None, :])
    if settings.lpf1_dynamic or settings.lpf1_static_hz > 0:
        thr = tracks.get("throttle")
        if settings.lpf1_dynamic and thr is None:
            notes.append("dynamic low-pass 1: no throttle in the log, held at throttle 0.5")
        th = thr.at(t) if thr is not None else np.full(n, 0.5)
        cut = np.array([settings.lpf1_cutoff_hz(float(x)) for x in th]) if settings.lpf1_dynamic else \
            np.full(n, float(settings.lpf1_static_hz))
        parts.append(_lowpass_sections(settings.lpf1_type, cut, fs))
    if settings.lpf2_static_hz > 0:
        parts.append(_lowpass_sections(settings.lpf2_type, np.full(n, float(settings.lpf2_static_hz)), fs))
    for centre, cutoff in ((settings.notch1_hz, settings.notch1_cutoff_hz), (settings.notch2_hz, settings.notch2_cutoff_hz)):
        if centre > 0 and 0 < cutoff < centre and centre < 0.5 * fs:
            parts.append(ardupilot_notch_sections(np.full(n, float(centre)), 0.0, notch_q(centre, cutoff), fs)[:, None])
    if settings.dyn_notch_max_hz > 0 and settings.dyn_notch_q > 0:
        notes.append(f"dynamic notch ({settings.dyn_notch_min_hz}-{settings.dyn_notch_max_hz} Hz): its centres "
                     "come from Betaflight's own FFT, not logged: left out")
    if not parts:
        return np.zeros((n, 0, 5)), notes
    return np.concatenate(parts, axis=1), notes
