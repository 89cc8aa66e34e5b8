"""One log end to end: read, find restarts, denoise, write.

Outputs of a log ``NAME.ext`` in the output folder:

* ``NAME.filtered.ext`` -- the log with the gyro fields of the IMU messages
  replaced by the filtered values (same messages, same order; only those
  fields, and for MAVLink the CRC, differ);
* ``NAME.STREAM.csv`` -- ``time,raw_x,filtered_x,raw_y,filtered_y,raw_z,filtered_z,restart``
  per stream (deg/s; ``*_counts`` columns when the unit is unknown);
* ``NAME.STREAM.png`` -- raw and filtered per axis, restarts marked;
* ``NAME.spectrum.png`` -- per stream raw and filtered PSD per axis, vibration
  peaks named; the filter's gain and lag; a spectrogram for a long record
  (:mod:`gyrodenoise.flightlog.spectra`).

A telemetry log with signed MAVLink 2 packets (:mod:`gyrodenoise.flightlog.signing`):
with ``signing_key`` every packet is checked in the log's order, those that fail are
neither filtered nor written (counted per source), and the changed packets are
re-signed; without it, signed packets are written unchanged, gyro raw.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from gyrodenoise.core.kernels import DEFAULT_METHOD
from gyrodenoise.errors import InputError
from gyrodenoise.flightlog.checks import usable_samples
from gyrodenoise.flightlog.engines import make_engine
from gyrodenoise.flightlog.filtering import check_some_stream_filterable, filter_form, filter_options, filter_streams
from gyrodenoise.flightlog.formats import log_format, read_log
from gyrodenoise.flightlog.model import ReadOptions
from gyrodenoise.flightlog.html_writer import HtmlWriter
from gyrodenoise.flightlog.log_review import OVER_FLYING, log_review, vehicle_rate_series
from gyrodenoise.flightlog.output import joined_time, safe_name, write_csv
from gyrodenoise.flightlog.plotting import BOOT_AXIS, Plotter, title_note
from gyrodenoise.flightlog.report import log_problems, signing_problems, stream_report
from gyrodenoise.flightlog.spectra import stream_spectrum
from gyrodenoise.flightlog.stopping import atomic_path


def process_log(path, out_dir, *, engine="native", method=DEFAULT_METHOD, ar_order=3, gap_factor=5.0,
                plots=True, csv=True, raw_imu_unit="auto", raw_imu_scale=None, fmu_path=None,
                sample_rate=None, out_stem=None, log=None, background_plots=False,
                plot_helpers=1, warmup_s=None, filter_kw=None, zero_phase=False, causal=False,
                signing_key=None, whole_log=False, html=True):
    """Process one log file; return its report (a JSON-able dict).

    The form of the filter (``rep["form"]``): a whole log is filtered offline by
    default where the engine and method have an offline form (the native engine
    with ``method="motion"``: forwards and backwards per session, no lag;
    ``zero_phase`` for the low-pass); ``causal=True`` gives the causal filter
    (``Denoiser``, as a live link, ``Denoiser.step`` and the FMUs run it). The FMU
    engine is always causal.

    ``signing_key`` (32 bytes, :func:`gyrodenoise.flightlog.signing.read_key`): a
    telemetry log's packets are checked and the changed ones re-signed; without it
    signed packets are written unchanged (``signed_left_raw``).

    Raises InputError (one line naming the file) for a file that cannot be
    used: unknown type, unreadable, or without a gyro stream.
    ``background_plots`` draws the PNGs in a forked helper process (Linux),
    which overlaps matplotlib's import and drawing with the filtering; the HTML
    report (``html``, with ``plots``) is written by another such helper.

    The flight review (:func:`gyrodenoise.flightlog.log_review.log_review`) adds the
    keys ``segments``, ``vehicle_filters``, ``filter_review``, ``vibration`` (each
    with its ``*_note``), ``over`` and ``report_html`` (None without plots); each
    stream says its ``stage``. Spectra, noise figures and vibration are computed
    over the flying segments (``"over": "flying"``) unless ``whole_log`` or the log
    has none.
    """
    t0 = time.perf_counter()
    path = Path(path)
    if not (path.is_file() or path.is_dir()):
        raise InputError(f"{path}: no such file")
    fmt = log_format(path)
    rep = {"file": str(path), "format": fmt.name}
    plotter = Plotter(background_plots, helpers=plot_helpers) if plots else None
    html_writer = HtmlWriter(background_plots) if plots and html else None
    done = False
    try:
        flight = read_log(path, fmt, ReadOptions(raw_imu_unit, raw_imu_scale))
        rep.update(flight.facts.to_fields())
        link = fmt.signing(flight, signing_key)
        streams = flight.gyro
        review = log_review(flight, whole_log)
        rep.update(review.fields)
        rep.pop("stream_stages", None)
        offline = engine == "native" and method == "motion" and not causal
        eng = make_engine(engine, method, ar_order, fmu_path, warmup_s, filter_kw, zero_phase, offline)
        rep.update(filter_form(eng, engine))
        try:
            filter_streams(streams, eng, gap_factor, sample_rate)
        finally:
            eng.close()
        if link is not None:
            fmt.keep_signed_raw(flight, link)
        check_some_stream_filterable(path, streams, filter_kw)
        what = f"{engine} {_method_label(method, ar_order, rep['form'])}"
        stem = out_stem or path.stem
        rep.update(_write_outputs(path, flight, Path(out_dir), stem,
                                  plotter, csv, what, method, filter_kw, log, link, review))
        for s in rep["streams"]:
            s["stage"] = review.fields["stream_stages"].get(s["name"], "unknown")
        rep["report_html"] = None
        rep.update(engine=engine, method=method, ar_order=int(ar_order), gap_factor=gap_factor,
                   warmup_s=warmup_s, filter_options=filter_options(method, filter_kw, zero_phase))
        if html_writer is not None:
            rep["report_html"] = str(Path(out_dir) / f"{stem}.report.html")
            html_writer.write(rep["report_html"], rep, _html_series(flight, review, rep))
        done = True
    finally:
        # an interrupt or a failure: stop the helpers now, without waiting for their plots
        for helper in (plotter, html_writer):
            if helper is not None:
                helper.close() if done else helper.abort()
    rep["seconds"] = round(time.perf_counter() - t0, 3)
    return rep


def _html_series(log, review, rep):
    """The ``series`` of :func:`gyrodenoise.flightlog.html_report.write_log_report`: the
    streams (raw, filtered, restarts), their spectra, the vehicle's own rate estimate
    and the filter review's spectra."""
    from gyrodenoise.flightlog.html_report import stream_series
    streams = log.gyro
    spectra = {s.name: s._spectrum_plot for s in streams if getattr(s, "_spectrum_plot", None) is not None}
    series = {"streams": [stream_series(s, f"filtered ({rep['method']}{', ' + rep['form'] if rep.get('form') else ''})")
                          for s in streams],
              "spectra": spectra,
              "vehicle_rate": vehicle_rate_series(log, streams)}
    series["filter_review"] = _review_series(review.plot, rep.get("vehicle_filters") or {}, streams)
    from gyrodenoise.flightlog.timeseries import flight_views
    series["views"] = flight_views(log, (rep.get("vehicle_filters") or {}).get("stages"))
    return series


