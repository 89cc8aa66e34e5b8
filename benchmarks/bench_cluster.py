"""Fleet throughput on a Dask cluster: a benchmark, not a test.

    python benchmarks/bench_cluster.py [--logs ../shared/data/logs] [--repeat 3]

Prints, from one run on this machine:
  * the shared logs (25) through ``process_many`` serially, on a 127.0.0.1
    LocalCluster with 1 worker and with 2 workers (processes, 1 thread each):
    throughput ratio 2 workers / 1 worker (target >= 1.6x on 2 cores);
  * the cluster path's overhead for one log (log171.bin): a task on a
    1-worker cluster against the same work in this process (target <= 10 %);
  * what one log costs, to size a cluster: CPU-seconds and peak memory of a
    ``gyrodenoise mavlink`` process per log (the largest of the shared logs).
Plots are off (``--no-plots``) so that the figures are about the filtering.

    python benchmarks/bench_cluster.py --local [--jobs 2] [--repeat 3]

instead times ``gyrodenoise mavlink LOGS/ --jobs 1`` against ``--jobs N`` as fresh
processes, alternately, with ``--no-plots`` and with plots (PNGs and HTML reports):
the median wall times and their ratio (target >= 1.7x for 2 on 2 cores), and the CPU
time of each run with its workers (the --jobs pool's forkserver and workers are
reaped here: this process is their subreaper), whose ratio serial / (N-jobs CPU / N)
is the speed-up an idle machine of N cores would give: on a machine shared with other
jobs the wall ratio is what the other jobs leave.
"""

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's benchmarks and gyrodenoise first

from benchmarks._data import SHARED_DATA
from benchmarks._timing import best_of


