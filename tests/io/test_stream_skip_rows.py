"""``--skip-rows N``: the first N lines skipped before the header row is looked for, by the
whole-array reader and the chunked one alike (`recording.text_layout`), for the free text
the automatic preamble detection refuses (a header row that holds a number); without it
such a file is refused in one line naming ``--skip-rows``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gyrodenoise.cli import main
from gyrodenoise.errors import InputError
from gyrodenoise.io.recording import read_recording

PREAMBLE = ['Bench run 7, operator said "keep still\n', "serial 42\n"]


def _write(path, n=400, preamble=PREAMBLE, header="time,rate,1000\n", seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    r = rng.normal(0.0, 0.05, n)
    with open(path, "w") as f:
        f.writelines(preamble)
        f.write(header)
        f.writelines(f"{a!r},{b!r},{k}\n" for k, (a, b) in enumerate(zip(t.tolist(), r.tolist())))
    return t, r


def test_refused_without_it_naming_the_option(tmp_path):
    p = tmp_path / "r.csv"
    _write(p)
    with pytest.raises(InputError) as e:
        read_recording(p)
    msg = str(e.value)
    assert "--skip-rows 2" in msg and "line 3" in msg and "\n" not in msg


def test_read_after_the_skipped_lines(tmp_path):
    p = tmp_path / "r.csv"
    t, r = _write(p)
    rec = read_recording(p, skip_rows=2)
    assert np.array_equal(rec.rate_deg_s, r) and np.array_equal(rec.time_s, t)
    assert any(n.startswith("2 line(s) skipped before the header row (--skip-rows 2): Bench run 7")
               for n in rec.notes)
    assert any("ignored columns: 1000" in n for n in rec.notes)


def test_the_chunked_reader_reads_the_same(tmp_path):
    pytest.importorskip("pyarrow")
    from gyrodenoise.io.chunked import open_stream
    p = tmp_path / "r.csv"
    _write(p)
    rec = read_recording(p, skip_rows=2)
    with open_stream(p, skip_rows=2, chunk=7) as s:
        assert s is not None
        parts = list(s.chunks(7))
        assert s.notes == rec.notes
    assert np.array_equal(np.concatenate([c[1] for c in parts]), rec.rate_deg_s)
    assert np.array_equal(np.concatenate([c[0] for c in parts]), rec.time_s)


def test_a_preamble_after_the_skipped_lines_is_still_detected(tmp_path):
    p = tmp_path / "r.csv"
    t, r = _write(p, preamble=["line one 1\n", "Gyro FOG-200\n", "calibrated\n"], header="time,rate,gain\n")
    rec = read_recording(p, skip_rows=1)
    assert np.array_equal(rec.rate_deg_s, r)
    assert any("skipped as a preamble" in n and "Gyro FOG-200" in n for n in rec.notes)


@pytest.mark.parametrize("skip", [50, -1])
def test_a_skip_beyond_the_file_or_negative_is_one_line(tmp_path, skip):
    p = tmp_path / "r.csv"
    _write(p, n=20)
    with pytest.raises(InputError, match="--skip-rows") as e:
        read_recording(p, skip_rows=skip)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("cmd", [["allan", "--json"], ["compare", "--json"]])
def test_commands_take_the_option(tmp_path, capsys, cmd):
    p = tmp_path / "r.csv"
    _write(p, n=2000)
    assert main([cmd[0], str(p), "--rate-column", "rate", "--skip-rows", "2", *cmd[1:]]) == 0
    d = json.loads(capsys.readouterr().out)
    assert any("--skip-rows 2" in n for n in d["notes"])


def test_without_the_option_the_command_names_it(tmp_path, capsys):
    p = tmp_path / "r.csv"
    _write(p, n=200)
    assert main(["allan", str(p), "--rate-column", "rate"]) == 2
    err = capsys.readouterr().err
    assert "--skip-rows 2" in err and "Traceback" not in err
