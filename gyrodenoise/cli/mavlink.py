"""``gyrodenoise mavlink``: the MAVLink bridge command (argparse layer only)."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import sys
from pathlib import Path

from gyrodenoise._extras import require
from gyrodenoise.cli.options import (METHOD_OPTIONS, add_filter_options, check_core_params, check_method_options,
                                     core_default, filter_kw, integer, number)
from gyrodenoise.cli.program import emit_json
from gyrodenoise.console import log
from gyrodenoise.core.kernels import DEFAULT_METHOD
from gyrodenoise.core.methods import BY_OPTION, METHODS, PARAMS
from gyrodenoise.errors import InputError

LINK_RE = re.compile(r"^(udpin|udpout|udp|tcp|tcpin|udpbcast|serial|com\d*)[:]", re.IGNORECASE)

EPILOG = """\
examples:
  gyrodenoise mavlink flight.bin -o out            # DataFlash log: filtered log, CSV + PNG per stream
  gyrodenoise mavlink logs/ --jobs 4 --json        # every log of a folder, in parallel, one summary
  gyrodenoise mavlink flight.tlog --engine fmu     # same through the FogDenoiser FMU (fmpy)
  gyrodenoise mavlink udpin:127.0.0.1:14550 --forward udpout:127.0.0.1:14551 --duration 60
  gyrodenoise mavlink signed.tlog --signing-key ~/.mavlink.key   # a signed link: verify, re-sign

The filtered log keeps every message and byte of the input except the gyro
fields of the IMU messages, which hold the filtered values (and, for MAVLink,
the packet CRC). Raw values stay in the input log and in the CSV files.

Each stream's filtered output is checked: finite, inside the raw range of each
session (restart to restart), and fitting the log's field type. A stream that
fails is written RAW (unfiltered) into the filtered log, with one line on stderr.
The summary gives, per axis, the noise figure (raw -> filtered) and beside it
the 0-5 Hz motion the filter kept (correlation, amplitude %) and the lag it
added; it warns when the filter removed most of the real motion. Streams
sampled below 20 Hz (telemetry RAW_IMU at 1-4 Hz) are too slow to denoise: they
are written raw (unfiltered, bit for bit) with a note instead of an improvement
figure. A stream the filter never changed (every session shorter than its
warm-up, e.g. the 2 kHz batch sampler's 1024-sample bursts) says why.
With --method lowpass the summary gives each stream's cutoff (default
min(20 Hz, rate / 4): 12.5 Hz on a 50 Hz log).

Signed MAVLink 2 (telemetry logs and live links): a signed packet is never
written or forwarded unsigned. With --signing-key FILE every packet is checked;
unsigned (once signed packets have come) or badly signed ones are dropped and
counted, and every changed packet is re-signed. Without it, signed packets go
out unchanged (gyro raw) and the summary says how many.

exit status:
  0  every log processed; every stream filtered and checked, or written raw for
     the reason its summary line states (too slow to denoise, no session longer
     than the warm-up, a --cutoff-hz it cannot take)
  1  completed, but some stream was left raw (its filtered output failed the check)
  2  bad usage or bad input (an option value, a path, a log that cannot be used):
     one line on stderr naming the option or file; with --json one JSON object
     on stdout with "error" in it
  130 interrupted (SIGINT, Ctrl-C), 143 terminated (SIGTERM): one line on stderr,
     every worker and plot process stopped, no partial output file (files are
     written under a temporary name and renamed when complete)
