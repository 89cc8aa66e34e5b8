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
import itertools
import math
import os
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any
from pathlib import Path

import numpy as np
import numpy.typing as npt

from gyrodenoise.errors import InputError
from gyrodenoise.io.stream import TextFile, check_regular, numeric_columns, save_columns
from gyrodenoise.io.timebase import MAX_RATE_HZ, analyse_time, restart_mask
from gyrodenoise.simulator import Record
from gyrodenoise.units import ACCEL_TO_M_S2, RATE_TO_DEG_S

MIN_SAMPLES = 2
ABSURD_RATE_DEG_S = 1.0e6   # 2,800 rev/s: no gyro measures that
ABSURD_ACCEL_M_S2 = 1.0e5   # 10,000 g: no accelerometer of an IMU measures that
SAT_RUN = 10                # equal samples at the column's max/min: suspected saturation
SPIKE_SIGMAS = 8.0          # isolated spike: this many robust sigmas from both neighbours


#: what a spike note advises (the filters' outlier gate); a command with another remedy passes its own
SPIKE_ADVICE = ("with --method shakf, kf or sh_classic the outlier gate (--outlier-sigma) keeps single "
                "wild samples out of the filter")


@dataclass(frozen=True)
class SensorKind:
    """What a column measures: its unit inside (``internal``), the units it may be read in
    (label -> factor to ``internal``), the column names that identify it (groups of axes,
    the first that the file holds wins; a group may imply its unit) and the magnitude
    beyond which a value is no reading."""
    name: str
    internal: str
    units: Mapping[str, float]
    groups: tuple[ColumnGroup, ...]
    absurd: float
    option: str            # the command-line option naming its unit
    scale_option: str      # the command-line option giving its unit per count (raw counts)


@dataclass(frozen=True)
class ColumnGroup:
    """Column names of the axes of one sensor as a file names them; ``unit``: the unit the
    names imply (ROS ``sensor_msgs/Imu`` is in SI, REP 103), with ``why``."""
    names: tuple[str, ...]
    unit: str | None = None
    why: str = ""


def _xyz(prefix: str, unit: str | None = None, why: str = "") -> ColumnGroup:
    return ColumnGroup(tuple(f"{prefix}{a}" for a in "xyz"), unit, why)


_ROS = "sensor_msgs/Imu, REP 103"
GYRO = SensorKind("gyro", "deg/s", RATE_TO_DEG_S, (
    _xyz("field.angular_velocity.", "rad/s", f"{_ROS}: rad/s"), _xyz("angular_velocity.", "rad/s", f"{_ROS}: rad/s"),
    _xyz("angular_velocity_", "rad/s", f"{_ROS}: rad/s"),
    _xyz("gyro_"), _xyz("gyr_"), _xyz("gyro"), _xyz("g"), _xyz("w")), ABSURD_RATE_DEG_S, "--rate-unit",
    "--rate-scale")
ACCEL = SensorKind("accel", "m/s^2", ACCEL_TO_M_S2, (
    _xyz("field.linear_acceleration.", "m/s^2", f"{_ROS}: m/s^2"),
    _xyz("linear_acceleration.", "m/s^2", f"{_ROS}: m/s^2"), _xyz("linear_acceleration_", "m/s^2", f"{_ROS}: m/s^2"),
    _xyz("accel_"), _xyz("acc_"), _xyz("accel"), _xyz("acc"), _xyz("a")), ABSURD_ACCEL_M_S2, "--accel-unit",
    "--accel-scale")

#: time column names tried in order when none is given: ours, a ROS message's own stamp and
#: ``rostopic echo -p``'s receive time (both ns since 1970), common others
TIME_COLUMNS = ("time", "field.header.stamp", "%time", "timestamp", "t")


@dataclass(frozen=True)
class Axis:
    """One column of a recording: ``values`` in its kind's internal unit (deg/s, m/s^2)."""
    column: str
    kind: SensorKind
    unit: str                  # the unit it was read in
    values: np.ndarray = field(repr=False)
    true: np.ndarray | None = field(default=None, repr=False)
    unit_how: str = ""         # how the unit was decided, as the note says it ("as stated", "assumed; ...")
    scale: float | None = None  # the --rate-scale / --accel-scale factor it was multiplied by (None: not given)


@dataclass
class Recording:
    """The axes of a file on one time base (the notes cover all of them)."""
    source: str
    sample_rate_hz: float
    time_s: np.ndarray = field(repr=False)
    restarts: np.ndarray | None = field(repr=False)
    axes: tuple[Axis, ...]
    notes: list[str]

    def record(self, axis: Axis) -> Record:
        """The `Record` of one axis (``rate_deg_s`` in the axis kind's internal unit: m/s^2
        for an accelerometer) for the filters and the Allan analysis."""
        return Record(rate_deg_s=axis.values, sample_rate_hz=self.sample_rate_hz, time_s=self.time_s,
                      true_rate_deg_s=axis.true, restarts=self.restarts, source=self.source, notes=self.notes,
                      unit=axis.unit, unit_how=axis.unit_how)


