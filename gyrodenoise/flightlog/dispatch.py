"""Many logs in one run: the inputs found, each log run as one task (serially, in
a local process pool or on a Dask cluster), and the summary of the run.

Each task is :func:`gyrodenoise.flightlog.cluster.run_task` (one log through
:func:`gyrodenoise.flightlog.pipeline.process_log`), whichever way the logs run, so
outputs are byte-identical. An interrupted run (Ctrl-C, SIGTERM) gets a summary
of what completed (:func:`interrupted_summary`).
"""

from __future__ import annotations

import contextlib
import os
import signal
import stat
import time
from pathlib import Path
from typing import NamedTuple

from gyrodenoise.errors import Terminated
from gyrodenoise.flightlog import cluster
from gyrodenoise.flightlog.formats import LOG_SUFFIXES, folder_format, sniffed
from gyrodenoise.flightlog.report import MOTION_METRIC, log_problems, streams_left_raw
from gyrodenoise.flightlog.spectra import SPECTRUM_METRIC
from gyrodenoise.flightlog.stopping import STOP_WAIT_S, as_child, remove_partials, signals_blocked, stop_processes
from gyrodenoise.flightlog.streams import NOISE_METRIC


def process_many(items, out_dir, jobs=1, log=None, scheduler=None, progress=False, on_interrupt=None, **kw):
    """Process files and folders; one summary dict. A failing log is listed
    under ``failed`` and does not stop the others (nor does a crashed worker).

    ``jobs`` > 1 runs a local process pool; ``scheduler`` (``tcp://HOST:PORT``
    or a ``distributed.Client``) runs each log as one task on a Dask cluster
    (:mod:`gyrodenoise.flightlog.cluster`). Items and ``out_dir`` may be fsspec URLs.
    ``progress`` shows logs done / failed / remaining and samples per second
    on stderr. Outputs are byte-identical whichever way the logs are run.
    ``kw``: the keywords of :func:`gyrodenoise.flightlog.pipeline.process_log`.

    Interrupted (KeyboardInterrupt, :class:`gyrodenoise.errors.Terminated`): the
    workers are stopped, then ``on_interrupt(summary)`` is called with the
    summary of the logs that completed (:func:`interrupted_summary`: which logs
    completed, which did not) before the interrupt goes on up; a text it
    returns is set as the exception's ``stop_note`` (the CLI's stop line).
    """
    files, ignored = _log_files(items)
    stems = _unique_stems(files)
    tasks = [(f, out_dir, dict(kw, out_stem=st, log=None)) for f, st in zip(files, stems)]
    t0 = time.perf_counter()
    where = "Dask cluster" if scheduler is not None else f"{jobs} processes" if jobs > 1 else "local"
    bar = cluster.Progress(len(tasks), where) if progress and tasks else None
    results = [None] * len(tasks)           # filled as the logs end (read by an interrupt)
    try:
        _run_tasks(tasks, jobs, scheduler, bar, results)
    except (KeyboardInterrupt, Terminated) as exc:
        if on_interrupt is not None:
            note = on_interrupt(interrupted_summary(files, stems, results, ignored, exc,
                                                    time.perf_counter() - t0, jobs, scheduler))
            if note:
                exc.stop_note = note            # the CLI's one line says it
        raise
    finally:
        if bar:
            bar.close()
    if log:
        _log_stream_problems([r["report"] for r in results if r["ok"]], log)
    return _summary(files, results, ignored, time.perf_counter() - t0, jobs, scheduler)


def _log_files(items):
    """(log files, ignored files: :class:`IgnoredFile`) of local paths and fsspec URLs, local ones first."""
    files, ignored = expand_inputs([it for it in items if not cluster.is_url(it)])
    urls = [it for it in items if cluster.is_url(it)]
    if urls:
        found, missing = cluster.expand_url_inputs(urls)
        files += found
        ignored += [IgnoredFile(m, "nothing found at this URL") for m in missing]
    return files, ignored


