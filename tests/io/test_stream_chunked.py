"""The chunked reader (gyrodenoise.io.chunked) and the chunked time model against the
whole-array ones, bit for bit, on records with gaps, restarts, jitter, bursts, varying rates,
ms/us/ns and epoch timestamps, spikes and saturation, at tiny chunk sizes."""

from __future__ import annotations

import numpy as np
import pytest

from gyrodenoise.io.recording import read_recording
from gyrodenoise.io.timebase import analyse_time

pytest.importorskip("pyarrow")
from gyrodenoise.io.chunked import open_stream  # noqa: E402

N = 2400


def _times(kind: str, rng: np.random.Generator) -> np.ndarray:
    i = np.arange(N)
    if kind == "gaps_s":
        keep = np.ones(N, bool)
        keep[[300, 301, 302, 1200, N - 3]] = False
        keep[900:912] = False
        return (i / 1000.0)[keep]
    if kind == "reversal_ms":
        t = (i * 10).astype(np.int64)
        t[1500:] -= 9000
        return t
    if kind == "jitter_us":
        return np.round(i * 1000.0 + rng.uniform(-300, 300, N))
    if kind == "epoch_ns":
        return 1_600_000_000_000_000_000 + i.astype(np.int64) * 5_000_000
    if kind == "bursts_s":
        t = np.repeat(np.arange(N // 8) * 8e-3, 8)[:N]
        t[1600:] += 0.2
        return t
    if kind == "varying_s":
        return np.concatenate([np.arange(N // 2) * 0.01, 12 + np.arange(N - N // 2) * 0.002])
    if kind == "drops_jitter_s":
        keep = rng.random(N) > 0.02
        return (i / 100 + rng.uniform(-0.002, 0.002, N))[keep]
    raise AssertionError(kind)


KINDS = ["gaps_s", "reversal_ms", "jitter_us", "epoch_ns", "bursts_s", "varying_s", "drops_jitter_s"]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("chunk", [1, 7, 1000])
def test_time_model_chunked_is_whole(kind: str, chunk: int) -> None:
    t = _times(kind, np.random.default_rng(3))
    a, b = analyse_time(t), analyse_time(t, chunk=chunk)
    for f in ("n", "rate_hz", "measured_rate_hz", "median_rate_hz", "epoch", "epoch_offset_s", "spread",
              "repeated", "note", "kind", "unit"):
        assert getattr(a, f) == getattr(b, f), f
    for f in ("gap_index", "gap_seconds", "gap_missing", "gap_restarts", "reversals"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert a.runs == b.runs


def _write(path, t, rate, true=None) -> None:
    cols = [np.asarray(t), rate] + ([true] if true is not None else [])
    head = "time,rate" + (",true_rate" if true is not None else "")
    with open(path, "w") as f:
        f.write(head + "\n")
        for row in zip(*cols):
            f.write(",".join(str(v) if isinstance(v, (int, np.integer)) else repr(float(v)) for v in row) + "\n")


def _rate(n: int, rng: np.random.Generator) -> np.ndarray:
    r = rng.normal(0.0, 0.1, n).round(6)
    r[n // 3] = 50.0                          # a spike
    r[n // 2:n // 2 + 12] = r.max()            # saturation at the maximum
    return r


@pytest.mark.parametrize("kind", KINDS)
def test_stream_chunks_are_the_whole_record(tmp_path, kind: str) -> None:
    rng = np.random.default_rng(11)
    t = _times(kind, rng)
    rate = _rate(t.size, rng)
    true = rng.normal(0.0, 0.01, t.size).round(6)
    p = tmp_path / "r.csv"
    _write(p, t, rate, true)
    rec = read_recording(p)
    for chunk in (7, 500):
        with open_stream(p, chunk=chunk) as s:
            assert s.notes == rec.notes
            assert s.sample_rate_hz == rec.sample_rate_hz and s.n == len(rec)
            parts = list(s.chunks(chunk))
        np.testing.assert_array_equal(np.concatenate([c[0] for c in parts]), rec.time_s)
        np.testing.assert_array_equal(np.concatenate([c[1] for c in parts]), rec.rate_deg_s)
        np.testing.assert_array_equal(np.concatenate([c[2] for c in parts]), rec.true_rate_deg_s)
        got = [c[3] if c[3] is not None else np.zeros(len(c[0]), bool) for c in parts]
        want = rec.restarts if rec.restarts is not None else np.zeros(len(rec), bool)
        np.testing.assert_array_equal(np.concatenate(got), want)


def test_stream_no_time_column_and_units(tmp_path) -> None:
    p = tmp_path / "r.csv"
    rng = np.random.default_rng(5)
    r = rng.normal(0, 1, 500)
    p.write_text("rate;x\n" + "".join(f"{float(v)!r};1\n" for v in r))
    rec = read_recording(p, sample_rate_hz=100.0, rate_unit="rad/s")
    with open_stream(p, sample_rate_hz=100.0, rate_unit="rad/s", chunk=13) as s:
        assert s.notes == rec.notes
        parts = list(s.chunks(13))
    np.testing.assert_array_equal(np.concatenate([c[0] for c in parts]), rec.time_s)
    np.testing.assert_array_equal(np.concatenate([c[1] for c in parts]), rec.rate_deg_s)


def test_stream_declines_what_only_the_loop_reads(tmp_path) -> None:
    p = tmp_path / "r.csv"
    p.write_text("time rate\n0 1\n1 2\n2 3\n")
    assert open_stream(p) is None
    p.write_text("time,rate\n0,1\n1,x\n2,3\n")
    assert open_stream(p) is None


@pytest.mark.parametrize("form", ["plain", "gzip", "crlf_bom", "units_row", "ints_then_floats"])
def test_text_parsed_in_tiny_blocks_is_the_whole_record(tmp_path, monkeypatch, form) -> None:
    """The first pass parses blocks of whole lines (`stream.csv_tables`): with blocks of 50
    bytes (a few lines each) the record, notes and time model of the whole-array reader; a
    time column of integers, then floats, declined (the whole-array reader reads it)."""
    import gzip

    import gyrodenoise.io.chunked as ch
    monkeypatch.setattr(ch, "STREAM_BLOCK", 50)
    rng = np.random.default_rng(8)
    n = 900
    t = [str(i) for i in range(n)] if form == "ints_then_floats" else [repr(i / 100) for i in range(n)]
    if form == "ints_then_floats":
        t[600:] = [f"{i}.5" for i in range(600, n)]      # integers in the first blocks, then floats
    r = rng.normal(0, 0.1, n)
    nl = "\r\n" if form == "crlf_bom" else "\n"
    text = ("\ufeff" if form == "crlf_bom" else "") + "time,rate" + nl + ("s,deg/s" + nl if form == "units_row" else "")
    text += "".join(f"{a},{b!r}{nl}" for a, b in zip(t, r.tolist()))
    p = tmp_path / ("r.csv.gz" if form == "gzip" else "r.csv")
    data = text.encode()
    p.write_bytes(gzip.compress(data) if form == "gzip" else data)
    rec = read_recording(p)
    if form == "ints_then_floats":       # the first block's type held (as pyarrow's streaming reader): declined
        assert open_stream(p, chunk=7) is None
        return
    with open_stream(p, chunk=7) as s:
        assert s.notes == rec.notes
        parts = list(s.chunks(7))
    np.testing.assert_array_equal(np.concatenate([c[0] for c in parts]), rec.time_s)
    np.testing.assert_array_equal(np.concatenate([c[1] for c in parts]), rec.rate_deg_s)
