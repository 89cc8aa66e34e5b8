"""Subcommands demo, denoise, allan, compare: argument parsing and printing only."""

from __future__ import annotations

import argparse
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from gyrodenoise.cli.options import (MODEL_OPTIONS, add_filter_options, add_recording_options, check_core_params,
                                     check_method_options, core_default, filter_kw)
from gyrodenoise.cli.program import emit_json
from gyrodenoise.console import log
from gyrodenoise.errors import InputError
from gyrodenoise.units import ALLAN_TERMS, TERM_BY_SYMBOL, TERM_SYMBOLS

if TYPE_CHECKING:
    from gyrodenoise.analysis.allan import AllanResult
    from gyrodenoise.simulator import ModelCard, Record


def _read(args: argparse.Namespace) -> Record:
    from gyrodenoise.io.export import check_export_args
    from gyrodenoise.io.recording import read_recording
    check_export_args(args)       # refused before the file is read (and its notes printed)
    rec = read_recording(args.input, rate_column=args.rate_column or "rate", time_column=args.time_column,
                         rate_unit=args.rate_unit, sample_rate_hz=args.sample_rate, time_unit=args.time_unit,
                         rate_scale=args.rate_scale, skip_rows=args.skip_rows)
    for note in rec.notes:
        log(f"gyrodenoise: note: {args.input}: {note}")
    return rec


def _open_stream(args: argparse.Namespace) -> Any:
    """The record as a :class:`gyrodenoise.io.chunked.RecordStream` (bounded memory) when
    it has no true_rate column and the chunked reader reads it; else None (the caller reads
    it whole). Its notes are printed as ``_read``'s."""
    from gyrodenoise.cli.axes import announced
    from gyrodenoise.io.chunked import open_stream
    from gyrodenoise.io.export import check_export_args
    check_export_args(args)
    scales = getattr(args, "rate_scale", None) or None
    if scales is not None and len(scales) != 1:
        return None
    stream = open_stream(args.input, rate_column=args.rate_column or "rate", time_column=args.time_column,
                         rate_unit=args.rate_unit, sample_rate_hz=args.sample_rate, time_unit=args.time_unit,
                         rate_scale=scales[0] if scales else None, skip_rows=args.skip_rows)
    return announced(stream, args.input)


def _check_params(args: argparse.Namespace, fs: float) -> None:
    """The filter options of ``denoise`` / ``compare`` at sample rate ``fs``: one line (InputError)."""
    check_method_options(args, ("--max-motion-hz",))
    mhz = getattr(args, "max_motion_hz", None)
    if mhz is not None and not 0.0 <= mhz < float("inf"):
        raise InputError(f"--max-motion-hz must be a finite number of Hz >= 0 (0 = off), got {mhz!r}")
    if mhz is not None and not mhz < 0.5 * fs:
        raise InputError(f"--max-motion-hz {mhz:g} Hz is not below half the sample rate ({0.5 * fs:g} Hz)")
    check_core_params(ar_order=args.ar_order, sample_rate_hz=fs, method=getattr(args, "method", "shakf"),
                      **filter_kw(args))
    check_method_options(args, ("--zero-phase", "--causal"))


# ---------------------------------------------------------------- denoise
def cmd_denoise(args: argparse.Namespace) -> int:
    from gyrodenoise.cli.axes import open_axes_args, read_axes_args, wants_axes
    from gyrodenoise.io.recording import write_axes, write_recording
    _check_params(args, 1e9 if args.method == "lowpass" or args.max_motion_hz is not None
                  else 1.0)   # bad options fail before the file is read
    offline = args.method == "motion" and not args.causal
    if wants_axes(args):
        stream = open_axes_args(args)
        if stream is not None:
            with stream:
                return _denoise_stream(args, stream, offline, several=True)
        recording = read_axes_args(args)
        _check_params(args, recording.sample_rate_hz)
        done = [(ax, _denoise_one(args, recording.record(ax), offline)) for ax in recording.axes]
        write_axes(args.output, recording, [out for _, (out, _) in done])
        log(f"gyrodenoise: wrote {args.output} ({len(recording.time_s)} samples x {len(done)} axes "
            f"({', '.join(ax.column for ax, _ in done)}), {recording.sample_rate_hz:g} Hz, {args.method}, "
            f"{_form_text(args, offline, recording.sample_rate_hz)})")
        for ax, (_, den) in done:
            _gate_note(args, den, ax.column)
        return 0
    stream = _open_stream(args)
    if stream is not None:
        with stream:
            return _denoise_stream(args, stream, offline)
    rec = _read(args)
    _check_params(args, rec.sample_rate_hz)
    out, den = _denoise_one(args, rec, offline)
    write_recording(args.output, rec.time_s, rec.rate_deg_s, out, rec.true_rate_deg_s)
    log(f"gyrodenoise: wrote {args.output} ({len(rec)} samples, {rec.sample_rate_hz:g} Hz, {args.method}, "
        f"{_form_text(args, offline, rec.sample_rate_hz)})")
    if rec.true_rate_deg_s is not None:
        log(f"gyrodenoise: {rmse_line(rec.rate_deg_s, out, rec.true_rate_deg_s)}")
    _gate_note(args, den)
    return 0


