"""One self-contained interactive HTML report per log, and one per fleet (plotly).

What ArduPilot's Filter Review and PX4's Flight Review give an engineer, from the
bridge's own report: zoom, hover and legend toggles on every plot, in one file
that opens offline (plotly.js is inlined once; no CDN, no web font, no request), or,
for a folder of pages, one copy of plotly.js beside them that each page refers to
(:class:`PlotlyScript`, :func:`write_shared_plotlyjs`).

:func:`write_log_report` draws, per section, whatever part of the report exists
(the keys come from several steps of the bridge; a missing one is skipped, a
``*_note`` key is shown where its section has none):

* the summary: file, format, method and form, streams, restarts, noise figures,
  flying time (from ``segments``);
* per stream the time series per axis: raw (lighter, drawn above) and filtered,
  both toggleable, the vehicle's own rate estimate beside them when given, restarts
  as dashed red lines, the flight segments (``report["segments"]``) shaded;
* per stream the spectrum: raw and filtered PSD per axis, the peaks marked (hover
  names them), the vehicle's filter response (``report["vehicle_filters"]``) and
  the recommended one (``report["filter_review"]``) on a second axis; a spectrogram;
* motors, throttle, vibration levels (their cited thresholds drawn) and clipping against
  time, and the events, mode changes and failsafes marked on every time axis
  (``series["views"]``: :func:`gyrodenoise.flightlog.timeseries.flight_views`);
* the frequency-by-throttle (and by-RPM) maps with the notch centres drawn
  (:mod:`gyrodenoise.flightlog.heatmap`);
* the filter review: its figures, the recommended parameters and the lines to paste;
* vibration levels per segment against their thresholds (``report["vibration"]``).

Long series are reduced to a min/max envelope per bin (:data:`ENVELOPE_BINS` bins
a trace, each session on its own): what a screen shows anyway, and a 10-minute
400 Hz log stays a few MB (plotly.js itself is ~4.7 MB of it).
"""

from __future__ import annotations

import datetime
import html
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrodenoise.core.sessions import sessions
from gyrodenoise.flightlog.stopping import atomic_path

#: bins of a long trace's min/max envelope (two points a bin)
ENVELOPE_BINS = 1500
#: shading of the flight segments on the time plots (kind -> colour)
SEGMENT_COLOURS = {"ground": "rgba(150,150,150,0.18)", "armed": "rgba(255,190,0,0.18)",
                   "flying": "rgba(0,170,80,0.14)", "hover": "rgba(0,120,255,0.14)",
                   "after impact": "rgba(220,0,0,0.16)"}
#: per axis: (filtered colour, raw colour: the same hue, lighter)
AXIS_COLOURS = (("#1f4fb4", "#9db8ee"), ("#d9650b", "#f7c08f"), ("#218a3a", "#9fd9a9"),
                ("#7b3fa0", "#cfb0e3"))
VEHICLE_RATE_COLOUR = "#222222"
#: the vehicle's further rate lines (e.g. ArduPilot's desired rate beside its measured one): colour, dash
VEHICLE_RATE_STYLES = ((VEHICLE_RATE_COLOUR, "dot"), ("#b15928", "dash"), ("#6a3d9a", "dashdot"))
#: plotly's config on every plot: hover, zoom, pan and the modebar, no link to plotly's site
PLOT_CONFIG = {"displaylogo": False, "responsive": True, "scrollZoom": False,
               "toImageButtonOptions": {"format": "png", "scale": 2}}
#: plotly's template of every plot
TEMPLATE = "plotly_white"
#: no web font: the browser's own sans-serif
FONT = "DejaVu Sans, Arial, Helvetica, sans-serif"

CSS = """
body{font-family:DejaVu Sans,Arial,Helvetica,sans-serif;margin:0 auto;max-width:1400px;padding:0 16px 40px;
color:#222;font-size:14px}
h1{font-size:22px;margin:16px 0 4px}h2{font-size:18px;margin:28px 0 6px;border-bottom:1px solid #ccc}
h3{font-size:15px;margin:18px 0 4px}h4{font-size:14px;margin:12px 0 4px}
table.inner{margin:0;font-size:12px}table.inner td{border-color:#e2e2e2}
table{border-collapse:collapse;margin:6px 0 10px;font-size:13px}
td,th{border:1px solid #ccc;padding:3px 7px;text-align:left;vertical-align:top}
th{background:#f2f2f2}td.num{text-align:right;font-variant-numeric:tabular-nums}
.note{color:#555;font-style:italic;margin:4px 0}.warn{color:#a15c00}.fail{color:#b00020;font-weight:bold}
.pass{color:#1a7f37;font-weight:bold}.plot{width:100%;min-height:300px}
.change{color:#0b5cad;font-weight:bold}.verdict.none{color:#555}
div.tbl{max-width:100%;overflow-x:auto}td{overflow-wrap:break-word;max-width:60em}
pre{background:#f6f6f6;padding:8px;border:1px solid #ddd;overflow-x:auto}
nav a{margin-right:12px}.small{font-size:12px;color:#555}
"""


# ------------------------------------------------------------------ data helpers
def envelope(t, y, nbins=ENVELOPE_BINS):
    """(t, y) of a line reduced to its min and max per bin, in time order (both
    arrays ``nbins * 2`` long at most; the input as it is when it is short). A
    bin whose samples are all NaN keeps a NaN (a gap in the line)."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = len(y)
    if n <= 2 * nbins:
        return t, y
    m = int(math.ceil(n / nbins))
    nb = int(math.ceil(n / m))
    pad = nb * m - n
    yy = np.concatenate([y, np.full(pad, np.nan)]).reshape(nb, m)
    fin = np.isfinite(yy)
    imin = np.where(fin, yy, np.inf).argmin(axis=1)
    imax = np.where(fin, yy, -np.inf).argmax(axis=1)
    base = np.arange(nb) * m
    idx = np.column_stack([np.minimum(imin, imax), np.maximum(imin, imax)]) + base[:, None]
    idx = np.minimum(idx.ravel(), n - 1)
    out = y[idx].copy()
    out[~np.repeat(fin.any(axis=1), 2)] = np.nan
    return t[idx], out


def session_envelope(t, y, restarts, nbins=ENVELOPE_BINS):
    """:func:`envelope` of each session (cut at ``restarts``, bool per sample) with a
    NaN between them, so that no line is drawn across a restart; about ``nbins``
    bins over the whole record."""
    t = np.asarray(t, dtype=np.float64)
    n = len(t)
    ts, ys = [], []
    for a, b in sessions(n, restarts):
        tb, yb = envelope(t[a:b], y[a:b], max(1, int(round(nbins * (b - a) / max(n, 1)))))
        if ts:
            ts.append(np.array([np.nan]))
            ys.append(np.array([np.nan]))
        ts.append(tb)
        ys.append(yb)
    if not ts:
        return t, np.asarray(y, dtype=np.float64)
    return np.concatenate(ts), np.concatenate(ys)


def _restart_mask(restarts, n):
    """Bool (n,) from a bool mask or a list of sample indices (None: no restart)."""
    mask = np.zeros(n, dtype=bool)
    if restarts is None:
        return mask
    r = np.asarray(restarts)
    if r.dtype == bool and len(r) == n:
        return r.copy()
    idx = r.astype(np.int64)
    mask[idx[(idx >= 0) & (idx < n)]] = True
    return mask


def stream_series(s, filtered_label="filtered", vehicle_rate=None):
    """The ``series["streams"]`` entry of a processed :class:`GyroStream` (its
    ``_work`` arrays: raw and filtered in the unit the filter worked in): a dict of
    :func:`write_log_report`'s stream shape. A stream written raw (too slow, or
    refused with a reason) gets ``filtered=None`` and its reason, so that no plot
    calls its raw samples "filtered"."""
    from gyrodenoise.analysis import motion_metrics as mm
    x, f, unit, _ = s._work
    raw_reason = ("too slow to denoise: written raw" if mm.too_slow_to_denoise(s.rate_hz)
                  else getattr(s, "not_filtered", None) or getattr(s, "left_raw", None))
    return {"name": s.name, "time_s": s.time_s, "raw": x, "filtered": None if raw_reason else f,
            "unit": unit, "axes": tuple(s.axes), "restarts": s.restarts,
            "filtered_label": filtered_label, "raw_reason": raw_reason}


def series_of_streams(streams, filtered_label="filtered", spectra=None, vehicle_rate=None):
    """The ``series`` of :func:`write_log_report` from a log's processed streams
    (after :func:`gyrodenoise.flightlog.filtering.filter_streams`), their spectrum plot
    data ``{name: plot data of gyrodenoise.flightlog.spectra.stream_spectrum}`` and the
    vehicle's rate estimate (``[{"name", "time_s", "rate", "unit"}]``)."""
    return {"streams": [stream_series(s, filtered_label) for s in streams],
            "spectra": dict(spectra or {}), "vehicle_rate": list(vehicle_rate or [])}


def _f(v, spec=".3g"):
    """A number as text ('' for None, 'NaN' for a non-finite one)."""
    if v is None:
        return ""
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return format(float(v), spec) if math.isfinite(v) else "NaN"
    return str(v)


def _e(v):
    return html.escape(str(v), quote=True)


def _table(rows, head=None, cls=""):
    """HTML table of rows (lists of cell texts, already escaped where they hold HTML), in
    a box that scrolls sideways when the table is wider than the window."""
    out = [f'<div class="tbl"><table class="{cls}">']
    if head:
        out.append("<tr>" + "".join(f"<th>{_e(h)}</th>" for h in head) + "</tr>")
    for r in rows:
        out.append("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>")
    out.append("</table></div>")
    return "".join(out)


def _value_html(v, depth=0):
    """A report value as HTML, whole: a number or text escaped, a dict as a nested
    key/value table, a list of scalars comma-separated, a list of dicts or texts as
    lines; nothing is cut."""
    if isinstance(v, dict):
        if not v:
            return ""
        if depth >= 3:
            return _e(json.dumps(v, default=_json_default))
        return _table([[_e(k), _value_html(x, depth + 1)] for k, x in v.items()], cls="inner")
    if isinstance(v, (list, tuple, np.ndarray)):
        items = list(v)
        if all(not isinstance(x, (dict, list, tuple)) for x in items) and sum(len(_f(x)) for x in items) < 120:
            return _e(", ".join(_f(x) for x in items))
        return "<ul>" + "".join(f"<li>{_value_html(x, depth + 1)}</li>" for x in items) + "</ul>"
    return _link(v) if isinstance(v, str) and v.startswith(("http://", "https://")) else _e(_f(v))


def _link(url):
    """An http(s) address as a link (any other text escaped; '' for None)."""
    if not url:
        return ""
    u = str(url)
    if u.startswith(("http://", "https://")):
        return f"<a href='{_e(u)}'>{_e(u)}</a>"
    return _e(u)


def _kv_table(d, skip=()):
    """Key/value table of a dict's entries (nested dicts and lists rendered whole by
    :func:`_value_html`, never cut)."""
    rows = [[_e(k), _value_html(v)] for k, v in d.items() if k not in skip and not str(k).startswith("_")]
    return _table(rows, ["key", "value"]) if rows else ""


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    return str(o)


def _note(text):
    return f'<p class="note">{_e(text)}</p>'


def _notes_for(report, *keys):
    """The ``*_note`` texts of a report for sections ``keys`` (e.g. ``vibration`` ->
    ``vibration_note``), as HTML paragraphs."""
    return "".join(_note(f"{k}: {report[k + '_note']}") for k in keys if report.get(k + "_note"))


