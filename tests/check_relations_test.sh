#!/usr/bin/env bash
# scripts/check-relations: bad input gives one line naming the file and exit status 2; on the SLAM benchmark's
# Intel log (../shared/data/carmen) it finds the benchmark's own relations agree with the scans, and finds the
# relations made wrong on purpose. Skips (77) without that data.
#   tests/check_relations_test.sh SOURCE_DIR BIN_DIR SHARED_DATA_DIR
set -uo pipefail
source=$(realpath "$1")
script=$source/scripts/check-relations
bin=$(realpath "$2")
data=$(realpath -m "$3")
tmp=$(mktemp -d /tmp/driftlab-check-relations-test-XXXXXX)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp" || exit 1
printf '0 1 0 0 0 0 0 0\n' >ok.relations
printf '# t1 t2 x y z roll pitch yaw\n0 1 0 0 0 0 0 0\n0 1 0 zero 0 0 0 0\n' >broken.relations
# shellcheck source=tests/script_bad_input.sh
source "$source/tests/script_bad_input.sh"
sample=$source/tests/data/sample.lcm
expect "missing.lcm: no such file" missing.lcm ok.relations
expect "missing.relations: no such file" "$sample" missing.relations
expect "broken.relations:3: expected 't1 t2 x y z roll pitch yaw'" "$sample" broken.relations
expect "empty.lcm: no scans" "$source/tests/data/empty.lcm" ok.relations
expect "sample.lcm: no driftlab.laser_scan_t channel named /scan" --channel /scan "$sample" ok.relations
expect "sample.lcm: no driftlab.odometry_t or driftlab.pose_t channel named /nope" \
  --odometry /nope "$sample" ok.relations
# The sample's scans are stamped in 2025, the relation at 0 and 1 s.
expect "ok.relations: no relation at most 30 s long has a scan of SCAN at both stamps" "$sample" ok.relations
expect "nowhere/driftlab: no such program" --bin "$tmp/nowhere" "$sample" ok.relations
printf 'not a bag\n' >broken.bag
expect "broken.bag: driftlab import failed" broken.bag ok.relations

if [[ ! -f $data/carmen/intel.orig.bag ]]; then
  echo "skipped the real-data half: no $data/carmen/intel.orig.bag"
  [[ $failed -eq 0 ]] && exit 77
  exit 1
fi
"$bin/driftlab" import "$data/carmen/intel.orig.bag" -o intel.lcm >/dev/null || exit 1
# The benchmark's relations, every tenth of those at most 30 s long made wrong: its yaw 5 degrees off (at 5 m a
# wall's points move 0.44 m, three times the 0.15 m a point may be off and still agree). The others are the
# benchmark's own, checked by people; the scans contradict none of them (none of 1,596).
/usr/bin/python3 - "$data/carmen/intel.relations" wrong.relations wrong.lines <<'PY' || exit 1
import math, sys
short = 0
with open(sys.argv[1]) as f, open(sys.argv[2], "w") as out, open(sys.argv[3], "w") as lines:
    for number, line in enumerate(f, 1):
        v = line.split()
        if line.startswith("#") or not v or float(v[1]) - float(v[0]) > 30:
            out.write(line)
            continue
        short += 1
        if short % 10 == 0:
            v[7] = repr(float(v[7]) + math.radians(5))
            lines.write(f"{number}\n")
        out.write(" ".join(v) + "\n")
PY
"$script" --bin "$bin" --json check.json intel.lcm wrong.relations >out.txt 2>err.txt || {
  echo "FAILED: check-relations on Intel: exit $?"
  cat err.txt
  exit 1
}
cat out.txt
/usr/bin/python3 - check.json wrong.lines <<'PY' || failed=1
import json, sys
j = json.load(open(sys.argv[1]))
wrong = {int(line) for line in open(sys.argv[2])}
checked = {r["line"]: r for r in j["per_relation"]}
made_wrong = [checked[n] for n in wrong if n in checked]
found = sum(r["contradicted"] for r in made_wrong)
others = [r for n, r in checked.items() if n not in wrong]
false_alarms = sum(r["contradicted"] for r in others)
print(f"made wrong: {found} of {len(made_wrong)} found; the benchmark's own: {false_alarms} of {len(others)} flagged")
ok = True
# Every relation checked: Intel's scans overlap at 30 s and less (1,773 of the file's short ones have a scan at
# both stamps: its stamps are its scans').
if len(made_wrong) < len(wrong) * 0.95:
    print(f"FAILED: only {len(made_wrong)} of the {len(wrong)} relations made wrong were checked"); ok = False
