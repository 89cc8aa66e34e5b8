"""Several axes in one run: ``allan`` and ``denoise`` over the gyro (and accelerometer)
columns of a file, a bag or a MATLAB file (:func:`gyrodenoise.io.recording.read_axes`).

A run is one of several axes when ``--rate-column`` lists more than one column, when
``--accel-column`` is given, when IN is a bag, an MCAP or a ``.mat`` file, or when no
``--rate-column`` is given and the CSV has no ``rate`` column (its gyro columns are then
detected). Otherwise the single-axis commands run as before (their output unchanged).
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any


from gyrodenoise.console import log
from gyrodenoise.units import ACCEL_TERMS, ALLAN_TERMS, TERM_SYMBOLS

if TYPE_CHECKING:
    from gyrodenoise.io.recording import Axis, Recording


def _split(text: str | None) -> list[str] | None:
    return [c.strip() for c in text.split(",") if c.strip()] if text else None


def wants_axes(args: argparse.Namespace) -> bool:
    """Whether ``args`` ask for the several-axes form (module doc)."""
    from gyrodenoise.io.recording import is_container, peek_header
    cols = _split(args.rate_column)
    if getattr(args, "accel_column", None) or (cols and len(cols) > 1) or is_container(args.input):
        return True
    if cols:
        return False
    header = peek_header(args.input, getattr(args, "skip_rows", 0))
    return header is not None and "rate" not in header


def read_axes_args(args: argparse.Namespace) -> Recording:
    """The recording of ``args`` (its notes printed on stderr)."""
    from gyrodenoise.flightlog.rosbag import read_imu
    from gyrodenoise.io.export import check_export_args
    from gyrodenoise.io.recording import read_axes
    check_export_args(args)
    rec = read_axes(args.input, _split(args.rate_column), _split(args.accel_column),
                    time_column=args.time_column, rate_unit=args.rate_unit, accel_unit=args.accel_unit,
                    sample_rate_hz=args.sample_rate, time_unit=args.time_unit, topic=getattr(args, "topic", None),
                    variable=getattr(args, "variable", None), bag_reader=read_imu, rate_scale=args.rate_scale,
                    accel_scale=getattr(args, "accel_scale", None), skip_rows=getattr(args, "skip_rows", 0))
    for note in rec.notes:
        log(f"gyrodenoise: note: {args.input}: {note}")
    return rec


def open_axes_args(args: argparse.Namespace) -> Any:
    """The axes of ``args`` as a :class:`gyrodenoise.io.chunked.RecordStream`, every column
    spooled in one pass (bounded memory), when the chunked reader reads the file and it has
    no true_rate column; else None (the caller reads it whole, :func:`read_axes_args`). Its
    notes are printed as :func:`read_axes_args` prints them."""
    from gyrodenoise.io.chunked import open_axes
    from gyrodenoise.io.export import check_export_args
    check_export_args(args)
    if getattr(args, "topic", None) is not None or getattr(args, "variable", None) is not None:
        return None
    stream = open_axes(args.input, _split(args.rate_column), _split(args.accel_column),
                       time_column=args.time_column, rate_unit=args.rate_unit, accel_unit=args.accel_unit,
                       sample_rate_hz=args.sample_rate, time_unit=args.time_unit, rate_scale=args.rate_scale,
                       accel_scale=getattr(args, "accel_scale", None), skip_rows=getattr(args, "skip_rows", 0))
    return announced(stream, args.input)


def announced(stream: Any, source: str) -> Any:
    """``stream`` (a chunked record, or None) with its notes printed as the whole-array reader's
    are; None for a record with a true_rate column (the whole-array reader reads those)."""
    if stream is not None and stream.has_true:
        stream.close()
        return None
    if stream is not None:
        for note in stream.notes:
            log(f"gyrodenoise: note: {source}: {note}")
    return stream


def allan_of_stream(stream: Any, source: str, axis: int = 0) -> Any:
    """`allan_of_record` of one axis of a record read a chunk at a time (the Allan sums in
    blocks; the taus of ``allan``): the whole-array result to rounding (the sums are added in
    another order)."""
    import numpy as np

    from gyrodenoise.analysis.allan import allan_of_chunks, default_m
    from gyrodenoise.errors import InputError
    if len(stream) < 5:
        raise InputError(f"only {len(stream)} samples; the Allan deviation needs at least 5", source)
    res = allan_of_chunks(stream.values(axis), stream.sample_rate_hz, m=default_m(len(stream)))
    if not np.isfinite(res.adev_deg_s).any():
        raise InputError(f"the Allan deviation is not a finite number at any tau at {stream.sample_rate_hz:g} Hz: "
                         f"the sample rate or the rates are beyond what float64 holds", source)
    return res


def _label(ax: Axis) -> tuple[str, ...]:
    """The term labels 'N (unit)' of the axis' kind."""
    if ax.kind.name == "accel":
        return tuple(f"{t} ({ACCEL_TERMS[t][1]})" for t in TERM_SYMBOLS)
    return tuple(f"{t.symbol} ({t.unit})" for t in ALLAN_TERMS)