class IgnoredFile(NamedTuple):
    """An input not processed, and why (the summary's ``ignored_files``: ``{"file", "reason"}``)."""
    file: str
    reason: str

    def as_dict(self):
        return {"file": str(self.file), "reason": self.reason}


#: files that are not regular files, by what ``stat`` says they are: never opened (a FIFO
#: blocks its reader until a writer comes, a device such as /dev/zero never ends)
SPECIAL_FILE_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
                      (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"),
                      (stat.S_ISDIR, "a folder"))


def special_file_reason(path):
    """None for a regular file (or a link to one), else why ``path`` is not read: what it is
    (a link: what it points to), or why it cannot be looked at."""
    p = Path(path)
    link = f"a link to {os.readlink(p)}, " if p.is_symlink() else ""
    try:
        mode = p.stat().st_mode
    except OSError as exc:
        return f"{link}cannot be looked at ({exc.strerror or exc})"
    if stat.S_ISREG(mode):
        return None
    what = next((name for test, name in SPECIAL_FILE_KINDS if test(mode)), "not a regular file")
    return f"{link}{what}: not a regular file, not opened"


def expand_inputs(items):
    """Files and folders -> (list of log files, list of :class:`IgnoredFile`): a folder that
    is one log (:func:`gyrodenoise.flightlog.formats.folder_format`: a ROS 2 bag) is a log,
    found at any depth and not looked into; in a folder of logs, files neither named as logs
    nor known as one by their content (:func:`gyrodenoise.flightlog.formats.sniffed`: a
    blackbox ``.txt``) (:data:`LOG_SUFFIXES`) and, anywhere, files that are not
    regular files (:func:`special_file_reason`: FIFOs, devices, sockets, broken links),
    which are never opened. A path that does not exist is left to fail as a log."""
    files, ignored = [], []

    def add(path, why):
        if why is None:
            files.append(path)
        else:
            ignored.append(IgnoredFile(str(path), why))

    for it in items:
        p = Path(it)
        if p.is_dir() and folder_format(p) is None:
            logs_in = []                    # folders that are one log each (a ROS 2 bag): not looked into
            for q in sorted(p.rglob("*")):
                if any(d in q.parents for d in logs_in):
                    continue
                if q.is_dir() and not q.is_symlink():
                    if folder_format(q) is not None:
                        logs_in.append(q)
                        add(q, None)
                    continue
                why = special_file_reason(q)
                if why is None and q.suffix.lower() not in LOG_SUFFIXES and not sniffed(q):
                    why = f"not named as a log ({' '.join(sorted(LOG_SUFFIXES))}) nor one by its content"
                add(q, why)
        elif p.is_dir():
            add(p, None)
        else:
            add(p, special_file_reason(p) if p.exists() or p.is_symlink() else None)
    return files, ignored


def _unique_stems(files):
    """The output stem of each log: its file stem, ``-2``, ``-3``... on a repeat."""
    seen = {}
    stems = []
    for f in files:
        st = Path(str(f).split("://", 1)[-1]).stem
        k = seen.get(st, 0)
        seen[st] = k + 1
        stems.append(st if k == 0 else f"{st}-{k + 1}")
    return stems


def _uses_pool(jobs, scheduler, n_tasks):
    """Whether a run of ``n_tasks`` logs goes to the local process pool."""
    return scheduler is None and jobs > 1 and n_tasks > 1


def _run_tasks(tasks, jobs, scheduler, bar, results):
    """Run every task, each result into ``results`` as it ends (``bar(result)`` then)."""
    if scheduler is not None:
        cluster.run_on_cluster(tasks, scheduler, bar, into=results)
    elif _uses_pool(jobs, scheduler, len(tasks)):
        _run_in_pool(tasks, jobs, bar, results)
    else:
        for i, t in enumerate(tasks):
            results[i] = cluster.run_task(t)
            if bar:
                bar(results[i])


#: the environment each ``--jobs`` worker starts with: one thread of BLAS (OpenBLAS,
#: MKL, BLIS, Accelerate), OpenMP and numba, as Dask's nanny gives its workers. N
#: workers each starting a thread per core oversubscribe the machine (measured on 16
#: cores, 80 logs: ``--jobs 16`` no faster than serial with them, 9x serial without).
WORKER_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                     "BLIS_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1", "NUMEXPR_NUM_THREADS": "1",
                     "NUMBA_NUM_THREADS": "1"}
