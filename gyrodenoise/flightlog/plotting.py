"""The stream plots of a processed log: raw and filtered per axis, restarts marked.

Drawn inline, or by :class:`Plotter` in forked helper processes that import
matplotlib and draw while the parent goes on filtering (Linux). The spectrum
figure of a log (:mod:`gyrodenoise.flightlog.spectra`) goes through the same helpers.
"""

from __future__ import annotations

import sys

import numpy as np

from gyrodenoise.analysis import motion_metrics as mm
from gyrodenoise.flightlog.output import joined_time
from gyrodenoise.flightlog.stopping import as_child, signals_blocked, stop_processes, atomic_path


def _envelope(t, y, nbins=2000):
    """Min/max per bin of a long line (what a raster plot shows anyway)."""
    n = len(y)
    if n <= 2 * nbins:
        return t, y
    edges = np.linspace(0, n, nbins + 1).astype(np.int64)[:-1]
    lo = np.minimum.reduceat(y, edges)
    hi = np.maximum.reduceat(y, edges)
    return np.repeat(t[edges], 2), np.column_stack([lo, hi]).ravel()


#: the x label of a log whose clock is the time since boot (the log's ``time_base["axis"]``)
BOOT_AXIS = "boot time [s]"


def plot_time(time_s, restarts, axis=BOOT_AXIS):
    """(time axis of a stream's plot, x-axis label). The log's time (``axis``: its
    time base's label: boot time, or the time since the start of a Unix epoch clock),
    as in the summary and the CSV (gaps shown as gaps), when it never goes backwards;
    else (a reboot, a concatenated log) the sessions laid end to end from the first
    sample's boot time (:func:`joined_time`), each restart line labelled with its
    boot time."""
    t = np.asarray(time_s, dtype=np.float64)
    if len(t) < 2 or np.all(np.diff(t) >= 0):
        return t, f"{axis} (as in the summary and the CSV)"
    return (t[0] + joined_time(t, restarts),
            "time [s]: sessions joined end to end (boot time went backwards); restarts labelled with boot time")


#: shading of the flight segments (``report["segments"]`` kinds) on the time plots
#: the filtered line (dark) and the raw one (lighter, drawn above it, half transparent)
FILTERED_COLOUR, RAW_COLOUR = "#0b3d91", "#8fb3e8"
SEGMENT_COLOURS = {"ground": "0.85", "armed": "#ffe08a", "flying": "#b7e4c7", "hover": "#b9d4ff",
                   "after impact": "#f4b0b0"}


#: the percentiles of the samples an initial y range keeps, widened by
#: :data:`Y_MARGIN` of their span each side: a crash spike does not set it. 1-99, not
#: 0.1-99.9: log171's crash (about 2 s at up to 1100 deg/s) is ~1 % of its flying
#: samples, and 0.1-99.9 still gave +-600 deg/s for a flight within +-100
Y_PERCENTILES = (1.0, 99.0)
#: the margin of the initial y range, a share of the percentiles' span each side
Y_MARGIN = 0.5
#: what a clipped time plot says of its y range
Y_CLIPPED_NOTE = "y clipped to 1-99 % of the samples + 50 %"


def flying_mask(time_s, segments):
    """Bool per sample: inside a ``flying`` or ``hover`` segment (all False without)."""
    t = np.asarray(time_s, dtype=np.float64)
    m = np.zeros(len(t), dtype=bool)
    for g in segments or []:
        try:
            if g["kind"] in ("flying", "hover"):
                m |= (t >= float(g["start_s"])) & (t <= float(g["end_s"]))
        except (KeyError, TypeError, ValueError):
            continue
    return m


def robust_ylim(values, keep=None, margin=Y_MARGIN):
    """(lo, hi): the initial y range of a time plot, the :data:`Y_PERCENTILES` of the
    finite ``values`` ((n,) or (n, k) samples; only the rows where ``keep`` when it
    selects at least 100, e.g. the flying ones) widened by ``margin`` of their span
    each side; None when every finite sample lies within half that range's width of
    it (nothing worth clipping) or there is no finite sample."""
    v = np.asarray(values, dtype=np.float64)
    v2 = v.reshape(len(v), -1)
    allv = v2[np.isfinite(v2)]
    if not len(allv):
        return None
    sel = v2[keep] if keep is not None and int(np.count_nonzero(keep)) >= 100 else v2
    sel = sel[np.isfinite(sel)]
    if not len(sel):
        sel = allv
    lo, hi = np.percentile(sel, Y_PERCENTILES)
    span = max(hi - lo, 1e-9 * max(abs(lo), abs(hi), 1.0))
    lo, hi = lo - margin * span, hi + margin * span
    slack = 0.5 * (hi - lo)
    if allv.min() >= lo - slack and allv.max() <= hi + slack:
        return None
    return float(lo), float(hi)


