"""Benchmark of the MAVLink bridge: ``gyrodenoise mavlink log171.bin`` against a
bare pymavlink read of every message of the same file, in the same run.

Both are timed as fresh processes (interpreter start and imports included),
alternately, ``--repeat`` times; the medians and their ratio are printed.
Target: ratio <= 1.2 with the HTML report (the default run: the PNGs and the HTML
report drawn by forked helpers while the log is read, filtered and written);
also printed: without the HTML report (``--no-plots`` drops both, so the PNG-only
figure is of the previous tree, ``--against``).

    python benchmarks/bench_bridge.py [LOG] [--repeat 5]
    python benchmarks/bench_bridge.py [LOG] --against REV [--repeat 7]

``--against REV`` instead times ``gyrodenoise mavlink LOG`` (with and without
plots) of this tree and of the commit REV, alternately, in fresh processes of
this interpreter: REV is checked out into a temporary git worktree and given
this tree's compiled C core (the comparison is of the Python around it; REV
must have the same C core); printed: the median wall time (and its ratio to a bare
pymavlink read, timed in the same rounds), the median CPU time of the process and
its children, and the ratio of the two trees.

``--parts`` instead prints the CPU seconds of each part of the bridge's work on
LOG, measured in one process after a first run (imports done; a helper pays its
imports and first calls once a log): the parent's work (read, review, filter, write,
the plots' data queued), each PNG, the HTML page, and the imports of matplotlib
and plotly the helpers pay. Their sum over two cores is the wall time's floor.

The bridge run does everything the command does by default: parse, detect
restarts, denoise 3 streams x 3 axes, the flight review (segments, parameters,
vehicle filters, filter review, vibration), write the filtered log, 3 CSV files,
3 PNG plots and the spectrum PNG, and the interactive HTML report. Not a test:
timings depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first

from benchmarks._data import REPO, SHARED_DATA

DEFAULT_LOG = SHARED_DATA / "logs" / "log171.bin"

FLOOR = """
import numpy as np
import gyrodenoise.cli as cli
cli.build_parser()
from gyrodenoise import denoise
denoise(np.zeros(100), 50.0)
"""

BARE = """
import sys
from pymavlink import mavutil
m = mavutil.mavlink_connection(sys.argv[1])
n = 0
while m.recv_msg() is not None:
    n += 1