def _denoise_one(args: argparse.Namespace, rec: Record, offline: bool) -> tuple[np.ndarray, Any]:
    """(the filtered series, the Denoiser that ran causally, for its gate counts) of one record."""
    from gyrodenoise.denoiser import Denoiser
    den = Denoiser(rec.sample_rate_hz, method=args.method, ar_order=args.ar_order, **filter_kw(args))
    if args.zero_phase or offline:
        from gyrodenoise.denoiser import denoise
        out = denoise(rec.rate_deg_s, rec.sample_rate_hz, method=args.method, ar_order=args.ar_order,
                      restarts=rec.restarts, zero_phase=args.zero_phase, offline=offline, **filter_kw(args))
    else:
        from gyrodenoise.io.stream import process_chunks
        out = process_chunks(den, rec.rate_deg_s, rec.restarts)      # the state carried chunk to chunk
    return out, den


def _denoise_stream(args: argparse.Namespace, stream: Any, offline: bool, several: bool = False) -> int:
    """``denoise`` of a record read a chunk at a time: the causal filter of each axis with
    its Denoiser's whole state carried from chunk to chunk; the offline smoother on each
    spooled column, its output spooled beside it (:func:`_offline_spooled`); the output
    written a chunk of rows at a time. The bytes of the whole-array run: ``time,raw,filtered``
    of one rate column, or (``several``: the axes form, `write_axes`) ``time`` then each
    axis' column and ``<column>_filtered``."""
    from gyrodenoise.denoiser import Denoiser
    from gyrodenoise.io.stream import write_rows
    fs = stream.sample_rate_hz
    _check_params(args, fs)
    dens = [Denoiser(fs, method=args.method, ar_order=args.ar_order, **filter_kw(args)) for _ in stream.axes]
    wholes = [_offline_spooled(args, stream, i) if args.zero_phase or offline else None
              for i in range(len(stream.axes))]
    header = ("time," + ",".join(f"{ax.column},{ax.column}_filtered" for ax in stream.axes) if several
              else "time,raw,filtered")
    try:
        with open(args.output, "wb") as f:
            f.write((header + "\n").encode())
            a = 0
            for t, vals, restarts in stream.axis_chunks():
                cols = [t]
                for r, den, whole in zip(vals, dens, wholes):
                    cols += [r, whole.read(a, a + len(r)) if whole is not None else den.process(r, restarts)]
                write_rows(f, cols)
                a += len(t)
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror}", str(args.output)) from None
    if several:
        log(f"gyrodenoise: wrote {args.output} ({len(stream)} samples x {len(dens)} axes "
            f"({', '.join(ax.column for ax in stream.axes)}), {fs:g} Hz, {args.method}, "
            f"{_form_text(args, offline, fs)})")
        for ax, den in zip(stream.axes, dens):
            _gate_note(args, den, ax.column)
        return 0
    log(f"gyrodenoise: wrote {args.output} ({len(stream)} samples, {fs:g} Hz, {args.method}, "
        f"{_form_text(args, offline, fs)})")
    _gate_note(args, dens[0])
    return 0


