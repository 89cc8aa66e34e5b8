"""``gyrodenoise mavlink``: the MAVLink bridge command (argparse layer only)."""

from __future__ import annotations

import contextlib
import json
import re
import sys
from pathlib import Path

from gyrodenoise.errors import InputError

LINK_RE = re.compile(r"^(udpin|udpout|udp|tcp|tcpin|udpbcast|serial|com\d*)[:]", re.IGNORECASE)

EPILOG = """\
examples:
  gyrodenoise mavlink flight.bin -o out            # DataFlash log: filtered log, CSV + PNG per stream
  gyrodenoise mavlink logs/ --jobs 4 --json        # every log of a folder, in parallel, one summary
  gyrodenoise mavlink flight.tlog --engine fmu     # same through the FogDenoiser FMU (fmpy)
  gyrodenoise mavlink udpin:127.0.0.1:14550 --forward udpout:127.0.0.1:14551 --duration 60

The filtered log keeps every message and byte of the input except the gyro
fields of the IMU messages, which hold the filtered values (and, for MAVLink,
the packet CRC). Raw values stay in the input log and in the CSV files.
"""


def _log(msg):
    print(f"gyrodenoise mavlink: {msg}", file=sys.stderr)


def register_cli(subparsers):
    p = subparsers.add_parser(
        "mavlink", help="denoise the gyro streams of MAVLink/DataFlash/ULog logs or a live link",
        description="Denoise every gyro stream of autopilot logs (.tlog, DataFlash .bin, PX4 .ulg) "
                    "or of a live MAVLink link, each axis with its own denoiser.",
        epilog=EPILOG, formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("logs", nargs="+", metavar="LOG",
                   help="log files, folders (every .tlog/.bin/.ulg inside), or one pymavlink "
                        "connection string (udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT)")
    p.add_argument("-o", "--out", default="out/mavlink", metavar="OUT",
                   help="output folder (default: out/mavlink)")
    p.add_argument("--json", action="store_true", help="print one JSON summary on stdout")
    p.add_argument("--engine", default="native", choices=["native", "fmu"],
                   help="native core (numba batch; default) or the FogDenoiser FMU through fmpy")
    p.add_argument("--fmu", default=None, metavar="PATH",
                   help="FogDenoiser.fmu for --engine fmu (default: build/FogDenoiser.fmu)")
    p.add_argument("--jobs", type=int, default=1, metavar="N", help="logs processed in parallel (processes)")
    p.add_argument("--method", default="shakf", choices=["shakf", "kf", "none", "sh_classic"],
                   help="filter (default shakf: the modified Sage-Husa AKF)")
    p.add_argument("--ar-order", type=int, default=3, metavar="N", help="AR model order (default 3)")
    p.add_argument("--gap-factor", type=float, default=5.0, metavar="K",
                   help="a time step over K times the recent sample period is a restart (default 5)")
    p.add_argument("--sample-rate", type=float, default=None, metavar="HZ",
                   help="filter sample rate for every stream (default: measured per stream; it only "
                        "sets the warm-up length)")
    p.add_argument("--warmup-s", type=float, default=None, metavar="S",
                   help="warm-up after each restart, raw passed through (default: the core's, 1 s; "
                        "at least 10(n+1) samples); short bursts such as the 2 kHz batch sampler "
                        "(1024 samples) need less, e.g. 0.1")
    p.add_argument("--outlier-sigma", type=float, default=None, metavar="K",
                   help="outlier gate: keep a sample with |innovation| > K sqrt(S) out of the filter "
                        "(default: the core's, 5; 0 = off, the paper's filter)")
    p.add_argument("--outlier-run", type=int, default=None, metavar="M",
                   help="consecutive rejected samples after which the filter re-opens (default 20)")
    p.add_argument("--raw-imu-unit", default="auto", choices=["auto", "mrad/s", "rad/s", "counts"],
                   help="unit of RAW_IMU gyro fields (default auto: mrad/s when the log shows "
                        "ArduPilot, else counts with unknown scale)")
    p.add_argument("--raw-imu-scale", type=float, default=None, metavar="DEG_S_PER_COUNT",
                   help="scale of RAW_IMU raw counts (old APM firmware)")
    p.add_argument("--no-plots", action="store_true", help="do not write PNG plots")
    p.add_argument("--no-csv", action="store_true", help="do not write CSV files")
    live = p.add_argument_group("live link (LOG is a connection string)")
    live.add_argument("--forward", default=None, metavar="CONN",
                      help="output connection, e.g. udpout:127.0.0.1:14551 (default: none, only report)")
    live.add_argument("--duration", type=float, default=None, metavar="S", help="stop after S seconds")
    live.add_argument("--count", type=int, default=None, metavar="N", help="stop after N messages")
    p.set_defaults(func=run)
    return p


def _check(args):
    if args.jobs < 1:
        raise InputError(f"--jobs must be >= 1, got {args.jobs}")
    if args.ar_order < 1:
        raise InputError(f"--ar-order must be >= 1, got {args.ar_order}")
    if not args.gap_factor > 1:
        raise InputError(f"--gap-factor must be > 1, got {args.gap_factor}")
    if args.sample_rate is not None and not args.sample_rate > 0:
        raise InputError(f"--sample-rate must be > 0, got {args.sample_rate}")
    if args.warmup_s is not None and not args.warmup_s >= 0:
        raise InputError(f"--warmup-s must be >= 0, got {args.warmup_s}")
    try:
        from gyrodenoise.core.kernels import make_params
        make_params(ar_order=args.ar_order, sample_rate_hz=50.0, **_filter_kw(args))
    except ValueError as exc:
        raise InputError(str(exc)) from None
    if args.raw_imu_scale is not None and not args.raw_imu_scale > 0:
        raise InputError(f"--raw-imu-scale must be > 0, got {args.raw_imu_scale}")
    if args.duration is not None and not args.duration > 0:
        raise InputError(f"--duration must be > 0, got {args.duration}")
    if args.count is not None and args.count < 1:
        raise InputError(f"--count must be >= 1, got {args.count}")


def _filter_kw(args):
    """Core filter parameters given on the command line (None = the core's default)."""
    kw = {}
    if args.outlier_sigma is not None:
        kw["outlier_sigma"] = float(args.outlier_sigma)
    if args.outlier_run is not None:
        kw["outlier_run"] = int(args.outlier_run)
    return kw


def _finite(obj):
    """NaN/inf (e.g. a noise figure of an all-NaN axis) as null: strict JSON."""
    if isinstance(obj, float):
        return obj if obj == obj and obj not in (float("inf"), float("-inf")) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def _emit(obj):
    sys.stdout.write(json.dumps(_finite(obj), allow_nan=False) + "\n")
    sys.stdout.flush()


def run(args):
    _check(args)
    links = [x for x in args.logs if LINK_RE.match(x) and not Path(x).exists()]
    if links:
        if len(args.logs) != 1:
            raise InputError(f"{links[0]}: a live connection must be the only LOG argument")
        return _run_live(args, links[0])
    for x in args.logs:
        if not Path(x).exists():
            raise InputError(f"{x}: no such file or folder")
    kw = dict(engine=args.engine, method=args.method, ar_order=args.ar_order,
              gap_factor=args.gap_factor, plots=not args.no_plots, csv=not args.no_csv,
              raw_imu_unit=args.raw_imu_unit, raw_imu_scale=args.raw_imu_scale,
              fmu_path=args.fmu, sample_rate=args.sample_rate, warmup_s=args.warmup_s,
              filter_kw=_filter_kw(args))
    single = len(args.logs) == 1 and Path(args.logs[0]).is_file()
    # stdout carries only our output: third-party prints (pymavlink, pyulog) go to stderr
    with contextlib.redirect_stdout(sys.stderr):
        summary = _run_files(args, kw, single)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    (Path(args.out) / "summary.json").write_text(json.dumps(_finite(summary), indent=1, allow_nan=False))
    for f in summary["failed"]:
        print(f"gyrodenoise: error: {f['error']}", file=sys.stderr)
    try:
        if args.json:
            _emit(summary)
        else:
            _print_text(summary)
            sys.stdout.flush()
    except BrokenPipeError:           # e.g. piped into `head`: the reader left, not an error of ours
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 2 if summary["failed"] else 0


def _run_files(args, kw, single):
    from .process import process_many, process_log
    if single:
        # one file: errors are the command's error (exit 2, one line)
        from .streams import NOISE_METRIC
        rep = process_log(args.logs[0], args.out, log=_log, background_plots=True, plot_helpers=1, **kw)
        return {"logs": [rep], "failed": [], "ignored_files": [], "n_logs": 1, "n_ok": 1,
                "n_failed": 0, "jobs": 1, "seconds": rep["seconds"], "noise_metric": NOISE_METRIC}
    summary = process_many(args.logs, args.out, jobs=args.jobs, log=_log, **kw)
    if summary["n_logs"] == 0:
        raise InputError(f"{', '.join(args.logs)}: no .tlog, .bin or .ulg file found")
    return summary


def _fmt(v, nd=4):
    return "-" if v is None else f"{v:.{nd}g}"


def _print_text(summary):
    out = sys.stdout
    for r in summary["logs"]:
        trunc = f", truncated ({r['truncated_bytes']} bytes cut)" if r.get("truncated") else ""
        unread = r.get("unreadable_records")
        out.write(f"{r['file']} ({r['format']}): {r['messages']} messages, "
                  f"{'-' if unread is None else unread} unreadable records skipped{trunc}\n")
        out.write(f"  filtered log: {r['output_log']}\n")
        for s in r["streams"]:
            out.write(f"  {s['name']:<16} {s['samples']:>7} samples  {_fmt(s['rate_hz'])} Hz  "
                      f"{s['restarts']} restart(s)  unit {s['field_unit']}"
                      f"{'' if s['unit_known'] else ' (scale unknown)'}\n")
            for a, nz in s["noise"].items():
                out.write(f"      {a}: noise {_fmt(nz['raw'])} -> {_fmt(nz['filtered'])} {s['noise_unit']}"
                          f"  (x{_fmt(nz['ratio'], 3)})\n")
        for e in r["restarts"]:
            out.write(f"  restart: {e['stream']} sample {e['sample']} at t={e['time_s']:.3f} s "
                      f"(previous {e['previous_time_s']:.3f} s): {e['reason']}\n")
    for f in summary["failed"]:
        out.write(f"FAILED {f['file']}: {f['error']}\n")
    out.write(f"{summary['n_ok']} of {summary['n_logs']} log(s) processed in {summary['seconds']} s\n")


def _run_live(args, conn):
    with contextlib.redirect_stdout(sys.stderr):
        rep, streams = _live(args, conn)
    return _report_live(args, conn, rep, streams)


def _live(args, conn):
    from .live import run_live
    return run_live(conn, args.forward, duration=args.duration, max_messages=args.count,
                    method=args.method, ar_order=args.ar_order, gap_factor=args.gap_factor,
                    sample_rate=args.sample_rate, raw_imu_unit=args.raw_imu_unit,
                    raw_imu_scale=args.raw_imu_scale, log=_log, warmup_s=args.warmup_s,
                    filter_kw=_filter_kw(args))


def _report_live(args, conn, rep, streams):
    from .process import plot_stream, safe_name, stream_report, write_csv, joined_time
    out = Path(args.out)
    srep, restarts = [], []
    for s in streams:
        x, f, unit, _ = s._work
        csv_path = png_path = None
        if s.n and (not args.no_csv or not args.no_plots):
            out.mkdir(parents=True, exist_ok=True)
        if s.n and not args.no_csv:
            csv_path = out / f"live.{safe_name(s.name)}.csv"
            write_csv(csv_path, s, x, f, unit)
        if s.n and not args.no_plots:
            png_path = out / f"live.{safe_name(s.name)}.png"
            plot_stream(png_path, f"{conn}: {s.name}", joined_time(s.time_s, s.restarts), x, f,
                        s.restarts, unit, s.axes)
        srep.append(stream_report(s, csv_path, png_path))
        restarts += s.restart_events
    rep["streams"] = srep
    rep["restarts"] = restarts
    from .streams import NOISE_METRIC
    rep["noise_metric"] = NOISE_METRIC
    if args.json:
        _emit(rep)
    else:
        sys.stdout.write(f"{conn} -> {args.forward or '(nowhere)'}: {rep['messages_in']} messages in, "
                         f"{rep['messages_forwarded']} forwarded, {rep['unreadable_records']} unreadable, "
                         f"stopped by {rep['stopped_by']} after {rep['seconds']} s\n")
        for s in srep:
            sys.stdout.write(f"  {s['name']}: {s['samples']} samples, {s['restarts']} restart(s)\n")
    return 0
