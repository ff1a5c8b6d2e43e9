#!/usr/bin/env bash
# scripts/slam-robustness on bad input: each gives one line naming the file (or the run) and exit status 2; a
# relations file driftlab eval refuses, found after the replays, too, however many runs failed on it. Its runs on
# real logs are docs/tutorial-public-dataset.md's block (docs.run.tutorial-public-dataset). And --compare on two
# --json files: the runs that now meet the bar and those that no longer do, with McNemar's exact test on them. And
# --more: the ten further runs, and --vary's, each replayed once with its own arguments and settings (a stand-in
# driftlab).
#   tests/slam_robustness_test.sh SOURCE_DIR BIN_DIR
set -uo pipefail
source=$(realpath "$1")
script=$source/scripts/slam-robustness
bin=$(realpath "$2")
tmp=$(mktemp -d /tmp/driftlab-slam-robustness-test-XXXXXX)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp" || exit 1
printf '0 1 0 0 0 0 0 0\n' >ok.relations
printf 'not a bag\n' >broken.bag
printf 'not a relation\n' >broken.relations
# shellcheck source=tests/script_bad_input.sh
source "$source/tests/script_bad_input.sh"
expect "missing.lcm: no such file" missing.lcm:ok.relations
expect "missing.relations: no such file" broken.bag:missing.relations
expect "broken.lcm: expected LOG:RELATIONS" broken.lcm
expect "broken.bag: driftlab import failed" broken.bag:ok.relations
expect "--runs: no run named 'start-7'" --runs whole,start-7 broken.bag:ok.relations
expect "--set match_odometry: expected KEY=VALUE" --set match_odometry broken.bag:ok.relations
expect "--vary threshold_ang: expected KEY=VALUE" --vary threshold_ang broken.bag:ok.relations
expect "--vary keyframe_distance=0.4: given twice" --vary keyframe_distance=0.4 --vary keyframe_distance=0.4 \
  broken.bag:ok.relations
expect "nowhere/driftlab: no such program" --bin "$tmp/nowhere" broken.bag:ok.relations
expect "broken.relations: driftlab eval failed" --runs whole,start-3,start-10 --jobs 3 \
  "$source/tests/data/sample.lcm:broken.relations"

# Seven runs in both files: five now meet the bar, none lost, one more with other figures and the same verdict;
# one run in the earlier file only. Five of five discordant runs one way: p = 2 / 2^5 = 0.0625. One run in both
# folded before and none after (a relation 5 m or more off: 5.0 counts, 4.99 does not; the run in one file only,
# folded too, is not counted).
run_json() {  # NAME MEAN MAX MEETS
  printf '{"log": "intel", "run": "%s", "label": "%s", "mean_m": %s, "max_m": %s, "loop_closures": 1, "meets_bar": %s}' \
    "$1" "$1" "$2" "$3" "$4"
}
{
  echo '{"runs": ['
  for r in whole start-3 start-10; do run_json $r 0.2 3.0 false && echo ,; done
  run_json start-20 0.2 4.99 false && echo ,
  run_json decimation-3 0.2 5.0 false && echo ,
  run_json decimation-10 0.05 1.0 true && echo ,
  run_json max-iterations-40 0.05 1.0 true && echo ,
  run_json keyframe-distance-0.6 0.5 12.0 false
  echo ']}'
} >earlier.json
{
  echo '{"runs": ['
  for r in whole start-3 start-10 start-20 decimation-3; do run_json $r 0.04 0.9 true && echo ,; done
  run_json decimation-10 0.06 1.1 true && echo ,
  run_json max-iterations-40 0.05 1.0 true
  echo ']}'
} >later.json
"$script" --compare earlier.json later.json >out.txt 2>err.txt
status=$?
want=(
  "against earlier.json (7 runs in both): 2 -> 7 meet the bar; 5 now meet it, 0 no longer do (McNemar's exact test: p = 0.06); 1 -> 0 folded; 6 runs' figures changed"
  "  now meets  intel  start-20                        0.200 / 4.99 m -> 0.040 / 0.90 m"
  "  in one file only, left out: intel keyframe-distance-0.6"
)
for line in "${want[@]}"; do
  if [[ $status -ne 0 ]] || ! grep -qxF -- "$line" out.txt; then
    echo "FAILED: --compare: exit $status, wanted 0 and the line '$line'; stdout:"
    cat out.txt err.txt
    failed=1
  fi
done
if [[ $(grep -c "^  now meets" out.txt) -ne 5 ]] || grep -q "^  no longer" out.txt; then
  echo "FAILED: --compare: wanted five runs that now meet the bar and none lost:"
  cat out.txt
  failed=1
fi
printf '{"runs": [%s]}' "$(run_json other 0.05 1.0 true | sed 's/"intel"/"aces"/')" >other.json
expect "missing.json: no such file" --compare missing.json later.json
expect "broken.relations: not a slam-robustness --json file" --compare broken.relations later.json
expect "other.json: no run in common" --compare other.json later.json
# A run without its figures (hand-edited, or from another tool) is refused by the key it lacks, not silently dropped:
# dropping it would leave the count and the test on fewer runs than the file holds.
printf '{"runs": [%s, {"log": "intel", "run": "start-3", "label": "start-3"}]}' \
  "$(run_json whole 0.05 1.0 true)" >nofigures.json
