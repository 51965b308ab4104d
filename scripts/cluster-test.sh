#!/bin/bash
# The cluster test (docs/cluster.md), run by .ci/run after `cargo test`:
#   bash scripts/cluster-test.sh
# Runs a small experiment unsharded (the reference), then
#   slurm:    scripts/slurm-sweep.sh as an array job over shards on a one-node cluster
#             (scripts/local-slurm.sh), merged and compared with the reference; then again,
#             cancelling one array task mid-run and requeueing it;
#   parallel: scripts/parallel-sweep.sh over shards, compared the same way; then again,
#             killing one shard's vizsim mid-run (SIGKILL) and re-running the script.
# Each comparison: the merged results.jsonl has the same bytes as the merged reference, and
# the shards' own results.jsonl hold every run exactly once (nothing lost, nothing duplicated).
# Where Slurm or GNU parallel cannot be installed or started, that part prints
# "skipped: <why>" and the script still exits 0; a failure exits 1.
# Environment: VIZSIM (the binary; default: the target/debug/vizsim that `cargo test` already
# made, brought up to date with `cargo test --no-run`), CLUSTER_TEST_SHARDS (default 4),
# CLUSTER_TEST_KEEP=1 keeps the work folder.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
T0=$SECONDS
N=${CLUSTER_TEST_SHARDS:-4}
VICTIM=1 # the shard that is killed

PASSED=0
FAILED=0
SKIPPED=0
say() { echo "cluster-test: $*"; }
fail() { say "FAILED: $*"; FAILED=$((FAILED + 1)); return 1; }

if [ -z "${VIZSIM:-}" ]; then
    # the binary `cargo test` builds (test profile, target/debug): after it, this is a no-op;
    # `cargo build` would rebuild everything with the dev profile's settings
    cargo test -q --no-run --test cli
    TARGET=$(cargo metadata -q --format-version 1 --no-deps |
        sed -n 's/.*"target_directory":"\([^"]*\)".*/\1/p')
    VIZSIM=$TARGET/debug/vizsim
fi
[ -x "$VIZSIM" ] || { say "FAILED: no vizsim binary at $VIZSIM"; exit 1; }
export VIZSIM

WORK=$(mktemp -d /tmp/vizsim-cluster-test.XXXXXX)
export VIZSIM_SLURM_DIR=$WORK/slurm
SLURM_UP=0
cleanup() {
    if [ "$SLURM_UP" = 1 ]; then bash "$ROOT/scripts/local-slurm.sh" down >/dev/null 2>&1 || true; fi
    if [ "${CLUSTER_TEST_KEEP:-0}" = 1 ]; then say "work folder kept: $WORK"; else rm -rf "$WORK"; fi
}
trap cleanup EXIT
cd "$WORK"

# 48 runs, each 0.01-0.3 s on one thread: a shard runs about 2 s, long enough to be killed mid-run
cat >exp.toml <<'EOF'
name = "ci-cluster"
datasets = ["phantom:metaballs:48", "phantom:shells:48"]
tf = ["class"]
modes = ["none", "ert+leap4"]
models = ["step", "cycle"]
[frames]
orbit = 72
select = [0, 3, 6, 9, 12, 15]
size = "128x128"
EOF

"$VIZSIM" sweep exp.toml --out ref --quiet >ref.log 2>&1
"$VIZSIM" merge ref --out ref-merged >/dev/null
RUNS=$(wc -l <ref-merged/results.jsonl)
say "reference: $RUNS runs unsharded ($((SECONDS - T0)) s so far)"

keys() { cat "$@" | grep -o '"key":"[0-9a-f]*"'; }

# check NAME DIR: DIR/shard-* hold every run once and DIR/merged equals the reference
check() {
    local name=$1 dir=$2 total dups
    total=$(keys "$dir"/shard-*/results.jsonl | wc -l)
    dups=$(keys "$dir"/shard-*/results.jsonl | sort | uniq -d | wc -l)
    [ "$total" -eq "$RUNS" ] && [ "$dups" -eq 0 ] ||
        fail "$name: the shards hold $total result lines for $RUNS runs ($dups keys twice)" || return 1
    cmp -s "$dir/merged/results.jsonl" ref-merged/results.jsonl ||
        fail "$name: merged results differ from the unsharded run (diff $dir/merged/results.jsonl ref-merged/results.jsonl)" || return 1
    return 0
}

lines() { if [ -f "$1" ]; then wc -l <"$1"; else echo 0; fi; }