def _offline_spooled(args: argparse.Namespace, stream: Any, axis: int = 0) -> Any:
    """The offline output of one axis of a streamed record, as a spool (``read(a, b)``): the
    smoother (`batch.run_offline`) reads the spooled column and writes its output a block at
    a time; the other offline forms (``--zero-phase``, the rigid-body and bias options) run
    on the column gathered whole, as ``denoise`` does."""
    from pathlib import Path

    from gyrodenoise.core import batch
    from gyrodenoise.core import kernels as K
    from gyrodenoise.denoiser import denoise
    from gyrodenoise.io.chunked import Spool, SpoolSlice
    fs = stream.sample_rate_hz
    restarts = stream.restarts
    p = K.make_params(ar_order=args.ar_order, method=args.method, sample_rate_hz=fs, **filter_kw(args))
    out = Spool(Path(stream.folder) / f"offline{axis}", np.dtype(np.float64))
    if not args.zero_phase and p[K.P_LP_NSEC] == 0.0 and p[K.P_BIAS] == 0.0:
        batch.run_offline(p, SpoolSlice(stream.axes[axis].values), restarts, out=SpoolSlice(out, 0, stream.n))
        return out
    rate = np.concatenate(list(stream.values(axis)))
    out.append(denoise(rate, fs, method=args.method, ar_order=args.ar_order, restarts=restarts,
                       zero_phase=args.zero_phase, offline=not args.zero_phase, **filter_kw(args)))
    return out


def _gate_note(args: argparse.Namespace, den: Any, column: str | None = None) -> None:
    if args.outlier_sigma > 0 and args.method in ("shakf", "kf", "sh_classic"):
        log(f"gyrodenoise: note: {args.input}: {column + ': ' if column else ''}outlier gate "
            f"(k={args.outlier_sigma:g}): {den.n_rejected} sample(s) kept out of the filter (output = prediction "
            f"there), {den.n_reopened} re-opening(s) after {args.outlier_run} consecutive rejections")


def _form_text(args: argparse.Namespace, offline: bool, sample_rate_hz: float) -> str:
    """'causal' or 'offline (...)', and the rigid-body low-pass applied with --max-motion-hz."""
    mode = "offline (forward + backward, no lag)" if offline or args.zero_phase else "causal"
    if args.max_motion_hz:
        from gyrodenoise.core.kernels import rigid_cutoff_hz
        fc = rigid_cutoff_hz(float(args.max_motion_hz), sample_rate_hz)
        capped = fc < 2.0 * args.max_motion_hz
        mode += (f", rigid body (--max-motion-hz {args.max_motion_hz:g}): a 4th-order low-pass flat to "
                 f"{args.max_motion_hz:g} Hz, -3 dB at {fc:.3g} Hz"
                 + (f" (at most 0.45 x the sample rate; twice the band would be {2.0 * args.max_motion_hz:g} Hz)"
                    if capped else "") + ", before the filter bank")
    return mode


def rmse_line(raw: npt.ArrayLike, filtered: npt.ArrayLike, truth: npt.ArrayLike) -> str:
    """'RMSE against true_rate over N samples: raw X, filtered Y deg/s (xR)' over the
    samples where all three are finite (the RMSE of `gyrodenoise.analysis.experiments`)."""
    from gyrodenoise.analysis.experiments import rmse
    raw, filtered, truth = (np.asarray(v, dtype=np.float64) for v in (raw, filtered, truth))
    ok = np.isfinite(raw) & np.isfinite(filtered) & np.isfinite(truth)
    if not ok.any():
        return "RMSE against true_rate: no sample where raw, filtered and true_rate are all finite"
    r, f = rmse(raw[ok], truth[ok]), rmse(filtered[ok], truth[ok])
    ratio = f" (x{f / r:.3g})" if r > 0 else ""
    return f"RMSE against true_rate over {int(ok.sum())} samples: raw {r:.4g}, filtered {f:.4g} deg/s{ratio}"


def true_rate_motion(rec: Record) -> dict[str, float] | None:
    """None when the record has no true_rate or a constant one; else
    {"std", "min", "max"} of its true rate (deg/s): the record moves."""
    if rec.true_rate_deg_s is None:
        return None
    tr = np.asarray(rec.true_rate_deg_s, dtype=np.float64)
    tr = tr[np.isfinite(tr)]
    if not tr.size or np.ptp(tr) == 0.0:
        return None
    return {"std": float(tr.std()), "min": float(tr.min()), "max": float(tr.max())}


#: what ``allan`` analyses when the recording has a true_rate column
ALLAN_OF_ERROR = ("rate - true_rate: the sensor's error (the recording has a true_rate column; the "
                  "vehicle's motion would otherwise enter the terms, K and R above all)")


