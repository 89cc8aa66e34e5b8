"""Reading and writing recordings (spec section 2) with the bad-input rules.

Every problem is either a one-line `gyrodenoise.errors.InputError`
naming the file, line and column, or a documented repair recorded in
``Record.notes`` (the CLI prints the notes on stderr and in ``--json``):

* the time column: its unit, sample rate, kind of timestamps (uniform,
  jittered, bursty, varying), gaps and restarts are those of
  :func:`gyrodenoise.io.timebase.analyse_time`, said in one note line. No
  interpolation: jitter, bursts, repeated timestamps and gaps of up to 4
  missing samples do not restart the filter; a longer gap or a time reversal
  marks the next sample as a restart (the AR model and filter are re-identified
  there) and the note gives the samples each run holds;
* columns other than time / rate / true_rate: ignored and reported;
* a constant rate: accepted (a valid, if dull, record: the filter passes it
  through and the Allan terms are zero) and reported;
* suspected saturation (a run of at least `SAT_RUN` equal samples at the
  rate column's maximum or minimum): kept as is and reported with the count and
  the first time;
* isolated spikes (a sample more than `SPIKE_SIGMAS` robust standard
  deviations of the sample-to-sample difference away from both neighbours, in
  the same direction): kept as is and reported; the SHAKF's outlier gate
  (``outlier_sigma``, docs/bench/outliers-soak.md) keeps them out of the filter.

Errors: missing or unreadable file, empty file, header only, missing rate or
time column, a value that is not a number, NaN or inf, a short (truncated)
row, time that never advances, fewer than 2 samples, unknown rate unit,
no time column and no sample rate, a rate beyond `ABSURD_RATE_DEG_S`
(after unit conversion; not a gyro reading).
The test suite's corpus of bad recordings holds one file per case.
"""

from __future__ import annotations

import csv
import gzip
import io
import math
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from gyrodenoise.errors import InputError
from gyrodenoise.io.timebase import MAX_RATE_HZ, analyse_time, restart_mask
from gyrodenoise.simulator import Record
from gyrodenoise.units import RATE_TO_DEG_S

if TYPE_CHECKING:
    from _csv import Reader as _CsvReader

MIN_SAMPLES = 2
ABSURD_RATE_DEG_S = 1.0e6   # 2,800 rev/s: no gyro measures that
SAT_RUN = 10                # equal samples at the column's max/min: suspected saturation
SPIKE_SIGMAS = 8.0          # isolated spike: this many robust sigmas from both neighbours


def _open_text(path: str | os.PathLike[str]) -> str:
    p = Path(path)
    if not p.exists():
        raise InputError("no such file", str(path))
    if p.is_dir():
        raise InputError("is a directory, expected a CSV file", str(path))
    try:
        raw = p.read_bytes()
        if raw[:2] == b"\x1f\x8b":
            raw = gzip.decompress(raw)
        return raw.decode("utf-8-sig")
    except (OSError, EOFError, gzip.BadGzipFile) as exc:
        raise InputError(f"cannot read: {exc}", str(path)) from None
    except UnicodeDecodeError:
        raise InputError("not a text CSV file (undecodable bytes)", str(path)) from None


#: what a spike note advises (the filters' outlier gate); a command with another remedy passes its own
SPIKE_ADVICE = ("with --method shakf, kf or sh_classic the outlier gate (--outlier-sigma) keeps single "
                "wild samples out of the filter")


