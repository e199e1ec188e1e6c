#!/usr/bin/env bash
# Starts a real one-node Slurm cluster on this machine (Debian's slurm-wlm 22.05 + munge, as
# `scripts/setup.sh` installs them) for the recipe and ablation Slurm tests, or for trying
# `repertoire recipe run --slurm` without a cluster. Everything it writes lies under DIR
# (default: target/slurm-local): slurm.conf, the controller's state, the daemons' logs and pids.
#
#   bash scripts/slurm-local.sh [DIR]        start (a no-op when its cluster already answers)
#   bash scripts/slurm-local.sh stop [DIR]   stop its slurmctld and slurmd
#
# It prints `export SLURM_CONF=DIR/slurm.conf`: sbatch, squeue and scontrol find the cluster
# through that variable. The daemons run as root (Slurm's own user is not needed on one node),
# with ProctrackType=proctrack/linuxproc and TaskPlugin=task/none, which need no cgroups.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
action=start
if [ "${1:-}" = stop ] || [ "${1:-}" = start ]; then action="$1"; shift; fi
dir="${1:-$root/target/slurm-local}"
mkdir -p "$dir"
dir="$(cd "$dir" && pwd)"
conf="$dir/slurm.conf"

stop() {
  local pid
  for pid in "$dir/slurmd.pid" "$dir/slurmctld.pid"; do
    if [ -f "$pid" ]; then kill "$(cat "$pid")" 2>/dev/null || true; rm -f "$pid"; fi
  done
}
if [ "$action" = stop ]; then stop; exit 0; fi

for tool in slurmctld slurmd sbatch munged; do
  command -v "$tool" >/dev/null || [ -x "/usr/sbin/$tool" ] || {
    echo "slurm-local: $tool is missing; run scripts/setup.sh (it installs Debian's slurm-wlm and munge)" >&2
    exit 1
  }
done
[ "$(id -u)" = 0 ] || { echo "slurm-local: the one-node cluster runs its daemons as root; run it as root" >&2; exit 1; }
export PATH="$PATH:/usr/sbin"
export SLURM_CONF="$conf"

# munge: one daemon per machine, shared by every cluster started here.
if ! munge -n </dev/null >/dev/null 2>&1; then
  mkdir -p /run/munge /var/log/munge /var/lib/munge
  [ -f /etc/munge/munge.key ] || mungekey --create >/dev/null 2>&1 || /usr/sbin/create-munge-key -f >/dev/null
  chown -R munge:munge /run/munge /var/log/munge /var/lib/munge /etc/munge 2>/dev/null || true
  if id munge >/dev/null 2>&1; then
    runuser -u munge -- munged || munged --force
  else
    munged --force
  fi
  for _ in $(seq 50); do munge -n </dev/null >/dev/null 2>&1 && break; sleep 0.1; done
  munge -n </dev/null >/dev/null 2>&1 || { echo "slurm-local: munged did not start" >&2; exit 1; }
fi

if [ -f "$conf" ] && scontrol ping 2>/dev/null | grep -q UP && sinfo -h -o %T 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then
  echo "export SLURM_CONF=$conf"
  exit 0
fi
stop

host="$(hostname -s)"
cpus="$(nproc)"
mem_mb="$(awk '/MemTotal/ { print int($2 / 1024) }' /proc/meminfo)"
mkdir -p "$dir/state" "$dir/spool" "$dir/log"
cat > "$conf" <<EOF
# Written by scripts/slurm-local.sh: a one-node cluster for tests.
ClusterName=repertoire-local
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldPort=${SLURMCTLD_PORT:-6817}
SlurmdPort=${SLURMD_PORT:-6818}
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
SlurmctldTimeout=30
SlurmdTimeout=30
MinJobAge=300
NodeName=$host CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=local Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF

slurmctld -c -f "$conf"
slurmd -f "$conf"
for _ in $(seq 100); do
  if sinfo -h -o %T 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then
    echo "export SLURM_CONF=$conf"
    exit 0
  fi
  sleep 0.2
done
echo "slurm-local: the node did not come up; see $dir/log/slurmctld.log and $dir/log/slurmd.log" >&2
sinfo >&2 || true
exit 1
