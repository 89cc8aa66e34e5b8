"""ROS bags with ``sensor_msgs/Imu``: ROS 1 bags, ROS 2 bags (sqlite3 or mcap storage), MCAP files.

Read and written with the ``rosbags`` package (pure Python, no ROS installation).
Every ``sensor_msgs/msg/Imu`` topic is read (header stamps, receive times, angular
velocity in rad/s and linear acceleration in m/s^2, as REP 103 defines them);
the other topics are listed, not decoded.

The filtered copy holds the same connections and the same messages in the same
order, with the same receive times; in an Imu message on a filtered topic only
the 24 bytes of ``angular_velocity`` differ: the values are patched in the
serialized message (their offset found from the message's own layout and
checked against rosbags' decode), never re-serialized. The container around the
messages (chunks, indexes, the sqlite3 database, the MCAP summary) is written
anew by rosbags, with the input's compression (a ROS 1 bag's first chunk's, a ROS 2
bag's mode and format).

The kinds of file are a small registry (:data:`BAG_KINDS`), each with its test of
the file's content: ``#ROSBAG V2.0`` for ROS 1, the MCAP magic, a folder with a
rosbag2 ``metadata.yaml``, the SQLite magic for a bare ``.db3``.
"""

from __future__ import annotations

import os
import re
import shutil
import struct
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, Mapping

import numpy as np

from gyrodenoise.errors import InputError

IMU_TYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
ROS1_MAGIC = b"#ROSBAG V2.0\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
EPOCH_AFTER_S = 1e9     # header stamps above this (2001-09-09) are Unix time, below it a boot or sim clock


def _head(path: Path, n: int = 16) -> bytes:
    try:
        with path.open("rb") as fh:
            return fh.read(n)
    except OSError:
        return b""


def sniff_ros1(path: Path) -> bool:
    return path.is_file() and _head(path).startswith(ROS1_MAGIC)


def sniff_mcap(path: Path) -> bool:
    return path.is_file() and _head(path).startswith(MCAP_MAGIC)


def sniff_db3(path: Path) -> bool:
    return path.is_file() and _head(path).startswith(SQLITE_MAGIC)


def sniff_ros2_dir(path: Path) -> bool:
    meta = path / "metadata.yaml"
    if not (path.is_dir() and meta.is_file()):
        return False
    try:
        return "rosbag2_bagfile_information" in meta.read_text(errors="replace")[:4096]
    except OSError:
        return False


@dataclass(frozen=True)
class BagKind:
    """One kind of bag: its name, its content test, the suffix rosbags needs, its storage when ROS 2."""

    name: str
    sniff: Callable[[Path], bool]
    ros2: bool
    suffix: str             # what rosbags opens it by ("" for a folder)
    storage: str | None     # rosbag2 storage plugin name, None for ROS 1


BAG_KINDS = (
    BagKind("ros1", sniff_ros1, False, ".bag", None),
    BagKind("ros2", sniff_ros2_dir, True, "", None),         # storage from its metadata.yaml
    BagKind("mcap", sniff_mcap, True, ".mcap", "MCAP"),
    BagKind("ros2-sqlite3-file", sniff_db3, True, ".db3", "SQLITE3"),
)


def bag_kind(path: str | os.PathLike) -> BagKind | None:
    """The kind of bag at ``path`` by its content, or None."""
    p = Path(path)
    return next((k for k in BAG_KINDS if k.sniff(p)), None)


@dataclass(frozen=True)
class ImuTopic:
    """One ``sensor_msgs/Imu`` topic of a bag, in message order."""

    topic: str
    msgtype: str
    frame_id: str                       # the first message's frame
    frame_ids: tuple[str, ...]          # every frame seen, in order of first appearance
    stamp_ns: np.ndarray                # header stamps (int64 ns: float seconds lose ns at Unix times)
    receive_ns: np.ndarray              # bag receive times (int64 ns, the recorder's clock)
    angular_velocity: np.ndarray        # (n, 3) rad/s
    linear_acceleration: np.ndarray     # (n, 3) m/s^2
    # messages that declare the field absent (covariance[0] == -1, sensor_msgs/Imu's convention)
    angular_velocity_absent: int = 0
    linear_acceleration_absent: int = 0

    def __len__(self) -> int:
        return len(self.stamp_ns)

    @property
    def stamp_s(self) -> np.ndarray:
        return self.stamp_ns * 1e-9

    @property
    def rate_hz(self) -> float:
        """Median rate of the header stamps (Hz); NaN with fewer than two increasing stamps."""
        d = np.diff(self.stamp_ns)
        d = d[d > 0]
        return 1e9 / float(np.median(d)) if len(d) else float("nan")

    @property
    def stamps_are_epoch(self) -> bool:
        """True when the header stamps are Unix time (a real clock), not a boot or simulation clock."""
        return len(self.stamp_ns) > 0 and float(self.stamp_ns[0]) * 1e-9 > EPOCH_AFTER_S


