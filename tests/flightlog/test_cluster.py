"""Fleet scale: logs as Dask tasks on a LocalCluster (127.0.0.1,
2 workers), fsspec inputs/outputs, the fleet report, the option's errors.
The reference is a serial run of the same logs: outputs must be byte-identical."""
import json
import sys
from pathlib import Path

import pytest

from gyrodenoise.flightlog.cluster import run_task
from gyrodenoise.flightlog.process import process_many
from gyrodenoise.cli import main
from tests.helpers import DATA


LOGS = [DATA / "ardusub_small.BIN", DATA / "fs-batt.log.tlog", DATA / "plane_truncated_test.BIN"]
distributed = pytest.importorskip("distributed", reason="Dask distributed not installed (extra 'cluster')")


@pytest.fixture(scope="module")
def cluster():
    from distributed import LocalCluster
    c = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                     dashboard_address=None)
    yield c
    c.close()


def _files(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(Path(folder).rglob("*"))
            if p.is_file() and p.name not in ("summary.json",) and not p.name.startswith("fleet.")}


@pytest.mark.slow
def test_cluster_outputs_are_byte_identical_and_a_bad_log_fails_alone(cluster, tmp_path, capsys):
    bad = tmp_path / "junk.bin"
    bad.write_bytes(b"\xa3\x95 not a log at all")
    logs = [str(p) for p in LOGS] + [str(bad)]
    serial, dask = tmp_path / "serial", tmp_path / "dask"
    assert main(["mavlink", *logs, "-o", str(serial), "--jobs", "1", "--no-plots"]) == 2
    capsys.readouterr()
    code = main(["mavlink", *logs, "-o", str(dask), "--scheduler", cluster.scheduler_address, "--no-plots",
                 "--json"])
    out, err = capsys.readouterr()
    assert code == 2                                   # a log failed: bad input
    d = json.loads(out)
    assert d["n_logs"] == 4 and d["n_ok"] == 3 and d["n_failed"] == 1
    assert d["failed"][0]["file"] == str(bad) and "junk.bin" in d["failed"][0]["error"]
    assert "1 of 4 log(s) failed" in err
    a, b = _files(serial), _files(dask)
    assert a and a.keys() == b.keys()
    for name in a:
        assert a[name] == b[name], name
    # the fleet report: one row per stream, the failure with its reason, a plot
    fleet = json.loads((dask / "fleet.json").read_text())
    assert {r["status"] for r in fleet["rows"]} == {"ok", "failed"}
    assert any(r["status"] == "failed" and "junk.bin" in r["error"] for r in fleet["rows"])
    assert (dask / "fleet.png").stat().st_size > 1000 and "| log | stream |" in (dask / "fleet.md").read_text()


def test_memory_filesystem_in_and_out(tmp_path):
    """fsspec URLs: logs read from and outputs written to memory:// (a threads
    LocalCluster shares the process's memory filesystem)."""
    import fsspec
    from distributed import Client, LocalCluster
    fs = fsspec.filesystem("memory")
    for p in LOGS[:2]:
        fs.pipe(f"/fleet/in/{p.name}", p.read_bytes())
    with LocalCluster(n_workers=2, processes=False, dashboard_address=None) as lc, \
            Client(lc) as client:
        summary = process_many(["memory://fleet/in"], "memory://fleet/out", scheduler=client, plots=False)
    assert summary["n_ok"] == 2 and summary["failed"] == []
    local = tmp_path / "local"
    for p in LOGS[:2]:
        r = run_task((p, local, {"out_stem": p.stem, "plots": False, "log": None}))
        assert r["ok"]
    for f in sorted(local.rglob("*")):
        if f.is_file():
            assert fs.cat(f"/fleet/out/{f.relative_to(local).as_posix()}") == f.read_bytes(), f.name
    assert all(r["output_log"].startswith("memory://fleet/out") for r in summary["logs"])


@pytest.mark.parametrize("extra,word", [(["--scheduler", "localhost:8786"], "--scheduler"),
                                        (["--scheduler", "tcp://127.0.0.1:1", "--jobs", "2"], "--jobs"),
                                        (["--scheduler", "tcp://127.0.0.1:9"], "--scheduler")])
