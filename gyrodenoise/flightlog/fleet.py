"""The fleet report: one table, one JSON and one plot for a batch of logs.

Built from the summary of :func:`gyrodenoise.flightlog.dispatch.process_many` (local pool or
Dask cluster alike): a row per log and gyro stream with its samples, rate,
restarts, noise before/after, the low-band motion kept and the lag the filter
added (when the bridge measured them; averaged over the axes whose low band
holds motion above the noise, "no motion above the noise" when none does), its dominant
vibration peak (:func:`vibration_peak`), and a row per failed log with its reason; then each
log's dominant vibration peak (:func:`dominant_peaks_by_log`). The plot shows each stream's white-noise density per log, so that an
IMU that is noisier than its siblings stands out: the thing an operator opens.

Noise density, deg/s/sqrt(Hz): the bridge's noise figure is the sensor's
white-noise sigma (deg/s; :func:`gyrodenoise.analysis.motion_metrics.white_noise_std`,
the core's 4th-difference estimate, which slow motion does not lift), and
sigma / sqrt(fs / 2) is the one-sided density (the tests check it against
Welch's estimate on real logs). The table gives
the mean over the stream's axes (x, y, z) of the per-axis figures. Vibration
near the Nyquist frequency still lifts it; the table flags a stream whose density is more than 3 robust sigmas
above the median of the same IMU at the same stage (pre-/post-filter, :func:`peer_group`)
across the fleet, over each log's flying time where it has one, where DataFlash's older
names are the same IMUs as the newer ones (``IMU`` = ``IMU[0]``, ``IMU2`` =
``IMU[1]``, ``IMU3`` = ``IMU[2]``: :func:`compared_as`), and gives each
density's ratio to that median, or why there is none (no peer: fewer than 3
of that IMU with a density; no density). Streams too slow to denoise (telemetry at 1-4
Hz: whatever a filter removes there is motion as much as noise, and they are
written raw) get no density and no flag, and a note that says so. Each log's flight
review (flying time, vibration verdict, the filter review's recommendation) is a row of
a second table (:func:`format_log_table`); ``fleet.html`` links each log's HTML report.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

FLAG_SIGMAS = 3.0
#: what the noise columns are: the mean of the per-axis figures
NOISE_COLUMN = "mean of the x, y, z figures"


def noise_density(noise_deg_s, rate_hz):
    """One-sided white-noise density, deg/s/sqrt(Hz), from the white noise's
    sigma ``noise_deg_s`` (the bridge's noise figure) at ``rate_hz``:
    sigma / sqrt(rate_hz / 2); None if either is missing."""
    if noise_deg_s is None or not rate_hz or rate_hz <= 0:
        return None
    return float(noise_deg_s) / math.sqrt(rate_hz / 2.0)


def compared_as(stream):
    """The name a stream is compared under across logs: DataFlash's one-type-per-IMU
    names as the instance names of newer logs (IMU -> IMU[0], IMU2 -> IMU[1],
    IMU3 -> IMU[2]); any other name as it is."""
    m = re.fullmatch(r"IMU([23]?)", stream)
    return f"IMU[{int(m.group(1) or 1) - 1}]" if m else stream


def _mean(values):
    v = [x for x in values if x is not None and math.isfinite(x)]
    return sum(v) / len(v) if v else None


def log_review_fields(log):
    """A log's flight review as the fleet table gives it: ``flying_time_s``,
    ``vibration_verdict`` (``pass``/``warn``/``fail``, None: no verdict or no
    vibration data), ``recommended`` (the filter review's ``param_lines``, [] when it
    recommends nothing, None when there is no review) and ``report_html``."""
    vib = log.get("vibration") or {}
    fr = log.get("filter_review")
    return {"flying_time_s": log.get("flying_time_s"), "over": log.get("over"),
            "vibration_verdict": vib.get("verdict"),
            "recommended": None if not fr else list(fr.get("param_lines") or []),
            "report_html": log.get("report_html")}


def fleet_rows(summary):
    """Flat rows (dicts) for the fleet table: one per log and stream, one per failed log."""
    rows = []
    for log in summary.get("logs", []):
        review = log_review_fields(log)
        for s in log.get("streams", []):
            noise = s.get("noise", {})
            raw = _mean([a.get("raw") for a in noise.values()])
            filt = _mean([a.get("filtered") for a in noise.values()])
            unit_ok = s.get("noise_unit") == "deg/s"
            measured = {a: m for a, m in (s.get("motion") or {}).items() if m is not None}
            # motion kept is averaged over the axes that move; elsewhere the low band is noise
            kept = {a: m for a, m in measured.items() if m.get("motion_above_noise") is not False}
            rows.append({
                "log": Path(log["file"]).name, "file": log["file"], "stream": s["name"], "status": "ok",
                "compared_as": compared_as(s["name"]), "stage": s.get("stage"),
                "noise_over": s.get("noise_over"), **review,
                "samples": s.get("samples"), "rate_hz": s.get("rate_hz"), "restarts": s.get("restarts"),
                "noise_raw": raw, "noise_filtered": filt, "noise_unit": s.get("noise_unit"),
                "noise_of": NOISE_COLUMN,
                "too_slow_to_denoise": bool(s.get("too_slow_to_denoise")),
                "not_filtered": s.get("not_filtered"),
                "noise_density_deg_s_rthz": (noise_density(raw, s.get("rate_hz"))
                                             if unit_ok and not s.get("too_slow_to_denoise") else None),
                "lowband_corr": _mean([a.get("corr") for a in kept.values()]) if kept else None,
                "lowband_amplitude": _mean([a.get("amplitude_ratio") for a in kept.values()]) if kept else None,
                "lag_s": _mean([a.get("lag_s") for a in kept.values()]) if kept else None,
                "no_motion": bool(measured) and not kept,
                "all_zero": bool(s.get("all_zero")),
                "note": s.get("note", ""), "left_raw": s.get("left_raw"),
                "warnings": list(s.get("warnings", [])),
                "vibration_peak": vibration_peak(s),
                "saturation": s.get("saturation"),
            })
    for f in summary.get("failed", []):
        rows.append({"log": Path(f["file"]).name, "file": f["file"], "stream": "", "status": "failed",
                     "error": f["error"]})
    _flag(rows)
    return rows


def vibration_peak(stream_report):
    """The stream's dominant vibration peak (the strongest over its axes, from
    :mod:`gyrodenoise.flightlog.spectra`) as {axis, freq_hz, amplitude_rms, unit, harmonics_hz},
    or None (no spectrum, or no peak above the noise floor)."""
    spec = stream_report.get("spectrum") or {}
    q = spec.get("dominant_peak")
    if not q:
        return None
    return {"axis": q["axis"], "freq_hz": q["freq_hz"], "amplitude_rms": q["amplitude_rms"],
            "unit": spec.get("unit"), "harmonics_hz": list(q.get("harmonics_hz") or []),
            "present_in_segments": q.get("present_in_segments")}


def _peak_text(p):
    if not p:
        return ""
    text = f"{p['axis']} {p['freq_hz']:.3g} Hz, {p['amplitude_rms']:.2g} {p['unit']} rms"
    if p.get("present_in_segments") is not None:
        text += f" (in {100 * p['present_in_segments']:.0f} % of segments)"
    if p["harmonics_hz"]:
        text += ", harmonics " + ", ".join(f"{h:.3g}" for h in p["harmonics_hz"]) + " Hz"
    return text


def dominant_peaks_by_log(rows):
    """Markdown lines: each log's dominant vibration peak (the strongest over its
    streams whose amplitudes are in deg/s), naming the stream."""
    best = {}
    for r in rows:
        p = r.get("vibration_peak")
        if r["status"] != "ok" or not p or p["unit"] != "deg/s":
            continue
        if r["log"] not in best or p["amplitude_rms"] > best[r["log"]][1]["amplitude_rms"]:
            best[r["log"]] = (r["stream"], p)
    logs = sorted({r["log"] for r in rows if r["status"] == "ok"})
    return [f"- {name}: " + (f"{best[name][0]} {_peak_text(best[name][1])}" if name in best else
                             "no vibration peak above the noise floor (or no spectrum: streams too slow)")
            for name in logs]


def peer_group(row):
    """What a stream's density is compared with across the fleet: the same IMU
    (:func:`compared_as`) at the same stage (``pre-filter``/``post-filter``/``unknown``,
    :func:`gyrodenoise.flightlog.vehicle_filters.stream_stage`): the batch sampler's
    pre-filter 2 kHz gyro and a 25 Hz post-filter IMU stream are not alike. As text:
    ``"IMU[0] post-filter"`` (the IMU alone for a report without stages)."""
    stage = row.get("stage")
    return f"{row['compared_as']} {stage}" if stage else row["compared_as"]


def _flag(rows):
    """Mark streams whose noise density is far above the fleet's for the same IMU at
    the same stage (:func:`peer_group`); give each density's ratio to that median."""
    by = {}
    for r in rows:
        if r.get("noise_density_deg_s_rthz") is not None:
            r["peer_group"] = peer_group(r)
            by.setdefault(r["peer_group"], []).append(r)
    for group in by.values():
        vals = sorted(r["noise_density_deg_s_rthz"] for r in group)
        med = vals[len(vals) // 2]
        mad = sorted(abs(v - med) for v in vals)[len(vals) // 2] * 1.4826
        for r in group:
            v = r["noise_density_deg_s_rthz"]
            r["density_vs_fleet_median"] = v / med if len(vals) >= 3 and med > 0 else None
            r["fleet_size"] = len(vals)
            r["flag"] = bool(len(vals) >= 3 and mad > 0 and (v - med) > FLAG_SIGMAS * mad)
            if len(vals) < 3:
                r["vs_fleet_note"] = (f"no peer: the only {r['peer_group']} with a density in the fleet"
                                      if len(vals) == 1 else
                                      f"only {len(vals)} {r['peer_group']} with a density in the fleet "
                                      f"(a median needs 3)")
            elif not med > 0:
                r["vs_fleet_note"] = f"the fleet median of {r['peer_group']} is 0"
    for r in rows:
        if r["status"] == "ok" and r.get("noise_density_deg_s_rthz") is None:
            r["vs_fleet_note"] = ("no density: " + ("too slow to denoise" if r.get("too_slow_to_denoise") else
                                                    "unit unknown" if r.get("noise_unit") != "deg/s" else
                                                    "no noise figure (too few samples)"))
    # several IMUs of one log noisy together: the vehicle (vibration, motion) more
    # likely than one sick sensor; one IMU noisy beside normal siblings: that IMU
    per_log = {}
    for r in rows:
        if r["status"] == "ok" and r.get("noise_density_deg_s_rthz") is not None:
            per_log.setdefault(r["log"], []).append(r)
    for streams in per_log.values():
        flagged = [r for r in streams if r.get("flag")]
        if len(flagged) >= 2:
            for r in flagged:
                r["flag_why"] = (f"NOISY vs fleet, with {len(flagged) - 1} other IMU(s) of this log: "
                                 f"vehicle vibration or motion more likely than a sick IMU")
        elif flagged:
            others = len(streams) - 1
            flagged[0]["flag_why"] = ("NOISY vs fleet" + (f", its {others} sibling IMU(s) in this log normal: "
                                                          f"this IMU" if others else ""))


def _fmt(v, spec=".3g"):
    return "" if v is None else format(v, spec)


def _rate(v):
    """A sample rate as people write it: 2002, 50, 24.99, 2.38 (never 2e+03)."""
    return "" if v is None else f"{v:.0f}" if v >= 100 else f"{v:.4g}"


def _noise(r):
    if r.get("too_slow_to_denoise") or r.get("not_filtered") or r.get("left_raw"):
        return f"{_fmt(r['noise_raw'])} {r['noise_unit'] or ''} (written raw)"
    return f"{_fmt(r['noise_raw'])} -> {_fmt(r['noise_filtered'])} {r['noise_unit'] or ''}"


def _notes(r):
    notes = ([r.get("flag_why", "NOISY vs fleet")] if r.get("flag") else [])
    if r.get("all_zero"):
        notes.append("ALL ZERO: no data (sensor absent or dead)")
    sat = r.get("saturation")
    if sat:
        notes.append(f"AT FULL SCALE: {sum(sat['samples'].values())} sample(s) at >= "
                     f"{100 * sat['threshold'] / sat['full_scale']:.0f} % of +-{sat['full_scale']:g} {sat['unit']} "
                     f"(peak {sat['peak']:.5g}): likely saturated")
    if r.get("too_slow_to_denoise"):
        notes.append(f"too slow to denoise ({_rate(r['rate_hz'])} Hz < 20 Hz): written raw; its noise "
                     f"figure may be mostly motion (motion reaches its Nyquist frequency)")
    if r.get("not_filtered"):
        notes.append(f"not filtered: {r['not_filtered']}")
    if r.get("left_raw"):
        notes.append(f"left raw: {r['left_raw']}")
    return "; ".join(notes + r.get("warnings", []))


def format_table(rows):
    """The fleet table as Markdown."""
    head = (f"| log | stream | status | samples | rate Hz | restarts | noise raw -> filtered ({NOISE_COLUMN}) | "
            f"density deg/s/rtHz ({NOISE_COLUMN}) | x fleet median | 0-5 Hz kept (corr, amp) | lag ms | "
            f"dominant vibration peak | flag / reason |")
    out = [head, "|" + "---|" * 13]
    for r in rows:
        if r["status"] == "failed":
            out.append(f"| {r['log']} | | FAILED | | | | | | | | | {r['error']} |")
            continue
        kept = ("no motion above the noise" if r.get("no_motion") else
                "" if r["lowband_corr"] is None else
                f"{r['lowband_corr']:.3f}, {100 * r['lowband_amplitude']:.0f} %")
        lag = "" if r["lag_s"] is None else f"{1000 * r['lag_s']:.1f}"
        vs = vs_fleet_text(r)
        out.append(f"| {r['log']} | {r['stream']} | ok | {r['samples']} | {_rate(r['rate_hz'])} | {r['restarts']} | "
                   f"{_noise(r)} | {_fmt(r['noise_density_deg_s_rthz'])} | {vs} | {kept} | {lag} | "
                   f"{_peak_text(r.get('vibration_peak'))} | {_notes(r)} |")
    return "\n".join(out)


def vs_fleet_text(r):
    """The "x fleet median" cell: the ratio, or why there is none."""
    vs = r.get("density_vs_fleet_median")
    if vs is not None:
        return f"{vs:.2g}x of {r['fleet_size']} {r.get('peer_group', r['compared_as'])}"
    return r.get("vs_fleet_note") or ""


def _named(rows):
    """': log stream, ...' for the header line (empty when there are none)."""
    return (": " + ", ".join(f"{r['log']} {r['stream']}" for r in rows)) if rows else ""


def write_fleet_report(summary, out_dir, html=True):
    """Write ``fleet.json``, ``fleet.md``, ``fleet.png`` and (``html``) ``fleet.html``
    (:func:`gyrodenoise.flightlog.html_report.write_fleet_report`, each log linked to its
    own report) into ``out_dir``; return their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = fleet_rows(summary)
    n_ok = sum(r["status"] == "ok" for r in rows)
    head = (f"# Fleet report\n\n{summary.get('n_logs', 0)} logs: {summary.get('n_ok', 0)} processed, "
            f"{summary.get('n_failed', 0)} failed; {n_ok} gyro streams; "
            f"{sum(bool(r.get('flag')) for r in rows)} flagged as noisier than the fleet "
            f"(> {FLAG_SIGMAS:g} robust sigmas above the median density of the same IMU at the same stage, "
            f"pre- or post-filter, across the fleet; IMU, IMU2, IMU3 compared as IMU[0], IMU[1], IMU[2]; "
            f"noise over each log's flying time where it has one)"
            f"{_named([r for r in rows if r.get('flag')])}; "
            f"{sum(bool(r.get('all_zero')) for r in rows)} with all samples zero"
            f"{_named([r for r in rows if r.get('all_zero')])}; "
            f"{sum(bool(r.get('too_slow_to_denoise')) for r in rows)} too slow to denoise (telemetry below "
            f"20 Hz: written raw, no density).\n\n"
            f"Noise and density columns: {NOISE_COLUMN} (noise: the white-noise sigma, the core's "
            f"4th-difference estimate, which slow motion does not lift; filtered: the same estimate on the "
            f"output; density: sigma / sqrt(rate / 2)).\n\n"
            f"![noise density per log and stream](fleet.png)\n\n")
    peaks = ("\n\n## Flight, vibration and filter review per log\n\n" + format_log_table(summary) +
             "\n\n## Dominant vibration peak per log\n\n(the strongest spectral peak above the noise "
             "floor over the log's streams and axes; gyrodenoise.flightlog.spectra)\n\n" + "\n".join(dominant_peaks_by_log(rows)))
    from gyrodenoise.flightlog.stopping import atomic_path
    with atomic_path(out / "fleet.md") as tmp:
        tmp.write_text(head + format_table(rows) + peaks + "\n")
    with atomic_path(out / "fleet.json") as tmp:
        tmp.write_text(json.dumps({"rows": rows, "n_logs": summary.get("n_logs"),
                                   "n_ok": summary.get("n_ok"), "n_failed": summary.get("n_failed"),
                                   "flag_sigmas": FLAG_SIGMAS, "noise_of": NOISE_COLUMN},
                                  indent=1, allow_nan=False) + "\n")
    _plot(rows, out / "fleet.png")
    paths = [out / "fleet.md", out / "fleet.json", out / "fleet.png"]
    if html:
        from gyrodenoise.flightlog.html_report import write_fleet_report as write_fleet_html
        paths.append(write_fleet_html(out / "fleet.html", json.loads((out / "fleet.json").read_text()),
                                      summary.get("logs", [])))
    return paths


def format_log_table(summary):
    """The per-log table of the fleet report (Markdown): flying time, what the figures
    are over, the vibration verdict, the filter review's recommendation."""
    out = ["| log | flying s | figures over | vibration | filter review: recommended |", "|---|---|---|---|---|"]
    for log in summary.get("logs", []):
        f = log_review_fields(log)
        vib = (f["vibration_verdict"] or "no verdict") if log.get("vibration") else "no data"
        rec = ("none: " + (log.get("filter_review_note") or "no review").split(":")[0] if f["recommended"] is None else
               " ".join(f"`{x}`" for x in f["recommended"]) or "no change")
        fly = f["flying_time_s"]
        out.append(f"| {Path(log['file']).name} | {'' if fly is None else format(fly, '.1f')} | "
                   f"{f['over'] or ''} | {vib} | {rec.replace('|', '/')} |")
    return "\n".join(out)


def plot_title(rows):
    """fleet.png's title: what is plotted, and why some logs are in the table only."""
    shown = {r["log"] for r in rows if r["status"] == "failed" or r.get("noise_density_deg_s_rthz") is not None}
    rest = [r for r in rows if r["log"] not in shown]
    slow = {r["log"] for r in rest} - {r["log"] for r in rest if not r.get("too_slow_to_denoise")}
    other = {r["log"] for r in rest} - slow
    why = []
    if slow:
        why.append(f"{len(slow)} log(s) with telemetry streams only, below 20 Hz (too slow to denoise, written raw)")
    if other:
        why.append(f"{len(other)} log(s) whose streams have no density (unit unknown, or not measurable)")
    return ("Gyro noise per log and stream (grey, red name: log failed)"
            + "".join(f";\n{w}" for w in why) + (":\nin the table only" if why else ""))


def _plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ok = [r for r in rows if r["status"] == "ok" and r["noise_density_deg_s_rthz"] is not None]
    failed = sorted({r["log"] for r in rows if r["status"] == "failed"})
    # logs with a density to show, and the failed ones; the others (telemetry too
    # slow to denoise) are in the table only
    logs = sorted({r["log"] for r in ok} | set(failed))
    xi = {name: i for i, name in enumerate(logs)}
    # one colour per IMU as compared across the fleet (IMU and IMU[0] alike)
    groups = sorted({r["peer_group"] for r in ok})
    # side by side within a log, so that two IMUs with the same density both show
    dx = {name: (k - (len(groups) - 1) / 2.0) * min(0.12, 0.6 / max(1, len(groups)))
          for k, name in enumerate(groups)}
    fig, ax = plt.subplots(figsize=(max(7.0, 0.45 * len(logs) + 3), 5.2))
    for g in groups:
        pts = [r for r in ok if r["peer_group"] == g]
        other = sorted({r["stream"] for r in pts} - {r["compared_as"] for r in pts})
        label = g + (f" (also named {', '.join(other)})" if other else "")
        ax.plot([xi[r["log"]] + dx[g] for r in pts], [r["noise_density_deg_s_rthz"] for r in pts], "o",
                label=label)
    flagged = [r for r in ok if r.get("flag")]
    if flagged:
        ax.plot([xi[r["log"]] + dx[r["peer_group"]] for r in flagged],
                [r["noise_density_deg_s_rthz"] for r in flagged],
                "o", ms=14, mfc="none", mec="red", label="noisier than the fleet")
    for name in failed:
        ax.axvspan(xi[name] - 0.4, xi[name] + 0.4, color="0.85", lw=0)
    ax.set_xticks(range(len(logs)), logs, rotation=60, ha="right", fontsize=7)
    for label in ax.get_xticklabels():
        if label.get_text() in failed:
            label.set_color("C3")
    ax.set_yscale("log")
    ax.set_ylabel(f"raw noise density, deg/s/sqrt(Hz)\n({NOISE_COLUMN})")
    ax.set_title(plot_title(rows), fontsize=9)
    if ax.get_legend_handles_labels()[0]:          # nothing to label when every log failed
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    from gyrodenoise.flightlog.stopping import atomic_path
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
