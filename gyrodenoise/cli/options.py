"""Options several commands share, each defined once, with the core's defaults.

* the recording options (``IN``, ``--rate-column``, ``--time-column``, ``--rate-unit``,
  ``--sample-rate``) of ``denoise``, ``allan``, ``compare`` and ``gap``;
* the filter options (``--method`` ... ``--outlier-run``) of ``denoise``, ``compare``,
  ``demo`` and ``mavlink``: their defaults are read from the signature of
  :func:`gyrodenoise.core.kernels.make_params` (and ``DEFAULT_METHOD`` / ``METHODS``),
  never restated here;
* the checks on them that the commands share: an option given with a method it does
  not apply to, and the core's own check of the values (``make_params``).

A command words an option in its own help when its context differs (the bridge filters
each stream at its own rate): :func:`add_filter_options` takes those texts.
"""

from __future__ import annotations

import argparse
import inspect

from gyrodenoise.core import kernels
from gyrodenoise.errors import InputError


def core_default(param):
    """The default of ``make_params``' parameter ``param``: the one source of the filter defaults."""
    return inspect.signature(kernels.make_params).parameters[param].default


def integer(text):
    """argparse type: an int, refused as ``not an integer: 'x'``."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None


def number(text):
    """argparse type: a float, refused as ``not a number: 'x'``."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None


# ------------------------------------------------------------------ the recording
def add_recording_options(parser, *, input_help=None, input_optional=False, rate_unit_default="deg/s"):
    """``IN`` and the options that say how to read it (:func:`gyrodenoise.io.recording.read_recording`).

    ``input_optional``: IN may be omitted (``gap --allan``); ``rate_unit_default`` None: the
    command says in a note that the unit was not given."""
    parser.add_argument("input", metavar="IN", nargs="?" if input_optional else None,
                        help=input_help or "recording CSV (columns time,rate[,true_rate]; .gz ok)")
    parser.add_argument("--rate-column", default="rate", help="rate column name (default: rate)")
    parser.add_argument("--time-column", default="time", help="time column name, s (default: time)")
    parser.add_argument("--rate-unit", default=rate_unit_default, help="deg/s (default), deg/h or rad/s")
    parser.add_argument("--sample-rate", type=float, default=None, metavar="HZ",
                        help="sample rate when there is no time column")


# ------------------------------------------------------------------ the filter
#: option -> make_params parameter, for the filter options with a value
FILTER_PARAMS = {"--method": "method", "--cutoff-hz": "cutoff_hz", "--order": "order",
                 "--max-motion-hz": "max_motion_hz", "--ar-order": "ar_order", "--warmup-s": "warmup_s",
                 "--b": "b", "--gamma": "gamma", "--lam": "lam", "--outlier-sigma": "outlier_sigma",
                 "--outlier-run": "outlier_run"}

#: the method each method-specific option applies to
METHOD_OF_OPTION = {"--cutoff-hz": "lowpass", "--order": "lowpass", "--zero-phase": "lowpass",
                    "--causal": "motion", "--max-motion-hz": "motion"}

#: make_params parameters whose value is an int (the others with a value are floats)
_INT_PARAMS = ("order", "ar_order", "outlier_run")

#: options whose default on the command line is None, "not given", whatever the core's:
#: the checks tell a given option from the default (``--max-motion-hz 0`` is given: off)
_UNSET_BY_DEFAULT = ("--cutoff-hz", "--max-motion-hz")


def _help_texts():
    """The filter options' help of ``denoise`` and ``compare``, with the core's defaults."""
    d = {p: core_default(p) for p in FILTER_PARAMS.values() if p != "method"}
    return {
        "--method": f"filter (default: {kernels.DEFAULT_METHOD}); shakf is the paper's modified Sage-Husa AKF, "
                    "lowpass a causal Butterworth (--cutoff-hz, --order)",
        "--cutoff-hz": "lowpass: -3 dB cutoff (default 20 Hz, at most a quarter of the sample rate)",
        "--order": f"lowpass: Butterworth order 1..8 (default {d['order']})",
        "--zero-phase": "lowpass, offline: filter forwards and backwards (no lag)",
        "--causal": "motion: the causal filter (as live, Denoiser.step and the FMUs run it); "
                    "default on a file: offline, the forward and backward runs blended (no lag)",
        "--max-motion-hz": "motion, rigid-body option for frames that vibrate (drones): the band of interest; "
                           "content above it counts as error (a 4th-order Butterworth before the filter bank, "
                           "flat to HZ, -3 dB at 2 HZ, -24 dB at 4 HZ); 0 < HZ < half the sample rate "
                           f"(default, {d['max_motion_hz']:g}: off)",
        "--ar-order": f"order n of the improved AR(n) model (default {d['ar_order']})",
        "--warmup-s": "seconds after each restart with raw pass-through while the AR model converges",
        "--b": f"Sage-Husa forgetting factor b, 0<b<1 (default {d['b']:g})",
        "--gamma": f"divergence criterion gamma >= 1 (Eq. 32, default {d['gamma']:g})",
        "--lam": f"RLS forgetting factor, 0<lam<=1 (default {d['lam']:g})",
        "--outlier-sigma": "outlier gate: after the warm-up a sample with |innovation| > K sqrt(S) is kept out "
                           "of the filter and the output is the prediction; 0 = off (the paper's filter); "
                           f"K >= 2 (default {d['outlier_sigma']:g}, see docs/bench/outliers-soak.md)",
        "--outlier-run": "after M consecutive rejected samples the next one is taken as a real rate change "
                         f"and the filter restarts there (default {d['outlier_run']})",
    }


