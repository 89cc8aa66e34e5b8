"""The fleet trends' change detector on synthetic airframes: false alarms and delay.

    python benchmarks/fleet_trends.py [--quick]

The detector (:mod:`gyrodenoise.flightlog.trends`: a one-sided self-starting CUSUM on
log10 of a log's level against the airframe's own earlier logs) is run, at each
decision level h, on seeded synthetic series:

* unchanged airframes (30 logs each; log-to-log scatter drawn in 0.04-0.15 decades,
  10-40 %), Gaussian in log10 and heavy-tailed (Student t, 4 degrees of freedom): the
  share of judged logs flagged and of airframes flagged at least once;
* drifting airframes (40 logs, onset at log 15, scatter 0.06 decades = 15 %) growing
  5 %, 10 % and 25 % a log (a propeller imbalance growing; a bent propeller): the
  logs from the onset to the first flag (median, 90th percentile; a miss counts as
  25), the share never flagged, and the share flagged before the onset.

Numbers are measured here, in this process; tests/flightlog/test_trends.py bounds them.
"""
import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's gyrodenoise first

from gyrodenoise.flightlog.trends import Detector, detection_delay, false_alarm_rate  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer synthetic airframes (a smoke run)")
    args = ap.parse_args(argv)
    airframes, trials = (300, 100) if args.quick else (3000, 1000)
    print(f"self-starting CUSUM on log10(level); baseline {Detector().baseline} logs, allowance "
          f"{Detector().allowance:g}, one-log jump {Detector().jump:g} sigma; {airframes} unchanged airframes, "
          f"{trials} drifting ones per row")
    print("| h | false alarms / judged log | airframes ever flagged | same, heavy tails (t4) | "
          "delay 5 %/log: median, p90, missed, early | 10 %/log | 25 %/log |")
    print("|---|---|---|---|---|---|---|")
    for h in (4.0, 5.0, 6.0):
        det = Detector(threshold=h)
        far = false_alarm_rate(det, seed=1, airframes=airframes)
        heavy = false_alarm_rate(det, seed=2, airframes=airframes, tails_dof=4)
        cells = []
        for g in (0.05, 0.10, 0.25):
            d = detection_delay(det, seed=3, trials=trials, growth_per_log=g)
            cells.append(f"{d.median:g}, {d.p90:g}, {100 * d.missed:.1f} %, {100 * d.early:.1f} %")
        default = " (default)" if h == Detector().threshold else ""
        print(f"| {h:g}{default} | {100 * far.per_log:.2f} % | {100 * far.per_airframe:.1f} % | "
              f"{100 * heavy.per_log:.2f} % / {100 * heavy.per_airframe:.1f} % | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
