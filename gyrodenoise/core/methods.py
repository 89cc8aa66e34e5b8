"""The filtering methods and their parameters, each declared once: the registry.

Every adapter reads this table instead of restating a method or a parameter:

* :func:`gyrodenoise.core.kernels.make_params` (the Python keywords, their defaults and
  their checks: :func:`check`), :class:`gyrodenoise.Denoiser` and :func:`gyrodenoise.denoise`;
* the command line (:mod:`gyrodenoise.cli.options`: the options, their spelling, help,
  metavar and type, the method each applies to, the keywords passed to the core);
* the FMUs: their parameter variables (:mod:`gyrodenoise.fmu.variables`), the pythonfmu
  slave's keywords and range checks, and the native FMUs' parameter struct, setters,
  defaults, checks and serialisation through the generated C header ``gdmethods.h``
  (:func:`c_header`; ``python -m gyrodenoise.core.methods`` rewrites it, a test holds the
  checked-in file to it);
* the method ids of the C core (``METHOD_*`` in ``gdmethods.h``, read by ``gdcore.h`` and
  the extension's constants table).

Adding a method is one :class:`Method` entry, its parameters as :class:`Param` entries
(with the slot of the core's parameter buffer each is written to), its kernel in
``kernels.py`` and ``gdcore.c``, and its tests.

This module imports nothing but the standard library: it is bundled into the pythonfmu
FMUs with the kernels.
"""

from __future__ import annotations

import math
import sys
from typing import NamedTuple


class Method(NamedTuple):
    """One filtering method."""

    name: str            #: its name in the API, on the command line and in the FMUs
    id: float            #: p[P_METHOD] (a double, compared with ==)
    help: str            #: one line: what it does
    #: its offline form (whole records): None, "zero_phase" (``zero_phase=True`` /
    #: ``--zero-phase``: forwards then backwards) or "smoother" (``offline=True``, the
    #: command line's default on files, ``--causal`` turns it off)
    offline: str | None = None
    #: False: the raw samples pass through for ``warmup_s`` after each restart (the AR methods, motion)
    #: do not apply; the output is filtered from the first sample on
    warmup: bool = True
    #: False: the output is the input (identification only)
    filters: bool = True
    #: False: no online AR(n) model is identified (no constant c, no outlier gate on its prediction)
    ar_model: bool = True


#: in the order of the command line's choices; the first is the default
METHODS: tuple[Method, ...] = (
    Method("motion", 4.0, "follows manoeuvres, averages at rest (a bank of Kalman filters)", "smoother",
           ar_model=False),
    Method("shakf", 2.0, "the paper's modified Sage-Husa adaptive KF on the online AR(n) model"),
    Method("kf", 1.0, "conventional KF on the online AR(n) model, fixed Q and R"),
    Method("sh_classic", 3.0, "classic Sage-Husa adaptive KF, Eq. (22) and (26) unmodified"),
    Method("lowpass", 5.0, "causal Butterworth low-pass (cutoff_hz, order)", "zero_phase", warmup=False,
           ar_model=False),
    Method("one_euro", 6.0, "the 1-euro filter (Casiez et al. 2012): a first-order low-pass whose cutoff "
           "rises with the rate's change (min_cutoff_hz, beta, d_cutoff_hz)", warmup=False, ar_model=False),
    Method("none", 0.0, "identification only, output = input", filters=False),
)
DEFAULT_METHOD = METHODS[0].name
BY_NAME = {m.name: m for m in METHODS}

#: offline form -> (its keyword of gd.denoise, its command-line option, the option's help)
OFFLINE_FORMS = {
    "zero_phase": ("zero_phase", "--zero-phase", "offline: filter forwards and backwards (no lag)"),
    "smoother": ("offline", "--causal", "the causal filter (as live, Denoiser.step and the FMUs run it); "
                 "default on a file: offline, the forward and backward runs blended (no lag)"),
}

#: FMI 2.0 min/max are inclusive: a bound that excludes 0 is declared as the smallest positive
#: normal double, one that excludes another value as the next double towards the inside
POSITIVE_MIN = sys.float_info.min


