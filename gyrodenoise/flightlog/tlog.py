"""MAVLink telemetry logs (``.tlog``): frame, check, decode the IMU gyro fields, re-pack.

A tlog is a sequence of records ``<8-byte big-endian UNIX time, us><MAVLink
packet>``. :func:`frame` walks the records (MAVLink 1 ``FE`` and MAVLink 2
``FD`` packets, signed or not); where the byte after a timestamp is not a
packet start it searches forward for the next record whose CRC checks and
counts the skipped bytes as one unreadable record. Every packet's CRC is then
checked in bulk (numpy) against the CRC_EXTRA of pymavlink's ``ardupilotmega``
dialect (a superset of ``common``): a packet that fails, or whose message id
the dialect does not know, is an unreadable record (pymavlink reports the same
records as ``BAD_DATA``). Unreadable bytes are copied to the output unchanged.

Gyro messages (all int16 mrad/s except HIGHRES_IMU, float rad/s):

* ``RAW_IMU`` -- the MAVLink spec says raw sensor counts. ArduPilot fills it
  with mrad/s (its IMU 1). The unit is taken as mrad/s only when the log shows
  that the sender is ArduPilot (HEARTBEAT autopilot 3) *and* either the packet
  is MAVLink 2 or an ArduPilot version string was sent; otherwise the unit is
  ``counts`` with an unknown scale (old APM 2.x firmware), the stream is
  filtered in counts and the report says so (``--raw-imu-unit`` /
  ``--raw-imu-scale`` override).
* ``SCALED_IMU``, ``SCALED_IMU2``, ``SCALED_IMU3`` -- mrad/s.
* ``HIGHRES_IMU`` -- rad/s.

Re-packing keeps the header (sequence, system, component, message id) and
changes the gyro bytes of the payload and the CRC. MAVLink 2 payloads are
re-trimmed of trailing zeros but never below their original length. A signed
MAVLink 2 packet is never written unsigned (:mod:`gyrodenoise.flightlog.signing`):
with the link's key it is re-signed (the original link id, a timestamp that keeps
the signing rules); without it, it is written unchanged, its gyro fields raw, and
counted (``signed_left_raw``). With a key, every packet is checked on the way in
(:func:`check_signatures`): one that fails is left out of the streams and of the
filtered log, and counted per source.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field

import numpy as np

from gyrodenoise.errors import InputError

from gyrodenoise.flightlog.signing import IFLAG_SIGNED, MAGIC_V1, MAGIC_V2, SIGNATURE_LEN, LinkSigning, is_signed
from gyrodenoise.flightlog.streams import UNIT_TO_DEG_S, GyroStream, require_fit


GYRO_MESSAGES = {
    # name: (time field, time scale to s, gyro unit ('raw' = decided per log))
    "RAW_IMU": ("time_usec", 1e-6, "raw"),
    "SCALED_IMU": ("time_boot_ms", 1e-3, "mrad/s"),
    "SCALED_IMU2": ("time_boot_ms", 1e-3, "mrad/s"),
    "SCALED_IMU3": ("time_boot_ms", 1e-3, "mrad/s"),
    "HIGHRES_IMU": ("time_usec", 1e-6, "rad/s"),
}
GYRO_FIELDS = ("xgyro", "ygyro", "zgyro")
AUTOPILOT_ARDUPILOT = 3
_AP_VERSION_RE = re.compile(r"(ArduCopter|ArduPlane|ArduRover|ArduSub|APM:\w+|Rover|Blimp|AntennaTracker)"
                            r"\s+V?\d+\.\d+", re.IGNORECASE)

_STRUCT_CHARS = {"Q": "<u8", "q": "<i8", "I": "<u4", "i": "<i4", "H": "<u2", "h": "<i2",
                 "B": "u1", "b": "i1", "f": "<f4", "d": "<f8", "c": "S1", "s": "S1"}


def _dialect():
    from pymavlink.dialects.v20 import ardupilotmega as mav
    return mav


@dataclass
class MsgLayout:
    """Wire layout of one MAVLink message type (from pymavlink's dialect)."""
    id: int
    name: str
    crc_extra: int
    size: int                  # full payload length (with extensions)
    base_size: int             # MAVLink 1 payload length (without extensions)
    offsets: dict              # field name -> (offset, numpy dtype)

    @classmethod
    def from_class(cls, c):
        fmt = c.unpacker.format
        tokens = re.findall(r"(\d*)([a-zA-Z?])", fmt.lstrip("<"))
        offs = {}
        off = 0
        for name, (cnt, ch), alen in zip(c.ordered_fieldnames, tokens, c.array_lengths):
            k = int(cnt) if cnt else 1
            dt = np.dtype(_STRUCT_CHARS[ch])
            offs[name] = (off, dt if k == 1 or ch == "s" else np.dtype((dt, (k,))))
            off += struct.calcsize("<" + (cnt + ch))
        ext = getattr(c, "extensions_start", None)
        base = off
        if ext is not None and ext < len(c.ordered_fieldnames):
            base = offs[c.ordered_fieldnames[ext]][0] if ext else 0
        return cls(c.id, c.msgname, c.crc_extra, off, base, offs)


_LAYOUTS = {}


def layout(name):
    if name not in _LAYOUTS:
        mav = _dialect()
        _LAYOUTS[name] = MsgLayout.from_class(mav.mavlink_map[getattr(mav, "MAVLINK_MSG_ID_" + name)])
    return _LAYOUTS[name]


# ----------------------------------------------------------------- CRC (X.25)
def x25_crc(buf, crc=0xFFFF):
    """MAVLink's CRC-16/MCRF4XX of ``buf`` (plain Python; for single packets)."""
    for b in buf:
        tmp = b ^ (crc & 0xFF)
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
    return crc


def _x25_columns(mat, crc):
    """CRC over the columns of a (n, L) uint8 matrix, vectorised over rows."""
    for j in range(mat.shape[1]):
        tmp = mat[:, j].astype(np.uint32) ^ (crc & 0xFF)
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
    return crc


def packet_ok(pkt):
    """True if ``pkt`` (bytes of one MAVLink packet) has a known id and a good CRC."""
    if len(pkt) < 8:
        return False
    mav = _dialect()
    if pkt[0] == MAGIC_V1:
        hl, msgid = 6, pkt[5]
    elif pkt[0] == MAGIC_V2:
        if len(pkt) < 12:
            return False
        hl, msgid = 10, pkt[7] | (pkt[8] << 8) | (pkt[9] << 16)
    else:
        return False
    plen = pkt[1]
    if len(pkt) < hl + plen + 2 or msgid not in mav.mavlink_map:
        return False
    crc = x25_crc(pkt[1:hl + plen])
    crc = x25_crc(bytes([mav.mavlink_map[msgid].crc_extra]), crc)
    return crc == (pkt[hl + plen] | (pkt[hl + plen + 1] << 8))


def packet_len(data, p, n):
    """Length of the packet starting at ``p`` (None if no magic, -1 if cut by the end)."""
    m = data[p]
    if m == MAGIC_V1:
        if p + 2 > n:
            return -1
        return 6 + data[p + 1] + 2
    if m == MAGIC_V2:
        if p + 3 > n:
            return -1
        ln = 10 + data[p + 1] + 2
        if data[p + 2] & 1:
            ln += SIGNATURE_LEN
        return ln
    return None


# ------------------------------------------------------------------ framing
@dataclass
class TlogFrames:
    path: str
    size: int
    start: np.ndarray          # record start (timestamp) offsets of framed packets
    length: np.ndarray         # record length (8 + packet)
    ok: np.ndarray             # CRC good and message id known
    msgid: np.ndarray
    v2: np.ndarray
    bad_regions: list = field(default_factory=list)   # (start, end) unframed bytes
    truncated_bytes: int = 0
    zero_tail: bool = False    # the truncated tail is zero bytes (log cut at a block boundary)
    signed: np.ndarray = None  # MAVLink 2 with the signed flag
    rejected: np.ndarray = None   # failed the signature check under the link's key (check_signatures)

    def __post_init__(self):
        if self.signed is None:
            self.signed = np.zeros(len(self.start), dtype=bool)
        if self.rejected is None:
            self.rejected = np.zeros(len(self.start), dtype=bool)

    @property
    def usable(self):
        """Readable and not rejected by the signature check."""
        return self.ok & ~self.rejected

    @property
    def n_unreadable(self):
        return int((~self.ok).sum()) + len(self.bad_regions)


def _resync(data, pos, n):
    """First record start > pos whose packet has a good CRC, or n."""
    q = pos + 1
    while q + 8 < n:
        # next byte that could be a magic, at q+8
        i1 = data.find(b"\xfe", q + 8)
        i2 = data.find(b"\xfd", q + 8)
        cands = [i for i in (i1, i2) if i >= 0]
        if not cands:
            return n
        m = min(cands)
        q = m - 8
        ln = packet_len(data, m, n)
        if ln is not None and ln > 0 and m + ln <= n and packet_ok(data[m:m + ln]):
            return q
        q += 1
    return n


def frame(data, path="<bytes>"):
    """Walk the records of a tlog held in ``data``; return :class:`TlogFrames`."""
    n = len(data)
    starts, lens = [], []
    bad = []
    pos = 0
    truncated = 0
    while pos + 9 <= n:
        ln = packet_len(data, pos + 8, n)
        if ln is None:
            nxt = _resync(data, pos, n)
            bad.append((pos, nxt))
            pos = nxt
            continue
        if ln < 0 or pos + 8 + ln > n:
            truncated = n - pos
            break
        starts.append(pos)
        lens.append(8 + ln)
        pos += 8 + ln
    else:
        if pos < n:
            truncated = n - pos
    zero_tail = False
    if bad and bad[-1][1] >= n and not any(data[bad[-1][0]:n]):
        # a log cut at a block boundary and zero-filled: truncated, not unreadable
        a = bad.pop()[0]
        truncated = n - a
        zero_tail = True
    start = np.asarray(starts, dtype=np.int64)
    length = np.asarray(lens, dtype=np.int64)
    buf = np.frombuffer(data, dtype=np.uint8)
    v2 = buf[start + 8] == MAGIC_V2 if len(start) else np.zeros(0, bool)
    msgid = np.where(v2, buf[np.minimum(start + 15, n - 1)].astype(np.int64)
                     | (buf[np.minimum(start + 16, n - 1)].astype(np.int64) << 8)
                     | (buf[np.minimum(start + 17, n - 1)].astype(np.int64) << 16),
                     buf[np.minimum(start + 13, n - 1)].astype(np.int64)) if len(start) else np.zeros(0, np.int64)
    ok = check_crcs(buf, start, length, v2, msgid)
    signed = v2 & ((buf[np.minimum(start + 10, n - 1)] & IFLAG_SIGNED) != 0) if len(start) else np.zeros(0, bool)
    return TlogFrames(path, n, start, length, ok, msgid, v2, bad, truncated, zero_tail, signed)


def check_signatures(data, fr: TlogFrames, link: LinkSigning):
    """Every readable packet of the log through ``link``'s check, in the log's order
    (the signing rules are stateful): sets ``fr.rejected``. Without a key it only
    counts the signed packets."""
    if link.key is None:
        link.signed += int((fr.signed & fr.ok).sum())
        return
    rejected = np.zeros(len(fr.start), dtype=bool)
    for i in np.nonzero(fr.ok)[0].tolist():
        a = int(fr.start[i]) + 8
        rejected[i] = link.check(data[a:a + int(fr.length[i]) - 8]) is not None
    fr.rejected = rejected


def check_crcs(buf, start, length, v2, msgid):
    mav = _dialect()
    n = len(start)
    ok = np.zeros(n, dtype=bool)
    if n == 0:
        return ok
    hl = np.where(v2, 10, 6)
    plen = buf[start + 9].astype(np.int64)
    span = hl - 1 + plen                          # bytes covered, after the magic
    extra = np.full(n, -1, dtype=np.int64)
    for mid in np.unique(msgid):
        c = mav.mavlink_map.get(int(mid))
        if c is not None:
            extra[msgid == mid] = c.crc_extra
    known = extra >= 0
    for L in np.unique(span[known]):
        sel = np.nonzero(known & (span == L))[0]
        first = start[sel] + 9
        mat = buf[first[:, None] + np.arange(L)]
        crc = _x25_columns(mat, np.full(len(sel), 0xFFFF, dtype=np.uint32))
        crc = _x25_columns(extra[sel].astype(np.uint8)[:, None], crc)
        crc_pos = first + L
        stored = buf[crc_pos].astype(np.uint32) | (buf[crc_pos + 1].astype(np.uint32) << 8)
        ok[sel] = crc == stored
    return ok


# ----------------------------------------------------------------- decoding
def _payloads(buf, fr: TlogFrames, sel, size):
    """(k, size) zero-padded payloads of the records ``sel``."""
    start = fr.start[sel]
    hl = np.where(fr.v2[sel], 10, 6)
    plen = buf[start + 9].astype(np.int64)
    first = start + 8 + hl
    cols = np.arange(size)
    idx = first[:, None] + cols
    valid = cols[None, :] < plen[:, None]
    out = np.zeros((len(sel), size), dtype=np.uint8)
    out[valid] = buf[idx[valid]]
    return out


def _field(pay, lay: MsgLayout, name):
    off, dt = lay.offsets[name]
    return np.ascontiguousarray(pay[:, off:off + dt.itemsize]).view(dt).reshape(len(pay))


def _select(buf, fr: TlogFrames, name):
    """Good frames of message ``name``: (frame indices, layout, payload rows,
    system ids), or None when the log has none."""
    mid = getattr(_dialect(), "MAVLINK_MSG_ID_" + name)
    sel = np.nonzero(fr.usable & (fr.msgid == mid))[0]
    if not len(sel):
        return None
    lay = layout(name)
    sysid = np.where(fr.v2[sel], buf[fr.start[sel] + 13], buf[fr.start[sel] + 11]).astype(np.int64)
    return sel, lay, _payloads(buf, fr, sel, lay.size), sysid


def _vehicle_info(data, buf, fr: TlogFrames):
    """Per system id: HEARTBEAT autopilot values and whether an ArduPilot version string was seen."""
    info = {}
    for name in ("HEARTBEAT", "STATUSTEXT"):
        got = _select(buf, fr, name)
        if got is None:
            continue
        sel, lay, pay, sysid = got
        if name == "HEARTBEAT":
            ap = _field(pay, lay, "autopilot")
            for s, a in zip(sysid.tolist(), ap.tolist()):
                info.setdefault(s, {"autopilots": set(), "ap_version": False})["autopilots"].add(a)
        else:
            off, _ = lay.offsets["text"]
            for s, row in zip(sysid.tolist(), pay):
                txt = bytes(row[off:off + 50]).split(b"\0", 1)[0].decode("ascii", "replace")
                if _AP_VERSION_RE.search(txt):
                    info.setdefault(s, {"autopilots": set(), "ap_version": False})["ap_version"] = True
    return info


def gyro_streams(data, fr: TlogFrames, raw_imu_unit="auto", raw_imu_scale=None):
    """The gyro streams of a framed tlog (one per message type, system,
    component and instance), in order of first appearance."""
    buf = np.frombuffer(data, dtype=np.uint8)
    info = None
    found = []
    for name, (tfield, tscale, unit) in GYRO_MESSAGES.items():
        got = _select(buf, fr, name)
        if got is None:
            continue
        sel, lay, pay, sysid = got
        v2 = fr.v2[sel]
        compid = np.where(v2, buf[fr.start[sel] + 14], buf[fr.start[sel] + 12]).astype(np.int64)
        inst = _field(pay, lay, "id").astype(np.int64) if "id" in lay.offsets else np.zeros(len(sel), np.int64)
        t = _field(pay, lay, tfield).astype(np.float64) * tscale
        raw = np.stack([_field(pay, lay, g).astype(np.float64) for g in GYRO_FIELDS], axis=1)
        key = sysid * 1_000_000 + compid * 1000 + inst
        for k in np.unique(key):
            s_sel = key == k
            s_id, c_id, i_id = int(k // 1_000_000), int(k // 1000 % 1000), int(k % 1000)
            u, to_deg, note = unit, None, ""
            if unit == "raw":
                if info is None:
                    info = _vehicle_info(data, buf, fr)
                u, to_deg, note = decide_raw_imu_unit(info.get(s_id), bool(v2[s_sel].any()),
                                                      raw_imu_unit, raw_imu_scale)
            else:
                to_deg = UNIT_TO_DEG_S[u]
            found.append((int(sel[s_sel][0]), name, s_id, c_id, i_id, GyroStream(
                name=name + (f"[{i_id}]" if i_id else ""), message=name, unit=u, to_deg_s=to_deg,
                time_s=t[s_sel], raw=raw[s_sel], index=sel[s_sel], note=note,
                field_dtype=field_dtype(name))))
    found.sort(key=lambda x: x[0])
    systems = {(f[2], f[3]) for f in found}
    streams = []
    for _, _, s_id, c_id, _, st in found:
        if len(systems) > 1:
            st.name += f"@{s_id}.{c_id}"
        streams.append(st)
    return streams


def field_dtype(name):
    """numpy dtype of the gyro fields of message ``name`` (int16 or float32)."""
    return layout(name).offsets[GYRO_FIELDS[0]][1].str


def decide_raw_imu_unit(info, any_v2, override="auto", scale=None, final=True):
    """The unit of a RAW_IMU stream: (unit, factor to deg/s or None, note) -- the
    one rule of the file mode and of live links.

    ``info``: what the log/link showed of the sender so far (``{"autopilots": set of
    HEARTBEAT autopilot values, "ap_version": an ArduPilot version string seen}``
    or None); ``any_v2``: a RAW_IMU packet of the stream was MAVLink 2. mrad/s
    when the sender is ArduPilot (HEARTBEAT autopilot 3) and the packets are
    MAVLink 2 or an ArduPilot version string was sent; else counts of unknown
    scale. ``final=False`` (a live link, more may come): returns None while the
    evidence is incomplete -- no HEARTBEAT of the sender yet, or an ArduPilot
    MAVLink 1 sender whose version string has not arrived."""
    if scale is not None:
        return "counts", float(scale), f"RAW_IMU in counts, scale {scale} deg/s per count (given)"
    if override not in (None, "auto"):
        if override == "counts":
            return "counts", None, "RAW_IMU in counts (given), scale unknown: filtered in counts"
        return override, UNIT_TO_DEG_S[override], f"RAW_IMU unit {override} (given)"
    is_ap = info is not None and AUTOPILOT_ARDUPILOT in info["autopilots"]
    if is_ap and (any_v2 or info["ap_version"]):
        why = "MAVLink 2" if any_v2 else "an ArduPilot version string"
        return "mrad/s", UNIT_TO_DEG_S["mrad/s"], (
            f"RAW_IMU from ArduPilot (HEARTBEAT autopilot 3, {why}): mrad/s")
    if not final and (info is None or is_ap):
        return None
    return "counts", None, (
        "RAW_IMU unit unknown: the log does not show an ArduPilot firmware that sends mrad/s "
        "(old APM firmware sends raw sensor counts, whose scale depends on the sensor); filtered "
        "in counts; pass --raw-imu-unit mrad/s or --raw-imu-scale DEG_S_PER_COUNT")




# ---------------------------------------------------------------- re-packing
class SignedPacketError(ValueError):
    """A signed packet to re-pack without the link's key (it would go out unsigned)."""


def _gyro_payload(pkt, lay, name, values):
    """The payload of ``pkt`` (message ``name``, layout ``lay``) zero-extended to the
    message's full size (MAVLink 2 trims trailing zeros), its gyro fields set to ``values``."""
    hl = 10 if pkt[0] == MAGIC_V2 else 6
    plen = pkt[1]
    full = bytearray(pkt[hl:hl + plen]) + bytes(max(0, lay.size - plen))
    for g, v in zip(GYRO_FIELDS, values):
        off, dt = lay.offsets[g]
        require_fit(f"{name}.{g}", v, dt)     # an infinity or a NaN in a float field is stored as itself
        if dt.kind == "i":
            v = int(np.rint(float(v)))
        full[off:off + dt.itemsize] = np.array(v, dtype=dt).tobytes()
    return full


def repack(pkt, name, values, signer=None):
    """Packet ``pkt`` (bytes) of message ``name`` with its gyro fields set to
    ``values`` (3 numbers in the field unit; int16 fields are rounded; a float
    field holds an infinity or a NaN as itself). A value
    that does not fit the field's type raises ValueError (never clipped: the
    callers check :func:`gyrodenoise.flightlog.streams.field_misfit` first and keep the raw
    values). A signed packet is re-signed by ``signer``
    (:class:`gyrodenoise.flightlog.signing.LinkSigning` holding the key); without one it
    raises :class:`SignedPacketError` (a signed packet is never made unsigned).
    Returns (new packet bytes, signature_dropped: always False)."""
    if is_signed(pkt) and (signer is None or signer.key is None):
        raise SignedPacketError(f"{name}: a signed packet cannot be changed without the link's key")
    lay = layout(name)
    v2 = pkt[0] == MAGIC_V2
    hl = 10 if v2 else 6
    plen = pkt[1]
    full = _gyro_payload(pkt, lay, name, values)
    if v2:
        k = len(full)
        while k > 1 and full[k - 1] == 0:
            k -= 1
        new_len = max(plen, k)
        header = bytearray(pkt[:hl])
        header[1] = new_len
    else:
        new_len = plen
        header = bytearray(pkt[:hl])
    body = bytes(header) + bytes(full[:new_len])
    crc = x25_crc(body[1:])
    crc = x25_crc(bytes([lay.crc_extra]), crc)
    body += struct.pack("<H", crc)
    if is_signed(pkt):
        return signer.resign(pkt, body), False
    return body, False


def keep_signed_raw(fr: TlogFrames, streams, link: LinkSigning):
    """Without the link's key: the samples of signed packets go out raw (their
    packets unchanged, signature kept), in ``s.filtered`` and the work values alike
    (the CSV and the figures say what the log holds); counts them in
    ``link.left_raw`` (those the filter had changed). A stream that the filter
    changed only in signed packets gets the reason in ``s.not_filtered``."""
    if link.key is not None:
        return
    for s in streams:
        if s.filtered is None:
            continue
        sig = fr.signed[s.index]
        changed = np.any(s.filtered != s.raw, axis=1) & ~np.all(np.isnan(s.filtered) & np.isnan(s.raw), axis=1)
        lost = sig & changed
        if not lost.any():
            continue
        link.left_raw += int(lost.sum())
        s.filtered = np.where(lost[:, None], s.raw.astype(np.float64), s.filtered)
        work = getattr(s, "_work", None)
        if work is not None:
            x, f, unit, rate = work
            s._work = (x, np.where(lost[:, None], x, f), unit, rate)
        if not (changed & ~sig).any() and not getattr(s, "not_filtered", None):
            from gyrodenoise.flightlog.signing import KEY_HINT
            s.not_filtered = (f"its packets are signed (MAVLink 2) and no --signing-key was given: written raw, "
                              f"signatures kept (a signed packet is never written unsigned); {KEY_HINT}")


def write_filtered(data, fr: TlogFrames, streams, path, link: LinkSigning | None = None):
    """Write the tlog with the filtered gyro values of ``streams``; returns the
    number of signatures dropped (0: a signed packet is never written unsigned).

    ``link`` (:class:`gyrodenoise.flightlog.signing.LinkSigning`): with its key,
    changed signed packets are re-signed and the records ``fr.rejected`` are left
    out; without one (or no ``link``), a signed packet is written unchanged (see
    :func:`keep_signed_raw`). A packet whose bytes the filter does not change
    keeps them, signature and all."""
    link = link if link is not None else LinkSigning()
    repl = {}
    for s in streams:
        if s.filtered is None:
            continue
        for rec, vals in zip(s.index.tolist(), s.filtered.tolist()):
            repl[rec] = (s.message, vals)
    cut = {int(r): None for r in np.nonzero(fr.rejected)[0]} if link.key is not None else {}
    with open(path, "wb") as fh:
        last = 0
        for rec in sorted({**repl, **cut}):
            a = int(fr.start[rec])
            b = a + int(fr.length[rec])
            if rec in cut:                      # failed the signature check: not written
                fh.write(data[last:a])
                last = b
                continue
            pkt = data[a + 8:b]
            if fr.signed[rec] and link.key is None:
                continue                        # never unsigned: written as it came
            new = repacked(pkt, repl[rec], link)
            fh.write(data[last:a + 8])
            fh.write(new)
            last = b
        fh.write(data[last:])
    return 0


def repacked(pkt, rep, link):
    """The packet with its new gyro values; a signed one whose payload the values do
    not change keeps its bytes (and signature)."""
    if not is_signed(pkt):
        return repack(pkt, *rep)[0]
    name, values = rep
    lay = layout(name)
    hl, plen = (10 if pkt[0] == MAGIC_V2 else 6), pkt[1]
    full = _gyro_payload(pkt, lay, name, values)
    if full == bytearray(pkt[hl:hl + plen]) + bytes(len(full) - plen):
        return pkt
    return repack(pkt, *rep, signer=link)[0]


def looks_like_tlog(head):
    """True if the first bytes look like a tlog record with a good packet."""
    if len(head) < 9:
        return False
    ln = packet_len(head, 8, len(head))
    return bool(ln and ln > 0 and 8 + ln <= len(head) and packet_ok(head[8:8 + ln]))


def read(path, raw_imu_unit="auto", raw_imu_scale=None):
    """Read a tlog: (bytes, TlogFrames, streams). InputError if unreadable."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    fr = frame(data, str(path))
    if len(fr.start) == 0 or not fr.ok.any():
        raise InputError(f"{path}: no readable MAVLink record (not a telemetry log?)")
    return data, fr, gyro_streams(data, fr, raw_imu_unit, raw_imu_scale)
