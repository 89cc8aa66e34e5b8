"""The flight review of one log, as the bridge reports it: the flight segments, the
vehicle's own gyro filters, the review of those filters and the vibration review
(the keys of a log's report in the interface spec, section 8).

:func:`log_review` runs :mod:`gyrodenoise.flightlog.parameters`,
:mod:`gyrodenoise.flightlog.segments`, :mod:`gyrodenoise.flightlog.vehicle_filters`,
:mod:`gyrodenoise.flightlog.filter_review` and :mod:`gyrodenoise.flightlog.vibration`
on a log read by :func:`gyrodenoise.flightlog.formats.read_log`, and says what the
figures are computed over: the ``flying`` segments by default (``"over":
"flying"``), the whole log with ``whole_log=True`` or when the log has no flying
segment (``"over": "whole log"``, and ``over_note`` says why).

Each part is independent: one that fails (an odd log) gives ``None`` and a note
naming the error; the others and the filtered outputs go on.
"""

from __future__ import annotations

import numpy as np

from gyrodenoise.flightlog.autopilots import UNKNOWN
from gyrodenoise.flightlog.filter_review import filter_review, pick_pre_filter_stream, review_context
from gyrodenoise.flightlog.inflight_noise import inflight_noise, noise_lines
from gyrodenoise.flightlog.notch_replay import replay_review
from gyrodenoise.flightlog.overview import overview, step_response_line, worst_figures
from gyrodenoise.flightlog.segments import flight_segments, flying_time_s, segment_mask
from gyrodenoise.flightlog.step_response import step_response_review
from gyrodenoise.flightlog.vehicle_filters import stream_stage, vehicle_filters
from gyrodenoise.flightlog.vibration import vibration_review

#: a stream needs this many flying samples for its figures over flying time
MIN_FLYING_SAMPLES = 64
OVER_FLYING, OVER_WHOLE = "flying", "whole log"


class Review:
    """The review of a log: ``fields`` (the JSON-able report keys), ``plot`` (the
    filter review's numpy arrays for plots, or None), ``over``, ``starts`` (the
    records where the log's boot sessions 1, 2, ... begin:
    :meth:`gyrodenoise.flightlog.model.FlightLog.boot_starts`) and :meth:`flying_mask`."""

    def __init__(self, fields, plot, segments, over, log=None):
        self.fields = fields
        self.plot = plot
        self.segments = segments
        self.over = over
        #: the log, where it has several boots (its ``boot_of`` places a sample in its boot)
        self.log = log if log is not None and len(log.boots) > 1 else None
        #: {axis: StepResponse} of the step response, for the plot
        self.step_curves = {}

    def flying_mask(self, time_s, records=None):
        """Bool array: the samples of ``time_s`` the figures are over (all True when
        they are over the whole log). ``records``: the samples' frame indices (a gyro
        stream's ``index``): in a log of several boot sessions a sample is flying when
        its session and its time are those of a flying segment (the boot times of the
        sessions overlap); without them the time alone decides."""
        t = np.asarray(time_s, dtype=np.float64)
        if self.over != OVER_FLYING:
            return np.ones(t.shape, dtype=bool)
        sess = self.log.boot_of(records) if records is not None and self.log is not None else None
        return segment_mask(t, self.segments, "flying", sess)

    def stream_mask(self, time_s, records=None):
        """(mask, over) for one stream: its flying samples and ``"flying"``, or all
        samples and ``"whole log"`` when it has fewer than :data:`MIN_FLYING_SAMPLES`
        flying ones (or the figures are over the whole log). ``records``: as
        :meth:`flying_mask`."""
        m = self.flying_mask(time_s, records)
        if self.over == OVER_FLYING and int(m.sum()) >= MIN_FLYING_SAMPLES:
            return m, OVER_FLYING
        return np.ones(m.shape, dtype=bool), OVER_WHOLE


def never_armed_note(segments):
    """The ``filter_review_note`` of a log whose segments show the vehicle never armed
    (all ``ground``), or "" (it armed or flew, or the log holds no segment evidence).
    The motors never turned: the gyro spectrum at rest says nothing about the motor
    noise the filters are there for, so no filter is recommended from it (the
    streams' own spectra stay in the report)."""
    kinds = {s.kind for s in segments or []}
    if not kinds or kinds & {"armed", "flying", "hover"}:
        return ""
    return ("no filter review: the vehicle never armed in this log (segments: ground only); the gyro "
            "spectrum at rest says nothing about motor noise (each stream's own spectrum is still in "
            "the report)")


