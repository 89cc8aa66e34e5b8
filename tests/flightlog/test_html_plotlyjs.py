"""plotly.js inlined in every page, or written once beside a folder of pages
(``gyrodenoise mavlink --plotlyjs shared``): the pages refer to the one copy by a
relative address, are otherwise the same page, and shrink to their own content."""
import json
import re

import numpy as np
import pytest

from tests.helpers import run_main
from tests.flightlog.synthetic_logs import DataFlashWriter

pytest.importorskip("plotly")


def _js_size():
    from plotly.offline import get_plotlyjs
    return len(get_plotlyjs().encode("utf-8"))


def _without_stamp(text):
    return re.sub(r"written \d{4}-\d\d-\d\d \d\d:\d\d UTC", "written -", text)


def _tiny_report(tmp_path):
    from tests.flightlog.html_browser import synthetic_report
    return synthetic_report(tmp_path, seconds=4.0, rate_hz=100.0)


def test_shared_page_refers_to_one_copy_by_a_relative_address(tmp_path):
    from gyrodenoise.flightlog.html_report import SHARED_PLOTLYJS, write_fleet_report, write_log_report, write_shared_plotlyjs
    rep, series = _tiny_report(tmp_path)
    js = write_shared_plotlyjs(tmp_path)
    assert js == tmp_path / SHARED_PLOTLYJS and js.stat().st_size == _js_size()
    inline = write_log_report(tmp_path / "inline.report.html", rep, series)
    shared = write_log_report(tmp_path / "logs" / "a.report.html", rep, series, plotlyjs=js)
    fleet = write_fleet_report(tmp_path / "fleet.html", {"rows": [], "n_logs": 0}, [], plotlyjs=js)
    text = shared.read_text()
    assert "<script type='text/javascript' src='../plotly.min.js'></script>" in text
    assert "src='plotly.min.js'" in fleet.read_text()
    # the library is not in the page: the page is its own content only
    assert inline.stat().st_size - shared.stat().st_size > 0.99 * _js_size()
    assert "beside this page" in text and "self-contained" not in text
    assert "self-contained (opens offline)" in inline.read_text()


def test_sharing_written_pages_gives_the_pages_written_shared(tmp_path):
    """share_plotlyjs on inline pages (what the command does after its helpers drew
    them) equals writing them shared in the first place; a second pass changes nothing."""
    from gyrodenoise.flightlog.html_report import share_plotlyjs, write_log_report, write_shared_plotlyjs
    rep, series = _tiny_report(tmp_path)
    a = write_log_report(tmp_path / "out" / "a.report.html", rep, series)
    direct = write_log_report(tmp_path / "direct" / "a.report.html", rep, series,
                              plotlyjs=write_shared_plotlyjs(tmp_path / "direct"))
    js, done = share_plotlyjs([a, tmp_path / "out" / "missing.html"], tmp_path / "out")
    assert done == [a] and js == tmp_path / "out" / "plotly.min.js"
    assert _without_stamp(a.read_text()) == _without_stamp(direct.read_text())
    before = a.read_text()
    assert share_plotlyjs([a], tmp_path / "out")[1] == []
    assert a.read_text() == before


def _imu_log(path, seed):
    """A SYNTHETIC DataFlash log: IMU at 50 Hz for 20 s (white noise, rad/s)."""
    rng = np.random.default_rng(seed)
    w = DataFlashWriter()
    w.define("IMU", "Qffffff", ["TimeUS", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
    for t in 1.0 + np.arange(1000) / 50.0:
        w.add("IMU", int(round(t * 1e6)), *map(float, rng.normal(0.0, 0.002, 3)), 0.0, 0.0, -9.81)
    path.write_bytes(w.bytes())
    return path


@pytest.mark.slow
def test_mavlink_plotlyjs_shared_writes_one_copy(tmp_path):
    logs = tmp_path / "logs"
    logs.mkdir()
    for i in range(2):
        _imu_log(logs / f"f{i}.bin", i)
    st, out, err = run_main("mavlink", logs, "-o", tmp_path / "out", "--json", "--no-csv",
                            "--plotlyjs", "shared", "--no-progress")
    assert st in (0, 1), err
    summary = json.loads(out)
    pages = [r["report_html"] for r in summary["logs"]] + [p for p in summary["fleet_report"] if p.endswith(".html")]
    assert len(pages) == 3
    assert sorted(p.name for p in (tmp_path / "out").glob("*.js")) == ["plotly.min.js"]
    for p in pages:
        text = open(p).read()
        assert "src='plotly.min.js'" in text and len(text) < 0.2 * _js_size(), p


def test_mavlink_plotlyjs_shared_needs_a_local_folder(tmp_path):
    st, out, err = run_main("mavlink", _imu_log(tmp_path / "f.bin", 0), "-o", "s3://bucket/out",
                            "--plotlyjs", "shared")
    assert st == 2
    assert err.strip().splitlines()[-1].endswith("--plotlyjs shared: -o s3://bucket/out must be a local folder "
                                                 "(the pages refer to plotly.min.js beside them)")
    assert "Traceback" not in err