print(n)
"""


def _gyrodenoise():
    exe = Path(sys.executable).with_name("gyrodenoise")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "gyrodenoise.cli"]


def timed(cmd, **kw):
    """(wall s, stdout) of one fresh process."""
    dt, _, out = timed_cpu(cmd, **kw)
    return dt, out


def _subreaper():
    """Make this process the subreaper of its descendants (Linux): a helper process
    the command leaves behind is adopted here, and its CPU time counted once reaped."""
    if sys.platform.startswith("linux"):
        import ctypes
        ctypes.CDLL(None).prctl(36, 1, 0, 0, 0)        # PR_SET_CHILD_SUBREAPER


def timed_cpu(cmd, **kw):
    """(wall s, CPU s, stdout) of one fresh process; CPU = user + system of it and its
    children (the plot helper's drawing included), which a loaded machine disturbs
    less than the wall time."""
    _subreaper()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    dt = time.perf_counter() - t
    while True:                      # the helpers it left (adopted: this process is their subreaper)
        try:
            os.waitpid(-1, 0)
        except ChildProcessError:
            break
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr}")
    return dt, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), r.stdout


@contextlib.contextmanager
def checkout(rev):
    """Yield the root of commit ``rev`` in a temporary git worktree (removed afterwards), with
    this tree's compiled extensions copied in: the comparison is then of the Python around the
    C core, and ``rev`` must have the same core."""
    with tempfile.TemporaryDirectory(prefix="gd_rev_") as tmp:
        root = Path(tmp) / "tree"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "-q", str(root), rev], check=True)
        try:
            for so in REPO.joinpath("gyrodenoise").rglob("*.so"):
                shutil.copy2(so, root / so.relative_to(REPO))
            yield root
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(root)], check=False)


RUN_TREE = ("import sys; sys.path.insert(0, sys.argv.pop(1)); sys.argv[0] = 'gyrodenoise'; "
            "from gyrodenoise.cli import entry; entry()")


def against(log, rev, repeat):
    """This tree against commit ``rev``, alternately (see the module's docstring)."""
    with tempfile.TemporaryDirectory() as tmp, checkout(rev) as base:
        trees = {rev: base, "this tree": REPO}
        bare = []
        for extra in ([], ["--no-plots"]):
            runs = {k: [] for k in trees}
            for i in range(repeat + 1):                      # the first round warms up
                if not extra:
                    wall, _, _ = timed_cpu([sys.executable, "-c", BARE, log])
                    bare += [wall] if i else []
                for name, root in trees.items():
                    wall, cpu, _ = timed_cpu([sys.executable, "-c", RUN_TREE, str(root), "mavlink", log,
                                              "-o", str(Path(tmp) / f"out{len(name)}"), "--json", *extra])
                    if i:
                        runs[name].append((wall, cpu))
            med = {k: statistics.median(w for w, _ in v) for k, v in runs.items()}
            for k, v in runs.items():
                print(f"{k:>12} {' '.join(extra) or '(log+CSV+PNG)':>14}: wall median {med[k]:.3f} s "
                      f"({med[k] / statistics.median(bare):.2f}x the bare read), CPU median "
                      f"{statistics.median(c for _, c in v):.3f} s  (walls: {', '.join(f'{w:.2f}' for w, _ in v)})")
            print(f"  ratio this tree / {rev}: {med['this tree'] / med[rev]:.3f}")
    print(f"bare pymavlink read: median {statistics.median(bare):.3f} s")
    print(f"cores: {os.cpu_count()}, load average: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


PARTS = """
import sys, time, tempfile
t = time.process_time()
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot
t_mpl = time.process_time() - t
t = time.process_time()
import plotly.graph_objects, plotly.subplots, gyrodenoise.flightlog.html_report
t_plotly = time.process_time() - t
from gyrodenoise.flightlog import pipeline, plotting, html_writer
jobs, pages = [], []
plotting.Plotter._submit = lambda self, job: jobs.append(job)
html_writer.HtmlWriter.write = lambda self, path, report, series: pages.append((path, report, series))
with tempfile.TemporaryDirectory() as tmp:
    pipeline.process_log(sys.argv[1], tmp)
    first = []
    for j in jobs:
        c = time.process_time(); plotting._draw(*j); first.append(time.process_time() - c)
    c = time.process_time(); html_writer._write(*pages[0]); html_first = time.process_time() - c
    jobs.clear(); pages.clear()
    c = time.process_time(); pipeline.process_log(sys.argv[1], tmp); parent = time.process_time() - c
    c = time.process_time(); pipeline.process_log(sys.argv[1], tmp, plots=False); noplots = time.process_time() - c
    png = []
    for j in jobs:
        c = time.process_time(); plotting._draw(*j); png.append(time.process_time() - c)
    c = time.process_time(); html_writer._write(*pages[0]); html = time.process_time() - c
print(f"parent's work (plots queued) {parent:.2f} s, --no-plots {noplots:.2f} s")
print(f"PNGs {sum(png):.2f} s ({' + '.join(f'{x:.2f}' for x in png)}; first time {sum(first):.2f} s)")
print(f"HTML page {html:.2f} s (first time {html_first:.2f} s)")
print(f"imports in the helpers: matplotlib {t_mpl:.2f} s, plotly and the report {t_plotly:.2f} s")
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", nargs="?", default=str(DEFAULT_LOG))
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--against", default=None, metavar="REV",
                    help="time this tree against commit REV instead (see the module's docstring)")
    ap.add_argument("--parts", action="store_true", help="CPU seconds per part of the work (see the docstring)")
    a = ap.parse_args(argv)
    if not Path(a.log).is_file():
        raise SystemExit(f"{a.log}: not found (the shared data folder is needed)")
    if a.against:
        return against(a.log, a.against, a.repeat)
    if a.parts:
        for _ in range(a.repeat):
            print(subprocess.run([sys.executable, "-c", PARTS, a.log], capture_output=True, text=True,
                                 check=True).stdout, end="")
        return 0
    bare_t, bridge_t, noplot_t, floor_t, bare_cpu, bridge_cpu = [], [], [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        # one warm-up run of each (OS file cache, imports)
        timed([sys.executable, "-c", BARE, a.log])
        _, out = timed(_gyrodenoise() + ["mavlink", a.log, "-o", tmp, "--json"])
        summary = json.loads(out)
        for _ in range(a.repeat):
            dt, cpu, n_msgs = timed_cpu([sys.executable, "-c", BARE, a.log])
            bare_t.append(dt)
            bare_cpu.append(cpu)
            dt, cpu, _ = timed_cpu(_gyrodenoise() + ["mavlink", a.log, "-o", tmp, "--json"])
            bridge_t.append(dt)
            bridge_cpu.append(cpu)
            dt, _ = timed(_gyrodenoise() + ["mavlink", a.log, "-o", tmp, "--json", "--no-plots"])
            noplot_t.append(dt)
            dt, _ = timed([sys.executable, "-c", FLOOR])
            floor_t.append(dt)
    rep = summary["logs"][0]
    b, g = statistics.median(bare_t), statistics.median(bridge_t)
    print(f"log: {a.log} ({os.path.getsize(a.log)} bytes, {n_msgs.strip()} messages, "
          f"{len(rep['streams'])} gyro streams, {sum(s['samples'] for s in rep['streams'])} samples)")
    print(f"cores: {os.cpu_count()}, load average: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"bare pymavlink read of every message : median {b:.3f} s  "
          f"(runs: {', '.join(f'{x:.2f}' for x in bare_t)})")
    print(f"gyrodenoise mavlink (log+CSV+PNG+HTML report): median {g:.3f} s  "
          f"(runs: {', '.join(f'{x:.2f}' for x in bridge_t)})")
    print(f"ratio with the HTML report: {g / b:.2f}x  (target <= 1.2x)")
    bc, gc = statistics.median(bare_cpu), statistics.median(bridge_cpu)
    print(f"  CPU (user + system, helpers included): bare read {bc:.3f} s, bridge {gc:.3f} s: {gc / bc:.2f}x "
          f"(the wall ratio needs the cores for the helpers: with fewer idle cores than 3 it tends to this)")
    npl, fl = statistics.median(noplot_t), statistics.median(floor_t)
    print(f"  same with --no-plots                : median {npl:.3f} s  ratio {npl / b:.2f}x")
    print(f"  floor: start + CLI imports + exit, no log: "
          f"median {fl:.3f} s  ({fl / b:.2f}x of the bare read)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