def read_recording(path: str | os.PathLike[str], rate_column: str = "rate", time_column: str | None = None,
                   rate_unit: str | None = None, sample_rate_hz: float | None = None,
                   true_column: str = "true_rate", spike_advice: str = SPIKE_ADVICE,
                   time_unit: str | None = None, rate_scale: Sequence[float] | float | None = None,
                   skip_rows: int = 0) -> Record:
    """Read one rate column of a recording into a `Record` (rates in deg/s).

    Parameters
    ----------
    path : str or Path
        CSV (optionally gzip-compressed) with a header row; fields separated by commas,
        semicolons, tabs or spaces (decimal commas read when the separator is not a comma).
    rate_column : str
        Name of the rate column.
    time_column : str, optional
        Name of the time column; default the first of `TIME_COLUMNS` in the file. Optional
        when ``sample_rate_hz`` is given.
    rate_unit : str, optional
        Unit of the rate and true-rate columns, a key of ``gyrodenoise.units.RATE_TO_DEG_S``:
        "deg/s", "deg/h", "rad/s" or "mrad/s"; default deg/s (said in a note).
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
    rate_scale : float or sequence of float, optional
        Multiply each rate by this first (raw counts: the unit per count, e.g. deg/s per
        LSB); the product is in ``rate_unit``. Said in a note.
    skip_rows : int
        Lines skipped before the header row is looked for (``--skip-rows``: a preamble
        the automatic detection refuses); said in a note.
    """
    rec = read_axes(path, [rate_column], time_column=time_column, rate_unit=rate_unit,
                    sample_rate_hz=sample_rate_hz, true_column=true_column, spike_advice=spike_advice,
                    time_unit=time_unit, rate_scale=rate_scale, skip_rows=skip_rows)
    return rec.record(rec.axes[0])