# ------------------------------------------------------------------ figures
class _Figures:
    """Collects the plot divs of one page (plotly.js goes once into the page's head).

    Used as a context manager around a page's figures: plotly's default template is
    off while they are built (each figure would otherwise copy and validate the whole
    default template when it is made, and again when :data:`TEMPLATE` replaces it),
    and :data:`TEMPLATE` goes into each figure's JSON as it is written, taken once a
    page (the same JSON as ``update_layout(template=TEMPLATE)`` gives)."""

    def __init__(self):
        self.n = 0
        self.template = None
        self._default = None

    def __enter__(self):
        import plotly.io as pio
        self._default = pio.templates.default
        pio.templates.default = None
        self.template = pio.templates[TEMPLATE].to_plotly_json()
        return self

    def __exit__(self, *exc):
        import plotly.io as pio
        pio.templates.default = self._default
        return False

    def div(self, fig, height=None):
        """The figure as a ``<div class="plot">`` with its script (no plotly.js)."""
        import plotly.io as pio
        self.n += 1
        top = fig.layout.margin.t
        fig.update_layout(font={"family": FONT, "size": 12},
                          margin={"l": 70, "r": 30, "t": top if top is not None else 50, "b": 50})
        if height:
            fig.update_layout(height=height)
        if self.template is None:           # outside a ``with``
            self.template = pio.templates[TEMPLATE].to_plotly_json()
        spec = fig.to_dict()
        spec["layout"]["template"] = self.template
        return '<div class="plot">' + pio.to_html(spec, validate=False, include_plotlyjs=False, full_html=False,
                                                 config=PLOT_CONFIG, div_id=f"plot{self.n}",
                                                 default_width="100%",
                                                 default_height=f"{height or 450}px") + "</div>"


def _shade_segments(fig, segments, rows, t_lo, t_hi, legend="legend"):
    """Shade each flight segment (kind -> :data:`SEGMENT_COLOURS`) behind the lines of
    ``rows`` subplots; one legend entry per kind (a clickable, empty trace)."""
    kinds, shapes = [], []
    for seg in segments or []:
        try:
            a, b, kind = float(seg["start_s"]), float(seg["end_s"]), str(seg["kind"])
        except (KeyError, TypeError, ValueError):
            continue
        if b < t_lo or a > t_hi:
            continue
        colour = SEGMENT_COLOURS.get(kind, "rgba(200,0,200,0.12)")
        for r in range(1, rows + 1):
            # the shapes of add_vrect, set at once: add_vrect per shape re-validates every
            # shape already there (quadratic: 108 shapes took seconds)
            ax = "" if r == 1 else str(r)
            shapes.append({"type": "rect", "x0": a, "x1": b, "xref": f"x{ax}", "y0": 0, "y1": 1,
                           "yref": f"y{ax} domain", "fillcolor": colour, "line": {"width": 0}, "layer": "below"})
        if kind not in kinds:
            kinds.append(kind)
    if shapes:
        fig.update_layout(shapes=list(fig.layout.shapes or ()) + shapes)
    import plotly.graph_objects as go
    for kind in kinds:
        fig.add_trace(go.Scatter(_validate=False, x=[None], y=[None], mode="markers", name=f"segment: {kind}",
                                 marker={"symbol": "square", "size": 12,
                                         "color": SEGMENT_COLOURS.get(kind, "rgba(200,0,200,0.3)")},
                                 legendgroup="segments", legend=legend), row=1, col=1)


def armed_mask(time_s, segments):
    """Bool per sample: inside an ``armed``, ``flying`` or ``hover`` segment."""
    t = np.asarray(time_s, dtype=np.float64)
    m = np.zeros(len(t), dtype=bool)
    for g in segments or []:
        try:
            if g["kind"] in ("armed", "flying", "hover"):
                m |= (t >= float(g["start_s"])) & (t <= float(g["end_s"]))
        except (KeyError, TypeError, ValueError):
            continue
    return m


def _is_target(vehicle_rate):
    """True for a rate controller's target (ArduPilot's ``RATE`` desired rates)."""
    return "desired" in str(vehicle_rate.get("name", "")).lower()


def _time_figure(st, vehicle_rates, segments, title, axis="boot time [s]", markers=()):
    """Per axis raw (light, above) and filtered, the vehicle's own rate, restarts and
    the segments: one plotly figure, subplots sharing the time axis."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots
    from gyrodenoise.flightlog.plotting import Y_CLIPPED_NOTE, flying_mask, plot_time, robust_ylim
    t = np.asarray(st["time_s"], dtype=np.float64)
    raw = np.atleast_2d(np.asarray(st["raw"], dtype=np.float64).T).T
    filt = st.get("filtered")
    filt = None if filt is None else np.atleast_2d(np.asarray(filt, dtype=np.float64).T).T
    axes = list(st.get("axes") or ["x", "y", "z"][:raw.shape[1]])
    unit = st.get("unit", "")
    restarts = _restart_mask(st.get("restarts"), len(t))
    pt, xlabel = plot_time(t, restarts, axis)
    boot_time = pt is t or np.array_equal(pt, t)
    fig = make_subplots(rows=len(axes), cols=1, shared_xaxes=True, vertical_spacing=0.04)
    label = st.get("filtered_label") or "filtered"
    for k, a in enumerate(axes):
        dark, light = AXIS_COLOURS[k % len(AXIS_COLOURS)]
        first = k == 0
        if filt is not None:
            tx, fy = session_envelope(pt, filt[:, k], restarts)
            fig.add_trace(go.Scatter(_validate=False, x=tx, y=fy.astype(np.float32), name=f"{label}", legendgroup="filtered",
                                       showlegend=first, line={"color": dark, "width": 1.3},
                                       hovertemplate=f"{a} {label}: %{{y:.4g}} {unit}<br>t=%{{x:.3f}} s<extra></extra>"),
                          row=k + 1, col=1)
        tx, ry = session_envelope(pt, raw[:, k], restarts)
        # a short legend name (a long reason ran the legend off the page): the reason
        # is in the title and the hover
        raw_name = "raw" if filt is not None else "raw (not filtered)"
        why = "" if filt is not None else f" (written raw: {_e(st.get('raw_reason') or 'not filtered')})"
        # raw is drawn after (above) the filtered line, lighter and half transparent: both show
        fig.add_trace(go.Scatter(_validate=False, x=tx, y=ry.astype(np.float32), name=raw_name, legendgroup="raw",
                                   showlegend=first, opacity=0.75 if filt is not None else 1.0,
                                   line={"color": light if filt is not None else dark, "width": 0.9},
                                   hovertemplate=f"{a} raw{why}: %{{y:.4g}} {unit}<br>t=%{{x:.3f}} s<extra></extra>"),
                      row=k + 1, col=1)
        for j, vr in enumerate(vehicle_rates):
            v_colour, v_dash = VEHICLE_RATE_STYLES[j % len(VEHICLE_RATE_STYLES)]
            vt = np.asarray(vr["time_s"], dtype=np.float64)
            rate = np.atleast_2d(np.asarray(vr["rate"], dtype=np.float64).T).T
            if k >= rate.shape[1] or not boot_time:
                continue
            vk = rate[:, k]
            vname = f"vehicle rate ({vr.get('name', '')})"
            if _is_target(vr) and segments:
                # a controller's target is meaningful only while armed: NaN (a gap) elsewhere
                vk = np.where(armed_mask(vt, segments), vk, np.nan)
                vname += " while armed"
            tx, vy = envelope(vt, vk)
            fig.add_trace(go.Scatter(_validate=False, x=tx, y=vy.astype(np.float32), name=vname, legendgroup=vname,
                                       showlegend=first, line={"color": v_colour, "width": 1.0, "dash": v_dash},
                                       hovertemplate=f"{a} {vname}: %{{y:.4g}} {vr.get('unit', unit)}"
                                                     f"<br>t=%{{x:.3f}} s<extra></extra>"),
                          row=k + 1, col=1)
        fig.update_yaxes(title_text=f"{a} [{unit}]", row=k + 1, col=1)
    rt = pt[restarts]
    if len(rt):
        # one trace of vertical lines per subplot (hover shows the restart's boot time)
        for k in range(len(axes)):
            yk = raw[:, k][np.isfinite(raw[:, k])]
            lo, hi = (float(yk.min()), float(yk.max())) if len(yk) else (0.0, 1.0)
            xs = np.repeat(rt, 3).astype(object)
            xs[2::3] = None
            ys = np.tile(np.array([lo, hi, None], dtype=object), len(rt))
            fig.add_trace(go.Scatter(_validate=False, x=xs, y=ys, mode="lines", name="restart", legendgroup="restart",
                                     showlegend=k == 0, line={"color": "#d62728", "dash": "dash", "width": 1},
                                     customdata=np.repeat(t[restarts], 3),
                                     hovertemplate="restart at boot time %{customdata:.3f} s<extra></extra>"),
                          row=k + 1, col=1)
    if segments and boot_time and len(pt):
        _shade_segments(fig, segments, len(axes), float(np.nanmin(pt)), float(np.nanmax(pt)))
    if markers and boot_time:
        _mark(fig, markers, [_span(raw[:, k]) for k in range(len(axes))])
    fig.update_xaxes(title_text=xlabel, row=len(axes), col=1)
    # the initial y range: the bulk of the (flying) samples, not a crash spike; the
    # modebar's autoscale (or a second double-click) shows everything
    keep = flying_mask(t, segments) if boot_time else None
    clipped = []
    for k, a in enumerate(axes):
        cols = [raw[:, k]] + ([filt[:, k]] if filt is not None and k < filt.shape[1] else [])
        lim = robust_ylim(np.column_stack(cols), keep)
        if lim is not None:
            fig.update_yaxes(range=list(lim), row=k + 1, col=1)
            clipped.append(a)
    if clipped:
        title = f"{title}; {Y_CLIPPED_NOTE} ({', '.join(clipped)}; autoscale in the modebar shows all)"
    # the title at the top, the legend between it and the plot
    fig.update_layout(title={"text": _e(title), "font": {"size": 14}, "y": 0.995, "yanchor": "top"},
                      hovermode="closest", margin={"t": 80},
                      legend={"orientation": "h", "yanchor": "bottom", "y": 1.01, "x": 0})
    note = "" if boot_time or not segments else "segments not shaded: the log's time goes backwards"
    return fig, note


def _psd_lists(pd):
    """(raw, filtered) PSDs per axis of a spectrum's plot data (either naming)."""
    raw = pd.get("raw", pd.get("psd_raw"))
    filt = pd.get("filtered", pd.get("psd_filtered"))
    return raw, filt


