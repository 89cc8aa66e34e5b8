"""Signed MAVLink 2 links through the bridge: signed with pymavlink's own signing,
checked with pymavlink's own receiver (a key, a passphrase, a second key that must
fail), in the file mode and live over loopback UDP (127.0.0.1 only, bounded by
--count and --duration).

The logs are made here, seeded: a 50 Hz SCALED_IMU2 stream (a 0.5 Hz manoeuvre of
350 mrad/s plus white noise of 30 mrad/s) with a HEARTBEAT of an ArduPilot vehicle
every second and an ATTITUDE every tenth sample, every packet signed by pymavlink.
"""

from __future__ import annotations

import hashlib
import json
import os
import struct

import numpy as np
import pytest

from gyrodenoise.errors import InputError
from gyrodenoise.flightlog import signing
from gyrodenoise.flightlog.process import process_log
from tests.helpers import run_main

KEY = hashlib.sha256(b"gyrodenoise test link").digest()
OTHER_KEY = hashlib.sha256(b"someone else").digest()
PASSPHRASE = "correct horse battery staple"
LINK_ID = 3
TS0 = 300_000_000_000          # 10 us units since 2015-01-01: about 2024
T0_US = 1_700_000_000_000_000   # tlog record time
GYRO = "SCALED_IMU2"


def _mav():
    from pymavlink.dialects.v20 import ardupilotmega as mav
    return mav


def _encoder(key, link_id=LINK_ID, ts=TS0, src=(1, 1)):
    """A pymavlink MAVLink 2 encoder that signs with ``key`` (None: unsigned)."""
    enc = _mav().MAVLink(None, srcSystem=src[0], srcComponent=src[1])
    if key is not None:
        enc.signing.secret_key = key
        enc.signing.sign_outgoing = True
        enc.signing.link_id = link_id
        enc.signing.timestamp = ts
    return enc


def _packets(key, n=600, seed=11):
    """[(record time us, packet bytes)] of the test link, signed by pymavlink with ``key``."""
    rng = np.random.default_rng(seed)
    enc = _encoder(key)
    t = np.arange(n) / 50.0
    g = np.rint(350.0 * np.sin(2 * np.pi * 0.5 * t)[:, None] + rng.normal(0.0, 30.0, (n, 3))).astype(int)
    out = []
    for i, (ti, gi) in enumerate(zip(t, g)):
        tu = T0_US + int(ti * 1e6)
        if i % 50 == 0:
            out.append((tu, enc.heartbeat_encode(2, 3, 0, 0, 4).pack(enc)))
        if i % 10 == 5:
            out.append((tu, enc.attitude_encode(int(1000 * ti), 0.1, 0.2, 0.3, 0.0, 0.0, 0.0).pack(enc)))
        out.append((tu, enc.scaled_imu2_encode(int(round(1000 * ti)), 0, 0, 1000, *map(int, gi),
                                               0, 0, 0, 0).pack(enc)))
    return out


def _write_tlog(path, records):
    with open(path, "wb") as fh:
        for tu, p in records:
            fh.write(struct.pack(">Q", tu) + p)
    return path


def _key_file(path, text, mode=0o600):
    path.write_text(text)
    os.chmod(path, mode)
    return path


def _with_crc(pkt):
    """A MAVLink 2 packet (signature kept as it is) with its CRC recomputed: what an attacker
    who changed the payload does."""
    from pymavlink.dialects.v20.ardupilotmega import x25crc
    mav = _mav()
    body = bytearray(pkt[:10 + pkt[1]])
    msgid = pkt[7] | (pkt[8] << 8) | (pkt[9] << 16)
    crc = x25crc(bytes(body[1:]))
    crc.accumulate(bytes([mav.mavlink_map[msgid].crc_extra]))
    return bytes(body) + struct.pack("<H", crc.crc) + bytes(pkt[12 + pkt[1]:])


