"""Peak memory and time of the commands on long records: ``gyrodenoise allan``,
``gyrodenoise denoise --causal`` and ``gyrodenoise denoise`` (the offline smoother) against
``pandas.read_csv`` + ``allantools.oadev`` on the same file, in the same run; stamped with
the commit.

Each row is a fresh process run under ``/usr/bin/time -f "%e %M"``: its wall time and its
maximum resident set (interpreter and imports included) as the kernel reports them. The
record is `allan_memory.write_records`'s (a seeded white noise plus random walk, one
``rate`` column, read at ``--sample-rate 100``), written once to ``--dir`` (default a new
temporary folder, never the repository). Rows:

* ``pandas.read_csv``: the file read, nothing else (the reader's yardstick);
* ``pandas + allantools``: read, then ``allantools.oadev`` at the octave taus (the baseline
  of the ratios);
* ``gyrodenoise allan``, ``gyrodenoise denoise --causal``, ``gyrodenoise denoise``
  (offline, the default form of ``motion`` on a file), ``gyrodenoise compare``: the
  commands as a user runs them, reading the CSV, writing their output (denoise: a CSV of
  time, raw and filtered);
* the same commands on the record with a ``time`` column (``time,rate``, seconds at
  ``FS``; rows marked ``[time]``): the time model read too;
* with ``--axes``: ``allan`` and both forms of ``denoise`` on a record of three gyro and three
  accelerometer columns with a time column (``time,gx,gy,gz,ax,ay,az``: the same series,
  scaled and offset; rows marked ``[6 axes]``), on the chunked reader and (rows marked
  ``[6 axes, whole]``) on the whole-array reader (``io.chunked.open_axes`` answering None);
  ``--axes-only`` runs these rows alone.

    python benchmarks/records/commands_memory.py [--sizes 1e6,1e7,3e7] [--axes | --axes-only] [--dir DIR] [--keep]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(HERE))

from allan_memory import FS, write_records  # noqa: E402

BASELINE = "pandas + allantools"
READ_ONLY = "pandas.read_csv"


def _python(code: str) -> list[str]:
    return [sys.executable, "-c", code]


def write_timed(n: int, folder: Path) -> Path:
    """The record of `write_records` with a ``time`` column (s at FS) as ``timed_N.csv``."""
    import numpy as np
    npy, _ = write_records(n, folder)
    out = folder / f"timed_{n}.csv"
    if out.exists():
        return out
    y = np.load(npy, mmap_mode="r")
    with open(out, "w") as f:
        f.write("time,rate\n")
        for a in range(0, n, 1 << 20):
            b = min(a + (1 << 20), n)
            t = np.arange(a, b) / FS
            f.write("".join(f"{u!r},{v!r}\n" for u, v in zip(t.tolist(), np.asarray(y[a:b]).tolist())))
    return out


def write_axes_record(n: int, folder: Path) -> Path:
    """The series of `write_records` as three gyro columns (deg/s) and three accelerometer
    columns about gravity (m/s^2), with a time column (s at FS), as ``imu_N.csv``."""
    import numpy as np
    npy, _ = write_records(n, folder)
    out = folder / f"imu_{n}.csv"
    if out.exists():
        return out
    y = np.load(npy, mmap_mode="r")
    row = "%r,%r,%r,%r,%r,%r,%r\n"
    with open(out, "w") as f:
        f.write("time,gx,gy,gz,ax,ay,az\n")
        for a in range(0, n, 1 << 18):
            b = min(a + (1 << 18), n)
            v = np.asarray(y[a:b])
            cols = np.column_stack([np.arange(a, b) / FS, v, 0.7 * v + 0.01, -v, 0.1 + 0.01 * v, -0.2 + 0.01 * v,
                                    9.81 + 0.01 * v])
            f.write((row * (b - a)) % tuple(cols.ravel().tolist()))
    return out


def axes_commands(imu: Path, out: Path) -> dict[str, list[str]]:
    """``allan`` and both forms of ``denoise`` on the six-axis record, on the chunked reader and
    on the whole-array one."""
    rows = {}
    for form, extra in (("allan", ["--json"]), ("denoise --causal", ["-o", str(out), "--causal"]),
                        ("denoise (offline)", ["-o", str(out)])):
        argv = [form.split()[0], str(imu), *extra]
        rows[f"gyrodenoise {form} [6 axes]"] = [sys.executable, "-m", "gyrodenoise.cli", *argv]
        rows[f"gyrodenoise {form} [6 axes, whole]"] = _python(
            "import sys\nimport gyrodenoise.io.chunked as C\nC.open_axes = lambda *a, **k: None\n"
            f"from gyrodenoise.cli import main\nsys.exit(main({argv!r}))")
    return rows


def gd_commands(rec: list[str], out: Path, tag: str = "") -> dict[str, list[str]]:
    """The gyrodenoise rows on the record ``rec`` (its path and options)."""
    gd = [sys.executable, "-m", "gyrodenoise.cli"]
    return {f"gyrodenoise allan{tag}": gd + ["allan"] + rec,
            f"gyrodenoise denoise --causal{tag}": gd + ["denoise"] + rec + ["-o", str(out), "--causal"],
            f"gyrodenoise denoise (offline){tag}": gd + ["denoise"] + rec + ["-o", str(out)],
            f"gyrodenoise compare{tag}": gd + ["compare"] + rec}


def commands(csv: Path, out: Path, timed: Path | None = None) -> dict[str, list[str]]:
    """Each row's command line."""
    rec = [str(csv), "--sample-rate", f"{FS:g}"]
    return {
        READ_ONLY: _python(f"import pandas as pd; pd.read_csv({str(csv)!r}, dtype={{'rate': 'float64'}})"),
        BASELINE: _python(
            "import numpy as np, pandas as pd, allantools\n"
            "from gyrodenoise.analysis.allan import octave_m\n"
            f"y = pd.read_csv({str(csv)!r}, dtype={{'rate': 'float64'}})['rate'].to_numpy()\n"
            f"allantools.oadev(y, rate={FS!r}, data_type='freq', taus=octave_m(y.shape[0]) / {FS!r})"),
        **gd_commands(rec, out),
        **(gd_commands([str(timed)], out, " [time]") if timed is not None else {}),
    }


