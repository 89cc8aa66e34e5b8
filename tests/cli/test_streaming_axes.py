"""``allan`` and ``denoise`` over several axes on the chunked reader (gyrodenoise.io.chunked.
open_axes): the output of the whole-array run (gyrodenoise.io.recording.read_axes), the
denoised CSV bit for bit and each axis' Allan curve to 1e-9 relative (the block sums add in
another order), with chunks of 333 samples on three gyro and three accelerometer columns
with a time column and a restart."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gyrodenoise.cli import main
from tests.io.test_stream_axes import imu_record

pytest.importorskip("pyarrow")


@pytest.fixture
def runs(monkeypatch):
    """run(argv, chunked): main(argv) on the chunked reader (the whole-array reader refused)
    or on the whole-array reader (the chunked one answering None)."""
    import gyrodenoise.io.chunked as C
    import gyrodenoise.io.recording as R
    monkeypatch.setattr(C, "CHUNK", 333)
    opener, reader = C.open_axes, R.read_axes

    def refused(*a, **k):
        raise AssertionError("the whole-array reader ran")

    def run(argv, chunked: bool) -> int:
        with monkeypatch.context() as m:
            if chunked:
                m.setattr(R, "read_axes", refused)
                m.setattr(C, "open_axes", opener)
            else:
                m.setattr(C, "open_axes", lambda *a, **k: None)
                m.setattr(R, "read_axes", reader)
            return main(argv)
    return run


@pytest.mark.parametrize("form", [["--causal"], [], ["--method", "shakf"]])
@pytest.mark.parametrize("cols", [[], ["--rate-column", "gx,gy,gz"]])
def test_denoise_axes_chunked_writes_the_whole_runs_bytes(tmp_path, runs, form, cols):
    p = tmp_path / "imu.csv"
    imu_record(p)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    method = [] if "--method" in form else ["--method", "motion"]
    assert runs(["denoise", str(p), "-o", str(a), *method, *form, *cols], chunked=True) == 0
    assert runs(["denoise", str(p), "-o", str(b), *method, *form, *cols], chunked=False) == 0
    assert a.read_bytes() == b.read_bytes()
    head = a.read_text().splitlines()[0]
    assert head == ("time,gx,gx_filtered,gy,gy_filtered,gz,gz_filtered" +
                    ("" if cols else ",ax,ax_filtered,ay,ay_filtered,az,az_filtered"))
    filtered = np.loadtxt(a, delimiter=",", skiprows=1)[:, 2::2]
    assert np.isfinite(filtered).all() and filtered.shape[0] == 2368


def test_allan_axes_chunked_is_the_whole_curve(tmp_path, runs, capsys):
    p = tmp_path / "imu.csv"
    imu_record(p, n=6000)
    assert runs(["allan", str(p), "--json"], chunked=True) == 0
    got = json.loads(capsys.readouterr().out)
    assert runs(["allan", str(p), "--json"], chunked=False) == 0
    want = json.loads(capsys.readouterr().out)
    assert got["notes"] == want["notes"] and got["n_samples"] == want["n_samples"]
    assert got["sample_rate_hz"] == want["sample_rate_hz"] and list(got["axes"]) == list(want["axes"])
    for col, w in want["axes"].items():
        g = got["axes"][col]
        key = "adev_deg_h" if w["sensor"] == "gyro" else "adev_m_s_h"
        np.testing.assert_array_equal(g["tau_s"], w["tau_s"])
        np.testing.assert_allclose(g[key], w[key], rtol=1e-9)
        for k, v in w["terms"].items():
            assert g["terms"][k] == pytest.approx(v, rel=1e-6, abs=1e-300), (col, k)
        for k, v in w.items():     # the scalars: the strings and flags equal, the numbers to rounding
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                assert g[k] == pytest.approx(v, rel=1e-6, abs=1e-300), (col, k)
            elif not isinstance(v, (list, dict)):
                assert g[k] == v, (col, k)
        assert g["bounds"] == w["bounds"] and g["sensor"] == w["sensor"] and g["unit_read"] == w["unit_read"]