class Param(NamedTuple):
    """One parameter of the core's filters.

    Its range: ``lo`` / ``hi`` (None: unbounded), open (excluded) where ``lo_open`` /
    ``hi_open``; ``off``: 0 is also accepted (off / automatic); ``nyquist``: it must
    also be below half the sample rate. A value must be finite, an ``int`` parameter a
    whole number."""

    name: str                       #: keyword of make_params, Denoiser and gd.denoise
    type: type                      #: int or float
    default: float | int | None     #: None: computed from the sample rate (see help)
    help: str                       #: one line, without the method or the range
    unit: str | None = None         #: an FMI unit name (gyrodenoise.fmu.variables.UNITS) or None
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    off: bool = False
    nyquist: bool = False
    #: the methods it applies to (empty: all)
    methods: tuple[str, ...] = ()
    #: the slot p[...] of kernels.py it is written to as a float (None: make_params computes it)
    slot: str | None = None
    #: its command-line option (None: not an option) and metavar (None: argparse's)
    option: str | None = None
    metavar: str | None = None
    #: its FMU variable (None: not an FMU parameter), the FMU's start value where the
    #: default is None (0.0 standing for "computed"), the FMU's upper bound where tighter
    fmu: str | None = None
    fmu_start: float | int | None = None
    fmu_max: float | int | None = None
    #: the switch (an ``off`` parameter) this one tunes: without effect, and not reported, while it is 0
    tunes: str | None = None

    # ---------------------------------------------------------------- range
    def rule(self, sample_rate_hz: float | None = None) -> str:
        """The range as a message says it: ``0 < lam <= 1``, ``>= 0 (deg/s)^2, 0 = automatic``."""
        unit = {"deg2/s2": " (deg/s)^2", "Hz": " Hz", "s": " s", "deg/h": " deg/h"}.get(self.unit or "", "")
        if self.lo is not None and self.hi is not None:
            text = (f"{self.lo:g} {'<' if self.lo_open else '<='} {self.name} "
                    f"{'<' if self.hi_open else '<='} {self.hi:g}")
        elif self.lo is not None:
            text = f"{'>' if self.lo_open else '>='} {self.lo:g}{unit}"
        else:
            text = "finite"
        if self.nyquist:
            half = "" if sample_rate_hz is None else f", {0.5 * sample_rate_hz:g} Hz"
            text = f"{text} and below half the sample rate{half}"
        if self.off:
            text = f"0 (off) or {text}" if self.lo not in (0.0, None) or self.nyquist else f"{text}, 0 = automatic"
        return text

    def int_rule(self) -> str:
        """The range of an int parameter: ``1..8``, ``>= 1``."""
        if self.hi is not None:
            return f"{self.lo:g}..{self.hi:g}"
        return f">= {self.lo:g}"

    def error(self, value: object, sample_rate_hz: float | None = None) -> str | None:
        """None if ``value`` is in range, else the one-line reason naming the parameter."""
        if self.type is int:
            try:
                ok = int(value) == value    # type: ignore[call-overload]
            except (TypeError, ValueError, OverflowError):
                ok = False
            if not (ok and self._inside(float(value), sample_rate_hz)):   # type: ignore[arg-type]
                return f"{self.name} must be an integer {self.int_rule()}, got {value!r}"
            return None
        try:
            v = float(value)   # type: ignore[arg-type]
        except (TypeError, ValueError):
            return f"{self.name} must be a number, got {value!r}"
        if not (math.isfinite(v) and (self._inside(v, sample_rate_hz) or (self.off and v == 0.0))):
            return f"{self.name} out of range: {value!r} (must be {self.rule(sample_rate_hz)})"
        return None

    def _inside(self, v: float, sample_rate_hz: float | None) -> bool:
        if self.lo is not None and not (v > self.lo if self.lo_open else v >= self.lo):
            return False
        if self.hi is not None and not (v < self.hi if self.hi_open else v <= self.hi):
            return False
        return not (self.nyquist and sample_rate_hz is not None and not v < 0.5 * sample_rate_hz)

    def applies_to(self, method: str) -> bool:
        return not self.methods or method in self.methods

    # ---------------------------------------------------------------- the FMUs
    def fmu_bounds(self) -> tuple[float | int | None, float | int | None]:
        """(min, max) an FMU declares (inclusive), or None for unbounded."""
        lo: float | int | None = self.lo
        if self.off or (self.default is None and self.fmu_start == 0.0):
            lo = 0.0 if self.type is float else 0
        elif lo is not None and self.lo_open:
            lo = POSITIVE_MIN if lo == 0.0 else math.nextafter(lo, math.inf)
        hi: float | int | None = self.fmu_max if self.fmu_max is not None else self.hi
        if hi is not None and self.hi_open:
            hi = math.nextafter(hi, -math.inf)
        if self.type is int:
            lo = None if lo is None else int(lo)
            hi = None if hi is None else int(hi)
        return lo, hi

    def fmu_rule(self, sample_rate_hz: float | None = None) -> str:
        """The range an FMU checks (whatever the method), as its message says it."""
        if self.type is int:
            hi = self.fmu_max if self.fmu_max is not None else self.hi
            return f"{self.lo:g}..{hi:g}" if hi is not None else f">= {self.lo:g}"
        rule = self.rule(sample_rate_hz)
        return f"{rule}; 0 = the default" if self.default is None else rule

    def fmu_error(self, value: object, sample_rate_hz: float) -> str | None:
        """:meth:`error` for an FMU's value of this parameter (its own name, its tighter
        bounds, 0 standing for a computed default), None if it is in range."""
        name = self.fmu or self.name
        if self.type is int:
            hi = self.fmu_max if self.fmu_max is not None else self.hi
            if not (isinstance(value, int) and value >= self.lo and (hi is None or value <= hi)):   # type: ignore[operator]
                return f"{name} must be an integer {self.fmu_rule()}, got {value!r}"
            return None
        if self.default is None and value == 0.0:
            return None
        if self.error(value, sample_rate_hz) is None:
            return None
        return f"{name} out of range: {value!r} (must be {self.fmu_rule(sample_rate_hz)})"

    def fmu_default(self) -> float | int:
        return self.fmu_start if self.default is None else self.default   # type: ignore[return-value]


