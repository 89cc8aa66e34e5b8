"""Low-level fidelity of the log readers and writers on SYNTHETIC logs with known
truth: a DataFlash FMT redefined mid-log, the ULog patched in place, malformed
streams, PX4's FIFO topics. The filtered copy is checked against independent
readers (pymavlink's DFReader, pyulog) and a byte diff, not against our reader."""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from gyrodenoise.errors import InputError

from tests.flightlog.synthetic_logs import _STRUCT, DataFlashWriter, ULogWriter, tlog_writer

from tests.helpers import shared_log


# ------------------------------------------------------------ our code, one place
def filter_copy(path, out, values):
    """Read ``path`` with gyrodenoise, set each stream's filtered values to
    ``values(stream)`` and write the filtered copy to ``out``; (streams, facts)."""
    from gyrodenoise.flightlog.formats import read_log
    log = read_log(path)
    for s in log.gyro:
        s.filtered = values(s)
    log.format.write_filtered(log, out)
    streams, facts = log.gyro, log.facts.to_fields()
    return streams, facts


# ------------------------------------------------------- independent references
def df_messages(path):
    """Every message of a DataFlash log as pymavlink's sequential reader decodes
    it: [(name, {field: value})]. pymavlink indexes the whole file first (leaving
    the last definition of each type in force) and caches one unpacker per type
    id; both are reset here so that each FMT holds from where it stands."""
    from pymavlink import DFReader
    r = DFReader.DFReader_binary(str(path))
    r.formats = {0x80: r.formats[0x80]}
    r.unpackers = {}
    r._rewind()
    out = []
    while True:
        m = r.recv_msg()
        if m is None:
            break
        name = m.get_type()
        if name == "FMT":
            r.unpackers.pop(m.Type, None)
        out.append((name, {c: getattr(m, c) for c in m.get_fieldnames()}))
    return out


def df_field_positions(written, names, fields):
    """Byte positions (a set) of ``fields`` in the messages ``names`` of a
    :class:`DataFlashWriter` log, from the layout each was written with."""
    pos = set()
    for name, off, fmt, cols in written:
        if name not in names:
            continue
        at = 3
        for ch, col in zip(fmt, cols):
            size = struct.calcsize("<" + _STRUCT[ch])
            if col in fields:
                pos.update(range(off + at, off + at + size))
            at += size
    return pos


def changed_positions(a, b):
    assert len(a) == len(b)
    x = np.frombuffer(a, np.uint8)
    y = np.frombuffer(b, np.uint8)
    return set(np.nonzero(x != y)[0].tolist())


