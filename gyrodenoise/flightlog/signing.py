"""MAVLink 2 packet signing: the link's key, checking a packet's signature, re-signing a changed packet.

A signed MAVLink 2 packet (incompat flag bit 0 set) ends in a 13-byte signature block:

* the link id (1 byte),
* a 48-bit little-endian timestamp in units of 10 us since 2015-01-01 00:00:00 UTC,
* the first 6 bytes of SHA-256(secret key + header + payload + CRC + link id + timestamp).

A receiver accepts a signed packet when the hash matches and its timestamp is newer
than the last one accepted from the same stream, a stream being the tuple (link id,
system, component); a stream it has not seen yet must not be more than one minute
behind the newest timestamp of the link (pymavlink, ArduPilot and PX4 apply the same
rules). The key is 32 bytes: 64 hex digits, or the SHA-256 of a passphrase (the way
MAVProxy and Mission Planner derive it from ``signing setup PASSPHRASE``).

:class:`LinkSigning` holds one link's state (a log file, or a live connection): it
checks every incoming packet (:meth:`LinkSigning.check`), counts what it rejects per
source, and re-signs the packets the bridge changes (:meth:`LinkSigning.resign`) with
the original link id and a timestamp that keeps those rules (the original's, or one
more than the last one the stream was given, whichever is greater).
"""

from __future__ import annotations

import hashlib
import os
import stat
import struct

from gyrodenoise.errors import InputError

MAGIC_V1, MAGIC_V2 = 0xFE, 0xFD
SIGNATURE_LEN = 13
IFLAG_SIGNED = 0x01
HEADER_LEN_V2 = 10
#: a stream first seen with a timestamp more than this behind the link's newest is refused
#: (10 us units: one minute, pymavlink's and ArduPilot's rule)
NEW_STREAM_SLACK = 6000 * 1000
#: the message a radio inserts unsigned into a signed link, which autopilots accept
#: unsigned (ArduPilot's and MAVProxy's rule): RADIO_STATUS
UNSIGNED_ALLOWED_IDS = frozenset({109})
#: the reasons a packet is rejected, as the report names them
REASONS = ("unsigned", "mavlink1", "bad_signature", "replayed_timestamp")
KEY_HINT = ("pass --signing-key FILE (FILE: the link's key as 64 hex digits, or its signing "
            "passphrase) to filter them and re-sign them")