expect "nofigures.json: not a slam-robustness --json file (KeyError: \"run 2 has no 'mean_m'\")" \
  --compare nofigures.json later.json
expect "--compare takes two --json files and no logs" --compare earlier.json later.json broken.bag:ok.relations
expect "missing.json: no such file" --against missing.json broken.bag:ok.relations
expect "no LOG:RELATIONS given" --runs whole

# --more: which runs it replays and with what. A stand-in driftlab (the real one's replays take minutes) notes each
# replay's arguments and settings and answers as the real one does; every run must reach it, in order, once.
mkdir fake
cat >fake/driftlab <<'FAKE'
#!/usr/bin/env bash
# replay LOG --modules slam --json -o OUT [--start S] [--config YAML]: one line "[--start S] | settings" in calls.txt
if [[ $1 == eval ]]; then
  echo "{\"relations\": {\"trans_m\": {\"mean\": 0.05, \"max\": ${FAKE_MAX_M:-1.0}}}}"
  exit 0
fi
[[ $1 == replay ]] || exit 1
shift 2
start="" settings=""
while (($#)); do
  case $1 in
    -o) : >"$2" && shift ;;
    --start) start="--start $2" && shift ;;
    --config) settings=$(grep -v ':$' "$2" | tr -d ' ' | paste -sd ' ') && shift ;;
  esac
  shift
done
echo "$start | $settings" >>"$(dirname "$0")/calls.txt"
echo '{"modules": [{"name": "slam", "metrics": {"loop_closures": 3}}]}'
FAKE
chmod +x fake/driftlab
cp "$source/tests/data/sample.lcm" s.lcm
# fake_run NAME PATTERN ARGS...: the script with the stand-in, one replay at a time, calls.txt fresh, its --json
# NAME.json; wants exit status 0 and a line of what it prints matching PATTERN.
fake_run() {
  local name=$1 pattern=$2
  shift 2
  rm -f fake/calls.txt
  "$source/scripts/slam-robustness" --bin fake --jobs 1 --json "$name.json" "$@" s.lcm:ok.relations >out.txt 2>err.txt
  local status=$?
  if [[ $status -ne 0 ]] || ! grep -q -- "$pattern" out.txt; then
    echo "FAILED: --$name: exit $status, wanted 0 and a line matching '$pattern':"
    cat out.txt err.txt
    failed=1
  fi
}
fake_run more "^11 of 11 runs meet the bar (.*); none folded (a relation 5 m or more off)$" --runs whole,start-5 \
  --more --set loop_radius=2
python3 - more.json fake/calls.txt <<'PY' || failed=1
import json, sys
written = json.load(open(sys.argv[1]))
runs = [r["run"] for r in written["runs"]]
want = ["whole", "start-5", "start-15", "start-30", "decimation-4", "decimation-7", "max-iterations-60",
        "keyframe-distance-0.4", "keyframe-distance-0.45", "local-map-keyframes-12", "min-dist-between-points-0.065"]
calls = open(sys.argv[2]).read().splitlines()
ok = runs == want and len(calls) == len(want) and written["fold_m"] == 5.0
for line in ("--start 30 | loop_radius:2", " | loop_radius:2 decimation:7", " | loop_radius:2 min_dist_between_points:0.065"):
    ok &= line in calls
if not ok:
    print("FAILED: --more: runs", runs, "replays", calls)
    sys.exit(1)
PY

# A run 5 m or more off is marked as folded, and counted.
FAKE_MAX_M=5.0 fake_run folded "^0 of 1 runs meet the bar (.*); 1 folded (a relation 5 m or more off)$" \
  --runs whole
if ! grep -q "^s  the whole log .*5.00 m      3  <- fails the bar, folded$" out.txt; then
  echo "FAILED: a run 5 m off not marked as folded:"
  cat out.txt
  failed=1
fi

# --vary: one run per setting after the named ones, that setting on top of --set's, named and labelled by it.
fake_run vary "^s  threshold_ang: 5  *0.050 m    1.00 m      3$" --runs whole --vary threshold_ang=5 \
  --vary loop_min_goodness=0.6 --set loop_radius=2
python3 - vary.json fake/calls.txt <<'PY' || failed=1
import json, sys
runs = [(r["run"], r["label"]) for r in json.load(open(sys.argv[1]))["runs"]]
want = [("whole", "the whole log"), ("threshold_ang=5", "threshold_ang: 5"),
        ("loop_min_goodness=0.6", "loop_min_goodness: 0.6")]
calls = open(sys.argv[2]).read().splitlines()
if runs != want or calls != [" | loop_radius:2", " | loop_radius:2 threshold_ang:5",
                             " | loop_radius:2 loop_min_goodness:0.6"]:
    print("FAILED: --vary: runs", runs, "replays", calls)
    sys.exit(1)
PY
exit $failed
