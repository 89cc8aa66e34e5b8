"""A text recording's rate column, or its gyro and accelerometer axes, read in bounded
memory: a first pass that reads the file once (pyarrow's CSV engine, a batch at a time) into
binary spool files (every wanted column) and keeps only summaries, then passes that yield
chunks of (time s, rate, true rate, restarts) or (time s, each axis' values, restarts).

* the time model is :func:`gyrodenoise.io.timebase.analyse_column` over the spooled time
  column (a few passes, one chunk of steps at a time): the TimeBase of the whole-array
  reader, bit for bit;
* the signal notes (constant, suspected saturation, isolated spikes) and the magnitude
  check are those of :mod:`gyrodenoise.io.recording`, from running summaries: the same
  notes, except that beyond 2 M samples the spike test's robust sigma (the median absolute
  deviation of the sample-to-sample differences) is read from an evenly spread sample of
  1 to 2 M differences (``MEDIAN_SAMPLE``; the count and first spike are then those of
  that sigma);
* :meth:`RecordStream.chunks` yields the record a chunk at a time for consumers that carry
  their state (the Allan sums, the Denoiser's whole state, accumulators).

:func:`open_stream` answers None where it cannot promise the whole-array reader's result
(no pyarrow, a container, a separator or cell only the reader's own loop reads); so does
:func:`open_axes` (the columns of :func:`gyrodenoise.io.recording.read_axes`): the caller
then reads the file whole with :func:`gyrodenoise.io.recording.read_recording` or
:func:`gyrodenoise.io.recording.read_axes`.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyrodenoise.errors import InputError
from gyrodenoise.io import recording as R
from gyrodenoise.io.stream import CHUNK, EXACT_INT, csv_tables
from gyrodenoise.io.timebase import TimeColumn, analyse_column

#: bytes of text parsed at a time by the CSV engine (`csv_tables`: one block's buffers, whatever the length)
STREAM_BLOCK = 1 << 22
#: the spike test's sigma from every difference up to 2 x this many, beyond an evenly spread sample
MEDIAN_SAMPLE = 1_000_000


@dataclass
class Spool:
    """A column written to a binary file, read back a slice at a time."""
    path: Path
    dtype: np.dtype
    n: int = 0

    def append(self, v: np.ndarray) -> None:
        with open(self.path, "ab") as f:
            np.ascontiguousarray(v, dtype=self.dtype).tofile(f)
        self.n += v.shape[0]

    def read(self, a: int, b: int) -> np.ndarray:
        with open(self.path, "rb") as f:
            f.seek(a * self.dtype.itemsize)
            return np.fromfile(f, dtype=self.dtype, count=b - a)

    def write(self, at: int, v: np.ndarray) -> None:
        """Values ``v`` written at sample ``at`` (the file grown to hold them)."""
        with open(self.path, "r+b" if self.path.exists() else "w+b") as f:
            f.seek(at * self.dtype.itemsize)
            np.ascontiguousarray(v, dtype=self.dtype).tofile(f)
        self.n = max(self.n, at + len(v))


@dataclass
class SpoolSlice:
    """Samples ``a``..``b``-1 of a :class:`Spool` as the offline smoother reads and writes a
    record spilled to disk (:func:`gyrodenoise.core.batch.run_offline`): ``len()``, slices
    read as arrays, slice (or index) assignment written to the file, ``window(lo, hi)``."""
    spool: Spool
    a: int = 0
    b: int | None = None

    def __post_init__(self) -> None:
        if self.b is None:
            self.b = self.spool.n

    def __len__(self) -> int:
        return int(self.b) - self.a

    def _span(self, key: slice) -> tuple[int, int]:
        lo, hi, step = key.indices(len(self))
        if step != 1:
            raise ValueError("a spooled record slices with step 1")
        return self.a + lo, self.a + max(lo, hi)

    def __getitem__(self, key: slice) -> np.ndarray:
        return self.spool.read(*self._span(key))

    def __setitem__(self, key, v) -> None:
        if isinstance(key, slice):
            lo, hi = self._span(key)
            self.spool.write(lo, np.broadcast_to(np.asarray(v, dtype=self.spool.dtype), (hi - lo,)))
            return
        idx = np.asarray(key).ravel()
        for i, x in zip(idx.tolist(), np.broadcast_to(np.asarray(v, dtype=self.spool.dtype), idx.shape).tolist()):
            self.spool.write(self.a + int(i), np.array([x]))

    def window(self, lo: int, hi: int) -> SpoolSlice:
        return SpoolSlice(self.spool, self.a + lo, self.a + hi)


@dataclass
class StreamAxis:
    """One spooled column of a :class:`RecordStream` (the attributes of
    :class:`gyrodenoise.io.recording.Axis`, its values on disk)."""
    column: str
    kind: R.SensorKind
    unit: str                      # the unit it was read in
    unit_how: str                  # how the unit was decided
    scale: float | None            # the --rate-scale / --accel-scale factor (None: not given)
    values: Spool = field(repr=False)


@dataclass
class RecordStream:
    """A recording's columns (one rate column, or several gyro and accelerometer axes), its
    notes and time model, read a chunk at a time."""
    source: str
    sample_rate_hz: float
    n: int
    notes: list[str]
    axes: tuple[StreamAxis, ...] = field(repr=False)
    true: Spool | None = field(repr=False)
    time: Spool | None = field(repr=False)
    timebase: object = field(repr=False)
    folder: str = field(repr=False)
    time_as_float: bool = False

    def __len__(self) -> int:
        return self.n

    @property
    def rate(self) -> Spool:
        """The first axis' spooled values (the rate column of a one-column read)."""
        return self.axes[0].values

    @property
    def unit(self) -> str:
        return self.axes[0].unit

    @property
    def unit_how(self) -> str:
        return self.axes[0].unit_how

    @property
    def has_true(self) -> bool:
        return self.true is not None

    @property
    def restarts(self) -> np.ndarray | None:
        """The whole-record restart mask (1 byte a sample), None without a restart."""
        tb = self.timebase
        return tb.restarts_in(0, self.n) if tb is not None and len(tb.runs) > 1 else None

    def axis_chunks(self, size: int | None = None) -> Iterator[tuple[np.ndarray, list[np.ndarray],
                                                                     np.ndarray | None]]:
        """(time s, [each axis' values], restarts or None) a chunk at a time: the whole-array
        reader's arrays at those samples, bit for bit."""
        size = int(size or CHUNK)
        tb = self.timebase
        for a in range(0, self.n, size):
            b = min(a + size, self.n)
            if self.time is None:
                t = np.arange(a, b) / self.sample_rate_hz
                restarts = None
            else:
                raw = self.time.read(a, b)
                t = tb.seconds_of_chunk(raw.astype(np.float64) if self.time_as_float else raw)
                restarts = tb.restarts_in(a, b) if len(tb.runs) > 1 else None
            yield t, [ax.values.read(a, b) for ax in self.axes], restarts

    def chunks(self, size: int | None = None) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray | None,
                                                                np.ndarray | None]]:
        """(time s, rate, true rate or None, restarts or None) of the first axis a chunk at a time."""
        size = int(size or CHUNK)
        for a, (t, vals, restarts) in zip(range(0, self.n, size), self.axis_chunks(size)):
            yield t, vals[0], (self.true.read(a, a + len(t)) if self.true else None), restarts

    def values(self, axis: int = 0, size: int | None = None) -> Iterator[np.ndarray]:
        """One axis' values a chunk at a time (the time column not read)."""
        size = int(size or CHUNK)
        sp = self.axes[axis].values
        for a in range(0, self.n, size):
            yield sp.read(a, min(a + size, self.n))

    def rates(self, size: int | None = None) -> Iterator[np.ndarray]:
        return self.values(0, size)

    def close(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)

    def __enter__(self) -> RecordStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_stream(path: str | os.PathLike[str], rate_column: str = "rate", time_column: str | None = None,
                rate_unit: str | None = None, sample_rate_hz: float | None = None,
                true_column: str = "true_rate", spike_advice: str = R.SPIKE_ADVICE,
                time_unit: str | None = None, chunk: int | None = None,
                spill_dir: str | None = None, rate_scale: float | None = None,
                skip_rows: int = 0) -> RecordStream | None:
    """The :class:`RecordStream` of one rate column (parameters as
    :func:`gyrodenoise.io.recording.read_recording`), or None where the whole-array reader
    must read the file (module docstring). ``chunk``: samples per chunk of the passes;
    ``rate_scale``: the rates' factor (``--rate-scale``, one column); ``skip_rows``: lines
    skipped before the header row (``--skip-rows``, :func:`gyrodenoise.io.recording.text_layout`)."""
    return open_axes(path, [rate_column], None, time_column=time_column, rate_unit=rate_unit,
                     sample_rate_hz=sample_rate_hz, true_column=true_column, spike_advice=spike_advice,
                     time_unit=time_unit, chunk=chunk, spill_dir=spill_dir, rate_scale=rate_scale,
                     skip_rows=skip_rows)


