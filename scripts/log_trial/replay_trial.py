"""The filter replay on held-out logs: per log, the replay's and the unfiltered gyro's
agreement with the logged post-filter gyro (dB rms over 30 Hz..the slower stream's
Nyquist frequency), the streams, the time compared and the flags.

Usage (from the repository root)::

    PYTHONPATH=. python scripts/log_trial/replay_trial.py LOG [LOG ...]

One line per log: ``name  pre -> post  band  replay x/y/z/all  unfiltered  over  flags``;
``--json`` prints the logs' ``notch_replay`` objects instead. No log is kept here: see
README.md for where the logs checked come from.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from gyrodenoise.flightlog.formats import read_log
from gyrodenoise.flightlog.log_review import log_review


def trial(path):
    """(the log's ``notch_replay`` or None, its note, whether any segment flew)."""
    fields = log_review(read_log(str(path))).fields
    flew = any(s.get("kind") == "flying" for s in fields.get("segments") or [])
    return fields.get("notch_replay"), fields.get("notch_replay_note") or "", flew


def line(name, rep, note, flew):
    if rep is None:
        return f"{name}: no replay ({note})"
    ag = rep.get("agreement")
    head = (f"{name}: {rep['pre']['stream']} {rep['pre']['rate_hz']:g} Hz -> {rep['post']['stream']} "
            f"{rep['post']['rate_hz']:g} Hz, filters at {rep['filter_rate_hz']:g} Hz")
    if ag is None:
        return f"{head}; no figure ({rep.get('agreement_note', '')})"
    d = ag["db_rms"]
    flags = [f for f, on in (("WORSE THAN UNFILTERED", rep.get("worse_than_unfiltered")),
                             ("never flew: all the log compared", not flew)) if on]
    return (f"{head}; band {ag['band_hz'][0]:g}-{ag['band_hz'][1]:g} Hz; replay dB rms "
            f"{d['x']}/{d['y']}/{d['z']}/{d['all']}; unfiltered {rep.get('unfiltered_db_rms')}; "
            f"over {ag['over_s'][0]:g}-{ag['over_s'][1]:g} s" + (f"; {'; '.join(flags)}" if flags else ""))


def main(argv):
    as_json = "--json" in argv
    paths = [a for a in argv if a != "--json"]
    if not paths:
        print(__doc__.strip().splitlines()[0], file=sys.stderr)
        return 2
    out = {}
    for p in paths:
        rep, note, flew = trial(p)
        out[Path(p).name] = rep if rep is not None else {"note": note}
        if not as_json:
            print(line(Path(p).name, rep, note, flew), flush=True)
    if as_json:
        print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
