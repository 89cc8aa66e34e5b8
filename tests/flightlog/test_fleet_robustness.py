"""Many logs in one run, off the happy path: files that are not regular files in the
inputs (never opened, listed with the reason), and a ``--jobs`` worker killed in the
middle of a log (that log fails alone, no partial file is left)."""
import os
import shutil
import sys
import threading
from pathlib import Path

import pytest

from gyrodenoise.flightlog.process import process_many
from tests.helpers import DATA, run_main

posix = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs and /dev/zero are POSIX")


def _in_thread(fn, timeout_s=120.0):
    """fn() in a thread; its result, or the test fails when it has not returned in ``timeout_s``
    (reading a FIFO or /dev/zero never ends)."""
    out = {}
    th = threading.Thread(target=lambda: out.update(result=fn()), daemon=True)
    th.start()
    th.join(timeout_s)
    assert not th.is_alive(), f"still running after {timeout_s} s (a special file opened?)"
    return out["result"]


@posix
def test_special_files_are_listed_with_the_reason_and_never_opened(tmp_path):
    folder = tmp_path / "logs"
    (folder / "sub").mkdir(parents=True)
    shutil.copy(DATA / "ardusub_small.BIN", folder)
    os.mkfifo(folder / "pipe.bin")
    os.symlink("/dev/zero", folder / "zero.tlog")
    os.symlink(tmp_path / "nowhere.ulg", folder / "sub" / "broken.ulg")
    (folder / "notes.txt").write_text("not a log")
    fifo_named = tmp_path / "named.tlog"
    os.mkfifo(fifo_named)
    summary = _in_thread(lambda: process_many([folder, fifo_named], tmp_path / "out", plots=False, csv=False))
    assert summary["n_logs"] == summary["n_ok"] == 1 and summary["n_failed"] == 0
    why = {Path(i["file"]).name: i["reason"] for i in summary["ignored_files"]}
    assert set(why) == {"pipe.bin", "zero.tlog", "broken.ulg", "notes.txt", "named.tlog"}, why
    assert why["pipe.bin"] == why["named.tlog"] == "a FIFO (named pipe): not a regular file, not opened"
    assert why["zero.tlog"] == "a link to /dev/zero, a character device: not a regular file, not opened"
    assert why["broken.ulg"].startswith(f"a link to {tmp_path / 'nowhere.ulg'}, cannot be looked at")
    assert why["notes.txt"].startswith("not named as a log")


# ------------------------------------------------------------ a worker killed mid-log
KILLED = "killed-mid-log"


def _run_task_killed_on_its_first_output(task):
    """:func:`gyrodenoise.flightlog.cluster.run_task`, in a pool worker; for the log named
    :data:`KILLED` the worker SIGKILLs itself the moment its first output file is complete
    under its partial name (before the rename): a worker killed in the middle of a log."""
    import signal

    from gyrodenoise.flightlog import cluster, stopping
    if Path(task[0]).stem == KILLED:
        def replace(src, dst):
            assert Path(src).name.endswith(stopping.PARTIAL_SUFFIX) and Path(src).exists()
            os.kill(os.getpid(), signal.SIGKILL)
        stopping.os.replace = replace            # the module's os: this worker's only, it dies
    return cluster.run_task(task)


@pytest.mark.skipif(not hasattr(os, "fork") or sys.platform == "win32", reason="SIGKILL of a pool worker")
def test_a_killed_worker_fails_its_own_log_alone_and_leaves_no_partial_file(tmp_path, monkeypatch):
    from gyrodenoise.flightlog import cluster
    folder = tmp_path / "logs"
    folder.mkdir()
    names = []
    for i, src in enumerate([DATA / "ardusub_small.BIN", DATA / "plane_truncated_test.BIN",
                             DATA / "fs-batt.log.tlog"] * 2):
        names.append(f"log{i}{src.suffix}")
        shutil.copy(src, folder / names[-1])
    shutil.copy(DATA / "ardusub_small.BIN", folder / f"{KILLED}.BIN")
    monkeypatch.setattr(cluster, "run_task", _run_task_killed_on_its_first_output)
    out = tmp_path / "out"
    summary = _in_thread(lambda: process_many([folder], out, jobs=3, plots=False, csv=True))
    assert summary["n_logs"] == 7 and summary["n_ok"] == 6 and summary["n_failed"] == 1, summary["failed"]
    assert sorted(Path(r["file"]).name for r in summary["logs"]) == sorted(names)
    (failed,) = summary["failed"]
    assert failed["file"] == str(folder / f"{KILLED}.BIN")
    assert "the worker process processing this log died (killed by SIGKILL)" in failed["error"]
    assert not [p.name for p in out.rglob("*") if p.name.endswith(".partial")]
    assert not list(out.glob(f"{KILLED}.*"))            # it died before its first output was complete
    for name in names:                                  # the others complete
        assert (out / f"{Path(name).stem}.filtered{Path(name).suffix}").is_file()


@posix
def test_only_special_files_named_exit_2_with_the_reason(tmp_path):
    fifo = tmp_path / "named.tlog"
    os.mkfifo(fifo)
    status, out, err = _in_thread(lambda: run_main("mavlink", fifo, "-o", tmp_path / "out", "--no-plots"))
    assert status == 2 and "Traceback" not in err
    from gyrodenoise.flightlog.formats import LOG_SUFFIXES
    assert err.strip() == (f"gyrodenoise: error: {fifo}: no flight log found (looked for "
                           f"{', '.join(sorted(LOG_SUFFIXES))} files and ROS 2 bag folders) "
                           f"(ignored: {fifo}: a FIFO (named pipe): not a regular file, not opened)")
