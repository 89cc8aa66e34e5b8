"""Live bridge: replay real tlogs over loopback UDP into ``gyrodenoise mavlink
udpin:... --forward udpout:...`` and check what comes out the other side.

Only 127.0.0.1 is used; the bridge is bounded by ``--count`` and ``--duration``
and every wait in the test has a timeout.
"""

from __future__ import annotations

import json
import math
import socket
import subprocess
import threading
import time

import numpy as np
import pytest

import gyrodenoise as gd
from tests.helpers import DATA, SHARED_DATA, gyrodenoise_cmd
from tests.flightlog.references import ref_restarts


SHARED_LOGS = SHARED_DATA / "logs"
R2D = 180.0 / math.pi
GYRO = ("RAW_IMU", "SCALED_IMU", "SCALED_IMU2", "SCALED_IMU3", "HIGHRES_IMU")


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def tlog_packets(path, limit=None):
    """pymavlink's reading of a tlog: the original bytes of each readable message."""
    from pymavlink import mavutil
    m = mavutil.mavlink_connection(str(path), robust_parsing=True)
    out = []
    while limit is None or len(out) < limit:
        msg = m.recv_match()
        if msg is None:
            break
        if msg.get_type() != "BAD_DATA":
            out.append(bytes(msg.get_msgbuf()))
    m.close()
    return out


def decode(pkts):
    from pymavlink.dialects.v20 import ardupilotmega as mav
    out = []
    for p in pkts:
        parser = mav.MAVLink(None)
        msgs = parser.parse_buffer(p) or []
        assert len(msgs) == 1, f"datagram is not exactly one good packet: {p.hex()}"
        out.append(msgs[0])
    return out


def replay(packets, sample_rate, out_dir, timeout=90.0, transport="udp", extra=()):
    """Run the bridge, send ``packets`` to it over UDP (bridge listens: ``udpin:``) or
    TCP (the test listens, the bridge connects: ``tcp:``), collect what it forwards.
    ``extra``: further command-line options."""
    in_port, out_port = free_port(), None
    server = None
    if transport == "tcp":
        server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        server.settimeout(60)
        in_port = server.getsockname()[1]
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
    rx.bind(("127.0.0.1", 0))
    out_port = rx.getsockname()[1]
    rx.settimeout(0.5)
    cmd = gyrodenoise_cmd() + [
        "mavlink", f"{'tcp' if transport == 'tcp' else 'udpin'}:127.0.0.1:{in_port}", "--forward", f"udpout:127.0.0.1:{out_port}",
        "--count", str(len(packets)), "--duration", str(timeout), "--sample-rate", str(sample_rate),
        "--json", "-o", str(out_dir), "--no-plots", *extra]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    ready = threading.Event()
    err_lines = []

    def read_err():
        for line in proc.stderr:
            err_lines.append(line)
            if "listening on" in line:
                ready.set()
    th = threading.Thread(target=read_err, daemon=True)
    th.start()
    received = []
    try:
        if server is not None:
            tcp_conn, _ = server.accept()
        assert ready.wait(60), f"bridge did not start: {''.join(err_lines)}"
        if server is not None:
            def send(p):
                tcp_conn.sendall(p)
        else:
            tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

            def send(p):
                tx.sendto(p, ("127.0.0.1", in_port))
        deadline = time.monotonic() + timeout
        window = 200                  # packets in flight at most: no loss however loaded the machine
        rx.settimeout(0.0)
        for n_sent, p in enumerate(packets, start=1):
            send(p)
            while True:               # drain what already came back
                try:
                    received.append(rx.recv(65536))
                except (BlockingIOError, socket.timeout):
                    break
            if n_sent - len(received) >= window:
                rx.settimeout(1.0)
                while n_sent - len(received) > window // 2 and time.monotonic() < deadline:
                    try:
                        received.append(rx.recv(65536))
                    except socket.timeout:
                        if proc.poll() is not None:
                            break
                        # a lost datagram would stall us: the bridge then stops at --duration
                rx.settimeout(0.0)
        rx.settimeout(0.5)
        while len(received) < len(packets) and time.monotonic() < deadline:
            try:
                received.append(rx.recv(65536))
            except socket.timeout:
                if proc.poll() is not None:
                    break
        stdout, _ = proc.communicate(timeout=60)
    finally:
        if server is not None:
            server.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
        rx.close()
    th.join(timeout=5)
    assert proc.returncode == 0, "".join(err_lines)
    return received, json.loads(stdout), "".join(err_lines)