#: Worker settings docs/logs/fleet.md recommends for this workload (measured here): the
#: statistical profiler samples every worker thread every 10 ms, and the nanny's
#: MALLOC_TRIM_THRESHOLD_=65536 makes glibc return and re-fault the memory of the
#: bridge's many medium-size arrays; together ~15 % of a log's time in a worker.
WORKER_TUNING = {"distributed.worker.profile.enabled": False,
                 "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}


def _reap_orphans():
    """Wait for this process's children adopted as a subreaper (a --jobs pool's
    forkserver outlives the CLI by a moment): their CPU time then counts in
    RUSAGE_CHILDREN."""
    while True:
        try:
            os.waitpid(-1, 0)
        except ChildProcessError:
            return


def local(logs, jobs, repeat):
    """Serial against ``--jobs`` (see the module's docstring)."""
    import ctypes
    import json
    import shutil
    import statistics
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None).prctl(36, 1, 0, 0, 0)        # PR_SET_CHILD_SUBREAPER
    cmd = [sys.executable, "-m", "gyrodenoise.cli", "mavlink", str(logs), "--json"]
    with tempfile.TemporaryDirectory() as tmp:
        for extra in (["--no-plots"], []):
            runs = {1: [], jobs: []}
            for i in range(repeat + 1):                # the first round warms the file cache
                for j in runs:
                    out = Path(tmp) / "out"
                    shutil.rmtree(out, ignore_errors=True)
                    before = resource.getrusage(resource.RUSAGE_CHILDREN)
                    t0 = time.perf_counter()
                    r = subprocess.run(cmd + ["-o", str(out), "--jobs", str(j)] + extra, capture_output=True, text=True)
                    wall = time.perf_counter() - t0
                    _reap_orphans()
                    after = resource.getrusage(resource.RUSAGE_CHILDREN)
                    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
                    n = json.loads(r.stdout)["n_logs"] if r.stdout.strip() else 0
                    if i:
                        runs[j].append((wall, cpu))
            w = {j: statistics.median(x for x, _ in v) for j, v in runs.items()}
            c = {j: statistics.median(y for _, y in v) for j, v in runs.items()}
            label = " ".join(extra) or "with plots"
            for j in runs:
                print(f"{label:>10} --jobs {j}: wall median {w[j]:6.2f} s, CPU median {c[j]:6.2f} s "
                      f"(walls {', '.join(f'{x:.2f}' for x, _ in runs[j])})")
            print(f"{label:>10}: wall ratio serial / --jobs {jobs}: {w[1] / w[jobs]:.2f}x (target >= 1.7x); "
                  f"CPU-bound ratio serial / (CPU of --jobs {jobs} / {jobs}): {c[1] / (c[jobs] / jobs):.2f}x")
    print(f"{n} logs under {logs}; cores: {os.cpu_count()}, load average: "
          f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", default=str(SHARED_DATA / "logs"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--dask-defaults", action="store_true",
                    help="keep Dask's worker defaults (statistical profiler on, MALLOC_TRIM_THRESHOLD_=65536); "
                         "by default both are switched off as docs/logs/fleet.md recommends")
    ap.add_argument("--local", action="store_true", help="serial against --jobs (see the module's docstring)")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args(argv)
    if args.local:
        return local(Path(args.logs), args.jobs, args.repeat)
    import dask
    from distributed import Client, LocalCluster
    if not args.dask_defaults:
        dask.config.set(WORKER_TUNING)

    from gyrodenoise.flightlog.cluster import run_task
    from gyrodenoise.flightlog.process import process_many
    logs = Path(args.logs)
    files = sorted(p for p in logs.iterdir() if p.suffix.lower() in (".bin", ".tlog", ".ulg"))
    kw = dict(plots=False)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        process_many([str(f) for f in files], tmp / "warm", **kw)            # OS file cache, imports
        t_serial = best_of(lambda: process_many([str(f) for f in files], tmp / "s", **kw), args.repeat)
        times = {}
        for n in (1, 2):
            with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                              dashboard_address=None) as lc, Client(lc) as client:
                process_many([str(f) for f in files], tmp / f"w{n}", scheduler=client, **kw)   # warm the workers
                times[n] = best_of(lambda: process_many([str(f) for f in files], tmp / f"c{n}",
                                                        scheduler=client, **kw), args.repeat)
                if n == 1:
                    one = logs / "log171.bin"
                    task = (one, tmp / "one_c", {"out_stem": "log171", "plots": False, "log": None})
                    client.submit(run_task, task, pure=False).result()
                    t_task = best_of(lambda: client.submit(run_task, task, pure=False).result(), 5)
        local_task = (logs / "log171.bin", tmp / "one_l", {"out_stem": "log171", "plots": False, "log": None})
        run_task(local_task)
        t_local = best_of(lambda: run_task(local_task), 5)
        # cost of one log as its own process (sizing)
        big = max(files, key=lambda f: f.stat().st_size)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "gyrodenoise.cli", "mavlink", str(big), "-o", str(tmp / "big"),
                        "--no-plots"], check=False, capture_output=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    print(f"{len(files)} logs ({sum(f.stat().st_size for f in files) / 1e6:.1f} MB), plots off, best of {args.repeat}, "
          f"worker settings: {'Dask defaults' if args.dask_defaults else 'profiler off, malloc trim default'}:")
    print(f"  serial, in this process        : {t_serial:6.2f} s")
    print(f"  Dask LocalCluster, 1 worker    : {times[1]:6.2f} s")
    print(f"  Dask LocalCluster, 2 workers   : {times[2]:6.2f} s   throughput 2 / 1 worker: "
          f"{times[1] / times[2]:.2f}x (target >= 1.6x)")
    print(f"one log (log171.bin): in this process {t_local * 1000:.0f} ms, as a task on a 1-worker cluster "
          f"{t_task * 1000:.0f} ms: overhead {100 * (t_task / t_local - 1):+.0f} % (target <= 10 %)")
    print(f"sizing: the largest log ({big.name}, {big.stat().st_size / 1e6:.1f} MB) as its own process: "
          f"{cpu:.2f} CPU-s, {wall:.2f} s wall, peak RSS {after.ru_maxrss / 1024:.0f} MB "
          f"(interpreter and imports included)")


if __name__ == "__main__":
    main()
