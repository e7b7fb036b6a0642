#!/usr/bin/env bash
# Stop the local test cluster started by cluster/start.sh: cancel its jobs, then stop slurmd,
# slurmctld and munged by the pids recorded in $DASHPOT_CLUSTER_DIR/run. A pid is signalled
# only if it still is that daemon of this cluster directory; nothing else is ever killed.
# Safe to run when nothing is running. Keeps the configuration and logs (for reuse/debugging).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=cluster/env.sh
source "$here/env.sh"

# Cancel what is still queued or running, while the controller is there to do it.
if our_pid slurmctld >/dev/null && command -v squeue >/dev/null; then
    jobs=$(timeout 10 squeue -h -o '%i' 2>/dev/null || true)
    if [[ -n $jobs ]]; then
        log "cancelling jobs: $(tr '\n' ' ' <<<"$jobs")"
        # shellcheck disable=SC2086
        timeout 10 scancel $jobs 2>/dev/null || true
        for _ in $(seq 20); do
            [[ -z $(timeout 10 squeue -h -t RUNNING,COMPLETING -o '%i' 2>/dev/null || true) ]] && break
            sleep 0.5
        done
    fi
fi

stop_daemon() {
    local name=$1 pid
    if ! pid=$(our_pid "$name"); then
        rm -f "$RUN_DIR/$name.pid" "$RUN_DIR/$name.own.pid"
        return 0
    fi
    kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 40); do   # up to 20 s for a clean shutdown
        is_our_daemon "$pid" "$name" || break
        sleep 0.5
    done
    if is_our_daemon "$pid" "$name"; then
        log "$name (pid $pid) ignored SIGTERM; sending SIGKILL"
        kill -KILL "$pid" 2>/dev/null || true
        sleep 0.5
    fi
    rm -f "$RUN_DIR/$name.pid" "$RUN_DIR/$name.own.pid"
    log "stopped $name (pid $pid)"
}

stop_daemon slurmd
stop_daemon slurmctld
stop_daemon munged
