"""Options several commands share, each defined once, with the core's defaults.

* the recording options (``IN``, ``--rate-column``, ``--time-column``, ``--rate-unit``,
  ``--rate-scale``, ``--skip-rows``, ``--sample-rate``) of ``denoise``, ``allan``, ``compare`` and ``gap``;
* the filter options (``--method`` ... ``--outlier-run``) of ``denoise``, ``compare``,
  ``demo`` and ``mavlink``: their spelling, type, help, range, default and the method
  each applies to are read from the registry (:mod:`gyrodenoise.core.methods`), never
  restated here;
* the checks on them that the commands share: an option given with a method it does
  not apply to, and the core's own check of the values (``make_params``).

A command words an option in its own help when its context differs (the bridge filters
each stream at its own rate): :func:`add_filter_options` takes those texts.
"""

from __future__ import annotations

import argparse
from typing import Any

from gyrodenoise.core import kernels, methods
from gyrodenoise.errors import InputError


def core_default(param: str) -> float | int | None:
    """The default of ``make_params``' parameter ``param``: the registry's (gyrodenoise.core.methods)."""
    return methods.BY_PARAM[param].default


def integer(text: str) -> int:
    """argparse type: an int, refused as ``not an integer: 'x'``."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None


def number(text: str) -> float:
    """argparse type: a float, refused as ``not a number: 'x'``."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None


def numbers(text: str) -> tuple[float, ...]:
    """argparse type: comma-separated floats, refused as ``not a number: 'x'``."""
    return tuple(number(c) for c in text.split(",") if c.strip()) or (number(text),)


# ------------------------------------------------------------------ the recording
#: the units ``--time-unit`` takes (gyrodenoise.io.timebase.time_unit reads them)
TIME_UNITS = ("s", "ms", "us", "ns")


def add_recording_options(parser: argparse.ArgumentParser, *, input_help: str | None = None,
                          input_optional: bool = False, rate_unit_default: str | None = None,
                          axes: bool = False, several_columns: str = "") -> None:
    """``IN`` and the options that say how to read it (:func:`gyrodenoise.io.recording.read_recording`).

    ``input_optional``: IN may be omitted (``gap --allan``); ``rate_unit_default`` None: the
    reader says in a note which unit it assumed. ``axes``: several columns in one run
    (:func:`gyrodenoise.io.recording.read_axes`): ``--rate-column`` takes a list and is detected
    when not given, ``--accel-column``, ``--accel-unit`` and ``--accel-scale`` are added. ``several_columns``: the
    help's words on several rate columns in the single-axis form (what the command does with them)."""
    parser.add_argument("input", metavar="IN", nargs="?" if input_optional else None,
                        help=input_help or "recording CSV (columns time,rate[,true_rate]; .gz ok)")
    if axes:
        parser.add_argument("--rate-column", default=None, metavar="NAME[,NAME...]",
                            help="gyro column(s), comma-separated (default: rate, else the gyro columns detected: "
                                 "gyro_x/y/z, gx/gy/gz, field.angular_velocity.x/y/z ..., with the accelerometer "
                                 "columns beside them)")
        parser.add_argument("--accel-column", default=None, metavar="NAME[,NAME...]",
                            help="accelerometer column(s), comma-separated (default: detected beside detected "
                                 "gyro columns: accel_x/y/z, ax/ay/az, field.linear_acceleration.x/y/z ...)")
        parser.add_argument("--accel-unit", default=None, help="m/s^2 (default), g or mg")
        parser.add_argument("--accel-scale", type=numbers, default=None, metavar="K[,K...]",
                            help="multiply each accelerometer value by this first (raw counts: the unit per "
                                 "count, e.g. 6.1035e-05 g per LSB for an MPU-6050 at +-2 g, with --accel-unit g); "
                                 "one factor for every accelerometer column or one per column; said in a note "
                                 "and in --json")
        parser.add_argument("--topic", default=None, metavar="NAME",
                            help="ROS bag / MCAP: the sensor_msgs/Imu topic (default: the only one)")
        parser.add_argument("--variable", default=None, metavar="NAME",
                            help="MATLAB .mat: the variable (a struct or a matrix) to read (default: all)")
    else:
        parser.add_argument("--rate-column", default="rate",
                            help=f"rate column name (default: rate){several_columns}")
    parser.add_argument("--time-column", default=None,
                        help="time column name (default: the first of time, field.header.stamp, %%time, timestamp, "
                             "t in the file)")
    parser.add_argument("--time-unit", default=None, choices=TIME_UNITS,
                        help="unit of the time column (default: detected from its values, said in a note; "
                             "an epoch in any of them is detected)")
    parser.add_argument("--rate-unit", default=rate_unit_default, help="deg/s (default, said in a note), deg/h, rad/s or mrad/s (ROS "
                        "sensor_msgs/Imu columns: rad/s)")
    parser.add_argument("--rate-scale", type=numbers, default=None, metavar="K[,K...]",
                        help="multiply each rate by this first (raw counts: the unit per count, e.g. 0.00763 "
                             "for deg/s per LSB; the product is in --rate-unit); one factor for every rate column "
                             "or one per column; said in a note and in --json")
    parser.add_argument("--skip-rows", type=integer, default=0, metavar="N",
                        help="skip the first N lines before looking for the header row (free text the automatic "
                             "preamble detection refuses, e.g. before a header row that holds a number); "
                             "said in a note")
    parser.add_argument("--sample-rate", type=float, default=None, metavar="HZ",
                        help="sample rate: the rate when there is no time column; with one, used when within "
                             "2%% of the column's own (samples over span), an error further off")


