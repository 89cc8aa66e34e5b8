"""Interrupting ``gyrodenoise mavlink``, with real processes and
signals: SIGINT to the process group (a terminal's Ctrl-C) and SIGINT / SIGTERM to
the main process only (timeout, systemd, Slurm, Dask's nanny). Each must stop the
whole process tree within seconds with one line on stderr, exit 130 / 143
(spec section 1), and leave no partial output file. Every wait is bounded."""
from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from gyrodenoise.flightlog.formats import LOG_SUFFIXES
from tests.helpers import SHARED_LOGS, gyrodenoise_cmd, shared_log

pytestmark = pytest.mark.slow          # process trees stopped by signals, with bounded waits

#: seconds the command is given to stop after the signal (it takes ~0.1-0.5 s here)
STOP_WITHIN_S = 10.0


def _session_pids(sid):
    """Live processes (not zombies) of session ``sid``, from /proc."""
    pids = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rfind(")") + 2:].split()
        if fields[0] != "Z" and int(fields[3]) == sid:
            pids.append(int(d.name))
    return pids


def _start(args, out):
    return subprocess.Popen(gyrodenoise_cmd() + ["mavlink", *map(str, args), "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _wait_until(cond, what, timeout_s=60.0):
    t0 = time.monotonic()
    while not cond():
        if time.monotonic() - t0 > timeout_s:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def _stop_and_check(proc, sig, to_group, status, out):
    sid = proc.pid                          # its own session (start_new_session)
    try:
        if to_group:
            os.killpg(sid, sig)
        else:
            proc.send_signal(sig)
        t0 = time.monotonic()
        _, err = proc.communicate(timeout=STOP_WITHIN_S)
        assert proc.returncode == status, err
        assert "Traceback" not in err, err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("gyrodenoise: "), err
        # the children (pool workers, plot helper) end with it
        _wait_until(lambda: not _session_pids(sid), "the workers to end",
                    timeout_s=max(0.5, STOP_WITHIN_S - (time.monotonic() - t0)))
    finally:
        if proc.poll() is None or _session_pids(sid):
            os.killpg(sid, signal.SIGKILL)      # never leave a process behind, even when failing
            proc.wait(5)
    _check_no_partial_file(out)


def _check_no_partial_file(out):
    """Every file left is complete: no partial name, PNGs end with their IEND chunk,
    CSVs with a full line, a DataFlash copy has the size of its input."""
    for f in Path(out).iterdir() if Path(out).exists() else []:
        assert not f.name.endswith(".partial"), f
        if f.suffix == ".png":
            assert f.read_bytes().endswith(b"IEND\xaeB`\x82"), f
        elif f.suffix == ".csv":
            assert f.read_bytes().endswith(b"\n"), f
        elif f.name.endswith(".filtered.bin") or f.name.endswith(".filtered.BIN"):
            src = SHARED_LOGS / f.name.replace(".filtered", "")
            assert f.stat().st_size == src.stat().st_size, f


def _work_under_way(out):
    return Path(out).exists() and any(Path(out).iterdir())


@pytest.mark.parametrize("sig, to_group, status", [(signal.SIGINT, True, 130), (signal.SIGINT, False, 130),
                                                   (signal.SIGTERM, False, 143)],
                         ids=["SIGINT-group", "SIGINT-main", "SIGTERM-main"])
def test_jobs_2_run_stops_whole_tree(tmp_path, sig, to_group, status):
    shared_log("log171.bin")
    out = tmp_path / "o"
    proc = _start([SHARED_LOGS, "--jobs", "2"], out)
    try:
        _wait_until(lambda: _work_under_way(out) or proc.poll() is not None, "the first output file")
        assert proc.poll() is None, "the run ended before it could be interrupted"
        assert len(_session_pids(proc.pid)) >= 3          # the main process and 2 workers
    except BaseException:
        os.killpg(proc.pid, signal.SIGKILL)
        raise
    _stop_and_check(proc, sig, to_group, status, out)
    # the run says which logs completed (summary.json, whole)
    import json
    sm = json.loads((out / "summary.json").read_text())
    n_logs = sum(1 for p in SHARED_LOGS.rglob("*") if p.suffix.lower() in LOG_SUFFIXES)
    assert sm["interrupted"] is True and sm["exit_status"] == status
    assert len(sm["completed"]) + len(sm["unfinished"]) == sm["n_logs"] == n_logs
    assert len(sm["logs"]) + len(sm["failed"]) == len(sm["completed"])


@pytest.mark.parametrize("sig, to_group, status", [(signal.SIGINT, True, 130), (signal.SIGTERM, False, 143)],
                         ids=["SIGINT-group", "SIGTERM-main"])
def test_single_log_with_plot_helper_stops(tmp_path, sig, to_group, status):
    log = shared_log("px4_sample.ulg")
    out = tmp_path / "o"
    proc = _start([log], out)
    try:     # the plot helper is forked at the start, the filtering follows (~0.5 s)
        _wait_until(lambda: len(_session_pids(proc.pid)) >= 2 or proc.poll() is not None, "the plot helper")
        assert proc.poll() is None, "the run ended before it could be interrupted"
    except BaseException:
        os.killpg(proc.pid, signal.SIGKILL)
        raise
    _stop_and_check(proc, sig, to_group, status, out)
    # nothing complete was written yet: no folder left behind either
    assert not out.exists() or any(out.iterdir())