def measure(cmd: list[str]) -> tuple[float, float]:
    """(wall s, peak MB) of ``cmd`` in a fresh process, read by /usr/bin/time."""
    timer = shutil.which("time", path="/usr/bin")
    if timer is None:
        raise SystemExit("needs /usr/bin/time (GNU time) for the peak resident memory")
    with tempfile.NamedTemporaryFile("r", suffix=".time") as rep:
        proc = subprocess.run([timer, "-f", "%e %M", "-o", rep.name] + cmd, cwd=REPO,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(cmd[:4])} ... failed (exit {proc.returncode}): {proc.stderr[-500:]}")
        wall, kb = rep.read().split()[-2:]
    return float(wall), float(kb) / 1024.0


def stamp() -> str:
    """The commit measured (with '+dirty' when the tree has changes)."""
    def git(*a: str) -> str:
        return subprocess.run(["git", *a], cwd=REPO, capture_output=True, text=True).stdout.strip()
    head = git("rev-parse", "--short", "HEAD") or "unknown"
    return head + ("+dirty" if git("status", "--porcelain", "--untracked-files=no") else "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1e6,1e7,3e7", help="record lengths, samples (default 1e6,1e7,3e7)")
    ap.add_argument("--dir", default=None, help="folder for the records (default: a new temporary folder)")
    ap.add_argument("--keep", action="store_true", help="keep the records")
    ap.add_argument("--axes", action="store_true", help="add the six-axis rows")
    ap.add_argument("--axes-only", action="store_true", help="the six-axis rows alone")
    args = ap.parse_args()
    folder = Path(args.dir) if args.dir else Path(tempfile.mkdtemp(prefix="gd_commands_memory_"))
    folder.mkdir(parents=True, exist_ok=True)
    print(f"# commit {stamp()}, python {sys.version.split()[0]}")
    rows = []
    try:
        for n in (int(float(s)) for s in args.sizes.split(",")):
            t0 = time.perf_counter()
            _, csv = write_records(n, folder)
            rows_of = {} if args.axes_only else commands(csv, folder / "out.csv", write_timed(n, folder))
            if args.axes or args.axes_only:
                imu = write_axes_record(n, folder)
                rows_of.update(axes_commands(imu, folder / "out.csv"))
                print(f"# {n} samples: six-axis record {imu.stat().st_size / 1e6:.0f} MB CSV", flush=True)
            print(f"# {n} samples: records written in {time.perf_counter() - t0:.0f} s "
                  f"({csv.stat().st_size / 1e6:.0f} MB CSV)", flush=True)
            got = {}
            for name, cmd in rows_of.items():
                got[name] = measure(cmd)
                print(f"  {name:<45} {got[name][0]:8.2f} s {got[name][1]:8.0f} MB", flush=True)
            base = got.get(BASELINE, (float("nan"), float("nan")))
            rows += [(n, name, w, mb, w / base[0], mb / base[1]) for name, (w, mb) in got.items()]
    finally:
        if not args.keep and not args.dir:
            shutil.rmtree(folder, ignore_errors=True)
    print()
    print(f"{'samples':>10}  {'':<45} {'time s':>8} {'peak MB':>8} {'time ratio':>11} {'memory ratio':>13}")
    for n, name, w, mb, rt, rm in rows:
        print(f"{n:>10}  {name:<45} {w:8.2f} {mb:8.0f} {rt:11.2f} {rm:13.2f}")
    print(f"(ratios to {BASELINE} on the same file in the same run; wall time and peak resident set of the "
          f"whole process, interpreter start and imports included)")


if __name__ == "__main__":
    main()
