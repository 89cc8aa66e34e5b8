"""Stopping cleanly: child processes that end with their parent,
and output files that are either complete or absent.

* :func:`as_child` -- called first in every child process the bridge forks (the
  ``--jobs`` workers, the plot helper): SIGINT ignored (a terminal's Ctrl-C goes
  to the whole process group; the parent decides, and a child interrupted in the
  middle of its work would print a traceback), SIGTERM back to its default
  (die at once; the parent's handler is inherited through fork), and on Linux
  ``PR_SET_PDEATHSIG`` = SIGTERM: the child is killed by the kernel when its
  parent dies, however it dies (even SIGKILL).
* :func:`signals_blocked` -- around the fork of such children: SIGINT and SIGTERM
  wait (pending) until the child has set itself up and the parent is past the
  fork, so that a Ctrl-C at that very moment reaches neither with the parent's
  handler in the child (a traceback) nor before the child ignores it.
* :func:`stop_processes` -- what the parent does on an interrupt: SIGTERM to
  each child, a short wait, SIGKILL to any that is left.
* :func:`atomic_path` -- every output file (or folder) is written under a partial name
  (``.NAME.partial`` beside it) and renamed into place when complete;
  :func:`remove_partials` deletes the partial files of an interrupted run.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import sys
from pathlib import Path

#: prctl option of Linux: signal sent to this process when its parent thread ends
_PR_SET_PDEATHSIG = 1
#: seconds a child is given to end after SIGTERM before it is killed
STOP_WAIT_S = 2.0
PARTIAL_SUFFIX = ".partial"


_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def signals_blocked():
    """Block SIGINT and SIGTERM in the calling thread for the block (children forked
    in it inherit the mask; :func:`as_child` unblocks it in them); signals that
    arrive meanwhile are delivered when the block ends."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def as_child():
    """Signal set-up of a forked child process (see the module's docstring)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if hasattr(signal, "pthread_sigmask"):       # forked inside signals_blocked()
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOP_SIGNALS)
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        except (OSError, AttributeError):   # no libc prctl: the parent's stop_processes still applies
            pass
        if os.getppid() == 1:                # the parent died before the line above
            os._exit(143)


def stop_processes(procs, wait_s=STOP_WAIT_S):
    """SIGTERM to each ``multiprocessing.Process`` of ``procs`` still alive, wait up
    to ``wait_s`` for all, then SIGKILL the rest and reap them."""
    procs = [p for p in procs if p is not None]
    for p in procs:
        with contextlib.suppress(OSError, ValueError, AttributeError):
            if p.is_alive():
                p.terminate()
    for p in procs:
        with contextlib.suppress(OSError, ValueError, AttributeError, AssertionError):
            p.join(wait_s)
            if p.is_alive():
                p.kill()
                p.join(wait_s)


def partial_path(path):
    """Where ``path`` is written until it is complete: ``.NAME.partial`` beside it."""
    path = Path(path)
    return path.with_name(f".{path.name}{PARTIAL_SUFFIX}")


def completed_path(partial):
    """The path a partial path (:func:`partial_path`) stands for (``partial`` itself when it is none)."""
    partial = Path(partial)
    name = partial.name
    if name.startswith(".") and name.endswith(PARTIAL_SUFFIX):
        return partial.with_name(name[1:-len(PARTIAL_SUFFIX)])
    return partial


@contextlib.contextmanager
def atomic_path(path):
    """Yield the partial path of ``path`` to write to; rename it to ``path`` when the
    block ends normally, delete it when the block raises (an interrupt included)."""
    tmp = partial_path(path)
    try:
        yield tmp
    except BaseException:
        _remove(tmp)
        raise
    os.replace(tmp, path)


def _remove(path):
    """Delete the file, or the folder (a ROS 2 bag is one), at ``path``; True when it was there."""
    with contextlib.suppress(OSError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
        return True
    return False


def remove_partials(folder, names="*"):
    """Delete the partial files (:func:`partial_path`) in ``folder`` of the files
    whose names match the glob pattern ``names`` (all by default); returns how many."""
    n = 0
    with contextlib.suppress(OSError):
        for p in Path(folder).glob(f".{names}{PARTIAL_SUFFIX}"):
            n += _remove(p)
    return n