def read_axes(path: str | os.PathLike[str], rate_columns: Sequence[str] | None = None,
              accel_columns: Sequence[str] | None = None, *, time_column: str | None = None,
              rate_unit: str | None = None, accel_unit: str | None = None, sample_rate_hz: float | None = None,
              true_column: str = "true_rate", spike_advice: str = SPIKE_ADVICE,
              time_unit: str | None = None, topic: str | None = None, variable: str | None = None,
              bag_reader: Callable[..., Any] | None = None,
              rate_scale: Sequence[float] | float | None = None,
              accel_scale: Sequence[float] | float | None = None, skip_rows: int = 0) -> Recording:
    """Read the gyro (and accelerometer) columns of a recording CSV on one time base.

    ``rate_columns`` None: ``rate`` when the file has it, else the first group of gyro
    columns of `GYRO` it holds (gyro_x/y/z, gx/gy/gz, field.angular_velocity.x/y/z ...),
    and then the accelerometer columns of `ACCEL` too unless ``accel_columns`` names them.
    The true-rate column is read with a single rate column only. Other parameters as
    :func:`read_recording`; ``accel_unit`` a key of ``ACCEL_TO_M_S2`` (default m/s^2).
    A ROS bag or MCAP file (``topic``; ``bag_reader``: pass
    :func:`gyrodenoise.flightlog.rosbag.read_imu`) and a MATLAB ``.mat`` file (``variable``)
    are read by :mod:`gyrodenoise.io.containers` into the same columns. ``rate_scale``: one
    factor for every gyro column or one per column (:func:`read_recording`); ``accel_scale``
    the same for the accelerometer columns (raw counts: the unit per count, the product in
    ``accel_unit``). ``skip_rows``: lines skipped before the header row is looked for
    (:func:`text_layout`).

    A text file may hold free-text lines before its header row (a preamble: `PREAMBLE_MAX`
    lines at most; the header row holds no number): they are skipped and said in a note. A unit after a column's name (``gyro_x (deg/s)``, ``time [s]``) is read
    as a units row is; the name without it finds the column too.
    """
    src = str(path)
    _check_arguments(rate_unit, accel_unit, sample_rate_hz, src)
    first = (rate_columns or ["rate"])[0]
    container = topic is not None or variable is not None or is_container(path)
    file_units: dict[str, str] = {}
    units_from = ""
    if container:
        from gyrodenoise.io.containers import read_container
        table = read_container(path, topic=topic, variable=variable, bag_reader=bag_reader)
        header, notes = list(table.columns), list(table.notes)
        where: Callable[[int], str] = lambda i: f"{table.row_name} {i + 1:,}"   # noqa: E731
    else:
        lay = text_layout(path, first, time_column, src, skip_rows)
        text, sep, header, rows, file_units, units_from, skip = (lay.text, lay.sep, lay.header, lay.rows,
                                                                 lay.file_units, lay.units_from, lay.skip)
        notes = list(lay.notes)
        where = lambda i: f"line {text.line_of(i, skip)}"   # noqa: E731
    lower = _names(header)
    rate_columns = [lower.get(c.lower(), c) if c not in header else c for c in rate_columns or []] or None
    accel_columns = [lower.get(c.lower(), c) if c not in header else c for c in accel_columns] \
        if accel_columns else accel_columns
    gyro_cols, gyro_group = _columns(GYRO, rate_columns, header, lower, "rate", src)
    scales = {GYRO.name: rate_scales(rate_scale, gyro_cols, src)}
    if accel_columns is None and rate_columns is None and gyro_group is not None:
        accel_cols, accel_group = _detected(ACCEL, lower)
    else:
        accel_cols, accel_group = _columns(ACCEL, accel_columns or [], header, lower, None, src)
    scales[ACCEL.name] = _scales(accel_scale, accel_cols, "--accel-scale", "accelerometer", src)
    if time_column is None:
        time_column = next((lower[c] for c in TIME_COLUMNS if c in lower), "time")
    elif time_column not in header:
        time_column = lower.get(time_column.lower(), time_column)
    has_time = time_column in header
    has_true = len(gyro_cols) == 1 and true_column in header
    if not has_time and sample_rate_hz is None:
        raise InputError(f"line 1: no column '{time_column}' and no --sample-rate given", src)
    wanted = [*gyro_cols, *accel_cols] + ([time_column] if has_time else []) + ([true_column] if has_true else [])
    if container:
        values: dict[str, Any] = {c: table.columns[c] for c in wanted}
    else:
        index = {name: header.index(name) for name in wanted}
        values = (numeric_columns(text, skip, len(header), index, sep, time_column if has_time else None)
                  or _read_values(rows, header, index, sep != ",", src))
        if values.pop(DECIMAL_COMMA, None) is not None:
            notes[-1] += "; decimal commas read"
    n = len(values[wanted[0]])
    if n == 0:
        raise InputError("header only, no data rows", src)
    if n < MIN_SAMPLES:
        raise InputError(f"only {n} data row(s); at least {MIN_SAMPLES} are needed", src)
    axes = []
    for kind, cols, group, unit in ((GYRO, gyro_cols, gyro_group, rate_unit),
                                    (ACCEL, accel_cols, accel_group, accel_unit)):
        if not cols:
            continue
        unit, why = column_unit(kind, cols, unit, file_units, units_from, group, src)
        counts = scales[kind.name]
        notes.append(unit_note(kind, cols, unit, why, counts))
        for i, c in enumerate(cols):
            scale = kind.units[unit] * (counts[i] if counts else 1.0)
            v = np.asarray(values[c], dtype=np.float64) * scale
            _check_magnitude(kind, v, values[c], where, c, unit, src)
            true = np.asarray(values[true_column], dtype=np.float64) * scale if has_true else None
            axes.append(Axis(c, kind, unit, v, true, unit_how=why, scale=counts[i] if counts else None))
    _check_gravity([a for a in axes if a.kind is ACCEL], accel_unit or file_units.get(accel_cols[0]) if accel_cols
                   else None, src, scaled=accel_scale is not None)
    ignored = [h for h in header if h not in wanted and h]
    if ignored:
        shown = ", ".join(ignored[:8]) + (f", ... ({len(ignored)} in all)" if len(ignored) > 8 else "")
        notes.append(f"ignored columns: {shown}")
    for ax in axes:
        for note in _signal_notes(ax.values, where, spike_advice, ax.kind.internal):
            notes.append(note if len(axes) == 1 else f"column {ax.column}: {note}")
    if not has_time:
        assert sample_rate_hz is not None     # refused above when there is no time column either
        fs = float(sample_rate_hz)
        t = np.arange(n) / fs
        restarts = None
        notes.append(f"no column '{time_column}': rate {fs:g} Hz as stated (--sample-rate)")
    else:
        if time_unit is None and file_units.get(time_column) in TIME_UNIT_NAMES:
            time_unit = file_units[time_column]
        tb = analyse_time(values[time_column], unit=time_unit, nominal_rate=sample_rate_hz,
                          name=f"column {time_column}", source=src)
        fs, t = tb.rate_hz, tb.seconds(values[time_column])
        restarts = restart_mask(tb) if len(tb.runs) > 1 else None
        notes.append(tb.note)
    return Recording(source=src, sample_rate_hz=fs, time_s=t, restarts=restarts, axes=tuple(axes), notes=notes)


@dataclass
class TextLayout:
    """Where a text recording's columns are: its ``sep`` (None: runs of spaces), ``header``
    (the names as written) and ``lower`` (:func:`_names`), the units it says per column
    (``file_units``, from ``units_from``: its units row or its header), ``skip`` (the lines
    before the first data row), the ``notes`` on its layout (separator, preamble) and the
    data ``rows`` after the header (an iterator over the text)."""
    text: TextFile
    sep: str | None
    header: list[str]
    lower: dict[str, str]
    file_units: dict[str, str]
    units_from: str
    skip: int
    notes: list[str]
    rows: Iterator[tuple[int, list[str]]]