"""


def _log(msg):
    log(msg, prefix="gyrodenoise mavlink: ")


def register_cli(subparsers):
    p = subparsers.add_parser(
        "mavlink", help="denoise the gyro streams of MAVLink/DataFlash/ULog logs or a live link",
        description="Denoise every gyro stream of autopilot logs (.tlog, DataFlash .bin, PX4 .ulg) "
                    "or of a live MAVLink link, each axis with its own denoiser.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter, json_errors=True)
    _add_run_options(p)
    # per stream, the tuning options not given take the core's defaults at the stream's rate
    form = dict(help=_filter_option_help(), metavar={"--order": "N", "--ar-order": "N", "--warmup-s": "S"},
                strict_numbers=True, unset=("--order", "--warmup-s", "--outlier-sigma", "--outlier-run"))
    add_filter_options(p, ("--method", *METHOD_OPTIONS, "--ar-order"), **form)
    p.add_argument("--gap-factor", type=number, default=5.0, metavar="K",
                   help="a time step over K times the recent sample period is a restart (default 5)")
    p.add_argument("--sample-rate", type=number, default=None, metavar="HZ",
                   help=f"filter sample rate for every stream, 0 < HZ <= {MAX_SAMPLE_RATE_HZ:g} (default: "
                        f"measured per stream; it sets the warm-up length and the low-pass design)")
    add_filter_options(p, ("--warmup-s", "--outlier-sigma", "--outlier-run"), **form)
    p.add_argument("--raw-imu-unit", default="auto", choices=["auto", "mrad/s", "rad/s", "counts"],
                   help="unit of RAW_IMU gyro fields (default auto: mrad/s when the log shows "
                        "ArduPilot, else counts with unknown scale)")
    p.add_argument("--raw-imu-scale", type=number, default=None, metavar="DEG_S_PER_COUNT",
                   help="scale of RAW_IMU raw counts (old APM firmware)")
    p.add_argument("--signing-key", default=None, metavar="FILE",
                   help="MAVLink 2 signing key of the link (.tlog and live links): FILE holds 64 hex digits, or "
                        "the signing passphrase (its SHA-256 is the key). Every packet is checked (unsigned or "
                        "badly signed ones on a signed link are dropped and counted) and every changed packet "
                        "re-signed. Without it a signed packet goes out unchanged (gyro raw)")
    p.add_argument("--no-plots", action="store_true",
                   help="do not write PNG plots nor the HTML report (NAME.report.html, fleet.html)")
    p.add_argument("--plotlyjs", default="inline", choices=["inline", "shared"],
                   help="inline: each HTML report holds plotly.js (opens alone, ~4.7 MB a page; default); "
                        "shared: plotly.min.js written once into OUT, every report and fleet.html refer to it "
                        "(keep the folder together)")
    p.add_argument("--whole-log", action="store_true",
                   help="compute the spectra, noise figures, filter review and vibration over the whole log "
                        "(default: over the flying segments, \"over\": \"flying\"; a log with no flying "
                        "segment: the whole log, and the summary says so)")
    p.add_argument("--no-csv", action="store_true", help="do not write CSV files")
    p.add_argument("--store", default=None, metavar="DIR",
                   help="append each reviewed log's figures and per-segment spectra to the fleet store DIR "
                        "(Parquet; a log already there is replaced, not counted twice; gyrodenoise "
                        "fleet-trends DIR reads it; needs pip install 'gyrodenoise[fleet]')")
    p.add_argument("--kalibr-yaml-flight", default=None, metavar="PATH",
                   help="write a Kalibr imu.yaml of the noise measured in flight (flying segments; random "
                        "walks from rest segments; one log only; a figure not measured is written .nan "
                        "with a comment)")
    p.add_argument("--airframe", default=None, metavar="NAME",
                   help="with --store: the airframe these logs belong to (default: the vehicle id the log "
                        "records, else the name of the folder holding the log)")
    live = p.add_argument_group("live link (LOG is a connection string)")
    live.add_argument("--forward", default=None, metavar="CONN",
                      help="output connection, e.g. udpout:127.0.0.1:14551 (default: none, only report)")
    live.add_argument("--duration", type=number, default=None, metavar="S",
                      help="stop after S seconds (live link only; refused with log files)")
    live.add_argument("--count", type=integer, default=None, metavar="N",
                      help="stop after N messages (live link only; refused with log files)")
    p.set_defaults(func=run)
    return p


def _add_run_options(p):
    """LOG, the output and how the logs are run (parallel, on a cluster, progress)."""
    p.add_argument("logs", nargs="+", metavar="LOG",
                   help="log files, folders (every .tlog/.bin/.ulg inside), or one pymavlink "
                        "connection string (udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT)")
    p.add_argument("-o", "--out", default="out/mavlink", metavar="OUT",
                   help="output folder (default: out/mavlink)")
    p.add_argument("--json", action="store_true", help="print one JSON summary on stdout")
    p.add_argument("--engine", default="native", choices=["native", "fmu"],
                   help="native core (the C core; default) or the FogDenoiser FMU through fmpy")
    p.add_argument("--fmu", default=None, metavar="PATH",
                   help="FogDenoiser.fmu for --engine fmu (default: build/FogDenoiser.fmu)")
    p.add_argument("--jobs", type=integer, default=1, metavar="N", help="logs processed in parallel (processes)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="run each log as one task on this Dask distributed scheduler (outputs identical to a "
                        "serial run; needs pip install 'gyrodenoise[cluster]'); LOG and -o may then also be "
                        "fsspec URLs (s3://, file://, memory://) readable by every worker")
    prog = p.add_mutually_exclusive_group()
    prog.add_argument("--progress", dest="progress", action="store_true", default=None,
                      help="show logs done / failed / remaining and samples/s on stderr (default: when stderr "
                           "is a terminal)")
    prog.add_argument("--no-progress", dest="progress", action="store_false")


def _filter_option_help():
    """The bridge's wording of the filter options: each stream is filtered at its own rate,
    a live link as it comes."""
    return {
        "--method": f"filter (default {DEFAULT_METHOD}): "
                    + "; ".join(f"{m.name}: {m.help}" for m in METHODS),
        "--cutoff-hz": "--method lowpass: -3 dB cutoff (default min(20 Hz, a quarter of each stream's "
                       "sample rate); the summary gives the one applied per stream)",
        "--order": f"--method lowpass: Butterworth order 1..8 (default {core_default('order')})",
        "--zero-phase": "--method lowpass: filter forwards then backwards, each session on its own (no "
                        "lag, squared magnitude; offline files only, not --engine fmu or a live link)",
        "--causal": "--method motion on log files: the causal filter (as a live link, Denoiser.step and "
                    "the FMUs run it); default on files: offline, the forward and backward runs blended "
                    "per session (no lag). A live link and --engine fmu are always causal",
        "--max-motion-hz": "--method motion, rigid-body option for frames that vibrate (drones): the band of "
                           "interest; content above it counts as error (a 4th-order Butterworth before the "
                           "filter bank, flat to HZ, -3 dB at 2 HZ, -24 dB at 4 HZ); "
                           f"{core_default('max_motion_hz'):g} = off (default); a stream whose "
                           "Nyquist is not above HZ is written raw, with the reason",
        "--ar-order": f"AR model order, 1..{MAX_AR_ORDER} (default {core_default('ar_order')})",
        "--warmup-s": f"warm-up after each restart, raw passed through (default: the core's, "
                      f"{core_default('warmup_s'):g} s; at least 10(n+1) samples); short bursts such as the "
                      "2 kHz batch sampler (1024 samples) need less, e.g. 0.1",
        "--outlier-sigma": "outlier gate: keep a sample with |innovation| > K sqrt(S) out of the filter "
                           f"(default: the core's, {core_default('outlier_sigma'):g}; 0 = off, the paper's "
                           "filter)",
        "--outlier-run": "consecutive rejected samples after which the filter re-opens "
                         f"(default {core_default('outlier_run')})",
    }


#: --ar-order above this is refused: the RLS state grows as n^2 (n = 1e6 is a
#: MemoryError), and orders above ~10 never helped on gyro data
MAX_AR_ORDER = 64
#: --warmup-s above this (s) is refused: longer than any log, and warmup_s x rate
#: must stay a finite number of samples
MAX_WARMUP_S = 1.0e6
#: --sample-rate above this (Hz) is refused: no gyro is sampled faster (the fastest
#: in logs is the 2 kHz batch sampler), and the warm-up of 1 s would be 1e5 samples
MAX_SAMPLE_RATE_HZ = 1.0e5
#: sample rate used to check the core's parameters when --sample-rate is not given
#: (measured per stream; the fastest seen in logs is the 2 kHz batch sampler)
_CHECK_RATE_HZ = MAX_SAMPLE_RATE_HZ


def _finite_num(v):
    return v is not None and math.isfinite(v)


def _check(args):
    """Every option value: one line naming the option (InputError, exit 2)."""
    from gyrodenoise.flightlog.cluster import is_url
    _check_run_options(args)
    _check_filter_options(args)
    if args.raw_imu_scale is not None and not (_finite_num(args.raw_imu_scale) and args.raw_imu_scale > 0):
        raise InputError(f"--raw-imu-scale must be a finite number > 0, got {args.raw_imu_scale}")
    if args.duration is not None and not (_finite_num(args.duration) and args.duration > 0):
        raise InputError(f"--duration must be a finite number > 0 s, got {args.duration}")
    if args.count is not None and args.count < 1:
        raise InputError(f"--count must be >= 1, got {args.count}")
    if args.plotlyjs == "shared" and is_url(args.out):
        raise InputError(f"--plotlyjs shared: -o {args.out} must be a local folder (the pages refer to "
                         f"plotly.min.js beside them)")
    if args.kalibr_yaml_flight is not None and (len(args.logs) != 1 or Path(args.logs[0]).is_dir()):
        raise InputError("--kalibr-yaml-flight: one log file only (the yaml describes one IMU in one flight)")
    _check_store(args)


def _check_store(args):
    """--store DIR: a folder that is a store, or that can become one; --airframe needs it."""
    from gyrodenoise.flightlog.cluster import is_url
    if args.airframe is not None and args.store is None:
        raise InputError("--airframe applies with --store only")
    if args.airframe is not None and not args.airframe.strip():
        raise InputError("--airframe must be a non-empty name")
    if args.store is None:
        return
    if is_url(args.store):
        raise InputError(f"--store {args.store}: the store is a local folder (not a URL)")
    p = Path(args.store)
    if p.exists() and not p.is_dir():
        raise InputError(f"--store {args.store}: exists and is not a folder")
    if p.is_dir() and any(p.iterdir()):
        from gyrodenoise.flightlog.fleet_store import is_store
        if not is_store(p):
            raise InputError(f"--store {args.store}: a folder that is not a fleet store (no logs/ table in it)")


def _check_run_options(args):
    """--jobs and --scheduler."""
    if args.jobs < 1:
        raise InputError(f"--jobs must be >= 1, got {args.jobs}")
    if args.scheduler is not None:
        if not re.match(r"^(tcp|tls|inproc|ucx|ws|wss)://\S+$", args.scheduler):
            raise InputError(f"--scheduler must be a Dask scheduler address such as tcp://HOST:PORT, "
                             f"got {args.scheduler!r}")
        if args.jobs != 1:
            raise InputError("--jobs and --scheduler exclude each other (the cluster decides the parallelism)")
        from gyrodenoise.flightlog.cluster import require_dask
        require_dask("--scheduler")


def _check_filter_options(args):
    """The filter options, --gap-factor and --sample-rate: the bridge's bounds, then the core's checks."""
    if not 1 <= args.ar_order <= MAX_AR_ORDER:
        raise InputError(f"--ar-order must be 1..{MAX_AR_ORDER}, got {args.ar_order}")
    if not (_finite_num(args.gap_factor) and args.gap_factor > 1):
        raise InputError(f"--gap-factor must be a finite number > 1, got {args.gap_factor}")
    if args.sample_rate is not None and not (_finite_num(args.sample_rate) and
                                             0 < args.sample_rate <= MAX_SAMPLE_RATE_HZ):
        raise InputError(f"--sample-rate must be a number of Hz in (0, {MAX_SAMPLE_RATE_HZ:g}], "
                         f"got {args.sample_rate:g}")
    check_method_options(args, METHOD_OPTIONS, notes={"--causal": " (the other methods are causal unless --zero-phase)"})
    # each option given against the registry's range (the band options' Nyquist bound is checked
    # per stream, at its rate, when it is filtered: a stream too slow for it is written raw)
    for opt, par in BY_OPTION.items():
        value = getattr(args, par.name, None)
        why = None if value is None else par.error(value)
        if why is not None:
            raise InputError(f"{opt}: {why}")
    if args.warmup_s is not None and not args.warmup_s <= MAX_WARMUP_S:
        raise InputError(f"--warmup-s must be a number of seconds in [0, {MAX_WARMUP_S:g}], "
                         f"got {args.warmup_s}")
    try:
        # the cutoff is checked against each stream's rate when it is filtered
        # (a stream too slow for it is written raw, with the reason)
        check_core_params(ar_order=args.ar_order, method=args.method,
                          sample_rate_hz=args.sample_rate or _CHECK_RATE_HZ, name_options=True, **filter_kw(args))
    except OverflowError as exc:
        raise InputError(f"--warmup-s {args.warmup_s} x --sample-rate {args.sample_rate}: the warm-up is "
                         f"not a finite number of samples ({exc})") from None


def _check_out(out, created=None):
    """-o OUT must be a folder we can create/write: one line naming it otherwise.
    The folders it creates are appended to ``created`` (outermost first), so that
    a run that fails removes them again (:func:`_clean_up`)."""
    p = Path(out)
    if p.exists() and not p.is_dir():
        raise InputError(f"-o {out}: exists and is not a folder")
    missing = [q for q in [p, *p.parents] if not q.exists()][::-1]
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"-o {out}: cannot create the output folder ({exc.strerror or exc})") from None
    finally:
        if created is not None:
            created += [q for q in missing if q.is_dir()]
    if not os.access(p, os.W_OK | os.X_OK):
        raise InputError(f"-o {out}: output folder is not writable")


def _clean_up(out, created):
    """After a failed or interrupted run: the partial files in ``out``
    (:mod:`gyrodenoise.flightlog.stopping`), then the folders this run created, if empty."""
    from gyrodenoise.flightlog.cluster import is_url
    from gyrodenoise.flightlog.stopping import remove_partials
    if out is None or is_url(out):
        return
    remove_partials(out)
    for q in reversed(created):
        try:
            q.rmdir()           # only an empty folder
        except OSError:
            break


def _filter_kw(args):
    """The core filter parameters given on the command line (None = the core's default),
    the warm-up apart: the bridge passes it on its own (``warmup_s=``)."""
    return {k: v for k, v in filter_kw(args).items() if k != "warmup_s"}


def _finite(obj):
    """NaN/inf (e.g. a noise figure of an all-NaN axis) as null: strict JSON."""
    if isinstance(obj, float):
        return obj if obj == obj and obj not in (float("inf"), float("-inf")) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def run(args):
    """The command; returns the exit status (0 ok, 1 a stream left raw, 2 bad input).
    A user error is an InputError (one line on stderr from the top-level CLI); with
    --json one JSON object holding it is printed on stdout first."""
    created = []
    try:
        return _run(args, created)
    except InputError:
        _clean_up(args.out, created)
        raise                       # the top-level CLI prints it (and, with --json, its JSON object)
    except BaseException:           # an interrupt (SIGINT/SIGTERM) or a crash: no partial file, no empty folder
        _clean_up(args.out, created)
        raise


def _require_extras(args):
    """The log readers ([logs]) always; the plots and HTML reports ([report]) unless --no-plots;
    fsspec ([cluster]) for an input or output URL."""
    from gyrodenoise.flightlog.cluster import is_url
    require("logs", what="gyrodenoise mavlink")
    if not args.no_plots:
        require("report", what="gyrodenoise mavlink's plots and HTML report (or --no-plots)")
    urls = [x for x in [*args.logs, args.out] if x is not None and is_url(x)]
    if urls:
        require("cluster", "fsspec", what=f"gyrodenoise mavlink's URL {urls[0]}")
    if args.store is not None:
        require("fleet", what="gyrodenoise mavlink --store")


def _signing_key(args):
    """The key of --signing-key (None without it); one line, exit 2, when it cannot be used."""
    if getattr(args, "signing_key", None) is None:
        return None
    from gyrodenoise.flightlog.signing import read_key
    return read_key(args.signing_key, warn=_log)


def _run(args, created):
    _require_extras(args)
    _check(args)
    args.key = _signing_key(args)
    links = [x for x in args.logs if LINK_RE.match(x) and not Path(x).exists()]
    if links:
        if len(args.logs) != 1:
            raise InputError(f"{links[0]}: a live connection must be the only LOG argument")
        if args.store is not None:
            raise InputError("--store applies to log files, not to a live link")
        if args.zero_phase:
            raise InputError("--zero-phase: a live link is filtered as it comes (causal); "
                             "zero phase needs the whole record")
        if not (args.no_csv and args.no_plots):
            _check_out(args.out, created)
        return _run_live(args, links[0])
    for opt, v in (("--count", args.count), ("--duration", args.duration), ("--forward", args.forward)):
        if v is not None:
            raise InputError(f"{opt} applies to a live link (udpin:, tcp:, ...) only, not to log files")
    from gyrodenoise.flightlog.cluster import connect, is_url
    for x in args.logs:
        if not is_url(x) and not Path(x).exists():
            raise InputError(f"{x}: no such file or folder")
    # the cluster answers before anything is written (no output folder for a wrong address)
    client = None if args.scheduler is None else connect(args.scheduler)
    try:
        return _run_logs(args, client, created)
    finally:
        if client is not None:
            client.close()


def _run_logs(args, client, created):
    from gyrodenoise.flightlog.cluster import is_url
    if not is_url(args.out):
        _check_out(args.out, created)
    kw = dict(engine=args.engine, method=args.method, ar_order=args.ar_order,
              gap_factor=args.gap_factor, plots=not args.no_plots, csv=not args.no_csv,
              raw_imu_unit=args.raw_imu_unit, raw_imu_scale=args.raw_imu_scale,
              fmu_path=args.fmu, sample_rate=args.sample_rate, warmup_s=args.warmup_s,
              filter_kw=_filter_kw(args), zero_phase=args.zero_phase, causal=args.causal,
              signing_key=args.key, whole_log=args.whole_log)
    from gyrodenoise.flightlog.formats import folder_format
    one = Path(args.logs[0]) if len(args.logs) == 1 and not is_url(args.logs[0]) else None
    # one log: a file, or a folder that is itself one log (a ROS 2 bag)
    single = (one is not None and (one.is_file() or (one.is_dir() and folder_format(one) is not None))
              and args.scheduler is None)
    # stdout carries only our output: third-party prints (pymavlink, pyulog) go to stderr
    with contextlib.redirect_stdout(sys.stderr):
        summary = _run_files(args, kw, single, client)
    if args.store is not None:
        summary["store"] = _append_to_store(args, summary)
    if args.kalibr_yaml_flight is not None:
        summary["kalibr_yaml_flight"] = _write_kalibr_flight(args.kalibr_yaml_flight, summary)
    try:
        _write_out(args.out, "summary.json", json.dumps(_finite(summary), indent=1, allow_nan=False))
        if not single:
            summary["fleet_report"] = _fleet_report(summary, args.out, html=not args.no_plots)
    except OSError as exc:
        raise InputError(f"-o {args.out}: cannot write summary.json ({exc.strerror or exc})") from None
    if args.plotlyjs == "shared" and not args.no_plots:
        try:
            _share_plotlyjs(summary, args.out)
        except OSError as exc:
            raise InputError(f"-o {args.out}: cannot write plotly.min.js ({exc.strerror or exc})") from None
    if summary["failed"]:
        log(f"gyrodenoise: {summary['n_failed']} of {summary['n_logs']} log(s) failed")
    for f in summary["failed"]:
        log(f"gyrodenoise: error: {f['error']}")
    try:
        if args.json:
            emit_json(_finite(summary))
        else:
            _print_text(summary)
            sys.stdout.flush()
    except BrokenPipeError:           # e.g. piped into `head`: the reader left, not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return summary["exit_status"]


def _write_kalibr_flight(path, summary):
    """Write the Kalibr imu.yaml of the one log's in-flight noise to ``path``; its path, or
    None with a line on stderr when the log gave no in-flight figures."""
    from gyrodenoise.flightlog.inflight_noise import kalibr_yaml
    from gyrodenoise.flightlog.stopping import atomic_path
    rep = summary["logs"][0] if summary["logs"] else {}
    nz = rep.get("inflight_noise")
    if not nz:
        _log(f"--kalibr-yaml-flight {path}: not written: "
             f"{rep.get('inflight_noise_note') or 'the log was not reviewed'}")
        return None
    try:
        with atomic_path(Path(path)) as tmp:
            Path(tmp).write_text(kalibr_yaml(nz["kalibr_flight"]))
    except OSError as exc:
        raise InputError(f"--kalibr-yaml-flight {path}: cannot write ({exc.strerror or exc})") from None
    return str(path)


def _append_to_store(args, summary):
    """Append the processed logs to --store; the summary's ``store`` key: the folder and,
    per log, its content key, rows written and whether it replaced an earlier entry."""
    from gyrodenoise.flightlog.fleet_store import append_summary
    from gyrodenoise.flightlog.model import ReadOptions
    try:
        got = append_summary(args.store, summary, airframe=args.airframe,
                             read_options=ReadOptions(args.raw_imu_unit, args.raw_imu_scale), log=_log)
    except OSError as exc:
        raise InputError(f"--store {args.store}: cannot write ({exc.strerror or exc})") from None
    return {"folder": str(args.store),
            "appended": [{"file": a.file, "log_key": a.log_key, "log_rows": a.log_rows,
                          "spectrum_rows": a.spectrum_rows, "replaced": a.replaced} for a in got]}


def _write_out(out, name, text):
    """Write ``name`` into the output folder ``out`` (a local path or an fsspec URL)."""
    from gyrodenoise.flightlog.cluster import is_url
    from gyrodenoise.flightlog.stopping import atomic_path
    if is_url(out):
        import fsspec
        with fsspec.open(str(out).rstrip("/") + "/" + name, "w") as fh:
            fh.write(text)
    else:
        with atomic_path(Path(out) / name) as tmp:
            tmp.write_text(text)


def _interrupted(out, summary):
    """On an interrupt of a run over several logs: summary.json (written whole, under
    a partial name first) says which logs completed and which did not; returns the
    note for the stop line."""
    try:
        _write_out(out, "summary.json", json.dumps(_finite(summary), indent=1, allow_nan=False))
    except OSError as exc:
        return f"summary.json not written ({exc.strerror or exc})"
    return (f"{out}/summary.json lists the {len(summary['completed'])} completed and "
            f"{len(summary['unfinished'])} unfinished log(s)")


def _share_plotlyjs(summary, out):
    """--plotlyjs shared: plotly.min.js written once into OUT, the run's HTML pages (each
    log's report and fleet.html, drawn with it inlined) made to refer to it; returns its path."""
    from gyrodenoise.flightlog.html_report import share_plotlyjs
    pages = [r["report_html"] for r in summary["logs"] if r.get("report_html")]
    pages += [p for p in summary.get("fleet_report") or [] if str(p).endswith(".html")]
    js, _ = share_plotlyjs(pages, Path(out))
    return str(js)


def _fleet_report(summary, out, html=True):
    """The fleet report (fleet.md, fleet.json, fleet.png and, with ``html``, fleet.html)
    beside the outputs; returns its paths."""
    import tempfile
    from gyrodenoise.flightlog.cluster import is_url
    from gyrodenoise.flightlog.fleet import write_fleet_report
    if not is_url(out):
        return [str(x) for x in write_fleet_report(summary, Path(out), html=html)]
    with tempfile.TemporaryDirectory() as tmp:
        import fsspec
        paths = []
        for f in write_fleet_report(summary, Path(tmp), html=html):
            dest = str(out).rstrip("/") + "/" + f.name
            with fsspec.open(dest, "wb") as fh:
                fh.write(f.read_bytes())
            paths.append(dest)
        return paths


def exit_status(summary):
    """2 if a log failed (bad input), else 1 if a stream was left raw, else 0."""
    return 2 if summary["failed"] else 1 if summary["streams_left_raw"] else 0


def _run_files(args, kw, single, client=None):
    from gyrodenoise.flightlog.process import MOTION_METRIC, process_many, process_log, streams_left_raw
    if single:
        # one file: errors are the command's error (exit 2, one line)
        from gyrodenoise.flightlog.streams import NOISE_METRIC
        rep = process_log(args.logs[0], args.out, log=_log, background_plots=True, plot_helpers=1, **kw)
        summary = {"logs": [rep], "failed": [], "ignored_files": [], "n_logs": 1, "n_ok": 1,
                   "n_failed": 0, "jobs": 1, "seconds": rep["seconds"], "noise_metric": NOISE_METRIC,
                   "motion_metric": MOTION_METRIC, "streams_left_raw": streams_left_raw([rep])}
    else:
        progress = sys.stderr.isatty() if args.progress is None else args.progress
        summary = process_many(args.logs, args.out, jobs=args.jobs, log=_log,
                               scheduler=client if client is not None else args.scheduler,
                               progress=progress, on_interrupt=lambda sm: _interrupted(args.out, sm), **kw)
        if args.scheduler is not None:
            summary["scheduler"] = args.scheduler
        if summary["n_logs"] == 0:
            ign = summary["ignored_files"]
            why = "; ".join(f"{i['file']}: {i['reason']}" for i in ign[:3]) + (f"; {len(ign) - 3} more" if len(ign) > 3 else "")
            from gyrodenoise.flightlog.formats import LOG_SUFFIXES
            looked = ", ".join(sorted(LOG_SUFFIXES))
            raise InputError(f"{', '.join(args.logs)}: no flight log found (looked for {looked} files and ROS 2 bag "
                             f"folders)" + (f" (ignored: {why})" if why else ""))
        refused = {f.get("option") for f in summary["failed"]}
        if not summary["n_ok"] and len(refused) == 1 and refused <= {"--cutoff-hz", "--max-motion-hz"}:
            # the option, not the logs: one line, nothing written (as for one log)
            option = refused.pop()
            value = args.cutoff_hz if option == "--cutoff-hz" else args.max_motion_hz
            fastest = max(r for f in summary["failed"] for r in f.get("rates_hz") or [0.0])
            raise InputError(f"{option} {value:g} is at or above the Nyquist frequency of every "
                             f"gyro stream of the {summary['n_logs']} log(s) (the fastest sampled at "
                             f"{fastest:.4g} Hz: Nyquist {fastest / 2:.4g} Hz); nothing to filter")
    summary["exit_status"] = exit_status(summary)
    return summary


def _fmt(v, nd=4):
    return "-" if v is None else f"{v:.{nd}g}"


def _pct(v):
    return "-" if v is None else f"{100.0 * v:.0f} %"


def _lag(v):
    # round() to an int: a lag of -0.2 ms reads "0 ms", not "-0 ms" (the offline form's lags)
    return "-" if v is None else f"{round(1000.0 * v)} ms"


def _first_diff_note(nz):
    """'; first differences 1.731: mostly motion' when the first-difference figure is
    well above the white-noise estimate (or the estimate is missing); else ''."""
    fd, wn = nz.get("first_diff_raw"), nz.get("raw")
    if fd is None:
        return ""
    if wn is None:
        return f"; {_FEW_FOR_NOISE}; first differences {_fmt(fd)}"
    if fd > FIRST_DIFF_NOTE_FACTOR * wn:
        return f"; first differences {_fmt(fd)}: motion/vibration"
    return ""


#: the summary names the first-difference figure when it is this many times the
#: white-noise estimate (what motion and vibration add to it)
FIRST_DIFF_NOTE_FACTOR = 2.0
_FEW_FOR_NOISE = "no session long enough for the noise estimate"


def _axis_line(s, a):
    nz = s["noise"][a]
    line = f"      {a}: noise {_fmt(nz['raw'])} -> {_fmt(nz['filtered'])} {s['noise_unit']}"
    if s.get("left_raw"):
        return line + f"{_first_diff_note(nz)}  (stream left raw: see above)\n"
    if s.get("too_slow_to_denoise") or s.get("not_filtered"):
        # written raw: no "raw -> filtered" that would read as a result
        why = "too slow to denoise" if s.get("too_slow_to_denoise") else "not filtered: see above"
        return f"      {a}: noise {_fmt(nz['raw'])} {s['noise_unit']}{_first_diff_note(nz)}  (written raw: {why})\n"
    line += f" (x{_fmt(nz['ratio'], 3)}{_first_diff_note(nz)})"
    m = (s.get("motion") or {}).get(a)
    if m is not None and m.get("motion_above_noise") is False:
        # the low band holds only noise (a vehicle at rest, or vibrating on the ground):
        # what the filter removed there is noise, not motion
        line += (f"  0-{s['motion_band_hz']:g} Hz: no motion above the noise "
                 f"({_pct(m['amplitude_ratio'])} of that band kept)")
    elif m is not None:
        line += (f"  0-{s['motion_band_hz']:g} Hz motion kept: corr {_fmt(m['corr'], 3)}, "
                 f"amplitude {_pct(m['amplitude_ratio'])}; lag {_lag(m['lag_s'])}")
    return line + "\n"


def _options_text(r):
    """', Butterworth order 2, zero phase' for the low-pass; ', rigid body: --max-motion-hz 20'
    for motion with that option; another method's own options (', --min-cutoff-hz 3, --beta
    0.01, --d-cutoff-hz 1' for one_euro); '' otherwise."""
    o = r.get("filter_options") or {}
    if r.get("method") == "motion" and o.get("max_motion_hz"):
        return (f", rigid body: --max-motion-hz {o['max_motion_hz']:g} (a 4th-order low-pass flat to it, "
                f"-3 dB at twice it or 0.45 x each stream's rate, whichever is lower)")
    if r.get("method") != "lowpass":   # another method's own options, as given or their defaults
        own = [p for p in PARAMS if r.get("method") in p.methods and p.name in o and p.option]
        return "".join(f", {p.option} {o[p.name]:g}" for p in own)
    return f", Butterworth order {o.get('order', 2)}, {'zero phase' if o.get('zero_phase') else 'causal'}"


def _form_text(r):
    """'offline: whole record: ...' or 'causal: ...' (the report's form and its note)."""
    return f"{r.get('form', 'causal')}: {r['form_note']}" if r.get("form_note") else r.get("form", "causal")


def _filter_rate_text(s, summary):
    """'  (filtered as 100 Hz: --sample-rate)' when the filter's rate is not the measured one."""
    fr, r = s.get("filter_rate_hz"), s.get("rate_hz")
    if fr is None or (r is not None and abs(fr - r) <= 1e-9 * r):
        return ""
    return f"  (filtered as {_fmt(fr)} Hz: --sample-rate)"


def _print_text(summary):
    out = sys.stdout
    for r in summary["logs"]:
        _print_log(out, r, summary)
    for f in summary["failed"]:
        # the error names its file already
        err = f["error"] if f["error"].startswith(str(f["file"])) else f"{f['file']}: {f['error']}"
        out.write(f"FAILED {err}\n")
    n_raw = len(summary.get("streams_left_raw", []))
    out.write(f"{summary['n_ok']} of {summary['n_logs']} log(s) processed in {summary['seconds']} s"
              f"{f'; {n_raw} stream(s) left raw (exit status 1)' if n_raw else ''}\n")
    if summary.get("fleet_report"):
        out.write(f"fleet report: {summary['fleet_report'][0]}\n")
    if summary.get("store"):
        got = summary["store"]["appended"]
        out.write(f"store {summary['store']['folder']}: {len(got)} log(s) appended "
                  f"({sum(a['replaced'] for a in got)} replaced an earlier entry of the same log)\n")


def _print_log(out, r, summary):
    """One log's lines of the text summary: the log, its streams, its restarts."""
    nb = r.get("truncated_bytes")
    trunc = f", truncated ({nb} byte{'' if nb == 1 else 's'} cut)" if r.get("truncated") else ""
    unread = r.get("unreadable_records")
    # pyulog does not count what it skips: no figure rather than a dash
    unread = "" if unread is None else f", {unread} unreadable records skipped"
    out.write(f"{r['file']} ({r['format']}): {r['messages']} messages{unread}{trunc}\n")
    out.write(f"  filtered log: {r['output_log']}  (method {r['method']}{_options_text(r)}; "
              f"{_form_text(r)})\n")
    _print_signing(out, r)
    from gyrodenoise.flightlog.log_review import review_text
    for line in review_text(r):
        out.write(f"  {line}\n")
    if r.get("report_html"):
        out.write(f"  report: {r['report_html']}\n")
    for s in r["streams"]:
        _print_stream(out, s, r, summary)
    for e in r["restarts"]:
        out.write(f"  restart: {e['stream']} sample {e['sample']} at t={e['time_s']:.3f} s "
                  f"(previous {e['previous_time_s']:.3f} s): {e['reason']}\n")


def _print_signing(out, r):
    """The signing lines of a log or link: the signed packets left raw for want of a key
    (with how to give one), or what the key did; nothing for a link without signing."""
    from gyrodenoise.flightlog.report import rejected_text
    if r.get("signed_left_raw"):
        out.write(f"  SIGNED, NOT FILTERED: {r['signing_note']}\n")
    if r.get("signing_key") and (r.get("signed_packets") or r.get("rejected_signatures")):
        out.write(f"  signing: {r['signed_packets']} signed packets in, {r['resigned_packets']} re-signed with "
                  f"the key (the others kept their bytes)\n")
    if r.get("rejected_signatures"):
        out.write(f"  SIGNATURE CHECK: {rejected_text(r)}\n")


def _print_stream(out, s, r, summary):
    """One stream's lines of the text summary of log ``r``."""
    from gyrodenoise.flightlog.process import saturation_note
    from gyrodenoise.flightlog.spectra import summary_lines
    stage = f"  {s['stage']}" if s.get("stage") else ""
    out.write(f"  {s['name']:<16} {s['samples']:>7} samples  {_fmt(s['rate_hz'])} Hz  "
              f"{s['restarts']} restart(s)  unit {s['field_unit']}"
              f"{'' if s['unit_known'] else ' (scale unknown)'}"
              f"{_filter_rate_text(s, summary)}{stage}\n")
    if s.get("left_raw"):
        out.write(f"    NOT FILTERED, written raw: {s['left_raw']}\n")
    if s.get("all_zero"):
        out.write("    note: every sample is zero: no data (sensor absent or dead)\n")
    if s.get("saturation"):
        out.write(f"    note: {saturation_note(s['saturation'])}\n")
    if s.get("too_slow_to_denoise"):
        out.write(f"    note: {s['slow_note']}\n")
    if s.get("not_filtered"):
        out.write(f"    NOT FILTERED: {s['not_filtered']}\n")
    if s.get("cutoff_hz"):
        out.write(f"    low-pass cutoff {s['cutoff_hz']:.4g} Hz at {_fmt(s['filter_rate_hz'])} Hz"
                  f"{'' if r['filter_options'].get('cutoff_hz') else ' (the default: min(20 Hz, rate / 4))'}\n")
    for a in s["noise"]:
        out.write(_axis_line(s, a))
    for line in summary_lines(s.get("spectrum")):
        out.write(f"      {line}\n")
    for w in s.get("warnings", []):
        out.write(f"    WARNING: {w}\n")


def _run_live(args, conn):
    with contextlib.redirect_stdout(sys.stderr):
        rep, streams = _live(args, conn)
    return _report_live(args, conn, rep, streams)


def _live(args, conn):
    from gyrodenoise.flightlog.live import run_live
    return run_live(conn, args.forward, duration=args.duration, max_messages=args.count,
                    method=args.method, ar_order=args.ar_order, gap_factor=args.gap_factor,
                    sample_rate=args.sample_rate, raw_imu_unit=args.raw_imu_unit,
                    raw_imu_scale=args.raw_imu_scale, log=_log, warmup_s=args.warmup_s,
                    filter_kw=_filter_kw(args), signing_key=args.key)


def _report_live(args, conn, rep, streams):
    _complete_live_report(args, conn, rep, streams)
    from gyrodenoise.flightlog.process import log_problems
    from gyrodenoise.flightlog.report import signing_problems
    log_problems(dict(rep, file=conn, output_log=args.forward or "(nowhere)"), _log)
    signing_problems(dict(rep, file=conn), _log)
    if args.json:
        emit_json(_finite(rep))
    else:
        _print_live(args, conn, rep)
    return rep["exit_status"]


def _complete_live_report(args, conn, rep, streams):
    """The link's report completed with its streams (their CSV and PNG written unless
    --no-csv / --no-plots), restarts, metrics, the streams left raw and the exit status."""
    from gyrodenoise.flightlog.process import MOTION_METRIC, plot_stream, safe_name, stream_report, write_csv
    from gyrodenoise.flightlog.streams import NOISE_METRIC
    out = Path(args.out)
    srep, restarts = [], []
    for s in streams:
        x, f, unit, _ = s._work
        csv_path = png_path = None
        if s.n and not args.no_csv:
            csv_path = out / f"live.{safe_name(s.name)}.csv"
            write_csv(csv_path, s, x, f, unit)
        if s.n and not args.no_plots:
            png_path = out / f"live.{safe_name(s.name)}.png"
            plot_stream(png_path, f"{conn}: {s.name}", s.time_s, x, f,
                        s.restarts, unit, s.axes)
        srep.append(stream_report(s, csv_path, png_path))
        restarts += s.restart_events
    rep["streams"] = srep
    rep["restarts"] = restarts
    rep["noise_metric"] = NOISE_METRIC
    rep["motion_metric"] = MOTION_METRIC
    rep["streams_left_raw"] = [{"file": conn, "stream": s["name"], "reason": s["left_raw"]}
                               for s in srep if s.get("left_raw")]
    rep["exit_status"] = 1 if rep["streams_left_raw"] else 0


def _print_live(args, conn, rep):
    """The text summary of a live link."""
    from gyrodenoise.flightlog.process import saturation_note
    out = sys.stdout
    out.write(f"{conn} -> {args.forward or '(nowhere)'}: {rep['messages_in']} messages in, "
              f"{rep['messages_forwarded']} forwarded, {rep['unreadable_records']} unreadable, "
              f"stopped by {rep['stopped_by']} after {rep['seconds']} s; "
              f"method {rep['method']}, causal\n")
    _print_signing(out, rep)
    for s in rep["streams"]:
        out.write(f"  {s['name']}: {s['samples']} samples, {_fmt(s['rate_hz'])} Hz, "
                  f"{s['restarts']} restart(s), unit {s['field_unit']}"
                  f"{'' if s['unit_known'] else ' (scale unknown)'}\n")
        if s.get("left_raw"):
            out.write(f"    NOT FILTERED from a sample on, forwarded raw: {s['left_raw']}\n")
        if s.get("not_filtered"):
            out.write(f"    NOT FILTERED: {s['not_filtered']}\n")
        if s.get("too_slow_to_denoise"):
            out.write(f"    note: {s['slow_note']}\n")
        if s.get("saturation"):
            out.write(f"    note: {saturation_note(s['saturation'])}\n")
        for a in s["noise"]:
            out.write(_axis_line(s, a))
        for w in s.get("warnings", []):
            out.write(f"    WARNING: {w}\n")
