#!/usr/bin/env bash
# Tests the cluster recipes on a real Slurm scheduler. Uses the running cluster when `sinfo`
# reaches one (or SLURM_CONF names one); otherwise, as root, installs Slurm and MUNGE if
# missing (Debian packages) and brings up a single-node cluster on this host from a config in
# a temporary folder, stopped again at exit. Then:
#   1. a 4-task array over 8 frames of an animated asset: every frame byte-identical to a local
#      `hemi render --frames 0..8`;
#   2. one task cancelled with scancel mid-way, `hemi status` reporting the gap, the array
#      re-submitted: every frame present and identical, finished frames not rendered again;
#   3. a still split 4 ways by sample index, the partials merged: byte-identical to the single
#      render with the same samples per frame.
# Usage: scripts/slurm-test.sh [HEMI_BINARY]   (default target/release/hemi, built first)
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)

fail() {
    echo "slurm-test: FAIL: $*" >&2
    exit 1
}
log() { echo "slurm-test: $*"; }

hemi=${1:-$repo/target/release/hemi}
if [ $# -eq 0 ]; then
    cargo build --release --quiet
fi
[ -x "$hemi" ] || fail "no hemi binary at $hemi"
hemi=$(realpath "$hemi")
asset=$(realpath -m "$repo/../shared/assets/BoxAnimated/glTF-Binary/BoxAnimated.glb")
[ -f "$asset" ] || fail "asset missing: $asset"

work=$(mktemp -d /tmp/hemi-slurm.XXXXXX)
chmod 755 "$work"
pids=()
cleanup() {
    local rc=$?
    if [ -n "${own_conf:-}" ]; then
        scancel --user="$(id -un)" >/dev/null 2>&1 || true
        # Daemons this script started, by the process ids they were given.
        for pidfile in "$work/slurm/slurmd.pid" "$work/slurm/slurmctld.pid" "$work/munge/munged.pid"; do
            [ -f "$pidfile" ] && kill "$(cat "$pidfile")" 2>/dev/null || true
        done
        for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
        sleep 1
    fi
    if [ $rc -ne 0 ]; then
        log "daemon logs and job output kept in $work"
    else
        rm -rf "$work"
    fi
}
trap cleanup EXIT

# Waits up to $1 seconds for the command in the other arguments to succeed.
wait_for() {
    local limit=$1
    shift
    local deadline=$((SECONDS + limit))
    until "$@" >/dev/null 2>&1; do
        [ $SECONDS -lt $deadline ] || return 1
        sleep 0.2
    done
}

# ---------------------------------------------------------------- a scheduler to talk to
if [ -z "${SLURM_CONF:-}" ] && ! timeout 10 sinfo >/dev/null 2>&1; then
    [ "$(id -u)" -eq 0 ] || fail "no Slurm cluster reachable, and bringing one up needs root"
    if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null \
        || ! command -v sbatch >/dev/null; then
        log "installing slurmd slurmctld munge slurm-client"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq >/dev/null || fail "apt-get update failed"
        apt-get install -y -qq slurmd slurmctld munge slurm-client >/dev/null || fail "apt-get install failed"
    fi
    own_conf=1
    host=$(hostname -s)
    mkdir -p "$work/slurm/state" "$work/slurm/spool" "$work/munge"
    # MUNGE: a key of our own and a socket in the temporary folder.
    dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
    chmod 400 "$work/munge/munge.key"
    export MUNGE_SOCKET=$work/munge/munge.socket
    munged --force --key-file="$work/munge/munge.key" --socket="$MUNGE_SOCKET" \
        --pid-file="$work/munge/munged.pid" --log-file="$work/munge/munged.log" \
        --seed-file="$work/munge/munged.seed" || fail "munged did not start (see $work/munge/munged.log)"
    conf=$work/slurm/slurm.conf
    cat >"$conf" <<CONF
ClusterName=hemitest
SlurmctldHost=$host
AuthType=auth/munge
AuthInfo=socket=$MUNGE_SOCKET
CredType=cred/munge
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
SlurmUser=root
SlurmdUser=root
SlurmctldPort=${HEMI_SLURMCTLD_PORT:-16817}
SlurmdPort=${HEMI_SLURMD_PORT:-16818}
StateSaveLocation=$work/slurm/state
SlurmdSpoolDir=$work/slurm/spool
SlurmctldPidFile=$work/slurm/slurmctld.pid
SlurmdPidFile=$work/slurm/slurmd.pid
SlurmctldLogFile=$work/slurm/slurmctld.log
SlurmdLogFile=$work/slurm/slurmd.log
ReturnToService=2
MinJobAge=600
SchedulerParameters=sched_interval=1
NodeName=$host CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
    export SLURM_CONF=$conf
    slurmctld -f "$conf" -i || fail "slurmctld did not start (see $work/slurm/slurmctld.log)"
    slurmd -f "$conf" || fail "slurmd did not start (see $work/slurm/slurmd.log)"
    wait_for 60 bash -c "sinfo -h -o %T | grep -qx idle" \
        || fail "the node did not come up idle within 60 s: $(sinfo 2>&1 | tail -1) (see $work/slurm/)"
    log "single-node Slurm up on $host ($(nproc) CPUs), config $conf"
else
    log "using the running Slurm cluster ($(sinfo -h -o %P | head -1))"
fi

# Waits for every task of job $1 to leave the queue, at most $2 seconds.
wait_job() {
    local job=$1 limit=$2
    wait_for "$limit" bash -c "[ -z \"\$(squeue -h -j $job 2>/dev/null)\" ]" \
        || fail "job $job still queued or running after ${limit} s: $(squeue -j "$job" 2>&1 | tail -n +2 | head -3)"
}
# Fails unless every task of job $1 completed, printing the log of those that did not.
check_completed() {
    local job=$1 states
    states=$(scontrol -o show job "$job" 2>/dev/null | grep -o 'JobState=[A-Z_]*' | sort | uniq -c | tr '\n' ' ')
    if scontrol -o show job "$job" | grep -v 'JobState=COMPLETED' | grep -q .; then
        cat "$work"/logs/*"$job"* 2>/dev/null | tail -20 >&2 || true
        fail "job $job: not every task completed ($states)"
    fi
}
# Fails unless the files of frames 0..7 in $1 and $2 are byte-identical.
same_frames() {
    for f in 0 1 2 3 4 5 6 7; do
        name=$(printf 'f_%04d.png' "$f")
        [ -f "$2/$name" ] || fail "$3: frame $f missing ($2/$name)"
        cmp -s "$1/$name" "$2/$name" || fail "$3: frame $f differs from the local render"
    done
}

mkdir -p "$work/logs"
chmod 777 "$work/logs"
export HEMI=$hemi
opts=(--frames 0..8 --fps 4 --size 48x32 --spp 8)
submit() { sbatch --parsable --chdir="$work" --output="$work/logs/%x-%A_%a.out" "$@"; }

# ---------------------------------------------------------------- 1. a frame array
t0=$SECONDS
"$hemi" render "$asset" "${opts[@]}" --out "$work/local/f_{:04}.png" 2>/dev/null || fail "local render failed"
job=$(submit --array=0-3 deploy/slurm/hemi-array.sbatch "$asset" "$work/array/f_{:04}.png" "${opts[@]}") \
    || fail "sbatch refused the array"
wait_job "$job" 120
check_completed "$job"
same_frames "$work/local" "$work/array" "array"
log "1. 4-task array over 8 frames: identical to the local render ($((SECONDS - t0)) s)"

# ---------------------------------------------------------------- 2. cancel, then re-submit
t0=$SECONDS
slow=(--frames 0..8 --fps 4 --size 48x32 --spp "${HEMI_SLURM_TEST_SLOW_SPP:-10000}")
"$hemi" render "$asset" "${slow[@]}" --out "$work/local-slow/f_{:04}.png" 2>/dev/null || fail "local render failed"
job=$(submit --array=0-3 deploy/slurm/hemi-array.sbatch "$asset" "$work/cancel/f_{:04}.png" "${slow[@]}") \
    || fail "sbatch refused the array"
# Task 0 renders frames 0 and 4: cancel it once frame 0 is written, while it renders frame 4.
wait_for 120 test -f "$work/cancel/f_0000.png" || fail "task 0 wrote no frame within 120 s"
scancel "${job}_0" || fail "scancel ${job}_0 failed"
wait_job "$job" 180
[ -f "$work/cancel/f_0004.png" ] \
    && fail "task 0 finished frame 4 before it was cancelled: raise HEMI_SLURM_TEST_SLOW_SPP"
if "$hemi" status "$work/cancel/f_{:04}.png" --frames 0..8 >"$work/status-before.txt" 2>&1; then
    fail "hemi status exited 0 with frame 4 missing"
fi
grep -Eq '^ +4  (missing|partial) ' "$work/status-before.txt" || fail "hemi status did not report frame 4: $(cat "$work/status-before.txt")"
declare -A before
for f in 0 1 2 3 5 6 7; do
    before[$f]=$(stat -c %Y.%y "$work/cancel/$(printf 'f_%04d.png' "$f")") || fail "frame $f missing after the cancel"
done
job2=$(submit --array=0-3 deploy/slurm/hemi-array.sbatch "$asset" "$work/cancel/f_{:04}.png" "${slow[@]}") \
    || fail "sbatch refused the re-submitted array"
wait_job "$job2" 180
check_completed "$job2"
same_frames "$work/local-slow" "$work/cancel" "re-submitted array"
for f in 0 1 2 3 5 6 7; do
    now=$(stat -c %Y.%y "$work/cancel/$(printf 'f_%04d.png' "$f")")
    [ "$now" = "${before[$f]}" ] || fail "frame $f was rendered again by the re-submitted array"
done
skipped=$(cat "$work"/logs/*"$job2"_*.out | grep -c 'exists, skipped' || true)
[ "$skipped" -eq 7 ] || fail "the re-submitted array skipped $skipped frames, not 7"
"$hemi" status "$work/cancel/f_{:04}.png" --frames 0..8 >"$work/status-after.txt" \
    || fail "hemi status exited non-zero with every frame done: $(tail -1 "$work/status-after.txt")"
log "2. task cancelled mid-way, array re-submitted: 7 frames kept, frame 4 rendered, all identical ($((SECONDS - t0)) s)"

# ---------------------------------------------------------------- 3. a split-sample still
t0=$SECONDS
still=(--size 64x48 --spp 64 --time 0.5)
"$hemi" render "$asset" "${still[@]}" --spf 16 --out "$work/still-local.png" 2>/dev/null || fail "local render failed"
job=$(submit --array=0-3 deploy/slurm/hemi-split.sbatch "$asset" "$work/parts/part_{}.exr" "${still[@]}") \
    || fail "sbatch refused the split array"
wait_job "$job" 120
check_completed "$job"
"$hemi" merge "$work"/parts/part_*.exr --out "$work/still-merged.png" || fail "hemi merge failed"
cmp -s "$work/still-local.png" "$work/still-merged.png" || fail "the merged still differs from the single render"
log "3. still split 4 ways by sample index, merged: identical to the single render ($((SECONDS - t0)) s)"
log "all passed"