#: metavar of the filter options in the help of ``denoise`` and ``compare`` (None: argparse's)
_METAVARS = {"--cutoff-hz": "HZ", "--max-motion-hz": "HZ", "--outlier-sigma": "K", "--outlier-run": "M"}

#: the filter options of ``denoise`` (in this order); ``compare`` has those from --ar-order on
FILTER_OPTIONS = ("--method", "--cutoff-hz", "--order", "--zero-phase", "--causal", "--max-motion-hz",
                  "--ar-order", "--warmup-s", "--b", "--gamma", "--lam", "--outlier-sigma", "--outlier-run")
#: the filter options that tune the AR model and the Kalman filters, those of ``compare``
MODEL_OPTIONS = FILTER_OPTIONS[FILTER_OPTIONS.index("--ar-order"):]


def add_filter_options(parser, options=FILTER_OPTIONS, *, help=None, metavar=None, strict_numbers=False,
                       unset=()):
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
    metavars = _METAVARS | (metavar or {})
    as_float, as_int = (number, integer) if strict_numbers else (float, int)
    for opt in options:
        if opt in ("--zero-phase", "--causal"):
            parser.add_argument(opt, action="store_true", help=texts[opt])
        elif opt == "--method":
            parser.add_argument(opt, default=kernels.DEFAULT_METHOD, choices=list(kernels.METHODS),
                                help=texts[opt])
        else:
            param = FILTER_PARAMS[opt]
            default = None if opt in _UNSET_BY_DEFAULT or opt in unset else core_default(param)
            parser.add_argument(opt, type=as_int if param in _INT_PARAMS else as_float, default=default,
                                metavar=metavars.get(opt), help=texts[opt])


def filter_kw(args):
    """The core filter parameters given on the command line, by ``make_params``' names
    (``method`` and ``ar_order`` apart): an option left at None is not passed (the
    core's default applies); ``--cutoff-hz`` and ``--order`` only with ``--method
    lowpass``; ``--max-motion-hz`` only with ``--method motion`` and when on (not 0)."""
    method = getattr(args, "method", None)
    kw = {}
    if method == "lowpass":
        for param in ("cutoff_hz", "order"):
            if getattr(args, param, None) is not None:
                kw[param] = getattr(args, param)
    if method == "motion" and getattr(args, "max_motion_hz", None):
        kw["max_motion_hz"] = float(args.max_motion_hz)
    for param in ("warmup_s", "b", "gamma", "lam", "outlier_sigma", "outlier_run"):
        if getattr(args, param, None) is not None:
            kw[param] = getattr(args, param)
    return kw


# ------------------------------------------------------------------ checks
def check_method_options(args, options, notes=None):
    """InputError ``--X applies to --method M only, not N`` for the first of ``options``
    given (not None, not False) with a method it does not apply to; ``notes``: option ->
    text appended to its message."""
    for opt in options:
        value = getattr(args, opt[2:].replace("-", "_"), None)
        method = METHOD_OF_OPTION[opt]
        if value is not None and value is not False and args.method != method:
            raise InputError(f"{opt} applies to --method {method} only, not {args.method}"
                             f"{(notes or {}).get(opt, '')}")


def option_named(message):
    """The core's message about a parameter (``warmup_s out of range: ...``), naming the
    command-line option first (``--warmup-s: warmup_s out of range: ...``)."""
    for opt, param in {**FILTER_PARAMS, "--sample-rate": "sample_rate_hz"}.items():
        if message.startswith(param + " "):
            return f"{opt}: {message}"
    return message


def check_core_params(*, name_options=False, **params):
    """``make_params(**params)``: the core's own checks of a filter's parameters, a
    refusal as one line (InputError), naming the option first when ``name_options``."""
    try:
        kernels.make_params(**params)
    except ValueError as exc:
        raise InputError(option_named(str(exc)) if name_options else str(exc)) from None
