#!/bin/bash
# Runs a command against a single-node Slurm cluster of its own (Debian's slurm-wlm and munge, no systemd): a munge
# key and socket, slurm.conf, state, spool and logs in a temporary folder, free ports on 127.0.0.1, this machine's
# short hostname as the node with CPUs=2. The command sees SLURM_CONF (so sbatch, squeue, scontrol find the cluster)
# and DRIFTLAB_SLURM_DIR (the folder). Every daemon started here is stopped when the command ends, when this script
# is interrupted, and (a watchdog) when this script is killed outright.
#   tests/slurm_run.sh COMMAND [ARGS...]
# Exit 77 (CTest: skipped) when slurm-wlm or munge is not installed, except under CI (CI=true), where it fails;
# a cluster that does not start is a failure everywhere. Needs root (SlurmUser=root, as CI runs).
set -u

need=(munged slurmctld slurmd sbatch squeue scontrol)
for p in "${need[@]}"; do
  if ! command -v "$p" >/dev/null 2>&1 && [ ! -x "/usr/sbin/$p" ]; then
    if [ "${CI:-}" = true ]; then
      echo "slurm_run: $p is not installed (scripts/bootstrap installs slurm-wlm and munge); CI=true: failing" >&2
      exit 1
    fi
    echo "slurm_run: $p is not installed (scripts/bootstrap installs slurm-wlm and munge); skipping" >&2
    exit 77
  fi
done
export PATH="$PATH:/usr/sbin"
if [ "$(id -u)" -ne 0 ]; then
  echo "slurm_run: the test cluster runs its daemons as root (SlurmUser=root); run as root" >&2
  exit 1
fi

dir=$(mktemp -d /tmp/driftlab-slurm-XXXXXX)
chmod 700 "$dir"
mkdir -p "$dir/munge" "$dir/state" "$dir/spool" "$dir/log"
chmod 700 "$dir/munge"
pids=()

stop_all() {
  # scancel everything first so slurmd has no job to keep, then the daemons, slurmd before slurmctld before munged.
  [ -f "$dir/slurm.conf" ] && SLURM_CONF="$dir/slurm.conf" timeout 5 scancel --full -u root >/dev/null 2>&1
  for f in slurmd slurmctld munged; do
    if [ -f "$dir/$f.pid" ]; then
      pid=$(cat "$dir/$f.pid" 2>/dev/null)
      [ -n "$pid" ] && kill "$pid" 2>/dev/null
    fi
  done
  for f in slurmd slurmctld munged; do
    pid=$(cat "$dir/$f.pid" 2>/dev/null)
    [ -z "$pid" ] && continue
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null
  done
  # What slurmd started for jobs (slurmstepd and the tasks under it): their session is gone with the daemons.
  pkill -9 -P "$(cat "$dir/slurmd.pid" 2>/dev/null || echo 0)" 2>/dev/null
  [ -n "${watchdog:-}" ] && kill "$watchdog" 2>/dev/null
  rm -rf "$dir"
}

fail_start() {
  echo "slurm_run: the test cluster did not start: $1" >&2
  for f in "$dir"/log/*.log; do [ -f "$f" ] && { echo "--- $f" >&2; tail -n 15 "$f" >&2; }; done
  stop_all
  exit 1
}

free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1]); s.close()'
}

trap 'stop_all; exit 130' INT TERM
trap 'stop_all' EXIT

# munge: a key of its own and a socket of its own.
dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$dir/munge/munge.key"
socket="$dir/munge/munge.socket"
munged --force --key-file="$dir/munge/munge.key" --socket="$socket" --pid-file="$dir/munged.pid" \
  --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed" >/dev/null 2>&1 ||
  fail_start "munged exited with $?"
for _ in $(seq 50); do [ -S "$socket" ] && break; sleep 0.1; done
[ -S "$socket" ] || fail_start "munged made no socket"

# The watchdog: stops the daemons should this script be killed without running its traps (a test timeout).
parent=$$
setsid sh -c '
  while kill -0 '"$parent"' 2>/dev/null; do sleep 1; done
  for f in slurmd slurmctld munged; do [ -f "'"$dir"'/$f.pid" ] && kill -9 "$(cat "'"$dir"'/$f.pid")" 2>/dev/null; done
  rm -rf "'"$dir"'"' >/dev/null 2>&1 </dev/null &
watchdog=$!

host=$(hostname -s)
ctld_port=$(free_port)
slurmd_port=$(free_port)
while [ "$slurmd_port" = "$ctld_port" ]; do slurmd_port=$(free_port); done
cat >"$dir/slurm.conf" <<EOF
# Written by tests/slurm_run.sh: a single-node test cluster on 127.0.0.1.
ClusterName=driftlabtest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
# cred_expire: how long a requeued task waits before it may start again (the default, 120 s, is for real clusters).
AuthInfo=socket=$socket,cred_expire=10
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
MailProg=/bin/true
SlurmctldTimeout=30
SlurmdTimeout=30
MinJobAge=300
MaxArraySize=10001
NodeName=$host NodeAddr=127.0.0.1 CPUs=2 RealMemory=1000 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
EOF
export SLURM_CONF="$dir/slurm.conf"

slurmctld -f "$SLURM_CONF" -i >/dev/null 2>&1 || fail_start "slurmctld exited with $?"
slurmd -f "$SLURM_CONF" -N "$host" >/dev/null 2>&1 || fail_start "slurmd exited with $?"
# Ready when the node takes jobs.
ok=
for _ in $(seq 150); do
  state=$(sinfo -h -N -o '%T' 2>/dev/null | head -n 1)
  case "$state" in idle*|mixed*|allocated*) ok=1; break ;; esac
  sleep 0.2
done
[ -n "$ok" ] || fail_start "the node did not come up (state: ${state:-none})"

export DRIFTLAB_SLURM_DIR="$dir"
"$@"
rc=$?
exit $rc