def open_axes(path: str | os.PathLike[str], rate_columns: Sequence[str] | None = None,
              accel_columns: Sequence[str] | None = None, *, time_column: str | None = None,
              rate_unit: str | None = None, accel_unit: str | None = None, sample_rate_hz: float | None = None,
              true_column: str = "true_rate", spike_advice: str = R.SPIKE_ADVICE,
              time_unit: str | None = None, chunk: int | None = None, spill_dir: str | None = None,
              rate_scale: Sequence[float] | float | None = None,
              accel_scale: Sequence[float] | float | None = None, skip_rows: int = 0) -> RecordStream | None:
    """The :class:`RecordStream` of the gyro (and accelerometer) columns that
    :func:`gyrodenoise.io.recording.read_axes` reads (the same parameters, the same choice
    of columns, notes and checks), every column spooled in one pass; or None where the
    whole-array reader must read the file (module docstring; also: three accelerometer
    axes whose median |a| the counts cannot place inside gravity's band: the reader then
    refuses them, or reads them, itself)."""
    try:
        import pyarrow as pa
    except ImportError:
        return None
    src = str(path)
    if R.is_container(path):
        return None
    R._check_arguments(rate_unit, accel_unit, sample_rate_hz, src)
    first = (rate_columns or ["rate"])[0]
    lay = R.text_layout(path, first, time_column, src, skip_rows)
    text, sep, header, file_units, skip = lay.text, lay.sep, lay.header, lay.file_units, lay.skip
    if sep not in (",", ";", "\t"):
        return None
    lower = R._names(header)
    rate_columns = [lower.get(c.lower(), c) if c not in header else c for c in rate_columns or []] or None
    accel_columns = [lower.get(c.lower(), c) if c not in header else c for c in accel_columns] \
        if accel_columns else accel_columns
    if any(c not in header for c in [*(rate_columns or []), *(accel_columns or [])]):
        return None                                  # the reader says which
    if rate_columns is None and "rate" not in header and not R._detected(R.GYRO, lower)[0]:
        return None
    gyro_cols, gyro_group = R._columns(R.GYRO, rate_columns, header, lower, "rate", src)
    if accel_columns is None and rate_columns is None and gyro_group is not None:
        accel_cols, accel_group = R._detected(R.ACCEL, lower)
    else:
        accel_cols, accel_group = R._columns(R.ACCEL, accel_columns or [], header, lower, None, src)
    counts_of = {R.GYRO.name: R.rate_scales(rate_scale, gyro_cols, src),
                 R.ACCEL.name: R._scales(accel_scale, accel_cols, "--accel-scale", "accelerometer", src)}
    if time_column is None:
        time_column = next((lower[c] for c in R.TIME_COLUMNS if c in lower), "time")
    elif time_column not in header:
        time_column = lower.get(time_column.lower(), time_column)
    has_time = time_column in header
    has_true = len(gyro_cols) == 1 and true_column in header
    if not has_time and sample_rate_hz is None:
        return None
    data_cols = [*gyro_cols, *accel_cols]
    wanted = data_cols + ([time_column] if has_time else []) + ([true_column] if has_true else [])
    if len(set(wanted)) != len(wanted):
        return None
    names = [f"f{i}" for i in range(len(header))]
    col_of = {c: names[header.index(c)] for c in wanted}
    head = text.lines()
    if any(not next(head, "").strip() for _ in range(skip)):
        return None
    head.close()
    text.check_decodable()
    unit_notes, plan = [], []             # plan: (column, kind, unit, how, --*-scale factor, factor to internal)
    for kind, cols, group, stated in ((R.GYRO, gyro_cols, gyro_group, rate_unit),
                                      (R.ACCEL, accel_cols, accel_group, accel_unit)):
        if not cols:
            continue
        unit, why = R.column_unit(kind, cols, stated, file_units, lay.units_from, group, src)
        counts = counts_of[kind.name]
        unit_notes.append(R.unit_note(kind, cols, unit, why, counts))
        plan += [(c, kind, unit, why, counts[i] if counts else None, kind.units[unit] * (counts[i] if counts else 1.0))
                 for i, c in enumerate(cols)]
    gravity = _GravityCount() if len(accel_cols) == 3 and not (
        accel_unit or file_units.get(accel_cols[0])) else None
    folder = tempfile.mkdtemp(prefix="gd_stream_", dir=spill_dir)
    ok = False
    try:
        spools = [Spool(Path(folder) / f"axis{i}", np.dtype(np.float64)) for i in range(len(plan))]
        stats = [_RateStats() for _ in plan]
        true = Spool(Path(folder) / "true", np.dtype(np.float64)) if has_true else None
        time = None
        big_all, big_any = True, False
        types = {col_of[c]: pa.float64() for c in wanted if c != time_column}
        reader = csv_tables(text, skip, names, sep, sorted(set(col_of.values())), types, STREAM_BLOCK)
        if reader is None:
            return None
        try:
            for batch in reader:
                cols = {}
                for c in wanted:
                    a = batch.column(col_of[c])
                    if a.null_count or a.type not in (pa.float64(), pa.int64()):
                        return None
                    v = a.to_numpy(zero_copy_only=False)
                    if v.dtype.kind == "f" and not np.isfinite(v).all():
                        return None
                    cols[c] = v
                if has_time:
                    t = cols[time_column]
                    if time is None:
                        time = Spool(Path(folder) / "time", t.dtype)
                    if t.dtype != time.dtype:
                        return None
                    if t.dtype.kind == "i":
                        big = t >= EXACT_INT
                        big_all = big_all and bool(big.all())
                        big_any = big_any or bool((np.abs(t) >= EXACT_INT).any())
                    time.append(t)
                scaled = []
                for (c, kind, *_, factor), sp, st in zip(plan, spools, stats):
                    v = np.asarray(cols[c], dtype=np.float64) * factor
                    st.add(v, cols[c], kind)
                    sp.append(v)
                    scaled.append((kind, v))
                if gravity is not None:
                    gravity.add([v for kind, v in scaled if kind is R.ACCEL])
                if true is not None:
                    true.append(np.asarray(cols[true_column], dtype=np.float64) * plan[0][-1])
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError, pa.ArrowTypeError):
            return None
        n = spools[0].n
        if n == 0 or n < R.MIN_SAMPLES:
            return None                              # the reader says why
        time_as_float = time is not None and time.dtype.kind == "i" and not big_all
        if time_as_float and big_any:
            return None                              # a mix of exact and float integers: the loop's
        where = lambda i: f"line {text.line_of(i, skip)}"   # noqa: E731
        for (c, kind, unit, *_), st in zip(plan, stats):
            if st.beyond is not None:
                j, cell = st.beyond
                raise InputError(f"{where(j)}: column {c}: {float(cell)!r} "
                                 f"{unit} is beyond {kind.absurd:g} {kind.internal}, not a {kind.name} reading "
                                 f"(wrong {kind.option}?)", src)
        if gravity is not None and not gravity.inside():
            return None                              # the reader's own check (its median) says what
        notes = lay.notes + unit_notes
        ignored = [h for h in header if h not in wanted and h]
        if ignored:
            shown = ", ".join(ignored[:8]) + (f", ... ({len(ignored)} in all)" if len(ignored) > 8 else "")
            notes.append(f"ignored columns: {shown}")
        for (c, kind, *_), sp, st in zip(plan, spools, stats):
            for note in _signal_notes(sp, st, where, spike_advice, kind.internal, chunk):
                notes.append(note if len(plan) == 1 else f"column {c}: {note}")
        tb = None
        if not has_time:
            fs = float(sample_rate_hz)
            notes.append(f"no column '{time_column}': rate {fs:g} Hz as stated (--sample-rate)")
        else:
            if time_unit is None and file_units.get(time_column) in R.TIME_UNIT_NAMES:
                time_unit = file_units[time_column]
            read = (lambda a, b: time.read(a, b).astype(np.float64)) if time_as_float else time.read
            first_t = read(0, 1)[0]
            tb = analyse_column(TimeColumn(n, first_t, read, chunk, exact_int=not time_as_float and
                                           time.dtype.kind == "i"),
                                unit=time_unit, nominal_rate=sample_rate_hz, name=f"column {time_column}", source=src)
            fs = tb.rate_hz
            notes.append(tb.note)
        axes = tuple(StreamAxis(c, kind, unit, why, counts, sp)
                     for (c, kind, unit, why, counts, _), sp in zip(plan, spools))
        ok = True
        return RecordStream(source=src, sample_rate_hz=fs, n=n, notes=notes, axes=axes, true=true, time=time,
                            timebase=tb, folder=folder, time_as_float=time_as_float)
    finally:
        if not ok:
            shutil.rmtree(folder, ignore_errors=True)


