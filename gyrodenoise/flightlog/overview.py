"""The first screen of a log's review: what a tuner asks first -- which vehicle, firmware,
board and frame, how long it flew in each boot, and one line per verdict (crash,
vibration, filters, step response) with its reason.

:func:`overview` builds the report's ``overview`` from the review's own keys (it judges
nothing itself: each verdict is the one its part of the review gave) and the log's
identity (:meth:`LogFormat.identity`, one reader per format below: ArduPilot's boot
messages, PX4's ULog info, Betaflight's header). A field the log does not hold is None.
"""

from __future__ import annotations

import re

IDENTITY_KEYS = ("vehicle", "firmware", "board", "frame", "vehicle_id")

_AP_VEHICLE = re.compile(r"^(ArduCopter|ArduPlane|ArduRover|ArduSub|APM:Copter|APM:Plane|APM:Rover|Rover|Blimp|"
                         r"AntennaTracker)\s+(V?\d\S*(?:\s+\([0-9a-f]+\))?)")
_AP_BOARD = re.compile(r"^([A-Za-z][\w-]*)\s+([0-9A-F]{8}(?:\s+[0-9A-F]{8}){2})\s*$")
_AP_FRAME = re.compile(r"^Frame:\s*(.+?)\s*$")
#: PX4's ``MAV_TYPE`` parameter -> the vehicle it names (the values PX4's parameter
#: reference lists, https://docs.px4.io/main/en/advanced_config/parameter_reference.html)
MAV_TYPES = {1: "fixed wing", 2: "quadrotor", 3: "coaxial", 4: "helicopter", 7: "airship", 8: "free balloon",
             10: "ground rover", 11: "surface boat", 12: "submarine", 13: "hexarotor", 14: "octorotor",
             15: "tricopter", 19: "VTOL two-rotor tailsitter", 20: "VTOL quad-rotor tailsitter",
             21: "VTOL tiltrotor", 22: "VTOL standard", 23: "VTOL tailsitter", 29: "dodecarotor"}


def _identity(**kw):
    out = dict.fromkeys(IDENTITY_KEYS)
    out.update({k: v for k, v in kw.items() if v not in (None, "")})
    return out


def ardupilot_identity(log):
    """Vehicle and firmware (``ArduCopter V4.1.1 (01d1aa1e)``), board and its id
    (``CUAVv5 0025001E 31385115 35333837``) and frame (``Frame: QUAD/X``) from the boot
    messages ArduPilot writes (DataFlash ``MSG``, telemetry ``STATUSTEXT``)."""
    vehicle = firmware = board = board_id = frame = None
    for e in log.events():
        text = e.text.strip()
        if vehicle is None and (m := _AP_VEHICLE.match(text)):
            vehicle, firmware = m.group(1), m.group(2)
        elif board is None and (m := _AP_BOARD.match(text)):
            board, board_id = m.group(1), m.group(2)
        elif frame is None and (m := _AP_FRAME.match(text)):
            frame = m.group(1)
    return _identity(vehicle=vehicle, firmware=firmware, board=board, frame=frame, vehicle_id=board_id)


def ulog_identity(log):
    """PX4's ULog info: ``ver_sw_release`` (0xAABBCCTT: version AA.BB.CC) and ``ver_sw``
    (git), ``ver_hw`` (board), ``sys_uuid``; the vehicle from ``MAV_TYPE``, the frame
    from ``SYS_AUTOSTART`` (the airframe id)."""
    info = getattr(getattr(log.payload, "ulog", None), "msg_info_dict", {}) or {}
    rel = info.get("ver_sw_release")
    fw = None
    if isinstance(rel, int) and rel:
        fw = f"{(rel >> 24) & 0xFF}.{(rel >> 16) & 0xFF}.{(rel >> 8) & 0xFF}"
    if info.get("ver_sw"):
        fw = f"{fw or '?'} (git {str(info['ver_sw'])[:8]})"
    try:
        params = log.parameters().values
    except Exception:  # noqa: BLE001 - identity is a convenience, never a reason to fail
        params = {}
    mav = params.get("MAV_TYPE")
    vehicle = "PX4" + (f" {MAV_TYPES.get(int(mav), f'MAV_TYPE {int(mav)}')}" if mav is not None else "")
    auto = params.get("SYS_AUTOSTART")
    return _identity(vehicle=vehicle, firmware=fw, board=info.get("ver_hw"),
                     frame=f"airframe {int(auto)} (SYS_AUTOSTART)" if auto else None,
                     vehicle_id=info.get("sys_uuid"))