# ------------------------------------------------------------------ allan
def cmd_allan(args: argparse.Namespace) -> int:
    from gyrodenoise.analysis.allan import allan_of_record
    stream = _open_stream(args)
    if stream is not None:
        with stream:
            return _allan_report(args, stream, _allan_of_stream(stream, args.input), "rate", None)
    rec = _read(args)
    series, analysed = rec.rate_deg_s, "rate"
    if rec.true_rate_deg_s is not None:
        series = np.asarray(rec.rate_deg_s, dtype=np.float64) - np.asarray(rec.true_rate_deg_s, dtype=np.float64)
        analysed = ALLAN_OF_ERROR
    res = allan_of_record(series, rec.sample_rate_hz, args.input)
    return _allan_report(args, rec, res, analysed, true_rate_motion(rec))


def _allan_of_stream(stream: Any, source: str) -> AllanResult:
    """`allan_of_record` of a record read a chunk at a time (`cli.axes.allan_of_stream`)."""
    from gyrodenoise.cli.axes import allan_of_stream
    return allan_of_stream(stream, source)


def _allan_report(args: argparse.Namespace, rec: Any, res: AllanResult, analysed: str,
                  moving: dict[str, float] | None) -> int:
    """``allan``'s exports, JSON or table of one record's result."""
    unit = rate_unit_used(args, rec)
    from gyrodenoise.io.export import export_from_args
    written = export_from_args(args, res)
    for path in written:
        log(f"gyrodenoise: wrote {path} ({exported_text(res)})")
    if args.json:
        d = res.to_json()
        d["source"] = args.input
        d["notes"] = rec.notes
        d["analysed"] = analysed
        d["rate_unit"] = unit
        d["rate_scale"] = args.rate_scale[0] if args.rate_scale else None
        d["true_rate_motion_deg_s"] = moving
        emit_json(d)
    else:
        print(f"analysed: {analysed}")
        print(f"rate unit: {unit['unit']} ({unit['how']})")
        print(format_terms_table({"record": res.terms}, {"record": res.bounds}))
        print()
        print(format_agreement(res))
        print()
        print(f"{'tau_s':>12} {'adev_deg_h':>14} {'err_deg_h':>12}")
        for t, a, e in zip(res.tau_s, res.adev_deg_h, res.adev_err_deg_h):
            print(f"{t:12.4g} {a:14.6g} {e:12.3g}")
    return 0


def rate_unit_used(args: argparse.Namespace, rec: Record) -> dict[str, str]:
    """{"unit", "how"}: the rate unit the record was read in and how the reader decided it
    (given; the file's units row or its column names; or the default deg/s, with a word
    when the column's name says another unit)."""
    if args.rate_unit is not None:
        return {"unit": args.rate_unit, "how": "given with --rate-unit"}
    if rec.unit_how and not rec.unit_how.startswith("assumed"):
        return {"unit": rec.unit, "how": rec.unit_how}
    how = "the default: --rate-unit not given"
    column = str(args.rate_column).lower()
    said = next((u for u in ("mrad", "rad", "dps", "deg") if u in column), None)
    if said in ("mrad", "rad"):
        how += (f"; the column's name {args.rate_column!r} says {said}: give --rate-unit {said}/s if it is "
                f"(rad/s read as deg/s makes every term {180 / np.pi:.1f}x too small)")
    else:
        how += ("; a record in rad/s read as deg/s gives every term 57.3x too small: give --rate-unit "
                "rad/s if it is")
    return {"unit": "deg/s", "how": how}


def exported_text(res: AllanResult) -> str:
    """'N fit, B slope-point read, ...': what the exports wrote, term by term."""
    words = {"fit": "fit", "upper_bound": "upper bound of the fit", "slope_point": "slope-point read"}
    return "terms: " + ", ".join(f"{k} {words[v]}" for k, v in res.exported_bounds.items() if k in ("N", "B", "K"))


