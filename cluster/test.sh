#!/usr/bin/env bash
# make cluster-test: run the workflow locally and through SLURM, and check the results agree.
#
#  1. SLURM and munge: installed from Debian's packages if missing (root only); where that is
#     impossible (not root, no apt-get, apt fails, no network) the test is SKIPPED, exit 0.
#  2. A single-node cluster on localhost (cluster/start.sh), reused if one is running.
#  3. Two copies of the working tree (tracked files plus untracked, not ignored ones, with
#     their uncommitted edits) in a temp dir, each with a `shared` symlink beside it to the
#     real ../shared; the default scenes run in one with `--profile workflow/profiles/default`
#     (each scene its own chunk: the automatic chunk size of a handful of scenes) and in the
#     other with `--profile workflow/profiles/slurm` and chunks of 3 scenes (chunk_size=3),
#     sent as SLURM jobs by the profile's job groups: the comparison checks the SLURM run and
#     the chunking at once (a scene's results must not depend on its chunk).
#  4. cluster/compare_results.py compares the two results/ trees.
#  5. The temp dir is removed, and the cluster is stopped if this run started it.
#
# Environment knobs: CLUSTER_TEST_TIMEOUT (seconds per workflow run, default 1200),
# CLUSTER_TEST_KEEP=1 (keep the temp dir), CLUSTER_TEST_KEEP_CLUSTER=1 (leave the cluster
# running), CLUSTER_TEST_BEFORE_COMPARE (a shell command run in the temp dir just before the
# comparison, with LOCAL_RESULTS and SLURM_RESULTS set; for checking the checker),
# DASHPOT_CLUSTER_DIR and ports: see cluster/env.sh.
set -euo pipefail
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
here="$repo/cluster"
# shellcheck source=cluster/env.sh
source "$here/env.sh"
venv_bin="$repo/.venv/bin"
run_timeout=${CLUSTER_TEST_TIMEOUT:-1200}
project=$(basename "$repo")
t0=$SECONDS

say() { printf 'cluster-test: %s\n' "$*"; }
skip() {
    say "SKIPPED: $*"
    exit 0
}

# --- 1. SLURM installed? -----------------------------------------------------------------------
missing=$(missing_binaries)
if [[ -n $missing ]]; then
    [[ $(id -u) -eq 0 ]] || skip "SLURM/munge are not installed (missing: $missing) and installing them needs root"
    command -v apt-get >/dev/null || skip "SLURM/munge are not installed (missing: $missing) and there is no apt-get"
    say "installing SLURM and munge from Debian's packages (missing: $missing)"
    apt_log=$(mktemp)
    packages=(slurmctld slurmd slurm-client munge)
    apt_install() {
        DEBIAN_FRONTEND=noninteractive timeout 900 \
            apt-get install -y --no-install-recommends "${packages[@]}" >>"$apt_log" 2>&1
    }
    # A fresh machine's package lists may be missing or stale: update once, then retry.
    if ! apt_install && ! { timeout 300 apt-get update >>"$apt_log" 2>&1 && apt_install; }; then
        tail -n 5 "$apt_log" | sed 's/^/    apt: /'
        rm -f "$apt_log"
        skip "SLURM could not be installed with apt-get (no network or no package source?)"
    fi
    rm -f "$apt_log"
    missing=$(missing_binaries)
    [[ -z $missing ]] || skip "SLURM installed, but still missing: $missing"
fi
[[ $(id -u) -eq 0 ]] || skip "the local SLURM test cluster needs root (slurmd starts jobs as their user)"
[[ -x $venv_bin/snakemake ]] || { say "no $venv_bin/snakemake: run 'make install' first"; exit 1; }

# One test at a time per cluster directory: a second run waits here instead of restarting
# or stopping the cluster under the first one's jobs.
exec 9>>"$CLUSTER_DIR.lock"
if ! flock -n 9; then
    say "waiting for another cluster-test using $CLUSTER_DIR"
    flock -w "$((2 * run_timeout + 300))" 9 || { say "gave up waiting for $CLUSTER_DIR.lock"; exit 1; }
fi

# --- cleanup, whatever happens -----------------------------------------------------------------
work=""
cluster_state=""
child=""
interrupted=0
cleanup() {
    local status=$?
    trap - EXIT INT TERM
    if [[ -n $child ]] && kill -0 "$child" 2>/dev/null; then
        kill -INT "$child" 2>/dev/null || true
        wait "$child" 2>/dev/null || true
    fi
    if [[ -n $work && -d $work ]]; then
        if [[ ${CLUSTER_TEST_KEEP:-0} == 1 ]]; then
            say "kept the run directories in $work"
        else
            rm -rf "$work"
        fi
    fi
    if [[ $cluster_state == started && ${CLUSTER_TEST_KEEP_CLUSTER:-0} != 1 ]]; then
        "$here/stop.sh" || status=1
    elif [[ -n $cluster_state ]]; then
        say "the cluster in $CLUSTER_DIR keeps running; stop it with cluster/stop.sh"
    fi
    exit "$status"
}
on_signal() {  # forward to a running workflow (it cancels its SLURM jobs), else stop now
    interrupted=1
    if [[ -n $child ]]; then
        kill -INT "$child" 2>/dev/null || true
    else
        say "interrupted"
        exit 130
    fi
}
trap cleanup EXIT
trap on_signal INT TERM