def _review_series(plot, filters, streams):
    """The ``series["filter_review"]`` of the HTML report: the review's spectra summed
    over the axes and the gains |H| of the logged and the recommended chains, each
    the ratio of the review's predicted post-filter PSD to the pre-filter one (the
    autopilot's own biquads, :func:`gyrodenoise.flightlog.vehicle_filters.chain_response`,
    with the notch centres the review used). Without a review, the logged chain's
    gain from its stages; None when there are none."""
    if plot is not None:
        pre = np.asarray(plot.psd_pre, dtype=np.float64)
        out = {"freq_hz": plot.freq_hz, "unit": "deg/s", "psd_pre": pre.sum(axis=0)}
        for post, name in ((plot.psd_logged, "logged"), (plot.psd_recommended, "recommended")):
            post = np.asarray(post, dtype=np.float64)
            out[f"psd_post_{name}"] = post.sum(axis=0)
            with np.errstate(divide="ignore", invalid="ignore"):
                out[f"response_{name}"] = np.sqrt(np.where(pre[0] > 0, post[0] / pre[0], np.nan))
        return out
    stages = [st for st in filters.get("stages") or [] if st.get("path", "rate") == "rate"]
    rates = [s.rate_hz for s in streams if s.rate_hz]
    fs = filters.get("filter_rate_hz")
    if not stages or not fs or not rates:
        return None
    from gyrodenoise.flightlog.vehicle_filters import chain_response
    freq = np.linspace(0.0, min(fs, max(rates)) / 2.0, 512)
    return {"freq_hz": freq, "unit": "deg/s", "response_logged": np.abs(chain_response(stages, freq, fs))}


def _method_label(method, ar_order, form):
    """The filter as the plots' titles name it, with its form (as the summary does)."""
    label = f"{method}, AR({ar_order})" if method in ("shakf", "kf", "sh_classic") else method
    return f"{label}, {form}" if form else label


