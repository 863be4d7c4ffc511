#!/usr/bin/env bash
# A private single-node Slurm cluster in one folder, for tests and for trying
# `rephoto ... --executor slurm` on one machine (docs/cluster.md).
#
#   scripts/slurm-cluster.sh start DIR    start munged, slurmctld and slurmd with a generated
#                                         slurm.conf in DIR; wait until the node is idle
#   scripts/slurm-cluster.sh stop DIR     stop them by the PIDs recorded in DIR
#   scripts/slurm-cluster.sh status DIR   exit 0 when the cluster in DIR answers
#   scripts/slurm-cluster.sh env DIR      print `export SLURM_CONF=DIR/slurm.conf`
#
# Use it:   eval "$(scripts/slurm-cluster.sh env DIR)"; sbatch --wrap 'hostname'; squeue
#
# Everything lives in DIR (sockets in a short folder in /tmp when DIR's path is long): its own
# munge key and socket, free TCP ports picked at start, state, spool, logs and pid files, so it
# runs beside other such clusters and beside a real Slurm.
# Nothing is stopped by name: `stop` sends SIGTERM to the recorded PIDs only, after checking that
# each still runs the program it was started as with this folder's files (a reused PID is left
# alone), then SIGKILL to those still alive 10 s later.
#
# Needs root (slurmd runs jobs as their submitting user and the daemons run as root here) and the
# Debian packages slurmctld, slurmd, slurm-client and munge (scripts/install-deps.sh). When either
# is missing, `start` prints why on one line and exits with --skip-code (default 1), so a ctest
# fixture can report the tests as skipped (SKIP_RETURN_CODE) instead of failed.
set -euo pipefail