# ------------------------------------------------------------------ the filter
#: option -> make_params parameter, for the filter options with a value (the registry's)
FILTER_PARAMS = {"--method": "method", **{opt: p.name for opt, p in methods.BY_OPTION.items()}}

#: the method each method-specific option applies to: the parameters of one method, and the
#: options of the methods' offline forms
METHOD_OF_OPTION = {**{opt: p.methods[0] for opt, p in methods.BY_OPTION.items() if len(p.methods) == 1},
                    **{methods.OFFLINE_FORMS[m.offline][1]: m.name for m in methods.METHODS if m.offline}}

#: the options of one method (in the order of the help), refused with another
METHOD_OPTIONS = tuple(METHOD_OF_OPTION)


def _offline_option(opt):
    """The method whose offline form ``opt`` (``--zero-phase``, ``--causal``) switches, or None."""
    return next((m for m in methods.METHODS if m.offline and methods.OFFLINE_FORMS[m.offline][1] == opt), None)


def _default_text(p):
    if p.default is None:
        return ""
    if p.off and p.default == 0:
        return " (default 0: off)"
    return f" (default {p.default:g})"


def _help_texts():
    """The filter options' help of ``denoise`` and ``compare``: the registry's text, the
    method it applies to, the range and the core's default."""
    texts = {"--method": f"filter (default: {kernels.DEFAULT_METHOD}): "
                         + "; ".join(f"{m.name}: {m.help}" for m in methods.METHODS)}
    for opt, p in methods.BY_OPTION.items():
        where = f"{p.methods[0]}: " if p.methods else ""
        rng = p.int_rule() if p.type is int else p.rule()
        texts[opt] = f"{where}{p.help}; {rng}{_default_text(p)}".replace("%", "%%")
    for m in methods.METHODS:
        if m.offline:
            _, opt, text = methods.OFFLINE_FORMS[m.offline]
            texts[opt] = f"{m.name}: {text}"
    return texts


#: the filter options of ``denoise`` (in this order); ``compare`` has those from --ar-order on
FILTER_OPTIONS = ("--method", *METHOD_OPTIONS,
                  *(opt for opt, p in methods.BY_OPTION.items() if not p.methods))