def _spectrum_figure(name, pd, responses, title):
    """PSD per axis (raw solid, filtered dashed), peaks marked; filter responses
    (``responses``: [(label, freq_hz, gain, dash, hover note)]) on a second y axis."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots
    fig = make_subplots(specs=[[{"secondary_y": True}]])
    fr = np.asarray(pd["freq_hz"], dtype=np.float64)
    sel = fr > 0
    raw, filt = _psd_lists(pd)
    unit = pd.get("unit", "")
    axes = list(pd.get("axes") or ["x", "y", "z"])
    same = pd.get("filtered_is_raw")
    for k, a in enumerate(axes):
        dark, light = AXIS_COLOURS[k % len(AXIS_COLOURS)]
        if raw is not None and k < len(raw) and raw[k] is not None:
            fig.add_trace(go.Scatter(_validate=False, x=fr[sel], y=np.asarray(raw[k])[sel], name=f"{a} raw", legendgroup=a,
                                     line={"color": dark, "width": 1.2},
                                     hovertemplate=f"{a} raw: %{{y:.3g}} ({unit})²/Hz at %{{x:.4g}} Hz<extra></extra>"),
                          secondary_y=False)
        if filt is not None and not same and k < len(filt) and filt[k] is not None:
            fig.add_trace(go.Scatter(_validate=False, x=fr[sel], y=np.asarray(filt[k])[sel], name=f"{a} filtered", legendgroup=a,
                                     line={"color": dark, "width": 1.2, "dash": "dash"}, opacity=0.75,
                                     hovertemplate=f"{a} filtered: %{{y:.3g}} ({unit})²/Hz at %{{x:.4g}} Hz"
                                                   f"<extra></extra>"),
                          secondary_y=False)
        peaks = (pd.get("peaks") or [[]] * len(axes))[k] if k < len(pd.get("peaks") or []) else []
        if peaks and raw is not None:
            px = [q["freq_hz"] for q in peaks]
            py = [float(np.asarray(raw[k])[int(np.argmin(np.abs(fr - f)))]) for f in px]
            txt = [_peak_hover(q, unit) for q in peaks]
            fig.add_trace(go.Scatter(_validate=False, x=px, y=py, mode="markers", name=f"{a} peaks", legendgroup=a,
                                     marker={"symbol": "triangle-down", "size": 11, "color": dark,
                                             "line": {"color": "black", "width": 1}},
                                     text=txt, hovertemplate="%{text}<extra></extra>"), secondary_y=False)
        humps = (pd.get("humps") or [])[k] if k < len(pd.get("humps") or []) else []
        if humps and raw is not None:
            fig.add_trace(_hump_trace(a, dark, fr, np.asarray(raw[k], dtype=np.float64), humps, unit), secondary_y=False)
    for label, rf, gain, dash, *more in responses:
        hover = _e(label + (f"; {more[0]}" if more and more[0] else ""))
        rf = np.asarray(rf, dtype=np.float64)
        ok = rf > 0
        fig.add_trace(go.Scatter(_validate=False, x=rf[ok], y=np.asarray(gain, dtype=np.float64)[ok], name=label,
                                 line={"color": "#555" if dash == "solid" else "#c2185b", "width": 1.6, "dash": dash},
                                 hovertemplate=f"{hover}: |H| %{{y:.3f}} at %{{x:.4g}} Hz<extra></extra>"),
                      secondary_y=True)
    fig.update_yaxes(type="log", title_text=f"PSD [({unit})²/Hz]", secondary_y=False,
                     range=_log_range([v for v in (raw or []) if v is not None], sel))
    fig.update_yaxes(title_text="filter gain |H|", range=[0, 1.3], secondary_y=True, showgrid=False,
                     visible=bool(responses), tickmode="array", tickvals=[0, 0.25, 0.5, 0.707, 1.0])
    log_x = str(name).startswith("ISB.")          # the batch sampler: kHz wide, its motion band at a few Hz
    fig.update_xaxes(title_text="frequency [Hz]", type="log" if log_x else "linear")
    fig.update_layout(updatemenus=[_frequency_axis_menu(log_x)])
    fig.update_layout(title={"text": _e(title), "font": {"size": 14}}, hovermode="closest",
                      legend={"orientation": "v", "x": 1.06, "y": 1})
    return fig


def _hump_trace(axis, colour, fr, raw, humps, unit):
    """A spectrum's broad humps on one axis (:func:`gyrodenoise.flightlog.spectra.find_humps`):
    a thick bar over each band (lo..hi Hz) just above the PSD's top there, hover naming it."""
    import plotly.graph_objects as go
    from gyrodenoise.flightlog.spectra import describe_hump
    xs, ys, txt = [], [], []
    for q in humps:
        band = (fr >= q["lo_hz"]) & (fr <= q["hi_hz"])
        top = 1.6 * float(np.max(raw[band])) if band.any() else float("nan")
        xs += [q["lo_hz"], q["freq_hz"], q["hi_hz"], None]
        ys += [top, top, top, None]
        txt += [_e(f"{axis}: " + describe_hump(q, unit))] * 3 + [""]
    return go.Scatter(_validate=False, x=xs, y=ys, mode="lines", name=f"{axis} humps", legendgroup=axis,
                      line={"color": colour, "width": 5}, opacity=0.55, text=txt,
                      hovertemplate="%{text}<extra></extra>")


def _frequency_axis_menu(log_x):
    """Plotly buttons switching a spectrum's frequency axis between linear and log
    (the active one first as ``log_x`` says)."""
    buttons = [{"label": "log frequency", "method": "relayout", "args": [{"xaxis.type": "log"}]},
               {"label": "linear frequency", "method": "relayout", "args": [{"xaxis.type": "linear"}]}]
    # under the legend, in the column right of the plot: above the plot they covered long titles
    return {"type": "buttons", "direction": "down", "x": 1.06, "xanchor": "left", "y": 0, "yanchor": "bottom",
            "showactive": True, "active": 0 if log_x else 1, "buttons": buttons, "font": {"size": 11}}


def _log_range(curves, sel, decades_below=3.0):
    """A log axis' range [log10 lo, log10 hi]: the curves' span and ``decades_below``
    decades under their lowest value (a steep filter's output would otherwise take
    the axis down to 1e-70), or None (plotly's own) without a positive value."""
    vals = [np.asarray(c, dtype=np.float64)[sel] for c in curves]
    vals = np.concatenate(vals) if vals else np.zeros(0)
    vals = vals[np.isfinite(vals) & (vals > 0)]
    if not len(vals):
        return None
    return [math.log10(float(vals.min())) - decades_below, math.log10(float(vals.max())) + 0.5]


def _peak_hover(q, unit):
    from gyrodenoise.flightlog.spectra import describe_peak
    try:
        text = describe_peak(q, unit)
    except (KeyError, TypeError, ValueError):
        text = f"{q.get('freq_hz')} Hz"
    if q.get("filter_gain") is not None:
        text += f", filter gain {q['filter_gain']:.2f}"
    return _e(text)


def _spectrogram_figure(name, pd, track=None):
    """The spectrogram (dB) of a stream's raw record with its colour bar and unit; the
    dynamic notch's logged centre over it (``track``: the strategy's ``notch_centre_track``,
    one boot's time axis), where given."""
    import plotly.graph_objects as go
    t, dens = pd["spectrogram"]
    fr = np.asarray(pd["freq_hz"], dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        db = 10.0 * np.log10(np.where(np.asarray(dens) > 0, dens, np.nan))
    lo, hi = np.nanpercentile(db, [5, 99.5]) if np.isfinite(db).any() else (0.0, 1.0)
    step = max(1, int(math.ceil(db.shape[0] / 600)))          # at most ~600 columns
    unit = pd.get("unit", "")
    fig = go.Figure(go.Heatmap(_validate=False, x=np.asarray(t)[::step], y=fr, z=db[::step].T.astype(np.float32),
                               zmin=lo, zmax=hi, colorscale="Viridis",
                               colorbar={"title": {"text": f"dB ({unit})²/Hz"}},
                               hovertemplate="t=%{x:.1f} s, %{y:.4g} Hz: %{z:.1f} dB<extra></extra>"))
    if track is not None:
        from gyrodenoise.flightlog.heatmap import track_centre_hz
        tt = np.asarray(track.time_s, np.float64)
        f = track_centre_hz(track)
        # within the spectrogram's time and frequency span: a 25 Hz stream's spectrogram ends
        # at 12.5 Hz, under any notch; the track would only stretch its frequency axis
        keep = np.isfinite(f) & (tt >= float(np.min(t))) & (tt <= float(np.max(t))) & (f <= float(fr[-1]))
        if keep.any():
            tx, fy = session_envelope(tt[keep], f[keep], _boot_cuts(track)[keep])
            fig.add_trace(go.Scatter(_validate=False, x=tx, y=fy.astype(np.float32), mode="lines",
                                     name=_e(f"logged notch centre ({track.source})"),
                                     line={"color": "#ffffff", "width": 1.5, "dash": "dot"},
                                     hovertemplate="notch centre %{y:.4g} Hz at t=%{x:.1f} s<extra></extra>"))
            fig.update_layout(legend={"orientation": "h", "yanchor": "top", "y": -0.2, "x": 0})
    fig.update_layout(title={"text": _e(f"{name}: spectrogram of the raw record (axes summed)"), "font": {"size": 14}})
    fig.update_xaxes(title_text="time [s]")
    fig.update_yaxes(title_text="frequency [Hz]", range=[float(fr[0]), float(fr[-1])])
    return fig


# ------------------------------------------------------------------ motors, throttle, vibration; markers
#: marker kind -> (colour, dash) of its vertical lines (gyrodenoise.flightlog.timeseries)
MARKER_STYLES = {"event": ("#7f7f7f", "dot"), "mode": ("#1f77b4", "dash"), "failsafe": ("#d62728", "solid")}
#: threshold level -> colour of its horizontal line
THRESHOLD_COLOURS = {"warn": "#e69500", "fail": "#b00020"}
#: a panel's lines, cycling
PANEL_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                 "#bcbd22", "#17becf", "#393b79", "#637939")


def _views(series):
    """The :class:`gyrodenoise.flightlog.timeseries.FlightViews` of a series, or None."""
    return (series or {}).get("views")


def _markers(series):
    v = _views(series)
    return list(v.time.markers) if v is not None else []


def _span(y):
    """(lo, hi) of the finite values of ``y`` ((0, 1) without any)."""
    y = np.asarray(y, np.float64)
    y = y[np.isfinite(y)]
    return (float(y.min()), float(y.max())) if len(y) else (0.0, 1.0)


def _mark(fig, markers, spans, legend="legend"):
    """The markers as vertical lines across each subplot (``spans``: its (lo, hi)), one
    trace per kind and subplot, the text on hover; one legend entry per kind."""
    import plotly.graph_objects as go
    for kind, (colour, dash) in MARKER_STYLES.items():
        ms = [m for m in markers if m.kind == kind]
        if not ms:
            continue
        xs = np.repeat([m.time_s for m in ms], 3).astype(object)
        xs[2::3] = None
        text = np.repeat([_e(f"{m.text} (boot {m.boot}, t={m.time_s:.2f} s)") for m in ms], 3)
        for r, (lo, hi) in enumerate(spans):
            ys = np.tile(np.array([lo, hi, None], dtype=object), len(ms))
            fig.add_trace(go.Scatter(_validate=False, x=xs, y=ys, mode="lines", name=f"{kind}s", legendgroup=kind,
                                     showlegend=r == 0, legend=legend, line={"color": colour, "dash": dash, "width": 1},
                                     opacity=0.7, text=text, hovertemplate="%{text}<extra></extra>"),
                          row=r + 1, col=1)


def _boot_cuts(ch):
    """Bool per row: a row that starts another boot than the row before."""
    b = ch.boots()
    cut = np.zeros(len(b), bool)
    cut[1:] = b[1:] != b[:-1]
    return cut


def _panel_legend(fig, row):
    """The legend of subplot ``row`` of a one-column figure (plotly's ``legend``,
    ``legend2``, ...): beside the subplot, at its top, so that each panel lists its own
    lines; returns its name for the traces."""
    name = "legend" if row == 1 else f"legend{row}"
    dom = fig.layout[f"yaxis{'' if row == 1 else row}"].domain
    fig.update_layout({name: {"x": 1.02, "xanchor": "left", "y": dom[1], "yanchor": "top",
                              "font": {"size": 10}, "tracegroupgap": 2}})
    return name


