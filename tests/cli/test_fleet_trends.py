"""``gyrodenoise fleet-trends`` and ``gyrodenoise mavlink --store``: exit statuses, one-line
errors, the query helper, the same log stored once."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("pyarrow")
pytest.importorskip("duckdb")

from gyrodenoise.cli.program import main  # noqa: E402
from tests.flightlog.test_trends import _fleet  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "logs"


def _one_line(capsys, argv):
    rc = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    return rc, err


def test_trends_flag_growth_exit_1(tmp_path, capsys):
    store = _fleet(tmp_path, n_logs=12, onset=6)
    rc = main(["fleet-trends", str(store), "--json", "--no-html"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 1
    assert {(f["airframe"], f["metric"]) for f in out["flagged"]} == {("AF-drift", "vibration"),
                                                                      ("AF-drift", "line level")}
    doc = json.loads((store / "trends" / "trends.json").read_text())
    assert doc["detector"]["baseline"] == 5 and len(doc["trends"]) == 6


def test_query_helper(tmp_path, capsys):
    store = _fleet(tmp_path, n_logs=3)
    assert main(["fleet-trends", str(store), "--json", "--sql",
                 "SELECT airframe, count(DISTINCT log_key) AS n FROM logs GROUP BY 1 ORDER BY 1"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out == {"columns": ["airframe", "n"], "rows": [["AF-drift", 3], ["AF-steady", 3]]}
    rc, err = _one_line(capsys, ["fleet-trends", str(store), "--sql", "SELECT nope FROM logs"])
    assert rc == 2 and len(err) == 1 and err[0].startswith("gyrodenoise: error: --sql: ")


@pytest.mark.parametrize("argv, says", [
    (["fleet-trends", "{tmp}/absent"], "no such folder"),
    (["fleet-trends", "{tmp}"], "not a fleet store"),
    (["fleet-trends", "{store}", "--baseline", "2"], "--baseline"),
    (["fleet-trends", "{store}", "--threshold", "0"], "--threshold"),
    (["mavlink", "{tmp}", "--airframe", "x"], "--airframe applies with --store only"),
    (["mavlink", "{tmp}", "--store", "{tmp}"], "not a fleet store"),
])
def test_bad_input_is_one_line(tmp_path, capsys, argv, says):
    (tmp_path / "store" / "logs").mkdir(parents=True)
    (tmp_path / "junk.txt").write_text("x")
    argv = [a.format(tmp=tmp_path, store=tmp_path / "store") for a in argv]
    rc, err = _one_line(capsys, argv)
    assert rc == 2 and len(err) == 1 and says in err[0], err


@pytest.mark.skipif(not (DATA / "px4_sample.ulg").exists(), reason="shared logs absent (../shared/data/logs)")
def test_mavlink_store_counts_a_log_once(tmp_path, capsys):
    log = str(DATA / "px4_sample.ulg")
    argv = ["mavlink", log, "-o", str(tmp_path / "out"), "--no-plots", "--no-csv", "--json",
            "--store", str(tmp_path / "store"), "--airframe", "bench-quad"]
    assert main(argv) == 0
    first = json.loads(capsys.readouterr().out)["store"]["appended"]
    assert main(argv) == 0
    again = json.loads(capsys.readouterr().out)["store"]["appended"]
    assert [a["replaced"] for a in first + again] == [False, True]
    assert main(["fleet-trends", str(tmp_path / "store"), "--json", "--sql",
                 "SELECT airframe, airframe_source, count(DISTINCT log_key) FROM logs GROUP BY ALL"]) == 0
    assert json.loads(capsys.readouterr().out)["rows"] == [["bench-quad", "option", 1]]
