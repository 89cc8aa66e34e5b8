"""The fleet over time: each reviewed log's figures appended to a Parquet store.

A store is a folder holding two tables, each a folder of Parquet files, one file per
log (named by the log's content hash), read together (DuckDB ``read_parquet``, or
:func:`query`):

* ``logs/`` -- one row per log and gyro stream (:class:`LogRow`): the log's identity
  and airframe key, its start on the wall clock where the log records it, flying time,
  vibration, the stream's noise density and dominant vibration peak, the filter
  review's outcome;
* ``spectra/`` -- one row per log, stream, flight segment and axis (:class:`SpectrumRow`):
  the raw gyro's one-sided PSD, (deg/s)^2/Hz, on the fixed frequency grid
  :data:`GRID_EDGES_HZ` (:func:`grid_psd`), so that the spectra of any logs stack.

Appends are atomic and idempotent. Each log's rows go into ``<hash>.parquet`` (the
SHA-256 of the log's bytes, :func:`content_key`), written under a partial name and
renamed when complete (:func:`gyrodenoise.flightlog.stopping.atomic_path`): a killed run
leaves the store as it was before that log, plus a hidden partial file the readers
never match; the same log appended twice (or two copies of it) replaces its own file,
so it is counted once. The spectra go first and the log's row last: a log in ``logs``
has its spectra.

The airframe a log belongs to (:func:`airframe_of`): the ``--airframe`` name given on
the command line, else the vehicle id the log records (ArduPilot's board id, PX4's
``sys_uuid``, Betaflight's craft name: :mod:`gyrodenoise.flightlog.overview`), else
the name of the folder holding the log (``airframe_source`` says which was used: one
folder per aircraft is the usual way to keep logs without ids; the trends check that a
folder's logs agree on their identity before they trend them:
:func:`gyrodenoise.flightlog.trends.groupings`).
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrodenoise.flightlog.fleet import fleet_rows
from gyrodenoise.flightlog.stopping import atomic_path

LOGS, SPECTRA = "logs", "spectra"
#: the fixed grid of the spectra table: 12 bins an octave from 1 Hz to 2048 Hz (each
#: 5.9 % wide: a 50 Hz line falls in a 3 Hz bin), edges in Hz
BINS_PER_OCTAVE = 12
GRID_EDGES_HZ = 2.0 ** (np.arange(11 * BINS_PER_OCTAVE + 1) / BINS_PER_OCTAVE)
#: a segment's stretch of samples needs this many for a Welch estimate
MIN_SPECTRUM_SAMPLES = 32
#: a time step above this many times the stream's median step splits it (Welch runs
#: within the stretches between gaps)
GAP_STEPS = 5.0
PSD_UNIT = "(deg/s)^2/Hz"
#: airframe_source values
AIRFRAME_OPTION, AIRFRAME_VEHICLE_ID, AIRFRAME_FOLDER = "option", "vehicle_id", "folder"


@dataclass
class LogRow:
    """One row of the ``logs`` table: a log and one of its gyro streams."""
    log_key: str                      # SHA-256 of the log's bytes (content_key)
    stored_utc: datetime.datetime     # when the row was appended
    file: str                         # the path the log was reviewed from
    log: str                          # its file name
    format: str | None
    autopilot: str | None             # ardupilot / px4 / betaflight (the review's vehicle filters)
    airframe: str
    airframe_source: str              # option / vehicle_id / folder
    vehicle: str | None
    firmware: str | None
    board: str | None
    frame: str | None
    vehicle_id: str | None
    start_utc: datetime.datetime | None  # the log's first boot's start on the wall clock, where recorded
    boots: int
    flying_time_s: float | None
    over: str | None                  # what the figures are over: flying / whole log
    stream: str
    compared_as: str                  # the stream's name across logs (IMU -> IMU[0])
    stage: str | None                 # pre-filter / post-filter / unknown
    rate_hz: float | None
    samples: int | None
    noise_unit: str | None
    noise_raw: float | None           # white-noise sigma of the raw gyro, mean over the axes
    noise_density_deg_s_rthz: float | None
    peak_freq_hz: float | None        # the stream's dominant vibration peak
    peak_amplitude_rms: float | None  # its level, in peak_unit rms
    peak_unit: str | None
    peak_axis: str | None
    vibration_verdict: str | None     # pass / warn / fail; None: no verdict
    vibration_figure: str | None      # the log's vibration level: its highest acceleration figure ...
    vibration_p95: float | None       # ... its 95th percentile over the flying segments ...
    vibration_unit: str | None        # ... in this unit
    filters_verdict: str | None       # the overview's filter line: pass / change / None
    filters_reason: str | None
    recommended: str | None           # the filter review's parameter lines, "; "-joined ("" none)
    method: str | None                # the bridge's denoiser method of the review


@dataclass
class SpectrumRow:
    """One row of the ``spectra`` table: a stream's raw PSD over one flight segment, one axis."""
    log_key: str
    airframe: str
    start_utc: datetime.datetime | None
    stream: str
    compared_as: str
    segment: int                      # the segment's index in the log's report
    kind: str                         # ground / armed / flying / hover / after impact / whole log
    session: int | None
    start_s: float
    end_s: float
    axis: str
    rate_hz: float
    samples: int
    resolution_hz: float              # of the Welch estimate put on the grid
    psd: list                         # len(GRID_EDGES_HZ) - 1 values, PSD_UNIT; None above Nyquist


