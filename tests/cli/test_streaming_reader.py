"""The commands on the chunked reader (gyrodenoise.io.chunked): ``denoise`` (causal and
offline) writes the bytes of the whole-array run; ``allan`` gives its Allan curve to
rounding (the block sums add in another order: 1e-9 relative); peak memory of the reader
bounded where the whole-array reader's grows."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from gyrodenoise.cli import main
from gyrodenoise.io.recording import read_recording, write_recording

pytest.importorskip("pyarrow")


def _record(path, n=3000, seed=2):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 200.0
    keep = np.ones(n, bool)
    keep[[400, 401]] = False          # a bridged gap
    keep[1500:1530] = False           # a restarting gap
    t = t[keep]
    r = np.cumsum(rng.normal(0, 1e-3, t.size)) + rng.normal(0, 0.05, t.size)
    with open(path, "w") as f:
        f.write("time,rate\n")
        f.writelines(f"{a!r},{b!r}\n" for a, b in zip(t.tolist(), r.tolist()))


@pytest.mark.parametrize("form", [["--causal"], []])
def test_denoise_stream_writes_the_whole_runs_bytes(tmp_path, form, monkeypatch):
    import gyrodenoise.io.stream as st
    monkeypatch.setattr(st, "CHUNK", 333)       # many chunks
    p = tmp_path / "r.csv"
    _record(p)
    out = tmp_path / "o.csv"
    assert main(["denoise", str(p), "-o", str(out), "--method", "motion", *form]) == 0
    rec = read_recording(p)
    from gyrodenoise.denoiser import denoise
    want = denoise(rec.rate_deg_s, rec.sample_rate_hz, method="motion", restarts=rec.restarts,
                   offline=not form)
    ref = tmp_path / "ref.csv"
    write_recording(ref, rec.time_s, rec.rate_deg_s, want)
    assert out.read_bytes() == ref.read_bytes()


def test_allan_stream_matches_whole(tmp_path, capsys):
    from gyrodenoise.analysis.allan import allan
    p = tmp_path / "r.csv"
    _record(p)
    assert main(["allan", str(p), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    rec = read_recording(p)
    res = allan(rec.rate_deg_s, rec.sample_rate_hz)
    np.testing.assert_allclose(d["tau_s"], res.tau_s, rtol=0)
    np.testing.assert_allclose(d["adev_deg_h"], res.adev_deg_h, rtol=1e-9)
    for k, v in res.terms.items():
        assert d["terms"][k] == pytest.approx(float(v), rel=1e-6, abs=1e-300)
    assert d["notes"] == rec.notes


def test_save_columns_is_savetxt(tmp_path):
    from gyrodenoise.io.stream import save_columns
    rng = np.random.default_rng(0)
    cols = [np.arange(5000) / 1000, rng.normal(0, 1, 5000),
            np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, 1.2345678901234e300, 123456789012.0] * 625)]
    np.savetxt(tmp_path / "a.csv", np.column_stack(cols), delimiter=",", header="a,b,c", comments="", fmt="%.10g")
    save_columns(tmp_path / "b.csv", cols, "a,b,c", size=777)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


PEAK = textwrap.dedent("""
    import sys
    import numpy as np
    path, how = sys.argv[1], sys.argv[2]
    if how == "stream":
        import gyrodenoise.io.chunked as C, gyrodenoise.io.timebase as T
        C.MEDIAN_SAMPLE = T.MEDIAN_SAMPLE = 100_000   # the capped samples small: what is left is the chunks'
        from gyrodenoise.io.chunked import open_stream
        with open_stream(path, sample_rate_hz=None, chunk=1 << 16) as s:
            for c in s.chunks(1 << 16):
                pass
    else:
        from gyrodenoise.io.recording import read_recording
        read_recording(path)
    print(next(int(ln.split()[1]) for ln in open("/proc/self/status") if ln.startswith("VmHWM")) / 1024)
""")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
def test_stream_peak_memory_is_bounded(tmp_path):
    """0.5 M and 2 M samples: the chunked reader's peak grows by less than 50 MB where the
    whole-array reader's grows by over 100 MB (~90 bytes a sample). The medians' evenly
    spread samples (at most 4 M time steps, 2 M differences of the rate: 48 MB) are capped
    at 0.2 M here, so that what grows is what the chunking leaves."""
    from gyrodenoise.io.stream import write_rows
    peaks = {}
    for n in (500_000, 2_000_000):
        p = tmp_path / f"r{n}.csv"
        t = np.arange(n, dtype=np.int64) * 1000           # us
        r = np.random.default_rng(0).normal(0, 1, n).round(4)
        with open(p, "wb") as f:
            f.write(b"time,rate\n")
            write_rows(f, [t, r], "%.10g")
        for how in ("stream", "whole"):
            peaks[how, n] = float(subprocess.run([sys.executable, "-c", PEAK, str(p), how], capture_output=True,
                                                 text=True, check=True).stdout)
    grow = {how: peaks[how, 2_000_000] - peaks[how, 500_000] for how in ("stream", "whole")}
    assert grow["stream"] < 50, peaks
    assert grow["whole"] > 100, peaks
