#!/usr/bin/env bash
# A throw-away one-node Slurm cluster on this machine, for tests and trying the farm scripts:
#   tools/farm/slurm_cluster.sh start DIR   # writes DIR/slurm.conf, starts munged, slurmctld, slurmd
#   tools/farm/slurm_cluster.sh stop DIR    # stops them and removes stale pid files
# Afterwards use Slurm's commands with SLURM_CONF=DIR/slurm.conf. Needs root and Debian's
# slurm-wlm and munge packages. There is no systemd here: every daemon is started by hand.
set -euo pipefail
cmd=${1:?start or stop}
dir=$(mkdir -p "${2:?state directory}" && cd "$2" && pwd)
conf=$dir/slurm.conf

stop() {
  for name in slurmd slurmctld; do
    if [ -f "$dir/$name.pid" ]; then
      pid=$(cat "$dir/$name.pid" 2>/dev/null || true)
      if [ -n "$pid" ]; then
        kill "$pid" 2>/dev/null || true
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$pid" 2>/dev/null || true
      fi
      rm -f "$dir/$name.pid"
    fi
  done
  # A killed slurmctld leaves Debian's pid file behind; remove it (it breaks package removal).
  rm -f /run/slurmctld.pid /run/slurmd.pid
  if [ -f "$dir/munged.pid" ]; then
    kill "$(cat "$dir/munged.pid")" 2>/dev/null || true
    rm -f "$dir/munged.pid"
  fi
}

if [ "$cmd" = stop ]; then
  stop
  exit 0
fi
[ "$cmd" = start ] || { echo "usage: $0 start|stop DIR" >&2; exit 2; }

# munge: its key is made by the package; its socket directory must belong to munge.
mkdir -p /run/munge "$dir/munge"
chown munge:munge /run/munge "$dir/munge"
[ -f /etc/munge/munge.key ] || runuser -u munge -- mungekey -c
if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
  runuser -u munge -- munged --pid-file="$dir/munge/munged.pid" --log-file="$dir/munge/munged.log" || true
  cp "$dir/munge/munged.pid" "$dir/munged.pid" 2>/dev/null || true
  for _ in $(seq 50); do munge -n 2>/dev/null | unmunge >/dev/null 2>&1 && break; sleep 0.1; done
fi
munge -n | unmunge >/dev/null

mkdir -p "$dir/state" "$dir/spool" "$dir/log"
chown -R slurm:slurm "$dir/state" "$dir/log"
node=$(slurmd -C | head -1)
cpus=$(sed -n 's/.*CPUs=\([0-9]*\).*/\1/p' <<<"$node")
mem=$(sed -n 's/.*RealMemory=\([0-9]*\).*/\1/p' <<<"$node")
cat >"$conf" <<CONF
ClusterName=velourci
SlurmctldHost=localhost
SlurmUser=slurm
AuthType=auth/munge
# A requeued job waits cred_expire seconds (default 120) before it may start again; keep the
# wait short on this test cluster.
AuthInfo=cred_expire=5
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
# Schedule at once rather than on the default periodic passes (a test cluster, idle otherwise).
SchedulerType=sched/builtin
SchedulerParameters=sched_interval=1,batch_sched_delay=0,sched_min_interval=0
KillWait=30
NodeName=localhost CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
CONF
export SLURM_CONF=$conf
slurmctld -f "$conf"
slurmd -f "$conf"
for _ in $(seq 150); do
  if sinfo -h -o %T 2>/dev/null | grep -q idle; then
    echo "slurm is up: SLURM_CONF=$conf"
    exit 0
  fi
  sleep 0.2
done
echo "slurm did not come up; logs in $dir/log" >&2
sinfo >&2 || true
exit 1
