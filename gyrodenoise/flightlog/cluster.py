"""Many logs on a Dask distributed cluster, and progress for long runs.

Each log is one task: :func:`run_task` runs the bridge's own per-log task
(:func:`gyrodenoise.flightlog.pipeline.process_log_task`, the same code as a serial
run, so outputs are byte-identical), on whichever worker Dask picks. Inputs and
outputs may be local paths on a shared filesystem or fsspec URLs
(``s3://bucket/logs/x.bin``, ``file:///data/x.bin``, ``memory://...``): a URL
input is copied to a temporary local file on the worker, a URL output folder
receives the worker's files once the log is done.
A failing log fails its own task with its one-line reason, never the batch.

Dask is an optional extra (``pip install 'gyrodenoise[cluster]'``); without
it :func:`require_dask` gives one clear line.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog.formats import log_kind
from gyrodenoise.flightlog.pipeline import process_log_task


#: seconds to wait for the scheduler to answer before the run is refused
CONNECT_TIMEOUT_S = 20.0


def require_dask(option="--scheduler"):
    """Import dask.distributed or raise InputError with one line naming ``option``."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise InputError(f"{option} needs Dask distributed, which is not installed: "
                         f"pip install 'gyrodenoise[cluster]'") from None


def is_url(path):
    """True for an fsspec URL (``proto://...``), false for a local path."""
    return "://" in str(path)


def expand_url_inputs(items):
    """fsspec URLs to files: a file URL stays, a folder URL gives the logs in
    it, a glob URL its matches. Returns (urls, unmatched items)."""
    import fsspec
    out, missing = [], []
    for item in items:
        fs, _, paths = fsspec.get_fs_token_paths(item)
        proto = item.split("://", 1)[0]
        found = []
        for p in paths:
            if fs.isdir(p):
                found += [q for q in sorted(fs.find(p)) if _is_log_name(q)]
            elif fs.exists(p):
                found.append(p)
        if not found:
            missing.append(item)
        out += [f"{proto}://{p.lstrip('/')}" if proto != "file" else f"file://{p}" for p in found]
    return out, missing


def _is_log_name(path):
    try:
        log_kind(Path(path))
        return True
    except InputError:
        return False


def run_task(task):
    """Run one log task ``(path, out_dir, kw)`` where paths may be fsspec URLs;
    returns the task's result dict (paths in it are the URLs)."""
    path, out_dir, kw = task
    if not (is_url(path) or is_url(out_dir)):
        return process_log_task(task)
    import fsspec
    with tempfile.TemporaryDirectory(prefix="gd_task_") as tmp:
        tmp = Path(tmp)
        local_in = path
        if is_url(path):
            local_in = tmp / "in" / Path(str(path).split("://", 1)[1]).name
            local_in.parent.mkdir()
            try:
                with fsspec.open(path, "rb") as src:
                    local_in.write_bytes(src.read())
            except (OSError, ValueError) as exc:
                return {"ok": False, "file": str(path), "error": f"{path}: cannot read ({exc})"}
        local_out = tmp / "out" if is_url(out_dir) else Path(out_dir)
        res = process_log_task((local_in, local_out, kw))
        res = _rename(res, str(local_in), str(path))
        if is_url(out_dir) and res["ok"]:
            fs, _, (root,) = fsspec.get_fs_token_paths(str(out_dir))
            for f in sorted(local_out.rglob("*")):
                if f.is_file():
                    dest = root.rstrip("/") + "/" + f.relative_to(local_out).as_posix()
                    fs.makedirs(dest.rsplit("/", 1)[0], exist_ok=True)
                    with fs.open(dest, "wb") as fh:
                        fh.write(f.read_bytes())
            res = _rename(res, str(local_out), str(out_dir).rstrip("/"))
        return res


def _rename(obj, old, new):
    """Replace the path prefix ``old`` by ``new`` in every string of a result."""
    if isinstance(obj, str):
        return new + obj[len(old):] if obj.startswith(old) else obj
    if isinstance(obj, dict):
        return {k: _rename(v, old, new) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_rename(v, old, new) for v in obj]
    return obj


def largest_first(tasks):
    """Indices of ``tasks`` (see :func:`run_task`) by input size, largest first
    (stable; a URL input, whose size would cost a request, counts as 0 bytes).

    The order the logs are handed to the workers: a log's cost grows with its
    size, and a large log started last keeps one worker busy after the others
    have run out of work (on the 25 shared logs, px4_sample.ulg is 29 % of the
    batch and comes 23rd by name)."""
    def size(task):
        path = task[0]
        if is_url(path):
            return 0
        try:
            return Path(path).stat().st_size
        except OSError:
            return 0
    return sorted(range(len(tasks)), key=lambda i: -size(tasks[i]))


