"""The --jobs pool's workers: one thread of BLAS / OpenMP / numba each (N workers
each with a thread per core oversubscribe the machine), said in the summary; and
the outputs byte-identical whichever way the logs run (serial, --jobs 2, a Dask
cluster of one-thread workers), on the shared PX4 quad logs."""
import json
import os
import sys
from pathlib import Path

import pytest

from gyrodenoise.flightlog import dispatch
from gyrodenoise.flightlog.process import process_many
from tests.helpers import DATA, run_main, shared_log

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="counts threads in /proc/self/task")


@linux
def test_each_worker_runs_one_thread_and_the_parent_keeps_its_environment(monkeypatch):
    """Counted from inside each worker, after a BLAS call (which starts OpenBLAS's
    threads, if it has any): the process has 1 thread, numba's count is 1, the
    thread variables are 1. The parent's environment is as it was (a variable the
    user set keeps its value)."""
    monkeypatch.setenv("OMP_NUM_THREADS", "7")
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    tasks = [(Path(f"log{i}.bin"), "out", {}) for i in range(4)]
    results = [None] * len(tasks)
    dispatch._run_in_pool(tasks, 2, None, results, fn=dispatch.worker_threads)
    for r in results:
        assert r["process"] == 1, r
        assert r["numba"] in (1, None), r           # None: numba not installed
        assert set(r["env"].values()) == {"1"}, r
    assert os.environ["OMP_NUM_THREADS"] == "7" and "OPENBLAS_NUM_THREADS" not in os.environ


@linux
def test_the_workers_start_with_the_bridge_imported():
    """The workers are forked from a forkserver that imported the bridge (and, for
    plots, matplotlib and plotly) once: no worker pays those imports itself."""
    tasks = [(Path(f"log{i}.bin"), "out", {"plots": True}) for i in range(2)]
    assert set(dispatch.PLOT_PRELOAD) <= set(dispatch._pool_preload(tasks))
    assert not set(dispatch.PLOT_PRELOAD) & set(dispatch._pool_preload([(Path("a.bin"), "out", {"plots": False})]))
    results = [None] * len(tasks)
    dispatch._run_in_pool(tasks, 2, None, results, fn=dispatch.worker_threads)
    for r in results:
        assert {"gyrodenoise.flightlog.pipeline", "gyrodenoise.flightlog.cluster"} <= set(r["preloaded"]), r


def test_the_summary_says_the_threads_per_worker(tmp_path):
    logs = [DATA / "ardusub_small.BIN", DATA / "plane_truncated_test.BIN"]
    pool = process_many(logs, tmp_path / "a", jobs=2, plots=False, csv=False)
    serial = process_many(logs, tmp_path / "b", jobs=1, plots=False, csv=False)
    assert pool["n_ok"] == serial["n_ok"] == 2
    assert pool["threads_per_worker"] == 1 and pool["jobs"] == 2
    assert serial["threads_per_worker"] is None          # no pool: this process's own threads


# ------------------------------------------------------------ byte-identical outputs
QUADS = ("px4_quad_battery_brownout.ulg", "px4_quad_ekf_failure.ulg", "px4_quad_gps_interference.ulg")


def _outputs(folder):
    """Every output file but summary.json (it holds the run's own paths and times)."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(Path(folder).rglob("*"))
            if p.is_file() and p.name != "summary.json"}


def _assert_identical(a, b, what):
    assert a.keys() == b.keys(), what
    diff = [name for name in a if a[name] != b[name]]
    assert not diff, f"{what}: {diff}"


@pytest.mark.slow
def test_serial_pool_and_cluster_outputs_are_byte_identical(tmp_path):
    """On the three PX4 quad logs (about 200 Hz, 60-80 s: long enough that a threaded
    BLAS splits its sums), serial (this process, BLAS with a thread per core),
    --jobs 2 (one-thread workers) and a Dask LocalCluster of 2 one-thread workers
    give the same bytes: fleet.json, the filtered logs, the CSVs. (A Dask run's
    fleet.json differed from the serial one in lag_s's 13th digit.)"""
    logs = [shared_log(n) for n in QUADS]
    runs = {"serial": ["--jobs", "1"], "jobs2": ["--jobs", "2"]}
    distributed = None
    try:
        import distributed
    except ImportError:
        pass
    cluster = None
    if distributed is not None:
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                           dashboard_address=None)
        runs["dask"] = ["--scheduler", cluster.scheduler_address]
    try:
        for name, extra in runs.items():
            status, _, err = run_main("mavlink", *logs, "-o", tmp_path / name, "--no-plots", *extra)
            assert status == 0, err
    finally:
        if cluster is not None:
            cluster.close()
    ref = _outputs(tmp_path / "serial")
    assert "fleet.json" in ref and len(ref) > 3
    for name in runs:
        _assert_identical(ref, _outputs(tmp_path / name), f"serial vs {name}")
    fleet = json.loads((tmp_path / "serial" / "fleet.json").read_text())
    assert any(r.get("lag_s") is not None for r in fleet["rows"])
