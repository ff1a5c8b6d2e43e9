#!/usr/bin/env bash
# `cmake --install` into a scratch prefix, then the installed driftlab run from a scratch folder with the source
# and build trees out of sight: the programs must find their data and each other relative to themselves
# (core/install_layout.h), never through a path compiled in.
#   tests/install_test.sh BUILD_DIR SOURCE_DIR          the install tree
#   tests/install_test.sh --deb BUILD_DIR SOURCE_DIR    the Debian package (cpack), unpacked with dpkg -x
# Where it may (root, unshare), the source tree is hidden under an empty tmpfs in a mount namespace of the test's
# own while the installed programs run; elsewhere they run with it in place, and the byte check below still holds.
set -euo pipefail
deb=0
if [[ ${1:-} == --deb ]]; then deb=1; shift; fi
build=$(realpath "$1") source=$(realpath "$2")
tmp=$(mktemp -d /tmp/driftlab-install-test-XXXXXX)
trap 'rm -rf "$tmp"' EXIT

if ((deb)); then
  # The package exactly as scripts/package makes it, into the scratch folder.
  (cd "$build" && cpack -G DEB -B "$tmp/package" >"$tmp/cpack.log" 2>&1) || { cat "$tmp/cpack.log"; exit 1; }
  package=$(ls "$tmp"/package/driftlab_*.deb)
  info=$(dpkg-deb -I "$package")
  for dep in python3-matplotlib libjs-dygraphs libbullet libmrpt liblcm libopencv liburdfdom libyaml-cpp; do
    grep -q "^ Depends:.*$dep" <<<"$info" || { echo "the package's Depends lacks $dep:"; grep Depends <<<"$info"; exit 1; }
  done
  # What `apt install ./driftlab_*.deb` does on this machine, simulated: every Depends resolves against its archive
  # (a name Debian 12 does not have, or a version it cannot give, fails here: "Depends: ... but it is not installable").
  if command -v apt-get >/dev/null; then
    plan=$(apt-get install --simulate "$package" 2>&1) || { echo "apt would not install $package:"; echo "$plan"; exit 1; }
    grep -q "^Inst driftlab " <<<"$plan" || { echo "apt's plan does not install driftlab:"; echo "$plan"; exit 1; }
  fi
  dpkg-deb -x "$package" "$tmp/root"
  prefix=$tmp/root/usr
else
  cmake --install "$build" --prefix "$tmp/usr" --strip >"$tmp/install.log" || { cat "$tmp/install.log"; exit 1; }
  prefix=$tmp/usr
fi
echo "installed into $prefix [at $SECONDS s]"

# The layout docs/install.md promises.
for f in bin/driftlab lib/driftlab/driftlab-sim lib/driftlab/driftlab-replay lib/driftlab/driftlab-rawlog \
  lib/driftlab/driftlab-icp-slam.so \
  share/driftlab/scenarios/indoor.yaml share/driftlab/worlds/building.yaml share/driftlab/robots/diffbot.urdf \
  share/bash-completion/completions/driftlab share/man/man1/driftlab.1 share/man/man1/driftlab-sim.1; do
  [[ -e $prefix/$f ]] || { echo "not installed: $f"; exit 1; }
done
# The Python module goes with the programs when the build has one.
if [[ -d $build/python/driftlab && ! -f $prefix/lib/python3/dist-packages/driftlab/__init__.py ]]; then
  echo "not installed: the Python module (lib/python3/dist-packages/driftlab)"
  exit 1
fi
# No installed file names the source tree (it holds the build tree too).
if grep -rlF "$source" "$prefix"; then
  echo "the files above name the source tree $source"
  exit 1
fi