def connect(scheduler, timeout_s=None):
    """A ``distributed.Client`` of the scheduler at ``scheduler`` (``tcp://HOST:PORT``),
    or InputError with one line: nothing listening there (at once), no answer, or a
    peer that does not complete Dask's handshake (a dashboard or other server port,
    on which the client would otherwise wait for ever) within ``timeout_s``."""
    import re
    import socket
    import threading
    timeout_s = CONNECT_TIMEOUT_S if timeout_s is None else timeout_s
    m = re.match(r"^tcp://\[?([^\]/]+?)\]?:(\d+)/?$", str(scheduler))
    if m:
        try:
            socket.create_connection((m.group(1), int(m.group(2))), timeout=timeout_s).close()
        except ConnectionRefusedError:
            raise InputError(f"--scheduler {scheduler}: connection refused (no scheduler listens there)") from None
        except socket.timeout:
            raise InputError(f"--scheduler {scheduler}: no answer within {timeout_s:g} s") from None
        except OSError as exc:
            raise InputError(f"--scheduler {scheduler}: cannot connect ({exc.strerror or exc})") from None
    from distributed import Client
    box = {}

    def make():
        try:
            box["client"] = Client(scheduler, set_as_default=False, timeout=timeout_s)
        except BaseException as exc:  # noqa: BLE001 - any failure becomes the one line below
            box["error"] = exc
    th = threading.Thread(target=make, name="gyrodenoise-dask-connect", daemon=True)
    th.start()
    th.join(2.0 * timeout_s)
    if th.is_alive():
        raise InputError(f"--scheduler {scheduler}: the peer did not complete the Dask handshake within "
                         f"{2.0 * timeout_s:g} s (is it a Dask scheduler's port? the dashboard's is not)")
    if "error" in box:
        exc = box["error"]
        first = (str(exc).strip().splitlines() or [""])[0][:200]
        raise InputError(f"--scheduler {scheduler}: no Dask scheduler answered ({type(exc).__name__}"
                         f"{': ' + first if first else ''})") from None
    return box["client"]


def _absolute(path):
    """A local path as an absolute one (workers resolve paths in their own
    working directories); a URL as it is."""
    return path if is_url(path) else str(Path(path).absolute())


def run_on_cluster(tasks, scheduler, progress=None, into=None):
    """Run ``tasks`` (see :func:`run_task`) on the Dask scheduler at
    ``scheduler`` (``tcp://HOST:PORT``, or a ``distributed.Client``), largest
    input first (:func:`largest_first`); results in the order of ``tasks``.
    ``progress(result)`` is called as each ends; ``into``: a list of
    len(tasks) to fill as the results come (what an interrupt leaves is read there).

    Local paths go to the workers absolute (a relative one would be read and
    written in each worker's own working directory) and come back in the
    caller's spelling, as in a serial run."""
    require_dask()
    from distributed import as_completed
    own = not hasattr(scheduler, "map")
    client = connect(scheduler) if own else scheduler
    try:
        order = {}
        futures = []
        ranked = largest_first(tasks)
        for rank, i in enumerate(ranked):         # a higher priority runs earlier
            path, out_dir, kw = tasks[i]
            task = (_absolute(path), _absolute(out_dir), kw)
            fut = client.submit(run_task, task, pure=False, priority=len(ranked) - rank)
            order[fut.key] = i
            futures.append(fut)
        results = [None] * len(tasks) if into is None else into
        for fut in as_completed(futures, loop=client.loop):
            i = order[fut.key]
            path, out_dir, _ = tasks[i]
            try:
                res = fut.result()
                res = _rename(_rename(res, _absolute(path), str(path)), _absolute(out_dir), str(out_dir))
            except Exception as exc:  # noqa: BLE001 - a worker died: that log fails, not the batch
                res = {"ok": False, "file": str(path),
                       "error": f"{path}: task failed on the cluster: {type(exc).__name__}: {exc}"}
            results[i] = res
            if progress:
                progress(results[i])
        return results
    finally:
        if own:
            client.close()


class Progress:
    """Logs done / failed / remaining and samples per second on stderr (tqdm)."""

    def __init__(self, total, where="local", stream=None):
        self.total = int(total)
        self.done = self.failed = self.samples = 0
        self.t0 = time.perf_counter()
        self.stream = stream or sys.stderr
        try:
            from tqdm import tqdm
            self.bar = tqdm(total=self.total, unit="log", file=self.stream, desc=f"gyrodenoise ({where})",
                            dynamic_ncols=True, mininterval=0.5)
        except ImportError:  # pragma: no cover - tqdm is a dependency
            self.bar = None

    def __call__(self, result):
        if result.get("ok"):
            self.done += 1
            self.samples += sum(s.get("samples", 0) for s in result["report"].get("streams", []))
        else:
            self.failed += 1
        rate = self.samples / max(time.perf_counter() - self.t0, 1e-9)
        info = dict(done=self.done, failed=self.failed, remaining=self.total - self.done - self.failed,
                    samples_per_s=f"{rate:.3g}")
        if self.bar is not None:
            self.bar.set_postfix(info, refresh=False)
            self.bar.update(1)
        else:  # pragma: no cover
            print(f"gyrodenoise: {info}", file=self.stream)

    def close(self):
        if self.bar is not None:
            self.bar.close()
