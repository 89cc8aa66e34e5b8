"""The fleet store: rows per log and stream, spectra on the fixed grid, atomic and
idempotent appends, DuckDB views. Synthetic logs with known truth (a white gyro of
known sigma plus a tone of known amplitude), and the shared real logs where present."""

from __future__ import annotations

import datetime
import math
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("pyarrow")
pytest.importorskip("duckdb")

from gyrodenoise.flightlog import fleet_store as fs  # noqa: E402
from gyrodenoise.flightlog.streams import GyroStream  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "logs"
RATE = 400.0
DURATION_S = 60.0


def synthetic_log(folder, name, *, seed, airframe="AF-1", tone_hz=80.0, tone_deg_s=1.0, sigma=0.2,
                  vibration=10.0, start=None, vehicle_id=True, duration_s=DURATION_S):
    """(report, flight) of a synthetic log: one gyro stream at :data:`RATE`, white noise of
    ``sigma`` deg/s on each axis plus a sine of ``tone_deg_s`` rms at ``tone_hz`` on x, one
    flying segment, a vibration figure ``vibration`` m/s/s (p95); the log file holds
    bytes unique to ``seed``."""
    rng = np.random.default_rng(seed)
    n = int(RATE * duration_s)
    t = np.arange(n) / RATE
    raw = rng.normal(0.0, sigma, (n, 3))
    raw[:, 0] += math.sqrt(2.0) * tone_deg_s * np.sin(2 * math.pi * tone_hz * t)
    s = GyroStream(name="IMU", message="IMU", unit="deg/s", to_deg_s=1.0, time_s=t, raw=raw,
                   index=np.arange(n))
    path = Path(folder) / name
    path.write_bytes(f"synthetic log {seed}".encode())
    flight = SimpleNamespace(gyro=[s], boots=[None], boot_of=lambda r: np.zeros(len(r), int))
    report = {
        "file": str(path), "format": "synthetic", "method": "motion", "over": "flying", "flying_time_s": duration_s,
        "overview": {"vehicle": "test quad", "vehicle_id": airframe if vehicle_id else None, "verdicts": [
            {"topic": "filters", "verdict": "pass", "reason": "nothing to change"}]},
        "boots": [{"start_s": 0.0, "wall_clock_offset_s": start}],
        "segments": [{"kind": "ground", "start_s": 0.0, "end_s": 5.0, "session": 0},
                     {"kind": "flying", "start_s": 5.0, "end_s": duration_s, "session": 0}],
        "vibration": {"verdict": "pass", "segments": [{"kind": "flying", "figures": {
            "VIBE.VibeX": {"p95": vibration, "unit": "m/s/s"}, "clip": {"increase": 0, "unit": "count"}}}]},
        "filter_review": {"param_lines": []},
        "streams": [{"name": "IMU", "samples": n, "rate_hz": RATE, "restarts": 0, "noise_unit": "deg/s",
                     "stage": "pre-filter", "noise": {a: {"raw": sigma, "filtered": sigma / 2} for a in "xyz"},
                     "spectrum": {"unit": "deg/s", "dominant_peak": {
                         "axis": "x", "freq_hz": tone_hz, "amplitude_rms": tone_deg_s, "harmonics_hz": []}}}],
    }
    return report, flight


