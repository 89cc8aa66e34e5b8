"""The gyro streams of a log through the filter: restarts found, each axis
denoised on its own, the output checked, and why a stream is left unfiltered.
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.analysis import motion_metrics as mm
from gyrodenoise.core.methods import BY_NAME, PARAMS
from gyrodenoise.core.sessions import sessions
from gyrodenoise.errors import InputError
from gyrodenoise.flightlog.checks import check_filtered, usable_samples
from gyrodenoise.flightlog.streams import detect_restarts, kept_restarts


def filter_streams(streams, engine, gap_factor, sample_rate=None):
    """Restarts, then each axis of each stream through its own denoiser. A non-finite
    sample (NaN/inf in a float field) is a dropout: it is fed to the filter, which heals
    it as ``gd.denoise`` does (the filter restarts at that sample and passes it through,
    so the output there is the raw NaN/inf, then warms up again): the output of every
    sample is the library's on the same samples. Dropouts are counted in
    ``dropouts_healed``. A corrupted record (finite but beyond
    :data:`gyrodenoise.flightlog.checks.ABSURD_WORK`) is not fed to the filter: it is kept
    as it is in the output. Both count in ``non_finite`` (left out of the noise figures).

    Then the safety net (:func:`gyrodenoise.flightlog.checks.check_filtered`): a stream
    whose filtered output is not finite, leaves the raw range of a session, or does
    not fit the log's field type is written RAW (``s.left_raw`` says why).

    A stream sampled too slowly to denoise
    (:func:`gyrodenoise.analysis.motion_metrics.too_slow_to_denoise`) is not filtered: it
    goes out raw, bit for bit. A stream the filter never changed gets the reason
    in ``s.not_filtered`` (:func:`not_filtered_reason`).

    Each stream gets ``filtered`` (field units) and ``_work``: (raw, filtered, unit,
    filter rate) in the unit the filter works in."""
    for s in streams:
        detect_restarts(s, gap_factor)
        rate = sample_rate or s.rate_hz or 1.0
        x, back, unit = s.work_units()
        s.non_finite = [0] * x.shape[1]
        s.dropouts_healed = [0] * x.shape[1]
        s.not_filtered = None
        s.warmup_samples = engine.warmup_samples(rate)
        s.cutoff_hz = engine.cutoff_hz(rate) if hasattr(engine, "cutoff_hz") else None
        s._work = (x, x.copy(), unit, rate)
        if not _accepts(s, engine, rate):
            continue
        usable = usable_samples(x)
        f, bias = _filter_axes(s, engine, x, usable, rate)
        f = _apply_safety_net(s, engine, x, f, bias, back, usable, rate, sample_rate)
        s._work = (x, f, unit, rate)


def _accepts(s, engine, rate):
    """Whether stream ``s`` goes through the filter; if not, it is set to go out raw,
    bit for bit (too slow to denoise, or a rate the filter refuses)."""
    if mm.too_slow_to_denoise(s.rate_hz):
        s.filtered = s.raw.astype(np.float64)
        s.left_raw = None
        return False
    try:
        engine.check_rate(rate)
    except ValueError as exc:               # e.g. --cutoff-hz not below this stream's Nyquist
        s.filtered = s.raw.astype(np.float64)
        s.not_filtered = f"the filter cannot run at {rate:g} Hz: {exc}; written raw"
        s.rate_refused = rate
        s.refused_option = refused_band_option(exc, getattr(engine, "filter_kw", None))
        # a band option this stream cannot take (a slow stream of a multi-rate log): not
        # filtered, with the reason, like a stream too slow to denoise; exit status 0.
        # Every stream refusing it: the log is refused (check_some_stream_filterable)
        s.left_raw = None
        return False
    return True


#: the band options (Hz) checked against each stream's rate: core parameter -> CLI option.
#: One rule for both: below half the stream's rate (its Nyquist frequency)
BAND_OPTIONS = {p.name: p.option for p in PARAMS if p.nyquist and p.option}


def refused_band_option(exc: Exception, filter_kw: dict | None) -> tuple[str, float] | None:
    """(CLI option, value) of the band option the core's ``exc`` (ValueError of a
    rate check) refused, or None when it was something else."""
    for param, option in BAND_OPTIONS.items():
        value = (filter_kw or {}).get(param)
        if value is not None and str(exc).startswith(f"{param} "):
            return option, float(value)
    return None


def _filter_axes(s, engine, x, usable, rate):
    """The filtered work values of each axis, and the bias that bias tracking removed after
    each sample (None when it is off; 0 where nothing was fed). The dropouts (non-finite
    samples) are fed to the filter with the readings and healed there as the library heals
    them; the corrupted records stay as they are, left out of the filter (a restart on one
    moves to the next sample fed)."""
    f = x.copy()
    bias = None
    for k in range(x.shape[1]):
        fin = usable[:, k]
        dropped = ~np.isfinite(x[:, k])
        fed = fin | dropped
        s.non_finite[k] = int((~fin).sum())
        if not fin.any():
            continue                    # no reading at all: nothing to filter, written as it is
        out, b = engine.filter_with_bias(x[fed, k], s.restarts if fed.all() else kept_restarts(s.restarts, fed),
                                         rate)
        f[fed, k] = out
        if b is not None:
            bias = np.zeros_like(x) if bias is None else bias
            bias[fed, k] = b
        s.dropouts_healed[k] = int(dropped.sum())
    return f, bias


def _apply_safety_net(s, engine, x, f, bias, back, usable, rate, sample_rate):
    """Set ``s.filtered`` (and ``s.left_raw`` / ``s.not_filtered`` where the raw
    values go out instead); return the work values written. ``bias``: what bias tracking
    removed after each sample (the range check is on the output plus it), or None."""
    s.filtered = f * back
    s.left_raw = check_filtered(s, x, f, usable, causal=getattr(engine, "causal", True), bias=bias)
    if s.left_raw:
        f = x.copy()
        s.filtered = s.raw.astype(np.float64)          # the raw values, bit for bit
    elif usable.any() and np.array_equal(f[usable], x[usable]):
        s.not_filtered = not_filtered_reason(s, engine.method, s.warmup_samples, rate, sample_rate)
        s.filtered = s.raw.astype(np.float64)
    return f


def not_filtered_reason(s, method: str, warmup_samples: int, rate: float,
                        sample_rate: float | None = None) -> str:
    """Why the filter's output of stream ``s`` equals its input on every sample."""
    m = BY_NAME[method]
    if not m.filters:
        return f"--method {method}: output = input"
    runs = sessions(s.n, s.restarts)
    longest = max(b - a for a, b in runs)
    if m.warmup and longest <= warmup_samples:
        each = "its one session is" if len(runs) == 1 else f"each of its {len(runs)} sessions is at most"
        return (f"{each} {longest} samples, not longer than the filter's warm-up of {warmup_samples} samples "
                f"at {rate:.4g} Hz{' (--sample-rate)' if sample_rate else ''}, during which the raw samples "
                f"pass through: the stream is written raw ({_shorter_warmup(method, warmup_samples, rate)})")
    return "the filter's output equals the raw input on every sample: the stream is written raw"