def _failed(part, exc):
    return f"{part} failed: {type(exc).__name__}: {exc}"


def boots_fields(log, segments):
    """The report's ``boots``: each boot of the log (:class:`~gyrodenoise.flightlog.model.Boot`)
    with its time base, its segments and its flying time."""
    out = []
    for b in log.boots:
        segs = [s for s in segments if s.session == b.index]
        out.append({**b.to_fields(), "segments": [s.to_fields() for s in segs], "flying_time_s": flying_time_s(segs)})
    return out


def log_review(log, whole_log=False):
    """The :class:`Review` of a :class:`~gyrodenoise.flightlog.model.FlightLog`.

    ``fields``: ``time_base``, ``boots`` (each boot: its time base, segments and flying
    time), ``segments``, ``segments_note``, ``flying_time_s``, ``over``,
    ``over_note``, ``impacts`` (each crash found: :class:`~gyrodenoise.flightlog.impact.Impact`;
    the flight ends there), ``vehicle_filters`` (``autopilot`` ``"ardupilot"``/``"px4"``/None,
    ``parameters``, ``stages``; ``note`` when the log holds no parameters),
    ``stream_stages`` ({stream name: ``pre-filter``/``post-filter``/``unknown``}),
    ``filter_review`` (None with ``filter_review_note``), ``vibration`` (None with
    ``vibration_note``), ``step_response`` (the rate loop's step response per axis:
    :mod:`gyrodenoise.flightlog.step_response`; None with ``step_response_note``),
    ``notch_replay`` (the vehicle's chain replayed against its logged post-filter gyro:
    :mod:`gyrodenoise.flightlog.notch_replay`; None with ``notch_replay_note``),
    ``inflight_noise`` (noise densities flying and at rest, EKF parameters, Kalibr
    figures: :mod:`gyrodenoise.flightlog.inflight_noise`; None with ``inflight_noise_note``),
    ``overview`` (the first screen: :mod:`gyrodenoise.flightlog.overview`)."""
    streams = log.gyro
    fields = {"time_base": log.time_base.to_fields()}
    try:
        got = log.parameters()
        autopilot, params = got.autopilot, got.values
        if got.notes:
            fields["parameters_note"] = "; ".join(got.notes)
    except Exception as exc:  # noqa: BLE001 - one part of the review must not stop the log
        autopilot, params = UNKNOWN, {}
        fields["parameters_note"] = _failed("reading the parameters", exc)
    try:
        segments, seg_note = flight_segments(log, autopilot)
    except Exception as exc:  # noqa: BLE001
        segments, seg_note = [], _failed("flight segments", exc)
    fields["boots"] = boots_fields(log, segments)
    fields["segments"] = [s.to_fields() for s in segments]
    fields["segments_note"] = seg_note
    fields["flying_time_s"] = flying_time_s(segments)
    fields["impacts"] = [s.impact.to_fields() for s in segments if s.impact is not None]
    has_flying = any(s.kind == "flying" for s in segments)
    if whole_log:
        over, over_note = OVER_WHOLE, "--whole-log: figures over the whole log"
    elif has_flying:
        over, over_note = OVER_FLYING, "figures over the flying segments (--whole-log: over the whole log)"
        if fields["impacts"]:
            over_note += "; the flight ends at the impact: what follows is shown (after impact), not judged"
    else:
        over, over_note = OVER_WHOLE, "no flying segment in the log: figures over the whole log"
    fields["over"] = over
    fields["over_note"] = over_note
    review = Review(fields, None, segments, over, log)

    filters = vehicle_filters(autopilot, params)
    if not params:
        filters["note"] = "no parameters in the log: the vehicle's filters are not known"
    fields["vehicle_filters"] = filters
    for s in streams:
        s.stage = stream_stage(autopilot, params, s)
    fields["stream_stages"] = {s.name: s.stage for s in streams}

    mask_fn = review.flying_mask if over == OVER_FLYING else None
    if len(log.boots) > 1:
        rev, note, review.plot = _review_per_boot(log, review, autopilot, params, filters, mask_fn)
    else:
        rev, note, review.plot = _filter_review(log, segments, autopilot, params, filters, mask_fn)
    fields["filter_review"] = rev
    fields["filter_review_note"] = note
    fields["notch_replay"], fields["notch_replay_note"] = _notch_replay(log, autopilot, params, filters, mask_fn)
    try:
        fields["inflight_noise"], fields["inflight_noise_note"] = inflight_noise(
            log, segments, autopilot, params, filters)
    except Exception as exc:  # noqa: BLE001
        fields["inflight_noise"], fields["inflight_noise_note"] = None, _failed("in-flight noise", exc)
    try:
        vib, vnote = vibration_review(log, segments, over="whole" if over == OVER_WHOLE else "flying")
    except Exception as exc:  # noqa: BLE001
        vib, vnote = None, _failed("vibration review", exc)
    fields["vibration"] = vib
    fields["vibration_note"] = vnote
    try:
        step, snote, review.step_curves = step_response_review(log, segments)
    except Exception as exc:  # noqa: BLE001
        step, snote = None, _failed("step response", exc)
    fields["step_response"] = step
    fields["step_response_note"] = snote
    try:
        ident = log.format.identity(log)
    except Exception:  # noqa: BLE001 - the identity is a convenience: unknown fields, never a failed log
        ident = {}
    fields["overview"] = overview(fields, ident)
    return review