def check_forwarded(sent, received, rep, sample_rate, **denoise_kw):
    assert len(received) == len(sent), f"{len(received)} of {len(sent)} packets came back"
    assert rep["messages_in"] == rep["messages_forwarded"] == len(sent)
    assert rep["stopped_by"] == "count" and rep["unreadable_records"] == 0
    ms, mr = decode(sent), decode(received)
    streams = {}
    for a, b, pa, pb in zip(ms, mr, sent, received):
        assert a.get_type() == b.get_type()
        if a.get_type() not in GYRO:
            assert pa == pb                       # forwarded byte for byte
            continue
        da, db = a.to_dict(), b.to_dict()
        for g in ("xgyro", "ygyro", "zgyro"):
            da.pop(g), db.pop(g)
        assert da == db                           # only the gyro fields differ
        assert (b.get_seq(), b.get_srcSystem(), b.get_srcComponent()) == \
            (a.get_seq(), a.get_srcSystem(), a.get_srcComponent())
        t = a.time_usec * 1e-6 if hasattr(a, "time_usec") else a.time_boot_ms * 1e-3
        streams.setdefault(a.get_type(), []).append(
            (t, a.xgyro, a.ygyro, a.zgyro, b.xgyro, b.ygyro, b.zgyro))
    reported = {s["name"].split("@")[0]: s for s in rep["streams"]}
    n_filtered = 0
    for name, rows in streams.items():
        arr = np.array(rows, dtype=float)
        t, raw, got = arr[:, 0], arr[:, 1:4], arr[:, 4:7]
        r = ref_restarts(t)
        assert reported[name]["restarts"] == int(r.sum()), name
        k = R2D / 1000.0                           # mrad/s (ArduPilot, MAVLink 2 / version string)
        if reported[name]["too_slow_to_denoise"]:
            # telemetry below 20 Hz: forwarded raw, as in the file mode
            assert reported[name]["rate_hz"] < 20.0
            np.testing.assert_array_equal(got, raw, err_msg=name)
            continue
        ref = np.stack([gd.denoise(raw[:, j] * k, sample_rate, restarts=r, **denoise_kw) for j in range(3)],
                       axis=1) / k
        expected = np.clip(np.rint(ref), -32768, 32767)
        assert np.abs(got - expected).max() <= 1, name      # .5 ties only
        assert np.mean(got != expected) < 1e-3, name
        n_filtered += int(np.sum(got != raw))
    return streams, n_filtered


def test_live_replay_fs_batt_forwards_everything(tmp_path):
    """Local data: every packet comes back, non-gyro ones byte for byte, gyro ones
    re-packed with valid CRCs (27 samples: all inside the warm-up, so = raw)."""
    sent = tlog_packets(DATA / "fs-batt.log.tlog")
    received, rep, _ = replay(sent, 2.4, tmp_path)
    streams, n_changed = check_forwarded(sent, received, rep, 2.4)
    assert set(streams) == {"RAW_IMU", "SCALED_IMU2"}
    assert n_changed == 0                      # warm-up: the raw samples pass through
    assert rep["handling_us"]["p99"] < 20000
    # RAW_IMU's unit: the file mode's rule (ArduPilot HEARTBEAT + version string, MAVLink 1),
    # decided once the link has shown it, not "counts" because RAW_IMU came first
    from gyrodenoise.flightlog.process import process_log
    file_units = {s["name"]: s["field_unit"] for s in process_log(DATA / "fs-batt.log.tlog", tmp_path / "f",
                                                                  plots=False, csv=False)["streams"]}
    live_units = {s["name"].split("@")[0]: s["field_unit"] for s in rep["streams"]}
    assert live_units == file_units == {"RAW_IMU": "mrad/s", "SCALED_IMU2": "mrad/s"}
    # the CSV of the live run holds the same samples
    csv = np.genfromtxt(next(tmp_path.glob("live.RAW_IMU*.csv")), delimiter=",", names=True)
    assert len(csv) == 27


