"""Per-airframe trends over the fleet store: a change against the airframe's own history.

Each airframe's logs (:mod:`gyrodenoise.flightlog.fleet_store`), in the order they were
flown (their start on the wall clock where every log of the airframe records one,
else the order they were stored), give one series per :class:`Metric` (:data:`METRICS`):

* ``vibration``: the log's highest acceleration vibration figure (its 95th percentile
  over flying time, m/s/s);
* ``line level``: per gyro stream, the raw gyro's PSD at the airframe's own vibration
  line (the median of the dominant peak's frequency over its baseline logs: a
  propeller imbalance or a motor line), sqrt of the largest axis's mean over the
  flying segments, deg/s/sqrt(Hz), from the store's spectra on the fixed grid (the
  bin holding the frequency and one each side);
* ``noise density``: per gyro stream, the raw gyro's white-noise density.

An airframe keyed by the folder holding its logs (no vehicle id: ``airframe_source``
``folder``) is one airframe only as far as its logs agree: where two of them record
different values of an :data:`IDENTITY` field (autopilot, vehicle type, board, frame),
the folder mixes aircraft and its logs are not trended (:func:`groupings` gives each
airframe a one-line reason, either way).

The change detector (:class:`Detector`, :func:`detect`) is a one-sided self-starting
CUSUM (Hawkins 1987) on the logarithm of the level, so that growth is judged as a
ratio: with y_i = log10(level_i) and the mean m and standard deviation s of the n
earlier logs not flagged (at least ``baseline`` of them; s floored at ``min_sigma``),

    t_i = (y_i - m) / (s sqrt(1 + 1/n))          (Student t with n - 1 degrees of freedom)
    z_i = Phi^-1(F_t,n-1(t_i))                    (a standard normal for an unchanged airframe)
    S_i = max(0, S_(i-1) + z_i - k),  flagged when S_i > h, or z_i > jump (one log's jump).

Its false-alarm rate on unchanged series and its delay on a drifting airframe are
measured on seeded synthetic series by :func:`false_alarm_rate` and
:func:`detection_delay` (the fleet-trends benchmark prints them; the tests bound them).
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from gyrodenoise.flightlog.fleet_store import GRID_EDGES_HZ, connect


# ------------------------------------------------------------------ the detector
@dataclass(frozen=True)
class Detector:
    """The change detector's settings (see the module's docstring)."""
    baseline: int = 5          # logs before the first verdict
    allowance: float = 0.5     # k: the CUSUM's drift allowance, in sigmas
    threshold: float = 5.0     # h: the CUSUM's decision level, in sigmas
    jump: float = 5.0          # one log this many sigmas above its history is flagged at once
    min_sigma: float = 0.01    # floor of the log10 scale (2.3 %): figures repeated to the digit

    def check(self):
        """One line naming the setting that cannot be used, or None."""
        if self.baseline < 3:
            return f"the baseline needs at least 3 logs, got {self.baseline}"
        for name in ("allowance", "threshold", "jump", "min_sigma"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                return f"{name} must be a finite number > 0, got {v}"
        return None


@dataclass
class Detection:
    """:func:`detect`'s answer for one series: per log its z (None within the baseline),
    the CUSUM and whether it is flagged; the first flagged log's index (None: none)."""
    z: list
    cusum: list
    flagged: list
    first_flag: int | None
    centre: list               # the history's mean of log10(level) each log was judged against
    sigma: list


def detect(values, detector=Detector()):
    """Run the self-starting CUSUM of the module's docstring on ``values`` (levels > 0,
    in the airframe's order); logs with a non-positive or missing level are skipped
    (z None, not flagged). Returns :class:`Detection`."""
    from scipy.special import ndtri, stdtr
    n = len(values)
    z, cusum, flagged, centre, sigma = [None] * n, [0.0] * n, [False] * n, [None] * n, [None] * n
    history, s_run, first = [], 0.0, None
    for i, v in enumerate(values):
        if v is None or not (math.isfinite(v) and v > 0):
            cusum[i] = s_run
            continue
        y = math.log10(v)
        if len(history) >= detector.baseline:
            h = np.asarray(history)
            m, s = float(h.mean()), max(float(h.std(ddof=1)), detector.min_sigma)
            t = (y - m) / (s * math.sqrt(1.0 + 1.0 / len(h)))
            zi = float(ndtri(stdtr(len(h) - 1, t)))
            zi = max(min(zi, 40.0), -40.0)          # the tails' ppf saturates to inf
            s_run = max(0.0, s_run + zi - detector.allowance)
            z[i], centre[i], sigma[i] = zi, m, s
            flagged[i] = s_run > detector.threshold or zi > detector.jump
            if flagged[i] and first is None:
                first = i
        cusum[i] = s_run
        if not flagged[i]:
            history.append(y)
    return Detection(z, cusum, flagged, first, centre, sigma)