def format_agreement(res: AllanResult) -> str:
    """Per term: the fit against its own points where the term dominates, the slope-point
    read beside it and which one the exports use, with why."""
    lines = [f"{'term (unit)':<20}{'fit':>12}{'slope point':>13}{'fit/measured':>14}{'95% band':>10}"
             f"{'at tau s':>10}  exported"]
    for term in ALLAN_TERMS:
        a = res.agreement[term.symbol]
        cells = (f"{res.terms[term.symbol]:12.4g}"
                 + (f"{a.slope_point:13.4g}" if a.slope_point is not None else f"{'-':>13}")
                 + (f"{a.fit_over_measured:14.3g}{'+-' + format(100 * a.band, '.2g') + '%':>10}"
                    f"{a.tau_s:10.3g}" if a.fit_over_measured is not None and a.band is not None
                    and a.tau_s is not None else f"{'-':>14}{'-':>10}{'-':>10}"))
        lines.append(f"{term.symbol + ' (' + term.unit + ')':<20}{cells}  {a.exported.replace('_', '-')}")
    lines.append("exported (Kalibr, MATLAB): the fit where it agrees with its own points within their 95 % "
                 "band; where it misses, the slope-point read (IEEE 952 / MathWorks recipe: N on the -1/2 "
                 "line at 1 s, B = minimum / 0.664, K on the +1/2 line at 3 s)")
    for sym, a in res.agreement.items():
        if a.misses:
            lines.append(f"{sym}: {a.why}")
    return "\n".join(lines)


def _allan_of_axes_or_one(args: argparse.Namespace) -> int:
    """``allan``: over several axes (gyrodenoise.cli.axes) or one (:func:`cmd_allan`)."""
    from gyrodenoise.cli.axes import cmd_allan_axes, wants_axes
    return cmd_allan_axes(args) if wants_axes(args) else cmd_allan(args)


# ---------------------------------------------------------------- compare
def cmd_compare(args: argparse.Namespace) -> int:
    _check_params(args, 1.0)          # bad options fail before the file is read
    columns = [c.strip() for c in str(args.rate_column).split(",") if c.strip()]
    if len(columns) > 1:
        return _compare_axes(args, columns)
    stream = _open_stream(args)
    if stream is not None:
        with stream:
            res = _compare_stream(args, stream)
    else:
        res = _compare_one(args, _read(args))
    if args.json:
        emit_json(public(res))
    else:
        print(format_compare(res))
    return 0


def _compare_one(args: argparse.Namespace, rec: Record) -> dict[str, Any]:
    """Table 1 of one record (its warnings added)."""
    from gyrodenoise.analysis.experiments import compare
    _check_params(args, rec.sample_rate_hz)
    _check_compare_length(args, len(rec))
    res = compare(rec, ar_order=args.ar_order, **filter_kw(args))
    _add_compare_warnings(res, true_rate_motion(rec))
    return res


def _compare_stream(args: argparse.Namespace, stream: Any) -> dict[str, Any]:
    """Table 1 of a record read a chunk at a time (`compare_chunks`: the filters' states
    carried, their outputs spooled in the stream's folder): the whole-array table, the std
    to rounding."""
    from gyrodenoise.analysis.compare_chunks import compare_chunks
    fs = stream.sample_rate_hz
    _check_params(args, fs)
    _check_compare_length(args, len(stream))
    res = compare_chunks(lambda: ((r, restarts) for _, r, _, restarts in stream.chunks()), len(stream), fs,
                         stream.folder, source=stream.source, notes=stream.notes, ar_order=args.ar_order,
                         **filter_kw(args))
    _add_compare_warnings(res, None)
    return res


def _check_compare_length(args: argparse.Namespace, n: int) -> None:
    if n < 100:
        raise InputError(f"only {n} samples; compare needs at least 100", args.input)


def _add_compare_warnings(res: dict[str, Any], moving: dict[str, float] | None) -> None:
    if moving:
        res["true_rate_motion_deg_s"] = moving
        add_warnings(res, [moving_warning(moving)])
    else:     # a moving record's raw curve is the motion's (its warning says so); `allan` analyses another
        add_warnings(res, raw_misfit_warnings(res))


def _compare_axes(args: argparse.Namespace, columns: list[str]) -> int:
    """``compare --rate-column gx,gy,gz``: Table 1 of each column; with --json one object whose
    ``axes`` maps each column to the object one column gives (as ``allan`` over several axes)."""
    from gyrodenoise.io.recording import read_axes
    recording = read_axes(args.input, columns, time_column=args.time_column, rate_unit=args.rate_unit,
                          sample_rate_hz=args.sample_rate, time_unit=args.time_unit, rate_scale=args.rate_scale,
                          skip_rows=args.skip_rows)
    for note in recording.notes:
        log(f"gyrodenoise: note: {args.input}: {note}")
    done = {ax.column: _compare_one(args, recording.record(ax)) for ax in recording.axes}
    if args.json:
        emit_json({"source": str(args.input), "notes": recording.notes,
                   "sample_rate_hz": recording.sample_rate_hz, "n_samples": len(recording.time_s),
                   "axes": {c: public(res) for c, res in done.items()}})
        return 0
    print("\n\n".join(f"{c}:\n{format_compare(res)}" for c, res in done.items()))
    return 0