# ---------------------------------------------------------------- Slurm
slurm_wait() { # JOB: until no task of the job is pending or running
    local _
    for _ in $(seq 600); do
        [ -z "$(squeue -h -j "$1" 2>/dev/null)" ] && return 0
        sleep 0.2
    done
    fail "slurm: job $1 still queued after 120 s: $(squeue -h -j "$1")"
}
slurm_state() { scontrol show job "$1" | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p' | head -n 1; }
slurm_all_completed() { # JOB
    local bad
    bad=$(scontrol show job "$1" | grep -o 'JobState=[A-Z_]*' | grep -v COMPLETED || true)
    [ -z "$bad" ] || fail "slurm: job $1 has tasks not COMPLETED: $(echo $bad)"
}
slurm_submit() { # OUT: submits the array, prints the job id
    mkdir -p "$1"
    # -c 1: the script asks for 4 CPUs per task, more than this node may have (see docs/cluster.md)
    sbatch --parsable -c 1 --array=0-$((N - 1)) --output="$1/slurm-%A_%a.log" \
        "$ROOT/scripts/slurm-sweep.sh" exp.toml "$1" "$N"
}

slurm_clean() {
    local t=$SECONDS job
    job=$(slurm_submit s-clean) || { fail "slurm: sbatch failed"; return 1; }
    slurm_wait "$job" || return 1
    slurm_all_completed "$job" || return 1
    "$VIZSIM" merge s-clean/shard-* --out s-clean/merged >/dev/null
    check "slurm" s-clean || return 1
    say "ok: slurm: array job $job, $N tasks, $RUNS runs merged = unsharded ($((SECONDS - t)) s)"
}

slurm_kill() {
    local t=$SECONDS job task shard_runs at_kill after_kill state _
    shard_runs=$(wc -l <s-clean/shard-$VICTIM/results.jsonl)
    job=$(slurm_submit s-kill) || { fail "slurm: sbatch failed"; return 1; }
    task=${job}_$VICTIM
    for _ in $(seq 3000); do
        [ "$(lines s-kill/shard-$VICTIM/results.jsonl)" -ge 1 ] && break
        sleep 0.02
    done
    at_kill=$(lines s-kill/shard-$VICTIM/results.jsonl)
    scancel "$task"
    for _ in $(seq 100); do
        state=$(slurm_state "$task")
        [ "$state" = CANCELLED ] && break
        sleep 0.1
    done
    slurm_wait "$job" || return 1
    after_kill=$(lines s-kill/shard-$VICTIM/results.jsonl)
    [ "$state" = CANCELLED ] || fail "slurm: task $task is $state after scancel, not CANCELLED" || return 1
    [ "$at_kill" -ge 1 ] && [ "$after_kill" -lt "$shard_runs" ] ||
        fail "slurm: task $task was not cancelled mid-run ($after_kill of $shard_runs runs done)" || return 1
    # requeue it; a requeued job is held back (BeginTime) for two minutes unless told otherwise
    scontrol requeue "$task"
    scontrol update JobId="$task" StartTime=now
    slurm_wait "$job" || return 1
    slurm_all_completed "$job" || return 1
    grep -q "; $after_kill already done" s-kill/slurm-${job}_$VICTIM.log ||
        fail "slurm: the requeued task did not resume ($(head -n 1 s-kill/slurm-${job}_$VICTIM.log))" || return 1
    "$VIZSIM" merge s-kill/shard-* --out s-kill/merged >/dev/null
    check "slurm kill+requeue" s-kill || return 1
    say "ok: slurm: task $task cancelled with $after_kill of $shard_runs runs done, requeued, resumed; $RUNS runs merged = unsharded, none lost or twice ($((SECONDS - t)) s)"
}

set +e
bash "$ROOT/scripts/local-slurm.sh" up 2>slurm-up.log
rc=$?
set -e
if [ $rc -eq 0 ]; then
    SLURM_UP=1
    sed 's/^/cluster-test: /' slurm-up.log
    export SLURM_CONF=$VIZSIM_SLURM_DIR/slurm.conf
    if slurm_clean; then PASSED=$((PASSED + 1)); fi
    if slurm_kill; then PASSED=$((PASSED + 1)); fi
    bash "$ROOT/scripts/local-slurm.sh" down 2>/dev/null
    SLURM_UP=0
elif [ $rc -eq 77 ]; then
    say "skipped: slurm: $(grep 'cannot run Slurm here' slurm-up.log | tail -n 1)"
    SKIPPED=$((SKIPPED + 2))
else
    cat slurm-up.log
    fail "slurm: scripts/local-slurm.sh up exited $rc" || true
fi

# ---------------------------------------------------------------- GNU parallel
parallel_kill() {
    local t=$SECONDS pid shard_runs at_kill after_kill vpid p _ rc2
    shard_runs=$(wc -l <p-clean/shard-$VICTIM/results.jsonl)
    bash "$ROOT/scripts/parallel-sweep.sh" exp.toml p-kill "$N" >p-kill.log 2>&1 &
    pid=$!
    for _ in $(seq 3000); do
        [ "$(lines p-kill/shard-$VICTIM/results.jsonl)" -ge 1 ] && break
        sleep 0.02
    done
    at_kill=$(lines p-kill/shard-$VICTIM/results.jsonl)
    # the vizsim of the victim shard: its command line names the shard's folder
    # (not a shell wrapping it: a killed wrapper would leave vizsim running)
    vpid=""
    for p in $(pgrep -f -- "--out p-kill/shard-$VICTIM --shard" || true); do
        [ "$(cat /proc/"$p"/comm 2>/dev/null)" = vizsim ] && vpid="$vpid $p"
    done
    [ -n "$vpid" ] || { wait "$pid" || true; fail "parallel: no running vizsim for shard $VICTIM"; return 1; }
    kill -KILL $vpid
    set +e
    wait "$pid"
    rc2=$?
    set -e
    after_kill=$(lines p-kill/shard-$VICTIM/results.jsonl)
    [ "$rc2" -ne 0 ] || fail "parallel: the script exited 0 although a shard was killed" || return 1
    [ "$at_kill" -ge 1 ] && [ "$after_kill" -lt "$shard_runs" ] ||
        fail "parallel: shard $VICTIM was not killed mid-run ($after_kill of $shard_runs runs done)" || return 1
    [ ! -e p-kill/merged ] || fail "parallel: merged although a shard failed" || return 1
    bash "$ROOT/scripts/parallel-sweep.sh" exp.toml p-kill "$N" >p-rerun.log 2>&1 ||
        { cat p-rerun.log; fail "parallel: the re-run failed"; return 1; }
    grep -q "; $after_kill already done in p-kill/shard-$VICTIM)" p-rerun.log ||
        fail "parallel: the re-run did not resume shard $VICTIM" || return 1
    check "parallel kill+rerun" p-kill || return 1
    say "ok: parallel: shard $VICTIM's vizsim killed (SIGKILL) with $after_kill of $shard_runs runs done, script exited $rc2; re-run resumed; $RUNS runs merged = unsharded, none lost or twice ($((SECONDS - t)) s)"
}

parallel_ok=1
if ! command -v parallel >/dev/null; then
    if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null &&
        { DEBIAN_FRONTEND=noninteractive apt-get -y -q install --no-install-recommends parallel >apt-parallel.log 2>&1 ||
            { apt-get -q update >>apt-parallel.log 2>&1 &&
                DEBIAN_FRONTEND=noninteractive apt-get -y -q install --no-install-recommends parallel >>apt-parallel.log 2>&1; }; }; then
        say "installed GNU parallel with apt-get"
    else
        say "skipped: parallel: GNU parallel is not installed and apt-get could not install it"
        SKIPPED=$((SKIPPED + 2))
        parallel_ok=0
    fi
fi
if [ $parallel_ok = 1 ]; then
    t=$SECONDS
    if ! bash "$ROOT/scripts/parallel-sweep.sh" exp.toml p-clean "$N" >p-clean.log 2>&1; then
        cat p-clean.log
        fail "parallel: scripts/parallel-sweep.sh failed; the kill test not run" || true
    elif check "parallel" p-clean; then
        say "ok: parallel: $N shards, $RUNS runs merged = unsharded ($((SECONDS - t)) s)"
        PASSED=$((PASSED + 1))
        if parallel_kill; then PASSED=$((PASSED + 1)); fi
    fi
fi

if [ "$PASSED" -gt 0 ] || [ "$FAILED" -gt 0 ]; then
    say "took $((SECONDS - T0)) s"
    say "$PASSED passed, $FAILED failed, $SKIPPED skipped"
else
    say "all $SKIPPED skipped ($((SECONDS - T0)) s)"
fi
[ "$FAILED" -eq 0 ]