#: the largest ar_order an FMU takes (it declares phi_1 .. phi_6)
FMU_MAX_AR_ORDER = 6

#: every parameter, in the order of the command line's help; the FMUs declare theirs in this order
PARAMS: tuple[Param, ...] = (
    Param("sample_rate_hz", float, 200.0, "sample rate", "Hz", lo=0.0, lo_open=True, slot="P_FS"),
    Param("ar_order", int, 3, "order n of the improved AR(n) model, Eq. (4)", lo=1, slot="P_ORDER",
          option="--ar-order", fmu="ar_order", fmu_max=FMU_MAX_AR_ORDER),
    Param("cutoff_hz", float, None, "-3 dB cutoff (default 20 Hz, at most a quarter of the sample rate)",
          lo=0.0, lo_open=True, methods=("lowpass",), option="--cutoff-hz", metavar="HZ", fmu="cutoff_hz",
          fmu_start=0.0, nyquist=True, unit="Hz"),
    Param("order", int, 2, "Butterworth order", lo=1, hi=8, methods=("lowpass",), option="--order",
          fmu="lowpass_order"),
    Param("max_motion_hz", float, 0.0, "rigid-body option for frames that vibrate (drones): the band of "
          "interest; content above it counts as error (a 4th-order Butterworth before the filter bank, flat "
          "to it, -3 dB at twice it, -24 dB at 4 times it)", lo=0.0, lo_open=True, off=True,
          methods=("motion",), option="--max-motion-hz", metavar="HZ", fmu="max_motion_hz", nyquist=True, unit="Hz"),
    Param("min_cutoff_hz", float, 1.0, "cutoff of the low-pass at rest", "Hz", lo=0.0, lo_open=True,
          methods=("one_euro",), slot="P_OE_MIN", option="--min-cutoff-hz", metavar="HZ", fmu="min_cutoff_hz"),
    Param("beta", float, 0.001, "growth of the cutoff with |rate change|: cutoff = min_cutoff_hz + beta "
          "|d rate/dt| (s/deg)", lo=0.0, methods=("one_euro",), slot="P_OE_BETA", option="--beta",
          fmu="beta"),
    Param("d_cutoff_hz", float, 1.0, "cutoff of the low-pass on the rate's change", "Hz", lo=0.0,
          lo_open=True, methods=("one_euro",), slot="P_OE_DCUT", option="--d-cutoff-hz", metavar="HZ",
          fmu="d_cutoff_hz"),
    Param("warmup_s", float, 1.0, "seconds after each restart with raw pass-through while the AR model "
          "converges (at least 10 (ar_order + 1) samples; motion: at most until its noise floor's first "
          "128-sample block)", "s", lo=0.0, option="--warmup-s", fmu="warmup_s"),
    Param("b", float, 0.99, "Sage-Husa forgetting factor b", lo=0.0, hi=1.0, lo_open=True, hi_open=True,
          slot="P_B", option="--b", fmu="b"),
    Param("gamma", float, 3.0, "divergence criterion gamma (Eq. 32)", lo=1.0, slot="P_GAMMA", option="--gamma",
          fmu="gamma"),
    Param("lam", float, 1.0, "RLS forgetting factor", lo=0.0, hi=1.0, lo_open=True, slot="P_LAM",
          option="--lam", fmu="lam"),
    Param("q0", float, 0.0, "process-noise variance", "deg2/s2", lo=0.0, off=True, slot="P_Q0", fmu="q0"),
    Param("r0", float, 0.0, "measurement-noise variance", "deg2/s2", lo=0.0, off=True, slot="P_R0", fmu="r0"),
    Param("p0_rls", float, 1.0e4, "initial RLS covariance (diagonal)", lo=0.0, lo_open=True, slot="P_P0_RLS",
          fmu="p0_rls"),
    Param("p0_kf", float, 1.0, "initial filter covariance (diagonal)", "deg2/s2", lo=0.0, lo_open=True,
          slot="P_P0_KF", fmu="p0_kf"),
    Param("r_floor", float, 1.0e-18, "lower bound of R and of the automatic noise levels", "deg2/s2", lo=0.0,
          lo_open=True, slot="P_R_FLOOR", fmu="r_floor"),
    Param("outlier_sigma", float, 5.0, "outlier gate: after the warm-up a sample with |innovation| > K sqrt(S) "
          "is kept out of the filter and the output is the prediction (0: the paper's filter; see "
          "docs/bench/outliers-soak.md)", lo=2.0, off=True, slot="P_OUTLIER_SIGMA", option="--outlier-sigma",
          metavar="K", fmu="outlier_sigma"),
    Param("outlier_run", int, 20, "after M consecutive rejected samples the next one is taken as a real rate "
          "change and the filter restarts there", lo=1, slot="P_OUTLIER_RUN", option="--outlier-run",
          metavar="M", fmu="outlier_run"),
    Param("bias_tracking", int, 0, "bias tracking for open-loop attitude: 1 = the gyro's bias, estimated while "
          "the bank says the gyro is still and carried through motion, is removed from the output "
          "(docs/method/bias.md); 0 = off", lo=0, hi=1, off=True, methods=("motion",), slot="P_BIAS",
          option="--bias-tracking", metavar="0|1", fmu="bias_tracking"),
    Param("bias_still_s", float, 1.0, "bias tracking: the block averaged; a still run's first and last blocks "
          "are not used", "s", lo=0.0, lo_open=True, methods=("motion",), option="--bias-still-s",
          metavar="S", fmu="bias_still_s", tunes="bias_tracking"),
    Param("bias_memory_s", float, 60.0, "bias tracking: the estimate averages the still blocks of the last "
          "this many still seconds (a drifting bias)", "s", lo=0.0, lo_open=True, methods=("motion",),
          option="--bias-memory-s", metavar="S", fmu="bias_memory_s", tunes="bias_tracking"),
    Param("earth_rate_floor_deg_h", float, 15.0, "bias tracking: this much of the estimated bias (deg/h) is "
          "never removed: a still sensor measures Earth's rotation, <= 15 deg/h on any axis (0: remove it "
          "all)", "deg/h", lo=0.0, methods=("motion",), option="--earth-rate-floor-deg-h", metavar="DEG_H",
          fmu="earth_rate_floor_deg_h", tunes="bias_tracking"),
)
BY_PARAM = {p.name: p for p in PARAMS}
#: FMU variable name -> parameter
BY_FMU = {p.fmu: p for p in PARAMS if p.fmu}
#: command-line option -> parameter
BY_OPTION = {p.option: p for p in PARAMS if p.option}


