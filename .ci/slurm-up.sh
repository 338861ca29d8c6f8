#!/usr/bin/env bash
# Start a single-node SLURM cluster on this machine, as root, without systemd:
# munged, slurmctld and slurmd from Debian's packages, one partition, no cgroups, no accounting.
#
#   .ci/slurm-up.sh [--install]     (make slurm-up)
#
# --install: apt-get install the packages when missing (slurmctld slurmd slurm-client munge).
# Writes /etc/slurm/slurm.conf (the default path: a job's nested srun loses SLURM_CONF) unless
# one not written by this script is there; the node is this machine (hostname -s, 127.0.0.1),
# CPUs = nproc, RealMemory = 80 % of MemTotal. Idempotent: running daemons are left alone.
# Ends when `srun -N1 -n1 true` works. Stop with .ci/slurm-down.sh (make slurm-down).
# The settings that matter and why: ../shared/slurm-single-node.md of the project notes.
set -euo pipefail

say() { echo "slurm-up: $*" >&2; }
die() { say "$*"; exit 1; }

[ "$(id -u)" = 0 ] || die "must run as root (it starts munged, slurmctld and slurmd)"

if [ "${1:-}" = "--install" ]; then
  missing=()
  for b in /usr/sbin/slurmctld /usr/sbin/slurmd /usr/bin/sinfo /usr/sbin/munged; do
    [ -x "$b" ] || missing+=("$b")
  done
  if [ "${#missing[@]}" -gt 0 ]; then
    say "installing slurmctld slurmd slurm-client munge"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends slurmctld slurmd slurm-client munge >/dev/null
  fi
fi
for b in /usr/sbin/slurmctld /usr/sbin/slurmd /usr/bin/sinfo /usr/bin/srun /usr/sbin/munged; do
  [ -x "$b" ] || die "$b missing: apt-get install --no-install-recommends slurmctld slurmd slurm-client munge (or run with --install)"
done

CONF=/etc/slurm/slurm.conf
MARK="# written by pose-uncertainty .ci/slurm-up.sh"
node=$(hostname -s)
cpus=$(nproc)
mem_total_mb=$(awk '/^MemTotal:/ {print int($2 / 1024)}' /proc/meminfo)
real_mb=$((mem_total_mb * 8 / 10))  # below the machine's memory, or the node drains

if [ -f "$CONF" ] && ! head -n 1 "$CONF" | grep -qF "$MARK"; then
  die "$CONF exists and was not written by this script; not touching a real cluster's config"
fi
mkdir -p /etc/slurm
cat >"$CONF.new" <<CONF
$MARK
ClusterName=ci
SlurmctldHost=${node}(127.0.0.1)
SlurmUser=slurm
SlurmdUser=root
AuthType=auth/munge
MpiDefault=none
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
# no cgroups (no systemd here)
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
# no accounting database: squeue is the status command (workflow/profiles/slurm-test)
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
# finished jobs stay visible to squeue for 5 minutes
MinJobAge=300
NodeName=${node} NodeAddr=127.0.0.1 CPUs=${cpus} RealMemory=${real_mb} State=UNKNOWN
# up to 4 jobs a core: a pipeline job mostly waits for the executor's next status poll
# (the plugin backs off 10 s whenever no job finished), so let others use the core meanwhile
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP OverSubscribe=FORCE:4
CONF
changed=1
if [ -f "$CONF" ] && cmp -s "$CONF.new" "$CONF"; then
  changed=0
fi
mv "$CONF.new" "$CONF"

install -d -o slurm -g slurm /var/spool/slurmctld /var/log/slurm
install -d /var/spool/slurmd
install -d -o munge -g munge -m 0755 /run/munge
if [ ! -s /etc/munge/munge.key ]; then
  install -d -o munge -g munge -m 0700 /etc/munge
  if command -v mungekey >/dev/null; then
    runuser -u munge -- mungekey -c -k /etc/munge/munge.key
  else
    dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
  fi
fi
chown munge:munge /etc/munge/munge.key
chmod 0400 /etc/munge/munge.key

running() { [ -s "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null; }

if ! running /run/munge/munged.pid; then
  runuser -u munge -- /usr/sbin/munged
fi
if ! running /run/slurmctld.pid; then
  /usr/sbin/slurmctld
elif [ "$changed" = 1 ]; then
  scontrol reconfigure
fi
if ! running /run/slurmd.pid; then
  /usr/sbin/slurmd
fi

for _ in $(seq 60); do
  state=$(sinfo -h -o %T 2>/dev/null | head -n 1 || true)
  case "$state" in
    idle | mixed | allocated) break ;;
    drain* | down*) scontrol update nodename="$node" state=resume 2>/dev/null || true ;;
  esac
  sleep 1
done
case "${state:-}" in
  idle | mixed | allocated) ;;
  *) die "node $node is '${state:-unknown}' after 60 s; see /var/log/slurm/slurmctld.log and slurmd.log" ;;
esac
timeout 60 srun -N1 -n1 true || die "srun -N1 -n1 true failed; see /var/log/slurm/"
say "up: node $node, $cpus CPUs, RealMemory ${real_mb} MB, partition debug (pids: munged $(cat /run/munge/munged.pid), slurmctld $(cat /run/slurmctld.pid), slurmd $(cat /run/slurmd.pid))"