def _tampered(records):
    """The records with five bad packets: a gyro packet's payload byte flipped (CRC made
    good again), an earlier gyro packet replayed, a packet of system 7 signed with another
    key, an unsigned MAVLink 2 packet of system 9 and a MAVLink 1 packet of system 9.
    Returns (records, the bad packets, {(system, component): {reason: n}})."""
    recs = list(records)
    gyro = [i for i, (_, p) in enumerate(recs) if p[7] == 116]        # SCALED_IMU2
    i_flip = gyro[200]
    p = bytearray(recs[i_flip][1])
    p[10 + 4] ^= 0x01                                                 # xacc low byte
    recs[i_flip] = (recs[i_flip][0], _with_crc(bytes(p)))
    bad = [recs[i_flip][1]]
    replay = recs[gyro[150]][1]        # after the warm-up (motion: 128 samples), so its bytes go out changed
    rogue = _encoder(OTHER_KEY, link_id=LINK_ID, ts=TS0 + 50_000, src=(7, 1))
    wrong = rogue.scaled_imu2_encode(4000, 0, 0, 1000, 5, 5, 5, 0, 0, 0, 0).pack(rogue)
    plain = _encoder(None, src=(9, 1))
    unsigned = plain.heartbeat_encode(2, 3, 0, 0, 4).pack(plain)
    from pymavlink.dialects.v10 import ardupilotmega as mav1
    m1 = mav1.MAVLink(None, srcSystem=9, srcComponent=1)
    v1 = mav1.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3).pack(m1)
    t = recs[gyro[300]][0]
    for k, q in enumerate((replay, wrong, unsigned, v1)):
        recs.insert(gyro[300] + 1 + k, (t, q))
    bad += [replay, wrong, unsigned, v1]
    zero = dict.fromkeys(signing.REASONS, 0)
    why = {(1, 1): dict(zero, bad_signature=1, replayed_timestamp=1), (7, 1): dict(zero, bad_signature=1),
           (9, 1): dict(zero, unsigned=1, mavlink1=1)}
    return recs, bad, why


def _receiver(key):
    """pymavlink's receiver holding ``key``: unsigned packets refused (no callback), timestamps
    from the start of time accepted (the log is older than now)."""
    rx = _mav().MAVLink(None)
    rx.robust_parsing = True
    rx.signing.secret_key = key
    rx.signing.timestamp = 0
    return rx


def _verify(packets, key):
    """pymavlink's receiver over ``packets``: (messages accepted, refused); each accepted one signed."""
    rx = _receiver(key)
    good, bad = [], 0
    for p in packets:
        msgs = rx.parse_buffer(p) or []
        ok = [m for m in msgs if m.get_type() != "BAD_DATA"]
        bad += len(msgs) - len(ok) + (not msgs)
        for m in ok:
            assert m._signed, f"an unsigned packet came out: {p.hex()}"
        good += ok
    return good, bad


def _tlog_packets(path):
    """The packets of a tlog, framed here (8-byte time, then a MAVLink 1 or 2 packet)."""
    data = path.read_bytes()
    out, pos = [], 0
    while pos < len(data):
        a = pos + 8
        ln = (8 + data[a + 1]) if data[a] == 0xFE else (12 + data[a + 1] + (13 if data[a + 2] & 1 else 0))
        out.append(data[a:a + ln])
        pos = a + ln
    assert pos == len(data)
    return out


def _gyro(msgs):
    return np.array([(m.xgyro, m.ygyro, m.zgyro) for m in msgs if m.get_type() == GYRO], dtype=float)