def method(name: str) -> Method:
    """The method called ``name``; ValueError naming the choices otherwise."""
    if name not in BY_NAME:
        raise ValueError(f"method must be one of {sorted(BY_NAME)}, got {name!r}")
    return BY_NAME[name]


def check(name: str, value: object, sample_rate_hz: float | None = None) -> None:
    """ValueError with the one-line reason if ``value`` is out of parameter ``name``'s range."""
    why = BY_PARAM[name].error(value, sample_rate_hz)
    if why is not None:
        raise ValueError(why)


def defaults(method_name: str | None = None) -> dict[str, float | int | None]:
    """{parameter: default} of those that apply to ``method_name`` (None: all)."""
    return {p.name: p.default for p in PARAMS if method_name is None or p.applies_to(method_name)}


def fmu_parameters() -> tuple[Param, ...]:
    """The parameters an FMU declares, in their order."""
    return tuple(p for p in PARAMS if p.fmu)


def method_doc() -> str:
    """The methods in one sentence: ``'motion' (default: ...), 'shakf' (...), ...``."""
    return ", ".join(f"'{m.name}' ({'default: ' if m.name == DEFAULT_METHOD else ''}{m.help})" for m in METHODS)


# ---------------------------------------------------------------- C header
HEADER = "gdmethods.h"


