"""gyrodenoise.io.stream: inputs that are no file refused with one line, and the fast
column engine (pyarrow) giving the reader's own numbers, refusals and notes."""

import gzip
import os
import signal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrodenoise.errors import InputError
from gyrodenoise.io import recording, stream
from tests.helpers import run_main

pytest.importorskip("pyarrow")


@pytest.fixture
def alarm():
    """A command that would wait on an endless input fails here instead of hanging."""
    def fail(*_):
        raise AssertionError("still reading after 20 s")
    old = signal.signal(signal.SIGALRM, fail)
    signal.alarm(20)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def _commands(path, tmp_path):
    out = tmp_path / "o.csv"
    return [("allan", path), ("allan", path, "--rate-column", "gx"), ("denoise", path, "-o", out),
            ("denoise", path, "-o", out, "--causal"), ("compare", path),
            ("gap", path, "--model", "paper_fog", "--out", tmp_path / "n.toml", "--no-plot")]


@pytest.mark.parametrize("special", ["fifo", "/dev/zero"])
def test_endless_inputs_are_refused_in_one_line(tmp_path, alarm, special):
    if special == "fifo":
        path = tmp_path / "pipe.csv"
        os.mkfifo(path)           # no writer: opening it would wait for ever
        what = "FIFO"
    else:
        path, what = special, "character device"
    for cmd in _commands(path, tmp_path):
        status, out, err = run_main(*cmd)
        assert status == 2, (cmd, err)
        assert err.count("\n") == 1 and what in err and str(path) in err, (cmd, err)


def _both(path, **kw):
    """(the reader with the fast engine, the reader's own loop): each a Record or the InputError's text."""
    def read():
        try:
            return recording.read_recording(path, **kw)
        except InputError as exc:
            return str(exc)
    fast = read()
    saved = recording.numeric_columns
    recording.numeric_columns = lambda *a, **k: None
    try:
        slow = read()
    finally:
        recording.numeric_columns = saved
    return fast, slow


def _same(fast, slow):
    if isinstance(slow, str) or isinstance(fast, str):
        assert fast == slow
        return
    assert fast.rate_deg_s.tobytes() == slow.rate_deg_s.tobytes()
    assert fast.time_s.tobytes() == slow.time_s.tobytes()
    assert fast.notes == slow.notes
    assert (fast.restarts is None) == (slow.restarts is None)
    if fast.true_rate_deg_s is not None or slow.true_rate_deg_s is not None:
        assert fast.true_rate_deg_s.tobytes() == slow.true_rate_deg_s.tobytes()


def test_the_engine_reads_the_file_and_the_loop_agrees(tmp_path, monkeypatch):
    """The engine answers (it is not left to the loop) and gives the loop's bits."""
    rng = np.random.default_rng(1)
    y = rng.standard_normal(5000)
    path = tmp_path / "r.csv"
    path.write_text("time,rate,true_rate,temp\n" + "".join(
        f"{i / 100:.2f},{v!r},{v / 3!r},21.5\n" for i, v in enumerate(y.tolist())))
    calls = []
    real = recording.numeric_columns
    monkeypatch.setattr(recording, "numeric_columns", lambda *a, **k: calls.append(real(*a, **k)) or calls[-1])
    fast = recording.read_recording(path)
    assert calls and calls[0] is not None
    monkeypatch.setattr(recording, "numeric_columns", real)
    assert fast.rate_deg_s.tobytes() == y.tobytes()
    _same(*_both(path))