def _notch_replay(log, autopilot, params, filters, mask_fn):
    """(replay or None, note): the vehicle's chain replayed on the pre-filter gyro and
    compared with the logged post-filter gyro over ``mask_fn``'s samples
    (:func:`gyrodenoise.flightlog.notch_replay.replay_review`)."""
    try:
        stream, _, _ = pick_pre_filter_stream(log.gyro, autopilot, params)
        if stream is None:
            return None, "no pre-filter gyro stream: nothing to replay"
        keep = None if mask_fn is None else (lambda t: mask_fn(t, None))
        return replay_review(log, autopilot, params, filters, stream, keep)
    except Exception as exc:  # noqa: BLE001 - one part of the review must not stop the log
        return None, _failed("notch replay", exc)


def _filter_review(log, segments, autopilot, params, filters, mask_fn):
    """(review or None, note, plot or None) of the filter review over ``mask_fn``'s
    samples; None and a note when the vehicle never armed in ``segments`` or the
    review failed."""
    idle = never_armed_note(segments)
    if idle:
        return None, idle, None
    try:
        ctx = review_context(log, autopilot, params, filters, mask_fn)
        fft = ctx.get("gyro_fft")
        if fft and fft.get("sample_rate_hz"):          # PX4: the raw gyro rate, measured on board
            filters["filter_rate_hz"] = fft["sample_rate_hz"]
            filters["filter_rate_source"] = "sensor_gyro_fft.sensor_sample_rate_hz (the raw gyro rate)"
        return filter_review(log.gyro, autopilot, params, filters, mask_fn, ctx)
    except Exception as exc:  # noqa: BLE001 - one part of the review must not stop the log
        return None, _failed("filter review", exc), None


def _review_per_boot(log, review, autopilot, params, filters, mask_fn):
    """The filter review of a log of several boots, boot by boot (no figure spans two):
    each boot's review (without its plot arrays) and note go into its entry of
    ``boots``; the log's ``filter_review`` is the review of the boot that flew longest
    (the first of those that has one), its ``source.boot`` saying which."""
    boots = review.fields["boots"]
    found = {}
    for b in boots:
        k = b["session"]

        def boot_mask(t, records=None, k=k):
            t = np.asarray(t, dtype=np.float64)
            base = mask_fn(t, records) if mask_fn is not None else np.ones(t.shape, dtype=bool)
            if records is None:                # samples that do not say their boot: none of this one's
                return np.zeros(t.shape, dtype=bool)
            return base & (log.boot_of(records) == k)
        rev, note, plot = _filter_review(log, [s for s in review.segments if s.session == k], autopilot, params,
                                         filters, boot_mask)
        if rev is not None:
            rev["source"]["boot"] = k
            found[k] = (rev, plot)
        b["filter_review"] = rev
        b["filter_review_note"] = note
    if not found:
        by_note = {}
        for b in boots:
            by_note.setdefault(b["filter_review_note"], []).append(str(b["session"]))
        return None, "; ".join(f"boot{'s' if len(ks) > 1 else ''} {', '.join(ks)}: {n}"
                               for n, ks in by_note.items()), None
    best = max(found, key=lambda k: (boots[k]["flying_time_s"] or 0.0, -k))
    return found[best][0], (f"the review of boot {best}, the one that flew longest ({len(boots)} boots, "
                            f"each reviewed on its own in boots)"), found[best][1]


