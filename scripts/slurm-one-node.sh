#!/usr/bin/env bash
# A one-node Slurm on this machine, to try docs/cluster.md's recipe and to test it: munged,
# slurmctld and slurmd on localhost; this host is the only node (its real CPUs and memory,
# from `slurmd -C`), in one partition, without cgroup plugins. Debian paths: the config in
# /etc/slurm/slurm.conf (so sbatch and sinfo need no SLURM_CONF), state in /var/lib/slurm,
# logs in /var/log/slurm. Runs as root; installs slurm-wlm and munge with apt when missing.
# A daemon already running is left alone, so a second run only checks that the node is up.
# Usage: scripts/slurm-one-node.sh [start|stop]   (stop ends the three daemons by pid file)
set -euo pipefail

conf=/etc/slurm/slurm.conf
mark="# Written by camplace's scripts/slurm-one-node.sh; it rewrites this file."
munge_pid=/run/munge/munged.pid
ctld_pid=/run/slurmctld.pid
slurmd_pid=/run/slurmd.pid
logs="/var/log/munge/munged.log /var/log/slurm/slurmctld.log /var/log/slurm/slurmd.log"
wait_s=${SLURM_ONE_NODE_WAIT_S:-60}

say() { echo "slurm-one-node: $*" >&2; }

# A pid file names a live daemon only when that pid runs the daemon's program: where /run
# is not a tmpfs the files outlive a reboot, and after one their pids often belong to
# other processes (a boot starts the same programs in the same order). Such a file is
# stale: the daemon is started anew, and `stop` never signals the stranger.
alive() {
  local pid
  [ -s "$1" ] || return 1
  pid=$(cat "$1")
  [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = "$(basename "$1" .pid)" ]
}

# Ends with the daemons' own words: their logs' tails, and what the controller thinks.
fail() {
  say "$*"
  for f in $logs; do
    echo "----- $f (last 40 lines)" >&2
    tail -n 40 "$f" >&2 2>/dev/null || echo "(no log)" >&2
  done
  echo "----- sinfo / scontrol show node" >&2
  sinfo -N -l >&2 2>&1 || true
  scontrol show node >&2 2>&1 || true
  exit 1
}

stop() {
  local f
  for f in $slurmd_pid $ctld_pid $munge_pid; do
    if alive "$f"; then kill "$(cat "$f")"; fi
  done
  for _ in $(seq 50); do
    if ! alive $slurmd_pid && ! alive $ctld_pid && ! alive $munge_pid; then
      # slurmctld leaves its pid file, which Debian's slurmctld prerm takes for a running one.
      rm -f $slurmd_pid $ctld_pid
      return 0
    fi
    sleep 0.2
  done
  say "the daemons did not stop within 10 s"
  exit 1
}

node_state() { sinfo -h -n "$node" -o %T 2>/dev/null || true; }

[ "$(id -u)" = 0 ] || { say "run as root: it writes $conf and starts munged, slurmctld and slurmd"; exit 1; }
case ${1:-start} in
  start) ;;
  stop) stop; exit 0 ;;
  *) say "usage: $0 [start|stop]"; exit 2 ;;
esac

if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null; then
  command -v apt-get >/dev/null || { say "slurmctld, slurmd or munged missing and no apt-get: install Slurm and MUNGE"; exit 1; }
  say "installing slurm-wlm and munge"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
fi

# `slurmd -C` prints this machine as a node line: NodeName=... CPUs=... RealMemory=...
node_line=$(slurmd -C | head -n 1)
node=$(echo "$node_line" | sed -E 's/^NodeName=([^ ]+).*/\1/')
[ -n "$node" ] || fail "slurmd -C gave no node name: $node_line"

new_conf=$(cat <<EOF
$mark
ClusterName=camplace
SlurmctldHost=$node(127.0.0.1)
SlurmUser=slurm
AuthType=auth/munge
StateSaveLocation=/var/lib/slurm/slurmctld
SlurmdSpoolDir=/var/lib/slurm/slurmd
SlurmctldPidFile=$ctld_pid
SlurmdPidFile=$slurmd_pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
# No cgroups: processes are tracked by parentage, tasks are not bound.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
MailProg=/bin/true
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
# A node that was down comes back as soon as its slurmd registers.
ReturnToService=2
$node_line NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=main Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
)
if [ -e $conf ] && ! grep -qxF "$mark" $conf; then
  say "$conf exists and was not written by this script; leaving it and the daemons alone"
  exit 1
fi
if [ "$(cat $conf 2>/dev/null)" != "$new_conf" ]; then
  # Daemons started on an older file would not match it.
  stop
  mkdir -p /etc/slurm
  echo "$new_conf" >$conf
fi

started=""
if [ ! -s /etc/munge/munge.key ]; then
  mungekey --create --keyfile=/etc/munge/munge.key
  chown munge:munge /etc/munge/munge.key
  chmod 0600 /etc/munge/munge.key
fi
if ! alive $munge_pid; then
  install -d -o munge -g munge -m 0755 /run/munge
  rm -f $munge_pid
  runuser -u munge -- munged || fail "munged did not start"
  started="$started munged"
fi
munge -n | unmunge >/dev/null || fail "munge cannot encode and decode a credential"

install -d -o slurm -g slurm /var/lib/slurm/slurmctld /var/lib/slurm/slurmd /var/log/slurm
if ! alive $ctld_pid; then
  rm -f $ctld_pid
  slurmctld || fail "slurmctld did not start"
  started="$started slurmctld"
fi
if ! alive $slurmd_pid; then
  rm -f $slurmd_pid
  slurmd || fail "slurmd did not start"
  started="$started slurmd"
fi

resumed=""
for _ in $(seq $((wait_s * 5))); do
  case $(node_state) in
    idle | mixed | allocated | completing)
      if [ -n "$started" ]; then say "started$started; node $node is $(node_state)"; else say "already running; node $node is $(node_state)"; fi
      exit 0
      ;;
    down* | drained* | draining*)
      # Left down by an earlier run (e.g. slurmd stopped under the controller).
      if [ -z "$resumed" ]; then scontrol update NodeName="$node" State=RESUME 2>/dev/null || true; resumed=1; fi
      ;;
  esac
  sleep 0.2
done
fail "node $node is not idle after ${wait_s} s (state: $(node_state))"