def _panels_figure(views, segments, axis):
    """The time panels (motors, throttle, vibration levels with their thresholds,
    clipping) in one figure sharing its time axis, the markers across every panel,
    the flight segments shaded."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots
    panels = views.panels
    fig = make_subplots(rows=len(panels), cols=1, shared_xaxes=True, vertical_spacing=0.05,
                        subplot_titles=[_e(p.title) for p in panels])
    spans, t_lo, t_hi = [], np.inf, -np.inf
    for r, p in enumerate(panels, 1):
        leg = _panel_legend(fig, r)
        ch = p.channels
        t = np.asarray(ch.time_s, np.float64)
        cuts = _boot_cuts(ch)
        lo, hi = np.inf, -np.inf
        for j, (name, v) in enumerate(ch.columns.items()):
            v = np.asarray(v, np.float64)
            keep = np.isfinite(v)
            if not keep.any():
                continue
            tx, y = session_envelope(t[keep], v[keep], cuts[keep])
            a, b = _span(y)
            lo, hi = min(lo, a), max(hi, b)
            fig.add_trace(go.Scatter(_validate=False, x=tx, y=y.astype(np.float32), name=_e(name), legend=leg,
                                     legendgroup=p.key + name, line={"color": PANEL_COLOURS[j % len(PANEL_COLOURS)],
                                                                     "width": 1.1},
                                     hovertemplate=f"{_e(name)}: %{{y:.4g}} {_e(ch.unit)}<br>t=%{{x:.2f}} s"
                                                   "<extra></extra>"), row=r, col=1)
        if p.key == "pid" and len(t):
            # the initial y range as the gyro plots' (:func:`plotting.robust_ylim`): the bulk of
            # the flying samples, so a crash spike does not flatten the flight; autoscale shows all
            from gyrodenoise.flightlog.plotting import Y_CLIPPED_NOTE, flying_mask, robust_ylim
            lim = robust_ylim(np.column_stack([np.asarray(v, np.float64) for v in ch.columns.values()]),
                              flying_mask(t, segments))
            if lim is not None:
                fig.update_yaxes(range=list(lim), row=r, col=1)
                fig.layout.annotations[r - 1].text += _e(f"; {Y_CLIPPED_NOTE} (autoscale in the modebar shows all)")
                lo, hi = lim
        for th in p.thresholds:
            lo, hi = min(lo, th.value), max(hi, th.value)
            fig.add_trace(go.Scatter(_validate=False, x=[float(np.nanmin(t)), float(np.nanmax(t))],
                                     y=[th.value, th.value], mode="lines", name=f"{th.level} threshold",
                                     legendgroup=f"threshold {th.level}", legend=leg,
                                     line={"color": THRESHOLD_COLOURS.get(th.level, "#555"), "dash": "dash",
                                           "width": 1.5}, text=[_e(th.label)] * 2,
                                     hovertemplate="%{text}<extra></extra>"), row=r, col=1)
        if len(t):
            t_lo, t_hi = min(t_lo, float(np.nanmin(t))), max(t_hi, float(np.nanmax(t)))
        spans.append((lo, hi) if np.isfinite(lo) else (0.0, 1.0))
        fig.update_yaxes(title_text=_e(ch.unit), row=r, col=1)
    # the markers and segments span every panel: their own legend, in a row under the figure
    common = f"legend{len(panels) + 1}"
    fig.update_layout({common: {"orientation": "h", "x": 0, "xanchor": "left", "yref": "container", "y": 0,
                                "yanchor": "bottom", "font": {"size": 10}}})
    _mark(fig, views.markers, spans, common)
    if segments and np.isfinite(t_lo):
        _shade_segments(fig, segments, len(panels), t_lo, t_hi, common)
    fig.update_xaxes(title_text=axis, row=len(panels), col=1)
    fig.update_layout(hovermode="closest", margin={"t": 60, "b": 90})
    fig.update_annotations(font_size=12)
    return fig


def _flight_section(report, series, figs):
    """Motors, throttle, RC input, battery, vibration and clipping against time with the events, modes
    and failsafes marked (``series["views"]``: :func:`gyrodenoise.flightlog.timeseries.flight_views`)."""
    v = _views(series)
    out = ["<h2 id=flight>Motors, throttle, RC, battery and vibration</h2>"]
    if v is None:
        return "".join(out) + _note("not given (the log's time series were not read)")
    tv = v.time
    for p in tv.panels:
        if p.channels.note:
            out.append(_note(f"{p.key}: {p.channels.note}"))
    for key, why in tv.missing.items():
        out.append(_note(f"{key}: {why}"))
    if tv.panels:
        out.append(figs.div(_panels_figure(tv, report.get("segments"), _axis(report)),
                            height=140 + 190 * len(tv.panels)))
    if tv.markers:
        kinds = {k: sum(m.kind == k for m in tv.markers) for k in MARKER_STYLES}
        out.append(_note("marked on every time axis: " + ", ".join(f"{n} {k}s" for k, n in kinds.items() if n)
                         + " (hover a line for its text)"))
        rows = [[_e(f"{m.time_s:.2f}"), _e(m.boot), _e(m.kind), _e(m.text)] for m in tv.markers
                if m.kind != "event"] + [[_e(f"{m.time_s:.2f}"), _e(m.boot), _e(m.kind), _e(m.text)]
                                         for m in tv.markers if m.kind == "event"]
        out.append("<details><summary>events, modes and failsafes (" + str(len(rows)) + ")</summary>" +
                   _table(rows, ["time [s]", "boot", "kind", "text"]) + "</details>")
    else:
        out.append(_note("no event, mode change or failsafe in the log"))
    return "".join(out)


def _heatmap_figure(hm):
    """A frequency map: mean PSD (dB, axes summed) per throttle/RPM bin and frequency,
    the notch centres and harmonics as lines over it."""
    import plotly.graph_objects as go
    with np.errstate(divide="ignore", invalid="ignore"):
        db = 10.0 * np.log10(np.where(hm.psd > 0, hm.psd, np.nan))
    lo, hi = np.nanpercentile(db, [5, 99.5]) if np.isfinite(db).any() else (0.0, 1.0)
    x = hm.centres
    fig = go.Figure(go.Heatmap(_validate=False, x=x, y=hm.freq_hz, z=db.T.astype(np.float32), zmin=lo, zmax=hi,
                               colorscale="Viridis", colorbar={"title": {"text": "dB (deg/s)²/Hz"}, "x": 1.0},
                               customdata=np.tile(hm.windows, (len(hm.freq_hz), 1)),
                               hovertemplate=f"{_e(hm.x_label)} %{{x:.3g}}, %{{y:.4g}} Hz: %{{z:.1f}} dB "
                                             "(%{customdata} windows)<extra></extra>"))
    dashes = ("dash", "dot", "dashdot", "longdash")
    for j, ln in enumerate(hm.lines):
        fig.add_trace(go.Scatter(_validate=False, x=ln.x, y=ln.freq_hz, mode="lines", name=_e(ln.label),
                                 line={"color": "#ffffff" if "notch" in ln.label else "#ff5555",
                                       "dash": dashes[j % len(dashes)], "width": 1.8},
                                 hovertemplate=f"{_e(ln.label)}: %{{y:.4g}} Hz at %{{x:.3g}}<extra></extra>"))
    fig.update_xaxes(title_text=_e(f"{hm.x_label} ({hm.x_source})"), range=[float(hm.edges[0]), float(hm.edges[-1])])
    fig.update_yaxes(title_text="frequency [Hz]", range=[0, float(hm.freq_hz[-1])])
    fig.update_layout(title={"text": _e(f"{hm.stream}: PSD by {hm.x_label.split(' [')[0]} (axes summed; "
                                        f"{int(hm.windows.sum())} windows)"), "font": {"size": 14}},
                      legend={"orientation": "h", "yanchor": "top", "y": -0.18, "x": 0})
    return fig


def _heatmap_section(series, figs):
    """The frequency-by-throttle and frequency-by-RPM maps with the notch lines."""
    v = _views(series)
    if v is None:
        return ""
    out = ["<h2 id=maps>Frequency by throttle and RPM</h2>"]
    for hm in v.maps:
        out.append(figs.div(_heatmap_figure(hm), height=460))
        for n in hm.notes:
            out.append(_note(n))
        if not hm.lines:
            out.append(_note("no notch of the vehicle's chain is drawn: none that this map's x sets"))
    for n in v.map_notes:
        out.append(_note(n))
    return "".join(out)


# ------------------------------------------------------------------ the vehicle's filters
def vehicle_response(stages, freq_hz, rate_hz):
    """(gain |H| of the vehicle's chain of ``stages`` at ``freq_hz``, the stages not
    modelled): the autopilot's own biquads on the gyro rate path, the one model the
    filter review uses too (:func:`gyrodenoise.flightlog.vehicle_filters.chain_sections`);
    a stage it cannot run (a notch that follows a measurement, a cutoff at or above
    the Nyquist frequency, a kind it does not know) is left out and named."""
    from gyrodenoise.flightlog import vehicle_filters as vf
    sos, skipped = [], []
    for st in stages or []:
        if not isinstance(st, dict):
            continue
        try:
            got, notes = vf.chain_sections([st], rate_hz)
        except (KeyError, TypeError, ValueError):
            got, notes = [], ["not modelled"]
        if notes or (not got and st.get("path", "rate") == "rate"):
            skipped.append(str(st.get("kind")))
        sos += got
    return np.abs(vf.sos_response(sos, np.asarray(freq_hz, dtype=np.float64), rate_hz)), skipped


# ------------------------------------------------------------------ sections
#: the overview's identity rows (report key, label)
OVERVIEW_ROWS = (("vehicle", "vehicle"), ("firmware", "firmware"), ("board", "board"), ("frame", "frame"),
                 ("vehicle_id", "vehicle / board id"))


def _overview_section(report):
    """The first screen: the vehicle, its flight time per boot and one line per verdict
    with its reason (the report's ``overview``: :mod:`gyrodenoise.flightlog.overview`)."""
    ov = report.get("overview")
    if not ov:
        return ""
    rows = [[_e(label), _e(ov.get(key) if ov.get(key) is not None else "not in the log")]
            for key, label in OVERVIEW_ROWS]
    times = ov.get("flight_time_s") or []
    if times:
        per = ", ".join(f"boot {k}: {t or 0:.1f} s" for k, t in enumerate(times)) if len(times) > 1 else \
            f"{times[0] or 0:.1f} s"
        rows.append(["flight time", _e(per)])
    vrows = [[_e(v["topic"]), f'<span class="verdict {_e(v["verdict"] or "none")}">'
              f'{_e((v["verdict"] or "no verdict").upper())}</span>', _e(v["reason"])] for v in ov.get("verdicts") or []]
    return ("<h2 id=overview>Overview</h2>" + _table(rows, ["", "value"]) +
            _table(vrows, ["", "verdict", "reason"], cls="verdicts"))


def _ms(v):
    return "" if v is None else f"{v * 1000:.0f}"


def _replay_section(report):
    """The notch replay's agreement with the logged post-filter gyro (:mod:`gyrodenoise.flightlog.notch_replay`)."""
    from gyrodenoise.flightlog.notch_replay import replay_section_html
    return f"<div id='replay'>{replay_section_html(report, _e)}</div>"


def _inflight_noise_section(report):
    """Noise measured in flight against rest, and the EKF parameters it gives
    (:mod:`gyrodenoise.flightlog.inflight_noise`)."""
    nz = report.get("inflight_noise")
    if not nz:
        return (f"<section id='noise'><h2>Noise in flight</h2>"
                f"<p>{_e(report.get('inflight_noise_note') or 'not measured')}</p></section>")
    rows = [[_e(f["sensor"]), _e(f["stream"]), _e(f["stage"]), _f(f["flying"]["mean"]),
             _f((f.get("rest") or {}).get("mean")), _f(f.get("ratio")), _e(f["unit"])]
            for f in nz["gyro"] + nz["accel"]]
    rows += [[_e(f["sensor"]), _e(f["stream"]), _e(f["stage"]), "refused", "", "", _e(f["refused"])]
             for f in nz.get("refused", [])]
    ekf = [[_e(k), _f(v["value"]), _e(v["unit"]), _f(v.get("logged")), "yes" if v.get("clamped") else "",
            _e(v.get("from", ""))] for k, v in nz["ekf_parameters"].items()]
    return ("<section id='noise'><h2>Noise in flight</h2>"
            f"<p>{_e(nz['metric'])}; band {_e(nz['band'])}.</p>"
            + _table(rows, ["sensor", "stream", "stage", "flying", "rest", "flying / rest", "unit"])
            + ("<h3>EKF noise parameters for this flight</h3>"
               + _table(ekf, ["parameter", "value", "unit", "logged", "clamped to range", "from"]) if ekf else "")
            + (f"<p>{_e(nz['ekf_note'])}</p>" if nz.get("ekf_note") else "")
            + "</section>")


def _step_response_section(report, figs):
    """The rate loop's step response per axis (the report's ``step_response``: each axis'
    averaged ``curve``), its figures in a table; a note when there is none."""
    sr = report.get("step_response")
    out = ["<h2 id=step>Step response</h2>"]
    if not sr:
        if report.get("step_response_note"):
            out.append(_note(f"no step response: {report['step_response_note']}"))
        return "".join(out) if len(out) > 1 else ""
    import plotly.graph_objects as go
    fig = go.Figure()
    rows = []
    for k, (axis, f) in enumerate((sr.get("axes") or {}).items()):
        if not f:
            rows.append([_e(axis), "", "", "", "", "", _e("too little setpoint motion")])
            continue
        c = f.get("curve") or {}
        if c.get("time_s"):
            fig.add_trace(go.Scatter(x=[t * 1000 for t in c["time_s"]], y=c["response"], mode="lines", name=axis,
                                     line={"color": AXIS_COLOURS[k % len(AXIS_COLOURS)][0]},
                                     hovertemplate=f"{axis}: %{{y:.3f}} at %{{x:.0f}} ms<extra></extra>"))
        rows.append([_e(axis), _e(_ms(f.get("rise_time_s"))), _e(_ms(f.get("delay_s"))),
                     _e("" if f.get("overshoot_pct") is None else f"{f['overshoot_pct']:.0f}"),
                     _e(_f(f.get("final"), ".2f")), _e(f"{f.get('windows')} x {f.get('window_s'):g} s"),
                     _e(f.get("note") or "")])
    fig.add_hline(y=1.0, line={"color": "#888", "dash": "dot"})
    fig.update_layout(title={"text": _e(f"step response to a unit setpoint step ({sr.get('source')})"),
                             "font": {"size": 14}}, xaxis_title="time after the step [ms]",
                      yaxis_title="rate / setpoint step", hovermode="closest")
    out.append(figs.div(fig, height=380))
    out.append(_table(rows, ["axis", "rise 10-90 % [ms]", "delay to 50 % [ms]", "overshoot [%]", "final",
                             "windows", "note"]))
    out.append(_note(sr.get("method", "")))
    return "".join(out)


def _summary_section(report, series):
    rows = []
    for key in ("file", "format", "engine", "method", "ar_order", "form", "form_note", "output_log", "seconds"):
        if report.get(key) is not None:
            rows.append([_e(key), _e(_f(report[key]))])
    if report.get("filter_options"):
        rows.append(["filter_options", _e(json.dumps(report["filter_options"], default=_json_default))])
    streams = report.get("streams") or []
    rows.append(["streams", _e(", ".join(s.get("name", "?") for s in streams) or "none")])
    rows.append(["restarts", _e(len(report.get("restarts") or []))])
    flying = _flying_time_s(report)
    if flying is not None:
        rows.append(["flying time", _e(f"{flying:.1f} s")])
    elif report.get("segments_note"):
        rows.append(["flying time", _e(f"unknown ({report['segments_note']})")])
    base = report.get("time_base") or {}
    if base.get("kind") and base.get("kind") != "boot time":
        rows.append(["time base", _e(f"{base['kind']}: times from {base.get('offset_s')} s on that clock "
                                     f"({base.get('axis')})")])
    out = ["<h2 id=summary>Summary</h2>", _table(rows, ["", "value"])]
    srows = []
    for s in streams:
        noise = s.get("noise") or {}
        for a, nz in noise.items():
            nz = nz or {}
            srows.append([_e(s.get("name")), _e(a), f'<span class=num>{_e(_f(s.get("rate_hz"), ".4g"))}</span>',
                          _e(_f(s.get("samples"))), _e(_f(s.get("restarts"))),
                          _e(_f(nz.get("raw"))), _e(_f(nz.get("filtered"))), _e(_f(nz.get("ratio"), ".2f")),
                          _e(s.get("noise_unit", "")),
                          (f'<span class="warn">{_e(passed_through(s))}</span>; ' if passed_through(s) else "") +
                          _e(s.get("left_raw") or s.get("not_filtered") or s.get("slow_note") or s.get("note") or "")])
    if srows:
        out.append("<h3>Noise figures (white-noise sigma, the core's estimate)</h3>")
        out.append(_table(srows, ["stream", "axis", "rate [Hz]", "samples", "restarts", "noise raw",
                                  "noise filtered", "filtered/raw", "unit", "note"]))
    warnings = [w for s in streams for w in s.get("warnings", [])]
    if warnings:
        out.append("<ul>" + "".join(f'<li class="warn">{_e(w)}</li>' for w in warnings) + "</ul>")
    boots = report.get("boots") or []
    if len(boots) > 1:
        out.append("<h3>Boots</h3>" + _note(
            f"the file holds {len(boots)} boots: each has its own time axis, its segments and figures; no "
            "segment or figure spans two") + _table(
            [[_e(b.get("session")), _e(_f(b.get("start_s"), ".2f")), _e(_f(b.get("end_s"), ".2f")),
              _e((b.get("time_base") or {}).get("kind")), _e(_f(b.get("wall_clock_offset_s"))),
              _e(_f(b.get("flying_time_s"), ".1f")), _e(len([g for g in b.get("segments") or []
                                                          if g.get("kind") != "hover"]))] for b in boots],
            ["boot", "start [s]", "end [s]", "time base", "wall clock at 0 [Unix s]", "flying [s]", "segments"]))
    segs = report.get("segments")
    if segs:
        several = len(boots) > 1
        out.append("<h3>Segments</h3>" + _table(
            [([_e(g.get("session", 0))] if several else []) +
             [_e(g.get("kind")), _e(_f(g.get("start_s"), ".2f")), _e(_f(g.get("end_s"), ".2f")),
              _e(_f(_dur(g), ".1f"))] for g in segs],
            (["boot"] if several else []) + ["kind", "start [s]", "end [s]", "duration [s]"]))
    elif "segments" in report or report.get("segments_note"):
        out.append(_note("segments: none" + (f" ({report['segments_note']})" if report.get("segments_note") else "")))
    return "".join(out)


#: a filtered/raw noise ratio this close to 1 means the filter passed the signal through
PASSED_THROUGH_TOL = 0.02
#: what the page says of such a stream
PASSED_THROUGH_NOTE = "kept as motion: the filter passed the signal through"


def passed_through(stream_report):
    """The note for a filtered stream whose every axis has a filtered/raw noise ratio
    within :data:`PASSED_THROUGH_TOL` of 1 (the filter changed nothing: what it saw
    was kept as motion), with the ratios; '' otherwise (or when written raw)."""
    s = stream_report or {}
    if s.get("too_slow_to_denoise") or s.get("left_raw") or s.get("not_filtered"):
        return ""
    ratios = [(nz or {}).get("ratio") for nz in (s.get("noise") or {}).values()]
    ratios = [float(r) for r in ratios if isinstance(r, (int, float)) and math.isfinite(r)]
    if not ratios or any(abs(r - 1.0) > PASSED_THROUGH_TOL for r in ratios):
        return ""
    return f"{PASSED_THROUGH_NOTE} (filtered/raw noise {', '.join(f'{r:.2f}' for r in ratios)})"


def _dur(seg):
    try:
        return float(seg["end_s"]) - float(seg["start_s"])
    except (KeyError, TypeError, ValueError):
        return None


def _flying_time_s(report):
    """The log's flying time (``flying_time_s``, summed over its boots by
    :func:`gyrodenoise.flightlog.segments.flying_time_s`), or None without segments."""
    if not report.get("segments"):
        return None
    return report.get("flying_time_s")


#: streams written raw at or below this rate [Hz] share one compact plot (e.g. PX4's
#: 1 Hz sensor_gyro[n] in a ULog that logs them slowly)
SLOW_STREAM_HZ = 5.0


def _stream_rate_hz(st, stream_report):
    """A stream's rate [Hz]: the report's, else from its median sample interval (0 when unknown)."""
    r = (stream_report or {}).get("rate_hz")
    if r:
        return float(r)
    t = np.asarray(st.get("time_s"), dtype=np.float64)
    dt = np.diff(t[np.isfinite(t)]) if len(t) > 1 else np.array([])
    dt = dt[dt > 0]
    return float(1.0 / np.median(dt)) if len(dt) else 0.0


def _is_slow_raw(st, stream_report):
    """True for a stream written raw whose rate is at most :data:`SLOW_STREAM_HZ`."""
    return st.get("filtered") is None and 0 < _stream_rate_hz(st, stream_report) <= SLOW_STREAM_HZ


def _axis(report):
    """The x label of the log's time (its ``time_base``: boot time or a Unix epoch clock)."""
    return (report.get("time_base") or {}).get("axis") or "boot time [s]"


def _slow_figure(streams, axis="boot time [s]"):
    """The slow streams written raw in one figure: a subplot per axis, a line per stream."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots
    axes = ("x", "y", "z")
    fig = make_subplots(rows=3, cols=1, shared_xaxes=True, vertical_spacing=0.05)
    for j, st in enumerate(streams):
        colour = AXIS_COLOURS[j % len(AXIS_COLOURS)][0]
        raw = np.atleast_2d(np.asarray(st["raw"], dtype=np.float64).T).T
        t = np.asarray(st["time_s"], dtype=np.float64)
        restarts = _restart_mask(st.get("restarts"), len(t))
        for k in range(min(3, raw.shape[1])):
            tx, y = session_envelope(t, raw[:, k], restarts)
            fig.add_trace(go.Scatter(_validate=False, x=tx, y=y.astype(np.float32), name=st["name"],
                                     legendgroup=st["name"], showlegend=k == 0, mode="lines+markers",
                                     marker={"size": 3}, line={"color": colour, "width": 1},
                                     hovertemplate=f"{_e(st['name'])} {axes[k]}: %{{y:.4g}} {_e(st.get('unit', ''))}"
                                                   f"<br>t=%{{x:.1f}} s<extra></extra>"), row=k + 1, col=1)
            fig.update_yaxes(title_text=f"{axes[k]} [{_e(st.get('unit', ''))}]", row=k + 1, col=1)
    fig.update_xaxes(title_text=axis, row=3, col=1)
    fig.update_layout(title={"text": "slow streams, written raw (NOT FILTERED)", "font": {"size": 14},
                             "y": 0.995, "yanchor": "top"}, margin={"t": 70},
                      legend={"orientation": "h", "yanchor": "bottom", "y": 1.01, "x": 0})
    return fig


def _streams_section(report, series, figs):
    out = ["<h2 id=streams>Gyro streams</h2>"]
    sts = series.get("streams") or []
    if not sts:
        return "".join(out) + _note("no time series given")
    vrates = series.get("vehicle_rate") or []
    by_name = {s.get("name"): s for s in report.get("streams") or []}
    slow = [st for st in sts if _is_slow_raw(st, by_name.get(st["name"]))]
    if len(slow) > 1:
        out.append("<h3>Slow streams, written raw</h3>" + _note(
            "; ".join(f"{st['name']}: {st.get('raw_reason') or 'not filtered'}" for st in slow)))
        out.append(figs.div(_slow_figure(slow, _axis(report)), height=130 + 120 * 3))
    for st in sts:
        if len(slow) > 1 and any(st is x for x in slow):
            continue
        title = f"{st['name']}: raw and {st.get('filtered_label') or 'filtered'}"
        if st.get("filtered") is None:
            title = f"{st['name']}: written raw (NOT FILTERED: {st.get('raw_reason') or 'no filtered output'})"
        fig, note = _time_figure(st, vrates, report.get("segments"), title, _axis(report), _markers(series))
        out.append(f"<h3>{_e(st['name'])}</h3>")
        if note:
            out.append(_note(note))
        if st.get("filtered") is not None and passed_through(by_name.get(st["name"])):
            out.append(f'<p class="warn">{_e(passed_through(by_name.get(st["name"])))}</p>')
        out.append(figs.div(fig, height=180 + 170 * len(st.get("axes") or "xyz")))
    if not vrates:
        out.append(_note("the vehicle's own rate estimate (ArduPilot RATE, PX4 vehicle_angular_velocity) "
                         "was not given"))
    return "".join(out)


def _responses_for(report, series, rate_hz):
    """[(label, freq_hz, gain, dash, hover note)] of the vehicle's filters and the
    recommended ones (the label short, for the legend; what is not modelled in the note)."""
    out = []
    fr_rev = series.get("filter_review") or {}
    for key, label, dash in (("response_logged", "vehicle's filters (logged)", "solid"),
                             ("response_recommended", "recommended settings", "dash")):
        if fr_rev.get(key) is not None and fr_rev.get("freq_hz") is not None:
            out.append((label, fr_rev["freq_hz"], fr_rev[key], dash, ""))
    if out:
        return out
    vf = report.get("vehicle_filters") or {}
    stages = vf.get("stages") or []
    if stages and rate_hz:
        freq = np.linspace(0, rate_hz / 2.0, 512)
        g, skipped = vehicle_response(stages, freq, rate_hz)
        label = "vehicle's filters (logged)" + (" *" if skipped else "")
        out.append((label, freq, g, "solid", f"* not modelled: {', '.join(skipped)}" if skipped else ""))
        rec = (report.get("filter_review") or {}).get("recommended_stages")
        if rec:
            g2, _ = vehicle_response(rec, freq, rate_hz)
            out.append(("recommended settings", freq, g2, "dash", ""))
    return out


def _one_boot_track(series):
    """The logged notch centre track (``series["views"].notch_track``) where the log is of one
    boot (the spectrogram's time axis is then the log's), else None."""
    v = _views(series)
    tr = getattr(v, "notch_track", None) if v is not None else None
    if tr is None or len(np.unique(tr.boots())) > 1:
        return None
    return tr


def _spectra_section(report, series, figs):
    out = ["<h2 id=spectra>Spectra</h2>"]
    spectra = series.get("spectra") or {}
    streams = {s.get("name"): s for s in report.get("streams") or []}
    if not spectra:
        reasons = [f"{n}: {s['spectrum'].get('reason')}" for n, s in streams.items()
                   if isinstance(s.get("spectrum"), dict) and not s["spectrum"].get("available")]
        return "".join(out) + _note("no spectrum" + (": " + "; ".join(reasons) if reasons else " given"))
    sg_done = False
    for name, pd in spectra.items():
        rate = (streams.get(name) or {}).get("rate_hz") or (2.0 * float(np.asarray(pd["freq_hz"])[-1]))
        stage = (streams.get(name) or {}).get("stage")
        responses = _responses_for(report, series, rate) if stage != "post-filter" else []
        title = f"{name}: PSD per axis (solid raw, dashed filtered; ▼ peaks, ━ broad humps, hover names them)"
        if stage:
            title += f"; the vehicle's {stage} gyro"
        out.append(f"<h3>{_e(name)}</h3>" + figs.div(_spectrum_figure(name, pd, responses, title), height=460))
        if pd.get("spectrogram") is not None and not sg_done:
            out.append(figs.div(_spectrogram_figure(name, pd, _one_boot_track(series)), height=380))
            sg_done = True
    if not (report.get("vehicle_filters") or {}).get("stages") and not series.get("filter_review"):
        out.append(_notes_for(report, "vehicle_filters") or
                   _note("the vehicle's filter settings were not found in the log: no response drawn"))
    return "".join(out)


#: the review's figure sets, in the table's order: (key in ``figures``, row label)
REVIEW_ROWS = (("pre_filter", "pre-filter (measured)"), ("logged", "logged settings (predicted)"),
               ("recommended", "recommended settings (predicted)"))
#: the frequencies of the review's phase lag columns [Hz]
REVIEW_LAG_HZ = ("10", "20", "30")


def _num(v, spec=".3g"):
    return f"<span class=num>{_e(_f(v, spec))}</span>"


def _review_html(fr):
    """The filter review (docs/logs/filter-review.md) as readable HTML: noise (deg/s rms
    per axis and rss) and phase lag at 10/20/30 Hz for the pre-filter / logged /
    recommended chains, the verdict and its changes, the lines to paste in a
    ``<pre>``, the peaks, the notch rule, the reasons and notes; what is left
    (source, rates...) as a key/value table, nothing cut."""
    out = []
    figures = fr.get("figures") or {}
    rows = []
    for key, label in REVIEW_ROWS:
        f = figures.get(key)
        if not isinstance(f, dict):
            continue
        noise = f.get("noise_rms_deg_s") or {}
        lag = f.get("phase_lag_ms") or {}
        rows.append([_e(label)] + [_num(noise.get(a)) for a in ("x", "y", "z", "rss")] +
                    [_num(lag.get(h), ".3g") if lag else "" for h in REVIEW_LAG_HZ])
    if rows:
        band = fr.get("noise_band_hz")
        band_txt = f" over {_f(band[0])}..{_f(band[1])} Hz" if isinstance(band, (list, tuple)) and len(band) == 2 else ""
        out.append(f"<h4>Noise{_e(band_txt)} and lag</h4>" + _table(
            rows, ["chain", "noise x [deg/s]", "noise y [deg/s]", "noise z [deg/s]", "noise rss [deg/s]"] +
            [f"lag at {h} Hz [ms]" for h in REVIEW_LAG_HZ]))
    verdict = fr.get("verdict")
    changes = fr.get("changes") or {}
    logged = fr.get("logged") or {}
    if verdict is not None or changes:
        cls = "warn" if changes else "pass"
        out.append(f'<p>verdict: <span class="{cls}">{_e(verdict or ("change" if changes else "no change"))}</span>'
                   + ("" if changes else ": the logged settings are kept") + "</p>")
    if changes:
        out.append(_table([[_e(k), _num(logged.get(k)), _num(v)] for k, v in changes.items()],
                          ["parameter", "logged", "recommended"]))
    lines = fr.get("param_lines")
    if lines:
        out.append("<p>Lines to paste into the autopilot's parameter file or console:</p><pre class=paste>" +
                   _e("\n".join(str(x) for x in lines)) + "</pre>")
    rec = fr.get("recommended") or {}
    if rec:
        out.append("<details><summary>every recommended value (" + str(len(rec)) + ", changed or not)</summary>" +
                   _table([[_e(k), _num(logged.get(k)), _num(v)] for k, v in rec.items()],
                          ["parameter", "logged", "recommended"]) + "</details>")
    for key, title in (("logged_stages", "logged filter chain"), ("recommended_stages", "recommended filter chain")):
        stages = [s for s in fr.get(key) or [] if isinstance(s, dict)]
        if stages:
            cols = [k for k in dict.fromkeys(k for s in stages for k in s) if k != "kind"]
            out.append(f"<h4>{_e(title)}</h4>" + _table([[_e(s.get("kind"))] + [_value_html(s.get(k)) for k in cols]
                                                         for s in stages], ["kind"] + cols))
    peaks = [p for p in fr.get("peaks") or [] if isinstance(p, dict)]
    if peaks:
        out.append("<h4>Peaks</h4>" + _table(
            [[_num(p.get("freq_hz"), ".4g"), _e(p.get("axis") or ""), _num(p.get("ratio_db"), ".3g"),
              _num(p.get("amplitude_rms_deg_s")),
              '<span class="pass">yes</span>' if p.get("notch_ok") else
              ('<span class="warn">no</span>' if p.get("notch_ok") is not None else ""),
              _e(p.get("why_not") or "")] for p in peaks],
            ["frequency [Hz]", "axis", "prominence [dB]", "amplitude [deg/s rms]", "notch ok", "why not"]))
    if fr.get("notch_rule"):
        out.append(f"<p><b>notch rule:</b> {_e(fr['notch_rule'])}</p>")
    for key, title in (("why", "why"), ("notes", "notes")):
        items = fr.get(key)
        if isinstance(items, str):
            items = [items]
        if items:
            out.append(f"<h4>{title}</h4><ul>" + "".join(f"<li>{_value_html(x)}</li>" for x in items) + "</ul>")
    out.append(_kv_table(fr, skip=("figures", "verdict", "changes", "param_lines", "recommended", "logged_stages",
                                   "recommended_stages", "peaks", "notch_rule", "why", "notes", "noise_band_hz")))
    return "".join(out)


def _filter_review_section(report, series, figs):
    out = ["<h2 id=filters>Vehicle filters and review</h2>"]
    vf = report.get("vehicle_filters")
    if vf:
        out.append(f"<p>autopilot: <b>{_e(vf.get('autopilot') or 'unknown')}</b></p>")
        stages = vf.get("stages") or []
        if stages:
            # the biquad coefficients (``sections``) stay in the JSON: numbers no tuner reads
            keys = sorted({k for s in stages if isinstance(s, dict) for k in s} - {"kind", "sections"})
            out.append(_table([[_e(s.get("kind"))] + [_e(_f(s.get(k))) for k in keys]
                               for s in stages if isinstance(s, dict)], ["kind"] + keys))
        params = vf.get("parameters") or {}
        if params:
            out.append("<details><summary>logged parameters (" + str(len(params)) + ")</summary>" +
                       _table([[_e(k), _e(_f(v))] for k, v in params.items()], ["parameter", "value"]) +
                       "</details>")
        stage_rows = [[_e(s.get("name")), _e(s.get("stage"))] for s in report.get("streams") or [] if s.get("stage")]
        if stage_rows:
            out.append(_table(stage_rows, ["stream", "stage"]))
    else:
        out.append(_notes_for(report, "vehicle_filters") or _note("vehicle_filters: not in this report"))
    fr = report.get("filter_review")
    if fr:
        out.append("<h3>Filter review</h3>" + _review_html(fr))
    else:
        out.append(_notes_for(report, "filter_review") or _note("filter_review: not in this report"))
    rev = series.get("filter_review") or {}
    if rev.get("freq_hz") is not None and any(rev.get(k) is not None for k in
                                             ("psd_pre", "psd_post_logged", "psd_post_recommended")):
        out.append(figs.div(_review_figure(rev), height=440))
    return "".join(out)


def _review_figure(rev):
    """The review's PSDs (pre-filter, predicted post-filter for the logged and the
    recommended settings) and the two responses on a second axis."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots
    fig = make_subplots(specs=[[{"secondary_y": True}]])
    fr = np.asarray(rev["freq_hz"], dtype=np.float64)
    sel = fr > 0
    unit = rev.get("unit", "deg/s")
    for key, label, colour, dash in (("psd_pre", "pre-filter (measured)", "#777", "solid"),
                                     ("psd_post_logged", "post-filter, logged settings", "#1f4fb4", "solid"),
                                     ("psd_post_recommended", "post-filter, recommended", "#c2185b", "dash")):
        if rev.get(key) is not None:
            fig.add_trace(go.Scatter(_validate=False, x=fr[sel], y=np.asarray(rev[key], dtype=np.float64)[sel], name=label,
                                     line={"color": colour, "dash": dash}), secondary_y=False)
    for key, label, dash in (("response_logged", "|H| logged", "dot"), ("response_recommended", "|H| recommended",
                                                                        "dashdot")):
        if rev.get(key) is not None:
            fig.add_trace(go.Scatter(_validate=False, x=fr[sel], y=np.asarray(rev[key], dtype=np.float64)[sel], name=label,
                                     line={"color": "#333", "dash": dash}), secondary_y=True)
    fig.update_yaxes(type="log", title_text=f"PSD [({unit})²/Hz]", secondary_y=False,
                     range=_log_range([rev[k] for k in ("psd_pre", "psd_post_logged") if rev.get(k) is not None], sel))
    fig.update_yaxes(title_text="gain |H|", range=[0, 1.3], secondary_y=True, showgrid=False,
                     tickmode="array", tickvals=[0, 0.25, 0.5, 0.707, 1.0])
    fig.update_xaxes(title_text="frequency [Hz]")
    fig.update_layout(title={"text": "filter review: predicted post-filter spectrum", "font": {"size": 14}},
                      legend={"x": 1.08, "y": 1})
    return fig