def read_key(path, warn=None):
    """The 32-byte key in file ``path``: 64 hex digits, else a passphrase whose SHA-256 is
    the key (surrounding white space and the line end ignored). InputError (one line) when
    the file cannot be read, is empty or holds more than one line; ``warn(line)`` is called
    when other users may read it (as ssh warns about private keys)."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(1 << 16)
        mode = os.stat(path).st_mode
    except OSError as exc:
        raise InputError(f"--signing-key {path}: cannot read ({exc.strerror or exc})") from None
    try:
        text = raw.decode("utf-8").strip()
    except UnicodeDecodeError:
        raise InputError(f"--signing-key {path}: not text (expected 64 hex digits or a passphrase)") from None
    if not text:
        raise InputError(f"--signing-key {path}: empty (expected 64 hex digits or a passphrase)")
    if "\n" in text or "\r" in text:
        raise InputError(f"--signing-key {path}: more than one line (expected 64 hex digits or a passphrase "
                         f"on one line)")
    if warn is not None and mode & (stat.S_IRWXG | stat.S_IRWXO):
        warn(f"warning: --signing-key {path}: other users can access it (mode {stat.S_IMODE(mode):04o}); "
             f"chmod 600 {path}")
    return key_from_text(text)


def key_from_text(text):
    """The key from the text of a key file (see :func:`read_key`)."""
    if len(text) == 64 and all(c in "0123456789abcdefABCDEF" for c in text):
        return bytes.fromhex(text)
    return hashlib.sha256(text.encode("utf-8")).digest()


def is_signed(pkt):
    """True for a MAVLink 2 packet with its signed flag set."""
    return len(pkt) > 2 and pkt[0] == MAGIC_V2 and bool(pkt[2] & IFLAG_SIGNED)


def signature_fields(pkt):
    """(link id, timestamp) of a signed packet."""
    sig = pkt[-SIGNATURE_LEN:]
    return sig[0], int.from_bytes(sig[1:7], "little")


def signature(key, body, link_id, timestamp):
    """The 13-byte signature block of ``body`` (header + payload + CRC, signed flag set)."""
    tail = struct.pack("<BQ", link_id, timestamp)[:7]
    return tail + hashlib.sha256(key + bytes(body) + tail).digest()[:6]


def signature_ok(key, pkt):
    """True if the signature of the signed packet ``pkt`` matches ``key`` (hash only, no timestamp rule)."""
    return hashlib.sha256(key + bytes(pkt[:-6])).digest()[:6] == bytes(pkt[-6:])


def source_of(pkt):
    """(system, component) of a MAVLink 1 or 2 packet."""
    return (pkt[5], pkt[6]) if pkt[0] == MAGIC_V2 else (pkt[3], pkt[4])


def message_id(pkt):
    return pkt[7] | (pkt[8] << 8) | (pkt[9] << 16) if pkt[0] == MAGIC_V2 else pkt[5]


class LinkSigning:
    """The signing state of one link (a log, or a live connection) under ``key``
    (None: no key, only counting). Count fields: ``signed`` (signed packets in),
    ``resigned``, ``left_raw`` (signed packets the bridge would have changed, sent
    unchanged for want of a key), ``rejected`` ({(system, component): {reason: n}})."""

    def __init__(self, key=None):
        self.key = key
        self.streams = {}           # (link id, system, component) -> last accepted timestamp
        self.emitted = {}           # (link id, system, component) -> last timestamp sent out
        self.newest = 0             # newest accepted timestamp of the link
        self.seen_signed = False    # a packet signed with the key has come: the link is signed
        self.signed = self.resigned = self.left_raw = 0
        self.rejected = {}

    def check(self, pkt):
        """None if packet ``pkt`` (bytes, CRC already good) may pass, else the reason it
        is rejected (counted). Without a key every packet passes (signed ones are counted)."""
        signed = is_signed(pkt)
        self.signed += signed
        if self.key is None:
            return None
        if not signed:
            if not self.seen_signed or message_id(pkt) in UNSIGNED_ALLOWED_IDS:
                return None
            return self._reject(pkt, "unsigned" if pkt[0] == MAGIC_V2 else "mavlink1")
        if len(pkt) < HEADER_LEN_V2 + 2 + SIGNATURE_LEN or not signature_ok(self.key, pkt):
            return self._reject(pkt, "bad_signature")     # anyone can set the flag: the link stays as it was
        self.seen_signed = True
        link_id, ts = signature_fields(pkt)
        stream = (link_id, *source_of(pkt))
        last = self.streams.get(stream)
        if (ts <= last) if last is not None else (ts + NEW_STREAM_SLACK < self.newest):
            return self._reject(pkt, "replayed_timestamp")
        self.streams[stream] = ts
        self.newest = max(self.newest, ts)
        return None

    def _reject(self, pkt, reason):
        counts = self.rejected.setdefault(source_of(pkt), dict.fromkeys(REASONS, 0))
        counts[reason] += 1
        return reason

    def passed(self, pkt):
        """Note a signed packet sent out unchanged (its stream's last timestamp out)."""
        if is_signed(pkt):
            link_id, ts = signature_fields(pkt)
            stream = (link_id, *source_of(pkt))
            self.emitted[stream] = max(ts, self.emitted.get(stream, -1))

    def resign(self, original, body):
        """``body`` (an unsigned re-packed MAVLink 2 packet: header + payload + CRC, from
        the signed packet ``original``) signed with the key, the original's link id and
        the original's timestamp, or one more than the last one its stream was sent with."""
        link_id, ts = signature_fields(original)
        stream = (link_id, *source_of(original))
        ts = max(ts, self.emitted.get(stream, -1) + 1)
        self.emitted[stream] = ts
        self.resigned += 1
        return bytes(body) + signature(self.key, body, link_id, ts)

    @property
    def n_rejected(self):
        return sum(sum(c.values()) for c in self.rejected.values())

    def report(self):
        """The report's fields (the key never in them)."""
        rep = {"signing_key": self.key is not None, "signed_packets": self.signed,
               "resigned_packets": self.resigned, "signed_left_raw": self.left_raw,
               "rejected_signatures": self.n_rejected,
               "rejected_by_source": [{"system": s, "component": c, "packets": sum(n.values()), **n}
                                      for (s, c), n in sorted(self.rejected.items())],
               "signatures_dropped": 0}
        if self.left_raw:
            rep["signing_note"] = left_raw_note(self.left_raw)
        return rep


def left_raw_note(n):
    """The summary's line on signed packets left raw for want of a key."""
    return (f"{n} signed packet{'' if n == 1 else 's'} left raw (gyro unfiltered, signature kept): "
            f"no --signing-key was given, and a signed packet is never sent unsigned; {KEY_HINT}")
