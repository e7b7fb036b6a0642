# shellcheck shell=bash disable=SC2034
# Shared settings of the local test cluster; sourced by start.sh, stop.sh and test.sh.
# Everything the cluster writes (slurm.conf, munge key and socket, state, spool, logs, pid files)
# lives under CLUSTER_DIR, never in /etc or /var.

CLUSTER_DIR=${DASHPOT_CLUSTER_DIR:-/tmp/dashpot-slurm}
SLURMCTLD_PORT=${DASHPOT_SLURMCTLD_PORT:-16817}
SLURMD_PORT=${DASHPOT_SLURMD_PORT:-16818}
# Partition of the test cluster; test.sh names it after the slurm profile's slurm_partition.
CLUSTER_PARTITION=${DASHPOT_CLUSTER_PARTITION:-main}

export SLURM_CONF="$CLUSTER_DIR/slurm.conf"
MUNGE_DIR="$CLUSTER_DIR/munge"
MUNGE_SOCKET="$MUNGE_DIR/munge.socket.2"
RUN_DIR="$CLUSTER_DIR/run"
LOG_DIR="$CLUSTER_DIR/log"

# Binaries the cluster needs (client commands are what the snakemake plugin calls).
CLUSTER_BINARIES=(munged mungekey munge unmunge slurmctld slurmd sbatch squeue sinfo scontrol scancel srun)

# The slurm and munge daemons live in /usr/sbin, which a non-login PATH may lack.
case ":$PATH:" in *:/usr/sbin:*) ;; *) PATH="$PATH:/usr/sbin" ;; esac

log() { printf '[cluster] %s\n' "$*" >&2; }

missing_binaries() {  # prints the missing ones, space separated; nothing if all are there
    local b absent=()
    for b in "${CLUSTER_BINARIES[@]}"; do
        command -v "$b" >/dev/null 2>&1 || absent+=("$b")
    done
    echo "${absent[*]}"
}

# Print the pid recorded in RUN_DIR/NAME.pid if that process is alive AND is our daemon
# (its command name is NAME and its command line mentions CLUSTER_DIR), so a stale pid
# file whose number was reused by an unrelated process is never trusted or killed.
our_pid() {
    local name=$1 file="$RUN_DIR/$1.pid" pid
    [[ -r $file ]] || return 1
    pid=$(tr -dc '0-9' <"$file")
    is_our_daemon "$pid" "$name" || return 1
    printf '%s\n' "$pid"
}

# True if process PID is alive and is daemon NAME of this cluster directory.
is_our_daemon() {
    local pid=$1 name=$2
    [[ -n $pid && -r /proc/$pid/comm ]] || return 1
    [[ $(cat "/proc/$pid/comm" 2>/dev/null) == "$name" ]] || return 1
    tr '\0' ' ' <"/proc/$pid/cmdline" 2>/dev/null | grep -qF -- "$CLUSTER_DIR"
}