# ------------------------------------------------------------------ the key file
def test_key_file_hex_passphrase_and_bad_files(tmp_path):
    assert signing.read_key(_key_file(tmp_path / "hex", KEY.hex() + "\n")) == KEY
    assert signing.read_key(_key_file(tmp_path / "HEX", "  " + KEY.hex().upper() + "\r\n")) == KEY
    # MAVProxy's `signing setup PASSPHRASE`: the key is SHA-256 of the passphrase
    assert signing.read_key(_key_file(tmp_path / "pass", PASSPHRASE + "\n")) == \
        hashlib.sha256(PASSPHRASE.encode()).digest()
    for name, text, what in (("empty", "\n \n", "empty"), ("two", "a\nb\n", "more than one line")):
        with pytest.raises(InputError, match=f"--signing-key .*{name}: {what}"):
            signing.read_key(_key_file(tmp_path / name, text))
    with pytest.raises(InputError, match="cannot read"):
        signing.read_key(tmp_path / "missing")
    lines = []
    signing.read_key(_key_file(tmp_path / "open", KEY.hex(), 0o644), warn=lines.append)
    assert len(lines) == 1 and "other users" in lines[0] and "0644" in lines[0]
    lines.clear()
    signing.read_key(tmp_path / "hex", warn=lines.append)
    assert lines == []


def test_signature_is_pymavlinks():
    """Re-signing here is accepted by pymavlink's receiver; pymavlink's signing passes the
    check here; a flipped byte, a replay and another key do not."""
    recs = _packets(KEY, n=20)
    link = signing.LinkSigning(KEY)
    assert all(link.check(p) is None for _, p in recs) and link.signed == len(recs)
    pkt = recs[-1][1]
    body = bytearray(pkt[:-13])
    body[2] &= 0xFE
    body[2] |= 1
    resigned = bytes(body) + signing.signature(KEY, body, LINK_ID, signing.signature_fields(pkt)[1] + 1)
    rx = _receiver(KEY)
    assert [m._signed for m in rx.parse_buffer(b"".join(p for _, p in recs[:-1]) + resigned)] == [True] * len(recs)
    assert link.check(recs[5][1]) == "replayed_timestamp"
    flipped = bytearray(pkt)
    flipped[12] ^= 1
    assert signing.LinkSigning(KEY).check(bytes(flipped)) == "bad_signature"
    assert signing.LinkSigning(OTHER_KEY).check(pkt) == "bad_signature"
    assert link.rejected == {(1, 1): dict(dict.fromkeys(signing.REASONS, 0), replayed_timestamp=1)}


# ------------------------------------------------------------------ file mode
@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("signed")
    return {"signed": _write_tlog(d / "signed.tlog", _packets(KEY)),
            "plain": _write_tlog(d / "plain.tlog", _packets(None)),
            "pass": _write_tlog(d / "pass.tlog", _packets(hashlib.sha256(PASSPHRASE.encode()).digest())),
            "dir": d}


def test_file_mode_with_the_key_verifies_end_to_end(logs, tmp_path):
    """Every packet of the filtered log is accepted by pymavlink's receiver holding the
    key, and signed; the gyro values are those of the unsigned log's filtering; other
    packets keep their bytes; link id and timestamp are the original's."""
    key_file = _key_file(tmp_path / "key", KEY.hex() + "\n")
    status, out, err = run_main("mavlink", logs["signed"], "-o", tmp_path / "out", "--no-plots", "--no-csv",
                                "--json", "--signing-key", key_file)
    assert status == 0, err
    rep = json.loads(out)["logs"][0]
    src, got = _tlog_packets(logs["signed"]), _tlog_packets(tmp_path / "out" / "signed.filtered.tlog")
    assert len(got) == len(src) == rep["signed_packets"] == 672
    good, refused = _verify(got, KEY)
    assert refused == 0 and len(good) == len(got)
    changed = [a != b for a, b in zip(src, got)]
    assert rep["resigned_packets"] == sum(changed) > 500
    assert rep["rejected_signatures"] == 0 and rep["signed_left_raw"] == 0 and rep["signatures_dropped"] == 0
    for a, b in zip(src, got):
        if a != b:
            assert a[7] == 116 and a[-13:-6] == b[-13:-6]      # a gyro packet; same link id and timestamp
    ref = process_log(logs["plain"], tmp_path / "plain", plots=False, csv=False)
    plain = _mav().MAVLink(None).parse_buffer(b"".join(_tlog_packets(tmp_path / "plain" / "plain.filtered.tlog")))
    np.testing.assert_array_equal(_gyro(good), _gyro(plain))
    assert ref["signed_packets"] == 0 and ref["resigned_packets"] == 0
    assert "signing: 672 signed packets in, " in run_main("mavlink", logs["signed"], "-o", tmp_path / "t",
                                                          "--no-plots", "--no-csv", "--signing-key", key_file)[1]