#: a row annotation's base type -> (its Arrow type, of the pyarrow module; its DuckDB type)
_TYPES = {"str": (lambda pa: pa.string(), "VARCHAR"), "float": (lambda pa: pa.float64(), "DOUBLE"),
          "int": (lambda pa: pa.int64(), "BIGINT"),
          "datetime.datetime": (lambda pa: pa.timestamp("us", tz="UTC"), "TIMESTAMPTZ"),
          "list": (lambda pa: pa.list_(pa.float32()), "FLOAT[]")}


def _base(annotation):
    return annotation.split("|")[0].strip()


def _arrow_type(annotation):
    import pyarrow as pa
    return _TYPES[_base(annotation)][0](pa)


def schema(row_class):
    """The Parquet schema of a row dataclass (its annotations, nullable where ``| None``)."""
    import pyarrow as pa
    return pa.schema([pa.field(f.name, _arrow_type(f.type), nullable="None" in f.type or f.type == "list")
                      for f in dataclasses.fields(row_class)],
                     metadata={"grid_edges_hz": ",".join(f"{e:.9g}" for e in GRID_EDGES_HZ),
                               "psd_unit": PSD_UNIT})


def _table(rows, row_class):
    import pyarrow as pa
    sch = schema(row_class)
    cols = {f.name: [getattr(r, f.name) for r in rows] for f in dataclasses.fields(row_class)}
    return pa.Table.from_pydict(cols, schema=sch)


