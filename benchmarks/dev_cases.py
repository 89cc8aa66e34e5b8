"""List the held-out benchmark's development cases by grade, profile and sample rate.

    python benchmarks/dev_cases.py [--n 100] [--grade consumer_mems] [--profile rest]
        [--fs-min 100] [--fs-max 400]

One line per seed of the development set (``benchmarks/heldout``, seeds 0..99): the drawn grade,
profile, sample rate, length, the white noise's standard deviation per sample (ARW density x
sqrt(fs / 2)), the LSB over it, the warm-up ramp's end value and the turn-on residual. To find
development seeds that look like a case the held-out set reports, without running the held-out
set. Only the case generator runs (no filter, no tuning).
"""

import argparse
import math
import sys

from benchmarks.heldout.cases import SEED_SETS, make_case


def describe(seed: int) -> str:
    c = make_case(seed)
    s = c.sensor
    sigma = s.white_density_dps_rt_hz * math.sqrt(s.sample_rate_hz / 2.0)
    return (f"{seed:>4} {s.grade:<15} {c.profile.name:<11} {s.sample_rate_hz:>6.0f} Hz {len(c.raw):>7} "
            f"sigma {sigma:9.3g} lsb/sigma {s.lsb_dps / sigma:7.3g} warm-up {s.warmup_dps:9.3g} "
            f"turn-on {s.turn_on_bias_dps:9.3g}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="the first N development seeds (1..100)")
    ap.add_argument("--grade", help="only this grade (consumer_mems, tactical_mems, tactical_fog, navigation_fog)")
    ap.add_argument("--profile", help="only this motion profile (rest, steps, ...)")
    ap.add_argument("--fs-min", type=float, default=0.0, help="lowest sample rate, Hz")
    ap.add_argument("--fs-max", type=float, default=math.inf, help="highest sample rate, Hz")
    args = ap.parse_args(argv)
    seeds = list(SEED_SETS["dev"])
    if not 1 <= args.n <= len(seeds):
        print(f"dev_cases: --n must be 1..{len(seeds)}, got {args.n}", file=sys.stderr)
        return 2
    for seed in seeds[:args.n]:
        c = make_case(seed)
        if args.grade and c.sensor.grade != args.grade:
            continue
        if args.profile and c.profile.name != args.profile:
            continue
        if not args.fs_min <= c.fs <= args.fs_max:
            continue
        print(describe(seed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