@pytest.mark.parametrize("body", [
    "0,1.5\n1,2.5\n",                                  # plain
    "0,1.5\n\n1,2.5\n\n",                              # blank lines
    "0,1.5\n1,nan\n", "0,1.5\n1,inf\n", "0,1.5\n1,-Infinity\n",
    "0,1.5\n1,\n", "0,1.5\n1\n", "0,1.5\n1,2,3\n", "0,1.5\n1,2.5,\n",
    "0,1.5\n1,1_5\n", "0,1.5\n1,0x10\n", "0,1.5\n1,abc\n", "0,1.5\n1,1e400\n",
    "0,+1.5\n1,.5\n2,5.\n3,1E-3\n", "0, 1.5\n1,2.5 \n", '0,"1.5"\n1,2.5\n',
    "1700000000000000000,1\n1700000000010000000,2\n1700000000020000000,3\n",     # ns since 1970
    "1700000000000000000,1\n17,2\n", "-1700000000000000000,1\n-1700000000010000000,2\n",
    "2024-01-01T00:00:00,1\n2024-01-01T00:00:01,2\n", "true,1\nfalse,2\n",
])
def test_odd_cells_read_as_the_loop_reads_them(tmp_path, body):
    path = tmp_path / "r.csv"
    path.write_text("time,rate\n" + body)
    _same(*_both(path))


@pytest.mark.parametrize("text", [
    "time;rate\n0;1,5\n1;2,5\n",                      # decimal commas
    "time\trate\n0\t1.5\n1\t2.5\n",
    "time rate\n0 1.5\n1 2.5\n",                       # runs of spaces: the loop
    "time,rate\ns,deg/s\n0,1.5\n1,2.5\n",              # a units row
    "time,rate\n\ns,rad/s\n0,1.5\n1,2.5\n",            # a units row after a blank line
    "\ufefftime,rate\n0,1.5\n1,2.5\n",                 # BOM
])
def test_separators_and_units_rows_as_the_loop(tmp_path, text):
    path = tmp_path / "r.csv"
    path.write_text(text, encoding="utf-8")
    _same(*_both(path))


def test_gzip_and_undecodable_bytes(tmp_path):
    path = tmp_path / "r.csv.gz"
    with gzip.open(path, "wt") as f:
        f.write("time,rate\n" + "".join(f"{i},{i * 0.25}\n" for i in range(100)))
    _same(*_both(path))
    bad = tmp_path / "bad.csv"
    bad.write_bytes(b"time,rate,label\n0,1.5,a\n1,2.5,\xff\n")
    fast, slow = _both(bad)
    assert fast == slow and "undecodable" in fast


def test_a_spike_note_names_the_line_of_the_file(tmp_path):
    """The notes' line numbers come from the file (no text held): blank lines counted."""
    y = 0.01 * np.random.default_rng(3).standard_normal(400)
    y[200] = 50.0
    lines = [f"{i / 100},{v!r}" for i, v in enumerate(y.tolist())]
    lines.insert(100, "")
    path = tmp_path / "r.csv"
    path.write_text("time,rate\n" + "\n".join(lines) + "\n")
    fast, slow = _both(path)
    _same(fast, slow)
    assert any("line 203" in n for n in fast.notes)


FLOAT_TEXT = st.floats(allow_nan=False, allow_infinity=False, width=64).flatmap(
    lambda v: st.sampled_from([repr(v), f"{v:.6g}", f"{v:e}", f"{v:.17e}", f"{v:.3f}", f"{v:E}"]))


@settings(max_examples=60, deadline=None)
@given(st.lists(FLOAT_TEXT, min_size=3, max_size=30))
def test_any_float_text_gives_the_loops_bits(tmp_path_factory, cells):
    path = tmp_path_factory.mktemp("f") / "r.csv"
    path.write_text("time,rate\n" + "".join(f"{i},{c}\n" for i, c in enumerate(cells)))
    _same(*_both(path, sample_rate_hz=None))


def test_the_engine_holds_each_column_once(tmp_path):
    """The arrays are filled in place (sized from the file) and cut to the rows read."""
    path = tmp_path / "r.csv"
    n = 30000
    path.write_text("time,rate\n" + "".join(f"{i},{i % 7}.5\n" for i in range(n)))
    got = stream.numeric_columns(stream.TextFile(path), 1, 2, {"time": 0, "rate": 1}, ",", "time")
    assert got["rate"].shape == (n,) and got["rate"][-1] == (n - 1) % 7 + 0.5
    assert got["time"].dtype == np.float64 and got["time"][-1] == n - 1