def read_recording(path: str | os.PathLike[str], rate_column: str = "rate", time_column: str = "time",
                   rate_unit: str = "deg/s", sample_rate_hz: float | None = None, true_column: str = "true_rate",
                   spike_advice: str = SPIKE_ADVICE, time_unit: str | None = None) -> Record:
    """Read a recording CSV into a `Record` (rates in deg/s).

    Parameters
    ----------
    path : str or Path
        CSV (optionally gzip-compressed) with a header row.
    rate_column : str
        Name of the rate column.
    time_column : str
        Name of the time column (s); optional when ``sample_rate_hz`` is given.
    rate_unit : str
        Unit of the rate and true-rate columns, a key of ``gyrodenoise.units.RATE_TO_DEG_S``:
        "deg/s", "deg/h", "rad/s" or "mrad/s".
    sample_rate_hz : float, optional
        Sample rate: the rate when the file has no time column; with a time column,
        used when within 2 % of the column's count over span (a one-line error further off).
    true_column : str
        Name of the true-rate column (optional in the file).
    spike_advice : str
        The remedy a spike note names (default: the filters' outlier gate).
    time_unit : str, optional
        Unit of the time column (s, ms, us, ns); detected when not given
        (:func:`gyrodenoise.io.timebase.analyse_time`).
    """
    src = str(path)
    _check_arguments(rate_unit, sample_rate_hz, src)
    text = _open_text(path)
    if not text.strip():
        raise InputError("empty file", src)
    reader = csv.reader(io.StringIO(text))
    header = _read_header(reader, rate_column, time_column, src)
    i_rate = header.index(rate_column)
    i_time = header.index(time_column) if time_column in header else None
    i_true = header.index(true_column) if true_column in header else None
    if i_time is None and sample_rate_hz is None:
        raise InputError(f"line 1: no column '{time_column}' and no --sample-rate given", src)
    names = {i_rate: rate_column, i_time: time_column, i_true: true_column}
    cols = [i_rate] + ([i_time] if i_time is not None else []) + ([i_true] if i_true is not None else [])
    values = _read_values(reader, header, cols, names, src)
    n = len(values[i_rate])
    if n == 0:
        raise InputError("header only, no data rows", src)
    if n < MIN_SAMPLES:
        raise InputError(f"only {n} data row(s); at least {MIN_SAMPLES} are needed", src)
    scale = RATE_TO_DEG_S[rate_unit]
    rate = np.asarray(values[i_rate]) * scale
    true = np.asarray(values[i_true]) * scale if i_true is not None else None
    _check_rate_magnitude(rate, values[i_rate], text, rate_column, rate_unit, src)
    notes: list[str] = []
    ignored = [h for j, h in enumerate(header) if j not in (i_rate, i_time, i_true)]
    if ignored:
        notes.append(f"ignored columns: {', '.join(ignored)}")
    notes.extend(_signal_notes(rate, lambda i: _line_of(text, i), spike_advice))
    if i_time is None:
        assert sample_rate_hz is not None     # refused above when there is no time column either
        fs = float(sample_rate_hz)
        t = np.arange(n) / fs
        restarts = None
        notes.append(f"no column '{time_column}': rate {fs:g} Hz as stated (--sample-rate)")
    else:
        tb = analyse_time(values[i_time], unit=time_unit, nominal_rate=sample_rate_hz,
                          name=f"column {time_column}", source=src)
        fs, t = tb.rate_hz, tb.seconds(values[i_time])
        restarts = restart_mask(tb) if len(tb.runs) > 1 else None
        notes.append(tb.note)
    return Record(rate_deg_s=rate, sample_rate_hz=fs, time_s=t, true_rate_deg_s=true,
                  restarts=restarts, source=src, notes=notes)


def _check_arguments(rate_unit: str, sample_rate_hz: float | None, src: str) -> None:
    """InputError for a rate unit or a stated sample rate the reader cannot use."""
    if rate_unit not in RATE_TO_DEG_S:
        raise InputError(f"unknown rate unit {rate_unit!r} (use one of {', '.join(RATE_TO_DEG_S)})", src)
    if sample_rate_hz is not None and not (0 < sample_rate_hz <= MAX_RATE_HZ):
        raise InputError(f"--sample-rate {sample_rate_hz:g} Hz is not a sample rate (it must be above 0 and "
                         f"at most {MAX_RATE_HZ:g} Hz)", src)


def _read_header(reader: Iterator[list[str]], rate_column: str, time_column: str, src: str) -> list[str]:
    """The header row's column names; InputError when it cannot be read or has no rate
    column (saying why: no header at all, another field separator, another name)."""
    try:
        header = [h.strip() for h in next(reader)]
    except (StopIteration, csv.Error) as exc:
        raise InputError(f"line 1: cannot read the header ({exc})", src) from None
    if rate_column in header:
        return header
    if all(_is_number(h) for h in header):   # a row of numbers: no header at all
        raise InputError(f"line 1: no header row (expected column names such as "
                         f"'{time_column},{rate_column}')", src)
    if len(header) == 1 and any(sep in header[0] for sep in ";\t"):
        raise InputError(f"line 1: fields are not separated by commas ({header[0]!r}); "
                         f"a recording is a comma-separated CSV", src)
    raise InputError(f"line 1: no column '{rate_column}' (columns: {', '.join(header)}); "
                     f"use --rate-column", src)


