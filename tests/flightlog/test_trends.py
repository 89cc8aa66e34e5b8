"""Per-airframe trends: the detector's false-alarm rate on unchanged synthetic airframes
and its delay on drifting ones (seeded, bounds stated), and a synthetic fleet in a
store whose one drifting airframe (a growing vibration line, rising vibration) is
flagged from its onset while the steady one is not."""

from __future__ import annotations

import datetime
import html
import json

import numpy as np
import pytest

pytest.importorskip("pyarrow")
pytest.importorskip("duckdb")

from gyrodenoise.flightlog import fleet_store as fs  # noqa: E402
from gyrodenoise.flightlog import trends as tr  # noqa: E402
from tests.flightlog.test_fleet_store import synthetic_log  # noqa: E402


def test_false_alarm_rate_on_unchanged_airframes():
    """300 unchanged airframes of 30 logs, scatter 10-40 %: the detector flags at most
    1 % of the logs it judges and at most 6 % of the airframes ever (measured 0.37 % and
    2 % on 500: benchmarks/fleet_trends.py); with heavy tails (Student t, 4 dof) at most
    1.5 % / 8 %."""
    far = tr.false_alarm_rate(seed=11, airframes=300)
    assert far.per_log <= 0.01 and far.per_airframe <= 0.06
    heavy = tr.false_alarm_rate(seed=12, airframes=300, tails_dof=4)
    assert heavy.per_log <= 0.015 and heavy.per_airframe <= 0.08


def test_delay_on_a_drifting_airframe():
    """Growth of 5 % a log from log 15 (scatter 15 %): flagged within 8 logs in half of
    the trials and 10 in nine out of ten, never missed over 25 logs; 10 % a log: within
    5 logs in half of them."""
    d = tr.detection_delay(seed=13, trials=200)
    assert d.median <= 8 and d.p90 <= 10 and d.missed == 0
    assert d.early <= 0.05
    fast = tr.detection_delay(seed=14, trials=200, growth_per_log=0.10)
    assert fast.median <= 5


def test_a_step_is_flagged_at_once_and_a_fall_never():
    rng = np.random.default_rng(15)
    v = list(tr.unchanged_series(rng, 20, 0.03))
    step = v[:12] + [3.0 * x for x in v[12:]]       # a broken propeller: x3 from log 12
    assert tr.detect(step).first_flag == 12
    fall = v[:12] + [x / 3.0 for x in v[12:]]       # a new propeller: less vibration, no flag
    assert tr.detect(fall).first_flag is None


def test_short_history_has_no_verdict():
    d = tr.detect([1.0, 5.0, 20.0, 100.0])
    assert d.first_flag is None and all(z is None for z in d.z)


def _fleet(tmp_path, n_logs=16, onset=8):
    """A store of two airframes flown alternately: AF-steady, and AF-drift whose 80 Hz
    line grows 25 % a log and whose vibration rises 15 % a log from log ``onset``."""
    rng = np.random.default_rng(16)
    t0 = datetime.datetime(2024, 1, 1, tzinfo=datetime.timezone.utc).timestamp()
    for i in range(n_logs):
        for frame, grows in (("AF-steady", False), ("AF-drift", True)):
            k = max(0, i - onset + 1) if grows else 0
            rep, flight = synthetic_log(
                tmp_path, f"{frame}-{i:02d}.bin", seed=1000 * grows + i, airframe=frame,
                tone_deg_s=0.5 * 1.25 ** k * rng.lognormal(0, 0.05),
                vibration=8.0 * 1.15 ** k * rng.lognormal(0, 0.05), start=t0 + 86400 * i,
                duration_s=15.0)
            fs.append_log(tmp_path / "store", rep, flight)
    return tmp_path / "store"


def test_synthetic_fleet_flags_the_drifting_airframe(tmp_path):
    store = _fleet(tmp_path)
    got = {(t.airframe, t.metric): t for t in tr.trends(store)}
    for metric in ("vibration", "line level"):
        steady, drift = got[("AF-steady", metric)], got[("AF-drift", metric)]
        assert steady.status == "steady", metric
        assert drift.status == "growth", metric
        first = drift.points[drift.detection.first_flag].log
        assert "AF-drift-08" <= first <= "AF-drift-12", (metric, first)      # onset 8, within 4 logs
        assert drift.ordered_by == "start time"
    assert got[("AF-drift", "line level")].reference_hz == pytest.approx(80.0)
    assert got[("AF-drift", "noise density")].status == "steady"            # the white noise did not change