#: threads of BLAS / OpenMP / numba in each worker of the local pool (the summary's
#: ``threads_per_worker``)
THREADS_PER_WORKER = 1


@contextlib.contextmanager
def _worker_environment():
    """The processes started in the block start with :data:`WORKER_THREAD_ENV`:
    set in this process's environment for the block (a spawned child inherits
    it), then restored as it was.

    The environment of a fresh interpreter, not a call in a forked worker: these
    libraries read the variables once, when they load (OpenBLAS starts its threads
    then), and a forked worker inherits the parent's numpy already loaded with a
    BLAS sized for every core; after the fork it restarts those threads at its
    first call, and setting its count to 1 then (threadpoolctl's way, not installed
    here) still starts them, idle (measured: numpy 2.4's OpenBLAS)."""
    old = {k: os.environ.get(k) for k in WORKER_THREAD_ENV}
    os.environ.update(WORKER_THREAD_ENV)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def worker_threads(task=None):
    """The threads of the calling process (``task`` is not used: the signature of a
    task, for :func:`_run_in_pool`):
    ``{"process": threads of the process (Linux, else None), "numba": numba's
    thread count or None (numba not installed), "env": the thread variables,
    "preloaded": the modules of :data:`WORKER_PRELOAD` and :data:`PLOT_PRELOAD` the
    process had imported before this call}``.
    Run in a worker in place of :func:`gyrodenoise.flightlog.cluster.run_task`, it says
    what the pool's workers get (the tests)."""
    import sys
    preloaded = sorted(m for m in WORKER_PRELOAD + PLOT_PRELOAD if m != "__main__" and m in sys.modules)
    import numpy as np
    a = np.ones((256, 256))
    a @ a                               # BLAS starts its threads (if any) at its first call
    task = Path("/proc/self/task")
    try:
        import numba
        nb = int(numba.config.NUMBA_NUM_THREADS)
    except ImportError:
        nb = None
    return {"process": len(list(task.iterdir())) if task.is_dir() else None, "numba": nb,
            "env": {k: os.environ.get(k) for k in WORKER_THREAD_ENV}, "preloaded": preloaded}


#: what each worker of the local pool imports before its first log; with plots also
#: :data:`PLOT_PRELOAD`. Imported once, by the forkserver the workers are forked from:
#: with spawned workers importing them each, ``--jobs 2`` over the shared logs took 1.7 s
#: (4.3 s with plots) of CPU more than serial, 0.8 s (3.3 s) with the forkserver
#: (docs/logs/mavlink.md, Speed)
WORKER_PRELOAD = ("__main__", "gyrodenoise.flightlog.cluster", "gyrodenoise.flightlog.pipeline",
                  "gyrodenoise.core.batch", "pymavlink.mavutil", "pyulog")
PLOT_PRELOAD = ("matplotlib.pyplot", "plotly.graph_objects", "plotly.subplots", "gyrodenoise.flightlog.html_report")


def _pool_preload(tasks):
    """The modules the pool's forkserver imports for ``tasks`` (:data:`WORKER_PRELOAD`,
    and :data:`PLOT_PRELOAD` when a task draws plots)."""
    plots = any(t[2].get("plots", True) for t in tasks)
    return list(WORKER_PRELOAD) + (list(PLOT_PRELOAD) if plots else [])


def _pool_context(tasks):
    """The multiprocessing context of the local pool: forkserver (preloading
    :func:`_pool_preload`) where the platform has it, else spawn. The forkserver is
    one per process, started at the pool's first worker (in :func:`_worker_environment`);
    a later pool reuses it and what it preloaded."""
    import multiprocessing as mp
    if "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(_pool_preload(tasks))
    return ctx