# ------------------------------------------------------------------ measured on synthetic series
def unchanged_series(rng, n_logs, sigma_log10, tails_dof=None):
    """Levels of an unchanged airframe: 10^(e_i), e_i iid N(0, sigma_log10) (or Student t
    with ``tails_dof`` degrees of freedom scaled to that sigma: heavier tails)."""
    if tails_dof is None:
        e = rng.normal(0.0, sigma_log10, n_logs)
    else:
        e = rng.standard_t(tails_dof, n_logs) * sigma_log10 * math.sqrt((tails_dof - 2) / tails_dof)
    return 10.0 ** e


def drifting_series(rng, n_logs, sigma_log10, onset, growth_per_log):
    """An airframe that starts to drift at log ``onset``: the unchanged series times
    (1 + growth_per_log)^(i - onset + 1) from log ``onset`` on (a growing imbalance)."""
    v = unchanged_series(rng, n_logs, sigma_log10)
    steps = np.clip(np.arange(n_logs) - onset + 1, 0, None)
    return v * (1.0 + growth_per_log) ** steps


@dataclass(frozen=True)
class FalseAlarms:
    """Flags on unchanged synthetic airframes: per judged log and per airframe (any flag)."""
    airframes: int
    logs_per_airframe: int
    per_log: float
    per_airframe: float
    sigma_log10: tuple
    tails_dof: float | None


def false_alarm_rate(detector=Detector(), seed=0, airframes=2000, n_logs=30,
                     sigma_log10=(0.04, 0.15), tails_dof=None):
    """:class:`FalseAlarms` of ``detector`` on ``airframes`` unchanged series of ``n_logs``
    logs, each airframe's log-to-log scatter drawn uniformly in ``sigma_log10`` (0.04-0.15
    decades: 10-40 %), seeded."""
    rng = np.random.default_rng(seed)
    judged = flagged = any_flag = 0
    for _ in range(airframes):
        v = unchanged_series(rng, n_logs, rng.uniform(*sigma_log10), tails_dof)
        d = detect(list(v), detector)
        judged += sum(z is not None for z in d.z)
        flagged += sum(d.flagged)
        any_flag += d.first_flag is not None
    return FalseAlarms(airframes, n_logs, flagged / max(judged, 1), any_flag / airframes,
                       tuple(sigma_log10), tails_dof)


@dataclass(frozen=True)
class Delays:
    """Logs from a drift's onset to the first flag on synthetic drifting airframes
    (``missed``: the share never flagged within the series; ``early``: flagged before the onset)."""
    trials: int
    onset: int
    growth_per_log: float
    sigma_log10: float
    median: float
    p90: float
    missed: float
    early: float


def detection_delay(detector=Detector(), seed=0, trials=500, n_logs=40, onset=15,
                    growth_per_log=0.05, sigma_log10=0.06):
    """:class:`Delays` of ``detector`` on ``trials`` drifting airframes (``growth_per_log``
    a log from ``onset`` on, scatter ``sigma_log10``), seeded. A missed drift counts as
    n_logs - onset logs in the median and 90th percentile."""
    rng = np.random.default_rng(seed)
    delays, missed, early = [], 0, 0
    for _ in range(trials):
        d = detect(list(drifting_series(rng, n_logs, sigma_log10, onset, growth_per_log)), detector)
        after = [i for i, f in enumerate(d.flagged) if f and i >= onset]
        early += any(f for f in d.flagged[:onset])
        if after:
            delays.append(after[0] - onset)
        else:
            missed += 1
            delays.append(n_logs - onset)
    return Delays(trials, onset, growth_per_log, sigma_log10, float(np.median(delays)),
                  float(np.percentile(delays, 90)), missed / trials, early / trials)