# ------------------------------------------------------------ FMT redefinition
IMU_OLD = ("QBffffff", ["TimeUS", "I", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"])
IMU_NEW = ("QBffffffH", ["TimeUS", "I", "AccX", "AccY", "AccZ", "GyrX", "GyrY", "GyrZ", "T"])
GYRO = ("GyrX", "GyrY", "GyrZ")


def redefined_fmt_log(n=200, seed=7, move=True):
    """IMU (type 0x81) redefined with another layout and length after n messages;
    BARO's type id renamed XYZ with another length; then (``move``) the name IMU
    moves to a third layout on a new type id while 0x81 becomes VIBE. Returns
    (bytes, writer, gyro truth (2n or 3n, 3) in file order)."""
    rng = np.random.default_rng(seed)
    w = DataFlashWriter()
    w.define("IMU", *IMU_OLD)                                   # 0x81
    w.define("BARO", "Qff", ["TimeUS", "Alt", "Press"])         # 0x82
    truth = rng.normal(0, 0.3, (3 * n, 3)).astype(np.float32)
    acc = rng.normal(0, 9.8, (3 * n, 3)).astype(np.float32)
    t = 1000
    for k in range(n):
        t += 2500
        w.add("IMU", t, 0, *truth[k], *acc[k])
        w.add("BARO", t, 12.5 + k, 1013.0)
    w.define("IMU", *IMU_NEW, type_id=0x81)
    w.define("XYZ", "QHHH", ["TimeUS", "A", "B", "C"], type_id=0x82)
    for k in range(n, 2 * n):
        t += 2500
        w.add("IMU", t, 0, *acc[k], *truth[k], 4000 + k)
        w.add("XYZ", t, k, 2 * k, 3 * k)
    if not move:
        return w.bytes(), w, truth[:2 * n]
    w.define("VIBE", "Qfff", ["TimeUS", "VibeX", "VibeY", "VibeZ"], type_id=0x81)
    w.define("IMU", "QBIffffff", ["TimeUS", "I", "EG", "GyrX", "GyrY", "GyrZ", "AccX", "AccY", "AccZ"],
             type_id=0x90)
    for k in range(2 * n, 3 * n):
        t += 2500
        w.add("IMU", t, 0, 7, *truth[k], *acc[k])
        w.add("VIBE", t, 0.1, 0.2, 0.3)
    return w.bytes(), w, truth


@pytest.mark.parametrize("move", [False, True], ids=["same_id_new_layout", "name_moves_to_new_id"])
def test_fmt_redefined_mid_log_is_honoured(tmp_path, move):
    data, w, truth = redefined_fmt_log(move=move)
    src = tmp_path / "redef.bin"
    src.write_bytes(data)
    out = tmp_path / "redef.filtered.bin"
    streams, _ = filter_copy(src, out, lambda s: s.raw * 0.5 + 0.01)
    names = [s.name for s in streams]
    assert len(names) == len(set(names)), names
    imu = [s for s in streams if s.name == "IMU[0]"]
    assert len(imu) == 1 and imu[0].n == len(truth)
    np.testing.assert_array_equal(imu[0].raw.astype(np.float32), truth)   # nothing invented
    # pymavlink's reading of the original agrees with the truth, that of the copy
    # holds the filtered values in the gyro fields and every other field unchanged
    before, after = df_messages(src), df_messages(out)
    assert [m[0] for m in before] == [m[0] for m in after]
    got = np.array([[f[g] for g in GYRO] for name, f in after if name == "IMU"], dtype=np.float32)
    np.testing.assert_array_equal(got, (truth.astype(np.float64) * 0.5 + 0.01).astype(np.float32))
    for (name, fa), (_, fb) in zip(before, after):
        skip = GYRO if name == "IMU" else ()
        assert {k: v for k, v in fa.items() if k not in skip} == {k: v for k, v in fb.items() if k not in skip}
    # the byte diff: nothing outside the IMU gyro fields
    allowed = df_field_positions(w.written, {"IMU"}, set(GYRO))
    assert changed_positions(data, out.read_bytes()) - allowed == set()


# ------------------------------------------------------------ ULog, in place
def ulog_gyro_positions(path, topics):
    """Byte positions (a set) of the fields ``topics[topic]`` in the data messages
    of a ULog file: the message headers walked here, each topic's layout from
    pyulog's field list (independent of our scanner; for uncorrupted files)."""
    import pyulog
    u = pyulog.ULog(str(path))
    fields = {}
    for d in u.data_list:
        if d.name not in topics:
            continue
        at, offs = 0, {}
        for f in d.field_data:
            size = pyulog.ULog._UNPACK_TYPES[f.type_str][1]
            offs[f.field_name] = (at, size)
            at += size
        fields[d.msg_id] = [offs[c] for c in topics[d.name] if c in offs]
    return ulog_field_positions(Path(path).read_bytes(), fields)


def ulog_field_positions(data, fields):
    """Byte positions (a set) of the fields ``fields[msg_id]`` ((offset after the msg
    id, size) each) in the data messages of a ULog file held in ``data``."""
    pos, n, out = 16, len(data), set()
    while pos + 3 <= n:
        size = data[pos] | (data[pos + 1] << 8)
        if data[pos + 2] == ord("D") and pos + 5 <= n:
            for off, k in fields.get(data[pos + 3] | (data[pos + 4] << 8), ()):
                out.update(range(pos + 5 + off, pos + 5 + off + k))
        pos += 3 + size
    return out


def assert_ulog_same_except(a_path, b_path, topics, expected=None):
    """pyulog's readings of two ULog files agree on everything but the fields
    ``topics[topic]``; those of ``b`` equal ``expected[(topic, multi_id)]`` (n, k)
    when given."""
    import pyulog
    a, b = pyulog.ULog(str(a_path)), pyulog.ULog(str(b_path))
    assert [(d.name, d.multi_id) for d in a.data_list] == [(d.name, d.multi_id) for d in b.data_list]
    for da, db in zip(a.data_list, b.data_list):
        assert list(da.data) == list(db.data)
        skip = topics.get(da.name, ())
        for f in da.data:
            if f not in skip:
                assert np.array_equal(da.data[f], db.data[f], equal_nan=da.data[f].dtype.kind == "f"), \
                    (da.name, da.multi_id, f)
        if expected is not None and (da.name, da.multi_id) in expected:
            got = np.stack([db.data[c] for c in skip], axis=1)
            np.testing.assert_array_equal(got, expected[(da.name, da.multi_id)].astype(got.dtype))
    assert a.msg_info_dict == b.msg_info_dict
    assert a.initial_parameters == b.initial_parameters
    assert a.changed_parameters == b.changed_parameters
    assert [(m.timestamp, m.message) for m in a.logged_messages] == [(m.timestamp, m.message) for m in b.logged_messages]
    assert [(d.timestamp, d.duration) for d in a.dropouts] == [(d.timestamp, d.duration) for d in b.dropouts]


ULOG_GYRO = {"sensor_combined": ("gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"), "sensor_gyro": ("x", "y", "z")}


def _ulog_expected(streams):
    out = {}
    for s in streams:
        base, _, inst = s.name.partition("[")
        out[(s.message, int(inst.rstrip("]")) if inst else 0)] = s.filtered
    return out


@pytest.mark.parametrize("name", ["px4_vtol_small.ulg", "px4_quad_ekf_failure.ulg"])
def test_ulog_filtered_copy_is_patched_in_place(tmp_path, name):
    src = shared_log(name)
    out = tmp_path / ("filtered_" + name)
    streams, _ = filter_copy(src, out, lambda s: s.raw * 0.5 + 0.01)
    import pyulog
    assert sorted(_ulog_expected(streams)) == sorted(
        (d.name, d.multi_id) for d in pyulog.ULog(str(src)).data_list if d.name in ULOG_GYRO)
    orig, new = src.read_bytes(), out.read_bytes()
    assert len(orig) == len(new)
    assert changed_positions(orig, new) - ulog_gyro_positions(src, ULOG_GYRO) == set()
    assert_ulog_same_except(src, out, ULOG_GYRO, _ulog_expected(streams))


def test_ulog_bad_timestamp_keeps_the_order(tmp_path):
    """One sensor_gyro timestamp set far back: the copy keeps the messages where they were."""
    import pyulog
    src = shared_log("px4_vtol_small.ulg")
    data = bytearray(src.read_bytes())
    u = pyulog.ULog(str(src))
    d = next(d for d in u.data_list if d.name == "sensor_gyro")
    pos, hits = 16, []
    while pos + 3 <= len(data):
        if data[pos + 2] == ord("D") and (data[pos + 3] | (data[pos + 4] << 8)) == d.msg_id:
            hits.append(pos)
        pos += 3 + (data[pos] | (data[pos + 1] << 8))
    data[hits[2] + 5:hits[2] + 13] = struct.pack("<Q", 5)      # timestamp is the first field
    bad = tmp_path / "bad_ts.ulg"
    bad.write_bytes(bytes(data))
    out = tmp_path / "bad_ts.filtered.ulg"
    streams, _ = filter_copy(bad, out, lambda s: s.raw * 0.5)
    assert changed_positions(bytes(data), out.read_bytes()) - ulog_gyro_positions(bad, ULOG_GYRO) == set()
    assert_ulog_same_except(bad, out, ULOG_GYRO, _ulog_expected(streams))


# ------------------------------------------------------------ malformed input
def test_dataflash_imu_format_without_gyro_fields(tmp_path):
    """A format named IMU without GyrX/GyrY/GyrZ (declared before the real one) is
    skipped with the reason; the gyro IMU is read and patched at its own offsets."""
    rng = np.random.default_rng(3)
    w = DataFlashWriter()
    w.define("IMU", "QBfff", ["TimeUS", "I", "AccX", "AccY", "AccZ"])
    w.define("IMU", *IMU_OLD)
    truth = rng.normal(0, 0.2, (300, 3)).astype(np.float32)
    for k in range(300):
        w.add("IMU", 1000 + 2500 * k, 0, *truth[k], 0.1, 0.2, 9.8)
    src = tmp_path / "nogyro.bin"
    src.write_bytes(w.bytes())
    out = tmp_path / "nogyro.filtered.bin"
    streams, facts = filter_copy(src, out, lambda s: s.raw * 0.5)
    assert [s.name for s in streams] == ["IMU[0]"]
    np.testing.assert_array_equal(streams[0].raw.astype(np.float32), truth)
    after = df_messages(out)
    got = np.array([[f[g] for g in GYRO] for name, f in after if name == "IMU"], dtype=np.float32)
    np.testing.assert_array_equal(got, (truth * 0.5).astype(np.float32))
    assert changed_positions(src.read_bytes(), out.read_bytes()) - \
        df_field_positions(w.written, {"IMU"}, set(GYRO)) == set()


def test_ulog_sensor_combined_without_timestamp(tmp_path):
    """sensor_combined without a timestamp field: skipped with the reason in the
    facts; sensor_gyro read and patched; every other byte kept. (pyulog stops
    reading at the first sensor_combined message of such a log: the check is on
    the bytes, with the layout this test wrote.)"""
    rng = np.random.default_rng(4)
    u = ULogWriter()
    u.define("sensor_combined", [("uint64_t", "time"), ("float[3]", "gyro_rad")])
    u.define("sensor_gyro", [("uint64_t", "timestamp"), ("uint8_t", "n"), ("uint8_t[3]", "_padding0"),
                             ("float", "x"), ("float", "y"), ("float", "z")])
    a, b = u.subscribe("sensor_combined"), u.subscribe("sensor_gyro")
    truth = rng.normal(0, 0.1, (500, 3)).astype(np.float32)
    for k in range(500):
        u.add(a, 1000 * k, rng.normal(0, 0.1, 3))
        u.add(b, 1000 * k, 7, *truth[k])
        if k % 100 == 0:
            u.sync()
    src = tmp_path / "nots.ulg"
    src.write_bytes(u.bytes())
    out = tmp_path / "nots.filtered.ulg"
    streams, facts = filter_copy(src, out, lambda s: s.raw * 0.5)
    assert [s.name for s in streams] == ["sensor_gyro"]
    np.testing.assert_array_equal(streams[0].raw.astype(np.float32), truth)
    assert any("sensor_combined" in r and "timestamp" in r for r in facts["streams_skipped"])
    xyz = {b: [(12, 4), (16, 4), (20, 4)]}
    new = out.read_bytes()
    assert changed_positions(src.read_bytes(), new) - ulog_field_positions(src.read_bytes(), xyz) == set()
    at = sorted(ulog_field_positions(new, {b: [(12, 12)]}))
    got = np.frombuffer(bytes(new[i] for i in at), dtype="<f4").reshape(-1, 3)
    np.testing.assert_array_equal(got, (truth * 0.5).astype(np.float32))


@pytest.mark.parametrize("fields", [
    [("uint64_t", "timestamp"), ("float", "x"), ("float", "x"), ("float", "y"), ("float", "z")],
    [("uint64_t", "timestamp"), ("float", "x"), ("float", "y"), ("float", "z"), ("uint8_t[99999999]", "big")],
    [("uint64_t", "timestamp"), ("sensor_gyro", "inner"), ("float", "x"), ("float", "y"), ("float", "z")],
], ids=["duplicate_field", "huge_array", "nests_itself"])
def test_ulog_malformed_gyro_format_is_skipped(tmp_path, fields):
    """sensor_gyro's format with two fields of one name or an array longer than a
    message: skipped with the reason, sensor_combined read; nested in itself (pyulog
    cannot read the file): one line."""
    u = ULogWriter()
    u.define("sensor_combined", [("uint64_t", "timestamp"), ("float[3]", "gyro_rad")])
    text = "sensor_gyro:" + "".join(f"{t} {f};" for t, f in fields)
    u._msg("F", text.encode())
    a, b = u.subscribe("sensor_combined"), u.subscribe("sensor_gyro")
    u.structs["sensor_gyro"] = "<Qfff"
    for k in range(200):
        u.add(a, 1000 * k, [0.1, 0.2, 0.3])
        u.add(b, 1000 * k, 0.1, 0.2, 0.3)
    src = tmp_path / "bad_format.ulg"
    src.write_bytes(u.bytes())
    if fields[1][0] == "sensor_gyro":           # pyulog cannot read it at all: one line
        with pytest.raises(InputError, match=r"not a readable ULog \(RecursionError") as exc:
            filter_copy(src, tmp_path / "out.ulg", lambda s: s.raw * 0.5)
        assert "\n" not in str(exc.value)
        return
    streams, facts = filter_copy(src, tmp_path / "out.ulg", lambda s: s.raw * 0.5)
    assert [s.name for s in streams] == ["sensor_combined"]
    assert any(r.startswith("sensor_gyro[0]") for r in facts["streams_skipped"])


def test_tlog_highres_imu_with_an_infinity(tmp_path):
    """One -inf in a HIGHRES_IMU gyro field: written back as -inf (the damaged sample
    kept as it was), the other samples filtered; no exception."""
    from pymavlink import mavutil
    rng = np.random.default_rng(5)
    mav, add, get = tlog_writer()
    truth = rng.normal(0, 0.1, (400, 3))
    truth[150, 1] = -np.inf
    for k in range(400):
        if k % 50 == 0:
            add(mav.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3), 1e15 + 4000 * k)
        add(mav.MAVLink_highres_imu_message(4000 * k, 0, 0, 9.8, *truth[k], 0, 0, 0, 1000, 0, 0, 20, 0),
            1e15 + 4000 * k)
    src = tmp_path / "inf.tlog"
    src.write_bytes(get())
    out = tmp_path / "inf.filtered.tlog"
    filter_copy(src, out, lambda s: np.where(np.isfinite(s.raw), s.raw * 0.5, s.raw))
    m = mavutil.mavlink_connection(str(out))
    got = []
    while (msg := m.recv_match(type="HIGHRES_IMU")) is not None:
        got.append((msg.xgyro, msg.ygyro, msg.zgyro))
    want = np.where(np.isfinite(truth), truth * 0.5, truth).astype(np.float32)
    np.testing.assert_array_equal(np.array(got, dtype=np.float32), want)


# ------------------------------------------------------------ PX4 FIFO topics
FIFO_FIELDS = [("uint64_t", "timestamp"), ("uint64_t", "timestamp_sample"), ("uint32_t", "device_id"),
               ("float", "dt"), ("float", "scale"), ("int16_t[32]", "x"), ("int16_t[32]", "y"),
               ("int16_t[32]", "z"), ("uint8_t", "samples"), ("uint8_t[7]", "_padding0")]


def fifo_log(tone_hz=173.0, rate_hz=2000.0, per_msg=8, seconds=4.0, seed=11):
    """A ULog with sensor_gyro_fifo and sensor_accel_fifo at ``rate_hz`` (``per_msg``
    samples a message), a tone on gyro x and accel z, and sensor_combined at 250
    Hz. Returns (bytes, fifo msg ids (gyro, accel), gyro counts (n, 3), scale)."""
    rng = np.random.default_rng(seed)
    n = int(seconds * rate_hz) // per_msg * per_msg
    t = np.arange(n) / rate_hz
    g_scale, a_scale = np.float32(2000 / 32768 * np.pi / 180), np.float32(16 * 9.81 / 32768)
    gyro = np.stack([0.3 * np.sin(2 * np.pi * tone_hz * t), 0.02 * t, np.zeros(n)], 1) + rng.normal(0, 0.01, (n, 3))
    counts = np.rint(gyro / g_scale).astype(np.int16)
    acc = np.stack([np.zeros(n), np.zeros(n), -9.81 + 2.0 * np.sin(2 * np.pi * tone_hz * t)], 1)
    acounts = np.rint(acc / a_scale).astype(np.int16)
    u = ULogWriter()
    u.define("sensor_gyro_fifo", FIFO_FIELDS)
    u.define("sensor_accel_fifo", FIFO_FIELDS)
    u.define("sensor_combined", [("uint64_t", "timestamp"), ("float[3]", "gyro_rad"),
                                 ("uint32_t", "gyro_integral_dt")])
    gi, ai, ci = u.subscribe("sensor_gyro_fifo"), u.subscribe("sensor_accel_fifo"), u.subscribe("sensor_combined")
    dt_us = 1e6 / rate_hz
    for m in range(n // per_msg):
        sl = slice(m * per_msg, (m + 1) * per_msg)
        last_us = int(round(1e6 + (m + 1) * per_msg * dt_us - dt_us))
        pad = np.zeros(32 - per_msg, np.int16)
        for mid, c, sc in ((gi, counts, g_scale), (ai, acounts, a_scale)):
            u.add(mid, last_us + 50, last_us, 123, dt_us, sc,
                  *[np.concatenate([c[sl, k], pad]) for k in range(3)], per_msg)
        u.add(ci, last_us + 60, gyro[sl].mean(0), 4000)
        if m % 100 == 0:
            u.sync()
    return u.bytes(), (gi, ai), counts, float(g_scale)


def test_px4_fifo_topics_read_at_their_rate_and_patched(tmp_path):
    from gyrodenoise.flightlog import ulog
    data, (gi, ai), counts, scale = fifo_log()
    src = tmp_path / "fifo.ulg"
    src.write_bytes(data)
    out = tmp_path / "fifo.filtered.ulg"
    streams, _ = filter_copy(src, out, lambda s: s.raw * 0.5)
    fifo = next(s for s in streams if s.name == "sensor_gyro_fifo")
    np.testing.assert_array_equal(fifo.raw, counts * np.float64(np.float32(scale)))
    step = np.median(np.diff(fifo.time_s))
    assert 1 / step == pytest.approx(2000.0, rel=1e-3) and np.all(np.diff(fifo.time_s) > 0)
    spec = np.abs(np.fft.rfft(fifo.raw[:, 0] - fifo.raw[:, 0].mean()))
    freqs = np.fft.rfftfreq(fifo.n, step)
    assert freqs[np.argmax(spec)] == pytest.approx(173.0, abs=freqs[1])
    # the accelerometer FIFO: the same tone at the same rate
    _, _, refs = ulog.read(src)
    acc = ulog.accel_streams(refs)
    assert [a.name for a in acc] == ["sensor_accel_fifo"] and acc[0].rate_hz == pytest.approx(2000.0)
    aspec = np.abs(np.fft.rfft(acc[0].values[:, 2] - acc[0].values[:, 2].mean()))
    assert np.fft.rfftfreq(len(aspec) * 2 - 2, 1 / 2000.0)[np.argmax(aspec)] == pytest.approx(173.0, abs=0.5)
    # the copy: pyulog reads every field unchanged but the valid FIFO samples, which hold
    # the filtered values in counts; bytes changed only there
    gyro_cols = {"sensor_gyro_fifo": tuple(f"{a}[{k}]" for a in "xyz" for k in range(8))}
    want = np.rint(counts.astype(np.float64) * 0.5).reshape(-1, 8, 3).transpose(0, 2, 1).reshape(-1, 24)
    assert_ulog_same_except(src, out, dict(gyro_cols, sensor_combined=("gyro_rad[0]", "gyro_rad[1]",
                                                                       "gyro_rad[2]")),
                            {("sensor_gyro_fifo", 0): want})
    allowed = ulog_field_positions(data, {gi: [(28 + 64 * a, 16) for a in range(3)]})
    comb = ulog_gyro_positions(src, {"sensor_combined": ("gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]")})
    assert changed_positions(data, out.read_bytes()) - allowed - comb == set()


@pytest.mark.parametrize("make", ["dataflash", "ulog"])
def test_overflowing_float_is_refused_not_stored_as_infinity(tmp_path, make):
    """A finite filtered value beyond float32 is refused (ValueError, as for an int16
    field): the pipeline checks field_misfit first and keeps such a stream raw."""
    if make == "dataflash":
        w = DataFlashWriter()
        w.define("IMU", *IMU_OLD)
        for k in range(50):
            w.add("IMU", 1000 + 2500 * k, 0, 0.1, 0.2, 0.3, 0.0, 0.0, 9.8)
        src = tmp_path / "o.bin"
        src.write_bytes(w.bytes())
    else:
        u = ULogWriter()
        u.define("sensor_gyro", [("uint64_t", "timestamp"), ("float", "x"), ("float", "y"), ("float", "z")])
        g = u.subscribe("sensor_gyro")
        for k in range(50):
            u.add(g, 1000 * k, 0.1, 0.2, 0.3)
        src = tmp_path / "o.ulg"
        src.write_bytes(u.bytes())
    with pytest.raises(ValueError, match="does not fit float32"):
        filter_copy(src, tmp_path / ("out" + src.suffix), lambda s: np.where(np.arange(s.n)[:, None] == 7, 1e39, s.raw))
