"""Bags and MATLAB files as recordings: a ROS 1 bag, a ROS 2 bag and an
MCAP file written here with rosbags, and .mat files (v5 by scipy, v7.3 by h5py), give the
same Allan terms as the same samples in a CSV; `allan imu.bag --topic /imu0 --kalibr-yaml`
is the whole calibration."""
from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest

from gyrodenoise.cli import main

pytest.importorskip("rosbags", reason="rosbags (ROS bag reader/writer) not installed")

from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

IMU = "sensor_msgs/msg/Imu"
T0_NS = 1_700_000_000_000_000_000
FS = 200.0
N = 8000


def _samples(seed=5):
    """(stamps ns, gyro rad/s (n, 3), accel m/s^2 (n, 3)): white noise of N 0.3 deg/sqrt(h)."""
    rng = np.random.default_rng(seed)
    stamp = T0_NS + np.arange(N, dtype=np.int64) * 5_000_000
    gyro = 0.3 / 60 * math.sqrt(FS) * math.pi / 180 * rng.standard_normal((N, 3))
    acc = 0.002 * math.sqrt(FS) * rng.standard_normal((N, 3)) + [0.0, 0.0, 9.81]
    return stamp, gyro, acc


def _bag(kind, path, stamp, gyro, acc, topics=("/imu0",)):
    ros1 = kind == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    T = ts.types
    if ros1:
        writer, ser = Writer1(path), ts.serialize_ros1
    else:
        writer = Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3)
        ser = ts.serialize_cdr
    v3 = T["geometry_msgs/msg/Vector3"]
    with writer:
        conns = [writer.add_connection(t, IMU, typestore=ts) for t in topics]
        for i, st in enumerate(stamp):
            st = int(st)
            hdr = T["std_msgs/msg/Header"](**({"seq": i} if ros1 else {}),
                                           stamp=T["builtin_interfaces/msg/Time"](sec=st // 10**9, nanosec=st % 10**9),
                                           frame_id="imu_link")
            msg = T[IMU](header=hdr, orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                         orientation_covariance=np.zeros(9), angular_velocity=v3(*gyro[i]),
                         angular_velocity_covariance=np.zeros(9), linear_acceleration=v3(*acc[i]),
                         linear_acceleration_covariance=np.zeros(9))
            for c in conns:
                writer.write(c, st + 1_000_000 + (i % 5) * 100_000, ser(msg, IMU))


def _csv(path, stamp, gyro, acc):
    names = ["time"] + [f"gyro_{a}" for a in "xyz"] + [f"accel_{a}" for a in "xyz"]
    with open(path, "w") as f:
        f.write(",".join(names) + "\n")
        for i in range(N):
            f.write(f"{stamp[i]}," + ",".join(f"{v:.17g}" for v in (*gyro[i], *acc[i])) + "\n")


def _allan(capsys, *argv):
    code = main(["allan", *map(str, argv), "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out), err


def _terms(d):
    return [[ax["terms"][t] for t in "NBKRQ"] for ax in d["axes"].values()]


@pytest.fixture(scope="module")
def csv_terms(tmp_path_factory):
    stamp, gyro, acc = _samples()
    path = tmp_path_factory.mktemp("csv") / "imu.csv"
    _csv(path, stamp, gyro, acc)
    code = main(["allan", str(path), "--json", "--rate-unit", "rad/s"])
    assert code == 0
    return path


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_a_bag_gives_the_terms_of_the_same_samples_in_a_csv(tmp_path, capsys, kind):
    stamp, gyro, acc = _samples()
    csv = tmp_path / "imu.csv"
    _csv(csv, stamp, gyro, acc)
    ref, _ = _allan(capsys, csv, "--rate-unit", "rad/s")
    bag = tmp_path / ("imu.bag" if kind == "ros1" else f"imu_{kind}")
    _bag(kind, bag, stamp, gyro, acc)
    if kind == "mcap":                 # a bare .mcap file, as a ROS 2 recorder leaves it
        bare = tmp_path / "imu.mcap"
        shutil.copy(next(bag.glob("*.mcap")), bare)
        bag = bare
    yaml = tmp_path / "imu.yaml"
    got, err = _allan(capsys, bag, "--topic", "/imu0", "--kalibr-yaml", yaml)
    assert list(got["axes"]) == [f"angular_velocity.{a}" for a in "xyz"] + [f"linear_acceleration.{a}" for a in "xyz"]
    np.testing.assert_allclose(_terms(got), _terms(ref), rtol=1e-9, atol=0)
    assert got["sample_rate_hz"] == pytest.approx(FS, rel=1e-9)
    assert "topic /imu0" in err and "8,000 sensor_msgs/Imu messages" in err and "in rad/s (sensor_msgs/Imu" in err
    text = yaml.read_text()
    assert "accelerometer_noise_density:" in text and "FILL_ME" not in text and "rostopic: /imu0" in text
    nd = float(text.split("gyroscope_noise_density:")[1].split("#")[0])
    assert nd == pytest.approx(0.3 * math.pi / 180 / 60, rel=0.15)


def test_a_bag_with_two_imu_topics_needs_topic(tmp_path, capsys):
    stamp, gyro, acc = _samples()
    bag = tmp_path / "two.bag"
    _bag("ros1", bag, stamp[:200], gyro, acc, topics=("/imu0", "/imu1"))
    code = main(["allan", str(bag)])
    _, err = capsys.readouterr()
    assert code == 2 and "2 sensor_msgs/Imu topics (/imu0, /imu1): choose one with --topic" in err
    code = main(["allan", str(bag), "--topic", "/nope"])
    _, err = capsys.readouterr()
    assert code == 2 and "no sensor_msgs/Imu topic '/nope'" in err and len(err.strip().splitlines()) == 1


def test_denoise_reads_a_bag(tmp_path, capsys):
    stamp, gyro, acc = _samples()
    bag = tmp_path / "imu.bag"
    _bag("ros1", bag, stamp, gyro, acc)
    out = tmp_path / "o.csv"
    assert main(["denoise", str(bag), "-o", str(out), "--method", "shakf"]) == 0
    capsys.readouterr()
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(got[:, 1], gyro[:, 0] * 180 / math.pi, rtol=1e-9)   # deg/s, as every output
    assert got.shape == (N, 13)


def test_mat_files_v5_and_v73_give_the_terms_of_the_csv(tmp_path, capsys):
    scipy_io = pytest.importorskip("scipy.io")
    stamp, gyro, acc = _samples()
    t = (stamp - stamp[0]) / 1e9
    csv = tmp_path / "imu.csv"
    with open(csv, "w") as f:
        f.write("time,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z\n")
        for i in range(N):
            f.write(f"{t[i]:.17g}," + ",".join(f"{v:.17g}" for v in (*gyro[i], *acc[i])) + "\n")
    ref, _ = _allan(capsys, csv, "--rate-unit", "rad/s")
    v5 = tmp_path / "imu.mat"
    scipy_io.savemat(v5, {"imu": {"time": t, "gyro": gyro, "acc": acc.T}, "fs": FS})   # acc as MATLAB's 3 x n
    got, err = _allan(capsys, v5, "--rate-unit", "rad/s")
    assert list(got["axes"]) == list(ref["axes"])
    np.testing.assert_allclose(_terms(got), _terms(ref), rtol=1e-9)
    h5py = pytest.importorskip("h5py")
    v73 = tmp_path / "imu73.mat"
    with h5py.File(v73, "w", userblock_size=512) as f:   # MATLAB -v7.3: column-major, h5py sees the transpose
        g = f.create_group("imu")
        g.attrs["MATLAB_class"] = np.bytes_("struct")
        for name, value in (("time", t[None, :]), ("gyro", gyro), ("acc", acc)):
            ds = g.create_dataset(name, data=np.ascontiguousarray(value.T))
            ds.attrs["MATLAB_class"] = np.bytes_("double")
    with open(v73, "r+b") as f:                  # MATLAB's text header in the user block
        f.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Sat Nov 28 20:00:00 2026 HDF5 schema 1.00 .")
    got, _ = _allan(capsys, v73, "--rate-unit", "rad/s", "--variable", "imu")
    np.testing.assert_allclose(_terms(got), _terms(ref), rtol=1e-9)
    code = main(["allan", str(v73), "--variable", "nope"])
    _, err = capsys.readouterr()
    assert code == 2 and "no variable 'nope' (variables: imu)" in err
