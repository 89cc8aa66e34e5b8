"""Before/after benchmark of the MAVLink bridge: this checkout against another
one (e.g. an older commit unpacked with ``git archive``), and a bare pymavlink
read of the same log, alternately in one run, each as a fresh process.

    git archive COMMIT | tar -x -C /tmp/base && cp gyrodenoise/core/_gdcore*.so /tmp/base/gyrodenoise/core/
    .venv/bin/python benchmarks/bench_bridge_ab.py --base /tmp/base [LOG] [--repeat 7]

Prints per variant the median wall time, its ratio to the bare read, and the
median CPU time (user + system of the process and its children: the plot
helper's drawing included), which a loaded machine disturbs less than the wall
time. Not a test: timings depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DEFAULT_LOG = REPO.parent / "shared" / "data" / "logs" / "log171.bin"

BARE = """
import sys
from pymavlink import mavutil
m = mavutil.mavlink_connection(sys.argv[1])
while m.recv_msg() is not None:
    pass
"""
RUN = "import sys; from gyrodenoise.cli import main; sys.exit(main(sys.argv[1:]))"


def timed(cmd, env, cwd):
    """(wall s, CPU s) of one fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, env=env, cwd=cwd)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr.decode()[-2000:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", nargs="?", default=str(DEFAULT_LOG))
    ap.add_argument("--base", required=True, help="root of the other checkout (put first on PYTHONPATH)")
    ap.add_argument("--repeat", type=int, default=7)
    a = ap.parse_args(argv)
    log = str(Path(a.log).resolve())
    if not Path(log).is_file():
        raise SystemExit(f"{a.log}: not found (the shared data folder is needed)")
    base = str(Path(a.base).resolve())
    if not (Path(base) / "bridge" / "process.py").is_file():
        raise SystemExit(f"--base {a.base}: no bridge/process.py there")
    env_here = dict(os.environ, PYTHONPATH=str(REPO))
    env_base = dict(os.environ, PYTHONPATH=base)
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        variants = {
            "bare pymavlink read": ([sys.executable, "-c", BARE, log], env_here),
            "bridge, base": ([sys.executable, "-c", RUN, "mavlink", log, "-o", f"{tmp}/b", "--json"], env_base),
            "bridge, this checkout": ([sys.executable, "-c", RUN, "mavlink", log, "-o", f"{tmp}/a", "--json"], env_here),
            "base, --no-plots": ([sys.executable, "-c", RUN, "mavlink", log, "-o", f"{tmp}/b", "--json",
                                  "--no-plots"], env_base),
            "this, --no-plots": ([sys.executable, "-c", RUN, "mavlink", log, "-o", f"{tmp}/a", "--json",
                                  "--no-plots"], env_here),
        }
        for i in range(a.repeat + 1):                # round 0 warms the caches
            for name, (cmd, env) in variants.items():
                wall, cpu = timed(cmd, env, tmp)     # cwd: not this checkout (it would shadow --base)
                if i:
                    res.setdefault(name, []).append((wall, cpu))
    print(f"log: {log}; {a.repeat} rounds; cores: {os.cpu_count()}, "
          f"load average: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    bare = statistics.median(w for w, _ in res["bare pymavlink read"])
    for name, runs in res.items():
        wall = statistics.median(w for w, _ in runs)
        cpu = statistics.median(c for _, c in runs)
        print(f"{name:24s} wall median {wall:.3f} s  ratio {wall / bare:.2f}x  CPU median {cpu:.3f} s  "
              f"(walls: {', '.join(f'{w:.2f}' for w, _ in runs)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