# ------------------------------------------------------------------ keys
def content_key(path):
    """SHA-256 (hex) of a log's bytes; a folder log (a ROS 2 bag): of its files' relative
    names and bytes, in name order."""
    path = Path(path)
    h = hashlib.sha256()
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
    for p in files:
        if p != path:
            h.update(p.relative_to(path).as_posix().encode() + b"\0")
        with open(p, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()


def airframe_of(report, airframe=None):
    """(airframe key, source): ``airframe`` when given (``option``), else the log's vehicle
    id (``vehicle_id``), else the name of the folder holding the log (``folder``)."""
    if airframe:
        return str(airframe), AIRFRAME_OPTION
    vid = (report.get("overview") or {}).get("vehicle_id")
    if vid:
        return str(vid), AIRFRAME_VEHICLE_ID
    return Path(str(report["file"])).resolve().parent.name or "/", AIRFRAME_FOLDER


def start_utc(report):
    """The log's first boot's start on the wall clock (UTC), None where the log does not record it."""
    for b in report.get("boots") or []:
        off, start = b.get("wall_clock_offset_s"), b.get("start_s")
        if off is not None and start is not None and math.isfinite(off + start):
            return datetime.datetime.fromtimestamp(off + start, tz=datetime.timezone.utc)
    return None


# ------------------------------------------------------------------ figures of a log
def vibration_level(report):
    """(figure, p95, unit): the log's highest acceleration vibration figure (unit m/s/s;
    the 95th percentile, the largest over the segments in the verdict), or (None,)*3."""
    vib = report.get("vibration") or {}
    best = (None, None, None)
    for seg in vib.get("segments") or []:
        if not seg.get("in_verdict", True) or seg.get("kind") == "after impact":
            continue
        for name, f in (seg.get("figures") or {}).items():
            p95 = f.get("p95")
            if f.get("unit") == "m/s/s" and p95 is not None and math.isfinite(p95) and (best[1] is None or p95 > best[1]):
                best = (name, float(p95), f["unit"])
    return best


def _verdict_line(report, topic):
    for v in (report.get("overview") or {}).get("verdicts") or []:
        if v.get("topic") == topic:
            return v.get("verdict"), v.get("reason")
    return None, None


def log_rows(report, key, airframe=None, stored=None):
    """The ``logs`` rows (:class:`LogRow`) of one log's report (as
    :func:`gyrodenoise.flightlog.pipeline.process_log` gives it), one per gyro stream."""
    stored = stored or datetime.datetime.now(datetime.timezone.utc)
    ident = report.get("overview") or {}
    frame, source = airframe_of(report, airframe)
    vfig, vp95, vunit = vibration_level(report)
    fverdict, freason = _verdict_line(report, "filters")
    fr = report.get("filter_review")
    rows = []
    for r in fleet_rows({"logs": [report]}):
        peak = r.get("vibration_peak") or {}
        rows.append(LogRow(
            log_key=key, stored_utc=stored, file=str(report["file"]), log=r["log"], format=report.get("format"),
            autopilot=(report.get("vehicle_filters") or {}).get("autopilot"),
            airframe=frame, airframe_source=source, vehicle=ident.get("vehicle"), firmware=ident.get("firmware"),
            board=ident.get("board"), frame=ident.get("frame"), vehicle_id=ident.get("vehicle_id"),
            start_utc=start_utc(report), boots=max(1, len(report.get("boots") or [])),
            flying_time_s=_num(report.get("flying_time_s")), over=report.get("over"),
            stream=r["stream"], compared_as=r["compared_as"], stage=r.get("stage"), rate_hz=_num(r.get("rate_hz")),
            samples=r.get("samples"), noise_unit=r.get("noise_unit"), noise_raw=_num(r.get("noise_raw")),
            noise_density_deg_s_rthz=_num(r.get("noise_density_deg_s_rthz")),
            peak_freq_hz=_num(peak.get("freq_hz")), peak_amplitude_rms=_num(peak.get("amplitude_rms")),
            peak_unit=peak.get("unit"), peak_axis=peak.get("axis"),
            vibration_verdict=r.get("vibration_verdict"), vibration_figure=vfig, vibration_p95=vp95,
            vibration_unit=vunit, filters_verdict=fverdict, filters_reason=freason,
            recommended=None if not fr else "; ".join(fr.get("param_lines") or []),
            method=report.get("method")))
    return rows


def _num(v):
    return None if v is None or not math.isfinite(float(v)) else float(v)


# ------------------------------------------------------------------ spectra on the grid
def grid_psd(freq_hz, psd, nyquist_hz):
    """A one-sided PSD (``freq_hz``, ``psd``) on :data:`GRID_EDGES_HZ`: per bin the mean
    of the estimate's values inside it, or, in a bin narrower than the estimate's
    resolution, its linear interpolation at the bin's centre; NaN for a bin that
    reaches above 0.98 x ``nyquist_hz`` (the anti-alias roll-off) or below the estimate's
    first non-zero frequency."""
    f, p = np.asarray(freq_hz, dtype=np.float64), np.asarray(psd, dtype=np.float64)
    lo, hi = GRID_EDGES_HZ[:-1], GRID_EDGES_HZ[1:]
    idx = np.searchsorted(f, lo, side="left"), np.searchsorted(f, hi, side="left")
    csum = np.concatenate([[0.0], np.cumsum(p)])
    count = idx[1] - idx[0]
    mean = np.where(count > 0, (csum[idx[1]] - csum[idx[0]]) / np.maximum(count, 1), np.nan)
    centre = np.sqrt(lo * hi)
    interp = np.interp(centre, f, p)
    out = np.where(count > 0, mean, interp)
    out[(hi > 0.98 * nyquist_hz) | (lo < (f[1] if len(f) > 1 else np.inf))] = np.nan
    return out


def _runs(t, mask):
    """Index arrays of the stretches of ``mask`` with no time gap (> GAP_STEPS median steps)."""
    idx = np.flatnonzero(mask)
    if len(idx) < 2:
        return [idx] if len(idx) else []
    dt = np.diff(t[idx])
    step = np.median(dt[dt > 0]) if np.any(dt > 0) else 0.0
    cut = np.flatnonzero((np.diff(idx) > 1) | (dt > GAP_STEPS * step) | (dt <= 0)) + 1
    return np.split(idx, cut)


def segment_psd(x, t, mask, rate_hz):
    """(freq_hz, psd, resolution_hz, samples) of ``x`` (one axis, deg/s) over the samples
    of ``mask``: Welch (Hann, half overlap, mean removed) in each gap-free stretch, the
    stretches' estimates averaged weighted by their Welch segments; segments of
    about 1 Hz resolution (the power of two nearest the rate), shorter when the longest
    stretch is. None when no stretch has :data:`MIN_SPECTRUM_SAMPLES`."""
    from scipy.signal import welch
    runs = [r for r in _runs(t, mask) if len(r) >= MIN_SPECTRUM_SAMPLES]
    if not runs:
        return None
    longest = max(len(r) for r in runs)
    nper = int(min(2 ** round(math.log2(max(rate_hz, MIN_SPECTRUM_SAMPLES))), 2 ** int(math.log2(longest))))
    runs = [r for r in runs if len(r) >= nper]
    acc, weight, freq = 0.0, 0, None
    for r in runs:
        n_seg = 1 + (len(r) - nper) // (nper // 2)
        freq, p = welch(x[r], fs=rate_hz, window="hann", nperseg=nper, noverlap=nper // 2, detrend="constant")
        acc = acc + p * n_seg
        weight += n_seg
    return freq, acc / weight, rate_hz / nper, int(sum(len(r) for r in runs))


def spectrum_rows(report, flight, key, airframe=None):
    """The ``spectra`` rows (:class:`SpectrumRow`) of one log: each stream in deg/s, each
    flight segment of the report (the whole log when it has none), each axis, on the
    grid. ``flight``: the log as :func:`gyrodenoise.flightlog.formats.read_log` reads it."""
    from gyrodenoise.flightlog.fleet import compared_as
    frame, _ = airframe_of(report, airframe)
    when = start_utc(report)
    segments = report.get("segments") or [{"kind": "whole log", "start_s": -math.inf, "end_s": math.inf,
                                           "session": None}]
    rows = []
    for s in flight.gyro:
        if s.to_deg_s is None or s.n < MIN_SPECTRUM_SAMPLES:
            continue
        t = np.asarray(s.time_s, dtype=np.float64)
        dt = np.diff(t)
        rate = 1.0 / float(np.median(dt[dt > 0])) if np.any(dt > 0) else None
        if not rate:
            continue
        sessions = flight.boot_of(s.sample_records) if len(flight.boots) > 1 else None
        x = np.asarray(s.raw, dtype=np.float64) * s.to_deg_s
        for i, seg in enumerate(segments):
            m = (t >= seg["start_s"]) & (t <= seg["end_s"]) & np.isfinite(x).all(axis=1)
            if sessions is not None and seg.get("session") is not None:
                m &= sessions == seg["session"]
            for k, axis in enumerate(s.axes):
                got = segment_psd(x[:, k], t, m, rate)
                if got is None:
                    continue
                f, p, res, n = got
                g = grid_psd(f, p, rate / 2.0)
                if not np.isfinite(g).any():       # a stream too slow for the grid's first bin
                    continue
                rows.append(SpectrumRow(
                    log_key=key, airframe=frame, start_utc=when, stream=s.name, compared_as=compared_as(s.name),
                    segment=i, kind=seg["kind"], session=seg.get("session"),
                    start_s=float(max(seg["start_s"], t[m][0])), end_s=float(min(seg["end_s"], t[m][-1])),
                    axis=axis, rate_hz=rate, samples=n, resolution_hz=res,
                    psd=[None if not math.isfinite(v) else float(v) for v in g]))
    return rows


# ------------------------------------------------------------------ the store
@dataclass(frozen=True)
class Appended:
    """What one append did: the log, its key, the rows written, whether it replaced an entry."""
    file: str
    log_key: str
    log_rows: int
    spectrum_rows: int
    replaced: bool


def _write(table, path):
    import pyarrow.parquet as pq
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd")


def append_log(store, report, flight=None, airframe=None, read_options=None):
    """Append one reviewed log (its report) to ``store``; return :class:`Appended`.
    ``flight``: the log as read (read again from ``report["file"]`` when None, for the
    spectra). Atomic and idempotent (the module's docstring)."""
    from gyrodenoise.flightlog.formats import read_log
    store = Path(store)
    key = content_key(report["file"])
    if flight is None:
        flight = read_log(report["file"], options=read_options)
    target = store / LOGS / f"{key}.parquet"
    replaced = target.exists()
    spectra = spectrum_rows(report, flight, key, airframe)
    rows = log_rows(report, key, airframe)
    _write(_table(spectra, SpectrumRow), store / SPECTRA / f"{key}.parquet")
    _write(_table(rows, LogRow), target)
    return Appended(str(report["file"]), key, len(rows), len(spectra), replaced)


def append_summary(store, summary, airframe=None, read_options=None, log=None):
    """Append every processed log of a ``gyrodenoise mavlink`` summary (its ``logs``) to
    ``store``; a log that cannot be read again is skipped with one line to ``log``.
    Returns the :class:`Appended` of each log appended."""
    out = []
    for rep in summary.get("logs") or []:
        try:
            out.append(append_log(store, rep, airframe=airframe, read_options=read_options))
        except (OSError, ValueError) as exc:
            if log is not None:
                log(f"--store: {rep.get('file')} not appended ({exc})")
    return out


def is_store(path):
    """True when ``path`` is a folder with a ``logs`` table folder."""
    return (Path(path) / LOGS).is_dir()


def connect(store):
    """A DuckDB connection with the views ``logs`` and ``spectra`` over the store's
    Parquet files (empty tables of the right columns when there are none; a column the
    row classes have and no file holds -- a store written before it -- reads as NULL) and
    ``grid`` (``bin``, ``f_lo_hz``, ``f_hi_hz``, ``f_centre_hz``: the spectra's ``psd[bin + 1]``)."""
    import duckdb
    store = Path(store)
    con = duckdb.connect()
    for name, row_class in ((LOGS, LogRow), (SPECTRA, SpectrumRow)):
        files = sorted((store / name).glob("*.parquet"))
        if files:
            glob = str(store / name / "*.parquet").replace("'", "''")
            con.execute(f"CREATE VIEW _{name}_files AS SELECT * FROM read_parquet('{glob}', union_by_name=true)")
            have = {d[0] for d in con.execute(f"SELECT * FROM _{name}_files LIMIT 0").description}
            absent = [f"NULL::{_TYPES[_base(f.type)][1]} AS {f.name}" for f in dataclasses.fields(row_class)
                      if f.name not in have]
            con.execute(f"CREATE VIEW {name} AS SELECT {', '.join(['*'] + absent)} FROM _{name}_files")
        else:
            empty = _table([], row_class)
            con.register(f"_{name}_empty", empty)
            con.execute(f"CREATE VIEW {name} AS SELECT * FROM _{name}_empty")
    lo, hi = GRID_EDGES_HZ[:-1], GRID_EDGES_HZ[1:]
    con.execute("CREATE TABLE grid (bin INTEGER, f_lo_hz DOUBLE, f_hi_hz DOUBLE, f_centre_hz DOUBLE)")
    con.executemany("INSERT INTO grid VALUES (?, ?, ?, ?)",
                    [(i, float(a), float(b), float(math.sqrt(a * b))) for i, (a, b) in enumerate(zip(lo, hi))])
    return con


def query(store, sql, params=None):
    """Run ``sql`` on the store (:func:`connect`'s views); return (column names, rows)."""
    con = connect(store)
    try:
        cur = con.execute(sql, params or [])
        cols = [d[0] for d in cur.description] if cur.description else []
        return cols, cur.fetchall()
    finally:
        con.close()