class _GravityCount:
    """Whether the median of |a| over three accelerometer axes lies inside
    ``recording.GRAVITY_M_S2`` (`recording._check_gravity`), from counts of the norms below
    and above that band: a median (the mean of the two middle values when the count is
    even) inside when the middle values are; False when the counts cannot say so."""

    def __init__(self) -> None:
        self.below = self.above = self.n = 0

    def add(self, axes: list[np.ndarray]) -> None:
        norm = np.sqrt(sum(a ** 2 for a in axes))      # `_check_gravity`'s sum, in its order
        lo, hi = R.GRAVITY_M_S2
        self.below += int(np.count_nonzero(norm < lo))
        self.above += int(np.count_nonzero(norm > hi))
        self.n += norm.size

    def inside(self) -> bool:
        k = self.n // 2
        room = k if self.n % 2 else k - 1          # values allowed outside on each side
        return self.below <= room and self.above <= room


class _RateStats:
    """Running min, max and the first value beyond the kind's absurd magnitude."""

    def __init__(self) -> None:
        self.lo, self.hi, self.n = np.inf, -np.inf, 0
        self.beyond: tuple[int, float] | None = None

    def add(self, v: np.ndarray, cells: np.ndarray, kind: R.SensorKind) -> None:
        if v.size:
            self.lo, self.hi = min(self.lo, float(v.min())), max(self.hi, float(v.max()))
        if self.beyond is None:
            big = np.flatnonzero(np.abs(v) > kind.absurd)
            if big.size:
                self.beyond = (self.n + int(big[0]), cells[int(big[0])])
        self.n += v.size