def add_warnings(res: dict[str, Any], warnings: list[str]) -> None:
    """Append ``warnings`` to ``res["warnings"]``, made only when there is one."""
    if warnings:
        res.setdefault("warnings", []).extend(warnings)


def raw_misfit_warnings(res: Mapping[str, Any]) -> list[str]:
    """A warning per term whose Eq. (40) fit on the raw record misses its own Allan points
    beyond their 95 % band, with the slope-point read beside it (what `allan` exports)."""
    out = []
    for sym, a in res.get("fit_agreement", {}).get("raw", {}).items():
        if not a["misses"]:
            continue
        unit = TERM_BY_SYMBOL[sym].unit
        beside = (f"the slope-point read gives {a['slope_point']:.4g} {unit} beside the fit's "
                  f"{res['rows']['raw'][sym]:.4g} (`gyrodenoise allan` exports the slope-point read)"
                  if a["exported"] == "slope_point" else "no slope-point read to put beside it")
        out.append(f"raw: the Eq. (40) fit misses its own Allan points where {sym} dominates (fit/measured "
                   f"{a['fit_over_measured']:.3g} at tau {a['tau_s']:.3g} s, 95 % band +-{100 * a['band_95']:.2g} %): "
                   f"{beside}")
    return out


def moving_warning(moving: Mapping[str, float]) -> str:
    """The warning of ``compare`` on a record whose true rate moves."""
    return (f"the record moves (true_rate {moving['min']:.4g} to {moving['max']:.4g} deg/s, std "
            f"{moving['std']:.4g}): every row's Allan terms include that motion (K and R above all are the "
            f"motion's, not the sensor's); read the RMSE against the true rate; `gyrodenoise allan` "
            f"analyses rate - true_rate")


def public(d: Mapping[str, Any]) -> dict[str, Any]:
    """Drop the private (array) entries of a result dict."""
    return {k: v for k, v in d.items() if not k.startswith("_")}


def format_terms_table(rows: Mapping[str, Mapping[str, float]], bounds: Mapping[str, Mapping[str, str]]) -> str:
    """Five-term table; '<' marks an upper bound (term not resolved)."""
    names = list(rows)
    lines = [f"{'term (unit)':<20}" + "".join(f"{n:>14}" for n in names)]
    for term in ALLAN_TERMS:
        t = term.symbol
        cells = []
        for n in names:
            v = rows[n][t]
            mark = "<" if bounds[n].get(t) == "upper_bound" else " "
            cells.append(f"{mark + format(v, '.4e'):>14}")
        lines.append(f"{t + ' (' + term.unit + ')':<20}" + "".join(cells))
    lines.append("('<' = upper bound: the record cannot resolve that term)")
    return "\n".join(lines)


POOR_FIT = 2.0     # fit_misfit_factor above which Table 1 flags a series' Eq. (40) fit


def format_compare(res: Mapping[str, Any]) -> str:
    """Table 1 (the Allan terms of each series, their ratios to raw, the AR model) as text."""
    out = [f"Table 1 -- Allan terms of {res['source']} ({res['n_samples']} samples, "
           f"{res['sample_rate_hz']:g} Hz; first {res['skipped_warmup_samples']} warm-up samples skipped)"]
    out.append(format_terms_table(res["rows"], res["bounds"]))
    out.append("")
    names = list(res["ratio_to_raw"])
    out.append(f"{'ratio to raw':<20}" + "".join(f"{n:>14}" for n in names))
    for t in TERM_SYMBOLS:
        cells = "".join(f"{_fmt(res['ratio_to_raw'][n][t]):>14}" for n in names)
        out.append(f"{t:<20}{cells}")
    poor = {k: v for k, v in res.get("fit_misfit_factor", {}).items()
            if k != "raw" and v is not None and v > POOR_FIT}     # raw: raw_misfit_warnings, per term
    if poor:
        out.append("Eq. (40) fit misses its own Allan points by up to " +
                   ", ".join(f"{v:.2g}x ({k})" for k, v in poor.items()) +
                   ": a filtered output is not a sum of Eq. (40) noises; read those terms as a fit of "
                   "the curve's shape, not as a sensor's (see the Allan figure)")
    if "motion" in names:
        out.append(f"motion: the {res.get('motion_form', 'causal')} filter (the form Denoiser.step, the FMUs "
                   "and live links run; `denoise` on a file defaults to the offline form)")
    acc = res["ar_fit_accuracy"]
    out.append("AR fit accuracy (1-|fit-raw|/raw): " +
               ", ".join(f"{t} {_fmt(acc[t], pct=True)}" for t in TERM_SYMBOLS))
    ar = res["ar_model"]
    out.append(f"AR({ar['order']}) model: phi = [{', '.join(f'{v:.4f}' for v in ar['phi'])}], "
               f"c = {ar['c_deg_s']:.4g} deg/s, sigma_a = {ar['sigma_a_deg_s']:.4g} deg/s")
    out.append("std about the mean (the paper's 'MSE', Eq. 41), deg/s: " +
               ", ".join(f"{k} {v:.4g}" for k, v in res["std_deg_s"].items()))
    if "rmse_deg_s" in res:
        out.append("RMSE against the true rate, deg/s: " +
                   ", ".join(f"{k} {v:.4g}" for k, v in res["rmse_deg_s"].items()))
    for w in res.get("warnings", []):
        out.append(f"WARNING: {w}")
    return "\n".join(out)


