"""Batch speed of this tree against an earlier commit, in the same run (issue 13:
"no slower than today").

    python benchmarks/bench_vs_commit.py REV [--repeat 2]

Checks REV out into a temporary git worktree and times the batch loop
(``run(p, init_state(p), z)`` on 2 h of the paper's FOG at 200 Hz, best of 5)
for the gated SHAKF, the paper's SHAKF (no gate) and the KF, alternately in
fresh processes of this interpreter: REV, then this tree, ``--repeat`` times. ``--paths``
times the loops those do not run instead: lowpass and AR(12) (gd_run's loop for any
method), a traced value (gd_run_trace) for kf and motion, motion with restarts.
REV must have the batch loop as ``gyrodenoise.core.batch.run`` (the C core) or
``gyrodenoise.batch.run`` (the numba loop before it, e.g. ``5848016~1``); ``--build``
compiles REV's C core in the checkout first (``pip wheel``, the same flags as an
install; without it a REV with a C core runs its plain-Python kernels). A method REV
does not have (e.g. motion before issue 12) fails the run.
Prints ns/sample per method and the ratio this tree / REV. Not a test.
"""

import argparse
import json
import subprocess
import sys
from pathlib import Path

from _rev import REPO, checkout

TIMING = r'''
import sys, time, json
import numpy as np
sys.path.insert(0, sys.argv[1])
import gyrodenoise as gd
try:
    from gyrodenoise.core.batch import run
    from gyrodenoise.core import kernels as K
except ImportError:
    from gyrodenoise.batch import run
    from gyrodenoise import kernels as K
z = np.ascontiguousarray(gd.simulate("paper_fog", 1_440_000, seed=0).rate_deg_s)
res = {}
cases = [("shakf", "shakf", {}, {}), ("shakf, no gate", "shakf", {"outlier_sigma": 0.0}, {}),
         ("kf", "kf", {}, {}), ("motion", "motion", {}, {})]
if sys.argv[2] == "paths":     # the loops the default cases do not run (gdcore.c gd_run, gd_run_trace)
    rs = np.zeros(z.size, dtype=bool)
    rs[::100_000] = True
    cases = [("lowpass", "lowpass", {"cutoff_hz": 20.0}, {}), ("shakf, AR(12)", "shakf", {"ar_order": 12}, {}),
             ("kf, trace", "kf", {}, {"trace_index": K.S_R}), ("motion, restarts", "motion", {}, {"restarts": rs}),
             ("motion, trace", "motion", {}, {"trace_index": "M_R"})]
for label, method, kw, rkw in cases:
    p = K.make_params(method=method, sample_rate_hz=200.0, **kw)
    if rkw.get("trace_index") == "M_R":
        rkw = {"trace_index": K.ext_offset(p) + K.M_R}
    run(p, K.init_state(p), z[:5000], **{k: v[:5000] if k == "restarts" else v for k, v in rkw.items()})  # warm
    ts = []
    for _ in range(5):
        t = time.perf_counter()
        run(p, K.init_state(p), z, **rkw)
        ts.append(time.perf_counter() - t)
    res[label] = min(ts) / z.size * 1e9
print(json.dumps(res))
'''


def _build(root):
    """Compile the C core of the checkout at ``root`` as an install would, extensions put beside the sources."""
    import tempfile
    import zipfile
    with tempfile.TemporaryDirectory(prefix="gd_wheel_") as wheels:
        subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", wheels, str(root)], check=True)
        for whl in Path(wheels).glob("*.whl"):
            with zipfile.ZipFile(whl) as zf:
                for name in zf.namelist():
                    if name.endswith((".so", ".pyd")):
                        zf.extract(name, root)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rev")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--build", action="store_true", help="compile REV's C core in the checkout first")
    ap.add_argument("--paths", action="store_true",
                    help="time the other loops of the C core instead: lowpass, AR(12), a traced value, "
                         "restarts (REV must have them)")
    a = ap.parse_args(argv)
    with checkout(a.rev) as old:
        if a.build:
            _build(old)
        best = {}
        for _ in range(a.repeat):
            for label, root in ((a.rev, old), ("this tree", REPO)):
                r = subprocess.run([sys.executable, "-c", TIMING, str(root), "paths" if a.paths else "default"],
                                   capture_output=True, text=True)
                if r.returncode != 0:
                    raise SystemExit(f"{label}: timing failed:\n{r.stderr[-2000:]}")
                for m, ns in json.loads(r.stdout).items():
                    best.setdefault(label, {})[m] = min(ns, best.get(label, {}).get(m, ns))
    print(f"batch loop, ns/sample (best of 5 x {a.repeat} alternate runs), 2 h of the paper's FOG at 200 Hz"
          f"{' (--paths)' if a.paths else ''}:")
    for m in best["this tree"]:
        t_old, t_new = best[a.rev][m], best["this tree"][m]
        print(f"  {m:<17} {a.rev}: {t_old:6.1f}   this tree: {t_new:6.1f}   ratio {t_new / t_old:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