#: verdict -> bar colour of the vibration plots (None: no published threshold)
VERDICT_COLOURS = {"pass": "#2e9d4f", "warn": "#e69500", "fail": "#b00020", None: "#8c8c8c"}
#: the bar pattern per segment of the vibration plots (the colour is the verdict's)
SEGMENT_PATTERNS = ("", "/", "x", ".", "\\", "+", "-", "|")
#: numeric keys of a vibration segment that are not metrics
_SEGMENT_KEYS = ("start_s", "end_s", "samples", "count", "n", "session")


def _segment_label(seg, i):
    """'kind start-end s' (with its boot session when it is not 0) of a vibration segment."""
    label = str(seg.get("kind") or seg.get("segment") or f"segment {i + 1}")
    if seg.get("start_s") is not None:
        label += f" {float(seg['start_s']):.0f}-{float(seg.get('end_s') or 0):.0f} s"
    if seg.get("session") not in (None, 0):
        label = f"session {seg['session']}: " + label
    return label


def vibration_levels(vib):
    """[(segment label, {metric: figure})] of a vibration report's ``segments``: each
    figure a dict ``{"mean", "p95", "max", "unit", "threshold": {"warn", "fail"} or
    None, "verdict", "samples"}`` of a level, or ``{"increase", "unit": "count",
    "threshold", "verdict"}`` of a clip counter (docs/logs/vibration.md). A segment's
    ``figures`` dict is read as it is; flat numbers of an older report (a segment's
    own numbers or its ``levels``; not ``session``, ``start_s``...) become
    ``{"p95": value}`` against the report's ``thresholds`` (one ``{"warn", "fail"}``
    or one per metric), with no verdict."""
    th = vib.get("thresholds") or {}
    if isinstance(th, dict) and ("warn" in th or "fail" in th):
        common = th
    else:
        common = None

    def thr(metric):
        t = common if common is not None else th.get(metric)
        if isinstance(t, dict) and (t.get("warn") is not None or t.get("fail") is not None):
            return {"warn": t.get("warn"), "fail": t.get("fail")}
        return None

    def flat(vals):
        return {k: {"p95": float(v), "unit": vib.get("unit"), "threshold": thr(k), "verdict": None}
                for k, v in vals.items() if isinstance(v, (int, float)) and not isinstance(v, bool)
                and k not in _SEGMENT_KEYS}

    rows = []
    for i, seg in enumerate(vib.get("segments") or vib.get("per_segment") or []):
        if not isinstance(seg, dict):
            continue
        if isinstance(seg.get("figures"), dict):
            figs = {k: dict(v) for k, v in seg["figures"].items() if isinstance(v, dict)}
        else:
            figs = flat(seg.get("levels") if isinstance(seg.get("levels"), dict) else seg)
        if figs:
            rows.append((_segment_label(seg, i), figs))
    if not rows and isinstance(vib.get("levels"), dict):
        figs = flat(vib["levels"])
        if figs:
            rows.append((str(vib.get("over") or "log"), figs))
    return rows