def test_file_mode_with_a_passphrase(logs, tmp_path):
    key_file = _key_file(tmp_path / "pass", PASSPHRASE + "\n")
    rep = process_log(logs["pass"], tmp_path, plots=False, csv=False, signing_key=signing.read_key(key_file))
    good, refused = _verify(_tlog_packets(tmp_path / "pass.filtered.tlog"), signing.read_key(key_file))
    assert refused == 0 and len(good) == 672 and rep["resigned_packets"] > 500


def test_file_mode_with_a_wrong_key_exits_2_and_writes_nothing(logs, tmp_path):
    key_file = _key_file(tmp_path / "other", OTHER_KEY.hex())
    status, out, err = run_main("mavlink", logs["signed"], "-o", tmp_path / "out", "--signing-key", key_file)
    assert status == 2 and out == ""
    assert err.strip().count("\n") == 0 and "none of its 672 signed packets verifies" in err
    assert not (tmp_path / "out").exists()
    status, _, err = run_main("mavlink", logs["signed"], "-o", tmp_path / "o2", "--signing-key", tmp_path / "none")
    assert status == 2 and "--signing-key" in err and "cannot read" in err and "Traceback" not in err


def test_file_mode_without_a_key_never_writes_a_signed_packet_unsigned(logs, tmp_path):
    status, out, err = run_main("mavlink", logs["signed"], "-o", tmp_path, "--no-plots", "--json")
    assert status == 0, err
    rep = json.loads(out)["logs"][0]
    # every packet signed: the filtered log is the log itself, byte for byte
    assert (tmp_path / "signed.filtered.tlog").read_bytes() == logs["signed"].read_bytes()
    assert rep["signed_packets"] == 672 and rep["resigned_packets"] == 0 and rep["signed_left_raw"] > 500
    assert "--signing-key FILE" in rep["signing_note"] and rep["streams"][0]["not_filtered"]
    csv = np.genfromtxt(tmp_path / f"signed.{GYRO}.csv", delimiter=",", names=True)
    np.testing.assert_array_equal(csv["raw_x"], csv["filtered_x"])        # the CSV says what the log holds
    text = run_main("mavlink", logs["signed"], "-o", tmp_path / "t", "--no-plots", "--no-csv")[1]
    line = [x for x in text.splitlines() if "signed packets left raw" in x]
    assert len(line) == 1 and "no --signing-key was given" in line[0] and "--signing-key FILE" in line[0]


def test_file_mode_drops_and_counts_tampered_packets(logs, tmp_path):
    """A flipped payload byte, a replay, another key, unsigned and MAVLink 1 packets on the
    signed link: neither filtered nor written, counted per source (pymavlink's receiver
    refuses the same five); the rest is the clean log's output."""
    recs, bad, why = _tampered(_packets(KEY))
    path = _write_tlog(tmp_path / "tampered.tlog", recs)
    _, refused = _verify([p for _, p in recs], KEY)
    assert refused == 5
    rep = process_log(path, tmp_path / "out", plots=False, csv=False, signing_key=KEY)
    assert rep["rejected_signatures"] == 5
    assert {(r["system"], r["component"]): {k: r[k] for k in signing.REASONS} for r in rep["rejected_by_source"]} \
        == why
    got = _tlog_packets(tmp_path / "out" / "tampered.filtered.tlog")
    good, refused = _verify(got, KEY)
    assert refused == 0 and len(got) == len(recs) - 5 and not set(bad) & set(got)
    clean = process_log(logs["signed"], tmp_path / "clean", plots=False, csv=False, signing_key=KEY)
    assert rep["streams"][0]["samples"] == clean["streams"][0]["samples"] - 1 == 599   # the flipped one is out
    assert rep["messages"] == len(recs)