#: the filter options that tune the AR model and the Kalman filters, those of ``compare``
MODEL_OPTIONS = FILTER_OPTIONS[FILTER_OPTIONS.index("--ar-order"):]


def add_filter_options(parser: argparse.ArgumentParser, options=FILTER_OPTIONS, *, help: dict | None = None,
                       metavar: dict | None = None, strict_numbers: bool = False, unset=()) -> None:
    """Add the filter ``options`` to ``parser``, each with the core's default.

    help, metavar : dict, optional
        option -> the command's own wording / metavar, where it differs from ``denoise``'s.
    strict_numbers : bool
        values read by :func:`number` / :func:`integer` ("not a number: 'x'") instead of
        argparse's float / int ("invalid float value: 'x'").
    unset : iterable of str
        options whose default is None ("not given": the command resolves the core's
        default itself, e.g. per stream).
    """
    texts = _help_texts() | (help or {})
    metavars = {opt: p.metavar for opt, p in methods.BY_OPTION.items()} | (metavar or {})
    as_float, as_int = (number, integer) if strict_numbers else (float, int)
    for opt in options:
        if _offline_option(opt) is not None:
            parser.add_argument(opt, action="store_true", help=texts[opt])
        elif opt == "--method":
            parser.add_argument(opt, default=kernels.DEFAULT_METHOD, choices=list(kernels.METHODS),
                                help=texts[opt])
        else:
            p = methods.BY_OPTION[opt]
            # a method's own option is "not given" by default: the checks tell it from the default
            default = None if p.methods or p.default is None or opt in unset else p.default
            parser.add_argument(opt, type=as_int if p.type is int else as_float, default=default,
                                metavar=metavars.get(opt), help=texts[opt])


def filter_kw(args: argparse.Namespace) -> dict[str, Any]:
    """The core filter parameters given on the command line, by ``make_params``' names
    (``method`` and ``ar_order`` apart): an option left at None is not passed (the
    core's default applies), nor a method's own option with another method, nor an
    option that is off (0, the default of ``--max-motion-hz``). InputError for a method's
    own option given with another method (:func:`check_method_options`)."""
    method = getattr(args, "method", None)
    if method is not None:      # a method's own option given with another method: refused, not dropped
        check_method_options(args, [o for o, p in methods.BY_OPTION.items() if p.methods and hasattr(args, p.name)])
    kw = {}
    for opt, p in methods.BY_OPTION.items():
        value = getattr(args, p.name, None)
        if p.name == "ar_order" or value is None or (p.methods and method not in p.methods):
            continue
        if p.off and p.methods and not value:
            continue
        kw[p.name] = float(value) if p.type is float and p.methods else value
    return kw


# ------------------------------------------------------------------ checks
def check_method_options(args: argparse.Namespace, options, notes: dict[str, str] | None = None) -> None:
    """InputError ``--X applies to --method M only, not N`` for the first of ``options``
    given (not None, not False) with a method it does not apply to; ``notes``: option ->
    text appended to its message."""
    for opt in options:
        value = getattr(args, opt[2:].replace("-", "_"), None)
        method = METHOD_OF_OPTION[opt]
        if value is not None and value is not False and args.method != method:
            raise InputError(f"{opt} applies to --method {method} only, not {args.method}"
                             f"{(notes or {}).get(opt, '')}")


def option_named(message: str) -> str:
    """The core's message about a parameter (``warmup_s out of range: ...``), naming the
    command-line option first (``--warmup-s: warmup_s out of range: ...``)."""
    for opt, param in {**FILTER_PARAMS, "--sample-rate": "sample_rate_hz"}.items():
        if message.startswith(param + " "):
            return f"{opt}: {message}"
    return message


def check_core_params(*, name_options: bool = False, **params) -> None:
    """``make_params(**params)``: the core's own checks of a filter's parameters, a
    refusal as one line (InputError), naming the option first when ``name_options``."""
    try:
        kernels.make_params(**params)
    except ValueError as exc:
        raise InputError(option_named(str(exc)) if name_options else str(exc)) from None