def blackbox_identity(log):
    """Betaflight's header: ``Firmware revision``, ``Board information``, ``Craft name``
    (the pilot's name for the craft: its id)."""
    if not log.payload:
        return _identity()
    h = log.payload[0].header
    rev = h.get("Firmware revision")
    return _identity(vehicle=(rev or h.get("Firmware type") or "").split(" ")[0] or None, firmware=rev,
                     board=h.get("Board information"), vehicle_id=h.get("Craft name"))


# ------------------------------------------------------------------ the screen
def _line(topic, verdict, reason):
    return {"topic": topic, "verdict": verdict, "reason": reason}


def crash_line(fields):
    imps = fields.get("impacts") or []
    if imps:
        return _line("crash", "fail", "; ".join(f"boot {i['session']}: {i['reason']}" for i in imps) +
                     " -- the flight ends there; what follows is kept out of the verdicts")
    if not any(s.get("kind") == "flying" for s in fields.get("segments") or []):
        return _line("crash", None, "not looked for: the log holds no flight")
    return _line("crash", "pass", "no impact found (a body-rate jump 4x the flight's envelope with a 3 g "
                                  "accelerometer spike, then a disarm or a tumble)")


def worst_figures(vib):
    """'; vibration_z p95 34.9 (warn), clipping_0 +6311 (fail)': the figures of a
    vibration review at warn or fail (the worst segment's value of each)."""
    worst = {}
    for seg in vib.get("segments") or []:
        if not seg.get("in_verdict", True):
            continue
        for name, f in (seg.get("figures") or {}).items():
            v = f.get("verdict")
            if v in ("warn", "fail"):
                value = f"+{f['increase']}" if "increase" in f else f"p95 {f.get('p95')}"
                if name not in worst or (v == "fail" and worst[name][1] != "fail"):
                    worst[name] = (value, v)
    return ("; " + ", ".join(f"{n} {val} ({v})" for n, (val, v) in worst.items())) if worst else ""


def vibration_line(fields):
    vib = fields.get("vibration")
    if not vib:
        return _line("vibration", None, fields.get("vibration_note") or "no vibration data")
    if not vib.get("verdict"):
        return _line("vibration", None, f"{vib.get('source')} only: no published threshold for it")
    worst = worst_figures(vib)[2:]
    return _line("vibration", vib["verdict"],
                 f"{vib.get('source')} over {vib.get('over')}: " + (worst or "every figure below its warn threshold"))


def filters_line(fields):
    fr = fields.get("filter_review")
    if not fr:
        return _line("filters", None, fields.get("filter_review_note") or "no filter review")
    rec = fr.get("param_lines") or []
    src = (fr.get("source") or {}).get("stream")
    if rec:
        return _line("filters", "change", f"from {src}: " + "; ".join(rec))
    return _line("filters", "pass", f"from {src}: no change recommended")


def step_response_line(sr):
    """'roll rise 32 ms, overshoot 17 %; pitch ...; (RATE ...)': a step response in a line."""
    parts = []
    for axis, f in (sr.get("axes") or {}).items():
        if not f:
            parts.append(f"{axis} none")
            continue
        rise = "?" if f["rise_time_s"] is None else f"{f['rise_time_s'] * 1000:.0f} ms"
        over = "?" if f["overshoot_pct"] is None else f"{f['overshoot_pct']:.0f} %"
        parts.append(f"{axis} rise {rise}, overshoot {over}")
    return "; ".join(parts) + f" ({sr.get('source')})"


def step_line(fields):
    sr = fields.get("step_response")
    if not sr:
        return _line("step response", None, fields.get("step_response_note") or "no rate setpoint")
    return _line("step response", None, step_response_line(sr) + "; no published threshold: read the figures")


#: the verdict lines, in the order shown
VERDICT_LINES = (crash_line, vibration_line, filters_line, step_line)


def overview(fields, identity):
    """The report's ``overview``: ``identity`` (:data:`IDENTITY_KEYS`), ``flight_time_s``
    (the flying seconds of each boot, up to a crash), ``flying_time_s`` (their sum) and
    ``verdicts`` (``{"topic", "verdict": pass/warn/fail/change or None, "reason"}``, one
    per :data:`VERDICT_LINES`) of a log's review ``fields``."""
    boots = fields.get("boots") or []
    return {**{k: identity.get(k) for k in IDENTITY_KEYS},
            "flight_time_s": [b.get("flying_time_s") for b in boots],
            "flying_time_s": fields.get("flying_time_s"),
            "verdicts": [f(fields) for f in VERDICT_LINES]}