def _write_outputs(path, flight_log, out_dir, stem, plotter, csv, what, method, filter_kw, log,
                   link=None, review=None):
    """Every output file of a filtered log (plots queued first: a helper draws them
    while the rest is written); the report's fields on them (a telemetry log's
    signing counts from ``link``)."""
    streams = flight_log.gyro
    out_dir.mkdir(parents=True, exist_ok=True)
    _queue_plots_and_spectra(path, streams, out_dir, stem, plotter, what, method, filter_kw, review)
    out_log = out_dir / flight_log.format.filtered_name(path, stem)
    with atomic_path(out_log) as tmp:
        rep = flight_log.format.write_filtered(flight_log, tmp, link)
    rep["output_log"] = str(out_log)
    srep, restarts = _stream_reports(path, streams, out_dir, stem, csv, plotter, log, review)
    rep.update(streams=srep, restarts=restarts)
    if log:
        log_problems(dict(rep, file=str(path)), log)
        signing_problems(dict(rep, file=str(path)), log)
    return rep


def _queue_plots_and_spectra(path, streams, out_dir, stem, plotter, what, method, filter_kw, review=None):
    """Queue each stream's plot (the flight segments shaded), compute its spectrum
    (``s._spectrum``, over the samples of ``review.stream_mask``: flying time by
    default) and queue the log's spectrum figure; ``s._png`` / ``s._spectrum_png``:
    where the plots go; ``s._spectrum_plot``: the spectrum's plot data."""
    segments = [s.to_fields() for s in review.segments] if review is not None else None
    axis = review.fields["time_base"]["axis"] if review is not None else BOOT_AXIS
    spec_items = []
    spec_png = out_dir / f"{stem}.spectrum.png"
    for s in streams:
        x, f, unit, rate = s._work
        if plotter is not None:                  # queued first: the helper draws while we go on
            s._png = out_dir / f"{stem}.{safe_name(s.name)}.png"
            cutoff = f" {s.cutoff_hz:.4g} Hz" if getattr(s, "cutoff_hz", None) else ""
            plotter.plot(s._png, f"{path.name}: {s.name} ({what}{cutoff}{title_note(s)})",
                         s.time_s, x, f, s.restarts, unit, s.axes, segments=segments, axis=axis)
        usable = (usable_samples(x) & np.isfinite(f)).all(axis=1)
        over = None
        if review is not None:
            s._figures_mask, over = review.stream_mask(s.time_s, s.sample_records)
            usable &= s._figures_mask
        s._spectrum, spec_plot = stream_spectrum(s, x, f, unit, rate, method, filter_kw,
                                                 getattr(s, "warmup_samples", 0),
                                                 joined_time(s.time_s, s.restarts), usable)
        if over is not None:
            s._spectrum["over"] = over
        s._spectrum_plot = spec_plot
        if spec_plot is not None:
            spec_items.append((s.name, spec_plot))
            s._spectrum_png = spec_png if plotter is not None else None
    if plotter is not None and spec_items:
        plotter.plot_spectrum(spec_png, f"{path.name}: spectrum ({what})", spec_items)


def _stream_reports(path, streams, out_dir, stem, csv, plotter, log, review=None):
    """(the stream reports, the restart events of all streams); writes the CSVs. The
    noise figures are over the samples of ``review.stream_mask`` (flying time by
    default; ``noise_over`` says which)."""
    srep, restarts = [], []
    for s in streams:
        x, f, unit, _ = s._work
        csv_path = png_path = None
        if csv:
            csv_path = out_dir / f"{stem}.{safe_name(s.name)}.csv"
            write_csv(csv_path, s, x, f, unit)
        if plotter is not None:
            png_path = s._png
        keep = getattr(s, "_figures_mask", None)
        srep.append(stream_report(s, csv_path, png_path, keep=keep))
        if review is not None:
            srep[-1]["noise_over"] = (OVER_FLYING if keep is not None and not keep.all()
                                      and "noise_over_note" not in srep[-1] else "whole log")
        srep[-1]["spectrum"] = s._spectrum
        if getattr(s, "_spectrum_png", None) is not None:
            srep[-1]["spectrum_plot"] = str(s._spectrum_png)
        restarts += s.restart_events
        if s.to_deg_s is None and log:
            log(f"{path}: {s.name}: unit unknown, filtered in {s.unit} ({s.note})")
    return srep, restarts


def process_log_task(task):
    """Run one log task ``(path, out_dir, process_log keywords)``: ``{"ok": True,
    "report": ...}``, or ``{"ok": False, "file", "error"}`` with the one-line reason
    (and the option a log refused, with its rates): one bad log never stops a batch."""
    path, out_dir, kw = task
    try:
        return {"ok": True, "report": process_log(path, out_dir, **kw)}
    except InputError as exc:
        res = {"ok": False, "file": str(path), "error": str(exc)}
        if getattr(exc, "option", None):            # the option the log refused (e.g. --cutoff-hz)
            res["option"] = exc.option
            res["rates_hz"] = list(getattr(exc, "rates_hz", []))
        return res
    except Exception as exc:  # noqa: BLE001 - one bad log must not stop the others
        return {"ok": False, "file": str(path), "error": f"{path}: {type(exc).__name__}: {exc}"}
