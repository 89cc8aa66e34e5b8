"""The offline smoother's checkpoints (batch.smooth_motion): the two banks restarted from
their saved states at each block's edge give the bits of one pass over the whole run
(one block as long as the run: no checkpoint at all), whatever the block size, the run's
length and where the restarts fall against the blocks."""

import numpy as np
import pytest

from gyrodenoise.core import batch
from gyrodenoise.core import kernels as K

FS = 100.0


def _record(n, seed):
    """Noise on a rate that moves (a sine burst, a step): every branch of the smoother runs."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    return 0.05 * rng.standard_normal(n) + 2.0 * np.sin(2 * np.pi * 0.7 * t) * (t % 4 < 1.5) + 5.0 * (t > t[-1] / 2)


def _params():
    p = list(K.make_params(3, "motion", sample_rate_hz=FS, warmup_s=0.2))
    p[K.P_MO_VAR] = 1.0           # as run_offline sets it
    return p


def _one_pass(monkeypatch, f):
    """``f()`` with one block longer than any run here: the banks recorded in one pass."""
    with monkeypatch.context() as m:
        m.setattr(batch, "SMOOTH_BLOCK", 1 << 30)
        return f()


@pytest.mark.parametrize("n", [1, 2, 6, 7, 8, 13, 14, 15, 50, 401])
@pytest.mark.parametrize("block", [1, 7])
def test_blocks_give_the_bits_of_one_pass(monkeypatch, n, block):
    z = _record(n, n)
    p = _params()
    ref = _one_pass(monkeypatch, lambda: batch.smooth_motion(p, z))
    monkeypatch.setattr(batch, "SMOOTH_BLOCK", block)
    assert batch.smooth_motion(p, z).tobytes() == ref.tobytes()


@pytest.mark.parametrize("cuts", [[7], [14, 15], [3, 21, 22, 70], [1, 2, 399]])
def test_restarts_at_and_beside_block_edges(monkeypatch, cuts):
    """run_offline with restarts on block edges (multiples of 7), one sample beside them and
    runs of 1 sample: the same bits as one pass per run."""
    n = 400
    z = _record(n, 11)
    rs = np.zeros(n, dtype=bool)
    rs[cuts] = True
    p = K.make_params(3, "motion", sample_rate_hz=FS, warmup_s=0.2)
    ref = _one_pass(monkeypatch, lambda: batch.run_offline(p, z, rs))
    monkeypatch.setattr(batch, "SMOOTH_BLOCK", 7)
    assert batch.run_offline(p, z, rs).tobytes() == ref.tobytes()


def test_plain_python_kernels_take_the_checkpoints_too(monkeypatch):
    z = _record(120, 4)
    p = _params()
    ref = _one_pass(monkeypatch, lambda: batch.smooth_motion(p, z, compiled=False))
    monkeypatch.setattr(batch, "SMOOTH_BLOCK", 7)
    assert batch.smooth_motion(p, z, compiled=False).tobytes() == ref.tobytes()
    assert batch.smooth_motion(p, z).tobytes() == ref.tobytes()      # and the C core's


class _Sliced:
    """A record read a slice at a time (a spilled one): only len() and [lo:hi]; counts the
    largest slice asked for."""

    def __init__(self, z):
        self.z, self.largest = z, 0

    def __len__(self):
        return self.z.shape[0]

    def __getitem__(self, s):
        piece = self.z[s].copy()
        self.largest = max(self.largest, piece.shape[0])
        return piece


def test_a_record_read_by_slices_into_a_given_output(monkeypatch):
    """``seg`` only sliced (never read whole) and ``out`` filled: the same bits, and no slice
    longer than a block and a sample (the non-finite stand-in, which reads the run, is not
    needed here)."""
    z = _record(300, 9)
    p = _params()
    ref = batch.smooth_motion(p, z)
    monkeypatch.setattr(batch, "SMOOTH_BLOCK", 16)
    src, out = _Sliced(z), np.full(300, np.nan)
    got = batch.smooth_motion(p, src, out=out)
    assert got is out and out.tobytes() == ref.tobytes()
    assert src.largest <= 17


def test_non_finite_samples_and_the_stand_in_across_blocks(monkeypatch):
    """NaN samples pass through and an output that would overflow takes the causal blend,
    in blocks as in one pass."""
    z = _record(200, 5)
    z[[3, 50, 51, 150]] = np.nan
    z[100:103] = [1e308, -1e308, 1e308]
    p = _params()
    ref = _one_pass(monkeypatch, lambda: batch.smooth_motion(p, z))
    monkeypatch.setattr(batch, "SMOOTH_BLOCK", 7)
    got = batch.smooth_motion(p, z)
    assert got.tobytes() == ref.tobytes()
    assert np.isnan(got[[3, 50, 51, 150]]).all()


def test_memory_grows_by_the_output_only():
    """The smoother's traced peak (numpy's allocations included) over 150,000 samples more:
    the output's 8 bytes a sample and a checkpoint's state per block; the whole-run records
    (704 bytes a sample, 100 MB here) are gone."""
    import tracemalloc
    p = K.make_params(3, "motion", sample_rate_hz=1000.0)
    peaks = []
    for n in (50_000, 200_000):
        z = np.random.default_rng(n).standard_normal(n)
        tracemalloc.start()
        batch.run_offline(p, z)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert peaks[1] - peaks[0] < 150_000 * 16


@pytest.mark.parametrize("nonfinite", [False, True])
def test_run_offline_on_a_spooled_record_into_a_spooled_output(monkeypatch, tmp_path, nonfinite):
    """run_offline reading its record from a spool file and writing its output to another
    (io.chunked.SpoolSlice: what ``denoise`` on a streamed record does), restarts on and
    beside the blocks of 7: the bits of the in-memory run (the non-finite stand-in's index
    writes too)."""
    from gyrodenoise.io.chunked import Spool, SpoolSlice
    n = 300
    z = _record(n, 12)
    if nonfinite:
        z[[3, 50]] = np.nan
        z[100:103] = [1e308, -1e308, 1e308]
    rs = np.zeros(n, dtype=bool)
    rs[[14, 15, 200]] = True
    p = K.make_params(3, "motion", sample_rate_hz=FS, warmup_s=0.2)
    monkeypatch.setattr(batch, "SMOOTH_BLOCK", 7)
    ref = batch.run_offline(p, z, rs)
    src, dst = Spool(tmp_path / "in", np.dtype(np.float64)), Spool(tmp_path / "out", np.dtype(np.float64))
    src.append(z)
    batch.run_offline(p, SpoolSlice(src), rs, out=SpoolSlice(dst, 0, n))
    assert dst.n == n and dst.read(0, n).tobytes() == ref.tobytes()