def _run_in_pool(tasks, jobs, bar, results, fn=None):
    """:func:`_run_tasks` in a local process pool of ``jobs`` workers, largest log first
    (``fn``: what runs each task, :func:`gyrodenoise.flightlog.cluster.run_task`).
    The workers end with this process, and on an interrupt they are stopped at
    once (without waiting for the logs under way).

    A worker that dies in the middle of a log (killed, out of memory, a crash in C)
    fails that log alone: it is listed as failed with how the worker ended, its
    partial files are deleted (:func:`remove_task_partials`), a new worker takes its
    place and the other logs go on. (concurrent.futures' pool fails every log with
    ``BrokenProcessPool`` then, those under way and those not started.)

    Each worker runs one thread of BLAS / OpenMP / numba: ``jobs`` workers each with
    a thread per core would oversubscribe the machine. The workers are forked from a
    fresh interpreter (multiprocessing's forkserver; spawned where there is none, as
    on macOS and Windows) started in :func:`_worker_environment`, which imports
    :func:`_pool_preload` once for all of them (:func:`_pool_context`). As with any
    spawned pool, a script that calls this with ``jobs`` > 1 keeps its work under
    ``if __name__ == "__main__":`` (the workers import the script's main module)."""
    from multiprocessing.connection import wait
    fn = cluster.run_task if fn is None else fn
    ctx = _pool_context(tasks)
    todo = list(cluster.largest_first(tasks))
    todo.reverse()                                  # popped from the end: largest first
    idle, busy, died = [], {}, []                  # busy: worker -> index of its task
    n_workers = min(jobs, len(tasks))
    try:
        while todo or busy:
            while todo and (idle or len(busy) < n_workers):
                was_idle = bool(idle)
                w = idle.pop() if was_idle else _PoolWorker(ctx, fn)
                i = todo[-1]
                if not w.send((i, tasks[i])) and was_idle:    # it died waiting: another one
                    w.close()
                    continue
                busy[w] = todo.pop()
            ready = set(wait([w.conn for w in busy] + [w.proc.sentinel for w in busy]))
            for w in [w for w in busy if w.conn in ready or w.proc.sentinel in ready]:
                i = busy.pop(w)
                res = w.result()
                if res is None:                     # the worker died with the log
                    res = _worker_died(tasks[i], w.proc)
                    died.append(tasks[i])
                    w.close()
                else:
                    idle.append(w)
                results[i] = res
                if bar:
                    bar(res)
    except BaseException:
        stop_processes([w.proc for w in [*busy, *idle]])
        raise
    finally:
        for w in idle:
            w.close()
        for t in died:          # its worker's plot helper (killed with it) may have written last
            remove_task_partials(t)


class _PoolWorker:
    """One worker process of :func:`_run_in_pool` and its end of a pipe: it is sent
    ``(index, task)`` and answers ``(index, result)``; ``None`` ends it."""

    def __init__(self, ctx, fn):
        self.conn, child = ctx.Pipe()
        # started in this block: its environment and signal mask (see _run_in_pool)
        with signals_blocked(), _worker_environment():
            # not a daemon: it starts a plot helper of its own
            self.proc = ctx.Process(target=_pool_worker_main, args=(child, fn))
            self.proc.start()
        child.close()

    def send(self, msg):
        """Send ``msg``; False when the worker is gone."""
        try:
            self.conn.send(msg)
            return True
        except OSError:
            return False

    def result(self):
        """The result of the task sent, or None when the worker died before it answered."""
        try:
            if self.conn.poll():
                return self.conn.recv()[1]
        except (EOFError, OSError):
            pass
        return None

    def close(self):
        """End the worker (asked, then stopped if it does not) and close its pipe."""
        self.send(None)
        self.proc.join(STOP_WAIT_S)
        stop_processes([self.proc])
        self.conn.close()


def _pool_worker_main(conn, fn):
    """A pool worker: :func:`as_child`, then the tasks it is sent, one at a time."""
    as_child()
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        i, task = msg
        try:
            res = fn(task)
        except Exception as exc:  # noqa: BLE001 - the task's own failure, said as its result
            res = {"ok": False, "file": str(task[0]), "error": f"{task[0]}: worker failed: {type(exc).__name__}: {exc}"}
        conn.send((i, res))