def _is_clip(fig):
    return "increase" in fig


def _vibration_figure(rows, metrics, title, value_key):
    """Bars of ``value_key`` (p95 of a level, increase of a clip counter) per metric
    (x) and segment (pattern), coloured by verdict, the max as a marker above a
    level's bar, its warn and fail thresholds as dashed lines; a metric with no
    threshold is labelled "no published threshold"."""
    import plotly.graph_objects as go
    cats = []
    for m in metrics:
        has = any((figs.get(m) or {}).get("threshold") for _, figs in rows)
        cats.append(m if has else f"{m}<br>(no published threshold)")
    fig = go.Figure()
    for i, (label, figs) in enumerate(rows):
        vals = [(figs.get(m) or {}).get(value_key) for m in metrics]
        if all(v is None for v in vals):
            continue
        verdicts = [(figs.get(m) or {}).get("verdict") for m in metrics]
        units = [(figs.get(m) or {}).get("unit") or "" for m in metrics]
        text = [f"{label}<br>{m}: {value_key} {_f(v)} {u}; verdict {vd or 'none (no published threshold)'}"
                for m, v, u, vd in zip(metrics, vals, units, verdicts)]
        fig.add_trace(go.Bar(_validate=False, x=cats, y=vals, name=label, offsetgroup=str(i),
                             marker={"color": [VERDICT_COLOURS.get(v, VERDICT_COLOURS[None]) for v in verdicts],
                                     "pattern": {"shape": SEGMENT_PATTERNS[i % len(SEGMENT_PATTERNS)]}},
                             text=text, textposition="none", hovertemplate="%{text}<extra></extra>"))
        if value_key == "p95":
            mx = [(figs.get(m) or {}).get("max") for m in metrics]
            if any(v is not None for v in mx):
                fig.add_trace(go.Scatter(_validate=False, x=cats, y=mx, mode="markers", name=f"{label}: max",
                                         offsetgroup=str(i), legendgroup="max", showlegend=i == 0,
                                         marker={"symbol": "line-ew-open", "size": 14, "color": "#222",
                                                 "line": {"width": 2}},
                                         text=[f"{label}<br>{m}: max {_f(v)}" for m, v in zip(metrics, mx)],
                                         hovertemplate="%{text}<extra></extra>"))
    shown = set()
    for j, m in enumerate(metrics):
        t = next(((figs.get(m) or {}).get("threshold") for _, figs in rows
                  if (figs.get(m) or {}).get("threshold")), None)
        for level in ("warn", "fail"):
            v = (t or {}).get(level)
            if v is None:
                continue
            colour = VERDICT_COLOURS[level]
            fig.add_shape(type="line", x0=j - 0.45, x1=j + 0.45, y0=v, y1=v,
                          line={"color": colour, "width": 2, "dash": "dash"})
            fig.add_trace(go.Scatter(_validate=False, x=[cats[j]], y=[v], mode="markers", name=f"{level} threshold",
                                     legendgroup=level, showlegend=level not in shown,
                                     marker={"color": colour, "symbol": "line-ew-open", "size": 18,
                                             "line": {"width": 2, "color": colour}},
                                     hovertemplate=f"{level} threshold of {m}: %{{y:.3g}}<extra></extra>"))
            shown.add(level)
    fig.update_layout(barmode="group", title={"text": title, "font": {"size": 14}},
                      legend={"orientation": "h", "yanchor": "top", "y": -0.25, "x": 0})
    return fig


