"""Each ADIS16405 record fitted on its own from an empty card (docs/GAP.md, issue 20: "the six
ADIS16405 records converge").

For imu1..imu6 (one axis, full length by default): ``gyrodenoise.gap`` from an empty card,
native engine, 4 seeds, ``--outliers`` (the same call as benchmarks/gap_heldout.py's fit on
imu1). Printed per record: gap before -> after, the scatter threshold, within_scatter, and
when not within the components above their own limits.

Run: .venv/bin/python benchmarks/gap_adis_all.py [AXIS] [N_SAMPLES]   (default gyro_x 1000000;
about 4 minutes on an idle 2-core box)
"""

from __future__ import annotations

import sys
import time

from _data import SHARED_DATA

STATIC = SHARED_DATA / "static"
EMPTY = "[sensor]\nname = \"empty\"\nsample_rate_hz = 100.0\n"


def main(*argv):
    axis = argv[0] if argv else "gyro_x"
    n = int(argv[1]) if len(argv) > 1 else 1000000
    if not (STATIC / "adis16405_imu1.csv.gz").exists():
        print(f"skipped: {STATIC} not present")
        return 0
    import gyrodenoise as gd
    from gyrodenoise.io.recording import read_recording
    from gyrodenoise.simulator import parse_card
    for i in range(1, 7):
        t = time.perf_counter()
        y = read_recording(STATIC / f"adis16405_imu{i}.csv.gz", rate_column=axis).rate_deg_s[:n]
        r = gd.gap(y, 100.0, parse_card(EMPTY), seeds=4, outliers=True)
        comp = r.iterations[-1]["components"]
        over = {c: round(v, 3) for c, v in comp.items() if not v <= r.component_threshold[c]}
        print(f"imu{i} {axis}: gap {r.gap_before:.4g} -> {r.gap_after:.4g}, threshold {r.threshold:.3g}, "
              f"within {r.within_scatter}" + (f", above their own limits: {over}" if over else "")
              + f" ({time.perf_counter() - t:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
