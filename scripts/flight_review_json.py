"""Print the flight review of one log as JSON (segments, vibration, the filter review), for docs.

Usage (from the repository root)::

    PYTHONPATH=. python scripts/flight_review_json.py ../shared/data/logs/px4_quad_battery_brownout.ulg

The review only (:func:`gyrodenoise.flightlog.log_review.log_review` on the log as read):
no filtering, no output files. The hover entries of ``segments`` are left out; the
filter review without its plot arrays and per-peak list.
"""
from __future__ import annotations

import json
import sys

from gyrodenoise.flightlog.formats import read_log
from gyrodenoise.flightlog.log_review import log_review


def review_json(path):
    """The JSON-able summary of the flight review of the log at ``path`` (a dict)."""
    fields = log_review(read_log(path)).fields
    out = {"segments": [s for s in fields["segments"] if s["kind"] != "hover"],
           "parameters_note": fields.get("parameters_note"),
           "vibration": fields["vibration"], "vibration_note": fields["vibration_note"]}
    fr = fields["filter_review"]
    if fr is None:
        out["filter_review"], out["filter_review_note"] = None, fields["filter_review_note"]
    else:
        out["filter_review"] = {k: v for k, v in fr.items() if k not in ("peaks", "_plot", "figures")}
    return out


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python scripts/flight_review_json.py LOG")
    print(json.dumps(review_json(sys.argv[1]), indent=1))