def _read_values(reader: _CsvReader, header: list[str], cols: list[int], names: dict[int | None, str],
                 src: str) -> dict[int, list[float]]:
    """{column index: list of floats} of the columns ``cols`` over the data rows (blank
    lines skipped); InputError at the first short row, non-number, NaN or inf."""
    need = max(cols) + 1
    values: dict[int, list[float]] = {c: [] for c in cols}
    lineno = 1
    try:
        for row in reader:
            lineno = reader.line_num
            if not row or (len(row) == 1 and not row[0].strip()):
                continue
            if len(row) < need:
                raise InputError(f"line {lineno}: {len(row)} fields, expected {len(header)} "
                                 f"(truncated row?)", src)
            for c in cols:
                cell = row[c].strip()
                try:
                    v = float(cell)
                except ValueError:
                    raise InputError(f"line {lineno}: column {names[c]}: {cell!r} is not a number",
                                     src) from None
                if not math.isfinite(v):
                    raise InputError(f"line {lineno}: column {names[c]} is {cell}", src)
                values[c].append(v)
    except csv.Error as exc:
        raise InputError(f"line {lineno}: {exc}", src) from None
    return values


def _check_rate_magnitude(rate: np.ndarray, cells: list[float], text: str, rate_column: str, rate_unit: str,
                          src: str) -> None:
    """InputError at the first rate beyond ABSURD_RATE_DEG_S (deg/s, after the unit)."""
    big = np.flatnonzero(np.abs(rate) > ABSURD_RATE_DEG_S)
    if big.size:
        j = int(big[0])
        raise InputError(f"line {_line_of(text, j)}: column {rate_column}: {cells[j]!r} "
                         f"{rate_unit} is beyond {ABSURD_RATE_DEG_S:g} deg/s, not a gyro reading "
                         f"(wrong --rate-unit?)", src)


def _runs_at(x: np.ndarray, value: float, min_len: int) -> tuple[int, int]:
    """(count of samples, first index) in runs of >= min_len samples equal to value."""
    eq = np.concatenate([[False], x == value, [False]]).astype(np.int8)
    d = np.diff(eq)
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1)
    long_ = (ends - starts) >= min_len
    if not long_.any():
        return 0, -1
    return int(np.sum((ends - starts)[long_])), int(starts[long_][0])


def _signal_notes(rate: np.ndarray, line_of: Callable[[int], int] = lambda i: i + 2,
                  spike_advice: str = SPIKE_ADVICE) -> list[str]:
    """Reported (never repaired) properties of the rate column: constant,
    suspected saturation, isolated spikes."""
    notes = []
    lo, hi = float(rate.min()), float(rate.max())
    if lo == hi:
        return [f"the rate is constant ({lo:g} deg/s): nothing to denoise; the filter passes it "
                f"through (to 1e-6 relative); its Allan deviation is zero, so the fit reports only "
                f"(tiny) upper bounds"]
    for label, value in (("maximum", hi), ("minimum", lo)):
        count, first = _runs_at(rate, value, SAT_RUN)
        if count:
            notes.append(f"suspected saturation: {count} samples in runs of >= {SAT_RUN} equal values at "
                         f"the rate's {label} {value:g} deg/s (first at line {line_of(first)}, sample {first}); kept as is")
    if rate.size >= 3:
        d = np.diff(rate)
        sigma = 1.4826 * float(np.median(np.abs(d - np.median(d))))
        if sigma > 0:
            lim = SPIKE_SIGMAS * sigma
            a, b = rate[1:-1] - rate[:-2], rate[1:-1] - rate[2:]
            spikes = np.flatnonzero(((a > lim) & (b > lim)) | ((a < -lim) & (b < -lim))) + 1
            if spikes.size:
                notes.append(f"{spikes.size} isolated spike(s) of more than {SPIKE_SIGMAS:g} robust sigmas "
                             f"(first at line {line_of(int(spikes[0]))}, sample {int(spikes[0])}, {rate[spikes[0]]:g} deg/s); "
                             f"kept as is in the input; {spike_advice}")
    return notes


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _line_of(text: str, sample_index: int) -> int:
    """File line number of data sample ``sample_index`` (skipping blank lines)."""
    line = 1
    count = -1
    for line, raw in enumerate(text.splitlines(), start=1):
        if line == 1 or not raw.strip():
            continue
        count += 1
        if count == sample_index:
            return line
    return line


def write_recording(path: str | os.PathLike[str], time_s: npt.ArrayLike, raw_deg_s: npt.ArrayLike,
                    filtered_deg_s: npt.ArrayLike, true_rate_deg_s: npt.ArrayLike | None = None) -> None:
    """Write ``time,raw,filtered[,true_rate]`` (deg/s) to a CSV file."""
    cols = [np.asarray(time_s), np.asarray(raw_deg_s), np.asarray(filtered_deg_s)]
    header = "time,raw,filtered"
    if true_rate_deg_s is not None:
        cols.append(np.asarray(true_rate_deg_s))
        header += ",true_rate"
    try:
        np.savetxt(path, np.column_stack(cols), delimiter=",", header=header, comments="",
                   fmt="%.10g")
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror}", str(path)) from None
