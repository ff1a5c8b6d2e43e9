#!/bin/sh
# Runs a command inside a private network namespace whose loopback carries multicast, so LCM's udpm
# transport never touches a real interface. Exit 77 (CTest: skipped) when namespaces are not available, except
# under CI (CI=true), where a skipped recorder, interop or live test would hide a failure: there it fails.
#   tests/netns_run.sh COMMAND [ARGS...]
if [ "${DRIFTLAB_IN_NETNS:-}" = 1 ]; then exec "$@"; fi
if ! unshare -n true 2>/dev/null; then
  if [ "${CI:-}" = true ]; then
    echo "netns_run: cannot create a network namespace (needs root or user namespaces); CI=true: failing" >&2
    exit 1
  fi
  echo "netns_run: cannot create a network namespace (needs root or user namespaces); skipping" >&2
  exit 77
fi
exec unshare -n sh -c '
  set -e
  ip link set lo up
  ip link set lo multicast on
  ip route add 224.0.0.0/4 dev lo
  DRIFTLAB_IN_NETNS=1 exec "$@"' netns_run "$@"
