# shellcheck shell=bash
# A single-node Slurm cluster on loopback, for tests (sourced): its slurm.conf, munge key, state,
# spool, logs and pid files all in a scratch folder, munged, slurmctld and slurmd children of the
# calling shell. Debian 12's slurm-wlm 22.05 and munge 0.5.15 (scripts/lib.sh installs them).
#   slurm_cluster_start DIR    starts it, waits for the node to be idle, exports SLURM_CONF
#   slurm_cluster_stop         stops the daemons it started (call it from an EXIT trap)
# Runs as root (CI), or as another user with SlurmUser and SlurmdUser set to that user.

SLURM_CLUSTER_PIDS=()

# A TCP port on 127.0.0.1 that nothing listens on (bash's /dev/tcp: a refused connection), taken
# below the kernel's ephemeral range: a port in that range can be any outgoing connection's local
# port a moment later (the browser and load tests run beside this one), and slurmd's bind fails.
slurm_cluster_free_port() {
  local port low=32768 high
  read -r low high </proc/sys/net/ipv4/ip_local_port_range 2>/dev/null || true
  ((low > 12000)) || low=32768
  for _ in $(seq 200); do
    port=$((10000 + RANDOM % (low - 10000)))
    if ! (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; then
      echo "$port"
      return 0
    fi
  done
  echo "no free port found" >&2
  return 1
}

# Starts the cluster; where a daemon could not bind its port (taken between the probe and the
# bind), stops what it started and tries again on other ports, three times at most.
slurm_cluster_start() {
  local dir=$1 attempt
  for attempt in 1 2 3; do
    slurm_cluster_try "$dir" && return 0
    grep -qs "Address already in use" "$dir"/log/*.log "$dir"/log/*.out || return 1
    echo "slurm_cluster_start: a port was taken; attempt $attempt of 3 failed, trying other ports" >&2
    slurm_cluster_stop
    rm -rf "${dir:?}"/{spool,state,log,run,munge.key,slurm.conf}
  done
  return 1
}

slurm_cluster_try() {
  local dir=$1 user host cpus ctld_port slurmd_port i
  mkdir -p "$dir"/{spool,state,log,run}
  dir=$(cd "$dir" && pwd)
  user=$(id -un)
  host=$(hostname -s)
  cpus=$(nproc)
  ctld_port=$(slurm_cluster_free_port)
  slurmd_port=$(slurm_cluster_free_port)
  while [[ $slurmd_port == "$ctld_port" ]]; do slurmd_port=$(slurm_cluster_free_port); done
  for cmd in munged slurmctld slurmd sbatch scontrol sinfo; do
    command -v "$cmd" >/dev/null || { echo "slurm_cluster_start: no $cmd (Debian packages slurm-wlm and munge)" >&2; return 1; }
  done

  # munge: its own key and socket; the Slurm config points at the socket.
  dd if=/dev/urandom of="$dir/munge.key" bs=1024 count=1 status=none
  chmod 400 "$dir/munge.key"
  chmod 700 "$dir/run"
  munged --foreground --force --socket="$dir/run/munge.socket" --key-file="$dir/munge.key" \
    --log-file="$dir/log/munged.log" --pid-file="$dir/run/munged.pid" --seed-file="$dir/run/munged.seed" \
    >"$dir/log/munged.out" 2>&1 &
  SLURM_CLUSTER_PIDS+=($!)
  for i in $(seq 100); do
    [[ -S $dir/run/munge.socket ]] && break
    kill -0 "${SLURM_CLUSTER_PIDS[-1]}" 2>/dev/null || { cat "$dir/log/munged.out" "$dir/log/munged.log" >&2; return 1; }
    sleep 0.1
  done

  # cred_expire: a requeued job waits this long before it starts again (default 120 s);
  # sched_interval, bf_interval: how often the scheduler looks (default 60 s and 30 s), so that
  # it starts the requeued task once it may, not a minute later.
  cat >"$dir/slurm.conf" <<CONF
ClusterName=substep-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
AuthInfo=socket=$dir/run/munge.socket,cred_expire=10
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
SchedulerParameters=sched_interval=1,bf_interval=1
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
ReturnToService=2
KillWait=5
MinJobAge=600
MailProg=/bin/true
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=1024 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
  export SLURM_CONF=$dir/slurm.conf
  slurmctld -D -i -f "$SLURM_CONF" >"$dir/log/slurmctld.out" 2>&1 &
  SLURM_CLUSTER_PIDS+=($!)
  slurmd -D -f "$SLURM_CONF" -N "$host" >"$dir/log/slurmd.out" 2>&1 &
  SLURM_CLUSTER_PIDS+=($!)
  for i in $(seq 300); do
    [[ $(sinfo -h -N -o %T 2>/dev/null) == idle ]] && return 0
    for pid in "${SLURM_CLUSTER_PIDS[@]}"; do
      kill -0 "$pid" 2>/dev/null || { slurm_cluster_logs "$dir" >&2; echo "a Slurm daemon (pid $pid) exited" >&2; return 1; }
    done
    sleep 0.1
  done
  slurm_cluster_logs "$dir" >&2
  echo "the node did not become idle in 30 s: $(sinfo -N 2>&1)" >&2
  return 1
}

slurm_cluster_logs() {
  local f
  for f in "$1"/log/*; do echo "--- $f"; tail -n 30 "$f"; done
}

# Stops the daemons in the reverse order of their start: SIGTERM, then SIGKILL after 10 s.
slurm_cluster_stop() {
  local pid i
  for ((i = ${#SLURM_CLUSTER_PIDS[@]} - 1; i >= 0; i--)); do
    pid=${SLURM_CLUSTER_PIDS[i]}
    kill -TERM "$pid" 2>/dev/null || continue
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  done
  SLURM_CLUSTER_PIDS=()
}