def text_layout(path: str | os.PathLike[str], first_column: str, time_column: str | None,
                src: str, skip_rows: int = 0) -> TextLayout:
    """The :class:`TextLayout` of a text recording (the whole-array reader's and the chunked
    reader's, :mod:`gyrodenoise.io.chunked`). ``skip_rows``: lines skipped before the header
    row is looked for (``--skip-rows``: a preamble the automatic detection refuses, such as
    free text before a header row that holds a number), said in a note. InputError for an
    empty file, no header, nothing after the skipped lines, or a header row without the
    column while a later line names it (a preamble: the line says which ``--skip-rows``)."""
    text = TextFile(path)
    if not text.first_line():
        raise InputError("empty file", src)
    if skip_rows < 0:
        raise InputError(f"--skip-rows {skip_rows}: give a number of lines, 0 or more", src)
    head = list(itertools.islice(text.lines(), skip_rows + PREAMBLE_MAX + 4))
    skipped, head = head[:skip_rows], head[skip_rows:]
    if not "".join(head).strip():
        raise InputError(f"--skip-rows {skip_rows}: no header row after the first {skip_rows} line(s) "
                         f"(the file holds {len(skipped)} line(s) with nothing after them)", src)
    header_text, preamble = _after_preamble("".join(head))
    sep = _separator(header_text)
    before = len(header_text) - len(header_text.lstrip("\n"))     # the preamble's lines, blanked
    rows = _rows(text, sep, src, skip_rows + (before if preamble else 0))
    header_line, header = _read_header(rows, first_column, time_column or "time", src)
    _check_not_preamble(header, header_line, head, skip_rows, first_column, time_column, src)
    notes = [] if sep == "," else [f"fields separated by {SEPARATOR_NAMES[sep]}"]
    if skip_rows:
        notes.append(skipped_note(skipped, skip_rows))
    if preamble:
        notes.append(preamble_note(preamble))
    rows, file_units = _units_row(rows, header)
    units_from = "its units row" if file_units else "its header"
    file_units = file_units or _header_units(header)
    skip = header_line + (1 if units_from == "its units row" else 0)
    return TextLayout(text, sep, header, _names(header), file_units, units_from, skip, notes, rows)


def skipped_note(skipped: Sequence[str], skip_rows: int) -> str:
    """The note of the lines ``--skip-rows`` skipped."""
    shown = [ln.strip() for ln in skipped if ln.strip()]
    text = "; ".join(shown[:6]) + (f"; ... ({len(shown)} with text)" if len(shown) > 6 else "")
    return f"{skip_rows} line(s) skipped before the header row (--skip-rows {skip_rows})" + (f": {text}" if text
                                                                                             else "")


def _known_names(first_column: str, time_column: str | None) -> set[str]:
    """The lower-case column names a header row of a recording may hold: the column asked
    for, the time columns and the gyro columns the reader detects."""
    return {first_column.lower(), (time_column or "time").lower(), *TIME_COLUMNS,
            *(n for g in GYRO.groups for n in g.names)}


def _check_not_preamble(header: list[str], header_line: int, head: Sequence[str], skip_rows: int,
                        first_column: str, time_column: str | None, src: str) -> None:
    """InputError naming ``--skip-rows`` when the header row read holds none of the names a
    recording's header holds while a later line among ``head`` (the lines after the skipped
    ones) does: free text before the header row that the preamble detection refused (a
    header row with a number in it)."""
    known = _known_names(first_column, time_column)
    if known & set(_names(header)):
        return
    for i, line in enumerate(head):
        lineno = skip_rows + i + 1
        if lineno <= header_line or not line.strip():
            continue
        cells = _fields(line, _separator(line))
        if _is_data(cells, _separator(line)):
            return                      # the data rows begin: no header row after the one read
        if known & set(_names(cells)):
            raise InputError(f"line {header_line}: no column '{first_column}' (columns: {', '.join(header[:8])}); "
                             f"line {lineno} names columns ({', '.join(cells[:8])}): free text before the header "
                             f"row? give --skip-rows {lineno - 1}", src)


def column_unit(kind: SensorKind, cols: Sequence[str], stated: str | None, file_units: dict[str, str],
                units_from: str, group: Any, src: str) -> tuple[str, str]:
    """(unit, how it was decided) of ``kind``'s columns ``cols``: as stated, as the file says
    (its units row or header), as the column group's names say, else the kind's default,
    assumed; InputError when the file gives the columns different units."""
    said = {file_units[c] for c in cols if file_units.get(c) in kind.units}
    if not stated and len(said) > 1:
        raise InputError(f"line 2: the units row gives the {kind.name} columns {', '.join(sorted(said))}: "
                         f"read them in separate runs", src)
    if stated:
        return stated, "as stated"
    if said:
        return said.pop(), f"as {units_from} says"
    if group and group.unit:
        return group.unit, group.why
    return next(iter(kind.units)), f"assumed; {kind.option} {'|'.join(list(kind.units)[1:])} if not"


def unit_note(kind: SensorKind, cols: Sequence[str], unit: str, why: str, counts: Sequence[float] | None) -> str:
    """The note of the unit ``kind``'s columns are read in (and the --rate-scale / --accel-scale factors)."""
    return (f"{kind.name} column{'s' if len(cols) > 1 else ''} {', '.join(cols)} "
            + (f"x {', '.join(f'{k:g}' for k in dict.fromkeys(counts))} ({kind.scale_option}) " if counts else "")
            + f"in {unit} ({why})")


#: the file name endings read as containers (gyrodenoise.io.containers), not as text
CONTAINER_SUFFIXES = (".bag", ".mcap", ".db3", ".mat")