def _shorter_warmup(method, warmup_samples, rate):
    """What filters a stream shorter than the warm-up: a shorter --warmup-s where the warm-up
    is ``warmup_s`` long, else a method whose warm-up it sets."""
    from gyrodenoise.flightlog.engines import warmup_samples as warmup_of
    if warmup_of(method, 3, rate, 0.1) < warmup_samples:
        return "a shorter --warmup-s, e.g. 0.1, filters it"
    return (f"--method {method}'s warm-up does not follow --warmup-s (it reads the noise level first); "
            f"an AR method, e.g. --method shakf --warmup-s 0.1, filters it")


def check_some_stream_filterable(path, streams, filter_kw):
    """InputError (one line, nothing written) when a band option (``--cutoff-hz``,
    ``--max-motion-hz``: :data:`BAND_OPTIONS`) was given and every stream that would
    be filtered (not too slow to denoise) refused it: at or above its Nyquist
    frequency. A log where some stream takes it goes on: the others are written
    raw, each with its reason (``not_filtered``), as streams too slow to denoise are."""
    tried = [s for s in streams if not mm.too_slow_to_denoise(s.rate_hz)]   # the slow ones never reach the filter
    if not tried or not all(getattr(s, "refused_option", None) for s in tried):
        return
    option, value = tried[0].refused_option
    rates = sorted({s.rate_refused for s in tried})
    exc = InputError(f"{path}: {option} {value:g} is at or above the Nyquist frequency of every gyro "
                     f"stream (sampled at {', '.join(f'{r:.4g}' for r in rates)} Hz: Nyquist "
                     f"{', '.join(f'{r / 2:.4g}' for r in rates)} Hz); nothing to filter")
    exc.option, exc.rates_hz = option, rates
    raise exc


def filter_form(eng, engine):
    """{"form": "offline" | "causal", "form_note": what it means} of an engine."""
    if not eng.causal:
        how = ("forwards then backwards, each session on its own (zero phase)" if getattr(eng, "zero_phase", False)
               else "forward and backward runs blended, each session on its own (no lag)")
        return {"form": "offline", "form_note": f"whole record: {how}"}
    if engine == "fmu":
        return {"form": "causal", "form_note": "the FMU filters one sample per step (causal only)"}
    return {"form": "causal", "form_note": "each output from the samples up to it (as live links, "
                                           "Denoiser.step and the FMUs)"}


def filter_options(method: str, filter_kw: dict | None, zero_phase: bool) -> dict:
    """The report's ``filter_options``: the method's options as given, its own
    parameters' defaults spelled out (the low-pass's, the 1-euro filter's), and
    ``zero_phase`` for a method whose offline form it is. A parameter that tunes a switch
    left off (bias tracking's) is not spelled out."""
    options = dict(filter_kw or {})
    for p in PARAMS:
        if method in p.methods and not p.off and (p.tunes is None or options.get(p.tunes)):
            options.setdefault(p.name, p.default)   # lowpass's cutoff_hz None: min(20 Hz, rate / 4)
    if method in BY_NAME and BY_NAME[method].offline == "zero_phase":
        options["zero_phase"] = bool(zero_phase)
    return options
