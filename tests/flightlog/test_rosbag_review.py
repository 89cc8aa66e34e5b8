"""ROS bags through the bridge (the rosbag adapter, gyrodenoise.flightlog.adapters.rosbag): a
ROS 2 bag (sqlite3, a folder with its metadata.yaml) and a bare MCAP file built here with
rosbags go through ``gyrodenoise mavlink --json`` and the review; the filtered bag, read back
by rosbags itself, holds the same messages with only angular_velocity changed; a folder
holding a bag folder gives the bag as one log."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="rosbags (ROS bag reader/writer) not installed")

from gyrodenoise.flightlog import formats  # noqa: E402
from gyrodenoise.flightlog.dispatch import expand_inputs  # noqa: E402
from tests.flightlog.test_rosbag import IMU, _build, _rosbags_read  # noqa: E402
from tests.helpers import main_in_process  # noqa: E402

N = 3000            # 15 s of /imu/data at 200 Hz, /cam/imu at 100 Hz


def _bag(tmp_path, kind):
    """(the input path, the generated truth): a ROS 2 sqlite3 bag folder, or a bare MCAP file
    (the storage file of a ROS 2 mcap bag, without its metadata.yaml)."""
    folder = tmp_path / f"in_{kind}"
    truth = _build(kind, folder, n=N)
    if kind == "sqlite3":
        return folder, truth
    bare = tmp_path / "flight.mcap"
    shutil.move(str(next(folder.glob("*.mcap"))), bare)
    shutil.rmtree(folder)
    return bare, truth


@pytest.mark.parametrize("kind", ["sqlite3", "mcap"])
def test_bag_through_the_cli_and_the_review(tmp_path, capfd, kind):
    path, truth = _bag(tmp_path, kind)
    out = tmp_path / "out"
    status, stdout, err = main_in_process(capfd, "mavlink", path, "-o", out, "--json")
    assert status == 0, err
    summary = json.loads(stdout)
    assert summary["n_ok"] == 1 and not summary["failed"] and not summary["ignored_files"]
    rep = summary["logs"][0]
    assert rep["format"] == "rosbag"
    by_name = {s["name"]: s for s in rep["streams"]}
    assert sorted(by_name) == ["/cam/imu", "/imu/data"]
    assert by_name["/imu/data"]["rate_hz"] == pytest.approx(200.0, rel=1e-6)     # from the header stamps
    assert by_name["/cam/imu"]["rate_hz"] == pytest.approx(100.0, rel=1e-6)
    assert {s["field_unit"] for s in rep["streams"]} == {"rad/s"}
    # the stamps are Unix time: the axis says so, and starts at the bag's first stamp
    assert rep["time_base"]["kind"] == "Unix epoch"
    assert rep["time_base"]["offset_s"] == pytest.approx(1_700_000_000.123456789, abs=1e-6)
    assert rep["boots"][0]["end_s"] == pytest.approx((N - 1) * 0.005, abs=1e-6)
    # the review: what a bag lacks is said with the reason, not an error
    assert rep["segments"] == [] and "no arming" in rep["segments_note"] and "ROS bag" in rep["segments_note"]
    assert "no autopilot parameters" in rep["parameters_note"]
    assert rep["filter_review"] is None and rep["filter_review_note"]
    accel = formats.read_log(path).accel                    # every Imu topic's linear_acceleration, m/s^2
    assert [(a.name, len(a.time_s)) for a in accel] == [("/imu/data", N), ("/cam/imu", N // 2)]
    np.testing.assert_array_equal(accel[0].values, truth["/imu/data"]["acc"])
    vib = rep["vibration"]
    assert vib["accel_source"] == "/imu/data.linear_acceleration"          # the topic with the most messages
    assert vib["segments"][0]["figures"]["accel_band_rms_x"]["samples"] == N
    # the filtered bag, read by rosbags: same connections and messages, only angular_velocity changed
    filtered = out / (f"{path.name}.filtered" if kind == "sqlite3" else "flight.filtered.mcap")
    assert rep["output_log"] == str(filtered)
    assert (filtered.is_dir() and (filtered / "metadata.yaml").is_file()) if kind == "sqlite3" else filtered.is_file()
    conns_in, msgs_in, dec_in = _rosbags_read(path)
    conns_out, msgs_out, dec_out = _rosbags_read(filtered)
    assert conns_out == conns_in
    assert [m[:3] for m in msgs_out] == [m[:3] for m in msgs_in]
    got = {t: [] for t in truth}
    for (topic, mt, _, a), (_, _, _, b), da, db in zip(msgs_in, msgs_out, dec_in, dec_out):
        if mt != IMU:
            assert a == b
            continue
        diff = np.flatnonzero(np.frombuffer(a, np.uint8) != np.frombuffer(b, np.uint8))
        assert len(a) == len(b) and (len(diff) == 0 or diff[-1] - diff[0] < 24)
        la, lb = da.linear_acceleration, db.linear_acceleration
        assert (la.x, la.y, la.z) == (lb.x, lb.y, lb.z)
        got[topic].append((db.angular_velocity.x, db.angular_velocity.y, db.angular_velocity.z))
    for topic, tr in truth.items():
        f = np.asarray(got[topic])
        assert f.shape == tr["gyro"].shape and np.isfinite(f).all()
        # white noise in, the filter's output out: the sample-to-sample scatter is much smaller
        assert np.std(np.diff(f, axis=0)) < 0.5 * np.std(np.diff(tr["gyro"], axis=0))


def test_a_folder_holding_a_bag_folder_gives_the_bag_as_one_log(tmp_path):
    bag = tmp_path / "flights" / "day1" / "bag_a"
    bag.parent.mkdir(parents=True)
    _build("sqlite3", bag, n=40)
    (tmp_path / "flights" / "notes.txt").write_text("x")
    files, ignored = expand_inputs([tmp_path / "flights"])
    assert files == [bag]
    assert [i.file for i in ignored] == [str(tmp_path / "flights" / "notes.txt")]
    assert expand_inputs([bag]) == ([bag], [])


@pytest.mark.parametrize("seed", range(4))
def test_mutated_bag_goes_through_or_gives_one_line(tmp_path, seed):
    """An MCAP file with seeded byte flips or a cut: the whole pipeline gives a report (a
    filtered bag rosbags reads, with as many messages) or the one-line InputError."""
    from gyrodenoise.errors import InputError
    from gyrodenoise.flightlog.pipeline import process_log
    from tests.flightlog.test_fuzz_logs import flips, truncation
    path, _ = _bag(tmp_path, "mcap")
    rng = np.random.default_rng(seed)
    data, what = (flips if seed % 2 else truncation)(path.read_bytes(), rng)
    path.write_bytes(data)
    try:
        rep = process_log(path, tmp_path / "out", plots=False, csv=False, html=False)
    except InputError as exc:
        assert "\n" not in str(exc), what
        return
    _, msgs_in, _ = _rosbags_read(path)
    _, msgs_out, _ = _rosbags_read(rep["output_log"])
    assert [m[:3] for m in msgs_out] == [m[:3] for m in msgs_in], what
