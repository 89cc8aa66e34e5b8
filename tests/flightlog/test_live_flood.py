"""The live bridge under a flood of garbage over loopback UDP (127.0.0.1 only), with
legitimate packets interleaved: its memory and the legitimate packets' latency stay
bounded, they are forwarded, the garbage is dropped and counted, and nothing is
amplified (datagrams out <= datagrams in). Bounded: a few seconds, a fixed count.

``python -m tests.flightlog.test_live_flood SECONDS RATE [framed] [same]`` prints the figures of a
longer flood (the bridge run is the ``gyrodenoise`` of the environment: set PYTHONPATH
to measure another copy of the code)."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from tests.helpers import gyrodenoise_cmd

GARBAGE_BYTES = 65000
LEGIT_HZ = 50.0


def _free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _rss_mb(pid):
    """Resident memory of process ``pid``, MB (Linux /proc); None once it has ended."""
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return None


def _legit(n, seed=5):
    """n SCALED_IMU2 packets (MAVLink 2) at :data:`LEGIT_HZ`; packet i has time_boot_ms = 20 i."""
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink.dialects.v20 import ardupilotmega as mav
    enc = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    g = np.random.default_rng(seed).integers(-300, 300, (n, 3))
    return [enc.scaled_imu2_encode(int(round(1000 * i / LEGIT_HZ)), 0, 0, 1000, *map(int, g[i]), 0, 0, 0, 0).pack(enc)
            for i in range(n)]


def _framed_garbage(rng, n_bytes):
    """Random SCALED_IMU2 packets (MAVLink 2 framing, a known id, random CRCs: bad) end to
    end, ``n_bytes`` at most: garbage that frames, so that each packet must be checked."""
    one = 12 + 22
    pk = rng.integers(0, 256, (n_bytes // one, one), dtype=np.uint8)
    pk[:, :10] = [0xFD, 22, 0, 0, 0, 1, 1, 116, 0, 0]
    return pk.tobytes()


def flood(out_dir, seconds=3.0, rate_hz=1000.0, lead_s=1.0, tail_s=1.0, env=None, seed=9, count=None, extra_s=15.0,
          framed=False, same_sender=False):
    """Run the bridge (``udpin:`` -> ``udpout:``) and send legitimate packets at 50 Hz for
    ``lead_s`` + ``seconds`` + ``tail_s``, with :data:`GARBAGE_BYTES`-byte random datagrams
    at ``rate_hz`` during ``seconds`` (``framed``: :func:`_framed_garbage`), from a socket of
    their own (``same_sender``: the legitimate packets'); return the figures (dict). The bridge stops after
    ``count`` messages (default: the legitimate ones) or ``extra_s`` after the last is sent."""
    in_port = _free_port()
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(0.2)
    total_s = lead_s + seconds + tail_s
    legit = _legit(int(total_s * LEGIT_HZ))
    cmd = gyrodenoise_cmd() + ["mavlink", f"udpin:127.0.0.1:{in_port}", "--forward",
                               f"udpout:127.0.0.1:{rx.getsockname()[1]}", "--count", str(count or len(legit)),
                               "--duration", str(total_s + extra_s), "--sample-rate", str(LEGIT_HZ),
                               "--json", "-o", str(out_dir), "--no-plots", "--no-csv"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    ready = threading.Event()
    err = []

    def read_err():
        for line in proc.stderr:
            err.append(line)
            if "listening on" in line:
                ready.set()
    threading.Thread(target=read_err, daemon=True).start()
    got = []                                        # (receive time, datagram)
    stop = threading.Event()

    def receive():
        while not stop.is_set():
            try:
                d = rx.recv(1 << 16)
                got.append((time.monotonic(), d))
            except socket.timeout:
                pass
    rth = threading.Thread(target=receive, daemon=True)
    rth.start()
    rng = np.random.default_rng(seed)
    garbage = [_framed_garbage(rng, GARBAGE_BYTES) if framed else
               rng.integers(0, 256, GARBAGE_BYTES, dtype=np.uint8).tobytes() for _ in range(16)]
    sent_at = {}
    rss = []
    n_garbage = 0
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gx = tx if same_sender else socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        assert ready.wait(60), "".join(err)
        t0 = time.monotonic()
        i_legit = 0
        rss_base = None
        next_rss = t0
        while i_legit < len(legit):
            now = time.monotonic()
            el = now - t0
            if i_legit <= el * LEGIT_HZ:
                tx.sendto(legit[i_legit], ("127.0.0.1", in_port))
                sent_at[i_legit] = time.monotonic()
                i_legit += 1
            elif lead_s <= el < lead_s + seconds and n_garbage < (el - lead_s) * rate_hz:
                gx.sendto(garbage[n_garbage % len(garbage)], ("127.0.0.1", in_port))
                n_garbage += 1
            else:
                time.sleep(0.0005)
            if now >= next_rss:
                r = _rss_mb(proc.pid)
                if el < lead_s:
                    rss_base = r                     # after start-up and the first packets
                elif r is not None:
                    rss.append(r)
                next_rss = now + 0.1
        stdout, _ = proc.communicate(timeout=total_s + 30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        time.sleep(0.3)
        stop.set()
        rth.join(5)
        rx.close()
        tx.close()
        gx.close()
    from pymavlink.dialects.v20 import ardupilotmega as mav
    lat = []
    for t, d in got:
        parser = mav.MAVLink(None)
        parser.robust_parsing = True                # what comes out may be garbage too
        for m in parser.parse_buffer(d) or []:
            if m.get_type() == "SCALED_IMU2":
                lat.append(t - sent_at[int(round(m.time_boot_ms * LEGIT_HZ / 1000))])
    rep = json.loads(stdout) if proc.returncode in (0, 1) else {"error": "".join(err)}
    return {"seconds": seconds, "rate_hz": rate_hz, "legit_sent": len(legit), "legit_forwarded": len(lat),
            "garbage_sent": n_garbage, "datagrams_sent": len(legit) + n_garbage, "datagrams_out": len(got),
            "rss_before_mb": rss_base, "rss_max_mb": max(rss) if rss else None,
            "latency_median_s": float(np.median(lat)) if lat else None,
            "latency_max_s": float(np.max(lat)) if lat else None, "report": rep}


@pytest.mark.slow                       # 5 s of traffic (little CPU)
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the bridge's memory in /proc")
def test_a_garbage_flood_is_dropped_and_counted_with_bounded_memory_and_latency(tmp_path):
    """3 s of 65 kB random datagrams at 1000/s (195 MB) with 50 Hz gyro packets before,
    during and after: before the bound the bridge's memory grew with the backlog (56 MB
    to 1.95 GB in 45 s), latency with it (median 52 s), and each garbage datagram came
    out as about 500 datagrams."""
    f = flood(tmp_path)
    rep = f["report"]
    print({k: v for k, v in f.items() if k != "report"})
    assert rep.get("stopped_by") == "count", f          # every legitimate packet came in
    assert f["datagrams_out"] <= f["datagrams_sent"], f
    assert f["legit_forwarded"] == f["legit_sent"] == rep["messages_forwarded"] == rep["messages_in"], f
    assert f["rss_max_mb"] - f["rss_before_mb"] < 40.0, f
    assert f["latency_median_s"] < 0.25 and f["latency_max_s"] < 2.0, f
    # each garbage datagram counted once: dropped unparsed by the bridge, or by the kernel
    # (receive buffer full), never forwarded
    assert rep["garbage_datagrams"] == rep["unreadable_records"] > 0
    assert rep["datagrams_in"] == rep["garbage_datagrams"] + f["legit_sent"]
    dropped = rep["kernel_dropped_datagrams"]
    assert rep["garbage_datagrams"] + dropped == f["garbage_sent"], (rep, f)
    assert rep["datagrams_out"] == f["datagrams_out"] == f["legit_sent"]


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the bridge's memory in /proc")
def test_a_flood_of_bad_packets_from_another_sender_does_not_crowd_out_the_link(tmp_path):
    """Garbage that frames as MAVLink packets (a known id, bad CRCs: each must be checked,
    ~1900 a datagram) at 1000 datagrams/s from another sender, more than the bridge can check:
    its queue stays bounded (the flood's oldest datagrams dropped and counted) and the link's
    own packets are all forwarded, in turn, with bounded latency."""
    f = flood(tmp_path, framed=True)
    rep = f["report"]
    print({k: v for k, v in f.items() if k != "report"})
    assert rep.get("stopped_by") == "count", f
    assert f["legit_forwarded"] == f["legit_sent"] == rep["messages_forwarded"], f
    assert f["datagrams_out"] == rep["datagrams_out"] == f["legit_sent"], f
    assert f["rss_max_mb"] - f["rss_before_mb"] < 40.0, f
    assert f["latency_median_s"] < 0.25 and f["latency_max_s"] < 2.0, f
    assert rep["garbage_datagrams"] == 0 and rep["unreadable_records"] > 0
    # every flood datagram: checked packet by packet, dropped from the full queue, or dropped by the kernel
    assert rep["datagrams_in"] + rep["kernel_dropped_datagrams"] == f["datagrams_sent"], (rep, f)


if __name__ == "__main__":
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        res = flood(Path(d), seconds=float(sys.argv[1]), rate_hz=float(sys.argv[2]), count=10 ** 9, extra_s=2.0,
                    framed="framed" in sys.argv[3:], same_sender="same" in sys.argv[3:])
    rep = res.pop("report")
    res["report"] = {k: rep.get(k) for k in ("stopped_by", "messages_in", "messages_forwarded", "unreadable_records",
                                             "datagrams_in", "datagrams_out", "garbage_datagrams",
                                             "overload_dropped_datagrams", "kernel_dropped_datagrams", "error")}
    print(json.dumps(res, indent=1))


# ------------------------------------------------------------ the pieces
def test_crc_check_of_many_packets_is_pymavlinks():
    """A datagram of 40 real packets (MAVLink 1 and 2 of fs-batt.log.tlog, and signed ones),
    five corrupted: the vectorised check and pymavlink's decode agree on each."""
    from pymavlink.dialects.v20 import ardupilotmega as mav

    from gyrodenoise.flightlog.live import crc_ok, mavlink_frames
    from tests.flightlog.test_live import tlog_packets
    from tests.helpers import DATA
    pk = tlog_packets(DATA / "fs-batt.log.tlog", limit=30)
    enc = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    enc.signing.secret_key, enc.signing.sign_outgoing, enc.signing.timestamp = b"k" * 32, True, 1
    pk += [enc.scaled_imu2_encode(i, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10).pack(enc) for i in range(10)]
    rng = np.random.default_rng(3)
    for i in rng.choice(len(pk), 5, replace=False):
        b = bytearray(pk[i])
        b[-3 if b[0] == 0xFE else 12] ^= 0x10            # a payload or CRC byte
        pk[i] = bytes(b)
    data = b"".join(pk)
    offsets = mavlink_frames(data)
    assert offsets == list(np.cumsum([0] + [len(p) for p in pk[:-1]]))
    want = []
    for p in pk:
        try:
            mav.MAVLink(None).decode(bytearray(p))
            want.append(True)
        except Exception:  # noqa: BLE001
            want.append(False)
    assert sum(want) == len(pk) - 5
    assert list(crc_ok(data, offsets)) == want
    assert mavlink_frames(data[1:]) is None and mavlink_frames(data[:-1]) is None


def test_fair_queue_serves_senders_in_turn_and_drops_from_the_largest():
    from gyrodenoise.flightlog.live import FairQueue
    q = FairQueue(100)
    assert q.put("flood", "f1", 40) == 0 and q.put("flood", "f2", 40) == 0
    assert q.put("link", "l1", 10) == 0
    assert q.put("flood", "f3", 40) == 1                 # 130 > 100: the flood's oldest goes
    assert q.get() == "f2" and q.get() == "l1" and q.get() == "f3" and q.get() is None
    assert q.bytes == 0 and len(q) == 0


@pytest.mark.slow
def test_garbage_on_a_tcp_link_is_dropped_and_counted(tmp_path):
    """A byte-stream link (TCP): garbage bytes before each packet are counted as unreadable and
    never forwarded (they were forwarded, a datagram each); the packets come out as they went in."""
    from tests.flightlog.test_live import replay, tlog_packets
    from tests.helpers import DATA
    sent = tlog_packets(DATA / "fs-batt.log.tlog", limit=60)
    rng = np.random.default_rng(4)
    noise = [bytes(rng.integers(0, 0xFD, 50, dtype=np.uint8)) for _ in sent]    # no magic byte in it
    received, rep, _ = replay([g + p for g, p in zip(noise, sent)], 2.4, tmp_path, transport="tcp")
    assert received == sent
    assert rep["messages_in"] == rep["messages_forwarded"] == len(sent)
    assert rep["unreadable_records"] >= 1 and rep["unreadable_bytes"] == 50 * len(sent)
