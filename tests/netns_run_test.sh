#!/bin/sh
# Tests tests/netns_run.sh where no network namespace can be made: outside CI it skips (exit 77, CTest's "skipped"),
# under CI=true it fails (exit 1), so CI cannot pass while the recorder, interop and live tests did not run. Two fake
# environments: one whose PATH has no unshare at all, one whose unshare refuses (no root, no user namespaces). In
# neither is the wrapped command run outside a namespace.
#   tests/netns_run_test.sh [PATH/TO/netns_run.sh]
script=${1:-$(dirname "$0")/netns_run.sh}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
mkdir "$dir/none" "$dir/refusing"
printf '#!/bin/sh\necho "unshare: unshare failed: Operation not permitted" >&2\nexit 1\n' >"$dir/refusing/unshare"
chmod +x "$dir/refusing/unshare"
failed=0
passed=0

# expect NAME CODE MESSAGE PATH [VAR=VALUE...]: netns_run.sh in a clean environment with that PATH and variables
# exits with CODE, says MESSAGE on stderr, and never runs its command.
expect() {
  name=$1 code=$2 message=$3 path=$4
  shift 4
  rm -f "$dir/ran"
  env -i PATH="$path" "$@" /bin/sh "$script" /bin/sh -c ": >'$dir/ran'" 2>"$dir/err"
  got=$?
  if [ "$got" -ne "$code" ]; then
    echo "FAIL $name: exit $got, expected $code; stderr: $(cat "$dir/err")"
    failed=$((failed + 1))
  elif ! grep -qF "$message" "$dir/err"; then
    echo "FAIL $name: stderr does not say \"$message\": $(cat "$dir/err")"
    failed=$((failed + 1))
  elif [ -e "$dir/ran" ]; then
    echo "FAIL $name: the command ran outside a network namespace"
    failed=$((failed + 1))
  else
    echo "ok   $name"
    passed=$((passed + 1))
  fi
}

expect "no unshare, outside CI: skipped" 77 "; skipping" "$dir/none"
expect "no unshare, CI=false: skipped" 77 "; skipping" "$dir/none" CI=false
expect "no unshare, CI=true: failed" 1 "CI=true: failing" "$dir/none" CI=true
expect "unshare refused, outside CI: skipped" 77 "; skipping" "$dir/refusing"
expect "unshare refused, CI=true: failed" 1 "CI=true: failing" "$dir/refusing" CI=true

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
