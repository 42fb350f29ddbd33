#!/usr/bin/env bash
# A one-node SLURM cluster on this machine, for tests/test_slurm.py.
#
#   cluster.sh install      install munge and SLURM from Debian's packages
#                           (slurmctld, slurmd, slurm-client, munge); needs root
#   cluster.sh start DIR    write DIR/slurm.conf, start munged (unless one
#                           runs), slurmctld and slurmd with their files under
#                           DIR, wait until sinfo shows the node idle
#   cluster.sh stop DIR     cancel the cluster's jobs, stop the daemons that
#                           `start DIR` started
#
# The node is this machine (`hostname -s`) with 2 CPUs, on the loopback
# address and free ports; no systemd, no cgroups (proctrack/linuxproc,
# task/none), no accounting database (job states come from slurmctld, and
# MinJobAge keeps finished jobs visible to squeue for 5 minutes).
#
# Clients (sinfo, sbatch, snakemake --executor slurm) find the cluster through
# SLURM_CONF=DIR/slurm.conf. Inside a job the executor's srun runs without it
# (the slurm-jobstep plugin drops every inherited SLURM_ variable), so slurmd
# runs "configless", as on many clusters: it fetches slurm.conf from slurmctld
# and links /run/slurm/conf to its copy, where srun looks; `stop` removes the
# link. Until it has the configuration slurmd reaches munge only at its default
# socket (/run/munge), so munged runs there: one already running is used as it
# is, otherwise one is started with a new key under DIR. Outside DIR only these
# two places in /run are used; an existing SLURM configuration on the machine
# (/etc/slurm/slurm.conf, /run/slurm/conf) stops `start` with a message.
set -euo pipefail

PACKAGES=(slurmctld slurmd slurm-client munge)
DAEMONS=(slurmd slurmctld munged)   # stop order

die() { echo "cluster.sh: $*" >&2; exit 1; }

install() {
    if command -v slurmctld >/dev/null && command -v slurmd >/dev/null \
        && command -v sbatch >/dev/null && command -v munged >/dev/null; then
        echo "cluster.sh: SLURM and munge already installed"
        return
    fi
    [[ $(id -u) == 0 ]] || die "installing SLURM needs root"
    command -v apt-get >/dev/null || die "installing SLURM needs apt-get"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${PACKAGES[@]}"
}

free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

write_conf() {
    local dir=$1 node=$2 mem_mb=$3 ctld_port=$4 slurmd_port=$5
    cat > "$dir/slurm.conf" <<CONF
# Written by tests/slurm/cluster.sh: one node, everything under $dir.
ClusterName=polypile-test
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
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
# Containers have neither systemd nor writable cgroups.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SlurmctldParameters=enable_configless
SwitchType=switch/none
# CPUs and memory are scheduled, so --cpus-per-task and --mem are honoured.
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
SchedulerType=sched/backfill
# A node that was down comes back by itself; the configured size is trusted.
ReturnToService=2
SlurmdParameters=config_overrides
# Finished jobs stay visible to squeue (the executor's status query) 5 min.
MinJobAge=300
# scancel: SIGTERM, then SIGKILL 5 s later.
KillWait=5
InactiveLimit=0
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=$node NodeAddr=127.0.0.1 CPUs=2 RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
}

start() {
    local dir=$1
    [[ $(id -u) == 0 ]] || die "starting slurmd needs root"
    # srun in a job would find an existing configuration before ours.
    [[ ! -e /etc/slurm/slurm.conf ]] \
        || die "/etc/slurm/slurm.conf exists: this machine already has a SLURM configuration"
    [[ ! -e /run/slurm/conf ]] \
        || die "/run/slurm/conf exists: another slurmd runs configless on this machine"
    mkdir -p "$dir"
    dir=$(cd "$dir" && pwd)
    mkdir -p "$dir"/{munge,state,spool,log}
    chmod 700 "$dir/munge"
    local node mem_mb ctld_port
    node=$(hostname -s)
    # RealMemory a bit below what is free, so that slurmd does not drain the node.
    mem_mb=$(awk '/^MemAvailable:/ {print int($2 / 1024 * 0.8)}' /proc/meminfo)
    ctld_port=$(free_port)
    write_conf "$dir" "$node" "$mem_mb" "$ctld_port" "$(free_port)"
    export SLURM_CONF=$dir/slurm.conf

    if munge --no-input >/dev/null 2>&1; then
        echo "cluster.sh: using the munged already running"
    else
        dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
        chmod 400 "$dir/munge/munge.key"
        mkdir -p /run/munge
        munged --force --key-file="$dir/munge/munge.key" --pid-file="$dir/munged.pid" \
            --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed"
    fi
    slurmctld -f "$SLURM_CONF"
    slurmd --conf-server "127.0.0.1:$ctld_port" -N "$node"

    local state=""
    for _ in $(seq 60); do
        state=$(sinfo --noheader --nodes="$node" --format=%T 2>/dev/null || true)
        if [[ $state == idle ]]; then
            echo "cluster.sh: node $node idle (SLURM_CONF=$SLURM_CONF)"
            return
        fi
        sleep 1
    done
    echo "cluster.sh: node $node not idle after 60 s (state: '${state}'); logs:" >&2
    tail -n 20 "$dir"/log/*.log >&2 || true
    exit 1
}

stop() {
    local dir=$1 pidfile pid
    # Every job of this cluster is the test's: cancel what still runs, so
    # that no job step outlives slurmd.
    if [[ -f $dir/slurmctld.pid ]]; then
        SLURM_CONF=$dir/slurm.conf scancel --user="$(id -un)" 2>/dev/null || true
        for _ in $(seq 20); do
            [[ -z $(SLURM_CONF=$dir/slurm.conf squeue --noheader --states=RUNNING,COMPLETING 2>/dev/null) ]] && break
            sleep 0.5
        done
    fi
    for daemon in "${DAEMONS[@]}"; do
        pidfile=$dir/$daemon.pid
        [[ -f $pidfile ]] || continue
        pid=$(<"$pidfile")
        if kill "$pid" 2>/dev/null; then
            for _ in $(seq 30); do
                kill -0 "$pid" 2>/dev/null || break
                sleep 0.5
            done
            if kill -0 "$pid" 2>/dev/null; then
                kill -9 "$pid"
            fi
        fi
        rm -f "$pidfile"
    done
    if [[ $(readlink /run/slurm/conf || true) == "$dir"/* ]]; then
        rm /run/slurm/conf
    fi
    echo "cluster.sh: stopped the daemons of $dir"
}

case ${1:-} in
    install) install ;;
    start) [[ $# == 2 ]] || die "usage: cluster.sh start DIR"; start "$2" ;;
    stop) [[ $# == 2 ]] || die "usage: cluster.sh stop DIR"; stop "$2" ;;
    *) die "usage: cluster.sh install | start DIR | stop DIR" ;;
esac
