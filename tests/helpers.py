"""Helpers shared by the tests of every area: where the repository, the test data and the
third-party data live (skipping without the latter), the command line in this process and
in a subprocess, and running a program under wine. Fixtures are in tests/conftest.py."""
import contextlib
import io
import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TESTS = REPO / "tests"
#: small permissively licensed logs and cards kept in the repository (tests/data/README.md)
DATA = TESTS / "data"
#: the C hosts and drivers of the FMU and simulator tests
CHOST = TESTS / "chost"
#: the bad-input corpus (tests/corpus/README.md)
CORPUS = TESTS / "corpus"
# ../shared/data beside the repository, or the folder named by GYRODENOISE_SHARED_DATA
SHARED_DATA = Path(os.environ.get("GYRODENOISE_SHARED_DATA") or REPO.parent / "shared" / "data")


def shared_file(*parts):
    """Path of a file in the shared data (SHARED_DATA), or skip the test with a reason."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"third-party data not present: {p} (licence forbids copying it into the repo)")
    return p


SHARED_LOGS = SHARED_DATA / "logs"


def shared_log(name):
    """Path of a flight log in the shared data (SHARED_LOGS), or skip the test with a reason."""
    p = SHARED_LOGS / name
    if not p.exists():
        pytest.skip(f"third-party log not present: {p} (licence forbids copying it into the repo, "
                    f"or too large)")
    return p


def gyrodenoise_cmd():
    """The command that runs the program: the installed console script, or ``python -m gyrodenoise.cli``."""
    exe = Path(sys.executable).with_name("gyrodenoise")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "gyrodenoise.cli"]


def run_wine(cmd, input=None, env=None, timeout=180):
    """``subprocess.run(cmd, input=input, capture_output=True, text=True, env=env, timeout=timeout)``
    for a program run under wine, with stdout and stderr caught in temporary files instead of
    pipes. The wineserver that a wine client starts inherits the client's stdout and stderr and
    stays ~3 s after the last client exits (its default persistence), so a pipe reader waits
    those 3 s for end-of-file on every run (measured: 2.9 s a run with pipes, 0.7 s with files,
    tests/chost/host.c under wine, 2400 samples); a file is read once the program has exited.

    A client that starts while the previous wineserver is shutting down can lose its connection
    to it ("wine client error:0: recvmsg: Connection reset by peer", exit 1, seen once in CI):
    wine's own failure, not the program's, so such a run is repeated, at most twice."""
    for _ in range(3):
        with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
            proc = subprocess.run(cmd, input=input, stdout=out, stderr=err, text=True, env=env, timeout=timeout)
            out.seek(0)
            err.seek(0)
            done = subprocess.CompletedProcess(proc.args, proc.returncode, out.read(), err.read())
        if done.returncode == 0 or "wine client error" not in done.stderr:
            break
    return done


#: the warnings a Python process prints with its default filters (all but these categories)
SILENT_BY_DEFAULT = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)


def run_main(*args):
    """``gyrodenoise ARGS`` run by gyrodenoise.cli in this process, sys.stdout and sys.stderr
    redirected (what Python writes): (exit status, stdout, stderr); argparse's own errors
    (SystemExit) give their exit status. ``main_in_process`` reads the file descriptors."""
    from gyrodenoise.cli import main
    so, se = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(so), contextlib.redirect_stderr(se):
        try:
            status = main([str(a) for a in args])
        except SystemExit as exc:
            status = exc.code
    return status, so.getvalue(), se.getvalue()


def main_in_process(capfd, *args):
    """``gyrodenoise ARGS`` run by gyrodenoise.cli in this process: (exit status,
    stdout, stderr). Read at the file descriptors (capfd: C-level writes too); a warning that
    a process of its own would print (default filters) is a line of stderr; an exception is
    a traceback and fails the caller."""
    from gyrodenoise.cli import main
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            status = main([str(a) for a in args])
        except SystemExit as exc:           # argparse errors leave with sys.exit(2)
            status = exc.code
    out, err = capfd.readouterr()
    err += "".join(f"{w.category.__name__}: {w.message}\n" for w in caught
                   if not issubclass(w.category, SILENT_BY_DEFAULT))
    return status, out, err


# ------------------------------------------------------------------ golden files
#: reviewed JSON outputs (tests/golden/README.md); scripts/regen_golden.py rewrites them
GOLDEN = TESTS / "golden"
#: set (to anything) to write the golden files instead of comparing with them
REGEN_GOLDEN_ENV = "GYRODENOISE_REGEN_GOLDEN"
#: keys whose values change from run to run or from release to release: never compared
VOLATILE_KEYS = frozenset({"seconds", "elapsed_s", "version", "gyrodenoise_version", "created"})
#: relative tolerance of a number against its golden value (the outputs are seeded; this
#: only absorbs a libm or BLAS that rounds differently, never a changed result)
GOLDEN_RTOL = 1e-7


def normalise_json(obj, replace=None):
    """``obj`` as its JSON text reads back, with VOLATILE_KEYS' values replaced by
    "<volatile>" and each ``replace`` key (a path of this run, e.g. tmp_path) replaced by its
    value ("<tmp>") inside every string."""
    import json
    replace = {str(k): v for k, v in (replace or {}).items()}

    def walk(o):
        if isinstance(o, dict):
            return {k: "<volatile>" if k in VOLATILE_KEYS else walk(v) for k, v in o.items()}
        if isinstance(o, list):
            return [walk(v) for v in o]
        if isinstance(o, str):
            for k in sorted(replace, key=len, reverse=True):
                o = o.replace(k, replace[k])
        return o
    return walk(json.loads(json.dumps(obj)))


def _golden_diffs(want, got, where):
    """Every difference of ``got`` from ``want`` ("where: ..." lines): the same keys, lengths,
    types, strings and booleans; numbers within GOLDEN_RTOL."""
    import math
    if isinstance(want, dict) and isinstance(got, dict):
        for k in sorted(set(want) | set(got)):
            if k not in got:
                yield f"{where}.{k}: missing"
            elif k not in want:
                yield f"{where}.{k}: not in the golden file ({got[k]!r:.80})"
            else:
                yield from _golden_diffs(want[k], got[k], f"{where}.{k}")
    elif isinstance(want, list) and isinstance(got, list):
        if len(want) != len(got):
            yield f"{where}: {len(got)} items, the golden file has {len(want)}"
        for i, (w, g) in enumerate(zip(want, got)):
            yield from _golden_diffs(w, g, f"{where}[{i}]")
    elif (isinstance(want, (int, float)) and isinstance(got, (int, float))
          and not isinstance(want, bool) and not isinstance(got, bool)):
        if not math.isclose(want, got, rel_tol=GOLDEN_RTOL, abs_tol=1e-300):
            yield f"{where}: {got!r}, the golden file has {want!r}"
    elif isinstance(want, str) and isinstance(got, str):
        if want != got:        # from the first character that differs
            i = next((i for i, (a, b) in enumerate(zip(want, got)) if a != b), min(len(want), len(got)))
            a = max(0, i - 20)
            yield f"{where}: ...{got[a:i + 60]!r}..., the golden file has ...{want[a:i + 60]!r}..."
    elif want != got or type(want) is not type(got):
        yield f"{where}: {got!r:.200}, the golden file has {want!r:.200}"


def assert_golden(name, obj, replace=None):
    """``obj`` (a JSON output) equals tests/golden/NAME.json after :func:`normalise_json`;
    with GYRODENOISE_REGEN_GOLDEN set, writes that file instead (review it as a diff)."""
    import json
    got = normalise_json(obj, replace)
    path = GOLDEN / f"{name}.json"
    if os.environ.get(REGEN_GOLDEN_ENV):
        path.parent.mkdir(exist_ok=True)
        path.write_text(json.dumps(got, indent=1, sort_keys=True, ensure_ascii=False) + "\n")
        return
    if not path.is_file():
        pytest.fail(f"{path} is missing: write it with `python scripts/regen_golden.py` and review it")
    diffs = list(_golden_diffs(json.loads(path.read_text()), got, name))
    assert not diffs, (f"{len(diffs)} difference(s) from {path.relative_to(REPO)} (if intended: "
                       f"python scripts/regen_golden.py, then review `git diff tests/golden`):\n"
                       + "\n".join(diffs[:30]))