def is_container(path: str | os.PathLike[str] | None) -> bool:
    """Whether ``path`` names a ROS bag (a ROS 2 bag folder too), an MCAP or a MATLAB file."""
    if path is None:
        return False
    p = Path(path)
    return p.suffix.lower() in CONTAINER_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").is_file())


def peek_header(path: str | os.PathLike[str] | None, skip_rows: int = 0) -> list[str] | None:
    """The header row's fields of a text recording (gzip too; after ``skip_rows`` lines and a
    preamble), or None when it cannot be read (the reader then says why)."""
    if path is None:
        return None
    try:
        check_regular(path)
        with open(path, "rb") as f:
            head = f.read(2)
        opener = gzip.open if head == b"\x1f\x8b" else open
        with opener(path, "rt", encoding="utf-8-sig", errors="replace") as f:
            text = "".join(itertools.islice(f, max(skip_rows, 0), max(skip_rows, 0) + PREAMBLE_MAX + 4))
    except (OSError, EOFError, gzip.BadGzipFile, InputError):
        return None
    first = next((ln for ln in io.StringIO(_after_preamble(text)[0]) if ln.strip()), None)
    if first is None:
        return None
    return _fields(first, _separator(first))


#: Earth's gravity read in an assumed m/s^2 by three accelerometer axes: |a| this far from 9.81
#: (median over the record) is gravity in another unit, never a valid m/s^2 reading on Earth
GRAVITY_IN = {"g": (0.5, 2.0), "mg": (500.0, 2000.0)}
#: |a| (median, m/s^2) of three axes at rest or in ordinary motion on Earth: 0.5 g .. 2 g
GRAVITY_M_S2 = (4.9, 19.6)


def _check_gravity(accel: list[Any], stated: str | None, src: str, scaled: bool = False) -> None:
    """Refuse three accelerometer axes read in an assumed m/s^2 whose |a| (median) is far from
    gravity's 9.81: about 1 is g, about 1000 mg (`GRAVITY_IN`), anything else outside
    `GRAVITY_M_S2` no unit of the reader's (raw counts: an MPU-6050 at +-2 g reads 16,384 per g),
    for ``--accel-scale``. ``scaled``: the columns were multiplied by ``--accel-scale``."""
    if stated or len(accel) != 3:
        return
    norm = float(np.nanmedian(np.sqrt(sum(np.asarray(a.values, dtype=np.float64) ** 2 for a in accel))))
    if GRAVITY_M_S2[0] <= norm <= GRAVITY_M_S2[1]:
        return
    cols = ", ".join(a.column for a in accel)
    read = "read as m/s^2" + (" after --accel-scale" if scaled else "")
    unit = next((u for u, (lo, hi) in GRAVITY_IN.items() if lo <= norm <= hi), None)
    if unit is not None:
        looks = f"the record looks to be in {unit}; give --accel-unit {unit}"
    else:
        looks = ("that is no unit of the reader's (raw counts? an MPU-6050 at +-2 g reads 16,384 per g); give "
                 "--accel-scale K (the unit per count) with --accel-unit for the product's unit")
    raise InputError(f"accelerometer columns {cols}: |a| is {norm:.3g} (median) {read}, gravity is 9.81 m/s^2: "
                     f"{looks} (or --accel-unit m/s^2 to read it as it is)", src)


def _check_arguments(rate_unit: str | None, accel_unit: str | None, sample_rate_hz: float | None,
                     src: str) -> None:
    """InputError for a unit or a stated sample rate the reader cannot use."""
    for kind, unit in ((GYRO, rate_unit), (ACCEL, accel_unit)):
        if unit is not None and unit not in kind.units:
            raise InputError(f"unknown {'rate' if kind is GYRO else 'acceleration'} unit {unit!r} "
                             f"(use one of {', '.join(kind.units)})", src)
    if sample_rate_hz is not None and not (0 < sample_rate_hz <= MAX_RATE_HZ):
        raise InputError(f"--sample-rate {sample_rate_hz:g} Hz is not a sample rate (it must be above 0 and "
                         f"at most {MAX_RATE_HZ:g} Hz)", src)


def _columns(kind: SensorKind, given: Sequence[str] | None, header: list[str], lower: dict[str, str],
             default: str | None, src: str) -> tuple[list[str], ColumnGroup | None]:
    """The columns of ``kind`` to read: those ``given`` (each must be there), else ``default``
    when the file has it, else the first group of ``kind`` it holds; InputError when none."""
    if given:
        missing = [c for c in given if c not in header]
        if missing:
            raise InputError(f"line 1: no column '{missing[0]}' (columns: {', '.join(header)}); "
                             f"use {'--rate-column' if kind is GYRO else '--accel-column'}", src)
        return list(given), next((g for g in kind.groups if set(given) <= set(g.names)), None)
    if default is None:
        return [], None
    if default in header:
        return [default], None
    cols, group = _detected(kind, lower)
    if not cols:
        raise InputError(f"line 1: no column '{default}' (columns: {', '.join(header)}); use --rate-column", src)
    return cols, group