def test_pages_inline_and_shared(tmp_path):
    pytest.importorskip("plotly")
    store = _fleet(tmp_path, n_logs=6, onset=5)
    found = tr.trends(store)
    inline = tr.write_pages(found, tmp_path / "inline")
    shared = tr.write_pages(found, tmp_path / "shared", plotlyjs="shared")
    assert not (tmp_path / "inline" / "plotly.min.js").exists()
    js = tmp_path / "shared" / "plotly.min.js"
    assert js.stat().st_size > 1_000_000
    for page in shared:
        text = page.read_text()
        assert "src='plotly.min.js'" in text and len(text) < 200_000
    for page in inline:
        assert page.stat().st_size > js.stat().st_size         # plotly.js inside
    assert {p.name for p in shared} == {"index.html", "airframe-AF-steady.html", "airframe-AF-drift.html"}
    index = (tmp_path / "shared" / "index.html").read_text()
    assert "airframe-AF-drift.html" in index and "airframe-AF-steady.html" in index


def _folder_fleet(tmp_path, folder, identities, n_logs=8, grow_from=6):
    """A store of ``n_logs`` logs with no vehicle id in ``tmp_path/folder`` (so keyed by
    the folder), log i of the identity ``identities[i % len(identities)]`` ((autopilot,
    vehicle, board, frame)), its vibration growing x1.5 a log from log ``grow_from``
    (what the logs of unrelated aircraft, sorted together, can look like)."""
    where = tmp_path / folder
    where.mkdir()
    t0 = datetime.datetime(2024, 1, 1, tzinfo=datetime.timezone.utc).timestamp()
    for i in range(n_logs):
        autopilot, vehicle, board, frame = identities[i % len(identities)]
        rep, flight = synthetic_log(where, f"{i:02d}.bin", seed=500 + i, vehicle_id=False, start=t0 + 3600 * i,
                                    vibration=5.0 * 1.5 ** max(0, i - grow_from + 1), duration_s=4.0)
        rep["vehicle_filters"] = {"autopilot": autopilot}
        rep["overview"].update(vehicle=vehicle, board=board, frame=frame)
        fs.append_log(tmp_path / "store", rep, flight)
    return tmp_path / "store"


def test_a_folder_of_two_aircraft_is_not_trended(tmp_path):
    """A folder holding a copter's and a plane's logs (no vehicle id): not one airframe,
    so not trended, whatever its series does, with the reason naming what differs; its
    page and trends.json say so."""
    store = _folder_fleet(tmp_path, "shared-logs", [("ardupilot", "ArduCopter", "CUAVv5", "QUAD/X"),
                                                    ("ardupilot", "ArduPlane", "MatekH743", None)])
    found = tr.trends(store)
    assert found and {t.airframe for t in found} == {"shared-logs"}
    assert {t.status for t in found} == {"not trended"}
    assert not any(t.detection.flagged[i] for t in found for i in range(len(t.points)))
    assert "line level" not in {t.metric for t in found}        # a line frequency over two aircraft means nothing
    why = found[0].grouping.reason
    assert why.startswith("not trended:") and "\n" not in why
    assert "vehicle: ArduCopter, ArduPlane" in why and "board: CUAVv5, MatekH743" in why
    assert "frame:" not in why and "autopilot:" not in why        # the same, or logged once: no conflict
    doc = json.loads(tr.write_json(found, tmp_path / "trends.json").read_text())
    assert doc["airframes"] == [{"airframe": "shared-logs", "source": "folder", "logs": 8, "trended": False,
                                 "reason": why}]
    pytest.importorskip("plotly")
    tr.write_pages(found, tmp_path / "pages", plotlyjs="shared")
    for page in ("index.html", "airframe-shared-logs.html"):
        text = (tmp_path / "pages" / page).read_text()
        assert html.escape(why) in text and "GROWTH" not in text


def test_a_folder_of_one_aircraft_is_trended(tmp_path):
    """The same series, every log of one copter (its frame logged in only some): trended,
    and its growth flagged; the reason names what its logs agree on."""
    store = _folder_fleet(tmp_path, "my-quad", [("ardupilot", "ArduCopter", "CUAVv5", "QUAD/X"),
                                                ("ardupilot", "ArduCopter", "CUAVv5", None)])
    got = {t.metric: t for t in tr.trends(store)}
    vib = got["vibration"]
    assert vib.trended and vib.status == "growth"
    assert vib.grouping.reason == ("no vehicle id: grouped by the folder 'my-quad'; its 8 log(s) agree where they "
                                   "record it (autopilot ardupilot, vehicle ArduCopter, board CUAVv5, frame QUAD/X)")


def test_grouping_reasons_of_each_key_source():
    g = tr._grouping("AF", "vehicle_id", [("px4", None, None, None)] * 3)
    assert g.trended and "vehicle id" in g.reason
    g = tr._grouping("AF", "option", [("px4", "PX4 quadrotor", None, None), ("ardupilot", "ArduPlane", None, None)])
    assert g.trended and "--airframe" in g.reason                  # the user said so
    g = tr._grouping("logs", "folder", [(None,) * 4] * 2)
    assert g.trended and "on the folder's word" in g.reason
    g = tr._grouping("logs", "folder", [(None, f"V{i}", None, None) for i in range(7)])
    assert not g.trended and "vehicle: V0, V1, V2, V3 (+3 more)" in g.reason