def _worker_died(task, proc):
    """The failed result of a task whose worker process ended before it answered."""
    proc.join(STOP_WAIT_S)
    code = proc.exitcode
    if code is None or code >= 0:
        how = f"exit status {code}"
    elif -code in signal.valid_signals():
        how = f"killed by {signal.Signals(-code).name}"
    else:
        how = f"killed by signal {-code}"
    return {"ok": False, "file": str(task[0]),
            "error": f"{task[0]}: the worker process processing this log died ({how}); "
                     f"its partial outputs were deleted, the other logs were not affected"}


def remove_task_partials(task):
    """Delete the partial files (:func:`gyrodenoise.flightlog.stopping.partial_path`) of one
    log task's outputs (``STEM.*`` in its output folder); how many."""
    out_dir, stem = task[1], task[2].get("out_stem")
    if stem is None or cluster.is_url(out_dir):
        return 0
    return remove_partials(out_dir, f"{stem}.*")


def _log_stream_problems(logs, log):
    """The stderr lines of a run: streams of unknown unit, streams left raw, warnings."""
    for r in logs:
        for s in r["streams"]:
            if not s["unit_known"]:
                log(f"{r['file']}: {s['name']}: unit unknown, filtered in {s['field_unit']}")
        log_problems(r, log)


def _summary(files, results, ignored, seconds, jobs, scheduler, head=None):
    """The summary of a run from the tasks' results (None: not completed); ``head``:
    the fields that open an interrupted run's summary (which then counts its
    unfinished logs)."""
    done = [r for r in results if r is not None]
    logs = [r["report"] for r in done if r["ok"]]
    failed = _failed_entries(done)
    out = dict(head or {})
    out.update({"logs": logs, "failed": failed, "ignored_files": [i.as_dict() for i in ignored],
                "n_logs": len(files), "n_ok": len(logs), "n_failed": len(failed)})
    if head is not None:
        out["n_unfinished"] = sum(r is None for r in results)
    out.update({
        "jobs": None if scheduler is not None else int(jobs),     # the cluster decides its parallelism
        # BLAS / OpenMP / numba threads of each pool worker; None: no pool (serial: this
        # process's own; a Dask cluster: its workers', e.g. 1 under a nanny)
        "threads_per_worker": THREADS_PER_WORKER if _uses_pool(jobs, scheduler, len(files)) else None,
        "scheduler": None if scheduler is None else str(scheduler),
        "seconds": round(seconds, 3),
        "noise_metric": NOISE_METRIC, "motion_metric": MOTION_METRIC, "spectrum_metric": SPECTRUM_METRIC,
        "streams_left_raw": streams_left_raw(logs),
    })
    return out


def _failed_entries(results):
    """The ``failed`` list of a summary: file, error and, when a log refused an option, which."""
    return [{k: r[k] for k in ("file", "error", "option", "rates_hz") if k in r} for r in results if not r["ok"]]


def interrupted_summary(files, stems, results, ignored, exc, seconds, jobs=1, scheduler=None):
    """The summary of an interrupted run: the completed logs' reports (``logs``,
    ``failed``) as in a full summary, ``"interrupted": true``, the signal, and
    ``completed`` / ``unfinished`` (file and output stem): an unfinished log's
    outputs (``STEM.*``) may be absent or only some of them present, each file
    whole (written under a partial name, renamed when complete)."""
    sig = "SIGINT" if isinstance(exc, KeyboardInterrupt) else "SIGTERM"
    head = {
        "interrupted": True, "signal": sig, "exit_status": 130 if sig == "SIGINT" else 143,
        "completed": [str(f) for f, r in zip(files, results) if r is not None],
        "unfinished": [{"file": str(f), "out_stem": st,
                        "note": f"not completed: its outputs {st}.* in this folder, if any, are not all there"}
                       for f, st, r in zip(files, stems, results) if r is None],
    }
    return _summary(files, results, ignored, seconds, jobs, scheduler, head)