# ------------------------------------------------------------------ which logs are one airframe
#: the identity a folder's logs must agree on where they record it: (what it is called, its column of ``logs``)
IDENTITY = (("autopilot", "autopilot"), ("vehicle", "vehicle"), ("board", "board"), ("frame", "frame"))
#: a reason line lists at most this many values of a field
_LISTED = 4


@dataclass(frozen=True)
class Grouping:
    """Why an airframe's logs are taken as one airframe (``trended``), or why not."""
    airframe: str
    source: str                # the store's airframe_source: option / vehicle_id / folder
    logs: int
    trended: bool
    reason: str


def _listed(values):
    values = sorted(values)
    more = f" (+{len(values) - _LISTED} more)" if len(values) > _LISTED else ""
    return ", ".join(values[:_LISTED]) + more


def _grouping(airframe, source, idents):
    """The :class:`Grouping` of one airframe from its logs' identities (one tuple of the
    :data:`IDENTITY` columns per log)."""
    n = len(idents)
    if source == "option":
        return Grouping(airframe, source, n, True, f"named with --airframe: its {n} log(s) are one airframe")
    if source == "vehicle_id":
        return Grouping(airframe, source, n, True, f"the vehicle id recorded in each of its {n} log(s)")
    seen = [(name, {i[k] for i in idents if i[k] is not None}) for k, (name, _) in enumerate(IDENTITY)]
    mixed = [(name, vals) for name, vals in seen if len(vals) > 1]
    if mixed:
        return Grouping(airframe, source, n, False,
                        f"not trended: no vehicle id, and the {n} logs of the folder '{airframe}' are of different "
                        f"aircraft ({'; '.join(f'{name}: {_listed(vals)}' for name, vals in mixed)}); keep one "
                        f"folder per aircraft, or name it with mavlink --store DIR --airframe NAME")
    agreed = [f"{name} {next(iter(vals))}" for name, vals in seen if vals]
    silent = sum(all(v is None for v in i) for i in idents)
    if not agreed:
        return Grouping(airframe, source, n, True,
                        f"no vehicle id: grouped by the folder '{airframe}'; none of its {n} log(s) records its "
                        f"{', '.join(name for name, _ in IDENTITY)}, so they are one airframe on the folder's word")
    return Grouping(airframe, source, n, True,
                    f"no vehicle id: grouped by the folder '{airframe}'; its {n} log(s) agree where they record "
                    f"it ({', '.join(agreed)}{f'; {silent} record none' if silent else ''})")


def groupings(con):
    """{airframe: :class:`Grouping`} of the store (a :func:`connect` connection)."""
    cols = ", ".join(f"min({c})" for _, c in IDENTITY)
    rows = con.execute(f"SELECT airframe, min(airframe_source), {cols} FROM logs GROUP BY airframe, log_key").fetchall()
    by = {}
    for a, src, *ident in rows:
        by.setdefault((a, src), []).append(tuple(ident))
    return {a: _grouping(a, src, idents) for (a, src), idents in sorted(by.items())}


# ------------------------------------------------------------------ the store's series
@dataclass
class Point:
    """One log of a series: its key and name, when (ISO text, or the store order), its level."""
    log_key: str
    log: str
    when: str
    value: float | None


@dataclass
class Trend:
    """One airframe's series of one metric (one stream, or the log for a log-level metric),
    with its :class:`Detection` and what it says."""
    airframe: str
    airframe_source: str
    metric: str
    unit: str
    stream: str                # the stream as compared across logs; "" for a log-level metric
    ordered_by: str            # "start time" / "store order"
    points: list
    detection: Detection
    reference_hz: float | None = None   # the line level's frequency
    note: str = ""
    grouping: Grouping | None = None    # why its logs are one airframe (or not: then not trended)

    @property
    def trended(self):
        return self.grouping is None or self.grouping.trended

    @property
    def status(self):
        """``growth`` (flagged), ``steady``, ``short history`` (fewer logs than the baseline),
        or ``not trended`` (its logs are not one airframe: :attr:`grouping`)."""
        if not self.trended:
            return "not trended"
        if self.detection.first_flag is not None:
            return "growth"
        return "steady" if any(z is not None for z in self.detection.z) else "short history"

    def to_fields(self):
        d = self.detection
        return {"airframe": self.airframe, "airframe_source": self.airframe_source, "metric": self.metric,
                "unit": self.unit, "stream": self.stream, "ordered_by": self.ordered_by, "status": self.status,
                "reference_hz": self.reference_hz, "note": self.note,
                "grouping": None if self.grouping is None else self.grouping.reason,
                "first_flag": None if d.first_flag is None else self.points[d.first_flag].log,
                "logs": [{"log": p.log, "log_key": p.log_key, "when": p.when, "value": p.value, "z": z,
                          "cusum": c, "flagged": f} for p, z, c, f in zip(self.points, d.z, d.cusum, d.flagged)]}


