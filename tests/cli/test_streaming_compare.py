"""``compare`` of a record read a chunk at a time (gyrodenoise.analysis.compare_chunks): the
whole-array Table 1 with chunks of a few samples: the filters' outputs, the AR model, the
Allan curves and terms bit for bit; the std about the mean to 1e-12 relative (numpy's
pairwise sum over the whole array adds in another order)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gyrodenoise.analysis.compare_chunks import compare_chunks
from gyrodenoise.analysis.experiments import compare
from gyrodenoise.cli.commands import public
from gyrodenoise.cli import main
from gyrodenoise.io.recording import read_recording
from gyrodenoise.simulator import Record

pytest.importorskip("pyarrow")

STD_RTOL = 1e-12


def _chunks(z, restarts, size):
    def gen():
        for a in range(0, len(z), size):
            yield z[a:a + size], None if restarts is None else restarts[a:a + size]
    return gen


def _same_table(got, want):
    assert got["rows"] == want["rows"]
    assert got["bounds"] == want["bounds"]
    assert got["ar_model"] == want["ar_model"]
    assert got["n_samples"] == want["n_samples"] and got["skipped_warmup_samples"] == want["skipped_warmup_samples"]
    assert got["fit_agreement"] == want["fit_agreement"]
    for k, v in want["std_deg_s"].items():
        assert got["std_deg_s"][k] == pytest.approx(v, rel=STD_RTOL, abs=0)


@pytest.mark.parametrize("size,ar_chunk", [(7, 5), (1000, 1 << 20)])
def test_chunks_give_the_whole_table(tmp_path, size, ar_chunk):
    rng = np.random.default_rng(4)
    n, fs = 3000, 200.0
    z = np.cumsum(rng.normal(0, 1e-3, n)) + rng.normal(0, 0.05, n)
    restarts = np.zeros(n, bool)
    restarts[[0, 1400, 1407]] = True           # restarts inside and at the edge of a chunk of 7
    want = compare(Record(rate_deg_s=z, sample_rate_hz=fs, restarts=restarts, source="x"))
    got = compare_chunks(_chunks(z, restarts, size), n, fs, tmp_path, source="x", ar_chunk=ar_chunk)
    _same_table(got, want)
    assert list(tmp_path.iterdir()) == []       # the spools removed


def test_compare_command_streams(tmp_path, capsys, monkeypatch):
    import gyrodenoise.io.stream as st
    import gyrodenoise.io.chunked as ch
    monkeypatch.setattr(st, "CHUNK", 333)
    monkeypatch.setattr(ch, "CHUNK", 333)
    rng = np.random.default_rng(5)
    t = np.arange(4000) / 100.0
    keep = np.ones(t.size, bool)
    keep[2000:2050] = False                     # a restarting gap
    t = t[keep]
    r = np.cumsum(rng.normal(0, 1e-3, t.size)) + rng.normal(0, 0.05, t.size)
    p = tmp_path / "r.csv"
    with open(p, "w") as f:
        f.write("time,rate\n")
        f.writelines(f"{a!r},{b!r}\n" for a, b in zip(t.tolist(), r.tolist()))
    calls = []
    import gyrodenoise.analysis.compare_chunks as cc
    real = cc.compare_chunks
    monkeypatch.setattr(cc, "compare_chunks", lambda *a, **k: calls.append(1) or real(*a, **k))
    assert main(["compare", str(p), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert calls, "compare did not take the chunked path"
    rec = read_recording(p)
    assert rec.restarts is not None and rec.restarts.sum() == 1
    want = json.loads(json.dumps(public(compare(rec))))
    _same_table(got, want)
    assert got["notes"] == want["notes"] and got.get("warnings") == want.get("warnings")