def test_scheduler_errors_are_one_line(tmp_path, capsys, monkeypatch, extra, word):
    import gyrodenoise.flightlog.cluster
    monkeypatch.setattr(gyrodenoise.flightlog.cluster, "CONNECT_TIMEOUT_S", 2.0)
    code = main(["mavlink", str(LOGS[0]), "-o", str(tmp_path / "o"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and word in err[0] and "Traceback" not in err[0]


def test_without_dask_the_option_says_what_to_install(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)        # import fails as when not installed
    code = main(["mavlink", str(LOGS[0]), "-o", str(tmp_path / "o"), "--scheduler", "tcp://127.0.0.1:8786"])
    err = capsys.readouterr().err
    assert code == 2 and "pip install 'gyrodenoise[cluster]'" in err and len(err.strip().splitlines()) == 1


def test_largest_input_first_and_results_in_input_order(tmp_path):
    """Logs are handed out largest first (a big log started last keeps one worker
    busy alone), yet every result comes back in the order of the inputs."""
    from gyrodenoise.flightlog.cluster import largest_first
    sizes = {"a.bin": 10, "b.bin": 300, "c.bin": 20, "d.bin": 300}
    for name, n in sizes.items():
        (tmp_path / name).write_bytes(b"\0" * n)
    tasks = [(tmp_path / name, tmp_path, {}) for name in sizes]
    tasks.insert(1, ("memory://x/e.bin", tmp_path, {}))        # a URL's size is not asked for: 0
    tasks.append((tmp_path / "missing.bin", tmp_path, {}))
    order = [Path(str(tasks[i][0])).name for i in largest_first(tasks)]
    assert order == ["b.bin", "d.bin", "c.bin", "a.bin", "e.bin", "missing.bin"]
    # smallest log first in the inputs: the pool runs them in another order
    logs = sorted(LOGS, key=lambda p: p.stat().st_size)
    assert [p.stat().st_size for p in logs] != sorted((p.stat().st_size for p in logs), reverse=True)
    summary = process_many([str(p) for p in logs], tmp_path / "out", jobs=2, plots=False)
    assert [r["file"] for r in summary["logs"]] == [str(p) for p in logs]


@pytest.mark.slow
def test_file_urls_in_and_out_through_the_cli(cluster, tmp_path, capsys):
    """file:// URLs (the local filesystem through fsspec) for the inputs, a folder
    of logs among them, and for the output folder: the same bytes as local paths."""
    folder = tmp_path / "logs"
    folder.mkdir()
    for p in LOGS[:2]:
        (folder / p.name).write_bytes(p.read_bytes())
    serial, urls = tmp_path / "serial", tmp_path / "urls"
    assert main(["mavlink", *[str(folder / p.name) for p in LOGS[:2]], str(LOGS[2]), "-o", str(serial),
                 "--no-plots"]) == 0
    capsys.readouterr()
    code = main(["mavlink", folder.as_uri(), LOGS[2].as_uri(), "-o", urls.as_uri(),
                 "--scheduler", cluster.scheduler_address, "--no-plots", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["n_ok"] == 3, out
    a, b = _files(serial), _files(urls)
    assert a and a.keys() == b.keys()
    for name in a:
        assert a[name] == b[name], name


@pytest.mark.slow
@pytest.mark.parametrize("greeting", [None, b"\xff" * 64 + b"HTTP/1.1 400 Bad Request\r\n\r\n"])
def test_a_port_that_is_not_a_scheduler_gives_one_line(tmp_path, capsys, monkeypatch, greeting):
    """A dashboard or other server port: the Dask client would wait for its handshake
    for ever (silent peer) or fail deep inside (garbage): one line, exit 2, in time."""
    import socket
    import threading
    import gyrodenoise.flightlog.cluster
    monkeypatch.setattr(gyrodenoise.flightlog.cluster, "CONNECT_TIMEOUT_S", 1.0)
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    conns = []

    def serve():
        while True:
            try:
                c, _ = srv.accept()
            except OSError:
                return
            conns.append(c)
            if greeting:
                c.sendall(greeting)
    threading.Thread(target=serve, daemon=True).start()
    try:
        code = main(["mavlink", str(LOGS[0]), "-o", str(tmp_path / "o"), "--no-plots",
                     "--scheduler", f"tcp://127.0.0.1:{srv.getsockname()[1]}"])
    finally:
        srv.close()
        for c in conns:
            c.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--scheduler" in err[0] and "Traceback" not in err[0], err


@pytest.mark.slow
def test_relative_paths_are_the_callers_not_the_workers(cluster, tmp_path, capsys, monkeypatch):
    """Workers have their own working directory: relative inputs and -o are sent
    absolute, and the summary speaks of them as the caller wrote them."""
    monkeypatch.chdir(tmp_path)
    for p in LOGS[:2]:
        Path(p.name).write_bytes(p.read_bytes())
    code = main(["mavlink", LOGS[0].name, LOGS[1].name, "-o", "out", "--scheduler", cluster.scheduler_address,
                 "--no-plots", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["n_ok"] == 2
    assert [r["file"] for r in out["logs"]] == [LOGS[0].name, LOGS[1].name]
    for r in out["logs"]:
        assert not Path(r["output_log"]).is_absolute() and (tmp_path / r["output_log"]).is_file()
    serial = tmp_path / "serial"
    assert main(["mavlink", LOGS[0].name, LOGS[1].name, "-o", str(serial), "--no-plots"]) == 0
    a, b = _files(serial), _files(tmp_path / "out")
    assert a and a == b


@pytest.mark.slow
def test_a_wrong_scheduler_writes_nothing(tmp_path, capsys):
    """Bad input writes nothing: the scheduler is reached before the output folder is made."""
    out = tmp_path / "never"
    code = main(["mavlink", str(LOGS[0]), "-o", str(out), "--scheduler", "tcp://127.0.0.1:9", "--json"])
    assert code == 2 and not out.exists()
    assert "connection refused" in json.loads(capsys.readouterr().out)["error"]