# --- 2. the cluster ----------------------------------------------------------------------------
# Its partition is the one the slurm profile submits to, so the profile is tested unchanged.
partition=$("$venv_bin/python" - "$repo/workflow/profiles/slurm/config.yaml" <<'EOF'
import sys
import yaml

with open(sys.argv[1]) as f:
    resources = (yaml.safe_load(f) or {}).get("default-resources") or {}
if isinstance(resources, list):  # the "key=value" list form
    resources = dict(item.split("=", 1) for item in resources)
print(str(resources.get("slurm_partition", "")).strip("'\" "))
EOF
)
export DASHPOT_CLUSTER_PARTITION=${partition:-$CLUSTER_PARTITION}
cluster_state=$("$here/start.sh" 9>&-)  # the daemons must not inherit the lock

# --- 3. two copies of the working tree ---------------------------------------------------------
work=$(mktemp -d "${TMPDIR:-/tmp}/dashpot-cluster-test.XXXXXX")
copy_tree() {  # copy_tree DEST: the project's files as the working tree has them
    local dest=$1
    mkdir -p "$dest"
    if command -v git >/dev/null && git -C "$repo" rev-parse --is-inside-work-tree >/dev/null 2>&1; then
        (
            cd "$repo"
            git ls-files -z --cached --others --exclude-standard |
                while IFS= read -r -d '' f; do
                    if [[ -e $f || -L $f ]]; then printf '%s\0' "$f"; fi  # skip deleted files
                done |
                xargs -0 -r cp -P --parents -t "$dest"
        )
    else  # not a git checkout: everything but the environment and previous outputs
        tar -C "$repo" --exclude=./.git --exclude=./.venv --exclude=./results \
            --exclude=./.snakemake -cf - . | tar -C "$dest" -xf -
    fi
    # The configuration reaches real recordings as ../shared/data relative to the project.
    if [[ -d $repo/../shared ]]; then
        ln -s "$(cd "$repo/../shared" && pwd -P)" "$(dirname "$dest")/shared"
    fi
}
copy_tree "$work/local/$project"
copy_tree "$work/slurm/$project"

# --- 4. the two runs ---------------------------------------------------------------------------
# Jobs (local or SLURM, which exports the submitting environment) use the project's .venv
# and the copy's own sources; $CLUSTER_DIR/bin holds the cluster's srun (see start.sh).
run_workflow() {  # run_workflow NAME SNAKEMAKE-ARGS...
    local name=$1 dir="$work/$1/$project" log="$work/$1.log" start=$SECONDS status=0
    shift
    say "$name run: snakemake $*"
    (
        cd "$dir"
        export PATH="$CLUSTER_DIR/bin:$venv_bin:$PATH" PYTHONPATH="$dir/src${PYTHONPATH:+:$PYTHONPATH}"
        exec timeout --signal=INT --kill-after=60 "$run_timeout" "$venv_bin/snakemake" "$@"
    ) >"$log" 2>&1 &
    child=$!
    # `wait` returns early when a signal arrives; keep waiting until the run has ended.
    while :; do
        status=0
        wait "$child" || status=$?
        kill -0 "$child" 2>/dev/null || break
    done
    child=""
    if ((interrupted)); then
        say "interrupted"
        exit 130
    fi
    if ((status != 0)); then
        if ((status == 124 || status == 137)); then  # timeout's INT (then KILL) after the limit
            say "$name run timed out after ${run_timeout}s (hanging status checks?)"
        else
            say "$name run failed (exit status $status)"
        fi
        say "---- last lines of the $name run's log"
        tail -n 40 "$log"
        local f
        for f in $(find "$dir/.snakemake/slurm_logs" -name "*.log" 2>/dev/null | sort); do
            [[ -f $f ]] || continue
            say "---- SLURM job log ${f#"$dir"/}"
            tail -n 20 "$f"
        done
        if [[ $name == slurm ]]; then
            say "---- cluster: $(sinfo -h -o '%P %T %N' 2>&1 | tr '\n' ' ')"
            tail -n 10 "$LOG_DIR/slurmctld.log" 2>/dev/null || true
        fi
        exit 1
    fi
    say "$name run finished in $((SECONDS - start)) s"
}
run_workflow local --profile workflow/profiles/default
# Without slurmdbd `sacct` knows no jobs: status comes from squeue (slurm.conf keeps finished
# jobs MinJobAge=300 s), first checked 2 s after submission.
run_workflow slurm --profile workflow/profiles/slurm --config chunk_size=3 \
    --slurm-status-command squeue --slurm-init-seconds-before-status-checks 2
slurm_jobs=$(grep -c "has been submitted with SLURM jobid" "$work/slurm.log" || true)
say "slurm run: $slurm_jobs SLURM job(s) submitted"

# --- 5. compare --------------------------------------------------------------------------------
export LOCAL_RESULTS="$work/local/$project/results" SLURM_RESULTS="$work/slurm/$project/results"
if [[ -n ${CLUSTER_TEST_BEFORE_COMPARE:-} ]]; then
    say "running CLUSTER_TEST_BEFORE_COMPARE: $CLUSTER_TEST_BEFORE_COMPARE"
    (cd "$work" && bash -c "$CLUSTER_TEST_BEFORE_COMPARE")
fi
if ! "$venv_bin/python" "$here/compare_results.py" "$LOCAL_RESULTS" "$SLURM_RESULTS"; then
    say "FAILED: the SLURM run's results differ from the local run's"
    exit 1
fi
say "passed in $((SECONDS - t0)) s"