def _detected(kind: SensorKind, lower: dict[str, str]) -> tuple[list[str], ColumnGroup | None]:
    """The file's columns (as spelt there) of the first group of ``kind`` it holds."""
    for g in kind.groups:
        cols = [lower[name] for name in g.names if name in lower]
        if cols:
            return cols, g
    return [], None


#: the separators told from the header line (None: runs of spaces), by name
SEPARATOR_NAMES = {",": "commas", ";": "semicolons", "\t": "tabs", None: "spaces"}
DECIMAL_COMMA = "\0decimal comma"     # key of _read_values' answer: a decimal comma was read
_DECIMAL_COMMA_CELL = re.compile(r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?")


def _separator(text: str) -> str | None:
    """The field separator of the header line (the first line that is not blank): a comma
    when it has one, else a semicolon, a tab, else runs of spaces (None; not within one
    name with its unit, ``gyro_x (rad/s)``)."""
    first = next((ln for ln in io.StringIO(text) if ln.strip()), "")
    for sep in (",", ";", "\t"):
        if sep in first:
            return sep
    return None if len(first.split()) > 1 and not _NAME_UNIT.fullmatch(first.strip()) else ","


def _rows(text: TextFile, sep: str | None, src: str, skip: int = 0) -> Iterator[tuple[int, list[str]]]:
    """(line number, fields) of each line after the first ``skip`` (a preamble); InputError for
    a line the csv module refuses."""
    lines = itertools.islice(text.lines(), skip, None)
    if sep is None:
        for lineno, line in enumerate(lines, start=skip + 1):
            yield lineno, line.split()
        return
    reader = csv.reader(lines, delimiter=sep)
    try:
        for row in reader:
            yield skip + reader.line_num, row
    except csv.Error as exc:
        raise InputError(f"line {skip + reader.line_num}: {exc}", src) from None


#: what a units row (a second header row) may say -> the unit's name here
UNIT_SPELLINGS = {**{u: u for u in (*RATE_TO_DEG_S, *ACCEL_TO_M_S2)},
                  "°/s": "deg/s", "dps": "deg/s", "deg/sec": "deg/s", "rad/sec": "rad/s", "°/h": "deg/h",
                  "m/s2": "m/s^2", "m/s²": "m/s^2", "m/s/s": "m/s^2",
                  "s": "s", "sec": "s", "ms": "ms", "us": "us", "µs": "us", "μs": "us", "ns": "ns"}
TIME_UNIT_NAMES = ("s", "ms", "us", "ns")


def _unit_cells(row: list[str]) -> list[str]:
    return [c.strip().strip("[]()").strip().lower() for c in row]


def _is_units_row(row: list[str]) -> bool:
    """No number in it and a unit among its cells (``s,rad/s,rad/s``, ``[s] [deg/s]``)."""
    cells = _unit_cells(row)
    return not any(_is_number(c) for c in cells if c) and any(c in UNIT_SPELLINGS for c in cells)


def _units_row(rows: Iterator[tuple[int, list[str]]], header: list[str]
               ) -> tuple[Iterator[tuple[int, list[str]]], dict[str, str]]:
    """(the rows, {column: unit}): a first data row with no number in it and a unit among its
    cells (``s,rad/s,rad/s``, ``[s] [deg/s]``) is a units row, taken out of the rows."""
    for lineno, row in rows:
        if not row or (len(row) == 1 and not row[0].strip()):
            continue
        if _is_units_row(row):
            cells = _unit_cells(row)
            return rows, {h: UNIT_SPELLINGS[c] for h, c in zip(header, cells) if c in UNIT_SPELLINGS}
        return itertools.chain([(lineno, row)], rows), {}
    return rows, {}


#: the most lines of free text (a preamble) read before a header row
PREAMBLE_MAX = 50
#: a unit after a column's name: ``gyro_x (deg/s)``, ``time [s]``
_NAME_UNIT = re.compile(r"^(?P<name>.*?\S)\s*[(\[]\s*(?P<unit>[^()\[\]]+?)\s*[)\]]$")


def _fields(line: str, sep: str | None) -> list[str]:
    return [c.strip() for c in (line.split() if sep is None else next(csv.reader([line], delimiter=sep), []))]


def _is_data(cells: list[str], sep: str | None) -> bool:
    """Whether ``cells`` are all numbers (decimal commas too where the separator is not a comma)."""
    return bool(cells) and all(_is_number(c) or (sep != "," and _DECIMAL_COMMA_CELL.fullmatch(c) is not None)
                               for c in cells)


def _after_preamble(text: str) -> tuple[str, list[str]]:
    """(``text`` with the lines before its header row blanked, those lines): the header row is
    the first line, among the first `PREAMBLE_MAX` + 1, that is not all numbers and is followed
    (after a units row, if any) by a row of numbers with as many fields; the lines before it are
    a preamble. A row with a number in it is no header after a preamble (it is a bad first data
    row under the header of line 1): the text is then left as it is."""
    head: list[str] = []
    for line in io.StringIO(text):
        head.append(line)
        if len(head) > PREAMBLE_MAX + 3:
            break
    lines = [(i, ln) for i, ln in enumerate(head) if ln.strip()]
    for j, (i, line) in enumerate(lines[:PREAMBLE_MAX + 1]):
        sep = _separator(line)
        names = _fields(line, sep)
        if _is_data(names, sep):
            break
        after = [_fields(ln, sep) for _, ln in lines[j + 1:j + 3]]
        if after and len(after[0]) == len(names) and _is_units_row(after[0]) and len(after) > 1:
            after = after[1:]
        if not after or len(after[0]) != len(names) or not _is_data(after[0], sep):
            continue
        before = [ln.strip() for _, ln in lines[:j]]
        if not before or any(_is_number(c) for c in names if c):
            return text, []
        cut = sum(len(ln) for ln in head[:i])
        return "\n" * i + text[cut:], before
    return text, []


def preamble_note(preamble: Sequence[str]) -> str:
    """The note of the lines skipped before the header row."""
    shown = "; ".join(preamble[:6]) + (f"; ... ({len(preamble)} lines)" if len(preamble) > 6 else "")
    return (f"{len(preamble)} line(s) before the header row skipped as a preamble (free text, not "
            f"columns): {shown}")


def _header_units(header: list[str]) -> dict[str, str]:
    """{column: unit} of the columns whose name ends in a unit: ``gyro_x (deg/s)``."""
    out = {}
    for h in header:
        m = _NAME_UNIT.match(h)
        if m and m["unit"].lower() in UNIT_SPELLINGS:
            out[h] = UNIT_SPELLINGS[m["unit"].lower()]
    return out


def _names(header: list[str]) -> dict[str, str]:
    """Lower-case name -> the column as the header spells it; a name that ends in a unit
    (``gyro_x (deg/s)``) is found by its name without the unit too."""
    lower = {h.lower(): h for h in header}
    for h in header:
        m = _NAME_UNIT.match(h)
        if m:
            lower.setdefault(m["name"].lower(), h)
    return lower


def rate_scales(rate_scale: Sequence[float] | float | None, cols: list[str], src: str) -> list[float] | None:
    """One ``--rate-scale`` factor per gyro column (`_scales`)."""
    return _scales(rate_scale, cols, "--rate-scale", "rate", src)


def _scales(factors: Sequence[float] | float | None, cols: list[str], option: str, what: str,
            src: str) -> list[float] | None:
    """One factor of ``option`` (``--rate-scale``, ``--accel-scale``) per column of ``what``
    (one given for all, or one per column); InputError for a factor that is not a finite
    nonzero number or a count that does not match."""
    if factors is None:
        return None
    given = [float(factors)] if isinstance(factors, (int, float)) else [float(k) for k in factors]
    bad = next((k for k in given if not (math.isfinite(k) and k != 0.0)), None)
    if bad is not None or not given:
        raise InputError(f"{option} {bad!r} is not a factor (a finite nonzero number: the unit per count)", src)
    if not cols:
        raise InputError(f"{option} is given but no {what} column is read", src)
    if len(given) not in (1, len(cols)):
        raise InputError(f"{option} gives {len(given)} factors for {len(cols)} {what} column(s) "
                         f"({', '.join(cols)}): give one for all or one per column", src)
    return given * len(cols) if len(given) == 1 else given


def _read_header(rows: Iterator[tuple[int, list[str]]], rate_column: str, time_column: str,
                 src: str) -> tuple[int, list[str]]:
    """(its line number, the header row's column names); InputError when it cannot be read or
    is a row of numbers (no header at all)."""
    try:
        lineno, row = next((r for r in rows if r[1] and any(c.strip() for c in r[1])))
    except StopIteration:
        raise InputError("line 1: cannot read the header", src) from None
    header = [h.strip() for h in row]
    if all(_is_number(h) for h in header):   # a row of numbers: no header at all
        raise InputError(f"line {lineno}: no header row (expected column names such as "
                         f"'{time_column},{rate_column}')", src)
    return lineno, header


def _read_values(rows: Iterator[tuple[int, list[str]]], header: list[str], index: dict[str, int],
                 decimal_comma: bool, src: str) -> dict[str, list[float]]:
    """{column name: list of floats} over the data rows (blank lines skipped); InputError at
    the first short row, non-number (``1_05`` too: Python would read it as 105), NaN or inf.
    With ``decimal_comma`` (the separator is not a comma) a cell such as ``0,25`` is read as
    0.25 and the key DECIMAL_COMMA is set."""
    need = max(index.values()) + 1
    width = len(header)
    values: dict[str, list[float]] = {c: [] for c in index}
    cols = [(name, c, values[name].append) for name, c in index.items()]
    for lineno, row in rows:
        if len(row) != width:
            if not row or (len(row) == 1 and not row[0].strip()):
                continue
            if len(row) < need:
                raise InputError(f"line {lineno}: {len(row)} fields, expected {width} (truncated row?)", src)
            if len(row) > width and any(c.strip() for c in row[width:]):
                raise InputError(f"line {lineno}: {len(row)} fields, expected {width}"
                                 + (" (decimal commas in a comma-separated file? separate the fields by ';')"
                                    if not decimal_comma else ""), src)
        for name, c, add in cols:
            cell = row[c]
            try:
                v = float(cell)
            except ValueError:
                cell = cell.strip()
                if not (decimal_comma and _DECIMAL_COMMA_CELL.fullmatch(cell)):
                    raise InputError(f"line {lineno}: column {name}: {cell!r} is not a number", src) from None
                v = float(cell.replace(",", "."))
                values[DECIMAL_COMMA] = []
            if "_" in cell:           # float() reads 1_05 as 105
                raise InputError(f"line {lineno}: column {name}: {cell.strip()!r} is not a number", src)
            if not -math.inf < v < math.inf:
                raise InputError(f"line {lineno}: column {name} is {cell.strip()}", src)
            if len(cell) > 15 and cell.strip().isdigit():    # ns since 1970: exact (a float keeps 16 digits)
                v = int(cell)
            add(v)
    return values


def _check_magnitude(kind: SensorKind, v: np.ndarray, cells: Any, where: Callable[[int], str], column: str,
                     unit: str, src: str) -> None:
    """InputError at the first value beyond the kind's absurd magnitude (after the unit)."""
    big = np.flatnonzero(np.abs(v) > kind.absurd)
    if big.size:
        j = int(big[0])
        raise InputError(f"{where(j)}: column {column}: {float(cells[j])!r} "
                         f"{unit} is beyond {kind.absurd:g} {kind.internal}, not a {kind.name} reading "
                         f"(wrong {kind.option}?)", src)


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


def _signal_notes(rate: np.ndarray, where: Callable[[int], str] = lambda i: f"line {i + 2}",
                  spike_advice: str = SPIKE_ADVICE, unit: str = "deg/s") -> list[str]:
    """Reported (never repaired) properties of the rate column: constant,
    suspected saturation, isolated spikes."""
    lo, hi = float(rate.min()), float(rate.max())
    sat = [(label, value, *_runs_at(rate, value, SAT_RUN)) for label, value in (("maximum", hi), ("minimum", lo))]
    spikes = None
    if lo != hi and rate.size >= 3:
        d = np.diff(rate)
        sigma = 1.4826 * float(np.median(np.abs(d - np.median(d))))
        if sigma > 0:
            lim = SPIKE_SIGMAS * sigma
            a, b = rate[1:-1] - rate[:-2], rate[1:-1] - rate[2:]
            found = np.flatnonzero(((a > lim) & (b > lim)) | ((a < -lim) & (b < -lim))) + 1
            if found.size:
                spikes = (int(found.size), int(found[0]), float(rate[found[0]]))
    return signal_note_texts(lo, hi, sat, spikes, where, spike_advice, unit)


def signal_note_texts(lo: float, hi: float, saturation: Sequence[tuple[str, float, int, int]],
                      spikes: tuple[int, int, float] | None, where: Callable[[int], str],
                      spike_advice: str = SPIKE_ADVICE, unit: str = "deg/s") -> list[str]:
    """The signal notes' text from the rate's minimum and maximum, its saturation runs
    ((label, value, samples in runs, first index) at the maximum and the minimum) and its
    isolated spikes ((count, first index, value) or None)."""
    if lo == hi:
        return [f"the rate is constant ({lo:g} {unit}): nothing to denoise; the filter passes it "
                f"through (to 1e-6 relative); its Allan deviation is zero, so the fit reports only "
                f"(tiny) upper bounds"]
    notes = []
    for label, value, count, first in saturation:
        if count:
            notes.append(f"suspected saturation: {count} samples in runs of >= {SAT_RUN} equal values at "
                         f"the rate's {label} {value:g} {unit} (first at {where(first)}, sample {first}); kept as is")
    if spikes is not None:
        count, first, value = spikes
        notes.append(f"{count} isolated spike(s) of more than {SPIKE_SIGMAS:g} robust sigmas "
                     f"(first at {where(first)}, sample {first}, {value:g} {unit}); "
                     f"kept as is in the input; {spike_advice}")
    return notes


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def write_recording(path: str | os.PathLike[str], time_s: npt.ArrayLike, raw_deg_s: npt.ArrayLike,
                    filtered_deg_s: npt.ArrayLike, true_rate_deg_s: npt.ArrayLike | None = None) -> None:
    """Write ``time,raw,filtered[,true_rate]`` (deg/s) to a CSV file."""
    cols = [np.asarray(time_s), np.asarray(raw_deg_s), np.asarray(filtered_deg_s)]
    header = "time,raw,filtered"
    if true_rate_deg_s is not None:
        cols.append(np.asarray(true_rate_deg_s))
        header += ",true_rate"
    try:
        save_columns(path, cols, header)
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror}", str(path)) from None


def write_axes(path: str | os.PathLike[str], rec: Recording, filtered: Sequence[np.ndarray]) -> None:
    """Write ``time`` (s), then for each axis of ``rec`` its column (raw, deg/s or m/s^2)
    and ``<column>_filtered`` (``filtered``, one series per axis) to a CSV file."""
    header = ["time"]
    cols = [np.asarray(rec.time_s)]
    for ax, out in zip(rec.axes, filtered, strict=True):
        header += [ax.column, f"{ax.column}_filtered"]
        cols += [ax.values, np.asarray(out)]
    try:
        save_columns(path, cols, ",".join(header))
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror}", str(path)) from None
