"""ROS bags with sensor_msgs/Imu (gyrodenoise.flightlog.rosbag): ROS 1, ROS 2 sqlite3, ROS 2
mcap and bare MCAP files built here with rosbags from a seeded generator; the values read
against the generated truth; the filtered copy read back with rosbags itself (not our
reader): the same connections, the same messages in the same order with the same receive
times, every non-gyro message byte-identical, in a filtered Imu message only the 24 bytes of
angular_velocity changed; content sniffing; bad input as one-line errors."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="rosbags (ROS bag reader/writer) not installed")

from rosbags.highlevel import AnyReader  # noqa: E402
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from gyrodenoise.errors import InputError  # noqa: E402
from gyrodenoise.flightlog import rosbag as rb  # noqa: E402

IMU = "sensor_msgs/msg/Imu"
T0_NS = 1_700_000_000_123_456_789
KINDS = ("ros1", "sqlite3", "mcap")


def _build(kind, path, n=300, seed=7, compression=None):
    """A bag with two Imu topics (200 Hz and 100 Hz, frame ids of varying length: CDR padding
    varies), a String topic and a Float64MultiArray topic; returns the generated values."""
    rng = np.random.default_rng(seed)
    ros1 = kind == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    T = ts.types
    truth = {}
    if ros1:
        writer, ser = Writer1(path), ts.serialize_ros1
        if compression:
            writer.set_compression(Writer1.CompressionFormat[compression])
    else:
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        writer, ser = Writer2(path, version=9, storage_plugin=plugin), ts.serialize_cdr
        if compression:
            writer.set_compression(CompressionMode[compression], CompressionFormat.ZSTD)
    with writer:
        conns = {"/imu/data": writer.add_connection("/imu/data", IMU, typestore=ts),
                 "/cam/imu": writer.add_connection("/cam/imu", IMU, typestore=ts),
                 "/status": writer.add_connection("/status", "std_msgs/msg/String", typestore=ts),
                 "/array": writer.add_connection("/array", "std_msgs/msg/Float64MultiArray", typestore=ts)}
        for topic, step in (("/imu/data", 1), ("/cam/imu", 2)):
            m = n // step
            truth[topic] = dict(gyro=rng.normal(0, 0.2, (m, 3)), acc=rng.normal(0, 1, (m, 3)) + [0, 0, 9.81],
                                quat=rng.normal(0, 1, (m, 4)), cov=rng.normal(0, 1, (m, 9)),
                                stamp=T0_NS + np.arange(m, dtype=np.int64) * 5_000_000 * step,
                                frames=[f"imu{'_' * (i % 5)}" for i in range(m)])
        messages = []
        for topic, tr in truth.items():
            for i, st in enumerate(tr["stamp"]):
                st = int(st)
                stamp = T["builtin_interfaces/msg/Time"](sec=st // 10**9, nanosec=st % 10**9)
                hdr = T["std_msgs/msg/Header"](**({"seq": i} if ros1 else {}), stamp=stamp, frame_id=tr["frames"][i])
                v3 = T["geometry_msgs/msg/Vector3"]
                q = tr["quat"][i]
                msg = T[IMU](header=hdr, orientation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
                             orientation_covariance=tr["cov"][i], angular_velocity=v3(*tr["gyro"][i]),
                             angular_velocity_covariance=tr["cov"][i][::-1].copy(),
                             linear_acceleration=v3(*tr["acc"][i]), linear_acceleration_covariance=tr["cov"][i] * 2)
                messages.append((st + 300_000 + i % 7, topic, ser(msg, IMU)))
        for i in range(0, n, 10):
            st = T0_NS + i * 5_000_000 + 1
            messages.append((st, "/status", ser(T["std_msgs/msg/String"](data=f"ok {i}" * (i % 4)),
                                                "std_msgs/msg/String")))
            arr = T["std_msgs/msg/Float64MultiArray"](layout=T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0),
                                                      data=rng.normal(size=i % 5))
            messages.append((st + 2, "/array", ser(arr, "std_msgs/msg/Float64MultiArray")))
        for t, topic, raw in sorted(messages, key=lambda x: x[0]):
            writer.write(conns[topic], t, raw)
    return truth


def _bag_path(tmp_path, kind):
    return tmp_path / ("in.bag" if kind == "ros1" else f"in_{kind}")


def _rosbags_read(path):
    """(connections, [(topic, msgtype, t_ns, raw)]) read by rosbags directly."""
    path = Path(path)
    if path.is_file() and path.suffix not in (".bag", ".mcap"):
        raise AssertionError("test reads only .bag/.mcap/folders")
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as r:
        conns = sorted((c.topic, c.msgtype, c.digest, c.msgcount) for c in r.connections)
        msgs = [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in r.messages()]
        decoded = [r.deserialize(raw, mt) if mt == IMU else None for _, mt, _, raw in msgs]
    return conns, msgs, decoded


@pytest.mark.parametrize("kind", KINDS)
def test_read_imu_gives_the_generated_values(tmp_path, kind):
    path = _bag_path(tmp_path, kind)
    truth = _build(kind, path)
    bag = rb.read_imu(path)
    assert (bag.kind, bag.storage) == (("ros1", None) if kind == "ros1" else ("ros2", kind))
    assert bag.topics == ("/array", "/cam/imu", "/imu/data", "/status")
    assert [(o.topic, o.msgtype, o.count) for o in bag.other] == [
        ("/array", "std_msgs/msg/Float64MultiArray", 30), ("/status", "std_msgs/msg/String", 30)]
    assert bag.message_count == 300 + 150 + 60
    for topic, tr in truth.items():
        t = bag.topic(topic)
        np.testing.assert_array_equal(t.angular_velocity, tr["gyro"])
        np.testing.assert_array_equal(t.linear_acceleration, tr["acc"])
        np.testing.assert_array_equal(t.stamp_ns, tr["stamp"])
        assert np.all(t.receive_ns - t.stamp_ns >= 300_000) and np.all(t.receive_ns - t.stamp_ns < 300_007)
        assert t.frame_id == "imu" and t.frame_ids == ("imu", "imu_", "imu__", "imu___", "imu____")
        assert t.stamps_are_epoch and t.angular_velocity_absent == 0
    assert bag.topic("/imu/data").rate_hz == pytest.approx(200.0, rel=1e-9)
    assert bag.topic("/cam/imu").rate_hz == pytest.approx(100.0, rel=1e-9)
    only = rb.read_imu(path, topic="/cam/imu")
    assert [t.topic for t in only.imu] == ["/cam/imu"]


@pytest.mark.parametrize("kind", KINDS)
def test_filtered_copy_changes_only_the_angular_velocity_of_the_filtered_topic(tmp_path, kind):
    path = _bag_path(tmp_path, kind)
    truth = _build(kind, path)
    new = np.random.default_rng(1).normal(0, 0.01, truth["/imu/data"]["gyro"].shape)
    out = tmp_path / ("out.bag" if kind == "ros1" else "out")
    assert rb.write_filtered(path, out, {"/imu/data": new}) == out
    conns_in, msgs_in, dec_in = _rosbags_read(path)
    conns_out, msgs_out, dec_out = _rosbags_read(out)
    assert conns_out == conns_in
    assert [m[:3] for m in msgs_out] == [m[:3] for m in msgs_in]       # topics, types, receive times, order
    row = 0
    for (topic, mt, _, a), (_, _, _, b), da, db in zip(msgs_in, msgs_out, dec_in, dec_out):
        if topic != "/imu/data":
            assert a == b                                              # byte for byte
            continue
        diff = np.flatnonzero(np.frombuffer(a, np.uint8) != np.frombuffer(b, np.uint8))
        assert len(a) == len(b) and (len(diff) == 0 or diff[-1] - diff[0] < 24)
        av = db.angular_velocity
        assert (av.x, av.y, av.z) == tuple(new[row])
        row += 1
        for name in ("linear_acceleration",):
            va, vb = getattr(da, name), getattr(db, name)
            assert (va.x, va.y, va.z) == (vb.x, vb.y, vb.z)
        np.testing.assert_array_equal(da.orientation_covariance, db.orientation_covariance)
        np.testing.assert_array_equal(da.angular_velocity_covariance, db.angular_velocity_covariance)
        assert (da.header.frame_id, da.header.stamp.sec, da.header.stamp.nanosec) == (
            db.header.frame_id, db.header.stamp.sec, db.header.stamp.nanosec)
    assert row == len(new)


@pytest.mark.parametrize("compression", ["BZ2", "LZ4"])
def test_compressed_ros1_bag_is_copied_compressed(tmp_path, compression):
    path = tmp_path / "c.bag"
    truth = _build("ros1", path, n=60, compression=compression)
    assert rb.ros1_chunk_compression(path) == compression.lower()
    out = rb.write_filtered(path, tmp_path / "o.bag", {"/imu/data": truth["/imu/data"]["gyro"] * 2})
    assert rb.ros1_chunk_compression(out) == compression.lower()
    _, msgs_in, _ = _rosbags_read(path)
    _, msgs_out, _ = _rosbags_read(out)
    assert [m[:3] for m in msgs_in] == [m[:3] for m in msgs_out]
    assert [m[3] for m in msgs_in if m[0] != "/imu/data"] == [m[3] for m in msgs_out if m[0] != "/imu/data"]
    np.testing.assert_array_equal(rb.read_imu(out).topic("/imu/data").angular_velocity, truth["/imu/data"]["gyro"] * 2)


@pytest.mark.parametrize("mode", ["MESSAGE", "FILE"])
def test_compressed_ros2_bag_keeps_its_compression(tmp_path, mode):
    path = tmp_path / "z"
    truth = _build("sqlite3", path, n=60, compression=mode)
    out = rb.write_filtered(path, tmp_path / "oz", {"/cam/imu": truth["/cam/imu"]["gyro"] + 1})
    meta = (out / "metadata.yaml").read_text()
    assert f"compression_mode: {mode.lower()}" in meta and "compression_format: zstd" in meta
    _, msgs_in, _ = _rosbags_read(path)
    _, msgs_out, _ = _rosbags_read(out)
    assert [m[:3] for m in msgs_in] == [m[:3] for m in msgs_out]
    assert [m[3] for m in msgs_in if m[0] != "/cam/imu"] == [m[3] for m in msgs_out if m[0] != "/cam/imu"]
    np.testing.assert_array_equal(rb.read_imu(out).topic("/cam/imu").angular_velocity, truth["/cam/imu"]["gyro"] + 1)


def test_bare_mcap_file_and_renamed_ros1_bag_are_known_by_content(tmp_path):
    folder = tmp_path / "b"
    truth = _build("mcap", folder)
    bare = tmp_path / "flight.mcap"
    shutil.copy(next(folder.glob("*.mcap")), bare)
    assert rb.bag_kind(bare).name == "mcap" and rb.bag_kind(folder).name == "ros2"
    new = np.zeros_like(truth["/cam/imu"]["gyro"])
    out = rb.write_filtered(bare, tmp_path / "flight_filtered.mcap", {"/cam/imu": new})
    assert out.is_file() and rb.bag_kind(out).name == "mcap"
    _, msgs_in, _ = _rosbags_read(bare)
    _, msgs_out, _ = _rosbags_read(out)
    assert [m[:3] for m in msgs_in] == [m[:3] for m in msgs_out]
    assert [m[3] for m in msgs_in if m[0] != "/cam/imu"] == [m[3] for m in msgs_out if m[0] != "/cam/imu"]
    np.testing.assert_array_equal(rb.read_imu(out).topic("/cam/imu").angular_velocity, new)
    ros1 = tmp_path / "r.bag"
    _build("ros1", ros1, n=20)
    renamed = tmp_path / "recording.dat"
    shutil.copy(ros1, renamed)
    assert rb.read_imu(renamed).kind == "ros1" and len(rb.read_imu(renamed).topic("/imu/data")) == 20


def test_bad_input_gives_one_line(tmp_path):
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"\x00\x01garbage" * 50)
    for path, match in ((junk, "not a ROS bag"), (tmp_path / "none.bag", "no such file")):
        with pytest.raises(InputError, match=match) as e:
            rb.read_imu(path)
        assert "\n" not in str(e.value)
    good = tmp_path / "g.bag"
    truth = _build("ros1", good, n=50)
    cut = tmp_path / "cut.bag"
    cut.write_bytes(good.read_bytes()[:3000])
    with pytest.raises(InputError, match="not a readable bag") as e:
        rb.read_imu(cut)
    assert "\n" not in str(e.value)
    with pytest.raises(InputError, match="no sensor_msgs/Imu topic '/nope'"):
        rb.read_imu(good, topic="/nope")
    g = truth["/imu/data"]["gyro"]
    with pytest.raises(InputError, match="shape"):
        rb.write_filtered(good, tmp_path / "o1.bag", {"/imu/data": g[:10]})
    with pytest.raises(InputError, match="not finite"):
        rb.write_filtered(good, tmp_path / "o2.bag", {"/imu/data": g * np.nan})
    with pytest.raises(InputError, match="no sensor_msgs/Imu topic '/status'"):
        rb.write_filtered(good, tmp_path / "o3.bag", {"/status": g})
    with pytest.raises(InputError, match="exists already"):
        rb.write_filtered(good, good, {"/imu/data": g})
    assert not any(p.name.startswith("o") for p in tmp_path.iterdir())


@pytest.mark.parametrize("ros2, frame, little", [(False, "", True), (False, "abc", True), (True, "", True),
                                                 (True, "a", True), (True, "abcd", True), (True, "abcdefgh", True),
                                                 (True, "abc", False), (True, "abcdefg", False)])
def test_angular_velocity_offset_matches_the_serializer(ros2, frame, little):
    ts = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)
    T = ts.types
    hdr = T["std_msgs/msg/Header"](**({} if ros2 else {"seq": 3}), stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=2),
                                   frame_id=frame)
    v3 = T["geometry_msgs/msg/Vector3"]
    z = np.zeros(9)
    msg = T[IMU](header=hdr, orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                 orientation_covariance=z, angular_velocity=v3(x=1.25, y=-2.5, z=3.75), angular_velocity_covariance=z,
                 linear_acceleration=v3(x=9.0, y=8.0, z=7.0), linear_acceleration_covariance=z)
    raw = ts.serialize_cdr(msg, IMU, little_endian=little) if ros2 else ts.serialize_ros1(msg, IMU)
    off, order = rb.angular_velocity_offset(bytes(raw), ros2)
    assert np.frombuffer(bytes(raw), dtype=order + "f8", count=3, offset=off).tolist() == [1.25, -2.5, 3.75]
    assert order == ("<" if little else ">")


def test_declared_absent_angular_velocity_is_counted(tmp_path):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    path = tmp_path / "absent"
    cov = np.zeros(9)
    none = np.array([-1.0] + [0.0] * 8)
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/imu", IMU, typestore=ts)
        for i in range(10):
            hdr = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="f")
            v3 = T["geometry_msgs/msg/Vector3"]
            msg = T[IMU](header=hdr, orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                         orientation_covariance=cov, angular_velocity=v3(x=0.0, y=0.0, z=0.0),
                         angular_velocity_covariance=none if i < 4 else cov,
                         linear_acceleration=v3(x=0.0, y=0.0, z=9.8), linear_acceleration_covariance=cov)
            w.write(c, i * 10**9, ts.serialize_cdr(msg, IMU))
    t = rb.read_imu(path).topic("/imu")
    assert (t.angular_velocity_absent, t.linear_acceleration_absent) == (4, 0)
    assert not t.stamps_are_epoch and t.rate_hz == 1.0


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_mutated_bags_read_or_give_one_line(tmp_path, kind):
    """Seeded fuzz: bytes changed, truncations, chunks replaced by zeros. Each bag is read (and its
    filtered copy written) or refused with one InputError line; no other exception, no partial output."""
    src = tmp_path / ("s.bag" if kind == "ros1" else "s")
    _build(kind, src, n=40)
    data = (src if kind == "ros1" else next(src.glob("*.mcap"))).read_bytes()
    rng = np.random.default_rng(11)
    refused = 0
    for trial in range(30):
        b = bytearray(data)
        mode = trial % 3
        if mode == 0:
            for _ in range(rng.integers(1, 10)):
                b[rng.integers(0, len(b))] = rng.integers(0, 256)
        elif mode == 1:
            b = b[: rng.integers(0, len(b))]
        else:
            i = int(rng.integers(0, len(b)))
            b = b[:i] + bytes(int(rng.integers(0, 30))) + b[i + int(rng.integers(1, 100)):]
        p = tmp_path / f"m{trial}{'.bag' if kind == 'ros1' else '.mcap'}"
        p.write_bytes(bytes(b))
        out = tmp_path / f"o{trial}{p.suffix}"
        try:
            bag = rb.read_imu(p)
            if bag.imu:
                rb.write_filtered(p, out, {bag.imu[0].topic: np.zeros((len(bag.imu[0]), 3))})
                assert out.exists()
        except InputError as e:
            assert "\n" not in str(e)
            assert not out.exists()
            refused += 1
    assert refused > 5
    assert not list(tmp_path.glob("gyrodenoise-bag-*"))