# ------------------------------------------------------------------ live mode
def test_live_with_the_key_forwards_only_verified_signed_packets(tmp_path):
    """Over loopback UDP: every forwarded datagram is accepted by pymavlink's receiver
    holding the key (none unsigned), the five bad packets are dropped and counted, and the
    gyro values equal the unsigned link's through the same bridge."""
    from tests.flightlog.test_live import replay
    recs, bad, why = _tampered(_packets(KEY))
    sent = [p for _, p in recs]
    key_file = _key_file(tmp_path / "key", KEY.hex())
    received, rep, _ = replay(sent, 50.0, tmp_path / "a", extra=("--signing-key", str(key_file)))
    assert rep["messages_in"] == len(sent) and rep["messages_forwarded"] == len(received) == len(sent) - 5
    good, refused = _verify(received, KEY)
    assert refused == 0 and len(good) == len(received) and not set(bad) & set(received)
    assert rep["rejected_signatures"] == 5 and rep["resigned_packets"] > 450    # the gyro packets after the warm-up
    assert {(r["system"], r["component"]): {k: r[k] for k in signing.REASONS} for r in rep["rejected_by_source"]} \
        == why
    plain = [p for _, p in _packets(None)]
    flipped = [i for i, p in enumerate(_packets(KEY)) if p[1] != recs[i][1]][0]
    del plain[flipped]                                  # the flipped packet never reached the filter
    received_plain, _, _ = replay(plain, 50.0, tmp_path / "b")
    mav = _mav()
    np.testing.assert_array_equal(_gyro(good), _gyro(mav.MAVLink(None).parse_buffer(b"".join(received_plain))))


@pytest.mark.slow
def test_live_without_a_key_forwards_signed_packets_unchanged(tmp_path):
    sent = [p for _, p in _packets(KEY, n=300)]
    received, rep, _ = replay_link(sent, tmp_path)
    assert received == sent                              # byte for byte: gyro raw, signatures kept
    assert rep["signed_packets"] == len(sent) and rep["signed_left_raw"] > 150 and rep["resigned_packets"] == 0   # after the 128-sample warm-up
    assert "no --signing-key was given" in rep["signing_note"] and rep["streams"][0]["not_filtered"]


def replay_link(sent, tmp_path, *extra):
    from tests.flightlog.test_live import replay
    return replay(sent, 50.0, tmp_path, extra=extra)


# ------------------------------------------------------------------ a bogus signed packet
def test_a_bogus_signed_packet_does_not_make_the_link_signed():
    """A signed packet whose signature does not verify (another key: anyone can set the
    flag) is rejected, and the unsigned link goes on as it was: its packets still pass.
    A packet that verifies makes the link signed: unsigned ones are refused from then on."""
    link = signing.LinkSigning(KEY)
    plain = _encoder(None)
    unsigned = [plain.heartbeat_encode(2, 3, 0, 0, 4).pack(plain) for _ in range(3)]
    rogue = _encoder(OTHER_KEY, src=(7, 1))
    bogus = rogue.scaled_imu2_encode(4000, 0, 0, 1000, 5, 5, 5, 0, 0, 0, 0).pack(rogue)
    assert link.check(unsigned[0]) is None
    assert link.check(bogus) == "bad_signature"
    assert link.check(unsigned[1]) is None                # not switched to signed by the bogus one
    good = _encoder(KEY)
    assert link.check(good.heartbeat_encode(2, 3, 0, 0, 4).pack(good)) is None
    assert link.check(unsigned[2]) == "unsigned"          # switched by the verified one
    assert link.rejected == {(7, 1): dict(dict.fromkeys(signing.REASONS, 0), bad_signature=1),
                             (1, 1): dict(dict.fromkeys(signing.REASONS, 0), unsigned=1)}