def _c_double(v: float) -> str:
    r = repr(float(v))
    return r if ("." in r or "e" in r or "n" in r) else r + ".0"


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def c_header() -> str:
    """The text of ``gdmethods.h``: the methods and the FMU parameters as X-macros."""
    lines = [
        "/* gdmethods.h -- generated from gyrodenoise/core/methods.py (python -m gyrodenoise.core.methods):",
        " * do not edit; tests/core/test_methods.py holds this file to the registry.",
        " *",
        " * METHOD_<NAME>: p[P_METHOD] of each method (doubles, compared with ==);",
        " * GD_METHODS(X): X(name, id) per method, the default first;",
        " * GD_AR_MODEL(m): method m identifies the online AR(n) model; GD_AR_FILTER(m): and filters with it",
        " *   (the outlier gate applies);",
        " * GD_REAL_PARAMS(X) / GD_INT_PARAMS(X): the FMU parameters, X(name, start, slot, lo, hi, flags, rule,",
        " *   methods) with slot the p[] index it is written to (-1: computed), lo / hi its range (-HUGE_VAL /",
        " *   HUGE_VAL: none), flags GD_LO_OPEN | GD_HI_OPEN | GD_OFF | GD_NYQUIST | GD_COMPUTED, rule the",
        " *   range as the message says it (%g: half the sample rate), method the METHOD_* it applies to",
        " *   (-1.0: all). An FMU checks every parameter against its range whatever the method. */",
        "#ifndef GDMETHODS_H",
        "#define GDMETHODS_H",
        "",
    ]
    for m in METHODS:
        lines.append(f"#define METHOD_{m.name.upper()} {_c_double(m.id)}")
    lines.append(f"#define GD_N_METHODS {len(METHODS)}")
    lines.append(f"#define GD_METHOD_NAMES {_c_string(str(sorted(BY_NAME)))}")
    lines.append("#define GD_METHODS(X) \\")
    lines += [f"    X({_c_string(m.name)}, METHOD_{m.name.upper()}) \\" for m in METHODS]
    lines.append("")
    for macro, pick in (("GD_AR_MODEL", lambda m: m.ar_model), ("GD_AR_FILTER", lambda m: m.ar_model and m.filters)):
        ids = " || ".join(f"(m) == METHOD_{m.name.upper()}" for m in METHODS if pick(m))
        lines.append(f"#define {macro}(m) ({ids})")
    lines += ["", "#define GD_LO_OPEN 1", "#define GD_HI_OPEN 2", "#define GD_OFF 4", "#define GD_NYQUIST 8",
              "#define GD_COMPUTED 16   /* 0 stands for the default computed from the sample rate */"]
    for kind, typ in (("REAL", float), ("INT", int)):
        ps = [p for p in fmu_parameters() if p.type is typ]
        lines.append(f"#define GD_N_{kind}_PARAMS {len(ps)}")
        lines.append(f"#define GD_{kind}_PARAMS(X) \\")
        for p in ps:
            assert len(p.methods) <= 1, "gdmethods.h: a parameter applies to all methods or to one"
            flags = " | ".join(f for f, on in (("GD_LO_OPEN", p.lo_open), ("GD_HI_OPEN", p.hi_open),
                                                ("GD_OFF", p.off), ("GD_NYQUIST", p.nyquist),
                                                ("GD_COMPUTED", p.default is None)) if on) or "0"
            lo = "-HUGE_VAL" if p.lo is None else _c_double(p.lo)
            hi = p.fmu_max if p.fmu_max is not None else p.hi
            hi_c = "HUGE_VAL" if hi is None else _c_double(hi)
            start = _c_double(p.fmu_default()) if typ is float else str(int(p.fmu_default()))
            rule = p.fmu_rule().replace("below half the sample rate", "below half the sample rate, %g Hz")
            applies = f"METHOD_{p.methods[0].upper()}" if p.methods else "-1.0"
            lines.append(f"    X({p.fmu}, {start}, {p.slot or -1}, {lo}, {hi_c}, {flags}, {_c_string(rule)}, "
                         f"{applies}) \\")
        lines.append("")
    lines += ["#endif", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:  # pragma: no cover - the test checks the file
    """Rewrite ``gdmethods.h`` beside this module."""
    from pathlib import Path
    (Path(__file__).parent / HEADER).write_text(c_header())
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
