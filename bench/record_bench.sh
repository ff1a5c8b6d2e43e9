#!/bin/bash
# Recorder benchmark: the same paced traffic recorded by stock lcm-logger and by `driftlab record`, one after
# the other, loss counted by sequence number from each log. Runs itself inside a private network namespace.
#   bench/record_bench.sh BUILD_DIR OUT_DIR [sweep SECONDS] [big SECONDS]
set -euo pipefail
if [[ "${DRIFTLAB_IN_NETNS:-}" != 1 ]]; then
  exec "$(dirname "$0")/../tests/netns_run.sh" "$0" "$@"
fi
build=$1 out=$2
shift 2
url="udpm://239.255.76.67:7667?ttl=0"
mkdir -p "$out"

# run RECORDER RATE SIZE SECONDS -> prints "received R lost L achieved RATE"
run() {
  local recorder=$1 rate=$2 size=$3 seconds=$4 log="$out/bench.lcm"
  rm -f "$log"
  if [[ $recorder == lcm-logger ]]; then
    lcm-logger -f -q --lcm-url="$url" "$log" >/dev/null 2>&1 &
  else
    "$build/bin/driftlab" record --url "$url" -o "$log" >/dev/null &
  fi
  local pid=$!
  sleep 1
  local sent took
  read -r sent took < <("$build/bin/lcm_publisher" "$url" BENCH "$rate" "$size" "$seconds")
  sleep 1
  kill -INT $pid
  wait $pid || true
  echo "$("$build/bin/count_loss" BENCH "$sent" "$log") achieved $(python3 -c "print(round($sent / $took))")"
  rm -f "$log"
}

loss_pct() { python3 -c "import sys; r, l = int(sys.argv[1]), int(sys.argv[2]); print(f'{100 * l / (r + l):.2f}%')" "$@"; }

while (($#)); do
  mode=$1 seconds=$2
  shift 2
  if [[ $mode == sweep ]]; then
    printf '%-10s %-8s %-16s %24s %24s\n' "rate msg/s" "size" "achieved msg/s" "lcm-logger lost" "driftlab record lost"
    for rate in 5000 10000 20000 50000 100000 150000 200000; do
      read -r _ r1 _ l1 _ a1 < <(run lcm-logger $rate 64 "$seconds")
      read -r _ r2 _ l2 _ a2 < <(run driftlab $rate 64 "$seconds")
      printf '%-10s %-8s %-16s %14s (%6s) %14s (%6s)\n' $rate "64 B" "$a1 / $a2" "$l1" "$(loss_pct $r1 $l1)" "$l2" "$(loss_pct $r2 $l2)"
    done
  else
    # 1 MB messages at 250 MB/s.
    printf '%-10s %-8s %-16s %24s %24s\n' "rate msg/s" "size" "achieved msg/s" "lcm-logger lost" "driftlab record lost"
    read -r _ r1 _ l1 _ a1 < <(run lcm-logger 250 1000000 "$seconds")
    read -r _ r2 _ l2 _ a2 < <(run driftlab 250 1000000 "$seconds")
    printf '%-10s %-8s %-16s %14s (%6s) %14s (%6s)\n' 250 "1 MB" "$a1 / $a2" "$l1" "$(loss_pct $r1 $l1)" "$l2" "$(loss_pct $r2 $l2)"
  fi
done