@dataclass(frozen=True)
class OtherTopic:
    topic: str
    msgtype: str
    count: int


@dataclass(frozen=True)
class ImuBag:
    path: str
    kind: str
    storage: str | None                 # ROS 2: "sqlite3" or "mcap"
    topics: tuple[str, ...]             # every topic, sorted
    imu: tuple[ImuTopic, ...]
    other: tuple[OtherTopic, ...]       # the topics that are not Imu
    message_count: int

    def topic(self, name: str) -> ImuTopic:
        for t in self.imu:
            if t.topic == name:
                return t
        raise InputError(f"no sensor_msgs/Imu topic {name!r} (Imu topics: "
                         f"{', '.join(t.topic for t in self.imu) or 'none'})", self.path)


# --- opening ---------------------------------------------------------------------------------------

def _rosbags_error(exc: Exception, path: Path) -> InputError:
    first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    return InputError(f"not a readable bag ({type(exc).__name__}: {first})", str(path))


@contextmanager
def _reader(path: Path, kind: BagKind) -> Iterator[object]:
    """An open rosbags AnyReader; a file whose suffix is not the one rosbags opens by is reached
    through a link that has it."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with tempfile.TemporaryDirectory(prefix="gyrodenoise-bag-") as tmp:
        target = path
        if kind.suffix and path.suffix != kind.suffix:
            target = Path(tmp) / f"bag{kind.suffix}"
            target.symlink_to(path.resolve())
        store = get_typestore(Stores.ROS2_HUMBLE if kind.ros2 else Stores.ROS1_NOETIC)
        try:
            reader = AnyReader([target], default_typestore=store)
            reader.open()
        except Exception as exc:        # rosbags' many error classes: one line for the user
            raise _rosbags_error(exc, path) from None
        try:
            yield reader
        finally:
            reader.close()


def _kind_or_error(path: Path) -> BagKind:
    if not path.exists():
        raise InputError("no such file or folder", str(path))
    kind = bag_kind(path)
    if kind is None:
        raise InputError("not a ROS bag: no '#ROSBAG V2.0' or MCAP magic, no rosbag2 metadata.yaml", str(path))
    return kind


def _storage_name(path: Path, kind: BagKind) -> str | None:
    """"sqlite3" or "mcap" for a ROS 2 bag (a folder's from its metadata.yaml), None for ROS 1."""
    if not kind.ros2:
        return None
    if kind.storage:
        return kind.storage.lower()
    m = re.search(r"storage_identifier:\s*['\"]?(\w+)", (path / "metadata.yaml").read_text(errors="replace"))
    return m.group(1).lower() if m else None


# --- reading ---------------------------------------------------------------------------------------

def read_imu(path: str | os.PathLike, topic: str | None = None) -> ImuBag:
    """Every ``sensor_msgs/Imu`` topic of a bag (only ``topic`` when given), and the other topics' names."""
    p = Path(path)
    kind = _kind_or_error(p)
    with _reader(p, kind) as reader:
        conns = reader.connections
        imu_conns = [c for c in conns if c.msgtype in IMU_TYPES]
        if topic is not None:
            imu_conns = [c for c in imu_conns if c.topic == topic]
            if not imu_conns:
                names = sorted({c.topic for c in conns if c.msgtype in IMU_TYPES})
                raise InputError(f"no sensor_msgs/Imu topic {topic!r} (Imu topics: {', '.join(names) or 'none'})",
                                 str(p))
        collected: dict[str, dict[str, list]] = {}
        try:
            for conn, t_ns, raw in reader.messages(connections=imu_conns) if imu_conns else ():
                msg = reader.deserialize(raw, conn.msgtype)
                rows = collected.setdefault(conn.topic, {"type": [conn.msgtype], "stamp": [], "recv": [],
                                                         "gyro": [], "acc": [], "frames": [],
                                                         "no_gyro": [0], "no_acc": [0]})
                rows["stamp"].append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
                rows["recv"].append(t_ns)
                av, la = msg.angular_velocity, msg.linear_acceleration
                rows["gyro"].append((av.x, av.y, av.z))
                rows["acc"].append((la.x, la.y, la.z))
                rows["no_gyro"][0] += bool(msg.angular_velocity_covariance[0] == -1)
                rows["no_acc"][0] += bool(msg.linear_acceleration_covariance[0] == -1)
                if msg.header.frame_id not in rows["frames"]:
                    rows["frames"].append(msg.header.frame_id)
        except InputError:
            raise
        except Exception as exc:
            raise _rosbags_error(exc, p) from None
        imu = tuple(
            ImuTopic(topic=name, msgtype=rows["type"][0],
                     frame_id=rows["frames"][0] if rows["frames"] else "", frame_ids=tuple(rows["frames"]),
                     stamp_ns=np.array(rows["stamp"], dtype=np.int64), receive_ns=np.array(rows["recv"], dtype=np.int64),
                     angular_velocity=np.array(rows["gyro"], dtype=float).reshape(-1, 3),
                     linear_acceleration=np.array(rows["acc"], dtype=float).reshape(-1, 3),
                     angular_velocity_absent=rows["no_gyro"][0], linear_acceleration_absent=rows["no_acc"][0])
            for name, rows in sorted(collected.items()))
        counts: dict[tuple[str, str], int] = {}
        for c in conns:
            if c.msgtype not in IMU_TYPES:
                counts[(c.topic, c.msgtype)] = counts.get((c.topic, c.msgtype), 0) + max(c.msgcount, 0)
        other = tuple(OtherTopic(t, m, n) for (t, m), n in sorted(counts.items()))
        return ImuBag(path=str(p), kind=kind.name, storage=_storage_name(p, kind),
                      topics=tuple(sorted({c.topic for c in conns})), imu=imu, other=other,
                      message_count=int(reader.message_count))


# --- patching --------------------------------------------------------------------------------------

def angular_velocity_offset(raw: bytes, ros2: bool) -> tuple[int, str]:
    """(offset, struct byte order) of ``angular_velocity`` (three float64) in a serialized Imu message.

    ROS 1: ``uint32 seq, uint32 sec, uint32 nsec, string frame_id`` (uint32 length
    and bytes), ``orientation`` (4 float64), ``orientation_covariance`` (9 float64),
    then ``angular_velocity``. CDR (ROS 2): a 4-byte encapsulation header (its second
    byte 1 = little-endian), ``int32 sec, uint32 nanosec, string frame_id`` (uint32
    length counting the NUL, bytes, NUL), padding to 8 bytes from the body's start,
    then the same fields.
    """
    if not ros2:
        (length,) = struct.unpack_from("<I", raw, 12)
        return 16 + length + 104, "<"
    if len(raw) < 4 or raw[0] != 0 or raw[1] not in (0, 1):
        raise ValueError(f"CDR encapsulation {raw[:2].hex()} is not plain CDR")
    order = "<" if raw[1] == 1 else ">"
    (length,) = struct.unpack_from(order + "I", raw, 4 + 8)
    body = 8 + 4 + length
    body = (body + 7) // 8 * 8
    return 4 + body + 104, order


def _patch(raw: bytes, ros2: bool, old: tuple[float, float, float], new: np.ndarray, where: str) -> bytes:
    try:
        off, order = angular_velocity_offset(raw, ros2)
        present = struct.unpack_from(order + "3d", raw, off)
    except (struct.error, ValueError) as exc:
        raise InputError(f"{where}: cannot place angular_velocity in the serialized message ({exc})") from None
    if present != tuple(old):
        raise InputError(f"{where}: angular_velocity at byte {off} is {present}, rosbags decodes {tuple(old)}: "
                         f"layout not understood, nothing written")
    out = bytearray(raw)
    struct.pack_into(order + "3d", out, off, *(float(v) for v in new))
    return bytes(out)


def _check_filtered(bag: ImuBag, filtered: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    arrays = {}
    for name, values in filtered.items():
        t = bag.topic(name)
        a = np.asarray(values, dtype=float)
        if a.shape != (len(t), 3):
            raise InputError(f"filtered {name}: shape {a.shape}, the bag has {len(t)} messages x 3 axes", bag.path)
        if not np.all(np.isfinite(a)):
            raise InputError(f"filtered {name}: {int(np.sum(~np.isfinite(a)))} values are not finite", bag.path)
        arrays[name] = a
    return arrays


def ros1_chunk_compression(path: Path) -> str:
    """The compression of a ROS 1 bag's first chunk ("none", "bz2", "lz4"), from its record header:
    the ``compression=`` field, whose uint32 length precedes it."""
    with path.open("rb") as fh:
        head = fh.read(1 << 16)
    at = head.find(b"compression=")
    if at < 4:
        return "none"
    (length,) = struct.unpack_from("<I", head, at - 4)
    return head[at + len(b"compression="):at + length].decode("ascii", "replace")


def _open_writer(kind: BagKind, storage: str | None, reader, dest: Path, source: Path):
    if not kind.ros2:
        from rosbags.rosbag1 import Writer as Writer1
        writer = Writer1(dest)
        compression = ros1_chunk_compression(source)
        if compression.upper() in Writer1.CompressionFormat.__members__:
            writer.set_compression(Writer1.CompressionFormat[compression.upper()])
        return writer
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    if storage is None or storage.upper() not in StoragePlugin.__members__:
        raise InputError(f"rosbag2 storage {storage!r}: rosbags writes sqlite3 and mcap only")
    writer = Writer2(dest, version=9, storage_plugin=StoragePlugin[storage.upper()])
    mode, fmt = reader.readers[0].compression_mode, reader.readers[0].compression_format
    if mode and fmt:
        writer.set_compression(CompressionMode[mode.upper()], CompressionFormat[fmt.upper()])
    return writer


def _add_connection(writer, conn, ros2: bool, typestore):
    if not ros2:
        ext = conn.ext
        if conn.msgdef.data and conn.digest:
            return writer.add_connection(conn.topic, conn.msgtype, msgdef=conn.msgdef.data, md5sum=conn.digest,
                                         callerid=ext.callerid, latching=ext.latching)
        return writer.add_connection(conn.topic, conn.msgtype, typestore=typestore, callerid=ext.callerid,
                                     latching=ext.latching)
    ext = conn.ext
    kwargs = dict(serialization_format=ext.serialization_format, offered_qos_profiles=ext.offered_qos_profiles)
    if conn.msgdef.data and conn.digest:
        return writer.add_connection(conn.topic, conn.msgtype, msgdef=conn.msgdef.data, rihs01=conn.digest, **kwargs)
    return writer.add_connection(conn.topic, conn.msgtype, typestore=typestore, **kwargs)


def write_filtered(path: str | os.PathLike, out_path: str | os.PathLike,
                   filtered: Mapping[str, np.ndarray]) -> Path:
    """A copy of the bag at ``out_path`` where each topic in ``filtered`` (topic -> (n, 3) rad/s, one row
    per message in order) has its ``angular_velocity`` replaced; every other byte of every message is
    kept, as are the messages' order and receive times. ``out_path`` must not exist."""
    p, out = Path(path), Path(out_path)
    kind = _kind_or_error(p)
    if out.exists() or out.is_symlink():
        raise InputError("exists already: the filtered bag is written to a new path", str(out))
    bag = read_imu(p)
    arrays = _check_filtered(bag, filtered)
    row = {name: 0 for name in arrays}
    with _reader(p, kind) as reader, tempfile.TemporaryDirectory(prefix="gyrodenoise-bag-", dir=out.parent) as tmp:
        folder_output = kind.ros2 and not kind.suffix
        dest = out if folder_output else Path(tmp) / ("out" + (".bag" if not kind.ros2 else ""))
        try:
            writer = _open_writer(kind, bag.storage, reader, dest, p)
            writer.open()
        except InputError:
            raise
        except Exception as exc:
            raise InputError(f"cannot write the filtered bag ({type(exc).__name__}: {exc})", str(out)) from None
        try:
            out_conns: dict[int, object] = {}
            by_key: dict[tuple, object] = {}
            for conn in reader.connections:
                key = (conn.topic, conn.msgtype, repr(conn.ext))
                if key not in by_key:
                    by_key[key] = _add_connection(writer, conn, kind.ros2, reader.typestore)
                out_conns[conn.id] = by_key[key]
            for conn, t_ns, raw in reader.messages():
                data = raw
                if conn.topic in arrays and conn.msgtype in IMU_TYPES:
                    i = row[conn.topic]
                    msg = reader.deserialize(raw, conn.msgtype)
                    av = msg.angular_velocity
                    data = _patch(raw, kind.ros2, (av.x, av.y, av.z), arrays[conn.topic][i],
                                  f"{p}: {conn.topic} message {i + 1}")
                    row[conn.topic] = i + 1
                writer.write(out_conns[conn.id], t_ns, data)
        except InputError:
            _abandon(writer, dest if folder_output else None)
            raise
        except Exception as exc:
            _abandon(writer, dest if folder_output else None)
            raise _rosbags_error(exc, p) from None
        writer.close()
        if not folder_output:
            produced = dest if not kind.ros2 else _single_storage_file(dest, kind.suffix)
            shutil.move(str(produced), str(out))
    return out


def _single_storage_file(folder: Path, suffix: str) -> Path:
    files = sorted(folder.glob(f"*{suffix}"))
    if len(files) != 1:
        raise InputError(f"rosbags wrote {len(files)} {suffix} files, expected one", str(folder))
    return files[0]


def _abandon(writer, folder: Path | None) -> None:
    try:
        writer.close()
    except Exception:
        pass
    if folder is not None and folder.exists():
        shutil.rmtree(folder, ignore_errors=True)

