"""The Allan sums in numpy blocks and from chunks: equal to the former per-sample loop,
exact against a correctly rounded sum, and in memory that does not grow with the record."""
import math
import tracemalloc

import numpy as np
import pytest

from gyrodenoise.analysis import allan as A


def _loop_sums(phase, ms):
    """The former Allan sums (the numba kernel's loop, run as plain Python here)."""
    out = np.empty(len(ms))
    for i, m in enumerate(ms):
        v = [phase[k + 2 * m] - 2.0 * phase[k + m] + phase[k] for k in range(phase.shape[0] - 2 * m)]
        acc = 0.0
        for x in v:
            acc += x * x
        out[i] = acc
    return out


def _record(n, seed=0):
    """A biased rate with white noise and a random walk (the bias makes the phase large,
    the differences small: the cancellation a real record has)."""
    rng = np.random.default_rng(seed)
    return 0.3 + 0.02 * rng.standard_normal(n) + 1e-4 * rng.standard_normal(n).cumsum()


def test_block_sums_equal_the_former_loop():
    n, fs = 40_001, 100.0
    y = _record(n)
    ms = A.octave_m(n)
    phase = np.concatenate(([0.0], np.cumsum(y))) * (1.0 / fs)
    sums = _loop_sums(phase, ms)
    ref = np.sqrt(sums / (2.0 * (ms / fs) ** 2 * (n + 1 - 2 * ms)))
    tau, ad, _, _ = A.adev(y, fs, m=ms)
    np.testing.assert_allclose(tau, ms / fs)
    np.testing.assert_allclose(ad, ref, rtol=1e-12, atol=0)


@pytest.mark.parametrize("block", [7, 64, 1 << 18])
def test_chunks_equal_the_whole_record(block, monkeypatch):
    """Chunks of uneven size, and blocks smaller than 2m (the shifted reads): the same
    sums bit for bit as the whole record in memory."""
    monkeypatch.setattr(A, "BLOCK", block)
    n, fs = 30_011, 50.0
    y = _record(n, seed=3)
    whole = A.adev(y, fs, m=A.default_m(n))
    cuts = np.cumsum(np.random.default_rng(1).integers(1, 5000, size=20))
    chunks = np.split(y, cuts[cuts < n])
    part = A.adev_of_chunks(iter(chunks), fs, m=A.default_m(n))
    for w, p in zip(whole, part):
        np.testing.assert_allclose(p, w, rtol=1e-12, atol=0)


def test_a_million_samples_are_summed_exactly():
    """On 1e6 samples the block sums agree with math.fsum of the same terms to 1e-14."""
    n, fs = 1_000_003, 100.0
    y = _record(n, seed=7)
    tau, ad, _, _ = A.adev_of_chunks((y[i:i + 65_537] for i in range(0, n, 65_537)), fs)
    phase = np.concatenate(([0.0], np.cumsum(y))) * (1.0 / fs)
    for i in (0, len(tau) // 2, len(tau) - 1):
        m = int(round(tau[i] * fs))
        v = phase[2 * m:] - 2.0 * phase[m:-m] + phase[:-2 * m]
        exact = math.sqrt(math.fsum(v * v) / (2.0 * tau[i] ** 2 * (n + 1 - 2 * m)))
        assert ad[i] == pytest.approx(exact, rel=1e-14, abs=0)


def _peak_bytes(n, chunk=100_000):
    def chunks():
        rng = np.random.default_rng(0)
        for a in range(0, n, chunk):
            yield 0.01 * rng.standard_normal(min(chunk, n - a))
    tracemalloc.start()
    try:
        res = A.allan_of_chunks(chunks(), 100.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert res.n_samples == n
    print(f"peak {peak / 1e6:.1f} MB for {n} samples")
    return peak


@pytest.mark.slow
def test_peak_memory_does_not_grow_with_the_length():
    """2 M and 8 M samples (16 and 64 MB as an array): the same peak, a few blocks."""
    small, large = _peak_bytes(2_000_000), _peak_bytes(8_000_000)
    assert large < 24e6, large
    assert large < 1.3 * small, (small, large)


def test_octave_taus_and_bad_chunks():
    assert list(A.octave_m(20)) == [1, 2, 4, 8]
    assert A.octave_m(2).size == 0
    with pytest.raises(ValueError, match="sample 12"):
        A.adev_of_chunks([np.zeros(10), np.array([0.0, 0.0, np.nan])], 1.0)
    with pytest.raises(ValueError, match="at least 5"):
        A.allan_of_chunks([np.zeros(3)], 1.0)