@dataclass(frozen=True)
class Metric:
    """A trended figure: its name, unit, whether it is per stream, and how its rows come
    out of the store (``collect(con, detector)`` -> rows (airframe, stream, log_key, value,
    reference_hz) over the logs that have it)."""
    name: str
    unit: str
    per_stream: bool
    collect: Callable


def _column(column, per_stream):
    def collect(con, detector):
        stream = "compared_as" if per_stream else "''"
        return con.execute(f"SELECT airframe, {stream}, log_key, max({column}), NULL FROM logs "
                           f"WHERE {column} IS NOT NULL GROUP BY ALL").fetchall()
    return collect


def _line_level(con, detector):
    """Rows of the ``line level`` metric: per airframe and stream, the reference frequency
    from the first ``baseline`` logs with a dominant peak, then each log's level there."""
    out = []
    orders = _orders(con)
    peaks = con.execute("SELECT airframe, compared_as, log_key, peak_freq_hz FROM logs "
                        "WHERE peak_freq_hz IS NOT NULL AND peak_unit = 'deg/s'").fetchall()
    refs = {}
    for a, s, key, f in sorted(peaks, key=lambda r: orders[r[0]].get(r[2], 0)):
        refs.setdefault((a, s), []).append(f)
    lo, hi = GRID_EDGES_HZ[:-1], GRID_EDGES_HZ[1:]
    for (a, s), fs in refs.items():
        ref = float(np.median(fs[:detector.baseline]))
        b = int(np.searchsorted(hi, ref, side="right"))
        bins = [i for i in (b - 1, b, b + 1) if 0 <= i < len(lo)]
        rows = con.execute(
            "SELECT log_key, axis, samples, psd FROM spectra "
            "WHERE airframe = ? AND compared_as = ? AND kind IN ('flying', 'whole log')", [a, s]).fetchall()
        acc = {}
        for key, axis, n, psd in rows:
            vals = [psd[i] for i in bins if psd[i] is not None]
            if vals:
                acc.setdefault(key, {}).setdefault(axis, []).append((n, max(vals)))
        for key, axes in acc.items():
            level = max(sum(n * v for n, v in segs) / sum(n for n, _ in segs) for segs in axes.values())
            out.append((a, s, key, math.sqrt(level), ref))
    return out


#: the trended figures (the module's docstring)
METRICS = (
    Metric("vibration", "m/s/s", False, _column("vibration_p95", False)),
    Metric("line level", "deg/s/sqrt(Hz)", True, _line_level),
    Metric("noise density", "deg/s/sqrt(Hz)", True, _column("noise_density_deg_s_rthz", True)),
)


def _orders(con):
    """{airframe: {log_key: rank}}: by start time where every log of the airframe has one,
    else by store time; the log name breaks ties."""
    rows = con.execute("SELECT airframe, log_key, min(log), min(start_utc), min(stored_utc) FROM logs "
                       "GROUP BY airframe, log_key").fetchall()
    by = {}
    for a, key, name, start, stored in rows:
        by.setdefault(a, []).append((key, name, start, stored))
    out = {}
    for a, logs in by.items():
        timed = all(start is not None for _, _, start, _ in logs)
        logs.sort(key=lambda r: ((r[2] if timed else r[3]), r[1]))
        out[a] = {key: i for i, (key, _, _, _) in enumerate(logs)}
        out[a]["__by__"] = "start time" if timed else "store order"
    return out


def _not_judged(n):
    """The :class:`Detection` of a series that is not trended: no verdict on any log."""
    return Detection([None] * n, [0.0] * n, [False] * n, None, [None] * n, [None] * n)