def _vibration_plots(rows):
    """[(title, figure)]: one per unit of the levels (p95 bars, max markers), one of the
    clip counters' increases."""
    metrics = []
    for _, figs in rows:
        metrics += [m for m in figs if m not in metrics]
    levels = [m for m in metrics if not any(_is_clip(figs.get(m) or {}) for _, figs in rows)]
    clips = [m for m in metrics if m not in levels]
    out = []
    units = []
    for m in levels:
        u = next(((figs.get(m) or {}).get("unit") for _, figs in rows if (figs.get(m) or {}).get("unit")), "")
        if u not in units:
            units.append(u)
    for u in units:
        ms = [m for m in levels if next(((figs.get(m) or {}).get("unit") for _, figs in rows
                                         if (figs.get(m) or {}).get("unit")), "") == u]
        fig = _vibration_figure(rows, ms, f"vibration levels [{u or 'no unit'}]: p95 per segment (bar, colour: "
                                          "verdict), max (dash), warn/fail thresholds (dashed lines)", "p95")
        fig.update_yaxes(title_text=f"p95 [{u}]" if u else "p95")
        out.append(fig)
    if clips:
        none = all(not (figs.get(m) or {}).get("increase") for _, figs in rows for m in clips)
        fig = _vibration_figure(rows, clips, "accelerometer clipping: increase over each segment "
                                             "(colour: verdict; dashed: warn/fail)" +
                                ("; no clipping: every increase is 0" if none else ""), "increase")
        fig.update_yaxes(title_text="increase [count]")
        out.append(fig)
    return out


def _vibration_table(rows):
    """The vibration figures as a table: a row per segment and metric."""
    out = []
    for label, figs in rows:
        for m, fg in figs.items():
            th = fg.get("threshold") or {}
            vd = fg.get("verdict")
            out.append([_e(label), _e(m), *(f'<span class=num>{_e(_f(fg.get(k)))}</span>'
                                            for k in ("mean", "p95", "max", "increase")),
                        _e(fg.get("unit") or ""),
                        _e(_f(th.get("warn"))) if th else "", _e(_f(th.get("fail"))) if th else "",
                        f'<span class="{_e(vd)}">{_e(vd)}</span>' if vd else
                        ('<span class=small>no published threshold</span>' if not th else ""),
                        _e(_f(fg.get("samples")))])
    return _table(out, ["segment", "metric", "mean", "p95", "max", "increase", "unit", "warn", "fail",
                        "verdict", "samples"])


def _vibration_section(report, figs):
    out = ["<h2 id=vibration>Vibration</h2>"]
    vib = report.get("vibration")
    if not vib:
        return "".join(out) + (_notes_for(report, "vibration") or _note("vibration: not in this report"))
    verdict = str(vib.get("verdict") or "")
    cls = verdict if verdict in ("pass", "warn", "fail") else ""
    src = ", ".join(str(vib[k]) for k in ("source", "accel_source") if vib.get(k))
    out.append(f'<p>verdict: <span class="{cls}">{_e(verdict or "none")}</span>'
               f'{" (source: " + _e(src) + ")" if src else ""}'
               f'{"; over " + _e(vib.get("over")) + " time" if vib.get("over") else ""}</p>')
    rows = vibration_levels(vib)
    for fig in _vibration_plots(rows):
        out.append(figs.div(fig, height=420))
    if rows:
        out.append("<h3>Vibration per segment and metric</h3>" + _vibration_table(rows))
    th = vib.get("thresholds")
    if isinstance(th, dict) and th and not ("warn" in th or "fail" in th):
        trows = [[_e(k), _e(_f(v.get("warn"))), _e(_f(v.get("fail"))), _e(v.get("unit") or ""),
                  _e(v.get("says") or ""), _link(v.get("source"))] for k, v in th.items() if isinstance(v, dict)]
        if trows:
            out.append("<h3>Thresholds</h3>" + _table(trows, ["metric", "warn", "fail", "unit", "says", "source"]))
    peaks = [(_segment_label(seg, i), p) for i, seg in enumerate(vib.get("segments") or [])
             if isinstance(seg, dict) for p in seg.get("accel_peaks") or [] if isinstance(p, dict)]
    if peaks:
        out.append("<h3>Accelerometer peaks</h3>" + _table(
            [[_e(lb), f"<span class=num>{_e(_f(p.get('freq_hz'), '.4g'))}</span>",
              f"<span class=num>{_e(_f(p.get('amplitude_rms_m_s2')))}</span>",
              f"<span class=num>{_e(_f(p.get('ratio_db'), '.3g'))}</span>"] for lb, p in peaks],
            ["segment", "frequency [Hz]", "amplitude [m/s/s rms]", "above floor [dB]"]))
    out.append(_kv_table(vib, skip=("segments", "per_segment", "levels", "thresholds", "verdict", "source",
                                    "accel_source", "over")))
    return "".join(out)


def _notes_section(report):
    notes = [(k, v) for k, v in report.items() if k.endswith("_note") and v]
    if not notes:
        return ""
    return "<h2 id=notes>Notes</h2>" + _table([[_e(k), _e(v)] for k, v in notes], ["note", "text"])


# ------------------------------------------------------------------ pages
#: the file name of plotly.js written once into a folder of pages (``--plotlyjs shared``)
SHARED_PLOTLYJS = "plotly.min.js"