usage() { echo "usage: $0 start|stop|status|env [--skip-code N] DIR" >&2; exit 2; }
[ $# -ge 2 ] || usage
action=$1
shift
skip_code=1
if [ "$1" = "--skip-code" ]; then
  [ $# -ge 3 ] || usage
  skip_code=$2
  shift 2
fi
[ $# -eq 1 ] || usage
mkdir -p "$1"
dir=$(cd "$1" && pwd)
conf="$dir/slurm.conf"

# The PID in pid file $1 if it still runs program $2 (its /proc/PID/cmdline mentions $dir).
recorded_pid() {
  local file=$1 program=$2 pid
  [ -s "$file" ] || return 1
  pid=$(tr -dc '0-9' <"$file")
  [ -n "$pid" ] && [ -r "/proc/$pid/cmdline" ] || return 1
  local cmdline
  cmdline=$(tr '\0' ' ' <"/proc/$pid/cmdline" 2>/dev/null) || return 1
  case "$cmdline" in
    *"$program"*"$dir"*) echo "$pid" ;;
    *) return 1 ;;
  esac
}

stop_cluster() {
  local pids=() pid
  for entry in "run/slurmd.pid:slurmd" "run/slurmctld.pid:slurmctld" "munge/munged.pid:munged"; do
    if pid=$(recorded_pid "$dir/${entry%%:*}" "${entry##*:}"); then
      kill -TERM "$pid" 2>/dev/null || true
      pids+=("$pid")
    fi
  done
  for _ in $(seq 100); do
    local alive=()
    for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive+=("$pid"); done
    [ ${#alive[@]} -eq 0 ] && break
    sleep 0.1
  done
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
  rm -f "$dir/run/slurmd.pid" "$dir/run/slurmctld.pid" "$dir/munge/munged.pid" 2>/dev/null || true
  # The short folder for sockets made by `start` when DIR's path is long.
  if [ -s "$dir/sockets" ]; then
    local sockets
    sockets=$(cat "$dir/sockets")
    case "$sockets" in /tmp/rephoto-slurm.*) rm -rf "$sockets" ;; esac
    rm -f "$dir/sockets"
  fi
}

skip() {
  echo "slurm-cluster: skipped: $*" >&2
  echo "$*" >"$dir/skipped"
  exit "$skip_code"
}

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

start_cluster() {
  rm -f "$dir/skipped"
  [ "$(id -u)" -eq 0 ] || skip "a private Slurm cluster needs root (slurmd runs jobs as their user); run as root"
  local program
  for program in munged slurmctld slurmd sbatch squeue scontrol; do
    command -v "$program" >/dev/null 2>&1 || [ -x "/usr/sbin/$program" ] ||
      skip "$program not found; install slurmctld slurmd slurm-client munge (scripts/install-deps.sh)"
  done
  # slurmd 22.05 initializes its cgroup plugin at start whatever the proctrack/task plugins are,
  # and gives up without a cgroup file system: a machine always has one; a bare chroot without
  # /sys (a build root) does not, and cannot host Slurm at all.
  if ! grep -qs ' /sys/fs/cgroup[/ ]' /proc/mounts; then
    skip "no cgroup file system at /sys/fs/cgroup (a chroot without /sys?): slurmd 22.05 cannot start"
  fi
  stop_cluster # a cluster left behind in this folder by an interrupted run
  rm -rf "$dir/state" "$dir/spool" "$dir/log" "$dir/run" "$dir/munge"
  mkdir -p "$dir/state" "$dir/log" "$dir/run" "$dir/munge"
  chmod 0700 "$dir/munge"
  # Unix socket paths must fit 108 bytes: below a long DIR, munged's and slurmd's sockets go to
  # a short folder in /tmp (removed by `stop`).
  local sockets="$dir"
  if [ ${#dir} -gt 50 ]; then
    sockets=$(mktemp -d /tmp/rephoto-slurm.XXXXXX)
    echo "$sockets" >"$dir/sockets"
  fi
  mkdir -p "$sockets/spool"

  # munge: a key of our own, its own socket; slurm.conf's AuthInfo points Slurm at it.
  dd if=/dev/urandom of="$dir/munge/munge.key" bs=1 count=1024 status=none
  chmod 0400 "$dir/munge/munge.key"
  local munged=/usr/sbin/munged
  command -v munged >/dev/null 2>&1 && munged=$(command -v munged)
  "$munged" --force --socket="$sockets/munge.socket" --key-file="$dir/munge/munge.key" \
    --pid-file="$dir/munge/munged.pid" --log-file="$dir/log/munged.log" \
    --seed-file="$dir/munge/munged.seed" ||
    { echo "slurm-cluster: munged did not start; see $dir/log/munged.log" >&2; exit 1; }

  local host port_ctld port_d memory_mb node
  host=$(hostname -s)
  port_ctld=$(free_port)
  port_d=$(free_port)
  while [ "$port_d" = "$port_ctld" ]; do port_d=$(free_port); done
  memory_mb=$(awk '/^MemTotal:/ { printf "%d", $2 / 1024 * 0.8 }' /proc/meminfo)
  node="rephoto-$port_d"
  cat >"$conf" <<EOF
# Generated by scripts/slurm-cluster.sh: a single-node cluster on this machine.
ClusterName=rephototest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port_ctld
SlurmdPort=$port_d
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$sockets/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$sockets/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
# Schedule at once instead of every few seconds (defaults 60/30/3 s): a chain of three arrays of
# no-op tasks took 12 s with the defaults and 2.3 s with these.
SchedulerParameters=sched_interval=1,bf_interval=1,batch_sched_delay=0
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
MinJobAge=600
KillWait=5
SlurmdTimeout=60
PlugStackConfig=$dir/plugstack.conf
NodeName=$node NodeHostname=$host NodeAddr=127.0.0.1 CPUs=2 RealMemory=$memory_mb State=UNKNOWN
PartitionName=rephoto Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
  : >"$dir/plugstack.conf"
  echo "$node" >"$dir/node"

  export SLURM_CONF="$conf"
  slurmctld -f "$conf" ||
    { echo "slurm-cluster: slurmctld did not start; see $dir/log/slurmctld.log" >&2; stop_cluster; exit 1; }
  slurmd -f "$conf" -N "$node" ||
    { echo "slurm-cluster: slurmd did not start; see $dir/log/slurmd.log" >&2; stop_cluster; exit 1; }
  local state=""
  for _ in $(seq 300); do
    state=$(sinfo -h -n "$node" -o '%T' 2>/dev/null || true)
    [ "$state" = "idle" ] && break
    sleep 0.1
  done
  if [ "$state" != "idle" ]; then
    echo "slurm-cluster: node $node is '${state:-not answering}' after 30 s; logs in $dir/log" >&2
    stop_cluster
    exit 1
  fi
  echo "slurm-cluster: running in $dir (node $node, ports $port_ctld/$port_d); export SLURM_CONF=$conf" >&2
}

case "$action" in
  start) start_cluster ;;
  stop) stop_cluster ;;
  status) SLURM_CONF="$conf" sinfo -h -o '%T' >/dev/null 2>&1 ;;
  env) printf 'export SLURM_CONF=%q\n' "$conf" ;;
  *) usage ;;
esac