def trends(store, detector=Detector(), metrics=METRICS):
    """Every airframe's :class:`Trend` of each metric in ``store``; an airframe whose
    logs are not one airframe (:func:`groupings`) has its series without verdicts
    (status ``not trended``) and no line level (its frequency would mix aircraft)."""
    con = connect(store)
    try:
        orders = _orders(con)
        groups = groupings(con)
        info = {(a, key): (name, start, stored) for a, key, name, start, stored in con.execute(
            "SELECT airframe, log_key, min(log), min(start_utc), min(stored_utc) FROM logs GROUP BY ALL").fetchall()}
        out = []
        for metric in metrics:
            series = {}
            for a, s, key, value, ref in metric.collect(con, detector):
                series.setdefault((a, s), {"ref": ref, "rows": {}})["rows"][key] = value
            for (a, s), got in sorted(series.items()):
                group = groups[a]
                if not group.trended and got["ref"] is not None:
                    continue
                keys = sorted(got["rows"], key=lambda k: orders[a][k])
                by = orders[a]["__by__"]
                points = []
                for k in keys:
                    name, start, stored = info[(a, k)]
                    when = (start if by == "start time" else stored).isoformat()
                    points.append(Point(k, name, when, got["rows"][k]))
                values = [p.value for p in points]
                out.append(Trend(a, group.source, metric.name, metric.unit, s, by, points,
                                 detect(values, detector) if group.trended else _not_judged(len(values)),
                                 got["ref"], grouping=group))
        return out
    finally:
        con.close()


# ------------------------------------------------------------------ pages
def _slug(text):
    keep = "".join(c if c.isalnum() or c in "-_" else "_" for c in text)
    return keep.strip("_")[:80] or "airframe"