def plot_stream(path, title, t, x, f, restarts, unit, axes=("x", "y", "z"), segments=None, axis=BOOT_AXIS):
    """PNG of raw and filtered per axis (``t``: the samples' boot times, s),
    restarts as dashed red lines; ``segments`` (``[{"kind", "start_s", "end_s"}]``,
    the log's time) shaded behind the lines when given. A stream written raw
    (``f`` None or equal to ``x``) gets one line, labelled as raw."""
    _draw(path, title, _plot_data(t, x, f, restarts, segments, axis), unit, axes)


def written_raw(x, f):
    """True when the output ``f`` is the raw record ``x`` (None, or equal, NaN alike):
    such a line must not be called "filtered"."""
    return f is None or np.array_equal(np.asarray(x), np.asarray(f), equal_nan=True)


def _plot_data(t, x, f, restarts, segments=None, axis=BOOT_AXIS):
    """What the plot needs: per axis the min/max envelopes (the filtered one None
    for a stream written raw), the restart times, their boot times (labels when the
    plot's time is not the boot time), the x label, the segments to shade
    (their times on the plot's axis; none when the plot's time is not the log's)
    and per axis the initial y range (:func:`robust_ylim` over the flying samples,
    else all; None where nothing is clipped)."""
    raw_only = written_raw(x, f)
    if raw_only:
        f = x
    pt, xlabel = plot_time(t, restarts, axis)
    keep = flying_mask(t, segments)
    ylims = [robust_ylim(np.column_stack([x[:, k]] + ([] if raw_only else [f[:, k]])), keep)
             for k in range(x.shape[1])]
    labels = None if pt is t or np.array_equal(pt, t) else np.asarray(t, dtype=np.float64)[restarts]
    rt = pt[restarts]
    cut = np.flatnonzero(restarts)          # no line drawn across a restart (a gap, a reboot)
    if len(cut):
        pt, x, f = (np.insert(pt, cut, np.nan), np.insert(x, cut, np.nan, axis=0),
                    np.insert(f, cut, np.nan, axis=0))
    lines = [(_envelope(pt, x[:, k]), None if raw_only else _envelope(pt, f[:, k])) for k in range(x.shape[1])]
    shade = []
    if segments and labels is None:
        for g in segments:
            try:
                shade.append((float(g["start_s"]), float(g["end_s"]), str(g["kind"])))
            except (KeyError, TypeError, ValueError):
                continue
    return lines, rt, labels, xlabel, shade, ylims


def _draw(path, title, pdata, unit, axes, spectrum=None):
    if spectrum is not None:                     # (path, title, [(stream, plot data)]) of gyrodenoise.flightlog.spectra
        from gyrodenoise.flightlog.spectra import draw_log_spectrum
        draw_log_spectrum(*spectrum)
    if pdata is None:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(len(axes), 1, figsize=(9, 6.5), sharex=True)
    fig.subplots_adjust(left=0.1, right=0.98, top=0.94, bottom=0.08, hspace=0.12)
    lines, rt, rlabels, xlabel, shade = pdata[:5]
    ylims = pdata[5] if len(pdata) > 5 else [None] * len(lines)
    for k, ax in enumerate(np.atleast_1d(axs)):
        kinds = set()
        for a, b, kind in shade:           # behind everything
            ax.axvspan(a, b, color=SEGMENT_COLOURS.get(kind, "#e8c6f0"), alpha=0.5, lw=0, zorder=0,
                       label=None if kind in kinds else kind)
            kinds.add(kind)
        if lines[k][1] is None:
            ax.plot(*lines[k][0], lw=0.8, color="C0", label="raw (written raw, NOT filtered)", zorder=2)
        else:
            # filtered first, raw above it, lighter and half transparent: both show
            ax.plot(*lines[k][1], lw=1.0, color=FILTERED_COLOUR, label="filtered", zorder=2)
            ax.plot(*lines[k][0], lw=0.6, color=RAW_COLOUR, alpha=0.6, label="raw", zorder=3)
        if len(rt):
            ax.vlines(rt, 0, 1, transform=ax.get_xaxis_transform(), colors="C3", lw=0.8,
                      linestyles="--", label="restart")
        if k == 0 and rlabels is not None and len(rt) <= 20:
            for x0, tb in zip(rt, rlabels):
                ax.text(x0, 0.02, f" t={tb:.1f} s", transform=ax.get_xaxis_transform(), fontsize=7,
                        color="C3", va="bottom")
        ax.set_ylabel(f"{axes[k]} [{unit}]")
        ax.grid(True, lw=0.3)
        if ylims[k] is not None:
            ax.set_ylim(*ylims[k])
    axs[0].legend(loc="upper right", fontsize=8, ncol=4)
    clipped = [a for a, y in zip(axes, ylims) if y is not None]
    axs[0].set_title(title + (f"  ({Y_CLIPPED_NOTE}: {', '.join(clipped)}; flying time where known)"
                              if clipped else ""), fontsize=9 if clipped else 10)
    axs[-1].set_xlabel(xlabel)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=90, pil_kwargs={"compress_level": 1})
    plt.close(fig)