@pytest.mark.slow
def test_live_tcp_link(tmp_path):
    """The same over a TCP link (``tcp:`` connection string, the bridge connects).
    --causal is accepted on a live link (it is what a live link does anyway) and
    the report names the form."""
    sent = tlog_packets(DATA / "fs-batt.log.tlog")
    received, rep, _ = replay(sent, 2.4, tmp_path, transport="tcp", extra=("--causal",))
    check_forwarded(sent, received, rep, 2.4)
    assert rep["input"].startswith("tcp:")
    assert rep["form"] == "causal" and rep["method"] == "motion"


@pytest.mark.slow
@pytest.mark.slow
def test_live_replay_copter_reboot_forwards_slow_streams_raw_and_restarts(tmp_path):
    """Real ArduCopter 4.1 tlog with three boot sessions: the first 6000 messages carry
    about 250 RAW_IMU / SCALED_IMU2 samples at 2 Hz, past the warm-up and across the
    first reboot. Too slow to denoise: forwarded raw, bit for bit, as the file mode
    writes them; the
    restarts are found."""
    path = SHARED_LOGS / "copter_20211208-151717.tlog"
    if not path.exists():
        pytest.skip(f"third-party log not present: {path} (GPL-3: not copied into the repo)")
    sent = tlog_packets(path, limit=6000)
    received, rep, _ = replay(sent, 2.0, tmp_path)
    streams, n_changed = check_forwarded(sent, received, rep, 2.0)
    assert set(streams) == {"RAW_IMU", "SCALED_IMU2"}
    assert n_changed == 0 and all(s["too_slow_to_denoise"] for s in rep["streams"])
    for name in streams:
        ev = [e for e in rep["restarts"] if e["stream"].startswith(name + "@")]
        assert [e["reason"] for e in ev] == ["boot_time_backwards"]
        assert ev[0]["previous_time_s"] > 190 and ev[0]["time_s"] < 40