def _figure(trend):
    """The series (log scale), the history's band and the flagged logs, and the CUSUM
    under it; a series not trended: its values only."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots
    d = trend.detection
    x = [f"{i + 1}: {p.log}" for i, p in enumerate(trend.points)]
    judged = trend.trended
    fig = make_subplots(rows=1 + judged, cols=1, shared_xaxes=True, row_heights=[0.7, 0.3] if judged else None,
                        vertical_spacing=0.06)
    fig.add_trace(go.Scatter(x=x, y=[p.value for p in trend.points], mode="lines+markers", name=trend.metric,
                             text=[p.when for p in trend.points],
                             hovertemplate="%{x}<br>%{text}<br>%{y:.4g} " + trend.unit + "<extra></extra>"),
                  row=1, col=1)
    fig.update_yaxes(type="log", title_text=trend.unit, row=1, col=1)
    title = f"{trend.metric}{' of ' + trend.stream if trend.stream else ''}"
    if trend.reference_hz is not None:
        title += f" at {trend.reference_hz:.3g} Hz"
    fig.update_layout(title={"text": f"{title}: {trend.status}", "font": {"size": 14}})
    if not judged:
        return fig
    band = [(None, None) if c is None else (10 ** (c - 3 * s), 10 ** (c + 3 * s)) for c, s in zip(d.centre, d.sigma)]
    fig.add_trace(go.Scatter(x=x, y=[b[1] for b in band], mode="lines", line={"dash": "dot", "color": "grey"},
                             name="history's mean x/÷ 3 sigma"), row=1, col=1)
    fig.add_trace(go.Scatter(x=x, y=[b[0] for b in band], mode="lines", line={"dash": "dot", "color": "grey"},
                             showlegend=False), row=1, col=1)
    flagged = [i for i, f in enumerate(d.flagged) if f]
    if flagged:
        fig.add_trace(go.Scatter(x=[x[i] for i in flagged], y=[trend.points[i].value for i in flagged],
                                 mode="markers", name="flagged: growth",
                                 marker={"size": 14, "color": "rgba(0,0,0,0)", "line": {"color": "red", "width": 2}}),
                      row=1, col=1)
    fig.add_trace(go.Scatter(x=x, y=d.cusum, mode="lines+markers", name="CUSUM", line={"color": "#7b3fa0"}),
                  row=2, col=1)
    fig.update_yaxes(title_text="CUSUM [sigma]", row=2, col=1)
    return fig


def _plotly_script(mode, folder):
    """The pages' plotly.js (:class:`gyrodenoise.flightlog.html_report.PlotlyScript`):
    inlined (``inline``), or ``plotly.min.js`` written once into ``folder`` and
    referred to (``shared``)."""
    from gyrodenoise.flightlog.html_report import PlotlyScript, write_shared_plotlyjs
    if mode == "inline":
        return PlotlyScript.inline()
    return PlotlyScript.shared(write_shared_plotlyjs(folder), folder)


def airframe_status(ts):
    """One airframe's status line from its trends: ``GROWTH: <what> from <log>, ...``,
    ``not trended``, ``steady`` or ``short history``."""
    grown = [t for t in ts if t.status == "growth"]
    if grown:
        return "GROWTH: " + ", ".join(f"{t.metric}{' ' + t.stream if t.stream else ''} from "
                                      f"{t.points[t.detection.first_flag].log}" for t in grown)
    for status in ("not trended", "steady"):
        if any(t.status == status for t in ts):
            return status
    return "short history"


def groupings_of(trend_list):
    """{airframe: :class:`Grouping`} of the trends, by airframe."""
    return dict(sorted({t.airframe: t.grouping for t in trend_list if t.grouping is not None}.items(),
                       key=lambda kv: kv[0]))


def write_pages(trend_list, out_dir, plotlyjs="inline", detector=Detector(), false_alarms=None):
    """One page per airframe (``airframe-<name>.html``: why its logs are one airframe,
    each metric's series, its flags and CUSUM) and ``index.html`` (every airframe's
    status and grouping), into ``out_dir``;
    plotly.js inlined in each page (``inline``) or written once as ``plotly.min.js``
    (``shared``). Returns the paths."""
    from gyrodenoise.flightlog.html_report import _Figures, _page, _write
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    script = _plotly_script(plotlyjs, out)
    by = {}
    for t in trend_list:
        by.setdefault(t.airframe, []).append(t)
    e = html.escape
    far = ("" if false_alarms is None else
           f" On {false_alarms.airframes} unchanged synthetic airframes of {false_alarms.logs_per_airframe} logs "
           f"it flags {100 * false_alarms.per_log:.2g} % of the logs it judges ({100 * false_alarms.per_airframe:.2g} % "
           f"of the airframes at least once).")
    method = (f"<p>A log is flagged when its level grows against the airframe's own earlier logs: a one-sided "
              f"self-starting CUSUM on log10(level) (baseline {detector.baseline} logs, allowance "
              f"{detector.allowance:g}, decision level {detector.threshold:g} sigma, or one log "
              f"{detector.jump:g} sigma above its history).{e(far)}</p>")
    paths, index = [], []
    groups = groupings_of(trend_list)
    for airframe, ts in sorted(by.items()):
        name = f"airframe-{_slug(airframe)}.html"
        group = groups.get(airframe)
        why = "" if group is None else f"<p><b>grouping:</b> {e(group.reason)}</p>"
        with _Figures() as figs:
            parts = [f"<h1>Airframe {e(airframe)}</h1>",
                     f"<p>airframe key from: {e(ts[0].airframe_source)}; logs ordered by {e(ts[0].ordered_by)}; "
                     f"<a href='index.html'>all airframes</a></p>", why, method]
            for t in ts:
                parts.append(f"<h2>{e(t.metric)}{' — ' + e(t.stream) if t.stream else ''}: {e(t.status)}</h2>")
                parts.append(figs.div(_figure(t), height=460))
        paths.append(_write(out / name, _page(f"airframe {airframe}: trends", "".join(parts), script)))
        n_logs = group.logs if group is not None else len({p.log_key for t in ts for p in t.points})
        index.append(f"<tr><td><a href='{e(name)}'>{e(airframe)}</a></td><td>{n_logs}</td>"
                     f"<td>{e(airframe_status(ts))}</td><td>{e(group.reason if group else '')}</td></tr>")
    body = ("<h1>Fleet trends</h1>" + method + "<table><tr><th>airframe</th><th>logs</th><th>status</th>"
            "<th>why these logs are one airframe</th></tr>" + "".join(index) + "</table>")
    paths.append(_write(out / "index.html", _page("fleet trends", body, script)))
    return paths


def write_json(trend_list, path, detector=Detector()):
    """``trends.json``: the detector's settings, every airframe's grouping (its logs,
    whether trended, the one-line reason: :class:`Grouping`) and every trend
    (:meth:`Trend.to_fields`)."""
    from gyrodenoise.flightlog.stopping import atomic_path
    doc = {"detector": {"baseline": detector.baseline, "allowance": detector.allowance,
                        "threshold": detector.threshold, "jump": detector.jump, "min_sigma": detector.min_sigma},
           "airframes": [asdict(g) for g in groupings_of(trend_list).values()],
           "trends": [t.to_fields() for t in trend_list]}
    with atomic_path(Path(path)) as tmp:
        Path(tmp).write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
    return Path(path)