def vehicle_rate_series(log, streams=()):
    """The vehicle's own body-rate estimate for the HTML report, ``[{"name", "time_s",
    "rate": (m, 3) deg/s, "unit"}]`` (the format adapter's ``vehicle_rate``: ArduPilot
    :func:`dataflash_rate_series`, PX4 :func:`ulog_rate_series`); empty when the log
    has none."""
    try:
        return log.format.vehicle_rate(log, streams)
    except Exception:  # noqa: BLE001 - a plot's extra line, never a reason to fail a log
        return []


def review_text(rep):
    """Lines of the text summary for a log's review: segments and flying time,
    vibration verdict, the filter review's recommendation (a line each)."""
    segs = rep.get("segments")
    if segs is None:
        return []
    main = [s for s in segs if s["kind"] != "hover"]
    if main:
        shown = ", ".join(f"{s['kind']} {s['start_s']:.1f}-{s['end_s']:.1f} s" for s in main[:6])
        more = f", ... ({len(main)} in all)" if len(main) > 6 else ""
        n_hover = sum(s["kind"] == "hover" for s in segs)
        hov = f"; {n_hover} hover stretch(es)" if n_hover else ""
        fly = rep.get("flying_time_s") or 0.0
        seg_line = (f"segments: {shown}{more}{hov}; flying {fly:.1f} s" if fly else
                    f"segments: {shown}{more}; never flying")
    else:
        seg_line = f"segments: none ({rep.get('segments_note', '')})"
    boots = rep.get("boots") or []
    if len(boots) > 1:
        seg_line += (f"; {len(boots)} boots, each on its own time (flying "
                     + ", ".join(f"{b.get('flying_time_s') or 0.0:.1f}" for b in boots) + " s)")
    base = rep.get("time_base") or {}
    if base.get("kind") and base.get("kind") != "boot time":
        seg_line += f"; times on a {base['kind']} clock from {base.get('offset_s')} s"
    lines = [seg_line + f"; figures over: {rep.get('over', OVER_WHOLE)}"]
    for imp in rep.get("impacts") or []:
        lines.append(f"crash: {imp['reason']}; the flight ends there (after impact: shown, not judged)")
    vib = rep.get("vibration")
    if vib and vib.get("verdict"):
        lines.append(f"vibration: {vib['verdict'].upper()} ({vib.get('source')} over {vib.get('over')}"
                     f"{worst_figures(vib)})")
    elif vib:
        lines.append(f"vibration: no verdict ({vib.get('source')} only, over {vib.get('over')}: no published "
                     f"threshold for them)")
    else:
        lines.append(f"vibration: none ({rep.get('vibration_note', '')})")
    sr = rep.get("step_response")
    if sr:
        lines.append("step response: " + step_response_line(sr))
    elif "step_response_note" in rep:
        lines.append(f"step response: none ({rep['step_response_note']})")
    nr = rep.get("notch_replay")
    if nr and nr.get("agreement"):
        lines.append(f"filter replay ({nr['pre']['stream']} -> {nr['post']['stream']}): "
                     f"{nr['agreement']['db_rms']['all']:.2f} dB rms from the logged post-filter gyro over "
                     f"{nr['agreement']['band_hz'][0]:g}-{nr['agreement']['band_hz'][1]:g} Hz")
    elif nr:
        lines.append(f"filter replay: no agreement figure ({nr.get('agreement_note', '')})")
    if "inflight_noise" in rep:
        lines += noise_lines(rep)
    fr = rep.get("filter_review")
    if fr:
        rec = fr.get("param_lines") or []
        src = fr.get("source", {}).get("stream")
        lines.append(f"filter review ({src}): " + ("recommends " + " ".join(rec) if rec else
                                                   "no change recommended"))
    else:
        lines.append(f"filter review: none ({rep.get('filter_review_note', '')})")
    return lines
