"""Peak memory and time of the Allan deviation of long records: gyrodenoise's chunked
estimator (`gyrodenoise.analysis.allan.allan_of_chunks`: the cumulative sum carried from
chunk to chunk, the sums read in blocks) against ``pandas.read_csv`` + ``allantools.oadev``
on the same file, in the same run, at the same octave-spaced taus.

Each measurement runs in a fresh process; its peak resident memory is the kernel's
maximum resident set of that process (``/usr/bin/time -f %M``), its time the wall time of the work inside it
(reading included, interpreter start and imports excluded). The records (white noise plus
a random walk, seeded, deg/s at 100 Hz) are written once to ``--dir`` (default a folder in
the system's temporary directory, never the repository) as a one-column CSV and as .npy.

Rows:

* ``gyrodenoise, .npy chunks``: the record read 1 M samples at a time from the .npy file;
* ``gyrodenoise, CSV chunks``: read 1 M rows at a time by ``pandas.read_csv(chunksize=...)``;
* ``pandas + allantools``: ``pandas.read_csv`` of the whole file, then ``allantools.oadev``;
* ``imports only``: a process that imports what the gyrodenoise rows import (numpy, scipy,
  pandas, gyrodenoise) and stops: the floor under their peaks (the baseline also imports
  allantools).

The gyrodenoise rows include the five-term fit and the slope-point reads (allantools has
neither); every row imports numpy, scipy and pandas before its clock starts.

The curves of the rows are compared (largest relative difference printed).

    python benchmarks/records/allan_memory.py [--sizes 1e6,1e7,3e7] [--dir DIR] [--keep]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

FS = 100.0
CHUNK = 1 << 20


def write_records(n: int, folder: Path) -> tuple[Path, Path]:
    """The seeded record of ``n`` samples as ``rate_N.npy`` and ``rate_N.csv`` (column ``rate``)."""
    npy, csv = folder / f"rate_{n}.npy", folder / f"rate_{n}.csv"
    if npy.exists() and csv.exists():
        return npy, csv
    rng = np.random.default_rng(n)
    out = np.lib.format.open_memmap(npy, mode="w+", dtype=np.float64, shape=(n,))
    walk = 0.0
    with open(csv, "w") as f:
        f.write("rate\n")
        for a in range(0, n, CHUNK):
            k = min(CHUNK, n - a)
            rw = walk + np.cumsum(1e-5 * rng.standard_normal(k))
            walk = float(rw[-1])
            y = 0.2 + 0.01 * rng.standard_normal(k) + rw
            out[a:a + k] = y
            f.write("\n".join(map(repr, y.tolist())))    # every bit: the rows see the same data
            f.write("\n")
    out.flush()
    del out
    return npy, csv


def _npy_chunks(path: str):
    with open(path, "rb") as f:
        version = np.lib.format.read_magic(f)
        shape, _, dtype = (np.lib.format.read_array_header_1_0(f) if version == (1, 0)
                           else np.lib.format.read_array_header_2_0(f))
        left = shape[0]
        while left:
            y = np.fromfile(f, dtype=dtype, count=min(CHUNK, left))
            left -= y.shape[0]
            yield y


def _csv_chunks(path: str):
    import pandas as pd
    for df in pd.read_csv(path, chunksize=CHUNK, dtype={"rate": np.float64}):
        yield df["rate"].to_numpy()


def one(kind: str, path: str) -> dict:
    """The measurement ``kind`` on ``path`` in this process: time and the curve."""
    from gyrodenoise.analysis.allan import allan_of_chunks, octave_m
    if kind == IMPORTS:
        import pandas  # noqa: F401
        import scipy.optimize  # noqa: F401
        return {"wall_s": 0.0, "tau_s": [], "adev": []}
    if kind == "pandas + allantools":
        import allantools
        import pandas as pd
        import scipy.optimize  # noqa: F401  (the same imports as the other rows)
        t0 = time.perf_counter()
        y = pd.read_csv(path, dtype={"rate": np.float64})["rate"].to_numpy()
        taus = octave_m(y.shape[0]) / FS
        tau, ad, _, _ = allantools.oadev(y, rate=FS, data_type="freq", taus=taus)[:4]
        wall = time.perf_counter() - t0
        return {"wall_s": wall, "tau_s": list(map(float, tau)), "adev": list(map(float, ad))}
    import pandas  # noqa: F401  (imports excluded from the time, as for the baseline)
    import scipy.optimize  # noqa: F401
    chunks = {"gyrodenoise, .npy chunks": _npy_chunks, "gyrodenoise, CSV chunks": _csv_chunks}[kind](path)
    t0 = time.perf_counter()
    res = allan_of_chunks(chunks, FS)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "tau_s": list(map(float, res.tau_s)), "adev": list(map(float, res.adev_deg_s)),
            "exported_terms": res.exported_terms}


def measure(kind: str, path: Path) -> dict:
    """``one`` in a fresh process: its result and its peak resident memory (MB), read by
    /usr/bin/time (a small parent: a child forked from this process would start its
    maximum at this process's size); without it, ``os.wait4``'s (an upper bound)."""
    cmd = [sys.executable, __file__, "--one", kind, str(path)]
    with tempfile.NamedTemporaryFile("r", suffix=".maxrss") as rss:
        timer = shutil.which("time", path="/usr/bin")
        if timer:
            cmd = [timer, "-f", "%M", "-o", rss.name] + cmd
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE)
        assert proc.stdout is not None
        out = proc.stdout.read()
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise SystemExit(f"{kind} on {path} failed (exit {proc.returncode})")
        kb = float(rss.read().split()[-1]) if timer else usage.ru_maxrss      # Linux: kilobytes
    d = json.loads(out)
    d["peak_mb"] = kb / 1024.0
    return d


#: the row of a process that only imports what the others import: the memory no row can go below
IMPORTS = "imports only"
KINDS = ((IMPORTS, "npy"), ("gyrodenoise, .npy chunks", "npy"), ("gyrodenoise, CSV chunks", "csv"), ("pandas + allantools", "csv"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1e6,1e7,3e7", help="record lengths, samples (default 1e6,1e7,3e7)")
    ap.add_argument("--dir", default=None, help="folder for the records (default: a new temporary folder)")
    ap.add_argument("--keep", action="store_true", help="keep the records")
    ap.add_argument("--one", nargs=2, metavar=("KIND", "PATH"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(*args.one)))
        return
    folder = Path(args.dir) if args.dir else Path(tempfile.mkdtemp(prefix="gd_allan_memory_"))
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    try:
        for n in (int(float(s)) for s in args.sizes.split(",")):
            t0 = time.perf_counter()
            files = dict(zip(("npy", "csv"), write_records(n, folder)))
            print(f"# {n} samples: records written in {time.perf_counter() - t0:.0f} s "
                  f"({files['csv'].stat().st_size / 1e6:.0f} MB CSV)", flush=True)
            got = {kind: measure(kind, files[ext]) for kind, ext in KINDS}
            base = got["pandas + allantools"]
            for kind, _ in KINDS:
                d = got[kind]
                diff = (float(np.max(np.abs(np.array(d["adev"]) / np.array(base["adev"]) - 1.0)))
                        if d["adev"] else float("nan"))
                rows.append((n, kind, d["wall_s"], d["peak_mb"], d["wall_s"] / base["wall_s"],
                             d["peak_mb"] / base["peak_mb"], diff))
                print(f"  {kind:<26} {d['wall_s']:8.2f} s {d['peak_mb']:9.0f} MB"
                      + (f"   adev vs allantools {diff:.1e}" if diff == diff else ""), flush=True)
    finally:
        if not args.keep and not args.dir:
            shutil.rmtree(folder, ignore_errors=True)
    print()
    print(f"{'samples':>10}  {'':<26} {'time s':>8} {'peak MB':>9} {'time ratio':>11} {'memory ratio':>13}"
          f"  {'max |adev/allantools - 1|':>26}")
    for n, kind, wall, mb, rt, rm, diff in rows:
        print(f"{n:>10}  {kind:<26} {wall:8.2f} {mb:9.0f} {rt:11.2f} {rm:13.3f}  "
              + (f"{diff:26.1e}" if diff == diff else f"{'-':>26}"))
    print("(ratios to pandas.read_csv + allantools.oadev on the same file in the same run; peak = the "
          "process's maximum resident set, interpreter and imports included)")


if __name__ == "__main__":
    main()
