#!/bin/bash
# Run `gyrodenoise mavlink` on every log of LOGDIR, then the independent checker on each.
# usage (from the repository root): scripts/log_trial/run.sh LOGDIR OUTDIR
# Per log NAME: OUTDIR/NAME/{stdout.json,stderr.txt,rc} and OUTDIR/NAME.check.json.
set -u
logdir=$(realpath "$1"); out=$(realpath -m "$2"); py=${PYTHON:-python}
mkdir -p "$out"
for f in "$logdir"/*; do
  [ -f "$f" ] || continue
  n=$(basename "$f"); n=${n%.*}
  mkdir -p "$out/$n"
  "$py" -m gyrodenoise.cli mavlink "$f" -o "$out/$n" --json >"$out/$n/stdout.json" 2>"$out/$n/stderr.txt"
  echo $? >"$out/$n/rc"
  case "${f,,}" in
    *.bin|*.tlog|*.ulg) "$py" scripts/log_trial/check.py "$f" "$out/$n" >"$out/$n.check.json" 2>"$out/$n.check.err" ;;
  esac
  echo "$n rc=$(cat "$out/$n/rc") traceback=$(grep -c Traceback "$out/$n/stderr.txt")"
done