def _plot_loop(conn):
    """Child process: import matplotlib while the parent filters, then plot jobs.
    Ends with its parent (:func:`gyrodenoise.flightlog.stopping.as_child`)."""
    as_child()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401
    while True:
        job = conn.recv()
        if job is None:
            break
        try:
            _draw(*job)
            conn.send(None)
        except Exception as exc:  # noqa: BLE001 - reported by the parent
            conn.send(f"{job[0]}: plot failed: {type(exc).__name__}: {exc}")
    conn.close()


class Plotter:
    """Plots inline, or in a forked helper process that overlaps the parent's work."""

    def __init__(self, background=False, helpers=1):
        self.procs, self.conns, self.threads, self.queues = [], [], [], []
        self.pending = []
        self.next = 0
        if background and sys.platform.startswith("linux"):
            import multiprocessing as mp
            import queue
            import threading
            ctx = mp.get_context("fork")
            for _ in range(max(1, int(helpers))):
                conn, child = ctx.Pipe()
                proc = ctx.Process(target=_plot_loop, args=(child,), daemon=True)
                with signals_blocked():           # until the helper ignores SIGINT itself
                    proc.start()
                child.close()
                # a thread does the sending: a send blocks while the helper is still importing
                q = queue.Queue()
                th = threading.Thread(target=self._sender, args=(conn, q), daemon=True)
                th.start()
                self.procs.append(proc)
                self.conns.append(conn)
                self.queues.append(q)
                self.threads.append(th)
                self.pending.append(0)

    @staticmethod
    def _sender(conn, q):
        while True:
            job = q.get()
            try:
                conn.send(job)
            except (OSError, ValueError):      # the helper was stopped (an interrupt): nothing to send to
                break
            if job is None:
                break

    def plot(self, path, title, t, x, f, restarts, unit, axes, segments=None, axis=BOOT_AXIS):
        """Queue (or draw) a stream's PNG (:func:`plot_stream`)."""
        self._submit((path, title, _plot_data(t, x, f, restarts, segments, axis), unit, axes))

    def plot_spectrum(self, path, title, items):
        """The spectrum PNG of a log: [(stream name, plot data)] (:mod:`gyrodenoise.flightlog.spectra`)."""
        self._submit((path, None, None, None, None, (path, title, items)))

    def _submit(self, job):
        if not self.procs:
            _draw(*job)
        else:
            i = self.next % len(self.procs)
            self.next += 1
            self.queues[i].put(job)
            self.pending[i] += 1

    def close(self):
        """Wait for the helpers; raise RuntimeError with the first failure. An
        interrupt while waiting stops them at once (:meth:`abort`)."""
        errors = []
        try:
            for proc, conn, q, th, n in zip(self.procs, self.conns, self.queues, self.threads, self.pending):
                try:
                    for _ in range(n):
                        r = conn.recv()
                        if r:
                            errors.append(r)
                except EOFError:
                    errors.append("plot helper process ended unexpectedly")
                q.put(None)
                th.join(timeout=30)
                proc.join(timeout=30)
                if proc.is_alive():
                    proc.terminate()
        except BaseException:
            self.abort()
            raise
        self.procs = []
        if errors:
            raise RuntimeError(errors[0])

    def abort(self):
        """Stop the helpers at once (the run was interrupted or failed): no waiting
        for plots; their partial files are deleted by the caller."""
        stop_processes(self.procs)
        for q in self.queues:
            q.put(None)
        for conn in self.conns:
            conn.close()
        self.procs = []


def title_note(s):
    """What a plot's title says of a stream written unfiltered."""
    if mm.too_slow_to_denoise(s.rate_hz):
        return "; too slow to denoise: written raw"
    if getattr(s, "not_filtered", None) or getattr(s, "left_raw", None):
        return "; NOT FILTERED: written raw"
    return ""