def test_grid_psd_holds_white_level_and_tone():
    """White noise of sigma at fs: one-sided density sigma^2 / (fs / 2): the median over
    the bins within 5 %, every bin within 30 % (a bin narrower than 1 Hz averages one or
    two Welch bins of ~120 segments: ~10 % scatter; a two-sided or per-bin-width scaling
    error would be 50 % or more); the tone's bin holds its power
    (A_rms^2 spread over the Hann window's noise bandwidth, 1.5 bins) far above."""
    rep, flight = synthetic_log("/tmp", "unused", seed=1, tone_deg_s=1.0)
    s = flight.gyro[0]
    got = fs.segment_psd(s.raw[:, 1], s.time_s, np.ones(s.n, bool), RATE)
    f, p, res, n = got
    g = fs.grid_psd(f, p, RATE / 2)
    centre = np.sqrt(fs.GRID_EDGES_HZ[:-1] * fs.GRID_EDGES_HZ[1:])
    ok = np.isfinite(g)
    white = 0.2 ** 2 / (RATE / 2)
    ratio = g[ok & (centre > 5)] / white
    assert abs(np.median(ratio) - 1) < 0.05
    assert np.all(np.abs(ratio - 1) < 0.3)
    assert not np.isfinite(g[fs.GRID_EDGES_HZ[1:] > 0.98 * RATE / 2]).any()     # nothing above Nyquist
    gx = fs.grid_psd(*fs.segment_psd(s.raw[:, 0], s.time_s, np.ones(s.n, bool), RATE)[:2], RATE / 2)
    k = int(np.nanargmax(gx))
    assert fs.GRID_EDGES_HZ[k] <= 80.0 < fs.GRID_EDGES_HZ[k + 1]
    # the tone's power over the grid bin: 1.0 (deg/s)^2 spread over a bin of ~4.7 Hz,
    # of which the Welch bins inside average it: between 1/width and 1/(1.5 res)
    width = fs.GRID_EDGES_HZ[k + 1] - fs.GRID_EDGES_HZ[k]
    assert 0.5 / width < gx[k] < 1.0 / res


def test_segment_psd_splits_at_gaps():
    """A stretch with a 10 s hole: the Welch runs stay inside the gap-free stretches
    (a tone keeps its frequency; no sample counted twice)."""
    rep, flight = synthetic_log("/tmp", "unused", seed=2)
    s = flight.gyro[0]
    t = s.time_s.copy()
    t[t > 30] += 10.0
    f, p, res, n = fs.segment_psd(s.raw[:, 0], t, np.ones(len(t), bool), RATE)
    assert n == len(t)
    assert abs(f[np.argmax(p)] - 80.0) <= res


def test_rows_airframe_and_identity(tmp_path):
    start = datetime.datetime(2024, 5, 1, 12, tzinfo=datetime.timezone.utc).timestamp()
    rep, flight = synthetic_log(tmp_path, "a.bin", seed=3, start=start, vibration=12.5)
    res = fs.append_log(tmp_path / "store", rep, flight)
    assert (res.log_rows, res.replaced) == (1, False)
    assert res.spectrum_rows == 6           # two segments x three axes
    cols, rows = fs.query(tmp_path / "store", "SELECT airframe, airframe_source, start_utc, vibration_p95, "
                                               "vibration_figure, peak_freq_hz, noise_density_deg_s_rthz, "
                                               "filters_verdict, recommended FROM logs")
    (a, src, when, vib, vfig, peak, dens, fv, rec), = rows
    assert (a, src, vib, vfig, peak, fv, rec) == ("AF-1", "vehicle_id", 12.5, "VIBE.VibeX", 80.0, "pass", "")
    assert when == datetime.datetime(2024, 5, 1, 12, tzinfo=datetime.timezone.utc)
    assert dens == pytest.approx(0.2 / math.sqrt(RATE / 2))
    # no vehicle id: the folder's name; --airframe: the name given
    rep2, flight2 = synthetic_log(tmp_path, "b.bin", seed=4, vehicle_id=False)
    assert fs.airframe_of(rep2) == (tmp_path.name, "folder")
    assert fs.airframe_of(rep2, "my-quad") == ("my-quad", "option")


def test_same_log_twice_is_counted_once(tmp_path):
    rep, flight = synthetic_log(tmp_path, "a.bin", seed=5)
    fs.append_log(tmp_path / "s", rep, flight)
    assert fs.append_log(tmp_path / "s", rep, flight).replaced
    shutil.copy(rep["file"], tmp_path / "copy.bin")              # the same bytes under another name
    again = fs.append_log(tmp_path / "s", dict(rep, file=str(tmp_path / "copy.bin")), flight)
    assert again.replaced
    rep2, flight2 = synthetic_log(tmp_path, "b.bin", seed=6)
    fs.append_log(tmp_path / "s", rep2, flight2)
    _, rows = fs.query(tmp_path / "s", "SELECT count(*), count(DISTINCT log_key) FROM logs")
    assert rows == [(2, 2)]
    _, rows = fs.query(tmp_path / "s", "SELECT count(*) FROM spectra")
    assert rows == [(12,)]