def _fmt(v: float | None, pct: bool = False) -> str:
    if v is None:
        return "n/a"
    return f"{100 * v:.1f}%" if pct else f"{v:.3g}"


def format_dynamic(dyn: Mapping[str, Any]) -> str:
    """Table 2 (constant rates, the step) as text."""
    names = list(dyn["rows"][0]["std_deg_s"])
    label = {"raw": "raw", "kf": "KF", "shakf": "SHAKF", "motion": "motion"}
    out = [f"Table 2 -- constant rotation, {dyn['duration_s']:g} s each ({dyn['card']})",
           f"{'rate deg/s':>10} | " + " ".join(f"{'std ' + label.get(n, n):>10}" for n in names) + " | "
           + " ".join(f"{'RMSE ' + label.get(n, n):>11}" for n in names)]
    for r in dyn["rows"]:
        s, e = r["std_deg_s"], r["rmse_deg_s"]
        out.append(f"{r['rate_deg_s']:>10g} | " + " ".join(f"{s[n]:10.4g}" for n in names) + " | "
                   + " ".join(f"{e[n]:11.4g}" for n in names))
    st = dyn["step"]
    rt = st["rise_time_90_s"]
    out.append(f"Price paid -- a {st['step_deg_s']:g} deg/s rate step at mid-record: 90% rise time "
               + ", ".join(f"{k} {('%.3g s' % v) if v is not None else 'never (within the record)'}"
                           for k, v in rt.items())
               + "; RMSE against truth " + ", ".join(f"{k} {v:.4g}" for k, v in st["rmse_deg_s"].items()))
    ng = st.get("no_gate")
    if ng:
        out.append("  the same step with the paper's filters (--outlier-sigma 0, no gate): 90% rise time "
                   + ", ".join(f"{k} {('%.3g s' % v) if v is not None else 'never (within the record)'}"
                               for k, v in ng["rise_time_90_s"].items())
                   + "; RMSE " + ", ".join(f"{k} {v:.4g}" for k, v in ng["rmse_deg_s"].items()))
        out.append(f"  (the default gate follows a step by re-opening the filter after "
                   f"{core_default('outlier_run')} rejected samples:"
                   " it rescues abrupt changes, not smooth motion -- docs/bench/outliers-soak.md)")
    out.append("(std = the paper's 'MSE' of Eq. 41, a standard deviation about the mean; it cannot see "
               "a wrong mean or a lag, the RMSE can.)")
    return "\n".join(out)