#: an accelerometer's curve keys: `AllanResult.to_json`'s (a gyro's, in deg/h) in its unit, m/s/h
ACCEL_CURVE_KEYS = {"adev_deg_h": "adev_m_s_h", "adev_err_deg_h": "adev_err_m_s_h"}


def _accel_path(path: str) -> str:
    key, sep, rest = path.partition("[")
    return ACCEL_CURVE_KEYS.get(key, key) + sep + rest


def axis_json(ax: Axis, res: Any) -> dict[str, Any]:
    """One axis' object: `AllanResult.to_json` (spec section 3), the sensor and the unit
    read; an accelerometer's terms and curve in m/s units (``units``, ``adev_unit``; the curve
    under ``adev_m_s_h`` and ``adev_err_m_s_h``, a gyro's under ``adev_deg_h``)."""
    d = res.to_json()
    d["sensor"] = ax.kind.name
    d["unit_read"] = ax.unit
    d["accel_scale" if ax.kind.name == "accel" else "rate_scale"] = ax.scale
    if ax.kind.name == "accel":
        d["units"] = {t: ACCEL_TERMS[t][1] for t in TERM_SYMBOLS}
        d["names"] = {t: ACCEL_TERMS[t][0] for t in TERM_SYMBOLS}
        d["adev_unit"] = "m/s/h"
        d = {ACCEL_CURVE_KEYS.get(k, k): v for k, v in d.items()}
        d["nulls"] = {_accel_path(k): v for k, v in d["nulls"].items()}
    else:
        d["adev_unit"] = "deg/h"
    return d


def cmd_allan_axes(args: argparse.Namespace) -> int:
    """``allan`` over every axis: one JSON object whose ``axes`` maps each column to its
    object; one Kalibr imu.yaml and one MATLAB script for all axes."""
    from gyrodenoise.analysis.allan import allan_of_record
    stream = open_axes_args(args)
    if stream is not None:
        with stream:
            results = [(ax, allan_of_stream(stream, args.input, i)) for i, ax in enumerate(stream.axes)]
            return _allan_axes_report(args, stream, results, len(stream))
    rec = read_axes_args(args)
    results = [(ax, allan_of_record(ax.values, rec.sample_rate_hz, args.input)) for ax in rec.axes]
    return _allan_axes_report(args, rec, results, len(rec.time_s))


def _allan_axes_report(args: argparse.Namespace, rec: Any, results: list[tuple[Any, Any]], n: int) -> int:
    """``allan``'s exports, JSON or table over every axis (``rec``: its notes and rate)."""
    from gyrodenoise.cli.program import emit_json
    from gyrodenoise.errors import InputError
    from gyrodenoise.io.export import AxisTerms, export_axes_from_args
    if any(ax.kind.name == "gyro" for ax in rec.axes):
        # what the single-axis exports write: the fit, or the slope-point read where it misses
        terms = [AxisTerms(ax.column, ax.kind.name == "accel", r.exported_terms, r.exported_bounds)
                 for ax, r in results]
        for path in export_axes_from_args(args, terms, rec.sample_rate_hz):
            log(f"gyrodenoise: wrote {path}")
    elif getattr(args, "kalibr_yaml", None) or getattr(args, "matlab", None):
        raise InputError("no gyro column: the exports need one (--rate-column)", args.input)
    if args.json:
        emit_json({"source": str(args.input), "notes": rec.notes, "sample_rate_hz": rec.sample_rate_hz,
                   "n_samples": n,
                   "axes": {ax.column: axis_json(ax, r) for ax, r in results}})
        return 0
    for ax, r in results:
        print(f"{ax.column} ({ax.kind.name}, read in {ax.unit})")
        for label, t in zip(_label(ax), TERM_SYMBOLS):
            mark = "<" if r.bounds.get(t) == "upper_bound" else " "
            print(f"  {label:<22}{mark}{r.terms[t]:.4e}")
    print("('<' = upper bound: the record cannot resolve that term)")
    return 0
