"""``gyrodenoise fleet-trends``: the fleet store's per-airframe trends (argparse layer only)."""

from __future__ import annotations

import argparse
import sys
from dataclasses import asdict
from pathlib import Path

from gyrodenoise._extras import require
from gyrodenoise.cli.options import integer, number
from gyrodenoise.cli.program import emit_json
from gyrodenoise.errors import InputError

EPILOG = """\
examples:
  gyrodenoise mavlink logs/ --store fleet-store -o out     # review the logs, append them to the store
  gyrodenoise fleet-trends fleet-store                     # trends per airframe: fleet-store/trends/index.html
  gyrodenoise fleet-trends fleet-store --plotlyjs shared   # plotly.js once in the folder, small pages
  gyrodenoise fleet-trends fleet-store --sql "SELECT airframe, count(DISTINCT log_key) FROM logs GROUP BY 1"

The store's DuckDB views: logs (a row per log and gyro stream), spectra (a row per
log, stream, flight segment and axis: psd on the fixed grid), grid (bin, f_lo_hz,
f_hi_hz, f_centre_hz; a bin's value is psd[bin + 1]).

exit status:
  0  written (or the query answered); no airframe flagged
  1  written; some airframe's level grew against its own history (flagged)
  2  bad usage or bad input: one line on stderr naming the option or folder
"""


def register_cli(subparsers):
    from gyrodenoise.flightlog.trends import Detector
    d = Detector()
    p = subparsers.add_parser(
        "fleet-trends", help="per-airframe trends of the fleet store (mavlink --store): flag growth",
        description="Per airframe, each trended figure of its logs in the order flown (vibration, the level "
                    "of its vibration line, the gyro noise density), flagged where it grows against the "
                    "airframe's own history (a self-starting CUSUM); an HTML page per airframe.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter, json_errors=True)
    p.add_argument("store", metavar="STORE", help="the fleet store folder (gyrodenoise mavlink --store STORE)")
    p.add_argument("-o", "--out", default=None, metavar="OUT",
                   help="folder of the pages and trends.json (default: STORE/trends)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--plotlyjs", default="inline", choices=["inline", "shared"],
                   help="inline: each page holds plotly.js (opens alone, ~4.7 MB a page; default); shared: "
                        "plotly.min.js written once into OUT, the pages refer to it (tens of kB a page)")
    p.add_argument("--no-html", action="store_true", help="do not write the pages (trends.json only)")
    p.add_argument("--baseline", type=integer, default=d.baseline, metavar="N",
                   help=f"logs of an airframe before its first verdict (default {d.baseline}, at least 3)")
    p.add_argument("--threshold", type=number, default=d.threshold, metavar="H",
                   help=f"the CUSUM's decision level in sigmas (default {d.threshold:g}; higher: fewer false "
                        "alarms, later detection)")
    p.add_argument("--sql", default=None, metavar="QUERY",
                   help="run QUERY on the store's views (logs, spectra, grid) and print the result instead")
    p.set_defaults(func=run)
    return p


def _detector(args):
    from gyrodenoise.flightlog.trends import Detector
    det = Detector(baseline=args.baseline, threshold=args.threshold)
    why = det.check()
    if why:
        raise InputError(f"--{'baseline' if 'baseline' in why else 'threshold'}: {why}")
    return det


def run(args):
    require("fleet", what="gyrodenoise fleet-trends")
    from gyrodenoise.flightlog.fleet_store import is_store
    store = Path(args.store)
    if not store.is_dir():
        raise InputError(f"{args.store}: no such folder")
    if not is_store(store):
        raise InputError(f"{args.store}: not a fleet store (no logs/ table; gyrodenoise mavlink --store writes one)")
    if args.sql is not None:
        return _query(args, store)
    det = _detector(args)
    if not args.no_html:
        require("report", "plotly", what="gyrodenoise fleet-trends' pages (or --no-html)")
    from gyrodenoise.flightlog import trends as tr
    out = Path(args.out) if args.out else store / "trends"
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"-o {out}: cannot create the output folder ({exc.strerror or exc})") from None
    found = tr.trends(store, det)
    paths = [tr.write_json(found, out / "trends.json", det)]
    if not args.no_html:
        paths += tr.write_pages(found, out, plotlyjs=args.plotlyjs, detector=det)
    grown = [t for t in found if t.status == "growth"]
    if args.json:
        emit_json({"store": str(store), "out": str(out), "files": [str(p) for p in paths],
                   "airframes": len({t.airframe for t in found}), "flagged": [t.to_fields() for t in grown],
                   "groupings": [asdict(g) for g in tr.groupings_of(found).values()],
                   "statuses": [{"airframe": t.airframe, "metric": t.metric, "stream": t.stream,
                                 "status": t.status, "logs": len(t.points)} for t in found]})
    else:
        _print(found, out)
    return 1 if grown else 0


def _print(found, out):
    from gyrodenoise.flightlog.trends import groupings_of
    w = sys.stdout.write
    for g in groupings_of(found).values():
        if not g.trended:
            w(f"{g.airframe}  {g.reason}\n")
    for t in found:
        if not t.trended:
            continue
        what = f"{t.metric}{' ' + t.stream if t.stream else ''}"
        flag = (f"  GROWTH from {t.points[t.detection.first_flag].log}" if t.status == "growth" else "")
        w(f"{t.airframe}  {what}: {len(t.points)} log(s), {t.status}{flag}\n")
    w(f"{len({t.airframe for t in found})} airframe(s); pages and trends.json in {out}\n")


def _query(args, store):
    import duckdb
    from gyrodenoise.flightlog.fleet_store import query
    try:
        cols, rows = query(store, args.sql)
    except duckdb.Error as exc:
        raise InputError(f"--sql: {str(exc).splitlines()[0]}") from None
    if args.json:
        emit_json({"columns": cols, "rows": [[_plain(v) for v in r] for r in rows]})
        return 0
    w = sys.stdout.write
    w("\t".join(cols) + "\n")
    for r in rows:
        w("\t".join("" if v is None else str(v) for v in r) + "\n")
    return 0


def _plain(v):
    """A query value as JSON takes it (times as ISO text, lists kept, NaN as null)."""
    if isinstance(v, float):
        return v if v == v and abs(v) != float("inf") else None
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, (int, str, bool)) or v is None:
        return v
    return v.isoformat() if hasattr(v, "isoformat") else str(v)