# ------------------------------------------------------------------- demo
def cmd_demo(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    check_core_params(**filter_kw(args))
    card, rec = _demo_record(args)
    res, dyn = _demo_tables(args, card, rec)
    figs = []
    if not args.no_plots:
        from gyrodenoise.analysis import plots
        outdir = Path(args.out)
        outdir.mkdir(parents=True, exist_ok=True)
        figs = plots.demo_figures(card, rec, res, outdir, ar_order=args.ar_order, seed=args.seed,
                                  **filter_kw(args))
    elapsed = time.perf_counter() - t0
    if args.json:
        emit_json({"model": card.name, "hours": args.hours, "static": public(res), "dynamic": dyn,
                   "figures": [str(f) for f in figs], "elapsed_s": elapsed})
    else:
        print(format_compare(res))
        print()
        print(format_dynamic(dyn))
        if figs:
            print()
            print("Figures:")
            for f in figs:
                print(f"  {f}")
        print(f"\n(done in {elapsed:.1f} s)")
    return 0


def _demo_record(args: argparse.Namespace) -> tuple[ModelCard, Record]:
    """The model card and its simulated static record of ``--hours``."""
    from gyrodenoise.simulator import load_card, simulate
    card = load_card(args.model)
    n = int(round(args.hours * 3600.0 * card.sample_rate_hz))
    if n < 1000:
        raise InputError(f"--hours {args.hours:g} gives only {n} samples; need at least 1000")
    log(f"gyrodenoise demo: simulating {args.hours:g} h of '{card.name}' at {card.sample_rate_hz:g} Hz "
        f"(seed {args.seed})")
    return card, simulate(card, n, seed=args.seed)


def _demo_tables(args: argparse.Namespace, card: ModelCard, rec: Record) -> tuple[dict[str, Any], dict[str, Any]]:
    """Table 1 (the static record) and Table 2 (constant rates and a step)."""
    from gyrodenoise.analysis.experiments import compare, dynamic_table
    log("gyrodenoise demo: static experiment (Table 1): KF, modified SHAKF and motion, Allan fits")
    res = compare(rec, ar_order=args.ar_order, seed=args.seed, **filter_kw(args))
    add_warnings(res, raw_misfit_warnings(res))
    log(f"gyrodenoise demo: dynamic experiment (Table 2): {args.dynamic_s:g} s at each rate")
    dyn = dynamic_table(card, duration_s=args.dynamic_s, seed=args.seed, ar_order=args.ar_order,
                        **filter_kw(args))
    return res, dyn


# ------------------------------------------------------------------ parsers
def register_cli(sub: Any) -> None:
    """Add the subcommands demo, denoise, allan and compare to the parser's subparsers ``sub``."""
    _register_demo(sub)
    p = sub.add_parser("denoise", help="filter a recording to time,raw,filtered CSV")
    add_recording_options(p, axes=True)
    p.add_argument("-o", "--output", required=True, metavar="OUT.csv")
    add_filter_options(p)
    p.set_defaults(func=cmd_denoise)

    p = sub.add_parser("allan", help="Allan deviation and five-term fit of a recording")
    add_recording_options(p, rate_unit_default=None, axes=True)
    p.add_argument("--json", action="store_true")
    from gyrodenoise.io.export import add_export_options
    add_export_options(p)
    p.set_defaults(func=_allan_of_axes_or_one)

    p = sub.add_parser("compare", help="the paper's Table 1 for a recording (raw, AR fit, KF, SHAKF)")
    add_recording_options(p, several_columns="; several, comma-separated (gx,gy,gz): a table for each, with "
                                             "--json one object whose axes maps each column to its table")
    add_filter_options(p, MODEL_OPTIONS)
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_compare)


def _register_demo(sub: Any) -> None:
    p = sub.add_parser("demo", help="simulate the default FOG, denoise with KF, SHAKF and motion, print Tables 1-2, "
                                    "plot",
                       description="The main job on the embedded default model card: simulate the paper's FOG, "
                                   "denoise with KF and modified SHAKF (the paper) and motion (the project's "
                                   "default), print the Allan table (Table 1) and the dynamic table (Table 2), "
                                   "write PNG plots.")
    p.add_argument("--model", default="paper_fog", help="model card path or embedded name (default paper_fog)")
    p.add_argument("--hours", type=float, default=2.0, help="static record length, h (default 2, as the paper)")
    p.add_argument("--dynamic-s", type=float, default=300.0, help="seconds per constant rate (default 300)")
    p.add_argument("--seed", type=int, default=0)
    add_filter_options(p, ("--ar-order", "--outlier-sigma", "--outlier-run"), help={
        "--ar-order": None,
        "--outlier-sigma": f"outlier gate of the filters (default {core_default('outlier_sigma'):g}; 0 = off, "
                           "the paper's filters exactly; see docs/bench/outliers-soak.md)",
        "--outlier-run": f"consecutive rejections after which the filter re-opens "
                         f"(default {core_default('outlier_run')})"})
    p.add_argument("--out", default="demo_out", help="folder for the PNG plots (default demo_out)")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=cmd_demo)