# 5 degrees off is found where it leaves clearly fewer points on the walls: in a small room at a few metres most
# of them still agree with the first scan (ours: 157 of 177 found; ICP turns nearly all of them back by 4-6
# degrees). A check that found nothing wrong, or everything, fails one of these.
if found < 0.8 * len(made_wrong):
    print(f"FAILED: {found} of {len(made_wrong)} relations 5 degrees off found (at least 80%)"); ok = False
if false_alarms > 0.01 * len(others):
    print(f"FAILED: {false_alarms} of the benchmark's {len(others)} relations flagged (at most 1%)"); ok = False
sys.exit(0 if ok else 1)
PY

# The sideways check. Intel's relations never move 0.5 m within 30 s (none is checked), so these come from Intel's
# own wheel odometry: a pair of its poses 3 s apart that moves 0.6-3 m and turns under 8 degrees every 20 s, as
# it is (the chord where the odometry's is: not sideways), its chord turned 5 degrees (at most 7 off the heading
# where the odometry's is within 2: under the 8 that count) or 12 (at least 10: sideways). The check reads the
# odometry at stamps between its poses, so a pose or a sign it read wrong moves every one of these.
"$bin/driftlab" export tum intel.lcm:/odom -o odom.tum >/dev/null || exit 1
/usr/bin/python3 - odom.tum side.relations side.turned <<'PY' || exit 1
import bisect, math, sys
rows = sorted(tuple(map(float, line.split())) for line in open(sys.argv[1]) if not line.startswith("#"))
t = [r[0] for r in rows]
def pose(r):
    return r[1], r[2], math.atan2(2 * (r[7] * r[6] + r[4] * r[5]), 1 - 2 * (r[5] ** 2 + r[6] ** 2))
count, last = 0, -1e9
with open(sys.argv[2], "w") as out, open(sys.argv[3], "w") as turned:
    for r in rows:
        j = bisect.bisect_left(t, r[0] + 3.0)
        if r[0] < last + 20 or j >= len(rows) or abs(t[j] - r[0] - 3.0) > 0.05:
            continue
        (ax, ay, ayaw), (bx, by, byaw) = pose(r), pose(rows[j])
        c, s = math.cos(ayaw), math.sin(ayaw)
        x, y = c * (bx - ax) + s * (by - ay), -s * (bx - ax) + c * (by - ay)
        yaw = math.remainder(byaw - ayaw, 2 * math.pi)
        if not 0.6 <= math.hypot(x, y) <= 3 or abs(math.degrees(yaw)) >= 8:
            continue
        last = r[0]
        turn = (0, 5, 12)[count % 3]
        count += 1
        k, l = math.cos(math.radians(turn)), math.sin(math.radians(turn))
        out.write(f"{r[0]:.6f} {t[j]:.6f} {k * x - l * y:.6f} {l * x + k * y:.6f} 0 0 0 {yaw:.6f}\n")
        turned.write(f"{turn}\n")
PY
"$script" --bin "$bin" --json side.json intel.lcm side.relations >out.txt 2>err.txt || {
  echo "FAILED: check-relations on Intel's odometry: exit $?"
  cat err.txt
  exit 1
}
grep '^sideways' out.txt
/usr/bin/python3 - side.json side.turned <<'PY' || failed=1
import json, sys
j = json.load(open(sys.argv[1]))
turned = [int(line) for line in open(sys.argv[2])]
by_turn = {0: [], 5: [], 12: []}
for r in j["per_relation_sideways"]:
    by_turn[turned[r["line"] - 1]].append(r)
print(", ".join(f"turned {k} deg: {sum(r['sideways'] for r in v)} of {len(v)} sideways" for k, v in by_turn.items()))
ok = True
if j["odometry"] != "/odom":
    print(f"FAILED: the odometry read was {j['odometry']}, not /odom"); ok = False
# Intel's robot drives along its heading: its odometry's chord is within 2 degrees on most of these stretches.
if min(len(v) for v in by_turn.values()) < 10:
    print(f"FAILED: too few relations checked: {[len(v) for v in by_turn.values()]}"); ok = False
straight = [r for r in by_turn[12] if abs(r["odometry_sideways_deg"]) <= 2]
if sum(r["sideways"] for r in straight) != len(straight) or not straight:
    print("FAILED: a relation turned 12 degrees where the odometry went straight was not found sideways"); ok = False
if any(r["sideways"] for r in by_turn[0] + by_turn[5]):
    print("FAILED: a relation within 7 degrees of the heading was found sideways"); ok = False
sys.exit(0 if ok else 1)
PY
exit $failed