@dataclass(frozen=True)
class PlotlyScript:
    """How a page gets plotly.js: ``tag`` goes into the page's head, ``footer`` says so
    at its foot. :meth:`inline` holds the library itself (the page opens alone);
    :meth:`shared` refers to one copy beside the pages (:func:`write_shared_plotlyjs`)."""
    tag: str
    footer: str

    @classmethod
    def inline(cls):
        from plotly.offline import get_plotlyjs
        return cls(f"<script type='text/javascript'>{get_plotlyjs()}</script>", "self-contained (opens offline)")

    @classmethod
    def shared(cls, js_path, page_folder):
        """The tag of the copy ``js_path`` seen from a page in ``page_folder`` (a relative
        address, so the folder can be moved as a whole)."""
        rel = Path(os.path.relpath(Path(js_path).resolve(), Path(page_folder).resolve())).as_posix()
        return cls(f"<script type='text/javascript' src='{_e(rel)}'></script>",
                   f"plotly.js from {rel} beside this page (keep them together)")


def write_shared_plotlyjs(folder):
    """Write plotly.js once into ``folder`` as :data:`SHARED_PLOTLYJS` (left as it is
    where it already holds the same text); return its path."""
    from plotly.offline import get_plotlyjs
    path = Path(folder) / SHARED_PLOTLYJS
    js = get_plotlyjs()
    if not (path.is_file() and path.stat().st_size == len(js.encode("utf-8")) and path.read_text(encoding="utf-8") == js):
        _write(path, js)
    return path


def _script_for(page_path, plotlyjs):
    """The page's :class:`PlotlyScript`: inlined when ``plotlyjs`` is None, else the
    shared copy at ``plotlyjs`` (a path) referred to from ``page_path``'s folder."""
    return PlotlyScript.inline() if plotlyjs is None else PlotlyScript.shared(plotlyjs, Path(page_path).parent)


def share_plotlyjs(pages, folder):
    """Pages written with plotly.js inlined (``pages``: paths; a missing one is skipped)
    rewritten to refer to one copy written into ``folder`` (:func:`write_shared_plotlyjs`),
    for a command whose pages are drawn by helpers that inline it. Returns the copy's path
    and the pages rewritten."""
    js_path = write_shared_plotlyjs(folder)
    inline = PlotlyScript.inline()
    done = []
    for page in pages:
        page = Path(page)
        if not page.is_file():
            continue
        text = page.read_text(encoding="utf-8")
        head = text.find(inline.tag)
        foot = text.rfind(_e(inline.footer))
        if head < 0 or foot < head:
            continue                                   # already shared, or not one of our pages
        shared = PlotlyScript.shared(js_path, page.parent)
        foot += len(shared.tag) - len(inline.tag)
        text = text[:head] + shared.tag + text[head + len(inline.tag):]
        _write(page, text[:foot] + _e(shared.footer) + text[foot + len(_e(inline.footer)):])
        done.append(page)
    return js_path, done


def _page(title, body, script):
    """A whole HTML page: plotly.js as ``script`` (:class:`PlotlyScript`) says, in the
    head; nothing else external."""
    import plotly
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    from gyrodenoise._version import __version__
    return ("<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8>"
            f"<meta name=viewport content='width=device-width, initial-scale=1'><title>{_e(title)}</title>"
            f"<style>{CSS}</style>{script.tag}</head><body>"
            f"{body}<p class=small>gyrodenoise {_e(__version__)}, plotly.js {_e(_plotlyjs_version(plotly))}; "
            f"written {stamp}; {_e(script.footer)}</p></body></html>\n")


def _plotlyjs_version(plotly):
    try:
        from plotly.offline import get_plotlyjs_version
        return get_plotlyjs_version()
    except ImportError:
        return plotly.__version__


def _write(path, text):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return path


def write_log_report(path, report, series=None, plotlyjs=None):
    """Write the interactive HTML report of one log to ``path``; return ``path``.

    ``report``: the log's report (:func:`gyrodenoise.flightlog.pipeline.process_log`,
    with whatever of ``segments``, ``vehicle_filters``, ``filter_review``,
    ``vibration`` and their ``*_note`` keys it has). ``series`` (arrays, all
    optional)::

        {"streams": [{"name": str, "time_s": (n,) boot time,
                      "raw": (n, k), "filtered": (n, k) or None (written raw),
                      "unit": "deg/s", "axes": ("x", "y", "z"),
                      "restarts": bool (n,) or sample indices,
                      "filtered_label": "filtered (motion, offline)",
                      "raw_reason": why it was written raw, or None}, ...],
         "vehicle_rate": [{"name": "RATE", "time_s": (m,), "rate": (m, 3), "unit": "deg/s"}],
         "spectra": {stream name: the plot data of
                     gyrodenoise.flightlog.spectra.stream_spectrum ("freq_hz", "raw" and
                     "filtered" (or "psd_raw"/"psd_filtered") per axis, "peaks" per axis,
                     "unit", "axes", "filtered_is_raw", "spectrogram": (t, density) or None)},
         "filter_review": {"freq_hz", "unit", "psd_pre", "psd_post_logged", "psd_post_recommended",
                           "response_logged", "response_recommended"},
         "views": gyrodenoise.flightlog.timeseries.FlightViews (motors, throttle,
                  vibration against time, the markers, the frequency maps)}

    :func:`stream_series` gives a stream's entry from a processed GyroStream. Without
    ``filter_review`` responses the vehicle's response is computed from
    ``report["vehicle_filters"]["stages"]`` (:func:`vehicle_response`).

    ``plotlyjs``: None inlines plotly.js in the page; a path (:func:`write_shared_plotlyjs`)
    makes the page refer to that copy instead."""
    series = series or {}
    name = Path(str(report.get("file", "log"))).name
    nav = "".join(f"<a href='#{a}'>{b}</a>" for a, b in (("overview", "overview"), ("summary", "summary"),
                                                         ("streams", "streams"), ("flight", "motors, RC, battery"),
                                                         ("spectra", "spectra"), ("maps", "by throttle/RPM"), ("filters", "filters"), ("replay", "filter replay"),
                                                         ("noise", "noise in flight"), ("step", "step response"),
                                                         ("vibration", "vibration"), ("notes", "notes")))
    with _Figures() as figs:
        body = [f"<h1>{_e(name)}: gyro review</h1><nav>{nav}</nav>",
                _overview_section(report),
                _summary_section(report, series),
                _streams_section(report, series, figs),
                _flight_section(report, series, figs),
                _spectra_section(report, series, figs),
                _heatmap_section(series, figs),
                _filter_review_section(report, series, figs),
                _replay_section(report),
                _inflight_noise_section(report),
                _step_response_section(report, figs),
                _vibration_section(report, figs),
                _notes_section(report)]
    return _write(path, _page(f"{name}: gyro review", "".join(body), _script_for(path, plotlyjs)))


def write_fleet_report(path, fleet_report, per_log=(), plotlyjs=None):
    """Write the fleet's interactive HTML report to ``path``; return ``path``.

    ``fleet_report``: what :func:`gyrodenoise.flightlog.fleet.write_fleet_report`
    writes to fleet.json (``rows`` of :func:`gyrodenoise.flightlog.fleet.fleet_rows`,
    ``n_logs``, ``n_ok``, ``n_failed``); ``per_log``: the logs' reports (their
    ``report_html`` becomes a link, relative to ``path``'s folder, and their
    ``vibration`` verdict and flying time a column); ``plotlyjs`` as for
    :func:`write_log_report`."""
    path = Path(path)
    rows = list(fleet_report.get("rows") or [])
    by_file = {str(r.get("file")): r for r in per_log or []}
    figs = _Figures()
    out = [f"<h1>Fleet report: {_e(fleet_report.get('n_logs', len(by_file)))} logs</h1>",
           f"<p>{_e(fleet_report.get('n_ok', ''))} processed, {_e(fleet_report.get('n_failed', ''))} failed; "
           f"noise columns: {_e(fleet_report.get('noise_of', ''))}</p>"]
    table = []
    for r in rows:
        rep = by_file.get(str(r.get("file"))) or {}
        link = _e(r.get("log"))
        if rep.get("report_html"):
            rel = os.path.relpath(Path(rep["report_html"]).resolve(), path.parent.resolve())
            link = f"<a href='{_e(Path(rel).as_posix())}'>{link}</a>"
        vib = rep.get("vibration") or {}
        verdict = str(vib.get("verdict") or "")
        flying = _flying_time_s(rep)
        if r.get("status") == "failed":
            table.append([link, "", '<span class="fail">failed</span>', "", "", "", "", "", "", _e(r.get("error"))])
            continue
        vs = r.get("density_vs_fleet_median")
        table.append([link, _e(r.get("stream")), "ok", _e(_f(r.get("rate_hz"), ".4g")),
                      _with_unit(r.get("noise_raw"), r.get("noise_unit")),
                      _with_unit(r.get("noise_filtered"), r.get("noise_unit")),
                      _e(_f(r.get("noise_density_deg_s_rthz"))),
                      ('<span class="fail">' if r.get("flag") else "<span>") + _e(_f(vs, ".2g")) + "</span>",
                      f'<span class="{_e(verdict)}">{_e(verdict)}</span>' +
                      ("" if flying is None else f" {flying:.0f} s flying"),
                      _e(r.get("left_raw") or r.get("vs_fleet_note") or r.get("note") or "")])
    out.append("<h2>Logs</h2>" + _table(table, ["log (its report)", "stream", "status", "rate [Hz]",
                                               "noise raw (unit)", "noise filtered (unit)", "density [deg/s/√Hz]", "x fleet median",
                                               "vibration", "note"]))
    with figs:
        fig = _fleet_figure(rows)
        if fig is not None:
            out.append("<h2>Noise density per log and stream</h2>" + figs.div(fig, height=480))
        else:
            out.append(_note("no stream has a noise density to compare"))
    return _write(path, _page("gyrodenoise fleet report", "".join(out), _script_for(path, plotlyjs)))


def _with_unit(v, unit):
    """A fleet table cell: the number with its unit ("0.81 deg/s", "12.3 raw counts"
    where the unit is unknown), '' for None."""
    if v is None:
        return ""
    return f"<span class=num>{_e(_f(v))}</span> {_e(unit or 'raw counts (unit unknown)')}"


def _fleet_figure(rows):
    """Noise density per log (x) and IMU (colour, as compared across the fleet);
    flagged streams circled red. None when no stream has a density."""
    import plotly.graph_objects as go
    ok = [r for r in rows if r.get("status") == "ok" and r.get("noise_density_deg_s_rthz") is not None]
    if not ok:
        return None
    logs = sorted({r["log"] for r in ok})
    fig = go.Figure()
    for g in sorted({r.get("compared_as") or r.get("stream") for r in ok}):
        pts = [r for r in ok if (r.get("compared_as") or r.get("stream")) == g]
        fig.add_trace(go.Scatter(_validate=False, x=[r["log"] for r in pts], y=[r["noise_density_deg_s_rthz"] for r in pts],
                                 mode="markers", name=g, marker={"size": 10},
                                 text=[f"{r['log']} {r['stream']}: filtered/raw noise "
                                       f"{_f((r.get('noise_filtered') or 0) / r['noise_raw'], '.2f') if r.get('noise_raw') else ''}"
                                       for r in pts],
                                 hovertemplate="%{text}<br>%{y:.3g} deg/s/√Hz<extra></extra>"))
    flagged = [r for r in ok if r.get("flag")]
    if flagged:
        fig.add_trace(go.Scatter(_validate=False, x=[r["log"] for r in flagged], y=[r["noise_density_deg_s_rthz"] for r in flagged],
                                 mode="markers", name="noisier than the fleet",
                                 marker={"size": 20, "color": "rgba(0,0,0,0)", "line": {"color": "red", "width": 2}}))
    fig.update_xaxes(categoryorder="array", categoryarray=logs, tickangle=-45)
    fig.update_yaxes(type="log", title_text="raw noise density [deg/s/√Hz]")
    fig.update_layout(title={"text": "gyro noise density per log and IMU", "font": {"size": 14}})
    return fig