# run_installed PREFIX WORK DEB: the installed driftlab on real work, from WORK, with nothing of the build on PATH.
run_installed() {
  set -euo pipefail
  local prefix=$1 work=$2 deb=$3
  cd "$work"
  export PATH=/usr/bin:/bin
  unset DRIFTLAB_PYTHON
  local driftlab=$prefix/bin/driftlab
  "$driftlab" --version
  # The default scenario (share/driftlab/scenarios/indoor.yaml, its world and URDF beside it) via driftlab-sim.
  "$driftlab" sim --duration 3 -o sim.lcm --json >sim.json
  "$driftlab" info sim.lcm --json >info.json
  grep -q '"GROUND_TRUTH"' info.json
  # Every program driftlab runs (lib/driftlab): sim above, replay, rawlog.
  "$driftlab" replay sim.lcm --modules estimator -o replay.lcm >/dev/null
  "$driftlab" export rawlog sim.lcm -o sim.rawlog >/dev/null
  [[ -s replay.lcm && -s sim.rawlog ]]
  # The icp-slam method's library (slam/internal/icp_slam.h), loaded from lib/driftlab; without it, one line that
  # names it and exit 2.
  printf 'slam:\n  2d:\n    method: icp-slam\n' >icp.yaml
  "$driftlab" replay sim.lcm --modules slam --config icp.yaml -o icp.lcm >/dev/null
  "$driftlab" info icp.lcm | grep -q '^SLAM_POSE '
  mv "$prefix/lib/driftlab/driftlab-icp-slam.so" "$work/away.so"
  local rc=0
  "$driftlab" replay sim.lcm --modules slam --config icp.yaml -o missing.lcm >/dev/null 2>missing.err || rc=$?
  mv "$work/away.so" "$prefix/lib/driftlab/driftlab-icp-slam.so"
  if ((rc != 2)) || [[ $(wc -l <missing.err) != 1 ]] || ! grep -q 'driftlab-icp-slam.so is not beside' missing.err; then
    echo "icp-slam without its library: exit $rc, said:"
    cat missing.err
    exit 1
  fi
  echo "sim, info, replay (icp-slam too), export rawlog [$SECONDS s into the run]"
  # The demo: sim, diagnose, replay twice, eval and the report (python3 with matplotlib), as child processes; once
  # (the package holds the same programs, and making it takes long enough).
  if ((!deb)); then
    "$driftlab" demo --duration 5 -o demo --json >demo.json
    [[ -s demo/report/index.html ]]
    echo "demo [$SECONDS s into the run]"
  fi
  # The Python module, where the build made one (pybind11 found): imported from the prefix, it reads the log and
  # diagnoses it as the installed program does.
  if [[ -d $prefix/lib/python3/dist-packages/driftlab ]]; then
    "$driftlab" diagnose sim.lcm --json >diagnose.json
    PYTHONPATH=$prefix/lib/python3/dist-packages python3 -c '
import json, driftlab
log = driftlab.open("sim.lcm")
assert "GROUND_TRUTH" in log.channels, log.channels
imu = log.read("IMU")
assert len(imu["stamp"]) == len(imu["arrival"]) > 0
assert driftlab.diagnose("sim.lcm") == json.load(open("diagnose.json")), "diagnose differs from the CLI"
'
    echo "python3 -c 'import driftlab' [$SECONDS s into the run]"
  fi
  # The bash completion completes verbs and options from the program's --help.
  (
    source "$prefix/share/bash-completion/completions/driftlab"
    COMP_WORDS=("$driftlab" s) COMP_CWORD=1
    _driftlab
    [[ " ${COMPREPLY[*]} " == *" sim "* && " ${COMPREPLY[*]} " == *" sweep "* ]] || {
      echo "completion of 'driftlab s': ${COMPREPLY[*]}"
      exit 1
    }
    COMP_WORDS=("$driftlab" info --j) COMP_CWORD=2
    _driftlab
    [[ ${COMPREPLY[*]} == "--json --json-out" ]] || { echo "completion of 'driftlab info --j': ${COMPREPLY[*]}"; exit 1; }
    COMP_WORDS=("$driftlab" eval --align "") COMP_CWORD=3
    _driftlab
    [[ " ${COMPREPLY[*]} " == *" posyaw "* ]] || { echo "completion of 'eval --align': ${COMPREPLY[*]}"; exit 1; }
  )
  # The man pages read (man's own formatter, when man-db is there).
  if command -v man >/dev/null; then
    MANWIDTH=100 man -l "$prefix/share/man/man1/driftlab-sim.1" 2>/dev/null | grep -q -- '--duration'
  fi
}

mkdir "$tmp/work"
script="$(declare -f run_installed); run_installed '$prefix' '$tmp/work' $deb"
# $tmp must stay visible: it is not under the source tree (mktemp in /tmp).
if [[ $(id -u) == 0 ]] && unshare --mount --propagation private true 2>/dev/null; then
  echo "running the installed driftlab with $source hidden"
  unshare --mount --propagation private bash -c "mount -t tmpfs none '$source' && $script"
else
  echo "running the installed driftlab (the source tree stays in place: not root, or no unshare)"
  bash -c "$script"
fi
echo "ok [at $SECONDS s]"
