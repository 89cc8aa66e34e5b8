"""Table 1 (:func:`gyrodenoise.analysis.experiments.compare`) of a record given in chunks,
in memory bounded by the chunk size whatever the record's length.

* the filters (kf, shakf, motion) run a chunk at a time, each with its whole state carried
  from chunk to chunk (the one-shot outputs, bit for bit), their outputs written to binary
  spool files in ``folder`` (8 bytes a sample each, on disk);
* the AR-fitted sequence is drawn a chunk at a time from the shakf filter's final state
  (:func:`~gyrodenoise.analysis.experiments.ar_fit_chunks`: the same values, bit for bit);
* each series' Allan curve is :func:`~gyrodenoise.analysis.allan.allan_of_chunks` at the
  taus ``compare`` uses (its phase carried as ``np.cumsum``'s, the sums read in the same
  blocks: the curve of ``allan``, bit for bit, and so the same fit);
* the std about the mean (Eq. 41) from running sums in two passes: the whole-array figure
  to rounding (numpy's pairwise sum over the whole array adds in another order; within
  1e-12 relative).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gyrodenoise.analysis.allan import allan_of_chunks, default_m
from gyrodenoise.analysis.experiments import (AR_METHOD, METHODS, ar_fit_chunks, compare_table, paper_params,
                                              warmup_skipped)
from gyrodenoise.core import kernels as K
from gyrodenoise.core.batch import run as batch_run
from gyrodenoise.io.chunked import Spool

#: the record's (rate, restarts or None) chunks, read again at each call
Chunks = Callable[[], Iterable[tuple[np.ndarray, np.ndarray | None]]]
#: samples of the AR-fitted sequence drawn at a time
AR_CHUNK = 1 << 20


def compare_chunks(chunks: Chunks, n: int, fs: float, folder: str | Path, *, source: str | None = None,
                   notes: Sequence[str] = (), ar_order: int = 3, seed: int = 0, skip_warmup: bool = True,
                   ar_chunk: int = AR_CHUNK, **kw: Any) -> dict[str, Any]:
    """``compare`` of the record of ``n`` samples at ``fs`` Hz that ``chunks()`` yields
    (module docstring); ``folder``: where the filters' outputs are spooled (the caller
    removes it)."""
    p = paper_params(ar_order, fs, **kw)
    start = warmup_skipped(p, n, skip_warmup)
    params = {m: K.make_params(ar_order=ar_order, method=m, sample_rate_hz=fs, **kw) for m in METHODS}
    states = {m: K.init_state(params[m]) for m in METHODS}
    spools = {m: Spool(Path(folder) / f"compare_{m}", np.dtype(np.float64)) for m in METHODS}
    first = None
    for z, restarts in chunks():
        if first is None and len(z):
            first = float(z[0])
        for m in METHODS:
            out, states[m] = batch_run(params[m], states[m], z, restarts)
            spools[m].append(out)
    st = list(states[AR_METHOD])
    size = max(1, int(ar_chunk))

    def spooled(m: str) -> Callable[[], Iterator[np.ndarray]]:
        return lambda: (spools[m].read(a, min(a + size, n)) for a in range(0, n, size))

    sources: dict[str, Callable[[], Iterable[np.ndarray]]] = {
        "raw": lambda: (z for z, _ in chunks()),
        "ar_fit": lambda: ar_fit_chunks(p, st, n, first if first is not None else 0.0, seed, size),
        **{m: spooled(m) for m in METHODS}}
    ms = default_m(n - start)
    results = {k: allan_of_chunks(_after(src(), start), fs, m=ms, spill_dir=str(folder))
               for k, src in sources.items()}
    stds = {k: _std(lambda k=k: _after(sources[k](), start)) for k in ("raw",) + METHODS}
    for s in spools.values():
        s.path.unlink(missing_ok=True)
    return compare_table(source, n, fs, notes, ar_order, p, st, start, results, stds)


def _after(chunks: Iterable[np.ndarray], start: int) -> Iterator[np.ndarray]:
    """The chunks without the first ``start`` samples of the record."""
    seen = 0
    for c in chunks:
        k = len(c)
        if seen + k > start:
            yield c[max(0, start - seen):]
        seen += k


def _std(chunks: Callable[[], Iterable[np.ndarray]]) -> float:
    """`paper_std` (the std about the mean, Eq. 41) of the chunks ``chunks()`` yields, in
    two passes: the mean, then the mean square about it."""
    total, count = 0.0, 0
    for c in chunks():
        total += float(np.sum(c))
        count += len(c)
    mean = total / count
    sq = 0.0
    for c in chunks():
        d = np.asarray(c, dtype=np.float64) - mean
        sq += float(np.dot(d, d))
    return float(math.sqrt(sq / count))
