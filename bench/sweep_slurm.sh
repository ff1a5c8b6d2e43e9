#!/bin/bash
# bench/sweep_slurm.sh DRIFTLAB SPEC OUT: runs SPEC on the Slurm cluster the caller started (tests/slurm_run.sh),
# waits for every point, merges the table (sweep collect) and prints the seconds from submission to the last point.
set -eu
exe=$1 spec=$2 out=$3
t0=$(date +%s.%N)
"$exe" sweep "$spec" -o "$out" --executor slurm >/dev/null
while :; do
  status=$("$exe" sweep status "$out" --json)
  done=$(python3 -c 'import json,sys; s=json.load(sys.stdin); print(int(s["done"] + s.get("failed", 0) >= s["points"]))' <<<"$status")
  [ "$done" = 1 ] && break
  sleep 0.5
done
t1=$(date +%s.%N)
"$exe" sweep collect "$out" --no-plots >/dev/null
python3 -c "print(f'{$t1 - $t0:.1f}')"