def _runs_at(rate: Spool, value: float, min_len: int, size: int) -> tuple[int, int]:
    """(count of samples, first index) in runs of >= min_len samples equal to value
    (`recording._runs_at`, a chunk at a time: the run open at a chunk's end carried)."""
    count, first = 0, -1
    run, start = 0, 0                 # the run open at the last chunk's end (length, first index)

    def close(s_abs: int, length: int) -> None:
        nonlocal count, first
        if length >= min_len:
            count += length
            first = s_abs if first < 0 else first

    for a in range(0, rate.n, size):
        eq = rate.read(a, min(a + size, rate.n)) == value
        if run and not eq[0]:
            close(start, run)
            run = 0
        d = np.diff(np.concatenate([[False], eq, [False]]).astype(np.int8))
        for s, e in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
            s_abs, length = (start, run + int(e)) if s == 0 and run else (a + int(s), int(e - s))
            run = 0
            if e == eq.size:          # still open
                run, start = length, s_abs
            else:
                close(s_abs, length)
    if run:
        close(start, run)
    return count, first


def _signal_notes(rate: Spool, stats: _RateStats, where, spike_advice: str, unit: str,
                  chunk: int | None) -> list[str]:
    """`recording._signal_notes` from a chunk at a time (module docstring)."""
    size = int(chunk or CHUNK)
    lo, hi, n = stats.lo, stats.hi, rate.n
    sat = [(label, value, *_runs_at(rate, value, R.SAT_RUN, size)) for label, value in (("maximum", hi),
                                                                                        ("minimum", lo))]
    spikes = None
    if lo != hi and n >= 3:
        s = max(1, (n - 1) // MEDIAN_SAMPLE)
        sample, seen = [], 0
        for a in range(0, n - 1, size):
            d = np.diff(rate.read(a, min(a + size, n - 1) + 1))
            sample.append(d[(-seen) % s::s].copy())      # a copy: a view would hold the whole chunk
            seen += d.size
        d = np.concatenate(sample)
        sigma = 1.4826 * float(np.median(np.abs(d - np.median(d))))
        del d, sample
        if sigma > 0:
            lim = R.SPIKE_SIGMAS * sigma
            count, first = 0, None
            for a in range(1, n - 1, size):
                b = min(a + size, n - 1)
                x = rate.read(a - 1, b + 1)
                da, db = x[1:-1] - x[:-2], x[1:-1] - x[2:]
                hit = np.flatnonzero(((da > lim) & (db > lim)) | ((da < -lim) & (db < -lim)))
                if hit.size and first is None:
                    first = (a + int(hit[0]), float(x[1 + int(hit[0])]))
                count += hit.size
            if count:
                spikes = (count, *first)
    return R.signal_note_texts(lo, hi, sat, spikes, where, spike_advice, unit)