def test_killed_append_leaves_the_store_readable(tmp_path, monkeypatch):
    """An append killed while it writes the log's row: the store reads as before (the
    earlier log whole, nothing of the killed one in ``logs``), the partial file hidden."""
    import pyarrow.parquet as pq
    rep, flight = synthetic_log(tmp_path, "a.bin", seed=7)
    fs.append_log(tmp_path / "s", rep, flight)
    real = pq.write_table

    def dying(table, where, **kw):
        real(table, where, **kw)
        if "log_key" in table.column_names and "airframe_source" in table.column_names:
            Path(where).write_bytes(Path(where).read_bytes()[:100])    # half a file, then the kill
            raise KeyboardInterrupt
    monkeypatch.setattr(pq, "write_table", dying)
    rep2, flight2 = synthetic_log(tmp_path, "b.bin", seed=8)
    with pytest.raises(KeyboardInterrupt):
        fs.append_log(tmp_path / "s", rep2, flight2)
    monkeypatch.setattr(pq, "write_table", real)
    _, rows = fs.query(tmp_path / "s", "SELECT log FROM logs")
    assert rows == [("a.bin",)]
    assert not list((tmp_path / "s" / "logs").glob(".*partial"))     # atomic_path removed it
    # the next run completes the killed log: counted once
    fs.append_log(tmp_path / "s", rep2, flight2)
    _, rows = fs.query(tmp_path / "s", "SELECT count(DISTINCT log) FROM logs")
    assert rows == [(2,)]


def test_empty_store_has_the_views(tmp_path):
    (tmp_path / "logs").mkdir()
    cols, rows = fs.query(tmp_path, "SELECT * FROM logs")
    assert rows == [] and "airframe" in cols
    _, rows = fs.query(tmp_path, "SELECT count(*) FROM grid")
    assert rows == [(len(fs.GRID_EDGES_HZ) - 1,)]


@pytest.mark.skipif(not (DATA / "log171.bin").exists(), reason="shared logs absent (../shared/data/logs)")
def test_real_log_rows(tmp_path):
    """log171.bin (ArduCopter 3.3, IMU/IMU2/IMU3 at 50 Hz): three rows keyed by the board
    id the log records; its spectra over each segment, nothing above 25 Hz."""
    from gyrodenoise.flightlog.pipeline import process_log
    rep = process_log(DATA / "log171.bin", tmp_path / "out", plots=False, csv=False)
    fs.append_log(tmp_path / "s", rep)
    _, rows = fs.query(tmp_path / "s", "SELECT DISTINCT airframe, airframe_source FROM logs")
    assert rows == [("004A002F 33345119 32383433", "vehicle_id")]
    _, rows = fs.query(tmp_path / "s", "SELECT count(*), count(DISTINCT stream), count(DISTINCT kind) FROM spectra")
    assert rows[0][1] == 3 and rows[0][2] >= 3
    _, rows = fs.query(tmp_path / "s", "SELECT max(g.f_hi_hz) FROM spectra s, grid g "
                                        "WHERE s.psd[g.bin + 1] IS NOT NULL")
    assert rows[0][0] <= 25.0


def test_a_column_older_files_lack_reads_as_null(tmp_path):
    """A store written before a column existed (its file without ``autopilot``) still
    reads, that column NULL; a newer file beside it keeps its value."""
    import pyarrow.parquet as pq
    rep, flight = synthetic_log(tmp_path, "a.bin", seed=9)
    got = fs.append_log(tmp_path / "s", rep, flight)
    path = tmp_path / "s" / "logs" / f"{got.log_key}.parquet"
    pq.write_table(pq.read_table(path).drop(["autopilot"]), path)
    _, rows = fs.query(tmp_path / "s", "SELECT log, autopilot FROM logs")
    assert rows == [("a.bin", None)]
    rep2, flight2 = synthetic_log(tmp_path, "b.bin", seed=10)
    rep2["vehicle_filters"] = {"autopilot": "px4"}
    fs.append_log(tmp_path / "s", rep2, flight2)
    _, rows = fs.query(tmp_path / "s", "SELECT log, autopilot FROM logs ORDER BY log")
    assert rows == [("a.bin", None), ("b.bin", "px4")]
