"""Many logs in one run, off the happy path: files that are not regular files in the
inputs (never opened, listed with the reason), and a ``--jobs`` worker killed in the
middle of a log (that log fails alone, no partial file is left)."""
import os
import shutil
import threading
from pathlib import Path

import pytest

from gyrodenoise.flightlog.process import process_many
from tests.helpers import DATA

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
