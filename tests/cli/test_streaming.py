"""`denoise` in chunks: the filter's whole state carried from chunk to chunk gives the
one-shot run's output bit for bit (every method, restarts on and beside the chunks' edges),
and the output CSV written a chunk of rows at a time is np.savetxt's, byte for byte."""

import numpy as np
import pytest

from gyrodenoise.core.methods import METHODS
from gyrodenoise.denoiser import Denoiser
from gyrodenoise.io import stream
from tests.helpers import run_main

FS = 100.0


def _record(n, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    return 0.05 * rng.standard_normal(n) + 2.0 * np.sin(2 * np.pi * 0.7 * t) + 3.0 * (t > t[-1] / 2)


@pytest.mark.parametrize("method", [m.name for m in METHODS])
@pytest.mark.parametrize("size", [1, 7])
def test_chunks_give_the_one_shot_bits(method, size):
    z = _record(300, 1)
    rs = np.zeros(z.size, dtype=bool)
    rs[[7, 8, 50, 140]] = True            # on a chunk's edge (7, 140), beside it, inside
    one = Denoiser(FS, method=method, warmup_s=0.2).process(z, rs)
    den = Denoiser(FS, method=method, warmup_s=0.2)
    got = stream.process_chunks(den, z, rs, size)
    assert got.tobytes() == one.tobytes()
    ref = Denoiser(FS, method=method, warmup_s=0.2)
    ref.process(z, rs)
    assert list(den.state) == list(ref.state)          # the whole state carried to the end


@pytest.mark.parametrize("n", [0, 1, 6, 7, 8, 20])
def test_the_writer_gives_savetxts_bytes(tmp_path, n):
    rng = np.random.default_rng(n)
    cols = [np.arange(n) / FS, rng.standard_normal(n), 1e300 * rng.standard_normal(n)]
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    np.savetxt(a, np.column_stack(cols) if n else np.empty((0, 3)), delimiter=",", header="time,raw,filtered",
               comments="", fmt="%.10g")
    stream.save_columns(b, cols, "time,raw,filtered", size=7)
    assert b.read_bytes() == a.read_bytes()


def test_denoise_causal_in_chunks_writes_the_one_shot_output(tmp_path, monkeypatch):
    """`denoise --causal` with chunks of 7 samples and a restart (a time gap) on a chunk's
    edge: the file holds Denoiser.process's one-shot output."""
    z = _record(400, 2)
    t = np.arange(400) / FS
    t[14:] += 1.0                          # a gap of 100 samples: sample 14 restarts the filter
    src = tmp_path / "r.csv"
    src.write_text("time,rate\n" + "".join(f"{a!r},{b!r}\n" for a, b in zip(t.tolist(), z.tolist())))
    monkeypatch.setattr(stream, "CHUNK", 7)
    out = tmp_path / "o.csv"
    status, _, err = run_main("denoise", src, "-o", out, "--causal", "--method", "motion")
    assert status == 0, err
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    rs = np.zeros(400, dtype=bool)
    rs[14] = True
    one = Denoiser(FS, method="motion").process(z, rs)
    assert np.array_equal(got[:, 2], np.array([float(f"{v:.10g}") for v in one]))