@pytest.mark.slow
def test_live_link_that_cannot_open_exits_2(tmp_path):
    port = free_port()                    # nothing listens there
    r = subprocess.run(gyrodenoise_cmd() + ["mavlink", f"tcp:127.0.0.1:{port}", "--json", "--duration", "5",
                                            "-o", str(tmp_path)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2                             # pymavlink's retry messages go to stderr
    assert r.stdout.count("\n") == 1                     # --json: exactly one object, the error in it
    err = json.loads(r.stdout)
    assert err["exit_status"] == 2 and err["error"].startswith(f"tcp:127.0.0.1:{port}: cannot open")
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith(f"gyrodenoise: error: tcp:127.0.0.1:{port}: cannot open the input link")
    assert "Traceback" not in r.stderr


def test_live_unit_rule_is_the_file_rule():
    """One function decides RAW_IMU's unit; on a live link it waits for the evidence."""
    from gyrodenoise.flightlog.tlog import decide_raw_imu_unit as d
    ap_v1 = {"autopilots": {3}, "ap_version": False}
    assert d(None, True, final=False) is None                      # no HEARTBEAT yet
    assert d(ap_v1, False, final=False) is None                     # ArduPilot, MAVLink 1, no version yet
    assert d(ap_v1, True, final=False)[0] == "mrad/s"
    assert d(dict(ap_v1, ap_version=True), False, final=False)[0] == "mrad/s"
    assert d({"autopilots": {12}, "ap_version": False}, True, final=False)[0] == "counts"   # PX4
    assert d(ap_v1, False, final=True)[0] == "counts" and d(None, True)[0] == "counts"


def test_live_safety_net_forwards_raw_from_the_bad_sample_on(monkeypatch):
    """A filter output outside the session's raw range (here: a monkeypatched
    Denoiser that returns 1e12 from its 50th call) is never forwarded: the stream
    is forwarded raw from that sample on and the report says why."""
    import gyrodenoise.denoiser as den
    from gyrodenoise.flightlog.live import _LiveStream

    class Garbage(den.Denoiser):
        calls = 0

        def step(self, z, restart=False):
            Garbage.calls += 1
            y = super().step(z, restart)
            return 1e12 if Garbage.calls > 150 else y

    monkeypatch.setattr(den, "Denoiser", Garbage)
    st = _LiveStream("SCALED_IMU2@1.1", "SCALED_IMU2", "mrad/s", R2D / 1000, "", 5.0, "<i2")
    rng = np.random.default_rng(3)
    raw = rng.integers(-50, 50, size=(100, 3))
    sent = [st.step(0.02 * i, list(map(int, r)), 50.0, "kf", 3, warmup_s=0.0) for i, r in enumerate(raw)]
    s = st.as_stream()
    assert s.left_raw and "outside the raw range" in s.left_raw and "sample 50" in s.left_raw
    got = np.array(sent, dtype=float)
    np.testing.assert_array_equal(got[50:], raw[50:])
    assert np.all(np.abs(got) <= 50)


def _scaled_imu2_packets(n=600, rate_hz=50.0, seed=21):
    """A 50 Hz SCALED_IMU2 stream (mrad/s, int16) of known content: a 0.5 Hz
    manoeuvre of 350 mrad/s plus white noise of 30 mrad/s, seeded; a 2 s gap
    (a restart) after 400 samples."""
    from pymavlink.dialects.v20 import ardupilotmega as mav
    rng = np.random.default_rng(seed)
    enc = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    t = np.arange(n) / rate_hz
    t[400:] += 2.0
    g = 350.0 * np.sin(2 * np.pi * 0.5 * t)[:, None] + rng.normal(0.0, 30.0, (n, 3))
    g = np.rint(g).astype(int)
    return [enc.scaled_imu2_encode(int(round(1000 * ti)), 0, 0, 1000, *map(int, gi), 0, 0, 0, 0).pack(enc)
            for ti, gi in zip(t, g)]


@pytest.mark.slow
def test_live_replay_of_a_fast_stream_is_the_batch_denoiser(tmp_path):
    """A stream fast enough to denoise (50 Hz) is filtered live, sample by sample, and
    what comes back equals the core's batch denoiser on the same samples and restarts."""
    sent = _scaled_imu2_packets()
    received, rep, _ = replay(sent, 50.0, tmp_path)
    streams, n_changed = check_forwarded(sent, received, rep, 50.0)
    assert set(streams) == {"SCALED_IMU2"} and rep["streams"][0]["restarts"] == 1
    assert not rep["streams"][0]["too_slow_to_denoise"] and n_changed > 500


@pytest.mark.slow
def test_live_replay_with_max_motion_hz_is_the_batch_denoiser_with_it(tmp_path):
    """--max-motion-hz on a live link: the 50 Hz stream filtered sample by
    sample with the rigid-body low-pass equals gd.denoise(..., max_motion_hz=10) on the same
    samples and restarts, and differs from the default (the option is really applied)."""
    sent = _scaled_imu2_packets()
    received, rep, _ = replay(sent, 50.0, tmp_path, extra=("--max-motion-hz", "10"))
    streams, n_changed = check_forwarded(sent, received, rep, 50.0, max_motion_hz=10.0)
    assert set(streams) == {"SCALED_IMU2"} and n_changed > 500
    default, _, _ = replay(sent, 50.0, tmp_path / "default")
    got, base = decode(received), decode(default)
    assert sum(a.xgyro != b.xgyro for a, b in zip(got, base) if a.get_type() == "SCALED_IMU2") > 100
